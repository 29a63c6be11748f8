//! The runtime tree: instantiation of a description, ticks, halts and status transitions, with
//! the semantics of BehaviorTree.CPP 4 (read from its 4.x sources: `src/controls/*.cpp`,
//! `src/decorators/*.cpp`, `TreeNode::executeTick`, `Tree::tickRoot`).
//!
//! # Ticks and statuses
//! A tick of a node returns running, success or failure; the node's status becomes that value
//! (transitions are recorded when they change it). Control nodes and decorators set themselves
//! running before ticking children. "Resetting" a child (`ControlNode::haltChild`,
//! `DecoratorNode::resetChild`) halts it if it is running and then sets it idle; "halting" a
//! node (`haltNode`) resets its own state and children and calls a running leaf's
//! [`LeafNode::halt`] hook.
//!
//! | node | rule |
//! |---|---|
//! | `Sequence` | ticks children from the current one; running: returns running and resumes at that child next tick (earlier children are *not* re-ticked); failure: resets all children, restarts at the first child next time, returns failure; all succeed: resets them, success. ([Stüde 2024] Algorithm 5.1 with memory of the running child.) |
//! | `SequenceWithMemory` | as `Sequence`, but on failure only the failed and later children are reset and the index is kept: the next tick retries the failed child. Halting keeps the index too (BehaviorTree.CPP leaves `current_child_idx_ = 0` commented out in `halt()`). |
//! | `ReactiveSequence` | ticks all children from the first every tick; a running child halts every *other* child (later ones that were running, earlier ones are reset to idle) and returns running; a failure resets all children (halting a running later one) and returns failure; all succeed: success. |
//! | `Fallback` | mirror of `Sequence` (Algorithm 5.2): resumes at the running child; success resets all and returns success; all fail: failure. |
//! | `ReactiveFallback` | mirror of `ReactiveSequence`: a success resets all and returns success; a running child halts the others. |
//! | `Parallel` | ticks every child that has not completed yet, left to right; after each child it checks: successes ≥ `success_count` → success; failures = `failure_count`, or too many failures to reach `success_count` → failure (both reset all children, halting running ones). A negative threshold `t` means `children + t + 1` (-1 = all); defaults -1 and 1. A threshold above the number of children is an error. |
//! | `Inverter`, `ForceSuccess`, `ForceFailure` | running passes through; a completed child is reset and its result inverted / replaced. |
//! | `RetryUntilSuccessful` | ticks the child; success: success; failure: counts an attempt, resets the child and, while attempts remain (`num_attempts`, -1 = forever), ticks it again — but if the child failed straight from idle it returns running first and tries again on the next tick (BehaviorTree.CPP returns running and emits a wake-up signal, "to make this interruptable", in every tree built by its factory). When the attempts are used up: failure. |
//! | `Repeat` | mirror for success with `num_cycles` (failure ends the loop with failure). |
//! | `Timeout` | on its first tick starts a timer of `msec` (0 = none); on a later tick at or after the deadline, if the child is still running, halts it and returns failure without ticking it (BehaviorTree.CPP halts it from a timer thread at the deadline; with the injected clock this happens at the first tick after the deadline, with that tick's time). |
//! | `SubTree` | ticks the root of its tree in its own blackboard scope; a completed child is reset. |
//!
//! [`Tree::tick_once`] is `Tree::tickOnce` (ticks the root again while it is running and a
//! node asked for a wake-up, so a retry of a failing synchronous action finishes within one
//! call); [`Tree::tick_exactly_once`] is `tickExactlyOnce` (one root tick). After the root
//! completes, its status is reset to idle, as `Tree::tickRoot` does.
//!
//! # Not implemented
//! Scripting (`Script`, pre/post-condition attributes such as `_skipIf`) and therefore
//! `SKIPPED`; asynchronous nodes and threads; the nodes in
//! [`UNSUPPORTED_BUILTINS`](super::UNSUPPORTED_BUILTINS). `ReactiveSequence`'s optional
//! exception for several running children (off by default in BehaviorTree.CPP) is not
//! reproduced.

