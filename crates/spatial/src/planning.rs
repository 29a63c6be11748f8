//! Where a robot may drive: a grid of square cells over a region of the map, each free or
//! blocked, whose free cells form the 8-connected (Moore) graph that the
//! [least-cost search](crate::search) plans on. Used by the service-disturbance benchmark of
//! CoPA-Map ([Stüde 2024] §4.3.5) and the person search of PSBT ([Stüde 2024] §5.4, eq. 5.13).

use thiserror::Error;

use crate::ObstacleGrid;
use crate::search::{Graph, ShortestPaths, Weighted, least_cost};

/// Why a planning grid could not be built or a point of it was refused.
#[derive(Clone, Debug, PartialEq, Error)]
#[non_exhaustive]
pub enum PlanningGridError {
    /// A grid size, cell size or origin is out of range.
    #[error("invalid configuration: {0}")]
    Config(String),
    /// A waypoint lies outside the planning grid.
    #[error("waypoint ({}, {}) lies outside the planning grid", .at[0], .at[1])]
    WaypointOutside {
        /// The waypoint.
        at: [f64; 2],
    },
    /// A waypoint's cell is blocked.
    #[error(
        "waypoint ({}, {}) is in a blocked cell (an obstacle within the robot's clearance, or \
         a cell without training data)",
        .at[0], .at[1]
    )]
    WaypointBlocked {
        /// The waypoint.
        at: [f64; 2],
    },
}

/// The cells a robot may drive through: `cols × rows` square cells of `cell` metres, cell
/// (0, 0) with its lower-left corner at `origin`, indexed `row · cols + column` from the
/// bottom up.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanningGrid {
    origin: [f64; 2],
    cell: f64,
    cols: usize,
    rows: usize,
    free: Vec<bool>,
}

impl PlanningGrid {
    /// A grid of free cells.
    ///
    /// # Errors
    /// [`PlanningGridError::Config`] for no cells, a cell size that is not a positive number
    /// or a non-finite origin.
    pub fn new(
        origin: [f64; 2],
        cell: f64,
        cols: usize,
        rows: usize,
    ) -> Result<Self, PlanningGridError> {
        if !(cell.is_finite() && cell > 0.0) {
            return Err(PlanningGridError::Config(format!(
                "the cell size {cell} is not a positive number"
            )));
        }
        let Some(cells) = cols.checked_mul(rows).filter(|&n| n > 0) else {
            return Err(PlanningGridError::Config(format!(
                "a planning grid of {cols} x {rows} cells"
            )));
        };
        if !(origin[0].is_finite() && origin[1].is_finite()) {
            return Err(PlanningGridError::Config(
                "the grid origin is not finite".into(),
            ));
        }
        Ok(PlanningGrid {
            origin,
            cell,
            cols,
            rows,
            free: vec![true; cells],
        })
    }

    /// Blocks every cell whose centre has an obstacle pixel within `clearance` metres (the
    /// robot's radius): the robot's centre then keeps that distance at every cell centre. On
    /// the straight step between two neighbouring centres it may come closer by up to half a
    /// cell diagonal (`0.35 · cell`).
    pub fn block_obstacles(&mut self, obstacles: &ObstacleGrid, clearance: f64) {
        self.keep_only(|centre| !obstacles.obstacle_within(centre, clearance));
    }

    /// Blocks every free cell whose centre `keep` rejects.
    pub fn keep_only(&mut self, mut keep: impl FnMut([f64; 2]) -> bool) {
        let rejected: Vec<usize> = (0..self.free.len())
            .filter(|&i| self.free[i] && !keep(self.centre(i)))
            .collect();
        for index in rejected {
            self.free[index] = false;
        }
    }

    /// Number of cells (free or not).
    pub fn len(&self) -> usize {
        self.free.len()
    }

    /// Whether the grid has no cells (never: [`PlanningGrid::new`] refuses that).
    pub fn is_empty(&self) -> bool {
        self.free.is_empty()
    }

    /// Cells along x.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Cells along y.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The cell size in metres.
    pub fn cell_size(&self) -> f64 {
        self.cell
    }

    /// The lower-left corner of cell (0, 0).
    pub fn origin(&self) -> [f64; 2] {
        self.origin
    }

    /// Whether the robot may drive through cell `index` (false for indices beyond the grid).
    pub fn is_free(&self, index: usize) -> bool {
        self.free.get(index).copied().unwrap_or(false)
    }

    /// Number of free cells.
    pub fn free_count(&self) -> usize {
        self.free.iter().filter(|&&f| f).count()
    }

