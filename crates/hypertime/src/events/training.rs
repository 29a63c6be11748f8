//! Training data of event models: the events, and the windows of time in which the robot
//! observed (a night spent recharging is not time in which nobody walked by).

use thiserror::Error;

use super::{Event, EventGrid, SpatialGrid, time_range, whole_bins};

/// Why events or a configuration of the event experiment were rejected.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum EventError {
    /// A time or position is NaN or infinite.
    #[error("event {index}: {field} {value} is not a finite number")]
    NonFinite {
        /// Index of the event.
        index: usize,
        /// `"t"`, `"x"` or `"y"`.
        field: &'static str,
        /// The offending number.
        value: f64,
    },
    /// Training events are not in time order.
    #[error("event {index}: time {time} is earlier than the event before it at {previous}")]
    TimeNotIncreasing {
        /// Index of the event.
        index: usize,
        /// Its time.
        time: f64,
        /// The time of the event before it.
        previous: f64,
    },
    /// There are no events where some are needed.
    #[error("no {what} events")]
    NoEvents {
        /// `"training"` or `"test"`.
        what: &'static str,
    },
    /// The observation windows are empty, overlap, are out of order or last no time at all.
    #[error("bad observation windows: {0}")]
    BadWindows(String),
    /// A model could not be fitted to the training events.
    #[error("the model cannot be fitted: {0}")]
    Fit(String),
    /// A cell size, bin length or other parameter is out of range.
    #[error("{name} = {value} is out of range: expected {expected}")]
    OutOfRange {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
}

/// A window `[start, end]` of time (s) in which the robot observed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Window {
    /// Start (s).
    pub start: f64,
    /// End (s).
    pub end: f64,
}

impl Window {
    /// Its length in seconds.
    pub fn secs(&self) -> f64 {
        self.end - self.start
    }

    /// Seconds of this window inside `[a, b)`.
    pub fn overlap(&self, a: f64, b: f64) -> f64 {
        (self.end.min(b) - self.start.max(a)).max(0.0)
    }
}

/// The windows of observation that time-ordered `events` reveal: consecutive events more
/// than `max_gap_secs` apart belong to different windows, and each window runs from its first
/// to its last event. With the Lincoln data (detections every few seconds in the day, none at
/// night while the robot recharged) and a gap of one hour, every day is one window.
///
/// ```
/// use chronomap_hypertime::events::{Event, Window, observed_windows};
///
/// let at = |t| Event { t, x: 0.0, y: 0.0 };
/// let windows = observed_windows(&[at(0.0), at(10.0), at(5000.0), at(5100.0)], 3600.0);
/// assert_eq!(windows, [Window { start: 0.0, end: 10.0 }, Window { start: 5000.0, end: 5100.0 }]);
/// ```
pub fn observed_windows(events: &[Event], max_gap_secs: f64) -> Vec<Window> {
    let mut windows: Vec<Window> = Vec::new();
    for e in events {
        match windows.last_mut() {
            Some(w) if e.t - w.end <= max_gap_secs => w.end = w.end.max(e.t),
            _ => windows.push(Window {
                start: e.t,
                end: e.t,
            }),
        }
    }
    windows
}

/// Training events and the windows in which they were observed.
///
/// Events outside every window are ignored by the models (they were not observed time);
/// rates are events per second of observed time.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainingData<'a> {
    events: &'a [Event],
    windows: Vec<Window>,
}

/// A chronological split of training data: models are fitted on `fit` and scored on the
/// counts of `validation_events` on `validation_grid`.
#[derive(Clone, Debug, PartialEq)]
pub struct Holdout<'a> {
    /// The earlier part of the training data.
    pub fit: TrainingData<'a>,
    /// The later events.
    pub validation_events: &'a [Event],
    /// The grid they are counted on (whole bins over their time span).
    pub validation_grid: EventGrid,
}

