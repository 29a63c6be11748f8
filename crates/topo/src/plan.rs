//! "Now or later?": plan a co-safe navigation task at any time from the edge models
//! ([Fentanes 2015] §V–VI).
//!
//! At time `t` the edge models give every edge's success probability `p_e(t)` and expected
//! duration; these make the Navigation MDP `M_t` ([`crate::mdp::NavigationMdp`]), whose product
//! with the task's automaton is solved for the maximum probability of fulfilling the task and
//! the least expected time among the policies achieving it. Doing this for many times of day
//! gives the table of [Fentanes 2015] Table III: when to start, and which way to go.
//!
//! ```
//! use chronomap_topo::edges::{Attempt, EdgeModelConfig, EdgeModels};
//! use chronomap_topo::plan::{Task, plan_at};
//! use chronomap_topo::mdp::SolverOptions;
//! use chronomap_topo::map::TopoMap;
//!
//! let mut map = TopoMap::new();
//! for node in ["Office", "Door", "Lab"] {
//!     map.add_node(node, None)?;
//! }
//! map.add_edge("Office_Door", "Office", "Door")?;
//! map.add_edge("Door_Lab", "Door", "Lab")?;
//! // The door is open afternoons only (attempts every 30 min for two weeks).
//! let door: Vec<Attempt> = (0..14 * 48)
//!     .map(|i| {
//!         let time = 1800.0 * i as f64;
//!         let afternoon = (time % 86_400.0) >= 43_200.0;
//!         Attempt { time, duration_secs: 20.0, success: afternoon }
//!     })
//!     .collect();
//! let always: Vec<Attempt> =
//!     door.iter().map(|a| Attempt { success: true, ..*a }).collect();
//! let models = EdgeModels::fit(map, &[always, door], EdgeModelConfig::default())
//!     .map_err(|(edge, e)| format!("{edge}: {e}"))?;
//!
//! let task = Task::parse("F Lab", models.map())?;
//! let office = models.map().node("Office")?;
//! let morning = plan_at(&models, office, &task, 15.0 * 86_400.0 + 8.0 * 3600.0, &SolverOptions::default())?;
//! let afternoon = plan_at(&models, office, &task, 15.0 * 86_400.0 + 16.0 * 3600.0, &SolverOptions::default())?;
//! assert!(morning.pmax < 0.3 && afternoon.pmax > 0.8);
//! assert_eq!(afternoon.first_edge, Some(0)); // Office_Door
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::automaton::Dfa;
use crate::edges::EdgeModels;
use crate::ltl::{self, Ltl, LtlError};
use crate::map::{TopoError, TopoMap};
use crate::mdp::{MdpError, NavigationMdp, ProductMdp, Solution, SolverOptions};

