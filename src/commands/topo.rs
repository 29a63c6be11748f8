//! `chronomap topo fit|eval|split|predict` and `chronomap plan`: topological maps whose edges
//! know time, and the now-or-later planner ([Fentanes 2015]). The summaries, merges, protocols,
//! routes and tables are computed by `chronomap_topo::report`; this file reads, prints and
//! writes.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use chronomap_app::topo::{self, TimedPlan, TimedWeek, fit_edge_models, plan_at, plan_week};
use chronomap_core::progress::NoProgress;
use chronomap_io::{
    read_edge_directory, read_edge_models, write_edge_directory, write_edge_models,
    write_route_geojson, write_tmap2,
};
use chronomap_plot::{Heatmap, render_heatmap_png};
use chronomap_topo::edges::{EdgeEvaluation, EdgeModels};
use chronomap_topo::map::TopoMap;
use chronomap_topo::mdp::{SolverOptions, prism_property, product_drn};
use chronomap_topo::plan::{PlanAt, Task};
use chronomap_topo::report::{Protocol, WeekTable, fit_summary, letters};
use serde_json::{Value, json};

use crate::cli::{
    PlanArgs, ProtocolArg, TopoEvalArgs, TopoFitArgs, TopoPredictArgs, TopoSplitArgs,
};
use crate::format::{Table, time};
use crate::output::{ProgressBar, print_json, usage};
use crate::{out, outln};

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
    let stats = read_edge_directory(&args.edges)?;
    let started = Instant::now();
    let models = fit_edge_models(
        stats.map.clone(),
        &stats.attempts,
        args.model.config(),
        &args.edges,
    )?;
    let seconds = started.elapsed().as_secs_f64();
    write_edge_models(&args.output, &models)?;
    let summary = fit_summary(&models, &stats.attempts);
    let span = stats.time_span();
    if args.json {
        return print_json(&json!({
            "nodes": stats.map.nodes().len(),
            "edges": stats.map.edges().len(),
            "attempts": stats.total_attempts(),
            "first": span.map(|s| s.0),
            "last": span.map(|s| s.1),
            "success_orders": summary.success_orders,
            "duration_orders": summary.duration_orders,
            "success_weights": summary.success_weights,
            "success_reconstruction_error": summary.success_error,
            "duration_reconstruction_error_secs": summary.duration_error_secs,
            "fit_seconds": seconds,
            "model": args.output.display().to_string(),
        }));
    }
    outln!(
        "{}: {} nodes, {} edges, {} attempts{}",
        args.edges.display(),
        stats.map.nodes().len(),
        stats.map.edges().len(),
        stats.total_attempts(),
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
        std::iter::once(name.to_string())
            .chain(std::iter::once(error))
            .chain(orders.iter().map(usize::to_string))
            .collect::<Vec<_>>()
    };
    table.row(row(
        "success",
        format!("{:.3}", summary.success_error),
        &summary.success_orders,
    ));
    table.row(row(
        "time",
        format!("{:.2} s", summary.duration_error_secs),
        &summary.duration_orders,
    ));
    outln!("{}", table.render())?;
    if !summary.success_weights.is_empty() {
        let weights: Vec<String> = summary
            .success_weights
            .iter()
            .map(|(spec, w)| format!("{spec} {w:.3}"))
            .collect();
        outln!(
            "success models: every edge weighs {} (shared weights, rolling-origin cross-validation; \
             counted above by their largest order)",
            weights.join(", ")
        )?;
    }
    outln!(
        "([Fentanes 2015] Table II, open-plan site: success 0.14 with orders 35/18/4/5; time 1.88 s with 24/19/10/9)"
    )?;
    outln!("fitted in {seconds:.2} s; wrote {}", args.output.display())?;
    Ok(())
}

fn score_json(score: &EdgeEvaluation) -> Value {
    json!({
        "success_brier": score.success_brier,
        "static_success_brier": score.static_success_brier,
        "duration_mse": score.duration_mse,
        "static_duration_mse": score.static_duration_mse,
    })
}

