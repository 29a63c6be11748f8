//! Building grids from whole sequences of frames: one frame at a time with the snapshots that
//! a chronological hold-out needs ([Krajník 2017] §IV-B, §VI), or from a source that streams any
//! range of cells on its own, split over tasks and [concatenated](FremenGrid::concat).
//!
//! The hold-out of [Krajník 2017] §VI keeps the most recent fraction of the frames back: orders are
//! chosen on it (§IV-B) and prediction errors measured on it. Choosing the orders of the model
//! whose prediction error is measured must not see those frames either, so two snapshots are
//! taken: the grid before the *inner* split (to choose the orders of the trained model) and
//! before the split itself ([`holdout_splits`]).
//!
//! ```
//! use chronomap_core::progress::NoProgress;
//! use chronomap_grid::build::{build_from_frames, holdout_splits, occupancy_percent};
//! use chronomap_grid::{GridConfig, GridGeometry, GridError};
//!
//! // Two cells observed hourly for 8 frames: a door (open at even hours) and a wall.
//! let geometry = GridGeometry::planar(2, 1, 1.0, [0.0, 0.0])?;
//! let config = GridConfig { keep_history: true, ..GridConfig::default() };
//! let splits = holdout_splits(8, 0.25);
//! assert_eq!(splits, [5, 6]);
//! let built = build_from_frames(geometry, &config, 8, &splits, &NoProgress, |f, grid| {
//!     let door = occupancy_percent(if f % 2 == 0 { 1.0 } else { 0.0 });
//!     grid.observe_occupancy(3600.0 * f as f64, &[door, 100])
//! })?;
//! assert_eq!(built.grid.frames(), 8);
//! assert_eq!(built.snapshots.iter().map(|g| g.frames()).collect::<Vec<_>>(), [5, 6]);
//! # Ok::<(), GridError>(())
//! ```

use std::ops::Range;

use chronomap_core::Parallelism;
use chronomap_core::progress::Progress;
use rayon::prelude::*;
use thiserror::Error;

use crate::{FremenGrid, GridConfig, GridError, GridGeometry};

/// Frame indices `[inner, split]` of a chronological hold-out of the most recent `holdout`
/// fraction of `frames`: `split = round(frames·(1 − holdout))` frames train the model whose
/// prediction error is measured on the rest, and `inner = round(split·(1 − holdout))` frames
/// train the model whose orders are chosen on frames `[inner, split)`.
pub fn holdout_splits(frames: u64, holdout: f64) -> [u64; 2] {
    let split = ((frames as f64) * (1.0 - holdout)).round() as u64;
    let inner = ((split as f64) * (1.0 - holdout)).round() as u64;
    [inner, split]
}

/// The occupancy in percent (`nav_msgs/OccupancyGrid`, 0..=100) of a state in `[0, 1]`, as
/// [`FremenGrid::observe_occupancy`] reads it back (`s = v / 100`).
pub fn occupancy_percent(state: f64) -> i8 {
    (100.0 * state).round() as i8
}

/// A grid built from a sequence of frames, and the grid as it was before some of them.
#[derive(Clone, Debug)]
pub struct GridBuild {
    /// The grid after every frame.
    pub grid: FremenGrid,
    /// The grid as it was before each frame of `snapshot_at` (in that order; frames past the
    /// last one are not taken).
    pub snapshots: Vec<FremenGrid>,
}

/// Builds a grid of `geometry` from `frames` frames that `next(f, grid)` feeds into the grid
/// one at a time (`f = 0, 1, ...`), taking a snapshot before each frame of `snapshot_at`
/// (e.g. [`holdout_splits`]). Reports one step per frame to `progress`.
///
/// # Errors
/// An invalid geometry or configuration, or the first error of `next` (which can name the
/// file and line the frame came from).
pub fn build_from_frames<E: From<GridError>>(
    geometry: GridGeometry,
    config: &GridConfig,
    frames: usize,
    snapshot_at: &[u64],
    progress: &dyn Progress,
    mut next: impl FnMut(usize, &mut FremenGrid) -> Result<(), E>,
) -> Result<GridBuild, E> {
    let mut builder = GridBuilder::new(geometry, config, snapshot_at)?;
    progress.stage("reading frames", frames as u64);
    for f in 0..frames {
        next(f, builder.next_frame())?;
        progress.advance(1);
    }
    Ok(builder.finish())
}

