//! Stochastic behavior trees ([Stüde 2024] §5.2.2, after Colledanchise, Marzinotto and Ögren,
//! ICRA 2014): actions and conditions with success/failure probabilities and exponentially
//! distributed durations, composed by Sequence and Fallback nodes, analysed through the
//! continuous-time Markov chain of the tree's execution.
//!
//! ```
//! use chronomap_bt_stochastic::{Action, Node};
//!
//! // Search a corridor (finds someone with probability 0.6, after 20 s on average; gives up
//! // after 40 s on average), else wait at the door (0.9, 50 s; gives up after 100 s).
//! let search = Action::new(0.6, 1.0 / 20.0, 1.0 / 40.0)?;
//! let wait = Action::new(0.9, 1.0 / 50.0, 1.0 / 100.0)?;
//! let tree = Node::Fallback(vec![Node::Action(search), Node::Action(wait)]);
//! let chain = tree.chain()?;
//! let at = chain.transient(&[60.0, 1e6], 1e-12)?;
//! // Eventually the tree succeeds with 0.6 + 0.4 · 0.9 = 0.96 (eq. 5.1 at t → ∞).
//! assert!((at[1].p_success - 0.96).abs() < 1e-9);
//! assert!(at[0].p_success < at[1].p_success);
//! // The exact mean time to success, given success: (0.6·20 + 0.36·(40 + 50)) / 0.96 s.
//! let means = chain.means();
//! assert!((means.time_to_success.unwrap() - (0.6 * 20.0 + 0.36 * 90.0) / 0.96).abs() < 1e-9);
//! # Ok::<(), chronomap_bt_stochastic::SbtError>(())
//! ```
//!
//! # Model (§5.2.2)
//! An action is the tuple `A_sbt = ⟨p_s(t), p_f(t), μ, ν⟩`: it ends in success with
//! probability `p_s`, after a time `~ Exp(μ)`, and otherwise in failure, after a time
//! `~ Exp(ν)` ("the time to succeed and time to fail are random variables with exponential
//! distribution and rates μ and ν"). Its probabilities to have succeeded or failed by time `t`
//! after it started are therefore
//!
//! `p_s(t) = p_s · (1 − e^{−μt})`,  `p_f(t) = (1 − p_s) · (1 − e^{−νt})`
//!
//! ([`Action::p_success_at`], [`Action::p_failure_at`]). In the chain an action is two
//! transient states, "running towards success" (entered with probability `p_s`, left with
//! rate `μ`) and "running towards failure" (`1 − p_s`, rate `ν`). A condition
//! `C_sbt = ⟨p_s, p_f⟩` takes no time: it routes the probability mass at once to where its
//! outcome leads. Sequence and Fallback route outcomes as Algorithms 5.1 and 5.2: the entry
//! of child `i + 1` is where child `i`'s success (Sequence) or failure (Fallback) leads; the
//! other outcome leaves the node. The root's outcomes are the absorbing states `S` and `F`.
//! Parallel nodes are not modelled.
//!
//! # Analysis
//! * **Eq. 5.2** `π̇ = Qπ`: the generator `Q` is constant here (the tuples do not change while
//!   the tree runs; the person search of `chronomap-psbt` evaluates its rates at the time help
//!   is requested, as eqs. 5.9 and 5.14 do). The dissertation calls the chain a DTMC; it is a
//!   continuous-time chain with generator `Q`.
//! * **Eq. 5.1** `p_{s,T}(t)`, `p_{f,T}(t)`: [`Chain::transient`] by uniformisation
//!   (`P = I + Q/Λ` with `Λ` the largest exit rate, `π(t) = Σ_k Pois(k; Λt) π₀Pᵏ`), truncated
//!   where the Poisson tail is below the requested tolerance. As absorbed probability is
//!   between 0 and 1, that tail bounds the error ([`Outcome::error_bound`]).
//! * **Eqs. 5.3–5.4** define the tree's success and failure rates `μ_T`, `ν_T` by averaging
//!   log-ratios of step matrices over time. They are replaced here by the exact conditional
//!   mean times to absorption, `1/μ_T = E[T | S]` and `1/ν_T = E[T | F]` ([`Chain::means`]),
//!   computed by one backward pass over the acyclic chain: with `h_i` the probability to be
//!   absorbed in `S` from state `i` and `q_i` its exit rate, `h_i = Σ_j (q_ij/q_i) h_j` and
//!   `E_i[T·1_S] = h_i/q_i + Σ_j (q_ij/q_i) E_j[T·1_S]`. This is what the averaged rates
//!   approximate, and it is exact for any tree.
//! * [`dense`] holds the straightforward reference (dense generator, dense uniformisation),
//!   [`simulate`] a Monte-Carlo execution of the tree itself; the tests check the chain
//!   against both and against closed forms.
//!
//! This crate knows nothing of running behavior trees: `chronomap-bt` reads a
//! BehaviorTree.CPP tree as a [`Node`] (`chronomap_bt::stochastic::from_bt`, with a table of
//! [`LeafParams`]), and the person search of `chronomap-psbt` builds its trees directly.

