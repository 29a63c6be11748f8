//! A bounded benchmark of a fleet (`chronomap serve --fleet`) on loopback against one
//! PostgreSQL server, with the bare database work measured in the same run as baselines.
//!
//! For 1, 2 and 3 nodes (each a service in this process, on `127.0.0.1:0`, with its own
//! connections, writer and tailer, on a fresh schema), clients spread over the nodes send
//! batched observations (`POST /v1/observations`; each acknowledged write is durable in the
//! shared log) for a fixed time while one more client per node times one-time predictions
//! back to back: durable observations per second and the p99 latency of `predict` under that
//! write load. The baselines write the same rows (`model_id`, `time`, `value`) into a plain
//! table, one transaction per request-sized batch, on as many connections as there are
//! writing clients: a batched `INSERT … SELECT unnest(…)` and `COPY … FROM STDIN`.
//!
//! Catch-up: a log of 10⁷ observations is written, then a new node recovers from it (verify
//! every entry and replay every group), and again after a checkpoint (snapshots of every model
//! at the log's end) and the compaction that follows it, as a node joining the fleet does.

use std::fmt::Write as _;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use chronomap_app::report::Table;
use chronomap_client::Client;
use chronomap_core::progress::Progress;
use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_serve::api::{AddValuesRequest, ObservationsRequest};
use chronomap_serve::log::{LogRecord, encode_group};
use chronomap_serve::registry::ModelConfig;
use chronomap_serve::store::{
    Access, Checkpoint, OWNER_WAIT, PostgresStore, Store, encode_snapshot,
};
use chronomap_serve::{Service, ServiceConfig};
use serde::Serialize;
use thiserror::Error;

/// What the benchmark does.
#[derive(Clone, Debug, PartialEq)]
pub struct FleetBenchConfig {
    /// libpq connection string or `postgresql://` URL.
    pub postgres: String,
    /// Node counts measured, in order (each on a fresh schema).
    pub nodes: Vec<usize>,
    /// Writing clients per node.
    pub clients_per_node: usize,
    /// Models written (split among the clients; each client owns its models).
    pub models: usize,
    /// Model spec.
    pub model: String,
    /// Observations per request.
    pub batch: usize,
    /// Models per request (the batch is split evenly among them).
    pub batch_ids: usize,
    /// Seconds of writing per node count.
    pub seconds: f64,
    /// Observations in the catch-up log (0: no catch-up measurement).
    pub catch_up_observations: u64,
    /// Keep the schemas (else dropped at the end).
    pub keep: bool,
}

impl Default for FleetBenchConfig {
    fn default() -> Self {
        FleetBenchConfig {
            postgres: String::new(),
            nodes: vec![1, 2, 3],
            clients_per_node: 2,
            models: 120,
            model: "fremen:2".into(),
            batch: 1_000,
            batch_ids: 10,
            seconds: 5.0,
            catch_up_observations: 10_000_000,
            keep: false,
        }
    }
}

/// Why the benchmark could not run.
#[derive(Debug, Error)]
pub enum FleetBenchError {
    /// A field out of range.
    #[error("{field}: {message}")]
    Config {
        /// The field.
        field: &'static str,
        /// Why.
        message: String,
    },
    /// The database.
    #[error("postgres: {0}")]
    Postgres(String),
    /// A service did not start or answer.
    #[error("service: {0}")]
    Service(String),
}

/// Most nodes, clients and models (the benchmark is bounded).
const MAX_NODES: usize = 8;
const MAX_CLIENTS_PER_NODE: usize = 16;
const MAX_MODELS: usize = 100_000;
const MAX_CATCH_UP: u64 = 100_000_000;
/// Observations per commit group of the catch-up log.
const CATCH_UP_GROUP: usize = 20_000;
/// Commit groups per partition of the catch-up log (the service's default is 100,000 groups
/// of any size; here groups are large, so segments are short).
const CATCH_UP_SEGMENT: u64 = 10;

