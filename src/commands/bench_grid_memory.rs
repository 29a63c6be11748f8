//! `chronomap bench grid-memory`: memory and grid-file bytes per changing cell of FreMEn grids
//! against the representation of grid-state format 1 in the same run
//! ([`chronomap_bench::grid_memory`] measures, this prints).

use anyhow::Result;
use chronomap_bench::grid_memory::{GridMemoryBench, GridMemoryConfig, bench_grid_memory};

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
    print_bench(args.json, &result, print)
}

fn print(r: &GridMemoryBench) -> Result<()> {
    outln!(
        "FreMEn grids whose every cell changes: {} periods ({}), {} frames; baseline: grid-state \
         format 1 (checked on {} cells: same sums read back)",
        r.period_count,
        r.periods,
        r.frames,
        r.checked_cells
    )?;
    outln!(
        "{:>9} {:>11} | {:>27} {:>8} | {:>27} | {:>7} {:>5} {:>4}",
        "cells",
        "shape",
        "bytes/cell: format 1  now",
        "RSS now",
        "file bytes/cell: fmt 1  now",
        "blocks",
        "snaps",
        "bits"
    )?;
    for row in &r.rows {
        outln!(
            "{:>9} {:>11} | {:>13.0} {:>5.0} {:>6.1}x {:>8} | {:>13.0} {:>5.0} {:>6.1}x | {:>7} {:>5} {:>4}",
            row.cells,
            format!("{}x{}", row.shape[0], row.shape[1]),
            row.baseline_bytes_per_cell,
            row.bytes_per_cell,
            row.memory_ratio,
            row.rss_bytes_per_cell
                .map_or("-".into(), |b| format!("{b:.0}")),
            row.baseline_file_bytes_per_cell,
            row.file_bytes_per_cell,
            row.file_ratio,
            row.storage.owned_accumulators + row.storage.snapshots,
            row.storage.snapshots,
            row.storage.sum_bits
        )?;
    }
    outln!(
        "blocks: blocks of exact sums in use (owned by cells, or snapshots: frame prefixes \
         shared by the cells that changed in that frame); bits: of the stored sums"
    )?;
    if let Some(last) = r.rows.last() {
        let e = &last.estimate;
        outln!(
            "estimate per changing cell (FremenGrid::memory_estimate): {} bytes while it changed at \
             most twice per state, {} with blocks of 64-bit sums, {} of 128-bit sums (the most); \
             {} cells: {:.1} MB fixed, {:.2} GB at most",
            e.cell_bytes_inline,
            e.cell_bytes_narrow,
            e.cell_bytes_wide,
            e.cells,
            e.fixed_bytes as f64 / 1e6,
            e.worst_case_bytes as f64 / 1e9
        )?;
    }
    Ok(())
}
