//! CoPA-Map as a [`RatePredictor`]: the heteroscedastic SVGP of [`crate::gp`] ([Stüde 2024]
//! eqs. 4.7–4.16) with the input and output scaling of the original implementation.
//!
//! * Space is scaled onto `[0, 1]` with one scale for both axes (distances keep their ratio),
//!   time by the span of the training times; rates are standardised (zero mean, unit variance).
//! * The temporal kernel starts with the day and its first harmonics (`day_period` in units of
//!   `t`, [`PeriodInitMode::Day`], the default) or with the periods and variances of
//!   Algorithm 4.1 (a NUDFT of sampled 5 m regions, [`super::init::initial_periods`];
//!   [`PeriodInitMode::Spectral`], the day again when it finds no period); periods are then
//!   trained with the other hyperparameters. The inducing
//!   points are k-means centres of the training inputs weighted by their observation durations
//!   ([`super::init::inducing_points`]; equal weights for grid files, which carry none).
//! * Negative predicted rates are set to zero, as §4.2.3 does.
//! * Predictive intervals ([`RatePredictor::interval`] and
//!   [`RatePredictor::observation_interval`]) come from the marginals of both latent GPs:
//!   of a whole bin, the latent rate function `f` alone ([`CopaMap::bin_intervals`]); of one
//!   observation, `f` plus the heteroscedastic noise `ζ(g) ε` of eq. 4.7, a scale mixture of
//!   normals ([`CopaMap::observation_intervals`]).

use serde::{Deserialize, Serialize};

use super::init::{PeriodInit, SpectralInitConfig, inducing_points, initial_periods};
use super::{RatePredictor, RateSamples};
use crate::gp::{
    ActivityKernel, GpError, HeteroSvgp, PeriodicComponent, Point, Prediction, RbfKernel,
    TrainConfig, train_with_progress,
};
use chronomap_core::par::Parallelism;
use chronomap_core::progress::{NoProgress, Progress};

/// Where the periods of CoPA-Map's temporal kernel start.
///
/// The default is [`PeriodInitMode::Day`]: on the bundled ATC grid (train `t < 96`, test the
/// last two days) it scores better than Algorithm 4.1, whose `ψ = 2` clusters merge the 6 h
/// and 12 h peaks (periods 11.1 and 30.5): NRMSE 2.0284 vs 2.0502 (χ² 217,628 vs 232,332)
/// with the defaults, 2.0415 vs 2.0439 (χ² 239,119 vs 234,049) with 100 inducing points and
/// 150 iterations.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum PeriodInitMode {
    /// Algorithm 4.1 ([Stüde 2024] §4.2.4): periods and variances from the spectra of sampled
    /// regions ([`initial_periods`]); the day and its harmonics if it finds none.
    Spectral,
    /// The day (`day_period`) and its `harmonics − 1` first harmonics, variances `0.5 / h`.
    #[default]
    Day,
}

/// How CoPA-Map is fitted.
#[derive(Clone, Debug, PartialEq)]
pub struct CopaConfig {
    /// Inducing points `M` (cost per iteration `O(B·M² + M³)`).
    pub inducing: usize,
    /// Training iterations (each a natural-gradient step on `q(u)` and an Adam step).
    pub iterations: usize,
    /// Minibatch size `B`.
    pub batch_size: usize,
    /// Length of a day in units of `t` (12 for the ATC grid's 12 recorded hours a day).
    pub day_period: f64,
    /// Periodic components of [`PeriodInitMode::Day`] (and of its fallback): the day and its
    /// harmonics day/2, …
    pub harmonics: usize,
    /// Where the periods start.
    pub init: PeriodInitMode,
    /// Parameters of Algorithm 4.1 for [`PeriodInitMode::Spectral`].
    pub spectral: SpectralInitConfig,
    /// Seed of the minibatches.
    pub seed: u64,
    /// Threads of the kernel evaluations (results do not depend on it).
    pub parallelism: Parallelism,
    /// The scale the GP models the rates on.
    pub target: RateScale,
}

