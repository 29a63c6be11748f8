use super::*;
use chronomap_core::rng::Xoshiro256StarStar;

use crate::map::test_map as map;

/// `F target`: state 0 waits, state 1 accepts.
fn eventually(target: &str) -> Dfa {
    Dfa {
        atoms: vec![target.into()],
        initial: 0,
        accepting: vec![false, true],
        delta: vec![1, 0, 1, 1],
    }
}

/// `F (a & F b)`: 0 = nothing yet, 1 = a seen, 2 = accept. Letters a, b, none.
fn ordered(a: &str, b: &str) -> Dfa {
    Dfa {
        atoms: vec![a.into(), b.into()],
        initial: 0,
        accepting: vec![false, false, true],
        delta: vec![1, 0, 0, 1, 2, 1, 2, 2, 2],
    }
}

/// `!x U y`: 0 = waiting, 1 = violated (trap), 2 = accept. Letters x, y, none.
fn avoid_until(x: &str, y: &str) -> Dfa {
    Dfa {
        atoms: vec![x.into(), y.into()],
        initial: 0,
        accepting: vec![false, false, true],
        delta: vec![1, 2, 0, 1, 1, 1, 2, 2, 2],
    }
}

fn solve_nav(
    nodes: &[&str],
    edges: &[(&str, &str, &str, f64, f64)],
    start: &str,
    dfa: &Dfa,
) -> (NavigationMdp, ProductMdp, Solution) {
    let triples: Vec<(&str, &str, &str)> = edges.iter().map(|e| (e.0, e.1, e.2)).collect();
    let m = map(nodes, &triples);
    let success: Vec<f64> = edges.iter().map(|e| e.3).collect();
    let duration: Vec<f64> = edges.iter().map(|e| e.4).collect();
    let nav = NavigationMdp::new(&m, &success, &duration).unwrap();
    let product = nav.product(m.node(start).unwrap(), dfa).unwrap();
    let solution = product.solve(&SolverOptions::default()).unwrap();
    (nav, product, solution)
}

fn edge_of(nav: &NavigationMdp, id: &str) -> usize {
    nav.edges().iter().position(|e| e.id == id).unwrap()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
}

/// A slowly leaking loop: 0 stays with 0.999, reaches the goal 1 with 0.001 (Pmax = 1).
fn leaky_loop() -> SparseMdp {
    SparseMdp::new(
        0,
        vec![false, true],
        vec!["a".into()],
        vec![
            vec![Choice {
                action: 0,
                cost: 1.0,
                outcomes: vec![(0, 0.999), (1, 0.001)],
            }],
            vec![],
        ],
    )
    .unwrap()
}

/// `F G` from S on a direct edge S_G (`success`, `duration`) and a detour S_M, M_G (0.9, 30 s
/// each).
fn direct_or_detour(success: f64, duration: f64) -> (NavigationMdp, ProductMdp, Solution) {
    solve_nav(
        &["S", "M", "G"],
        &[
            ("S_G", "S", "G", success, duration),
            ("S_M", "S", "M", 0.9, 30.0),
            ("M_G", "M", "G", 0.9, 30.0),
        ],
        "S",
        &eventually("G"),
    )
}

#[test]
fn navigation_mdp_follows_seed_003_definition() {
    let m = map(&["A", "B"], &[("A_B", "A", "B"), ("B_A", "B", "A")]);
    let nav = NavigationMdp::new(&m, &[0.7, 1.0], &[12.5, 3.0]).unwrap();
    assert_eq!((nav.node_count(), nav.state_count(), nav.sink()), (2, 3, 2));
    // δ(A, A_B, B) = 0.7, δ(A, A_B, s_f) = 0.3; the certain edge has no failure outcome.
    let ab: Vec<(usize, f64)> = nav.outcomes(0).collect();
    assert_eq!(ab.len(), 2);
    assert_eq!(ab[0], (1, 0.7));
    assert_eq!(ab[1].0, 2);
    assert!(close(ab[1].1, 0.3));
    assert_eq!(nav.outcomes(1).collect::<Vec<_>>(), vec![(0, 1.0)]);
    assert_eq!(nav.actions(0), &[0]);
    assert!(nav.actions(nav.sink()).is_empty());
    assert_eq!(nav.outcomes(7).count(), 0);
}

