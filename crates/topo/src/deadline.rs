//! "Arrive by T with 95 % probability": the policy that maximises the probability of fulfilling
//! a co-safe task *within a deadline* `D`, by backward induction over the product of
//! [Fentanes 2015] §V extended with the time left.
//!
//! # What is maximised
//! The planner of [`crate::plan`] solves the product `M_t ⊗ A` of the Navigation MDP at the
//! start time `t` ([Fentanes 2015] §V, `δ(v_i, e, v_j) = p_e(t)`, `δ(v_i, e, s_f) = 1 − p_e(t)`)
//! and a task automaton for `Pmax`, then the least expected time. Here every edge also has a
//! *law* of its traversal duration, and a run succeeds when it reaches a goal state of the
//! product (every edge taken succeeded, the task holds) with the sum of the traversal
//! durations `≤ D`:
//!
//! ```text
//!     P*_D(s) = max_σ P_s^σ[ a goal is reached and Σ durations ≤ D ]
//! ```
//!
//! Storm writes it `Pmax=? [F{"time"}<=D "goal"]` (reward-bounded reachability, Hartmanns,
//! Junges, Katoen and Quatmann, "Multi-cost bounded reachability in MDP", TACAS 2018); the
//! optimal policies need to know the time left, so they are not memoryless on the product.
//!
//! # Buckets, and why the result is a lower bound
//! Time is counted in buckets of `Δ` seconds ([`DeadlineOptions::bucket_secs`]; default
//! `max(D / 600, 1 s)`, at most `D`; a bucket wider than the deadline is refused),
//! `K = ⌊D / Δ⌋` of them fit into the deadline. Every duration is rounded
//! **up** to whole buckets, at least one: `b = max(1, ⌈d / Δ⌉)` (`⌈·⌉` forgives 1e-9 of a
//! bucket of floating-point noise). Then `Σ b_i ≤ K` implies `Σ d_i ≤ K·Δ ≤ D`, so the
//! probability computed is a **certified lower bound** of the probability under the durations'
//! law — also when the robot executes the policy with the time actually left, read as
//! `⌊left / Δ⌋` buckets (the values grow with the buckets left). At least one bucket per edge
//! makes every step consume time, so the recursion below is finite even on maps whose
//! durations are zero.
//!
//! # Duration laws from the quantile functions
//! [`crate::duration_intervals`] describes the duration of a successful traversal of edge `e`
//! at `t` by the quantile function `Q_e(u) = d̂_e(t) · exp(q_e(u))` of log residuals, known at
//! the levels `u = i / 200`, `i = 1..=199` (the edge's own quantiles mixed with the pooled
//! ones). [`BucketLaw::from_quantiles`] puts mass `1/200` on `Q_e(i / 200)` for each level:
//! the slice `u ∈ ((i − 1)/200, i/200]` of the law takes the longest duration of the slice,
//! another upward rounding. The top slice `u > 0.995`, where the model knows nothing, is
//! counted as *late* (it misses every deadline), so a route of `n` edges cannot be certified
//! above `0.995ⁿ` times its success probability. As the planner of [`crate::plan`] uses the
//! models at one time `t`, the laws are those at the start time `t`. A failed traversal
//! takes the same law (the failure sink is usually not a goal, and then it does not matter).
//! Models without duration spread (files written before it existed) use the expected
//! duration as a sure one ([`DeadlinePlan::duration_quantiles`] is then `false`).
//!
//! # The recursion (finite-horizon backward induction, Puterman 1994 ch. 4)
//! On the *time-augmented product* — states `(s, k)`: product state `s` with `k` buckets left,
//! `k = 0..=K` —, with `L_e(b)` the mass of `b` buckets in edge `e`'s law:
//!
//! ```text
//!     V(s, k) = 1                                                         s a goal
//!     V(s, k) = max_{c ∈ choices(s)} Σ_{b ≤ k} L_e(c)(b) · Σ_{s'} δ(s, c, s') · V(s', k − b)
//!     V(s, k) = 0                                                         s without choices
//! ```
//!
//! computed for `k = 0, 1, …, K` in turn (each `V(·, k)` only needs `V(·, k − b)`, `b ≥ 1`).
//! `V(s₀, K)` is [`DeadlinePlan::probability`]; `V(s₀, k)` for `k ≤ K` is the curve
//! "probability of arriving within `k·Δ`" ([`DeadlinePlan::curve`]), every point with its own
//! optimal policy. Among choices within 1e-12 of the best the one of the expected-time plan is
//! kept, so a loose deadline gives that plan back; a state with `V = 0` has no choice. The
//! expected-time plan ([`crate::plan::plan_full`], memoryless) is evaluated on the same
//! time-augmented product with its choice fixed ([`DeadlinePlan::min_time_probability`]),
//! which the deadline plan can only match or beat.
//!
//! Memory and time grow with the cells `states × (K + 1)`: more than
//! [`DeadlineOptions::max_cells`] (default 10⁶) is refused with [`DeadlineError::TooManyCells`].
//!
//! ```
//! use chronomap_topo::deadline::{BucketLaw, solve_deadline};
//! use chronomap_topo::mdp::{NavigationMdp, SolverOptions};
//! use chronomap_topo::plan::Task;
//! use chronomap_topo::map::TopoMap;
//!
//! // A door straight to the lab (10 s, open 80 %) or a corridor (2 × 30 s, always passable).
//! let mut map = TopoMap::new();
//! for node in ["Office", "Hall", "Lab"] {
//!     map.add_node(node, None)?;
//! }
//! map.add_edge("Office_Lab", "Office", "Lab")?;
//! map.add_edge("Office_Hall", "Office", "Hall")?;
//! map.add_edge("Hall_Lab", "Hall", "Lab")?;
//! let nav = NavigationMdp::new(&map, &[0.8, 1.0, 1.0], &[10.0, 30.0, 30.0])?;
//! let task = Task::parse("F Lab", &map)?;
//! let product = nav.product(map.node("Office")?, task.dfa())?;
//! let min_time = product.solve(&SolverOptions::default())?;
//! // Buckets of 1 s; the laws are sure durations here.
//! let laws: Vec<BucketLaw> = [10.0, 30.0, 30.0]
//!     .iter()
//!     .map(|&d| BucketLaw::point(d, 1.0, 100))
//!     .collect();
//! let within = |k| solve_deadline(product.mdp(), &laws, k, Some(&min_time.policy_choice), 1_000_000);
//! assert_eq!(within(59)?.value(0, 59), 0.8); // only the door makes it
//! assert_eq!(within(60)?.value(0, 60), 1.0); // the corridor does
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use chronomap_core::rng::Xoshiro256StarStar;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::edges::EdgeModels;
use crate::mdp::{Choice, MdpError, SolverOptions, SparseMdp};
use crate::plan::{PlanError, Planned, Task, plan_full};

