//! The node on the DDS network (ros2-client on RustDDS): subscriptions, publishers, the clock,
//! schedules, the checks of what publishers send, and the node's ROS interfaces — parameter
//! services, `/rosout`, and, managed, the lifecycle services. Messages become calls of
//! [`World`] and its predictions become messages; nothing is computed here.
//!
//! One thread does everything, in rounds of at most [`POLL`]. Each round it answers the
//! parameter and lifecycle services, then, while active, takes `/clock` (with
//! `use_sim_time`), the states, maps and people, and runs what is due in the node's time
//! (simulated or not, as ROS timers run): the route graph every `edges.period`, state
//! predictions every `publish_period`, maps, masks and people every `map_period`; and it saves
//! every `save_period` seconds of wall-clock time.
//!
//! **Parameters** are ROS parameters: every parameter is declared (dotted names,
//! `states.door.model`) and served through the six `rcl_interfaces` services
//! (`~/get_parameters`, `~/set_parameters`, ...), so `ros2 param list/get/set/describe` work;
//! changes are published on `/parameter_events`. The periods, `horizon` and the costmap
//! filters' `filter_type`, `filter_base` and `filter_multiplier` change the running node
//! ([`config::is_dynamic`]); the others are read only while the node is configured, and a
//! refused value comes back with the reason, naming the parameter.
//!
//! **Managed** (REP-2002): the node starts unconfigured and offers `~/change_state`,
//! `~/get_state`, `~/get_available_states`, `~/get_available_transitions`,
//! `~/get_transition_graph`, publishing `~/transition_event` ([`crate::lifecycle`]).
//! Configure checks the parameters, restores the models ([`World::new`]) and creates the
//! subscriptions and publishers; activate starts learning and publishing; deactivate stops
//! both (messages wait in the subscriptions' history, as REP-2002 has inactive nodes leave
//! them); cleanup saves and drops the models, subscriptions and publishers; shutdown saves and
//! finalizes. Unmanaged, the node configures and activates itself at start.
//!
//! States carry no stamp: each is learned at the node's time when RustDDS received it (with
//! `use_sim_time`, the last `/clock` value received before it, taken 0.2 s later). Maps and
//! people are learned at their `header.stamp`. RustDDS matches readers and writers by topic
//! name only, so the node checks the type every publisher of an input topic announces and
//! logs one error per publisher of another type, whose messages it ignores. Messages that
//! cannot be learned are logged with their reason: each reason the first time, then once every
//! 30 s with the count of those refused since ([`Throttle`]).

use std::collections::{BTreeMap, HashMap, HashSet, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::dds::rustdds::{GUID, Topic, TopicDescription};
use ros2_client::parameters::raw;
use ros2_client::qos::{Durability, History, Reliability as QosReliability, WhenFull};
use ros2_client::rcl_interfaces::{
    DescribeParametersRequest, DescribeParametersResponse, GetParameterTypesRequest,
    GetParameterTypesResponse, GetParametersRequest, GetParametersResponse, ListParametersRequest,
    ListParametersResponse, ListParametersResult, SetParametersAtomicallyResponse,
    SetParametersRequest, SetParametersResponse,
};
use ros2_client::{
    Context, ContextOptions, MessageInfo, MessageTypeName, Name, Node, NodeName, NodeOptions,
    Publisher, QosProfile, Server, ServiceMapping, ServiceTypeName, Subscription,
};
use thiserror::Error;

use crate::config::{
    self, ConfigError, GridSource, InputQos, NodeConfig, Reliability, Setup, StateType,
};
use crate::lifecycle::{self, Machine, Outcome, State};
use crate::msgs::{
    Bool, ChangeStateRequest, ChangeStateResponse, Clock, CostmapFilterInfo, EmptyRequest, Float32,
    Float64, GetAvailableStatesResponse, GetAvailableTransitionsResponse, GetStateResponse,
    LifecycleState, LifecycleTransition, Message, OccupancyGrid, PoseArray, Time,
    TransitionDescription, TransitionEvent, TypeName, ros_type_of_dds,
};
use crate::params::{self, Origin, Value};
use crate::rosout;
use crate::world::{Learned, StoreError, World};

/// Longest wait for messages and requests before the node looks at its clock and schedules
/// again.
const POLL: Duration = Duration::from_millis(20);
/// How often the publishers on the input topics are checked.
const CHECK_WRITERS: Duration = Duration::from_secs(1);
/// Messages taken from one subscription per round at most (the others get their turn).
const MAX_TAKE: usize = 10_000;
/// Requests answered per service per round at most.
const MAX_REQUESTS: usize = 100;

/// How the node runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RunOptions {
    /// DDS domain (`ROS_DOMAIN_ID`).
    pub domain_id: u16,
    /// A managed (lifecycle) node: starts unconfigured, driven through `~/change_state`.
    pub managed: bool,
    /// Publish the log on `/rosout`.
    pub rosout: bool,
}

impl Default for RunOptions {
    /// Domain 0, unmanaged, logging to `/rosout`.
    fn default() -> Self {
        RunOptions {
            domain_id: 0,
            managed: false,
            rosout: true,
        }
    }
}

/// Why the node could not run.
#[derive(Debug, Error)]
pub enum NodeError {
    /// DDS could not create the participant, a topic, a reader or a writer.
    #[error("DDS: {0}")]
    Dds(String),
    /// A name ros2-client refuses.
    #[error("{0}")]
    Name(String),
    /// Polling failed.
    #[error("polling the subscriptions: {0}")]
    Poll(#[from] std::io::Error),
    /// The parameters cannot be used.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The saved models cannot be restored.
    #[error("cannot restore the models: {0}")]
    Restore(#[from] StoreError),
}

/// What a run learned, per input, in configuration order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Summary {
    /// States: name and counts.
    pub states: Vec<(String, Learned)>,
    /// Grids: section (`maps`/`people`), name and counts.
    pub grids: Vec<(String, String, Learned)>,
    /// Messages refused per input topic.
    pub refused: BTreeMap<String, u64>,
    /// Why saving at shutdown failed, if it did.
    pub save_error: Option<String>,
    /// Whether the node held models (was configured) when it stopped or last cleaned up; a
    /// managed node never configured learned nothing and saved nothing.
    pub configured: bool,
}

/// How long the node waits, with `use_sim_time`, before it takes a received message as
/// ordered with the `/clock` messages received before it: RustDDS stamps a sample when it
/// arrives and stores it a moment later, so a clock sample stamped earlier than a state may
/// still be on its way into its reader when the state is taken.
const SIM_LATENCY_NS: i64 = 200_000_000;

/// Simulated time as received on `/clock`: values by RustDDS receive time.
///
/// A state has no stamp: it is observed at the node's time when it was received. With the
/// system clock that is the time RustDDS received it. With `use_sim_time` it is the last
/// `/clock` value received before it, so a state published right after a clock message is
/// stamped with that clock even when both are taken in the same round. The node acts on what
/// was received up to [`SIM_LATENCY_NS`] ago (the cutoff): states received before it are
/// learned, and its time for publishing is the clock at the cutoff.
#[derive(Default)]
struct SimClock {
    /// The value before the first entry of `history`.
    base: Option<f64>,
    /// Receive time (ns) and value, in receive order.
    history: VecDeque<(i64, f64)>,
}

impl SimClock {
    /// The clock when something was received at `received` (ns).
    fn at(&self, received: i64) -> Option<f64> {
        self.history
            .iter()
            .rev()
            .find(|&&(at, _)| at <= received)
            .map(|&(_, t)| t)
            .or(self.base)
    }

    fn push(&mut self, received: i64, value: f64) {
        let at = self.history.partition_point(|&(r, _)| r <= received);
        self.history.insert(at, (received, value));
    }

