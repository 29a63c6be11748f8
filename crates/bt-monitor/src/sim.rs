//! A deterministic fault-injection simulation of the monitoring system of [Stüde 2024] §5.3
//! (Fig. 5.5): a robot patrols; faults are injected (a crashed node, a slow topic, CPU
//! overload, localization lost, navigation failure, or a "stuck" fault no monitor sees); the
//! [`Monitor`]s turn the simulated signals into states that are written to the blackboard of
//! the arbiter, a behavior tree ([`arbiter_document`], or any tree with the same leaves) ticked
//! once per simulated tick. Its conditions read the monitor states; its recovery actions are
//! registered leaves that take the time of [`Recovery::duration`] and fix the fault with
//! probability [`Recovery::p_fix`] (seeded). An error blocks the patrol (§5.3.1: "the system
//! temporarily blocks the main task execution by setting a condition that is reverted after
//! the error is corrected").
//!
//! When the robot has not moved for [`SimConfig::stall_limit`], a supervisor steps in
//! unrequested and clears every fault: these interventions give the TSL of §5.3.2 ([`tsl`]).
//! Recoveries are judged by the one-minute rule of §5.3.2 ([`judge_interventions`]).
//!
//! The blackboard contract: before each tick the root blackboard holds `monitor_node`,
//! `monitor_topic`, `monitor_resources`, `monitor_navigation`, `monitor_localization` (`ok`,
//! `warning` or `error`: the worst monitor of the group). Leaves: conditions `MonitorError`
//! (port `monitor`: a group name; success when that group is in error), `AnyMonitorError`
//! (success when a blocking group — node, topic, navigation, localization — is in error),
//! `ResourcesOutOfBand` (success when the resources group is not ok); actions `Patrol` (runs
//! forever), `SendMessage` (port `text`; once per out-of-band episode), and one action per
//! [`RECOVERIES`] leaf.

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use chronomap_bt::{
    BtDocument, DefinitionError, LeafContext, LeafError, LeafNode, NodeCategory, NodeDef, Registry,
    Status, TickError, Tree, TreeDef,
};
use chronomap_rng::{Xoshiro256StarStar, derive_seed};

use crate::{
    Band, Category, Monitor, MonitorKind, MonitorState, RECOVERIES, Recovery, SUCCESS_WINDOW,
    judge_interventions, tsl,
};

/// The simulated ROS nodes (node monitor, heartbeats).
pub const NODES: [&str; 3] = ["localization", "move_base", "camera"];
/// The simulated topics (topic monitor, rates).
pub const TOPICS: [&str; 1] = ["/scan"];
/// The monitor groups, in the arbiter's priority order, then the non-blocking resources group.
pub const GROUPS: [&str; 5] = ["node", "topic", "navigation", "localization", "resources"];

/// A kind of injected fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// A node stops sending heartbeats (node monitor; restart node).
    NodeCrash,
    /// A topic publishes at 2 Hz instead of 10 Hz (topic monitor; restart publishing node).
    TopicSlow,
    /// CPU at 97 % for a while (resources monitor; send message; clears by itself).
    CpuOverload,
    /// No loop closure (localization monitor).
    LocalizationLost,
    /// No global path and MoveBase recoveries failed (navigation monitor).
    NavigationFailure,
    /// The robot cannot move and no monitor notices (ends with an unrequested supervisor
    /// intervention).
    Stuck,
}

impl FaultKind {
    /// All kinds.
    pub const ALL: [FaultKind; 6] = [
        FaultKind::NodeCrash,
        FaultKind::TopicSlow,
        FaultKind::CpuOverload,
        FaultKind::LocalizationLost,
        FaultKind::NavigationFailure,
        FaultKind::Stuck,
    ];

