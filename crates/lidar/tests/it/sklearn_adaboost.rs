//! scikit-learn cross-check of `chronomap_lidar::adaboost`: on the same data our AdaBoost must
//! fit scikit-learn 1.9's `AdaBoostClassifier(estimator=DecisionTreeClassifier(max_depth=1),
//! n_estimators=T)` round by round — the same number of stumps, the same split feature,
//! threshold and leaf classes in every round, estimator weights and errors to 1e-9 — and give
//! the same decision function and probabilities (to 1e-9) and classes on unseen rows. Cases:
//! Gaussian blobs, 41-feature pair-like data with a few informative features, noisy labels
//! that keep boosting busy for all 50 rounds, sample weights, one feature with many repeated
//! values, and a separable case that stops after one perfect stump.
//!
//! scikit-learn trees read `X` as `float32` and visit features in a random order, so the data
//! are rounded to `float32` and continuous (no two features tie).
//!
//! scikit-learn runs when `CHRONOMAP_SKLEARN_PYTHON` names a Python interpreter that imports
//! `sklearn` (the script is `tests/oracle/sklearn_adaboost.py` at the workspace root). Without
//! it the test checks our own fits only and says how to enable the comparison, unless
//! `CHRONOMAP_REQUIRE_SKLEARN=1`, when it fails.

use std::path::PathBuf;
use std::process::Command;

use chronomap_lidar::adaboost::{AdaBoost, AdaBoostParams};
use chronomap_rng::Xoshiro256StarStar;
use serde_json::{Value, json};

const TOLERANCE: f64 = 1e-9;

struct Case {
    name: &'static str,
    x: Vec<Vec<f64>>,
    y: Vec<bool>,
    weights: Option<Vec<f64>>,
    rounds: usize,
    test: Vec<Vec<f64>>,
}