    /// Forgets what no message received at or after `received` needs.
    fn forget_before(&mut self, received: i64) {
        while self.history.len() > 1 && self.history[1].0 <= received {
            self.base = self.history.pop_front().map(|(_, t)| t);
        }
    }
}

/// A state received with `use_sim_time`, waiting for the cutoff.
struct Pending {
    index: usize,
    received: i64,
    value: f64,
}

/// When RustDDS received a sample (ns since the unix epoch), or now if it does not say.
fn received_ns(info: &MessageInfo) -> i64 {
    info.received_timestamp()
        .map_or_else(system_now_ns, |r| r.to_nanos())
}

/// Learns a state, logging what is refused.
fn learn_state(
    world: &mut World,
    throttles: &mut BTreeMap<String, Throttle>,
    topic: &str,
    index: usize,
    time: f64,
    value: f64,
) {
    match world.observe_state(index, time, value) {
        Ok(()) => log::trace!("{topic}: learned {value} at {time}"),
        Err(e) => throttle(throttles, topic).error(topic, || e.to_string()),
    }
}

/// Now as RustDDS stamps receive times (ns since the unix epoch).
fn system_now_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}

/// How often a reason already logged for a topic is logged again, with the count since.
const REASON_EVERY: Duration = Duration::from_secs(30);
/// Reasons remembered per topic; further new reasons share one entry (bounded memory).
const MAX_REASONS: usize = 32;

/// The reasons messages of one input were refused: each distinct reason (its text with the
/// numbers left out) is logged when first seen, then at most once every [`REASON_EVERY`] with
/// the count refused for it since, so no reason vanishes from the log and none floods it.
#[derive(Default)]
struct Throttle {
    /// Messages refused.
    total: u64,
    reasons: BTreeMap<String, Reason>,
}

struct Reason {
    logged: Instant,
    since: u64,
    last: String,
}

/// `message` without its numbers (`value 1.5 is not in [0, 1]` → `value # is not in [#, #]`):
/// what makes two refusals the same reason.
fn reason_key(message: &str) -> String {
    let mut key = String::with_capacity(message.len());
    let mut in_number = false;
    let mut chars = message.chars().peekable();
    while let Some(c) = chars.next() {
        let sign = c == '-' && !in_number && chars.peek().is_some_and(char::is_ascii_digit);
        if sign || c.is_ascii_digit() || (in_number && c == '.') {
            if !in_number {
                key.push('#');
                in_number = true;
            }
        } else {
            in_number = false;
            key.push(c);
        }
    }
    key
}

impl Throttle {
    /// A refusal at `now`: the line to log, if any.
    fn note(&mut self, message: String, now: Instant) -> Option<String> {
        self.total += 1;
        let mut key = reason_key(&message);
        if !self.reasons.contains_key(&key) && self.reasons.len() >= MAX_REASONS {
            key = String::from("(other reasons)");
        }
        match self.reasons.get_mut(&key) {
            None => {
                self.reasons.insert(
                    key,
                    Reason {
                        logged: now,
                        since: 0,
                        last: message.clone(),
                    },
                );
                Some(message)
            }
            Some(r) => {
                r.since += 1;
                r.last = message;
                (now.duration_since(r.logged) >= REASON_EVERY).then(|| r.summary(now))
            }
        }
    }

    /// Lines for reasons with refusals not logged for [`REASON_EVERY`] (or for all of them,
    /// with `all`, when the node stops).
    fn due(&mut self, now: Instant, all: bool) -> Vec<String> {
        self.reasons
            .values_mut()
            .filter(|r| r.since > 0 && (all || now.duration_since(r.logged) >= REASON_EVERY))
            .map(|r| r.summary(now))
            .collect()
    }

    /// Logs a refusal of a message of `topic`.
    fn error(&mut self, topic: &str, message: impl FnOnce() -> String) {
        if let Some(line) = self.note(message(), Instant::now()) {
            log::error!("{topic}: {line}");
        }
    }
}

impl Reason {
    fn summary(&mut self, now: Instant) -> String {
        let line = format!(
            "{} more refused for the same reason in the last {:.0} s (the last: {})",
            self.since,
            now.duration_since(self.logged).as_secs_f64(),
            self.last
        );
        self.since = 0;
        self.logged = now;
        line
    }
}

/// Logs the summaries that are due.
fn log_due(throttles: &mut BTreeMap<String, Throttle>, all: bool) {
    let now = Instant::now();
    for (topic, t) in throttles.iter_mut() {
        for line in t.due(now, all) {
            log::error!("{topic}: {line}");
        }
    }
}

/// The throttle of `topic`'s error messages.
fn throttle<'t>(throttles: &'t mut BTreeMap<String, Throttle>, topic: &str) -> &'t mut Throttle {
    throttles.entry(topic.to_string()).or_default()
}

/// A subscription of a state topic.
enum StateReader {
    Bool(Subscription<Bool>),
    Float32(Subscription<Float32>),
    Float64(Subscription<Float64>),
}

impl StateReader {
    /// The next message as a value in [0, 1] (Bool: 0 or 1).
    fn take(&self) -> Result<Option<(f64, MessageInfo)>, String> {
        let taken = match self {
            StateReader::Bool(s) => s
                .take()
                .map(|m| m.map(|(b, i)| (if b.data { 1.0 } else { 0.0 }, i))),
            StateReader::Float32(s) => s.take().map(|m| m.map(|(f, i)| (f64::from(f.data), i))),
            StateReader::Float64(s) => s.take().map(|m| m.map(|(f, i)| (f.data, i))),
        };
        taken.map_err(|e| e.to_string())
    }

    fn register(&mut self, poll: &Poll, token: Token) -> std::io::Result<()> {
        let registry = poll.registry();
        match self {
            StateReader::Bool(s) => registry.register(s, token, Interest::READABLE),
            StateReader::Float32(s) => registry.register(s, token, Interest::READABLE),
            StateReader::Float64(s) => registry.register(s, token, Interest::READABLE),
        }
    }

    fn deregister(&mut self, poll: &Poll) -> std::io::Result<()> {
        let registry = poll.registry();
        match self {
            StateReader::Bool(s) => registry.deregister(s),
            StateReader::Float32(s) => registry.deregister(s),
            StateReader::Float64(s) => registry.deregister(s),
        }
    }
}

enum GridReader {
    Map(Subscription<OccupancyGrid>),
    People(Subscription<PoseArray>),
}

struct StateIo {
    topic: String,
    reader: StateReader,
    probability: Publisher<Float64>,
    entropy: Publisher<Float64>,
}

struct GridIo {
    topic: String,
    reader: GridReader,
    map: Publisher<OccupancyGrid>,
    mask: Option<Publisher<OccupancyGrid>>,
    info: Option<Publisher<CostmapFilterInfo>>,
}

/// An input topic as DDS names it, for checking the types of its publishers.
struct Input {
    topic: String,
    expected: TypeName,
    parameter: String,
}

/// Which publishers on the input topics send another type than configured.
struct WriterCheck {
    inputs: HashMap<String, Input>,
    reported: HashSet<GUID>,
    wrong: HashSet<GUID>,
    right: HashSet<GUID>,
    last: Option<Instant>,
}

impl WriterCheck {
    /// Logs every newly discovered publisher of a wrong type on an input topic.
    fn scan(&mut self, context: &Context) {
        if self.last.is_some_and(|t| t.elapsed() < CHECK_WRITERS) {
            return;
        }
        self.last = Some(Instant::now());
        for writer in context.domain_participant().discovered_writers() {
            let data = &writer.publication_topic_data;
            self.judge(data.key, &data.topic_name, &data.type_name);
        }
    }

    /// Whether the publisher `guid` of `topic` sends the configured type; logs it once if not.
    fn judge(&mut self, guid: GUID, topic: &str, type_name: &str) -> bool {
        let Some(input) = self.inputs.get(topic) else {
            return true;
        };
        if type_name == input.expected.dds() {
            self.right.insert(guid);
            return true;
        }
        self.wrong.insert(guid);
        if self.reported.insert(guid) {
            log::error!(
                "{}: a publisher sends {}, but this node expects {} ({}); its messages are \
                 ignored, the other topics are served",
                input.topic,
                ros_type_of_dds(type_name),
                input.expected,
                input.parameter
            );
        }
        false
    }