impl FleetBenchConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// The first field out of range.
    pub fn validate(&self) -> Result<(), FleetBenchError> {
        let bad = |field, message: String| Err(FleetBenchError::Config { field, message });
        if self.nodes.is_empty() || self.nodes.iter().any(|&n| n == 0 || n > MAX_NODES) {
            return bad("nodes", format!("node counts must be 1..={MAX_NODES}"));
        }
        if self.clients_per_node == 0 || self.clients_per_node > MAX_CLIENTS_PER_NODE {
            return bad(
                "clients_per_node",
                format!("must be 1..={MAX_CLIENTS_PER_NODE}"),
            );
        }
        let writers = self.clients_per_node * self.nodes.iter().max().copied().unwrap_or(1);
        if self.models < writers || self.models > MAX_MODELS {
            return bad(
                "models",
                format!(
                    "must be at least the writing clients ({writers}) and at most {MAX_MODELS}"
                ),
            );
        }
        if self.batch_ids == 0 || self.batch < self.batch_ids || self.batch > 1_000_000 {
            return bad(
                "batch",
                "must be at least --batch-ids and at most 1000000".into(),
            );
        }
        if !(self.seconds.is_finite() && self.seconds > 0.0 && self.seconds <= 600.0) {
            return bad("seconds", "must be in (0, 600]".into());
        }
        if self.catch_up_observations > MAX_CATCH_UP {
            return bad("catch_up_observations", format!("at most {MAX_CATCH_UP}"));
        }
        ModelConfig::parse(Some(&self.model), None)
            .map_err(|message| FleetBenchError::Config {
                field: "model",
                message,
            })
            .map(|_| ())
    }
}

/// What was measured.
#[derive(Clone, Debug, Serialize)]
pub struct FleetBench {
    /// Hardware threads of this machine (nodes, clients and the database share them).
    pub threads: usize,
    /// The PostgreSQL server's version.
    pub server_version: String,
    /// One run per node count.
    pub runs: Vec<FleetRun>,
    /// The catch-up of a new node, if measured.
    pub catch_up: Option<CatchUp>,
}

/// One node count.
#[derive(Clone, Debug, Serialize)]
pub struct FleetRun {
    /// Nodes.
    pub nodes: usize,
    /// Writing clients (spread evenly over the nodes).
    pub writers: usize,
    /// Observations acknowledged.
    pub observations: u64,
    /// Requests acknowledged.
    pub requests: u64,
    /// Commit groups in the log at the end (several requests share one).
    pub commit_groups: u64,
    /// Seconds of writing.
    pub seconds: f64,
    /// Durable observations per second.
    pub observations_per_second: f64,
    /// Predictions timed (one model, one time, back to back on every node during the writes).
    pub predicts: usize,
    /// Median predict latency (µs).
    pub predict_p50_us: f64,
    /// p99 predict latency (µs).
    pub predict_p99_us: f64,
    /// The baselines on the same rows.
    pub baselines: Vec<Baseline>,
}

/// The bare database work on the same rows.
#[derive(Clone, Debug, Serialize)]
pub struct Baseline {
    /// What it is.
    pub what: String,
    /// Rows written.
    pub rows: u64,
    /// Seconds.
    pub seconds: f64,
    /// Rows per second.
    pub rows_per_second: f64,
    /// The fleet's observations per second divided by this.
    pub ratio_fleet_to_baseline: f64,
}

/// A new node's start over a long log.
#[derive(Clone, Debug, Serialize)]
pub struct CatchUp {
    /// Observations in the log.
    pub observations: u64,
    /// Commit groups in the log.
    pub groups: u64,
    /// Models.
    pub models: usize,
    /// Seconds to write the log (one appender, groups of 20,000 observations).
    pub write_seconds: f64,
    /// Seconds for a new node to verify and replay the whole log.
    pub replay_seconds: f64,
    /// Seconds to write a checkpoint of every model at the log's end.
    pub checkpoint_seconds: f64,
    /// Seconds to move the log's segments that the checkpoint covers to the archive.
    pub compact_seconds: f64,
    /// Segments (of 10 commit groups) moved.
    pub segments_compacted: u64,
    /// Seconds for a new node to start from that checkpoint: snapshots, then the live log
    /// after the compacted segments, verified and replayed.
    pub start_from_checkpoint_seconds: f64,
    /// Whether both new nodes hold bit-identical models.
    pub identical: bool,
}

