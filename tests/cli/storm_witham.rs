//! Storm cross-check on the real Witham MDP: the edge models fitted on all of the bundled
//! Witham data, the Navigation MDP at every hour 00:00..23:00 UTC of 2014-09-04, three tasks.
//! Every product state's `Pmax` and expected time must equal Storm's (stormpy 2.0, exact
//! arithmetic, `tests/oracle/storm_check.py`) to 1e-9, and so must the `Pmax` Storm computes
//! from the PRISM model and the co-safe LTL property through its own product (Spot).
//!
//! Storm runs when `CHRONOMAP_STORM_PYTHON` names a Python interpreter that imports stormpy
//! (`.ci/run` sets it up). Without it the test checks our own values only and says how to
//! enable the comparison, unless `CHRONOMAP_REQUIRE_STORM=1`, when it fails.

use std::collections::BTreeMap;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_topo::edges::{EdgeModelConfig, EdgeModels};
use chronomap_topo::mdp::{SolverOptions, prism_property};
use chronomap_topo::plan::{Task, plan_full};
use serde_json::Value;

use crate::common::{oracle_python, run_oracle, scratch};
use crate::storm_case::write_case;

/// 2014-09-04 00:00 UTC, the day after the last attempt in the data.
const DAY: f64 = 1_409_788_800.0;

/// (file name prefix, start node, task). All start in the lab, so every task crosses the
/// often-closed door LabDoor1 -> LabDoor2.
const TASKS: [(&str, &str, &str); 3] = [
    // Reachability.
    ("reach", "Station", "F Kitchen"),
    // An ordered visit: print, fetch something from the kitchen, come back (through the
    // door both ways).
    (
        "ordered",
        "Station",
        "F (Printer & F (Kitchen & F Station))",
    ),
    // Avoid the printer corridor until the kitchen: only the ramp route by WayPoint2 is left.
    ("avoid", "Station", "!Printer U Kitchen"),
];

/// Absolute tolerance of every comparison.
const TOLERANCE: f64 = 1e-9;

fn witham_models() -> EdgeModels {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/witham_topological_nav/edges");
    let stats = chronomap_io::read_edge_directory(dir).unwrap();
    assert_eq!(stats.total_attempts(), 25_316);
    EdgeModels::fit(stats.map, &stats.attempts, EdgeModelConfig::default())
        .unwrap_or_else(|(edge, e)| panic!("edge {edge}: {e}"))
}

/// Our values for one case.
struct Ours {
    pmax: Vec<f64>,
    cost: Vec<f64>,
    pmax_initial: f64,
    cost_initial: f64,
    property: String,
}

/// Plans every case, writes its files and `expected.json` into `dir`; returns our values by
/// case name (`reach_00`, ...) and the file names.
fn write_cases(models: &EdgeModels, dir: &Path) -> (BTreeMap<String, Ours>, Vec<PathBuf>) {
    let mut ours = BTreeMap::new();
    let mut expected = serde_json::Map::new();
    let mut files = Vec::new();
    for (prefix, start, text) in TASKS {
        let task = Task::parse(text, models.map()).unwrap();
        let start = models.map().node(start).unwrap();
        let property = prism_property(text).unwrap();
        for hour in 0..24 {
            let planned = plan_full(
                models,
                start,
                &task,
                DAY + 3600.0 * f64::from(hour),
                &SolverOptions::default(),
            )
            .unwrap();
            let (mdp, sol) = (planned.product.mdp(), &planned.solution);
            let name = format!("{prefix}_{hour:02}");
            files.extend(
                write_case(
                    dir,
                    &name,
                    (&planned.mdp, start),
                    mdp,
                    sol,
                    &property,
                    &mut expected,
                )
                .unwrap(),
            );
            ours.insert(
                name,
                Ours {
                    pmax: sol.pmax.clone(),
                    cost: sol.cost.clone(),
                    pmax_initial: sol.pmax_initial,
                    cost_initial: sol.cost_initial,
                    property: property.clone(),
                },
            );
        }
    }
    std::fs::write(
        dir.join("expected.json"),
        serde_json::to_string(&Value::Object(expected)).unwrap(),
    )
    .unwrap();
    (ours, files)
}

/// A JSON number of Storm's output; `null` is infinity.
fn storm_number(value: &Value) -> f64 {
    match value {
        Value::Null => f64::INFINITY,
        v => v.as_f64().unwrap_or_else(|| panic!("not a number: {v}")),
    }
}

/// |a - b|, zero if both are infinite.
fn difference(a: f64, b: f64) -> f64 {
    if a == f64::INFINITY && b == f64::INFINITY {
        0.0
    } else {
        (a - b).abs()
    }
}

/// Largest difference between our per-state values and Storm's list `key` of `result`.
fn max_difference(name: &str, result: &Value, key: &str, ours: &[f64]) -> f64 {
    let storm = result[key]
        .as_array()
        .unwrap_or_else(|| panic!("{name}: Storm gave no {key}: {result}"));
    assert_eq!(storm.len(), ours.len(), "{name}: {key}: state count");
    storm
        .iter()
        .zip(ours)
        .map(|(s, &o)| difference(storm_number(s), o))
        .fold(0.0, f64::max)
}

/// Per case: max |Δ Pmax| (product, restricted product, PRISM + LTL), max |Δ time|, and
/// Storm's PRISM + LTL value.
struct Agreement {
    pmax: f64,
    time: f64,
    ltl: f64,
}

