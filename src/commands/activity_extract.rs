//! `chronomap activity extract`: CoPA-Map's training data from pedestrian detections as
//! simulated patrol robots see them (§4.2.2, eqs. 4.5–4.6 of dissertation chapter 4), or the
//! ground truth of §4.3.2.

use std::time::Instant;

use anyhow::{Context, Result, bail};
use chronomap_activity::extract::{ExtractConfig, Extraction, RobotPath};
use chronomap_app::activity::{SampleSource, extract_samples};
use chronomap_core::num::{count_of, fmt_number};
use chronomap_core::progress::NoProgress;
use chronomap_hypertime::events::Event;
use chronomap_io::{read_rate_samples, read_track_files, write_rate_grid};
use serde_json::json;

use crate::cli::ActivityExtractArgs;
use crate::outln;
use crate::output::{print_json, usage};

/// The setup of `activity extract` and `bench activity`.
pub(super) use chronomap_app::activity::robots_on_map;

/// The most time bins `activity extract` counts from t0 over the detections (2^24).
const MAX_BINS: usize = 1 << 24;

pub fn run(args: &ActivityExtractArgs) -> Result<()> {
    let started = Instant::now();
    let detections = read_track_files(&args.tracks).context("cannot read the tracks")?;
    let Some(first) = detections.first().map(|d| d.t) else {
        bail!("the track files have no detection");
    };
    crate::errln!(
        "read {} detections from {} files in {:.1} s",
        detections.len(),
        args.tracks.len(),
        started.elapsed().as_secs_f64()
    );
    let t0 = args.t0.unwrap_or((first / args.bin).floor() * args.bin);
    // Bin indices are counted from t0 over the detections: refuse a --bin (or --t0) that gives
    // more than MAX_BINS of them instead of letting `as i64` saturate them into one.
    let last = detections.iter().map(|d| d.t).fold(first, f64::max);
    let span = (last.max(t0) - first.min(t0)) / args.bin;
    if !t0.is_finite() || count_of(span.floor(), MAX_BINS).is_none() {
        return Err(usage(format!(
            "--bin {}: gives {} bins from t0 {} over the detections; at most {MAX_BINS}",
            fmt_number(args.bin),
            fmt_number(span.floor()),
            fmt_number(t0)
        )));
    }
    let config = ExtractConfig {
        fov_radius: args.fov,
        cell_size: args.cell,
        bin_seconds: args.bin,
        step_seconds: args.step,
        t0,
    };
    // By default every bin with a detection: a bin without any (an hour missing from the
    // data) would read as "nobody there".
    let bins: Vec<i64> = if args.bins.is_empty() {
        detection_bins(&detections, t0, args.bin)
    } else {
        args.bins.clone()
    };

    let simulate = Instant::now();
    let (extraction, robots) = match (&args.cells_from, args.ground_truth) {
        (Some(cells_file), true) => {
            let cells: Vec<[f64; 2]> = read_rate_samples(cells_file)
                .context("cannot read the cells of --cells-from")?
                .x()
                .to_vec();
            let source = SampleSource::TruthIn(&cells);
            let truth = extract_samples(&detections, source, &bins, &config, &NoProgress)?;
            (truth, Vec::new())
        }
        _ => {
            let (Some(map_file), Some(paths_file)) = (&args.map, &args.paths) else {
                return Err(usage(
                    "give --map and --paths (or --ground-truth with --cells-from)",
                ));
            };
            let (grid, robots) = robots_on_map(
                map_file,
                paths_file,
                args.speed,
                args.min_occupancy,
                &args.robots,
            )?;
            let paths: Vec<RobotPath> = robots.iter().map(|(_, p)| p.clone()).collect();
            let source = SampleSource::Robots {
                grid: &grid,
                paths: &paths,
                truth: args.ground_truth,
            };
            let progress = crate::output::ProgressBar::new();
            let samples = extract_samples(&detections, source, &bins, &config, &progress)?;
            (samples, robots)
        }
    };
    let seconds = simulate.elapsed().as_secs_f64();
    if extraction.is_empty() {
        bail!("no cell was observed in bins {bins:?}: nothing to write");
    }
    write_rate_grid(&args.output, &extraction, args.zero_rate).context("cannot write the rates")?;
    report(args, &extraction, &robots, &bins, t0, seconds)
}

/// Every time bin (of `bin` seconds from `t0`) with a detection
/// ([`chronomap_activity::grids::detection_bins`]).
pub(super) fn detection_bins(detections: &[Event], t0: f64, bin: f64) -> Vec<i64> {
    chronomap_activity::grids::detection_bins(detections, t0, bin)
}

fn report(
    args: &ActivityExtractArgs,
    extraction: &Extraction,
    robots: &[(String, RobotPath)],
    bins: &[i64],
    t0: f64,
    seconds: f64,
) -> Result<()> {
    let cells = extraction.cells().len();
    let samples = extraction.len();
    let count = extraction.total_count();
    let duration = extraction.total_duration();
    let mean_rate = extraction.to_rate_samples().mean_rate();
    let pooled_rate = count as f64 * 3600.0 / duration;
    let kind = if args.ground_truth {
        "ground truth"
    } else {
        "training data"
    };
    if args.json {
        let robots: Vec<_> = robots
            .iter()
            .map(|(name, p)| {
                json!({"name": name, "length_m": p.length(), "loop_s": p.period(), "waypoints": p.waypoints().len()})
            })
            .collect();
        return print_json(&json!({
            "kind": kind,
            "output": args.output.display().to_string(),
            "samples": samples,
            "cells": cells,
            "bins": bins,
            "t0": t0,
            "total_count": count,
            "total_duration_s": duration,
            "mean_rate_per_hour": mean_rate,
            "pooled_rate_per_hour": pooled_rate,
            "robots": robots,
            "seconds": seconds,
        }));
    }
    for (name, p) in robots {
        outln!(
            "robot {name}: {} waypoints, loop {:.1} m, {:.0} s at {} m/s",
            p.waypoints().len(),
            p.length(),
            p.period(),
            p.speed()
        )?;
    }
    outln!(
        "{kind}: {samples} samples over {cells} cells and {} bins (t0 = {t0}, {} s each), \
         written to {}",
        bins.len(),
        args.bin,
        args.output.display()
    )?;
    outln!(
        "{count} detections in {:.1} h of cell observation: mean rate {mean_rate:.2} per hour \
         (pooled {pooled_rate:.2}); computed in {seconds:.2} s",
        duration / 3600.0
    )?;
    Ok(())
}
