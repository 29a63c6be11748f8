//! `chronomap activity extract`: CoPA-Map's training data from pedestrian detections as
//! simulated patrol robots see them (§4.2.2, eqs. 4.5–4.6 of [Stüde 2024] chapter 4), or the
//! ground truth of §4.3.2 ([`chronomap_app::activity::extract_job`] extracts and reports).

use std::time::Instant;

use anyhow::{Context, Result};
use chronomap_app::activity::{
    ActivityJobError, ExtractRequest, ExtractWhere, extract_job, read_detections,
};
use chronomap_io::write_rate_grid;

use crate::cli::ActivityExtractArgs;
use crate::out;
use crate::output::{ProgressBar, print_json, usage};

pub fn run(args: &ActivityExtractArgs) -> Result<()> {
    let started = Instant::now();
    let detections = read_detections(&args.tracks)?;
    crate::errln!(
        "read {} detections from {} files in {:.1} s",
        detections.len(),
        args.tracks.len(),
        started.elapsed().as_secs_f64()
    );
    let source = match (&args.cells_from, args.ground_truth, &args.map, &args.paths) {
        (Some(cells), true, _, _) => ExtractWhere::TruthInCellsOf(cells),
        (_, _, Some(map), Some(paths)) => ExtractWhere::Robots {
            map,
            paths,
            speed: args.speed,
            min_occupancy: args.min_occupancy,
            robots: &args.robots,
            truth: args.ground_truth,
        },
        _ => {
            return Err(usage(
                "give --map and --paths (or --ground-truth with --cells-from)",
            ));
        }
    };
    let request = ExtractRequest {
        fov: args.fov,
        cell: args.cell,
        bin: args.bin,
        step: args.step,
        t0: args.t0,
        bins: &args.bins,
        source,
    };
    let report = extract_job(&detections, &request, &args.output, &ProgressBar::new()).map_err(
        |e| match e {
            ActivityJobError::TooManyBins { .. } => usage(e.to_string()),
            e => e.into(),
        },
    )?;
    write_rate_grid(&args.output, &report.extraction, args.zero_rate)
        .context("cannot write the rates")?;
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    Ok(out!("{}", report.text())?)
}
