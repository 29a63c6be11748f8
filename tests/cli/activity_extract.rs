//! `chronomap activity extract` end to end on the bundled ATC day ([Stüde 2024] §4.2.2, §4.3.2):
//! one hour of the real tracks seen by the bundled patrol robots on the real map, with the
//! measured numbers of samples, cells, observed duration and detections; the ground truth of
//! the same hour; and errors naming the file and line of a bad robot path.

use std::path::PathBuf;

use crate::common::{assert_mentions, chronomap, error, json, repo, tmp};
use chronomap_io::read_rate_grid;
use serde_json::Value;

/// Measured on the 10:00 file (38,633 detections) with the three bundled robots: the cells
/// seen in the hour (each once: one bin), the detections counted while visible and the summed
/// observed duration (seconds).
const SAMPLES: usize = 800;
const COUNT: u64 = 5167;
const DURATION: f64 = 1_132_028.0;
/// The ground truth of the same hour and cells: all detections in them, and the cells where
/// nobody was detected.
const TRUTH_COUNT: u64 = 11_511;
const TRUTH_ZERO: usize = 190;

/// A file of the module's tests (`target/tmp/activity_extract/NAME`).
fn scratch(name: &str) -> PathBuf {
    tmp("activity_extract").join(name)
}

/// `activity extract` of the 10:00 file (bin 1 from 09:00 JST) with the bundled map and paths,
/// plus `extra` flags; returns the summary and the rows read back.
fn ten_oclock(output: &str, extra: &[&str]) -> (Value, chronomap_io::RateGrid) {
    let out = scratch(output);
    let tracks = repo("data/atc_20121024_1hz/atc-1024-10_train.csv.xz");
    let map = repo("data/atc_copa_map_grid/atc_map.yaml");
    let paths = repo("data/atc_20121024_1hz/robot_paths.csv");
    let out_text = out.display().to_string();
    let mut args = vec![
        "activity",
        "extract",
        "--tracks",
        &tracks,
        "--map",
        &map,
        "--paths",
        &paths,
        "--t0",
        "1351036800",
        "--bins",
        "1",
        "-o",
        &out_text,
        "--json",
    ];
    args.extend_from_slice(extra);
    let summary = json(&chronomap(&args));
    (
        summary,
        read_rate_grid(&out).expect("the output reads back"),
    )
}

#[test]
fn one_atc_hour_seen_by_the_three_patrol_robots() {
    let (summary, grid) = ten_oclock("ten.csv", &[]);
    assert_eq!(summary["kind"], "training data");
    assert_eq!(summary["bins"], serde_json::json!([1]));
    assert_eq!(summary["samples"], SAMPLES);
    assert_eq!(summary["cells"], SAMPLES);
    assert_eq!(summary["total_count"], COUNT);
    assert_eq!(summary["total_duration_s"], DURATION);
    assert_eq!(summary["robots"].as_array().unwrap().len(), 3);
    assert_eq!(summary["robots"][0]["name"], "corridor");

    // Every row: t = 1, 0 < Δ ≤ 3600 whole seconds, y = c / Δ per hour.
    let (counts, durations) = (grid.counts.unwrap(), grid.durations.unwrap());
    assert_eq!(grid.samples.len(), SAMPLES);
    for i in 0..grid.samples.len() {
        let (c, d, y) = (counts[i], durations[i], grid.samples.y()[i]);
        assert_eq!(grid.samples.t()[i], 1.0);
        assert!(d > 0.0 && d <= 3600.0 && d.fract() == 0.0, "{d}");
        assert!(
            (y - c * 3600.0 / d).abs() <= 1e-9 * y.max(1.0),
            "{y} {c} {d}"
        );
    }
    assert_eq!(counts.iter().sum::<f64>(), COUNT as f64);
    // The cells lie on the 0.5 m lattice of the bundled grid (centres at .25 / .75).
    for x in grid.samples.x() {
        for v in x {
            assert_eq!((v * 4.0).rem_euclid(2.0), 1.0, "{x:?}");
        }
    }
}

#[test]
fn ground_truth_counts_the_seen_cells_for_the_whole_hour() {
    let (summary, grid) = ten_oclock("ten-truth.csv", &["--ground-truth", "--zero-rate", "1e-6"]);
    assert_eq!(summary["kind"], "ground truth");
    assert_eq!(summary["samples"], SAMPLES);
    assert_eq!(summary["total_duration_s"], SAMPLES as f64 * 3600.0);
    assert_eq!(summary["total_count"], TRUTH_COUNT);
    let counts = grid.counts.unwrap();
    let zero = counts.iter().filter(|&&c| c == 0.0).count();
    assert_eq!(zero, TRUTH_ZERO);
    assert_eq!(
        grid.samples.y().iter().filter(|&&y| y == 1e-6).count(),
        zero
    );
}

#[test]
fn bad_robot_paths_name_the_file_and_line() {
    let map = repo("data/atc_copa_map_grid/atc_map.yaml");
    let tracks = repo("data/atc_20121024_1hz/atc-1024-9_train.csv.xz");
    let out = scratch("never.csv").display().to_string();
    let run = |paths: &str, extra: &[&str]| {
        let file = scratch("paths.csv");
        std::fs::write(&file, paths).unwrap();
        let file = file.display().to_string();
        let mut args = vec![
            "activity", "extract", "--tracks", &tracks, "--map", &map, "--paths", &file, "-o", &out,
        ];
        args.extend_from_slice(extra);
        error(&chronomap(&args))
    };
    // Through the pillar at (16.5, -8): an obstacle of the map.
    let err = run(
        "path,x,y,stop_s\nok,6.5,0.5,10\nwall,16,-10.25,0\nwall,16.8,-7.5,0\n",
        &[],
    );
    assert_mentions(
        &err,
        &["paths.csv:3: path \"wall\" passes (", "an obstacle of"],
    );
    let err = run("path,x,y,stop_s\nfar,500,0,10\n", &[]);
    assert_mentions(&err, &["paths.csv:2: path \"far\"", "outside the map"]);
    let err = run("path,x,y,stop_s\nok,6.5,0.5,-1\n", &[]);
    assert!(
        err.contains("paths.csv:2: stop_s: \"-1\" is negative"),
        "{err}"
    );
    let err = run("path,x,y,stop_s\nok,6.5,0.5,10\n", &["--robot", "nobody"]);
    assert!(err.contains("no path named \"nobody\""), "{err}");
    assert!(!std::path::Path::new(&out).exists());
}
