//! The `chronomap` binary end to end: the evaluation call acceptance checks make, model
//! files, and clear errors for bad input.

use std::path::Path;
use std::process::Output;

use crate::common::{
    assert_mentions, chronomap, closed_pipe, data, error, scratch, stdout, write_arg,
};

fn greg(name: &str) -> String {
    data(&format!("door_greg_2016/{name}"))
}

/// The JSON of a run that must succeed.
fn json_of(out: &Output) -> serde_json::Value {
    crate::common::json(out)
}

fn tom(name: &str) -> String {
    data(&format!("door_tom_2013/sec/{name}"))
}

/// Test set `i` of a bundled door (`greg` or `tom`) as `--test` takes it: `TIMES,VALUES`.
fn test_set(door: fn(&str) -> String, i: usize) -> String {
    format!(
        "{},{}",
        door(&format!("test_times_{i}.txt.xz")),
        door(&format!("test_data_{i}.txt.xz"))
    )
}

/// `chronomap fit` of `spec` on the greg door's training data into `dir/name`: its path.
fn fit_greg(dir: &Path, name: &str, spec: &str) -> String {
    let model = dir.join(name).display().to_string();
    stdout(&chronomap(&[
        "fit",
        "--train",
        &greg("training_data.txt.xz"),
        "--model",
        spec,
        "-o",
        &model,
    ]));
    model
}

