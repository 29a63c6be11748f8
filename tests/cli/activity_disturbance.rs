//! `chronomap activity disturbance` end to end: the service-disturbance benchmark of CoPA-Map
//! ([Stüde 2024] eq. 4.22, §4.3.5) on the bundled ATC grid, map and tracks of 2012-10-24. Two
//! hours of tracks (13:00–15:00 JST) and the cheap models keep it fast; the measured
//! encounters are asserted.

use std::process::Output;

use crate::common::{chronomap, data, stdout, tmp, write};
use serde_json::Value;

/// A file of the module's tests (`target/tmp/activity_disturbance_cli/NAME`).
fn scratch(name: &str, text: &str) -> String {
    let dir = tmp("activity_disturbance_cli");
    write(&dir, name, text).display().to_string()
}

/// The benchmark on the hallway scenario with two hours of tracks, plus `extra` flags.
fn hallway(scenarios: &str, extra: &[&str]) -> Output {
    let (train, t13, t14, map) = (
        data("atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz"),
        data("atc_20121024_1hz/atc-1024-13_train.csv.xz"),
        data("atc_20121024_1hz/atc-1024-14_train.csv.xz"),
        data("atc_copa_map_grid/atc_map.yaml"),
    );
    let mut args = vec![
        "activity",
        "disturbance",
        "--train",
        &train,
        "--tracks",
        &t13,
        &t14,
        "--map",
        &map,
        "--scenarios",
        scenarios,
        "--scenario",
        "hallway",
        "--day-start",
        "2012-10-24T09:00+09:00",
        "--no-copa",
    ];
    args.extend_from_slice(extra);
    chronomap(&args)
}

fn curve(model: &Value) -> Vec<u64> {
    model["curve"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["encounters"].as_u64().unwrap())
        .collect()
}

#[test]
fn atc_hallway_two_hours_measured_encounters() {
    let scenarios = data("atc_20121024_1hz/disturbance_scenarios.csv");
    let out = hallway(&scenarios, &["--json"]);
    stdout(&out);
    let json: Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    // 13:00 .. 14:45 JST, four patrols an hour; the test day is t = 120 + hour after 09:00.
    assert_eq!(json["n_nav"], 8);
    assert_eq!(json["t0"], 120.0);
    assert_eq!(json["starts"][0], 1_351_051_200.0);
    assert_eq!(json["free_cells"], 523);
    let models = json["scenarios"][0]["models"].as_array().unwrap();
    let names: Vec<&str> = models
        .iter()
        .map(|m| m["model"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "occupancy",
            "global_mean",
            "ml",
            "ml_log",
            "fr_aam",
            "whyte",
            "log_additive"
        ]
    );
    let patrols = models[0]["patrols"].as_array().unwrap();
    assert_eq!(patrols[0]["model_t"], 124.0);
    assert_eq!(patrols[7]["model_t"], 125.0);
    // Measured. The shortest route (27.5 m, 55 s) meets 67 detections in 8 patrols; the
    // per-cell models take 20-25 % longer detours through cells that were quiet in training
    // and meet more people on this day (E(1) 81 and 76).
    assert_eq!(curve(&models[0]), [0, 8, 15, 23, 29, 29, 37, 41, 46, 67]);
    assert!((models[0]["mean_path_m"].as_f64().unwrap() - 27.521).abs() < 1e-3);
    assert_eq!(curve(&models[2]), [0, 17, 29, 31, 44, 44, 51, 55, 71, 81]);
    assert_eq!(curve(&models[4])[9], 76);
    // The log-scale per-cell mean, led by the typical hour of each cell rather than by the
    // glimpses, plans routes that meet 31 % fewer people than the shortest one.
    assert_eq!(curve(&models[3]), [0, 6, 16, 18, 24, 24, 30, 34, 36, 46]);
    let ml = models[2]["reduction_vs_occupancy_percent"]
        .as_f64()
        .unwrap();
    assert!((ml - 100.0 * (67.0 - 81.0) / 67.0).abs() < 1e-9, "{ml}");
    // Fr-AAM's costs change with the hour; ML's do not.
    let fr: Vec<f64> = models[4]["patrols"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["cost"].as_f64().unwrap())
        .collect();
    assert!(fr[0] != fr[7]);
    // WHyTe's smooth rates pick routes as short as the shortest one (27.5 m), other ones
    // among the equally short, and meet 73 detections in all (9 % more).
    assert_eq!(curve(&models[5]), [0, 11, 14, 19, 43, 43, 51, 58, 67, 73]);
    // Log-AM follows the training days' rhythm: its cheapest patrols meet the fewest people
    // (5 in the cheapest fifth), but in all it meets 6 % more than the shortest route.
    assert_eq!(curve(&models[6]), [0, 5, 11, 18, 28, 28, 39, 54, 57, 71]);
    assert!((models[5]["mean_path_m"].as_f64().unwrap() - 27.521).abs() < 1e-3);

    // The table says the same.
    let out = hallway(&scenarios, &[]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("n_nav = 8 per scenario"), "{text}");
    assert!(text.contains("-20.9 %"), "{text}");
}

#[test]
fn bad_waypoints_and_scenarios_are_errors_naming_them() {
    // (0.25, 0.25) is outside the training grid; a waypoint on the map's obstacles is blocked.
    let outside = scratch(
        "outside.csv",
        "scenario,waypoint,x,y\nhallway,A,0.25,0.25\nhallway,B,4.25,0.75\n",
    );
    let out = hallway(&outside, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("scenario \"hallway\", waypoint A: waypoint (0.25, 0.25) lies outside"),
        "{err}"
    );
    let missing = scratch(
        "missing.csv",
        "scenario,waypoint,x,y\nshops,A,1,1\nshops,B,2,2\n",
    );
    let out = hallway(&missing, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no scenario \"hallway\""), "{err}");
    let bad = scratch(
        "bad.csv",
        "scenario,waypoint,x,y\nhallway,A,1,1\nhallway,A,2,2\n",
    );
    let out = hallway(&bad, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.csv:3: waypoint: \"A\" appears twice in scenario \"hallway\""),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}
