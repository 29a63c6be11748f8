//! Gaussian mixtures fitted by expectation–maximisation, and k-means: the clustering stage of
//! Warped Hypertime ([Krajník 2019] §III-C eq. 2, §IV: HyT-EM and HyT-KM).
//!
//! [Krajník 2019] §IV reports that clustering the sparse hypertime space is the hard part: EM "sometimes
//! exhibited numerical instabilities", detected "through eigenvalue analysis of the covariance
//! matrices", fixed by restarts or diagonal covariances. Here EM is made robust by construction:
//! responsibilities in the log domain (log-sum-exp), a ridge `regularization` added to every
//! covariance diagonal (as scikit-learn's `reg_covar`), Cholesky factors checked on every
//! M-step (a failed or ill-conditioned factor — smallest/largest eigenvalue below `1e-12` —
//! restarts from a new seeded initialisation, and after [`NUMERICAL_RESTARTS`] failures falls
//! back to diagonal covariances), empty components re-seeded at the worst-explained point.
//!
//! Every EM iteration is the standard pair (Dempster, Laird & Rubin 1977) for [Krajník 2019] eq. 2,
//! `p(x) = Σ_c w_c N(x; μ_c, Σ_c)`: the E-step `r_ic = w_c N(x_i; μ_c, Σ_c) / p(x_i)`, the
//! M-step `n_c = Σ_i v_i r_ic`, `w_c = n_c / Σ n`, `μ_c = Σ_i v_i r_ic x_i / n_c`,
//! `Σ_c = Σ_i v_i r_ic (x_i − μ_c)(x_i − μ_c)ᵀ / n_c + λI` (`v_i` the row weights, `λ` the
//! ridge), in the order and with the conventions of scikit-learn's `GaussianMixture`, whose
//! trajectory [`fit_em_from`] reproduces (to ~1e-14 in `tests/cli/sklearn_gmm.rs`). With the ridge
//! the M-step maximises a penalised expected log-likelihood, so the likelihood is
//! non-decreasing only up to terms of the order of `λ` (invisible at the default relative
//! `1e-6`; about 1e-6 with an absolute `λ = 1e-4` on a 0/1 column, as in scikit-learn).
//!
//! The per-row loops run over fixed chunks of rows whose partial sums are added in chunk
//! order, on the rayon pool when there are several: the bits do not depend on the number of
//! threads.
//!
//! Data are `n × dim` row-major slices with optional non-negative per-row weights (a weight
//! `w` counts as `w` identical rows: integer weights give exactly the result of duplicated
//! rows). All randomness comes from the seeded [`chronomap_core::rng::Xoshiro256StarStar`]: the same
//! data, config and seed give bit-identical results.

use chronomap_core::Parallelism;
use serde::{Deserialize, Serialize};
use thiserror::Error;

mod em;
mod kmeans;
mod linalg;
mod rows;
#[cfg(test)]
mod tests;

use rows::Rows;

/// Numerical failures (a covariance that is not positive definite or is ill-conditioned) after
/// which one start of [`fit_em`] stops restarting from new seeded initialisations and fits
/// diagonal covariances instead.
pub const NUMERICAL_RESTARTS: usize = 3;

/// What went wrong.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum MixtureError {
    /// No rows (or all weights zero).
    #[error("no data to fit")]
    EmptyData,
    /// `data.len()` is not a multiple of `dim`, or weights/points disagree in length.
    #[error("dimension mismatch: {0}")]
    DimensionMismatch(String),
    /// A coordinate is NaN or infinite.
    #[error("row {row}, coordinate {coordinate}: {value} is not finite")]
    NonFinite {
        /// 0-based row.
        row: usize,
        /// 0-based coordinate.
        coordinate: usize,
        /// The value.
        value: f64,
    },
    /// A weight is negative or not finite.
    #[error("row {row}: weight {weight} is not a finite number >= 0")]
    InvalidWeight {
        /// 0-based row.
        row: usize,
        /// The weight.
        weight: f64,
    },
    /// Fewer distinct rows than components.
    #[error("{points} distinct points cannot make {components} components")]
    TooFewPoints {
        /// Distinct rows with positive weight.
        points: usize,
        /// Components asked for.
        components: usize,
    },
    /// A covariance given to [`GaussianMixture::new`] is not symmetric positive definite.
    #[error("component {component}: the covariance is not symmetric positive definite")]
    NotPositiveDefinite {
        /// 0-based component.
        component: usize,
    },
    /// A configuration value out of range.
    #[error("invalid configuration: {0}")]
    InvalidConfig(String),
}

