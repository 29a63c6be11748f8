//! FreMEn: Frequency Map Enhancement of one state from irregular observations.
//!
//! # Model ([Krajník 2017] §III-B/C, [Santos 2017] §4.1)
//! The probability that the state is 1 at time `t` is a mean plus the `m` strongest
//! periodic components of the observed signal's spectrum over a fixed set Ω of candidate
//! periods `T_k` (`ω_k = 2π / T_k`):
//!
//! ```text
//! p(t) = ς( μ + Σ_{l=1..m} 2|γ_l| cos(ω_l t + arg γ_l) )
//! ```
//!
//! ([Santos 2017] eq. (4); [Krajník 2017] eq. (10) with `α_l = 2|γ_l|`), where `ς` saturates to
//! `[0, 1]` ([Krajník 2017] eq. (2)). The coefficients are the centred non-uniform spectrum
//! `γ_k = (1/n) Σ (s_i − μ) e^{-jω_k t_i}` ([Krajník 2017] eq. (11), [Santos 2017] eq. (3)),
//! accumulated exactly by [`SpectralSums`]: the mean is
//! removed with its *final* value, not a running one, so the model does not depend on how
//! the observations were batched (the original FreMEn server does).
//!
//! The order `m` (number of components used) is a query-time choice: all coefficients are
//! kept, so changing the order or selecting it on held-back data ([Krajník 2017] §IV-B, see
//! [`crate::select`]) loses nothing.

use std::f64::consts::TAU;
use std::sync::OnceLock;

use serde::{Deserialize, Serialize};

use crate::error::{ConfigError, ObservationError};
use crate::model::{Ordered, TemporalModel, saturate};
use crate::observe::ObservedSpan;
use crate::par::Parallelism;
use crate::periods::{PeriodSet, cycle_fraction, phase_angle};
use crate::spectrum::SpectralSums;

/// Configuration of a [`FremenModel`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FremenConfig {
    /// Candidate periods Ω (default: one week / k, k = 1..=84).
    pub periods: PeriodSet,
    /// Number of spectral components used for prediction (the model order `m`).
    pub order: usize,
    /// A period `T` is used only once the observations span at least
    /// `min_span_factor × T` (0 = always; the original FreMEn server used 1.5, the
    /// benchmark code none). Keeps a model trained on two days from inventing a weekly cycle.
    pub min_span_factor: f64,
}

impl Default for FremenConfig {
    fn default() -> Self {
        FremenConfig {
            periods: PeriodSet::default(),
            order: 2,
            min_span_factor: 0.0,
        }
    }
}

impl FremenConfig {
    /// Default configuration with the given order.
    pub fn with_order(order: usize) -> Self {
        FremenConfig {
            order,
            ..FremenConfig::default()
        }
    }

    /// Checks the configuration.
    ///
    /// # Errors
    /// Invalid periods, or a `min_span_factor` that is negative or not finite.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.periods.clone().validated()?;
        if !(self.min_span_factor.is_finite() && self.min_span_factor >= 0.0) {
            return Err(ConfigError::OutOfRange {
                name: "min_span_factor",
                value: self.min_span_factor.to_string(),
                expected: "a finite number >= 0",
            });
        }
        Ok(())
    }
}

/// One periodic component of a FreMEn model.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrequencyComponent {
    /// Period `T = 2π/ω` in seconds.
    pub period_secs: f64,
    /// Spectral magnitude `|γ|`; the component's cosine amplitude is `2|γ|`.
    pub amplitude: f64,
    /// Phase `arg γ` in radians: the component is `2|γ| cos(ωt + arg γ)`.
    pub phase: f64,
}

impl FrequencyComponent {
    /// The component's contribution `2|γ| cos(ωt + arg γ)` at `time`.
    #[inline]
    pub fn value_at(&self, time: f64) -> f64 {
        2.0 * self.amplitude * (phase_angle(time, self.period_secs) + self.phase).cos()
    }
}

