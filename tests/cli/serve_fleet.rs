//! Fleet test of `chronomap serve --fleet`: three nodes on loopback over one PostgreSQL schema.
//! Clients write at full speed through all three nodes in turn (the same model through
//! different nodes), and after each write ask another node, with the write's sequence token,
//! whether it sees it; one node is killed with SIGKILL and restarted, twice. Afterwards every
//! acknowledged observation is present exactly once, nothing else is, and every node predicts
//! every model bit for bit as a model that saw the same observations in one process.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use chronomap_client::{Client, ClientError};
use chronomap_core::TemporalModel;
use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_serve::registry::ModelConfig;

use crate::serve_crash::{History, Sent, histories, present_batches};
use crate::service::{self, Backend, Server, free_port, scratch, start, token};

const NODES: usize = 3;
const CLIENTS: usize = 6;
const IDS_PER_CLIENT: usize = 2;
const SPECS: [&str; 4] = ["fremen:2", "persistence:2", "hist:24", "stm"];

/// Counts of the read-your-writes checks.
#[derive(Default)]
struct Checks {
    on_other_node: AtomicUsize,
}

async fn client_loop(
    urls: Vec<String>,
    token: String,
    client_index: usize,
    stop: Arc<AtomicBool>,
    history: Arc<Mutex<History>>,
    checks: Arc<Checks>,
) {
    let clients: Vec<Client> = urls
        .iter()
        .map(|url| Client::new(url, Some(token.clone())).unwrap())
        .collect();
    let mut rng = Xoshiro256StarStar::seed_from_u64(client_index as u64 + 11);
    let mut clock = [1_400_000_000.0_f64; IDS_PER_CLIENT];
    let mut node = client_index % NODES;
    while !stop.load(Ordering::Relaxed) {
        let slot = (rng.next_u64() % IDS_PER_CLIENT as u64) as usize;
        let (id, spec) = {
            let h = history.lock().unwrap();
            (h[slot].0.clone(), h[slot].1)
        };
        let n = 1 + (rng.next_u64() % 200) as usize;
        let mut times = Vec::with_capacity(n);
        let mut values = Vec::with_capacity(n);
        for _ in 0..n {
            clock[slot] += 60.0 + (rng.next_u64() % 1200) as f64 + rng.next_f64();
            let hour = (clock[slot] % 86_400.0) / 3600.0;
            let open = (8.0..18.0).contains(&hour);
            times.push(clock[slot]);
            values.push(f64::from(u8::from(open != (rng.next_f64() < 0.1))));
        }
        let writer = node;
        node = (node + 1) % NODES;
        let outcome = clients[writer]
            .add_values(&id, &times, &values, Some(spec))
            .await;
        let acknowledged = match &outcome {
            Ok(ack) => {
                assert_eq!(ack.observations, n as u64);
                true
            }
            Err(ClientError::Transport(_)) => false,
            Err(e) => panic!("client {client_index}: node {writer} refused a valid batch: {e}"),
        };
        let last = *times.last().unwrap();
        history.lock().unwrap()[slot].2.push(Sent {
            times,
            values,
            acknowledged,
        });
        match outcome {
            Ok(ack) => {
                // Read your write on the next node, with the write's token.
                let reader = clients[node].reading_after(ack.seq);
                match reader.view(&id).await {
                    Ok(info) => {
                        assert_eq!(
                            info.last_time,
                            Some(last),
                            "{id}: node {node} read with token {} does not see the write \
                             acknowledged by node {writer}",
                            ack.seq
                        );
                        checks.on_other_node.fetch_add(1, Ordering::Relaxed);
                    }
                    Err(ClientError::Transport(_)) => {}
                    Err(e) => panic!("{id}: read on node {node} failed: {e}"),
                }
            }
            // The node is down (killed): the next request goes to the next node.
            Err(_) => tokio::time::sleep(Duration::from_millis(10)).await,
        }
    }
}

fn flags(token_file: &std::path::Path) -> Vec<String> {
    [
        "--fleet",
        "--snapshot-every",
        "3000",
        "--snapshot-secs",
        "0.3",
        "--token-file",
    ]
    .iter()
    .map(|s| (*s).to_owned())
    .chain([token_file.display().to_string()])
    .collect()
}

