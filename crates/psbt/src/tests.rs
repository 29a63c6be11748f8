//! Hand-computed actions, planners against oracles, the fast synthesis against the dense
//! reference, and small maps whose best tree is known.

use super::actions::{SearchAction, WaitAction, move_to};
use super::path::{CellPath, DistanceTree, astar, sample_cells};
use super::places::{open_tsp, open_tsp_brute_force, open_tsp_genetic, tour_cost};
use super::*;
use chronomap_activity::disturbance::shortest_path;
use chronomap_activity::truth::TrackPoint;
use chronomap_bt_stochastic::Node;
use chronomap_core::Parallelism;
use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_testutil::{close, monte_carlo_agrees};

/// Eqs. 5.9–5.12 by hand: `μ_w = 0.05/s`, `p'_s = 0.9` → `T' = ln 10 / 0.05 = 46.0517 s`.
#[test]
fn wait_action_by_hand() {
    let w = WaitAction::planned(0.05, 0.9);
    assert!(close(w.timeout, 46.051_701_859_880_914, 1e-12));
    assert!(close(w.p_success_at(10.0), 1.0 - (-0.5f64).exp(), 1e-15)); // 0.393469
    assert_eq!(w.p_success_at(-1.0), 0.0);
    assert!(close(w.p_success_at(1e6), 0.9, 1e-12)); // stops at T'
    assert_eq!(w.p_failure_at(46.0), 0.0);
    assert!(close(w.p_failure_at(46.06), 0.1, 1e-12)); // 1 − p'_s
    let a = w.sbt().unwrap();
    assert!(close(a.p_success(), 0.9, 1e-12));
    assert_eq!(a.mu(), 0.05);
    assert!(close(a.nu(), 0.05 / 10f64.ln(), 1e-15));
}

/// Eqs. 5.14–5.19 by hand on a 2 m path at 0.5 m/s, `Δt = 1 s`: five points with rates
/// 0.1, 0.2, 0, 0.4, 0.1 per second.
#[test]
fn search_action_by_hand() {
    let config = PsbtConfig::default();
    let s = SearchAction::new(2.0, vec![0.1, 0.2, 0.0, 0.4, 0.1], &config);
    let c = 10f64.ln(); // −ln(1 − 0.9)
    // Eq. 5.15: min(0 + c/0.1, 1 + c/0.2, 3 + c/0.4, 4 + c/0.1) = 3 + 5.7565 = 8.7565 s.
    assert!(close(s.time_to_success(), 3.0 + c / 0.4, 1e-12));
    // Eq. 5.16: ∫_0^2.5 μ = 0.1 + 0.2 + 0.5·0 = 0.3.
    assert!(close(s.p_success_at(2.5), 1.0 - (-0.3f64).exp(), 1e-15));
    assert!(close(s.p_success_at(100.0), 1.0 - (-0.8f64).exp(), 1e-15));
    // Eq. 5.17: ν = 0.5/2 + 0.5/100 = 0.255.
    assert!(close(s.failure_rate(), 0.255, 1e-15));
    // Eq. 5.18: navigation only before 1/ν = 3.9216 s, then 1 − p_s(1/ν).
    assert!(close(s.p_failure_at(2.0), 1.0 - (-0.01f64).exp(), 1e-15));
    let end = 1.0 / 0.255;
    let ps_end = 1.0 - (-(0.3f64 + 0.4 * (end - 3.0))).exp();
    assert!(close(s.p_failure_at(5.0), 1.0 - ps_end, 1e-12));
    // Eq. 5.19: 0.4877 > exp(−2/102) = 0.9806 is false, so it holds.
    assert!(s.satisfies_eq_5_19());
    let a = s.sbt().unwrap();
    assert!(close(a.p_success(), ps_end, 1e-12));
    assert!(close(a.mu(), 1.0 / (3.0 + c / 0.4), 1e-12));
    assert!(close(a.nu(), 0.255, 1e-15));
    // No people on the way: the search can only fail.
    let empty = SearchAction::new(2.0, vec![0.0; 5], &config).sbt().unwrap();
    assert_eq!(empty.p_success(), 0.0);
    // Moving back 30 m: arrives with e^{−0.3}, after 60 s on average.
    let m = move_to(30.0, &config).unwrap().unwrap();
    assert!(close(m.p_success(), (-0.3f64).exp(), 1e-15));
    assert!(close(m.mu(), 0.5 / 30.0, 1e-15));
    assert!(move_to(0.0, &config).unwrap().is_none());
}

