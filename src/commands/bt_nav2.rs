//! Nav2's custom control nodes and decorators as `chronomap bt run` emulates them, so that
//! Nav2 navigator trees run with the statuses Nav2 gives: [`PipelineSequence`],
//! [`RecoveryNode`], [`RoundRobin`], [`RateController`] and [`GoalUpdater`], written after
//! Nav2's `nav2_behavior_tree` plugins (ros-navigation/navigation2, Apache-2.0; the behaviour,
//! not the code). Each implements [`ControlNode`]; [`register`] adds the ones a document
//! declares and uses.

use chronomap_bt::{
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