/// Runs the benchmark, announcing each stage to `progress`.
///
/// # Errors
/// A bad configuration, the database, or a service that does not start.
pub fn run(
    config: &FleetBenchConfig,
    progress: &dyn Progress,
) -> Result<FleetBench, FleetBenchError> {
    config.validate()?;
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let db = Database::connect(&config.postgres)?;
    let server_version = db.query_text("SHOW server_version")?;
    let stamp = format!(
        "{}_{}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos())
    );
    let mut runs = Vec::new();
    let mut schemas = Vec::new();
    for &nodes in &config.nodes {
        let schema = format!("bench_fleet_{stamp}_{nodes}");
        schemas.push(schema.clone());
        progress.stage(&format!("{nodes} node(s) writing"), 0);
        let mut run = fleet_run(config, nodes, &schema)?;
        progress.stage(&format!("{nodes} node(s): baselines"), 0);
        let writers = run.writers;
        let rows = run.observations;
        let baseline_schema = format!("{schema}_bare");
        schemas.push(baseline_schema.clone());
        db.execute(&format!(
            "CREATE SCHEMA {baseline_schema};
             CREATE TABLE {baseline_schema}.insert_rows (model_id TEXT NOT NULL, time DOUBLE PRECISION NOT NULL, value DOUBLE PRECISION NOT NULL);
             CREATE TABLE {baseline_schema}.copy_rows (model_id TEXT NOT NULL, time DOUBLE PRECISION NOT NULL, value DOUBLE PRECISION NOT NULL);"
        ))?;
        for what in [Bare::Insert, Bare::Copy] {
            let baseline = bare_writes(config, &baseline_schema, what, writers, rows)?;
            run.baselines.push(Baseline {
                ratio_fleet_to_baseline: run.observations_per_second / baseline.rows_per_second,
                ..baseline
            });
        }
        runs.push(run);
    }
    let catch_up = if config.catch_up_observations > 0 {
        let schema = format!("bench_fleet_{stamp}_catch_up");
        schemas.push(schema.clone());
        Some(catch_up(config, &schema, progress)?)
    } else {
        None
    };
    if !config.keep {
        for schema in schemas {
            db.execute(&format!("DROP SCHEMA IF EXISTS {schema} CASCADE"))?;
        }
    }
    Ok(FleetBench {
        threads,
        server_version,
        runs,
        catch_up,
    })
}

/// The observations of model `m`, request `r` of its client: a door open in working hours,
/// one observation a minute, with 10 % noise.
fn observations(
    m: usize,
    start: u64,
    n: usize,
    rng: &mut Xoshiro256StarStar,
) -> (Vec<f64>, Vec<f64>) {
    let t0 = 1.4e9 + 3600.0 * (m % 24) as f64;
    let times: Vec<f64> = (0..n)
        .map(|k| t0 + 60.0 * (start + k as u64) as f64)
        .collect();
    let values = times
        .iter()
        .map(|t| {
            let hour = (t % 86_400.0) / 3600.0;
            let open = (8.0..18.0).contains(&hour);
            f64::from(u8::from(open != (rng.next_f64() < 0.1)))
        })
        .collect();
    (times, values)
}

/// One writing client's requests, made lazily: request `r` covers `batch_ids` of its models.
struct Writer {
    models: Vec<usize>,
    next: Vec<u64>,
    cursor: usize,
    rng: Xoshiro256StarStar,
}

impl Writer {
    fn new(w: usize, writers: usize, models: usize) -> Self {
        let models: Vec<usize> = (w..models).step_by(writers).collect();
        Writer {
            next: vec![0; models.len()],
            models,
            cursor: 0,
            rng: Xoshiro256StarStar::seed_from_u64(w as u64 + 1),
        }
    }

    /// The next request's (model, times, values) triples.
    fn request(&mut self, batch: usize, batch_ids: usize) -> Vec<(usize, Vec<f64>, Vec<f64>)> {
        let ids = batch_ids.min(self.models.len());
        let mut out = Vec::with_capacity(ids);
        for k in 0..ids {
            let slot = self.cursor % self.models.len();
            self.cursor += 1;
            let n = batch / ids + usize::from(k < batch % ids);
            let (times, values) =
                observations(self.models[slot], self.next[slot], n, &mut self.rng);
            self.next[slot] += n as u64;
            out.push((self.models[slot], times, values));
        }
        out
    }
}

