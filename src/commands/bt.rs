//! `chronomap bt check`, `chronomap bt run` and `chronomap bt analyse`: BehaviorTree.CPP 4 XML
//! trees ([Stüde 2024] §5.2–5.3) checked and printed, ticked with leaves that follow a script of
//! outcomes, or analysed as stochastic behavior trees (§5.2.2, eqs. 5.1–5.4).

use std::time::Duration;

use anyhow::{Context, Result, anyhow};
use chronomap_bt::sbt;
use chronomap_bt::script::{run_script, scripted_registry};
use chronomap_bt::{BtDocument, NodeCategory, Registry, Status, Tree};
use chronomap_io::{
    BtXml, read_bt_script, read_bt_xml, read_leaf_params, write_bt_xml, write_btlog,
};
use chronomap_plot::{Panel, Series, SeriesStyle, render_panels_png};
use serde::Serialize;
use serde_json::{Value, json};

use crate::cli::{BtAnalyseArgs, BtCheckArgs, BtRunArgs};
use crate::outln;
use crate::output::print_json;

/// Reads the file with the built-in nodes and the file's own node models, printing warnings.
fn load(file: &std::path::Path) -> Result<BtDocument> {
    Ok(load_xml(file)?.document)
}

fn load_xml(file: &std::path::Path) -> Result<BtXml> {
    let xml = read_bt_xml(file, &Registry::new())?;
    for warning in &xml.warnings {
        eprintln!("warning: {warning}");
    }
    Ok(xml)
}

/// The tree to use: `--tree`, or the document's main tree.
fn instantiate(
    file: &std::path::Path,
    doc: &BtDocument,
    tree: Option<&str>,
) -> Result<(Tree, chronomap_bt::script::ScriptedOutcomes)> {
    let name = file.display();
    let (registry, outcomes) =
        scripted_registry(doc).with_context(|| format!("{name}: cannot implement the leaves"))?;
    let main = match tree {
        Some(t) => t.to_owned(),
        None => doc
            .main_tree_id()
            .with_context(|| format!("{name}: which tree? (use --tree)"))?
            .to_owned(),
    };
    let tree = Tree::with_main(doc, &main, &registry).with_context(|| name.to_string())?;
    Ok((tree, outcomes))
}

pub fn check(args: &BtCheckArgs) -> Result<()> {
    let doc = load(&args.file)?;
    let (tree, _) = instantiate(&args.file, &doc, args.tree.as_deref())?;
    let ids: Vec<&str> = doc.trees.iter().map(|t| t.id.as_str()).collect();
    let leaves = tree
        .nodes()
        .iter()
        .filter(|n| n.category().is_leaf())
        .count();
    if let Some(path) = &args.output {
        write_bt_xml(path, &doc)?;
    }
    if args.json {
        let mut nodes = Vec::new();
        node_json(&tree, 0, 0, &mut nodes);
        return print_json(&json!({
            "file": args.file.display().to_string(),
            "format": 4,
            "trees": ids,
            "tree": tree.subtrees()[0].tree_id,
            "leaves": leaves,
            "nodes": nodes,
            "output": args.output.as_ref().map(|p| p.display().to_string()),
        }));
    }
    outln!(
        "{}: BehaviorTree.CPP 4, {} tree{} ({}); {} has {} nodes, {} of them leaves",
        args.file.display(),
        ids.len(),
        if ids.len() == 1 { "" } else { "s" },
        ids.join(", "),
        tree.subtrees()[0].tree_id,
        tree.nodes().len(),
        leaves
    )?;
    outln!(" uid  node")?;
    print_node(&tree, 0, 0)?;
    if let Some(path) = &args.output {
        outln!(
            "wrote {} (canonical BehaviorTree.CPP 4 XML)",
            path.display()
        )?;
    }
    Ok(())
}

fn print_node(tree: &Tree, index: usize, depth: usize) -> Result<()> {
    let node = &tree.nodes()[index];
    let mut label = match node.category() {
        NodeCategory::SubTree => format!("SubTree {}", node.id()),
        _ => node.id().to_owned(),
    };
    if node.name() != node.id() {
        label.push_str(&format!(" {:?}", node.name()));
    }
    if node.category().is_leaf() {
        label.push_str(&format!(" ({})", node.category()));
    }
    for (port, value) in node.attributes() {
        label.push_str(&format!(" {port}={value}"));
    }
    outln!("{:>4}  {}{label}", node.uid(), "  ".repeat(depth))?;
    for &child in node.children() {
        print_node(tree, child, depth + 1)?;
    }
    Ok(())
}

