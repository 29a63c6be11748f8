//! `chronomap bench grid-memory`: memory and grid-file bytes per changing cell of FreMEn grids
//! against the representation of grid-state format 1 in the same run
//! ([`chronomap_bench::grid_memory`] measures and writes the text, this prints).

use anyhow::Result;
use chronomap_bench::grid_memory::{GridMemoryConfig, bench_grid_memory};

use crate::cli::BenchGridMemoryArgs;
use crate::outln;
use crate::output::{ProgressBar, print_bench};

pub fn grid_memory(args: &BenchGridMemoryArgs) -> Result<()> {
    let config = GridMemoryConfig {
        cells: args.cells.iter().map(|&c| c as usize).collect(),
        frames: args.frames,
        periods: args.periods.clone(),
        order: args.order,
    };
    let result = {
        let bar = ProgressBar::new();
        bench_grid_memory(&config, &bar)?
    };
    print_bench(args.json, &result, |r| Ok(outln!("{}", r.text())?))
}
