//! Weighted k-means: k-means++ seeding (Arthur & Vassilvitskii 2007, `D²·w` sampling) and
//! Lloyd iterations; HyT-KM of [Krajník 2019] §IV clusters hypertime this way.
//!
//! A cluster left empty by an assignment takes the row farthest from its centre among
//! clusters with more than one row, so every cluster keeps a row whenever there are at least
//! `k` distinct rows, and the inertia never increases.

use super::rows::Rows;
use super::{KMeansConfig, KMeansFit};
use chronomap_core::rng::{Xoshiro256StarStar, derive_seed};

/// Purpose tag of the seeds of k-means starts ("KMEANS").
const TAG_KMEANS: u64 = 0x4b4d_4541_4e53;

/// `‖a − b‖²`.
#[inline]
fn distance2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The nearest centre (the lowest index on ties) and the squared distance to it.
#[inline]
fn nearest(centres: &[f64], d: usize, x: &[f64]) -> (usize, f64) {
    let mut best = (0, f64::INFINITY);
    for (c, centre) in centres.chunks_exact(d).enumerate() {
        let d2 = distance2(x, centre);
        if d2 < best.1 {
            best = (c, d2);
        }
    }
    best
}

/// The first index whose running sum of `mass` exceeds `u`; the last index of positive mass
/// if rounding leaves none.
fn sample(mass: impl Iterator<Item = f64>, u: f64) -> Option<usize> {
    let mut cumulative = 0.0;
    let mut last = None;
    for (i, m) in mass.enumerate() {
        if m > 0.0 {
            cumulative += m;
            last = Some(i);
            if cumulative > u {
                return Some(i);
            }
        }
    }
    last
}

/// k-means++ centres (`k × dim`): the first row drawn with probability ∝ `w`, each next one
/// ∝ `w·D²` (`D` the distance to the nearest chosen centre). Needs at least `k` distinct rows
/// of positive weight; every centre is such a row and no two are equal.
pub(super) fn plus_plus(rows: &Rows<'_>, k: usize, rng: &mut Xoshiro256StarStar) -> Vec<f64> {
    let d = rows.dim;
    let mut chosen: Vec<usize> = Vec::with_capacity(k);
    let first = sample(
        (0..rows.n).map(|i| rows.weight(i)),
        rng.next_f64() * rows.total,
    )
    .expect("a row of positive weight");
    chosen.push(first);
    let mut d2 = vec![f64::INFINITY; rows.n];
    while chosen.len() < k {
        let last = rows.row(*chosen.last().expect("a centre"));
        let mut total = 0.0;
        for (i, e) in d2.iter_mut().enumerate() {
            let w = rows.weight(i);
            if w > 0.0 {
                *e = e.min(distance2(rows.row(i), last));
                total += w * *e;
            }
        }
        let mass = |i: usize| rows.weight(i) * d2[i];
        let next = if total > 0.0 && total.is_finite() {
            sample((0..rows.n).map(mass), rng.next_f64() * total)
        } else {
            None
        };
        let next = next.unwrap_or_else(|| {
            // Distances underflowed or overflowed: a uniform choice among the rows that
            // differ from every centre.
            let fresh: Vec<usize> = (0..rows.n)
                .filter(|&i| rows.weight(i) > 0.0)
                .filter(|&i| chosen.iter().all(|&j| rows.row(j) != rows.row(i)))
                .collect();
            fresh[rng.int_in(0, fresh.len() as u64 - 1) as usize]
        });
        chosen.push(next);
    }
    chosen
        .iter()
        .flat_map(|&i| rows.row(i).iter().copied())
        .take(k * d)
        .collect()
}

/// Per-cluster sums of one assignment.
struct Assignment {
    changed: bool,
    inertia: f64,
    /// `Σ w x` per cluster (`k × dim`).
    sums: Vec<f64>,
    /// `Σ w` per cluster.
    weights: Vec<f64>,
    /// Rows of positive weight per cluster.
    counts: Vec<usize>,
}

impl Assignment {
    fn new(k: usize, d: usize) -> Self {
        Assignment {
            changed: false,
            inertia: 0.0,
            sums: vec![0.0; k * d],
            weights: vec![0.0; k],
            counts: vec![0; k],
        }
    }

