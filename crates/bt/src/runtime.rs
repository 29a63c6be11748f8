//! The runtime tree: instantiation of a description, ticks, halts and status transitions, with
//! the semantics of BehaviorTree.CPP 4 (read from its 4.x sources: `src/controls/*.cpp`,
//! `src/decorators/*.cpp`, `src/actions/*.cpp`, `TreeNode::executeTick`, `Tree::tickRoot`,
//! and the behaviour its gtests state).
//!
//! # Ticks and statuses
//! A tick of a node returns running, success, failure or skipped; the node's status becomes
//! that value (transitions are recorded when they change it). Control nodes and decorators set
//! themselves running before ticking children. "Resetting" a child (`ControlNode::haltChild`,
//! `DecoratorNode::resetChild`) halts it if it is running and then sets it idle; "halting" a
//! node (`haltNode`) resets its own state and children, calls a running leaf's
//! [`LeafNode::halt`] hook and runs the node's `_onHalted` script.
//!
//! # Pre- and post-conditions (`TreeNode::checkPreConditions`, `checkPostConditions`)
//! The scripts of [`NodeDef::scripts`] are parsed when the tree is instantiated (see
//! [`scripting`](super::scripting)). Before every tick of a node that is not active (idle or
//! skipped), `_failureIf`, `_successIf`, `_skipIf` are evaluated in this order, and the first
//! that is true gives the node's result (failure, success, skipped) without ticking it; then a
//! false `_while` skips it. While the node is running only `_while` is checked: when false the
//! node is halted and returns skipped. After a tick (or a pre-condition) that completes the
//! node, `_onSuccess` or `_onFailure` runs, then `_post`.
//!
//! # Skipped children ([Stüde 2024] has no skipped status; this follows BehaviorTree.CPP 4.8.2)
//! A node that returns skipped keeps its status ("preserve the IDLE state if skipped, but
//! communicate SKIPPED to parent", `TreeNode::executeTick`): idle, or running for a control
//! node that set itself running before all its children were skipped — which its parent then
//! halts like any running node (its `_onHalted` runs). No transition to skipped is ever
//! recorded. Sequences and fallbacks (with or without memory, asynchronous) go past a skipped
//! child; reactive ones too, resetting it so that it can be skipped again. A control node all
//! of whose children were skipped in its execution returns skipped, and so do `Parallel` and
//! `ParallelAll` when every child was skipped in a tick (but a `Parallel` with a negative
//! `success_count` counts skipped children as successes, so it succeeds then). Decorators pass
//! a skipped child through (`RetryUntilSuccessful` and `Repeat` reset it and keep their
//! counters; `KeepRunningUntilFailure` returns running). A skipped condition of `IfThenElse` or
//! `WhileDoElse` is an error at that tick, as BehaviorTree.CPP throws there.
//!
//! Every rule here was checked by running random trees through BehaviorTree.CPP 4.8.2 and
//! chronomap side by side (`tests/cli/bt_differential.rs`, docs/bt.md).
//!
//! | node | rule |
//! |---|---|
//! | `Sequence` | ticks children from the current one; running: returns running and resumes at that child next tick (earlier children are *not* re-ticked); failure: resets all children, restarts at the first child next time, returns failure; all succeed: resets them, success. ([Stüde 2024] Algorithm 5.1 with memory of the running child.) |
//! | `SequenceWithMemory` (`SequenceStar`) | as `Sequence`, but on failure only the failed and later children are reset and the index is kept: the next tick retries the failed child. Halting keeps the index too (BehaviorTree.CPP leaves `current_child_idx_ = 0` commented out in `halt()`). A child that succeeds straight from idle with children left makes it return running and ask for a wake-up (`requiresWakeUp()`, true in every tree BehaviorTree.CPP's factory builds). |
//! | `AsyncSequence`, `AsyncFallback` | as `Sequence` / `Fallback`, but after a child that completed (success / failure) straight from idle with more children to go, returns running and asks for a wake-up, so [`Tree::tick_once`] ticks again at once. |
//! | `ReactiveSequence` | ticks all children from the first every tick; a running child halts every *other* child (later ones that were running, earlier ones are reset to idle) and returns running; a failure resets all children (halting a running later one) and returns failure; all succeed: success. |
//! | `Fallback` | mirror of `Sequence` (Algorithm 5.2): resumes at the running child; success resets all and returns success; all fail: failure. |
//! | `ReactiveFallback` | mirror of `ReactiveSequence`: a success resets all and returns success; a running child halts the others. |
//! | `Parallel` | ticks every child that has not completed yet, left to right; after each child it checks: successes ≥ `success_count` → success; failures = `failure_count`, or too many failures to reach `success_count` → failure (both reset all children, halting running ones). A negative threshold `t` means `children + t + 1` (-1 = all); defaults -1 and 1. A threshold above the number of children is an error. |
//! | `ParallelAll` | ticks every child that has not completed yet; when all have completed (or were skipped), resets them and returns failure if at least `max_failures` failed (negative: `children + t + 1`), else success. |
//! | `IfThenElse` | 2 or 3 children: ticks the condition (first child) until it completes; success: the second child, failure: the third (or failure with 2 children); the chosen branch is ticked until it completes, then all are reset. |
//! | `WhileDoElse` | 2 or 3 children: the condition is ticked *every* tick; success: halts the third child and ticks the second; failure: halts the second and ticks the third (or returns failure); a completed branch resets all. |
//! | `Switch2` … `Switch6` | `variable` is compared with `case_1` … `case_N` (as text, then as integers with enum names, then as reals within `f32::EPSILON`: `CheckStringEquality`); the first match, or the last child (default), is ticked; a change of branch halts the running one; completion resets all. The node does not set itself running: its status is its child's. |
//! | `TryCatch` | the children but the last are a sequence (the "try"); if one fails they are halted and the last child (the "catch") is ticked until it completes, and the node returns failure whatever the catch returned. With `catch_on_halt`, halting the node during the try ticks the catch once (halting it if it returns running). |
//! | `Inverter`, `ForceSuccess`, `ForceFailure` | running passes through; a completed child is reset and its result inverted / replaced. |
//! | `RetryUntilSuccessful` | ticks the child; success: success; failure: counts an attempt, resets the child and, while attempts remain (`num_attempts`, -1 = forever), ticks it again — but if the child failed straight from idle it returns running first and tries again on the next tick (BehaviorTree.CPP returns running and emits a wake-up signal, "to make this interruptable", in every tree built by its factory). When the attempts are used up: failure. |
//! | `Repeat` | mirror for success with `num_cycles` (failure ends the loop with failure). |
//! | `KeepRunningUntilFailure` | a success of the child resets it and returns running; failure: failure. |
//! | `Timeout` | on its first tick starts a timer of `msec` (0 = none); on a later tick at or after the deadline, if the child is still running, halts it and returns failure without ticking it (BehaviorTree.CPP halts it from a timer thread at the deadline; with the injected clock this happens at the first tick after the deadline, with that tick's time). |
//! | `Delay` | on its first tick starts a timer of `delay_msec` and returns running; from the first tick at or after the deadline it ticks the child (at once when `delay_msec` is 0: BehaviorTree.CPP's timer fires immediately and wakes the tree up). A completed child resets the timer. |
//! | `LoopInt`, `LoopDouble`, `LoopString`, `LoopBool` | when starting, a literal `queue` (`"1;2;3"`) is copied; while the child is not running, each tick pops the front of the queue (a `{key}` queue is popped *on the blackboard*, as BehaviorTree.CPP's shared queue) into `value` and ticks the child; running while it runs or succeeds, failure when it fails; when there is nothing to pop, returns `if_empty` (default success). |
//! | `Precondition` | if the child ran (`_children_running`, which a halt does not clear) or the `if` script is true, ticks the child (resetting it when it completes) and returns its status; otherwise returns `else` (default failure). |
//! | `RunOnce` | ticks the child until it completes once; afterwards returns skipped (`then_skip`, default) or that same result, without ticking it. Halting does not re-arm it. |
//! | `SkipUnlessUpdated`, `WaitValueUpdate` | tick the child only if the blackboard `entry` was written since the node last looked (sequence numbers, BehaviorTree.CPP 4.5) or the child is running; otherwise skipped / running. |
//! | `Script`, `ScriptCondition` | run `code`; success, or the truth of its value. |
//! | `WasEntryUpdated` | success if `entry` was written since the node last looked. |
//! | `UnsetBlackboard` | removes the entry `key` of the node's scope; success. |
//! | `SubTree` | ticks the root of its tree in its own blackboard scope; a completed child is reset. |
//! | custom controls and decorators | their [`ControlNode`] implementation; stubs ([`Registry::register_stub`](super::Registry::register_stub)) of controls are `Sequence`s and of decorators pass their child's status through. |
//!
//! [`Tree::tick_once`] is `Tree::tickOnce` (ticks the root again while it is running and a
//! node asked for a wake-up, so a retry of a failing synchronous action finishes within one
//! call); [`Tree::tick_exactly_once`] is `tickExactlyOnce` (one root tick). After the root
//! completes, its status is reset to idle, as `Tree::tickRoot` does.
//!
//! # Bounds
//! A tree nests at most [`MAX_DEPTH`] levels (subtrees expanded), which instantiation checks
//! before anything else (the description is walked without recursion), so ticks and halts,
//! which recurse once per level, cannot overflow the stack; instantiation itself is iterative
//! and linear in the number of nodes. A tree that BehaviorTree.CPP 4.8.2 loads is instantiated:
//! what it rejects only while ticking (a missing `num_attempts`, `ParallelAll` thresholds above
//! the number of children, the number of children of `IfThenElse`, `WhileDoElse`, `Switch*`)
//! fails at that tick with its message, and [`validate_strict`](super::validate_strict)
//! (`chronomap bt check`) reports it before anything runs, with the node and the attribute.
//!
//! # Not implemented
//! Asynchronous nodes and threads (time is injected; leaves return running instead); the
//! nodes in [`UNSUPPORTED_BUILTINS`](super::UNSUPPORTED_BUILTINS). `ReactiveSequence`'s
//! optional exception for several running children (off by default in BehaviorTree.CPP) is
//! not reproduced.

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap, VecDeque};
use std::fmt;
use std::sync::Arc;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::Status;
use super::blackboard::{Blackboard, DeclaredType, FromValue, ScopeId, Value};
use super::builtin::{BuiltinKind, LoopType, builtin_model};
use super::error::{DefinitionError, DefinitionErrorKind, PortError, TickError, TickErrorKind};
use super::model::{
    BtDocument, NodeCategory, NodeDef, NodeLocation, NodeModel, TreeDef, blackboard_pointer,
};
use super::registry::{
    ControlContext, ControlNode, Defaults, Instance, LeafContext, LeafNode, Ports, Registry,
    port_attribute, read_port, write_port,
};
use super::scripting::{Environment, Program, truthy};
use super::validate::{required_count, validate};

