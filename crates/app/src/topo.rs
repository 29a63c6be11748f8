//! Jobs on topological maps whose edges know time ([Fentanes 2015]): the edge models of a
//! directory of edge files (§IV, the file at fault named), their evaluation on the later
//! attempts of another directory against the static per-edge rates (§V-A), by both protocols
//! and edge by edge, and timed plans (§V): at one time with the route if every edge succeeds,
//! and now-or-later over days (Table III).
//!
//! Files in, result structs out: the faces print the tables and map their own argument names.

use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_core::BuildError;
use chronomap_core::progress::Progress;
use chronomap_io::{
    DataError, ModelFileError, TopoFileError, read_edge_directory, write_edge_directory,
    write_edge_models,
};
#[cfg(feature = "plot")]
use chronomap_plot::{Heatmap, Panel, Series, SeriesStyle};
use chronomap_topo::deadline::{DeadlineError, DeadlineOptions, plan_deadline};
use chronomap_topo::edges::{
    Attempt, EVALUATION_COVERAGE, EdgeEvaluation, EdgeModelConfig, EdgeModels, EdgeStatistics,
    ObserveAllError,
};
use chronomap_topo::map::TopoMap;
use chronomap_topo::mdp::{SolverOptions, prism_property, product_drn};
use chronomap_topo::plan::{PlanError, Planned, Task, plan_full};
use chronomap_topo::report::{
    EdgeScore, MergeError, Protocol, WeekTable, fit_summary, letters, merge_maps, per_edge_scores,
    success_route,
};
use serde::Serialize;
use serde_json::{Value, json};

use crate::report::{Table, time};

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
    /// The model file cannot be written.
    #[error(transparent)]
    Write(#[from] ModelFileError),
    /// A directory of edge files cannot be written.
    #[error(transparent)]
    WriteEdges(#[from] TopoFileError),
    /// A split time leaves one side without attempts.
    #[error(
        "splitting at {} leaves {before} attempts before and {after} after; choose a time inside the data{}",
        time(*at),
        span.map(|(a, b)| format!(" ({} .. {})", time(a), time(b))).unwrap_or_default()
    )]
    SplitOutside {
        /// The time asked for.
        at: f64,
        /// Attempts before it.
        before: usize,
        /// Attempts from it on.
        after: usize,
        /// The first and last attempt's times, if any.
        span: Option<(f64, f64)>,
    },
    /// The bundled Witham Wharf data hold no attempt.
    #[error("the Witham data have no attempt")]
    WithamEmpty,
    /// A plan cannot be made.
    #[error(transparent)]
    Plan(#[from] PlanError),
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

impl TimedPlan {
    /// The Navigation MDP in PRISM's language with `start` as the initial state, and the
    /// property of `task` (a `.props` file's text).
    ///
    /// # Errors
    /// The MDP or the task cannot be written in PRISM's language.
    pub fn prism(&self, start: usize, task: &Task) -> Result<(String, String), PlanError> {
        Ok((
            self.planned.mdp.to_prism(start)?,
            format!("{}\n", prism_property(task.text())?),
        ))
    }

    /// The product MDP with its solution in Storm's explicit DRN format.
    ///
    /// # Errors
    /// The product cannot be written in that format.
    pub fn drn(&self) -> Result<String, PlanError> {
        Ok(product_drn(
            self.planned.product.mdp(),
            &self.planned.solution,
        )?)
    }
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

/// What `chronomap topo fit` reports: the directory read, the orders and reconstruction errors
/// of the edge models ([Fentanes 2015] Table II), and the file written. Serialises as the
/// command's `--json`.
#[derive(Clone, Debug, Serialize)]
pub struct TopoFitReport {
    /// Nodes of the map.
    pub nodes: usize,
    /// Edges of the map.
    pub edges: usize,
    /// Traversal attempts in all.
    pub attempts: usize,
    /// The first attempt's time, if any.
    pub first: Option<f64>,
    /// The last attempt's time, if any.
    pub last: Option<f64>,
    /// Edges per order bucket of the success models ([`chronomap_topo::report::FitSummary::success_orders`]).
    pub success_orders: [usize; 6],
    /// The same for the duration models.
    pub duration_orders: [usize; 6],
    /// The shared weights of the success models' orders, heaviest first.
    pub success_weights: Vec<(String, f64)>,
    /// Mean absolute error of the success probabilities (eq. 3 / n).
    pub success_reconstruction_error: f64,
    /// Mean absolute error of the expected durations (seconds).
    pub duration_reconstruction_error_secs: f64,
    /// Seconds spent fitting (timed on purpose: the report says it).
    pub fit_seconds: f64,
    /// The model file written.
    pub model: String,
    /// The directory of edge files read.
    #[serde(skip)]
    pub directory: String,
}

/// Reads the edge files of `edges`, fits their models with `config` ([Fentanes 2015] §IV),
/// timing the fit, and writes them to `output`.
///
/// # Errors
/// [`TopoJobError`]: the directory cannot be read, the attempts cannot be fitted, the file
/// cannot be written.
pub fn fit_report(
    edges: &Path,
    output: &Path,
    config: EdgeModelConfig,
) -> Result<TopoFitReport, TopoJobError> {
    let stats = read_edge_directory(edges)?;
    let started = Instant::now();
    let models = fit_edge_models(stats.map.clone(), &stats.attempts, config, edges)?;
    let fit_seconds = started.elapsed().as_secs_f64();
    write_edge_models(output, &models)?;
    let summary = fit_summary(&models, &stats.attempts);
    let span = stats.time_span();
    Ok(TopoFitReport {
        nodes: stats.map.nodes().len(),
        edges: stats.map.edges().len(),
        attempts: stats.total_attempts(),
        first: span.map(|s| s.0),
        last: span.map(|s| s.1),
        success_orders: summary.success_orders,
        duration_orders: summary.duration_orders,
        success_weights: summary.success_weights,
        success_reconstruction_error: summary.success_error,
        duration_reconstruction_error_secs: summary.duration_error_secs,
        fit_seconds,
        model: output.display().to_string(),
        directory: edges.display().to_string(),
    })
}

/// What `chronomap topo observe` learned: later attempts taught to fitted edge models, and
/// the file written. Serialises as the command's `--json`.
#[derive(Clone, Debug, Serialize)]
pub struct TopoObserveReport {
    /// Attempts learned.
    pub attempts: usize,
    /// Successful ones among them (whose durations adapted the intervals).
    pub successes: usize,
    /// Edges with at least one attempt learned.
    pub edges: usize,
    /// Edges the models did not have, added (modelled from their priors, then learned).
    pub new_edges: Vec<String>,
    /// The first attempt's time, if any.
    pub first: Option<f64>,
    /// The last attempt's time, if any.
    pub last: Option<f64>,
    /// Successful traversals the duration intervals had adapted to before.
    pub adapted_before: u64,
    /// Successful traversals the duration intervals have adapted to in all, these included
    /// ([`chronomap_topo::duration_intervals::DurationSpread::adapt`]).
    pub adapted_traversals: u64,
    /// The levels the ends of a nominal 90 % duration interval are now read at (0.05 and 0.95
    /// before any adaptation).
    pub interval_levels: (f64, f64),
    /// The model file written.
    pub model: String,
    /// The directory of edge files read.
    #[serde(skip)]
    pub directory: String,
}

/// Teaches `models` the attempts in the edge files of `edges` (later than what each edge
/// learned last; edges the models do not have are added, [`EdgeModels::add_edge`]), in the
/// order of their times, as a robot that keeps travelling learns them
/// ([`EdgeModels::observe_all`]: success models, static rates and the online adaptation of the
/// duration intervals), and writes them to `output`.
///
/// # Errors
/// [`TopoJobError`]: the directory cannot be read, an edge that joins other nodes than the
/// models' edge of its name ([`MergeError::EdgeMismatch`]), an attempt out of order or earlier than its edge's last (naming
/// the file and attempt; nothing is learned then), the file cannot be written.
pub fn observe_report(
    mut models: EdgeModels,
    edges: &Path,
    output: &Path,
) -> Result<TopoObserveReport, TopoJobError> {
    let mut report = observe_directory(&mut models, edges)?;
    write_edge_models(output, &models)?;
    report.model = output.display().to_string();
    Ok(report)
}

/// [`observe_report`] without the file: teaches `models` the attempts of `edges` and says what
/// they learned (`model` empty). On an error `models` are unchanged.
///
/// # Errors
/// As [`observe_report`], but for writing.
pub fn observe_directory(
    models: &mut EdgeModels,
    edges: &Path,
) -> Result<TopoObserveReport, TopoJobError> {
    let stats = read_edge_directory(edges)?;
    let mut learner = models.clone();
    let report = observe_statistics(&mut learner, &stats, edges)?;
    *models = learner;
    Ok(report)
}

/// Teaches `models` the attempts of `stats`, read from `edges` (for errors).
fn observe_statistics(
    models: &mut EdgeModels,
    stats: &EdgeStatistics,
    edges: &Path,
) -> Result<TopoObserveReport, TopoJobError> {
    // The models' map with the edges only the directory has, as `topo eval` merges them; those
    // are added to the models in the same order, so the indices agree.
    let known = models.map().edges().len();
    let (map, _, lists) = merge_maps(
        models.map().clone(),
        vec![Vec::new(); known],
        &stats.map,
        &stats.attempts,
    )?;
    let mut new_edges = Vec::new();
    for edge in &map.edges()[known..] {
        let (from, to) = (&map.nodes()[edge.from].name, &map.nodes()[edge.to].name);
        models
            .add_edge(&edge.id, from, to)
            .map_err(MergeError::from)?;
        new_edges.push(edge.id.clone());
    }
    let before = models.duration_spread().adapted.count;
    models.observe_all(&lists).map_err(|e| match e {
        ObserveAllError::Attempt {
            edge,
            position,
            error,
        } => TopoJobError::Fit {
            file: edges.join(format!("{}.data", map.edges()[edge].id)),
            attempt: Some(position + 1),
            error: error.into(),
        },
        ObserveAllError::Lists { .. } => {
            TopoJobError::Evaluate(BuildError::NotEnoughData(e.to_string()))
        }
    })?;
    let adapted = &models.duration_spread().adapted;
    let span = stats.time_span();
    let alpha = 1.0 - EVALUATION_COVERAGE;
    Ok(TopoObserveReport {
        attempts: stats.total_attempts(),
        successes: lists.iter().flatten().filter(|a| a.success).count(),
        edges: lists.iter().filter(|l| !l.is_empty()).count(),
        new_edges,
        first: span.map(|s| s.0),
        last: span.map(|s| s.1),
        adapted_before: before,
        adapted_traversals: adapted.count,
        interval_levels: (adapted.read(alpha / 2.0), adapted.read(1.0 - alpha / 2.0)),
        model: String::new(),
        directory: edges.display().to_string(),
    })
}

impl fmt::Display for TopoObserveReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let span = self.first.zip(self.last);
        writeln!(
            f,
            "{}: learned {} attempts ({} successful) on {} edges{}",
            self.directory,
            self.attempts,
            self.successes,
            self.edges,
            span.map(|(a, b)| format!(", {} .. {}", time(a), time(b)))
                .unwrap_or_default()
        )?;
        if !self.new_edges.is_empty() {
            writeln!(
                f,
                "new edges (from their priors): {}",
                self.new_edges.join(", ")
            )?;
        }
        writeln!(
            f,
            "duration intervals adapted to {} traversals ({} before; [Gibbs 2021]): a nominal \
             {:.0} % interval now reads the levels {:.4} .. {:.4}",
            self.adapted_traversals,
            self.adapted_before,
            100.0 * EVALUATION_COVERAGE,
            self.interval_levels.0,
            self.interval_levels.1
        )?;
        writeln!(f, "wrote {}", self.model)
    }
}

