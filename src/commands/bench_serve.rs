//! `chronomap bench serve`: a bounded load generator against the service on loopback, with the
//! same work done without the service in the same run as baselines.
//!
//! The service runs in this process on `127.0.0.1:0` with a redb store in a fresh directory
//! and a bearer token. Its models (the training door, shifted by one hour per model) are
//! preloaded through the API. Then concurrent clients, each with its own connection, time
//! health checks, predictions of one model at one time and at the next hours, and forecasts of
//! many models at one time; the baselines are the same predictions computed in-process on
//! equivalent models, and the health round trip. Then the same clients send batched
//! observations (`POST /v1/observations`, each request one durable commit, acknowledged after
//! redb's fsync); the baselines are the pieces of that work alone, on one thread: parsing the
//! same request bodies, applying the same observations to in-process models, encoding them as
//! log groups, and appending groups of the same size to a redb store, one transaction per
//! request.

use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result, anyhow, bail, ensure};
use chronomap_client::Client;
use chronomap_core::TemporalModel;
use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_io::TimeSeries;
use chronomap_serve::api::{AddValuesRequest, ForecastRequest, ObservationsRequest, WriteAck};
use chronomap_serve::log::{LogRecord, encode_group};
use chronomap_serve::registry::{Entry, ModelConfig, Registry};
use chronomap_serve::store::{RedbStore, Store};
use chronomap_serve::{Service, ServiceConfig};
use serde_json::{Value, json};

use crate::cli::BenchServeArgs;
use crate::format::Table;

/// Untimed requests per client before each latency test.
const WARM_UP: usize = 20;
/// Goal for the p99 latency of a one-time prediction (µs).
const GOAL_P99_US: f64 = 1_000.0;
/// Goal for durable observations per second in batches.
const GOAL_OBSERVATIONS_PER_SECOND: f64 = 1e6;
/// Most observations the write baselines redo (a prefix of what the clients sent).
const BASELINE_OBSERVATIONS: u64 = 2_000_000;
/// Time limit of each write baseline.
const BASELINE_SECONDS: f64 = 5.0;
/// Longest wait for one answer of the service (the benchmark ends with an error instead).
const REQUEST_TIMEOUT: Duration = Duration::from_secs(60);

