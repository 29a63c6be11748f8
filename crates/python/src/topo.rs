//! Topological maps whose edges know time, and the now-or-later planner ([Fentanes 2015]):
//! `chronomap.EdgeModels` over [`chronomap_topo::edges::EdgeModels`], the edge files of
//! [`chronomap_io::topo_files`] and the edge-model files of [`chronomap_io::model_file`].

use std::path::{Path, PathBuf};

use chronomap_app::topo::{TopoJobError, deadline_report, observe_directory};
use chronomap_io::{read_edge_directory, read_edge_models, write_edge_models};
use chronomap_topo::deadline::{DeadlineError, DeadlineOptions, now_or_later_by_deadline};
use chronomap_topo::duration_intervals::MAX_COVERAGE;
use chronomap_topo::edges::{EdgeModelConfig, EdgeModels};
use chronomap_topo::mdp::SolverOptions;
use chronomap_topo::plan::{Task, now_or_later, plan_full};
use chronomap_topo::report::success_route;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{self, to_numpy};
use crate::errors;

/// Checks a time argument.
fn check_time(name: &str, time: f64) -> PyResult<()> {
    if time.is_finite() {
        Ok(())
    } else {
        Err(PyValueError::new_err(format!(
            "{name}: {time} is not a finite number"
        )))
    }
}

/// The confidence of a deadline plan when none is given (as `chronomap plan --deadline`).
const DEFAULT_CONFIDENCE: f64 = 0.95;

/// Checks that `value` is a probability, as `chronomap topo fit --prior/--floor` do.
/// A deadline planner's error as a ValueError naming the argument at fault: the deadline, or
/// the bucket width when it was given (too many cells without one: the deadline).
fn deadline_error(e: DeadlineError, bucket_given: bool) -> PyErr {
    match e {
        DeadlineError::InvalidDeadline(_) => PyValueError::new_err(format!("deadline: {e}")),
        DeadlineError::TooManyCells { .. } if !bucket_given => {
            PyValueError::new_err(format!("deadline: {e}"))
        }
        DeadlineError::InvalidBucket(_)
        | DeadlineError::BucketWiderThanDeadline { .. }
        | DeadlineError::TooManyCells { .. } => PyValueError::new_err(format!("bucket_secs: {e}")),
        e => PyValueError::new_err(e.to_string()),
    }
}

fn probability(name: &str, value: f64) -> PyResult<f64> {
    if (0.0..=1.0).contains(&value) {
        Ok(value)
    } else {
        Err(PyValueError::new_err(format!(
            "{name}: {value} is not a probability in [0, 1]"
        )))
    }
}

/// The success and duration models of every edge of a topological map ([Fentanes 2015] §IV):
/// p_e(t), the probability that traversing edge e started at t succeeds, and its expected
/// duration, each a FreMEn model (with persistence) learnt from the robot's attempts.
///
/// Fit them with `EdgeModels.fit(edges_dir)` from a directory of edge files (what `chronomap
/// topo fit` reads), or read an edge-model file with `chronomap.load_edge_models(path)`.
/// `predict(t)` gives every edge's prediction (`chronomap topo predict`), `plan(start, task, t)`
/// the now-or-later plan of a co-safe LTL task (`chronomap plan --time`), and with `deadline=D`
/// the plan most likely to fulfil it within `D` seconds (`chronomap plan --deadline`).
#[pyclass(name = "EdgeModels", module = "chronomap", frozen)]
pub struct PyEdgeModels {
    models: EdgeModels,
}

impl PyEdgeModels {
    fn start_and_task(&self, start: &str, task: &str) -> PyResult<(usize, Task)> {
        let map = self.models.map();
        let start = map
            .node(start)
            .map_err(|e| PyValueError::new_err(format!("start: {e}")))?;
        let task =
            Task::parse(task, map).map_err(|e| PyValueError::new_err(format!("task: {e}")))?;
        Ok((start, task))
    }

