//! `chronomap topo fit|eval|split|predict` and `chronomap plan`: topological maps whose edges
//! know time, and the now-or-later planner ([Fentanes 2015]). The jobs and their reports are
//! `chronomap_app::topo`; this file translates flags, prints and writes.

use std::path::Path;

use anyhow::{Context, Result};
use chronomap_app::topo::{self, DayTable, TimedPlan, deadline_report, plan_at, plan_report};
use chronomap_core::progress::NoProgress;
use chronomap_io::output::write_output;
use chronomap_io::{read_edge_models, write_route_geojson, write_tmap2};
use chronomap_plot::{render_heatmap_png, render_panels_png};
use chronomap_topo::edges::EdgeModels;
use chronomap_topo::mdp::SolverOptions;
use chronomap_topo::plan::Task;
use chronomap_topo::report::Protocol;

use crate::cli::{
    PlanArgs, ProtocolArg, TopoEvalArgs, TopoFitArgs, TopoObserveArgs, TopoPredictArgs,
    TopoSplitArgs,
};
use crate::output::{ProgressBar, print_json, usage};
use crate::{errln, out};

impl From<ProtocolArg> for Protocol {
    fn from(p: ProtocolArg) -> Protocol {
        match p {
            ProtocolArg::Online => Protocol::Online,
            ProtocolArg::Frozen => Protocol::Frozen,
        }
    }
}

fn load(path: &Path) -> Result<EdgeModels> {
    read_edge_models(path).context("cannot load the edge models")
}

pub fn fit(args: &TopoFitArgs) -> Result<()> {
    let report = topo::fit_report(&args.edges, &args.output, args.model.config())?;
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    out!("{report}")?;
    Ok(())
}

pub fn observe(args: &TopoObserveArgs) -> Result<()> {
    let models = load(&args.model)?;
    let report = topo::observe_report(models, &args.edges, &args.output)?;
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    out!("{report}")?;
    Ok(())
}

/// A usage error (ending in `why`) when the two directories of `flags` are one.
fn distinct_directories(flags: [&str; 2], dirs: [&Path; 2], why: &str) -> Result<()> {
    if dirs[0] == dirs[1] {
        return Err(usage(format!(
            "{} and {} are the same directory ({}){why}",
            flags[0],
            flags[1],
            dirs[0].display()
        )));
    }
    Ok(())
}

pub fn eval(args: &TopoEvalArgs) -> Result<()> {
    distinct_directories(
        ["--train", "--test"],
        [&args.train, &args.test],
        ": score on later attempts",
    )?;
    // A bar only for the edges scored one by one.
    let bar = args.per_edge.then(ProgressBar::new);
    let report = topo::eval_report(
        &args.train,
        &args.test,
        args.model.config(),
        Protocol::from(args.protocol),
        args.per_edge,
        match &bar {
            Some(bar) => bar,
            None => &NoProgress,
        },
    )?;
    if let Some(path) = &args.plot {
        render_panels_png(&report.calibration_panels(), path, 1000, 1400)?;
    }
    if args.json {
        return print_json(&report.json());
    }
    out!("{report}")?;
    Ok(())
}

pub fn split(args: &TopoSplitArgs) -> Result<()> {
    distinct_directories(["--before", "--after"], [&args.before, &args.after], "")?;
    let report = topo::split(&args.edges, args.at, &args.before, &args.after)?;
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    out!("{}", report.text())?;
    Ok(())
}

pub fn predict(args: &TopoPredictArgs) -> Result<()> {
    let models = load(&args.model)?;
    let report = topo::predict(&models, args.time);
    if let Some(path) = &args.geojson {
        write_route_geojson(path, models.map(), &report.route_metadata())?;
        errln!("wrote {}", path.display());
    }
    if let Some(path) = &args.tmap2 {
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("chronomap");
        write_tmap2(path, models.map(), name)?;
        errln!("wrote {}", path.display());
    }
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    out!("{}", report.text())?;
    Ok(())
}

pub fn plan(args: &PlanArgs) -> Result<()> {
    if args.plot.is_some() && args.when.time.is_some() && args.deadline.is_none() {
        return Err(usage(
            "--plot draws the day table (--day-table) or the deadline curve (--deadline); \
             with --time alone there is nothing to draw",
        ));
    }
    let models = load(&args.model)?;
    let first_day = match args.when.time {
        Some(t) => t,
        None => args
            .week_of
            .or_else(|| models.last_time().map(|t| t + 86_400.0))
            .context("the model has seen no attempt; give --week-of")?,
    };
    let map = models.map();
    let start = map
        .node(&args.from)
        .with_context(|| format!("--from {}", args.from))?;
    let task = Task::parse(&args.task, map).context("--task")?;
    if let Some(t) = args.when.time {
        if let Some(deadline) = args.deadline {
            return plan_deadline(args, &models, start, &task, t, deadline);
        }
        return plan_once(args, &models, start, &task, t);
    }
    let mut table = DayTable::compute(
        &models,
        (start, &args.from),
        (&task, &args.task),
        first_day,
        args.days as usize,
        args.step_mins as usize,
    )?;
    if let Some(deadline) = args.deadline {
        table
            .add_deadline(
                &models,
                (start, &task),
                deadline,
                args.bucket_secs,
                &ProgressBar::new(),
            )
            .context("--deadline")?;
    }
    if let Some(path) = &args.plot {
        render_heatmap_png(&table.heatmap(), path)?;
    }
    if args.json {
        return print_json(&table.json());
    }
    out!("{}", table.text())?;
    Ok(())
}

/// The PRISM and DRN files of the plan at one time, if asked for.
fn write_exports(args: &PlanArgs, timed: &TimedPlan, start: usize, task: &Task) -> Result<()> {
    if let Some(path) = &args.prism {
        let (model, property) = timed.prism(start, task)?;
        write_output(path, model.as_bytes())?;
        let props = path.with_extension("props");
        write_output(&props, property.as_bytes())?;
        errln!("wrote {} and {}", path.display(), props.display());
    }
    if let Some(path) = &args.drn {
        write_output(path, timed.drn()?.as_bytes())?;
        errln!("wrote {}", path.display());
    }
    Ok(())
}

/// `chronomap plan --time`: the plan at one time, with the PRISM and DRN files asked for.
fn plan_once(
    args: &PlanArgs,
    models: &EdgeModels,
    start: usize,
    task: &Task,
    t: f64,
) -> Result<()> {
    let timed = plan_at(models, start, task, t, &SolverOptions::default())?;
    write_exports(args, &timed, start, task)?;
    let report = plan_report(models, &timed, &args.from, &args.task, t);
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    out!("{report}")?;
    Ok(())
}

/// `chronomap plan --time --deadline`: the plan most likely to fulfil the task in time.
fn plan_deadline(
    args: &PlanArgs,
    models: &EdgeModels,
    start: usize,
    task: &Task,
    t: f64,
    deadline: f64,
) -> Result<()> {
    // Exports and the deadline plan are independent: write the MDPs first.
    if args.prism.is_some() || args.drn.is_some() {
        let timed = plan_at(models, start, task, t, &SolverOptions::default())?;
        write_exports(args, &timed, start, task)?;
    }
    let report = deadline_report(
        models,
        (start, &args.from),
        (task, &args.task),
        t,
        deadline,
        args.bucket_secs,
        args.confidence.unwrap_or(0.95),
    )
    .context("--deadline")?;
    if let Some(path) = &args.plot {
        render_panels_png(&[report.panel()], path, 1000, 500)?;
        errln!("wrote {}", path.display());
    }
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    out!("{report}")?;
    Ok(())
}
