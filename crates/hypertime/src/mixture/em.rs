//! Expectation–maximisation for Gaussian mixtures with full covariances ([Krajník 2019] eq. 2;
//! Dempster, Laird & Rubin 1977), laid out like scikit-learn's `GaussianMixture` so that
//! [`super::fit_em_from`] follows its trajectory: every iteration is an E-step on the current
//! mixture (its mean log-likelihood is scikit-learn's `lower_bound_`) followed by an M-step,
//! and the run stops after the M-step of the first iteration whose E-step log-likelihood
//! changed by less than the tolerance.
//!
//! Numerics (module doc of [`super`]): responsibilities in the log domain (log-sum-exp), the
//! covariance update `Σ_c = Σ_i r_ic (x_i − μ_c)(x_i − μ_c)ᵀ / n_c + λI` centred on the new
//! mean (two passes, no `E[xxᵀ] − μμᵀ` cancellation), `n_c = Σ_i r_ic + 10ε` as scikit-learn,
//! every factor checked ([`linalg::checked_cholesky`]), empty components re-seeded.

use std::ops::Range;

use super::kmeans;
use super::linalg;
use super::rows::Rows;
use super::{EmConfig, EmFit, EmInit, GaussianMixture, NUMERICAL_RESTARTS};
use chronomap_core::rng::{Xoshiro256StarStar, derive_seed};

/// Purpose tag of the seeds of EM's initialisations ("EM init").
const TAG_EM: u64 = 0x0045_4d5f_696e_6974;

/// Lloyd iterations of the k-means that initialises EM ([`EmInit::KMeans`]).
const INIT_KMEANS_ITERATIONS: usize = 100;

/// A component whose responsibilities sum to at most this share of the total weight is empty
/// and is re-seeded.
const EMPTY_SHARE: f64 = 1e-12;

/// Variance floors of diagonal covariances, relative to each dimension's data variance.
const DIAGONAL_FLOOR: f64 = 1e-12;

/// How covariances are finished and factored.
#[derive(Clone, Copy, Debug)]
pub(super) enum Covariances<'a> {
    /// Full, positive definite (Cholesky succeeds).
    Full,
    /// Full, positive definite and well-conditioned ([`linalg::checked_cholesky`]).
    Checked,
    /// Diagonal, every variance at least its floor (one per dimension): never fails.
    Diagonal(&'a [f64]),
}

impl Covariances<'_> {
    fn is_diagonal(self) -> bool {
        matches!(self, Covariances::Diagonal(_))
    }

    /// Adds `reg` to the diagonal of the symmetric `cov` (lower triangle filled; the upper is
    /// mirrored here), applies the kind (diagonal: off-diagonals zeroed, variances floored),
    /// and returns the lower Cholesky factor, or `None` on a numerical failure.
    fn finish(self, cov: &mut [f64], d: usize, reg: f64) -> Option<Vec<f64>> {
        for a in 0..d {
            cov[a * d + a] += reg;
            for b in 0..a {
                cov[b * d + a] = cov[a * d + b];
            }
        }
        match self {
            Covariances::Full => linalg::cholesky(cov, d),
            Covariances::Checked => linalg::checked_cholesky(cov, d),
            Covariances::Diagonal(floors) => {
                let mut l = vec![0.0; d * d];
                for a in 0..d {
                    for b in 0..d {
                        if a != b {
                            cov[a * d + b] = 0.0;
                        }
                    }
                    let v = cov[a * d + a].max(floors[a]);
                    cov[a * d + a] = v;
                    l[a * d + a] = v.sqrt();
                }
                l.iter()
                    .all(|v| v.is_finite())
                    .then_some(l)
                    .filter(|l| (0..d).all(|a| l[a * d + a] > 0.0))
            }
        }
    }
}

/// Settings of one fit, derived from the config and the data.
pub(super) struct Settings {
    max_iterations: usize,
    tolerance: f64,
    /// Absolute ridge added to every covariance diagonal.
    reg: f64,
    /// Variance floors of diagonal covariances.
    floors: Vec<f64>,
    /// Weighted covariance of the data (`dim × dim`).
    data_covariance: Vec<f64>,
}

