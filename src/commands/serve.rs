//! `chronomap serve` and `chronomap client`: flags to a store, a token and a service
//! ([`chronomap_serve::startup`]); the client subcommands print what the service answers.

use std::collections::HashMap;
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use chronomap_client::Client;
use chronomap_client::api::{TimeRangeError, time_range};
use chronomap_serve::api::{CreateRequest, EvaluateRequest, ForecastRequest};
use chronomap_serve::bt_monitor::{BtMonitors, MonitorOptions};
use chronomap_serve::check;
use chronomap_serve::heavy::HeavyLimits;
use chronomap_serve::server::ConnectionLimits;
use chronomap_serve::startup::{self, MapFiles, StoreLocation};
use chronomap_serve::writer::CheckpointPolicy;
use chronomap_serve::{Service, ServiceConfig};
use serde_json::json;

use crate::cli::{ClientArgs, ClientCommand, SeriesSource, ServeArgs};
use crate::outln;
use crate::output::{print_json, usage};

/// `chronomap serve`.
pub fn serve(args: &ServeArgs) -> Result<()> {
    // Flags that contradict each other are refused before any file is opened.
    let files = MapFiles {
        topological: args.topo.clone(),
        layouts: attached(&args.topo_layout, &args.topo, "--topo-layout", "--topo")?,
        grids: args.grid.clone(),
        activity: args.activity.clone(),
        activity_maps: attached(
            &args.activity_map,
            &args.activity,
            "--activity-map",
            "--activity",
        )?,
    };
    if args.no_token && !args.listen.ip().is_loopback() {
        return Err(usage(format!(
            "--no-token is refused with --listen {}: without a token anyone who can reach that \
             address can change every model; listen on a loopback address (127.0.0.1, ::1) or \
             use the token",
            args.listen
        )));
    }
    let store_at = match &args.postgres {
        Some(config) => StoreLocation::Postgres {
            config: config.clone(),
            schema: args.postgres_schema.clone(),
        },
        None => StoreLocation::Redb {
            data: args.data.clone(),
        },
    };
    let token_file = (!args.no_token).then(|| {
        args.token_file
            .clone()
            .unwrap_or_else(|| args.data.join("token"))
    });
    if args.check {
        // Every file the flags name is read as the start reads it (the token only if it
        // exists: the start makes it), so that --check finds what would stop the start.
        let maps = startup::read_maps(&files)?;
        if let Some(file) = &token_file {
            startup::read_token(file)?;
        }
        let checked = check::check_store(&store_at)?;
        outln!("{}", checked.text().trim_end())?;
        if let Some(failure) = checked.failure() {
            bail!("{failure}");
        }
        outln!(
            "maps: {} topological, {} grids, {} activity maps read",
            maps.topological.len(),
            maps.grids.len(),
            maps.activity.len()
        )?;
        return Ok(());
    }
    if args.salvage {
        return Ok(outln!(
            "{}",
            check::salvage_store(&store_at)?.text().trim_end()
        )?);
    }
    startup::create_private_dir(&args.data)?;
    let token = token_file
        .as_deref()
        .map(startup::read_or_create_token)
        .transpose()?;
    let maps = startup::read_maps(&files)?;
    let store = startup::open_store(&store_at, args.fleet, args.postgres_segment_groups)?;
    let description = store.describe();
    let config = ServiceConfig {
        token,
        max_body_bytes: args.max_body_bytes,
        checkpoint: CheckpointPolicy {
            every_observations: args.snapshot_every,
            every: Duration::from_secs_f64(args.snapshot_secs),
        },
        maps: Arc::new(maps),
        allowed_hosts: args.allow_host.clone(),
        limits: ConnectionLimits {
            header_timeout: Duration::from_secs_f64(args.header_timeout),
            body_timeout: Duration::from_secs_f64(args.body_timeout),
            max_connections: args.max_connections as usize,
        },
        refit: chronomap_models::RefitPolicy {
            observations: args.refit_every,
            data_secs: args.refit_secs,
        },
        bt_monitors: Arc::new(
            BtMonitors::start(args.bt_monitor.clone(), MonitorOptions::default()).map_err(usage)?,
        ),
        heavy: HeavyLimits {
            workers: args
                .heavy_workers
                .map_or_else(HeavyLimits::default_workers, |n| n as usize),
            queue: args.heavy_queue as usize,
        },
        light: HeavyLimits {
            workers: args
                .light_workers
                .map_or_else(HeavyLimits::default_workers, |n| n as usize),
            queue: args.light_queue as usize,
        },
    };
    let service = Service::start(store, config).map_err(anyhow::Error::msg)?;
    let models = service.models();
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    runtime.block_on(async move {
        let listener = tokio::net::TcpListener::bind(args.listen)
            .await
            .with_context(|| format!("cannot listen on {}", args.listen))?;
        let address = listener.local_addr()?;
        outln!(
            "chronomap serve: listening on http://{address} ({description}, {models} models recovered)"
        )?;
        match &token_file {
            Some(file) => outln!(
                "writes need `Authorization: Bearer TOKEN` with the token in {}",
                file.display()
            )?,
            None => outln!("warning: writes need no token (--no-token)")?,
        }
        for target in &args.bt_monitor {
            outln!(
                "watching the behavior tree of the Groot2 publisher at {} as {:?} \
                 (http://{address}/v1/bt/monitors)",
                target.address,
                target.id
            )?;
        }
        outln!("API description: http://{address}/openapi.json")?;
        std::io::stdout().flush()?;
        service
            .run(listener, startup::shutdown_signal())
            .await
            .context("the service failed")
    })
}