#![deny(missing_docs)]

pub mod dense;
pub mod simulate;

use thiserror::Error;

/// The stochastic parameters of one leaf (§5.2.2): `p_s`, and for actions the rates `μ`
/// (success) and `ν` (failure) in 1/s. `p_f = 1 − p_s`: an action or condition always ends.
/// `chronomap-io` reads a table of them by leaf name; `chronomap-bt` turns a BehaviorTree.CPP
/// tree with such a table into a [`Node`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeafParams {
    /// Probability of success `p_s`.
    pub p_success: f64,
    /// Success rate `μ` (1/s); `None` for conditions.
    pub mu: Option<f64>,
    /// Failure rate `ν` (1/s); `None` for conditions.
    pub nu: Option<f64>,
}

/// The tree whose outcome is the opposite of `node`'s, with the same timing (De Morgan:
/// `¬Sequence(a, b) = Fallback(¬a, ¬b)`; an inverted action swaps `p_s ↔ p_f` and `μ ↔ ν`).
pub fn invert(node: Node) -> Node {
    match node {
        Node::Action(a) => Node::Action(
            Action::new(1.0 - a.p_success(), a.nu(), a.mu()).expect("a valid action, inverted"),
        ),
        Node::Condition(c) => Node::Condition(
            Condition::new(1.0 - c.p_success()).expect("a valid condition, inverted"),
        ),
        Node::Sequence(children) => Node::Fallback(children.into_iter().map(invert).collect()),
        Node::Fallback(children) => Node::Sequence(children.into_iter().map(invert).collect()),
    }
}

/// Why a stochastic tree or chain was rejected.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum SbtError {
    /// A probability is not a number in `[0, 1]`.
    #[error("probability {value} is not in [0, 1]")]
    Probability {
        /// The offending value.
        value: f64,
    },
    /// A rate that an outcome of positive probability needs is not a positive finite number.
    #[error("the {which} rate {value} is not a positive finite number")]
    Rate {
        /// `"success"` or `"failure"`.
        which: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A chain transition has a negative or non-finite rate, or leads to a state that is not
    /// earlier in the chain (chains are acyclic, states ordered against their transitions).
    #[error("transition {index} of state {state}: {reason}")]
    Transition {
        /// The state.
        state: usize,
        /// Index of the transition among the state's transitions.
        index: usize,
        /// What is wrong.
        reason: String,
    },
    /// A transient state has no way out (it would trap probability for ever).
    #[error("state {state} has no outgoing transition")]
    Trap {
        /// The state.
        state: usize,
    },
    /// The initial distribution is not a probability distribution.
    #[error("the initial probabilities sum to {sum}, not 1")]
    Initial {
        /// Their sum.
        sum: f64,
    },
    /// A query time is negative or not finite, or the tolerance is not in `(0, 1)`.
    #[error("invalid query: {0}")]
    Query(String),
}

/// An SBT action `⟨p_s(t), p_f(t), μ, ν⟩` ([module docs](self#model-522)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Action {
    p_success: f64,
    mu: f64,
    nu: f64,
}

impl Action {
    /// An action that succeeds with probability `p_success` after `Exp(mu)` seconds and
    /// otherwise fails after `Exp(nu)` seconds.
    ///
    /// # Errors
    /// [`SbtError::Probability`] unless `0 ≤ p_success ≤ 1`; [`SbtError::Rate`] if `mu`
    /// (when `p_success > 0`) or `nu` (when `p_success < 1`) is not a positive finite number.
    /// A rate whose outcome has probability 0 is not used and may be anything finite ≥ 0.
    pub fn new(p_success: f64, mu: f64, nu: f64) -> Result<Self, SbtError> {
        if !(0.0..=1.0).contains(&p_success) {
            return Err(SbtError::Probability { value: p_success });
        }
        let check = |which, rate: f64, needed: bool| {
            let ok = if needed {
                rate.is_finite() && rate > 0.0
            } else {
                rate.is_finite() && rate >= 0.0
            };
            if ok {
                Ok(())
            } else {
                Err(SbtError::Rate { which, value: rate })
            }
        };
        check("success", mu, p_success > 0.0)?;
        check("failure", nu, p_success < 1.0)?;
        Ok(Action { p_success, mu, nu })
    }