    /// `plan` without a deadline.
    fn plan_at<'py>(
        &self,
        py: Python<'py>,
        start: &str,
        task: &str,
        time: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (start_node, parsed) = self.start_and_task(start, task)?;
        let models = &self.models;
        let map = models.map();
        let planned = py
            .detach(|| plan_full(models, start_node, &parsed, time, &SolverOptions::default()))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let route = success_route(&planned, map);
        let plan = &planned.plan;
        let dict = PyDict::new(py);
        dict.set_item("task", task)?;
        dict.set_item("from", start)?;
        dict.set_item("time", time)?;
        dict.set_item("pmax", plan.pmax)?;
        dict.set_item("expected_secs", plan.expected_secs)?;
        dict.set_item(
            "first_edge",
            plan.first_edge.map(|e| map.edges()[e].id.clone()),
        )?;
        dict.set_item(
            "route",
            route
                .iter()
                .map(|&e| map.edges()[e].id.clone())
                .collect::<Vec<_>>(),
        )?;
        dict.set_item(
            "route_success_probabilities",
            route
                .iter()
                .map(|&e| models.success_probability(e, time))
                .collect::<Vec<_>>(),
        )?;
        dict.set_item("product_states", planned.product.states().len())?;
        // The policy: the edge to take in every undecided state of the product (node,
        // automaton state), with that state's Pmax.
        let (mut nodes, mut dfa_states, mut edges, mut pmax) = (vec![], vec![], vec![], vec![]);
        for (s, state) in planned.product.states().iter().enumerate() {
            if let (Some(node), Some(edge)) = (state.node, planned.solution.policy[s]) {
                nodes.push(map.nodes()[node].name.clone());
                dfa_states.push(state.dfa_state as i64);
                edges.push(map.edges()[edge].id.clone());
                pmax.push(planned.solution.pmax[s]);
            }
        }
        let policy = PyDict::new(py);
        policy.set_item("node", nodes)?;
        policy.set_item("automaton_state", numpy::PyArray1::from_vec(py, dfa_states))?;
        policy.set_item("edge", edges)?;
        policy.set_item("pmax", to_numpy(py, pmax))?;
        dict.set_item("policy", policy)?;
        Ok(dict)
    }

    /// The deadline and bucket width of `plan` and `now_or_later`, checked (a ValueError
    /// naming the argument).
    fn check_deadline(deadline: f64, bucket_secs: Option<f64>) -> PyResult<()> {
        if !(deadline.is_finite() && deadline > 0.0) {
            return Err(PyValueError::new_err(format!(
                "deadline: {deadline} is not a finite number of seconds > 0"
            )));
        }
        if let Some(width) = bucket_secs
            && !(width.is_finite() && width > 0.0)
        {
            return Err(PyValueError::new_err(format!(
                "bucket_secs: {width} is not a finite number of seconds > 0"
            )));
        }
        Ok(())
    }

    /// `plan` with a deadline: [`deadline_report`] as a dict.
    fn plan_deadline<'py>(
        &self,
        py: Python<'py>,
        (start, task, time): (&str, &str, f64),
        deadline: f64,
        confidence: Option<f64>,
        bucket_secs: Option<f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        Self::check_deadline(deadline, bucket_secs)?;
        let confidence = probability("confidence", confidence.unwrap_or(DEFAULT_CONFIDENCE))?;
        let (start_node, parsed) = self.start_and_task(start, task)?;
        let models = &self.models;
        let report = py
            .detach(|| {
                deadline_report(
                    models,
                    (start_node, start),
                    (&parsed, task),
                    time,
                    deadline,
                    bucket_secs,
                    confidence,
                )
            })
            .map_err(|e| deadline_error(e, bucket_secs.is_some()))?;
        let dict = PyDict::new(py);
        dict.set_item("task", &report.task)?;
        dict.set_item("from", &report.from)?;
        dict.set_item("time", report.time)?;
        dict.set_item("utc", &report.utc)?;
        dict.set_item("deadline_secs", report.deadline_secs)?;
        dict.set_item("confidence", report.confidence)?;
        dict.set_item("probability", report.probability)?;
        dict.set_item("reaches_confidence", report.reaches_confidence)?;
        dict.set_item("first_edge", &report.first_edge)?;
        dict.set_item("median_route", &report.median_route)?;
        dict.set_item("shortest_deadline_secs", report.shortest_deadline_secs)?;
        dict.set_item("min_time_probability", report.min_time_probability)?;
        dict.set_item("min_time_first_edge", &report.min_time_first_edge)?;
        dict.set_item("pmax", report.pmax)?;
        dict.set_item("expected_secs", report.expected_secs)?;
        dict.set_item("bucket_secs", report.bucket_secs)?;
        let rows = report.curve.len();
        let flat: Vec<f64> = report.curve.iter().flatten().copied().collect();
        dict.set_item("curve", to_numpy(py, flat).reshape([rows, 3])?)?;
        dict.set_item("duration_quantiles", report.duration_quantiles)?;
        dict.set_item("product_states", report.product_states)?;
        dict.set_item("seconds", report.seconds)?;
        Ok(dict)
    }
}

