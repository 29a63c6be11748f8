//! The registration of [Stüde 2024] §3.2.2 end to end: filters → FPFH at several scales with
//! persistence → correspondences → RANSAC (coarse) → ICP (fine) → information matrix.

use chronomap_geometry::scan::Scan2d;

use crate::RegistrationError;
use crate::cloud::{Cloud, Filters, positive};
use crate::features::{estimate_normals, multiscale_fpfh};
use crate::icp::{IcpMethod, IcpParams, IcpResult, Information, icp, information};
use crate::kdtree::KdTree;
use crate::ransac::{MatchParams, RansacParams, match_features, ransac_about};
use crate::rigid::{Rigid, assert_dim};

/// Parameters of [`register`].
#[derive(Clone, Debug, PartialEq)]
pub struct RegistrationParams {
    /// Filters applied to both clouds first (see [`Filters`]).
    pub filters: Filters,
    /// Voxel leaf of the clouds the features and RANSAC work on (m).
    pub coarse_voxel: f64,
    /// Neighbours (at most) and radius (m) of the PCA normals.
    pub normal_neighbours: usize,
    /// Radius of the PCA normals (m).
    pub normal_radius: f64,
    /// FPFH support radii, ascending (m): the scales of the persistence analysis.
    pub feature_radii: Vec<f64>,
    /// At most this many neighbours per FPFH support.
    pub feature_neighbours: usize,
    /// Persistence threshold β in standard deviations of the χ² distances to the mean
    /// histogram; `None` keeps every point with a histogram.
    pub persistence: Option<f64>,
    /// Feature matching.
    pub matching: MatchParams,
    /// RANSAC.
    pub ransac: RansacParams,
    /// Voxel leaf of the clouds ICP works on (`None`: the filtered clouds as they are).
    pub fine_voxel: Option<f64>,
    /// Neighbours (at most) of the target normals for point-to-plane ICP.
    pub fine_normal_neighbours: usize,
    /// Radius of the target normals for point-to-plane ICP (m).
    pub fine_normal_radius: f64,
    /// ICP.
    pub icp: IcpParams,
    /// Correspondence distance of the information matrix (m).
    pub information_distance: f64,
    /// Floor of `σ̂` (m).
    pub min_sigma: f64,
}

impl RegistrationParams {
    /// Parameters scaled to a coarse voxel leaf `v` (m), after Open3D's global-registration
    /// recipe and Rusu's multi-scale FPFH: normals within 2v (30 neighbours), FPFH at 4v, 5v
    /// and 6v (100 neighbours), persistence off, mutual nearest features, RANSAC inliers within
    /// 1.5v, then symmetric ICP on the filtered clouds as they are (normals: 20 neighbours within
    /// 2v) with correspondences within v, and the information matrix from correspondences
    /// within v. Filters: none (set [`RegistrationParams::filters`]).
    pub fn for_voxel(v: f64) -> RegistrationParams {
        RegistrationParams {
            filters: Filters {
                voxel: None,
                height: None,
                intensity: None,
                range: None,
                max_points: None,
            },
            coarse_voxel: v,
            normal_neighbours: 30,
            normal_radius: 2.0 * v,
            feature_radii: vec![4.0 * v, 5.0 * v, 6.0 * v],
            feature_neighbours: 100,
            persistence: None,
            matching: MatchParams::default(),
            ransac: RansacParams::with_inlier_distance(1.5 * v),
            fine_voxel: None,
            fine_normal_neighbours: 20,
            fine_normal_radius: 2.0 * v,
            icp: IcpParams {
                method: IcpMethod::Symmetric,
                ..IcpParams::point_to_plane(v)
            },
            information_distance: v,
            min_sigma: 1e-4,
        }
    }
}

