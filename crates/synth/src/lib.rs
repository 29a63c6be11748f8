//! # chronomap-synth
//!
//! Seeded, reproducible synthetic workloads with known ground truth for chronomap's
//! benchmarks and accuracy tests. Pure code: no I/O, no printing, no clocks; every random
//! draw comes from the configuration's seed through the crate's own [`rng`].
#![deny(missing_docs)]

pub mod error;
pub mod rng;

pub use error::SynthError;
