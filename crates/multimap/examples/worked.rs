//! The worked example of docs/multimap.md: four maps linked at doors, the robot's pose and
//! covariance in the first map's frame (eq. (3.14)), the loop search (eq. (3.8)), a loop
//! closure and the optimised map poses ([Stüde 2024] §3.3.3).
//! `cargo run --release -p chronomap-multimap --example worked`

use std::f64::consts::FRAC_PI_2;

use chronomap_multimap::config::MapConfig;
use chronomap_multimap::graph::{MapGraph, PathWeight};
use chronomap_multimap::mapper::OdometryNoise;
use chronomap_multimap::optimize::{OptimizeParams, optimize};
use chronomap_multimap::se2::{
    Mat3, Pose2, UncertainPose, jacobian_compose_first, jacobian_compose_second, mat_add, sandwich,
};
use chronomap_multimap::search::SearchParams;

/// Drives `legs` (metres ahead, then a turn in radians) from a map's origin in 0.1 m and
/// 0.1 rad steps with odometry that over-reads distances by 2 % and turns by 3 %; returns
/// the true local pose, the odometry's, and its covariance (eq. (3.13) per increment).
fn drive(legs: &[(f64, f64)], noise: &OdometryNoise) -> (Pose2, UncertainPose) {
    let mut truth = Pose2::IDENTITY;
    let mut odom = UncertainPose::exact(Pose2::IDENTITY);
    for &(dist, turn) in legs {
        let steps = (dist / 0.1).round() as usize;
        for _ in 0..steps {
            let u = Pose2 {
                x: dist / steps as f64,
                y: 0.0,
                theta: 0.0,
            };
            truth = truth.compose(&u);
            let m = Pose2 { x: u.x * 1.02, ..u };
            odom = odom.compose(&UncertainPose {
                mean: m,
                cov: noise.covariance(&m),
            });
        }
        let steps = (turn.abs() / 0.1).ceil() as usize;
        for _ in 0..steps {
            let u = Pose2 {
                x: 0.0,
                y: 0.0,
                theta: turn / steps as f64,
            };
            truth = truth.compose(&u);
            let m = Pose2 {
                theta: u.theta * 1.03,
                ..u
            };
            odom = odom.compose(&UncertainPose {
                mean: m,
                cov: noise.covariance(&m),
            });
        }
    }
    (truth, odom)
}

fn show(m: &Mat3) -> String {
    format!(
        "[[{:.5}, {:.5}, {:.5}], [{:.5}, {:.5}, {:.5}], [{:.5}, {:.5}, {:.5}]]",
        m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2]
    )
}

fn pose(p: &Pose2) -> String {
    format!("({:.3} m, {:.3} m, {:.4} rad)", p.x, p.y, p.theta)
}