#[test]
fn chain_with_one_risky_edge_has_pmax_p() {
    let (nav, product, sol) = solve_nav(
        &["A", "B", "C"],
        &[("A_B", "A", "B", 1.0, 5.0), ("B_C", "B", "C", 0.3, 7.0)],
        "A",
        &eventually("C"),
    );
    assert!(close(sol.pmax_initial, 0.3), "{}", sol.pmax_initial);
    // Both edges are always taken: the run is decided at C or in the sink after B_C.
    assert!(close(sol.cost_initial, 12.0), "{}", sol.cost_initial);
    assert_eq!(sol.policy[0], Some(edge_of(&nav, "A_B")));
    let at_b = product
        .index_of(ProductState {
            node: Some(1),
            dfa_state: 0,
        })
        .unwrap();
    assert_eq!(sol.policy[at_b], Some(edge_of(&nav, "B_C")));
    assert!(close(sol.pmax[at_b], 0.3));
    assert!(close(sol.cost[at_b], 7.0));
    assert!(sol.gap < 1e-12, "gap {}", sol.gap);
    // The optimistic upper bound x + tol/2 is proved by one Bellman sweep.
    assert_eq!(sol.iterations.pmax_upper, 1);
    // A, B, C (goal) and the sink.
    assert_eq!((sol.state_count, sol.choice_count), (4, 2));
}

#[test]
fn a_long_safe_route_beats_a_short_risky_one() {
    let (nav, _, sol) = direct_or_detour(0.5, 10.0);
    assert!(close(sol.pmax_initial, 0.81), "{}", sol.pmax_initial);
    assert_eq!(sol.policy[0], Some(edge_of(&nav, "S_M")));
    // 30 s, then 30 s more if S_M succeeded.
    assert!(
        close(sol.cost_initial, 30.0 + 0.9 * 30.0),
        "{}",
        sol.cost_initial
    );
    // The risky edge is not Pmax-optimal.
    let s_g = sol.policy_choice[0].unwrap() - 1;
    assert!(!sol.optimal[s_g]);
}

#[test]
fn a_tie_in_probability_goes_to_the_cheaper_route() {
    // The direct edge comes first in edge order but takes 100 s; the detour has the same
    // probability 0.9 · 0.9 = 0.81 and takes 30 + 0.9 · 30 = 57 s in expectation.
    let (nav, _, sol) = direct_or_detour(0.81, 100.0);
    assert!(close(sol.pmax_initial, 0.81));
    assert!(
        sol.optimal[0] && sol.optimal[1],
        "both routes are Pmax-optimal"
    );
    assert_eq!(sol.policy[0], Some(edge_of(&nav, "S_M")));
    assert!(close(sol.cost_initial, 57.0), "{}", sol.cost_initial);
    // A tie in both probability and cost goes to the first edge.
    let (nav, _, sol) = solve_nav(
        &["S", "G"],
        &[
            ("S_G_1", "S", "G", 0.5, 10.0),
            ("S_G_2", "S", "G", 0.5, 10.0),
        ],
        "S",
        &eventually("G"),
    );
    assert_eq!(sol.policy[0], Some(edge_of(&nav, "S_G_1")));
    assert!(close(sol.cost_initial, 10.0));
}

#[test]
fn an_unreachable_goal_has_pmax_zero() {
    let (_, _, sol) = solve_nav(
        &["A", "B", "G"],
        &[("A_B", "A", "B", 0.9, 5.0), ("G_A", "G", "A", 1.0, 5.0)],
        "A",
        &eventually("G"),
    );
    assert_eq!(sol.pmax_initial, 0.0);
    assert_eq!(sol.cost_initial, 0.0, "nothing to gain: decided at once");
    assert!(sol.decided[0]);
    assert_eq!(sol.policy[0], None);
    assert!(sol.optimal.iter().all(|&o| !o));
}

#[test]
fn a_goal_at_the_start_has_pmax_one_and_costs_nothing() {
    let (_, product, sol) = solve_nav(
        &["G", "A"],
        &[("G_A", "G", "A", 0.5, 5.0)],
        "G",
        &eventually("G"),
    );
    assert_eq!((sol.pmax_initial, sol.cost_initial), (1.0, 0.0));
    assert_eq!(sol.policy[0], None);
    // The goal is absorbing: the product has no other state.
    assert_eq!((product.states().len(), sol.choice_count), (1, 0));
}

