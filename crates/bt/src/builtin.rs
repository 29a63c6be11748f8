//! The built-in nodes: their IDs, categories and ports as BehaviorTree.CPP 4 registers them
//! (`BehaviorTreeFactory::BehaviorTreeFactory` and each node's `providedPorts`).

use super::model::{NodeCategory, NodeModel, PortSpec};

/// The nodes the runtime implements itself: controls, decorators, `SubTree`, and the leaves
/// that need the runtime (scripts, blackboard entry stamps).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum BuiltinKind {
    Sequence,
    ReactiveSequence,
    SequenceWithMemory,
    Fallback,
    ReactiveFallback,
    /// `AsyncSequence`: a `Sequence` that returns running (with a wake-up) after each child
    /// that succeeded straight from idle.
    AsyncSequence,
    /// `AsyncFallback`: the mirror for failures.
    AsyncFallback,
    Parallel,
    ParallelAll,
    IfThenElse,
    WhileDoElse,
    /// `Switch2` … `Switch6`: the number of cases.
    Switch(usize),
    TryCatch,
    Inverter,
    RetryUntilSuccessful,
    Repeat,
    Timeout,
    Delay,
    ForceSuccess,
    ForceFailure,
    KeepRunningUntilFailure,
    /// `LoopInt`, `LoopDouble`, `LoopString`, `LoopBool`.
    Loop(LoopType),
    Precondition,
    RunOnce,
    /// `SkipUnlessUpdated` (not updated: skipped) and `WaitValueUpdate` (not updated:
    /// running).
    EntryUpdated {
        skip: bool,
    },
    SubTree,
    Script,
    ScriptCondition,
    WasEntryUpdated,
    UnsetBlackboard,
    /// A decorator that returns what its child returns (stubs of custom decorators).
    PassThrough,
}

/// The element type of a `Loop*` node's queue.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum LoopType {
    Int,
    Double,
    String,
    Bool,
}

impl BuiltinKind {
    pub(crate) fn of(id: &str) -> Option<BuiltinKind> {
        Some(match id {
            "Sequence" => BuiltinKind::Sequence,
            "ReactiveSequence" => BuiltinKind::ReactiveSequence,
            // "SequenceStar" is BehaviorTree.CPP 3's name (registered with
            // USE_BTCPP3_OLD_NAMES).
            "SequenceWithMemory" | "SequenceStar" => BuiltinKind::SequenceWithMemory,
            "Fallback" => BuiltinKind::Fallback,
            "ReactiveFallback" => BuiltinKind::ReactiveFallback,
            "AsyncSequence" => BuiltinKind::AsyncSequence,
            "AsyncFallback" => BuiltinKind::AsyncFallback,
            "Parallel" => BuiltinKind::Parallel,
            "ParallelAll" => BuiltinKind::ParallelAll,
            "IfThenElse" => BuiltinKind::IfThenElse,
            "WhileDoElse" => BuiltinKind::WhileDoElse,
            "Switch2" => BuiltinKind::Switch(2),
            "Switch3" => BuiltinKind::Switch(3),
            "Switch4" => BuiltinKind::Switch(4),
            "Switch5" => BuiltinKind::Switch(5),
            "Switch6" => BuiltinKind::Switch(6),
            "TryCatch" => BuiltinKind::TryCatch,
            "Inverter" => BuiltinKind::Inverter,
            // "RetryUntilSuccesful" (sic) is BehaviorTree.CPP 3's spelling.
            "RetryUntilSuccessful" | "RetryUntilSuccesful" => BuiltinKind::RetryUntilSuccessful,
            "Repeat" => BuiltinKind::Repeat,
            "Timeout" => BuiltinKind::Timeout,
            "Delay" => BuiltinKind::Delay,
            "ForceSuccess" => BuiltinKind::ForceSuccess,
            "ForceFailure" => BuiltinKind::ForceFailure,
            "KeepRunningUntilFailure" => BuiltinKind::KeepRunningUntilFailure,
            "LoopInt" => BuiltinKind::Loop(LoopType::Int),
            "LoopDouble" => BuiltinKind::Loop(LoopType::Double),
            "LoopString" => BuiltinKind::Loop(LoopType::String),
            "LoopBool" => BuiltinKind::Loop(LoopType::Bool),
            "Precondition" => BuiltinKind::Precondition,
            "RunOnce" => BuiltinKind::RunOnce,
            "SkipUnlessUpdated" => BuiltinKind::EntryUpdated { skip: true },
            "WaitValueUpdate" => BuiltinKind::EntryUpdated { skip: false },
            "SubTree" => BuiltinKind::SubTree,
            "Script" => BuiltinKind::Script,
            "ScriptCondition" => BuiltinKind::ScriptCondition,
            "WasEntryUpdated" => BuiltinKind::WasEntryUpdated,
            "UnsetBlackboard" => BuiltinKind::UnsetBlackboard,
            _ => return None,
        })
    }