fn main() {
    let noise = OdometryNoise::default();
    println!("odometry noise {noise:?}; distances read 2 % long, turns 3 % large");
    // The building: a corridor M0 along x (8 m), a door on the left into office M1 (6 m up),
    // a door on the left into lab M2 (8 m back along −x), a door on the left into corridor
    // M3 that leads back down towards M0's start.
    let legs: [&[(f64, f64)]; 3] = [
        &[(8.0, FRAC_PI_2)],
        &[(6.0, FRAC_PI_2)],
        &[(8.0, FRAC_PI_2)],
    ];
    let configs = [
        MapConfig::ShortRange,
        MapConfig::ShortRange,
        MapConfig::LongRange,
        MapConfig::ShortRange,
    ];
    let mut g = MapGraph::new();
    for c in configs {
        g.add_map(c, None).unwrap();
    }
    let mut true_origin = vec![Pose2::IDENTITY];
    // A link-point candidate: at the start, the robot saw the open door to M3 ahead-left
    // (its data is saved with tag 0).
    let start_door = UncertainPose::exact(Pose2::new(0.0, 0.5, -FRAC_PI_2).unwrap());
    g.add_candidate(0, start_door, 0).unwrap();
    for (m, leg) in legs.iter().enumerate() {
        let (truth, odom) = drive(leg, &noise);
        true_origin.push(true_origin[m].compose(&truth));
        let link = g
            .add_link(m, odom, m + 1, UncertainPose::exact(Pose2::IDENTITY))
            .unwrap();
        let rel = g.relative_pose(link, m).unwrap();
        println!(
            "link L{link} (M{m} → M{}): pose in M{m} by odometry {} (true {}), eq. (3.10) relative pose {} with eq. (3.13) covariance {}",
            m + 1,
            pose(&odom.mean),
            pose(&truth),
            pose(&rel.mean),
            show(&rel.cov)
        );
    }
    // In M3 the robot drives 5.5 m down the corridor towards M0's start.
    let (truth3, robot) = drive(&[(5.5, 0.0)], &noise);
    let true_robot = true_origin[3].compose(&truth3);
    let path = g.map_path(0, 3, PathWeight::Hops).unwrap();
    let in0 = g.pose_in(0, 3, &robot, PathWeight::Hops).unwrap();
    println!(
        "\nrobot in M3: {} with covariance {}",
        pose(&robot.mean),
        show(&robot.cov)
    );
    println!(
        "Dijkstra path of maps {:?} via link points {:?}; eq. (3.14): robot in M0 {} (true {}), covariance {}",
        path.maps,
        path.links,
        pose(&in0.mean),
        pose(&true_robot),
        show(&in0.cov)
    );
    let params = SearchParams::default();
    let search = g
        .loop_search(0, 3, &robot, &params, PathWeight::Hops)
        .unwrap();
    println!(
        "λ_max = {:.4} m², 95 % major axis {:.3} m, eq. (3.8) radius r = {:.3} m (r_min = {}, β = {}); hits {:?}",
        in0.lambda_max(),
        chronomap_multimap::search::major_axis_95(in0.lambda_max()),
        search.radius,
        params.r_min,
        params.beta,
        search.hits
    );
    let chains: Vec<UncertainPose> = (0..4)
        .map(|m| {
            g.compose_path(&g.map_path(0, m, PathWeight::Hops).unwrap())
                .unwrap()
        })
        .collect();
    // Registration against the candidate's data finds the robot's true pose in M0 to within
    // 2 cm and 0.01 rad: a new link point between M3 and M0.
    let measured = UncertainPose::new(
        true_robot,
        [[4e-4, 0.0, 0.0], [0.0, 4e-4, 0.0], [0.0, 0.0, 1e-4]],
    )
    .unwrap();
    g.add_link(3, robot, 0, measured).unwrap();
    let opt = optimize(&g, &OptimizeParams::default()).unwrap();
    println!(
        "\noptimisation: cost F {:.3} → {:.3} in {} iterations",
        opt.initial_cost, opt.final_cost, opt.iterations
    );
    for m in 0..4 {
        let chain = chains[m];
        println!(
            "M{m}: true origin {}; by the chain before the loop {} (error {:.3} m), trace of its covariance {:.4}; optimised {} (error {:.3} m), marginal covariance {}",
            pose(&true_origin[m]),
            pose(&chain.mean),
            chain.mean.distance(&true_origin[m]),
            chronomap_multimap::se2::trace(&chain.cov),
            pose(&opt.poses[m]),
            opt.poses[m].distance(&true_origin[m]),
            show(&opt.covariances[m])
        );
        println!(
            "    trace of the optimised marginal covariance {:.4}",
            chronomap_multimap::se2::trace(&opt.covariances[m])
        );
    }
    // The robot's pose in M0 after the loop: the optimised M3 pose ⊕ its pose in M3.
    let x3 = UncertainPose {
        mean: opt.poses[3],
        cov: opt.covariances[3],
    };
    let after = x3.compose(&robot);
    let j1 = jacobian_compose_first(&x3.mean, &robot.mean);
    let j2 = jacobian_compose_second(&x3.mean);
    debug_assert_eq!(
        after.cov,
        mat_add(&sandwich(&j1, &x3.cov), &sandwich(&j2, &robot.cov))
    );
    println!(
        "robot in M0 after the loop: {} (error {:.3} m), covariance {}, λ_max {:.4} m² (before {:.4} m²)",
        pose(&after.mean),
        after.mean.distance(&true_robot),
        show(&after.cov),
        after.lambda_max(),
        in0.lambda_max()
    );
    println!(
        "robot in M0 by the loop link alone (Dijkstra picks it: 1 hop): {}",
        pose(&g.pose_in(0, 3, &robot, PathWeight::Hops).unwrap().mean)
    );
}
