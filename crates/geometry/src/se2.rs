//! Poses in the plane (SE(2)), the composition operator `⊕` with its Jacobians, and
//! uncertain poses propagated to first order ([Stüde 2024] §3.3.3, eqs. (3.10)–(3.13), after
//! Smith & Cheeseman 1986); the 95 % confidence ellipse of a position and the loop-search
//! radius of [Stüde 2024] eq. (3.8) that grows with it.
//!
//! A pose `p = (x, y, θ)ᵀ` is the vector `π(T)` of the homogeneous transform
//! `T = [[cos θ, −sin θ, x], [sin θ, cos θ, y], [0, 0, 1]]`; `a ⊕ b = π(T_a T_b)` and
//! `⊖a = π(T_a⁻¹)`. Angles of [`Pose2`] are kept in `(−π, π]`; the array forms [`compose`]
//! and [`between`] of odometry increments `(dx, dy, dθ)` leave a composed heading unwrapped.
//!
//! ```
//! use chronomap_geometry::se2::{Pose2, UncertainPose};
//!
//! // One metre ahead, then a quarter turn, then one metre ahead again.
//! let step = Pose2::new(1.0, 0.0, std::f64::consts::FRAC_PI_2)?;
//! let two = step.compose(&step);
//! assert!((two.x - 1.0).abs() < 1e-12 && (two.y - 1.0).abs() < 1e-12);
//! // a ⊕ ⊖a is the identity.
//! let id = two.compose(&two.inverse());
//! assert!(id.x.abs() < 1e-12 && id.y.abs() < 1e-12 && id.theta.abs() < 1e-12);
//!
//! // An uncertain step composed with a certain one: eq. (3.13).
//! let a = UncertainPose::new(step, [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.001]])?;
//! let b = UncertainPose::exact(Pose2::new(2.0, 0.0, 0.0)?);
//! let c = a.compose(&b);
//! // The heading error of `a` moves `b`'s two metres sideways: var(x) grows by 2²·0.001.
//! assert!((c.cov[0][0] - (0.01 + 4.0 * 0.001)).abs() < 1e-12);
//! # Ok::<(), chronomap_geometry::GeometryError>(())
//! ```
//!
//! [Stüde 2024]: M. Stüde, dissertation, Leibniz Universität Hannover, 2024.

use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use crate::GeometryError;
use crate::linalg::largest_eigenvalue;

/// A 3×3 matrix in row-major order (covariances and Jacobians of `(x, y, θ)`).
pub type Mat3 = [[f64; 3]; 3];

/// The 3×3 zero matrix.
pub const ZERO3: Mat3 = [[0.0; 3]; 3];

/// The 3×3 identity.
pub const IDENTITY3: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// `angle` wrapped into `(−π, π]`.
pub fn wrap_angle(angle: f64) -> f64 {
    let mut a = angle % (2.0 * PI);
    if a <= -PI {
        a += 2.0 * PI;
    } else if a > PI {
        a -= 2.0 * PI;
    }
    a
}

/// A pose in the plane: position (m) and heading (rad, counter-clockwise from `x`).
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose2 {
    /// Position `x` (m).
    pub x: f64,
    /// Position `y` (m).
    pub y: f64,
    /// Heading (rad), in `(−π, π]` for poses made by [`Pose2::new`] and the operations here.
    pub theta: f64,
}

impl Pose2 {
    /// The identity pose (the origin of a frame).
    pub const IDENTITY: Pose2 = Pose2 {
        x: 0.0,
        y: 0.0,
        theta: 0.0,
    };

    /// A checked pose: all three numbers finite; the heading is wrapped into `(−π, π]`.
    pub fn new(x: f64, y: f64, theta: f64) -> Result<Pose2, GeometryError> {
        let pose = Pose2 {
            x,
            y,
            theta: wrap_angle(theta),
        };
        pose.validate("pose")?;
        Ok(pose)
    }

    /// Checks that all three numbers are finite, naming `field` if not.
    pub fn validate(&self, field: &'static str) -> Result<(), GeometryError> {
        for value in [self.x, self.y, self.theta] {
            if !value.is_finite() {
                return Err(GeometryError::NotFinite { field, value });
            }
        }
        Ok(())
    }