fn random_grid(
    rng: &mut Xoshiro256StarStar,
    cols: usize,
    rows: usize,
    blocked: f64,
) -> PlanningGrid {
    let mut grid = PlanningGrid::new([0.0, 0.0], 0.5, cols, rows).unwrap();
    let walls: Vec<bool> = (0..cols * rows).map(|_| rng.bernoulli(blocked)).collect();
    grid.keep_only(|c| {
        let (col, row) = ((c[0] / 0.5) as usize, (c[1] / 0.5) as usize);
        !walls[row * cols + col]
    });
    grid
}

fn check_path(grid: &PlanningGrid, path: &CellPath, from: usize, to: usize) {
    assert_eq!((path.cells[0], *path.cells.last().unwrap()), (from, to));
    let mut length = 0.0;
    for w in path.cells.windows(2) {
        assert!(grid.is_free(w[1]));
        let (a, b) = (grid.centre(w[0]), grid.centre(w[1]));
        let step = (a[0] - b[0]).hypot(a[1] - b[1]);
        assert!(step < 0.5 * 1.5, "not neighbours");
        length += step;
    }
    assert!(close(length, path.length, 1e-9));
}

/// A* and the bounded Dijkstra tree against the disturbance benchmark's Dijkstra (the oracle)
/// on random grids with 25 % blocked cells.
#[test]
fn astar_equals_dijkstra() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(7);
    let mut compared = 0;
    for _ in 0..30 {
        let grid = random_grid(&mut rng, 30, 20, 0.25);
        let ones = vec![1.0; grid.len()];
        let free: Vec<usize> = (0..grid.len()).filter(|&i| grid.is_free(i)).collect();
        let source = free[rng.int_in(0, free.len() as u64 - 1) as usize];
        let tree = DistanceTree::new(&grid, source, f64::INFINITY).unwrap();
        for _ in 0..20 {
            let goal = free[rng.int_in(0, free.len() as u64 - 1) as usize];
            let oracle = shortest_path(&grid, &ones, source, goal);
            let got = astar(&grid, source, goal);
            assert_eq!(oracle.is_some(), got.is_some());
            if let (Some(o), Some(g)) = (oracle, got) {
                assert!(close(o.cost, g.length, 1e-9), "{} vs {}", o.cost, g.length);
                check_path(&grid, &g, source, goal);
                assert!(close(tree.distance(goal), o.cost, 1e-9));
                check_path(&grid, &tree.path_to(goal).unwrap(), source, goal);
                compared += 1;
            }
        }
        // The bound: nothing beyond 3 m is reached.
        let near = DistanceTree::new(&grid, source, 3.0).unwrap();
        for c in near.reached() {
            assert!(near.distance(c) <= 3.0 && close(near.distance(c), tree.distance(c), 1e-9));
        }
    }
    assert!(compared > 300);
    let grid = PlanningGrid::new([0.0, 0.0], 0.5, 5, 1).unwrap();
    let path = astar(&grid, 0, 4).unwrap();
    assert_eq!(
        sample_cells(&grid, &path, 0.5).unwrap(),
        vec![0, 1, 2, 3, 4]
    );
    assert_eq!(sample_cells(&grid, &path, 1.0).unwrap(), vec![0, 2, 4]);
    // A spacing far below the path's length is refused, not wrapped into no points.
    assert!(matches!(
        sample_cells(&grid, &path, 1e-300),
        Err(crate::PsbtError::TooMany { .. })
    ));
}

