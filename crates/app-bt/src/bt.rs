//! Behavior trees as the faces run them ([Stüde 2024] §5.2–5.3): a BehaviorTree.CPP 4 document
//! read with the node models of other files, a registry that implements every node of it
//! (leaves driven by a script of outcomes or stubbed, declared controls and decorators stubbed or
//! emulated as Nav2 does), the tree flattened depth first as it is instantiated, and the
//! stochastic behavior tree of §5.2.2 with its default horizon.
//!
//! The command line (`chronomap bt check`, `bt run`, `bt analyse`) translates flags into these
//! calls and prints what they return.

use std::collections::{BTreeMap, BTreeSet, HashSet};
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Duration;

use chronomap_bt::nav2;
use chronomap_bt::script::{
    Script, ScriptError, ScriptRun, ScriptTick, ScriptedOutcomes, run_script, run_script_with,
    scripted_registry,
};
use chronomap_bt::stochastic::from_bt;
use chronomap_bt::{
    BtDocument, DefinitionError, DefinitionErrorKind, ManifestSource, NodeCategory, NodeDef,
    NodeModel, Registry, RegistryError, Status, StubPolicy, TickMonitor, Transition, Tree, TreeDef,
    is_builtin,
};
use chronomap_bt_stochastic::{Chain, LeafParams, Means, SbtError};
use chronomap_io::{
    BtReadOptions, BtScriptError, BtXml, BtXmlError, BtXmlErrorKind, SbtParamsError,
    read_bt_script, read_bt_xml_with, read_leaf_params, read_node_models,
};
use chronomap_plot::{Panel, Series, SeriesStyle};
use serde::Serialize;
use serde_json::{Value, json};
use thiserror::Error;

use chronomap_app::report::{elide, pad_right};

/// What a stub makes of a node that chronomap does not implement.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StubBehaviour {
    /// A leaf that succeeds.
    Success,
    /// A leaf that fails.
    Failure,
    /// An action that is running for n ticks, then succeeds.
    Running(u32),
    /// A control node that ticks its children as a `Sequence`.
    Sequence,
    /// A decorator that returns its child's status.
    Pass,
    /// Nav2's node of that ID, as chronomap emulates it.
    Nav2,
}

impl StubBehaviour {
    /// Whether this is for actions and conditions.
    pub fn is_leaf(self) -> bool {
        matches!(
            self,
            StubBehaviour::Success | StubBehaviour::Failure | StubBehaviour::Running(_)
        )
    }

    /// The behaviour in words, as a run's notes give it.
    pub fn describe(self) -> String {
        match self {
            StubBehaviour::Success => "stub, SUCCESS".to_owned(),
            StubBehaviour::Failure => "stub, FAILURE".to_owned(),
            StubBehaviour::Running(n) => format!("stub, RUNNING for {n} ticks, then SUCCESS"),
            StubBehaviour::Sequence => "stub, ticks its children as a Sequence".to_owned(),
            StubBehaviour::Pass => "stub, returns its child's status".to_owned(),
            StubBehaviour::Nav2 => "Nav2's behaviour (chronomap's emulation)".to_owned(),
        }
    }
}

/// One node ID stubbed with a behaviour (`--stub ID=BEHAVIOUR` at the command line).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StubSpec {
    /// The node ID.
    pub id: String,
    /// What it does.
    pub behaviour: StubBehaviour,
}

