//! The whitened sparse variational GP with two latent functions `f` (activity rate) and `g`
//! (noise), [Stüde 2024] eqs. (4.12)–(4.16), its natural-gradient and Adam updates, and
//! prediction.
//!
//! **Whitening.** Each latent GP has inducing values `u = L v` with `L Lᵀ = K(Z, Z) + jitter·I`
//! and `q(v) = N(μ, S)`, `S = L_S L_Sᵀ`. Then `q(u) = N(L μ, L S Lᵀ)` and the marginals of
//! eqs. (4.13)–(4.16) become, with `a_i = L⁻¹ k(Z, x_i)`,
//! `m_i = a_iᵀ μ` and `Σ_ii = k(x_i, x_i) + a_iᵀ (S − I) a_i`, while
//! `KL(q(u) ‖ p(u)) = KL(N(μ, S) ‖ N(0, I))` no longer depends on the hyperparameters.

use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Accum, Mat, MatRef, Par};
use serde::{Deserialize, Serialize};

use super::kernel::{
    ActivityKernel, Kernel, Point, RbfKernel, cross, cross_grad, diag_grad, gram, gram_grad,
};
use super::quad::HeteroGaussian;
use chronomap_core::par::Parallelism;
use chronomap_core::progress::{NoProgress, Progress};
use chronomap_core::rng::Xoshiro256StarStar;

/// Errors of the GP module.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GpError {
    /// A matrix that must be positive definite is not (numerically).
    #[error("{what} is not positive definite")]
    NotPositiveDefinite {
        /// Which matrix.
        what: &'static str,
    },
    /// Inputs are inconsistent (lengths, non-finite values, empty sets).
    #[error("invalid input: {0}")]
    InvalidInput(String),
}

// ---------------------------------------------------------------- small dense linear algebra

