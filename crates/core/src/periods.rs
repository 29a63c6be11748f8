//! Candidate periods of the spectral models (the set Ω of [Krajník 2017] §III-C).

use std::f64::consts::TAU;
use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::ConfigError;

/// Seconds in a week.
pub const WEEK: f64 = 604_800.0;
/// Seconds in a day.
pub const DAY: f64 = 86_400.0;
/// Seconds in a Julian year (365.25 days).
pub const YEAR: f64 = 31_557_600.0;
/// Largest number of candidate periods a set may have.
pub const MAX_PERIODS: usize = 1 << 16;

/// The shortest period of a set, in seconds (1 ms): times are seconds up to 10^11, which an
/// `f64` resolves to about 10 µs, so a shorter period has no meaningful phase.
pub const MIN_PERIOD_SECS: f64 = 1e-3;

/// The candidate periods Ω a spectral model tracks.
///
/// The default, [`PeriodSet::week_harmonics`], is one week divided by `k = 1..=84`
/// (one week down to two hours): the configuration of the original FreMEn benchmark code,
/// which reproduces its published figures. Harmonic sets are evaluated with a fast,
/// exact-phase recurrence; arbitrary lists are supported too.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum PeriodSet {
    /// `base_secs / k` for `k = 1..=count`: the frequencies of a DFT over `base_secs`.
    Harmonics {
        /// Longest period, in seconds.
        base_secs: f64,
        /// Number of harmonics.
        count: u32,
    },
    /// Any list of periods in seconds.
    List(Vec<f64>),
}

impl Default for PeriodSet {
    fn default() -> Self {
        PeriodSet::week_harmonics()
    }
}

impl PeriodSet {
    /// One week divided by 1..=84: periods from one week down to two hours.
    pub fn week_harmonics() -> Self {
        PeriodSet::Harmonics {
            base_secs: WEEK,
            count: 84,
        }
    }

    /// One (Julian) year divided by 1..=1095: periods from a year down to 8 hours
    /// (about the 1000-component set of [Krajník 2017] §VII-B).
    pub fn year_harmonics() -> Self {
        PeriodSet::Harmonics {
            base_secs: YEAR,
            count: 1095,
        }
    }

    /// `base_secs / k` for `k = 1..=count`.
    ///
    /// # Errors
    /// If `base_secs` is not positive and finite, `count` is 0 or above [`MAX_PERIODS`], or
    /// the shortest period `base_secs / count` is below [`MIN_PERIOD_SECS`].
    pub fn harmonics(base_secs: f64, count: u32) -> Result<Self, ConfigError> {
        check_period(base_secs)?;
        if count == 0 {
            return Err(ConfigError::NoPeriods);
        }
        if count as usize > MAX_PERIODS {
            return Err(ConfigError::TooManyPeriods {
                count: count as usize,
                max: MAX_PERIODS,
            });
        }
        // The shortest harmonic too.
        check_period(base_secs / f64::from(count))?;
        Ok(PeriodSet::Harmonics { base_secs, count })
    }

    /// An arbitrary list of periods in seconds (kept in the order given).
    ///
    /// # Errors
    /// If the list is empty, too long, or a period is not positive and finite or below
    /// [`MIN_PERIOD_SECS`].
    pub fn from_periods(periods: Vec<f64>) -> Result<Self, ConfigError> {
        if periods.is_empty() {
            return Err(ConfigError::NoPeriods);
        }
        if periods.len() > MAX_PERIODS {
            return Err(ConfigError::TooManyPeriods {
                count: periods.len(),
                max: MAX_PERIODS,
            });
        }
        for &p in &periods {
            check_period(p)?;
        }
        Ok(PeriodSet::List(periods))
    }

    /// Number of periods.
    pub fn len(&self) -> usize {
        match self {
            PeriodSet::Harmonics { count, .. } => *count as usize,
            PeriodSet::List(list) => list.len(),
        }
    }

    /// Whether the set is empty (never true for a validated set).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The `i`-th period in seconds.
    ///
    /// # Panics
    /// If `i >= self.len()`.
    pub fn period(&self, i: usize) -> f64 {
        match self {
            PeriodSet::Harmonics { base_secs, count } => {
                assert!(i < *count as usize, "period index {i} out of range");
                base_secs / (i + 1) as f64
            }
            PeriodSet::List(list) => list[i],
        }
    }

    /// All periods in seconds.
    pub fn periods(&self) -> Vec<f64> {
        (0..self.len()).map(|i| self.period(i)).collect()
    }

    /// Validates a set that may come from a deserialised file.
    ///
    /// # Errors
    /// As [`PeriodSet::harmonics`] / [`PeriodSet::from_periods`].
    pub fn validated(self) -> Result<Self, ConfigError> {
        match self {
            PeriodSet::Harmonics { base_secs, count } => PeriodSet::harmonics(base_secs, count),
            PeriodSet::List(list) => PeriodSet::from_periods(list),
        }
    }
}