/// Mean and spectrum derived from the accumulators (computed lazily, cached).
#[derive(Clone, Debug, PartialEq)]
pub struct FremenFit {
    /// Mean of the observations `μ` (`α_0`).
    pub mean: f64,
    /// Eligible components (see [`FremenConfig::min_span_factor`]) by decreasing amplitude;
    /// ties keep the longer period first.
    pub components: Vec<FrequencyComponent>,
    /// For harmonic period sets `base/k`: the base period and each component's `k`, so that a
    /// prediction reduces the time modulo the base once instead of once per component.
    harmonics: Option<(f64, Vec<u32>)>,
}

/// FreMEn model of one state (see the [module docs](self)).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FremenModel {
    config: FremenConfig,
    span: ObservedSpan,
    sums: SpectralSums,
    #[serde(skip)]
    fit: OnceLock<FremenFit>,
}

impl PartialEq for FremenModel {
    fn eq(&self, other: &Self) -> bool {
        self.config == other.config && self.span == other.span && self.sums == other.sums
    }
}

impl Default for FremenModel {
    fn default() -> Self {
        FremenModel::with_order(FremenConfig::default().order)
    }
}

impl FremenModel {
    /// An empty model.
    ///
    /// # Errors
    /// If the configuration is invalid ([`FremenConfig::validate`]).
    pub fn new(config: FremenConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        let sums = SpectralSums::new(config.periods.clone());
        Ok(FremenModel {
            config,
            span: ObservedSpan::default(),
            sums,
            fit: OnceLock::new(),
        })
    }

    /// A model from its exact accumulators and span (e.g. one cell of a grid, see
    /// `chronomap-grid`). Equal to the model that observed the same data.
    ///
    /// # Errors
    /// Invalid configuration, or accumulators over other periods or with another count.
    pub fn from_parts(
        config: FremenConfig,
        span: ObservedSpan,
        sums: SpectralSums,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        if sums.periods() != &config.periods || sums.count() != span.count {
            return Err(ConfigError::OutOfRange {
                name: "accumulators",
                value: format!("{} observations over {}", sums.count(), sums.periods()),
                expected: "the configured periods and the span's count",
            });
        }
        Ok(FremenModel {
            config,
            span,
            sums,
            fit: OnceLock::new(),
        })
    }

    /// An empty model with the default periods (one week / 1..=84) and the given order.
    pub fn with_order(order: usize) -> Self {
        FremenModel::new(FremenConfig::with_order(order)).expect("default config is valid")
    }

    /// The configuration.
    pub fn config(&self) -> &FremenConfig {
        &self.config
    }

    /// Checks invariants (for models read from files).
    pub fn is_consistent(&self) -> bool {
        self.config.validate().is_ok()
            && self.sums.periods() == &self.config.periods
            && self.sums.is_consistent()
            && self.sums.count() == self.span.count
            && self.span.is_consistent()
    }

    /// The exact spectral accumulators.
    pub fn sums(&self) -> &SpectralSums {
        &self.sums
    }