    /// The name used in fault files (`node_crash`).
    pub fn as_str(self) -> &'static str {
        match self {
            FaultKind::NodeCrash => "node_crash",
            FaultKind::TopicSlow => "topic_slow",
            FaultKind::CpuOverload => "cpu_overload",
            FaultKind::LocalizationLost => "localization_lost",
            FaultKind::NavigationFailure => "navigation_failure",
            FaultKind::Stuck => "stuck",
        }
    }

    /// The monitor group that sees it (`None`: stuck).
    pub fn group(self) -> Option<&'static str> {
        match self {
            FaultKind::NodeCrash => Some("node"),
            FaultKind::TopicSlow => Some("topic"),
            FaultKind::CpuOverload => Some("resources"),
            FaultKind::LocalizationLost => Some("localization"),
            FaultKind::NavigationFailure => Some("navigation"),
            FaultKind::Stuck => None,
        }
    }

    /// Default random rate per hour of operation, after the counts of Table 5.3 over the
    /// 71.2 h of §5.3.2 (about 2.7 navigation, 1.1 localization and 0.45 ROS recoveries an
    /// hour) and its 4 unrequested interventions; topic and CPU faults are assumptions.
    pub fn default_rate_per_hour(self) -> f64 {
        match self {
            FaultKind::NodeCrash => 0.3,
            FaultKind::TopicSlow => 0.05,
            FaultKind::CpuOverload => 0.2,
            FaultKind::LocalizationLost => 0.9,
            FaultKind::NavigationFailure => 2.2,
            FaultKind::Stuck => 0.05,
        }
    }
}

impl FaultKind {
    /// The targets a fault of this kind needs one of: a node of [`NODES`] (node crash), a
    /// topic of [`TOPICS`] (slow topic); empty for the kinds that take no target.
    pub fn targets(self) -> &'static [&'static str] {
        match self {
            FaultKind::NodeCrash => &NODES,
            FaultKind::TopicSlow => &TOPICS,
            _ => &[],
        }
    }
}

impl std::str::FromStr for FaultKind {
    type Err = String;

    fn from_str(s: &str) -> Result<FaultKind, String> {
        FaultKind::ALL
            .into_iter()
            .find(|k| k.as_str() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = FaultKind::ALL.iter().map(|k| k.as_str()).collect();
                format!("unknown fault {s:?} (expected {})", names.join(", "))
            })
    }
}

/// An injected fault.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fault {
    /// When it starts.
    #[serde(with = "secs")]
    pub at: Duration,
    /// What it is.
    pub kind: FaultKind,
    /// The node or topic (node crash, slow topic), else empty.
    pub target: String,
    /// The number of recoveries that fail on it whatever their probability (for hand-written
    /// scenarios).
    pub fails: u32,
    /// How long a CPU overload lasts (default 120 s); ignored otherwise.
    #[serde(with = "secs")]
    pub lasts: Duration,
}

impl Fault {
    /// How long a CPU overload lasts unless a fault says otherwise.
    pub const DEFAULT_LASTS: Duration = Duration::from_secs(120);

    /// A fault of `kind` starting `at`, without a target, with no forced failures and the
    /// default length ([`Fault::DEFAULT_LASTS`]). Set `target` for the kinds that need one
    /// ([`FaultKind::targets`]).
    pub fn new(at: Duration, kind: FaultKind) -> Fault {
        Fault {
            at,
            kind,
            target: String::new(),
            fails: 0,
            lasts: Fault::DEFAULT_LASTS,
        }
    }
}

mod secs {
    use serde::{Deserialize, Deserializer, Serializer};
    use std::time::Duration;

