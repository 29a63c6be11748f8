//! The studies of people detected by a robot ([Krajník 2019] §V-D) on event files: the
//! experiment that scores every event model's expected counts on a spatio-temporal grid of a
//! later day against the static map (MSE per cell, its reduction and a paired t-test), and the
//! Warped Hypertime event intensity fitted on the training events and drawn as hourly density
//! maps.
//!
//! Files in, result structs out ([`EventsReport`] and [`HypertimeReport`] render themselves as
//! text and JSON): the faces print, plot and name their own arguments.

use std::path::Path;
use std::time::Instant;

use chronomap_core::num::fmt_number;
use chronomap_core::progress::Progress;
use chronomap_core::time::format_time;
use chronomap_core::{BuildError, Parallelism};
use chronomap_hypertime::events::density::{DensityMap, Extent, hourly_density};
use chronomap_hypertime::events::{
    Event, EventError, EventModelBuilder, EventScore, SpatialGrid, TrainingData, default_builders,
    run_experiment_reporting,
};
use chronomap_hypertime::hypertime::Components;
use chronomap_hypertime::hypertime::events::{
    EventModelConfig, HypertimeEvents, HypertimeEventsBuilder,
};
use chronomap_io::{DataError, read_event_files, read_events};
use serde_json::{Value, json};

use crate::report::{Table, duration, time};

/// Why a study of event files failed.
#[derive(Debug, thiserror::Error)]
pub enum EventsJobError {
    /// The training files cannot be read.
    #[error("cannot read the training events")]
    ReadTraining(#[source] DataError),
    /// The test file cannot be read.
    #[error("cannot read the test events")]
    ReadTest(#[source] DataError),
    /// No training or no test event is left.
    #[error("{name}: no {what}")]
    Empty {
        /// The files.
        name: String,
        /// `training detections`, `test detections`.
        what: &'static str,
    },
    /// The test does not come after its training data.
    #[error(
        "{name}: the test starts at {} but the training data end at {}: a test must come after \
         its training data",
        format_time(*test_start),
        format_time(*train_end)
    )]
    TestBeforeTraining {
        /// The test file.
        name: String,
        /// Its first event (s).
        test_start: f64,
        /// The last training event (s).
        train_end: f64,
    },
    /// The events of `name` cannot be used (the windows of observation, the experiment).
    #[error("{name}: {error}")]
    Events {
        /// The files.
        name: String,
        /// Why.
        error: EventError,
    },
    /// The cells of a density map would be too many along an axis (`--cell`).
    #[error(
        "--cell {}: more than {} cells along an axis over the detections",
        fmt_number(*cell),
        chronomap_hypertime::events::MAX_COUNT
    )]
    TooManyCells {
        /// The cell size (m).
        cell: f64,
    },
    /// The Warped Hypertime model cannot be fitted.
    #[error("cannot fit the hypertime model to {name}")]
    Fit {
        /// The training files.
        name: String,
        /// Why.
        #[source]
        source: BuildError,
    },
}

/// The models of the experiment, in order: static map, global mean, `Hist_n`, FreMEn per cell
/// ([`default_builders`]), then Warped Hypertime ([Krajník 2019]).
///
/// Extension point: a new event model is one more [`EventModelBuilder`] pushed here; the
/// experiment and the faces' tables pick it up. Builders choose their parameters on the
/// training data only.
pub fn model_builders() -> Vec<Box<dyn EventModelBuilder>> {
    let mut builders = default_builders();
    builders.push(Box::new(HypertimeEventsBuilder::new(
        EventModelConfig::default(),
    )));
    builders
}

/// The events of `files`, merged in time order, before `before` when given (empty when none
/// is left).
///
/// # Errors
/// [`EventsJobError::ReadTraining`].
pub fn read_training_events(
    files: &[impl AsRef<Path>],
    before: Option<f64>,
) -> Result<Vec<Event>, EventsJobError> {
    let mut events = read_event_files(files).map_err(EventsJobError::ReadTraining)?;
    if let Some(before) = before {
        events.retain(|e| e.t < before);
    }
    Ok(events)
}