/// The scale on which CoPA-Map models the rates `y`.
///
/// Rates seen by a moving robot are heavy-tailed: a cell glimpsed for seconds with one person
/// in it reads hundreds of people per hour. [`RateScale::Log1p`] models `ln(1 + y)` and
/// predicts `exp(m) − 1` for the predictive mean `m` of `ln(1 + y)` (the predictive median of
/// the rate), which follows what is typical rather than the spikes; [`RateScale::Rate`] models
/// `y` itself, as §4.2 writes it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum RateScale {
    /// Model the rates themselves (standardised).
    #[default]
    Rate,
    /// Model `ln(1 + y)` (standardised) and predict `exp(m) − 1`.
    Log1p,
}

impl RateScale {
    fn forward(self, y: f64) -> f64 {
        match self {
            RateScale::Rate => y,
            RateScale::Log1p => y.ln_1p(),
        }
    }

    /// The rate of a value `v` on this scale, clipped at 0 (monotone, so quantiles of `v` are
    /// quantiles of the rate).
    fn inverse(self, v: f64) -> f64 {
        match self {
            RateScale::Rate => v.max(0.0),
            RateScale::Log1p => v.exp_m1().max(0.0),
        }
    }
}

impl Default for CopaConfig {
    fn default() -> Self {
        CopaConfig {
            inducing: 200,
            iterations: 300,
            batch_size: 1000,
            day_period: 12.0,
            harmonics: 2,
            init: PeriodInitMode::default(),
            spectral: SpectralInitConfig::default(),
            seed: 0,
            parallelism: Parallelism::Sequential,
            target: RateScale::default(),
        }
    }
}

/// A fitted CoPA-Map.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CopaMap {
    model: HeteroSvgp,
    scaling: InputScaling,
    mean: f64,
    sd: f64,
    target: RateScale,
    /// Minibatch ELBO after every iteration.
    pub trace: Vec<f64>,
    /// What Algorithm 4.1 found (with [`PeriodInitMode::Spectral`]).
    #[serde(default)]
    pub period_init: Option<PeriodInit>,
}

impl CopaMap {
    /// Fits CoPA-Map to training rates, every sample weighing the same in the initialisation.
    ///
    /// # Errors
    /// Fewer training samples than inducing points, a configuration out of range, or a
    /// kernel matrix that is not positive definite.
    pub fn fit(train_samples: &RateSamples, config: &CopaConfig) -> Result<Self, GpError> {
        Self::fit_init(train_samples, None, config, &NoProgress)
    }

    /// [`CopaMap::fit`], reporting the stage `CoPA-Map` with one step per training iteration
    /// to `progress`. The result is the same.
    ///
    /// # Errors
    /// As [`CopaMap::fit`].
    pub fn fit_with_progress(
        train_samples: &RateSamples,
        config: &CopaConfig,
        progress: &dyn Progress,
    ) -> Result<Self, GpError> {
        Self::fit_init(train_samples, None, config, progress)
    }

    /// Fits CoPA-Map to training rates observed for `dwell[i]` hours each: the durations weight
    /// the initial inducing points and the series of Algorithm 4.1 (§4.2.4).
    ///
    /// # Errors
    /// As [`CopaMap::fit`], and durations that are not one positive number per sample.
    pub fn fit_with_dwell(
        train_samples: &RateSamples,
        dwell: &[f64],
        config: &CopaConfig,
    ) -> Result<Self, GpError> {
        Self::fit_init(train_samples, Some(dwell), config, &NoProgress)
    }