    pub fn serialize<S: Serializer>(d: &Duration, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(d.as_secs_f64())
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Duration, D::Error> {
        let v = f64::deserialize(d)?;
        Duration::try_from_secs_f64(v).map_err(serde::de::Error::custom)
    }
}

/// Random faults: a Poisson process per kind at [`FaultKind::default_rate_per_hour`] over
/// `[0, duration)`, drawn from `seed` (one stream per kind), sorted by time.
pub fn random_faults(seed: u64, duration: Duration) -> Vec<Fault> {
    let mut out = Vec::new();
    for (k, kind) in FaultKind::ALL.into_iter().enumerate() {
        let rate = kind.default_rate_per_hour() / 3600.0;
        let mut rng = Xoshiro256StarStar::seed_from_u64(derive_seed(seed, 0x5303, k as u64, 0));
        let mut t = 0.0f64;
        loop {
            t += -(1.0 - rng.next_f64()).ln() / rate;
            if t >= duration.as_secs_f64() {
                break;
            }
            let target = match kind {
                FaultKind::NodeCrash => NODES[rng.int_in(0, NODES.len() as u64 - 1) as usize],
                FaultKind::TopicSlow => TOPICS[rng.int_in(0, TOPICS.len() as u64 - 1) as usize],
                _ => "",
            };
            out.push(Fault {
                at: Duration::from_secs(t.floor() as u64),
                kind,
                target: target.to_owned(),
                fails: 0,
                lasts: Fault::DEFAULT_LASTS,
            });
        }
    }
    out.sort_by(|a, b| a.at.cmp(&b.at).then(a.kind.cmp(&b.kind)));
    out
}

/// What the simulation runs.
#[derive(Clone, Debug)]
pub struct SimConfig {
    /// Simulated time.
    pub duration: Duration,
    /// Time between arbiter ticks (and signal samples).
    pub tick: Duration,
    /// Seed of the recovery outcomes.
    pub seed: u64,
    /// The faults.
    pub faults: Vec<Fault>,
    /// No motion for this long brings an unrequested supervisor.
    pub stall_limit: Duration,
    /// Replaces every recovery's fix probability (hand-written scenarios use 1).
    pub p_fix: Option<f64>,
}

impl SimConfig {
    /// `duration` with the given faults, 1 s ticks, a 10-minute stall limit, Table 5.3's
    /// probabilities.
    pub fn new(duration: Duration, seed: u64, faults: Vec<Fault>) -> SimConfig {
        SimConfig {
            duration,
            tick: Duration::from_secs(1),
            seed,
            faults,
            stall_limit: Duration::from_secs(600),
            p_fix: None,
        }
    }
}

/// How a recovery ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// The fault was gone afterwards.
    Fixed,
    /// The fault was still there.
    NotFixed,
    /// Halted by the arbiter (a higher-priority monitor) or a supervisor.
    Halted,
    /// Still running when the simulation ended.
    Unfinished,
}

/// One recovery the arbiter started (a row of the intervention table).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Intervention {
    /// Start.
    #[serde(with = "secs")]
    pub start: Duration,
    /// End.
    #[serde(with = "secs")]
    pub end: Duration,
    /// The monitor group.
    pub monitor: String,
    /// The arbiter leaf.
    pub leaf: String,
    /// The reaction (Table 5.3).
    pub reaction: String,
    /// The category (Table 5.3).
    pub category: Category,
    /// The step in Table 5.1's escalation.
    pub step: u8,
    /// How it ended.
    pub outcome: Outcome,
    /// Successful by the one-minute rule of §5.3.2.
    pub success: bool,
}

/// Counts of one reaction (a row of Table 5.3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReactionSummary {
    /// The category.
    pub category: Category,
    /// The reaction.
    pub reaction: String,
    /// How often it ran.
    pub count: usize,
    /// How many succeeded by the one-minute rule.
    pub successes: usize,
}

/// The result of a simulation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimReport {
    /// The injected faults.
    pub faults: Vec<Fault>,
    /// Every recovery, in start order.
    pub interventions: Vec<Intervention>,
    /// Messages sent (time in seconds, text).
    pub messages: Vec<(f64, String)>,
    /// Times (seconds) of supervisor interventions the robot did not request.
    pub unrequested: Vec<f64>,
    /// Table 5.3: per reaction, in catalogue order, those that ran.
    pub reactions: Vec<ReactionSummary>,
    /// Simulated (operating) time t_o, hours.
    pub operating_h: f64,
    /// Time the patrol ran and the robot moved, t_m, hours.
    pub moving_h: f64,
    /// A%(t_o) = t_m / t_o (Table 5.2).
    pub autonomy: f64,
    /// TSL intervals (hours), §5.3.2.
    pub tsl_h: Vec<f64>,
    /// Mean TSL, hours.
    pub tsl_mean_h: f64,
    /// Max TSL, hours.
    pub tsl_max_h: f64,
}

