//! Warped Hypertime (seed 004): time projected onto circles, one pair of dimensions per
//! periodicity, and the result clustered into a Gaussian mixture.
//!
//! The method of seed 004 §III-B, for a state over time (a door, a robot's velocity):
//! 1. *initialisation*: no periodicity, the vectors hold only the value (or nothing);
//! 2. *spatio-temporal clustering*: a Gaussian mixture over the vectors (eq. 2; HyT-EM:
//!    EM with `k` components, HyT-KM: k-means-initialised EM with `k` chosen by eq. 9);
//! 3. *model error estimation* (eqs. 3–6): predictions at the observed times, their errors and
//!    the mean squared error;
//! 4. *identification of periodicities* (eq. 7): the strongest component of the error series'
//!    non-uniform spectrum over the candidate periods (FreMEn's, one week divided by
//!    `1..=84`), periods already used excluded;
//! 5. *hypertime extension* (eqs. 1, 8): every vector gets `cos(2πt/T)`, `sin(2πt/T)`;
//!
//! repeated while the error falls. One deliberate deviation: the error that decides whether a
//! periodicity is kept (eq. 6) is measured on the most recent [`HypertimeConfig::holdout`] of
//! the training data, which the clustering did not see (the training error nearly always
//! falls with more dimensions, so the paper's stopping rule would add periods until the cap);
//! the chosen model is then refitted on all the data.
//!
//! Binary states are predicted as the original HyT-EM does (a mixture per class over the
//! hypertime vector; `p(t) = P·f₊(t) / (P·f₊(t) + N·f₋(t))`, scaled so that the mean
//! prediction over the training data equals the observed mean, eq. 3); other values in
//! `[0, 1]` by the conditional mean of the value given the hypertime vector (the mixture over
//! `[value, hypertime]` conditioned on time, [`GaussianMixture::conditional`]), which also
//! gives a variance ([`HypertimeModel::predict_distribution`]).
//!
//! When every candidate period divides one week (the default), a time and that time plus a
//! week have the same hypertime vector: the observations are then merged by second of the week
//! (and class), and the mixtures are fitted to the weighted merged points — the same
//! likelihood, up to 60× fewer points on minute-sampled data.

use serde::{Deserialize, Serialize};

use crate::error::{BuildError, ConfigError, ObservationError};
use crate::mixture::{EmConfig, EmInit, GaussianMixture, fit_em};
use crate::model::TemporalModel;
use crate::observe::{ObservedSpan, validate};
use crate::periods::WEEK;

/// How many mixture components.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Components {
    /// Exactly this many (HyT-EM_k).
    Fixed(usize),
    /// Chosen on the hold-out among `1..=max_components` (for HyT-EM) or grown while the
    /// error spectrum's amplitude sum falls (HyT-KM, eq. 9).
    Auto,
}

/// The clustering of stage 2.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Clustering {
    /// HyT-EM: EM from k-means++ seeds with `k` components (`Auto`: chosen on the hold-out).
    Em(Components),
    /// HyT-KM: k-means initialisation, covariances of the hard clusters, then EM; `k` starts
    /// at 1 and grows while the sum of the error spectrum's amplitudes falls (eq. 9).
    KMeans,
}

/// Settings of a [`HypertimeModel`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HypertimeConfig {
    /// The clustering.
    pub clustering: Clustering,
    /// Candidate periods in seconds (default: one week divided by `1..=84`).
    pub candidate_periods: Vec<f64>,
    /// Most periodicities (pairs of hypertime dimensions). Default 5 (the original stopped at
    /// 10 time dimensions).
    pub max_periods: usize,
    /// Most mixture components tried by `Auto`. Default 6.
    pub max_components: usize,
    /// Fraction of the training span (the most recent part) that decides which periodicities
    /// and how many components help. Default 0.25.
    pub holdout: f64,
    /// Seed of the clustering.
    pub seed: u64,
    /// EM starts per fit. Default 2.
    pub starts: usize,
}

impl HypertimeConfig {
    /// The default settings with the given clustering.
    pub fn new(clustering: Clustering) -> Self {
        HypertimeConfig {
            clustering,
            candidate_periods: (1..=84).map(|k| WEEK / f64::from(k)).collect(),
            max_periods: 5,
            max_components: 6,
            holdout: 0.25,
            seed: 0,
            starts: 2,
        }
    }

