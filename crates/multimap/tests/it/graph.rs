//! Relative map poses and their propagated covariance ([Stüde 2024] eqs. (3.10)–(3.14))
//! against Monte Carlo and hand computation, Dijkstra's map paths against brute force, and
//! the loop search of eq. (3.8).
// Matrix entries are indexed by row and column as in the equations; the brute-force search
// carries its state in arguments.
#![allow(clippy::needless_range_loop, clippy::too_many_arguments)]

use chronomap_multimap::MultimapError;
use chronomap_multimap::config::MapConfig;
use chronomap_multimap::graph::{
    LoopTarget, MAX_LINKS, MAX_LINKS_PER_MAP_FOR_EDGES, MAX_MAPS, MapGraph, PathWeight,
};
use chronomap_multimap::se2::{Mat3, Pose2, UncertainPose, position_lambda_max, wrap_angle};
use chronomap_multimap::search::{SearchParams, search_radius};
use chronomap_rng::Xoshiro256StarStar;
use std::f64::consts::FRAC_PI_2;

fn normal(rng: &mut Xoshiro256StarStar) -> f64 {
    let (u1, u2) = (1.0 - rng.next_f64(), rng.next_f64());
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// A sample of `N(mean, cov)` by the Cholesky factor of `cov` (positive definite).
fn sample(rng: &mut Xoshiro256StarStar, p: &UncertainPose) -> Pose2 {
    let c = &p.cov;
    let l00 = c[0][0].sqrt();
    let l10 = c[1][0] / l00;
    let l11 = (c[1][1] - l10 * l10).sqrt();
    let l20 = c[2][0] / l00;
    let l21 = (c[2][1] - l20 * l10) / l11;
    let l22 = (c[2][2] - l20 * l20 - l21 * l21).sqrt();
    let z = [normal(rng), normal(rng), normal(rng)];
    Pose2 {
        x: p.mean.x + l00 * z[0],
        y: p.mean.y + l10 * z[0] + l11 * z[1],
        theta: p.mean.theta + l20 * z[0] + l21 * z[1] + l22 * z[2],
    }
}

fn diag(a: f64, b: f64, c: f64) -> Mat3 {
    [[a, 0.0, 0.0], [0.0, b, 0.0], [0.0, 0.0, c]]
}

fn up(x: f64, y: f64, t: f64, cov: Mat3) -> UncertainPose {
    UncertainPose::new(Pose2::new(x, y, t).unwrap(), cov).unwrap()
}

/// Three maps in a row: corridor → room → room; every link pose uncertain in both maps.
fn chain(sigma_theta: f64) -> MapGraph {
    let mut g = MapGraph::new();
    for _ in 0..3 {
        g.add_map(MapConfig::ShortRange, None).unwrap();
    }
    let st2 = sigma_theta * sigma_theta;
    g.add_link(
        0,
        up(
            4.0,
            1.0,
            0.3,
            [[0.02, 0.005, 0.0], [0.005, 0.03, 0.001], [0.0, 0.001, st2]],
        ),
        1,
        up(0.2, -0.1, -0.05, diag(0.01, 0.01, st2 / 2.0)),
    )
    .unwrap();
    g.add_link(
        1,
        up(5.0, -2.0, -1.2, diag(0.04, 0.02, st2)),
        2,
        up(-0.3, 0.4, 0.1, diag(0.01, 0.015, st2 / 4.0)),
    )
    .unwrap();
    g
}

/// The Monte-Carlo covariance of the robot's pose in map 0 (eq. (3.14) applied to samples of
/// all four link poses), `n` samples.
fn monte_carlo(g: &MapGraph, robot: &Pose2, n: usize, seed: u64) -> (Pose2, Mat3) {
    let mut rng = Xoshiro256StarStar::seed_from_u64(seed);
    let samples: Vec<[f64; 3]> = (0..n)
        .map(|_| {
            let mut acc = Pose2::IDENTITY;
            for l in g.links() {
                let a = sample(&mut rng, &l.poses[0]);
                let b = sample(&mut rng, &l.poses[1]);
                acc = acc.compose(&a.compose(&b.inverse())); // eq. (3.10), then (3.14)
            }
            let p = acc.compose(robot);
            [p.x, p.y, p.theta]
        })
        .collect();
    let mean: Vec<f64> = (0..3)
        .map(|k| samples.iter().map(|s| s[k]).sum::<f64>() / n as f64)
        .collect();
    let mut cov = [[0.0; 3]; 3];
    for s in &samples {
        let d = [s[0] - mean[0], s[1] - mean[1], wrap_angle(s[2] - mean[2])];
        for i in 0..3 {
            for k in 0..3 {
                cov[i][k] += d[i] * d[k] / (n - 1) as f64;
            }
        }
    }
    (
        Pose2 {
            x: mean[0],
            y: mean[1],
            theta: mean[2],
        },
        cov,
    )
}

/// First-order propagation (eqs. (3.12)–(3.13)) against 10⁵ Monte-Carlo samples.
///
/// Tolerance: the sample covariance of `n` Gaussian draws has standard error
/// `√((Σᵢᵢ Σₖₖ + Σᵢₖ²)/n)`, 0.45 % of the variances at `n = 10⁵`; 5 of them bound the sampling
/// error. The linearisation neglects terms of relative size `σ_θ²` (cos θ ≈ 1 − θ²/2 in the
/// lever arms): with σ_θ = 0.03 rad per link pose that is below 0.1 %, so 1 % of
/// `√(Σᵢᵢ Σₖₖ)` is added. With σ_θ = 0.4 rad the same check must fail: the test sees the
/// linearisation break down.
#[test]
fn first_order_covariance_matches_monte_carlo_for_small_heading_noise() {
    let robot = Pose2::new(3.0, 1.0, 0.5).unwrap();
    let n = 100_000;
    let check = |sigma_theta: f64| -> f64 {
        let g = chain(sigma_theta);
        let lin = g
            .pose_in(0, 2, &UncertainPose::exact(robot), PathWeight::Hops)
            .unwrap();
        let (mc_mean, mc) = monte_carlo(&g, &robot, n, 2024);
        let mut worst: f64 = 0.0;
        for i in 0..3 {
            for k in 0..3 {
                let se = ((mc[i][i] * mc[k][k] + mc[i][k] * mc[i][k]) / n as f64).sqrt();
                let tol = 5.0 * se + 0.01 * (lin.cov[i][i] * lin.cov[k][k]).sqrt();
                worst = worst.max((lin.cov[i][k] - mc[i][k]).abs() / tol);
            }
        }
        // The means agree to the same order (the bias of the mean is O(σ_θ²) times the lever).
        if sigma_theta < 0.1 {
            assert!(
                lin.mean.distance(&mc_mean) < 0.02,
                "{:?} vs {mc_mean:?}",
                lin.mean
            );
        }
        worst
    };
    let small = check(0.03);
    assert!(
        small <= 1.0,
        "first order vs Monte Carlo: {small} tolerances"
    );
    let large = check(0.4);
    assert!(
        large > 1.0,
        "a 0.4 rad heading noise should break the linearisation: {large}"
    );
}

/// A three-map chain by hand: (2, 0, 90°) ⊕ (3, 0, 0) ⊕ robot (1, 0, 0) = (2, 4, 90°), and the
/// heading variance `b` of the first link acts over the 4 m lever: var(x) = a + 16b + d + e.
#[test]
fn hand_computed_chain() {
    let (a, b, c, d, e) = (0.01, 0.002, 0.03, 0.05, 0.004);
    let mut g = MapGraph::new();
    for _ in 0..3 {
        g.add_map(MapConfig::ShortRange, None).unwrap();
    }
    let origin = UncertainPose::exact(Pose2::IDENTITY);
    g.add_link(0, up(2.0, 0.0, FRAC_PI_2, diag(a, a, b)), 1, origin)
        .unwrap();
    g.add_link(1, up(3.0, 0.0, 0.0, diag(c, d, e)), 2, origin)
        .unwrap();
    let r = g
        .pose_in(
            0,
            2,
            &UncertainPose::exact(Pose2::new(1.0, 0.0, 0.0).unwrap()),
            PathWeight::Hops,
        )
        .unwrap();
    assert!((r.mean.x - 2.0).abs() < 1e-12 && (r.mean.y - 4.0).abs() < 1e-12);
    assert!((r.mean.theta - FRAC_PI_2).abs() < 1e-12);
    let want = [
        [a + 16.0 * b + d + e, 0.0, -4.0 * b - e],
        [0.0, a + c, 0.0],
        [-4.0 * b - e, 0.0, b + e],
    ];
    for i in 0..3 {
        for k in 0..3 {
            assert!((r.cov[i][k] - want[i][k]).abs() < 1e-12, "{:?}", r.cov);
        }
    }
    // The reverse direction: map 2's robot seen from map 0, then map 0's origin seen from map 2
    // is its inverse.
    let back = g
        .pose_in(
            2,
            0,
            &UncertainPose::exact(Pose2::IDENTITY),
            PathWeight::Hops,
        )
        .unwrap();
    let id = back
        .mean
        .compose(&g.pose_in(0, 2, &origin, PathWeight::Hops).unwrap().mean);
    assert!(id.x.abs() < 1e-12 && id.y.abs() < 1e-12 && id.theta.abs() < 1e-12);
}

/// Brute force: every walk from `from`'s origin to `to`'s origin that uses each link point at
/// most once, its cost under `weight`.
fn brute_force(g: &MapGraph, from: usize, to: usize, weight: PathWeight) -> Option<f64> {
    fn go(
        g: &MapGraph,
        map: usize,
        at: [f64; 2],
        to: usize,
        used: &mut Vec<bool>,
        cost: f64,
        w: PathWeight,
        best: &mut f64,
    ) {
        if map == to {
            let close = if w == PathWeight::Distance {
                at[0].hypot(at[1])
            } else {
                0.0
            };
            *best = best.min(cost + close);
        }
        for (i, l) in g.links().iter().enumerate() {
            if used[i] {
                continue;
            }
            for s in 0..2 {
                if l.maps[s] != map {
                    continue;
                }
                let (here, there) = (l.poses[s].mean, l.poses[1 - s].mean);
                let step = match w {
                    PathWeight::Hops => 1.0,
                    PathWeight::Distance => (here.x - at[0]).hypot(here.y - at[1]),
                    PathWeight::Uncertainty => {
                        let c = g.relative_pose(i, map).unwrap().cov;
                        c[0][0] + c[1][1]
                    }
                };
                used[i] = true;
                go(
                    g,
                    l.maps[1 - s],
                    [there.x, there.y],
                    to,
                    used,
                    cost + step,
                    w,
                    best,
                );
                used[i] = false;
            }
        }
    }
    let mut best = f64::INFINITY;
    go(
        g,
        from,
        [0.0, 0.0],
        to,
        &mut vec![false; g.links().len()],
        0.0,
        weight,
        &mut best,
    );
    best.is_finite().then_some(best)
}

#[test]
fn dijkstra_map_paths_match_brute_force() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(99);
    let mut compared = 0;
    for _ in 0..150 {
        let n = rng.int_in(2, 5) as usize;
        let mut g = MapGraph::new();
        for _ in 0..n {
            g.add_map(MapConfig::ShortRange, None).unwrap();
        }
        for _ in 0..rng.int_in(1, 6) {
            let a = rng.int_in(0, n as u64 - 1) as usize;
            let b = (a + 1 + rng.int_in(0, n as u64 - 2) as usize) % n;
            let mut pose = || {
                let s = rng.uniform(0.001, 0.1);
                up(
                    rng.uniform(-8.0, 8.0),
                    rng.uniform(-8.0, 8.0),
                    rng.uniform(-3.0, 3.0),
                    diag(s, s, s / 10.0),
                )
            };
            let (pa, pb) = (pose(), pose());
            g.add_link(a, pa, b, pb).unwrap();
        }
        let (from, to) = (
            rng.int_in(0, n as u64 - 1) as usize,
            rng.int_in(0, n as u64 - 1) as usize,
        );
        for w in [
            PathWeight::Hops,
            PathWeight::Distance,
            PathWeight::Uncertainty,
        ] {
            let oracle = brute_force(&g, from, to, w);
            match g.map_path(from, to, w) {
                Ok(path) => {
                    let o = oracle.expect("Dijkstra found a path brute force did not");
                    assert!(
                        (path.cost - o).abs() < 1e-9 * (1.0 + o),
                        "{w:?}: {} vs {o}",
                        path.cost
                    );
                    // The path is a chain: link k joins maps k and k + 1.
                    assert_eq!(path.maps.len(), path.links.len() + 1);
                    assert_eq!((path.maps[0], *path.maps.last().unwrap()), (from, to));
                    for (k, &l) in path.links.iter().enumerate() {
                        let m = g.links()[l].maps;
                        assert!(m.contains(&path.maps[k]) && m.contains(&path.maps[k + 1]));
                    }
                    compared += 1;
                }
                Err(MultimapError::NoPath { .. }) => assert!(oracle.is_none(), "{w:?}"),
                Err(e) => panic!("{e}"),
            }
        }
    }
    assert!(compared > 200, "{compared}");
}