/// The push side of [`build_from_frames`], for sources that hand out frames one at a time
/// (a bag read as a stream): [`GridBuilder::next_frame`] gives the grid to observe the next
/// frame into, after a snapshot if that frame is in `snapshot_at`.
///
/// ```
/// use chronomap_grid::{GridConfig, GridGeometry, build::GridBuilder};
///
/// let geometry = GridGeometry::planar(2, 1, 0.5, [0.0, 0.0])?;
/// let mut builder = GridBuilder::new(geometry, &GridConfig::default(), &[1])?;
/// for (t, frame) in [(0.0, [0i8, 100]), (60.0, [100, 100])] {
///     builder.next_frame().observe_occupancy(t, &frame)?;
/// }
/// let build = builder.finish();
/// assert_eq!((build.grid.frames(), build.snapshots[0].frames()), (2, 1));
/// # Ok::<(), chronomap_grid::GridError>(())
/// ```
#[derive(Debug)]
pub struct GridBuilder {
    grid: FremenGrid,
    snapshots: Vec<FremenGrid>,
    snapshot_at: Vec<u64>,
    frame: u64,
}

impl GridBuilder {
    /// An empty grid of `geometry` that will be snapshot before each frame of `snapshot_at`.
    ///
    /// # Errors
    /// An invalid geometry or configuration.
    pub fn new(
        geometry: GridGeometry,
        config: &GridConfig,
        snapshot_at: &[u64],
    ) -> Result<Self, GridError> {
        Ok(GridBuilder {
            grid: FremenGrid::new(geometry, config.clone())?,
            snapshots: Vec::new(),
            snapshot_at: snapshot_at.to_vec(),
            frame: 0,
        })
    }

    /// The grid to observe the next frame into.
    pub fn next_frame(&mut self) -> &mut FremenGrid {
        if self.snapshot_at.contains(&self.frame) {
            self.snapshots.push(self.grid.clone());
        }
        self.frame += 1;
        &mut self.grid
    }

    /// Frames handed out so far.
    pub fn frames(&self) -> u64 {
        self.frame
    }

    /// The grid and its snapshots.
    pub fn finish(self) -> GridBuild {
        GridBuild {
            grid: self.grid,
            snapshots: self.snapshots,
        }
    }
}

/// Bit-packed frames of a range of cells in time order, as [`FremenGrid::observe_bits`] takes
/// them.
pub trait BitFrames {
    /// The next frame: its index (from 0), its time and its words (bit `i % 64` of word
    /// `i / 64` is the `i`-th cell of the range, 1 = occupied); `None` after the last frame.
    fn next_frame(&mut self) -> Option<(u64, f64, &[u64])>;
}

/// A source of frames that streams any range of cells starting on a 64-cell boundary on its
/// own, from frame 0, so that parts of a grid can be built on separate threads. Every stream
/// must give the same frame times.
pub trait PartitionedFrames: Sync {
    /// A stream of one range of cells.
    type Stream<'a>: BitFrames
    where
        Self: 'a;
    /// Why a range cannot be streamed.
    type Error: std::error::Error + Send + Sync + 'static;
    /// Number of cells.
    fn cells(&self) -> usize;
    /// Number of frames.
    fn frames(&self) -> u64;
    /// Streams the cells `range`.
    ///
    /// # Errors
    /// A range the source cannot stream.
    fn stream(&self, range: Range<usize>) -> Result<Self::Stream<'_>, Self::Error>;
}

