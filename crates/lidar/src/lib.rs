//! # chronomap-lidar
//!
//! Loop closure from range data ([Stüde 2024] §3.2.1):
//! * [`scan`] — 2-D laser scans as the sensors give them (ranges at evenly spaced angles,
//!   REP 117 no-returns) and their points: [`chronomap_geometry::scan`], which registration
//!   and multi-map management share.
//! * [`descriptor`] — the global descriptor `χ = (χ^I, χ^II)` of [Granström 2009] (32 scalar
//!   features, 9 range histograms; eq. (3.7)) of 2-D scans and 3-D clouds, and the pair
//!   feature vector (absolute differences, histogram correlations).
//! * [`adaboost`] — the loop classifier: discrete AdaBoost (SAMME) with decision stumps,
//!   `T = 50`, checked against scikit-learn.
//! * [`threshold`] — ROC curves, AUC and the threshold `p_min` keeping the false-positive rate
//!   below 1 %.
//! * [`search`] — where to look for loops: the search radius of eq. (3.8) from the odometry
//!   covariance, global search while `α = n_local/n_WM < α_min`, verification of the first
//!   loops (appendix A defaults).
//! * [`profile`] — three heading-tolerant pair features of range profiles (our extension).
//! * [`classifier`] — a deployable classifier: configuration (the paper's or ours), model,
//!   threshold; saved as a model file.
//! * [`evaluation`] — labelled keyframe pairs, keyframe-disjoint cross-validation and the
//!   whole loop-detection pipeline on a keyframe sequence (the Málaga evaluation of
//!   `examples/malaga_loops.rs`).
//!
//! ```
//! use chronomap_lidar::adaboost::{AdaBoost, AdaBoostParams};
//! use chronomap_lidar::descriptor::{DescriptorParams, compare, describe_scan};
//! use chronomap_lidar::Scan2d;
//!
//! // Rooms of different sizes: the same room twice is a loop, two rooms are not.
//! let room = |r: f64| Scan2d::new(0.0, -3.0, 3.0, 80.0, vec![r; 181]);
//! let params = DescriptorParams::default();
//! let d = |r: f64| describe_scan(&room(r).unwrap(), &params).unwrap();
//! let (mut x, mut y) = (Vec::new(), Vec::new());
//! for k in 0..20 {
//!     let r = 2.0 + k as f64;
//!     x.push(compare(&d(r), &d(r + 0.01)).unwrap());
//!     y.push(true);
//!     x.push(compare(&d(r), &d(r + 3.0)).unwrap());
//!     y.push(false);
//! }
//! let classifier = AdaBoost::fit(&x, &y, None, &AdaBoostParams::default())?;
//! let same = compare(&d(7.5), &d(7.52)).unwrap();
//! let other = compare(&d(7.5), &d(11.0)).unwrap();
//! assert!(classifier.probability(&same)? > 0.5 && classifier.probability(&other)? < 0.5);
//! # Ok::<(), chronomap_lidar::adaboost::AdaBoostError>(())
//! ```
//!
//! [Stüde 2024]: M. Stüde, *Environment and Task Modeling of Long-Term-Autonomous Service
//! Robots*, dissertation, Gottfried Wilhelm Leibniz Universität Hannover, 2024.
//! [Granström 2009]: K. Granström, J. Callmer, F. Ramos, J. Nieto, "Learning to detect loop
//! closure from range data", ICRA 2009.
#![deny(missing_docs)]

pub mod adaboost;
pub mod classifier;
pub mod descriptor;
pub mod evaluation;
pub mod profile;
pub use chronomap_geometry::scan;
pub mod search;
pub mod threshold;

pub use adaboost::{AdaBoost, AdaBoostError, AdaBoostParams};
pub use descriptor::{Descriptor, DescriptorError, DescriptorParams};
pub use scan::{Scan2d, ScanError};
