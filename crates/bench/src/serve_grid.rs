//! Grid predictions under load (`chronomap bench serve --grid-load`): the service of this build
//! and of a baseline binary, each run as `chronomap serve` in a process of its own on loopback
//! with the same grid and door model, measured in turns in the same run.
//!
//! Each service serves a synthetic office grid ([Krajník 2017] §VI, `chronomap-synth`) kept
//! with its learning state, and a `fremen:2` door model learned from the training door through
//! the API. In every round, each service in turn is measured twice:
//!
//! * **quiet**: 4 clients ask back to back for a door prediction at one time, then 4 clients
//!   for `GET /v1/health` (as `chronomap bench serve` does);
//! * **loaded**: `grid_clients` clients ask back to back for the grid's map at a time
//!   (`POST /v1/grid/office/predict`) while one client asks for `GET /v1/health` and one for a
//!   door prediction.
//!
//! The latencies of all rounds are pooled per service; the ratios are this build's over the
//! baseline's. Taking turns spreads the noise of a shared machine over both services.

use std::fmt::Write as _;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use chronomap_app::report::Table;
use chronomap_client::{Client, ClientError, Method, StatusCode};
use chronomap_core::Parallelism;
use chronomap_grid::AnyGrid;
use chronomap_grid::GridConfig;
use serde::Serialize;
use thiserror::Error;

/// Untimed requests of each client before a phase.
const WARM_UP: usize = 5;
/// Longest wait for one answer.
const REQUEST_TIMEOUT: Duration = Duration::from_secs(120);
/// Longest wait for a service to say where it listens.
const START_TIMEOUT: Duration = Duration::from_secs(60);
/// Clients of the quiet phases.
const QUIET_CLIENTS: usize = 4;
/// The door model's spec.
const DOOR_MODEL: &str = "fremen:2";

/// What to run.
#[derive(Clone, Debug, PartialEq)]
pub struct GridLoadConfig {
    /// The `chronomap` binary of this build.
    pub this_build: PathBuf,
    /// A `chronomap` binary to compare with (e.g. built from an earlier commit).
    pub baseline: Option<PathBuf>,
    /// Cells of the synthetic office grid.
    pub cells: usize,
    /// Days of frames it learns from.
    pub days: u32,
    /// Concurrent clients asking for the grid's map.
    pub grid_clients: usize,
    /// Seconds of each phase.
    pub seconds: f64,
    /// Rounds (each service measured once per round).
    pub rounds: usize,
}

impl GridLoadConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`GridLoadError::Config`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), GridLoadError> {
        let checks: [(bool, &'static str, &'static str); 5] = [
            (
                (64..=4_000_000).contains(&self.cells),
                "cells",
                "64 to 4,000,000 cells",
            ),
            ((1..=28).contains(&self.days), "days", "1 to 28 days"),
            (
                (1..=256).contains(&self.grid_clients),
                "grid_clients",
                "1 to 256 clients",
            ),
            (
                self.seconds > 0.0 && self.seconds <= 600.0,
                "seconds",
                "more than 0 and at most 600",
            ),
            ((1..=100).contains(&self.rounds), "rounds", "1 to 100"),
        ];
        match checks.into_iter().find(|(ok, ..)| !ok) {
            Some((_, field, message)) => Err(GridLoadError::Config { field, message }),
            None => Ok(()),
        }
    }
}

