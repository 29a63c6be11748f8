//! `chronomap activity fit` then `predict` on the bundled ATC grid: a saved CoPA-Map answers
//! with mean and standard deviation over the map, draws them, and damaged or foreign model
//! files are refused with their name.

use crate::common;

use std::path::PathBuf;

use common::{chronomap, error, fit_small_copa, repo, stdout, usage_error};

#[test]
fn a_fitted_copa_map_predicts_mean_and_std_over_the_map() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("activity_model");
    std::fs::create_dir_all(&dir).unwrap();
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
