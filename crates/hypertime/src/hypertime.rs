//! Warped Hypertime ([Krajník 2019]): time projected onto circles, one pair of dimensions per
//! periodicity, and the result clustered into a Gaussian mixture.
//!
//! The method of [Krajník 2019] §III-B, for a state over time (a door, a robot's velocity):
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

pub mod events;

use serde::{Deserialize, Serialize};

use crate::mixture::{EmConfig, EmInit, GaussianMixture, fit_em_at_most};
use chronomap_core::Parallelism;
use chronomap_core::error::{BuildError, ConfigError, ObservationError};
use chronomap_core::model::TemporalModel;
use chronomap_core::observe::{ObservedSpan, validate};
use chronomap_core::periods::WEEK;

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
    /// Threads a fit may use (the component counts tried by `Auto` and EM's per-row loops);
    /// the model is the same on any. Default `Rayon(0)`; not stored (a model read back gets
    /// the default).
    #[serde(skip, default = "crate::mixture::all_threads")]
    pub parallelism: Parallelism,
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
            parallelism: Parallelism::Rayon(0),
        }
    }

    fn validate(&self) -> Result<(), ConfigError> {
        check_candidate_periods(&self.candidate_periods)?;
        if let Clustering::Em(Components::Fixed(0)) = self.clustering {
            return out_of_range("components", "0".into(), "at least 1");
        }
        if self.max_components == 0 {
            return out_of_range("max_components", "0".into(), "at least 1");
        }
        chronomap_core::select::check_holdout(self.holdout)?;
        if self.starts == 0 {
            return out_of_range("starts", "0".into(), "at least 1");
        }
        Ok(())
    }
}

/// A setting of a hypertime model out of its range.
pub(crate) fn out_of_range(
    name: &'static str,
    value: String,
    expected: &'static str,
) -> Result<(), ConfigError> {
    Err(ConfigError::OutOfRange {
        name,
        value,
        expected,
    })
}

