//! PerGaM: a periodic Gaussian mixture over the time of day, fitted by EM on the circle.
//!
//! # Model ([Santos 2017] §4.3.2, eqs. (7)–(9))
//! A Gaussian mixture approximates a function as a weighted sum of Gaussians (eq. (7)). To
//! make it periodic with a period `P` known a priori (one day by default), the observations
//! are first folded onto one period (eq. (8)): the period is cut into `B` bins (default 1440,
//! one minute each) and each observed bin `b` gets the mean `p'_b = sum_b / n_b` of the `n_b`
//! observations whose `t mod P` fell into it. A mixture is then fitted to `p'` by Expectation
//! Maximisation and evaluated at `t mod P` (eq. (9)).
//!
//! # Wrap-around
//! The time of day lives on a circle: 23:50 and 0:10 are 20 minutes apart. The original
//! implementation fitted ordinary Gaussians on `[0, P)` (after rotating the histogram), so a
//! bump straddling midnight was cut in two. Here every component is a *wrapped* normal
//! density on the circle,
//!
//! ```text
//! g_j(x) = Σ_{m=−2..2} 𝒩(x + mP; μ_j, σ_j),    g(x) = Σ_{j=1..K} π_j g_j(x),
//! ```
//!
//! (σ is at most `P/2`, so the images beyond `|m| = 2` are negligible), and EM treats the image
//! `m` as part of the latent variable.
//!
//! # Fitting
//! The data are the bin centres `c_b` of the observed bins, weighted by `p'_b`. EM starts
//! from `μ_j = (j + ½)·P/K`, `σ_j = P/(2K)`, `π_j = 1/K` and iterates
//!
//! * E-step: responsibilities `r_{bjm} ∝ π_j 𝒩(c_b + mP; μ_j, σ_j)`, normalised jointly over
//!   the component `j` and the image `m`;
//! * M-step: with `W_j = Σ_{b,m} p'_b r_{bjm}`, `μ_j = Σ p'_b r_{bjm} (c_b + mP) / W_j` wrapped
//!   into `[0, P)`, `σ_j² = Σ p'_b r_{bjm} (c_b + mP − μ_j)² / W_j` with `σ_j` floored at one
//!   bin width and capped at `P/2`, and `π_j = W_j / Σ W`;
//!
//! until the weighted log-likelihood `Σ_b p'_b ln g(c_b)` improves by less than `1e-10` of its
//! magnitude, or for at most 500 iterations. A component whose responsibilities all
//! underflow keeps its mean and width and gets weight 0.
//!
//! From that single start EM stalls at a saddle, or lets one broad component absorb
//! everything, whenever the bumps of the data lie halfway between the initial means (two
//! bumps at 12:00 and 23:50 with `K = 2` and initial means at 6:00 and 18:00, for example).
//! The fit therefore runs EM from [`STARTS`] = 4 deterministic starts, the grid of means
//! rotated by `s·P/(4K)` for `s = 0..4` (rotations by `P/K` only relabel components), and
//! keeps the run with the highest log-likelihood (the unrotated grid on ties).
//!
//! # Prediction and scale
//! EM fits a *density* (`∫ g = 1` over the period), while eq. (9) predicts a probability with
//! unnormalised weights `w_j`: the overall scale of `p'` is absorbed into them. We recover it
//! as the least-squares scale of the density against the folded data, weighting each bin by
//! its number of observations:
//!
//! ```text
//! A = Σ_b n_b p'_b g(c_b) / Σ_b n_b g(c_b)²,    p(t) = ς(A · g(t mod P)),
//! ```
//!
//! i.e. `w_j = A π_j` in eq. (9), with `ς` the saturation to `[0, 1]`. A model that has seen
//! nothing predicts 0.5; one that has seen only zeros predicts 0 (no mixture is fitted).
//!
//! The fit is computed lazily on first use after new observations (or a new number of
//! components) and cached. The per-bin sums are exact ([`ExactSum`](crate::exact::ExactSum), kept by a [`HistogramModel`]), so the model does not
//! depend on how the observations were batched.
//!
//! # Complexity
//! Observing is `O(1)` per observation. A fit costs `O(S · I · K · B)` for `S = 4` starts of
//! `I ≤ 500` iterations; a prediction `O(K)`.

