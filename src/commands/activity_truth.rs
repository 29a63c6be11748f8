//! `chronomap activity truth`: the ground truth of §4.3.2 ([Stüde 2024]) from pedestrian tracks —
//! distinct people per cell and time bin, counted over whole bins — in the cells of a
//! training grid, written as an `x1,x2,t,y` grid for `chronomap activity eval --test`
//! ([`chronomap_app::activity::truth_job`] counts and reports).

use anyhow::Result;
use chronomap_activity::truth::TruthGrid;
use chronomap_app::activity::truth_job;
use chronomap_io::write_rate_samples;

use crate::cli::ActivityTruthArgs;
use crate::out;
use crate::output::print_json;

pub fn truth(args: &ActivityTruthArgs) -> Result<()> {
    let grid = TruthGrid {
        cell: args.cell,
        t0: args.t0,
        bin: args.bin_seconds,
        t_offset: args.t_offset,
    };
    let report = truth_job(&args.cells, &args.tracks, &args.bins, &grid, &args.output)?;
    write_rate_samples(&args.output, &report.truth)?;
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    Ok(out!("{}", report.text())?)
}
