//! A bounded load generator against the service (`chronomap_serve`) on loopback, with the same
//! work done without the service in the same run as baselines.
//!
//! The service runs in this process on `127.0.0.1:0` with a redb store in a fresh directory
//! and a bearer token. Its models (the training door, shifted by one hour per model) are
//! preloaded through the API. Then concurrent clients, each with its own connection, time
//! health checks, predictions of one model at one time and at the next hours, and forecasts of
//! many models at one time; the baselines are the same predictions computed in-process on
//! equivalent models (`in_process`), and the health round trip. Then the same clients send
//! batched observations (`POST /v1/observations`, each request one durable commit,
//! acknowledged after redb's fsync); the baselines are the pieces of that work alone, on one
//! thread (`write_baselines`): parsing the same request bodies, applying the same
//! observations to in-process models, encoding them as log groups, and appending groups of the
//! same size to a redb store, one transaction per request.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use chronomap_app::report::Table;
use chronomap_client::{Client, ClientError, Method, StatusCode};
use chronomap_core::TemporalModel;
use chronomap_core::TimeSeries;
use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_serve::api::{AddValuesRequest, ForecastRequest, ObservationsRequest, WriteAck};
use chronomap_serve::log::{LogRecord, encode_group};
use chronomap_serve::registry::{Entry, ModelConfig, Registry};
use chronomap_serve::store::{RedbStore, Store, StoreError};
use chronomap_serve::{Service, ServiceConfig};
use serde::{Serialize, Serializer};
use thiserror::Error;

/// Untimed requests per client before each latency test.
pub const WARM_UP: usize = 20;
/// Goal for the p99 latency of a one-time prediction (µs).
pub const GOAL_P99_US: f64 = 1_000.0;
/// Goal for durable observations per second in batches.
pub const GOAL_OBSERVATIONS_PER_SECOND: f64 = 1e6;
/// Most observations the write baselines redo (a prefix of what the clients sent).
const BASELINE_OBSERVATIONS: u64 = 2_000_000;
/// Time limit of each write baseline.
const BASELINE_SECONDS: f64 = 5.0;
/// Longest wait for one answer of the service (the benchmark ends with an error instead).
const REQUEST_TIMEOUT: Duration = Duration::from_secs(60);

/// The load: models, clients, requests and batches.
#[derive(Clone, Debug, PartialEq)]
pub struct ServeBenchConfig {
    /// Models served (each is the training door, shifted by one hour per model).
    pub models: usize,
    /// Spec of the models (e.g. `fremen:2`).
    pub model: String,
    /// Observations added to each model through the API before the latency test.
    pub preload: usize,
    /// Concurrent clients, each with its own connection.
    pub clients: usize,
    /// Timed requests per client and kind of request (after [`WARM_UP`] untimed ones).
    pub requests: usize,
    /// Time limit per kind of request of the latency test (s).
    pub latency_seconds: f64,
    /// Times per request of the second predict test (the next hours).
    pub predict_times: usize,
    /// Models per forecast request (at most `models`).
    pub forecast_ids: usize,
    /// Observations of the durable-throughput test, in all.
    pub observations: u64,
    /// Observations per request (`POST /v1/observations`, one durable commit).
    pub batch: usize,
    /// Models per request (the batch is split evenly among them).
    pub batch_ids: usize,
    /// Time limit of the durable-throughput test (s).
    pub seconds: f64,
    /// Keep the service's store in this (new or empty) directory instead of a temporary one.
    pub data: Option<PathBuf>,
}

impl ServeBenchConfig {
    /// Checks every field; [`run`] does too.
    ///
    /// # Errors
    /// [`ServeBenchError::Config`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), ServeBenchError> {
        let checks: [(bool, &'static str, &'static str); 9] = [
            (self.models >= 1, "models", "at least 1 model"),
            (self.clients >= 1, "clients", "at least 1 client"),
            (
                self.preload >= 1,
                "preload",
                "every model needs observations to predict from",
            ),
            (self.batch >= 1, "batch", "at least 1 observation a request"),
            (self.observations >= 1, "observations", "at least 1"),
            (
                self.batch_ids >= 1,
                "batch_ids",
                "at least 1 model a request",
            ),
            (self.predict_times >= 1, "predict_times", "at least 1 time"),
            (
                self.latency_seconds > 0.0,
                "latency_seconds",
                "must be positive",
            ),
            (self.seconds > 0.0, "seconds", "must be positive"),
        ];
        match checks.into_iter().find(|(ok, ..)| !ok) {
            Some((_, field, message)) => Err(ServeBenchError::Config { field, message }),
            None => Ok(()),
        }
    }
}

