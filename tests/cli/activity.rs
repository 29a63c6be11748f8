//! `chronomap activity eval` end to end on the bundled ATC grid of CoPA-Map (dissertation
//! chapter 4): the measured scores of the baselines on a chronological split (8 days of
//! training, 2 of test), the JSON shape of issue 8, and errors naming file, line and column.

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common::{chronomap, close, data, error, json, stdout, tmp, write};
use serde_json::Value;

fn atc() -> String {
    data("atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz")
}

/// A file of the module's tests (`target/tmp/activity_cli/NAME`).
fn scratch(name: &str, text: &str) -> PathBuf {
    write(&tmp("activity_cli"), name, text)
}

/// `chronomap activity eval ARGS`.
fn eval(args: &[&str]) -> Output {
    chronomap(&[&["activity", "eval"], args].concat())
}

/// The JSON of `activity eval ARGS --json` on the files `train` and `test`.
fn eval_files(train: &Path, test: &Path, args: &[&str]) -> Value {
    let files = [
        "--train",
        train.to_str().unwrap(),
        "--test",
        test.to_str().unwrap(),
    ];
    json(&eval(&[&files, args, &["--json"]].concat()))
}

/// `activity eval` of the bundled ATC grid split at t = 96 with `flags` (split at white
/// space): the stdout of a run that must succeed.
fn atc_eval(flags: &str) -> String {
    let train = atc();
    let mut args = vec!["--train", &train, "--split-at", "96"];
    args.extend(flags.split_whitespace());
    stdout(&eval(&args))
}

/// The error of `activity eval --train TRAIN ARGS`, which must fail.
fn eval_error(train: &str, args: &[&str]) -> String {
    error(&eval(&[&["--train", train], args].concat()))
}

#[test]
fn atc_split_after_eight_days_json_has_the_issue_shape_and_measured_scores() {
    // A tiny GP-Hom (20 inducing points, 20 iterations): its scores are checked at the
    // settings of `copa_map_beats_every_baseline_on_the_later_days`.
    let text = atc_eval("--inducing 20 --iterations 20 --model auto --json");
    let json: Value = serde_json::from_str(&text).expect("one JSON object");
    assert_eq!(json["train"]["samples"], 61_131);
    assert_eq!(json["test"]["samples"], 15_325);
    assert_eq!(json["train"]["cells"], 652);
    close(&json["test"]["mean_rate"], 40.4974, 1e-4);
    let b = &json["baselines"];
    // Measured: on the last two days every baseline is poor (NRMSE > 2); the temporal
    // Fr-AAM is best, the per-cell mean beats the global mean only slightly.
    // (baseline, NRMSE, chi2, chi2 tolerance); every NRMSE within 1e-4.
    let measured = [
        ("global_mean", 2.18116, 476_455.5, 1.0),
        ("ml", 2.15099, 346_923.2, 1.0),
        ("fr_aam", 2.10227, 268_615.3, 1.0),
        // The log-scale per-cell mean follows the typical hour, not the glimpses that
        // dominate robot-sampled test rates: here it is no better than the global mean.
        ("ml_log", 2.18193, 305_379.4, 1.0),
        // WHyTe (periods 12, 6 and 4 h, 32 components, chosen on the training times
        // t >= 77): between Fr-AAM and ML in NRMSE, but its smooth rates miss the busiest
        // cells, so its chi2 is nearly the global mean's. EM runs deterministically; the
        // tolerances leave room for another libm's last bits.
        ("whyte", 2.11119, 409_188.1, 50.0),
        // Log-AM (ln(1 + y) = level per cell + profile of the day + interaction shrunk by
        // κ = 10, a memory of τ = 1 day, both chosen on t >= 77): the least NRMSE and chi2 of
        // every model here (CoPA-Map with its defaults: 2.0284 / 217,628). Backfitting and sums
        // in a fixed order: deterministic up to libm.
        ("log_additive", 2.02578, 190_878.4, 1.0),
    ];
    for (name, nrmse, chi2, chi2_tolerance) in measured {
        close(&b[name]["nrmse"], nrmse, 1e-4);
        close(&b[name]["chi2"], chi2, chi2_tolerance);
    }
    for baseline in [
        "global_mean",
        "ml",
        "ml_log",
        "fr_aam",
        "gp_hom",
        "whyte",
        "log_additive",
    ] {
        assert!(b[baseline]["nrmse"].is_f64(), "{baseline}: {text}");
        assert!(b[baseline]["train_seconds"].as_f64().unwrap() >= 0.0);
    }
    // `auto` chooses on the training data alone (t >= 77 held out): Log-AM wins there, ahead
    // of the global mean, so the top-level scores are Log-AM's.
    assert_eq!(json["model"], "log_additive");
    close(&json["selected_by"]["holdout_from_t"], 77.0, 0.0);
    let held_out = &json["selected_by"]["scores"];
    for (name, nrmse) in [
        ("global_mean", 1.81434),
        ("fr_aam", 1.95707),
        ("ml_log", 1.88103),
        ("log_additive", 1.76084),
    ] {
        close(&held_out[name]["nrmse"], nrmse, 1e-4);
    }
    // GP-Hom and WHyTe are too slow to be tried by `auto`.
    assert!(json["selected_by"]["scores"].get("gp_hom").is_none());
    assert!(json["selected_by"]["scores"].get("whyte").is_none());
    assert_eq!(json["nrmse"], b["log_additive"]["nrmse"]);
    assert_eq!(json["chi2"], b["log_additive"]["chi2"]);
    assert!(json["train_seconds"].as_f64().unwrap() >= 0.0);
    // Log-AM's 90 % intervals of one observation (the log-normal of its σ) on the last two
    // days' glimpses: measured 86.6 % of the rates inside, more below than above
    // (docs/accuracy.md). Its intervals of whole hours leave the glimpses' noise out, so they
    // hold fewer of these glimpses (75.4 %) in half the width.
    let observation = &json["observation_interval"];
    close(&observation["nominal"], 0.9, 0.0);
    close(&observation["coverage"], 0.866, 0.005);
    assert!(observation["below"].as_u64().unwrap() > observation["above"].as_u64().unwrap());
    let hours = &json["interval"];
    close(&hours["coverage"], 0.754, 0.005);
    assert!(hours["mean_width"].as_f64() < observation["mean_width"].as_f64());
}

