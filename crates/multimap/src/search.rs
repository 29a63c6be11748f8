//! The uncertainty-dependent loop-search radius of [Stüde 2024] §3.2.1, eq. (3.8), which
//! §3.3.3 reuses for the loop search over link points and link-point candidates.
//!
//! `r(λ_max) = r_min + β·g_max(λ_max)` with `g_max = 2√(5.991·λ_max)`, the length of the
//! major axis of the 95 % confidence ellipse (5.991 is the 95 % quantile of χ² with two
//! degrees of freedom) of a position covariance whose larger eigenvalue is `λ_max`.
//!
//! ```
//! use chronomap_multimap::search::{search_radius, SearchParams};
//!
//! let params = SearchParams::default(); // r_min = 3 m, β = 0.25 (appendix A, indoor)
//! assert_eq!(search_radius(0.0, &params)?, 3.0);
//! // λ_max = 1 m²: the 95 % ellipse's major axis is 2√5.991 ≈ 4.895 m.
//! assert!((search_radius(1.0, &params)? - (3.0 + 0.25 * 2.0 * 5.991f64.sqrt())).abs() < 1e-12);
//! # Ok::<(), chronomap_multimap::MultimapError>(())
//! ```
//!
//! The lidar crate has the same function for §3.2's node search; the two are meant to be
//! merged into one.
//!
//! [Stüde 2024]: M. Stüde, dissertation, Leibniz Universität Hannover, 2024.

use serde::{Deserialize, Serialize};

use crate::MultimapError;

/// The 95 % quantile of the χ² distribution with two degrees of freedom ([Stüde 2024]
/// eq. (3.8)).
pub const CHI2_2DOF_95: f64 = 5.991;

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

/// `g_max(λ_max) = 2√(5.991·λ_max)`: the major axis of the 95 % confidence ellipse (m).
pub fn major_axis_95(lambda_max: f64) -> f64 {
    2.0 * (CHI2_2DOF_95 * lambda_max).sqrt()
}

/// The search radius `r(λ_max)` of [Stüde 2024] eq. (3.8) (m). `λ_max` must be finite and
/// non-negative (round-off below zero down to `−1e-12` is read as 0).
pub fn search_radius(lambda_max: f64, params: &SearchParams) -> Result<f64, MultimapError> {
    params.validate()?;
    if !lambda_max.is_finite() || lambda_max < -1e-12 {
        return Err(MultimapError::Parameter {
            field: "lambda_max",
            value: lambda_max,
            why: "must be a finite variance (≥ 0)",
        });
    }
    Ok(params.r_min + params.beta * major_axis_95(lambda_max.max(0.0)))
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
    }

    #[test]
    fn bad_input_is_refused() {
        let p = SearchParams::default();
        assert!(search_radius(f64::NAN, &p).is_err());
        assert!(search_radius(-1.0, &p).is_err());
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
