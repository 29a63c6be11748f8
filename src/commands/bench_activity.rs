//! `chronomap bench activity`: the two performance goals of CoPA-Map's activity pipeline
//! ([Stüde 2024] chapter 4) on the bundled ATC data, each timed against a baseline in the same run —
//! [`chronomap_bench::activity`] measures; [`chronomap_app::activity::extraction_setup`] reads
//! the data with `activity extract`'s setup (the bundled patrol robots on the real map over the
//! tracks of 2012-10-24: the whole day, one hour with `--quick`); this prints.

use anyhow::{Context, Result};
use chronomap_app::activity::{atc_tracks, extraction_setup};
use chronomap_bench::activity::{
    ActivityBench, ActivityBenchConfig, COPA_GOAL_SECONDS, ExtractionInput, PRODUCTS_PER_ITERATION,
    TrainingInput, product_flops,
};
use chronomap_io::read_rate_samples;

use super::bench_plan::StageLog;
use crate::cli::BenchActivityArgs;
use crate::format::Table;
use crate::outln;
use crate::output::print_bench;

/// The run's sizes: `--quick` or the full run, overridden by the flags given.
fn config_of(args: &BenchActivityArgs) -> ActivityBenchConfig {
    let mut config = ActivityBenchConfig::new(args.quick);
    if let Some(n) = args.repeats {
        config.repeats = n as usize;
    }
    config.fit_repeats = args.fit_repeats as usize;
    if let Some(n) = args.iterations {
        config.iterations = n as usize;
    }
    if let Some(n) = args.sequential_iterations {
        config.sequential_iterations = n as usize;
    }
    config
}

pub fn activity(args: &BenchActivityArgs) -> Result<()> {
    let config = config_of(args);
    // Extraction: `activity extract`'s setup and defaults over the ATC day (or its quick hour).
    let tracks = atc_tracks(&args.tracks, args.quick)?;
    let setup = extraction_setup(&tracks, &args.map, &args.paths)?;
    let track_files: Vec<String> = tracks.iter().map(|p| p.display().to_string()).collect();
    let extraction = chronomap_bench::activity::extraction(
        &ExtractionInput {
            track_files: &track_files,
            detections: &setup.detections,
            grid: &setup.grid,
            robots: &setup.robots,
            bins: &setup.bins,
            config: &setup.config,
        },
        &config,
        &StageLog,
    )?;
    drop(setup);

    let name = args.train.display().to_string();
    let train = read_rate_samples(&args.train).context("cannot read the training rates")?;
    let copa = chronomap_bench::activity::training(
        &TrainingInput {
            name: &name,
            samples: &train,
        },
        &config,
        &StageLog,
    )?;
    let bench = ActivityBench::new(&config, extraction, copa);
    print_bench(args.json, &bench, print_table)
}

fn print_table(b: &ActivityBench) -> Result<()> {
    let (ex, tr) = (&b.extraction, &b.copa);
    let seconds = ex.seconds;
    let fit = tr.seconds;
    let per_iteration = tr.seconds_per_iteration;
    let bare_fit = tr.bare_gemm_seconds_per_iteration * tr.iterations as f64;
    outln!(
        "extraction (§4.2.2): ATC 2012-10-24, {} detections from {} track files, {} hour bins; \
         robots {} ({} robot steps of 1 s); {} samples over {} cells",
        ex.detections,
        ex.track_files.len(),
        ex.bins.len(),
        ex.robots.join(", "),
        ex.robot_steps,
        ex.samples,
        ex.cells
    )?;
    outln!(
        "  {:.3e} detections/s, {:.3e} robot steps/s; field of view ray cast {} times (once per robot \
         map cell) instead of {} (once per robot step)",
        ex.detections_per_second,
        ex.robot_steps_per_second,
        ex.cached_ray_casts,
        ex.uncached_ray_casts
    )?;
    outln!(
        "CoPA-Map (eqs. 4.12–4.16): {} samples over {} cells, {} inducing points, batch {}, {} \
         iterations, {} threads; setup (scaling, k-means inducing points) {:.2} s of the fit",
        tr.samples,
        tr.cells,
        tr.inducing,
        tr.batch,
        tr.iterations,
        tr.threads,
        tr.setup_seconds
    )?;
    outln!(
        "  bare baseline: the {PRODUCTS_PER_ITERATION} faer products of an iteration ({:.2e} flops), one thread",
        product_flops(tr.inducing, tr.batch)
    )?;
    let mut table = Table::new(["goal", "measured", "baseline (same run)", "ratio"]);
    table.row([
        format!("extraction, median of {}", ex.runs.len()),
        format!("{seconds:.3} s"),
        format!(
            "bare (cell, hour) binning {:.2} ms",
            ex.bare_scan_seconds * 1e3
        ),
        format!("{:.0}", ex.ratio_to_bare_scan),
    ]);
    table.row([
        "extraction with its field-of-view cache".to_string(),
        format!("{seconds:.3} s"),
        format!("ray casts at every step {:.2} s", ex.uncached_seconds),
        format!("{:.3}", seconds / ex.uncached_seconds),
    ]);
    table.row([
        format!(
            "CoPA-Map fit <= {COPA_GOAL_SECONDS:.0} s, median of {}",
            tr.runs.len()
        ),
        format!(
            "{fit:.1} s ({})",
            if tr.goal_met { "met" } else { "missed" }
        ),
        format!("{} x bare products {bare_fit:.2} s", tr.iterations),
        format!("{:.2}", fit / bare_fit),
    ]);
    for (bare, seconds, ratio) in [
        (
            "bare products",
            tr.bare_gemm_seconds_per_iteration,
            tr.ratio_iteration_to_bare_gemm,
        ),
        (
            "+ solves, Cholesky",
            tr.bare_dense_seconds_per_iteration,
            tr.ratio_iteration_to_bare_dense,
        ),
    ] {
        table.row([
            "  one iteration".to_string(),
            format!("{:.1} ms", per_iteration * 1e3),
            format!("{bare} {:.1} ms", seconds * 1e3),
            format!("{ratio:.2}"),
        ]);
    }
    if let Some(s) = &tr.sequential {
        table.row([
            format!(
                "  one thread vs {} ({} iterations)",
                tr.threads, s.iterations
            ),
            format!("{:.1} ms", s.one_thread_seconds_per_iteration * 1e3),
            format!("{:.1} ms", s.all_threads_seconds_per_iteration * 1e3),
            format!("{:.2}", s.speedup),
        ]);
    }
    outln!("{}", table.render())?;
    Ok(())
}
