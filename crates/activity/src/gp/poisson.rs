//! GP-Hom, the homoscedastic baseline of [Stüde 2024] §4.3.2: a log-Gaussian Cox process with one
//! latent function `f ~ GP(c, k_f)` (the kernel of CoPA-Map, [`ActivityKernel`], eqs.
//! 4.8–4.10, and a constant prior mean `c`) and a Poisson likelihood with log link,
//! `y ~ Poisson(exp f(x))`. The latent GP is the whitened SVGP of [`super::svgp`] (eqs.
//! 4.12–4.14 with one latent function instead of two) and is trained the same way
//! ([`train`](super::train): natural gradients on `q(v)`, Adam on the hyperparameters).
//!
//! The targets are rates, not counts (`y ≥ 0`, not necessarily integer), so the likelihood is
//! the Poisson density continued to real `y`, `ln p(y | f) = y f − eᶠ − ln Γ(y + 1)`. Its
//! expectation under `q(f) = N(m, v)` is closed form (the log-normal mean):
//! `E[ln p(y | f)] = y m − exp(m + v/2) − ln Γ(y + 1)` ([`expected_poisson_log_lik`]).
//!
//! The natural-gradient step of [`LatentGp::natgrad_update`] is exact only for a Gaussian
//! likelihood; here it is the usual damped approximation (step sizes `≤ 0.1`). Because
//! `∂E/∂v = −½ exp(m + v/2) < 0`, the new precision stays positive definite for any step
//! size `≤ 1`.

use serde::{Deserialize, Serialize};
use statrs::function::gamma::ln_gamma;

use super::kernel::{ActivityKernel, Kernel, Point};
use super::svgp::{
    Batch, BatchLik, GpError, LatentGp, Marginals, Prediction, SvgpModel, TrainConfig, check_data,
    check_saved, flatten, pack_lower, predict_in_chunks, svgp_model, with_step_halving,
};
use chronomap_core::par::Parallelism;

/// `E_{q(f)}[ln p(y | f)]` of the Poisson likelihood for `q(f) = N(m, v)` and its derivatives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExpectedPoissonLogLik {
    /// `y m − exp(m + v/2) − ln Γ(y + 1)`.
    pub value: f64,
    /// `∂/∂m = y − exp(m + v/2)`.
    pub d_m: f64,
    /// `∂/∂v = −½ exp(m + v/2)`.
    pub d_v: f64,
}

/// The expected log-likelihood of one rate `y ≥ 0` under the Poisson likelihood with log link
/// (the first term of [Stüde 2024] eq. 4.12 for GP-Hom, §4.3.2), closed form:
/// `E[y f − eᶠ − ln Γ(y + 1)] = y m − exp(m + v/2) − ln Γ(y + 1)` for `f ~ N(m, v)`.
pub fn expected_poisson_log_lik(y: f64, m: f64, v: f64) -> ExpectedPoissonLogLik {
    let rate = (m + 0.5 * v).exp();
    ExpectedPoissonLogLik {
        value: y * m - rate - ln_gamma(y + 1.0),
        d_m: y - rate,
        d_v: -0.5 * rate,
    }
}

/// The serialised form of [`PoissonSvgp`], validated on the way back.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct SavedPoissonSvgp {
    kernel: Vec<f64>,
    mean: f64,
    z: Vec<Point>,
    q_mean: Vec<f64>,
    q_chol: Vec<f64>,
    jitter: f64,
}

impl From<PoissonSvgp> for SavedPoissonSvgp {
    fn from(m: PoissonSvgp) -> Self {
        SavedPoissonSvgp {
            kernel: m.f.kernel.params().to_vec(),
            mean: m.mean,
            q_chol: pack_lower(&m.f.q.chol),
            z: m.f.z,
            q_mean: m.f.q.mean,
            jitter: m.jitter,
        }
    }
}

impl SavedPoissonSvgp {
    /// Finite values, a kernel of a valid length and one `q(v)` mean per inducing input.
    fn is_consistent(&self) -> bool {
        let all_finite = self
            .kernel
            .iter()
            .chain(self.z.iter().flatten())
            .chain(&self.q_mean)
            .chain(&self.q_chol)
            .chain([&self.mean, &self.jitter])
            .all(|v| v.is_finite());
        all_finite
            && self.kernel.len() >= 3
            && (self.kernel.len() - 3).is_multiple_of(3)
            && self.z.len() == self.q_mean.len()
            && self.jitter >= 0.0
    }
}

