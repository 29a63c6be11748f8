//! Benchmarks of chronomap as library functions: each times a fast path against a baseline
//! measured in the same run and returns the measurements (see BENCHMARKS.md). The
//! `chronomap bench ...` commands print them.
#![deny(missing_docs)]

pub mod grid;
