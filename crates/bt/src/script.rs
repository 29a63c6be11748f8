//! Leaves whose outcomes are given tick by tick: to try a tree without a robot
//! (`chronomap bt run`) and to test tick semantics against hand-written traces.
//!
//! A [`Script`] is a list of ticks, each with the outcomes that change at that tick
//! (`OpenDoor` is running from tick 1, succeeds from tick 3). An outcome holds until the script
//! changes it. Leaves are addressed by instance name (the `name` attribute, or the ID); all
//! leaves with that name share the outcome. [`scripted_registry`] implements every leaf of a
//! document this way, and [`run_script`] ticks a tree through the script, one root tick
//! ([`Tree::tick_exactly_once`]) per script tick, recording every transition.
//!
//! ```
//! use std::time::Duration;
//! use chronomap_bt::script::{Script, ScriptTick, run_script, scripted_registry};
//! use chronomap_bt::{BtDocument, NodeDef, Status, Tree, TreeDef};
//!
//! let root = NodeDef::control("Sequence")
//!     .child(NodeDef::condition("BatteryOk"))
//!     .child(NodeDef::action("Patrol"));
//! let doc = BtDocument::single(TreeDef::new("Main", root));
//! let (registry, outcomes) = scripted_registry(&doc)?;
//! let mut tree = Tree::new(&doc, &registry)?;
//! let script = Script {
//!     ticks: vec![
//!         ScriptTick::new(1).outcome("BatteryOk", Status::Success).outcome("Patrol", Status::Running),
//!         ScriptTick::new(3).outcome("Patrol", Status::Success),
//!     ],
//! };
//! let run = run_script(&mut tree, &outcomes, &script, Duration::from_millis(100))?;
//! let statuses: Vec<Status> = run.ticks.iter().map(|t| t.status).collect();
//! assert_eq!(statuses, [Status::Running, Status::Running, Status::Success]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use thiserror::Error;

use super::Status;
use super::builtin::is_builtin;
use super::error::TickError;
use super::model::{BtDocument, NodeCategory};
use super::registry::{LeafContext, LeafError, LeafNode, Registry, RegistryError};
use super::runtime::{Transition, Tree};

/// One tick of a script: its number (from 1), optionally its time, and the outcomes that
/// change at it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ScriptTick {
    /// The tick number (1 is the first tick).
    pub tick: u64,
    /// The time of the tick in milliseconds since the start, if given.
    pub at_ms: Option<u64>,
    /// Leaf instance names and the outcome they return from this tick on.
    pub outcomes: Vec<(String, Status)>,
}

impl ScriptTick {
    /// A tick without time or outcomes.
    pub fn new(tick: u64) -> ScriptTick {
        ScriptTick {
            tick,
            at_ms: None,
            outcomes: Vec::new(),
        }
    }

    /// At a time (milliseconds since the start).
    pub fn at(mut self, ms: u64) -> ScriptTick {
        self.at_ms = Some(ms);
        self
    }

    /// With one more outcome.
    pub fn outcome(mut self, name: &str, status: Status) -> ScriptTick {
        self.outcomes.push((name.to_owned(), status));
        self
    }
}

/// The outcomes of leaves, tick by tick. Ticks must increase; ticks not listed change nothing.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Script {
    /// The ticks, in increasing order.
    pub ticks: Vec<ScriptTick>,
}

/// The current outcome of every scripted leaf, by instance name; shared between the leaves
/// of a tree and whoever drives them.
#[derive(Clone, Debug, Default)]
pub struct ScriptedOutcomes {
    table: Arc<Mutex<BTreeMap<String, Status>>>,
}

impl ScriptedOutcomes {
    /// Sets the outcome of the leaves named `name`.
    pub fn set(&self, name: &str, status: Status) {
        self.table
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .insert(name.to_owned(), status);
    }

    /// The outcome of the leaves named `name`, if set.
    pub fn get(&self, name: &str) -> Option<Status> {
        self.table
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .get(name)
            .copied()
    }

    /// Forgets all outcomes.
    pub fn clear(&self) {
        self.table
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clear();
    }
}

/// A leaf that returns the current outcome of its instance name. An action is
/// BehaviorTree.CPP's `StatefulActionNode`, the base of actions that run over several ticks:
/// `onStart` (from idle) and `onRunning` return the outcome, and an action ticked again while
/// it still holds a completed status (a reactive parent did not reset it) returns that status
/// without asking. A condition is a `SimpleConditionNode`, asked at every tick.
struct ScriptedLeaf {
    outcomes: ScriptedOutcomes,
    action: bool,
}

impl LeafNode for ScriptedLeaf {
    fn tick(&mut self, ctx: &mut LeafContext<'_>) -> Result<Status, LeafError> {
        if self.action && ctx.status().is_completed() {
            return Ok(ctx.status());
        }
        self.outcomes.get(ctx.name()).ok_or_else(|| {
            LeafError::new(format!(
                "ticked, but the script has given no outcome for \"{}\" yet",
                ctx.name()
            ))
        })
    }
}

