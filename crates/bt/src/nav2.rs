//! Nav2's custom control nodes and decorators, so that Nav2 navigator trees run with the
//! statuses Nav2 gives: `PipelineSequence`, `RecoveryNode`, `RoundRobin`, `RateController` and
//! `GoalUpdater`, written after the documented behaviour of Nav2's `nav2_behavior_tree`
//! plugins (ros-navigation/navigation2, Apache-2.0; the behaviour, not the code). Each
//! implements [`ControlNode`]; [`register`] adds one to a [`Registry`] under the model a
//! document declares (Nav2's `nav2_tree_nodes.xml`), as `chronomap bt run` does for the IDs a
//! tree uses.
//!
//! ```
//! use std::time::Duration;
//! use chronomap_bt::{BtDocument, NodeCategory, NodeDef, NodeModel, Registry, Status};
//! use chronomap_bt::{Tree, TreeDef};
//!
//! let mut registry = Registry::new();
//! let pipeline = NodeModel::new(NodeCategory::Control, "PipelineSequence");
//! chronomap_bt::nav2::register(&mut registry, &pipeline)?;
//! registry.register_action_fn("ComputePath", |_| Ok(Status::Success))?;
//! registry.register_action_fn("FollowPath", |_| Ok(Status::Running))?;
//! let root = NodeDef::control("PipelineSequence")
//!     .child(NodeDef::action("ComputePath"))
//!     .child(NodeDef::action("FollowPath"));
//! let mut tree = Tree::new(&BtDocument::single(TreeDef::new("Main", root)), &registry)?;
//! // The path is recomputed on every tick while the robot follows it.
//! assert_eq!(tree.tick_exactly_once(Duration::ZERO)?, Status::Running);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use super::{
    ControlContext, ControlNode, NodeCategory, NodeModel, Registry, RegistryError, Status,
    TickError, Value,
};

/// The IDs emulated, with their category.
pub const EMULATED: [(&str, NodeCategory); 5] = [
    ("PipelineSequence", NodeCategory::Control),
    ("RecoveryNode", NodeCategory::Control),
    ("RoundRobin", NodeCategory::Control),
    ("RateController", NodeCategory::Decorator),
    ("GoalUpdater", NodeCategory::Decorator),
];

/// Whether `id` of `category` is emulated.
pub fn is_emulated(id: &str, category: NodeCategory) -> bool {
    EMULATED.iter().any(|&(e, c)| e == id && c == category)
}

/// Registers the emulation of `model` (one of [`EMULATED`]).
///
/// # Errors
/// [`RegistryError`] if the registry has the ID already.
pub fn register(registry: &mut Registry, model: &NodeModel) -> Result<(), RegistryError> {
    let model = model.clone();
    match model.id.as_str() {
        "PipelineSequence" => {
            registry.register_control(model, || Box::new(PipelineSequence { last_running: 0 }))
        }
        "RecoveryNode" => registry.register_control(model, || {
            Box::new(RecoveryNode {
                current: 0,
                retries: 0,
            })
        }),
        "RoundRobin" => registry.register_control(model, || {
            Box::new(RoundRobin {
                current: 0,
                failed: 0,
            })
        }),
        "RateController" => registry.register_control(model, || {
            Box::new(RateController {
                start: std::time::Duration::ZERO,
                first: true,
            })
        }),
        _ => registry.register_control(model, || Box::new(GoalUpdater)),
    }
}

/// Nav2's `PipelineSequence`: ticks every child from the first each tick; a child that
/// succeeds lets the next one run, a running child before the furthest one reached lets the
/// later ones keep running, the furthest running child makes it return running; a failure
/// halts all and fails; success of the last halts all and succeeds.
struct PipelineSequence {
    /// `last_child_ticked_`: the furthest child that returned running.
    last_running: usize,
}

impl ControlNode for PipelineSequence {
    fn tick(&mut self, ctx: &mut ControlContext<'_>) -> Result<Status, TickError> {
        for i in 0..ctx.child_count() {
            match ctx.tick_child(i)? {
                Status::Failure => {
                    ctx.reset_children();
                    self.last_running = 0;
                    return Ok(Status::Failure);
                }
                Status::Running if i >= self.last_running => {
                    self.last_running = i;
                    return Ok(Status::Running);
                }
                _ => {} // success, skipped, or running behind the furthest child
            }
        }
        ctx.reset_children();
        self.last_running = 0;
        Ok(Status::Success)
    }