impl Settings {
    pub(super) fn new(rows: &Rows<'_>, config: &EmConfig) -> Self {
        let d = rows.dim;
        let (_, data_covariance) = rows.mean_covariance();
        let variances: Vec<f64> = (0..d).map(|a| data_covariance[a * d + a]).collect();
        let mean_variance = variances.iter().sum::<f64>() / d as f64;
        let scale = if mean_variance > 0.0 && mean_variance.is_finite() {
            mean_variance
        } else {
            1.0
        };
        let reg = if config.relative_regularization {
            config.regularization * scale
        } else {
            config.regularization
        };
        let floors = variances
            .iter()
            .map(|&v| DIAGONAL_FLOOR * if v > 0.0 && v.is_finite() { v } else { scale })
            .collect();
        Settings {
            max_iterations: config.max_iterations,
            tolerance: config.tolerance,
            reg,
            floors,
            data_covariance,
        }
    }
}

/// Per-row buffers of EM, allocated once per fit.
pub(super) struct Workspace {
    /// `n × k` responsibilities (times nothing: the row weight is applied in the sums).
    resp: Vec<f64>,
    /// `n` values `ln p(x_i)`.
    log_p: Vec<f64>,
}

impl Workspace {
    pub(super) fn new(n: usize, k: usize) -> Self {
        Workspace {
            resp: vec![0.0; n * k],
            log_p: vec![0.0; n],
        }
    }
}

/// What an E-step gives the M-step.
struct EStats {
    /// Mean log-likelihood per unit weight.
    ll: f64,
    /// `Σ_i w_i r_ic`.
    nk: Vec<f64>,
    /// `Σ_i w_i r_ic x_i` (`k × dim`).
    sx: Vec<f64>,
}

/// `$f(d, args…)` with `d` a literal for `d <= 14` (the dimensions of hypertime), so that the
/// `#[inline(always)]` row loops of `$f` are compiled with fixed trip counts and unrolled;
/// the same arithmetic in the same order either way.
macro_rules! specialise {
    ($d:expr, $f:ident($($arg:expr),* $(,)?)) => {
        match $d {
            1 => $f(1, $($arg),*),
            2 => $f(2, $($arg),*),
            3 => $f(3, $($arg),*),
            4 => $f(4, $($arg),*),
            5 => $f(5, $($arg),*),
            6 => $f(6, $($arg),*),
            7 => $f(7, $($arg),*),
            8 => $f(8, $($arg),*),
            9 => $f(9, $($arg),*),
            10 => $f(10, $($arg),*),
            11 => $f(11, $($arg),*),
            12 => $f(12, $($arg),*),
            13 => $f(13, $($arg),*),
            14 => $f(14, $($arg),*),
            d => $f(d, $($arg),*),
        }
    };
}

/// The per-row kernel of the E-step: for every component the mean, the inverse `P = L⁻¹` of
/// its Cholesky factor (lower triangular, rows packed), and `ln w_c − ½ ln det(2πΣ_c)`, so
/// that `ln w_c N(x; μ_c, Σ_c) = log_normaliser − ½‖P(x − μ_c)‖²` (scikit-learn's
/// `precisions_cholesky_`, transposed). A product instead of a substitution: the rows of `P`
/// are independent, where each step of a substitution waits for the previous one.
pub(super) struct Kernel<'a> {
    mix: &'a GaussianMixture,
    /// `k × d(d+1)/2`.
    precision: Vec<f64>,
}