/// Lower Cholesky factor of the symmetric matrix `a` (lower triangle read).
pub(super) fn chol(a: MatRef<'_, f64>) -> Option<Mat<f64>> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
    let n = a.nrows();
    let mut m = Mat::from_fn(n, n, |i, j| if j <= i { a[(i, j)] } else { 0.0 });
    let mut mem = MemBuffer::new(cholesky_in_place_scratch::<f64>(
        n,
        Par::Seq,
        Default::default(),
    ));
    cholesky_in_place(
        m.as_mut(),
        Default::default(),
        Par::Seq,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .ok()?;
    for j in 0..n {
        for i in 0..j {
            m[(i, j)] = 0.0;
        }
        if m[(j, j)].partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
    }
    let finite = (0..n).all(|j| (j..n).all(|i| m[(i, j)].is_finite()));
    finite.then_some(m)
}

/// Cholesky factor of a matrix that is positive definite in exact arithmetic but may have lost
/// it to rounding: a growing ridge (from `ε·max|a_ii|`) is added until the factor exists.
fn chol_ridge(a: &Mat<f64>) -> Option<Mat<f64>> {
    if let Some(l) = chol(a.as_ref()) {
        return Some(l);
    }
    let n = a.nrows();
    let scale = (0..n)
        .map(|i| a[(i, i)].abs())
        .fold(0.0, f64::max)
        .max(1e-300);
    let mut ridge = scale * f64::EPSILON;
    for _ in 0..10 {
        let b = Mat::from_fn(n, n, |i, j| a[(i, j)] + if i == j { ridge } else { 0.0 });
        if let Some(l) = chol(b.as_ref()) {
            return Some(l);
        }
        ridge *= 10.0;
    }
    None
}

/// `L x = b` in place.
pub(super) fn solve_l(l: &Mat<f64>, b: &mut Mat<f64>) {
    solve_lower_triangular_in_place(l.as_ref(), b.as_mut(), Par::Seq);
}

/// `Lᵀ x = b` in place.
pub(super) fn solve_lt(l: &Mat<f64>, b: &mut Mat<f64>) {
    solve_upper_triangular_in_place(l.as_ref().transpose(), b.as_mut(), Par::Seq);
}

/// `a · b`.
pub(super) fn mm(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut c = Mat::zeros(a.nrows(), b.ncols());
    matmul(c.as_mut(), Accum::Replace, a, b, 1.0, Par::Seq);
    c
}

/// `L⁻¹` of a lower-triangular `L`.
fn inv_lower(l: &Mat<f64>) -> Mat<f64> {
    let mut x = Mat::identity(l.nrows(), l.nrows());
    solve_l(l, &mut x);
    x
}

fn col(v: &[f64]) -> Mat<f64> {
    Mat::from_fn(v.len(), 1, |i, _| v[i])
}

// ---------------------------------------------------------------- variational distribution

/// The whitened variational distribution `q(v) = N(μ, L_S L_Sᵀ)` of one latent GP.
#[derive(Clone, Debug, PartialEq)]
pub struct Variational {
    /// The mean `μ` (length `M`).
    pub mean: Vec<f64>,
    /// Lower Cholesky factor `L_S` of the covariance (`M × M`).
    pub chol: Mat<f64>,
}

impl Variational {
    /// The prior `N(0, I)` over `M` whitened inducing values (GPflow's initialisation).
    pub fn prior(m: usize) -> Self {
        Variational {
            mean: vec![0.0; m],
            chol: Mat::identity(m, m),
        }
    }

    /// Number of inducing values `M`.
    pub fn len(&self) -> usize {
        self.mean.len()
    }

    /// `true` when there are no inducing values.
    pub fn is_empty(&self) -> bool {
        self.mean.is_empty()
    }

    /// The covariance `S = L_S L_Sᵀ`.
    pub fn covariance(&self) -> Mat<f64> {
        mm(self.chol.as_ref(), self.chol.as_ref().transpose())
    }

    /// `KL(N(μ, S) ‖ N(0, I)) = ½ (tr S + μᵀμ − M − ln|S|)`, which equals
    /// `KL(q(u) ‖ p(u))` of [Stüde 2024] eq. (4.12) under whitening.
    pub fn kl(&self) -> f64 {
        let m = self.len();
        let mut tr = 0.0;
        let mut logdet = 0.0;
        for j in 0..m {
            for i in j..m {
                tr += self.chol[(i, j)] * self.chol[(i, j)];
            }
            logdet += 2.0 * self.chol[(j, j)].ln();
        }
        let mm: f64 = self.mean.iter().map(|v| v * v).sum();
        0.5 * (tr + mm - m as f64 - logdet)
    }
}

// ---------------------------------------------------------------- one latent GP

/// One latent GP of the model: kernel, inducing inputs `Z` and whitened `q(v)`.
#[derive(Clone, Debug, PartialEq)]
pub struct LatentGp<K> {
    /// The covariance function.
    pub kernel: K,
    /// The inducing inputs `Z` (`M` points).
    pub z: Vec<Point>,
    /// The whitened variational distribution.
    pub q: Variational,
}

/// Marginals of one latent GP at a batch of inputs and the intermediates for gradients.
#[derive(Clone, Debug)]
pub struct Marginals {
    /// Means `m_i`, [Stüde 2024] eq. (4.13)/(4.15).
    pub mean: Vec<f64>,
    /// Variances `Σ_ii`, [Stüde 2024] eq. (4.14)/(4.16).
    pub var: Vec<f64>,
    /// `L = chol(K(Z, Z) + jitter·I)`.
    l: Mat<f64>,
    /// `A = L⁻¹ K(Z, X)` (`M × B`).
    a: Mat<f64>,
    /// `L_Sᵀ A`.
    sa: Mat<f64>,
}

impl<K> LatentGp<K> {
    /// A latent GP restored from its saved parts: inducing inputs `z` and `q(v)` with mean
    /// `q_mean` and the lower Cholesky factor packed row by row in `q_chol`.
    pub(super) fn restore(
        kernel: K,
        z: Vec<Point>,
        q_mean: Vec<f64>,
        q_chol: &[f64],
    ) -> Result<Self, GpError> {
        Ok(LatentGp {
            kernel,
            q: Variational {
                chol: unpack_lower(q_chol, z.len())?,
                mean: q_mean,
            },
            z,
        })
    }
}

impl<K: Kernel> LatentGp<K> {
    /// A latent GP with the prior `q(v) = N(0, I)`.
    pub fn new(kernel: K, z: Vec<Point>) -> Self {
        let m = z.len();
        LatentGp {
            kernel,
            z,
            q: Variational::prior(m),
        }
    }

    /// The marginals `q(f_i) = N(m_i, Σ_ii)` at `x` ([Stüde 2024] eqs. 4.13–4.16, diagonal only,
    /// whitened): cost `O(B·M² + M³)`.
    pub fn marginals(
        &self,
        x: &[Point],
        jitter: f64,
        par: Parallelism,
    ) -> Result<Marginals, GpError> {
        let kzz = gram(&self.kernel, &self.z, jitter, par);
        let l = chol(kzz.as_ref()).ok_or(GpError::NotPositiveDefinite { what: "K(Z, Z)" })?;
        let mut a = cross(&self.kernel, &self.z, x, par);
        solve_l(&l, &mut a);
        Ok(self.with_q(l, a))
    }

    /// The marginals for the current `q` from `L` and `A` (which do not depend on `q`).
    fn with_q(&self, l: Mat<f64>, a: Mat<f64>) -> Marginals {
        let sa = mm(self.q.chol.as_ref().transpose(), a.as_ref());
        let kxx = self.kernel.diag();
        let (m, b) = (a.nrows(), a.ncols());
        let mut mean = vec![0.0; b];
        let mut var = vec![0.0; b];
        for j in 0..b {
            let (mut mj, mut aa, mut ss) = (0.0, 0.0, 0.0);
            for i in 0..m {
                mj += a[(i, j)] * self.q.mean[i];
                aa += a[(i, j)] * a[(i, j)];
                ss += sa[(i, j)] * sa[(i, j)];
            }
            mean[j] = mj;
            var[j] = (kxx - aa + ss).max(1e-12 * kxx);
        }
        Marginals {
            mean,
            var,
            l,
            a,
            sa,
        }
    }

    /// Marginals computed for another `q` of this latent GP, updated to the current `q`
    /// (`O(B·M²)`: the kernel matrices and `L⁻¹ K(Z, X)` are reused).
    pub fn refresh(&self, marg: Marginals) -> Marginals {
        self.with_q(marg.l, marg.a)
    }

    /// The gradient of `Σ_i dm_i m_i + dv_i Σ_ii` through the marginals with respect to the
    /// kernel log-parameters and the inducing inputs, in that order (reverse mode through
    /// `A = L⁻¹K(Z,X)` and the Cholesky factor `L`, Murray 2016: `K̄ = L⁻ᵀ Φ(Lᵀ L̄) L⁻¹`).
    pub fn marginals_backward(
        &self,
        x: &[Point],
        marg: &Marginals,
        dm: &[f64],
        dv: &[f64],
        par: Parallelism,
    ) -> (Vec<f64>, Vec<Point>) {
        let mut dtheta = vec![0.0; self.kernel.params().len()];
        let mut dz = vec![[0.0; 3]; self.z.len()];
        let (m, b) = (self.z.len(), x.len());
        // Ā = μ dmᵀ + 2 (S − I) A diag(dv), with (S − I) A = L_S (L_Sᵀ A) − A.
        let s_a = mm(self.q.chol.as_ref(), marg.sa.as_ref());
        let mut kzx_bar = Mat::from_fn(m, b, |i, j| {
            self.q.mean[i] * dm[j] + 2.0 * (s_a[(i, j)] - marg.a[(i, j)]) * dv[j]
        });
        // K̄(Z, X) = L⁻ᵀ Ā; L̄ = −K̄(Z, X) Aᵀ.
        solve_lt(&marg.l, &mut kzx_bar);
        let mut lbar = Mat::zeros(m, m);
        matmul(
            lbar.as_mut(),
            Accum::Replace,
            kzx_bar.as_ref(),
            marg.a.as_ref().transpose(),
            -1.0,
            Par::Seq,
        );
        // Φ(Lᵀ L̄): lower triangle with halved diagonal.
        let mut phi = mm(marg.l.as_ref().transpose(), lbar.as_ref());
        for j in 0..m {
            for i in 0..j {
                phi[(i, j)] = 0.0;
            }
            phi[(j, j)] *= 0.5;
        }
        // K̄(Z, Z) = L⁻ᵀ Φ L⁻¹ = (L⁻ᵀ (L⁻ᵀ Φ)ᵀ)ᵀ.
        solve_lt(&marg.l, &mut phi);
        let mut t = phi.transpose().to_owned();
        solve_lt(&marg.l, &mut t);
        let kzz_bar = t.transpose().to_owned();
        gram_grad(
            &self.kernel,
            &self.z,
            kzz_bar.as_ref(),
            &mut dtheta,
            &mut dz,
            par,
        );
        cross_grad(
            &self.kernel,
            &self.z,
            x,
            kzx_bar.as_ref(),
            &mut dtheta,
            Some(&mut dz),
            None,
            par,
        );
        diag_grad(&self.kernel, dv, &mut dtheta);
        (dtheta, dz)
    }

    /// One natural-gradient step of size `rho` on `q(v)` (Salimbeni et al. 2018), given the
    /// gradient of the (scaled) expected log-likelihood with respect to the marginals
    /// (`dm_i = ∂/∂m_i`, `dv_i = ∂/∂Σ_ii`). In natural parameters
    /// `θ = (S⁻¹μ, −½S⁻¹)` the step is `θ ← (1−ρ)θ + ρ(θ_prior + ∂E/∂η)` with `η = (μ, S + μμᵀ)`:
    /// `S⁻¹ ← (1−ρ)S⁻¹ + ρ(I − 2G)`, `S⁻¹μ ← (1−ρ)S⁻¹μ + ρ(A dm − 2Gμ)`, `G = A diag(dv) Aᵀ`.
    /// With a Gaussian likelihood and `ρ = 1` this is the optimal (Titsias) `q`.
    /// Returns the new `q` (fails when the new `S⁻¹` is not positive definite).
    pub fn natgrad_update(
        &self,
        marg: &Marginals,
        dm: &[f64],
        dv: &[f64],
        rho: f64,
    ) -> Result<Variational, GpError> {
        let (m, b) = (self.z.len(), dm.len());
        let a = &marg.a;
        let a_dv = Mat::from_fn(m, b, |i, j| a[(i, j)] * dv[j]);
        let g = mm(a_dv.as_ref(), a.as_ref().transpose());
        let linv = inv_lower(&self.q.chol);
        let prec = mm(linv.as_ref().transpose(), linv.as_ref());
        let mu = col(&self.q.mean);
        let theta1 = mm(prec.as_ref(), mu.as_ref());
        let g_mu = mm(g.as_ref(), mu.as_ref());
        let a_dm = mm(a.as_ref(), col(dm).as_ref());
        let new_prec = Mat::from_fn(m, m, |i, j| {
            let eye = if i == j { 1.0 } else { 0.0 };
            (1.0 - rho) * prec[(i, j)] + rho * (eye - 2.0 * 0.5 * (g[(i, j)] + g[(j, i)]))
        });
        let mut t1 = Mat::from_fn(m, 1, |i, _| {
            (1.0 - rho) * theta1[(i, 0)] + rho * (a_dm[(i, 0)] - 2.0 * g_mu[(i, 0)])
        });
        let lp = chol(new_prec.as_ref()).ok_or(GpError::NotPositiveDefinite {
            what: "natural-gradient precision",
        })?;
        solve_l(&lp, &mut t1);
        solve_lt(&lp, &mut t1);
        let w = inv_lower(&lp);
        let s = mm(w.as_ref().transpose(), w.as_ref());
        let ls = chol_ridge(&s).ok_or(GpError::NotPositiveDefinite {
            what: "natural-gradient covariance",
        })?;
        Ok(Variational {
            mean: (0..m).map(|i| t1[(i, 0)]).collect(),
            chol: ls,
        })
    }
}

// ---------------------------------------------------------------- the heteroscedastic model

/// The serialised form of [`HeteroSvgp`] (log-parameters, inducing inputs, `q(v)` means and
/// packed lower Cholesky factors row by row), validated on the way back.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct SavedHeteroSvgp {
    kernel_f: Vec<f64>,
    kernel_g: Vec<f64>,
    z_f: Vec<Point>,
    z_g: Vec<Point>,
    q_mean_f: Vec<f64>,
    q_chol_f: Vec<f64>,
    q_mean_g: Vec<f64>,
    q_chol_g: Vec<f64>,
    jitter: f64,
    quadrature_nodes: usize,
}

