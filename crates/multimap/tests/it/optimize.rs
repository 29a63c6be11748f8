//! Pose-graph optimisation of map poses ([Stüde 2024] §3.3.3, eqs. (3.3)–(3.5)): known
//! answers, a stationarity oracle, and agreement with eq. (3.14) on loop-free graphs.
// Matrix entries are indexed by row and column as in the equations; the brute-force search
// carries its state in arguments.
#![allow(clippy::needless_range_loop, clippy::too_many_arguments)]

use chronomap_multimap::MultimapError;
use chronomap_multimap::config::MapConfig;
use chronomap_multimap::graph::{MapGraph, PathWeight};
use chronomap_multimap::optimize::{OptimizeParams, optimize};
use chronomap_multimap::se2::{Mat3, Pose2, UncertainPose, inverse3, trace, wrap_angle};
use chronomap_rng::Xoshiro256StarStar;
use std::f64::consts::FRAC_PI_2;

fn diag(a: f64, b: f64, c: f64) -> Mat3 {
    [[a, 0.0, 0.0], [0.0, b, 0.0], [0.0, 0.0, c]]
}

fn up(x: f64, y: f64, t: f64, cov: Mat3) -> UncertainPose {
    UncertainPose::new(Pose2::new(x, y, t).unwrap(), cov).unwrap()
}

fn graph_of(n: usize, links: &[(usize, usize, UncertainPose)]) -> MapGraph {
    let mut g = MapGraph::new();
    for _ in 0..n {
        g.add_map(MapConfig::ShortRange, None).unwrap();
    }
    for (a, b, p) in links {
        g.add_link(*a, *p, *b, UncertainPose::exact(Pose2::IDENTITY))
            .unwrap();
    }
    g
}

/// The cost of eq. (3.4) written independently of the optimiser: `z ⊖ (xᵢ⁻¹ ⊕ xⱼ)` as a
/// vector difference with the heading wrapped, weighted by the inverse covariance.
fn cost(g: &MapGraph, x: &[Pose2]) -> f64 {
    g.links()
        .iter()
        .enumerate()
        .map(|(k, l)| {
            let z = g.relative_pose(k, l.maps[0]).unwrap();
            let zhat = x[l.maps[0]].between(&x[l.maps[1]]);
            let e = [
                z.mean.x - zhat.x,
                z.mean.y - zhat.y,
                wrap_angle(z.mean.theta - zhat.theta),
            ];
            let o = inverse3(&z.cov).unwrap();
            (0..3)
                .map(|i| (0..3).map(|j| e[i] * o[i][j] * e[j]).sum::<f64>())
                .sum::<f64>()
        })
        .sum()
}

/// A square of four maps with headings pinned (σ_θ² = 1e-12, measured turns 0): the problem
/// is linear in the translations and its optimum is closed-form — the loop's misclosure `r`
/// is spread over the edges in proportion to their covariances, `zᵢ − Σᵢ (Σ Σₖ)⁻¹ r`, and the
/// marginal variances add like resistors (the two ways round the loop in parallel).
#[test]
fn square_with_a_noisy_loop_has_the_closed_form_optimum() {
    let s = [0.01, 0.02, 0.01, 0.04]; // translation variance of each edge (isotropic)
    let z = [[4.0, 0.0], [0.0, 4.0], [-4.0, 0.0], [0.3, -3.8]];
    let links: Vec<(usize, usize, UncertainPose)> = (0..4)
        .map(|k| {
            (
                k,
                (k + 1) % 4,
                up(z[k][0], z[k][1], 0.0, diag(s[k], s[k], 1e-12)),
            )
        })
        .collect();
    let g = graph_of(4, &links);
    let result = optimize(&g, &OptimizeParams::default()).unwrap();
    let r = [
        z.iter().map(|v| v[0]).sum::<f64>(),
        z.iter().map(|v| v[1]).sum::<f64>(),
    ];
    let total: f64 = s.iter().sum();
    let mut want = [0.0, 0.0];
    for k in 1..4 {
        for c in 0..2 {
            want[c] += z[k - 1][c] - s[k - 1] / total * r[c];
        }
        let got = result.poses[k];
        assert!(
            (got.x - want[0]).abs() < 1e-6 && (got.y - want[1]).abs() < 1e-6,
            "map {k}: {got:?} vs {want:?}"
        );
        assert!(got.theta.abs() < 1e-6);
        // Marginal variance: the path 0 → k (Σ s before k) in parallel with the rest.
        let a: f64 = s[..k].iter().sum();
        let var = a * (total - a) / total;
        assert!(
            (result.covariances[k][0][0] - var).abs() < 1e-6 * var,
            "{} vs {var}",
            result.covariances[k][0][0]
        );
    }
    assert!(result.final_cost < result.initial_cost);
    // The optimum's cost is r·r / Σs (one residual spread over the cycle).
    let f = (r[0] * r[0] + r[1] * r[1]) / total;
    assert!(
        (result.final_cost - f).abs() < 1e-6 * f,
        "{} vs {f}",
        result.final_cost
    );
}

