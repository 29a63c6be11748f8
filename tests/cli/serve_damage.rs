//! Damaged stores: real byte flips in `chronomap.redb` after a clean stop and after SIGKILL.
//! The start must stop naming the damaged entry (and the model it still names) and say how to
//! recover; `--check` reports and exits 1; `--salvage` keeps every intact model and
//! observation, after which the service starts again. PostgreSQL: a damaged entry behind the
//! checkpoint, the same way.

use crate::service;

use std::ffi::OsStr;
use std::path::Path;

use chronomap_client::Client;
use chronomap_core::TemporalModel;
use chronomap_serve::registry::ModelConfig;
use service::{Backend, free_port, scratch, serve_once, start, token};

/// A time only the batch `k` of "door" holds (not first or last of the model, so no snapshot
/// holds it either): its bytes mark the log entry in the file.
fn marker(k: usize) -> f64 {
    1_400_000_000.0 + k as f64 * 86_400.0 + 1234.5625
}

/// The batches: "door" 6 of 5 observations, "lab" 6 of 4, each batch its own log entry.
fn batches() -> Vec<(&'static str, Vec<f64>, Vec<f64>)> {
    let mut all = Vec::new();
    for k in 0..6 {
        let t0 = 1_400_000_000.0 + k as f64 * 86_400.0;
        all.push((
            "door",
            vec![t0, t0 + 600.0, marker(k), t0 + 3600.0, t0 + 7200.0],
            vec![0.0, 1.0, 1.0, 0.0, 1.0],
        ));
        all.push((
            "lab",
            vec![t0 + 10.0, t0 + 20.0, t0 + 30.0, t0 + 40.0],
            vec![1.0, 1.0, 0.0, 1.0],
        ));
    }
    all
}

fn fill(url: &str, data: &Path) {
    let client = Client::new(url, Some(token(data))).unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    for (id, times, values) in batches() {
        runtime
            .block_on(client.add_values(id, &times, &values, Some("fremen:2")))
            .unwrap();
    }
}

/// Flips one bit of every copy of `needle` in the file; returns how many.
fn flip(file: &Path, needle: &[u8]) -> usize {
    let mut bytes = std::fs::read(file).unwrap();
    let places: Vec<usize> = bytes
        .windows(needle.len())
        .enumerate()
        .filter(|(_, w)| *w == needle)
        .map(|(i, _)| i)
        .collect();
    for &at in &places {
        bytes[at + 1] ^= 0x04;
    }
    std::fs::write(file, bytes).unwrap();
    places.len()
}

fn args<'a>(data: &'a Path, extra: &'a [&'a str]) -> Vec<&'a OsStr> {
    let mut all: Vec<&OsStr> = vec!["--data".as_ref(), data.as_os_str()];
    all.extend(extra.iter().map(OsStr::new));
    all
}

/// After the salvage, "lab" is whole and "door" lost only the damaged batch `lost`: both
/// predict as models that observed exactly those batches.
fn check_salvaged(data: &Path, lost: usize) {
    let port = free_port();
    let server = start(data, port, &Backend::Redb, &[]);
    let client = Client::new(&server.url, None).unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    for id in ["door", "lab"] {
        let config = ModelConfig::parse(Some("fremen:2"), None).unwrap();
        let mut reference = config.empty_model().unwrap();
        let mut k = 0;
        for (batch_id, times, values) in batches() {
            if batch_id != id {
                continue;
            }
            if !(id == "door" && k == lost) {
                reference.observe(&times, &values).unwrap();
            }
            k += 1;
        }
        let probes: Vec<f64> = (0..50).map(|i| 1.4e9 + i as f64 * 7_000.0).collect();
        let served = runtime.block_on(client.predict(id, &probes, None)).unwrap();
        let expected = reference.predict_many(&probes);
        assert_eq!(served.values, expected, "{id}");
        let info = runtime.block_on(client.view(id)).unwrap();
        assert_eq!(info.observations, reference.span().count, "{id}");
    }
    server.stop();
    let (code, stdout, stderr) = serve_once(&args(data, &["--check"]));
    assert_eq!(code, 0, "{stdout}{stderr}");
    assert!(
        stdout.contains("ok: every snapshot and log entry is intact"),
        "{stdout}"
    );
}