    /// Whether a sample from the publisher `info` names may be learned: not from a publisher
    /// of a wrong type (RustDDS matches readers and writers by topic name only).
    fn accepts(&mut self, context: &Context, info: &MessageInfo) -> bool {
        let guid = GUID::from(info.publisher_gid());
        if self.right.contains(&guid) {
            return true;
        }
        if self.wrong.contains(&guid) {
            return false;
        }
        let found = context
            .domain_participant()
            .discovered_writers()
            .into_iter()
            .find(|w| w.publication_topic_data.key == guid);
        match found {
            Some(w) => {
                let data = &w.publication_topic_data;
                self.judge(guid, &data.topic_name.clone(), &data.type_name.clone())
            }
            // Not discovered (yet): the reader matched it on its topic name.
            None => true,
        }
    }
}

/// When something is due next, in the node's time.
#[derive(Default)]
struct Schedule {
    next: Option<f64>,
}

impl Schedule {
    /// Whether it is due at `now`; if so, the next time is `now + period`. A clock that went
    /// back (a restarted simulation) makes it due at once.
    fn due(&mut self, now: f64, period: f64) -> bool {
        match self.next {
            Some(next) if now < next && next - now <= period => false,
            _ => {
                self.next = Some(now + period);
                true
            }
        }
    }
}

fn qos_of(input: &InputQos) -> QosProfile {
    let profile = QosProfile::subscription_default()
        .history(History::KeepLast { depth: input.depth })
        .durability(if input.transient_local {
            Durability::TransientLocal
        } else {
            Durability::Volatile
        });
    match input.reliability {
        Reliability::Reliable => profile.reliability_reliable(WhenFull::DEFAULT),
        Reliability::BestEffort => profile.reliability(QosReliability::BestEffort),
    }
}

/// What the node publishes: reliable and transient local with depth 1, as Nav2's map_server
/// and costmap_filter_info_server publish, so that late subscribers get the latest.
fn latched() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
}

struct Builder<'a> {
    node: &'a mut Node,
}

impl Builder<'_> {
    fn topic(&self, name: &str, ty: TypeName, qos: &QosProfile) -> Result<Topic, NodeError> {
        let parsed = Name::parse(name).map_err(|e| NodeError::Name(format!("{name}: {e}")))?;
        self.node
            .create_topic(&parsed, MessageTypeName::new(ty.package, ty.name), qos)
            .map_err(|e| NodeError::Dds(format!("topic {name}: {e}")))
    }

    fn reader<M: Message>(
        &mut self,
        name: &str,
        qos: QosProfile,
    ) -> Result<(Subscription<M>, String), NodeError> {
        let topic = self.topic(name, M::TYPE, &qos)?;
        let dds_name = topic.name();
        let reader = self
            .node
            .create_subscription(&topic, Some(qos))
            .map_err(|e| NodeError::Dds(format!("subscription of {name}: {e}")))?;
        Ok((reader, dds_name))
    }

    fn writer<M: Message>(&mut self, name: &str) -> Result<Publisher<M>, NodeError> {
        let qos = latched();
        let topic = self.topic(name, M::TYPE, &qos)?;
        self.node
            .create_publisher(&topic, Some(qos))
            .map_err(|e| NodeError::Dds(format!("publisher of {name}: {e}")))
    }
}

/// The QoS of services (rmw's `rmw_qos_profile_services_default`): reliable, volatile, keep
/// last 10.
fn service_qos() -> QosProfile {
    QosProfile::subscription_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
}

impl Builder<'_> {
    /// The server of the service `~/LEAF` (remapped) of type `package/srv/TYPE`.
    fn server<Q, A>(
        &mut self,
        setup: &Setup,
        leaf: &str,
        package: &str,
        ty: &str,
    ) -> Result<Server<Q, A>, NodeError>
    where
        Q: ros2_client::Message + Clone + 'static,
        A: ros2_client::Message + 'static,
    {
        let full = format!("{}/{leaf}", setup.fully_qualified_name());
        let name = setup
            .args
            .remap(&full, true, &setup.namespace, &setup.name)
            .map_err(|e| NodeError::Name(e.to_string()))?;
        let parsed = Name::parse(&name).map_err(|e| NodeError::Name(format!("{name}: {e}")))?;
        self.node
            .create_server(
                ServiceMapping::Enhanced,
                &parsed,
                &ServiceTypeName::new(package, ty),
                service_qos(),
                service_qos(),
            )
            .map_err(|e| NodeError::Dds(format!("service {name}: {e}")))
    }
}

/// The six `rcl_interfaces` parameter services.
struct ParamServers {
    get: Server<GetParametersRequest, GetParametersResponse>,
    types: Server<GetParameterTypesRequest, GetParameterTypesResponse>,
    set: Server<SetParametersRequest, SetParametersResponse>,
    set_atomically: Server<SetParametersRequest, SetParametersAtomicallyResponse>,
    list: Server<ListParametersRequest, ListParametersResponse>,
    describe: Server<DescribeParametersRequest, DescribeParametersResponse>,
}

impl ParamServers {
    fn new(b: &mut Builder<'_>, setup: &Setup, poll: &Poll) -> Result<Self, NodeError> {
        let pkg = "rcl_interfaces";
        let mut servers = ParamServers {
            get: b.server(setup, "get_parameters", pkg, "GetParameters")?,
            types: b.server(setup, "get_parameter_types", pkg, "GetParameterTypes")?,
            set: b.server(setup, "set_parameters", pkg, "SetParameters")?,
            set_atomically: b.server(
                setup,
                "set_parameters_atomically",
                pkg,
                "SetParametersAtomically",
            )?,
            list: b.server(setup, "list_parameters", pkg, "ListParameters")?,
            describe: b.server(setup, "describe_parameters", pkg, "DescribeParameters")?,
        };
        let r = poll.registry();
        let t = Token(usize::MAX - 1);
        r.register(&mut servers.get, t, Interest::READABLE)?;
        r.register(&mut servers.types, t, Interest::READABLE)?;
        r.register(&mut servers.set, t, Interest::READABLE)?;
        r.register(&mut servers.set_atomically, t, Interest::READABLE)?;
        r.register(&mut servers.list, t, Interest::READABLE)?;
        r.register(&mut servers.describe, t, Interest::READABLE)?;
        Ok(servers)
    }
}

/// The five `lifecycle_msgs` services and `~/transition_event`.
struct LifecycleServers {
    change: Server<ChangeStateRequest, ChangeStateResponse>,
    get: Server<EmptyRequest, GetStateResponse>,
    states: Server<EmptyRequest, GetAvailableStatesResponse>,
    transitions: Server<EmptyRequest, GetAvailableTransitionsResponse>,
    graph: Server<EmptyRequest, GetAvailableTransitionsResponse>,
    events: Publisher<TransitionEvent>,
}

impl LifecycleServers {
    fn new(b: &mut Builder<'_>, setup: &Setup, poll: &Poll) -> Result<Self, NodeError> {
        let pkg = "lifecycle_msgs";
        let events_topic = setup
            .args
            .remap(
                &format!("{}/transition_event", setup.fully_qualified_name()),
                false,
                &setup.namespace,
                &setup.name,
            )
            .map_err(|e| NodeError::Name(e.to_string()))?;
        // rcl_lifecycle publishes with the default QoS: reliable, volatile, keep last 10.
        let qos = QosProfile::publisher_default()
            .reliability_reliable(WhenFull::DEFAULT)
            .durability(Durability::Volatile)
            .history(History::KeepLast { depth: 10 });
        let topic = b.topic(&events_topic, TransitionEvent::TYPE, &qos)?;
        let events = b
            .node
            .create_publisher(&topic, Some(qos))
            .map_err(|e| NodeError::Dds(format!("publisher of {events_topic}: {e}")))?;
        let mut servers = LifecycleServers {
            change: b.server(setup, "change_state", pkg, "ChangeState")?,
            get: b.server(setup, "get_state", pkg, "GetState")?,
            states: b.server(setup, "get_available_states", pkg, "GetAvailableStates")?,
            transitions: b.server(
                setup,
                "get_available_transitions",
                pkg,
                "GetAvailableTransitions",
            )?,
            graph: b.server(
                setup,
                "get_transition_graph",
                pkg,
                "GetAvailableTransitions",
            )?,
            events,
        };
        let r = poll.registry();
        let t = Token(usize::MAX - 2);
        r.register(&mut servers.change, t, Interest::READABLE)?;
        r.register(&mut servers.get, t, Interest::READABLE)?;
        r.register(&mut servers.states, t, Interest::READABLE)?;
        r.register(&mut servers.transitions, t, Interest::READABLE)?;
        r.register(&mut servers.graph, t, Interest::READABLE)?;
        Ok(servers)
    }
}

