//! Ground truth for activity models ([Stüde 2024] §4.3.2): how many people were in each cell
//! during each time bin, counted over the whole bin (`Δ_i = τ`, no field of view, no
//! occupancy map), in the cells a model was trained on.
//!
//! The people count `c_i` of a cell and bin is the number of **distinct people** detected in
//! it. Counting detections instead would make a person who stands in a queue for an hour
//! weigh as much as thousands of passers-by; on the bundled ATC day (2012-10-24), counting
//! distinct people gives a ground truth on which the global mean of the bundled training grid
//! scores NRMSE 1.385, close to the 1.36 reported for the original's kept-back test days,
//! while counting 1 Hz detections gives 2.72.
//!
//! ```
//! use chronomap_activity::truth::{TrackPoint, TruthGrid, person_counts};
//!
//! let grid = TruthGrid { cell: 0.5, t0: 0.0, bin: 3600.0, t_offset: 0.0 };
//! // Person 7 walks through cell (0.25, 0.25) twice in bin 0; person 8 once; bin 1 is empty.
//! let points = [
//!     TrackPoint { t: 10.0, person: 7, x: 0.1, y: 0.2 },
//!     TrackPoint { t: 11.0, person: 7, x: 0.3, y: 0.2 },
//!     TrackPoint { t: 900.0, person: 8, x: 0.4, y: 0.4 },
//!     TrackPoint { t: 901.0, person: 8, x: 0.6, y: 0.4 }, // another cell
//! ];
//! let truth = person_counts(&points, &[[0.25, 0.25]], &[0, 1], &grid)?;
//! assert_eq!(truth.t(), [0.0, 1.0]);
//! assert_eq!(truth.y(), [2.0, 0.0]); // people per hour
//! # Ok::<(), chronomap_activity::ActivityError>(())
//! ```

use std::collections::{HashMap, HashSet};

use chronomap_core::num::fmt_number;

use super::{ActivityError, CellKey, RateSamples};

/// The largest magnitude of a cell or bin index (2^53, exact as an `f64`).
const MAX_INDEX: f64 = 9_007_199_254_740_992.0;

/// One detection of a tracked person: time (seconds), the person's id, position (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackPoint {
    /// Time in seconds (unix time in the ATC data).
    pub t: f64,
    /// Id of the tracked person.
    pub person: u64,
    /// x in metres (map frame).
    pub x: f64,
    /// y in metres (map frame).
    pub y: f64,
}

/// The spatio-temporal grid of the ground truth: square cells of side `cell` aligned to
/// multiples of `cell` (cell `k` spans `[k·cell, (k+1)·cell)`, centre `(k + ½)·cell`), and time
/// bins of `bin` seconds from `t0` (bin `b` spans `[t0 + b·bin, t0 + (b+1)·bin)`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruthGrid {
    /// Side of a cell in metres (0.5 in the ATC grid).
    pub cell: f64,
    /// Start of bin 0, in the time unit of the detections (seconds).
    pub t0: f64,
    /// Length `τ` of a bin in seconds (3600 in the ATC grid).
    pub bin: f64,
    /// Added to the bin index to give the `t` of the samples (e.g. 120 to place a day after
    /// the ten days of the ATC training grid, whose `t` runs 0..119).
    pub t_offset: f64,
}