/// The files of `extra` (`--topo-layout`, `--activity-map`) by the name of the map of `base`
/// (`--topo`, `--activity`) they belong to.
fn attached(
    extra: &[(String, PathBuf)],
    base: &[(String, PathBuf)],
    extra_flag: &str,
    base_flag: &str,
) -> Result<HashMap<String, PathBuf>> {
    let mut by_name = HashMap::new();
    for (name, path) in extra {
        if !base.iter().any(|(n, _)| n == name) {
            return Err(usage(format!(
                "{extra_flag} {name}: no {base_flag} map is named {name:?}"
            )));
        }
        if by_name.insert(name.clone(), path.clone()).is_some() {
            return Err(usage(format!("{extra_flag} {name} is given twice")));
        }
    }
    Ok(by_name)
}

/// `chronomap client`.
pub fn client(args: &ClientArgs) -> Result<()> {
    // Flags that contradict each other are refused before any connection.
    let times = match &args.command {
        ClientCommand::Predict {
            at, from, to, step, ..
        } => Some(match (from, to) {
            (Some(from), Some(to)) => range_times(*from, *to, *step)?,
            _ if !at.is_empty() => at.clone(),
            _ => return Err(usage("give --at TIMES or --from T --to T [--step S]")),
        }),
        ClientCommand::Create {
            range: Some(range), ..
        } if range.len() != 2 => {
            return Err(usage(format!(
                "--range takes LO,HI (two numbers), not {} number",
                range.len()
            )));
        }
        _ => None,
    };
    let token = args
        .token_file
        .as_deref()
        .map(|path| -> Result<String> {
            Ok(std::fs::read_to_string(path)
                .with_context(|| format!("cannot read the token file {}", path.display()))?
                .trim()
                .to_owned())
        })
        .transpose()?;
    let mut client = Client::new(&args.url, token)?;
    if let Some(seq) = args.read_after {
        client = client.reading_after(seq);
    }
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    runtime.block_on(run_client(&client, &args.command, times, args.json))
}