    fn validate(&self) -> Result<(), ConfigError> {
        let bad = |name: &'static str, value: String, expected: &'static str| {
            Err(ConfigError::OutOfRange {
                name,
                value,
                expected,
            })
        };
        if self.candidate_periods.is_empty() {
            return Err(ConfigError::NoPeriods);
        }
        if let Some(p) = self
            .candidate_periods
            .iter()
            .find(|p| !(p.is_finite() && **p > 0.0))
        {
            return bad("period", p.to_string(), "a positive number of seconds");
        }
        if let Clustering::Em(Components::Fixed(0)) = self.clustering {
            return bad("components", "0".into(), "at least 1");
        }
        if self.max_components == 0 {
            return bad("max_components", "0".into(), "at least 1");
        }
        if !(self.holdout > 0.0 && self.holdout < 1.0) {
            return bad(
                "holdout",
                self.holdout.to_string(),
                "a fraction strictly between 0 and 1",
            );
        }
        if self.starts == 0 {
            return bad("starts", "0".into(), "at least 1");
        }
        Ok(())
    }
}

/// The hypertime vector of `t` (eqs. 1, 8): `cos(2πt/T)`, `sin(2πt/T)` for every period `T`,
/// appended to `out`.
pub fn project(t: f64, periods: &[f64], out: &mut Vec<f64>) {
    for &period in periods {
        let phase = std::f64::consts::TAU * (t.rem_euclid(period) / period);
        let (sin, cos) = phase.sin_cos();
        out.push(cos);
        out.push(sin);
    }
}

/// The inverse of [`project`] for one circle: the time in `[0, period)` whose projection is
/// `(cos, sin)` (any point off the origin; its direction is what counts).
pub fn phase_time(cos: f64, sin: f64, period: f64) -> f64 {
    let angle = sin.atan2(cos).rem_euclid(std::f64::consts::TAU);
    let t = angle / std::f64::consts::TAU * period;
    if t >= period { 0.0 } else { t }
}

/// A fitted hypertime model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
enum Fitted {
    /// Too few data (or no periodicity and no spread): a constant.
    Constant(f64),
    /// Binary states: one mixture per class over the hypertime vector (absent for a class
    /// without observations), the class weights and the scaling factor of eq. 3.
    Binary {
        positives: Option<GaussianMixture>,
        negatives: Option<GaussianMixture>,
        positive_weight: f64,
        negative_weight: f64,
        scale: f64,
    },
    /// Values in `[0, 1]`: one mixture over `[value, hypertime]`.
    Continuous { joint: GaussianMixture },
}

/// A state over time modelled by Warped Hypertime (seed 004); a [`TemporalModel`].
///
/// The model keeps its observations: every [`observe`](TemporalModel::observe) refits it on
/// all of them (a batch method — the periodicities and clusters are chosen anew), so
/// observing in chunks gives exactly the model of one batch.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HypertimeModel {
    config: HypertimeConfig,
    times: Vec<f64>,
    values: Vec<f64>,
    periods: Vec<f64>,
    components: usize,
    fitted: Fitted,
}

/// Observations merged by hypertime position: `(time, value, weight)` rows.
struct Rows {
    times: Vec<f64>,
    values: Vec<f64>,
    weights: Vec<f64>,
}

impl Rows {
    /// Merges observations whose hypertime vectors coincide (same second of the week and the
    /// same value) when every candidate period divides a week; otherwise one row each.
    fn merge(times: &[f64], values: &[f64], candidates: &[f64], binary: bool) -> Rows {
        let divides_week = candidates.iter().all(|&p| {
            let k = WEEK / p;
            (k - k.round()).abs() < 1e-9
        });
        if !(divides_week && binary) {
            return Rows {
                times: times.to_vec(),
                values: values.to_vec(),
                weights: vec![1.0; times.len()],
            };
        }
        let mut keyed: Vec<(i64, bool)> = times
            .iter()
            .zip(values)
            .map(|(&t, &v)| (t.rem_euclid(WEEK).round() as i64, v == 1.0))
            .collect();
        keyed.sort_unstable();
        let mut rows = Rows {
            times: Vec::new(),
            values: Vec::new(),
            weights: Vec::new(),
        };
        for (key, one) in keyed {
            if rows.times.last() == Some(&(key as f64))
                && rows.values.last() == Some(&f64::from(u8::from(one)))
            {
                *rows.weights.last_mut().expect("non-empty") += 1.0;
            } else {
                rows.times.push(key as f64);
                rows.values.push(f64::from(u8::from(one)));
                rows.weights.push(1.0);
            }
        }
        rows
    }
}

fn em_config(config: &HypertimeConfig, components: usize, stage: u64) -> EmConfig {
    EmConfig {
        components,
        starts: config.starts,
        init: match config.clustering {
            Clustering::KMeans => EmInit::KMeans,
            Clustering::Em(_) => EmInit::KMeansPlusPlus,
        },
        seed: crate::rng::derive_seed(config.seed, 0x4879_5445, stage, components as u64),
        ..EmConfig::default()
    }
}

