//! # chronomap-lidar
//!
//! Loop closure from range data ([Stüde 2024] §3.2): [`scan`] — 2-D laser scans as the
//! sensors give them (ranges at evenly spaced angles, REP 117 no-returns) and their points.
//!
//! [Stüde 2024]: M. Stüde, *Navigation and localisation of mobile robots in changing
//! environments* (dissertation), Leibniz Universität Hannover, 2024.
#![deny(missing_docs)]

pub mod scan;

pub use scan::{Scan2d, ScanError};