/// The checks of every spectral model's candidate periods.
pub(crate) fn check_candidate_periods(periods: &[f64]) -> Result<(), ConfigError> {
    chronomap_core::periods::PeriodSet::from_periods(periods.to_vec())?;
    Ok(())
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

/// A state over time modelled by Warped Hypertime ([Krajník 2019]); a [`TemporalModel`].
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
        seed: chronomap_core::rng::derive_seed(config.seed, 0x4879_5445, stage, components as u64),
        parallelism: config.parallelism,
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
    fit_em_at_most(data, dim, Some(weights), components, |k| {
        em_config(config, k, stage)
    })
    .map(|fit| fit.mixture)
    .map_err(|e| BuildError::NotEnoughData(e.to_string()))
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

    /// Whether the fit can predict with `periods` (for models read from files): a constant
    /// in `[0, 1]`, or consistent mixtures over the hypertime vector of those periods with
    /// finite, non-negative weights.
    fn is_consistent(&self, periods: &[f64]) -> bool {
        let dim = 2 * periods.len();
        let mixture_ok = |m: &GaussianMixture, dim: usize| m.is_consistent() && m.dim() == dim;
        match self {
            Fitted::Constant(p) => (0.0..=1.0).contains(p),
            Fitted::Binary {
                positives,
                negatives,
                positive_weight,
                negative_weight,
                scale,
            } => {
                [*positive_weight, *negative_weight, *scale]
                    .iter()
                    .all(|v| v.is_finite() && *v >= 0.0)
                    && positives
                        .iter()
                        .chain(negatives)
                        .all(|m| mixture_ok(m, dim))
            }
            Fitted::Continuous { joint } => mixture_ok(joint, dim + 1),
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
pub fn strongest_period(
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
            && self.fitted.is_consistent(&self.periods)
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
        let split = chronomap_core::select::holdout_split(&self.times, self.config.holdout).ok();
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
                        // Every k independently (in parallel if allowed), then chosen in
                        // order: the result does not depend on the threads.
                        use rayon::prelude::*;
                        let ks = 1..=self.config.max_components;
                        let grow_k =
                            |k| grow(&fit_rows, &check_rows, Some(k), &self.config, binary);
                        let structures: Vec<Structure> = match self.config.parallelism {
                            Parallelism::Sequential => ks.map(grow_k).collect::<Result<_, _>>()?,
                            Parallelism::Rayon(_) => {
                                ks.into_par_iter().map(grow_k).collect::<Result<_, _>>()?
                            }
                        };
                        let mut best: Option<Structure> = None;
                        for s in structures {
                            // Fewer components unless more are clearly better.
                            if best
                                .as_ref()
                                .is_none_or(|b| s.error < b.error * (1.0 - 1e-9))
                            {
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

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_core::periods::DAY;

    #[test]
    fn projection_and_its_inverse() {
        let periods = [WEEK, DAY, DAY / 3.0];
        for i in 0..1000 {
            let t = 1_451_865_600.0 + 7_919.0 * f64::from(i) + 0.25;
            let mut x = Vec::new();
            project(t, &periods, &mut x);
            assert_eq!(x.len(), 6);
            for (k, &period) in periods.iter().enumerate() {
                let (cos, sin) = (x[2 * k], x[2 * k + 1]);
                assert!((cos * cos + sin * sin - 1.0).abs() < 1e-12, "on the circle");
                let back = phase_time(cos, sin, period);
                let expected = t.rem_euclid(period);
                let diff = (back - expected).abs();
                assert!(
                    diff < 1e-6 || (period - diff).abs() < 1e-6,
                    "t {t} period {period}: {back} vs {expected}"
                );
                // A point off the unit circle in the same direction gives the same time.
                assert!((phase_time(3.0 * cos, 3.0 * sin, period) - back).abs() < 1e-6);
            }
            // One period later: the same vector (what lets observations merge by week).
            let mut y = Vec::new();
            project(t + WEEK, &periods, &mut y);
            for (a, b) in x.iter().zip(&y) {
                assert!((a - b).abs() < 1e-9);
            }
        }
        assert_eq!(phase_time(1.0, 0.0, DAY), 0.0);
        assert!((phase_time(0.0, 1.0, DAY) - DAY / 4.0).abs() < 1e-9);
        assert!((phase_time(-1.0, -1e-18, DAY) - DAY / 2.0).abs() < 1e-6);
    }

    #[test]
    fn binary_rows_merge_by_second_of_the_week() {
        let times = [0.0, 60.0, WEEK, WEEK + 60.0, 2.0 * WEEK + 0.2];
        let values = [1.0, 0.0, 1.0, 1.0, 1.0];
        let candidates: Vec<f64> = (1..=84).map(|k| WEEK / f64::from(k)).collect();
        let rows = Rows::merge(&times, &values, &candidates, true);
        assert_eq!(rows.times, vec![0.0, 60.0, 60.0]);
        assert_eq!(rows.values, vec![1.0, 0.0, 1.0]);
        assert_eq!(rows.weights, vec![3.0, 1.0, 1.0]);
        // A candidate that does not divide the week: no merging.
        let rows = Rows::merge(&times, &values, &[WEEK, 100_000.0], true);
        assert_eq!(rows.weights, vec![1.0; 5]);
        // Continuous values are never merged.
        let rows = Rows::merge(&times, &values, &candidates, false);
        assert_eq!(rows.times, times.to_vec());
    }

    #[test]
    fn the_strongest_period_of_an_error_series() {
        // A daily cosine plus a weaker 8-hour one, sampled irregularly.
        let times: Vec<f64> = (0..3000).map(|i| 613.0 * f64::from(i) + 17.0).collect();
        let e: Vec<f64> = times
            .iter()
            .map(|&t| {
                (std::f64::consts::TAU * t / DAY).cos()
                    + 0.3 * (std::f64::consts::TAU * t / (DAY / 3.0)).sin()
            })
            .collect();
        let w = vec![1.0; times.len()];
        let candidates: Vec<f64> = (1..=84).map(|k| WEEK / f64::from(k)).collect();
        let (best, sum) = strongest_period(&times, &e, &w, &candidates, &[]);
        assert_eq!(best, Some(DAY));
        assert!(sum > 0.5 + 0.15 - 0.05, "{sum}");
        let (next, _) = strongest_period(&times, &e, &w, &candidates, &[DAY]);
        assert_eq!(next, Some(DAY / 3.0));
        // All candidates used: none left.
        assert_eq!(strongest_period(&times, &e, &w, &[DAY], &[DAY]).0, None);
    }

    /// A door open 8:00-18:00 every day, observed every 20 minutes for three weeks.
    fn daily_door() -> (Vec<f64>, Vec<f64>) {
        let times: Vec<f64> = (0..3 * 7 * 72)
            .map(|i| 1_451_865_600.0 + 1200.0 * f64::from(i))
            .collect();
        let values = times
            .iter()
            .map(|&t| f64::from(u8::from((8.0..18.0).contains(&((t % DAY) / 3600.0)))))
            .collect();
        (times, values)
    }

    #[test]
    fn a_daily_door_is_found_and_predicted() {
        let (times, values) = daily_door();
        for clustering in [Clustering::Em(Components::Fixed(2)), Clustering::KMeans] {
            let mut model = HypertimeModel::new(HypertimeConfig::new(clustering)).unwrap();
            model.observe(&times, &values).unwrap();
            assert_eq!(model.periods()[0], DAY, "{clustering:?}");
            let next_week = times[times.len() - 1] + 1200.0;
            let noon = next_week - next_week % DAY + 7.0 * DAY + 13.0 * 3600.0;
            let night = noon - 10.0 * 3600.0;
            assert!(
                model.predict(noon) > 0.9,
                "{clustering:?}: {}",
                model.predict(noon)
            );
            assert!(
                model.predict(night) < 0.1,
                "{clustering:?}: {}",
                model.predict(night)
            );
        }
    }

    #[test]
    fn sequential_and_parallel_fits_agree_bit_for_bit() {
        // Continuous values (not merged by week): 5040 rows, more than one chunk of EM's
        // per-row loops, and every component count of `Auto` tried.
        let times: Vec<f64> = (0..5 * 7 * 144)
            .map(|i| 1_451_865_600.0 + 600.0 * f64::from(i))
            .collect();
        let values: Vec<f64> = times
            .iter()
            .enumerate()
            .map(|(i, &t)| {
                let open = (8.0..18.0).contains(&((t % DAY) / 3600.0));
                0.2 + 0.5 * f64::from(u8::from(open)) + 0.01 * ((i * 7919) % 11) as f64
            })
            .collect();
        let fit = |parallelism: Parallelism| {
            let mut config = HypertimeConfig::new(Clustering::Em(Components::Auto));
            config.max_components = 3;
            config.max_periods = 2;
            config.parallelism = parallelism;
            let mut model = HypertimeModel::new(config).unwrap();
            model.observe(&times, &values).unwrap();
            let predictions: Vec<u64> = (0..200)
                .map(|i| {
                    model
                        .predict(times[0] + 35.0 * DAY + 1234.5 * f64::from(i))
                        .to_bits()
                })
                .collect();
            (model.periods().to_vec(), model.components(), predictions)
        };
        let sequential = fit(Parallelism::Sequential);
        assert_eq!(sequential.0[0], DAY, "{:?}", sequential.0);
        for parallelism in [Parallelism::Rayon(0), Parallelism::Rayon(3)] {
            assert!(fit(parallelism) == sequential, "{parallelism:?}");
        }
    }

    #[test]
    fn conformance() {
        let (times, values) = daily_door();
        let (times, values) = (&times[..60], &values[..60]);
        chronomap_core::conformance::check_temporal_model(
            || {
                HypertimeModel::new(HypertimeConfig::new(Clustering::Em(Components::Fixed(2))))
                    .unwrap()
            },
            times,
            values,
        );
        // Continuous values.
        let soft: Vec<f64> = values.iter().map(|v| 0.2 + 0.5 * v).collect();
        chronomap_core::conformance::check_temporal_model(
            || HypertimeModel::new(HypertimeConfig::new(Clustering::KMeans)).unwrap(),
            times,
            &soft,
        );
    }

    #[test]
    fn configuration_is_checked() {
        let mut config = HypertimeConfig::new(Clustering::Em(Components::Fixed(0)));
        assert!(HypertimeModel::new(config.clone()).is_err());
        config.clustering = Clustering::KMeans;
        config.holdout = 1.0;
        assert!(HypertimeModel::new(config.clone()).is_err());
        config.holdout = 0.25;
        config.candidate_periods = vec![DAY, -1.0];
        assert!(HypertimeModel::new(config.clone()).is_err());
        config.candidate_periods = vec![];
        assert!(HypertimeModel::new(config).is_err());
    }

    #[test]
    fn bad_observations_leave_the_model_unchanged() {
        let mut model = HypertimeModel::new(HypertimeConfig::new(Clustering::KMeans)).unwrap();
        let before = model.clone();
        assert!(model.observe(&[0.0, f64::NAN], &[0.0, 1.0]).is_err());
        assert!(model.observe(&[10.0, 5.0], &[0.0, 1.0]).is_err());
        assert!(model.observe(&[0.0, 5.0], &[0.0, 1.5]).is_err());
        assert_eq!(model, before);
        assert_eq!(model.predict(0.0), 0.5);
    }
}
