//! `chronomap bench plan`: planning on the Witham map end to end (seed 003 §V), against Storm
//! on the same 72 cases (24 hours × 3 tasks) in the same run.
//!
//! chronomap's time per case: parse the task and build its automaton, predict every edge at
//! `t`, build the Navigation MDP and its product with the automaton, solve for `Pmax`, the
//! least expected time among the `Pmax`-optimal policies and the policy. Storm's
//! (`tests/oracle/storm_time.py`, embedded here and run with `--storm-python`): parse the
//! PRISM model of the same Navigation MDP and the task as co-safe LTL, build, check `Pmax`
//! (Storm's own product through Spot); and, apart, Storm solving chronomap's products from DRN.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result, anyhow, bail};
use chronomap_topo::edges::{EdgeModelConfig, EdgeModels};
use chronomap_topo::mdp::{SolverOptions, prism_property, product_drn, restricted_drn};
use chronomap_topo::plan::{Planned, Task, plan_full};
use serde_json::{Value, json};

use crate::cli::BenchPlanArgs;

/// 2014-09-04 00:00 UTC, the day after the last attempt of the Witham data.
const DAY: f64 = 1_409_788_800.0;

/// (start node, task): reachability, an ordered visit, an avoid-until; all cross the lab door
/// (the same cases as `tests/storm_witham.rs`).
const TASKS: [(&str, &str); 3] = [
    ("Station", "F Kitchen"),
    ("Station", "F (Printer & F (Kitchen & F Station))"),
    ("Station", "!Printer U Kitchen"),
];

/// The Storm timing script.
const STORM_TIME_PY: &str = include_str!("../../tests/oracle/storm_time.py");

/// One sweep: every task at every hour, from the task's text to the solution.
fn sweep(models: &EdgeModels) -> Result<Vec<(String, Planned)>> {
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

/// The median of `values` (the mean of the middle two for an even count).
pub(super) fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n.is_multiple_of(2) {
        (values[n / 2 - 1] + values[n / 2]) / 2.0
    } else {
        values[n / 2]
    }
}

/// A temporary directory, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> Result<Self> {
        let nanos = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        let dir = std::env::temp_dir().join(format!(
            "chronomap-bench-plan-{}-{nanos}",
            std::process::id()
        ));
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        Ok(TempDir(dir))
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Writes every case for Storm (PRISM + property, product and restricted DRN) and the script;
/// returns the `.nm` files.
fn write_cases(
    dir: &Path,
    models: &EdgeModels,
    cases: &[(String, Planned)],
) -> Result<Vec<PathBuf>> {
    let mut files = Vec::with_capacity(cases.len());
    for (i, (name, planned)) in cases.iter().enumerate() {
        let (start, text) = TASKS[i / 24];
        let start = models.map().node(start)?;
        let (mdp, sol) = (planned.product.mdp(), &planned.solution);
        let nm = dir.join(format!("{name}.nm"));
        std::fs::write(&nm, planned.mdp.to_prism(start)?)?;
        std::fs::write(
            dir.join(format!("{name}.props")),
            format!("{}\n", prism_property(text)?),
        )?;
        std::fs::write(dir.join(format!("{name}.drn")), product_drn(mdp, sol)?)?;
        std::fs::write(
            dir.join(format!("{name}.restricted.drn")),
            restricted_drn(mdp, sol)?,
        )?;
        files.push(nm);
    }
    std::fs::write(dir.join("storm_time.py"), STORM_TIME_PY)?;
    Ok(files)
}