/// A mixture of `k` multivariate normal densities in `dim` dimensions ([Krajník 2019] eq. 2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GaussianMixture {
    dim: usize,
    /// `k` weights summing to 1.
    weights: Vec<f64>,
    /// `k × dim` means, row-major.
    means: Vec<f64>,
    /// `k × dim × dim` covariances, row-major.
    covariances: Vec<f64>,
    /// `k × dim × dim` lower Cholesky factors of the covariances (derived, kept in sync).
    cholesky: Vec<f64>,
    /// `k` values `ln w_c − ½·(dim·ln 2π + ln det Σ_c)` (derived).
    log_normalisers: Vec<f64>,
}

impl GaussianMixture {
    /// A mixture from weights (normalised to sum 1), means (`k × dim`) and covariances
    /// (`k × dim × dim`).
    ///
    /// # Errors
    /// [`MixtureError::DimensionMismatch`], [`MixtureError::NonFinite`], negative or all-zero
    /// weights ([`MixtureError::InvalidConfig`]), [`MixtureError::NotPositiveDefinite`].
    pub fn new(
        dim: usize,
        weights: Vec<f64>,
        means: Vec<f64>,
        covariances: Vec<f64>,
    ) -> Result<Self, MixtureError> {
        if dim == 0 {
            return Err(MixtureError::DimensionMismatch(
                "dim must be at least 1".into(),
            ));
        }
        let k = weights.len();
        if k == 0 {
            return Err(MixtureError::InvalidConfig(
                "a mixture needs a component".into(),
            ));
        }
        let d2 = dim * dim;
        if means.len() != k * dim || covariances.len() != k * d2 {
            return Err(MixtureError::DimensionMismatch(format!(
                "{k} weights, {} mean values and {} covariance values in {dim} dimensions",
                means.len(),
                covariances.len()
            )));
        }
        for (values, stride) in [(&means, dim), (&covariances, d2)] {
            if let Some(i) = values.iter().position(|v| !v.is_finite()) {
                return Err(MixtureError::NonFinite {
                    row: i / stride,
                    coordinate: i % stride,
                    value: values[i],
                });
            }
        }
        if let Some(w) = weights.iter().find(|w| !(w.is_finite() && **w >= 0.0)) {
            return Err(MixtureError::InvalidConfig(format!(
                "weight {w} is not a finite number >= 0"
            )));
        }
        let sum: f64 = weights.iter().sum();
        if !(sum > 0.0 && sum.is_finite()) {
            return Err(MixtureError::InvalidConfig(format!(
                "the weights sum to {sum}"
            )));
        }
        let weights: Vec<f64> = weights.iter().map(|w| w / sum).collect();
        let mut covariances = covariances;
        let mut cholesky = Vec::with_capacity(k * d2);
        for c in 0..k {
            let cov = &mut covariances[c * d2..(c + 1) * d2];
            for a in 0..dim {
                for b in 0..a {
                    let (x, y) = (cov[a * dim + b], cov[b * dim + a]);
                    let scale = x
                        .abs()
                        .max(y.abs())
                        .max((cov[a * dim + a] * cov[b * dim + b]).abs().sqrt());
                    if (x - y).abs() > 1e-10 * scale {
                        return Err(MixtureError::NotPositiveDefinite { component: c });
                    }
                    let m = 0.5 * (x + y);
                    cov[a * dim + b] = m;
                    cov[b * dim + a] = m;
                }
            }
            let l = linalg::cholesky(cov, dim)
                .ok_or(MixtureError::NotPositiveDefinite { component: c })?;
            cholesky.extend_from_slice(&l);
        }
        Ok(GaussianMixture::from_factors(
            dim,
            weights,
            means,
            covariances,
            cholesky,
        ))
    }

