//! Gaussian mixtures fitted by expectation–maximisation, and k-means: the clustering stage of
//! Warped Hypertime (seed 004 §III-C eq. 2, §IV: HyT-EM and HyT-KM).
//!
//! Seed 004 §IV reports that clustering the sparse hypertime space is the hard part: EM "sometimes
//! exhibited numerical instabilities", detected "through eigenvalue analysis of the covariance
//! matrices", fixed by restarts or diagonal covariances. Here EM is made robust by construction:
//! responsibilities in the log domain (log-sum-exp), a ridge `regularization` added to every
//! covariance diagonal (as scikit-learn's `reg_covar`), Cholesky factors checked on every
//! M-step (a failed or ill-conditioned factor — smallest/largest eigenvalue below `1e-12` —
//! restarts from a new seeded initialisation, and after `restarts` failures falls back to
//! diagonal covariances), empty components re-seeded at the worst-explained point.
//!
//! Data are `n × dim` row-major slices with optional non-negative per-row weights (a weight
//! `w` counts as `w` identical rows: integer weights give exactly the result of duplicated
//! rows). All randomness comes from the seeded [`crate::rng::Xoshiro256StarStar`]: the same
//! data, config and seed give bit-identical results.

use serde::{Deserialize, Serialize};
use thiserror::Error;

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

/// A mixture of `k` multivariate normal densities in `dim` dimensions (seed 004 eq. 2).
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
        let _ = (dim, weights, means, covariances);
        todo!()
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
        let _ = x;
        todo!()
    }

    /// `ln(w_c · N(x; μ_c, Σ_c))` for every component, written into `out` (length `k`).
    ///
    /// # Panics
    /// If the lengths are wrong.
    pub fn component_log_densities(&self, x: &[f64], out: &mut [f64]) {
        let _ = (x, out);
        todo!()
    }

    /// Weighted mean log-likelihood per unit weight of `data` (`n × dim`).
    ///
    /// # Errors
    /// As [`fit_em`] for malformed data.
    pub fn mean_log_likelihood(
        &self,
        data: &[f64],
        weights: Option<&[f64]>,
    ) -> Result<f64, MixtureError> {
        let _ = (data, weights);
        todo!()
    }

    /// The marginal mixture over `dims` (in that order).
    ///
    /// # Panics
    /// If a dimension is out of range or repeated.
    pub fn marginal(&self, dims: &[usize]) -> GaussianMixture {
        let _ = dims;
        todo!()
    }

    /// The conditional mixture of the other dimensions (in increasing order) given
    /// `x[given_dims[i]] = given[i]`: each component conditioned (Schur complement), the
    /// weights re-weighted by the components' marginal densities at `given` (in the log
    /// domain, so far-away points do not underflow to 0/0).
    ///
    /// # Panics
    /// If a dimension is out of range or repeated, lengths differ, or no dimension is left.
    pub fn conditional(&self, given_dims: &[usize], given: &[f64]) -> GaussianMixture {
        let _ = (given_dims, given);
        todo!()
    }

    /// Mean and variance of the mixture in dimension `d` (law of total variance).
    pub fn moments(&self, d: usize) -> (f64, f64) {
        let _ = d;
        todo!()
    }
}

/// How EM starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum EmInit {
    /// k-means++ seeding, then k-means, then covariances of the hard clusters (HyT-KM, seed 004
    /// §IV; scikit-learn's default `init_params="kmeans"` is similar).
    KMeans,
    /// k-means++ seeding only (means), unit-weighted covariances of the data.
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
    /// rounding: EM's monotonicity).
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

/// Fits a Gaussian mixture to `data` (`n × dim`, optional weights) by EM.
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
    let _ = (data, dim, weights, config);
    todo!()
}

/// EM from a given initial mixture (one start, no random choices): what scikit-learn's
/// `GaussianMixture(means_init=…, weights_init=…, precisions_init=…)` does, for oracle tests.
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
    let _ = (data, dim, weights, initial, config);
    todo!()
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
}

impl Default for KMeansConfig {
    fn default() -> Self {
        KMeansConfig {
            clusters: 1,
            max_iterations: 100,
            starts: 3,
            seed: 0,
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
    let _ = (data, dim, weights, config);
    todo!()
}

/// The mixture of hard clusters: weights = cluster weight shares, means and (regularised)
/// covariances of each cluster's rows (HyT-KM: "calculates the covariance matrices of the
/// clusters", seed 004 §IV). Empty clusters are dropped.
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
    let _ = (data, dim, weights, labels, k, regularization);
    todo!()
}