/// The deepest nesting of nodes a tree may have, subtrees expanded (the root is level 1).
/// Deeper trees are refused when instantiated ([`DefinitionErrorKind::TooDeep`]), so that
/// ticking and halting, which recurse once per level, cannot overflow the stack.
pub const MAX_DEPTH: usize = 1000;

/// Hooks around every node's tick: BehaviorTree.CPP's `PreTickCallback` and
/// `PostTickCallback` (`TreeNode::executeTick`), which its `Groot2Publisher` installs for
/// breakpoints and for replacing a node's result. A hook may block (a breakpoint waits there
/// until a client unlocks it).
pub trait TickMonitor: Send {
    /// Before the tick of node `uid` (whose status is `status`, not a completed one) and after
    /// its pre-conditions: a success or failure returned here is the node's result, and the
    /// node is not ticked.
    fn pre_tick(&mut self, uid: u16, status: Status) -> Option<Status> {
        let _ = (uid, status);
        None
    }

    /// After the tick of node `uid` (and its post-conditions), which returned `status`: a
    /// success or failure returned here replaces it.
    fn post_tick(&mut self, uid: u16, status: Status) -> Option<Status> {
        let _ = (uid, status);
        None
    }
}

/// A change of a node's status: what a Groot2 `.btlog` file records.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Transition {
    /// The time of the tick (or halt) in which the status changed.
    pub time: Duration,
    /// The node's uid.
    pub uid: u16,
    /// The status before.
    pub from: Status,
    /// The status after.
    pub to: Status,
}

/// One instance of a tree in the runtime tree: the main tree, or a tree expanded where a
/// `SubTree` node uses it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SubtreeInstance {
    /// The tree ID.
    pub tree_id: String,
    /// The instance path: `""` for the main tree, else the parent's path, `/`, and the
    /// `SubTree` node's name or `ID::uid` (BehaviorTree.CPP's `_fullpath`).
    pub path: String,
    /// The uid of the instance's root node.
    pub root_uid: u16,
    /// The uid of the `SubTree` node that opened it (`None` for the main tree).
    pub subtree_uid: Option<u16>,
    /// Its blackboard scope.
    pub scope: ScopeId,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Builtin(BuiltinKind),
    Leaf,
    Custom,
}

#[derive(Clone, Debug, Default)]
struct ParallelState {
    completed: Vec<bool>,
    successes: usize,
    failures: usize,
}

/// A parsed script and where it comes from.
#[derive(Debug)]
struct Compiled {
    attribute: String,
    code: String,
    program: Program,
}

/// The pre-condition attributes in the order BehaviorTree.CPP checks them (`PreCond`).
const PRE_CONDITIONS: [&str; 4] = ["_failureIf", "_successIf", "_skipIf", "_while"];
/// The post-condition attributes (`PostCond`).
const POST_CONDITIONS: [&str; 4] = ["_onHalted", "_onFailure", "_onSuccess", "_post"];

#[derive(Debug, Default)]
struct Conditions {
    pre: [Option<Compiled>; 4],
    post: [Option<Compiled>; 4],
}

/// A node of a runtime tree. Nodes are stored in depth-first order; a node's index in
/// [`Tree::nodes`] is its uid − 1.
pub struct Node {
    uid: u16,
    id: String,
    name: String,
    category: NodeCategory,
    attributes: Vec<(String, String)>,
    ports: Ports,
    children: Vec<usize>,
    parent: Option<usize>,
    scope: ScopeId,
    status: Status,
    path: String,
    kind: Kind,
    // Per-kind state (BehaviorTree.CPP's member variables).
    index: usize,
    count: i64,
    skipped: usize,
    flag: bool,
    returned: Status,
    running_child: Option<usize>,
    sequence_id: u64,
    parallel: ParallelState,
    deadline: Option<Duration>,
    timer_started: bool,
    child_halted: bool,
    queue: Option<VecDeque<Value>>,
    leaf: Option<Box<dyn LeafNode>>,
    custom: Option<Box<dyn ControlNode>>,
    conditions: Option<Arc<Conditions>>,
    /// The script of `Script`, `ScriptCondition` (`code`) and `Precondition` (`if`).
    code: Option<Arc<Compiled>>,
}

impl Node {
    /// The uid: 1 for the root, then depth-first order with subtrees expanded.
    pub fn uid(&self) -> u16 {
        self.uid
    }

    /// The registration ID (`Sequence`, `OpenDoor`); for a `SubTree` node, the tree ID.
    pub fn id(&self) -> &str {
        &self.id
    }

    /// The instance name (`name` attribute, or the ID).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The category.
    pub fn category(&self) -> NodeCategory {
        self.category
    }

    /// The port attributes as written in the description (for a `SubTree`: its remappings).
    pub fn attributes(&self) -> &[(String, String)] {
        &self.attributes
    }

    /// The ports as the node reads them: `{=}` expanded, defaults of absent ports added
    /// (after the node's own).
    pub fn ports(&self) -> Vec<(String, String)> {
        self.ports.merged()
    }

    /// The children, as indices into [`Tree::nodes`].
    pub fn children(&self) -> &[usize] {
        &self.children
    }

    /// The parent, as an index into [`Tree::nodes`].
    pub fn parent(&self) -> Option<usize> {
        self.parent
    }

    /// The blackboard scope of the node.
    pub fn scope(&self) -> ScopeId {
        self.scope
    }

    /// The current status.
    pub fn status(&self) -> Status {
        self.status
    }

    /// The node's path: its subtree instance's path, `/`, and its name (`ID::uid` when it has
    /// no `name` attribute).
    pub fn path(&self) -> &str {
        &self.path
    }
}

impl fmt::Debug for Node {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Node")
            .field("uid", &self.uid)
            .field("id", &self.id)
            .field("name", &self.name)
            .field("category", &self.category)
            .field("ports", &self.ports.merged())
            .field("children", &self.children)
            .field("status", &self.status)
            .finish_non_exhaustive()
    }
}

/// A behavior tree ready to tick: nodes with state, a blackboard, and the recorded transitions.
pub struct Tree {
    nodes: Vec<Node>,
    subtrees: Vec<SubtreeInstance>,
    models: BTreeMap<String, NodeModel>,
    blackboard: Blackboard,
    enums: Arc<BTreeMap<String, i64>>,
    now: Duration,
    last_tick: Option<Duration>,
    wake_up: bool,
    recording: bool,
    transitions: Vec<Transition>,
    /// An error of a halt made through a [`ControlContext`] (whose methods cannot fail),
    /// raised when the custom node's tick or halt returns.
    pub(crate) halt_error: Option<TickError>,
    monitor: Option<Box<dyn TickMonitor>>,
}

impl fmt::Debug for Tree {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Tree")
            .field("nodes", &self.nodes)
            .field("subtrees", &self.subtrees)
            .field("blackboard", &self.blackboard)
            .finish_non_exhaustive()
    }
}

/// Checks that no tree of `doc` nests deeper than [`MAX_DEPTH`], without recursion, before
/// anything is built (ticking and halting recurse once per level).
fn check_depth(doc: &BtDocument) -> Result<(), DefinitionError> {
    for tree in &doc.trees {
        let mut stack: Vec<(&NodeDef, usize, usize)> = vec![(&tree.root, 1, 0)];
        let mut path: Vec<usize> = Vec::new();
        while let Some((node, depth, k)) = stack.pop() {
            path.truncate(depth.saturating_sub(2));
            if depth > 1 {
                path.push(k);
            }
            if depth > MAX_DEPTH {
                return Err(DefinitionError::at(
                    NodeLocation {
                        tree: tree.id.clone(),
                        path,
                    },
                    DefinitionErrorKind::TooDeep { max: MAX_DEPTH },
                ));
            }
            for (k, child) in node.children.iter().enumerate().rev() {
                stack.push((child, depth + 1, k));
            }
        }
    }
    Ok(())
}

impl Tree {
    /// Instantiates the main tree of `doc` (`main_tree_to_execute`, or the only tree) with the
    /// nodes of `registry`.
    ///
    /// # Errors
    /// Any [`validate`] error; a node with no implementation in the registry
    /// ([`DefinitionErrorKind::NotImplemented`]); more than 65535 nodes; nesting deeper than
    /// [`MAX_DEPTH`]; a script that does not parse; an out-of-range port value.
    pub fn new(doc: &BtDocument, registry: &Registry) -> Result<Tree, DefinitionError> {
        let main = doc.main_tree_id()?.to_owned();
        Tree::with_main(doc, &main, registry)
    }

    /// Instantiates the tree `tree_id` of `doc`.
    ///
    /// # Errors
    /// As [`Tree::new`], and [`DefinitionErrorKind::UnknownTree`] if there is no such tree.
    pub fn with_main(
        doc: &BtDocument,
        tree_id: &str,
        registry: &Registry,
    ) -> Result<Tree, DefinitionError> {
        check_depth(doc)?;
        validate(doc, registry)?;
        let def = doc.tree(tree_id).ok_or_else(|| {
            DefinitionError::document(DefinitionErrorKind::UnknownTree {
                id: tree_id.to_owned(),
            })
        })?;
        let mut tree = Tree {
            nodes: Vec::new(),
            subtrees: Vec::new(),
            models: BTreeMap::new(),
            blackboard: Blackboard::new(),
            enums: Arc::new(registry.enums().clone()),
            now: Duration::ZERO,
            last_tick: None,
            wake_up: false,
            recording: false,
            transitions: Vec::new(),
            halt_error: None,
            monitor: None,
        };
        let scope = tree.blackboard.root();
        tree.subtrees.push(SubtreeInstance {
            tree_id: def.id.clone(),
            path: String::new(),
            root_uid: 1,
            subtree_uid: None,
            scope,
        });
        let mut builder = Builder {
            trees: doc.trees.iter().map(|t| (t.id.as_str(), t)).collect(),
            models: doc.node_models.iter().fold(HashMap::new(), |mut map, m| {
                // The first model of an ID counts, as with `BtDocument::node_model`.
                map.entry(m.id.as_str()).or_insert(m);
                map
            }),
            registry,
            tree,
            defaults: HashMap::new(),
            trail: Vec::new(),
        };
        builder.build(&def.root, &def.id)?;
        Ok(builder.tree)
    }

    /// The nodes in depth-first order (index = uid − 1).
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// The node with uid `uid`.
    pub fn node(&self, uid: u16) -> Option<&Node> {
        usize::from(uid)
            .checked_sub(1)
            .and_then(|i| self.nodes.get(i))
    }

    /// The root node.
    pub fn root(&self) -> &Node {
        &self.nodes[0]
    }

    /// The tree instances: the main tree first, then each expanded subtree in depth-first
    /// order.
    pub fn subtrees(&self) -> &[SubtreeInstance] {
        &self.subtrees
    }

    /// The models of the node IDs used (built-in, registered or declared), by ID.
    pub fn node_models(&self) -> impl Iterator<Item = &NodeModel> {
        self.models.values()
    }

