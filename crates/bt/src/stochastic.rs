//! A BehaviorTree.CPP tree ([`BtDocument`]) read as a stochastic behavior tree ([Stüde 2024]
//! §5.2.2, `chronomap-bt-stochastic`): every action leaf gets the tuple `⟨p_s, p_f, μ, ν⟩` and every condition
//! `⟨p_s, p_f⟩` from a table of [`LeafParams`], and the control flow becomes a [`Node`].
//!
//! The conversion is exact for the nodes it accepts — the stochastic model of the leaves is
//! the only assumption:
//!
//! | BehaviorTree.CPP | stochastic tree |
//! |---|---|
//! | `Sequence`, `SequenceWithMemory` | `Sequence` (Algorithm 5.1; in one execution of the tree the memory never matters) |
//! | `Fallback` | `Fallback` (Algorithm 5.2) |
//! | `Inverter(c)` | pushed down to the leaves by De Morgan: an action `⟨p, μ, ν⟩` becomes `⟨1 − p, ν, μ⟩`, a condition `p` becomes `1 − p`, a Sequence a Fallback of inverted children and vice versa |
//! | `ForceSuccess(c)` | `Fallback(c, true)` (a condition with `p_s = 1`) |
//! | `ForceFailure(c)` | `Sequence(c, false)` |
//! | `RetryUntilSuccessful(c)`, `num_attempts = n ≥ 1` | `Fallback` of `n` independent copies of `c` |
//! | `Repeat(c)`, `num_cycles = n ≥ 1` | `Sequence` of `n` copies of `c` |
//! | `SubTree` | the subtree, expanded |
//! | `AlwaysSuccess`, `SetBlackboard` / `AlwaysFailure` | a condition with `p_s = 1` / `0` |
//!
//! Not representable, hence refused with the node's location: `Parallel` (the chain of
//! [`Chain::from_tree`](chronomap_bt_stochastic::Chain::from_tree) runs one leaf at a time), `ReactiveSequence`
//! and `ReactiveFallback` (they re-tick conditions while an action runs, which the model's
//! independent outcomes cannot express), `Timeout` and `Sleep` (deterministic durations),
//! `RetryUntilSuccessful`/`Repeat` with `-1` (unbounded) or a blackboard reference.

use std::collections::BTreeMap;

use thiserror::Error;

use chronomap_bt_stochastic::{Action, Condition, LeafParams, Node, SbtError, invert};

use crate::{BtDocument, NodeCategory, NodeDef, NodeLocation};

/// Why a behavior tree could not be read as a stochastic tree; `location` says which node.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("{location}: {kind}")]
pub struct FromBtError {
    /// The node (tree ID and child path, as the XML reader locates nodes).
    pub location: NodeLocation,
    /// What is wrong.
    pub kind: FromBtErrorKind,
}

/// What is wrong (the part of a [`FromBtError`] after the location).
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum FromBtErrorKind {
    /// A node type the stochastic model cannot express.
    #[error("{id} is not supported by the stochastic analysis ({why})")]
    Unsupported {
        /// The node's ID.
        id: String,
        /// Why.
        why: &'static str,
    },
    /// A leaf without parameters.
    #[error("no parameters for {category} {name:?} (give a row for its name or ID)")]
    MissingParams {
        /// `Action` or `Condition`.
        category: NodeCategory,
        /// Its instance name.
        name: String,
    },
    /// An action whose parameters lack a rate.
    #[error("action {name:?} needs both rates mu and nu")]
    MissingRate {
        /// Its instance name.
        name: String,
    },
    /// Invalid parameters.
    #[error("parameters of {name:?}: {error}")]
    Params {
        /// Its instance name.
        name: String,
        /// The tuple's error.
        error: SbtError,
    },
    /// A `SubTree` naming no tree, or a tree that contains itself.
    #[error("subtree {id:?}: {why}")]
    SubTree {
        /// The tree ID.
        id: String,
        /// What is wrong.
        why: &'static str,
    },
}

