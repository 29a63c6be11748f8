//! Behavior trees as the faces run them ([Stüde 2024] §5.2–5.3): a BehaviorTree.CPP 4 document
//! read with the node models of other files, a registry that implements every node of it
//! (leaves driven by a script of outcomes or stubbed, declared controls and decorators stubbed or
//! emulated as Nav2 does), the tree flattened depth first as it is instantiated, and the
//! stochastic behavior tree of §5.2.2 with its default horizon.
//!
//! The command line (`chronomap bt check`, `bt run`, `bt analyse`) translates flags into these
//! calls and prints what they return.

use std::collections::{BTreeMap, BTreeSet, HashSet};
use std::path::{Path, PathBuf};

use chronomap_bt::nav2;
use chronomap_bt::script::{ScriptedOutcomes, scripted_registry};
use chronomap_bt::stochastic::from_bt;
use chronomap_bt::{
    BtDocument, DefinitionError, DefinitionErrorKind, ManifestSource, NodeCategory, NodeDef,
    NodeModel, Registry, RegistryError, StubPolicy, TreeDef, is_builtin,
};
use chronomap_bt_stochastic::{Chain, LeafParams, Means, SbtError};
use chronomap_io::{
    BtReadOptions, BtXml, BtXmlError, BtXmlErrorKind, read_bt_xml_with, read_node_models,
};
use thiserror::Error;

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
}