use std::collections::BTreeMap;
use std::fmt;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::Status;
use super::blackboard::{Blackboard, ScopeId, Value};
use super::builtin::{BuiltinKind, builtin_model};
use super::error::{DefinitionError, DefinitionErrorKind, TickError, TickErrorKind};
use super::model::{
    BtDocument, NodeCategory, NodeDef, NodeLocation, NodeModel, blackboard_pointer,
};
use super::registry::{LeafContext, LeafNode, Registry, read_port};
use super::validate::{required_count, validate};

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
}

#[derive(Clone, Debug, Default)]
struct ParallelState {
    completed: Vec<bool>,
    successes: usize,
    failures: usize,
}

/// A node of a runtime tree. Nodes are stored in depth-first order; a node's index in
/// [`Tree::nodes`] is its uid − 1.
pub struct Node {
    uid: u16,
    id: String,
    name: String,
    category: NodeCategory,
    attributes: Vec<(String, String)>,
    ports: Vec<(String, String)>,
    children: Vec<usize>,
    parent: Option<usize>,
    scope: ScopeId,
    status: Status,
    path: String,
    kind: Kind,
    // Per-kind state (BehaviorTree.CPP's member variables).
    index: usize,
    count: i64,
    parallel: ParallelState,
    deadline: Option<Duration>,
    timer_started: bool,
    child_halted: bool,
    leaf: Option<Box<dyn LeafNode>>,
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

