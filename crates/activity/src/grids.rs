//! The cells and time bins the activity commands work on: the distinct cells of a rate grid,
//! checked to be aligned to a cell size (the ground truth of §4.3.2 counts people in such
//! cells), a lattice of cells over a rectangular region (where a fitted CoPA-Map is
//! queried), and the time bins that hold detections (what the training-sample extraction of
//! §4.2.2 simulates).
//!
//! ```
//! use chronomap_activity::grids::RegionGrid;
//!
//! // A region of 2 x 1 m in cells of 0.5 m: 4 x 2 cells, centres listed from the top row down.
//! let grid = RegionGrid::new([0.0, 0.0], [2.0, 1.0], 0.5)?;
//! assert_eq!((grid.cols, grid.rows), (4, 2));
//! let centres = grid.centres();
//! assert_eq!(centres[0], [0.25, 0.75]);
//! assert_eq!(centres[7], [1.75, 0.25]);
//! # Ok::<(), chronomap_activity::grids::GridError>(())
//! ```

use std::collections::HashSet;

use chronomap_core::num::{count_of, fmt_number};
use chronomap_hypertime::events::Event;
use thiserror::Error;

use super::{CellKey, RateSamples};

/// Why cells or a region do not make a grid.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum GridError {
    /// A cell centre that is not the centre of a cell aligned to multiples of the side.
    #[error(
        "cell centre ({}, {}) is not the centre of a {side} m cell aligned to multiples of \
         {side} m", .centre[0], .centre[1]
    )]
    Misaligned {
        /// The centre.
        centre: [f64; 2],
        /// The side of a cell.
        side: f64,
    },
    /// A region that is not finite, or empty.
    #[error(
        "{},{},{},{}: needs finite x_min < x_max and y_min < y_max",
        .min[0], .min[1], .max[0], .max[1]
    )]
    EmptyRegion {
        /// Lower-left corner.
        min: [f64; 2],
        /// Upper-right corner.
        max: [f64; 2],
    },
    /// A cell side that is not a positive number.
    #[error("cell side {0} is not a positive number")]
    CellSize(f64),
    /// A region and cell side that give more than [`MAX_REGION_CELLS`] cells.
    #[error(
        "cells of {} m over the region give {} x {} cells; at most {} in all",
        fmt_number(.cell), fmt_number(.cols), fmt_number(.rows), MAX_REGION_CELLS
    )]
    TooManyCells {
        /// The cell side.
        cell: f64,
        /// Cells along x1 (may be infinite).
        cols: f64,
        /// Cells along x2 (may be infinite).
        rows: f64,
    },
}

/// The most cells of a [`RegionGrid`] (2²⁸).
pub const MAX_REGION_CELLS: usize = 1 << 28;

/// The distinct cell centres of `samples`, sorted by x1, then x2.
pub fn distinct_cells(samples: &RateSamples) -> Vec<[f64; 2]> {
    let keys: HashSet<CellKey> = samples.x().iter().map(|&x| CellKey::of(x)).collect();
    let mut cells: Vec<[f64; 2]> = keys.into_iter().map(CellKey::centre).collect();
    cells.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    cells
}

/// Checks that every centre is the centre of a cell of `side` metres aligned to multiples of
/// `side` (within `1e-9` cells).
///
/// # Errors
/// [`GridError::Misaligned`] naming the first centre that is not.
pub fn check_aligned(cells: &[[f64; 2]], side: f64) -> Result<(), GridError> {
    for c in cells {
        for v in c {
            let k = v / side - 0.5;
            if (k - k.round()).abs() > 1e-9 {
                return Err(GridError::Misaligned { centre: *c, side });
            }
        }
    }
    Ok(())
}

/// A lattice of square cells over a region, listed row by row from the top (`max[1]`) down,
/// left to right, as images are drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionGrid {
    /// Lower-left corner of the region.
    pub min: [f64; 2],
    /// Upper-right corner of the region.
    pub max: [f64; 2],
    /// Side of a cell.
    pub cell: f64,
    /// Cells along x1 (the last may reach past `max[0]`).
    pub cols: usize,
    /// Cells along x2 (the last may reach below `min[1]`).
    pub rows: usize,
}

impl RegionGrid {
    /// The cells of `cell` metres covering `[min, max]`.
    ///
    /// # Errors
    /// [`GridError::EmptyRegion`] for a non-finite or empty region, [`GridError::CellSize`]
    /// for a cell that is not a positive number, [`GridError::TooManyCells`] for more than
    /// [`MAX_REGION_CELLS`] cells.
    pub fn new(min: [f64; 2], max: [f64; 2], cell: f64) -> Result<Self, GridError> {
        if !(cell.is_finite() && cell > 0.0) {
            return Err(GridError::CellSize(cell));
        }
        if !(min.iter().chain(&max).all(|v| v.is_finite()) && max[0] > min[0] && max[1] > min[1]) {
            return Err(GridError::EmptyRegion { min, max });
        }
        let (cols, rows) = (
            ((max[0] - min[0]) / cell).ceil(),
            ((max[1] - min[1]) / cell).ceil(),
        );
        let too_many = GridError::TooManyCells { cell, cols, rows };
        let across = |n: f64| count_of(n, MAX_REGION_CELLS).ok_or(too_many.clone());
        let (cols, rows) = (across(cols)?, across(rows)?);
        if cols.saturating_mul(rows) > MAX_REGION_CELLS {
            return Err(too_many);
        }
        Ok(RegionGrid {
            min,
            max,
            cell,
            cols,
            rows,
        })
    }

