//! `chronomap bt check`, `chronomap bt run` and `chronomap bt analyse`: BehaviorTree.CPP 4 XML
//! trees (seed 002 §5.2–5.3) checked and printed, ticked with leaves that follow a script of
//! outcomes, or analysed as stochastic behavior trees (§5.2.2, eqs. 5.1–5.4).

use std::io::Write;
use std::time::Duration;

use std::collections::BTreeMap;

use anyhow::{Context, Result, anyhow, bail};
use chronomap_bt::sbt::{self, LeafParams};
use chronomap_bt::script::{run_script, scripted_registry};
use chronomap_bt::{BtDocument, NodeCategory, Registry, Status, Tree};
use chronomap_io::{BtXml, read_bt_script, read_bt_xml, write_bt_xml, write_btlog};
use chronomap_plot::{Panel, Series, SeriesStyle, render_panels_png};
use serde::Serialize;

use crate::cli::{BtAnalyseArgs, BtCheckArgs, BtRunArgs};

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
    let mut out = std::io::stdout().lock();
    let ids: Vec<&str> = doc.trees.iter().map(|t| t.id.as_str()).collect();
    let leaves = tree
        .nodes()
        .iter()
        .filter(|n| n.category().is_leaf())
        .count();
    writeln!(
        out,
        "{}: BehaviorTree.CPP 4, {} tree{} ({}); {} has {} nodes, {} of them leaves",
        args.file.display(),
        ids.len(),
        if ids.len() == 1 { "" } else { "s" },
        ids.join(", "),
        tree.subtrees()[0].tree_id,
        tree.nodes().len(),
        leaves
    )?;
    writeln!(out, " uid  node")?;
    print_node(&mut out, &tree, 0, 0)?;
    if let Some(path) = &args.save {
        write_bt_xml(path, &doc)?;
        writeln!(
            out,
            "wrote {} (canonical BehaviorTree.CPP 4 XML)",
            path.display()
        )?;
    }
    Ok(())
}

fn print_node(out: &mut impl Write, tree: &Tree, index: usize, depth: usize) -> Result<()> {
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
    writeln!(out, "{:>4}  {}{label}", node.uid(), "  ".repeat(depth))?;
    for &child in node.children() {
        print_node(out, tree, child, depth + 1)?;
    }
    Ok(())
}

pub fn run(args: &BtRunArgs) -> Result<()> {
    let doc = load(&args.file)?;
    let script = read_bt_script(&args.script)?;
    let (mut tree, outcomes) = instantiate(&args.file, &doc, args.tree.as_deref())?;
    let period = Duration::from_millis(args.tick_ms);
    let run = run_script(&mut tree, &outcomes, &script, period)
        .with_context(|| format!("{}", args.script.display()))?;
    let width = tree
        .nodes()
        .iter()
        .map(|n| n.name().chars().count())
        .max()
        .unwrap_or(0);
    let mut out = std::io::stdout().lock();
    for tick in &run.ticks {
        writeln!(
            out,
            "tick {} @ {} ms: {}",
            tick.tick,
            tick.time.as_millis(),
            tick.status
        )?;
        for t in &tick.transitions {
            let name = tree.node(t.uid).map_or("?", |n| n.name());
            let halted = if t.from == Status::Running && t.to == Status::Idle {
                " (halted)"
            } else {
                ""
            };
            writeln!(
                out,
                "  {:>3} {name:<width$}  {} -> {}{halted}",
                t.uid, t.from, t.to
            )?;
        }
    }
    let last = run.ticks.last().expect("scripts have at least one tick");
    if run.finished {
        writeln!(
            out,
            "result: {} at tick {} ({} ms)",
            last.status,
            last.tick,
            last.time.as_millis()
        )?;
    } else {
        writeln!(
            out,
            "result: still RUNNING after tick {} ({} ms)",
            last.tick,
            last.time.as_millis()
        )?;
    }
    if !run.unused.is_empty() {
        let unused: Vec<String> = run.unused.iter().map(u64::to_string).collect();
        writeln!(
            out,
            "note: the tree finished before script tick{} {}",
            if unused.len() == 1 { "" } else { "s" },
            unused.join(", ")
        )?;
    }
    if let Some(path) = &args.btlog {
        let transitions: Vec<_> = run
            .ticks
            .iter()
            .flat_map(|t| t.transitions.iter().copied())
            .collect();
        write_btlog(path, &tree, Duration::ZERO, &transitions)?;
        writeln!(
            out,
            "wrote {} ({} transitions of {} nodes)",
            path.display(),
            transitions.len(),
            tree.nodes().len()
        )?;
    }
    Ok(())
}

