//! The service under load from requests that compute: a grid of the synthetic office of
//! [Krajník 2017] §VI (213,000 cells, a week of 5-second frames) and a CoPA-Map fitted on the
//! bundled ATC grid ([Stüde 2024] §4.2) are served over TCP while eight clients ask for their
//! predictions back to back, or for the largest `predict` and `evaluate` the service takes;
//! meanwhile `GET /v1/health` and a door prediction must stay fast, an abandoned prediction or
//! evaluation must stop computing, and a full pool must answer `503` with `Retry-After`.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use chronomap_activity::{CopaConfig, CopaMap};
use chronomap_core::Parallelism;
use chronomap_grid::AnyGrid;
use chronomap_grid::{FremenGrid, GridConfig};
use chronomap_serve::api::Health;
use chronomap_serve::heavy::HeavyLimits;
use chronomap_serve::maps::{Maps, ServedActivity};
use chronomap_serve::server::MAX_REQUEST_PREDICTIONS;
use chronomap_serve::store::RedbStore;
use chronomap_serve::{Service, ServiceConfig};

/// A time within the office's week (2016-01-06 12:00 UTC).
const OFFICE_NOON: f64 = 1_452_081_600.0;

/// The office grid, built once for all tests of this file.
fn office() -> &'static FremenGrid {
    static GRID: OnceLock<FremenGrid> = OnceLock::new();
    GRID.get_or_init(|| {
        let workload = chronomap_synth::office_grid::office(213_000, 7, 0).unwrap();
        workload
            .learned_grid(&GridConfig::default(), Parallelism::Rayon(0))
            .unwrap()
    })
}

/// A CoPA-Map fitted cheaply on the bundled ATC grid (as `chronomap activity fit --inducing 10
/// --iterations 3`).
fn atc() -> &'static CopaMap {
    static MODEL: OnceLock<CopaMap> = OnceLock::new();
    MODEL.get_or_init(|| {
        let train = chronomap_io::read_rate_samples(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz"
        ))
        .unwrap();
        let config = CopaConfig {
            inducing: 10,
            iterations: 3,
            ..CopaConfig::default()
        };
        CopaMap::fit(&train, &config).unwrap()
    })
}

/// A service on a loopback port with the office grid, the ATC map and a door model.
struct Served {
    port: u16,
    runtime: Option<tokio::runtime::Runtime>,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    _dir: std::path::PathBuf,
}

impl Served {
    fn start(name: &str, heavy: HeavyLimits) -> Served {
        let dir = std::env::temp_dir().join(format!(
            "chronomap-serve-load-{name}-{}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let mut maps = Maps::default();
        maps.grids
            .insert("office".into(), AnyGrid::State(Box::new(office().clone())));
        maps.activity
            .insert("atc".into(), ServedActivity::new(atc().clone(), None));
        let store = Arc::new(RedbStore::open(dir.join("chronomap.redb")).unwrap());
        let service = Service::start(
            store,
            ServiceConfig {
                maps: Arc::new(maps),
                heavy,
                ..ServiceConfig::default()
            },
        )
        .unwrap();
        // As `chronomap serve` runs it: a worker per hardware thread.
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .build()
            .unwrap();
        let listener = runtime
            .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
            .unwrap();
        let port = listener.local_addr().unwrap().port();
        let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
        runtime.spawn(service.run(listener, async {
            let _ = stopped.await;
        }));
        let served = Served {
            port,
            runtime: Some(runtime),
            stop: Some(stop),
            _dir: dir,
        };
        let times: Vec<f64> = (0..24).map(|h| 1.7e9 + 3600.0 * f64::from(h)).collect();
        let states: Vec<bool> = (0..24).map(|h| (8..18).contains(&h)).collect();
        let body = serde_json::json!({"id": "door", "model": "fremen:2", "times": times,
                                      "states": states});
        let (status, _, text) = served.connect().send("POST", "/v1/add", &body.to_string());
        assert_eq!(status, 200, "{}", String::from_utf8_lossy(&text));
        served
    }

    fn connect(&self) -> Connection {
        Connection::open(self.port)
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(runtime) = self.runtime.take() {
            runtime.shutdown_timeout(Duration::from_secs(10));
        }
    }
}

/// A keep-alive HTTP/1.1 connection.
struct Connection {
    reader: BufReader<TcpStream>,
}

impl Connection {
    fn open(port: u16) -> Connection {
        let stream = TcpStream::connect(("127.0.0.1", port)).unwrap();
        stream.set_nodelay(true).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(120)))
            .unwrap();
        Connection {
            reader: BufReader::new(stream),
        }
    }

