//! System monitoring of [Stüde 2024] §5.3.1 (Fig. 5.5, 5.6, Table 5.1) and its
//! evaluation metrics of §5.3.2 (Table 5.3, TSL of Table 5.2).
//!
//! * [`Monitor`]: a named signal with a warning and an error range ([`Band`]), evaluated from
//!   timestamped samples at a time the caller gives into a [`MonitorState`] (§5.3.1: "Each
//!   monitor includes an individual warning and error range, the activation of which serves as
//!   an input to the BT-based arbiter"). Kinds ([`MonitorKind`]): a level (CPU, RAM, NTP offset,
//!   network load), a heartbeat timeout (node monitor: "node not pingable"), a message rate over
//!   a window (topic monitor: "publish frequency not in tolerance band"), and a status reported
//!   by the monitored system itself (localization: no loop closure; navigation: no global path).
//! * [`Recovery`] and [`RECOVERIES`]: the reactions of Table 5.1 with their [`Category`] (the
//!   "Type" column of Table 5.3) and their order.
//! * [`judge_interventions`]: the success rule of §5.3.2 ("a recovery behavior is considered
//!   successful if no further recovery of the same category needs to be performed within one
//!   minute").
//! * [`tsl`]: the total system lifetime of §5.3.2 (time between interventions by supervisors
//!   that the robot did not request).
//! * [`sim`]: a deterministic fault-injection simulation whose arbiter is a behavior tree
//!   ([`chronomap_bt`]) reading the monitor states from its blackboard.
//!
//! Everything here is pure: times are [`Duration`]s since an origin the caller chooses.
#![deny(missing_docs)]

pub mod sim;

use std::collections::VecDeque;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// An invalid monitor definition.
#[derive(Debug, Error, PartialEq)]
pub enum MonitorError {
    /// The band's thresholds are not ordered or not numbers.
    #[error(
        "band of {monitor:?}: thresholds must be ordered error_low <= warn_low <= warn_high <= error_high (got {lo_error}, {lo_warn}, {hi_warn}, {hi_error})"
    )]
    BadBand {
        /// The monitor.
        monitor: String,
        /// Lower error threshold.
        lo_error: f64,
        /// Lower warning threshold.
        lo_warn: f64,
        /// Upper warning threshold.
        hi_warn: f64,
        /// Upper error threshold.
        hi_error: f64,
    },
    /// A rate window of zero length.
    #[error("rate monitor {monitor:?}: the window must be longer than zero")]
    EmptyWindow {
        /// The monitor.
        monitor: String,
    },
    /// An empty monitor name.
    #[error("a monitor needs a name")]
    EmptyName,
    /// A sample that is not a number.
    #[error("monitor {monitor:?}: sample {value} is not a finite number")]
    BadSample {
        /// The monitor.
        monitor: String,
        /// The sample.
        value: f64,
    },
}

/// The state of a monitor (§5.3.1: warning and error range).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MonitorState {
    /// Inside the tolerance band.
    Ok,
    /// In the warning range.
    Warning,
    /// In the error range: the arbiter blocks the task and recovers (§5.3.1).
    Error,
}

impl MonitorState {
    /// `ok`, `warning`, `error` (the blackboard values of the arbiter).
    pub fn as_str(self) -> &'static str {
        match self {
            MonitorState::Ok => "ok",
            MonitorState::Warning => "warning",
            MonitorState::Error => "error",
        }
    }
}

impl std::fmt::Display for MonitorState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A tolerance band with a warning and an error range on each side (§5.3.1: "an individual
/// warning and error range"; Table 5.1: "not in tolerance band"). A value `v` is
/// an error if `v < error_low` or `v > error_high`, else a warning if `v < warn_low` or
/// `v > warn_high`, else ok. One-sided bands use infinite thresholds on the other side.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Band {
    /// Below this: error.
    pub error_low: f64,
    /// Below this: warning.
    pub warn_low: f64,
    /// Above this: warning.
    pub warn_high: f64,
    /// Above this: error.
    pub error_high: f64,
}

