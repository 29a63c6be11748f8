//! Navigation MDPs at a time `t` ([Fentanes 2015] §V), their product with a task automaton, and the
//! solvers that turn them into policies: maximum probability of fulfilling the task, then the
//! least expected time among the policies that achieve it.
//!
//! # The Navigation MDP at time `t` ([Fentanes 2015] §V)
//! A topological map `T = ⟨V, E, …⟩` and, per edge `e`, the predicted probability `p_e(t)` that
//! navigating it succeeds and its expected duration give [`NavigationMdp`]
//! `M_t = ⟨S, s̄, A, δ⟩`: states `S = V ∪ {s_f}` (the nodes plus the *dump* state `s_f`
//! reached after a navigation failure, [`NavigationMdp::sink`]), actions `A = E` (the edges
//! leaving a node), and for an edge `e = (v_i, v_j)`: `δ(v_i, e, v_j) = p_e(t)`,
//! `δ(v_i, e, s_f) = 1 − p_e(t)` (outcomes of probability zero are left out). Taking `e` costs
//! its duration (seconds), whatever the outcome. `s_f` has no actions.
//!
//! # Product with a task automaton
//! A co-safe task is a [`Dfa`] over node names (see [`crate::automaton`] for the alphabet).
//! [`NavigationMdp::product`] builds the part of `M_t ⊗ A` reachable from
//! `(s̄, next(q₀, letter(s̄)))`: taking `e` in `(s, q)` leads to `(s', next(q, letter(s')))`
//! with probability `δ(s, e, s')`, where the sink reads the letter "no atom". States whose
//! automaton state is accepting are *goal* states; they are absorbing and get no choices.
//! A state without actions (the sink, a node without leaving edges) keeps the robot where it
//! is forever, as PRISM and Storm read deadlocks: the automaton keeps reading the same letter,
//! so such a state is a goal state if that lasso passes through an accepting automaton state.
//!
//! # What is optimised ([`solve`], on any [`SparseMdp`] with goal states)
//! 1. `Pmax(s)`: the maximum probability of reaching a goal state (`Pmax=? [F "goal"]`; in a
//!    product, the probability of fulfilling the task), by value iteration from below after a
//!    graph analysis fixes the states with `Pmax = 0`, with an upper bound on the quotient by
//!    the maximal end components that certifies the precision ([`Solution::gap`]): first the
//!    optimistic guess `x + ε/2`, proved when a Bellman sweep does not raise it (optimistic
//!    value iteration, Hartmanns and Kaminski, CAV 2020; one sweep on the Witham products,
//!    25× faster than closing the gap from 1), else an interval iteration from 1.
//! 2. The *restricted* MDP keeps, in every state with `Pmax > 0` that is not a goal, the
//!    choices whose one-step value `Σ δ(s, c, s')·Pmax(s')` equals `Pmax(s)` — numerically,
//!    those within `max(ε·Pmax(s), gap)` of the best one (`ε` = [`SolverOptions::tolerance`],
//!    `1e-12`; widening to the certified gap keeps every truly optimal choice). The set `D`
//!    of *decided* states holds the goals and the states from which no goal is reachable in
//!    the restricted MDP (the failure sink, the states with `Pmax = 0`): there the outcome of
//!    the run is known.
//! 3. The *expected cost* is
//!    `C(s) = min_σ E_s^σ[ Σ_{k<T} cost(c_k) ]`, `T` the first time the run is in `D`, over
//!    the policies `σ` of the restricted MDP, where a policy with `P_s^σ(T < ∞) < 1` costs
//!    `+∞`. This is Storm's `R{"time"}min=? [F "decided"]` on the restricted product
//!    ([`restricted_drn`]; "decided" labels `D`), which follows the same `+∞` convention.
//!    `C(s) = +∞` (no restricted policy reaches `D` almost surely) cannot happen with exact
//!    values — a memoryless `Pmax`-optimal policy uses restricted choices only and ends,
//!    almost surely, in a goal or in a state with `Pmax = 0` — so it flags a numerical
//!    problem. Zero-cost cycles are handled (zero-cost end components are collapsed before the
//!    value iteration, which otherwise would stop at a too-low fixpoint).
//! 4. The policy picks, in every state that is not decided, the restricted choice of least
//!    expected cost `cost(c) + Σ δ(s, c, s')·C(s')`; ties go to the first choice (edge order in
//!    a product), except where that would loop forever through zero-cost choices: then the
//!    first tied choice that moves closer to a decided state is taken. The policy reaches the
//!    goal with probability `Pmax` and costs `C` in expectation.
//!
//! # Exports
//! [`NavigationMdp::to_prism`] writes the PRISM language in the layout of STRANDS
//! `mdp_plan_exec` (one `waypoint` variable, `-1` the failure sink, one command per edge
//! named by its id, one label per node, rewards `"time"`), [`prism_property`] the matching
//! `Pmax=? [ … ]` of a co-safe LTL formula (node names that read as operators, `F`, `G`, `X`,
//! `U`, `R`, `W`, must be quoted in the formula). [`SparseMdp::to_drn`], [`product_drn`] and
//! [`restricted_drn`] write Storm's explicit DRN format, so that Storm can check the product
//! without LTL (`tests/oracle/storm_check.py`).