pub(super) fn pack_lower(l: &Mat<f64>) -> Vec<f64> {
    let n = l.nrows();
    (0..n)
        .flat_map(|i| (0..=i).map(move |j| l[(i, j)]))
        .collect()
}

pub(super) fn unpack_lower(v: &[f64], n: usize) -> Result<Mat<f64>, GpError> {
    if v.len() != n * (n + 1) / 2 {
        return Err(GpError::InvalidInput(format!(
            "packed Cholesky factor has {} entries, expected {}",
            v.len(),
            n * (n + 1) / 2
        )));
    }
    let mut m = Mat::zeros(n, n);
    let mut k = 0;
    for i in 0..n {
        for j in 0..=i {
            m[(i, j)] = v[k];
            k += 1;
        }
        if m[(i, i)].partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Err(GpError::InvalidInput(
                "Cholesky factor has a non-positive diagonal".into(),
            ));
        }
    }
    Ok(m)
}

impl From<HeteroSvgp> for SavedHeteroSvgp {
    fn from(m: HeteroSvgp) -> Self {
        SavedHeteroSvgp {
            kernel_f: m.f.kernel.params().to_vec(),
            kernel_g: m.g.kernel.params().to_vec(),
            q_chol_f: pack_lower(&m.f.q.chol),
            q_chol_g: pack_lower(&m.g.q.chol),
            z_f: m.f.z,
            z_g: m.g.z,
            q_mean_f: m.f.q.mean,
            q_mean_g: m.g.q.mean,
            jitter: m.jitter,
            quadrature_nodes: m.likelihood.n_nodes(),
        }
    }
}

