//! `chronomap topo fit|eval|split|predict` and `chronomap plan`: topological maps whose edges
//! know time, and the now-or-later planner (seed 003).

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use chronomap_io::{
    EdgeStatistics, read_edge_directory, read_edge_models, write_edge_directory, write_edge_models,
    write_route_geojson, write_tmap2,
};
use chronomap_plot::{Heatmap, render_heatmap_png};
use chronomap_topo::edges::{Attempt, EdgeEvaluation, EdgeModelConfig, EdgeModels};
use chronomap_topo::map::TopoMap;
use chronomap_topo::mdp::{SolverOptions, prism_property, product_drn};
use chronomap_topo::plan::{PlanAt, Task, now_or_later, plan_full};
use serde_json::{Value, json};

use crate::cli::{
    PlanArgs, ProtocolArg, TopoEvalArgs, TopoFitArgs, TopoPredictArgs, TopoSplitArgs,
};
use crate::format::{Table, time};

/// Fits edge models, naming the edge file whose attempts are at fault.
fn fit_models(
    map: TopoMap,
    attempts: &[Vec<Attempt>],
    config: EdgeModelConfig,
    dir: &Path,
) -> Result<EdgeModels> {
    EdgeModels::fit(map, attempts, config).map_err(|(edge, error)| {
        let at = error
            .observation_index()
            .map(|i| format!(": attempt {}", i + 1))
            .unwrap_or_default();
        anyhow!(
            "{}{at}: {error}",
            dir.join(format!("{edge}.data")).display()
        )
    })
}

fn load(path: &Path) -> Result<EdgeModels> {
    read_edge_models(path).context("cannot load the edge models")
}

/// Per-edge order counts and mean reconstruction errors (seed 003 Table II).
struct Summary {
    success_orders: [usize; 6],
    duration_orders: [usize; 6],
    success_error: f64,
    duration_error_secs: f64,
}

/// Buckets: static rate (few attempts), orders 0, 1, 2, 3, ≥ 4.
fn bucket(order: Option<usize>) -> usize {
    order.map_or(0, |o| 1 + o.min(4))
}

fn summarise(models: &EdgeModels, attempts: &[Vec<Attempt>]) -> Summary {
    let mut s = Summary {
        success_orders: [0; 6],
        duration_orders: [0; 6],
        success_error: 0.0,
        duration_error_secs: 0.0,
    };
    let (mut success_edges, mut duration_edges) = (0usize, 0usize);
    for (e, list) in attempts.iter().enumerate() {
        let model = models.edge(e);
        s.success_orders[bucket(model.success_model().and_then(|m| m.order()))] += 1;
        s.duration_orders[bucket(model.duration_model().and_then(|m| m.order()))] += 1;
        if !list.is_empty() {
            // Seed 003 eq. (3) divided by n: the mean absolute reconstruction error.
            let error: f64 = list
                .iter()
                .map(|a| {
                    (f64::from(u8::from(a.success)) - models.success_probability(e, a.time)).abs()
                })
                .sum();
            s.success_error += error / list.len() as f64;
            success_edges += 1;
        }
        let good: Vec<&Attempt> = list.iter().filter(|a| a.success).collect();
        if !good.is_empty() {
            let error: f64 = good
                .iter()
                .map(|a| (a.duration_secs - models.expected_duration(e, a.time)).abs())
                .sum();
            s.duration_error_secs += error / good.len() as f64;
            duration_edges += 1;
        }
    }
    s.success_error /= success_edges.max(1) as f64;
    s.duration_error_secs /= duration_edges.max(1) as f64;
    s
}