/// Why the benchmark could not run.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum GridLoadError {
    /// A field of [`GridLoadConfig`] is out of range.
    #[error("{field}: {message}")]
    Config {
        /// The field.
        field: &'static str,
        /// What it must be.
        message: &'static str,
    },
    /// The training door has too few observations.
    #[error("the training data needs at least 2 observations, not {0}")]
    TooFewObservations(usize),
    /// The grid could not be built or written.
    #[error("cannot build the office grid: {0}")]
    Grid(String),
    /// A scratch directory or file could not be made.
    #[error("cannot create {}", path.display())]
    Scratch {
        /// The path.
        path: PathBuf,
        /// What went wrong.
        source: std::io::Error,
    },
    /// A service could not be started or did not say where it listens.
    #[error("cannot start {}: {message}", binary.display())]
    Start {
        /// The binary.
        binary: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The clients' async runtime could not start.
    #[error("cannot start the clients' async runtime")]
    Runtime(#[source] std::io::Error),
    /// A request failed.
    #[error(transparent)]
    Client(#[from] ClientError),
    /// A request was answered with an error.
    #[error("{what}: {status}: {text}")]
    Status {
        /// The request.
        what: &'static str,
        /// The HTTP status.
        status: StatusCode,
        /// The answer (its start).
        text: String,
    },
    /// A request was not answered in time.
    #[error("{0}: no answer within 120 s")]
    Timeout(&'static str),
    /// A client task panicked.
    #[error("a client task panicked")]
    Panicked,
}

/// Latencies of one kind of request.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Percentiles {
    /// Requests timed.
    pub requests: usize,
    /// Median (µs).
    pub p50_us: f64,
    /// 99th percentile (µs).
    pub p99_us: f64,
    /// Largest (µs).
    pub max_us: f64,
}

impl Percentiles {
    fn of(mut all: Vec<f64>) -> Percentiles {
        all.sort_by(f64::total_cmp);
        let rank = |q: f64| {
            all.get(((q * all.len() as f64).ceil() as usize).clamp(1, all.len().max(1)) - 1)
                .copied()
                .unwrap_or(f64::NAN)
        };
        Percentiles {
            requests: all.len(),
            p50_us: rank(0.5),
            p99_us: rank(0.99),
            max_us: all.last().copied().unwrap_or(f64::NAN),
        }
    }
}

/// One service's latencies, all rounds pooled.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ServiceLoad {
    /// `baseline` or `this build`.
    pub name: String,
    /// Its binary.
    pub binary: String,
    /// Quiet: door predictions at one time, 4 clients.
    pub quiet_predict: Percentiles,
    /// Quiet: `GET /v1/health`, 4 clients.
    pub quiet_health: Percentiles,
    /// Loaded: the grid's map, `grid_clients` clients.
    pub loaded_grid: Percentiles,
    /// Loaded: `GET /v1/health`, one client, while the maps are asked for.
    pub loaded_health: Percentiles,
    /// Loaded: door predictions at one time, one client, while the maps are asked for.
    pub loaded_predict: Percentiles,
    /// Grid maps answered per second while loaded.
    pub grid_per_second: f64,
}

/// The benchmark's result.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GridLoadBench {
    /// Cells of the grid.
    pub cells: usize,
    /// Of which changing (with a model of their own).
    pub changing_cells: usize,
    /// Bytes of one map's JSON answer.
    pub map_bytes: usize,
    /// Concurrent map clients.
    pub grid_clients: usize,
    /// Seconds of each phase.
    pub seconds: f64,
    /// Rounds.
    pub rounds: usize,
    /// Hardware threads of the machine.
    pub threads: usize,
    /// The baseline first (if given), then this build.
    pub services: Vec<ServiceLoad>,
}

impl GridLoadBench {
    /// This build's p99 over the baseline's, for each measured kind: `(kind, ratio)`.
    pub fn ratios(&self) -> Vec<(&'static str, f64)> {
        let [base, this] = &self.services[..] else {
            return Vec::new();
        };
        let r = |a: &Percentiles, b: &Percentiles| a.p99_us / b.p99_us;
        vec![
            (
                "quiet predict p99",
                r(&this.quiet_predict, &base.quiet_predict),
            ),
            (
                "quiet health p99",
                r(&this.quiet_health, &base.quiet_health),
            ),
            ("loaded grid p99", r(&this.loaded_grid, &base.loaded_grid)),
            (
                "loaded health p99",
                r(&this.loaded_health, &base.loaded_health),
            ),
            (
                "loaded predict p99",
                r(&this.loaded_predict, &base.loaded_predict),
            ),
        ]
    }
}

/// A service in a process of its own, stopped when dropped.
struct Served {
    child: Child,
    base: String,
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts `binary serve` on `127.0.0.1:0` with a fresh store in `dir` and the grid file.
fn start(binary: &Path, dir: &Path, grid: &Path) -> Result<Served, GridLoadError> {
    let failed = |message: String| GridLoadError::Start {
        binary: binary.to_owned(),
        message,
    };
    let data = dir.join("store");
    let mut child = Command::new(binary)
        .arg("serve")
        .arg("--data")
        .arg(&data)
        .args(["--listen", "127.0.0.1:0", "--no-token", "--grid"])
        .arg(format!("office={}", grid.display()))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| failed(e.to_string()))?;
    let stdout = child.stdout.take().expect("piped");
    let (found, address) = std::sync::mpsc::channel();
    // Reads the lines until the address, then drains the rest so the service never blocks.
    std::thread::spawn(move || {
        let mut found = Some(found);
        for line in BufReader::new(stdout).lines() {
            let Ok(line) = line else { break };
            if let Some(rest) = line.split("listening on http://").nth(1)
                && let Some(sender) = found.take()
            {
                let _ = sender.send(rest.split_whitespace().next().unwrap_or("").to_owned());
            }
        }
    });
    let mut served = Served {
        child,
        base: String::new(),
    };
    match address.recv_timeout(START_TIMEOUT) {
        Ok(address) if !address.is_empty() => {
            served.base = format!("http://{address}");
            Ok(served)
        }
        _ => Err(failed("it did not say where it listens within 60 s".into())),
    }
}

