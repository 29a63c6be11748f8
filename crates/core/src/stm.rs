//! Short-term memory: a two-state continuous-time Markov chain.
//!
//! # Model ([Santos 2017] §4.2, eqs. (5)–(6))
//! The state switches from 0 to 1 with rate `α` and from 1 to 0 with rate `β` (per second):
//!
//! ```text
//! dp₀/dt = −α p₀ + β p₁,    dp₁/dt = −β p₁ + α p₀                      (5)
//! ```
//!
//! whose solution, given the state `s_l` observed last, at time `T`, is
//!
//! ```text
//! p(t) = π + (s_l − π)·exp(−(α + β)|t − T|),    π = α / (α + β)        (6)
//! ```
//!
//! Right after an observation the model predicts what was seen; far from it, the stationary
//! probability `π`. The paper writes `t − T` for future times; queries before `T` use
//! `|t − T|`, which is exact for a stationary two-state chain: every two-state chain satisfies
//! detailed balance (`π_0 α = π_1 β`), so it is time-reversible and the state a time `d`
//! *before* an observation has the same conditional law as the state a time `d` after it.
//!
//! # Estimation
//! The rates are "inversely proportional to the average time that an observed state remains
//! at 0 or 1" ([Santos 2017] §4.2). For every pair of consecutive observations `(t', s')`,
//! `(t, s)` with `dt = t − t' > 0` the model assumes the state `s'` held during `dt` and
//! accumulates
//!
//! * dwell times `D_0 += (1 − s')·dt`, `D_1 += s'·dt`;
//! * transitions `N_up += (1 − s')·s`, `N_down += s'·(1 − s)`;
//!
//! and estimates `α = N_up / D_0`, `β = N_down / D_1` (a rate whose dwell time is 0 is 0).
//! For binary states these are the transition counts and dwell times (the maximum-likelihood
//! rates of a chain observed at every change); for states in `[0, 1]` they are their
//! expectations when consecutive states are independent draws. Observations at the same
//! instant as the previous one (`dt = 0`) carry no rate evidence and only replace the last
//! observed state.
//!
//! The sums are accumulated strictly in observation order, so observing a series in chunks
//! gives bit-identically the same model as observing it in one batch.

use serde::{Deserialize, Serialize};

use crate::error::ObservationError;
use crate::model::{TemporalModel, saturate};
use crate::observe::ObservedSpan;

/// Short-term memory model of one state: a two-state continuous-time Markov chain
/// (see the [module docs](self)).
///
/// ```
/// use chronomap_core::{MarkovModel, TemporalModel};
///
/// let mut door = MarkovModel::new();
/// // Closed for 100 s, open for 50 s, closed again, observed every 10 s.
/// let times: Vec<f64> = (0..20).map(|i| 10.0 * i as f64).collect();
/// let states: Vec<f64> = times.iter().map(|&t| ((100.0..150.0).contains(&t) as u8) as f64).collect();
/// door.observe(&times, &states)?;
/// assert!(door.predict(191.0) < 0.1); // just seen closed
/// assert!((door.predict(1e6) - door.stationary().unwrap()).abs() < 1e-12);
/// # Ok::<(), chronomap_core::ObservationError>(())
/// ```
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MarkovModel {
    span: ObservedSpan,
    /// Latest observed state `s_l` (meaningless while `span.count == 0`).
    last_value: f64,
    /// Time spent in state 0, `D_0`, in seconds.
    dwell0_secs: f64,
    /// Time spent in state 1, `D_1`, in seconds.
    dwell1_secs: f64,
    /// Number of 0 → 1 transitions, `N_up`.
    ups: f64,
    /// Number of 1 → 0 transitions, `N_down`.
    downs: f64,
}

impl MarkovModel {
    /// An empty model (predicts 0.5).
    pub fn new() -> Self {
        MarkovModel::default()
    }

    /// Checks invariants (for models read from files): a valid span, a last value in
    /// `[0, 1]`, finite non-negative dwell times, transition counts of at most one per
    /// observation, finite rates.
    pub fn is_consistent(&self) -> bool {
        let count = self.span.count as f64;
        self.span.is_consistent()
            && (0.0..=1.0).contains(&self.last_value)
            && [self.dwell0_secs, self.dwell1_secs]
                .iter()
                .all(|d| d.is_finite() && *d >= 0.0)
            && [self.ups, self.downs]
                .iter()
                .all(|n| (0.0..=count).contains(n))
            && (self.rate_up_per_sec() + self.rate_down_per_sec()).is_finite()
    }

    /// Rate `α` of the 0 → 1 transition, per second (0 before any time was spent in state 0).
    pub fn rate_up_per_sec(&self) -> f64 {
        rate(self.ups, self.dwell0_secs)
    }

    /// Rate `β` of the 1 → 0 transition, per second (0 before any time was spent in state 1).
    pub fn rate_down_per_sec(&self) -> f64 {
        rate(self.downs, self.dwell1_secs)
    }

    /// Stationary probability of state 1, `π = α / (α + β)`; `None` while `α + β = 0`.
    pub fn stationary(&self) -> Option<f64> {
        let (alpha, beta) = (self.rate_up_per_sec(), self.rate_down_per_sec());
        (alpha + beta > 0.0).then(|| alpha / (alpha + beta))
    }

    /// The latest observation `(T, s_l)`, if any.
    pub fn last_observation(&self) -> Option<(f64, f64)> {
        self.span.last_time().map(|t| (t, self.last_value))
    }

    /// Accumulated dwell times `(D_0, D_1)` in seconds.
    pub fn dwell_secs(&self) -> (f64, f64) {
        (self.dwell0_secs, self.dwell1_secs)
    }

