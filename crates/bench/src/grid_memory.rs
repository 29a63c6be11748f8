//! `chronomap bench grid-memory`: the memory a [`FremenGrid`] holds per changing cell, and the
//! size of its grid file per changing cell, against the grid's cell count, for a map whose
//! every cell changes, compared in the same run with the representation of grid-state format 1
//! ([`legacy`], the baseline).
//!
//! The frames are those of a map that grows and changes everywhere (as the 2000 × 2000 map of
//! a ROS 2 user did): in frame 0 every fourth cell is unknown and the others alternate occupied
//! and free; from frame 1 on every cell flips, so every cell of the grid changes in every frame.
//! The new grid is measured by [`FremenGrid::heap_bytes`] (capacities), by the growth of the
//! process's resident memory while it is built, and by its grid file (format 2). The baseline is
//! built the same way, part by part (65,536 cells at a time, as the partitioned build of
//! format 1 did, so that millions of its 2–5 KB cells need not be held at once), measured as
//! format 1 measured itself (its arrays by length: what is resident) and by the exact size of
//! its format-1 file. A 4096-cell grid of the same frames is checked first: its baseline, written
//! as a format-1 file and read back by `chronomap_io`, must hold every cell's sums exactly as the
//! new grid does, and the computed file size must be the real one.
//!
//! ```
//! use chronomap_bench::grid_memory::{GridMemoryConfig, bench_grid_memory};
//! use chronomap_core::progress::NoProgress;
//!
//! let config = GridMemoryConfig { cells: vec![10_000], ..GridMemoryConfig::default() };
//! let result = bench_grid_memory(&config, &NoProgress)?;
//! let row = &result.rows[0];
//! assert_eq!((row.cells, row.changing_cells), (10_000, 10_000));
//! assert!(row.memory_ratio > 10.0 && row.file_ratio > 10.0);
//! # Ok::<(), chronomap_bench::BenchError>(())
//! ```
//!
//! [`FremenGrid`]: chronomap_grid::FremenGrid
//! [`FremenGrid::heap_bytes`]: chronomap_grid::FremenGrid::heap_bytes

pub mod legacy;

use chronomap_core::FremenConfig;
use chronomap_core::periods::PeriodSet;
use chronomap_core::progress::Progress;
use chronomap_grid::AnyGrid;
use chronomap_grid::{FremenGrid, GridConfig, GridGeometry, GridStorage, MemoryEstimate};
use chronomap_io::grid_file::{decode_grid, encode_grid_state};
use chronomap_io::model_file::encode_model;
use serde::Serialize;

use crate::BenchError;
use legacy::{Format1File, LegacyGrid, row_len, slot_len, varint_len};

/// Cells of a part of the baseline (a multiple of 64).
const PART: usize = 1 << 16;

/// Cells of the grid on which the baseline is checked against the new grid.
const CHECKED_CELLS: usize = 4096;

/// The workload of the memory benchmark.
#[derive(Clone, Debug, PartialEq)]
pub struct GridMemoryConfig {
    /// Cell counts of the grids (each a rectangle as close to a square as the count allows).
    pub cells: Vec<usize>,
    /// Frames (every cell changes in every frame after the first).
    pub frames: u32,
    /// Candidate periods of every cell's model.
    pub periods: PeriodSet,
    /// Order of the models (stored in the grid's configuration; it does not change memory).
    pub order: usize,
}

impl Default for GridMemoryConfig {
    /// 10⁴, 10⁵, 10⁶ and 4·10⁶ cells, three frames, one week of periods, order 2: the ROS 2
    /// node's defaults and the frames after which the 2000 × 2000 map held 7.4 GB.
    fn default() -> Self {
        GridMemoryConfig {
            cells: vec![10_000, 100_000, 1_000_000, 4_000_000],
            frames: 3,
            periods: PeriodSet::week_harmonics(),
            order: 2,
        }
    }
}