fn start_node(data: &std::path::Path, port: u16, backend: &Backend, flags: &[String]) -> Server {
    let flags: Vec<&str> = flags.iter().map(String::as_str).collect();
    start(data, port, backend, &flags)
}

#[test]
fn a_fleet_of_three_loses_nothing_when_a_node_is_killed_twice() {
    let Some(backend) = service::postgres_backend("fleet") else {
        return;
    };
    let data: Vec<_> = (0..NODES)
        .map(|k| scratch(&format!("serve_fleet_{k}")))
        .collect();
    let ports: Vec<u16> = (0..NODES).map(|_| free_port()).collect();
    // The first node makes the token; the others read it.
    let first = start(&data[0], ports[0], &backend, &[]);
    first.stop();
    let token_file = data[0].join("token");
    let flags = flags(&token_file);
    let mut nodes: Vec<Option<Server>> = (0..NODES)
        .map(|k| Some(start_node(&data[k], ports[k], &backend, &flags)))
        .collect();
    let urls: Vec<String> = nodes
        .iter()
        .map(|n| n.as_ref().unwrap().url.clone())
        .collect();
    let token = token(&data[0]);

    let stop = Arc::new(AtomicBool::new(false));
    let checks = Arc::new(Checks::default());
    let histories = histories(CLIENTS, IDS_PER_CLIENT, &SPECS, |c, i, _| {
        format!("robot{c}/door-{i}")
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
                urls.clone(),
                token.clone(),
                c,
                Arc::clone(&stop),
                Arc::clone(h),
                Arc::clone(&checks),
            ))
        })
        .collect();

    // One node killed and restarted, twice, while the clients write.
    let victim = 1;
    let mut rng = Xoshiro256StarStar::seed_from_u64(2027);
    let mut restarts = Vec::new();
    for _ in 0..2 {
        std::thread::sleep(Duration::from_millis(400 + rng.next_u64() % 400));
        nodes[victim].take().unwrap().kill();
        std::thread::sleep(Duration::from_millis(50 + rng.next_u64() % 100));
        let restarted = start_node(&data[victim], ports[victim], &backend, &flags);
        restarts.push(restarted.started_in);
        nodes[victim] = Some(restarted);
    }
    std::thread::sleep(Duration::from_millis(500));
    stop.store(true, Ordering::Relaxed);
    runtime.block_on(async {
        for task in tasks {
            task.await.unwrap();
        }
    });

    let readers: Vec<Client> = urls.iter().map(|u| Client::new(u, None).unwrap()).collect();
    // Every node reaches the log's head without being asked to (its tailer).
    let head = runtime.block_on(readers[0].health()).unwrap().head;
    let level = Instant::now();
    for (k, reader) in readers.iter().enumerate() {
        loop {
            let health = runtime.block_on(reader.health()).unwrap();
            assert!(health.fleet && health.head >= head, "node {k}: {health:?}");
            if health.seq >= head {
                assert_eq!(health.status, "ok", "node {k}: {health:?}");
                break;
            }
            assert!(
                level.elapsed() < Duration::from_secs(10),
                "node {k} is not level with the log after 10 s: {health:?}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    let mut acknowledged = 0;
    let mut unacknowledged = 0;
    let mut durable_unacknowledged = 0;
    let mut compared = 0;
    for history in &histories {
        for (id, spec, sent) in history.lock().unwrap().iter() {
            acknowledged += sent.iter().filter(|b| b.acknowledged).count();
            unacknowledged += sent.iter().filter(|b| !b.acknowledged).count();
            if sent.is_empty() {
                continue;
            }
            let held = runtime.block_on(readers[2].observations(id)).unwrap();
            let present = present_batches(id, sent, &held.times, &held.values);
            durable_unacknowledged += present.iter().filter(|b| !b.acknowledged).count();
            let config = ModelConfig::parse(Some(spec), None).unwrap();
            let mut reference = config.empty_model().unwrap();
            for batch in &present {
                reference.observe(&batch.times, &batch.values).unwrap();
            }
            let last = present.last().map_or(1.4e9, |b| *b.times.last().unwrap());
            let probes: Vec<f64> = (0..200)
                .map(|k| last - 7.0 * 86_400.0 + k as f64 * 5_000.0)
                .collect();
            let expected = reference.predict_many(&probes);
            for (k, reader) in readers.iter().enumerate() {
                let served = runtime
                    .block_on(reader.reading_after(head).predict(id, &probes, None))
                    .unwrap();
                for (t, (s, r)) in probes.iter().zip(served.values.iter().zip(&expected)) {
                    assert_eq!(
                        s.to_bits(),
                        r.to_bits(),
                        "{id} ({spec}) on node {k} at t = {t}: served {s}, reference {r}"
                    );
                }
                compared += probes.len();
            }
        }
    }
    // The namespace question: one robot's models, from any node.
    let robot0 = runtime.block_on(readers[1].list_prefix("robot0/")).unwrap();
    assert_eq!(
        robot0
            .models
            .iter()
            .map(|m| m.id.as_str())
            .collect::<Vec<_>>(),
        ["robot0/door-0", "robot0/door-1"]
    );
    let read_your_writes = checks.on_other_node.load(Ordering::Relaxed);
    eprintln!(
        "fleet: {NODES} nodes, node {victim} SIGKILLed twice (restarts took {restarts:?}); \
         {acknowledged} acknowledged batches all present once, {unacknowledged} unacknowledged \
         ({durable_unacknowledged} of them durable); {read_your_writes} reads with a token on \
         another node saw the write; {compared} predictions bit-identical on every node"
    );
    assert!(
        acknowledged > 100,
        "the clients hardly wrote: {acknowledged} batches"
    );
    assert!(
        read_your_writes > 50,
        "few read-your-writes checks: {read_your_writes}"
    );
    assert!(unacknowledged >= 1, "no kill hit a request in flight");
}

/// Compaction: after checkpoints, the log's partitions that the checkpoint covers move to the
/// archive; a new node recovers from the snapshots and the rest of the log, predicts as the
/// nodes that saw everything, and the observations endpoint still reads the whole history.
#[test]
fn checkpointed_log_segments_move_to_the_archive_and_a_new_node_starts_after_them() {
    use chronomap_serve::store::{PostgresStore, Store};
    let Some(backend) = service::postgres_backend("fleet_compact") else {
        return;
    };
    let Backend::Postgres(config, schema) = &backend else {
        unreachable!("a postgres backend")
    };
    let data: Vec<_> = (0..3)
        .map(|k| scratch(&format!("serve_fleet_compact_{k}")))
        .collect();
    let ports: Vec<u16> = (0..3).map(|_| free_port()).collect();
    let flags: Vec<&str> = vec![
        "--fleet",
        "--no-token",
        "--postgres-segment-groups",
        "5",
        "--snapshot-every",
        "20",
        "--snapshot-secs",
        "0.05",
    ];
    let nodes: Vec<Server> = (0..2)
        .map(|k| start(&data[k], ports[k], &backend, &flags))
        .collect();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let clients: Vec<Client> = nodes
        .iter()
        .map(|n| Client::new(&n.url, None).unwrap())
        .collect();
    let mut rng = Xoshiro256StarStar::seed_from_u64(5);
    let mut sent = vec![(Vec::new(), Vec::new()); 2];
    let ids = ["lab/door", "lab/window"];
    let mut clock = [1.4e9, 1.4e9];
    for request in 0..60 {
        let m = request % 2;
        let (times, values): (Vec<f64>, Vec<f64>) = (0..7)
            .map(|_| {
                clock[m] += 300.0 + (rng.next_u64() % 900) as f64;
                (clock[m], f64::from(u8::from(rng.next_f64() < 0.4)))
            })
            .unzip();
        runtime
            .block_on(clients[request % 2].add_values(ids[m], &times, &values, Some("fremen:2")))
            .unwrap();
        sent[m].0.extend(times);
        sent[m].1.extend(values);
        // Let the checkpoints (every 20 observations or 0.05 s) happen along the way.
        std::thread::sleep(Duration::from_millis(5));
    }
    for node in nodes {
        node.stop();
    }
    let reader = PostgresStore::connect_reader(config, schema).unwrap();
    let recovered = reader.recover().unwrap();
    assert_eq!(recovered.last_seq, 60, "one commit group per request");
    assert!(
        recovered.compacted >= 50 && recovered.compacted.is_multiple_of(5),
        "whole segments of 5 groups up to the checkpoint {} are compacted: {}",
        recovered.checkpoint,
        recovered.compacted
    );
    assert!(recovered.compacted <= recovered.checkpoint);
    // A new node: snapshots + the live log only; the history is still whole.
    let newcomer = start(&data[2], ports[2], &backend, &flags);
    let client = Client::new(&newcomer.url, None).unwrap();
    for (m, id) in ids.iter().enumerate() {
        let held = runtime.block_on(client.observations(id)).unwrap();
        assert_eq!(
            (&held.times, &held.values),
            (&sent[m].0, &sent[m].1),
            "{id}"
        );
        let mut reference = ModelConfig::parse(Some("fremen:2"), None)
            .unwrap()
            .empty_model()
            .unwrap();
        reference.observe(&sent[m].0, &sent[m].1).unwrap();
        let probes: Vec<f64> = (0..100).map(|k| 1.4e9 + k as f64 * 3_000.0).collect();
        let served = runtime.block_on(client.predict(id, &probes, None)).unwrap();
        for (s, r) in served.values.iter().zip(reference.predict_many(&probes)) {
            assert_eq!(s.to_bits(), r.to_bits(), "{id}");
        }
    }
    let health = runtime.block_on(client.health()).unwrap();
    assert_eq!((health.seq, health.head, health.lag), (60, 60, 0));
    newcomer.stop();
    // The store passes the full check (snapshots, live log after the compacted positions).
    let (code, stdout, stderr) = service::serve_once(&[
        "--data".as_ref(),
        data[2].as_os_str(),
        "--postgres".as_ref(),
        config.as_ref(),
        "--postgres-schema".as_ref(),
        schema.as_ref(),
        "--check".as_ref(),
    ]);
    assert_eq!(code, 0, "{stdout}{stderr}");
}

/// `chronomap bench fleet`, small: every number is there, the baselines ran on the same
/// server, and the catch-up's two new nodes agree bit for bit.
#[test]
fn bench_fleet_reports_throughput_latency_baselines_and_catch_up() {
    let Some(config) = service::postgres() else {
        return;
    };
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args([
            "bench",
            "fleet",
            "--postgres",
            &config,
            "--nodes",
            "1,2",
            "--seconds",
            "0.5",
            "--models",
            "24",
            "--catch-up-observations",
            "200000",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let bench: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let runs = bench["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    for (run, nodes) in runs.iter().zip([1, 2]) {
        assert_eq!(run["nodes"], nodes);
        assert!(run["observations"].as_u64().unwrap() > 0, "{run}");
        assert!(run["predicts"].as_u64().unwrap() > 0, "{run}");
        assert!(run["predict_p99_us"].as_f64().unwrap() >= run["predict_p50_us"].as_f64().unwrap());
        let baselines = run["baselines"].as_array().unwrap();
        assert_eq!(baselines.len(), 2, "INSERT and COPY");
        for baseline in baselines {
            assert!(
                baseline["rows"].as_u64().unwrap() >= run["observations"].as_u64().unwrap() / 2
            );
            let ratio = baseline["ratio_fleet_to_baseline"].as_f64().unwrap();
            assert!(ratio.is_finite() && ratio > 0.0, "{baseline}");
        }
    }
    let catch_up = &bench["catch_up"];
    assert_eq!(catch_up["observations"], 200_000);
    assert_eq!(catch_up["groups"], 10, "groups of 20,000 observations");
    assert_eq!(
        catch_up["segments_compacted"], 1,
        "one whole segment of 10 groups"
    );
    assert_eq!(catch_up["identical"], true);
    // Bad flags are usage errors naming the flag.
    let bad = std::process::Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args(["bench", "fleet", "--postgres", &config, "--nodes", "0"])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--nodes"));
}

/// A node whose database sessions end (the server restarted, an administrator terminated them)
/// connects again, takes the schema's shared lock again, and goes on writing and tailing.
#[test]
fn a_fleet_node_reconnects_when_the_server_ends_its_sessions() {
    let Some(backend) = service::postgres_backend("fleet_reconnect") else {
        return;
    };
    let Backend::Postgres(config, schema) = &backend else {
        unreachable!("a postgres backend")
    };
    let application = format!("chronomap_test_{schema}");
    let node2_backend = Backend::Postgres(
        format!("{config} application_name={application}"),
        schema.clone(),
    );
    let data: Vec<_> = (0..2)
        .map(|k| scratch(&format!("serve_fleet_reconnect_{k}")))
        .collect();
    let ports: Vec<u16> = (0..2).map(|_| free_port()).collect();
    let flags = ["--fleet", "--no-token"];
    let node1 = start(&data[0], ports[0], &backend, &flags);
    let node2 = start(&data[1], ports[1], &node2_backend, &flags);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let (one, two) = (
        Client::new(&node1.url, None).unwrap(),
        Client::new(&node2.url, None).unwrap(),
    );
    let door = |t0: f64| (vec![t0, t0 + 60.0], vec![1.0, 0.0]);
    let (t, v) = door(1.4e9);
    runtime
        .block_on(two.add_values("lab/door", &t, &v, Some("fremen:2")))
        .unwrap();

    let sessions = |terminate: bool| -> i64 {
        runtime.block_on(async {
            let (client, connection) = tokio_postgres::connect(config, tokio_postgres::NoTls)
                .await
                .unwrap();
            tokio::spawn(connection);
            let sql = if terminate {
                "SELECT count(pg_terminate_backend(pid)) FROM pg_stat_activity WHERE application_name = $1"
            } else {
                "SELECT count(*) FROM pg_stat_activity WHERE application_name = $1"
            };
            client.query_one(sql, &[&application]).await.unwrap().get(0)
        })
    };
    assert_eq!(sessions(true), 2, "node 2's client and listener sessions");
    std::thread::sleep(Duration::from_millis(300));

    // Node 2 writes again (at most one write may meet the dead session first).
    let (t, v) = door(1.4e9 + 600.0);
    let mut attempts = 0;
    let ack = loop {
        attempts += 1;
        match runtime.block_on(two.add_values("lab/door", &t, &v, None)) {
            Ok(ack) => break ack,
            Err(e)
                if attempts < 2
                    && e.status() == Some(chronomap_client::StatusCode::SERVICE_UNAVAILABLE) => {}
            Err(e) => panic!("node 2 does not write after reconnecting: {e}"),
        }
    };
    assert_eq!(ack.observations, 2);
    assert_eq!(sessions(false), 2, "node 2 has its two sessions back");
    // Node 1's write reaches node 2 without a token (its tailer listens again).
    let (t, v) = door(1.4e9 + 1200.0);
    let written = runtime
        .block_on(one.add_values("lab/door", &t, &v, None))
        .unwrap();
    let waited = Instant::now();
    loop {
        let health = runtime.block_on(two.health()).unwrap();
        if health.seq >= written.seq {
            assert_eq!(health.status, "ok");
            break;
        }
        assert!(waited.elapsed() < Duration::from_secs(5), "{health:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
    let info = runtime.block_on(two.view("lab/door")).unwrap();
    assert_eq!(info.observations, 6);
    // The command-line client: a token read on the other node, and one namespace's models.
    let client_cli = |args: &[&str]| {
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_chronomap"))
            .args(["client", "--url"])
            .args(args)
            .output()
            .unwrap();
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        serde_json::from_slice::<serde_json::Value>(&output.stdout).unwrap()
    };
    let (t, v) = door(1.4e9 + 1800.0);
    let written = runtime
        .block_on(two.add_values("lab/door", &t, &v, None))
        .unwrap();
    let view = client_cli(&[
        &node1.url,
        "--read-after",
        &written.seq.to_string(),
        "view",
        "lab/door",
    ]);
    assert_eq!(view["observations"], 8, "{view}");
    runtime
        .block_on(one.add_values("yard/gate", &t, &v, Some("fremen:2")))
        .unwrap();
    let listed = client_cli(&[&node1.url, "list", "--prefix", "lab/", "--json"]);
    assert_eq!(listed["models"].as_array().unwrap().len(), 1, "{listed}");
    drop((node1, node2));
}

/// A damaged group in the shared log stops every node from applying past it: health says
/// `failed` and names the entry, writes are refused, reads answer from the last good position.
#[test]
fn a_damaged_group_in_the_shared_log_fails_the_nodes_loudly_and_keeps_their_reads() {
    use chronomap_serve::store::{PostgresStore, Store};
    let Some(backend) = service::postgres_backend("fleet_damage") else {
        return;
    };
    let Backend::Postgres(config, schema) = &backend else {
        unreachable!("a postgres backend")
    };
    let data = scratch("serve_fleet_damage");
    let port = free_port();
    let node = start(&data, port, &backend, &["--fleet", "--no-token"]);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let client = Client::new(&node.url, None).unwrap();
    let ack = runtime
        .block_on(client.add_values(
            "lab/door",
            &[1.4e9, 1.4e9 + 60.0],
            &[1.0, 0.0],
            Some("fremen:2"),
        ))
        .unwrap();
    // Another writer (a broken tool, a bad restore) puts garbage at the next position.
    let store = PostgresStore::connect_fleet(config, schema).unwrap();
    store
        .append(ack.seq + 1, b"CMLOG\x002\nnot a commit group")
        .unwrap();
    let waited = Instant::now();
    let health = loop {
        let health = runtime.block_on(client.health()).unwrap();
        if health.status != "ok" {
            break health;
        }
        assert!(waited.elapsed() < Duration::from_secs(5), "{health:?}");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(health.status, "failed");
    let reason = health.reason.unwrap();
    assert!(
        reason.contains(&format!("log entry {}", ack.seq + 1)),
        "{reason}"
    );
    assert_eq!(
        (health.seq, health.head, health.lag),
        (ack.seq, ack.seq + 1, 1)
    );
    let refused = runtime
        .block_on(client.add_values("lab/door", &[1.4e9 + 120.0], &[1.0], None))
        .unwrap_err();
    assert_eq!(
        refused.status(),
        Some(chronomap_client::StatusCode::SERVICE_UNAVAILABLE),
        "{refused}"
    );
    let info = runtime.block_on(client.view("lab/door")).unwrap();
    assert_eq!(
        info.observations, 2,
        "reads answer from the last good position"
    );
    drop(node);
}

/// A node that fell behind a compaction catches up from the archive when it appends: its
/// catch-up sees every group in order, the archived ones included, then appends after them.
#[test]
fn an_append_catches_up_through_the_archive() {
    use chronomap_serve::store::{Access, Checkpoint, OWNER_WAIT, PostgresStore, Store};
    let Some(Backend::Postgres(config, schema)) = service::postgres_backend("fleet_archive") else {
        return;
    };
    let open =
        || PostgresStore::connect_with(&config, &schema, Access::Fleet, OWNER_WAIT, 5).unwrap();
    let (behind, ahead) = (open(), open());
    let group = |seq: u64| {
        chronomap_serve::log::encode_group(
            seq,
            &[chronomap_serve::log::LogRecord::Remove {
                id: format!("m{seq}"),
            }],
        )
    };
    for seq in 1..=23 {
        let appended = ahead
            .append_next(seq - 1, &mut |_, _| Ok(()), &mut |next| Some(group(next)))
            .unwrap();
        assert_eq!(appended, Some(seq));
    }
    ahead
        .checkpoint(&Checkpoint {
            seq: 23,
            snapshots: &[],
            removed: &[],
        })
        .unwrap();
    assert_eq!(
        ahead.compact().unwrap(),
        4,
        "segments 1-5, 6-10, 11-15, 16-20"
    );
    assert_eq!(behind.recover().unwrap().compacted, 20);
    let mut seen = Vec::new();
    let appended = behind
        .append_next(
            0,
            &mut |seq, bytes| {
                assert_eq!(bytes, group(seq).as_slice());
                seen.push(seq);
                Ok(())
            },
            &mut |next| Some(group(next)),
        )
        .unwrap();
    assert_eq!(seen, (1..=23).collect::<Vec<_>>());
    assert_eq!(appended, Some(24));
    let mut scanned = Vec::new();
    behind
        .scan(1, &mut |seq, _| {
            scanned.push(seq);
            Ok(())
        })
        .unwrap();
    assert_eq!(scanned, (1..=24).collect::<Vec<_>>());
}