#[test]
fn ordered_visit_product_is_hand_computed() {
    // F (A & F B) from H. Routes: H→A→B 0.9·0.5 = 0.45; H→A→H→B 0.9·1·0.8 = 0.72;
    // H→B→A→H→B 0.8·1·1·0.8 = 0.64. The best detours through H after A.
    let (nav, product, sol) = solve_nav(
        &["H", "A", "B"],
        &[
            ("H_A", "H", "A", 0.9, 10.0),
            ("H_B", "H", "B", 0.8, 20.0),
            ("A_B", "A", "B", 0.5, 5.0),
            ("A_H", "A", "H", 1.0, 10.0),
            ("B_A", "B", "A", 1.0, 5.0),
            ("B_H", "B", "H", 1.0, 10.0),
        ],
        "H",
        &ordered("A", "B"),
    );
    // (H,0) (A,1) (sink,0) (B,0) (B,2)=goal (sink,1) (H,1), in breadth-first order.
    let expected = [
        (Some(0), 0),
        (Some(1), 1),
        (None, 0),
        (Some(2), 0),
        (Some(2), 2),
        (None, 1),
        (Some(0), 1),
    ];
    let got: Vec<(Option<usize>, usize)> = product
        .states()
        .iter()
        .map(|s| (s.node, s.dfa_state))
        .collect();
    assert_eq!(got, expected);
    assert_eq!(
        product.mdp().goal(),
        &[false, false, false, false, true, false, false]
    );
    assert_eq!((sol.state_count, sol.choice_count), (7, 8));
    let pmax = [0.72, 0.8, 0.0, 0.8, 1.0, 0.0, 0.8];
    for (s, &p) in pmax.iter().enumerate() {
        assert!(close(sol.pmax[s], p), "state {s}: {} vs {p}", sol.pmax[s]);
    }
    // Restricted: (H,1) → B (20 s); (A,1) → H (10 s) then 20 s; (H,0) → A (10 s), then 30 s
    // if it succeeded: C = 10 + 0.9 · 30 = 37. (B,0) → A: 5 + 30.
    let cost = [37.0, 30.0, 0.0, 35.0, 0.0, 0.0, 20.0];
    for (s, &c) in cost.iter().enumerate() {
        assert!(close(sol.cost[s], c), "state {s}: {} vs {c}", sol.cost[s]);
    }
    let policy = [
        Some("H_A"),
        Some("A_H"),
        None,
        Some("B_A"),
        None,
        None,
        Some("H_B"),
    ];
    for (s, p) in policy.iter().enumerate() {
        assert_eq!(sol.policy[s], p.map(|id| edge_of(&nav, id)), "state {s}");
    }
    // Executing: from (H,0) the robot takes H_A and arrives at A: product state (A,1).
    let c = sol.policy_choice[0].unwrap();
    assert_eq!(product.successor(0, c, Some(1)), Some(1));
    assert_eq!(product.successor(0, c, None), Some(2));
    assert_eq!(product.successor(0, c, Some(2)), None);
    assert_eq!(product.successor(1, c, Some(1)), None);
}

#[test]
fn avoid_until_blocks_the_forbidden_node() {
    // !X U G: the direct route passes X; the long route avoids it.
    let solve_from_s = |dfa: &Dfa| {
        solve_nav(
            &["S", "X", "Y", "G"],
            &[
                ("S_X", "S", "X", 1.0, 5.0),
                ("X_G", "X", "G", 1.0, 5.0),
                ("S_Y", "S", "Y", 0.7, 20.0),
                ("Y_G", "Y", "G", 0.9, 20.0),
            ],
            "S",
            dfa,
        )
    };
    let (nav, _, sol) = solve_from_s(&avoid_until("X", "G"));
    assert!(close(sol.pmax_initial, 0.63));
    assert_eq!(sol.policy[0], Some(edge_of(&nav, "S_Y")));
    assert!(close(sol.cost_initial, 20.0 + 0.7 * 20.0));
    // With F G instead, the certain route through X wins.
    let (nav, _, sol) = solve_from_s(&eventually("G"));
    assert_eq!(sol.pmax_initial, 1.0);
    assert_eq!(sol.policy[0], Some(edge_of(&nav, "S_X")));
    assert!(close(sol.cost_initial, 10.0));
}

#[test]
fn dead_ends_read_their_letter_forever() {
    // F (!A & X !A) accepts after two consecutive letters other than A. The robot goes from
    // A to the dead end D: it reads "none" once, then (staying at D forever) again.
    let dfa = Dfa {
        atoms: vec!["A".into()],
        initial: 0,
        accepting: vec![false, false, true],
        delta: vec![0, 1, 0, 2, 2, 2],
    };
    let (_, product, sol) = solve_nav(&["A", "D"], &[("A_D", "A", "D", 1.0, 4.0)], "A", &dfa);
    assert_eq!(product.states()[1].node, Some(1));
    assert_eq!(product.states()[1].dfa_state, 1);
    assert!(
        product.mdp().goal()[1],
        "the lasso at D passes the accepting state"
    );
    assert_eq!(sol.pmax_initial, 1.0);
    assert_eq!(sol.cost_initial, 4.0);
}

#[test]
fn certain_cycles_do_not_stall_the_upper_bound() {
    // X ↔ Y with certain edges is an end component: iterating from 1 without collapsing it
    // would keep the upper bound at 1.
    let (_, _, sol) = solve_nav(
        &["X", "Y", "G"],
        &[
            ("X_Y", "X", "Y", 1.0, 1.0),
            ("Y_X", "Y", "X", 1.0, 1.0),
            ("Y_G", "Y", "G", 0.5, 1.0),
        ],
        "X",
        &eventually("G"),
    );
    assert!(close(sol.pmax_initial, 0.5));
    assert!(sol.gap < 1e-12, "gap {}", sol.gap);
    assert!(close(sol.pmax_upper[0], 0.5));
    assert!(close(sol.cost_initial, 2.0));
}

