//! The grid part of `chronomap demo`: a real symbolic map (the Aruba apartment) and the
//! synthetic office, with predicted maps written as Nav2 maps and drawn side by side.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use chronomap_core::TimeSeries;
use chronomap_core::{FremenConfig, Parallelism};
use chronomap_grid::build::{build_from_frames, build_partitioned, occupancy_percent};
use chronomap_grid::report::score_frames;
use chronomap_grid::{GridConfig, GridError, GridGeometry, OrderChoice};
use chronomap_io::navmap::{SaveOptions, save_map};
use chronomap_plot::{MapImage, render_maps_png};
use chronomap_spatial::OccupancyMap;
use chronomap_synth::office_grid::office;

use super::demo::indent;
use crate::bundled;
use crate::format::{Table, time};
use crate::outln;
use crate::output::ProgressBar;

/// Prints section 4 of the demo; writes maps into `out` if given. Returns the files written.
pub fn run(out: Option<&Path>) -> Result<Vec<String>> {
    outln!("\n4. Occupancy grids ([Krajník 2017] §VI, §VIII): one FreMEn model per cell.\n")?;
    let rooms: Vec<TimeSeries> = bundled::ARUBA_ROOMS
        .iter()
        .map(|r| r.pairs())
        .collect::<Result<_>>()?;
    let train = 12 * 7 * 1440;
    let config = GridConfig {
        fremen: FremenConfig::with_order(2),
        keep_history: true,
    };
    let bar = ProgressBar::new();
    let built = build_from_frames(
        GridGeometry::planar(10, 1, 1.0, [0.0, 0.0])?,
        &config,
        train,
        &[train as u64 * 3 / 4],
        &bar,
        |f, grid| -> Result<(), GridError> {
            let frame: Vec<i8> = rooms
                .iter()
                .map(|r| occupancy_percent(r.values[f]))
                .collect();
            grid.observe_occupancy(rooms[0].times[f], &frame)
        },
    )?;
    let grid = built.grid;
    let auto = grid.select_cell_orders(&built.snapshots[0], 5, Parallelism::Rayon(0))?;
    drop(bar);
    let end = rooms[0].len();
    let states: Vec<&[f64]> = rooms.iter().map(|r| r.values.as_slice()).collect();
    let mut table = Table::new(["model", "Brier score", "binary error"]);
    for (name, orders) in [
        ("static map (order 0)", OrderChoice::Fixed(0)),
        ("FreMEn order 2", OrderChoice::Fixed(2)),
        ("FreMEn auto (per room)", OrderChoice::PerCell(auto)),
    ] {
        let fitted = grid.fitted(orders, Parallelism::Rayon(0));
        let scores = score_frames(&fitted, &rooms[0].times, &states, train..end)
            .context("no held-back week to score")?;
        table.row([
            name.to_string(),
            format!("{:.4}", scores.brier),
            format!("{:.1} %", 100.0 * scores.binary_error),
        ]);
    }
    outln!(
        "   a) The CASAS Aruba apartment as a 10-cell symbolic map (data/aruba_rooms_1min): \
         trained on weeks 1-12 by the minute, predicting weeks 13-16:\n"
    )?;
    outln!("{}", indent(&table.render()))?;

    let (cells, days) = (213_000, 14);
    let workload = office(cells, days, 0)?;
    let geometry = workload.geometry()?;
    let started = Instant::now();
    let bar = ProgressBar::new();
    let built = build_partitioned(
        &workload,
        geometry,
        &GridConfig {
            keep_history: true,
            ..GridConfig::default()
        },
        &[],
        Parallelism::Rayon(0),
        &bar,
    )?;
    let seconds = started.elapsed().as_secs_f64();
    let office_grid = built.grid;
    let frames = office_grid.frames();
    let static_error = office_grid.estimation_error(
        &office_grid.fitted(OrderChoice::Fixed(0), Parallelism::Rayon(0)),
        0,
        frames,
        Parallelism::Rayon(0),
    )?;
    let fitted = office_grid.fitted(OrderChoice::Fixed(4), Parallelism::Rayon(0));
    let fremen_error = office_grid.estimation_error(&fitted, 0, frames, Parallelism::Rayon(0))?;
    drop(bar);
    outln!(
        "\n   b) The synthetic office of [Krajník 2017] §VI (chronomap-synth: {cells} cells of 10 cm, a frame every 5 s) \
         for {days} days: {:.2e} cell observations in {:.2} s; over the {} cells that changed, a static map \
         mis-estimates {:.2} % of the states, FreMEn order 4 {:.2} % (the paper: ~6 % and 3-4 %).",
        cells as f64 * frames as f64,
        seconds,
        fremen_error.changed_cells,
        100.0 * static_error.mean_cell_error,
        100.0 * fremen_error.mean_cell_error
    )?;
    let Some(out) = out else {
        return Ok(Vec::new());
    };
    // The day after the data (a Monday: the office starts on a Monday and runs whole weeks),
    // 3:00 and 11:00; one horizontal layer of the 3-D grid.
    let monday = (office_grid.frame_span().last / 86_400.0).floor() * 86_400.0 + 86_400.0;
    let layer = 25usize;
    let (w, h) = (geometry.width as usize, geometry.height as usize);
    let mut written = Vec::new();
    let mut images = Vec::new();
    for hour in [3.0, 11.0] {
        let t = monday + hour * 3600.0;
        let values = fitted.predict_map(t)[layer * w * h..(layer + 1) * w * h].to_vec();
        let map = OccupancyMap::from_probabilities(
            w as u32,
            h as u32,
            geometry.resolution as f32,
            [geometry.origin[0], geometry.origin[1], 0.0],
            &values,
        );
        let saved = save_map(
            &out.join(format!("office_{:02}00", hour as u32)),
            &map,
            &SaveOptions {
                comment: Some(format!(
                    "map predicted by chronomap for t = {t} ({}), layer {layer}",
                    time(t)
                )),
                free_thresh: 0.196,
                ..SaveOptions::default()
            },
        )?;
        written.push(format!("{}  (Nav2 map, {})", saved.yaml.display(), time(t)));
        images.push(MapImage {
            title: format!("office layer {layer} predicted for {}", time(t)),
            width: w as u32,
            height: h as u32,
            values,
        });
    }
    let png = out.join("office_maps.png");
    render_maps_png(&images, &png, 9)?;
    written.push(format!(
        "{}  (the two predicted maps side by side)",
        png.display()
    ));
    Ok(written)
}