    /// Sends a request without waiting for the answer.
    fn write(&mut self, method: &str, path: &str, body: &str) {
        let head = format!(
            "{method} {path} HTTP/1.1\r\nhost: 127.0.0.1\r\ncontent-type: application/json\r\n\
             content-length: {}\r\n\r\n{body}",
            body.len()
        );
        self.reader.get_mut().write_all(head.as_bytes()).unwrap();
    }

    /// Status, `Retry-After` and body of the answer.
    fn read(&mut self) -> (u16, Option<String>, Vec<u8>) {
        let mut line = String::new();
        self.reader.read_line(&mut line).unwrap();
        let status: u16 = line
            .split(' ')
            .nth(1)
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("status line {line:?}"));
        let (mut length, mut retry_after) = (None, None);
        loop {
            line.clear();
            self.reader.read_line(&mut line).unwrap();
            let header = line.trim_end();
            if header.is_empty() {
                break;
            }
            let (name, value) = header.split_once(':').unwrap();
            match name.to_ascii_lowercase().as_str() {
                "content-length" => length = value.trim().parse::<usize>().ok(),
                "retry-after" => retry_after = Some(value.trim().to_owned()),
                _ => {}
            }
        }
        let mut body = vec![0; length.expect("a content-length")];
        self.reader.read_exact(&mut body).unwrap();
        (status, retry_after, body)
    }

    fn send(&mut self, method: &str, path: &str, body: &str) -> (u16, Option<String>, Vec<u8>) {
        self.write(method, path, body);
        self.read()
    }

    fn health(&mut self) -> Health {
        let (status, _, body) = self.send("GET", "/v1/health", "");
        assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
        serde_json::from_slice(&body).unwrap()
    }
}

/// Held by the tests that measure latency, so that they do not load the machine for each
/// other (CI has two cores).
static MEASURING: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The `q` quantile of `samples` (s), in milliseconds.
fn quantile_ms(samples: &mut [f64], q: f64) -> f64 {
    samples.sort_by(f64::total_cmp);
    let i = ((q * samples.len() as f64).ceil() as usize).clamp(1, samples.len()) - 1;
    1000.0 * samples[i]
}

