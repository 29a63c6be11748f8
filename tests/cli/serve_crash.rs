//! Crash test of `chronomap serve`: several clients add observations at full speed while the
//! server is killed with SIGKILL at random moments and restarted. Afterwards every
//! acknowledged observation must be present, nothing may be there that was not sent, and
//! every model must predict bit for bit as a model that saw the same observations without
//! interruption. Run for the embedded store and for PostgreSQL.

use crate::service;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use chronomap_client::{Client, ClientError};
use chronomap_core::TemporalModel;
use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_serve::registry::ModelConfig;
use service::{Backend, Server, free_port, scratch, start, token};

/// Model kinds exercised (every snapshot format the service writes).
const SPECS: [&str; 5] = ["fremen:2", "persistence:2", "hist:24", "pergam:2", "stm"];
const CLIENTS: usize = 4;
const IDS_PER_CLIENT: usize = 3;
const KILLS: usize = 5;

/// One batch a client sent, and whether the service acknowledged it.
#[derive(Clone, Debug)]
pub(crate) struct Sent {
    pub(crate) times: Vec<f64>,
    pub(crate) values: Vec<f64>,
    pub(crate) acknowledged: bool,
}

/// What one client sent to each of its ids.
pub(crate) type History = Vec<(String, &'static str, Vec<Sent>)>;

async fn client_loop(
    url: String,
    token: String,
    client_index: usize,
    stop: Arc<AtomicBool>,
    history: Arc<Mutex<History>>,
) {
    let client = Client::new(&url, Some(token)).unwrap();
    let mut rng = Xoshiro256StarStar::seed_from_u64(client_index as u64 + 1);
    let mut clock = [1_400_000_000.0_f64; IDS_PER_CLIENT];
    while !stop.load(Ordering::Relaxed) {
        let slot = (rng.next_u64() % IDS_PER_CLIENT as u64) as usize;
        let (id, spec) = {
            let h = history.lock().unwrap();
            (h[slot].0.clone(), h[slot].1)
        };
        let n = 1 + (rng.next_u64() % 300) as usize;
        let mut times = Vec::with_capacity(n);
        let mut values = Vec::with_capacity(n);
        for _ in 0..n {
            clock[slot] += 60.0 + (rng.next_u64() % 1200) as f64 + rng.next_f64();
            let hour = (clock[slot] % 86_400.0) / 3600.0;
            let open = (8.0..18.0).contains(&hour);
            let noise = rng.next_f64() < 0.1;
            times.push(clock[slot]);
            values.push(f64::from(u8::from(open != noise)));
        }
        let outcome = client.add_values(&id, &times, &values, Some(spec)).await;
        let acknowledged = match outcome {
            Ok(ack) => {
                assert_eq!(ack.observations, n as u64);
                true
            }
            Err(ClientError::Transport(_)) => false,
            Err(e) => panic!("client {client_index}: the service refused a valid batch: {e}"),
        };
        history.lock().unwrap()[slot].2.push(Sent {
            times,
            values,
            acknowledged,
        });
        if !acknowledged {
            // The server is down (killed); wait for the restart.
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }
}

/// For each of `clients` clients, its `ids` models (named by `name(client, i, k)` with `k` the
/// model's number over all clients, kinds taken round-robin from `specs`), nothing sent yet.
pub(crate) fn histories(
    clients: usize,
    ids: usize,
    specs: &[&'static str],
    name: impl Fn(usize, usize, usize) -> String,
) -> Vec<Arc<Mutex<History>>> {
    (0..clients)
        .map(|c| {
            let models = (0..ids)
                .map(|i| {
                    let k = c * ids + i;
                    (name(c, i, k), specs[k % specs.len()], Vec::new())
                })
                .collect();
            Arc::new(Mutex::new(models))
        })
        .collect()
}

/// Matches what the service holds against what was sent: acknowledged batches must all be
/// there, unacknowledged ones may be (the crash came after the commit, before the answer),
/// nothing else may. Returns the batches present.
pub(crate) fn present_batches(id: &str, sent: &[Sent], times: &[f64], values: &[f64]) -> Vec<Sent> {
    let mut at = 0;
    let mut present = Vec::new();
    for (k, batch) in sent.iter().enumerate() {
        let n = batch.times.len();
        let matches = at + n <= times.len()
            && times[at..at + n] == batch.times[..]
            && values[at..at + n] == batch.values[..];
        if matches {
            present.push(batch.clone());
            at += n;
        } else {
            assert!(
                !batch.acknowledged,
                "{id}: acknowledged batch {k} ({n} observations from t = {}) is missing",
                batch.times[0]
            );
        }
    }
    assert_eq!(
        at,
        times.len(),
        "{id}: the service holds observations that were never sent"
    );
    present
}

fn crash_test(name: &str, backend: Backend) {
    let data = scratch(name);
    let port = free_port();
    // Small checkpoints, so that recovery loads snapshots *and* replays the log.
    let flags = ["--snapshot-every", "2000", "--snapshot-secs", "0.2"];
    let mut server = Some(start(&data, port, &backend, &flags));
    let url = server.as_ref().unwrap().url.clone();
    let token = token(&data);

    let stop = Arc::new(AtomicBool::new(false));
    let histories = histories(CLIENTS, IDS_PER_CLIENT, &SPECS, |_, _, k| {
        format!("{name}/door-{k}")
    });
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let tasks: Vec<_> = histories
        .iter()
        .enumerate()
        .map(|(c, h)| {
            runtime.spawn(client_loop(
                url.clone(),
                token.clone(),
                c,
                Arc::clone(&stop),
                Arc::clone(h),
            ))
        })
        .collect();

    let mut rng = Xoshiro256StarStar::seed_from_u64(2026);
    let mut restarts = Vec::new();
    for _ in 0..KILLS {
        std::thread::sleep(Duration::from_millis(150 + rng.next_u64() % 450));
        server.take().unwrap().kill();
        std::thread::sleep(Duration::from_millis(rng.next_u64() % 100));
        let restarted = start(&data, port, &backend, &flags);
        restarts.push(restarted.started_in);
        server = Some(restarted);
    }
    std::thread::sleep(Duration::from_millis(300));
    stop.store(true, Ordering::Relaxed);
    runtime.block_on(async {
        for task in tasks {
            task.await.unwrap();
        }
    });
    // One last kill, so that the final state is also a recovered one.
    server.take().unwrap().kill();
    let server: Server = start(&data, port, &backend, &flags);

    let client = Client::new(&server.url, None).unwrap();
    let mut acknowledged = 0;
    let mut unacknowledged = 0;
    let mut durable_unacknowledged = 0;
    let mut checked_predictions = 0;
    for history in &histories {
        for (id, spec, sent) in history.lock().unwrap().iter() {
            acknowledged += sent.iter().filter(|b| b.acknowledged).count();
            unacknowledged += sent.iter().filter(|b| !b.acknowledged).count();
            if sent.is_empty() {
                continue;
            }
            let held = runtime.block_on(client.observations(id)).unwrap();
            let present = present_batches(id, sent, &held.times, &held.values);
            durable_unacknowledged += present.iter().filter(|b| !b.acknowledged).count();
            // The uninterrupted reference: the same batches, observed in one process.
            let config = ModelConfig::parse(Some(spec), None).unwrap();
            let mut reference = config.empty_model().unwrap();
            for batch in &present {
                reference.observe(&batch.times, &batch.values).unwrap();
            }
            let last = present.last().map_or(1.4e9, |b| *b.times.last().unwrap());
            let probes: Vec<f64> = (0..200)
                .map(|k| last - 7.0 * 86_400.0 + k as f64 * 5_000.0)
                .collect();
            let served = runtime.block_on(client.predict(id, &probes, None)).unwrap();
            for (t, (s, r)) in probes
                .iter()
                .zip(served.values.iter().zip(reference.predict_many(&probes)))
            {
                assert_eq!(
                    s.to_bits(),
                    r.to_bits(),
                    "{id} ({spec}) at t = {t}: served {s}, reference {r}"
                );
            }
            checked_predictions += probes.len();
            let info = runtime.block_on(client.view(id)).unwrap();
            assert_eq!(info.observations, reference.span().count);
        }
    }
    eprintln!(
        "{name}: {KILLS} SIGKILLs + 1; {acknowledged} acknowledged batches all present, \
         {unacknowledged} unacknowledged ({durable_unacknowledged} of them durable); {checked_predictions} predictions bit-identical; \
         restarts took {:?}",
        restarts
    );
    assert!(
        acknowledged > 50,
        "the clients hardly wrote: {acknowledged} batches"
    );
    assert!(unacknowledged >= 1, "no kill hit a request in flight");
}

service::on_each_backend!(
    crash_test,
    "crash",
    sigkill_loses_no_acknowledged_observation_redb,
    sigkill_loses_no_acknowledged_observation_postgres
);

/// One service per schema: a second store on a schema that a live session holds is refused
/// with a message that says so, and gets the schema once the first is gone (as a restarted
/// service does after a crash, when PostgreSQL has ended the dead process's session).
#[test]
fn a_postgres_schema_has_one_owner_at_a_time() {
    use chronomap_serve::store::PostgresStore;
    let Some(config) = service::postgres() else {
        return;
    };
    let schema = format!("owner_{}", std::process::id());
    let first = PostgresStore::connect(&config, &schema).unwrap();
    let wait = Duration::from_millis(300);
    let refused = PostgresStore::connect_waiting(&config, &schema, wait)
        .err()
        .expect("a second owner of a held schema");
    let message = refused.to_string();
    assert!(
        message.contains(&format!("postgres schema {schema}")),
        "{message}"
    );
    assert!(message.contains("one service per schema"), "{message}");
    drop(first);
    PostgresStore::connect_waiting(&config, &schema, Duration::from_secs(5)).unwrap();
}