/// Why a tree cannot be read, implemented, flattened or analysed.
#[derive(Debug, Error)]
pub enum BtJobError {
    /// What the caller asked for does not fit the document: a stub of an ID the document does
    /// not use, of an implemented node or of the wrong kind, or a declared control or
    /// decorator without one (a usage error at the command line).
    #[error("{0}")]
    Usage(String),
    /// A file cannot be read as BehaviorTree.CPP XML or node models.
    #[error(transparent)]
    Read(#[from] BtXmlError),
    /// The document uses a node no model declares (the message says how to give models
    /// declared in another file).
    #[error("{0}")]
    UnknownNode(String),
    /// The document does not say which tree to use.
    #[error("{file}: which tree? (use --tree)")]
    WhichTree {
        /// The file's name.
        file: String,
        /// Why the document has no main tree.
        #[source]
        error: DefinitionError,
    },
    /// The scripted leaves cannot be registered.
    #[error("cannot implement the leaves")]
    Leaves(#[source] RegistryError),
    /// A stub cannot be registered.
    #[error("--stub {id}")]
    Stub {
        /// The node ID.
        id: String,
        /// Why.
        #[source]
        error: RegistryError,
    },
    /// A declared control or decorator cannot be registered.
    #[error(transparent)]
    Registry(#[from] RegistryError),
    /// The document has no tree of that ID.
    #[error("there is no <BehaviorTree ID=\"{0}\">")]
    NoTree(String),
    /// The tree has more than [`MAX_FLAT_NODES`] nodes with its subtrees expanded.
    #[error("tree {0} has more than {MAX_FLAT_NODES} nodes with its subtrees expanded")]
    TooManyNodes(String),
    /// A definition error at a place in a file (`file:line:column: tree "ID": what`).
    #[error("{0}")]
    Located(String),
    /// A definition error that has no place in a file.
    #[error("{name}")]
    Definition {
        /// The file's name.
        name: String,
        /// What is wrong.
        #[source]
        error: DefinitionError,
    },
    /// The stochastic analysis cannot express the tree (the message names the node).
    #[error("{0}")]
    Stochastic(String),
    /// The Markov chain of a stochastic tree cannot be built or solved.
    #[error("{file}")]
    Chain {
        /// The file's name.
        file: String,
        /// Why.
        #[source]
        error: SbtError,
    },
    /// The outcome curve of a stochastic tree cannot be computed.
    #[error(transparent)]
    Transient(SbtError),
    /// An error of the file `name` (`NAME: error`).
    #[error("{name}")]
    InFile {
        /// The file's name.
        name: String,
        /// The error.
        #[source]
        error: Box<BtJobError>,
    },
    /// The script of outcomes cannot be read.
    #[error(transparent)]
    Script(#[from] BtScriptError),
    /// The leaf parameters cannot be read.
    #[error(transparent)]
    Params(#[from] SbtParamsError),
    /// The script does not fit the tree (`name`: the script's file, or "the run").
    #[error("{name}")]
    Run {
        /// The script's file, or "the run".
        name: String,
        /// Why.
        #[source]
        error: ScriptError,
    },
}

impl BtJobError {
    /// This error under the name of the file it concerns (`NAME: error`).
    pub fn in_file(self, name: &str) -> BtJobError {
        BtJobError::InFile {
            name: name.to_owned(),
            error: Box::new(self),
        }
    }
}

/// Reads the file (and its includes) with the built-in nodes, the files' own node models and
/// those of the `nodes` files (the first model of an ID counts); every warning goes to `warn`
/// as it is found.
///
/// # Errors
/// A file cannot be read, or the document uses a node no model declares.
pub fn load_xml(
    file: &Path,
    nodes: &[PathBuf],
    warn: &mut dyn FnMut(String),
) -> Result<BtXml, BtJobError> {
    let mut models: Vec<NodeModel> = Vec::new();
    let mut seen = HashSet::new();
    for path in nodes {
        let read = read_node_models(path)?;
        for warning in &read.warnings {
            warn(warning.to_string());
        }
        for model in read.models {
            if seen.insert(model.id.clone()) {
                models.push(model);
            } else {
                warn(format!(
                    "{}: skipped a second model of \"{}\" (an earlier --nodes file has one)",
                    path.display(),
                    model.id
                ));
            }
        }
    }
    let options = BtReadOptions::with_node_models(models);
    let xml = read_bt_xml_with(file, &Registry::new(), &options).map_err(|e| {
        let unknown = matches!(
            e.kind(),
            BtXmlErrorKind::Definition(DefinitionErrorKind::UnknownNode { .. })
        );
        if unknown && nodes.is_empty() {
            BtJobError::UnknownNode(format!(
                "{e}; node models declared in another file (such as Nav2's \
                 nav2_tree_nodes.xml) count with --nodes FILE"
            ))
        } else {
            BtJobError::Read(e)
        }
    })?;
    for warning in &xml.warnings {
        warn(warning.to_string());
    }
    Ok(xml)
}

/// The tree to use: `tree` if given, else the document's main tree.
///
/// # Errors
/// No tree is given and the document does not say which is the main one.
pub fn main_tree(file: &str, doc: &BtDocument, tree: Option<&str>) -> Result<String, BtJobError> {
    Ok(match tree {
        Some(t) => t.to_owned(),
        None => doc
            .main_tree_id()
            .map_err(|error| BtJobError::WhichTree {
                file: file.to_owned(),
                error,
            })?
            .to_owned(),
    })
}

/// How the nodes without implementation are to be run.
#[derive(Default)]
pub struct Stubs<'a> {
    /// Stubs by node ID.
    pub specs: &'a [StubSpec],
    /// The stub of every leaf that the script does not mention.
    pub all: Option<StubBehaviour>,
    /// Instance names (or IDs) the script gives outcomes to.
    pub scripted_names: BTreeSet<String>,
    /// Stub every unimplemented control as a Sequence and decorator as a pass-through
    /// without asking (for a check, which does not tick).
    pub structure_only: bool,
}

/// A registry implementing every node of a document ([`implement`]).
pub struct Implemented {
    /// The built-in nodes, the scripted leaves, the stubs and the Nav2 emulations.
    pub registry: Registry,
    /// The outcomes the scripted leaves follow.
    pub outcomes: ScriptedOutcomes,
    /// What was stubbed or emulated, one `ID: behaviour` each.
    pub notes: Vec<String>,
}

/// A registry implementing every node of `doc`: leaves by the script (or stubs), custom
/// controls and decorators by stubs or Nav2 emulations; notes on what was stubbed.
///
/// # Errors
/// [`BtJobError::Usage`] for a stub that does not fit the document or a declared control or
/// decorator without a stub; a registration that fails.
pub fn implement(doc: &BtDocument, stubs: &Stubs<'_>) -> Result<Implemented, BtJobError> {
    // The IDs used, their category, and the instance names of leaves.
    let mut used: BTreeMap<String, (NodeCategory, BTreeSet<String>)> = BTreeMap::new();
    for tree in &doc.trees {
        tree.root.walk(&mut |_, node| {
            if node.category != NodeCategory::SubTree {
                used.entry(node.id.clone())
                    .or_insert_with(|| (node.category, BTreeSet::new()))
                    .1
                    .insert(node.instance_name().to_owned());
            }
        });
    }
    let base = Registry::new();
    let mut explicit: BTreeMap<&str, StubBehaviour> = BTreeMap::new();
    for spec in stubs.specs {
        let Some((category, _)) = used.get(&spec.id) else {
            return Err(BtJobError::Usage(format!(
                "--stub {}=...: no node of the document has the ID \"{}\"",
                spec.id, spec.id
            )));
        };
        let implemented = match base.lookup(&spec.id, &[]) {
            Ok(m) => m.source != ManifestSource::Declared,
            Err(_) => false,
        };
        if implemented {
            return Err(BtJobError::Usage(format!(
                "--stub {}=...: \"{}\" is implemented by chronomap; stubs are for declared nodes",
                spec.id, spec.id
            )));
        }
        let fits = match spec.behaviour {
            StubBehaviour::Success | StubBehaviour::Failure => category.is_leaf(),
            StubBehaviour::Running(_) => *category == NodeCategory::Action,
            StubBehaviour::Sequence => *category == NodeCategory::Control,
            StubBehaviour::Pass => *category == NodeCategory::Decorator,
            StubBehaviour::Nav2 => nav2::is_emulated(&spec.id, *category),
        };
        if !fits {
            let expected = match category {
                NodeCategory::Action => "SUCCESS, FAILURE or RUNNING:n",
                NodeCategory::Condition => "SUCCESS or FAILURE (conditions do not run)",
                NodeCategory::Control if nav2::is_emulated(&spec.id, *category) => {
                    "SEQUENCE or NAV2"
                }
                NodeCategory::Control => "SEQUENCE",
                NodeCategory::Decorator if nav2::is_emulated(&spec.id, *category) => "PASS or NAV2",
                _ => "PASS",
            };
            return Err(BtJobError::Usage(format!(
                "--stub {}={:?}: \"{}\" is a {category}; its stub is {expected}",
                spec.id, spec.behaviour, spec.id
            )));
        }
        explicit.insert(spec.id.as_str(), spec.behaviour);
    }

    // Leaves: stubbed, or driven by the script.
    let mut stubbed_leaves: Vec<(String, NodeCategory, StubBehaviour)> = Vec::new();
    let mut scripted = NodeDef::control("Sequence");
    for (id, (category, names)) in &used {
        // Built-in leaves (`Script`, `UnsetBlackboard`, ...) run as they are.
        if !category.is_leaf() || base.contains(id) || is_builtin(id) {
            continue;
        }
        let behaviour = explicit.get(id.as_str()).copied().or_else(|| {
            let mentioned = stubs.scripted_names.contains(id)
                || names.iter().any(|n| stubs.scripted_names.contains(n));
            let running_condition = *category == NodeCategory::Condition
                && matches!(stubs.all, Some(StubBehaviour::Running(_)));
            stubs.all.filter(|_| !mentioned && !running_condition)
        });
        match behaviour {
            Some(b) => stubbed_leaves.push((id.clone(), *category, b)),
            None => scripted = scripted.child(NodeDef::new(*category, id)),
        }
    }
    let leaves = BtDocument {
        main_tree: None,
        trees: vec![TreeDef::new("leaves", scripted)],
        node_models: doc.node_models.clone(),
    };
    let (mut registry, outcomes) = scripted_registry(&leaves).map_err(BtJobError::Leaves)?;
    // Looked up by hash: a document may declare and use many models.
    let models = doc.node_models_by_id();
    let model_of = |id: &str, category: NodeCategory| {
        models
            .get(id)
            .filter(|m| m.category == category)
            .map(|m| (*m).clone())
            .unwrap_or_else(|| NodeModel::new(category, id))
    };
    let mut notes = Vec::new();
    for (id, category, behaviour) in &stubbed_leaves {
        let policy = match *behaviour {
            StubBehaviour::Failure => StubPolicy::Failure,
            StubBehaviour::Running(n) => StubPolicy::Running(n),
            _ => StubPolicy::Success,
        };
        registry
            .register_stub(model_of(id, *category), policy)
            .map_err(|error| BtJobError::Stub {
                id: id.clone(),
                error,
            })?;
        notes.push(format!("{id}: {}", behaviour.describe()));
    }

    // Custom controls and decorators that are declared but not implemented.
    for (id, (category, _)) in &used {
        if category.is_leaf() || registry.contains(id) {
            continue;
        }
        let declared = models.get(id.as_str()).map(|m| std::slice::from_ref(*m));
        match base.lookup(id, declared.unwrap_or_default()) {
            Ok(m) if m.source == ManifestSource::Declared => {}
            _ => continue, // built in (or unknown: validation says so)
        }
        let model = model_of(id, *category);
        let behaviour = match explicit.get(id.as_str()) {
            Some(&b) => b,
            None if nav2::is_emulated(id, *category) => StubBehaviour::Nav2,
            None if stubs.structure_only => match category {
                NodeCategory::Control => StubBehaviour::Sequence,
                _ => StubBehaviour::Pass,
            },
            None => {
                let suggestion = match category {
                    NodeCategory::Control => "SEQUENCE",
                    _ => "PASS",
                };
                return Err(BtJobError::Usage(format!(
                    "{category} \"{id}\" is declared but chronomap has no implementation of it: \
                     give --stub {id}={suggestion}"
                )));
            }
        };
        match behaviour {
            StubBehaviour::Nav2 => nav2::register(&mut registry, &model)?,
            _ => registry.register_stub(model, StubPolicy::Success)?,
        }
        if !stubs.structure_only {
            notes.push(format!("{id}: {}", behaviour.describe()));
        }
    }
    Ok(Implemented {
        registry,
        outcomes,
        notes,
    })
}

/// One node of the tree to execute, depth first with subtrees expanded (uids as in
/// [`chronomap_bt::Tree`]).
pub struct Flat<'d> {
    /// The node's uid (its index + 1).
    pub uid: usize,
    /// The node as the document describes it.
    pub node: &'d NodeDef,
    /// Its depth below the root (0).
    pub depth: usize,
    /// The uids of its children (of the expanded tree, for a subtree node).
    pub children: Vec<usize>,
}

/// The most nodes [`flatten`] gives once subtrees are expanded.
pub const MAX_FLAT_NODES: usize = 2_000_000;

/// The nodes of tree `id` depth first, subtrees expanded, without recursion.
///
/// # Errors
/// There is no tree `id`, or it has more than [`MAX_FLAT_NODES`] nodes expanded.
pub fn flatten<'d>(doc: &'d BtDocument, id: &str) -> Result<Vec<Flat<'d>>, BtJobError> {
    let tree = doc
        .tree(id)
        .ok_or_else(|| BtJobError::NoTree(id.to_owned()))?;
    let trees = doc.trees_by_id();
    let mut out: Vec<Flat<'d>> = Vec::new();
    let mut stack: Vec<(&NodeDef, usize, Option<usize>)> = vec![(&tree.root, 0, None)];
    while let Some((node, depth, parent)) = stack.pop() {
        if out.len() == MAX_FLAT_NODES {
            return Err(BtJobError::TooManyNodes(id.to_owned()));
        }
        let index = out.len();
        out.push(Flat {
            uid: index + 1,
            node,
            depth,
            children: Vec::new(),
        });
        if let Some(p) = parent {
            out[p].children.push(index + 1);
        }
        if node.category == NodeCategory::SubTree {
            if let Some(sub) = trees.get(node.id.as_str()) {
                stack.push((&sub.root, depth + 1, Some(index)));
            }
        } else {
            for child in node.children.iter().rev() {
                stack.push((child, depth + 1, Some(index)));
            }
        }
    }
    Ok(out)
}

/// An error of instantiation at the file, line and column of the node concerned (in the file
/// that node is in), else after the file's `name`.
pub fn located(xml: &BtXml, e: &DefinitionError, name: &str) -> BtJobError {
    match e.location().and_then(|l| Some((l, xml.locate(l)?))) {
        Some((l, (file, line, column))) => BtJobError::Located(format!(
            "{file}:{line}:{column}: tree \"{}\": {}",
            l.tree,
            e.kind()
        )),
        None => BtJobError::Definition {
            name: name.to_owned(),
            error: e.clone(),
        },
    }
}

/// The Markov chain of tree `tree_id` of `xml` as a stochastic behavior tree (§5.2.2), its
/// leaves parameterised by `params`; `file` names the document in errors.
///
/// # Errors
/// The tree has a node the analysis cannot express or a leaf without parameters (located in
/// its file where possible), or the chain cannot be built.
pub fn stochastic_chain(
    xml: &BtXml,
    file: &str,
    tree_id: &str,
    params: &BTreeMap<String, LeafParams>,
) -> Result<Chain, BtJobError> {
    let tree = from_bt(&xml.document, tree_id, params).map_err(|e| {
        BtJobError::Stochastic(match xml.locate(&e.location) {
            Some((at, line, column)) => format!("{at}:{line}:{column}: {}", e.kind),
            None => format!("{file}: {e}"),
        })
    })?;
    tree.chain().map_err(|error| BtJobError::Chain {
        file: file.to_owned(),
        error,
    })
}

/// The horizon of the outcome curve when none is given: three times the longer of the mean
/// times to success and to failure (eqs. 5.3–5.4), or 1 s when neither outcome takes time.
pub fn default_t_max(means: &Means) -> f64 {
    let longest = [means.time_to_success, means.time_to_failure]
        .into_iter()
        .flatten()
        .fold(0.0, f64::max);
    if longest > 0.0 { 3.0 * longest } else { 1.0 }
}

/// `steps + 1` times evenly from 0 to `t_max`, both included.
pub fn curve_times(t_max: f64, steps: u32) -> Vec<f64> {
    (0..=steps)
        .map(|i| t_max * f64::from(i) / f64::from(steps))
        .collect()
}

/// A node as `chronomap bt check` reports it.
#[derive(Clone, Debug, Serialize)]
pub struct CheckedNode {
    /// Its uid (depth first from 1, as [`chronomap_bt::Tree`] numbers them).
    pub uid: usize,
    /// Its ID.
    pub id: String,
    /// Its instance name (the ID when it has none).
    pub name: String,
    /// Action, Condition, Control, Decorator or SubTree.
    pub category: String,
    /// Its depth below the root (0).
    pub depth: usize,
    /// Its ports and scripts.
    pub attributes: BTreeMap<String, String>,
    /// The uids of its children.
    pub children: Vec<usize>,
    /// The line `bt check` prints for it, after the uid and indentation.
    #[serde(skip)]
    pub label: String,
}

impl CheckedNode {
    fn of(flat: &Flat<'_>) -> Self {
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
        CheckedNode {
            uid: flat.uid,
            id: node.id.clone(),
            name: node.instance_name().to_owned(),
            category: node.category.to_string(),
            depth: flat.depth,
            attributes: node
                .ports
                .iter()
                .chain(&node.scripts)
                .map(|(k, v)| (k.clone(), v.clone()))
                .collect(),
            children: flat.children.clone(),
            label,
        }
    }
}

/// What `chronomap bt check` reports: the trees of a BehaviorTree.CPP 4 document and the
/// nodes of the one to execute, depth first (serialises as its `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct CheckReport {
    /// The file's name.
    pub file: String,
    /// The BehaviorTree.CPP format (4).
    pub format: u32,
    /// The IDs of the document's trees.
    pub trees: Vec<String>,
    /// The tree to execute.
    pub tree: String,
    /// Its leaves.
    pub leaves: usize,
    /// Its nodes with subtrees expanded.
    pub nodes: Vec<CheckedNode>,
    /// The canonical XML written, if any (set by the caller that writes it).
    pub output: Option<String>,
}