/// Buckets of the default width: `Δ = D / 600`, unless that is below [`MIN_DEFAULT_BUCKET_SECS`].
pub const DEFAULT_BUCKETS: f64 = 600.0;

/// The finest default bucket width (seconds).
pub const MIN_DEFAULT_BUCKET_SECS: f64 = 1.0;

/// Default of [`DeadlineOptions::max_cells`].
pub const DEFAULT_MAX_CELLS: usize = 1_000_000;

/// Floating-point noise forgiven when rounding a duration up to buckets (in buckets).
const ROUNDING_SLACK: f64 = 1e-9;

/// Values closer than this count as ties (the expected-time plan's choice wins them).
const TIE: f64 = 1e-12;

/// No choice in a cell of a policy table.
const NONE: u32 = u32::MAX;

/// Why a deadline plan could not be made.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum DeadlineError {
    /// The deadline is NaN, infinite, zero or negative.
    #[error("the deadline must be a finite number of seconds > 0, not {0}")]
    InvalidDeadline(f64),
    /// The bucket width is NaN, infinite, zero or negative.
    #[error("the bucket width must be a finite number of seconds > 0, not {0}")]
    InvalidBucket(f64),
    /// The bucket width is wider than the deadline: no whole bucket would fit into it.
    #[error("the bucket width {bucket} s is wider than the deadline {deadline} s")]
    BucketWiderThanDeadline {
        /// The bucket width (seconds).
        bucket: f64,
        /// The deadline (seconds).
        deadline: f64,
    },
    /// The time-augmented product would be too large.
    #[error(
        "the deadline plan would need {states} states × {buckets} buckets = {cells:.3e} cells, \
         more than the limit of {max} (widen the buckets or shorten the deadline)"
    )]
    TooManyCells {
        /// States of the product.
        states: usize,
        /// Buckets `K + 1` (`0..=K` left).
        buckets: f64,
        /// Their product.
        cells: f64,
        /// The limit ([`DeadlineOptions::max_cells`]).
        max: usize,
    },
    /// A law of durations is not a probability distribution over whole buckets `≥ 1`.
    #[error("the duration law of action {action} is invalid: {reason}")]
    InvalidLaw {
        /// The action (edge) index.
        action: usize,
        /// What is wrong.
        reason: String,
    },
    /// There is not one law per action of the MDP, or a policy not one entry per state.
    #[error("{what} has {found} entries, expected {expected}")]
    LengthMismatch {
        /// What the vector holds.
        what: &'static str,
        /// The length it should have.
        expected: usize,
        /// The length it has.
        found: usize,
    },
    /// A policy names a choice that is not one of its state's.
    #[error("the policy picks choice {choice} in state {state}, which is not one of its choices")]
    ForeignChoice {
        /// The state.
        state: usize,
        /// The choice.
        choice: usize,
    },
    /// The task could not be planned without the deadline.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// The duration-branching MDP could not be built or written.
    #[error(transparent)]
    Mdp(#[from] MdpError),
}

