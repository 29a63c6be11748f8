//! Events in space and time (people detected at `(t, x, y)`): counts on a spatio-temporal grid
//! and models that predict them ([Krajník 2019] §V-D).
//!
//! A model of events is anything that predicts the expected number of events in every cell of
//! an [`EventGrid`] ([`EventIntensity`]); the experiment counts the test events on the same
//! grid and compares.
//!
//! ```
//! use chronomap_hypertime::events::{Event, EventGrid, EventIntensity, StaticMap, TrainingData};
//!
//! // Two detections in one cell, one in another, during 100 s of observation.
//! let train = [
//!     Event { t: 0.0, x: 0.2, y: 0.2 },
//!     Event { t: 50.0, x: 0.3, y: 0.1 },
//!     Event { t: 100.0, x: 1.5, y: 0.5 },
//! ];
//! let training = TrainingData::from_events(&train, 3600.0)?; // one window, 0..100 s
//! // Cells of 1 m, bins of 50 s: 3 bins (0, 50, 100 s) x 1 row x 2 columns.
//! let grid = EventGrid::covering(&train, 1.0, 50.0).unwrap();
//! assert_eq!(grid.count(&train), [1.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
//! let static_map = StaticMap::fit(&training, grid.spatial());
//! // 2 events / 100 s: 1 per 50-s bin in the first cell, 0.5 in the second.
//! assert_eq!(static_map.expected_counts(&grid), [1.0, 0.5, 1.0, 0.5, 1.0, 0.5]);
//! # Ok::<(), chronomap_hypertime::events::EventError>(())
//! ```
//!
//! # Layout
//! * [`Event`], [`EventGrid`] (space × time bins), [`SpatialGrid`] (space only), and the
//!   trait [`EventIntensity`] every event model implements.
//! * [`TrainingData`] — training events and the windows of time in which the robot observed
//!   ([`Window`], [`observed_windows`]): nights without data are not observed time.
//! * Baselines: [`StaticMap`], [`GlobalMean`], [`CellHistogram`], [`CellFremen`]; builders
//!   that choose their parameters on a chronological hold-out of the training data
//!   ([`EventModelBuilder`], [`default_builders`]).
//! * [`run_experiment`] — the experiment of [Krajník 2019] §V-D: MSE per cell of every model against
//!   the test counts, its reduction against the static map and a paired t-test.
//! * [`density`] — maps of the expected events per m² per hour at given times, and the
//!   extent of a set of events.

mod baselines;
pub mod density;
mod experiment;
mod training;

pub use baselines::{CellFremen, CellHistogram, GlobalMean, StaticMap};
pub use experiment::{
    Built, EventModelBuilder, EventScore, FremenBuilder, GlobalMeanBuilder, HistogramBuilder,
    StaticBuilder, default_builders, run_experiment, run_experiment_reporting,
};
pub use training::{EventError, Holdout, TrainingData, Window, observed_windows};

use chronomap_core::num::count_of;
use serde::{Deserialize, Serialize};

/// The most cells along one axis of a [`SpatialGrid::covering`] the events, and the most time
/// bins over their span (2^28): a smaller cell or bin gives `None`.
pub const MAX_COUNT: usize = 1 << 28;

/// One event: time (s) and position (m).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Event {
    /// Time in seconds (UNIX).
    pub t: f64,
    /// x in metres.
    pub x: f64,
    /// y in metres.
    pub y: f64,
}

impl Event {
    /// The first coordinate (`"t"`, `"x"`, `"y"`) that is not finite, and its value.
    pub fn non_finite(&self) -> Option<(&'static str, f64)> {
        [("t", self.t), ("x", self.x), ("y", self.y)]
            .into_iter()
            .find(|(_, value)| !value.is_finite())
    }
}

/// A regular grid of `nt` time bins × `ny` rows × `nx` columns of square cells.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EventGrid {
    /// Left edge (m).
    pub x0: f64,
    /// Bottom edge (m).
    pub y0: f64,
    /// Cell side (m).
    pub cell: f64,
    /// Columns.
    pub nx: usize,
    /// Rows.
    pub ny: usize,
    /// Start of the first time bin (s).
    pub t0: f64,
    /// Length of a time bin (s).
    pub bin_secs: f64,
    /// Time bins.
    pub nt: usize,
}