#[test]
fn zero_cost_cycles_do_not_hide_the_cost() {
    // 0 ↔ 1 at no cost, 1 → goal for 5: value iteration from 0 without collapsing the
    // zero-cost end component would stay at 0, and the first tied choice at 1 loops.
    let c = |action, cost, outcomes: &[(usize, f64)]| Choice {
        action,
        cost,
        outcomes: outcomes.to_vec(),
    };
    let mdp = SparseMdp::new(
        0,
        vec![false, false, true],
        vec!["a".into(), "b".into(), "c".into()],
        vec![
            vec![c(0, 0.0, &[(1, 1.0)])],
            vec![c(1, 0.0, &[(0, 1.0)]), c(2, 5.0, &[(2, 1.0)])],
            vec![],
        ],
    )
    .unwrap();
    let sol = solve(&mdp, &SolverOptions::default()).unwrap();
    assert_eq!(sol.pmax, vec![1.0, 1.0, 1.0]);
    assert_eq!(sol.cost, vec![5.0, 5.0, 0.0]);
    assert_eq!(sol.policy, vec![Some(0), Some(2), None]);
}

// ---------------------------------------------------------------------------------------
// Brute force: all deterministic memoryless policies, each Markov chain solved exactly.

/// Solves `a x = b` by Gaussian elimination with partial pivoting (`a` is `n × n`, row-major).
fn gauss(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for col in 0..n {
        let pivot = (col..n)
            .max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))
            .unwrap();
        a.swap(col, pivot);
        b.swap(col, pivot);
        assert!(a[col][col].abs() > 1e-12, "singular system");
        let (upper, lower) = a.split_at_mut(col + 1);
        let pivot_row = &upper[col];
        for (row, r) in lower.iter_mut().enumerate() {
            let f = r[col] / pivot_row[col];
            for (x, p) in r[col..].iter_mut().zip(&pivot_row[col..]) {
                *x -= f * p;
            }
            b[col + 1 + row] -= f * b[col];
        }
    }
    let mut x = vec![0.0; n];
    for row in (0..n).rev() {
        let s: f64 = (row + 1..n).map(|k| a[row][k] * x[k]).sum();
        x[row] = (b[row] - s) / a[row][row];
    }
    x
}

/// The chain of a policy: `policy[s]` a choice of `s` or `None` (absorbing).
struct Chain<'a> {
    mdp: &'a SparseMdp,
    policy: &'a [Option<usize>],
}

impl Chain<'_> {
    fn successors(&self, s: usize) -> Vec<(usize, f64)> {
        self.policy[s].map_or_else(Vec::new, |c| self.mdp.outcomes(c).collect())
    }

    /// States that can reach `target` (graph).
    fn can_reach(&self, target: &[bool]) -> Vec<bool> {
        let n = target.len();
        let mut reach = target.to_vec();
        loop {
            let mut changed = false;
            for s in 0..n {
                if !reach[s] && self.successors(s).iter().any(|&(t, _)| reach[t]) {
                    reach[s] = true;
                    changed = true;
                }
            }
            if !changed {
                return reach;
            }
        }
    }

    /// Probability of reaching `target`, exactly.
    fn reach_probability(&self, target: &[bool]) -> Vec<f64> {
        let n = target.len();
        let reach = self.can_reach(target);
        let unknown: Vec<usize> = (0..n).filter(|&s| reach[s] && !target[s]).collect();
        let mut x: Vec<f64> = target.iter().map(|&t| f64::from(u8::from(t))).collect();
        let pos = |s: usize| unknown.iter().position(|&u| u == s);
        let mut a = vec![vec![0.0; unknown.len()]; unknown.len()];
        let mut b = vec![0.0; unknown.len()];
        for (i, &s) in unknown.iter().enumerate() {
            a[i][i] += 1.0;
            for (t, p) in self.successors(s) {
                if target[t] {
                    b[i] += p;
                } else if let Some(j) = pos(t) {
                    a[i][j] -= p;
                }
            }
        }
        for (i, v) in gauss(a, b).into_iter().enumerate() {
            x[unknown[i]] = v;
        }
        x
    }

    /// Expected cost until `target`: +∞ where `target` is not reached almost surely.
    fn cost_until(&self, target: &[bool]) -> Vec<f64> {
        let n = target.len();
        let reach = self.can_reach(target);
        let cannot: Vec<bool> = reach.iter().map(|r| !r).collect();
        let doomed = self.can_reach(&cannot);
        let unknown: Vec<usize> = (0..n).filter(|&s| !doomed[s] && !target[s]).collect();
        let mut y = vec![f64::INFINITY; n];
        for s in (0..n).filter(|&s| target[s]) {
            y[s] = 0.0;
        }
        let pos = |s: usize| unknown.iter().position(|&u| u == s);
        let mut a = vec![vec![0.0; unknown.len()]; unknown.len()];
        let mut b = vec![0.0; unknown.len()];
        for (i, &s) in unknown.iter().enumerate() {
            a[i][i] += 1.0;
            b[i] = self.mdp.cost(self.policy[s].unwrap());
            for (t, p) in self.successors(s) {
                if let Some(j) = pos(t) {
                    a[i][j] -= p;
                }
            }
        }
        for (i, v) in gauss(a, b).into_iter().enumerate() {
            y[unknown[i]] = v;
        }
        y
    }
}

