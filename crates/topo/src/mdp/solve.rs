//! Maximum reachability probability, then minimum expected cost among the `Pmax`-optimal
//! choices, and the policy (see the [module documentation](super) for the definitions).

use super::graph::{Classes, Predecessors, mecs};
use super::{MdpError, SparseMdp};

const NONE: usize = usize::MAX;

/// Sweeps allowed to prove the optimistic upper bound before falling back to the interval
/// iteration from 1.
const OPTIMISTIC_SWEEPS: usize = 8;

/// Solver settings.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverOptions {
    /// Convergence threshold: an iteration stops when the largest change of a sweep is below
    /// it (absolute for probabilities, relative to `max(1, |C(s)|)` for costs). It is also the
    /// relative tolerance of "one-step value equals `Pmax(s)`" (widened to the certified
    /// [`Solution::gap`] when that is larger) and of cost ties. Default `1e-12`.
    pub tolerance: f64,
    /// Most sweeps of one value iteration. Default `1_000_000`.
    pub max_iterations: usize,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            tolerance: 1e-12,
            max_iterations: 1_000_000,
        }
    }
}

/// Sweeps used by each iteration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Iterations {
    /// Value iteration for `Pmax` from below.
    pub pmax: usize,
    /// Interval iteration for `Pmax` from above (stops early once the gap is below the
    /// tolerance; not an error if it reaches the cap: the gap then says how far it got).
    pub pmax_upper: usize,
    /// Value iteration for the expected cost.
    pub cost: usize,
}

/// The solution of an MDP with goal states (see the [module documentation](super)).
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// The initial state.
    pub initial: usize,
    /// `Pmax` at the initial state (lower bound from value iteration).
    pub pmax_initial: f64,
    /// Expected cost at the initial state (`+∞` if no restricted policy decides the run
    /// almost surely).
    pub cost_initial: f64,
    /// `Pmax(s)` per state: the value iteration from below (a lower bound).
    pub pmax: Vec<f64>,
    /// Upper bounds of `Pmax(s)` from the interval iteration.
    pub pmax_upper: Vec<f64>,
    /// `max_s (pmax_upper[s] − pmax[s])`, at least 0: the certified precision of `pmax`.
    pub gap: f64,
    /// Expected cost `C(s)` per state until the run is decided (0 in decided states).
    pub cost: Vec<f64>,
    /// Decided states: goals, and states from which no goal is reachable with `Pmax`-optimal
    /// choices (the failure sink, `Pmax = 0`).
    pub decided: Vec<bool>,
    /// Per choice: whether it is `Pmax`-optimal (kept in the restricted MDP). Always false for
    /// choices of goal states and of states with `Pmax = 0`.
    pub optimal: Vec<bool>,
    /// Per state, the action of the chosen choice (an edge index in a product); `None` in
    /// decided states.
    pub policy: Vec<Option<usize>>,
    /// Per state, the chosen choice (global choice index); `None` in decided states.
    pub policy_choice: Vec<Option<usize>>,
    /// Number of states.
    pub state_count: usize,
    /// Number of choices.
    pub choice_count: usize,
    /// Sweeps used.
    pub iterations: Iterations,
}

/// Counts one more sweep of a value iteration, or fails with [`MdpError::NotConverged`] once
/// `options.max_iterations` sweeps left it changing by `change`.
fn next_sweep(
    count: &mut usize,
    options: &SolverOptions,
    what: &'static str,
    change: f64,
) -> Result<(), MdpError> {
    if *count == options.max_iterations {
        return Err(MdpError::NotConverged {
            what,
            iterations: *count,
            change,
        });
    }
    *count += 1;
    Ok(())
}

