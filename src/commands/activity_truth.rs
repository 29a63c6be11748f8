//! `chronomap activity truth`: the ground truth of §4.3.2 (seed 002) from pedestrian tracks —
//! distinct people per cell and time bin, counted over whole bins — in the cells of a
//! training grid, written as an `x1,x2,t,y` grid for `chronomap activity eval --test`.

use std::io::Write;

use anyhow::{Context, Result, bail};
use chronomap_activity::truth::{TruthGrid, person_counts};
use chronomap_io::{read_rate_samples, read_track_point_files, write_rate_samples};

use crate::cli::ActivityTruthArgs;

pub fn truth(args: &ActivityTruthArgs) -> Result<()> {
    let cells_name = args.cells.display().to_string();
    let grid = read_rate_samples(&args.cells).context("cannot read the grid of --cells")?;
    let mut cells: Vec<[f64; 2]> = grid.cells().keys().map(|k| k.centre()).collect();
    cells.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    for c in &cells {
        for v in c {
            let k = v / args.cell - 0.5;
            if (k - k.round()).abs() > 1e-9 {
                bail!(
                    "{cells_name}: cell centre ({}, {}) is not the centre of a {} m cell aligned \
                     to multiples of {} m (--cell)",
                    c[0],
                    c[1],
                    args.cell,
                    args.cell
                );
            }
        }
    }
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
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
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
