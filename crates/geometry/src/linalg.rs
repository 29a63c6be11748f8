//! Small dense linear algebra: vectors on fixed-size arrays, the symmetric eigen-decomposition
//! by cyclic Jacobi rotations, the closed-form largest eigenvalue of a 2×2 covariance, and one
//! Cholesky factorisation with its solve.
//!
//! Why not `faer` here: the sizes are 2 to 6 in the registration's inner loops (a Kabsch fit per
//! RANSAC hypothesis, a 3×3 or 6×6 normal system per ICP iteration), where `faer`'s matrices
//! and scratch buffers cost an allocation per call and its blocked kernels gain nothing; and
//! its rounding differs from these loops', which would change every registration and pose-graph
//! result in the last bits. `faer` is the oracle of the tests below instead.
//!
//! ```
//! use chronomap_geometry::linalg::{cholesky, cholesky_solve, sym_eigen, Pivot};
//!
//! // [[4, 2], [2, 3]] x = (0, −4) has x = (1, −2).
//! let mut a = [4.0, 2.0, 2.0, 3.0];
//! cholesky(&mut a, 2, Pivot::Diagonal(1e-13)).unwrap();
//! let mut x = [0.0, -4.0];
//! cholesky_solve(&a, 2, &mut x);
//! assert!((x[0] - 1.0).abs() < 1e-12 && (x[1] + 2.0).abs() < 1e-12);
//! // Its eigenvalues are (7 ∓ √17)/2, ascending.
//! let (values, _) = sym_eigen([[4.0, 2.0], [2.0, 3.0]]);
//! assert!((values[1] - (7.0 + 17f64.sqrt()) / 2.0).abs() < 1e-12);
//! ```

use crate::GeometryError;

/// Eigen-decomposition of a symmetric `N×N` matrix by cyclic Jacobi rotations (Golub & Van Loan,
/// *Matrix Computations*, §8.5). Returns the eigenvalues in ascending order and the matching unit
/// eigenvectors (`vectors[k]` belongs to `values[k]`).
pub fn sym_eigen<const N: usize>(mut a: [[f64; N]; N]) -> ([f64; N], [[f64; N]; N]) {
    let mut v = [[0.0; N]; N];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for _sweep in 0..64 {
        let off: f64 = (0..N)
            .flat_map(|p| ((p + 1)..N).map(move |q| (p, q)))
            .map(|(p, q)| a[p][q] * a[p][q])
            .sum();
        let scale: f64 = (0..N).map(|i| a[i][i] * a[i][i]).sum::<f64>() + off;
        if off <= 1e-30 * scale || off == 0.0 {
            break;
        }
        for p in 0..N {
            for q in (p + 1)..N {
                if a[p][q] == 0.0 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for row in a.iter_mut() {
                    let (akp, akq) = (row[p], row[q]);
                    row[p] = c * akp - s * akq;
                    row[q] = s * akp + c * akq;
                }
                for k in 0..N {
                    let (apk, aqk) = (a[p][k], a[q][k]);
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
                for row in v.iter_mut() {
                    let (vkp, vkq) = (row[p], row[q]);
                    row[p] = c * vkp - s * vkq;
                    row[q] = s * vkp + c * vkq;
                }
            }
        }
    }
    let mut order: [usize; N] = std::array::from_fn(|i| i);
    order.sort_by(|&i, &j| a[i][i].total_cmp(&a[j][j]));
    let values = std::array::from_fn(|k| a[order[k]][order[k]]);
    let vectors = std::array::from_fn(|k| std::array::from_fn(|r| v[r][order[k]]));
    (values, vectors)
}

/// The largest eigenvalue `λ_max` of a symmetric positive semi-definite 2×2 covariance, in
/// closed form: `(a + d)/2 + √((a − d)²/4 + b²)`.
///
/// # Errors
/// [`GeometryError::NotCovariance`] (field `covariance`) if it is not finite, not symmetric
/// (to 1e-9 relative) or has a negative variance.
pub fn largest_eigenvalue(cov: [[f64; 2]; 2]) -> Result<f64, GeometryError> {
    let bad = |why| {
        Err(GeometryError::NotCovariance {
            field: "covariance",
            why,
        })
    };
    let [[a, b], [c, d]] = cov;
    if ![a, b, c, d].iter().all(|v| v.is_finite()) {
        return bad("not finite");
    }
    if (b - c).abs() > 1e-9 * (a.abs() + d.abs()).max(f64::MIN_POSITIVE) {
        return bad("not symmetric");
    }
    if a < 0.0 || d < 0.0 {
        return bad("a variance is negative");
    }
    let half_trace = 0.5 * (a + d);
    let root = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    Ok(half_trace + root)
}

/// When [`cholesky`] accepts a pivot `d_j` (the diagonal of `L` squared, before its root).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pivot {
    /// `d_j > tol·|a_jj|`: each pivot against its own diagonal entry (the pose graph's dense
    /// normal equations, whose blocks have unrelated scales).
    Diagonal(f64),
    /// `d_j > tol·Σ|a_ii|`: every pivot against the trace (the registration's small systems,
    /// where a pivot small against the whole matrix means degenerate geometry).
    Trace(f64),
}