/// Why the benchmark could not run.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ServeBenchError {
    /// A field of [`ServeBenchConfig`] is out of range.
    #[error("{field}: {message}")]
    Config {
        /// The field.
        field: &'static str,
        /// What it must be.
        message: &'static str,
    },
    /// The model spec is not one the service knows.
    #[error("model {spec}: {message}")]
    Model {
        /// The spec.
        spec: String,
        /// What is wrong with it.
        message: String,
    },
    /// The training data are too short to replay.
    #[error("the training data needs at least 2 observations, not {count}")]
    TooFewObservations {
        /// Observations given.
        count: usize,
    },
    /// The data directory could not be created or read.
    #[error("cannot create or read {}", path.display())]
    DataDir {
        /// The directory.
        path: PathBuf,
        /// What went wrong.
        source: std::io::Error,
    },
    /// The data directory holds files already.
    #[error("{} is not empty; the benchmark needs a new or empty directory", path.display())]
    NotEmpty {
        /// The directory.
        path: PathBuf,
    },
    /// A file of the baselines could not be removed.
    #[error("cannot remove {}", path.display())]
    Remove {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        source: std::io::Error,
    },
    /// The system gave no random numbers for the token.
    #[error("no random numbers for a token: {0}")]
    Token(getrandom::Error),
    /// An async runtime could not be started.
    #[error("cannot start the {what} async runtime")]
    Runtime {
        /// Whose: the service's or the clients'.
        what: &'static str,
        /// What went wrong.
        source: std::io::Error,
    },
    /// The service cannot listen on loopback.
    #[error("cannot listen on 127.0.0.1")]
    Listen(#[source] std::io::Error),
    /// The store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// The service could not start.
    #[error("the service cannot start: {0}")]
    Start(String),
    /// The service stopped with an error.
    #[error("the service failed")]
    Service(#[source] std::io::Error),
    /// A task of the service or of a client panicked.
    #[error("a {0} task panicked")]
    Panicked(&'static str),
    /// A request failed.
    #[error(transparent)]
    Client(#[from] ClientError),
    /// The service did not answer within the request timeout (60 s).
    #[error("{what}: no answer")]
    Timeout {
        /// The request.
        what: String,
    },
    /// A batch of observations was rejected.
    #[error("POST /v1/observations: {status}: {text}")]
    Rejected {
        /// The HTTP status.
        status: StatusCode,
        /// The service's answer.
        text: String,
    },
    /// A request body could not be encoded or an answer parsed.
    #[error("JSON")]
    Json(#[from] serde_json::Error),
    /// The service acknowledged a different number of observations than sent.
    #[error("{acknowledged} of {sent} observations acknowledged")]
    Acknowledged {
        /// Acknowledged.
        acknowledged: u64,
        /// Sent.
        sent: u64,
    },
    /// The service answered with the wrong number of values.
    #[error("the service answered {what} with the wrong number of values")]
    WrongLength {
        /// The request.
        what: String,
    },
    /// No request of a kind finished within the latency test's time limit.
    #[error("no {what} request finished in time")]
    NoRequest {
        /// The kind of request.
        what: String,
    },
    /// The preload did not get every observation acknowledged.
    #[error("the preload stopped after {sent} of {expected} observations")]
    PreloadStopped {
        /// Acknowledged.
        sent: u64,
        /// Meant.
        expected: u64,
    },
    /// An in-process model could not take or answer what the service's did.
    #[error("in-process model {id}: {message}")]
    InProcess {
        /// The model.
        id: String,
        /// What went wrong.
        message: String,
    },
}

/// Runs the benchmark, replaying `train` (at least 2 observations) as the door of every model.
///
/// # Errors
/// A field of `config` out of range, a data directory that is not new or empty, and any
/// failure of the service, its store or a request.
pub fn run(config: &ServeBenchConfig, train: TimeSeries) -> Result<ServeBench, ServeBenchError> {
    config.validate()?;
    let model_config = ModelConfig::parse(Some(&config.model), None).map_err(|message| {
        ServeBenchError::Model {
            spec: config.model.clone(),
            message,
        }
    })?;
    let door = Door::new(train)?;
    let forecast_ids = config.forecast_ids.clamp(1, config.models);
    let writers = config.clients.min(config.models);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let ids: Vec<String> = (0..config.models).map(|i| format!("door-{i:05}")).collect();

    let dir = DataDir::new(config.data.as_deref())?;
    let store = RedbStore::open(dir.path.join("chronomap.redb"))?;
    let token = random_token()?;
    let service = Service::start(
        Arc::new(store),
        ServiceConfig {
            token: Some(token.clone()),
            ..ServiceConfig::default()
        },
    )
    .map_err(ServeBenchError::Start)?;
    let server = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .thread_name("bench-server")
        .build()
        .map_err(|source| ServeBenchError::Runtime {
            what: "service's",
            source,
        })?;
    let listener = server
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .map_err(ServeBenchError::Listen)?;
    let address = listener.local_addr().map_err(ServeBenchError::Listen)?;
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let running = server.spawn(service.run(listener, async {
        let _ = stopped.await;
    }));
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(config.clients.min(threads))
        .enable_all()
        .thread_name("bench-client")
        .build()
        .map_err(|source| ServeBenchError::Runtime {
            what: "clients'",
            source,
        })?;
    let base = format!("http://{address}");
    let clients = (0..config.clients)
        .map(|_| Client::new(&base, Some(token.clone())))
        .collect::<Result<Vec<_>, _>>()?;

    // Streams of observations: model i replays the door shifted by i hours (mod 24).
    let mut streams: Vec<Stream> = (0..config.models)
        .map(|i| Stream {
            cursor: 0,
            offset: 3600.0 * (i % 24) as f64,
        })
        .collect();
    let owned: Vec<Vec<usize>> = (0..writers)
        .map(|w| (w..config.models).step_by(writers).collect())
        .collect();

    // Preload through the API, and the same observations into in-process models.
    let started = Instant::now();
    let preload_bodies: Vec<Vec<Body>> = owned
        .iter()
        .map(|own| preload_bodies(&door, &mut streams, &ids, own, config, &model_config))
        .collect::<Result<_, _>>()?;
    let preload_encode_seconds = started.elapsed().as_secs_f64();
    let preload = runtime.block_on(send_all(
        &clients,
        &token,
        preload_bodies,
        Duration::from_secs(86_400),
    ))?;
    let expected = (config.models * config.preload) as u64;
    if preload.observations != expected {
        return Err(ServeBenchError::PreloadStopped {
            sent: preload.observations,
            expected,
        });
    }
    let mut local = Registry::new();
    let mut replay: Vec<Stream> = (0..config.models)
        .map(|i| Stream {
            cursor: 0,
            offset: 3600.0 * (i % 24) as f64,
        })
        .collect();
    let started = Instant::now();
    let (mut times, mut values) = (Vec::new(), Vec::new());
    for (id, stream) in ids.iter().zip(&mut replay) {
        let in_process_error = |message: String| ServeBenchError::InProcess {
            id: id.clone(),
            message,
        };
        let mut entry = Entry::new(model_config.clone()).map_err(in_process_error)?;
        times.clear();
        values.clear();
        door.take(stream, config.preload, &mut times, &mut values);
        entry
            .observe(id, &times, &values)
            .map_err(|e| in_process_error(e.to_string()))?;
        local.put(id.clone(), Some(entry));
    }
    let preload_in_process = started.elapsed().as_secs_f64();

    // Latency.
    let end = replay
        .iter()
        .map(|s| s.last_time(&door))
        .fold(0.0, f64::max);
    let mut rng = Xoshiro256StarStar::seed_from_u64(2016);
    let queries = Arc::new(Queries {
        ids: ids.clone(),
        times: (0..4096)
            .map(|_| end + rng.uniform(0.0, 7.0 * 86_400.0))
            .collect(),
        forecast_ids,
    });
    let mut probes = vec![Probe::Health, Probe::Predict(1)];
    if config.predict_times > 1 {
        probes.push(Probe::Predict(config.predict_times));
    }
    probes.push(Probe::Forecast);
    let mut measured = Vec::with_capacity(probes.len());
    for probe in probes {
        let latencies = runtime.block_on(measure(
            &clients,
            &queries,
            probe,
            config.requests,
            Duration::from_secs_f64(config.latency_seconds),
        ))?;
        let in_process_ns = match probe {
            Probe::Health => None,
            _ => Some(in_process(&local, &queries, probe)?),
        };
        measured.push((probe, latencies, in_process_ns));
    }

    // Durable throughput.
    let requests_total = config.observations.div_ceil(config.batch as u64) as usize;
    let started = Instant::now();
    let bodies: Vec<Vec<Body>> = owned
        .iter()
        .enumerate()
        .map(|(w, own)| {
            let requests = requests_total / writers + usize::from(w < requests_total % writers);
            throughput_bodies(&door, &mut streams, &ids, own, config, requests)
        })
        .collect::<Result<_, _>>()?;
    let encode_seconds = started.elapsed().as_secs_f64();
    let prepared: u64 = bodies.iter().flatten().map(|b| b.observations).sum();
    let body_bytes: usize = bodies.iter().flatten().map(|b| b.bytes.len()).sum();
    let seq_before = runtime.block_on(clients[0].health())?.seq;
    let sent = runtime.block_on(send_all(
        &clients,
        &token,
        bodies,
        Duration::from_secs_f64(config.seconds),
    ))?;
    let seq_after = runtime.block_on(clients[0].health())?.seq;
    let durable_rate = sent.observations as f64 / sent.seconds;

    drop(clients);
    drop(runtime);
    let _ = stop.send(());
    server
        .block_on(running)
        .map_err(|_| ServeBenchError::Panicked("service"))?
        .map_err(ServeBenchError::Service)?;
    drop(server);

    let baselines = write_baselines(&sent.bodies, &mut local, &dir.path)?;
    let kept = dir.keep.then(|| dir.path.clone());
    drop(dir);

    // The report.
    let health_p50 = measured
        .iter()
        .find(|(p, ..)| matches!(p, Probe::Health))
        .map_or(f64::NAN, |(_, l, _)| l.p50_us);
    let latency: Vec<LatencyBench> = measured
        .into_iter()
        .map(|(probe, l, in_process_ns)| LatencyBench {
            key: probe.key(forecast_ids),
            request: probe.describe(forecast_ids),
            requests: l.requests,
            seconds: l.seconds,
            p50_us: l.p50_us,
            p99_us: l.p99_us,
            max_us: l.max_us,
            requests_per_second: l.requests as f64 / l.seconds,
            in_process_ns,
            ratio_p50_to_in_process: in_process_ns.map(|ns| l.p50_us * 1e3 / ns),
            ratio_p50_to_health: in_process_ns.map(|_| l.p50_us / health_p50),
        })
        .collect();
    let predict_p99 = latency
        .iter()
        .find(|l| l.key == Probe::Predict(1).key(forecast_ids))
        .map_or(f64::NAN, |l| l.p99_us);
    // Observations/s of the baselines' pieces one after the other on one thread.
    let pipeline_rate = 1.0
        / baselines
            .iter()
            .map(|b| 1.0 / b.observations_per_second)
            .sum::<f64>();
    let baselines = baselines
        .into_iter()
        .map(|b| BaselineBench {
            ratio_service_to_baseline: durable_rate / b.observations_per_second,
            ..b
        })
        .collect();
    Ok(ServeBench {
        models: config.models,
        model: config.model.clone(),
        clients: config.clients,
        threads,
        preload: PreloadBench {
            observations: preload.observations,
            requests: preload.requests,
            seconds: preload.seconds,
            observations_per_second: preload.observations as f64 / preload.seconds,
            in_process_seconds: preload_in_process,
            client_encode_seconds: preload_encode_seconds,
        },
        latency,
        throughput: ThroughputBench {
            observations: sent.observations,
            requests: sent.requests,
            writers,
            batch: config.batch,
            batch_ids: config.batch_ids,
            commits: seq_after - seq_before,
            seconds: sent.seconds,
            observations_per_second: durable_rate,
            prepared_observations: prepared,
            body_bytes,
            client_encode_seconds: encode_seconds,
            baselines,
            baseline_pipeline_observations_per_second: pipeline_rate,
            ratio_service_to_pipeline: durable_rate / pipeline_rate,
        },
        goals: Goals {
            predict_p99_under_1ms: predict_p99 < GOAL_P99_US,
            durable_1m_observations_per_second: durable_rate >= GOAL_OBSERVATIONS_PER_SECOND,
        },
        data: kept.map(|p| p.display().to_string()),
    })
}

// ---------------------------------------------------------------------------------------------
// The report

/// Serializes items with a `key` as a map from key to item.
fn by_key<S: Serializer, T: Serialize + Keyed>(items: &[T], s: S) -> Result<S::Ok, S::Error> {
    s.collect_map(items.iter().map(|item| (item.key(), item)))
}

/// An item of a list reported as a map.
trait Keyed {
    fn key(&self) -> &str;
}

/// The benchmark's measurements.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ServeBench {
    /// Models served.
    pub models: usize,
    /// Their spec.
    pub model: String,
    /// Concurrent clients.
    pub clients: usize,
    /// Hardware threads of the machine.
    pub threads: usize,
    /// The preload through the API.
    pub preload: PreloadBench,
    /// One kind of request each, in the order measured (a map by its `key` in
    /// JSON).
    #[serde(serialize_with = "by_key")]
    pub latency: Vec<LatencyBench>,
    /// The durable-throughput test.
    pub throughput: ThroughputBench,
    /// Whether the goals are met.
    pub goals: Goals,
    /// The directory the store was kept in, if any.
    pub data: Option<String>,
}

impl ServeBench {
    /// The p99 latency (µs) of a one-time prediction (NaN if not measured).
    pub fn predict_p99_us(&self) -> f64 {
        self.latency
            .iter()
            .find(|l| l.key == "predict_1")
            .map_or(f64::NAN, |l| l.p99_us)
    }
}

/// The preload: every model's first observations, through the API.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PreloadBench {
    /// Observations acknowledged.
    pub observations: u64,
    /// Requests sent.
    pub requests: usize,
    /// Seconds until the last acknowledgement.
    pub seconds: f64,
    /// `observations / seconds`.
    pub observations_per_second: f64,
    /// Seconds of the same observations applied to in-process models.
    pub in_process_seconds: f64,
    /// Seconds of encoding the request bodies (before the clock of `seconds` starts).
    pub client_encode_seconds: f64,
}

/// The latencies of one kind of request from every client.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LatencyBench {
    /// Its key in JSON: `health`, `predict_K`, `forecast_N`.
    #[serde(skip)]
    pub key: String,
    /// What it asks, in words.
    #[serde(skip)]
    pub request: String,
    /// Requests timed, all clients together.
    pub requests: usize,
    /// Seconds from the first client's start to the last one's end.
    pub seconds: f64,
    /// Median latency (µs).
    pub p50_us: f64,
    /// 99th percentile (µs).
    pub p99_us: f64,
    /// Largest (µs).
    pub max_us: f64,
    /// `requests / seconds`.
    pub requests_per_second: f64,
    /// Mean nanoseconds of the same request computed in-process (`in_process`); none for
    /// the health check.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub in_process_ns: Option<f64>,
    /// `p50 / in-process`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ratio_p50_to_in_process: Option<f64>,
    /// `p50 / p50 of the health check`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ratio_p50_to_health: Option<f64>,
}

impl Keyed for LatencyBench {
    fn key(&self) -> &str {
        &self.key
    }
}

/// The durable-throughput test.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ThroughputBench {
    /// Observations acknowledged.
    pub observations: u64,
    /// Requests acknowledged.
    pub requests: usize,
    /// Clients that sent (at most one per model).
    pub writers: usize,
    /// Observations per request.
    pub batch: usize,
    /// Models per request.
    pub batch_ids: usize,
    /// Commit groups of the service's log over the test.
    pub commits: u64,
    /// Seconds until the last acknowledgement.
    pub seconds: f64,
    /// `observations / seconds`: durable observations per second.
    pub observations_per_second: f64,
    /// Observations prepared (more than acknowledged when the time limit stopped the test).
    pub prepared_observations: u64,
    /// Bytes of the request bodies prepared.
    pub body_bytes: usize,
    /// Seconds of encoding them (before the clock starts).
    pub client_encode_seconds: f64,
    /// The pieces of the write path alone, on one thread (`write_baselines`; a map by
    /// its `key` in JSON).
    #[serde(serialize_with = "by_key")]
    pub baselines: Vec<BaselineBench>,
    /// Observations/s of the pieces one after the other on one thread.
    pub baseline_pipeline_observations_per_second: f64,
    /// `observations_per_second / baseline_pipeline_observations_per_second`.
    pub ratio_service_to_pipeline: f64,
}

