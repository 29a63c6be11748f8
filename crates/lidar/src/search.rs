//! Where to look for loops ([Stüde 2024] §3.2.1, "Defining the search space"): nodes within
//! the radius of eq. (3.8) around the estimated pose, the whole working memory while the local
//! map is a small part of it (`α = n_local/n_WM < α_min`), and a neighbourhood check of the
//! first `n_start` loops. Defaults: the indoor column of appendix A.
//!
//! ```
//! use chronomap_lidar::search::{SearchMode, SearchParams, search_mode, search_radius};
//!
//! let params = SearchParams::default();
//! // No position uncertainty: the minimal radius r_min = 3 m.
//! assert_eq!(search_radius([[0.0, 0.0], [0.0, 0.0]], &params)?, 3.0);
//! // λ_max = 4 m²: r = 3 + 0.25 · 2√(5.991 · 4) ≈ 5.45 m.
//! let r = search_radius([[4.0, 0.0], [0.0, 1.0]], &params)?;
//! assert!((r - (3.0 + 0.5 * (5.991f64 * 4.0).sqrt())).abs() < 1e-12);
//! // A new session of 10 nodes next to 90 old ones: search globally.
//! assert_eq!(search_mode(10, 100, params.alpha_min), SearchMode::Global);
//! # Ok::<(), chronomap_lidar::search::SearchError>(())
//! ```
//!
//! [Stüde 2024]: M. Stüde, dissertation, Hannover 2024.

use chronomap_geometry::GeometryError;
use chronomap_geometry::linalg::largest_eigenvalue;
use chronomap_geometry::se2::{self, Pose2, jacobian_compose_first, jacobian_compose_second};
use serde::{Deserialize, Serialize};

/// The χ² quantile of 2 degrees of freedom at 95 % (the 95 % confidence ellipse).
pub use chronomap_geometry::se2::CHI2_95_2D;

/// Parameters of the loop search ([Stüde 2024] appendix A, indoor column).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SearchParams {
    /// `p_min`: pairs whose loop probability exceeds it are loops (52.4 %).
    pub p_min: f64,
    /// `r_min`: the minimal search radius (3 m).
    pub r_min: f64,
    /// `β`: scale of the uncertainty-dependent part of the radius (0.25).
    pub beta: f64,
    /// `α_min`: below this ratio of local to working-memory nodes the search is global (0.5).
    pub alpha_min: f64,
    /// `n_start`: loops that need verification before the search trusts single detections (3).
    pub n_start: usize,
    /// `n_ver`: further detected pairs needed near the target node to verify a loop (2).
    pub n_ver: usize,
    /// `r_ver`: radius of that neighbourhood (5 m).
    pub r_ver: f64,
}

impl Default for SearchParams {
    fn default() -> Self {
        SearchParams {
            p_min: 0.524,
            r_min: 3.0,
            beta: 0.25,
            alpha_min: 0.5,
            n_start: 3,
            n_ver: 2,
            r_ver: 5.0,
        }
    }
}

impl SearchParams {
    /// Checks the parameters: finite, `r_min`, `β`, `r_ver` non-negative, `α_min` in `[0, 1]`,
    /// `p_min` in `[0, 1]`.
    pub fn validate(&self) -> Result<(), SearchError> {
        let check = |field, value: f64, ok: bool| {
            if value.is_finite() && ok {
                Ok(())
            } else {
                Err(SearchError::Param { field, value })
            }
        };
        check("p_min", self.p_min, (0.0..=1.0).contains(&self.p_min))?;
        check("r_min", self.r_min, self.r_min >= 0.0)?;
        check("beta", self.beta, self.beta >= 0.0)?;
        check(
            "alpha_min",
            self.alpha_min,
            (0.0..=1.0).contains(&self.alpha_min),
        )?;
        check("r_ver", self.r_ver, self.r_ver >= 0.0)
    }
}