/// A simulation error.
#[derive(Debug, Error)]
pub enum SimError {
    /// The arbiter tree does not fit the simulation's leaves.
    #[error("arbiter: {0}")]
    Definition(#[from] DefinitionError),
    /// A tick failed.
    #[error("arbiter tick at {at:.0} s: {source}")]
    Tick {
        /// Seconds.
        at: f64,
        /// The error.
        source: TickError,
    },
    /// A bad configuration.
    #[error("{0}")]
    Config(String),
}

#[derive(Debug)]
struct ActiveFault {
    kind: FaultKind,
    target: String,
    fails_left: u32,
    until: Option<Duration>,
}

#[derive(Debug)]
struct World {
    active: Vec<ActiveFault>,
    interventions: Vec<Intervention>,
    messages: Vec<(f64, String)>,
    message_sent: bool,
    patrol_ticked: bool,
    rng: Xoshiro256StarStar,
    p_fix: Option<f64>,
}

type Shared = Arc<Mutex<World>>;

fn lock(world: &Shared) -> MutexGuard<'_, World> {
    world.lock().unwrap_or_else(|e| e.into_inner())
}

impl World {
    /// Applies a finished recovery to the faults of its monitor; true if none is left.
    fn resolve(&mut self, recovery: &Recovery) -> bool {
        let p = self.p_fix.unwrap_or(recovery.p_fix);
        let mut i = 0;
        while i < self.active.len() {
            let f = &mut self.active[i];
            if f.kind.group() != Some(recovery.monitor) {
                i += 1;
                continue;
            }
            let fixed = if f.fails_left > 0 {
                f.fails_left -= 1;
                false
            } else {
                self.rng.next_f64() < p
            };
            if fixed {
                self.active.remove(i);
            } else {
                i += 1;
            }
        }
        !self
            .active
            .iter()
            .any(|f| f.kind.group() == Some(recovery.monitor))
    }
}

struct RecoveryLeaf {
    world: Shared,
    spec: &'static Recovery,
    until: Duration,
    index: usize,
}

impl LeafNode for RecoveryLeaf {
    fn tick(&mut self, ctx: &mut LeafContext<'_>) -> Result<Status, LeafError> {
        let now = ctx.now();
        let mut w = lock(&self.world);
        if ctx.status() != Status::Running {
            self.index = w.interventions.len();
            self.until = now + self.spec.duration;
            w.interventions.push(Intervention {
                start: now,
                end: now,
                monitor: self.spec.monitor.to_owned(),
                leaf: self.spec.leaf.to_owned(),
                reaction: self.spec.reaction.to_owned(),
                category: self.spec.category,
                step: self.spec.step,
                outcome: Outcome::Unfinished,
                success: true,
            });
            return Ok(Status::Running);
        }
        if now < self.until {
            return Ok(Status::Running);
        }
        let fixed = w.resolve(self.spec);
        let row = &mut w.interventions[self.index];
        row.end = now;
        row.outcome = if fixed {
            Outcome::Fixed
        } else {
            Outcome::NotFixed
        };
        Ok(if fixed {
            Status::Success
        } else {
            Status::Failure
        })
    }

    fn halt(&mut self, ctx: &mut LeafContext<'_>) {
        let mut w = lock(&self.world);
        if let Some(row) = w.interventions.get_mut(self.index) {
            row.end = ctx.now();
            row.outcome = Outcome::Halted;
        }
    }
}

fn group_state(ctx: &LeafContext<'_>, group: &str) -> Result<MonitorState, LeafError> {
    let key = format!("monitor_{group}");
    let v: String = ctx
        .blackboard()
        .get_as(&key)
        .ok_or_else(|| LeafError::new(format!("no blackboard entry {key:?}")))?;
    match v.as_str() {
        "ok" => Ok(MonitorState::Ok),
        "warning" => Ok(MonitorState::Warning),
        "error" => Ok(MonitorState::Error),
        _ => Err(LeafError::new(format!("{key} = {v:?} is not a state"))),
    }
}

fn status_of(b: bool) -> Status {
    if b { Status::Success } else { Status::Failure }
}