impl Band {
    /// High values are bad: warning above `warn`, error above `error` (CPU, RAM, heartbeat age).
    pub fn above(warn: f64, error: f64) -> Band {
        Band {
            error_low: f64::NEG_INFINITY,
            warn_low: f64::NEG_INFINITY,
            warn_high: warn,
            error_high: error,
        }
    }

    /// Low values are bad: warning below `warn`, error below `error`.
    pub fn below(warn: f64, error: f64) -> Band {
        Band {
            error_low: error,
            warn_low: warn,
            warn_high: f64::INFINITY,
            error_high: f64::INFINITY,
        }
    }

    /// A two-sided tolerance band (topic rates).
    pub fn within(error_low: f64, warn_low: f64, warn_high: f64, error_high: f64) -> Band {
        Band {
            error_low,
            warn_low,
            warn_high,
            error_high,
        }
    }

    fn is_valid(&self) -> bool {
        !self.error_low.is_nan()
            && !self.warn_low.is_nan()
            && !self.warn_high.is_nan()
            && !self.error_high.is_nan()
            && self.error_low <= self.warn_low
            && self.warn_low <= self.warn_high
            && self.warn_high <= self.error_high
    }

    /// The state of a value.
    pub fn classify(&self, v: f64) -> MonitorState {
        if v < self.error_low || v > self.error_high {
            MonitorState::Error
        } else if v < self.warn_low || v > self.warn_high {
            MonitorState::Warning
        } else {
            MonitorState::Ok
        }
    }
}

/// What a monitor observes (§5.3.1, Table 5.1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MonitorKind {
    /// The latest sample, classified by the band (CPU, RAM, NTP, network monitor). No sample
    /// yet is ok.
    Level,
    /// Seconds since the latest sample (a ping or heartbeat), classified by the band (node
    /// monitor: "node not pingable"). Before the first sample the age counts from time zero.
    Heartbeat,
    /// Samples per second within the window `(now − window, now]`, classified by the band
    /// (topic monitor: "publish frequency not in tolerance band"). Before a whole window has
    /// passed since time zero the state is ok.
    Rate {
        /// The window.
        window: Duration,
    },
    /// The latest sample is a state reported by the monitored system: 0 ok, 1 warning, 2 (or
    /// more) error (localization: no loop closure; navigation: no global path and MoveBase
    /// recoveries failed). No sample yet is ok.
    Status,
}

/// A monitor over one named signal (§5.3.1).
#[derive(Clone, Debug, PartialEq)]
pub struct Monitor {
    name: String,
    kind: MonitorKind,
    band: Band,
    samples: VecDeque<(Duration, f64)>,
}

impl Monitor {
    /// A monitor of signal `name`.
    ///
    /// # Errors
    /// An empty name, unordered thresholds, an empty rate window.
    pub fn new(name: &str, kind: MonitorKind, band: Band) -> Result<Monitor, MonitorError> {
        if name.is_empty() {
            return Err(MonitorError::EmptyName);
        }
        if !band.is_valid() {
            return Err(MonitorError::BadBand {
                monitor: name.to_owned(),
                lo_error: band.error_low,
                lo_warn: band.warn_low,
                hi_warn: band.warn_high,
                hi_error: band.error_high,
            });
        }
        if let MonitorKind::Rate { window } = kind
            && window.is_zero()
        {
            return Err(MonitorError::EmptyWindow {
                monitor: name.to_owned(),
            });
        }
        Ok(Monitor {
            name: name.to_owned(),
            kind,
            band,
            samples: VecDeque::new(),
        })
    }

    /// A heartbeat monitor: warning after `warn`, error after `error` without a heartbeat.
    ///
    /// # Errors
    /// As [`Monitor::new`].
    pub fn heartbeat(name: &str, warn: Duration, error: Duration) -> Result<Monitor, MonitorError> {
        Monitor::new(
            name,
            MonitorKind::Heartbeat,
            Band::above(warn.as_secs_f64(), error.as_secs_f64()),
        )
    }