/// All deterministic memoryless policies (goal states and states without choices absorb).
fn all_policies(mdp: &SparseMdp) -> Vec<Vec<Option<usize>>> {
    let mut policies = vec![vec![]];
    for s in 0..mdp.state_count() {
        let options: Vec<Option<usize>> = if mdp.goal()[s] || mdp.choices(s).is_empty() {
            vec![None]
        } else {
            mdp.choices(s).map(Some).collect()
        };
        policies = policies
            .into_iter()
            .flat_map(|p| {
                options.iter().map(move |&o| {
                    let mut q = p.clone();
                    q.push(o);
                    q
                })
            })
            .collect();
    }
    policies
}

fn random_mdp(rng: &mut Xoshiro256StarStar) -> SparseMdp {
    let n = rng.int_in(2, 6) as usize;
    let goals = rng.int_in(1, 2) as usize;
    let mut goal = vec![false; n];
    for _ in 0..goals {
        goal[rng.int_in(0, n as u64 - 1) as usize] = true;
    }
    let costs = [0.0, 0.0, 1.0, 2.5, 7.0];
    let rows = (0..n)
        .map(|_| {
            // Some states without choices: traps that make Pmax fractional.
            let choices = if rng.bernoulli(0.3) {
                0
            } else {
                rng.int_in(1, 3) as usize
            };
            (0..choices)
                .map(|_| {
                    let k = rng.int_in(1, 3) as usize;
                    // Small integer weights make exact ties between choices common.
                    let weights: Vec<f64> = (0..k).map(|_| rng.int_in(1, 3) as f64).collect();
                    let total: f64 = weights.iter().sum();
                    Choice {
                        action: rng.int_in(0, 2) as usize,
                        cost: costs[rng.int_in(0, 4) as usize],
                        outcomes: weights
                            .iter()
                            .map(|w| (rng.int_in(0, n as u64 - 1) as usize, w / total))
                            .collect(),
                    }
                })
                .collect()
        })
        .collect();
    let initial = rng.int_in(0, n as u64 - 1) as usize;
    SparseMdp::new(
        initial,
        goal,
        vec!["a".into(), "b".into(), "c".into()],
        rows,
    )
    .unwrap()
}

#[test]
fn value_iteration_equals_brute_force_policy_enumeration() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(3);
    let (mut with_goal, mut with_ties, mut with_infinite) = (0, 0, 0);
    for case in 0..1000 {
        let mdp = random_mdp(&mut rng);
        let n = mdp.state_count();
        let goal = mdp.goal().to_vec();
        let policies = all_policies(&mdp);
        let values: Vec<Vec<f64>> = policies
            .iter()
            .map(|p| {
                Chain {
                    mdp: &mdp,
                    policy: p,
                }
                .reach_probability(&goal)
            })
            .collect();
        let pmax: Vec<f64> = (0..n)
            .map(|s| values.iter().map(|v| v[s]).fold(0.0, f64::max))
            .collect();
        let decided: Vec<bool> = (0..n).map(|s| goal[s] || pmax[s] == 0.0).collect();
        let mut cost = vec![f64::INFINITY; n];
        let mut optimal_policies = 0;
        for (p, v) in policies.iter().zip(&values) {
            if (0..n).all(|s| v[s] >= pmax[s] - 1e-9) {
                optimal_policies += 1;
                let y = Chain {
                    mdp: &mdp,
                    policy: p,
                }
                .cost_until(&decided);
                for s in 0..n {
                    cost[s] = cost[s].min(y[s]);
                }
            }
        }
        let sol = solve(&mdp, &SolverOptions::default()).unwrap();
        for s in 0..n {
            assert!(
                (sol.pmax[s] - pmax[s]).abs() <= 1e-9,
                "case {case} state {s}: Pmax {} vs brute force {}",
                sol.pmax[s],
                pmax[s]
            );
            assert!(sol.pmax_upper[s] >= pmax[s] - 1e-9);
            assert_eq!(sol.decided[s], decided[s], "case {case} state {s}");
            let (a, b) = (sol.cost[s], cost[s]);
            assert!(
                a == b || (a - b).abs() <= 1e-9 * b.abs().max(1.0),
                "case {case} state {s}: cost {a} vs brute force {b}"
            );
        }
        assert!(sol.gap <= 1e-9, "case {case}: gap {}", sol.gap);
        // The extracted policy achieves both values.
        let chain = Chain {
            mdp: &mdp,
            policy: &sol.policy_choice,
        };
        let reach = chain.reach_probability(&goal);
        let y = chain.cost_until(&decided);
        for s in (0..n).filter(|&s| !decided[s]) {
            assert!((reach[s] - pmax[s]).abs() <= 1e-9, "case {case} state {s}");
            assert!(
                (y[s] - cost[s]).abs() <= 1e-9 * cost[s].max(1.0),
                "case {case} state {s}: policy cost {} vs {}",
                y[s],
                cost[s]
            );
        }
        with_goal += usize::from(pmax.iter().any(|&p| p > 0.0 && p < 1.0));
        with_ties += usize::from(optimal_policies > 1);
        with_infinite += usize::from(cost.iter().any(|c| c.is_infinite()));
    }
    // The random cases exercise what they should.
    assert!(with_goal > 200, "{with_goal}");
    assert!(with_ties > 300, "{with_ties}");
    assert_eq!(
        with_infinite, 0,
        "Pmax-optimal policies always decide the run"
    );
}

