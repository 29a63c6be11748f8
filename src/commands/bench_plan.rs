//! `chronomap bench plan`: planning on the Witham map end to end ([Fentanes 2015] §V), against Storm
//! on the same 72 cases (24 hours × 3 tasks) in the same run — [`chronomap_bench::plan`]
//! measures and reports, this prints.

use anyhow::Result;
use chronomap_bench::plan::PlanConfig;
use chronomap_core::progress::Progress;

use crate::cli::BenchPlanArgs;
use crate::out;
use crate::output::print_bench;

/// The stages of a benchmark, one line each on stderr (`name...`), shown whatever stderr is:
/// a benchmark's log says what ran when.
pub(super) struct StageLog;

impl Progress for StageLog {
    fn stage(&self, name: &str, _total: u64) {
        crate::errln!("{name}...");
    }
}

pub fn plan(args: &BenchPlanArgs) -> Result<()> {
    let bench = chronomap_bench::plan::run(
        &PlanConfig {
            edges: args.edges.clone(),
            storm_python: args.storm_python.clone(),
            repeat: args.repeat,
            exact: args.exact,
        },
        &StageLog,
    )?;
    print_bench(args.json, &bench, |b| Ok(out!("{}", b.text())?))
}