/// Success Brier score and duration MSE of each labelled evaluation against the static per-edge
/// rates ([Fentanes 2015] §V-A); `static_mse` heads the static duration column.
pub(super) fn score_table<'a>(
    static_mse: &str,
    scores: impl IntoIterator<Item = (String, &'a EdgeEvaluation)>,
) -> Table {
    let mut table = Table::new([
        "protocol",
        "success Brier",
        "static Brier",
        "ratio",
        "duration MSE (s²)",
        static_mse,
    ]);
    for (label, s) in scores {
        table.row([
            label,
            format!("{:.4}", s.success_brier),
            format!("{:.4}", s.static_success_brier),
            format!("{:.2}", s.success_brier / s.static_success_brier),
            format!("{:.2}", s.duration_mse),
            format!("{:.2}", s.static_duration_mse),
        ]);
    }
    table
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
    let protocol = Protocol::from(args.protocol);
    // A bar only for the edges scored one by one.
    let bar = args.per_edge.then(ProgressBar::new);
    let evaluation = topo::evaluate(
        &args.train,
        &args.test,
        args.model.config(),
        args.per_edge.then_some(protocol),
        match &bar {
            Some(bar) => bar,
            None => &NoProgress,
        },
    )?;
    let topo::Evaluation {
        models,
        train_attempts: train_total,
        online,
        frozen,
        per_edge,
    } = &evaluation;
    let chosen = evaluation.by(protocol);
    let edge_id = |e: usize| models.map().edges()[e].id.clone();
    if args.json {
        let mut report = json!({
            "success_brier": chosen.success_brier,
            "duration_mse": chosen.duration_mse,
            "static_success_brier": chosen.static_success_brier,
            "static_duration_mse": chosen.static_duration_mse,
            "attempts": chosen.attempts,
            "successes": chosen.successes,
            "protocol": protocol.name(),
            "train_attempts": train_total,
            "edges": models.map().edges().len(),
            "online": score_json(online),
            "frozen": score_json(frozen),
        });
        if args.per_edge {
            report["per_edge"] = per_edge
                .iter()
                .map(|s| {
                    json!({
                        "edge": edge_id(s.edge),
                        "train_attempts": s.train_attempts,
                        "test_attempts": s.score.attempts,
                        "success_brier": s.score.success_brier,
                        "static_success_brier": s.score.static_success_brier,
                    })
                })
                .collect();
        }
        return print_json(&report);
    }
    outln!(
        "trained on {} attempts ({}), tested on {} attempts ({}) of {} edges",
        train_total,
        args.train.display(),
        chosen.attempts,
        args.test.display(),
        models.map().edges().len()
    )?;
    let label = |p: Protocol| {
        if p == protocol {
            format!("{} *", p.name())
        } else {
            p.name().to_string()
        }
    };
    let table = score_table(
        "static MSE (s²)",
        [
            (label(Protocol::Online), online),
            (label(Protocol::Frozen), frozen),
        ],
    );
    outln!("{}", table.render())?;
    outln!(
        "(* the protocol asked for; ratio < 1: the per-edge models beat the static per-edge rates; durations of the {} successful attempts, models as fitted)",
        chosen.successes
    )?;
    if args.per_edge {
        let mut table = Table::new(["edge", "train", "test", "Brier", "static"]);
        for s in per_edge {
            table.row([
                edge_id(s.edge),
                s.train_attempts.to_string(),
                s.score.attempts.to_string(),
                format!("{:.4}", s.score.success_brier),
                format!("{:.4}", s.score.static_success_brier),
            ]);
        }
        outln!("\n{}", table.render())?;
    }
    Ok(())
}

pub fn split(args: &TopoSplitArgs) -> Result<()> {
    distinct_directories(["--before", "--after"], [&args.before, &args.after], "")?;
    let stats = read_edge_directory(&args.edges)?;
    let (before, after) = stats.split_at(args.at);
    if before.total_attempts() == 0 || after.total_attempts() == 0 {
        bail!(
            "splitting at {} leaves {} attempts before and {} after; choose a time inside the data{}",
            time(args.at),
            before.total_attempts(),
            after.total_attempts(),
            stats
                .time_span()
                .map(|(a, b)| format!(" ({} .. {})", time(a), time(b)))
                .unwrap_or_default()
        );
    }
    let a = write_edge_directory(&args.before, &before)?;
    let b = write_edge_directory(&args.after, &after)?;
    if args.json {
        let part = |dir: &Path, attempts: usize, files: usize| json!({"directory": dir.display().to_string(), "attempts": attempts, "edge_files": files});
        return print_json(&json!({
            "at": args.at,
            "utc": time(args.at),
            "before": part(&args.before, before.total_attempts(), a),
            "after": part(&args.after, after.total_attempts(), b),
        }));
    }
    outln!(
        "before {}: {} attempts in {a} edge files -> {}",
        time(args.at),
        before.total_attempts(),
        args.before.display()
    )?;
    outln!(
        "from {}: {} attempts in {b} edge files -> {}",
        time(args.at),
        after.total_attempts(),
        args.after.display()
    )?;
    Ok(())
}

