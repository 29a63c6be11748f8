//! The planning grids of the benchmarks that drive a robot among people: over the cells of an
//! activity grid (the service-disturbance benchmark, [Stüde 2024] §4.3.5), and over a whole map
//! (the person search of §5.4).
//!
//! ```
//! use chronomap_activity::RateSamples;
//! use chronomap_activity::planning::{square_lattice, training_grid};
//! use chronomap_spatial::ObstacleGrid;
//!
//! // Training cells of 0.5 m centred at x = 0.25, 0.75, 1.25 and y = 0.25, 0.75.
//! let centres: Vec<[f64; 2]> =
//!     [0.25, 0.75, 1.25].iter().flat_map(|&x| [[x, 0.25], [x, 0.75]]).collect();
//! let train = RateSamples::new(centres, vec![0.0; 6], vec![1.0; 6])?;
//! let lattice = square_lattice(train.x())?;
//! assert_eq!((lattice.cell, lattice.cols, lattice.rows), (0.5, 3, 2));
//! assert_eq!(lattice.origin, [0.0, 0.0]);
//! // A map of 4 x 2 m (0.1 m pixels; beyond it counts as obstacle) with one wall pixel at
//! // (1.3, 0.3): the cell beside it is blocked with 0.3 m of clearance.
//! let mut walls = ObstacleGrid::free(40, 20, 0.1, [-1.0, -0.5])?;
//! walls.set_blocked(23, 8, true);
//! let grid = training_grid(&train, &walls, 0.3)?;
//! assert_eq!(grid.free_count(), 5);
//! assert!(grid.is_free(grid.cell_at([0.25, 0.25]).unwrap()));
//! assert!(!grid.is_free(grid.cell_at([1.25, 0.25]).unwrap()));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::collections::HashSet;

use chronomap_spatial::OccupancyMap;
use thiserror::Error;

use super::{CellKey, RateSamples};
use crate::disturbance::{ObstacleGrid, PlanningGrid};

/// Why a planning grid could not be built.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum PlanningGridError {
    /// The map cannot be planned on (rotated, or inconsistent).
    #[error(transparent)]
    Map(#[from] chronomap_spatial::InvalidMap),
    /// No cell centre at all.
    #[error("no training cell")]
    NoCells,
    /// The cell centres are not spaced alike along both axes (or one axis has a single
    /// value, so that its spacing is unknown: infinite).
    #[error(
        "the training cells do not lie on a square grid (spacing {x_step} m along x1, \
         {y_step} m along x2)"
    )]
    NotSquare {
        /// Least spacing of the distinct x1 values.
        x_step: f64,
        /// Least spacing of the distinct x2 values.
        y_step: f64,
    },
    /// Every training cell is too close to an obstacle.
    #[error("no training cell is {clearance} m away from every obstacle of the map")]
    NoFreeTrainingCell {
        /// The clearance asked for.
        clearance: f64,
    },
    /// Every cell of the map is too close to an obstacle.
    #[error("no planning cell is {clearance} m away from every obstacle")]
    NoFreeMapCell {
        /// The clearance asked for.
        clearance: f64,
    },
    /// The grid itself is invalid (no cells, a bad cell size or origin).
    #[error("{0}")]
    Grid(Box<dyn std::error::Error + Send + Sync>),
}

/// A square lattice of cell centres: `cols × rows` cells of side `cell`, cell (0, 0) with its
/// lower-left corner at `origin`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    /// Lower-left corner of the first cell (metres).
    pub origin: [f64; 2],
    /// Side of a cell (metres).
    pub cell: f64,
    /// Cells along x1.
    pub cols: usize,
    /// Cells along x2.
    pub rows: usize,
}

