//! # chronomap-testutil
//!
//! What the tests of chronomap share, so that every test binary finds the bundled data, makes
//! its scratch directories, runs the `chronomap` binary and checks its output the same way.
//! A dev-dependency only (`publish = false`).
//!
//! * **Paths**: [`repo_path`] and [`data_path`] (the repository root and its bundled `data/`),
//!   and [`repo`] / [`data`], the same as text for a command's arguments.
//! * **Scratch directories** under cargo's temporary directory for integration tests
//!   (`target/tmp`): [`scratch!`] (emptied for one test), [`fresh_dir`], [`shared_dir`] (kept,
//!   for the tests of one module that write files of different names) and [`write()`].
//! * **Numbers**: [`close`], and [`assert_close`] for a number of a JSON document.
//! * **Running a binary**: [`run`] with the path cargo gives an integration test
//!   (`env!("CARGO_BIN_EXE_chronomap")`, which exists only when the test is compiled), then
//!   [`stdout`] or [`json`] of a run that must succeed, [`error`] of one that must fail with
//!   exit code 1 and [`usage_error`] of one refused with exit code 2, never with a panic.
//! * **Hostile input**: [`proptest_config`] (reproducible cases, `PROPTEST_CASES` for a deeper
//!   run), [`mutate`] and [`edit`] (byte mutations of real files), [`null_device`] and
//!   [`memory`] (an allocator that counts what each thread holds, for memory bounds).
//! * **Groot2 publishers**: [`free_port_pair`] (a port whose successor is free too),
//!   [`bt_python`] (the Python with BehaviorTree.CPP) and [`BtcppTree`] (a tree run by the real
//!   BehaviorTree.CPP under its `Groot2Publisher`).
//!
//! ```
//! use chronomap_testutil::{close, data_path, repo_path};
//!
//! assert!(repo_path("Cargo.toml").is_file());
//! assert!(data_path("README.md").is_file());
//! assert!(close(0.1 + 0.2, 0.3, 1e-15) && !close(1.0, 1.1, 0.05));
//! ```
#![deny(missing_docs)]

pub mod memory;

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

/// The repository root (this crate lives in `crates/testutil`).
fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// A path inside the repository, `relative` to its root.
pub fn repo_path(relative: &str) -> PathBuf {
    root().join(relative)
}

/// [`repo_path`] as text, for a command's arguments.
pub fn repo(relative: &str) -> String {
    repo_path(relative).display().to_string()
}

/// A path inside the bundled data, `relative` to `data/`.
pub fn data_path(relative: &str) -> PathBuf {
    root().join("data").join(relative)
}

/// [`data_path`] as text, for a command's arguments.
pub fn data(relative: &str) -> String {
    data_path(relative).display().to_string()
}

/// The directory `dir`, emptied: removed with everything in it and made again.
///
/// # Panics
/// If it cannot be made.
pub fn fresh_dir(dir: impl Into<PathBuf>) -> PathBuf {
    let dir = dir.into();
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    dir
}

/// The directory `dir`, made if it is missing and otherwise left as it is (for tests that run
/// at the same time and write files of different names into it).
///
/// # Panics
/// If it cannot be made.
pub fn shared_dir(dir: impl Into<PathBuf>) -> PathBuf {
    let dir = dir.into();
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    dir
}

/// A fresh scratch directory for one test: `target/tmp/PART/...`, emptied ([`fresh_dir`]).
/// A macro, so that cargo's `CARGO_TARGET_TMPDIR` is the one of the integration test that
/// uses it.
///
/// ```text
/// let dir = chronomap_testutil::scratch!("chronomap-io-navmap", test);
/// ```
#[macro_export]
macro_rules! scratch {
    ($($part:expr),+ $(,)?) => {
        $crate::fresh_dir(::std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))$(.join($part))+)
    };
}

/// Writes `contents` to the file `name` in `dir`; its path.
///
/// # Panics
/// If it cannot be written.
pub fn write(dir: &Path, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    path
}

/// Whether `a` is within `tolerance` of `b`.
pub fn close(a: f64, b: f64, tolerance: f64) -> bool {
    (a - b).abs() <= tolerance
}

