//! One test day of the service-disturbance benchmark (dissertation chapter 4, [Stüde 2024] §4.3.5,
//! eq. 4.22): when the patrols start, which model time each is planned for, and every model's
//! patrols and `E(ρ)` curve in one scenario ([`crate::disturbance`] plans and drives them).
//!
//! ```
//! use chronomap_activity::disturbance::Detections;
//! use chronomap_activity::disturbance_day::test_day;
//! use chronomap_activity::RateSamples;
//! use chronomap_hypertime::events::Event;
//!
//! // Training hours t = 0 .. 23 (a "day" of 12 bins); people tracked at 1 Hz from 10:00 to
//! // 10:40 of the test day (unix seconds).
//! let train = RateSamples::new(vec![[0.25, 0.25]; 24], (0..24).map(f64::from).collect(), vec![1.0; 24])?;
//! let ten = 36_000.0;
//! let tracks: Vec<Event> = (0..2400).map(|s| Event { t: ten + f64::from(s), x: 0.25, y: 0.25 }).collect();
//! let day = test_day(&Detections::new(tracks)?, &train, None, None, 12.0);
//! // The day starts at the hour of the first detection; the model time at the first whole
//! // day after the training data (t = 24).
//! assert_eq!((day.day_start, day.t0), (ten, 24.0));
//! // Two 15-minute slots lie wholly inside the tracked 40 minutes.
//! assert_eq!(day.starts, [ten, ten + 900.0]);
//! assert!(day.slots.iter().all(|s| s.model_t == 24.0));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use chronomap_core::progress::Progress;
use chronomap_hypertime::events::observed_windows;
use thiserror::Error;

use super::RateSamples;
use crate::disturbance::{
    Detections, DisturbanceConfig, DisturbanceError, PathCost, PatrolRun, PatrolSlot, PlanningGrid,
    disturbance_curve, patrol_starts, run_patrols,
};

/// Servicing ratios `ρ` of the curve: 0.1, 0.2, … 1.0.
pub const RATIOS: [f64; 10] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0];

/// Patrols start every 15 minutes (four per hour, §4.3.5); a patrol must fit its slot.
pub const SLOT_SECS: f64 = 900.0;

/// Consecutive detections further apart than this split the tracked time.
pub const TRACKING_GAP_SECS: f64 = 60.0;

/// The tracks are sampled at 1 Hz: the tracked time extends one sample period before the first
/// and after the last detection of a window (files start at e.g. 13:00:00.98).
pub const SAMPLE_SECS: f64 = 1.0;

/// When the patrols of a test day run.
#[derive(Clone, Debug, PartialEq)]
pub struct TestDay {
    /// Start of the day's first hour bin, in the time of the detections.
    pub day_start: f64,
    /// End of the day: `day_start` plus `period` hours.
    pub day_end: f64,
    /// The model time of the first hour bin.
    pub t0: f64,
    /// Every [`SLOT_SECS`] from `day_start`, the starts whose whole slot lies inside the
    /// tracked time; empty when none does.
    pub starts: Vec<f64>,
    /// The patrol of each start, planned for `t0` plus the whole hours since `day_start`.
    pub slots: Vec<PatrolSlot>,
}

