//! `chronomap bench grid`: the paper-scale 4-D grid workload of [Krajník 2017] §VI, timed against a
//! bare scan of the same frames in the same run (`chronomap_bench::grid`).

use anyhow::Result;
use chronomap_bench::grid::{GridBench, GridBenchConfig, bench_grid};
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
    print_text(&result)?;
    Ok(())
}

fn print_text(r: &GridBench) -> std::io::Result<()> {
    outln!(
        "synthetic office: {} cells x {} frames ({} days at 5 s) = {:.3e} cell observations, {} changes, {} threads",
        r.cells,
        r.frames,
        r.days,
        r.cell_observations as f64,
        r.changed_bits,
        r.threads
    )?;
    outln!(
        "bare scan (stream frames, XOR with the previous one, popcount): {:.2} s",
        r.bare_scan_seconds
    )?;
    outln!(
        "FreMEn grid ({} periods per cell, exact):                      {:.2} s = {:.2} x the bare scan, {:.3e} cell observations/s",
        r.periods,
        r.seconds,
        r.ratio_to_bare_scan,
        r.cell_observations as f64 / r.seconds
    )?;
    outln!(
        "cells with storage: {}; grid memory {:.1} MB; peak RSS {}",
        r.changing_cells,
        r.grid_memory_mb,
        r.peak_rss_mb
            .map_or("unknown".into(), |p| format!("{p:.0} MB"))
    )?;
    outln!("([Krajník 2017] §VI: 4e11 cell observations in < 1 h on an i7-4500U)")
}