mod export;
mod graph;
mod product;
mod solve;
mod sparse;
#[cfg(test)]
mod tests;

use thiserror::Error;

use crate::automaton::Dfa;
use crate::map::{Edge, TopoMap};

pub use export::{prism_property, product_drn, restricted_drn};
pub use product::{ProductMdp, ProductState};
pub use solve::{Iterations, Solution, SolverOptions, solve};
pub use sparse::{Choice, SparseMdp};

/// Why an MDP could not be built, solved or exported.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum MdpError {
    /// A per-edge (or per-state, per-choice) vector has the wrong length.
    #[error("{what} has {found} entries, expected {expected}")]
    LengthMismatch {
        /// What the vector holds.
        what: &'static str,
        /// The length it should have.
        expected: usize,
        /// The length it has.
        found: usize,
    },
    /// A success probability `p_e(t)` is NaN or outside `[0, 1]`.
    #[error("success probability {value} of edge {edge:?} is not in [0, 1]")]
    InvalidSuccess {
        /// The edge id.
        edge: String,
        /// The edge index.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// A duration is NaN, infinite or negative.
    #[error("duration {value} of edge {edge:?} is not a finite number of seconds >= 0")]
    InvalidDuration {
        /// The edge id.
        edge: String,
        /// The edge index.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// An edge of the map refers to a node the map does not have.
    #[error("edge {edge:?} refers to node {node}, but the map has {nodes} nodes")]
    EdgeOutOfRange {
        /// The edge id.
        edge: String,
        /// The offending node index.
        node: usize,
        /// Number of nodes of the map.
        nodes: usize,
    },
    /// A node index (the robot's position) is not a node of the map.
    #[error("node {node} does not exist (the map has {nodes} nodes)")]
    NodeOutOfRange {
        /// The offending index.
        node: usize,
        /// Number of nodes.
        nodes: usize,
    },
    /// A state index is out of range.
    #[error("{what} {state} does not exist (the MDP has {states} states)")]
    StateOutOfRange {
        /// What the index is (initial state, a target of state `s` choice `c`, …).
        what: String,
        /// The offending index.
        state: usize,
        /// Number of states.
        states: usize,
    },
    /// A choice refers to an action that has no name.
    #[error(
        "choice {choice} of state {state} has action {action}, but there are {actions} actions"
    )]
    ActionOutOfRange {
        /// The state.
        state: usize,
        /// Index of the choice among the state's choices.
        choice: usize,
        /// The offending action index.
        action: usize,
        /// Number of actions.
        actions: usize,
    },
    /// An outcome probability is NaN or outside `(0, 1]`.
    #[error("probability {value} of choice {choice} of state {state} is not in (0, 1]")]
    InvalidProbability {
        /// The state.
        state: usize,
        /// Index of the choice among the state's choices.
        choice: usize,
        /// The offending value.
        value: f64,
    },
    /// The outcome probabilities of a choice do not sum to one (within 1e-9).
    #[error("the probabilities of choice {choice} of state {state} sum to {sum}, not 1")]
    NotStochastic {
        /// The state.
        state: usize,
        /// Index of the choice among the state's choices.
        choice: usize,
        /// Their sum.
        sum: f64,
    },
    /// A choice has no outcome.
    #[error("choice {choice} of state {state} has no outcome")]
    NoOutcome {
        /// The state.
        state: usize,
        /// Index of the choice among the state's choices.
        choice: usize,
    },
    /// A cost is NaN, infinite or negative.
    #[error("cost {value} of choice {choice} of state {state} is not a finite number >= 0")]
    InvalidCost {
        /// The state.
        state: usize,
        /// Index of the choice among the state's choices.
        choice: usize,
        /// The offending value.
        value: f64,
    },
    /// The automaton's shape is inconsistent ([`Dfa::is_consistent`] is false).
    #[error("the task automaton is inconsistent (initial state, transition table or states)")]
    InconsistentDfa,
    /// A solver option is out of range.
    #[error("invalid solver option: {0}")]
    InvalidOptions(String),
    /// A value iteration did not converge within the iteration cap.
    #[error("{what} did not converge in {iterations} iterations (last change {change:e})")]
    NotConverged {
        /// Which iteration.
        what: &'static str,
        /// The cap reached.
        iterations: usize,
        /// The largest change of the last iteration.
        change: f64,
    },
    /// The solution was computed for another MDP.
    #[error("the solution has {found} states, the MDP {expected}")]
    SolutionMismatch {
        /// States of the MDP.
        expected: usize,
        /// States of the solution.
        found: usize,
    },
    /// A name cannot be written in the export format.
    #[error("{name:?} cannot be written as {role}: {reason}")]
    InvalidName {
        /// The name.
        name: String,
        /// What it names in the format (PRISM action, PRISM label, DRN label, …).
        role: &'static str,
        /// Why not.
        reason: &'static str,
    },
    /// A task formula cannot be turned into a PRISM property.
    #[error("cannot write the formula as a PRISM property: {0}")]
    InvalidFormula(String),
}

