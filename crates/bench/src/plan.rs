//! Planning on the Witham map end to end ([Fentanes 2015] §V), against Storm on the same 72 cases
//! (24 hours × 3 tasks) in the same run.
//!
//! chronomap's time per case: parse the task and build its automaton, predict every edge at
//! `t`, build the Navigation MDP and its product with the automaton, solve for `Pmax`, the
//! least expected time among the `Pmax`-optimal policies and the policy
//! (`chronomap_topo::plan::plan_full`). Storm's (`tests/oracle/storm_time.py`, embedded here
//! and run with the Python of [`PlanConfig::storm_python`]): parse the PRISM model of the same
//! Navigation MDP and the task as co-safe LTL, build, check `Pmax` (Storm's own product
//! through Spot); and, apart, Storm solving chronomap's products from DRN.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use chronomap_core::progress::Progress;
use chronomap_topo::edges::{EdgeModelConfig, EdgeModels};
use chronomap_topo::mdp::{SolverOptions, prism_property, product_drn, restricted_drn};
use chronomap_topo::plan::{Planned, Task, plan_full};
use serde::Serialize;
use serde_json::Value;

use crate::{BenchError, median};

/// 2014-09-04 00:00 UTC, the day after the last attempt of the Witham data.
pub const DAY: f64 = 1_409_788_800.0;

/// (start node, task): reachability, an ordered visit, an avoid-until; all cross the lab door
/// (the same cases as `tests/cli/storm_witham.rs`). Each is planned at every hour of [`DAY`].
pub const TASKS: [(&str, &str); 3] = [
    ("Station", "F Kitchen"),
    ("Station", "F (Printer & F (Kitchen & F Station))"),
    ("Station", "!Printer U Kitchen"),
];

/// The Storm timing script.
const STORM_TIME_PY: &str = include_str!("../../../tests/oracle/storm_time.py");

/// What the planning benchmark reads and runs.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanConfig {
    /// The Witham edge files (`<From>_<To>.data.xz`).
    pub edges: PathBuf,
    /// A Python interpreter that imports stormpy 2.0: time Storm on the same cases.
    pub storm_python: Option<PathBuf>,
    /// Timed sweeps over the 72 cases after a warm-up (the median is reported; at least 1).
    pub repeat: usize,
    /// Also time Storm in exact (rational) arithmetic (slow).
    pub exact: bool,
}

/// One sweep: every task at every hour, from the task's text to the solution.
fn sweep(models: &EdgeModels) -> Result<Vec<(String, Planned)>, BenchError> {
    let options = SolverOptions::default();
    let mut cases = Vec::with_capacity(TASKS.len() * 24);
    for (t, (start, text)) in TASKS.iter().enumerate() {
        for hour in 0..24 {
            let task = Task::parse(text, models.map())?;
            let start = models.map().node(start)?;
            let planned = plan_full(
                models,
                start,
                &task,
                DAY + 3600.0 * f64::from(hour),
                &options,
            )?;
            cases.push((format!("task{t}_{hour:02}"), planned));
        }
    }
    Ok(cases)
}

/// A temporary directory, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> Result<Self, BenchError> {
        let nanos = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        let dir = std::env::temp_dir().join(format!(
            "chronomap-bench-plan-{}-{nanos}",
            std::process::id()
        ));
        std::fs::create_dir_all(&dir).map_err(|source| BenchError::Write {
            path: dir.clone(),
            source,
        })?;
        Ok(TempDir(dir))
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn write(path: PathBuf, contents: impl AsRef<[u8]>) -> Result<(), BenchError> {
    std::fs::write(&path, contents).map_err(|source| BenchError::Write { path, source })
}

