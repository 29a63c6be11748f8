//! 2-D registration without an initial guess (FPFH-2D + RANSAC + ICP) on every loop pair of the
//! Málaga 2006 keyframes, against the SLAM estimate.
//!
//! ```text
//! cargo run --release -p chronomap-registration --example malaga_loops [-- β]
//! ```

#[path = "../tests/malaga_data/mod.rs"]
mod malaga_data;

use std::time::Instant;

use chronomap_registration::{register_scans, scan_params};

fn main() {
    let frames = malaga_data::keyframes();
    let pairs = malaga_data::loop_pairs(&frames);
    let mut params = scan_params();
    // Optional persistence threshold β (the first argument).
    params.persistence = std::env::args()
        .nth(1)
        .map(|b| b.parse().expect("β is a number"));
    println!("persistence β: {:?}", params.persistence);
    let (mut ok, mut rot, mut trans, mut total) = (0, Vec::new(), Vec::new(), 0.0);
    for &(i, j) in &pairs {
        let truth = malaga_data::relative(&frames[j], &frames[i]);
        let start = Instant::now();
        let result = register_scans(&frames[j].scan, &frames[i].scan, &params);
        total += start.elapsed().as_secs_f64();
        match result {
            Ok(r) => {
                let (dr, dt) = r.transform.error_to(&truth);
                if dr.to_degrees() < 2.0 && dt < 0.2 {
                    ok += 1;
                    rot.push(dr.to_degrees());
                    trans.push(dt);
                }
                println!(
                    "{i:>3} {j:>3} dist {:>5.2} m  rot err {:>7.3}°  trans err {:>7.3} m  inliers {:>4}/{:<4} σ̂ {:.3} m",
                    truth.translation_norm(),
                    dr.to_degrees(),
                    dt,
                    r.inliers,
                    r.correspondences,
                    r.information.sigma
                );
            }
            Err(e) => println!("{i:>3} {j:>3} failed: {e}"),
        }
    }
    rot.sort_by(f64::total_cmp);
    trans.sort_by(f64::total_cmp);
    let median = |v: &[f64]| {
        if v.is_empty() {
            f64::NAN
        } else {
            v[v.len() / 2]
        }
    };
    println!(
        "\n{ok}/{} pairs within 2° and 0.2 m of the SLAM estimate; their median errors {:.3}° and {:.3} m; {:.1} ms per pair",
        pairs.len(),
        median(&rot),
        median(&trans),
        1e3 * total / pairs.len() as f64
    );
}