impl TryFrom<SavedPoissonSvgp> for PoissonSvgp {
    type Error = GpError;
    fn try_from(s: SavedPoissonSvgp) -> Result<Self, GpError> {
        check_saved(s.is_consistent())?;
        let mut kernel = ActivityKernel::new(1.0, [1.0, 1.0], &[]);
        kernel.set_params(&s.kernel);
        Ok(PoissonSvgp {
            f: LatentGp::restore(kernel, s.z, s.q_mean, &s.q_chol)?,
            mean: s.mean,
            jitter: s.jitter,
        })
    }
}

/// The GP-Hom model of [Stüde 2024] §4.3.2: `y ~ Poisson(exp f(x))`, `f ~ GP(c, k_f)` with
/// CoPA-Map's kernel [`ActivityKernel`] (eqs. 4.8–4.10), approximated by one whitened SVGP
/// (eqs. 4.12–4.14). The constant prior mean `c` of the log rate is a hyperparameter (trained
/// by Adam with the kernel); a good start is the log of the mean training rate.
///
/// Serialisable (serde) for saving a trained model; deserialisation validates shapes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "SavedPoissonSvgp", into = "SavedPoissonSvgp")]
pub struct PoissonSvgp {
    /// The latent log rate `f − c`.
    pub f: LatentGp<ActivityKernel>,
    /// The constant prior mean `c` of the log rate.
    pub mean: f64,
    /// Jitter added to the diagonal of `K(Z, Z)` (default `1e-6`).
    pub jitter: f64,
}

/// The ELBO estimate of a minibatch under [`PoissonSvgp`] and its gradient.
#[derive(Clone, Debug, PartialEq)]
pub struct PoissonElboGrad {
    /// `scale · Σ_batch E[ln p(y|f)] − KL`.
    pub elbo: f64,
    /// `∂/∂` log-parameters of `k_f`.
    pub d_kernel: Vec<f64>,
    /// `∂/∂c`.
    pub d_mean: f64,
    /// `∂/∂Z`.
    pub d_z: Vec<Point>,
}

impl PoissonElboGrad {
    /// The gradient flattened in the order of [`PoissonSvgp::hyperparameters`].
    pub fn flatten(&self, with_inducing: bool) -> Vec<f64> {
        flatten(
            &[&self.d_kernel, &[self.d_mean]],
            &[&self.d_z],
            with_inducing,
        )
    }
}

/// [`check_data`] and rates `y ≥ 0`.
fn check_rates(x: &[Point], y: &[f64]) -> Result<(), GpError> {
    check_data(x, y)?;
    if let Some(i) = y.iter().position(|&v| v < 0.0) {
        return Err(GpError::InvalidInput(format!(
            "rate {} at row {i} is negative (a Poisson rate is >= 0)",
            y[i]
        )));
    }
    Ok(())
}

impl PoissonSvgp {
    /// A model with kernel `kernel`, inducing inputs `z`, constant prior mean `mean` of the
    /// log rate and the prior `q(v) = N(0, I)`.
    pub fn new(kernel: ActivityKernel, z: Vec<Point>, mean: f64) -> Self {
        PoissonSvgp {
            f: LatentGp::new(kernel, z),
            mean,
            jitter: 1e-6,
        }
    }

    /// The marginals of `f` on a checked batch.
    fn marginals(&self, batch: &Batch<'_>, par: Parallelism) -> Result<Marginals, GpError> {
        check_rates(batch.x, batch.y)?;
        self.f.marginals(batch.x, self.jitter, par)
    }

    /// The ELBO of eq. 4.12 from the batch likelihood: minus the KL term.
    fn elbo_of(&self, lik: &BatchLik<1>) -> f64 {
        lik.ell - self.f.q.kl()
    }

    fn batch_lik(&self, batch: &Batch<'_>, marg: &Marginals) -> BatchLik<1> {
        let y = batch.y;
        BatchLik::new(batch, |i| {
            let e = expected_poisson_log_lik(y[i], self.mean + marg.mean[i], marg.var[i]);
            (e.value, [e.d_m], [e.d_v])
        })
    }

    /// The ELBO ([Stüde 2024] eq. 4.12 with the one latent function of GP-Hom) estimated on
    /// `batch`: the expected log-likelihood summed over the batch times its `scale` minus
    /// `KL(q(u) ‖ p(u))`.
    ///
    /// # Errors
    /// Inconsistent or non-finite data, negative rates, or a `K(Z, Z)` that is not positive
    /// definite.
    pub fn elbo(&self, batch: &Batch<'_>, par: Parallelism) -> Result<f64, GpError> {
        let marg = self.marginals(batch, par)?;
        Ok(self.elbo_of(&self.batch_lik(batch, &marg)))
    }

