//! A held-out day for CoPA-Map: `chronomap activity truth` turns the bundled ATC tracks of
//! 2012-10-24 into the ground truth of [Stüde 2024] §4.3.2 (distinct people per cell and hour, over
//! whole hours) in the cells of the bundled training grid, and `chronomap activity eval` scores
//! the models trained on the grid's ten days against it.

use crate::common;

use std::process::Output;

use common::{chronomap, close, repo, stdout, tmp};
use serde_json::Value;

/// The bundled ATC tracks of 2012-10-24 at `hour`.
fn tracks(hour: u32) -> String {
    repo(&format!(
        "data/atc_20121024_1hz/atc-1024-{hour}_train.csv.xz"
    ))
}

/// `chronomap activity truth` of the track files `tracks` in the cells of the bundled training
/// grid from `t0`, with `flags`.
fn truth(tracks: &[&str], t0: &str, flags: &[&str]) -> Output {
    let grid = repo("data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz");
    let cells = ["--cells", &grid, "--t0", t0];
    chronomap(
        &[
            &["activity", "truth", "--tracks"][..],
            tracks,
            &cells,
            flags,
        ]
        .concat(),
    )
}

/// The ground truth of 2012-10-24 (every bundled hour, whole bins 1, 2, 4 … 10 at t = 120 +
/// bin) written to `dir/truth.csv`: the file's path and `activity truth`'s stdout.
fn day_truth(dir: &str) -> (String, String) {
    let truth_arg = tmp(dir).join("truth.csv").display().to_string();
    let hours = [9, 10, 11, 13, 14, 15, 16, 17, 18, 19, 20];
    let tracks: Vec<String> = hours.into_iter().map(tracks).collect();
    let tracks: Vec<&str> = tracks.iter().map(String::as_str).collect();
    let flags = [
        "--bins",
        "1,2,4,5,6,7,8,9,10",
        "--t-offset",
        "120",
        "-o",
        &truth_arg,
    ];
    let text = stdout(&truth(&tracks, "1351036800", &flags));
    (truth_arg, text)
}

/// `activity eval --json --plot` of `model` trained on the grid and scored on the tracks day's
/// whole-hour counts (GP-Hom, and CoPA-Map if it is the model, with `inducing` points and
/// `iterations`): the report and the picture's path.
fn eval_on_the_day(
    test: &str,
    model: &str,
    (inducing, iterations): (&str, &str),
) -> (Value, std::path::PathBuf) {
    let (truth_arg, _) = day_truth(test);
    let grid = repo("data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz");
    let png = tmp(test).join("intervals.png");
    let png_arg = png.display().to_string();
    let text = stdout(&chronomap(&[
        "activity",
        "eval",
        "--train",
        &grid,
        "--test",
        &truth_arg,
        "--model",
        model,
        "--inducing",
        inducing,
        "--iterations",
        iterations,
        "--json",
        "--plot",
        &png_arg,
    ]));
    (serde_json::from_str(&text).unwrap(), png)
}

/// Log-AM's 90 % intervals of whole hours on the held-out day (proxy (b) of
/// `docs/accuracy.md`): the spread of whole hours is estimated from the glimpses'
/// autocovariance over neighbouring hours, their own noise (the nugget) left out.
#[test]
fn log_am_intervals_of_whole_hours_hold_nine_tenths_of_the_days_counts() {
    // GP-Hom, a baseline of the table, is trained small: only Log-AM is checked here.
    let (v, png) = eval_on_the_day("activity_truth_intervals", "log-additive", ("10", "5"));
    close(&v["nrmse"], 0.66435, 5e-4);
    // Measured: 90.6 % of the day's 5,868 whole-hour counts inside (239 below, 313 above),
    // 72 people per hour wide; the intervals of one glimpse (σ of all residuals) hold 97.7 %
    // at twice the width.
    close(&v["interval"]["coverage"], 0.906, 0.003);
    close(&v["interval"]["mean_width"], 72.19, 0.05);
    close(&v["observation_interval"]["coverage"], 0.977, 0.003);
    close(&v["observation_interval"]["mean_width"], 151.87, 0.05);
    // The curve over nominal coverages (the --plot's data): its 90 % point is the interval
    // above, and the share inside grows with the nominal coverage.
    let curve = v["interval_curve"].as_array().unwrap();
    assert_eq!(curve.len(), 11);
    let at_90 = curve.iter().find(|l| l["nominal"] == 0.9).unwrap();
    assert_eq!(at_90["coverage"], v["interval"]["coverage"]);
    assert_eq!(
        at_90["observation_coverage"],
        v["observation_interval"]["coverage"]
    );
    let shares: Vec<f64> = curve
        .iter()
        .map(|l| l["coverage"].as_f64().unwrap())
        .collect();
    assert!(shares.windows(2).all(|w| w[0] <= w[1]), "{shares:?}");
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
}

