//! Error types of the core crate.
//!
//! Every variant carries the offending value and, for batch input, the index of the
//! offending element inside the batch, so that the I/O layer can name a file and line.

use thiserror::Error;

use crate::num::fmt_number;

/// Why a batch of observations was rejected. A rejected batch leaves the model unchanged.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ObservationError {
    /// `times` and `values` have different lengths.
    #[error("{times} times but {values} values")]
    LengthMismatch {
        /// Number of times given.
        times: usize,
        /// Number of values given.
        values: usize,
    },
    /// A time is NaN or infinite.
    #[error("time {} is not a finite number", fmt_number(.time))]
    NonFiniteTime {
        /// Index in the batch.
        index: usize,
        /// The offending time.
        time: f64,
    },
    /// A time is negative (times are unix seconds, or seconds from a dataset start, ≥ 0).
    #[error("time {} is negative (times are seconds >= 0)", fmt_number(.time))]
    NegativeTime {
        /// Index in the batch.
        index: usize,
        /// The offending time.
        time: f64,
    },
    /// A time is after [`MAX_TIME_SECS`](crate::observe::MAX_TIME_SECS) (10^11 s).
    #[error("time {time:e} s is after the largest time 1e11 s (about the year 5138)")]
    TimeTooLarge {
        /// Index in the batch.
        index: usize,
        /// The offending time.
        time: f64,
    },
    /// A time is earlier than the observation before it (observations must be in time order).
    #[error(
        "time {} is earlier than the previous observation at {}",
        fmt_number(.time),
        fmt_number(.previous)
    )]
    TimeNotIncreasing {
        /// Index in the batch.
        index: usize,
        /// The offending time.
        time: f64,
        /// The latest time observed before it.
        previous: f64,
    },
    /// A value is NaN or infinite.
    #[error("value {} is not a finite number", fmt_number(.value))]
    NonFiniteValue {
        /// Index in the batch.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// A value lies outside [0, 1].
    #[error("value {} is outside [0, 1]", fmt_number(.value))]
    ValueOutOfRange {
        /// Index in the batch.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// A model of binary states got a value other than 0 or 1.
    #[error("value {} is not binary (0 or 1)", fmt_number(.value))]
    NonBinaryValue {
        /// Index in the batch.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// A model of uniformly sampled series got a time off its sampling grid.
    #[error(
        "time {} is not the next sample time {} of the uniform series",
        fmt_number(.time),
        fmt_number(.expected)
    )]
    OffGrid {
        /// Index in the batch.
        index: usize,
        /// The offending time.
        time: f64,
        /// The time the next sample must have.
        expected: f64,
    },
}

impl ObservationError {
    /// Index of the offending element within its batch, if the error concerns one element.
    pub fn index(&self) -> Option<usize> {
        match *self {
            ObservationError::LengthMismatch { .. } => None,
            ObservationError::NonFiniteTime { index, .. }
            | ObservationError::NegativeTime { index, .. }
            | ObservationError::TimeTooLarge { index, .. }
            | ObservationError::TimeNotIncreasing { index, .. }
            | ObservationError::NonFiniteValue { index, .. }
            | ObservationError::ValueOutOfRange { index, .. }
            | ObservationError::NonBinaryValue { index, .. }
            | ObservationError::OffGrid { index, .. } => Some(index),
        }
    }

    /// Whether the error concerns a time (as opposed to a value).
    pub fn is_about_time(&self) -> bool {
        matches!(
            self,
            ObservationError::NonFiniteTime { .. }
                | ObservationError::NegativeTime { .. }
                | ObservationError::TimeTooLarge { .. }
                | ObservationError::TimeNotIncreasing { .. }
                | ObservationError::OffGrid { .. }
        )
    }
}

/// Why a model configuration or model specification was rejected.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// A period is zero, negative or not finite.
    #[error(
        "period {} s is not a positive finite number",
        fmt_number(.period_secs)
    )]
    PeriodNotPositive {
        /// The offending period in seconds.
        period_secs: f64,
    },
    /// A period is shorter than [`MIN_PERIOD_SECS`](crate::periods::MIN_PERIOD_SECS) (times
    /// are seconds up to 10^11, whose resolution is far coarser than such a period).
    #[error(
        "period {} s is shorter than the shortest period {} s",
        fmt_number(.period_secs),
        crate::periods::MIN_PERIOD_SECS
    )]
    PeriodTooShort {
        /// The offending period in seconds.
        period_secs: f64,
    },
    /// A period set has no periods.
    #[error("the set of candidate periods is empty")]
    NoPeriods,
    /// A period set is too large.
    #[error("{count} candidate periods requested; at most {max} are supported")]
    TooManyPeriods {
        /// Requested number.
        count: usize,
        /// Largest supported number.
        max: usize,
    },
    /// A numeric parameter is outside its range.
    #[error("{name} = {value} is out of range: {expected}")]
    OutOfRange {
        /// Parameter name.
        name: &'static str,
        /// The value given.
        value: String,
        /// What is accepted.
        expected: &'static str,
    },
    /// A textual specification could not be parsed.
    #[error("cannot parse {what} {text:?}: {reason}")]
    Parse {
        /// What was being parsed (e.g. "model", "period set").
        what: &'static str,
        /// The text given.
        text: String,
        /// Why it failed, including what would be accepted.
        reason: String,
    },
}

/// Why a model could not be built from a data set.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum BuildError {
    /// The configuration is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The data violate the observation contract or the model's input requirements.
    #[error(transparent)]
    Observation(#[from] ObservationError),
    /// There are not enough data to build the model.
    #[error("not enough data: {0}")]
    NotEnoughData(String),
}

impl BuildError {
    /// Index of the offending observation, for errors about one observation.
    pub fn observation_index(&self) -> Option<usize> {
        match self {
            BuildError::Observation(e) => e.index(),
            _ => None,
        }
    }
}

/// Checks a setting that must be a positive finite number. The error is the message
/// `"{what} {value} is not a positive number"`, for the caller to wrap in its own
/// configuration error.
///
/// # Errors
/// The message for a value that is not finite or not above 0.
pub fn check_positive(what: &str, value: f64) -> Result<(), String> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(format!(
            "{what} {} is not a positive number",
            crate::num::fmt_number(value)
        ))
    }
}
