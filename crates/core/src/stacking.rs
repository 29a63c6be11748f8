//! Combining the predictions of several models: non-negative weights that sum to one, fitted
//! to predictions the models made of data they had not seen.
//!
//! This is stacking ([Wolpert 1992]; with non-negative weights, [Breiman 1996] "stacked
//! regressions"): given the out-of-sample predictions `P[i][j]` of candidate `i` for observation
//! `j` and the observed values `y[j]`, find
//!
//! ```text
//!     w* = argmin_{w ≥ 0, Σ w = 1}  (1/n) Σ_j (Σ_i w_i P[i][j] − y[j])²
//! ```
//!
//! The combination of probabilities is again a probability, the best single candidate is one of
//! the feasible points (so in-sample the combination is never worse than any candidate), and the
//! constraint keeps the weights from overfitting strongly correlated candidates (a FreMEn model
//! of order 8 and one of order 9) the way unconstrained least squares would.
//!
//! The problem is a convex quadratic programme over the probability simplex; it depends on the
//! data only through the Gram matrix `G = P Pᵀ / n` and `b = P y / n` ([`StackingProblem`]),
//! so many series (the edges of a map, the areas of a flat) can share one set of weights by
//! adding their problems. [`simplex_least_squares`] solves it by accelerated projected gradient
//! (FISTA, Beck & Teboulle 2009) with the Euclidean projection onto the simplex of Duchi et al.
//! (2008).
//!
//! ```
//! use chronomap_core::stacking::StackingProblem;
//!
//! // Two candidates, each right half of the time: the best combination is half of each.
//! let a = [1.0, 0.0, 1.0, 0.0];
//! let b = [0.0, 1.0, 0.0, 1.0];
//! let y = [0.5, 0.5, 0.5, 0.5];
//! let mut problem = StackingProblem::new(2);
//! problem.add(&[&a, &b], &y);
//! let w = problem.solve();
//! assert!((w[0] - 0.5).abs() < 1e-9 && (w[1] - 0.5).abs() < 1e-9);
//! ```
//!
//! [Wolpert 1992]: D. H. Wolpert, "Stacked generalization", Neural Networks 5(2), 1992.
//! [Breiman 1996]: L. Breiman, "Stacked regressions", Machine Learning 24(1), 1996.

use serde::{Deserialize, Serialize};

/// The sufficient statistics of a stacking problem: `G = Σ_j p_j p_jᵀ`, `b = Σ_j p_j y_j`,
/// `c = Σ_j y_j²` and the number of observations `n`, where `p_j` holds every candidate's
/// prediction of observation `j`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StackingProblem {
    candidates: usize,
    gram: Vec<f64>,
    rhs: Vec<f64>,
    squares: f64,
    count: usize,
}

impl StackingProblem {
    /// An empty problem over `candidates` candidates.
    pub fn new(candidates: usize) -> Self {
        StackingProblem {
            candidates,
            gram: vec![0.0; candidates * candidates],
            rhs: vec![0.0; candidates],
            squares: 0.0,
            count: 0,
        }
    }

    /// Number of candidates.
    pub fn candidates(&self) -> usize {
        self.candidates
    }

    /// Number of observations added.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Adds observations `values` and every candidate's predictions of them
    /// (`predictions[i][j]`: candidate `i`, observation `j`).
    ///
    /// # Panics
    /// If the number of prediction rows is not the number of candidates, or a row's length
    /// differs from `values`.
    pub fn add(&mut self, predictions: &[&[f64]], values: &[f64]) {
        let k = self.candidates;
        assert_eq!(predictions.len(), k, "one row of predictions per candidate");
        for row in predictions {
            assert_eq!(row.len(), values.len(), "one prediction per observation");
        }
        for (i, pi) in predictions.iter().enumerate() {
            self.rhs[i] += dot(pi, values);
            for (j, pj) in predictions.iter().enumerate().skip(i) {
                let g = dot(pi, pj);
                self.gram[i * k + j] += g;
                if j != i {
                    self.gram[j * k + i] += g;
                }
            }
        }
        self.squares += dot(values, values);
        self.count += values.len();
    }

