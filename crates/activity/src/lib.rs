//! Maps of human activity over space × time (dissertation chapter 4, CoPA-Map): rates of
//! people per hour of observation at spatio-temporal cells, the metrics of §4.3.2 and the
//! baselines a learned model must beat.
//!
//! ```
//! use chronomap_activity::{GlobalMean, CellMean, RatePredictor, RateSamples, score};
//!
//! // Two cells, observed in hour bins 0..4; the cell at (0.25, 0.25) is busy.
//! let mut samples = RateSamples::default();
//! for t in 0..4 {
//!     samples.push([0.25, 0.25], f64::from(t), 10.0)?;
//!     samples.push([0.75, 0.25], f64::from(t), 1e-6)?;
//! }
//! let (train, test) = samples.split_at(3.0);
//! assert_eq!((train.len(), test.len()), (6, 2));
//! let ml = CellMean::fit(&train)?;
//! assert_eq!(ml.predict([0.25, 0.25], 3.0), 10.0);
//! let scores = score(&ml, &test)?;
//! assert!(scores.nrmse < 1e-6);
//! let flat = score(&GlobalMean::fit(&train)?, &test)?;
//! assert!(flat.nrmse > 0.9);
//! # Ok::<(), chronomap_activity::ActivityError>(())
//! ```
//!
//! # Data
//! A [`RateSamples`] holds one row per observed spatio-temporal cell, as in the
//! `atc_copa_map_grid` files of CoPA-Map: the cell centre `x = [x1, x2]` (metres), the time `t`
//! (there: the index of the hour bin, 12 recorded hours per day with the nights removed) and
//! the rate `y >= 0` (people per hour of observation; the files write `1e-6` where the cell was
//! observed and nobody was seen). Cells are identified by their exact centre coordinates.
//!
//! # Models
//! Every model implements [`RatePredictor`]; [`score`] evaluates any of them with the NRMSE of
//! eq. (4.20) ([`nrmse`]) and the χ²-distance of eq. (4.21) ([`chi2_distance`]). The baselines
//! of §4.3.2 are in [`baselines`]: [`GlobalMean`], the maximum-likelihood per-cell mean
//! [`CellMean`] ("ML"), the per-cell Poisson-spectral FreMEn model [`FrAam`] ("Fr-AAM") and the
//! log-Gaussian Cox process [`GpHom`] ("GP-Hom", in [`gphom`]); Warped Hypertime ([Krajník 2019]) is
//! [`Whyte`] ("WHyTe", in [`whyte`]): a mixture of people over warped space-time divided by one
//! of observation. CoPA-Map is [`CopaMap`]; [`AnyActivityModel`] is whichever of CoPA-Map and
//! Log-AM a model file holds. Beyond the dissertation, [`LogAdditive`] ("Log-AM",
//! in [`lograte`]) models ln(1 + rate) as a level per cell plus a profile of the day and a shrunken
//! interaction of the two.
//!
//! # Where samples come from
//! [`extract`] builds them from pedestrian detections as a simulated robot sees them (§4.2.2,
//! eqs. 4.5–4.6: a field of view pruned at the obstacles of a map, counts over observed
//! durations), and the ground truth of §4.3.2 from all detections.
//!
//! [`disturbance`] is the service-disturbance benchmark of eq. (4.22): patrols planned on any
//! model's predicted rates, and the people they pass; [`disturbance_day`] its test day (patrol
//! slots, every model's patrols and curves), [`planning`] the grids the robot drives on (over
//! training cells or a whole map), [`atc`] the time axis of the bundled ATC grid, [`grids`]
//! the cells and bins the command line works on (aligned cells, regions, detection bins).
#![deny(missing_docs)]

pub mod gp;

pub mod any;
pub mod atc;
pub mod baselines;
pub mod copa;
pub mod disturbance;
pub mod disturbance_day;
pub mod extract;
pub mod gphom;
pub mod grids;
pub mod init;
pub mod lograte;
pub mod nugget;
pub mod planning;
pub mod truth;
pub mod whyte;

