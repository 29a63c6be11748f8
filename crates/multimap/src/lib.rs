//! # chronomap-multimap
//!
//! Modular multi-map management ([Stüde 2024] §3.3).
#![deny(missing_docs)]