    fn halt(&mut self, ctx: &mut ControlContext<'_>) {
        ctx.reset_children();
        self.last_running = 0;
    }
}

/// Nav2's `RecoveryNode` (`number_of_retries`, default 1; exactly 2 children): the first
/// child's success succeeds; its failure runs the second child (the recovery) if retries are
/// left, and after the recovery succeeds the first child is tried again; the recovery's
/// failure, or a failure with no retries left, fails. A skipped first child skips the node; a
/// skipped recovery fails it without counting a retry.
struct RecoveryNode {
    current: usize,
    retries: i64,
}

impl RecoveryNode {
    fn reset(&mut self, ctx: &mut ControlContext<'_>) {
        ctx.reset_children();
        self.current = 0;
        self.retries = 0;
    }
}

impl ControlNode for RecoveryNode {
    fn tick(&mut self, ctx: &mut ControlContext<'_>) -> Result<Status, TickError> {
        // Nav2's model gives the default (1) when the attribute is absent.
        let allowed: i64 = ctx.input("number_of_retries")?;
        if ctx.child_count() != 2 {
            return Err(ctx.error(format!(
                "a RecoveryNode must have exactly 2 children, it has {}",
                ctx.child_count()
            )));
        }
        while self.current < 2 && self.retries <= allowed {
            let status = ctx.tick_child(self.current)?;
            if self.current == 0 {
                match status {
                    Status::Skipped => {
                        self.reset(ctx);
                        return Ok(Status::Skipped);
                    }
                    Status::Success => {
                        self.reset(ctx);
                        return Ok(Status::Success);
                    }
                    Status::Running => return Ok(Status::Running),
                    _ => {
                        if self.retries < allowed {
                            ctx.halt_child(0);
                            self.current = 1;
                        } else {
                            self.reset(ctx);
                            return Ok(Status::Failure);
                        }
                    }
                }
            } else {
                match status {
                    Status::Skipped => {
                        self.current = 0;
                        ctx.halt_child(1);
                        return Ok(Status::Failure);
                    }
                    Status::Running => return Ok(Status::Running),
                    Status::Success => {
                        ctx.halt_child(1);
                        self.retries += 1;
                        self.current = 0;
                    }
                    _ => {
                        self.reset(ctx);
                        return Ok(Status::Failure);
                    }
                }
            }
        }
        self.reset(ctx);
        Ok(Status::Failure)
    }

    fn halt(&mut self, ctx: &mut ControlContext<'_>) {
        self.reset(ctx);
    }
}

/// Nav2's `RoundRobin` (as in Nav2 Humble to Jazzy, which always wrap around; the
/// `wrap_around` port is accepted and not used): ticks one child, starting where the last
/// tick left off; a completed child moves on to the next (after the last, the first); success
/// succeeds (and resets the failure count), running runs, and it fails when every child has
/// failed in turn.
struct RoundRobin {
    current: usize,
    failed: usize,
}

impl ControlNode for RoundRobin {
    fn tick(&mut self, ctx: &mut ControlContext<'_>) -> Result<Status, TickError> {
        let n = ctx.child_count();
        let mut skipped = 0;
        while self.failed + skipped < n {
            let status = ctx.tick_child(self.current)?;
            if status != Status::Running {
                self.current = (self.current + 1) % n;
            }
            match status {
                Status::Success => {
                    self.failed = 0;
                    ctx.reset_children();
                    return Ok(Status::Success);
                }
                Status::Failure => self.failed += 1,
                Status::Skipped => skipped += 1,
                _ => return Ok(Status::Running),
            }
        }
        let all_skipped = skipped == n;
        ctx.reset_children();
        self.failed = 0;
        Ok(if all_skipped {
            Status::Skipped
        } else {
            Status::Failure
        })
    }

    fn halt(&mut self, ctx: &mut ControlContext<'_>) {
        ctx.reset_children();
        self.current = 0;
        self.failed = 0;
    }
}

/// Nav2's `RateController` (`hz`, default 10): ticks its child when it starts, while the child
/// is running, and when 1/`hz` seconds have passed since the child last succeeded (or since
/// it started); in between it returns running without ticking the child.
struct RateController {
    start: std::time::Duration,
    first: bool,
}