impl<'a> TrainingData<'a> {
    /// Training data with explicit windows of observation.
    ///
    /// # Errors
    /// [`EventError::NonFinite`] or [`EventError::TimeNotIncreasing`] for a bad event (times
    /// must not go backwards; equal times are fine); [`EventError::BadWindows`] if the windows
    /// are empty, not finite, out of order, overlapping or of zero total length;
    /// [`EventError::NoEvents`] if no event lies in a window.
    pub fn new(events: &'a [Event], windows: Vec<Window>) -> Result<Self, EventError> {
        check_events(events, true)?;
        if windows.is_empty() {
            return Err(EventError::BadWindows("there is none".into()));
        }
        let mut previous_end = f64::NEG_INFINITY;
        let mut total = 0.0;
        for (i, w) in windows.iter().enumerate() {
            if !(w.start.is_finite() && w.end.is_finite() && w.start <= w.end) {
                return Err(EventError::BadWindows(format!(
                    "window {i} [{}, {}] is not a finite interval",
                    w.start, w.end
                )));
            }
            if w.start < previous_end {
                return Err(EventError::BadWindows(format!(
                    "window {i} starts at {} before the window before it ends ({previous_end})",
                    w.start
                )));
            }
            previous_end = w.end;
            total += w.secs();
        }
        if total <= 0.0 {
            return Err(EventError::BadWindows(
                "they last no time (one detection is not a span of observation)".into(),
            ));
        }
        let data = TrainingData { events, windows };
        if data.observed_events().next().is_none() {
            return Err(EventError::NoEvents { what: "training" });
        }
        Ok(data)
    }

    /// Training data whose windows are [`observed_windows`]`(events, max_gap_secs)`.
    ///
    /// # Errors
    /// As [`TrainingData::new`]; [`EventError::NoEvents`] if `events` is empty.
    pub fn from_events(events: &'a [Event], max_gap_secs: f64) -> Result<Self, EventError> {
        if events.is_empty() {
            return Err(EventError::NoEvents { what: "training" });
        }
        check_events(events, true)?;
        if !(max_gap_secs.is_finite() && max_gap_secs > 0.0) {
            return Err(EventError::OutOfRange {
                name: "max_gap_secs",
                value: max_gap_secs,
                expected: "a finite number of seconds > 0",
            });
        }
        TrainingData::new(events, observed_windows(events, max_gap_secs))
    }

    /// All training events (in time order).
    pub fn events(&self) -> &'a [Event] {
        self.events
    }

    /// The windows of observation.
    pub fn windows(&self) -> &[Window] {
        &self.windows
    }

    /// The events inside a window.
    pub fn observed_events(&self) -> impl Iterator<Item = &'a Event> + '_ {
        self.events
            .iter()
            .filter(|e| self.windows.iter().any(|w| w.start <= e.t && e.t <= w.end))
    }

    /// Total observed time in seconds.
    pub fn observed_secs(&self) -> f64 {
        self.windows.iter().map(Window::secs).sum()
    }

    /// Observed seconds inside `[a, b)`.
    pub fn observed_between(&self, a: f64, b: f64) -> f64 {
        self.windows.iter().map(|w| w.overlap(a, b)).sum()
    }

    /// Observed events per cell of `space` (row-major), events outside it ignored.
    pub fn counts(&self, space: &SpatialGrid) -> Vec<f64> {
        let mut counts = vec![0.0; space.len()];
        for e in self.observed_events() {
            if let Some((r, c)) = space.cell_of(e.x, e.y) {
                counts[space.index(r, c)] += 1.0;
            }
        }
        counts
    }

    /// The chronological hold-out on which the baselines choose their parameters, for a grid
    /// of `space` and bins of `bin_secs`:
    ///
    /// * with two or more windows (days), the last window is held out and the others are fitted;
    /// * with one window, its last quarter is held out, from the bin boundary nearest to 75 %
    ///   of the window.
    ///
    /// The validation grid has whole bins over the held-out events, as the test grid has over
    /// the test events. `None` if either part would have no events or no observed time.
    pub fn holdout(&self, space: SpatialGrid, bin_secs: f64) -> Option<Holdout<'a>> {
        let (fit_windows, split) = if self.windows.len() >= 2 {
            let last = self.windows[self.windows.len() - 1];
            (self.windows[..self.windows.len() - 1].to_vec(), last.start)
        } else {
            let w = self.windows[0];
            let target = w.start + 0.75 * w.secs();
            let split = (target / bin_secs).round() * bin_secs;
            if !(split > w.start && split < w.end) {
                return None;
            }
            (vec![Window { end: split, ..w }], split)
        };
        let cut = self.events.partition_point(|e| e.t < split);
        let (fit_events, later) = self.events.split_at(cut);
        let fit = TrainingData::new(fit_events, fit_windows).ok()?;
        let last_end = self.windows[self.windows.len() - 1].end;
        let end = later.partition_point(|e| e.t <= last_end);
        let validation_events = &later[..end];
        let (first, last) = time_range(validation_events)?;
        let (t0, nt) = whole_bins(first, last, bin_secs)?;
        Some(Holdout {
            fit,
            validation_events,
            validation_grid: space.with_bins(t0, bin_secs, nt),
        })
    }
}