/// Writes every case for Storm (PRISM + property, product and restricted DRN) and the script;
/// returns the `.nm` files.
fn write_cases(
    dir: &Path,
    models: &EdgeModels,
    cases: &[(String, Planned)],
) -> Result<Vec<PathBuf>, BenchError> {
    let mut files = Vec::with_capacity(cases.len());
    for (i, (name, planned)) in cases.iter().enumerate() {
        let (start, text) = TASKS[i / 24];
        let start = models.map().node(start)?;
        let (mdp, sol) = (planned.product.mdp(), &planned.solution);
        let nm = dir.join(format!("{name}.nm"));
        write(nm.clone(), planned.mdp.to_prism(start)?)?;
        write(
            dir.join(format!("{name}.props")),
            format!("{}\n", prism_property(text)?),
        )?;
        write(dir.join(format!("{name}.drn")), product_drn(mdp, sol)?)?;
        write(
            dir.join(format!("{name}.restricted.drn")),
            restricted_drn(mdp, sol)?,
        )?;
        files.push(nm);
    }
    write(dir.join("storm_time.py"), STORM_TIME_PY)?;
    Ok(files)
}

/// Storm's timings: the script's JSON and the wall-clock time of the whole process.
fn run_storm(
    python: &Path,
    config: &PlanConfig,
    models: &EdgeModels,
    cases: &[(String, Planned)],
    progress: &dyn Progress,
) -> Result<(Value, f64), BenchError> {
    let dir = TempDir::new()?;
    let files = write_cases(&dir.0, models, cases)?;
    let mut command = Command::new(python);
    command
        .arg(dir.0.join("storm_time.py"))
        .arg("--repeat")
        .arg(config.repeat.max(1).to_string())
        .args(&files);
    if config.exact {
        command.arg("--exact");
    }
    progress.stage(&format!("timing Storm on {} cases", files.len()), 0);
    let started = Instant::now();
    let output = command.output().map_err(|source| BenchError::StormStart {
        python: python.to_path_buf(),
        source,
    })?;
    let wall = started.elapsed().as_secs_f64();
    if !output.status.success() {
        return Err(BenchError::StormFailed {
            python: python.to_path_buf(),
            status: output.status.to_string(),
            stderr: String::from_utf8_lossy(&output.stderr).into_owned(),
        });
    }
    let value = serde_json::from_slice(&output.stdout).map_err(BenchError::StormOutput)?;
    Ok((value, wall))
}

/// One timing of Storm's: a path through Storm with one engine, over all cases.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StormTiming {
    /// `prism_ltl` (PRISM + co-safe LTL, `Pmax` at the initial state) or `drn` (chronomap's
    /// products from DRN, `Pmax` and `Rmin` in every state).
    pub path: String,
    /// `default` (sound, 1e-6), `sound12` (sound, 1e-12) or `exact` (rationals).
    pub engine: String,
    /// Median seconds of a sweep over all cases.
    pub seconds: f64,
    /// `seconds` over chronomap's sweep.
    pub ratio_to_chronomap: f64,
    /// Largest `|Pmax − chronomap's|` at the initial states (None if the script gave none).
    pub max_abs_delta_pmax: Option<f64>,
}

/// What Storm measured on the same cases.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StormBench {
    /// stormpy's version.
    pub stormpy: Option<String>,
    /// Timed sweeps per timing (after a warm-up).
    pub repeat: Option<u64>,
    /// One per path and engine, in the script's order.
    pub timings: Vec<StormTiming>,
    /// Seconds of `import stormpy` (not in the timings).
    pub import_seconds: Option<f64>,
    /// Wall-clock seconds of the whole Python process.
    pub process_seconds: f64,
    /// The process's seconds outside the script: the interpreter's start-up.
    pub interpreter_startup_seconds: Option<f64>,
}

/// The planning benchmark's measurements.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlanBench {
    /// Nodes of the map (text report only).
    #[serde(skip)]
    pub nodes: usize,
    /// Edges of the map (text report only).
    #[serde(skip)]
    pub edges: usize,
    /// Navigation attempts the edge models were fitted on (text report only).
    #[serde(skip)]
    pub attempts: usize,
    /// Cases of a sweep: [`TASKS`] × 24 hours.
    pub cases: usize,
    /// Product states of all cases.
    pub product_states: usize,
    /// Seconds of fitting the edge models (not part of the sweeps).
    pub fit_seconds: f64,
    /// Median seconds of a sweep over all cases, end to end.
    pub chronomap_seconds: f64,
    /// Seconds of every timed sweep.
    pub chronomap_sweeps: Vec<f64>,
    /// Storm's timings, when it was run.
    pub storm: Option<StormBench>,
    /// Storm (PRISM + LTL, default engine) over chronomap.
    pub ratio_storm_to_chronomap: Option<f64>,
}