    /// The signal's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The kind.
    pub fn kind(&self) -> MonitorKind {
        self.kind
    }

    /// The band.
    pub fn band(&self) -> Band {
        self.band
    }

    /// Adds a sample at time `t` (samples should come in time order; an earlier one is placed
    /// where it belongs). Samples no longer needed to evaluate at or after the latest sample are
    /// dropped: a level, status or heartbeat keeps its latest sample, a rate the latest window.
    ///
    /// # Errors
    /// A value that is not finite.
    pub fn push(&mut self, t: Duration, value: f64) -> Result<(), MonitorError> {
        if !value.is_finite() {
            return Err(MonitorError::BadSample {
                monitor: self.name.clone(),
                value,
            });
        }
        let at = self.samples.partition_point(|&(s, _)| s <= t);
        self.samples.insert(at, (t, value));
        match self.kind {
            MonitorKind::Rate { window } => {
                // Keep what a window ending at the latest sample can see.
                let latest = self.samples.back().map_or(t, |s| s.0);
                let from = latest.saturating_sub(window);
                while self.samples.front().is_some_and(|&(s, _)| s <= from) {
                    self.samples.pop_front();
                }
            }
            _ => {
                while self.samples.len() > 1 {
                    self.samples.pop_front();
                }
            }
        }
        Ok(())
    }

    /// The monitored quantity at `now`: the latest level or status, the heartbeat age in
    /// seconds, or the rate in samples per second; `None` where the state is ok by definition
    /// (no sample of a level or status, a rate before its first whole window).
    pub fn value(&self, now: Duration) -> Option<f64> {
        let latest = self.samples.iter().rev().find(|&&(t, _)| t <= now).copied();
        match self.kind {
            MonitorKind::Level | MonitorKind::Status => latest.map(|s| s.1),
            MonitorKind::Heartbeat => {
                let last = latest.map_or(Duration::ZERO, |s| s.0);
                Some(now.saturating_sub(last).as_secs_f64())
            }
            MonitorKind::Rate { window } => {
                if now < window {
                    return None;
                }
                let from = now - window;
                let n = self
                    .samples
                    .iter()
                    .filter(|&&(t, _)| t > from && t <= now)
                    .count();
                Some(n as f64 / window.as_secs_f64())
            }
        }
    }

    /// The state at `now` (§5.3.1).
    pub fn state(&self, now: Duration) -> MonitorState {
        match (self.kind, self.value(now)) {
            (_, None) => MonitorState::Ok,
            (MonitorKind::Status, Some(v)) => {
                if v >= 2.0 {
                    MonitorState::Error
                } else if v >= 1.0 {
                    MonitorState::Warning
                } else {
                    MonitorState::Ok
                }
            }
            (_, Some(v)) => self.band.classify(v),
        }
    }
}

/// The recovery categories of [Stüde 2024] Table 5.3 ("Type"); §5.3.2 judges success within a
/// category.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum Category {
    /// ROS: node and topic monitors (restart node).
    Ros,
    /// Navigation monitor.
    Navigation,
    /// Localization monitor.
    Localization,
}

impl Category {
    /// `ROS`, `Navigation`, `Localization` (as Table 5.3 writes them).
    pub fn as_str(self) -> &'static str {
        match self {
            Category::Ros => "ROS",
            Category::Navigation => "Navigation",
            Category::Localization => "Localization",
        }
    }
}

/// A recovery reaction of Table 5.1 / Table 5.3.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Recovery {
    /// The leaf ID of the arbiter tree that performs it.
    pub leaf: &'static str,
    /// The monitor (group) it answers.
    pub monitor: &'static str,
    /// The reaction as Table 5.3 names it.
    pub reaction: &'static str,
    /// Its category.
    pub category: Category,
    /// Its position in the monitor's escalation (1 = first), Table 5.1.
    pub step: u8,
    /// How long it takes (simulation).
    pub duration: Duration,
    /// The probability that it fixes the fault (simulation default: the success rate of
    /// Table 5.3).
    pub p_fix: f64,
}