impl TopoFitReport {
    /// The report as `chronomap topo fit` prints it.
    pub fn text(&self) -> String {
        self.to_string()
    }
}

impl fmt::Display for TopoFitReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let span = self.first.zip(self.last);
        writeln!(
            f,
            "{}: {} nodes, {} edges, {} attempts{}",
            self.directory,
            self.nodes,
            self.edges,
            self.attempts,
            span.map(|(a, b)| format!(", {} .. {}", time(a), time(b)))
                .unwrap_or_default()
        )?;
        let mut table = Table::new([
            "model",
            "mean error (eq. 3 / n)",
            "rate only",
            "order 0",
            "1",
            "2",
            "3",
            ">= 4",
        ]);
        let row = |name: &str, error: String, orders: &[usize; 6]| {
            [name.to_string(), error]
                .into_iter()
                .chain(orders.iter().map(usize::to_string))
                .collect::<Vec<_>>()
        };
        table.row(row(
            "success",
            format!("{:.3}", self.success_reconstruction_error),
            &self.success_orders,
        ));
        table.row(row(
            "time",
            format!("{:.2} s", self.duration_reconstruction_error_secs),
            &self.duration_orders,
        ));
        writeln!(f, "{}", table.render())?;
        if !self.success_weights.is_empty() {
            let weights: Vec<String> = self
                .success_weights
                .iter()
                .map(|(spec, w)| format!("{spec} {w:.3}"))
                .collect();
            writeln!(
                f,
                "success models: every edge weighs {} (shared weights, rolling-origin \
                 cross-validation; counted above by their largest order)",
                weights.join(", ")
            )?;
        }
        writeln!(
            f,
            "([Fentanes 2015] Table II, open-plan site: success 0.14 with orders 35/18/4/5; time 1.88 s with 24/19/10/9)"
        )?;
        writeln!(
            f,
            "fitted in {:.2} s; wrote {}",
            self.fit_seconds, self.model
        )
    }
}