/// A consistent graph (every loop closes exactly) is returned with exactly its poses.
#[test]
fn a_consistent_graph_keeps_its_poses() {
    let truth = [
        Pose2::IDENTITY,
        Pose2::new(5.0, 0.5, FRAC_PI_2).unwrap(),
        Pose2::new(4.0, 7.0, 2.8).unwrap(),
        Pose2::new(-1.0, 6.0, -2.0).unwrap(),
    ];
    let cov = [
        [0.02, 0.004, 0.001],
        [0.004, 0.03, -0.002],
        [0.001, -0.002, 0.004],
    ];
    let mut links = Vec::new();
    for (a, b) in [(0, 1), (1, 2), (2, 3), (3, 0), (0, 2)] {
        let z = truth[a].between(&truth[b]);
        links.push((a, b, up(z.x, z.y, z.theta, cov)));
    }
    let result = optimize(&graph_of(4, &links), &OptimizeParams::default()).unwrap();
    for (got, want) in result.poses.iter().zip(&truth) {
        assert!(got.distance(want) < 1e-12 && wrap_angle(got.theta - want.theta).abs() < 1e-12);
    }
    assert!(result.final_cost < 1e-24);
}

/// A noisy square with 90° turns (nonlinear): the optimum is a stationary point of the cost
/// (its numerical gradient vanishes) and no random nearby configuration is cheaper.
#[test]
fn a_noisy_square_converges_to_a_local_minimum() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(5);
    let mut links = Vec::new();
    for k in 0..4 {
        let noise = |rng: &mut Xoshiro256StarStar, a: f64| rng.uniform(-a, a);
        let z = up(
            10.0 + noise(&mut rng, 0.3),
            noise(&mut rng, 0.3),
            FRAC_PI_2 + noise(&mut rng, 0.05),
            diag(0.04, 0.04, 0.003),
        );
        links.push((k, (k + 1) % 4, z));
    }
    let g = graph_of(4, &links);
    let result = optimize(&g, &OptimizeParams::default()).unwrap();
    let x = result.poses.clone();
    let f0 = cost(&g, &x);
    assert!((f0 - result.final_cost).abs() < 1e-9 * (1.0 + f0));
    assert!(
        result.final_cost < 0.5 * result.initial_cost,
        "{} → {}",
        result.initial_cost,
        result.final_cost
    );
    let h = 1e-6;
    for m in 1..4 {
        for c in 0..3 {
            let shift = |d: f64| {
                let mut y = x.clone();
                match c {
                    0 => y[m].x += d,
                    1 => y[m].y += d,
                    _ => y[m].theta += d,
                }
                cost(&g, &y)
            };
            let grad = (shift(h) - shift(-h)) / (2.0 * h);
            assert!(grad.abs() < 1e-5, "∂F/∂x[{m}][{c}] = {grad}");
        }
    }
    for _ in 0..200 {
        let mut y = x.clone();
        for p in y.iter_mut().skip(1) {
            p.x += rng.uniform(-0.05, 0.05);
            p.y += rng.uniform(-0.05, 0.05);
            p.theta += rng.uniform(-0.01, 0.01);
        }
        assert!(cost(&g, &y) >= f0);
    }
}