impl ControlNode for RateController {
    fn tick(&mut self, ctx: &mut ControlContext<'_>) -> Result<Status, TickError> {
        // Nav2's model gives the default (10) when the attribute is absent.
        let hz: f64 = ctx.input("hz")?;
        if !(hz.is_finite() && hz > 0.0) {
            return Err(ctx.error(format!("hz={hz}: expected a positive rate")));
        }
        // Nav2: a new iteration starts when the node is not active (idle or skipped).
        if matches!(ctx.status(), Status::Idle | Status::Skipped) {
            self.start = ctx.now();
            self.first = true;
        }
        let elapsed = ctx.now().saturating_sub(self.start).as_secs_f64();
        if self.first || ctx.child_status(0) == Status::Running || elapsed >= 1.0 / hz {
            self.first = false;
            return Ok(match ctx.tick_child(0)? {
                Status::Success => {
                    self.start = ctx.now();
                    Status::Success
                }
                Status::Running => Status::Running,
                Status::Skipped => Status::Skipped,
                _ => Status::Failure,
            });
        }
        Ok(Status::Running)
    }
}

/// Nav2's `GoalUpdater` as far as a run without ROS goes: `output_goal` gets `input_goal`
/// (no goal topic updates it here), then the child is ticked and its status returned.
struct GoalUpdater;