    /// The blackboard.
    pub fn blackboard(&self) -> &Blackboard {
        &self.blackboard
    }

    /// The blackboard, writable (to set inputs before ticking).
    pub fn blackboard_mut(&mut self) -> &mut Blackboard {
        &mut self.blackboard
    }

    /// The enum values scripts see (copied from the registry).
    pub fn enums(&self) -> &BTreeMap<String, i64> {
        &self.enums
    }

    /// The time of the current (or last) tick.
    pub(crate) fn now(&self) -> Duration {
        self.now
    }

    /// Installs (or removes, with `None`) the [`TickMonitor`] whose hooks run around every
    /// node's tick (BehaviorTree.CPP's `PreTickCallback` and `PostTickCallback`, which
    /// `Groot2Publisher` uses for breakpoints and for replacing a node's result).
    pub fn set_tick_monitor(&mut self, monitor: Option<Box<dyn TickMonitor>>) {
        self.monitor = monitor;
    }

    /// Starts or stops recording status transitions (off initially).
    pub fn set_recording(&mut self, on: bool) {
        self.recording = on;
    }

    /// The transitions recorded so far.
    pub fn transitions(&self) -> &[Transition] {
        &self.transitions
    }

    /// Takes the transitions recorded so far.
    pub fn take_transitions(&mut self) -> Vec<Transition> {
        std::mem::take(&mut self.transitions)
    }

    /// One tick as BehaviorTree.CPP's `Tree::tickOnce`: the root is ticked, and ticked again
    /// at once while it returns running after a node asked for a wake-up (a
    /// `RetryUntilSuccessful` or `Repeat` between attempts, an `AsyncSequence` between
    /// children, a `Delay` of 0 ms). `now` is the time of the tick (any origin; never earlier
    /// than the previous tick).
    ///
    /// # Errors
    /// [`TickError`] if a node fails (a port that cannot be read, a leaf error, a condition
    /// returning running, a script error, ...) or `now` goes backwards.
    pub fn tick_once(&mut self, now: Duration) -> Result<Status, TickError> {
        self.tick_root(now, true)
    }

    /// One root tick, as BehaviorTree.CPP's `Tree::tickExactlyOnce`.
    ///
    /// # Errors
    /// As [`Tree::tick_once`].
    pub fn tick_exactly_once(&mut self, now: Duration) -> Result<Status, TickError> {
        self.tick_root(now, false)
    }

    /// Ticks with `tick_once` at `start`, `start + period`, … until the root completes (or
    /// is skipped) or `max_ticks` ticks are done; returns the last status.
    ///
    /// # Errors
    /// As [`Tree::tick_once`].
    pub fn tick_while_running(
        &mut self,
        start: Duration,
        period: Duration,
        max_ticks: usize,
    ) -> Result<Status, TickError> {
        let mut status = Status::Idle;
        let mut now = start;
        for _ in 0..max_ticks {
            status = self.tick_once(now)?;
            if status != Status::Running {
                break;
            }
            now = now.saturating_add(period);
        }
        Ok(status)
    }

    /// Halts the whole tree (BehaviorTree.CPP's `Tree::haltTree`): running nodes are halted
    /// (leaves get their halt hook, `_onHalted` scripts run), every status becomes idle, and
    /// controls start over.
    pub fn halt(&mut self, now: Duration) {
        self.now = self.last_tick.map_or(now, |last| now.max(last));
        // Errors of `_onHalted` scripts cannot be reported from here; the tree is idle after.
        let _ = self.halt_node(0);
        for i in 0..self.nodes.len() {
            if self.nodes[i].status == Status::Running {
                let _ = self.halt_node(i);
            }
            self.set_status(i, Status::Idle);
        }
    }

    fn tick_root(&mut self, now: Duration, follow_wake_ups: bool) -> Result<Status, TickError> {
        if let Some(previous) = self.last_tick.filter(|&last| now < last) {
            return Err(TickError::new(
                None,
                TickErrorKind::ClockWentBackwards { previous, now },
            ));
        }
        self.last_tick = Some(now);
        self.now = now;
        self.wake_up = false;
        let mut status = self.execute_tick(0)?;
        while follow_wake_ups && status == Status::Running && std::mem::take(&mut self.wake_up) {
            status = self.execute_tick(0)?;
        }
        if status.is_completed() {
            self.set_status(0, Status::Idle);
        }
        Ok(status)
    }

    // ------------------------------------------------------------------------------------
    // Statuses, resets and halts

    fn set_status(&mut self, i: usize, to: Status) {
        let node = &mut self.nodes[i];
        if node.status != to {
            if self.recording {
                self.transitions.push(Transition {
                    time: self.now,
                    uid: node.uid,
                    from: node.status,
                    to,
                });
            }
            node.status = to;
        }
    }

    /// `ControlNode::haltChild` / `DecoratorNode::resetChild`.
    pub(crate) fn halt_child(&mut self, child: usize) -> Result<(), TickError> {
        if self.nodes[child].status == Status::Running {
            self.halt_node(child)?;
        }
        self.set_status(child, Status::Idle);
        Ok(())
    }

    /// `ControlNode::resetChildren`.
    pub(crate) fn reset_children(&mut self, i: usize) -> Result<(), TickError> {
        for k in 0..self.nodes[i].children.len() {
            let child = self.nodes[i].children[k];
            self.halt_child(child)?;
        }
        Ok(())
    }

    /// `TreeNode::haltNode`: the node type's `halt()`, which ends with `resetStatus()`, then
    /// the `_onHalted` script. An `_onHalted` script that fails ends the tick that halted the
    /// node with its error, as the exception does in BehaviorTree.CPP.
    fn halt_node(&mut self, i: usize) -> Result<(), TickError> {
        match self.nodes[i].kind {
            Kind::Leaf => {
                if self.nodes[i].status == Status::Running {
                    self.with_leaf(i, |leaf, ctx| {
                        leaf.halt(ctx);
                    });
                }
            }
            Kind::Custom => {
                if let Some(mut custom) = self.nodes[i].custom.take() {
                    let previous = self.nodes[i].status;
                    let mut ctx = ControlContext {
                        tree: self,
                        index: i,
                        previous,
                    };
                    custom.halt(&mut ctx);
                    self.nodes[i].custom = Some(custom);
                    if let Some(error) = self.halt_error.take() {
                        return Err(error);
                    }
                }
                self.reset_children(i)?;
            }
            // `EntryUpdatedDecorator::halt` only forgets that its child runs: the child is not
            // halted and the node's status stays (the parent resets it afterwards).
            Kind::Builtin(BuiltinKind::EntryUpdated { .. }) => {
                self.nodes[i].flag = false;
                return self.run_on_halted(i);
            }
            Kind::Builtin(kind) => {
                if kind == BuiltinKind::TryCatch {
                    self.halt_try_catch(i)?;
                }
                let node = &mut self.nodes[i];
                match kind {
                    // SequenceWithMemory::halt keeps current_child_idx_.
                    BuiltinKind::SequenceWithMemory => node.skipped = 0,
                    BuiltinKind::Sequence
                    | BuiltinKind::Fallback
                    | BuiltinKind::AsyncSequence
                    | BuiltinKind::AsyncFallback
                    | BuiltinKind::IfThenElse
                    | BuiltinKind::TryCatch => {
                        node.index = 0;
                        node.skipped = 0;
                        node.flag = false;
                    }
                    BuiltinKind::Parallel | BuiltinKind::ParallelAll => {
                        node.parallel = ParallelState::default();
                    }
                    BuiltinKind::RetryUntilSuccessful | BuiltinKind::Repeat => node.count = 0,
                    BuiltinKind::Timeout | BuiltinKind::Delay => {
                        node.timer_started = false;
                        node.deadline = None;
                    }
                    BuiltinKind::Switch(_) => node.running_child = None,
                    // `LoopNode`, `PreconditionNode` (its `_children_running`) and `RunOnceNode`
                    // keep their state: `DecoratorNode::halt` only resets the child.
                    _ => {}
                }
                self.reset_children(i)?;
            }
        }
        self.set_status(i, Status::Idle);
        self.run_on_halted(i)
    }

    /// The `_onHalted` script of node `i`.
    fn run_on_halted(&mut self, i: usize) -> Result<(), TickError> {
        if let Some(conditions) = self.nodes[i].conditions.clone()
            && let Some(script) = &conditions.post[0]
        {
            self.eval(i, script)?;
        }
        Ok(())
    }