/// The registry of the arbiter's leaves (see the module documentation), acting on `world`.
fn registry(world: &Shared) -> Registry {
    let mut r = Registry::new();
    r.register_condition_fn("MonitorError", |ctx| {
        let group: String = ctx.input("monitor")?;
        if !GROUPS.contains(&group.as_str()) {
            return Err(LeafError::new(format!("unknown monitor group {group:?}")));
        }
        Ok(status_of(group_state(ctx, &group)? == MonitorState::Error))
    })
    .expect("fresh registry");
    r.register_condition_fn("AnyMonitorError", |ctx| {
        let mut any = false;
        for g in &GROUPS[..4] {
            any |= group_state(ctx, g)? == MonitorState::Error;
        }
        Ok(status_of(any))
    })
    .expect("fresh registry");
    r.register_condition_fn("ResourcesOutOfBand", |ctx| {
        Ok(status_of(
            group_state(ctx, "resources")? != MonitorState::Ok,
        ))
    })
    .expect("fresh registry");
    let w = Arc::clone(world);
    r.register_action_fn("Patrol", move |_| {
        lock(&w).patrol_ticked = true;
        Ok(Status::Running)
    })
    .expect("fresh registry");
    let w = Arc::clone(world);
    r.register_action_fn("SendMessage", move |ctx| {
        let text: String = ctx.input("text")?;
        let mut w = lock(&w);
        if !w.message_sent {
            w.message_sent = true;
            w.messages.push((ctx.now().as_secs_f64(), text));
        }
        Ok(Status::Success)
    })
    .expect("fresh registry");
    for spec in &RECOVERIES {
        let w = Arc::clone(world);
        r.register_unchecked(NodeCategory::Action, spec.leaf, move || {
            Box::new(RecoveryLeaf {
                world: Arc::clone(&w),
                spec,
                until: Duration::ZERO,
                index: usize::MAX,
            })
        })
        .expect("fresh registry");
    }
    r
}

/// The arbiter of Fig. 5.5 and Table 5.1 as a behavior tree (the same tree as
/// `tests/data/bt/monitor_arbiter.xml`): a `ReactiveFallback` whose first child, the nominal
/// `ReactiveSequence`, sends a message when resources are out of band and runs the patrol while
/// no blocking monitor is in error; its second child, a `ReactiveFallback`, runs the recoveries
/// by priority (node, topic, navigation, localization monitors), each monitor's reactions as a
/// `Fallback` in Table 5.1's order. A higher-priority error halts a running lower-priority
/// recovery.
pub fn arbiter_document() -> BtDocument {
    let guarded = |group: &str, body: NodeDef| {
        NodeDef::control("Sequence")
            .named(&format!("{group}_monitor"))
            .child(NodeDef::condition("MonitorError").port("monitor", group))
            .child(body)
    };
    let escalation = |leaves: &[&str]| {
        leaves.iter().fold(NodeDef::control("Fallback"), |f, l| {
            f.child(NodeDef::action(l))
        })
    };
    let root = NodeDef::control("ReactiveFallback")
        .named("arbiter")
        .child(
            NodeDef::control("ReactiveSequence")
                .named("nominal")
                .child(
                    NodeDef::decorator("ForceSuccess").child(
                        NodeDef::control("Sequence")
                            .named("resources")
                            .child(NodeDef::condition("ResourcesOutOfBand"))
                            .child(
                                NodeDef::action("SendMessage")
                                    .port("text", "CPU, RAM, NTP or network out of band"),
                            ),
                    ),
                )
                .child(NodeDef::decorator("Inverter").child(NodeDef::condition("AnyMonitorError")))
                .child(NodeDef::action("Patrol")),
        )
        .child(
            NodeDef::control("ReactiveFallback")
                .named("recoveries")
                .child(guarded("node", NodeDef::action("RestartNode")))
                .child(guarded("topic", NodeDef::action("RestartPublisher")))
                .child(guarded(
                    "navigation",
                    escalation(&[
                        "WaitAndRetry",
                        "MoveBackwards",
                        "AskSupervisorTeleoperation",
                    ]),
                ))
                .child(guarded(
                    "localization",
                    escalation(&[
                        "SlowRotate",
                        "RestartLocalization",
                        "AskSupervisorRelocalization",
                    ]),
                )),
        );
    BtDocument::single(TreeDef::new("Arbiter", root))
}

struct Signals {
    heartbeats: Vec<Monitor>,
    rates: Vec<Monitor>,
    cpu: Monitor,
    ram: Monitor,
    navigation: Monitor,
    localization: Monitor,
}