/// Storm's timings: the script's JSON and the wall-clock time of the whole process.
fn run_storm(
    python: &Path,
    args: &BenchPlanArgs,
    models: &EdgeModels,
    cases: &[(String, Planned)],
) -> Result<(Value, f64)> {
    let dir = TempDir::new()?;
    let files = write_cases(&dir.0, models, cases)?;
    let mut command = Command::new(python);
    command
        .arg(dir.0.join("storm_time.py"))
        .arg("--repeat")
        .arg(args.repeat.max(1).to_string())
        .args(&files);
    if args.exact {
        command.arg("--exact");
    }
    eprintln!("timing Storm on {} cases...", files.len());
    let started = Instant::now();
    let output = command
        .output()
        .with_context(|| format!("cannot run {}", python.display()))?;
    let wall = started.elapsed().as_secs_f64();
    if !output.status.success() {
        bail!(
            "{} storm_time.py failed ({}):\n{}",
            python.display(),
            output.status,
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let value = serde_json::from_slice(&output.stdout).context("storm_time.py output")?;
    Ok((value, wall))
}

pub fn plan(args: &BenchPlanArgs) -> Result<()> {
    let stats = chronomap_io::read_edge_directory(&args.edges)
        .with_context(|| format!("cannot read the Witham edges in {}", args.edges.display()))?;
    let (nodes, edges, attempts) = (
        stats.map.nodes().len(),
        stats.map.edges().len(),
        stats.total_attempts(),
    );
    let started = Instant::now();
    let models = EdgeModels::fit(stats.map, &stats.attempts, EdgeModelConfig::default())
        .map_err(|(edge, e)| anyhow!("edge {edge}: {e}"))?;
    let fit_seconds = started.elapsed().as_secs_f64();

    let cases = sweep(&models)?; // warm-up, and the cases exported for Storm
    let mut sweeps = Vec::with_capacity(args.repeat.max(1));
    for _ in 0..args.repeat.max(1) {
        let started = Instant::now();
        let again = sweep(&models)?;
        sweeps.push(started.elapsed().as_secs_f64());
        std::hint::black_box(again);
    }
    let ours = median(sweeps.clone());
    let product_states: usize = cases.iter().map(|(_, p)| p.solution.state_count).sum();

    let storm = match &args.storm_python {
        Some(python) => Some(run_storm(python, args, &models, &cases)?),
        None => None,
    };
    // Storm's PRISM + LTL Pmax (default engine) against ours.
    let max_delta = |key: &str| -> Option<f64> {
        let (value, _) = storm.as_ref()?;
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
    let timings: Vec<(String, String, f64)> = storm
        .as_ref()
        .and_then(|(v, _)| v["timings"].as_array())
        .map(|list| {
            list.iter()
                .filter_map(|t| {
                    Some((
                        t["path"].as_str()?.to_string(),
                        t["engine"].as_str()?.to_string(),
                        t["seconds"].as_f64()?,
                    ))
                })
                .collect()
        })
        .unwrap_or_default();
    let headline = timings
        .iter()
        .find(|(path, engine, _)| path == "prism_ltl" && engine == "default")
        .map(|(_, _, s)| *s);

    if args.json {
        let storm_json = storm.as_ref().map(|(v, wall)| {
            json!({
                "stormpy": v["stormpy"],
                "repeat": v["repeat"],
                "timings": timings.iter().map(|(path, engine, s)| json!({
                    "path": path,
                    "engine": engine,
                    "seconds": s,
                    "ratio_to_chronomap": s / ours,
                    "max_abs_delta_pmax": max_delta(&format!("{path}/{engine}")),
                })).collect::<Vec<_>>(),
                "import_seconds": v["import_seconds"],
                "process_seconds": wall,
                "interpreter_startup_seconds": v["script_seconds"].as_f64().map(|s| wall - s),
            })
        });
        println!(
            "{}",
            json!({
                "cases": cases.len(),
                "product_states": product_states,
                "fit_seconds": fit_seconds,
                "chronomap_seconds": ours,
                "chronomap_sweeps": sweeps,
                "storm": storm_json,
                "ratio_storm_to_chronomap": headline.map(|s| s / ours),
            })
        );
        return Ok(());
    }

    println!(
        "Witham: {nodes} nodes, {edges} edges, {attempts} attempts; edge models fitted in {fit_seconds:.2} s (not timed below)"
    );
    println!(
        "{} cases: every hour of 2014-09-04 (UTC) x {} tasks from Station ({}); {product_states} product states in all",
        cases.len(),
        TASKS.len(),
        TASKS
            .iter()
            .map(|(_, t)| t.to_string())
            .collect::<Vec<_>>()
            .join("; ")
    );
    println!(
        "chronomap end to end (task automaton, predictions of {edges} edges, Navigation MDP, product, Pmax + expected time + policy in every state):\n  {:8.2} ms per sweep of {} cases (median of {}), {:.0} µs per case",
        ours * 1e3,
        cases.len(),
        sweeps.len(),
        ours * 1e6 / cases.len() as f64
    );
    let Some((value, wall)) = &storm else {
        println!("Storm was not run (give --storm-python PATH, a Python that imports stormpy 2.0)");
        return Ok(());
    };
    println!(
        "Storm {} (stormpy), the same cases, median of {} sweeps after a warm-up:",
        value["stormpy"].as_str().unwrap_or("?"),
        value["repeat"]
    );
    for (path, engine, seconds) in &timings {
        let what = match path.as_str() {
            "prism_ltl" => "PRISM + co-safe LTL (Spot), Pmax at the initial state",
            _ => "chronomap's products from DRN, Pmax + Rmin in every state",
        };
        let engine_text = match engine.as_str() {
            "default" => "default engine (sound, 1e-6)",
            "sound12" => "sound, 1e-12",
            "exact" => "exact rationals",
            other => other,
        };
        let delta =
            max_delta(&format!("{path}/{engine}")).map_or("?".into(), |d| format!("{d:.1e}"));
        println!(
            "  {what}, {engine_text}:\n  {:8.2} ms = {:6.1} x chronomap   (max |Pmax - ours| {delta})",
            seconds * 1e3,
            seconds / ours
        );
    }
    let import = value["import_seconds"].as_f64().unwrap_or(f64::NAN);
    let startup = value["script_seconds"]
        .as_f64()
        .map_or(f64::NAN, |s| wall - s);
    println!(
        "  not included: Python start-up {:.2} s, import stormpy {:.2} s (whole process {:.1} s)",
        startup, import, wall
    );
    if let Some(s) = headline {
        println!(
            "ratio Storm (PRISM + LTL, default engine) / chronomap: {:.1}",
            s / ours
        );
    }
    Ok(())
}