/// A standard normal deviate (Box–Muller), rounded to `float32`.
fn normal(rng: &mut Xoshiro256StarStar) -> f64 {
    let u = rng.next_f64().max(1e-300);
    let v = rng.next_f64();
    f32r((-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos())
}

fn f32r(v: f64) -> f64 {
    v as f32 as f64
}

/// `n` rows of `d` features: class 1 shifted by `shift` on the first `informative` features;
/// labels flipped with probability `noise`.
fn blobs(
    seed: u64,
    n: usize,
    d: usize,
    informative: usize,
    shift: f64,
    noise: f64,
) -> (Vec<Vec<f64>>, Vec<bool>) {
    let mut rng = Xoshiro256StarStar::seed_from_u64(seed);
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for i in 0..n {
        let class = i % 2 == 1;
        let row: Vec<f64> = (0..d)
            .map(|f| {
                let z = normal(&mut rng);
                if class && f < informative {
                    f32r(z + shift)
                } else {
                    z
                }
            })
            .collect();
        x.push(row);
        y.push(if rng.bernoulli(noise) { !class } else { class });
    }
    (x, y)
}

fn cases() -> Vec<Case> {
    let mut out = Vec::new();
    let (x, y) = blobs(1, 200, 5, 2, 1.0, 0.0);
    let (test, _) = blobs(2, 100, 5, 2, 1.0, 0.0);
    out.push(Case {
        name: "blobs",
        x,
        y,
        weights: None,
        rounds: 50,
        test,
    });
    let (x, y) = blobs(3, 300, 41, 6, 0.7, 0.05);
    let (test, _) = blobs(4, 150, 41, 6, 0.7, 0.05);
    out.push(Case {
        name: "pairs41",
        x,
        y,
        weights: None,
        rounds: 50,
        test,
    });
    let (x, y) = blobs(5, 150, 3, 1, 0.3, 0.3);
    let (test, _) = blobs(6, 80, 3, 1, 0.3, 0.3);
    out.push(Case {
        name: "noisy",
        x,
        y,
        weights: None,
        rounds: 50,
        test,
    });
    let (x, y) = blobs(7, 120, 4, 2, 0.8, 0.1);
    let mut rng = Xoshiro256StarStar::seed_from_u64(8);
    // Positive weights only: a zero-weight sample between two values makes the splits on its
    // two sides tie exactly, and scikit-learn breaks such ties by rounding (its running sums
    // go both ways); our unit tests cover zero weights.
    let weights = (0..120).map(|_| rng.uniform(0.5, 3.0)).collect();
    let (test, _) = blobs(9, 60, 4, 2, 0.8, 0.1);
    out.push(Case {
        name: "weighted",
        x,
        y,
        weights: Some(weights),
        rounds: 30,
        test,
    });
    // Many repeated values (quarters) of one feature: splits only between distinct values.
    let (x, y) = blobs(10, 160, 1, 1, 0.6, 0.1);
    let quarter = |rows: Vec<Vec<f64>>| -> Vec<Vec<f64>> {
        rows.into_iter()
            .map(|r| r.iter().map(|v| (v * 4.0).round() / 4.0).collect())
            .collect()
    };
    let (test, _) = blobs(11, 40, 1, 1, 0.6, 0.1);
    out.push(Case {
        name: "ties",
        x: quarter(x),
        y,
        weights: None,
        rounds: 20,
        test: quarter(test),
    });
    let x: Vec<Vec<f64>> = (0..20)
        .map(|i| vec![i as f64, f32r((i * 7 % 20) as f64 * 0.1)])
        .collect();
    let y = (0..20).map(|i| i >= 12).collect();
    out.push(Case {
        name: "separable",
        x,
        y,
        weights: None,
        rounds: 50,
        test: vec![vec![11.0, 0.0], vec![12.5, 0.0]],
    });
    out
}

fn fit(case: &Case) -> AdaBoost {
    AdaBoost::fit(
        &case.x,
        &case.y,
        case.weights.as_deref(),
        &AdaBoostParams {
            rounds: case.rounds,
        },
    )
    .unwrap_or_else(|e| panic!("{}: {e}", case.name))
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= TOLERANCE * (1.0 + a.abs().max(b.abs()))
}

#[test]
fn adaboost_matches_scikit_learn() {
    let cases = cases();
    // Our own fits, checked without the oracle: training accuracy well above chance where the
    // classes differ, one stump for the separable case.
    for case in &cases {
        let m = fit(case);
        m.validate().unwrap();
        let right = case
            .x
            .iter()
            .zip(&case.y)
            .filter(|(x, y)| m.predict(x).unwrap() == **y)
            .count();
        assert!(
            right as f64 > 0.6 * case.x.len() as f64,
            "{}: {right}",
            case.name
        );
    }
    assert_eq!(fit(&cases[5]).stumps.len(), 1);

    let Some(python) = oracle_python() else {
        return;
    };
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("sklearn_adaboost");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("cases.json");
    let json_cases: serde_json::Map<String, Value> = cases
        .iter()
        .map(|c| {
            let y: Vec<u8> = c.y.iter().map(|&v| u8::from(v)).collect();
            (c.name.to_string(), json!({"X": c.x, "y": y, "sample_weight": c.weights, "n_estimators": c.rounds, "X_test": c.test}))
        })
        .collect();
    std::fs::write(&file, serde_json::to_string(&json_cases).unwrap()).unwrap();
    let script =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/oracle/sklearn_adaboost.py");
    let output = Command::new(&python)
        .arg(&script)
        .arg(&file)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {python} (CHRONOMAP_SKLEARN_PYTHON): {e}"));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "sklearn_adaboost.py failed:\n{stderr}"
    );
    println!("{}", stderr.lines().last().unwrap_or(""));
    let reference: Value = serde_json::from_slice(&output.stdout).unwrap();
    for case in &cases {
        let m = fit(case);
        let r = &reference[case.name];
        let stumps = r["stumps"].as_array().unwrap();
        assert_eq!(
            m.stumps.len(),
            stumps.len(),
            "{}: number of stumps",
            case.name
        );
        for (t, (ours, theirs)) in m.stumps.iter().zip(stumps).enumerate() {
            let feature = theirs["feature"].as_i64().unwrap();
            assert_eq!(
                ours.feature.map_or(-1, |f| f as i64),
                feature,
                "{} round {t}: feature",
                case.name
            );
            if feature >= 0 {
                assert_eq!(
                    ours.threshold,
                    theirs["threshold"].as_f64().unwrap(),
                    "{} round {t}: threshold",
                    case.name
                );
            }
            assert_eq!(
                u8::from(ours.below) as i64,
                theirs["below"].as_i64().unwrap(),
                "{} round {t}",
                case.name
            );
            assert_eq!(
                u8::from(ours.above) as i64,
                theirs["above"].as_i64().unwrap(),
                "{} round {t}",
                case.name
            );
            let (a, e) = (
                r["alphas"][t].as_f64().unwrap(),
                r["errors"][t].as_f64().unwrap(),
            );
            assert!(
                close(m.alphas[t], a),
                "{} round {t}: alpha {} vs {a}",
                case.name,
                m.alphas[t]
            );
            assert!(
                close(m.errors[t], e),
                "{} round {t}: error {} vs {e}",
                case.name,
                m.errors[t]
            );
        }
        for (i, row) in case.test.iter().enumerate() {
            let (d, p) = (
                r["decision"][i].as_f64().unwrap(),
                r["proba"][i].as_f64().unwrap(),
            );
            assert!(
                close(m.decision(row).unwrap(), d),
                "{} test {i}: decision",
                case.name
            );
            assert!(
                close(m.probability(row).unwrap(), p),
                "{} test {i}: probability",
                case.name
            );
            assert_eq!(
                i64::from(m.predict(row).unwrap()),
                r["predict"][i].as_i64().unwrap()
            );
        }
        println!(
            "{}: {} stumps agree with scikit-learn",
            case.name,
            m.stumps.len()
        );
    }
}

/// The Python of `CHRONOMAP_SKLEARN_PYTHON`; without it `None` (after saying so), or a failure
/// when `CHRONOMAP_REQUIRE_SKLEARN=1`.
fn oracle_python() -> Option<String> {
    if let Ok(python) = std::env::var("CHRONOMAP_SKLEARN_PYTHON") {
        return Some(python);
    }
    let enable = "set CHRONOMAP_SKLEARN_PYTHON to a Python with scikit-learn 1.9";
    assert!(
        std::env::var("CHRONOMAP_REQUIRE_SKLEARN").as_deref() != Ok("1"),
        "CHRONOMAP_REQUIRE_SKLEARN=1 but CHRONOMAP_SKLEARN_PYTHON is not set: {enable}"
    );
    eprintln!("adaboost_matches_scikit_learn: scikit-learn comparison SKIPPED: {enable}");
    None
}