/// The stochastic tree of the tree `tree_id` of `doc`. A leaf's parameters are
/// `params[instance name]`, else `params[ID]` (so one row can serve every instance of an ID).
///
/// # Errors
/// A [`FromBtError`] locating the first node that is not supported, a leaf without (valid)
/// parameters, or a bad subtree.
pub fn from_bt(
    doc: &BtDocument,
    tree_id: &str,
    params: &BTreeMap<String, LeafParams>,
) -> Result<Node, FromBtError> {
    let Some(tree) = doc.tree(tree_id) else {
        return Err(FromBtError {
            location: NodeLocation {
                tree: tree_id.to_owned(),
                path: Vec::new(),
            },
            kind: FromBtErrorKind::SubTree {
                id: tree_id.to_owned(),
                why: "no tree has this ID",
            },
        });
    };
    let mut converter = Converter {
        doc,
        params,
        stack: vec![tree_id.to_owned()],
    };
    converter.node(&tree.root, tree_id, &mut Vec::new())
}

struct Converter<'a> {
    doc: &'a BtDocument,
    params: &'a BTreeMap<String, LeafParams>,
    stack: Vec<String>,
}

impl Converter<'_> {
    fn node(
        &mut self,
        def: &NodeDef,
        tree: &str,
        path: &mut Vec<usize>,
    ) -> Result<Node, FromBtError> {
        let here = NodeLocation {
            tree: tree.to_owned(),
            path: path.clone(),
        };
        let fail = |kind| FromBtError {
            location: here.clone(),
            kind,
        };
        let unsupported = |why| {
            fail(FromBtErrorKind::Unsupported {
                id: def.id.clone(),
                why,
            })
        };
        match def.category {
            NodeCategory::Action | NodeCategory::Condition => {
                match def.id.as_str() {
                    "AlwaysSuccess" | "SetBlackboard" => {
                        return Ok(Node::Condition(Condition::new(1.0).expect("valid")));
                    }
                    "AlwaysFailure" => {
                        return Ok(Node::Condition(Condition::new(0.0).expect("valid")));
                    }
                    "Sleep" => return Err(unsupported("a deterministic duration")),
                    _ => {}
                }
                let name = def.instance_name();
                let Some(p) = self.params.get(name).or_else(|| self.params.get(&def.id)) else {
                    return Err(fail(FromBtErrorKind::MissingParams {
                        category: def.category,
                        name: name.to_owned(),
                    }));
                };
                let bad = |error| {
                    fail(FromBtErrorKind::Params {
                        name: name.to_owned(),
                        error,
                    })
                };
                if def.category == NodeCategory::Condition {
                    return Condition::new(p.p_success)
                        .map(Node::Condition)
                        .map_err(bad);
                }
                let (Some(mu), Some(nu)) = (p.mu, p.nu) else {
                    return Err(fail(FromBtErrorKind::MissingRate {
                        name: name.to_owned(),
                    }));
                };
                Action::new(p.p_success, mu, nu)
                    .map(Node::Action)
                    .map_err(bad)
            }
            NodeCategory::Control => {
                // The node itself is checked before its children, so that the error names
                // the outermost node that cannot be analysed.
                let sequence = match def.id.as_str() {
                    "Sequence" | "SequenceWithMemory" => true,
                    "Fallback" => false,
                    "Parallel" => return Err(unsupported("children run at the same time")),
                    "ReactiveSequence" | "ReactiveFallback" => {
                        return Err(unsupported(
                            "it re-ticks earlier children while a later one runs",
                        ));
                    }
                    _ => return Err(unsupported("not a built-in control node")),
                };
                let children = self.children(def, tree, path)?;
                Ok(if sequence {
                    Node::Sequence(children)
                } else {
                    Node::Fallback(children)
                })
            }
            NodeCategory::Decorator => {
                match def.id.as_str() {
                    "Inverter"
                    | "ForceSuccess"
                    | "ForceFailure"
                    | "RetryUntilSuccessful"
                    | "Repeat" => {}
                    "Timeout" => return Err(unsupported("a deterministic deadline")),
                    _ => return Err(unsupported("not a built-in decorator")),
                }
                let mut children = self.children(def, tree, path)?;
                let child = children.pop().ok_or_else(|| unsupported("no child"))?;
                let copies = |port: &str| -> Result<usize, FromBtError> {
                    match def.port_value(port).map(str::trim) {
                        None => Ok(1),
                        Some(text) => match text.parse::<i64>() {
                            Ok(n) if n >= 1 => Ok(n as usize),
                            Ok(0) => Ok(0),
                            Ok(_) => Err(unsupported("an unbounded number of attempts")),
                            Err(_) => {
                                Err(unsupported("a number of attempts that is not a literal"))
                            }
                        },
                    }
                };
                match def.id.as_str() {
                    "Inverter" => Ok(invert(child)),
                    "ForceSuccess" => Ok(Node::Fallback(vec![child, always(true)])),
                    "ForceFailure" => Ok(Node::Sequence(vec![child, always(false)])),
                    // BehaviorTree.CPP: zero attempts (cycles) end at once in failure (success).
                    "RetryUntilSuccessful" => {
                        Ok(Node::Fallback(vec![child; copies("num_attempts")?]))
                    }
                    _ => Ok(Node::Sequence(vec![child; copies("num_cycles")?])),
                }
            }
            NodeCategory::SubTree => {
                let id = def.id.as_str();
                if self.stack.iter().any(|t| t == id) {
                    return Err(fail(FromBtErrorKind::SubTree {
                        id: id.to_owned(),
                        why: "the tree contains itself",
                    }));
                }
                let Some(sub) = self.doc.tree(id) else {
                    return Err(fail(FromBtErrorKind::SubTree {
                        id: id.to_owned(),
                        why: "no tree has this ID",
                    }));
                };
                self.stack.push(id.to_owned());
                let node = self.node(&sub.root, id, &mut Vec::new());
                self.stack.pop();
                node
            }
        }
    }

    fn children(
        &mut self,
        def: &NodeDef,
        tree: &str,
        path: &mut Vec<usize>,
    ) -> Result<Vec<Node>, FromBtError> {
        let mut out = Vec::with_capacity(def.children.len());
        for (i, child) in def.children.iter().enumerate() {
            path.push(i);
            let node = self.node(child, tree, path);
            path.pop();
            out.push(node?);
        }
        Ok(out)
    }
}