/// Whether `hits` successes in `n` Monte Carlo runs agree with the probability `p`: the
/// frequency within five binomial standard deviations `5 √(p (1 − p) / n)` of `p` (plus
/// `1e-12`, for `p` of 0 or 1). Returns the frequency for the message of a failed check.
pub fn monte_carlo_agrees(hits: usize, n: usize, p: f64) -> (bool, f64) {
    let frequency = hits as f64 / n as f64;
    let sigma = (p * (1.0 - p) / n as f64).sqrt();
    ((frequency - p).abs() <= 5.0 * sigma + 1e-12, frequency)
}

/// Asserts that `value` is a number within `tolerance` of `expected`.
///
/// # Panics
/// If it is not a number or not that close.
pub fn assert_close(value: &Value, expected: f64, tolerance: f64) {
    let v = value
        .as_f64()
        .unwrap_or_else(|| panic!("not a number: {value}"));
    assert!(close(v, expected, tolerance), "{v} != {expected}");
}

/// The number at `path` (keys from the top) in `value`.
///
/// # Panics
/// If there is none.
pub fn number_at(value: &Value, path: &[&str]) -> f64 {
    path.iter()
        .fold(value, |v, key| &v[*key])
        .as_f64()
        .unwrap_or_else(|| panic!("{path:?} missing in {value}"))
}

/// [`number_at`], which must be a positive finite number.
///
/// # Panics
/// If it is not.
pub fn positive_at(value: &Value, path: &[&str]) -> f64 {
    let number = number_at(value, path);
    assert!(number > 0.0 && number.is_finite(), "{path:?} = {number}");
    number
}

/// The strings of a JSON array.
///
/// # Panics
/// If `value` is not an array of strings.
pub fn strings(value: &Value) -> Vec<&str> {
    value
        .as_array()
        .unwrap_or_else(|| panic!("not an array: {value}"))
        .iter()
        .map(|v| v.as_str().unwrap_or_else(|| panic!("not a string: {v}")))
        .collect()
}

/// Runs the binary `bin` with `args` and waits for it.
///
/// # Panics
/// If it cannot be started.
pub fn run(bin: impl AsRef<OsStr>, args: &[&str]) -> Output {
    let bin = bin.as_ref();
    Command::new(bin)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("run {}: {e}", bin.to_string_lossy()))
}