/// Without loops the optimiser's marginal covariances are eq. (3.14)'s propagated ones
/// (both are the same linearisation of a tree), and a loop closure shrinks them.
#[test]
fn without_a_loop_marginals_equal_propagation_and_a_loop_shrinks_them() {
    let cov = diag(0.03, 0.03, 0.002);
    let chain: Vec<(usize, usize, UncertainPose)> = (0..4)
        .map(|k| (k, k + 1, up(6.0, 0.5, 0.4 + 0.3 * k as f64, cov)))
        .collect();
    let g = graph_of(5, &chain);
    let result = optimize(&g, &OptimizeParams::default()).unwrap();
    assert!(result.final_cost < 1e-20);
    for m in 1..5 {
        let prop = g
            .pose_in(
                0,
                m,
                &UncertainPose::exact(Pose2::IDENTITY),
                PathWeight::Hops,
            )
            .unwrap();
        for i in 0..3 {
            for k in 0..3 {
                let (a, b) = (result.covariances[m][i][k], prop.cov[i][k]);
                assert!(
                    (a - b).abs() < 1e-9 * (1.0 + b.abs()),
                    "map {m} [{i}][{k}]: {a} vs {b}"
                );
            }
        }
    }
    // Close the loop 4 → 0 with the true relative pose.
    let last = result.poses[4];
    let z = last.inverse();
    let mut looped = chain.clone();
    looped.push((4, 0, up(z.x, z.y, z.theta, cov)));
    let closed = optimize(&graph_of(5, &looped), &OptimizeParams::default()).unwrap();
    for m in 1..5 {
        assert!(
            trace(&closed.covariances[m]) < trace(&result.covariances[m]),
            "map {m}"
        );
    }
}

#[test]
fn unusable_graphs_are_refused() {
    // Map 2 has no link: its pose is not determined.
    let g = graph_of(3, &[(0, 1, up(1.0, 0.0, 0.0, diag(0.1, 0.1, 0.1)))]);
    assert_eq!(
        optimize(&g, &OptimizeParams::default()).unwrap_err(),
        MultimapError::SingularGraph { map: 2 }
    );
    // A link known exactly in both maps has no information matrix.
    let g = graph_of(2, &[(0, 1, up(1.0, 0.0, 0.0, diag(0.0, 0.0, 0.0)))]);
    assert_eq!(
        optimize(&g, &OptimizeParams::default()).unwrap_err(),
        MultimapError::SingularCovariance { link: 0 }
    );
    let bad = OptimizeParams {
        tolerance: f64::NAN,
        ..OptimizeParams::default()
    };
    assert!(
        optimize(&g, &bad)
            .unwrap_err()
            .to_string()
            .contains("tolerance")
    );
    assert!(optimize(&MapGraph::new(), &OptimizeParams::default()).is_err());
}

/// Running out of iterations is an error, not a result presented as the optimum.
#[test]
fn an_iteration_limit_is_an_error() {
    let z = |x: f64, y: f64, t: f64| up(x, y, t, diag(0.04, 0.04, 0.003));
    // A square whose four edges disagree: the first step cannot reach the tolerance.
    let links = [
        (0, 1, z(10.2, 0.1, FRAC_PI_2 + 0.04)),
        (1, 2, z(9.8, -0.2, FRAC_PI_2 - 0.03)),
        (2, 3, z(10.1, 0.3, FRAC_PI_2 + 0.05)),
        (3, 0, z(9.9, -0.1, FRAC_PI_2 - 0.02)),
    ];
    let g = graph_of(4, &links);
    let full = optimize(&g, &OptimizeParams::default()).unwrap();
    assert!(
        full.iterations > 1 && full.iterations < 100,
        "{}",
        full.iterations
    );
    let one = OptimizeParams {
        max_iterations: 1,
        ..OptimizeParams::default()
    };
    match optimize(&g, &one) {
        Err(MultimapError::NotConverged { iterations, cost }) => {
            assert_eq!(iterations, 1);
            // One Gauss–Newton step from the initial guess lowered the cost, not below the
            // optimum.
            assert!(cost < full.initial_cost && cost >= full.final_cost - 1e-12);
        }
        other => panic!("{other:?}"),
    }
    let none = OptimizeParams {
        max_iterations: 0,
        ..OptimizeParams::default()
    };
    assert!(matches!(
        optimize(&g, &none),
        Err(MultimapError::NotConverged { iterations: 0, .. })
    ));
}