/// The recoveries of Table 5.1 in arbiter priority order (node, topic, navigation,
/// localization monitors), each monitor's reactions in escalation order. Table 5.1's
/// localization steps 2 ("restart localization") and 3 ("slow rotate") are one reaction, as
/// Table 5.3 counts them ("restart localization & rotate again"). Durations are assumptions
/// (the dissertation gives none except "usually takes less than a minute" for a supervisor); fix
/// probabilities default to the success rates of Table 5.3.
pub const RECOVERIES: [Recovery; 8] = [
    Recovery {
        leaf: "RestartNode",
        monitor: "node",
        reaction: "Restart node",
        category: Category::Ros,
        step: 1,
        duration: Duration::from_secs(10),
        p_fix: 0.625,
    },
    Recovery {
        leaf: "RestartPublisher",
        monitor: "topic",
        reaction: "Restart publishing node",
        category: Category::Ros,
        step: 1,
        duration: Duration::from_secs(10),
        p_fix: 0.625,
    },
    Recovery {
        leaf: "WaitAndRetry",
        monitor: "navigation",
        reaction: "Wait and retry",
        category: Category::Navigation,
        step: 1,
        duration: Duration::from_secs(10),
        p_fix: 0.788,
    },
    Recovery {
        leaf: "MoveBackwards",
        monitor: "navigation",
        reaction: "Move backwards",
        category: Category::Navigation,
        step: 2,
        duration: Duration::from_secs(8),
        p_fix: 0.878,
    },
    Recovery {
        leaf: "AskSupervisorTeleoperation",
        monitor: "navigation",
        reaction: "Ask supervisor for teleoperation",
        category: Category::Navigation,
        step: 3,
        duration: Duration::from_secs(60),
        p_fix: 1.0,
    },
    Recovery {
        leaf: "SlowRotate",
        monitor: "localization",
        reaction: "Slow rotate",
        category: Category::Localization,
        step: 1,
        duration: Duration::from_secs(20),
        p_fix: 0.842,
    },
    Recovery {
        leaf: "RestartLocalization",
        monitor: "localization",
        reaction: "Restart localization & rotate again",
        category: Category::Localization,
        step: 2,
        duration: Duration::from_secs(30),
        p_fix: 0.666,
    },
    Recovery {
        leaf: "AskSupervisorRelocalization",
        monitor: "localization",
        reaction: "Ask supervisor for relocalization",
        category: Category::Localization,
        step: 3,
        duration: Duration::from_secs(60),
        p_fix: 1.0,
    },
];

/// The recovery performed by arbiter leaf `leaf`.
pub fn recovery(leaf: &str) -> Option<&'static Recovery> {
    RECOVERIES.iter().find(|r| r.leaf == leaf)
}

/// §5.3.2's window: "a recovery behavior is considered successful if no further recovery of the
/// same category needs to be performed within one minute".
pub const SUCCESS_WINDOW: Duration = Duration::from_secs(60);

/// Judges recoveries by the rule of [Stüde 2024] §5.3.2 (after \[HBJ+17\]): the recovery started at
/// `starts[i].0` in category `starts[i].1` succeeded iff no other recovery of the same category
/// starts in `(t_i, t_i + window]`. Recoveries are judged from their start times; a recovery
/// with less than `window` left before `end` and no later one of its category counts as a
/// success (nothing contradicts it). The additional navigation requirement of §5.3.2 (no
/// recovery within 1 m) needs positions and is not applied.
pub fn judge_interventions(starts: &[(Duration, Category)], window: Duration) -> Vec<bool> {
    starts
        .iter()
        .map(|&(t, c)| {
            !starts
                .iter()
                .any(|&(u, d)| d == c && u > t && u <= t + window)
        })
        .collect()
}