impl SavedHeteroSvgp {
    /// Finite values, kernels of valid lengths and one `q(v)` mean per inducing input.
    fn is_consistent(&self) -> bool {
        let all_finite = self
            .kernel_f
            .iter()
            .chain(&self.kernel_g)
            .chain(self.z_f.iter().flatten())
            .chain(self.z_g.iter().flatten())
            .chain(&self.q_mean_f)
            .chain(&self.q_mean_g)
            .chain(&self.q_chol_f)
            .chain(&self.q_chol_g)
            .all(|v| v.is_finite());
        all_finite
            && self.kernel_f.len() >= 3
            && (self.kernel_f.len() - 3).is_multiple_of(3)
            && self.kernel_g.len() == 4
            && self.z_f.len() == self.q_mean_f.len()
            && self.z_g.len() == self.q_mean_g.len()
            && self.jitter >= 0.0
            && (1..=200).contains(&self.quadrature_nodes)
    }
}

/// `Ok` for a saved model that [`is_consistent`](SavedHeteroSvgp::is_consistent), else the
/// error of one whose parts do not fit together.
pub(super) fn check_saved(consistent: bool) -> Result<(), GpError> {
    if consistent {
        Ok(())
    } else {
        Err(GpError::InvalidInput("inconsistent saved model".into()))
    }
}

impl TryFrom<SavedHeteroSvgp> for HeteroSvgp {
    type Error = GpError;
    fn try_from(s: SavedHeteroSvgp) -> Result<Self, GpError> {
        check_saved(s.is_consistent())?;
        let mut kf = ActivityKernel::new(1.0, [1.0, 1.0], &[]);
        let mut kg = RbfKernel::new(1.0, [1.0; 3]);
        // ActivityKernel::new with no components has 3 parameters; grow to the saved length.
        kf.set_params(&s.kernel_f);
        kg.params_mut().copy_from_slice(&s.kernel_g);
        Ok(HeteroSvgp {
            f: LatentGp::restore(kf, s.z_f, s.q_mean_f, &s.q_chol_f)?,
            g: LatentGp::restore(kg, s.z_g, s.q_mean_g, &s.q_chol_g)?,
            likelihood: HeteroGaussian::new(s.quadrature_nodes),
            jitter: s.jitter,
        })
    }
}

/// The CoPA-Map model, [Stüde 2024] eq. (4.7): `y ~ N(f(x), ζ(g(x))²)` with `f ~ GP(0, k_f)`
/// ([`ActivityKernel`], eqs. 4.8–4.10) and `g ~ GP(0, k_g)` ([`RbfKernel`], eq. 4.11), each
/// approximated by a whitened SVGP with its own inducing inputs.
///
/// Serialisable (serde) for saving a trained model; deserialisation validates shapes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "SavedHeteroSvgp", into = "SavedHeteroSvgp")]
pub struct HeteroSvgp {
    /// The latent rate function `f`.
    pub f: LatentGp<ActivityKernel>,
    /// The latent noise function `g` (noise standard deviation `ζ(g)`).
    pub g: LatentGp<RbfKernel>,
    /// The likelihood and its quadrature rule.
    pub likelihood: HeteroGaussian,
    /// Jitter added to the diagonal of `K(Z, Z)` (default `1e-6`).
    pub jitter: f64,
}

/// The ELBO estimate of a minibatch and its gradient.
#[derive(Clone, Debug, PartialEq)]
pub struct ElboGrad {
    /// `scale · Σ_batch E[ln p(y|f,g)] − KL_f − KL_g`.
    pub elbo: f64,
    /// `∂/∂` log-parameters of `k_f`.
    pub d_kernel_f: Vec<f64>,
    /// `∂/∂` log-parameters of `k_g`.
    pub d_kernel_g: Vec<f64>,
    /// `∂/∂Z_f`.
    pub d_z_f: Vec<Point>,
    /// `∂/∂Z_g`.
    pub d_z_g: Vec<Point>,
}

