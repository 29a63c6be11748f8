//! CoPA-Map ([Stüde 2024] ch. 4): a heteroscedastic sparse variational Gaussian process of a human
//! activity rate over space × time.
//!
//! `y ~ N(f(x), ζ(g(x))²)` with `x = (x1, x2, t)`, `ζ` = softplus (the noise *standard
//! deviation*, as in the original GPflow code), `f ~ GP(0, k_f)` with the spatio-temporal
//! product kernel [`ActivityKernel`] ([Stüde 2024] eqs. 4.8–4.10) and `g ~ GP(0, k_g)` with an
//! [`RbfKernel`] (eq. 4.11). Both latent GPs are whitened SVGPs (eqs. 4.12–4.16) trained by
//! alternating natural-gradient steps on `q(u)` and Adam steps on the kernel
//! log-parameters and inducing inputs ([`train`]); the expected log-likelihood is closed
//! form in `f` and Gauss–Hermite in `g` ([`HeteroGaussian`]).
//!
//! GP-Hom, the homoscedastic baseline of §4.3.2, is [`PoissonSvgp`]: one latent function with
//! the same kernel and a Poisson likelihood with log link (a log-Gaussian Cox process), trained
//! by the same [`train`] (any [`SvgpModel`]).
//!
//! Per iteration the cost is `O(B·M² + M³)` for a minibatch of `B` points and `M` inducing
//! points; nothing of size `n` is touched except the minibatch copy.
//!
//! ```
//! use chronomap_activity::gp::{
//!     train, ActivityKernel, HeteroSvgp, PeriodicComponent, Point, RbfKernel, TrainConfig,
//! };
//! use chronomap_core::Parallelism;
//!
//! // A daily rhythm on a 1 × 1 area, noisier on the right half; t in hours.
//! let mut x: Vec<Point> = Vec::new();
//! let mut y = Vec::new();
//! for i in 0..300 {
//!     let p = [(i % 10) as f64 / 10.0, (i / 10 % 3) as f64 / 3.0, (i / 30) as f64 * 2.4];
//!     let noise = if p[0] > 0.5 { 0.3 } else { 0.05 } * ((i * 7919 % 13) as f64 / 6.0 - 1.0);
//!     y.push(1.0 + (2.0 * std::f64::consts::PI * p[2] / 24.0).sin() + noise);
//!     x.push(p);
//! }
//! let kf = ActivityKernel::new(
//!     1.0,
//!     [0.5, 0.5],
//!     &[PeriodicComponent { variance: 1.0, lengthscale: 0.5, period: 24.0 }],
//! );
//! let kg = RbfKernel::new(0.5, [0.5, 0.5, 10.0]);
//! let z: Vec<Point> = x.iter().step_by(15).copied().collect();
//! let mut model = HeteroSvgp::new(kf, kg, z);
//! let config = TrainConfig { iterations: 40, batch_size: 100, ..TrainConfig::default() };
//! let trace = train(&mut model, &x, &y, &config, Parallelism::Sequential)?;
//! assert!(trace.last().unwrap() > &trace[0]);
//! let pred = model.predict(&[[0.25, 0.5, 6.0]], Parallelism::Sequential)?;
//! assert!(pred.mean[0].is_finite() && pred.std[0] > 0.0);
//! # Ok::<(), chronomap_activity::gp::GpError>(())
//! ```

pub mod kernel;
pub mod poisson;
pub mod quad;
pub mod svgp;
#[cfg(test)]
mod tests;

pub use kernel::{ActivityKernel, Kernel, PeriodicComponent, Point, RbfKernel};
pub use poisson::{ExpectedPoissonLogLik, PoissonElboGrad, PoissonSvgp, expected_poisson_log_lik};
pub use quad::{ExpectedLogLik, HeteroGaussian, gauss_hermite, softplus};
pub use svgp::{
    Adam, Batch, ElboGrad, GpError, HeteroSvgp, LatentGp, LatentPrediction, Marginals, Prediction,
    SvgpModel, TrainConfig, Variational, train, train_with_progress,
};
