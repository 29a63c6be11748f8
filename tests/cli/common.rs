//! Helpers shared by the command-line tests: chronomap-testutil's, with the `chronomap` binary
//! and the scratch directory of this test binary.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Command, Output, Stdio};

use chronomap_io::{TimeSeries, read_pairs, read_test_set};
use chronomap_models::eval::{EvalReport, TestSet, evaluate};
use chronomap_models::spec::{FitOptions, parse_model_list};

pub use chronomap_testutil::{
    assert_close as close, data, error, json, number_at, positive_at, repo, repo_path, shared_dir,
    stdout, strings, usage_error, write,
};

/// Runs `chronomap` with `args`.
pub fn chronomap(args: &[&str]) -> Output {
    chronomap_testutil::run(env!("CARGO_BIN_EXE_chronomap"), args)
}

/// Runs `chronomap` with `args` into a pipe that is closed after the first `lines` lines of its
/// stdout (0: before anything is read): those lines and the stderr, after checking that the run
/// still ended with exit code 0 and no panic.
pub fn closed_pipe(args: &[&str], lines: usize) -> (String, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut read = String::new();
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    for _ in 0..lines {
        stdout.read_line(&mut read).unwrap();
    }
    drop(stdout);
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(0), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    (read, err)
}

/// A fresh scratch directory for one test (`target/tmp/TEST`).
pub fn scratch(test: &str) -> PathBuf {
    chronomap_testutil::scratch!(test)
}

/// A directory the tests of one module share (`target/tmp/NAME`, not emptied).
pub fn tmp(name: &str) -> PathBuf {
    shared_dir(PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name))
}

/// `chronomap activity fit` of a small CoPA-Map (30 inducing points, 20 iterations: about
/// 2 s) on the bundled ATC grid, saved to `model`: its stdout.
pub fn fit_small_copa(model: &str) -> String {
    let grid = data("atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz");
    stdout(&chronomap(&[
        "activity",
        "fit",
        "--train",
        &grid,
        "--inducing",
        "30",
        "--iterations",
        "20",
        "-o",
        model,
    ]))
}

/// The training data of the bundled greg door (Lincoln, 2016).
pub fn greg_training() -> TimeSeries {
    read_pairs(chronomap_testutil::data_path(
        "door_greg_2016/training_data.txt.xz",
    ))
    .unwrap()
}

/// The five test weeks of the bundled greg door.
pub fn greg_tests() -> Vec<TimeSeries> {
    let file = |name: String| chronomap_testutil::data_path(&format!("door_greg_2016/{name}"));
    (1..=5)
        .map(|i| {
            let (times, values) = (
                format!("test_times_{i}.txt.xz"),
                format!("test_data_{i}.txt.xz"),
            );
            read_test_set(file(times), file(values)).unwrap()
        })
        .collect()
}

/// Every model of the list `specs` fitted on `train` and scored on `tests`.
pub fn evaluate_specs_on(specs: &str, train: &TimeSeries, tests: &[TimeSeries]) -> EvalReport {
    let sets: Vec<TestSet<'_>> = tests.iter().map(TimeSeries::as_test_set).collect();
    evaluate(
        &parse_model_list(specs).unwrap(),
        &train.times,
        &train.values,
        &sets,
        &FitOptions::default(),
        |_| {},
    )
    .unwrap()
}
