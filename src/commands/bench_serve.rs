//! `chronomap bench serve`: a bounded load generator against the service on loopback, with the
//! same work done without the service in the same run as baselines —
//! [`chronomap_bench::serve`] measures, this prints.

use anyhow::{Context, Result, anyhow};
use chronomap_bench::serve::{ServeBenchConfig, ServeBenchError};
use chronomap_bench::serve_grid::{GridLoadConfig, GridLoadError};

use crate::cli::BenchServeArgs;
use crate::out;
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
    print_bench(args.json, &bench, |b| Ok(out!("{}", b.text(&config))?))
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
    print_bench(args.json, &bench, |b| Ok(out!("{}", b.text())?))
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