#[pymethods]
impl PyEdgeModels {
    /// `EdgeModels.fit(edges, *, static=False, persistence=True, min_attempts=10, prior=0.9,
    /// prior_attempts=2.0, floor=0.05, max_order=10, success_order=None, holdout=0.25)`
    ///
    /// Fits the models of every edge from `edges`, a directory of edge files
    /// `<From>_<To>.data` (plain, .xz or .gz; lines `t duration_s success(0|1)`), exactly as
    /// `chronomap topo fit --edges` does with the same options: `static` keeps static per-edge
    /// models only, `persistence=False` drops the persistence term, edges with fewer than
    /// `min_attempts` attempts use their shrunk success rate, `prior` / `prior_attempts` are the
    /// prior success probability and its weight, `floor` the lowest success probability,
    /// `max_order` the largest FreMEn order tried, `success_order` a fixed order for every
    /// success model ([Fentanes 2015]: "typically, m = 2"), `holdout` the most recent fraction of
    /// each edge's history held back to choose orders.
    #[staticmethod]
    #[pyo3(signature = (edges, *, r#static = false, persistence = true, min_attempts = 10, prior = 0.9, prior_attempts = 2.0, floor = 0.05, max_order = 10, success_order = None, holdout = 0.25))]
    #[allow(clippy::too_many_arguments)]
    fn fit(
        py: Python<'_>,
        edges: PathBuf,
        r#static: bool,
        persistence: bool,
        min_attempts: usize,
        prior: f64,
        prior_attempts: f64,
        floor: f64,
        max_order: usize,
        success_order: Option<usize>,
        holdout: f64,
    ) -> PyResult<Self> {
        if !(prior_attempts.is_finite() && prior_attempts >= 0.0) {
            return Err(PyValueError::new_err(format!(
                "prior_attempts: {prior_attempts} is not a finite number >= 0"
            )));
        }
        if !(holdout > 0.0 && holdout < 1.0) {
            return Err(PyValueError::new_err(format!(
                "holdout: {holdout} is not a number strictly between 0 and 1"
            )));
        }
        let config = EdgeModelConfig {
            min_attempts,
            prior_success: probability("prior", prior)?,
            prior_attempts,
            floor: probability("floor", floor)?,
            periodic: !r#static,
            persistence,
            holdout,
            max_order,
            success_order,
            default_duration_secs: None,
        };
        let stats = py
            .detach(|| read_edge_directory(&edges))
            .map_err(|e| errors::data(&e))?;
        let models = py
            .detach(|| EdgeModels::fit(stats.map, &stats.attempts, config))
            .map_err(|(edge, error)| {
                let at = error
                    .observation_index()
                    .map(|i| format!(": attempt {}", i + 1))
                    .unwrap_or_default();
                PyValueError::new_err(format!(
                    "{}{at}: {error}",
                    Path::new(&edges).join(format!("{edge}.data")).display()
                ))
            })?;
        Ok(PyEdgeModels { models })
    }