/// The events of `file` from `from` on when given (empty when none is left).
///
/// # Errors
/// [`EventsJobError::ReadTest`].
pub fn read_test_events(file: &Path, from: Option<f64>) -> Result<Vec<Event>, EventsJobError> {
    let mut events = read_events(file).map_err(EventsJobError::ReadTest)?;
    if let Some(from) = from {
        events.retain(|e| e.t >= from);
    }
    Ok(events)
}

/// The experiment of [Krajník 2019] §V-D on named training and test events.
#[derive(Clone, Copy, Debug)]
pub struct Experiment<'a> {
    /// The training files, for messages.
    pub train_name: &'a str,
    /// The training events, in time order.
    pub train: &'a [Event],
    /// The test file, for messages.
    pub test_name: &'a str,
    /// The test events, in time order, after the training events.
    pub test: &'a [Event],
    /// The longest gap (s) between detections inside one window of observation.
    pub gap_secs: f64,
    /// Cell sizes (m) of the grids scored.
    pub cells: &'a [f64],
    /// Time bins (s) of the grids scored.
    pub bins: &'a [f64],
}

/// What [`Experiment::run`] found.
#[derive(Clone, Debug)]
pub struct ExperimentResult<'a> {
    /// The training events with their windows of observation.
    pub training: TrainingData<'a>,
    /// One row per cell size, time bin and model, in the order of [`model_builders`].
    pub rows: Vec<EventScore>,
}

impl<'a> Experiment<'a> {
    /// Scores every model of [`model_builders`] on every grid, reporting to `progress`.
    ///
    /// # Errors
    /// [`EventsJobError::Empty`] without training or test events,
    /// [`EventsJobError::TestBeforeTraining`], and [`EventsJobError::Events`] naming the
    /// training files (windows of observation) or the test file (the experiment).
    pub fn run(
        &self,
        parallelism: Parallelism,
        progress: &dyn Progress,
    ) -> Result<ExperimentResult<'a>, EventsJobError> {
        let (Some(last_train), Some(first_test)) = (self.train.last(), self.test.first()) else {
            return Err(if self.train.is_empty() {
                EventsJobError::Empty {
                    name: self.train_name.to_string(),
                    what: "training detections",
                }
            } else {
                EventsJobError::Empty {
                    name: self.test_name.to_string(),
                    what: "test detections",
                }
            });
        };
        if first_test.t <= last_train.t {
            return Err(EventsJobError::TestBeforeTraining {
                name: self.test_name.to_string(),
                test_start: first_test.t,
                train_end: last_train.t,
            });
        }
        let training = TrainingData::from_events(self.train, self.gap_secs).map_err(|error| {
            EventsJobError::Events {
                name: self.train_name.to_string(),
                error,
            }
        })?;
        let rows = run_experiment_reporting(
            &training,
            self.test,
            self.cells,
            self.bins,
            &model_builders(),
            parallelism,
            progress,
        )
        .map_err(|error| EventsJobError::Events {
            name: self.test_name.to_string(),
            error,
        })?;
        Ok(ExperimentResult { training, rows })
    }
}

/// A Warped Hypertime event intensity fitted on training events.
#[derive(Clone, Debug)]
pub struct HypertimeFit<'a> {
    /// The training events with their windows of observation.
    pub training: TrainingData<'a>,
    /// The model.
    pub model: HypertimeEvents,
    /// Seconds spent fitting.
    pub seconds: f64,
}