/// One piece of the write path, alone on one thread.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BaselineBench {
    /// Its key in JSON.
    #[serde(skip)]
    pub key: &'static str,
    /// What it does, in words.
    #[serde(skip)]
    pub what: &'static str,
    /// Observations done.
    pub observations: u64,
    /// Seconds taken.
    pub seconds: f64,
    /// `observations / seconds`.
    pub observations_per_second: f64,
    /// The service's durable rate over this one's.
    pub ratio_service_to_baseline: f64,
}

impl Keyed for BaselineBench {
    fn key(&self) -> &str {
        self.key
    }
}

/// Whether the goals are met.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Goals {
    /// p99 of a one-time prediction under [`GOAL_P99_US`].
    pub predict_p99_under_1ms: bool,
    /// At least [`GOAL_OBSERVATIONS_PER_SECOND`] durable observations per second.
    pub durable_1m_observations_per_second: bool,
}

// ---------------------------------------------------------------------------------------------
// Data

/// The training door, replayed as often as needed.
struct Door {
    times: Vec<f64>,
    values: Vec<f64>,
    /// Time from one replay to the next: the span plus one sampling step.
    cycle: f64,
}

impl Door {
    fn new(series: TimeSeries) -> Result<Self, ServeBenchError> {
        if series.len() < 2 {
            return Err(ServeBenchError::TooFewObservations {
                count: series.len(),
            });
        }
        let step = series
            .times
            .windows(2)
            .map(|w| w[1] - w[0])
            .find(|&d| d > 0.0)
            .unwrap_or(1.0);
        let cycle = series.times[series.len() - 1] - series.times[0] + step;
        Ok(Door {
            times: series.times,
            values: series.values,
            cycle,
        })
    }