/// A registry (with the built-in leaves) in which every other action and condition of `doc`
/// is a scripted leaf, and the outcome table they read. Leaves with a `<TreeNodesModel>` entry
/// keep its ports (and their defaults).
///
/// # Errors
/// [`RegistryError`] if an ID is used both as an action and as a condition.
pub fn scripted_registry(doc: &BtDocument) -> Result<(Registry, ScriptedOutcomes), RegistryError> {
    let mut registry = Registry::new();
    let outcomes = ScriptedOutcomes::default();
    let mut leaves: BTreeMap<String, NodeCategory> = BTreeMap::new();
    for tree in &doc.trees {
        tree.root.walk(&mut |_, node| {
            if node.category.is_leaf() && !registry.contains(&node.id) && !is_builtin(&node.id) {
                leaves.entry(node.id.clone()).or_insert(node.category);
            }
        });
    }
    let models = doc.node_models_by_id();
    for (id, category) in leaves {
        let shared = outcomes.clone();
        let action = category == NodeCategory::Action;
        let factory = move || -> Box<dyn LeafNode> {
            Box::new(ScriptedLeaf {
                outcomes: shared.clone(),
                action,
            })
        };
        match models.get(id.as_str()).filter(|m| m.category == category) {
            Some(model) => registry.register((*model).clone(), factory)?,
            None => registry.register_unchecked(category, &id, factory)?,
        }
    }
    Ok((registry, outcomes))
}

/// One tick of a scripted run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TickRecord {
    /// The tick number.
    pub tick: u64,
    /// Its time.
    pub time: Duration,
    /// What the root returned.
    pub status: Status,
    /// The status changes of this tick, in the order they happened.
    pub transitions: Vec<Transition>,
}

/// The result of [`run_script`].
#[derive(Debug)]
pub struct ScriptRun {
    /// Every tick done that returned a status.
    pub ticks: Vec<TickRecord>,
    /// Whether the root stopped running (success, failure or skipped) at the last tick done.
    pub finished: bool,
    /// Script ticks after the one at which the root stopped (not used).
    pub unused: Vec<u64>,
    /// The tick that failed, which ended the run (BehaviorTree.CPP throws from that tick).
    pub failure: Option<TickFailure>,
}

/// A tick that failed: what [`Tree::tick_exactly_once`] returned, and the status changes made
/// before the failure.
#[derive(Debug)]
pub struct TickFailure {
    /// The tick number.
    pub tick: u64,
    /// Its time.
    pub time: Duration,
    /// Why it failed.
    pub error: TickError,
    /// The status changes of the tick up to the failure, in order.
    pub transitions: Vec<Transition>,
}

/// Why a script cannot run, or stopped.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ScriptError {
    /// The script has no ticks.
    #[error("the script has no ticks")]
    Empty,
    /// Tick numbers must start at 1 and increase.
    #[error("tick {tick} comes after tick {previous} (tick numbers start at 1 and increase)")]
    TickOrder {
        /// The tick.
        tick: u64,
        /// The tick before it (0 for none).
        previous: u64,
    },
    /// Times must not decrease.
    #[error("tick {tick} is at {at_ms} ms, before the previous tick at {previous_ms} ms")]
    TimeOrder {
        /// The tick.
        tick: u64,
        /// Its time.
        at_ms: u64,
        /// The previous tick's time.
        previous_ms: u128,
    },
    /// A name that is no leaf of the tree.
    #[error(
        "tick {tick}: the tree has no leaf named \"{name}\" (its leaves: {})",
        .leaves.join(", ")
    )]
    UnknownLeaf {
        /// The tick.
        tick: u64,
        /// The name.
        name: String,
        /// The leaf names of the tree.
        leaves: Vec<String>,
    },
    /// An outcome that is not success, failure or running (for a condition: not success or
    /// failure).
    #[error("tick {tick}: \"{name}\" is {what} and cannot return {status}")]
    BadOutcome {
        /// The tick.
        tick: u64,
        /// The leaf name.
        name: String,
        /// `"a condition"` or `"a leaf"`.
        what: &'static str,
        /// The outcome given.
        status: Status,
    },
}

/// Runs `tree` through `script`: for every tick from 1 to the last tick of the script, the
/// outcomes listed at that tick are set, then the root is ticked once
/// ([`Tree::tick_exactly_once`]) at the tick's time — the time given in the script, or the
/// previous tick's time plus `period` (tick 1: 0). The run stops early when the root stops
/// running (it succeeded, failed or was skipped: BehaviorTree.CPP's `tickWhileRunning` ends
/// there too), or at a tick that fails, which is recorded in [`ScriptRun::failure`] with the
/// status changes made before it (a script that throws, a leaf ticked before the script gave it
/// an outcome, a port value that cannot be read).
///
/// # Errors
/// [`ScriptError`] for an empty or disordered script, names that are no leaves and outcomes a
/// leaf cannot return, before anything runs.
pub fn run_script(
    tree: &mut Tree,
    outcomes: &ScriptedOutcomes,
    script: &Script,
    period: Duration,
) -> Result<ScriptRun, ScriptError> {
    run_script_with(tree, outcomes, script, period, &mut || {}, &mut |_, _| {})
}

