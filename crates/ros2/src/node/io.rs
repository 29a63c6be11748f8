//! The node's subscriptions and publishers, their QoS, and the type check of publishers.

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use ros2_client::dds::rustdds::mio1::{Interest, Poll, Token};
use ros2_client::dds::rustdds::{GUID, Topic, TopicDescription};
use ros2_client::qos::{Durability, History, Reliability as QosReliability, WhenFull};
use ros2_client::{
    Context, MessageInfo, MessageTypeName, Name, Node, Publisher, QosProfile, Server,
    ServiceMapping, ServiceTypeName, Subscription,
};

use super::{CHECK_WRITERS, NodeError};
use crate::config::{GridSource, InputQos, NodeConfig, Reliability, Setup, StateType};
use crate::msgs::{
    Bool, Clock, CostmapFilterInfo, Float32, Float64, Message, OccupancyGrid, PoseArray,
    Prediction, TypeName, ros_type_of_dds,
};

/// A subscription of a state topic.
pub(super) enum StateReader {
    Bool(Subscription<Bool>),
    Float32(Subscription<Float32>),
    Float64(Subscription<Float64>),
}

impl StateReader {
    /// The next message as a value in [0, 1] (Bool: 0 or 1).
    pub(super) fn take(&self) -> Result<Option<(f64, MessageInfo)>, String> {
        let taken = match self {
            StateReader::Bool(s) => s
                .take()
                .map(|m| m.map(|(b, i)| (if b.data { 1.0 } else { 0.0 }, i))),
            StateReader::Float32(s) => s.take().map(|m| m.map(|(f, i)| (f64::from(f.data), i))),
            StateReader::Float64(s) => s.take().map(|m| m.map(|(f, i)| (f.data, i))),
        };
        taken.map_err(|e| e.to_string())
    }

    pub(super) fn register(&mut self, poll: &Poll, token: Token) -> std::io::Result<()> {
        let registry = poll.registry();
        match self {
            StateReader::Bool(s) => registry.register(s, token, Interest::READABLE),
            StateReader::Float32(s) => registry.register(s, token, Interest::READABLE),
            StateReader::Float64(s) => registry.register(s, token, Interest::READABLE),
        }
    }

    pub(super) fn deregister(&mut self, poll: &Poll) -> std::io::Result<()> {
        let registry = poll.registry();
        match self {
            StateReader::Bool(s) => registry.deregister(s),
            StateReader::Float32(s) => registry.deregister(s),
            StateReader::Float64(s) => registry.deregister(s),
        }
    }
}

pub(super) enum GridReader {
    Map(Subscription<OccupancyGrid>),
    People(Subscription<PoseArray>),
}

/// A state topic and the states learned from it (several models may learn one topic).
pub(super) struct StateInput {
    pub(super) topic: String,
    pub(super) reader: StateReader,
    /// Indices of the states in the configuration.
    pub(super) states: Vec<usize>,
}

/// What a state publishes.
pub(super) struct StateOutput {
    pub(super) probability: Publisher<Float64>,
    pub(super) entropy: Publisher<Float64>,
    pub(super) prediction: Option<Publisher<Prediction>>,
}

pub(super) struct GridIo {
    pub(super) topic: String,
    pub(super) reader: GridReader,
    pub(super) map: Publisher<OccupancyGrid>,
    pub(super) mask: Option<Publisher<OccupancyGrid>>,
    pub(super) info: Option<Publisher<CostmapFilterInfo>>,
}

/// An input topic as DDS names it, for checking the types of its publishers.
pub(super) struct Input {
    pub(super) topic: String,
    pub(super) expected: TypeName,
    pub(super) parameter: String,
}

/// Which publishers on the input topics send another type than configured.
pub(super) struct WriterCheck {
    pub(super) inputs: HashMap<String, Input>,
    pub(super) reported: HashSet<GUID>,
    pub(super) wrong: HashSet<GUID>,
    pub(super) right: HashSet<GUID>,
    pub(super) last: Option<Instant>,
}

