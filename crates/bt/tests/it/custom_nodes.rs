//! Custom control nodes and decorators, and stubs of declared but unimplemented nodes.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use chronomap_bt::{
    BtDocument, ControlContext, ControlNode, NodeCategory, NodeDef, NodeModel, PortSpec, Registry,
    RegistryError, Status, StubPolicy, TickError, Tree, TreeDef,
};

fn tree(root: NodeDef, registry: &Registry) -> Tree {
    Tree::new(&BtDocument::single(TreeDef::new("Main", root)), registry).unwrap()
}

fn ticks(tree: &mut Tree, n: usize) -> Vec<Status> {
    (0..n)
        .map(|k| tree.tick_once(Duration::from_millis(k as u64)).unwrap())
        .collect()
}

#[test]
fn leaf_stubs_follow_their_policy() {
    let mut registry = Registry::new();
    registry
        .register_stub(
            NodeModel::new(NodeCategory::Action, "Dock"),
            StubPolicy::Running(2),
        )
        .unwrap();
    registry
        .register_stub(
            NodeModel::new(NodeCategory::Condition, "IsCharged"),
            StubPolicy::Failure,
        )
        .unwrap();
    registry
        .register_stub(
            NodeModel::new(NodeCategory::Action, "Beep").port(PortSpec::input("volume")),
            StubPolicy::Success,
        )
        .unwrap();
    let mut t = tree(NodeDef::action("Dock"), &registry);
    assert_eq!(
        ticks(&mut t, 6),
        [
            Status::Running,
            Status::Running,
            Status::Success,
            Status::Running,
            Status::Running,
            Status::Success
        ]
    );
    let mut t = tree(NodeDef::condition("IsCharged"), &registry);
    assert_eq!(ticks(&mut t, 1), [Status::Failure]);
    let mut t = tree(NodeDef::action("Beep").port("volume", "11"), &registry);
    assert_eq!(ticks(&mut t, 1), [Status::Success]);

    assert_eq!(
        registry.register_stub(
            NodeModel::new(NodeCategory::Condition, "Slow"),
            StubPolicy::Running(1)
        ),
        Err(RegistryError::RunningCondition { id: "Slow".into() })
    );
    assert!(matches!(
        registry.register_stub(
            NodeModel::new(NodeCategory::Action, "Dock"),
            StubPolicy::Success
        ),
        Err(RegistryError::AlreadyRegistered { .. })
    ));
    assert!(matches!(
        registry.register_stub(
            NodeModel::new(NodeCategory::Control, "Sequence"),
            StubPolicy::Success
        ),
        Err(RegistryError::Builtin { .. })
    ));
}

#[test]
fn control_stubs_are_sequences_and_decorator_stubs_pass_through() {
    let mut registry = Registry::new();
    registry
        .register_stub(
            NodeModel::new(NodeCategory::Control, "PipelineSequence"),
            StubPolicy::Failure,
        )
        .unwrap();
    registry
        .register_stub(
            NodeModel::new(NodeCategory::Decorator, "RateController").port(PortSpec::input("hz")),
            StubPolicy::Failure,
        )
        .unwrap();
    registry
        .register_stub(
            NodeModel::new(NodeCategory::Action, "Drive"),
            StubPolicy::Running(1),
        )
        .unwrap();
    let root = NodeDef::decorator("RateController")
        .port("hz", "1.0")
        .child(
            NodeDef::control("PipelineSequence")
                .child(NodeDef::action("AlwaysSuccess"))
                .child(NodeDef::action("Drive")),
        );
    let mut t = tree(root, &registry);
    assert_eq!(ticks(&mut t, 2), [Status::Running, Status::Success]);
    let root = NodeDef::control("PipelineSequence")
        .child(NodeDef::action("AlwaysFailure"))
        .child(NodeDef::action("Drive"));
    let mut t = tree(root, &registry);
    assert_eq!(ticks(&mut t, 1), [Status::Failure]);
}

/// Ticks its children in order every tick (reactively) and succeeds when one of them does,
/// like a ReactiveFallback; counts its halts.
struct FirstSuccess {
    halts: Arc<AtomicUsize>,
}

