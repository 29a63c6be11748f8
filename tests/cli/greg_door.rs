//! The greg door dataset (Lincoln, 2016): chronomap against the original FreMEn code's
//! published figures, and the model contract on real data.

use chronomap_core::TimeSeries;
use chronomap_core::conformance::check_temporal_model;
use chronomap_core::{
    FremenModel, HistogramModel, MarkovModel, MeanModel, PergamModel, PersistenceModel,
    TemporalModel,
};
use chronomap_io::{decode_any_model, encode_model};
use chronomap_models::AnyModel;
use chronomap_models::spec::{FitOptions, ModelSpec};

use crate::common::{evaluate_specs_on, greg_tests as tests, greg_training as training};

/// Mean squared error per test week 1..5 of the original FreMEn C++ code (data README).
const ORIGINAL: [(&str, [f64; 5], f64); 3] = [
    ("fremen:0", [0.0899, 0.0772, 0.0835, 0.0849, 0.0681], 0.0807),
    ("fremen:2", [0.0728, 0.0683, 0.0751, 0.0697, 0.0646], 0.0701),
    ("fremen:4", [0.0700, 0.0688, 0.0711, 0.0641, 0.0611], 0.0670),
];

fn evaluate_specs(specs: &str) -> Vec<(String, Vec<f64>, f64)> {
    evaluate_specs_on(specs, &training(), &tests())
        .models
        .iter()
        .map(|m| (m.spec.to_string(), m.mses(), m.mean_mse()))
        .collect()
}

#[test]
fn original_fremen_figures_are_reproduced() {
    let results = evaluate_specs("fremen:0,fremen:2,fremen:4");
    for ((name, weeks, mean), (ref_name, ref_weeks, ref_mean)) in results.iter().zip(ORIGINAL) {
        assert_eq!(name, ref_name);
        assert!(
            (mean - ref_mean).abs() <= 0.0005,
            "{name}: mean {mean:.5} vs original {ref_mean}"
        );
        for (week, (got, want)) in weeks.iter().zip(ref_weeks).enumerate() {
            assert!(
                (got - want).abs() <= 0.0005,
                "{name} week {}: {got:.5} vs original {want}",
                week + 1
            );
        }
    }
}

#[test]
fn automatic_models_reach_the_target_from_training_data_only() {
    for (name, _, mean) in evaluate_specs("fremen:auto,auto") {
        assert!(mean <= 0.0680, "{name}: mean MSE {mean:.5} > 0.0680");
    }
}

/// Issue 23: `auto` (stacking over rolling origins) beats the originals on the test weeks,
/// and the best fixed FreMEn order (16, chosen knowing the answers) on the mean and on every
/// week but the first. Measured: 0.0591 against 0.0634 (fremen:16), 0.0656 (fremen:auto) and
/// 0.0670 (fremen:4); week 1 (Good Friday's) 0.0649 against fremen:16's 0.0641 — the drift
/// candidates (issue 41) follow the door's falling rate, which helps the later weeks most (before
/// them the stack scored 0.0603 and won every week).
#[test]
fn auto_beats_every_fixed_fremen_order_on_the_mean_and_on_weeks_2_to_5() {
    let results = evaluate_specs("auto,fremen:16,fremen:auto,fremen:4");
    let (auto_weeks, auto_mean) = (&results[0].1, results[0].2);
    assert!((auto_mean - 0.0591).abs() <= 0.0005, "{results:?}");
    for (name, weeks, mean) in &results[1..] {
        assert!(auto_mean < *mean, "{name}: {results:?}");
        for (week, (ours, theirs)) in auto_weeks.iter().zip(weeks).enumerate() {
            assert!(
                ours < theirs || (week == 0 && name == "fremen:16"),
                "{name} week {}: {ours} vs {theirs}",
                week + 1
            );
        }
    }
}

#[test]
fn the_original_histogram_figure_is_24_bins_over_a_day() {
    let results = evaluate_specs("hist:24:86400,hist:24");
    assert!((results[0].2 - 0.0703).abs() <= 0.0005, "{:?}", results[0]);
    // Over a week the same 24 bins are 7 h wide and do worse.
    assert!(results[1].2 > results[0].2);
}

#[test]
fn every_model_keeps_the_contract_on_real_data() {
    let train = training();
    // Two weeks keep the chunk-by-one part of the check fast.
    let n = 2 * 7 * 1440;
    let (t, v) = (&train.times[..n], &train.values[..n]);
    check_temporal_model(MeanModel::new, t, v);
    check_temporal_model(|| HistogramModel::weekly(24).unwrap(), t, v);
    check_temporal_model(|| FremenModel::with_order(4), t, v);
    check_temporal_model(|| PersistenceModel::with_order(2), t, v);
    check_temporal_model(MarkovModel::new, t, v);
    check_temporal_model(|| PergamModel::with_components(2).unwrap(), t, v);
}