    /// Like [`TemporalModel::observe`], splitting the work as `par` says. The resulting
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
        self.span.validate(times, values)?;
        self.sums.add(times, values, par);
        self.span.extend(times);
        self.fit = OnceLock::new();
        Ok(())
    }

    /// Adds everything `other` has observed (same configuration of periods).
    ///
    /// # Errors
    /// [`ConfigError::Parse`]-free mismatch report if the period sets differ.
    pub fn merge(&mut self, other: &FremenModel) -> Result<(), ConfigError> {
        if !self.sums.merge(&other.sums) {
            return Err(ConfigError::OutOfRange {
                name: "periods",
                value: other.config.periods.to_string(),
                expected: "the same period set as the model merged into",
            });
        }
        self.span = self.span.merged(&other.span);
        self.fit = OnceLock::new();
        Ok(())
    }

    /// Mean and sorted spectrum (computed on first use after new observations).
    pub fn fit(&self) -> &FremenFit {
        self.fit.get_or_init(|| {
            let gammas = self.sums.coefficients();
            let duration = self.span.duration();
            let mut indexed: Vec<(usize, FrequencyComponent)> = gammas
                .iter()
                .enumerate()
                .map(|(k, g)| {
                    let component = FrequencyComponent {
                        period_secs: self.config.periods.period(k),
                        amplitude: g.norm(),
                        phase: g.arg(),
                    };
                    (k, component)
                })
                .filter(|(_, c)| duration >= self.config.min_span_factor * c.period_secs)
                .collect();
            // Stable sort: equal amplitudes keep the period-set order (longer first).
            indexed.sort_by(|a, b| b.1.amplitude.total_cmp(&a.1.amplitude));
            let harmonics = match self.config.periods {
                PeriodSet::Harmonics { base_secs, .. } => Some((
                    base_secs,
                    indexed.iter().map(|&(k, _)| k as u32 + 1).collect(),
                )),
                PeriodSet::List(_) => None,
            };
            FremenFit {
                mean: self.sums.mean().unwrap_or(0.5),
                components: indexed.into_iter().map(|(_, c)| c).collect(),
                harmonics,
            }
        })
    }

    /// The full spectrum, one component per candidate period, in period-set order
    /// (for plots and inspection; includes periods not yet eligible).
    pub fn spectrum(&self) -> Vec<FrequencyComponent> {
        self.sums
            .coefficients()
            .iter()
            .enumerate()
            .map(|(k, g)| FrequencyComponent {
                period_secs: self.config.periods.period(k),
                amplitude: g.norm(),
                phase: g.arg(),
            })
            .collect()
    }

    /// The components used for prediction: the `order` strongest eligible ones.
    pub fn components(&self) -> &[FrequencyComponent] {
        let fit = self.fit();
        &fit.components[..self.config.order.min(fit.components.len())]
    }

    /// Prediction before saturation: `μ + Σ 2|γ| cos(ωt + arg γ)` (may leave `[0, 1]`).
    pub fn predict_unsaturated(&self, time: f64) -> f64 {
        let fit = self.fit();
        let components = self.components();
        match &fit.harmonics {
            // Harmonic `k` of the base is at phase 2π·frac(k·r) with r = frac(t / base): one
            // modulo per prediction, and the same exact phase the spectrum was computed with.
            Some((base, ks)) => {
                let r = cycle_fraction(time, *base);
                fit.mean
                    + components
                        .iter()
                        .zip(ks)
                        .map(|(c, &k)| {
                            let angle = TAU * (f64::from(k) * r).fract() + c.phase;
                            2.0 * c.amplitude * angle.cos()
                        })
                        .sum::<f64>()
            }
            None => fit.mean + components.iter().map(|c| c.value_at(time)).sum::<f64>(),
        }
    }

    /// Evenly spaced times: rotate each component's phasor instead of calling `cos` per
    /// time, re-anchoring on the exact phase every 256 steps.
    fn predict_evenly_spaced(&self, times: &[f64], step: f64, out: &mut [f64]) {
        const ANCHOR: usize = 256;
        out.fill(self.fit().mean);
        for c in self.components() {
            let (rot_sin, rot_cos) = (TAU * cycle_fraction(step, c.period_secs)).sin_cos();
            let amp2 = 2.0 * c.amplitude;
            for (chunk_index, chunk) in out.chunks_mut(ANCHOR).enumerate() {
                let t0 = times[chunk_index * ANCHOR];
                let (mut s, mut co) = (phase_angle(t0, c.period_secs) + c.phase).sin_cos();
                for o in chunk {
                    *o += amp2 * co;
                    let next_co = co * rot_cos - s * rot_sin;
                    s = s * rot_cos + co * rot_sin;
                    co = next_co;
                }
            }
        }
        out.iter_mut().for_each(|p| *p = saturate(*p));
    }
}