    fn fit_init(
        train_samples: &RateSamples,
        dwell: Option<&[f64]>,
        config: &CopaConfig,
        progress: &dyn Progress,
    ) -> Result<Self, GpError> {
        let n = train_samples.len();
        check_fit(
            n,
            config.inducing,
            config.inducing,
            config.harmonics,
            config.day_period,
        )?;
        let ys: Vec<f64> = train_samples
            .y()
            .iter()
            .map(|&y| config.target.forward(y))
            .collect();
        let mean = ys.iter().sum::<f64>() / n as f64;
        let sd = (ys.iter().map(|y| (y - mean).powi(2)).sum::<f64>() / n as f64)
            .sqrt()
            .max(1e-12);
        let scaling = InputScaling::of(train_samples, config.day_period);
        let x = scaling.apply_all(train_samples);
        let y: Vec<f64> = ys.iter().map(|v| (v - mean) / sd).collect();
        // Inducing points: k-means centres of the inputs weighted by observation duration.
        let z = inducing_points(&x, dwell, config.inducing, config.seed)
            .map_err(|e| GpError::InvalidInput(e.to_string()))?;
        let period_init = match config.init {
            PeriodInitMode::Spectral => Some(
                initial_periods(train_samples, dwell, &config.spectral)
                    .map_err(|e| GpError::InvalidInput(format!("period initialisation: {e}")))?,
            ),
            PeriodInitMode::Day => None,
        };
        let components: Vec<PeriodicComponent> = match &period_init {
            Some(init) if !init.periods.is_empty() => init
                .periods
                .iter()
                .zip(&init.variances)
                .map(|(&period, &variance)| PeriodicComponent {
                    variance,
                    lengthscale: 0.4,
                    period: period / scaling.time_scale,
                })
                .collect(),
            _ => day_harmonics(config.day_period / scaling.time_scale, config.harmonics),
        };
        let mut model = HeteroSvgp::new(
            ActivityKernel::new(0.3, [0.05, 0.05], &components),
            RbfKernel::new(0.5, [0.05, 0.05, 0.05]),
            z,
        );
        let train_config = fit_training(config.iterations, config.batch_size, n, config.seed);
        progress.stage("CoPA-Map", config.iterations as u64);
        let trace = train_with_progress(
            &mut model,
            &x,
            &y,
            &train_config,
            config.parallelism,
            progress,
        )?;
        Ok(CopaMap {
            model,
            scaling,
            mean,
            sd,
            target: config.target,
            trace,
            period_init,
        })
    }

    /// The rates and their standard deviations of `predict_with_std` from the GP's prediction
    /// in scaled units.
    fn rates(&self, prediction: Prediction) -> (Vec<f64>, Vec<f64>) {
        prediction
            .mean
            .iter()
            .zip(&prediction.std)
            .map(|(f, s)| {
                let (m, s) = (self.mean + self.sd * f, s * self.sd);
                match self.target {
                    RateScale::Rate => (m.max(0.0), s),
                    // 1 + y is log-normal: median e^m, std sqrt((e^{s²} − 1) e^{2m + s²}).
                    RateScale::Log1p => (
                        m.exp_m1().max(0.0),
                        ((s * s).exp_m1() * (2.0 * m + s * s).exp()).sqrt(),
                    ),
                }
            })
            .unzip()
    }

    /// Central intervals of probability `coverage` (in `(0, 1)`) of the rate of a *whole bin*
    /// at many points: the latent rate function `f` of [Stüde 2024] eq. 4.7 — the model's rate
    /// with the observation noise `ζ(g) ε` left out — under its predictive marginal
    /// `N(m_f, v_f)` (eqs. 4.13–4.14): `m_f ± z √v_f`, `z` the standard normal quantile of
    /// `(1 + coverage) / 2`, turned into rates by the de-standardisation and the scale of the
    /// fit (`μ + σ_y v` with [`RateScale::Rate`], `exp(μ + σ_y v) − 1` with
    /// [`RateScale::Log1p`]; clipped at 0, as [`RatePredictor::predict`] is).
    ///
    /// `v_f` is the uncertainty of the *function* and shrinks as data accumulate: CoPA-Map puts
    /// every deviation from a function smooth in space and time — glimpses' counting noise and
    /// the hour-to-hour swings of the real rate alike — into `ζ(g)`. Where whole bins vary
    /// about `f` by more than `f` is uncertain, these intervals hold fewer of them than
    /// `coverage` says (compare [`LogAdditive`](crate::LogAdditive)'s, which estimate that
    /// spread: [`crate::nugget`]).
    ///
    /// # Errors
    /// Non-finite inputs, `coverage` outside `(0, 1)`.
    pub fn bin_intervals(
        &self,
        points: &[([f64; 2], f64)],
        coverage: f64,
        par: Parallelism,
    ) -> Result<Vec<(f64, f64)>, GpError> {
        use statrs::distribution::{ContinuousCDF, Normal};
        check_coverage(coverage)?;
        let z = Normal::standard().inverse_cdf(0.5 + coverage / 2.0);
        let latent = self
            .model
            .predict_latent(&self.scaling.apply_points(points), par)?;
        Ok(latent
            .f_mean
            .iter()
            .zip(&latent.f_var)
            .map(|(&m, &v)| self.rate_interval(m, z * v.sqrt()))
            .collect())
    }