/// The nodes depth first, as `bt check` prints them.
fn node_json(tree: &Tree, index: usize, depth: usize, out: &mut Vec<Value>) {
    let node = &tree.nodes()[index];
    out.push(json!({
        "uid": node.uid(),
        "id": node.id(),
        "name": node.name(),
        "category": node.category().to_string(),
        "depth": depth,
        "attributes": node
            .attributes()
            .iter()
            .map(|(k, v)| (k.clone(), json!(v)))
            .collect::<serde_json::Map<_, _>>(),
        "children": node.children().iter().map(|&c| tree.nodes()[c].uid()).collect::<Vec<_>>(),
    }));
    for &child in node.children() {
        node_json(tree, child, depth + 1, out);
    }
}

pub fn run(args: &BtRunArgs) -> Result<()> {
    let doc = load(&args.file)?;
    let script = read_bt_script(&args.script)?;
    let (mut tree, outcomes) = instantiate(&args.file, &doc, args.tree.as_deref())?;
    let period = Duration::from_millis(args.tick_ms);
    let run = run_script(&mut tree, &outcomes, &script, period)
        .with_context(|| format!("{}", args.script.display()))?;
    let transitions: Vec<_> = run
        .ticks
        .iter()
        .flat_map(|t| t.transitions.iter().copied())
        .collect();
    if let Some(path) = &args.btlog {
        write_btlog(path, &tree, Duration::ZERO, &transitions)?;
    }
    let last = run.ticks.last().expect("scripts have at least one tick");
    let name_of = |uid: u16| tree.node(uid).map_or("?", |n| n.name());
    if args.json {
        let ticks: Vec<Value> = run
            .ticks
            .iter()
            .map(|tick| {
                json!({
                    "tick": tick.tick,
                    "time_ms": tick.time.as_millis() as u64,
                    "status": tick.status.to_string(),
                    "transitions": tick.transitions.iter().map(|t| json!({
                        "uid": t.uid,
                        "name": name_of(t.uid),
                        "from": t.from.to_string(),
                        "to": t.to.to_string(),
                    })).collect::<Vec<_>>(),
                })
            })
            .collect();
        return print_json(&json!({
            "file": args.file.display().to_string(),
            "script": args.script.display().to_string(),
            "tree": tree.subtrees()[0].tree_id,
            "finished": run.finished,
            "status": last.status.to_string(),
            "last_tick": last.tick,
            "last_time_ms": last.time.as_millis() as u64,
            "unused_ticks": run.unused,
            "ticks": ticks,
            "transitions": transitions.len(),
            "btlog": args.btlog.as_ref().map(|p| p.display().to_string()),
        }));
    }
    let width = tree
        .nodes()
        .iter()
        .map(|n| n.name().chars().count())
        .max()
        .unwrap_or(0);
    for tick in &run.ticks {
        outln!(
            "tick {} @ {} ms: {}",
            tick.tick,
            tick.time.as_millis(),
            tick.status
        )?;
        for t in &tick.transitions {
            let name = name_of(t.uid);
            let halted = if t.from == Status::Running && t.to == Status::Idle {
                " (halted)"
            } else {
                ""
            };
            outln!(
                "  {:>3} {name:<width$}  {} -> {}{halted}",
                t.uid,
                t.from,
                t.to
            )?;
        }
    }
    if run.finished {
        outln!(
            "result: {} at tick {} ({} ms)",
            last.status,
            last.tick,
            last.time.as_millis()
        )?;
    } else {
        outln!(
            "result: still RUNNING after tick {} ({} ms)",
            last.tick,
            last.time.as_millis()
        )?;
    }
    if !run.unused.is_empty() {
        let unused: Vec<String> = run.unused.iter().map(u64::to_string).collect();
        outln!(
            "note: the tree finished before script tick{} {}",
            if unused.len() == 1 { "" } else { "s" },
            unused.join(", ")
        )?;
    }
    if let Some(path) = &args.btlog {
        outln!(
            "wrote {} ({} transitions of {} nodes)",
            path.display(),
            transitions.len(),
            tree.nodes().len()
        )?;
    }
    Ok(())
}

#[derive(Serialize)]
struct Analysis {
    file: String,
    tree: String,
    states: usize,
    p_success: f64,
    p_failure: f64,
    time_to_success: Option<f64>,
    time_to_failure: Option<f64>,
    mu_t: Option<f64>,
    nu_t: Option<f64>,
    error_bound: f64,
    curve: Vec<CurvePoint>,
}

#[derive(Serialize)]
struct CurvePoint {
    t: f64,
    p_success: f64,
    p_failure: f64,
}

