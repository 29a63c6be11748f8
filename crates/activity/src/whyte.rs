//! WHyTe (Warped Hypertime, [Krajník 2019]; Vintr et al. 2019) as a baseline of the CoPA-Map
//! comparison ([Stüde 2024] §4.3.2): rates of people from two Gaussian mixtures over warped
//! space-time.
//!
//! # Warping ([Krajník 2019] eqs. 1, 8)
//! A sample at the cell centre `x = [x1, x2]` and time `t` becomes the vector
//!
//! `w(x, t) = [(x1 − x̄1)/s, (x2 − x̄2)/s, cos(2πt/T₁), sin(2πt/T₁), …, sin(2πt/T_p)]`
//!
//! ([`chronomap_hypertime::hypertime::project`] appends the circles). Space is centred on the mean training
//! cell centre `x̄` and divided by one scale for both axes, `s = sqrt((var x1 + var x2) / 2)`
//! (so distances stay isotropic and each spatial axis has a variance of about 1), while every
//! circle has radius 1 (a variance of at most 1/2 per time dimension): no dimension dwarfs
//! the others, and the ridge that EM adds to every covariance
//! ([`WhyteConfig::regularization`], relative to the mean variance of the dimensions) is a
//! small, similar fraction of each. With every candidate period a divisor of the day (`day/k`),
//! `w(x, t) = w(x, t + day)`: samples are merged by cell and time of day into weighted points
//! before EM (at most cells × bins-per-day points), which is exact for weighted EM and makes the
//! fits fast.
//!
//! # The rate: a ratio of two mixtures ([Krajník 2019] eq. 2)
//! Sample `i` is `Δ_i` hours of observation (1 for the `x1,x2,t,y` grid files, see
//! [`Whyte::fit_with_dwell`]) during which `c_i = y_i Δ_i` people were seen; `C = Σ c_i`,
//! `D = Σ Δ_i`. People seen near `w` are `C·f_c(w)` and hours spent looking near `w` are
//! `D·f_Δ(w)`, with `f_c` the density of people and `f_Δ` the density of observation over warped
//! space-time, so the rate is their ratio
//!
//! `rate(x, t) = (C / D) · f_c(w(x, t)) / f_Δ(w(x, t))`
//!
//! (with unit dwell times `C / D = Σ y_i / N`, the global mean rate). This is a mixture-based
//! regression: the numerator alone is what the original WHyTe models (the density of
//! detections; [Stüde 2024] §4.3.2 notes that it "directly incorporates the detections without
//! accounting for varying observation times"); dividing by the density of observation corrects
//! for where and when the robot looked, so a place seen often is not mistaken for a busy one.
//! `C / D` plays the part of eq. (3)'s scaling: `∫ rate · D f_Δ = C`, the people observed.
//!
//! Both densities are Gaussian mixtures of the form of eq. (2), `Σ_j π_j N(w; μ_j, Σ_j)`, that
//! share their Gaussians. [`chronomap_hypertime::mixture::fit_em`] fits `f_c` to the warped samples weighted by
//! their people `c_i` (WHyTe's model of people); with its responsibilities `r_ij` at the
//! training points, component `j` explains `A_j = Σ_i c_i r_ij` people and `B_j = Σ_i Δ_i r_ij`
//! hours of observation, and
//!
//! `f_c = Σ_j (A_j / C) N_j`,   `f_Δ = Σ_j (B_j / D) N_j`,
//!
//! so that the rate is a convex combination of the components' rates `λ_j = A_j / B_j`, each the
//! observation-weighted mean rate of the samples it explains:
//!
//! `rate(x, t) = Σ_j g_j(w) λ_j`,   `g_j(w) = (B_j / D) N_j(w) / f_Δ(w)`.
//!
//! Sharing the Gaussians is what makes the ratio sound: two mixtures fitted independently (one
//! with weights `c_i`, one with weights `Δ_i`) put their components in different places and
//! orientations, and in the thin directions of hypertime (hourly bins lie on a few points of
//! each circle) their ratio swings over orders of magnitude between neighbouring points. Shared,
//! every prediction lies between the smallest and the largest `λ_j`, never above the largest
//! training rate.
//!
//! Where the robot (almost) never looked, the ratio means nothing: where
//! `f_Δ(w) < ε · f̄_Δ`, with `f̄_Δ` the `Δ`-weighted mean of `f_Δ` at the training points and
//! `ε` = [`WhyteConfig::min_relative_density`], the prediction is the global rate `C / D`.
//!
//! # Periodicities and components ([Krajník 2019] §III-B, eq. 7)
//! As WHyTe: start without periodicity (space only), predict the training samples and form the
//! error series of eq. (5) per time bin,
//!
//! `e(t) = Σ_{i: t_i = t} Δ_i (rate(x_i, t_i) − y_i) / Σ_{i: t_i = t} Δ_i`,
//!
//! take the strongest period of its non-uniform spectrum (eq. 7, the `strongest_period` of
//! [`chronomap_hypertime::hypertime`]) among the candidates `day/k`, `k = 1..=`[`WhyteConfig::harmonics`], not
//! used yet, add it (eq. 8), refit, and keep it while the error falls. As in
//! [`chronomap_hypertime::hypertime`], the error that decides (eq. 6) is measured on a chronological
//! hold-out — the last [`WhyteConfig::holdout`] of the distinct training times, fitted on the
//! rest — because the training error nearly always falls with more dimensions.
//! The number of components (shared by both densities) is chosen on the same hold-out among
//! [`WhyteConfig::components`]; the periods and components of the least hold-out error are
//! then refitted on all the training data.
//!
//! ```
//! use chronomap_activity::{RatePredictor, RateSamples, Whyte, WhyteConfig};
//!
//! // Two cells over six days of 12 hour bins: one busiest at hour 3, one at hour 9.
//! let mut samples = RateSamples::default();
//! for t in 0..72 {
//!     let c = (std::f64::consts::TAU * (f64::from(t) - 3.0) / 12.0).cos();
//!     samples.push([0.25, 0.25], f64::from(t), 12.0 + 10.0 * c)?;
//!     samples.push([5.25, 0.25], f64::from(t), 6.0 - 4.0 * c)?;
//! }
//! let model = Whyte::fit(&samples, &WhyteConfig::default())?;
//! assert_eq!(model.name(), "whyte");
//! assert_eq!(model.periods()[0], 12.0);
//! // The next day, hours 3 and 9 of its 12 recorded hours (t = 72 + 3, 72 + 9).
//! assert!(model.predict([0.25, 0.25], 75.0) > model.predict([5.25, 0.25], 75.0) + 8.0);
//! assert!(model.predict([0.25, 0.25], 81.0) + 3.0 < model.predict([5.25, 0.25], 81.0));
//! # Ok::<(), chronomap_activity::ActivityError>(())
//! ```

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

