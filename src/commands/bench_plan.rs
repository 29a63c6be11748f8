//! `chronomap bench plan`: planning on the Witham map end to end ([Fentanes 2015] §V), against Storm
//! on the same 72 cases (24 hours × 3 tasks) in the same run — [`chronomap_bench::plan`]
//! measures, this prints.

use anyhow::Result;
use chronomap_bench::plan::{PlanBench, PlanConfig, TASKS};
use chronomap_core::progress::Progress;

use crate::cli::BenchPlanArgs;
use crate::outln;
use crate::output::print_bench;

/// The stages of a benchmark, one line each on stderr (`name...`), shown whatever stderr is:
/// a benchmark's log says what ran when.
pub(super) struct StageLog;

impl Progress for StageLog {
    fn stage(&self, name: &str, _total: u64) {
        crate::errln!("{name}...");
    }
}

pub fn plan(args: &BenchPlanArgs) -> Result<()> {
    let bench = chronomap_bench::plan::run(
        &PlanConfig {
            edges: args.edges.clone(),
            storm_python: args.storm_python.clone(),
            repeat: args.repeat,
            exact: args.exact,
        },
        &StageLog,
    )?;
    print_bench(args.json, &bench, print)
}

fn print(b: &PlanBench) -> Result<()> {
    let ours = b.chronomap_seconds;
    outln!(
        "Witham: {} nodes, {} edges, {} attempts; edge models fitted in {:.2} s (not timed below)",
        b.nodes,
        b.edges,
        b.attempts,
        b.fit_seconds
    )?;
    outln!(
        "{} cases: every hour of 2014-09-04 (UTC) x {} tasks from Station ({}); {} product states in all",
        b.cases,
        TASKS.len(),
        TASKS
            .iter()
            .map(|(_, t)| t.to_string())
            .collect::<Vec<_>>()
            .join("; "),
        b.product_states
    )?;
    outln!(
        "chronomap end to end (task automaton, predictions of {} edges, Navigation MDP, product, Pmax + expected time + policy in every state):\n  {:8.2} ms per sweep of {} cases (median of {}), {:.0} µs per case",
        b.edges,
        ours * 1e3,
        b.cases,
        b.chronomap_sweeps.len(),
        ours * 1e6 / b.cases as f64
    )?;
    let Some(storm) = &b.storm else {
        outln!("Storm was not run (give --storm-python PATH, a Python that imports stormpy 2.0)")?;
        return Ok(());
    };
    outln!(
        "Storm {} (stormpy), the same cases, median of {} sweeps after a warm-up:",
        storm.stormpy.as_deref().unwrap_or("?"),
        storm
            .repeat
            .map_or_else(|| "null".to_string(), |r| r.to_string())
    )?;
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
        outln!(
            "  {what}, {engine_text}:\n  {:8.2} ms = {:6.1} x chronomap   (max |Pmax - ours| {delta})",
            t.seconds * 1e3,
            t.seconds / ours
        )?;
    }
    outln!(
        "  not included: Python start-up {:.2} s, import stormpy {:.2} s (whole process {:.1} s)",
        storm.interpreter_startup_seconds.unwrap_or(f64::NAN),
        storm.import_seconds.unwrap_or(f64::NAN),
        storm.process_seconds
    )?;
    if let Some(ratio) = b.ratio_storm_to_chronomap {
        outln!("ratio Storm (PRISM + LTL, default engine) / chronomap: {ratio:.1}")?;
    }
    Ok(())
}