    /// The composition `self ⊕ other`: `other` expressed in the frame `self` defines
    /// ([Stüde 2024] eq. (3.11)).
    /// [`compose`] with the heading wrapped.
    pub fn compose(&self, other: &Pose2) -> Pose2 {
        let [x, y, theta] = compose(self.to_array(), other.to_array());
        Pose2 {
            x,
            y,
            theta: wrap_angle(theta),
        }
    }

    /// `[x, y, θ]`.
    pub fn to_array(&self) -> [f64; 3] {
        [self.x, self.y, self.theta]
    }

    /// The pose `[x, y, θ]` as it is (unchecked, heading not wrapped).
    pub fn from_array(p: [f64; 3]) -> Pose2 {
        Pose2 {
            x: p[0],
            y: p[1],
            theta: p[2],
        }
    }

    /// The inverse `⊖self`, `π(T⁻¹)`: the pose of the reference frame seen from `self`.
    pub fn inverse(&self) -> Pose2 {
        let (s, c) = self.theta.sin_cos();
        Pose2 {
            x: -c * self.x - s * self.y,
            y: s * self.x - c * self.y,
            theta: wrap_angle(-self.theta),
        }
    }

    /// `⊖self ⊕ other`: `other` in the frame of `self`.
    pub fn between(&self, other: &Pose2) -> Pose2 {
        self.inverse().compose(other)
    }

    /// A point `[x, y]` given in this pose's frame, in the reference frame.
    pub fn transform_point(&self, p: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.theta.sin_cos();
        [self.x + c * p[0] - s * p[1], self.y + s * p[0] + c * p[1]]
    }

    /// The homogeneous transform `T` with `π(T) = self`.
    pub fn to_matrix(&self) -> Mat3 {
        let (s, c) = self.theta.sin_cos();
        [[c, -s, self.x], [s, c, self.y], [0.0, 0.0, 1.0]]
    }

    /// `π(T)`: the pose of a homogeneous transform (its rotation part read by `atan2`).
    pub fn from_matrix(t: &Mat3) -> Pose2 {
        Pose2 {
            x: t[0][2],
            y: t[1][2],
            theta: t[1][0].atan2(t[0][0]),
        }
    }

    /// Distance of the positions (m).
    pub fn distance(&self, other: &Pose2) -> f64 {
        (self.x - other.x).hypot(self.y - other.y)
    }
}

/// Robot-frame increments `(dx, dy, dθ)` composed, `a ⊕ b` ([Stüde 2024] eq. (3.11)), the
/// heading `a_θ + b_θ` left unwrapped (odometry integrated along a path keeps its turns).
pub fn compose(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    let (s, c) = a[2].sin_cos();
    [
        a[0] + c * b[0] - s * b[1],
        a[1] + s * b[0] + c * b[1],
        a[2] + b[2],
    ]
}

/// The motion from pose `a` to pose `b` in `a`'s frame, `⊖a ⊕ b` written out: the rotated
/// difference of positions and the heading difference wrapped into `[−π, π]` by
/// `atan2(sin, cos)` (the inverse of [`compose`]: `compose(a, between(a, b)) = b` up to 2π).
///
/// ```
/// use chronomap_geometry::se2::{between, compose};
///
/// let (a, b) = ([1.0, 2.0, 0.7], [-0.3, 0.5, -2.9]);
/// let c = compose(a, between(a, b));
/// assert!((c[0] - b[0]).abs() < 1e-12 && (c[1] - b[1]).abs() < 1e-12);
/// assert!((c[2] - b[2]).sin().abs() < 1e-12);
/// // The robot 1 m ahead of a pose facing +y is at (0, 1) in the map.
/// let d = between([0.0, 0.0, std::f64::consts::FRAC_PI_2], [0.0, 1.0, 0.0]);
/// assert!((d[0] - 1.0).abs() < 1e-12 && d[1].abs() < 1e-12);
/// ```
pub fn between(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    let (s, c) = a[2].sin_cos();
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let dyaw = b[2] - a[2];
    [
        c * dx + s * dy,
        -s * dx + c * dy,
        dyaw.sin().atan2(dyaw.cos()),
    ]
}

/// `J₁ = ∂(a ⊕ b)/∂a` ([Stüde 2024] eq. (3.12)).
pub fn jacobian_compose_first(a: &Pose2, b: &Pose2) -> Mat3 {
    let (s, c) = a.theta.sin_cos();
    [
        [1.0, 0.0, -s * b.x - c * b.y],
        [0.0, 1.0, c * b.x - s * b.y],
        [0.0, 0.0, 1.0],
    ]
}

