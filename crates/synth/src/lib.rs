//! # chronomap-synth
//!
//! Seeded, reproducible synthetic workloads with known ground truth for chronomap's
//! benchmarks and accuracy tests. Pure code: no I/O, no printing, no clocks; every random
//! draw comes from the configuration's seed through [`rng`] (the PRNG of chronomap-core).
//!
//! * [`office`] — a 4-D occupancy grid of an office at the scale of the FreMEn paper
//!   ([Krajník 2017] §VI: 213,000 cells, a frame every 5 s, 112 days), streamed frame by frame
//!   so that the ~51 GB of frame bits never exist in memory at once.
//! * [`stats`] — per-cell statistics of a streamed range (the static model's error).
//! * [`office_grid`] — the office as a `chronomap-grid` grid: its geometry and its streams as
//!   a source of partitioned builds.
//!
//! ```
//! use chronomap_synth::office::{OfficeConfig, OfficeWorkload};
//!
//! let office = OfficeWorkload::new(OfficeConfig { cells: 640, days: 1, ..OfficeConfig::default() })?;
//! let mut stream = office.stream(0..640)?;
//! let mut events = 0;
//! while let Some((frame, time, bits)) = stream.next_frame() {
//!     assert_eq!(time, office.frame_time(frame));
//!     assert_eq!(bits.len(), 10); // 640 cells, 64 a word
//!     events += stream.last_changes().len();
//! }
//! assert_eq!(office.frames(), 17_280);
//! assert!(events > 0);
//! # Ok::<(), chronomap_synth::SynthError>(())
//! ```
#![deny(missing_docs)]

pub mod error;
pub mod office;
pub mod office_grid;
/// Seeded pseudo-random numbers (shared with the rest of chronomap).
pub use chronomap_core::rng;
pub mod stats;

pub use error::SynthError;
pub use office::{CellClass, FrameStream, OfficeConfig, OfficeWorkload};
