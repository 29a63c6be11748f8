//! GP-Hom ([Stüde 2024] §4.3.2) as a [`RatePredictor`]: "the same modules as CoPA-Map but
//! realized as a log-Gaussian Cox process", i.e. the Poisson SVGP [`PoissonSvgp`] with one
//! latent log rate, CoPA-Map's kernel and CoPA-Map's fitting ([`super::copa`]):
//!
//! * the same input scaling (space onto `[0, 1]` with one scale, time by the training span),
//!   the same k-means inducing points and the same initial periods (the day and its first
//!   harmonics), trained with the same natural-gradient + Adam loop and defaults;
//! * but the raw rates `y ≥ 0` (not standardised) with the Poisson likelihood, and a constant
//!   prior mean of the log rate that starts at the log of the mean training rate.
//!
//! Predictions are the mean rate `E[exp f]`, never negative.

use serde::{Deserialize, Serialize};

use super::copa::{InputScaling, check_fit, day_harmonics, fit_training, gp_rate_predictor};
use super::init::inducing_points;
use super::{RatePredictor, RateSamples};
use crate::gp::{ActivityKernel, GpError, Point, PoissonSvgp, Prediction, train_with_progress};
use chronomap_core::par::Parallelism;
use chronomap_core::progress::{NoProgress, Progress};

/// How GP-Hom is fitted (the defaults of [`super::CopaConfig`]).
#[derive(Clone, Debug, PartialEq)]
pub struct GpHomConfig {
    /// Inducing points `M` (fewer when the training data have fewer distinct inputs).
    pub inducing: usize,
    /// Training iterations (each a natural-gradient step on `q(u)` and an Adam step).
    pub iterations: usize,
    /// Minibatch size `B`.
    pub batch_size: usize,
    /// Length of a day in units of `t` (12 for the ATC grid's 12 recorded hours a day).
    pub day_period: f64,
    /// Periodic components: the day and its harmonics day/2, …
    pub harmonics: usize,
    /// Seed of the inducing points and the minibatches.
    pub seed: u64,
    /// Threads of the kernel evaluations (results do not depend on it).
    pub parallelism: Parallelism,
}

impl Default for GpHomConfig {
    fn default() -> Self {
        GpHomConfig {
            inducing: 200,
            iterations: 300,
            batch_size: 1000,
            day_period: 12.0,
            harmonics: 2,
            seed: 0,
            parallelism: Parallelism::Sequential,
        }
    }
}

/// A fitted GP-Hom.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct GpHom {
    model: PoissonSvgp,
    scaling: InputScaling,
    /// Minibatch ELBO after every iteration.
    pub trace: Vec<f64>,
}

/// Number of distinct points (by their bits).
fn distinct(x: &[Point]) -> usize {
    let mut keys: Vec<[u64; 3]> = x
        .iter()
        .map(|p| [p[0].to_bits(), p[1].to_bits(), p[2].to_bits()])
        .collect();
    keys.sort_unstable();
    keys.dedup();
    keys.len()
}

impl GpHom {
    /// Fits GP-Hom to training rates.
    ///
    /// # Errors
    /// No training samples, a configuration out of range, a training mean rate of 0, or a
    /// kernel matrix that is not positive definite.
    pub fn fit(train_samples: &RateSamples, config: &GpHomConfig) -> Result<Self, GpError> {
        Self::fit_with_progress(train_samples, config, &NoProgress)
    }

    /// [`GpHom::fit`], reporting the stage `GP-Hom` with one step per training iteration to
    /// `progress`. The result is the same.
    ///
    /// # Errors
    /// As [`GpHom::fit`].
    pub fn fit_with_progress(
        train_samples: &RateSamples,
        config: &GpHomConfig,
        progress: &dyn Progress,
    ) -> Result<Self, GpError> {
        let n = train_samples.len();
        check_fit(n, 1, config.inducing, config.harmonics, config.day_period)?;
        let mean_rate = train_samples.mean_rate();
        if mean_rate <= 0.0 {
            return Err(GpError::InvalidInput(
                "every training rate is 0: a log rate has no starting point".into(),
            ));
        }
        let scaling = InputScaling::of(train_samples, config.day_period);
        let x = scaling.apply_all(train_samples);
        let z = inducing_points(&x, None, config.inducing.min(distinct(&x)), config.seed)
            .map_err(|e| GpError::InvalidInput(e.to_string()))?;
        let components = day_harmonics(config.day_period / scaling.time_scale, config.harmonics);
        // Log rates: a prior spread of about e^{±1} around the mean rate.
        let mut model = PoissonSvgp::new(
            ActivityKernel::new(1.0, [0.05, 0.05], &components),
            z,
            mean_rate.ln(),
        );
        let train_config = fit_training(config.iterations, config.batch_size, n, config.seed);
        progress.stage("GP-Hom", config.iterations as u64);
        let trace = train_with_progress(
            &mut model,
            &x,
            train_samples.y(),
            &train_config,
            config.parallelism,
            progress,
        )?;
        Ok(GpHom {
            model,
            scaling,
            trace,
        })
    }

