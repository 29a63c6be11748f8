//! # chronomap-app
//!
//! The application layer between chronomap's domains and its faces (the command line, the
//! service, the Python package and the ROS 2 node), in the spirit of kiss-icp's `pipeline`:
//! what more than one face needs and no single domain owns. The domains stay pure (no I/O,
//! clock or printing); the faces only translate arguments, messages and errors; everything that
//! combines files with algorithms into a job lives here, once.
//!
//! Data still flow one way, observations → models → predictions → decisions: this crate
//! depends on the domains and on `chronomap-io`, and nothing below it depends on it.
#![deny(missing_docs)]

pub mod activity;
pub mod bt;
pub mod compress;
pub mod disturbance;
pub mod eval;
pub mod events;
pub mod explore;
pub mod grid;
pub mod ingest;
pub mod laser_log;
pub mod lidar_study;
pub mod open;
pub mod topo;