/// Why a search quantity cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SearchError {
    /// A parameter is out of range.
    #[error("search parameter {field}: {value} is not valid")]
    Param {
        /// The parameter.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// The covariance is not a finite symmetric positive semi-definite matrix.
    #[error("covariance: {0}")]
    Covariance(&'static str),
}

impl From<GeometryError> for SearchError {
    fn from(e: GeometryError) -> Self {
        match e {
            GeometryError::NotCovariance { why, .. } => SearchError::Covariance(why),
            // `largest_eigenvalue` refuses covariances only.
            _ => SearchError::Covariance("not a covariance matrix"),
        }
    }
}

/// The search radius of [Stüde 2024] eq. (3.8): `r = r_min + β·g_max` with
/// `g_max = 2√(5.991·λ_max)` the major axis of the 95 % confidence ellipse of the 2×2
/// position covariance ([`se2::search_radius`] of its
/// [`largest_eigenvalue`]).
///
/// # Errors
/// [`SearchError::Covariance`] if `cov` is not finite, not symmetric (to 1e-9 relative) or
/// has a negative variance, and [`SearchError::Param`] for bad parameters.
pub fn search_radius(cov: [[f64; 2]; 2], params: &SearchParams) -> Result<f64, SearchError> {
    params.validate()?;
    let lambda = largest_eigenvalue(cov)?;
    Ok(se2::search_radius(params.r_min, params.beta, lambda))
}

/// Where to search for loops.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum SearchMode {
    /// Within the search radius around the estimated pose.
    Local,
    /// In the whole working memory.
    Global,
}

/// The search mode for `n_local` nodes of the local map among `n_wm` nodes in working memory:
/// global while `α = n_local/n_WM < α_min` ([Stüde 2024] §3.2.1), local otherwise (and when the
/// working memory is empty).
pub fn search_mode(n_local: usize, n_wm: usize, alpha_min: f64) -> SearchMode {
    if n_wm == 0 || n_local as f64 / n_wm as f64 >= alpha_min {
        SearchMode::Local
    } else {
        SearchMode::Global
    }
}

/// The nodes (indices into `nodes`) within `radius` of `query` for which `eligible` holds.
pub fn within_radius(
    query: [f64; 2],
    radius: f64,
    nodes: &[[f64; 2]],
    eligible: impl Fn(usize) -> bool,
) -> Vec<usize> {
    (0..nodes.len())
        .filter(|&i| {
            eligible(i) && (nodes[i][0] - query[0]).hypot(nodes[i][1] - query[1]) <= radius
        })
        .collect()
}

/// Whether a loop to node `target` is verified ([Stüde 2024] §3.2.1): at least `n_ver` other
/// detected pairs of the same query (`detected`, node indices) have their node within `r_ver`
/// of the target.
pub fn verified(
    target: usize,
    detected: &[usize],
    nodes: &[[f64; 2]],
    params: &SearchParams,
) -> bool {
    let t = nodes[target];
    let near = detected
        .iter()
        .filter(|&&i| i != target && (nodes[i][0] - t[0]).hypot(nodes[i][1] - t[1]) <= params.r_ver)
        .count();
    near >= params.n_ver
}

/// Odometry noise for the covariance of dead reckoning: standard deviations proportional to
/// the motion of each increment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OdometryNoise {
    /// Translation sd per metre travelled (m/m).
    pub translation: f64,
    /// Heading sd per metre travelled (rad/m).
    pub heading_per_metre: f64,
    /// Heading sd per radian turned (rad/rad).
    pub heading_per_radian: f64,
}

impl Default for OdometryNoise {
    /// 5 % of the distance, 0.01 rad/m and 5 % of the rotation: a typical wheeled robot.
    fn default() -> Self {
        OdometryNoise {
            translation: 0.05,
            heading_per_metre: 0.01,
            heading_per_radian: 0.05,
        }
    }
}