impl EventGrid {
    /// Number of cells (`nt · ny · nx`).
    pub fn len(&self) -> usize {
        self.nt * self.ny * self.nx
    }

    /// Whether the grid has no cell.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Index of cell `(bin, row, column)` in the `nt × ny × nx` row-major layout.
    pub fn index(&self, bin: usize, row: usize, column: usize) -> usize {
        (bin * self.ny + row) * self.nx + column
    }

    /// Centre `(t, x, y)` of cell `(bin, row, column)`.
    pub fn centre(&self, bin: usize, row: usize, column: usize) -> (f64, f64, f64) {
        (
            self.t0 + (bin as f64 + 0.5) * self.bin_secs,
            self.x0 + (column as f64 + 0.5) * self.cell,
            self.y0 + (row as f64 + 0.5) * self.cell,
        )
    }

    /// The cell of an event, if it falls inside the grid.
    pub fn cell_of(&self, e: &Event) -> Option<(usize, usize, usize)> {
        let bin = ((e.t - self.t0) / self.bin_secs).floor();
        let column = ((e.x - self.x0) / self.cell).floor();
        let row = ((e.y - self.y0) / self.cell).floor();
        let inside = |v: f64, n: usize| v >= 0.0 && v < n as f64;
        (inside(bin, self.nt) && inside(row, self.ny) && inside(column, self.nx)).then_some((
            bin as usize,
            row as usize,
            column as usize,
        ))
    }

    /// The grid in space only (its cells, without the time bins).
    pub fn spatial(&self) -> SpatialGrid {
        SpatialGrid {
            x0: self.x0,
            y0: self.y0,
            cell: self.cell,
            nx: self.nx,
            ny: self.ny,
        }
    }

    /// The grid over `events`: the [`SpatialGrid::covering`] of their positions, and whole
    /// time bins of `bin_secs` aligned to multiples of `bin_secs` (so to the clock: with
    /// 600 s bins they start at :00, :10, ...) from the bin of the first event to the bin of
    /// the last one. `None` if there are no events or a size is not finite and positive.
    pub fn covering(events: &[Event], cell: f64, bin_secs: f64) -> Option<EventGrid> {
        let space = SpatialGrid::covering(events, cell)?;
        let (first, last) = time_range(events)?;
        let (t0, nt) = whole_bins(first, last, bin_secs)?;
        Some(space.with_bins(t0, bin_secs, nt))
    }

    /// Counts of `events` per cell (events outside the grid are ignored).
    pub fn count(&self, events: &[Event]) -> Vec<f64> {
        let mut counts = vec![0.0; self.len()];
        for e in events {
            if let Some((b, r, c)) = self.cell_of(e) {
                counts[self.index(b, r, c)] += 1.0;
            }
        }
        counts
    }
}

/// A model that predicts how many events happen in each cell of a grid.
pub trait EventIntensity: Send + Sync {
    /// Short name for tables (e.g. `"static"`, `"hyt-em:3"`).
    fn name(&self) -> String;

    /// Expected number of events in every cell of `grid` (`nt × ny × nx`, row-major).
    fn expected_counts(&self, grid: &EventGrid) -> Vec<f64>;
}

/// A regular grid of `ny` rows × `nx` columns of square cells (an [`EventGrid`] without time).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SpatialGrid {
    /// Left edge (m).
    pub x0: f64,
    /// Bottom edge (m).
    pub y0: f64,
    /// Cell side (m).
    pub cell: f64,
    /// Columns.
    pub nx: usize,
    /// Rows.
    pub ny: usize,
}

impl SpatialGrid {
    /// Number of cells (`ny · nx`).
    pub fn len(&self) -> usize {
        self.ny * self.nx
    }

