//! Rigid transforms SE(2) and SE(3) as rotation matrices and translations (the form that
//! code generic over the dimension needs; [`crate::se2::Pose2`] is the `(x, y, θ)` form of
//! SE(2)), and their least-squares fit to point pairs by SVD (Kabsch / Umeyama without scale).
//!
//! ```
//! use chronomap_geometry::rigid::{Rigid, kabsch};
//!
//! // A quarter turn and a shift by (1, 0): (1, 0) ↦ (1, 1), (0, 1) ↦ (0, 0).
//! let t = Rigid::from_pose(1.0, 0.0, std::f64::consts::FRAC_PI_2);
//! let p = t.apply(&[1.0, 0.0]);
//! assert!((p[0] - 1.0).abs() < 1e-15 && (p[1] - 1.0).abs() < 1e-15);
//! // Three point pairs determine it again.
//! let source = [[0.0, 0.0], [1.0, 0.0], [0.0, 2.0]];
//! let target: Vec<[f64; 2]> = source.iter().map(|q| t.apply(q)).collect();
//! let (angle, shift) = kabsch(&source, &target)?.error_to(&t);
//! assert!(angle < 1e-12 && shift < 1e-12);
//! # Ok::<(), chronomap_geometry::GeometryError>(())
//! ```

use crate::GeometryError;
use crate::linalg::{cross, dot, sym_eigen};

/// Compile-time check that a dimension is 2 or 3 (the only ones [`Rigid`] implements): call
/// it as `const { assert_dim::<D>() }` in code generic over `D`.
pub const fn assert_dim<const D: usize>() {
    assert!(
        D == 2 || D == 3,
        "rigid transforms: 2-D and 3-D points only"
    );
}

/// A rigid transform `p ↦ R p + t` in `D` = 2 or 3 dimensions (SE(2), SE(3)). `rotation` is
/// row-major and orthonormal with determinant +1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rigid<const D: usize> {
    /// `R`, row-major.
    pub rotation: [[f64; D]; D],
    /// `t`.
    pub translation: [f64; D],
}

impl<const D: usize> Default for Rigid<D> {
    fn default() -> Self {
        Self::identity()
    }
}

impl<const D: usize> Rigid<D> {
    /// The identity.
    pub fn identity() -> Self {
        const { assert_dim::<D>() };
        Rigid {
            rotation: std::array::from_fn(|i| std::array::from_fn(|j| f64::from(u8::from(i == j)))),
            translation: [0.0; D],
        }
    }

    /// `R p + t`.
    pub fn apply(&self, p: &[f64; D]) -> [f64; D] {
        std::array::from_fn(|i| dot(&self.rotation[i], p) + self.translation[i])
    }

    /// `R v` (a direction, e.g. a normal).
    pub fn rotate(&self, v: &[f64; D]) -> [f64; D] {
        std::array::from_fn(|i| dot(&self.rotation[i], v))
    }

    /// `self ∘ other`: first `other`, then `self`.
    pub fn compose(&self, other: &Rigid<D>) -> Rigid<D> {
        Rigid {
            rotation: std::array::from_fn(|i| {
                std::array::from_fn(|j| {
                    (0..D)
                        .map(|k| self.rotation[i][k] * other.rotation[k][j])
                        .sum()
                })
            }),
            translation: self.apply(&other.translation),
        }
    }

    /// The inverse `p ↦ Rᵀ (p − t)`.
    pub fn inverse(&self) -> Rigid<D> {
        let rotation: [[f64; D]; D] =
            std::array::from_fn(|i| std::array::from_fn(|j| self.rotation[j][i]));
        let translation = std::array::from_fn(|i| -dot(&rotation[i], &self.translation));
        Rigid {
            rotation,
            translation,
        }
    }