    /// Checks invariants (for mixtures read from files): lengths that fit `k` components in
    /// `dim` dimensions, finite numbers, weights `>= 0` and Cholesky factors with a positive
    /// diagonal.
    pub fn is_consistent(&self) -> bool {
        let (dim, k) = (self.dim, self.weights.len());
        let Some(d2) = dim.checked_mul(dim) else {
            return false;
        };
        dim > 0
            && k > 0
            && Some(self.means.len()) == k.checked_mul(dim)
            && Some(self.covariances.len()) == k.checked_mul(d2)
            && self.cholesky.len() == self.covariances.len()
            && self.log_normalisers.len() == k
            && self.weights.iter().all(|w| w.is_finite() && *w >= 0.0)
            && self
                .means
                .iter()
                .chain(&self.covariances)
                .chain(&self.cholesky)
                .chain(&self.log_normalisers)
                .all(|v| v.is_finite())
            && (0..k).all(|c| (0..dim).all(|a| self.cholesky[c * d2 + a * dim + a] > 0.0))
    }

    /// A mixture from normalised weights, means, covariances and their lower Cholesky
    /// factors ([Krajník 2019] eq. 2): computes the log-normalisers.
    fn from_factors(
        dim: usize,
        weights: Vec<f64>,
        means: Vec<f64>,
        covariances: Vec<f64>,
        cholesky: Vec<f64>,
    ) -> Self {
        let d2 = dim * dim;
        let log_2pi = dim as f64 * (2.0 * std::f64::consts::PI).ln();
        let log_normalisers = weights
            .iter()
            .enumerate()
            .map(|(c, w)| {
                w.ln() - 0.5 * log_2pi - linalg::half_log_det(&cholesky[c * d2..(c + 1) * d2], dim)
            })
            .collect();
        GaussianMixture {
            dim,
            weights,
            means,
            covariances,
            cholesky,
            log_normalisers,
        }
    }

    /// [`GaussianMixture::component_log_densities`] with caller-provided scratch `z`
    /// (length `dim`): allocation-free, the kernel of every E-step.
    #[inline]
    fn component_log_densities_into(&self, x: &[f64], out: &mut [f64], z: &mut [f64]) {
        let (d, d2) = (self.dim, self.dim * self.dim);
        for (c, o) in out.iter_mut().enumerate() {
            let q = linalg::mahalanobis2(
                &self.cholesky[c * d2..(c + 1) * d2],
                &self.means[c * d..(c + 1) * d],
                x,
                z,
            );
            *o = self.log_normalisers[c] - 0.5 * q;
        }
    }

    /// `ln p(x)` with caller-provided scratch: `lp` (length `k`) and `z` (length `dim`).
    #[inline]
    fn log_density_into(&self, x: &[f64], lp: &mut [f64], z: &mut [f64]) -> f64 {
        self.component_log_densities_into(x, lp, z);
        linalg::log_sum_exp(lp)
    }

    /// Dimensions.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of components.
    pub fn components(&self) -> usize {
        self.weights.len()
    }

    /// Component weights (sum 1).
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// Mean of component `c`.
    pub fn mean(&self, c: usize) -> &[f64] {
        &self.means[c * self.dim..(c + 1) * self.dim]
    }

    /// Covariance of component `c` (`dim × dim`, row-major).
    pub fn covariance(&self, c: usize) -> &[f64] {
        let d2 = self.dim * self.dim;
        &self.covariances[c * d2..(c + 1) * d2]
    }