/// The law of an edge's traversal duration in whole buckets: `mass[i] = (b, p)` — `b ≥ 1`
/// buckets with probability `p`, `b` increasing —, and the probability `late` that the
/// traversal misses any deadline considered. The masses and `late` sum to one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BucketLaw {
    /// `(buckets, probability)`, buckets increasing and `≥ 1`, probabilities `> 0`.
    pub mass: Vec<(usize, f64)>,
    /// Probability of taking longer than any deadline considered.
    pub late: f64,
}

/// `max(1, ⌈secs / bucket⌉)`, forgiving [`ROUNDING_SLACK`] of a bucket; `None` beyond
/// `max_buckets` (or for a NaN or infinite duration).
fn buckets_of(secs: f64, bucket_secs: f64, max_buckets: usize) -> Option<usize> {
    let b = (secs / bucket_secs - ROUNDING_SLACK).ceil().max(1.0);
    (b.is_finite() && b <= max_buckets as f64).then_some(b as usize)
}

impl BucketLaw {
    /// A law from its masses, checked: buckets `≥ 1` and strictly increasing, probabilities in
    /// `(0, 1]`, `late` in `[0, 1]`, all summing to one within 1e-9.
    ///
    /// # Errors
    /// [`DeadlineError::InvalidLaw`] (with `action` 0: the caller knows which edge).
    pub fn new(mass: Vec<(usize, f64)>, late: f64) -> Result<Self, DeadlineError> {
        let law = BucketLaw { mass, late };
        law.check(0)?;
        Ok(law)
    }

    fn check(&self, action: usize) -> Result<(), DeadlineError> {
        let invalid = |reason: String| DeadlineError::InvalidLaw { action, reason };
        if !(0.0..=1.0).contains(&self.late) {
            return Err(invalid(format!(
                "late probability {} not in [0, 1]",
                self.late
            )));
        }
        let mut previous = 0;
        let mut sum = self.late;
        for &(b, p) in &self.mass {
            if b <= previous {
                return Err(invalid(format!(
                    "buckets {b} after {previous}: not increasing from 1"
                )));
            }
            if !(p > 0.0 && p <= 1.0) {
                return Err(invalid(format!(
                    "probability {p} of {b} buckets not in (0, 1]"
                )));
            }
            previous = b;
            sum += p;
        }
        if (sum - 1.0).abs() > 1e-9 {
            return Err(invalid(format!("probabilities sum to {sum}, not 1")));
        }
        Ok(())
    }

    /// A sure duration of `secs` seconds, rounded up to buckets of `bucket_secs` (late beyond
    /// `max_buckets`, or if not finite).
    pub fn point(secs: f64, bucket_secs: f64, max_buckets: usize) -> Self {
        match buckets_of(secs, bucket_secs, max_buckets) {
            Some(b) => BucketLaw {
                mass: vec![(b, 1.0)],
                late: 0.0,
            },
            None => BucketLaw {
                mass: Vec::new(),
                late: 1.0,
            },
        }
    }

    /// The law of the quantile function known at `n` levels `i / (n + 1)`, `i = 1..=n`
    /// (`durations[i − 1]` seconds, increasing): mass `1 / (n + 1)` on each level's duration
    /// rounded up to buckets (the longest duration of the slice below the level), the top
    /// slice and durations beyond `max_buckets` late (see the [module docs](self)). Masses of
    /// equal buckets are merged and computed as `count / (n + 1)`.
    pub fn from_quantiles(durations: &[f64], bucket_secs: f64, max_buckets: usize) -> Self {
        let slices = durations.len() + 1;
        let mut counts: Vec<(usize, usize)> = Vec::new();
        let mut on_time = 0;
        for &d in durations {
            let Some(b) = buckets_of(d, bucket_secs, max_buckets) else {
                continue;
            };
            on_time += 1;
            match counts.iter_mut().find(|(c, _)| *c == b) {
                Some((_, n)) => *n += 1,
                None => counts.push((b, 1)),
            }
        }
        counts.sort_unstable();
        BucketLaw {
            mass: counts
                .into_iter()
                .map(|(b, n)| (b, n as f64 / slices as f64))
                .collect(),
            late: (slices - on_time) as f64 / slices as f64,
        }
    }

