//! The node on the DDS network (ros2-client on RustDDS): subscriptions, publishers, the clock,
//! schedules, the checks of what publishers send, and the node's ROS interfaces — parameter
//! services, `/rosout`, and, managed, the lifecycle services. Messages become calls of
//! [`World`](crate::World) and its predictions become messages; nothing is computed here.
//!
//! One thread does everything, in rounds of at most 20 ms. Each round it answers the
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
//! Configure checks the parameters, restores the models ([`World::new`](crate::World::new)) and creates the
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
//! 30 s with the count of those refused since (`Throttle`).

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::dds::rustdds::mio1::{Events, Poll};
use ros2_client::parameters::raw;
use ros2_client::rcl_interfaces::{
    DescribeParametersResponse, GetParameterTypesResponse, GetParametersResponse,
    ListParametersResponse, SetParametersAtomicallyResponse, SetParametersResponse,
};
use ros2_client::{Context, Node, NodeName, NodeOptions, Publisher};
use thiserror::Error;

use crate::config::{self, ConfigError, NodeConfig, Setup};
use crate::lifecycle::{self, Machine, Outcome, State};
use crate::msgs::{
    ChangeStateResponse, GetAvailableStatesResponse, GetAvailableTransitionsResponse,
    GetStateResponse, LifecycleTransition, TransitionEvent, TriggerResponse,
};
use crate::params::{self, Origin, Value};
use crate::rosout;
use crate::world::{Learned, StoreError};

mod clock;
mod configured;
mod io;
mod refits;
mod services;
mod throttle;

use clock::system_now_ns;
use configured::Configured;
use io::Builder;
use services::{
    LifecycleServers, ModelServers, ParamServers, describe_parameter, description, list_parameters,
    predict_answer, serve, state_msg,
};

/// Bytes a message may have beside `max_map_cells` cells: the largest sample the node takes
/// from DDS is `max_map_cells` + this (an OccupancyGrid's header and metadata, a long
/// `frame_id`).
const MAX_HEADER_BYTES: usize = 64 * 1024;
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
    Poll(std::io::Error),
    /// The parameters cannot be used.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The saved models cannot be restored.
    #[error("cannot restore the models: {0}")]
    Restore(StoreError),
}

// Not `#[from]`: the message holds the cause, so it is not repeated as a further error of the
// chain (`error: {:#}` prints the chain).
impl From<std::io::Error> for NodeError {
    fn from(e: std::io::Error) -> Self {
        NodeError::Poll(e)
    }
}

impl From<StoreError> for NodeError {
    fn from(e: StoreError) -> Self {
        NodeError::Restore(e)
    }
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
                "node {} on DDS domain {}: {} state, {} grid topics{}{}{}",
                config.fully_qualified_name(),
                self.domain_id,
                config.states.len(),
                config.grids.len(),
                if config.edges.is_some() {
                    ", a route graph"
                } else {
                    ""
                },
                match &config.days_off_file {
                    Some(file) => format!(
                        ", {} days off for the states ({})",
                        config.days_off.len(),
                        file.display()
                    ),
                    None => String::new(),
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

    /// Answers `~/predict` and `~/save`.
    fn serve_models(&mut self, s: &ModelServers) {
        serve(&s.predict, "predict", |request| {
            predict_answer(self.configured.as_ref().map(|c| &c.world), &request)
        });
        serve(&s.save, "save", |_| match &mut self.configured {
            None => TriggerResponse {
                success: false,
                message: "the node is not configured (lifecycle configure first)".into(),
            },
            Some(c) => match c.world.save(false) {
                Ok(Some(saved)) => {
                    c.last_save = std::time::Instant::now();
                    TriggerResponse {
                        success: true,
                        message: saved.to_string(),
                    }
                }
                Ok(None) => TriggerResponse {
                    success: false,
                    message: "nothing to save: the node has no save_dir".into(),
                },
                Err(e) => {
                    log::error!("save: {e}");
                    TriggerResponse {
                        success: false,
                        message: e.to_string(),
                    }
                }
            },
        });
    }

    /// Answers `~/refit`: every model fitted on a whole series is refitted at the next
    /// round; the outcome is logged.
    fn serve_refit(&mut self, s: &ModelServers) {
        serve(&s.refit, "refit", |_| match &mut self.configured {
            None => TriggerResponse {
                success: false,
                message: "the node is not configured (lifecycle configure first)".into(),
            },
            Some(c) => {
                let names = c.refits.request(&c.world);
                if names.is_empty() {
                    TriggerResponse {
                        success: false,
                        message: "no state is refitted: every model learns online".into(),
                    }
                } else {
                    TriggerResponse {
                        success: true,
                        message: format!(
                            "refits of states.{} start now; their outcome is logged",
                            names.join(", states.")
                        ),
                    }
                }
            }
        });
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
    // Larger samples are dropped by RustDDS at their first fragment, before memory is
    // allocated for them, with one error line naming the topic and the size (vendor/README.md).
    let max_sample_bytes = usize::try_from(initial.max_map_cells)
        .unwrap_or(usize::MAX)
        .saturating_add(MAX_HEADER_BYTES);
    let participant = DomainParticipantBuilder::new(options.domain_id)
        .max_sample_size(max_sample_bytes)
        .build()
        .map_err(|e| NodeError::Dds(format!("cannot join domain {}: {e}", options.domain_id)))?;
    let context = Context::from_domain_participant(participant)
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
        let model_servers = ModelServers::new(&mut b, &self.setup, &self.poll)?;
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
            self.serve_models(&model_servers);
            self.serve_refit(&model_servers);
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