    /// `ln p(x)`.
    ///
    /// # Panics
    /// If `x.len() != dim`.
    pub fn log_density(&self, x: &[f64]) -> f64 {
        assert_eq!(
            x.len(),
            self.dim,
            "log_density: point of the wrong dimension"
        );
        let mut lp = vec![0.0; self.components()];
        let mut z = vec![0.0; self.dim];
        self.log_density_into(x, &mut lp, &mut z)
    }

    /// `ln(w_c · N(x; μ_c, Σ_c))` for every component, written into `out` (length `k`).
    ///
    /// # Panics
    /// If the lengths are wrong.
    pub fn component_log_densities(&self, x: &[f64], out: &mut [f64]) {
        assert_eq!(
            x.len(),
            self.dim,
            "component_log_densities: point of the wrong dimension"
        );
        assert_eq!(
            out.len(),
            self.components(),
            "component_log_densities: output length"
        );
        let mut z = vec![0.0; self.dim];
        self.component_log_densities_into(x, out, &mut z);
    }

    /// Weighted mean log-likelihood per unit weight of `data` (`n × dim`), summed in fixed
    /// chunks on the threads `parallelism` allows (the same bits on any).
    ///
    /// # Errors
    /// As [`fit_em`] for malformed data.
    pub fn mean_log_likelihood(
        &self,
        data: &[f64],
        weights: Option<&[f64]>,
        parallelism: Parallelism,
    ) -> Result<f64, MixtureError> {
        let rows = Rows::new(data, self.dim, weights)?.with_parallelism(parallelism);
        Ok(em::mean_log_likelihood(&rows, self))
    }

    /// The marginal mixture over `dims` (in that order).
    ///
    /// # Panics
    /// If a dimension is out of range or repeated.
    pub fn marginal(&self, dims: &[usize]) -> GaussianMixture {
        self.check_dims(dims);
        assert!(!dims.is_empty(), "marginal: no dimension");
        let (d, d2, m) = (self.dim, self.dim * self.dim, dims.len());
        let k = self.components();
        let mut means = Vec::with_capacity(k * m);
        let mut covariances = Vec::with_capacity(k * m * m);
        let mut cholesky = Vec::with_capacity(k * m * m);
        for c in 0..k {
            let mean = self.mean(c);
            means.extend(dims.iter().map(|&i| mean[i]));
            let cov = &self.covariances[c * d2..(c + 1) * d2];
            let mut sub: Vec<f64> = dims
                .iter()
                .flat_map(|&i| dims.iter().map(move |&j| cov[i * d + j]))
                .collect();
            let l = linalg::cholesky_with_jitter(&mut sub, m)
                .expect("a principal submatrix of a positive definite covariance");
            covariances.extend_from_slice(&sub);
            cholesky.extend_from_slice(&l);
        }
        GaussianMixture::from_factors(m, self.weights.clone(), means, covariances, cholesky)
    }

    /// Panics unless `dims` are distinct dimensions of the mixture.
    fn check_dims(&self, dims: &[usize]) {
        let mut seen = vec![false; self.dim];
        for &i in dims {
            assert!(i < self.dim, "dimension {i} out of range 0..{}", self.dim);
            assert!(!seen[i], "dimension {i} repeated");
            seen[i] = true;
        }
    }

