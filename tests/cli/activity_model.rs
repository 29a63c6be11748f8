//! `chronomap activity fit` then `predict` on the bundled ATC grid: a saved CoPA-Map answers
//! with mean and standard deviation over the map, draws them, and damaged or foreign model
//! files are refused with their name.

use crate::common;

use common::{chronomap, error, fit_small_copa, repo, stdout, tmp, usage_error};

#[test]
fn a_fitted_copa_map_predicts_mean_and_std_over_the_map() {
    let dir = tmp("activity_model");
    let path = |name: &str| dir.join(name).display().to_string();
    let (model, csv, png) = (path("atc.cmcopa"), path("atc.csv"), path("atc.png"));
    let text = fit_small_copa(&model);
    assert!(
        text.contains("on 76456 samples, 652 cells; periods"),
        "{text}"
    );

    let map = repo("data/atc_copa_map_grid/atc_map.yaml");
    let text = stdout(&chronomap(&[
        "activity", "predict", "--model", &model, "--t", "123", "--t", "129", "--map", &map,
        "--csv", &csv, "--png", &png,
    ]));
    // The training square (24 m, centres 3.75 .. 27.75) in 49 × 49 cells of 0.5 m, minus
    // the cells on walls of the map, at two times.
    assert!(text.contains("atc.csv: 4084 predictions"), "{text}");
    assert!(text.contains("(49 × 49 cells of 0.5 m)"), "{text}");
    let rows: Vec<Vec<f64>> = std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 4084);
    assert_eq!(&rows[0][..3], [3.75, 4.25, 123.0]);
    assert!(rows.iter().all(|r| r[3] >= 0.0 && r[4] > 0.0));
    let mean = rows.iter().map(|r| r[3]).sum::<f64>() / rows.len() as f64;
    // The grid's mean rate is 42.5 per hour; the map covers quieter corners too.
    assert!((20.0..60.0).contains(&mean), "{mean}");
    assert!(std::fs::metadata(&png).unwrap().len() > 10_000);

    // A damaged file and a file of another kind are refused, naming the file.
    let mut bytes = std::fs::read(&model).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    let damaged = path("damaged.cmcopa");
    std::fs::write(&damaged, &bytes).unwrap();
    let err = error(&chronomap(&[
        "activity", "predict", "--model", &damaged, "--t", "1",
    ]));
    assert!(err.contains("damaged.cmcopa"), "{err}");
    let err = usage_error(&chronomap(&[
        "activity", "predict", "--model", &model, "--t", "1", "--region", "0,0,-1,1",
    ]));
    assert!(err.contains("--region"), "{err}");
}

#[test]
fn a_fitted_log_additive_model_is_saved_checked_and_predicts_the_median() {
    let dir = tmp("activity_model_log");
    let path = |name: &str| dir.join(name).display().to_string();
    let model = path("atc.cmlog");
    let grid = repo("data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz");
    let text = stdout(&chronomap(&[
        "activity",
        "fit",
        "--model",
        "log-additive",
        "--train",
        &grid,
        "-o",
        &model,
        "--json",
    ]));
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(json["kind"], "log-additive");
    assert_eq!(json["cells"], 652);
    // τ and κ chosen on the last two days (t >= 96) among 5 × 8 candidates: every day alike
    // and κ = 10, hold-out RMSE of ln(1 + y) 1.0619 (no interaction: 1.0830).
    assert_eq!(json["shrinkage"], 10.0);
    assert_eq!(json["memory_days"], "inf");
    let scores = json["holdout_rmse_log1p"].as_array().unwrap();
    assert_eq!(scores.len(), 40);
    assert_eq!(scores[0]["shrinkage"], "inf");
    assert_eq!(scores[0]["memory_days"], "inf");
    assert_eq!(scores[4]["shrinkage"], 10.0);
    common::close(&scores[0]["rmse"], 1.08304, 1e-4);
    common::close(&scores[4]["rmse"], 1.06186, 1e-4);
    let bytes = std::fs::read(&model).unwrap();
    assert!(bytes.starts_with(b"chronomap-model 1 kind=log-additive encoding=postcard"));

    // A busy cell of the hallway at 12:00 and 18:00 of the next day: the median of 1 + y
    // under (L2), and the log-normal's std.
    let text = stdout(&chronomap(&[
        "activity", "predict", "--model", &model, "--t", "123,129", "--region", "10.5", "-5.5",
        "11", "-5", "--json",
    ]));
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let p = json["predictions"].as_array().unwrap();
    assert_eq!(p.len(), 2);
    assert_eq!(
        (p[0]["x1"].as_f64(), p[0]["x2"].as_f64()),
        (Some(10.75), Some(-5.25))
    );
    common::close(&p[0]["mean"], 107.180, 1e-2);
    common::close(&p[1]["mean"], 58.296, 1e-2);
    common::close(&p[0]["std"], 288.275, 1e-1);

    // A damaged file is refused, naming it.
    let mut bytes = bytes;
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    let damaged = path("damaged.cmlog");
    std::fs::write(&damaged, &bytes).unwrap();
    let err = error(&chronomap(&[
        "activity", "predict", "--model", &damaged, "--t", "1",
    ]));
    assert!(err.contains("damaged.cmlog"), "{err}");
}

#[test]
fn predict_writes_with_the_new_spellings_prints_json_and_survives_a_closed_pipe() {
    let dir = tmp("activity_model_json");
    let path = |name: &str| dir.join(name).display().to_string();
    let model = path("tiny.cmcopa");
    let grid = repo("data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz");
    let text = stdout(&chronomap(&[
        "activity",
        "fit",
        "--train",
        &grid,
        "--inducing",
        "10",
        "--iterations",
        "3",
        "--output",
        &model,
        "--json",
    ]));
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(
        (v["samples"].as_u64(), v["cells"].as_u64()),
        (Some(76_456), Some(652))
    );
    assert_eq!(v["iterations"], 3);
    assert_eq!(v["periods"].as_array().unwrap().len(), 2);

    let (csv, png) = (path("tiny.csv"), path("tiny.png"));
    let map = repo("data/atc_copa_map_grid/atc_map.yaml");
    let text = stdout(&chronomap(&[
        "activity", "predict", "--model", &model, "--t", "123,129", "--map", &map, "-o", &csv,
        "--plot", &png, "--json",
    ]));
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    // The same cells as the documented call: 49 × 49 minus the walls, at two times.
    assert_eq!(
        (v["cols"].as_u64(), v["rows"].as_u64()),
        (Some(49), Some(49))
    );
    assert_eq!(v["times"], serde_json::json!([123.0, 129.0]));
    let predictions = v["predictions"].as_array().unwrap();
    assert_eq!(predictions.len(), 4084);
    assert_eq!(predictions[0]["x1"], 3.75);
    assert_eq!(predictions[0]["x2"], 4.25);
    let rows = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(rows.lines().count(), 4085);
    let first: Vec<f64> = rows
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    assert_eq!(first[3], predictions[0]["mean"].as_f64().unwrap());
    assert!(std::fs::metadata(&png).unwrap().len() > 10_000);
    // Times must be finite: a usage error.
    let err = usage_error(&chronomap(&[
        "activity", "predict", "--model", &model, "--t", "inf",
    ]));
    assert!(err.contains("--t inf"), "{err}");

    // 4 × 2401 rows of CSV (about 400 KB) into a pipe closed after the header.
    let (header, _) = common::closed_pipe(
        &[
            "activity",
            "predict",
            "--model",
            &model,
            "--t",
            "120,121,122,123",
        ],
        1,
    );
    assert_eq!(header, "x1,x2,t,mean,std\n");
}