    fn with_leaf<R>(
        &mut self,
        i: usize,
        f: impl FnOnce(&mut dyn LeafNode, &mut LeafContext<'_>) -> R,
    ) -> R {
        let Tree {
            nodes,
            blackboard,
            now,
            ..
        } = self;
        let node = &mut nodes[i];
        let leaf = node
            .leaf
            .as_deref_mut()
            .expect("leaf nodes hold an implementation");
        let status = match node.status {
            Status::Skipped => Status::Idle,
            other => other,
        };
        let mut ctx = LeafContext {
            uid: node.uid,
            id: &node.id,
            name: &node.name,
            ports: &node.ports,
            status,
            now: *now,
            blackboard,
            scope: node.scope,
        };
        f(leaf, &mut ctx)
    }

    fn error(&self, i: usize, kind: impl Into<TickErrorKind>) -> TickError {
        let node = &self.nodes[i];
        TickError::new(
            Some((node.uid, node.name.clone(), node.id.clone())),
            kind.into(),
        )
    }

    pub(crate) fn node_error(&self, i: usize, kind: TickErrorKind) -> TickError {
        self.error(i, kind)
    }

    pub(crate) fn port<T: FromValue>(&self, i: usize, port: &str) -> Result<T, TickError> {
        let node = &self.nodes[i];
        read_port(&node.ports, port, &self.blackboard, node.scope).map_err(|e| self.error(i, e))
    }

    pub(crate) fn set_port(&mut self, i: usize, port: &str, value: Value) -> Result<(), TickError> {
        let node = &self.nodes[i];
        write_port(&node.ports, port, value, &mut self.blackboard, node.scope)
            .map_err(|e| self.error(i, e))
    }

    /// A status given as text in a port (`else`, `if_empty`).
    fn status_port(&self, i: usize, port: &str) -> Result<Status, TickError> {
        let text: String = self.port(i, port)?;
        text.trim()
            .parse::<Status>()
            .ok()
            .filter(|s| *s != Status::Idle)
            .ok_or_else(|| {
                self.error(
                    i,
                    PortError::BadValue {
                        port: port.to_owned(),
                        value: text,
                        expected: "SUCCESS, FAILURE, RUNNING or SKIPPED",
                    },
                )
            })
    }

    /// Evaluates a script in the node's scope.
    fn eval(&mut self, i: usize, script: &Compiled) -> Result<Value, TickError> {
        let scope = self.nodes[i].scope;
        let enums = Arc::clone(&self.enums);
        let mut env = Environment::new(&mut self.blackboard, scope, &enums);
        script.program.eval(&mut env).map_err(|error| {
            self.error(
                i,
                TickErrorKind::Script {
                    attribute: script.attribute.clone(),
                    code: script.code.clone(),
                    error,
                },
            )
        })
    }

    fn eval_bool(&mut self, i: usize, script: &Compiled) -> Result<bool, TickError> {
        let value = self.eval(i, script)?;
        truthy(&value).map_err(|error| {
            self.error(
                i,
                TickErrorKind::Script {
                    attribute: script.attribute.clone(),
                    code: script.code.clone(),
                    error,
                },
            )
        })
    }

    /// The script of a `code`/`if` port: parsed at instantiation for a literal, or read from
    /// the blackboard (and parsed again when it changed: BehaviorTree.CPP's `loadExecutor`).
    fn code(&mut self, i: usize, port: &str) -> Result<Arc<Compiled>, TickError> {
        let raw = port_attribute(&self.nodes[i].ports, port).unwrap_or("");
        if blackboard_pointer(raw).is_none()
            && let Some(code) = &self.nodes[i].code
        {
            return Ok(Arc::clone(code));
        }
        let text: String = self.port(i, port)?;
        if let Some(code) = &self.nodes[i].code
            && code.code == text
        {
            return Ok(Arc::clone(code));
        }
        let program = Program::parse(&text).map_err(|error| {
            self.error(
                i,
                TickErrorKind::Script {
                    attribute: port.to_owned(),
                    code: text.clone(),
                    error,
                },
            )
        })?;
        let compiled = Arc::new(Compiled {
            attribute: port.to_owned(),
            code: text,
            program,
        });
        self.nodes[i].code = Some(Arc::clone(&compiled));
        Ok(compiled)
    }

    // ------------------------------------------------------------------------------------
    // Ticks

    /// `TreeNode::executeTick`: pre-conditions, the node's tick, post-conditions, then its
    /// status becomes the result — except a skipped result, which leaves the status as it was
    /// (idle, or running for a control node that set itself running): "preserve the IDLE state
    /// if skipped, but communicate SKIPPED to parent". A tick that returns idle is an error, as
    /// `setStatus(IDLE)` throws. Decorators then reset a child that completed
    /// (`DecoratorNode::executeTick`), after their own status changed.
    pub(crate) fn execute_tick(&mut self, i: usize) -> Result<Status, TickError> {
        let conditions = self.nodes[i].conditions.clone();
        let pre = match &conditions {
            Some(c) => self.check_preconditions(i, c)?,
            None => None,
        };
        let status = match pre {
            Some(status) => status,
            None => {
                // An injected pre-tick hook may give the result instead of the tick (not for a
                // node that holds a completed status).
                let replaced = match self.monitor.as_mut() {
                    Some(m) if !self.nodes[i].status.is_completed() => m
                        .pre_tick(self.nodes[i].uid, self.nodes[i].status)
                        .filter(|s| s.is_completed()),
                    _ => None,
                };
                match replaced {
                    Some(status) => status,
                    None => self.tick_node(i)?,
                }
            }
        };
        if let Some(c) = &conditions
            && status.is_completed()
        {
            let slot = if status == Status::Success { 2 } else { 1 };
            for script in [&c.post[slot], &c.post[3]].into_iter().flatten() {
                self.eval(i, script)?;
            }
        }
        let uid = self.nodes[i].uid;
        let status = match self.monitor.as_mut() {
            Some(m) => m
                .post_tick(uid, status)
                .filter(|s| s.is_completed())
                .unwrap_or(status),
            None => status,
        };
        match status {
            Status::Skipped => {}
            Status::Idle => return Err(self.error(i, TickErrorKind::SetIdle)),
            status => self.set_status(i, status),
        }
        if self.is_decorator(i)
            && let Some(&child) = self.nodes[i].children.first()
            && self.nodes[child].status.is_completed()
        {
            self.set_status(child, Status::Idle);
        }
        Ok(status)
    }

    /// Whether node `i` is a decorator (a `SubTree` node is one: `SubTreeNode` derives from
    /// `DecoratorNode`).
    fn is_decorator(&self, i: usize) -> bool {
        matches!(
            self.nodes[i].category,
            NodeCategory::Decorator | NodeCategory::SubTree
        )
    }

    /// `TreeNode::checkPreConditions`.
    fn check_preconditions(
        &mut self,
        i: usize,
        conditions: &Conditions,
    ) -> Result<Option<Status>, TickError> {
        let status = self.nodes[i].status;
        for (slot, script) in conditions.pre.iter().enumerate() {
            let Some(script) = script else { continue };
            if !status.is_active() {
                let holds = self.eval_bool(i, script)?;
                match (slot, holds) {
                    (0, true) => return Ok(Some(Status::Failure)),
                    (1, true) => return Ok(Some(Status::Success)),
                    (2, true) => return Ok(Some(Status::Skipped)),
                    (3, false) => return Ok(Some(Status::Skipped)),
                    _ => {}
                }
            } else if status == Status::Running && slot == 3 && !self.eval_bool(i, script)? {
                self.halt_node(i)?;
                return Ok(Some(Status::Skipped));
            }
        }
        Ok(None)
    }

    fn tick_node(&mut self, i: usize) -> Result<Status, TickError> {
        use BuiltinKind as B;
        match self.nodes[i].kind {
            Kind::Leaf => self.tick_leaf(i),
            Kind::Custom => self.tick_custom(i),
            Kind::Builtin(kind) => match kind {
                B::Sequence => self.tick_in_order(i, true, false, false),
                B::SequenceWithMemory => self.tick_in_order(i, true, true, false),
                B::AsyncSequence => self.tick_in_order(i, true, false, true),
                B::Fallback => self.tick_in_order(i, false, false, false),
                B::AsyncFallback => self.tick_in_order(i, false, false, true),
                B::ReactiveSequence => self.tick_reactive(i, true),
                B::ReactiveFallback => self.tick_reactive(i, false),
                B::Parallel => self.tick_parallel(i),
                B::ParallelAll => self.tick_parallel_all(i),
                B::IfThenElse => self.tick_if_then_else(i),
                B::WhileDoElse => self.tick_while_do_else(i),
                B::Switch(n) => self.tick_switch(i, n),
                B::TryCatch => self.tick_try_catch(i),
                B::Inverter | B::ForceSuccess | B::ForceFailure | B::PassThrough => {
                    self.tick_simple_decorator(i, kind)
                }
                B::RetryUntilSuccessful => self.tick_loop(i, Status::Failure),
                B::Repeat => self.tick_loop(i, Status::Success),
                B::Timeout => self.tick_timeout(i),
                B::Delay => self.tick_delay(i),
                B::KeepRunningUntilFailure => self.tick_keep_running(i),
                B::Loop(ty) => self.tick_queue_loop(i, ty),
                B::Precondition => self.tick_precondition(i),
                B::RunOnce => self.tick_run_once(i),
                B::EntryUpdated { skip } => self.tick_entry_updated(i, skip),
                B::SubTree => self.tick_subtree(i),
                B::Script => {
                    let code = self.code(i, "code")?;
                    self.eval(i, &code)?;
                    Ok(Status::Success)
                }
                B::ScriptCondition => {
                    let code = self.code(i, "code")?;
                    Ok(if self.eval_bool(i, &code)? {
                        Status::Success
                    } else {
                        Status::Failure
                    })
                }
                B::WasEntryUpdated => Ok(if self.entry_updated(i) {
                    Status::Success
                } else {
                    Status::Failure
                }),
                B::UnsetBlackboard => {
                    let key: String = self.port(i, "key")?;
                    let scope = self.nodes[i].scope;
                    self.blackboard.unset_in(scope, &key);
                    Ok(Status::Success)
                }
            },
        }
    }

    fn tick_leaf(&mut self, i: usize) -> Result<Status, TickError> {
        let result = self.with_leaf(i, |leaf, ctx| leaf.tick(ctx));
        match result {
            Err(e) => Err(self.error(i, e)),
            Ok(Status::Idle) => Err(self.error(i, TickErrorKind::ReturnedIdle)),
            Ok(Status::Running) if self.nodes[i].category == NodeCategory::Condition => {
                Err(self.error(i, TickErrorKind::ConditionRunning))
            }
            Ok(status) => Ok(status),
        }
    }

    fn tick_custom(&mut self, i: usize) -> Result<Status, TickError> {
        let Some(mut custom) = self.nodes[i].custom.take() else {
            return Err(self.error(
                i,
                TickErrorKind::Node("ticked again from its own tick".to_owned()),
            ));
        };
        let previous = match self.nodes[i].status {
            Status::Skipped => Status::Idle,
            other => other,
        };
        self.set_status(i, Status::Running);
        let mut ctx = ControlContext {
            tree: self,
            index: i,
            previous,
        };
        let result = custom.tick(&mut ctx);
        self.nodes[i].custom = Some(custom);
        if let Some(error) = self.halt_error.take() {
            return Err(error);
        }
        match result? {
            Status::Idle => Err(self.error(i, TickErrorKind::ReturnedIdle)),
            status => Ok(status),
        }
    }

    /// An error BehaviorTree.CPP raises while ticking node `i`, with its message.
    fn refused(&self, i: usize, message: &str) -> TickError {
        self.error(i, TickErrorKind::Refused(message.to_owned()))
    }

    fn returned_idle(&self, i: usize) -> TickError {
        self.error(i, TickErrorKind::ReturnedIdle)
    }

    /// `SequenceNode::tick`, `SequenceWithMemory::tick` (`with_memory`), `FallbackNode::tick`
    /// (not `sequence`), and the asynchronous variants: the children in order from the current
    /// one, until one returns the status that stops the node ([`stop_and_otherwise`]).
    fn tick_in_order(
        &mut self,
        i: usize,
        sequence: bool,
        with_memory: bool,
        asynchronous: bool,
    ) -> Result<Status, TickError> {
        let (stop, otherwise) = stop_and_otherwise(sequence);
        if !self.nodes[i].status.is_active() {
            self.nodes[i].skipped = 0;
        }
        self.set_status(i, Status::Running);
        let n = self.nodes[i].children.len();
        while self.nodes[i].index < n {
            let current = self.nodes[i].index;
            let child = self.nodes[i].children[current];
            let previous = self.nodes[child].status;
            match self.execute_tick(child)? {
                Status::Running => return Ok(Status::Running),
                Status::Idle => return Err(self.returned_idle(child)),
                Status::Skipped => {
                    self.nodes[i].index += 1;
                    self.nodes[i].skipped += 1;
                }
                status if status == stop => {
                    if with_memory {
                        // "DO NOT reset current_child_idx_ on failure"
                        for k in current..n {
                            let c = self.nodes[i].children[k];
                            self.halt_child(c)?;
                        }
                    } else {
                        self.reset_children(i)?;
                        self.nodes[i].index = 0;
                    }
                    return Ok(stop);
                }
                _ => {
                    self.nodes[i].index += 1;
                    // "Return the execution flow if the child is async, to make this
                    // interruptible": the asynchronous variants, and `SequenceWithMemory`,
                    // which asks `requiresWakeUp()` alone (true in every tree a factory builds).
                    if (asynchronous || with_memory)
                        && previous == Status::Idle
                        && self.nodes[i].index < n
                    {
                        self.wake_up = true;
                        return Ok(Status::Running);
                    }
                }
            }
        }
        let all_skipped = self.nodes[i].skipped == n;
        self.reset_children(i)?;
        self.nodes[i].index = 0;
        self.nodes[i].skipped = 0;
        Ok(if all_skipped {
            Status::Skipped
        } else {
            otherwise
        })
    }

    /// `ReactiveSequence::tick` (`sequence`) and `ReactiveFallback::tick`.
    fn tick_reactive(&mut self, i: usize, sequence: bool) -> Result<Status, TickError> {
        let (stop, otherwise) = stop_and_otherwise(sequence);
        self.set_status(i, Status::Running);
        let n = self.nodes[i].children.len();
        let mut all_skipped = true;
        for k in 0..n {
            let child = self.nodes[i].children[k];
            let status = self.execute_tick(child)?;
            all_skipped &= status == Status::Skipped;
            if status == Status::Running {
                // "reset the previous children, to make sure that they are in IDLE state the
                // next time we tick them" — and halt any other running child.
                for j in (0..n).filter(|&j| j != k) {
                    let other = self.nodes[i].children[j];
                    self.halt_child(other)?;
                }
                return Ok(Status::Running);
            }
            if status == stop {
                self.reset_children(i)?;
                return Ok(stop);
            }
            if status == Status::Skipped {
                // "to allow it to be skipped again, we must reset the node"
                self.halt_child(child)?;
            }
        }
        self.reset_children(i)?;
        Ok(if all_skipped {
            Status::Skipped
        } else {
            otherwise
        })
    }

    /// `ParallelNode::tick`.
    /// Gives a `Parallel`/`ParallelAll` node one "completed" flag per child, unless it has
    /// them already (BehaviorTree.CPP's `completed_list_` is kept across ticks until reset).
    fn start_parallel(&mut self, i: usize, n: usize) {
        if self.nodes[i].parallel.completed.len() != n {
            self.nodes[i].parallel = ParallelState {
                completed: vec![false; n],
                ..ParallelState::default()
            };
        }
    }

    fn tick_parallel(&mut self, i: usize) -> Result<Status, TickError> {
        let success_threshold: i64 = self.port(i, "success_count")?;
        let failure_threshold: i64 = self.port(i, "failure_count")?;
        let n = self.nodes[i].children.len();
        let required_success = required_count(success_threshold, n);
        let required_failure = required_count(failure_threshold, n);
        for (port, threshold, required) in [
            ("success_count", success_threshold, required_success),
            ("failure_count", failure_threshold, required_failure),
        ] {
            if n < required {
                return Err(self.error(
                    i,
                    TickErrorKind::ParallelThreshold {
                        port,
                        threshold,
                        required,
                        children: n,
                    },
                ));
            }
        }
        self.set_status(i, Status::Running);
        self.start_parallel(i, n);
        let mut skipped = 0;
        for k in 0..n {
            if !self.nodes[i].parallel.completed[k] {
                let child = self.nodes[i].children[k];
                match self.execute_tick(child)? {
                    Status::Success => {
                        let state = &mut self.nodes[i].parallel;
                        state.completed[k] = true;
                        state.successes += 1;
                    }
                    Status::Failure => {
                        let state = &mut self.nodes[i].parallel;
                        state.completed[k] = true;
                        state.failures += 1;
                    }
                    Status::Skipped => skipped += 1,
                    Status::Running => {}
                    Status::Idle => return Err(self.returned_idle(child)),
                }
            }
            let state = &self.nodes[i].parallel;
            let (successes, failures) = (state.successes, state.failures);
            if successes >= required_success
                || (success_threshold < 0 && successes + skipped >= required_success)
            {
                self.nodes[i].parallel = ParallelState::default();
                self.reset_children(i)?;
                return Ok(Status::Success);
            }
            // "It fails if it is not possible to succeed anymore or if number of failures are
            // equal to failure_threshold_"
            if n - failures < required_success || failures == required_failure {
                self.nodes[i].parallel = ParallelState::default();
                self.reset_children(i)?;
                return Ok(Status::Failure);
            }
        }
        Ok(if skipped == n {
            Status::Skipped
        } else {
            Status::Running
        })
    }

    /// `ParallelAllNode::tick`.
    fn tick_parallel_all(&mut self, i: usize) -> Result<Status, TickError> {
        let max_failures: i64 = self.port(i, "max_failures")?;
        let n = self.nodes[i].children.len();
        let threshold = required_count(max_failures, n);
        if n < threshold {
            return Err(self.error(
                i,
                TickErrorKind::ParallelThreshold {
                    port: "max_failures",
                    threshold: max_failures,
                    required: threshold,
                    children: n,
                },
            ));
        }
        self.set_status(i, Status::Running);
        self.start_parallel(i, n);
        let mut skipped = 0;
        let mut completed = 0;
        for k in 0..n {
            if self.nodes[i].parallel.completed[k] {
                completed += 1;
                continue;
            }
            let child = self.nodes[i].children[k];
            match self.execute_tick(child)? {
                Status::Success => {
                    self.nodes[i].parallel.completed[k] = true;
                    completed += 1;
                }
                Status::Failure => {
                    let state = &mut self.nodes[i].parallel;
                    state.completed[k] = true;
                    state.failures += 1;
                    completed += 1;
                }
                Status::Skipped => skipped += 1,
                Status::Running => {}
                Status::Idle => return Err(self.returned_idle(child)),
            }
        }
        if skipped == n {
            return Ok(Status::Skipped);
        }
        if skipped + completed >= n {
            let failures = self.nodes[i].parallel.failures;
            self.reset_children(i)?;
            self.nodes[i].parallel = ParallelState::default();
            return Ok(if failures >= threshold {
                Status::Failure
            } else {
                Status::Success
            });
        }
        Ok(Status::Running)
    }

    /// `IfThenElseNode::tick` (`index` is `child_idx_`).
    fn tick_if_then_else(&mut self, i: usize) -> Result<Status, TickError> {
        let n = self.nodes[i].children.len();
        if !(2..=3).contains(&n) {
            return Err(self.refused(i, "IfThenElseNode must have either 2 or 3 children"));
        }
        self.set_status(i, Status::Running);
        if self.nodes[i].index == 0 {
            let condition = self.nodes[i].children[0];
            match self.execute_tick(condition)? {
                Status::Running => return Ok(Status::Running),
                Status::Success => self.nodes[i].index = 1,
                Status::Failure if n == 3 => self.nodes[i].index = 2,
                Status::Failure => return Ok(Status::Failure),
                // BehaviorTree.CPP has no branch for a skipped condition.
                Status::Skipped => {
                    return Err(self.refused(i, "Something unexpected happened in IfThenElseNode"));
                }
                Status::Idle => return Err(self.returned_idle(condition)),
            }
        }
        let branch = self.nodes[i].children[self.nodes[i].index];
        let status = self.execute_tick(branch)?;
        if status == Status::Running {
            return Ok(Status::Running);
        }
        self.reset_children(i)?;
        self.nodes[i].index = 0;
        Ok(status)
    }

    /// `WhileDoElseNode::tick`.
    fn tick_while_do_else(&mut self, i: usize) -> Result<Status, TickError> {
        let n = self.nodes[i].children.len();
        if !(2..=3).contains(&n) {
            return Err(self.refused(i, "WhileDoElseNode must have either 2 or 3 children"));
        }
        self.set_status(i, Status::Running);
        let condition = self.nodes[i].children[0];
        let status = match self.execute_tick(condition)? {
            Status::Running => return Ok(Status::Running),
            Status::Success => {
                if n == 3 {
                    let other = self.nodes[i].children[2];
                    self.halt_child(other)?;
                }
                let branch = self.nodes[i].children[1];
                self.execute_tick(branch)?
            }
            Status::Failure if n == 3 => {
                let other = self.nodes[i].children[1];
                self.halt_child(other)?;
                let branch = self.nodes[i].children[2];
                self.execute_tick(branch)?
            }
            Status::Failure => Status::Failure,
            // BehaviorTree.CPP has no branch for a skipped condition: it resets the children
            // and returns IDLE, which `executeTick` refuses.
            Status::Skipped => Status::Idle,
            Status::Idle => return Err(self.returned_idle(condition)),
        };
        if status == Status::Running {
            return Ok(Status::Running);
        }
        self.reset_children(i)?;
        Ok(status)
    }

    /// `SwitchNode<N>::tick`.
    fn tick_switch(&mut self, i: usize, cases: usize) -> Result<Status, TickError> {
        if self.nodes[i].children.len() != cases + 1 {
            return Err(self.refused(
                i,
                "Wrong number of children in SwitchNode; must be (num_cases + default)",
            ));
        }
        let mut matched = cases;
        if let Ok(variable) = self.port::<String>(i, "variable") {
            for k in 0..cases {
                if let Ok(value) = self.port::<String>(i, &format!("case_{}", k + 1))
                    && check_string_equality(&variable, &value, &self.enums)
                {
                    matched = k;
                    break;
                }
            }
        }
        // A `SwitchNode` does not set itself running: its status is its child's.
        if let Some(running) = self.nodes[i].running_child
            && running != matched
        {
            let child = self.nodes[i].children[running];
            self.halt_child(child)?;
        }
        let child = self.nodes[i].children[matched];
        let status = self.execute_tick(child)?;
        match status {
            Status::Skipped => self.nodes[i].running_child = None,
            Status::Running => self.nodes[i].running_child = Some(matched),
            _ => {
                self.reset_children(i)?;
                self.nodes[i].running_child = None;
            }
        }
        Ok(status)
    }

    /// `TryCatchNode::tick` (`flag` is `in_catch_`).
    fn tick_try_catch(&mut self, i: usize) -> Result<Status, TickError> {
        let n = self.nodes[i].children.len();
        if !self.nodes[i].status.is_active() {
            self.nodes[i].skipped = 0;
            self.nodes[i].flag = false;
        }
        self.set_status(i, Status::Running);
        let tries = n - 1;
        let catch = self.nodes[i].children[tries];
        if !self.nodes[i].flag {
            while self.nodes[i].index < tries {
                let child = self.nodes[i].children[self.nodes[i].index];
                match self.execute_tick(child)? {
                    Status::Running => return Ok(Status::Running),
                    Status::Success => self.nodes[i].index += 1,
                    Status::Skipped => {
                        self.nodes[i].index += 1;
                        self.nodes[i].skipped += 1;
                    }
                    Status::Failure => {
                        for k in 0..tries {
                            let c = self.nodes[i].children[k];
                            self.halt_child(c)?;
                        }
                        self.nodes[i].index = 0;
                        self.nodes[i].flag = true;
                        break;
                    }
                    Status::Idle => return Err(self.returned_idle(child)),
                }
            }
            if !self.nodes[i].flag {
                let all_skipped = self.nodes[i].skipped == tries;
                self.reset_children(i)?;
                let node = &mut self.nodes[i];
                node.index = 0;
                node.skipped = 0;
                return Ok(if all_skipped {
                    Status::Skipped
                } else {
                    Status::Success
                });
            }
        }
        // In the catch: run it to completion, then fail whatever it returned.
        if self.execute_tick(catch)? == Status::Running {
            return Ok(Status::Running);
        }
        self.reset_children(i)?;
        let node = &mut self.nodes[i];
        node.index = 0;
        node.flag = false;
        Ok(Status::Failure)
    }

    /// `TryCatchNode::halt` with `catch_on_halt`: during the try, the catch runs once.
    fn halt_try_catch(&mut self, i: usize) -> Result<(), TickError> {
        let catch_on_halt = self.port::<bool>(i, "catch_on_halt").unwrap_or(false);
        if catch_on_halt && !self.nodes[i].flag && self.nodes[i].status.is_active() {
            let n = self.nodes[i].children.len();
            for k in 0..n - 1 {
                let c = self.nodes[i].children[k];
                self.halt_child(c)?;
            }
            let catch = self.nodes[i].children[n - 1];
            // "best-effort cleanup during halt": errors of the catch's tick are not reported.
            if matches!(self.execute_tick(catch), Ok(Status::Running)) {
                self.halt_child(catch)?;
            }
        }
        Ok(())
    }

    /// `InverterNode::tick`, `ForceSuccessNode::tick`, `ForceFailureNode::tick`, and the
    /// pass-through of decorator stubs.
    fn tick_simple_decorator(&mut self, i: usize, kind: BuiltinKind) -> Result<Status, TickError> {
        let child = self.nodes[i].children[0];
        if kind == BuiltinKind::PassThrough {
            // `SimpleDecoratorNode`: the child's status; `executeTick` resets a completed
            // child after the decorator's own status changed.
            return self.execute_tick(child);
        }
        self.set_status(i, Status::Running);
        let status = self.execute_tick(child)?;
        if !status.is_completed() {
            return Ok(status);
        }
        self.halt_child(child)?;
        Ok(match kind {
            BuiltinKind::Inverter if status == Status::Success => Status::Failure,
            BuiltinKind::Inverter => Status::Success,
            BuiltinKind::ForceSuccess => Status::Success,
            BuiltinKind::ForceFailure => Status::Failure,
            _ => status,
        })
    }

    /// `RetryNode::tick` (`again_on` = failure) and `RepeatNode::tick` (success); `flag` is
    /// `all_skipped_`.
    fn tick_loop(&mut self, i: usize, again_on: Status) -> Result<Status, TickError> {
        let port = if again_on == Status::Failure {
            "num_attempts"
        } else {
            "num_cycles"
        };
        let limit: i64 = self.port(i, port).map_err(|_| {
            let node = if again_on == Status::Failure {
                "RetryNode"
            } else {
                "RepeatNode"
            };
            self.refused(i, &format!("Missing parameter [{port}] in {node}"))
        })?;
        let mut count = self.nodes[i].count;
        let mut do_loop = count < limit || limit == -1;
        self.set_status(i, Status::Running);
        let child = self.nodes[i].children[0];
        while do_loop {
            let previous = self.nodes[child].status;
            let status = self.execute_tick(child)?;
            match status {
                Status::Running => return Ok(Status::Running),
                Status::Skipped => {
                    // "the child has been skipped. Skip the decorator too. Don't reset the
                    // counter, though!"
                    self.halt_child(child)?;
                    return Ok(Status::Skipped);
                }
                Status::Idle => return Err(self.returned_idle(child)),
                status if status != again_on => {
                    // Retry: success; Repeat: failure. Ends the loop with the child's result.
                    self.nodes[i].count = 0;
                    self.halt_child(child)?;
                    return Ok(status);
                }
                _ => {}
            }
            count = count.saturating_add(1);
            do_loop = count < limit || limit == -1;
            self.nodes[i].count = count;
            self.halt_child(child)?;
            // "Return the execution flow if the child is async, to make this interruptable."
            if previous == Status::Idle && do_loop {
                self.wake_up = true;
                return Ok(Status::Running);
            }
        }
        self.nodes[i].count = 0;
        Ok(if again_on == Status::Failure {
            Status::Failure
        } else {
            Status::Success
        })
    }

    /// `TimeoutNode::tick` with the timer replaced by the injected clock.
    fn tick_timeout(&mut self, i: usize) -> Result<Status, TickError> {
        let msec: u64 = self.port(i, "msec")?;
        if !self.nodes[i].timer_started {
            let node = &mut self.nodes[i];
            node.timer_started = true;
            node.child_halted = false;
            node.deadline =
                (msec > 0).then(|| self.now.saturating_add(Duration::from_millis(msec)));
            self.set_status(i, Status::Running);
        }
        let child = self.nodes[i].children[0];
        let expired = self.nodes[i].deadline.is_some_and(|d| self.now >= d);
        if expired && !self.nodes[i].child_halted && self.nodes[child].status == Status::Running {
            // The timer callback: "if(child()->status() == NodeStatus::RUNNING) {
            // child_halted_ = true; haltChild(); }"
            self.nodes[i].child_halted = true;
            self.halt_child(child)?;
        }
        if self.nodes[i].child_halted {
            self.stop_timer(i);
            return Ok(Status::Failure);
        }
        self.tick_timed_child(i)
    }

    /// Forgets the timer of a `Timeout` or `Delay`.
    fn stop_timer(&mut self, i: usize) {
        let node = &mut self.nodes[i];
        node.timer_started = false;
        node.deadline = None;
    }

    /// Ticks the child of a `Timeout` or `Delay` once its time has come; a completed child
    /// ends the timer and is reset.
    fn tick_timed_child(&mut self, i: usize) -> Result<Status, TickError> {
        let child = self.nodes[i].children[0];
        let status = self.execute_tick(child)?;
        if status.is_completed() {
            self.stop_timer(i);
            self.halt_child(child)?;
        }
        Ok(status)
    }

    /// `DelayNode::tick` with the timer replaced by the injected clock.
    fn tick_delay(&mut self, i: usize) -> Result<Status, TickError> {
        let msec: u64 = self.port(i, "delay_msec")?;
        if !self.nodes[i].timer_started {
            let node = &mut self.nodes[i];
            node.timer_started = true;
            node.deadline = Some(self.now.saturating_add(Duration::from_millis(msec)));
            self.set_status(i, Status::Running);
        }
        if self.nodes[i].deadline.is_some_and(|d| self.now < d) {
            return Ok(Status::Running);
        }
        self.tick_timed_child(i)
    }

    /// `KeepRunningUntilFailureNode::tick`.
    fn tick_keep_running(&mut self, i: usize) -> Result<Status, TickError> {
        self.set_status(i, Status::Running);
        let child = self.nodes[i].children[0];
        match self.execute_tick(child)? {
            Status::Failure => {
                self.halt_child(child)?;
                Ok(Status::Failure)
            }
            Status::Success => {
                self.halt_child(child)?;
                Ok(Status::Running)
            }
            // BehaviorTree.CPP returns its own status (running) for anything else.
            _ => Ok(Status::Running),
        }
    }

    /// `LoopNode<T>::tick` (`flag` is `child_running_`, `queue` the copy of a literal queue).
    fn tick_queue_loop(&mut self, i: usize, ty: LoopType) -> Result<Status, TickError> {
        let raw = port_attribute(&self.nodes[i].ports, "queue")
            .unwrap_or("")
            .to_owned();
        let key = blackboard_pointer(&raw).map(str::to_owned);
        if !self.nodes[i].status.is_active() {
            self.nodes[i].flag = false;
            if key.is_none() {
                let items = Vec::<Value>::from_value(&Value::Str(raw.clone())).unwrap_or_default();
                self.nodes[i].queue = Some(items.into());
            }
        }
        let mut popped = false;
        if !self.nodes[i].flag {
            let front = match &key {
                Some(key) => {
                    let scope = self.nodes[i].scope;
                    let items = self
                        .blackboard
                        .get_in(scope, key)
                        .and_then(Vec::<Value>::from_value)
                        .unwrap_or_default();
                    let mut items = VecDeque::from(items);
                    let front = items.pop_front();
                    if front.is_some() {
                        self.blackboard
                            .set_in(scope, key, Value::List(items.into()))
                            .map_err(|error| {
                                self.error(
                                    i,
                                    PortError::Blackboard {
                                        port: "queue".to_owned(),
                                        error,
                                    },
                                )
                            })?;
                    }
                    front
                }
                None => self.nodes[i].queue.as_mut().and_then(VecDeque::pop_front),
            };
            if let Some(item) = front {
                popped = true;
                let converted = match ty {
                    LoopType::Int => i64::from_value(&item).map(Value::Int),
                    LoopType::Double => f64::from_value(&item).map(Value::Double),
                    LoopType::Bool => bool::from_value(&item).map(Value::Bool),
                    LoopType::String => Some(Value::Str(item.to_string())),
                };
                let value = converted.ok_or_else(|| {
                    self.error(
                        i,
                        PortError::BadValue {
                            port: "queue".to_owned(),
                            value: item.to_string(),
                            expected: match ty {
                                LoopType::Int => i64::EXPECTED,
                                LoopType::Double => f64::EXPECTED,
                                LoopType::Bool => bool::EXPECTED,
                                LoopType::String => String::EXPECTED,
                            },
                        },
                    )
                })?;
                self.set_port(i, "value", value)?;
            }
        }
        if !popped && !self.nodes[i].flag {
            return self.status_port(i, "if_empty");
        }
        if self.nodes[i].status == Status::Idle {
            self.set_status(i, Status::Running);
        }
        let child = self.nodes[i].children[0];
        let status = self.execute_tick(child)?;
        self.nodes[i].flag = status == Status::Running;
        if status.is_completed() {
            self.halt_child(child)?;
        }
        Ok(if status == Status::Failure {
            Status::Failure
        } else {
            Status::Running
        })
    }

    /// `PreconditionNode::tick`.
    fn tick_precondition(&mut self, i: usize) -> Result<Status, TickError> {
        let code = self.code(i, "if")?;
        let otherwise = self.status_port(i, "else")?;
        let child = self.nodes[i].children[0];
        // `_children_running` (`flag`) survives a halt: a halted precondition whose child ran
        // ticks the child again without evaluating `if`.
        let tick_child = self.nodes[i].flag || {
            let holds = self.eval_bool(i, &code)?;
            self.nodes[i].flag = holds;
            holds
        };
        if !tick_child {
            return Ok(otherwise);
        }
        let status = self.execute_tick(child)?;
        if status.is_completed() {
            self.halt_child(child)?;
            self.nodes[i].flag = false;
        }
        Ok(status)
    }

    /// `RunOnceNode::tick` (`flag` is `already_ticked_`).
    fn tick_run_once(&mut self, i: usize) -> Result<Status, TickError> {
        let skip: bool = self.port(i, "then_skip")?;
        if self.nodes[i].flag {
            return Ok(if skip {
                Status::Skipped
            } else {
                self.nodes[i].returned
            });
        }
        self.set_status(i, Status::Running);
        let child = self.nodes[i].children[0];
        let status = self.execute_tick(child)?;
        if status.is_completed() {
            self.nodes[i].flag = true;
            self.nodes[i].returned = status;
            self.halt_child(child)?;
        }
        Ok(status)
    }

    /// Whether the blackboard entry of the `entry` port was written since the node last looked
    /// (`EntryUpdatedDecorator` / `EntryUpdatedAction`: compares sequence numbers).
    fn entry_updated(&mut self, i: usize) -> bool {
        let node = &self.nodes[i];
        let raw = port_attribute(&node.ports, "entry").unwrap_or("");
        let key = blackboard_pointer(raw).unwrap_or(raw);
        match self.blackboard.sequence_id_in(node.scope, key) {
            Some(current) => {
                let previous = std::mem::replace(&mut self.nodes[i].sequence_id, current);
                previous != current
            }
            None => false,
        }
    }

    /// `EntryUpdatedDecorator::tick` (`flag` is `still_executing_child_`).
    fn tick_entry_updated(&mut self, i: usize, skip: bool) -> Result<Status, TickError> {
        let child = self.nodes[i].children[0];
        if !self.nodes[i].flag && !self.entry_updated(i) {
            return Ok(if skip {
                Status::Skipped
            } else {
                Status::Running
            });
        }
        // The child is reset by `execute_tick` (`DecoratorNode::executeTick`), after this
        // node's status changed.
        let status = self.execute_tick(child)?;
        self.nodes[i].flag = status == Status::Running;
        Ok(status)
    }

    /// `SubTreeNode::tick`.
    fn tick_subtree(&mut self, i: usize) -> Result<Status, TickError> {
        if !self.nodes[i].status.is_active() {
            self.set_status(i, Status::Running);
        }
        let child = self.nodes[i].children[0];
        let status = self.execute_tick(child)?;
        if status.is_completed() {
            self.halt_child(child)?;
        }
        Ok(status)
    }
}

/// BehaviorTree.CPP's `details::CheckStringEquality` (Switch cases): equal text, or equal
/// integers (enum names allowed), or reals equal within `f32::EPSILON`.
fn check_string_equality(a: &str, b: &str, enums: &BTreeMap<String, i64>) -> bool {
    if a == b {
        return true;
    }
    let to_int = |s: &str| enums.get(s).copied().or_else(|| s.parse::<i64>().ok());
    if let (Some(x), Some(y)) = (to_int(a), to_int(b))
        && x == y
    {
        return true;
    }
    if let (Ok(x), Ok(y)) = (a.parse::<f64>(), b.parse::<f64>()) {
        return (x - y).abs() <= f64::from(f32::EPSILON);
    }
    false
}

/// The status that stops a sequence (`Failure`) or a fallback (`Success`) before its last
/// child, and the one it returns when no child does.
fn stop_and_otherwise(sequence: bool) -> (Status, Status) {
    if sequence {
        (Status::Failure, Status::Success)
    } else {
        (Status::Success, Status::Failure)
    }
}

/// Builds the node arena from a description, iteratively in depth-first pre-order. Trees and
/// models are looked up by ID in maps, so that building is linear in the number of nodes.
struct Builder<'a> {
    trees: HashMap<&'a str, &'a TreeDef>,
    models: HashMap<&'a str, &'a NodeModel>,
    registry: &'a Registry,
    tree: Tree,
    /// The defaults of each model's ports, made once per ID and shared by its nodes.
    defaults: HashMap<String, Arc<Defaults>>,
    /// Where each pending node is: the entry of its parent (in the same tree description) and
    /// its child index. A node's [`NodeLocation`] is made from these only when it is wrong,
    /// so that building takes memory in proportion to the nodes, however deep they nest.
    trail: Vec<(Option<usize>, usize)>,
}