/// Reads and checks `file` as `chronomap bt check` does: with the node models of `nodes`,
/// every node instantiated (custom controls and decorators stubbed, [`Stubs::structure_only`])
/// and validated as BehaviorTree.CPP would before it ticks ([`chronomap_bt::validate_strict`]);
/// `tree` or the main tree flattened. Warnings (read, and a tree too large for `bt run` and
/// Groot2's 16-bit uids) go to `warn`.
///
/// # Errors
/// A file that cannot be read, a tree that cannot be instantiated (located in its file).
pub fn check(
    file: &Path,
    nodes: &[PathBuf],
    tree: Option<&str>,
    warn: &mut dyn FnMut(String),
) -> Result<(BtXml, CheckReport), BtJobError> {
    let xml = load_xml(file, nodes, warn)?;
    let doc = &xml.document;
    let name = file.display().to_string();
    let main = main_tree(&name, doc, tree)?;
    let stubs = Stubs {
        structure_only: true,
        ..Stubs::default()
    };
    let registry = implement(doc, &stubs)
        .map_err(|e| e.in_file(&name))?
        .registry;
    // What BehaviorTree.CPP refuses only when it ticks the node is reported here, before
    // anything runs (`bt run` raises it at the tick, as BehaviorTree.CPP does).
    chronomap_bt::validate_strict(doc, &registry).map_err(|e| located(&xml, &e, &name))?;
    if let Err(e) = Tree::with_main(doc, &main, &registry) {
        if *e.kind() == DefinitionErrorKind::TooManyNodes {
            warn(format!(
                "{name}: tree {main} has more than 65535 nodes: `bt run` and Groot2 logs take \
                 at most 65535 (uids are 16-bit)"
            ));
        } else {
            return Err(located(&xml, &e, &name));
        }
    }
    let flat = flatten(doc, &main).map_err(|e| e.in_file(&name))?;
    let report = CheckReport {
        file: name,
        format: 4,
        trees: doc.trees.iter().map(|t| t.id.clone()).collect(),
        tree: main,
        leaves: flat.iter().filter(|n| n.node.category.is_leaf()).count(),
        nodes: flat.iter().map(CheckedNode::of).collect(),
        output: None,
    };
    Ok((xml, report))
}