    /// Central intervals of probability `coverage` (in `(0, 1)`) of *one observation* like the
    /// training samples at many points: the rate `y = f + ζ(g) ε` of [Stüde 2024] eq. 4.7
    /// under the marginals of `f` and `g` (eqs. 4.13–4.16), `m_f ± h` with `h` the half-width
    /// of that scale mixture of normals ([`HeteroGaussian::central_half_width`](
    /// crate::gp::HeteroGaussian::central_half_width): the mixture over `g`, not the normal of
    /// eq. 4.19's variance `v_f + E[ζ(g)²]`, whose tails are too light), turned into rates as
    /// [`CopaMap::bin_intervals`] does.
    ///
    /// # Errors
    /// Non-finite inputs, `coverage` outside `(0, 1)`.
    pub fn observation_intervals(
        &self,
        points: &[([f64; 2], f64)],
        coverage: f64,
        par: Parallelism,
    ) -> Result<Vec<(f64, f64)>, GpError> {
        check_coverage(coverage)?;
        let latent = self
            .model
            .predict_latent(&self.scaling.apply_points(points), par)?;
        let likelihood = &self.model.likelihood;
        Ok((0..points.len())
            .map(|i| {
                let h = likelihood.central_half_width(
                    latent.f_var[i],
                    latent.g_mean[i],
                    latent.g_var[i],
                    coverage,
                );
                self.rate_interval(latent.f_mean[i], h)
            })
            .collect())
    }

    /// The rates of the standardised interval `m ± h`.
    fn rate_interval(&self, m: f64, h: f64) -> (f64, f64) {
        let rate = |v: f64| self.target.inverse(self.mean + self.sd * v);
        (rate(m - h), rate(m + h))
    }

    /// Intervals of `coverage` of one kind (`observation` or whole bins) at `points`, for
    /// [`RatePredictor`]: on one thread, `None` unless `coverage` is in `(0, 1)`, `NaN` bounds
    /// where the prediction fails (for one point, or everywhere for a batch).
    fn rate_predictor_intervals(
        &self,
        points: &[([f64; 2], f64)],
        coverage: f64,
        observation: bool,
    ) -> Option<Vec<(f64, f64)>> {
        check_coverage(coverage).ok()?;
        let par = Parallelism::Sequential;
        let intervals = if observation {
            self.observation_intervals(points, coverage, par)
        } else {
            self.bin_intervals(points, coverage, par)
        };
        Some(intervals.unwrap_or_else(|_| vec![(f64::NAN, f64::NAN); points.len()]))
    }

    /// [`CopaMap::rate_predictor_intervals`] at the samples of `at`.
    fn sample_intervals(
        &self,
        at: &RateSamples,
        coverage: f64,
        observation: bool,
    ) -> Option<Vec<(f64, f64)>> {
        let points: Vec<([f64; 2], f64)> =
            at.x().iter().copied().zip(at.t().iter().copied()).collect();
        self.rate_predictor_intervals(&points, coverage, observation)
    }

    /// The square of the plane the model was trained on: `[x_min, y_min, x_max, y_max]` with
    /// the lower-left corner of the training cells' centres and the longer of their two spans.
    pub fn domain(&self) -> [f64; 4] {
        let [x, y] = self.scaling.origin;
        let s = self.scaling.space_scale;
        [x, y, x + s, y + s]
    }

    /// The times the model was trained on, `[t_min, t_min + span]` in units of `t`: the span
    /// is the training span, or one day period if the training was shorter.
    pub fn time_span(&self) -> [f64; 2] {
        let s = &self.scaling;
        [s.time_origin, s.time_origin + s.time_scale]
    }