/// One model of every kind (`fremen` the FreMEn one) fitted on the training data, with the
/// training data and the times of the first test week.
fn fit_every_kind(fremen: &str) -> (TimeSeries, Vec<f64>, Vec<(ModelSpec, AnyModel)>) {
    let train = training();
    let week = tests().swap_remove(0).times;
    let fitted = [
        "mean",
        "hist:24",
        "recent:24:86400:14",
        fremen,
        "persistence:2",
        "stm",
        "pergam:2",
    ]
    .map(|s| {
        let spec: ModelSpec = s.parse().unwrap();
        let model = fit(&spec, &train.times, &train.values);
        (spec, model)
    });
    (train, week, fitted.into())
}

/// `spec` fitted on `times` and `values` with the default options.
fn fit(spec: &ModelSpec, times: &[f64], values: &[f64]) -> AnyModel {
    spec.fit(times, values, &FitOptions::default())
        .unwrap()
        .model
}

/// Whether two models predict the same bits at every time of `times`.
fn same_predictions(a: &AnyModel, b: &AnyModel, times: &[f64]) -> bool {
    let (a, b) = (a.predict_many(times), b.predict_many(times));
    a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits())
}

#[test]
fn daily_chunks_give_the_same_models_as_one_batch() {
    let (train, week, fitted) = fit_every_kind("fremen:4");
    for (spec, batch) in fitted {
        let mut chunked = fit(&spec, &train.times[..1], &train.values[..1]);
        for (t, v) in train.times[1..]
            .chunks(1440)
            .zip(train.values[1..].chunks(1440))
        {
            chunked.observe(t, v).unwrap();
        }
        assert!(
            same_predictions(&batch, &chunked, &week),
            "{spec}: chunked and batch models differ"
        );
    }
}

#[test]
fn every_model_survives_save_and_load_bit_identically() {
    let (_, week, fitted) = fit_every_kind("fremen:auto");
    for (spec, model) in fitted {
        let bytes = encode_model(model.kind(), &model).unwrap();
        let loaded: AnyModel = decode_any_model(&bytes).unwrap();
        assert_eq!(loaded.spec(), model.spec());
        assert!(same_predictions(&model, &loaded, &week), "{spec}");
        // A model whose header names another kind is refused, not misread.
        let other = if model.kind() == "mean" {
            "hist"
        } else {
            "mean"
        };
        let relabelled = encode_model(other, &model).unwrap();
        assert!(
            decode_any_model(&relabelled).is_err(),
            "{spec} relabelled as {other}"
        );
    }
}

/// `chronomap eval --json` of `models` trained on the greg door's training weeks and tested on
/// its five public weeks, with `extra` arguments.
fn greg_eval_json(models: &str, extra: &[&str]) -> serde_json::Value {
    let greg = |name: &str| chronomap_testutil::data(&format!("door_greg_2016/{name}"));
    let tests: Vec<String> = (1..=5)
        .map(|i| {
            format!(
                "{},{}",
                greg(&format!("test_times_{i}.txt.xz")),
                greg(&format!("test_data_{i}.txt.xz"))
            )
        })
        .collect();
    let train = greg("training_data.txt.xz");
    let mut args = vec!["eval", "--train", &train, "--models", models, "--json"];
    for t in &tests {
        args.extend(["--test", t]);
    }
    args.extend(extra);
    chronomap_testutil::json(&crate::common::chronomap(&args))
}

/// Issue 41: the drift candidates of `auto` (the last 7–56 days' mean and histograms,
/// `chronomap_models::stack::RECENT_DAYS`) follow the door's falling rate. Measured on the public
/// weeks pooled (before them: mean forecast 0.1219, ECE 0.0354, Brier 0.0603): mean forecast
/// 0.1099 where the door was open 8.74 % of the time, ECE 0.0267, Brier 0.0591, the windows
/// holding 0.23 of the weight.
#[test]
fn the_drift_candidates_follow_the_doors_falling_rate() {
    let json = greg_eval_json("auto", &[]);
    let auto = &json["models"][0];
    let calibration = &auto["calibration"];
    let number = |v: &serde_json::Value| v.as_f64().unwrap();
    assert!((number(&calibration["base_rate"]) - 0.0874).abs() < 5e-5);
    assert!(
        (number(&calibration["mean_prediction"]) - 0.1099).abs() < 5e-4,
        "{calibration}"
    );
    assert!(
        (number(&calibration["ece"]) - 0.0267).abs() < 5e-4,
        "{calibration}"
    );
    assert!(
        (number(&calibration["brier"]) - 0.0591).abs() < 5e-4,
        "{calibration}"
    );
    let selection = auto["selection"].as_str().unwrap();
    assert!(
        selection.contains("recent:168:604800:1 0.19"),
        "{selection}"
    );
}