use std::f64::consts::TAU;
use std::sync::OnceLock;

use serde::{Deserialize, Serialize};

use crate::error::{ConfigError, ObservationError};
use crate::hist::HistogramModel;
use crate::model::{Ordered, TemporalModel, saturate};
use crate::observe::ObservedSpan;
use crate::periods::{DAY, cycle_fraction};

/// Largest number of mixture components.
pub const MAX_COMPONENTS: usize = 16;
/// Largest number of bins per period.
pub const MAX_BINS: usize = 1 << 16;
/// Largest number of EM iterations.
pub const MAX_ITERATIONS: usize = 500;
/// EM stops when the weighted log-likelihood improves by less than this fraction.
pub const RELATIVE_TOLERANCE: f64 = 1e-10;
/// Number of EM starts: the initial grid of means rotated by `s·P/(K·STARTS)`,
/// `s = 0..STARTS` (see the [module docs](self)).
pub const STARTS: usize = 4;
/// Images `x + mP` summed in the wrapped normal density.
const WRAPS: [f64; 5] = [-2.0, -1.0, 0.0, 1.0, 2.0];

/// Configuration of a [`PergamModel`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PergamConfig {
    /// Number of mixture components `K` (`1..=16`).
    pub components: usize,
    /// The period `P` in seconds (default one day).
    pub period_secs: f64,
    /// Number of bins the period is folded into (`2..=65536`, default 1440: one minute per
    /// bin for a day). The bin width is also the smallest σ a component may have.
    pub bins: usize,
}

impl Default for PergamConfig {
    fn default() -> Self {
        PergamConfig {
            components: 2,
            period_secs: DAY,
            bins: 1440,
        }
    }
}

impl PergamConfig {
    /// Default configuration (one day, 1440 bins) with `components` components.
    pub fn with_components(components: usize) -> Self {
        PergamConfig {
            components,
            ..PergamConfig::default()
        }
    }

    /// Checks the configuration.
    ///
    /// # Errors
    /// [`ConfigError::OutOfRange`] for a number of components or bins out of range,
    /// [`ConfigError::PeriodNotPositive`] for a period that is not positive and finite.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(1..=MAX_COMPONENTS).contains(&self.components) {
            return Err(ConfigError::OutOfRange {
                name: "components",
                value: self.components.to_string(),
                expected: "1 ..= 16",
            });
        }
        if !(2..=MAX_BINS).contains(&self.bins) {
            return Err(ConfigError::OutOfRange {
                name: "bins",
                value: self.bins.to_string(),
                expected: "2 ..= 65536",
            });
        }
        if !(self.period_secs.is_finite() && self.period_secs > 0.0) {
            return Err(ConfigError::PeriodNotPositive {
                period_secs: self.period_secs,
            });
        }
        Ok(())
    }

    /// Width of one bin in seconds.
    pub fn bin_width_secs(&self) -> f64 {
        self.period_secs / self.bins as f64
    }
}

/// One wrapped normal component of a fitted mixture.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PergamComponent {
    /// Mixture weight `π_j` (the weights of a fit sum to 1).
    pub weight: f64,
    /// Mean `μ_j` in seconds into the period, in `[0, P)`.
    pub mean_secs: f64,
    /// Standard deviation `σ_j` in seconds.
    pub sigma_secs: f64,
}

impl PergamComponent {
    /// Wrapped normal density of the component (without its weight) at `x` seconds into a
    /// period of `period_secs`, per second.
    pub fn density(&self, x: f64, period_secs: f64) -> f64 {
        let inv_sigma = 1.0 / self.sigma_secs;
        let norm = inv_sigma / TAU.sqrt();
        WRAPS
            .iter()
            .map(|&m| {
                let z = (x + m * period_secs - self.mean_secs) * inv_sigma;
                (-0.5 * z * z).exp()
            })
            .sum::<f64>()
            * norm
    }
}