    /// Probability `p_s` that the action ends in success.
    pub fn p_success(&self) -> f64 {
        self.p_success
    }

    /// Success rate `μ` (1/s): the time to succeed is `~ Exp(μ)`.
    pub fn mu(&self) -> f64 {
        self.mu
    }

    /// Failure rate `ν` (1/s): the time to fail is `~ Exp(ν)`.
    pub fn nu(&self) -> f64 {
        self.nu
    }

    /// `p_s(t) = p_s (1 − e^{−μt})`: probability to have succeeded `t` seconds after the start.
    pub fn p_success_at(&self, t: f64) -> f64 {
        if self.p_success == 0.0 {
            return 0.0;
        }
        self.p_success * -(-self.mu * t.max(0.0)).exp_m1()
    }

    /// `p_f(t) = (1 − p_s)(1 − e^{−νt})`: probability to have failed `t` seconds after the start.
    pub fn p_failure_at(&self, t: f64) -> f64 {
        if self.p_success == 1.0 {
            return 0.0;
        }
        (1.0 - self.p_success) * -(-self.nu * t.max(0.0)).exp_m1()
    }
}

/// An SBT condition `⟨p_s, p_f⟩`: true with probability `p_s`, evaluated instantly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Condition {
    p_success: f64,
}

impl Condition {
    /// A condition that holds with probability `p_success`.
    ///
    /// # Errors
    /// [`SbtError::Probability`] unless `0 ≤ p_success ≤ 1`.
    pub fn new(p_success: f64) -> Result<Self, SbtError> {
        if !(0.0..=1.0).contains(&p_success) {
            return Err(SbtError::Probability { value: p_success });
        }
        Ok(Condition { p_success })
    }

    /// Probability that the condition holds.
    pub fn p_success(&self) -> f64 {
        self.p_success
    }
}

/// A stochastic behavior tree.
#[derive(Clone, Debug, PartialEq)]
pub enum Node {
    /// A leaf that takes time.
    Action(Action),
    /// A leaf that takes no time.
    Condition(Condition),
    /// Ticks its children in order until one fails (Algorithm 5.1); no children: success.
    Sequence(Vec<Node>),
    /// Ticks its children in order until one succeeds (Algorithm 5.2); no children: failure.
    Fallback(Vec<Node>),
}

impl Node {
    /// The Markov chain of this tree's execution ([`Chain::from_tree`]).
    ///
    /// # Errors
    /// None for trees built from valid actions and conditions; the `Result` is that of
    /// [`Chain::new`].
    pub fn chain(&self) -> Result<Chain, SbtError> {
        Chain::from_tree(self)
    }
}

/// Where a transition leads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Target {
    /// A transient state (its index).
    State(usize),
    /// The absorbing success state `S`.
    Success,
    /// The absorbing failure state `F`.
    Failure,
}

/// A probability distribution over targets (sparse).
type Dist = Vec<(Target, f64)>;

/// Adds `factor` times the distribution `from` to `into`, merging equal targets.
pub fn add_scaled(into: &mut Vec<(Target, f64)>, from: &[(Target, f64)], factor: f64) {
    if factor == 0.0 {
        return;
    }
    for &(target, p) in from {
        match into.iter_mut().find(|(t, _)| *t == target) {
            Some((_, q)) => *q += p * factor,
            None => into.push((target, p * factor)),
        }
    }
}

/// The absorbing continuous-time Markov chain of a tree's execution (eq. 5.2): transient
/// states `0..n`, each with transitions (target, rate), and the absorbing states `S` and `F`.
/// Every transition of state `i` leads to a state `j < i` or to `S`/`F`, so the chain is
/// acyclic and the states are numbered against the flow of time (the last state runs first).
#[derive(Clone, Debug, PartialEq)]
pub struct Chain {
    exits: Vec<Vec<(Target, f64)>>,
    initial: Vec<(Target, f64)>,
}

