//! Sparse MDPs with goal states: CSR rows of choices per state and of outcomes per choice.

use std::ops::Range;

use super::MdpError;

/// One choice of a state, for [`SparseMdp::new`].
#[derive(Clone, Debug, PartialEq)]
pub struct Choice {
    /// Index of the action into the MDP's action names.
    pub action: usize,
    /// Cost of taking it (≥ 0, finite).
    pub cost: f64,
    /// `(target state, probability)` pairs; probabilities in `(0, 1]` summing to one.
    pub outcomes: Vec<(usize, f64)>,
}

/// A finite MDP with an initial state, goal states, action names and per-choice costs, stored
/// sparsely: the choices of state `s` are `choices(s)`, numbered globally; the outcomes of
/// choice `c` are `outcomes(c)`.
///
/// Goal states are absorbing for the solvers: their choices, if any, are ignored.
#[derive(Clone, Debug, PartialEq)]
pub struct SparseMdp {
    pub(crate) initial: usize,
    pub(crate) goal: Vec<bool>,
    pub(crate) action_names: Vec<String>,
    /// Choices of state `s`: `state_start[s]..state_start[s + 1]`.
    pub(crate) state_start: Vec<usize>,
    pub(crate) choice_action: Vec<usize>,
    pub(crate) choice_cost: Vec<f64>,
    /// Outcomes of choice `c`: `choice_start[c]..choice_start[c + 1]`.
    pub(crate) choice_start: Vec<usize>,
    pub(crate) target: Vec<usize>,
    pub(crate) prob: Vec<f64>,
}

impl SparseMdp {
    /// An MDP from its rows: `choices[s]` are the choices of state `s`, in order.
    ///
    /// # Errors
    /// [`MdpError::LengthMismatch`] if `goal` and `choices` differ in length,
    /// [`MdpError::StateOutOfRange`] for a bad initial state or target,
    /// [`MdpError::ActionOutOfRange`], [`MdpError::InvalidCost`], [`MdpError::NoOutcome`],
    /// [`MdpError::InvalidProbability`] (NaN or outside `(0, 1]`) and
    /// [`MdpError::NotStochastic`] (probabilities not summing to one within 1e-9).
    pub fn new(
        initial: usize,
        goal: Vec<bool>,
        action_names: Vec<String>,
        choices: Vec<Vec<Choice>>,
    ) -> Result<Self, MdpError> {
        let n = choices.len();
        if goal.len() != n {
            return Err(MdpError::LengthMismatch {
                what: "goal",
                expected: n,
                found: goal.len(),
            });
        }
        if initial >= n {
            return Err(MdpError::StateOutOfRange {
                what: "initial state".into(),
                state: initial,
                states: n,
            });
        }
        let mut mdp = SparseMdp::without_choices(initial, goal, action_names);
        for (state, row) in choices.into_iter().enumerate() {
            for (choice, c) in row.into_iter().enumerate() {
                if c.action >= mdp.action_names.len() {
                    return Err(MdpError::ActionOutOfRange {
                        state,
                        choice,
                        action: c.action,
                        actions: mdp.action_names.len(),
                    });
                }
                if !(c.cost.is_finite() && c.cost >= 0.0) {
                    return Err(MdpError::InvalidCost {
                        state,
                        choice,
                        value: c.cost,
                    });
                }
                if c.outcomes.is_empty() {
                    return Err(MdpError::NoOutcome { state, choice });
                }
                let mut sum = 0.0;
                for &(t, p) in &c.outcomes {
                    if t >= n {
                        return Err(MdpError::StateOutOfRange {
                            what: format!("target of choice {choice} of state {state}"),
                            state: t,
                            states: n,
                        });
                    }
                    if !(p > 0.0 && p <= 1.0) {
                        return Err(MdpError::InvalidProbability {
                            state,
                            choice,
                            value: p,
                        });
                    }
                    sum += p;
                }
                if (sum - 1.0).abs() > 1e-9 {
                    return Err(MdpError::NotStochastic { state, choice, sum });
                }
                mdp.push_choice(c.action, c.cost, &c.outcomes);
            }
            mdp.end_state();
        }
        Ok(mdp)
    }

    /// An MDP of no state yet, to be built with [`SparseMdp::push_choice`] and
    /// [`SparseMdp::end_state`].
    pub(crate) fn without_choices(
        initial: usize,
        goal: Vec<bool>,
        action_names: Vec<String>,
    ) -> SparseMdp {
        SparseMdp {
            initial,
            goal,
            action_names,
            state_start: vec![0],
            choice_action: Vec::new(),
            choice_cost: Vec::new(),
            choice_start: vec![0],
            target: Vec::new(),
            prob: Vec::new(),
        }
    }