impl fmt::Display for CheckReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}: BehaviorTree.CPP 4, {} tree{} ({}); {} has {} nodes, {} of them leaves",
            self.file,
            self.trees.len(),
            if self.trees.len() == 1 { "" } else { "s" },
            self.trees.join(", "),
            self.tree,
            self.nodes.len(),
            self.leaves
        )?;
        writeln!(f, " uid  node")?;
        for node in &self.nodes {
            writeln!(
                f,
                "{:>4}  {}{}",
                node.uid,
                "  ".repeat(node.depth),
                node.label
            )?;
        }
        if let Some(path) = &self.output {
            writeln!(f, "wrote {path} (canonical BehaviorTree.CPP 4 XML)")?;
        }
        Ok(())
    }
}

/// What `chronomap bt run` is given: the file, its node models, the script (or a number of
/// ticks), the stubs, enum values and the tree.
#[derive(Clone, Copy, Debug)]
pub struct RunSetup<'a> {
    /// The BehaviorTree.CPP 4 XML file.
    pub file: &'a Path,
    /// Files of node models.
    pub nodes: &'a [PathBuf],
    /// The script of outcomes, if any.
    pub script: Option<&'a Path>,
    /// Ticks without a script (default 100).
    pub ticks: Option<u64>,
    /// Stubs by node ID.
    pub stubs: &'a [StubSpec],
    /// The stub of every leaf the script does not mention.
    pub stub_all: Option<StubBehaviour>,
    /// Enum values registered for scripts (`NAME=VALUE`).
    pub enums: &'a [(String, i64)],
    /// The tree to execute (default: the main tree).
    pub tree: Option<&'a str>,
}

/// A tree instantiated and ready to run its script ([`prepare_run`]).
pub struct PreparedRun {
    /// The document read.
    pub xml: BtXml,
    /// The tree to execute.
    pub tree: Tree,
    /// The outcomes the scripted leaves follow.
    pub outcomes: ScriptedOutcomes,
    /// The script.
    pub script: Script,
    /// What was stubbed or emulated, one `ID: behaviour` each.
    pub notes: Vec<String>,
    file: String,
    script_file: Option<String>,
}