/// Fits a mixture with at most `components` components to the projected rows (fewer if
/// there are fewer distinct points).
fn fit_mixture(
    data: &[f64],
    dim: usize,
    weights: &[f64],
    components: usize,
    config: &HypertimeConfig,
    stage: u64,
) -> Result<GaussianMixture, BuildError> {
    let mut k = components;
    loop {
        match fit_em(data, dim, Some(weights), &em_config(config, k, stage)) {
            Ok(fit) => return Ok(fit.mixture),
            Err(crate::mixture::MixtureError::TooFewPoints { points, .. }) if points >= 1 => {
                k = points.min(k - 1).max(1);
            }
            Err(e) => return Err(BuildError::NotEnoughData(e.to_string())),
        }
    }
}

impl Fitted {
    fn fit(
        times: &[f64],
        values: &[f64],
        weights: &[f64],
        periods: &[f64],
        components: usize,
        config: &HypertimeConfig,
        binary: bool,
    ) -> Result<Fitted, BuildError> {
        let total: f64 = weights.iter().sum();
        let mean = times
            .iter()
            .zip(values)
            .zip(weights)
            .map(|((_, v), w)| v * w)
            .sum::<f64>()
            / total;
        if times.is_empty() || total <= 0.0 {
            return Ok(Fitted::Constant(0.5));
        }
        let stage = periods.len() as u64;
        let dim = 2 * periods.len();
        if binary {
            if periods.is_empty() {
                return Ok(Fitted::Constant(mean));
            }
            let class = |one: bool| -> Result<(Option<GaussianMixture>, f64), BuildError> {
                let mut data = Vec::new();
                let mut w = Vec::new();
                for ((&t, &v), &weight) in times.iter().zip(values).zip(weights) {
                    if (v == 1.0) == one && weight > 0.0 {
                        project(t, periods, &mut data);
                        w.push(weight);
                    }
                }
                let sum: f64 = w.iter().sum();
                if w.is_empty() {
                    return Ok((None, 0.0));
                }
                Ok((
                    Some(fit_mixture(&data, dim, &w, components, config, stage)?),
                    sum,
                ))
            };
            let (positives, positive_weight) = class(true)?;
            let (negatives, negative_weight) = class(false)?;
            let mut fitted = Fitted::Binary {
                positives,
                negatives,
                positive_weight,
                negative_weight,
                scale: 1.0,
            };
            // Eq. (3): the mean prediction over the training data equals the observed mean.
            let predicted: f64 = times
                .iter()
                .zip(weights)
                .map(|(&t, &w)| w * fitted.predict(t, periods).0)
                .sum::<f64>()
                / total;
            if let Fitted::Binary { scale, .. } = &mut fitted
                && predicted > 0.0
            {
                *scale = mean / predicted;
            }
            Ok(fitted)
        } else {
            let mut data = Vec::with_capacity(times.len() * (dim + 1));
            for (&t, &v) in times.iter().zip(values) {
                data.push(v);
                project(t, periods, &mut data);
            }
            let joint = fit_mixture(&data, dim + 1, weights, components, config, stage)?;
            Ok(Fitted::Continuous { joint })
        }
    }

    /// Mean and variance of the state at `t`.
    fn predict(&self, t: f64, periods: &[f64]) -> (f64, f64) {
        match self {
            Fitted::Constant(p) => (*p, p * (1.0 - p)),
            Fitted::Binary {
                positives,
                negatives,
                positive_weight,
                negative_weight,
                scale,
            } => {
                let mut x = Vec::with_capacity(2 * periods.len());
                project(t, periods, &mut x);
                let p = match (positives, negatives) {
                    (None, _) => 0.0,
                    (_, None) => 1.0,
                    (Some(pos), Some(neg)) => {
                        // 1 / (1 + N f₋ / (P f₊)), in the log domain.
                        let log_ratio = negative_weight.ln() + neg.log_density(&x)
                            - positive_weight.ln()
                            - pos.log_density(&x);
                        if log_ratio.is_nan() {
                            positive_weight / (positive_weight + negative_weight)
                        } else {
                            1.0 / (1.0 + log_ratio.exp())
                        }
                    }
                };
                let p = (p * scale).clamp(0.0, 1.0);
                (p, p * (1.0 - p))
            }
            Fitted::Continuous { joint } => {
                let mut x = Vec::with_capacity(2 * periods.len());
                project(t, periods, &mut x);
                if periods.is_empty() {
                    return joint.moments(0);
                }
                let given: Vec<usize> = (1..=x.len()).collect();
                let value = joint.conditional(&given, &x);
                value.moments(0)
            }
        }
    }
}