    /// Appends the next `n` observations of `stream`.
    fn take(&self, stream: &mut Stream, n: usize, times: &mut Vec<f64>, values: &mut Vec<f64>) {
        for _ in 0..n {
            times.push(self.times[stream.cursor] + stream.offset);
            values.push(self.values[stream.cursor]);
            stream.cursor += 1;
            if stream.cursor == self.times.len() {
                stream.cursor = 0;
                stream.offset += self.cycle;
            }
        }
    }
}

/// Where one model is in its replay of the door.
#[derive(Clone, Copy)]
struct Stream {
    cursor: usize,
    offset: f64,
}

impl Stream {
    /// Time of the last observation taken (after at least one).
    fn last_time(&self, door: &Door) -> f64 {
        match self.cursor {
            0 => door.times[door.times.len() - 1] + self.offset - door.cycle,
            c => door.times[c - 1] + self.offset,
        }
    }
}

/// One `POST /v1/observations` body.
struct Body {
    bytes: Vec<u8>,
    observations: u64,
}

/// A body adding `counts[j]` observations to model `group[j]`.
fn body(
    door: &Door,
    streams: &mut [Stream],
    ids: &[String],
    group: &[usize],
    counts: &[usize],
    model: Option<&str>,
) -> Result<Body, ServeBenchError> {
    let mut batches = Vec::with_capacity(group.len());
    for (&i, &n) in group.iter().zip(counts) {
        let (mut times, mut values) = (Vec::with_capacity(n), Vec::with_capacity(n));
        door.take(&mut streams[i], n, &mut times, &mut values);
        batches.push(AddValuesRequest {
            id: ids[i].clone(),
            times,
            values,
            model: model.map(str::to_owned),
        });
    }
    let observations = counts.iter().sum::<usize>() as u64;
    let bytes = serde_json::to_vec(&ObservationsRequest { batches })?;
    Ok(Body {
        bytes,
        observations,
    })
}

/// `batch` observations split over `n` models, the remainder to the first.
fn split(batch: usize, n: usize) -> Vec<usize> {
    (0..n)
        .map(|j| batch / n + usize::from(j < batch % n))
        .collect()
}

