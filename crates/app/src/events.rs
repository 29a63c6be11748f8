//! The studies of people detected by a robot ([Krajník 2019] §V-D) on event files: the
//! experiment that scores every event model's expected counts on a spatio-temporal grid of a
//! later day against the static map (MSE per cell, its reduction and a paired t-test), and the
//! Warped Hypertime event intensity fitted on the training events and drawn as hourly density
//! maps.
//!
//! Files in, result structs out: the faces print, plot and name their own arguments.

use std::path::Path;
use std::time::Instant;

use chronomap_core::progress::Progress;
use chronomap_core::time::format_time;
use chronomap_core::{BuildError, Parallelism};
use chronomap_hypertime::events::{
    Event, EventError, EventModelBuilder, EventScore, TrainingData, default_builders,
    run_experiment_reporting,
};
use chronomap_hypertime::hypertime::Components;
use chronomap_hypertime::hypertime::events::{
    EventModelConfig, HypertimeEvents, HypertimeEventsBuilder,
};
use chronomap_io::{DataError, read_event_files, read_events};

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
