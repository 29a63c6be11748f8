//! # chronomap-registration
//!
//! Point-cloud registration ([Stüde 2024] §3.2.2).
#![deny(missing_docs)]
