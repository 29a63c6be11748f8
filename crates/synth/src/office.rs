//! A synthetic office observed by a stationary depth camera: a 4-D (3-D + time) occupancy
//! grid with known ground truth, generated from a seed and streamed frame by frame.
//!
//! # Why
//! The large spatio-temporal experiment of FreMEn ([Krajník 2017] §VI) observed ~213,000 cells of
//! an office every 5 s (17,280 frames a day) for 112 days: 4·10¹¹ cell observations. No such
//! data set is public. This module generates one with the same shape — by default the same
//! size — whose generating process is known, so that throughput can be measured at paper
//! scale and accuracy against the truth ([`OfficeWorkload::truth_probability`]).
//!
//! # The grid
//! Cells are indexed `0..cells`; neighbouring indices are neighbouring cells (an object
//! covers a run of consecutive indices). Every cell belongs to one [`CellClass`]; the layout
//! is drawn once from the seed by [`OfficeWorkload::new`]:
//!
//! * exactly `round(dynamic_fraction × cells)` cells are *dynamic* (their generating process
//!   changes them), of which 25 % are periodic, 9 % persistent and the rest (66 %) noise
//!   cells (exact quotas, up to rounding);
//! * of the static cells, 10 % are static occupied (walls, furniture) in runs of 4–64
//!   cells, the rest static free (air);
//! * periodic cells come in clusters of 8–32 consecutive cells sharing one process (an
//!   object covers several cells), persistent cells in clusters of 4–16 sharing one step
//!   (a remainder too small for a cluster joins the last one),
//!   static occupied cells in runs of 4–64, noise and static free cells singly; the
//!   clusters, runs and single cells are laid out in a random order.
//!
//! # Days and frames
//! Frame `f` is taken at `start_time + f × frame_secs` ([`OfficeWorkload::frame_time`]);
//! there are `⌊days × 86 400 / frame_secs⌋` frames. Days are UTC calendar days (day
//! `⌊t / 86 400⌋`, Monday to Friday are weekdays, 1970-01-01 was a Thursday). Each dynamic
//! cell's occupancy on a day is a set of time intervals drawn from a random stream seeded by
//! the seed, the cell (or the cluster sharing its process) and the day only, so any range of
//! cells streams the same bits as the whole grid. A frame is occupied when its time lies in
//! one of the intervals; an interval `[a, b)` covers the frames with `a <= time < b`.
//!
//! # The processes (all numbers drawn uniformly from the ranges given, once per cluster)
//! **Periodic** — an object present in a daily interval `[start + J_s, end + J_e)` on its
//! active days, absent otherwise; `J_s`, `J_e` are independent daily jitters uniform in
//! `[−w, w]`; on each active day the interval is skipped with probability `skip`. Each cell
//! of a cluster shrinks the cluster's interval by its own fixed 0–5 min at each end (the edge
//! of an object covers a cell for a little less time). Four kinds, each with its exact
//! share of the periodic cells (so the mix holds even on small grids):
//!
//! | kind (share of periodic cells) | days | interval start | duration | jitter `w` | skip |
//! |---|---|---|---|---|---|
//! | desk chair in use (40 %) | weekdays | 7:30–9:30 | 6–9 h | 15–45 min | 5–15 % |
//! | door, *occupied when closed* (15 %) | weekdays open | 7:00–9:00 | 8–11 h | 15–30 min | 2–8 % (stays closed) |
//! | table at lunch (25 %) | weekdays | 11:30–13:00 | 1–1.5 h | 10–20 min | 10–30 % |
//! | bin, trolley, coat (20 %) | every day | 5:00–19:00 | 1–4 h | 10–20 min | 5–20 % |
//!
//! The door is inverted: its cells are occupied outside the interval, all day at weekends
//! and on skipped days.
//!
//! **Noise** — people passing: bursts of 1–6 frames (uniform) starting at the times of an
//! inhomogeneous Poisson process with rate `r × m(t)` bursts per hour, where the cell's rate
//! `r` is log-uniform in 0.05–5 per hour and the profile `m(t)` is, on weekdays, 1 from 8:00
//! to 18:00, 0.2 from 6:00 to 8:00 and from 18:00 to 22:00, 0.01 at night, and at weekends
//! 0.1 from 8:00 to 18:00, 0.05 from 18:00 to 22:00, 0.01 otherwise. A burst starts at the
//! first frame at or after its time; bursts are cut at midnight (a day's bursts never reach
//! into the next day). Nothing periodic can predict these.
//!
//! **Persistent** — a piece of furniture moved once: the cluster's cells are occupied until
//! (or from) a switch time and free from (or until) then, 50/50. The switch day is spread
//! evenly over the workload's days (systematic sampling: the `k`-th of `K` clusters switches
//! on day `⌊(k + u) days / K⌋`, one `u` uniform in `[0, 1)` for all), at a uniform time
//! between 8:00 and 18:00 UTC. (With a `start_time` that is not midnight, a switch can fall
//! outside the workload; such cells then never change.)
//!
//! # Ground truth and calibration
//! [`OfficeWorkload::truth_probability`] is the probability that a cell is occupied at a time
//! under its generating process, given the layout: 0 or 1 for static and persistent cells;
//! for periodic cells `(1 − skip) P(start + J_s <= t) P(t < end + J_e)` on active days, with
//! `start` and `end` shrunk by the cell's own trims (one minus that for the door); for noise cells `1 − exp(−Σ_k (6 − k)/6 × Λ_k)`, `Λ_k` the
//! expected number of bursts starting in the `k`-th frame interval before `t` (`k` = 0..5)
//! on the same day. All are exact at frame times.
//!
//! The numbers above are calibrated so that the static model (each cell predicted by its
//! majority state over the whole workload) mis-estimates about 6 % of the frames of the cells
//! that changed at least once, as in [Krajník 2017] §VI; the crate's tests check 5.5–6.5 % on a
//! grid of 32,000 cells. At the default size (seed 0) it is 5.95 %: periodic cells (static
//! error 14.3 % each on average) contribute 3.6 points, persistent cells (25 %) 2.3, noise
//! cells (0.2 %) 0.1; over seeds 0–7 it ranges from 5.95 to 6.08 %. There are 7.3 change
//! events per frame on average (about 10 on a weekday, fewer at weekends), against 3,329
//! words in a frame; `cargo run --release -p chronomap-synth --example office_stats` prints
//! these numbers for any size, and the streaming throughput.
//!
//! Not calibrated, for comparison: FFT FreMEn (`chronomap_core::fft`, example
//! `office_fremen`) built from all frames of each changed cell of a 6,400-cell grid
//! mis-estimates 3.4 % (order 1), 2.4 % (order 2) and 1.2 % (order 5) of them, below the
//! paper's 3–4 %: its spectrum spans the whole workload, so its slowest components also fit
//! the persistent steps (their error falls from 23 % to 5 % at order 1), and the periodic
//! cells' error falls from 14 % to 8 % at order 2 (the rest is jitter and skipped days).