use super::init::check_dwell;
use super::{ActivityError, CellKey, RatePredictor, RateSamples};
use chronomap_core::par::Parallelism;
use chronomap_hypertime::hypertime::{project, strongest_period};
use chronomap_hypertime::mixture::{EmConfig, EmInit, GaussianMixture, fit_em_at_most};

/// How [`Whyte`] is fitted.
#[derive(Clone, Debug, PartialEq)]
pub struct WhyteConfig {
    /// Length of a day in units of `t` (default 12: the bundled ATC grid's 12 recorded hours a
    /// day).
    pub day_period: f64,
    /// Candidate periods are `day_period / k` for `k = 1..=harmonics` (default 6: 12, 6, 4, 3,
    /// 2.4 and 2 hours on the ATC grid, as Fr-AAM's).
    pub harmonics: usize,
    /// Most periodicities (pairs of hypertime dimensions) added. Default 6 (all candidates).
    pub max_periods: usize,
    /// Numbers of mixture components tried on the hold-out (default 4, 8, 16, 32).
    pub components: Vec<usize>,
    /// Fraction of the distinct training times, the most recent, held out to choose the
    /// periods and the components. Default 0.2.
    pub holdout: f64,
    /// Most EM iterations per fit. Default 100.
    pub max_iterations: usize,
    /// EM stops when the mean log-likelihood per unit weight rises by less than this.
    /// Default `1e-4`.
    pub tolerance: f64,
    /// EM starts per fit (the best likelihood wins). Default 1.
    pub starts: usize,
    /// Ridge added to every covariance diagonal, relative to the mean variance of the warped
    /// dimensions. Default `1e-3`.
    pub regularization: f64,
    /// `ε`: where the observation density is below `ε` times its mean at the training points,
    /// the prediction is the global rate. Default `1e-3`.
    pub min_relative_density: f64,
    /// Seed of the EM initialisations.
    pub seed: u64,
    /// Whether the candidate numbers of components are tried in parallel (results do not
    /// depend on it; each EM also splits its rows over the rayon pool).
    pub parallelism: Parallelism,
}