#[test]
fn eval_json_has_the_documented_shape_and_values() {
    let (test1, test2) = (test_set(greg, 1), test_set(greg, 2));
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

/// `eval` measures calibration: per test set and over all test sets, with the Brier score's
/// decomposition (Murphy 1973) adding up to the pooled Brier score, and `--plot` draws the
/// reliability diagram.
#[test]
fn eval_reports_calibration_and_draws_the_reliability_diagram() {
    let dir = scratch("eval-calibration");
    let png = dir.join("reliability.png");
    let (test1, test2) = (test_set(greg, 1), test_set(greg, 2));
    let args = [
        "eval",
        "--train",
        &greg("training_data.txt.xz"),
        "--test",
        &test1,
        "--test",
        &test2,
        "--models",
        "mean,fremen:4",
    ];
    let mut with_plot = args.to_vec();
    with_plot.extend(["--json", "--plot", png.to_str().unwrap()]);
    let json = json_of(&chronomap(&with_plot));
    assert_eq!(&std::fs::read(&png).unwrap()[..8], b"\x89PNG\r\n\x1a\n");
    let fremen = &json["models"][1];
    let c = &fremen["calibration"];
    let number = |v: &serde_json::Value| v.as_f64().unwrap();
    let tests = fremen["tests"].as_array().unwrap();
    // Both weeks have 10,081 minutes: the pooled Brier score is the mean of the two.
    let pooled = (number(&tests[0]["mse"]) + number(&tests[1]["mse"])) / 2.0;
    assert!((number(&c["brier"]) - pooled).abs() < 1e-12);
    let sum = number(&c["reliability"]) - number(&c["resolution"])
        + number(&c["uncertainty"])
        + number(&c["within_bin"]);
    assert!((sum - pooled).abs() < 1e-12, "{sum} vs {pooled}");
    // FreMEn of order 4 over-predicts the door in March: ECE 0.0677 on week 1 (scikit-learn
    // agrees, tests/cli/sklearn_calibration.rs), and its mean forecast is above the rate.
    assert!(
        (number(&tests[0]["ece"]) - 0.0677).abs() < 5e-5,
        "{}",
        tests[0]["ece"]
    );
    assert!(number(&c["mean_prediction"]) > number(&c["base_rate"]) + 0.04);
    let bins = c["bins"].as_array().unwrap();
    let counted: u64 = bins.iter().map(|b| b["count"].as_u64().unwrap()).sum();
    assert_eq!(counted, 2 * 10_081);
    // The training mean is one forecast: one bin, and its ECE is |mean − rate|.
    let mean = &json["models"][0]["calibration"];
    assert_eq!(mean["bins"].as_array().unwrap().len(), 1);
    let gap = (number(&mean["mean_prediction"]) - number(&mean["base_rate"])).abs();
    assert!((number(&mean["ece"]) - gap).abs() < 1e-12);
    let text = stdout(&chronomap(&args));
    assert!(
        text.contains("Expected calibration error of p(t) (10 equal-width bins)"),
        "{text}"
    );
    assert!(text.contains("Calibration over all test sets"), "{text}");
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
        args.push(test_set(greg, i));
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
    let good_times = write_arg(&dir, "times.txt", "0\n60\n120\n");
    let good_values = write_arg(&dir, "values.txt", "0\n1\n0\n");
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
        let train = write_arg(&dir, name, content);
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
    let train = write_arg(&dir, "train.txt", "0 0\n60 1\n");
    let short = write_arg(&dir, "short.txt", "0\n1\n");
    let test = format!("{good_times},{short}");
    let err = error(&chronomap(&["eval", "--train", &train, "--test", &test]));
    assert_mentions(&err, &["short.txt", "times.txt"]);
}

#[test]
fn fit_predict_inspect_and_damaged_model_files() {
    let dir = scratch("model_files");
    let model = fit_greg(&dir, "door.cmm", "fremen:4");

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
    // The same times comma-separated, repeated and in ISO 8601, as JSON: the same numbers.
    for at in [
        &["--at", "1458565200,1458529200"][..],
        &["--at", "2016-03-21T13:00:00Z", "--at", "2016-03-21T03:00Z"],
    ] {
        let mut args = vec!["predict", &model, "--json"];
        args.extend(at);
        let json = json_of(&chronomap(&args));
        assert_eq!(json["spec"], "fremen:4");
        assert_eq!(json["order"], 4);
        let rows = json["predictions"].as_array().unwrap();
        assert_eq!(rows.len(), 2, "{at:?}");
        assert_eq!(rows[0]["time"], 1_458_565_200.0);
        assert_eq!(rows[1]["time"], 1_458_529_200.0);
        for (row, text) in rows.iter().zip(&p) {
            let q = row["p"].as_f64().unwrap();
            assert_eq!(format!("{q:.6}").parse::<f64>().unwrap(), *text, "{at:?}");
            let h = row["entropy_bits"].as_f64().unwrap();
            let bits = |x: f64| if x > 0.0 { -x * x.log2() } else { 0.0 };
            let expected = bits(q) + bits(1.0 - q);
            assert!((h - expected).abs() < 1e-12, "{h} vs {expected}");
        }
    }

    let out = chronomap(&["inspect", &model]);
    let text = String::from_utf8(out.stdout).unwrap();
    assert_mentions(&text, &["fremen:4", "24 h"]);
    // As JSON: the four components in use, the daily one among them, and the mean shown.
    let json = json_of(&chronomap(&["inspect", &model, "--json"]));
    assert_eq!(
        (json["model"].as_str(), json["kind"].as_str()),
        (Some("fremen:4"), Some("fremen"))
    );
    assert_eq!(json["data"]["observations"], 96_480);
    let fremen = &json["details"]["fremen"];
    assert_eq!(
        (fremen["order"].as_u64(), fremen["max_order"].as_u64()),
        (Some(4), Some(84))
    );
    let mean = fremen["mean"].as_f64().unwrap();
    assert!(text.contains(&format!("mean {mean:.6}")), "{text}");
    let components = fremen["components"].as_array().unwrap();
    assert_eq!(components.len(), 4);
    assert!(components.iter().all(|c| c["used"] == true));
    assert!(components.iter().any(|c| c["period_secs"] == 86_400.0));
    let whole = json_of(&chronomap(&["inspect", &model, "--spectrum", "--json"]));
    let spectrum = whole["details"]["fremen"]["components"].as_array().unwrap();
    assert_eq!(spectrum.len(), 84);
    assert_eq!(spectrum.iter().filter(|c| c["used"] == true).count(), 4);

    // `fit --json` says what it fitted and wrote.
    let auto = dir.join("auto.cmm").display().to_string();
    let json = json_of(&chronomap(&[
        "fit",
        "--train",
        &greg("training_data.txt.xz"),
        "--model",
        "fremen:auto",
        "-o",
        &auto,
        "--json",
    ]));
    assert_eq!(json["model"], "fremen:auto");
    assert_eq!(json["train"]["observations"], 96_480);
    assert_eq!(json["bytes"], std::fs::metadata(&auto).unwrap().len());
    let fitted = json["fitted"].as_str().unwrap();
    assert_eq!(format!("fremen:{}", json["order"]), fitted);
    assert!(
        json["selection"]
            .as_str()
            .unwrap()
            .contains("held-back observations")
    );

    let mut bytes = std::fs::read(&model).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0x55;
    std::fs::write(&model, &bytes).unwrap();
    let err = error(&chronomap(&["predict", &model, "--at", "0"]));
    assert_mentions(&err, &["checksum", "door.cmm"]);
}

#[test]
fn demo_runs_on_bundled_data_and_writes_plots() {
    let dir = scratch("demo");
    let out = chronomap(&["demo", "-o", &dir.display().to_string()]);
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
    assert_mentions(online, &["0.0336", "0.1297"]);
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

#[test]
fn anomalies_and_compress_print_the_same_numbers_as_json() {
    let dir = scratch("anomalies_compress");
    let model = fit_greg(&dir, "door.cmm", "fremen:4");
    let test = test_set(greg, 1);
    let args = ["anomalies", &model, "--test", &test, "--confidence", "0.7"];
    let out = chronomap(&args);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let mut with_json = args.to_vec();
    with_json.push("--json");
    let json = json_of(&chronomap(&with_json));
    assert_eq!(json["observations"], 10_081);
    assert_eq!(json["confidence"], 0.7);
    let found = json["anomalies"].as_array().unwrap();
    assert!(!found.is_empty());
    assert!(
        text.starts_with(&format!(
            "{} of 10081 observations are anomalous at confidence 0.7",
            found.len()
        )),
        "{text}"
    );
    // Every anomaly: observed 0 while p >= 0.7, or 1 while p < 0.3; its p is in the table.
    for a in found {
        let (p, observed) = (a["p"].as_f64().unwrap(), a["observed"].as_f64().unwrap());
        assert!(
            (observed == 0.0 && p >= 0.7) || (observed == 1.0 && p < 0.3),
            "{a}"
        );
        assert!(text.contains(&format!("{p:.4}")), "{p}");
    }

    // The door week of the FreMEn paper at one second, order 5.
    let (series, day8) = (test_set(tom, 0), test_set(tom, 1));
    let args = [
        "compress", "--series", &series, "--order", "5", "--test", &day8,
    ];
    let out = chronomap(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let mut with_json = args.to_vec();
    with_json.push("--json");
    let json = json_of(&chronomap(&with_json));
    assert_eq!(json["series"]["samples"], 604_800);
    assert_eq!(json["series"]["changes"], 350);
    assert_eq!(json["order"], 5);
    assert_eq!(json["components"].as_array().unwrap().len(), 5);
    assert_eq!(json["lossless"], true);
    let toggles = json["outlier_toggles"].as_u64().unwrap();
    let eps_e = json["estimation_error"].as_f64().unwrap();
    assert!(
        text.contains(&format!("outlier set O: {toggles} toggles")),
        "{text}"
    );
    assert!(text.contains(&format!("eps_e = {eps_e:.4}")), "{text}");
    let (bytes, lossy) = (
        json["file_bytes"].as_u64().unwrap(),
        json["lossy_file_bytes"].as_u64().unwrap(),
    );
    let ratio = json["ratio_lossless"].as_f64().unwrap();
    assert_eq!(ratio, 604_800.0 / (8.0 * bytes as f64));
    assert!(
        text.contains(&format!("model file: {bytes} bytes, compression ratio 1:{ratio:.0} lossless; without the outlier set {lossy} bytes")),
        "{text}"
    );
    let eps_p = json["test"]["prediction_error"].as_f64().unwrap();
    assert_eq!(json["test"]["samples"], 86_400);
    assert!(
        text.contains(&format!("prediction error eps_p = {eps_p:.4}")),
        "{text}"
    );
}

#[test]
fn a_closed_pipe_ends_the_output_quietly() {
    let dir = scratch("closed_pipe");
    let model = fit_greg(&dir, "door.cmm", "fremen:4");
    // 604,800 predictions (about 15 MB): far more than a pipe holds. Read one line, close.
    let (first, err) = closed_pipe(
        &["predict", &model, "--times", &tom("test_times_0.txt.xz")],
        1,
    );
    assert_eq!(first, "# time\tp\tentropy_bits\n");
    assert!(!err.contains("error"), "{err}");
    // Text and JSON to a pipe that is closed before anything is written.
    for args in [
        &["inspect", &model, "--spectrum"][..],
        &["inspect", &model, "--spectrum", "--json"],
        &[
            "predict",
            &model,
            "--times",
            &tom("test_times_1.txt.xz"),
            "--json",
        ],
    ] {
        let (_, err) = closed_pipe(args, 0);
        assert!(!err.contains("error"), "{args:?}: {err}");
    }
}

#[test]
fn runtime_errors_exit_1_and_usage_errors_exit_2() {
    let dir = scratch("exit_codes");
    let mean = fit_greg(&dir, "mean.cmm", "mean");
    let code = |args: &[&str]| {
        let out = chronomap(args);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        (out.status.code(), err)
    };
    // Run time: files that are missing or bad.
    let missing = dir.join("missing.cmm").display().to_string();
    let (c, err) = code(&["predict", &missing, "--at", "0"]);
    assert_eq!(c, Some(1), "{err}");
    assert!(err.contains("missing.cmm"), "{err}");
    let (c, err) = code(&["grid", "stats", &missing]);
    assert_eq!(c, Some(1), "{err}");
    let (c, _) = code(&["inspect", &greg("training_data.txt.xz")]);
    assert_eq!(c, Some(1));
    // Usage: what clap refuses, and flags that contradict each other or the input.
    for (args, says) in [
        (&["predict", &mean][..], "--times"),
        (&["predict", &mean, "--at", "yesterday"], "ISO 8601"),
        (&["predict", &mean, "--at", "0", "--order", "3"], "--order"),
        (
            &["compress", "--series", &mean, "--order", "many"],
            "--order",
        ),
        (
            &["anomalies", &mean, "--test", &mean, "--confidence", "2"],
            "confidence",
        ),
        (
            &[
                "eval",
                "--train",
                &greg("training_data.txt.xz"),
                "--split-at",
                "2016-02-01,2016-01-20",
            ],
            "is not after",
        ),
        (&["grid", "predict", &mean, "--time", "0"], "--output"),
        (&["hypertime", "--train", &mean, "--plot", "x.png"], "--at"),
        (
            &["features", "--matrix", &mean, "--lines-per-slot", "0"],
            "--lines-per-slot",
        ),
    ] {
        let (c, err) = code(args);
        assert_eq!(c, Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
}

#[test]
fn help_says_which_time_formats_are_accepted() {
    for command in [
        &["predict"][..],
        &["eval"],
        &["grid", "predict"],
        &["grid", "plot"],
        &["hypertime"],
        &["events", "eval"],
    ] {
        let mut args = command.to_vec();
        args.push("--help");
        let out = chronomap(&args);
        assert!(out.status.success());
        // Words as they read, whatever the terminal's width wraps.
        let help = String::from_utf8_lossy(&out.stdout)
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ");
        assert!(
            help.contains("ISO 8601") && help.contains("unix seconds"),
            "{command:?}: {help}"
        );
    }
}