/// A fitted mixture (computed lazily, cached).
#[derive(Clone, Debug, PartialEq)]
pub struct PergamFit {
    /// The `K` components, in the order of their initial means (empty when every observed
    /// value is 0).
    pub components: Vec<PergamComponent>,
    /// The least-squares scale `A` of the density (see the [module docs](self)).
    pub scale: f64,
    /// Number of EM iterations (M-steps) of the chosen start.
    pub iterations: usize,
    /// Final weighted log-likelihood `Σ_b p'_b ln g(c_b)`.
    pub log_likelihood: f64,
}

/// Periodic Gaussian mixture model (see the [module docs](self)).
///
/// ```
/// use chronomap_core::{PergamModel, TemporalModel};
///
/// // Somebody is in the kitchen from 23:30 to 0:10 every night, observed every 5 minutes.
/// let times: Vec<f64> = (0..7 * 288).map(|i| 300.0 * i as f64).collect();
/// let present: Vec<f64> = times.iter().map(|t| (t % 86_400.0) / 3600.0)
///     .map(|hour| ((hour >= 23.5 || hour < 1.0 / 6.0) as u8) as f64)
///     .collect();
/// let mut kitchen = PergamModel::with_components(1)?;
/// kitchen.observe(&times, &present)?;
/// let bump = kitchen.components()[0];
/// // One bump at 23:50 (± 5 min: the samples are 5 min apart), across midnight.
/// assert!((bump.mean_secs - (23.0 * 3600.0 + 50.0 * 60.0)).abs() < 300.0);
/// assert!(kitchen.predict(0.0) > 0.5 && kitchen.predict(12.0 * 3600.0) < 0.01);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PergamModel {
    config: PergamConfig,
    /// The fold of eq. (8): per-bin sums and counts over the period.
    fold: HistogramModel,
    #[serde(skip)]
    fit: OnceLock<PergamFit>,
}

impl PartialEq for PergamModel {
    fn eq(&self, other: &Self) -> bool {
        self.config == other.config && self.fold == other.fold
    }
}

impl Default for PergamModel {
    fn default() -> Self {
        PergamModel::new(PergamConfig::default()).expect("default config is valid")
    }
}

impl PergamModel {
    /// An empty model.
    ///
    /// # Errors
    /// If the configuration is invalid ([`PergamConfig::validate`]).
    pub fn new(config: PergamConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(PergamModel {
            fold: HistogramModel::new(config.bins, config.period_secs)?,
            config,
            fit: OnceLock::new(),
        })
    }

    /// An empty model over one day in 1440 bins with `components` components.
    ///
    /// # Errors
    /// If `components` is not in `1..=16`.
    pub fn with_components(components: usize) -> Result<Self, ConfigError> {
        PergamModel::new(PergamConfig::with_components(components))
    }

    /// The configuration.
    pub fn config(&self) -> &PergamConfig {
        &self.config
    }

    /// Bin of a time.
    pub fn bin_of(&self, time: f64) -> usize {
        self.fold.bin_of(time)
    }

    /// Centre `c_b` of bin `b`, in seconds into the period.
    pub fn bin_centre_secs(&self, bin: usize) -> f64 {
        (bin as f64 + 0.5) * self.config.bin_width_secs()
    }

    /// The folded data `p'_b` of eq. (8): per-bin means (`None` for bins never observed).
    pub fn bin_means(&self) -> Vec<Option<f64>> {
        self.fold.bin_means()
    }

    /// The fitted mixture (computed on first use after new observations).
    pub fn fit(&self) -> &PergamFit {
        self.fit.get_or_init(|| self.compute_fit())
    }

    /// The fitted components (empty while every observed value is 0).
    pub fn components(&self) -> &[PergamComponent] {
        &self.fit().components
    }

    /// Mixture density `g(t mod P)` per second (0 when no mixture is fitted).
    pub fn density(&self, time: f64) -> f64 {
        let x = cycle_fraction(time, self.config.period_secs) * self.config.period_secs;
        mixture_density(&self.fit().components, x, self.config.period_secs)
    }