/// Checks that events are finite and, if `ordered`, in time order.
pub(crate) fn check_events(events: &[Event], ordered: bool) -> Result<(), EventError> {
    let mut previous = f64::NEG_INFINITY;
    for (index, e) in events.iter().enumerate() {
        if let Some((field, value)) = e.non_finite() {
            return Err(EventError::NonFinite {
                index,
                field,
                value,
            });
        }
        if ordered && e.t < previous {
            return Err(EventError::TimeNotIncreasing {
                index,
                time: e.t,
                previous,
            });
        }
        previous = e.t;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(t: f64) -> Event {
        Event { t, x: 0.5, y: 0.5 }
    }

    #[test]
    fn windows_split_at_long_gaps() {
        let events = [at(0.0), at(100.0), at(100.0), at(10_000.0), at(10_050.0)];
        let data = TrainingData::from_events(&events, 3600.0).unwrap();
        assert_eq!(
            data.windows(),
            [
                Window {
                    start: 0.0,
                    end: 100.0
                },
                Window {
                    start: 10_000.0,
                    end: 10_050.0
                }
            ]
        );
        assert_eq!(data.observed_secs(), 150.0);
        assert_eq!(data.observed_between(50.0, 10_010.0), 60.0);
    }

    #[test]
    fn rejects_bad_events_and_windows() {
        let backwards = [at(5.0), at(4.0)];
        assert!(matches!(
            TrainingData::from_events(&backwards, 60.0),
            Err(EventError::TimeNotIncreasing { index: 1, .. })
        ));
        let nan = [
            at(0.0),
            Event {
                t: 1.0,
                x: f64::NAN,
                y: 0.0,
            },
        ];
        assert!(matches!(
            TrainingData::from_events(&nan, 60.0),
            Err(EventError::NonFinite {
                index: 1,
                field: "x",
                ..
            })
        ));
        // One detection is no span of observation.
        assert!(matches!(
            TrainingData::from_events(&[at(3.0)], 60.0),
            Err(EventError::BadWindows(_))
        ));
        let overlapping = vec![
            Window {
                start: 0.0,
                end: 10.0,
            },
            Window {
                start: 5.0,
                end: 20.0,
            },
        ];
        assert!(TrainingData::new(&[at(1.0)], overlapping).is_err());
    }

    #[test]
    fn holdout_is_the_last_day_or_the_last_quarter() {
        let space = SpatialGrid::covering(&[at(0.0)], 1.0).unwrap();
        // Two days: the second is held out.
        let two_days = [at(0.0), at(3000.0), at(86_400.0), at(87_000.0)];
        let data = TrainingData::from_events(&two_days, 3600.0).unwrap();
        let h = data.holdout(space, 600.0).unwrap();
        assert_eq!(h.fit.events().len(), 2);
        assert_eq!(h.fit.observed_secs(), 3000.0);
        assert_eq!(h.validation_events.len(), 2);
        assert_eq!((h.validation_grid.t0, h.validation_grid.nt), (86_400.0, 2));
        // One day from 0 to 4000 s: split at the 600-s boundary nearest to 3000 s.
        let one_day: Vec<Event> = (0..=40).map(|i| at(100.0 * f64::from(i))).collect();
        let data = TrainingData::from_events(&one_day, 3600.0).unwrap();
        let h = data.holdout(space, 600.0).unwrap();
        assert_eq!(h.fit.windows()[0].end, 3000.0);
        assert_eq!(h.fit.events().len(), 30);
        assert_eq!(h.validation_events.len(), 11);
        assert_eq!((h.validation_grid.t0, h.validation_grid.nt), (3000.0, 2));
    }
}