    /// The probability of at most `k` buckets.
    pub fn within(&self, k: usize) -> f64 {
        self.mass
            .iter()
            .take_while(|&&(b, _)| b <= k)
            .fold(0.0, |sum, &(_, p)| sum + p)
    }

    /// The buckets of the law's median (`None` if it is late with probability ≥ 1/2).
    pub fn median(&self) -> Option<usize> {
        let mut sum = 0.0;
        self.mass.iter().find_map(|&(b, p)| {
            sum += p;
            (sum >= 0.5).then_some(b)
        })
    }

    /// Draws a duration: `Some(buckets)`, or `None` for late.
    fn sample(&self, rng: &mut Xoshiro256StarStar) -> Option<usize> {
        let mut u = rng.next_f64();
        for &(b, p) in &self.mass {
            if u < p {
                return Some(b);
            }
            u -= p;
        }
        None
    }
}

/// The values and the policy of the time-augmented product (see the [module docs](self)):
/// per cell `(state, k)`, `k` buckets left.
#[derive(Clone, Debug, PartialEq)]
pub struct DeadlineSolution {
    states: usize,
    buckets: usize,
    /// `values[k * states + s]`.
    values: Vec<f64>,
    /// `policy[k * states + s]`: a global choice index, [`NONE`] for none.
    policy: Vec<u32>,
}

impl DeadlineSolution {
    /// `K`: the most buckets left.
    pub fn buckets(&self) -> usize {
        self.buckets
    }

    /// Number of states.
    pub fn states(&self) -> usize {
        self.states
    }

    /// `V(state, k)`: the probability of reaching a goal within `k` buckets (0 out of range
    /// of the states; `k` beyond `K` reads `K`).
    pub fn value(&self, state: usize, k: usize) -> f64 {
        if state >= self.states {
            return 0.0;
        }
        self.values[k.min(self.buckets) * self.states + state]
    }

    /// The choice (global index) to take in `state` with `k` buckets left: `None` in goals,
    /// states without choices and states that cannot make it any more.
    pub fn choice(&self, state: usize, k: usize) -> Option<usize> {
        if state >= self.states {
            return None;
        }
        let c = self.policy[k.min(self.buckets) * self.states + state];
        (c != NONE).then_some(c as usize)
    }

    /// `V(state, k)` for `k = 0..=K`: the probability of reaching a goal within `k` buckets.
    pub fn curve(&self, state: usize) -> Vec<f64> {
        (0..=self.buckets).map(|k| self.value(state, k)).collect()
    }
}

/// Checks one law per action and that the cells fit.
fn check_inputs(
    mdp: &SparseMdp,
    laws: &[BucketLaw],
    buckets: usize,
    max_cells: usize,
) -> Result<(), DeadlineError> {
    if laws.len() != mdp.action_names().len() {
        return Err(DeadlineError::LengthMismatch {
            what: "duration laws",
            expected: mdp.action_names().len(),
            found: laws.len(),
        });
    }
    for (action, law) in laws.iter().enumerate() {
        law.check(action)?;
    }
    check_cells(mdp.state_count(), buckets as f64, max_cells)?;
    if mdp.choice_count() >= NONE as usize {
        return Err(DeadlineError::TooManyCells {
            states: mdp.state_count(),
            buckets: buckets as f64 + 1.0,
            cells: mdp.choice_count() as f64,
            max: NONE as usize,
        });
    }
    Ok(())
}

fn check_cells(states: usize, buckets: f64, max_cells: usize) -> Result<(), DeadlineError> {
    let cells = states as f64 * (buckets + 1.0);
    if cells > max_cells as f64 {
        return Err(DeadlineError::TooManyCells {
            states,
            buckets: buckets + 1.0,
            cells,
            max: max_cells,
        });
    }
    Ok(())
}