/// The strongest period of the weighted error series `e` at `times` among `candidates` not
/// yet `used` (eq. 7), and the sum of all candidates' amplitudes (eq. 9).
fn strongest_period(
    times: &[f64],
    errors: &[f64],
    weights: &[f64],
    candidates: &[f64],
    used: &[f64],
) -> (Option<f64>, f64) {
    let total: f64 = weights.iter().sum();
    let mean = errors.iter().zip(weights).map(|(e, w)| e * w).sum::<f64>() / total;
    let mut best: Option<(f64, f64)> = None;
    let mut sum = 0.0;
    for &period in candidates {
        let (mut re, mut im) = (0.0, 0.0);
        for ((&t, &e), &w) in times.iter().zip(errors).zip(weights) {
            let phase = std::f64::consts::TAU * (t.rem_euclid(period) / period);
            let (sin, cos) = phase.sin_cos();
            re += w * (e - mean) * cos;
            im -= w * (e - mean) * sin;
        }
        let amplitude = (re * re + im * im).sqrt() / total;
        sum += amplitude;
        if !used.contains(&period) && best.is_none_or(|(a, _)| amplitude > a) {
            best = Some((amplitude, period));
        }
    }
    (best.map(|(_, p)| p), sum)
}

/// Weighted mean squared error of `fitted` on rows (eq. 6).
fn mse(fitted: &Fitted, periods: &[f64], rows: &Rows) -> f64 {
    let mut sum = 0.0;
    let mut total = 0.0;
    for ((&t, &v), &w) in rows.times.iter().zip(&rows.values).zip(&rows.weights) {
        let e = fitted.predict(t, periods).0 - v;
        sum += w * e * e;
        total += w;
    }
    sum / total.max(f64::MIN_POSITIVE)
}

/// The result of the method's iterations: periods and components.
struct Structure {
    periods: Vec<f64>,
    components: usize,
    error: f64,
}

/// Stages 2–5 with a fixed `components` (or eq. 9 for HyT-KM) on `fit_rows`, the error of
/// eq. 6 measured on `check_rows`.
fn grow(
    fit_rows: &Rows,
    check_rows: &Rows,
    components: Option<usize>,
    config: &HypertimeConfig,
    binary: bool,
) -> Result<Structure, BuildError> {
    let mut periods: Vec<f64> = Vec::new();
    let mut k = components.unwrap_or(1);
    let fit = |periods: &[f64], k: usize| {
        Fitted::fit(
            &fit_rows.times,
            &fit_rows.values,
            &fit_rows.weights,
            periods,
            k,
            config,
            binary,
        )
    };
    let mut model = fit(&periods, k)?;
    let mut error = mse(&model, &periods, check_rows);
    while periods.len() < config.max_periods {
        let residuals = |model: &Fitted, periods: &[f64]| -> Vec<f64> {
            fit_rows
                .times
                .iter()
                .zip(&fit_rows.values)
                .map(|(&t, &v)| model.predict(t, periods).0 - v)
                .collect()
        };
        let errors = residuals(&model, &periods);
        let (next, _) = strongest_period(
            &fit_rows.times,
            &errors,
            &fit_rows.weights,
            &config.candidate_periods,
            &periods,
        );
        let Some(next) = next else { break };
        let mut extended = periods.clone();
        extended.push(next);
        let mut candidate = fit(&extended, k)?;
        if components.is_none() && !extended.is_empty() {
            // HyT-KM (eq. 9): more clusters while the error spectrum's amplitude sum falls.
            let amplitude = |model: &Fitted, k_periods: &[f64]| {
                let e = residuals(model, k_periods);
                strongest_period(
                    &fit_rows.times,
                    &e,
                    &fit_rows.weights,
                    &config.candidate_periods,
                    k_periods,
                )
                .1
            };
            let mut s = amplitude(&candidate, &extended);
            while k < config.max_components {
                let more = fit(&extended, k + 1)?;
                let s_more = amplitude(&more, &extended);
                if s_more < s {
                    candidate = more;
                    s = s_more;
                    k += 1;
                } else {
                    break;
                }
            }
        }
        let candidate_error = mse(&candidate, &extended, check_rows);
        if candidate_error >= error {
            break;
        }
        periods = extended;
        model = candidate;
        error = candidate_error;
    }
    Ok(Structure {
        periods,
        components: k,
        error,
    })
}