/// The genetic algorithm finds the brute-force optimum of random open TSPs with n ≤ 8.
#[test]
fn tsp_genetic_matches_brute_force() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(3);
    for n in 1..=8 {
        for _ in 0..8 {
            let pts: Vec<[f64; 2]> = (0..=n)
                .map(|_| [rng.uniform(0.0, 30.0), rng.uniform(0.0, 30.0)])
                .collect();
            let cost: Vec<Vec<f64>> = pts
                .iter()
                .map(|a| {
                    pts.iter()
                        .map(|b| (a[0] - b[0]).hypot(a[1] - b[1]))
                        .collect()
                })
                .collect();
            let best = open_tsp_brute_force(&cost);
            let ga = open_tsp_genetic(
                &cost,
                &TspConfig::default(),
                &mut Xoshiro256StarStar::seed_from_u64(1),
            );
            let mut sorted = ga.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, (1..=n).collect::<Vec<_>>());
            assert!(
                close(tour_cost(&cost, &ga), tour_cost(&cost, &best), 1e-9),
                "n={n}"
            );
            // What the synthesis uses: exact up to 7 places, the GA beyond.
            let chosen = open_tsp(
                &cost,
                &TspConfig::default(),
                &mut Xoshiro256StarStar::seed_from_u64(1),
            );
            assert_eq!(chosen, if n <= 7 { best } else { ga }, "n={n}");
        }
    }
}

fn random_action(rng: &mut Xoshiro256StarStar) -> Action {
    let p = if rng.bernoulli(0.1) {
        0.0
    } else {
        rng.next_f64()
    };
    Action::new(p, rng.uniform(0.005, 1.0), rng.uniform(0.005, 1.0)).unwrap()
}

fn random_candidates(rng: &mut Xoshiro256StarStar, n: usize) -> Candidates {
    let mut search = vec![vec![None; n + 1]; n + 1];
    for (i, row) in search.iter_mut().enumerate() {
        for slot in row.iter_mut().skip(i + 1) {
            *slot = Some(random_action(rng));
        }
    }
    let wait = (0..=n).map(|_| random_action(rng)).collect();
    let ret = (0..=n)
        .map(|j| (j > 0 && rng.bernoulli(0.8)).then(|| random_action(rng)))
        .collect();
    Candidates { search, wait, ret }
}

/// The fast synthesis equals the dense reference (and the per-tree sparse solve) on every
/// candidate of random small cases.
#[test]
fn fast_equals_reference() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(21);
    for n in 0..=4 {
        for _ in 0..4 {
            let c = random_candidates(&mut rng, n);
            let horizon = rng.uniform(5.0, 200.0);
            let fast = c.values(horizon, 1e-12);
            let reference = c.reference_values(horizon, 1e-12).unwrap();
            assert_eq!(fast.len(), 3usize.pow(n as u32) + 1);
            for (i, (a, b)) in fast.iter().zip(&reference).enumerate() {
                assert!(close(*a, *b, 1e-9), "n={n} candidate {i}: {a} vs {b}");
                assert!(close(
                    *a,
                    c.per_tree_value(i, horizon, 1e-12).unwrap(),
                    1e-9
                ));
            }
            let (best, value) = c.best(horizon, 1e-12, Parallelism::Sequential);
            let max = fast.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            assert_eq!(value, max);
            assert_eq!(fast[best], max);
            assert_eq!(c.best(horizon, 1e-12, Parallelism::Rayon(4)), (best, value));
        }
    }
}

