//! # chronomap-registration
//!
//! Point-cloud registration as in [Stüde 2024] §3.2.2: when two places are recognised as a
//! loop, their clouds are registered without an initial guess — filters, fast point feature
//! histograms at several scales with persistence analysis [Rusu 2009], correspondences by nearest
//! neighbour in feature space, RANSAC over SVD-aligned minimal samples, ICP refinement
//! (point-to-point [Besl & McKay 1992] or point-to-plane [Chen & Medioni 1992]) and the
//! information matrix `Ω = I / σ̂²` from the median absolute deviation of the residuals.
//!
//! One generic core serves 2-D laser scans (`[f64; 2]` points, SE(2)) and 3-D clouds
//! (`[f64; 3]`, SE(3)); other dimensions do not compile.
//!
//! ```
//! use chronomap_registration::{Cloud, Rigid, RegistrationParams, register};
//!
//! // An L-shaped room corner with a pillar, seen from two poses 0.4 m and 20° apart.
//! let mut points = Vec::new();
//! for i in 0..80 {
//!     let s = f64::from(i) * 0.05;
//!     points.push([s, 0.0]);
//!     points.push([0.0, s]);
//!     points.push([4.0, s * 0.5]);
//! }
//! for k in 0..24 {
//!     let a = f64::from(k) * std::f64::consts::TAU / 24.0;
//!     points.push([2.0 + 0.3 * a.cos(), 2.0 + 0.3 * a.sin()]);
//! }
//! let truth = Rigid::from_pose(0.3, -0.25, 20f64.to_radians());
//! let target = Cloud::from_points(points.clone())?;
//! let source = Cloud::from_points(points.iter().map(|p| truth.inverse().apply(p)).collect())?;
//!
//! let mut params = RegistrationParams::for_voxel(0.1);
//! params.feature_radii = vec![0.6, 0.8];
//! let result = register(&source, &target, &params)?;
//! let (rotation, translation) = result.transform.error_to(&truth);
//! assert!(rotation.to_degrees() < 0.1 && translation < 0.01, "{rotation} {translation}");
//! assert_eq!(result.information.dof, 3);
//! # Ok::<(), chronomap_registration::RegistrationError>(())
//! ```
//!
//! ## Layout
//! * [`cloud`] — [`Cloud`] and the filters of §3.2.2 ([`Filters`]): voxel grid, height,
//!   intensity, range, seeded random downsampling.
//! * [`features`] — PCA normals, FPFH (33 bins; a 2-D analogue is defined there) and the
//!   multi-scale persistence analysis.
//! * [`ransac`](mod@ransac) — feature correspondences and RANSAC with edge-length pre-rejection.
//! * [`rigid`] — SE(2)/SE(3) transforms and the Kabsch/Umeyama SVD fit [`kabsch`]
//!   ([`chronomap_geometry::rigid`]).
//! * [`icp`](mod@icp) — ICP and the [`Information`] matrix.
//! * [`kdtree`] — the k-d tree all nearest-neighbour searches use
//!   ([`chronomap_geometry::kdtree`]).
//! * [`pipeline`] — [`register`] end to end, and [`register_scans`] for
//!   [`chronomap_geometry::Scan2d`].
//!
//! [Stüde 2024]: M. Stüde, *Environment and Task Modeling of Long-Term-Autonomous Service
//! Robots*, dissertation, Gottfried Wilhelm Leibniz Universität Hannover, 2024.
//! [Rusu 2009]: R. B. Rusu, N. Blodow, M. Beetz, "Fast Point Feature Histograms (FPFH) for 3D
//! registration", ICRA 2009.
//! [Besl & McKay 1992]: P. Besl, N. McKay, "A method for registration of 3-D shapes", IEEE
//! TPAMI 14(2), 1992.
//! [Chen & Medioni 1992]: Y. Chen, G. Medioni, "Object modelling by registration of multiple
//! range images", Image and Vision Computing 10(3), 1992.
#![deny(missing_docs)]
// Index loops read like the matrix formulas they implement; `!(x > 0.0)` is deliberate: it is
// true for NaN too.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

pub mod cloud;
pub mod features;
pub mod icp;
pub use chronomap_geometry::{kdtree, rigid};
pub mod pipeline;
pub mod ransac;

pub use cloud::{Cloud, Filters, MAX_POINTS};
pub use features::{
    Histogram, MultiScaleFeatures, chi_squared, estimate_normals, fpfh, multiscale_fpfh,
};
pub use icp::{IcpMethod, IcpParams, IcpResult, Information, icp, information};
pub use kdtree::KdTree;
pub use pipeline::{
    CENTRE_STEP, MAX_FEATURE_POINTS, MAX_ICP_POINTS, MAX_INPUT_POINTS, Registration,
    RegistrationParams, register, register_scans, scan_params,
};
pub use ransac::{MatchParams, RansacParams, RansacResult, match_features, ransac};
pub use rigid::{Rigid, kabsch};