/// Success Brier score, expected calibration error and duration MSE of each labelled evaluation
/// against the static per-edge rates ([Fentanes 2015] §V-A); `static_mse` heads the static
/// duration column.
pub fn score_table<'a>(
    static_mse: &str,
    scores: impl IntoIterator<Item = (String, &'a EdgeEvaluation)>,
) -> Table {
    let mut table = Table::new([
        "protocol",
        "success Brier",
        "static Brier",
        "ratio",
        "ECE",
        "static ECE",
        "duration MSE (s²)",
        static_mse,
        "90 % interval: coverage",
        "width (s)",
    ]);
    for (label, s) in scores {
        table.row([
            label,
            format!("{:.4}", s.success_brier),
            format!("{:.4}", s.static_success_brier),
            format!("{:.2}", s.success_brier / s.static_success_brier),
            format!("{:.4}", s.success_ece),
            format!("{:.4}", s.static_success_ece),
            format!("{:.2}", s.duration_mse),
            format!("{:.2}", s.static_duration_mse),
            format!("{:.3}", s.duration_coverage),
            format!("{:.1}", s.duration_interval_width),
        ]);
    }
    table
}

/// What `chronomap topo eval` reports: an [`Evaluation`] with the protocol asked for and the
/// directories it read ([Fentanes 2015] §V-A).
pub struct EvalReport {
    /// The evaluation.
    pub evaluation: Evaluation,
    /// The protocol asked for.
    pub protocol: Protocol,
    /// Whether every edge was scored alone.
    pub per_edge: bool,
    /// The training directory.
    pub train: String,
    /// The test directory.
    pub test: String,
}

/// [`evaluate`] as `chronomap topo eval` reports it: every edge alone when `per_edge`.
///
/// # Errors
/// As [`evaluate`].
pub fn eval_report(
    train: &Path,
    test: &Path,
    config: EdgeModelConfig,
    protocol: Protocol,
    per_edge: bool,
    progress: &dyn Progress,
) -> Result<EvalReport, TopoJobError> {
    let evaluation = evaluate(train, test, config, per_edge.then_some(protocol), progress)?;
    Ok(EvalReport {
        evaluation,
        protocol,
        per_edge,
        train: train.display().to_string(),
        test: test.display().to_string(),
    })
}

/// The scores of one evaluation as JSON.
fn score_json(score: &EdgeEvaluation) -> Value {
    json!({
        "success_brier": score.success_brier,
        "static_success_brier": score.static_success_brier,
        "success_ece": score.success_ece,
        "static_success_ece": score.static_success_ece,
        "duration_mse": score.duration_mse,
        "duration_coverage": score.duration_coverage,
        "duration_interval_width": score.duration_interval_width,
        "duration_below": score.duration_below,
        "duration_above": score.duration_above,
        "static_duration_mse": score.static_duration_mse,
    })
}

impl EvalReport {
    fn edge_id(&self, e: usize) -> String {
        self.evaluation.models.map().edges()[e].id.clone()
    }

    /// The report as `chronomap topo eval --json` prints it.
    pub fn json(&self) -> Value {
        let e = &self.evaluation;
        let chosen = e.by(self.protocol);
        let mut report = json!({
            "success_brier": chosen.success_brier,
            "duration_mse": chosen.duration_mse,
            "static_success_brier": chosen.static_success_brier,
            "static_duration_mse": chosen.static_duration_mse,
            "success_ece": chosen.success_ece,
            "static_success_ece": chosen.static_success_ece,
            "duration_coverage": chosen.duration_coverage,
            "duration_interval_width": chosen.duration_interval_width,
            "duration_below": chosen.duration_below,
            "duration_above": chosen.duration_above,
            "duration_nominal_coverage": EVALUATION_COVERAGE,
            "attempts": chosen.attempts,
            "successes": chosen.successes,
            "protocol": self.protocol.name(),
            "train_attempts": e.train_attempts,
            "edges": e.models.map().edges().len(),
            "online": score_json(&e.online),
            "frozen": score_json(&e.frozen),
            "success_reliability_bins": chosen.success_bins,
            "static_success_reliability_bins": chosen.static_success_bins,
            "duration_curve": chosen.duration_curve.iter().map(|(nominal, c)| json!({
                "nominal": nominal,
                "coverage": c.coverage,
                "mean_width": c.mean_width,
                "below": c.below,
                "above": c.above,
            })).collect::<Vec<_>>(),
        });
        if self.per_edge {
            report["per_edge"] = e
                .per_edge
                .iter()
                .map(|s| {
                    json!({
                        "edge": self.edge_id(s.edge),
                        "train_attempts": s.train_attempts,
                        "test_attempts": s.score.attempts,
                        "success_brier": s.score.success_brier,
                        "static_success_brier": s.score.static_success_brier,
                    })
                })
                .collect();
        }
        report
    }

    /// The report as `chronomap topo eval` prints it.
    pub fn text(&self) -> String {
        self.to_string()
    }

    /// The calibration of the chosen protocol's predictions, as `chronomap topo eval --plot`
    /// draws it: the reliability diagram of the success probabilities (the models' and the
    /// static rates') and the coverage curve of the duration intervals.
    #[cfg(feature = "plot")]
    pub fn calibration_panels(&self) -> Vec<Panel> {
        use crate::calibration_plots::{coverage_panels, reliability_panels};
        let chosen = self.evaluation.by(self.protocol);
        let mut panels = reliability_panels(
            format!(
                "Success probabilities ({}): reliability over {} attempts, 10 bins",
                self.protocol.name(),
                chosen.attempts
            ),
            &[
                (
                    format!("edge models (ECE {:.3})", chosen.success_ece),
                    chosen.success_bins.as_slice(),
                ),
                (
                    format!("static rates (ECE {:.3})", chosen.static_success_ece),
                    chosen.static_success_bins.as_slice(),
                ),
            ],
        );
        // Both protocols' duration intervals, the one asked for first: adapted after each
        // traversal (online) against as fitted (frozen).
        let curve = |p: Protocol| {
            let label = match p {
                Protocol::Online => "online: adapted after each traversal",
                Protocol::Frozen => "frozen: as fitted",
            };
            (
                label.to_string(),
                self.evaluation.by(p).duration_curve.clone(),
            )
        };
        let other = match self.protocol {
            Protocol::Online => Protocol::Frozen,
            Protocol::Frozen => Protocol::Online,
        };
        panels.extend(coverage_panels(
            format!(
                "Duration intervals on {} successful traversals: share inside",
                chosen.successes
            ),
            "seconds",
            &[curve(self.protocol), curve(other)],
        ));
        panels
    }
}

impl fmt::Display for EvalReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let e = &self.evaluation;
        let chosen = e.by(self.protocol);
        writeln!(
            f,
            "trained on {} attempts ({}), tested on {} attempts ({}) of {} edges",
            e.train_attempts,
            self.train,
            chosen.attempts,
            self.test,
            e.models.map().edges().len()
        )?;
        let label = |p: Protocol| {
            if p == self.protocol {
                format!("{} *", p.name())
            } else {
                p.name().to_string()
            }
        };
        let table = score_table(
            "static MSE (s²)",
            [
                (label(Protocol::Online), &e.online),
                (label(Protocol::Frozen), &e.frozen),
            ],
        );
        writeln!(f, "{}", table.render())?;
        writeln!(
            f,
            "(* the protocol asked for; ratio < 1: the per-edge models beat the static per-edge rates; durations of the {} successful attempts: expected by the models as fitted; online, the intervals adapt after each traversal)",
            chosen.successes
        )?;
        if self.per_edge {
            let mut table = Table::new(["edge", "train", "test", "Brier", "static"]);
            for s in &e.per_edge {
                table.row([
                    self.edge_id(s.edge),
                    s.train_attempts.to_string(),
                    s.score.attempts.to_string(),
                    format!("{:.4}", s.score.success_brier),
                    format!("{:.4}", s.score.static_success_brier),
                ]);
            }
            writeln!(f, "\n{}", table.render())?;
        }
        Ok(())
    }
}

