//! # chronomap-core
//!
//! Pure algorithms for world models that know time: models of a state (a door, a grid cell,
//! a corridor, a person's presence) that learn from sparse, irregular observations how it
//! changes with daily and weekly rhythms, and predict it for any time as a probability whose
//! calibration [`calibration`] measures. No I/O, no printing, no clocks, no global state: file
//! formats, plots and the command line live in `chronomap-io` and the `chronomap` binary.
//!
//! ```
//! use chronomap_core::{FremenModel, TemporalModel, Ordered};
//!
//! // An office door observed every 10 minutes for two weeks: open 9:00-17:00.
//! let times: Vec<f64> = (0..2 * 7 * 144).map(|i| 1_451_865_600.0 + 600.0 * i as f64).collect();
//! let open: Vec<f64> = times.iter()
//!     .map(|&t| ((9.0..17.0).contains(&((t % 86_400.0) / 3600.0)) as u8) as f64)
//!     .collect();
//! let mut door = FremenModel::with_order(2);
//! door.observe(&times, &open)?;
//! let monday_noon_in_a_month = 1_451_865_600.0 + 28.0 * 86_400.0 + 12.0 * 3600.0;
//! assert!(door.predict(monday_noon_in_a_month) > 0.7);
//! assert_eq!(door.components()[0].period_secs, 86_400.0); // the daily rhythm
//! # Ok::<(), chronomap_core::ObservationError>(())
//! ```
//!
//! ## Layout
//! * [`TemporalModel`] — the one trait of a state over time; [`Ordered`] — models whose
//!   order can change without re-observing. [`conformance`] checks any implementation.
//! * Models: [`MeanModel`], [`HistogramModel`] (and [`recent::RecentHistogram`], which
//!   forgets all but the last cycles), [`FremenModel`] (non-uniform incremental FreMEn),
//!   [`PersistenceModel`], [`MarkovModel`] (short-term memory), [`PergamModel`] (periodic
//!   Gaussian mixture), [`FftFremen`] (FFT FreMEn with outlier set).
//! * [`select`] — order and model selection on held-back data. [`stacking`] — weights that
//!   combine models' out-of-sample predictions. [`anomaly`] — anomaly
//!   detection. [`metrics`] — Brier score, binary error, paired t-tests. [`calibration`] —
//!   reliability diagrams, expected calibration error, the Brier score's decomposition.
//!   [`spread`] — intervals of a continuous state from the models of its first two moments.
//!   [`calendar`] — days off (holidays) predicted as the Sunday before. [`naive`] — slow
//!   oracles for tests and benchmarks. [`Parallelism`] — how many threads a computation may
//!   use (results never depend on it); [`rng`] — seeded randomness; [`time`] — calendar
//!   conversions and ISO 8601 parsing without a clock.
//!
//! The other domains are crates of their own over this one (see `ARCHITECTURE.md`):
//! `chronomap-models` (models by name, the serialisable union of all models, the benchmark
//! experiment), `chronomap-grid`, `chronomap-explore`, `chronomap-hypertime`,
//! `chronomap-topo`, `chronomap-activity`, `chronomap-bt` and `chronomap-psbt`.
#![deny(missing_docs)]

pub mod anomaly;
pub mod calendar;
pub mod calibration;
pub mod conformance;
pub mod crossings;
pub mod error;
pub mod error_chain;
pub mod exact;
pub mod fft;
pub mod fremen;
pub mod hist;
pub mod mean;
pub mod metrics;
pub mod model;
pub mod naive;
pub mod num;
pub mod observe;
pub mod par;
pub mod pergam;
pub mod periods;
pub mod persistence;
pub mod progress;
pub mod recent;
/// Seeded pseudo-random numbers (the `chronomap-rng` crate).
pub use chronomap_rng as rng;
pub mod select;
pub mod spectrum;
pub mod spread;
pub mod stacking;
pub mod stm;
#[cfg(test)]
mod testdata;
pub mod time;
pub mod visibility;

pub use error::{BuildError, ConfigError, ObservationError};
pub use fft::{FftFremen, FftFremenConfig};
pub use fremen::{FremenConfig, FremenModel, FrequencyComponent};
pub use hist::HistogramModel;
pub use mean::MeanModel;
pub use model::{Ordered, TemporalModel, binary_entropy};
pub use observe::{ObservedSpan, TimeSeries};
pub use par::Parallelism;
pub use pergam::{PergamComponent, PergamConfig, PergamFit, PergamModel};
pub use periods::PeriodSet;
pub use persistence::PersistenceModel;
/// Complex numbers used by the spectral models.
pub use rustfft::num_complex::Complex64;
pub use stm::MarkovModel;
