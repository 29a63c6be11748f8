//! Helpers shared by the modules of this test binary (the ones of every test binary are in
//! chronomap-testutil).

use std::path::PathBuf;

use chronomap_io::text::{DataError, Field};

/// A bundled behavior tree or script of `tests/data/bt`.
pub fn bt_example(name: &str) -> PathBuf {
    chronomap_testutil::repo_path("tests/data/bt").join(name)
}

/// Checks name, line, field and the whole message of a data error.
pub fn check(
    err: &DataError,
    name: &str,
    line: Option<usize>,
    field: Option<Field>,
    message: &str,
) {
    assert_eq!(err.name(), name, "{err}");
    assert_eq!(err.line(), line, "{err}");
    assert_eq!(err.field(), field, "{err}");
    assert_eq!(err.to_string(), message);
}