/// One grid size.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GridMemoryRow {
    /// Cells of the grid.
    pub cells: usize,
    /// Its width and height.
    pub shape: [u32; 2],
    /// Cells with storage (all of them: every cell changes).
    pub changing_cells: usize,
    /// Heap bytes of the grid ([`FremenGrid::heap_bytes`]).
    pub heap_bytes: u64,
    /// `heap_bytes / changing_cells`.
    pub bytes_per_cell: f64,
    /// Growth of the process's resident memory while the grid was built, per changing cell
    /// (Linux), if known.
    pub rss_bytes_per_cell: Option<f64>,
    /// Bytes of the baseline (format 1, arrays by length) per changing cell.
    pub baseline_bytes_per_cell: f64,
    /// `baseline_bytes_per_cell / bytes_per_cell`.
    pub memory_ratio: f64,
    /// Bytes of the grid file (format 2) per changing cell.
    pub file_bytes_per_cell: f64,
    /// Bytes of the baseline's grid file (format 1) per changing cell.
    pub baseline_file_bytes_per_cell: f64,
    /// `baseline_file_bytes_per_cell / file_bytes_per_cell`.
    pub file_ratio: f64,
    /// How the grid holds its cells.
    pub storage: GridStorage,
    /// [`FremenGrid::memory_estimate`] of the geometry and configuration: `heap_bytes` never
    /// exceeds its worst case.
    pub estimate: MemoryEstimate,
}

/// What the memory benchmark measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GridMemoryBench {
    /// The candidate periods, as `--periods` takes them.
    pub periods: String,
    /// Their number.
    pub period_count: usize,
    /// Frames.
    pub frames: u32,
    /// Order of the models.
    pub order: usize,
    /// Cells of the grid on which the baseline was checked against the new grid (every cell's
    /// sums equal, file size as computed).
    pub checked_cells: usize,
    /// One row per grid size.
    pub rows: Vec<GridMemoryRow>,
}

impl GridMemoryBench {
    /// The result as `chronomap bench grid-memory` prints it: a row per grid size, the bytes
    /// per changing cell in memory and in the file beside grid-state format 1, and the
    /// estimate of [`FremenGrid::memory_estimate`] for the largest grid.
    pub fn text(&self) -> String {
        let mut lines = vec![
            format!(
                "FreMEn grids whose every cell changes: {} periods ({}), {} frames; baseline: grid-state \
                 format 1 (checked on {} cells: same sums read back)",
                self.period_count, self.periods, self.frames, self.checked_cells
            ),
            format!(
                "{:>9} {:>11} | {:>27} {:>8} | {:>27} | {:>7} {:>5} {:>4}",
                "cells",
                "shape",
                "bytes/cell: format 1  now",
                "RSS now",
                "file bytes/cell: fmt 1  now",
                "blocks",
                "snaps",
                "bits"
            ),
        ];
        for row in &self.rows {
            lines.push(format!(
                "{:>9} {:>11} | {:>13.0} {:>5.0} {:>6.1}x {:>8} | {:>13.0} {:>5.0} {:>6.1}x | {:>7} {:>5} {:>4}",
                row.cells,
                format!("{}x{}", row.shape[0], row.shape[1]),
                row.baseline_bytes_per_cell,
                row.bytes_per_cell,
                row.memory_ratio,
                row.rss_bytes_per_cell
                    .map_or("-".into(), |b| format!("{b:.0}")),
                row.baseline_file_bytes_per_cell,
                row.file_bytes_per_cell,
                row.file_ratio,
                row.storage.owned_accumulators + row.storage.snapshots,
                row.storage.snapshots,
                row.storage.sum_bits
            ));
        }
        lines.push(
            "blocks: blocks of exact sums in use (owned by cells, or snapshots: frame prefixes \
             shared by the cells that changed in that frame); bits: of the stored sums"
                .to_string(),
        );
        if let Some(last) = self.rows.last() {
            let e = &last.estimate;
            lines.push(format!(
                "estimate per changing cell (FremenGrid::memory_estimate): {} bytes while it changed at \
                 most twice per state, {} with blocks of 64-bit sums, {} of 128-bit sums (the most); \
                 {} cells: {:.1} MB fixed, {:.2} GB at most",
                e.cell_bytes_inline,
                e.cell_bytes_narrow,
                e.cell_bytes_wide,
                e.cells,
                e.fixed_bytes as f64 / 1e6,
                e.worst_case_bytes as f64 / 1e9
            ));
        }
        lines.join("\n")
    }
}

/// The occupancy of `cell` in `frame`: in frame 0 every fourth cell unknown and the others
/// alternating; from frame 1 on every cell flips.
pub fn workload_value(cell: usize, frame: u32) -> i8 {
    if frame == 0 && cell.is_multiple_of(4) {
        -1
    } else if (cell + frame as usize) % 2 == 1 {
        100
    } else {
        0
    }
}