    /// Adds the statistics of another problem over the same candidates (pooling series).
    ///
    /// # Panics
    /// If the problems have different numbers of candidates.
    pub fn merge(&mut self, other: &StackingProblem) {
        assert_eq!(self.candidates, other.candidates, "same candidates");
        for (a, b) in self.gram.iter_mut().zip(&other.gram) {
            *a += b;
        }
        for (a, b) in self.rhs.iter_mut().zip(&other.rhs) {
            *a += b;
        }
        self.squares += other.squares;
        self.count += other.count;
    }

    /// Mean squared error of the combination with `weights` on the observations added
    /// (NaN if none were added).
    pub fn error(&self, weights: &[f64]) -> f64 {
        let k = self.candidates;
        let mut quadratic = 0.0;
        for i in 0..k {
            for j in 0..k {
                quadratic += weights[i] * self.gram[i * k + j] * weights[j];
            }
        }
        let linear = dot(weights, &self.rhs);
        ((quadratic - 2.0 * linear + self.squares) / self.count as f64).max(0.0)
    }

    /// Whether candidates `i` and `j` made the same predictions of every observation added
    /// (to rounding): `‖p_i − p_j‖² = G_ii + G_jj − 2 G_ij` is zero exactly when the rows agree,
    /// and rows that agree bit for bit give bit-equal statistics.
    pub fn predicted_alike(&self, i: usize, j: usize) -> bool {
        let k = self.candidates;
        let g = |a: usize, b: usize| self.gram[a * k + b];
        g(i, i) == g(j, j) && g(i, j) == g(i, i) && self.rhs[i] == self.rhs[j]
    }

    /// Mean squared error of candidate `i` alone.
    pub fn candidate_error(&self, i: usize) -> f64 {
        let mut w = vec![0.0; self.candidates];
        w[i] = 1.0;
        self.error(&w)
    }

