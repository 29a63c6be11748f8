//! Geometric search paths `𝔾`, `l_sp` of eq. 5.13: A* on the 8-connected planning grid (the
//! [`PlanningGrid`] of the disturbance benchmark, whose weighted Dijkstra is the oracle of the
//! tests), and a bounded Dijkstra tree from the help location, which gives every place's path
//! and distance back to it in one pass. Both are `chronomap_spatial`'s one least-cost search.

use chronomap_core::num::count_of;
use chronomap_spatial::PlanningGrid;
use chronomap_spatial::search::ShortestPaths;

use crate::PsbtError;

/// The most points [`sample_cells`] gives along one path.
pub const MAX_SAMPLES: usize = 1 << 24;

/// A path through free cells and its length in metres (centre to centre).
#[derive(Clone, Debug, PartialEq)]
pub struct CellPath {
    /// The cells from start to goal, both included.
    pub cells: Vec<usize>,
    /// Length in metres.
    pub length: f64,
}

impl CellPath {
    /// The same path driven the other way.
    pub fn reversed(&self) -> CellPath {
        let mut cells = self.cells.clone();
        cells.reverse();
        CellPath {
            cells,
            length: self.length,
        }
    }
}

/// The shortest path from cell `from` to cell `to` through free cells (8-connected, no
/// corner cutting, steps of `cell` and `cell·√2`), by A* with the octile heuristic
/// ([`PlanningGrid::shortest_path`] without weights). `None` if either cell is blocked or they
/// are not connected.
///
/// # Complexity
/// `O(E log E)` for the `E` cells expanded, at most the free cells of the grid.
pub fn astar(grid: &PlanningGrid, from: usize, to: usize) -> Option<CellPath> {
    let (cells, length) = grid.shortest_path(None, from, to)?;
    Some(CellPath { cells, length })
}

/// Shortest distances from one cell to every free cell within a bound, and the tree of
/// shortest paths (Dijkstra, the same moves as [`astar`]: [`PlanningGrid::paths_within`]).
#[derive(Clone, Debug)]
pub struct DistanceTree(ShortestPaths);

impl DistanceTree {
    /// Dijkstra from `source`, settling the cells up to `max_distance` metres away.
    /// Returns `None` if `source` is blocked.
    pub fn new(grid: &PlanningGrid, source: usize, max_distance: f64) -> Option<Self> {
        grid.paths_within(source, max_distance).map(DistanceTree)
    }

    /// The source cell.
    pub fn source(&self) -> usize {
        self.0.source()
    }

    /// Distance in metres to `cell` (infinite beyond the bound or unreachable).
    pub fn distance(&self, cell: usize) -> f64 {
        self.0.cost(cell)
    }

    /// The cells within the bound, the source included, in index order.
    pub fn reached(&self) -> impl Iterator<Item = usize> + '_ {
        self.0.reached()
    }

    /// The shortest path from the source to `cell`, if it is within the bound.
    pub fn path_to(&self, cell: usize) -> Option<CellPath> {
        let cells = self.0.path_to(cell)?;
        Some(CellPath {
            cells,
            length: self.distance(cell),
        })
    }
}

/// Points along a path every `spacing` metres from its start (`⌊l/spacing⌋ + 1` points), each
/// given as the path cell nearest to it: the positions `x(t_k)` of the robot at
/// `t_k = k Δt` when it drives at `v̄` and `spacing = v̄ Δt` (eq. 5.14).
///
/// # Errors
/// [`PsbtError::TooMany`] for more than [`MAX_SAMPLES`] points (a spacing far smaller than
/// the path).
pub fn sample_cells(
    grid: &PlanningGrid,
    path: &CellPath,
    spacing: f64,
) -> Result<Vec<usize>, PsbtError> {
    let cells = &path.cells;
    if cells.len() <= 1 || spacing.is_nan() || spacing <= 0.0 {
        return Ok(cells.first().copied().into_iter().collect());
    }
    let points = (path.length / spacing + 1e-9).floor() + 1.0;
    let count = count_of(points, MAX_SAMPLES).ok_or(PsbtError::TooMany {
        parameter: "sample spacing (speed x time step)",
        value: spacing,
        what: "points along the path",
        count: points,
        limit: MAX_SAMPLES,
    })?;
    let mut out = Vec::with_capacity(count);
    let (mut segment, mut start_of_segment) = (0usize, 0.0f64);
    let length_of = |i: usize| {
        let (a, b) = (grid.centre(cells[i]), grid.centre(cells[i + 1]));
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
    };
    let mut current = length_of(0);
    for k in 0..count {
        let s = k as f64 * spacing;
        while segment + 2 < cells.len() && s > start_of_segment + current {
            start_of_segment += current;
            segment += 1;
            current = length_of(segment);
        }
        let along = s - start_of_segment;
        out.push(if along <= current / 2.0 {
            cells[segment]
        } else {
            cells[segment + 1]
        });
    }
    Ok(out)
}