fn model_id(m: usize) -> String {
    format!("robot{:02}/door-{m:05}", m % 100)
}

/// Nodes of one run, each a service in this process.
struct Nodes {
    runtime: tokio::runtime::Runtime,
    urls: Vec<String>,
    stops: Vec<tokio::sync::oneshot::Sender<()>>,
    running: Vec<tokio::task::JoinHandle<std::io::Result<()>>>,
}

impl Nodes {
    fn start(
        config: &FleetBenchConfig,
        nodes: usize,
        schema: &str,
    ) -> Result<Self, FleetBenchError> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .thread_name("bench-fleet")
            .build()
            .map_err(|e| FleetBenchError::Service(e.to_string()))?;
        let (mut urls, mut stops, mut running) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..nodes {
            let store = PostgresStore::connect_fleet(&config.postgres, schema)
                .map_err(|e| FleetBenchError::Postgres(e.to_string()))?;
            let service = Service::start(Arc::new(store), ServiceConfig::default())
                .map_err(FleetBenchError::Service)?;
            let listener = runtime
                .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
                .map_err(|e| FleetBenchError::Service(e.to_string()))?;
            let address = listener
                .local_addr()
                .map_err(|e| FleetBenchError::Service(e.to_string()))?;
            let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
            running.push(runtime.spawn(service.run(listener, async {
                let _ = stopped.await;
            })));
            stops.push(stop);
            urls.push(format!("http://{address}"));
        }
        Ok(Nodes {
            runtime,
            urls,
            stops,
            running,
        })
    }

    fn stop(self) {
        for stop in self.stops {
            let _ = stop.send(());
        }
        self.runtime.block_on(async {
            for running in self.running {
                let _ = running.await;
            }
        });
    }
}

