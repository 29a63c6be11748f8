//! `chronomap events eval` end to end on the bundled Lincoln pedestrian data ([Krajník 2019] §V-D):
//! the measured numbers of both documented splits, the JSON shape the docs describe, and
//! errors naming file, line and field for bad event files.

use crate::common::{chronomap, close, error, scratch, stdout, tmp, write_arg};
use serde_json::Value;

fn data(relative: &str) -> String {
    crate::common::data(&format!("lincoln_pedestrians_2017/{relative}"))
}

fn whytes() -> String {
    data("whytes/wednesday_thursday_days_nights_only_ones.txt.xz")
}

#[test]
fn wednesday_and_thursday_to_friday_json_has_the_documented_shape_and_numbers() {
    let friday = data("raw_days/2017_05_26.txt.xz");
    let text = stdout(&chronomap(&[
        "events",
        "eval",
        "--train",
        &whytes(),
        "--test",
        &friday,
        "--cells",
        "1",
        "--bins",
        "1800",
        "--json",
    ]));
    let json: Value = serde_json::from_str(&text).expect("one JSON object");
    let train = &json["train"];
    assert_eq!(train["events"], 61_489);
    assert_eq!(train["files"].as_array().unwrap().len(), 1);
    assert!(train["before"].is_null());
    // Two days, each one window of observation from its first to its last detection.
    let windows = train["windows"].as_array().unwrap();
    assert_eq!(windows.len(), 2);
    close(&windows[0][0], 1_495_617_883.77, 1e-3);
    close(&windows[1][1], 1_495_733_019.57, 1e-3);
    close(&train["observed_secs"], 55_760.71, 0.01);
    let test = &json["test"];
    assert_eq!(test["events"], 22_449);
    close(&test["first"], 1_495_792_639.39, 1e-3);
    close(&test["last"], 1_495_817_745.59, 1e-3);

    let results = json["results"].as_array().unwrap();
    let models: Vec<&str> = results
        .iter()
        .map(|r| r["model"].as_str().unwrap())
        .collect();
    assert_eq!(models.len(), 5, "{models:?}");
    assert_eq!(models[..2], ["static", "mean"]);
    assert!(models[2].starts_with("hist:") && models[3].starts_with("fremen:"));
    for r in results {
        for key in [
            "cell_m",
            "bin_secs",
            "model",
            "mse",
            "reduction_pct",
            "t",
            "p_value",
            "test_events",
            "cells",
            "predicted_total",
            "grid",
        ] {
            assert!(r.get(key).is_some(), "{key} missing in {r}");
        }
        assert_eq!(r["cell_m"], 1.0);
        assert_eq!(r["bin_secs"], 1800.0);
        // 15 half-hour bins (09:30-17:00 UTC) × 19 × 19 one-metre cells from (-8, -3).
        assert_eq!(r["cells"], 5415);
        assert_eq!(r["test_events"], 22_449);
        assert_eq!(r["grid"]["nt"], 15);
        assert_eq!(
            (r["grid"]["nx"].as_u64(), r["grid"]["ny"].as_u64()),
            (Some(19), Some(19))
        );
        assert_eq!(
            (r["grid"]["x0"].as_f64(), r["grid"]["y0"].as_f64()),
            (Some(-8.0), Some(-3.0))
        );
        let p = r["p_value"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&p));
    }
    // The measured static map and the reductions of the temporal baselines.
    let statics = &results[0];
    close(&statics["mse"], 6901.8609, 5e-5);
    assert_eq!(statics["reduction_pct"], 0.0);
    assert_eq!(statics["p_value"], 1.0);
    close(&statics["predicted_total"], 24_373.29, 0.01);
    close(&results[1]["mse"], 7462.8509, 5e-5);
    assert_eq!(models[2], "hist:24");
    close(&results[2]["reduction_pct"], 45.30, 0.005);
    assert_eq!(models[3], "fremen:4");
    close(&results[3]["reduction_pct"], 24.24, 0.005);
    // Warped Hypertime ([Krajník 2019]): 2 components and the 12-hour periodicity, chosen on the
    // Thursday held out of the training days; better than the static map, worse than the
    // per-cell temporal models here.
    assert_eq!(models[4], "hyt-em:2@12h");
    close(&results[4]["reduction_pct"], 9.646, 0.005);
}