    /// The conditional mixture of the other dimensions (in increasing order) given
    /// `x[given_dims[i]] = given[i]`: each component conditioned (Schur complement), the
    /// weights re-weighted by the components' marginal densities at `given` (in the log
    /// domain, so far-away points do not underflow to 0/0).
    ///
    /// # Panics
    /// If a dimension is out of range or repeated, lengths differ, no dimension is left, or a
    /// given value is not finite.
    pub fn conditional(&self, given_dims: &[usize], given: &[f64]) -> GaussianMixture {
        self.check_dims(given_dims);
        assert_eq!(given_dims.len(), given.len(), "conditional: lengths differ");
        assert!(
            given.iter().all(|v| v.is_finite()),
            "conditional: a given value is not finite"
        );
        let others: Vec<usize> = (0..self.dim).filter(|i| !given_dims.contains(i)).collect();
        assert!(!others.is_empty(), "conditional: no dimension is left");
        let (d, d2) = (self.dim, self.dim * self.dim);
        let (p, m, k) = (others.len(), given_dims.len(), self.components());
        let log_2pi = m as f64 * (2.0 * std::f64::consts::PI).ln();
        let mut log_weights = Vec::with_capacity(k);
        let mut means = Vec::with_capacity(k * p);
        let mut covariances = Vec::with_capacity(k * p * p);
        let mut cholesky = Vec::with_capacity(k * p * p);
        for c in 0..k {
            let mean = self.mean(c);
            let cov = &self.covariances[c * d2..(c + 1) * d2];
            // Σ_bb = L_b L_bᵀ, u = L_b⁻¹ (x_b − μ_b), V = L_b⁻¹ Σ_ba (m × p).
            let mut s_bb: Vec<f64> = given_dims
                .iter()
                .flat_map(|&i| given_dims.iter().map(move |&j| cov[i * d + j]))
                .collect();
            let (mut u, mut v) = (Vec::new(), vec![0.0; m * p]);
            let mut log_weight = self.weights[c].ln();
            if m > 0 {
                let l_b = linalg::cholesky_with_jitter(&mut s_bb, m)
                    .expect("a principal submatrix of a positive definite covariance");
                u = given_dims
                    .iter()
                    .zip(given)
                    .map(|(&i, x)| x - mean[i])
                    .collect();
                linalg::forward_solve(&l_b, m, &mut u);
                let mut column = vec![0.0; m];
                for (j, &a) in others.iter().enumerate() {
                    for (e, &b) in column.iter_mut().zip(given_dims) {
                        *e = cov[b * d + a];
                    }
                    linalg::forward_solve(&l_b, m, &mut column);
                    for i in 0..m {
                        v[i * p + j] = column[i];
                    }
                }
                let q: f64 = u.iter().map(|e| e * e).sum();
                log_weight += -0.5 * log_2pi - linalg::half_log_det(&l_b, m) - 0.5 * q;
            }
            log_weights.push(log_weight);
            // μ_a|b = μ_a + Vᵀu, Σ_a|b = Σ_aa − VᵀV (Schur complement).
            for (j, &a) in others.iter().enumerate() {
                let shift: f64 = (0..m).map(|i| v[i * p + j] * u[i]).sum();
                means.push(mean[a] + shift);
            }
            let mut schur = vec![0.0; p * p];
            for (j, &a) in others.iter().enumerate() {
                for (l, &b) in others.iter().enumerate().take(j + 1) {
                    let vv: f64 = (0..m).map(|i| v[i * p + j] * v[i * p + l]).sum();
                    let s = cov[a * d + b] - vv;
                    schur[j * p + l] = s;
                    schur[l * p + j] = s;
                }
            }
            let l = linalg::cholesky_with_jitter(&mut schur, p)
                .expect("a Schur complement of a positive definite covariance");
            covariances.extend_from_slice(&schur);
            cholesky.extend_from_slice(&l);
        }
        let total = linalg::log_sum_exp(&log_weights);
        let weights = if total.is_finite() {
            log_weights.iter().map(|lw| (lw - total).exp()).collect()
        } else {
            // Every component is infinitely far (in its own metric): keep the prior weights.
            self.weights.clone()
        };
        GaussianMixture::from_factors(p, weights, means, covariances, cholesky)
    }

    /// Mean and variance of the mixture in dimension `d` (law of total variance).
    pub fn moments(&self, d: usize) -> (f64, f64) {
        assert!(d < self.dim, "dimension {d} out of range 0..{}", self.dim);
        let k = self.components();
        let mean: f64 = (0..k).map(|c| self.weights[c] * self.mean(c)[d]).sum();
        let variance: f64 = (0..k)
            .map(|c| {
                let delta = self.mean(c)[d] - mean;
                self.weights[c] * (self.covariance(c)[d * self.dim + d] + delta * delta)
            })
            .sum();
        (mean, variance)
    }
}