fn fleet_run(
    config: &FleetBenchConfig,
    nodes: usize,
    schema: &str,
) -> Result<FleetRun, FleetBenchError> {
    let fleet = Nodes::start(config, nodes, schema)?;
    let writers = config.clients_per_node * nodes;
    let model_config = config.model.clone();
    let clients: Vec<Client> = fleet
        .urls
        .iter()
        .map(|u| Client::new(u, None).map_err(|e| FleetBenchError::Service(e.to_string())))
        .collect::<Result<_, _>>()?;
    // Every model gets its first observations before the clock starts, so that predictions
    // have a model to ask from the first moment.
    let observed = Arc::new(AtomicU64::new(0));
    let requests = Arc::new(AtomicU64::new(0));
    let stop = Arc::new(AtomicBool::new(false));
    let limit = Duration::from_secs_f64(config.seconds);
    let (batch, batch_ids) = (config.batch, config.batch_ids);
    let result = fleet.runtime.block_on(async {
        // Warm-up: one request per writer, untimed (creates every model).
        let mut prepared: Vec<Writer> = (0..writers)
            .map(|w| Writer::new(w, writers, config.models))
            .collect();
        let mut created = 0;
        for (w, writer) in prepared.iter_mut().enumerate() {
            for _ in 0..writer.models.len().div_ceil(batch_ids) {
                let body = request_body(writer.request(batch, batch_ids), &model_config);
                let ack = clients[w % nodes]
                    .add_batches(&body)
                    .await
                    .map_err(|e| FleetBenchError::Service(e.to_string()))?;
                created = created.max(ack.seq);
            }
        }
        let start = Instant::now();
        let mut tasks = Vec::new();
        for (w, mut writer) in prepared.into_iter().enumerate() {
            let client = clients[w % nodes].clone();
            let (observed, requests, stop) = (
                Arc::clone(&observed),
                Arc::clone(&requests),
                Arc::clone(&stop),
            );
            let spec = model_config.clone();
            tasks.push(tokio::spawn(async move {
                while start.elapsed() < limit && !stop.load(Ordering::Relaxed) {
                    let body = request_body(writer.request(batch, batch_ids), &spec);
                    let ack = client
                        .add_batches(&body)
                        .await
                        .map_err(|e| FleetBenchError::Service(e.to_string()))?;
                    observed.fetch_add(ack.observations, Ordering::Relaxed);
                    requests.fetch_add(1, Ordering::Relaxed);
                }
                Ok::<_, FleetBenchError>(Vec::new())
            }));
        }
        // One predicting client per node, back to back during the writes.
        for (k, client) in clients.iter().enumerate() {
            // Every node has every model: the first request waits for the last creation.
            let first = client.reading_after(created);
            let client = client.clone();
            let stop = Arc::clone(&stop);
            let models = config.models;
            tasks.push(tokio::spawn(async move {
                let mut latencies = Vec::new();
                first
                    .health()
                    .await
                    .map_err(|e| FleetBenchError::Service(e.to_string()))?;
                let mut i = k;
                while start.elapsed() < limit && !stop.load(Ordering::Relaxed) {
                    let id = model_id(i % models);
                    let t = 1.45e9 + 3600.0 * (i % 168) as f64;
                    i += 7;
                    let t0 = Instant::now();
                    client
                        .predict(&id, &[t], None)
                        .await
                        .map_err(|e| FleetBenchError::Service(e.to_string()))?;
                    latencies.push(t0.elapsed().as_secs_f64() * 1e6);
                }
                Ok(latencies)
            }));
        }
        let mut latencies = Vec::new();
        let mut failure = None;
        for task in tasks {
            match task.await {
                Ok(Ok(l)) => latencies.extend(l),
                Ok(Err(e)) => {
                    stop.store(true, Ordering::Relaxed);
                    failure.get_or_insert(e);
                }
                Err(e) => {
                    failure.get_or_insert(FleetBenchError::Service(e.to_string()));
                }
            }
        }
        if let Some(e) = failure {
            return Err(e);
        }
        let seconds = start.elapsed().as_secs_f64();
        let head = clients[0]
            .health()
            .await
            .map_err(|e| FleetBenchError::Service(e.to_string()))?
            .head;
        Ok((seconds, latencies, head))
    });
    fleet.stop();
    let (seconds, mut latencies, commit_groups) = result?;
    latencies.sort_by(f64::total_cmp);
    let rank = |q: f64| {
        if latencies.is_empty() {
            f64::NAN
        } else {
            latencies[((q * latencies.len() as f64).ceil() as usize).clamp(1, latencies.len()) - 1]
        }
    };
    let observations = observed.load(Ordering::Relaxed);
    Ok(FleetRun {
        nodes,
        writers,
        observations,
        requests: requests.load(Ordering::Relaxed),
        commit_groups,
        seconds,
        observations_per_second: observations as f64 / seconds,
        predicts: latencies.len(),
        predict_p50_us: rank(0.5),
        predict_p99_us: rank(0.99),
        baselines: Vec::new(),
    })
}

fn request_body(parts: Vec<(usize, Vec<f64>, Vec<f64>)>, spec: &str) -> ObservationsRequest {
    ObservationsRequest {
        batches: parts
            .into_iter()
            .map(|(m, times, values)| AddValuesRequest {
                id: model_id(m),
                times,
                values,
                model: Some(spec.to_owned()),
            })
            .collect(),
    }
}

#[derive(Clone, Copy, Debug)]
enum Bare {
    Insert,
    Copy,
}

/// `rows` rows of the same kind the fleet wrote, in request-sized transactions, on `writers`
/// connections at once.
fn bare_writes(
    config: &FleetBenchConfig,
    schema: &str,
    what: Bare,
    writers: usize,
    rows: u64,
) -> Result<Baseline, FleetBenchError> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(|e| FleetBenchError::Postgres(e.to_string()))?;
    let per_writer = rows.div_ceil(writers as u64).max(config.batch as u64);
    let (batch, batch_ids, models) = (config.batch, config.batch_ids, config.models);
    let seconds = runtime.block_on(async {
        let mut connections = Vec::new();
        for _ in 0..writers {
            let (client, connection) =
                tokio_postgres::connect(&config.postgres, tokio_postgres::NoTls)
                    .await
                    .map_err(|e| FleetBenchError::Postgres(e.to_string()))?;
            tokio::spawn(connection);
            connections.push(client);
        }
        let start = Instant::now();
        let tasks: Vec<_> = connections
            .into_iter()
            .enumerate()
            .map(|(w, mut client)| {
                let schema = schema.to_owned();
                tokio::spawn(async move {
                    let mut writer = Writer::new(w, writers, models);
                    let mut written = 0u64;
                    while written < per_writer {
                        let parts = writer.request(batch, batch_ids);
                        written += parts.iter().map(|p| p.1.len() as u64).sum::<u64>();
                        write_rows(&mut client, &schema, what, &parts).await?;
                    }
                    Ok::<u64, FleetBenchError>(written)
                })
            })
            .collect();
        let mut total = 0;
        for task in tasks {
            total += task
                .await
                .map_err(|e| FleetBenchError::Postgres(e.to_string()))??;
        }
        Ok::<_, FleetBenchError>((start.elapsed().as_secs_f64(), total))
    })?;
    let (seconds, written) = seconds;
    Ok(Baseline {
        what: match what {
            Bare::Insert => format!(
                "INSERT … SELECT unnest(…), one transaction per {batch} rows, {writers} connections"
            ),
            Bare::Copy => format!(
                "COPY … FROM STDIN (text), one transaction per {batch} rows, {writers} connections"
            ),
        },
        rows: written,
        seconds,
        rows_per_second: written as f64 / seconds,
        ratio_fleet_to_baseline: f64::NAN,
    })
}