impl TemporalModel for FremenModel {
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        self.observe_par(times, values, Parallelism::Sequential)
    }

    fn predict(&self, time: f64) -> f64 {
        if self.span.count == 0 {
            return 0.5;
        }
        saturate(self.predict_unsaturated(time))
    }

    fn predict_into(&self, times: &[f64], out: &mut [f64]) {
        assert_eq!(times.len(), out.len(), "predict_into: length mismatch");
        if self.span.count > 0 && times.len() >= 32 {
            let step = times[1] - times[0];
            if step > 0.0 && times.windows(2).all(|w| w[1] - w[0] == step) {
                return self.predict_evenly_spaced(times, step, out);
            }
        }
        for (o, &t) in out.iter_mut().zip(times) {
            *o = self.predict(t);
        }
    }

    fn span(&self) -> ObservedSpan {
        self.span
    }
}

impl Ordered for FremenModel {
    fn order(&self) -> usize {
        self.config.order
    }

    fn max_order(&self) -> usize {
        self.config.periods.len()
    }

    fn set_order(&mut self, order: usize) {
        self.config.order = order.min(self.max_order());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::naive::{naive_fremen_predict, naive_spectrum};
    use crate::testdata::door_weeks;

    #[test]
    fn predictions_equal_the_naive_oracle() {
        let (times, values) = door_weeks();
        let mut model = FremenModel::with_order(5);
        model.observe(&times, &values).unwrap();
        let periods = model.config().periods.periods();
        let (mean, gammas) = naive_spectrum(&times, &values, &periods);
        let mut order: Vec<usize> = (0..periods.len()).collect();
        order.sort_by(|&a, &b| gammas[b].norm().total_cmp(&gammas[a].norm()));
        let chosen = &order[..5];
        for probe in 0..500 {
            let t = 1_453_000_000.0 + probe as f64 * 997.0;
            let expected = naive_fremen_predict(mean, &gammas, &periods, chosen, t);
            // The oracle reduces t modulo each inexact period week/k (phase error up to
            // ~1e-10 rad at unix times); the model reduces modulo the exact week.
            assert!((model.predict(t) - expected).abs() < 1e-10);
        }
        // The strongest period of a weekday door is the day.
        assert_eq!(model.components()[0].period_secs, 86_400.0);
    }

    #[test]
    fn evenly_spaced_batch_prediction_equals_pointwise() {
        let (times, values) = door_weeks();
        let mut model = FremenModel::with_order(4);
        model.observe(&times, &values).unwrap();
        let grid: Vec<f64> = (0..5000)
            .map(|i| 1_453_000_000.0 + 60.0 * i as f64)
            .collect();
        let batch = model.predict_many(&grid);
        for (&t, &p) in grid.iter().zip(&batch) {
            assert!((model.predict(t) - p).abs() < 1e-12);
        }
    }

    #[test]
    fn order_zero_is_the_mean_and_empty_model_predicts_half() {
        let mut model = FremenModel::with_order(0);
        assert_eq!(model.predict(0.0), 0.5);
        model
            .observe(&[0.0, 10.0, 20.0, 30.0], &[1.0, 0.0, 0.0, 0.0])
            .unwrap();
        assert_eq!(model.predict(12345.0), 0.25);
    }

    #[test]
    fn span_rule_hides_periods_longer_than_the_data() {
        let (times, values) = door_weeks();
        let config = FremenConfig {
            min_span_factor: 1.5,
            ..FremenConfig::with_order(3)
        };
        let mut model = FremenModel::new(config).unwrap();
        let two_days = times
            .iter()
            .position(|&t| t > times[0] + 2.0 * 86_400.0)
            .unwrap();
        model
            .observe(&times[..two_days], &values[..two_days])
            .unwrap();
        assert!(
            model
                .fit()
                .components
                .iter()
                .all(|c| c.period_secs * 1.5 <= 2.0 * 86_400.0)
        );
    }
}