/// The bank holidays of England and Wales (`data/calendars/`): Good Friday (week 1) and Easter
/// Monday (week 2), predicted as the Sunday before, make those weeks better and leave the
/// others bit for bit as they were (measured: fremen:4 0.0700 → 0.0650 and 0.0688 → 0.0634).
#[test]
fn days_off_predicted_as_sundays_improve_the_easter_weeks_only() {
    let calendar = chronomap_testutil::data("calendars/england_wales_2016.txt");
    let run = |extra: &[&str]| greg_eval_json("fremen:4", extra);
    let brier = |json: &serde_json::Value| -> Vec<f64> {
        json["models"][0]["tests"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["mse"].as_f64().unwrap())
            .collect()
    };
    let (before, after) = (brier(&run(&[])), brier(&run(&["--days-off", &calendar])));
    assert!(
        (before[0] - 0.0700).abs() < 5e-5 && (after[0] - 0.0650).abs() < 5e-5,
        "{after:?}"
    );
    assert!(
        (before[1] - 0.0688).abs() < 5e-5 && (after[1] - 0.0634).abs() < 5e-5,
        "{after:?}"
    );
    assert_eq!(before[2..], after[2..]);

    // `predict --days-off`: Good Friday 10:00 is predicted as Sunday 20 March 10:00.
    let dir = crate::common::scratch("days_off");
    let model = dir.join("fremen4.cfm");
    let train = chronomap_testutil::data("door_greg_2016/training_data.txt.xz");
    let model = model.to_str().unwrap();
    let fit = ["fit", "--train", &train, "--model", "fremen:4", "-o", model];
    chronomap_testutil::stdout(&crate::common::chronomap(&fit));
    let p = |at: &str, extra: &[&str]| -> f64 {
        let mut args = vec!["predict", model, "--at", at, "--json"];
        args.extend(extra);
        let json = chronomap_testutil::json(&crate::common::chronomap(&args));
        json["predictions"][0]["p"].as_f64().unwrap()
    };
    let friday = p("2016-03-25T10:00Z", &["--days-off", &calendar]);
    assert_eq!(friday, p("2016-03-20T10:00Z", &[]));
    assert!(friday < p("2016-03-25T10:00Z", &[]) - 0.1);

    // `fit --days-off`: the model keeps its calendar, so `predict` needs no flag, and on the
    // test weeks it predicts what `eval --days-off` scored (Brier of week 1 as above).
    let with_calendar = dir.join("fremen4-calendar.cfm");
    let with_calendar = with_calendar.to_str().unwrap();
    let fit = [
        "fit",
        "--train",
        &train,
        "--model",
        "fremen:4",
        "--days-off",
        &calendar,
        "-o",
        with_calendar,
        "--json",
    ];
    let report = chronomap_testutil::json(&crate::common::chronomap(&fit));
    assert_eq!(report["kind"], "calendar");
    assert_eq!(report["days_off"], 8);
    let predict_week = |week: &TimeSeries| -> Vec<f64> {
        let times: Vec<String> = week.times.iter().map(f64::to_string).collect();
        let times = crate::common::write_arg(&dir, "week.txt", times.join("\n"));
        let args = ["predict", with_calendar, "--times", &times, "--json"];
        let json = chronomap_testutil::json(&crate::common::chronomap(&args));
        let rows = json["predictions"].as_array().unwrap();
        rows.iter().map(|r| r["p"].as_f64().unwrap()).collect()
    };
    for (week, expected) in tests().iter().zip(&after).take(2) {
        let p = predict_week(week);
        let mse = p
            .iter()
            .zip(&week.values)
            .map(|(p, v)| (p - v) * (p - v))
            .sum::<f64>()
            / p.len() as f64;
        assert!((mse - expected).abs() < 1e-12, "{mse} vs {expected}");
    }
    let inspect = ["inspect", with_calendar];
    let text = chronomap_testutil::stdout(&crate::common::chronomap(&inspect));
    assert!(
        text.contains("days off: 8 (2016-01-01 .. 2016-12-27), predicted as the Sunday before"),
        "{text}"
    );

    let bad = crate::common::write_arg(&dir, "days.txt", "2016-03-25\n2016-02-30 Leap\n");
    let out = crate::common::chronomap(&[
        "eval",
        "--train",
        &chronomap_testutil::data("door_greg_2016/training_data.txt.xz"),
        "--split-at",
        "2016-03-01",
        "--days-off",
        &bad,
    ]);
    assert_eq!(out.status.code(), Some(1));
    let message = chronomap_testutil::error(&out);
    assert!(
        message.contains(&format!(
            "{bad}:2: date: \"2016-02-30\" is not a date YYYY-MM-DD"
        )),
        "{message}"
    );
}
