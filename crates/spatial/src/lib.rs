//! # chronomap-spatial
//!
//! The spatial pieces every map-based domain of chronomap shares: the occupancy map of
//! `nav_msgs/OccupancyGrid`, occupancy of a 2-D map as an obstacle grid with ray casting, the planning grid a robot drives on, and the one
//! least-cost search (Dijkstra, or A* with a heuristic) over them with its least-cost-first
//! queue.
#![deny(missing_docs)]

pub mod obstacle;
pub mod occupancy;
pub mod planning;
pub mod queue;
pub mod search;

pub use obstacle::{ObstacleGrid, ObstacleGridError};
pub use occupancy::{InvalidMap, OccupancyMap};
pub use planning::{PlanningGrid, PlanningGridError};