/// One side of a split: the directory written, its attempts and edge files.
#[derive(Clone, Debug, Serialize)]
pub struct SplitPart {
    /// The directory written.
    pub directory: String,
    /// Attempts in it.
    pub attempts: usize,
    /// Edge files written.
    pub edge_files: usize,
}

/// What `chronomap topo split` reports (serialises as its `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct SplitReport {
    /// The time split at.
    pub at: f64,
    /// The same in UTC.
    pub utc: String,
    /// The attempts before it.
    pub before: SplitPart,
    /// The attempts from it on.
    pub after: SplitPart,
}

/// Splits the attempts of the edge files of `edges` at time `at`: those before into the
/// directory `before`, the others into `after` (to train on one and score on the later).
///
/// # Errors
/// [`TopoJobError::SplitOutside`] when either side would be empty; a directory that cannot be
/// read or written.
pub fn split(
    edges: &Path,
    at: f64,
    before_dir: &Path,
    after_dir: &Path,
) -> Result<SplitReport, TopoJobError> {
    let stats = read_edge_directory(edges)?;
    let (before, after) = stats.split_at(at);
    if before.total_attempts() == 0 || after.total_attempts() == 0 {
        return Err(TopoJobError::SplitOutside {
            at,
            before: before.total_attempts(),
            after: after.total_attempts(),
            span: stats.time_span(),
        });
    }
    let a = write_edge_directory(before_dir, &before)?;
    let b = write_edge_directory(after_dir, &after)?;
    let part = |dir: &Path, attempts: usize, edge_files: usize| SplitPart {
        directory: dir.display().to_string(),
        attempts,
        edge_files,
    };
    Ok(SplitReport {
        at,
        utc: time(at),
        before: part(before_dir, before.total_attempts(), a),
        after: part(after_dir, after.total_attempts(), b),
    })
}

impl SplitReport {
    /// The report as `chronomap topo split` prints it.
    pub fn text(&self) -> String {
        format!(
            "before {}: {} attempts in {} edge files -> {}\nfrom {}: {} attempts in {} edge files -> {}\n",
            self.utc,
            self.before.attempts,
            self.before.edge_files,
            self.before.directory,
            self.utc,
            self.after.attempts,
            self.after.edge_files,
            self.after.directory
        )
    }
}

/// One edge at one time as `chronomap topo predict` reports it.
#[derive(Clone, Debug, Serialize)]
pub struct EdgePrediction {
    /// The edge's ID.
    pub edge: String,
    /// The name of the node it leaves.
    pub from: String,
    /// The name of the node it reaches.
    pub to: String,
    /// Probability that a traversal succeeds.
    pub success_probability: f64,
    /// Standard deviation of that probability.
    pub uncertainty: f64,
    /// The static per-edge success rate.
    pub static_success_probability: f64,
    /// Expected duration of a successful traversal (seconds).
    pub duration_secs: f64,
    /// The interval that holds a successful traversal's duration with probability
    /// [`EVALUATION_COVERAGE`] (90 %), in seconds (`None` for models written before
    /// intervals existed).
    pub duration_interval_secs: Option<(f64, f64)>,
    /// Attempts the model was fitted on.
    pub attempts: usize,
}

/// What `chronomap topo predict` reports (serialises as its `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct PredictReport {
    /// The time predicted for.
    pub time: f64,
    /// Every edge, in map order.
    pub edges: Vec<EdgePrediction>,
}

/// Every edge of `models` at time `t`: success probability with its uncertainty, the static
/// rate, the expected duration ([Fentanes 2015] §IV) and its 90 % interval.
pub fn predict(models: &EdgeModels, t: f64) -> PredictReport {
    let (success, duration) = models.at(t);
    let map = models.map();
    let edges = map
        .edges()
        .iter()
        .enumerate()
        .map(|(e, edge)| EdgePrediction {
            edge: edge.id.clone(),
            from: map.nodes()[edge.from].name.clone(),
            to: map.nodes()[edge.to].name.clone(),
            success_probability: success[e],
            uncertainty: models.success_uncertainty(e, t),
            static_success_probability: models.static_success_probability(e),
            duration_secs: duration[e],
            duration_interval_secs: models.duration_interval(e, t, EVALUATION_COVERAGE),
            attempts: models.edge(e).attempts,
        })
        .collect();
    PredictReport { time: t, edges }
}

impl PredictReport {
    /// Every edge's metadata in a Nav2 route graph: success probability, expected duration
    /// and its [`EVALUATION_COVERAGE`] (90 %) interval where the models have one.
    pub fn route_metadata(&self) -> Vec<chronomap_io::RouteEdgeMetadata> {
        self.edges
            .iter()
            .map(|e| {
                chronomap_io::RouteEdgeMetadata::new(e.success_probability, e.duration_secs)
                    .with_time_interval(e.duration_interval_secs, EVALUATION_COVERAGE)
            })
            .collect()
    }

    /// The report as `chronomap topo predict` prints it.
    pub fn text(&self) -> String {
        let mut table = Table::new([
            "edge",
            "p(success)",
            "± sd",
            "static p",
            "duration",
            "90 % interval",
            "attempts",
        ]);
        for e in &self.edges {
            table.row([
                e.edge.clone(),
                format!("{:.3}", e.success_probability),
                format!("{:.3}", e.uncertainty),
                format!("{:.3}", e.static_success_probability),
                format!("{:.1} s", e.duration_secs),
                e.duration_interval_secs
                    .map_or("-".into(), |(lo, hi)| format!("{lo:.1} – {hi:.1} s")),
                e.attempts.to_string(),
            ]);
        }
        format!(
            "{} edges at {}\n{}\n",
            self.edges.len(),
            time(self.time),
            table.render()
        )
    }
}

/// What `chronomap plan --time` reports: the plan at one time ([Fentanes 2015] §V) with the
/// route if every edge succeeds (serialises as its `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct PlanReport {
    /// The task, as given.
    pub task: String,
    /// The start node, as given.
    pub from: String,
    /// The start time.
    pub time: f64,
    /// The same in UTC.
    pub utc: String,
    /// Maximum probability of fulfilling the task.
    pub pmax: f64,
    /// Expected time until done or failed (seconds).
    pub expected_secs: f64,
    /// The first edge to take, if any.
    pub first_edge: Option<String>,
    /// The route if every edge succeeds.
    pub route: Vec<String>,
    /// The success probability of each edge of the route at the start time.
    pub route_success_probabilities: Vec<f64>,
    /// States of the product of the Navigation MDP and the task automaton.
    pub product_states: usize,
    /// Seconds spent planning (timed on purpose: the report says it).
    pub seconds: f64,
}

