//! `chronomap bench psbt`: person search tree synthesis ([Stüde 2024] §5.4.3) for 6 and 10 places
//! on the bundled ATC day, against the dense reference and a per-tree solve in the same run —
//! [`chronomap_bench::psbt`] measures, the world loads as `chronomap psbt` loads it
//! ([`chronomap_app_bt::psbt::load_world`]).

use anyhow::Result;
use chronomap_app_bt::psbt::{PsbtJobError, fit_model, load_world};
use chronomap_bench::psbt::PsbtBenchConfig;

use super::psbt::job_error;
use crate::cli::BenchPsbtArgs;
use crate::out;
use crate::output::print_bench;

pub fn psbt(args: &BenchPsbtArgs) -> Result<()> {
    let world = load_world(&args.map, &args.activity, 0.5, 0.3).map_err(job_error)?;
    let model = fit_model(&world, 1.0, 3600.0, |_| true)
        .and_then(|m| m.ok_or(PsbtJobError::NoDetection))
        .map_err(job_error)?;
    let bench = chronomap_bench::psbt::run(
        &world.grid,
        &model,
        &PsbtBenchConfig {
            from: args.from,
            time: args.time,
            repeats: args.repeats,
            reference_sample: args.reference_sample,
        },
    )?;
    print_bench(args.json, &bench, |b| Ok(out!("{}", b.text())?))
}