/// The phase chain is the chain of `Sequence(Fallback(a₁ … a_m), MoveTo)` when every return
/// is the same action; and a Monte-Carlo run of the phases agrees with it otherwise.
#[test]
fn phase_chain_semantics() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(8);
    let actions: Vec<Action> = (0..4).map(|_| random_action(&mut rng)).collect();
    let ret = Action::new(0.8, 0.1, 0.3).unwrap();
    let phases: Vec<(Action, Option<Action>)> = actions.iter().map(|&a| (a, Some(ret))).collect();
    let tree = Node::Sequence(vec![
        Node::Fallback(actions.iter().map(|&a| Node::Action(a)).collect()),
        Node::Action(ret),
    ]);
    let times = [1.0, 10.0, 60.0];
    let a = phase_chain(&phases)
        .unwrap()
        .transient(&times, 1e-12)
        .unwrap();
    let b = tree.chain().unwrap().transient(&times, 1e-12).unwrap();
    for (x, y) in a.iter().zip(&b) {
        assert!(close(x.p_success, y.p_success, 1e-11) && close(x.p_failure, y.p_failure, 1e-11));
    }
    // Different returns (and one instantaneous): simulate 100,000 runs, 5 standard errors.
    let rets = [
        Some(Action::new(0.9, 0.05, 0.2).unwrap()),
        None,
        Some(ret),
        Some(Action::new(0.5, 1.0, 1.0).unwrap()),
    ];
    let phases: Vec<(Action, Option<Action>)> = actions.iter().copied().zip(rets).collect();
    let exact = phase_chain(&phases)
        .unwrap()
        .transient(&times, 1e-12)
        .unwrap();
    let n = 100_000;
    let mut hits = [0usize; 3];
    for _ in 0..n {
        let mut t = 0.0;
        for (a, r) in &phases {
            if rng.bernoulli(a.p_success()) {
                t += rng.exp1() / a.mu();
                let ok = match r {
                    None => true,
                    Some(r) if rng.bernoulli(r.p_success()) => {
                        t += rng.exp1() / r.mu();
                        true
                    }
                    Some(_) => false,
                };
                if ok {
                    for (h, &limit) in hits.iter_mut().zip(&times) {
                        *h += usize::from(t <= limit);
                    }
                }
                break;
            }
            t += rng.exp1() / a.nu();
        }
    }
    for (o, h) in exact.iter().zip(hits) {
        let (agrees, p) = monte_carlo_agrees(h, n, o.p_success);
        assert!(agrees, "{p} vs {}", o.p_success);
    }
}

/// Eq. 5.7: distinct people per cell and interval over the observed span, the Gamma prior,
/// the pooled rate for an unobserved interval, and the disc integral of a flat field.
#[test]
fn grid_poisson_learns_rates() {
    let spec = GridSpec {
        origin: [0.0, 0.0],
        cell: 1.0,
        cols: 4,
        rows: 4,
        t0: 0.0,
        interval: 100.0,
        intervals: 3,
    };
    let prior = GammaPrior {
        alpha: 0.5,
        beta: 10.0,
    };
    let p = |t: f64, person: u64, x: f64, y: f64| TrackPoint { t, person, x, y };
    // Interval 0 spans t = 0..49 (50 s observed); person 1 twice in cell (0, 0), person 2 once.
    let points = [
        p(0.0, 1, 0.5, 0.5),
        p(1.0, 1, 0.6, 0.5),
        p(20.0, 2, 0.5, 0.2),
        p(49.0, 3, 3.5, 3.5),
        p(150.0, 4, 0.5, 0.5),
    ];
    let m = GridPoisson::from_tracks(&points, spec, prior).unwrap();
    assert!(close(
        m.cell_rate([0.5, 0.5], 10.0),
        (0.5 + 2.0) / (10.0 + 50.0),
        1e-15
    ));
    assert!(close(m.cell_rate([1.5, 0.5], 10.0), 0.5 / 60.0, 1e-15));
    // Interval 1: one detection, observed 1 s.
    assert!(close(m.cell_rate([0.5, 0.5], 150.0), 1.5 / 11.0, 1e-15));
    // Interval 2 was never observed: the cell's pooled posterior (3 people in 51 s).
    assert!(close(m.cell_rate([0.5, 0.5], 250.0), 3.5 / 61.0, 1e-15));
    assert!(m.has_detections([0.5, 0.5]) && !m.has_detections([1.5, 1.5]));
    // A flat field: the disc integral is λ·πr² (cells measured on 6 × 6 points: within 3 %).
    let spec = GridSpec {
        cols: 20,
        rows: 20,
        intervals: 1,
        ..spec
    };
    let mut flat = GridPoisson::new(spec, prior).unwrap();
    for x in 0..20 {
        for y in 0..20 {
            flat.observe([x as f64 + 0.5, y as f64 + 0.5], 0.0, 99.5, 990.0)
                .unwrap();
        }
    }
    let lambda = 100.0 / 1000.0;
    let exact = lambda * std::f64::consts::PI * 4.0;
    assert!(close(
        flat.disc_rate([10.3, 9.7], 2.0, 0.0),
        exact,
        0.03 * exact
    ));
    // The trait's default quadrature agrees.
    struct Flat;
    impl RateField for Flat {
        fn density(&self, _: [f64; 2], _: f64) -> f64 {
            0.1
        }
    }
    assert!(close(
        Flat.disc_rate([0.0, 0.0], 2.0, 0.0),
        exact,
        0.015 * exact
    ));
    assert!(GridPoisson::new(GridSpec { cell: 0.0, ..spec }, prior).is_err());
    assert!(
        GridPoisson::new(
            spec,
            GammaPrior {
                alpha: 0.0,
                beta: 1.0
            }
        )
        .is_err()
    );
    assert!(flat.observe([1.0, 1.0], 0.0, -1.0, 1.0).is_err());
}