impl PlanBench {
    /// The measurements as `chronomap bench plan` prints them.
    pub fn text(&self) -> String {
        let mut out = String::new();
        let ours = self.chronomap_seconds;
        let _ = writeln!(
            out,
            "Witham: {} nodes, {} edges, {} attempts; edge models fitted in {:.2} s (not timed below)",
            self.nodes, self.edges, self.attempts, self.fit_seconds
        );
        let _ = writeln!(
            out,
            "{} cases: every hour of 2014-09-04 (UTC) x {} tasks from Station ({}); {} product states in all",
            self.cases,
            TASKS.len(),
            TASKS
                .iter()
                .map(|(_, t)| t.to_string())
                .collect::<Vec<_>>()
                .join("; "),
            self.product_states
        );
        let _ = writeln!(
            out,
            "chronomap end to end (task automaton, predictions of {} edges, Navigation MDP, product, Pmax + expected time + policy in every state):\n  {:8.2} ms per sweep of {} cases (median of {}), {:.0} µs per case",
            self.edges,
            ours * 1e3,
            self.cases,
            self.chronomap_sweeps.len(),
            ours * 1e6 / self.cases as f64
        );
        let Some(storm) = &self.storm else {
            out.push_str(
                "Storm was not run (give --storm-python PATH, a Python that imports stormpy 2.0)\n",
            );
            return out;
        };
        let _ = writeln!(
            out,
            "Storm {} (stormpy), the same cases, median of {} sweeps after a warm-up:",
            storm.stormpy.as_deref().unwrap_or("?"),
            storm
                .repeat
                .map_or_else(|| "null".to_string(), |r| r.to_string())
        );
        for t in &storm.timings {
            let what = match t.path.as_str() {
                "prism_ltl" => "PRISM + co-safe LTL (Spot), Pmax at the initial state",
                _ => "chronomap's products from DRN, Pmax + Rmin in every state",
            };
            let engine_text = match t.engine.as_str() {
                "default" => "default engine (sound, 1e-6)",
                "sound12" => "sound, 1e-12",
                "exact" => "exact rationals",
                other => other,
            };
            let delta = t
                .max_abs_delta_pmax
                .map_or("?".into(), |d| format!("{d:.1e}"));
            let _ = writeln!(
                out,
                "  {what}, {engine_text}:\n  {:8.2} ms = {:6.1} x chronomap   (max |Pmax - ours| {delta})",
                t.seconds * 1e3,
                t.seconds / ours
            );
        }
        let _ = writeln!(
            out,
            "  not included: Python start-up {:.2} s, import stormpy {:.2} s (whole process {:.1} s)",
            storm.interpreter_startup_seconds.unwrap_or(f64::NAN),
            storm.import_seconds.unwrap_or(f64::NAN),
            storm.process_seconds
        );
        if let Some(ratio) = self.ratio_storm_to_chronomap {
            let _ = writeln!(
                out,
                "ratio Storm (PRISM + LTL, default engine) / chronomap: {ratio:.1}"
            );
        }
        out
    }
}

