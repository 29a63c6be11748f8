//! Helpers shared by the command-line tests of the activity maps: run the binary, read its
//! output, find bundled data.

use std::path::PathBuf;
use std::process::{Command, Output};

use serde_json::Value;

/// Runs `chronomap` with `args`.
pub fn chronomap(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args(args)
        .output()
        .expect("run chronomap")
}

/// A path inside the repository.
pub fn repo(path: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join(path)
        .display()
        .to_string()
}

/// The stdout of a run that must succeed.
pub fn stdout(out: &Output) -> String {
    assert!(
        out.status.success(),
        "failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The error of a run that must fail at run time (exit code 1) without a panic.
pub fn error(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "accepted: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// Asserts that `value` is a number within `tolerance` of `expected`.
pub fn close(value: &Value, expected: f64, tolerance: f64) {
    let v = value
        .as_f64()
        .unwrap_or_else(|| panic!("not a number: {value}"));
    assert!((v - expected).abs() <= tolerance, "{v} != {expected}");
}

/// The error of a run that must be refused as a usage error (exit code 2) without a panic.
pub fn usage_error(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "accepted: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}
