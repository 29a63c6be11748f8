//! The node's services: the `rcl_interfaces` parameter services, chronomap's own (`~/predict`,
//! `~/save`) and, managed, the `lifecycle_msgs` services.

use ros2_client::dds::rustdds::mio1::{Interest, Poll, Token};
use ros2_client::parameters::raw;
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::rcl_interfaces::{
    DescribeParametersRequest, DescribeParametersResponse, GetParameterTypesRequest,
    GetParameterTypesResponse, GetParametersRequest, GetParametersResponse, ListParametersRequest,
    ListParametersResponse, ListParametersResult, SetParametersAtomicallyResponse,
    SetParametersRequest, SetParametersResponse,
};
use ros2_client::{Publisher, QosProfile, Server};

use super::io::Builder;
use super::{MAX_REQUESTS, NodeError};
use crate::config::{self, Setup};
use crate::lifecycle::{self, State};
use crate::msgs::{
    ChangeStateRequest, ChangeStateResponse, EmptyRequest, GetAvailableStatesResponse,
    GetAvailableTransitionsResponse, GetStateResponse, LifecycleState, LifecycleTransition,
    Message, PredictRequest, PredictResponse, TransitionDescription, TransitionEvent,
    TriggerResponse,
};
use crate::params::Value;
use crate::world::World;

/// The six `rcl_interfaces` parameter services.
pub(super) struct ParamServers {
    pub(super) get: Server<GetParametersRequest, GetParametersResponse>,
    pub(super) types: Server<GetParameterTypesRequest, GetParameterTypesResponse>,
    pub(super) set: Server<SetParametersRequest, SetParametersResponse>,
    pub(super) set_atomically: Server<SetParametersRequest, SetParametersAtomicallyResponse>,
    pub(super) list: Server<ListParametersRequest, ListParametersResponse>,
    pub(super) describe: Server<DescribeParametersRequest, DescribeParametersResponse>,
}

