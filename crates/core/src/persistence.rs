//! FreMEn with persistence: periodic long-term memory plus short-term persistence.
//!
//! # Model ([Krajník 2017] §III-D, eqs. (12)–(13))
//! A [`FremenModel`] predicts the periodic, long-term behaviour `p(t)` of a state; the
//! persistence model adds the expectation that a state seen recently has not changed yet.
//! Its one parameter is the persistence `τ`, the mean time between changes, estimated as
//!
//! ```text
//! 1/τ = (1/n) Σ |s(t) − s(t_l)| / (t − t_l)                            (12)
//! ```
//!
//! over the `n` pairs of consecutive observations with `t − t_l > 0` (eq. (12) writes the
//! same mean as a running update). Observations at the same instant as the previous one
//! carry no evidence about the rate of change and only replace the last state `s(t_l)`.
//! The prediction blends the last observation and the long-term model:
//!
//! ```text
//! p'(t) = s(t_l)·w + p(t)·(1 − w),    w = exp(−|t − t_l| / τ)          (13)
//! ```
//!
//! Close to the last observation (`|t − t_l| ≪ τ`) the model repeats it; far from it
//! (`|t − t_l| ≫ τ`) it is FreMEn. The paper writes `t_l − t` for future times; queries before
//! `t_l` use `|t − t_l|` so that `w ≤ 1` everywhere.
//!
//! Until a pair of observations with `t > t_l` differ, `τ^{-1} = 0` (the state has never been
//! seen to change, its persistence is infinite): `w = 1` and the model predicts the last
//! observed state at all times.
//!
//! The sum of eq. (12) is accumulated strictly in observation order and FreMEn's sums are
//! exact, so observing a series in chunks gives bit-identically the same model as observing
//! it in one batch.

use serde::{Deserialize, Serialize};

use crate::error::{ConfigError, ObservationError};
use crate::fremen::{FremenConfig, FremenModel};
use crate::model::{Ordered, TemporalModel, saturate};
use crate::observe::ObservedSpan;
use crate::par::Parallelism;

/// FreMEn extended with a persistence model (see the [module docs](self)).
///
/// ```
/// use chronomap_core::{PersistenceModel, TemporalModel};
///
/// let mut door = PersistenceModel::with_order(2);
/// // Open from 9:00 to 10:00 every day, observed every 10 minutes for two weeks ...
/// let times: Vec<f64> = (0..14 * 144).map(|i| 600.0 * i as f64).collect();
/// let states: Vec<f64> = times.iter().map(|t| ((t % 86_400.0) / 3600.0))
///     .map(|hour| ((9.0..10.0).contains(&hour) as u8) as f64)
///     .collect();
/// door.observe(&times, &states)?;
/// // ... then seen open at 3:00 in the night.
/// let night = 14.0 * 86_400.0 + 3.0 * 3600.0;
/// door.observe(&[night], &[1.0])?;
/// assert!(door.predict(night + 60.0) > 0.9); // it is probably still open a minute later
/// assert!(door.predict(night + 7.0 * 86_400.0) < 0.2); // but not at 3:00 next week
/// # Ok::<(), chronomap_core::ObservationError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PersistenceModel {
    fremen: FremenModel,
    /// Latest observed state `s(t_l)` (meaningless while nothing was observed).
    last_value: f64,
    /// Sum of `|s(t) − s(t_l)| / (t − t_l)` over the pairs with `t > t_l`.
    change_rate_sum: f64,
    /// Number of such pairs.
    pairs: u64,
}

impl Default for PersistenceModel {
    fn default() -> Self {
        PersistenceModel::from_fremen(FremenModel::default())
    }
}

impl PersistenceModel {
    /// An empty model whose long-term part is a FreMEn model configured by `config`.
    ///
    /// # Errors
    /// If the configuration is invalid ([`FremenConfig::validate`]).
    pub fn new(config: FremenConfig) -> Result<Self, ConfigError> {
        Ok(PersistenceModel::from_fremen(FremenModel::new(config)?))
    }

    /// An empty model with FreMEn's default periods and the given order.
    pub fn with_order(order: usize) -> Self {
        PersistenceModel::from_fremen(FremenModel::with_order(order))
    }