/// The square lattice that cell centres lie on: the least spacing of their distinct
/// coordinates along each axis, equal on both axes to a relative `1e-9`, and their bounding
/// box widened by half a cell.
///
/// # Errors
/// [`PlanningGridError::NoCells`] for no centre, [`PlanningGridError::NotSquare`] for unequal
/// spacings or an axis with one value.
pub fn square_lattice(centres: &[[f64; 2]]) -> Result<Lattice, PlanningGridError> {
    if centres.is_empty() {
        return Err(PlanningGridError::NoCells);
    }
    let spacing = |k: usize| {
        let mut v: Vec<f64> = centres.iter().map(|c| c[k]).collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        let step = v
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::INFINITY, f64::min);
        (v[0], v[v.len() - 1], step)
    };
    let (x_lo, x_hi, x_step) = spacing(0);
    let (y_lo, y_hi, y_step) = spacing(1);
    if !(x_step.is_finite() && (x_step - y_step).abs() <= 1e-9 * x_step) {
        return Err(PlanningGridError::NotSquare { x_step, y_step });
    }
    let cell = x_step;
    Ok(Lattice {
        origin: [x_lo - cell / 2.0, y_lo - cell / 2.0],
        cell,
        cols: ((x_hi - x_lo) / cell).round() as usize + 1,
        rows: ((y_hi - y_lo) / cell).round() as usize + 1,
    })
}

/// The planning grid over the cells of training rates (§4.3.5): their lattice
/// ([`square_lattice`] of the distinct cells), every cell free that is a training cell and
/// has no obstacle within `clearance` metres of its centre. Every free cell then has training
/// data, so no model falls back to a global value on the robot's way.
///
/// # Errors
/// As [`square_lattice`]; [`PlanningGridError::NoFreeTrainingCell`] when no cell is left.
pub fn training_grid(
    train: &RateSamples,
    obstacles: &ObstacleGrid,
    clearance: f64,
) -> Result<PlanningGrid, PlanningGridError> {
    let cells: HashSet<CellKey> = train.x().iter().map(|&x| CellKey::of(x)).collect();
    let centres: Vec<[f64; 2]> = cells.iter().map(|c| c.centre()).collect();
    let lattice = square_lattice(&centres)?;
    let mut grid = PlanningGrid::new(lattice.origin, lattice.cell, lattice.cols, lattice.rows)
        .map_err(|e| PlanningGridError::Grid(Box::new(e)))?;
    grid.keep_only(|c| cells.contains(&CellKey::of(c)));
    grid.block_obstacles(obstacles, clearance);
    if grid.free_count() == 0 {
        return Err(PlanningGridError::NoFreeTrainingCell { clearance });
    }
    Ok(grid)
}

/// The planning grid over a whole map (§5.4): square cells of `cell` metres from the map's
/// lower-left corner, as many as fit whole, free unless an obstacle lies within `clearance`
/// metres of the centre.
///
/// # Errors
/// [`PlanningGridError::Grid`] for a cell larger than the map or not a positive number,
/// [`PlanningGridError::NoFreeMapCell`] when no cell is left.
pub fn map_grid(
    obstacles: &ObstacleGrid,
    cell: f64,
    clearance: f64,
) -> Result<PlanningGrid, PlanningGridError> {
    let [width, height] = map_size(obstacles);
    let cols = (width / cell).floor() as usize;
    let rows = (height / cell).floor() as usize;
    let mut grid = PlanningGrid::new(obstacles.origin(), cell, cols, rows)
        .map_err(|e| PlanningGridError::Grid(Box::new(e)))?;
    grid.block_obstacles(obstacles, clearance);
    if grid.free_count() == 0 {
        return Err(PlanningGridError::NoFreeMapCell { clearance });
    }
    Ok(grid)
}

/// A whole map as a grid of planning cells ([`map_grid`]) with the map's lower-left corner and
/// size: what the service-disturbance benchmark (§4.3.5) and the person search (§5.4) plan on.
#[derive(Clone, Debug)]
pub struct MapPlanningGrid {
    /// Free planning cells of side `cell`, those nearer than `clearance` to an obstacle blocked.
    pub grid: PlanningGrid,
    /// Lower-left corner of the map (m).
    pub origin: [f64; 2],
    /// Width and height of the map (m).
    pub size: [f64; 2],
}