/// The result of [`register`].
#[derive(Clone, Debug, PartialEq)]
pub struct Registration<const D: usize> {
    /// The transform mapping source points into the target frame (`ⁱT_j` of [Stüde 2024]
    /// §3.2.2), after ICP.
    pub transform: Rigid<D>,
    /// The coarse alignment (RANSAC) ICP started from.
    pub coarse: Rigid<D>,
    /// Source and target points the features were computed on.
    pub coarse_points: (usize, usize),
    /// Persistent keypoints in source and target.
    pub keypoints: (usize, usize),
    /// Feature correspondences.
    pub correspondences: usize,
    /// Of which RANSAC inliers.
    pub inliers: usize,
    /// RANSAC samples drawn.
    pub ransac_iterations: usize,
    /// The fine registration.
    pub icp: IcpResult<D>,
    /// `Ω = I / σ̂²`.
    pub information: Information,
}

/// Registers `source` to `target` without an initial guess ([Stüde 2024] §3.2.2, Figure 3.6.a):
/// both clouds are filtered, voxel-downsampled to the coarse leaf, given PCA normals (facing
/// their sensor at the origin) and multi-scale FPFH; persistent keypoints are matched by nearest
/// neighbour in feature space, RANSAC finds the coarse alignment, point-to-plane ICP on the fine
/// clouds refines it, and the information matrix comes from the refined correspondences.
pub fn register<const D: usize>(
    source: &Cloud<D>,
    target: &Cloud<D>,
    params: &RegistrationParams,
) -> Result<Registration<D>, RegistrationError> {
    const { assert_dim::<D>() };
    positive("coarse_voxel", params.coarse_voxel)?;
    positive("normal_radius", params.normal_radius)?;
    positive("fine_normal_radius", params.fine_normal_radius)?;
    if params.feature_radii.is_empty() {
        return Err(RegistrationError::Parameter {
            field: "feature_radii",
            value: 0.0,
            why: "needs at least one radius",
        });
    }
    for &r in &params.feature_radii {
        positive("feature_radii", r)?;
    }
    if let Some(b) = params.persistence
        && !b.is_finite()
    {
        return Err(RegistrationError::Parameter {
            field: "persistence",
            value: b,
            why: "must be finite",
        });
    }
    for (what, cloud) in [("source", source), ("target", target)] {
        if cloud.len() > MAX_INPUT_POINTS {
            return Err(RegistrationError::TooManyInputPoints {
                what,
                got: cloud.len(),
            });
        }
    }
    // The points entering ICP are bounded (MAX_ICP_POINTS) where they are made: in the filters
    // when ICP works on the filtered clouds, on the fine grid otherwise; both are made before
    // any feature work, so that a refusal comes early.
    let icp_limit = |what: &'static str| {
        move |e: RegistrationError| match e {
            RegistrationError::PointLimit {
                counted,
                seen,
                points,
                ..
            } => RegistrationError::TooManyIcpPoints {
                what,
                counted,
                seen,
                points,
            },
            e => e,
        }
    };
    let filter = |cloud: &Cloud<D>, what| match params.fine_voxel {
        None => params
            .filters
            .apply_at_most(cloud, MAX_ICP_POINTS)
            .map_err(icp_limit(what)),
        Some(_) => params.filters.apply(cloud),
    };
    let source = filter(source, "source")?;
    let target = filter(target, "target")?;
    for (what, cloud) in [("filtered source", &source), ("filtered target", &target)] {
        if cloud.len() < 3 * D {
            return Err(RegistrationError::TooFewPoints {
                what,
                got: cloud.len(),
                need: 3 * D,
            });
        }
    }
    // Work near the origin: clouds in a far frame (UTM: millions of metres) lose the precision
    // the normals and the linearised ICP need (their rotations about the origin turn into huge
    // lever arms), so every cloud is moved by −c, c the target's centroid rounded to a multiple
    // of [`CENTRE_STEP`] (clouds near the origin are not moved at all), and the transform is
    // moved back at the end. The sensor, at the origin, moves with them.
    let centre = centre_of(target.points());
    let origin: [f64; D] = std::array::from_fn(|a| -centre[a]);
    let shift = |points: Vec<[f64; D]>| -> Vec<[f64; D]> {
        if centre == [0.0; D] {
            return points;
        }
        points
            .into_iter()
            .map(|p| std::array::from_fn(|a| p[a] - centre[a]))
            .collect()
    };
    let fine_grid = |cloud: &Cloud<D>, what| match params.fine_voxel {
        Some(leaf) => cloud
            .voxel_grid_at_most(leaf, MAX_ICP_POINTS)
            .map(|c| Some(c.into_parts().0))
            .map_err(icp_limit(what)),
        None => Ok(None),
    };
    let src_fine = fine_grid(&source, "source")?;
    let tgt_fine = fine_grid(&target, "target")?;
    let describe = |cloud: &Cloud<D>, what: &'static str| -> Result<_, RegistrationError> {
        // The grid stops at the first point over the bound: memory stays bounded by it.
        let coarse = match cloud.voxel_grid_at_most(params.coarse_voxel, MAX_FEATURE_POINTS) {
            Ok(coarse) => coarse.into_parts().0,
            Err(RegistrationError::PointLimit { seen, points, .. }) => {
                return Err(RegistrationError::TooManyFeaturePoints {
                    what,
                    voxel: params.coarse_voxel,
                    seen,
                    points,
                });
            }
            Err(e) => return Err(e),
        };
        let coarse = shift(coarse);
        let tree = KdTree::new(&coarse);
        let normals = estimate_normals(
            &coarse,
            &tree,
            params.normal_neighbours,
            params.normal_radius,
            origin,
        )?;
        let features = multiscale_fpfh(
            &coarse,
            &normals,
            &tree,
            &params.feature_radii,
            params.feature_neighbours,
            params.persistence,
        )?;
        Ok((coarse, features))
    };
    let (src_coarse, src_features) = describe(&source, "source")?;
    let (tgt_coarse, tgt_features) = describe(&target, "target")?;
    let correspondences = match_features(
        &src_features.histograms,
        &src_features.keypoints,
        &tgt_features.histograms,
        &tgt_features.keypoints,
        &params.matching,
    )?;
    let consensus = ransac_about(
        &src_coarse,
        &tgt_coarse,
        &correspondences,
        &params.ransac,
        &centre,
    )?;
    let src_fine = src_fine.unwrap_or_else(|| source.into_parts().0);
    let tgt_fine = tgt_fine.unwrap_or_else(|| target.into_parts().0);
    let (src_fine, tgt_fine) = (shift(src_fine), shift(tgt_fine));
    let tree = KdTree::new(&tgt_fine);
    let normals = estimate_normals(
        &tgt_fine,
        &tree,
        params.fine_normal_neighbours,
        params.fine_normal_radius,
        origin,
    )?;
    let src_normals = match params.icp.method {
        IcpMethod::Symmetric => Some(estimate_normals(
            &src_fine,
            &KdTree::new(&src_fine),
            params.fine_normal_neighbours,
            params.fine_normal_radius,
            origin,
        )?),
        _ => None,
    };
    let fine = icp(
        &src_fine,
        src_normals.as_deref(),
        &tgt_fine,
        &tree,
        Some(&normals),
        consensus.transform,
        &params.icp,
    )?;
    let info = information(
        &src_fine,
        &tree,
        &fine.transform,
        params.information_distance,
        params.min_sigma,
    )?;
    let fine = IcpResult {
        transform: uncentre(&fine.transform, &centre),
        ..fine
    };
    Ok(Registration {
        transform: fine.transform,
        coarse: uncentre(&consensus.transform, &centre),
        coarse_points: (src_coarse.len(), tgt_coarse.len()),
        keypoints: (src_features.keypoints.len(), tgt_features.keypoints.len()),
        correspondences: correspondences.len(),
        inliers: consensus.inliers.len(),
        ransac_iterations: consensus.iterations,
        icp: fine,
        information: info,
    })
}