/// A node description waiting to be built.
struct Pending<'d> {
    def: &'d NodeDef,
    /// The ID of the tree description the node is in.
    tree_id: &'d str,
    /// Its entry in [`Builder::trail`] (`None` for the root of a tree description).
    trail: Option<usize>,
    parent: Option<usize>,
    scope: ScopeId,
    /// The instance path of the subtree, followed by `/` (empty for the main tree).
    prefix: Arc<str>,
    depth: usize,
}

impl<'a> Builder<'a> {
    fn build(&mut self, root: &'a NodeDef, tree_id: &'a str) -> Result<(), DefinitionError> {
        let mut stack = vec![Pending {
            def: root,
            tree_id,
            trail: None,
            parent: None,
            scope: self.tree.blackboard.root(),
            prefix: Arc::from(""),
            depth: 1,
        }];
        // The location given to the checks of each node, replaced by the node's own when one
        // fails.
        let stand_in = NodeLocation {
            tree: String::new(),
            path: Vec::new(),
        };
        while let Some(pending) = stack.pop() {
            if pending.depth > MAX_DEPTH {
                return Err(DefinitionError::at(
                    self.location(&pending),
                    DefinitionErrorKind::TooDeep { max: MAX_DEPTH },
                ));
            }
            let index = self
                .create(&pending, &stand_in)
                .map_err(|e| e.relocated(self.location(&pending)))?;
            if let Some(parent) = pending.parent {
                self.tree.nodes[parent].children.push(index);
            }
            let def = pending.def;
            if def.category == NodeCategory::SubTree {
                let next = self
                    .open_subtree(&pending, index, &stand_in)
                    .map_err(|e| e.relocated(self.location(&pending)))?;
                stack.push(next);
            } else {
                for (k, child) in def.children.iter().enumerate().rev() {
                    self.trail.push((pending.trail, k));
                    stack.push(Pending {
                        def: child,
                        tree_id: pending.tree_id,
                        trail: Some(self.trail.len() - 1),
                        parent: Some(index),
                        scope: pending.scope,
                        prefix: Arc::clone(&pending.prefix),
                        depth: pending.depth + 1,
                    });
                }
            }
        }
        Ok(())
    }