/// Probabilities of the absorbing states at a time (eq. 5.1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    /// `p_{s,T}(t)`.
    pub p_success: f64,
    /// `p_{f,T}(t)`.
    pub p_failure: f64,
    /// Bound on the truncation error of either probability (the Poisson tail left out).
    pub error_bound: f64,
}

/// Eventual outcome probabilities and exact conditional mean times ([`Chain::means`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Means {
    /// Probability of ending in `S`.
    pub p_success: f64,
    /// Probability of ending in `F`.
    pub p_failure: f64,
    /// `E[T | S]` in seconds (`1/μ_T`), `None` if success is impossible.
    pub time_to_success: Option<f64>,
    /// `E[T | F]` in seconds (`1/ν_T`), `None` if failure is impossible.
    pub time_to_failure: Option<f64>,
}

impl Chain {
    /// A chain from its transitions (`exits[i]`: the `(target, rate)` pairs of state `i`) and
    /// its initial distribution.
    ///
    /// # Errors
    /// [`SbtError::Transition`] for a rate that is negative or not finite, or a target state
    /// that is not earlier than its source; [`SbtError::Trap`] for a state without a positive
    /// exit rate; [`SbtError::Initial`] unless the initial probabilities are ≥ 0 and sum to 1
    /// (within 1e-9), or one names a state that does not exist.
    pub fn new(
        exits: Vec<Vec<(Target, f64)>>,
        initial: Vec<(Target, f64)>,
    ) -> Result<Self, SbtError> {
        for (state, out) in exits.iter().enumerate() {
            let mut total = 0.0;
            for (index, &(target, rate)) in out.iter().enumerate() {
                let bad = |reason: String| SbtError::Transition {
                    state,
                    index,
                    reason,
                };
                if !(rate.is_finite() && rate >= 0.0) {
                    return Err(bad(format!("rate {rate} is not a finite number >= 0")));
                }
                if let Target::State(j) = target
                    && j >= state
                {
                    return Err(bad(format!(
                        "leads to state {j}, not to an earlier one (chains are acyclic)"
                    )));
                }
                total += rate;
            }
            if total <= 0.0 {
                return Err(SbtError::Trap { state });
            }
        }
        let mut sum = 0.0;
        for &(target, p) in &initial {
            let exists = match target {
                Target::State(j) => j < exits.len(),
                _ => true,
            };
            if !(p.is_finite() && p >= 0.0 && exists) {
                return Err(SbtError::Initial { sum: f64::NAN });
            }
            sum += p;
        }
        if (sum - 1.0).abs() > 1e-9 {
            return Err(SbtError::Initial { sum });
        }
        Ok(Chain { exits, initial })
    }

    /// The chain of a tree (the [module docs](self#model-522) say how nodes become states).
    /// Each action adds at most two states, so the chain is linear in the size of the tree.
    ///
    /// # Errors
    /// As [`Chain::new`] (never for trees of valid leaves).
    pub fn from_tree(tree: &Node) -> Result<Self, SbtError> {
        let mut exits = Vec::new();
        let initial = compile(
            tree,
            &vec![(Target::Success, 1.0)],
            &vec![(Target::Failure, 1.0)],
            &mut exits,
        );
        Chain::new(exits, initial)
    }

    /// Number of transient states.
    pub fn states(&self) -> usize {
        self.exits.len()
    }

    /// The transitions `(target, rate)` of each transient state.
    pub fn exits(&self) -> &[Vec<(Target, f64)>] {
        &self.exits
    }

    /// The initial distribution `π₀` (over transient and absorbing states).
    pub fn initial(&self) -> &[(Target, f64)] {
        &self.initial
    }

    /// The largest exit rate of a state (the uniformisation rate `Λ`; 0 without states).
    pub fn max_exit_rate(&self) -> f64 {
        self.exits
            .iter()
            .map(|out| out.iter().map(|&(_, r)| r).sum::<f64>())
            .fold(0.0, f64::max)
    }

