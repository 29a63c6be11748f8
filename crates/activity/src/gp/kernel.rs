//! Covariance functions over spatio-temporal inputs `x = (x1, x2, t)` ([Stüde 2024] §4.2.3),
//! their Gram matrices, and their gradients with respect to the log-hyperparameters and to
//! the inputs (for moving inducing points).
//!
//! All hyperparameters are stored as natural logarithms, so any real vector is a valid
//! parameter vector and gradient steps keep variances, length scales and periods positive.
//! Every kernel here is stationary (`k(x, y) = φ(x − y)` with `φ` even), so the gradient with
//! respect to the second argument is the negated gradient with respect to the first.

use faer::{Mat, MatRef};
use rayon::prelude::*;

use chronomap_core::par::Parallelism;

/// A spatio-temporal input `(x1, x2, t)`.
pub type Point = [f64; 3];

/// A stationary covariance function with log-parameters.
pub trait Kernel: Sync {
    /// The log-hyperparameters (layout documented by each kernel).
    fn params(&self) -> &[f64];
    /// Mutable access to the log-hyperparameters.
    fn params_mut(&mut self) -> &mut [f64];
    /// `k(x, y)`.
    fn eval(&self, x: &Point, y: &Point) -> f64;
    /// `k(x, y)`; writes `∂k/∂θ` (θ = log-parameters, in [`Kernel::params`] order) into
    /// `dtheta` and `∂k/∂x` (first argument) into `dx`.
    fn eval_grad(&self, x: &Point, y: &Point, dtheta: &mut [f64], dx: &mut Point) -> f64;
    /// `k(x, x)` (the same for every `x`: the kernel is stationary).
    fn diag(&self) -> f64;
    /// Writes `∂k(x, x)/∂θ` into `dtheta`.
    fn diag_grad(&self, dtheta: &mut [f64]);
}

/// Matérn-5/2 correlation of [Stüde 2024] eq. (4.9) (without the variance) at `d = x − x'`:
/// returns `(m, ∂m/∂ln l, ∂m/∂d)`.
fn matern52(d: f64, l: f64) -> (f64, f64, f64) {
    let a = 5f64.sqrt() * d.abs() / l;
    let e = (-a).exp();
    let m = (1.0 + a + a * a / 3.0) * e;
    let dlog_l = e * a * a * (1.0 + a) / 3.0;
    let dd = -e * (1.0 + a) * 5.0 * d / (3.0 * l * l);
    (m, dlog_l, dd)
}

/// The covariance `k_f` of the activity rate, [Stüde 2024] eq. (4.8): a spatial Matérn-5/2 part
/// (eq. 4.9) over `x1` and `x2` times a sum of periodic components over `t` (eq. 4.10).
///
/// `k_f(x, x') = σ_s² · m(|Δx1|/l_1) · m(|Δx2|/l_2) · Σ_i σ_i² exp(−½ sin²(π Δt/γ_i) / l_{t,i}²)`
///
/// The dissertation writes one `k_s` per spatial dimension, each with its own variance; the two
/// variances multiply, so a single `σ_s²` is kept (as GPflow's one `Matern52` variance).
/// Each dimension has its own length scale (set them equal for the dissertation's shared `l_s`).
/// The periodic argument is `π Δt / γ_i` as in GPflow's `Periodic` kernel, so that `γ_i` is
/// the period (the dissertation's eq. 4.10 writes `γ_i⁻¹ Δt`, a period of `π γ_i`).
///
/// Parameter layout (natural logs): `[σ_s², l_1, l_2]` then `[σ_i², l_{t,i}, γ_i]` for each
/// periodic component `i`.
#[derive(Clone, Debug, PartialEq)]
pub struct ActivityKernel {
    params: Vec<f64>,
}

/// One periodic component of [`ActivityKernel`] (natural, not log, values).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeriodicComponent {
    /// Variance `σ_{t,i}²`.
    pub variance: f64,
    /// Length scale `l_{t,i}`.
    pub lengthscale: f64,
    /// Period `γ_i` (same unit as `t`).
    pub period: f64,
}

