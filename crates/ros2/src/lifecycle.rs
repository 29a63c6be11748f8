//! The managed-node state machine of REP-2002 (ROS 2 "lifecycle" nodes), as `rcl_lifecycle`
//! defines it: four primary states (unconfigured, inactive, active, finalized), six transition
//! states, and the transitions between them with the ids and labels of `lifecycle_msgs`.
//! `nav2_lifecycle_manager`, `ros2 lifecycle` and launch's lifecycle events drive a node
//! through its `change_state` service with these ids.
//!
//! Pure: [`Machine`] says which transition a request starts and where a transition's callback
//! result leads; the node runs the callbacks (configure: read the parameters, restore the
//! models, create the subscriptions and publishers; activate; ...) and publishes the
//! `transition_event`s.
//!
//! ```
//! use chronomap_ros2::lifecycle::{Machine, Outcome, State};
//!
//! let mut machine = Machine::default();
//! assert_eq!(machine.state(), State::Unconfigured);
//! let configure = machine.start(1, "")?; // lifecycle_msgs/msg/Transition TRANSITION_CONFIGURE
//! assert_eq!(machine.state(), State::Configuring);
//! let done = machine.finish(Outcome::Success);
//! assert_eq!((configure.label, done.goal, machine.state()), ("configure", State::Inactive, State::Inactive));
//! assert!(machine.start(0, "deactivate").is_err()); // not from inactive
//! # Ok::<(), String>(())
//! ```

/// A state of `lifecycle_msgs/msg/State`, with its id.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum State {
    /// 0: not a state a node is in.
    Unknown = 0,
    /// 1: created, not configured.
    Unconfigured = 1,
    /// 2: configured, not processing.
    Inactive = 2,
    /// 3: processing.
    Active = 3,
    /// 4: shut down, waiting to be destroyed.
    Finalized = 4,
    /// 10: running `on_configure`.
    Configuring = 10,
    /// 11: running `on_cleanup`.
    CleaningUp = 11,
    /// 12: running `on_shutdown`.
    ShuttingDown = 12,
    /// 13: running `on_activate`.
    Activating = 13,
    /// 14: running `on_deactivate`.
    Deactivating = 14,
    /// 15: running `on_error`.
    ErrorProcessing = 15,
}

impl State {
    /// Every state, in the order `get_available_states` lists them.
    pub const ALL: [State; 11] = [
        State::Unknown,
        State::Unconfigured,
        State::Inactive,
        State::Active,
        State::Finalized,
        State::Configuring,
        State::CleaningUp,
        State::ShuttingDown,
        State::Activating,
        State::Deactivating,
        State::ErrorProcessing,
    ];

    /// The id of `lifecycle_msgs/msg/State`.
    pub fn id(self) -> u8 {
        self as u8
    }

    /// The label rcl_lifecycle gives it.
    pub fn label(self) -> &'static str {
        match self {
            State::Unknown => "unknown",
            State::Unconfigured => "unconfigured",
            State::Inactive => "inactive",
            State::Active => "active",
            State::Finalized => "finalized",
            State::Configuring => "configuring",
            State::CleaningUp => "cleaningup",
            State::ShuttingDown => "shuttingdown",
            State::Activating => "activating",
            State::Deactivating => "deactivating",
            State::ErrorProcessing => "errorprocessing",
        }
    }

    /// Whether it is a primary state (the node rests in it).
    pub fn is_primary(self) -> bool {
        self.id() <= 4
    }
}

/// A transition of the graph (`lifecycle_msgs/msg/TransitionDescription`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transition {
    /// The id of `lifecycle_msgs/msg/Transition`.
    pub id: u8,
    /// Its label.
    pub label: &'static str,
    /// Where it starts.
    pub start: State,
    /// Where it leads.
    pub goal: State,
}

const fn t(id: u8, label: &'static str, start: State, goal: State) -> Transition {
    Transition {
        id,
        label,
        start,
        goal,
    }
}

use State::{
    Activating, Active, CleaningUp, Configuring, Deactivating, ErrorProcessing, Finalized,
    Inactive, ShuttingDown, Unconfigured,
};