/// The Navigation MDP at time `t` of [Fentanes 2015] §V: nodes of a topological map plus the failure
/// sink `s_f`, the edges as actions, succeeding with `p_e(t)` and costing their duration.
///
/// State `i < node_count()` is node `i` of the map; state [`sink`](Self::sink)` = node_count()`
/// is `s_f`.
#[derive(Clone, Debug, PartialEq)]
pub struct NavigationMdp {
    names: Vec<String>,
    edges: Vec<Edge>,
    success: Vec<f64>,
    duration: Vec<f64>,
    /// Edges leaving node `v`: `out_edges[out_start[v]..out_start[v + 1]]`, in edge order.
    out_start: Vec<usize>,
    out_edges: Vec<usize>,
}

impl NavigationMdp {
    /// The Navigation MDP `M_t` of `map` with `success[e] = p_e(t)` and `duration[e]` (seconds)
    /// for every edge `e` of the map ([Fentanes 2015] §V, `δ(v_i, e, v_j) = p_e(t)`,
    /// `δ(v_i, e, s_f) = 1 − p_e(t)`).
    ///
    /// # Errors
    /// [`MdpError::LengthMismatch`] if a vector does not have one entry per edge,
    /// [`MdpError::InvalidSuccess`] for a probability that is NaN or outside `[0, 1]`,
    /// [`MdpError::InvalidDuration`] for a duration that is NaN, infinite or negative,
    /// [`MdpError::EdgeOutOfRange`] for an edge between nodes the map does not have.
    pub fn new(map: &TopoMap, success: &[f64], duration: &[f64]) -> Result<Self, MdpError> {
        let edges = map.edges();
        let nodes = map.nodes().len();
        for (what, found) in [("success", success.len()), ("duration", duration.len())] {
            if found != edges.len() {
                return Err(MdpError::LengthMismatch {
                    what,
                    expected: edges.len(),
                    found,
                });
            }
        }
        for (index, edge) in edges.iter().enumerate() {
            for node in [edge.from, edge.to] {
                if node >= nodes {
                    return Err(MdpError::EdgeOutOfRange {
                        edge: edge.id.clone(),
                        node,
                        nodes,
                    });
                }
            }
            let p = success[index];
            if !(0.0..=1.0).contains(&p) {
                return Err(MdpError::InvalidSuccess {
                    edge: edge.id.clone(),
                    index,
                    value: p,
                });
            }
            let d = duration[index];
            if !(d.is_finite() && d >= 0.0) {
                return Err(MdpError::InvalidDuration {
                    edge: edge.id.clone(),
                    index,
                    value: d,
                });
            }
        }
        // Counting sort of the edges by source node, stable (edge order within a node).
        let mut out_start = vec![0usize; nodes + 2];
        for edge in edges {
            out_start[edge.from + 1] += 1;
        }
        for v in 0..=nodes {
            out_start[v + 1] += out_start[v];
        }
        let mut next = out_start.clone();
        let mut out_edges = vec![0usize; edges.len()];
        for (index, edge) in edges.iter().enumerate() {
            out_edges[next[edge.from]] = index;
            next[edge.from] += 1;
        }
        Ok(NavigationMdp {
            names: map.nodes().iter().map(|n| n.name.clone()).collect(),
            edges: edges.to_vec(),
            success: success.to_vec(),
            duration: duration.to_vec(),
            out_start,
            out_edges,
        })
    }