#[test]
fn chosen_model_gives_the_top_level_scores_and_the_table_names_it() {
    let text = atc_eval("--model fr-aam --inducing 20 --iterations 20");
    assert!(text.contains("61131 samples (t < 96), 652 cells"), "{text}");
    assert!(text.contains("fr_aam        2.1023  268615.3"), "{text}");
    assert!(text.contains("\ngp_hom  "), "{text}");
    assert!(
        text.contains("model: fr_aam (chosen by --model); NRMSE 2.1023"),
        "{text}"
    );
}

#[test]
fn train_and_test_files_are_scored_as_given() {
    let train = scratch(
        "train.csv",
        "x1,x2,t,y\n0.25,0.25,0,10\n0.25,0.25,1,10\n0.75,0.25,0,1e-06\n0.75,0.25,1,2\n",
    );
    let test = scratch("test.csv", "x1,x2,t,y\n0.25,0.25,2,10\n0.75,0.25,2,1\n");
    let json = eval_files(&train, &test, &["--model", "ml"]);
    // ML predicts 10 and ~1: errors 0 and ~0; mean truth 5.5.
    close(&json["nrmse"], 0.0, 1e-6);
    // Global mean 5.5: errors 4.5 and -4.5, NRMSE sqrt(2 · 4.5² / (5.5² · 2)) = 4.5 / 5.5.
    close(&json["baselines"]["global_mean"]["nrmse"], 4.5 / 5.5, 1e-6);
    // chi2: 4.5² / 15.5 + 4.5² / 6.5
    close(
        &json["baselines"]["global_mean"]["chi2"],
        4.5 * 4.5 / 15.5 + 4.5 * 4.5 / 6.5,
        1e-6,
    );
    assert!(json["split_at"].is_null());
    // Without --model the top-level scores are Log-AM's, the table's fit.
    let json = eval_files(&train, &test, &[]);
    assert_eq!(json["model"], "log_additive");
    assert_eq!(json["nrmse"], json["baselines"]["log_additive"]["nrmse"]);
    // GP-Hom on four samples uses four inducing points; as the top-level model it is the
    // table's fit, not a second one.
    let json = eval_files(&train, &test, &["--model", "gp-hom", "--iterations", "50"]);
    assert_eq!(json["model"], "gp_hom");
    assert!(
        json["interval"].is_null(),
        "GP-Hom has no predictive intervals here"
    );
    assert_eq!(json["nrmse"], json["baselines"]["gp_hom"]["nrmse"]);
    assert_eq!(json["chi2"], json["baselines"]["gp_hom"]["chi2"]);
    // Measured 0.1979: the space-time GP shares the two cells' rates a little, so it lies
    // between the exact per-cell mean and the global mean (4.5 / 5.5).
    close(&json["nrmse"], 0.1979, 0.005);
    // WHyTe fits four samples too, and as the top-level model it is the table's fit.
    let json = eval_files(&train, &test, &["--model", "whyte"]);
    assert_eq!(json["model"], "whyte");
    assert_eq!(json["nrmse"], json["baselines"]["whyte"]["nrmse"]);
    assert!(json["nrmse"].as_f64().unwrap() < 4.5 / 5.5, "{json}");
}