/// A corridor 30 m long: people appear only at its east end (1 every 10 s per m²), the help
/// location is at the west end. The best tree drives east and waits there, and beats
/// waiting at the empty start (W) and the purely proactive PP.
fn corridor() -> (PlanningGrid, GridPoisson) {
    let grid = PlanningGrid::new([0.0, 0.0], 0.5, 60, 6).unwrap();
    let model = one_hour_model(30, 3, |x, _| if x >= 24 { 360.0 } else { 0.0 });
    (grid, model)
}

/// A grid Poisson model of `cols × rows` 1 m cells from the origin, one hour observed, with
/// `people(x, y)` people seen in cell (x, y).
fn one_hour_model(
    cols: usize,
    rows: usize,
    mut people: impl FnMut(usize, usize) -> f64,
) -> GridPoisson {
    let spec = GridSpec {
        origin: [0.0, 0.0],
        cell: 1.0,
        cols,
        rows,
        t0: 0.0,
        interval: 3600.0,
        intervals: 1,
    };
    let mut model = GridPoisson::new(spec, GammaPrior::default()).unwrap();
    for x in 0..cols {
        for y in 0..rows {
            let seen = people(x, y);
            model
                .observe([x as f64 + 0.5, y as f64 + 0.5], 0.0, seen, 3600.0)
                .unwrap();
        }
    }
    model
}

/// PSBT on the corridor from `from` at model time `t`, with the default settings and `seed`,
/// on one thread.
fn corridor_synthesis(
    grid: &PlanningGrid,
    model: &GridPoisson,
    from: [f64; 2],
    t: f64,
    seed: u64,
) -> Result<Synthesis, PsbtError> {
    let config = PsbtConfig::default();
    synthesize(grid, model, from, t, &config, seed, Parallelism::Sequential)
}

/// The plan of `method` (on one thread) from `from` at model time 10 s.
fn plan_at_10s(
    grid: &PlanningGrid,
    model: &GridPoisson,
    from: [f64; 2],
    config: &PsbtConfig,
    method: Method,
    seed: u64,
) -> Plan {
    SearchContext::new(grid, model, from, 10.0, config)
        .unwrap()
        .plan(method, seed, Parallelism::Sequential)
        .unwrap()
}

/// PSBT and the W baseline (waiting at the start) on the corridor from `from` at model time
/// 10 s, with the default settings and `seed`.
fn psbt_and_waiting(
    grid: &PlanningGrid,
    model: &GridPoisson,
    from: [f64; 2],
    seed: u64,
) -> (Synthesis, Plan) {
    let psbt = corridor_synthesis(grid, model, from, 10.0, seed).unwrap();
    let config = PsbtConfig::default();
    let w = plan_at_10s(grid, model, from, &config, Method::W, seed);
    (psbt, w)
}

