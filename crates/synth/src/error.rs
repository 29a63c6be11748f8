//! The error type of the synthetic workloads.

use thiserror::Error;

/// Why a workload configuration or a cell range was rejected. Every variant names the
/// offending field and carries the value given.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum SynthError {
    /// A configuration field is outside its range.
    #[error("{field} = {value} is out of range: expected {expected}")]
    Config {
        /// The field, as named in the configuration struct (e.g. `"frame_secs"`).
        field: &'static str,
        /// The value given.
        value: String,
        /// What is accepted.
        expected: &'static str,
    },
    /// A range of cells cannot be streamed.
    #[error("cell range {start}..{end} is invalid: {field} must be {expected}")]
    Range {
        /// `"range.start"` or `"range.end"`.
        field: &'static str,
        /// The range's start.
        start: usize,
        /// The range's end.
        end: usize,
        /// What is accepted.
        expected: String,
    },
}

impl SynthError {
    /// The offending field.
    pub fn field(&self) -> &'static str {
        match self {
            SynthError::Config { field, .. } | SynthError::Range { field, .. } => field,
        }
    }
}