/// In-place Cholesky factorisation `A = L Lᵀ` of the symmetric positive definite `n×n`
/// row-major matrix in `a` (its lower triangle is read; `L` is written there, the strict upper
/// triangle is left as it was). Returns the index of the first pivot that is not finite or not
/// above the [`Pivot`] rule's bound.
///
/// # Panics
/// If `a` has fewer than `n²` entries.
pub fn cholesky(a: &mut [f64], n: usize, pivot: Pivot) -> Result<(), usize> {
    assert!(
        a.len() >= n * n,
        "cholesky: {} entries for n = {n}",
        a.len()
    );
    let trace: f64 = (0..n).map(|i| a[i * n + i].abs()).sum();
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        let bound = match pivot {
            Pivot::Diagonal(tol) => tol * a[j * n + j].abs().max(f64::MIN_POSITIVE),
            Pivot::Trace(tol) => tol * trace,
        };
        if !(d > bound) || !d.is_finite() {
            return Err(j);
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / d;
        }
    }
    Ok(())
}

/// Solves `L Lᵀ x = b` in place, `L` the factor [`cholesky`] left in `l` (`n×n`, row-major).
///
/// # Panics
/// If `l` has fewer than `n²` entries or `b` fewer than `n`.
pub fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i * n + k] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[k * n + i] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
}

/// Solves `A x = b` for the leading `n×n` block of a symmetric positive definite 6×6 `A`
/// ([`cholesky`] with [`Pivot::Trace`]`(1e-12)`); `None` if the block is not positive definite
/// (degenerate geometry). Entries of `x` beyond `n` are zero.
///
/// # Panics
/// If `n > 6`.
pub fn solve_spd(a: &[[f64; 6]; 6], b: &[f64; 6], n: usize) -> Option<[f64; 6]> {
    let mut l = [0.0; 36];
    for i in 0..n {
        l[i * n..i * n + n].copy_from_slice(&a[i][..n]);
    }
    cholesky(&mut l, n, Pivot::Trace(1e-12)).ok()?;
    let mut x = *b;
    x[n..].fill(0.0);
    cholesky_solve(&l, n, &mut x[..n]);
    Some(x)
}

