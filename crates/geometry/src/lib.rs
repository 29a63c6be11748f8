//! # chronomap-geometry
//!
//! The geometry that chronomap's range-data crates (loop closure, registration, multi-map
//! management) share, written once:
//! * [`scan`] — 2-D laser scans as the sensors give them (ranges at evenly spaced angles,
//!   REP 117 no-returns) and their points.
//! * [`se2`] — poses in the plane, `⊕`/`⊖` with their Jacobians, uncertain poses propagated
//!   to first order ([Stüde 2024] eqs. (3.10)–(3.13)), odometry increments, and the loop-search
//!   radius of eq. (3.8) from a position covariance.
//! * [`rigid`] — rigid transforms in 2-D and 3-D as matrices and the least-squares fit of one
//!   to point pairs (Kabsch / Umeyama).
//! * [`linalg`] — small dense linear algebra: Jacobi eigen-decomposition, the closed-form
//!   largest eigenvalue of a 2×2 covariance, one Cholesky factorisation and solve (checked
//!   against `faer`).
//! * [`kdtree`] — a static k-d tree (nearest and `k` nearest within a radius).
//!
//! All of it is pure: no I/O, clock or global state.
//!
//! [Stüde 2024]: M. Stüde, *Environment and Task Modeling of Long-Term-Autonomous Service
//! Robots*, dissertation, Gottfried Wilhelm Leibniz Universität Hannover, 2024.
#![deny(missing_docs)]
// Index loops read like the matrix formulas they implement; `!(x > 0.0)` is deliberate: it is
// true for NaN too.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

pub mod kdtree;
pub mod linalg;
pub mod rigid;
pub mod scan;
pub mod se2;

pub use kdtree::KdTree;
pub use rigid::{Rigid, kabsch};
pub use scan::{Scan2d, ScanError};
pub use se2::{Pose2, UncertainPose};

/// Why a geometric quantity is refused or cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GeometryError {
    /// A number that must be finite is NaN or infinite.
    #[error("{field}: {value} is not finite")]
    NotFinite {
        /// The field.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// A matrix given as a covariance is not one (not finite, asymmetric, negative variance,
    /// not positive semi-definite).
    #[error("{field} is not a covariance matrix: {why}")]
    NotCovariance {
        /// The field.
        field: &'static str,
        /// What is wrong with it.
        why: &'static str,
    },
    /// Too few points (or point pairs) for a fit.
    #[error("{what}: {got} points, at least {need} needed")]
    TooFewPoints {
        /// What was short.
        what: &'static str,
        /// How many there were.
        got: usize,
        /// How many are needed.
        need: usize,
    },
    /// The geometry does not determine a transform.
    #[error("degenerate: {0}")]
    Degenerate(&'static str),
}