impl ControlNode for GoalUpdater {
    fn tick(&mut self, ctx: &mut ControlContext<'_>) -> Result<Status, TickError> {
        if let Ok(goal) = ctx.input::<Value>("input_goal") {
            let _ = ctx.set_output("output_goal", goal);
        }
        ctx.tick_child(0)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::time::Duration;

    use super::*;
    use crate::{BtDocument, NodeDef, Tree, TreeDef};

    /// A leaf whose outcome on tick `k` (the tick's time in ms) is `outcomes[k]` (the last one
    /// after that), counting its ticks.
    fn leaf(registry: &mut Registry, id: &str, outcomes: &'static [Status]) -> Arc<AtomicUsize> {
        let ticks = Arc::new(AtomicUsize::new(0));
        let counter = ticks.clone();
        registry
            .register_action_fn(id, move |ctx| {
                counter.fetch_add(1, Ordering::SeqCst);
                let k = ctx.now().as_millis() as usize;
                Ok(outcomes[k.min(outcomes.len() - 1)])
            })
            .unwrap();
        ticks
    }

    fn control(registry: &mut Registry, id: &str, category: NodeCategory) {
        let model = NodeModel::new(category, id);
        let model = match id {
            "RecoveryNode" => model.port(
                crate::PortSpec::input("number_of_retries")
                    .typed("int")
                    .with_default("1"),
            ),
            _ => model,
        };
        assert!(is_emulated(id, category));
        register(registry, &model).unwrap();
    }

    fn tree(root: NodeDef, registry: &Registry) -> Tree {
        Tree::new(&BtDocument::single(TreeDef::new("Main", root)), registry).unwrap()
    }

    fn tick(tree: &mut Tree, k: u64) -> Status {
        tree.tick_exactly_once(Duration::from_millis(k)).unwrap()
    }

    #[test]
    fn pipeline_sequence_reticks_earlier_children_and_lets_them_run_behind_the_furthest() {
        use Status::{Running, Success};
        let mut registry = Registry::new();
        control(&mut registry, "PipelineSequence", NodeCategory::Control);
        // A: running, success, running, ...; B: running on its first two ticks, then success.
        let a = leaf(&mut registry, "A", &[Running, Success, Running]);
        let b = leaf(&mut registry, "B", &[Running, Running, Running, Success]);
        let root = NodeDef::control("PipelineSequence")
            .child(NodeDef::action("A"))
            .child(NodeDef::action("B"));
        let mut t = tree(root, &registry);
        // Tick 0: A runs, B is not reached.
        assert_eq!(tick(&mut t, 0), Running);
        assert_eq!((a.load(Ordering::SeqCst), b.load(Ordering::SeqCst)), (1, 0));
        // Tick 1: A succeeds, B runs (the furthest child).
        assert_eq!(tick(&mut t, 1), Running);
        // Tick 2: A runs again, behind B, so B is ticked too and still runs.
        assert_eq!(tick(&mut t, 2), Running);
        assert_eq!((a.load(Ordering::SeqCst), b.load(Ordering::SeqCst)), (3, 2));
        // Tick 3: A running, B succeeds: the last child's success ends the pipeline.
        assert_eq!(tick(&mut t, 3), Success);
    }

    #[test]
    fn pipeline_sequence_fails_on_any_failure() {
        use Status::{Failure, Running, Success};
        let mut registry = Registry::new();
        control(&mut registry, "PipelineSequence", NodeCategory::Control);
        leaf(&mut registry, "A", &[Success, Failure]);
        let b = leaf(&mut registry, "B", &[Running]);
        let root = NodeDef::control("PipelineSequence")
            .child(NodeDef::action("A"))
            .child(NodeDef::action("B"));
        let mut t = tree(root, &registry);
        assert_eq!(tick(&mut t, 0), Running);
        assert_eq!(tick(&mut t, 1), Failure);
        // B was running and is halted, not ticked again.
        assert_eq!(b.load(Ordering::SeqCst), 1);
    }

    #[test]
    fn recovery_node_runs_the_recovery_and_retries_within_the_tick() {
        use Status::{Failure, Success};
        let mut registry = Registry::new();
        control(&mut registry, "RecoveryNode", NodeCategory::Control);
        let main = leaf(&mut registry, "Navigate", &[Failure]);
        let recovery = leaf(&mut registry, "Clear", &[Success]);
        let root = NodeDef::control("RecoveryNode")
            .port("number_of_retries", "2")
            .child(NodeDef::action("Navigate"))
            .child(NodeDef::action("Clear"));
        let mut t = tree(root, &registry);
        // Fail, recover, fail, recover, fail: two retries used, then failure, in one tick.
        assert_eq!(tick(&mut t, 0), Failure);
        assert_eq!(main.load(Ordering::SeqCst), 3);
        assert_eq!(recovery.load(Ordering::SeqCst), 2);
    }

    #[test]
    fn recovery_node_succeeds_when_the_retry_succeeds_and_fails_when_the_recovery_fails() {
        use Status::{Failure, Success};
        let mut registry = Registry::new();
        control(&mut registry, "RecoveryNode", NodeCategory::Control);
        leaf(&mut registry, "Navigate", &[Failure, Success]);
        leaf(&mut registry, "Clear", &[Success]);
        leaf(&mut registry, "Broken", &[Failure]);
        let ok = NodeDef::control("RecoveryNode")
            .child(NodeDef::action("Navigate"))
            .child(NodeDef::action("Clear"));
        let mut t = tree(ok, &registry);
        // Tick 0: Navigate fails, Clear succeeds, Navigate (still tick 0) fails again: with
        // one retry (the default) that is failure.
        assert_eq!(tick(&mut t, 0), Failure);
        // Tick 1: Navigate succeeds at once.
        assert_eq!(tick(&mut t, 1), Success);
        let broken = NodeDef::control("RecoveryNode")
            .child(NodeDef::action("Navigate"))
            .child(NodeDef::action("Broken"));
        let mut t = tree(broken, &registry);
        assert_eq!(tick(&mut t, 0), Failure);
    }

    #[test]
    fn round_robin_moves_on_after_each_completion_and_fails_when_all_failed() {
        use Status::{Failure, Success};
        let mut registry = Registry::new();
        control(&mut registry, "RoundRobin", NodeCategory::Control);
        let a = leaf(&mut registry, "A", &[Failure]);
        let b = leaf(&mut registry, "B", &[Success, Failure]);
        let root = NodeDef::control("RoundRobin")
            .child(NodeDef::action("A"))
            .child(NodeDef::action("B"));
        let mut t = tree(root, &registry);
        // Tick 0: A fails, B succeeds: success, and the next tick starts after B, at A.
        assert_eq!(tick(&mut t, 0), Success);
        assert_eq!((a.load(Ordering::SeqCst), b.load(Ordering::SeqCst)), (1, 1));
        // Tick 1: A fails, B fails: every child failed in turn.
        assert_eq!(tick(&mut t, 1), Failure);
        assert_eq!((a.load(Ordering::SeqCst), b.load(Ordering::SeqCst)), (2, 2));
    }
}
