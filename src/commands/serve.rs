//! `chronomap serve` and `chronomap client`: flags to a store, a token and a service; the
//! client subcommands print what the service answers.

use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use chronomap_app::open::FileKind;
use chronomap_client::Client;
use chronomap_io::navmap::{LoadSemantics, load_map};
use chronomap_serve::api::{EvaluateRequest, ForecastRequest};
use chronomap_serve::bt_monitor::{BtMonitors, MonitorOptions};
use chronomap_serve::heavy::HeavyLimits;
use chronomap_serve::maps::{Maps, ServedActivity, ServedTopo};
use chronomap_serve::server::ConnectionLimits;
use chronomap_serve::store::{Access, OWNER_WAIT, PostgresStore, RedbStore, Store};
use chronomap_serve::writer::CheckpointPolicy;
use chronomap_serve::{Service, ServiceConfig};
use chronomap_topo::map::TopoMap;
use serde_json::json;

use crate::cli::{ClientArgs, ClientCommand, ServeArgs};
use crate::outln;
use crate::output::{print_json, usage};

/// Shortest token accepted from a token file: 32 characters (128 bits as hex; the tokens
/// the service makes are 64 hex characters, 256 bits).
const MIN_TOKEN_CHARS: usize = 32;

/// `chronomap serve`.
pub fn serve(args: &ServeArgs) -> Result<()> {
    // Flags that contradict each other are refused before any file is opened.
    let layouts = attached(&args.topo_layout, &args.topo, "--topo-layout", "--topo")?;
    let activity_maps = attached(
        &args.activity_map,
        &args.activity,
        "--activity-map",
        "--activity",
    )?;
    if args.no_token && !args.listen.ip().is_loopback() {
        return Err(usage(format!(
            "--no-token is refused with --listen {}: without a token anyone who can reach that \
             address can change every model; listen on a loopback address (127.0.0.1, ::1) or \
             use the token",
            args.listen
        )));
    }
    if args.check {
        // Every file the flags name is read as the start reads it (the token only if it
        // exists: the start makes it), so that --check finds what would stop the start.
        let maps = read_maps(args, &layouts, &activity_maps)?;
        let token_file = args
            .token_file
            .clone()
            .unwrap_or_else(|| args.data.join("token"));
        if !args.no_token {
            read_token(&token_file)?;
        }
        check_or_salvage(args)?;
        outln!(
            "maps: {} topological, {} grids, {} activity maps read",
            maps.topological.len(),
            maps.grids.len(),
            maps.activity.len()
        )?;
        return Ok(());
    }
    if args.salvage {
        return check_or_salvage(args);
    }
    create_private_dir(&args.data)?;
    let token_file = if args.no_token {
        None
    } else {
        Some(
            args.token_file
                .clone()
                .unwrap_or_else(|| args.data.join("token")),
        )
    };
    let token = token_file
        .as_deref()
        .map(read_or_create_token)
        .transpose()?;
    let maps = read_maps(args, &layouts, &activity_maps)?;
    let store: Arc<dyn Store> = match &args.postgres {
        Some(config) => Arc::new(PostgresStore::connect_with(
            config,
            &args.postgres_schema,
            if args.fleet {
                Access::Fleet
            } else {
                Access::Owner
            },
            OWNER_WAIT,
            args.postgres_segment_groups,
        )?),
        None => Arc::new(RedbStore::open(args.data.join("chronomap.redb"))?),
    };
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
            .run(listener, shutdown_signal())
            .await
            .context("the service failed")
    })
}

/// The data directory, created readable by its owner only (mode 0700 on unix) if missing.
fn create_private_dir(dir: &Path) -> Result<()> {
    let mut builder = std::fs::DirBuilder::new();
    builder.recursive(true);
    #[cfg(unix)]
    std::os::unix::fs::DirBuilderExt::mode(&mut builder, 0o700);
    builder
        .create(dir)
        .with_context(|| format!("cannot create the data directory {}", dir.display()))
}

