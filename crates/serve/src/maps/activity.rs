//! A CoPA-Map ([Stüde 2024] §4.2) as the service holds it, with the Nav2 map whose walls
//! mask it, and its prediction over a grid of cells: the cells and values of
//! `chronomap activity predict --model M --t T --cell C [--map MAP]`.

use std::fmt;

use chronomap_activity::CopaMap;
use chronomap_activity::grids::RegionGrid;
use chronomap_core::Parallelism;
use chronomap_core::observe::MAX_TIME_SECS;
use chronomap_spatial::OccupancyMap;

/// Side of a cell when a request gives none (m): the default of `chronomap activity predict`.
pub const DEFAULT_CELL: f64 = 0.5;

/// Most cells of one prediction, checked from the model's domain and the side asked for
/// before anything is computed.
pub const MAX_ACTIVITY_CELLS: usize = 250_000;

/// Most work of one prediction: cells × inducing points², counted before anything is
/// computed. A cell's prediction solves with and multiplies by the `M × M` factors of both
/// latent GPs of the model ([`CopaMap::inducing_points`] `M`), so its cost grows with `M²`:
/// on one thread about 7.6 µs a cell with 10 inducing points, 20 µs with 50 and 194 µs with
/// 200. At this bound a 200-point model predicts 25,000 cells (about 5 s), a 100-point one
/// 100,000 and a model of up to 63 points the 250,000 cells of [`MAX_ACTIVITY_CELLS`].
pub const MAX_ACTIVITY_WORK: u64 = 1_000_000_000;

/// Points predicted between two checks whether the client went away: a multiple of the 1024
/// points the model predicts at once, so that the chunks give the bits of one call.
pub const PREDICT_CHUNK: usize = 4096;

/// A predicted cell is masked when its centre lies on a map cell at least this occupied
/// (percent), as `chronomap activity predict --map` leaves it out
/// (`OccupancyMap::is_occupied_at`; unknown cells and centres outside the map are not masked).
pub use chronomap_spatial::occupancy::WALL_PERCENT;

/// What `t` is, as `GET /v1/activity/{name}` says.
pub const TIME_UNIT: &str = "time bins of the training grid (t = k is the bin [t0 + k·τ, \
    t0 + (k+1)·τ) of chronomap activity extract)";

/// Why a prediction was refused; each names the request field at fault.
#[derive(Clone, Debug, PartialEq)]
pub enum ActivityError {
    /// `t` is not finite or beyond ±[`MAX_TIME_SECS`].
    Time(f64),
    /// `cell` is not a positive number of metres.
    Cell(f64),
    /// The cells of that size are too many.
    TooManyCells {
        /// The side asked for.
        cell: f64,
        /// Columns of that side over the model's domain (may be beyond any integer).
        cols: f64,
        /// Rows, likewise.
        rows: f64,
    },
    /// The cells of that size are too much work for the model's inducing points
    /// ([`MAX_ACTIVITY_WORK`]).
    TooMuchWork {
        /// The side asked for.
        cell: f64,
        /// Cells of that side.
        cells: u64,
        /// The model's inducing points.
        inducing: u64,
    },
    /// The model cannot predict (a model file that passed its checks should not get here).
    Model(String),
    /// The request was given up (its client went away) before the prediction was done.
    Cancelled,
}

impl fmt::Display for ActivityError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ActivityError::Time(t) => write!(
                f,
                "field `t`: {t} is not a finite number within ±{MAX_TIME_SECS:e}"
            ),
            ActivityError::Cell(c) => write!(
                f,
                "field `cell`: {} is not a positive number of metres",
                number(*c)
            ),
            ActivityError::TooManyCells { cell, cols, rows } => write!(
                f,
                "field `cell`: cells of {} m give {} × {} cells over the model's domain, \
                 more than {MAX_ACTIVITY_CELLS}; ask for larger cells",
                number(*cell),
                number(*cols),
                number(*rows)
            ),
            ActivityError::TooMuchWork {
                cell,
                cells,
                inducing,
            } => write!(
                f,
                "field `cell`: cells of {} m give {cells} cells; with the model's {inducing} \
                 inducing points that is {} units of work (cells × inducing points²), more \
                 than {MAX_ACTIVITY_WORK}; ask for larger cells",
                number(*cell),
                work(*cells, *inducing)
            ),
            ActivityError::Model(reason) => write!(f, "the model cannot predict: {reason}"),
            ActivityError::Cancelled => write!(f, "the prediction was given up"),
        }
    }
}

impl std::error::Error for ActivityError {}