/// Total system lifetime (TSL) of [Stüde 2024] §5.3.2: "the time interval between interventions by
/// supervisors that were not explicitly requested by the robot". The intervals are those
/// between consecutive points of `start, interventions…, end` (the first and last intervals
/// are censored by the evaluation period): the dissertation's 4 interventions in 12 days give 5
/// intervals, whose mean of at most 288 h / 5 = 57.6 h matches its mean TSL of 56.7 h
/// (Table 5.2). Returns the intervals; interventions outside `[start, end]` are ignored.
pub fn tsl(start: Duration, end: Duration, interventions: &[Duration]) -> Vec<Duration> {
    let mut points: Vec<Duration> = interventions
        .iter()
        .copied()
        .filter(|&t| t >= start && t <= end)
        .collect();
    points.sort();
    let mut out = Vec::with_capacity(points.len() + 1);
    let mut prev = start;
    for t in points.into_iter().chain(std::iter::once(end)) {
        out.push(t.saturating_sub(prev));
        prev = t;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(x: u64) -> Duration {
        Duration::from_secs(x)
    }

    #[test]
    fn bands_classify_both_sides() {
        let b = Band::within(5.0, 8.0, 12.0, 15.0);
        assert_eq!(b.classify(10.0), MonitorState::Ok);
        assert_eq!(b.classify(8.0), MonitorState::Ok);
        assert_eq!(b.classify(7.9), MonitorState::Warning);
        assert_eq!(b.classify(4.9), MonitorState::Error);
        assert_eq!(b.classify(12.5), MonitorState::Warning);
        assert_eq!(b.classify(15.1), MonitorState::Error);
        let cpu = Band::above(80.0, 95.0);
        assert_eq!(cpu.classify(50.0), MonitorState::Ok);
        assert_eq!(cpu.classify(81.0), MonitorState::Warning);
        assert_eq!(cpu.classify(96.0), MonitorState::Error);
        let battery = Band::below(30.0, 10.0);
        assert_eq!(battery.classify(20.0), MonitorState::Warning);
        assert_eq!(battery.classify(5.0), MonitorState::Error);
    }

    #[test]
    fn bad_definitions_are_refused() {
        assert!(matches!(
            Monitor::new("cpu", MonitorKind::Level, Band::above(95.0, 80.0)),
            Err(MonitorError::BadBand { .. })
        ));
        assert!(matches!(
            Monitor::new("cpu", MonitorKind::Level, Band::above(f64::NAN, 80.0)),
            Err(MonitorError::BadBand { .. })
        ));
        assert_eq!(
            Monitor::new("", MonitorKind::Level, Band::above(1.0, 2.0)),
            Err(MonitorError::EmptyName)
        );
        assert_eq!(
            Monitor::new(
                "/scan",
                MonitorKind::Rate { window: s(0) },
                Band::below(8.0, 5.0)
            ),
            Err(MonitorError::EmptyWindow {
                monitor: "/scan".into()
            })
        );
        let mut m = Monitor::new("cpu", MonitorKind::Level, Band::above(80.0, 95.0)).unwrap();
        assert!(matches!(
            m.push(s(1), f64::NAN),
            Err(MonitorError::BadSample { .. })
        ));
    }

    #[test]
    fn level_uses_the_latest_sample_at_or_before_now() {
        let mut m = Monitor::new("cpu", MonitorKind::Level, Band::above(80.0, 95.0)).unwrap();
        assert_eq!(m.state(s(0)), MonitorState::Ok);
        m.push(s(1), 97.0).unwrap();
        assert_eq!(m.state(s(0)), MonitorState::Ok);
        assert_eq!(m.state(s(1)), MonitorState::Error);
        m.push(s(2), 85.0).unwrap();
        assert_eq!(m.state(s(2)), MonitorState::Warning);
    }

    #[test]
    fn heartbeat_age_trips_warning_then_error() {
        let mut m = Monitor::heartbeat("camera", s(2), s(5)).unwrap();
        m.push(s(10), 1.0).unwrap();
        assert_eq!(m.value(s(12)), Some(2.0));
        assert_eq!(m.state(s(12)), MonitorState::Ok);
        assert_eq!(m.state(s(13)), MonitorState::Warning);
        assert_eq!(m.state(s(15)), MonitorState::Warning);
        assert_eq!(m.state(s(16)), MonitorState::Error);
        // Never seen: the age counts from zero.
        let fresh = Monitor::heartbeat("laser", s(2), s(5)).unwrap();
        assert_eq!(fresh.state(s(6)), MonitorState::Error);
    }

    #[test]
    fn rate_counts_messages_in_the_window() {
        let mut m = Monitor::new(
            "/scan",
            MonitorKind::Rate { window: s(2) },
            Band::within(5.0, 8.0, 12.0, 20.0),
        )
        .unwrap();
        // 10 Hz for 4 s, then 3 Hz.
        for i in 1..=40 {
            m.push(Duration::from_millis(100 * i), 1.0).unwrap();
        }
        assert_eq!(m.state(s(1)), MonitorState::Ok); // before a whole window
        assert_eq!(m.value(s(4)), Some(10.0));
        for i in 1..=3 {
            m.push(s(4) + Duration::from_millis(333 * i), 1.0).unwrap();
        }
        // (3, 5]: 10 messages at 10 Hz + 3 = 13 messages / 2 s = 6.5 Hz: warning.
        assert_eq!(m.value(s(5)), Some(6.5));
        assert_eq!(m.state(s(5)), MonitorState::Warning);
        for i in 4..=6 {
            m.push(s(4) + Duration::from_millis(333 * i), 1.0).unwrap();
        }
        // (4, 6]: 6 messages in 2 s = 3 Hz: error.
        assert_eq!(m.value(s(6)), Some(3.0));
        assert_eq!(m.state(s(6)), MonitorState::Error);
    }

    #[test]
    fn status_maps_codes() {
        let mut m =
            Monitor::new("localization", MonitorKind::Status, Band::above(1.0, 2.0)).unwrap();
        m.push(s(1), 0.0).unwrap();
        assert_eq!(m.state(s(1)), MonitorState::Ok);
        m.push(s(2), 2.0).unwrap();
        assert_eq!(m.state(s(2)), MonitorState::Error);
        m.push(s(3), 1.0).unwrap();
        assert_eq!(m.state(s(3)), MonitorState::Warning);
    }

    #[test]
    fn one_minute_rule_counts_the_earlier_recovery_as_failure() {
        let l = Category::Localization;
        let n = Category::Navigation;
        // Slow rotate at 0, repeated 30 s later: the first fails. A navigation recovery in
        // between does not matter. The one at 30 is followed by one at 91 (61 s later): success.
        let starts = [(s(0), l), (s(10), n), (s(30), l), (s(91), l)];
        assert_eq!(
            judge_interventions(&starts, SUCCESS_WINDOW),
            vec![false, true, true, true]
        );
        // Exactly 60 s later still counts (within one minute).
        assert_eq!(
            judge_interventions(&[(s(0), l), (s(60), l)], SUCCESS_WINDOW),
            vec![false, true]
        );
    }

    #[test]
    fn tsl_intervals_include_the_censored_ends() {
        let h = |x: u64| s(3600 * x);
        assert_eq!(
            tsl(h(0), h(288), &[h(50), h(100), h(200), h(250)]),
            vec![h(50), h(50), h(100), h(50), h(38)]
        );
        assert_eq!(tsl(h(0), h(10), &[]), vec![h(10)]);
    }

    #[test]
    fn catalogue_follows_table_5_1() {
        let nav: Vec<&str> = RECOVERIES
            .iter()
            .filter(|r| r.category == Category::Navigation)
            .map(|r| r.reaction)
            .collect();
        assert_eq!(
            nav,
            [
                "Wait and retry",
                "Move backwards",
                "Ask supervisor for teleoperation"
            ]
        );
        assert_eq!(recovery("SlowRotate").unwrap().step, 1);
        assert_eq!(recovery("RestartLocalization").unwrap().p_fix, 0.666);
        assert!(recovery("Teleport").is_none());
    }
}