/// Reads the document and the script of `setup`, implements every node (scripted leaves,
/// stubs, Nav2 emulations, [`implement`]) and instantiates the tree; read warnings go to
/// `warn`.
///
/// # Errors
/// A file that cannot be read, a stub that does not fit ([`BtJobError::Usage`]), a tree that
/// cannot be instantiated.
pub fn prepare_run(
    setup: &RunSetup<'_>,
    warn: &mut dyn FnMut(String),
) -> Result<PreparedRun, BtJobError> {
    let xml = load_xml(setup.file, setup.nodes, warn)?;
    let script = match setup.script {
        Some(path) => read_bt_script(path)?,
        None => Script {
            ticks: vec![ScriptTick::new(setup.ticks.unwrap_or(100))],
        },
    };
    let stubs = Stubs {
        specs: setup.stubs,
        all: setup.stub_all,
        scripted_names: script
            .ticks
            .iter()
            .flat_map(|t| t.outcomes.iter().map(|(name, _)| name.clone()))
            .collect(),
        structure_only: false,
    };
    let file = setup.file.display().to_string();
    let Implemented {
        mut registry,
        outcomes,
        notes,
    } = implement(&xml.document, &stubs).map_err(|e| e.in_file(&file))?;
    for (enum_name, value) in setup.enums {
        registry.register_enum(enum_name, *value);
    }
    let main = main_tree(&file, &xml.document, setup.tree)?;
    let tree =
        Tree::with_main(&xml.document, &main, &registry).map_err(|e| located(&xml, &e, &file))?;
    Ok(PreparedRun {
        xml,
        tree,
        outcomes,
        script,
        notes,
        file,
        script_file: setup.script.map(|p| p.display().to_string()),
    })
}

/// A run in real time (`bt run --groot2`/`--tick-period`): a pause before each tick, a monitor
/// of the ticks (a Groot2 server's breakpoints hold the run's thread) and a hook after each.
pub struct Pacing<'a> {
    /// The wall-clock pause before each tick.
    pub pause: Duration,
    /// Watches the ticks while the run lasts.
    pub monitor: Option<Box<dyn TickMonitor>>,
    /// Called after each tick with the tree, its document and the tick's transitions.
    pub after_tick: &'a mut dyn FnMut(&Tree, &BtDocument, &[Transition]),
}

/// A transition as `bt run` reports it.
#[derive(Clone, Debug, Serialize)]
pub struct TransitionReport {
    /// The node's uid.
    pub uid: u16,
    /// Its name.
    pub name: String,
    /// The status before.
    pub from: String,
    /// The status after.
    pub to: String,
    /// Whether the node was halted (RUNNING to IDLE).
    #[serde(skip)]
    pub halted: bool,
}

/// A tick as `bt run` reports it.
#[derive(Clone, Debug, Serialize)]
pub struct TickReport {
    /// The tick's number.
    pub tick: u64,
    /// Its time since the start (milliseconds).
    pub time_ms: u64,
    /// The root's status after it.
    pub status: String,
    /// The nodes whose status changed.
    pub transitions: Vec<TransitionReport>,
}

/// The tick at which a run failed.
#[derive(Clone, Debug, Serialize)]
pub struct RunFailure {
    /// The tick's number.
    pub tick: u64,
    /// Its time since the start (milliseconds).
    pub time_ms: u64,
    /// What went wrong.
    pub message: String,
    /// The nodes whose status changed before.
    pub transitions: Vec<TransitionReport>,
}

/// What `chronomap bt run` reports: every tick with its transitions, the end, the blackboard
/// (serialises as its `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct RunReport {
    /// The file run.
    pub file: String,
    /// The script file, if any.
    pub script: Option<String>,
    /// What was stubbed or emulated.
    pub stubs: Vec<String>,
    /// The tree run.
    pub tree: String,
    /// Whether the tree finished.
    pub finished: bool,
    /// The root's status after the last tick.
    pub status: Option<String>,
    /// The last tick's number.
    pub last_tick: Option<u64>,
    /// The last tick's time (milliseconds).
    pub last_time_ms: Option<u64>,
    /// Script ticks never reached because the tree finished before.
    pub unused_ticks: Vec<u64>,
    /// The ticks.
    pub ticks: Vec<TickReport>,
    /// The tick that failed, if any.
    pub error: Option<RunFailure>,
    /// The root blackboard's entries.
    pub blackboard: serde_json::Map<String, Value>,
    /// Transitions in all.
    pub transitions: usize,
    /// The Groot2 log written, if any (set by the caller that writes it).
    pub btlog: Option<String>,
    /// Every transition, in order (for a Groot2 log).
    #[serde(skip)]
    pub recorded: Vec<Transition>,
    /// Nodes of the tree.
    #[serde(skip)]
    pub node_count: usize,
    /// `SCRIPT: tick N: why` when a tick failed.
    #[serde(skip)]
    failure: Option<String>,
    /// The width of the name column of the text.
    #[serde(skip)]
    width: usize,
}

/// A blackboard value as JSON: numbers and booleans as themselves, text as a string, a queue
/// as an array.
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

impl PreparedRun {
    /// Runs the script ([`run_script_with`]), `period` of simulated time a tick, in real
    /// time with `pacing` if given.
    ///
    /// # Errors
    /// [`BtJobError::Run`] naming the script (or "the run") when the script does not fit the
    /// tree; a tick that fails is reported in [`RunReport::error`] instead.
    pub fn run(
        &mut self,
        period: Duration,
        pacing: Option<Pacing<'_>>,
    ) -> Result<RunReport, BtJobError> {
        let run = match pacing {
            Some(Pacing {
                pause,
                monitor,
                after_tick,
            }) => {
                let watched = monitor.is_some();
                if watched {
                    self.tree.set_tick_monitor(monitor);
                }
                let doc = &self.xml.document;
                let run = run_script_with(
                    &mut self.tree,
                    &self.outcomes,
                    &self.script,
                    period,
                    &mut || std::thread::sleep(pause),
                    &mut |tree, transitions| after_tick(tree, doc, transitions),
                );
                self.tree.set_tick_monitor(None);
                run
            }
            None => run_script(&mut self.tree, &self.outcomes, &self.script, period),
        };
        let script_name = self
            .script_file
            .clone()
            .unwrap_or_else(|| "the run".to_owned());
        let run = run.map_err(|error| BtJobError::Run {
            name: script_name.clone(),
            error,
        })?;
        Ok(self.report(&run, &script_name))
    }