/// How EM starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum EmInit {
    /// k-means++ seeding, then k-means, then covariances of the hard clusters (HyT-KM, [Krajník 2019]
    /// §IV; scikit-learn's default `init_params="kmeans"` is similar).
    KMeans,
    /// k-means++ seeding only (means), equal weights, and every covariance the weighted
    /// covariance of all the data (plus the ridge).
    KMeansPlusPlus,
}

/// EM settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EmConfig {
    /// Components `k >= 1`.
    pub components: usize,
    /// Most EM iterations per start. Default 200.
    pub max_iterations: usize,
    /// Stop when the mean log-likelihood per unit weight rises by less than this. Default
    /// `1e-6`.
    pub tolerance: f64,
    /// Added to every covariance diagonal (after scaling by the mean variance of the data
    /// when `relative_regularization`). Default `1e-6`.
    pub regularization: f64,
    /// Scale `regularization` by the mean per-dimension variance of the data. Default `true`.
    pub relative_regularization: bool,
    /// Independent starts; the one with the highest final log-likelihood wins. Default 3.
    pub starts: usize,
    /// Initialisation. Default [`EmInit::KMeans`].
    pub init: EmInit,
    /// Seed of every random choice. Default 0.
    pub seed: u64,
    /// Threads the per-row loops may use; the fit is the same on any. Default
    /// `Rayon(0)`; not stored (a configuration read back gets the default).
    #[serde(skip, default = "all_threads")]
    pub parallelism: Parallelism,
}

/// [`Parallelism::Rayon`]`(0)`: the default of the fits' configurations.
pub(crate) fn all_threads() -> Parallelism {
    Parallelism::Rayon(0)
}

impl Default for EmConfig {
    fn default() -> Self {
        EmConfig {
            components: 1,
            max_iterations: 200,
            tolerance: 1e-6,
            regularization: 1e-6,
            relative_regularization: true,
            starts: 3,
            init: EmInit::KMeans,
            seed: 0,
            parallelism: all_threads(),
        }
    }
}

/// The result of EM.
#[derive(Clone, Debug, PartialEq)]
pub struct EmFit {
    /// The fitted mixture.
    pub mixture: GaussianMixture,
    /// Final mean log-likelihood per unit weight.
    pub log_likelihood: f64,
    /// Mean log-likelihood after every iteration of the winning start (non-decreasing up to
    /// rounding: EM's monotonicity; up to `O(regularization)` with a large ridge, see the
    /// module doc). `trace.len() == iterations`; the last value is `log_likelihood`.
    pub trace: Vec<f64>,
    /// Iterations of the winning start.
    pub iterations: usize,
    /// Whether the winning start met the tolerance before `max_iterations`.
    pub converged: bool,
    /// Starts restarted because of a numerical failure (ill-conditioned covariance).
    pub numerical_restarts: usize,
    /// Whether the fit fell back to diagonal covariances.
    pub diagonal: bool,
}

/// Fits a Gaussian mixture to `data` (`n × dim`, optional weights) by EM ([Krajník 2019] eq. 2;
/// HyT-EM of §IV).
///
/// `starts` independent starts, each from its own seeded initialisation; the start with the
/// highest final log-likelihood wins. The ridge is `regularization`, times the mean
/// per-dimension weighted variance of the data when `relative_regularization` (times 1 if that
/// is 0). A start whose covariance fails the checks of the module doc restarts from a new
/// seeded initialisation ([`EmFit::numerical_restarts`] counts them over all starts); after
/// [`NUMERICAL_RESTARTS`] failures it fits diagonal covariances (variances floored at `1e-12`
/// of the data's), which cannot fail.
///
/// # Errors
/// Malformed data ([`MixtureError::DimensionMismatch`], [`MixtureError::NonFinite`],
/// [`MixtureError::InvalidWeight`], [`MixtureError::EmptyData`]), fewer distinct points than
/// components, or an invalid config.
pub fn fit_em(
    data: &[f64],
    dim: usize,
    weights: Option<&[f64]>,
    config: &EmConfig,
) -> Result<EmFit, MixtureError> {
    config.check()?;
    let rows = Rows::new(data, dim, weights)?.with_parallelism(config.parallelism);
    check_distinct(&rows, config.components)?;
    Ok(em::fit(&rows, config))
}