/// `Σ_{b ≤ k} L(b) · Σ_{s'} δ(c, s') · V(s', k − b)` with `V` of the finished rows.
fn choice_value(
    mdp: &SparseMdp,
    law: &BucketLaw,
    choice: usize,
    values: &[f64],
    states: usize,
    k: usize,
) -> f64 {
    // Folds from +0.0 (`Iterator::sum` of no `f64` is −0.0, printed "-0.0").
    law.mass
        .iter()
        .take_while(|&&(b, _)| b <= k)
        .fold(0.0, |sum, &(b, p)| {
            let row = &values[(k - b) * states..(k - b + 1) * states];
            sum + p * mdp.outcomes(choice).fold(0.0, |s, (t, q)| s + q * row[t])
        })
}

/// The backward induction of the [module docs](self) on `mdp` (a product whose actions are
/// edges, `laws[a]` the law of action `a`) for `0..=buckets` buckets left. Among choices within
/// 1e-12 of the best, `prefer[s]` (a global choice index, e.g. the expected-time plan's
/// [`crate::mdp::Solution::policy_choice`]) is kept, else the first.
///
/// # Errors
/// [`DeadlineError::LengthMismatch`] without one law per action or one preference per state,
/// [`DeadlineError::InvalidLaw`], [`DeadlineError::TooManyCells`] beyond `max_cells` cells.
pub fn solve_deadline(
    mdp: &SparseMdp,
    laws: &[BucketLaw],
    buckets: usize,
    prefer: Option<&[Option<usize>]>,
    max_cells: usize,
) -> Result<DeadlineSolution, DeadlineError> {
    check_inputs(mdp, laws, buckets, max_cells)?;
    let n = mdp.state_count();
    if let Some(prefer) = prefer
        && prefer.len() != n
    {
        return Err(DeadlineError::LengthMismatch {
            what: "preferred choices",
            expected: n,
            found: prefer.len(),
        });
    }
    let mut values = vec![0.0; n * (buckets + 1)];
    let mut policy = vec![NONE; n * (buckets + 1)];
    for k in 0..=buckets {
        let (done, row) = values.split_at_mut(k * n);
        for s in 0..n {
            if mdp.goal()[s] {
                row[s] = 1.0;
                continue;
            }
            let mut best = (0.0, NONE);
            for c in mdp.choices(s) {
                let v = choice_value(mdp, &laws[mdp.action(c)], c, done, n, k);
                if v > best.0 + TIE {
                    best = (v, c as u32);
                }
            }
            if best.1 != NONE
                && let Some(p) = prefer.and_then(|p| p[s])
                && mdp.choices(s).contains(&p)
            {
                let v = choice_value(mdp, &laws[mdp.action(p)], p, done, n, k);
                // The value of the choice kept: `V` is the value of the policy returned.
                if v >= best.0 - TIE {
                    best = (v, p as u32);
                }
            }
            row[s] = best.0;
            policy[k * n + s] = best.1;
        }
    }
    Ok(DeadlineSolution {
        states: n,
        buckets,
        values,
        policy,
    })
}

/// The probability of reaching a goal of `mdp` within `0..=buckets` buckets following the
/// memoryless `policy` (a global choice index per state, `None`: stop; e.g. the expected-time
/// plan's [`crate::mdp::Solution::policy_choice`]) — the recursion of the [module docs](self)
/// without the maximum.
///
/// # Errors
/// As [`solve_deadline`]; [`DeadlineError::ForeignChoice`] for a choice of another state.
pub fn evaluate_policy(
    mdp: &SparseMdp,
    laws: &[BucketLaw],
    buckets: usize,
    policy: &[Option<usize>],
    max_cells: usize,
) -> Result<DeadlineSolution, DeadlineError> {
    check_inputs(mdp, laws, buckets, max_cells)?;
    let n = mdp.state_count();
    if policy.len() != n {
        return Err(DeadlineError::LengthMismatch {
            what: "policy",
            expected: n,
            found: policy.len(),
        });
    }
    for (state, &c) in policy.iter().enumerate() {
        if let Some(choice) = c
            && !mdp.choices(state).contains(&choice)
        {
            return Err(DeadlineError::ForeignChoice { state, choice });
        }
    }
    let mut values = vec![0.0; n * (buckets + 1)];
    let mut table = vec![NONE; n * (buckets + 1)];
    for k in 0..=buckets {
        let (done, row) = values.split_at_mut(k * n);
        for s in 0..n {
            if mdp.goal()[s] {
                row[s] = 1.0;
            } else if let Some(c) = policy[s] {
                row[s] = choice_value(mdp, &laws[mdp.action(c)], c, done, n, k);
                table[k * n + s] = c as u32;
            }
        }
    }
    Ok(DeadlineSolution {
        states: n,
        buckets,
        values,
        policy: table,
    })
}