impl<'a> Kernel<'a> {
    pub(super) fn new(mix: &'a GaussianMixture) -> Self {
        let (d, k) = (mix.dim, mix.components());
        let (d2, packed) = (d * d, d * (d + 1) / 2);
        let mut precision = vec![0.0; k * packed];
        let mut column = vec![0.0; d];
        for c in 0..k {
            let l = &mix.cholesky[c * d2..(c + 1) * d2];
            let p = &mut precision[c * packed..(c + 1) * packed];
            for j in 0..d {
                column.fill(0.0);
                column[j] = 1.0;
                linalg::forward_solve(l, d, &mut column);
                for i in j..d {
                    p[i * (i + 1) / 2 + j] = column[i];
                }
            }
        }
        Kernel { mix, precision }
    }

    /// `ln w_c N(x; μ_c, Σ_c)` for every component into `out`; `diff` (length `d`, the
    /// dimension) is scratch.
    #[inline(always)]
    fn log_densities(&self, d: usize, x: &[f64], out: &mut [f64], diff: &mut [f64]) {
        let packed = d * (d + 1) / 2;
        for (c, o) in out.iter_mut().enumerate() {
            let mean = &self.mix.means[c * d..(c + 1) * d];
            for ((e, xj), mj) in diff.iter_mut().zip(x).zip(mean) {
                *e = xj - mj;
            }
            let p = &self.precision[c * packed..(c + 1) * packed];
            let mut q = 0.0;
            for i in 0..d {
                let row = &p[i * (i + 1) / 2..][..=i];
                let mut z = 0.0;
                for (a, b) in row.iter().zip(&diff[..=i]) {
                    z += a * b;
                }
                q += z * z;
            }
            *o = self.mix.log_normalisers[c] - 0.5 * q;
        }
    }
}

/// Sums in chunk order, starting from `+0.0` (the same order everywhere, so that a mixture's
/// [`GaussianMixture::mean_log_likelihood`] equals the value EM computed, bit for bit).
fn ordered_sum(parts: impl IntoIterator<Item = f64>) -> f64 {
    parts.into_iter().fold(0.0, |a, b| a + b)
}

/// `Σ_i w_i ln p(x_i) / Σ_i w_i`.
pub(super) fn mean_log_likelihood(rows: &Rows<'_>, mix: &GaussianMixture) -> f64 {
    let kernel = Kernel::new(mix);
    let parts = rows.map_chunks(|start, len| {
        specialise!(
            rows.dim,
            log_likelihood_rows(rows, &kernel, start..start + len)
        )
    });
    ordered_sum(parts) / rows.total
}

/// `Σ w_i ln p(x_i)` over the rows `chunk`.
#[inline(always)]
fn log_likelihood_rows(d: usize, rows: &Rows<'_>, kernel: &Kernel<'_>, chunk: Range<usize>) -> f64 {
    let (mut lp, mut z) = (vec![0.0; kernel.mix.components()], vec![0.0; d]);
    let mut sum = 0.0;
    for i in chunk {
        let w = rows.weight(i);
        if w == 0.0 {
            continue;
        }
        kernel.log_densities(d, rows.row(i), &mut lp, &mut z);
        sum += w * linalg::log_sum_exp(&lp);
    }
    sum
}

/// The E-step: responsibilities `r_ic = exp(ln w_c N_c(x_i) − ln p(x_i))` into `ws`, and the
/// first-order sums of the M-step.
fn e_step(rows: &Rows<'_>, mix: &GaussianMixture, ws: &mut Workspace) -> EStats {
    let (k, d) = (mix.components(), rows.dim);
    let kernel = Kernel::new(mix);
    let parts = rows.map_chunks_mut(
        &mut ws.resp,
        k,
        &mut ws.log_p,
        1,
        |start, len, resp, log_p| specialise!(d, e_rows(rows, &kernel, start, len, resp, log_p)),
    );
    let mut nk = vec![0.0; k];
    let mut sx = vec![0.0; k * d];
    for (_, pn, ps) in &parts {
        nk.iter_mut().zip(pn).for_each(|(a, b)| *a += b);
        sx.iter_mut().zip(ps).for_each(|(a, b)| *a += b);
    }
    let ll = ordered_sum(parts.iter().map(|p| p.0)) / rows.total;
    EStats { ll, nk, sx }
}