/// `chronomap bt analyse`: the stochastic behavior tree of §5.2.2 ([`sbt::from_bt()`]), eq. 5.1
/// by uniformisation ([`sbt::Chain::transient`]) and the exact mean times that replace the
/// averaged rates of eqs. 5.3–5.4 ([`sbt::Chain::means`]).
pub fn analyse(args: &BtAnalyseArgs) -> Result<()> {
    let file = args.file.display().to_string();
    let xml = load_xml(&args.file)?;
    let params = read_leaf_params(&args.params)?;
    let doc = &xml.document;
    let tree_id = match &args.tree {
        Some(t) => t.clone(),
        None => doc
            .main_tree_id()
            .with_context(|| format!("{file}: which tree? (use --tree)"))?
            .to_owned(),
    };
    let tree =
        sbt::from_bt(doc, &tree_id, &params).map_err(|e| match xml.position(&e.location) {
            Some((line, column)) => anyhow!("{file}:{line}:{column}: {}", e.kind),
            None => anyhow!("{file}: {e}"),
        })?;
    let chain = tree.chain().with_context(|| file.clone())?;
    let means = chain.means();
    let t_max = match args.t_max {
        Some(t) => t,
        None => {
            let longest = [means.time_to_success, means.time_to_failure]
                .into_iter()
                .flatten()
                .fold(0.0, f64::max);
            if longest > 0.0 { 3.0 * longest } else { 1.0 }
        }
    };
    let times: Vec<f64> = (0..=args.steps)
        .map(|i| t_max * f64::from(i) / f64::from(args.steps))
        .collect();
    const TOLERANCE: f64 = 1e-12;
    let curve = chain.transient(&times, TOLERANCE)?;
    let analysis = Analysis {
        file: file.clone(),
        tree: tree_id.clone(),
        states: chain.states(),
        p_success: means.p_success,
        p_failure: means.p_failure,
        time_to_success: means.time_to_success,
        time_to_failure: means.time_to_failure,
        mu_t: means.time_to_success.map(|t| 1.0 / t),
        nu_t: means.time_to_failure.map(|t| 1.0 / t),
        error_bound: curve.iter().map(|o| o.error_bound).fold(0.0, f64::max),
        curve: times
            .iter()
            .zip(&curve)
            .map(|(&t, o)| CurvePoint {
                t,
                p_success: o.p_success,
                p_failure: o.p_failure,
            })
            .collect(),
    };
    if args.json {
        print_json(&analysis)?;
    } else {
        let leaves = params.len();
        outln!(
            "{file}: tree {tree_id} as a stochastic behavior tree (§5.2.2): {} transient states, \
             {leaves} leaf parameter rows",
            analysis.states
        )?;
        outln!(
            "eventually: p_s = {:.6}, p_f = {:.6}",
            analysis.p_success,
            analysis.p_failure
        )?;
        let mean = |label: &str, rate: &str, t: Option<f64>| match t {
            Some(t) => format!("{label} = {t:.3} s ({rate} = {:.6} /s)", 1.0 / t),
            None => format!("{label}: never"),
        };
        outln!(
            "{}, {}",
            mean("E[T | success]", "mu_T", analysis.time_to_success),
            mean("E[T | failure]", "nu_T", analysis.time_to_failure)
        )?;
        outln!("{:>12}  {:>10}  {:>10}", "t [s]", "p_s,T(t)", "p_f,T(t)")?;
        for p in &analysis.curve {
            outln!(
                "{:>12.3}  {:>10.6}  {:>10.6}",
                p.t,
                p.p_success,
                p.p_failure
            )?;
        }
    }
    if let Some(path) = &args.plot {
        let fine: Vec<f64> = (0..=200).map(|i| t_max * i as f64 / 200.0).collect();
        let at = chain.transient(&fine, TOLERANCE)?;
        let series = |label: &str, pick: fn(&sbt::Outcome) -> f64| Series {
            label: label.to_owned(),
            points: fine.iter().zip(&at).map(|(&t, o)| (t, pick(o))).collect(),
            style: SeriesStyle::Line,
        };
        let panel = Panel {
            title: format!("{tree_id}: stochastic behavior tree (eq. 5.1)"),
            x_label: "t [s] since the tree started".to_owned(),
            y_label: "probability".to_owned(),
            y_range: (0.0, 1.0),
            series: vec![
                series("p_s,T(t)", |o| o.p_success),
                series("p_f,T(t)", |o| o.p_failure),
            ],
        };
        render_panels_png(&[panel], path, 1000, 500)?;
        if !args.json {
            outln!("wrote {}", path.display())?;
        }
    }
    Ok(())
}
