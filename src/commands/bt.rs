//! `chronomap bt check` and `chronomap bt run`: BehaviorTree.CPP 4 XML trees (seed 002 §5.2–5.3)
//! checked and printed, or ticked with leaves that follow a script of outcomes.

use std::io::Write;
use std::time::Duration;

use anyhow::{Context, Result};
use chronomap_core::bt::script::{run_script, scripted_registry};
use chronomap_core::bt::{BtDocument, NodeCategory, Registry, Status, Tree};
use chronomap_io::{BtXml, read_bt_script, read_bt_xml, write_bt_xml, write_btlog};

use crate::cli::{BtCheckArgs, BtRunArgs};

/// Reads the file with the built-in nodes and the file's own node models, printing warnings.
fn load(file: &std::path::Path) -> Result<BtDocument> {
    let BtXml { document, warnings } = read_bt_xml(file, &Registry::new())?;
    for warning in warnings {
        eprintln!("warning: {warning}");
    }
    Ok(document)
}

/// The tree to use: `--tree`, or the document's main tree.
fn instantiate(
    file: &std::path::Path,
    doc: &BtDocument,
    tree: Option<&str>,
) -> Result<(Tree, chronomap_core::bt::script::ScriptedOutcomes)> {
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