    /// Checks what a model read from a file must satisfy beyond the shapes its deserialiser
    /// checks: finite scalings with positive scales and a finite standardisation.
    ///
    /// # Errors
    /// [`GpError::InvalidInput`] naming the first bad value.
    pub fn check(&self) -> Result<(), GpError> {
        let s = &self.scaling;
        let finite = [
            s.origin[0],
            s.origin[1],
            s.space_scale,
            s.time_origin,
            s.time_scale,
            self.mean,
            self.sd,
        ]
        .iter()
        .all(|v| v.is_finite());
        if !finite || s.space_scale <= 0.0 || s.time_scale <= 0.0 || self.sd <= 0.0 {
            return Err(GpError::InvalidInput(format!(
                "CoPA-Map scaling {s:?}, mean {} and sd {} must be finite with positive scales",
                self.mean, self.sd
            )));
        }
        Ok(())
    }

    /// The fitted periods, in units of `t`.
    pub fn periods(&self) -> Vec<f64> {
        self.scaling.periods(&self.model.f.kernel)
    }

    /// Inducing points of the model (the larger count of its two latent GPs): a prediction's
    /// cost per point grows with its square.
    pub fn inducing_points(&self) -> usize {
        self.model.f.z.len().max(self.model.g.z.len())
    }
}

/// `Ok` if `coverage` is a probability strictly between 0 and 1.
fn check_coverage(coverage: f64) -> Result<(), GpError> {
    if coverage > 0.0 && coverage < 1.0 {
        Ok(())
    } else {
        Err(GpError::InvalidInput(format!(
            "coverage {coverage} is not in (0, 1)"
        )))
    }
}

/// Inputs onto `[0, 1]`: both spatial axes by one scale (distances keep their ratio), time by
/// the training span.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub(crate) struct InputScaling {
    origin: [f64; 2],
    space_scale: f64,
    time_origin: f64,
    /// The training span in units of `t` (at least one day).
    pub(crate) time_scale: f64,
}

impl InputScaling {
    /// The scaling of the (non-empty) training samples: origin at the least coordinates and
    /// time, time scale the training span but at least `day_period`.
    pub(crate) fn of(samples: &RateSamples, day_period: f64) -> Self {
        let xs = samples.x();
        let ts = samples.t();
        let lo = |k: usize| xs.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min);
        let hi = |k: usize| xs.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max);
        let origin = [lo(0), lo(1)];
        let space_scale = (hi(0) - origin[0]).max(hi(1) - origin[1]).max(1e-9);
        let time_origin = ts.iter().copied().fold(f64::INFINITY, f64::min);
        let time_scale =
            (ts.iter().copied().fold(f64::NEG_INFINITY, f64::max) - time_origin).max(day_period);
        InputScaling {
            origin,
            space_scale,
            time_origin,
            time_scale,
        }
    }

    /// Every sample's input, scaled.
    pub(crate) fn apply_all(&self, samples: &RateSamples) -> Vec<Point> {
        samples
            .x()
            .iter()
            .zip(samples.t())
            .map(|(&p, &t)| self.apply(p, t))
            .collect()
    }

    /// Every point `(x, t)`, scaled.
    pub(crate) fn apply_points(&self, points: &[([f64; 2], f64)]) -> Vec<Point> {
        points.iter().map(|&(p, t)| self.apply(p, t)).collect()
    }

    /// The periods of a kernel fitted on scaled inputs, in units of `t`.
    pub(crate) fn periods(&self, kernel: &ActivityKernel) -> Vec<f64> {
        kernel
            .components()
            .iter()
            .map(|c| c.period * self.time_scale)
            .collect()
    }

    /// One input, scaled.
    pub(crate) fn apply(&self, p: [f64; 2], t: f64) -> Point {
        [
            (p[0] - self.origin[0]) / self.space_scale,
            (p[1] - self.origin[1]) / self.space_scale,
            (t - self.time_origin) / self.time_scale,
        ]
    }
}

/// What [`CopaMap::fit`] and [`GpHom::fit`](super::GpHom::fit) require: at least
/// `min_samples` samples, inducing points, periodic components and a positive day period.
pub(crate) fn check_fit(
    n: usize,
    min_samples: usize,
    inducing: usize,
    harmonics: usize,
    day_period: f64,
) -> Result<(), GpError> {
    if n < min_samples || inducing == 0 || harmonics == 0 {
        return Err(GpError::InvalidInput(format!(
            "{n} training samples for {inducing} inducing points and {harmonics} periodic \
             components"
        )));
    }
    if !(day_period.is_finite() && day_period > 0.0) {
        return Err(GpError::InvalidInput(format!(
            "day period {day_period} is not a positive time"
        )));
    }
    Ok(())
}

