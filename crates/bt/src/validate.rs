//! Checks of a tree description against what is known about its node IDs.

use std::collections::{BTreeMap, BTreeSet};

use super::error::{DefinitionError, DefinitionErrorKind as K};
use super::model::{
    BtDocument, NodeCategory, NodeDef, NodeLocation, PortDirection, blackboard_pointer,
};
use super::registry::Registry;

/// Checks a document: at least one tree, unique tree IDs, `main_tree_to_execute` and every
/// `SubTree` naming a tree, no recursive subtrees, and for every node: a known ID of the
/// category written, the number of children of its category, only declared ports, required
/// ports present, literal values of the declared type, output ports given as `{key}`, and
/// `Parallel` thresholds that its children can reach.
///
/// IDs are resolved by [`Registry::lookup`] with the document's `<TreeNodesModel>`, so a leaf
/// declared there but not registered passes here (and fails when instantiated).
///
/// # Errors
/// The first problem found, in document order, as a [`DefinitionError`] with the node's
/// location and the attribute concerned.
pub fn validate(doc: &BtDocument, registry: &Registry) -> Result<(), DefinitionError> {
    if doc.trees.is_empty() {
        return Err(DefinitionError::document(K::NoTrees));
    }
    let mut seen = BTreeSet::new();
    for tree in &doc.trees {
        if tree.id.is_empty() {
            return Err(DefinitionError::document(K::EmptyId).with_attribute("ID"));
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
    for tree in &doc.trees {
        let mut result = Ok(());
        tree.root.walk(&mut |path, node| {
            if result.is_ok() {
                let location = NodeLocation {
                    tree: tree.id.clone(),
                    path: path.to_vec(),
                };
                result = check_node(doc, registry, location, node);
            }
        });
        result?;
    }
    check_recursion(doc)
}

fn check_node(
    doc: &BtDocument,
    registry: &Registry,
    location: NodeLocation,
    node: &NodeDef,
) -> Result<(), DefinitionError> {
    let fail = |kind: K, attribute: Option<&str>| {
        let error = DefinitionError::at(location.clone(), kind);
        Err(match attribute {
            Some(a) => error.with_attribute(a),
            None => error,
        })
    };
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
    if node.category == NodeCategory::SubTree {
        if doc.tree(&node.id).is_none() {
            return fail(
                K::UnknownTree {
                    id: node.id.clone(),
                },
                Some("ID"),
            );
        }
        return Ok(());
    }
    let manifest = match registry.lookup(&node.id, &doc.node_models) {
        Ok(m) => m,
        Err(kind) => return fail(kind, Some("ID")),
    };
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
            let Some(spec) = specs.iter().find(|s| &s.name == name) else {
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
            if spec.direction == PortDirection::Output {
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
        }
        for spec in specs.iter().filter(|s| s.required) {
            if node.port_value(&spec.name).is_none() {
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
    if node.id == "Parallel" {
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
    let mut uses: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for tree in &doc.trees {
        let mut used = Vec::new();
        tree.root.walk(&mut |_, node| {
            if node.category == NodeCategory::SubTree {
                used.push(node.id.as_str());
            }
        });
        uses.insert(tree.id.as_str(), used);
    }
    // Depth-first search with colours: on the stack (grey) or finished (black).
    fn visit<'a>(
        id: &'a str,
        uses: &BTreeMap<&'a str, Vec<&'a str>>,
        stack: &mut Vec<&'a str>,
        done: &mut BTreeSet<&'a str>,
    ) -> Option<Vec<String>> {
        if done.contains(id) {
            return None;
        }
        if let Some(start) = stack.iter().position(|&s| s == id) {
            let mut chain: Vec<String> = stack[start..].iter().map(|s| (*s).to_owned()).collect();
            chain.push(id.to_owned());
            return Some(chain);
        }
        stack.push(id);
        for &next in uses.get(id).into_iter().flatten() {
            if let Some(chain) = visit(next, uses, stack, done) {
                return Some(chain);
            }
        }
        stack.pop();
        done.insert(id);
        None
    }
    let mut done = BTreeSet::new();
    for tree in &doc.trees {
        if let Some(chain) = visit(&tree.id, &uses, &mut Vec::new(), &mut done) {
            // Point at the SubTree node of the first tree of the cycle that uses the next one.
            let (from, to) = (&chain[chain.len() - 2], &chain[chain.len() - 1]);
            let mut location = None;
            if let Some(t) = doc.tree(from) {
                t.root.walk(&mut |path, node| {
                    if location.is_none()
                        && node.category == NodeCategory::SubTree
                        && &node.id == to
                    {
                        location = Some(NodeLocation {
                            tree: from.clone(),
                            path: path.to_vec(),
                        });
                    }
                });
            }
            let kind = K::RecursiveSubTree { chain };
            return Err(match location {
                Some(l) => DefinitionError::at(l, kind).with_attribute("ID"),
                None => DefinitionError::document(kind),
            });
        }
    }
    Ok(())
}