async fn write_rows(
    client: &mut tokio_postgres::Client,
    schema: &str,
    what: Bare,
    parts: &[(usize, Vec<f64>, Vec<f64>)],
) -> Result<(), FleetBenchError> {
    let pg = |e: tokio_postgres::Error| FleetBenchError::Postgres(e.to_string());
    match what {
        Bare::Insert => {
            let mut ids = Vec::new();
            let mut times = Vec::new();
            let mut values = Vec::new();
            for (m, t, v) in parts {
                let id = model_id(*m);
                ids.extend(std::iter::repeat_n(id, t.len()));
                times.extend_from_slice(t);
                values.extend_from_slice(v);
            }
            client
                .execute(
                    &format!(
                        "INSERT INTO {schema}.insert_rows (model_id, time, value)
                         SELECT * FROM unnest($1::text[], $2::float8[], $3::float8[])"
                    ),
                    &[&ids, &times, &values],
                )
                .await
                .map_err(pg)?;
        }
        Bare::Copy => {
            use futures_util::SinkExt;
            let mut text = String::new();
            for (m, t, v) in parts {
                let id = model_id(*m);
                for (time, value) in t.iter().zip(v) {
                    text.push_str(&format!("{id}\t{time:?}\t{value:?}\n"));
                }
            }
            let transaction = client.transaction().await.map_err(pg)?;
            let sink = transaction
                .copy_in::<_, bytes::Bytes>(&format!(
                    "COPY {schema}.copy_rows (model_id, time, value) FROM STDIN"
                ))
                .await
                .map_err(pg)?;
            let mut sink = std::pin::pin!(sink);
            sink.send(bytes::Bytes::from(text)).await.map_err(pg)?;
            sink.as_mut().finish().await.map_err(pg)?;
            transaction.commit().await.map_err(pg)?;
        }
    }
    Ok(())
}