/// The stdout of a run that must succeed.
///
/// # Panics
/// If it failed.
pub fn stdout(out: &Output) -> String {
    assert!(
        out.status.success(),
        "failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The stdout of a run that must succeed, one JSON document.
///
/// # Panics
/// If it failed or wrote something else.
pub fn json(out: &Output) -> Value {
    serde_json::from_str(&stdout(out)).expect("one JSON object")
}

/// The error of a run that must fail at run time (exit code 1) without a panic.
///
/// # Panics
/// If it exited otherwise or panicked.
pub fn error(out: &Output) -> String {
    failure(out, 1)
}

/// The error of a run that must be refused as a usage error (exit code 2) without a panic.
///
/// # Panics
/// If it exited otherwise or panicked.
pub fn usage_error(out: &Output) -> String {
    failure(out, 2)
}

fn failure(out: &Output, code: i32) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(code), "accepted: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// The configuration of a property test: `PROPTEST_CASES` cases if set, else `default_cases`,
/// drawn from the fixed `RngSeed::Fixed(rng_seed)` so that a failure reproduces, and no failure
/// files written beside the sources.
pub fn proptest_config(default_cases: u32, rng_seed: u64) -> proptest::test_runner::Config {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|c| c.parse().ok())
        .unwrap_or(default_cases);
    proptest::test_runner::Config {
        cases,
        rng_seed: proptest::test_runner::RngSeed::Fixed(rng_seed),
        failure_persistence: None,
        ..proptest::test_runner::Config::default()
    }
}

/// One edit of `bytes` at `at` (modulo their length), by `kind` modulo 5: 0 flips the bit
/// `value % 8`, 1 overwrites the byte with `value`, 2 inserts `value`, 3 deletes the byte, 4
/// cuts the bytes there. Empty bytes get `value`.
pub fn edit(bytes: &mut Vec<u8>, at: usize, kind: u8, value: u8) {
    if bytes.is_empty() {
        bytes.push(value);
        return;
    }
    let at = at % bytes.len();
    match kind % 5 {
        0 => bytes[at] ^= 1 << (value % 8),
        1 => bytes[at] = value,
        2 => bytes.insert(at, value),
        3 => {
            bytes.remove(at);
        }
        _ => bytes.truncate(at),
    }
}

/// `bytes` after each [`edit`] of `edits` (place, kind, value) in turn: flipped bits,
/// overwritten, inserted or deleted bytes, a cut.
///
/// ```
/// use chronomap_testutil::mutate;
///
/// // Overwrite the byte at 4 % 3, insert at 0, cut at 3.
/// assert_eq!(mutate(b"abc".to_vec(), &[(4, 1, b'B'), (0, 2, b'x'), (3, 4, 0)]), b"xaB");
/// // Flip bit 0 of the last byte, delete the first.
/// assert_eq!(mutate(b"abc".to_vec(), &[(2, 0, 8), (0, 3, 0)]), b"bb");
/// assert_eq!(mutate(Vec::new(), &[(7, 3, b'z')]), b"z");
/// ```
pub fn mutate(mut bytes: Vec<u8>, edits: &[(usize, u8, u8)]) -> Vec<u8> {
    for &(at, kind, value) in edits {
        edit(&mut bytes, at, kind, value);
    }
    bytes
}

/// A null character device in `dir` when this process may make one (root, who could also
/// rename over `/dev/null` itself); otherwise `/dev/null`, which no other user can replace.
pub fn null_device(dir: &Path) -> PathBuf {
    let own = dir.join("null");
    let made = Command::new("mknod")
        .arg(&own)
        .args(["c", "1", "3"])
        .status()
        .is_ok_and(|s| s.success());
    if made {
        own
    } else {
        eprintln!("mknod is not permitted: the device is /dev/null itself");
        PathBuf::from("/dev/null")
    }
}

/// A loopback port whose successor is free too (a Groot2 publisher binds both).
///
/// # Panics
/// If no such pair is found in 100 tries.
pub fn free_port_pair() -> u16 {
    for _ in 0..100 {
        let first = std::net::TcpListener::bind("127.0.0.1:0").expect("a free port");
        let port = first.local_addr().expect("its address").port();
        if port < 65534 && std::net::TcpListener::bind(("127.0.0.1", port + 1)).is_ok() {
            return port;
        }
    }
    panic!("no two free ports in a row on 127.0.0.1");
}

/// The Python with BehaviorTree.CPP (`behaviortreepy`): `CHRONOMAP_BT_PYTHON`, else the
/// workspace's `target/bt-venv`. `None` (the caller skips, after this says so on stderr)
/// unless `CHRONOMAP_REQUIRE_BT=1`, which makes a missing one a failure.
///
/// # Panics
/// If it is missing and `CHRONOMAP_REQUIRE_BT=1`.
pub fn bt_python() -> Option<PathBuf> {
    let python = std::env::var_os("CHRONOMAP_BT_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("target/bt-venv/bin/python"));
    if python.exists() {
        return Some(python);
    }
    assert!(
        std::env::var("CHRONOMAP_REQUIRE_BT").as_deref() != Ok("1"),
        "{} does not exist (CHRONOMAP_REQUIRE_BT=1)",
        python.display()
    );
    eprintln!(
        "skipped: no BehaviorTree.CPP Python at {}",
        python.display()
    );
    None
}

/// `tests/bt/btcpp_groot2_tree.py`: a tree run by the real BehaviorTree.CPP with its own
/// `Groot2Publisher` on a port, killed when dropped.
pub struct BtcppTree {
    child: std::process::Child,
    /// The line the script printed when it was ready (`ready port=P nodes=N`).
    pub ready: String,
}

impl BtcppTree {
    /// Starts the script with `python` on `port`, running `tree` (its default without), for at
    /// most two minutes, and waits until it is ready.
    ///
    /// # Panics
    /// If the script cannot be started or does not say it is ready.
    pub fn start(python: &Path, port: u16, tree: Option<&str>) -> BtcppTree {
        use std::io::BufRead;
        let mut command = Command::new(python);
        command
            .arg(repo_path("tests/bt/btcpp_groot2_tree.py"))
            .args(["--port", &port.to_string(), "--seconds", "120"]);
        if let Some(tree) = tree {
            command.args(["--tree", tree]);
        }
        let mut child = command
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::inherit())
            .spawn()
            .expect("the BehaviorTree.CPP tree starts");
        let mut ready = String::new();
        std::io::BufReader::new(child.stdout.as_mut().expect("its stdout"))
            .read_line(&mut ready)
            .expect("its first line");
        assert!(
            ready.starts_with("ready"),
            "the tree did not start: {ready:?}"
        );
        BtcppTree {
            child,
            ready: ready.trim().to_owned(),
        }
    }
}

impl Drop for BtcppTree {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
