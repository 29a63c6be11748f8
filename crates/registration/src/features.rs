//! Local geometry: normals by PCA, Fast Point Feature Histograms [Rusu 2009] and their
//! persistence over several scales ([Stüde 2024] §3.2.2).
//!
//! [Rusu 2009]: R. B. Rusu, N. Blodow, M. Beetz, "Fast Point Feature Histograms (FPFH) for 3D
//! registration", ICRA 2009.

use crate::RegistrationError;
use crate::kdtree::KdTree;
use chronomap_geometry::linalg::{cross, dot, dot_slice, norm, sub, sym_eigen};

/// Bins per angular feature; a histogram has three features, [`FEATURE_LEN`] bins.
pub const BINS: usize = 11;
/// Length of an FPFH histogram (3 × 11, [Rusu 2009] §IV).
pub const FEATURE_LEN: usize = 3 * BINS;

/// A feature histogram: three sub-histograms of [`BINS`] bins, each summing to 100 (or all zero
/// for a point without a valid neighbourhood).
pub type Histogram = [f64; FEATURE_LEN];

/// Unit normals by principal component analysis of each point's neighbourhood (the `k` nearest
/// within `radius`, the point included): the eigenvector of the smallest eigenvalue of the
/// neighbourhood's covariance (Hoppe et al. 1992), flipped to face `viewpoint` (the sensor), so
/// that `n · (viewpoint − p) ≥ 0`. Points with fewer than `D` neighbours get the zero vector,
/// which the features and point-to-plane ICP treat as "no normal".
pub fn estimate_normals<const D: usize>(
    points: &[[f64; D]],
    tree: &KdTree<D>,
    k: usize,
    radius: f64,
    viewpoint: [f64; D],
) -> Result<Vec<[f64; D]>, RegistrationError> {
    same_len("normals: k-d tree", tree.len(), points.len())?;
    let mut nn = Vec::with_capacity(k.min(1 << 16));
    Ok(points
        .iter()
        .map(|p| {
            tree.nearest_within(p, k, radius * radius, &mut nn);
            if nn.len() < D {
                return [0.0; D];
            }
            let m = nn.len() as f64;
            let mean: [f64; D] =
                std::array::from_fn(|a| nn.iter().map(|&(i, _)| points[i][a]).sum::<f64>() / m);
            let mut cov = [[0.0; D]; D];
            for &(i, _) in &nn {
                let d = sub(&points[i], &mean);
                for a in 0..D {
                    for b in 0..D {
                        cov[a][b] += d[a] * d[b] / m;
                    }
                }
            }
            let (values, vectors) = sym_eigen(cov);
            if !(values[D - 1] > 0.0) {
                return [0.0; D];
            }
            let mut n = vectors[0];
            if dot(&n, &sub(&viewpoint, p)) < 0.0 {
                n = n.map(|x| -x);
            }
            n
        })
        .collect())
}

/// The k-d tree or the normals must belong to the points.
fn same_len(what: &'static str, got: usize, points: usize) -> Result<(), RegistrationError> {
    if got == points {
        Ok(())
    } else {
        Err(RegistrationError::Mismatch { what, got, points })
    }
}

/// The three angular features of a point pair ([Rusu 2009] eq. (1)–(2), with PCL's choice of
/// the source point: the one whose normal makes the smaller angle with the connecting line; on a
/// tie, the one that makes `φ ≥ 0`).
///
/// 3-D: Darboux frame `u = n_s`, `v = u × d̂`, `w = u × v` and
/// `(θ, α, φ) = (atan2(w·n_t, u·n_t), v·n_t, u·d̂)`.
///
/// 2-D analogue (this crate's definition): the frame is `u = n_s` and its left perpendicular
/// `v = (−u_y, u_x)` (a rotation keeps it right-handed); `θ = atan2(v·n_t, u·n_t)` is the angle
/// from the source normal to the target normal, `φ = u·d̂` as in 3-D, and `α = n_t·d̂`, the
/// target normal against the connecting line, which replaces the out-of-plane component that 2-D
/// lacks and resolves the sign of the angle of `d̂` that `φ` leaves open. All three are invariant
/// to rotations and translations of the plane. `None` for coincident points or undefined normals.
pub(crate) fn pair_features<const D: usize>(
    p1: &[f64; D],
    n1: &[f64; D],
    p2: &[f64; D],
    n2: &[f64; D],
) -> Option<[f64; 3]> {
    let mut d = sub(p2, p1);
    let len = norm(&d);
    if len == 0.0 || dot(n1, n1) == 0.0 || dot(n2, n2) == 0.0 {
        return None;
    }
    let a1 = dot(n1, &d) / len;
    let a2 = dot(n2, &d) / len;
    // PCL's rule, with near ties (parallel normals on a plane, where rounding would decide)
    // broken towards φ ≥ 0 so that the choice does not depend on the frame.
    let (g1, g2) = (a1.abs().acos(), a2.abs().acos());
    let swap = if (g1 - g2).abs() <= 1e-9 {
        a1 < 0.0 && -a2 >= 0.0
    } else {
        g1 > g2
    };
    let (ns, nt, phi) = if swap {
        d = d.map(|x| -x);
        (n2, n1, -a2)
    } else {
        (n1, n2, a1)
    };
    if D == 3 {
        let v = cross(&d, ns);
        let vn = norm(&v);
        if vn == 0.0 {
            return None;
        }
        let v = v.map(|x| x / vn);
        let w = cross(ns, &v);
        let theta = dot_slice(&w, nt).atan2(dot(ns, nt));
        Some([theta, dot_slice(&v, nt), phi])
    } else {
        let v = [-ns[1], ns[0]];
        let (nt0, nt1) = (nt[0], nt[1]);
        let theta = (v[0] * nt0 + v[1] * nt1).atan2(ns[0] * nt0 + ns[1] * nt1);
        let alpha = dot(nt, &d) / len;
        Some([theta, alpha, phi])
    }
}