/// The most points of one cloud that enter feature computation (normals, FPFH, matching):
/// 250,000. FPFH keeps every point's neighbour list (up to
/// [`RegistrationParams::feature_neighbours`] + 1 entries of 16 bytes) and a 264-byte histogram
/// per scale, about 2 KB a point with the defaults, so this bounds that stage to about 0.5 GB
/// a cloud. More points after the coarse voxel grid are
/// [`RegistrationError::TooManyFeaturePoints`]: a larger [`RegistrationParams::coarse_voxel`]
/// leaves fewer.
pub const MAX_FEATURE_POINTS: usize = 250_000;

/// The most points of one cloud that enter ICP (the fine clouds: the filtered clouds, or their
/// [`RegistrationParams::fine_voxel`] grid): 1,000,000. Each takes its normal, a k-d tree entry
/// and ICP's correspondences (about 200 bytes with both clouds' normals), so this bounds that
/// stage to about 0.2 GB a cloud. The grid that makes them stops at the first point over the
/// bound ([`RegistrationError::TooManyIcpPoints`]): a larger fine voxel leaves fewer.
pub const MAX_ICP_POINTS: usize = 1_000_000;

/// The most points of a cloud [`register`] takes: 10,000,000 (240 MB of coordinates); more
/// are [`RegistrationError::TooManyInputPoints`]. A reader can check this before reading
/// (the PLY reader does, from the header: `chronomap_io::ply::read_ply_at_most`).
pub const MAX_INPUT_POINTS: usize = 10_000_000;