fn state_msg(state: State) -> LifecycleState {
    LifecycleState {
        id: state.id(),
        label: state.label().to_string(),
    }
}

fn description(t: &lifecycle::Transition) -> TransitionDescription {
    TransitionDescription {
        transition: LifecycleTransition {
            id: t.id,
            label: t.label.to_string(),
        },
        start_state: state_msg(t.start),
        goal_state: state_msg(t.goal),
    }
}

/// Answers every waiting request of `server` with `answer`.
fn serve<Q, A>(server: &Server<Q, A>, what: &str, mut answer: impl FnMut(Q) -> A)
where
    Q: ros2_client::Message + Clone + 'static,
    A: ros2_client::Message + 'static,
{
    for _ in 0..MAX_REQUESTS {
        match server.receive_request() {
            Ok(Some((id, request))) => {
                let response = answer(request);
                if let Err(e) = server.send_response(id, response) {
                    log::warn!("{what}: cannot send the response: {e}");
                }
            }
            Ok(None) => break,
            Err(e) => {
                log::warn!("{what}: a request that cannot be read: {e}");
                break;
            }
        }
    }
}

/// The subscriptions and publishers of a configured node.
struct Io {
    clock: Option<Subscription<Clock>>,
    states: Vec<StateIo>,
    grids: Vec<GridIo>,
}

impl Io {
    /// Creates the subscriptions and publishers of `config`, registered with `poll`; also
    /// the input topics as DDS names them, for the type check of publishers.
    fn open(
        node: &mut Node,
        config: &NodeConfig,
        poll: &Poll,
    ) -> Result<(Io, HashMap<String, Input>), NodeError> {
        let mut inputs = HashMap::new();
        let mut b = Builder { node };
        let clock = if config.use_sim_time {
            let qos = QosProfile::subscription_default()
                .reliability(QosReliability::BestEffort)
                .history(History::KeepLast { depth: 1000 });
            let (reader, dds) = b.reader::<Clock>(&config.clock_topic, qos)?;
            inputs.insert(
                dds,
                Input {
                    topic: config.clock_topic.clone(),
                    expected: Clock::TYPE,
                    parameter: "use_sim_time".into(),
                },
            );
            Some(reader)
        } else {
            None
        };
        let mut states = Vec::new();
        for s in &config.states {
            let qos = qos_of(&s.qos);
            let (reader, dds) = match s.message {
                StateType::Bool => {
                    let (r, d) = b.reader::<Bool>(&s.topic, qos)?;
                    (StateReader::Bool(r), d)
                }
                StateType::Float32 => {
                    let (r, d) = b.reader::<Float32>(&s.topic, qos)?;
                    (StateReader::Float32(r), d)
                }
                StateType::Float64 => {
                    let (r, d) = b.reader::<Float64>(&s.topic, qos)?;
                    (StateReader::Float64(r), d)
                }
            };
            inputs.insert(
                dds,
                Input {
                    topic: s.topic.clone(),
                    expected: s.message.type_name(),
                    parameter: format!("states.{}.type", s.name),
                },
            );
            states.push(StateIo {
                topic: s.topic.clone(),
                reader,
                probability: b.writer(&s.probability_topic)?,
                entropy: b.writer(&s.entropy_topic)?,
            });
        }
        let mut grids = Vec::new();
        for g in &config.grids {
            let qos = qos_of(&g.qos);
            let (reader, dds, expected) = match g.source {
                GridSource::Map => {
                    let (r, d) = b.reader::<OccupancyGrid>(&g.topic, qos)?;
                    (GridReader::Map(r), d, OccupancyGrid::TYPE)
                }
                GridSource::People { .. } => {
                    let (r, d) = b.reader::<PoseArray>(&g.topic, qos)?;
                    (GridReader::People(r), d, PoseArray::TYPE)
                }
            };
            inputs.insert(
                dds,
                Input {
                    topic: g.topic.clone(),
                    expected,
                    parameter: format!("{}.{}.topic", g.section(), g.name),
                },
            );
            let (mask, info) = match &g.filter {
                Some(f) => (
                    Some(b.writer::<OccupancyGrid>(&f.mask_topic)?),
                    Some(b.writer::<CostmapFilterInfo>(&f.info_topic)?),
                ),
                None => (None, None),
            };
            grids.push(GridIo {
                topic: g.topic.clone(),
                reader,
                map: b.writer(&g.predicted_topic)?,
                mask,
                info,
            });
        }
        let mut io = Io {
            clock,
            states,
            grids,
        };
        let token = Token(1);
        if let Some(reader) = &mut io.clock {
            poll.registry()
                .register(reader, token, Interest::READABLE)?;
        }
        for s in &mut io.states {
            s.reader.register(poll, token)?;
        }
        for g in &mut io.grids {
            match &mut g.reader {
                GridReader::Map(r) => poll.registry().register(r, token, Interest::READABLE)?,
                GridReader::People(r) => poll.registry().register(r, token, Interest::READABLE)?,
            }
        }
        Ok((io, inputs))
    }

    /// Deregisters the subscriptions (the node drops them next).
    fn close(&mut self, poll: &Poll) {
        let r = poll.registry();
        let mut results = Vec::new();
        if let Some(reader) = &mut self.clock {
            results.push(r.deregister(reader));
        }
        for s in &mut self.states {
            results.push(s.reader.deregister(poll));
        }
        for g in &mut self.grids {
            results.push(match &mut g.reader {
                GridReader::Map(x) => r.deregister(x),
                GridReader::People(x) => r.deregister(x),
            });
        }
        for e in results.into_iter().filter_map(Result::err) {
            log::debug!("deregistering a subscription: {e}");
        }
    }
}

/// What a configured node holds: its checked parameters (the dynamic ones as last set), the
/// models, the subscriptions and publishers, and the state of its schedules.
struct Configured {
    config: NodeConfig,
    world: World,
    io: Io,
    sim_clock: Option<SimClock>,
    pending: VecDeque<Pending>,
    check: WriterCheck,
    throttles: BTreeMap<String, Throttle>,
    schedules: [Schedule; 3],
    infos_published: bool,
    last_save: Instant,
    waiting_for_clock_logged: bool,
}

impl Configured {
    /// Configures: restores the models ([`World::new`]) and opens the subscriptions and
    /// publishers.
    fn open(node: &mut Node, config: NodeConfig, poll: &Poll) -> Result<Configured, NodeError> {
        let world = World::new(config.clone())?;
        let (io, inputs) = Io::open(node, &config, poll)?;
        Ok(Configured {
            sim_clock: config.use_sim_time.then(SimClock::default),
            config,
            world,
            io,
            pending: VecDeque::new(),
            check: WriterCheck {
                inputs,
                reported: HashSet::new(),
                wrong: HashSet::new(),
                right: HashSet::new(),
                last: None,
            },
            throttles: BTreeMap::new(),
            schedules: Default::default(),
            infos_published: false,
            last_save: Instant::now(),
            waiting_for_clock_logged: false,
        })
    }

