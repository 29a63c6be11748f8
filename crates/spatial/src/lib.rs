//! # chronomap-spatial
//!
//! The spatial pieces every map-based domain of chronomap shares: occupancy of a 2-D map as
//! an obstacle grid with ray casting, and the least-cost-first queue of the grid searches.
#![deny(missing_docs)]

pub mod obstacle;
pub mod queue;

pub use obstacle::{ObstacleGrid, ObstacleGridError};