/// Runs the planning benchmark: fits the edge models, sweeps all cases once as a warm-up and
/// `repeat` times timed, then (with a Python) Storm on the same cases.
///
/// # Errors
/// The edge files cannot be read or fitted, a case cannot be planned or exported, or Storm
/// fails.
pub fn run(config: &PlanConfig, progress: &dyn Progress) -> Result<PlanBench, BenchError> {
    let stats =
        chronomap_io::read_edge_directory(&config.edges).map_err(|source| BenchError::Edges {
            dir: config.edges.clone(),
            source: Box::new(source),
        })?;
    let (nodes, edges, attempts) = (
        stats.map.nodes().len(),
        stats.map.edges().len(),
        stats.total_attempts(),
    );
    let started = Instant::now();
    let models = EdgeModels::fit(stats.map, &stats.attempts, EdgeModelConfig::default())
        .map_err(|(edge, source)| BenchError::Fit { edge, source })?;
    let fit_seconds = started.elapsed().as_secs_f64();

    let cases = sweep(&models)?; // warm-up, and the cases exported for Storm
    let mut sweeps = Vec::with_capacity(config.repeat.max(1));
    for _ in 0..config.repeat.max(1) {
        let started = Instant::now();
        let again = sweep(&models)?;
        sweeps.push(started.elapsed().as_secs_f64());
        std::hint::black_box(again);
    }
    let ours = median(&sweeps);
    let product_states: usize = cases.iter().map(|(_, p)| p.solution.state_count).sum();

    let storm = match &config.storm_python {
        Some(python) => Some(run_storm(python, config, &models, &cases, progress)?),
        None => None,
    };
    let storm = storm.map(|(value, wall)| {
        // Storm's Pmax at the initial state of every case against ours.
        let max_delta = |key: &str| -> Option<f64> {
            let values = value["pmax"][key].as_object()?;
            cases
                .iter()
                .map(|(name, p)| {
                    values
                        .get(name)
                        .and_then(Value::as_f64)
                        .map(|s| (s - p.solution.pmax_initial).abs())
                })
                .try_fold(0.0, |m: f64, d| d.map(|d| m.max(d)))
        };
        let timings = value["timings"]
            .as_array()
            .map(|list| {
                list.iter()
                    .filter_map(|t| {
                        let (path, engine) = (t["path"].as_str()?, t["engine"].as_str()?);
                        let seconds = t["seconds"].as_f64()?;
                        Some(StormTiming {
                            path: path.to_string(),
                            engine: engine.to_string(),
                            seconds,
                            ratio_to_chronomap: seconds / ours,
                            max_abs_delta_pmax: max_delta(&format!("{path}/{engine}")),
                        })
                    })
                    .collect()
            })
            .unwrap_or_default();
        StormBench {
            stormpy: value["stormpy"].as_str().map(str::to_string),
            repeat: value["repeat"].as_u64(),
            timings,
            import_seconds: value["import_seconds"].as_f64(),
            process_seconds: wall,
            interpreter_startup_seconds: value["script_seconds"].as_f64().map(|s| wall - s),
        }
    });
    let headline = storm.as_ref().and_then(|s| {
        s.timings
            .iter()
            .find(|t| t.path == "prism_ltl" && t.engine == "default")
            .map(|t| t.seconds)
    });
    Ok(PlanBench {
        nodes,
        edges,
        attempts,
        cases: cases.len(),
        product_states,
        fit_seconds,
        chronomap_seconds: ours,
        chronomap_sweeps: sweeps,
        storm,
        ratio_storm_to_chronomap: headline.map(|s| s / ours),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_report_without_storm_says_how_to_run_it() {
        let bench = PlanBench {
            nodes: 3,
            edges: 4,
            attempts: 50,
            cases: 72,
            product_states: 900,
            fit_seconds: 0.25,
            chronomap_seconds: 0.0144,
            chronomap_sweeps: vec![0.0144, 0.0150],
            storm: None,
            ratio_storm_to_chronomap: None,
        };
        let text = bench.text();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "Witham: 3 nodes, 4 edges, 50 attempts; edge models fitted in 0.25 s (not timed below)"
        );
        // 14.4 ms over 72 cases: 200 µs a case.
        assert_eq!(
            lines[3],
            "     14.40 ms per sweep of 72 cases (median of 2), 200 µs per case"
        );
        assert_eq!(
            lines[4],
            "Storm was not run (give --storm-python PATH, a Python that imports stormpy 2.0)"
        );
        assert_eq!(lines.len(), 5);
    }
}