/// Time of frame `frame` (one a minute).
fn frame_time(frame: u32) -> f64 {
    1.7e9 + 60.0 * f64::from(frame)
}

/// A `width × height` rectangle of `cells` cells, as square as the count allows.
fn geometry_of(cells: usize) -> Result<GridGeometry, BenchError> {
    let mut width = (cells as f64).sqrt().floor().max(1.0) as usize;
    while !cells.is_multiple_of(width) {
        width -= 1;
    }
    let height = u32::try_from(cells / width).unwrap_or(u32::MAX);
    Ok(GridGeometry::planar(
        width as u32,
        height,
        0.05,
        [0.0, 0.0],
    )?)
}

fn grid_config(config: &GridMemoryConfig) -> GridConfig {
    GridConfig {
        fremen: FremenConfig {
            periods: config.periods.clone(),
            order: config.order,
            ..FremenConfig::default()
        },
        keep_history: false,
    }
}

/// The new grid of `geometry` after the workload's frames.
fn build(
    geometry: GridGeometry,
    config: &GridConfig,
    frames: u32,
    progress: &dyn Progress,
) -> Result<FremenGrid, BenchError> {
    let mut grid = FremenGrid::new(geometry, config.clone())?;
    let mut frame = vec![0i8; geometry.cells()];
    for f in 0..frames {
        for (cell, v) in frame.iter_mut().enumerate() {
            *v = workload_value(cell, f);
        }
        grid.observe_occupancy(frame_time(f), &frame)?;
        progress.advance(1);
    }
    Ok(grid)
}

/// Resident memory of this process in bytes (Linux `VmRSS`), if known.
fn rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

fn baseline_error(what: impl std::fmt::Display) -> BenchError {
    BenchError::GridBaseline(what.to_string())
}

/// The baseline's memory (as format 1 counted it) and its grid file's exact size, built part
/// by part.
fn measure_baseline(
    geometry: GridGeometry,
    config: &GridConfig,
    frames: u32,
) -> Result<(u64, u64), BenchError> {
    let cells = geometry.cells();
    let k = config.fremen.periods.len();
    let mut memory = 0u64;
    // The arrays of the whole grid's file: contents, then their lengths.
    let (mut slots, mut occupied_rows, mut unknown_rows) = (0usize, 0usize, 0usize);
    let (mut slot_bytes, mut occupied_bytes, mut unknown_bytes) = (0usize, 0usize, 0usize);
    let (mut plane_bytes, mut slot_of_bytes, mut prefix_bytes) = (0usize, 0usize, 0usize);
    let mut unknown_cells = 0u64;
    let mut skeleton = None;
    for start in (0..cells).step_by(PART) {
        let len = PART.min(cells - start);
        let part_geometry = GridGeometry::planar(len as u32, 1, geometry.resolution, [0.0; 2])?;
        let mut part = LegacyGrid::new(part_geometry, config.clone());
        let mut frame = vec![0i8; len];
        for f in 0..frames {
            for (i, v) in frame.iter_mut().enumerate() {
                *v = workload_value(start + i, f);
            }
            part.observe(frame_time(f), &frame);
        }
        // The whole grid's planes and slot index are those of its parts side by side.
        memory += part.memory_bytes() as u64;
        let (part_slots, occupied, unknown) = part.parts();
        slot_bytes += part_slots
            .iter()
            .map(|s| slot_len(s, start as u32, (unknown_rows / k.max(1)) as u32))
            .sum::<usize>();
        occupied_bytes += occupied.iter().map(row_len).sum::<usize>();
        unknown_bytes += unknown.iter().map(row_len).sum::<usize>();
        let (prefix, planes, slot_of) = part.prefix_and_planes();
        plane_bytes += planes
            .iter()
            .flat_map(|p| p.iter())
            .map(|&w| varint_len(u128::from(w)))
            .sum::<usize>();
        slot_of_bytes += slot_of
            .iter()
            .map(|&s| {
                let global = if s == u32::MAX { s } else { s + slots as u32 };
                varint_len(u128::from(global))
            })
            .sum::<usize>();
        prefix_bytes = prefix.iter().map(row_len).sum();
        unknown_cells += part.unknown_cells();
        slots += part_slots.len();
        occupied_rows += occupied.len();
        unknown_rows += unknown.len();
        if skeleton.is_none() {
            skeleton = Some(part.skeleton());
        }
    }
    let skeleton = skeleton
        .ok_or_else(|| baseline_error("no cells"))?
        .with_whole(geometry, unknown_cells);
    let skeleton_file =
        encode_model("grid-state", &Format1File(&skeleton)).map_err(baseline_error)?;
    let header = skeleton_file
        .iter()
        .position(|&b| b == b'\n')
        .ok_or_else(|| baseline_error("no header line"))?
        + 1;
    let words = geometry.words();
    // The skeleton holds its nine arrays empty (one byte each).
    let payload = skeleton_file.len() - header - 9
        + varint_len(k as u128)
        + prefix_bytes
        + 3 * varint_len(words as u128)
        + plane_bytes
        + varint_len(cells as u128)
        + slot_of_bytes
        + varint_len(slots as u128)
        + slot_bytes
        + varint_len(occupied_rows as u128)
        + occupied_bytes
        + varint_len(unknown_rows as u128)
        + unknown_bytes
        + 1;
    let digits = |n: usize| n.to_string().len();
    let header = header - digits(skeleton_file.len() - header) + digits(payload);
    // Format 1 counted its planes and slot index once, its prefix not at all.
    Ok((memory, (header + payload) as u64))
}

