//! Helpers shared by the command-line tests: chronomap-testutil's, with the `chronomap` binary
//! and the scratch directory of this test binary.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use chronomap_core::TimeSeries;
use chronomap_io::{read_pairs, read_test_set};
use chronomap_models::eval::{EvalReport, TestSet, evaluate};
use chronomap_models::spec::{FitOptions, parse_model_list};

pub use chronomap_testutil::{
    assert_close as close, data, error, json, number_at, positive_at, repo, repo_path, shared_dir,
    stdout, strings, usage_error, write,
};

/// Writes `contents` to the file `name` in `dir`; its path as a command-line argument.
pub fn write_arg(dir: &std::path::Path, name: &str, contents: impl AsRef<[u8]>) -> String {
    write(dir, name, contents).display().to_string()
}

/// Asserts that `text` contains every one of `parts`, showing the text if not.
#[track_caller]
pub fn assert_mentions(text: &str, parts: &[&str]) {
    for part in parts {
        assert!(text.contains(part), "{part:?} is missing from: {text}");
    }
}

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

/// `chronomap ARGS` in a mount namespace of its own where the folder `ro` is `data` mounted
/// read-only (a read-only bind mount, which needs root); `None`, after saying so, where
/// `unshare -m` is not permitted.
pub fn on_read_only_mount(data: &Path, ro: &Path, args: &[&str]) -> Option<Output> {
    let probe = Command::new("unshare")
        .args(["-m", "--propagation", "private", "true"])
        .status();
    if !probe.is_ok_and(|s| s.success()) {
        eprintln!("skipped: `unshare -m` is not permitted (needs root)");
        return None;
    }
    let script = format!(
        "mount --bind {data} {ro} && mount -o remount,bind,ro {ro} && exec {exe} {args}",
        data = data.display(),
        ro = ro.display(),
        exe = env!("CARGO_BIN_EXE_chronomap"),
        args = args.join(" "),
    );
    let run = Command::new("unshare")
        .args(["-m", "--propagation", "private", "sh", "-c", &script])
        .output()
        .unwrap();
    Some(run)
}

/// A fresh scratch directory for one test (`target/tmp/TEST`).
pub fn scratch(test: &str) -> PathBuf {
    chronomap_testutil::scratch!(test)
}

/// A directory the tests of one module share (`target/tmp/NAME`, not emptied).
pub fn tmp(name: &str) -> PathBuf {
    shared_dir(PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name))
}

/// The Python interpreter of an oracle, named by the environment variable `CHRONOMAP_{NAME}_PYTHON`
/// (`STORM`, `SKLEARN`). Without it: `None`, after saying on stderr that `test` skips its
/// comparison with `oracle` and how to `enable` it; a failure instead when
/// `CHRONOMAP_REQUIRE_{NAME}=1` (as in CI).
pub fn oracle_python(name: &str, test: &str, oracle: &str, enable: &str) -> Option<String> {
    let var = format!("CHRONOMAP_{name}_PYTHON");
    let require = format!("CHRONOMAP_REQUIRE_{name}");
    if let Ok(python) = std::env::var(&var) {
        return Some(python);
    }
    assert!(
        std::env::var(&require).as_deref() != Ok("1"),
        "{require}=1 but {var} is not set: {enable}"
    );
    eprintln!("{test}: {oracle} comparison SKIPPED: {enable}");
    None
}

/// Runs the oracle script `tests/oracle/SCRIPT` with `python` (named by `var`) and `args`;
/// prints how long it took (after `label`) and the last line of its stderr. Its JSON output.
pub fn run_oracle(
    python: &str,
    var: &str,
    script: &str,
    args: &[&std::ffi::OsStr],
    label: &str,
) -> serde_json::Value {
    let started = std::time::Instant::now();
    let output = Command::new(python)
        .arg(
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("tests/oracle")
                .join(script),
        )
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {python} ({var}): {e}"));
    let stderr = String::from_utf8_lossy(&output.stderr);
    println!(
        "{label}: {:.1} s; {}",
        started.elapsed().as_secs_f64(),
        stderr.lines().last().unwrap_or("")
    );
    assert!(
        output.status.success(),
        "{script} failed ({}):\n{stderr}",
        output.status
    );
    serde_json::from_slice(&output.stdout)
        .unwrap_or_else(|e| panic!("{script} printed no JSON ({e}):\n{stderr}"))
}

/// `chronomap topo fit` of the bundled Witham Wharf edges into `model`, with `extra` flags:
/// its stdout.
pub fn fit_witham(model: &str, extra: &[&str]) -> String {
    let edges = data("witham_topological_nav/edges");
    let mut args = vec!["topo", "fit", "--edges", &edges, "-o", model];
    args.extend_from_slice(extra);
    stdout(&chronomap(&args))
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
    let sets: Vec<TestSet<'_>> = tests.iter().map(TestSet::from).collect();
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
