//! Closed forms, the dense reference and Monte Carlo against the chain of a tree.

use super::dense::DenseGenerator;
use super::simulate::{Run, run};
use super::*;
use chronomap_rng::Xoshiro256StarStar;
use chronomap_testutil::monte_carlo_agrees;

const TOL: f64 = 1e-13;

fn action(p: f64, mu: f64, nu: f64) -> Node {
    Node::Action(Action::new(p, mu, nu).unwrap())
}

/// `P(X + Y ≤ t)` for independent `X ~ Exp(a)`, `Y ~ Exp(b)` (hypoexponential CDF):
/// `1 − (b e^{−at} − a e^{−bt}) / (b − a)`, and `1 − e^{−at}(1 + at)` for `a = b`.
fn hypo(a: f64, b: f64, t: f64) -> f64 {
    if (a - b).abs() < 1e-12 {
        1.0 - (-a * t).exp() * (1.0 + a * t)
    } else {
        1.0 - (b * (-a * t).exp() - a * (-b * t).exp()) / (b - a)
    }
}

fn expo(a: f64, t: f64) -> f64 {
    1.0 - (-a * t).exp()
}

/// Checks the transient outcome probabilities of `tree`'s chain at `times` against
/// `expected(t) = (p_s(t), p_f(t))`.
fn check(tree: &Node, times: &[f64], expected: impl Fn(f64) -> (f64, f64)) {
    let chain = tree.chain().unwrap();
    let got = chain.transient(times, TOL).unwrap();
    for (o, &t) in got.iter().zip(times) {
        let (s, f) = expected(t);
        assert!(o.error_bound <= TOL);
        assert!(
            (o.p_success - s).abs() < 1e-11,
            "t={t}: p_s {} vs {s}",
            o.p_success
        );
        assert!(
            (o.p_failure - f).abs() < 1e-11,
            "t={t}: p_f {} vs {f}",
            o.p_failure
        );
    }
}

const TIMES: [f64; 6] = [0.0, 0.5, 3.0, 10.0, 40.0, 300.0];

/// One action: `p_s(t) = p(1 − e^{−μt})`, `p_f(t) = (1 − p)(1 − e^{−νt})`,
/// `E[T|S] = 1/μ`, `E[T|F] = 1/ν`.
#[test]
fn one_action_closed_form() {
    let (p, mu, nu) = (0.7, 0.2, 0.05);
    let tree = action(p, mu, nu);
    check(&tree, &TIMES, |t| {
        (p * expo(mu, t), (1.0 - p) * expo(nu, t))
    });
    let Node::Action(a) = tree else {
        unreachable!()
    };
    assert!((a.p_success_at(10.0) - p * expo(mu, 10.0)).abs() < 1e-15);
    assert!((a.p_failure_at(10.0) - (1.0 - p) * expo(nu, 10.0)).abs() < 1e-15);
    let m = tree.chain().unwrap().means();
    assert!((m.p_success - p).abs() < 1e-15);
    assert!((m.time_to_success.unwrap() - 1.0 / mu).abs() < 1e-12);
    assert!((m.time_to_failure.unwrap() - 1.0 / nu).abs() < 1e-12);
}

/// Sequence(A1, A2): success needs both, `p1 p2 · Hypo(μ1, μ2)(t)`; failure is A1 failing,
/// `(1 − p1)(1 − e^{−ν1 t})`, or A1 succeeding and A2 failing, `p1 (1 − p2) Hypo(μ1, ν2)(t)`.
#[test]
fn sequence_of_two_closed_form() {
    let (p1, m1, n1) = (0.8, 0.3, 0.1);
    let (p2, m2, n2) = (0.6, 0.05, 0.4);
    let tree = Node::Sequence(vec![action(p1, m1, n1), action(p2, m2, n2)]);
    check(&tree, &TIMES, |t| {
        (
            p1 * p2 * hypo(m1, m2, t),
            (1.0 - p1) * expo(n1, t) + p1 * (1.0 - p2) * hypo(m1, n2, t),
        )
    });
    let m = tree.chain().unwrap().means();
    assert!((m.p_success - p1 * p2).abs() < 1e-15);
    assert!((m.time_to_success.unwrap() - (1.0 / m1 + 1.0 / m2)).abs() < 1e-12);
}