    /// The location of a pending node: its tree and path of child indices.
    fn location(&self, pending: &Pending<'_>) -> NodeLocation {
        let mut path = Vec::new();
        let mut at = pending.trail;
        while let Some(i) = at {
            let (up, k) = self.trail[i];
            path.push(k);
            at = up;
        }
        path.reverse();
        NodeLocation {
            tree: pending.tree_id.to_owned(),
            path,
        }
    }

    /// The scope and instance of the tree a `SubTree` node (at `index`) opens, and its root
    /// to build next.
    fn open_subtree(
        &mut self,
        pending: &Pending<'a>,
        index: usize,
        location: &NodeLocation,
    ) -> Result<Pending<'a>, DefinitionError> {
        let def = pending.def;
        let subtree: &'a TreeDef = self.trees.get(def.id.as_str()).copied().ok_or_else(|| {
            DefinitionError::at(
                location.clone(),
                DefinitionErrorKind::UnknownTree { id: def.id.clone() },
            )
            .with_attribute("ID")
        })?;
        // BehaviorTree.CPP's recursivelyCreateSubtree: `{key}` attributes remap, literals
        // are set in the new scope, `_autoremap` shares the remaining keys.
        let mut remap = BTreeMap::new();
        let mut literals = Vec::new();
        for (name, value) in self.tree.nodes[index].ports.merged() {
            match blackboard_pointer(&value) {
                Some(key) => {
                    remap.insert(name.clone(), key.to_owned());
                }
                None => literals.push((name, value)),
            }
        }
        let inner = self
            .tree
            .blackboard
            .add_scope(pending.scope, remap, def.autoremap);
        for (name, value) in literals {
            self.tree
                .blackboard
                .set_local(inner, &name, Value::Str(value));
        }
        let uid = self.tree.nodes[index].uid;
        let own = match &def.name {
            Some(n) => n.clone(),
            None => format!("{}::{uid}", def.id),
        };
        let instance_path = format!("{}{own}", pending.prefix);
        let root_uid = u16::try_from(index + 2).map_err(|_| {
            DefinitionError::at(location.clone(), DefinitionErrorKind::TooManyNodes)
        })?;
        self.tree.subtrees.push(SubtreeInstance {
            tree_id: subtree.id.clone(),
            path: instance_path.clone(),
            root_uid,
            subtree_uid: Some(uid),
            scope: inner,
        });
        Ok(Pending {
            def: &subtree.root,
            tree_id: &subtree.id,
            trail: None,
            parent: Some(index),
            scope: inner,
            prefix: Arc::from(format!("{instance_path}/")),
            depth: pending.depth + 1,
        })
    }

    fn create(
        &mut self,
        pending: &Pending<'a>,
        location: &NodeLocation,
    ) -> Result<usize, DefinitionError> {
        let def = pending.def;
        let index = self.tree.nodes.len();
        let uid = u16::try_from(index + 1).map_err(|_| {
            DefinitionError::at(location.clone(), DefinitionErrorKind::TooManyNodes)
        })?;
        let mut leaf = None;
        let mut custom = None;
        let (kind, model): (Kind, Option<Cow<'a, NodeModel>>) =
            if def.category == NodeCategory::SubTree {
                (
                    Kind::Builtin(BuiltinKind::SubTree),
                    self.models.get(def.id.as_str()).map(|m| Cow::Borrowed(*m)),
                )
            } else if let Some(kind) = BuiltinKind::of(&def.id) {
                (Kind::Builtin(kind), builtin_model(&def.id).map(Cow::Owned))
            } else {
                let model = self
                    .registry
                    .model(&def.id)
                    .or_else(|| self.models.get(def.id.as_str()).copied())
                    .map(Cow::Borrowed);
                let instance = self.registry.instantiate(&def.id).ok_or_else(|| {
                    DefinitionError::at(
                        location.clone(),
                        DefinitionErrorKind::NotImplemented {
                            id: def.id.clone(),
                            category: def.category,
                        },
                    )
                    .with_attribute("ID")
                })?;
                let kind = match instance {
                    Instance::Leaf(l) => {
                        leaf = Some(l);
                        Kind::Leaf
                    }
                    Instance::Control(c) => {
                        custom = Some(c);
                        Kind::Custom
                    }
                    Instance::Builtin(kind) => Kind::Builtin(kind),
                };
                (kind, model)
            };
        // A model's defaults and its copy in the tree are made once per ID.
        let defaults = match &model {
            Some(model) => Arc::clone(
                self.defaults
                    .entry(model.id.clone())
                    .or_insert_with(|| Arc::new(Defaults::of(model))),
            ),
            None => Arc::default(),
        };
        let ports = ports_as_read(def, defaults);
        // "Initialize the ports in the BB to set the type": BehaviorTree.CPP creates an entry,
        // without a value, for every port the XML remaps to the blackboard (not for a
        // `SubTree`'s remappings), which a script's `:=` then finds instead of creating.
        if def.category != NodeCategory::SubTree {
            for (port, value) in &ports.own {
                if let Some(key) = blackboard_pointer(value) {
                    let type_name = model.as_ref().and_then(|m| {
                        m.ports
                            .iter()
                            .find(|spec| &spec.name == port)
                            .and_then(|spec| spec.type_name.as_deref())
                    });
                    let declared = match type_name {
                        Some("std::string") => DeclaredType::Text,
                        Some("BT::Any") => DeclaredType::Any,
                        _ => DeclaredType::Other,
                    };
                    self.tree
                        .blackboard
                        .declare_in(pending.scope, key, declared);
                }
            }
        }
        if let Some(model) = model
            && !self.tree.models.contains_key(&model.id)
        {
            self.tree
                .models
                .insert(model.id.clone(), model.into_owned());
        }
        let builtin = match kind {
            Kind::Builtin(kind) => Some(kind),
            _ => None,
        };
        let (conditions, code) = compile_definition(def, builtin, &ports, location, false)?;
        let name = def.instance_name().to_owned();
        let path = match &def.name {
            Some(n) => format!("{}{n}", pending.prefix),
            None => format!("{}{}::{uid}", pending.prefix, def.id),
        };
        self.tree.nodes.push(Node {
            uid,
            id: def.id.clone(),
            name,
            category: def.category,
            attributes: def.ports.clone(),
            ports,
            children: Vec::with_capacity(def.children.len().max(1)),
            parent: pending.parent,
            scope: pending.scope,
            status: Status::Idle,
            path,
            kind,
            index: 0,
            count: 0,
            skipped: 0,
            flag: false,
            returned: Status::Idle,
            running_child: None,
            sequence_id: 0,
            parallel: ParallelState::default(),
            deadline: None,
            timer_started: false,
            child_halted: false,
            queue: None,
            leaf,
            custom,
            conditions,
            code,
        });
        Ok(index)
    }
}

