//! Shared by the service tests: start `chronomap serve` as a real process on a fixed loopback
//! port, kill it, restart it.

use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub use crate::common::scratch;

/// A loopback port free right now.
pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Where the models live.
#[derive(Clone, Debug)]
pub enum Backend {
    /// `DATA/chronomap.redb`.
    Redb,
    /// PostgreSQL (connection string, schema).
    Postgres(String, String),
}

/// The PostgreSQL connection string for tests, if configured (`CHRONOMAP_POSTGRES`). Without
/// it the test is skipped, unless `CHRONOMAP_REQUIRE_POSTGRES=1` (as in CI) makes it fail.
pub fn postgres() -> Option<String> {
    match std::env::var("CHRONOMAP_POSTGRES") {
        Ok(config) if !config.is_empty() => Some(config),
        _ => {
            if std::env::var("CHRONOMAP_REQUIRE_POSTGRES").as_deref() == Ok("1") {
                panic!("CHRONOMAP_REQUIRE_POSTGRES=1 but CHRONOMAP_POSTGRES is not set");
            }
            eprintln!(
                "skipped: set CHRONOMAP_POSTGRES='host=127.0.0.1 user=... dbname=...' to run the \
                 PostgreSQL variant (.ci/run does)"
            );
            None
        }
    }
}

/// A PostgreSQL backend on a schema of its own (`PREFIX_PID_NANOS`), so that runs at the same
/// time do not share one; `None` (skipped) as [`postgres`] says.
pub fn postgres_backend(prefix: &str) -> Option<Backend> {
    let config = postgres()?;
    let schema = format!(
        "{prefix}_{}_{}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .subsec_nanos()
    );
    Some(Backend::Postgres(config, schema))
}

/// The two tests of one service test `fn(name, Backend)`: `$redb` on redb, always, and
/// `$postgres` on a schema of its own (prefix `$prefix`), skipped as [`postgres_backend`] says.
/// The scratch names are `serve_PREFIX_redb` and `serve_PREFIX_postgres`.
macro_rules! on_each_backend {
    ($test:ident, $prefix:literal, $redb:ident, $postgres:ident) => {
        #[test]
        fn $redb() {
            $test(
                concat!("serve_", $prefix, "_redb"),
                $crate::service::Backend::Redb,
            );
        }

        #[test]
        fn $postgres() {
            if let Some(backend) = $crate::service::postgres_backend($prefix) {
                $test(concat!("serve_", $prefix, "_postgres"), backend);
            }
        }
    };
}
pub(crate) use on_each_backend;

/// A redb store in `dir/data` of one model, `door`, observed 4 times in 3 log entries; its data
/// folder.
pub fn small_store(dir: &Path) -> PathBuf {
    use chronomap_serve::log::{LogRecord, encode_group};
    use chronomap_serve::registry::ModelConfig;
    use chronomap_serve::store::{RedbStore, Store};

    let data = dir.join("data");
    std::fs::create_dir_all(&data).unwrap();
    let store = RedbStore::open(data.join("chronomap.redb")).unwrap();
    let groups = [
        vec![LogRecord::Create {
            id: "door".into(),
            config: ModelConfig::parse(None, None).unwrap(),
        }],
        vec![LogRecord::Observe {
            id: "door".into(),
            times: vec![0.0, 60.0],
            values: vec![0.0, 1.0],
        }],
        vec![LogRecord::Observe {
            id: "door".into(),
            times: vec![120.0, 180.0],
            values: vec![1.0, 0.0],
        }],
    ];
    for (i, records) in groups.iter().enumerate() {
        let seq = i as u64 + 1;
        store.append(seq, &encode_group(seq, records)).unwrap();
    }
    data
}

/// A running `chronomap serve`.
pub struct Server {
    pub child: Child,
    pub url: String,
    pub started_in: Duration,
}

/// Starts `chronomap serve` on `port` and waits until it listens.
pub fn start(data: &Path, port: u16, backend: &Backend, extra: &[&str]) -> Server {
    let begin = Instant::now();
    let mut command = Command::new(env!("CARGO_BIN_EXE_chronomap"));
    command
        .args(["serve", "--data"])
        .arg(data)
        .args(["--listen", &format!("127.0.0.1:{port}")])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit());
    if let Backend::Postgres(config, schema) = backend {
        command.args(["--postgres", config, "--postgres-schema", schema]);
    }
    let mut child = command.spawn().expect("chronomap serve starts");
    let stdout = child.stdout.take().unwrap();
    let mut lines = BufReader::new(stdout).lines();
    let first = lines
        .next()
        .expect("chronomap serve prints a line")
        .expect("readable stdout");
    assert!(
        first.contains(&format!("listening on http://127.0.0.1:{port}")),
        "unexpected first line: {first}"
    );
    // Keep draining stdout so that the server never blocks on a full pipe.
    std::thread::spawn(move || for _ in lines {});
    Server {
        child,
        url: format!("http://127.0.0.1:{port}"),
        started_in: begin.elapsed(),
    }
}

impl Server {
    /// SIGKILL: no shutdown code runs.
    pub fn kill(mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The token the server generated in `data`.
pub fn token(data: &Path) -> String {
    std::fs::read_to_string(data.join("token"))
        .unwrap()
        .trim()
        .to_owned()
}

/// One raw HTTP/1.1 exchange on a fresh connection (for headers a client library sets itself,
/// such as `Host`): sends `request` as written, reads the answer until the server closes.
/// Returns the status, the head (lower case) and the body.
pub fn raw_http(port: u16, request: &str) -> (u16, String, String) {
    use std::io::{Read, Write};
    let mut stream = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(20)))
        .unwrap();
    stream.write_all(request.as_bytes()).unwrap();
    let mut answer = Vec::new();
    let _ = stream.read_to_end(&mut answer);
    let answer = String::from_utf8_lossy(&answer).into_owned();
    let (head, body) = answer.split_once("\r\n\r\n").unwrap_or((&answer, ""));
    let status = head
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no HTTP answer to {request:?}: {answer:?}"));
    (status, head.to_ascii_lowercase(), body.to_owned())
}

/// `chronomap serve ARGS` run to its end (a start that must fail, `--check`, `--salvage`):
/// exit code, stdout, stderr.
pub fn serve_once(args: &[&std::ffi::OsStr]) -> (i32, String, String) {
    let output = Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .arg("serve")
        .args(args)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

impl Server {
    /// SIGTERM and wait: the graceful stop (last checkpoint written).
    pub fn stop(mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        self.child.wait().unwrap();
    }
}