/// CoPA-Map's intervals on the held-out day (proxy (b) of `docs/accuracy.md`), with a small
/// model (50 inducing points, 100 iterations; the defaults take over a minute here with GP-Hom
/// trained alike). Its intervals of whole hours are the latent rate function's: they know how
/// uncertain the function is, not how much one day's hour swings about it, and the function
/// follows the robot's glimpse-laden rates, above the typical whole hour — so they hold far
/// fewer than 90 % of the day's counts, nearly all misses below. The intervals of one glimpse
/// add the fitted noise and hold nearly all.
#[test]
fn copa_map_intervals_of_whole_hours_hold_less_than_the_nominal_share_of_the_days_counts() {
    let (v, png) = eval_on_the_day("activity_truth_copa_intervals", "copa", ("50", "100"));
    assert_eq!(v["model"], "copa");
    close(&v["nrmse"], 1.17489, 5e-4);
    // Measured: 61.0 % of the day's 5,868 whole-hour counts inside the 90 % intervals (2,234
    // below, 53 above), 37.5 people per hour wide; the intervals of one glimpse hold all of
    // them at 158 wide. (The default model, 200 inducing points and 300 iterations, is more
    // certain of its function: 33.2 % inside, 3,413 below and 504 above, 10.2 wide; one
    // glimpse's 99.7 %, 106 wide.)
    let hours = &v["interval"];
    close(&hours["coverage"], 0.610, 0.01);
    close(&hours["mean_width"], 37.52, 0.5);
    let (below, above) = (
        hours["below"].as_u64().unwrap(),
        hours["above"].as_u64().unwrap(),
    );
    assert!(below > 10 * above, "{below} below, {above} above");
    let glimpse = &v["observation_interval"];
    assert!(glimpse["coverage"].as_f64().unwrap() >= 0.99, "{glimpse}");
    close(&glimpse["mean_width"], 157.98, 1.0);
    // At every nominal level the whole hours' intervals hold fewer than nominal, the glimpses'
    // more.
    let curve = v["interval_curve"].as_array().unwrap();
    assert_eq!(curve.len(), 11);
    for level in curve {
        let nominal = level["nominal"].as_f64().unwrap();
        assert!(level["coverage"].as_f64().unwrap() < nominal, "{level}");
        assert!(
            level["observation_coverage"].as_f64().unwrap() > nominal,
            "{level}"
        );
    }
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
}