#[test]
fn bad_input_is_an_error_naming_file_line_and_column() {
    // (training file, its text, the start of the message).
    let bad_training = [
        (
            "negative.csv",
            "x1,x2,t,y\n0,0,0,1\n0,0,1,-3\n",
            ":3: y: \"-3\" is negative",
        ),
        (
            "header.csv",
            "x,y,t,rate\n0,0,0,1\n",
            ":1: expected the header `x1,x2,t,y`",
        ),
        ("short.csv", "x1,x2,t,y\n0,0,0,1\n0,0\n", ":3: t: missing"),
    ];
    for (name, text, message) in bad_training {
        let train = scratch(name, text);
        let err = eval_error(train.to_str().unwrap(), &["--split-at", "1"]);
        assert!(err.contains(&format!("{name}{message}")), "{err}");
    }
    let nan = scratch("nan.csv", "x1,x2,t,y\n0,NaN,0,1\n");
    let err = eval_error(&atc(), &["--test", nan.to_str().unwrap()]);
    assert!(
        err.contains("nan.csv:2: x2: \"NaN\" is not a finite number"),
        "{err}"
    );
    // A split that leaves nothing to test on.
    let err = eval_error(&atc(), &["--split-at", "500"]);
    assert!(err.contains("no sample has t >= 500"), "{err}");
    // A missing file names itself.
    let err = eval_error("no-such-grid.csv", &["--split-at", "1"]);
    assert!(err.contains("no-such-grid.csv"), "{err}");
}

#[test]
// One of the two slowest tests (about 45 s of CPU each: CoPA-Map and GP-Hom are trained in a
// debug build), kept out of the default run so that CI stays under 25 minutes; run it with
// `cargo test --workspace -- --include-ignored`.
#[ignore = "slow: trains CoPA-Map and GP-Hom (cargo test -- --include-ignored)"]
fn copa_map_beats_every_baseline_on_the_later_days() {
    // A small CoPA-Map and GP-Hom (100 inducing points, 150 iterations) to keep the test
    // short; with the defaults (200, 300) CoPA-Map reaches NRMSE 2.028 in about 45 s of a
    // release build, GP-Hom 2.317.
    let text = atc_eval("--model copa --inducing 100 --iterations 150 --json");
    let json: Value = serde_json::from_str(&text).expect("one JSON object");
    assert_eq!(json["model"], "copa");
    assert_eq!(json["copa_init"]["mode"], "day");
    let nrmse = json["nrmse"].as_f64().unwrap();
    let chi2 = json["chi2"].as_f64().unwrap();
    // Measured: NRMSE 2.0415, chi2 239,119 (Fr-AAM 2.1023 / 268,615, WHyTe 2.1112 / 409,188,
    // ML 2.1510, global 2.1812, GP-Hom 2.2215 / 292,616).
    assert!((2.0..2.07).contains(&nrmse), "{nrmse}");
    // GP-Hom: the Poisson likelihood takes the rare huge rates of briefly observed cells at
    // face value (a rate is weighed like a count), so it does worse than even the global mean
    // in squared error; its training is deterministic, but a CPU whose vector units sum in
    // another order may end elsewhere, hence the tolerances.
    let gp_hom = &json["baselines"]["gp_hom"];
    close(&gp_hom["nrmse"], 2.2215, 0.01);
    close(&gp_hom["chi2"], 292_616.2, 3000.0);
    for baseline in ["global_mean", "ml", "ml_log", "fr_aam", "gp_hom", "whyte"] {
        let b = &json["baselines"][baseline];
        assert!(nrmse < b["nrmse"].as_f64().unwrap(), "{baseline}: {text}");
        assert!(chi2 < b["chi2"].as_f64().unwrap(), "{baseline}: {text}");
    }
    // Log-AM, a median of ln(1 + y) fitted in well under a second, is ahead of this CoPA-Map
    // in both (2.0258 / 190,878) and of the default one (2.0284 / 217,628) too.
    let log_am = &json["baselines"]["log_additive"];
    assert!(log_am["nrmse"].as_f64().unwrap() < nrmse - 0.01, "{text}");
    assert!(log_am["chi2"].as_f64().unwrap() < chi2 - 40_000.0, "{text}");
    assert!(json["train_seconds"].as_f64().unwrap() > 0.0);
}

#[test]
fn test_and_split_at_together_or_neither_are_usage_errors() {
    use crate::common::usage_error;
    let train = scratch(
        "usage_train.csv",
        "x1,x2,t,y\n0.25,0.25,0,10\n0.25,0.25,1,10\n",
    );
    let train = train.to_str().unwrap();
    let err = usage_error(&chronomap(&[
        "activity",
        "eval",
        "--train",
        train,
        "--test",
        train,
        "--split-at",
        "1",
    ]));
    assert!(err.contains("--split-at"), "{err}");
    let err = usage_error(&chronomap(&["activity", "eval", "--train", train]));
    assert!(
        err.contains("--split-at") || err.contains("--test"),
        "{err}"
    );
    // A model that cannot be trained is a failure at run time.
    let err = error(&chronomap(&[
        "activity",
        "eval",
        "--train",
        train,
        "--split-at",
        "1",
        "--model",
        "copa",
    ]));
    assert!(err.contains("CoPA-Map"), "{err}");
    // Only Log-AM and CoPA-Map have predictive intervals to plot: asked of another model,
    // before any fit.
    let png = scratch("usage_plot.png", "");
    let err = usage_error(&chronomap(&[
        "activity",
        "eval",
        "--train",
        train,
        "--split-at",
        "1",
        "--model",
        "ml",
        "--plot",
        png.to_str().unwrap(),
    ]));
    assert!(
        err.contains("--plot") && err.contains("log-additive"),
        "{err}"
    );
}
