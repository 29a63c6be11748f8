//! The grid part of `chronomap demo`: a real symbolic map (the Aruba apartment) and the
//! synthetic office, with predicted maps written as Nav2 maps and drawn side by side.

use std::path::Path;

use anyhow::Result;
use chronomap_core::FremenConfig;
use chronomap_grid::{FremenGrid, GridConfig, GridGeometry, OrderChoice};
use chronomap_io::TimeSeries;
use chronomap_io::navmap::{OccupancyMap, SaveOptions, save_map};
use chronomap_plot::{MapImage, render_maps_png};

use super::synthetic::{build, office, office_geometry, partition};
use crate::bundled;
use crate::format::{Table, time};

/// Brier score and binary error of a grid's predictions over frames `[from, to)` of the rooms.
fn room_scores(
    grid: &FremenGrid,
    orders: OrderChoice,
    rooms: &[TimeSeries],
    from: usize,
    to: usize,
) -> (f64, f64) {
    let fitted = grid.fitted(orders);
    let (mut brier, mut binary, mut n) = (0.0, 0.0, 0.0);
    for f in from..to {
        for (room, &p) in rooms.iter().zip(&fitted.predict(rooms[0].times[f])) {
            let (s, p) = (room.values[f], f64::from(p));
            brier += (p - s) * (p - s);
            binary += f64::from(u8::from((p > 0.5) != (s == 1.0)));
            n += 1.0;
        }
    }
    (brier / n, binary / n)
}

/// Prints section 4 of the demo; writes maps into `out` if given. Returns the files written.
pub fn run(out: Option<&Path>) -> Result<Vec<String>> {
    println!("\n4. Occupancy grids (seed 001 §VI, §VIII): one FreMEn model per cell.\n");
    let rooms: Vec<TimeSeries> = bundled::ARUBA_ROOMS
        .iter()
        .map(|r| r.pairs())
        .collect::<Result<_>>()?;
    let train = 12 * 7 * 1440;
    let config = GridConfig {
        fremen: FremenConfig::with_order(2),
        keep_history: true,
    };
    let mut grid = FremenGrid::new(GridGeometry::planar(10, 1, 1.0, [0.0, 0.0])?, config)?;
    let mut trained = None;
    for f in 0..train {
        if f == train * 3 / 4 {
            trained = Some(grid.clone());
        }
        let frame: Vec<i8> = rooms
            .iter()
            .map(|r| (100.0 * r.values[f]).round() as i8)
            .collect();
        grid.observe_occupancy(rooms[0].times[f], &frame)?;
    }
    let auto = grid.select_cell_orders(&trained.expect("taken"), 5)?;
    let end = rooms[0].len();
    let mut table = Table::new(["model", "Brier score", "binary error"]);
    for (name, orders) in [
        ("static map (order 0)", OrderChoice::Fixed(0)),
        ("FreMEn order 2", OrderChoice::Fixed(2)),
        ("FreMEn auto (per room)", OrderChoice::PerCell(auto)),
    ] {
        let (brier, binary) = room_scores(&grid, orders, &rooms, train, end);
        table.row([
            name.to_string(),
            format!("{brier:.4}"),
            format!("{:.1} %", 100.0 * binary),
        ]);
    }
    println!(
        "   a) The CASAS Aruba apartment as a 10-cell symbolic map (data/aruba_rooms_1min): \
         trained on weeks 1-12 by the minute, predicting weeks 13-16:\n"
    );
    println!("{}", indent(&table.render()));

    let (cells, days) = (213_000, 14);
    let workload = office(cells, days, 0)?;
    let geometry = office_geometry(cells)?;
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let counter = std::sync::atomic::AtomicU64::new(0);
    let built = build(
        &workload,
        geometry,
        &GridConfig {
            keep_history: true,
            ..GridConfig::default()
        },
        threads.min(partition(cells, threads).len()),
        &[],
        &counter,
    )?;
    let office_grid = built.grid;
    let frames = office_grid.frames();
    let static_error =
        office_grid.estimation_error(&office_grid.fitted(OrderChoice::Fixed(0)), 0, frames)?;
    let fitted = office_grid.fitted(OrderChoice::Fixed(4));
    let fremen_error = office_grid.estimation_error(&fitted, 0, frames)?;
    println!(
        "\n   b) The synthetic office of seed 001 §VI (chronomap-synth: {cells} cells of 10 cm, a frame every 5 s) \
         for {days} days: {:.2e} cell observations in {:.2} s; over the {} cells that changed, a static map \
         mis-estimates {:.2} % of the states, FreMEn order 4 {:.2} % (the paper: ~6 % and 3-4 %).",
        cells as f64 * frames as f64,
        built.seconds,
        fremen_error.changed_cells,
        100.0 * static_error.mean_cell_error,
        100.0 * fremen_error.mean_cell_error
    );
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
        let values = fitted.predict(t)[layer * w * h..(layer + 1) * w * h].to_vec();
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

fn indent(text: &str) -> String {
    text.lines()
        .map(|l| format!("   {l}"))
        .collect::<Vec<_>>()
        .join("\n")
}