/// The ground truth of §4.3.2 at `cells × bins`: for every cell centre in `cells` and every
/// bin index in `bins` (in that order: all cells of the first bin, then the next bin), the
/// number of distinct people detected in the cell during the bin, per hour
/// (`c_i / τ` with `τ` in hours). Cells and bins without anybody get rate 0.
///
/// # Errors
/// [`ActivityError::Config`] if `cell` or `bin` is not a positive finite number, or `t0` or
/// `t_offset` is not finite; [`ActivityError::NonFinite`] if a cell centre or a detection is
/// not finite.
pub fn person_counts(
    points: &[TrackPoint],
    cells: &[[f64; 2]],
    bins: &[i64],
    grid: &TruthGrid,
) -> Result<RateSamples, ActivityError> {
    let valid = grid.cell > 0.0
        && grid.cell.is_finite()
        && grid.bin > 0.0
        && grid.bin.is_finite()
        && grid.t0.is_finite()
        && grid.t_offset.is_finite();
    if !valid {
        return Err(ActivityError::Config(format!(
            "ground-truth grid {grid:?}: cell and bin must be positive, t0 and t_offset finite"
        )));
    }
    // Cell and bin indices are integer keys and must be exact (|i| ≤ 2^53); `as i64` would
    // saturate far-away values into one shared key. A detection whose index is out of that
    // range cannot be in a wanted cell or bin, which are checked to be in it.
    let exact = |v: f64| {
        let i = v.floor();
        (i.abs() <= MAX_INDEX).then_some(i as i64)
    };
    let index = |v: f64| exact(v / grid.cell);
    let mut wanted: HashMap<(i64, i64), CellKey> = HashMap::with_capacity(cells.len());
    for (i, &c) in cells.iter().enumerate() {
        let (Some(x), Some(y)) = (index(c[0]), index(c[1])) else {
            return Err(ActivityError::Config(format!(
                "cell {i} at ({}, {}) is more than 2^53 cells of {} m from the origin",
                fmt_number(c[0]),
                fmt_number(c[1]),
                fmt_number(grid.cell)
            )));
        };
        wanted.insert((x, y), CellKey::of(c));
    }
    let bin_set: HashSet<i64> = bins.iter().copied().collect();
    let mut people: HashMap<(i64, CellKey), HashSet<u64>> = HashMap::new();
    for (i, p) in points.iter().enumerate() {
        for (field, value) in [("t", p.t), ("x1", p.x), ("x2", p.y)] {
            if !value.is_finite() {
                return Err(ActivityError::NonFinite {
                    index: i,
                    field,
                    value,
                });
            }
        }
        let Some(b) = exact((p.t - grid.t0) / grid.bin) else {
            continue;
        };
        if !bin_set.contains(&b) {
            continue;
        }
        let (Some(x), Some(y)) = (index(p.x), index(p.y)) else {
            continue;
        };
        if let Some(&key) = wanted.get(&(x, y)) {
            people.entry((b, key)).or_default().insert(p.person);
        }
    }
    let hours = grid.bin / 3600.0;
    let mut out = RateSamples::default();
    for &b in bins {
        for &c in cells {
            let count = people.get(&(b, CellKey::of(c))).map_or(0, HashSet::len);
            out.push(c, b as f64 + grid.t_offset, count as f64 / hours)?;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> TruthGrid {
        TruthGrid {
            cell: 0.5,
            t0: 100.0,
            bin: 1800.0,
            t_offset: 10.0,
        }
    }

    #[test]
    fn counts_distinct_people_per_cell_and_bin_per_hour() {
        let p = |t, person, x, y| TrackPoint { t, person, x, y };
        let points = [
            p(100.0, 1, -0.1, -0.1), // cell (-0.25, -0.25), bin 0
            p(101.0, 1, -0.2, -0.3), // same person again
            p(102.0, 2, -0.4, -0.01),
            p(1899.9, 3, -0.49, -0.49), // still bin 0
            p(1900.0, 3, -0.49, -0.49), // bin 1
            p(99.0, 4, -0.1, -0.1),     // before t0: bin -1, not asked for
            p(500.0, 5, 0.1, -0.1),     // another cell
        ];
        let cells = [[-0.25, -0.25], [0.25, -0.25], [5.25, 5.25]];
        let truth = person_counts(&points, &cells, &[0, 1], &grid()).unwrap();
        assert_eq!(truth.t(), [10.0, 10.0, 10.0, 11.0, 11.0, 11.0]);
        // 30-minute bins: a count of 3 is 6 people per hour.
        assert_eq!(truth.y(), [6.0, 2.0, 0.0, 2.0, 0.0, 0.0]);
        assert_eq!(truth.x()[1], [0.25, -0.25]);
    }

    #[test]
    fn rejects_bad_grids_and_points() {
        let bad = TruthGrid {
            cell: 0.0,
            ..grid()
        };
        assert!(matches!(
            person_counts(&[], &[[0.25, 0.25]], &[0], &bad),
            Err(ActivityError::Config(_))
        ));
        let nan = [TrackPoint {
            t: 1.0,
            person: 1,
            x: f64::NAN,
            y: 0.0,
        }];
        assert!(matches!(
            person_counts(&nan, &[[0.25, 0.25]], &[0], &grid()),
            Err(ActivityError::NonFinite { field: "x1", .. })
        ));
    }
}