// ---------------------------------------------------------------------------------------
// Bad input.

#[test]
fn bad_input_is_rejected_with_the_edge_named() {
    let m = map(&["A", "B"], &[("A_B", "A", "B"), ("B_A", "B", "A")]);
    let err = NavigationMdp::new(&m, &[0.5], &[1.0, 1.0]).unwrap_err();
    assert_eq!(
        err,
        MdpError::LengthMismatch {
            what: "success",
            expected: 2,
            found: 1
        }
    );
    let err = NavigationMdp::new(&m, &[0.5, 0.5], &[1.0, 1.0, 1.0]).unwrap_err();
    assert_eq!(err.to_string(), "duration has 3 entries, expected 2");
    for p in [1.5, -0.1, f64::NAN, f64::INFINITY] {
        let err = NavigationMdp::new(&m, &[0.5, p], &[1.0, 1.0]).unwrap_err();
        assert!(
            matches!(&err, MdpError::InvalidSuccess { edge, index: 1, .. } if edge == "B_A"),
            "{err:?}"
        );
        assert!(err.to_string().contains("\"B_A\""), "{err}");
    }
    for d in [-1.0, f64::NAN, f64::INFINITY] {
        let err = NavigationMdp::new(&m, &[0.5, 0.5], &[d, 1.0]).unwrap_err();
        assert!(
            matches!(&err, MdpError::InvalidDuration { edge, index: 0, .. } if edge == "A_B"),
            "{err:?}"
        );
        assert!(err.to_string().contains("\"A_B\""), "{err}");
    }
    // Boundary values are fine.
    let nav = NavigationMdp::new(&m, &[0.0, 1.0], &[0.0, 1.0]).unwrap();
    assert!(nav.product(2, &eventually("B")).is_err());
    let broken = Dfa {
        delta: vec![1, 0, 1],
        ..eventually("B")
    };
    assert_eq!(nav.product(0, &broken), Err(MdpError::InconsistentDfa));
    // A deserialised map may refer to nodes it does not have.
    #[derive(serde::Serialize)]
    struct RawMap {
        nodes: Vec<crate::map::Node>,
        edges: Vec<Edge>,
    }
    let raw = RawMap {
        nodes: m.nodes().to_vec(),
        edges: vec![Edge {
            id: "A_Z".into(),
            from: 0,
            to: 9,
        }],
    };
    let bytes = postcard::to_allocvec(&raw).unwrap();
    let mut bad_map: TopoMap = postcard::from_bytes(&bytes).unwrap();
    bad_map.reindex();
    assert_eq!(
        NavigationMdp::new(&bad_map, &[0.5], &[1.0]),
        Err(MdpError::EdgeOutOfRange {
            edge: "A_Z".into(),
            node: 9,
            nodes: 2
        })
    );
}