    /// Takes the dynamic parameters of `new` (periods, horizon, filters); what changed is
    /// published at once.
    fn update(&mut self, new: &NodeConfig) {
        let old = &self.config;
        if new.publish_period != old.publish_period || new.horizon != old.horizon {
            self.schedules[0] = Schedule::default();
        }
        if new.map_period != old.map_period || new.horizon != old.horizon {
            self.schedules[1] = Schedule::default();
        }
        if new.edges.as_ref().map(|e| e.period) != old.edges.as_ref().map(|e| e.period)
            || new.horizon != old.horizon
        {
            self.schedules[2] = Schedule::default();
        }
        let filters = |c: &NodeConfig| c.grids.iter().map(|g| g.filter.clone()).collect::<Vec<_>>();
        if filters(new) != filters(old) {
            self.infos_published = false;
        }
        self.config = new.clone();
    }

    /// One round of an active node: take what arrived, learn it, publish what is due.
    fn step(&mut self, context: &Context) {
        let Configured {
            config,
            world,
            io,
            sim_clock,
            pending,
            check,
            throttles,
            schedules,
            infos_published,
            last_save,
            waiting_for_clock_logged,
        } = self;
        let states = &io.states;
        let grids = &io.grids;
        check.scan(context);
        // With simulated time, what was received before the cutoff is complete.
        let cutoff = system_now_ns() - SIM_LATENCY_NS;
        if let (Some(reader), Some(clock)) = (&io.clock, sim_clock.as_mut()) {
            for _ in 0..MAX_TAKE {
                match reader.take() {
                    Ok(Some((msg, info))) => {
                        if check.accepts(context, &info) {
                            let received = received_ns(&info);
                            log::trace!(
                                "{}: {} received at {received} ns",
                                config.clock_topic,
                                msg.clock.seconds()
                            );
                            clock.push(received, msg.clock.seconds());
                        }
                    }
                    Ok(None) => break,
                    Err(e) => throttle(throttles, &config.clock_topic)
                        .error(&config.clock_topic, || e.to_string()),
                }
            }
        }
        for (index, s) in states.iter().enumerate() {
            for _ in 0..MAX_TAKE {
                match s.reader.take() {
                    Ok(Some((value, info))) => {
                        if !check.accepts(context, &info) {
                            continue;
                        }
                        let received = received_ns(&info);
                        if sim_clock.is_some() {
                            pending.push_back(Pending {
                                index,
                                received,
                                value,
                            });
                        } else {
                            let time = received as f64 / 1e9;
                            learn_state(world, throttles, &s.topic, index, time, value);
                        }
                    }
                    Ok(None) => break,
                    Err(e) => throttle(throttles, &s.topic).error(&s.topic, || e),
                }
            }
        }
        if let Some(clock) = sim_clock.as_mut() {
            let mut waiting = VecDeque::with_capacity(pending.len());
            for p in pending.drain(..) {
                if p.received > cutoff {
                    waiting.push_back(p);
                    continue;
                }
                let topic = &states[p.index].topic;
                match clock.at(p.received) {
                    Some(time) => {
                        learn_state(world, throttles, topic, p.index, time, p.value);
                    }
                    None => throttle(throttles, topic).error(topic, || {
                        "a state before the first /clock message (use_sim_time): not learned".into()
                    }),
                }
            }
            *pending = waiting;
            // Pending states of several topics are not in receive order among each other.
            let oldest = pending
                .iter()
                .map(|p| p.received)
                .min()
                .map_or(cutoff, |r| r.min(cutoff));
            clock.forget_before(oldest);
        }
        for (index, g) in grids.iter().enumerate() {
            for _ in 0..MAX_TAKE {
                let (result, info) = match &g.reader {
                    GridReader::Map(r) => match r.take() {
                        Ok(Some((msg, info))) => {
                            if !check.accepts(context, &info) {
                                continue;
                            }
                            (world.observe_map(index, &msg), info)
                        }
                        Ok(None) => break,
                        Err(e) => {
                            throttle(throttles, &g.topic).error(&g.topic, || e.to_string());
                            continue;
                        }
                    },
                    GridReader::People(r) => match r.take() {
                        Ok(Some((msg, info))) => {
                            if !check.accepts(context, &info) {
                                continue;
                            }
                            (world.observe_people(index, &msg), info)
                        }
                        Ok(None) => break,
                        Err(e) => {
                            throttle(throttles, &g.topic).error(&g.topic, || e.to_string());
                            continue;
                        }
                    },
                };
                match result {
                    Ok(()) => {
                        log::trace!("{}: learned message {}", g.topic, info.sequence_number())
                    }
                    Err(e) => throttle(throttles, &g.topic).error(&g.topic, || e.to_string()),
                }
            }
        }
        log_due(throttles, false);
        // What was learned is durable once the journal is synced (at most `sync_period`).
        world.sync_journal(Instant::now());

        let now = match sim_clock.as_ref() {
            Some(clock) => clock.at(cutoff),
            None => Some(system_now_ns() as f64 / 1e9),
        };
        let Some(now) = now else {
            if !*waiting_for_clock_logged {
                log::info!(
                    "waiting for the first {} message (use_sim_time)",
                    config.clock_topic
                );
                *waiting_for_clock_logged = true;
            }
            return;
        };
        let target = now + config.horizon;
        let stamp = Time::from_seconds(now);
        if !*infos_published {
            for (index, g) in grids.iter().enumerate() {
                let info = world.filter_info(index, stamp).map(|mut info| {
                    // The filter's values as last set (they change at run time).
                    if let Some(f) = &config.grids[index].filter {
                        info.filter_type = f.filter_type;
                        info.base = f.base;
                        info.multiplier = f.multiplier;
                    }
                    info
                });
                if let (Some(publisher), Some(info)) = (&g.info, info)
                    && let Err(e) = publisher.publish(info)
                {
                    log::error!("{}: cannot publish the filter info: {e}", g.topic);
                }
            }
            *infos_published = true;
        }
        if let Some(edges) = &config.edges
            && schedules[2].due(now, edges.period)
        {
            match world.write_route_graph(target) {
                Ok(_) => log::debug!("wrote {} for {target}", edges.geojson.display()),
                Err(e) => log::error!("route graph: {e}"),
            }
        }
        if schedules[0].due(now, config.publish_period) {
            for (index, s) in states.iter().enumerate() {
                let (p, h) = world.predict_state(index, target);
                for (publisher, data) in [(&s.probability, p), (&s.entropy, h)] {
                    if let Err(e) = publisher.publish(Float64 { data }) {
                        log::error!("{}: cannot publish a prediction: {e}", s.topic);
                    }
                }
            }
        }
        if schedules[1].due(now, config.map_period) {
            if let Err(e) = world.close_stale_bins(now) {
                log::error!("people: {e}");
            }
            for (index, g) in grids.iter().enumerate() {
                let Some(prediction) = world.predict_grid(index, target, stamp) else {
                    continue;
                };
                if let Err(e) = g.map.publish(prediction.map) {
                    log::error!("{}: cannot publish the predicted map: {e}", g.topic);
                }
                if let (Some(publisher), Some(mask)) = (&g.mask, prediction.mask)
                    && let Err(e) = publisher.publish(mask)
                {
                    log::error!("{}: cannot publish the mask: {e}", g.topic);
                }
            }
        }
        if last_save.elapsed().as_secs_f64() >= config.save_period {
            *last_save = Instant::now();
            if let Err(e) = world.save(false) {
                log::error!("saving: {e}");
            }
        }
    }

    /// Learns what waits for the clock cutoff and saves (learning open people bins first).
    fn finish(&mut self) -> Result<(), StoreError> {
        if let Some(clock) = &self.sim_clock {
            for p in self.pending.drain(..) {
                if let Some(time) = clock.at(p.received) {
                    let topic = &self.io.states[p.index].topic;
                    learn_state(
                        &mut self.world,
                        &mut self.throttles,
                        topic,
                        p.index,
                        time,
                        p.value,
                    );
                }
            }
        }
        log_due(&mut self.throttles, true);
        self.world.save(true)
    }