/// Fits the Warped Hypertime event intensity ([Krajník 2019] eqs. 1–9 over the plane) with
/// `components` mixture components on the events of `name` (windows of observation split at
/// gaps over `gap_secs`), reporting the stage `fitting Warped Hypertime` to `progress`.
///
/// # Errors
/// [`EventsJobError::Events`] for events without a window of observation,
/// [`EventsJobError::Fit`] when the model cannot be fitted.
pub fn fit_hypertime<'a>(
    name: &str,
    events: &'a [Event],
    gap_secs: f64,
    components: Components,
    progress: &dyn Progress,
) -> Result<HypertimeFit<'a>, EventsJobError> {
    let training =
        TrainingData::from_events(events, gap_secs).map_err(|error| EventsJobError::Events {
            name: name.to_string(),
            error,
        })?;
    let config = EventModelConfig {
        components,
        ..EventModelConfig::default()
    };
    let started = Instant::now();
    progress.stage("fitting Warped Hypertime", 0);
    let model = HypertimeEvents::fit(&training, &config).map_err(|source| EventsJobError::Fit {
        name: name.to_string(),
        source,
    })?;
    Ok(HypertimeFit {
        training,
        model,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// The names of `files`, comma-separated.
pub fn file_list(files: &[impl AsRef<Path>]) -> String {
    files
        .iter()
        .map(|p| p.as_ref().display().to_string())
        .collect::<Vec<_>>()
        .join(",")
}

/// The training events of `files` before `before` ([`read_training_events`]) with the list of
/// the files' names.
///
/// # Errors
/// [`EventsJobError::Empty`] saying there are no `what` (`training detections`) if none is
/// left, or the files' error.
pub fn read_named_training(
    files: &[impl AsRef<Path>],
    before: Option<f64>,
    what: &'static str,
) -> Result<(String, Vec<Event>), EventsJobError> {
    let name = file_list(files);
    let events = read_training_events(files, before)?;
    if events.is_empty() {
        return Err(EventsJobError::Empty { name, what });
    }
    Ok((name, events))
}

/// ` WORD TIME` for a time bound that was given (`before`, `from`), else nothing.
fn bound(word: &str, t: Option<f64>) -> String {
    t.map(|t| format!(" {word} {}", time(t)))
        .unwrap_or_default()
}

/// `, area x -8.0 .. 23.0 m, y -5.9 .. 15.9 m`.
fn extent(events: &[Event]) -> String {
    match Extent::of(events) {
        Some(e) => format!(
            ", area x {:.1} .. {:.1} m, y {:.1} .. {:.1} m",
            e.x_min, e.x_max, e.y_min, e.y_max
        ),
        None => String::new(),
    }
}

fn p_value(p: f64) -> String {
    if p < 1e-4 {
        format!("{p:.0e}")
    } else {
        format!("{p:.4}")
    }
}

fn score_json(r: &EventScore) -> Value {
    json!({
        "cell_m": r.cell,
        "bin_secs": r.bin_secs,
        "model": r.model,
        "mse": r.mse,
        "reduction_pct": r.reduction_pct,
        "t": r.t,
        "p_value": r.p_value,
        "test_events": r.test_events,
        "cells": r.cells,
        "predicted_total": r.predicted_total,
        "grid": {
            "x0": r.grid.x0,
            "y0": r.grid.y0,
            "nx": r.grid.nx,
            "ny": r.grid.ny,
            "t0": r.grid.t0,
            "nt": r.grid.nt,
        },
    })
}

/// The experiment of [Krajník 2019] §V-D as `chronomap events eval` reports it: the data, the
/// bounds they were cut at, and every model's score.
#[derive(Clone, Debug)]
pub struct EventsReport<'a> {
    /// The experiment run.
    pub experiment: Experiment<'a>,
    /// What it found.
    pub result: ExperimentResult<'a>,
    /// The training files, each named.
    pub train_files: Vec<String>,
    /// The training events were those before this time, if given.
    pub train_before: Option<f64>,
    /// The test events were those from this time on, if given.
    pub test_from: Option<f64>,
}

impl EventsReport<'_> {
    /// The report as `chronomap events eval --json` prints it.
    pub fn json(&self) -> Value {
        let (e, training) = (&self.experiment, &self.result.training);
        let windows: Vec<Value> = training
            .windows()
            .iter()
            .map(|w| json!([w.start, w.end]))
            .collect();
        json!({
            "train": {
                "files": self.train_files,
                "before": self.train_before,
                "events": e.train.len(),
                "windows": windows,
                "observed_secs": training.observed_secs(),
            },
            "test": {
                "file": e.test_name,
                "from": self.test_from,
                "events": e.test.len(),
                "first": e.test[0].t,
                "last": e.test[e.test.len() - 1].t,
            },
            "results": self.result.rows.iter().map(score_json).collect::<Vec<_>>(),
        })
    }

    /// The report as `chronomap events eval` prints it: the data, a table of the MSE per
    /// cell of every model and grid, and what the columns mean.
    pub fn text(&self) -> String {
        let (e, training) = (&self.experiment, &self.result.training);
        let mut lines = vec![format!(
            "training: {}{}: {} detections in {} window(s) of observation, {} observed",
            e.train_name,
            bound("before", self.train_before),
            e.train.len(),
            training.windows().len(),
            duration(training.observed_secs()),
        )];
        for w in training.windows() {
            lines.push(format!("  {} .. {}", time(w.start), time(w.end)));
        }
        lines.push(format!(
            "test: {}{}: {} detections, {} .. {}{}",
            e.test_name,
            bound("from", self.test_from),
            e.test.len(),
            time(e.test[0].t),
            time(e.test[e.test.len() - 1].t),
            extent(e.test),
        ));
        lines.push(String::new());
        let mut table = Table::new([
            "cell",
            "bin",
            "cells",
            "events",
            "model",
            "MSE",
            "vs static",
            "p",
        ]);
        for r in &self.result.rows {
            table.row([
                format!("{} m", r.cell),
                format!("{} min", r.bin_secs / 60.0),
                r.cells.to_string(),
                r.test_events.to_string(),
                r.model.clone(),
                format!("{:.4}", r.mse),
                format!("{:+.1} %", r.reduction_pct),
                r.p_value.map_or("-".into(), p_value),
            ]);
        }
        lines.push(table.render());
        lines.push(
            "MSE: mean squared error per cell of the expected counts; vs static: reduction of the \
             MSE against the static map (positive = smaller error); p: paired t-test of the \
             per-cell squared errors against the static map's. Parameters (hist:n intervals per \
             day, fremen:order) were chosen on a chronological hold-out of the training data."
                .to_string(),
        );
        lines.join("\n")
    }
}

