//! `chronomap bench fleet`: a fleet of 1, 2 and 3 nodes over one PostgreSQL server, against
//! the bare database work in the same run — [`chronomap_bench::fleet`] measures, this prints.

use anyhow::Result;
use chronomap_bench::fleet::{FleetBench, FleetBenchConfig, FleetBenchError};

use crate::cli::BenchFleetArgs;
use crate::format::Table;
use crate::outln;
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
    print_bench(args.json, &bench, |b| print(&config, b))
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

fn print(config: &FleetBenchConfig, b: &FleetBench) -> Result<()> {
    outln!(
        "chronomap serve --fleet on 127.0.0.1, PostgreSQL {}, {} hardware threads shared by nodes, clients and the database",
        b.server_version,
        b.threads
    )?;
    outln!(
        "writes: {} clients per node, POST /v1/observations of {} observations over {} models, for {} s; one client per node times predict (one model, one time) meanwhile",
        config.clients_per_node,
        config.batch,
        config.batch_ids,
        config.seconds
    )?;
    let mut table = Table::new([
        "nodes",
        "observations/s",
        "requests",
        "commit groups",
        "predict p50 µs",
        "predict p99 µs",
        "INSERT rows/s",
        "fleet / INSERT",
        "COPY rows/s",
        "fleet / COPY",
    ]);
    for run in &b.runs {
        let baseline = |k: usize| {
            run.baselines.get(k).map_or(("-".into(), "-".into()), |x| {
                (
                    format!("{:.3e}", x.rows_per_second),
                    format!("{:.2}", x.ratio_fleet_to_baseline),
                )
            })
        };
        let (insert, insert_ratio) = baseline(0);
        let (copy, copy_ratio) = baseline(1);
        table.row([
            run.nodes.to_string(),
            format!("{:.3e}", run.observations_per_second),
            run.requests.to_string(),
            run.commit_groups.to_string(),
            format!("{:.0}", run.predict_p50_us),
            format!("{:.0}", run.predict_p99_us),
            insert,
            insert_ratio,
            copy,
            copy_ratio,
        ]);
    }
    outln!("{}", table.render())?;
    if let Some(c) = &b.catch_up {
        outln!(
            "\ncatch-up of a new node: {} observations of {} models in {} commit groups (written in {:.1} s)",
            c.observations,
            c.models,
            c.groups,
            c.write_seconds
        )?;
        outln!(
            "  from the log alone (verify + replay every group): {:.2} s = {:.3e} observations/s",
            c.replay_seconds,
            c.observations as f64 / c.replay_seconds
        )?;
        outln!(
            "  checkpoint of every model: {:.2} s; compaction ({} segments of 10 groups to the archive): {:.2} s",
            c.checkpoint_seconds,
            c.segments_compacted,
            c.compact_seconds
        )?;
        outln!(
            "  a new node from the checkpoint and the live log: {:.2} s ({:.1}x faster); models bit-identical: {}",
            c.start_from_checkpoint_seconds,
            c.replay_seconds / c.start_from_checkpoint_seconds,
            if c.identical { "yes" } else { "NO" }
        )?;
    }
    Ok(())
}