    /// An empty model with `fremen` as its long-term part.
    ///
    /// # Panics
    /// If `fremen` has already observed something (its persistence would be unknown).
    pub fn from_fremen(fremen: FremenModel) -> Self {
        assert_eq!(
            fremen.span().count,
            0,
            "PersistenceModel::from_fremen needs an empty FreMEn model"
        );
        PersistenceModel {
            fremen,
            last_value: 0.0,
            change_rate_sum: 0.0,
            pairs: 0,
        }
    }

    /// The long-term FreMEn model `p(t)`.
    pub fn fremen(&self) -> &FremenModel {
        &self.fremen
    }

    /// Checks invariants (for models read from files): a consistent FreMEn part, a last
    /// value in `[0, 1]`, a finite, non-negative sum of rates over at most as many pairs as
    /// observations.
    pub fn is_consistent(&self) -> bool {
        self.fremen.is_consistent()
            && (0.0..=1.0).contains(&self.last_value)
            && self.change_rate_sum.is_finite()
            && self.change_rate_sum >= 0.0
            && self.pairs <= self.fremen.span().count
    }

    /// `τ^{-1}` of eq. (12), per second: the mean rate of change (0 before any change).
    pub fn inverse_persistence_per_sec(&self) -> f64 {
        if self.pairs == 0 {
            0.0
        } else {
            self.change_rate_sum / self.pairs as f64
        }
    }

    /// The persistence `τ` in seconds, the mean time between changes; `None` while no change
    /// has been observed (infinite persistence).
    pub fn persistence_secs(&self) -> Option<f64> {
        let inverse = self.inverse_persistence_per_sec();
        (inverse > 0.0).then(|| 1.0 / inverse)
    }

    /// The latest observation `(t_l, s(t_l))`, if any.
    pub fn last_observation(&self) -> Option<(f64, f64)> {
        self.fremen.span().last_time().map(|t| (t, self.last_value))
    }

    /// Like [`TemporalModel::observe`], splitting FreMEn's work as `par` says. The resulting
    /// model is bit-identical whatever `par` is.
    ///
    /// # Errors
    /// See [`TemporalModel::observe`].
    pub fn observe_par(
        &mut self,
        times: &[f64],
        values: &[f64],
        par: Parallelism,
    ) -> Result<(), ObservationError> {
        // FreMEn validates the whole batch before changing anything; on error we have not
        // touched our own state either.
        let previous = self.last_observation();
        self.fremen.observe_par(times, values, par)?;
        let mut previous = previous;
        for (&t, &s) in times.iter().zip(values) {
            if let Some((t_l, s_l)) = previous {
                let dt = t - t_l;
                if dt > 0.0 {
                    // Eq. (12).
                    self.change_rate_sum += (s - s_l).abs() / dt;
                    self.pairs += 1;
                }
            }
            previous = Some((t, s));
        }
        if let Some(&s) = values.last() {
            self.last_value = s;
        }
        Ok(())
    }

    /// Eq. (13): blends the last observation with FreMEn's prediction `p`.
    fn blend(&self, time: f64, p: f64) -> f64 {
        match self.last_observation() {
            None => 0.5,
            Some((t_l, s_l)) => {
                let w = (-(time - t_l).abs() * self.inverse_persistence_per_sec()).exp();
                saturate(s_l * w + p * (1.0 - w))
            }
        }
    }
}

impl TemporalModel for PersistenceModel {
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        self.observe_par(times, values, Parallelism::Sequential)
    }

    fn predict(&self, time: f64) -> f64 {
        self.blend(time, self.fremen.predict(time))
    }

    fn predict_into(&self, times: &[f64], out: &mut [f64]) {
        self.fremen.predict_into(times, out);
        for (o, &t) in out.iter_mut().zip(times) {
            *o = self.blend(t, *o);
        }
    }

    fn span(&self) -> ObservedSpan {
        self.fremen.span()
    }
}

impl Ordered for PersistenceModel {
    fn order(&self) -> usize {
        self.fremen.order()
    }

    fn max_order(&self) -> usize {
        self.fremen.max_order()
    }