fn check_period(period_secs: f64) -> Result<(), ConfigError> {
    if !(period_secs.is_finite() && period_secs > 0.0) {
        Err(ConfigError::PeriodNotPositive { period_secs })
    } else if period_secs < MIN_PERIOD_SECS {
        Err(ConfigError::PeriodTooShort { period_secs })
    } else {
        Ok(())
    }
}

/// Fraction of a period elapsed at `time`: `frac(time / period)` in `[0, 1)`.
///
/// Computed as `(time mod period) / period`; the remainder is exact in floating point,
/// so large unix times lose no phase accuracy (the original code cast times to `float`
/// and lost up to 128 s).
#[inline]
pub fn cycle_fraction(time: f64, period: f64) -> f64 {
    let r = time.rem_euclid(period) / period;
    if r >= 1.0 { 0.0 } else { r }
}

/// Phase angle `ω t mod 2π` of a period at `time`, in `[0, 2π)`.
#[inline]
pub fn phase_angle(time: f64, period: f64) -> f64 {
    TAU * cycle_fraction(time, period)
}

impl fmt::Display for PeriodSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PeriodSet::Harmonics { base_secs, count } => write!(f, "{base_secs}/{count}"),
            PeriodSet::List(list) => {
                let parts: Vec<String> = list.iter().map(|p| p.to_string()).collect();
                write!(f, "{}", parts.join(","))
            }
        }
    }
}

impl FromStr for PeriodSet {
    type Err = ConfigError;

    /// Parses `week` (604800/84), `day` (86400/24), `year` (31557600/1095),
    /// `BASE/COUNT` (harmonics of BASE seconds) or a comma list of periods in seconds.
    fn from_str(text: &str) -> Result<Self, ConfigError> {
        let parse_error = |reason: &str| ConfigError::Parse {
            what: "period set",
            text: text.to_string(),
            reason: format!(
                "{reason}; expected week, day, year, BASE/COUNT (e.g. 604800/168) or a comma list of seconds"
            ),
        };
        match text.trim() {
            "week" => Ok(PeriodSet::week_harmonics()),
            "day" => PeriodSet::harmonics(DAY, 24),
            "year" => Ok(PeriodSet::year_harmonics()),
            spec if spec.contains('/') => {
                let (base, count) = spec.split_once('/').expect("contains '/'");
                let base: f64 = base
                    .trim()
                    .parse()
                    .map_err(|_| parse_error("BASE is not a number"))?;
                let count: u32 = count
                    .trim()
                    .parse()
                    .map_err(|_| parse_error("COUNT is not a whole number"))?;
                PeriodSet::harmonics(base, count)
            }
            spec => {
                let periods = spec
                    .split(',')
                    .map(|p| p.trim().parse::<f64>())
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(|_| parse_error("not a number"))?;
                PeriodSet::from_periods(periods)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn periods_shorter_than_a_millisecond_are_refused() {
        for text in ["1e-300", "60,1e-300", "1e-300/1", "1/10000"] {
            let err = text.parse::<PeriodSet>().unwrap_err();
            assert!(
                matches!(err, ConfigError::PeriodTooShort { .. }),
                "{text}: {err}"
            );
        }
        let err = "1e-300".parse::<PeriodSet>().unwrap_err().to_string();
        assert_eq!(
            err,
            "period 1e-300 s is shorter than the shortest period 0.001 s"
        );
        assert!("0.001,60".parse::<PeriodSet>().is_ok());
        assert!("10/10000".parse::<PeriodSet>().is_ok());
    }

    #[test]
    fn week_harmonics_go_from_a_week_to_two_hours() {
        let set = PeriodSet::week_harmonics();
        assert_eq!(set.len(), 84);
        assert_eq!(set.period(0), WEEK);
        assert_eq!(set.period(6), DAY);
        assert_eq!(set.period(83), 7200.0);
    }

    #[test]
    fn parses_specs_and_rejects_nonsense() {
        assert_eq!(
            "week".parse::<PeriodSet>().unwrap(),
            PeriodSet::week_harmonics()
        );
        assert_eq!(
            "604800/168".parse::<PeriodSet>().unwrap(),
            PeriodSet::Harmonics {
                base_secs: WEEK,
                count: 168
            }
        );
        assert_eq!(
            "86400, 43200".parse::<PeriodSet>().unwrap(),
            PeriodSet::List(vec![86400.0, 43200.0])
        );
        assert!("0/5".parse::<PeriodSet>().is_err());
        assert!("604800/0".parse::<PeriodSet>().is_err());
        assert!("86400,-5".parse::<PeriodSet>().is_err());
        assert!("abc".parse::<PeriodSet>().is_err());
    }

    #[test]
    fn cycle_fraction_is_exact_for_large_times() {
        // 2016-01-04 00:00 UTC is a Monday midnight: whole number of days since the epoch.
        assert_eq!(cycle_fraction(1_451_865_600.0, DAY), 0.0);
        assert_eq!(cycle_fraction(1_451_865_600.0 + 21_600.0, DAY), 0.25);
    }
}