    /// Whether the grid has no cell.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The smallest grid of cells of side `cell` whose edges are multiples of `cell` and which
    /// contains every event's position. `None` if there are no events, a position is not
    /// finite, `cell` is not finite and positive, or it gives more than [`MAX_COUNT`] cells
    /// along an axis.
    ///
    /// ```
    /// use chronomap_hypertime::events::{Event, SpatialGrid};
    ///
    /// let e = |x, y| Event { t: 0.0, x, y };
    /// let g = SpatialGrid::covering(&[e(-0.7, 0.2), e(1.2, 2.0)], 0.5).unwrap();
    /// assert_eq!((g.x0, g.y0, g.nx, g.ny), (-1.0, 0.0, 5, 5));
    /// ```
    pub fn covering(events: &[Event], cell: f64) -> Option<SpatialGrid> {
        if !(cell.is_finite() && cell > 0.0) || events.is_empty() {
            return None;
        }
        let (mut x_min, mut x_max) = (f64::INFINITY, f64::NEG_INFINITY);
        let (mut y_min, mut y_max) = (f64::INFINITY, f64::NEG_INFINITY);
        for e in events {
            if !(e.x.is_finite() && e.y.is_finite()) {
                return None;
            }
            x_min = x_min.min(e.x);
            x_max = x_max.max(e.x);
            y_min = y_min.min(e.y);
            y_max = y_max.max(e.y);
        }
        let x0 = (x_min / cell).floor() * cell;
        let y0 = (y_min / cell).floor() * cell;
        // The same arithmetic as `cell_of`, so the extreme events fall inside.
        // Checked: a tiny cell must not saturate the count (and wrap the `+ 1`).
        let nx = count_of(((x_max - x0) / cell).floor() + 1.0, MAX_COUNT)?;
        let ny = count_of(((y_max - y0) / cell).floor() + 1.0, MAX_COUNT)?;
        Some(SpatialGrid {
            x0,
            y0,
            cell,
            nx,
            ny,
        })
    }

    /// Index `row · nx + column` of cell `(row, column)`.
    pub fn index(&self, row: usize, column: usize) -> usize {
        row * self.nx + column
    }

    /// The cell `(row, column)` of a position, if it falls inside the grid.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let column = ((x - self.x0) / self.cell).floor();
        let row = ((y - self.y0) / self.cell).floor();
        let inside = |v: f64, n: usize| v >= 0.0 && v < n as f64;
        (inside(row, self.ny) && inside(column, self.nx)).then_some((row as usize, column as usize))
    }

    /// Centre `(x, y)` of cell `(row, column)`.
    pub fn centre(&self, row: usize, column: usize) -> (f64, f64) {
        (
            self.x0 + (column as f64 + 0.5) * self.cell,
            self.y0 + (row as f64 + 0.5) * self.cell,
        )
    }

    /// This grid with `nt` time bins of `bin_secs` from `t0`.
    pub fn with_bins(&self, t0: f64, bin_secs: f64, nt: usize) -> EventGrid {
        EventGrid {
            x0: self.x0,
            y0: self.y0,
            cell: self.cell,
            nx: self.nx,
            ny: self.ny,
            t0,
            bin_secs,
            nt,
        }
    }

    /// For every cell of `grid` in space (`ny × nx` of `grid`, row-major), the index of the
    /// cell of this grid that contains its centre, if any. Lets a model fitted on one spatial
    /// grid answer for another.
    pub fn lookup(&self, grid: &SpatialGrid) -> Vec<Option<usize>> {
        let mut out = Vec::with_capacity(grid.len());
        for row in 0..grid.ny {
            for column in 0..grid.nx {
                let (x, y) = grid.centre(row, column);
                out.push(self.cell_of(x, y).map(|(r, c)| self.index(r, c)));
            }
        }
        out
    }
}

/// Earliest and latest time of `events` (`None` if empty or a time is not finite).
pub(crate) fn time_range(events: &[Event]) -> Option<(f64, f64)> {
    let mut range = (f64::INFINITY, f64::NEG_INFINITY);
    for e in events {
        if !e.t.is_finite() {
            return None;
        }
        range = (range.0.min(e.t), range.1.max(e.t));
    }
    (!events.is_empty()).then_some(range)
}

/// Start and number of the whole bins of `bin_secs`, aligned to multiples of `bin_secs`, that
/// cover `[first, last]` (`None` for a bin length that is not finite and positive, or that
/// gives more than [`MAX_COUNT`] bins).
pub(crate) fn whole_bins(first: f64, last: f64, bin_secs: f64) -> Option<(f64, usize)> {
    if !(bin_secs.is_finite() && bin_secs > 0.0 && first.is_finite() && last >= first) {
        return None;
    }
    let t0 = (first / bin_secs).floor() * bin_secs;
    // Checked: a tiny bin must not saturate the count (and wrap the `+ 1`).
    let nt = count_of(((last - t0) / bin_secs).floor() + 1.0, MAX_COUNT)?;
    t0.is_finite().then_some((t0, nt))
}