/// The door's observations: times (s, not decreasing) and values in `[0, 1]`.
#[derive(Clone, Copy, Debug)]
pub struct Door<'a> {
    /// Times.
    pub times: &'a [f64],
    /// Values.
    pub values: &'a [f64],
}

/// Runs the benchmark with `train` as the door's observations.
///
/// # Errors
/// A field of `config` out of range, a service that does not start, and any failed request.
pub fn run(config: &GridLoadConfig, train: Door<'_>) -> Result<GridLoadBench, GridLoadError> {
    config.validate()?;
    if train.times.len() < 2 || train.times.len() != train.values.len() {
        return Err(GridLoadError::TooFewObservations(train.times.len()));
    }
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    let scratch = std::env::temp_dir().join(format!(
        "chronomap-bench-grid-load-{}-{nanos}",
        std::process::id()
    ));
    let made = |source| GridLoadError::Scratch {
        path: scratch.clone(),
        source,
    };
    std::fs::create_dir_all(&scratch).map_err(made)?;
    let result = run_in(config, train, &scratch);
    let _ = std::fs::remove_dir_all(&scratch);
    result
}

fn run_in(
    config: &GridLoadConfig,
    train: Door<'_>,
    scratch: &Path,
) -> Result<GridLoadBench, GridLoadError> {
    let workload = chronomap_synth::office_grid::office(config.cells, config.days, 0)
        .map_err(|e| GridLoadError::Grid(e.to_string()))?;
    let grid = workload
        .learned_grid(&GridConfig::default(), Parallelism::Rayon(0))
        .map_err(|e| GridLoadError::Grid(e.to_string()))?;
    let changing_cells = grid.dynamic_cells();
    let grid_path = scratch.join("office.cmg");
    chronomap_io::grid_file::write_grid_file(&grid_path, &AnyGrid::State(Box::new(grid)))
        .map_err(|e| GridLoadError::Grid(e.to_string()))?;

    let mut binaries = Vec::new();
    if let Some(baseline) = &config.baseline {
        binaries.push(("baseline", baseline.clone()));
    }
    binaries.push(("this build", config.this_build.clone()));
    let mut served = Vec::new();
    for (k, (_, binary)) in binaries.iter().enumerate() {
        let dir = scratch.join(format!("service-{k}"));
        std::fs::create_dir_all(&dir).map_err(|source| GridLoadError::Scratch {
            path: dir.clone(),
            source,
        })?;
        served.push(start(binary, &dir, &grid_path)?);
    }
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(threads)
        .enable_all()
        .build()
        .map_err(GridLoadError::Runtime)?;
    let end = train.times[train.times.len() - 1];
    let mut map_bytes = 0;
    for s in &served {
        let client = Client::new(&s.base, None)?;
        runtime.block_on(client.add_values("door", train.times, train.values, Some(DOOR_MODEL)))?;
        // The first map fits the grid's compact model.
        map_bytes = runtime.block_on(grid_map(&client, end))?;
    }
    let mut pooled: Vec<[Vec<f64>; 5]> = vec![Default::default(); served.len()];
    let mut grid_seconds = vec![(0usize, 0.0f64); served.len()];
    let phase = Duration::from_secs_f64(config.seconds);
    for _ in 0..config.rounds {
        for (k, s) in served.iter().enumerate() {
            let [quiet_predict, quiet_health, grid, health, predict] = &mut pooled[k];
            quiet_predict.extend(runtime.block_on(quiet(&s.base, Kind::Predict, end, phase))?);
            quiet_health.extend(runtime.block_on(quiet(&s.base, Kind::Health, end, phase))?);
            let loaded = runtime.block_on(loaded(&s.base, config.grid_clients, end, phase))?;
            grid_seconds[k].0 += loaded.0.len();
            grid_seconds[k].1 += loaded.3;
            grid.extend(loaded.0);
            health.extend(loaded.1);
            predict.extend(loaded.2);
        }
    }
    drop(served);
    let services = binaries
        .into_iter()
        .zip(pooled)
        .zip(grid_seconds)
        .map(|(((name, binary), lat), (maps, seconds))| {
            let [quiet_predict, quiet_health, grid, health, predict] = lat;
            ServiceLoad {
                name: name.into(),
                binary: binary.display().to_string(),
                quiet_predict: Percentiles::of(quiet_predict),
                quiet_health: Percentiles::of(quiet_health),
                loaded_grid: Percentiles::of(grid),
                loaded_health: Percentiles::of(health),
                loaded_predict: Percentiles::of(predict),
                grid_per_second: maps as f64 / seconds,
            }
        })
        .collect();
    Ok(GridLoadBench {
        cells: config.cells,
        changing_cells,
        map_bytes,
        grid_clients: config.grid_clients,
        seconds: config.seconds,
        rounds: config.rounds,
        threads,
        services,
    })
}