/// Clouds are moved by their target's centroid rounded to a multiple of this many metres before
/// registration ([`register`]): 64, so that clouds within 32 m of the origin are registered
/// exactly as given.
pub const CENTRE_STEP: f64 = 64.0;

/// The centroid of `points` rounded to a multiple of [`CENTRE_STEP`] (zero for no points).
fn centre_of<const D: usize>(points: &[[f64; D]]) -> [f64; D] {
    if points.is_empty() {
        return [0.0; D];
    }
    let n = points.len() as f64;
    std::array::from_fn(|a| {
        let mean = points.iter().map(|p| p[a]).sum::<f64>() / n;
        (mean / CENTRE_STEP).round() * CENTRE_STEP
    })
}

/// `T` of points moved by `−c` as a transform of the unmoved points: `p ↦ R (p − c) + t + c`,
/// i.e. rotation `R`, translation `t + c − R c`.
pub(crate) fn uncentre<const D: usize>(t: &Rigid<D>, centre: &[f64; D]) -> Rigid<D> {
    if *centre == [0.0; D] {
        return *t;
    }
    let rc = t.rotate(centre);
    Rigid {
        rotation: t.rotation,
        translation: std::array::from_fn(|a| t.translation[a] + (centre[a] - rc[a])),
    }
}

/// Parameters for 2-D laser scans of indoor spaces (SICK-like, 0.5° beams): coarse voxel
/// 0.1 m, normals within 0.3 m (10 neighbours), FPFH-2D at 0.8, 1.0 and 1.2 m, RANSAC inliers
/// within 0.15 m and translations up to 10 m, point-to-line ICP on 0.05 m cells (normals: 8
/// neighbours within 0.1 m) with correspondences within 0.3 m.
pub fn scan_params() -> RegistrationParams {
    let mut p = RegistrationParams::for_voxel(0.1);
    p.normal_neighbours = 10;
    p.normal_radius = 0.3;
    p.feature_radii = vec![0.8, 1.0, 1.2];
    p.feature_neighbours = 60;
    p.ransac.max_translation = Some(10.0);
    p.fine_voxel = Some(0.05);
    p.fine_normal_neighbours = 8;
    p.fine_normal_radius = 0.1;
    p.icp = IcpParams::point_to_plane(0.3);
    p.information_distance = 0.3;
    p
}

/// Registers two 2-D laser scans without an initial guess (a loop pair has none): the transform
/// maps points of `source` (its sensor frame) into the sensor frame of `target`. The scans'
/// returns ([`Scan2d::points`]) are the clouds; see [`scan_params`].
pub fn register_scans(
    source: &Scan2d,
    target: &Scan2d,
    params: &RegistrationParams,
) -> Result<Registration<2>, RegistrationError> {
    let s = Cloud::from_points(source.points())?;
    let t = Cloud::from_points(target.points())?;
    register(&s, &t, params)
}