    fn report(&self, run: &ScriptRun, script_name: &str) -> RunReport {
        let tree = &self.tree;
        let name_of = |uid: u16| tree.node(uid).map_or("?", |n| n.name());
        let transitions = |list: &[Transition]| -> Vec<TransitionReport> {
            list.iter()
                .map(|t| TransitionReport {
                    uid: t.uid,
                    name: name_of(t.uid).to_owned(),
                    from: t.from.to_string(),
                    to: t.to.to_string(),
                    halted: t.from == Status::Running && t.to == Status::Idle,
                })
                .collect()
        };
        let failed = run.failure.as_ref();
        let recorded: Vec<Transition> = run
            .ticks
            .iter()
            .flat_map(|t| t.transitions.iter().copied())
            .chain(failed.iter().flat_map(|f| f.transitions.iter().copied()))
            .collect();
        let last = run.ticks.last();
        let board = tree.blackboard();
        RunReport {
            file: self.file.clone(),
            script: self.script_file.clone(),
            stubs: self.notes.clone(),
            tree: tree.subtrees()[0].tree_id.clone(),
            finished: run.finished,
            status: last.map(|t| t.status.to_string()),
            last_tick: last.map(|t| t.tick),
            last_time_ms: last.map(|t| t.time.as_millis() as u64),
            unused_ticks: run.unused.clone(),
            ticks: run
                .ticks
                .iter()
                .map(|tick| TickReport {
                    tick: tick.tick,
                    time_ms: tick.time.as_millis() as u64,
                    status: tick.status.to_string(),
                    transitions: transitions(&tick.transitions),
                })
                .collect(),
            error: failed.map(|f| RunFailure {
                tick: f.tick,
                time_ms: f.time.as_millis() as u64,
                message: f.error.to_string(),
                transitions: transitions(&f.transitions),
            }),
            blackboard: board
                .entries(board.root())
                .map(|(key, value)| (key.to_owned(), blackboard_json(value)))
                .collect(),
            transitions: recorded.len(),
            btlog: None,
            failure: failed.map(|f| format!("{script_name}: tick {}: {}", f.tick, f.error)),
            recorded,
            node_count: tree.nodes().len(),
            width: tree
                .nodes()
                .iter()
                .map(|n| elide(n.name()).chars().count())
                .max()
                .unwrap_or(0),
        }
    }
}

impl RunReport {
    /// The error the run fails with, if a tick failed: `SCRIPT: tick N: why`.
    pub fn failure(&self) -> Option<&str> {
        self.failure.as_deref()
    }

    fn transitions_text(
        &self,
        f: &mut fmt::Formatter<'_>,
        list: &[TransitionReport],
    ) -> fmt::Result {
        for t in list {
            // A name from the XML may be longer than a format width can pad (65,535).
            let name = pad_right(&elide(&t.name), self.width);
            let halted = if t.halted { " (halted)" } else { "" };
            writeln!(f, "  {:>3} {name}  {} -> {}{halted}", t.uid, t.from, t.to)?;
        }
        Ok(())
    }
}

impl fmt::Display for RunReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for tick in &self.ticks {
            writeln!(
                f,
                "tick {} @ {} ms: {}",
                tick.tick, tick.time_ms, tick.status
            )?;
            self.transitions_text(f, &tick.transitions)?;
        }
        if let Some(failure) = &self.error {
            writeln!(f, "tick {} @ {} ms: error", failure.tick, failure.time_ms)?;
            return self.transitions_text(f, &failure.transitions);
        }
        if let Some(last) = self.ticks.last() {
            if self.finished {
                writeln!(
                    f,
                    "result: {} at tick {} ({} ms)",
                    last.status, last.tick, last.time_ms
                )?;
            } else {
                writeln!(
                    f,
                    "result: still RUNNING after tick {} ({} ms)",
                    last.tick, last.time_ms
                )?;
            }
        }
        if self.script.is_some() && !self.unused_ticks.is_empty() {
            let unused: Vec<String> = self.unused_ticks.iter().map(u64::to_string).collect();
            writeln!(
                f,
                "note: the tree finished before script tick{} {}",
                if unused.len() == 1 { "" } else { "s" },
                unused.join(", ")
            )?;
        }
        if let Some(path) = &self.btlog {
            writeln!(
                f,
                "wrote {path} ({} transitions of {} nodes)",
                self.transitions, self.node_count
            )?;
        }
        Ok(())
    }
}

/// A point of the outcome curve of a stochastic behavior tree.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct CurvePoint {
    /// Seconds since the tree started.
    pub t: f64,
    /// Probability that it has succeeded by then, `p_s,T(t)`.
    pub p_success: f64,
    /// Probability that it has failed by then, `p_f,T(t)`.
    pub p_failure: f64,
}

/// What `chronomap bt analyse` reports: a tree as a stochastic behavior tree ([Stüde 2024]
/// §5.2.2), its eventual outcome, mean times (eqs. 5.3–5.4) and outcome curve (eq. 5.1)
/// (serialises as its `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct Analysis {
    /// The file's name.
    pub file: String,
    /// The tree analysed.
    pub tree: String,
    /// Transient states of the Markov chain.
    pub states: usize,
    /// Probability that the tree eventually succeeds.
    pub p_success: f64,
    /// Probability that it eventually fails.
    pub p_failure: f64,
    /// Mean time to success, given success (seconds); `None`: never.
    pub time_to_success: Option<f64>,
    /// Mean time to failure, given failure (seconds); `None`: never.
    pub time_to_failure: Option<f64>,
    /// The success rate `mu_T` = 1 / mean time to success.
    pub mu_t: Option<f64>,
    /// The failure rate `nu_T` = 1 / mean time to failure.
    pub nu_t: Option<f64>,
    /// The largest error bound of the uniformisation over the curve.
    pub error_bound: f64,
    /// The outcome curve at the times asked for.
    pub curve: Vec<CurvePoint>,
    /// Rows of leaf parameters read.
    #[serde(skip)]
    pub leaf_rows: usize,
    /// The curve at 201 times for a figure, when asked for.
    #[serde(skip)]
    pub fine_curve: Vec<CurvePoint>,
}

/// The tolerance of the uniformisation of [`analyse`].
const TOLERANCE: f64 = 1e-12;