impl ActivityKernel {
    /// A kernel with spatial variance `spatial_variance`, spatial length scales
    /// `spatial_lengthscales` and the given periodic components (all values positive).
    pub fn new(
        spatial_variance: f64,
        spatial_lengthscales: [f64; 2],
        components: &[PeriodicComponent],
    ) -> Self {
        let mut params = vec![
            spatial_variance.ln(),
            spatial_lengthscales[0].ln(),
            spatial_lengthscales[1].ln(),
        ];
        for c in components {
            params.extend([c.variance.ln(), c.lengthscale.ln(), c.period.ln()]);
        }
        ActivityKernel { params }
    }

    /// Replaces all log-parameters (layout above; the number of periodic components may
    /// change). Panics unless `params.len() = 3 + 3ψ`.
    pub fn set_params(&mut self, params: &[f64]) {
        assert!(
            params.len() >= 3 && (params.len() - 3).is_multiple_of(3),
            "ActivityKernel needs 3 + 3ψ parameters"
        );
        self.params = params.to_vec();
    }

    /// Number of periodic components `ψ`.
    pub fn n_components(&self) -> usize {
        (self.params.len() - 3) / 3
    }

    /// The periodic components (natural values).
    pub fn components(&self) -> Vec<PeriodicComponent> {
        self.params[3..]
            .chunks_exact(3)
            .map(|c| PeriodicComponent {
                variance: c[0].exp(),
                lengthscale: c[1].exp(),
                period: c[2].exp(),
            })
            .collect()
    }
}

impl Kernel for ActivityKernel {
    fn params(&self) -> &[f64] {
        &self.params
    }
    fn params_mut(&mut self) -> &mut [f64] {
        &mut self.params
    }
    fn eval(&self, x: &Point, y: &Point) -> f64 {
        let p = &self.params;
        let (m1, _, _) = matern52(x[0] - y[0], p[1].exp());
        let (m2, _, _) = matern52(x[1] - y[1], p[2].exp());
        let dt = x[2] - y[2];
        let t: f64 = p[3..]
            .chunks_exact(3)
            .map(|c| {
                let (l, gamma) = (c[1].exp(), c[2].exp());
                let s = (std::f64::consts::PI * dt / gamma).sin();
                c[0].exp() * (-0.5 * s * s / (l * l)).exp()
            })
            .sum();
        p[0].exp() * m1 * m2 * t
    }
    fn eval_grad(&self, x: &Point, y: &Point, dtheta: &mut [f64], dx: &mut Point) -> f64 {
        let p = &self.params;
        let var_s = p[0].exp();
        let (m1, m1_l, m1_d) = matern52(x[0] - y[0], p[1].exp());
        let (m2, m2_l, m2_d) = matern52(x[1] - y[1], p[2].exp());
        let s = var_s * m1 * m2;
        let dt = x[2] - y[2];
        let mut t = 0.0;
        let mut t_d = 0.0;
        for (c, g) in p[3..].chunks_exact(3).zip(dtheta[3..].chunks_exact_mut(3)) {
            let (l, gamma) = (c[1].exp(), c[2].exp());
            let u = std::f64::consts::PI * dt / gamma;
            let (sn, cs) = u.sin_cos();
            let ci = c[0].exp() * (-0.5 * sn * sn / (l * l)).exp();
            t += ci;
            t_d += -ci * sn * cs / (l * l) * std::f64::consts::PI / gamma;
            g[0] = s * ci;
            g[1] = s * ci * sn * sn / (l * l);
            g[2] = s * ci * sn * cs * u / (l * l);
        }
        dtheta[0] = s * t;
        dtheta[1] = var_s * m1_l * m2 * t;
        dtheta[2] = var_s * m1 * m2_l * t;
        dx[0] = var_s * m1_d * m2 * t;
        dx[1] = var_s * m1 * m2_d * t;
        dx[2] = s * t_d;
        s * t
    }
    fn diag(&self) -> f64 {
        let sum: f64 = self.params[3..].chunks_exact(3).map(|c| c[0].exp()).sum();
        self.params[0].exp() * sum
    }
    fn diag_grad(&self, dtheta: &mut [f64]) {
        dtheta.fill(0.0);
        let var_s = self.params[0].exp();
        let mut sum = 0.0;
        for (c, g) in self.params[3..]
            .chunks_exact(3)
            .zip(dtheta[3..].chunks_exact_mut(3))
        {
            sum += c[0].exp();
            g[0] = var_s * c[0].exp();
        }
        dtheta[0] = var_s * sum;
    }
}