    /// The rates and their standard deviations of `predict_with_std`: the GP's prediction as
    /// it is (it is a rate already).
    fn rates(&self, prediction: Prediction) -> (Vec<f64>, Vec<f64>) {
        (prediction.mean, prediction.std)
    }

    /// The fitted periods, in units of `t`.
    pub fn periods(&self) -> Vec<f64> {
        self.scaling.periods(&self.model.f.kernel)
    }

    /// The fitted model (in scaled inputs).
    pub fn model(&self) -> &PoissonSvgp {
        &self.model
    }
}

gp_rate_predictor!(
    GpHom,
    "gp_hom",
    /// Mean and standard deviation of the rate at many points (see [`PoissonSvgp::predict`]).
);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{CellMean, GlobalMean, score};

    /// Two cells over ten 12-bin days: a busy one with a daily rhythm, a quiet one.
    fn rhythm() -> RateSamples {
        let mut s = RateSamples::default();
        for t in 0..120 {
            let tf = f64::from(t);
            let busy = 20.0 * (1.0 + 0.8 * (std::f64::consts::TAU * tf / 12.0).sin());
            s.push([0.25, 0.25], tf, busy).unwrap();
            s.push([2.25, 0.25], tf, 1.0).unwrap();
        }
        s
    }

    #[test]
    fn gp_hom_follows_a_daily_rhythm_into_later_days() {
        let (train, test) = rhythm().split_at(96.0);
        let config = GpHomConfig {
            inducing: 30,
            iterations: 100,
            batch_size: 100,
            ..GpHomConfig::default()
        };
        let model = GpHom::fit(&train, &config).unwrap();
        let s = score(&model, &test).unwrap();
        let ml = score(&CellMean::fit(&train).unwrap(), &test).unwrap();
        let flat = score(&GlobalMean::fit(&train).unwrap(), &test).unwrap();
        // Measured: NRMSE 0.014; the per-cell mean cannot follow the rhythm (0.76).
        assert!(s.nrmse < 0.05, "{} vs ML {}", s.nrmse, ml.nrmse);
        assert!(ml.nrmse > 0.7);
        assert!(ml.nrmse < flat.nrmse);
        let (mean, std) = model
            .predict_with_std(&[([2.25, 0.25], 100.0)], Parallelism::Sequential)
            .unwrap();
        assert!(mean[0] > 0.0 && std[0] > 0.0, "{mean:?} {std:?}");
        assert!(model.trace.last().unwrap() > &model.trace[0]);
        // The periods stay at the day and half a day.
        let periods = model.periods();
        assert!((periods[0] - 12.0).abs() < 0.05 && (periods[1] - 6.0).abs() < 0.05);
    }

    #[test]
    fn gp_hom_rejects_bad_inputs_and_uses_at_most_one_inducing_point_per_input() {
        let s = rhythm();
        let zero = RateSamples::new(vec![[0.0; 2]; 2], vec![0.0, 1.0], vec![0.0, 0.0]).unwrap();
        assert!(GpHom::fit(&zero, &GpHomConfig::default()).is_err());
        assert!(GpHom::fit(&RateSamples::default(), &GpHomConfig::default()).is_err());
        for config in [
            GpHomConfig {
                day_period: 0.0,
                ..GpHomConfig::default()
            },
            GpHomConfig {
                harmonics: 0,
                ..GpHomConfig::default()
            },
        ] {
            assert!(GpHom::fit(&s, &config).is_err());
        }
        // Four samples, 200 inducing points asked: four are used.
        let tiny = RateSamples::new(
            vec![[0.25, 0.25], [0.25, 0.25], [0.75, 0.25], [0.75, 0.25]],
            vec![0.0, 1.0, 0.0, 1.0],
            vec![10.0, 10.0, 1e-6, 2.0],
        )
        .unwrap();
        let config = GpHomConfig {
            iterations: 5,
            ..GpHomConfig::default()
        };
        let model = GpHom::fit(&tiny, &config).unwrap();
        assert_eq!(model.model().f.z.len(), 4);
    }
}
