//! scikit-learn cross-check of `chronomap_core::calibration::Calibration`: the reliability
//! diagram's bins (mean forecast, observed frequency, count) must be those of
//! `sklearn.calibration.calibration_curve(strategy="uniform")`, the Brier score that of
//! `sklearn.metrics.brier_score_loss`, and the ECE the count-weighted gap of those bins, to
//! 1e-12 — on a real forecast (FreMEn of order 4 fitted on the greg door's training weeks,
//! predicting the first public test week minute by minute, [Krajník 2017] §VI), on forecasts
//! that lie exactly on the bin edges, and on random forecasts (over-confident in some bins,
//! under-confident in others) with 3 and 25 bins.
//!
//! scikit-learn runs when `CHRONOMAP_SKLEARN_PYTHON` names a Python interpreter that imports
//! `sklearn` (`.ci/run` sets it up); without it the test checks the decomposition only and
//! says how to enable the comparison, unless `CHRONOMAP_REQUIRE_SKLEARN=1`, when it fails.

use chronomap_core::calibration::Calibration;
use chronomap_core::model::TemporalModel;
use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_io::read_test_set;
use chronomap_models::spec::{FitOptions, ModelSpec};
use serde_json::{Value, json};

use crate::common::{greg_training, oracle_python, run_oracle, scratch};

const TOLERANCE: f64 = 1e-12;

/// The cases: name, forecasts, outcomes, bins.
fn cases() -> Vec<(&'static str, Vec<f64>, Vec<f64>, usize)> {
    let train = greg_training();
    let week = read_test_set(
        chronomap_testutil::data_path("door_greg_2016/test_times_1.txt.xz"),
        chronomap_testutil::data_path("door_greg_2016/test_data_1.txt.xz"),
    )
    .unwrap();
    let spec: ModelSpec = "fremen:4".parse().unwrap();
    let fremen = spec
        .fit(&train.times, &train.values, &FitOptions::default())
        .unwrap()
        .model;
    let greg = fremen.predict_many(&week.times);
    // Every edge of 10 bins, 0 and 1, and values just beside edges.
    let edges: Vec<f64> = (0..=10)
        .flat_map(|i| {
            let e = f64::from(i) / 10.0;
            [e, (e - 1e-12).max(0.0), (e + 1e-12).min(1.0)]
        })
        .collect();
    let edge_outcomes = (0..edges.len())
        .map(|i| f64::from(u8::from(i % 3 == 1)))
        .collect();
    let mut rng = Xoshiro256StarStar::seed_from_u64(11);
    let random: Vec<f64> = (0..3000).map(|_| rng.next_f64()).collect();
    let random_outcomes: Vec<f64> = random
        .iter()
        .map(|&p| f64::from(u8::from(rng.next_f64() < (7.0 * p).sin().abs())))
        .collect();
    vec![
        ("greg fremen:4, test week 1", greg, week.values, 10),
        ("on the edges", edges, edge_outcomes, 10),
        ("random, 3 bins", random.clone(), random_outcomes.clone(), 3),
        ("random, 25 bins", random, random_outcomes, 25),
    ]
}

#[test]
fn reliability_bins_brier_and_ece_match_scikit_learn() {
    let cases = cases();
    for (name, p, y, bins) in &cases {
        let c = Calibration::of(p, y, *bins);
        let sum = c.reliability - c.resolution + c.uncertainty + c.within_bin;
        assert!(
            (sum - c.brier).abs() < TOLERANCE,
            "{name}: {sum} vs {}",
            c.brier
        );
        assert_eq!(c.samples, p.len(), "{name}");
    }
    let Some(python) = oracle_python(
        "SKLEARN",
        "sklearn_calibration",
        "scikit-learn",
        "set CHRONOMAP_SKLEARN_PYTHON to a Python with scikit-learn (.ci/run does)",
    ) else {
        return;
    };
    let dir = scratch("sklearn-calibration");
    let input = dir.join("cases.json");
    let document = json!({"cases": cases.iter().map(|(name, p, y, bins)| json!({
        "name": name, "p": p, "y": y, "bins": bins,
    })).collect::<Vec<_>>()});
    std::fs::write(&input, document.to_string()).unwrap();
    let reference = run_oracle(
        &python,
        "CHRONOMAP_SKLEARN_PYTHON",
        "sklearn_calibration.py",
        &[input.as_os_str()],
        "scikit-learn calibration_curve",
    );
    let reference = reference.as_array().unwrap();
    assert_eq!(reference.len(), cases.len());
    let floats = |v: &Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    for ((name, p, y, bins), r) in cases.iter().zip(reference) {
        let c = Calibration::of(p, y, *bins);
        let (truth, predicted, counts) = (
            floats(&r["prob_true"]),
            floats(&r["prob_pred"]),
            floats(&r["counts"]),
        );
        assert_eq!(c.bins.len(), truth.len(), "{name}: non-empty bins");
        let mut ece = 0.0;
        for (k, bin) in c.bins.iter().enumerate() {
            assert_eq!(bin.count as f64, counts[k], "{name}: bin {k} count");
            assert!(
                (bin.observed_frequency - truth[k]).abs() < TOLERANCE,
                "{name}: bin {k} frequency {} vs {}",
                bin.observed_frequency,
                truth[k]
            );
            assert!(
                (bin.mean_prediction - predicted[k]).abs() < TOLERANCE,
                "{name}: bin {k} mean {} vs {}",
                bin.mean_prediction,
                predicted[k]
            );
            ece += counts[k] / c.samples as f64 * (truth[k] - predicted[k]).abs();
        }
        assert!(
            (c.ece - ece).abs() < TOLERANCE,
            "{name}: ECE {} vs {ece}",
            c.ece
        );
        let brier = r["brier"].as_f64().unwrap();
        assert!(
            (c.brier - brier).abs() < TOLERANCE,
            "{name}: Brier {} vs {brier}",
            c.brier
        );
        println!(
            "{name}: {} bins agree, ECE {:.4}, Brier {:.4}",
            c.bins.len(),
            c.ece,
            c.brier
        );
    }
}