/// The E-step over rows `start..start + len` (`resp` and `log_p` their slices): the partial
/// `(Σ w ln p, Σ w r_c, Σ w r_c x)`.
#[inline(always)]
fn e_rows(
    d: usize,
    rows: &Rows<'_>,
    kernel: &Kernel<'_>,
    start: usize,
    len: usize,
    resp: &mut [f64],
    log_p: &mut [f64],
) -> (f64, Vec<f64>, Vec<f64>) {
    let k = kernel.mix.components();
    let mut z = vec![0.0; d];
    let (mut ll, mut nk, mut sx) = (0.0, vec![0.0; k], vec![0.0; k * d]);
    for r in 0..len {
        let i = start + r;
        let g = &mut resp[r * k..(r + 1) * k];
        let w = rows.weight(i);
        if w == 0.0 {
            g.fill(0.0);
            log_p[r] = 0.0;
            continue;
        }
        let x = &rows.row(i)[..d];
        kernel.log_densities(d, x, g, &mut z);
        let lse = linalg::log_sum_exp_normalise(g);
        log_p[r] = lse;
        if !lse.is_finite() {
            g.fill(1.0 / k as f64);
        }
        ll += w * lse;
        for c in 0..k {
            let rc = w * g[c];
            if rc == 0.0 {
                continue;
            }
            for (s, xj) in sx[c * d..(c + 1) * d].iter_mut().zip(x) {
                *s += rc * xj;
            }
            nk[c] += rc;
        }
    }
    (ll, nk, sx)
}

/// The scatter `Σ w r_c (x − μ_c)(x − μ_c)ᵀ` (lower triangles; diagonals only if `diagonal`)
/// of rows `start..start + len`, components with `skip[c]` left out.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn scatter_rows(
    d: usize,
    rows: &Rows<'_>,
    resp: &[f64],
    means: &[f64],
    skip: &[bool],
    diagonal: bool,
    start: usize,
    len: usize,
) -> Vec<f64> {
    let (k, d2) = (skip.len(), d * d);
    let mut s = vec![0.0; k * d2];
    let mut diff = vec![0.0; d];
    for i in start..start + len {
        let w = rows.weight(i);
        if w == 0.0 {
            continue;
        }
        let (x, g) = (&rows.row(i)[..d], &resp[i * k..(i + 1) * k]);
        for c in (0..k).filter(|&c| !skip[c]) {
            let r = w * g[c];
            if r == 0.0 {
                continue;
            }
            for ((e, xj), mj) in diff.iter_mut().zip(x).zip(&means[c * d..(c + 1) * d]) {
                *e = xj - mj;
            }
            let sc = &mut s[c * d2..(c + 1) * d2];
            for a in 0..d {
                let ra = r * diff[a];
                if diagonal {
                    sc[a * d + a] += ra * diff[a];
                } else {
                    for b in 0..=a {
                        sc[a * d + b] += ra * diff[b];
                    }
                }
            }
        }
    }
    s
}