mod layout;
mod process;
mod stream;

use std::ops::Range;

use crate::error::SynthError;

pub use stream::FrameStream;

/// Seconds in a day.
pub(crate) const DAY_SECS: f64 = 86_400.0;

/// Largest number of cells supported (cell indices must fit the `u32`s of
/// [`FrameStream::last_changes`]; the layout takes 12 bytes a cell).
pub const MAX_CELLS: usize = 1 << 28;

/// Smallest frame interval supported, in seconds.
pub const MIN_FRAME_SECS: f64 = 1e-3;

/// Parameters of an [`OfficeWorkload`]. The defaults are the office of [Krajník 2017] §VI.
#[derive(Clone, Debug, PartialEq)]
pub struct OfficeConfig {
    /// Number of grid cells (default 213,000), 1 to [`MAX_CELLS`].
    pub cells: usize,
    /// Fraction of the cells whose state ever changes (default 0.05), in `[0, 1]`.
    pub dynamic_fraction: f64,
    /// Seconds between frames (default 5), at least [`MIN_FRAME_SECS`] and at most the
    /// workload's length.
    pub frame_secs: f64,
    /// Days observed (default 112), at least 1.
    pub days: u32,
    /// Time of the first frame, unix seconds (default 1,451,865,600: Monday 2016-01-04
    /// 00:00 UTC), finite and `>= 0`.
    pub start_time: f64,
    /// Seed of every random draw (default 0).
    pub seed: u64,
}

impl Default for OfficeConfig {
    fn default() -> Self {
        OfficeConfig {
            cells: 213_000,
            dynamic_fraction: 0.05,
            frame_secs: 5.0,
            days: 112,
            start_time: 1_451_865_600.0,
            seed: 0,
        }
    }
}

impl OfficeConfig {
    /// The default configuration with another seed.
    pub fn with_seed(seed: u64) -> Self {
        OfficeConfig {
            seed,
            ..OfficeConfig::default()
        }
    }

    /// Checks the configuration.
    ///
    /// # Errors
    /// [`SynthError::Config`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), SynthError> {
        fn bad(field: &'static str, value: impl ToString, expected: &'static str) -> SynthError {
            SynthError::Config {
                field,
                value: value.to_string(),
                expected,
            }
        }
        if self.cells == 0 || self.cells > MAX_CELLS {
            return Err(bad("cells", self.cells, "1 to 2^28 cells"));
        }
        if !(0.0..=1.0).contains(&self.dynamic_fraction) {
            return Err(bad(
                "dynamic_fraction",
                self.dynamic_fraction,
                "a fraction in [0, 1]",
            ));
        }
        if self.days == 0 {
            return Err(bad("days", self.days, "at least 1 day"));
        }
        let span = f64::from(self.days) * DAY_SECS;
        if !(self.frame_secs.is_finite()
            && self.frame_secs >= MIN_FRAME_SECS
            && self.frame_secs <= span)
        {
            return Err(bad(
                "frame_secs",
                self.frame_secs,
                "a finite number of seconds from 0.001 to days × 86400",
            ));
        }
        if !(self.start_time.is_finite() && self.start_time >= 0.0) {
            return Err(bad(
                "start_time",
                self.start_time,
                "finite unix seconds >= 0",
            ));
        }
        Ok(())
    }
}