    /// `p_{s,T}(t)` and `p_{f,T}(t)` (eq. 5.1) at each of `times` (seconds since the tree
    /// started), by uniformisation of eq. 5.2 truncated where the Poisson tail of every time
    /// is below `tolerance`.
    ///
    /// # Complexity
    /// `O((Λ t_max + √(Λ t_max)) · transitions)`.
    ///
    /// # Errors
    /// [`SbtError::Query`] for a negative or non-finite time, or a tolerance outside `(0, 1)`.
    pub fn transient(&self, times: &[f64], tolerance: f64) -> Result<Vec<Outcome>, SbtError> {
        check_query(times, tolerance)?;
        let lambda = self.max_exit_rate().max(f64::MIN_POSITIVE);
        let t_max = times.iter().copied().fold(0.0, f64::max);
        let steps = poisson_truncation(lambda * t_max, tolerance);
        // Absorbed probability after k jumps of the uniformised chain.
        let (mut absorbed_s, mut absorbed_f) =
            (Vec::with_capacity(steps + 1), Vec::with_capacity(steps + 1));
        let mut v = vec![0.0; self.exits.len()];
        let (mut s, mut f) = (0.0, 0.0);
        for &(target, p) in &self.initial {
            match target {
                Target::State(j) => v[j] += p,
                Target::Success => s += p,
                Target::Failure => f += p,
            }
        }
        absorbed_s.push(s);
        absorbed_f.push(f);
        let mut next = vec![0.0; v.len()];
        for _ in 0..steps {
            next.iter_mut().for_each(|x| *x = 0.0);
            for (i, out) in self.exits.iter().enumerate() {
                let mass = v[i];
                if mass == 0.0 {
                    continue;
                }
                let mut leaving = 0.0;
                for &(target, rate) in out {
                    let flow = mass * rate / lambda;
                    leaving += flow;
                    match target {
                        Target::State(j) => next[j] += flow,
                        Target::Success => s += flow,
                        Target::Failure => f += flow,
                    }
                }
                next[i] += mass - leaving;
            }
            std::mem::swap(&mut v, &mut next);
            absorbed_s.push(s);
            absorbed_f.push(f);
        }
        Ok(times
            .iter()
            .map(|&t| {
                let (weights, tail) = poisson_weights(lambda * t, steps);
                let dot = |a: &[f64]| weights.iter().zip(a).map(|(w, x)| w * x).sum::<f64>();
                Outcome {
                    p_success: dot(&absorbed_s),
                    p_failure: dot(&absorbed_f),
                    error_bound: tail,
                }
            })
            .collect())
    }

    /// Eventual outcome probabilities and the exact mean times to success and to failure
    /// (the replacement of eqs. 5.3–5.4, [module docs](self#analysis)).
    pub fn means(&self) -> Means {
        let n = self.exits.len();
        // h: P(absorbed in S); m: E[T·1_S]; g: E[T·1_F] from each state.
        let (mut h, mut m, mut g) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let value = |target: Target, v: &[f64], at_s: f64, at_f: f64| match target {
            Target::State(j) => v[j],
            Target::Success => at_s,
            Target::Failure => at_f,
        };
        for i in 0..n {
            let q: f64 = self.exits[i].iter().map(|&(_, r)| r).sum();
            let (mut hi, mut mi, mut gi) = (0.0, 0.0, 0.0);
            for &(target, rate) in &self.exits[i] {
                let w = rate / q;
                hi += w * value(target, &h, 1.0, 0.0);
                mi += w * value(target, &m, 0.0, 0.0);
                gi += w * value(target, &g, 0.0, 0.0);
            }
            // Leaving state i takes Exp(q): add its mean to every path through it.
            h[i] = hi;
            m[i] = mi + hi / q;
            g[i] = gi + (1.0 - hi) / q;
        }
        let (mut ps, mut ms, mut gs) = (0.0, 0.0, 0.0);
        for &(target, p) in &self.initial {
            ps += p * value(target, &h, 1.0, 0.0);
            ms += p * value(target, &m, 0.0, 0.0);
            gs += p * value(target, &g, 0.0, 0.0);
        }
        let pf = (1.0 - ps).max(0.0);
        Means {
            p_success: ps,
            p_failure: pf,
            time_to_success: (ps > 0.0).then(|| ms / ps),
            time_to_failure: (pf > 1e-15).then(|| gs / pf),
        }
    }
}

