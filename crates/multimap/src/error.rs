//! The typed errors of the crate: every refusal names the field, map, link or parameter.

use chronomap_geometry::GeometryError;
use chronomap_geometry::scan::ScanError;

/// Why an input or a computation is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MultimapError {
    /// A parameter outside its range.
    #[error("parameter {field} = {value}: {why}")]
    Parameter {
        /// The parameter.
        field: &'static str,
        /// Its value.
        value: f64,
        /// The range it must lie in.
        why: &'static str,
    },
    /// A scan refused by [`chronomap_geometry::Scan2d::validate`] (its message is part of this
    /// one's, not a source).
    #[error("scan: {0}")]
    Scan(ScanError),
    /// Scan times must not decrease.
    #[error("time: scan at {time} s comes after one at {previous} s")]
    TimeGoesBack {
        /// The new scan's time.
        time: f64,
        /// The previous scan's time.
        previous: f64,
    },
    /// A map index that is not in the graph.
    #[error("map {0} is not in the graph")]
    UnknownMap(usize),
    /// A link-point index that is not in the graph.
    #[error("link point {0} is not in the graph")]
    UnknownLink(usize),
    /// A link point must join two different maps.
    #[error("a link point must join two different maps, both are map {0}")]
    SameMap(usize),
    /// No chain of link points joins the two maps.
    #[error("no path of link points joins map {from} and map {to}")]
    NoPath {
        /// Start map.
        from: usize,
        /// Target map.
        to: usize,
    },
    /// More elements than the crate's bound for them.
    #[error("{what}: {n} is more than the {max} allowed")]
    TooLarge {
        /// What is counted.
        what: &'static str,
        /// How many there are.
        n: usize,
        /// The most allowed.
        max: usize,
    },
    /// A relative map pose whose covariance cannot be inverted into an information matrix
    /// (eq. (3.4) needs `Ω = Σ⁻¹`).
    #[error("link point {link}: the covariance of its relative map pose is singular")]
    SingularCovariance {
        /// The link point.
        link: usize,
    },
    /// The optimiser used all its iterations without meeting its stopping rule.
    #[error(
        "the pose-graph optimisation did not converge in {iterations} iterations (cost {cost})"
    )]
    NotConverged {
        /// Iterations made.
        iterations: usize,
        /// The cost `F` of eq. (3.4) when it stopped.
        cost: f64,
    },
    /// A refusal of the shared geometry: a number that is not finite, a matrix that is not a
    /// covariance, a fit to too few or degenerate points.
    #[error(transparent)]
    Geometry(GeometryError),
    /// The normal equations of the pose graph are singular (a map not tied to map 0).
    #[error("the pose graph is singular: map {map} is not constrained")]
    SingularGraph {
        /// A map whose pose is not determined.
        map: usize,
    },
}

/// A pose or covariance refused by [`chronomap_geometry::se2`] (the same field and message).
impl From<GeometryError> for MultimapError {
    fn from(e: GeometryError) -> Self {
        MultimapError::Geometry(e)
    }
}

impl From<ScanError> for MultimapError {
    fn from(e: ScanError) -> Self {
        MultimapError::Scan(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_inner_message_is_said_once() {
        // Its Display includes the scan error; returning it from `source()` as well made a
        // printed chain repeat it ("scan: …: …").
        let scan = chronomap_geometry::Scan2d::new(0.0, 0.0, 1.0, f64::NAN, vec![1.0, 2.0]);
        let e = MultimapError::from(scan.unwrap_err());
        assert!(e.to_string().starts_with("scan: "), "{e}");
        assert!(std::error::Error::source(&e).is_none());
    }
}