impl ParamServers {
    pub(super) fn new(b: &mut Builder<'_>, setup: &Setup, poll: &Poll) -> Result<Self, NodeError> {
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

/// Largest number of times one `~/predict` request may ask for (a day at one per second fits;
/// the node answers on its own round, so a request is kept short).
pub(super) const MAX_PREDICT_TIMES: usize = 100_000;

/// chronomap's services: `~/predict` (`chronomap_msgs/srv/Predict`: a state at given times),
/// `~/save` (`std_srvs/srv/Trigger`: a checkpoint now) and `~/refit` (`std_srvs/srv/Trigger`:
/// refit every model fitted on a whole series now).
pub(super) struct ModelServers {
    pub(super) predict: Server<PredictRequest, PredictResponse>,
    pub(super) save: Server<EmptyRequest, TriggerResponse>,
    pub(super) refit: Server<EmptyRequest, TriggerResponse>,
}

impl ModelServers {
    pub(super) fn new(b: &mut Builder<'_>, setup: &Setup, poll: &Poll) -> Result<Self, NodeError> {
        let mut servers = ModelServers {
            predict: b.server(setup, "predict", "chronomap_msgs", "Predict")?,
            save: b.server(setup, "save", "std_srvs", "Trigger")?,
            refit: b.server(setup, "refit", "std_srvs", "Trigger")?,
        };
        let r = poll.registry();
        let t = Token(usize::MAX - 3);
        r.register(&mut servers.predict, t, Interest::READABLE)?;
        r.register(&mut servers.save, t, Interest::READABLE)?;
        r.register(&mut servers.refit, t, Interest::READABLE)?;
        Ok(servers)
    }
}

/// The answer of `~/predict` from `world` (`None`: the node is not configured).
pub(super) fn predict_answer(world: Option<&World>, request: &PredictRequest) -> PredictResponse {
    let refuse = |message: String| PredictResponse {
        success: false,
        message,
        ..PredictResponse::default()
    };
    let Some(world) = world else {
        return refuse("the node is not configured (lifecycle configure first)".into());
    };
    let states = &world.config().states;
    let Some(index) = states.iter().position(|s| s.name == request.name) else {
        let names: Vec<&str> = states.iter().map(|s| s.name.as_str()).collect();
        return refuse(format!(
            "no state {:?} (the states: {})",
            request.name,
            if names.is_empty() {
                "none".to_string()
            } else {
                names.join(", ")
            }
        ));
    };
    if request.times.len() > MAX_PREDICT_TIMES {
        return refuse(format!(
            "{} times is more than {MAX_PREDICT_TIMES} in one request",
            request.times.len()
        ));
    }
    if let Some(t) = request.times.iter().find(|t| t.nanosec >= 1_000_000_000) {
        return refuse(format!(
            "nanosec {} is not below 1,000,000,000 (builtin_interfaces/msg/Time)",
            t.nanosec
        ));
    }
    let (probability, entropy) = request
        .times
        .iter()
        .map(|t| world.predict_state(index, t.seconds()))
        .unzip();
    // The intervals of a state with them (empty lists and coverage 0 otherwise).
    let (coverage, (lower, upper)) = if world.state_has_interval(index) {
        let intervals = request
            .times
            .iter()
            .filter_map(|t| world.state_interval(index, t.seconds()));
        (states[index].coverage, intervals.unzip())
    } else {
        (0.0, (Vec::new(), Vec::new()))
    };
    PredictResponse {
        success: true,
        message: String::new(),
        model: states[index].model.to_string(),
        probability,
        entropy,
        coverage,
        lower,
        upper,
    }
}

/// The five `lifecycle_msgs` services and `~/transition_event`.
pub(super) struct LifecycleServers {
    pub(super) change: Server<ChangeStateRequest, ChangeStateResponse>,
    pub(super) get: Server<EmptyRequest, GetStateResponse>,
    pub(super) states: Server<EmptyRequest, GetAvailableStatesResponse>,
    pub(super) transitions: Server<EmptyRequest, GetAvailableTransitionsResponse>,
    pub(super) graph: Server<EmptyRequest, GetAvailableTransitionsResponse>,
    pub(super) events: Publisher<TransitionEvent>,
}

impl LifecycleServers {
    pub(super) fn new(b: &mut Builder<'_>, setup: &Setup, poll: &Poll) -> Result<Self, NodeError> {
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

pub(super) fn state_msg(state: State) -> LifecycleState {
    LifecycleState {
        id: state.id(),
        label: state.label().to_string(),
    }
}

pub(super) fn description(t: &lifecycle::Transition) -> TransitionDescription {
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
pub(super) fn serve<Q, A>(server: &Server<Q, A>, what: &str, mut answer: impl FnMut(Q) -> A)
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

/// `list_parameters` as rclcpp answers it: with no prefixes, the names with fewer than `depth`
/// dots (0: all); otherwise the names equal to a prefix or under `prefix.` within `depth`
/// more levels; `prefixes` are the distinct namespaces of the names listed.
pub(super) fn list_parameters<'a>(
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
pub(super) fn describe_parameter(name: &str, value: Option<&Value>) -> raw::ParameterDescriptor {
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

#[cfg(test)]
mod tests {
    use super::*;
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
    fn predict_answers_a_state_at_given_times_or_says_why_not() {
        use crate::config::NodeConfig;
        use crate::msgs::Time;
        let text = "chronomap:\n  ros__parameters:\n    states:\n      door: {topic: /door, type: std_msgs/msg/Bool, model: fremen:2}\n      light: {topic: /light, type: std_msgs/msg/Bool, model: hist:24}\n      level: {topic: /level, type: std_msgs/msg/Float64, model: hist:24, coverage: 0.8}\n";
        let config = NodeConfig::parse("node.yaml".as_ref(), text.as_bytes(), None).unwrap();
        let mut world = World::new(config).unwrap();
        for k in 0..500 {
            let t = 1_450_000_000.0 + f64::from(k) * 600.0;
            let open = (t / 3600.0).rem_euclid(24.0) > 8.0;
            world
                .observe_state(0, t, if open { 1.0 } else { 0.0 })
                .unwrap();
            // States are in the order of their names: door, level, light.
            let level = f64::from(k % 5) / 4.0 * if open { 1.0 } else { 0.5 };
            world.observe_state(1, t, level).unwrap();
        }
        let at = |sec: i32| Time { sec, nanosec: 0 };
        let request = |name: &str, times: Vec<Time>| PredictRequest {
            name: name.into(),
            times,
        };
        let answer = predict_answer(
            Some(&world),
            &request("door", vec![at(1_450_400_000), at(1_450_430_000)]),
        );
        assert!(answer.success, "{answer:?}");
        assert_eq!(answer.model, "fremen:2");
        for (i, t) in [1_450_400_000.0, 1_450_430_000.0].into_iter().enumerate() {
            let (p, h) = world.predict_state(0, t);
            assert_eq!(answer.probability[i].to_bits(), p.to_bits());
            assert_eq!(answer.entropy[i].to_bits(), h.to_bits());
        }
        assert_ne!(answer.probability[0], answer.probability[1]);
        // A Bool state has no interval; a Float64 one its intervals at each time.
        assert_eq!(answer.coverage, 0.0);
        assert!(answer.lower.is_empty() && answer.upper.is_empty());
        let times = [1_450_400_000.0, 1_450_430_000.0];
        let level = predict_answer(
            Some(&world),
            &request("level", vec![at(1_450_400_000), at(1_450_430_000)]),
        );
        assert_eq!(level.coverage, 0.8);
        for (i, t) in times.into_iter().enumerate() {
            let (lo, hi) = world.state_interval(1, t).unwrap();
            assert_eq!(level.lower[i].to_bits(), lo.to_bits());
            assert_eq!(level.upper[i].to_bits(), hi.to_bits());
            assert!(lo < level.probability[i] && level.probability[i] < hi);
        }
        // The light has learned nothing: 0.5, one bit.
        let light = predict_answer(Some(&world), &request("light", vec![at(5)]));
        assert_eq!((light.probability[0], light.entropy[0]), (0.5, 1.0));
        let refused = [
            (
                predict_answer(Some(&world), &request("window", vec![at(5)])),
                "no state \"window\" (the states: door, level, light)",
            ),
            (
                predict_answer(
                    Some(&world),
                    &request(
                        "door",
                        vec![Time {
                            sec: 5,
                            nanosec: 1_000_000_000,
                        }],
                    ),
                ),
                "nanosec 1000000000 is not below 1,000,000,000",
            ),
            (
                predict_answer(None, &request("door", vec![])),
                "the node is not configured",
            ),
        ];
        for (answer, why) in refused {
            assert!(
                !answer.success && answer.message.starts_with(why),
                "{answer:?}"
            );
            assert!(answer.probability.is_empty());
        }
        let many = predict_answer(
            Some(&world),
            &request("door", vec![at(0); MAX_PREDICT_TIMES + 1]),
        );
        assert!(
            many.message.contains("more than 100000 in one request"),
            "{many:?}"
        );
    }
}