/// Predictive means and standard deviations: of `y` for [`HeteroSvgp::predict`], of the rate
/// `exp f` for [`PoissonSvgp::predict`](super::PoissonSvgp::predict).
#[derive(Clone, Debug, PartialEq)]
pub struct Prediction {
    /// [`HeteroSvgp`]: `E[y] = m_f`; [`PoissonSvgp`](super::PoissonSvgp): `E[exp f]`.
    pub mean: Vec<f64>,
    /// [`HeteroSvgp`]: `√(Σ_f + E[ζ(g)²])`; [`PoissonSvgp`](super::PoissonSvgp): the standard
    /// deviation of `exp f`.
    pub std: Vec<f64>,
}

/// The marginals of both latent GPs of a [`HeteroSvgp`] at prediction points
/// ([`HeteroSvgp::predict_latent`]): `q(f(x_i)) = N(f_mean_i, f_var_i)`,
/// `q(g(x_i)) = N(g_mean_i, g_var_i)` ([Stüde 2024] eqs. 4.13–4.16).
#[derive(Clone, Debug, PartialEq)]
pub struct LatentPrediction {
    /// Means of the rate function `f`.
    pub f_mean: Vec<f64>,
    /// Variances of `f` (the uncertainty of the function, without the noise).
    pub f_var: Vec<f64>,
    /// Means of the noise function `g` (noise standard deviation `ζ(g)`).
    pub g_mean: Vec<f64>,
    /// Variances of `g`.
    pub g_var: Vec<f64>,
}

/// A batch of training data `(x, y)` and the factor `scale` by which its expected
/// log-likelihood enters the ELBO estimate ([Stüde 2024] eq. 4.12): `n / |B|` for a minibatch
/// of a data set of `n` points, `1` for the full data.
#[derive(Clone, Copy, Debug)]
pub struct Batch<'a> {
    /// The inputs.
    pub x: &'a [Point],
    /// The targets.
    pub y: &'a [f64],
    /// The factor of the expected log-likelihood.
    pub scale: f64,
}

/// The likelihood term of the ELBO on a batch (the first term of [Stüde 2024] eq. 4.12) for a
/// model of `L` latent GPs: `scale · Σ_i E_{q}[ln p(y_i | ·)]` and its per-point gradients
/// with respect to the marginal mean `m_{l,i}` and variance `v_{l,i}` of every latent GP `l`,
/// scaled the same way. The one batch likelihood of [`HeteroSvgp`] (`L = 2`: `f`, `g`) and
/// [`PoissonSvgp`](super::PoissonSvgp) (`L = 1`).
pub(super) struct BatchLik<const L: usize> {
    /// `scale · Σ_i E_i`.
    pub(super) ell: f64,
    /// `scale · ∂E_i/∂m_{l,i}`, indexed `[l][i]`.
    pub(super) dm: [Vec<f64>; L],
    /// `scale · ∂E_i/∂v_{l,i}`, indexed `[l][i]`.
    pub(super) dv: [Vec<f64>; L],
}

impl<const L: usize> BatchLik<L> {
    /// The likelihood of `batch` from `point(i) = (E_i, [∂E_i/∂m_l], [∂E_i/∂v_l])`.
    pub(super) fn new(
        batch: &Batch<'_>,
        mut point: impl FnMut(usize) -> (f64, [f64; L], [f64; L]),
    ) -> Self {
        let (n, scale) = (batch.y.len(), batch.scale);
        let mut out = BatchLik {
            ell: 0.0,
            dm: std::array::from_fn(|_| vec![0.0; n]),
            dv: std::array::from_fn(|_| vec![0.0; n]),
        };
        for i in 0..n {
            let (value, dm, dv) = point(i);
            out.ell += value;
            for l in 0..L {
                out.dm[l][i] = scale * dm[l];
                out.dv[l][i] = scale * dv[l];
            }
        }
        out.ell *= scale;
        out
    }
}

/// The [`Prediction`] at `x`, built in chunks of 1024 points (bounding the size of the
/// marginals): `push(chunk, out)` appends the predictions of one chunk to `out`.
pub(super) fn predict_in_chunks(
    x: &[Point],
    mut push: impl FnMut(&[Point], &mut Prediction) -> Result<(), GpError>,
) -> Result<Prediction, GpError> {
    let mut out = Prediction {
        mean: Vec::with_capacity(x.len()),
        std: Vec::with_capacity(x.len()),
    };
    for chunk in x.chunks(1024) {
        push(chunk, &mut out)?;
    }
    Ok(out)
}

/// Hyperparameters, or their gradient, flattened in the order Adam sees them: the `parts`
/// (kernel log-parameters, a prior mean, ...) in turn, then, if `with_inducing`, the inducing
/// inputs of every latent GP row by row.
pub(super) fn flatten(parts: &[&[f64]], inducing: &[&[Point]], with_inducing: bool) -> Vec<f64> {
    let mut p: Vec<f64> = parts.concat();
    if with_inducing {
        for z in inducing {
            p.extend(z.iter().flatten());
        }
    }
    p
}

pub(super) fn check_data(x: &[Point], y: &[f64]) -> Result<(), GpError> {
    if x.len() != y.len() {
        return Err(GpError::InvalidInput(format!(
            "{} inputs but {} targets",
            x.len(),
            y.len()
        )));
    }
    if let Some(i) = x
        .iter()
        .zip(y)
        .position(|(p, v)| !(p.iter().all(|c| c.is_finite()) && v.is_finite()))
    {
        return Err(GpError::InvalidInput(format!(
            "non-finite value at row {i}"
        )));
    }
    Ok(())
}

