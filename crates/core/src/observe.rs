//! Validation of observations and the bookkeeping every model shares.
//!
//! # The observation contract
//!
//! Every [`TemporalModel`](crate::TemporalModel) accepts observations `(t, s)` under one rule:
//!
//! * `t` is a finite number of seconds `>= 0` (unix time, or seconds from a dataset start)
//!   and at most [`MAX_TIME_SECS`] (10^11 s, about the year 5138: a time beyond it is a unit
//!   error, and a model that observed 1.8e308 could never observe a later time);
//! * times never go backwards: each time is `>=` the one before it, in the batch and across
//!   batches. Equal times are allowed and count as separate observations (a state observed
//!   twice at the same instant);
//! * `s` is finite and in `[0, 1]`: `0`/`1` for binary states, or a probability / normalised
//!   value;
//! * a batch is validated completely before anything is added: an error leaves the model
//!   exactly as it was, and names the index of the first offending element.
//!
//! Rejecting out-of-order times (instead of silently sorting or dropping them, as the
//! original FreMEn server did) keeps models that depend on order (persistence, Markov
//! chains) well defined and makes errors in upstream data visible.

use serde::{Deserialize, Serialize};

use crate::error::ObservationError;

/// Largest observation time (s) any model accepts: 10^11 s after the epoch, about the year
/// 5138. Unix times in milliseconds (1.7·10^12) are refused instead of learned as seconds.
pub const MAX_TIME_SECS: f64 = 1e11;

/// Observations in time order: `values[i]` was observed at `times[i]` (seconds).
///
/// What the readers of `chronomap-io` return satisfies the
/// [observation contract](self), so it can be passed to
/// [`TemporalModel::observe`](crate::TemporalModel::observe) as it is.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TimeSeries {
    /// Times in seconds, never decreasing.
    pub times: Vec<f64>,
    /// States in `[0, 1]`, one per time.
    pub values: Vec<f64>,
}

impl TimeSeries {
    /// Number of observations.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// The observations with `from <= t < to`, in order.
    pub fn between(&self, from: f64, to: f64) -> TimeSeries {
        let (times, values) = self
            .times
            .iter()
            .zip(&self.values)
            .filter(|&(&t, _)| t >= from && t < to)
            .map(|(&t, &v)| (t, v))
            .unzip();
        TimeSeries { times, values }
    }

    /// Whether there are no observations.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }
}

/// Count and time span of the observations a model has seen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ObservedSpan {
    /// Number of observations.
    pub count: u64,
    /// Time of the first observation (meaningless when `count == 0`).
    pub first: f64,
    /// Time of the latest observation (meaningless when `count == 0`).
    pub last: f64,
}

impl ObservedSpan {
    /// Latest observed time, if any.
    pub fn last_time(&self) -> Option<f64> {
        (self.count > 0).then_some(self.last)
    }

    /// Seconds between the first and the latest observation (0 when empty).
    pub fn duration(&self) -> f64 {
        if self.count == 0 {
            0.0
        } else {
            self.last - self.first
        }
    }

    /// Whether the span can be that of observations under the [contract](self) (for spans
    /// read from files): finite times, and `0 <= first <= last` once something was observed.
    pub fn is_consistent(&self) -> bool {
        self.first.is_finite()
            && self.last.is_finite()
            && (self.count == 0 || (0.0 <= self.first && self.first <= self.last))
    }

    /// Checks a batch against the [observation contract](self) given what was seen before.
    ///
    /// # Errors
    /// The first violation found, with its index in the batch.
    pub fn validate(&self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        validate(self.last_time(), times, values)
    }

    /// Records a batch that has already been validated.
    pub fn extend(&mut self, times: &[f64]) {
        if let (Some(&first), Some(&last)) = (times.first(), times.last()) {
            if self.count == 0 {
                self.first = first;
            }
            self.last = last;
            self.count += times.len() as u64;
        }
    }

    /// Span of the union of two spans (used when merging models).
    pub fn merged(&self, other: &ObservedSpan) -> ObservedSpan {
        match (self.count, other.count) {
            (0, _) => *other,
            (_, 0) => *self,
            _ => ObservedSpan {
                count: self.count + other.count,
                first: self.first.min(other.first),
                last: self.last.max(other.last),
            },
        }
    }
}

/// Checks a batch of observations against the [observation contract](self).
///
/// `previous` is the latest time already observed, if any.
///
/// # Errors
/// The first violation found, with its index in the batch.
pub fn validate(
    previous: Option<f64>,
    times: &[f64],
    values: &[f64],
) -> Result<(), ObservationError> {
    if times.len() != values.len() {
        return Err(ObservationError::LengthMismatch {
            times: times.len(),
            values: values.len(),
        });
    }
    let mut previous = previous;
    for (index, (&time, &value)) in times.iter().zip(values).enumerate() {
        check_time(index, time, previous)?;
        check_value(index, value)?;
        previous = Some(time);
    }
    Ok(())
}