fn bad_value(
    def: &NodeDef,
    location: &NodeLocation,
    port: &str,
    value: &str,
    expected: &str,
) -> DefinitionError {
    DefinitionError::at(
        location.clone(),
        DefinitionErrorKind::BadValue {
            id: def.id.clone(),
            port: port.to_owned(),
            value: value.to_owned(),
            expected: expected.to_owned(),
        },
    )
    .with_attribute(port)
}

/// The literal value of a port (`None` for a `{key}` or an absent port).
fn literal<'p>(ports: &'p Ports, port: &str) -> Option<&'p str> {
    port_attribute(ports, port).filter(|v| blackboard_pointer(v).is_none())
}

fn check_non_negative(
    def: &NodeDef,
    ports: &Ports,
    port: &str,
    location: &NodeLocation,
) -> Result<(), DefinitionError> {
    if let Some(value) = literal(ports, port)
        && value.trim().parse::<u64>().is_err()
    {
        return Err(bad_value(
            def,
            location,
            port,
            value,
            "a non-negative number of milliseconds",
        ));
    }
    Ok(())
}

/// A node's ports as read: `{=}` is `{port}`, and absent ports take the model's default.
fn ports_as_read(def: &NodeDef, defaults: Arc<Defaults>) -> Ports {
    let own = def
        .ports
        .iter()
        .map(|(name, value)| {
            let value = if value.trim() == "{=}" {
                format!("{{{name}}}")
            } else {
                value.clone()
            };
            (name.clone(), value)
        })
        .collect();
    Ports { own, defaults }
}

