//! Days off: public holidays and closures that a daily and weekly rhythm cannot know.
//!
//! The greg door's first public test week holds Good Friday (2016-03-25): the office stayed shut
//! and every model, having learned that Fridays are busy, predicted it open. A model of rhythms
//! has no way to learn a holiday from ten weeks without one; a user who knows the calendar
//! can say so. [`DaysOff`] holds the days (UTC dates) and predicts a day off as the most recent
//! Sunday that was not one, at the same time of day ([`DaysOff::stand_in`]): a closed office
//! looks like its weekend. Any [`TemporalModel`] can be asked this way
//! ([`DaysOff::predict_many`]), so the stack and its members need no change.
//!
//! ```
//! use chronomap_core::calendar::DaysOff;
//! use chronomap_core::time::days_from_civil;
//!
//! // Good Friday 2016 and Easter Monday.
//! let days_off = DaysOff::new([days_from_civil(2016, 3, 25), days_from_civil(2016, 3, 28)]);
//! let friday_10am = 86_400.0 * days_from_civil(2016, 3, 25) as f64 + 10.0 * 3600.0;
//! let sunday_10am = 86_400.0 * days_from_civil(2016, 3, 20) as f64 + 10.0 * 3600.0;
//! assert_eq!(days_off.stand_in(friday_10am), sunday_10am);
//! assert_eq!(days_off.stand_in(friday_10am + 86_400.0), friday_10am + 86_400.0); // Saturday
//! ```

use std::borrow::Cow;
use std::collections::BTreeSet;

use serde::{Deserialize, Serialize};

use crate::model::TemporalModel;

/// Seconds in a day.
const DAY: f64 = 86_400.0;

/// Longest run of consecutive days off a stand-in looks back over (a year); days further
/// back are not searched and the time is predicted as it is.
const MAX_LOOKBACK_DAYS: i64 = 366;

/// A set of days off, as days since 1970-01-01 (UTC dates).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct DaysOff {
    days: BTreeSet<i64>,
}

impl DaysOff {
    /// The days `days` (days since 1970-01-01, as [`crate::time::days_from_civil`] counts).
    pub fn new(days: impl IntoIterator<Item = i64>) -> Self {
        DaysOff {
            days: days.into_iter().collect(),
        }
    }

    /// Number of days off.
    pub fn len(&self) -> usize {
        self.days.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.days.is_empty()
    }

    /// The days, in increasing order.
    pub fn days(&self) -> impl Iterator<Item = i64> + '_ {
        self.days.iter().copied()
    }

    /// Whether the UTC date of `time` (seconds) is a day off (non-finite times are not).
    pub fn contains(&self, time: f64) -> bool {
        time.is_finite() && self.days.contains(&day_of(time))
    }

    /// The time whose prediction stands for `time`: `time` itself on a working day; on a day
    /// off, the same time of day on the most recent Sunday that is not a day off (within a
    /// year; else `time` itself).
    pub fn stand_in(&self, time: f64) -> f64 {
        if !self.contains(time) {
            return time;
        }
        let day = day_of(time);
        // 1970-01-01 was a Thursday: day d is a Sunday when (d + 4) mod 7 = 0.
        (1..=MAX_LOOKBACK_DAYS)
            .map(|back| day - back)
            .find(|d| (d + 4).rem_euclid(7) == 0 && !self.days.contains(d))
            .map_or(time, |sunday| time - (day - sunday) as f64 * DAY)
    }

    /// The days off of both.
    pub fn union(&self, other: &DaysOff) -> DaysOff {
        DaysOff {
            days: self.days.union(&other.days).copied().collect(),
        }
    }

    /// The observations `(times[i], values[i])` made on working days: what a model of the
    /// rhythms learns from (a day off is predicted by its stand-in, never learned). Without
    /// days off they are the slices themselves, not a copy.
    ///
    /// # Panics
    /// If the slices differ in length.
    pub fn working_days<'a>(
        &self,
        times: &'a [f64],
        values: &'a [f64],
    ) -> (Cow<'a, [f64]>, Cow<'a, [f64]>) {
        assert_eq!(times.len(), values.len(), "one value per time");
        if self.is_empty() {
            return (Cow::Borrowed(times), Cow::Borrowed(values));
        }
        let (times, values): (Vec<f64>, Vec<f64>) = times
            .iter()
            .zip(values)
            .filter(|(t, _)| !self.contains(**t))
            .unzip();
        (Cow::Owned(times), Cow::Owned(values))
    }

    /// The times whose predictions stand for `times`: each day off moved to its
    /// [stand-in](Self::stand_in). Without days off, `times` themselves, not a copy.
    pub fn stand_ins<'a>(&self, times: &'a [f64]) -> Cow<'a, [f64]> {
        if self.is_empty() {
            return Cow::Borrowed(times);
        }
        times.iter().map(|&t| self.stand_in(t)).collect()
    }

    /// `model`'s predictions at `times`, each day off predicted by its [stand-in](Self::stand_in).
    pub fn predict_many<M: TemporalModel + ?Sized>(&self, model: &M, times: &[f64]) -> Vec<f64> {
        model.predict_many(&self.stand_ins(times))
    }
}