impl WriterCheck {
    /// Logs every newly discovered publisher of a wrong type on an input topic.
    pub(super) fn scan(&mut self, context: &Context) {
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
    pub(super) fn judge(&mut self, guid: GUID, topic: &str, type_name: &str) -> bool {
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
    pub(super) fn accepts(&mut self, context: &Context, info: &MessageInfo) -> bool {
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

pub(super) fn qos_of(input: &InputQos) -> QosProfile {
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
pub(super) fn latched() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
}

pub(super) struct Builder<'a> {
    pub(super) node: &'a mut Node,
}

impl Builder<'_> {
    pub(super) fn topic(
        &self,
        name: &str,
        ty: TypeName,
        qos: &QosProfile,
    ) -> Result<Topic, NodeError> {
        let parsed = Name::parse(name).map_err(|e| NodeError::Name(format!("{name}: {e}")))?;
        self.node
            .create_topic(&parsed, MessageTypeName::new(ty.package, ty.name), qos)
            .map_err(|e| NodeError::Dds(format!("topic {name}: {e}")))
    }

    pub(super) fn reader<M: Message>(
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

    pub(super) fn writer<M: Message>(&mut self, name: &str) -> Result<Publisher<M>, NodeError> {
        let qos = latched();
        let topic = self.topic(name, M::TYPE, &qos)?;
        self.node
            .create_publisher(&topic, Some(qos))
            .map_err(|e| NodeError::Dds(format!("publisher of {name}: {e}")))
    }
}

/// The QoS of services (rmw's `rmw_qos_profile_services_default`): reliable, volatile, keep
/// last 10.
pub(super) fn service_qos() -> QosProfile {
    QosProfile::subscription_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
}

impl Builder<'_> {
    /// The server of the service `~/LEAF` (remapped) of type `package/srv/TYPE`.
    pub(super) fn server<Q, A>(
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

/// The subscriptions and publishers of a configured node.
pub(super) struct Io {
    pub(super) clock: Option<Subscription<Clock>>,
    pub(super) state_inputs: Vec<StateInput>,
    /// Per state, in configuration order.
    pub(super) states: Vec<StateOutput>,
    pub(super) grids: Vec<GridIo>,
}

impl Io {
    /// Creates the subscriptions and publishers of `config`, registered with `poll`; also
    /// the input topics as DDS names them, for the type check of publishers.
    pub(super) fn open(
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
        let mut state_inputs: Vec<StateInput> = Vec::new();
        let mut states = Vec::new();
        for (index, s) in config.states.iter().enumerate() {
            states.push(StateOutput {
                probability: b.writer(&s.probability_topic)?,
                entropy: b.writer(&s.entropy_topic)?,
                prediction: match &s.prediction_topic {
                    Some(topic) => Some(b.writer(topic)?),
                    None => None,
                },
            });
            // States of one topic share its subscription (the configuration checked that
            // they agree on type and QoS).
            if let Some(input) = state_inputs.iter_mut().find(|i| i.topic == s.topic) {
                input.states.push(index);
                continue;
            }
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
            state_inputs.push(StateInput {
                topic: s.topic.clone(),
                reader,
                states: vec![index],
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
            state_inputs,
            states,
            grids,
        };
        let token = Token(1);
        if let Some(reader) = &mut io.clock {
            poll.registry()
                .register(reader, token, Interest::READABLE)?;
        }
        for s in &mut io.state_inputs {
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
    pub(super) fn close(&mut self, poll: &Poll) {
        let r = poll.registry();
        let mut results = Vec::new();
        if let Some(reader) = &mut self.clock {
            results.push(r.deregister(reader));
        }
        for s in &mut self.state_inputs {
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

#[cfg(test)]
mod tests {
    use super::*;
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