impl HeteroSvgp {
    /// A model with kernels `kernel_f`, `kernel_g`, the same initial inducing inputs `z` for
    /// both latent GPs and priors `q(v_f) = q(v_g) = N(0, I)` (as GPflow's `SVGP`).
    pub fn new(kernel_f: ActivityKernel, kernel_g: RbfKernel, z: Vec<Point>) -> Self {
        HeteroSvgp {
            f: LatentGp::new(kernel_f, z.clone()),
            g: LatentGp::new(kernel_g, z),
            likelihood: HeteroGaussian::default(),
            jitter: 1e-6,
        }
    }

    /// The marginals of `f` and `g` on a checked batch.
    fn marginals(
        &self,
        batch: &Batch<'_>,
        par: Parallelism,
    ) -> Result<(Marginals, Marginals), GpError> {
        check_data(batch.x, batch.y)?;
        let mf = self.f.marginals(batch.x, self.jitter, par)?;
        let mg = self.g.marginals(batch.x, self.jitter, par)?;
        Ok((mf, mg))
    }

    /// The ELBO of eq. 4.12 from the batch likelihood: minus both KL terms.
    fn elbo_of(&self, lik: &BatchLik<2>) -> f64 {
        lik.ell - self.f.q.kl() - self.g.q.kl()
    }

    fn batch_lik(&self, batch: &Batch<'_>, mf: &Marginals, mg: &Marginals) -> BatchLik<2> {
        let y = batch.y;
        BatchLik::new(batch, |i| {
            let e = self
                .likelihood
                .expected_log_lik(y[i], mf.mean[i], mf.var[i], mg.mean[i], mg.var[i]);
            (e.value, [e.d_mf, e.d_mg], [e.d_vf, e.d_vg])
        })
    }

    /// The ELBO ([Stüde 2024] eq. 4.12) estimated on `batch`: the expected log-likelihood
    /// summed over the batch times its `scale` minus both KL terms.
    pub fn elbo(&self, batch: &Batch<'_>, par: Parallelism) -> Result<f64, GpError> {
        let (mf, mg) = self.marginals(batch, par)?;
        let lik = self.batch_lik(batch, &mf, &mg);
        Ok(self.elbo_of(&lik))
    }

    /// [`HeteroSvgp::elbo`] and its exact gradient with respect to both kernels'
    /// log-parameters and both sets of inducing inputs (with `q(v)` held fixed).
    pub fn elbo_grad(&self, batch: &Batch<'_>, par: Parallelism) -> Result<ElboGrad, GpError> {
        let (mf, mg) = self.marginals(batch, par)?;
        Ok(self.grad_from(batch, &mf, &mg, par))
    }

    /// [`HeteroSvgp::elbo_grad`] from already computed marginals.
    fn grad_from(
        &self,
        batch: &Batch<'_>,
        mf: &Marginals,
        mg: &Marginals,
        par: Parallelism,
    ) -> ElboGrad {
        let lik = self.batch_lik(batch, mf, mg);
        let x = batch.x;
        let (d_kernel_f, d_z_f) = self
            .f
            .marginals_backward(x, mf, &lik.dm[0], &lik.dv[0], par);
        let (d_kernel_g, d_z_g) = self
            .g
            .marginals_backward(x, mg, &lik.dm[1], &lik.dv[1], par);
        ElboGrad {
            elbo: self.elbo_of(&lik),
            d_kernel_f,
            d_kernel_g,
            d_z_f,
            d_z_g,
        }
    }

    /// One natural-gradient step of size `rho` on `q(v_f)` and `q(v_g)` with `batch` (both
    /// use the marginals before the step, as GPflow's `NaturalGradient` does). Returns the
    /// ELBO estimate before the step. If a step is not positive definite, neither `q` changes
    /// and the error is returned.
    pub fn natgrad_step(
        &mut self,
        batch: &Batch<'_>,
        rho: f64,
        par: Parallelism,
    ) -> Result<f64, GpError> {
        let (mf, mg) = self.marginals(batch, par)?;
        let lik = self.batch_lik(batch, &mf, &mg);
        let elbo = self.elbo_of(&lik);
        let qf = self.f.natgrad_update(&mf, &lik.dm[0], &lik.dv[0], rho)?;
        let qg = self.g.natgrad_update(&mg, &lik.dm[1], &lik.dv[1], rho)?;
        self.f.q = qf;
        self.g.q = qg;
        Ok(elbo)
    }

    /// One training iteration on `batch`: a natural-gradient step of size `rho` on both `q`
    /// (halved up to 10 times while the new precision is not positive definite), then the
    /// ELBO gradient for the hyperparameters at the new `q`, reusing the kernel matrices of
    /// the step. Returns the ELBO estimate before the step and that gradient.
    pub fn train_step(
        &mut self,
        batch: &Batch<'_>,
        rho: f64,
        par: Parallelism,
    ) -> Result<(f64, ElboGrad), GpError> {
        let (mf, mg) = self.marginals(batch, par)?;
        let lik = self.batch_lik(batch, &mf, &mg);
        let elbo = self.elbo_of(&lik);
        let (qf, qg) = with_step_halving(rho, |rho| {
            let qf = self.f.natgrad_update(&mf, &lik.dm[0], &lik.dv[0], rho)?;
            Ok((qf, self.g.natgrad_update(&mg, &lik.dm[1], &lik.dv[1], rho)?))
        })?;
        self.f.q = qf;
        self.g.q = qg;
        let mf = self.f.refresh(mf);
        let mg = self.g.refresh(mg);
        Ok((elbo, self.grad_from(batch, &mf, &mg, par)))
    }

