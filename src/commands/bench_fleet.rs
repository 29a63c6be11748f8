//! `chronomap bench fleet`: a fleet of 1, 2 and 3 nodes over one PostgreSQL server, against
//! the bare database work in the same run — [`chronomap_bench::fleet`] measures, this prints.

use anyhow::Result;
use chronomap_bench::fleet::{FleetBenchConfig, FleetBenchError};

use crate::cli::BenchFleetArgs;
use crate::out;
use crate::output::{ProgressBar, print_bench, usage};

pub fn fleet(args: &BenchFleetArgs) -> Result<()> {
    let config = FleetBenchConfig {
        postgres: args.postgres.clone(),
        nodes: args.nodes.clone(),
        clients_per_node: args.clients_per_node,
        models: args.models,
        model: args.model.clone(),
        batch: args.batch,
        batch_ids: args.batch_ids,
        seconds: args.seconds,
        catch_up_observations: args.catch_up_observations,
        keep: args.keep,
    };
    config.validate().map_err(flag_error)?;
    let bench = {
        let progress = ProgressBar::new();
        chronomap_bench::fleet::run(&config, &progress).map_err(flag_error)?
    };
    print_bench(args.json, &bench, |b| Ok(out!("{}", b.text(&config))?))
}

/// The library's error, naming the flag of a bad field (`--batch-ids` for `batch_ids`): a usage
/// error (exit code 2).
fn flag_error(error: FleetBenchError) -> anyhow::Error {
    match error {
        FleetBenchError::Config { field, message } => {
            usage(format!("--{}: {message}", field.replace('_', "-")))
        }
        other => other.into(),
    }
}