/// A kind of small request.
#[derive(Clone, Copy, Debug)]
enum Kind {
    Health,
    Predict,
}

/// One request of `kind` (a door prediction at a time after `end` that changes with `i`).
async fn small(client: &Client, kind: Kind, end: f64, i: usize) -> Result<(), GridLoadError> {
    let answer = async {
        match kind {
            Kind::Health => client.health().await.map(|_| ()),
            Kind::Predict => {
                let t = end + 600.0 * (i % 1008) as f64;
                client.predict("door", &[t], None).await.map(|_| ())
            }
        }
    };
    tokio::time::timeout(REQUEST_TIMEOUT, answer)
        .await
        .map_err(|_| GridLoadError::Timeout("a small request"))??;
    Ok(())
}

/// The grid's map at a time after `end` that changes with `i`; answers its bytes.
async fn grid_map(client: &Client, time: f64) -> Result<usize, GridLoadError> {
    let body = format!("{{\"time\":{time}}}").into_bytes();
    let (status, text) = tokio::time::timeout(
        REQUEST_TIMEOUT,
        client.raw(Method::POST, "/v1/grid/office/predict", body, None),
    )
    .await
    .map_err(|_| GridLoadError::Timeout("a grid map"))??;
    if status != StatusCode::OK {
        return Err(GridLoadError::Status {
            what: "POST /v1/grid/office/predict",
            status,
            text: text.chars().take(200).collect(),
        });
    }
    Ok(text.len())
}

/// [`QUIET_CLIENTS`] clients send `kind` back to back for `phase`; the latencies (µs).
async fn quiet(
    base: &str,
    kind: Kind,
    end: f64,
    phase: Duration,
) -> Result<Vec<f64>, GridLoadError> {
    let tasks: Vec<_> = (0..QUIET_CLIENTS)
        .map(|c| {
            let client = Client::new(base, None);
            tokio::spawn(async move {
                let client = client?;
                back_to_back(&client, kind, end, c * 7919, phase, None).await
            })
        })
        .collect();
    let mut all = Vec::new();
    for task in tasks {
        all.extend(task.await.map_err(|_| GridLoadError::Panicked)??);
    }
    Ok(all)
}

/// Requests of `kind` back to back for `phase` (or until `stop`), after [`WARM_UP`].
async fn back_to_back(
    client: &Client,
    kind: Kind,
    end: f64,
    seed: usize,
    phase: Duration,
    stop: Option<&AtomicBool>,
) -> Result<Vec<f64>, GridLoadError> {
    for i in 0..WARM_UP {
        small(client, kind, end, seed + i).await?;
    }
    let deadline = Instant::now() + phase;
    let mut latencies = Vec::new();
    let mut i = 0;
    while Instant::now() < deadline && !stop.is_some_and(|s| s.load(Ordering::Acquire)) {
        let t0 = Instant::now();
        small(client, kind, end, seed + WARM_UP + i).await?;
        latencies.push(t0.elapsed().as_secs_f64() * 1e6);
        i += 1;
    }
    Ok(latencies)
}

/// Latencies (µs) of the maps, the health checks and the door predictions of a loaded phase,
/// and the seconds the map clients ran.
type Loaded = (Vec<f64>, Vec<f64>, Vec<f64>, f64);

