//! Registration without an initial guess ([Stüde 2024] §3.2.2: filters, FPFH, RANSAC, ICP) of a
//! pair of 3-D clouds, timed against a bare nearest-neighbour pass over the same clouds in the
//! same run — one k-d tree build over the target and one query per source point, the least any
//! alignment of the two clouds must do — with the errors against the known transform.

use std::time::Instant;

use chronomap_registration::{Cloud, KdTree, RegistrationParams, Rigid, register};
use serde::Serialize;

use crate::median;

/// The measurements.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RegistrationBench {
    /// Source and target points.
    pub points: (usize, usize),
    /// Timed repetitions of each part (the median is reported).
    pub repeats: usize,
    /// The bare pass, median, ms.
    pub bare_nn_ms: f64,
    /// The registration, median, ms.
    pub registration_ms: f64,
    /// `registration_ms / bare_nn_ms`.
    pub ratio: f64,
    /// Rotation error of the registration against the truth (degrees).
    pub rotation_error_deg: f64,
    /// Translation error (m).
    pub translation_error_m: f64,
    /// RANSAC inliers and ICP iterations of the last run.
    pub inliers: usize,
    /// ICP iterations of the last run.
    pub icp_iterations: usize,
}

/// Registers `source` onto `target` `repeats` times (at least once) with `params`, and runs the
/// bare pass as often; errors against `truth`.
///
/// # Errors
/// If the registration fails.
pub fn run(
    source: &Cloud<3>,
    target: &Cloud<3>,
    truth: &Rigid<3>,
    params: &RegistrationParams,
    repeats: usize,
) -> Result<RegistrationBench, chronomap_registration::RegistrationError> {
    let repeats = repeats.max(1);
    let mut bare = Vec::with_capacity(repeats);
    let mut timed = Vec::with_capacity(repeats);
    let mut last = None;
    for _ in 0..repeats {
        let start = Instant::now();
        let tree = KdTree::new(target.points());
        let sum: f64 = source
            .points()
            .iter()
            .filter_map(|p| tree.nearest(p))
            .map(|(_, d2)| d2)
            .sum();
        bare.push(start.elapsed().as_secs_f64() * 1e3);
        std::hint::black_box(sum);
        let start = Instant::now();
        let result = register(source, target, params)?;
        timed.push(start.elapsed().as_secs_f64() * 1e3);
        last = Some(result);
    }
    let result = last.expect("at least one repetition");
    let (rotation, translation) = result.transform.error_to(truth);
    let (bare_nn_ms, registration_ms) = (median(&bare), median(&timed));
    Ok(RegistrationBench {
        points: (source.len(), target.len()),
        repeats,
        bare_nn_ms,
        registration_ms,
        ratio: registration_ms / bare_nn_ms,
        rotation_error_deg: rotation.to_degrees(),
        translation_error_m: translation,
        inliers: result.inliers,
        icp_iterations: result.icp.iterations,
    })
}
