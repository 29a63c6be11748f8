//! Events in space and time (people detected at `(t, x, y)`): counts on a spatio-temporal grid
//! and models that predict them (seed 004 §V-D).
//!
//! A model of events is anything that predicts the expected number of events in every cell of
//! an [`EventGrid`] ([`EventIntensity`]); the experiment counts the test events on the same
//! grid and compares.

use serde::{Deserialize, Serialize};

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
        (inside(bin, self.nt) && inside(row, self.ny) && inside(column, self.nx))
            .then(|| (bin as usize, row as usize, column as usize))
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