/// The transition graph, in the order `rcl_lifecycle` lists it (`get_transition_graph` of an
/// rclpy 9.1.2 `LifecycleNode`, probed): the transitions a request starts (ids 1-7) and those
/// a callback's result takes (10-62: success, failure, error).
pub const GRAPH: [Transition; 25] = [
    t(1, "configure", Unconfigured, Configuring),
    t(10, "transition_success", Configuring, Inactive),
    t(11, "transition_failure", Configuring, Unconfigured),
    t(12, "transition_error", Configuring, ErrorProcessing),
    t(2, "cleanup", Inactive, CleaningUp),
    t(20, "transition_success", CleaningUp, Unconfigured),
    t(21, "transition_failure", CleaningUp, Inactive),
    t(22, "transition_error", CleaningUp, ErrorProcessing),
    t(3, "activate", Inactive, Activating),
    t(30, "transition_success", Activating, Active),
    t(31, "transition_failure", Activating, Inactive),
    t(32, "transition_error", Activating, ErrorProcessing),
    t(4, "deactivate", Active, Deactivating),
    t(40, "transition_success", Deactivating, Inactive),
    t(41, "transition_failure", Deactivating, Active),
    t(42, "transition_error", Deactivating, ErrorProcessing),
    t(5, "shutdown", Unconfigured, ShuttingDown),
    t(6, "shutdown", Inactive, ShuttingDown),
    t(7, "shutdown", Active, ShuttingDown),
    t(50, "transition_success", ShuttingDown, Finalized),
    t(51, "transition_failure", ShuttingDown, Finalized),
    t(52, "transition_error", ShuttingDown, ErrorProcessing),
    t(60, "transition_success", ErrorProcessing, Unconfigured),
    t(61, "transition_failure", ErrorProcessing, Finalized),
    t(62, "transition_error", ErrorProcessing, Finalized),
];

/// What a transition's callback returned (`lifecycle_msgs` `TRANSITION_CALLBACK_*`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// It did what it should.
    Success,
    /// It could not (the node stays where it was, or goes back).
    Failure,
    /// It failed in a way that needs error processing.
    Error,
}

/// The transitions a request may start from `state` (`get_available_transitions`).
pub fn available(state: State) -> Vec<Transition> {
    GRAPH
        .iter()
        .filter(|t| t.start == state && t.id < 10)
        .copied()
        .collect()
}

/// Where a node is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Machine {
    state: State,
}

impl Default for Machine {
    /// A node just created: unconfigured.
    fn default() -> Self {
        Machine {
            state: State::Unconfigured,
        }
    }
}

impl Machine {
    /// The current state.
    pub fn state(&self) -> State {
        self.state
    }

    /// Starts the transition a `change_state` request asks for: by `id`, or by `label` when
    /// `id` is 0 (`TRANSITION_CREATE`) and a label is given, as rclcpp does. The node is then
    /// in the transition state.
    ///
    /// # Errors
    /// No such transition from the current state (the message rcl_lifecycle logs).
    pub fn start(&mut self, id: u8, label: &str) -> Result<Transition, String> {
        let by_label = id == 0 && !label.is_empty();
        let found = available(self.state).into_iter().find(|t| {
            if by_label {
                t.label == label
            } else {
                t.id == id
            }
        });
        match found {
            Some(t) => {
                self.state = t.goal;
                Ok(t)
            }
            None => Err(format!(
                "no transition matching {} found for current state {}",
                if by_label {
                    label.to_string()
                } else {
                    id.to_string()
                },
                self.state.label()
            )),
        }
    }