impl MapPlanningGrid {
    /// `map` gridded for planning: cells at least `occupied_percent` occupied, or unknown, are
    /// obstacles ([`OccupancyMap::planning_obstacles`]); planning cells of `cell` metres keep
    /// `clearance` metres from them.
    ///
    /// # Errors
    /// [`PlanningGridError::Map`] for a rotated or inconsistent map, and as [`map_grid`].
    pub fn of_map(
        map: &OccupancyMap,
        occupied_percent: i8,
        cell: f64,
        clearance: f64,
    ) -> Result<Self, PlanningGridError> {
        let obstacles = map.planning_obstacles(occupied_percent)?;
        Ok(MapPlanningGrid {
            grid: map_grid(&obstacles, cell, clearance)?,
            origin: obstacles.origin(),
            size: map_size(&obstacles),
        })
    }
}

/// Width and height of a map in metres (cells times resolution).
pub fn map_size(obstacles: &ObstacleGrid) -> [f64; 2] {
    [
        obstacles.width() as f64 * obstacles.resolution(),
        obstacles.height() as f64 * obstacles.resolution(),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(x: Vec<[f64; 2]>) -> RateSamples {
        let n = x.len();
        RateSamples::new(x, vec![0.0; n], vec![1.0; n]).unwrap()
    }

    #[test]
    fn the_lattice_of_the_training_cells_spans_their_bounding_box() {
        // Cells of 0.5 m; a gap at x = 1.25 does not change the spacing.
        let centres = [[3.75, -1.25], [4.25, -1.25], [5.25, -0.75], [3.75, 0.25]];
        let lattice = square_lattice(&centres).unwrap();
        assert_eq!(
            lattice,
            Lattice {
                origin: [3.5, -1.5],
                cell: 0.5,
                cols: 4,
                rows: 4
            }
        );
    }

    #[test]
    fn unequal_or_unknown_spacings_are_refused() {
        let error = square_lattice(&[[0.0, 0.0], [1.0, 0.0], [0.0, 0.5]]).unwrap_err();
        assert_eq!(
            error.to_string(),
            "the training cells do not lie on a square grid (spacing 1 m along x1, 0.5 m \
             along x2)"
        );
        // One row: the spacing along x2 is unknown.
        assert!(matches!(
            square_lattice(&[[0.0, 0.0], [1.0, 0.0]]),
            Err(PlanningGridError::NotSquare { y_step, .. }) if y_step == f64::INFINITY
        ));
        assert!(matches!(
            square_lattice(&[]),
            Err(PlanningGridError::NoCells)
        ));
    }

    #[test]
    fn only_training_cells_away_from_obstacles_are_free() {
        // A 3 x 2 lattice of 1 m cells with one cell missing from the training data.
        let train = samples(vec![
            [0.5, 0.5],
            [1.5, 0.5],
            [2.5, 0.5],
            [0.5, 1.5],
            [2.5, 1.5],
        ]);
        let free = ObstacleGrid::free(30, 20, 0.1, [0.0, 0.0]).unwrap();
        let grid = training_grid(&train, &free, 0.3).unwrap();
        assert_eq!((grid.cols(), grid.rows(), grid.free_count()), (3, 2, 5));
        assert!(!grid.is_free(grid.cell_at([1.5, 1.5]).unwrap()));
        // Walls everywhere: nothing is left.
        let mut walls = free.clone();
        walls.block_rectangle([0.0, 0.0], [3.0, 2.0]);
        assert_eq!(
            training_grid(&train, &walls, 0.3).unwrap_err().to_string(),
            "no training cell is 0.3 m away from every obstacle of the map"
        );
    }

    #[test]
    fn the_map_grid_has_the_whole_cells_that_fit() {
        // A 2.05 x 1 m map: four whole 0.5 m cells across, two up.
        let mut map = ObstacleGrid::free(41, 20, 0.05, [-1.0, 2.0]).unwrap();
        assert_eq!(map_size(&map)[1], 1.0);
        let grid = map_grid(&map, 0.5, 0.0).unwrap();
        assert_eq!(
            (grid.cols(), grid.rows(), grid.origin()),
            (4, 2, [-1.0, 2.0])
        );
        assert_eq!(grid.free_count(), 8);
        map.block_rectangle([-1.0, 2.0], [1.05, 3.0]);
        assert_eq!(
            map_grid(&map, 0.5, 0.3).unwrap_err().to_string(),
            "no planning cell is 0.3 m away from every obstacle"
        );
        assert!(matches!(
            map_grid(&map, 5.0, 0.3),
            Err(PlanningGridError::Grid(_))
        ));
    }
}