    /// The centre of cell `index`: `origin + (column + ½, row + ½) · cell`.
    pub fn centre(&self, index: usize) -> [f64; 2] {
        let (row, column) = (index / self.cols, index % self.cols);
        [
            self.origin[0] + (column as f64 + 0.5) * self.cell,
            self.origin[1] + (row as f64 + 0.5) * self.cell,
        ]
    }

    /// The cell containing `p` (cells are closed below, open above), if any.
    pub fn cell_at(&self, p: [f64; 2]) -> Option<usize> {
        let column = ((p[0] - self.origin[0]) / self.cell).floor();
        let row = ((p[1] - self.origin[1]) / self.cell).floor();
        (column >= 0.0 && row >= 0.0 && column < self.cols as f64 && row < self.rows as f64)
            .then(|| row as usize * self.cols + column as usize)
    }

    /// The free cell of a waypoint.
    ///
    /// # Errors
    /// [`PlanningGridError::WaypointOutside`] or [`PlanningGridError::WaypointBlocked`].
    pub fn waypoint(&self, at: [f64; 2]) -> Result<usize, PlanningGridError> {
        let index = self
            .cell_at(at)
            .ok_or(PlanningGridError::WaypointOutside { at })?;
        if !self.free[index] {
            return Err(PlanningGridError::WaypointBlocked { at });
        }
        Ok(index)
    }

    /// The free neighbours of cell `index` in its Moore neighbourhood with the step lengths;
    /// a diagonal neighbour only if both cells beside the diagonal are free (no cutting of
    /// corners).
    pub fn neighbours(&self, index: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let (row, column) = ((index / self.cols) as isize, (index % self.cols) as isize);
        const STEPS: [(isize, isize); 8] = [
            (1, 0),
            (-1, 0),
            (0, 1),
            (0, -1),
            (1, 1),
            (1, -1),
            (-1, 1),
            (-1, -1),
        ];
        let at = move |dc: isize, dr: isize| -> Option<usize> {
            let (c, r) = (column + dc, row + dr);
            (c >= 0 && r >= 0 && (c as usize) < self.cols && (r as usize) < self.rows)
                .then(|| r as usize * self.cols + c as usize)
                .filter(|&i| self.free[i])
        };
        STEPS.into_iter().filter_map(move |(dc, dr)| {
            let to = at(dc, dr)?;
            if dc != 0 && dr != 0 {
                at(dc, 0)?;
                at(0, dr)?;
                Some((to, self.cell * std::f64::consts::SQRT_2))
            } else {
                Some((to, self.cell))
            }
        })
    }

    /// The octile distance between two cells: the length of the shortest 8-connected path
    /// without obstacles, `cell · (max(Δx, Δy) + (√2 − 1) · min(Δx, Δy))`, a consistent A*
    /// heuristic for [`PlanningGrid::shortest_path`].
    pub fn octile(&self, a: usize, b: usize) -> f64 {
        let dx = (a % self.cols).abs_diff(b % self.cols) as f64;
        let dy = (a / self.cols).abs_diff(b / self.cols) as f64;
        self.cell * (dx.max(dy) + (std::f64::consts::SQRT_2 - 1.0) * dx.min(dy))
    }

    /// The least-cost path from cell `from` to cell `to` through free cells and its cost
    /// ([`least_cost`]): with `weights`, entering cell `v` from its neighbour `u` costs
    /// `|u − v| · weights[v]` (Dijkstra); without, the step length `|u − v|` (A* with the
    /// [octile](PlanningGrid::octile) heuristic). `None` if either cell is blocked, `weights`
    /// do not have one entry per cell, or no path joins the cells.
    pub fn shortest_path(
        &self,
        weights: Option<&[f64]>,
        from: usize,
        to: usize,
    ) -> Option<(Vec<usize>, f64)> {
        if !self.is_free(from) || !self.is_free(to) {
            return None;
        }
        let paths = match weights {
            Some(weights) => least_cost(
                &Weighted::new(self, weights)?,
                from,
                Some(to),
                |_| 0.0,
                f64::INFINITY,
            ),
            None => least_cost(self, from, Some(to), |n| self.octile(n, to), f64::INFINITY),
        }?;
        Some((paths.path_to(to)?, paths.cost(to)))
    }

    /// The shortest paths from cell `source` to every free cell at most `max_distance` metres
    /// along them (Dijkstra over step lengths). `None` if `source` is blocked.
    pub fn paths_within(&self, source: usize, max_distance: f64) -> Option<ShortestPaths> {
        if !self.is_free(source) {
            return None;
        }
        least_cost(self, source, None, |_| 0.0, max_distance)
    }
}

impl Graph for PlanningGrid {
    fn node_count(&self) -> usize {
        self.len()
    }

    fn edges(&self, node: usize) -> impl Iterator<Item = (usize, f64)> {
        self.neighbours(node)
    }
}