/// The M-step from the responsibilities in `ws`; `None` on a numerical failure.
fn m_step(
    rows: &Rows<'_>,
    ws: &Workspace,
    stats: &EStats,
    settings: &Settings,
    kind: Covariances<'_>,
) -> Option<GaussianMixture> {
    let (k, d, d2) = (stats.nk.len(), rows.dim, rows.dim * rows.dim);
    let empty: Vec<bool> = stats
        .nk
        .iter()
        .map(|&n| n.is_nan() || n <= EMPTY_SHARE * rows.total)
        .collect();
    let mut nk: Vec<f64> = stats.nk.iter().map(|n| n + 10.0 * f64::EPSILON).collect();
    let mut means: Vec<f64> = (0..k * d).map(|i| stats.sx[i] / nk[i / d]).collect();
    // Empty components restart at the worst-explained rows (distinct ones).
    let mut reseeded: Vec<usize> = Vec::new();
    for c in (0..k).filter(|&c| empty[c]) {
        let worst = (0..rows.n)
            .filter(|&i| rows.weight(i) > 0.0)
            .filter(|&i| reseeded.iter().all(|&j| rows.row(j) != rows.row(i)))
            .min_by(|&a, &b| ws.log_p[a].total_cmp(&ws.log_p[b]).then(a.cmp(&b)));
        if let Some(i) = worst {
            means[c * d..(c + 1) * d].copy_from_slice(rows.row(i));
            nk[c] = rows.weight(i);
            reseeded.push(i);
        }
    }
    let diagonal = kind.is_diagonal();
    let parts = rows.map_chunks(|start, len| {
        specialise!(
            d,
            scatter_rows(rows, &ws.resp, &means, &empty, diagonal, start, len)
        )
    });
    let mut covariances = vec![0.0; k * d2];
    for p in &parts {
        covariances.iter_mut().zip(p).for_each(|(a, b)| *a += b);
    }
    let mut cholesky = Vec::with_capacity(k * d2);
    for c in 0..k {
        let cov = &mut covariances[c * d2..(c + 1) * d2];
        if empty[c] {
            // A fresh component: a spherical-ish share of the data's spread.
            cov.fill(0.0);
            for a in 0..d {
                cov[a * d + a] =
                    (settings.data_covariance[a * d + a] / k as f64).max(settings.floors[a]);
            }
        } else {
            for a in 0..d {
                for b in 0..=a {
                    cov[a * d + b] /= nk[c];
                }
            }
        }
        cholesky.extend(kind.finish(cov, d, settings.reg)?);
    }
    let total: f64 = nk.iter().sum();
    let weights: Vec<f64> = nk.iter().map(|n| n / total).collect();
    if !means.iter().chain(&weights).all(|v| v.is_finite()) {
        return None;
    }
    Some(GaussianMixture::from_factors(
        d,
        weights,
        means,
        covariances,
        cholesky,
    ))
}

/// What to do when a full-covariance M-step fails.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum OnFailure {
    /// Give up this start (the caller restarts from a new initialisation).
    Abort,
    /// Go on with diagonal covariances (deterministic: [`super::fit_em_from`]).
    Diagonalise,
}

/// One EM run.
struct Run {
    mixture: GaussianMixture,
    log_likelihood: f64,
    trace: Vec<f64>,
    iterations: usize,
    converged: bool,
    diagonal: bool,
}

/// EM from `initial` until the tolerance or the iteration limit. `Err` only with
/// [`OnFailure::Abort`] and full covariances.
fn run<'s>(
    rows: &Rows<'_>,
    initial: GaussianMixture,
    settings: &'s Settings,
    mut kind: Covariances<'s>,
    on_failure: OnFailure,
    ws: &mut Workspace,
) -> Result<Run, ()> {
    let mut diagonal = kind.is_diagonal();
    let mut mixture = initial;
    let mut stats = e_step(rows, &mixture, ws);
    let abort = |kind: Covariances<'_>| on_failure == OnFailure::Abort && !kind.is_diagonal();
    if !stats.ll.is_finite() && abort(kind) {
        return Err(());
    }
    let mut trace = Vec::new();
    let (mut iterations, mut converged) = (0, false);
    // scikit-learn's `prev_lower_bound` and `lower_bound` of the coming iteration.
    let (mut previous, mut current) = (f64::NEG_INFINITY, stats.ll);
    for iteration in 1..=settings.max_iterations {
        if !stats.ll.is_finite() {
            break;
        }
        let next = match m_step(rows, ws, &stats, settings, kind) {
            Some(next) => next,
            None if abort(kind) => return Err(()),
            None if kind.is_diagonal() => break,
            None => {
                kind = Covariances::Diagonal(&settings.floors);
                match m_step(rows, ws, &stats, settings, kind) {
                    Some(next) => next,
                    None => break,
                }
            }
        };
        let next_stats = e_step(rows, &next, ws);
        if !next_stats.ll.is_finite() {
            if abort(kind) {
                return Err(());
            }
            // Keep the last finite state (its responsibilities are lost, but not needed).
            break;
        }
        mixture = next;
        stats = next_stats;
        diagonal |= kind.is_diagonal();
        trace.push(stats.ll);
        iterations = iteration;
        if (current - previous).abs() < settings.tolerance {
            converged = true;
            break;
        }
        previous = current;
        current = stats.ll;
    }
    Ok(Run {
        mixture,
        log_likelihood: stats.ll,
        trace,
        iterations,
        converged,
        diagonal,
    })
}