/// Compiles `node` so that its success leads to `on_success` and its failure to
/// `on_failure`; returns the node's entry distribution. States of later children are
/// created first, so transitions always lead to earlier states.
fn compile(
    node: &Node,
    on_success: &Dist,
    on_failure: &Dist,
    exits: &mut Vec<Vec<(Target, f64)>>,
) -> Dist {
    match node {
        Node::Condition(c) => {
            let mut entry = Vec::new();
            add_scaled(&mut entry, on_success, c.p_success);
            add_scaled(&mut entry, on_failure, 1.0 - c.p_success);
            entry
        }
        Node::Action(a) => {
            let mut entry = Vec::new();
            if a.p_success > 0.0 {
                let mut out = Vec::new();
                add_scaled(&mut out, on_success, a.mu);
                exits.push(out);
                entry.push((Target::State(exits.len() - 1), a.p_success));
            }
            if a.p_success < 1.0 {
                let mut out = Vec::new();
                add_scaled(&mut out, on_failure, a.nu);
                exits.push(out);
                entry.push((Target::State(exits.len() - 1), 1.0 - a.p_success));
            }
            entry
        }
        Node::Sequence(children) => {
            let mut next = on_success.clone();
            for child in children.iter().rev() {
                next = compile(child, &next, on_failure, exits);
            }
            next
        }
        Node::Fallback(children) => {
            let mut next = on_failure.clone();
            for child in children.iter().rev() {
                next = compile(child, on_success, &next, exits);
            }
            next
        }
    }
}

pub(crate) fn check_query(times: &[f64], tolerance: f64) -> Result<(), SbtError> {
    if let Some(t) = times.iter().find(|t| !(t.is_finite() && **t >= 0.0)) {
        return Err(SbtError::Query(format!(
            "time {t} is not a finite number >= 0"
        )));
    }
    if !(tolerance > 0.0 && tolerance < 1.0) {
        return Err(SbtError::Query(format!(
            "tolerance {tolerance} is not in (0, 1)"
        )));
    }
    Ok(())
}

/// The Poisson distribution with mean `m` on `0..len`, normalised, where `len` reaches past
/// every weight above `1e-300` of the mode's: computed from the mode outwards by the ratios
/// `w_{k+1}/w_k = m/(k+1)` (no logarithms, no underflow for large `m`, relative errors of a
/// few ulp per step), then divided by the sum.
fn poisson_pmf(m: f64) -> Vec<f64> {
    if m <= 0.0 {
        return vec![1.0];
    }
    let mode = m.floor() as usize;
    let mut up = vec![1.0];
    let mut k = mode;
    loop {
        let next = up[up.len() - 1] * m / (k + 1) as f64;
        if next < 1e-300 {
            break;
        }
        up.push(next);
        k += 1;
    }
    let mut down = Vec::with_capacity(mode);
    let mut w = 1.0;
    for k in (1..=mode).rev() {
        w *= k as f64 / m;
        if w < 1e-300 {
            break;
        }
        down.push(w);
    }
    let mut pmf = vec![0.0; mode - down.len()];
    pmf.extend(down.iter().rev());
    pmf.extend(&up);
    let total: f64 = pmf.iter().sum();
    pmf.iter_mut().for_each(|w| *w /= total);
    pmf
}

/// The smallest `K ≥ m` with `P(N > K) ≤ tolerance` for `N ~ Poisson(m)`.
pub fn poisson_truncation(m: f64, tolerance: f64) -> usize {
    let pmf = poisson_pmf(m);
    let mut tail = 0.0;
    let mut k = pmf.len() - 1;
    while k > 0 && (k as f64) > m && tail + pmf[k] <= tolerance {
        tail += pmf[k];
        k -= 1;
    }
    k
}

/// `Pois(k; m)` for `k = 0..=steps` and the probability `P(N > steps)` left out.
pub(crate) fn poisson_weights(m: f64, steps: usize) -> (Vec<f64>, f64) {
    let mut pmf = poisson_pmf(m);
    let tail = pmf.iter().skip(steps + 1).sum::<f64>();
    pmf.resize(steps + 1, 0.0);
    (pmf, tail)
}

/// `P(N ≥ k)` for `k = 0..=steps`, `N ~ Poisson(m)` (the probability that the `k`-th jump of
/// the uniformised chain has happened by the time `m/Λ`), and `P(N > steps)`.
pub fn poisson_survival(m: f64, steps: usize) -> (Vec<f64>, f64) {
    let (weights, tail) = poisson_weights(m, steps);
    let mut survival = vec![0.0; steps + 1];
    let mut acc = tail;
    for k in (0..=steps).rev() {
        acc += weights[k];
        survival[k] = acc.min(1.0);
    }
    (survival, tail)
}

#[cfg(test)]
mod tests;