impl Default for WhyteConfig {
    fn default() -> Self {
        WhyteConfig {
            day_period: 12.0,
            harmonics: 6,
            max_periods: 6,
            components: vec![4, 8, 16, 32],
            holdout: 0.2,
            max_iterations: 100,
            tolerance: 1e-4,
            starts: 1,
            regularization: 1e-3,
            min_relative_density: 1e-3,
            seed: 0,
            parallelism: Parallelism::Sequential,
        }
    }
}

impl WhyteConfig {
    fn check(&self) -> Result<(), ActivityError> {
        let bad = |what: String| Err(ActivityError::Config(what));
        if !(self.day_period.is_finite() && self.day_period > 0.0) {
            return bad(format!(
                "day period {} must be a positive number",
                self.day_period
            ));
        }
        if self.harmonics == 0 {
            return bad("harmonics must be at least 1".into());
        }
        if self.components.is_empty() || self.components.contains(&0) {
            return bad(format!(
                "components {:?}: give one or more numbers, each at least 1",
                self.components
            ));
        }
        if !(self.holdout > 0.0 && self.holdout < 1.0) {
            return bad(format!(
                "hold-out fraction {} must be in (0, 1)",
                self.holdout
            ));
        }
        if self.max_iterations == 0 || self.starts == 0 {
            return bad("max_iterations and starts must be at least 1".into());
        }
        for (name, v) in [
            ("tolerance", self.tolerance),
            ("regularization", self.regularization),
            ("min_relative_density", self.min_relative_density),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{name} {v} must be a finite number >= 0"));
            }
        }
        Ok(())
    }

    /// The candidate periods `day / k`.
    fn candidates(&self) -> Vec<f64> {
        (1..=self.harmonics)
            .map(|k| self.day_period / k as f64)
            .collect()
    }
}

/// One configuration tried on the hold-out.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WhyteTrial {
    /// Mixture components asked for.
    pub components: usize,
    /// The periods kept by the search (in the order found).
    pub periods: Vec<f64>,
    /// Dwell-weighted mean squared error of the rates on the hold-out (eq. 6).
    pub holdout_mse: f64,
}

/// Space is centred and divided by one scale (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
struct SpaceScaling {
    centre: [f64; 2],
    scale: f64,
}

impl SpaceScaling {
    fn of(x: &[[f64; 2]]) -> Self {
        let n = x.len().max(1) as f64;
        let centre = [
            x.iter().map(|p| p[0]).sum::<f64>() / n,
            x.iter().map(|p| p[1]).sum::<f64>() / n,
        ];
        let var = x
            .iter()
            .map(|p| (p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2))
            .sum::<f64>()
            / (2.0 * n);
        let scale = if var > 0.0 && var.is_finite() {
            var.sqrt()
        } else {
            1.0
        };
        SpaceScaling { centre, scale }
    }

    /// `w(x, t)` of the module doc, appended to `out`.
    fn warp(&self, x: [f64; 2], t: f64, periods: &[f64], out: &mut Vec<f64>) {
        out.push((x[0] - self.centre[0]) / self.scale);
        out.push((x[1] - self.centre[1]) / self.scale);
        project(t, periods, out);
    }
}

/// Samples merged by cell and time of day (the same warped vector for every candidate
/// period): observation time and people per point, and the point of every sample.
struct Merged {
    /// Cell centre and time of day of every point.
    points: Vec<([f64; 2], f64)>,
    /// `Σ Δ_i` per point.
    observed: Vec<f64>,
    /// `Σ c_i = Σ y_i Δ_i` per point.
    people: Vec<f64>,
    /// The point of every merged sample, in the order given.
    of_sample: Vec<usize>,
}

impl Merged {
    fn new(x: &[[f64; 2]], t: &[f64], y: &[f64], dwell: &[f64], idx: &[usize], day: f64) -> Self {
        let mut index: HashMap<(CellKey, u64), usize> = HashMap::new();
        let mut merged = Merged {
            points: Vec::new(),
            observed: Vec::new(),
            people: Vec::new(),
            of_sample: Vec::with_capacity(idx.len()),
        };
        for &i in idx {
            // `+ 0.0` turns -0.0 into 0.0.
            let phase = t[i].rem_euclid(day) + 0.0;
            let key = (CellKey::of(x[i]), phase.to_bits());
            let p = *index.entry(key).or_insert_with(|| {
                merged.points.push((x[i], phase));
                merged.observed.push(0.0);
                merged.people.push(0.0);
                merged.points.len() - 1
            });
            merged.observed[p] += dwell[i];
            merged.people[p] += y[i] * dwell[i];
            merged.of_sample.push(p);
        }
        merged
    }