/// [`fit_em`] with at most `components` components ([Krajník 2019] eq. 2 with fewer Gaussians
/// where the data have fewer distinct points): when only `p ≥ 1` distinct rows carry weight,
/// fits `p` components instead. `config(k)` is the EM configuration for `k` components.
///
/// # Errors
/// As [`fit_em`]; [`MixtureError::TooFewPoints`] only when no row carries weight.
pub fn fit_em_at_most(
    data: &[f64],
    dim: usize,
    weights: Option<&[f64]>,
    components: usize,
    config: impl Fn(usize) -> EmConfig,
) -> Result<EmFit, MixtureError> {
    let mut k = components;
    loop {
        match fit_em(data, dim, weights, &config(k)) {
            Err(MixtureError::TooFewPoints { points, .. }) if points >= 1 && points < k => {
                k = points;
            }
            result => return result,
        }
    }
}

/// EM from a given initial mixture (one start, no random choices): what scikit-learn's
/// `GaussianMixture(means_init=…, weights_init=…, precisions_init=…)` does, for oracle tests.
///
/// With `relative_regularization: false` this is scikit-learn's `reg_covar = regularization`,
/// `tol = tolerance`, `max_iter = max_iterations`: the same iterations (E-step, then M-step;
/// stop after the M-step of the first iteration whose E-step log-likelihood changed by less
/// than `tolerance`), `iterations` is its `n_iter_`. `components`, `starts`, `init` and `seed`
/// are not used. A numerical failure (module doc) does not restart (there is nothing to draw):
/// the fit goes on with diagonal covariances from that M-step on (`diagonal` is set).
/// Components that become empty are re-seeded as in [`fit_em`].
///
/// # Errors
/// As [`fit_em`].
pub fn fit_em_from(
    data: &[f64],
    dim: usize,
    weights: Option<&[f64]>,
    initial: &GaussianMixture,
    config: &EmConfig,
) -> Result<EmFit, MixtureError> {
    config.check_iteration_settings()?;
    let rows = Rows::new(data, dim, weights)?.with_parallelism(config.parallelism);
    if initial.dim() != dim {
        return Err(MixtureError::DimensionMismatch(format!(
            "the initial mixture has {} dimensions, the data {dim}",
            initial.dim()
        )));
    }
    check_distinct(&rows, initial.components())?;
    Ok(em::fit_from(&rows, initial, config))
}

/// [`MixtureError::TooFewPoints`] unless `rows` has at least `k` distinct rows.
fn check_distinct(rows: &Rows<'_>, k: usize) -> Result<(), MixtureError> {
    let points = rows.distinct_up_to(k);
    if points < k {
        return Err(MixtureError::TooFewPoints {
            points,
            components: k,
        });
    }
    Ok(())
}

impl EmConfig {
    /// Checks every field.
    fn check(&self) -> Result<(), MixtureError> {
        if self.components == 0 {
            return Err(MixtureError::InvalidConfig(
                "components must be >= 1".into(),
            ));
        }
        if self.starts == 0 {
            return Err(MixtureError::InvalidConfig("starts must be >= 1".into()));
        }
        self.check_iteration_settings()
    }

