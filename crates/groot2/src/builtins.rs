//! The node models BehaviorTree.CPP 4.8.2's factory registers by itself, as its
//! `WriteTreeToXML` lists them in a tree's `<TreeNodesModel>`: every built-in node type with
//! its ports in the order in which BehaviorTree.CPP's port map (a `std::unordered_map`)
//! yields them, with the C++ type names, defaults and descriptions it prints. This is data
//! about BehaviorTree.CPP's interface, taken from what its Groot2 publisher sends for a tree
//! (`tests/cli/bt_groot2.rs` compares the whole message).

use chronomap_bt::NodeCategory::{self, Action, Condition, Control, Decorator, SubTree};
use chronomap_bt::PortDirection::{self, InOut, Input, Output};

/// A port of a built-in model.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BuiltinPort {
    pub(crate) direction: PortDirection,
    pub(crate) name: &'static str,
    pub(crate) type_name: Option<&'static str>,
    pub(crate) default: Option<&'static str>,
    pub(crate) description: Option<&'static str>,
}

/// A built-in model: category, registration ID, ports in BehaviorTree.CPP's iteration order.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BuiltinModel {
    pub(crate) category: NodeCategory,
    pub(crate) id: &'static str,
    pub(crate) ports: &'static [BuiltinPort],
}

const fn p(
    direction: PortDirection,
    name: &'static str,
    type_name: Option<&'static str>,
    default: Option<&'static str>,
    description: Option<&'static str>,
) -> BuiltinPort {
    BuiltinPort {
        direction,
        name,
        type_name,
        default,
        description,
    }
}

const fn m(
    category: NodeCategory,
    id: &'static str,
    ports: &'static [BuiltinPort],
) -> BuiltinModel {
    BuiltinModel {
        category,
        id,
        ports,
    }
}