pub fn predict(args: &TopoPredictArgs) -> Result<()> {
    let models = load(&args.model)?;
    let (success, duration) = models.at(args.time);
    if let Some(path) = &args.geojson {
        let metadata: Vec<(f64, f64)> = success
            .iter()
            .copied()
            .zip(duration.iter().copied())
            .collect();
        write_route_geojson(path, models.map(), &metadata)?;
        crate::errln!("wrote {}", path.display());
    }
    if let Some(path) = &args.tmap2 {
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("chronomap");
        write_tmap2(path, models.map(), name)?;
        crate::errln!("wrote {}", path.display());
    }
    let map = models.map();
    if args.json {
        let edges: Vec<Value> = map
            .edges()
            .iter()
            .enumerate()
            .map(|(e, edge)| {
                json!({
                    "edge": edge.id,
                    "from": map.nodes()[edge.from].name,
                    "to": map.nodes()[edge.to].name,
                    "success_probability": success[e],
                    "uncertainty": models.success_uncertainty(e, args.time),
                    "static_success_probability": models.static_success_probability(e),
                    "duration_secs": duration[e],
                    "attempts": models.edge(e).attempts,
                })
            })
            .collect();
        return print_json(&json!({"time": args.time, "edges": edges}));
    }
    outln!("{} edges at {}", map.edges().len(), time(args.time))?;
    let mut table = Table::new([
        "edge",
        "p(success)",
        "± sd",
        "static p",
        "duration",
        "attempts",
    ]);
    for (e, edge) in map.edges().iter().enumerate() {
        table.row([
            edge.id.clone(),
            format!("{:.3}", success[e]),
            format!("{:.3}", models.success_uncertainty(e, args.time)),
            format!("{:.3}", models.static_success_probability(e)),
            format!("{:.1} s", duration[e]),
            models.edge(e).attempts.to_string(),
        ]);
    }
    outln!("{}", table.render())?;
    Ok(())
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

/// A now-or-later table ([`WeekTable`], [Fentanes 2015] Table III) with the names it is printed
/// with, as `plan --day-table` and the demo show it.
pub(super) struct DayTable<'a> {
    map: &'a TopoMap,
    task: String,
    from: String,
    table: WeekTable,
    /// Seconds spent planning.
    pub(super) seconds: f64,
}

impl<'a> DayTable<'a> {
    /// Plans `task` from `from` at every start time (`step_mins` apart, `days` days from
    /// midnight UTC of `first_day`).
    pub(super) fn compute(
        models: &'a EdgeModels,
        from: &str,
        task: &str,
        first_day: f64,
        days: usize,
        step_mins: usize,
    ) -> Result<Self> {
        let map = models.map();
        let start = map.node(from).with_context(|| format!("--from {from}"))?;
        let parsed = Task::parse(task, map).context("--task")?;
        let TimedWeek { table, seconds } =
            plan_week(models, start, &parsed, first_day, days, step_mins)?;
        Ok(DayTable {
            map,
            task: task.to_string(),
            from: from.to_string(),
            table,
            seconds,
        })
    }

    fn at(&self, day: usize, k: usize) -> &PlanAt {
        self.table.at(day, k)
    }

    fn row_label(&self, k: usize) -> String {
        let minutes = self.table.minutes(k);
        format!("{:02}:{:02}", minutes / 60, minutes % 60)
    }

    fn day_label(&self, d: usize) -> String {
        day_label(self.table.day(d))
    }

    fn legend(&self) -> Vec<String> {
        self.table
            .first_edges
            .iter()
            .enumerate()
            .map(|(i, &e)| format!("{} = {}", letters(i), self.map.edges()[e].id))
            .chain(std::iter::once(
                "- = nothing to do (the task holds, or cannot be fulfilled)".to_string(),
            ))
            .collect()
    }

    /// The table as text: `Pmax code` per start time (rows) and day (columns), then the legend.
    pub(super) fn render(&self) -> String {
        let mut header = vec!["start (UTC)".to_string()];
        header.extend((0..self.table.days).map(|d| self.day_label(d)));
        let mut grid = Table::new(header);
        for k in 0..self.table.per_day {
            let mut row = vec![self.row_label(k)];
            for d in 0..self.table.days {
                let p = self.at(d, k);
                row.push(format!("{:.2} {}", p.pmax, self.table.code(p)));
            }
            grid.row(row);
        }
        let mut text = grid.render();
        for line in self.legend() {
            text.push_str(&format!("\n  {line}"));
        }
        text
    }

    /// The plans as JSON.
    fn json(&self) -> Value {
        let rows: Vec<Value> = self
            .table
            .plans
            .iter()
            .map(|p| {
                json!({
                    "time": p.time,
                    "utc": time(p.time),
                    "pmax": p.pmax,
                    "expected_secs": p.expected_secs,
                    "first_edge": p.first_edge.map(|e| self.map.edges()[e].id.clone()),
                })
            })
            .collect();
        json!({"task": self.task, "from": self.from, "plans": rows, "seconds": self.seconds})
    }