    /// Every edge's prediction at `time` (seconds), as `chronomap topo predict --json` gives it:
    /// a dict with `edge`, `from`, `to` (lists of names, in edge order) and the arrays
    /// `success_probability`, `uncertainty` (sd of the Beta posterior),
    /// `static_success_probability`, `duration_secs` (expected duration of a successful
    /// traversal), `duration_lower_secs` and `duration_upper_secs` (the interval that holds a
    /// successful traversal's duration with probability `coverage`, 0.9 by default as in the
    /// CLI, at most 0.99; NaN for models written before intervals existed) and `attempts`.
    #[pyo3(signature = (time, *, coverage = 0.9))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        time: &Bound<'py, PyAny>,
        coverage: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let time = arrays::time_scalar(time, "time")?;
        check_time("time", time)?;
        if !(coverage > 0.0 && coverage <= MAX_COVERAGE) {
            return Err(PyValueError::new_err(format!(
                "coverage: {coverage} is not in (0, {MAX_COVERAGE}]"
            )));
        }
        let models = &self.models;
        let map = models.map();
        let (success, duration) = py.detach(|| models.at(time));
        let n = map.edges().len();
        let dict = PyDict::new(py);
        let edges = map.edges();
        dict.set_item(
            "edge",
            edges.iter().map(|e| e.id.clone()).collect::<Vec<_>>(),
        )?;
        dict.set_item(
            "from",
            edges
                .iter()
                .map(|e| map.nodes()[e.from].name.clone())
                .collect::<Vec<_>>(),
        )?;
        dict.set_item(
            "to",
            edges
                .iter()
                .map(|e| map.nodes()[e.to].name.clone())
                .collect::<Vec<_>>(),
        )?;
        dict.set_item("success_probability", to_numpy(py, success))?;
        dict.set_item(
            "uncertainty",
            to_numpy(
                py,
                (0..n)
                    .map(|e| models.success_uncertainty(e, time))
                    .collect(),
            ),
        )?;
        dict.set_item(
            "static_success_probability",
            to_numpy(
                py,
                (0..n)
                    .map(|e| models.static_success_probability(e))
                    .collect(),
            ),
        )?;
        dict.set_item("duration_secs", to_numpy(py, duration))?;
        let intervals: Vec<(f64, f64)> = (0..n)
            .map(|e| {
                models
                    .duration_interval(e, time, coverage)
                    .unwrap_or((f64::NAN, f64::NAN))
            })
            .collect();
        dict.set_item(
            "duration_lower_secs",
            to_numpy(py, intervals.iter().map(|i| i.0).collect()),
        )?;
        dict.set_item(
            "duration_upper_secs",
            to_numpy(py, intervals.iter().map(|i| i.1).collect()),
        )?;
        dict.set_item(
            "attempts",
            PyArray1::from_vec(py, (0..n).map(|e| models.edge(e).attempts as i64).collect()),
        )?;
        Ok(dict)
    }

    /// The now-or-later plan of `task` (co-safe LTL over node names: `"F Kitchen"`,
    /// `"F (Printer & F Kitchen)"`, `"!Ramp1 U Kitchen"`) from node `start` at `time` (seconds)
    /// ([Fentanes 2015] §V): the Navigation MDP at that time, its product with the task's
    /// automaton, solved. A dict with what `chronomap plan --time --json` prints: `task`,
    /// `from`, `time`, `pmax` (maximum probability of fulfilling the task), `expected_secs`
    /// (expected time until done or failed, following the policy), `first_edge` (the edge to
    /// take now, None if the task holds already or cannot be fulfilled), `route` (the edges
    /// taken if every edge succeeds), `route_success_probabilities` and `product_states`;
    /// and `policy`, the whole policy: for every undecided state of the product MDP, its
    /// `node`, `automaton_state`, the `edge` to take and the state's `pmax` (lists/arrays).
    ///
    /// With `deadline` (seconds, finite, > 0): "arrive by T" — the plan most likely to fulfil
    /// the task within `deadline` seconds of `time` ([`chronomap_topo::deadline`]), as
    /// `chronomap plan --time --deadline --json` gives it instead: `probability` (a certified
    /// lower bound: durations rounded up to buckets of `bucket_secs`, default
    /// `max(deadline / 600, 1)` s), `first_edge`, `median_route`, `reaches_confidence` and
    /// `shortest_deadline_secs` (for `confidence`, default 0.95), the expected-time plan's
    /// `min_time_probability`, `min_time_first_edge`, `pmax` and `expected_secs`, `curve` (a
    /// float64 array of rows `[d, deadline plan, expected-time plan]`: the probabilities
    /// within `d`, `d = 0, bucket_secs, …`), `deadline_secs`, `confidence`, `bucket_secs`,
    /// `duration_quantiles`, `product_states`, `seconds`, `task`, `from`, `time`, `utc`. More
    /// than 10^6 cells (product states × buckets) is a ValueError. The GIL is released while
    /// it plans.
    #[pyo3(signature = (start, task, time, *, deadline = None, confidence = None, bucket_secs = None))]
    #[allow(clippy::too_many_arguments)]
    fn plan<'py>(
        &self,
        py: Python<'py>,
        start: &str,
        task: &str,
        time: &Bound<'py, PyAny>,
        deadline: Option<f64>,
        confidence: Option<f64>,
        bucket_secs: Option<f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let time = arrays::time_scalar(time, "time")?;
        check_time("time", time)?;
        let Some(deadline) = deadline else {
            for (name, given) in [
                ("confidence", confidence.is_some()),
                ("bucket_secs", bucket_secs.is_some()),
            ] {
                if given {
                    return Err(PyValueError::new_err(format!("{name}: only with deadline")));
                }
            }
            return self.plan_at(py, start, task, time);
        };
        self.plan_deadline(py, (start, task, time), deadline, confidence, bucket_secs)
    }

    /// "Now or later?" ([Fentanes 2015] Table III): the plan of `task` from `start` at each of
    /// `times` (float64 seconds). A dict with the arrays `time`, `pmax`, `expected_secs` and the
    /// list `first_edge` (edge ids or None), as `chronomap plan --day-table --json` gives per
    /// start time. With `deadline` (seconds > 0; `bucket_secs` as for `plan`), also the plan
    /// most likely to fulfil the task within it at each time, as `chronomap plan --day-table
    /// --deadline --json`: the arrays `deadline_probability` and `min_time_probability` (the
    /// expected-time plan's probability in time), the list `deadline_first_edge`, and
    /// `deadline_secs`, `bucket_secs`. The GIL is released while it plans.
    #[pyo3(signature = (start, task, times, *, deadline = None, bucket_secs = None))]
    fn now_or_later<'py>(
        &self,
        py: Python<'py>,
        start: &str,
        task: &str,
        times: &Bound<'py, PyAny>,
        deadline: Option<f64>,
        bucket_secs: Option<f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let times = arrays::time_array(times, "times")?;
        let times = times.as_slice();
        if let Some(i) = times.iter().position(|t| !t.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "times[{i}]: {} is not a finite number",
                times[i]
            )));
        }
        let (start_node, parsed) = self.start_and_task(start, task)?;
        let models = &self.models;
        let plans = py
            .detach(|| {
                now_or_later(
                    models,
                    start_node,
                    &parsed,
                    times,
                    &SolverOptions::default(),
                )
            })
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let edges = models.map().edges();
        // The first edges of plans as edge ids (None where there is nothing to do).
        let first_edges = |first: &mut dyn Iterator<Item = Option<usize>>| {
            first
                .map(|e| e.map(|e| edges[e].id.clone()))
                .collect::<Vec<_>>()
        };
        let dict = PyDict::new(py);
        dict.set_item("time", to_numpy(py, times.to_vec()))?;
        dict.set_item("pmax", to_numpy(py, plans.iter().map(|p| p.pmax).collect()))?;
        dict.set_item(
            "expected_secs",
            to_numpy(py, plans.iter().map(|p| p.expected_secs).collect()),
        )?;
        dict.set_item(
            "first_edge",
            first_edges(&mut plans.iter().map(|p| p.first_edge)),
        )?;
        let Some(deadline) = deadline else {
            if bucket_secs.is_some() {
                return Err(PyValueError::new_err("bucket_secs: only with deadline"));
            }
            return Ok(dict);
        };
        Self::check_deadline(deadline, bucket_secs)?;
        let options = DeadlineOptions {
            bucket_secs,
            ..DeadlineOptions::default()
        };
        let by_deadline = py
            .detach(|| {
                now_or_later_by_deadline(
                    models,
                    start_node,
                    &parsed,
                    times,
                    deadline,
                    &options,
                    || {},
                )
            })
            .map_err(|e| deadline_error(e, bucket_secs.is_some()))?;
        dict.set_item("deadline_secs", deadline)?;
        if let Some(plan) = by_deadline.first() {
            dict.set_item("bucket_secs", plan.bucket_secs)?;
        }
        dict.set_item(
            "deadline_probability",
            to_numpy(py, by_deadline.iter().map(|p| p.probability).collect()),
        )?;
        dict.set_item(
            "min_time_probability",
            to_numpy(
                py,
                by_deadline.iter().map(|p| p.min_time_probability).collect(),
            ),
        )?;
        dict.set_item(
            "deadline_first_edge",
            first_edges(&mut by_deadline.iter().map(|p| p.first_edge)),
        )?;
        Ok(dict)
    }

    /// Writes the models to `path` (versioned, checksummed, atomic): the file `chronomap topo
    /// fit -o` writes and `chronomap topo predict`, `chronomap plan` and `chronomap serve --topo`
    /// read.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| write_edge_models(&path, &self.models))
            .map_err(|e| errors::model_file(&e))
    }

    /// `models.observe(edges)`: new models that have also learnt the attempts in the edge files
    /// of `edges` (a directory as `fit` reads; each attempt later than what its edge learnt
    /// last), in the order of their times, as a robot that keeps travelling learns them — what
    /// `chronomap topo observe` does: the success models, the static rates and the online
    /// adaptation of the duration intervals ([Gibbs 2021], adaptive conformal inference).
    /// Edges the models lack are added, modelled from their priors. These models stay as they
    /// are. An attempt out of order or already learnt is a `ValueError` naming the file and
    /// the attempt; a missing directory a `FileNotFoundError`.
    fn observe(&self, py: Python<'_>, edges: PathBuf) -> PyResult<Self> {
        let mut models = self.models.clone();
        py.detach(|| observe_directory(&mut models, &edges))
            .map_err(|e| match e {
                TopoJobError::Read(data) => errors::data(&data),
                other => PyValueError::new_err(other.to_string()),
            })?;
        Ok(PyEdgeModels { models })
    }

    /// Successful traversals the duration intervals have adapted to since the fit (`observe`).
    #[getter]
    fn adapted_traversals(&self) -> u64 {
        self.models.duration_spread().adapted.count
    }

    /// The node names, in map order.
    #[getter]
    fn nodes(&self) -> Vec<String> {
        self.models
            .map()
            .nodes()
            .iter()
            .map(|n| n.name.clone())
            .collect()
    }

    /// The edge ids (`From_To`), in map order (the order of `predict`'s arrays).
    #[getter]
    fn edges(&self) -> Vec<String> {
        self.models
            .map()
            .edges()
            .iter()
            .map(|e| e.id.clone())
            .collect()
    }

    /// Time of the latest attempt the models learnt from, or None.
    #[getter]
    fn last_time(&self) -> Option<f64> {
        self.models.last_time()
    }

    fn __repr__(&self) -> String {
        let map = self.models.map();
        format!(
            "<chronomap.EdgeModels {} nodes, {} edges>",
            map.nodes().len(),
            map.edges().len()
        )
    }
}

/// `load_edge_models(path)`: an edge-model file written by `chronomap topo fit` or
/// `EdgeModels.save`, checked (version, checksum, invariants). A missing file is a
/// `FileNotFoundError`, a damaged or foreign one a `ValueError`; both name the file.
#[pyfunction]
fn load_edge_models(py: Python<'_>, path: PathBuf) -> PyResult<PyEdgeModels> {
    let models = py
        .detach(|| read_edge_models(&path))
        .map_err(|e| errors::model_file(&e))?;
    Ok(PyEdgeModels { models })
}

/// Registers this module's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyEdgeModels>()?;
    m.add_function(wrap_pyfunction!(load_edge_models, m)?)?;
    Ok(())
}