pub fn serve(args: &BenchServeArgs) -> Result<()> {
    ensure!(args.models >= 1, "--models: at least 1 model");
    ensure!(args.clients >= 1, "--clients: at least 1 client");
    ensure!(
        args.preload >= 1,
        "--preload: every model needs observations to predict from"
    );
    ensure!(args.batch >= 1, "--batch: at least 1 observation a request");
    ensure!(args.observations >= 1, "--observations: at least 1");
    ensure!(
        args.batch_ids >= 1,
        "--batch-ids: at least 1 model a request"
    );
    ensure!(args.predict_times >= 1, "--predict-times: at least 1 time");
    ensure!(
        args.latency_seconds > 0.0 && args.seconds > 0.0,
        "--latency-seconds and --seconds must be positive"
    );
    let config = ModelConfig::parse(Some(&args.model), None)
        .map_err(|e| anyhow!("--model {}: {e}", args.model))?;
    let door = Door::new(match &args.train {
        Some(path) => chronomap_io::read_pairs(path)
            .with_context(|| format!("cannot read {}", path.display()))?,
        None => crate::bundled::GREG_TRAINING.pairs()?,
    })?;
    let forecast_ids = args.forecast_ids.clamp(1, args.models);
    let writers = args.clients.min(args.models);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let ids: Vec<String> = (0..args.models).map(|i| format!("door-{i:05}")).collect();

    let dir = DataDir::new(args.data.as_deref())?;
    let store = RedbStore::open(dir.path.join("chronomap.redb"))?;
    let token = random_token()?;
    let service = Service::start(
        Arc::new(store),
        ServiceConfig {
            token: Some(token.clone()),
            ..ServiceConfig::default()
        },
    )
    .map_err(anyhow::Error::msg)?;
    let server = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .thread_name("bench-server")
        .build()
        .context("cannot start the service's async runtime")?;
    let listener = server
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .context("cannot listen on 127.0.0.1")?;
    let address = listener.local_addr()?;
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let running = server.spawn(service.run(listener, async {
        let _ = stopped.await;
    }));
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(args.clients.min(threads))
        .enable_all()
        .thread_name("bench-client")
        .build()
        .context("cannot start the clients' async runtime")?;
    let base = format!("http://{address}");
    let clients = (0..args.clients)
        .map(|_| Client::new(&base, Some(token.clone())))
        .collect::<Result<Vec<_>, _>>()?;

    // Streams of observations: model i replays the door shifted by i hours (mod 24).
    let mut streams: Vec<Stream> = (0..args.models)
        .map(|i| Stream {
            cursor: 0,
            offset: 3600.0 * (i % 24) as f64,
        })
        .collect();
    let owned: Vec<Vec<usize>> = (0..writers)
        .map(|w| (w..args.models).step_by(writers).collect())
        .collect();

    // Preload through the API, and the same observations into in-process models.
    let started = Instant::now();
    let preload_bodies: Vec<Vec<Body>> = owned
        .iter()
        .map(|own| preload_bodies(&door, &mut streams, &ids, own, args, &config))
        .collect::<Result<_>>()?;
    let preload_encode_seconds = started.elapsed().as_secs_f64();
    let preload = runtime.block_on(send_all(
        &clients,
        &token,
        preload_bodies,
        Duration::from_secs(86_400),
    ))?;
    ensure!(
        preload.observations == (args.models * args.preload) as u64,
        "the preload stopped after {} of {} observations",
        preload.observations,
        args.models * args.preload
    );
    let mut local = Registry::new();
    let mut replay: Vec<Stream> = (0..args.models)
        .map(|i| Stream {
            cursor: 0,
            offset: 3600.0 * (i % 24) as f64,
        })
        .collect();
    let started = Instant::now();
    let (mut times, mut values) = (Vec::new(), Vec::new());
    for (id, stream) in ids.iter().zip(&mut replay) {
        let mut entry = Entry {
            config: config.clone(),
            model: config.empty_model().map_err(anyhow::Error::msg)?,
        };
        times.clear();
        values.clear();
        door.take(stream, args.preload, &mut times, &mut values);
        entry
            .observe(id, &times, &values)
            .map_err(|e| anyhow!("{e}"))?;
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
    if args.predict_times > 1 {
        probes.push(Probe::Predict(args.predict_times));
    }
    probes.push(Probe::Forecast);
    let mut latencies = Vec::with_capacity(probes.len());
    for probe in probes {
        let measured = runtime.block_on(measure(
            &clients,
            &queries,
            probe,
            args.requests,
            Duration::from_secs_f64(args.latency_seconds),
        ))?;
        let in_process_ns = match probe {
            Probe::Health => None,
            _ => Some(in_process(&local, &queries, probe)?),
        };
        latencies.push((probe, measured, in_process_ns));
    }

    // Durable throughput.
    let requests_total = args.observations.div_ceil(args.batch as u64) as usize;
    let started = Instant::now();
    let bodies: Vec<Vec<Body>> = owned
        .iter()
        .enumerate()
        .map(|(w, own)| {
            let requests = requests_total / writers + usize::from(w < requests_total % writers);
            throughput_bodies(&door, &mut streams, &ids, own, args, requests)
        })
        .collect::<Result<_>>()?;
    let encode_seconds = started.elapsed().as_secs_f64();
    let prepared: u64 = bodies.iter().flatten().map(|b| b.observations).sum();
    let body_bytes: usize = bodies.iter().flatten().map(|b| b.bytes.len()).sum();
    let seq_before = runtime.block_on(clients[0].health())?.seq;
    let sent = runtime.block_on(send_all(
        &clients,
        &token,
        bodies,
        Duration::from_secs_f64(args.seconds),
    ))?;
    let seq_after = runtime.block_on(clients[0].health())?.seq;
    let durable_rate = sent.observations as f64 / sent.seconds;

    drop(clients);
    drop(runtime);
    let _ = stop.send(());
    server
        .block_on(running)
        .context("the service task panicked")?
        .context("the service failed")?;
    drop(server);

    let baselines = write_baselines(&sent.bodies, &mut local, &dir.path)?;
    let kept = dir.keep.then(|| dir.path.clone());
    drop(dir);

    let report = Report {
        args,
        threads,
        writers,
        forecast_ids,
        preload,
        preload_in_process,
        preload_encode_seconds,
        latencies,
        sent,
        durable_rate,
        prepared,
        body_bytes,
        encode_seconds,
        commits: seq_after - seq_before,
        baselines,
        kept,
    };
    let mut out = std::io::stdout().lock();
    if args.json {
        writeln!(out, "{}", report.json())?;
    } else {
        report.print(&mut out)?;
    }
    Ok(())
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
    fn new(series: TimeSeries) -> Result<Self> {
        ensure!(
            series.len() >= 2,
            "the training data needs at least 2 observations"
        );
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
) -> Result<Body> {
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

/// One writer's preload: its models in groups of `--batch-ids`, `--preload` observations each,
/// the first request of a group creating its models.
fn preload_bodies(
    door: &Door,
    streams: &mut [Stream],
    ids: &[String],
    own: &[usize],
    args: &BenchServeArgs,
    config: &ModelConfig,
) -> Result<Vec<Body>> {
    let spec = config.spec.to_string();
    let mut bodies = Vec::new();
    for group in own.chunks(args.batch_ids) {
        let chunk = (args.batch / group.len()).max(1);
        let mut done = 0;
        while done < args.preload {
            let n = chunk.min(args.preload - done);
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

/// One writer's share of the throughput test: `requests` bodies of `--batch` observations,
/// cycling through its models in groups of `--batch-ids`.
fn throughput_bodies(
    door: &Door,
    streams: &mut [Stream],
    ids: &[String],
    own: &[usize],
    args: &BenchServeArgs,
    requests: usize,
) -> Result<Vec<Body>> {
    let groups: Vec<&[usize]> = own.chunks(args.batch_ids).collect();
    (0..requests)
        .map(|r| {
            let group = groups[r % groups.len()];
            let counts = split(args.batch, group.len());
            body(door, streams, ids, group, &counts, None)
        })
        .collect()
}

/// The service's data directory: `--data` (kept) or a temporary one (removed when dropped).
struct DataDir {
    path: PathBuf,
    keep: bool,
}

impl DataDir {
    fn new(data: Option<&Path>) -> Result<Self> {
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
        std::fs::create_dir_all(&path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        let occupied = std::fs::read_dir(&path)
            .with_context(|| format!("cannot read {}", path.display()))?
            .next()
            .is_some();
        if occupied {
            bail!(
                "{} is not empty; the benchmark needs a new or empty directory",
                path.display()
            );
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

fn random_token() -> Result<String> {
    let mut bytes = [0u8; 24];
    getrandom::fill(&mut bytes).map_err(|e| anyhow!("no random numbers for a token: {e}"))?;
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
    /// Its key in `--json` (`forecast_ids`: models per forecast).
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

impl Latencies {
    fn per_second(&self) -> f64 {
        self.requests as f64 / self.seconds
    }
}

/// Request `i` of client `c` (`forecast`: the forecast request, its time set here).
async fn call(
    client: &Client,
    queries: &Queries,
    forecast: &mut ForecastRequest,
    probe: Probe,
    c: usize,
    i: usize,
) -> Result<()> {
    let answer = async {
        Ok::<_, anyhow::Error>(match probe {
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
        .with_context(|| format!("{probe:?}: no answer"))??;
    ensure!(
        right_length,
        "the service answered with the wrong number of values"
    );
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
) -> Result<Latencies> {
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
                Ok::<_, anyhow::Error>((start, Instant::now(), latencies))
            })
        })
        .collect();
    let mut all = Vec::new();
    let (mut first, mut last) = (None::<Instant>, None::<Instant>);
    for task in tasks {
        let (start, end, latencies) = task
            .await
            .context("a client task panicked")?
            .with_context(|| format!("{probe:?} requests"))?;
        first = Some(first.map_or(start, |f| f.min(start)));
        last = Some(last.map_or(end, |l| l.max(end)));
        all.extend(latencies);
    }
    ensure!(!all.is_empty(), "no {probe:?} request finished in time");
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

/// Mean time (ns) of the same request computed in-process on equivalent models, as the
/// service's handler computes it (look-up by id, model at its order, predictions).
fn in_process(local: &Registry, queries: &Queries, probe: Probe) -> Result<f64> {
    let once = |i: usize| -> Result<f64> {
        Ok(match probe {
            Probe::Health => 0.0,
            Probe::Predict(k) => {
                let (id, times) = queries.predict(0, i, k);
                let entry = local.get(id).context("in-process model")?;
                let model = entry.with_order(None).map_err(anyhow::Error::msg)?;
                model.predict_many(&times).iter().sum()
            }
            Probe::Forecast => {
                let time = queries.forecast_time(0, i);
                let mut sum = 0.0;
                for id in &queries.ids[..queries.forecast_ids] {
                    let entry = local.get(id).context("in-process model")?;
                    let model = entry.with_order(None).map_err(anyhow::Error::msg)?;
                    sum += model.predict(time);
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
) -> Result<Sent> {
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
                        chronomap_client::Method::POST,
                        "/v1/observations",
                        body.bytes.clone(),
                        Some(&token),
                    );
                    let (status, text) = tokio::time::timeout(REQUEST_TIMEOUT, request)
                        .await
                        .context("POST /v1/observations: no answer")??;
                    ensure!(
                        status == chronomap_client::StatusCode::OK,
                        "POST /v1/observations: {status}: {text}"
                    );
                    let ack: WriteAck =
                        serde_json::from_str(&text).context("POST /v1/observations answer")?;
                    ensure!(
                        ack.observations == body.observations,
                        "{} of {} observations acknowledged",
                        ack.observations,
                        body.observations
                    );
                    last = Instant::now();
                    acknowledged.push(body);
                }
                Ok::<_, anyhow::Error>((last, acknowledged))
            })
        })
        .collect();
    let mut per_client = Vec::with_capacity(tasks.len());
    let mut last = started;
    for task in tasks {
        let (end, acknowledged) = task.await.context("a client task panicked")??;
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

/// One baseline: observations done and seconds taken.
struct Baseline {
    key: &'static str,
    what: &'static str,
    observations: u64,
    seconds: f64,
}

impl Baseline {
    fn rate(&self) -> f64 {
        self.observations as f64 / self.seconds
    }
}

/// The write path's pieces alone, on one thread, on a prefix of the acknowledged bodies.
fn write_baselines(bodies: &[Body], local: &mut Registry, dir: &Path) -> Result<Vec<Baseline>> {
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
    let parse = Baseline {
        key: "json_parse",
        what: "parse the request bodies (serde_json)",
        observations: bodies[..parsed.len()].iter().map(|b| b.observations).sum(),
        seconds: started.elapsed().as_secs_f64(),
    };

    let started = Instant::now();
    let mut applied = 0;
    let mut staged: HashMap<String, Entry> = HashMap::new();
    for request in &parsed {
        for batch in &request.batches {
            let entry = match staged.get_mut(&batch.id) {
                Some(entry) => entry,
                None => {
                    let entry = local.get(&batch.id).context("in-process model")?.clone();
                    staged.entry(batch.id.clone()).or_insert(entry)
                }
            };
            entry
                .observe(&batch.id, &batch.times, &batch.values)
                .map_err(|e| anyhow!("{e}"))?;
            applied += batch.times.len() as u64;
        }
        if started.elapsed() > limit {
            break;
        }
    }
    let apply = Baseline {
        key: "model_update",
        what: "apply the observations to in-process models",
        observations: applied,
        seconds: started.elapsed().as_secs_f64(),
    };
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
        groups.push((encode_group(&records), encoded));
        if started.elapsed() > limit {
            break;
        }
    }
    let encode = Baseline {
        key: "log_encode",
        what: "encode them as log groups (postcard, CRC-32)",
        observations: encoded,
        seconds: started.elapsed().as_secs_f64(),
    };

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
    let redb = Baseline {
        key: "redb_append",
        what: "append the groups to redb, one transaction (fsync) each",
        observations: written,
        seconds: started.elapsed().as_secs_f64(),
    };
    drop(store);
    std::fs::remove_file(&path).with_context(|| format!("cannot remove {}", path.display()))?;
    Ok(vec![parse, apply, encode, redb])
}

// ---------------------------------------------------------------------------------------------
// Report

struct Report<'a> {
    args: &'a BenchServeArgs,
    threads: usize,
    writers: usize,
    forecast_ids: usize,
    preload: Sent,
    preload_in_process: f64,
    preload_encode_seconds: f64,
    latencies: Vec<(Probe, Latencies, Option<f64>)>,
    sent: Sent,
    durable_rate: f64,
    prepared: u64,
    body_bytes: usize,
    encode_seconds: f64,
    commits: u64,
    baselines: Vec<Baseline>,
    kept: Option<PathBuf>,
}

impl Report<'_> {
    fn health_p50(&self) -> f64 {
        self.latencies
            .iter()
            .find(|(p, ..)| matches!(p, Probe::Health))
            .map_or(f64::NAN, |(_, l, _)| l.p50_us)
    }

    fn predict_p99(&self) -> f64 {
        self.latencies
            .iter()
            .find(|(p, ..)| matches!(p, Probe::Predict(1)))
            .map_or(f64::NAN, |(_, l, _)| l.p99_us)
    }

    /// Observations/s of the baselines' pieces one after the other on one thread.
    fn pipeline_rate(&self) -> f64 {
        1.0 / self.baselines.iter().map(|b| 1.0 / b.rate()).sum::<f64>()
    }

    fn json(&self) -> Value {
        let health = self.health_p50();
        let mut latency = serde_json::Map::new();
        for (probe, l, in_process) in &self.latencies {
            let mut entry = json!({
                "requests": l.requests,
                "seconds": l.seconds,
                "p50_us": l.p50_us,
                "p99_us": l.p99_us,
                "max_us": l.max_us,
                "requests_per_second": l.per_second(),
            });
            if let Some(ns) = in_process {
                entry["in_process_ns"] = json!(ns);
                entry["ratio_p50_to_in_process"] = json!(l.p50_us * 1e3 / ns);
                entry["ratio_p50_to_health"] = json!(l.p50_us / health);
            }
            latency.insert(probe.key(self.forecast_ids), entry);
        }
        let baselines: serde_json::Map<String, Value> = self
            .baselines
            .iter()
            .map(|b| {
                (
                    b.key.to_string(),
                    json!({
                        "observations": b.observations,
                        "seconds": b.seconds,
                        "observations_per_second": b.rate(),
                        "ratio_service_to_baseline": self.durable_rate / b.rate(),
                    }),
                )
            })
            .collect();
        json!({
            "models": self.args.models,
            "model": self.args.model,
            "clients": self.args.clients,
            "threads": self.threads,
            "preload": {
                "observations": self.preload.observations,
                "requests": self.preload.requests,
                "seconds": self.preload.seconds,
                "observations_per_second": self.preload.observations as f64 / self.preload.seconds,
                "in_process_seconds": self.preload_in_process,
                "client_encode_seconds": self.preload_encode_seconds,
            },
            "latency": latency,
            "throughput": {
                "observations": self.sent.observations,
                "requests": self.sent.requests,
                "writers": self.writers,
                "batch": self.args.batch,
                "batch_ids": self.args.batch_ids,
                "commits": self.commits,
                "seconds": self.sent.seconds,
                "observations_per_second": self.durable_rate,
                "prepared_observations": self.prepared,
                "body_bytes": self.body_bytes,
                "client_encode_seconds": self.encode_seconds,
                "baselines": baselines,
                "baseline_pipeline_observations_per_second": self.pipeline_rate(),
                "ratio_service_to_pipeline": self.durable_rate / self.pipeline_rate(),
            },
            "goals": {
                "predict_p99_under_1ms": self.predict_p99() < GOAL_P99_US,
                "durable_1m_observations_per_second": self.durable_rate >= GOAL_OBSERVATIONS_PER_SECOND,
            },
            "data": self.kept.as_ref().map(|p| p.display().to_string()),
        })
    }

    fn print(&self, out: &mut impl Write) -> Result<()> {
        let args = self.args;
        writeln!(
            out,
            "chronomap serve on 127.0.0.1 (redb store, bearer token), {} {} models, {}, {} hardware threads",
            args.models,
            args.model,
            clients(args.clients),
            self.threads
        )?;
        writeln!(
            out,
            "preload: {} observations ({} per model) in {} requests, durable in {:.2} s = {:.3e} observations/s (in-process models: {:.2} s)",
            self.preload.observations,
            args.preload,
            self.preload.requests,
            self.preload.seconds,
            self.preload.observations as f64 / self.preload.seconds,
            self.preload_in_process
        )?;
        writeln!(
            out,
            "\nlatency: {} back to back, up to {} requests each per kind (or {} s), after {WARM_UP} untimed ones",
            clients(args.clients),
            args.requests,
            args.latency_seconds
        )?;
        let health = self.health_p50();
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
        for (probe, l, in_process) in &self.latencies {
            let (ip, ratio, ratio_health) = match in_process {
                Some(ns) => (
                    format!("{:.3}", ns / 1e3),
                    format!("{:.0}", l.p50_us * 1e3 / ns),
                    format!("{:.2}", l.p50_us / health),
                ),
                None => ("-".into(), "-".into(), "1.00".into()),
            };
            table.row([
                probe.describe(self.forecast_ids),
                l.requests.to_string(),
                format!("{:.0}", l.p50_us),
                format!("{:.0}", l.p99_us),
                format!("{:.0}", l.max_us),
                format!("{:.0}", l.per_second()),
                ip,
                ratio,
                ratio_health,
            ]);
        }
        writeln!(out, "{}", table.render())?;
        writeln!(
            out,
            "\ndurable throughput: {}, POST /v1/observations of {} observations over {} models each ({:.1} MB of JSON bodies, encoded beforehand in {:.2} s)",
            clients(self.writers),
            args.batch,
            args.batch_ids.min(args.models.div_ceil(self.writers)),
            self.body_bytes as f64 / 1e6,
            self.encode_seconds
        )?;
        writeln!(
            out,
            "  {} observations in {} requests acknowledged in {:.2} s ({} commit groups{}) = {:.3e} durable observations/s",
            self.sent.observations,
            self.sent.requests,
            self.sent.seconds,
            self.commits,
            if self.sent.observations < self.prepared {
                format!(", stopped by --seconds before {}", self.prepared)
            } else {
                String::new()
            },
            self.durable_rate
        )?;
        let mut table = Table::new([
            "baseline (one thread, same bodies)",
            "observations",
            "observations/s",
            "service / baseline",
        ]);
        for b in &self.baselines {
            table.row([
                b.what.to_string(),
                b.observations.to_string(),
                format!("{:.3e}", b.rate()),
                format!("{:.2}", self.durable_rate / b.rate()),
            ]);
        }
        table.row([
            "all four one after the other".to_string(),
            "-".into(),
            format!("{:.3e}", self.pipeline_rate()),
            format!("{:.2}", self.durable_rate / self.pipeline_rate()),
        ]);
        writeln!(out, "{}", table.render())?;
        let p99 = self.predict_p99();
        writeln!(
            out,
            "\ngoals: predict p99 < 1 ms: {} ({p99:.0} µs); >= 1e6 durable observations/s in batches: {} ({:.3e})",
            if p99 < GOAL_P99_US { "met" } else { "missed" },
            if self.durable_rate >= GOAL_OBSERVATIONS_PER_SECOND {
                "met"
            } else {
                "missed"
            },
            self.durable_rate
        )?;
        if let Some(path) = &self.kept {
            writeln!(out, "the store is kept in {}", path.display())?;
        }
        Ok(())
    }
}

/// "1 client", "4 clients".
fn clients(n: usize) -> String {
    format!("{n} client{}", if n == 1 { "" } else { "s" })
}
