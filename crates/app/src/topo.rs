//! Jobs on topological maps whose edges know time ([Fentanes 2015]): the edge models of a
//! directory of edge files (§IV, the file at fault named), their evaluation on the later
//! attempts of another directory against the static per-edge rates (§V-A), by both protocols
//! and edge by edge, and timed plans (§V): at one time with the route if every edge succeeds,
//! and now-or-later over days (Table III).
//!
//! Files in, result structs out: the faces print the tables and map their own argument names.

use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_core::BuildError;
use chronomap_core::progress::Progress;
use chronomap_io::{DataError, read_edge_directory};
use chronomap_topo::edges::{Attempt, EdgeEvaluation, EdgeModelConfig, EdgeModels};
use chronomap_topo::map::TopoMap;
use chronomap_topo::mdp::SolverOptions;
use chronomap_topo::plan::{PlanError, Planned, Task, plan_full};
use chronomap_topo::report::{
    EdgeScore, MergeError, Protocol, WeekTable, merge_maps, per_edge_scores, success_route,
};

/// Why a job on edge files failed.
#[derive(Debug, thiserror::Error)]
pub enum TopoJobError {
    /// A directory of edge files cannot be read.
    #[error(transparent)]
    Read(#[from] DataError),
    /// The attempts of one edge cannot be fitted.
    #[error(
        "{}{}: {error}",
        file.display(),
        attempt.map(|n| format!(": attempt {n}")).unwrap_or_default()
    )]
    Fit {
        /// The edge file (`DIR/EDGE.data`), or `DIR/the map.data` when the map and the
        /// attempts disagree.
        file: PathBuf,
        /// The attempt at fault, counted from 1.
        attempt: Option<usize>,
        /// Why.
        error: BuildError,
    },
    /// The test directory holds no attempt.
    #[error("{}: no test attempts", dir.display())]
    NoTestAttempts {
        /// The test directory.
        dir: PathBuf,
    },
    /// The training and test maps do not fit together.
    #[error(transparent)]
    Merge(#[from] MergeError),
    /// The models cannot score the test attempts.
    #[error(transparent)]
    Evaluate(#[from] BuildError),
}

/// Fits the success and duration models of every edge ([Fentanes 2015] §IV) from `attempts`
/// (one list per edge of `map`), naming the edge file in `dir` whose attempts are at fault.
///
/// # Errors
/// [`TopoJobError::Fit`] with the file and attempt.
pub fn fit_edge_models(
    map: TopoMap,
    attempts: &[Vec<Attempt>],
    config: EdgeModelConfig,
    dir: &Path,
) -> Result<EdgeModels, TopoJobError> {
    EdgeModels::fit(map, attempts, config).map_err(|(edge, error)| TopoJobError::Fit {
        file: dir.join(format!("{edge}.data")),
        attempt: error.observation_index().map(|i| i + 1),
        error,
    })
}

/// Edge models fitted on one directory and scored on the later attempts of another
/// ([Fentanes 2015] §V-A).
#[derive(Clone, Debug)]
pub struct Evaluation {
    /// The models, fitted on the training attempts over the union of both maps.
    pub models: EdgeModels,
    /// Training attempts in all.
    pub train_attempts: usize,
    /// The scores when each test attempt is predicted from everything before it.
    pub online: EdgeEvaluation,
    /// The scores of the models as fitted.
    pub frozen: EdgeEvaluation,
    /// Every edge with test attempts scored alone, when asked for.
    pub per_edge: Vec<EdgeScore>,
}

impl Evaluation {
    /// The scores of `protocol`.
    pub fn by(&self, protocol: Protocol) -> &EdgeEvaluation {
        match protocol {
            Protocol::Online => &self.online,
            Protocol::Frozen => &self.frozen,
        }
    }
}

/// Reads the edge files of `train` and `test`, fits the models of the union of their maps on
/// the training attempts with `config`, and scores them on the test attempts by both protocols;
/// with `per_edge`, also every edge alone by that protocol (reported to `progress` as the stage
/// `edges`).
///
/// # Errors
/// [`TopoJobError`]: a directory that cannot be read, a test directory without attempts, maps
/// that disagree on an edge, attempts that cannot be fitted or scored.
pub fn evaluate(
    train: &Path,
    test: &Path,
    config: EdgeModelConfig,
    per_edge: Option<Protocol>,
    progress: &dyn Progress,
) -> Result<Evaluation, TopoJobError> {
    let train_stats = read_edge_directory(train)?;
    let test_stats = read_edge_directory(test)?;
    if test_stats.total_attempts() == 0 {
        return Err(TopoJobError::NoTestAttempts {
            dir: test.to_path_buf(),
        });
    }
    let train_attempts = train_stats.total_attempts();
    let (map, train_lists, test_lists) = merge_maps(
        train_stats.map,
        train_stats.attempts,
        &test_stats.map,
        &test_stats.attempts,
    )?;
    let models = fit_edge_models(map, &train_lists, config, train)?;
    let online = Protocol::Online.evaluate(&models, &test_lists)?;
    let frozen = Protocol::Frozen.evaluate(&models, &test_lists)?;
    let per_edge = match per_edge {
        Some(protocol) => per_edge_scores(&models, &train_lists, &test_lists, protocol, progress)?,
        None => Vec::new(),
    };
    Ok(Evaluation {
        models,
        train_attempts,
        online,
        frozen,
        per_edge,
    })
}

/// A plan at one time ([Fentanes 2015] §V) and how long it took.
pub struct TimedPlan {
    /// The Navigation MDP, its product with the task, its solution and the plan.
    pub planned: Planned,
    /// The route if every edge succeeds, as edge indices ([`success_route`]).
    pub route: Vec<usize>,
    /// Seconds spent planning (building and solving; not the route).
    pub seconds: f64,
}

/// Plans `task` from node `start` at time `t` with `options`, timing it.
///
/// # Errors
/// As [`plan_full`].
pub fn plan_at(
    models: &EdgeModels,
    start: usize,
    task: &Task,
    t: f64,
    options: &SolverOptions,
) -> Result<TimedPlan, PlanError> {
    let started = Instant::now();
    let planned = plan_full(models, start, task, t, options)?;
    let seconds = started.elapsed().as_secs_f64();
    let route = success_route(&planned, models.map());
    Ok(TimedPlan {
        planned,
        route,
        seconds,
    })
}

/// The now-or-later table of [Fentanes 2015] Table III ([`WeekTable::compute`]) and how long it
/// took.
#[derive(Clone, Debug)]
pub struct TimedWeek {
    /// The plans at every start time of every day.
    pub table: WeekTable,
    /// Seconds spent planning.
    pub seconds: f64,
}

/// Plans `task` from node `start` at every start time, `step_mins` apart, of `days` days from
/// midnight UTC of the day of `first_day`, timing it.
///
/// # Errors
/// As [`WeekTable::compute`].
pub fn plan_week(
    models: &EdgeModels,
    start: usize,
    task: &Task,
    first_day: f64,
    days: usize,
    step_mins: usize,
) -> Result<TimedWeek, PlanError> {
    let started = Instant::now();
    let table = WeekTable::compute(models, start, task, first_day, days, step_mins)?;
    Ok(TimedWeek {
        table,
        seconds: started.elapsed().as_secs_f64(),
    })
}

#[cfg(test)]
mod tests {
    use chronomap_core::progress::NoProgress;

    use super::*;

    #[test]
    fn a_test_directory_without_attempts_is_named() {
        let tmp = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-app-topo-{}", std::process::id())),
        );
        let (train, test) = (tmp.join("train"), tmp.join("test"));
        std::fs::create_dir_all(&train).unwrap();
        std::fs::create_dir_all(&test).unwrap();
        // `time duration success`: one success, one failure.
        chronomap_testutil::write(&train, "A_B.data", "0 10 1\n60 20 0\n");
        let error =
            evaluate(&train, &test, EdgeModelConfig::default(), None, &NoProgress).unwrap_err();
        assert_eq!(
            error.to_string(),
            format!("{}: no test attempts", test.display())
        );
        // With one later attempt: scored, and scored alone as the edge's only one.
        chronomap_testutil::write(&test, "A_B.data", "120 10 1\n");
        let done = evaluate(
            &train,
            &test,
            EdgeModelConfig::default(),
            Some(Protocol::Frozen),
            &NoProgress,
        )
        .unwrap();
        assert_eq!(done.train_attempts, 2);
        assert_eq!((done.frozen.attempts, done.frozen.successes), (1, 1));
        assert_eq!(done.per_edge.len(), 1);
        assert_eq!(done.per_edge[0].train_attempts, 2);
        assert_eq!(done.by(Protocol::Frozen), &done.frozen);

        // Reaching B from A is one attempt of A_B: the plan takes it, and succeeds as often as
        // the edge's model predicts ([Fentanes 2015] §V).
        let models = done.models;
        let (a, b) = (
            models.map().node("A").unwrap(),
            models.map().node("B").unwrap(),
        );
        assert_ne!(a, b);
        let task = Task::parse("F B", models.map()).unwrap();
        let timed = plan_at(&models, a, &task, 300.0, &SolverOptions::default()).unwrap();
        assert_eq!(timed.route, [0]);
        assert_eq!(timed.planned.plan.first_edge, Some(0));
        let p = models.success_probability(0, 300.0);
        assert!((timed.planned.plan.pmax - p).abs() < 1e-9, "{p}");
        // Two start times a day (every 720 minutes) over two days.
        let week = plan_week(&models, a, &task, 0.0, 2, 720).unwrap();
        assert_eq!((week.table.days, week.table.per_day), (2, 2));
        assert_eq!(week.table.plans.len(), 4);
        assert!(week.table.plans.iter().all(|p| p.first_edge == Some(0)));
        let _ = std::fs::remove_dir_all(&tmp);
    }
}