/// The class of a grid cell: the kind of process that generates its occupancy.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CellClass {
    /// Always free (air).
    StaticFree,
    /// Always occupied (walls, fixed furniture).
    StaticOccupied,
    /// Occupied in a daily interval with jitter and skipped days (chair, door, table, bin).
    Periodic,
    /// Short random bursts of occupancy (people passing).
    Noise,
    /// One step change that stays (furniture moved once).
    Persistent,
}

impl CellClass {
    /// All classes, in declaration order.
    pub const ALL: [CellClass; 5] = [
        CellClass::StaticFree,
        CellClass::StaticOccupied,
        CellClass::Periodic,
        CellClass::Noise,
        CellClass::Persistent,
    ];

    /// Whether the generating process changes the cell's state.
    pub fn is_dynamic(self) -> bool {
        matches!(
            self,
            CellClass::Periodic | CellClass::Noise | CellClass::Persistent
        )
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// A seeded synthetic office: per-cell descriptors drawn from the seed, from which frames are
/// streamed ([`stream`](Self::stream)) and truths computed
/// ([`truth_probability`](Self::truth_probability)). See the [module docs](self).
#[derive(Clone, Debug)]
pub struct OfficeWorkload {
    config: OfficeConfig,
    frames: u64,
    layout: layout::Layout,
}

impl OfficeWorkload {
    /// Draws the office's layout and processes from `config.seed`.
    ///
    /// # Errors
    /// [`SynthError::Config`] if the configuration is invalid ([`OfficeConfig::validate`]).
    pub fn new(config: OfficeConfig) -> Result<Self, SynthError> {
        config.validate()?;
        let frames = (f64::from(config.days) * DAY_SECS / config.frame_secs).floor() as u64;
        let layout = layout::Layout::generate(&config);
        Ok(OfficeWorkload {
            config,
            frames,
            layout,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &OfficeConfig {
        &self.config
    }

    /// Number of grid cells.
    pub fn cells(&self) -> usize {
        self.config.cells
    }

    /// Number of frames: `⌊days × 86 400 / frame_secs⌋`.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Time of frame `frame`: `start_time + frame × frame_secs` (also for frames past the
    /// last one).
    pub fn frame_time(&self, frame: u64) -> f64 {
        self.config.start_time + frame as f64 * self.config.frame_secs
    }

    /// Streams the frames of the cells `range`, from frame 0, one frame at a time.
    ///
    /// # Errors
    /// [`SynthError::Range`] if `range.start` is not a multiple of 64, the range is reversed
    /// or it ends past the last cell.
    pub fn stream(&self, range: Range<usize>) -> Result<FrameStream<'_>, SynthError> {
        self.check_range(&range)?;
        Ok(FrameStream::new(self, range))
    }

    /// Ground truth: the probability that `cell` is occupied at time `t` under its generating
    /// process (0 or 1 for static and persistent cells); `None` if the cell does not exist or
    /// `t` is not finite.
    pub fn truth_probability(&self, cell: usize, t: f64) -> Option<f64> {
        if cell >= self.config.cells || !t.is_finite() {
            return None;
        }
        Some(self.truth(cell, t))
    }

    /// The class of `cell`; `None` if it does not exist.
    pub fn cell_class(&self, cell: usize) -> Option<CellClass> {
        self.layout.cells.get(cell).map(|c| c.class())
    }

    /// Number of cells of `class`.
    pub fn class_count(&self, class: CellClass) -> usize {
        self.layout.counts[class.index()]
    }

    fn check_range(&self, range: &Range<usize>) -> Result<(), SynthError> {
        let bad = |field, expected: String| SynthError::Range {
            field,
            start: range.start,
            end: range.end,
            expected,
        };
        if !range.start.is_multiple_of(64) {
            return Err(bad("range.start", "a multiple of 64".into()));
        }
        if range.end > self.config.cells {
            return Err(bad(
                "range.end",
                format!("at most the number of cells, {}", self.config.cells),
            ));
        }
        if range.start > range.end {
            return Err(bad("range.start", "at most range.end".into()));
        }
        Ok(())
    }

    /// The first frame taken at or after `t`, clamped to `0..=frames`.
    pub(crate) fn frame_ceil(&self, t: f64) -> u64 {
        let x = ((t - self.config.start_time) / self.config.frame_secs).ceil();
        if x <= 0.0 {
            0
        } else if x >= self.frames as f64 {
            self.frames
        } else {
            x as u64
        }
    }
}

/// The UTC calendar day of unix time `t`.
#[inline]
pub(crate) fn day_of(t: f64) -> i64 {
    (t / DAY_SECS).floor() as i64
}

/// Whether calendar day `day` (days since 1970-01-01, a Thursday) is Monday to Friday.
#[inline]
pub(crate) fn is_weekday(day: i64) -> bool {
    (day + 3).rem_euclid(7) < 5
}

#[cfg(test)]
mod tests;