    /// [`PoissonSvgp::elbo`] and its exact gradient with respect to the kernel
    /// log-parameters, the prior mean `c` and the inducing inputs (with `q(v)` held fixed).
    ///
    /// # Errors
    /// As [`PoissonSvgp::elbo`].
    pub fn elbo_grad(
        &self,
        batch: &Batch<'_>,
        par: Parallelism,
    ) -> Result<PoissonElboGrad, GpError> {
        let marg = self.marginals(batch, par)?;
        Ok(self.grad_from(batch, &marg, par))
    }

    fn grad_from(&self, batch: &Batch<'_>, marg: &Marginals, par: Parallelism) -> PoissonElboGrad {
        let lik = self.batch_lik(batch, marg);
        let (d_kernel, d_z) = self
            .f
            .marginals_backward(batch.x, marg, &lik.dm[0], &lik.dv[0], par);
        PoissonElboGrad {
            elbo: self.elbo_of(&lik),
            d_kernel,
            // m_i = c + a_iᵀμ: ∂/∂c = Σ_i ∂/∂m_i.
            d_mean: lik.dm[0].iter().sum(),
            d_z,
        }
    }

    /// One training iteration on `batch`: a natural-gradient step of size `rho` on
    /// `q(v)` (halved up to 10 times while the new precision is not positive definite), then
    /// the ELBO gradient at the new `q`, reusing the kernel matrices of the step. Returns the
    /// ELBO estimate before the step and that gradient.
    ///
    /// # Errors
    /// As [`PoissonSvgp::elbo`], or a step that stays not positive definite (e.g. a rate
    /// `exp(m + v/2)` that overflows).
    pub fn train_step(
        &mut self,
        batch: &Batch<'_>,
        rho: f64,
        par: Parallelism,
    ) -> Result<(f64, PoissonElboGrad), GpError> {
        let marg = self.marginals(batch, par)?;
        let lik = self.batch_lik(batch, &marg);
        let elbo = self.elbo_of(&lik);
        self.f.q = with_step_halving(rho, |rho| {
            self.f.natgrad_update(&marg, &lik.dm[0], &lik.dv[0], rho)
        })?;
        let marg = self.f.refresh(marg);
        Ok((elbo, self.grad_from(batch, &marg, par)))
    }

    /// Predicted rate at `x`: the mean `E[exp f] = exp(c + m + v/2)` and the standard deviation
    /// `√((eᵛ − 1) exp(2(c + m) + v))` of the log-normal `exp f` (the uncertainty of the rate,
    /// not the Poisson spread of a count). Works in chunks of 1024 points.
    ///
    /// # Errors
    /// Non-finite inputs or a `K(Z, Z)` that is not positive definite.
    pub fn predict(&self, x: &[Point], par: Parallelism) -> Result<Prediction, GpError> {
        if let Some(i) = x.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(GpError::InvalidInput(format!(
                "non-finite value at row {i}"
            )));
        }
        predict_in_chunks(x, |chunk, out| {
            let marg = self.f.marginals(chunk, self.jitter, par)?;
            for (m, v) in marg.mean.iter().zip(&marg.var) {
                let rate = (self.mean + m + 0.5 * v).exp();
                out.mean.push(rate);
                out.std.push(v.exp_m1().sqrt() * rate);
            }
            Ok(())
        })
    }

    /// All hyperparameters trained by Adam, flattened: the `k_f` log-parameters, `c`, then (if
    /// `with_inducing`) `Z` row by row.
    pub fn hyperparameters(&self, with_inducing: bool) -> Vec<f64> {
        flatten(
            &[self.f.kernel.params(), &[self.mean]],
            &[&self.f.z],
            with_inducing,
        )
    }

    /// Inverse of [`PoissonSvgp::hyperparameters`].
    ///
    /// # Panics
    /// If `p` is shorter than [`PoissonSvgp::hyperparameters`] (a programmer error).
    pub fn set_hyperparameters(&mut self, p: &[f64], with_inducing: bool) {
        let nk = self.f.kernel.params().len();
        self.f.kernel.params_mut().copy_from_slice(&p[..nk]);
        self.mean = p[nk];
        if with_inducing {
            let mut rest = p[nk + 1..].chunks_exact(3);
            for z in &mut self.f.z {
                let c = rest.next().expect("parameter vector too short");
                z.copy_from_slice(c);
            }
        }
    }
}

svgp_model!(PoissonSvgp, check_rates);