/// The Warped Hypertime event intensity of training events drawn as density maps: expected
/// detections per m² per hour on the cells covering the detections, at each of some times.
#[derive(Clone, Debug)]
pub struct HypertimeReport<'a> {
    /// The training files.
    pub names: String,
    /// The training events.
    pub events: usize,
    /// The fitted model.
    pub fit: HypertimeFit<'a>,
    /// The cells of the maps.
    pub space: SpatialGrid,
    /// One map per time asked for.
    pub maps: Vec<DensityMap>,
}

/// Fits the Warped Hypertime event intensity ([`fit_hypertime`]) on the events of `names` and
/// maps its hourly density on cells of `cell` metres at each of `times`.
///
/// # Errors
/// [`EventsJobError`]: the fit, no detection in the plane, or too many cells.
#[allow(clippy::too_many_arguments)]
pub fn hypertime_maps<'a>(
    names: &str,
    events: &'a [Event],
    gap_secs: f64,
    components: Components,
    cell: f64,
    times: &[f64],
    progress: &dyn Progress,
) -> Result<HypertimeReport<'a>, EventsJobError> {
    let fit = fit_hypertime(names, events, gap_secs, components, progress)?;
    let observed: Vec<Event> = fit.training.observed_events().copied().collect();
    if observed.is_empty() {
        return Err(EventsJobError::Empty {
            name: names.to_string(),
            what: "detections in the plane",
        });
    }
    let space =
        SpatialGrid::covering(&observed, cell).ok_or(EventsJobError::TooManyCells { cell })?;
    // Expected detections per m² per hour at each time, on the cells' centres.
    let maps = hourly_density(&fit.model, &space, times);
    Ok(HypertimeReport {
        names: names.to_string(),
        events: events.len(),
        fit,
        space,
        maps,
    })
}