#[test]
// One of the two slowest tests (about 45 s of CPU each: CoPA-Map and GP-Hom are trained in a
// debug build), kept out of the default run so that CI stays under 25 minutes; run it with
// `cargo test --workspace -- --include-ignored`.
#[ignore = "slow: trains CoPA-Map and GP-Hom (cargo test -- --include-ignored)"]
fn the_atc_day_is_a_test_day_on_which_copa_map_beats_the_baselines() {
    let (truth_arg, text) = day_truth("activity_truth");
    let truth_file = std::path::PathBuf::from(&truth_arg);
    let grid = repo("data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz");
    assert!(
        text.contains("5868 samples (652 cells × 9 bins) from 554969 detections; mean 21.805"),
        "{text}"
    );
    let written = std::fs::read_to_string(&truth_file).unwrap();
    assert!(
        written.starts_with("x1,x2,t,y\n3.75,-1.25,121,3\n"),
        "{written:.60}"
    );

    let text = stdout(&chronomap(&[
        "activity",
        "eval",
        "--train",
        &grid,
        "--test",
        &truth_arg,
        "--model",
        "copa",
        "--inducing",
        "100",
        "--iterations",
        "150",
        "--json",
    ]));
    let v: Value = serde_json::from_str(&text).unwrap();
    // Measured: the global mean scores 1.385 here (the original's kept-back test days: 1.36),
    // the per-cell mean 2.348 (there: 1.98), Fr-AAM 2.790.
    close(&v["baselines"]["global_mean"]["nrmse"], 1.3850, 5e-4);
    close(&v["baselines"]["ml"]["nrmse"], 2.3479, 5e-4);
    close(&v["baselines"]["fr_aam"]["nrmse"], 2.7897, 5e-4);
    close(&v["test"]["samples"], 5868.0, 0.0);
    // The per-cell mean of ln(1 + rate), constant over time, is the best model of this day:
    // whole-hour counts follow the typical hour of a cell, not the glimpses of the robot's
    // rates, and the day's profile is flatter than the training days'.
    close(&v["baselines"]["ml_log"]["nrmse"], 0.62857, 5e-4);
    close(&v["baselines"]["ml_log"]["chi2"], 19_499.6, 1.0);
    // CoPA-Map (a small model: 100 inducing points, 150 iterations) beats the global mean,
    // ML, Fr-AAM, GP-Hom and WHyTe, but not ML-log.
    close(&v["nrmse"], 1.1280, 2e-3);
    close(&v["chi2"], 52152.5, 60.0);
    close(&v["baselines"]["gp_hom"]["nrmse"], 2.7909, 0.01);
    // WHyTe (the day's period, 32 components) lies between the global mean and ML in NRMSE;
    // its smooth rates give the largest chi2 of all models.
    close(&v["baselines"]["whyte"]["nrmse"], 1.69666, 5e-4);
    close(&v["baselines"]["whyte"]["chi2"], 123_003.1, 50.0);
    // Log-AM (ln(1 + y) with the training days' rhythm, κ = 10 chosen on t >= 96): far ahead
    // of CoPA-Map, near ML-log in NRMSE and below it in chi2.
    close(&v["baselines"]["log_additive"]["nrmse"], 0.66435, 5e-4);
    close(&v["baselines"]["log_additive"]["chi2"], 18_762.2, 1.0);
    for baseline in ["global_mean", "ml", "fr_aam", "gp_hom", "whyte"] {
        assert!(v["nrmse"].as_f64() < v["baselines"][baseline]["nrmse"].as_f64());
    }
}

#[test]
fn truth_prints_its_summary_as_json_and_takes_comma_separated_tracks() {
    let file = tmp("activity_truth_json").join("truth.csv");
    let file = file.display().to_string();
    let tracks = [10, 11].map(tracks).join(",");
    let text = stdout(&truth(
        &[&tracks],
        "2012-10-24T09:00+09:00",
        &[
            "--bins",
            "1",
            "--bins",
            "2",
            "--t-offset",
            "120",
            "-o",
            &file,
            "--json",
        ],
    ));
    let v: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["samples"], 1304);
    assert_eq!(v["cells"], 652);
    assert_eq!(v["bins"], serde_json::json!([1, 2]));
    // The file holds what the summary says.
    let written = chronomap_io::read_rate_samples(&file).unwrap();
    assert_eq!(written.len(), 1304);
    assert_eq!(written.t()[0], 121.0);
    close(&v["mean_rate_per_hour"], written.mean_rate(), 1e-12);
    // A cell size the grid's cells are not aligned to names the file and the flag.
    let err = common::error(&truth(
        &[&tracks],
        "1351036800",
        &["--bins", "1", "--cell", "0.3", "-o", &file],
    ));
    assert!(
        err.contains("grid_atc_50cm_60min_train_xy.csv.xz: cell centre"),
        "{err}"
    );
    assert!(err.contains("(--cell)"), "{err}");
}