/// The loop search (§3.3.3 with eq. (3.8)): a square of four maps driven around; in the last
/// one the robot is near the first map's door. What falls inside the radius depends on the
/// propagated uncertainty.
#[test]
fn loop_search_radius_follows_the_propagated_uncertainty() {
    let build = |var: f64| {
        let mut g = MapGraph::new();
        for _ in 0..4 {
            g.add_map(MapConfig::ShortRange, None).unwrap();
        }
        let origin = UncertainPose::exact(Pose2::IDENTITY);
        // Each map: 10 m ahead, then a left turn into the next.
        for m in 0..3 {
            g.add_link(
                m,
                up(10.0, 0.0, FRAC_PI_2, diag(var, var, var / 100.0)),
                m + 1,
                origin,
            )
            .unwrap();
        }
        // A door of map 0 seen earlier, 2 m behind its origin along its −y axis; and a door
        // candidate in map 1 far away.
        g.add_candidate(0, up(0.0, -2.0, 0.0, diag(0.0, 0.0, 0.0)), 7)
            .unwrap();
        g.add_candidate(1, up(5.0, 3.0, 0.0, diag(0.0, 0.0, 0.0)), 8)
            .unwrap();
        g
    };
    // The robot 8 m into map 3 is 2 m from map 0's origin (at (0, 2) there), 4 m from the
    // candidate.
    let robot = UncertainPose::exact(Pose2::new(8.0, 0.0, 0.0).unwrap());
    let params = SearchParams::default();
    let certain = build(1e-6)
        .loop_search(0, 3, &robot, &params, PathWeight::Hops)
        .unwrap();
    assert!((certain.pose.mean.x - 0.0).abs() < 1e-9 && (certain.pose.mean.y - 2.0).abs() < 1e-9);
    assert!(
        (certain.radius - search_radius(position_lambda_max(&certain.pose.cov), &params).unwrap())
            .abs()
            < 1e-12
    );
    assert!(certain.radius < 3.1, "{}", certain.radius);
    // Within 3.1 m: map 0 → 1's door at (10, 0) is 10.2 m away; nothing else is near.
    assert!(certain.hits.is_empty(), "{:?}", certain.hits);
    let uncertain = build(0.2)
        .loop_search(0, 3, &robot, &params, PathWeight::Hops)
        .unwrap();
    assert!(uncertain.radius > 4.0, "{}", uncertain.radius);
    assert_eq!(uncertain.hits[0].target, LoopTarget::Candidate(0));
    assert!((uncertain.hits[0].distance - 4.0).abs() < 1e-9);
    // The link point of map 3 itself (2 → 3) is never a loop target.
    assert!(
        uncertain
            .hits
            .iter()
            .all(|h| h.target != LoopTarget::Link(2))
    );
}

