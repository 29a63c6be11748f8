//! # chronomap-models
//!
//! Every temporal model of chronomap by name: [`ModelSpec`] parses `fremen:auto`, `hist:24`,
//! `hyt-em:3` or `auto` and fits it; [`AnyModel`] is the serialisable union of all models that
//! files, the command line and the service pass around; [`learner`] learns any spec online
//! ([`Learner`]: the model itself where it learns online, else kept observations refitted on
//! request, `auto` included); [`eval`] runs the train/test
//! experiment of the FreMEn benchmarks over any list of specs; [`stack`] what `auto` fits, a
//! combination of many models weighted by rolling-origin cross-validation; [`features`] the feature
//! visibility experiment (which features will the robot see?); [`split`] chronological
//! splits of one series into training and test parts.
//!
//! The Warped Hypertime models come from `chronomap-hypertime` behind the `hypertime` cargo
//! feature (on by default); without it, crates that only need the FreMEn family (topological
//! edge models) do not compile the mixture code and its linear algebra.
#![deny(missing_docs)]

pub mod calendar;
pub mod eval;
pub mod features;
pub mod learner;
pub mod spec;
pub mod split;
pub mod stack;

pub use learner::{Learner, RefitPolicy};
pub use spec::{AnyModel, FitOptions, ModelSpec};