    /// Accumulated transition counts `(N_up, N_down)` (expected counts for non-binary states).
    pub fn transitions(&self) -> (f64, f64) {
        (self.ups, self.downs)
    }
}

fn rate(count: f64, dwell: f64) -> f64 {
    if dwell > 0.0 { count / dwell } else { 0.0 }
}

impl TemporalModel for MarkovModel {
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        self.span.validate(times, values)?;
        let mut previous = self.last_observation();
        for (&t, &s) in times.iter().zip(values) {
            if let Some((t_prev, s_prev)) = previous {
                let dt = t - t_prev;
                if dt > 0.0 {
                    self.dwell0_secs += (1.0 - s_prev) * dt;
                    self.dwell1_secs += s_prev * dt;
                    self.ups += (1.0 - s_prev) * s;
                    self.downs += s_prev * (1.0 - s);
                }
            }
            previous = Some((t, s));
        }
        if let Some(&s) = values.last() {
            self.last_value = s;
        }
        self.span.extend(times);
        Ok(())
    }

    /// Eq. (6) from the latest observation; `s_l` while no transition was seen; 0.5 before
    /// any observation.
    fn predict(&self, time: f64) -> f64 {
        let Some((last_time, last_value)) = self.last_observation() else {
            return 0.5;
        };
        let (alpha, beta) = (self.rate_up_per_sec(), self.rate_down_per_sec());
        let k = alpha + beta;
        if k <= 0.0 {
            return last_value;
        }
        let pi = alpha / k;
        saturate(pi + (last_value - pi) * (-k * (time - last_time).abs()).exp())
    }

    fn span(&self) -> ObservedSpan {
        self.span
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
        check_temporal_model(MarkovModel::new, &times, &values);
        // Fractional states too.
        let soft: Vec<f64> = values.iter().map(|v| 0.1 + 0.8 * v).collect();
        check_temporal_model(MarkovModel::new, &times, &soft);
    }

    #[test]
    fn rates_and_prediction_match_hand_computation() {
        let mut m = MarkovModel::new();
        // 0 @0, 0 @10, 1 @20, 1 @25, 0 @45, 0 @45 (repeat: no evidence), 1 @50 (replaces).
        m.observe(
            &[0.0, 10.0, 20.0, 25.0, 45.0, 45.0, 45.0, 50.0],
            &[0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0],
        )
        .unwrap();
        // Pairs with dt > 0: (0,0,10) (0,1,10) (1,1,5) (1,0,20) (1,1,5) — the last from the
        // replaced value 1 @45 to 1 @50.
        // D_0 = 10 + 10 = 20, D_1 = 5 + 20 + 5 = 30, N_up = 1, N_down = 1.
        assert_eq!(m.dwell_secs(), (20.0, 30.0));
        assert_eq!(m.transitions(), (1.0, 1.0));
        let (alpha, beta) = (0.05, 1.0 / 30.0);
        assert_eq!(m.rate_up_per_sec(), alpha);
        assert_eq!(m.rate_down_per_sec(), beta);
        let pi = alpha / (alpha + beta); // 0.6
        assert!((m.stationary().unwrap() - 0.6).abs() < 1e-15);
        // Eq. (6) from s_l = 1 at T = 50: p(60) = 0.6 + 0.4 e^{-(1/12)·10}.
        let expected = pi + (1.0 - pi) * (-(alpha + beta) * 10.0f64).exp();
        assert!((m.predict(60.0) - 0.6 - 0.4 * (-10.0f64 / 12.0).exp()).abs() < 1e-15);
        assert!((m.predict(60.0) - expected).abs() < 1e-15);
        assert!((m.predict(60.0) - 0.773_839_283_402_831).abs() < 1e-12);
        // Time-reversible: 10 s before T is predicted like 10 s after.
        assert_eq!(m.predict(40.0), m.predict(60.0));
        assert_eq!(m.predict(50.0), 1.0);
        assert!((m.predict(1e9) - 0.6).abs() < 1e-15);
    }

    #[test]
    fn no_transition_predicts_the_last_state_and_empty_predicts_half() {
        let mut m = MarkovModel::new();
        assert_eq!(m.predict(0.0), 0.5);
        assert_eq!(m.last_observation(), None);
        m.observe(&[0.0, 100.0, 200.0], &[1.0, 1.0, 1.0]).unwrap();
        assert_eq!(m.stationary(), None);
        assert_eq!(m.predict(1e9), 1.0);
        m.observe(&[300.0], &[0.25]).unwrap();
        // One (expected) 1 → 0 transition of 0.75 over 300 s in state 1; no time in state 0.
        assert_eq!(m.rate_up_per_sec(), 0.0);
        assert_eq!(m.rate_down_per_sec(), 0.0025);
        assert_eq!(m.stationary(), Some(0.0));
        assert!((m.predict(400.0) - 0.25 * (-0.25f64).exp()).abs() < 1e-15);
    }

    #[test]
    fn learns_the_rates_of_a_fast_alternating_state() {
        // Alternates every 60 s, sampled every 20 s: three samples per dwell.
        let times: Vec<f64> = (0..3000).map(|i| 20.0 * i as f64).collect();
        let values: Vec<f64> = (0..3000).map(|i| ((i / 3) % 2) as f64).collect();
        let mut m = MarkovModel::new();
        m.observe(&times, &values).unwrap();
        // One transition per 60 s dwell in each state.
        assert!((m.rate_up_per_sec() - 1.0 / 60.0).abs() < 1e-4);
        assert!((m.rate_down_per_sec() - 1.0 / 60.0).abs() < 1e-4);
        assert!((m.stationary().unwrap() - 0.5).abs() < 1e-3);
    }
}