/// The initial periodic components of the day (`day` in scaled time) and its first
/// `harmonics − 1` harmonics `day / h`, variances `0.5 / h` (§4.2.4, [`PeriodInitMode::Day`]).
pub(crate) fn day_harmonics(day: f64, harmonics: usize) -> Vec<PeriodicComponent> {
    (1..=harmonics)
        .map(|h| PeriodicComponent {
            variance: 0.5 / h as f64,
            lengthscale: 0.4,
            period: day / h as f64,
        })
        .collect()
}

/// The training settings of a fit: `iterations`, minibatches of `batch_size` (at most the `n`
/// samples) and `seed`, the rest [`TrainConfig::default`].
pub(crate) fn fit_training(
    iterations: usize,
    batch_size: usize,
    n: usize,
    seed: u64,
) -> TrainConfig {
    TrainConfig {
        iterations,
        batch_size: batch_size.min(n),
        seed,
        ..TrainConfig::default()
    }
}

/// Gives a GP model (fields `model`, the GP, and `scaling`, its [`InputScaling`]) the inherent
/// `predict_with_std(points, par)`, documented by `$doc`: the GP's prediction at the scaled
/// points, turned into rates by the model's `rates`. Implements [`RatePredictor`], named
/// `$name`, on it: on one thread, `NaN` where the prediction fails (for one point, or
/// everywhere for a batch); the items of an optional last `{ … }` are added to that
/// implementation. `RatePredictor`, `RateSamples`, `GpError` and `Parallelism` must be in scope.
macro_rules! gp_rate_predictor {
    ($model:ty, $name:literal, $(#[$doc:meta])* $({ $($extra:tt)* })?) => {
        impl $model {
            $(#[$doc])*
            ///
            /// # Errors
            /// Non-finite inputs.
            pub fn predict_with_std(
                &self,
                points: &[([f64; 2], f64)],
                par: Parallelism,
            ) -> Result<(Vec<f64>, Vec<f64>), GpError> {
                let prediction = self
                    .model
                    .predict(&self.scaling.apply_points(points), par)?;
                Ok(self.rates(prediction))
            }
        }

        impl RatePredictor for $model {
            fn name(&self) -> &str {
                $name
            }

            fn predict(&self, x: [f64; 2], t: f64) -> f64 {
                self.predict_with_std(&[(x, t)], Parallelism::Sequential)
                    .map_or(f64::NAN, |(mean, _)| mean[0])
            }

            fn predict_samples(&self, at: &RateSamples) -> Vec<f64> {
                let points: Vec<([f64; 2], f64)> =
                    at.x().iter().copied().zip(at.t().iter().copied()).collect();
                self.predict_with_std(&points, Parallelism::Sequential)
                    .map_or_else(|_| vec![f64::NAN; points.len()], |(mean, _)| mean)
            }

            $($($extra)*)?
        }
    };
}
pub(crate) use gp_rate_predictor;

gp_rate_predictor!(
    CopaMap,
    "copa",
    /// Predicted rate (≥ 0) and its standard deviation at many points: with
    /// [`RateScale::Rate`] the predictive mean of eq. (4.19) (negative means set to 0), with
    /// [`RateScale::Log1p`] the predictive median `exp(m) − 1`.
    {
        /// The rate of a whole bin: [`CopaMap::bin_intervals`], the latent rate function's
        /// predictive interval ([Stüde 2024] eqs. 4.7, 4.13–4.14).
        fn interval(&self, x: [f64; 2], t: f64, coverage: f64) -> Option<(f64, f64)> {
            self.rate_predictor_intervals(&[(x, t)], coverage, false)
                .map(|v| v[0])
        }

        /// One observation like the training samples: [`CopaMap::observation_intervals`],
        /// the scale mixture of normals of eq. 4.7 under the marginals of `f` and `g`.
        fn observation_interval(&self, x: [f64; 2], t: f64, coverage: f64) -> Option<(f64, f64)> {
            self.rate_predictor_intervals(&[(x, t)], coverage, true)
                .map(|v| v[0])
        }

        fn interval_samples(&self, at: &RateSamples, coverage: f64) -> Option<Vec<(f64, f64)>> {
            self.sample_intervals(at, coverage, false)
        }

        fn observation_interval_samples(
            &self,
            at: &RateSamples,
            coverage: f64,
        ) -> Option<Vec<(f64, f64)>> {
            self.sample_intervals(at, coverage, true)
        }
    }
);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gp::{Variational, softplus};
    use chronomap_core::rng::Xoshiro256StarStar;

    /// A CoPA-Map built by hand on a 10 m × 10 m area over 24 hours: 24 inducing points, a
    /// whitened `q(u)` away from the prior for both latent GPs (means varying over the
    /// inducing points, covariances `0.6²I` and `0.8²I`), so that `f` and the noise level
    /// `ζ(g)` vary over space and time and `g` is uncertain: the law of an observation is a
    /// proper mixture of normals. Rates standardised by `mean` and `sd` on `target`.
    fn hand_built(target: RateScale, mean: f64, sd: f64) -> CopaMap {
        let z: Vec<Point> = (0..24)
            .map(|i| {
                let i = f64::from(i);
                [
                    (i % 4.0) / 3.0,
                    (i / 4.0).floor() % 2.0,
                    (i / 8.0).floor() / 2.0,
                ]
            })
            .collect();
        let kf = ActivityKernel::new(
            1.0,
            [0.4, 0.4],
            &[PeriodicComponent {
                variance: 1.0,
                lengthscale: 0.5,
                period: 0.5,
            }],
        );
        let mut model = HeteroSvgp::new(kf, RbfKernel::new(1.0, [0.5, 0.5, 0.5]), z);
        let m = model.f.z.len();
        let scaled = |s: f64| {
            let mut q = Variational::prior(m);
            q.chol *= faer::Scale(s);
            q
        };
        model.f.q = Variational {
            mean: (0..m).map(|i| (i as f64).sin()).collect(),
            ..scaled(0.6)
        };
        model.g.q = Variational {
            mean: (0..m).map(|i| 0.7 * (i as f64 * 0.7).cos() - 0.6).collect(),
            ..scaled(0.8)
        };
        CopaMap {
            model,
            scaling: InputScaling {
                origin: [0.0, 0.0],
                space_scale: 10.0,
                time_origin: 0.0,
                time_scale: 24.0,
            },
            mean,
            sd,
            target,
            trace: Vec::new(),
            period_init: None,
        }
    }

    /// Points and, at each, a draw of a whole bin and of an observation.
    struct Draws {
        points: Vec<([f64; 2], f64)>,
        bins: Vec<f64>,
        observations: Vec<f64>,
    }

    /// `n` points spread over the area and the day, and for each one draw from `model`'s own
    /// law: the rate function `f ~ q(f)` (a whole bin), and an observation
    /// `y = f + ζ(g) ε` with `g ~ q(g)` ([Stüde 2024] eq. 4.7), both as rates.
    fn draws(model: &CopaMap, n: usize, seed: u64) -> Draws {
        let mut rng = Xoshiro256StarStar::seed_from_u64(seed);
        let points: Vec<([f64; 2], f64)> = (0..n)
            .map(|_| {
                let x = [rng.uniform(0.0, 10.0), rng.uniform(0.0, 5.0)];
                (x, rng.uniform(0.0, 24.0))
            })
            .collect();
        let latent = model
            .model
            .predict_latent(
                &model.scaling.apply_points(&points),
                Parallelism::Sequential,
            )
            .unwrap();
        let rate = |v: f64| model.target.inverse(model.mean + model.sd * v);
        let (mut bins, mut observations) = (Vec::new(), Vec::new());
        for i in 0..n {
            let f = latent.f_mean[i] + latent.f_var[i].sqrt() * rng.standard_normal();
            let g = latent.g_mean[i] + latent.g_var[i].sqrt() * rng.standard_normal();
            bins.push(rate(f));
            observations.push(rate(f + softplus(g) * rng.standard_normal()));
        }
        Draws {
            points,
            bins,
            observations,
        }
    }

    /// Both kinds of interval of `model` at 50, 90 and 99 % hold draws from its own law that
    /// often ([`chronomap_core::conformance::check_interval_coverage`]), through the batch
    /// and the point paths of [`RatePredictor`] alike.
    fn check_own_law(what: &str, model: &CopaMap, seed: u64) {
        let Draws {
            points,
            bins,
            observations,
        } = draws(model, 20_000, seed);
        let mut at = RateSamples::default();
        for (&(x, t), &y) in points.iter().zip(&bins) {
            at.push(x, t, y.max(0.0)).unwrap();
        }
        for coverage in [0.5, 0.9, 0.99] {
            let whole = model.interval_samples(&at, coverage).unwrap();
            let one = model.observation_interval_samples(&at, coverage).unwrap();
            for i in [0, 777, 19_999] {
                let (x, t) = points[i];
                // One point or a batch: the same up to the rounding of the matrix products.
                let near = |a: (f64, f64), b: (f64, f64)| {
                    (a.0 - b.0).abs() <= 1e-12 * b.0.abs().max(1.0)
                        && (a.1 - b.1).abs() <= 1e-12 * b.1.abs().max(1.0)
                };
                assert!(near(model.interval(x, t, coverage).unwrap(), whole[i]));
                let point = model.observation_interval(x, t, coverage).unwrap();
                assert!(near(point, one[i]), "{point:?} vs {:?}", one[i]);
                assert!(whole[i].0 <= whole[i].1 && one[i].0 <= whole[i].0);
                assert!(whole[i].1 <= one[i].1);
            }
            chronomap_core::conformance::check_interval_coverage(
                &format!("CoPA-Map {what}, whole bins, {coverage}"),
                coverage,
                &whole,
                &bins,
            );
            chronomap_core::conformance::check_interval_coverage(
                &format!("CoPA-Map {what}, observations, {coverage}"),
                coverage,
                &one,
                &observations,
            );
        }
        assert_eq!(model.interval([1.0, 1.0], 3.0, 1.0), None);
        assert_eq!(model.observation_interval([1.0, 1.0], 3.0, 0.0), None);
        assert!(
            model
                .bin_intervals(&points[..1], f64::NAN, Parallelism::Sequential)
                .is_err()
        );
    }

    /// The conformance check of CoPA-Map's intervals on a hand-built model, both scales: on
    /// rates (standardised by mean 100 and deviation 10, so that no draw is near 0 where the
    /// rate is clipped) and on `ln(1 + y)` (mean 2.5, deviation 0.5).
    #[test]
    fn intervals_of_a_hand_built_model_cover_draws_from_its_own_law() {
        check_own_law("on rates", &hand_built(RateScale::Rate, 100.0, 10.0), 3);
        check_own_law("on ln(1 + y)", &hand_built(RateScale::Log1p, 2.5, 0.5), 5);
    }

    /// The conformance check on a fitted CoPA-Map (on `ln(1 + y)`, a small model of
    /// heteroscedastic data: the right half of the area is noisier), whose `q(u)` and
    /// hyperparameters come from training. The rates are high enough (`ln(1 + y)` about 4)
    /// that the law's mass below a rate of 0, which both the intervals and the draws clip,
    /// is negligible.
    #[test]
    fn intervals_of_a_fitted_model_cover_draws_from_its_own_law() {
        let mut rng = Xoshiro256StarStar::seed_from_u64(17);
        let mut train = RateSamples::default();
        for i in 0..1200 {
            let x = [f64::from(i % 10) + 0.5, f64::from(i / 10 % 5) + 0.5];
            let t = f64::from(i / 50) + rng.uniform(0.0, 1.0);
            let noise = if x[0] > 5.0 { 0.8 } else { 0.2 };
            let z = 4.0
                + 0.1 * x[1]
                + (2.0 * std::f64::consts::PI * t / 12.0).sin()
                + noise * rng.standard_normal();
            train.push(x, t, z.exp_m1().max(0.0)).unwrap();
        }
        let config = CopaConfig {
            inducing: 30,
            iterations: 60,
            batch_size: 300,
            target: RateScale::Log1p,
            ..CopaConfig::default()
        };
        let model = CopaMap::fit(&train, &config).unwrap();
        check_own_law("fitted on ln(1 + y)", &model, 7);
    }
}
