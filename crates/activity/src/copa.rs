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
/// everywhere for a batch). `RatePredictor`, `RateSamples`, `GpError` and `Parallelism` must be
/// in scope.
macro_rules! gp_rate_predictor {
    ($model:ty, $name:literal, $(#[$doc:meta])*) => {
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
);
