//! Correspondences in feature space and their consensus: RANSAC [Fischler & Bolles 1981] over
//! minimal samples aligned by SVD, with edge-length pre-rejection ([Stüde 2024] §3.2.2).

use chronomap_rng::Xoshiro256StarStar;

use crate::RegistrationError;
use crate::features::{FEATURE_LEN, Histogram};
use crate::kdtree::KdTree;
use crate::rigid::{Rigid, assert_dim, kabsch};
use chronomap_geometry::linalg::dist2;

/// How features are matched.
#[derive(Clone, Debug, PartialEq)]
pub struct MatchParams {
    /// Keep a pair only if each is the other's nearest neighbour.
    pub mutual: bool,
    /// Lowe's ratio test: keep a pair only if the nearest feature distance is below `ratio`
    /// times the second nearest (`None`: off).
    pub ratio: Option<f64>,
}

impl Default for MatchParams {
    fn default() -> Self {
        MatchParams {
            mutual: true,
            ratio: None,
        }
    }
}

/// Correspondences `(source point, target point)` by nearest neighbour in feature space
/// (Euclidean distance between histograms), from each source keypoint to the target keypoints
/// ([Stüde 2024] §3.2.2: "determined by nearest-neighbor search in the feature space").
pub fn match_features(
    source: &[Histogram],
    source_keys: &[usize],
    target: &[Histogram],
    target_keys: &[usize],
    params: &MatchParams,
) -> Result<Vec<(usize, usize)>, RegistrationError> {
    for (what, keys, n) in [
        ("source keypoints", source_keys, source.len()),
        ("target keypoints", target_keys, target.len()),
    ] {
        if let Some(&k) = keys.iter().find(|&&k| k >= n) {
            return Err(RegistrationError::Mismatch {
                what,
                got: k,
                points: n,
            });
        }
    }
    let target_features: Vec<[f64; FEATURE_LEN]> = target_keys.iter().map(|&i| target[i]).collect();
    let tree = KdTree::new(&target_features);
    let reverse = params.mutual.then(|| {
        let source_features: Vec<[f64; FEATURE_LEN]> =
            source_keys.iter().map(|&i| source[i]).collect();
        KdTree::new(&source_features)
    });
    let mut nn = Vec::new();
    let mut out = Vec::new();
    for (si, &s) in source_keys.iter().enumerate() {
        let k = if params.ratio.is_some() { 2 } else { 1 };
        tree.nearest_within(&source[s], k, f64::INFINITY, &mut nn);
        let Some(&(tj, d2)) = nn.first() else {
            continue;
        };
        if let (Some(ratio), Some(&(_, second))) = (params.ratio, nn.get(1))
            && d2 > ratio * ratio * second
        {
            continue;
        }
        if let Some(rev) = &reverse
            && rev.nearest(&target[target_keys[tj]]).map(|(i, _)| i) != Some(si)
        {
            continue;
        }
        out.push((s, target_keys[tj]));
    }
    Ok(out)
}

/// RANSAC parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct RansacParams {
    /// A correspondence is an inlier if the transformed source point lies within this distance
    /// of its target point.
    pub inlier_distance: f64,
    /// Most samples drawn (pre-rejected ones included).
    pub max_iterations: usize,
    /// Stop once the probability of having drawn an all-inlier sample reaches this, given the
    /// best inlier ratio `w`: after `ln(1 − p) / ln(1 − w^s)` samples of size `s`.
    pub confidence: f64,
    /// Pre-rejection: every edge between two sample points must have a length ratio between
    /// source and target of at least this (0.9: 10 % difference), as rigid motions keep lengths.
    pub edge_similarity: f64,
    /// Hypotheses translating farther are rejected (`t_max` of [Stüde 2024] appendix A: 3 m
    /// indoors, 10 m on KITTI); `None`: no limit.
    pub max_translation: Option<f64>,
    /// Seed of the sampler.
    pub seed: u64,
}

impl RansacParams {
    /// Defaults around an inlier distance: 100,000 samples, confidence 0.999, edges within 10 %.
    pub fn with_inlier_distance(inlier_distance: f64) -> RansacParams {
        RansacParams {
            inlier_distance,
            max_iterations: 100_000,
            confidence: 0.999,
            edge_similarity: 0.9,
            max_translation: None,
            seed: 0x5eed,
        }
    }
}

/// The consensus found by [`ransac`].
#[derive(Clone, Debug, PartialEq)]
pub struct RansacResult<const D: usize> {
    /// Least-squares fit on the inliers of the best sample.
    pub transform: Rigid<D>,
    /// Indices into the correspondences of its inliers.
    pub inliers: Vec<usize>,
    /// Samples drawn.
    pub iterations: usize,
}

/// RANSAC over minimal samples of `D` correspondences (3 in 3-D, 2 in 2-D), each aligned with
/// [`kabsch`] after the edge-length pre-rejection; the best sample's inliers are refitted by
/// least squares, and the inliers of that fit recounted once more.
pub fn ransac<const D: usize>(
    source: &[[f64; D]],
    target: &[[f64; D]],
    correspondences: &[(usize, usize)],
    params: &RansacParams,
) -> Result<RansacResult<D>, RegistrationError> {
    ransac_about(source, target, correspondences, params, &[0.0; D])
}

