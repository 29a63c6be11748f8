//! FreMEn against the static model on the synthetic office ([Krajník 2017] §VI, Fig. 8).
//!
//! ```text
//! cargo run --release -p chronomap-synth --example office_fremen -- [cells] [days] [seed]
//! ```
//!
//! Streams a grid (default 6,400 cells, 112 days, seed 0), builds an FFT FreMEn model of each
//! cell that changed at least once from all its frames, and prints the estimation error (the
//! fraction of frames the thresholded model gets wrong, averaged over those cells) for
//! orders 0 (the static model) to 5, overall and per class. The paper reports ~6 % for the
//! static model and 3–4 % for FreMEn of orders 1–5.

use chronomap_core::fft::{FftFremen, FftFremenConfig, expand_edges};
use chronomap_synth::{CellClass, OfficeConfig, OfficeWorkload};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize| args.get(i).map(String::as_str);
    let defaults = OfficeConfig::default();
    let config = OfficeConfig {
        cells: arg(0).map_or(Ok(6_400), str::parse)?,
        days: arg(1).map_or(Ok(defaults.days), str::parse)?,
        seed: arg(2).map_or(Ok(defaults.seed), str::parse)?,
        ..defaults
    };
    let office = OfficeWorkload::new(config.clone())?;
    let frames = office.frames();

    // Change positions of every cell (a cell occupied at frame 0 starts with an edge at 0).
    let mut edges: Vec<Vec<u64>> = vec![Vec::new(); office.cells()];
    let mut stream = office.stream(0..office.cells())?;
    while let Some((frame, _, _)) = stream.next_frame() {
        for &cell in stream.last_changes() {
            edges[cell as usize].push(frame);
        }
    }

    const ORDERS: usize = 6;
    let classes = [CellClass::Periodic, CellClass::Noise, CellClass::Persistent];
    let mut sums = [[0.0; ORDERS]; 3];
    let mut counts = [0usize; 3];
    for (cell, cell_edges) in edges.iter().enumerate() {
        let changes = cell_edges.iter().filter(|&&f| f > 0).count();
        if changes == 0 {
            continue;
        }
        let class = office.cell_class(cell).ok_or("no class")?;
        let c = classes
            .iter()
            .position(|&k| k == class)
            .ok_or("static cell changed")?;
        counts[c] += 1;
        let samples = expand_edges(cell_edges, frames);
        let mut model = FftFremen::build(
            office.frame_time(0),
            config.frame_secs,
            &samples,
            FftFremenConfig::with_order(0),
        )?;
        for (order, sum) in sums[c].iter_mut().enumerate() {
            if order > 0 {
                model.update_with_order(order);
            }
            *sum += model.estimation_error();
        }
    }
    let changed: usize = counts.iter().sum();
    println!(
        "office: {} cells, {} days, seed {}; {changed} cells changed at least once",
        config.cells, config.days, config.seed
    );
    for order in 0..ORDERS {
        let total: f64 = sums.iter().map(|s| s[order]).sum();
        let per_class: Vec<String> = classes
            .iter()
            .zip(&sums)
            .zip(&counts)
            .map(|((k, s), &n)| format!("{k:?} {:.2} %", 100.0 * s[order] / n.max(1) as f64))
            .collect();
        println!(
            "order {order}{}: {:.3} % of frames mis-estimated ({})",
            if order == 0 { " (static)" } else { "" },
            100.0 * total / changed.max(1) as f64,
            per_class.join(", ")
        );
    }
    Ok(())
}