/// The report of a [`TimedPlan`] of `task` from `from` at time `t`.
pub fn plan_report(
    models: &EdgeModels,
    timed: &TimedPlan,
    from: &str,
    task: &str,
    t: f64,
) -> PlanReport {
    let edges = models.map().edges();
    let plan = &timed.planned.plan;
    PlanReport {
        task: task.to_string(),
        from: from.to_string(),
        time: t,
        utc: time(t),
        pmax: plan.pmax,
        expected_secs: plan.expected_secs,
        first_edge: plan.first_edge.map(|e| edges[e].id.clone()),
        route: timed.route.iter().map(|&e| edges[e].id.clone()).collect(),
        route_success_probabilities: timed
            .route
            .iter()
            .map(|&e| models.success_probability(e, t))
            .collect(),
        product_states: timed.planned.product.states().len(),
        seconds: timed.seconds,
    }
}

impl PlanReport {
    /// The report as `chronomap plan --time` prints it.
    pub fn text(&self) -> String {
        self.to_string()
    }
}

impl fmt::Display for PlanReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "task {:?} from {} at {}", self.task, self.from, self.utc)?;
        writeln!(
            f,
            "maximum probability of success: {:.4}; expected time: {:.1} s (until done or failed)",
            self.pmax, self.expected_secs
        )?;
        match &self.first_edge {
            Some(e) => writeln!(f, "first action: {e}")?,
            None if self.pmax >= 1.0 => writeln!(f, "the task holds already")?,
            None => writeln!(f, "the task cannot be fulfilled from here")?,
        }
        if !self.route.is_empty() {
            let names: Vec<String> = self
                .route
                .iter()
                .zip(&self.route_success_probabilities)
                .map(|(e, p)| format!("{e} ({p:.2})"))
                .collect();
            writeln!(f, "route if every edge succeeds: {}", names.join(" -> "))?;
        }
        writeln!(
            f,
            "({} product states, solved in {:.1} ms)",
            self.product_states,
            self.seconds * 1e3
        )
    }
}

/// What `chronomap plan --time --deadline` reports: the plan most likely to fulfil the task
/// within the deadline ([`chronomap_topo::deadline`]) beside the expected-time plan of
/// [Fentanes 2015] §V under the same deadline (serialises as its `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct DeadlineReport {
    /// The task, as given.
    pub task: String,
    /// The start node, as given.
    pub from: String,
    /// The start time.
    pub time: f64,
    /// The same in UTC.
    pub utc: String,
    /// The deadline (seconds after the start).
    pub deadline_secs: f64,
    /// The probability asked for.
    pub confidence: f64,
    /// The greatest probability of fulfilling the task within the deadline (a certified lower
    /// bound: durations rounded up to buckets).
    pub probability: f64,
    /// Whether it reaches `confidence`.
    pub reaches_confidence: bool,
    /// The first edge to take, if any.
    pub first_edge: Option<String>,
    /// The route if every edge succeeds in its median duration.
    pub median_route: Vec<String>,
    /// The shortest deadline (seconds, a multiple of the bucket) within which the task is
    /// fulfilled with probability `confidence`; `None` if not within the deadline.
    pub shortest_deadline_secs: Option<f64>,
    /// The expected-time plan's probability of fulfilling the task within the deadline.
    pub min_time_probability: f64,
    /// The expected-time plan's first edge.
    pub min_time_first_edge: Option<String>,
    /// `Pmax` without a deadline.
    pub pmax: f64,
    /// The expected-time plan's expected time (seconds, until done or failed).
    pub expected_secs: f64,
    /// The bucket width (seconds).
    pub bucket_secs: f64,
    /// `[d, deadline plan, expected-time plan]`: the probabilities of fulfilling the task
    /// within `d` seconds, `d = 0, Δ, …, K·Δ`.
    pub curve: Vec<[f64; 3]>,
    /// Whether the durations' laws come from their quantiles (else: sure expected durations).
    pub duration_quantiles: bool,
    /// States of the product of the Navigation MDP and the task automaton.
    pub product_states: usize,
    /// Seconds spent planning (timed on purpose: the report says it).
    pub seconds: f64,
}

/// Plans `task` from node `start` (named `from`) at time `t` for the greatest probability of
/// fulfilling it within `deadline_secs` (buckets of `bucket_secs`, default `max(D / 600, 1 s)`),
/// and says whether that reaches `confidence`.
///
/// # Errors
/// As [`plan_deadline`]: an invalid deadline or bucket, too many cells, a plan that cannot be
/// made.
pub fn deadline_report(
    models: &EdgeModels,
    (start, from): (usize, &str),
    (task, text): (&Task, &str),
    t: f64,
    deadline_secs: f64,
    bucket_secs: Option<f64>,
    confidence: f64,
) -> Result<DeadlineReport, DeadlineError> {
    let started = Instant::now();
    let options = DeadlineOptions {
        bucket_secs,
        ..DeadlineOptions::default()
    };
    let planned = plan_deadline(models, start, task, t, deadline_secs, &options)?;
    let seconds = started.elapsed().as_secs_f64();
    let plan = &planned.plan;
    let edges = models.map().edges();
    let name = |e: Option<usize>| e.map(|e| edges[e].id.clone());
    Ok(DeadlineReport {
        task: text.to_string(),
        from: from.to_string(),
        time: t,
        utc: time(t),
        deadline_secs,
        confidence,
        probability: plan.probability,
        reaches_confidence: plan.probability >= confidence,
        first_edge: name(plan.first_edge),
        median_route: planned
            .median_route()
            .iter()
            .map(|&e| edges[e].id.clone())
            .collect(),
        shortest_deadline_secs: plan.shortest_deadline(confidence),
        min_time_probability: plan.min_time_probability,
        min_time_first_edge: name(plan.min_time_first_edge),
        pmax: plan.pmax,
        expected_secs: plan.expected_secs,
        bucket_secs: plan.bucket_secs,
        curve: plan
            .curve
            .iter()
            .zip(&plan.min_time_curve)
            .enumerate()
            .map(|(k, (&p, &q))| [k as f64 * plan.bucket_secs, p, q])
            .collect(),
        duration_quantiles: plan.duration_quantiles,
        product_states: planned.planned.product.states().len(),
        seconds,
    })
}

impl DeadlineReport {
    /// The report as `chronomap plan --deadline` prints it.
    pub fn text(&self) -> String {
        self.to_string()
    }

    /// The curves "probability within `d`" of both plans, for `--plot`.
    #[cfg(feature = "plot")]
    pub fn panel(&self) -> Panel {
        let series = |label: String, column: usize| Series {
            label,
            points: self.curve.iter().map(|row| (row[0], row[column])).collect(),
            style: SeriesStyle::Step,
        };
        Panel {
            title: format!(
                "{:?} from {} at {}: probability of fulfilling it within d",
                self.task, self.from, self.utc
            ),
            x_label: "d (s)".into(),
            y_label: "probability".into(),
            y_range: (0.0, 1.0),
            series: vec![
                series("best plan for each d".into(), 1),
                series("expected-time plan".into(), 2),
            ],
        }
    }
}

