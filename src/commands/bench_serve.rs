//! `chronomap bench serve`: a bounded load generator against the service on loopback, with the
//! same work done without the service in the same run as baselines —
//! [`chronomap_bench::serve`] measures, this prints.

use anyhow::{Context, Result, anyhow};
use chronomap_bench::serve::{ServeBench, ServeBenchConfig, ServeBenchError, WARM_UP};
use chronomap_bench::serve_grid::{GridLoadBench, GridLoadConfig, GridLoadError, Percentiles};

use crate::cli::BenchServeArgs;
use crate::format::Table;
use crate::outln;
use crate::output::print_bench;

pub fn serve(args: &BenchServeArgs) -> Result<()> {
    if args.grid_load {
        return grid_load(args);
    }
    let config = ServeBenchConfig {
        models: args.models,
        model: args.model.clone(),
        preload: args.preload,
        clients: args.clients,
        requests: args.requests,
        latency_seconds: args.latency_seconds,
        predict_times: args.predict_times,
        forecast_ids: args.forecast_ids,
        observations: args.observations,
        batch: args.batch,
        batch_ids: args.batch_ids,
        seconds: args.seconds,
        data: args.data.clone(),
    };
    config.validate().map_err(flag_error)?;
    let train = match &args.train {
        Some(path) => chronomap_io::read_pairs(path)
            .with_context(|| format!("cannot read {}", path.display()))?,
        None => crate::bundled::GREG_TRAINING.pairs()?,
    };
    let bench = chronomap_bench::serve::run(&config, train).map_err(flag_error)?;
    print_bench(args.json, &bench, |b| print(&config, b))
}

/// `--grid-load`: this binary's service against --baseline-bin's under grid maps.
fn grid_load(args: &BenchServeArgs) -> Result<()> {
    let config = GridLoadConfig {
        this_build: std::env::current_exe().context("cannot find this binary")?,
        baseline: args.baseline_bin.clone(),
        cells: args.grid_cells,
        days: 7,
        grid_clients: args.grid_clients,
        seconds: args.grid_seconds,
        rounds: args.grid_rounds,
    };
    config.validate().map_err(|e| match e {
        GridLoadError::Config { field, message } => crate::output::usage(format!(
            "--grid-{}: {message}",
            field.trim_start_matches("grid_").replace('_', "-")
        )),
        other => other.into(),
    })?;
    let train = match &args.train {
        Some(path) => chronomap_io::read_pairs(path)
            .with_context(|| format!("cannot read {}", path.display()))?,
        None => crate::bundled::GREG_TRAINING.pairs()?,
    };
    let door = chronomap_bench::serve_grid::Door {
        times: &train.times,
        values: &train.values,
    };
    let bench = chronomap_bench::serve_grid::run(&config, door)?;
    print_bench(args.json, &bench, print_grid_load)
}

fn print_grid_load(b: &GridLoadBench) -> Result<()> {
    outln!(
        "chronomap serve in processes of their own on 127.0.0.1, in turns, {} rounds of {} s phases, {} hardware threads",
        b.rounds,
        b.seconds,
        b.threads
    )?;
    outln!(
        "grid: synthetic office, {} cells ({} changing, kept with its learning state), a map is {:.2} MB of JSON; door: fremen:2 on the greg door",
        b.cells,
        b.changing_cells,
        b.map_bytes as f64 / 1e6
    )?;
    outln!(
        "quiet: 4 clients back to back; loaded: {} clients ask for maps while 1 client checks health and 1 predicts the door\n",
        b.grid_clients
    )?;
    let mut table = Table::new([
        "service",
        "quiet predict p50 / p99 µs",
        "quiet health p50 / p99 µs",
        "loaded map p50 / p99 ms",
        "maps/s",
        "loaded health p50 / p99 µs",
        "loaded predict p50 / p99 µs",
    ]);
    let us = |p: &Percentiles| format!("{:.0} / {:.0}", p.p50_us, p.p99_us);
    for s in &b.services {
        table.row([
            s.name.clone(),
            us(&s.quiet_predict),
            us(&s.quiet_health),
            format!(
                "{:.1} / {:.1}",
                s.loaded_grid.p50_us / 1e3,
                s.loaded_grid.p99_us / 1e3
            ),
            format!("{:.0}", s.grid_per_second),
            us(&s.loaded_health),
            us(&s.loaded_predict),
        ]);
    }
    outln!("{}", table.render())?;
    for (what, ratio) in b.ratios() {
        outln!("{what}: this build / baseline = {ratio:.2}")?;
    }
    if let Some(this) = b.services.last() {
        outln!(
            "goal: door predict p99 < 1 ms (quiet): {} ({:.0} µs)",
            if this.quiet_predict.p99_us < 1000.0 {
                "met"
            } else {
                "missed"
            },
            this.quiet_predict.p99_us
        )?;
    }
    Ok(())
}