    /// Checks internal consistency (for models read from files).
    pub fn is_consistent(&self) -> bool {
        self.config.validate().is_ok()
            && self.fold.is_consistent()
            && self.fold.bins() == self.config.bins
            && self.fold.period_secs() == self.config.period_secs
    }

    fn compute_fit(&self) -> PergamFit {
        let period = self.config.period_secs;
        let observed: Vec<(f64, f64, f64)> = self
            .fold
            .bin_means()
            .iter()
            .zip(self.fold.bin_counts())
            .enumerate()
            .filter_map(|(b, (mean, &n))| mean.map(|m| (self.bin_centre_secs(b), m, n as f64)))
            .collect();
        let points: Vec<(f64, f64)> = observed
            .iter()
            .filter(|&&(_, y, _)| y > 0.0)
            .map(|&(x, y, _)| (x, y))
            .collect();
        if points.is_empty() {
            return PergamFit {
                components: Vec::new(),
                scale: 0.0,
                iterations: 0,
                log_likelihood: 0.0,
            };
        }
        let (components, iterations, log_likelihood) = fit_wrapped_mixture(
            &points,
            self.config.components,
            period,
            self.config.bin_width_secs(),
        );
        let (mut num, mut den) = (0.0, 0.0);
        for &(x, y, n) in &observed {
            let g = mixture_density(&components, x, period);
            num += n * y * g;
            den += n * g * g;
        }
        let scale = if den > 0.0 && num.is_finite() {
            num / den
        } else {
            0.0
        };
        PergamFit {
            components,
            scale,
            iterations,
            log_likelihood,
        }
    }
}

/// Density of a mixture of wrapped normals at `x` seconds into the period.
fn mixture_density(components: &[PergamComponent], x: f64, period: f64) -> f64 {
    components
        .iter()
        .map(|c| c.weight * c.density(x, period))
        .sum()
}

/// EM for a mixture of `k` wrapped normals on the circle `[0, period)` fitted to the points
/// `(x, weight)` (weights > 0), from [`STARTS`] rotated grids; see the [module docs](self).
/// Returns the components, the number of iterations and the final weighted log-likelihood
/// of the best run.
fn fit_wrapped_mixture(
    points: &[(f64, f64)],
    k: usize,
    period: f64,
    min_sigma: f64,
) -> (Vec<PergamComponent>, usize, f64) {
    let mut best: Option<(Vec<PergamComponent>, usize, f64)> = None;
    for start in 0..STARTS {
        let offset = start as f64 * period / (k * STARTS) as f64;
        let run = run_em(points, k, period, min_sigma, offset);
        // Strictly better only: on ties the earlier start (the unrotated grid) wins.
        if best.as_ref().is_none_or(|b| run.2 > b.2) {
            best = Some(run);
        }
    }
    best.expect("STARTS > 0")
}

/// `x` wrapped into `[0, period)`.
fn wrap(x: f64, period: f64) -> f64 {
    let r = x.rem_euclid(period);
    if r >= period { 0.0 } else { r }
}

