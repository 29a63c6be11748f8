//! # chronomap-multimap
//!
//! Modular multi-map management ([Stüde 2024] §3.3): instead of one large map made with one
//! SLAM configuration, a robot makes one map per room, corridor or outdoor area, detects the
//! doorways between them from 2-D laser scans, chooses each new map's configuration by the
//! size of its room, links the maps at the doors, tracks its pose and its uncertainty across
//! maps, and optimises the map poses when a loop closes.
//!
//! * [`door`] — door-passage detection by criteria (C1)–(C3) (§3.3.2);
//! * [`config`] — the configuration of a new map from the room's bounding box (§3.3.2);
//! * [`graph`] — maps, link points and candidates; relative map poses and their covariance
//!   (eqs. (3.10)–(3.13)); paths of maps by Dijkstra and the composition along them
//!   (eq. (3.14)); the loop search (§3.3.3);
//! * [`search`] — the search radius of eq. (3.8);
//! * [`optimize`] — pose-graph optimisation of the map poses (eqs. (3.3)–(3.5));
//! * [`mapper`] — all of it driven by scans and odometry;
//! * [`se2`] — poses, `⊕`, `⊖`, their Jacobians, uncertain poses
//!   ([`chronomap_geometry::se2`]); [`synth`] — a ray caster for tests.
//!
//! ```
//! use chronomap_multimap::config::MapConfig;
//! use chronomap_multimap::graph::{MapGraph, PathWeight};
//! use chronomap_multimap::optimize::{optimize, OptimizeParams};
//! use chronomap_multimap::se2::{Pose2, UncertainPose};
//!
//! // A corridor (map 0) with doors into two rooms (maps 1, 2) that share a connecting door.
//! let mut g = MapGraph::new();
//! let m: Vec<usize> = (0..3)
//!     .map(|_| g.add_map(MapConfig::ShortRange, None))
//!     .collect::<Result<_, _>>()?;
//! let cov = [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.0025]];
//! let at = |x, y, t| UncertainPose::new(Pose2::new(x, y, t).unwrap(), cov).unwrap();
//! let origin = UncertainPose::exact(Pose2::IDENTITY);
//! let up = std::f64::consts::FRAC_PI_2;
//! g.add_link(m[0], at(2.0, 1.0, up), m[1], origin)?;
//! g.add_link(m[0], at(8.0, 1.0, up), m[2], origin)?;
//! g.add_link(m[1], at(0.0, -6.0, 0.0), m[2], origin)?; // room 2 lies 6 m to room 1's right
//! // The robot in room 2, two metres in: its pose in the corridor's frame.
//! let robot = UncertainPose::exact(Pose2::new(2.0, 0.0, 0.0)?);
//! let direct = g.pose_in(m[0], m[2], &robot, PathWeight::Hops)?;
//! assert!((direct.mean.x - 8.0).abs() < 1e-12 && (direct.mean.y - 3.0).abs() < 1e-12);
//! // The loop is consistent, so the optimised poses are those of the links.
//! let opt = optimize(&g, &OptimizeParams::default())?;
//! assert!((opt.poses[2].x - 8.0).abs() < 1e-9 && opt.final_cost < 1e-18);
//! # Ok::<(), chronomap_multimap::MultimapError>(())
//! ```
//!
//! [Stüde 2024]: M. Stüde, *Environment and Task Modeling of Long-Term-Autonomous Service
//! Robots*, dissertation, Gottfried Wilhelm Leibniz Universität Hannover, 2024.
#![deny(missing_docs)]
// Small fixed-size matrix code indexes rows and columns by number, as the equations do.
#![allow(clippy::needless_range_loop)]

pub mod config;
pub mod door;
mod error;
pub mod graph;
pub mod mapper;
pub mod optimize;
pub use chronomap_geometry::se2;
pub mod search;
pub mod synth;

pub use error::MultimapError;
