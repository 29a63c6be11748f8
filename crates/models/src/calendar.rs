//! A model that keeps its calendar of days off: [`OnCalendar`].
//!
//! [`DaysOff`] answers a day off with the most recent Sunday
//! that is not one; `chronomap eval --days-off` and `predict --days-off` ask any model that
//! way. A model saved with its calendar (`chronomap fit --days-off`) does it by itself, so every
//! face that opens the file (`chronomap predict`, Python's `load`) predicts the holidays
//! without being told again: observations on a day off are not learned, and a day off is
//! predicted by its stand-in.
//!
//! ```
//! use chronomap_core::calendar::DaysOff;
//! use chronomap_core::time::days_from_civil;
//! use chronomap_core::{HistogramModel, TemporalModel};
//! use chronomap_models::AnyModel;
//! use chronomap_models::calendar::OnCalendar;
//!
//! // Open on weekdays 8-18 h, two weeks from Monday 2016-03-07.
//! let start = 86_400.0 * days_from_civil(2016, 3, 7) as f64;
//! let times: Vec<f64> = (0..14 * 24).map(|h| start + 3600.0 * f64::from(h)).collect();
//! let values: Vec<f64> = times
//!     .iter()
//!     .map(|&t| {
//!         let (day, hour) = ((t - start) / 86_400.0, (t % 86_400.0) / 3600.0);
//!         f64::from(u8::from(day.floor() as i64 % 7 < 5 && (8.0..18.0).contains(&hour)))
//!     })
//!     .collect();
//! let mut week = HistogramModel::new(168, 7.0 * 86_400.0)?;
//! week.observe(&times, &values)?;
//! let good_friday = days_from_civil(2016, 3, 25);
//! let model = OnCalendar::new(AnyModel::Histogram(week), DaysOff::new([good_friday]));
//! let noon = 86_400.0 * good_friday as f64 + 12.0 * 3600.0;
//! assert_eq!(model.predict(noon), 0.0); // shut, as on Sunday
//! assert_eq!(model.predict(noon - 86_400.0), 1.0); // Thursday is a working day
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use chronomap_core::calendar::DaysOff;
use chronomap_core::{ObservationError, ObservedSpan, TemporalModel};
use serde::{Deserialize, Serialize};

use crate::spec::AnyModel;

/// A model and the days off it predicts by their stand-ins (see the [module docs](self)).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct OnCalendar {
    model: AnyModel,
    days_off: DaysOff,
}

impl OnCalendar {
    /// `model` with the calendar `days_off`. A model that has a calendar already keeps one:
    /// the days off of both.
    pub fn new(model: AnyModel, days_off: DaysOff) -> Self {
        match model {
            AnyModel::Calendar(inner) => OnCalendar {
                days_off: inner.days_off.union(&days_off),
                model: inner.model,
            },
            model => OnCalendar { model, days_off },
        }
    }

    /// The model of the working days.
    pub fn model(&self) -> &AnyModel {
        &self.model
    }

    /// The model of the working days, to change (its order, say).
    pub fn model_mut(&mut self) -> &mut AnyModel {
        &mut self.model
    }

    /// The days off.
    pub fn days_off(&self) -> &DaysOff {
        &self.days_off
    }

    /// Whether a value read from a file can be used: the model is consistent and has no
    /// calendar of its own (calendars are merged, never nested).
    pub fn is_consistent(&self) -> bool {
        !matches!(self.model, AnyModel::Calendar(_)) && self.model.is_consistent()
    }
}

impl TemporalModel for OnCalendar {
    /// Learns the observations made on working days; those on days off are left out.
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        if times.len() != values.len() {
            // The model names a length mismatch as it always does.
            return self.model.observe(times, values);
        }
        let (times, values) = self.days_off.working_days(times, values);
        self.model.observe(&times, &values)
    }

    fn predict(&self, time: f64) -> f64 {
        self.model.predict(self.days_off.stand_in(time))
    }

    fn predict_into(&self, times: &[f64], out: &mut [f64]) {
        self.model
            .predict_into(&self.days_off.stand_ins(times), out);
    }

    fn span(&self) -> ObservedSpan {
        self.model.span()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_core::FremenModel;
    use chronomap_core::time::days_from_civil;

    /// Observations on a day off are not learned; the calendars of a model that has one
    /// already are merged, not nested.
    #[test]
    fn days_off_are_neither_learned_nor_nested() {
        let day = |d: u32| 86_400.0 * days_from_civil(2016, 3, d) as f64;
        let off = DaysOff::new([days_from_civil(2016, 3, 25)]);
        let mut model = OnCalendar::new(AnyModel::Fremen(FremenModel::with_order(0)), off);
        // Two working-day observations of 0 and one of 1 on the day off: the mean stays 0.
        model
            .observe(&[day(23), day(24), day(25) + 10.0], &[0.0, 0.0, 1.0])
            .unwrap();
        assert_eq!(model.predict(day(26)), 0.0);
        assert_eq!(model.span().count, 2);
        let merged = OnCalendar::new(
            AnyModel::Calendar(Box::new(model)),
            DaysOff::new([days_from_civil(2016, 3, 28)]),
        );
        assert_eq!(merged.days_off().len(), 2);
        assert!(merged.is_consistent());
        assert!(matches!(merged.model(), AnyModel::Fremen(_)));
        let nested = OnCalendar {
            model: AnyModel::Calendar(Box::new(merged.clone())),
            days_off: DaysOff::default(),
        };
        assert!(!nested.is_consistent());
    }
}