    /// Ends the running transition with its callback's `outcome`: the transition taken.
    ///
    /// # Panics
    /// If the node is not in a transition state.
    pub fn finish(&mut self, outcome: Outcome) -> Transition {
        let offset = match outcome {
            Outcome::Success => 0,
            Outcome::Failure => 1,
            Outcome::Error => 2,
        };
        let base = match self.state {
            State::Configuring => 10,
            State::CleaningUp => 20,
            State::Activating => 30,
            State::Deactivating => 40,
            State::ShuttingDown => 50,
            State::ErrorProcessing => 60,
            other => panic!("finish in the primary state {}", other.label()),
        };
        let transition = GRAPH
            .iter()
            .find(|t| t.id == base + offset)
            .copied()
            .expect("every transition state has its three results");
        self.state = transition.goal;
        transition
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `get_available_transitions` of an rclpy 9.1.2 `LifecycleNode` in each primary state
    /// (probed), as (id, label, start id, goal id).
    #[test]
    fn available_transitions_are_those_of_rcl_lifecycle() {
        let ids = |s: State| {
            available(s)
                .iter()
                .map(|t| (t.id, t.label, t.start.id(), t.goal.id()))
                .collect::<Vec<_>>()
        };
        assert_eq!(
            ids(Unconfigured),
            [(1, "configure", 1, 10), (5, "shutdown", 1, 12)]
        );
        assert_eq!(
            ids(Inactive),
            [
                (2, "cleanup", 2, 11),
                (3, "activate", 2, 13),
                (6, "shutdown", 2, 12)
            ]
        );
        assert_eq!(
            ids(Active),
            [(4, "deactivate", 3, 14), (7, "shutdown", 3, 12)]
        );
        assert!(ids(Finalized).is_empty());
        let labels: Vec<(u8, &str)> = State::ALL.iter().map(|s| (s.id(), s.label())).collect();
        assert_eq!(
            labels,
            [
                (0, "unknown"),
                (1, "unconfigured"),
                (2, "inactive"),
                (3, "active"),
                (4, "finalized"),
                (10, "configuring"),
                (11, "cleaningup"),
                (12, "shuttingdown"),
                (13, "activating"),
                (14, "deactivating"),
                (15, "errorprocessing")
            ]
        );
    }

    /// The cycle nav2_lifecycle_manager drives (configure, activate, deactivate, cleanup),
    /// then a shutdown by label, as rclpy answered it.
    #[test]
    fn a_managed_cycle_goes_through_the_transition_states() {
        let mut m = Machine::default();
        // rclpy: "activate from unconfigured" is refused and changes nothing.
        assert_eq!(
            m.start(3, "").unwrap_err(),
            "no transition matching 3 found for current state unconfigured"
        );
        assert_eq!(m.state(), Unconfigured);
        let mut path = Vec::new();
        for (id, label) in [(1, ""), (0, "activate"), (4, ""), (2, "")] {
            let started = m.start(id, label).unwrap();
            path.push((started.id, m.state()));
            let done = m.finish(Outcome::Success);
            path.push((done.id, m.state()));
        }
        assert_eq!(
            path,
            [
                (1, Configuring),
                (10, Inactive),
                (3, Activating),
                (30, Active),
                (4, Deactivating),
                (40, Inactive),
                (2, CleaningUp),
                (20, Unconfigured)
            ]
        );
        // "shutdown" by label picks the shutdown of the current state (5 from unconfigured).
        assert_eq!(m.start(0, "shutdown").unwrap().id, 5);
        assert_eq!(m.finish(Outcome::Failure).goal, Finalized);
        assert!(m.start(0, "configure").is_err());
        assert!(m.start(0, "bogus").unwrap_err().contains("bogus"));
    }

    #[test]
    fn failures_go_back_and_errors_go_through_error_processing() {
        let mut m = Machine::default();
        m.start(1, "").unwrap();
        assert_eq!(m.finish(Outcome::Failure).id, 11);
        assert_eq!(m.state(), Unconfigured);
        m.start(1, "").unwrap();
        assert_eq!(m.finish(Outcome::Error).goal, ErrorProcessing);
        assert_eq!(m.finish(Outcome::Success).id, 60);
        assert_eq!(m.state(), Unconfigured);
        // id 5 (unconfigured shutdown) is not the shutdown of an active node (7).
        m.start(1, "").unwrap();
        m.finish(Outcome::Success);
        m.start(3, "").unwrap();
        m.finish(Outcome::Success);
        assert!(m.start(5, "").is_err());
        assert_eq!(m.start(7, "").unwrap().goal, ShuttingDown);
    }
}
