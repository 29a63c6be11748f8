//! Checks of a tree description against what is known about its node IDs.

use std::collections::{BTreeSet, HashMap, HashSet};
use std::rc::Rc;

use super::error::{DefinitionError, DefinitionErrorKind as K};
use super::model::{
    BtDocument, NodeCategory, NodeDef, NodeLocation, PortDirection, blackboard_pointer,
};
use super::registry::{Manifest, ManifestSource, Registry};
use super::runtime::check_definition;

/// Built-in ports with a range narrower than their type: (node, port, least value, what is
/// expected). BehaviorTree.CPP: -1 means "without limit" for the loop counts.
/// Built-in ports whose absence BehaviorTree.CPP 4.8.2 refuses when it loads a tree ("Missing
/// parameter [if] in Precondition", "Missing port [code] in Script", "[queue] not found").
const LOAD_REQUIRED: &[(&str, &str)] = &[
    ("Precondition", "if"),
    ("Script", "code"),
    ("ScriptCondition", "code"),
    ("SkipUnlessUpdated", "entry"),
    ("WaitValueUpdate", "entry"),
    ("WasEntryUpdated", "entry"),
    ("LoopInt", "queue"),
    ("LoopDouble", "queue"),
    ("LoopString", "queue"),
    ("LoopBool", "queue"),
];

const PORT_RANGES: &[(&str, &str, i64, &str)] = &[
    (
        "RetryUntilSuccessful",
        "num_attempts",
        -1,
        "an integer of at least -1 (-1: without limit)",
    ),
    (
        "Repeat",
        "num_cycles",
        -1,
        "an integer of at least -1 (-1: without limit)",
    ),
    ("Timeout", "msec", 0, "a non-negative integer"),
    ("Delay", "delay_msec", 0, "a non-negative integer"),
    ("Sleep", "msec", 0, "a non-negative integer"),
];

/// What a document's IDs are resolved with: the registry, and the document's models and tree
/// IDs by ID (so that checking a node does not search lists).
struct Known<'d> {
    registry: &'d Registry,
    declared: HashMap<&'d str, &'d super::model::NodeModel>,
    trees: HashSet<&'d str>,
    /// What is known of each ID looked up so far, made once per ID (a model's ports are
    /// copied into a [`Manifest`] and indexed once, not once per node using it).
    manifests: HashMap<&'d str, Result<Rc<Resolved>, K>>,
}

/// A [`Manifest`] with its ports indexed by name and its required ports listed.
struct Resolved {
    manifest: Manifest,
    /// Index into the ports by name (the first port of a name).
    index: HashMap<String, usize>,
    /// Indices of the required ports.
    required: Vec<usize>,
}

impl<'d> Known<'d> {
    /// [`Registry::lookup`] with the document's models, without searching them, once per ID.
    fn lookup(&mut self, id: &'d str) -> Result<Rc<Resolved>, K> {
        if let Some(known) = self.manifests.get(id) {
            return known.clone();
        }
        let manifest = match self.registry.lookup(id, &[]) {
            Ok(manifest) => Ok(manifest),
            Err(kind) => match self.declared.get(id) {
                Some(model) => self.registry.lookup(id, std::slice::from_ref(*model)),
                None => Err(kind),
            },
        };
        let resolved = manifest.map(|manifest| {
            let specs = manifest.ports.as_deref().unwrap_or_default();
            let mut index = HashMap::with_capacity(specs.len());
            for (i, spec) in specs.iter().enumerate() {
                index.entry(spec.name.clone()).or_insert(i);
            }
            let required = (0..specs.len()).filter(|&i| specs[i].required).collect();
            Rc::new(Resolved {
                manifest,
                index,
                required,
            })
        });
        self.manifests.insert(id, resolved.clone());
        resolved
    }
}