/// Runs `solution`'s policy `runs` times from `mdp`'s initial state with all `K` buckets
/// left, drawing each traversal's duration from `laws` and its outcome from `mdp`: the number
/// of runs that reach a goal in time. The Monte Carlo check of [`solve_deadline`] and
/// [`evaluate_policy`] (the frequency estimates `V(initial, K)`).
pub fn simulate(
    mdp: &SparseMdp,
    laws: &[BucketLaw],
    solution: &DeadlineSolution,
    runs: usize,
    rng: &mut Xoshiro256StarStar,
) -> usize {
    let mut reached = 0;
    for _ in 0..runs {
        let (mut s, mut k) = (mdp.initial(), solution.buckets());
        loop {
            if mdp.goal()[s] {
                reached += 1;
                break;
            }
            let Some(c) = solution.choice(s, k) else {
                break;
            };
            let law = &laws[mdp.action(c)];
            match law.sample(rng) {
                Some(b) if b <= k => k -= b,
                _ => break,
            }
            let mut u = rng.next_f64();
            let mut next = None;
            for (t, q) in mdp.outcomes(c) {
                next = Some(t);
                if u < q {
                    break;
                }
                u -= q;
            }
            match next {
                Some(t) => s = t,
                None => break,
            }
        }
    }
    reached
}

/// The *duration-branching* MDP of `mdp` and `laws`, for model checkers that bound rewards
/// (Storm: `Pmax=? [F{"time"}<=K "goal"]` is [`DeadlineSolution::value`]`(initial, K)`): the
/// states of `mdp` keep their numbers, goals and initial state; each choice `c` (edge `e`,
/// reward 0) leads with `L_e(b)` to a new state "`c` takes `b` buckets", whose one choice (the
/// same edge, reward `b`) has `c`'s outcomes; its late mass leads to one absorbing state
/// `late` (the last). With `policy` (a global choice index per state, `None`: stop), only
/// those choices are kept: the Markov chain of a memoryless plan.
///
/// # Errors
/// As [`solve_deadline`] and [`SparseMdp::new`].
pub fn duration_branching_mdp(
    mdp: &SparseMdp,
    laws: &[BucketLaw],
    policy: Option<&[Option<usize>]>,
) -> Result<SparseMdp, DeadlineError> {
    check_inputs(mdp, laws, 0, usize::MAX)?;
    let n = mdp.state_count();
    if let Some(policy) = policy
        && policy.len() != n
    {
        return Err(DeadlineError::LengthMismatch {
            what: "policy",
            expected: n,
            found: policy.len(),
        });
    }
    let mut rows: Vec<Vec<Choice>> = vec![Vec::new(); n];
    let mut intermediate: Vec<Vec<Choice>> = Vec::new();
    let late_state = usize::MAX; // patched below, once the count is known
    for (s, row) in rows.iter_mut().enumerate() {
        for c in mdp.choices(s) {
            if policy.is_some_and(|p| p[s] != Some(c)) {
                continue;
            }
            let e = mdp.action(c);
            let mut outcomes = Vec::new();
            for &(b, p) in &laws[e].mass {
                outcomes.push((n + intermediate.len(), p));
                intermediate.push(vec![Choice {
                    action: e,
                    cost: b as f64,
                    outcomes: mdp.outcomes(c).collect(),
                }]);
            }
            if laws[e].late > 0.0 {
                outcomes.push((late_state, laws[e].late));
            }
            row.push(Choice {
                action: e,
                cost: 0.0,
                outcomes,
            });
        }
    }
    let late = n + intermediate.len();
    for row in &mut rows {
        for choice in row {
            for (t, _) in &mut choice.outcomes {
                if *t == late_state {
                    *t = late;
                }
            }
        }
    }
    rows.extend(intermediate);
    rows.push(Vec::new());
    let mut goal = mdp.goal().to_vec();
    goal.resize(rows.len(), false);
    Ok(SparseMdp::new(
        mdp.initial(),
        goal,
        mdp.action_names().to_vec(),
        rows,
    )?)
}

/// Settings of [`plan_deadline`].
#[derive(Clone, Debug, PartialEq)]
pub struct DeadlineOptions {
    /// Bucket width `Δ` (seconds); `None`: `max(D / 600, 1 s)`, at most `D`.
    pub bucket_secs: Option<f64>,
    /// Most cells `states × (K + 1)` of the time-augmented product. Default 10⁶.
    pub max_cells: usize,
    /// Settings of the expected-time planner.
    pub solver: SolverOptions,
}