/// [`ransac`] on points moved by `−centre` (see [`crate::register`]): the hypotheses and the
/// result are transforms of the moved points, [`RansacParams::max_translation`] applies to
/// the translation of the unmoved ones.
pub(crate) fn ransac_about<const D: usize>(
    source: &[[f64; D]],
    target: &[[f64; D]],
    correspondences: &[(usize, usize)],
    params: &RansacParams,
    centre: &[f64; D],
) -> Result<RansacResult<D>, RegistrationError> {
    const { assert_dim::<D>() };
    crate::cloud::positive("inlier_distance", params.inlier_distance)?;
    if !(params.confidence > 0.0 && params.confidence < 1.0) {
        return Err(RegistrationError::Parameter {
            field: "confidence",
            value: params.confidence,
            why: "must be in (0, 1)",
        });
    }
    if !(0.0..=1.0).contains(&params.edge_similarity) {
        return Err(RegistrationError::Parameter {
            field: "edge_similarity",
            value: params.edge_similarity,
            why: "must be in [0, 1]",
        });
    }
    let n = correspondences.len();
    if n < D {
        return Err(RegistrationError::TooFewPoints {
            what: "correspondences",
            got: n,
            need: D,
        });
    }
    if let Some(&(s, t)) = correspondences
        .iter()
        .find(|&&(s, t)| s >= source.len() || t >= target.len())
    {
        return Err(RegistrationError::NoConsensus(format!(
            "correspondence ({s}, {t}) is out of range ({} source, {} target points)",
            source.len(),
            target.len()
        )));
    }
    let eps2 = params.inlier_distance * params.inlier_distance;
    let count = |t: &Rigid<D>| {
        correspondences
            .iter()
            .filter(|&&(s, q)| dist2(&t.apply(&source[s]), &target[q]) <= eps2)
            .count()
    };
    let mut rng = Xoshiro256StarStar::seed_from_u64(params.seed);
    let mut best: Option<(usize, Rigid<D>)> = None;
    let mut needed = params.max_iterations;
    let mut iterations = 0;
    let tau = params.edge_similarity;
    while iterations < needed.min(params.max_iterations) {
        iterations += 1;
        let mut sample = [0usize; D];
        for k in 0..D {
            sample[k] = rng.int_in(0, n as u64 - 1) as usize;
        }
        let (ps, qs): (Vec<[f64; D]>, Vec<[f64; D]>) = sample
            .iter()
            .map(|&c| (source[correspondences[c].0], target[correspondences[c].1]))
            .unzip();
        let lengths_agree = (0..D).all(|a| {
            ((a + 1)..D).all(|b| {
                let ls = dist2(&ps[a], &ps[b]).sqrt();
                let lt = dist2(&qs[a], &qs[b]).sqrt();
                ls > 0.0 && lt > 0.0 && ls >= tau * lt && lt >= tau * ls
            })
        });
        if !lengths_agree {
            continue;
        }
        let Ok(t) = kabsch(&ps, &qs) else { continue };
        if params
            .max_translation
            .is_some_and(|m| crate::pipeline::uncentre(&t, centre).translation_norm() > m)
        {
            continue;
        }
        let inliers = count(&t);
        if best.as_ref().is_none_or(|(b, _)| inliers > *b) {
            let w = inliers as f64 / n as f64;
            let miss = 1.0 - w.powi(D as i32);
            if miss <= 0.0 {
                needed = iterations;
            } else if miss < 1.0 {
                let k = ((1.0 - params.confidence).ln() / miss.ln()).ceil();
                needed = if k.is_finite() && k < params.max_iterations as f64 {
                    k as usize
                } else {
                    params.max_iterations
                };
            }
            best = Some((inliers, t));
        }
    }
    let Some((_, mut transform)) = best else {
        return Err(RegistrationError::NoConsensus(format!(
            "no sample of {n} correspondences passed the edge-length test in {iterations} draws"
        )));
    };
    for _refit in 0..2 {
        let inliers: Vec<usize> = (0..n)
            .filter(|&c| {
                dist2(
                    &transform.apply(&source[correspondences[c].0]),
                    &target[correspondences[c].1],
                ) <= eps2
            })
            .collect();
        if inliers.len() < D {
            break;
        }
        let (ps, qs): (Vec<[f64; D]>, Vec<[f64; D]>) = inliers
            .iter()
            .map(|&c| (source[correspondences[c].0], target[correspondences[c].1]))
            .unzip();
        match kabsch(&ps, &qs) {
            Ok(t) => transform = t,
            Err(_) => break,
        }
    }
    let inliers = (0..n)
        .filter(|&c| {
            dist2(
                &transform.apply(&source[correspondences[c].0]),
                &target[correspondences[c].1],
            ) <= eps2
        })
        .collect();
    Ok(RansacResult {
        transform,
        inliers,
        iterations,
    })
}