// `BtDocument::main_tree_id` is a check of the description, so it lives here and the
// description (`model`) needs nothing of the errors.
impl BtDocument {
    /// The ID of the tree to execute: `main_tree_to_execute`, or the only tree.
    ///
    /// # Errors
    /// [`DefinitionErrorKind::UnknownTree`](super::DefinitionErrorKind::UnknownTree) if
    /// `main_tree_to_execute` names no tree, `NoMainTree` if there are several trees and none
    /// is named, `NoTrees` if there are none.
    pub fn main_tree_id(&self) -> Result<&str, DefinitionError> {
        match (&self.main_tree, self.trees.as_slice()) {
            (_, []) => Err(DefinitionError::document(K::NoTrees)),
            (Some(main), _) => match self.tree(main) {
                Some(t) => Ok(&t.id),
                None => Err(
                    DefinitionError::document(K::UnknownTree { id: main.clone() })
                        .with_attribute("main_tree_to_execute"),
                ),
            },
            (None, [only]) => Ok(&only.id),
            (None, trees) => Err(DefinitionError::document(K::NoMainTree {
                trees: trees.iter().map(|t| t.id.clone()).collect(),
            })),
        }
    }
}

/// Checks a document as BehaviorTree.CPP 4 checks it when it loads a tree: at least one tree,
/// unique tree IDs, `main_tree_to_execute` and every `SubTree` naming a tree, no recursive
/// subtrees, and for every node: a known ID of the category written, the number of children
/// of its category, only declared ports, and literal values of the declared type. A tree that
/// passes loads, as it loads in BehaviorTree.CPP; what BehaviorTree.CPP refuses only when it
/// ticks the node is found by [`validate_strict`].
///
/// IDs are resolved by [`Registry::lookup`] with the document's `<TreeNodesModel>`, so a leaf
/// declared there but not registered passes here (and fails when instantiated).
///
/// # Errors
/// The first problem found, in document order, as a [`DefinitionError`] with the node's
/// location and the attribute concerned.
pub fn validate(doc: &BtDocument, registry: &Registry) -> Result<(), DefinitionError> {
    validate_at(doc, registry, false)
}

/// [`validate`], and what BehaviorTree.CPP refuses only when it ticks the node (or never, but
/// misbehaves on): required ports missing, output ports not given as `{key}`, port values out
/// of range (`num_attempts="-5"`), `Parallel` and `ParallelAll` thresholds its children cannot
/// reach, the number of children of `IfThenElse`, `WhileDoElse`, `Switch*` and `TryCatch`,
/// statuses given as text (`else`, `if_empty`). `chronomap bt check` reports these before
/// anything runs; `bt run` and the runtime raise them at the tick, as BehaviorTree.CPP does.
///
/// # Errors
/// As [`validate`].
pub fn validate_strict(doc: &BtDocument, registry: &Registry) -> Result<(), DefinitionError> {
    validate_at(doc, registry, true)
}

fn validate_at(doc: &BtDocument, registry: &Registry, strict: bool) -> Result<(), DefinitionError> {
    if doc.trees.is_empty() {
        return Err(DefinitionError::document(K::NoTrees));
    }
    let mut seen = BTreeSet::new();
    for tree in &doc.trees {
        if tree.id.is_empty() {
            return Err(DefinitionError::document(K::EmptyId).with_attribute("ID"));
        }
        // "The attribute [ID] of tag <BehaviorTree> must not use the name of a registered
        // Node" (BehaviorTree.CPP refuses it when it loads the tree).
        if super::builtin::is_builtin(&tree.id) || registry.contains(&tree.id) {
            return Err(DefinitionError::document(K::TreeIdIsANode {
                id: tree.id.clone(),
            })
            .with_attribute("ID"));
        }
        if !seen.insert(tree.id.as_str()) {
            return Err(DefinitionError::document(K::DuplicateTree {
                id: tree.id.clone(),
            })
            .with_attribute("ID"));
        }
    }
    if doc.main_tree.is_some() {
        doc.main_tree_id()?;
    }
    let mut declared = HashMap::new();
    for model in &doc.node_models {
        declared.entry(model.id.as_str()).or_insert(model);
    }
    let mut known = Known {
        registry,
        declared,
        trees: doc.trees.iter().map(|t| t.id.as_str()).collect(),
        manifests: HashMap::new(),
    };
    for tree in &doc.trees {
        // One stand-in location per tree: the path is made only for the node that fails, so
        // checking takes time in proportion to the nodes, however deep they nest.
        let here = NodeLocation {
            tree: tree.id.clone(),
            path: Vec::new(),
        };
        let mut result = Ok(());
        tree.root.walk(&mut |path, node| {
            if result.is_ok() {
                let located = || NodeLocation {
                    tree: tree.id.clone(),
                    path: path.to_vec(),
                };
                result = match check_node(&mut known, node, strict) {
                    Ok(()) => {
                        check_definition(node, &here, strict).map_err(|e| e.relocated(located()))
                    }
                    Err(failure) => {
                        let (kind, attribute) = *failure;
                        let error = DefinitionError::at(located(), kind);
                        Err(match attribute {
                            Some(a) => error.with_attribute(&a),
                            None => error,
                        })
                    }
                };
            }
        });
        result?;
    }
    check_recursion(doc)
}