    /// Appends a choice to the state being built (no checks).
    pub(crate) fn push_choice(&mut self, action: usize, cost: f64, outcomes: &[(usize, f64)]) {
        self.choice_action.push(action);
        self.choice_cost.push(cost);
        for &(t, p) in outcomes {
            self.target.push(t);
            self.prob.push(p);
        }
        self.choice_start.push(self.target.len());
    }

    /// Closes the state being built.
    pub(crate) fn end_state(&mut self) {
        self.state_start.push(self.choice_action.len());
    }

    /// Number of states.
    pub fn state_count(&self) -> usize {
        self.state_start.len() - 1
    }

    /// Number of choices (state-action pairs).
    pub fn choice_count(&self) -> usize {
        self.choice_action.len()
    }

    /// Number of transitions (outcomes of all choices).
    pub fn transition_count(&self) -> usize {
        self.target.len()
    }

    /// The initial state.
    pub fn initial(&self) -> usize {
        self.initial
    }

    /// Goal flags per state.
    pub fn goal(&self) -> &[bool] {
        &self.goal
    }

    /// Action names.
    pub fn action_names(&self) -> &[String] {
        &self.action_names
    }

    /// The (global) indices of a state's choices; empty for an out-of-range state.
    pub fn choices(&self, state: usize) -> Range<usize> {
        if state >= self.state_count() {
            return 0..0;
        }
        self.state_start[state]..self.state_start[state + 1]
    }

    /// The state a choice belongs to (`None` out of range).
    pub fn owner(&self, choice: usize) -> Option<usize> {
        if choice >= self.choice_count() {
            return None;
        }
        // The first state whose choices start after `choice`, minus one.
        Some(self.state_start.partition_point(|&start| start <= choice) - 1)
    }

    /// The action of a choice.
    ///
    /// # Panics
    /// If `choice` is out of range.
    pub fn action(&self, choice: usize) -> usize {
        self.choice_action[choice]
    }

    /// The name of a choice's action.
    ///
    /// # Panics
    /// If `choice` is out of range.
    pub fn action_name(&self, choice: usize) -> &str {
        &self.action_names[self.choice_action[choice]]
    }

    /// The cost of a choice.
    ///
    /// # Panics
    /// If `choice` is out of range.
    pub fn cost(&self, choice: usize) -> f64 {
        self.choice_cost[choice]
    }

    /// The outcomes `(target, probability)` of a choice.
    ///
    /// # Panics
    /// If `choice` is out of range.
    pub fn outcomes(&self, choice: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let range = self.choice_start[choice]..self.choice_start[choice + 1];
        self.target[range.clone()]
            .iter()
            .copied()
            .zip(self.prob[range].iter().copied())
    }

    /// The targets of a choice.
    pub(crate) fn targets(&self, choice: usize) -> &[usize] {
        &self.target[self.choice_start[choice]..self.choice_start[choice + 1]]
    }

    /// `Σ p·values[t]` over the outcomes of a choice.
    pub(crate) fn expect(&self, choice: usize, values: &[f64]) -> f64 {
        let range = self.choice_start[choice]..self.choice_start[choice + 1];
        self.target[range.clone()]
            .iter()
            .zip(&self.prob[range])
            .map(|(&t, &p)| p * values[t])
            .sum()
    }

    /// The same MDP with only the choices `keep[c]` (states, goal flags and action names
    /// unchanged).
    ///
    /// # Errors
    /// [`MdpError::LengthMismatch`] if `keep` does not have one flag per choice.
    pub fn restrict(&self, keep: &[bool]) -> Result<SparseMdp, MdpError> {
        if keep.len() != self.choice_count() {
            return Err(MdpError::LengthMismatch {
                what: "kept choices",
                expected: self.choice_count(),
                found: keep.len(),
            });
        }
        let mut out =
            SparseMdp::without_choices(self.initial, self.goal.clone(), self.action_names.clone());
        let mut outcomes = Vec::new();
        for s in 0..self.state_count() {
            for c in self.choices(s).filter(|&c| keep[c]) {
                outcomes.clear();
                outcomes.extend(self.outcomes(c));
                out.push_choice(self.choice_action[c], self.choice_cost[c], &outcomes);
            }
            out.end_state();
        }
        Ok(out)
    }
}