pub fn fit(args: &TopoFitArgs) -> Result<()> {
    let mut out = std::io::stdout().lock();
    let stats = read_edge_directory(&args.edges)?;
    let started = Instant::now();
    let models = fit_models(
        stats.map.clone(),
        &stats.attempts,
        args.model.config(),
        &args.edges,
    )?;
    let seconds = started.elapsed().as_secs_f64();
    write_edge_models(&args.output, &models)?;
    let summary = summarise(&models, &stats.attempts);
    let span = stats.time_span();
    if args.json {
        writeln!(
            out,
            "{}",
            json!({
                "nodes": stats.map.nodes().len(),
                "edges": stats.map.edges().len(),
                "attempts": stats.total_attempts(),
                "first": span.map(|s| s.0),
                "last": span.map(|s| s.1),
                "success_orders": summary.success_orders,
                "duration_orders": summary.duration_orders,
                "success_reconstruction_error": summary.success_error,
                "duration_reconstruction_error_secs": summary.duration_error_secs,
                "fit_seconds": seconds,
                "model": args.output.display().to_string(),
            })
        )?;
        return Ok(());
    }
    writeln!(
        out,
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
    writeln!(out, "{}", table.render())?;
    writeln!(
        out,
        "(seed 003 Table II, open-plan site: success 0.14 with orders 35/18/4/5; time 1.88 s with 24/19/10/9)"
    )?;
    writeln!(
        out,
        "fitted in {seconds:.2} s; wrote {}",
        args.output.display()
    )?;
    Ok(())
}

/// Attempts per edge, in the edge order of a map.
type AttemptsPerEdge = Vec<Vec<Attempt>>;

/// The union of the edges of two directories: the training map, plus the nodes and edges only
/// the test directory has (they get no training attempts: their prior answers for them).
fn align(
    train: EdgeStatistics,
    test: &EdgeStatistics,
) -> Result<(TopoMap, AttemptsPerEdge, AttemptsPerEdge)> {
    let mut map = train.map;
    let mut train_attempts = train.attempts;
    for node in test.map.nodes() {
        if map.node(&node.name).is_err() {
            map.add_node(&node.name, node.pose)?;
        }
    }
    let mut test_attempts = vec![Vec::new(); map.edges().len()];
    for (edge, attempts) in test.map.edges().iter().zip(&test.attempts) {
        let from = &test.map.nodes()[edge.from].name;
        let to = &test.map.nodes()[edge.to].name;
        let index = match map.edges().iter().position(|e| e.id == edge.id) {
            Some(i) => {
                let known = &map.edges()[i];
                if map.nodes()[known.from].name != *from || map.nodes()[known.to].name != *to {
                    bail!(
                        "edge {} joins different nodes in the training and test directories",
                        edge.id
                    );
                }
                i
            }
            None => {
                let i = map.add_edge(&edge.id, from, to)?;
                train_attempts.push(Vec::new());
                test_attempts.push(Vec::new());
                i
            }
        };
        test_attempts[index] = attempts.clone();
    }
    Ok((map, train_attempts, test_attempts))
}

fn score_json(score: &EdgeEvaluation) -> Value {
    json!({
        "success_brier": score.success_brier,
        "static_success_brier": score.static_success_brier,
        "duration_mse": score.duration_mse,
        "static_duration_mse": score.static_duration_mse,
    })
}

fn evaluate(
    models: &EdgeModels,
    test: &[Vec<Attempt>],
    protocol: ProtocolArg,
) -> Result<EdgeEvaluation> {
    Ok(match protocol {
        ProtocolArg::Online => models.evaluate_online(test)?,
        ProtocolArg::Frozen => models.evaluate(test)?,
    })
}

pub fn eval(args: &TopoEvalArgs) -> Result<()> {
    let mut out = std::io::stdout().lock();
    let train = read_edge_directory(&args.train)?;
    let test = read_edge_directory(&args.test)?;
    if test.total_attempts() == 0 {
        bail!("{}: no test attempts", args.test.display());
    }
    let train_total = train.total_attempts();
    let (map, train_attempts, test_attempts) = align(train, &test)?;
    let models = fit_models(map, &train_attempts, args.model.config(), &args.train)?;
    let online = evaluate(&models, &test_attempts, ProtocolArg::Online)?;
    let frozen = evaluate(&models, &test_attempts, ProtocolArg::Frozen)?;
    let chosen = match args.protocol {
        ProtocolArg::Online => &online,
        ProtocolArg::Frozen => &frozen,
    };
    let protocol = match args.protocol {
        ProtocolArg::Online => "online",
        ProtocolArg::Frozen => "frozen",
    };
    let mut per_edge = Vec::new();
    if args.per_edge {
        for (e, list) in test_attempts.iter().enumerate() {
            if list.is_empty() {
                continue;
            }
            let mut only = vec![Vec::new(); test_attempts.len()];
            only[e] = list.clone();
            let score = evaluate(&models, &only, args.protocol)?;
            per_edge.push((e, train_attempts[e].len(), score));
        }
    }
    if args.json {
        let mut report = json!({
            "success_brier": chosen.success_brier,
            "duration_mse": chosen.duration_mse,
            "static_success_brier": chosen.static_success_brier,
            "static_duration_mse": chosen.static_duration_mse,
            "attempts": chosen.attempts,
            "successes": chosen.successes,
            "protocol": protocol,
            "train_attempts": train_total,
            "edges": models.map().edges().len(),
            "online": score_json(&online),
            "frozen": score_json(&frozen),
        });
        if args.per_edge {
            report["per_edge"] = per_edge
                .iter()
                .map(|(e, n, s)| {
                    json!({
                        "edge": models.map().edges()[*e].id,
                        "train_attempts": n,
                        "test_attempts": s.attempts,
                        "success_brier": s.success_brier,
                        "static_success_brier": s.static_success_brier,
                    })
                })
                .collect();
        }
        writeln!(out, "{report}")?;
        return Ok(());
    }
    writeln!(
        out,
        "trained on {} attempts ({}), tested on {} attempts ({}) of {} edges",
        train_total,
        args.train.display(),
        chosen.attempts,
        args.test.display(),
        models.map().edges().len()
    )?;
    let mut table = Table::new([
        "protocol",
        "success Brier",
        "static Brier",
        "ratio",
        "duration MSE (s²)",
        "static MSE (s²)",
    ]);
    for (name, s) in [("online", &online), ("frozen", &frozen)] {
        table.row([
            if name == protocol {
                format!("{name} *")
            } else {
                name.to_string()
            },
            format!("{:.4}", s.success_brier),
            format!("{:.4}", s.static_success_brier),
            format!("{:.2}", s.success_brier / s.static_success_brier),
            format!("{:.2}", s.duration_mse),
            format!("{:.2}", s.static_duration_mse),
        ]);
    }
    writeln!(out, "{}", table.render())?;
    writeln!(
        out,
        "(* the protocol asked for; ratio < 1: the per-edge models beat the static per-edge rates; durations of the {} successful attempts, models as fitted)",
        chosen.successes
    )?;
    if args.per_edge {
        let mut table = Table::new(["edge", "train", "test", "Brier", "static"]);
        for (e, n, s) in &per_edge {
            table.row([
                models.map().edges()[*e].id.clone(),
                n.to_string(),
                s.attempts.to_string(),
                format!("{:.4}", s.success_brier),
                format!("{:.4}", s.static_success_brier),
            ]);
        }
        writeln!(out, "\n{}", table.render())?;
    }
    Ok(())
}

pub fn split(args: &TopoSplitArgs) -> Result<()> {
    let mut out = std::io::stdout().lock();
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
    writeln!(
        out,
        "before {}: {} attempts in {a} edge files -> {}",
        time(args.at),
        before.total_attempts(),
        args.before.display()
    )?;
    writeln!(
        out,
        "from {}: {} attempts in {b} edge files -> {}",
        time(args.at),
        after.total_attempts(),
        args.after.display()
    )?;
    Ok(())
}

pub fn predict(args: &TopoPredictArgs) -> Result<()> {
    let mut out = std::io::stdout().lock();
    let models = load(&args.model)?;
    let (success, duration) = models.at(args.time);
    if let Some(path) = &args.geojson {
        let metadata: Vec<(f64, f64)> = success
            .iter()
            .copied()
            .zip(duration.iter().copied())
            .collect();
        write_route_geojson(path, models.map(), &metadata)?;
        eprintln!("wrote {}", path.display());
    }
    if let Some(path) = &args.tmap2 {
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("chronomap");
        write_tmap2(path, models.map(), name)?;
        eprintln!("wrote {}", path.display());
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
        writeln!(out, "{}", json!({"time": args.time, "edges": edges}))?;
        return Ok(());
    }
    writeln!(out, "{} edges at {}", map.edges().len(), time(args.time))?;
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
    writeln!(out, "{}", table.render())?;
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

/// Short codes for first actions: `a`, `b`, ..., `z`, `aa`, ...
fn code(i: usize) -> String {
    let letters = b"abcdefghijklmnopqrstuvwxyz";
    if i < 26 {
        (letters[i] as char).to_string()
    } else {
        format!(
            "{}{}",
            letters[(i / 26 - 1) % 26] as char,
            letters[i % 26] as char
        )
    }
}

/// A now-or-later table (seed 003 Table III): the plans of `days` days × `per_day` start
/// times, `step_mins` apart from midnight UTC of `first_day`; day-major.
pub(super) struct DayTable<'a> {
    map: &'a TopoMap,
    task: String,
    from: String,
    first_day: f64,
    days: usize,
    per_day: usize,
    step_mins: usize,
    plans: Vec<PlanAt>,
    /// The first edges that occur, in edge order: edge `codes[i]` is written `code(i)`.
    codes: Vec<usize>,
    /// Seconds spent planning.
    pub(super) seconds: f64,
}

impl<'a> DayTable<'a> {
    /// Plans `task` from `from` at every start time.
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
        let first_day = (first_day / 86_400.0).floor() * 86_400.0;
        let per_day = 1440 / step_mins.max(1);
        let times: Vec<f64> = (0..days)
            .flat_map(|d| {
                (0..per_day)
                    .map(move |k| first_day + 86_400.0 * d as f64 + 60.0 * (k * step_mins) as f64)
            })
            .collect();
        let started = Instant::now();
        let plans = now_or_later(models, start, &parsed, &times, &SolverOptions::default())?;
        let seconds = started.elapsed().as_secs_f64();
        let mut codes: Vec<usize> = plans.iter().filter_map(|p| p.first_edge).collect();
        codes.sort_unstable();
        codes.dedup();
        Ok(DayTable {
            map,
            task: task.to_string(),
            from: from.to_string(),
            first_day,
            days,
            per_day,
            step_mins,
            plans,
            codes,
            seconds,
        })
    }

    fn at(&self, day: usize, k: usize) -> &PlanAt {
        &self.plans[day * self.per_day + k]
    }

    fn code_of(&self, p: &PlanAt) -> String {
        p.first_edge
            .and_then(|e| self.codes.iter().position(|&c| c == e))
            .map_or_else(|| "-".to_string(), code)
    }

    fn row_label(&self, k: usize) -> String {
        let minutes = k * self.step_mins;
        format!("{:02}:{:02}", minutes / 60, minutes % 60)
    }

    fn day_label(&self, d: usize) -> String {
        day_label(self.first_day + 86_400.0 * d as f64)
    }

    fn legend(&self) -> Vec<String> {
        self.codes
            .iter()
            .enumerate()
            .map(|(i, &e)| format!("{} = {}", code(i), self.map.edges()[e].id))
            .chain(std::iter::once(
                "- = nothing to do (the task holds, or cannot be fulfilled)".to_string(),
            ))
            .collect()
    }

    /// The table as text: `Pmax code` per start time (rows) and day (columns), then the legend.
    pub(super) fn render(&self) -> String {
        let mut header = vec!["start (UTC)".to_string()];
        header.extend((0..self.days).map(|d| self.day_label(d)));
        let mut grid = Table::new(header);
        for k in 0..self.per_day {
            let mut row = vec![self.row_label(k)];
            for d in 0..self.days {
                let p = self.at(d, k);
                row.push(format!("{:.2} {}", p.pmax, self.code_of(p)));
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
        let heatmap = Heatmap {
            title: format!(
                "Now or later? P(success) of {:?} from {}",
                self.task, self.from
            ),
            row_label: "start (UTC)".to_string(),
            column_label: "day".to_string(),
            rows: (0..self.per_day).map(|k| self.row_label(k)).collect(),
            columns: (0..self.days).map(|d| self.day_label(d)).collect(),
            // Row-major, one row per start time.
            values: (0..self.per_day)
                .flat_map(|k| (0..self.days).map(move |d| (d, k)))
                .map(|(d, k)| self.at(d, k).pmax.clamp(0.0, 1.0))
                .collect(),
            cell_text: (0..self.per_day)
                .flat_map(|k| (0..self.days).map(move |d| (d, k)))
                .map(|(d, k)| self.code_of(self.at(d, k)))
                .collect(),
            value_label: "Pmax".to_string(),
            legend: self.legend(),
        };
        render_heatmap_png(&heatmap, path)?;
        Ok(())
    }
}

pub fn plan(args: &PlanArgs) -> Result<()> {
    let mut out = std::io::stdout().lock();
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
        writeln!(out, "{}", table.json())?;
        return Ok(());
    }
    writeln!(
        out,
        "task {:?} from {}: maximum probability of success and first action, {} start times in {:.2} s",
        args.task,
        args.from,
        table.plans.len(),
        table.seconds
    )?;
    writeln!(out, "{}", table.render())?;
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
    let mut out = std::io::stdout().lock();
    let started = Instant::now();
    let planned = plan_full(models, start, task, t, options)?;
    let seconds = started.elapsed().as_secs_f64();
    let map = models.map();
    if let Some(path) = &args.prism {
        let model = planned.mdp.to_prism(start)?;
        std::fs::write(path, model).with_context(|| format!("cannot write {}", path.display()))?;
        let props = path.with_extension("props");
        std::fs::write(&props, format!("{}\n", prism_property(task.text())?))
            .with_context(|| format!("cannot write {}", props.display()))?;
        eprintln!("wrote {} and {}", path.display(), props.display());
    }
    if let Some(path) = &args.drn {
        let text = product_drn(planned.product.mdp(), &planned.solution)?;
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    // The route if every edge succeeds: follow the policy through the product.
    let mut route = Vec::new();
    let (product, solution) = (&planned.product, &planned.solution);
    let mut state = solution.initial;
    while let Some(choice) = solution.policy_choice[state] {
        let edge = product.mdp().action(choice);
        route.push(edge);
        let target = map.edges()[edge].to;
        match product.successor(state, choice, Some(target)) {
            Some(next) if route.len() <= product.states().len() => state = next,
            _ => break,
        }
    }
    let plan = &planned.plan;
    if args.json {
        writeln!(
            out,
            "{}",
            json!({
                "task": args.task,
                "from": args.from,
                "time": t,
                "utc": time(t),
                "pmax": plan.pmax,
                "expected_secs": plan.expected_secs,
                "first_edge": plan.first_edge.map(|e| map.edges()[e].id.clone()),
                "route": route.iter().map(|&e| map.edges()[e].id.clone()).collect::<Vec<_>>(),
                "route_success_probabilities": route.iter().map(|&e| models.success_probability(e, t)).collect::<Vec<_>>(),
                "product_states": product.states().len(),
                "seconds": seconds,
            })
        )?;
        return Ok(());
    }
    writeln!(
        out,
        "task {:?} from {} at {}",
        args.task,
        args.from,
        time(t)
    )?;
    writeln!(
        out,
        "maximum probability of success: {:.4}; expected time: {:.1} s (until done or failed)",
        plan.pmax, plan.expected_secs
    )?;
    match plan.first_edge {
        Some(e) => writeln!(out, "first action: {}", map.edges()[e].id)?,
        None if plan.pmax >= 1.0 => writeln!(out, "the task holds already")?,
        None => writeln!(out, "the task cannot be fulfilled from here")?,
    }
    if !route.is_empty() {
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
        writeln!(out, "route if every edge succeeds: {}", names.join(" -> "))?;
    }
    writeln!(
        out,
        "({} product states, solved in {:.1} ms)",
        product.states().len(),
        seconds * 1e3
    )?;
    Ok(())
}