impl From<chronomap_geometry::GeometryError> for RegistrationError {
    fn from(e: chronomap_geometry::GeometryError) -> Self {
        use chronomap_geometry::GeometryError as G;
        match e {
            G::TooFewPoints { what, got, need } => {
                RegistrationError::TooFewPoints { what, got, need }
            }
            G::Degenerate(why) => RegistrationError::Degenerate(why),
            G::NotFinite { field, value } => RegistrationError::Parameter {
                field,
                value,
                why: "not finite",
            },
            G::NotCovariance { why, .. } => RegistrationError::Degenerate(why),
        }
    }
}

/// Why a registration step is refused or failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RegistrationError {
    /// A coordinate is NaN or infinite.
    #[error("point {index}: coordinate {axis} is {value}, not finite")]
    NonFinitePoint {
        /// The point.
        index: usize,
        /// The coordinate (0 = x).
        axis: usize,
        /// Its value.
        value: f64,
    },
    /// An intensity is NaN or infinite.
    #[error("intensity {index}: {value} is not finite")]
    NonFiniteIntensity {
        /// The point.
        index: usize,
        /// Its intensity.
        value: f64,
    },
    /// Not one intensity per point.
    #[error("intensity: {got} values for {points} points")]
    IntensityLength {
        /// Intensities given.
        got: usize,
        /// Points.
        points: usize,
    },
    /// More than [`MAX_POINTS`] points.
    #[error("a cloud may have at most {MAX_POINTS} points, this one has {0}")]
    TooManyPoints(usize),
    /// Too few points (or correspondences) for a step.
    #[error("{what}: {got} points, at least {need} needed")]
    TooFewPoints {
        /// What was short.
        what: &'static str,
        /// How many there were.
        got: usize,
        /// How many are needed.
        need: usize,
    },
    /// A parameter out of its range.
    #[error("{field}: {value} is not valid ({why})")]
    Parameter {
        /// The parameter.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What is wrong.
        why: &'static str,
    },
    /// A filter needs intensities the cloud does not have.
    #[error("{0}: the cloud has no intensity")]
    NoIntensity(&'static str),
    /// A voxel index does not fit 64 bits (a tiny leaf for a huge extent).
    #[error("voxel grid: point {index} is too far out for the leaf size")]
    VoxelOverflow {
        /// The point.
        index: usize,
    },
    /// A k-d tree, normals or keypoints that do not belong to the points they come with.
    #[error("{what}: {got} does not fit {points} points")]
    Mismatch {
        /// What does not fit.
        what: &'static str,
        /// Its length (or the offending index).
        got: usize,
        /// Number of points.
        points: usize,
    },
    /// The geometry does not determine a transform.
    #[error("degenerate: {0}")]
    Degenerate(&'static str),
    /// A bounded step ([`Cloud::voxel_grid_at_most`], [`Filters::apply_at_most`]) met more than
    /// `max` points (occupied voxels, or filtered points).
    #[error("more than {max} points: {counted} counted in the first {seen} of {points}")]
    PointLimit {
        /// The bound.
        max: usize,
        /// Points (or cells) counted when the step stopped: more than `max`.
        counted: usize,
        /// Points of the input read by then.
        seen: usize,
        /// Points of the input.
        points: usize,
    },
    /// More points than [`MAX_FEATURE_POINTS`] would enter feature computation: the coarse
    /// voxel grid stopped at the first point over the bound.
    #[error(
        "{what}: more than {MAX_FEATURE_POINTS} points on the {voxel} m coarse voxel grid \
         (counted in the first {seen} of its {points} filtered points), at most \
         {MAX_FEATURE_POINTS} enter feature computation (a larger coarse voxel leaves fewer)"
    )]
    TooManyFeaturePoints {
        /// `source` or `target`.
        what: &'static str,
        /// The coarse voxel leaf (m).
        voxel: f64,
        /// Filtered points read when the grid stopped.
        seen: usize,
        /// Filtered points of the cloud.
        points: usize,
    },
    /// More points than [`MAX_ICP_POINTS`] would enter ICP (the fine clouds: after the filters
    /// or the fine voxel grid).
    #[error(
        "{what}: more than {MAX_ICP_POINTS} points would enter ICP ({counted} counted in the \
         first {seen} of its {points} points), at most {MAX_ICP_POINTS} do (a larger fine voxel \
         leaves fewer)"
    )]
    TooManyIcpPoints {
        /// `source` or `target`.
        what: &'static str,
        /// Points counted when the step stopped.
        counted: usize,
        /// Points read by then.
        seen: usize,
        /// Points of the cloud given to that step.
        points: usize,
    },
    /// A cloud given to [`register`] has more than [`MAX_INPUT_POINTS`] points.
    #[error("{what}: {got} points, at most {MAX_INPUT_POINTS} may be registered")]
    TooManyInputPoints {
        /// `source` or `target`.
        what: &'static str,
        /// Its points.
        got: usize,
    },
    /// RANSAC found no consensus.
    #[error("RANSAC: {0}")]
    NoConsensus(String),
}
