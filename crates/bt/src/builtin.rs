//! The built-in nodes: their IDs, categories and ports as BehaviorTree.CPP 4 registers them
//! (`BehaviorTreeFactory::BehaviorTreeFactory` and each node's `providedPorts`).

use super::model::{NodeCategory, NodeModel, PortSpec};

/// The control and decorator nodes the runtime implements (and `SubTree`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum BuiltinKind {
    Sequence,
    ReactiveSequence,
    SequenceWithMemory,
    Fallback,
    ReactiveFallback,
    Parallel,
    Inverter,
    RetryUntilSuccessful,
    Repeat,
    Timeout,
    ForceSuccess,
    ForceFailure,
    SubTree,
}

impl BuiltinKind {
    pub(crate) fn of(id: &str) -> Option<BuiltinKind> {
        Some(match id {
            "Sequence" => BuiltinKind::Sequence,
            "ReactiveSequence" => BuiltinKind::ReactiveSequence,
            "SequenceWithMemory" => BuiltinKind::SequenceWithMemory,
            "Fallback" => BuiltinKind::Fallback,
            "ReactiveFallback" => BuiltinKind::ReactiveFallback,
            "Parallel" => BuiltinKind::Parallel,
            "Inverter" => BuiltinKind::Inverter,
            "RetryUntilSuccessful" => BuiltinKind::RetryUntilSuccessful,
            "Repeat" => BuiltinKind::Repeat,
            "Timeout" => BuiltinKind::Timeout,
            "ForceSuccess" => BuiltinKind::ForceSuccess,
            "ForceFailure" => BuiltinKind::ForceFailure,
            "SubTree" => BuiltinKind::SubTree,
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
            | BuiltinKind::Parallel => NodeCategory::Control,
            BuiltinKind::SubTree => NodeCategory::SubTree,
            _ => NodeCategory::Decorator,
        }
    }
}

/// The built-in leaves (implemented in `registry.rs` and registered by `Registry::new`).
pub(crate) const BUILTIN_LEAVES: [&str; 4] =
    ["AlwaysSuccess", "AlwaysFailure", "SetBlackboard", "Sleep"];

/// BehaviorTree.CPP 4 built-in nodes that chronomap does not implement; loading a tree that
/// uses one is an error that says so (rather than "unknown node").
pub const UNSUPPORTED_BUILTINS: &[&str] = &[
    "AsyncFallback",
    "AsyncSequence",
    "Delay",
    "EntryUpdated",
    "IfThenElse",
    "KeepRunningUntilFailure",
    "LoopBool",
    "LoopDouble",
    "LoopInt",
    "LoopString",
    "ParallelAll",
    "Precondition",
    "RetryUntilSuccesful",
    "RunOnce",
    "Script",
    "ScriptCondition",
    "SequenceStar",
    "SkipUnlessUpdated",
    "Switch2",
    "Switch3",
    "Switch4",
    "Switch5",
    "Switch6",
    "TryCatch",
    "UnsetBlackboard",
    "WaitValueUpdate",
    "WasEntryUpdated",
    "WhileDoElse",
];

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
        "Sequence" | "ReactiveSequence" | "SequenceWithMemory" | "Fallback"
        | "ReactiveFallback" => NodeModel::new(Control, id),
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
        "RetryUntilSuccessful" => NodeModel::new(Decorator, id).port(
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
