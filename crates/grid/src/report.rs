//! What a grid's models are worth: the error table of [Krajník 2017] §VI (estimation and prediction
//! errors of the static map, fixed orders and per-cell orders), scores of predicted frames
//! against observed states, and the views of a fitted grid that maps and reports show.

use std::ops::Range;

use chronomap_core::Parallelism;
use chronomap_core::progress::Progress;
use serde::{Deserialize, Serialize};

use crate::{EstimationError, FittedGrid, FremenGrid, GridError, GridGeometry, OrderChoice};

/// The orders of one row of the error table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum RowOrders {
    /// Every cell with this order (0: the static map).
    Fixed(usize),
    /// Each cell with the order that predicts its held-back frames best ([Krajník 2017] §IV-B).
    PerCell,
}

/// One row of the error table of [Krajník 2017] §VI.
#[derive(Clone, Debug)]
pub struct OrderErrors {
    /// The orders of the row.
    pub orders: RowOrders,
    /// The orders of the model built on every frame (for [`FremenGrid::lossless`] and files).
    pub final_orders: OrderChoice,
    /// The compact model built on every frame with `final_orders`.
    pub fitted: FittedGrid,
    /// Estimation error of `fitted` over every frame.
    pub estimation: EstimationError,
    /// Prediction error on the held-back frames of the model built before them (its per-cell
    /// orders chosen without those frames).
    pub prediction: EstimationError,
}

/// The error table of [Krajník 2017] §VI for orders `0..=max_order` and per-cell orders: the
/// estimation error (eq. (14)) over all frames of models built on all of them, and the
/// prediction error on the frames `[split, frames)` of models built before `split`.
///
/// `trained` is the grid before frame `split` and `inner` the grid at an earlier frame
/// (see [`holdout_splits`](crate::build::holdout_splits)): the per-cell orders of the final model are
/// chosen on `[split, frames)`, those of the trained model on `[inner, split)`, so that no
/// model is scored on frames that chose its orders. Fits and compares on the threads
/// `parallelism` allows (the same table on any). Reports one step per row to `progress`.
///
/// # Errors
/// A grid built without history, or snapshots that are not earlier states of `grid`.
pub fn order_errors(
    grid: &FremenGrid,
    inner: &FremenGrid,
    trained: &FremenGrid,
    max_order: usize,
    parallelism: Parallelism,
    progress: &dyn Progress,
) -> Result<Vec<OrderErrors>, GridError> {
    let (split, frames) = (trained.frames(), grid.frames());
    progress.stage("error table", max_order as u64 + 2);
    let auto_final =
        OrderChoice::PerCell(grid.select_cell_orders(trained, max_order, parallelism)?);
    // For the prediction error, choose the orders without the frames they are tested on.
    let auto_trained =
        OrderChoice::PerCell(trained.select_cell_orders(inner, max_order, parallelism)?);
    let mut rows: Vec<(RowOrders, OrderChoice, OrderChoice)> = (0..=max_order)
        .map(|k| {
            (
                RowOrders::Fixed(k),
                OrderChoice::Fixed(k),
                OrderChoice::Fixed(k),
            )
        })
        .collect();
    rows.push((RowOrders::PerCell, auto_final, auto_trained));
    rows.into_iter()
        .map(|(orders, final_orders, trained_orders)| {
            let fitted = grid.fitted(final_orders.clone(), parallelism);
            let estimation = grid.estimation_error(&fitted, 0, frames, parallelism)?;
            let prediction = grid.estimation_error(
                &trained.fitted(trained_orders, parallelism),
                split,
                frames,
                parallelism,
            )?;
            progress.advance(1);
            Ok(OrderErrors {
                orders,
                final_orders,
                fitted,
                estimation,
                prediction,
            })
        })
        .collect()
}

/// Brier score and binary error of predicted frames against observed states.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameScores {
    /// Mean squared error of `p` against the states (the Brier score for binary states).
    pub brier: f64,
    /// Fraction of (cell, frame) pairs where `p > 0.5` differs from `state == 1`.
    pub binary_error: f64,
}

/// Scores the maps `fitted` predicts at the frames `frames` of `times` against `states`
/// (`states[cell][frame]`, one series per cell, aligned with `times`): the mean over cells
/// and frames of `(p − s)²` and of `[p > 0.5] ≠ [s = 1]`. Frames outside `times` are not
/// scored; `None` if none is.
pub fn score_frames(
    fitted: &FittedGrid,
    times: &[f64],
    states: &[&[f64]],
    frames: Range<usize>,
) -> Option<FrameScores> {
    let (mut brier, mut binary, mut n) = (0.0, 0.0, 0.0);
    for f in frames.start..frames.end.min(times.len()) {
        for (cell, &p) in states.iter().zip(&fitted.predict_map(times[f])) {
            let (s, p) = (cell[f], f64::from(p));
            brier += (p - s) * (p - s);
            binary += f64::from(u8::from((p > 0.5) != (s == 1.0)));
            n += 1.0;
        }
    }
    (n > 0.0).then(|| FrameScores {
        brier: brier / n,
        binary_error: binary / n,
    })
}

/// A 2-D map of a 3-D prediction (`values`, one per cell of `geometry`): each column
/// `(x, y)` takes its most occupied known cell among the layers `z ∈ layers`; NaN where all
/// of them are unknown (NaN). Layers past the grid's depth are ignored.
pub fn project_layers(geometry: &GridGeometry, values: &[f32], layers: Range<u32>) -> Vec<f32> {
    let (w, h) = (geometry.width as usize, geometry.height as usize);
    let mut out = vec![f32::NAN; w * h];
    for z in layers.start..layers.end.min(geometry.depth) {
        let Some(layer) = values.get(z as usize * w * h..(z as usize + 1) * w * h) else {
            break;
        };
        for (o, &v) in out.iter_mut().zip(layer) {
            if !v.is_nan() && (o.is_nan() || v > *o) {
                *o = v;
            }
        }
    }
    out
}

