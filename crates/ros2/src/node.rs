//! The node on the DDS network (ros2-client on RustDDS): subscriptions, publishers, the clock,
//! schedules and the checks of what publishers send. Messages become calls of [`World`] and
//! its predictions become messages; nothing is computed here.
//!
//! One thread polls every subscription. Each round it takes `/clock` (with `use_sim_time`),
//! the states, maps and people, then runs what is due in the node's time (simulated or not,
//! as ROS timers run): the route graph every `edges.period`, state predictions every
//! `publish_period`, maps, masks and people every `map_period`; and it saves every
//! `save_period` seconds of wall-clock time.
//!
//! States carry no stamp: each is learned at the node's time when RustDDS received it (with
//! `use_sim_time`, the last `/clock` value received before it, taken 0.2 s later). Maps and
//! people are learned at their `header.stamp`. RustDDS matches readers and writers by topic
//! name only, so the node checks the type every publisher of an input topic announces and
//! logs one error per publisher of another type, whose messages it ignores.

use std::collections::{BTreeMap, HashMap, HashSet, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::dds::rustdds::{GUID, Topic, TopicDescription};
use ros2_client::qos::{Durability, History, Reliability as QosReliability, WhenFull};
use ros2_client::{
    Context, ContextOptions, MessageInfo, MessageTypeName, Name, Node, NodeName, NodeOptions,
    Publisher, QosProfile, Subscription,
};
use thiserror::Error;

use crate::config::{GridSource, InputQos, Reliability, StateType};
use crate::msgs::{
    Bool, Clock, CostmapFilterInfo, Float32, Float64, Message, OccupancyGrid, PoseArray, Time,
    TypeName, ros_type_of_dds,
};
use crate::world::{Learned, World};

/// Longest wait for messages before the node looks at its clock and schedules again.
const POLL: Duration = Duration::from_millis(20);
/// How often the publishers on the input topics are checked.
const CHECK_WRITERS: Duration = Duration::from_secs(1);
/// Messages taken from one subscription per round at most (the others get their turn).
const MAX_TAKE: usize = 10_000;

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

/// Error messages of one input, at most a few at first and then one summary every 30 s.
#[derive(Default)]
struct Throttle {
    shown: u32,
    suppressed: u64,
    total: u64,
    last_summary: Option<Instant>,
}

impl Throttle {
    const SHOWN: u32 = 5;

    fn error(&mut self, topic: &str, message: impl FnOnce() -> String) {
        self.total += 1;
        if self.shown < Self::SHOWN {
            self.shown += 1;
            log::error!("{topic}: {}", message());
            return;
        }
        self.suppressed += 1;
        let due = self
            .last_summary
            .is_none_or(|t| t.elapsed() >= Duration::from_secs(30));
        if due {
            log::error!(
                "{topic}: {} more messages refused (the last: {})",
                self.suppressed,
                message()
            );
            self.suppressed = 0;
            self.last_summary = Some(Instant::now());
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

/// Runs the node on DDS domain `domain_id` until `stop` is set, then saves (learning open
/// people bins first) and returns what it learned.
///
/// # Errors
/// DDS entities that cannot be created, or polling that fails. Bad messages and failed saves
/// are logged, not returned: the node goes on.
pub fn run(mut world: World, domain_id: u16, stop: &AtomicBool) -> Result<Summary, NodeError> {
    let config = world.config().clone();
    let context = Context::with_options(ContextOptions::new().domain_id(domain_id))
        .map_err(|e| NodeError::Dds(format!("cannot join domain {domain_id}: {e}")))?;
    let node_name = NodeName::new(&config.namespace, &config.node_name)
        .map_err(|e| NodeError::Name(format!("node name: {e}")))?;
    let mut node = context
        .new_node(node_name, NodeOptions::new().enable_rosout(false))
        .map_err(|e| NodeError::Dds(format!("node: {e}")))?;
    let mut inputs = HashMap::new();
    let mut b = Builder { node: &mut node };

    let clock = if config.use_sim_time {
        let qos = QosProfile::subscription_default()
            .reliability(QosReliability::BestEffort)
            .history(History::KeepLast { depth: 1000 });
        let (reader, dds) = b.reader::<Clock>("/clock", qos)?;
        inputs.insert(
            dds,
            Input {
                topic: "/clock".into(),
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

    let mut poll = Poll::new()?;
    let mut token = 0;
    let mut next_token = || {
        token += 1;
        Token(token)
    };
    let mut clock_reader = clock;
    if let Some(reader) = &mut clock_reader {
        poll.registry()
            .register(reader, next_token(), Interest::READABLE)?;
    }
    for s in &mut states {
        s.reader.register(&poll, next_token())?;
    }
    for g in &mut grids {
        let t = next_token();
        match &mut g.reader {
            GridReader::Map(r) => poll.registry().register(r, t, Interest::READABLE)?,
            GridReader::People(r) => poll.registry().register(r, t, Interest::READABLE)?,
        }
    }
    log::info!(
        "node {} on DDS domain {domain_id}: {} state, {} grid topics{}{}",
        config.fully_qualified_name(),
        states.len(),
        grids.len(),
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
    );

    let mut sim_clock = config.use_sim_time.then(SimClock::default);
    let mut pending: VecDeque<Pending> = VecDeque::new();
    let mut check = WriterCheck {
        inputs,
        reported: HashSet::new(),
        wrong: HashSet::new(),
        right: HashSet::new(),
        last: None,
    };
    let mut throttles: BTreeMap<String, Throttle> = BTreeMap::new();
    let mut schedules = [
        Schedule::default(),
        Schedule::default(),
        Schedule::default(),
    ];
    let mut infos_published = false;
    let mut last_save = Instant::now();
    let mut events = Events::with_capacity(64);
    let mut waiting_for_clock_logged = false;

    while !stop.load(Ordering::Relaxed) {
        match poll.poll(&mut events, Some(POLL)) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e.into()),
        }
        check.scan(&context);
        // With simulated time, what was received before the cutoff is complete.
        let cutoff = system_now_ns() - SIM_LATENCY_NS;
        if let (Some(reader), Some(clock)) = (&clock_reader, &mut sim_clock) {
            for _ in 0..MAX_TAKE {
                match reader.take() {
                    Ok(Some((msg, info))) => {
                        if check.accepts(&context, &info) {
                            let received = received_ns(&info);
                            log::trace!(
                                "/clock: {} received at {received} ns",
                                msg.clock.seconds()
                            );
                            clock.push(received, msg.clock.seconds());
                        }
                    }
                    Ok(None) => break,
                    Err(e) => throttle(&mut throttles, "/clock").error("/clock", || e.to_string()),
                }
            }
        }
        for (index, s) in states.iter().enumerate() {
            for _ in 0..MAX_TAKE {
                match s.reader.take() {
                    Ok(Some((value, info))) => {
                        if !check.accepts(&context, &info) {
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
                            learn_state(&mut world, &mut throttles, &s.topic, index, time, value);
                        }
                    }
                    Ok(None) => break,
                    Err(e) => throttle(&mut throttles, &s.topic).error(&s.topic, || e),
                }
            }
        }
        if let Some(clock) = &mut sim_clock {
            let mut waiting = VecDeque::with_capacity(pending.len());
            for p in pending.drain(..) {
                if p.received > cutoff {
                    waiting.push_back(p);
                    continue;
                }
                let topic = &states[p.index].topic;
                match clock.at(p.received) {
                    Some(time) => {
                        learn_state(&mut world, &mut throttles, topic, p.index, time, p.value);
                    }
                    None => throttle(&mut throttles, topic).error(topic, || {
                        "a state before the first /clock message (use_sim_time): not learned".into()
                    }),
                }
            }
            pending = waiting;
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
                            if !check.accepts(&context, &info) {
                                continue;
                            }
                            (world.observe_map(index, &msg), info)
                        }
                        Ok(None) => break,
                        Err(e) => {
                            throttle(&mut throttles, &g.topic).error(&g.topic, || e.to_string());
                            continue;
                        }
                    },
                    GridReader::People(r) => match r.take() {
                        Ok(Some((msg, info))) => {
                            if !check.accepts(&context, &info) {
                                continue;
                            }
                            (world.observe_people(index, &msg), info)
                        }
                        Ok(None) => break,
                        Err(e) => {
                            throttle(&mut throttles, &g.topic).error(&g.topic, || e.to_string());
                            continue;
                        }
                    },
                };
                match result {
                    Ok(()) => {
                        log::trace!("{}: learned message {}", g.topic, info.sequence_number())
                    }
                    Err(e) => throttle(&mut throttles, &g.topic).error(&g.topic, || e.to_string()),
                }
            }
        }

        let now = match &sim_clock {
            Some(clock) => clock.at(cutoff),
            None => Some(system_now_ns() as f64 / 1e9),
        };
        let Some(now) = now else {
            if !waiting_for_clock_logged {
                log::info!("waiting for the first /clock message (use_sim_time)");
                waiting_for_clock_logged = true;
            }
            continue;
        };
        let target = now + config.horizon;
        let stamp = Time::from_seconds(now);
        if !infos_published {
            for (index, g) in grids.iter().enumerate() {
                if let (Some(publisher), Some(info)) = (&g.info, world.filter_info(index, stamp))
                    && let Err(e) = publisher.publish(info)
                {
                    log::error!("{}: cannot publish the filter info: {e}", g.topic);
                }
            }
            infos_published = true;
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
            last_save = Instant::now();
            if let Err(e) = world.save(false) {
                log::error!("saving: {e}");
            }
        }
    }
    if let Some(clock) = &sim_clock {
        for p in pending {
            if let Some(time) = clock.at(p.received) {
                let topic = &states[p.index].topic;
                learn_state(&mut world, &mut throttles, topic, p.index, time, p.value);
            }
        }
    }
    log::info!("stopping: saving the models");
    let save_error = world.save(true).err().map(|e| e.to_string());
    let (learned_states, learned_grids) = world.learned();
    Ok(Summary {
        states: config
            .states
            .iter()
            .zip(learned_states)
            .map(|(s, l)| (s.name.clone(), l))
            .collect(),
        grids: config
            .grids
            .iter()
            .zip(learned_grids)
            .map(|(g, l)| (g.section().to_string(), g.name.clone(), l))
            .collect(),
        refused: throttles
            .into_iter()
            .map(|(topic, t)| (topic, t.total))
            .collect(),
        save_error,
    })
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
    fn throttles_show_five_errors_then_summaries() {
        let mut t = Throttle::default();
        for _ in 0..8 {
            t.error("/x", || "bad".into());
        }
        // Five shown, the sixth starts a summary period, the last two wait for the next one.
        assert_eq!((t.total, t.shown, t.suppressed), (8, 5, 2));
        assert!(t.last_summary.is_some());
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