/// Dot product.
pub fn dot<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Dot product of slices of equal length.
pub fn dot_slice(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `a − b`.
pub fn sub<const D: usize>(a: &[f64; D], b: &[f64; D]) -> [f64; D] {
    std::array::from_fn(|i| a[i] - b[i])
}

/// Euclidean norm.
pub fn norm<const D: usize>(a: &[f64; D]) -> f64 {
    dot(a, a).sqrt()
}

/// Squared distance.
pub fn dist2<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// 3-D cross product (of the first three entries).
pub fn cross(a: &[f64], b: &[f64]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_rng::Xoshiro256StarStar;
    use faer::Mat;
    use faer::linalg::solvers::Solve;

    #[test]
    fn jacobi_recovers_a_hand_made_spectrum() {
        // A = Q diag(1, 2, 5) Qᵀ with Q a rotation by 30° about z.
        let (s, c) = (0.5_f64, 3f64.sqrt() / 2.0);
        let q = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
        let d = [1.0, 2.0, 5.0];
        let a: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| (0..3).map(|k| q[i][k] * d[k] * q[j][k]).sum())
        });
        let (values, vectors) = sym_eigen(a);
        for k in 0..3 {
            assert!((values[k] - d[k]).abs() < 1e-12, "{values:?}");
            let column = [q[0][k], q[1][k], q[2][k]];
            assert!((dot(&vectors[k], &column).abs() - 1.0).abs() < 1e-12);
        }
    }

    /// A random symmetric positive definite `n×n` matrix `M Mᵀ + n·I`, row-major.
    fn random_spd(rng: &mut Xoshiro256StarStar, n: usize) -> Vec<f64> {
        let m: Vec<f64> = (0..n * n).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                a[i * n + j] = (0..n).map(|k| m[i * n + k] * m[j * n + k]).sum::<f64>()
                    + if i == j { n as f64 } else { 0.0 };
            }
        }
        a
    }

    #[test]
    fn jacobi_agrees_with_faer() {
        let mut rng = Xoshiro256StarStar::seed_from_u64(11);
        for _ in 0..50 {
            let a = random_spd(&mut rng, 6);
            let arr: [[f64; 6]; 6] = std::array::from_fn(|i| std::array::from_fn(|j| a[i * 6 + j]));
            let (values, vectors) = sym_eigen(arr);
            let m = Mat::<f64>::from_fn(6, 6, |i, j| a[i * 6 + j]);
            let oracle = m.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
            for k in 0..6 {
                assert!(
                    (values[k] - oracle[k]).abs() < 1e-12 * oracle[5],
                    "{values:?} {oracle:?}"
                );
                // A v = λ v.
                for i in 0..6 {
                    let av = dot(&arr[i], &vectors[k]);
                    assert!((av - values[k] * vectors[k][i]).abs() < 1e-11);
                }
            }
        }
    }

    #[test]
    fn closed_form_largest_eigenvalue_agrees_with_jacobi() {
        // [[4, 1], [1, 3]]: (7 + √5)/2.
        let l = largest_eigenvalue([[4.0, 1.0], [1.0, 3.0]]).unwrap();
        assert!((l - (7.0 + 5f64.sqrt()) / 2.0).abs() < 1e-15);
        // diag(9, 1) rotated by 30°: the eigenvalues stay 9 and 1.
        let (s, c) = 30f64.to_radians().sin_cos();
        let (a, d, b) = (9.0 * c * c + s * s, 9.0 * s * s + c * c, 8.0 * s * c);
        assert!((largest_eigenvalue([[a, b], [b, d]]).unwrap() - 9.0).abs() < 1e-12);
        let mut rng = Xoshiro256StarStar::seed_from_u64(3);
        for _ in 0..100 {
            let a = random_spd(&mut rng, 2);
            let l = largest_eigenvalue([[a[0], a[1]], [a[2], a[3]]]).unwrap();
            let (values, _) = sym_eigen([[a[0], a[1]], [a[2], a[3]]]);
            assert!((l - values[1]).abs() < 1e-13 * values[1]);
        }
        assert!(largest_eigenvalue([[1.0, 2.0], [0.0, 1.0]]).is_err());
        assert!(largest_eigenvalue([[-1.0, 0.0], [0.0, 1.0]]).is_err());
        assert_eq!(
            largest_eigenvalue([[f64::NAN, 0.0], [0.0, 1.0]])
                .unwrap_err()
                .to_string(),
            "covariance is not a covariance matrix: not finite"
        );
    }

    #[test]
    fn cholesky_solves_and_refuses_singular_blocks() {
        let mut a = [[0.0; 6]; 6];
        a[0] = [4.0, 2.0, 0.0, 0.0, 0.0, 0.0];
        a[1] = [2.0, 3.0, 0.0, 0.0, 0.0, 0.0];
        // x = (1, -2): b = (4 - 4, 2 - 6) = (0, -4).
        let x = solve_spd(&a, &[0.0, -4.0, 0.0, 0.0, 0.0, 0.0], 2).unwrap();
        assert!(
            (x[0] - 1.0).abs() < 1e-12 && (x[1] + 2.0).abs() < 1e-12,
            "{x:?}"
        );
        assert_eq!(&x[2..], &[0.0; 4]);
        a[1] = [2.0, 1.0, 0.0, 0.0, 0.0, 0.0];
        assert!(solve_spd(&a, &[1.0; 6], 2).is_none());
        // The second pivot of [[1, 1], [1, 1]] is 0: refused at index 1 by either rule.
        let mut s = [1.0, 1.0, 1.0, 1.0];
        assert_eq!(cholesky(&mut s, 2, Pivot::Diagonal(1e-13)), Err(1));
        let mut s = [1.0, 1.0, 1.0, 1.0];
        assert_eq!(cholesky(&mut s, 2, Pivot::Trace(1e-12)), Err(1));
        let mut s = [f64::NAN, 0.0, 0.0, 1.0];
        assert_eq!(cholesky(&mut s, 2, Pivot::Diagonal(1e-13)), Err(0));
    }

    #[test]
    fn cholesky_agrees_with_faer() {
        let mut rng = Xoshiro256StarStar::seed_from_u64(5);
        for n in [1, 2, 3, 6, 17, 40] {
            let a = random_spd(&mut rng, n);
            let b: Vec<f64> = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let mut l = a.clone();
            cholesky(&mut l, n, Pivot::Diagonal(1e-13)).unwrap();
            let mut x = b.clone();
            cholesky_solve(&l, n, &mut x);
            let m = Mat::<f64>::from_fn(n, n, |i, j| a[i * n + j]);
            let llt = m.llt(faer::Side::Lower).unwrap();
            let fl = llt.L();
            for i in 0..n {
                for j in 0..=i {
                    assert!((l[i * n + j] - fl[(i, j)]).abs() < 1e-12 * n as f64);
                }
            }
            let rhs = Mat::<f64>::from_fn(n, 1, |i, _| b[i]);
            let oracle = llt.solve(rhs.as_ref());
            for i in 0..n {
                assert!((x[i] - oracle[(i, 0)]).abs() < 1e-12, "{n}: {x:?}");
            }
        }
    }
}