/// The built-in models of BehaviorTree.CPP 4.8.2, sorted by ID.
pub(crate) const BUILTIN_MODELS: &[BuiltinModel] = &[
    m(Action, "AlwaysFailure", &[]),
    m(Action, "AlwaysSuccess", &[]),
    m(Control, "AsyncFallback", &[]),
    m(Control, "AsyncSequence", &[]),
    m(
        Decorator,
        "Delay",
        &[p(
            Input,
            "delay_msec",
            Some("unsigned int"),
            None,
            Some("Tick the child after a few milliseconds"),
        )],
    ),
    m(Control, "Fallback", &[]),
    m(Decorator, "ForceFailure", &[]),
    m(Decorator, "ForceSuccess", &[]),
    m(Control, "IfThenElse", &[]),
    m(Decorator, "Inverter", &[]),
    m(Decorator, "KeepRunningUntilFailure", &[]),
    m(
        Decorator,
        "LoopBool",
        &[
            p(Output, "value", Some("bool"), None, None),
            p(
                Input,
                "if_empty",
                Some("BT::NodeStatus"),
                Some("SUCCESS"),
                Some("Status to return if queue is empty: SUCCESS, FAILURE, SKIPPED"),
            ),
            p(
                InOut,
                "queue",
                Some("std::shared_ptr<std::deque<bool, std::allocator<bool> > >"),
                None,
                None,
            ),
        ],
    ),
    m(
        Decorator,
        "LoopDouble",
        &[
            p(Output, "value", Some("double"), None, None),
            p(
                Input,
                "if_empty",
                Some("BT::NodeStatus"),
                Some("SUCCESS"),
                Some("Status to return if queue is empty: SUCCESS, FAILURE, SKIPPED"),
            ),
            p(
                InOut,
                "queue",
                Some("std::shared_ptr<std::deque<double, std::allocator<double> > >"),
                None,
                None,
            ),
        ],
    ),
    m(
        Decorator,
        "LoopInt",
        &[
            p(Output, "value", Some("int"), None, None),
            p(
                Input,
                "if_empty",
                Some("BT::NodeStatus"),
                Some("SUCCESS"),
                Some("Status to return if queue is empty: SUCCESS, FAILURE, SKIPPED"),
            ),
            p(
                InOut,
                "queue",
                Some("std::shared_ptr<std::deque<int, std::allocator<int> > >"),
                None,
                None,
            ),
        ],
    ),
    m(
        Decorator,
        "LoopString",
        &[
            p(Output, "value", Some("std::string"), None, None),
            p(
                Input,
                "if_empty",
                Some("BT::NodeStatus"),
                Some("SUCCESS"),
                Some("Status to return if queue is empty: SUCCESS, FAILURE, SKIPPED"),
            ),
            p(
                InOut,
                "queue",
                Some("std::shared_ptr<std::deque<std::string, std::allocator<std::string> > >"),
                None,
                None,
            ),
        ],
    ),
    m(
        Control,
        "Parallel",
        &[
            p(
                Input,
                "failure_count",
                Some("int"),
                Some("1"),
                Some("number of children that need to fail to trigger a FAILURE"),
            ),
            p(
                Input,
                "success_count",
                Some("int"),
                Some("-1"),
                Some("number of children that need to succeed to trigger a SUCCESS"),
            ),
        ],
    ),
    m(
        Control,
        "ParallelAll",
        &[p(
            Input,
            "max_failures",
            Some("int"),
            Some("1"),
            Some(
                "If the number of children returning FAILURE exceeds this value, ParallelAll returns FAILURE",
            ),
        )],
    ),
    m(
        Decorator,
        "Precondition",
        &[
            p(
                Input,
                "else",
                Some("BT::NodeStatus"),
                Some("FAILURE"),
                Some("Return status if condition is false"),
            ),
            p(Input, "if", Some("std::string"), None, None),
        ],
    ),
    m(Control, "ReactiveFallback", &[]),
    m(Control, "ReactiveSequence", &[]),
    m(
        Decorator,
        "Repeat",
        &[p(
            Input,
            "num_cycles",
            Some("int"),
            None,
            Some("Repeat a successful child up to N times. Use -1 to create an infinite loop."),
        )],
    ),
    m(
        Decorator,
        "RetryUntilSuccessful",
        &[p(
            Input,
            "num_attempts",
            Some("int"),
            None,
            Some("Execute again a failing child up to N times. Use -1 to create an infinite loop."),
        )],
    ),
    m(
        Decorator,
        "RunOnce",
        &[p(
            Input,
            "then_skip",
            Some("bool"),
            Some("true"),
            Some(
                "If true, skip after the first execution, otherwise return the same NodeStatus returned once by the child.",
            ),
        )],
    ),
    m(
        Action,
        "Script",
        &[p(
            Input,
            "code",
            Some("std::string"),
            None,
            Some("Piece of code that can be parsed"),
        )],
    ),
    m(
        Condition,
        "ScriptCondition",
        &[p(
            Input,
            "code",
            Some("BT::AnyTypeAllowed"),
            None,
            Some("Piece of code that can be parsed. Must return false or true"),
        )],
    ),
    m(Control, "Sequence", &[]),
    m(Control, "SequenceWithMemory", &[]),
    m(
        Action,
        "SetBlackboard",
        &[
            p(
                InOut,
                "output_key",
                Some("BT::AnyTypeAllowed"),
                None,
                Some("Name of the blackboard entry where the value should be written"),
            ),
            p(
                Input,
                "value",
                Some("BT::AnyTypeAllowed"),
                None,
                Some("Value to be written into the output_key"),
            ),
        ],
    ),
    m(
        Decorator,
        "SkipUnlessUpdated",
        &[p(
            Input,
            "entry",
            Some("BT::Any"),
            None,
            Some("Entry to check"),
        )],
    ),
    m(
        Action,
        "Sleep",
        &[p(Input, "msec", Some("unsigned int"), None, None)],
    ),
    m(
        SubTree,
        "SubTree",
        &[p(
            Input,
            "_autoremap",
            Some("bool"),
            Some("false"),
            Some("If true, all the ports with the same name will be remapped"),
        )],
    ),
    m(
        Control,
        "Switch2",
        &[
            p(Input, "case_2", Some("std::string"), None, None),
            p(Input, "case_1", Some("std::string"), None, None),
            p(Input, "variable", Some("std::string"), None, None),
        ],
    ),
    m(
        Control,
        "Switch3",
        &[
            p(Input, "case_3", Some("std::string"), None, None),
            p(Input, "case_2", Some("std::string"), None, None),
            p(Input, "case_1", Some("std::string"), None, None),
            p(Input, "variable", Some("std::string"), None, None),
        ],
    ),
    m(
        Control,
        "Switch4",
        &[
            p(Input, "case_4", Some("std::string"), None, None),
            p(Input, "case_3", Some("std::string"), None, None),
            p(Input, "case_2", Some("std::string"), None, None),
            p(Input, "case_1", Some("std::string"), None, None),
            p(Input, "variable", Some("std::string"), None, None),
        ],
    ),
    m(
        Control,
        "Switch5",
        &[
            p(Input, "case_5", Some("std::string"), None, None),
            p(Input, "case_4", Some("std::string"), None, None),
            p(Input, "case_3", Some("std::string"), None, None),
            p(Input, "case_2", Some("std::string"), None, None),
            p(Input, "case_1", Some("std::string"), None, None),
            p(Input, "variable", Some("std::string"), None, None),
        ],
    ),
    m(
        Control,
        "Switch6",
        &[
            p(Input, "case_5", Some("std::string"), None, None),
            p(Input, "case_4", Some("std::string"), None, None),
            p(Input, "case_6", Some("std::string"), None, None),
            p(Input, "case_3", Some("std::string"), None, None),
            p(Input, "case_2", Some("std::string"), None, None),
            p(Input, "case_1", Some("std::string"), None, None),
            p(Input, "variable", Some("std::string"), None, None),
        ],
    ),
    m(
        Decorator,
        "Timeout",
        &[p(
            Input,
            "msec",
            Some("unsigned int"),
            None,
            Some("After a certain amount of time, halt() the child if it is still running."),
        )],
    ),
    m(
        Action,
        "UnsetBlackboard",
        &[p(
            Input,
            "key",
            Some("std::string"),
            None,
            Some("Key of the entry to remove"),
        )],
    ),
    m(
        Decorator,
        "WaitValueUpdate",
        &[p(
            Input,
            "entry",
            Some("BT::Any"),
            None,
            Some("Entry to check"),
        )],
    ),
    m(
        Action,
        "WasEntryUpdated",
        &[p(
            Input,
            "entry",
            Some("BT::Any"),
            None,
            Some("Entry to check"),
        )],
    ),
    m(Control, "WhileDoElse", &[]),
];