/// Checks the baseline against the new grid on a grid of [`CHECKED_CELLS`] cells: its format-1
/// file, as `chronomap_io` reads it, holds every cell's sums exactly as the new grid does, and
/// [`measure_baseline`] computes its size exactly.
fn check_baseline(config: &GridConfig, frames: u32) -> Result<usize, BenchError> {
    let geometry = geometry_of(CHECKED_CELLS)?;
    let grid = build(
        geometry,
        config,
        frames,
        &chronomap_core::progress::NoProgress,
    )?;
    let mut legacy = LegacyGrid::new(geometry, config.clone());
    let mut frame = vec![0i8; CHECKED_CELLS];
    for f in 0..frames {
        for (cell, v) in frame.iter_mut().enumerate() {
            *v = workload_value(cell, f);
        }
        legacy.observe(frame_time(f), &frame);
    }
    let bytes = encode_model("grid-state", &Format1File(&legacy)).map_err(baseline_error)?;
    let (_, computed) = measure_baseline(geometry, config, frames)?;
    if computed != bytes.len() as u64 {
        return Err(baseline_error(format!(
            "its file has {} bytes, {computed} computed",
            bytes.len()
        )));
    }
    let read = match decode_grid(&bytes).map_err(baseline_error)? {
        AnyGrid::State(read) => read,
        other => {
            return Err(baseline_error(format!(
                "read back as {}",
                chronomap_io::grid_kind(&other)
            )));
        }
    };
    for cell in 0..CHECKED_CELLS {
        if read.cell_sums(cell) != grid.cell_sums(cell) {
            return Err(baseline_error(format!(
                "cell {cell} holds other sums than the new grid"
            )));
        }
    }
    Ok(CHECKED_CELLS)
}