impl Signals {
    fn new() -> Signals {
        let hb = |n: &str| {
            Monitor::heartbeat(n, Duration::from_secs(2), Duration::from_secs(4)).expect("valid")
        };
        let rate = |t: &str| {
            Monitor::new(
                t,
                MonitorKind::Rate {
                    window: Duration::from_secs(2),
                },
                Band::within(5.0, 8.0, 12.0, 15.0),
            )
            .expect("valid")
        };
        let status = |n: &str| Monitor::new(n, MonitorKind::Status, Band::above(1.0, 2.0));
        Signals {
            heartbeats: NODES.iter().map(|n| hb(n)).collect(),
            rates: TOPICS.iter().map(|t| rate(t)).collect(),
            cpu: Monitor::new("cpu", MonitorKind::Level, Band::above(80.0, 95.0)).expect("valid"),
            ram: Monitor::new("ram", MonitorKind::Level, Band::above(85.0, 95.0)).expect("valid"),
            navigation: status("navigation").expect("valid"),
            localization: status("localization").expect("valid"),
        }
    }

    /// Samples of the interval `(prev, now]` given the active faults.
    fn sample(&mut self, prev: Duration, now: Duration, active: &[ActiveFault], noise: f64) {
        let has = |k: FaultKind, target: &str| {
            active
                .iter()
                .any(|f| f.kind == k && (target.is_empty() || f.target == target))
        };
        for m in &mut self.heartbeats {
            if !has(FaultKind::NodeCrash, m.name()) {
                m.push(now, 1.0).expect("finite");
            }
        }
        for m in &mut self.rates {
            let hz = if has(FaultKind::TopicSlow, m.name()) {
                2.0
            } else {
                10.0
            };
            let span = (now - prev).as_secs_f64();
            let n = (hz * span).round() as u32;
            for i in 1..=n {
                let t = prev + (now - prev).mul_f64(f64::from(i) / f64::from(n));
                m.push(t, 1.0).expect("finite");
            }
        }
        let cpu = if has(FaultKind::CpuOverload, "") {
            97.0
        } else {
            30.0 + 20.0 * noise
        };
        self.cpu.push(now, cpu).expect("finite");
        self.ram.push(now, 45.0).expect("finite");
        let code = |b: bool| if b { 2.0 } else { 0.0 };
        self.navigation
            .push(now, code(has(FaultKind::NavigationFailure, "")))
            .expect("finite");
        self.localization
            .push(now, code(has(FaultKind::LocalizationLost, "")))
            .expect("finite");
    }

    fn groups(&self, now: Duration) -> [MonitorState; 5] {
        let worst = |ms: &[Monitor]| {
            ms.iter()
                .map(|m| m.state(now))
                .max()
                .unwrap_or(MonitorState::Ok)
        };
        [
            worst(&self.heartbeats),
            worst(&self.rates),
            self.navigation.state(now),
            self.localization.state(now),
            self.cpu.state(now).max(self.ram.state(now)),
        ]
    }
}