/// One writer's preload: its models in groups of `batch_ids`, `preload` observations each,
/// the first request of a group creating its models.
fn preload_bodies(
    door: &Door,
    streams: &mut [Stream],
    ids: &[String],
    own: &[usize],
    config: &ServeBenchConfig,
    model_config: &ModelConfig,
) -> Result<Vec<Body>, ServeBenchError> {
    let spec = model_config.spec.to_string();
    let mut bodies = Vec::new();
    for group in own.chunks(config.batch_ids) {
        let chunk = (config.batch / group.len()).max(1);
        let mut done = 0;
        while done < config.preload {
            let n = chunk.min(config.preload - done);
            let model = (done == 0).then_some(spec.as_str());
            bodies.push(body(
                door,
                streams,
                ids,
                group,
                &vec![n; group.len()],
                model,
            )?);
            done += n;
        }
    }
    Ok(bodies)
}

/// One writer's share of the throughput test: `requests` bodies of `batch` observations,
/// cycling through its models in groups of `batch_ids`.
fn throughput_bodies(
    door: &Door,
    streams: &mut [Stream],
    ids: &[String],
    own: &[usize],
    config: &ServeBenchConfig,
    requests: usize,
) -> Result<Vec<Body>, ServeBenchError> {
    let groups: Vec<&[usize]> = own.chunks(config.batch_ids).collect();
    (0..requests)
        .map(|r| {
            let group = groups[r % groups.len()];
            let counts = split(config.batch, group.len());
            body(door, streams, ids, group, &counts, None)
        })
        .collect()
}

/// The service's data directory: `data` (kept) or a temporary one (removed when dropped).
struct DataDir {
    path: PathBuf,
    keep: bool,
}

impl DataDir {
    fn new(data: Option<&Path>) -> Result<Self, ServeBenchError> {
        let (path, keep) = match data {
            Some(path) => (path.to_path_buf(), true),
            None => {
                let nanos = SystemTime::now()
                    .duration_since(UNIX_EPOCH)
                    .map_or(0, |d| d.as_nanos());
                let name = format!("chronomap-bench-serve-{}-{nanos}", std::process::id());
                (std::env::temp_dir().join(name), false)
            }
        };
        let io_error = |source| ServeBenchError::DataDir {
            path: path.clone(),
            source,
        };
        std::fs::create_dir_all(&path).map_err(io_error)?;
        let occupied = std::fs::read_dir(&path).map_err(io_error)?.next().is_some();
        if occupied {
            return Err(ServeBenchError::NotEmpty { path });
        }
        Ok(DataDir { path, keep })
    }
}

impl Drop for DataDir {
    fn drop(&mut self) {
        if !self.keep {
            let _ = std::fs::remove_dir_all(&self.path);
        }
    }
}