    /// Writes the table as a PNG heat map.
    pub(super) fn plot(&self, path: &Path) -> Result<()> {
        let (days, per_day) = (self.table.days, self.table.per_day);
        let heatmap = Heatmap {
            title: format!(
                "Now or later? P(success) of {:?} from {}",
                self.task, self.from
            ),
            row_label: "start (UTC)".to_string(),
            column_label: "day".to_string(),
            rows: (0..per_day).map(|k| self.row_label(k)).collect(),
            columns: (0..days).map(|d| self.day_label(d)).collect(),
            // Row-major, one row per start time.
            values: (0..per_day)
                .flat_map(|k| (0..days).map(move |d| (d, k)))
                .map(|(d, k)| self.at(d, k).pmax.clamp(0.0, 1.0))
                .collect(),
            cell_text: (0..per_day)
                .flat_map(|k| (0..days).map(move |d| (d, k)))
                .map(|(d, k)| self.table.code(self.at(d, k)))
                .collect(),
            value_label: "Pmax".to_string(),
            legend: self.legend(),
        };
        render_heatmap_png(&heatmap, path)?;
        Ok(())
    }
}

pub fn plan(args: &PlanArgs) -> Result<()> {
    let models = load(&args.model)?;
    let map = models.map();
    if let Some(t) = args.when.time {
        let start = map
            .node(&args.from)
            .with_context(|| format!("--from {}", args.from))?;
        let task = Task::parse(&args.task, map).context("--task")?;
        return plan_once(args, &models, start, &task, t, &SolverOptions::default());
    }
    let first_day = match args
        .week_of
        .or_else(|| models.last_time().map(|t| t + 86_400.0))
    {
        Some(t) => t,
        None => bail!("the model has seen no attempt; give --week-of"),
    };
    let table = DayTable::compute(
        &models,
        &args.from,
        &args.task,
        first_day,
        args.days as usize,
        args.step_mins as usize,
    )?;
    if let Some(path) = &args.plot {
        table.plot(path)?;
    }
    if args.json {
        return print_json(&table.json());
    }
    outln!(
        "task {:?} from {}: maximum probability of success and first action, {} start times in {:.2} s",
        args.task,
        args.from,
        table.table.plans.len(),
        table.seconds
    )?;
    outln!("{}", table.render())?;
    Ok(())
}

fn plan_once(
    args: &PlanArgs,
    models: &EdgeModels,
    start: usize,
    task: &Task,
    t: f64,
    options: &SolverOptions,
) -> Result<()> {
    let TimedPlan {
        planned,
        route,
        seconds,
    } = plan_at(models, start, task, t, options)?;
    let map = models.map();
    if let Some(path) = &args.prism {
        let model = planned.mdp.to_prism(start)?;
        chronomap_io::output::write_output(path, model.as_bytes())?;
        let props = path.with_extension("props");
        chronomap_io::output::write_output(
            &props,
            format!("{}\n", prism_property(task.text())?).as_bytes(),
        )?;
        crate::errln!("wrote {} and {}", path.display(), props.display());
    }
    if let Some(path) = &args.drn {
        let text = product_drn(planned.product.mdp(), &planned.solution)?;
        chronomap_io::output::write_output(path, text.as_bytes())?;
        crate::errln!("wrote {}", path.display());
    }
    let plan = &planned.plan;
    let product_states = planned.product.states().len();
    if args.json {
        return print_json(&json!({
            "task": args.task,
            "from": args.from,
            "time": t,
            "utc": time(t),
            "pmax": plan.pmax,
            "expected_secs": plan.expected_secs,
            "first_edge": plan.first_edge.map(|e| map.edges()[e].id.clone()),
            "route": route.iter().map(|&e| map.edges()[e].id.clone()).collect::<Vec<_>>(),
            "route_success_probabilities": route.iter().map(|&e| models.success_probability(e, t)).collect::<Vec<_>>(),
            "product_states": product_states,
            "seconds": seconds,
        }));
    }
    outln!("task {:?} from {} at {}", args.task, args.from, time(t))?;
    outln!(
        "maximum probability of success: {:.4}; expected time: {:.1} s (until done or failed)",
        plan.pmax,
        plan.expected_secs
    )?;
    match plan.first_edge {
        Some(e) => outln!("first action: {}", map.edges()[e].id)?,
        None if plan.pmax >= 1.0 => outln!("the task holds already")?,
        None => outln!("the task cannot be fulfilled from here")?,
    }
    if !route.is_empty() {
        out!("route if every edge succeeds: ")?;
        let names: Vec<String> = route
            .iter()
            .map(|&e| {
                format!(
                    "{} ({:.2})",
                    map.edges()[e].id,
                    models.success_probability(e, t)
                )
            })
            .collect();
        outln!("{}", names.join(" -> "))?;
    }
    outln!(
        "({} product states, solved in {:.1} ms)",
        product_states,
        seconds * 1e3
    )?;
    Ok(())
}