impl HypertimeReport<'_> {
    /// The report as `chronomap hypertime --json` prints it.
    pub fn json(&self) -> Value {
        let model = &self.fit.model;
        json!({
            "train": {"files": self.names, "events": self.events, "observed_secs": self.fit.training.observed_secs()},
            "periods_secs": model.periods(),
            "components": model.mixture().components(),
            "fit_seconds": self.fit.seconds,
            "maps": self.maps.iter().map(|m| json!({
                "time": m.time,
                "total_per_hour": m.total_per_hour(&self.space),
                "max_per_m2_hour": m.max_per_m2_hour(),
            })).collect::<Vec<_>>(),
        })
    }

    /// The report as `chronomap hypertime` prints it.
    pub fn text(&self) -> String {
        let model = &self.fit.model;
        let periods: Vec<String> = model.periods().iter().map(|&p| duration(p)).collect();
        let mut lines = vec![
            format!(
                "{}: {} detections, {} observed; fitted in {:.1} s",
                self.names,
                self.events,
                duration(self.fit.training.observed_secs()),
                self.fit.seconds
            ),
            format!(
                "{} mixture components over [x, y{}]; periodicities: {}",
                model.mixture().components(),
                ", cos, sin".repeat(model.periods().len()),
                if periods.is_empty() {
                    "none (the spatial distribution does not change with time)".to_string()
                } else {
                    periods.join(", ")
                }
            ),
        ];
        for map in &self.maps {
            lines.push(format!(
                "{}: {:.0} detections per hour expected, at most {:.1} per m² per hour",
                time(map.time),
                map.total_per_hour(&self.space),
                map.max_per_m2_hour()
            ));
        }
        lines.join("\n")
    }
}

#[cfg(test)]
mod tests {
    use chronomap_core::progress::NoProgress;

    use super::*;

    fn at(t: f64) -> Event {
        Event { t, x: 1.0, y: 2.0 }
    }

    #[test]
    fn a_test_must_come_after_its_training_events() {
        // 2017-05-24 09:24 and 09:23 UTC.
        let (train, test) = ([at(1_495_617_883.0)], [at(1_495_617_800.0)]);
        let experiment = Experiment {
            train_name: "wed.txt",
            train: &train,
            test_name: "thu.txt",
            test: &test,
            gap_secs: 600.0,
            cells: &[1.0],
            bins: &[3600.0],
        };
        let error = experiment
            .run(Parallelism::Sequential, &NoProgress)
            .unwrap_err();
        assert_eq!(
            error.to_string(),
            "thu.txt: the test starts at 2017-05-24 09:23 UTC but the training data end at \
             2017-05-24 09:24 UTC: a test must come after its training data"
        );
        let none = Experiment {
            test: &[],
            ..experiment
        };
        assert_eq!(
            none.run(Parallelism::Sequential, &NoProgress)
                .unwrap_err()
                .to_string(),
            "thu.txt: no test detections"
        );
    }

    /// A detection a minute for `days` days from day `first`: at (1, 2) in even hours, at
    /// (3, 4) in odd ones.
    fn minutes(first: u32, days: u32) -> Vec<Event> {
        (first * 1440..(first + days) * 1440)
            .map(|m| {
                let odd = f64::from((m / 60) % 2);
                Event {
                    t: f64::from(m) * 60.0,
                    x: 1.0 + 2.0 * odd,
                    y: 2.0 + 2.0 * odd,
                }
            })
            .collect()
    }

