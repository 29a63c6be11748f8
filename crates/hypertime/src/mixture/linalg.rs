//! Small dense linear algebra for the mixtures: Cholesky factors and the conditioning check
//! through `faer` (always sequential, so results never depend on a thread pool), and the
//! per-row kernels (forward substitution with a stored factor) as plain loops.

use faer::diag::Diag;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::evd::{ComputeEigenvectors, self_adjoint_evd, self_adjoint_evd_scratch};
use faer::{Mat, MatRef, Par};

/// Smallest accepted ratio of the smallest to the largest eigenvalue of a fitted covariance
/// (module doc: "smallest/largest eigenvalue below `1e-12`").
pub(super) const MIN_CONDITION: f64 = 1e-12;

/// The lower Cholesky factor `L` (`L·Lᵀ = a`) of the symmetric `d × d` row-major matrix `a`
/// (only its lower triangle is read), row-major with a zero upper triangle; `None` if `a` is
/// not numerically positive definite or the factor is not finite.
pub(super) fn cholesky(a: &[f64], d: usize) -> Option<Vec<f64>> {
    debug_assert_eq!(a.len(), d * d);
    let mut m = Mat::<f64>::zeros(d, d);
    for i in 0..d {
        for j in 0..=i {
            m[(i, j)] = a[i * d + j];
        }
    }
    let par = Par::Seq;
    let mut mem = MemBuffer::new(cholesky_in_place_scratch::<f64>(d, par, Default::default()));
    let stack = MemStack::new(&mut mem);
    cholesky_in_place(
        m.as_mut(),
        Default::default(),
        par,
        stack,
        Default::default(),
    )
    .ok()?;
    let mut l = vec![0.0; d * d];
    for i in 0..d {
        for j in 0..=i {
            l[i * d + j] = m[(i, j)];
        }
        if !(l[i * d + i] > 0.0 && l[i * d + i].is_finite()) {
            return None;
        }
    }
    l.iter().all(|v| v.is_finite()).then_some(l)
}

/// The eigenvalues of the symmetric `d × d` row-major matrix `a` (lower triangle read), in
/// non-decreasing order; `None` if the decomposition fails.
pub(super) fn symmetric_eigenvalues(a: &[f64], d: usize) -> Option<Vec<f64>> {
    let m = MatRef::from_row_major_slice(a, d, d);
    let par = Par::Seq;
    let mut s = Diag::<f64>::zeros(d);
    let mut mem = MemBuffer::new(self_adjoint_evd_scratch::<f64>(
        d,
        ComputeEigenvectors::No,
        par,
        Default::default(),
    ));
    self_adjoint_evd(
        m,
        s.as_mut(),
        None,
        par,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .ok()?;
    let values: Vec<f64> = s.column_vector().iter().copied().collect();
    values.iter().all(|v| v.is_finite()).then_some(values)
}

/// The Cholesky factor of a covariance fitted by EM, or `None` when the covariance is not
/// positive definite or is ill-conditioned (smallest/largest eigenvalue below
/// [`MIN_CONDITION`]) — the numerical failure of [Krajník 2019] §IV, "detected through eigenvalue
/// analysis of the covariance matrices".
pub(super) fn checked_cholesky(a: &[f64], d: usize) -> Option<Vec<f64>> {
    let l = cholesky(a, d)?;
    if d > 1 {
        let eig = symmetric_eigenvalues(a, d)?;
        let (lo, hi) = (eig[0], eig[d - 1]);
        if !(lo > 0.0 && lo >= MIN_CONDITION * hi) {
            return None;
        }
    }
    Some(l)
}

/// The Cholesky factor of a symmetric matrix that is positive definite in exact arithmetic
/// (a marginal or a Schur complement of a positive definite matrix) but may have lost it to
/// rounding: a tiny growing ridge is added until the factor exists. `None` only if `a` is far
/// from positive definite or not finite.
pub(super) fn cholesky_with_jitter(a: &mut [f64], d: usize) -> Option<Vec<f64>> {
    if let Some(l) = cholesky(a, d) {
        return Some(l);
    }
    let scale = (0..d).map(|i| a[i * d + i].abs()).fold(0.0, f64::max);
    let scale = if scale > 0.0 && scale.is_finite() {
        scale
    } else {
        1.0
    };
    let mut jitter = scale * f64::EPSILON;
    let mut added = 0.0;
    for _ in 0..12 {
        for i in 0..d {
            a[i * d + i] += jitter - added;
        }
        added = jitter;
        if let Some(l) = cholesky(a, d) {
            return Some(l);
        }
        jitter *= 10.0;
    }
    None
}

/// `Σ ln L_ii`: half the log-determinant of `L·Lᵀ`.
pub(super) fn half_log_det(l: &[f64], d: usize) -> f64 {
    (0..d).map(|i| l[i * d + i].ln()).sum()
}

/// `‖L⁻¹(x − μ)‖²` by forward substitution; `z` (length `d`) is scratch.
#[inline]
pub(super) fn mahalanobis2(l: &[f64], mean: &[f64], x: &[f64], z: &mut [f64]) -> f64 {
    let d = mean.len();
    let mut q = 0.0;
    for i in 0..d {
        let row = &l[i * d..i * d + i];
        let mut s = x[i] - mean[i];
        for (lij, zj) in row.iter().zip(&z[..i]) {
            s -= lij * zj;
        }
        let zi = s / l[i * d + i];
        z[i] = zi;
        q += zi * zi;
    }
    q
}

/// Solves `L·y = b` in place (`L` lower triangular, row-major, `d × d`).
pub(super) fn forward_solve(l: &[f64], d: usize, b: &mut [f64]) {
    for i in 0..d {
        let mut s = b[i];
        for j in 0..i {
            s -= l[i * d + j] * b[j];
        }
        b[i] = s / l[i * d + i];
    }
}

/// `ln Σ exp(v)`, stable; `−∞` if every value is `−∞`.
#[inline]
pub(super) fn log_sum_exp(v: &[f64]) -> f64 {
    let m = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !m.is_finite() {
        return m;
    }
    let mut s = 0.0;
    for &a in v {
        s += (a - m).exp();
    }
    m + s.ln()
}

/// [`log_sum_exp`] (the same bits), replacing `v` by the normalised `exp(v_c − ln Σ exp(v))`
/// (the responsibilities), computed as `exp(v_c − max) / Σ exp(v − max)`: one exponential
/// per value. If the sum is not finite, `v` is left as it was.
#[inline]
pub(super) fn log_sum_exp_normalise(v: &mut [f64]) -> f64 {
    let m = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !m.is_finite() {
        return m;
    }
    let mut s = 0.0;
    for a in v.iter_mut() {
        *a = (*a - m).exp();
        s += *a;
    }
    v.iter_mut().for_each(|a| *a /= s);
    m + s.ln()
}