/// One EM run from the grid `μ_j = (j + ½)·P/K + offset`.
fn run_em(
    points: &[(f64, f64)],
    k: usize,
    period: f64,
    min_sigma: f64,
    offset: f64,
) -> (Vec<PergamComponent>, usize, f64) {
    let max_sigma = period / 2.0;
    let clamp_sigma = |s: f64| s.max(min_sigma).min(max_sigma);
    let mut components: Vec<PergamComponent> = (0..k)
        .map(|j| PergamComponent {
            weight: 1.0 / k as f64,
            mean_secs: wrap((j as f64 + 0.5) * period / k as f64 + offset, period),
            sigma_secs: clamp_sigma(period / (2.0 * k as f64)),
        })
        .collect();
    let log_norm = -0.5 * TAU.ln();
    let slots = k * WRAPS.len();
    let mut log_terms = vec![0.0; slots];
    let mut previous = f64::NEG_INFINITY;
    let mut iterations = 0;
    loop {
        // E-step, accumulating the M-step's sufficient statistics on the fly: per component,
        // Σ p' r, Σ p' r d and Σ p' r d² with d = x + mP − μ_j (deviation from the old mean).
        let prepared: Vec<(f64, f64, f64)> = components
            .iter()
            .map(|c| {
                (
                    c.weight.ln() - c.sigma_secs.ln() + log_norm,
                    c.mean_secs,
                    0.5 / (c.sigma_secs * c.sigma_secs),
                )
            })
            .collect();
        let mut stats = vec![(0.0f64, 0.0f64, 0.0f64); k];
        let mut log_likelihood = 0.0;
        for &(x, y) in points {
            let mut max = f64::NEG_INFINITY;
            for (j, &(log_coef, mean, inv_two_var)) in prepared.iter().enumerate() {
                for (w, &m) in WRAPS.iter().enumerate() {
                    let d = x + m * period - mean;
                    let l = log_coef - d * d * inv_two_var;
                    log_terms[j * WRAPS.len() + w] = l;
                    max = max.max(l);
                }
            }
            let mut total = 0.0;
            for l in log_terms.iter_mut() {
                // Terms below e^-45 of the largest (together < 1e-17 of the total) are
                // skipped: most images lie many σ away from their component.
                let relative = *l - max;
                *l = if relative > -45.0 {
                    relative.exp()
                } else {
                    0.0
                };
                total += *l;
            }
            log_likelihood += y * (max + total.ln());
            let y_over_total = y / total;
            for (j, &(_, mean, _)) in prepared.iter().enumerate() {
                let stat = &mut stats[j];
                for (w, &m) in WRAPS.iter().enumerate() {
                    let wr = y_over_total * log_terms[j * WRAPS.len() + w];
                    let d = x + m * period - mean;
                    stat.0 += wr;
                    stat.1 += wr * d;
                    stat.2 += wr * d * d;
                }
            }
        }
        let converged =
            iterations > 0 && log_likelihood - previous <= RELATIVE_TOLERANCE * previous.abs();
        if converged || iterations == MAX_ITERATIONS {
            return (components, iterations, log_likelihood);
        }
        // M-step.
        let total_weight: f64 = stats.iter().map(|s| s.0).sum();
        for (c, &(w, sum_d, sum_d2)) in components.iter_mut().zip(&stats) {
            if w > 0.0 {
                let shift = sum_d / w;
                c.mean_secs = wrap(c.mean_secs + shift, period);
                c.sigma_secs = clamp_sigma((sum_d2 / w - shift * shift).max(0.0).sqrt());
                c.weight = w / total_weight;
            } else {
                c.weight = 0.0;
            }
        }
        previous = log_likelihood;
        iterations += 1;
    }
}

impl TemporalModel for PergamModel {
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        self.fold.observe(times, values)?;
        self.fit = OnceLock::new();
        Ok(())
    }

    fn predict(&self, time: f64) -> f64 {
        if self.fold.span().count == 0 {
            return 0.5;
        }
        let fit = self.fit();
        if fit.scale == 0.0 {
            return 0.0;
        }
        saturate(fit.scale * self.density(time))
    }

    fn span(&self) -> ObservedSpan {
        self.fold.span()
    }
}

impl Ordered for PergamModel {
    /// The number of components `K`.
    fn order(&self) -> usize {
        self.config.components
    }

    fn max_order(&self) -> usize {
        MAX_COMPONENTS
    }