#[test]
fn bad_sparse_mdps_are_rejected() {
    let c = |outcomes: &[(usize, f64)], cost| Choice {
        action: 0,
        cost,
        outcomes: outcomes.to_vec(),
    };
    let names = || vec!["a".to_string()];
    let build = |rows: Vec<Vec<Choice>>| SparseMdp::new(0, vec![false, true], names(), rows);
    assert!(matches!(
        build(vec![vec![c(&[(2, 1.0)], 1.0)], vec![]]),
        Err(MdpError::StateOutOfRange { state: 2, .. })
    ));
    assert!(matches!(
        build(vec![vec![c(&[(1, 0.5), (0, 0.4)], 1.0)], vec![]]),
        Err(MdpError::NotStochastic {
            state: 0,
            choice: 0,
            ..
        })
    ));
    assert!(matches!(
        build(vec![vec![c(&[(1, f64::NAN)], 1.0)], vec![]]),
        Err(MdpError::InvalidProbability { .. })
    ));
    assert!(matches!(
        build(vec![vec![], vec![c(&[(1, 0.0), (0, 1.0)], 1.0)]]),
        Err(MdpError::InvalidProbability {
            state: 1,
            choice: 0,
            ..
        })
    ));
    assert!(matches!(
        build(vec![vec![c(&[(1, 1.0)], -2.0)], vec![]]),
        Err(MdpError::InvalidCost { value: -2.0, .. })
    ));
    assert!(matches!(
        build(vec![vec![c(&[], 1.0)], vec![]]),
        Err(MdpError::NoOutcome { .. })
    ));
    let mut bad_action = c(&[(1, 1.0)], 1.0);
    bad_action.action = 1;
    assert!(matches!(
        build(vec![vec![bad_action], vec![]]),
        Err(MdpError::ActionOutOfRange { action: 1, .. })
    ));
    assert!(matches!(
        SparseMdp::new(5, vec![false], names(), vec![vec![]]),
        Err(MdpError::StateOutOfRange { state: 5, .. })
    ));
    assert!(matches!(
        SparseMdp::new(0, vec![false, false], names(), vec![vec![]]),
        Err(MdpError::LengthMismatch { .. })
    ));
    let mdp = build(vec![vec![c(&[(1, 1.0)], 1.0)], vec![]]).unwrap();
    for tolerance in [0.0, -1.0, f64::NAN, 1.0] {
        let options = SolverOptions {
            tolerance,
            ..SolverOptions::default()
        };
        assert!(matches!(
            solve(&mdp, &options),
            Err(MdpError::InvalidOptions(_))
        ));
    }
    assert!(mdp.restrict(&[true, false]).is_err());
}

#[test]
fn the_iteration_cap_is_an_error() {
    let mdp = leaky_loop();
    let options = SolverOptions {
        max_iterations: 10,
        ..SolverOptions::default()
    };
    assert!(matches!(
        solve(&mdp, &options),
        Err(MdpError::NotConverged { iterations: 10, .. })
    ));
    let sol = solve(&mdp, &SolverOptions::default()).unwrap();
    // Stopping at a change below 1e-12 leaves an error of about 1e-12 / (1 − 0.999).
    assert!((sol.pmax_initial - 1.0).abs() < 1e-8);
    assert!(sol.gap < 1e-8);
    assert!(
        (sol.cost_initial - 1000.0).abs() < 1e-5,
        "{}",
        sol.cost_initial
    );
}

// ---------------------------------------------------------------------------------------
// Exports.

