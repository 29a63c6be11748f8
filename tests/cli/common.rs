//! Helpers shared by the command-line tests: chronomap-testutil's, with the `chronomap` binary
//! and the scratch directory of this test binary.

use std::path::PathBuf;
use std::process::Output;

pub use chronomap_testutil::{
    assert_close as close, data, error, json, repo, shared_dir, stdout, usage_error, write,
};

/// Runs `chronomap` with `args`.
pub fn chronomap(args: &[&str]) -> Output {
    chronomap_testutil::run(env!("CARGO_BIN_EXE_chronomap"), args)
}

/// A fresh scratch directory for one test (`target/tmp/TEST`).
pub fn scratch(test: &str) -> PathBuf {
    chronomap_testutil::scratch!(test)
}

/// A directory the tests of one module share (`target/tmp/NAME`, not emptied).
pub fn tmp(name: &str) -> PathBuf {
    shared_dir(PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name))
}
