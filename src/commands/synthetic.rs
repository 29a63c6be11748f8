//! Streaming the synthetic office (chronomap-synth) into grids on several threads, and the
//! bare scan it is measured against.

use std::io::IsTerminal;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use chronomap_grid::{FremenGrid, GridConfig, GridGeometry};
use chronomap_synth::office::{OfficeConfig, OfficeWorkload};

/// Geometry of the synthetic office: the paper's 213,000 cells as a 71 × 60 × 50 block of
/// 10 cm cells (7.1 m × 6 m × 5 m); other sizes as the most square 2-D grid.
pub fn office_geometry(cells: usize) -> Result<GridGeometry> {
    let geometry = if cells == 213_000 {
        GridGeometry {
            width: 71,
            height: 60,
            depth: 50,
            resolution: 0.1,
            origin: [0.0, 0.0, 0.0],
        }
    } else {
        let mut width = (cells as f64).sqrt() as usize;
        while width > 1 && !cells.is_multiple_of(width) {
            width -= 1;
        }
        GridGeometry {
            width: u32::try_from(cells / width.max(1)).context("too many cells")?,
            height: width.max(1) as u32,
            depth: 1,
            resolution: 0.1,
            origin: [0.0, 0.0, 0.0],
        }
    };
    geometry.validate()?;
    Ok(geometry)
}

/// The office workload of the given size.
pub fn office(cells: usize, days: u32, seed: u64) -> Result<OfficeWorkload> {
    Ok(OfficeWorkload::new(OfficeConfig {
        cells,
        days,
        seed,
        ..OfficeConfig::default()
    })?)
}

/// Consecutive cell ranges, one per thread, starting on 64-cell boundaries.
pub fn partition(cells: usize, parts: usize) -> Vec<Range<usize>> {
    let words = cells.div_ceil(64);
    let per = words.div_ceil(parts.max(1)).max(1) * 64;
    (0..cells)
        .step_by(per)
        .map(|s| s..(s + per).min(cells))
        .collect()
}

/// Reports progress on an interactive terminal while `work` runs.
pub fn with_progress<T>(label: &str, total: u64, work: impl FnOnce(&AtomicU64) -> T) -> T {
    let done = AtomicU64::new(0);
    let finished = AtomicBool::new(false);
    let show = std::io::stderr().is_terminal() && total > 0;
    std::thread::scope(|scope| {
        if show {
            scope.spawn(|| {
                let start = Instant::now();
                while !finished.load(Ordering::Relaxed) {
                    std::thread::sleep(Duration::from_millis(250));
                    let d = done.load(Ordering::Relaxed).min(total);
                    eprint!(
                        "\r{label}: {:5.1} % ({:.0} s)   ",
                        100.0 * d as f64 / total as f64,
                        start.elapsed().as_secs_f64()
                    );
                }
                eprint!("\r{}\r", " ".repeat(label.len() + 30));
            });
        }
        let result = work(&done);
        finished.store(true, Ordering::Relaxed);
        result
    })
}

/// Frames between progress updates.
const REPORT_EVERY: u64 = 4096;

/// A grid of the whole office built on `threads` threads, and the same grid as it was before
/// each of the snapshot frames (for choosing orders and measuring prediction errors on
/// held-back frames).
pub struct Built {
    pub grid: FremenGrid,
    pub snapshots: Vec<FremenGrid>,
    pub seconds: f64,
}

/// Streams every frame of `workload` into a grid, one part of the cells per thread, and
/// concatenates the parts.
pub fn build(
    workload: &OfficeWorkload,
    geometry: GridGeometry,
    config: &GridConfig,
    threads: usize,
    snapshot_at: &[u64],
    progress: &AtomicU64,
) -> Result<Built> {
    let start = Instant::now();
    let ranges = partition(workload.cells(), threads);
    type Part = (FremenGrid, Vec<FremenGrid>);
    let parts: Vec<Result<Part>> = std::thread::scope(|scope| {
        let handles: Vec<_> = ranges
            .iter()
            .map(|range| {
                let range = range.clone();
                scope.spawn(move || -> Result<Part> {
                    let part_geometry = GridGeometry::planar(
                        range.len() as u32,
                        1,
                        geometry.resolution,
                        [0.0, 0.0],
                    )?;
                    let mut grid = FremenGrid::new(part_geometry, config.clone())?;
                    let mut snapshots = Vec::new();
                    let mut stream = workload.stream(range)?;
                    while let Some((frame, time, bits)) = stream.next_frame() {
                        if snapshot_at.contains(&frame) {
                            snapshots.push(grid.clone());
                        }
                        grid.observe_bits(time, bits, None)?;
                        if frame % REPORT_EVERY == REPORT_EVERY - 1 {
                            progress.fetch_add(REPORT_EVERY, Ordering::Relaxed);
                        }
                    }
                    Ok((grid, snapshots))
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("builder thread panicked"))
            .collect()
    });
    let (grids, mut part_snapshots): (Vec<_>, Vec<_>) = parts
        .into_iter()
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .unzip();
    let grid = FremenGrid::concat(geometry, grids)?;
    let mut snapshots = Vec::new();
    for _ in 0..snapshot_at
        .len()
        .min(part_snapshots.first().map_or(0, Vec::len))
    {
        let parts = part_snapshots.iter_mut().map(|s| s.remove(0)).collect();
        snapshots.push(FremenGrid::concat(geometry, parts)?);
    }
    Ok(Built {
        grid,
        snapshots,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The bare scan: the same streams feeding a consumer that only XORs each frame with the
/// previous one and counts the changed bits. Returns (seconds, changed bits).
pub fn bare_scan(
    workload: &OfficeWorkload,
    threads: usize,
    progress: &AtomicU64,
) -> Result<(f64, u64)> {
    let start = Instant::now();
    let ranges = partition(workload.cells(), threads);
    let counts: Vec<Result<u64>> = std::thread::scope(|scope| {
        let handles: Vec<_> = ranges
            .iter()
            .map(|range| {
                let range = range.clone();
                scope.spawn(move || -> Result<u64> {
                    let mut stream = workload.stream(range.clone())?;
                    let mut previous = vec![0u64; range.len().div_ceil(64)];
                    let mut changed = 0u64;
                    while let Some((frame, _, bits)) = stream.next_frame() {
                        for (p, &b) in previous.iter_mut().zip(bits) {
                            changed += u64::from((*p ^ b).count_ones());
                            *p = b;
                        }
                        if frame % REPORT_EVERY == REPORT_EVERY - 1 {
                            progress.fetch_add(REPORT_EVERY, Ordering::Relaxed);
                        }
                    }
                    Ok(changed)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("scan thread panicked"))
            .collect()
    });
    let changed = counts.into_iter().sum::<Result<u64>>()?;
    Ok((start.elapsed().as_secs_f64(), changed))
}

/// Peak resident memory of this process in MB (Linux `VmHWM`), if known.
pub fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partitions_cover_the_cells_on_word_boundaries() {
        let parts = partition(213_000, 2);
        assert_eq!(parts.len(), 2);
        assert_eq!(parts[0].start, 0);
        assert_eq!(parts[0].end % 64, 0);
        assert_eq!(parts[1].end, 213_000);
        assert_eq!(partition(100, 4), vec![0..64, 64..100]);
        assert_eq!(office_geometry(213_000).unwrap().cells(), 213_000);
        let g = office_geometry(6400).unwrap();
        assert_eq!((g.width, g.height), (80, 80));
    }
}