#[test]
fn prism_export_uses_the_strands_layout() {
    let m = map(
        &["WayPoint1", "WayPoint2"],
        &[
            ("WayPoint1_WayPoint2", "WayPoint1", "WayPoint2"),
            ("WayPoint2_WayPoint1", "WayPoint2", "WayPoint1"),
            ("Closed", "WayPoint2", "WayPoint2"),
        ],
    );
    let nav = NavigationMdp::new(&m, &[0.93, 1.0, 0.0], &[12.4, 3.0, 0.5]).unwrap();
    let expected = "\
// Navigation MDP at time t ([Fentanes 2015] sec. V), STRANDS mdp_plan_exec layout: waypoint = node index, -1 = failure sink
mdp

module M
  waypoint:[-1..1] init 1;
  [WayPoint1_WayPoint2] (waypoint=0) -> 0.93:(waypoint'=1) + 0.06999999999999995:(waypoint'=-1);
  [WayPoint2_WayPoint1] (waypoint=1) -> 1.0:(waypoint'=0);
  [Closed] (waypoint=1) -> 1.0:(waypoint'=-1);
endmodule

label \"WayPoint1\" = (waypoint=0);
label \"WayPoint2\" = (waypoint=1);

rewards \"time\"
  [WayPoint1_WayPoint2] (waypoint=0):12.4;
  [WayPoint2_WayPoint1] (waypoint=1):3.0;
  [Closed] (waypoint=1):0.5;
endrewards
";
    assert_eq!(nav.to_prism(1).unwrap(), expected);
    assert!(matches!(
        nav.to_prism(2),
        Err(MdpError::NodeOutOfRange { node: 2, nodes: 2 })
    ));
}

#[test]
fn prism_export_rejects_names_prism_cannot_read() {
    let check = |nodes: &[&str], edge: &str| {
        let m = map(nodes, &[(edge, nodes[0], nodes[0])]);
        NavigationMdp::new(&m, &[1.0], &[1.0]).unwrap().to_prism(0)
    };
    assert!(check(&["A"], "A_A").is_ok());
    for (nodes, edge, name) in [
        (&["A"][..], "a-b", "a-b"),
        (&["A"][..], "module", "module"),
        (&["A"][..], "1st", "1st"),
        (&["init"][..], "e", "init"),
        (&["Kitchen.1"][..], "e", "Kitchen.1"),
    ] {
        let err = check(nodes, edge).unwrap_err();
        assert!(
            matches!(&err, MdpError::InvalidName { name: n, .. } if n == name),
            "{err:?}"
        );
    }
}

#[test]
fn prism_property_quotes_node_names() {
    let cases = [
        ("F Kitchen", r#"Pmax=? [ F "Kitchen" ]"#),
        ("F (A & F B)", r#"Pmax=? [ F ("A" & F "B") ]"#),
        ("!X1 U Y", r#"Pmax=? [ !"X1" U "Y" ]"#),
        ("F v1 || F v14", r#"Pmax=? [ F "v1" | F "v14" ]"#),
        ("(F a) && G !b", r#"Pmax=? [ (F "a") & G !"b" ]"#),
        ("a -> X b", r#"Pmax=? [ "a" => X "b" ]"#),
        ("a <-> b", r#"Pmax=? [ "a" <=> "b" ]"#),
        (r#"F "G" & true"#, r#"Pmax=? [ F "G" & true ]"#),
    ];
    for (ltl, prism) in cases {
        assert_eq!(prism_property(ltl).unwrap(), prism, "{ltl}");
    }
    for bad in ["F a-b", "F 3x", "F \"open", "F a.b"] {
        assert!(
            matches!(prism_property(bad), Err(MdpError::InvalidFormula(_))),
            "{bad}"
        );
    }
}

#[test]
fn drn_export_is_storm_s_explicit_format() {
    let (_, product, sol) = direct_or_detour(0.5, 10.0);
    // Product states: 0 = (S,0), 1 = (G,1) goal, 2 = (sink,0), 3 = (M,0).
    let header = |choices: usize| {
        format!(
            "// written by chronomap-core (mdp::SparseMdp::to_drn)\n@type: MDP\n@parameters\n\n\
             @reward_models\ntime\n@nr_states\n4\n@nr_choices\n{choices}\n@model\n"
        )
    };
    let tail = "\
state 1 goal decided
\taction absorb [0.0]
\t\t1 : 1.0
state 2 decided
\taction absorb [0.0]
\t\t2 : 1.0
state 3
\taction M_G [30.0]
\t\t1 : 0.9
\t\t2 : 0.09999999999999998
";
    let full = format!(
        "{}state 0 init\n\taction S_G [10.0]\n\t\t1 : 0.5\n\t\t2 : 0.5\n\
         \taction S_M [30.0]\n\t\t3 : 0.9\n\t\t2 : 0.09999999999999998\n{tail}",
        header(5)
    );
    assert_eq!(product_drn(product.mdp(), &sol).unwrap(), full);
    // The restricted product keeps the Pmax-optimal S_M only.
    let restricted = format!(
        "{}state 0 init\n\taction S_M [30.0]\n\t\t3 : 0.9\n\t\t2 : 0.09999999999999998\n{tail}",
        header(4)
    );
    assert_eq!(restricted_drn(product.mdp(), &sol).unwrap(), restricted);

    let mdp = product.mdp();
    assert!(matches!(
        mdp.to_drn(&[("here", &[true][..])]),
        Err(MdpError::LengthMismatch { .. })
    ));
    assert!(matches!(
        mdp.to_drn(&[("goal", &[true; 4][..])]),
        Err(MdpError::InvalidName { .. })
    ));
    let other = solve_nav(&["A"], &[], "A", &eventually("B")).2;
    assert!(matches!(
        product_drn(mdp, &other),
        Err(MdpError::SolutionMismatch { .. })
    ));
}

#[test]
fn a_failed_optimistic_guess_falls_back_to_an_honest_gap() {
    // 0 stays with 0.999, reaches the goal with 0.001: Pmax = 1. With tolerance 1e-3 the
    // iteration from below stops at about 0.002; the guess 0.0025 is not inductive
    // (B(u) = 0.001 + 0.999 u > u), so the interval iteration from 1 takes over, and the
    // reported upper bound and gap are honest.
    let mdp = leaky_loop();
    let options = SolverOptions {
        tolerance: 1e-3,
        ..SolverOptions::default()
    };
    let sol = solve(&mdp, &options).unwrap();
    assert!(sol.pmax_initial < 0.01, "{}", sol.pmax_initial);
    assert_eq!(sol.pmax_upper[0], 1.0);
    assert!(close(sol.gap, 1.0 - sol.pmax_initial));
    assert!(sol.iterations.pmax_upper > 1);
}