/// Days since 1970-01-01 of the UTC date of `time`.
fn day_of(time: f64) -> i64 {
    (time / DAY).floor() as i64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::time::days_from_civil;
    use crate::{HistogramModel, TemporalModel};

    #[test]
    fn a_run_of_days_off_over_a_sunday_looks_further_back() {
        // 2016-12-24 (Sat) to 2016-12-27 (Tue) off, Sunday the 25th included: the 26th
        // stands in for the Sunday before, the 18th.
        let days = (24..=27).map(|d| days_from_civil(2016, 12, d));
        let off = DaysOff::new(days);
        let t = 86_400.0 * days_from_civil(2016, 12, 26) as f64 + 3600.0 * 8.5;
        let expected = 86_400.0 * days_from_civil(2016, 12, 18) as f64 + 3600.0 * 8.5;
        assert_eq!(off.stand_in(t), expected);
        assert!(off.contains(t) && !off.contains(expected));
        assert!(off.stand_in(f64::NAN).is_nan());
        assert_eq!(off.len(), 4);
    }

    #[test]
    fn working_days_leave_out_the_days_off_and_calendars_unite() {
        let off = DaysOff::new([days_from_civil(2016, 3, 25)]);
        let day = |d: u32| 86_400.0 * days_from_civil(2016, 3, d) as f64;
        let observed = [day(24), day(25) + 1.0, day(26) + 1.0];
        let (times, values) = off.working_days(&observed, &[1.0, 2.0, 3.0]);
        assert_eq!(*times, [day(24), day(26) + 1.0]);
        assert_eq!(*values, [1.0, 3.0]);
        let both = off.union(&DaysOff::new([days_from_civil(2016, 3, 28)]));
        assert_eq!(both.len(), 2);
        assert_eq!(both.union(&off), both);
    }

    #[test]
    fn a_weekly_histogram_predicts_a_holiday_as_its_sunday() {
        // Busy (1) on weekdays 8–18 h, idle otherwise; two weeks from Monday 2016-03-07.
        let start = 86_400.0 * days_from_civil(2016, 3, 7) as f64;
        let times: Vec<f64> = (0..14 * 24)
            .map(|h| start + 3600.0 * f64::from(h))
            .collect();
        let values: Vec<f64> = times
            .iter()
            .map(|&t| {
                let (day, hour) = ((t - start) / 86_400.0, (t % 86_400.0) / 3600.0);
                let weekday = (day.floor() as i64).rem_euclid(7) < 5;
                f64::from(u8::from(weekday && (8.0..18.0).contains(&hour)))
            })
            .collect();
        let mut model = HistogramModel::new(168, 7.0 * 86_400.0).unwrap();
        model.observe(&times, &values).unwrap();
        let good_friday_noon = 86_400.0 * days_from_civil(2016, 3, 25) as f64 + 12.0 * 3600.0;
        let off = DaysOff::new([days_from_civil(2016, 3, 25)]);
        assert_eq!(model.predict(good_friday_noon), 1.0);
        assert_eq!(off.predict_many(&model, &[good_friday_noon]), [0.0]);
        let thursday_noon = good_friday_noon - 86_400.0;
        assert_eq!(off.predict_many(&model, &[thursday_noon]), [1.0]);
    }
}