/// `chronomap serve --check` and `--salvage`.
fn check_or_salvage(args: &ServeArgs) -> Result<()> {
    use chronomap_serve::check;
    let redb_path = args.data.join("chronomap.redb");
    if args.postgres.is_none() && !redb_path.exists() {
        bail!("{}: no store to check or salvage", redb_path.display());
    }
    if args.salvage {
        let (report, kept) = match &args.postgres {
            None => {
                let (report, kept) = check::salvage_redb(&redb_path)?;
                (report, kept.display().to_string())
            }
            Some(config) => {
                let source = PostgresStore::connect_checker(config, &args.postgres_schema)?;
                let target = format!("{}_salvaged", args.postgres_schema);
                let into = PostgresStore::connect(config, &target)?;
                let held = into.recover()?;
                if held.last_seq > 0 || !held.snapshots.is_empty() {
                    bail!(
                        "postgres schema {target} already holds a store; drop it (DROP SCHEMA \
                         {target} CASCADE) or salvage into another --postgres-schema"
                    );
                }
                let (candidates, unread) = check::candidates_of(&source);
                let mut report = check::salvage(&candidates, &into)?;
                if let Some(e) = unread {
                    report
                        .lost
                        .insert(0, format!("the log cannot be read to its end: {e}"));
                }
                (
                    report,
                    format!(
                        "schema {} (unchanged); the salvaged store is the schema {target}: \
                         serve it with --postgres-schema {target}",
                        args.postgres_schema
                    ),
                )
            }
        };
        outln!("{}", report.text().trim_end())?;
        outln!("the damaged store is kept: {kept}")?;
        return Ok(());
    }
    // Nothing is written: the redb file is read read-only (redb's page check runs on a copy
    // elsewhere), a PostgreSQL schema without a store is not created.
    let verified = match &args.postgres {
        Some(config) => {
            let store = PostgresStore::connect_checker(config, &args.postgres_schema)?;
            check::verify(&store)?
        }
        None => match check::verify_redb(&redb_path) {
            Ok(verified) => verified,
            Err(e) => {
                outln!("store: redb {}", redb_path.display())?;
                outln!("cannot be read: {}", e.reason)?;
                bail!(
                    "{}: the store cannot be read; nothing was changed",
                    redb_path.display()
                );
            }
        },
    };
    outln!(
        "{}",
        verified.report.text(verified.registry.len()).trim_end()
    )?;
    if !verified.report.damage.is_empty() {
        bail!(
            "the store is damaged ({} problems); `chronomap serve --salvage` with the same flags \
             rebuilds it from every intact log entry",
            verified.report.damage.len()
        );
    }
    Ok(())
}

/// The files of `extra` (`--topo-layout`, `--activity-map`) by the name of the map of `base`
/// (`--topo`, `--activity`) they belong to.
fn attached<'a>(
    extra: &'a [(String, PathBuf)],
    base: &[(String, PathBuf)],
    extra_flag: &str,
    base_flag: &str,
) -> Result<HashMap<&'a str, &'a Path>> {
    let mut by_name = HashMap::new();
    for (name, path) in extra {
        if !base.iter().any(|(n, _)| n == name) {
            return Err(usage(format!(
                "{extra_flag} {name}: no {base_flag} map is named {name:?}"
            )));
        }
        if by_name.insert(name.as_str(), path.as_path()).is_some() {
            return Err(usage(format!("{extra_flag} {name} is given twice")));
        }
    }
    Ok(by_name)
}

/// Reads every map file the flags name, and lays out the topological maps.
fn read_maps(
    args: &ServeArgs,
    layouts: &HashMap<&str, &Path>,
    activity_maps: &HashMap<&str, &Path>,
) -> Result<Maps> {
    let mut maps = Maps::default();
    for (name, path) in &args.topo {
        let models = chronomap_io::model_file::read_edge_models(path)
            .with_context(|| format!("--topo {name}"))?;
        let served = match layouts.get(name.as_str()) {
            Some(layout) => {
                let context = || format!("--topo-layout {name}");
                let map = read_layout(layout).with_context(context)?;
                ServedTopo::with_layout(models, &layout.display().to_string(), &map)
                    .with_context(context)?
            }
            None => ServedTopo::new(models),
        };
        maps.topological.insert(name.clone(), served);
    }
    for (name, path) in &args.grid {
        let grid = chronomap_io::grid_file::read_grid_file(path)
            .with_context(|| format!("--grid {name}"))?;
        maps.grids.insert(name.clone(), grid);
    }
    for (name, path) in &args.activity {
        let model =
            chronomap_io::read_copa_map(path).with_context(|| format!("--activity {name}"))?;
        let map = activity_maps
            .get(name.as_str())
            .map(|yaml| load_map(yaml, LoadSemantics::Nav2))
            .transpose()
            .with_context(|| format!("--activity-map {name}"))?;
        maps.activity
            .insert(name.clone(), ServedActivity::new(model, map));
    }
    Ok(maps)
}

/// The nodes (with positions) of a Nav2 route graph (`.geojson`, `.json`) or else of a tmap2
/// map; either may be compressed (`.xz`, `.gz`).
fn read_layout(path: &Path) -> Result<TopoMap> {
    Ok(match FileKind::by_name(path) {
        FileKind::RouteGeoJson => chronomap_io::topo_files::read_route_geojson(path)?,
        _ => chronomap_io::topo_files::read_tmap2(path)?,
    })
}

/// Completes on Ctrl-C or SIGTERM.
async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut signal) => {
                signal.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {}
        () = terminate => {}
    }
}