    pub(crate) fn category(self) -> NodeCategory {
        match self {
            BuiltinKind::Sequence
            | BuiltinKind::ReactiveSequence
            | BuiltinKind::SequenceWithMemory
            | BuiltinKind::Fallback
            | BuiltinKind::ReactiveFallback
            | BuiltinKind::AsyncSequence
            | BuiltinKind::AsyncFallback
            | BuiltinKind::Parallel
            | BuiltinKind::ParallelAll
            | BuiltinKind::IfThenElse
            | BuiltinKind::WhileDoElse
            | BuiltinKind::Switch(_)
            | BuiltinKind::TryCatch => NodeCategory::Control,
            BuiltinKind::SubTree => NodeCategory::SubTree,
            BuiltinKind::Script | BuiltinKind::WasEntryUpdated | BuiltinKind::UnsetBlackboard => {
                NodeCategory::Action
            }
            BuiltinKind::ScriptCondition => NodeCategory::Condition,
            _ => NodeCategory::Decorator,
        }
    }
}

/// The built-in leaves (implemented in `registry.rs` and registered by `Registry::new`).
pub(crate) const BUILTIN_LEAVES: [&str; 4] =
    ["AlwaysSuccess", "AlwaysFailure", "SetBlackboard", "Sleep"];

/// BehaviorTree.CPP 4 built-in nodes that chronomap does not implement; loading a tree that
/// uses one is an error that says so (rather than "unknown node").
///
/// `EntryUpdated` is the name of `SkipUnlessUpdated`'s C++ class (`EntryUpdatedDecorator`),
/// which some 4.x releases briefly registered under that name with semantics that changed
/// since; write `SkipUnlessUpdated` or `WaitValueUpdate` instead. Everything else of
/// BehaviorTree.CPP 4's factory is implemented; coroutine actions and threaded actions are
/// user leaves ([`LeafNode`](super::LeafNode)s returning running), not built-ins.
pub const UNSUPPORTED_BUILTINS: &[&str] = &["EntryUpdated"];

/// Whether `id` is a node chronomap implements itself (controls, decorators, `SubTree` and the
/// built-in leaves); such IDs cannot be registered again and are left out of saved
/// `<TreeNodesModel>`s.
pub fn is_builtin(id: &str) -> bool {
    BuiltinKind::of(id).is_some() || BUILTIN_LEAVES.contains(&id)
}