async fn run_client(
    client: &Client,
    command: &ClientCommand,
    times: Option<Vec<f64>>,
    as_json: bool,
) -> Result<()> {
    match command {
        ClientCommand::Health => print_json(&client.health().await?)?,
        ClientCommand::List { prefix } => {
            let list = match prefix {
                Some(prefix) => client.list_prefix(prefix).await?,
                None => client.list().await?,
            };
            if as_json {
                return print_json(&list);
            }
            for model in list.models {
                outln!(
                    "{}\t{}\t{} observations",
                    model.id,
                    model.model,
                    model.observations
                )?;
            }
        }
        ClientCommand::View { id } => print_json(&client.view(id).await?)?,
        ClientCommand::Create {
            id,
            model,
            range,
            days_off,
        } => {
            // (two values: checked in client())
            let range = range.as_ref().map(|r| [r[0], r[1]]);
            let days_off = match days_off {
                // The days as the service takes them: `YYYY-MM-DD`.
                Some(path) => Some(
                    chronomap_io::read_days_off(path)
                        .context("--days-off")?
                        .days()
                        .map(chronomap_core::time::format_date)
                        .collect(),
                ),
                None => None,
            };
            let request = CreateRequest {
                model: Some(model.clone()),
                range,
                days_off,
            };
            let ack = client.create_with(id, &request).await?;
            if as_json {
                return print_json(&json!({"id": id, "model": model, "seq": ack.seq}));
            }
            outln!("created {id:?} ({model}) at log position {}", ack.seq)?;
        }
        ClientCommand::Remove { id } => {
            let ack = client.remove(id).await?;
            if as_json {
                return print_json(&json!({"id": id, "removed": true, "seq": ack.seq}));
            }
            outln!("removed {id:?}")?;
        }
        ClientCommand::Refit { id } => {
            let refit = client.refit(id).await?;
            if as_json {
                return print_json(&refit);
            }
            let fit = &refit.fit;
            let how = if refit.refitted {
                format!("refitted in {:.2} s", refit.secs)
            } else {
                "already fitted on every observation".into()
            };
            outln!(
                "{id:?} {how}: {} on {} observations, {} .. {} (log position {})",
                fit.fitted,
                fit.observations,
                chronomap_core::time::format_time(fit.first_time),
                chronomap_core::time::format_time(fit.last_time),
                refit.seq
            )?;
            for weight in &fit.weights {
                outln!("  {}\t{:.4}", weight.model, weight.weight)?;
            }
            if let Some(error) = fit.error {
                outln!("  held-back error {error:.4}")?;
            }
        }
        ClientCommand::Add {
            id,
            file,
            model,
            batch,
        } => {
            // Values in the units of a continuous state's range are checked by the service,
            // which knows the model's range.
            let series = match file {
                SeriesSource::Pairs(path) => chronomap_io::read_measurements(path)?,
                split => super::read_series(split)?,
            };
            let added = client
                .add_series(id, &series.times, &series.values, model.as_deref(), *batch)
                .await
                .with_context(|| super::source_name(file))?;
            let (added, seq) = (added.observations, added.seq);
            if as_json {
                return print_json(&json!({"id": id, "added": added, "seq": seq}));
            }
            outln!("added {added} observations to {id:?}")?;
        }
        ClientCommand::Predict {
            id,
            order,
            coverage: None,
            ..
        } => {
            let times = times.expect("checked in client()");
            let p = client.predict(id, &times, *order).await?;
            let entropies = client.entropy(id, &times, *order).await?;
            if as_json {
                return print_json(&json!({
                    "id": id,
                    "times": times,
                    "probability": p.values,
                    "entropy": entropies.values,
                }));
            }
            outln!("time\tprobability\tentropy")?;
            for ((t, p), h) in times.iter().zip(&p.values).zip(&entropies.values) {
                outln!("{}\t{p:.4}\t{h:.4}", crate::format::time(*t))?;
            }
        }
        ClientCommand::Predict {
            id,
            order,
            coverage: Some(coverage),
            ..
        } => {
            let times = times.expect("checked in client()");
            let answer = client
                .predict_interval(id, &times, *order, *coverage)
                .await?;
            let (Some(value), Some(lower), Some(upper)) =
                (answer.scaled, answer.lower, answer.upper)
            else {
                bail!(
                    "model {id:?} has no prediction intervals: only models of continuous \
                     values (created with --range) whose spec learns online, or `auto` once \
                     fitted, have them"
                );
            };
            if as_json {
                return print_json(&json!({
                    "id": id,
                    "times": times,
                    "value": value,
                    "coverage": coverage,
                    "lower": lower,
                    "upper": upper,
                }));
            }
            outln!("time\tvalue\tlower\tupper")?;
            for (((t, v), lo), hi) in times.iter().zip(&value).zip(&lower).zip(&upper) {
                outln!("{}\t{v:.4}\t{lo:.4}\t{hi:.4}", crate::format::time(*t))?;
            }
        }
        ClientCommand::Forecast { ids, at, order } => {
            let request = ForecastRequest {
                ids: ids.clone(),
                time: *at,
                order: *order,
                orders: None,
            };
            let p = client.forecast(&request).await?;
            if as_json {
                return print_json(&json!({"time": at, "ids": ids, "probability": p.values}));
            }
            for (id, p) in ids.iter().zip(p.values) {
                outln!("{id}\t{p:.4}")?;
            }
        }
        ClientCommand::Evaluate {
            id,
            file,
            max_order,
        } => {
            let series = super::read_series(file)?;
            let request = EvaluateRequest {
                id: id.clone(),
                times: series.times,
                values: series.values,
                max_order: *max_order,
            };
            let e = client.evaluate(&request).await?;
            if as_json {
                return print_json(&e);
            }
            outln!("order\t{}\tbrier", e.metric)?;
            for ((order, error), brier) in e.orders.iter().zip(&e.errors).zip(&e.brier) {
                outln!("{order}\t{error:.4}\t{brier:.4}")?;
            }
            outln!("best order: {}", e.best_order)?;
        }
    }
    Ok(())
}

/// `--from T --to T --step S` as times ([`time_range`]).
fn range_times(from: f64, to: f64, step: f64) -> Result<Vec<f64>> {
    time_range(from, to, step).map_err(|e| match e {
        TimeRangeError::Backwards => usage("--to is before --from"),
        TimeRangeError::TooMany { times } => usage(format!(
            "{times:e} times from --from to --to every --step {step:e} s: at most 1,000,000; \
             choose a larger --step"
        )),
    })
}