    fn warped(&self, space: &SpaceScaling, periods: &[f64]) -> Vec<f64> {
        let mut data = Vec::with_capacity(self.points.len() * (2 + 2 * periods.len()));
        for &(x, phase) in &self.points {
            space.warp(x, phase, periods, &mut data);
        }
        data
    }
}

/// The observation mixture and the rate of every component.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Fitted {
    /// `f_Δ`: the Gaussians of `f_c` weighted by observation time; `None` when nobody was
    /// seen (every rate 0).
    observed: Option<GaussianMixture>,
    /// `λ_j` of every component.
    rates: Vec<f64>,
    /// `C / D`.
    rate: f64,
    /// `ln(ε f̄_Δ)`: below it, the prediction is `rate`.
    log_floor: f64,
}

impl Fitted {
    fn fit(
        merged: &Merged,
        space: &SpaceScaling,
        periods: &[f64],
        components: usize,
        config: &WhyteConfig,
    ) -> Result<Fitted, ActivityError> {
        let dim = 2 + 2 * periods.len();
        let total_observed: f64 = merged.observed.iter().sum();
        let total_people: f64 = merged.people.iter().sum();
        let rate = total_people / total_observed;
        if total_people <= 0.0 {
            return Ok(Fitted {
                observed: None,
                rates: Vec::new(),
                rate,
                log_floor: f64::NEG_INFINITY,
            });
        }
        let data = merged.warped(space, periods);
        let people = fit_mixture(
            &data,
            dim,
            &merged.people,
            components,
            config,
            periods.len(),
        )?;
        // Responsibilities under f_c; A_j = Σ c_i r_ij, B_j = Σ Δ_i r_ij.
        let k = people.components();
        let (mut a, mut b) = (vec![0.0; k], vec![0.0; k]);
        let mut log_r = vec![0.0; k];
        for ((w, &c), &d) in data
            .chunks_exact(dim)
            .zip(&merged.people)
            .zip(&merged.observed)
        {
            people.component_log_densities(w, &mut log_r);
            let total = log_sum_exp(&log_r);
            for j in 0..k {
                let r = (log_r[j] - total).exp();
                if r.is_finite() {
                    a[j] += c * r;
                    b[j] += d * r;
                }
            }
        }
        // Components no observation falls in carry no weight (and no people either).
        let keep: Vec<usize> = (0..k).filter(|&j| b[j] > 0.0).collect();
        let means = keep.iter().flat_map(|&j| people.mean(j).to_vec()).collect();
        let covariances = keep
            .iter()
            .flat_map(|&j| people.covariance(j).to_vec())
            .collect();
        let weights = keep.iter().map(|&j| b[j] / total_observed).collect();
        let observed = GaussianMixture::new(dim, weights, means, covariances)
            .map_err(|e| ActivityError::Config(format!("WHyTe mixture: {e}")))?;
        let rates = keep.iter().map(|&j| a[j] / b[j]).collect();
        // f̄_Δ: the Δ-weighted mean of f_Δ at the training points.
        let mean_density = data
            .chunks_exact(dim)
            .zip(&merged.observed)
            .map(|(w, d)| d * observed.log_density(w).exp())
            .sum::<f64>()
            / total_observed;
        Ok(Fitted {
            observed: Some(observed),
            rates,
            rate,
            log_floor: (config.min_relative_density * mean_density).ln(),
        })
    }

    /// Components of the fit.
    fn components(&self) -> usize {
        self.rates.len()
    }

    /// The rate at the warped point `w`: `Σ_j λ_j π_j^Δ N_j(w) / f_Δ(w)`.
    fn rate_at(&self, w: &[f64]) -> f64 {
        let Some(observed) = &self.observed else {
            return 0.0;
        };
        let mut log_g = vec![0.0; self.rates.len()];
        observed.component_log_densities(w, &mut log_g);
        let log_observed = log_sum_exp(&log_g);
        if !(log_observed >= self.log_floor && log_observed.is_finite()) {
            // Where the robot (almost) never looked: the global rate.
            return self.rate;
        }
        log_g
            .iter()
            .zip(&self.rates)
            .map(|(l, r)| (l - log_observed).exp() * r)
            .sum()
    }
}