/// Checks one time against the contract.
///
/// # Errors
/// [`ObservationError::NonFiniteTime`], [`ObservationError::NegativeTime`],
/// [`ObservationError::TimeTooLarge`] or [`ObservationError::TimeNotIncreasing`].
pub fn check_time(index: usize, time: f64, previous: Option<f64>) -> Result<(), ObservationError> {
    if !time.is_finite() {
        return Err(ObservationError::NonFiniteTime { index, time });
    }
    if time < 0.0 {
        return Err(ObservationError::NegativeTime { index, time });
    }
    if time > MAX_TIME_SECS {
        return Err(ObservationError::TimeTooLarge { index, time });
    }
    if let Some(previous) = previous
        && time < previous
    {
        return Err(ObservationError::TimeNotIncreasing {
            index,
            time,
            previous,
        });
    }
    Ok(())
}

/// Checks one value against the contract.
///
/// # Errors
/// [`ObservationError::NonFiniteValue`] or [`ObservationError::ValueOutOfRange`].
pub fn check_value(index: usize, value: f64) -> Result<(), ObservationError> {
    if !value.is_finite() {
        return Err(ObservationError::NonFiniteValue { index, value });
    }
    if !(0.0..=1.0).contains(&value) {
        return Err(ObservationError::ValueOutOfRange { index, value });
    }
    Ok(())
}

/// Checks that every value is exactly 0 or 1 (for models of binary states).
///
/// # Errors
/// [`ObservationError::NonBinaryValue`] for the first other value.
pub fn check_binary(values: &[f64]) -> Result<(), ObservationError> {
    match values.iter().position(|&v| v != 0.0 && v != 1.0) {
        Some(index) => Err(ObservationError::NonBinaryValue {
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_equal_times_and_rejects_backwards_ones() {
        assert!(validate(None, &[1.0, 1.0, 2.0], &[0.0, 1.0, 0.5]).is_ok());
        assert_eq!(
            validate(Some(5.0), &[6.0, 4.0], &[0.0, 0.0]),
            Err(ObservationError::TimeNotIncreasing {
                index: 1,
                time: 4.0,
                previous: 6.0
            })
        );
        assert_eq!(
            validate(Some(5.0), &[4.0], &[0.0]).unwrap_err().index(),
            Some(0)
        );
    }

    #[test]
    fn rejects_bad_numbers_with_their_index() {
        let err = validate(None, &[0.0, f64::NAN], &[0.0, 0.0]).unwrap_err();
        assert!(matches!(
            err,
            ObservationError::NonFiniteTime { index: 1, .. }
        ));
        let err = validate(None, &[0.0, -1.0], &[0.0, 0.0]).unwrap_err();
        assert!(matches!(
            err,
            ObservationError::NegativeTime { index: 1, .. }
        ));
        // The largest time is accepted, anything later (1.797e308) is not.
        assert!(validate(None, &[MAX_TIME_SECS], &[0.0]).is_ok());
        let err = validate(None, &[0.0, 1.797e308], &[0.0, 0.0]).unwrap_err();
        assert!(matches!(
            err,
            ObservationError::TimeTooLarge { index: 1, .. }
        ));
        assert!(err.is_about_time());
        let err = validate(None, &[0.0, 1.0], &[0.0, f64::INFINITY]).unwrap_err();
        assert!(matches!(
            err,
            ObservationError::NonFiniteValue { index: 1, .. }
        ));
        let err = validate(None, &[0.0, 1.0], &[1.5, 0.0]).unwrap_err();
        assert!(matches!(
            err,
            ObservationError::ValueOutOfRange { index: 0, .. }
        ));
        let err = validate(None, &[0.0], &[]).unwrap_err();
        assert_eq!(
            err,
            ObservationError::LengthMismatch {
                times: 1,
                values: 0
            }
        );
        assert!(check_binary(&[0.0, 1.0, 0.5]).is_err());
    }

    #[test]
    fn span_tracks_first_last_and_count() {
        let mut span = ObservedSpan::default();
        assert_eq!(span.last_time(), None);
        span.extend(&[3.0, 4.0]);
        span.extend(&[]);
        span.extend(&[10.0]);
        assert_eq!((span.count, span.first, span.last), (3, 3.0, 10.0));
        assert_eq!(span.duration(), 7.0);
    }
}