    /// Sets `K`, clamped to `1..=16` (a mixture needs at least one component).
    fn set_order(&mut self, order: usize) {
        let components = order.clamp(1, MAX_COMPONENTS);
        if components != self.config.components {
            self.config.components = components;
            self.fit = OnceLock::new();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conformance::check_temporal_model;

    const HOUR: f64 = 3600.0;
    const START: f64 = 1_451_865_600.0; // Monday 2016-01-04 00:00 UTC

    /// Irregular times (60–300 s apart) over `days` days and the state `open(hour of day)`.
    fn series(days: f64, open: impl Fn(f64) -> bool) -> (Vec<f64>, Vec<f64>) {
        let (mut times, mut values) = (Vec::new(), Vec::new());
        let (mut t, mut i) = (START, 0u64);
        while t < START + days * DAY {
            times.push(t);
            values.push(if open(cycle_fraction(t, DAY) * 24.0) {
                1.0
            } else {
                0.0
            });
            i += 1;
            t += 60.0 + ((i * 2_654_435_761) % 240) as f64;
        }
        (times, values)
    }

    /// Distance on the circle of one day, in seconds.
    fn circular_distance(a: f64, b: f64) -> f64 {
        let d = (a - b).rem_euclid(DAY);
        d.min(DAY - d)
    }

    fn fitted(components: usize, times: &[f64], values: &[f64]) -> PergamModel {
        let mut model = PergamModel::with_components(components).unwrap();
        model.observe(times, values).unwrap();
        model
    }

    #[test]
    fn conforms_to_the_temporal_model_contract() {
        // Weekday office door 8:00–18:00 with a lunch break, three weeks, sparser sampling.
        let (times, values) = series(21.0, |h| {
            (8.0..12.0).contains(&h) || (13.0..18.0).contains(&h)
        });
        let times: Vec<f64> = times.iter().step_by(5).copied().collect();
        let values: Vec<f64> = values.iter().step_by(5).copied().collect();
        for k in [1, 2] {
            check_temporal_model(|| PergamModel::with_components(k).unwrap(), &times, &values);
        }
    }

    #[test]
    fn recovers_a_two_bump_daily_pattern() {
        // Open 7:30–8:30 and 16:45–17:45: bumps centred at 8:00 and 17:15.
        let (times, values) = series(14.0, |h| {
            (7.5..8.5).contains(&h) || (16.75..17.75).contains(&h)
        });
        let model = fitted(2, &times, &values);
        let fit = model.fit();
        assert!(fit.iterations < MAX_ITERATIONS, "EM did not converge");
        let mut means: Vec<f64> = fit.components.iter().map(|c| c.mean_secs).collect();
        means.sort_by(f64::total_cmp);
        assert!((means[0] - 8.0 * HOUR).abs() < 180.0, "means {means:?}");
        assert!((means[1] - 17.25 * HOUR).abs() < 180.0, "means {means:?}");
        for c in &fit.components {
            // Equal bumps, equal weights; a 1 h boxcar has σ = 1 h / √12 ≈ 17.3 min.
            assert!((c.weight - 0.5).abs() < 0.05, "{c:?}");
            assert!((c.sigma_secs - HOUR / 12f64.sqrt()).abs() < 180.0, "{c:?}");
        }
        let day = START + 30.0 * DAY;
        assert!(model.predict(day + 8.0 * HOUR) > 0.6);
        assert!(model.predict(day + 17.25 * HOUR) > 0.6);
        assert!(model.predict(day + 12.5 * HOUR) < 0.01);
        assert!(model.predict(day + 2.0 * HOUR) < 0.01);
    }

    #[test]
    fn a_bump_across_midnight_is_one_component() {
        // Open 23:20–0:20: one bump centred at 23:50, straddling midnight.
        let across_midnight = |h: f64| !(0.0 + 1.0 / 3.0..23.0 + 1.0 / 3.0).contains(&h);
        let (times, values) = series(14.0, across_midnight);
        let centre = 23.0 * HOUR + 50.0 * 60.0;
        let model = fitted(1, &times, &values);
        let c = model.components()[0];
        assert!(circular_distance(c.mean_secs, centre) < 180.0, "{c:?}");
        assert!((c.sigma_secs - HOUR / 12f64.sqrt()).abs() < 180.0, "{c:?}");
        let day = START + 30.0 * DAY;
        assert!(model.predict(day) > 0.6, "0:00 → {}", model.predict(day));
        let before = day - 20.0 * 60.0; // 23:40
        assert!(
            model.predict(before) > 0.6,
            "23:40 → {}",
            model.predict(before)
        );
        assert!(model.predict(day + 12.0 * HOUR) < 0.01);

        // With a second bump at noon, each bump gets one component: the midnight bump is not
        // split at 0:00.
        let (times, values) = series(14.0, |h| across_midnight(h) || (11.5..12.5).contains(&h));
        let model = fitted(2, &times, &values);
        let mut means: Vec<f64> = model.components().iter().map(|c| c.mean_secs).collect();
        means.sort_by(f64::total_cmp);
        assert!((means[0] - 12.0 * HOUR).abs() < 180.0, "means {means:?}");
        assert!(
            circular_distance(means[1], centre) < 180.0,
            "means {means:?}"
        );
        assert!(model.predict(day) > 0.6 && model.predict(before) > 0.6);
    }

    #[test]
    fn scale_is_the_least_squares_fit_of_the_density() {
        let (times, values) = series(7.0, |h| (9.0..11.0).contains(&h));
        let model = fitted(1, &times, &values);
        let (mut num, mut den) = (0.0, 0.0);
        for (b, mean) in model.bin_means().iter().enumerate() {
            if let Some(p) = mean {
                let g = model.density(model.bin_centre_secs(b));
                let n = model.fold.bin_counts()[b] as f64;
                num += n * p * g;
                den += n * g * g;
            }
        }
        assert!((model.fit().scale - num / den).abs() <= 1e-12 * model.fit().scale);
        let t = START + 10.0 * HOUR;
        assert!((model.predict(t) - saturate(num / den * model.density(t))).abs() < 1e-15);
    }

    #[test]
    fn empty_all_zero_and_order_changes() {
        let mut model = PergamModel::default();
        assert_eq!(model.predict(0.0), 0.5);
        assert_eq!(model.order(), 2);
        model
            .observe(&[0.0, 100.0, 5000.0], &[0.0, 0.0, 0.0])
            .unwrap();
        assert!(model.components().is_empty());
        assert_eq!(model.predict(100.0), 0.0);
        assert_eq!(model.predict(50_000.0), 0.0);

        let (times, values) = series(7.0, |h| {
            (9.0..10.0).contains(&h) || (15.0..16.0).contains(&h)
        });
        let mut model = fitted(1, &times, &values);
        assert_eq!(model.components().len(), 1);
        model.set_order(3);
        assert_eq!((model.order(), model.components().len()), (3, 3));
        model.set_order(100);
        assert_eq!((model.order(), model.max_order()), (16, 16));
        model.set_order(0);
        assert_eq!(model.order(), 1);
        let weights: f64 = model.components().iter().map(|c| c.weight).sum();
        assert!((weights - 1.0).abs() < 1e-12);
    }

    #[test]
    fn rejects_bad_configurations() {
        assert!(matches!(
            PergamModel::with_components(0),
            Err(ConfigError::OutOfRange {
                name: "components",
                ..
            })
        ));
        assert!(PergamModel::with_components(17).is_err());
        assert!(PergamModel::with_components(16).is_ok());
        let bad_bins = PergamConfig {
            bins: 1,
            ..PergamConfig::default()
        };
        assert!(matches!(
            PergamModel::new(bad_bins),
            Err(ConfigError::OutOfRange { name: "bins", .. })
        ));
        let bad_period = PergamConfig {
            period_secs: -1.0,
            ..PergamConfig::default()
        };
        assert!(matches!(
            PergamModel::new(bad_period),
            Err(ConfigError::PeriodNotPositive { .. })
        ));
    }

    #[test]
    fn survives_a_serde_round_trip() {
        let (times, values) = series(3.0, |h| (9.0..10.0).contains(&h));
        let model = fitted(2, &times, &values);
        let bytes = postcard::to_allocvec(&model).unwrap();
        let back: PergamModel = postcard::from_bytes(&bytes).unwrap();
        assert!(back.is_consistent());
        assert_eq!(back, model);
        for t in [START, START + 9.5 * HOUR, START + 20.0 * HOUR] {
            assert_eq!(back.predict(t).to_bits(), model.predict(t).to_bits());
        }
    }
}