    /// The weights `w ≥ 0`, `Σ w = 1` with the least mean squared error (see the
    /// [module docs](self)). With no observations, all weight on the first candidate.
    pub fn solve(&self) -> Vec<f64> {
        if self.count == 0 || self.candidates == 0 {
            let mut w = vec![0.0; self.candidates];
            if let Some(first) = w.first_mut() {
                *first = 1.0;
            }
            return w;
        }
        let n = self.count as f64;
        let gram: Vec<f64> = self.gram.iter().map(|g| g / n).collect();
        let rhs: Vec<f64> = self.rhs.iter().map(|b| b / n).collect();
        simplex_least_squares(&gram, &rhs, self.candidates)
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Minimises `wᵀ G w − 2 bᵀ w` over the probability simplex (`w ≥ 0`, `Σ w = 1`) for a
/// symmetric positive semi-definite `k × k` matrix `G` (row-major) — the stacking problem of
/// the [module docs](self) — by FISTA with projection onto the simplex. Ties between equally
/// good combinations are broken towards the start point (equal weights).
///
/// # Panics
/// If `gram` is not `k × k` or `rhs` not of length `k`.
pub fn simplex_least_squares(gram: &[f64], rhs: &[f64], k: usize) -> Vec<f64> {
    assert_eq!(gram.len(), k * k, "gram is k × k");
    assert_eq!(rhs.len(), k, "rhs has k entries");
    if k == 0 {
        return Vec::new();
    }
    // The gradient 2(Gw − b) is Lipschitz with constant 2·λmax(G) ≤ 2·max row sum of |G|.
    let lipschitz = 2.0
        * (0..k)
            .map(|i| {
                gram[i * k..(i + 1) * k]
                    .iter()
                    .map(|g| g.abs())
                    .sum::<f64>()
            })
            .fold(0.0, f64::max);
    if !(lipschitz > 0.0 && lipschitz.is_finite()) {
        return vec![1.0 / k as f64; k];
    }
    let step = 1.0 / lipschitz;
    let objective = |w: &[f64]| -> f64 {
        let mut q = 0.0;
        for i in 0..k {
            let gi = &gram[i * k..(i + 1) * k];
            q += w[i] * (dot(gi, w) - 2.0 * rhs[i]);
        }
        q
    };
    let mut w = vec![1.0 / k as f64; k];
    let mut momentum_point = w.clone();
    let mut t = 1.0_f64;
    let mut best = (objective(&w), w.clone());
    let mut gradient = vec![0.0; k];
    for _ in 0..MAX_ITERATIONS {
        for i in 0..k {
            gradient[i] = 2.0 * (dot(&gram[i * k..(i + 1) * k], &momentum_point) - rhs[i]);
        }
        let mut next: Vec<f64> = momentum_point
            .iter()
            .zip(&gradient)
            .map(|(y, g)| y - step * g)
            .collect();
        project_onto_simplex(&mut next);
        let t_next = (1.0 + (1.0 + 4.0 * t * t).sqrt()) / 2.0;
        let change: f64 = next.iter().zip(&w).map(|(a, b)| (a - b).abs()).sum();
        for i in 0..k {
            momentum_point[i] = next[i] + (t - 1.0) / t_next * (next[i] - w[i]);
        }
        w = next;
        t = t_next;
        let value = objective(&w);
        if value < best.0 {
            best = (value, w.clone());
        } else if value > best.0 + 1e-15 {
            // Restart the momentum when the objective goes up (O'Donoghue & Candès 2015).
            momentum_point.clone_from(&w);
            t = 1.0;
        }
        if change < 1e-13 {
            break;
        }
    }
    best.1
}

/// Iterations of [`simplex_least_squares`] at most (convergence usually takes a few hundred).
const MAX_ITERATIONS: usize = 20_000;

/// Euclidean projection of `v` onto the probability simplex (Duchi, Shalev-Shwartz, Singer,
/// Chandra 2008, Fig. 1), in place.
pub fn project_onto_simplex(v: &mut [f64]) {
    if v.is_empty() {
        return;
    }
    let mut sorted = v.to_vec();
    sorted.sort_by(|a, b| b.total_cmp(a));
    let mut cumulative = 0.0;
    let mut theta = 0.0;
    for (i, &u) in sorted.iter().enumerate() {
        cumulative += u;
        let candidate = (cumulative - 1.0) / (i + 1) as f64;
        if u - candidate > 0.0 {
            theta = candidate;
        }
    }
    for x in v.iter_mut() {
        *x = (*x - theta).max(0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Xoshiro256StarStar;

    /// The exact minimiser by enumeration of supports (the oracle): on each support S, the
    /// equality-constrained minimiser solves the KKT system [2G_SS 1; 1ᵀ 0][w; μ] = [2b_S; 1];
    /// the best feasible (w ≥ 0) one over all supports is the answer.
    fn brute_force(gram: &[f64], rhs: &[f64], k: usize) -> (f64, Vec<f64>) {
        let objective = |w: &[f64]| -> f64 {
            (0..k)
                .map(|i| {
                    w[i] * ((0..k).map(|j| gram[i * k + j] * w[j]).sum::<f64>() - 2.0 * rhs[i])
                })
                .sum()
        };
        let mut best = (f64::INFINITY, vec![]);
        for mask in 1u32..(1 << k) {
            let s: Vec<usize> = (0..k).filter(|i| mask & (1 << i) != 0).collect();
            let m = s.len() + 1;
            let mut a = vec![0.0; m * m];
            let mut r = vec![0.0; m];
            for (x, &i) in s.iter().enumerate() {
                for (y, &j) in s.iter().enumerate() {
                    a[x * m + y] = 2.0 * gram[i * k + j];
                }
                a[x * m + m - 1] = 1.0;
                a[(m - 1) * m + x] = 1.0;
                r[x] = 2.0 * rhs[i];
            }
            r[m - 1] = 1.0;
            let Some(sol) = gauss(a, r, m) else { continue };
            if sol[..s.len()].iter().any(|&x| x < -1e-12) {
                continue;
            }
            let mut w = vec![0.0; k];
            for (x, &i) in s.iter().enumerate() {
                w[i] = sol[x].max(0.0);
            }
            let value = objective(&w);
            if value < best.0 {
                best = (value, w);
            }
        }
        best
    }

    fn gauss(mut a: Vec<f64>, mut r: Vec<f64>, m: usize) -> Option<Vec<f64>> {
        for c in 0..m {
            let p = (c..m).max_by(|&x, &y| a[x * m + c].abs().total_cmp(&a[y * m + c].abs()))?;
            if a[p * m + c].abs() < 1e-12 {
                return None;
            }
            for j in 0..m {
                a.swap(c * m + j, p * m + j);
            }
            r.swap(c, p);
            for row in 0..m {
                if row != c {
                    let f = a[row * m + c] / a[c * m + c];
                    for j in 0..m {
                        a[row * m + j] -= f * a[c * m + j];
                    }
                    r[row] -= f * r[c];
                }
            }
        }
        Some((0..m).map(|i| r[i] / a[i * m + i]).collect())
    }

    #[test]
    fn candidates_that_predict_alike_are_recognised() {
        let a = [0.2, 0.7, 0.1];
        let b = [0.3, 0.6, 0.1];
        let mut problem = StackingProblem::new(3);
        problem.add(&[&a, &b, &a], &[0.0, 1.0, 0.0]);
        assert!(problem.predicted_alike(0, 2) && problem.predicted_alike(2, 0));
        assert!(!problem.predicted_alike(0, 1) && !problem.predicted_alike(1, 2));
        // Equal norms and targets are not enough: the rows must agree.
        let c = [0.7, 0.2, 0.1];
        let mut mirrored = StackingProblem::new(2);
        mirrored.add(&[&a, &c], &[0.5, 0.5, 0.0]);
        assert!(!mirrored.predicted_alike(0, 1));
    }

    #[test]
    fn weights_match_the_exact_minimiser_found_by_enumerating_supports() {
        let mut rng = Xoshiro256StarStar::seed_from_u64(7);
        for case in 0..60 {
            let k = 2 + case % 6;
            let n = 40;
            let y: Vec<f64> = (0..n)
                .map(|_| f64::from(u8::from(rng.bernoulli(0.3))))
                .collect();
            let rows: Vec<Vec<f64>> = (0..k)
                .map(|i| {
                    y.iter()
                        .map(|&v| {
                            let noise = rng.next_f64();
                            (0.2 * i as f64 * v + 0.6 * noise).clamp(0.0, 1.0)
                        })
                        .collect()
                })
                .collect();
            let refs: Vec<&[f64]> = rows.iter().map(Vec::as_slice).collect();
            let mut problem = StackingProblem::new(k);
            problem.add(&refs, &y);
            let w = problem.solve();
            let gram: Vec<f64> = problem.gram.iter().map(|g| g / n as f64).collect();
            let rhs: Vec<f64> = problem.rhs.iter().map(|b| b / n as f64).collect();
            let (_, exact) = brute_force(&gram, &rhs, k);
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            assert!(w.iter().all(|&x| x >= 0.0));
            let (ours, theirs) = (problem.error(&w), problem.error(&exact));
            assert!(
                ours <= theirs + 1e-10,
                "case {case}: error {ours} vs exact {theirs} ({w:?} vs {exact:?})"
            );
            // Never worse than the best single candidate.
            for i in 0..k {
                assert!(ours <= problem.candidate_error(i) + 1e-12);
            }
        }
    }

    #[test]
    fn the_error_of_the_statistics_is_the_direct_mean_squared_error() {
        let a = [0.1, 0.9, 0.4];
        let b = [0.3, 0.2, 0.8];
        let y = [0.0, 1.0, 1.0];
        let mut problem = StackingProblem::new(2);
        problem.add(&[&a[..2], &b[..2]], &y[..2]);
        let mut rest = StackingProblem::new(2);
        rest.add(&[&a[2..], &b[2..]], &y[2..]);
        problem.merge(&rest);
        let w = [0.25, 0.75];
        let direct: f64 = (0..3)
            .map(|j| (w[0] * a[j] + w[1] * b[j] - y[j]).powi(2))
            .sum::<f64>()
            / 3.0;
        assert!((problem.error(&w) - direct).abs() < 1e-15);
        assert_eq!(problem.count(), 3);
    }

    #[test]
    fn projection_onto_the_simplex_of_known_points() {
        let mut v = [0.5, 0.5];
        project_onto_simplex(&mut v);
        assert_eq!(v, [0.5, 0.5]);
        let mut v = [2.0, 0.0, -1.0];
        project_onto_simplex(&mut v);
        assert_eq!(v, [1.0, 0.0, 0.0]);
        // (1, 1, 0) → subtract θ = 0.5 from the two largest.
        let mut v = [1.0, 1.0, 0.0];
        project_onto_simplex(&mut v);
        assert_eq!(v, [0.5, 0.5, 0.0]);
    }
}
