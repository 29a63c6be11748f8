//! `chronomap bt check`, `chronomap bt run` and `chronomap bt analyse`: BehaviorTree.CPP 4 XML
//! trees ([Stüde 2024] §5.2–5.3) checked and printed, ticked with leaves that follow a script of
//! outcomes (or stubs), or analysed as stochastic behavior trees (§5.2.2, eqs. 5.1–5.4).

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result, anyhow};
use chronomap_app::bt::{self, BtJobError, Flat, Implemented, Stubs};
use chronomap_bt::script::{Script, ScriptTick, ScriptedOutcomes, run_script, run_script_with};
use chronomap_bt::{BtDocument, DefinitionErrorKind, NodeCategory, Status, Tree};
use chronomap_bt_stochastic as sbt;
use chronomap_io::{BtXml, read_bt_script, read_leaf_params, write_bt_xml, write_btlog};
use chronomap_plot::{Panel, Series, SeriesStyle, render_panels_png};
use serde::Serialize;
use serde_json::{Value, json};

use crate::cli::{BtAnalyseArgs, BtCheckArgs, BtRunArgs};
use crate::outln;
use crate::output::{print_json, usage};

/// An error of the application layer as the command reports it: a stub that does not fit the
/// document is a usage error (exit code 2).
fn job_error(e: BtJobError) -> anyhow::Error {
    match e {
        BtJobError::Usage(message) => usage(message),
        e => anyhow::Error::new(e),
    }
}

/// Reads the file (and its includes) with the node models of the `--nodes` files, printing
/// warnings ([`chronomap_app::bt::load_xml`]).
fn load_xml(file: &Path, nodes: &[PathBuf]) -> Result<BtXml> {
    bt::load_xml(file, nodes, &mut |warning| eprintln!("warning: {warning}")).map_err(job_error)
}