/// `ln Σ exp(v)`, `-∞` for an empty or all `-∞` slice.
fn log_sum_exp(v: &[f64]) -> f64 {
    let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !max.is_finite() {
        return max;
    }
    max + v.iter().map(|x| (x - max).exp()).sum::<f64>().ln()
}

/// EM with at most `components` components (fewer if there are fewer distinct points).
fn fit_mixture(
    data: &[f64],
    dim: usize,
    weights: &[f64],
    components: usize,
    config: &WhyteConfig,
    periods: usize,
) -> Result<GaussianMixture, ActivityError> {
    let em = |k: usize| EmConfig {
        components: k,
        max_iterations: config.max_iterations,
        tolerance: config.tolerance,
        regularization: config.regularization,
        relative_regularization: true,
        starts: config.starts,
        init: EmInit::KMeansPlusPlus,
        parallelism: config.parallelism,
        seed: chronomap_core::rng::derive_seed(
            config.seed,
            0x0057_4879_5465,
            periods as u64,
            k as u64,
        ),
    };
    fit_em_at_most(data, dim, Some(weights), components, em)
        .map(|fit| fit.mixture)
        .map_err(|e| ActivityError::Config(format!("WHyTe mixture: {e}")))
}

/// WHyTe as a [`RatePredictor`]: the ratio of a mixture of people to a mixture of
/// observation over warped space-time (module doc).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Whyte {
    periods: Vec<f64>,
    components: usize,
    space: SpaceScaling,
    fitted: Fitted,
    trials: Vec<WhyteTrial>,
}

/// The training samples in the form the fits need.
struct Training<'a> {
    x: &'a [[f64; 2]],
    t: &'a [f64],
    y: &'a [f64],
    dwell: &'a [f64],
    space: SpaceScaling,
    config: &'a WhyteConfig,
    candidates: Vec<f64>,
}

impl Training<'_> {
    fn merge(&self, idx: &[usize]) -> Merged {
        Merged::new(
            self.x,
            self.t,
            self.y,
            self.dwell,
            idx,
            self.config.day_period,
        )
    }

    fn fit(&self, merged: &Merged, periods: &[f64], k: usize) -> Result<Fitted, ActivityError> {
        Fitted::fit(merged, &self.space, periods, k, self.config)
    }

    /// The rate at every point of `merged`.
    fn point_rates(&self, model: &Fitted, merged: &Merged, periods: &[f64]) -> Vec<f64> {
        let dim = 2 + 2 * periods.len();
        merged
            .warped(&self.space, periods)
            .chunks_exact(dim)
            .map(|w| model.rate_at(w))
            .collect()
    }

    /// Dwell-weighted mean squared error of `model` on the samples `idx` (merged as `merged`).
    fn mse(&self, model: &Fitted, merged: &Merged, idx: &[usize], periods: &[f64]) -> f64 {
        let rates = self.point_rates(model, merged, periods);
        let (mut sum, mut weight) = (0.0, 0.0);
        for (&i, &p) in idx.iter().zip(&merged.of_sample) {
            let e = rates[p] - self.y[i];
            sum += self.dwell[i] * e * e;
            weight += self.dwell[i];
        }
        sum / weight
    }

    /// Eq. (5) per time bin: the dwell-weighted mean error at every distinct time of `idx`,
    /// with the dwell time of the bin as its weight.
    fn error_series(
        &self,
        model: &Fitted,
        merged: &Merged,
        idx: &[usize],
        periods: &[f64],
    ) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let rates = self.point_rates(model, merged, periods);
        let mut bins: HashMap<u64, usize> = HashMap::new();
        let (mut times, mut errors, mut weights) = (Vec::new(), Vec::new(), Vec::new());
        for (&i, &p) in idx.iter().zip(&merged.of_sample) {
            let b = *bins.entry((self.t[i] + 0.0).to_bits()).or_insert_with(|| {
                times.push(self.t[i]);
                errors.push(0.0);
                weights.push(0.0);
                times.len() - 1
            });
            errors[b] += self.dwell[i] * (rates[p] - self.y[i]);
            weights[b] += self.dwell[i];
        }
        for (e, w) in errors.iter_mut().zip(&weights) {
            *e /= w;
        }
        (times, errors, weights)
    }

    /// [Krajník 2019] §III-B with `k` components: periods added while the hold-out error falls.
    fn grow(
        &self,
        fit_idx: &[usize],
        held_idx: &[usize],
        k: usize,
    ) -> Result<WhyteTrial, ActivityError> {
        let fit_part = self.merge(fit_idx);
        let held = self.merge(held_idx);
        let mut periods: Vec<f64> = Vec::new();
        let mut model = self.fit(&fit_part, &periods, k)?;
        let mut error = self.mse(&model, &held, held_idx, &periods);
        while periods.len() < self.config.max_periods {
            let (times, errors, weights) = self.error_series(&model, &fit_part, fit_idx, &periods);
            let (next, _) = strongest_period(&times, &errors, &weights, &self.candidates, &periods);
            let Some(next) = next else { break };
            let mut extended = periods.clone();
            extended.push(next);
            let candidate = self.fit(&fit_part, &extended, k)?;
            let candidate_error = self.mse(&candidate, &held, held_idx, &extended);
            if candidate_error.is_nan() || candidate_error >= error {
                break;
            }
            periods = extended;
            model = candidate;
            error = candidate_error;
        }
        Ok(WhyteTrial {
            components: k,
            periods,
            holdout_mse: error,
        })
    }
}