/// The RBF (squared exponential) covariance `k_g` of the noise process, [Stüde 2024] eq. (4.11),
/// with one length scale per input dimension:
/// `k_g(x, x') = σ_g² exp(−½ Σ_d (Δx_d / l_d)²)`.
///
/// Parameter layout (natural logs): `[σ_g², l_1, l_2, l_t]`.
#[derive(Clone, Debug, PartialEq)]
pub struct RbfKernel {
    params: Vec<f64>,
}

impl RbfKernel {
    /// An RBF kernel with variance `variance` and length scales `lengthscales`.
    pub fn new(variance: f64, lengthscales: [f64; 3]) -> Self {
        RbfKernel {
            params: vec![
                variance.ln(),
                lengthscales[0].ln(),
                lengthscales[1].ln(),
                lengthscales[2].ln(),
            ],
        }
    }
}

impl Kernel for RbfKernel {
    fn params(&self) -> &[f64] {
        &self.params
    }
    fn params_mut(&mut self) -> &mut [f64] {
        &mut self.params
    }
    fn eval(&self, x: &Point, y: &Point) -> f64 {
        let r2: f64 = (0..3)
            .map(|d| ((x[d] - y[d]) / self.params[d + 1].exp()).powi(2))
            .sum();
        self.params[0].exp() * (-0.5 * r2).exp()
    }
    fn eval_grad(&self, x: &Point, y: &Point, dtheta: &mut [f64], dx: &mut Point) -> f64 {
        let k = self.eval(x, y);
        dtheta[0] = k;
        for d in 0..3 {
            let l = self.params[d + 1].exp();
            let q = (x[d] - y[d]) / l;
            dtheta[d + 1] = k * q * q;
            dx[d] = -k * q / l;
        }
        k
    }
    fn diag(&self) -> f64 {
        self.params[0].exp()
    }
    fn diag_grad(&self, dtheta: &mut [f64]) {
        dtheta.fill(0.0);
        dtheta[0] = self.params[0].exp();
    }
}

/// Runs `f(i)` for `i in 0..n`, in parallel when `par` allows; results keep index order, so
/// they never depend on `par`.
pub(crate) fn map_rows<T: Send, F: Fn(usize) -> T + Sync + Send>(
    n: usize,
    par: Parallelism,
    f: F,
) -> Vec<T> {
    if par.tasks() > 1 && n > 1 {
        let min_len = n.div_ceil(par.tasks() * 4).max(1);
        (0..n)
            .into_par_iter()
            .with_min_len(min_len)
            .map(f)
            .collect()
    } else {
        (0..n).map(f).collect()
    }
}

/// The cross-covariance `K(A, B)` (`|A| × |B|`, entry `(i, j)` = `k(a_i, b_j)`).
pub fn cross<K: Kernel>(k: &K, a: &[Point], b: &[Point], par: Parallelism) -> Mat<f64> {
    let rows = map_rows(a.len(), par, |i| {
        b.iter().map(|bj| k.eval(&a[i], bj)).collect::<Vec<f64>>()
    });
    Mat::from_fn(a.len(), b.len(), |i, j| rows[i][j])
}

/// The Gram matrix `K(Z, Z) + jitter·I`.
pub fn gram<K: Kernel>(k: &K, z: &[Point], jitter: f64, par: Parallelism) -> Mat<f64> {
    let mut m = cross(k, z, z, par);
    for i in 0..z.len() {
        m[(i, i)] += jitter;
    }
    m
}