    /// The region a model trained on cell centres spanning `domain` (`[x_min, y_min, x_max,
    /// y_max]`) covers with cells of `cell` metres: the domain widened by half a cell to the
    /// cell edges.
    ///
    /// # Errors
    /// As [`RegionGrid::new`].
    pub fn around_centres(domain: [f64; 4], cell: f64) -> Result<Self, GridError> {
        let h = cell / 2.0;
        RegionGrid::new(
            [domain[0] - h, domain[1] - h],
            [domain[2] + h, domain[3] + h],
            cell,
        )
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.cols * self.rows
    }

    /// Whether the grid has no cell (never, for a grid from [`RegionGrid::new`]).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The cell centres, row by row from the top.
    pub fn centres(&self) -> Vec<[f64; 2]> {
        let mut centres = Vec::with_capacity(self.len());
        for r in 0..self.rows {
            for c in 0..self.cols {
                centres.push([
                    self.min[0] + (c as f64 + 0.5) * self.cell,
                    self.max[1] - (r as f64 + 0.5) * self.cell,
                ]);
            }
        }
        centres
    }
}

/// Every time bin (of `bin` seconds from `t0`) with a detection, in order, for detections
/// sorted by time (as the track readers return them): the bins the extraction simulates by
/// default, so that an hour missing from the data is not read as an empty hour.
///
/// ```
/// use chronomap_activity::grids::detection_bins;
/// use chronomap_hypertime::events::Event;
///
/// let at = |t: f64| Event { t, x: 0.0, y: 0.0 };
/// assert_eq!(detection_bins(&[at(10.0), at(20.0), at(7300.0)], 0.0, 3600.0), [0, 2]);
/// ```
pub fn detection_bins(detections: &[Event], t0: f64, bin: f64) -> Vec<i64> {
    let mut bins: Vec<i64> = detections
        .iter()
        .map(|d| ((d.t - t0) / bin).floor() as i64)
        .collect();
    bins.dedup();
    bins
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distinct_cells_are_sorted_and_checked_against_the_cell_size() {
        let samples = RateSamples::new(
            vec![[0.75, 0.25], [0.25, 0.75], [0.25, 0.25], [0.75, 0.25]],
            vec![0.0, 0.0, 1.0, 1.0],
            vec![1.0; 4],
        )
        .unwrap();
        let cells = distinct_cells(&samples);
        assert_eq!(cells, [[0.25, 0.25], [0.25, 0.75], [0.75, 0.25]]);
        assert_eq!(check_aligned(&cells, 0.5), Ok(()));
        assert_eq!(
            check_aligned(&cells, 1.0).unwrap_err().to_string(),
            "cell centre (0.25, 0.25) is not the centre of a 1 m cell aligned to multiples of 1 m"
        );
        assert!(check_aligned(&[[-1.25, 3.75]], 0.5).is_ok());
    }

    #[test]
    fn a_region_is_covered_by_whole_cells() {
        // The bundled ATC square: centres 3.75 .. 27.75 in 0.5 m cells: 49 x 49 cells.
        let grid = RegionGrid::around_centres([3.75, -20.25, 27.75, 3.75], 0.5).unwrap();
        assert_eq!((grid.cols, grid.rows, grid.len()), (49, 49, 2401));
        assert_eq!(grid.centres()[0], [3.75, 3.75]);
        // A region not a multiple of the cell: the last column reaches past it.
        let grid = RegionGrid::new([0.0, 0.0], [1.2, 0.5], 0.5).unwrap();
        assert_eq!((grid.cols, grid.rows), (3, 1));
        assert_eq!(grid.centres()[2], [1.25, 0.25]);
        assert_eq!(
            RegionGrid::new([0.0, 0.0], [-1.0, 1.0], 0.5)
                .unwrap_err()
                .to_string(),
            "0,0,-1,1: needs finite x_min < x_max and y_min < y_max"
        );
        assert!(matches!(
            RegionGrid::new([0.0, 0.0], [1.0, f64::NAN], 0.5),
            Err(GridError::EmptyRegion { .. })
        ));
        assert_eq!(
            RegionGrid::new([0.0, 0.0], [1.0, 1.0], 0.0),
            Err(GridError::CellSize(0.0))
        );
    }

    #[test]
    fn bins_with_detections_in_order() {
        let at = |t: f64| Event { t, x: 0.0, y: 0.0 };
        let d = [at(-1.0), at(0.0), at(3599.0), at(3600.0), at(9000.0)];
        assert_eq!(detection_bins(&d, 0.0, 3600.0), [-1, 0, 1, 2]);
        assert_eq!(detection_bins(&d, 100.0, 3600.0), [-1, 0, 2]);
        assert!(detection_bins(&[], 0.0, 3600.0).is_empty());
    }
}