    /// Predictive mean and standard deviation of `y` at `x` ([Stüde 2024] eq. 4.19): mean `m_f`,
    /// variance `Σ_f + E_{q(g)}[ζ(g)²]`. Works in chunks of 1024 points.
    pub fn predict(&self, x: &[Point], par: Parallelism) -> Result<Prediction, GpError> {
        let latent = self.predict_latent(x, par)?;
        let std = latent
            .f_var
            .iter()
            .zip(latent.g_mean.iter().zip(&latent.g_var))
            .map(|(vf, (&mg, &vg))| (vf + self.likelihood.expected_noise_variance(mg, vg)).sqrt())
            .collect();
        Ok(Prediction {
            mean: latent.f_mean,
            std,
        })
    }

    /// The marginals of `f` and `g` at `x` ([Stüde 2024] eqs. 4.13–4.16): what the predictive
    /// law of `y` is made of ([`HeteroGaussian::central_half_width`]). Works in chunks of 1024
    /// points.
    pub fn predict_latent(
        &self,
        x: &[Point],
        par: Parallelism,
    ) -> Result<LatentPrediction, GpError> {
        let mut out = LatentPrediction {
            f_mean: Vec::with_capacity(x.len()),
            f_var: Vec::with_capacity(x.len()),
            g_mean: Vec::with_capacity(x.len()),
            g_var: Vec::with_capacity(x.len()),
        };
        for chunk in x.chunks(1024) {
            let mf = self.f.marginals(chunk, self.jitter, par)?;
            let mg = self.g.marginals(chunk, self.jitter, par)?;
            out.f_mean.extend(mf.mean);
            out.f_var.extend(mf.var);
            out.g_mean.extend(mg.mean);
            out.g_var.extend(mg.var);
        }
        Ok(out)
    }

    /// All hyperparameters trained by Adam, flattened: `k_f` log-parameters, `k_g`
    /// log-parameters, then (if `with_inducing`) `Z_f` and `Z_g` row by row.
    pub fn hyperparameters(&self, with_inducing: bool) -> Vec<f64> {
        flatten(
            &[self.f.kernel.params(), self.g.kernel.params()],
            &[&self.f.z, &self.g.z],
            with_inducing,
        )
    }

    /// Inverse of [`HeteroSvgp::hyperparameters`].
    pub fn set_hyperparameters(&mut self, p: &[f64], with_inducing: bool) {
        let nf = self.f.kernel.params().len();
        let ng = self.g.kernel.params().len();
        self.f.kernel.params_mut().copy_from_slice(&p[..nf]);
        self.g.kernel.params_mut().copy_from_slice(&p[nf..nf + ng]);
        if with_inducing {
            let mut rest = p[nf + ng..].chunks_exact(3);
            for z in self.f.z.iter_mut().chain(self.g.z.iter_mut()) {
                let c = rest.next().expect("parameter vector too short");
                z.copy_from_slice(c);
            }
        }
    }
}

impl ElboGrad {
    /// The gradient flattened in the order of [`HeteroSvgp::hyperparameters`].
    pub fn flatten(&self, with_inducing: bool) -> Vec<f64> {
        flatten(
            &[&self.d_kernel_f, &self.d_kernel_g],
            &[&self.d_z_f, &self.d_z_g],
            with_inducing,
        )
    }
}

// ---------------------------------------------------------------- optimisation

/// The Adam optimiser (Kingma & Ba 2014), here ascending an objective.
#[derive(Clone, Debug, PartialEq)]
pub struct Adam {
    /// Step size.
    pub learning_rate: f64,
    /// First-moment decay (0.9).
    pub beta1: f64,
    /// Second-moment decay (0.999).
    pub beta2: f64,
    /// Denominator offset (1e-7 as in TensorFlow).
    pub epsilon: f64,
    m: Vec<f64>,
    v: Vec<f64>,
    t: i32,
}

impl Adam {
    /// Adam with step size `learning_rate` and the usual defaults.
    pub fn new(learning_rate: f64) -> Self {
        Adam {
            learning_rate,
            beta1: 0.9,
            beta2: 0.999,
            epsilon: 1e-7,
            m: Vec::new(),
            v: Vec::new(),
            t: 0,
        }
    }

    /// One ascent step: `p ← p + lr · m̂ / (√v̂ + ε)`.
    pub fn ascend(&mut self, params: &mut [f64], grad: &[f64]) {
        if self.m.len() != params.len() {
            self.m = vec![0.0; params.len()];
            self.v = vec![0.0; params.len()];
            self.t = 0;
        }
        self.t += 1;
        let c1 = 1.0 - self.beta1.powi(self.t);
        let c2 = 1.0 - self.beta2.powi(self.t);
        for i in 0..params.len() {
            self.m[i] = self.beta1 * self.m[i] + (1.0 - self.beta1) * grad[i];
            self.v[i] = self.beta2 * self.v[i] + (1.0 - self.beta2) * grad[i] * grad[i];
            params[i] +=
                self.learning_rate * (self.m[i] / c1) / ((self.v[i] / c2).sqrt() + self.epsilon);
        }
    }
}

/// Settings of [`train`] (defaults follow the original `adam_natgrad` optimiser).
#[derive(Clone, Debug, PartialEq)]
pub struct TrainConfig {
    /// Number of iterations (one natural-gradient step and one Adam step each).
    pub iterations: usize,
    /// Minibatch size (the full data when larger than `n`).
    pub batch_size: usize,
    /// Natural-gradient step size `γ` (0.1).
    pub natgrad_step: f64,
    /// Adam step size (0.01).
    pub learning_rate: f64,
    /// Whether Adam also moves the inducing inputs.
    pub train_inducing: bool,
    /// Seed of the minibatch sampler.
    pub seed: u64,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            iterations: 200,
            batch_size: 1100,
            natgrad_step: 0.1,
            learning_rate: 0.01,
            train_inducing: true,
            seed: 0,
        }
    }
}

