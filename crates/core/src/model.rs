//! The one trait every model of a state over time implements.

use crate::error::ObservationError;
use crate::observe::ObservedSpan;

/// A model of one state over time: it learns from observations `(t, s)` made at arbitrary,
/// irregular times and predicts `p(t) = P(s(t) = 1)` (or the expected value of a state in
/// `[0, 1]`) for any time, past or future.
///
/// Spatial containers (grids, topological maps, feature maps) hold many of these; decisions
/// (where and when to observe, which route to take) consume their predictions and
/// [entropies](TemporalModel::entropy).
///
/// # Contract
/// * [`observe`](TemporalModel::observe) follows the [observation contract](crate::observe):
///   finite times `>= 0` that never go backwards, values in `[0, 1]`, atomic batches.
/// * Observing a sequence in several batches gives exactly the same model as observing it in
///   one batch (every implementation is tested for this by [`crate::conformance`]).
/// * [`predict`](TemporalModel::predict) returns a value in `[0, 1]`; a model that has seen no
///   observation predicts `0.5` (nothing known, maximum entropy).
/// * Times are seconds as `f64`; models reduce them modulo their periods in double precision,
///   so unix times of this century keep sub-millisecond phase accuracy.
///
/// # Example
/// ```
/// use chronomap_core::{FremenModel, TemporalModel};
///
/// // A door that is open (1) from 8:00 to 18:00 every day, observed every 10 minutes for a week.
/// let times: Vec<f64> = (0..7 * 144).map(|i| i as f64 * 600.0).collect();
/// let states: Vec<f64> = times
///     .iter()
///     .map(|t| if (8.0..18.0).contains(&((t % 86400.0) / 3600.0)) { 1.0 } else { 0.0 })
///     .collect();
/// let mut door = FremenModel::with_order(2);
/// door.observe(&times, &states)?;
/// let noon_next_week = 8.0 * 86400.0 + 12.0 * 3600.0;
/// let night_next_week = 8.0 * 86400.0 + 2.0 * 3600.0;
/// assert!(door.predict(noon_next_week) > 0.8);
/// assert!(door.predict(night_next_week) < 0.2);
/// # Ok::<(), chronomap_core::ObservationError>(())
/// ```
pub trait TemporalModel: Send + Sync {
    /// Adds a batch of observations (`times[i]`, `values[i]`).
    ///
    /// # Errors
    /// The first violation of the [observation contract](crate::observe); the model is then
    /// unchanged.
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError>;

    /// Probability that the state is 1 at `time` (expected value for states in `[0, 1]`).
    fn predict(&self, time: f64) -> f64;

    /// Predictions for many times, written into `out`.
    ///
    /// Implementations may use faster algorithms than repeated [`predict`](Self::predict)
    /// (e.g. for evenly spaced times) but return the same values up to rounding.
    ///
    /// # Panics
    /// If `times` and `out` have different lengths.
    fn predict_into(&self, times: &[f64], out: &mut [f64]) {
        assert_eq!(times.len(), out.len(), "predict_into: length mismatch");
        for (o, &t) in out.iter_mut().zip(times) {
            *o = self.predict(t);
        }
    }

    /// Predictions for many times.
    fn predict_many(&self, times: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; times.len()];
        self.predict_into(times, &mut out);
        out
    }

    /// Binary entropy (bits) of the prediction at `time`: how uncertain the state is then.
    fn entropy(&self, time: f64) -> f64 {
        binary_entropy(self.predict(time))
    }

    /// Count and time span of the observations seen so far.
    fn span(&self) -> ObservedSpan;
}

/// Models whose complexity is one integer that can be changed without re-observing
/// (FreMEn order, number of mixture components): the capability that order selection needs.
pub trait Ordered {
    /// Current order.
    fn order(&self) -> usize;
    /// Largest order the model supports with its current configuration.
    fn max_order(&self) -> usize;
    /// Changes the order; predictions change accordingly, no observation is lost.
    /// Orders above [`max_order`](Self::max_order) are clamped to it.
    fn set_order(&mut self, order: usize);
}

/// Binary entropy in bits: `H(p) = -p log2 p - (1-p) log2 (1-p)`, 0 at `p` = 0 or 1.
pub fn binary_entropy(p: f64) -> f64 {
    if p <= 0.0 || p >= 1.0 || p.is_nan() {
        return 0.0;
    }
    -p * p.log2() - (1.0 - p) * (1.0 - p).log2()
}

/// Saturation `ς(x) = min(max(x, 0), 1)` of [Krajník 2017] eq. (2): keeps a prediction a probability.
#[inline]
pub fn saturate(x: f64) -> f64 {
    x.clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entropy_known_values() {
        assert_eq!(binary_entropy(0.5), 1.0);
        assert_eq!(binary_entropy(0.0), 0.0);
        assert_eq!(binary_entropy(1.0), 0.0);
        // H(0.25) = 0.25*2 + 0.75*log2(4/3) = 0.811278...
        assert!((binary_entropy(0.25) - 0.811_278_124_459_132_8).abs() < 1e-15);
    }
}