    #[test]
    fn the_report_names_the_data_windows_and_every_model() {
        let (train, test) = (minutes(0, 2), minutes(2, 1));
        let experiment = Experiment {
            train_name: "a.txt",
            train: &train,
            test_name: "b.txt",
            test: &test,
            gap_secs: 600.0,
            cells: &[2.0],
            bins: &[3600.0],
        };
        let result = experiment
            .run(Parallelism::Sequential, &NoProgress)
            .unwrap();
        let report = EventsReport {
            experiment,
            result,
            train_files: vec!["a.txt".into()],
            train_before: None,
            test_from: None,
        };
        let text = report.text();
        let lines: Vec<&str> = text.lines().collect();
        // One window from the first to the last detection: 2 days less a minute, 47.98 h.
        assert_eq!(
            lines[0],
            "training: a.txt: 2880 detections in 1 window(s) of observation, 48.0 h observed"
        );
        assert_eq!(
            lines[2],
            format!(
                "test: b.txt: 1440 detections, {} .. {}, area x 1.0 .. 3.0 m, y 2.0 .. 4.0 m",
                time(172_800.0),
                time(259_140.0)
            )
        );
        // A row per model, under the header and its rule.
        assert_eq!(lines.len(), 4 + 2 + model_builders().len() + 1);
        assert!(lines[lines.len() - 1].starts_with("MSE: mean squared error per cell"));
        let json = report.json();
        assert_eq!(json["train"]["events"], 2880);
        assert_eq!(json["train"]["windows"][0][1], 172_740.0);
        assert_eq!(json["test"]["last"], 259_140.0);
        assert_eq!(
            json["results"].as_array().unwrap().len(),
            model_builders().len()
        );
    }

    #[test]
    fn hypertime_maps_cover_the_detections_and_count_them() {
        let train = minutes(0, 2);
        let report = hypertime_maps(
            "a.txt",
            &train,
            600.0,
            Components::Fixed(2),
            1.0,
            &[3600.0, 7200.0],
            &NoProgress,
        )
        .unwrap();
        // Cells of 1 m over x 1..3 and y 2..4.
        assert_eq!((report.space.nx, report.space.ny), (3, 3));
        assert_eq!(report.maps.len(), 2);
        let text = report.text();
        let lines: Vec<&str> = text.lines().collect();
        assert!(
            lines[0].starts_with("a.txt: 2880 detections, 48.0 h observed; fitted in "),
            "{text}"
        );
        assert!(
            lines[1].starts_with("2 mixture components over [x, y"),
            "{text}"
        );
        assert!(
            lines[2].starts_with(&format!("{}: ", time(3600.0))),
            "{text}"
        );
        assert_eq!(lines.len(), 4);
        let json = report.json();
        assert_eq!(json["train"]["events"], 2880);
        assert_eq!(json["components"], 2);
        assert_eq!(json["maps"][1]["time"], 7200.0);
        assert!(matches!(
            hypertime_maps(
                "a.txt",
                &train,
                600.0,
                Components::Fixed(2),
                1e-9,
                &[0.0],
                &NoProgress
            ),
            Err(EventsJobError::TooManyCells { .. })
        ));
    }

    #[test]
    fn reads_events_inside_the_bounds_and_names_the_files_it_cannot_read() {
        let dir = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-app-events-{}", std::process::id())),
        );
        let file = chronomap_testutil::write(&dir, "people.txt", "10 0 0\n20 1 1\n30 2 2\n");
        let times = |events: Vec<Event>| events.iter().map(|e| e.t).collect::<Vec<_>>();
        assert_eq!(
            times(read_training_events(&[&file], Some(30.0)).unwrap()),
            [10.0, 20.0]
        );
        assert_eq!(
            times(read_test_events(&file, Some(20.0)).unwrap()),
            [20.0, 30.0]
        );
        assert_eq!(
            times(read_test_events(&file, Some(31.0)).unwrap()),
            [] as [f64; 0]
        );
        let missing = dir.join("missing.txt");
        let error = read_test_events(&missing, None).unwrap_err();
        assert!(matches!(error, EventsJobError::ReadTest(_)));
        assert_eq!(error.to_string(), "cannot read the test events");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
