//! Calibration and throughput of the synthetic office.
//!
//! ```text
//! cargo run --release -p chronomap-synth --example office_stats -- [cells] [days] [seed]
//! ```
//!
//! Streams all cells through the first day and times it (frames per second), then through
//! all frames, and prints the class shares among dynamic cells, the static model's error on
//! the cells that changed at least once (overall and per class), and the mean number of
//! change events per frame. Defaults: the paper's office (213,000 cells, 112 days), seed 0.

use std::time::Instant;

use chronomap_synth::{CellClass, OfficeConfig, OfficeWorkload};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize| args.get(i).map(String::as_str);
    let defaults = OfficeConfig::default();
    let config = OfficeConfig {
        cells: arg(0).map_or(Ok(defaults.cells), str::parse)?,
        days: arg(1).map_or(Ok(defaults.days), str::parse)?,
        seed: arg(2).map_or(Ok(defaults.seed), str::parse)?,
        ..defaults
    };
    let started = Instant::now();
    let office = OfficeWorkload::new(config.clone())?;
    let layout_secs = started.elapsed().as_secs_f64();
    // Pure streaming of the first day (at most), as a consumer that XORs frames would.
    let day_frames = office.frames().min((86_400.0 / config.frame_secs) as u64);
    let started = Instant::now();
    let mut stream = office.stream(0..office.cells())?;
    let mut checksum = 0u64;
    let mut day_events = 0usize;
    for _ in 0..day_frames {
        if let Some((_, _, words)) = stream.next_frame() {
            checksum ^= words[0];
        }
        day_events += stream.last_changes().len();
    }
    let day_secs = started.elapsed().as_secs_f64();
    let started = Instant::now();
    let summary = office.summarize(0..office.cells())?;
    let stream_secs = started.elapsed().as_secs_f64();

    println!(
        "office: {} cells, {} days, {} frames, seed {}",
        config.cells,
        config.days,
        office.frames(),
        config.seed
    );
    let dynamic: usize = CellClass::ALL
        .iter()
        .filter(|c| c.is_dynamic())
        .map(|&c| office.class_count(c))
        .sum();
    for class in CellClass::ALL {
        let cells: Vec<usize> = (0..office.cells())
            .filter(|&c| office.cell_class(c) == Some(class))
            .collect();
        let changed: Vec<usize> = cells
            .iter()
            .copied()
            .filter(|&c| summary.changes[c] > 0)
            .collect();
        let error: f64 = changed.iter().map(|&c| summary.static_error(c)).sum();
        let share = if class.is_dynamic() {
            format!(
                "{:5.1} % of dynamic",
                100.0 * cells.len() as f64 / dynamic as f64
            )
        } else {
            "".into()
        };
        println!(
            "{class:?}: {} cells {share}, {} changed, static error on changed {:.2} %, \
             contribution {:.2} points",
            cells.len(),
            changed.len(),
            100.0 * error / changed.len().max(1) as f64,
            100.0 * error / summary.changed_cells().max(1) as f64
        );
    }
    println!(
        "changed at least once: {} cells; static model error on them: {:.3} %",
        summary.changed_cells(),
        100.0 * summary.static_error_on_changed().unwrap_or(0.0)
    );
    println!(
        "change events: {} in all, {:.2} per frame (a frame is {} words)",
        summary.total_changes(),
        summary.changes_per_frame(),
        office.cells().div_ceil(64)
    );
    println!(
        "layout {layout_secs:.3} s; first day: {day_frames} frames, {day_events} events \
         (checksum {checksum:x}) in {day_secs:.3} s: {:.0} frames/s",
        day_frames as f64 / day_secs
    );
    println!(
        "summary: streamed {} frames in {stream_secs:.2} s: {:.0} frames/s, \
         {:.3e} cell observations/s",
        office.frames(),
        office.frames() as f64 / stream_secs,
        office.frames() as f64 * office.cells() as f64 / stream_secs
    );
    Ok(())
}