impl fmt::Display for DeadlineReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "task {:?} from {} at {}, deadline {} s",
            self.task,
            self.from,
            self.utc,
            trim(self.deadline_secs)
        )?;
        let verdict = if self.reaches_confidence {
            "reaches"
        } else {
            "does not reach"
        };
        writeln!(
            f,
            "probability of fulfilling it in time: {:.4} ({verdict} {}; a lower bound, durations \
             rounded up to {} s)",
            self.probability,
            trim(self.confidence),
            trim(self.bucket_secs)
        )?;
        match &self.first_edge {
            Some(e) => writeln!(f, "first action: {e}")?,
            None if self.probability >= 1.0 => writeln!(f, "the task holds already")?,
            None => writeln!(f, "the task cannot be fulfilled in time from here")?,
        }
        if !self.median_route.is_empty() {
            writeln!(
                f,
                "route if every edge succeeds in its median time: {}",
                self.median_route.join(" -> ")
            )?;
        }
        match self.shortest_deadline_secs {
            Some(d) => writeln!(
                f,
                "{} is reached within {} s ({} s to spare)",
                trim(self.confidence),
                trim(d),
                trim(self.deadline_secs - d)
            )?,
            None => writeln!(
                f,
                "{} is not reached within the deadline: at most {:.4}",
                trim(self.confidence),
                self.probability
            )?,
        }
        writeln!(
            f,
            "expected-time plan (Pmax {:.4}, expected {:.1} s, first action {}): {:.4} in time",
            self.pmax,
            self.expected_secs,
            self.min_time_first_edge.as_deref().unwrap_or("none"),
            self.min_time_probability
        )?;
        if !self.duration_quantiles {
            writeln!(
                f,
                "(the model file has no duration quantiles: expected durations taken as sure)"
            )?;
        }
        writeln!(
            f,
            "({} product states x {} buckets, solved in {:.1} ms)",
            self.product_states,
            self.curve.len(),
            self.seconds * 1e3
        )
    }
}

/// `100`, `0.95`, `2.5`: a number without trailing zeros.
fn trim(x: f64) -> String {
    let s = format!("{x:.6}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Monday = 0.
fn weekday(t: f64) -> usize {
    ((t / 86_400.0).floor() as i64 + 3).rem_euclid(7) as usize
}

const WEEKDAYS: [&str; 7] = ["Mon", "Tue", "Wed", "Thu", "Fri", "Sat", "Sun"];

/// `Thu 09-04`.
fn day_label(t: f64) -> String {
    let date = time(t);
    let month_day = date.get(5..10).unwrap_or(&date);
    format!("{} {month_day}", WEEKDAYS[weekday(t)])
}

/// A now-or-later table ([`WeekTable`], [Fentanes 2015] Table III) with the names it is
/// printed with, as `chronomap plan --day-table` and the demo show it.
#[derive(Clone, Debug)]
pub struct DayTable {
    /// The IDs of the map's edges.
    edges: Vec<String>,
    /// The task, as given.
    pub task: String,
    /// The start node, as given.
    pub from: String,
    /// The plans.
    pub table: WeekTable,
    /// Seconds spent planning.
    pub seconds: f64,
}

impl DayTable {
    /// Plans `task` from node `from` at every start time (`step_mins` apart, `days` days from
    /// midnight UTC of `first_day`), timing it ([`plan_week`]).
    ///
    /// # Errors
    /// As [`plan_week`].
    pub fn compute(
        models: &EdgeModels,
        (start, from): (usize, &str),
        (task, text): (&Task, &str),
        first_day: f64,
        days: usize,
        step_mins: usize,
    ) -> Result<Self, PlanError> {
        let TimedWeek { table, seconds } =
            plan_week(models, start, task, first_day, days, step_mins)?;
        Ok(DayTable {
            edges: models.map().edges().iter().map(|e| e.id.clone()).collect(),
            task: text.to_string(),
            from: from.to_string(),
            table,
            seconds,
        })
    }

    /// Plans, at every start time, for the greatest probability of fulfilling the task within
    /// `deadline_secs` (buckets of `bucket_secs`, default `max(D / 600, 1 s)`;
    /// [`WeekTable::add_deadline`]), reporting the stage `deadline plans` with one step per
    /// start time to `progress` and adding the time it takes to [`DayTable::seconds`]. The
    /// table then shows those probabilities and first actions.
    ///
    /// # Errors
    /// As [`plan_deadline`]; the table is then unchanged.
    pub fn add_deadline(
        &mut self,
        models: &EdgeModels,
        (start, task): (usize, &Task),
        deadline_secs: f64,
        bucket_secs: Option<f64>,
        progress: &dyn Progress,
    ) -> Result<(), DeadlineError> {
        let started = Instant::now();
        let options = DeadlineOptions {
            bucket_secs,
            ..DeadlineOptions::default()
        };
        progress.stage("deadline plans", self.table.plans.len() as u64);
        self.table
            .add_deadline(models, start, task, deadline_secs, &options, || {
                progress.advance(1)
            })?;
        self.seconds += started.elapsed().as_secs_f64();
        Ok(())
    }

    /// The deadline, once [`DayTable::add_deadline`] planned for one.
    pub fn deadline_secs(&self) -> Option<f64> {
        self.table.deadline_plans.first().map(|p| p.deadline_secs)
    }

    /// What the table shows at start time `k` of day `day`: the probability (of fulfilling
    /// the task within the deadline, or `Pmax` without one) and the first edge.
    fn cell(&self, day: usize, k: usize) -> (f64, Option<usize>) {
        match self.table.deadline_at(day, k) {
            Some(plan) => (plan.probability, plan.first_edge),
            None => {
                let plan = self.table.at(day, k);
                (plan.pmax, plan.first_edge)
            }
        }
    }

    /// What the table's numbers are.
    fn what(&self) -> String {
        match self.deadline_secs() {
            Some(d) => format!("greatest probability of fulfilling it within {d} s"),
            None => "maximum probability of success".to_string(),
        }
    }

    /// `HH:MM` of start time `k`.
    pub fn row_label(&self, k: usize) -> String {
        let minutes = self.table.minutes(k);
        format!("{:02}:{:02}", minutes / 60, minutes % 60)
    }

    /// `Thu 09-04` of day `d`.
    pub fn day_label(&self, d: usize) -> String {
        day_label(self.table.day(d))
    }

    /// What the codes of the first actions stand for.
    pub fn legend(&self) -> Vec<String> {
        self.table
            .first_edges
            .iter()
            .enumerate()
            .map(|(i, &e)| format!("{} = {}", letters(i), self.edges[e]))
            .chain(std::iter::once(
                "- = nothing to do (the task holds, or cannot be fulfilled)".to_string(),
            ))
            .collect()
    }

    /// The table as text: `Pmax code` per start time (rows) and day (columns), then the
    /// legend.
    pub fn render(&self) -> String {
        let mut header = vec!["start (UTC)".to_string()];
        header.extend((0..self.table.days).map(|d| self.day_label(d)));
        let mut grid = Table::new(header);
        for k in 0..self.table.per_day {
            let mut row = vec![self.row_label(k)];
            for d in 0..self.table.days {
                let (p, first_edge) = self.cell(d, k);
                row.push(format!("{p:.2} {}", self.table.code(first_edge)));
            }
            grid.row(row);
        }
        let mut text = grid.render();
        for line in self.legend() {
            text.push_str(&format!("\n  {line}"));
        }
        text
    }

    /// The table as `chronomap plan --day-table` prints it.
    pub fn text(&self) -> String {
        format!(
            "task {:?} from {}: {} and first action, {} start times in {:.2} s\n{}\n",
            self.task,
            self.from,
            self.what(),
            self.table.plans.len(),
            self.seconds,
            self.render()
        )
    }

    /// The plans as `chronomap plan --day-table --json` prints them; with a deadline each
    /// start time also has `deadline_probability`, `deadline_first_edge` and
    /// `min_time_probability` (the expected-time plan's probability within the deadline).
    pub fn json(&self) -> Value {
        let name = |e: Option<usize>| e.map(|e| self.edges[e].clone());
        let rows: Vec<Value> = self
            .table
            .plans
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let mut row = json!({
                    "time": p.time,
                    "utc": time(p.time),
                    "pmax": p.pmax,
                    "expected_secs": p.expected_secs,
                    "first_edge": name(p.first_edge),
                });
                if let Some(d) = self.table.deadline_plans.get(i) {
                    row["deadline_probability"] = json!(d.probability);
                    row["deadline_first_edge"] = json!(name(d.first_edge));
                    row["min_time_probability"] = json!(d.min_time_probability);
                }
                row
            })
            .collect();
        let mut table =
            json!({"task": self.task, "from": self.from, "plans": rows, "seconds": self.seconds});
        if let Some(d) = self.table.deadline_plans.first() {
            table["deadline_secs"] = json!(d.deadline_secs);
            table["bucket_secs"] = json!(d.bucket_secs);
        }
        table
    }

    /// The table as a heat map of `Pmax` (or of the probability within the deadline) with
    /// the codes of the first actions.
    #[cfg(feature = "plot")]
    pub fn heatmap(&self) -> Heatmap {
        let (days, per_day) = (self.table.days, self.table.per_day);
        // Row-major, one row per start time.
        let cells = || (0..per_day).flat_map(move |k| (0..days).map(move |d| (d, k)));
        let (what, value_label) = match self.deadline_secs() {
            Some(d) => (format!("P(within {d} s)"), format!("P(within {d} s)")),
            None => ("P(success)".to_string(), "Pmax".to_string()),
        };
        Heatmap {
            title: format!("Now or later? {what} of {:?} from {}", self.task, self.from),
            row_label: "start (UTC)".to_string(),
            column_label: "day".to_string(),
            rows: (0..per_day).map(|k| self.row_label(k)).collect(),
            columns: (0..days).map(|d| self.day_label(d)).collect(),
            values: cells()
                .map(|(d, k)| self.cell(d, k).0.clamp(0.0, 1.0))
                .collect(),
            cell_text: cells()
                .map(|(d, k)| self.table.code(self.cell(d, k).1))
                .collect(),
            value_label,
            legend: self.legend(),
        }
    }
}