/// The library's error, naming the flag of a bad field (`--batch-ids` for `batch_ids`).
fn flag_error(error: ServeBenchError) -> anyhow::Error {
    match error {
        ServeBenchError::Config { field, message } => {
            anyhow!("--{}: {message}", field.replace('_', "-"))
        }
        ServeBenchError::Model { spec, message } => anyhow!("--model {spec}: {message}"),
        other => other.into(),
    }
}

/// "1 client", "4 clients".
fn clients(n: usize) -> String {
    format!("{n} client{}", if n == 1 { "" } else { "s" })
}

fn print(config: &ServeBenchConfig, b: &ServeBench) -> Result<()> {
    outln!(
        "chronomap serve on 127.0.0.1 (redb store, bearer token), {} {} models, {}, {} hardware threads",
        b.models,
        b.model,
        clients(b.clients),
        b.threads
    )?;
    let p = &b.preload;
    outln!(
        "preload: {} observations ({} per model) in {} requests, durable in {:.2} s = {:.3e} observations/s (in-process models: {:.2} s)",
        p.observations,
        config.preload,
        p.requests,
        p.seconds,
        p.observations_per_second,
        p.in_process_seconds
    )?;
    outln!(
        "\nlatency: {} back to back, up to {} requests each per kind (or {} s), after {WARM_UP} untimed ones",
        clients(b.clients),
        config.requests,
        config.latency_seconds
    )?;
    let mut table = Table::new([
        "request",
        "requests",
        "p50 µs",
        "p99 µs",
        "max µs",
        "requests/s",
        "in-process µs",
        "p50 / in-process",
        "p50 / health p50",
    ]);
    for l in &b.latency {
        let (ip, ratio, ratio_health) = match (
            l.in_process_ns,
            l.ratio_p50_to_in_process,
            l.ratio_p50_to_health,
        ) {
            (Some(ns), Some(ratio), Some(health)) => (
                format!("{:.3}", ns / 1e3),
                format!("{ratio:.0}"),
                format!("{health:.2}"),
            ),
            _ => ("-".into(), "-".into(), "1.00".into()),
        };
        table.row([
            l.request.clone(),
            l.requests.to_string(),
            format!("{:.0}", l.p50_us),
            format!("{:.0}", l.p99_us),
            format!("{:.0}", l.max_us),
            format!("{:.0}", l.requests_per_second),
            ip,
            ratio,
            ratio_health,
        ]);
    }
    outln!("{}", table.render())?;
    let t = &b.throughput;
    outln!(
        "\ndurable throughput: {}, POST /v1/observations of {} observations over {} models each ({:.1} MB of JSON bodies, encoded beforehand in {:.2} s)",
        clients(t.writers),
        t.batch,
        t.batch_ids.min(b.models.div_ceil(t.writers)),
        t.body_bytes as f64 / 1e6,
        t.client_encode_seconds
    )?;
    outln!(
        "  {} observations in {} requests acknowledged in {:.2} s ({} commit groups{}) = {:.3e} durable observations/s",
        t.observations,
        t.requests,
        t.seconds,
        t.commits,
        if t.observations < t.prepared_observations {
            format!(", stopped by --seconds before {}", t.prepared_observations)
        } else {
            String::new()
        },
        t.observations_per_second
    )?;
    let mut table = Table::new([
        "baseline (one thread, same bodies)",
        "observations",
        "observations/s",
        "service / baseline",
    ]);
    for baseline in &t.baselines {
        table.row([
            baseline.what.to_string(),
            baseline.observations.to_string(),
            format!("{:.3e}", baseline.observations_per_second),
            format!("{:.2}", baseline.ratio_service_to_baseline),
        ]);
    }
    table.row([
        "all four one after the other".to_string(),
        "-".into(),
        format!("{:.3e}", t.baseline_pipeline_observations_per_second),
        format!("{:.2}", t.ratio_service_to_pipeline),
    ]);
    outln!("{}", table.render())?;
    let p99 = b.predict_p99_us();
    outln!(
        "\ngoals: predict p99 < 1 ms: {} ({p99:.0} µs); >= 1e6 durable observations/s in batches: {} ({:.3e})",
        if b.goals.predict_p99_under_1ms {
            "met"
        } else {
            "missed"
        },
        if b.goals.durable_1m_observations_per_second {
            "met"
        } else {
            "missed"
        },
        t.observations_per_second
    )?;
    if let Some(path) = &b.data {
        outln!("the store is kept in {path}")?;
    }
    Ok(())
}