fn compare(ours: &BTreeMap<String, Ours>, storm: &Value) -> BTreeMap<String, Agreement> {
    ours.iter()
        .map(|(name, o)| {
            let drn = &storm[format!("{name}.drn")];
            let restricted = &storm[format!("{name}.restricted.drn")];
            let prism = &storm[format!("{name}.nm")];
            let ltl = storm_number(&prism["properties"][&o.property]);
            let pmax = [
                max_difference(name, drn, "pmax", &o.pmax),
                max_difference(name, restricted, "pmax", &o.pmax),
                difference(storm_number(&drn["pmax_initial"]), o.pmax_initial),
                difference(ltl, o.pmax_initial),
            ]
            .into_iter()
            .fold(0.0, f64::max);
            let time = f64::max(
                max_difference(name, restricted, "rmin", &o.cost),
                difference(storm_number(&restricted["rmin_initial"]), o.cost_initial),
            );
            (name.clone(), Agreement { pmax, time, ltl })
        })
        .collect()
}

/// Runs `storm_check.py` on every file; returns its JSON output.
fn run_storm(python: &str, dir: &Path, files: &[PathBuf]) -> Value {
    let (expect, tol) = (dir.join("expected.json"), TOLERANCE.to_string());
    let mut args: Vec<&OsStr> = vec!["--expect".as_ref(), expect.as_ref(), "--tol".as_ref()];
    args.push(tol.as_ref());
    args.extend(files.iter().map(|f| f.as_os_str()));
    let label = format!("storm_check.py on {} files", files.len());
    run_oracle(
        python,
        "CHRONOMAP_STORM_PYTHON",
        "storm_check.py",
        &args,
        &label,
    )
}

#[test]
fn witham_pmax_and_expected_times_equal_storms_for_every_hour() {
    let started = Instant::now();
    let models = witham_models();
    let dir = scratch("storm_witham");
    let (ours, files) = write_cases(&models, &dir);
    println!(
        "chronomap: fitted and planned {} cases in {:.2} s",
        ours.len(),
        started.elapsed().as_secs_f64()
    );

    // Our own sanity: avoiding the printer never helps, and on this map it costs
    // probability at some hours (the constraint matters); the ordered visit is never more
    // likely than reaching the kitchen.
    let initial = |prefix: &str, hour: u32| ours[&format!("{prefix}_{hour:02}")].pmax_initial;
    let mut constrained_hours = 0;
    for hour in 0..24 {
        let (reach, ordered, avoid) = (
            initial("reach", hour),
            initial("ordered", hour),
            initial("avoid", hour),
        );
        assert!(avoid <= reach + TOLERANCE, "{hour}: {avoid} > {reach}");
        assert!(ordered <= reach + TOLERANCE, "{hour}: {ordered} > {reach}");
        assert!(reach > 0.0, "{hour}: the kitchen is reachable");
        if avoid < reach - 0.01 {
            constrained_hours += 1;
        }
    }
    assert!(
        constrained_hours >= 6,
        "avoiding the printer changes Pmax by > 0.01 at only {constrained_hours} hours"
    );

    let enable = "set CHRONOMAP_STORM_PYTHON to a Python with stormpy 2.0 \
                  (python3 -m venv storm-venv && storm-venv/bin/pip install stormpy==2.0.0), \
                  see tests/oracle/README.md";
    let Some(python) = oracle_python("STORM", "storm_witham", "Storm", enable) else {
        return;
    };
    let storm = run_storm(&python, &dir, &files);
    let agreement = compare(&ours, &storm);

    println!(
        "Witham, 2014-09-04 (UTC), from Station: Pmax, expected time (s), max |Δ| vs Storm over \
         all product states (Pmax incl. PRISM + LTL; time)"
    );
    println!(
        "| hour | {} |",
        TASKS
            .iter()
            .map(|(_, _, t)| format!("`{t}` Pmax | time (s) | max ΔPmax | max Δtime"))
            .collect::<Vec<_>>()
            .join(" | ")
    );
    println!("|---|{}", "---|---|---|---|".repeat(TASKS.len()));
    for hour in 0..24 {
        let cells: Vec<String> = TASKS
            .iter()
            .map(|(prefix, _, _)| {
                let name = format!("{prefix}_{hour:02}");
                let (o, a) = (&ours[&name], &agreement[&name]);
                format!(
                    "{:.6} | {:.2} | {:.1e} | {:.1e}",
                    o.pmax_initial, o.cost_initial, a.pmax, a.time
                )
            })
            .collect();
        println!("| {hour:02}:00 | {} |", cells.join(" | "));
    }
    let worst = |f: fn(&Agreement) -> f64| agreement.values().map(f).fold(0.0, f64::max);
    let (pmax, time) = (worst(|a| a.pmax), worst(|a| a.time));
    println!(
        "{} cases: max |ΔPmax| = {pmax:.2e}, max |Δtime| = {time:.2e} s; total {:.1} s",
        agreement.len(),
        started.elapsed().as_secs_f64()
    );
    for (name, a) in &agreement {
        assert!(
            a.pmax <= TOLERANCE && a.time <= TOLERANCE,
            "{name}: |ΔPmax| {:e}, |Δtime| {:e} (Storm PRISM + LTL Pmax {})",
            a.pmax,
            a.time,
            a.ltl
        );
    }
}