    /// The ports as the node reads them: `{=}` expanded, defaults of absent ports added.
    pub fn ports(&self) -> &[(String, String)] {
        &self.ports
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
            .field("ports", &self.ports)
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
    now: Duration,
    last_tick: Option<Duration>,
    wake_up: bool,
    recording: bool,
    transitions: Vec<Transition>,
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

impl Tree {
    /// Instantiates the main tree of `doc` (`main_tree_to_execute`, or the only tree) with the
    /// leaves of `registry`.
    ///
    /// # Errors
    /// Any [`validate`] error; a leaf with no implementation in the registry
    /// ([`DefinitionErrorKind::NotImplemented`]); more than 65535 nodes.
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
            now: Duration::ZERO,
            last_tick: None,
            wake_up: false,
            recording: false,
            transitions: Vec::new(),
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
            doc,
            registry,
            tree,
        };
        let location = NodeLocation {
            tree: def.id.clone(),
            path: Vec::new(),
        };
        builder.build(&def.root, location, None, scope, "")?;
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
    /// `RetryUntilSuccessful` or `Repeat` between attempts). `now` is the time of the tick
    /// (any origin; never earlier than the previous tick).
    ///
    /// # Errors
    /// [`TickError`] if a node fails (a port that cannot be read, a leaf error, a condition
    /// returning running, ...) or `now` goes backwards.
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

    /// Ticks with `tick_once` at `start`, `start + period`, … until the root completes or
    /// `max_ticks` ticks are done; returns the last status.
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
            if status.is_completed() {
                break;
            }
            now = now.saturating_add(period);
        }
        Ok(status)
    }

    /// Halts the whole tree (BehaviorTree.CPP's `Tree::haltTree`): running nodes are halted
    /// (leaves get their halt hook), every status becomes idle, and controls start over.
    pub fn halt(&mut self, now: Duration) {
        self.now = self.last_tick.map_or(now, |last| now.max(last));
        self.halt_node(0);
        for i in 0..self.nodes.len() {
            if self.nodes[i].status == Status::Running {
                self.halt_node(i);
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
    fn halt_child(&mut self, child: usize) {
        if self.nodes[child].status == Status::Running {
            self.halt_node(child);
        }
        self.set_status(child, Status::Idle);
    }

    /// `ControlNode::resetChildren`.
    fn reset_children(&mut self, i: usize) {
        for k in 0..self.nodes[i].children.len() {
            let child = self.nodes[i].children[k];
            self.halt_child(child);
        }
    }

    /// `TreeNode::haltNode`: the node type's `halt()`, which ends with `resetStatus()`.
    fn halt_node(&mut self, i: usize) {
        match self.nodes[i].kind {
            Kind::Leaf => {
                if self.nodes[i].status == Status::Running {
                    self.with_leaf(i, |leaf, ctx| {
                        leaf.halt(ctx);
                    });
                }
            }
            Kind::Builtin(kind) => {
                let node = &mut self.nodes[i];
                match kind {
                    // SequenceWithMemory::halt keeps current_child_idx_.
                    BuiltinKind::SequenceWithMemory => {}
                    BuiltinKind::Sequence | BuiltinKind::Fallback => node.index = 0,
                    BuiltinKind::Parallel => node.parallel = ParallelState::default(),
                    BuiltinKind::RetryUntilSuccessful | BuiltinKind::Repeat => node.count = 0,
                    BuiltinKind::Timeout => {
                        node.timer_started = false;
                        node.deadline = None;
                    }
                    _ => {}
                }
                self.reset_children(i);
            }
        }
        self.set_status(i, Status::Idle);
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
        let mut ctx = LeafContext {
            uid: node.uid,
            id: &node.id,
            name: &node.name,
            ports: &node.ports,
            status: node.status,
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

    fn port<T: super::FromValue>(&self, i: usize, port: &str) -> Result<T, TickError> {
        let node = &self.nodes[i];
        read_port(&node.ports, port, &self.blackboard, node.scope).map_err(|e| self.error(i, e))
    }

    // ------------------------------------------------------------------------------------
    // Ticks

    /// `TreeNode::executeTick`: the node's tick, then its status becomes the result.
    fn execute_tick(&mut self, i: usize) -> Result<Status, TickError> {
        let status = match self.nodes[i].kind {
            Kind::Leaf => self.tick_leaf(i)?,
            Kind::Builtin(kind) => match kind {
                BuiltinKind::Sequence => self.tick_in_order(i, true, false)?,
                BuiltinKind::SequenceWithMemory => self.tick_in_order(i, true, true)?,
                BuiltinKind::Fallback => self.tick_in_order(i, false, false)?,
                BuiltinKind::ReactiveSequence => self.tick_reactive(i, true)?,
                BuiltinKind::ReactiveFallback => self.tick_reactive(i, false)?,
                BuiltinKind::Parallel => self.tick_parallel(i)?,
                BuiltinKind::Inverter | BuiltinKind::ForceSuccess | BuiltinKind::ForceFailure => {
                    self.tick_simple_decorator(i, kind)?
                }
                BuiltinKind::RetryUntilSuccessful => self.tick_loop(i, Status::Failure)?,
                BuiltinKind::Repeat => self.tick_loop(i, Status::Success)?,
                BuiltinKind::Timeout => self.tick_timeout(i)?,
                BuiltinKind::SubTree => self.tick_subtree(i)?,
            },
        };
        self.set_status(i, status);
        Ok(status)
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

    /// `SequenceNode::tick` and `SequenceWithMemory::tick` (`sequence`) and
    /// `FallbackNode::tick`: the children in order from the current one, until one returns
    /// the status that stops the node ([`stop_and_otherwise`]).
    fn tick_in_order(
        &mut self,
        i: usize,
        sequence: bool,
        with_memory: bool,
    ) -> Result<Status, TickError> {
        let (stop, otherwise) = stop_and_otherwise(sequence);
        self.set_status(i, Status::Running);
        let n = self.nodes[i].children.len();
        while self.nodes[i].index < n {
            let current = self.nodes[i].index;
            let child = self.nodes[i].children[current];
            match self.execute_tick(child)? {
                Status::Running => return Ok(Status::Running),
                Status::Idle => unreachable!("executed ticks never return IDLE"),
                status if status == stop => {
                    if with_memory {
                        // "DO NOT reset current_child_idx_ on failure"
                        for k in current..n {
                            let c = self.nodes[i].children[k];
                            self.halt_child(c);
                        }
                    } else {
                        self.reset_children(i);
                        self.nodes[i].index = 0;
                    }
                    return Ok(stop);
                }
                _ => self.nodes[i].index += 1,
            }
        }
        self.reset_children(i);
        self.nodes[i].index = 0;
        Ok(otherwise)
    }

    /// `ReactiveSequence::tick` (`sequence`) and `ReactiveFallback::tick`.
    fn tick_reactive(&mut self, i: usize, sequence: bool) -> Result<Status, TickError> {
        let (stop, otherwise) = stop_and_otherwise(sequence);
        self.set_status(i, Status::Running);
        let n = self.nodes[i].children.len();
        for k in 0..n {
            let child = self.nodes[i].children[k];
            let status = self.execute_tick(child)?;
            if status == Status::Running {
                // "reset the previous children, to make sure that they are in IDLE state the
                // next time we tick them" — and halt any other running child.
                for j in (0..n).filter(|&j| j != k) {
                    let other = self.nodes[i].children[j];
                    self.halt_child(other);
                }
                return Ok(Status::Running);
            }
            if status == stop {
                self.reset_children(i);
                return Ok(stop);
            }
        }
        self.reset_children(i);
        Ok(otherwise)
    }

    /// `ParallelNode::tick`.
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
        if self.nodes[i].parallel.completed.len() != n {
            self.nodes[i].parallel = ParallelState {
                completed: vec![false; n],
                ..ParallelState::default()
            };
        }
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
                    Status::Running => {}
                    Status::Idle => unreachable!("executed ticks never return IDLE"),
                }
            }
            let state = &self.nodes[i].parallel;
            let (successes, failures) = (state.successes, state.failures);
            if successes >= required_success {
                self.nodes[i].parallel = ParallelState::default();
                self.reset_children(i);
                return Ok(Status::Success);
            }
            // "It fails if it is not possible to succeed anymore or if number of failures are
            // equal to failure_threshold_"
            if n - failures < required_success || failures == required_failure {
                self.nodes[i].parallel = ParallelState::default();
                self.reset_children(i);
                return Ok(Status::Failure);
            }
        }
        Ok(Status::Running)
    }

    /// `InverterNode::tick`, `ForceSuccessNode::tick`, `ForceFailureNode::tick`.
    fn tick_simple_decorator(&mut self, i: usize, kind: BuiltinKind) -> Result<Status, TickError> {
        self.set_status(i, Status::Running);
        let child = self.nodes[i].children[0];
        let status = self.execute_tick(child)?;
        if !status.is_completed() {
            return Ok(status);
        }
        self.halt_child(child);
        Ok(match kind {
            BuiltinKind::Inverter if status == Status::Success => Status::Failure,
            BuiltinKind::Inverter => Status::Success,
            BuiltinKind::ForceSuccess => Status::Success,
            _ => Status::Failure,
        })
    }

    /// `RetryNode::tick` (`again_on` = failure) and `RepeatNode::tick` (success).
    fn tick_loop(&mut self, i: usize, again_on: Status) -> Result<Status, TickError> {
        let port = if again_on == Status::Failure {
            "num_attempts"
        } else {
            "num_cycles"
        };
        let limit: i64 = self.port(i, port)?;
        let mut count = self.nodes[i].count;
        let mut do_loop = count < limit || limit == -1;
        self.set_status(i, Status::Running);
        let child = self.nodes[i].children[0];
        while do_loop {
            let previous = self.nodes[child].status;
            let status = self.execute_tick(child)?;
            if status == Status::Running {
                return Ok(Status::Running);
            }
            if status != again_on {
                // Retry: success; Repeat: failure. Ends the loop with the child's result.
                self.nodes[i].count = 0;
                self.halt_child(child);
                return Ok(status);
            }
            count = count.saturating_add(1);
            do_loop = count < limit || limit == -1;
            self.nodes[i].count = count;
            self.halt_child(child);
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
            self.halt_child(child);
        }
        if self.nodes[i].child_halted {
            let node = &mut self.nodes[i];
            node.timer_started = false;
            node.deadline = None;
            return Ok(Status::Failure);
        }
        let status = self.execute_tick(child)?;
        if status.is_completed() {
            let node = &mut self.nodes[i];
            node.timer_started = false;
            node.deadline = None;
            self.halt_child(child);
        }
        Ok(status)
    }

    /// `SubTreeNode::tick`.
    fn tick_subtree(&mut self, i: usize) -> Result<Status, TickError> {
        if self.nodes[i].status == Status::Idle {
            self.set_status(i, Status::Running);
        }
        let child = self.nodes[i].children[0];
        let status = self.execute_tick(child)?;
        if status.is_completed() {
            self.halt_child(child);
        }
        Ok(status)
    }
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

/// Builds the node arena from a description.
struct Builder<'a> {
    doc: &'a BtDocument,
    registry: &'a Registry,
    tree: Tree,
}

impl Builder<'_> {
    fn build(
        &mut self,
        def: &NodeDef,
        location: NodeLocation,
        parent: Option<usize>,
        scope: ScopeId,
        prefix: &str,
    ) -> Result<usize, DefinitionError> {
        let index = self.tree.nodes.len();
        let uid = u16::try_from(index + 1).map_err(|_| {
            DefinitionError::at(location.clone(), DefinitionErrorKind::TooManyNodes)
        })?;
        let (kind, model) = if def.category == NodeCategory::SubTree {
            (
                Kind::Builtin(BuiltinKind::SubTree),
                self.doc.node_model(&def.id).cloned(),
            )
        } else if let Some(kind) = BuiltinKind::of(&def.id) {
            (Kind::Builtin(kind), builtin_model(&def.id))
        } else {
            let model = self
                .registry
                .model(&def.id)
                .or_else(|| self.doc.node_model(&def.id))
                .cloned();
            (Kind::Leaf, model)
        };
        let leaf = match kind {
            Kind::Leaf => Some(self.registry.instantiate(&def.id).ok_or_else(|| {
                DefinitionError::at(
                    location.clone(),
                    DefinitionErrorKind::NotImplemented {
                        id: def.id.clone(),
                        category: def.category,
                    },
                )
                .with_attribute("ID")
            })?),
            Kind::Builtin(_) => None,
        };
        // Ports as read: `{=}` is `{port}`, and absent ports take the model's default.
        let mut ports: Vec<(String, String)> = def
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
        if let Some(model) = &model {
            for spec in &model.ports {
                if let Some(default) = &spec.default
                    && def.port_value(&spec.name).is_none()
                {
                    ports.push((spec.name.clone(), default.clone()));
                }
            }
            self.tree
                .models
                .entry(model.id.clone())
                .or_insert_with(|| model.clone());
        }
        let name = def.instance_name().to_owned();
        let path = match &def.name {
            Some(n) => format!("{prefix}{n}"),
            None => format!("{prefix}{}::{uid}", def.id),
        };
        self.tree.nodes.push(Node {
            uid,
            id: def.id.clone(),
            name,
            category: def.category,
            attributes: def.ports.clone(),
            ports: ports.clone(),
            children: Vec::new(),
            parent,
            scope,
            status: Status::Idle,
            path,
            kind,
            index: 0,
            count: 0,
            parallel: ParallelState::default(),
            deadline: None,
            timer_started: false,
            child_halted: false,
            leaf,
        });
        if def.category == NodeCategory::SubTree {
            let subtree = self
                .doc
                .tree(&def.id)
                .expect("validated: SubTree IDs name trees");
            // BehaviorTree.CPP's recursivelyCreateSubtree: `{key}` attributes remap, literals
            // are set in the new scope, `_autoremap` shares the remaining keys.
            let mut remap = BTreeMap::new();
            let mut literals = Vec::new();
            for (name, value) in &ports {
                match blackboard_pointer(value) {
                    Some(key) => {
                        remap.insert(name.clone(), key.to_owned());
                    }
                    None => literals.push((name.clone(), value.clone())),
                }
            }
            let inner = self.tree.blackboard.add_scope(scope, remap, def.autoremap);
            for (name, value) in literals {
                self.tree
                    .blackboard
                    .set_local(inner, &name, Value::Str(value));
            }
            let parent_path = self
                .tree
                .subtrees
                .iter()
                .find(|s| s.scope == scope)
                .map_or(String::new(), |s| s.path.clone());
            let own = match &def.name {
                Some(n) => n.clone(),
                None => format!("{}::{uid}", def.id),
            };
            let instance_path = if parent_path.is_empty() {
                own
            } else {
                format!("{parent_path}/{own}")
            };
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
            let child_location = NodeLocation {
                tree: subtree.id.clone(),
                path: Vec::new(),
            };
            let child = self.build(
                &subtree.root,
                child_location,
                Some(index),
                inner,
                &format!("{instance_path}/"),
            )?;
            self.tree.nodes[index].children.push(child);
        } else {
            for (k, child_def) in def.children.iter().enumerate() {
                let mut child_location = location.clone();
                child_location.path.push(k);
                let child = self.build(child_def, child_location, Some(index), scope, prefix)?;
                self.tree.nodes[index].children.push(child);
            }
        }
        Ok(index)
    }
}