/// A mixture of the hard clusters `labels` (weighted shares, means, covariances + `reg`),
/// empty clusters dropped; `Err(c)` if the factor of output component `c` fails.
pub(super) fn cluster_mixture(
    rows: &Rows<'_>,
    labels: &[usize],
    k: usize,
    reg: f64,
    kind: Covariances<'_>,
) -> Result<GaussianMixture, usize> {
    let (d, d2) = (rows.dim, rows.dim * rows.dim);
    let mut wk = vec![0.0; k];
    let mut sx = vec![0.0; k * d];
    for (i, &c) in labels.iter().enumerate() {
        let w = rows.weight(i);
        if w == 0.0 {
            continue;
        }
        wk[c] += w;
        for (s, x) in sx[c * d..(c + 1) * d].iter_mut().zip(rows.row(i)) {
            *s += w * x;
        }
    }
    let means: Vec<f64> = (0..k * d).map(|i| sx[i] / wk[i / d]).collect();
    let mut scatter = vec![0.0; k * d2];
    let mut diff = vec![0.0; d];
    for (i, &c) in labels.iter().enumerate() {
        let w = rows.weight(i);
        if w == 0.0 {
            continue;
        }
        for ((e, x), m) in diff.iter_mut().zip(rows.row(i)).zip(&means[c * d..]) {
            *e = x - m;
        }
        let s = &mut scatter[c * d2..(c + 1) * d2];
        for a in 0..d {
            let wa = w * diff[a];
            for b in 0..=a {
                s[a * d + b] += wa * diff[b];
            }
        }
    }
    let kept: Vec<usize> = (0..k).filter(|&c| wk[c] > 0.0).collect();
    let total: f64 = kept.iter().map(|&c| wk[c]).sum();
    let mut weights = Vec::with_capacity(kept.len());
    let mut out_means = Vec::with_capacity(kept.len() * d);
    let mut covariances = Vec::with_capacity(kept.len() * d2);
    let mut cholesky = Vec::with_capacity(kept.len() * d2);
    for (out, &c) in kept.iter().enumerate() {
        weights.push(wk[c] / total);
        out_means.extend_from_slice(&means[c * d..(c + 1) * d]);
        let mut cov: Vec<f64> = scatter[c * d2..(c + 1) * d2]
            .iter()
            .map(|s| s / wk[c])
            .collect();
        cholesky.extend(kind.finish(&mut cov, d, reg).ok_or(out)?);
        covariances.extend(cov);
    }
    Ok(GaussianMixture::from_factors(
        d,
        weights,
        out_means,
        covariances,
        cholesky,
    ))
}

/// A seeded initial mixture of `k` components; `None` on a numerical failure.
fn initialise(
    rows: &Rows<'_>,
    k: usize,
    init: EmInit,
    rng: &mut Xoshiro256StarStar,
    settings: &Settings,
    kind: Covariances<'_>,
) -> Option<GaussianMixture> {
    let d = rows.dim;
    let centres = kmeans::plus_plus(rows, k, rng);
    match init {
        EmInit::KMeans => {
            let fit = kmeans::lloyd(rows, centres, INIT_KMEANS_ITERATIONS, None);
            let mixture = cluster_mixture(rows, &fit.labels, k, settings.reg, kind).ok()?;
            (mixture.components() == k).then_some(mixture)
        }
        EmInit::KMeansPlusPlus => {
            let mut covariances = Vec::with_capacity(k * d * d);
            let mut cholesky = Vec::with_capacity(k * d * d);
            for _ in 0..k {
                let mut cov = settings.data_covariance.clone();
                cholesky.extend(kind.finish(&mut cov, d, settings.reg)?);
                covariances.extend(cov);
            }
            Some(GaussianMixture::from_factors(
                d,
                vec![1.0 / k as f64; k],
                centres,
                covariances,
                cholesky,
            ))
        }
    }
}