/// Writes a log of `config.catch_up_observations` observations, then times a new node's
/// recovery from it, and from a checkpoint at its end.
fn catch_up(
    config: &FleetBenchConfig,
    schema: &str,
    progress: &dyn Progress,
) -> Result<CatchUp, FleetBenchError> {
    let pg = |e: chronomap_serve::store::StoreError| FleetBenchError::Postgres(e.to_string());
    let store = Arc::new(
        PostgresStore::connect_with(
            &config.postgres,
            schema,
            Access::Fleet,
            OWNER_WAIT,
            CATCH_UP_SEGMENT,
        )
        .map_err(pg)?,
    );
    let total = config.catch_up_observations;
    let create = ModelConfig::parse(Some(&config.model), None).map_err(FleetBenchError::Service)?;
    let mut next = vec![0u64; config.models];
    let mut rng = Xoshiro256StarStar::seed_from_u64(7);
    progress.stage("catch-up: writing the log", total);
    let start = Instant::now();
    let (mut written, mut known, mut group) = (0u64, 0u64, 0usize);
    while written < total {
        let n = (total - written).min(CATCH_UP_GROUP as u64) as usize;
        let per_model = n.div_ceil(config.models.min(n)).max(1);
        let mut records = Vec::new();
        let mut left = n;
        let mut m = (group * 7) % config.models;
        while left > 0 {
            let k = left.min(per_model);
            if next[m] == 0 {
                records.push(LogRecord::Create {
                    id: model_id(m),
                    config: create.clone(),
                });
            }
            let (times, values) = observations(m, next[m], k, &mut rng);
            next[m] += k as u64;
            records.push(LogRecord::Observe {
                id: model_id(m),
                times,
                values,
            });
            left -= k;
            m = (m + 1) % config.models;
        }
        let appended = store
            .append_next(known, &mut |_, _| Ok(()), &mut |seq| {
                Some(encode_group(seq, &records))
            })
            .map_err(pg)?;
        known = appended.unwrap_or(known);
        written += n as u64;
        group += 1;
        progress.advance(n as u64);
    }
    let write_seconds = start.elapsed().as_secs_f64();
    progress.stage("catch-up: new node replays", 0);

    let start = Instant::now();
    let replayed = chronomap_serve::writer::recover(Arc::clone(&store) as Arc<dyn Store>)
        .map_err(FleetBenchError::Service)?;
    let replay_seconds = start.elapsed().as_secs_f64();
    progress.stage("catch-up: from a checkpoint", 0);

    let start = Instant::now();
    let snapshots: Vec<(String, Vec<u8>)> = {
        let registry = replayed.registry.read().expect("registry lock");
        registry
            .ids()
            .into_iter()
            .map(|id| {
                (
                    id.to_owned(),
                    encode_snapshot(registry.get(id).expect("listed")),
                )
            })
            .collect()
    };
    store
        .checkpoint(&Checkpoint {
            seq: known,
            snapshots: &snapshots,
            removed: &[],
        })
        .map_err(pg)?;
    let checkpoint_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let segments_compacted = store.compact().map_err(pg)?;
    let compact_seconds = start.elapsed().as_secs_f64();

    let start = Instant::now();
    let from_checkpoint = chronomap_serve::writer::recover(Arc::clone(&store) as Arc<dyn Store>)
        .map_err(FleetBenchError::Service)?;
    let start_from_checkpoint_seconds = start.elapsed().as_secs_f64();
    let identical = {
        let a = replayed.registry.read().expect("registry lock");
        let b = from_checkpoint.registry.read().expect("registry lock");
        a.ids() == b.ids()
            && a.ids().into_iter().all(|id| {
                encode_snapshot(a.get(id).expect("listed"))
                    == encode_snapshot(b.get(id).expect("listed"))
            })
    };
    Ok(CatchUp {
        observations: written,
        groups: known,
        models: config.models,
        write_seconds,
        replay_seconds,
        checkpoint_seconds,
        compact_seconds,
        segments_compacted,
        start_from_checkpoint_seconds,
        identical,
    })
}

/// A plain connection for the schemas and the baselines' tables.
struct Database {
    runtime: tokio::runtime::Runtime,
    client: tokio_postgres::Client,
}

impl Database {
    fn connect(config: &str) -> Result<Self, FleetBenchError> {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(|e| FleetBenchError::Postgres(e.to_string()))?;
        let client = runtime.block_on(async {
            let (client, connection) = tokio_postgres::connect(config, tokio_postgres::NoTls)
                .await
                .map_err(|e| FleetBenchError::Postgres(format!("cannot connect: {e}")))?;
            tokio::spawn(connection);
            Ok::<_, FleetBenchError>(client)
        })?;
        Ok(Database { runtime, client })
    }

    fn execute(&self, sql: &str) -> Result<(), FleetBenchError> {
        self.runtime
            .block_on(self.client.batch_execute(sql))
            .map_err(|e| FleetBenchError::Postgres(e.to_string()))
    }

    fn query_text(&self, sql: &str) -> Result<String, FleetBenchError> {
        self.runtime
            .block_on(self.client.query_one(sql, &[]))
            .map(|row| row.get::<_, String>(0))
            .map_err(|e| FleetBenchError::Postgres(e.to_string()))
    }
}