/// Simplified Point Feature Histograms ([Rusu 2009] §IV): for each point, the features of the
/// pairs it forms with its neighbours (the `max_neighbours` nearest within `radius`), binned
/// into 11 bins each (`θ ∈ [−π, π]`, `α, φ ∈ [−1, 1]`), every sub-histogram normalised to sum
/// to 100. Also returns each point's neighbour lists (index, distance).
fn spfh<const D: usize>(
    points: &[[f64; D]],
    normals: &[[f64; D]],
    tree: &KdTree<D>,
    radius: f64,
    max_neighbours: usize,
) -> (Vec<Histogram>, Vec<Vec<(usize, f64)>>) {
    let mut nn = Vec::new();
    let mut hists = Vec::with_capacity(points.len());
    let mut neighbours = Vec::with_capacity(points.len());
    for (i, p) in points.iter().enumerate() {
        tree.nearest_within(p, max_neighbours + 1, radius * radius, &mut nn);
        let mut h = [0.0; FEATURE_LEN];
        let mut count = 0.0;
        let mut list = Vec::with_capacity(nn.len());
        for &(j, d2) in &nn {
            if j == i {
                continue;
            }
            list.push((j, d2.sqrt()));
            if let Some(f) = pair_features(p, &normals[i], &points[j], &normals[j]) {
                let bin = |x: f64, lo: f64, hi: f64| {
                    ((BINS as f64 * (x - lo) / (hi - lo)).floor() as isize)
                        .clamp(0, BINS as isize - 1) as usize
                };
                h[bin(f[0], -std::f64::consts::PI, std::f64::consts::PI)] += 1.0;
                h[BINS + bin(f[1], -1.0, 1.0)] += 1.0;
                h[2 * BINS + bin(f[2], -1.0, 1.0)] += 1.0;
                count += 1.0;
            }
        }
        if count > 0.0 {
            h.iter_mut().for_each(|x| *x *= 100.0 / count);
        }
        hists.push(h);
        neighbours.push(list);
    }
    (hists, neighbours)
}

/// Normalises each of the three sub-histograms to sum to 100 (zero ones stay zero).
fn normalise(h: &mut Histogram) {
    for part in h.chunks_mut(BINS) {
        let s: f64 = part.iter().sum();
        if s > 0.0 {
            part.iter_mut().for_each(|x| *x *= 100.0 / s);
        }
    }
}

/// Fast Point Feature Histograms ([Rusu 2009] eq. (3)):
/// `FPFH(p) = SPFH(p) + (1/k) Σₖ (1/ωₖ) SPFH(pₖ)` over the neighbours `pₖ` within `radius`
/// (at most `max_neighbours`), `ωₖ = ‖p − pₖ‖`. The weighted neighbour sum is normalised per
/// sub-histogram to 100 (which absorbs the `1/k`), as PCL and Open3D do, so a histogram's three
/// parts each sum to 200 (or 100 for an isolated point).
pub fn fpfh<const D: usize>(
    points: &[[f64; D]],
    normals: &[[f64; D]],
    tree: &KdTree<D>,
    radius: f64,
    max_neighbours: usize,
) -> Result<Vec<Histogram>, RegistrationError> {
    same_len("fpfh: k-d tree", tree.len(), points.len())?;
    same_len("fpfh: normals", normals.len(), points.len())?;
    let (s, neighbours) = spfh(points, normals, tree, radius, max_neighbours);
    Ok((0..points.len())
        .map(|i| {
            let mut h = [0.0; FEATURE_LEN];
            for &(j, w) in &neighbours[i] {
                if w > 0.0 {
                    for (b, x) in h.iter_mut().enumerate() {
                        *x += s[j][b] / w;
                    }
                }
            }
            normalise(&mut h);
            for (b, x) in h.iter_mut().enumerate() {
                *x += s[i][b];
            }
            h
        })
        .collect())
}