/// Analyses tree `tree` (default: the main tree) of `file` (with the node models of `nodes`)
/// as a stochastic behavior tree with the leaf parameters of `params` ([Stüde 2024] §5.2.2):
/// eq. 5.1 by uniformisation at `steps + 1` times up to `t_max` (default [`default_t_max`]),
/// and the exact mean times that replace the averaged rates of eqs. 5.3–5.4; with `fine`,
/// also the curve at 201 times for a figure. Read warnings go to `warn`.
///
/// # Errors
/// A file that cannot be read, a tree the analysis cannot express, a chain that cannot be
/// built or solved.
pub fn analyse(
    (file, nodes, params): (&Path, &[PathBuf], &Path),
    tree: Option<&str>,
    (t_max, steps, fine): (Option<f64>, u32, bool),
    warn: &mut dyn FnMut(String),
) -> Result<Analysis, BtJobError> {
    let name = file.display().to_string();
    let xml = load_xml(file, nodes, warn)?;
    let params = read_leaf_params(params)?;
    let tree_id = main_tree(&name, &xml.document, tree)?;
    let chain = stochastic_chain(&xml, &name, &tree_id, &params)?;
    let means = chain.means();
    let t_max = t_max.unwrap_or_else(|| default_t_max(&means));
    let curve_at = |times: &[f64]| -> Result<Vec<(CurvePoint, f64)>, BtJobError> {
        let outcomes = chain
            .transient(times, TOLERANCE)
            .map_err(BtJobError::Transient)?;
        Ok(times
            .iter()
            .zip(outcomes)
            .map(|(&t, o)| {
                (
                    CurvePoint {
                        t,
                        p_success: o.p_success,
                        p_failure: o.p_failure,
                    },
                    o.error_bound,
                )
            })
            .collect())
    };
    let curve = curve_at(&curve_times(t_max, steps))?;
    let fine_curve = if fine {
        curve_at(&curve_times(t_max, 200))?
            .into_iter()
            .map(|(p, _)| p)
            .collect()
    } else {
        Vec::new()
    };
    Ok(Analysis {
        file: name,
        tree: tree_id,
        states: chain.states(),
        p_success: means.p_success,
        p_failure: means.p_failure,
        time_to_success: means.time_to_success,
        time_to_failure: means.time_to_failure,
        mu_t: means.time_to_success.map(|t| 1.0 / t),
        nu_t: means.time_to_failure.map(|t| 1.0 / t),
        error_bound: curve.iter().map(|(_, e)| *e).fold(0.0, f64::max),
        curve: curve.into_iter().map(|(p, _)| p).collect(),
        leaf_rows: params.len(),
        fine_curve,
    })
}

impl Analysis {
    /// The outcome curves for a figure ([`Analysis::fine_curve`]).
    pub fn panel(&self) -> Panel {
        let series = |label: &str, pick: fn(&CurvePoint) -> f64| Series {
            label: label.to_owned(),
            points: self.fine_curve.iter().map(|p| (p.t, pick(p))).collect(),
            style: SeriesStyle::Line,
        };
        Panel {
            title: format!("{}: stochastic behavior tree (eq. 5.1)", self.tree),
            x_label: "t [s] since the tree started".to_owned(),
            y_label: "probability".to_owned(),
            y_range: (0.0, 1.0),
            series: vec![
                series("p_s,T(t)", |p| p.p_success),
                series("p_f,T(t)", |p| p.p_failure),
            ],
        }
    }
}