/// Why a partitioned build or scan failed.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum PartitionError {
    /// The source could not stream a part.
    #[error("cells {start}..{end}: {source}")]
    Source {
        /// First cell of the part.
        start: usize,
        /// End (exclusive) of the part.
        end: usize,
        /// The source's error.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A part could not be built or the parts combined.
    #[error(transparent)]
    Grid(#[from] GridError),
}

/// Consecutive ranges of `cells` cells, at most `parts` of them, starting on 64-cell
/// boundaries (whole words of a bit-packed frame) and as even as those allow.
///
/// ```
/// use chronomap_grid::build::partition;
/// assert_eq!(partition(100, 4), vec![0..64, 64..100]);
/// assert_eq!(partition(256, 2), vec![0..128, 128..256]);
/// ```
pub fn partition(cells: usize, parts: usize) -> Vec<Range<usize>> {
    let words = cells.div_ceil(64);
    let per = words.div_ceil(parts.max(1)).max(1) * 64;
    (0..cells)
        .step_by(per)
        .map(|s| s..(s + per).min(cells))
        .collect()
}

/// Frames between progress reports of a part.
const REPORT_EVERY: u64 = 4096;

/// Runs `work` on every range of [`partition`]`(cells, parallelism.tasks())`, on the calling
/// thread or as rayon tasks, reporting `frames` steps per part as stage `stage`. Results come
/// in the order of the ranges.
fn for_each_part<T: Send>(
    cells: usize,
    frames: u64,
    parallelism: Parallelism,
    stage: &str,
    progress: &dyn Progress,
    work: impl Fn(Range<usize>, &dyn Fn(u64)) -> Result<T, PartitionError> + Sync,
) -> Result<Vec<T>, PartitionError> {
    let ranges = partition(cells, parallelism.tasks());
    progress.stage(stage, frames * ranges.len() as u64);
    let run = |range: Range<usize>| work(range, &|frame| report(progress, frame, frames));
    match parallelism {
        Parallelism::Sequential => ranges.into_iter().map(run).collect(),
        Parallelism::Rayon(_) => ranges.into_par_iter().map(run).collect(),
    }
}

/// Reports progress every [`REPORT_EVERY`] frames and the remainder after the last frame.
fn report(progress: &dyn Progress, frame: u64, frames: u64) {
    if frame % REPORT_EVERY == REPORT_EVERY - 1 {
        progress.advance(REPORT_EVERY);
    } else if frame + 1 == frames {
        progress.advance(frames % REPORT_EVERY);
    }
}

/// Streams every frame of `source` into a grid of `geometry`, one part of the cells
/// ([`partition`]) per task of `parallelism`, and concatenates the parts; also the grid as
/// it was before each frame of `snapshot_at` (for choosing orders and measuring prediction
/// errors on held-back frames, [`holdout_splits`]). Reports the frames of every part to
/// `progress` as one stage.
///
/// The result does not depend on `parallelism`: every cell's model (its exact sums and span)
/// is the one a grid built from all cells on one thread has.
///
/// # Errors
/// A geometry whose number of cells is not the source's, a part the source cannot stream, or
/// a frame the grid rejects.
pub fn build_partitioned<S: PartitionedFrames>(
    source: &S,
    geometry: GridGeometry,
    config: &GridConfig,
    snapshot_at: &[u64],
    parallelism: Parallelism,
    progress: &dyn Progress,
) -> Result<GridBuild, PartitionError> {
    if geometry.cells() != source.cells() {
        return Err(GridError::Incompatible {
            reason: format!(
                "the geometry has {} cells, the frames {}",
                geometry.cells(),
                source.cells()
            ),
        }
        .into());
    }
    type Part = (FremenGrid, Vec<FremenGrid>);
    let parts: Vec<Part> = for_each_part(
        source.cells(),
        source.frames(),
        parallelism,
        "building the grid",
        progress,
        |range, advance| {
            let part_geometry =
                GridGeometry::planar(range.len() as u32, 1, geometry.resolution, [0.0, 0.0])?;
            let mut grid = FremenGrid::new(part_geometry, config.clone())?;
            let mut snapshots = Vec::new();
            let mut stream = open(source, &range)?;
            while let Some((frame, time, bits)) = stream.next_frame() {
                if snapshot_at.contains(&frame) {
                    snapshots.push(grid.clone());
                }
                grid.observe_bits(time, bits, None)?;
                advance(frame);
            }
            Ok((grid, snapshots))
        },
    )?;
    let (grids, mut part_snapshots): (Vec<_>, Vec<_>) = parts.into_iter().unzip();
    let grid = FremenGrid::concat(geometry, grids)?;
    let mut snapshots = Vec::new();
    let taken = part_snapshots.first().map_or(0, Vec::len);
    for _ in 0..snapshot_at.len().min(taken) {
        let parts = part_snapshots.iter_mut().map(|s| s.remove(0)).collect();
        snapshots.push(FremenGrid::concat(geometry, parts)?);
    }
    Ok(GridBuild { grid, snapshots })
}

/// The bare scan that a partitioned build is measured against: the same parts of the same
/// streams, each frame only XORed with the previous one and the changed bits counted (frame
/// 0 against an all-free frame). Returns the number of changed bits, which does not depend
/// on `parallelism`.
///
/// # Errors
/// A part the source cannot stream.
pub fn bare_scan<S: PartitionedFrames>(
    source: &S,
    parallelism: Parallelism,
    progress: &dyn Progress,
) -> Result<u64, PartitionError> {
    let counts = for_each_part(
        source.cells(),
        source.frames(),
        parallelism,
        "bare scan",
        progress,
        |range, advance| {
            let mut stream = open(source, &range)?;
            let mut previous = vec![0u64; range.len().div_ceil(64)];
            let mut changed = 0u64;
            while let Some((frame, _, bits)) = stream.next_frame() {
                for (p, &b) in previous.iter_mut().zip(bits) {
                    changed += u64::from((*p ^ b).count_ones());
                    *p = b;
                }
                advance(frame);
            }
            Ok(changed)
        },
    )?;
    Ok(counts.into_iter().sum())
}

fn open<'a, S: PartitionedFrames>(
    source: &'a S,
    range: &Range<usize>,
) -> Result<S::Stream<'a>, PartitionError> {
    source
        .stream(range.clone())
        .map_err(|e| PartitionError::Source {
            start: range.start,
            end: range.end,
            source: Box::new(e),
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_core::progress::NoProgress;
    use std::sync::atomic::{AtomicU64, Ordering};

    /// 300 cells, 500 frames a minute apart: cell `c` is occupied at frame `f` when a hash of
    /// both says so, for one cell in five; the others never change.
    struct Hashed;

    struct HashedStream {
        range: Range<usize>,
        frame: u64,
        words: Vec<u64>,
    }

    fn occupied(cell: usize, frame: u64) -> bool {
        let h = (cell as u64 ^ frame.rotate_left(17)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        cell.is_multiple_of(5) && (h >> 60) < 5
    }

    impl BitFrames for HashedStream {
        fn next_frame(&mut self) -> Option<(u64, f64, &[u64])> {
            if self.frame == 500 {
                return None;
            }
            self.words.fill(0);
            for (i, cell) in self.range.clone().enumerate() {
                if occupied(cell, self.frame) {
                    self.words[i / 64] |= 1 << (i % 64);
                }
            }
            self.frame += 1;
            Some((self.frame - 1, 60.0 * self.frame as f64, &self.words))
        }
    }

    impl PartitionedFrames for Hashed {
        type Stream<'a> = HashedStream;
        type Error = std::fmt::Error;
        fn cells(&self) -> usize {
            300
        }
        fn frames(&self) -> u64 {
            500
        }
        fn stream(&self, range: Range<usize>) -> Result<HashedStream, std::fmt::Error> {
            if !range.start.is_multiple_of(64) {
                return Err(std::fmt::Error);
            }
            Ok(HashedStream {
                words: vec![0; range.len().div_ceil(64)],
                range,
                frame: 0,
            })
        }
    }

    struct Count(AtomicU64);

    impl Progress for Count {
        fn advance(&self, steps: u64) {
            self.0.fetch_add(steps, Ordering::Relaxed);
        }
    }

    #[test]
    fn partitions_cover_the_cells_on_word_boundaries() {
        let parts = partition(213_000, 2);
        assert_eq!(parts.len(), 2);
        assert_eq!(parts[0], 0..106_560);
        assert_eq!(parts[1], 106_560..213_000);
        assert_eq!(partition(100, 4), vec![0..64, 64..100]);
        assert_eq!(partition(64, 0), vec![0..64]);
        assert_eq!(partition(300, 3), vec![0..128, 128..256, 256..300]);
    }

    #[test]
    fn a_partitioned_grid_does_not_depend_on_the_tasks() {
        let geometry = GridGeometry::planar(300, 1, 0.1, [0.0, 0.0]).unwrap();
        let config = crate::tests::with_history();
        // Each of `tasks` tasks streams all 500 frames of its cells.
        let build = |parallelism, tasks: u64| {
            let count = Count(AtomicU64::new(0));
            let built =
                build_partitioned(&Hashed, geometry, &config, &[250, 400], parallelism, &count)
                    .unwrap();
            assert_eq!(count.0.load(Ordering::Relaxed), tasks * 500);
            built
        };
        let one = build(Parallelism::Sequential, 1);
        let three = build(Parallelism::Rayon(3), 3);
        assert_eq!(three.grid.frames(), 500);
        assert_eq!(three.grid.dynamic_cells(), one.grid.dynamic_cells());
        assert_eq!(one.grid.dynamic_cells(), 60);
        for c in 0..300 {
            assert_eq!(three.grid.cell_model(c), one.grid.cell_model(c), "cell {c}");
        }
        let frames: Vec<u64> = three.snapshots.iter().map(FremenGrid::frames).collect();
        assert_eq!(frames, [250, 400]);
        for (a, b) in one.snapshots.iter().zip(&three.snapshots) {
            for c in (0..300).step_by(5) {
                assert_eq!(a.cell_model(c), b.cell_model(c), "cell {c}");
            }
        }
        // The bare scan counts the same changes however it is split.
        let changed = bare_scan(&Hashed, Parallelism::Sequential, &NoProgress).unwrap();
        assert_eq!(
            bare_scan(&Hashed, Parallelism::Rayon(3), &NoProgress).unwrap(),
            changed
        );
        let mut expected = 0;
        for c in 0..300 {
            let mut was = false;
            for f in 0..500 {
                expected += u64::from(occupied(c, f) != was);
                was = occupied(c, f);
            }
        }
        assert_eq!(changed, expected);
        assert!(changed > 1000, "{changed}");
    }

    #[test]
    fn a_geometry_of_another_size_is_refused() {
        let geometry = GridGeometry::planar(299, 1, 0.1, [0.0, 0.0]).unwrap();
        let err = build_partitioned(
            &Hashed,
            geometry,
            &GridConfig::default(),
            &[],
            Parallelism::Sequential,
            &NoProgress,
        )
        .unwrap_err();
        assert!(
            err.to_string().contains("299 cells, the frames 300"),
            "{err}"
        );
    }
}
