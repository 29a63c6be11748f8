//! # chronomap-app-range
//!
//! The application layer for range data ([Stüde 2024] chapter 3): what the command line (and any
//! other face) runs on laser logs, keyframes and point clouds, beside `chronomap-app`, whose
//! [`report`](chronomap_app::report) tables it renders with. The algorithms stay in their domain
//! crates (`chronomap-lidar`: descriptors, AdaBoost, the loop pipeline; `chronomap-registration`:
//! FPFH, RANSAC, ICP; `chronomap-multimap`: the map manager); here they meet files and become
//! studies with reports.
//!
//! ```
//! use chronomap_app_range::registration::matrix_text;
//!
//! // A 4×4 homogeneous transform as `lidar register -o` writes it: one row a line.
//! let identity = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
//! assert_eq!(matrix_text(&identity).lines().count(), 4);
//! ```
//!
//! | module | what the faces get |
//! |---|---|
//! | [`laser_log`] | laser logs from text or a rosbag2 bag, keyframes, odometry increments and dead reckoning |
//! | [`lidar_study`] | descriptors, the cross-validated loop-closure study over fold layouts, the out-of-fold pipeline and the `p_min` training rule (§3.2.1), detection |
//! | [`registration`] | clouds and keyframe pairs registered against a truth or SLAM (§3.2.2) |
//! | [`maps`] | the map manager along a log (§3.3) |
#![deny(missing_docs)]

pub mod laser_log;
pub mod lidar_study;
pub mod maps;
pub mod registration;