/// Solves `mdp`: `Pmax`, the expected cost among `Pmax`-optimal choices, and the policy.
///
/// # Errors
/// [`MdpError::InvalidOptions`] for a tolerance that is not in `(0, 1)` or a zero iteration
/// cap; [`MdpError::NotConverged`] if the `Pmax` or the cost iteration reaches the cap.
pub fn solve(mdp: &SparseMdp, options: &SolverOptions) -> Result<Solution, MdpError> {
    let tol = options.tolerance;
    if !(tol > 0.0 && tol < 1.0) {
        return Err(MdpError::InvalidOptions(format!(
            "tolerance {tol} is not in (0, 1)"
        )));
    }
    if options.max_iterations == 0 {
        return Err(MdpError::InvalidOptions(
            "max_iterations must be at least 1".into(),
        ));
    }
    let n = mdp.state_count();
    let m = mdp.choice_count();
    let goal = mdp.goal();
    let pred = Predecessors::new(mdp);
    let owner = &pred.owner;
    let mut iterations = Iterations::default();

    // 1. Qualitative step: Pmax = 0 exactly where no goal is reachable at all.
    let can_reach = pred.backward(goal, |_| true);
    let maybe: Vec<bool> = (0..n).map(|s| can_reach[s] && !goal[s]).collect();
    let order: Vec<usize> = (0..n).rev().filter(|&s| maybe[s]).collect();

    // 2. Value iteration from below (Gauss-Seidel; values only grow).
    let mut x: Vec<f64> = goal.iter().map(|&g| f64::from(u8::from(g))).collect();
    let mut change = f64::INFINITY;
    while !order.is_empty() && change >= tol {
        next_sweep(
            &mut iterations.pmax,
            options,
            "Pmax value iteration",
            change,
        )?;
        change = 0.0;
        for &s in &order {
            let best = mdp
                .choices(s)
                .map(|c| mdp.expect(c, &x))
                .fold(0.0, f64::max);
            change = change.max((best - x[s]).abs());
            x[s] = best;
        }
    }

    // 3. Interval iteration from above on the quotient by the maximal end components of the
    // undecided states (without them the iteration from 1 could stay at 1 in a cycle).
    let mec = mecs(mdp, &maybe, |_| true);
    let classes = Classes::new(&maybe, &mec);
    let internal = |c: usize, id: &[usize]| {
        let k = id[owner[c]];
        k != NONE && mdp.targets(c).iter().all(|&t| id[t] == k)
    };
    let exits: Vec<bool> = (0..m)
        .map(|c| maybe[owner[c]] && !internal(c, &mec))
        .collect();
    let class_value = |k: usize, u: &[f64]| {
        classes
            .members(k)
            .iter()
            .flat_map(|&s| mdp.choices(s))
            .filter(|&c| exits[c])
            .map(|c| mdp.expect(c, u))
            .fold(0.0, f64::max)
    };
    let gap_of = |u: &[f64]| order.iter().map(|&s| u[s] - x[s]).fold(0.0, f64::max);
    // 3a. Optimistic value iteration (Hartmanns and Kaminski, CAV 2020): guess an upper bound
    // just above x and check that one Bellman sweep of the quotient does not raise it. On the
    // quotient the Bellman operator B has Pmax as its only fixpoint and B^k(u) → Pmax from any
    // u, so B(u) ≤ u (B is monotone) proves Pmax ≤ B(u) ≤ u. Usually one or two sweeps instead
    // of the hundreds the iteration from 1 needs to close the gap.
    let mut u: Vec<f64> = (0..n).map(|s| f64::from(u8::from(goal[s]))).collect();
    for k in 0..classes.len() {
        let members = classes.members(k);
        let guess = members
            .iter()
            .map(|&s| x[s] + 0.5 * tol)
            .fold(0.0, f64::max)
            .min(1.0);
        for &s in members {
            u[s] = guess;
        }
    }
    let mut verified = false;
    let mut next = vec![0.0; classes.len()];
    while classes.len() > 0 && iterations.pmax_upper < OPTIMISTIC_SWEEPS.min(options.max_iterations)
    {
        iterations.pmax_upper += 1;
        let mut inductive = true;
        let mut below_lower = false;
        for (k, value) in next.iter_mut().enumerate() {
            let members = classes.members(k);
            *value = class_value(k, &u);
            inductive &= *value <= u[members[0]];
            below_lower |= members.iter().any(|&s| *value < x[s]);
        }
        for (k, &value) in next.iter().enumerate() {
            for &s in classes.members(k) {
                u[s] = value;
            }
        }
        if inductive {
            verified = true;
            break;
        }
        if below_lower {
            // The guess was below Pmax somewhere: it cannot become a proof.
            break;
        }
    }
    if !verified {
        // 3b. Interval iteration from the trivial upper bound.
        for s in 0..n {
            u[s] = f64::from(u8::from(goal[s] || maybe[s]));
        }
    }
    while classes.len() > 0
        && iterations.pmax_upper < options.max_iterations
        && (!verified || gap_of(&u) >= tol)
    {
        iterations.pmax_upper += 1;
        let mut change = 0.0f64;
        for k in 0..classes.len() {
            let members = classes.members(k);
            let best = class_value(k, &u);
            change = change.max((best - u[members[0]]).abs());
            for &s in members {
                u[s] = best;
            }
        }
        if change < tol || gap_of(&u) < tol {
            break;
        }
    }
    let gap = gap_of(&u);

    // 4. The restricted MDP: choices whose one-step value equals Pmax(s). As x ≤ Pmax ≤ u,
    // a truly optimal choice c has value(c, x) ≥ Pmax(s) − gap ≥ best − gap: widening the
    // tolerance to the gap keeps every optimal choice (and admits choices at most 2·gap
    // worse).
    let mut optimal = vec![false; m];
    for &s in &order {
        let best = mdp
            .choices(s)
            .map(|c| mdp.expect(c, &x))
            .fold(0.0, f64::max);
        let threshold = best - (tol * best).max(gap);
        for c in mdp.choices(s) {
            optimal[c] = mdp.expect(c, &x) >= threshold;
        }
    }

    // 5. Decided: goals, and states from which no goal is reachable in the restricted MDP.
    let reach = pred.backward(goal, |c| optimal[c]);
    let decided: Vec<bool> = (0..n).map(|s| goal[s] || !reach[s]).collect();

    // 6. Where some restricted policy decides the run almost surely (else the cost is +∞).
    let finite = pred.prob1e(mdp, &decided, |c| optimal[c]);
    let open: Vec<bool> = (0..n).map(|s| finite[s] && !decided[s]).collect();
    let allowed: Vec<bool> = (0..m)
        .map(|c| optimal[c] && open[owner[c]] && mdp.targets(c).iter().all(|&t| finite[t]))
        .collect();

    // 7. Minimum expected cost until decided: value iteration from 0 on the quotient by the
    // zero-cost end components (which would otherwise keep it at a too-low fixpoint).
    let zero = mecs(mdp, &open, |c| allowed[c] && mdp.cost(c) == 0.0);
    let classes = Classes::new(&open, &zero);
    let exits: Vec<bool> = (0..m)
        .map(|c| allowed[c] && !(mdp.cost(c) == 0.0 && internal(c, &zero)))
        .collect();
    let mut y: Vec<f64> = (0..n)
        .map(|s| if finite[s] { 0.0 } else { f64::INFINITY })
        .collect();
    let mut change = f64::INFINITY;
    while classes.len() > 0 && change >= tol {
        next_sweep(
            &mut iterations.cost,
            options,
            "expected cost value iteration",
            change,
        )?;
        change = 0.0;
        for k in 0..classes.len() {
            let members = classes.members(k);
            let best = members
                .iter()
                .flat_map(|&s| mdp.choices(s))
                .filter(|&c| exits[c])
                .map(|c| mdp.cost(c) + mdp.expect(c, &y))
                .fold(f64::INFINITY, f64::min);
            let old = y[members[0]];
            if best != old {
                change = change.max((best - old).abs() / best.abs().max(1.0));
            }
            for &s in members {
                y[s] = best;
            }
        }
    }

    // 8. The policy: the least-cost restricted choice, first in order among ties ...
    let mut greedy = vec![false; m];
    let mut policy_choice: Vec<Option<usize>> = vec![None; n];
    for s in (0..n).filter(|&s| open[s]) {
        let q = |c: usize| mdp.cost(c) + mdp.expect(c, &y);
        let best = mdp
            .choices(s)
            .filter(|&c| allowed[c])
            .map(q)
            .fold(f64::INFINITY, f64::min);
        let threshold = best + tol * best.abs().max(1.0);
        for c in mdp.choices(s).filter(|&c| allowed[c]) {
            greedy[c] = q(c) <= threshold;
        }
        policy_choice[s] = mdp.choices(s).find(|&c| greedy[c]);
    }
    // ... unless that loops forever through zero-cost choices: then, in the states that do
    // not reach a decided state almost surely, take the first tied choice with an outcome in a
    // state that does (attractor layers; all its outcomes stay where the cost is finite).
    let follows = |c: usize, policy: &[Option<usize>]| policy[owner[c]] == Some(c);
    let reaches = pred.backward(&decided, |c| follows(c, &policy_choice));
    let stuck: Vec<bool> = (0..n).map(|s| open[s] && !reaches[s]).collect();
    let bad = pred.backward(&stuck, |c| follows(c, &policy_choice));
    let mut assigned: Vec<bool> = (0..n).map(|s| decided[s] || (open[s] && !bad[s])).collect();
    for candidates in [&greedy, &allowed] {
        loop {
            let mut progress = false;
            for s in 0..n {
                if !open[s] || assigned[s] {
                    continue;
                }
                let next = mdp
                    .choices(s)
                    .find(|&c| candidates[c] && mdp.targets(c).iter().any(|&t| assigned[t]));
                if let Some(c) = next {
                    policy_choice[s] = Some(c);
                    assigned[s] = true;
                    progress = true;
                }
            }
            if !progress {
                break;
            }
        }
    }
    // States where the cost is infinite (a numerical problem): the first Pmax-optimal choice.
    for s in (0..n).filter(|&s| !decided[s] && !finite[s]) {
        policy_choice[s] = mdp.choices(s).find(|&c| optimal[c]);
    }
    let policy = policy_choice
        .iter()
        .map(|c| c.map(|c| mdp.action(c)))
        .collect();

    let initial = mdp.initial();
    Ok(Solution {
        initial,
        pmax_initial: x[initial],
        cost_initial: y[initial],
        pmax: x,
        pmax_upper: u,
        gap,
        cost: y,
        decided,
        optimal,
        policy,
        policy_choice,
        state_count: n,
        choice_count: m,
        iterations,
    })
}