/// Fallback(A1, A2): `p1(1 − e^{−μ1 t}) + (1 − p1) p2 Hypo(ν1, μ2)(t)` succeed,
/// `(1 − p1)(1 − p2) Hypo(ν1, ν2)(t)` fail; `E[T|S] = (p1/μ1 + (1−p1)p2(1/ν1 + 1/μ2)) / P_S`.
#[test]
fn fallback_of_two_closed_form() {
    let (p1, m1, n1) = (0.4, 0.25, 0.125);
    let (p2, m2, n2) = (0.9, 0.02, 0.125);
    let tree = Node::Fallback(vec![action(p1, m1, n1), action(p2, m2, n2)]);
    check(&tree, &TIMES, |t| {
        (
            p1 * expo(m1, t) + (1.0 - p1) * p2 * hypo(n1, m2, t),
            (1.0 - p1) * (1.0 - p2) * hypo(n1, n2, t), // equal rates: the Erlang case
        )
    });
    let m = tree.chain().unwrap().means();
    let ps = p1 + (1.0 - p1) * p2;
    assert!((m.p_success - ps).abs() < 1e-15);
    let mean = (p1 / m1 + (1.0 - p1) * p2 * (1.0 / n1 + 1.0 / m2)) / ps;
    assert!((m.time_to_success.unwrap() - mean).abs() < 1e-12);
    assert!((m.time_to_failure.unwrap() - 2.0 / n1).abs() < 1e-12);
}

/// Sequence(C, A): the condition routes mass at once: `p_f(0) = 1 − c`.
#[test]
fn condition_takes_no_time() {
    let (c, p, mu, nu) = (0.3, 0.5, 0.1, 0.2);
    let tree = Node::Sequence(vec![
        Node::Condition(Condition::new(c).unwrap()),
        action(p, mu, nu),
    ]);
    check(&tree, &TIMES, |t| {
        (c * p * expo(mu, t), (1.0 - c) + c * (1.0 - p) * expo(nu, t))
    });
    // Empty composites: Sequence succeeds, Fallback fails, at once.
    check(&Node::Sequence(vec![]), &[0.0, 1.0], |_| (1.0, 0.0));
    check(&Node::Fallback(vec![]), &[0.0, 1.0], |_| (0.0, 1.0));
    // Certain outcomes need only one state.
    assert_eq!(action(1.0, 1.0, 0.0).chain().unwrap().states(), 1);
}

fn random_tree(rng: &mut Xoshiro256StarStar, depth: usize) -> Node {
    if depth == 0 || rng.bernoulli(0.3) {
        if rng.bernoulli(0.15) {
            return Node::Condition(Condition::new(rng.next_f64()).unwrap());
        }
        let p = if rng.bernoulli(0.1) {
            1.0
        } else {
            rng.next_f64()
        };
        return action(p, rng.uniform(0.05, 2.0), rng.uniform(0.05, 2.0));
    }
    let children = (0..rng.int_in(1, 3))
        .map(|_| random_tree(rng, depth - 1))
        .collect();
    if rng.bernoulli(0.5) {
        Node::Sequence(children)
    } else {
        Node::Fallback(children)
    }
}

/// The sparse chain against the dense reference on random trees.
#[test]
fn sparse_equals_dense_reference() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(11);
    for _ in 0..200 {
        let tree = random_tree(&mut rng, 3);
        let chain = tree.chain().unwrap();
        let times = [0.0, 0.7, 4.0, 25.0];
        let fast = chain.transient(&times, TOL).unwrap();
        let slow = DenseGenerator::of(&chain).transient(&times, TOL).unwrap();
        for (a, b) in fast.iter().zip(&slow) {
            assert!((a.p_success - b.p_success).abs() < 1e-11);
            assert!((a.p_failure - b.p_failure).abs() < 1e-11);
        }
        // Eventually everything is absorbed, and the means agree with the long-time limit.
        let m = chain.means();
        let late = chain.transient(&[1e4], TOL).unwrap()[0];
        assert!((late.p_success - m.p_success).abs() < 1e-9);
        assert!((late.p_success + late.p_failure - 1.0).abs() < 1e-9);
    }
}