impl HypertimeModel {
    /// An empty model.
    ///
    /// # Errors
    /// An invalid configuration.
    pub fn new(config: HypertimeConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(HypertimeModel {
            config,
            times: Vec::new(),
            values: Vec::new(),
            periods: Vec::new(),
            components: 0,
            fitted: Fitted::Constant(0.5),
        })
    }

    /// The settings.
    pub fn config(&self) -> &HypertimeConfig {
        &self.config
    }

    /// The periodicities chosen, in the order found (seconds).
    pub fn periods(&self) -> &[f64] {
        &self.periods
    }

    /// The number of mixture components chosen (per class for binary states).
    pub fn components(&self) -> usize {
        self.components
    }

    /// Checks internal invariants (for models read from files): as many values as times, times
    /// finite and non-decreasing, values in `[0, 1]`, chosen periods among the candidates, a
    /// valid configuration.
    pub fn is_consistent(&self) -> bool {
        self.config.validate().is_ok()
            && self.times.len() == self.values.len()
            && validate(None, &self.times, &self.values).is_ok()
            && self.periods.len() <= self.config.max_periods
            && self
                .periods
                .iter()
                .all(|p| self.config.candidate_periods.contains(p))
    }

    /// Mean and variance of the state at `time` (for binary states `p` and `p(1 − p)`).
    pub fn predict_distribution(&self, time: f64) -> (f64, f64) {
        self.fitted.predict(time, &self.periods)
    }

    fn refit(&mut self) -> Result<(), BuildError> {
        let binary = self.values.iter().all(|&v| v == 0.0 || v == 1.0);
        let all = Rows::merge(
            &self.times,
            &self.values,
            &self.config.candidate_periods,
            binary,
        );
        let split = crate::select::holdout_split(&self.times, self.config.holdout).ok();
        let structure = match split {
            // Too few data to hold some back: no periodicity.
            None => Structure {
                periods: Vec::new(),
                components: 1,
                error: f64::NAN,
            },
            Some(split) => {
                let candidates = &self.config.candidate_periods;
                let fit_rows = Rows::merge(
                    &self.times[..split],
                    &self.values[..split],
                    candidates,
                    binary,
                );
                let check_rows = Rows::merge(
                    &self.times[split..],
                    &self.values[split..],
                    candidates,
                    binary,
                );
                match self.config.clustering {
                    Clustering::Em(Components::Fixed(k)) => {
                        grow(&fit_rows, &check_rows, Some(k), &self.config, binary)?
                    }
                    Clustering::KMeans => grow(&fit_rows, &check_rows, None, &self.config, binary)?,
                    Clustering::Em(Components::Auto) => {
                        let mut best: Option<Structure> = None;
                        for k in 1..=self.config.max_components {
                            let s = grow(&fit_rows, &check_rows, Some(k), &self.config, binary)?;
                            if best.as_ref().is_none_or(|b| s.error < b.error) {
                                best = Some(s);
                            }
                        }
                        best.expect("max_components >= 1")
                    }
                }
            }
        };
        self.fitted = Fitted::fit(
            &all.times,
            &all.values,
            &all.weights,
            &structure.periods,
            structure.components,
            &self.config,
            binary,
        )?;
        self.periods = structure.periods;
        self.components = structure.components;
        Ok(())
    }

    /// Observes and refits, reporting fitting failures (which [`TemporalModel::observe`] can
    /// only report as an unchanged model).
    ///
    /// # Errors
    /// Observations violating the contract (the model is then unchanged), or a fit that
    /// failed.
    pub fn observe_and_fit(&mut self, times: &[f64], values: &[f64]) -> Result<(), BuildError> {
        validate(self.times.last().copied(), times, values)?;
        let previous = self.clone();
        self.times.extend_from_slice(times);
        self.values.extend_from_slice(values);
        if let Err(e) = self.refit() {
            *self = previous;
            return Err(e);
        }
        Ok(())
    }
}

impl TemporalModel for HypertimeModel {
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        match self.observe_and_fit(times, values) {
            Ok(()) => Ok(()),
            Err(BuildError::Observation(e)) => Err(e),
            // A clustering failure on valid data keeps the data and falls back to the mean.
            Err(_) => {
                self.times.extend_from_slice(times);
                self.values.extend_from_slice(values);
                let mean = self.values.iter().sum::<f64>() / self.values.len() as f64;
                self.periods.clear();
                self.components = 0;
                self.fitted = Fitted::Constant(mean);
                Ok(())
            }
        }
    }

    fn predict(&self, time: f64) -> f64 {
        self.predict_distribution(time).0.clamp(0.0, 1.0)
    }

    fn span(&self) -> ObservedSpan {
        let mut span = ObservedSpan::default();
        span.extend(&self.times);
        span
    }
}