#[cfg(test)]
mod progress_tests;

use std::collections::HashMap;

use thiserror::Error;

pub use any::AnyActivityModel;
pub use baselines::{
    Baseline, BaselineConfig, BaselineSelection, CellLogMean, CellMean, FrAam, FrAamCell,
    FrAamComponent, FrAamConfig, GlobalMean, select_baseline,
};
pub use copa::{CopaConfig, CopaMap, PeriodInitMode, RateScale};
pub use gphom::{GpHom, GpHomConfig};
pub use init::{PeriodInit, SpectralInitConfig, initial_periods};
pub use lograte::{HoldoutScore, LogAdditive, LogAdditiveConfig, LogCell};
pub use whyte::{Whyte, WhyteConfig, WhyteTrial};

/// Why rate samples or a model were rejected.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ActivityError {
    /// A coordinate or time is NaN or infinite.
    #[error("sample {index}: {field} {value} is not a finite number")]
    NonFinite {
        /// Index of the sample.
        index: usize,
        /// `"x1"`, `"x2"`, `"t"` or `"y"`.
        field: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A rate is negative.
    #[error("sample {index}: rate y = {value} is negative (rates are >= 0)")]
    NegativeRate {
        /// Index of the sample.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// There are no samples where some are needed (training a model, scoring).
    #[error("no samples")]
    Empty,
    /// Predictions and ground truth differ in length.
    #[error("{predictions} predictions but {truth} ground-truth rates")]
    LengthMismatch {
        /// Number of predictions.
        predictions: usize,
        /// Number of ground-truth rates.
        truth: usize,
    },
    /// The mean ground-truth rate is 0, so the NRMSE of eq. (4.20) is undefined.
    #[error("the mean ground-truth rate is 0: the NRMSE is undefined")]
    ZeroMean,
    /// A model's configuration is invalid.
    #[error("invalid configuration: {0}")]
    Config(String),
    /// A Gaussian-process model (GP-Hom) could not be fitted.
    #[error(transparent)]
    Gp(#[from] crate::gp::GpError),
}

/// Rates of people at spatio-temporal cells: `y[i]` people per hour of observation were seen
/// in the cell centred at `x[i]` during the time bin `t[i]`.
///
/// All values are finite and every rate is `>= 0` (checked by [`RateSamples::push`] and
/// [`RateSamples::new`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RateSamples {
    x: Vec<[f64; 2]>,
    t: Vec<f64>,
    y: Vec<f64>,
}

impl RateSamples {
    /// Samples from aligned columns.
    ///
    /// # Errors
    /// [`ActivityError::LengthMismatch`] if the columns differ in length, or the first
    /// non-finite value or negative rate.
    pub fn new(x: Vec<[f64; 2]>, t: Vec<f64>, y: Vec<f64>) -> Result<Self, ActivityError> {
        if x.len() != t.len() || t.len() != y.len() {
            return Err(ActivityError::LengthMismatch {
                predictions: x.len().max(t.len()),
                truth: y.len(),
            });
        }
        for i in 0..x.len() {
            check_sample(i, x[i], t[i], y[i])?;
        }
        Ok(RateSamples { x, t, y })
    }

    /// Appends one sample.
    ///
    /// # Errors
    /// [`ActivityError::NonFinite`] or [`ActivityError::NegativeRate`]; the samples are then
    /// unchanged.
    pub fn push(&mut self, x: [f64; 2], t: f64, y: f64) -> Result<(), ActivityError> {
        check_sample(self.len(), x, t, y)?;
        self.x.push(x);
        self.t.push(t);
        self.y.push(y);
        Ok(())
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Cell centres `[x1, x2]` in metres.
    pub fn x(&self) -> &[[f64; 2]] {
        &self.x
    }

    /// Times (in the bundled data: hour-bin indices).
    pub fn t(&self) -> &[f64] {
        &self.t
    }

    /// Rates, people per hour of observation.
    pub fn y(&self) -> &[f64] {
        &self.y
    }

    /// Chronological split: the samples with `t < at` (training) and those with `t >= at`
    /// (test), each in the original order.
    pub fn split_at(&self, at: f64) -> (RateSamples, RateSamples) {
        let mut before = RateSamples::default();
        let mut after = RateSamples::default();
        for i in 0..self.len() {
            let part = if self.t[i] < at {
                &mut before
            } else {
                &mut after
            };
            part.x.push(self.x[i]);
            part.t.push(self.t[i]);
            part.y.push(self.y[i]);
        }
        (before, after)
    }

    /// Mean rate (0 when empty).
    pub fn mean_rate(&self) -> f64 {
        if self.is_empty() {
            0.0
        } else {
            self.y.iter().sum::<f64>() / self.len() as f64
        }
    }

    /// Number of distinct cells.
    pub fn cell_count(&self) -> usize {
        self.cells().len()
    }

    /// The indices of the samples of every cell, in sample order, keyed by [`CellKey`].
    pub fn cells(&self) -> HashMap<CellKey, Vec<usize>> {
        let mut cells: HashMap<CellKey, Vec<usize>> = HashMap::new();
        for (i, &x) in self.x.iter().enumerate() {
            cells.entry(CellKey::of(x)).or_default().push(i);
        }
        cells
    }
}

fn check_sample(index: usize, x: [f64; 2], t: f64, y: f64) -> Result<(), ActivityError> {
    for (field, value) in [("x1", x[0]), ("x2", x[1]), ("t", t), ("y", y)] {
        if !value.is_finite() {
            return Err(ActivityError::NonFinite {
                index,
                field,
                value,
            });
        }
    }
    if y < 0.0 {
        return Err(ActivityError::NegativeRate { index, value: y });
    }
    Ok(())
}

/// A cell, identified by the exact coordinates of its centre (`-0.0` and `0.0` are the same
/// cell).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct CellKey([u64; 2]);

impl CellKey {
    /// The key of the cell centred at `x`.
    pub fn of(x: [f64; 2]) -> Self {
        // Adding 0.0 turns -0.0 into 0.0.
        CellKey([(x[0] + 0.0).to_bits(), (x[1] + 0.0).to_bits()])
    }

    /// The cell centre.
    pub fn centre(self) -> [f64; 2] {
        [f64::from_bits(self.0[0]), f64::from_bits(self.0[1])]
    }
}

/// A model of the activity rate at any place and time: the interface every baseline and
/// CoPA-Map implement, so that [`score`] and the command line treat them alike.
pub trait RatePredictor {
    /// Short name (`"ml"`, `"global_mean"`, `"fr_aam"`, `"whyte"`, ...).
    fn name(&self) -> &str;

    /// Predicted rate (people per hour of observation, `>= 0`) in the cell centred at `x` at
    /// time `t`.
    fn predict(&self, x: [f64; 2], t: f64) -> f64;

    /// Predicted rates at every sample of `at` (the rates of `at` are not used). The default
    /// calls [`RatePredictor::predict`]; models with a faster batch path override it.
    fn predict_samples(&self, at: &RateSamples) -> Vec<f64> {
        at.x()
            .iter()
            .zip(at.t())
            .map(|(&x, &t)| self.predict(x, t))
            .collect()
    }

    /// The interval that holds the rate of a whole time bin (what the ground truth of
    /// [Stüde 2024] §4.3.2 counts: people in the cell over the whole hour) in the cell centred
    /// at `x` at time `t` with probability `coverage` (in `(0, 1)`) under the model's own
    /// predictive distribution; `None` for models without one (the default).
    fn interval(&self, _x: [f64; 2], _t: f64, _coverage: f64) -> Option<(f64, f64)> {
        None
    }

    /// The interval that holds one observation like the training samples (for a robot's
    /// rates: a glimpse of the cell, with its counting noise) with probability `coverage`;
    /// `None` for models without one (the default).
    fn observation_interval(&self, _x: [f64; 2], _t: f64, _coverage: f64) -> Option<(f64, f64)> {
        None
    }

    /// [`RatePredictor::interval`] at every sample of `at` (the rates of `at` are not used);
    /// `None` where the model has no intervals. The default calls `interval` point by point;
    /// models with a faster batch path override it.
    fn interval_samples(&self, at: &RateSamples, coverage: f64) -> Option<Vec<(f64, f64)>> {
        at.x()
            .iter()
            .zip(at.t())
            .map(|(&x, &t)| self.interval(x, t, coverage))
            .collect()
    }

    /// [`RatePredictor::observation_interval`] at every sample of `at`, as
    /// [`RatePredictor::interval_samples`] is.
    fn observation_interval_samples(
        &self,
        at: &RateSamples,
        coverage: f64,
    ) -> Option<Vec<(f64, f64)>> {
        at.x()
            .iter()
            .zip(at.t())
            .map(|(&x, &t)| self.observation_interval(x, t, coverage))
            .collect()
    }
}

/// Normalised root mean square error, eq. (4.20):
/// `sqrt( Σ (ŷ_i − y_i)² / (ȳ² n) )` with `ȳ` the mean of the ground truth `y`.
///
/// ```
/// use chronomap_activity::nrmse;
/// // errors 1 and -1, mean truth 2: sqrt(2 / (4 · 2)) = 0.5
/// assert_eq!(nrmse(&[2.0, 2.0], &[1.0, 3.0])?, 0.5);
/// # Ok::<(), chronomap_activity::ActivityError>(())
/// ```
///
/// # Errors
/// [`ActivityError::LengthMismatch`], [`ActivityError::Empty`], or
/// [`ActivityError::ZeroMean`] if the ground truth averages to 0.
pub fn nrmse(predictions: &[f64], truth: &[f64]) -> Result<f64, ActivityError> {
    check_aligned(predictions, truth)?;
    let n = truth.len() as f64;
    let mean = truth.iter().sum::<f64>() / n;
    if mean == 0.0 {
        return Err(ActivityError::ZeroMean);
    }
    let sum: f64 = predictions
        .iter()
        .zip(truth)
        .map(|(p, y)| (p - y) * (p - y))
        .sum();
    Ok((sum / (mean * mean * n)).sqrt())
}

/// χ²-distance, eq. (4.21): `Σ (ŷ_i − y_i)² / (ŷ_i + y_i)`, summed over the samples where
/// `ŷ_i + y_i > 0` (a term with both 0 is a perfect prediction and contributes nothing).
///
/// ```
/// use chronomap_activity::chi2_distance;
/// // (3 − 1)² / 4 + (0 − 0) skipped + (2 − 2)² / 4 = 1
/// assert_eq!(chi2_distance(&[3.0, 0.0, 2.0], &[1.0, 0.0, 2.0])?, 1.0);
/// # Ok::<(), chronomap_activity::ActivityError>(())
/// ```
///
/// # Errors
/// [`ActivityError::LengthMismatch`] or [`ActivityError::Empty`].
pub fn chi2_distance(predictions: &[f64], truth: &[f64]) -> Result<f64, ActivityError> {
    check_aligned(predictions, truth)?;
    Ok(predictions
        .iter()
        .zip(truth)
        .filter(|(p, y)| *p + *y > 0.0)
        .map(|(p, y)| (p - y) * (p - y) / (p + y))
        .sum())
}

fn check_aligned(predictions: &[f64], truth: &[f64]) -> Result<(), ActivityError> {
    if predictions.len() != truth.len() {
        return Err(ActivityError::LengthMismatch {
            predictions: predictions.len(),
            truth: truth.len(),
        });
    }
    if truth.is_empty() {
        return Err(ActivityError::Empty);
    }
    Ok(())
}

/// The metrics of §4.3.2 for one model on one test set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scores {
    /// Eq. (4.20), see [`nrmse`].
    pub nrmse: f64,
    /// Eq. (4.21), see [`chi2_distance`].
    pub chi2: f64,
}

/// Scores `model` on `test`: its predictions at every test sample against the test rates.
///
/// # Errors
/// As [`nrmse`].
pub fn score(
    model: &(impl RatePredictor + ?Sized),
    test: &RateSamples,
) -> Result<Scores, ActivityError> {
    let predictions = model.predict_samples(test);
    Ok(Scores {
        nrmse: nrmse(&predictions, test.y())?,
        chi2: chi2_distance(&predictions, test.y())?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nrmse_by_hand() {
        // errors 1, -2, 0; mean truth (1 + 4 + 1) / 3 = 2; sqrt(5 / (4 · 3))
        let v = nrmse(&[2.0, 2.0, 1.0], &[1.0, 4.0, 1.0]).unwrap();
        assert!((v - (5.0f64 / 12.0).sqrt()).abs() < 1e-15, "{v}");
        assert_eq!(nrmse(&[1.0, 4.0], &[1.0, 4.0]).unwrap(), 0.0);
        assert_eq!(nrmse(&[1.0], &[0.0]), Err(ActivityError::ZeroMean));
        assert_eq!(nrmse(&[], &[]), Err(ActivityError::Empty));
        assert_eq!(
            nrmse(&[1.0], &[1.0, 2.0]),
            Err(ActivityError::LengthMismatch {
                predictions: 1,
                truth: 2
            })
        );
    }

    #[test]
    fn chi2_by_hand_skips_zero_denominators() {
        // (2 − 1)² / 3 + (0 − 4)² / 4 + 0/0 skipped = 1/3 + 4
        let v = chi2_distance(&[2.0, 0.0, 0.0], &[1.0, 4.0, 0.0]).unwrap();
        assert!((v - (1.0 / 3.0 + 4.0)).abs() < 1e-15, "{v}");
        assert_eq!(chi2_distance(&[0.0], &[0.0]).unwrap(), 0.0);
        assert_eq!(chi2_distance(&[], &[]), Err(ActivityError::Empty));
    }

    #[test]
    fn samples_reject_nan_and_negative_rates_and_leave_the_samples_unchanged() {
        let mut s = RateSamples::default();
        s.push([0.0, 0.0], 0.0, 1.0).unwrap();
        assert_eq!(
            s.push([f64::NAN, 0.0], 1.0, 1.0).unwrap_err().to_string(),
            "sample 1: x1 NaN is not a finite number"
        );
        assert_eq!(
            s.push([0.0, 0.0], 1.0, -0.5),
            Err(ActivityError::NegativeRate {
                index: 1,
                value: -0.5
            })
        );
        assert!(matches!(
            s.push([0.0, 0.0], f64::INFINITY, 1.0),
            Err(ActivityError::NonFinite { field: "t", .. })
        ));
        assert_eq!(s.len(), 1);
        assert!(RateSamples::new(vec![[0.0; 2]], vec![0.0], vec![]).is_err());
        assert!(RateSamples::new(vec![[0.0; 2]], vec![0.0], vec![f64::NAN]).is_err());
    }

    #[test]
    fn split_is_chronological_and_keeps_order() {
        let s = RateSamples::new(
            vec![[0.0, 0.0], [1.0, 0.0], [0.0, 0.0], [1.0, 0.0]],
            vec![5.0, 1.0, 3.0, 2.0],
            vec![1.0, 2.0, 3.0, 4.0],
        )
        .unwrap();
        let (a, b) = s.split_at(3.0);
        assert_eq!(a.t(), [1.0, 2.0]);
        assert_eq!(a.y(), [2.0, 4.0]);
        assert_eq!(b.t(), [5.0, 3.0]);
        assert_eq!(s.cell_count(), 2);
        assert_eq!(CellKey::of([-0.0, 1.0]), CellKey::of([0.0, 1.0]));
        assert_eq!(CellKey::of([2.5, -1.0]).centre(), [2.5, -1.0]);
    }
}