    /// The rotation angle of `R` (rad, in [0, π]): `atan2(sin θ, cos θ)` with
    /// `cos θ = (tr R − 1)/2` and `sin θ = ‖vee(R − Rᵀ)‖/2` in 3-D, `|atan2(R₁₀, R₀₀)|` in 2-D.
    ///
    /// Not `acos((tr R − 1)/2)` alone: near θ = 0 its slope is unbounded, so a rotation that is
    /// orthonormal only to 1e-6 (a matrix printed with six digits) would read as 0.1° off.
    pub fn angle(&self) -> f64 {
        let r = &self.rotation;
        if D == 2 {
            r[1][0].atan2(r[0][0]).abs()
        } else {
            let trace: f64 = (0..D).map(|i| r[i][i]).sum();
            let axis = [r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]];
            let sin = 0.5 * dot(&axis, &axis).sqrt();
            sin.atan2((trace - 1.0) / 2.0)
        }
    }

    /// Length of the translation.
    pub fn translation_norm(&self) -> f64 {
        dot(&self.translation, &self.translation).sqrt()
    }

    /// Rotation error (rad) and translation error (length) of `self` against `truth`: the angle
    /// and translation of `truth⁻¹ ∘ self`.
    pub fn error_to(&self, truth: &Rigid<D>) -> (f64, f64) {
        let delta = truth.inverse().compose(self);
        (delta.angle(), delta.translation_norm())
    }

    /// Whether every entry is finite and `R` is orthonormal with determinant +1 to `1e-6`.
    pub fn is_valid(&self) -> bool {
        let r = &self.rotation;
        let finite = r
            .iter()
            .flatten()
            .chain(&self.translation)
            .all(|x| x.is_finite());
        let orthonormal = (0..D).all(|i| {
            (0..D).all(|j| {
                let e = dot(&r[i], &r[j]) - f64::from(u8::from(i == j));
                e.abs() < 1e-6
            })
        });
        finite && orthonormal && determinant(r) > 0.0
    }

    /// The exponential map of a small motion `x` (rotation part first): `[θ, tx, ty]` in 2-D,
    /// `[ωx, ωy, ωz, tx, ty, tz]` in 3-D, with `R = exp([ω]×)` (Rodrigues) and `t` as given.
    ///
    /// # Panics
    /// If `x` has fewer than 3 (2-D) or 6 (3-D) entries.
    pub fn from_twist(x: &[f64]) -> Rigid<D> {
        let mut out = Rigid::identity();
        if D == 2 {
            let (s, c) = x[0].sin_cos();
            out.rotation[0][0] = c;
            out.rotation[0][1] = -s;
            out.rotation[1][0] = s;
            out.rotation[1][1] = c;
            out.translation[0] = x[1];
            out.translation[1] = x[2];
        } else {
            let w = [x[0], x[1], x[2]];
            let theta = dot(&w, &w).sqrt();
            if theta > 0.0 {
                let k = [w[0] / theta, w[1] / theta, w[2] / theta];
                let (s, c) = theta.sin_cos();
                let kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
                for i in 0..3 {
                    for j in 0..3 {
                        let kk: f64 = (0..3).map(|m| kx[i][m] * kx[m][j]).sum();
                        out.rotation[i][j] += s * kx[i][j] + (1.0 - c) * kk;
                    }
                }
            }
            out.translation.copy_from_slice(&x[3..D + 3]);
        }
        out
    }
}

impl Rigid<2> {
    /// The pose `(x, y, yaw)` as a transform.
    pub fn from_pose(x: f64, y: f64, yaw: f64) -> Rigid<2> {
        Rigid::from_twist(&[yaw, x, y])
    }

    /// `(x, y, yaw)` of the transform.
    pub fn to_pose(&self) -> [f64; 3] {
        let r = &self.rotation;
        [
            self.translation[0],
            self.translation[1],
            r[1][0].atan2(r[0][0]),
        ]
    }
}

impl Rigid<3> {
    /// From a row-major homogeneous 4×4 matrix (the last row must be `0 0 0 1`, `R` a rotation).
    pub fn from_matrix4(m: &[[f64; 4]; 4]) -> Result<Rigid<3>, GeometryError> {
        let out = Rigid {
            rotation: std::array::from_fn(|i| std::array::from_fn(|j| m[i][j])),
            translation: std::array::from_fn(|i| m[i][3]),
        };
        let last_row_ok = m[3] == [0.0, 0.0, 0.0, 1.0];
        if !last_row_ok || !out.is_valid() {
            return Err(GeometryError::Degenerate(
                "the 4×4 matrix is not a rigid transform (rotation not orthonormal or last row not 0 0 0 1)",
            ));
        }
        Ok(out)
    }

    /// The row-major homogeneous 4×4 matrix.
    pub fn to_matrix4(&self) -> [[f64; 4]; 4] {
        let mut m = [[0.0; 4]; 4];
        for i in 0..3 {
            m[i][..3].copy_from_slice(&self.rotation[i]);
            m[i][3] = self.translation[i];
        }
        m[3][3] = 1.0;
        m
    }
}

/// Determinant of a 2×2 or 3×3 matrix.
fn determinant<const D: usize>(r: &[[f64; D]; D]) -> f64 {
    if D == 2 {
        r[0][0] * r[1][1] - r[0][1] * r[1][0]
    } else {
        dot(&[r[0][0], r[0][1], r[0][2]], &cross(&r[1], &r[2]))
    }
}