#[test]
fn a_busy_place_beats_waiting_at_an_empty_start() {
    let (grid, model) = corridor();
    let config = PsbtConfig::default();
    let from = [1.25, 1.25];
    let (psbt, w) = psbt_and_waiting(&grid, &model, from, 4);
    let pp = plan_at_10s(&grid, &model, from, &config, Method::Pp, 4);
    let gm = plan_at_10s(&grid, &model, from, &config, Method::Gm, 4);
    // Six places do not fit 2 m apart into the busy 6 x 3 m: fewer were sampled.
    assert!(psbt.places.len() >= 3);
    assert_eq!(psbt.candidates, 3usize.pow(psbt.places.len() as u32) + 1);
    assert!(w.p_success < 0.01, "W {}", w.p_success);
    // Found there with 0.9 at most, and back 23 m without a navigation failure with
    // e^{-23/100} = 0.79.
    assert!(psbt.p_success > 0.7, "PSBT {}", psbt.p_success);
    assert!(psbt.p_success >= pp.p_success && psbt.p_success >= w.p_success);
    // It waits somewhere in the busy east end.
    assert!(
        psbt.tree
            .phases
            .iter()
            .any(|p| matches!(p.step, Step::Wait { at, .. } if at[0] >= 24.0))
    );
    // GM drives to the busy end and waits.
    assert!(
        matches!(gm.tree.phases[..], [Phase { step: Step::Search { .. }, .. }, Phase { step: Step::Wait { at, .. }, .. }] if at[0] >= 24.0)
    );
    // The analysis of the plan agrees with the synthesis, and synthesis is deterministic.
    let again = psbt
        .tree
        .analyse(&grid, &model, 10.0, &config, &[config.horizon_s])
        .unwrap();
    assert!(close(again.p_success[0], psbt.p_success, 1e-9));
    let twice = synthesize(&grid, &model, from, 10.0, &config, 4, Parallelism::Rayon(3)).unwrap();
    assert_eq!(twice, psbt);
}

/// Starting in the busy end, waiting right there is at least as good as anything found, and
/// PSBT is never worse than W.
#[test]
fn waiting_at_a_busy_start_is_kept() {
    let (grid, model) = corridor();
    let from = [27.25, 1.25];
    let (psbt, w) = psbt_and_waiting(&grid, &model, from, 9);
    assert!(psbt.p_success >= w.p_success);
    assert!(w.p_success > 0.85);
    // The first action is a wait at x0, or a search ending within r_D of it.
    match &psbt.tree.phases[0].step {
        Step::Wait { at, .. } => assert_eq!(*at, from),
        Step::Search { to, .. } => assert!(
            (to[0] - from[0]).hypot(to[1] - from[1]) < 2.0 + 1e-9 || psbt.p_success > w.p_success
        ),
    }
}

#[test]
fn bad_starts_and_settings_are_errors() {
    let (mut grid, model) = corridor();
    let config = PsbtConfig::default();
    let err = corridor_synthesis(&grid, &model, [-5.0, 1.0], 0.0, 0).unwrap_err();
    assert_eq!(err, PsbtError::StartOutside { at: [-5.0, 1.0] });
    grid.keep_only(|c| c[0] > 1.0);
    let err = corridor_synthesis(&grid, &model, [0.75, 1.0], 0.0, 0).unwrap_err();
    assert_eq!(err, PsbtError::StartBlocked { at: [0.75, 1.0] });
    let bad = PsbtConfig {
        places: 20,
        ..Default::default()
    };
    assert!(matches!(
        synthesize(
            &grid,
            &model,
            [5.0, 1.0],
            0.0,
            &bad,
            0,
            Parallelism::Sequential
        ),
        Err(PsbtError::Config(_))
    ));
    let bad = PsbtConfig {
        confidence: 1.0,
        ..Default::default()
    };
    assert!(bad.validate().is_err());
    assert!(matches!(
        synthesize(
            &grid,
            &model,
            [5.0, 1.0],
            f64::NAN,
            &config,
            0,
            Parallelism::Sequential
        ),
        Err(PsbtError::Config(_))
    ));
}