/// k-means++ centres, equal weights and diagonal covariances of the data's variances (its
/// mean variance where a variance is zero or not finite): finite and positive definite by
/// construction.
fn fallback_mixture(
    rows: &Rows<'_>,
    k: usize,
    rng: &mut Xoshiro256StarStar,
    settings: &Settings,
) -> GaussianMixture {
    let d = rows.dim;
    let centres = kmeans::plus_plus(rows, k, rng);
    let mut covariances = vec![0.0; k * d * d];
    let mut cholesky = vec![0.0; k * d * d];
    for c in 0..k {
        for a in 0..d {
            let v = settings.floors[a] / DIAGONAL_FLOOR;
            covariances[c * d * d + a * d + a] = v;
            cholesky[c * d * d + a * d + a] = v.sqrt();
        }
    }
    GaussianMixture::from_factors(d, vec![1.0 / k as f64; k], centres, covariances, cholesky)
}

/// [`super::fit_em`] on checked rows.
pub(super) fn fit(rows: &Rows<'_>, config: &EmConfig) -> EmFit {
    let k = config.components;
    let settings = Settings::new(rows, config);
    let mut ws = Workspace::new(rows.n, k);
    let mut best: Option<Run> = None;
    let mut restarts = 0;
    for start in 0..config.starts {
        let mut failures = 0;
        let run = loop {
            let seed = derive_seed(config.seed, TAG_EM, start as u64, failures as u64);
            let mut rng = Xoshiro256StarStar::seed_from_u64(seed);
            let kind = if failures < NUMERICAL_RESTARTS {
                Covariances::Checked
            } else {
                Covariances::Diagonal(&settings.floors)
            };
            let initial = if failures <= NUMERICAL_RESTARTS {
                initialise(rows, k, config.init, &mut rng, &settings, kind)
            } else {
                // Even diagonal k-means clusters failed (only with data whose squares
                // overflow): a mixture that cannot fail.
                Some(fallback_mixture(rows, k, &mut rng, &settings))
            };
            let attempt = initial
                .ok_or(())
                .and_then(|initial| run(rows, initial, &settings, kind, OnFailure::Abort, &mut ws));
            match attempt {
                Ok(run) => break run,
                Err(()) => {
                    failures += 1;
                    restarts += 1;
                }
            }
        };
        if best
            .as_ref()
            .is_none_or(|b| run.log_likelihood > b.log_likelihood)
        {
            best = Some(run);
        }
    }
    let best = best.expect("at least one start");
    EmFit {
        mixture: best.mixture,
        log_likelihood: best.log_likelihood,
        trace: best.trace,
        iterations: best.iterations,
        converged: best.converged,
        numerical_restarts: restarts,
        diagonal: best.diagonal,
    }
}

/// [`super::fit_em_from`] on checked rows.
pub(super) fn fit_from(rows: &Rows<'_>, initial: &GaussianMixture, config: &EmConfig) -> EmFit {
    let settings = Settings::new(rows, config);
    let mut ws = Workspace::new(rows.n, initial.components());
    let run = run(
        rows,
        initial.clone(),
        &settings,
        Covariances::Checked,
        OnFailure::Diagonalise,
        &mut ws,
    )
    .expect("a run that diagonalises on failure does not fail");
    EmFit {
        mixture: run.mixture,
        log_likelihood: run.log_likelihood,
        trace: run.trace,
        iterations: run.iterations,
        converged: run.converged,
        numerical_restarts: 0,
        diagonal: run.diagonal,
    }
}