impl Default for DeadlineOptions {
    fn default() -> Self {
        DeadlineOptions {
            bucket_secs: None,
            max_cells: DEFAULT_MAX_CELLS,
            solver: SolverOptions::default(),
        }
    }
}

/// The deadline plan for one start time and deadline, beside the expected-time plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DeadlinePlan {
    /// The start time.
    pub time: f64,
    /// The deadline `D` (seconds after the start).
    pub deadline_secs: f64,
    /// The bucket width `Δ` (seconds).
    pub bucket_secs: f64,
    /// `K = ⌊D / Δ⌋`: buckets within the deadline.
    pub buckets: usize,
    /// The greatest probability of fulfilling the task within the deadline (a lower bound,
    /// see the [module docs](self)).
    pub probability: f64,
    /// The first edge to take (`None`: the task holds already, or cannot be fulfilled in time).
    pub first_edge: Option<usize>,
    /// The probability of the expected-time plan ([`crate::plan`]) fulfilling the task within
    /// the deadline, under the same laws.
    pub min_time_probability: f64,
    /// The expected-time plan's first edge.
    pub min_time_first_edge: Option<usize>,
    /// `Pmax` without a deadline.
    pub pmax: f64,
    /// The expected-time plan's expected time (seconds, until done or failed).
    pub expected_secs: f64,
    /// `curve[k]`: the greatest probability of fulfilling the task within `k·Δ`, `k = 0..=K`.
    pub curve: Vec<f64>,
    /// `min_time_curve[k]`: the expected-time plan's probability within `k·Δ`.
    pub min_time_curve: Vec<f64>,
    /// Whether the laws come from the duration quantiles (else: sure expected durations).
    pub duration_quantiles: bool,
}

impl DeadlinePlan {
    /// The shortest deadline `k·Δ` (seconds) within which the task can be fulfilled with
    /// probability at least `confidence`; `None` if not within [`Self::deadline_secs`].
    pub fn shortest_deadline(&self, confidence: f64) -> Option<f64> {
        self.curve
            .iter()
            .position(|&p| p >= confidence)
            .map(|k| k as f64 * self.bucket_secs)
    }
}

/// A deadline plan with what it was computed from.
pub struct DeadlinePlanned {
    /// The expected-time plan: the Navigation MDP, the product, its solution.
    pub planned: Planned,
    /// The duration law of every edge.
    pub laws: Vec<BucketLaw>,
    /// The deadline policy and its values.
    pub solution: DeadlineSolution,
    /// The expected-time plan's values under the deadline.
    pub min_time: DeadlineSolution,
    /// The summary.
    pub plan: DeadlinePlan,
}

impl DeadlinePlanned {
    /// The route of the deadline plan if every edge succeeds and takes its median duration,
    /// as edge indices (stops where the median is late or time runs out).
    pub fn median_route(&self) -> Vec<usize> {
        let (product, map) = (&self.planned.product, &self.planned.mdp);
        let mut route = Vec::new();
        let (mut s, mut k) = (self.planned.solution.initial, self.solution.buckets());
        while let Some(c) = self.solution.choice(s, k) {
            let edge = product.mdp().action(c);
            route.push(edge);
            let Some(b) = self.laws[edge].median().filter(|&b| b <= k) else {
                break;
            };
            k -= b;
            match product.successor(s, c, Some(map.edges()[edge].to)) {
                Some(next) => s = next,
                None => break,
            }
        }
        route
    }
}

/// The default bucket width of a deadline `D`: `D / 600`, at least
/// [`MIN_DEFAULT_BUCKET_SECS`] and at most `D` (one bucket).
fn default_bucket_secs(deadline_secs: f64) -> f64 {
    (deadline_secs / DEFAULT_BUCKETS)
        .max(MIN_DEFAULT_BUCKET_SECS)
        .min(deadline_secs)
}

/// "Now or later, to be there in time?": the deadline plan ([`plan_deadline`]) at each of
/// `times`, the now-or-later question of [Fentanes 2015] Table III asked of a deadline.
/// `planned` is called after each time (for progress: one plan can take seconds).
///
/// # Errors
/// As [`plan_deadline`], for the first time that cannot be planned.
pub fn now_or_later_by_deadline(
    models: &EdgeModels,
    start: usize,
    task: &Task,
    times: &[f64],
    deadline_secs: f64,
    options: &DeadlineOptions,
    mut planned: impl FnMut(),
) -> Result<Vec<DeadlinePlan>, DeadlineError> {
    times
        .iter()
        .map(|&time| {
            let plan = plan_deadline(models, start, task, time, deadline_secs, options);
            planned();
            plan.map(|d| d.plan)
        })
        .collect()
}