/// Runs the simulation with `arbiter` (for example [`arbiter_document`]).
///
/// # Errors
/// A tree whose leaves or structure do not fit, a failing tick, a tick of zero length or a
/// fix probability outside `[0, 1]`.
pub fn simulate(config: &SimConfig, arbiter: &BtDocument) -> Result<SimReport, SimError> {
    if config.tick.is_zero() {
        return Err(SimError::Config("the tick must be longer than zero".into()));
    }
    if let Some(p) = config.p_fix
        && !(0.0..=1.0).contains(&p)
    {
        return Err(SimError::Config(format!(
            "fix probability {p} is not in [0, 1]"
        )));
    }
    let world: Shared = Arc::new(Mutex::new(World {
        active: Vec::new(),
        interventions: Vec::new(),
        messages: Vec::new(),
        message_sent: false,
        patrol_ticked: false,
        rng: Xoshiro256StarStar::seed_from_u64(derive_seed(config.seed, 0x5303, 100, 0)),
        p_fix: config.p_fix,
    }));
    let registry = registry(&world);
    let mut tree = Tree::new(arbiter, &registry)?;
    let mut noise = Xoshiro256StarStar::seed_from_u64(derive_seed(config.seed, 0x5303, 101, 0));
    let mut faults = config.faults.clone();
    faults.sort_by_key(|f| f.at);
    let mut next_fault = 0;
    let mut signals = Signals::new();
    let mut unrequested = Vec::new();
    let mut moving = Duration::ZERO;
    let mut last_motion = Duration::ZERO;
    let mut prev = Duration::ZERO;
    let mut now = Duration::ZERO;
    while now <= config.duration {
        {
            let mut w = lock(&world);
            w.active.retain(|f| f.until.is_none_or(|u| u > now));
            while next_fault < faults.len() && faults[next_fault].at <= now {
                let f = &faults[next_fault];
                let duplicate = w
                    .active
                    .iter()
                    .any(|a| a.kind == f.kind && a.target == f.target);
                if !duplicate {
                    w.active.push(ActiveFault {
                        kind: f.kind,
                        target: f.target.clone(),
                        fails_left: f.fails,
                        until: (f.kind == FaultKind::CpuOverload).then(|| f.at + f.lasts),
                    });
                }
                next_fault += 1;
            }
            signals.sample(prev, now, &w.active, noise.next_f64());
            let states = signals.groups(now);
            if states[4] == MonitorState::Ok {
                w.message_sent = false;
            }
            w.patrol_ticked = false;
            drop(w);
            for (g, s) in GROUPS.iter().zip(states) {
                tree.blackboard_mut()
                    .set(&format!("monitor_{g}"), s.as_str())
                    .map_err(|e| SimError::Config(e.to_string()))?;
            }
        }
        tree.tick_once(now).map_err(|source| SimError::Tick {
            at: now.as_secs_f64(),
            source,
        })?;
        let stuck;
        let patrolled;
        {
            let w = lock(&world);
            stuck = w.active.iter().any(|f| f.kind == FaultKind::Stuck);
            patrolled = w.patrol_ticked;
        }
        if patrolled && !stuck {
            if now > Duration::ZERO {
                moving += now - prev;
            }
            last_motion = now;
        } else if now - last_motion >= config.stall_limit {
            // A supervisor notices and fixes everything, unrequested (§5.3.2, TSL).
            tree.halt(now);
            lock(&world).active.clear();
            unrequested.push(now);
            last_motion = now;
        }
        prev = now;
        now += config.tick;
    }
    let end = prev;
    let mut w = lock(&world);
    let mut interventions = std::mem::take(&mut w.interventions);
    for row in &mut interventions {
        if row.outcome == Outcome::Unfinished {
            row.end = end;
        }
    }
    let starts: Vec<(Duration, Category)> = interventions
        .iter()
        .map(|r| (r.start, r.category))
        .collect();
    for (row, ok) in interventions
        .iter_mut()
        .zip(judge_interventions(&starts, SUCCESS_WINDOW))
    {
        row.success = ok;
    }
    let reactions = RECOVERIES
        .iter()
        .filter_map(|spec| {
            let rows: Vec<&Intervention> = interventions
                .iter()
                .filter(|r| r.leaf == spec.leaf)
                .collect();
            (!rows.is_empty()).then(|| ReactionSummary {
                category: spec.category,
                reaction: spec.reaction.to_owned(),
                count: rows.len(),
                successes: rows.iter().filter(|r| r.success).count(),
            })
        })
        .collect();
    let tsl_h: Vec<f64> = tsl(Duration::ZERO, end, &unrequested)
        .iter()
        .map(|d| d.as_secs_f64() / 3600.0)
        .collect();
    let operating_h = end.as_secs_f64() / 3600.0;
    let moving_h = moving.as_secs_f64() / 3600.0;
    Ok(SimReport {
        faults,
        interventions,
        messages: std::mem::take(&mut w.messages),
        unrequested: unrequested.iter().map(Duration::as_secs_f64).collect(),
        reactions,
        operating_h,
        moving_h,
        autonomy: if operating_h > 0.0 {
            moving_h / operating_h
        } else {
            0.0
        },
        tsl_mean_h: tsl_h.iter().sum::<f64>() / tsl_h.len() as f64,
        tsl_max_h: tsl_h.iter().copied().fold(0.0, f64::max),
        tsl_h,
    })
}

#[cfg(test)]
mod tests;