/// χ² distance between histograms, `Σ (aᵢ − bᵢ)² / (aᵢ + bᵢ)` over bins with `aᵢ + bᵢ > 0`, the
/// metric of the persistence analysis ([Stüde 2024] §3.2.2).
pub fn chi_squared(a: &Histogram, b: &Histogram) -> f64 {
    a.iter()
        .zip(b)
        .filter(|(x, y)| *x + *y > 0.0)
        .map(|(x, y)| (x - y) * (x - y) / (x + y))
        .sum()
}

/// Features at several scales and the points whose features persist ([Stüde 2024] §3.2.2,
/// after Rusu, Marton, Blodow & Beetz, "Persistent point feature histograms for 3D point
/// clouds", IAS 2008): at each scale `s` (radius `rₛ`), with `μₛ` the mean histogram of the
/// cloud and `dᵢ = χ²(FPFHₛ(pᵢ), μₛ)`, a point is *unique* if `dᵢ > mean(d) + β·sd(d)`; it is
/// *persistent* if it is unique at two neighbouring scales `rₛ, rₛ₊₁` (at the one scale if only
/// one is given). Points without a neighbourhood (all-zero histogram) are never kept.
#[derive(Clone, Debug)]
pub struct MultiScaleFeatures {
    /// FPFH at the largest scale, for every point.
    pub histograms: Vec<Histogram>,
    /// Indices of the persistent points, ascending (all points with a histogram if the
    /// persistence analysis is off).
    pub keypoints: Vec<usize>,
}

/// Computes [`MultiScaleFeatures`] at `radii` (ascending), `beta = None` to keep every point
/// with a histogram.
pub fn multiscale_fpfh<const D: usize>(
    points: &[[f64; D]],
    normals: &[[f64; D]],
    tree: &KdTree<D>,
    radii: &[f64],
    max_neighbours: usize,
    beta: Option<f64>,
) -> Result<MultiScaleFeatures, RegistrationError> {
    let mut unique_prev: Option<Vec<bool>> = None;
    let mut persistent = vec![false; points.len()];
    let mut histograms = Vec::new();
    for &r in radii {
        histograms = fpfh(points, normals, tree, r, max_neighbours)?;
        let Some(beta) = beta else { continue };
        let valid: Vec<usize> = (0..points.len())
            .filter(|&i| histograms[i].iter().any(|&x| x > 0.0))
            .collect();
        let mut unique = vec![false; points.len()];
        if !valid.is_empty() {
            let n = valid.len() as f64;
            let mut mean = [0.0; FEATURE_LEN];
            for &i in &valid {
                for (b, m) in mean.iter_mut().enumerate() {
                    *m += histograms[i][b] / n;
                }
            }
            let d: Vec<f64> = valid
                .iter()
                .map(|&i| chi_squared(&histograms[i], &mean))
                .collect();
            let md = d.iter().sum::<f64>() / n;
            let sd = (d.iter().map(|x| (x - md) * (x - md)).sum::<f64>() / n).sqrt();
            for (&i, &di) in valid.iter().zip(&d) {
                unique[i] = di > md + beta * sd;
            }
        }
        match &unique_prev {
            Some(prev) => (0..points.len()).for_each(|i| persistent[i] |= prev[i] && unique[i]),
            None if radii.len() == 1 => persistent = unique.clone(),
            None => {}
        }
        unique_prev = Some(unique);
    }
    let keypoints = (0..points.len())
        .filter(|&i| {
            histograms
                .get(i)
                .is_some_and(|h| h.iter().any(|&x| x > 0.0))
        })
        .filter(|&i| beta.is_none() || persistent[i])
        .collect();
    Ok(MultiScaleFeatures {
        histograms,
        keypoints,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn persistent_points_are_where_the_shape_is_distinctive() {
        // An L of two 3 m walls sampled every 2 cm: along the walls every histogram is alike;
        // the corner and the two ends are what persists across the scales.
        let mut points: Vec<[f64; 2]> = (0..150).map(|i| [0.02 * f64::from(i), 0.0]).collect();
        points.extend((1..150).map(|i| [0.0, 0.02 * f64::from(i)]));
        let tree = KdTree::new(&points);
        let normals = estimate_normals(&points, &tree, 10, 0.1, [1.0, 1.0]).unwrap();
        let f =
            multiscale_fpfh(&points, &normals, &tree, &[0.2, 0.3, 0.4], 100, Some(1.0)).unwrap();
        assert!(!f.keypoints.is_empty());
        let near =
            |p: [f64; 2], q: [f64; 2]| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt() < 0.5;
        let special = [[0.0, 0.0], [2.98, 0.0], [0.0, 2.98]];
        for &k in &f.keypoints {
            assert!(
                special.iter().any(|&s| near(points[k], s)),
                "{:?}",
                points[k]
            );
        }
        assert!(f.keypoints.iter().any(|&k| near(points[k], [0.0, 0.0])));
        // Without the analysis every point with a histogram is kept.
        let all = multiscale_fpfh(&points, &normals, &tree, &[0.2], 100, None).unwrap();
        assert_eq!(all.keypoints.len(), points.len());
    }
}