fn always(success: bool) -> Node {
    Node::Condition(Condition::new(if success { 1.0 } else { 0.0 }).expect("valid"))
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};
    use std::time::Duration;

    use super::*;
    use crate::{Registry, Status, Tree, TreeDef};
    use chronomap_rng::Xoshiro256StarStar;

    fn action(p: f64, mu: f64, nu: f64) -> LeafParams {
        LeafParams {
            p_success: p,
            mu: Some(mu),
            nu: Some(nu),
        }
    }

    fn condition(p: f64) -> LeafParams {
        LeafParams {
            p_success: p,
            mu: None,
            nu: None,
        }
    }

    /// Fallback(A1, A2) from a description is the stochastic tree of the same shape with each
    /// leaf's parameters (by instance name before ID), whose transient outcomes
    /// `chronomap-bt-stochastic` checks against the closed form (`fallback_of_two_closed_form`);
    /// here the means: `p_s = p1 + (1 − p1) p2`, `E[T | F] = 1/ν1 + 1/ν2`.
    #[test]
    fn fallback_of_two_actions_is_the_stochastic_fallback_of_their_parameters() {
        let root = NodeDef::control("Fallback")
            .child(NodeDef::action("Search"))
            .child(NodeDef::action("Wait").named("wait_at_door"));
        let doc = BtDocument::single(TreeDef::new("Main", root));
        let (p1, m1, n1) = (0.6, 1.0 / 20.0, 1.0 / 40.0);
        let (p2, m2, n2) = (0.9, 1.0 / 50.0, 1.0 / 100.0);
        let params = BTreeMap::from([
            ("Search".to_owned(), action(p1, m1, n1)),
            // By instance name, which wins over the ID.
            ("wait_at_door".to_owned(), action(p2, m2, n2)),
            ("Wait".to_owned(), action(0.1, 1.0, 1.0)),
        ]);
        let tree = from_bt(&doc, "Main", &params).unwrap();
        let expected = Node::Fallback(vec![
            Node::Action(Action::new(p1, m1, n1).unwrap()),
            Node::Action(Action::new(p2, m2, n2).unwrap()),
        ]);
        assert_eq!(format!("{tree:?}"), format!("{expected:?}"));
        let means = tree.chain().unwrap().means();
        assert!((means.p_success - (p1 + (1.0 - p1) * p2)).abs() < 1e-12);
        // E[T | F] = 1/ν1 + 1/ν2 (both failed).
        assert!((means.time_to_failure.unwrap() - (40.0 + 100.0)).abs() < 1e-9);
    }

    /// Inverter by De Morgan: ¬Sequence(C, A) = Fallback(¬C, ¬A).
    #[test]
    fn inverter_swaps_outcomes_and_rates() {
        let root = NodeDef::decorator("Inverter").child(
            NodeDef::control("Sequence")
                .child(NodeDef::condition("Ready"))
                .child(NodeDef::action("Go")),
        );
        let doc = BtDocument::single(TreeDef::new("Main", root));
        let params = BTreeMap::from([
            ("Ready".to_owned(), condition(0.7)),
            ("Go".to_owned(), action(0.8, 0.5, 0.25)),
        ]);
        let tree = from_bt(&doc, "Main", &params).unwrap();
        let expected = Node::Fallback(vec![
            Node::Condition(Condition::new(1.0 - 0.7).unwrap()),
            Node::Action(Action::new(1.0 - 0.8, 0.25, 0.5).unwrap()),
        ]);
        assert_eq!(format!("{tree:?}"), format!("{expected:?}"));
        let m = tree.chain().unwrap().means();
        assert!((m.p_success - (1.0 - 0.7 * 0.8)).abs() < 1e-12);
    }

    /// The door tree of tests/data/bt (Inverter, SubTree, RetryUntilSuccessful) with every
    /// decorator the conversion accepts.
    fn door() -> BtDocument {
        let main = NodeDef::control("Sequence")
            .child(
                NodeDef::control("Fallback")
                    .child(NodeDef::decorator("Inverter").child(NodeDef::condition("IsDoorClosed")))
                    .child(NodeDef::subtree("DoorClosed")),
            )
            .child(NodeDef::decorator("ForceSuccess").child(NodeDef::action("Wave")))
            .child(
                NodeDef::decorator("Repeat")
                    .port("num_cycles", "2")
                    .child(NodeDef::action("PassThroughDoor")),
            );
        let closed = NodeDef::control("Fallback")
            .child(NodeDef::action("OpenDoor"))
            .child(
                NodeDef::decorator("RetryUntilSuccessful")
                    .port("num_attempts", "3")
                    .child(NodeDef::action("PickLock")),
            )
            .child(NodeDef::decorator("ForceFailure").child(NodeDef::action("SmashDoor")));
        let mut doc = BtDocument::single(TreeDef::new("MainTree", main));
        doc.trees.push(TreeDef::new("DoorClosed", closed));
        doc
    }

    fn door_params() -> BTreeMap<String, LeafParams> {
        BTreeMap::from([
            ("IsDoorClosed".to_owned(), condition(0.6)),
            ("OpenDoor".to_owned(), action(0.3, 0.2, 0.5)),
            ("PickLock".to_owned(), action(0.4, 0.05, 0.1)),
            ("SmashDoor".to_owned(), action(0.9, 0.1, 0.2)),
            ("Wave".to_owned(), action(0.5, 1.0, 2.0)),
            ("PassThroughDoor".to_owned(), action(0.95, 0.1, 0.3)),
        ])
    }

    /// The conversion against the behavior-tree runtime itself: leaves that draw their
    /// outcome and duration from the same tuples, ticked by [`Tree`] (which knows nothing of
    /// the chain), give the chain's eventual probability and mean times within Monte-Carlo
    /// error (4 standard errors; the seed is fixed).
    #[test]
    fn the_chain_agrees_with_ticking_the_tree_with_random_leaves() {
        let doc = door();
        let params = door_params();
        let means = from_bt(&doc, "MainTree", &params)
            .unwrap()
            .chain()
            .unwrap()
            .means();
        let rng = Arc::new(Mutex::new(Xoshiro256StarStar::seed_from_u64(7)));
        let clock = Arc::new(Mutex::new(0.0_f64));
        let mut registry = Registry::new();
        for (id, p) in &params {
            let (rng, clock, p) = (rng.clone(), clock.clone(), *p);
            let tick = move |_: &mut crate::LeafContext<'_>| {
                let mut rng = rng.lock().unwrap();
                let success = rng.bernoulli(p.p_success);
                if let (Some(mu), Some(nu)) = (p.mu, p.nu) {
                    *clock.lock().unwrap() += rng.exp1() / if success { mu } else { nu };
                }
                Ok(if success {
                    Status::Success
                } else {
                    Status::Failure
                })
            };
            if p.mu.is_some() {
                registry.register_action_fn(id, tick).unwrap();
            } else {
                registry.register_condition_fn(id, tick).unwrap();
            }
        }
        let runs = 40_000;
        let (mut successes, mut time_s, mut time_f) = (0usize, 0.0, 0.0);
        let mut tree = Tree::new(&doc, &registry).unwrap();
        for _ in 0..runs {
            *clock.lock().unwrap() = 0.0;
            let status = tree.tick_once(Duration::ZERO).unwrap();
            let t = *clock.lock().unwrap();
            match status {
                Status::Success => {
                    successes += 1;
                    time_s += t;
                }
                Status::Failure => time_f += t,
                other => panic!("leaves complete at once, the tree returned {other}"),
            }
        }
        let p = successes as f64 / runs as f64;
        let se = (means.p_success * (1.0 - means.p_success) / runs as f64).sqrt();
        assert!(
            (p - means.p_success).abs() < 4.0 * se,
            "{p} vs {}",
            means.p_success
        );
        let (ts, tf) = (
            time_s / successes as f64,
            time_f / (runs - successes) as f64,
        );
        let (es, ef) = (
            means.time_to_success.unwrap(),
            means.time_to_failure.unwrap(),
        );
        // Times are sums of a few exponentials: a relative error of 3 % is > 4 standard errors.
        assert!((ts - es).abs() < 0.03 * es, "E[T|S] {ts} vs {es}");
        assert!((tf - ef).abs() < 0.03 * ef, "E[T|F] {tf} vs {ef}");
    }

    #[test]
    fn unsupported_nodes_and_missing_parameters_are_located() {
        let params = door_params();
        let mut doc = door();
        doc.trees[1].root.children[1] = NodeDef::decorator("Timeout")
            .port("msec", "100")
            .child(NodeDef::action("PickLock"));
        let e = from_bt(&doc, "MainTree", &params).unwrap_err();
        assert_eq!(e.location.tree, "DoorClosed");
        assert_eq!(e.location.path, vec![1]);
        assert!(e.to_string().contains("Timeout is not supported"), "{e}");

        let mut doc = door();
        doc.trees[1].root.children[1].ports[0].1 = "-1".to_owned();
        let e = from_bt(&doc, "MainTree", &params).unwrap_err();
        assert!(e.to_string().contains("unbounded"), "{e}");

        let doc = door();
        let mut missing = door_params();
        missing.remove("Wave");
        let e = from_bt(&doc, "MainTree", &missing).unwrap_err();
        assert_eq!(e.location.path, vec![1, 0]);
        assert!(
            e.to_string().contains("no parameters for Action \"Wave\""),
            "{e}"
        );

        let mut bad = door_params();
        bad.insert("Wave".to_owned(), action(1.5, 1.0, 1.0));
        let e = from_bt(&doc, "MainTree", &bad).unwrap_err();
        assert!(e.to_string().contains("not in [0, 1]"), "{e}");

        let mut doc = door();
        doc.trees[0].root.children[0] = NodeDef::control("Parallel")
            .child(NodeDef::action("Wave"))
            .child(NodeDef::action("Wave"));
        let e = from_bt(&doc, "MainTree", &params).unwrap_err();
        assert!(e.to_string().contains("Parallel is not supported"), "{e}");
    }
}