fn random_token() -> Result<String, ServeBenchError> {
    let mut bytes = [0u8; 24];
    getrandom::fill(&mut bytes).map_err(ServeBenchError::Token)?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

// ---------------------------------------------------------------------------------------------
// Latency

/// One kind of request.
#[derive(Clone, Copy, Debug)]
enum Probe {
    /// `GET /v1/health`: the bare round trip.
    Health,
    /// `POST /v1/predict`: one model at this many times (the next hours from a random time).
    Predict(usize),
    /// `POST /v1/forecast`: the first `forecast_ids` models at one random time.
    Forecast,
}

impl Probe {
    /// Its key in JSON (`forecast_ids`: models per forecast).
    fn key(self, forecast_ids: usize) -> String {
        match self {
            Probe::Health => "health".into(),
            Probe::Predict(k) => format!("predict_{k}"),
            Probe::Forecast => format!("forecast_{forecast_ids}"),
        }
    }

    fn describe(self, forecast_ids: usize) -> String {
        match self {
            Probe::Health => "GET /v1/health".into(),
            Probe::Predict(1) => "predict, 1 model, 1 time".into(),
            Probe::Predict(k) => format!("predict, 1 model, {k} times"),
            Probe::Forecast => format!("forecast, {forecast_ids} models, 1 time"),
        }
    }
}

/// What the latency tests ask.
struct Queries {
    ids: Vec<String>,
    times: Vec<f64>,
    forecast_ids: usize,
}

impl Queries {
    /// Model and times of request `i` of client `c`.
    fn predict(&self, c: usize, i: usize, k: usize) -> (&str, Vec<f64>) {
        let id = &self.ids[(c * 7919 + i) % self.ids.len()];
        let t0 = self.times[(c * 1031 + i) % self.times.len()];
        (id, (0..k).map(|h| t0 + 3600.0 * h as f64).collect())
    }

    fn forecast_time(&self, c: usize, i: usize) -> f64 {
        self.times[(c * 1031 + i) % self.times.len()]
    }
}

/// Latencies of one kind of request from every client.
struct Latencies {
    requests: usize,
    seconds: f64,
    p50_us: f64,
    p99_us: f64,
    max_us: f64,
}

/// Request `i` of client `c` (`forecast`: the forecast request, its time set here).
async fn call(
    client: &Client,
    queries: &Queries,
    forecast: &mut ForecastRequest,
    probe: Probe,
    c: usize,
    i: usize,
) -> Result<(), ServeBenchError> {
    let answer = async {
        Ok::<_, ServeBenchError>(match probe {
            Probe::Health => {
                client.health().await?;
                true
            }
            Probe::Predict(k) => {
                let (id, times) = queries.predict(c, i, k);
                client.predict(id, &times, None).await?.values.len() == k
            }
            Probe::Forecast => {
                forecast.time = queries.forecast_time(c, i);
                client.forecast(forecast).await?.values.len() == forecast.ids.len()
            }
        })
    };
    let right_length = tokio::time::timeout(REQUEST_TIMEOUT, answer)
        .await
        .map_err(|_| ServeBenchError::Timeout {
            what: format!("{probe:?}"),
        })??;
    if !right_length {
        return Err(ServeBenchError::WrongLength {
            what: format!("{probe:?}"),
        });
    }
    Ok(())
}

/// Every client sends `requests` requests of one kind back to back (after a warm-up, all
/// starting together) or until `limit` has passed.
async fn measure(
    clients: &[Client],
    queries: &Arc<Queries>,
    probe: Probe,
    requests: usize,
    limit: Duration,
) -> Result<Latencies, ServeBenchError> {
    let barrier = Arc::new(tokio::sync::Barrier::new(clients.len()));
    let tasks: Vec<_> = clients
        .iter()
        .enumerate()
        .map(|(c, client)| {
            let (client, queries, barrier) =
                (client.clone(), Arc::clone(queries), Arc::clone(&barrier));
            tokio::spawn(async move {
                let mut forecast = ForecastRequest {
                    ids: queries.ids[..queries.forecast_ids].to_vec(),
                    time: 0.0,
                    order: None,
                    orders: None,
                };
                let mut warm_up = Ok(());
                for i in 0..WARM_UP {
                    warm_up = call(&client, &queries, &mut forecast, probe, c, requests + i).await;
                    if warm_up.is_err() {
                        break;
                    }
                }
                // Every client reaches the barrier, or the others would wait for ever.
                barrier.wait().await;
                warm_up?;
                let start = Instant::now();
                let deadline = start + limit;
                let mut latencies = Vec::with_capacity(requests);
                for i in 0..requests {
                    let t0 = Instant::now();
                    if t0 >= deadline {
                        break;
                    }
                    call(&client, &queries, &mut forecast, probe, c, i).await?;
                    latencies.push(t0.elapsed().as_secs_f64() * 1e6);
                }
                Ok::<_, ServeBenchError>((start, Instant::now(), latencies))
            })
        })
        .collect();
    let mut all = Vec::new();
    let (mut first, mut last) = (None::<Instant>, None::<Instant>);
    for task in tasks {
        let (start, end, latencies) = task
            .await
            .map_err(|_| ServeBenchError::Panicked("client"))??;
        first = Some(first.map_or(start, |f| f.min(start)));
        last = Some(last.map_or(end, |l| l.max(end)));
        all.extend(latencies);
    }
    if all.is_empty() {
        return Err(ServeBenchError::NoRequest {
            what: format!("{probe:?}"),
        });
    }
    all.sort_by(f64::total_cmp);
    let rank = |q: f64| all[((q * all.len() as f64).ceil() as usize).clamp(1, all.len()) - 1];
    let seconds = match (first, last) {
        (Some(f), Some(l)) => (l - f).as_secs_f64(),
        _ => f64::NAN,
    };
    Ok(Latencies {
        requests: all.len(),
        seconds,
        p50_us: rank(0.5),
        p99_us: rank(0.99),
        max_us: all[all.len() - 1],
    })
}

/// The baseline of the latency of predict and forecast: mean time (ns) of the same request
/// computed in-process on equivalent models, as the service's handler computes it (look-up by
/// id, model at its order, predictions).
fn in_process(local: &Registry, queries: &Queries, probe: Probe) -> Result<f64, ServeBenchError> {
    let model = |id: &str| {
        let missing = |message: String| ServeBenchError::InProcess {
            id: id.to_owned(),
            message,
        };
        local
            .get(id)
            .ok_or_else(|| missing("not loaded".into()))?
            .with_order(None)
            .map_err(missing)
    };
    let once = |i: usize| -> Result<f64, ServeBenchError> {
        Ok(match probe {
            Probe::Health => 0.0,
            Probe::Predict(k) => {
                let (id, times) = queries.predict(0, i, k);
                model(id)?.predict_many(&times).iter().sum()
            }
            Probe::Forecast => {
                let time = queries.forecast_time(0, i);
                let mut sum = 0.0;
                for id in &queries.ids[..queries.forecast_ids] {
                    sum += model(id)?.predict(time);
                }
                sum
            }
        })
    };
    for i in 0..1000 {
        std::hint::black_box(once(i)?);
    }
    let started = Instant::now();
    let mut calls = 0;
    while calls < 1000 || started.elapsed() < Duration::from_millis(200) {
        for _ in 0..100 {
            std::hint::black_box(once(calls)?);
            calls += 1;
        }
    }
    Ok(started.elapsed().as_secs_f64() * 1e9 / calls as f64)
}

// ---------------------------------------------------------------------------------------------
// Durable throughput

/// What the clients got acknowledged.
struct Sent {
    observations: u64,
    requests: usize,
    seconds: f64,
    /// The bodies acknowledged, in the order sent (round robin over the clients).
    bodies: Vec<Body>,
}

/// Every client sends its bodies back to back until they are all acknowledged or `limit` has
/// passed; each must be acknowledged with its number of observations.
async fn send_all(
    clients: &[Client],
    token: &str,
    bodies: Vec<Vec<Body>>,
    limit: Duration,
) -> Result<Sent, ServeBenchError> {
    let started = Instant::now();
    let deadline = started + limit;
    let tasks: Vec<_> = clients
        .iter()
        .zip(bodies)
        .map(|(client, bodies)| {
            let (client, token) = (client.clone(), token.to_owned());
            tokio::spawn(async move {
                let mut acknowledged = Vec::with_capacity(bodies.len());
                let mut last = Instant::now();
                for body in bodies {
                    if Instant::now() >= deadline {
                        break;
                    }
                    let request = client.raw(
                        Method::POST,
                        "/v1/observations",
                        body.bytes.clone(),
                        Some(&token),
                    );
                    let (status, text) = tokio::time::timeout(REQUEST_TIMEOUT, request)
                        .await
                        .map_err(|_| ServeBenchError::Timeout {
                            what: "POST /v1/observations".into(),
                        })??;
                    if status != StatusCode::OK {
                        return Err(ServeBenchError::Rejected { status, text });
                    }
                    let ack: WriteAck = serde_json::from_str(&text)?;
                    if ack.observations != body.observations {
                        return Err(ServeBenchError::Acknowledged {
                            acknowledged: ack.observations,
                            sent: body.observations,
                        });
                    }
                    last = Instant::now();
                    acknowledged.push(body);
                }
                Ok::<_, ServeBenchError>((last, acknowledged))
            })
        })
        .collect();
    let mut per_client = Vec::with_capacity(tasks.len());
    let mut last = started;
    for task in tasks {
        let (end, acknowledged) = task
            .await
            .map_err(|_| ServeBenchError::Panicked("client"))??;
        last = last.max(end);
        per_client.push(acknowledged.into_iter());
    }
    let mut bodies = Vec::new();
    loop {
        let before = bodies.len();
        bodies.extend(per_client.iter_mut().filter_map(Iterator::next));
        if bodies.len() == before {
            break;
        }
    }
    Ok(Sent {
        observations: bodies.iter().map(|b| b.observations).sum(),
        requests: bodies.len(),
        seconds: (last - started).as_secs_f64(),
        bodies,
    })
}

/// One baseline: observations done and seconds taken (the ratio to the service is set once
/// the service's rate is known).
fn baseline(
    key: &'static str,
    what: &'static str,
    observations: u64,
    seconds: f64,
) -> BaselineBench {
    BaselineBench {
        key,
        what,
        observations,
        seconds,
        observations_per_second: observations as f64 / seconds,
        ratio_service_to_baseline: f64::NAN,
    }
}

/// The baselines of the durable-throughput test: the write path's pieces alone, on one
/// thread, on a prefix of the acknowledged bodies (at most 2 million observations, at most
/// 5 s each): parse the bodies, apply them to the in-process models, encode them as log
/// groups, append the groups to a fresh redb store in `dir` (removed afterwards).
fn write_baselines(
    bodies: &[Body],
    local: &mut Registry,
    dir: &Path,
) -> Result<Vec<BaselineBench>, ServeBenchError> {
    let limit = Duration::from_secs_f64(BASELINE_SECONDS);
    let mut sample = 0;
    let mut observations = 0;
    while sample < bodies.len() && observations < BASELINE_OBSERVATIONS {
        observations += bodies[sample].observations;
        sample += 1;
    }
    let bodies = &bodies[..sample];

    let started = Instant::now();
    let mut parsed = Vec::with_capacity(bodies.len());
    for body in bodies {
        parsed.push(serde_json::from_slice::<ObservationsRequest>(&body.bytes)?);
        if started.elapsed() > limit {
            break;
        }
    }
    let parse = baseline(
        "json_parse",
        "parse the request bodies (serde_json)",
        bodies[..parsed.len()].iter().map(|b| b.observations).sum(),
        started.elapsed().as_secs_f64(),
    );

    let started = Instant::now();
    let mut applied = 0;
    let mut staged: HashMap<String, Entry> = HashMap::new();
    for request in &parsed {
        for batch in &request.batches {
            let entry = match staged.get_mut(&batch.id) {
                Some(entry) => entry,
                None => {
                    let entry = local
                        .get(&batch.id)
                        .ok_or_else(|| ServeBenchError::InProcess {
                            id: batch.id.clone(),
                            message: "not loaded".into(),
                        })?
                        .clone();
                    staged.entry(batch.id.clone()).or_insert(entry)
                }
            };
            entry
                .observe(&batch.id, &batch.times, &batch.values)
                .map_err(|e| ServeBenchError::InProcess {
                    id: batch.id.clone(),
                    message: e.to_string(),
                })?;
            applied += batch.times.len() as u64;
        }
        if started.elapsed() > limit {
            break;
        }
    }
    let apply = baseline(
        "model_update",
        "apply the observations to in-process models",
        applied,
        started.elapsed().as_secs_f64(),
    );
    for (id, entry) in staged {
        local.put(id, Some(entry));
    }

    let started = Instant::now();
    let mut groups = Vec::with_capacity(parsed.len());
    let mut encoded = 0;
    for request in parsed {
        let records: Vec<LogRecord> = request
            .batches
            .into_iter()
            .map(|b| LogRecord::Observe {
                id: b.id,
                times: b.times,
                values: b.values,
            })
            .collect();
        encoded += records.iter().map(|r| r.observations() as u64).sum::<u64>();
        groups.push((encode_group(groups.len() as u64 + 1, &records), encoded));
        if started.elapsed() > limit {
            break;
        }
    }
    let encode = baseline(
        "log_encode",
        "encode them as log groups (postcard, CRC-32)",
        encoded,
        started.elapsed().as_secs_f64(),
    );

    let path = dir.join("baseline.redb");
    let store = RedbStore::open(&path)?;
    let started = Instant::now();
    let mut written = 0;
    for (seq, (bytes, upto)) in groups.iter().enumerate() {
        store.append(seq as u64 + 1, bytes)?;
        written = *upto;
        if started.elapsed() > limit {
            break;
        }
    }
    let redb = baseline(
        "redb_append",
        "append the groups to redb, one transaction (fsync) each",
        written,
        started.elapsed().as_secs_f64(),
    );
    drop(store);
    std::fs::remove_file(&path).map_err(|source| ServeBenchError::Remove {
        path: path.clone(),
        source,
    })?;
    Ok(vec![parse, apply, encode, redb])
}

impl ServeBench {
    /// The result as `chronomap bench serve` prints it, with the `config` it ran with.
    pub fn text(&self, config: &ServeBenchConfig) -> String {
        let b = self;
        let mut text = String::new();
        let _ = writeln!(
            text,
            "chronomap serve on 127.0.0.1 (redb store, bearer token), {} {} models, {}, {} hardware threads",
            b.models,
            b.model,
            clients(b.clients),
            b.threads
        );
        let p = &b.preload;
        let _ = writeln!(
            text,
            "preload: {} observations ({} per model) in {} requests, durable in {:.2} s = {:.3e} observations/s (in-process models: {:.2} s)",
            p.observations,
            config.preload,
            p.requests,
            p.seconds,
            p.observations_per_second,
            p.in_process_seconds
        );
        let _ = writeln!(
            text,
            "\nlatency: {} back to back, up to {} requests each per kind (or {} s), after {WARM_UP} untimed ones",
            clients(b.clients),
            config.requests,
            config.latency_seconds
        );
        let mut table = Table::new([
            "request",
            "requests",
            "p50 µs",
            "p99 µs",
            "max µs",
            "requests/s",
            "in-process µs",
            "p50 / in-process",
            "p50 / health p50",
        ]);
        for l in &b.latency {
            let (ip, ratio, ratio_health) = match (
                l.in_process_ns,
                l.ratio_p50_to_in_process,
                l.ratio_p50_to_health,
            ) {
                (Some(ns), Some(ratio), Some(health)) => (
                    format!("{:.3}", ns / 1e3),
                    format!("{ratio:.0}"),
                    format!("{health:.2}"),
                ),
                _ => ("-".into(), "-".into(), "1.00".into()),
            };
            table.row([
                l.request.clone(),
                l.requests.to_string(),
                format!("{:.0}", l.p50_us),
                format!("{:.0}", l.p99_us),
                format!("{:.0}", l.max_us),
                format!("{:.0}", l.requests_per_second),
                ip,
                ratio,
                ratio_health,
            ]);
        }
        let _ = writeln!(text, "{}", table.render());
        let t = &b.throughput;
        let _ = writeln!(
            text,
            "\ndurable throughput: {}, POST /v1/observations of {} observations over {} models each ({:.1} MB of JSON bodies, encoded beforehand in {:.2} s)",
            clients(t.writers),
            t.batch,
            t.batch_ids.min(b.models.div_ceil(t.writers)),
            t.body_bytes as f64 / 1e6,
            t.client_encode_seconds
        );
        let _ = writeln!(
            text,
            "  {} observations in {} requests acknowledged in {:.2} s ({} commit groups{}) = {:.3e} durable observations/s",
            t.observations,
            t.requests,
            t.seconds,
            t.commits,
            if t.observations < t.prepared_observations {
                format!(", stopped by --seconds before {}", t.prepared_observations)
            } else {
                String::new()
            },
            t.observations_per_second
        );
        let mut table = Table::new([
            "baseline (one thread, same bodies)",
            "observations",
            "observations/s",
            "service / baseline",
        ]);
        for baseline in &t.baselines {
            table.row([
                baseline.what.to_string(),
                baseline.observations.to_string(),
                format!("{:.3e}", baseline.observations_per_second),
                format!("{:.2}", baseline.ratio_service_to_baseline),
            ]);
        }
        table.row([
            "all four one after the other".to_string(),
            "-".into(),
            format!("{:.3e}", t.baseline_pipeline_observations_per_second),
            format!("{:.2}", t.ratio_service_to_pipeline),
        ]);
        let _ = writeln!(text, "{}", table.render());
        let p99 = b.predict_p99_us();
        let _ = writeln!(
            text,
            "\ngoals: predict p99 < 1 ms: {} ({p99:.0} µs); >= 1e6 durable observations/s in batches: {} ({:.3e})",
            if b.goals.predict_p99_under_1ms {
                "met"
            } else {
                "missed"
            },
            if b.goals.durable_1m_observations_per_second {
                "met"
            } else {
                "missed"
            },
            t.observations_per_second
        );
        if let Some(path) = &b.data {
            let _ = writeln!(text, "the store is kept in {path}");
        }
        text
    }
}

/// "1 client", "4 clients".
fn clients(n: usize) -> String {
    format!("{n} client{}", if n == 1 { "" } else { "s" })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config() -> ServeBenchConfig {
        ServeBenchConfig {
            models: 5,
            model: "fremen:2".into(),
            preload: 600,
            clients: 2,
            requests: 30,
            latency_seconds: 5.0,
            predict_times: 3,
            forecast_ids: 4,
            observations: 20_000,
            batch: 2000,
            batch_ids: 2,
            seconds: 30.0,
            data: None,
        }
    }

    #[test]
    fn validate_names_the_first_field_out_of_range() {
        assert!(config().validate().is_ok());
        let field = |c: ServeBenchConfig| match c.validate() {
            Err(ServeBenchError::Config { field, .. }) => field,
            other => panic!("{other:?}"),
        };
        assert_eq!(
            field(ServeBenchConfig {
                batch_ids: 0,
                ..config()
            }),
            "batch_ids"
        );
        assert_eq!(
            field(ServeBenchConfig {
                latency_seconds: f64::NAN,
                seconds: 0.0,
                ..config()
            }),
            "latency_seconds"
        );
        assert_eq!(
            field(ServeBenchConfig {
                seconds: -1.0,
                ..config()
            }),
            "seconds"
        );
    }

    #[test]
    fn a_batch_is_split_evenly_with_the_remainder_first() {
        assert_eq!(split(10, 3), [4, 3, 3]);
        assert_eq!(split(2000, 2), [1000, 1000]);
        assert_eq!(split(1, 2), [1, 0]);
    }

    #[test]
    fn the_door_replays_itself_one_cycle_later() {
        let door = Door::new(TimeSeries {
            times: vec![0.0, 60.0, 120.0],
            values: vec![0.0, 1.0, 0.0],
        })
        .unwrap();
        let mut stream = Stream {
            cursor: 0,
            offset: 3600.0,
        };
        let (mut times, mut values) = (Vec::new(), Vec::new());
        door.take(&mut stream, 4, &mut times, &mut values);
        assert_eq!(times, [3600.0, 3660.0, 3720.0, 3780.0]);
        assert_eq!(values, [0.0, 1.0, 0.0, 0.0]);
        assert_eq!(stream.last_time(&door), 3780.0);
        door.take(&mut stream, 2, &mut times, &mut values);
        assert_eq!(stream.last_time(&door), 3900.0);
        assert_eq!(stream.cursor, 0);
        assert!(matches!(
            Door::new(TimeSeries {
                times: vec![0.0],
                values: vec![1.0],
            }),
            Err(ServeBenchError::TooFewObservations { count: 1 })
        ));
    }

    #[test]
    fn latencies_and_baselines_are_maps_by_key_in_json() {
        let latency = |key: &str, in_process_ns: Option<f64>| LatencyBench {
            key: key.into(),
            request: String::new(),
            requests: 60,
            seconds: 0.5,
            p50_us: 100.0,
            p99_us: 200.0,
            max_us: 300.0,
            requests_per_second: 120.0,
            in_process_ns,
            ratio_p50_to_in_process: in_process_ns.map(|ns| 100.0 * 1e3 / ns),
            ratio_p50_to_health: in_process_ns.map(|_| 1.0),
        };
        #[derive(Serialize)]
        struct Latency {
            #[serde(serialize_with = "by_key")]
            latency: Vec<LatencyBench>,
        }
        let json = serde_json::to_value(Latency {
            latency: vec![latency("health", None), latency("predict_1", Some(500.0))],
        })
        .unwrap();
        let health = json["latency"]["health"].as_object().unwrap();
        assert_eq!(health.len(), 6, "{health:?}");
        assert!(!health.contains_key("in_process_ns") && !health.contains_key("key"));
        assert_eq!(
            json["latency"]["predict_1"]["ratio_p50_to_in_process"],
            200.0
        );
        assert_eq!(json["latency"]["predict_1"]["requests"], 60);
        let b = baseline("redb_append", "append", 20_000, 0.5);
        assert_eq!(b.observations_per_second, 40_000.0);
        let json = serde_json::to_value(&b).unwrap();
        assert_eq!(json.as_object().unwrap().len(), 4, "{json}");
    }
}
