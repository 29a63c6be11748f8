//! Registration of the bundled real 3-D lidar pair without an initial guess (FPFH + RANSAC +
//! point-to-plane ICP), against the transform shipped with it, and the time of a bare
//! nearest-neighbour pass over the same clouds in the same run.
//!
//! ```text
//! cargo run --release -p chronomap-registration --example small_gicp [-- --voxel 0.25 --persistence 1.0 --seeds 5]
//! ```

use std::time::Instant;

use chronomap_registration::{Cloud, IcpMethod, KdTree, RegistrationParams, Rigid, register};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut voxel = 0.25;
    let mut persistence = None;
    let mut seeds = 5u64;
    let mut fine = None;
    let mut icp_distance = None;
    let mut method: Option<String> = None;
    let mut fine_normal = None;
    let mut fine_k = None;
    let args: Vec<String> = std::env::args().skip(1).collect();
    for pair in args.chunks(2) {
        let value = pair.get(1).ok_or("every option needs a value")?;
        match pair[0].as_str() {
            "--voxel" => voxel = value.parse()?,
            "--persistence" => persistence = Some(value.parse()?),
            "--seeds" => seeds = value.parse()?,
            "--fine-normal-radius" => fine_normal = Some(value.parse::<f64>()?),
            "--fine-normal-k" => fine_k = Some(value.parse::<usize>()?),
            "--fine" => fine = Some(value.parse::<f64>()?),
            "--icp-distance" => icp_distance = Some(value.parse::<f64>()?),
            "--method" => method = Some(value.clone()),
            other => return Err(format!("unknown option {other}").into()),
        }
    }
    let data = chronomap_testutil::data_path("registration_small_gicp");
    let source: Cloud<3> = chronomap_io::read_ply(data.join("source.ply.xz"))?;
    let target: Cloud<3> = chronomap_io::read_ply(data.join("target.ply.xz"))?;
    let truth = read_truth(&std::fs::read_to_string(data.join("T_target_source.txt"))?)?;
    println!(
        "source {} points, target {} points; truth: {:.3} m, {:.3}°",
        source.len(),
        target.len(),
        truth.translation_norm(),
        truth.angle().to_degrees()
    );

    // The bare pass: one k-d tree build over the target, one nearest-neighbour query per
    // source point (best of 3).
    let mut bare = f64::INFINITY;
    let mut checksum = 0.0;
    for _ in 0..3 {
        let start = Instant::now();
        let tree = KdTree::new(target.points());
        checksum = source
            .points()
            .iter()
            .filter_map(|p| tree.nearest(p))
            .map(|(_, d2)| d2)
            .sum::<f64>();
        bare = bare.min(start.elapsed().as_secs_f64());
    }
    println!(
        "bare nearest-neighbour pass: {:.1} ms (sum of squared distances {checksum:.1})",
        bare * 1e3
    );

    let mut params = RegistrationParams::for_voxel(voxel);
    params.persistence = persistence;
    if let Some(f) = fine {
        params.fine_voxel = (f > 0.0).then_some(f);
    }
    if let Some(d) = icp_distance {
        params.icp.max_correspondence_distance = d;
    }
    if let Some(r) = fine_normal {
        params.fine_normal_radius = r;
    }
    if let Some(k) = fine_k {
        params.fine_normal_neighbours = k;
    }
    match method.as_deref() {
        None => {}
        Some("point-to-point") => params.icp.method = IcpMethod::PointToPoint,
        Some("point-to-plane") => params.icp.method = IcpMethod::PointToPlane,
        Some("symmetric") => params.icp.method = IcpMethod::Symmetric,
        Some(other) => return Err(format!("unknown ICP method {other}").into()),
    }
    println!(
        "\nvoxel {voxel} m, persistence {persistence:?}\n{:>5} {:>9} {:>9} {:>7} {:>7} {:>7} {:>6} {:>9} {:>9} {:>8} {:>8} {:>6}",
        "seed",
        "rot °",
        "trans cm",
        "keys s",
        "keys t",
        "corr",
        "inl",
        "coarse °",
        "coarse cm",
        "σ̂ cm",
        "time ms",
        "ratio"
    );
    for seed in 0..seeds {
        params.ransac.seed = seed;
        let start = Instant::now();
        let result = register(&source, &target, &params)?;
        let time = start.elapsed().as_secs_f64();
        let (r, t) = result.transform.error_to(&truth);
        let (cr, ct) = result.coarse.error_to(&truth);
        eprintln!(
            "icp: {} iterations, converged {}, fitness {:.3}, rmse {:.4}",
            result.icp.iterations, result.icp.converged, result.icp.fitness, result.icp.rmse
        );
        println!(
            "{seed:>5} {:>9.4} {:>9.3} {:>7} {:>7} {:>7} {:>6} {:>9.3} {:>9.2} {:>8.2} {:>8.0} {:>6.1}",
            r.to_degrees(),
            t * 100.0,
            result.keypoints.0,
            result.keypoints.1,
            result.correspondences,
            result.inliers,
            cr.to_degrees(),
            ct * 100.0,
            result.information.sigma * 100.0,
            time * 1e3,
            time / bare
        );
    }
    Ok(())
}

/// The 4×4 row-major matrix of `T_target_source.txt`.
fn read_truth(text: &str) -> Result<Rigid<3>, Box<dyn std::error::Error>> {
    let values: Vec<f64> = text
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    if values.len() != 16 {
        return Err(format!("T_target_source.txt: {} numbers, 16 expected", values.len()).into());
    }
    let m: [[f64; 4]; 4] = std::array::from_fn(|i| std::array::from_fn(|j| values[4 * i + j]));
    // The file has 6 significant digits: re-orthonormalise the rotation before checking it.
    let r = chronomap_registration::kabsch(
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ],
        &[
            [0.0; 3],
            [m[0][0], m[1][0], m[2][0]],
            [m[0][1], m[1][1], m[2][1]],
            [m[0][2], m[1][2], m[2][2]],
        ],
    )?;
    let mut clean = m;
    for i in 0..3 {
        clean[i][..3].copy_from_slice(&r.rotation[i]);
    }
    Ok(Rigid::from_matrix4(&clean)?)
}