    /// What it learned.
    fn summary(&self, save_error: Option<String>) -> Summary {
        let (learned_states, learned_grids) = self.world.learned();
        Summary {
            states: self
                .config
                .states
                .iter()
                .zip(learned_states)
                .map(|(s, l)| (s.name.clone(), l))
                .collect(),
            grids: self
                .config
                .grids
                .iter()
                .zip(learned_grids)
                .map(|(g, l)| (g.section().to_string(), g.name.clone(), l))
                .collect(),
            refused: self
                .throttles
                .iter()
                .map(|(topic, t)| (topic.clone(), t.total))
                .collect(),
            save_error,
            configured: true,
        }
    }
}

/// The node: its DDS entities, parameters, lifecycle state and, when configured, models.
struct Host<'c> {
    context: &'c Context,
    node: Node,
    poll: Poll,
    setup: Setup,
    managed: bool,
    domain_id: u16,
    machine: Machine,
    /// The declared parameters' values (`get_parameters`).
    values: BTreeMap<String, Value>,
    configured: Option<Configured>,
    /// What the last configured period learned (a managed node cleaned up).
    last: Option<Summary>,
}

impl Host<'_> {
    fn announce(&self) {
        let config = self.configured.as_ref().map(|c| &c.config);
        match config {
            Some(config) => log::info!(
                "node {} on DDS domain {}: {} state, {} grid topics{}{}",
                config.fully_qualified_name(),
                self.domain_id,
                config.states.len(),
                config.grids.len(),
                if config.edges.is_some() {
                    ", a route graph"
                } else {
                    ""
                },
                if config.use_sim_time {
                    "; time from /clock"
                } else {
                    ""
                }
            ),
            None => log::info!(
                "node {} on DDS domain {}: managed, {} (change_state configures it)",
                self.setup.fully_qualified_name(),
                self.domain_id,
                self.machine.state().label()
            ),
        }
    }

    /// Configures: checks the parameters, restores the models, opens the topics.
    fn configure(&mut self) -> Result<(), NodeError> {
        let config = self.setup.config()?;
        let configured = Configured::open(&mut self.node, config, &self.poll)?;
        self.configured = Some(configured);
        Ok(())
    }

    fn on_configure(&mut self) -> Outcome {
        match self.configure() {
            Ok(()) => {
                self.announce();
                Outcome::Success
            }
            Err(e) => {
                log::error!("configure: {e}");
                self.drop_configured();
                Outcome::Failure
            }
        }
    }

    fn on_activate(&mut self) -> Outcome {
        if let Some(c) = &mut self.configured {
            // Publish at once: the filter info and every prediction.
            c.schedules = Default::default();
            c.infos_published = false;
        }
        Outcome::Success
    }

    /// Saves and drops the models; a failed save keeps them (and fails the transition).
    fn save_and_drop(&mut self, what: &str) -> Outcome {
        let Some(c) = &mut self.configured else {
            return Outcome::Success;
        };
        log::info!("{what}: saving the models");
        match c.finish() {
            Ok(()) => {
                self.last = Some(c.summary(None));
                self.drop_configured();
                Outcome::Success
            }
            Err(e) => {
                log::error!("{what}: saving: {e}");
                Outcome::Failure
            }
        }
    }

    fn drop_configured(&mut self) {
        if let Some(mut c) = self.configured.take() {
            c.io.close(&self.poll);
        }
    }

    /// Runs the transition `change_state` asks for, publishing its events.
    fn change_state(
        &mut self,
        request: &LifecycleTransition,
        events: &Publisher<TransitionEvent>,
    ) -> bool {
        let from = self.machine.state();
        let started = match self.machine.start(request.id, &request.label) {
            Ok(t) => t,
            Err(message) => {
                log::warn!("change_state: {message}");
                return false;
            }
        };
        let publish = |t: &lifecycle::Transition| {
            let timestamp = u64::try_from(system_now_ns()).unwrap_or(0);
            let event = TransitionEvent {
                timestamp,
                transition: LifecycleTransition {
                    id: t.id,
                    label: t.label.to_string(),
                },
                start_state: state_msg(t.start),
                goal_state: state_msg(t.goal),
            };
            if let Err(e) = events.publish(event) {
                log::error!("cannot publish the transition event: {e}");
            }
        };
        publish(&started);
        let outcome = match started.goal {
            State::Configuring => self.on_configure(),
            State::Activating => self.on_activate(),
            State::Deactivating => Outcome::Success,
            State::CleaningUp => self.save_and_drop("cleanup"),
            State::ShuttingDown => self.save_and_drop("shutdown"),
            other => unreachable!("a request starts no transition into {}", other.label()),
        };
        let done = self.machine.finish(outcome);
        publish(&done);
        if self.machine.state() == State::ErrorProcessing {
            self.drop_configured();
            let recovered = self.machine.finish(Outcome::Success);
            publish(&recovered);
        }
        log::info!(
            "{}: {} -> {}",
            started.label,
            from.label(),
            self.machine.state().label()
        );
        outcome == Outcome::Success
    }

    fn active(&self) -> bool {
        !self.managed || self.machine.state() == State::Active
    }

    /// Why `name` may not be set to `value` now, or the parameters it gives (`None`: an
    /// unconfigured managed node whose other parameters are not complete yet).
    fn check_set(
        &self,
        setup: &Setup,
        name: &str,
        value: &Value,
    ) -> Result<Option<NodeConfig>, String> {
        if matches!(value, Value::NotSet) {
            return Err(format!(
                "{name}: the node's parameters cannot be undeclared"
            ));
        }
        let configured = self.configured.is_some();
        if configured && self.values.contains_key(name) && !config::is_dynamic(name) {
            return Err(if self.managed {
                format!(
                    "{name}: read only while the node is configured: clean it up (lifecycle \
                     cleanup), set it, configure again"
                )
            } else {
                format!("{name}: read only: restart the node with the new value")
            });
        }
        match setup.config_with(name, value, !configured) {
            Ok(config) => Ok(Some(config)),
            Err(e) if configured || e.key.as_deref() == Some(name) => Err(match e.key {
                Some(key) => format!("{key}: {}", e.message),
                None => e.message,
            }),
            Err(_) => Ok(None),
        }
    }

    /// Sets `name` to `value` (already checked to give `checked`).
    fn apply(&mut self, name: &str, value: Value, checked: Option<NodeConfig>) {
        self.setup
            .params
            .insert(name, value.clone(), Origin::Service);
        let mut changed = Vec::new();
        match checked {
            Some(config) => {
                let fresh: BTreeMap<String, Value> = config.parameters().into_iter().collect();
                for (n, v) in &fresh {
                    if self.values.get(n) != Some(v) {
                        changed.push((n.clone(), v.clone()));
                    }
                }
                self.values.extend(fresh);
                if let Some(c) = &mut self.configured {
                    c.update(&config);
                }
            }
            None => {
                self.values.insert(name.to_string(), value.clone());
                changed.push((name.to_string(), value.clone()));
            }
        }
        for (n, v) in changed {
            // Publishes the change on /parameter_events.
            if let Err(e) = self.node.set_parameter(&n, v) {
                log::debug!("parameter event of {n}: {e}");
            }
        }
        log::info!("parameter {name} set to {}", params::show(&value));
    }

    /// Sets parameters one by one (`set_parameters`).
    fn set_each(&mut self, parameters: Vec<raw::Parameter>) -> Vec<raw::SetParametersResult> {
        parameters
            .into_iter()
            .map(|p| {
                let value = Value::from(p.value);
                match self.check_set(&self.setup, &p.name, &value) {
                    Ok(checked) => {
                        self.apply(&p.name, value, checked);
                        raw::SetParametersResult {
                            successful: true,
                            reason: String::new(),
                        }
                    }
                    Err(reason) => {
                        log::warn!("set_parameters: refused: {reason}");
                        raw::SetParametersResult {
                            successful: false,
                            reason,
                        }
                    }
                }
            })
            .collect()
    }

    /// Sets parameters all or none (`set_parameters_atomically`).
    fn set_all(&mut self, parameters: Vec<raw::Parameter>) -> raw::SetParametersResult {
        let mut trial = self.setup.clone();
        let mut checked = Vec::new();
        for p in parameters {
            let value = Value::from(p.value);
            match self.check_set(&trial, &p.name, &value) {
                Ok(config) => {
                    trial.params.insert(&p.name, value.clone(), Origin::Service);
                    checked.push((p.name, value, config));
                }
                Err(reason) => {
                    log::warn!("set_parameters_atomically: refused: {reason}");
                    return raw::SetParametersResult {
                        successful: false,
                        reason,
                    };
                }
            }
        }
        for (name, value, config) in checked {
            self.apply(&name, value, config);
        }
        raw::SetParametersResult {
            successful: true,
            reason: String::new(),
        }
    }

    fn serve_parameters(&mut self, s: &ParamServers) {
        serve(&s.get, "get_parameters", |r| GetParametersResponse {
            values: r
                .names
                .iter()
                .map(|n| {
                    raw::ParameterValue::from(self.values.get(n).cloned().unwrap_or(Value::NotSet))
                })
                .collect(),
        });
        serve(&s.types, "get_parameter_types", |r| {
            GetParameterTypesResponse {
                values: r
                    .names
                    .iter()
                    .map(|n| self.values.get(n).map_or(0, Value::to_parameter_type_raw))
                    .collect(),
            }
        });
        serve(&s.list, "list_parameters", |r| ListParametersResponse {
            result: list_parameters(self.values.keys(), &r.prefixes, r.depth),
        });
        serve(&s.describe, "describe_parameters", |r| {
            DescribeParametersResponse {
                values: r
                    .names
                    .iter()
                    .map(|n| describe_parameter(n, self.values.get(n)))
                    .collect(),
            }
        });
        for _ in 0..MAX_REQUESTS {
            match s.set.receive_request() {
                Ok(Some((id, request))) => {
                    let results = self.set_each(request.parameter);
                    if let Err(e) = s.set.send_response(id, SetParametersResponse { results }) {
                        log::warn!("set_parameters: cannot send the response: {e}");
                    }
                }
                Ok(None) => break,
                Err(e) => {
                    log::warn!("set_parameters: a request that cannot be read: {e}");
                    break;
                }
            }
        }
        for _ in 0..MAX_REQUESTS {
            match s.set_atomically.receive_request() {
                Ok(Some((id, request))) => {
                    let result = self.set_all(request.parameter);
                    let response = SetParametersAtomicallyResponse { result };
                    if let Err(e) = s.set_atomically.send_response(id, response) {
                        log::warn!("set_parameters_atomically: cannot send the response: {e}");
                    }
                }
                Ok(None) => break,
                Err(e) => {
                    log::warn!("set_parameters_atomically: a request that cannot be read: {e}");
                    break;
                }
            }
        }
    }

    fn serve_lifecycle(&mut self, s: &LifecycleServers) {
        for _ in 0..MAX_REQUESTS {
            match s.change.receive_request() {
                Ok(Some((id, request))) => {
                    let success = self.change_state(&request.transition, &s.events);
                    if let Err(e) = s.change.send_response(id, ChangeStateResponse { success }) {
                        log::warn!("change_state: cannot send the response: {e}");
                    }
                }
                Ok(None) => break,
                Err(e) => {
                    log::warn!("change_state: a request that cannot be read: {e}");
                    break;
                }
            }
        }
        let state = self.machine.state();
        serve(&s.get, "get_state", |_| GetStateResponse {
            current_state: state_msg(state),
        });
        serve(&s.states, "get_available_states", |_| {
            GetAvailableStatesResponse {
                available_states: State::ALL.iter().map(|&s| state_msg(s)).collect(),
            }
        });
        serve(&s.transitions, "get_available_transitions", |_| {
            GetAvailableTransitionsResponse {
                available_transitions: lifecycle::available(state)
                    .iter()
                    .map(description)
                    .collect(),
            }
        });
        serve(&s.graph, "get_transition_graph", |_| {
            GetAvailableTransitionsResponse {
                available_transitions: lifecycle::GRAPH.iter().map(description).collect(),
            }
        });
    }
}