/// `grid_clients` clients ask for maps back to back while one client checks health and one
/// predicts the door, for `phase`.
async fn loaded(
    base: &str,
    grid_clients: usize,
    end: f64,
    phase: Duration,
) -> Result<Loaded, GridLoadError> {
    let stop = Arc::new(AtomicBool::new(false));
    let started = Arc::new(tokio::sync::Barrier::new(grid_clients + 1));
    let maps: Vec<_> = (0..grid_clients)
        .map(|c| {
            let (client, stop, started) = (
                Client::new(base, None),
                Arc::clone(&stop),
                Arc::clone(&started),
            );
            tokio::spawn(async move {
                let client = client?;
                let first = grid_map(&client, end + 3600.0 * c as f64).await;
                started.wait().await;
                first?;
                let mut latencies = Vec::new();
                let mut i = 0;
                while !stop.load(Ordering::Acquire) {
                    let t0 = Instant::now();
                    grid_map(&client, end + 600.0 * ((c * 131 + i) % 1008) as f64).await?;
                    latencies.push(t0.elapsed().as_secs_f64() * 1e6);
                    i += 1;
                }
                Ok::<_, GridLoadError>(latencies)
            })
        })
        .collect();
    // Every map client has its first answer and asks again: the load is on.
    started.wait().await;
    let t0 = Instant::now();
    let small_tasks: Vec<_> = [(Kind::Health, 0), (Kind::Predict, 1)]
        .into_iter()
        .map(|(kind, c)| {
            let (client, stop) = (Client::new(base, None), Arc::clone(&stop));
            tokio::spawn(async move {
                let client = client?;
                back_to_back(&client, kind, end, c * 7919, phase, Some(&stop)).await
            })
        })
        .collect();
    let mut small = Vec::new();
    for task in small_tasks {
        small.push(task.await.map_err(|_| GridLoadError::Panicked)?);
    }
    stop.store(true, Ordering::Release);
    let seconds = t0.elapsed().as_secs_f64();
    let mut grid = Vec::new();
    for task in maps {
        grid.extend(task.await.map_err(|_| GridLoadError::Panicked)??);
    }
    let predict = small.pop().expect("two")?;
    let health = small.pop().expect("two")?;
    Ok((grid, health, predict, seconds))
}

impl GridLoadBench {
    /// The result as `chronomap bench serve --grid-load` prints it.
    pub fn text(&self) -> String {
        let b = self;
        let mut text = String::new();
        let _ = writeln!(
            text,
            "chronomap serve in processes of their own on 127.0.0.1, in turns, {} rounds of {} s phases, {} hardware threads",
            b.rounds, b.seconds, b.threads
        );
        let _ = writeln!(
            text,
            "grid: synthetic office, {} cells ({} changing, kept with its learning state), a map is {:.2} MB of JSON; door: fremen:2 on the greg door",
            b.cells,
            b.changing_cells,
            b.map_bytes as f64 / 1e6
        );
        let _ = writeln!(
            text,
            "quiet: 4 clients back to back; loaded: {} clients ask for maps while 1 client checks health and 1 predicts the door\n",
            b.grid_clients
        );
        let mut table = Table::new([
            "service",
            "quiet predict p50 / p99 µs",
            "quiet health p50 / p99 µs",
            "loaded map p50 / p99 ms",
            "maps/s",
            "loaded health p50 / p99 µs",
            "loaded predict p50 / p99 µs",
        ]);
        let us = |p: &Percentiles| format!("{:.0} / {:.0}", p.p50_us, p.p99_us);
        for s in &b.services {
            table.row([
                s.name.clone(),
                us(&s.quiet_predict),
                us(&s.quiet_health),
                format!(
                    "{:.1} / {:.1}",
                    s.loaded_grid.p50_us / 1e3,
                    s.loaded_grid.p99_us / 1e3
                ),
                format!("{:.0}", s.grid_per_second),
                us(&s.loaded_health),
                us(&s.loaded_predict),
            ]);
        }
        let _ = writeln!(text, "{}", table.render());
        for (what, ratio) in b.ratios() {
            let _ = writeln!(text, "{what}: this build / baseline = {ratio:.2}");
        }
        if let Some(this) = b.services.last() {
            let _ = writeln!(
                text,
                "goal: door predict p99 < 1 ms (quiet): {} ({:.0} µs)",
                if this.quiet_predict.p99_us < 1000.0 {
                    "met"
                } else {
                    "missed"
                },
                this.quiet_predict.p99_us
            );
        }
        text
    }
}