/// 2014-08-20 00:00 UTC: the chronological split of the Witham Wharf data in the demo (train
/// before, test from).
pub const WITHAM_SPLIT: f64 = 1_408_492_800.0;

/// The topological part of `chronomap demo` ([Fentanes 2015]): edge models of the Witham Wharf
/// deployment scored on its later weeks, and a now-or-later table through the lab door.
pub struct WithamDemo {
    /// Nodes, edges and attempts of the data.
    pub nodes: usize,
    /// Edges of the map.
    pub edges: usize,
    /// Attempts in all.
    pub attempts: usize,
    /// The first and last attempt's times.
    pub span: (f64, f64),
    /// Attempts before [`WITHAM_SPLIT`] (trained on).
    pub train_attempts: usize,
    /// Attempts from it on (scored on).
    pub test_attempts: usize,
    /// Scores when each attempt is predicted from everything before it.
    pub online: EdgeEvaluation,
    /// Scores of the models as trained.
    pub frozen: EdgeEvaluation,
    /// Seconds spent fitting the models on all attempts (timed on purpose: the demo says it).
    pub fit_seconds: f64,
    /// "F Kitchen" from Station over the week after the data.
    pub table: DayTable,
}

/// The models of the demo: success by FreMEn of order 1 with persistence (the daily rhythm of
/// the doors plus the memory of the last attempts), durations by FreMEn with automatic order.
fn witham_config() -> EdgeModelConfig {
    EdgeModelConfig {
        success_order: Some(1),
        ..EdgeModelConfig::default()
    }
}

/// Runs the demo's topological section on the Witham Wharf edge statistics `stats`: trains
/// before [`WITHAM_SPLIT`] and scores after it, then fits all attempts and plans "F Kitchen"
/// from Station every two hours of the week after the data (reported to `progress` as the
/// stages `Witham edges` and `Witham plans`).
///
/// # Errors
/// [`TopoJobError::WithamEmpty`] for data without attempts, a fit or evaluation that fails,
/// a map without the Station or Kitchen node.
pub fn witham_demo(
    stats: &EdgeStatistics,
    progress: &dyn Progress,
) -> Result<WithamDemo, TopoJobError> {
    let fit = |map, attempts: &[_]| {
        EdgeModels::fit(map, attempts, witham_config()).map_err(|(edge, error)| TopoJobError::Fit {
            file: PathBuf::from(format!("Witham edge {edge}")),
            attempt: None,
            error,
        })
    };
    progress.stage("Witham edges", 0);
    let span = stats.time_span().ok_or(TopoJobError::WithamEmpty)?;
    let (train, test) = stats.split_at(WITHAM_SPLIT);
    let train_attempts = train.total_attempts();
    let models = fit(train.map, &train.attempts)?;
    let online = models.evaluate_online(&test.attempts)?;
    let frozen = models.evaluate(&test.attempts)?;
    progress.stage("Witham plans", 0);
    let started = Instant::now();
    let models = fit(stats.map.clone(), &stats.attempts)?;
    let fit_seconds = started.elapsed().as_secs_f64();
    let (from, text) = ("Station", "F Kitchen");
    let start = models.map().node(from).map_err(PlanError::from)?;
    let task = Task::parse(text, models.map())?;
    let table = DayTable::compute(
        &models,
        (start, from),
        (&task, text),
        span.1 + 86_400.0,
        7,
        120,
    )?;
    Ok(WithamDemo {
        nodes: stats.map.nodes().len(),
        edges: stats.map.edges().len(),
        attempts: stats.total_attempts(),
        span,
        train_attempts,
        test_attempts: test.total_attempts(),
        online,
        frozen,
        fit_seconds,
        table,
    })
}

/// `text` with every line indented by three spaces, as the demo's sections are.
fn indent(text: &str) -> String {
    text.lines()
        .map(|l| format!("   {l}"))
        .collect::<Vec<_>>()
        .join("\n")
}

impl WithamDemo {
    /// The section as `chronomap demo` prints it (after its title).
    pub fn text(&self) -> String {
        self.to_string()
    }
}