/// Runs `step(rho)` and, while it fails for a matrix that is not positive definite, again
/// with half the step size (up to 10 times) before the error is returned.
pub(super) fn with_step_halving<T>(
    rho: f64,
    mut step: impl FnMut(f64) -> Result<T, GpError>,
) -> Result<T, GpError> {
    let mut rho = rho;
    let mut tries = 0;
    loop {
        match step(rho) {
            Err(GpError::NotPositiveDefinite { .. }) if tries < 10 => {
                rho *= 0.5;
                tries += 1;
            }
            result => return result,
        }
    }
}

/// A sparse variational GP that [`train`] optimises: [`HeteroSvgp`] (CoPA-Map) and
/// [`PoissonSvgp`](super::PoissonSvgp) (GP-Hom).
pub trait SvgpModel {
    /// Checks a training set before any change (lengths, finite values, the likelihood's
    /// range of `y`).
    ///
    /// # Errors
    /// [`GpError::InvalidInput`] naming the first offending row.
    fn check_training_data(&self, x: &[Point], y: &[f64]) -> Result<(), GpError>;

    /// One training iteration of [`train`] on `batch`: a natural-gradient step of size
    /// `config.natgrad_step` on every `q(v)` (halved while not positive definite), then the
    /// ELBO gradient at the new `q` flattened in the order of
    /// [`SvgpModel::hyperparameters`]`(config.train_inducing)`. Returns the ELBO estimate
    /// before the step and that gradient.
    ///
    /// # Errors
    /// As the model's `train_step`.
    fn train_iteration(
        &mut self,
        batch: &Batch<'_>,
        config: &TrainConfig,
        par: Parallelism,
    ) -> Result<(f64, Vec<f64>), GpError>;

    /// The hyperparameters trained by Adam, flattened.
    fn hyperparameters(&self, with_inducing: bool) -> Vec<f64>;

    /// Inverse of [`SvgpModel::hyperparameters`].
    fn set_hyperparameters(&mut self, p: &[f64], with_inducing: bool);
}

/// Implements [`SvgpModel`] for a model with inherent `train_step`, `hyperparameters` and
/// `set_hyperparameters` and a gradient with `flatten`, whose training data `$check` checks.
macro_rules! svgp_model {
    ($model:ty, $check:path) => {
        impl SvgpModel for $model {
            fn check_training_data(&self, x: &[Point], y: &[f64]) -> Result<(), GpError> {
                $check(x, y)
            }

            fn train_iteration(
                &mut self,
                batch: &Batch<'_>,
                config: &TrainConfig,
                par: Parallelism,
            ) -> Result<(f64, Vec<f64>), GpError> {
                let (elbo, grad) = self.train_step(batch, config.natgrad_step, par)?;
                Ok((elbo, grad.flatten(config.train_inducing)))
            }

            fn hyperparameters(&self, with_inducing: bool) -> Vec<f64> {
                <$model>::hyperparameters(self, with_inducing)
            }

            fn set_hyperparameters(&mut self, p: &[f64], with_inducing: bool) {
                <$model>::set_hyperparameters(self, p, with_inducing);
            }
        }
    };
}
pub(super) use svgp_model;

svgp_model!(HeteroSvgp, check_data);

/// Trains `model` on `(x, y)` by alternating a natural-gradient step on its `q(v)` and an
/// Adam step on the hyperparameters (and inducing inputs) on the same minibatch ([Stüde 2024]
/// §4.2.5). Returns the minibatch ELBO estimate (scaled by `n/|B|`) measured at the start of
/// each iteration. A natural-gradient step that is not positive definite is retried with half
/// the step size (up to 10 times) before the error is returned.
pub fn train<M: SvgpModel>(
    model: &mut M,
    x: &[Point],
    y: &[f64],
    config: &TrainConfig,
    par: Parallelism,
) -> Result<Vec<f64>, GpError> {
    train_with_progress(model, x, y, config, par, &NoProgress)
}

/// [`train`], reporting one step to `progress` per iteration (the caller names the stage).
///
/// # Errors
/// As [`train`].
pub fn train_with_progress<M: SvgpModel>(
    model: &mut M,
    x: &[Point],
    y: &[f64],
    config: &TrainConfig,
    par: Parallelism,
    progress: &dyn Progress,
) -> Result<Vec<f64>, GpError> {
    model.check_training_data(x, y)?;
    if x.is_empty() {
        return Err(GpError::InvalidInput("no training data".into()));
    }
    let n = x.len();
    let b = config.batch_size.clamp(1, n);
    let scale = n as f64 / b as f64;
    let mut rng = Xoshiro256StarStar::seed_from_u64(config.seed);
    let mut adam = Adam::new(config.learning_rate);
    let mut idx: Vec<usize> = (0..n).collect();
    let mut trace = Vec::with_capacity(config.iterations);
    let (mut bx, mut by) = (Vec::with_capacity(b), Vec::with_capacity(b));
    for _ in 0..config.iterations {
        // Partial Fisher–Yates: the first b entries of idx are a uniform sample.
        for i in 0..b {
            let j = rng.int_in(i as u64, (n - 1) as u64) as usize;
            idx.swap(i, j);
        }
        bx.clear();
        by.clear();
        for &i in &idx[..b] {
            bx.push(x[i]);
            by.push(y[i]);
        }
        let batch = Batch {
            x: &bx,
            y: &by,
            scale,
        };
        let (elbo, grad) = model.train_iteration(&batch, config, par)?;
        trace.push(elbo);
        let mut p = model.hyperparameters(config.train_inducing);
        adam.ascend(&mut p, &grad);
        model.set_hyperparameters(&p, config.train_inducing);
        progress.advance(1);
    }
    Ok(trace)
}