#[test]
fn wednesday_to_thursday_table_with_a_time_split_of_one_file() {
    let w = whytes();
    let text = stdout(&chronomap(&[
        "events",
        "eval",
        "--train",
        &w,
        "--train-before",
        "2017-05-25",
        "--test",
        &w,
        "--test-from",
        "2017-05-25T00:00Z",
        "--cells",
        "1",
        "--bins",
        "1800",
    ]));
    assert!(
        text.contains("29938 detections in 1 window(s) of observation, 8.0 h observed"),
        "{text}"
    );
    assert!(
        text.contains("31551 detections, 2017-05-25 09:53 UTC"),
        "{text}"
    );
    let row = |model: &str| {
        text.lines()
            .find(|l| l.split_whitespace().nth(6) == Some(model))
            .unwrap_or_else(|| panic!("no row for {model}:\n{text}"))
            .split_whitespace()
            .collect::<Vec<_>>()
    };
    // cell, unit, bin, unit, cells, events, model, MSE, reduction, %, p
    let statics = row("static");
    assert_eq!(statics[4..8], ["10912", "31551", "static", "1469.6431"]);
    assert_eq!(row("mean")[7], "1613.4851");
    // One training day: its last quarter is the hold-out, and neither the histogram nor
    // FreMEn finds anything there that beats the static map.
    assert_eq!(row("hist:1")[7], "1469.6431");
    assert_eq!(row("fremen:0")[8], "+0.0");
}

#[test]
fn bad_event_files_name_file_line_and_field() {
    let dir = scratch("events_cli_bad_input");
    let good = write_arg(&dir, "good.txt", "100 0 0\n200 1 1\n");
    let later = write_arg(&dir, "later.txt", "1000 0 0\n1100 1 1\n");
    let cases = [
        (
            "nan.txt",
            "100 0 0\n150 nan 1\n",
            ":2: x: \"nan\" is not a finite number",
        ),
        (
            "backwards.txt",
            "100 0 0\n\n90 1 1\n",
            ":3: time: \"90\" is earlier than the time 100 on line 1 (times must not go backwards)",
        ),
        (
            "missing.txt",
            "100 0 0\n150 1\n",
            ":2: y: missing (expected at least three fields: t x y)",
        ),
        (
            "word.txt",
            "100 0 0\n150 1 one\n",
            ":2: y: \"one\" is not a number",
        ),
    ];
    for (name, text, message) in cases {
        let path = write_arg(&dir, name, text);
        // As training data (second of two files) ...
        let train = format!("{good},{path}");
        let err = error(&chronomap(&[
            "events", "eval", "--train", &train, "--test", &later,
        ]));
        assert!(err.contains(&format!("{path}{message}")), "{err}");
        // ... and as test data.
        let err = error(&chronomap(&[
            "events", "eval", "--train", &good, "--test", &path,
        ]));
        assert!(err.contains(&format!("{path}{message}")), "{err}");
    }
    // A test that does not come after the training data is refused.
    let err = error(&chronomap(&[
        "events", "eval", "--train", &later, "--test", &good,
    ]));
    assert!(
        err.contains("a test must come after its training data"),
        "{err}"
    );
    // Sizes must be positive.
    let out = chronomap(&[
        "events", "eval", "--train", &good, "--test", &later, "--cells", "0",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("\"0\" is not a finite number > 0"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn help_shows_the_documented_commands() {
    let help = stdout(&chronomap(&["events", "eval", "--help"]));
    assert!(help.contains("--train-before 2017-05-25"), "{help}");
    assert!(help.contains("raw_days/2017_05_26.txt.xz --json"), "{help}");
}

/// `chronomap hypertime` on Wednesday and Thursday: the 12-hour periodicity and two
/// components chosen on Thursday, a busy late afternoon (16:30) against a quiet morning, and
/// the maps as a PNG.
#[test]
fn hypertime_finds_the_afternoon_and_draws_it() {
    let dir = tmp("hypertime_cli");
    let png = dir.join("maps.png").display().to_string();
    let text = stdout(&chronomap(&[
        "hypertime",
        "--train",
        &whytes(),
        "--at",
        "2017-05-26T10:00Z,2017-05-26T16:30Z",
        "--plot",
        &png,
        "--json",
    ]));
    let json: Value = serde_json::from_str(&text).expect("one JSON object");
    assert_eq!(json["periods_secs"], serde_json::json!([43200.0]));
    assert_eq!(json["components"], 2);
    let morning = json["maps"][0]["total_per_hour"].as_f64().unwrap();
    let afternoon = json["maps"][1]["total_per_hour"].as_f64().unwrap();
    assert!((morning - 92.0).abs() < 1.0, "{morning}");
    assert!((afternoon - 24_078.0).abs() < 10.0, "{afternoon}");
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    // A value clap cannot take is a usage error (exit code 2).
    let bad = chronomap(&["hypertime", "--train", &whytes(), "--components", "0"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--components"));
}