/// A CoPA-Map as the field of the person search: people per hour in 0.5 m cells become
/// people per second per square metre (`y / (3600 · 0.25)`), cell by cell at the model time,
/// and 0 outside the training square.
#[test]
fn copa_field_converts_people_per_hour_per_cell_to_a_density() {
    use chronomap_activity::{CopaConfig, CopaMap, RatePredictor, RateSamples};
    let (mut x, mut t, mut y) = (Vec::new(), Vec::new(), Vec::new());
    for hour in 0..6 {
        for i in 0..8 {
            for j in 0..8 {
                x.push([i as f64 * 0.5 + 0.25, j as f64 * 0.5 + 0.25]);
                t.push(f64::from(hour));
                y.push(20.0 + 10.0 * i as f64 + f64::from(hour));
            }
        }
    }
    let samples = RateSamples::new(x, t, y).unwrap();
    let config = CopaConfig {
        inducing: 10,
        iterations: 10,
        batch_size: 100,
        ..CopaConfig::default()
    };
    let model = CopaMap::fit(&samples, &config).unwrap();
    let field = copa_field(&model, 0.5, 3.0, chronomap_core::Parallelism::Sequential).unwrap();
    for &(cx, cy) in &[(0.25, 0.25), (3.75, 1.25), (2.25, 3.75)] {
        let per_hour = model.predict([cx, cy], 3.0);
        assert!(per_hour > 1.0, "{per_hour}");
        let expected = per_hour / 3600.0 / 0.25;
        // Any point of the cell, at any query time (the field is the model at t = 3).
        for (dx, dy, at) in [(0.0, 0.0, 0.0), (0.2, -0.2, 1e9)] {
            let d = field.density([cx + dx, cy + dy], at);
            assert!((d - expected).abs() < 1e-12 * expected, "{d} vs {expected}");
        }
    }
    assert_eq!(field.density([-1.0, 1.0], 0.0), 0.0);
    assert_eq!(field.density([1.0, 4.5], 0.0), 0.0);
    assert!(copa_field(&model, 0.0, 3.0, chronomap_core::Parallelism::Sequential).is_err());
    assert!(
        copa_field(
            &model,
            0.5,
            f64::NAN,
            chronomap_core::Parallelism::Sequential
        )
        .is_err()
    );
}

/// Fixed places come first and stay; draws near them are dropped, whatever their rate.
#[test]
fn fixed_places_are_kept_first() {
    use super::places::sample_places;
    let candidates: Vec<([f64; 2], f64)> = (0..40)
        .map(|i| ([i as f64, 0.0], if i == 5 { 0.001 } else { 1.0 + i as f64 }))
        .collect();
    let mut rng = Xoshiro256StarStar::seed_from_u64(3);
    let kept = sample_places(&candidates, &[5, 30], 6, 2.0, &mut rng);
    assert_eq!(&kept[..2], &[5, 30]);
    assert_eq!(kept.len(), 6);
    for (a, &i) in kept.iter().enumerate() {
        for &j in &kept[a + 1..] {
            assert!(
                (candidates[i].0[0] - candidates[j].0[0]).abs() >= 2.0,
                "{kept:?}"
            );
        }
    }
    // More fixed places than wanted: the first ones.
    assert_eq!(
        sample_places(&candidates, &[7, 9, 11], 2, 2.0, &mut rng),
        vec![7, 9]
    );
    // No rate at all: only the fixed ones.
    let dead: Vec<([f64; 2], f64)> = candidates.iter().map(|&(at, _)| (at, 0.0)).collect();
    assert_eq!(sample_places(&dead, &[4], 6, 2.0, &mut rng), vec![4]);
}

/// With the greedy targets among its places, PSBT's candidates contain the trees of GM, GC and
/// W (and PP's, which searches the same places): on random activity over random rooms, PSBT's
/// `p_s,T(t_max)` is never below theirs.
#[test]
fn psbt_is_never_below_the_baselines_it_contains() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(17);
    let config = PsbtConfig {
        places: 4,
        ..PsbtConfig::default()
    };
    for case in 0..6 {
        let grid = random_grid(&mut rng, 40, 24, 0.15);
        let model = one_hour_model(20, 12, |_, _| {
            if rng.bernoulli(0.1) {
                rng.next_f64() * 400.0
            } else {
                rng.next_f64() * 5.0
            }
        });
        let free: Vec<usize> = (0..grid.len()).filter(|&c| grid.is_free(c)).collect();
        for start in 0..3 {
            let from = grid.centre(free[rng.int_in(0, free.len() as u64 - 1) as usize]);
            let seed = (case * 3 + start) as u64;
            let Ok(psbt) = synthesize(
                &grid,
                &model,
                from,
                10.0,
                &config,
                seed,
                Parallelism::Sequential,
            ) else {
                continue; // a start walled in: places unreachable
            };
            for method in [Method::Gm, Method::Gc, Method::W, Method::Pp] {
                let other = plan_at_10s(&grid, &model, from, &config, method, seed);
                assert!(
                    psbt.p_success >= other.p_success - 1e-9,
                    "case {case} start {start}: PSBT {} < {method:?} {}",
                    psbt.p_success,
                    other.p_success
                );
            }
        }
    }
}