    /// Number of nodes (states without the sink).
    pub fn node_count(&self) -> usize {
        self.names.len()
    }

    /// Number of states: the nodes and the sink.
    pub fn state_count(&self) -> usize {
        self.names.len() + 1
    }

    /// The failure sink `s_f` (the state after the last node).
    pub fn sink(&self) -> usize {
        self.names.len()
    }

    /// The node names, in state order.
    pub fn node_names(&self) -> &[String] {
        &self.names
    }

    /// The name of a state's node (`None` for the sink and out-of-range states).
    pub fn node_name(&self, state: usize) -> Option<&str> {
        self.names.get(state).map(String::as_str)
    }

    /// The edges (actions).
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }

    /// `p_e(t)` per edge.
    pub fn success(&self) -> &[f64] {
        &self.success
    }

    /// Duration (cost) per edge, seconds.
    pub fn duration(&self) -> &[f64] {
        &self.duration
    }

    /// The actions of a state: the indices of the edges leaving it, in edge order (none for
    /// the sink and out-of-range states).
    pub fn actions(&self, state: usize) -> &[usize] {
        if state >= self.names.len() {
            return &[];
        }
        &self.out_edges[self.out_start[state]..self.out_start[state + 1]]
    }

    /// The outcomes `(state, probability)` of taking `edge`: its target with `p_e`, the sink
    /// with `1 − p_e`; outcomes of probability zero are left out. Empty for an unknown edge.
    pub fn outcomes(&self, edge: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let (to, p) = match self.edges.get(edge) {
            Some(e) => (e.to, self.success[edge]),
            None => (0, 0.0),
        };
        let known = edge < self.edges.len();
        [(to, p), (self.sink(), 1.0 - p)]
            .into_iter()
            .filter(move |&(_, q)| known && q > 0.0)
    }

    /// The product with a task automaton, reachable part only (see the [module
    /// documentation](self)): starts at `(initial, next(q₀, letter(initial)))`.
    ///
    /// # Errors
    /// [`MdpError::NodeOutOfRange`] if `initial` is not a node, [`MdpError::InconsistentDfa`]
    /// if the automaton is malformed.
    pub fn product(&self, initial: usize, dfa: &Dfa) -> Result<ProductMdp, MdpError> {
        product::build(self, initial, dfa)
    }
}
