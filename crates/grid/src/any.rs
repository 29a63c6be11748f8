//! Any grid a grid file holds, behind one interface: the learning state ([`FremenGrid`]), its
//! compact model ([`FittedGrid`], [Krajník 2017] §VI "lossy") or the compact model with the
//! outliers that reproduce every frame ([`LosslessGrid`], §VI "lossless").
//!
//! The command line, the service, the Python package and the ROS 2 node all hold "a grid" and
//! ask the same questions of it (its geometry, its frames, the map at a time, one cell over
//! time); [`AnyGrid`] answers them once, so none of them matches on what was stored.
//!
//! ```
//! use chronomap_core::Parallelism;
//! use chronomap_core::fremen::FremenConfig;
//! use chronomap_grid::{AnyGrid, FremenGrid, GridConfig, GridGeometry, GridStore, OrderChoice};
//!
//! let geometry = GridGeometry::planar(2, 1, 0.5, [0.0, 0.0])?;
//! let fremen = FremenConfig { periods: "day".parse()?, order: 1, ..FremenConfig::default() };
//! let mut grid = FremenGrid::new(geometry, GridConfig { fremen, keep_history: false })?;
//! // Cell 0 always free, cell 1 occupied in the afternoon and at night.
//! for (t, door) in [(0.0, 100), (21_600.0, 0), (43_200.0, 100), (64_800.0, 100)] {
//!     grid.observe_occupancy(t, &[0, door])?;
//! }
//! let sequential = Parallelism::Sequential;
//! let state = AnyGrid::State(Box::new(grid.clone()));
//! let lossy = AnyGrid::store(&grid, GridStore::Lossy, OrderChoice::Fixed(1), sequential)?;
//! // The learning state fits its changing cells on the fly; the compact model holds them.
//! let t = 30_000.0;
//! assert_eq!(state.predict_map(t, sequential), lossy.predict_map(t, sequential));
//! assert_eq!(state.predict_cell(1, &[t]), lossy.predict_cell(1, &[t]));
//! assert_eq!(lossy.frame_span().count, 4);
//! assert_eq!((state.learned_order(), lossy.learned_order()), (Some(1), None));
//! assert!(lossy.fitted(Some(2), sequential).is_err());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::borrow::Cow;

use chronomap_core::Parallelism;
use chronomap_core::observe::ObservedSpan;
use thiserror::Error;

use crate::{FittedGrid, FremenGrid, GridError, GridGeometry, LosslessGrid, OrderChoice};

/// What a grid file holds: one of the three forms of [Krajník 2017] §VI.
#[derive(Clone, Debug, PartialEq)]
pub enum AnyGrid {
    /// Everything needed to continue learning (exact accumulators of every changing cell).
    State(Box<FremenGrid>),
    /// The compact model: predicts maps, cannot learn further (§VI "lossy").
    Lossy(Box<FittedGrid>),
    /// The compact model and the outlier sets that reproduce every frame (§VI "lossless").
    Lossless(Box<LosslessGrid>),
}

/// Which of the forms of [`AnyGrid`] to store a learning state as.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GridStore {
    /// The learning state itself.
    State,
    /// The compact model.
    Lossy,
    /// The compact model and the outliers of every frame (needs the grid's history).
    Lossless,
}

/// Why a grid cannot do what was asked of it.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum AnyGridError {
    /// An order was asked of a grid that holds a fitted model: its orders were fixed when it
    /// was fitted.
    #[error("needs a learning-state grid (this one holds a fitted model, {0})")]
    Fitted(&'static str),
}

impl AnyGrid {
    /// The learning state of `grid` stored as `store`: the state itself (cloned), or fitted
    /// with `orders` on the threads `parallelism` allows.
    ///
    /// # Errors
    /// [`GridError`] when a lossless model is asked of a grid built without its history.
    pub fn store(
        grid: &FremenGrid,
        store: GridStore,
        orders: OrderChoice,
        parallelism: Parallelism,
    ) -> Result<AnyGrid, GridError> {
        Ok(match store {
            GridStore::State => AnyGrid::State(Box::new(grid.clone())),
            GridStore::Lossy => AnyGrid::Lossy(Box::new(grid.fitted(orders, parallelism))),
            GridStore::Lossless => AnyGrid::Lossless(Box::new(grid.lossless(orders, parallelism)?)),
        })
    }

    /// Which form this is.
    pub fn form(&self) -> GridStore {
        match self {
            AnyGrid::State(_) => GridStore::State,
            AnyGrid::Lossy(_) => GridStore::Lossy,
            AnyGrid::Lossless(_) => GridStore::Lossless,
        }
    }

    /// Size, resolution and placement of the grid.
    pub fn geometry(&self) -> &GridGeometry {
        match self {
            AnyGrid::State(g) => g.geometry(),
            AnyGrid::Lossy(g) => g.geometry(),
            AnyGrid::Lossless(g) => g.fitted.geometry(),
        }
    }

