//! `chronomap bench grid`: the paper-scale 4-D grid workload of [Krajník 2017] §VI, timed against a
//! bare scan of the same frames in the same run (`chronomap_bench::grid`).

use anyhow::Result;
use chronomap_bench::grid::{GridBenchConfig, bench_grid};
use chronomap_core::Parallelism;

use crate::cli::BenchGridArgs;
use crate::outln;
use crate::output::{ProgressBar, print_json};

pub fn grid(args: &BenchGridArgs) -> Result<()> {
    let config = GridBenchConfig {
        cells: args.cells,
        days: args.days,
        seed: args.seed,
    };
    let run = || {
        let bar = ProgressBar::new();
        bench_grid(&config, Parallelism::Rayon(0), &bar)
    };
    let result = match args.threads {
        None => run()?,
        Some(threads) => rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .build()?
            .install(run)?,
    };
    if args.json {
        return print_json(&result);
    }
    Ok(outln!("{}", result.text())?)
}