/// Why a task could not be planned.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum PlanError {
    /// The task is not a co-safe LTL formula (the error shows where).
    #[error(transparent)]
    Task(#[from] LtlError),
    /// The task or the start names a node the map does not have.
    #[error(transparent)]
    Node(#[from] TopoError),
    /// The MDP could not be built or solved.
    #[error(transparent)]
    Mdp(#[from] MdpError),
}

/// A co-safe LTL task whose atoms are nodes of a map, with its automaton.
#[derive(Clone, Debug, PartialEq)]
pub struct Task {
    text: String,
    formula: Ltl,
    dfa: Dfa,
}

impl Task {
    /// Parses `text` (see [`crate::ltl`] for the syntax), checks that every atom is a node of
    /// `map`, and builds the automaton.
    ///
    /// # Errors
    /// [`PlanError::Task`] for a malformed or not co-safe formula (with its position),
    /// [`PlanError::Node`] for an atom that is not a node (with the closest node name).
    pub fn parse(text: &str, map: &TopoMap) -> Result<Self, PlanError> {
        let formula = ltl::parse_co_safe(text)?;
        for atom in ltl::atoms(&formula) {
            map.node(&atom)?;
        }
        let dfa = ltl::to_dfa(&formula)?;
        Ok(Task {
            text: text.to_string(),
            formula,
            dfa,
        })
    }

    /// The formula as written.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// The parsed formula.
    pub fn formula(&self) -> &Ltl {
        &self.formula
    }

    /// The automaton.
    pub fn dfa(&self) -> &Dfa {
        &self.dfa
    }
}

/// The plan for one start time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanAt {
    /// The start time.
    pub time: f64,
    /// Maximum probability of fulfilling the task.
    pub pmax: f64,
    /// Expected time (seconds) until the task is fulfilled or has failed, following the
    /// policy (least among the `pmax`-optimal policies).
    pub expected_secs: f64,
    /// The first edge to take (`None`: the task holds already, or cannot be fulfilled).
    pub first_edge: Option<usize>,
}

/// The Navigation MDP at `time`, its product with the task from `start`, and its solution.
pub struct Planned {
    /// The Navigation MDP `M_t`.
    pub mdp: NavigationMdp,
    /// Its product with the task's automaton.
    pub product: ProductMdp,
    /// Pmax, expected costs and the policy.
    pub solution: Solution,
    /// The summary.
    pub plan: PlanAt,
}

/// Builds and solves the Navigation MDP at `time` ([Fentanes 2015] §V) for `task` from node `start`.
///
/// # Errors
/// [`PlanError::Mdp`] if the models' predictions make an invalid MDP (they cannot, unless a
/// model was edited by hand) or the solver does not converge.
pub fn plan_full(
    models: &EdgeModels,
    start: usize,
    task: &Task,
    time: f64,
    options: &SolverOptions,
) -> Result<Planned, PlanError> {
    let (success, duration) = models.at(time);
    let mdp = NavigationMdp::new(models.map(), &success, &duration)?;
    let product = mdp.product(start, &task.dfa)?;
    let solution = product.solve(options)?;
    let plan = PlanAt {
        time,
        pmax: solution.pmax_initial,
        expected_secs: solution.cost_initial,
        first_edge: solution.policy[solution.initial],
    };
    Ok(Planned {
        mdp,
        product,
        solution,
        plan,
    })
}

/// The plan for `task` from `start` at `time`: [`plan_full`] without the MDPs.
///
/// # Errors
/// As [`plan_full`].
pub fn plan_at(
    models: &EdgeModels,
    start: usize,
    task: &Task,
    time: f64,
    options: &SolverOptions,
) -> Result<PlanAt, PlanError> {
    Ok(plan_full(models, start, task, time, options)?.plan)
}

/// "Now or later?": the plan at each of `times` ([Fentanes 2015] Table III).
///
/// # Errors
/// As [`plan_full`].
pub fn now_or_later(
    models: &EdgeModels,
    start: usize,
    task: &Task,
    times: &[f64],
    options: &SolverOptions,
) -> Result<Vec<PlanAt>, PlanError> {
    times
        .iter()
        .map(|&t| plan_at(models, start, task, t, options))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::edges::{Attempt, EdgeModelConfig};

    /// Office → Lab either through a door (10 s, open 12:00–24:00) or round a corridor
    /// (3 × 30 s, always passable).
    fn office() -> EdgeModels {
        let mut map = TopoMap::new();
        for n in ["Office", "Door", "Lab", "C1", "C2"] {
            map.add_node(n, None).unwrap();
        }
        let edges = [
            ("Office_Door", "Office", "Door"),
            ("Door_Lab", "Door", "Lab"),
            ("Office_C1", "Office", "C1"),
            ("C1_C2", "C1", "C2"),
            ("C2_Lab", "C2", "Lab"),
        ];
        for (id, a, b) in edges {
            map.add_edge(id, a, b).unwrap();
        }
        let attempts = |duration: f64, door: bool| -> Vec<Attempt> {
            (0..21 * 24)
                .map(|i| {
                    let time = 3600.0 * f64::from(i) + 600.0;
                    let open = (time % 86_400.0) >= 43_200.0;
                    Attempt {
                        time,
                        duration_secs: duration,
                        success: !door || open,
                    }
                })
                .collect()
        };
        let data = [
            attempts(5.0, false),
            attempts(5.0, true),
            attempts(30.0, false),
            attempts(30.0, false),
            attempts(30.0, false),
        ];
        // The planner is under test, not the choice of orders: a square wave needs the
        // sharpest model available.
        let config = EdgeModelConfig {
            persistence: false,
            success_order: Some(10),
            ..EdgeModelConfig::default()
        };
        EdgeModels::fit(map, &data, config).unwrap()
    }

    #[test]
    fn the_door_is_taken_when_open_and_the_corridor_when_closed() {
        let models = office();
        let task = Task::parse("F Lab", models.map()).unwrap();
        let start = models.map().node("Office").unwrap();
        let day = 22.0 * 86_400.0;
        let times: Vec<f64> = (0..24)
            .map(|h| day + 3600.0 * f64::from(h) + 600.0)
            .collect();
        let table = now_or_later(&models, start, &task, &times, &SolverOptions::default()).unwrap();
        let corridor = models
            .map()
            .edges()
            .iter()
            .position(|e| e.id == "Office_C1");
        let door = models
            .map()
            .edges()
            .iter()
            .position(|e| e.id == "Office_Door");
        for (hour, plan) in table.iter().enumerate() {
            // The corridor always succeeds (shrunk towards the prior 0.9 by 2 of 506 attempts).
            assert!(plan.pmax > 0.99, "{hour}: {plan:?}");
            let expected = if (13..23).contains(&hour) {
                door
            } else {
                corridor
            };
            if (1..11).contains(&hour) || (13..23).contains(&hour) {
                assert_eq!(plan.first_edge, expected, "{hour}: {plan:?}");
            }
        }
        // Through the open door: 5 + 5 s; round the corridor: 90 s.
        assert!(table[18].expected_secs < 15.0, "{:?}", table[18]);
        assert!(table[6].expected_secs > 85.0, "{:?}", table[6]);
    }

    #[test]
    fn tasks_naming_unknown_nodes_or_malformed_are_errors() {
        let models = office();
        let err = Task::parse("F Lba", models.map()).unwrap_err();
        assert!(err.to_string().contains("did you mean \"Lab\""), "{err}");
        let err = Task::parse("F (Lab", models.map()).unwrap_err();
        assert!(matches!(err, PlanError::Task(_)), "{err}");
        assert!(err.to_string().contains('^'), "{err}");
        let err = Task::parse("G Lab", models.map()).unwrap_err();
        assert!(err.to_string().contains("co-safe"), "{err}");
    }
}