impl fmt::Display for Analysis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}: tree {} as a stochastic behavior tree (§5.2.2): {} transient states, \
             {} leaf parameter rows",
            self.file, self.tree, self.states, self.leaf_rows
        )?;
        writeln!(
            f,
            "eventually: p_s = {:.6}, p_f = {:.6}",
            self.p_success, self.p_failure
        )?;
        let mean = |label: &str, rate: &str, t: Option<f64>| match t {
            Some(t) => format!("{label} = {t:.3} s ({rate} = {:.6} /s)", 1.0 / t),
            None => format!("{label}: never"),
        };
        writeln!(
            f,
            "{}, {}",
            mean("E[T | success]", "mu_T", self.time_to_success),
            mean("E[T | failure]", "nu_T", self.time_to_failure)
        )?;
        writeln!(f, "{:>12}  {:>10}  {:>10}", "t [s]", "p_s,T(t)", "p_f,T(t)")?;
        for p in &self.curve {
            writeln!(
                f,
                "{:>12.3}  {:>10.6}  {:>10.6}",
                p.t, p.p_success, p.p_failure
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn means(success: Option<f64>, failure: Option<f64>) -> Means {
        Means {
            p_success: 0.5,
            p_failure: 0.5,
            time_to_success: success,
            time_to_failure: failure,
        }
    }

    #[test]
    fn the_default_horizon_is_three_times_the_longer_mean_time() {
        assert_eq!(default_t_max(&means(Some(2.0), Some(5.0))), 15.0);
        assert_eq!(default_t_max(&means(Some(4.0), None)), 12.0);
        assert_eq!(default_t_max(&means(None, None)), 1.0);
        assert_eq!(default_t_max(&means(Some(0.0), Some(0.0))), 1.0);
    }

    #[test]
    fn curve_times_run_from_zero_to_the_horizon() {
        assert_eq!(curve_times(10.0, 4), [0.0, 2.5, 5.0, 7.5, 10.0]);
    }

    /// A document of one tree: a Sequence of a declared action `Go` and a declared control
    /// `Around` holding a condition `Near`.
    fn document() -> BtDocument {
        let root = NodeDef::control("Sequence")
            .child(NodeDef::new(NodeCategory::Action, "Go"))
            .child(
                NodeDef::new(NodeCategory::Control, "Around")
                    .child(NodeDef::new(NodeCategory::Condition, "Near")),
            );
        BtDocument {
            main_tree: Some("main".into()),
            trees: vec![TreeDef::new("main", root)],
            node_models: vec![
                NodeModel::new(NodeCategory::Action, "Go"),
                NodeModel::new(NodeCategory::Control, "Around"),
                NodeModel::new(NodeCategory::Condition, "Near"),
            ],
        }
    }

    fn usage_of(result: Result<Implemented, BtJobError>) -> String {
        match result {
            Err(BtJobError::Usage(m)) => m,
            Err(e) => panic!("not a usage error: {e}"),
            Ok(_) => panic!("no error"),
        }
    }

    #[test]
    fn a_declared_control_needs_a_stub_unless_only_the_structure_counts() {
        let doc = document();
        assert_eq!(
            usage_of(implement(&doc, &Stubs::default())),
            "Control \"Around\" is declared but chronomap has no implementation of it: \
             give --stub Around=SEQUENCE"
        );
        let structure = Stubs {
            structure_only: true,
            ..Stubs::default()
        };
        let implemented = implement(&doc, &structure).unwrap();
        assert!(implemented.registry.contains("Around"));
        assert!(implemented.notes.is_empty());
    }

    #[test]
    fn stubs_are_checked_against_the_document_and_noted() {
        let doc = document();
        let stub = |id: &str, behaviour| {
            vec![StubSpec {
                id: id.into(),
                behaviour,
            }]
        };
        let missing = stub("Fly", StubBehaviour::Success);
        assert_eq!(
            usage_of(implement(
                &doc,
                &Stubs {
                    specs: &missing,
                    ..Stubs::default()
                }
            )),
            "--stub Fly=...: no node of the document has the ID \"Fly\""
        );
        let wrong = stub("Near", StubBehaviour::Running(2));
        assert_eq!(
            usage_of(implement(
                &doc,
                &Stubs {
                    specs: &wrong,
                    ..Stubs::default()
                }
            )),
            "--stub Near=Running(2): \"Near\" is a Condition; its stub is SUCCESS or FAILURE \
             (conditions do not run)"
        );
        let specs = [
            StubSpec {
                id: "Around".into(),
                behaviour: StubBehaviour::Sequence,
            },
            StubSpec {
                id: "Go".into(),
                behaviour: StubBehaviour::Running(3),
            },
        ];
        let implemented = implement(
            &doc,
            &Stubs {
                specs: &specs,
                ..Stubs::default()
            },
        )
        .unwrap();
        assert_eq!(
            implemented.notes,
            [
                "Go: stub, RUNNING for 3 ticks, then SUCCESS",
                "Around: stub, ticks its children as a Sequence"
            ]
        );
    }

    #[test]
    fn flatten_numbers_nodes_depth_first() {
        let doc = document();
        let flat = flatten(&doc, "main").unwrap();
        let rows: Vec<(usize, &str, usize, Vec<usize>)> = flat
            .iter()
            .map(|f| (f.uid, f.node.id.as_str(), f.depth, f.children.clone()))
            .collect();
        assert_eq!(
            rows,
            [
                (1, "Sequence", 0, vec![2, 3]),
                (2, "Go", 1, vec![]),
                (3, "Around", 1, vec![4]),
                (4, "Near", 2, vec![]),
            ]
        );
        assert_eq!(
            flatten(&doc, "other").err().unwrap().to_string(),
            "there is no <BehaviorTree ID=\"other\">"
        );
    }

    #[test]
    fn check_reports_the_door_tree_depth_first_through_the_subtree() {
        let door = chronomap_testutil::repo_path("tests/data/bt/door.xml");
        let mut warnings = Vec::new();
        let (xml, report) = check(&door, &[], None, &mut |w| warnings.push(w)).unwrap();
        assert!(warnings.is_empty(), "{warnings:?}");
        assert_eq!(xml.document.trees.len(), 2);
        assert_eq!(report.trees, ["MainTree", "DoorClosed"]);
        assert_eq!((report.nodes.len(), report.leaves), (11, 5));
        let lock = &report.nodes[8];
        assert_eq!((lock.uid, lock.id.as_str(), lock.depth), (9, "PickLock", 5));
        assert_eq!(lock.attributes["door"], "{door}");
        assert_eq!(report.nodes[0].children, [2, 11]);
        let text = report.to_string();
        assert!(
            text.starts_with(&format!(
                "{}: BehaviorTree.CPP 4, 2 trees (MainTree, DoorClosed); MainTree has 11 nodes, \
                 5 of them leaves\n uid  node\n   1  Sequence \"cross_door\"\n",
                door.display()
            )),
            "{text}"
        );
        assert!(text.contains("\n   5      SubTree DoorClosed \"open_it\" door={door}\n"));
        assert!(text.ends_with("  11    PassThroughDoor (Action) door={door}\n"));
    }

    #[test]
    fn the_door_script_runs_to_success_at_tick_5() {
        let door = chronomap_testutil::repo_path("tests/data/bt/door.xml");
        let script = chronomap_testutil::repo_path("tests/data/bt/door.script");
        let setup = RunSetup {
            file: &door,
            nodes: &[],
            script: Some(&script),
            ticks: None,
            stubs: &[],
            stub_all: None,
            enums: &[],
            tree: None,
        };
        let mut prepared = prepare_run(&setup, &mut |_| {}).unwrap();
        let report = prepared.run(Duration::from_millis(100), None).unwrap();
        // Ticks 1-3 every 100 ms, tick 4 at 1000 ms as the script says, tick 5 100 ms later.
        let ticks: Vec<(u64, u64, &str)> = report
            .ticks
            .iter()
            .map(|t| (t.tick, t.time_ms, t.status.as_str()))
            .collect();
        assert_eq!(
            ticks,
            [
                (1, 0, "RUNNING"),
                (2, 100, "RUNNING"),
                (3, 200, "RUNNING"),
                (4, 1000, "RUNNING"),
                (5, 1100, "SUCCESS")
            ]
        );
        assert!(report.finished && report.failure().is_none());
        assert_eq!(report.transitions, report.recorded.len());
        let text = report.to_string();
        assert!(text.starts_with("tick 1 @ 0 ms: RUNNING\n"), "{text}");
        assert!(
            text.ends_with("result: SUCCESS at tick 5 (1100 ms)\n"),
            "{text}"
        );
    }

    #[test]
    fn the_stochastic_door_has_a_curve_from_zero() {
        let door = chronomap_testutil::repo_path("tests/data/bt/door.xml");
        let params = chronomap_testutil::repo_path("tests/data/bt/door_sbt.csv");
        let analysis = analyse(
            (&door, &[], &params),
            None,
            (Some(10.0), 4, true),
            &mut |_| {},
        )
        .unwrap();
        assert_eq!(analysis.tree, "MainTree");
        let times: Vec<f64> = analysis.curve.iter().map(|p| p.t).collect();
        assert_eq!(times, [0.0, 2.5, 5.0, 7.5, 10.0]);
        // Nothing has happened at t = 0; eventually the tree succeeds or fails.
        assert_eq!(
            (analysis.curve[0].p_success, analysis.curve[0].p_failure),
            (0.0, 0.0)
        );
        // Hand-computed in tests/cli/bt.rs: the lock opens with 1 - 0.6 · 0.5³ · 0.2 = 0.985,
        // the fallback succeeds with 0.3 + 0.7 · 0.985 = 0.9895, the sequence with
        // 0.9895 · 0.95.
        assert!((analysis.p_success - 0.940025).abs() < 1e-12);
        assert!((analysis.p_failure - 0.059975).abs() < 1e-12);
        assert_eq!(analysis.fine_curve.len(), 201);
        assert_eq!(analysis.panel().series.len(), 2);
        let text = analysis.to_string();
        assert!(
            text.contains("\neventually: p_s = 0.940025, p_f = 0.059975\n"),
            "{text}"
        );
        assert!(
            text.contains("\n       t [s]    p_s,T(t)    p_f,T(t)\n"),
            "{text}"
        );
        assert!(text.ends_with(&format!(
            "      10.000  {:>10.6}  {:>10.6}\n",
            analysis.curve[4].p_success, analysis.curve[4].p_failure
        )));
    }
}