/// [`run_script`] with a call before every tick (`before_tick`: a wall-clock pause, say) and
/// one after it (`after_tick`, with the tree and the tick's status changes, also for a tick
/// that failed): what a run watched live needs (`chronomap bt run --groot2`).
///
/// # Errors
/// As [`run_script`].
pub fn run_script_with(
    tree: &mut Tree,
    outcomes: &ScriptedOutcomes,
    script: &Script,
    period: Duration,
    before_tick: &mut dyn FnMut(),
    after_tick: &mut dyn FnMut(&Tree, &[Transition]),
) -> Result<ScriptRun, ScriptError> {
    check(tree, script, period)?;
    let last = script.ticks.last().map_or(0, |t| t.tick);
    let by_tick: BTreeMap<u64, &ScriptTick> = script.ticks.iter().map(|t| (t.tick, t)).collect();
    tree.set_recording(true);
    tree.take_transitions();
    let mut ticks = Vec::new();
    let mut time = Duration::ZERO;
    let mut finished = false;
    let mut failure = None;
    for k in 1..=last {
        let line = by_tick.get(&k);
        time = match line.and_then(|l| l.at_ms) {
            Some(ms) => Duration::from_millis(ms),
            None if k == 1 => Duration::ZERO,
            None => time.saturating_add(period),
        };
        for (name, status) in line.map(|l| l.outcomes.as_slice()).unwrap_or_default() {
            outcomes.set(name, *status);
        }
        before_tick();
        let result = tree.tick_exactly_once(time);
        let transitions = tree.take_transitions();
        after_tick(tree, &transitions);
        match result {
            Ok(status) => {
                ticks.push(TickRecord {
                    tick: k,
                    time,
                    status,
                    transitions,
                });
                if status != Status::Running {
                    finished = true;
                    break;
                }
            }
            Err(error) => {
                failure = Some(TickFailure {
                    tick: k,
                    time,
                    error,
                    transitions,
                });
                break;
            }
        }
    }
    let done = failure.as_ref().map_or_else(
        || ticks.last().map_or(0, |t| t.tick),
        |f: &TickFailure| f.tick,
    );
    let unused = script
        .ticks
        .iter()
        .map(|t| t.tick)
        .filter(|&t| t > done)
        .collect();
    Ok(ScriptRun {
        ticks,
        finished,
        unused,
        failure,
    })
}

/// Order, times, names and outcomes of a script against a tree, before anything runs.
fn check(tree: &Tree, script: &Script, period: Duration) -> Result<(), ScriptError> {
    if script.ticks.is_empty() {
        return Err(ScriptError::Empty);
    }
    let mut conditions = BTreeSet::new();
    let mut leaves = BTreeSet::new();
    for node in tree.nodes() {
        match node.category() {
            NodeCategory::Condition => {
                conditions.insert(node.name());
                leaves.insert(node.name());
            }
            NodeCategory::Action => {
                leaves.insert(node.name());
            }
            _ => {}
        }
    }
    // Times as run_script computes them: given, or the previous time plus the period.
    let (mut previous, mut previous_ms) = (0, 0u128);
    for line in &script.ticks {
        if line.tick <= previous {
            return Err(ScriptError::TickOrder {
                tick: line.tick,
                previous,
            });
        }
        // The time of tick `line.tick - 1` (listed or not); tick 1 is at 0.
        let before = match line.tick - 1 {
            0 => None,
            t if previous == 0 => Some(period.as_millis() * u128::from(t - 1)),
            t => Some(previous_ms + period.as_millis() * u128::from(t - previous)),
        };
        previous_ms = match (line.at_ms, before) {
            (Some(at), Some(b)) if u128::from(at) < b => {
                return Err(ScriptError::TimeOrder {
                    tick: line.tick,
                    at_ms: at,
                    previous_ms: b,
                });
            }
            (Some(at), _) => u128::from(at),
            (None, Some(b)) => b + period.as_millis(),
            (None, None) => 0,
        };
        previous = line.tick;
        for (name, status) in &line.outcomes {
            if !leaves.contains(name.as_str()) {
                return Err(ScriptError::UnknownLeaf {
                    tick: line.tick,
                    name: name.clone(),
                    leaves: leaves.iter().map(|s| (*s).to_owned()).collect(),
                });
            }
            let condition = conditions.contains(name.as_str());
            let allowed = match status {
                Status::Success | Status::Failure => true,
                Status::Running => !condition,
                Status::Idle | Status::Skipped => false,
            };
            if !allowed {
                return Err(ScriptError::BadOutcome {
                    tick: line.tick,
                    name: name.clone(),
                    what: if condition { "a condition" } else { "a leaf" },
                    status: *status,
                });
            }
        }
    }
    Ok(())
}
