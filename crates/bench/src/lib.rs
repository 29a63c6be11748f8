//! Benchmarks of chronomap: every fast path is timed against a baseline measured in the same
//! run on the same machine, and the ratio is reported (see BENCHMARKS.md).
//!
//! One module per domain. Each exposes a function that runs its benchmark from a config struct
//! and returns a result struct (`serde::Serialize`) with the timings, the baseline timings of
//! the same run and the ratios; printing (tables, `--json`) is the caller's:
//! `chronomap bench plan|serve|activity|psbt|registration` and the `chronomap-bench` binary of this crate
//! (the FreMEn benchmarks).
//!
//! * [`fremen`]: FFT FreMEn build, FreMEn observe and predict ([Krajník 2017]) against the textbook
//!   transforms of `chronomap_core::naive`.
//! * [`grid`]: the occupancy-grid build at paper scale ([Krajník 2017] §VI) against a bare scan of
//!   the same frames.
//! * [`grid_memory`]: memory and file size per changing cell of occupancy grids against the
//!   representation of grid-state format 1, for 10⁴ to 4·10⁶ cells.
//! * [`ingest`]: reading ROS 2 bags (`chronomap ingest`) against a bare read of the same file.
//! * [`plan`]: planning on the Witham map ([Fentanes 2015] §V) against Storm on the same cases.
//! * `serve` (feature `serve`): the service on loopback against the same work done in-process.
//! * [`activity`]: CoPA-Map's training-data extraction and training ([Stüde 2024] chapter 4)
//!   against bare scans and bare matrix products.
//! * [`bt`]: reading and checking BehaviorTree.CPP 4 XML (100,000 siblings, deep nesting, many
//!   attributes) against parsing the same text with roxmltree alone.
//! * [`registration`]: registration of two 3-D clouds without an initial guess ([Stüde 2024]
//!   §3.2.2) against a bare nearest-neighbour pass over the same clouds.
//! * [`ros2`]: delivery delay of the ROS 2 node's 1 MB and 4 MB predicted maps to an rclpy
//!   subscriber against Fast DDS to Fast DDS (rclpy publisher, same subscriber).
//! * [`psbt`]: person search tree synthesis ([Stüde 2024] §5.4.3) against the dense reference and
//!   a per-tree solve.
//!
//! Benchmarks are an edge of the workspace: they read clocks and files. The algorithms they
//! time come from the library crates; a baseline written only for a benchmark lives here, with
//! a doc comment saying what it is the baseline of (slow oracles that tests need too live in
//! the domain crates' `naive` modules).
#![deny(missing_docs)]

pub mod activity;
pub mod bt;
mod error;
#[cfg(feature = "serve")]
pub mod fleet;
pub mod fremen;
pub mod grid;
pub mod grid_memory;
pub mod ingest;
pub mod plan;
pub mod psbt;
pub mod registration;
pub mod ros2;
#[cfg(feature = "serve")]
pub mod serve;
#[cfg(feature = "serve")]
pub mod serve_grid;

pub use error::BenchError;

pub use chronomap_core::num::median;
