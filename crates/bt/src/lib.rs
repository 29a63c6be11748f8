//! Behavior trees with the semantics of BehaviorTree.CPP 4: the task-switching formalism of the
//! executive system of [Stüde 2024] (§5.2.1, Algorithms 5.1 and 5.2) and of its
//! monitoring arbiter (§5.3, Table 5.1), as Nav2 and many ROS robots run them.
//!
//! A tree is first a plain, reusable description — a [`BtDocument`] of [`TreeDef`]s made of
//! [`NodeDef`]s (kind, ID, instance name, port attributes, children) — which
//! `chronomap-io` reads from and writes to BehaviorTree.CPP 4 XML and which analyses (stochastic
//! behavior trees, §5.2.2) can walk without running anything. [`Tree::new`] instantiates it with
//! a [`Registry`] of leaf implementations into a runtime tree whose nodes carry a status, a
//! uid (1, 2, … in depth-first order, subtrees expanded where they are used) and the blackboard
//! scope they read their ports from.
//!
//! ```
//! use std::time::Duration;
//! use chronomap_bt::{BtDocument, NodeDef, Registry, Status, Tree, TreeDef};
//!
//! // Fallback(IsDoorOpen, RetryUntilSuccessful(OpenDoor)) with closures as leaves.
//! let mut registry = Registry::new();
//! registry.register_condition_fn("IsDoorOpen", |_| Ok(Status::Failure))?;
//! registry.register_action_fn("OpenDoor", |ctx| {
//!     // Running on the first tick of an attempt, success on the next one.
//!     Ok(if ctx.status() == Status::Running { Status::Success } else { Status::Running })
//! })?;
//! let root = NodeDef::control("Fallback")
//!     .child(NodeDef::condition("IsDoorOpen"))
//!     .child(
//!         NodeDef::decorator("RetryUntilSuccessful")
//!             .port("num_attempts", "3")
//!             .child(NodeDef::action("OpenDoor")),
//!     );
//! let doc = BtDocument::single(TreeDef::new("Main", root));
//! let mut tree = Tree::new(&doc, &registry)?;
//! assert_eq!(tree.tick_once(Duration::ZERO)?, Status::Running);
//! assert_eq!(tree.tick_once(Duration::from_millis(100))?, Status::Success);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! ## What is implemented
//! * Statuses [`Status`]: idle, running, success, failure, skipped (BehaviorTree.CPP's codes
//!   0–4).
//! * Every built-in node of BehaviorTree.CPP 4's factory (except the few in
//!   [`UNSUPPORTED_BUILTINS`]): control nodes `Sequence`, `ReactiveSequence`,
//!   `SequenceWithMemory` (`SequenceStar`), `AsyncSequence`, `Fallback`, `ReactiveFallback`,
//!   `AsyncFallback`, `Parallel` (`success_count`, `failure_count`, negative = "all"),
//!   `ParallelAll` (`max_failures`), `IfThenElse`, `WhileDoElse`, `Switch2` … `Switch6`,
//!   `TryCatch` (`catch_on_halt`); decorators `Inverter`, `RetryUntilSuccessful`
//!   (`num_attempts`; also spelled `RetryUntilSuccesful`), `Repeat` (`num_cycles`), `Timeout`
//!   (`msec`), `Delay` (`delay_msec`), `ForceSuccess`, `ForceFailure`,
//!   `KeepRunningUntilFailure`, `LoopInt`/`LoopDouble`/`LoopString`/`LoopBool` (`queue`,
//!   `value`, `if_empty`), `Precondition` (`if`, `else`), `RunOnce` (`then_skip`),
//!   `SkipUnlessUpdated`, `WaitValueUpdate` (`entry`); `SubTree` with port remapping and
//!   `_autoremap`; leaves `AlwaysSuccess`, `AlwaysFailure`, `SetBlackboard`, `Sleep`,
//!   `Script`, `ScriptCondition` (`code`), `WasEntryUpdated` (`entry`), `UnsetBlackboard`
//!   (`key`). The exact rules, with the BehaviorTree.CPP 4 functions they follow, are in
//!   [`runtime`].
//! * BehaviorTree.CPP's scripting language ([`scripting`]): parsed when a tree is
//!   instantiated, run by `Script`, `ScriptCondition`, `Precondition` and the pre- and
//!   post-condition attributes of every node (`_failureIf`, `_successIf`, `_skipIf`, `_while`,
//!   `_onSuccess`, `_onFailure`, `_onHalted`, `_post`: [`NodeDef::scripts`]), with enum values
//!   registered by name ([`Registry::register_enum`]).
//! * User nodes registered by ID in a [`Registry`]: leaves (actions and conditions) as
//!   closures or [`LeafNode`] trait objects with a halt hook (actions may return running
//!   across ticks); custom control nodes and decorators as [`ControlNode`] trait objects that
//!   tick and halt their children through a [`ControlContext`]; stubs of declared but
//!   unimplemented nodes ([`Registry::register_stub`], [`StubPolicy`]).
//! * A typed [`Blackboard`] ([`Value`]: bool, i64, f64, string, list; literal port strings are
//!   parsed as BehaviorTree.CPP's `convertFromString` does), input/output ports, `{key}`
//!   references, `{=}`, `@key` for the root blackboard, subtree remapping, entry sequence
//!   numbers (for `SkipUnlessUpdated` and `WasEntryUpdated`).
//! * Time is injected: every tick gets `now` from the caller (a [`Duration`] since an origin the
//!   caller chooses), so `Timeout`, `Delay` and `Sleep` are deterministic; nothing here reads
//!   a clock.
//! * Bounded: trees nest at most [`MAX_DEPTH`] levels, scripts [`scripting::MAX_NESTING`];
//!   instantiation is iterative and linear in the number of nodes.
//! * Every status change can be recorded as a [`Transition`] (time, uid, previous and new
//!   status), the content of a Groot2 `.btlog` file (written by `chronomap-io`).
//! * [`script`]: leaves whose outcomes a script gives tick by tick, for `chronomap bt run` and
//!   for tests.
//! * [`stochastic`]: a tree read as a stochastic behavior tree of `chronomap-bt-stochastic`
//!   (§5.2.2), which needs nothing of this crate.
//!
//! Monitoring and the fault-injection simulation whose arbiter is a tree of this crate (§5.3)
//! are `chronomap-bt-monitor`.
//!
//! [`Duration`]: std::time::Duration
#![deny(missing_docs)]

