//! `chronomap bench activity --quick --json` end to end: the extraction processes every
//! detection of the track file it reads, CoPA-Map trains on the whole bundled ATC grid, and
//! every timing and ratio of the report is a positive number. (Speed itself is measured by the
//! command, never by a test.)

use std::io::{BufRead, BufReader};
use std::process::Command;

use crate::common::{json, number_at, positive_at, repo_path, strings};

/// Training samples of `data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz`.
const ATC_GRID_SAMPLES: u64 = 76_456;

/// Data rows of a track file (plain, .xz or .gz): lines that are neither blank nor comments.
fn rows(path: &str) -> u64 {
    let reader = chronomap_io::text::open_data_file(repo_path(path))
        .unwrap_or_else(|e| panic!("{path}: {e}"));
    BufReader::new(reader)
        .lines()
        .map(|line| line.unwrap_or_else(|e| panic!("{path}: {e}")))
        .filter(|line| {
            let line = line.trim();
            !line.is_empty() && !line.starts_with('#')
        })
        .count() as u64
}

#[test]
#[ignore = "slow: a benchmark's smoke test (cargo test -- --include-ignored)"]
fn bench_activity_quick_processes_every_detection_and_reports_positive_timings() {
    let out = Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args(["bench", "activity", "--quick", "--json"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run chronomap");
    let report = json(&out);
    let number = |path: &[&str]| number_at(&report, path);
    let positive = |path: &[&str]| positive_at(&report, path);
    assert_eq!(report["quick"], true);

    // Extraction: one hour of tracks, every row of its file read and binned.
    let extraction = &report["extraction"];
    let files = strings(&extraction["track_files"]);
    assert_eq!(files, ["data/atc_20121024_1hz/atc-1024-10_train.csv.xz"]);
    let detections: u64 = files.iter().map(|f| rows(f)).sum();
    assert_eq!(extraction["detections"].as_u64(), Some(detections));
    // One hour bin, three bundled robots, 1 s steps; every robot step ray cast once without
    // the cache, far fewer map cells with it.
    let bins = extraction["bins"].as_array().expect("bins").len() as u64;
    let robots = extraction["robots"].as_array().expect("robots").len() as u64;
    assert_eq!((bins, robots), (1, 3));
    assert_eq!(
        extraction["robot_steps"].as_u64(),
        Some(bins * 3600 * robots)
    );
    assert_eq!(
        extraction["fov_uncached_ray_casts"],
        extraction["robot_steps"]
    );
    let cached = positive(&["extraction", "fov_cached_ray_casts"]);
    assert!(cached < positive(&["extraction", "robot_steps"]));
    let counted = positive(&["extraction", "total_count"]);
    assert!(counted <= detections as f64);
    positive(&["extraction", "samples"]);
    // The bare scan sees every detection: binned or outside the map.
    assert!(number(&["extraction", "bare_scan_outside"]) < detections as f64);
    for key in [
        "seconds",
        "detections_per_second",
        "robot_steps_per_second",
        "bare_scan_seconds",
        "ratio_to_bare_scan",
        "fov_uncached_seconds",
        "ratio_uncached_fov_to_extraction",
    ] {
        positive(&["extraction", key]);
    }
    let seconds = number(&["extraction", "seconds"]);
    assert!(
        (positive(&["extraction", "detections_per_second"]) * seconds - detections as f64).abs()
            < 1e-6 * detections as f64
    );

    // CoPA-Map: the whole bundled grid, the default model, the quick iterations.
    let copa = &report["copa"];
    assert_eq!(copa["samples"].as_u64(), Some(ATC_GRID_SAMPLES));
    assert_eq!(
        (
            copa["inducing"].as_u64(),
            copa["batch"].as_u64(),
            copa["iterations"].as_u64()
        ),
        (Some(200), Some(1000), Some(12))
    );
    assert!(number(&["copa", "final_elbo"]).is_finite());
    assert_eq!(copa["bare_gemm_products_per_iteration"], 16);
    assert_eq!(
        number(&["copa", "bare_gemm_flops_per_iteration"]),
        2.0 * (5.0 * 2.0 * 200.0 * 200.0 * 1000.0 + 3.0 * 2.0 * 200f64.powi(3))
    );
    for key in [
        "seconds",
        "setup_seconds",
        "seconds_per_iteration",
        "bare_gemm_seconds_per_iteration",
        "ratio_iteration_to_bare_gemm",
        "ratio_fit_to_bare_gemm",
        "bare_dense_seconds_per_iteration",
        "ratio_iteration_to_bare_dense",
    ] {
        positive(&["copa", key]);
    }
    for key in [
        "one_thread_seconds_per_iteration",
        "all_threads_seconds_per_iteration",
        "speedup",
    ] {
        positive(&["copa", "sequential", key]);
    }
    assert_eq!(copa["sequential"]["iterations"], 12);
    positive(&["threads"]);
}