/// `list_parameters` as rclcpp answers it: with no prefixes, the names with fewer than `depth`
/// dots (0: all); otherwise the names equal to a prefix or under `prefix.` within `depth`
/// more levels; `prefixes` are the distinct namespaces of the names listed.
fn list_parameters<'a>(
    names: impl Iterator<Item = &'a String>,
    prefixes: &[String],
    depth: u64,
) -> ListParametersResult {
    let within = |s: &str| depth == 0 || (s.matches('.').count() as u64) < depth;
    let mut result = ListParametersResult {
        names: vec![],
        prefixes: vec![],
    };
    for name in names {
        let all = prefixes.is_empty() && within(name);
        let under = prefixes.iter().any(|prefix| {
            name == prefix
                || name
                    .strip_prefix(prefix.as_str())
                    .and_then(|rest| rest.strip_prefix('.'))
                    .is_some_and(|rest| within(&format!(".{rest}")))
        });
        if all || under {
            result.names.push(name.clone());
            if let Some((namespace, _)) = name.rsplit_once('.')
                && !result.prefixes.iter().any(|p| p == namespace)
            {
                result.prefixes.push(namespace.to_string());
            }
        }
    }
    result
}

/// The descriptor of the parameter `name` (`describe_parameters`).
fn describe_parameter(name: &str, value: Option<&Value>) -> raw::ParameterDescriptor {
    let dynamic = config::is_dynamic(name);
    let (integer_range, floating_point_range) = if name.ends_with(".filter_type") {
        (
            vec![raw::IntegerRange {
                from_value: 0,
                to_value: 3,
                step: 1,
            }],
            vec![],
        )
    } else {
        (vec![], vec![])
    };
    raw::ParameterDescriptor {
        name: name.to_string(),
        r#type: value.map_or(0, Value::to_parameter_type_raw),
        description: config::description(name).to_string(),
        additional_constraints: if value.is_none() {
            String::new()
        } else if dynamic {
            "changes the running node".to_string()
        } else {
            "read while the node starts or configures".to_string()
        },
        read_only: value.is_some() && !dynamic,
        dynamic_typing: false,
        floating_point_range,
        integer_range,
    }
}

/// Runs the node until `stop` is set, then saves (learning open people bins first) and
/// returns what it learned. Unmanaged, it configures and activates at once; managed, it waits
/// unconfigured for `~/change_state`.
///
/// # Errors
/// Parameters that cannot be used and models that cannot be restored (unmanaged: a managed
/// node logs them and stays unconfigured), DDS entities that cannot be created, or polling
/// that fails. Bad messages, refused parameter values and failed saves are logged (or
/// answered), not returned: the node goes on.
pub fn run(setup: Setup, options: &RunOptions, stop: &AtomicBool) -> Result<Summary, NodeError> {
    let initial = if options.managed {
        setup.config_allowing_empty()?
    } else {
        setup.config()?
    };
    let context = Context::with_options(ContextOptions::new().domain_id(options.domain_id))
        .map_err(|e| NodeError::Dds(format!("cannot join domain {}: {e}", options.domain_id)))?;
    let node_name = NodeName::new(&setup.namespace, &setup.name)
        .map_err(|e| NodeError::Name(format!("node name: {e}")))?;
    let values: BTreeMap<String, Value> = initial.parameters().into_iter().collect();
    let mut node_options = NodeOptions::new()
        .enable_rosout(options.rosout)
        .start_parameter_services(false)
        .allow_undeclared_parameters(true);
    for (name, value) in &values {
        node_options = node_options.declare_parameter(name, value.clone());
    }
    let node = context
        .new_node(node_name, node_options)
        .map_err(|e| NodeError::Dds(format!("node: {e}")))?;
    if options.rosout {
        rosout::install(
            node.logging_handle(),
            rosout::logger_name(&setup.fully_qualified_name()),
        );
    }
    let mut host = Host {
        context: &context,
        node,
        poll: Poll::new()?,
        setup,
        managed: options.managed,
        domain_id: options.domain_id,
        machine: Machine::default(),
        values,
        configured: None,
        last: None,
    };
    let result = host.run(stop);
    rosout::remove();
    result
}