impl Whyte {
    /// Fits WHyTe to training rates, each sample counting as one hour of observation
    /// (`Δ_i = 1`: the `x1,x2,t,y` grid files carry rates only).
    ///
    /// # Errors
    /// [`ActivityError::Empty`] without training samples, [`ActivityError::Config`] for an
    /// invalid configuration (or a mixture that could not be fitted).
    pub fn fit(train: &RateSamples, config: &WhyteConfig) -> Result<Self, ActivityError> {
        Self::fit_with_dwell(train, &vec![1.0; train.len()], config)
    }

    /// Fits WHyTe with the observation time `dwell[i]` (hours) of every sample: the
    /// observation density is weighted by `Δ_i`, the people density by `y_i Δ_i`.
    ///
    /// # Errors
    /// As [`Whyte::fit`], and [`ActivityError::LengthMismatch`] /
    /// [`ActivityError::NonFinite`] for dwell times that are not one positive finite number
    /// per sample.
    pub fn fit_with_dwell(
        train: &RateSamples,
        dwell: &[f64],
        config: &WhyteConfig,
    ) -> Result<Self, ActivityError> {
        config.check()?;
        if train.is_empty() {
            return Err(ActivityError::Empty);
        }
        check_dwell(dwell, train.len())?;
        let data = Training {
            x: train.x(),
            t: train.t(),
            y: train.y(),
            dwell,
            space: SpaceScaling::of(train.x()),
            config,
            candidates: config.candidates(),
        };
        let mut components: Vec<usize> = config.components.clone();
        components.sort_unstable();
        components.dedup();

        // The chronological hold-out: the last `holdout` of the distinct training times.
        let mut times = train.t().to_vec();
        times.sort_by(f64::total_cmp);
        times.dedup();
        let trials: Vec<WhyteTrial> = if times.len() < 2 {
            // Nothing to hold out: space only, the fewest components.
            Vec::new()
        } else {
            let first_held = ((times.len() as f64 * (1.0 - config.holdout)).ceil() as usize)
                .clamp(1, times.len() - 1);
            let cut = times[first_held];
            let (fit_idx, held_idx): (Vec<usize>, Vec<usize>) =
                (0..train.len()).partition(|&i| train.t()[i] < cut);
            let grow = |&k: &usize| data.grow(&fit_idx, &held_idx, k);
            match config.parallelism {
                Parallelism::Sequential => components.iter().map(grow).collect::<Result<_, _>>(),
                Parallelism::Rayon(_) => {
                    use rayon::prelude::*;
                    components.par_iter().map(grow).collect::<Result<_, _>>()
                }
            }?
        };
        // The least hold-out error; fewer components unless more are clearly better.
        let mut best: Option<&WhyteTrial> = None;
        for trial in &trials {
            if best.is_none_or(|b| trial.holdout_mse < b.holdout_mse * (1.0 - 1e-9)) {
                best = Some(trial);
            }
        }
        let (periods, k) = match best {
            Some(b) => (b.periods.clone(), b.components),
            None => (Vec::new(), components[0]),
        };
        let all: Vec<usize> = (0..train.len()).collect();
        let merged = data.merge(&all);
        let fitted = data.fit(&merged, &periods, k)?;
        let components = fitted.components();
        Ok(Whyte {
            periods,
            components,
            space: data.space,
            fitted,
            trials,
        })
    }

    /// The periods chosen, in the order found (units of `t`).
    pub fn periods(&self) -> &[f64] {
        &self.periods
    }