/// The bucket width and `K` for a deadline.
///
/// # Errors
/// [`DeadlineError::InvalidDeadline`], [`DeadlineError::InvalidBucket`],
/// [`DeadlineError::BucketWiderThanDeadline`].
pub fn buckets_for(
    deadline_secs: f64,
    bucket_secs: Option<f64>,
) -> Result<(f64, f64), DeadlineError> {
    if !(deadline_secs.is_finite() && deadline_secs > 0.0) {
        return Err(DeadlineError::InvalidDeadline(deadline_secs));
    }
    let width = bucket_secs.unwrap_or_else(|| default_bucket_secs(deadline_secs));
    if !(width.is_finite() && width > 0.0) {
        return Err(DeadlineError::InvalidBucket(width));
    }
    if width > deadline_secs {
        return Err(DeadlineError::BucketWiderThanDeadline {
            bucket: width,
            deadline: deadline_secs,
        });
    }
    // ⌊D / Δ⌋, forgiving the noise of D / (D / 600).
    let k = (deadline_secs / width + ROUNDING_SLACK).floor();
    Ok((width, k))
}

/// The duration law of every edge of `models` at `time` in buckets of `bucket_secs`, at most
/// `max_buckets` (see the [module docs](self)); whether they come from the quantiles.
pub fn edge_laws(
    models: &EdgeModels,
    time: f64,
    bucket_secs: f64,
    max_buckets: usize,
) -> (Vec<BucketLaw>, bool) {
    let edges = models.map().edges().len();
    let spread = models.duration_spread();
    let mut quantiles = true;
    let laws = (0..edges)
        .map(|e| {
            let expected = models.expected_duration(e, time);
            match spread.durations(e, expected) {
                Some(durations) => BucketLaw::from_quantiles(&durations, bucket_secs, max_buckets),
                None => {
                    quantiles = false;
                    BucketLaw::point(expected, bucket_secs, max_buckets)
                }
            }
        })
        .collect();
    (laws, quantiles)
}

/// The deadline plan for `task` from node `start` at `time` with `deadline_secs` seconds
/// (see the [module docs](self)), beside the expected-time plan of [`plan_full`] evaluated
/// under the same deadline.
///
/// # Errors
/// [`DeadlineError::InvalidDeadline`], [`DeadlineError::InvalidBucket`],
/// [`DeadlineError::TooManyCells`], [`DeadlineError::Plan`] as [`plan_full`].
pub fn plan_deadline(
    models: &EdgeModels,
    start: usize,
    task: &Task,
    time: f64,
    deadline_secs: f64,
    options: &DeadlineOptions,
) -> Result<DeadlinePlanned, DeadlineError> {
    let (bucket_secs, k) = buckets_for(deadline_secs, options.bucket_secs)?;
    let planned = plan_full(models, start, task, time, &options.solver)?;
    // Refuse before allocating anything of the size of K (`k as usize` saturates).
    check_cells(planned.product.states().len(), k, options.max_cells)?;
    let buckets = k as usize;
    let (laws, duration_quantiles) = edge_laws(models, time, bucket_secs, buckets);
    let mdp = planned.product.mdp();
    let prefer = &planned.solution.policy_choice;
    let solution = solve_deadline(mdp, &laws, buckets, Some(prefer), options.max_cells)?;
    let min_time = evaluate_policy(mdp, &laws, buckets, prefer, options.max_cells)?;
    let initial = planned.solution.initial;
    let choice_edge = |c: Option<usize>| c.map(|c| mdp.action(c));
    let plan = DeadlinePlan {
        time,
        deadline_secs,
        bucket_secs,
        buckets,
        probability: solution.value(initial, buckets),
        first_edge: choice_edge(solution.choice(initial, buckets)),
        min_time_probability: min_time.value(initial, buckets),
        min_time_first_edge: planned.plan.first_edge,
        pmax: planned.plan.pmax,
        expected_secs: planned.plan.expected_secs,
        curve: solution.curve(initial),
        min_time_curve: min_time.curve(initial),
        duration_quantiles,
    };
    Ok(DeadlinePlanned {
        planned,
        laws,
        solution,
        min_time,
        plan,
    })
}

#[cfg(test)]
mod tests;