/// `Display` of a type with a name method (`$name(self) -> &'static str`): writes that name.
macro_rules! display_by_name {
    ($ty:ty, $name:ident) => {
        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.$name())
            }
        }
    };
}

pub mod nav2;
pub mod stochastic;

pub mod blackboard;
mod builtin;
mod error;
pub mod model;
pub mod registry;
pub mod runtime;
pub mod script;
pub mod scripting;
#[cfg(test)]
mod tests;
mod validate;

pub use blackboard::{
    Blackboard, BlackboardError, DeclaredType, FromValue, ScopeId, ScriptedWrite, Value,
};
pub use builtin::{UNSUPPORTED_BUILTINS, builtin_model, is_builtin};
pub use error::{DefinitionError, DefinitionErrorKind, PortError, TickError, TickErrorKind};
pub use model::{
    BtDocument, NodeCategory, NodeDef, NodeLocation, NodeModel, PortDirection, PortSpec, PortType,
    TreeDef, blackboard_pointer,
};
pub use registry::{
    ControlContext, ControlNode, LeafContext, LeafError, LeafNode, Manifest, ManifestSource,
    Registry, RegistryError, StubPolicy,
};
pub use runtime::{MAX_DEPTH, Node, SubtreeInstance, TickMonitor, Transition, Tree};
pub use scripting::{Program, ScriptError};
pub use validate::{validate, validate_strict};

use serde::{Deserialize, Serialize};

/// The status of a node: what a tick returns, and what a node is between ticks.
///
/// The discriminants are BehaviorTree.CPP's `NodeStatus` codes (`IDLE = 0`, `RUNNING = 1`,
/// `SUCCESS = 2`, `FAILURE = 3`, `SKIPPED = 4`), which Groot2 `.btlog` files store.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Status {
    /// Not ticked since it was last reset or halted.
    Idle = 0,
    /// Execution ongoing ([Stüde 2024] §5.2.1: *R*).
    Running = 1,
    /// Goal achieved (*S*).
    Success = 2,
    /// Failed (*F*).
    Failure = 3,
    /// Not executed because a pre-condition (`_skipIf`, `_while`) said so, or every child was
    /// skipped (BehaviorTree.CPP 4's `SKIPPED`). Like `Idle`, a skipped node is not active: it
    /// starts afresh (pre-conditions are checked again) the next time it is ticked.
    Skipped = 4,
}

impl Status {
    /// The BehaviorTree.CPP code (0–4).
    pub fn code(self) -> u8 {
        self as u8
    }

    /// The status of a BehaviorTree.CPP code (0–4); `None` for others.
    pub fn from_code(code: u8) -> Option<Status> {
        match code {
            0 => Some(Status::Idle),
            1 => Some(Status::Running),
            2 => Some(Status::Success),
            3 => Some(Status::Failure),
            4 => Some(Status::Skipped),
            _ => None,
        }
    }

    /// Success or failure (BehaviorTree.CPP's `isStatusCompleted`).
    pub fn is_completed(self) -> bool {
        matches!(self, Status::Success | Status::Failure)
    }

    /// Neither idle nor skipped (BehaviorTree.CPP's `isStatusActive`).
    pub fn is_active(self) -> bool {
        !matches!(self, Status::Idle | Status::Skipped)
    }

    /// The upper-case name BehaviorTree.CPP prints (`RUNNING`).
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Idle => "IDLE",
            Status::Running => "RUNNING",
            Status::Success => "SUCCESS",
            Status::Failure => "FAILURE",
            Status::Skipped => "SKIPPED",
        }
    }
}

display_by_name!(Status, as_str);

impl std::str::FromStr for Status {
    type Err = String;

    /// `idle`, `running`, `success`, `failure`, `skipped` in any case.
    fn from_str(s: &str) -> Result<Status, String> {
        match s.to_ascii_lowercase().as_str() {
            "idle" => Ok(Status::Idle),
            "running" => Ok(Status::Running),
            "success" => Ok(Status::Success),
            "failure" => Ok(Status::Failure),
            "skipped" => Ok(Status::Skipped),
            _ => Err(format!(
                "{s:?} is not a status (expected success, failure, running, skipped or idle)"
            )),
        }
    }
}
