//! The product of a Navigation MDP with a task automaton (reachable part).

use std::collections::HashMap;

use super::{MdpError, NavigationMdp, Solution, SolverOptions, SparseMdp, solve};
use crate::automaton::Dfa;

/// A state of the product: where the robot is and how far the task has progressed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ProductState {
    /// The node (`None`: the failure sink `s_f`).
    pub node: Option<usize>,
    /// The automaton state after reading the letters of the run so far.
    pub dfa_state: usize,
}

/// The reachable part of `M_t ⊗ A` (see [`NavigationMdp::product`]): a [`SparseMdp`] whose
/// actions are the edges of the map (action `e` = edge index `e`, named by the edge id), and
/// the [`ProductState`] of every state. State 0 is the initial state; states are numbered in
/// breadth-first order and choices follow edge order within a state.
#[derive(Clone, Debug, PartialEq)]
pub struct ProductMdp {
    mdp: SparseMdp,
    states: Vec<ProductState>,
    index: HashMap<ProductState, usize>,
}

impl ProductMdp {
    /// The product as a sparse MDP (goal states = accepting automaton states).
    pub fn mdp(&self) -> &SparseMdp {
        &self.mdp
    }

    /// The node and automaton state of every product state.
    pub fn states(&self) -> &[ProductState] {
        &self.states
    }

    /// The index of a product state, if it is reachable.
    pub fn index_of(&self, state: ProductState) -> Option<usize> {
        self.index.get(&state).copied()
    }

    /// Where taking `choice` in product state `from` leads when the robot ends up at `node`
    /// (`None`: the navigation failed): the successor product state, if that outcome is
    /// possible. For executing a policy.
    pub fn successor(&self, from: usize, choice: usize, node: Option<usize>) -> Option<usize> {
        if !self.mdp.choices(from).contains(&choice) {
            return None;
        }
        self.mdp
            .outcomes(choice)
            .map(|(t, _)| t)
            .find(|&t| self.states[t].node == node)
    }

    /// Solves the product (see [`solve`]).
    ///
    /// # Errors
    /// See [`solve`].
    pub fn solve(&self, options: &SolverOptions) -> Result<Solution, MdpError> {
        solve(&self.mdp, options)
    }
}

/// Whether the automaton, reading `letter` forever from `q`, passes an accepting state.
fn lasso_accepts(dfa: &Dfa, mut q: usize, letter: usize) -> bool {
    for _ in 0..=dfa.states() {
        if dfa.accepting[q] {
            return true;
        }
        q = dfa.next(q, letter);
    }
    false
}

pub(super) fn build(
    nav: &NavigationMdp,
    initial: usize,
    dfa: &Dfa,
) -> Result<ProductMdp, MdpError> {
    if initial >= nav.node_count() {
        return Err(MdpError::NodeOutOfRange {
            node: initial,
            nodes: nav.node_count(),
        });
    }
    if !dfa.is_consistent() {
        return Err(MdpError::InconsistentDfa);
    }
    // The letter each navigation state reads: its node's atom, or "no atom" (the sink too).
    let letter: Vec<usize> = (0..nav.state_count())
        .map(|s| dfa.letter_of(nav.node_name(s)))
        .collect();
    let node_of = |s: usize| (s < nav.node_count()).then_some(s);
    let dead_end = |s: usize| nav.actions(s).is_empty();

    let mut product = ProductMdp {
        mdp: SparseMdp::without_choices(
            0,
            Vec::new(),
            nav.edges().iter().map(|e| e.id.clone()).collect(),
        ),
        states: Vec::new(),
        index: HashMap::new(),
    };
    // Navigation state of every product state (the sink as `nav.sink()`).
    let mut nav_state: Vec<usize> = Vec::new();
    let add = |product: &mut ProductMdp, nav_state: &mut Vec<usize>, s: usize, q: usize| {
        let key = ProductState {
            node: node_of(s),
            dfa_state: q,
        };
        if let Some(&i) = product.index.get(&key) {
            return i;
        }
        let i = product.states.len();
        product.states.push(key);
        product.index.insert(key, i);
        nav_state.push(s);
        let goal = dfa.accepting[q] || (dead_end(s) && lasso_accepts(dfa, q, letter[s]));
        product.mdp.goal.push(goal);
        i
    };
    add(
        &mut product,
        &mut nav_state,
        initial,
        dfa.next(dfa.initial, letter[initial]),
    );
    let mut outcomes = Vec::with_capacity(2);
    // Breadth-first: states are expanded in the order they were added, so rows are appended
    // in state order.
    let mut expanded = 0;
    while expanded < product.states.len() {
        let i = expanded;
        expanded += 1;
        let (s, q) = (nav_state[i], product.states[i].dfa_state);
        if !product.mdp.goal[i] {
            for &e in nav.actions(s) {
                outcomes.clear();
                for (t, p) in nav.outcomes(e) {
                    let next = add(&mut product, &mut nav_state, t, dfa.next(q, letter[t]));
                    outcomes.push((next, p));
                }
                product.mdp.push_choice(e, nav.duration()[e], &outcomes);
            }
        }
        product.mdp.end_state();
    }
    Ok(product)
}