/// One dead-reckoning step: the pose `(x, y, θ)` composed with the increment `(dx, dy, dθ)`
/// of the robot frame ([`se2::compose`], heading unwrapped), and the first-order propagation
/// of its covariance `Σ' = J_x Σ J_xᵀ + J_u Q J_uᵀ` with the Jacobians of the composition
/// ([Stüde 2024] eqs. (3.12)–(3.13), which propagate link-point uncertainty the same way) and
/// `Q` from [`OdometryNoise`].
pub fn propagate(
    pose: [f64; 3],
    cov: [[f64; 3]; 3],
    increment: [f64; 3],
    noise: &OdometryNoise,
) -> ([f64; 3], [[f64; 3]; 3]) {
    let [dx, dy, dt] = increment;
    let next = se2::compose(pose, increment);
    let jx = jacobian_compose_first(&Pose2::from_array(pose), &Pose2::from_array(increment));
    let ju = jacobian_compose_second(&Pose2::from_array(pose));
    let d = dx.hypot(dy);
    let st = noise.translation * d;
    let sh = noise.heading_per_metre * d + noise.heading_per_radian * dt.abs();
    let q = [st * st, st * st, sh * sh];
    let mut out = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let mut v = 0.0;
            for k in 0..3 {
                for l in 0..3 {
                    v += jx[i][k] * cov[k][l] * jx[j][l];
                }
                v += ju[i][k] * q[k] * ju[j][k];
            }
            out[i][j] = v;
        }
    }
    (next, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radius_of_a_rotated_ellipse_and_refused_covariances() {
        // diag(9, 1) rotated by 30°: λ_max stays 9, r = 3 + 0.25 · 2√(5.991 · 9).
        let (s, c) = 30f64.to_radians().sin_cos();
        let a = 9.0 * c * c + s * s;
        let d = 9.0 * s * s + c * c;
        let b = (9.0 - 1.0) * s * c;
        let p = SearchParams::default();
        let r = search_radius([[a, b], [b, d]], &p).unwrap();
        assert!((r - (3.0 + 0.5 * (5.991f64 * 9.0).sqrt())).abs() < 1e-12);
        assert_eq!(
            search_radius([[1.0, 2.0], [0.0, 1.0]], &p),
            Err(SearchError::Covariance("not symmetric"))
        );
        assert_eq!(
            search_radius([[-1.0, 0.0], [0.0, 1.0]], &p),
            Err(SearchError::Covariance("a variance is negative"))
        );
        assert_eq!(
            search_radius([[f64::NAN, 0.0], [0.0, 1.0]], &p),
            Err(SearchError::Covariance("not finite"))
        );
    }

    #[test]
    fn radius_grows_with_uncertainty() {
        let p = SearchParams::default();
        let r = search_radius([[1.0, 0.0], [0.0, 1.0]], &p).unwrap();
        assert!((r - (3.0 + 0.25 * 2.0 * 5.991f64.sqrt())).abs() < 1e-12);
        let bad = SearchParams { beta: -1.0, ..p };
        assert!(matches!(
            search_radius([[0.0; 2]; 2], &bad),
            Err(SearchError::Param { field: "beta", .. })
        ));
    }

    #[test]
    fn global_until_the_local_map_is_half_the_working_memory() {
        assert_eq!(search_mode(49, 100, 0.5), SearchMode::Global);
        assert_eq!(search_mode(50, 100, 0.5), SearchMode::Local);
        assert_eq!(search_mode(0, 0, 0.5), SearchMode::Local);
    }

    #[test]
    fn verification_counts_detections_near_the_target() {
        let nodes = [[0.0, 0.0], [1.0, 0.0], [4.0, 3.0], [10.0, 0.0]];
        let p = SearchParams::default();
        // Node 0 with detections 1 (1 m) and 2 (5 m): two within r_ver = 5 m.
        assert!(verified(0, &[0, 1, 2, 3], &nodes, &p));
        assert!(!verified(0, &[0, 1, 3], &nodes, &p));
        assert_eq!(within_radius([0.0, 0.0], 4.0, &nodes, |i| i != 1), vec![0]);
    }

    #[test]
    fn straight_driving_grows_lateral_variance_through_heading() {
        let noise = OdometryNoise::default();
        let (mut pose, mut cov) = ([0.0; 3], [[0.0; 3]; 3]);
        for _ in 0..10 {
            (pose, cov) = propagate(pose, cov, [1.0, 0.0, 0.0], &noise);
        }
        assert!((pose[0] - 10.0).abs() < 1e-12);
        // Along the path: 10 steps of (0.05 m)².
        assert!((cov[0][0] - 10.0 * 0.0025).abs() < 1e-12);
        // Across: (0.05)² per step plus the heading error (0.01 rad per step) carried over
        // the remaining distance: Σ_k (0.05² + 0.01² · k²) for k = 0..9.
        let expected: f64 = (0..10).map(|k| 0.0025 + 1e-4 * (k * k) as f64).sum();
        assert!((cov[1][1] - expected).abs() < 1e-12, "{}", cov[1][1]);
        assert!((cov[2][2] - 10.0 * 1e-4).abs() < 1e-15);
    }
}
