//! The `chronomap` binary end to end: the evaluation call acceptance checks make, model
//! files, and clear errors for bad input.

use std::path::Path;

use crate::common::{chronomap, data, scratch, stdout};

fn greg(name: &str) -> String {
    data(&format!("door_greg_2016/{name}"))
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    crate::common::write(dir, name, text).display().to_string()
}

#[test]
fn eval_json_has_the_documented_shape_and_values() {
    let test1 = format!(
        "{},{}",
        greg("test_times_1.txt.xz"),
        greg("test_data_1.txt.xz")
    );
    let test2 = format!(
        "{},{}",
        greg("test_times_2.txt.xz"),
        greg("test_data_2.txt.xz")
    );
    let out = chronomap(&[
        "eval",
        "--train",
        &greg("training_data.txt.xz"),
        "--test",
        &test1,
        "--test",
        &test2,
        "--models",
        "mean,fremen:4",
        "--json",
    ]);
    stdout(&out);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let models = json["models"].as_array().unwrap();
    assert_eq!(models.len(), 2);
    assert_eq!(models[1]["name"], "fremen:4");
    let tests = models[1]["tests"].as_array().unwrap();
    assert_eq!(tests.len(), 2);
    // Original FreMEn code: 0.0700 and 0.0688 on weeks 1 and 2.
    assert!((tests[0]["mse"].as_f64().unwrap() - 0.0700).abs() < 0.0005);
    assert!((tests[1]["mse"].as_f64().unwrap() - 0.0688).abs() < 0.0005);
    assert!(tests[0]["binary_error"].as_f64().unwrap() > 0.0);
    let mean = models[1]["mean_mse"].as_f64().unwrap();
    let expected = (tests[0]["mse"].as_f64().unwrap() + tests[1]["mse"].as_f64().unwrap()) / 2.0;
    assert!((mean - expected).abs() < 1e-15);
}

#[test]
fn eval_prints_tables_and_significance() {
    let mut args = vec![
        "eval".to_string(),
        "--train".into(),
        greg("training_data.txt.xz"),
        "--models".into(),
        "mean,fremen:2,fremen:4".into(),
    ];
    for i in 1..=5 {
        args.push("--test".into());
        args.push(format!(
            "{},{}",
            greg(&format!("test_times_{i}.txt.xz")),
            greg(&format!("test_data_{i}.txt.xz"))
        ));
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = chronomap(&args);
    stdout(&out);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("Brier"), "{text}");
    assert!(text.contains("Binary error"), "{text}");
    assert!(text.contains("fremen:4"), "{text}");
    assert!(text.contains("0.0670"), "{text}");
    assert!(text.contains("better than mean"), "{text}");
}

#[test]
fn bad_input_is_named_by_file_and_line() {
    let dir = scratch("bad_input");
    let good_times = write(&dir, "times.txt", "0\n60\n120\n");
    let good_values = write(&dir, "values.txt", "0\n1\n0\n");
    let cases = [
        ("nan.txt", "0 0\n60 nan\n", "nan.txt:2: value"),
        ("inf.txt", "0 0\ninf 1\n", "inf.txt:2: time"),
        ("negative.txt", "-60 0\n0 1\n", "negative.txt:1: time"),
        (
            "unordered.txt",
            "0 0\n120 1\n60 0\n",
            "unordered.txt:3: time",
        ),
        (
            "text.txt",
            "0 0\n60 open\n",
            "text.txt:2: value: \"open\" is not a number",
        ),
        ("range.txt", "0 0\n60 2\n", "range.txt:2: value"),
        ("empty.txt", "", "empty.txt: no data lines"),
        ("fields.txt", "0 0\n60\n", "fields.txt:2: value: missing"),
    ];
    for (name, content, expected) in cases {
        let train = write(&dir, name, content);
        let test = format!("{good_times},{good_values}");
        let out = chronomap(&[
            "eval", "--train", &train, "--test", &test, "--models", "mean",
        ]);
        assert_eq!(out.status.code(), Some(1), "{name} accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expected), "{name}: {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
    }
    // A test set whose two files differ in length.
    let train = write(&dir, "train.txt", "0 0\n60 1\n");
    let short = write(&dir, "short.txt", "0\n1\n");
    let test = format!("{good_times},{short}");
    let out = chronomap(&["eval", "--train", &train, "--test", &test]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        err.contains("short.txt") && err.contains("times.txt"),
        "{err}"
    );
}

#[test]
fn fit_predict_inspect_and_damaged_model_files() {
    let dir = scratch("model_files");
    let model = dir.join("door.cmm").display().to_string();
    let out = chronomap(&[
        "fit",
        "--train",
        &greg("training_data.txt.xz"),
        "--model",
        "fremen:4",
        "-o",
        &model,
    ]);
    stdout(&out);

    // Monday 2016-03-21 13:00 UTC (door often open) and 03:00 (closed).
    let out = chronomap(&["predict", &model, "--at", "1458565200", "1458529200"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let p: Vec<f64> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split('\t').nth(1).unwrap().parse().unwrap())
        .collect();
    assert_eq!(p.len(), 2);
    assert!(p[0] > 0.2 && p[1] < 0.05, "{p:?}");

    let out = chronomap(&["inspect", &model]);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("fremen:4") && text.contains("24 h"), "{text}");

    let mut bytes = std::fs::read(&model).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0x55;
    std::fs::write(&model, &bytes).unwrap();
    let out = chronomap(&["predict", &model, "--at", "0"]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("checksum") && err.contains("door.cmm"),
        "{err}"
    );
}

#[test]
fn demo_runs_on_bundled_data_and_writes_plots() {
    let dir = scratch("demo");
    let out = chronomap(&["demo", "--out", &dir.display().to_string()]);
    stdout(&out);
    let text = String::from_utf8(out.stdout).unwrap();
    // The original FreMEn figures appear beside ours (fremen:4: 0.0670 both).
    let fremen4 = text
        .lines()
        .find(|l| l.trim_start().starts_with("fremen:4"))
        .unwrap();
    assert_eq!(fremen4.matches("0.0670").count(), 2, "{fremen4}");
    assert!(text.contains("lossless"), "{text}");
    // Section 5: the Witham edge models beat the static rates online (0.0336 vs 0.1297).
    let online = text
        .lines()
        .find(|l| l.trim_start().starts_with("online:"))
        .unwrap();
    assert!(
        online.contains("0.0336") && online.contains("0.1297"),
        "{online}"
    );
    for png in [
        "tom_door_week.png",
        "tom_door_spectrum.png",
        "greg_door_test_week.png",
        "greg_door_spectrum.png",
        "witham_now_or_later.png",
    ] {
        let size = std::fs::metadata(dir.join(png))
            .map(|m| m.len())
            .unwrap_or(0);
        assert!(size > 10_000, "{png}: {size} bytes");
    }
}