/// The patrols of a test day. `day_start` defaults to the hour of the first detection; `t0`,
/// the model time of that hour, to the first whole day after the training data (the least
/// multiple of `period` above the last training time). The tracked time is the detections'
/// windows ([`observed_windows`], gaps over [`TRACKING_GAP_SECS`]) widened by one sample
/// ([`SAMPLE_SECS`]) at both ends; the day has `period` hours.
pub fn test_day(
    detections: &Detections,
    train: &RateSamples,
    day_start: Option<f64>,
    t0: Option<f64>,
    period: f64,
) -> TestDay {
    // No detection: no tracked time, no patrol (and a NaN day start unless one is given).
    let first = detections.events().first().map_or(f64::NAN, |e| e.t);
    let day_start = day_start.unwrap_or((first / 3600.0).floor() * 3600.0);
    let max_t = train.t().iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let t0 = t0.unwrap_or(((max_t + 1.0) / period).ceil() * period);
    let mut tracked = observed_windows(detections.events(), TRACKING_GAP_SECS);
    for window in &mut tracked {
        window.start -= SAMPLE_SECS;
        window.end += SAMPLE_SECS;
    }
    let day_end = day_start + period * 3600.0;
    let starts = patrol_starts(&tracked, day_start, day_end, SLOT_SECS);
    let slots = starts
        .iter()
        .map(|&start| PatrolSlot {
            start,
            model_t: t0 + ((start - day_start) / 3600.0).floor(),
        })
        .collect();
    TestDay {
        day_start,
        day_end,
        t0,
        starts,
        slots,
    }
}

/// One model's patrols in one scenario and its curve `E(ρ)` at [`RATIOS`] (eq. 4.22).
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// One run per slot, in slot order.
    pub runs: Vec<PatrolRun>,
    /// Encounters of the cheapest `⌊n_nav ρ⌋` patrols, per ratio.
    pub curve: Vec<usize>,
}

impl Outcome {
    /// `E(1)`: the encounters of all patrols.
    pub fn at_one(&self) -> usize {
        self.curve.last().copied().unwrap_or(0)
    }

    /// Mean length of the patrols in metres (0 for none).
    pub fn mean_length(&self) -> f64 {
        self.runs.iter().map(|r| r.length).sum::<f64>() / self.runs.len().max(1) as f64
    }

    /// The patrol with the most encounters (the earliest of equals), if any.
    pub fn busiest(&self) -> Option<usize> {
        self.runs
            .iter()
            .enumerate()
            .max_by_key(|(i, r)| (r.encounters, std::cmp::Reverse(*i)))
            .map(|(i, _)| i)
    }
}

/// How many percent fewer encounters `model` has than `baseline`; `None` when the baseline
/// has none.
pub fn reduction_percent(baseline: usize, model: usize) -> Option<f64> {
    (baseline > 0).then(|| 100.0 * (baseline as f64 - model as f64) / baseline as f64)
}

/// A model whose patrols could not be run.
#[derive(Debug, Error)]
#[error("{model}: {source}")]
pub struct ModelRunError {
    /// The model's name.
    pub model: String,
    /// What went wrong.
    #[source]
    pub source: DisturbanceError,
}