impl fmt::Display for WithamDemo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "   Witham Wharf, {} nodes, {} edges, {} traversal attempts, {} .. {}.",
            self.nodes,
            self.edges,
            self.attempts,
            time(self.span.0),
            time(self.span.1)
        )?;
        writeln!(
            f,
            "   Trained on the {} attempts before {}, scored on the {} after (the robot's later weeks):\n",
            self.train_attempts,
            time(WITHAM_SPLIT),
            self.test_attempts
        )?;
        let table = score_table(
            "static (s²)",
            [
                (
                    "online: models learn each attempt after predicting it".to_string(),
                    &self.online,
                ),
                ("frozen: models as trained".to_string(), &self.frozen),
            ],
        );
        writeln!(f, "{}", indent(&table.render()))?;
        writeln!(
            f,
            "\n   Online, the per-edge models beat the static per-edge rates by far: persistence (\
             [Krajník 2017] eq. 12-13)\n   carries the robot's retry bursts. Frozen for weeks, the daily rhythm \
             alone does not transfer."
        )?;
        writeln!(
            f,
            "\n   Fitted on all attempts in {:.2} s. Task \"F Kitchen\" from Station: the lab's \
             only way out\n   is the door LabDoor1 -> LabDoor2. Maximum probability of success and first \
             action in the week\n   after the data ({} plans in {:.1} ms):\n",
            self.fit_seconds,
            7 * 12,
            1e3 * self.table.seconds
        )?;
        writeln!(f, "{}", indent(&self.table.render()))?;
        writeln!(
            f,
            "\n   The door's daily rhythm: hopeless at night, best in the afternoon; the first night \
             still\n   remembers the successes just before the data end (persistence)."
        )
    }
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

    #[test]
    fn fit_split_predict_and_plan_report_one_edge() {
        let tmp = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-app-topo-report-{}", std::process::id())),
        );
        let edges = tmp.join("edges");
        std::fs::create_dir_all(&edges).unwrap();
        // Four attempts of A_B on 2014-08-20 (Wednesday): `time duration success`.
        let t0 = 1_408_492_800.0;
        chronomap_testutil::write(
            &edges,
            "A_B.data",
            format!(
                "{t0} 10 1\n{} 20 0\n{} 30 1\n{} 40 1\n",
                t0 + 60.0,
                t0 + 120.0,
                t0 + 180.0
            ),
        );
        let model = tmp.join("m.cme");
        let fit = fit_report(&edges, &model, EdgeModelConfig::default()).unwrap();
        assert_eq!((fit.nodes, fit.edges, fit.attempts), (2, 1, 4));
        assert_eq!((fit.first, fit.last), (Some(t0), Some(t0 + 180.0)));
        assert_eq!(fit.success_orders.iter().sum::<usize>(), 1);
        let text = fit.to_string();
        assert!(
            text.starts_with(&format!(
                "{}: 2 nodes, 1 edges, 4 attempts, 2014-08-20 00:00 UTC .. 2014-08-20 00:03 UTC\n",
                edges.display()
            )),
            "{text}"
        );
        assert!(text.ends_with(&format!("; wrote {}\n", model.display())));

        // Two attempts on either side of t0 + 90 s.
        let (before, after) = (tmp.join("before"), tmp.join("after"));
        let split_at = split(&edges, t0 + 90.0, &before, &after).unwrap();
        assert_eq!((split_at.before.attempts, split_at.after.attempts), (2, 2));
        assert_eq!(
            (split_at.before.edge_files, split_at.after.edge_files),
            (1, 1)
        );
        assert_eq!(split_at.utc, "2014-08-20 00:01 UTC");
        let outside = split(&edges, t0 + 1000.0, &tmp.join("b2"), &tmp.join("a2")).unwrap_err();
        assert_eq!(
            outside.to_string(),
            "splitting at 2014-08-20 00:16 UTC leaves 4 attempts before and 0 after; choose a \
             time inside the data (2014-08-20 00:00 UTC .. 2014-08-20 00:03 UTC)"
        );

        let models = chronomap_io::read_edge_models(&model).unwrap();
        let predicted = predict(&models, t0);
        assert_eq!(predicted.edges.len(), 1);
        let edge = &predicted.edges[0];
        assert_eq!(
            (edge.edge.as_str(), edge.from.as_str(), edge.to.as_str()),
            ("A_B", "A", "B")
        );
        assert_eq!(edge.attempts, 4);
        assert_eq!(edge.success_probability, models.success_probability(0, t0));

        let (a, task) = (
            models.map().node("A").unwrap(),
            Task::parse("F B", models.map()).unwrap(),
        );
        let timed = plan_at(&models, a, &task, t0, &SolverOptions::default()).unwrap();
        let report = plan_report(&models, &timed, "A", "F B", t0);
        assert_eq!(report.first_edge.as_deref(), Some("A_B"));
        assert_eq!(report.route, ["A_B"]);
        assert_eq!(
            report.route_success_probabilities,
            [edge.success_probability]
        );
        let text = report.to_string();
        assert!(
            text.starts_with("task \"F B\" from A at 2014-08-20 00:00 UTC\n"),
            "{text}"
        );
        assert!(text.contains(&format!(
            "\nfirst action: A_B\nroute if every edge succeeds: A_B ({:.2})\n",
            edge.success_probability
        )));
        let (prism, property) = timed.prism(a, &task).unwrap();
        assert!(!prism.is_empty() && property.ends_with('\n'));

        // Two days from Wednesday, every 12 hours: one code, `a`, for the only edge.
        let table =
            DayTable::compute(&models, (a, "A"), (&task, "F B"), t0 + 3600.0, 2, 720).unwrap();
        assert_eq!(table.table.plans.len(), 4);
        assert_eq!(
            (table.day_label(0), table.day_label(1)),
            ("Wed 08-20".to_string(), "Thu 08-21".to_string())
        );
        assert_eq!(
            (table.row_label(0), table.row_label(1)),
            ("00:00".to_string(), "12:00".to_string())
        );
        assert_eq!(
            table.legend(),
            [
                "a = A_B",
                "- = nothing to do (the task holds, or cannot be fulfilled)"
            ]
        );
        #[cfg(feature = "plot")]
        assert_eq!(table.heatmap().cell_text, ["a", "a", "a", "a"]);
        assert_eq!(table.json()["plans"][3]["first_edge"], "A_B");
        let _ = std::fs::remove_dir_all(&tmp);
    }

    #[test]
    fn the_witham_demo_trains_before_the_split_and_plans_the_week_after() {
        let stats = read_edge_directory(chronomap_testutil::data_path(
            "witham_topological_nav/edges",
        ))
        .unwrap();
        let demo = witham_demo(&stats, &NoProgress).unwrap();
        assert_eq!(demo.train_attempts + demo.test_attempts, demo.attempts);
        let (before, after) = stats.split_at(WITHAM_SPLIT);
        assert_eq!(
            (demo.train_attempts, demo.test_attempts),
            (before.total_attempts(), after.total_attempts())
        );
        // Seven days of twelve start times, two hours apart.
        assert_eq!((demo.table.table.days, demo.table.table.per_day), (7, 12));
        let text = demo.to_string();
        assert!(text.contains("(84 plans in "), "{text}");
        assert!(text.lines().all(|l| l.is_empty() || l.starts_with("   ")));
    }
}
