//! Chronological splits of one series into a training part and later test parts (the
//! protocol of the deployed FreMEn tools and of [Krajník 2019] §V-C: train on what came before a
//! time, test on each following interval).
//!
//! ```
//! use chronomap_models::split::{SplitError, chronological_split};
//!
//! let times = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0];
//! let parts = chronological_split(&times, &[20.0, 40.0])?;
//! assert_eq!(parts.train, 0..2);
//! assert_eq!(parts.tests, [2..4, 4..6]);
//! assert_eq!(
//!     chronological_split(&times, &[40.0, 20.0]),
//!     Err(SplitError::NotIncreasing { previous: 40.0, next: 20.0 })
//! );
//! # Ok::<(), SplitError>(())
//! ```

use std::ops::Range;

use thiserror::Error;

/// The parts of a split, as index ranges of the series.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChronologicalSplit {
    /// Observations before the first split time.
    pub train: Range<usize>,
    /// For each split time `a_i`: the observations at or after it and before the next split
    /// time (the last one: to the end).
    pub tests: Vec<Range<usize>>,
}

/// Why a series cannot be split at the times given.
#[derive(Clone, Debug, PartialEq, Error)]
#[non_exhaustive]
pub enum SplitError {
    /// No split time was given.
    #[error("no split time given")]
    NoTimes,
    /// The split times do not increase.
    #[error("{next} is not after {previous} (split times must increase)")]
    NotIncreasing {
        /// The earlier split time in the list.
        previous: f64,
        /// The split time that is not after it.
        next: f64,
    },
    /// No observation comes before the first split time.
    #[error("no observation before {before}")]
    EmptyTrain {
        /// The first split time.
        before: f64,
    },
    /// An interval between split times (or after the last) holds no observation.
    #[error("no observation from {from} to {to}")]
    EmptyTest {
        /// Start of the interval.
        from: f64,
        /// End of the interval (infinite for the last).
        to: f64,
    },
}

/// Splits a series with non-decreasing `times` at the increasing times `at`: training on
/// `[−∞, a_1)`, tests on `[a_1, a_2)`, …, `[a_k, ∞)`.
///
/// # Errors
/// No split time, split times that do not increase, or a part without observations.
pub fn chronological_split(times: &[f64], at: &[f64]) -> Result<ChronologicalSplit, SplitError> {
    let (&first, _) = at.split_first().ok_or(SplitError::NoTimes)?;
    if let Some(w) = at
        .windows(2)
        .find(|w| w[0].partial_cmp(&w[1]) != Some(std::cmp::Ordering::Less))
    {
        return Err(SplitError::NotIncreasing {
            previous: w[0],
            next: w[1],
        });
    }
    let index = |t: f64| times.partition_point(|&x| x < t);
    let train = 0..index(first);
    if train.is_empty() {
        return Err(SplitError::EmptyTrain { before: first });
    }
    let mut tests = Vec::with_capacity(at.len());
    for (i, &from) in at.iter().enumerate() {
        let to = at.get(i + 1).copied().unwrap_or(f64::INFINITY);
        let part = index(from)..index(to);
        if part.is_empty() {
            return Err(SplitError::EmptyTest { from, to });
        }
        tests.push(part);
    }
    Ok(ChronologicalSplit { train, tests })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_hold_the_observations_of_their_intervals() {
        // Equal times at a boundary go to the later part.
        let times = [1.0, 2.0, 3.0, 3.0, 5.0, 8.0];
        let parts = chronological_split(&times, &[3.0]).unwrap();
        assert_eq!(parts.train, 0..2);
        assert_eq!((parts.tests.len(), parts.tests[0].clone()), (1, 2..6));
        let parts = chronological_split(&times, &[2.5, 4.0, 6.0]).unwrap();
        assert_eq!(parts.tests, [2..4, 4..5, 5..6]);
        assert_eq!(
            chronological_split(&times, &[1.0]),
            Err(SplitError::EmptyTrain { before: 1.0 })
        );
        assert_eq!(
            chronological_split(&times, &[2.5, 2.8]),
            Err(SplitError::EmptyTest { from: 2.5, to: 2.8 })
        );
        assert_eq!(
            chronological_split(&times, &[2.0, 9.0]),
            Err(SplitError::EmptyTest {
                from: 9.0,
                to: f64::INFINITY
            })
        );
        assert_eq!(chronological_split(&times, &[]), Err(SplitError::NoTimes));
        assert_eq!(
            chronological_split(&times, &[3.0, 3.0]),
            Err(SplitError::NotIncreasing {
                previous: 3.0,
                next: 3.0
            })
        );
    }
}
