//! Small dense linear algebra on fixed-size arrays: symmetric eigen-decomposition by cyclic
//! Jacobi rotations and Cholesky solves. Sizes are 2 to 6, so no allocation and no BLAS.

/// Eigen-decomposition of a symmetric `N×N` matrix by cyclic Jacobi rotations (Golub & Van Loan,
/// *Matrix Computations*, §8.5). Returns the eigenvalues in ascending order and the matching unit
/// eigenvectors (`vectors[k]` belongs to `values[k]`).
pub(crate) fn sym_eigen<const N: usize>(mut a: [[f64; N]; N]) -> ([f64; N], [[f64; N]; N]) {
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

/// Solves `A x = b` for the leading `n×n` block of a symmetric positive definite `A` by Cholesky
/// factorisation; `None` if the block is not positive definite (degenerate geometry).
pub(crate) fn solve_spd(a: &[[f64; 6]; 6], b: &[f64; 6], n: usize) -> Option<[f64; 6]> {
    let mut l = [[0.0; 6]; 6];
    let trace: f64 = (0..n).map(|i| a[i][i].abs()).sum();
    for i in 0..n {
        for j in 0..=i {
            let s = a[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if !(s > 1e-12 * trace) {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut y = [0.0; 6];
    for i in 0..n {
        y[i] = (b[i] - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
    }
    let mut x = [0.0; 6];
    for i in (0..n).rev() {
        x[i] = (y[i] - ((i + 1)..n).map(|k| l[k][i] * x[k]).sum::<f64>()) / l[i][i];
    }
    Some(x)
}

/// Dot product.
pub(crate) fn dot<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Dot product of slices of equal length.
pub(crate) fn dot_slice(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `a − b`.
pub(crate) fn sub<const D: usize>(a: &[f64; D], b: &[f64; D]) -> [f64; D] {
    std::array::from_fn(|i| a[i] - b[i])
}

/// Euclidean norm.
pub(crate) fn norm<const D: usize>(a: &[f64; D]) -> f64 {
    dot(a, a).sqrt()
}

/// Squared distance.
pub(crate) fn dist2<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// 3-D cross product.
pub(crate) fn cross(a: &[f64], b: &[f64]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

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
        a[1] = [2.0, 1.0, 0.0, 0.0, 0.0, 0.0];
        assert!(solve_spd(&a, &[1.0; 6], 2).is_none());
    }
}