/// The model (category and ports) of a built-in node, with BehaviorTree.CPP's port names,
/// types, defaults and documentation.
pub fn builtin_model(id: &str) -> Option<NodeModel> {
    use NodeCategory::{Action, Control, Decorator, SubTree};
    let model = match id {
        "Sequence" | "ReactiveSequence" | "SequenceWithMemory" | "SequenceStar" | "Fallback"
        | "ReactiveFallback" | "AsyncSequence" | "AsyncFallback" | "IfThenElse" | "WhileDoElse" => {
            NodeModel::new(Control, id)
        }
        "ParallelAll" => NodeModel::new(Control, id).port(
            PortSpec::input("max_failures")
                .typed("int")
                .with_default("1")
                .described(
                    "If the number of children returning FAILURE exceeds this value, \
                     ParallelAll returns FAILURE",
                ),
        ),
        "Switch2" | "Switch3" | "Switch4" | "Switch5" | "Switch6" => {
            let cases = match BuiltinKind::of(id) {
                Some(BuiltinKind::Switch(n)) => n,
                _ => 0,
            };
            let mut model =
                NodeModel::new(Control, id).port(PortSpec::input("variable").typed("std::string"));
            for k in 1..=cases {
                model = model.port(PortSpec::input(&format!("case_{k}")).typed("std::string"));
            }
            model
        }
        "TryCatch" => NodeModel::new(Control, id).port(
            PortSpec::input("catch_on_halt")
                .typed("bool")
                .with_default("false")
                .described(
                    "If true, execute the catch child when the node is halted during the \
                     try-block",
                ),
        ),
        "KeepRunningUntilFailure" => NodeModel::new(Decorator, id),
        "Delay" => NodeModel::new(Decorator, id).port(
            PortSpec::input("delay_msec")
                .typed("unsigned int")
                .required()
                .described("Tick the child after a few milliseconds"),
        ),
        "LoopInt" | "LoopDouble" | "LoopString" | "LoopBool" => {
            let ty = match id {
                "LoopInt" => "int",
                "LoopDouble" => "double",
                "LoopString" => "std::string",
                _ => "bool",
            };
            NodeModel::new(Decorator, id)
                .port(PortSpec::inout("queue").typed(&format!("std::shared_ptr<std::deque<{ty}>>")))
                .port(PortSpec::output("value").typed(ty))
                .port(
                    PortSpec::input("if_empty")
                        .typed("BT::NodeStatus")
                        .with_default("SUCCESS")
                        .described("Status to return if queue is empty: SUCCESS, FAILURE, SKIPPED"),
                )
        }
        "Precondition" => NodeModel::new(Decorator, id)
            .port(PortSpec::input("if").typed("std::string").required())
            .port(
                PortSpec::input("else")
                    .typed("BT::NodeStatus")
                    .with_default("FAILURE")
                    .described("Return status if condition is false"),
            ),
        "RunOnce" => NodeModel::new(Decorator, id).port(
            PortSpec::input("then_skip")
                .typed("bool")
                .with_default("true")
                .described(
                    "If true, skip after the first execution, otherwise return the same \
                     NodeStatus returned once by the child.",
                ),
        ),
        "SkipUnlessUpdated" | "WaitValueUpdate" => NodeModel::new(Decorator, id).port(
            PortSpec::input("entry")
                .typed("BT::Any")
                .required()
                .described("Entry to check"),
        ),
        "Script" => NodeModel::new(Action, id).port(
            PortSpec::input("code")
                .typed("std::string")
                .required()
                .described("Piece of code that can be parsed"),
        ),
        "ScriptCondition" => NodeModel::new(NodeCategory::Condition, id).port(
            PortSpec::input("code")
                .typed("std::string")
                .required()
                .described("Piece of code that can be parsed. Must return false or true"),
        ),
        "WasEntryUpdated" => NodeModel::new(Action, id).port(
            PortSpec::input("entry")
                .typed("BT::Any")
                .required()
                .described("Entry to check"),
        ),
        "UnsetBlackboard" => NodeModel::new(Action, id).port(
            PortSpec::input("key")
                .typed("std::string")
                .required()
                .described("Key of the entry to remove"),
        ),
        "Parallel" => NodeModel::new(Control, id)
            .port(
                PortSpec::input("success_count")
                    .typed("int")
                    .with_default("-1")
                    .described("number of children that need to succeed to trigger a SUCCESS"),
            )
            .port(
                PortSpec::input("failure_count")
                    .typed("int")
                    .with_default("1")
                    .described("number of children that need to fail to trigger a FAILURE"),
            ),
        "Inverter" | "ForceSuccess" | "ForceFailure" => NodeModel::new(Decorator, id),
        "RetryUntilSuccessful" | "RetryUntilSuccesful" => NodeModel::new(Decorator, id).port(
            PortSpec::input("num_attempts")
                .typed("int")
                .required()
                .described(
                    "Execute again a failing child up to N times. Use -1 to create an infinite \
                     loop.",
                ),
        ),
        "Repeat" => NodeModel::new(Decorator, id).port(
            PortSpec::input("num_cycles")
                .typed("int")
                .required()
                .described(
                    "Repeat a successful child up to N times. Use -1 to create an infinite loop.",
                ),
        ),
        "Timeout" => NodeModel::new(Decorator, id).port(
            PortSpec::input("msec")
                .typed("unsigned int")
                .required()
                .described(
                    "After a certain amount of time, halt() the child if it is still running.",
                ),
        ),
        "SubTree" => NodeModel::new(SubTree, id),
        "AlwaysSuccess" | "AlwaysFailure" => NodeModel::new(Action, id),
        "SetBlackboard" => NodeModel::new(Action, id)
            .port(
                PortSpec::input("value")
                    .required()
                    .described("Value to be written into the output_key"),
            )
            .port(
                PortSpec::inout("output_key")
                    .required()
                    .described("Name of the blackboard entry where the value should be written"),
            ),
        "Sleep" => NodeModel::new(Action, id).port(
            PortSpec::input("msec")
                .typed("unsigned int")
                .required()
                .described("Time to wait, in milliseconds"),
        ),
        _ => return None,
    };
    Some(model)
}