impl FittedGrid {
    /// How many fitted cells have each order: `(order, cells)` for every order that occurs,
    /// smallest first.
    pub fn order_counts(&self) -> Vec<(usize, usize)> {
        let mut counts = [0usize; 256];
        for c in self.cells() {
            counts[usize::from(c.count)] += 1;
        }
        counts
            .iter()
            .enumerate()
            .filter(|&(_, &n)| n > 0)
            .map(|(k, &n)| (k, n))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::GridConfig;
    use crate::build::{build_from_frames, holdout_splits};
    use chronomap_core::FremenConfig;
    use chronomap_core::progress::NoProgress;

    /// Three cells over four weeks of hourly frames: a door shut 18:00-8:00, a wall, and a
    /// cell that flips every 5 hours.
    fn door_grid() -> (FremenGrid, Vec<FremenGrid>) {
        let geometry = GridGeometry::planar(3, 1, 1.0, [0.0, 0.0]).unwrap();
        let config = GridConfig {
            fremen: FremenConfig::with_order(2),
            keep_history: true,
        };
        let frames = 28 * 24;
        let built = build_from_frames(
            geometry,
            &config,
            frames,
            &holdout_splits(frames as u64, 0.25),
            &NoProgress,
            |f, grid| -> Result<(), GridError> {
                let hour = f % 24;
                let door = if (8..18).contains(&hour) { 0 } else { 100 };
                let flip = if (f / 5) % 2 == 0 { 0 } else { 100 };
                grid.observe_occupancy(1_451_865_600.0 + 3600.0 * f as f64, &[door, 100, flip])
            },
        )
        .unwrap();
        (built.grid, built.snapshots)
    }

    #[test]
    fn the_error_table_ranks_the_static_map_below_fremen() {
        let (grid, snapshots) = door_grid();
        let rows = order_errors(
            &grid,
            &snapshots[0],
            &snapshots[1],
            3,
            Parallelism::Rayon(2),
            &NoProgress,
        )
        .unwrap();
        let orders: Vec<RowOrders> = rows.iter().map(|r| r.orders).collect();
        assert_eq!(
            orders,
            [
                RowOrders::Fixed(0),
                RowOrders::Fixed(1),
                RowOrders::Fixed(2),
                RowOrders::Fixed(3),
                RowOrders::PerCell
            ]
        );
        // Two cells change (the door and the flipping cell); the wall is constant.
        assert!(rows.iter().all(|r| r.estimation.changed_cells == 2));
        // Static: the door is shut 14 of 24 hours, so always predicted shut and wrong 10/24 of
        // the time; the flipping cell is occupied in 335 of the 672 frames, so always
        // predicted free and wrong 335/672 of the time.
        let static_error = rows[0].estimation.mean_cell_error;
        let expected = (10.0 / 24.0 + 335.0 / 672.0) / 2.0;
        assert!((static_error - expected).abs() < 1e-12, "{static_error}");
        // The daily rhythm of order 1 gets the door nearly right.
        assert!(rows[1].estimation.mean_cell_error < static_error - 0.1);
        assert!(rows[1].prediction.mean_cell_error < rows[0].prediction.mean_cell_error);
        let per_cell = &rows[4];
        assert!(matches!(per_cell.final_orders, OrderChoice::PerCell(_)));
        assert!(per_cell.estimation.mean_cell_error < static_error);
        assert_eq!(per_cell.fitted.cells().len(), 2);
    }

    #[test]
    fn scores_projections_and_order_counts() {
        let (grid, _) = door_grid();
        let fitted = grid.fitted(OrderChoice::PerCell(vec![2, 0, 0]), Parallelism::Sequential);
        assert_eq!(fitted.order_counts(), [(0, 1), (2, 1)]);
        let times: Vec<f64> = (0..48)
            .map(|h| 1_451_865_600.0 + 3600.0 * h as f64)
            .collect();
        let door: Vec<f64> = (0..48)
            .map(|h| {
                if (8..18).contains(&(h % 24)) {
                    0.0
                } else {
                    1.0
                }
            })
            .collect();
        let wall = vec![1.0; 48];
        let flip: Vec<f64> = (0..48).map(|h| ((h / 5) % 2) as f64).collect();
        let scores = score_frames(&fitted, &times, &[&door, &wall, &flip], 0..48).unwrap();
        assert!(scores.brier > 0.0 && scores.brier < 0.25, "{scores:?}");
        // The flipping cell's mean is 335/672 < 0.5 at order 0: never `p > 0.5`, so it is
        // wrong whenever it is occupied (23 of these 48 frames).
        assert!(scores.binary_error >= 23.0 / 144.0, "{scores:?}");
        assert!(score_frames(&fitted, &times, &[&door, &wall, &flip], 48..60).is_none());

        let geometry = GridGeometry {
            width: 2,
            height: 1,
            depth: 3,
            resolution: 1.0,
            origin: [0.0; 3],
        };
        let values = [0.1, f32::NAN, 0.7, f32::NAN, 0.3, f32::NAN];
        let all = project_layers(&geometry, &values, 0..3);
        assert_eq!(all[0], 0.7);
        assert!(all[1].is_nan());
        assert_eq!(project_layers(&geometry, &values, 2..3)[0], 0.3);
        assert_eq!(project_layers(&geometry, &values, 0..9)[0], 0.7);
    }
}