/// A node's parsed pre- and post-conditions, and its `code` or `if` script.
type CompiledScripts = (Option<Arc<Conditions>>, Option<Arc<Compiled>>);

/// The checks of one node that need no implementation: a built-in's port ranges and
/// children, the scripts of its pre- and post-conditions and of a `Script`'s `code` or a
/// `Precondition`'s `if`; gives the parsed scripts.
fn compile_definition(
    def: &NodeDef,
    builtin: Option<BuiltinKind>,
    ports: &Ports,
    location: &NodeLocation,
    strict: bool,
) -> Result<CompiledScripts, DefinitionError> {
    // `TryCatch` (BehaviorTree.CPP 4.9, not in 4.8) checks its children when it is parsed.
    if let Some(kind) = builtin
        && (strict || kind == BuiltinKind::TryCatch)
    {
        check_builtin(def, kind, ports, location)?;
    }
    if strict && def.id == "Sleep" && def.category == NodeCategory::Action {
        check_non_negative(def, ports, "msec", location)?;
    }
    let conditions = compile_conditions(def, location)?;
    let code = match builtin {
        Some(BuiltinKind::Script | BuiltinKind::ScriptCondition) => {
            compile_port(def, ports, "code", location)?
        }
        Some(BuiltinKind::Precondition) => compile_port(def, ports, "if", location)?,
        _ => None,
    };
    Ok((conditions, code))
}

/// [`compile_definition`] for [`validate`](super::validate): what instantiation would refuse
/// in a node, found without instantiating it (so `chronomap bt check` reports it too).
pub(crate) fn check_definition(
    def: &NodeDef,
    location: &NodeLocation,
    strict: bool,
) -> Result<(), DefinitionError> {
    let builtin = if def.category == NodeCategory::SubTree {
        None
    } else {
        BuiltinKind::of(&def.id)
    };
    let defaults = builtin
        .and_then(|_| builtin_model(&def.id))
        .map_or_else(Arc::default, |model| Arc::new(Defaults::of(&model)));
    let ports = ports_as_read(def, defaults);
    compile_definition(def, builtin, &ports, location, strict).map(|_| ())
}

/// Checks of built-in nodes that BehaviorTree.CPP makes only when ticking (or never): port
/// ranges, numbers of children, statuses given as text.
fn check_builtin(
    def: &NodeDef,
    kind: BuiltinKind,
    ports: &Ports,
    location: &NodeLocation,
) -> Result<(), DefinitionError> {
    let children = def.children.len();
    let wrong_children = |expected: String| {
        DefinitionError::at(
            location.clone(),
            DefinitionErrorKind::WrongChildren {
                id: def.id.clone(),
                expected,
                found: children,
            },
        )
    };
    match kind {
        BuiltinKind::RetryUntilSuccessful | BuiltinKind::Repeat => {
            let port = if kind == BuiltinKind::Repeat {
                "num_cycles"
            } else {
                "num_attempts"
            };
            if let Some(value) = literal(ports, port)
                && value.trim().parse::<i64>().is_ok_and(|n| n < -1)
            {
                return Err(bad_value(
                    def,
                    location,
                    port,
                    value,
                    "-1 (forever) or a non-negative integer",
                ));
            }
        }
        BuiltinKind::Timeout => check_non_negative(def, ports, "msec", location)?,
        BuiltinKind::Delay => check_non_negative(def, ports, "delay_msec", location)?,
        BuiltinKind::ParallelAll => {
            if let Some(value) = literal(ports, "max_failures")
                && let Ok(threshold) = value.trim().parse::<i64>()
            {
                let required = required_count(threshold, children);
                if children < required {
                    return Err(DefinitionError::at(
                        location.clone(),
                        DefinitionErrorKind::ParallelThreshold {
                            port: "max_failures".to_owned(),
                            threshold,
                            required,
                            children,
                        },
                    )
                    .with_attribute("max_failures"));
                }
            }
        }
        BuiltinKind::IfThenElse | BuiltinKind::WhileDoElse if !(2..=3).contains(&children) => {
            return Err(wrong_children("2 or 3 children".to_owned()));
        }
        BuiltinKind::Switch(n) if children != n + 1 => {
            return Err(wrong_children(format!(
                "{} children ({n} cases and the default)",
                n + 1
            )));
        }
        BuiltinKind::TryCatch if children < 2 => {
            return Err(wrong_children(
                "at least 2 children (the try children and the catch)".to_owned(),
            ));
        }
        BuiltinKind::Loop(_) | BuiltinKind::Precondition => {
            let port = if kind == BuiltinKind::Precondition {
                "else"
            } else {
                "if_empty"
            };
            if let Some(value) = literal(ports, port)
                && !value
                    .trim()
                    .parse::<Status>()
                    .is_ok_and(|s| s != Status::Idle)
            {
                return Err(bad_value(
                    def,
                    location,
                    port,
                    value,
                    "SUCCESS, FAILURE, RUNNING or SKIPPED",
                ));
            }
        }
        _ => {}
    }
    Ok(())
}

fn bad_script(
    def: &NodeDef,
    location: &NodeLocation,
    attribute: &str,
    code: &str,
    message: String,
) -> DefinitionError {
    DefinitionError::at(
        location.clone(),
        DefinitionErrorKind::BadScript {
            id: def.id.clone(),
            attribute: attribute.to_owned(),
            message: format!("{code:?}: {message}"),
        },
    )
    .with_attribute(attribute)
}

/// Parses the pre- and post-condition attributes of a node.
fn compile_conditions(
    def: &NodeDef,
    location: &NodeLocation,
) -> Result<Option<Arc<Conditions>>, DefinitionError> {
    if def.scripts.is_empty() {
        return Ok(None);
    }
    let mut conditions = Conditions::default();
    for (attribute, code) in &def.scripts {
        let slot = if let Some(k) = PRE_CONDITIONS.iter().position(|a| a == attribute) {
            &mut conditions.pre[k]
        } else if let Some(k) = POST_CONDITIONS.iter().position(|a| a == attribute) {
            &mut conditions.post[k]
        } else {
            return Err(bad_script(
                def,
                location,
                attribute,
                code,
                format!(
                    "not a pre- or post-condition attribute (those are {}, {})",
                    PRE_CONDITIONS.join(", "),
                    POST_CONDITIONS.join(", ")
                ),
            ));
        };
        let program = Program::parse(code)
            .map_err(|e| bad_script(def, location, attribute, code, e.to_string()))?;
        *slot = Some(Compiled {
            attribute: attribute.clone(),
            code: code.clone(),
            program,
        });
    }
    Ok(Some(Arc::new(conditions)))
}

/// Parses the script of a `code`/`if` port when it is a literal.
fn compile_port(
    def: &NodeDef,
    ports: &Ports,
    port: &str,
    location: &NodeLocation,
) -> Result<Option<Arc<Compiled>>, DefinitionError> {
    let Some(code) = literal(ports, port) else {
        return Ok(None);
    };
    let program =
        Program::parse(code).map_err(|e| bad_script(def, location, port, code, e.to_string()))?;
    Ok(Some(Arc::new(Compiled {
        attribute: port.to_owned(),
        code: code.to_owned(),
        program,
    })))
}