impl FleetBench {
    /// The result as `chronomap bench fleet` prints it, with the `config` it ran with.
    pub fn text(&self, config: &FleetBenchConfig) -> String {
        let b = self;
        let mut text = String::new();
        let _ = writeln!(
            text,
            "chronomap serve --fleet on 127.0.0.1, PostgreSQL {}, {} hardware threads shared by nodes, clients and the database",
            b.server_version, b.threads
        );
        let _ = writeln!(
            text,
            "writes: {} clients per node, POST /v1/observations of {} observations over {} models, for {} s; one client per node times predict (one model, one time) meanwhile",
            config.clients_per_node, config.batch, config.batch_ids, config.seconds
        );
        let mut table = Table::new([
            "nodes",
            "observations/s",
            "requests",
            "commit groups",
            "predict p50 µs",
            "predict p99 µs",
            "INSERT rows/s",
            "fleet / INSERT",
            "COPY rows/s",
            "fleet / COPY",
        ]);
        for run in &b.runs {
            let baseline = |k: usize| {
                run.baselines.get(k).map_or(("-".into(), "-".into()), |x| {
                    (
                        format!("{:.3e}", x.rows_per_second),
                        format!("{:.2}", x.ratio_fleet_to_baseline),
                    )
                })
            };
            let (insert, insert_ratio) = baseline(0);
            let (copy, copy_ratio) = baseline(1);
            table.row([
                run.nodes.to_string(),
                format!("{:.3e}", run.observations_per_second),
                run.requests.to_string(),
                run.commit_groups.to_string(),
                format!("{:.0}", run.predict_p50_us),
                format!("{:.0}", run.predict_p99_us),
                insert,
                insert_ratio,
                copy,
                copy_ratio,
            ]);
        }
        let _ = writeln!(text, "{}", table.render());
        if let Some(c) = &b.catch_up {
            let _ = writeln!(
                text,
                "\ncatch-up of a new node: {} observations of {} models in {} commit groups (written in {:.1} s)",
                c.observations, c.models, c.groups, c.write_seconds
            );
            let _ = writeln!(
                text,
                "  from the log alone (verify + replay every group): {:.2} s = {:.3e} observations/s",
                c.replay_seconds,
                c.observations as f64 / c.replay_seconds
            );
            let _ = writeln!(
                text,
                "  checkpoint of every model: {:.2} s; compaction ({} segments of 10 groups to the archive): {:.2} s",
                c.checkpoint_seconds, c.segments_compacted, c.compact_seconds
            );
            let _ = writeln!(
                text,
                "  a new node from the checkpoint and the live log: {:.2} s ({:.1}x faster); models bit-identical: {}",
                c.start_from_checkpoint_seconds,
                c.replay_seconds / c.start_from_checkpoint_seconds,
                if c.identical { "yes" } else { "NO" }
            );
        }
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validate_names_the_first_field_out_of_range() {
        let ok = FleetBenchConfig {
            postgres: "host=127.0.0.1".into(),
            ..FleetBenchConfig::default()
        };
        assert!(ok.validate().is_ok());
        for (config, field) in [
            (
                FleetBenchConfig {
                    nodes: vec![1, 0],
                    ..ok.clone()
                },
                "nodes",
            ),
            (
                FleetBenchConfig {
                    models: 3,
                    ..ok.clone()
                },
                "models",
            ),
            (
                FleetBenchConfig {
                    seconds: f64::NAN,
                    ..ok.clone()
                },
                "seconds",
            ),
            (
                FleetBenchConfig {
                    model: "nonsense".into(),
                    ..ok.clone()
                },
                "model",
            ),
        ] {
            match config.validate() {
                Err(FleetBenchError::Config { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        }
    }

    #[test]
    fn writers_own_disjoint_models_and_continue_their_times() {
        let mut a = Writer::new(0, 2, 5);
        let mut b = Writer::new(1, 2, 5);
        assert_eq!(a.models, [0, 2, 4]);
        assert_eq!(b.models, [1, 3]);
        let first = a.request(10, 3);
        assert_eq!(
            first.iter().map(|p| (p.0, p.1.len())).collect::<Vec<_>>(),
            [(0, 4), (2, 3), (4, 3)]
        );
        let second = a.request(4, 2);
        // Model 0 again: its times continue one minute after its last one.
        assert_eq!(second[0].0, 0);
        assert_eq!(second[0].1[0], first[0].1[3] + 60.0);
        assert_eq!(b.request(2, 2).len(), 2);
    }
}