/// The `i`-th request of client `k` of a [`Load`]: its path, its body and the counter of its
/// answers (0 or 1).
type Request = dyn Fn(u32, u32) -> (&'static str, Arc<String>, usize) + Send + Sync;

/// Eight clients, each on a connection of its own, sending their requests back to back until
/// stopped. A `503` must say `Retry-After: 1`; the client then waits 50 ms.
struct Load {
    done: Arc<AtomicBool>,
    answered: Arc<[AtomicU64; 3]>,
    clients: Vec<std::thread::JoinHandle<()>>,
}

impl Load {
    fn start(served: &Served, request: Arc<Request>) -> Load {
        let done = Arc::new(AtomicBool::new(false));
        let answered = Arc::new([0, 1, 2].map(|_| AtomicU64::new(0)));
        let clients = (0..8)
            .map(|k| {
                let (done, answered) = (Arc::clone(&done), Arc::clone(&answered));
                let request = Arc::clone(&request);
                let mut connection = served.connect();
                std::thread::spawn(move || {
                    let mut i = 0u32;
                    while !done.load(Ordering::Acquire) {
                        let (path, body, counter) = request(k, i);
                        let (status, retry_after, text) = connection.send("POST", path, &body);
                        match status {
                            200 => {
                                answered[counter].fetch_add(1, Ordering::AcqRel);
                            }
                            503 => {
                                assert_eq!(retry_after.as_deref(), Some("1"));
                                answered[2].fetch_add(1, Ordering::AcqRel);
                                std::thread::sleep(Duration::from_millis(50));
                            }
                            _ => panic!("{path}: {status} {}", String::from_utf8_lossy(&text)),
                        }
                        i += 1;
                    }
                })
            })
            .collect();
        Load {
            done,
            answered,
            clients,
        }
    }

    /// Stops the clients: the answers counted by each of the two counters, and the `503`s.
    fn stop(self) -> [u64; 3] {
        self.done.store(true, Ordering::Release);
        for client in self.clients {
            client.join().unwrap();
        }
        [0, 1, 2].map(|k| self.answered[k].load(Ordering::Acquire))
    }
}

/// A prediction of the door at 12:30 on its day.
fn door_noon() -> String {
    serde_json::json!({"id": "door", "times": [1.7e9 + 12.5 * 3600.0]}).to_string()
}

/// What a client of its own measures for `seconds`, after 200 ms of the load: the seconds of
/// each `GET /v1/health` and of each [`door_noon`] prediction (5 ms apart), and the most heavy
/// requests running and waiting at once.
fn probe_under_load(served: &Served, seconds: f64) -> (Vec<f64>, Vec<f64>, u64) {
    let mut probe = served.connect();
    let door = door_noon();
    let (mut health, mut predict) = (Vec::new(), Vec::new());
    let mut busiest = 0;
    let start = Instant::now();
    std::thread::sleep(Duration::from_millis(200));
    while start.elapsed().as_secs_f64() < seconds {
        let t = Instant::now();
        let now = probe.health();
        health.push(t.elapsed().as_secs_f64());
        busiest = busiest.max(now.heavy_running + now.heavy_waiting);
        let t = Instant::now();
        let (status, _, body) = probe.send("POST", "/v1/predict", &door);
        predict.push(t.elapsed().as_secs_f64());
        assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
        std::thread::sleep(Duration::from_millis(5));
    }
    (health, predict, busiest)
}

/// The latencies of [`probe_under_load`], for a summary.
fn latencies(health: &mut [f64], predict: &mut [f64]) -> String {
    format!(
        "{} health requests: p50 {:.1} ms, p99 {:.1} ms; {} door predictions: p50 {:.1} ms, \
         p99 {:.1} ms",
        health.len(),
        quantile_ms(health, 0.5),
        quantile_ms(health, 0.99),
        predict.len(),
        quantile_ms(predict, 0.5),
        quantile_ms(predict, 0.99),
    )
}

/// At least 200 health requests were answered, and 99 % of them and of the door predictions
/// within 50 ms.
fn assert_fast(health: &mut [f64], predict: &mut [f64], summary: &str) {
    assert!(health.len() >= 200, "{summary}");
    assert!(quantile_ms(health, 0.99) <= 50.0, "{summary}");
    assert!(quantile_ms(predict, 0.99) <= 50.0, "{summary}");
}

/// Waits until the service computes a heavy request (at most 20 s).
fn wait_until_heavy_runs(probe: &mut Connection) {
    let start = Instant::now();
    while probe.health().heavy_running == 0 {
        assert!(start.elapsed() < Duration::from_secs(20), "it never ran");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The health once the heavy request a client left stopped, which must be within `limit` of
/// now: nothing waits, and it is counted as cancelled.
fn health_once_stopped(probe: &mut Connection, limit: Duration) -> Health {
    let gone = Instant::now();
    let health = loop {
        let health = probe.health();
        if health.heavy_running == 0 {
            break health;
        }
        assert!(
            gone.elapsed() < limit,
            "still computing {:.1} s after the client left",
            gone.elapsed().as_secs_f64()
        );
        std::thread::sleep(Duration::from_millis(5));
    };
    assert_eq!(
        (health.heavy_waiting, health.heavy_cancelled),
        (0, 1),
        "{health:?}"
    );
    health
}

/// The first 300 characters of a `503` answer with `Retry-After: 1`.
fn refused_busy((status, retry_after, body): (u16, Option<String>, Vec<u8>)) -> String {
    let text: String = String::from_utf8_lossy(&body).chars().take(300).collect();
    assert_eq!((status, retry_after.as_deref()), (503, Some("1")), "{text}");
    text
}

/// A service whose heavy pool has one worker and no queue.
fn one_heavy_worker(name: &str) -> Served {
    Served::start(
        name,
        HeavyLimits {
            workers: 1,
            queue: 0,
        },
    )
}

#[test]
fn health_and_a_door_prediction_stay_fast_while_eight_clients_ask_for_grid_and_activity_maps() {
    let _alone = MEASURING
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let served = Served::start("latency", HeavyLimits::default());

    // The first grid prediction fits the office's compact model; every prediction is the map
    // the grid itself predicts, bit for bit.
    let (status, _, body) = served.connect().send(
        "POST",
        "/v1/grid/office/predict",
        &serde_json::json!({ "time": OFFICE_NOON }).to_string(),
    );
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    let answer: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let values = answer["values"].as_array().unwrap();
    let expected = office().predict_map(OFFICE_NOON, Parallelism::Sequential);
    assert_eq!(values.len(), 213_000);
    let mut modelled = 0;
    for (i, (served, expected)) in values.iter().zip(&expected).enumerate() {
        match served.as_f64() {
            Some(v) => assert_eq!((v as f32).to_bits(), expected.to_bits(), "cell {i}"),
            None => assert!(expected.is_nan(), "cell {i}: {expected}"),
        }
        modelled += usize::from(expected.is_finite() && *expected > 0.0 && *expected < 1.0);
    }
    assert!(modelled > 1000, "{modelled} cells between 0 and 1");

    let load = Load::start(
        &served,
        Arc::new(|k, i| {
            if (i + k).is_multiple_of(2) {
                let time = OFFICE_NOON + 600.0 * f64::from(i);
                let body = serde_json::json!({ "time": time }).to_string();
                ("/v1/grid/office/predict", Arc::new(body), 0)
            } else {
                let t = 5.0 + f64::from(i % 7);
                let body = serde_json::json!({ "t": t }).to_string();
                ("/v1/activity/atc/predict", Arc::new(body), 1)
            }
        }),
    );
    let (mut health, mut predict, _) = probe_under_load(&served, 4.0);
    let [grids, activity, refused] = load.stop();
    let summary = format!(
        "{}; under load: {grids} grid maps, {activity} activity maps, {refused} 503",
        latencies(&mut health, &mut predict)
    );
    eprintln!("{summary}");
    assert!(grids >= 8 && activity >= 8, "{summary}");
    assert_fast(&mut health, &mut predict, &summary);
}

#[test]
fn an_abandoned_prediction_stops_and_a_full_pool_answers_503_with_retry_after() {
    // One worker, nobody waiting: a second heavy request while one computes is refused.
    let served = one_heavy_worker("abandoned");
    let mut probe = served.connect();
    // Cells of 5 cm over the 24 m square of ATC: 231,361 cells, seconds of work.
    let slow = serde_json::json!({"t": 5.0, "cell": 0.05}).to_string();
    let mut abandoned = served.connect();
    abandoned.write("POST", "/v1/activity/atc/predict", &slow);
    wait_until_heavy_runs(&mut probe);
    let text = refused_busy(served.connect().send(
        "POST",
        "/v1/grid/office/predict",
        &serde_json::json!({ "time": OFFICE_NOON }).to_string(),
    ));
    assert!(text.contains("--heavy-workers"), "{text}");
    // Cheap requests are answered meanwhile.
    let (status, _, body) = probe.send("GET", "/v1/activity/atc", "");
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));

    // The client goes away: the prediction stops within a chunk of 4096 cells.
    drop(abandoned);
    health_once_stopped(&mut probe, Duration::from_secs(2));
    // The worker is free again.
    let (status, _, body) = probe.send(
        "POST",
        "/v1/activity/atc/predict",
        &serde_json::json!({"t": 5.0}).to_string(),
    );
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
}

/// The largest `predict` the service takes: [`MAX_REQUEST_PREDICTIONS`] whole seconds of the
/// door's day in an irregular order (26 MB of JSON).
fn maximal_predict() -> String {
    let n = MAX_REQUEST_PREDICTIONS;
    let times: Vec<f64> = (0..n)
        .map(|i| 1.7e9 + ((i * 7919) % 86_400) as f64)
        .collect();
    serde_json::json!({ "id": "door", "times": times }).to_string()
}

/// The largest `evaluate` of the door's `fremen:2` model at every order up to its largest
/// (84: 85 orders) with a small body: 23,529 rows × 85 orders = 1,999,965 predictions.
fn maximal_evaluate() -> String {
    let rows = 23_529;
    let times: Vec<f64> = (0..rows).map(|i| 1.7e9 + 3.0 * f64::from(i)).collect();
    let values: Vec<f64> = (0..rows).map(|i| f64::from(i % 2)).collect();
    serde_json::json!({ "id": "door", "times": times, "values": values, "max_order": 1000 })
        .to_string()
}

#[test]
fn health_and_a_door_prediction_stay_fast_while_eight_clients_send_maximal_predictions() {
    let _alone = MEASURING
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let served = Served::start("maximal", HeavyLimits::default());
    let predict = Arc::new(maximal_predict());
    let evaluate = Arc::new(maximal_evaluate());
    // Both are the largest accepted: one more time or row is refused.
    let (status, _, body) = served.connect().send("POST", "/v1/evaluate", &evaluate);
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    let answer: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(answer["orders"].as_array().unwrap().len(), 85);

    let load = Load::start(
        &served,
        Arc::new(move |k, _| {
            if k % 2 == 0 {
                ("/v1/predict", Arc::clone(&predict), 0)
            } else {
                ("/v1/evaluate", Arc::clone(&evaluate), 1)
            }
        }),
    );
    let (mut health, mut door_times, busiest) = probe_under_load(&served, 4.0);
    let [predicts, evaluates, refused] = load.stop();
    let summary = format!(
        "{}; under load: {predicts} predictions of 2,000,000 times, {evaluates} evaluations of \
         1,999,965 predictions, {refused} 503, at most {busiest} heavy requests admitted at once",
        latencies(&mut health, &mut door_times)
    );
    eprintln!("{summary}");
    // The maximal requests went to the heavy pool, and were answered.
    assert!(busiest >= 4, "{summary}");
    assert!(predicts >= 1 && evaluates >= 1, "{summary}");
    assert_fast(&mut health, &mut door_times, &summary);
}

#[test]
fn an_abandoned_evaluation_stops_between_orders() {
    let served = one_heavy_worker("abandoned-evaluate");
    let mut probe = served.connect();
    let mut abandoned = served.connect();
    // 1,999,965 predictions, each of an order up to 84: seconds of work.
    abandoned.write("POST", "/v1/evaluate", &maximal_evaluate());
    wait_until_heavy_runs(&mut probe);
    // A second large request is refused while it computes; a small one is answered.
    refused_busy(
        served
            .connect()
            .send("POST", "/v1/evaluate", &maximal_evaluate()),
    );
    let (status, _, body) = probe.send("POST", "/v1/predict", &door_noon());
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));

    drop(abandoned);
    let health = health_once_stopped(&mut probe, Duration::from_secs(1));
    assert_eq!(
        (health.light_running, health.light_cancelled),
        (0, 0),
        "{health:?}"
    );
}
