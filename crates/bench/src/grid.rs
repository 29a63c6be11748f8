//! `chronomap bench grid`: the paper-scale 4-D office grid of [Krajník 2017] §VI (213,000 cells, a
//! frame every 5 s for 112 days: 4·10¹¹ cell observations) streamed from the synthetic
//! generator into FreMEn grids, timed against a bare scan of the same frames in the same run.
//!
//! ```
//! use chronomap_bench::grid::{GridBenchConfig, bench_grid};
//! use chronomap_core::Parallelism;
//! use chronomap_core::progress::NoProgress;
//!
//! let config = GridBenchConfig { cells: 640, days: 1, seed: 0 };
//! let result = bench_grid(&config, Parallelism::Rayon(2), &NoProgress)?;
//! assert_eq!(result.frames, 17_280);
//! assert_eq!(result.cell_observations, 640 * 17_280);
//! assert!(result.changed_bits > 0 && result.changing_cells > 0);
//! assert!(result.text().starts_with("synthetic office: 640 cells x 17280 frames (1 days at 5 s)"));
//! # Ok::<(), chronomap_bench::BenchError>(())
//! ```

use std::time::Instant;

use chronomap_core::Parallelism;
use chronomap_core::progress::Progress;
use chronomap_grid::GridConfig;
use chronomap_grid::build::{bare_scan, build_partitioned};
use chronomap_synth::office_grid::office;
use serde::Serialize;

use crate::BenchError;

/// The workload of the grid benchmark.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GridBenchConfig {
    /// Number of cells (the paper: 213,000).
    pub cells: usize,
    /// Days of 5-second frames (the paper: 112).
    pub days: u32,
    /// Seed of the synthetic office.
    pub seed: u64,
}

impl Default for GridBenchConfig {
    fn default() -> Self {
        GridBenchConfig {
            cells: 213_000,
            days: 112,
            seed: 0,
        }
    }
}

/// What the grid benchmark measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GridBench {
    /// Cells × frames.
    pub cell_observations: u64,
    /// Seconds to build the FreMEn grid.
    pub seconds: f64,
    /// Seconds of the bare scan of the same frames.
    pub bare_scan_seconds: f64,
    /// Peak resident memory of the process (MB), if the system tells.
    pub peak_rss_mb: Option<f64>,
    /// `seconds / bare_scan_seconds`.
    pub ratio_to_bare_scan: f64,
    /// Number of cells.
    pub cells: usize,
    /// Number of frames.
    pub frames: u64,
    /// Days of frames.
    pub days: u32,
    /// Tasks the cells were split into (threads).
    pub threads: usize,
    /// Bits that changed from one frame to the next (the bare scan's count).
    pub changed_bits: u64,
    /// Cells that changed or needed storage in the grid.
    pub changing_cells: usize,
    /// Memory of the grid (MB).
    pub grid_memory_mb: f64,
    /// Candidate periods of every cell's model.
    pub periods: usize,
}

impl GridBench {
    /// The result as `chronomap bench grid` prints it, beside the figure of [Krajník 2017] §VI.
    pub fn text(&self) -> String {
        format!(
            "synthetic office: {} cells x {} frames ({} days at 5 s) = {:.3e} cell observations, {} changes, {} threads\n\
             bare scan (stream frames, XOR with the previous one, popcount): {:.2} s\n\
             FreMEn grid ({} periods per cell, exact):                      {:.2} s = {:.2} x the bare scan, {:.3e} cell observations/s\n\
             cells with storage: {}; grid memory {:.1} MB; peak RSS {}\n\
             ([Krajník 2017] §VI: 4e11 cell observations in < 1 h on an i7-4500U)",
            self.cells,
            self.frames,
            self.days,
            self.cell_observations as f64,
            self.changed_bits,
            self.threads,
            self.bare_scan_seconds,
            self.periods,
            self.seconds,
            self.ratio_to_bare_scan,
            self.cell_observations as f64 / self.seconds,
            self.changing_cells,
            self.grid_memory_mb,
            self.peak_rss_mb
                .map_or("unknown".into(), |p| format!("{p:.0} MB"))
        )
    }
}

/// Runs the bare scan, then builds the grid (the default [`GridConfig`]: one week of
/// candidate periods, exact sums), both split into the tasks of `parallelism`; reports both
/// stages to `progress`.
///
/// # Errors
/// A configuration the office generator refuses.
pub fn bench_grid(
    config: &GridBenchConfig,
    parallelism: Parallelism,
    progress: &dyn Progress,
) -> Result<GridBench, BenchError> {
    let workload = office(config.cells, config.days, config.seed)?;
    let geometry = workload.geometry()?;
    let frames = workload.frames();
    let clock = Instant::now();
    let changed_bits = bare_scan(&workload, parallelism, progress)?;
    let bare_scan_seconds = clock.elapsed().as_secs_f64();
    let clock = Instant::now();
    let built = build_partitioned(
        &workload,
        geometry,
        &GridConfig::default(),
        &[],
        parallelism,
        progress,
    )?;
    let seconds = clock.elapsed().as_secs_f64();
    let grid = built.grid;
    Ok(GridBench {
        cell_observations: config.cells as u64 * frames,
        seconds,
        bare_scan_seconds,
        peak_rss_mb: peak_rss_mb(),
        ratio_to_bare_scan: seconds / bare_scan_seconds,
        cells: config.cells,
        frames,
        days: config.days,
        threads: parallelism.tasks(),
        changed_bits,
        changing_cells: grid.dynamic_cells(),
        grid_memory_mb: grid.memory_bytes() as f64 / 1_048_576.0,
        periods: grid.config().fremen.periods.len(),
    })
}

/// Peak resident memory of this process in MB (Linux `VmHWM` of `/proc/self/status`), if
/// known.
pub fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}