/// Monte Carlo of the tree itself (Algorithms 5.1–5.2, independent of the chain) against the
/// chain: with N = 100,000 runs per tree (seed 5), every `p_{s,T}(t)` estimate lies within
/// 5 standard errors `5·√(p(1−p)/N)` (at most 0.008) of the chain's value, and the mean time
/// to success within 5 standard errors of `E[T|S]`.
#[test]
fn monte_carlo_agrees_with_the_chain() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(5);
    let n = 100_000;
    let trees = [
        action(0.7, 0.2, 0.05),
        Node::Sequence(vec![action(0.8, 0.3, 0.1), action(0.6, 0.05, 0.4)]),
        Node::Fallback(vec![action(0.4, 0.25, 0.125), action(0.9, 0.02, 0.125)]),
        random_tree(&mut Xoshiro256StarStar::seed_from_u64(3), 3),
        random_tree(&mut Xoshiro256StarStar::seed_from_u64(4), 3),
    ];
    let times = [1.0, 5.0, 20.0, 80.0];
    for tree in &trees {
        let chain = tree.chain().unwrap();
        let exact = chain.transient(&times, TOL).unwrap();
        let runs: Vec<Run> = (0..n).map(|_| run(tree, &mut rng)).collect();
        for (o, &t) in exact.iter().zip(&times) {
            let hits = runs.iter().filter(|r| r.success && r.duration <= t).count();
            let (agrees, p_hat) = monte_carlo_agrees(hits, n, o.p_success);
            assert!(agrees, "t={t}: MC {p_hat} vs chain {}", o.p_success);
        }
        let successes: Vec<f64> = runs
            .iter()
            .filter(|r| r.success)
            .map(|r| r.duration)
            .collect();
        if successes.len() > 1000 {
            let k = successes.len() as f64;
            let mean = successes.iter().sum::<f64>() / k;
            let var = successes.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / (k - 1.0);
            let expected = chain.means().time_to_success.unwrap();
            assert!(
                (mean - expected).abs() <= 5.0 * (var / k).sqrt(),
                "{mean} vs {expected}"
            );
        }
    }
}

#[test]
fn bad_input_is_an_error() {
    assert_eq!(
        Action::new(1.2, 1.0, 1.0),
        Err(SbtError::Probability { value: 1.2 })
    );
    assert!(matches!(
        Action::new(0.5, 0.0, 1.0),
        Err(SbtError::Rate {
            which: "success",
            ..
        })
    ));
    assert!(matches!(
        Action::new(0.5, 1.0, f64::NAN),
        Err(SbtError::Rate {
            which: "failure",
            ..
        })
    ));
    assert!(Action::new(0.0, 0.0, 1.0).is_ok());
    assert!(Condition::new(-0.1).is_err());
    // A transition to a later state (a cycle could follow) and a trap.
    let cyclic = Chain::new(
        vec![vec![(Target::State(0), 1.0)]],
        vec![(Target::State(0), 1.0)],
    );
    assert!(matches!(cyclic, Err(SbtError::Transition { state: 0, .. })));
    let trap = Chain::new(vec![vec![]], vec![(Target::State(0), 1.0)]);
    assert_eq!(trap, Err(SbtError::Trap { state: 0 }));
    let half = Chain::new(
        vec![vec![(Target::Success, 1.0)]],
        vec![(Target::State(0), 0.5)],
    );
    assert_eq!(half, Err(SbtError::Initial { sum: 0.5 }));
    let chain = action(0.5, 1.0, 1.0).chain().unwrap();
    assert!(matches!(
        chain.transient(&[-1.0], 1e-9),
        Err(SbtError::Query(_))
    ));
    assert!(matches!(
        chain.transient(&[1.0], 0.0),
        Err(SbtError::Query(_))
    ));
}

/// Large `Λt` (a stiff chain over a long horizon) does not underflow the Poisson weights.
#[test]
fn long_horizons_are_accurate() {
    let (p, mu, nu) = (0.5, 5.0, 0.001);
    let tree = Node::Sequence(vec![action(1.0, mu, 0.0), action(p, 0.01, nu)]);
    check(&tree, &[500.0, 2000.0], |t| {
        (p * hypo(mu, 0.01, t), (1.0 - p) * hypo(mu, nu, t))
    });
}