/// Gradient of `Σ_ij W_ij K(a_i, b_j)` (jitter-free) with respect to the log-parameters
/// (added to `dtheta`) and to the points `a_i` (added to `da`, if given) and `b_j` (added to
/// `db`, if given). Rows are summed in index order, so the result does not depend on `par`.
#[allow(clippy::too_many_arguments)]
pub fn cross_grad<K: Kernel>(
    k: &K,
    a: &[Point],
    b: &[Point],
    w: MatRef<'_, f64>,
    dtheta: &mut [f64],
    mut da: Option<&mut [Point]>,
    mut db: Option<&mut [Point]>,
    par: Parallelism,
) {
    let np = k.params().len();
    let want_b = db.is_some();
    // Per row i: (Σ_j W_ij ∂k/∂θ, Σ_j W_ij ∂k/∂a_i, [W_ij ∂k/∂b_j]_j).
    let rows = map_rows(a.len(), par, |i| {
        let mut g = vec![0.0; np];
        let mut gi = [0.0; 3];
        let mut gb = if want_b {
            vec![[0.0; 3]; b.len()]
        } else {
            Vec::new()
        };
        let mut tmp = vec![0.0; np];
        let mut dx = [0.0; 3];
        for (j, bj) in b.iter().enumerate() {
            let wij = w[(i, j)];
            if wij == 0.0 {
                continue;
            }
            k.eval_grad(&a[i], bj, &mut tmp, &mut dx);
            for (gp, tp) in g.iter_mut().zip(&tmp) {
                *gp += wij * tp;
            }
            for d in 0..3 {
                gi[d] += wij * dx[d];
            }
            if want_b {
                for d in 0..3 {
                    gb[j][d] -= wij * dx[d];
                }
            }
        }
        (g, gi, gb)
    });
    for (i, (g, gi, gb)) in rows.into_iter().enumerate() {
        for (t, v) in dtheta.iter_mut().zip(&g) {
            *t += v;
        }
        if let Some(da) = da.as_deref_mut() {
            for d in 0..3 {
                da[i][d] += gi[d];
            }
        }
        if let Some(db) = db.as_deref_mut() {
            for (dbj, gbj) in db.iter_mut().zip(&gb) {
                for d in 0..3 {
                    dbj[d] += gbj[d];
                }
            }
        }
    }
}

/// Gradient of `Σ_ij W_ij [K(Z, Z) + jitter·I]_ij` with respect to the log-parameters
/// (added to `dtheta`) and to the points `z_i` (added to `dz`).
pub fn gram_grad<K: Kernel>(
    k: &K,
    z: &[Point],
    w: MatRef<'_, f64>,
    dtheta: &mut [f64],
    dz: &mut [Point],
    par: Parallelism,
) {
    // Stationarity: ∂k(z_j, z_i)/∂z_i = ∂k(z_i, z_j)/∂z_i, so z_i collects (W_ij + W_ji).
    let np = k.params().len();
    let rows = map_rows(z.len(), par, |i| {
        let mut g = vec![0.0; np];
        let mut gi = [0.0; 3];
        let mut tmp = vec![0.0; np];
        let mut dx = [0.0; 3];
        for (j, zj) in z.iter().enumerate() {
            let (wij, wji) = (w[(i, j)], w[(j, i)]);
            if wij == 0.0 && wji == 0.0 {
                continue;
            }
            k.eval_grad(&z[i], zj, &mut tmp, &mut dx);
            for (gp, tp) in g.iter_mut().zip(&tmp) {
                *gp += wij * tp;
            }
            for d in 0..3 {
                gi[d] += (wij + wji) * dx[d];
            }
        }
        (g, gi)
    });
    for (i, (g, gi)) in rows.into_iter().enumerate() {
        for (t, v) in dtheta.iter_mut().zip(&g) {
            *t += v;
        }
        for d in 0..3 {
            dz[i][d] += gi[d];
        }
    }
}

/// Gradient of `Σ_i w_i k(x_i, x_i)` with respect to the log-parameters (added to `dtheta`).
pub fn diag_grad<K: Kernel>(k: &K, w: &[f64], dtheta: &mut [f64]) {
    let mut tmp = vec![0.0; k.params().len()];
    k.diag_grad(&mut tmp);
    let s: f64 = w.iter().sum();
    for (t, v) in dtheta.iter_mut().zip(&tmp) {
        *t += s * v;
    }
}
