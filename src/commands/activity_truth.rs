//! `chronomap activity truth`: the ground truth of §4.3.2 ([Stüde 2024]) from pedestrian tracks —
//! distinct people per cell and time bin, counted over whole bins — in the cells of a
//! training grid, written as an `x1,x2,t,y` grid for `chronomap activity eval --test`.

use anyhow::{Context, Result, anyhow};
use chronomap_activity::grids::{check_aligned, distinct_cells};
use chronomap_activity::truth::{TruthGrid, person_counts};
use chronomap_io::{read_rate_samples, read_track_point_files, write_rate_samples};
use serde_json::json;

use crate::cli::ActivityTruthArgs;
use crate::outln;
use crate::output::print_json;

pub fn truth(args: &ActivityTruthArgs) -> Result<()> {
    let cells_name = args.cells.display().to_string();
    let grid = read_rate_samples(&args.cells).context("cannot read the grid of --cells")?;
    let cells = distinct_cells(&grid);
    check_aligned(&cells, args.cell).map_err(|e| anyhow!("{cells_name}: {e} (--cell)"))?;
    let points = read_track_point_files(&args.tracks).context("cannot read the tracks")?;
    let truth = person_counts(
        &points,
        &cells,
        &args.bins,
        &TruthGrid {
            cell: args.cell,
            t0: args.t0,
            bin: args.bin_seconds,
            t_offset: args.t_offset,
        },
    )?;
    write_rate_samples(&args.output, &truth)?;
    if args.json {
        return print_json(&json!({
            "output": args.output.display().to_string(),
            "samples": truth.len(),
            "cells": cells.len(),
            "bins": args.bins,
            "detections": points.len(),
            "mean_rate_per_hour": truth.mean_rate(),
        }));
    }
    outln!(
        "{}: {} samples ({} cells × {} bins) from {} detections; mean {:.3} people per hour",
        args.output.display(),
        truth.len(),
        cells.len(),
        args.bins.len(),
        points.len(),
        truth.mean_rate()
    )?;
    Ok(())
}