    /// Mixture components of the final fit (of the observation density; the people density
    /// has as many or, with fewer distinct points, fewer).
    pub fn components(&self) -> usize {
        self.components
    }

    /// Every configuration tried on the hold-out, in increasing number of components (empty
    /// when the training data have a single time).
    pub fn trials(&self) -> &[WhyteTrial] {
        &self.trials
    }

    /// The global rate `C / D`, predicted where the robot never looked.
    pub fn global_rate(&self) -> f64 {
        self.fitted.rate
    }
}

impl RatePredictor for Whyte {
    fn name(&self) -> &str {
        "whyte"
    }

    fn predict(&self, x: [f64; 2], t: f64) -> f64 {
        let mut w = Vec::with_capacity(2 + 2 * self.periods.len());
        self.space.warp(x, t, &self.periods, &mut w);
        self.fitted.rate_at(&w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{GlobalMean, score};

    /// Two cells 5 m apart over `days` days of 12 hour bins: the first busy in the morning
    /// (12 + 10 cos(2π(t − 3)/12) people an hour, most at hour 3), the second in the afternoon
    /// (6 − 4 cos(…), most at hour 9). Their rhythms must not cancel: the error series of
    /// eq. (5) is summed over space, so exactly opposite rhythms would show no period at all.
    fn morning_and_afternoon(days: u32) -> RateSamples {
        let mut s = RateSamples::default();
        for t in 0..12 * days {
            let c = (std::f64::consts::TAU * (f64::from(t) - 3.0) / 12.0).cos();
            s.push([0.25, 0.25], f64::from(t), 12.0 + 10.0 * c).unwrap();
            s.push([5.25, 0.25], f64::from(t), 6.0 - 4.0 * c).unwrap();
        }
        s
    }

    fn small() -> WhyteConfig {
        WhyteConfig {
            components: vec![2, 4],
            ..WhyteConfig::default()
        }
    }

    #[test]
    fn finds_the_day_and_predicts_the_busy_cell_at_the_right_phase() {
        let (train, test) = morning_and_afternoon(8).split_at(72.0);
        let model = Whyte::fit(&train, &WhyteConfig::default()).unwrap();
        assert_eq!(model.periods()[0], 12.0, "{:?}", model.trials());
        for t in 72..96 {
            let t = f64::from(t);
            let (a, b) = (
                model.predict([0.25, 0.25], t),
                model.predict([5.25, 0.25], t),
            );
            match t % 12.0 {
                // The first cell is busier by at least 18 in truth, the second by at least 6.4.
                2.0..=4.0 => assert!(a > b + 8.0, "t {t}: {a} vs {b}"),
                8.0..=10.0 => assert!(b > a + 3.0, "t {t}: {a} vs {b}"),
                _ => {}
            }
        }
        // The global mean (9 everywhere) scores NRMSE sqrt((59 + 17) / 2) / 9 = 0.685; WHyTe is
        // at least ten times better (24 points of warped space-time, up to 32 components: it
        // can be exact).
        let flat = score(&GlobalMean::fit(&train).unwrap(), &test).unwrap();
        assert!((flat.nrmse - 38f64.sqrt() / 9.0).abs() < 1e-9, "{flat:?}");
        let whyte = score(&model, &test).unwrap();
        assert!(whyte.nrmse < flat.nrmse / 10.0, "{whyte:?} vs {flat:?}");
        // Every number of components was tried on the hold-out; an unseen place far away gets
        // the global rate.
        assert_eq!(model.trials().len(), 4);
        assert!((model.global_rate() - 9.0).abs() < 1e-12);
        assert_eq!(model.predict([500.0, 500.0], 75.0), model.global_rate());
        // With at most 4 components it is smoother but still finds the day and halves the
        // global mean's error.
        let coarse = Whyte::fit(&train, &small()).unwrap();
        assert_eq!(coarse.periods(), [12.0]);
        assert!(score(&coarse, &test).unwrap().nrmse < flat.nrmse / 2.0);
    }

    #[test]
    fn without_a_rhythm_no_period_is_kept() {
        // A busy and a quiet cell, constant over time: space alone explains everything.
        let mut s = RateSamples::default();
        for t in 0..60 {
            s.push([0.25, 0.25], f64::from(t), 10.0).unwrap();
            s.push([3.25, 0.25], f64::from(t), 1.0).unwrap();
        }
        let model = Whyte::fit(&s, &small()).unwrap();
        assert!(model.periods().is_empty(), "{:?}", model.periods());
        assert!((model.predict([0.25, 0.25], 70.0) - 10.0).abs() < 0.1);
        assert!((model.predict([3.25, 0.25], 70.0) - 1.0).abs() < 0.1);
    }

    #[test]
    fn the_observation_density_corrects_for_where_the_robot_looked() {
        // Two cells with the same rate 5; the first seen four times as often. A density of
        // people alone would call it four times busier; the ratio does not.
        let mut s = RateSamples::default();
        for t in 0..40 {
            for _ in 0..4 {
                s.push([0.25, 0.25], f64::from(t), 5.0).unwrap();
            }
            s.push([4.25, 0.25], f64::from(t), 5.0).unwrap();
        }
        let model = Whyte::fit(&s, &small()).unwrap();
        for x in [[0.25, 0.25], [4.25, 0.25]] {
            assert!((model.predict(x, 50.0) - 5.0).abs() < 1e-6, "{x:?}");
        }
        // Dwell times count as observation: the same cell seen for 3 hours at rate 2 and
        // 1 hour at rate 6 has rate (6 + 6) / 4 = 3.
        let s = RateSamples::new(
            vec![[0.25, 0.25]; 4],
            vec![0.0, 1.0, 2.0, 3.0],
            vec![2.0, 6.0, 2.0, 6.0],
        )
        .unwrap();
        let model = Whyte::fit_with_dwell(&s, &[3.0, 1.0, 3.0, 1.0], &small()).unwrap();
        assert!((model.global_rate() - 3.0).abs() < 1e-12);
    }

    #[test]
    fn the_same_seed_gives_the_same_model() {
        let train = morning_and_afternoon(4);
        let a = Whyte::fit(&train, &small()).unwrap();
        let b = Whyte::fit(&train, &small()).unwrap();
        assert_eq!(a, b);
        // In parallel: the same bits.
        let par = WhyteConfig {
            parallelism: Parallelism::Rayon(2),
            ..small()
        };
        assert_eq!(Whyte::fit(&train, &par).unwrap(), a);
        let at: Vec<f64> = (0..24)
            .map(|t| a.predict([0.25, 0.25], f64::from(t)))
            .collect();
        let again: Vec<f64> = (0..24)
            .map(|t| b.predict([0.25, 0.25], f64::from(t)))
            .collect();
        assert_eq!(at, again);
    }

    #[test]
    fn bad_input_and_configurations_are_errors() {
        assert_eq!(
            Whyte::fit(&RateSamples::default(), &small()),
            Err(ActivityError::Empty)
        );
        let s = morning_and_afternoon(1);
        for config in [
            WhyteConfig {
                day_period: 0.0,
                ..small()
            },
            WhyteConfig {
                harmonics: 0,
                ..small()
            },
            WhyteConfig {
                components: vec![],
                ..small()
            },
            WhyteConfig {
                components: vec![0, 4],
                ..small()
            },
            WhyteConfig {
                holdout: 1.0,
                ..small()
            },
            WhyteConfig {
                regularization: f64::NAN,
                ..small()
            },
        ] {
            assert!(
                matches!(Whyte::fit(&s, &config), Err(ActivityError::Config(_))),
                "{config:?}"
            );
        }
        assert!(matches!(
            Whyte::fit_with_dwell(&s, &[1.0], &small()),
            Err(ActivityError::LengthMismatch { .. })
        ));
        let mut dwell = vec![1.0; s.len()];
        dwell[3] = 0.0;
        assert!(matches!(
            Whyte::fit_with_dwell(&s, &dwell, &small()),
            Err(ActivityError::NonFinite {
                index: 3,
                field: "dwell",
                ..
            })
        ));
    }

    #[test]
    fn degenerate_data_still_fit() {
        // One sample: one time, one point, one component.
        let one = RateSamples::new(vec![[1.0, 2.0]], vec![3.0], vec![4.0]).unwrap();
        let model = Whyte::fit(&one, &small()).unwrap();
        assert!(model.periods().is_empty());
        assert_eq!(model.components(), 1);
        assert!((model.predict([1.0, 2.0], 9.0) - 4.0).abs() < 1e-9);
        // Nobody ever seen: rate 0 everywhere.
        let none =
            RateSamples::new(vec![[0.0, 0.0], [1.0, 0.0]], vec![0.0, 1.0], vec![0.0, 0.0]).unwrap();
        let model = Whyte::fit(&none, &small()).unwrap();
        assert_eq!(model.predict([0.0, 0.0], 5.0), 0.0);
    }
}