/// The least-squares rigid transform mapping `source[i]` onto `target[i]` (Arun, Huang &
/// Blostein 1987; Umeyama 1991 without scale): with centroids `p̄, q̄` and
/// `H = Σ (pᵢ − p̄)(qᵢ − q̄)ᵀ = U S Vᵀ`, `R = V diag(1, …, det(V Uᵀ)) Uᵀ` and `t = q̄ − R p̄`.
/// The coarse alignment of [Stüde 2024] §3.2.2 ("computed using singular-value decomposition").
///
/// The SVD is taken from the eigen-decomposition `HᵀH = V S² Vᵀ`, `uᵢ = H vᵢ / sᵢ` for the
/// `D − 1` largest singular values, and the last column of `U` completes a right-handed basis,
/// which makes the reflection correction `det(V Uᵀ)` equal `det V` and keeps the fit exact for
/// 3 points in 3-D (rank-2 `H`). Fewer than `D` points, or points on a line in 3-D (on a point in
/// 2-D), are [`GeometryError::Degenerate`].
pub fn kabsch<const D: usize>(
    source: &[[f64; D]],
    target: &[[f64; D]],
) -> Result<Rigid<D>, GeometryError> {
    const { assert_dim::<D>() };
    if source.len() != target.len() {
        return Err(GeometryError::Degenerate(
            "kabsch: source and target have different numbers of points",
        ));
    }
    if source.len() < D {
        return Err(GeometryError::TooFewPoints {
            what: "kabsch correspondences",
            got: source.len(),
            need: D,
        });
    }
    let n = source.len() as f64;
    let mean = |pts: &[[f64; D]]| -> [f64; D] {
        std::array::from_fn(|i| pts.iter().map(|p| p[i]).sum::<f64>() / n)
    };
    let (ps, qs) = (mean(source), mean(target));
    let mut h = [[0.0; D]; D];
    for (p, q) in source.iter().zip(target) {
        for i in 0..D {
            for j in 0..D {
                h[i][j] += (p[i] - ps[i]) * (q[j] - qs[j]);
            }
        }
    }
    let hth: [[f64; D]; D] =
        std::array::from_fn(|i| std::array::from_fn(|j| (0..D).map(|k| h[k][i] * h[k][j]).sum()));
    let (values, vectors) = sym_eigen(hth);
    // Descending singular values.
    let s: [f64; D] = std::array::from_fn(|k| values[D - 1 - k].max(0.0).sqrt());
    let v: [[f64; D]; D] = std::array::from_fn(|k| vectors[D - 1 - k]);
    if !(s[0] > 0.0) || !(s[D - 2] > 1e-9 * s[0]) || !s[0].is_finite() {
        return Err(GeometryError::Degenerate(
            "kabsch: the points are collinear (3-D) or coincide (2-D)",
        ));
    }
    let mut u = [[0.0; D]; D];
    for k in 0..D - 1 {
        u[k] = std::array::from_fn(|i| dot(&h[i], &v[k]) / s[k]);
    }
    if D == 2 {
        u[1][0] = -u[0][1];
        u[1][1] = u[0][0];
    } else {
        let c = cross(&u[0], &u[1]);
        let len = dot(&c, &c).sqrt();
        for i in 0..3 {
            u[2][i] = c[i] / len;
        }
    }
    // V as a matrix has the vectors v[k] as columns.
    let v_matrix: [[f64; D]; D] = std::array::from_fn(|i| std::array::from_fn(|k| v[k][i]));
    let sign = determinant(&v_matrix).signum();
    let rotation: [[f64; D]; D] = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            (0..D)
                .map(|k| {
                    let d = if k == D - 1 { sign } else { 1.0 };
                    v[k][i] * d * u[k][j]
                })
                .sum()
        })
    });
    let rp: [f64; D] = std::array::from_fn(|i| dot(&rotation[i], &ps));
    Ok(Rigid {
        rotation,
        translation: std::array::from_fn(|i| qs[i] - rp[i]),
    })
}

#[cfg(test)]
mod angle_tests {
    use super::*;

    #[test]
    fn the_angle_of_a_nearly_orthonormal_rotation_is_not_inflated() {
        // 0.06° about z, every entry then rounded to six decimals (as T_target_source.txt is
        // printed): the angle stays 0.06°, where acos of the trace would read about 0.07°.
        let t = 0.06f64.to_radians();
        let round = |v: f64| (v * 1e6).round() / 1e6;
        let (s, c) = t.sin_cos();
        let m = [
            [round(c), round(-s), 0.0, 0.0],
            [round(s), round(c), 0.0, 0.0],
            [0.0, 0.0, 1.0000004, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let r = Rigid::from_matrix4(&m).unwrap();
        assert!(
            (r.angle().to_degrees() - 0.06).abs() < 1e-3,
            "{}",
            r.angle().to_degrees()
        );
        let trace = m[0][0] + m[1][1] + m[2][2];
        let naive = ((trace - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees();
        assert!((naive - 0.06).abs() > 5e-3, "{naive}");
        // Exact rotations: 90° and 180° about x.
        let x90 = Rigid::<3> {
            rotation: [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
            translation: [0.0; 3],
        };
        assert!((x90.angle() - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        let x180 = x90.compose(&x90);
        assert!((x180.angle() - std::f64::consts::PI).abs() < 1e-15);
    }
}
