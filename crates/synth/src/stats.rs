//! Per-cell statistics of a streamed range over a whole workload: how often each cell is
//! occupied and how often it changes, and from those the error of the static model (each
//! cell predicted by its majority state), the baseline of [Krajník 2017] §VI.

use std::ops::Range;

use crate::error::SynthError;
use crate::office::OfficeWorkload;

/// Occupancy and change counts of every cell of a range over all frames of a workload
/// ([`OfficeWorkload::summarize`]).
#[derive(Clone, Debug, PartialEq)]
pub struct RangeSummary {
    /// The cells summarised; entry `i` of the vectors is cell `range.start + i`.
    pub range: Range<usize>,
    /// Number of frames.
    pub frames: u64,
    /// Frames in which each cell is occupied.
    pub occupied_frames: Vec<u64>,
    /// Changes of each cell between consecutive frames (frame 0's initial state is not a
    /// change).
    pub changes: Vec<u64>,
}

impl OfficeWorkload {
    /// Streams `range` through all frames and counts, per cell, occupied frames and changes.
    /// Takes time proportional to the number of frames plus the number of change events.
    ///
    /// # Errors
    /// As [`OfficeWorkload::stream`].
    pub fn summarize(&self, range: Range<usize>) -> Result<RangeSummary, SynthError> {
        let mut stream = self.stream(range.clone())?;
        let n = range.len();
        let mut occupied_frames = vec![0u64; n];
        let mut changes = vec![0u64; n];
        let mut since = vec![0u64; n];
        while let Some((frame, _, _)) = stream.next_frame() {
            for &cell in stream.last_changes() {
                let i = cell as usize - range.start;
                if frame > 0 {
                    changes[i] += 1;
                }
                if stream.is_occupied(cell as usize) == Some(true) {
                    since[i] = frame;
                } else {
                    occupied_frames[i] += frame - since[i];
                }
            }
        }
        let frames = self.frames();
        for (i, occupied) in occupied_frames.iter_mut().enumerate() {
            if stream.is_occupied(range.start + i) == Some(true) {
                *occupied += frames - since[i];
            }
        }
        Ok(RangeSummary {
            range,
            frames,
            occupied_frames,
            changes,
        })
    }
}

impl RangeSummary {
    /// The static model's error on cell `range.start + i`: the fraction of frames in which
    /// the cell is not in its majority state.
    pub fn static_error(&self, i: usize) -> f64 {
        let occupied = self.occupied_frames[i];
        occupied.min(self.frames - occupied) as f64 / self.frames as f64
    }

    /// Number of cells that changed at least once.
    pub fn changed_cells(&self) -> usize {
        self.changes.iter().filter(|&&c| c > 0).count()
    }

    /// The static model's error averaged over the cells that changed at least once (the
    /// measure of [Krajník 2017] §VI); `None` if no cell changed.
    pub fn static_error_on_changed(&self) -> Option<f64> {
        let (sum, count) = self
            .changes
            .iter()
            .enumerate()
            .filter(|&(_, &c)| c > 0)
            .fold((0.0, 0usize), |(s, n), (i, _)| {
                (s + self.static_error(i), n + 1)
            });
        (count > 0).then(|| sum / count as f64)
    }

    /// Total number of changes.
    pub fn total_changes(&self) -> u64 {
        self.changes.iter().sum()
    }

    /// Mean number of change events per frame.
    pub fn changes_per_frame(&self) -> f64 {
        self.total_changes() as f64 / self.frames as f64
    }
}