    fn add(&mut self, d: usize, c: usize, w: f64, x: &[f64], d2: f64) {
        if w > 0.0 {
            self.inertia += w * d2;
            self.weights[c] += w;
            self.counts[c] += 1;
            for (s, xj) in self.sums[c * d..(c + 1) * d].iter_mut().zip(x) {
                *s += w * xj;
            }
        }
    }

    fn merge(&mut self, other: &Assignment) {
        self.changed |= other.changed;
        self.inertia += other.inertia;
        self.sums
            .iter_mut()
            .zip(&other.sums)
            .for_each(|(a, b)| *a += b);
        self.weights
            .iter_mut()
            .zip(&other.weights)
            .for_each(|(a, b)| *a += b);
        self.counts
            .iter_mut()
            .zip(&other.counts)
            .for_each(|(a, b)| *a += b);
    }
}

/// Lloyd's iterations from `centres` (at most `max_iterations` centre updates); the inertia
/// after every assignment is pushed to `trace`.
pub(super) fn lloyd(
    rows: &Rows<'_>,
    mut centres: Vec<f64>,
    max_iterations: usize,
    mut trace: Option<&mut Vec<f64>>,
) -> KMeansFit {
    let d = rows.dim;
    let k = centres.len() / d;
    let mut labels = vec![usize::MAX; rows.n];
    let mut dist = vec![0.0; rows.n];
    let mut iterations = 0;
    loop {
        let parts = rows.map_chunks_mut(&mut labels, 1, &mut dist, 1, |start, len, lab, dst| {
            let mut a = Assignment::new(k, d);
            for r in 0..len {
                let i = start + r;
                let x = rows.row(i);
                let (c, d2) = nearest(&centres, d, x);
                a.changed |= lab[r] != c;
                lab[r] = c;
                dst[r] = d2;
                a.add(d, c, rows.weight(i), x, d2);
            }
            a
        });
        let mut a = Assignment::new(k, d);
        for p in &parts {
            a.merge(p);
        }
        if a.counts.contains(&0) {
            // Empty clusters take the farthest rows of clusters with more than one row.
            for c in 0..k {
                if a.counts[c] > 0 {
                    continue;
                }
                let far = (0..rows.n)
                    .filter(|&i| rows.weight(i) > 0.0 && dist[i] > 0.0)
                    .filter(|&i| a.counts[labels[i]] > 1)
                    .max_by(|&x, &y| dist[x].total_cmp(&dist[y]).then(y.cmp(&x)));
                let Some(i) = far else { continue };
                a.counts[labels[i]] -= 1;
                a.counts[c] += 1;
                labels[i] = c;
                dist[i] = 0.0;
                centres[c * d..(c + 1) * d].copy_from_slice(rows.row(i));
            }
            let mut fixed = Assignment::new(k, d);
            fixed.changed = true;
            for i in 0..rows.n {
                fixed.add(d, labels[i], rows.weight(i), rows.row(i), dist[i]);
            }
            a = fixed;
        }
        if let Some(t) = trace.as_deref_mut() {
            t.push(a.inertia);
        }
        if !a.changed || iterations >= max_iterations {
            return KMeansFit {
                centres,
                labels,
                inertia: a.inertia,
                iterations,
            };
        }
        for c in 0..k {
            if a.weights[c] > 0.0 {
                for j in 0..d {
                    centres[c * d + j] = a.sums[c * d + j] / a.weights[c];
                }
            }
        }
        iterations += 1;
    }
}

/// [`super::kmeans`] on checked rows: the start of lowest inertia.
pub(super) fn fit(rows: &Rows<'_>, config: &KMeansConfig) -> KMeansFit {
    let mut best: Option<KMeansFit> = None;
    for start in 0..config.starts {
        let seed = derive_seed(config.seed, TAG_KMEANS, start as u64, 0);
        let mut rng = Xoshiro256StarStar::seed_from_u64(seed);
        let centres = plus_plus(rows, config.clusters, &mut rng);
        let fit = lloyd(rows, centres, config.max_iterations, None);
        if best.as_ref().is_none_or(|b| fit.inertia < b.inertia) {
            best = Some(fit);
        }
    }
    best.expect("at least one start")
}