/// Checks one node; the error's kind and attribute.
fn check_node<'d>(
    known: &mut Known<'d>,
    node: &'d NodeDef,
    strict: bool,
) -> Result<(), Box<(K, Option<String>)>> {
    let fail =
        |kind: K, attribute: Option<&str>| Err(Box::new((kind, attribute.map(str::to_owned))));
    if !node.category.allows_children(node.children.len()) {
        return fail(
            K::ChildCount {
                id: node.id.clone(),
                category: node.category,
                found: node.children.len(),
            },
            None,
        );
    }
    if node.id == "ReactiveSequence"
        && node.category == NodeCategory::Control
        && node
            .children
            .iter()
            .filter(|c| c.id == "AsyncSequence" && c.category == NodeCategory::Control)
            .count()
            > 1
    {
        return fail(
            K::AsyncChildren {
                id: node.id.clone(),
            },
            None,
        );
    }
    if node.category == NodeCategory::SubTree {
        if !known.trees.contains(node.id.as_str()) {
            return fail(
                K::UnknownTree {
                    id: node.id.clone(),
                },
                Some("ID"),
            );
        }
        return Ok(());
    }
    let resolved = match known.lookup(&node.id) {
        Ok(m) => m,
        Err(kind) => return fail(kind, Some("ID")),
    };
    let manifest = &resolved.manifest;
    if manifest.category != node.category {
        return fail(
            K::WrongCategory {
                id: node.id.clone(),
                written: node.category,
                actual: manifest.category,
            },
            Some("ID"),
        );
    }
    if let Some(specs) = &manifest.ports {
        for (name, value) in &node.ports {
            let Some(spec) = resolved.index.get(name.as_str()).map(|&i| &specs[i]) else {
                return fail(
                    K::UnknownPort {
                        id: node.id.clone(),
                        port: name.clone(),
                        known: specs.iter().map(|s| s.name.clone()).collect(),
                    },
                    Some(name.as_str()),
                );
            };
            if blackboard_pointer(value).is_some() {
                continue;
            }
            if strict && spec.direction == PortDirection::Output {
                return fail(
                    K::OutputNotReference {
                        id: node.id.clone(),
                        port: name.clone(),
                        value: value.clone(),
                    },
                    Some(name.as_str()),
                );
            }
            let ty = spec.port_type();
            if !ty.check_literal(value) {
                return fail(
                    K::BadValue {
                        id: node.id.clone(),
                        port: name.clone(),
                        value: value.clone(),
                        expected: ty.expected().to_owned(),
                    },
                    Some(name.as_str()),
                );
            }
            if strict
                && manifest.source == ManifestSource::Builtin
                && let Some(&(_, _, least, expected)) = PORT_RANGES
                    .iter()
                    .find(|(id, port, _, _)| *id == node.id && port == name)
                && value.trim().parse::<i64>().is_ok_and(|v| v < least)
            {
                return fail(
                    K::BadValue {
                        id: node.id.clone(),
                        port: name.clone(),
                        value: value.clone(),
                        expected: expected.to_owned(),
                    },
                    Some(name.as_str()),
                );
            }
        }
        if manifest.source == ManifestSource::Builtin {
            for &(_, port) in LOAD_REQUIRED.iter().filter(|(id, _)| *id == node.id) {
                if node.port_value(port).is_none() {
                    return fail(
                        K::MissingPort {
                            id: node.id.clone(),
                            port: port.to_owned(),
                        },
                        Some(port),
                    );
                }
            }
        }
        if strict && !resolved.required.is_empty() {
            let given: Option<HashSet<&str>> = (node.ports.len() > 8)
                .then(|| node.ports.iter().map(|(n, _)| n.as_str()).collect());
            for spec in resolved.required.iter().map(|&i| &specs[i]) {
                let present = match &given {
                    Some(given) => given.contains(spec.name.as_str()),
                    None => node.port_value(&spec.name).is_some(),
                };
                if !present {
                    return fail(
                        K::MissingPort {
                            id: node.id.clone(),
                            port: spec.name.clone(),
                        },
                        Some(spec.name.as_str()),
                    );
                }
            }
        }
    }
    if strict && node.id == "Parallel" {
        for (port, default) in [("success_count", -1), ("failure_count", 1)] {
            let threshold = match node.port_value(port) {
                None => default,
                Some(text) => match text.parse::<i64>() {
                    Ok(t) => t,
                    Err(_) => continue, // a {key}: checked when ticked
                },
            };
            let children = node.children.len();
            let required = required_count(threshold, children);
            if children < required {
                return fail(
                    K::ParallelThreshold {
                        port: port.to_owned(),
                        threshold,
                        required,
                        children,
                    },
                    Some(port),
                );
            }
        }
    }
    Ok(())
}

