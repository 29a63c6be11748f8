//! # chronomap-hypertime
//!
//! Warped Hypertime (Krajník et al., RA-L 2019): continuous models of where and when. Time is
//! projected onto circles of the periods found in the data ([`hypertime`]), Gaussian mixtures
//! are fitted in that warped space by robust EM or k-means ([`mixture`]), and events in the
//! plane — people seen in a corridor — become counts and intensities on spatio-temporal grids
//! ([`events`]).
#![deny(missing_docs)]

pub mod events;
pub mod hypertime;
pub mod mixture;

pub use hypertime::{HypertimeConfig, HypertimeModel};