/// Every model's patrols through `waypoints` (cells of `grid`) at `slots`, and their curves:
/// one [`Outcome`] per `(name, cost)` of `models`, in order. Reports the stage `patrols` with
/// one step per patrol to `progress`.
///
/// # Errors
/// [`ModelRunError`] naming the model of a failed [`run_patrols`] or curve.
pub fn run_scenario(
    grid: &PlanningGrid,
    waypoints: &[usize],
    models: &[(&str, PathCost<'_>)],
    slots: &[PatrolSlot],
    detections: &Detections,
    config: &DisturbanceConfig,
    progress: &dyn Progress,
) -> Result<Vec<Outcome>, ModelRunError> {
    progress.stage("patrols", (models.len() * slots.len()) as u64);
    models
        .iter()
        .map(|(name, cost)| {
            let error = |source| ModelRunError {
                model: (*name).to_owned(),
                source,
            };
            let runs =
                run_patrols(grid, waypoints, cost, slots, detections, config).map_err(error)?;
            let costs: Vec<f64> = runs.iter().map(|r| r.cost).collect();
            let encounters: Vec<usize> = runs.iter().map(|r| r.encounters).collect();
            let curve = disturbance_curve(&costs, &encounters, &RATIOS).map_err(error)?;
            progress.advance(slots.len() as u64);
            Ok(Outcome { runs, curve })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicU64, Ordering};

    use chronomap_hypertime::events::Event;

    use super::*;

    struct Steps(AtomicU64);

    impl Progress for Steps {
        fn advance(&self, steps: u64) {
            self.0.fetch_add(steps, Ordering::Relaxed);
        }
    }

    fn detections(times: impl Iterator<Item = f64>, x: f64) -> Detections {
        Detections::new(times.map(|t| Event { t, x, y: 0.25 }).collect()).unwrap()
    }

    #[test]
    fn slots_follow_the_tracked_time_and_the_model_hours() {
        let train = RateSamples::new(vec![[0.25, 0.25]; 2], vec![0.0, 10.5], vec![1.0; 2]).unwrap();
        // Tracked 09:00..09:50 and 10:20..11:40 (1 Hz), the day from 09:00.
        let nine = 32_400.0;
        let times = (0..3000)
            .map(|s| nine + f64::from(s))
            .chain((0..4800).map(|s| nine + 4800.0 + f64::from(s)));
        let day = test_day(&detections(times, 0.25), &train, None, Some(100.0), 12.0);
        assert_eq!(day.day_start, nine);
        assert_eq!(day.day_end, nine + 12.0 * 3600.0);
        // 09:00, 09:15, 09:30 (ends 09:45 < 09:50:01), then 10:30 .. 11:15.
        let offsets: Vec<f64> = day.starts.iter().map(|s| s - nine).collect();
        assert_eq!(
            offsets,
            [0.0, 900.0, 1800.0, 5400.0, 6300.0, 7200.0, 8100.0]
        );
        let model_t: Vec<f64> = day.slots.iter().map(|s| s.model_t).collect();
        assert_eq!(model_t, [100.0, 100.0, 100.0, 101.0, 101.0, 102.0, 102.0]);
        // The default model time: the first multiple of the period above t = 10.5 + 1.
        let day = test_day(
            &detections([nine].into_iter(), 0.25),
            &train,
            None,
            None,
            12.0,
        );
        assert_eq!(day.t0, 12.0);
        assert!(day.starts.is_empty());
    }

    #[test]
    fn every_model_drives_every_slot_and_the_busiest_patrol_is_found() {
        // A corridor of 5 cells; somebody stands at its far end from t = 900 on.
        let grid = PlanningGrid::new([0.0, 0.0], 0.5, 5, 1).unwrap();
        let waypoints = [0, 4];
        let people = detections((0..60).map(|s| 900.0 + f64::from(s)), 2.25);
        let slots = [
            PatrolSlot {
                start: 0.0,
                model_t: 0.0,
            },
            PatrolSlot {
                start: 900.0,
                model_t: 0.0,
            },
        ];
        let steps = Steps(AtomicU64::new(0));
        let models = [("a", PathCost::Length), ("b", PathCost::Length)];
        let outcomes = run_scenario(
            &grid,
            &waypoints,
            &models,
            &slots,
            &people,
            &DisturbanceConfig::default(),
            &steps,
        )
        .unwrap();
        assert_eq!(steps.0.load(Ordering::Relaxed), 4);
        assert_eq!(outcomes.len(), 2);
        let a = &outcomes[0];
        assert_eq!(a.mean_length(), 2.0);
        assert_eq!(a.busiest(), Some(1));
        // 0.5 m/s, within 1 m of (2.25, 0.25) from 2 s to 4 s after the start: 3 detections.
        assert_eq!(a.runs[1].encounters, 3);
        assert_eq!(a.at_one(), 3);
        assert_eq!(a.curve[..4], [0, 0, 0, 0]);
        assert_eq!(reduction_percent(4, 3), Some(25.0));
        assert_eq!(reduction_percent(0, 3), None);
        // A slot too short for the patrol names the model.
        let short = DisturbanceConfig {
            max_duration: 1.0,
            ..DisturbanceConfig::default()
        };
        let error =
            run_scenario(&grid, &waypoints, &models, &slots, &people, &short, &steps).unwrap_err();
        assert_eq!(error.model, "a");
        assert!(error.to_string().starts_with("a: "), "{error}");
    }
}