impl ControlNode for FirstSuccess {
    fn tick(&mut self, ctx: &mut ControlContext<'_>) -> Result<Status, TickError> {
        for k in 0..ctx.child_count() {
            match ctx.tick_child(k)? {
                Status::Success => {
                    ctx.reset_children();
                    return Ok(Status::Success);
                }
                Status::Running => return Ok(Status::Running),
                _ => {}
            }
        }
        ctx.reset_children();
        Ok(Status::Failure)
    }

    fn halt(&mut self, ctx: &mut ControlContext<'_>) {
        self.halts.fetch_add(1, Ordering::SeqCst);
        ctx.reset_children();
    }
}

/// A decorator that fails with its own error when `limit` ticks are exceeded.
struct AtMost {
    seen: u32,
}

impl ControlNode for AtMost {
    fn tick(&mut self, ctx: &mut ControlContext<'_>) -> Result<Status, TickError> {
        let limit: u32 = ctx.input::<i64>("limit")?.try_into().unwrap_or(0);
        self.seen += 1;
        if self.seen > limit {
            return Err(ctx.error(format!("ticked more than {limit} times")));
        }
        ctx.set_output("seen", i64::from(self.seen))?;
        ctx.tick_child(0)
    }
}

#[test]
fn custom_controls_and_decorators_tick_halt_and_fail_through_their_context() {
    let halts = Arc::new(AtomicUsize::new(0));
    let mut registry = Registry::new();
    let h = Arc::clone(&halts);
    registry
        .register_control(
            NodeModel::new(NodeCategory::Control, "FirstSuccess"),
            move || {
                Box::new(FirstSuccess {
                    halts: Arc::clone(&h),
                })
            },
        )
        .unwrap();
    registry
        .register_control(
            NodeModel::new(NodeCategory::Decorator, "AtMost")
                .port(PortSpec::input("limit").typed("int"))
                .port(PortSpec::output("seen")),
            || Box::new(AtMost { seen: 0 }),
        )
        .unwrap();
    registry
        .register_action_fn("Forever", |_| Ok(Status::Running))
        .unwrap();
    assert!(matches!(
        registry.register_control(NodeModel::new(NodeCategory::Action, "Leafy"), || {
            Box::new(AtMost { seen: 0 })
        }),
        Err(RegistryError::NotALeaf { .. })
    ));

    let root = NodeDef::decorator("AtMost")
        .port("limit", "2")
        .port("seen", "{seen}")
        .child(
            NodeDef::control("FirstSuccess")
                .child(NodeDef::action("AlwaysFailure"))
                .child(NodeDef::action("Forever").named("forever")),
        );
    let mut t = tree(root, &registry);
    assert_eq!(ticks(&mut t, 2), [Status::Running, Status::Running]);
    assert_eq!(t.blackboard().get_as::<i64>("seen"), Some(2));
    t.halt(Duration::from_secs(1));
    assert_eq!(halts.load(Ordering::SeqCst), 1);
    assert!(t.nodes().iter().all(|n| n.status() == Status::Idle));
    let e = t.tick_once(Duration::from_secs(2)).unwrap_err();
    assert_eq!(e.to_string(), "node 1 (AtMost): ticked more than 2 times");

    // Pre-conditions apply to custom nodes as to every node.
    let root = NodeDef::control("FirstSuccess")
        .script("_skipIf", "true")
        .child(NodeDef::action("AlwaysSuccess"));
    let mut t = tree(root, &registry);
    assert_eq!(ticks(&mut t, 1), [Status::Skipped]);
}

#[test]
fn custom_nodes_are_validated_like_built_ins() {
    let mut registry = Registry::new();
    registry
        .register_control(NodeModel::new(NodeCategory::Decorator, "Once"), || {
            Box::new(AtMost { seen: 0 })
        })
        .unwrap();
    // A decorator with two children, and an unknown port.
    let root = NodeDef::decorator("Once")
        .child(NodeDef::action("AlwaysSuccess"))
        .child(NodeDef::action("AlwaysSuccess"));
    assert!(Tree::new(&BtDocument::single(TreeDef::new("Main", root)), &registry).is_err());
    let root = NodeDef::decorator("Once")
        .port("limit", "1")
        .child(NodeDef::action("AlwaysSuccess"));
    let e = Tree::new(&BtDocument::single(TreeDef::new("Main", root)), &registry).unwrap_err();
    assert_eq!(e.attribute(), Some("limit"));
}