    /// Count and times of the frames the grid learned from.
    pub fn frame_span(&self) -> ObservedSpan {
        match self {
            AnyGrid::State(g) => g.frame_span(),
            AnyGrid::Lossy(g) => g.frames(),
            AnyGrid::Lossless(g) => g.fitted.frames(),
        }
    }

    /// Number of frames the grid learned from (a lossless model: the frames it reproduces).
    pub fn frames(&self) -> u64 {
        match self {
            AnyGrid::State(g) => g.frames(),
            AnyGrid::Lossy(g) => g.frames().count,
            AnyGrid::Lossless(g) => g.frames(),
        }
    }

    /// The order a learning state predicts with ([`GridConfig`](crate::GridConfig)'s FreMEn
    /// order); `None` for a fitted model, whose orders were fixed when it was fitted.
    pub fn learned_order(&self) -> Option<usize> {
        match self {
            AnyGrid::State(g) => Some(g.config().fremen.order),
            _ => None,
        }
    }

    /// The learning state, if this is one.
    pub fn learning_state(&self) -> Option<&FremenGrid> {
        match self {
            AnyGrid::State(g) => Some(g),
            _ => None,
        }
    }

    /// The learning state, mutable (to observe more frames), if this is one.
    pub fn learning_state_mut(&mut self) -> Option<&mut FremenGrid> {
        match self {
            AnyGrid::State(g) => Some(g),
            _ => None,
        }
    }

    /// The compact model that predicts: a learning state fitted with `order` (its own order
    /// when `None`) on the threads `parallelism` allows, or the fitted model held.
    ///
    /// # Errors
    /// [`AnyGridError::Fitted`] when an `order` is asked of a fitted model.
    pub fn fitted(
        &self,
        order: Option<usize>,
        parallelism: Parallelism,
    ) -> Result<Cow<'_, FittedGrid>, AnyGridError> {
        match (self, order) {
            (AnyGrid::State(g), _) => {
                let k = order.unwrap_or(g.config().fremen.order);
                Ok(Cow::Owned(g.fitted(OrderChoice::Fixed(k), parallelism)))
            }
            (AnyGrid::Lossy(_), Some(_)) => Err(AnyGridError::Fitted("lossy")),
            (AnyGrid::Lossless(_), Some(_)) => Err(AnyGridError::Fitted("lossless")),
            (AnyGrid::Lossy(g), None) => Ok(Cow::Borrowed(g)),
            (AnyGrid::Lossless(g), None) => Ok(Cow::Borrowed(&g.fitted)),
        }
    }

    /// As [`AnyGrid::fitted`], taking the grid: a fitted model is moved out, not copied.
    ///
    /// # Errors
    /// [`AnyGridError::Fitted`] when an `order` is asked of a fitted model.
    pub fn into_fitted(
        self,
        order: Option<usize>,
        parallelism: Parallelism,
    ) -> Result<FittedGrid, AnyGridError> {
        match (self, order) {
            (AnyGrid::State(g), _) => {
                let k = order.unwrap_or(g.config().fremen.order);
                Ok(g.fitted(OrderChoice::Fixed(k), parallelism))
            }
            (AnyGrid::Lossy(_), Some(_)) => Err(AnyGridError::Fitted("lossy")),
            (AnyGrid::Lossless(_), Some(_)) => Err(AnyGridError::Fitted("lossless")),
            (AnyGrid::Lossy(g), None) => Ok(*g),
            (AnyGrid::Lossless(g), None) => Ok(g.fitted),
        }
    }

    /// Predicted occupancy probability of every cell at `time` (NaN for cells never
    /// observed), [Krajník 2017] eq. (10) per cell: a learning state fits its changing cells
    /// on the threads `parallelism` allows (the same bits on any), a fitted model predicts
    /// from what it holds.
    pub fn predict_map(&self, time: f64, parallelism: Parallelism) -> Vec<f32> {
        match self {
            AnyGrid::State(g) => g.predict_map(time, parallelism),
            AnyGrid::Lossy(g) => g.predict_map(time),
            AnyGrid::Lossless(g) => g.fitted.predict_map(time),
        }
    }

    /// Predicted occupancy probability of the cell with flat index `cell` at each of `times`
    /// (NaN for a cell never observed).
    pub fn predict_cell(&self, cell: usize, times: &[f64]) -> Vec<f32> {
        match self {
            AnyGrid::State(g) => g.predict_cell(cell, times),
            AnyGrid::Lossy(g) => g.predict_cell(cell, times),
            AnyGrid::Lossless(g) => g.fitted.predict_cell(cell, times),
        }
    }

    /// Whether the grid's invariants hold (checked when a file is read).
    pub fn is_consistent(&self) -> bool {
        match self {
            AnyGrid::State(g) => g.is_consistent(),
            AnyGrid::Lossy(g) => g.is_consistent(),
            AnyGrid::Lossless(g) => g.is_consistent(),
        }
    }
}