    fn set_order(&mut self, order: usize) {
        self.fremen.set_order(order);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conformance::check_temporal_model;
    use crate::testdata::door_weeks;

    #[test]
    fn conforms_to_the_temporal_model_contract() {
        let (times, values) = door_weeks();
        check_temporal_model(|| PersistenceModel::with_order(2), &times, &values);
        check_temporal_model(|| PersistenceModel::with_order(4), &times, &values);
    }

    #[test]
    fn persistence_and_prediction_match_hand_computation() {
        let mut m = PersistenceModel::with_order(0); // FreMEn of order 0 is the mean
        assert_eq!(m.predict(0.0), 0.5);
        m.observe(&[0.0, 10.0, 20.0], &[1.0, 1.0, 0.0]).unwrap();
        // Pairs: |1-1|/10 = 0, |0-1|/10 = 0.1 → τ^{-1} = 0.05.
        assert_eq!(m.inverse_persistence_per_sec(), 0.05);
        m.observe(&[20.0, 20.0, 60.0], &[0.0, 0.5, 0.0]).unwrap();
        // 20 → 20: dt = 0, only replaces s_l with 0.5; then |0 − 0.5|/40 = 0.0125.
        // τ^{-1} = (0 + 0.1 + 0.0125) / 3 = 0.0375.
        assert!((m.inverse_persistence_per_sec() - 0.0375).abs() < 1e-15);
        assert!((m.persistence_secs().unwrap() - 80.0 / 3.0).abs() < 1e-12);
        // Mean of 1, 1, 0, 0, 0.5, 0 = 2.5 / 6; s_l = 0 at t_l = 60.
        let mean = 2.5 / 6.0;
        assert!((m.fremen().predict(1e6) - mean).abs() < 1e-15);
        // Eq. (13) at t = 80: w = e^{-20·0.0375} = e^{-0.75}.
        let w = (-0.75f64).exp();
        let expected = 0.0 * w + mean * (1.0 - w);
        assert!((m.predict(80.0) - expected).abs() < 1e-15);
        assert!((m.predict(80.0) - 0.219_847_269_691_244).abs() < 1e-12);
        // Symmetric in time around t_l; the last observation at t_l; the mean far away.
        assert_eq!(m.predict(40.0), m.predict(80.0));
        assert_eq!(m.predict(60.0), 0.0);
        assert!((m.predict(1e6) - mean).abs() < 1e-15);
    }

    #[test]
    fn without_change_the_last_state_persists_forever() {
        let mut m = PersistenceModel::with_order(2);
        m.observe(&[0.0, 0.0, 100.0, 200.0], &[0.0, 1.0, 1.0, 1.0])
            .unwrap();
        // The 0 → 1 pair had dt = 0: no change observed.
        assert_eq!(m.persistence_secs(), None);
        assert_eq!(m.predict(1e9), 1.0);
        // A single observation: no pairs at all.
        let mut m = PersistenceModel::with_order(2);
        m.observe(&[5.0], &[0.3]).unwrap();
        assert_eq!(m.inverse_persistence_per_sec(), 0.0);
        assert_eq!(m.predict(1e9), 0.3);
    }

    #[test]
    fn tracks_recent_observations_and_falls_back_to_fremen() {
        let (times, values) = door_weeks();
        let mut m = PersistenceModel::with_order(2);
        m.observe(&times, &values).unwrap();
        let tau = m.persistence_secs().unwrap();
        assert!(tau > 3600.0 && tau < 1e6, "τ = {tau}");
        // A surprising observation: open on Saturday night.
        let saturday_night = 1_451_865_600.0 + 26.0 * 86_400.0 + 3.0 * 3600.0;
        m.observe(&[saturday_night], &[1.0]).unwrap();
        assert!(m.predict(saturday_night + 60.0) > 0.95);
        let far = saturday_night + 50.0 * tau;
        assert!((m.predict(far) - m.fremen().predict(far)).abs() < 1e-12);
        // Ordered delegates to FreMEn and keeps the persistence.
        let before = m.persistence_secs();
        m.set_order(4);
        assert_eq!((m.order(), m.fremen().order()), (4, 4));
        assert_eq!(m.max_order(), 84);
        assert_eq!(m.persistence_secs(), before);
    }
}