#[test]
fn a_flipped_byte_behind_the_last_checkpoint_stops_the_start_and_salvage_keeps_the_rest() {
    let data = scratch("serve_damage_clean");
    let port = free_port();
    let server = start(&data, port, &Backend::Redb, &[]);
    fill(&server.url, &data);
    // A clean stop: the last checkpoint covers every log entry.
    server.stop();
    let file = data.join("chronomap.redb");
    assert!(flip(&file, &marker(2).to_le_bytes()) >= 1);

    let (code, stdout, stderr) = serve_once(&args(&data, &["--listen", "127.0.0.1:0"]));
    assert_eq!(code, 1, "the damaged store started: {stdout}{stderr}");
    for needed in [
        "log entry 5: checksum mismatch",
        "\"door\"",
        "--check",
        "--salvage",
    ] {
        assert!(stderr.contains(needed), "missing {needed:?} in: {stderr}");
    }
    let (code, stdout, stderr) = serve_once(&args(&data, &["--check"]));
    assert_eq!(code, 1, "{stdout}{stderr}");
    assert!(stdout.contains("damaged: "), "{stdout}");
    assert!(stdout.contains("log entry 5"), "{stdout}");

    let (code, stdout, stderr) = serve_once(&args(&data, &["--salvage"]));
    assert_eq!(code, 0, "{stdout}{stderr}");
    assert!(
        stdout.contains("kept: 2 models, 49 observations"),
        "{stdout}"
    );
    assert!(
        stdout.contains("log entry 5: checksum mismatch"),
        "{stdout}"
    );
    let kept = std::fs::read_dir(&data)
        .unwrap()
        .filter_map(Result::ok)
        .any(|e| {
            e.file_name()
                .to_string_lossy()
                .starts_with("chronomap.redb.damaged-")
        });
    assert!(kept, "the damaged file is kept");
    check_salvaged(&data, 2);
}

#[test]
fn a_file_redb_cannot_repair_after_sigkill_is_named_and_salvaged_from_its_raw_bytes() {
    let data = scratch("serve_damage_killed");
    let port = free_port();
    let server = start(&data, port, &Backend::Redb, &[]);
    fill(&server.url, &data);
    server.kill();
    let file = data.join("chronomap.redb");
    assert!(flip(&file, &marker(4).to_le_bytes()) >= 1);

    let (code, stdout, stderr) = serve_once(&args(&data, &["--listen", "127.0.0.1:0"]));
    assert_eq!(code, 1, "the damaged store started: {stdout}{stderr}");
    assert!(stderr.contains("--salvage"), "{stderr}");
    let (code, stdout, stderr) = serve_once(&args(&data, &["--check"]));
    assert_eq!(code, 1, "{stdout}{stderr}");
    assert!(stdout.contains("damaged"), "{stdout}");

    let (code, stdout, stderr) = serve_once(&args(&data, &["--salvage"]));
    assert_eq!(code, 0, "{stdout}{stderr}");
    eprintln!("{stdout}");
    check_salvaged(&data, 4);
}

/// PostgreSQL keeps its own page checksums; a damaged entry is written through the store and
/// a checkpoint placed after it, as a flip behind the checkpoint would leave it.
#[test]
fn a_damaged_entry_behind_the_checkpoint_stops_the_start_postgres() {
    use chronomap_serve::store::{Checkpoint, PostgresStore, Store};
    let Some(Backend::Postgres(config, schema)) = service::postgres_backend("damage") else {
        return;
    };
    let backend = Backend::Postgres(config.clone(), schema.clone());
    let data = scratch("serve_damage_postgres");
    let port = free_port();
    let server = start(&data, port, &backend, &[]);
    fill(&server.url, &data);
    server.stop();
    {
        let store = PostgresStore::connect(&config, &schema).unwrap();
        let last = store.recover().unwrap().last_seq;
        let mut bytes = chronomap_serve::log::encode_group(
            last + 1,
            &[chronomap_serve::log::LogRecord::Remove { id: "door".into() }],
        );
        *bytes.last_mut().unwrap() ^= 0x01;
        store.append(last + 1, &bytes).unwrap();
        store
            .checkpoint(&Checkpoint {
                seq: last + 1,
                snapshots: &[],
                removed: &[],
            })
            .unwrap();
    }
    let pg = [
        "--postgres",
        config.as_str(),
        "--postgres-schema",
        schema.as_str(),
    ];
    let mut start_args = pg.to_vec();
    start_args.extend(["--listen", "127.0.0.1:0"]);
    let (code, stdout, stderr) = serve_once(&args(&data, &start_args));
    assert_eq!(code, 1, "the damaged store started: {stdout}{stderr}");
    assert!(stderr.contains("log entry 13"), "{stderr}");
    let mut check = pg.to_vec();
    check.push("--check");
    let (code, stdout, _) = serve_once(&args(&data, &check));
    assert_eq!(code, 1, "{stdout}");
    let mut salvage = pg.to_vec();
    salvage.push("--salvage");
    let (code, stdout, stderr) = serve_once(&args(&data, &salvage));
    assert_eq!(code, 0, "{stdout}{stderr}");
    assert!(
        stdout.contains("kept: 2 models, 54 observations"),
        "{stdout}"
    );
    let salvaged = Backend::Postgres(config.clone(), format!("{schema}_salvaged"));
    let server = start(&data, free_port(), &salvaged, &[]);
    server.stop();
}