#[test]
fn bad_graph_input_is_refused() {
    let mut g = MapGraph::new();
    let a = g.add_map(MapConfig::ShortRange, None).unwrap();
    let origin = UncertainPose::exact(Pose2::IDENTITY);
    assert_eq!(
        g.add_link(a, origin, a, origin),
        Err(MultimapError::SameMap(0))
    );
    assert_eq!(
        g.add_link(a, origin, 5, origin),
        Err(MultimapError::UnknownMap(5))
    );
    let b = g.add_map(MapConfig::LongRange, None).unwrap();
    assert!(matches!(
        g.map_path(a, b, PathWeight::Distance),
        Err(MultimapError::NoPath { from: 0, to: 1 })
    ));
    assert_eq!(g.relative_pose(3, a), Err(MultimapError::UnknownLink(3)));
    let bad = UncertainPose {
        mean: Pose2 {
            x: f64::INFINITY,
            y: 0.0,
            theta: 0.0,
        },
        cov: [[0.0; 3]; 3],
    };
    assert!(
        g.add_link(a, bad, b, origin)
            .unwrap_err()
            .to_string()
            .contains("not finite")
    );
}

/// The graph's bounds are errors, never a silently reused index.
#[test]
fn the_graph_bounds_are_errors() {
    let mut g = MapGraph::new();
    for k in 0..MAX_MAPS {
        assert_eq!(g.add_map(MapConfig::ShortRange, None), Ok(k));
    }
    assert_eq!(
        g.add_map(MapConfig::LongRange, None),
        Err(MultimapError::TooLarge {
            what: "maps",
            n: MAX_MAPS + 1,
            max: MAX_MAPS,
        })
    );
    assert_eq!(g.maps().len(), MAX_MAPS);
    assert_eq!(g.maps()[MAX_MAPS - 1].config, MapConfig::ShortRange);
    // Link points and candidates share their bound.
    let origin = UncertainPose::exact(Pose2::IDENTITY);
    for k in 0..MAX_LINKS {
        if k % 2 == 0 {
            assert_eq!(g.add_link(k % 7, origin, 7, origin), Ok(k / 2));
        } else {
            assert_eq!(g.add_candidate(k % 5, origin, k as u64), Ok(k / 2));
        }
    }
    let full = MultimapError::TooLarge {
        what: "link points and candidates",
        n: MAX_LINKS + 1,
        max: MAX_LINKS,
    };
    assert_eq!(g.add_link(0, origin, 1, origin), Err(full.clone()));
    assert_eq!(g.add_candidate(0, origin, 0), Err(full));
    // Map 7 now has 50,000 link points: all pairs of them (distance paths) would be 1.25·10⁹
    // edges, so those are refused; paths by hops do not need them.
    let crowded = MultimapError::TooLarge {
        what: "link points of one map (their edges are all pairs)",
        n: MAX_LINKS / 2,
        max: MAX_LINKS_PER_MAP_FOR_EDGES,
    };
    assert_eq!(g.link_edges(7), Err(crowded));
    // Map 0, the first the distance path visits, already has 7,143 (every 14th k).
    assert!(matches!(
        g.map_path(0, 7, PathWeight::Distance),
        Err(MultimapError::TooLarge {
            n: 7143,
            max: MAX_LINKS_PER_MAP_FOR_EDGES,
            ..
        })
    ));
    assert_eq!(g.map_path(0, 7, PathWeight::Hops).unwrap().maps, [0, 7]);
}