pub fn check(args: &BtCheckArgs) -> Result<()> {
    let xml = load_xml(&args.file, &args.nodes)?;
    let doc = &xml.document;
    let name = args.file.display();
    let main = bt::main_tree(&name.to_string(), doc, args.tree.as_deref()).map_err(job_error)?;
    // Instantiating finds what only instantiation checks (children of IfThenElse, Switch…);
    // custom controls and decorators stand in as stubs for that.
    let stubs = Stubs {
        structure_only: true,
        ..Stubs::default()
    };
    let registry = bt::implement(doc, &stubs)
        .map_err(job_error)
        .with_context(|| name.to_string())?
        .registry;
    // What BehaviorTree.CPP refuses only when it ticks the node is reported here, before
    // anything runs (`bt run` raises it at the tick, as BehaviorTree.CPP does).
    chronomap_bt::validate_strict(doc, &registry)
        .map_err(|e| job_error(bt::located(&xml, &e, &name.to_string())))?;
    if let Err(e) = Tree::with_main(doc, &main, &registry) {
        if *e.kind() == DefinitionErrorKind::TooManyNodes {
            eprintln!(
                "warning: {name}: tree {main} has more than 65535 nodes: `bt run` and Groot2 \
                 logs take at most 65535 (uids are 16-bit)"
            );
        } else {
            return Err(job_error(bt::located(&xml, &e, &name.to_string())));
        }
    }
    let nodes = bt::flatten(doc, &main)
        .map_err(job_error)
        .with_context(|| name.to_string())?;
    let ids: Vec<&str> = doc.trees.iter().map(|t| t.id.as_str()).collect();
    let leaves = nodes.iter().filter(|n| n.node.category.is_leaf()).count();
    if let Some(path) = &args.output {
        write_bt_xml(path, doc)?;
    }
    if args.json {
        let nodes: Vec<Value> = nodes.iter().map(node_json).collect();
        return print_json(&json!({
            "file": args.file.display().to_string(),
            "format": 4,
            "trees": ids,
            "tree": main,
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
        main,
        nodes.len(),
        leaves
    )?;
    outln!(" uid  node")?;
    for flat in &nodes {
        print_node(flat)?;
    }
    if let Some(path) = &args.output {
        outln!(
            "wrote {} (canonical BehaviorTree.CPP 4 XML)",
            path.display()
        )?;
    }
    Ok(())
}

fn print_node(flat: &Flat<'_>) -> Result<()> {
    let node = flat.node;
    let mut label = match node.category {
        NodeCategory::SubTree => format!("SubTree {}", node.id),
        _ => node.id.clone(),
    };
    if node.instance_name() != node.id {
        label.push_str(&format!(" {:?}", node.instance_name()));
    }
    if node.category.is_leaf() {
        label.push_str(&format!(" ({})", node.category));
    }
    for (port, value) in node.ports.iter().chain(&node.scripts) {
        label.push_str(&format!(" {port}={value}"));
    }
    outln!("{:>4}  {}{label}", flat.uid, "  ".repeat(flat.depth))?;
    Ok(())
}

/// A node as `bt check --json` prints it.
fn node_json(flat: &Flat<'_>) -> Value {
    let node = flat.node;
    json!({
        "uid": flat.uid,
        "id": node.id,
        "name": node.instance_name(),
        "category": node.category.to_string(),
        "depth": flat.depth,
        "attributes": node
            .ports
            .iter()
            .chain(&node.scripts)
            .map(|(k, v)| (k.clone(), json!(v)))
            .collect::<serde_json::Map<_, _>>(),
        "children": flat.children,
    })
}

pub fn run(args: &BtRunArgs) -> Result<()> {
    let xml = load_xml(&args.file, &args.nodes)?;
    let doc = &xml.document;
    let script = match &args.script {
        Some(path) => read_bt_script(path)?,
        None => Script {
            ticks: vec![ScriptTick::new(args.ticks.unwrap_or(100))],
        },
    };
    let stubs = Stubs {
        specs: &args.stubs,
        all: args.stub_all,
        scripted_names: script
            .ticks
            .iter()
            .flat_map(|t| t.outcomes.iter().map(|(name, _)| name.clone()))
            .collect(),
        structure_only: false,
    };
    let name = args.file.display();
    let Implemented {
        mut registry,
        outcomes,
        notes,
    } = bt::implement(doc, &stubs)
        .map_err(job_error)
        .with_context(|| name.to_string())?;
    for (enum_name, value) in &args.enums {
        registry.register_enum(enum_name, *value);
    }
    let main = bt::main_tree(&name.to_string(), doc, args.tree.as_deref()).map_err(job_error)?;
    let mut tree = Tree::with_main(doc, &main, &registry)
        .map_err(|e| job_error(bt::located(&xml, &e, &name.to_string())))?;
    for note in &notes {
        eprintln!("note: {note}");
    }
    let period = Duration::from_millis(args.tick_ms);
    let script_name = args
        .script
        .as_ref()
        .map_or_else(|| "the run".to_owned(), |p| p.display().to_string());
    let live = start_live(args, &tree, doc)?;
    let run = match &live {
        Some(live) => run_live(live, &mut tree, doc, &outcomes, &script, period),
        None => run_script(&mut tree, &outcomes, &script, period),
    }
    .with_context(|| script_name.clone())?;
    let failed = run.failure.as_ref();
    let transitions: Vec<_> = run
        .ticks
        .iter()
        .flat_map(|t| t.transitions.iter().copied())
        .chain(failed.iter().flat_map(|f| f.transitions.iter().copied()))
        .collect();
    if let Some(path) = &args.btlog {
        write_btlog(path, &tree, Duration::ZERO, &transitions)?;
    }
    let name_of = |uid: u16| tree.node(uid).map_or("?", |n| n.name());
    let transitions_json = |list: &[chronomap_bt::Transition]| -> Vec<Value> {
        list.iter()
            .map(|t| {
                json!({
                    "uid": t.uid,
                    "name": name_of(t.uid),
                    "from": t.from.to_string(),
                    "to": t.to.to_string(),
                })
            })
            .collect()
    };
    let failure_message = failed.map(|f| format!("{script_name}: tick {}: {}", f.tick, f.error));
    if args.json {
        let ticks: Vec<Value> = run
            .ticks
            .iter()
            .map(|tick| {
                json!({
                    "tick": tick.tick,
                    "time_ms": tick.time.as_millis() as u64,
                    "status": tick.status.to_string(),
                    "transitions": transitions_json(&tick.transitions),
                })
            })
            .collect();
        let last = run.ticks.last();
        let board = tree.blackboard();
        let blackboard: serde_json::Map<String, Value> = board
            .entries(board.root())
            .map(|(key, value)| (key.to_owned(), blackboard_json(value)))
            .collect();
        print_json(&json!({
            "file": args.file.display().to_string(),
            "script": args.script.as_ref().map(|p| p.display().to_string()),
            "stubs": notes,
            "tree": tree.subtrees()[0].tree_id,
            "finished": run.finished,
            "status": last.map(|t| t.status.to_string()),
            "last_tick": last.map(|t| t.tick),
            "last_time_ms": last.map(|t| t.time.as_millis() as u64),
            "unused_ticks": run.unused,
            "ticks": ticks,
            "error": failed.map(|f| json!({
                "tick": f.tick,
                "time_ms": f.time.as_millis() as u64,
                "message": f.error.to_string(),
                "transitions": transitions_json(&f.transitions),
            })),
            "blackboard": blackboard,
            "transitions": transitions.len(),
            "btlog": args.btlog.as_ref().map(|p| p.display().to_string()),
        }))?;
        return match failure_message {
            Some(message) => Err(anyhow!(message)),
            None => Ok(()),
        };
    }
    let width = tree
        .nodes()
        .iter()
        .map(|n| crate::format::elide(n.name()).chars().count())
        .max()
        .unwrap_or(0);
    let print_transitions = |list: &[chronomap_bt::Transition]| -> Result<()> {
        for t in list {
            // A name from the XML may be longer than a format width can pad (65,535).
            let name = crate::format::pad_right(&crate::format::elide(name_of(t.uid)), width);
            let halted = if t.from == Status::Running && t.to == Status::Idle {
                " (halted)"
            } else {
                ""
            };
            outln!("  {:>3} {name}  {} -> {}{halted}", t.uid, t.from, t.to)?;
        }
        Ok(())
    };
    for tick in &run.ticks {
        outln!(
            "tick {} @ {} ms: {}",
            tick.tick,
            tick.time.as_millis(),
            tick.status
        )?;
        print_transitions(&tick.transitions)?;
    }
    if let Some(f) = failed {
        outln!("tick {} @ {} ms: error", f.tick, f.time.as_millis())?;
        print_transitions(&f.transitions)?;
        return Err(anyhow!(
            failure_message.expect("a failed tick has a message")
        ));
    }
    let last = run.ticks.last().expect("a run that did not fail has ticks");
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
    if args.script.is_some() && !run.unused.is_empty() {
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

/// `--groot2`, `--tick-period`, `--linger`: the Groot2 server of a run and the wall-clock
/// pacing of its ticks. Dropped at the end of the run: it keeps answering for the linger
/// time first.
struct Live {
    publisher: Option<chronomap_groot2::publisher::Publisher>,
    pause: Duration,
    linger: Duration,
}

impl Drop for Live {
    fn drop(&mut self) {
        if let Some(publisher) = &self.publisher
            && !self.linger.is_zero()
        {
            eprintln!(
                "note: groot2: answering on port {} for {} s more",
                publisher.port(),
                self.linger.as_secs()
            );
            std::thread::sleep(self.linger);
        }
    }
}

/// The Groot2 server (started now, before the first tick) and the pacing a run asks for, if
/// any.
fn start_live(args: &BtRunArgs, tree: &Tree, doc: &BtDocument) -> Result<Option<Live>> {
    if args.groot2.is_none() && args.tick_period.is_none() {
        return Ok(None);
    }
    let publisher = match args.groot2 {
        Some(port) => {
            let publisher = chronomap_groot2::publisher::Publisher::start(tree, doc, port)
                .with_context(|| format!("--groot2 {port}"))?;
            if let Some(ms) = args.groot2_heartbeat {
                publisher.set_max_heartbeat_delay(Duration::from_millis(ms));
            }
            eprintln!("note: groot2: serving on ports {port} and {}", port + 1);
            Some(publisher)
        }
        None => None,
    };
    let default_ms = if publisher.is_some() { 500 } else { 0 };
    Ok(Some(Live {
        publisher,
        pause: Duration::from_millis(args.tick_period.unwrap_or(default_ms)),
        linger: Duration::from_secs(args.linger.unwrap_or(0)),
    }))
}

/// A run in real time: `tree` runs the script with a pause before each tick and the server
/// updated after each (the script is checked before anything runs, as by `run_script`).
fn run_live(
    live: &Live,
    tree: &mut Tree,
    doc: &BtDocument,
    outcomes: &ScriptedOutcomes,
    script: &Script,
    period: Duration,
) -> Result<chronomap_bt::script::ScriptRun, chronomap_bt::script::ScriptError> {
    // The clients' hooks act on the ticks (a breakpoint holds this thread).
    if let Some(publisher) = &live.publisher {
        tree.set_tick_monitor(Some(publisher.tick_monitor()));
    }
    let run = run_script_with(
        tree,
        outcomes,
        script,
        period,
        &mut || std::thread::sleep(live.pause),
        &mut |tree, transitions| {
            if let Some(publisher) = &live.publisher {
                publisher.update(tree, doc, transitions);
            }
        },
    );
    tree.set_tick_monitor(None);
    run
}

/// A blackboard value as JSON: numbers and booleans as themselves, text as a string, a queue as
/// an array.
fn blackboard_json(value: &chronomap_bt::Value) -> Value {
    use chronomap_bt::Value as V;
    match value {
        V::Bool(b) => json!(b),
        V::Int(i) => json!(i),
        V::Double(d) => json!(d),
        V::Str(s) => json!(s),
        V::List(items) => Value::Array(items.iter().map(blackboard_json).collect()),
    }
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

/// `chronomap bt analyse`: the stochastic behavior tree of §5.2.2
/// ([`chronomap_app::bt::stochastic_chain`]), eq. 5.1 by uniformisation
/// ([`sbt::Chain::transient`]) and the exact mean times that replace the averaged rates of
/// eqs. 5.3–5.4 ([`sbt::Chain::means`]).
pub fn analyse(args: &BtAnalyseArgs) -> Result<()> {
    let file = args.file.display().to_string();
    let xml = load_xml(&args.file, &args.nodes)?;
    let params = read_leaf_params(&args.params)?;
    let doc = &xml.document;
    let tree_id = bt::main_tree(&file, doc, args.tree.as_deref()).map_err(job_error)?;
    let chain = bt::stochastic_chain(&xml, &file, &tree_id, &params).map_err(job_error)?;
    let means = chain.means();
    let t_max = args.t_max.unwrap_or_else(|| bt::default_t_max(&means));
    let times = bt::curve_times(t_max, args.steps);
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
        let fine = bt::curve_times(t_max, 200);
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
