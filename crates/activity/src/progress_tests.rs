//! Progress reports of the long fits: one step per training iteration, and the same model as
//! without a watcher.

use std::sync::Mutex;

use chronomap_core::progress::Progress;

use super::{Baseline, BaselineConfig, CopaConfig, CopaMap, GpHomConfig, RateSamples};

/// Records every stage and the steps reported in it.
#[derive(Default)]
struct Log(Mutex<Vec<(String, u64, u64)>>);

impl Progress for Log {
    fn stage(&self, name: &str, total: u64) {
        self.0.lock().unwrap().push((name.to_owned(), total, 0));
    }

    fn advance(&self, steps: u64) {
        if let Some(last) = self.0.lock().unwrap().last_mut() {
            last.2 += steps;
        }
    }
}

/// Two cells over four days of 12 hour bins, one busy in the afternoon.
fn samples() -> RateSamples {
    let mut samples = RateSamples::default();
    for t in 0..48 {
        let hour = t % 12;
        let busy = if (5..9).contains(&hour) { 20.0 } else { 2.0 };
        samples.push([0.25, 0.25], f64::from(t), busy).unwrap();
        samples.push([0.75, 0.25], f64::from(t), 1.0).unwrap();
    }
    samples
}

#[test]
fn copa_map_reports_every_iteration_and_fits_the_same_model() {
    let config = CopaConfig {
        inducing: 8,
        iterations: 5,
        ..CopaConfig::default()
    };
    let log = Log::default();
    let watched = CopaMap::fit_with_progress(&samples(), &config, &log).unwrap();
    assert_eq!(*log.0.lock().unwrap(), [("CoPA-Map".to_owned(), 5, 5)]);
    let plain = CopaMap::fit(&samples(), &config).unwrap();
    assert_eq!(watched.trace, plain.trace);
    assert_eq!(watched.trace.len(), 5);
}

#[test]
fn gp_hom_reports_its_iterations_through_the_baselines() {
    let config = BaselineConfig {
        gp_hom: GpHomConfig {
            inducing: 8,
            iterations: 4,
            ..GpHomConfig::default()
        },
        ..BaselineConfig::default()
    };
    let log = Log::default();
    let watched = Baseline::GpHom
        .fit_with_progress(&samples(), &config, &log)
        .unwrap();
    assert_eq!(*log.0.lock().unwrap(), [("GP-Hom".to_owned(), 4, 4)]);
    let plain = Baseline::GpHom.fit(&samples(), &config).unwrap();
    for t in [5.0, 6.5, 11.0] {
        assert_eq!(
            watched.predict([0.25, 0.25], t),
            plain.predict([0.25, 0.25], t)
        );
    }
    // The baselines without iterations report nothing.
    let log = Log::default();
    Baseline::Ml
        .fit_with_progress(&samples(), &config, &log)
        .unwrap();
    assert!(log.0.lock().unwrap().is_empty());
}

#[test]
fn the_extraction_reports_every_bin_and_sees_the_same() {
    use crate::extract::{
        ExtractConfig, ObstacleGrid, RobotPath, Waypoint, extract, extract_with_progress,
    };
    use chronomap_hypertime::events::Event;

    let room = ObstacleGrid::free(200, 200, 0.05, [0.0, 0.0]).unwrap();
    let robot = RobotPath::new(vec![Waypoint::new([5.0, 5.0], 60.0)], 0.5).unwrap();
    let people = [
        Event {
            t: 10.0,
            x: 5.2,
            y: 5.3,
        },
        Event {
            t: 3700.0,
            x: 5.4,
            y: 5.1,
        },
    ];
    let config = ExtractConfig {
        step_seconds: 60.0,
        ..ExtractConfig::default()
    };
    let log = Log::default();
    let robots = [robot];
    let watched =
        extract_with_progress(&room, &robots, &people, &[0, 1, 3], &config, &log).unwrap();
    assert_eq!(*log.0.lock().unwrap(), [("bins".to_owned(), 3, 3)]);
    let plain = extract(&room, &robots, &people, &[0, 1, 3], &config).unwrap();
    assert_eq!(watched.observations, plain.observations);
    assert_eq!(watched.total_count(), 2);
}