impl Host<'_> {
    fn run(&mut self, stop: &AtomicBool) -> Result<Summary, NodeError> {
        let mut b = Builder {
            node: &mut self.node,
        };
        let param_servers = ParamServers::new(&mut b, &self.setup, &self.poll)?;
        let lifecycle_servers = if self.managed {
            Some(LifecycleServers::new(&mut b, &self.setup, &self.poll)?)
        } else {
            None
        };
        if !self.managed {
            self.configure()?;
        }
        self.announce();
        let mut events = Events::with_capacity(64);
        while !stop.load(Ordering::Relaxed) {
            match self.poll.poll(&mut events, Some(POLL)) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e.into()),
            }
            self.serve_parameters(&param_servers);
            if let Some(servers) = &lifecycle_servers {
                self.serve_lifecycle(servers);
            }
            if self.active()
                && let Some(c) = &mut self.configured
            {
                c.step(self.context);
            }
        }
        let summary = match &mut self.configured {
            Some(c) => {
                log::info!("stopping: saving the models");
                let save_error = c.finish().err().map(|e| e.to_string());
                c.summary(save_error)
            }
            None => {
                log::info!("stopping ({})", self.machine.state().label());
                self.last.take().unwrap_or(Summary {
                    states: Vec::new(),
                    grids: Vec::new(),
                    refused: BTreeMap::new(),
                    save_error: None,
                    configured: false,
                })
            }
        };
        self.drop_configured();
        Ok(summary)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_state_gets_the_last_clock_received_before_it() {
        let mut clock = SimClock::default();
        assert_eq!(clock.at(5), None);
        clock.push(10, 100.0);
        clock.push(30, 300.0);
        clock.push(20, 200.0); // stored in receive order
        assert_eq!(
            [clock.at(5), clock.at(10), clock.at(25), clock.at(99)],
            [None, Some(100.0), Some(200.0), Some(300.0)]
        );
        // Forgetting keeps what a message received at or after 25 needs.
        clock.forget_before(25);
        assert_eq!(clock.history.len(), 2);
        assert_eq!([clock.at(25), clock.at(30)], [Some(200.0), Some(300.0)]);
        assert_eq!(clock.at(0), Some(100.0));
        clock.forget_before(1000);
        assert_eq!((clock.history.len(), clock.at(1000)), (1, Some(300.0)));
    }

    #[test]
    fn schedules_run_once_per_period_and_at_once_after_the_clock_went_back() {
        let mut s = Schedule::default();
        let due: Vec<bool> = [0.0, 0.5, 1.0, 1.2, 2.5, 2.9, 3.5, 0.1, 0.2]
            .iter()
            .map(|&t| s.due(t, 1.0))
            .collect();
        assert_eq!(
            due,
            [true, false, true, false, true, false, true, true, false]
        );
    }

    #[test]
    fn every_reason_is_logged_first_and_then_every_30_s_with_its_count() {
        let mut t = Throttle::default();
        let start = Instant::now();
        let at = |s: u64| start + Duration::from_secs(s);
        // Values differ, the reason is the same.
        assert_eq!(
            t.note("value 1.5 is not in [0, 1]".into(), at(0))
                .as_deref(),
            Some("value 1.5 is not in [0, 1]")
        );
        assert_eq!(t.note("value 2 is not in [0, 1]".into(), at(1)), None);
        // A sixth, seventh, ... reason still reaches the log at once.
        for k in 0..6 {
            let message = format!(
                "frame \"f{}\" is not \"map\"",
                ["a", "b", "c", "d", "e", "f"][k]
            );
            assert_eq!(t.note(message.clone(), at(2)), Some(message));
        }
        assert_eq!(t.note("value -3 is not in [0, 1]".into(), at(10)), None);
        // Nothing is due before 30 s; then one line with the count and the last message.
        assert!(t.due(at(29), false).is_empty());
        assert_eq!(
            t.due(at(30), false),
            [
                "2 more refused for the same reason in the last 30 s (the last: value -3 is not in [0, 1])"
            ]
        );
        assert!(t.due(at(31), false).is_empty());
        // A repeat 30 s after the last line is logged with its count at once.
        t.note("value 7 is not in [0, 1]".into(), at(45));
        assert_eq!(
            t.note("value 8 is not in [0, 1]".into(), at(61)).as_deref(),
            Some(
                "2 more refused for the same reason in the last 31 s (the last: value 8 is not in [0, 1])"
            )
        );
        assert_eq!(t.total, 11);
        // At the end, whatever is left is logged.
        t.note("value 9 is not in [0, 1]".into(), at(62));
        assert_eq!(t.due(at(62), true).len(), 1);
        assert_eq!(
            reason_key("30 x 20 cells is more than max_map_cells (16.5)"),
            "# x # cells is more than max_map_cells (#)"
        );
    }

    #[test]
    fn distinct_reasons_are_bounded() {
        let mut t = Throttle::default();
        let now = Instant::now();
        for k in 0..100 {
            t.note(
                format!("frame \"{}\" is not \"map\"", "x".repeat(k + 1)),
                now,
            );
        }
        assert_eq!(t.reasons.len(), MAX_REASONS + 1);
        assert_eq!(t.total, 100);
    }

    #[test]
    fn parameters_are_listed_as_rclcpp_lists_them() {
        let names: Vec<String> = ["a", "a.b", "a.b.c", "ab", "x.y"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let list = |prefixes: &[&str], depth| {
            let prefixes: Vec<String> = prefixes.iter().map(|p| p.to_string()).collect();
            list_parameters(names.iter(), &prefixes, depth)
        };
        let all = list(&[], 0);
        assert_eq!(all.names, ["a", "a.b", "a.b.c", "ab", "x.y"]);
        assert_eq!(all.prefixes, ["a", "a.b", "x"]);
        assert_eq!(list(&[], 1).names, ["a", "ab"]);
        assert_eq!(list(&["a"], 0).names, ["a", "a.b", "a.b.c"]);
        assert_eq!(list(&["a"], 2).names, ["a", "a.b"]);
        let d = describe_parameter("maps.office.filter_type", Some(&Value::Integer(0)));
        assert!(!d.read_only && d.integer_range.len() == 1);
        let d = describe_parameter("states.door.model", Some(&Value::String("x".into())));
        assert!(d.read_only && d.r#type == 4);
        assert_eq!(describe_parameter("nope", None).r#type, 0);
    }

    #[test]
    fn publishers_of_another_type_on_an_input_topic_are_refused_once_logged() {
        let mut check = WriterCheck {
            inputs: HashMap::from([(
                "rt/window".to_string(),
                Input {
                    topic: "/window".into(),
                    expected: Bool::TYPE,
                    parameter: "states.window.type".into(),
                },
            )]),
            reported: HashSet::new(),
            wrong: HashSet::new(),
            right: HashSet::new(),
            last: None,
        };
        let (a, b) = (GUID::from_bytes([1; 16]), GUID::from_bytes([2; 16]));
        let grid = "nav_msgs::msg::dds_::OccupancyGrid_";
        assert!(!check.judge(a, "rt/window", grid));
        assert!(!check.judge(a, "rt/window", grid));
        assert_eq!(check.reported.len(), 1);
        assert!(check.judge(b, "rt/window", "std_msgs::msg::dds_::Bool_"));
        assert!(
            check.judge(a, "rt/other", grid),
            "topics the node does not read"
        );
        assert!(check.wrong.contains(&a) && check.right.contains(&b));
    }
}