/// `J₂ = ∂(a ⊕ b)/∂b` ([Stüde 2024] eq. (3.12)).
pub fn jacobian_compose_second(a: &Pose2) -> Mat3 {
    let (s, c) = a.theta.sin_cos();
    [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
}

/// `∂(⊖a)/∂a`.
pub fn jacobian_inverse(a: &Pose2) -> Mat3 {
    let (s, c) = a.theta.sin_cos();
    [
        [-c, -s, s * a.x - c * a.y],
        [s, -c, c * a.x + s * a.y],
        [0.0, 0.0, -1.0],
    ]
}

/// The matrix product `a·b`.
pub fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut out = ZERO3;
    for (i, row) in out.iter_mut().enumerate() {
        for (j, cell) in row.iter_mut().enumerate() {
            *cell = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    out
}

/// The transpose `aᵀ`.
pub fn transpose(a: &Mat3) -> Mat3 {
    let mut out = ZERO3;
    for (i, row) in a.iter().enumerate() {
        for (j, &v) in row.iter().enumerate() {
            out[j][i] = v;
        }
    }
    out
}

/// The sum `a + b`.
pub fn mat_add(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut out = *a;
    for (row, brow) in out.iter_mut().zip(b) {
        for (v, w) in row.iter_mut().zip(brow) {
            *v += w;
        }
    }
    out
}

/// `J Σ Jᵀ`, symmetrised (the first-order propagation of a covariance through `J`).
pub fn sandwich(j: &Mat3, sigma: &Mat3) -> Mat3 {
    let mut out = mat_mul(&mat_mul(j, sigma), &transpose(j));
    for i in 0..3 {
        for k in 0..i {
            let m = 0.5 * (out[i][k] + out[k][i]);
            out[i][k] = m;
            out[k][i] = m;
        }
    }
    out
}

/// The trace of a 3×3 matrix.
pub fn trace(a: &Mat3) -> f64 {
    a[0][0] + a[1][1] + a[2][2]
}

/// The determinant of a 3×3 matrix.
pub fn det3(a: &Mat3) -> f64 {
    a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
}

/// The inverse of a 3×3 matrix by its adjugate, or `None` where it is singular relative to
/// its scale (`|det| ≤ 1e-14·max|aᵢⱼ|³`).
pub fn inverse3(a: &Mat3) -> Option<Mat3> {
    let det = det3(a);
    let scale = a.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
    if !det.is_finite() || scale == 0.0 || det.abs() <= 1e-14 * scale.powi(3) {
        return None;
    }
    let cof =
        |r0: usize, r1: usize, c0: usize, c1: usize| a[r0][c0] * a[r1][c1] - a[r0][c1] * a[r1][c0];
    let adj = [
        [cof(1, 2, 1, 2), -cof(0, 2, 1, 2), cof(0, 1, 1, 2)],
        [-cof(1, 2, 0, 2), cof(0, 2, 0, 2), -cof(0, 1, 0, 2)],
        [cof(1, 2, 0, 1), -cof(0, 2, 0, 1), cof(0, 1, 0, 1)],
    ];
    let mut out = adj;
    for v in out.iter_mut().flatten() {
        *v /= det;
    }
    Some(out)
}

/// The 2×2 position block of a pose covariance, symmetrised.
pub fn position_block(cov: &Mat3) -> [[f64; 2]; 2] {
    let b = 0.5 * (cov[0][1] + cov[1][0]);
    [[cov[0][0], b], [b, cov[1][1]]]
}

/// The larger eigenvalue of the 2×2 position block of a pose covariance (m²): the `λ_max`
/// whose confidence ellipse sizes the loop search of [Stüde 2024] eq. (3.8), by
/// [`largest_eigenvalue`] of the symmetrised block ([`position_block`]). NaN where the block
/// is not finite or has a negative variance (not a covariance: [`validate_covariance`]
/// refuses it).
pub fn position_lambda_max(cov: &Mat3) -> f64 {
    largest_eigenvalue(position_block(cov)).unwrap_or(f64::NAN)
}

/// The 95 % quantile of the χ² distribution with two degrees of freedom: the 95 % confidence
/// ellipse of a position ([Stüde 2024] eq. (3.8)).
pub const CHI2_95_2D: f64 = 5.991;

/// The search radius of [Stüde 2024] eq. (3.8), `r = r_min + β·g_max(λ_max)` with
/// `g_max = 2√(5.991·λ_max)` the major axis of the 95 % confidence ellipse of a position
/// covariance whose larger eigenvalue is `λ_max` (m²; [`largest_eigenvalue`]). The callers
/// check the parameters and `λ_max ≥ 0`; a negative `λ_max` gives NaN.
///
/// ```
/// use chronomap_geometry::se2::search_radius;
///
/// assert_eq!(search_radius(3.0, 0.25, 0.0), 3.0);
/// // λ_max = 4 m²: 3 + 0.25 · 2√(5.991 · 4) ≈ 5.45 m.
/// assert!((search_radius(3.0, 0.25, 4.0) - (3.0 + 0.5 * (5.991f64 * 4.0).sqrt())).abs() < 1e-12);
/// ```
pub fn search_radius(r_min: f64, beta: f64, lambda_max: f64) -> f64 {
    r_min + beta * 2.0 * (CHI2_95_2D * lambda_max).sqrt()
}

/// Checks that `cov` is a covariance matrix: finite, symmetric (to `1e-9` relative), with all
/// principal minors non-negative (to round-off), i.e. positive semi-definite.
pub fn validate_covariance(field: &'static str, cov: &Mat3) -> Result<(), GeometryError> {
    let bad = |why| Err(GeometryError::NotCovariance { field, why });
    if cov.iter().flatten().any(|v| !v.is_finite()) {
        return bad("an entry is not finite");
    }
    let scale = cov.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
    let tol = 1e-9 * scale;
    for i in 0..3 {
        if cov[i][i] < 0.0 {
            return bad("a variance is negative");
        }
        for k in 0..i {
            if (cov[i][k] - cov[k][i]).abs() > tol {
                return bad("not symmetric");
            }
        }
    }
    for (i, k) in [(0, 1), (0, 2), (1, 2)] {
        if cov[i][i] * cov[k][k] - cov[i][k] * cov[k][i] < -tol * scale {
            return bad("not positive semi-definite (a 2×2 principal minor is negative)");
        }
    }
    if det3(cov) < -tol * scale * scale {
        return bad("not positive semi-definite (the determinant is negative)");
    }
    Ok(())
}

/// A normally distributed pose `N(mean, cov)` ([Stüde 2024] §3.3.3: the link-point poses
/// `⁽ⁱ⁾mᵢ` and relative map poses `⁽ⁱ⁾pᵢ₊₁`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct UncertainPose {
    /// The expected pose.
    pub mean: Pose2,
    /// Its covariance (`x, y` in m², `θ` in rad²).
    pub cov: Mat3,
}

impl UncertainPose {
    /// A checked uncertain pose (finite pose, covariance matrix per [`validate_covariance`]).
    pub fn new(mean: Pose2, cov: Mat3) -> Result<UncertainPose, GeometryError> {
        mean.validate("mean")?;
        validate_covariance("cov", &cov)?;
        Ok(UncertainPose {
            mean: Pose2 {
                theta: wrap_angle(mean.theta),
                ..mean
            },
            cov,
        })
    }

    /// A pose known exactly (zero covariance).
    pub fn exact(mean: Pose2) -> UncertainPose {
        UncertainPose { mean, cov: ZERO3 }
    }

    /// Whether the pose and every entry of its covariance are finite (a composition of finite
    /// poses can overflow to infinity, and then to NaN).
    pub fn is_finite(&self) -> bool {
        [self.mean.x, self.mean.y, self.mean.theta]
            .into_iter()
            .chain(self.cov.iter().flatten().copied())
            .all(f64::is_finite)
    }

    /// `self ⊕ other` for independent poses, with the first-order covariance
    /// `J₁ Σ_self J₁ᵀ + J₂ Σ_other J₂ᵀ` ([Stüde 2024] eqs. (3.11)–(3.13)).
    ///
    /// Eq. (3.13) as printed has `⁽ⁱ⁾Σᵢ₊₁` on both sides; the first term on the right is
    /// the covariance `ᵖΣᵢ₊₁` of the first operand, as eq. (3.12) shows.
    pub fn compose(&self, other: &UncertainPose) -> UncertainPose {
        let j1 = jacobian_compose_first(&self.mean, &other.mean);
        let j2 = jacobian_compose_second(&self.mean);
        UncertainPose {
            mean: self.mean.compose(&other.mean),
            cov: mat_add(&sandwich(&j1, &self.cov), &sandwich(&j2, &other.cov)),
        }
    }

    /// `⊖self` with the first-order covariance `J Σ Jᵀ`, `J = ∂(⊖a)/∂a`.
    pub fn inverse(&self) -> UncertainPose {
        UncertainPose {
            mean: self.mean.inverse(),
            cov: sandwich(&jacobian_inverse(&self.mean), &self.cov),
        }
    }

    /// `λ_max` of the position block of the covariance ([`position_lambda_max`]).
    pub fn lambda_max(&self) -> f64 {
        position_lambda_max(&self.cov)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64, t: f64) -> Pose2 {
        Pose2::new(x, y, t).unwrap()
    }

    #[test]
    fn a_composition_that_overflows_is_not_finite() {
        let step = UncertainPose::new(
            p(1e308, 0.0, 0.0),
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.01]],
        )
        .unwrap();
        assert!(step.is_finite());
        // 1e308 + 1e308 overflows the mean.
        let twice = step.compose(&step);
        assert_eq!(twice.mean.x, f64::INFINITY);
        assert!(!twice.is_finite());
        // A finite mean whose covariance overflows: the heading variance times a lever arm of
        // 1e200 m squared.
        let far = UncertainPose::new(
            p(0.0, 0.0, 0.0),
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.01]],
        )
        .unwrap();
        let lever = UncertainPose::exact(p(1e200, 0.0, 0.0));
        let moved = far.compose(&lever);
        assert_eq!(moved.mean.x, 1e200);
        assert!(moved.cov[1][1].is_infinite(), "{:?}", moved.cov);
        assert!(!moved.is_finite());
        assert!(UncertainPose::exact(p(3.0, 4.0, 0.5)).is_finite());
    }

    #[test]
    fn array_forms_compose_unwrapped_and_invert() {
        // (0, 0, 90°) ⊕ (1, 0, 0): one metre ahead of a pose facing +y is (0, 1).
        let q = PI / 2.0;
        let c = compose([0.0, 0.0, q], [1.0, 0.0, 0.0]);
        assert!(c[0].abs() < 1e-12 && (c[1] - 1.0).abs() < 1e-12 && c[2] == q);
        // Headings add without wrapping: 3 + 3 = 6.
        assert_eq!(compose([0.0, 0.0, 3.0], [0.0, 0.0, 3.0])[2], 6.0);
        // Pose2::compose gives the same numbers, the heading wrapped: 2.5 + 2 = 4.5 − 2π.
        let (a, b) = ([1.0, -2.0, 2.5], [0.3, 0.4, 2.0]);
        let p = Pose2::from_array(a).compose(&Pose2::from_array(b));
        let r = compose(a, b);
        assert_eq!((p.x, p.y), (r[0], r[1]));
        assert!((p.theta - (4.5 - 2.0 * PI)).abs() < 1e-12);
        // From (1, 0) facing +y to (1, 2) facing +x: 2 m ahead, a quarter turn clockwise.
        let d = between([1.0, 0.0, q], [1.0, 2.0, 0.0]);
        assert!((d[0] - 2.0).abs() < 1e-12 && d[1].abs() < 1e-12);
        assert!((d[2] + q).abs() < 1e-12);
    }

    #[test]
    fn search_radius_is_r_min_plus_beta_times_the_major_axis() {
        assert_eq!(search_radius(3.0, 0.25, 0.0), 3.0);
        let r = search_radius(3.0, 0.25, 1.0);
        assert!((r - (3.0 + 0.25 * 2.0 * 5.991f64.sqrt())).abs() < 1e-12);
        // [[4, 0, ·], [0, 1, ·], ·]: λ_max = 4, whatever the heading variance.
        let cov = [[4.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 100.0]];
        assert_eq!(position_lambda_max(&cov), 4.0);
        assert!(position_lambda_max(&[[-1.0, 0.0, 0.0], [0.0; 3], [0.0; 3]]).is_nan());
    }

    #[test]
    fn composition_is_the_product_of_homogeneous_transforms() {
        let a = p(1.0, -2.0, 0.7);
        let b = p(-0.3, 0.5, -2.9);
        let t = mat_mul(&a.to_matrix(), &b.to_matrix());
        let c = a.compose(&b);
        let d = Pose2::from_matrix(&t);
        assert!((c.x - d.x).abs() < 1e-12 && (c.y - d.y).abs() < 1e-12);
        assert!((c.theta - d.theta).abs() < 1e-12);
        // Heading wraps: 0.7 − 2.9 = −2.2 stays, −2.9 − 2.9 wraps to 2π − 5.8.
        assert!((c.theta + 2.2).abs() < 1e-12);
        assert!((b.compose(&b).theta - (2.0 * PI - 5.8)).abs() < 1e-12);
    }

    #[test]
    fn hand_computed_composition() {
        // (1, 0, 90°) ⊕ (2, 1, 0): rotate (2, 1) by 90° to (−1, 2), add (1, 0).
        let c = p(1.0, 0.0, PI / 2.0).compose(&p(2.0, 1.0, 0.0));
        assert!((c.x - 0.0).abs() < 1e-12 && (c.y - 2.0).abs() < 1e-12);
        assert!((c.theta - PI / 2.0).abs() < 1e-12);
        let inv = p(1.0, 0.0, PI / 2.0).inverse();
        // The origin seen from (1, 0) facing +y: one metre to its right, at (0, 1) of its frame.
        assert!((inv.x - 0.0).abs() < 1e-12 && (inv.y - 1.0).abs() < 1e-12);
        assert!((inv.theta + PI / 2.0).abs() < 1e-12);
    }

    #[test]
    fn jacobians_match_central_differences() {
        let a = p(0.4, -1.1, 2.3);
        let b = p(-1.7, 0.8, -0.6);
        let h = 1e-6;
        let num = |f: &dyn Fn(&Pose2) -> Pose2, at: &Pose2| {
            let mut j = ZERO3;
            for k in 0..3 {
                let mut plus = *at;
                let mut minus = *at;
                match k {
                    0 => (plus.x += h, minus.x -= h),
                    1 => (plus.y += h, minus.y -= h),
                    _ => (plus.theta += h, minus.theta -= h),
                };
                let (fp, fm) = (f(&plus), f(&minus));
                j[0][k] = (fp.x - fm.x) / (2.0 * h);
                j[1][k] = (fp.y - fm.y) / (2.0 * h);
                j[2][k] = wrap_angle(fp.theta - fm.theta) / (2.0 * h);
            }
            j
        };
        let cases = [
            (num(&|x| x.compose(&b), &a), jacobian_compose_first(&a, &b)),
            (num(&|x| a.compose(x), &b), jacobian_compose_second(&a)),
            (num(&|x| x.inverse(), &a), jacobian_inverse(&a)),
        ];
        for (n, j) in cases {
            for (rn, rj) in n.iter().zip(&j) {
                for (vn, vj) in rn.iter().zip(rj) {
                    assert!((vn - vj).abs() < 1e-8, "{n:?} vs {j:?}");
                }
            }
        }
    }

    #[test]
    fn inverse3_and_lambda_max() {
        let a = [[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 2.0]];
        let inv = inverse3(&a).unwrap();
        let id = mat_mul(&a, &inv);
        for (i, row) in id.iter().enumerate() {
            for (k, v) in row.iter().enumerate() {
                assert!((v - if i == k { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
        assert!(inverse3(&[[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 1.0]]).is_none());
        // [[4, 1], [1, 3]]: eigenvalues (7 ± √5)/2.
        assert!((position_lambda_max(&a) - (7.0 + 5f64.sqrt()) / 2.0).abs() < 1e-12);
    }

    #[test]
    fn bad_covariances_and_poses_are_refused() {
        assert!(Pose2::new(f64::NAN, 0.0, 0.0).is_err());
        let e = UncertainPose::new(
            Pose2::IDENTITY,
            [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]],
        );
        assert!(e.unwrap_err().to_string().contains("negative"));
        let e = UncertainPose::new(
            Pose2::IDENTITY,
            [[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        );
        assert!(e.unwrap_err().to_string().contains("semi-definite"));
        let e = UncertainPose::new(
            Pose2::IDENTITY,
            [[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        );
        assert!(e.unwrap_err().to_string().contains("symmetric"));
        let e = UncertainPose::new(
            Pose2::IDENTITY,
            [[f64::INFINITY, 0.0, 0.0], [0.0; 3], [0.0; 3]],
        );
        assert!(e.unwrap_err().to_string().starts_with("cov is not"));
    }
}