/// The token in `path`, or a new random one written there (readable by the owner only).
/// An existing file must be readable by its owner only (as ssh requires of private keys) and
/// hold at least [`MIN_TOKEN_CHARS`] visible ASCII characters.
fn read_or_create_token(path: &Path) -> Result<String> {
    if let Some(token) = read_token(path)? {
        return Ok(token);
    }
    let mut bytes = [0u8; 32];
    getrandom::fill(&mut bytes)
        .map_err(|e| anyhow::anyhow!("no random numbers for a token: {e}"))?;
    let token: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let mut file = options
        .open(path)
        .with_context(|| format!("cannot create the token file {}", path.display()))?;
    writeln!(file, "{token}")
        .and_then(|()| file.sync_all())
        .with_context(|| format!("cannot write the token file {}", path.display()))?;
    Ok(token)
}

/// Most bytes of a token file (a token is at least [`MIN_TOKEN_CHARS`] characters; the
/// service makes 64).
const MAX_TOKEN_FILE_BYTES: u64 = 4096;

/// The token in the file `path`, `None` if there is no such file. The file must be a regular
/// file of at most [`MAX_TOKEN_FILE_BYTES`] (a device such as `/dev/zero` or a pipe is refused
/// before it is read), readable by its owner only.
fn read_token(path: &Path) -> Result<Option<String>> {
    let cannot = || format!("cannot read the token file {}", path.display());
    let metadata = match std::fs::metadata(path) {
        Ok(metadata) => metadata,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e).with_context(cannot),
    };
    if !metadata.is_file() {
        bail!(
            "{}: the token file is not a regular file (a directory, a device or a pipe)",
            path.display()
        );
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = metadata.permissions().mode();
        if mode & 0o077 != 0 {
            bail!(
                "{}: the token file is readable by others (mode {:04o}); anyone who reads it \
                 can change every model. Run `chmod 600 {}`",
                path.display(),
                mode & 0o7777,
                path.display()
            );
        }
    }
    let text = match chronomap_io::read_regular_at_most(path, MAX_TOKEN_FILE_BYTES) {
        Ok(bytes) => String::from_utf8_lossy(&bytes).into_owned(),
        Err(e) if e.kind() == std::io::ErrorKind::InvalidData => bail!(
            "{}: the token file has more than {MAX_TOKEN_FILE_BYTES} bytes (is this the right \
             file?)",
            path.display()
        ),
        Err(e) => return Err(e).with_context(cannot),
    };
    let token = text.trim().to_owned();
    if token.chars().count() < MIN_TOKEN_CHARS || !token.bytes().all(|b| b.is_ascii_graphic()) {
        bail!(
            "{}: a token must be at least {MIN_TOKEN_CHARS} visible ASCII characters without \
             spaces (this one has {}); delete the file to have a random one made",
            path.display(),
            token.chars().count()
        );
    }
    Ok(Some(token))
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
        ClientCommand::Create { id, model, range } => {
            let range = range.as_ref().map(|r| [r[0], r[1]]);
            // (two values: checked in client())
            let ack = client.create(id, Some(model), range).await?;
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
            let series = super::read_series(file)?;
            let mut added: u64 = 0;
            let mut seq = None;
            for (times, values) in series
                .times
                .chunks((*batch).max(1))
                .zip(series.values.chunks((*batch).max(1)))
            {
                let ack = client
                    .add_values(id, times, values, model.as_deref())
                    .await
                    .with_context(|| {
                        format!(
                            "{}: observations {}..{} were not added ({added} were)",
                            super::source_name(file),
                            added + 1,
                            added + times.len() as u64
                        )
                    })?;
                added += ack.observations;
                seq = Some(ack.seq);
            }
            if as_json {
                return print_json(&json!({"id": id, "added": added, "seq": seq}));
            }
            outln!("added {added} observations to {id:?}")?;
        }
        ClientCommand::Predict { id, order, .. } => {
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

/// `from, from + step, ...` up to `to`.
fn range_times(from: f64, to: f64, step: f64) -> Result<Vec<f64>> {
    if to < from {
        return Err(usage("--to is before --from"));
    }
    // In floating point first: a cast would saturate (1e9 / 1e-300) and the + 1 wrap to 0.
    let steps = ((to - from) / step).floor();
    if !(steps.is_finite() && steps < 1_000_000.0) {
        return Err(usage(format!(
            "{:e} times from --from to --to every --step {step:e} s: at most 1,000,000; choose a \
             larger --step",
            steps + 1.0
        )));
    }
    let n = steps as usize + 1;
    Ok((0..n).map(|i| from + i as f64 * step).collect())
}

#[cfg(test)]
mod tests {
    /// docs/limits.md names the token file's limit as `tests/cli/limits.rs` checks the
    /// library's limits (that test cannot see the binary's constants).
    #[test]
    fn the_token_file_limit_in_docs_limits_is_the_one_here() {
        let doc = include_str!("../../docs/limits.md");
        let row = doc
            .lines()
            .find(|l| {
                l.starts_with("| `MAX_TOKEN_FILE_BYTES`") && l.contains("`src/commands/serve.rs`")
            })
            .expect("docs/limits.md has a row for MAX_TOKEN_FILE_BYTES");
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        assert_eq!(
            cells[2].replace(',', ""),
            super::MAX_TOKEN_FILE_BYTES.to_string()
        );
    }
}