    /// Checks the fields [`fit_em_from`] uses.
    fn check_iteration_settings(&self) -> Result<(), MixtureError> {
        if !(self.tolerance >= 0.0 && self.tolerance.is_finite()) {
            return Err(MixtureError::InvalidConfig(format!(
                "tolerance {} is not a finite number >= 0",
                self.tolerance
            )));
        }
        if !(self.regularization >= 0.0 && self.regularization.is_finite()) {
            return Err(MixtureError::InvalidConfig(format!(
                "regularization {} is not a finite number >= 0",
                self.regularization
            )));
        }
        Ok(())
    }
}

/// k-means settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct KMeansConfig {
    /// Clusters `k >= 1`.
    pub clusters: usize,
    /// Most Lloyd iterations per start. Default 100.
    pub max_iterations: usize,
    /// Independent k-means++ starts; the lowest inertia wins. Default 3.
    pub starts: usize,
    /// Seed. Default 0.
    pub seed: u64,
    /// Threads the per-row loops may use; the fit is the same on any. Default
    /// `Rayon(0)`; not stored.
    #[serde(skip, default = "all_threads")]
    pub parallelism: Parallelism,
}

impl Default for KMeansConfig {
    fn default() -> Self {
        KMeansConfig {
            clusters: 1,
            max_iterations: 100,
            starts: 3,
            seed: 0,
            parallelism: all_threads(),
        }
    }
}

/// The result of k-means.
#[derive(Clone, Debug, PartialEq)]
pub struct KMeansFit {
    /// `k × dim` centres.
    pub centres: Vec<f64>,
    /// Cluster of every row.
    pub labels: Vec<usize>,
    /// Weighted sum of squared distances to the centres.
    pub inertia: f64,
    /// Lloyd iterations of the winning start.
    pub iterations: usize,
}

/// Weighted k-means (Lloyd) with k-means++ seeding.
///
/// # Errors
/// As [`fit_em`].
pub fn kmeans(
    data: &[f64],
    dim: usize,
    weights: Option<&[f64]>,
    config: &KMeansConfig,
) -> Result<KMeansFit, MixtureError> {
    if config.clusters == 0 {
        return Err(MixtureError::InvalidConfig("clusters must be >= 1".into()));
    }
    if config.starts == 0 {
        return Err(MixtureError::InvalidConfig("starts must be >= 1".into()));
    }
    let rows = Rows::new(data, dim, weights)?.with_parallelism(config.parallelism);
    check_distinct(&rows, config.clusters)?;
    Ok(kmeans::fit(&rows, config))
}

/// The mixture of hard clusters: weights = cluster weight shares, means and (regularised)
/// covariances of each cluster's rows (HyT-KM: "calculates the covariance matrices of the
/// clusters", [Krajník 2019] §IV). Empty clusters are dropped.
///
/// # Errors
/// As [`fit_em`]; [`MixtureError::DimensionMismatch`] for a label `>= k`.
pub fn mixture_of_clusters(
    data: &[f64],
    dim: usize,
    weights: Option<&[f64]>,
    labels: &[usize],
    k: usize,
    regularization: f64,
) -> Result<GaussianMixture, MixtureError> {
    if k == 0 {
        return Err(MixtureError::InvalidConfig("k must be >= 1".into()));
    }
    if !(regularization >= 0.0 && regularization.is_finite()) {
        return Err(MixtureError::InvalidConfig(format!(
            "regularization {regularization} is not a finite number >= 0"
        )));
    }
    let rows = Rows::new(data, dim, weights)?;
    if labels.len() != rows.n {
        return Err(MixtureError::DimensionMismatch(format!(
            "{} labels for {} rows",
            labels.len(),
            rows.n
        )));
    }
    if let Some(l) = labels.iter().find(|&&l| l >= k) {
        return Err(MixtureError::DimensionMismatch(format!(
            "label {l} is not below k = {k}"
        )));
    }
    em::cluster_mixture(&rows, labels, k, regularization, em::Covariances::Full)
        .map_err(|component| MixtureError::NotPositiveDefinite { component })
}