/// `x` as Rust writes it between 0.001 and 10^15, else in scientific notation (`1e-300`, not
/// three hundred zeros).
fn number(x: f64) -> String {
    if x == 0.0 || (1e-3..1e15).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// The work of predicting `cells` cells with `inducing` inducing points: cells × inducing².
fn work(cells: u64, inducing: u64) -> u64 {
    cells.saturating_mul(inducing.saturating_mul(inducing))
}

/// The prediction over a grid of cells (row 0 at the bottom).
#[derive(Clone, Debug, PartialEq)]
pub struct ActivityGrid {
    /// Lower-left corner of cell (0, 0) (m).
    pub origin: [f64; 2],
    /// Side of a cell (m).
    pub cell: f64,
    /// Columns (along x).
    pub cols: usize,
    /// Rows (along y).
    pub rows: usize,
    /// Mean rate of cell `(col, row)` at `col + cols·row`; `None` on walls.
    pub mean: Vec<Option<f64>>,
    /// Its standard deviation, likewise.
    pub std: Vec<Option<f64>>,
}

/// A CoPA-Map served read-only.
#[derive(Debug)]
pub struct ServedActivity {
    model: CopaMap,
    map: Option<OccupancyMap>,
}

impl ServedActivity {
    /// Serves `model`, masked by the walls of `map` if given.
    pub fn new(model: CopaMap, map: Option<OccupancyMap>) -> Self {
        ServedActivity { model, map }
    }

    /// The model.
    pub fn model(&self) -> &CopaMap {
        &self.model
    }

    /// Whether a map masks the predictions.
    pub fn masked(&self) -> bool {
        self.map.is_some()
    }

    /// The cells of `cell` metres covering the training square, as `chronomap activity
    /// predict` takes them by default (`RegionGrid::around_centres` of the model's domain).
    ///
    /// # Errors
    /// [`ActivityError::Cell`] for a side that is not a positive number,
    /// [`ActivityError::TooManyCells`] for more than [`MAX_ACTIVITY_CELLS`] (counted before any
    /// integer or allocation is made of them).
    pub fn region(&self, cell: f64) -> Result<RegionGrid, ActivityError> {
        if !(cell.is_finite() && cell > 0.0) {
            return Err(ActivityError::Cell(cell));
        }
        let [x0, y0, x1, y1] = self.model.domain();
        // The domain widened by half a cell each side, in cells (as `around_centres` counts).
        let (cols, rows) = (
            ((x1 - x0) / cell + 1.0).ceil(),
            ((y1 - y0) / cell + 1.0).ceil(),
        );
        let cells = cols * rows;
        if cells.is_nan() || cells > MAX_ACTIVITY_CELLS as f64 {
            return Err(ActivityError::TooManyCells { cell, cols, rows });
        }
        let grid = RegionGrid::around_centres(self.model.domain(), cell)
            .map_err(|e| ActivityError::Model(format!("the model's domain {e}")))?;
        if grid.len() > MAX_ACTIVITY_CELLS {
            return Err(ActivityError::TooManyCells {
                cell,
                cols: grid.cols as f64,
                rows: grid.rows as f64,
            });
        }
        Ok(grid)
    }

    /// The cells of `cell` metres covering the training square ([`ServedActivity::region`]),
    /// if predicting them is at most [`MAX_ACTIVITY_WORK`] for the model's inducing points.
    ///
    /// # Errors
    /// As [`ServedActivity::region`], and [`ActivityError::TooMuchWork`].
    pub fn checked_region(&self, cell: f64) -> Result<RegionGrid, ActivityError> {
        let grid = self.region(cell)?;
        let (cells, inducing) = (grid.len() as u64, self.model.inducing_points() as u64);
        if work(cells, inducing) > MAX_ACTIVITY_WORK {
            return Err(ActivityError::TooMuchWork {
                cell,
                cells,
                inducing,
            });
        }
        Ok(grid)
    }

    /// Mean and standard deviation of the rate at `t` in every cell of `cell` metres over the
    /// training square: the values `chronomap activity predict` computes for the same model,
    /// `t` and cell (same cells, same call, bit for bit), with the cells its `--map` leaves
    /// out as `None`. The library lists cells from the top row; here row 0 is the bottom one.
    ///
    /// # Errors
    /// A `t` that is not finite or beyond ±[`MAX_TIME_SECS`], a bad `cell`, more than
    /// [`MAX_ACTIVITY_CELLS`] cells or [`MAX_ACTIVITY_WORK`].
    pub fn predict(&self, t: f64, cell: f64) -> Result<ActivityGrid, ActivityError> {
        self.predict_until(t, cell, Parallelism::Rayon(0), &|| false)
    }

    /// [`ServedActivity::predict`] with the given parallelism, [`PREDICT_CHUNK`] points at a
    /// time, giving up with [`ActivityError::Cancelled`] once `cancelled()` says so (it is
    /// asked between chunks). The values do not depend on `par` or the chunks.
    ///
    /// # Errors
    /// As [`ServedActivity::predict`], and [`ActivityError::Cancelled`].
    pub fn predict_until(
        &self,
        t: f64,
        cell: f64,
        par: Parallelism,
        cancelled: &dyn Fn() -> bool,
    ) -> Result<ActivityGrid, ActivityError> {
        if !(t.is_finite() && t.abs() <= MAX_TIME_SECS) {
            return Err(ActivityError::Time(t));
        }
        let grid = self.checked_region(cell)?;
        let (cols, rows) = (grid.cols, grid.rows);
        let centres = grid.centres();
        let (mut mean, mut std) = (
            Vec::with_capacity(centres.len()),
            Vec::with_capacity(centres.len()),
        );
        for chunk in centres.chunks(PREDICT_CHUNK) {
            if cancelled() {
                return Err(ActivityError::Cancelled);
            }
            let points: Vec<([f64; 2], f64)> = chunk.iter().map(|&c| (c, t)).collect();
            let (m, s) = self
                .model
                .predict_with_std(&points, par)
                .map_err(|e| ActivityError::Model(e.to_string()))?;
            mean.extend(m);
            std.extend(s);
        }
        let shown = |i: usize| {
            !self
                .map
                .as_ref()
                .is_some_and(|m| m.is_occupied_at(centres[i], WALL_PERCENT))
        };
        // Row `r` from the bottom is row `rows - 1 - r` of the library's, from the top.
        let from_bottom = |values: &[f64]| -> Vec<Option<f64>> {
            (0..rows)
                .flat_map(|r| (0..cols).map(move |c| c + cols * (rows - 1 - r)))
                .map(|i| shown(i).then_some(values[i]))
                .collect()
        };
        Ok(ActivityGrid {
            origin: [grid.min[0], grid.max[1] - rows as f64 * grid.cell],
            cell: grid.cell,
            cols,
            rows,
            mean: from_bottom(&mean),
            std: from_bottom(&std),
        })
    }
}
