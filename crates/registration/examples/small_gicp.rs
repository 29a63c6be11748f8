//! Registration of the bundled real 3-D lidar pair without an initial guess (filters, FPFH,
//! RANSAC, ICP), against the transform shipped with it, and the time of a bare
//! nearest-neighbour pass over the same clouds (one k-d tree build over the target, one query per
//! source point) in the same run.
//!
//! ```text
//! cargo run --release -p chronomap-registration --example small_gicp [-- SEEDS]
//! ```

use std::time::Instant;

use chronomap_registration::{
    Cloud, IcpMethod, KdTree, RegistrationParams, Rigid, kabsch, register,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seeds: u64 = match std::env::args().nth(1) {
        Some(s) => s.parse()?,
        None => 5,
    };
    let data = chronomap_testutil::data_path("registration_small_gicp");
    let source: Cloud<3> = chronomap_io::read_ply(data.join("source.ply.xz"))?;
    let target: Cloud<3> = chronomap_io::read_ply(data.join("target.ply.xz"))?;
    let truth = read_truth(&std::fs::read_to_string(data.join("T_target_source.txt"))?)?;
    println!(
        "source {} points, target {} points; T_target_source: {:.3} m, {:.3}°",
        source.len(),
        target.len(),
        truth.translation_norm(),
        truth.angle().to_degrees()
    );

    let mut bare = f64::INFINITY;
    for _ in 0..3 {
        let start = Instant::now();
        let tree = KdTree::new(target.points());
        let sum: f64 = source
            .points()
            .iter()
            .filter_map(|p| tree.nearest(p))
            .map(|(_, d2)| d2)
            .sum();
        bare = bare.min(start.elapsed().as_secs_f64());
        assert!(sum.is_finite());
    }
    println!(
        "bare nearest-neighbour pass (best of 3): {:.1} ms\n",
        bare * 1e3
    );

    // The variants: [Stüde 2024] appendix A's range filter (30 m) on a 5 cm grid, then each ICP.
    use IcpMethod::{PointToPlane, PointToPoint, Symmetric};
    let variants = [
        (
            "5 cm, r ≤ 30 m, symmetric",
            Some(0.05),
            Some(30.0),
            Symmetric,
            None,
        ),
        (
            "… with persistence β = 0.5",
            Some(0.05),
            Some(30.0),
            Symmetric,
            Some(0.5),
        ),
        (
            "… with persistence β = 0",
            Some(0.05),
            Some(30.0),
            Symmetric,
            Some(0.0),
        ),
        (
            "5 cm, r ≤ 30 m, point-to-plane",
            Some(0.05),
            Some(30.0),
            PointToPlane,
            None,
        ),
        (
            "5 cm, r ≤ 30 m, point-to-point",
            Some(0.05),
            Some(30.0),
            PointToPoint,
            None,
        ),
        (
            "10 cm, r ≤ 30 m, symmetric",
            Some(0.1),
            Some(30.0),
            Symmetric,
            None,
        ),
        (
            "5 cm, no range filter, symmetric",
            Some(0.05),
            None,
            Symmetric,
            None,
        ),
    ];
    println!(
        "{:<34} {:>4} {:>5} {:>8} {:>8} {:>9} {:>9} {:>5} {:>5} {:>6} {:>8} {:>7}",
        "filters, ICP",
        "seed",
        "keys",
        "rot °",
        "trans cm",
        "coarse °",
        "coarse cm",
        "corr",
        "inl",
        "σ̂ cm",
        "time ms",
        "× bare"
    );
    for (name, voxel, range, method, persistence) in variants {
        let mut params = RegistrationParams::for_voxel(0.25);
        params.filters.voxel = voxel;
        params.filters.range = range.map(|r| (0.0, r));
        params.icp.method = method;
        params.persistence = persistence;
        if method == IcpMethod::PointToPoint {
            params.icp.max_iterations = 100;
        }
        for seed in 0..seeds {
            params.ransac.seed = seed;
            let start = Instant::now();
            let result = register(&source, &target, &params)?;
            let time = start.elapsed().as_secs_f64();
            let (r, t) = result.transform.error_to(&truth);
            let (cr, ct) = result.coarse.error_to(&truth);
            println!(
                "{name:<34} {seed:>4} {:>5} {:>8.4} {:>8.3} {:>9.3} {:>9.2} {:>5} {:>5} {:>6.2} {:>8.0} {:>7.1}",
                result.keypoints.0,
                r.to_degrees(),
                t * 100.0,
                cr.to_degrees(),
                ct * 100.0,
                result.correspondences,
                result.inliers,
                result.information.sigma * 100.0,
                time * 1e3,
                time / bare
            );
        }
    }
    Ok(())
}

/// The 4×4 row-major matrix of `T_target_source.txt`, its rotation re-orthonormalised (the file
/// has 6 significant digits).
fn read_truth(text: &str) -> Result<Rigid<3>, Box<dyn std::error::Error>> {
    let v: Vec<f64> = text
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    if v.len() != 16 {
        return Err(format!("T_target_source.txt: {} numbers, 16 expected", v.len()).into());
    }
    let axes = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let columns = [
        [0.0; 3],
        [v[0], v[4], v[8]],
        [v[1], v[5], v[9]],
        [v[2], v[6], v[10]],
    ];
    let mut t = kabsch(&axes, &columns)?;
    t.translation = [v[3], v[7], v[11]];
    Ok(t)
}