/// Reads the parameters CSV `node,p_s,p_f,mu,nu` (header first; `#` comments and blank lines
/// skipped; `p_f`, and `mu`, `nu` for conditions, may be empty). `p_f`, when given, must be
/// `1 − p_s`: the model of §5.2.2 has every leaf end in success or failure.
fn read_params(path: &std::path::Path) -> Result<BTreeMap<String, LeafParams>> {
    let name = path.display();
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {name}"))?;
    let mut rows = text
        .lines()
        .enumerate()
        .map(|(i, line)| (i + 1, line.trim()))
        .filter(|(_, line)| !line.is_empty() && !line.starts_with('#'));
    const HEADER: [&str; 5] = ["node", "p_s", "p_f", "mu", "nu"];
    match rows.next() {
        Some((_, header)) if header.split(',').map(str::trim).eq(HEADER.iter().copied()) => {}
        Some((line, header)) => {
            bail!(
                "{name}:{line}: header {header:?}: expected {}",
                HEADER.join(",")
            )
        }
        None => bail!("{name}: no rows (expected the header {})", HEADER.join(",")),
    }
    let mut params = BTreeMap::new();
    for (line, row) in rows {
        let fields: Vec<&str> = row.split(',').map(str::trim).collect();
        if fields.len() != HEADER.len() {
            bail!(
                "{name}:{line}: {} fields, expected {} ({})",
                fields.len(),
                HEADER.len(),
                HEADER.join(",")
            );
        }
        let number = |i: usize| -> Result<Option<f64>> {
            if fields[i].is_empty() {
                return Ok(None);
            }
            match fields[i].parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(Some(v)),
                _ => bail!(
                    "{name}:{line}: field {}: {:?} is not a finite number",
                    HEADER[i],
                    fields[i]
                ),
            }
        };
        if fields[0].is_empty() {
            bail!("{name}:{line}: field node: empty");
        }
        let Some(p_success) = number(1)? else {
            bail!("{name}:{line}: field p_s: empty");
        };
        if let Some(p_failure) = number(2)?
            && (p_success + p_failure - 1.0).abs() > 1e-9
        {
            bail!(
                "{name}:{line}: field p_f: p_s + p_f = {} (every leaf ends in success or \
                 failure, so p_f = 1 - p_s)",
                p_success + p_failure
            );
        }
        let (mu, nu) = (number(3)?, number(4)?);
        if mu.is_some() != nu.is_some() {
            bail!("{name}:{line}: give both mu and nu (action) or neither (condition)");
        }
        if params
            .insert(fields[0].to_owned(), LeafParams { p_success, mu, nu })
            .is_some()
        {
            bail!("{name}:{line}: field node: {:?} appears twice", fields[0]);
        }
    }
    Ok(params)
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
    let params = read_params(&args.params)?;
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
    if args.steps == 0 {
        bail!("--steps must be at least 1");
    }
    let t_max = match args.t_max {
        Some(t) if t.is_finite() && t > 0.0 => t,
        Some(t) => bail!("--t-max {t}: expected a positive number of seconds"),
        None => {
            let longest = [means.time_to_success, means.time_to_failure]
                .into_iter()
                .flatten()
                .fold(0.0, f64::max);
            if longest > 0.0 { 3.0 * longest } else { 1.0 }
        }
    };
    let times: Vec<f64> = (0..=args.steps)
        .map(|i| t_max * i as f64 / args.steps as f64)
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
    let mut out = std::io::stdout().lock();
    if args.json {
        serde_json::to_writer_pretty(&mut out, &analysis)?;
        writeln!(out)?;
    } else {
        let leaves = params.len();
        writeln!(
            out,
            "{file}: tree {tree_id} as a stochastic behavior tree (§5.2.2): {} transient states, \
             {leaves} leaf parameter rows",
            analysis.states
        )?;
        writeln!(
            out,
            "eventually: p_s = {:.6}, p_f = {:.6}",
            analysis.p_success, analysis.p_failure
        )?;
        let mean = |label: &str, rate: &str, t: Option<f64>| match t {
            Some(t) => format!("{label} = {t:.3} s ({rate} = {:.6} /s)", 1.0 / t),
            None => format!("{label}: never"),
        };
        writeln!(
            out,
            "{}, {}",
            mean("E[T | success]", "mu_T", analysis.time_to_success),
            mean("E[T | failure]", "nu_T", analysis.time_to_failure)
        )?;
        writeln!(
            out,
            "{:>12}  {:>10}  {:>10}",
            "t [s]", "p_s,T(t)", "p_f,T(t)"
        )?;
        for p in &analysis.curve {
            writeln!(
                out,
                "{:>12.3}  {:>10.6}  {:>10.6}",
                p.t, p.p_success, p.p_failure
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
            writeln!(out, "wrote {}", path.display())?;
        }
    }
    Ok(())
}