/// Runs the benchmark: the check of the baseline, then each grid size of `config` (the new
/// grid, then the baseline); reports one stage per size to `progress`.
///
/// # Errors
/// A cell count of 0 or above the grid's limit, or a baseline that fails its check.
pub fn bench_grid_memory(
    config: &GridMemoryConfig,
    progress: &dyn Progress,
) -> Result<GridMemoryBench, BenchError> {
    let grid_config = grid_config(config);
    grid_config
        .fremen
        .validate()
        .map_err(chronomap_grid::GridError::from)?;
    let checked_cells = check_baseline(&grid_config, config.frames)?;
    let mut rows = Vec::new();
    for &cells in &config.cells {
        let geometry = geometry_of(cells)?;
        progress.stage(&format!("{cells} cells"), u64::from(config.frames));
        let before = rss_bytes();
        let grid = build(geometry, &grid_config, config.frames, progress)?;
        let after = rss_bytes();
        let changing = grid.dynamic_cells().max(1) as f64;
        let heap = grid.heap_bytes() as u64;
        let file = encode_grid_state(&grid).map_err(baseline_error)?.len() as u64;
        let storage = grid.storage();
        let changing_cells = grid.dynamic_cells();
        drop(grid);
        let (baseline, baseline_file) = measure_baseline(geometry, &grid_config, config.frames)?;
        let bytes_per_cell = heap as f64 / changing;
        let file_bytes_per_cell = file as f64 / changing;
        let baseline_bytes_per_cell = baseline as f64 / changing;
        let baseline_file_bytes_per_cell = baseline_file as f64 / changing;
        rows.push(GridMemoryRow {
            cells,
            shape: [geometry.width, geometry.height],
            changing_cells,
            heap_bytes: heap,
            bytes_per_cell,
            rss_bytes_per_cell: before
                .zip(after)
                .map(|(b, a)| a.saturating_sub(b) as f64 / changing),
            baseline_bytes_per_cell,
            memory_ratio: baseline_bytes_per_cell / bytes_per_cell,
            file_bytes_per_cell,
            baseline_file_bytes_per_cell,
            file_ratio: baseline_file_bytes_per_cell / file_bytes_per_cell,
            storage,
            estimate: FremenGrid::memory_estimate(&geometry, &grid_config),
        });
    }
    Ok(GridMemoryBench {
        periods: config.periods.to_string(),
        period_count: config.periods.len(),
        frames: config.frames,
        order: config.order,
        checked_cells,
        rows,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_core::progress::NoProgress;

    #[test]
    fn every_cell_changes_in_every_frame_after_the_first() {
        for cell in 0..64 {
            for frame in 1..5 {
                assert_ne!(
                    workload_value(cell, frame),
                    workload_value(cell, frame - 1),
                    "cell {cell} frame {frame}"
                );
            }
        }
        assert_eq!(
            (0..8).map(|c| workload_value(c, 0)).collect::<Vec<_>>(),
            [-1, 100, 0, 100, -1, 100, 0, 100]
        );
        let g = geometry_of(4_000_000).unwrap();
        assert_eq!((g.width, g.height), (2000, 2000));
        let g = geometry_of(100_000).unwrap();
        assert_eq!((g.width, g.height), (250, 400));
    }

    #[test]
    fn the_baseline_is_format_1_in_parts_as_in_one() {
        // 3 parts of the baseline give the memory and file of one built whole.
        let config = grid_config(&GridMemoryConfig {
            periods: "day".parse().unwrap(),
            ..GridMemoryConfig::default()
        });
        let geometry = GridGeometry::planar(PART as u32 * 2 + 100, 1, 0.05, [0.0; 2]).unwrap();
        let mut whole = LegacyGrid::new(geometry, config.clone());
        for f in 0..4 {
            let frame: Vec<i8> = (0..geometry.cells())
                .map(|c| workload_value(c, f))
                .collect();
            whole.observe(frame_time(f), &frame);
        }
        let bytes = encode_model("grid-state", &Format1File(&whole)).unwrap();
        let (memory, file) = measure_baseline(geometry, &config, 4).unwrap();
        assert_eq!(file, bytes.len() as u64);
        assert_eq!(memory, whole.memory_bytes() as u64);
        // 80-byte slots and, per changing cell, 24 rows of 32 bytes, plus 24 more for the
        // cells that were unknown (a quarter), and 4 bytes of slot index and 3 bits of planes.
        let cells = geometry.cells() as u64;
        let unknown = cells.div_ceil(4);
        assert_eq!(
            memory,
            cells * (80 + 24 * 32 + 4) + unknown * 24 * 32 + 3 * 8 * geometry.words() as u64
        );
    }

    #[test]
    fn small_grids_hold_less_than_the_baseline() {
        let config = GridMemoryConfig {
            cells: vec![6400],
            frames: 3,
            periods: "day".parse().unwrap(),
            order: 2,
        };
        let result = bench_grid_memory(&config, &NoProgress).unwrap();
        assert_eq!(result.checked_cells, CHECKED_CELLS);
        let row = &result.rows[0];
        assert_eq!(row.shape, [80, 80]);
        assert_eq!(row.storage.owned_accumulators, 0);
        // Format 1: an 80-byte slot, 24 occupied rows (and 24 unknown rows for a quarter of the
        // cells) of 32 bytes, 4 bytes of slot index and 3 bits of planes.
        let baseline = 80.0 + 24.0 * 32.0 * 1.25 + 4.0 + 3.0 / 8.0;
        assert!(
            (row.baseline_bytes_per_cell - baseline).abs() < 1e-9,
            "{row:?}"
        );
        assert!(row.bytes_per_cell < 80.0, "{row:?}");
        assert!(row.memory_ratio > 10.0 && row.file_ratio > 5.0, "{row:?}");
        assert!(row.heap_bytes <= row.estimate.worst_case_bytes);
    }
}
