//! The uncertainty-dependent loop-search radius of [Stüde 2024] §3.2.1, eq. (3.8), which
//! §3.3.3 reuses for the loop search over link points and link-point candidates.
//!
//! `r(λ_max) = r_min + β·g_max(λ_max)` with `g_max = 2√(5.991·λ_max)`, the length of the
//! major axis of the 95 % confidence ellipse (5.991 is the 95 % quantile of χ² with two
//! degrees of freedom) of a position covariance whose larger eigenvalue is `λ_max`.
//!
//! The equation is implemented once in the workspace, by
//! [`chronomap_geometry::se2::search_radius`] (and `λ_max` by
//! [`chronomap_geometry::linalg::largest_eigenvalue`]); this module holds the two parameters
//! §3.3.3 needs and thin wrappers that take a pose covariance or `λ_max` and give this crate's
//! errors.
//!
//! ```
//! use chronomap_multimap::search::{search_radius, search_radius_for, SearchParams};
//!
//! let params = SearchParams::default(); // r_min = 3 m, β = 0.25 (appendix A, indoor)
//! assert_eq!(search_radius(0.0, &params)?, 3.0);
//! // λ_max = 1 m²: the 95 % ellipse's major axis is 2√5.991 ≈ 4.895 m.
//! assert!((search_radius(1.0, &params)? - (3.0 + 0.25 * 2.0 * 5.991f64.sqrt())).abs() < 1e-12);
//! // A pose covariance: only its position block counts, and of it the larger eigenvalue.
//! let cov = [[4.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 100.0]];
//! assert_eq!(search_radius_for(&cov, &params)?, search_radius(4.0, &params)?);
//! # Ok::<(), chronomap_multimap::MultimapError>(())
//! ```
//!
//! [Stüde 2024]: M. Stüde, dissertation, Leibniz Universität Hannover, 2024.

use chronomap_geometry::GeometryError;
use chronomap_geometry::linalg::largest_eigenvalue;
use chronomap_geometry::se2::{self, Mat3};
use serde::{Deserialize, Serialize};

use crate::MultimapError;

pub use chronomap_geometry::se2::position_block;

/// The 95 % quantile of the χ² distribution with two degrees of freedom ([Stüde 2024]
/// eq. (3.8)); [`chronomap_geometry::se2::CHI2_95_2D`].
pub const CHI2_2DOF_95: f64 = se2::CHI2_95_2D;

/// The parameters of eq. (3.8).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SearchParams {
    /// `r_min`: radius when the pose is certain (m). Default 3 m ([Stüde 2024] appendix A,
    /// indoor and outdoor).
    pub r_min: f64,
    /// `β`: weight of the confidence-ellipse term. Default 0.25 (appendix A).
    pub beta: f64,
}

impl Default for SearchParams {
    fn default() -> Self {
        SearchParams {
            r_min: 3.0,
            beta: 0.25,
        }
    }
}

impl SearchParams {
    /// Checks `r_min ≥ 0` and `β ≥ 0`, both finite.
    pub fn validate(&self) -> Result<(), MultimapError> {
        for (field, value) in [("r_min", self.r_min), ("beta", self.beta)] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(MultimapError::Parameter {
                    field,
                    value,
                    why: "must be finite and non-negative",
                });
            }
        }
        Ok(())
    }
}

/// Eq. (3.8) for a 2×2 position covariance (`params` checked by the caller); a covariance
/// that is not one is refused naming the `position covariance`.
fn radius_of(cov: [[f64; 2]; 2], params: &SearchParams) -> Result<f64, MultimapError> {
    let lambda = largest_eigenvalue(cov).map_err(|e| {
        MultimapError::from(match e {
            GeometryError::NotCovariance { why, .. } => GeometryError::NotCovariance {
                field: "position covariance",
                why,
            },
            other => other,
        })
    })?;
    Ok(se2::search_radius(params.r_min, params.beta, lambda))
}

/// `g_max(λ_max) = 2√(5.991·λ_max)`: the major axis of the 95 % confidence ellipse (m), eq.
/// (3.8) with `r_min = 0`, `β = 1`; NaN where `λ_max` is not a finite variance.
pub fn major_axis_95(lambda_max: f64) -> f64 {
    let unit = SearchParams {
        r_min: 0.0,
        beta: 1.0,
    };
    search_radius(lambda_max, &unit).unwrap_or(f64::NAN)
}

/// The search radius `r(λ_max)` of [Stüde 2024] eq. (3.8) (m), by
/// [`chronomap_geometry::se2::search_radius`] of the covariance `diag(λ_max, 0)`. `λ_max`
/// must be finite and non-negative (round-off below zero down to `−1e-12` is read as 0).
pub fn search_radius(lambda_max: f64, params: &SearchParams) -> Result<f64, MultimapError> {
    params.validate()?;
    if !lambda_max.is_finite() || lambda_max < -1e-12 {
        return Err(MultimapError::Parameter {
            field: "lambda_max",
            value: lambda_max,
            why: "must be a finite variance (≥ 0)",
        });
    }
    let cov = [[lambda_max.max(0.0), 0.0], [0.0, 0.0]];
    radius_of(cov, params)
}

/// The search radius of eq. (3.8) for a pose covariance `(x, y, θ)`: `λ_max` of its position
/// block ([`position_block`]), by [`chronomap_geometry::se2::search_radius`].
pub fn search_radius_for(cov: &Mat3, params: &SearchParams) -> Result<f64, MultimapError> {
    params.validate()?;
    radius_of(position_block(cov), params)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radius_grows_with_the_square_root_of_the_variance() {
        let p = SearchParams {
            r_min: 1.0,
            beta: 0.5,
        };
        let r4 = search_radius(4.0, &p).unwrap();
        let r16 = search_radius(16.0, &p).unwrap();
        // 1 + 0.5·2·√(5.991·λ): quadrupling λ doubles the second term.
        assert!(((r16 - 1.0) - 2.0 * (r4 - 1.0)).abs() < 1e-12);
        assert!((r4 - (1.0 + 2.0 * 5.991f64.sqrt())).abs() < 1e-12);
        assert!((major_axis_95(4.0) - 4.0 * 5.991f64.sqrt()).abs() < 1e-12);
        assert!(major_axis_95(-1.0).is_nan());
    }

    #[test]
    fn the_covariance_form_uses_the_larger_eigenvalue_of_the_position_block() {
        // [[4, 1], [1, 3]]: eigenvalues (7 ± √5)/2; the heading variance does not count.
        let cov = [[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 50.0]];
        let p = SearchParams::default();
        let lambda = (7.0 + 5f64.sqrt()) / 2.0;
        let r = search_radius_for(&cov, &p).unwrap();
        assert!((r - (3.0 + 0.25 * 2.0 * (5.991 * lambda).sqrt())).abs() < 1e-12);
        let bad = [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert_eq!(
            search_radius_for(&bad, &p).unwrap_err().to_string(),
            "position covariance is not a covariance matrix: a variance is negative"
        );
    }

    #[test]
    fn bad_input_is_refused() {
        let p = SearchParams::default();
        assert!(search_radius(f64::NAN, &p).is_err());
        assert!(search_radius(-1.0, &p).is_err());
        assert_eq!(search_radius(-1e-13, &p).unwrap(), 3.0);
        let bad = SearchParams {
            r_min: -1.0,
            beta: 0.0,
        };
        assert!(
            search_radius(0.0, &bad)
                .unwrap_err()
                .to_string()
                .contains("r_min")
        );
    }
}