/// BehaviorTree.CPP's `ParallelNode::successThreshold` / `failureThreshold`: a negative
/// threshold `t` means `children + t + 1` (so -1 is "all").
pub(crate) fn required_count(threshold: i64, children: usize) -> usize {
    if threshold < 0 {
        let n = i64::try_from(children).unwrap_or(i64::MAX);
        usize::try_from((n.saturating_add(threshold).saturating_add(1)).max(0)).unwrap_or(0)
    } else {
        usize::try_from(threshold).unwrap_or(usize::MAX)
    }
}

/// No tree reaches itself through `SubTree` nodes.
fn check_recursion(doc: &BtDocument) -> Result<(), DefinitionError> {
    let mut uses: HashMap<&str, Vec<&str>> = HashMap::with_capacity(doc.trees.len());
    for tree in &doc.trees {
        let mut used = Vec::new();
        tree.root.walk(&mut |_, node| {
            if node.category == NodeCategory::SubTree {
                used.push(node.id.as_str());
            }
        });
        uses.entry(tree.id.as_str()).or_insert(used);
    }
    // Depth-first search with colours, without recursion (a chain of subtrees may be as long
    // as the document has trees): on the path (grey, with the position on it) or finished
    // (black). Each tree and each use is visited once.
    let mut on_path: HashMap<&str, usize> = HashMap::new();
    let mut done: HashSet<&str> = HashSet::new();
    let mut cycle = None;
    'trees: for tree in &doc.trees {
        let start = tree.id.as_str();
        if done.contains(start) {
            continue;
        }
        // The path: each tree and the index of the next use to follow.
        let mut path: Vec<(&str, usize)> = vec![(start, 0)];
        on_path.insert(start, 0);
        while let Some(&mut (id, ref mut next)) = path.last_mut() {
            let used = uses.get(id).map_or(&[][..], Vec::as_slice);
            let Some(&to) = used.get(*next) else {
                path.pop();
                on_path.remove(id);
                done.insert(id);
                continue;
            };
            *next += 1;
            if done.contains(to) {
                continue;
            }
            if let Some(&at) = on_path.get(to) {
                let mut chain: Vec<String> =
                    path[at..].iter().map(|(s, _)| (*s).to_owned()).collect();
                chain.push(to.to_owned());
                cycle = Some(chain);
                break 'trees;
            }
            on_path.insert(to, path.len());
            path.push((to, 0));
        }
    }
    let Some(chain) = cycle else {
        return Ok(());
    };
    // Point at the SubTree node of the first tree of the cycle that uses the next one.
    let (from, to) = (&chain[chain.len() - 2], &chain[chain.len() - 1]);
    let mut location = None;
    if let Some(t) = doc.tree(from) {
        t.root.walk(&mut |path, node| {
            if location.is_none() && node.category == NodeCategory::SubTree && &node.id == to {
                location = Some(NodeLocation {
                    tree: from.clone(),
                    path: path.to_vec(),
                });
            }
        });
    }
    let kind = K::RecursiveSubTree { chain };
    Err(match location {
        Some(l) => DefinitionError::at(l, kind).with_attribute("ID"),
        None => DefinitionError::document(kind),
    })
}
