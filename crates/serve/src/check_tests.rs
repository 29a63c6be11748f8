//! The reading side of a store on damaged files: seeded mutations (bit flips, overwritten
//! bytes, cuts, zeroed pages) of a real redb store are opened read-only, verified and read to
//! the end as `chronomap export parquet` reads them, and checked as `chronomap serve --check`
//! checks them. Each must give a result or an error naming the file, never a panic, and must
//! leave the file's bytes and time as they were.
//!
//! The number of cases is small enough for CI; set `PROPTEST_CASES` for a deeper run, e.g.
//! `PROPTEST_CASES=10000 cargo test --release -p chronomap-serve check::tests`.

use std::path::{Path, PathBuf};
use std::time::SystemTime;

use chronomap_testutil::proptest_config;
use proptest::prelude::*;

use super::{Candidates, salvage, verify, verify_redb};
use crate::log::{LogRecord, decode_group, encode_group};
use crate::registry::ModelConfig;
use crate::store::{RedbStore, Store};

/// A folder of this test process's own.
fn scratch() -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "chronomap-serve-check-properties-{}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The log of a small service: two models created, observed in six batches, one removed and
/// created again.
fn groups() -> Vec<Vec<LogRecord>> {
    let create = |id: &str, model: &str| LogRecord::Create {
        id: id.into(),
        config: ModelConfig::parse(Some(model), None).unwrap(),
    };
    let mut groups = vec![vec![create("door", "fremen:2"), create("lab", "hist:24")]];
    for k in 0..6 {
        let t0 = 1_400_000_000.0 + f64::from(k) * 86_400.0;
        groups.push(vec![
            LogRecord::Observe {
                id: "door".into(),
                times: vec![t0, t0 + 600.0, t0 + 3600.0],
                values: vec![0.0, 1.0, f64::from(k % 2)],
            },
            LogRecord::Observe {
                id: "lab".into(),
                times: vec![t0 + 10.0, t0 + 20.0],
                values: vec![1.0, 0.0],
            },
        ]);
    }
    groups.push(vec![LogRecord::Remove { id: "lab".into() }]);
    groups.push(vec![create("lab", "mean")]);
    groups
}

/// The bytes of a redb store holding [`groups`] and a checkpoint with a snapshot of each
/// model, written by [`salvage`] as the service writes them, then two more log entries after
/// the checkpoint.
fn store_bytes() -> Vec<u8> {
    static BYTES: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    BYTES.get_or_init(write_store).clone()
}

fn write_store() -> Vec<u8> {
    let path = scratch().join("seed.redb");
    let _ = std::fs::remove_file(&path);
    let groups = groups();
    {
        let store = RedbStore::open(&path).unwrap();
        let candidates: Candidates = groups
            .iter()
            .enumerate()
            .map(|(i, records)| {
                let seq = i as u64 + 1;
                (seq, vec![encode_group(seq, records)])
            })
            .collect();
        let report = salvage(&candidates, &store).unwrap();
        assert!(report.lost.is_empty(), "{:?}", report.lost);
        assert_eq!(report.models, 2);
        let next = groups.len() as u64;
        for seq in next + 1..=next + 2 {
            let records = vec![LogRecord::Observe {
                id: "door".into(),
                times: vec![1_500_000_000.0 + seq as f64],
                values: vec![1.0],
            }];
            store.append(seq, &encode_group(seq, &records)).unwrap();
        }
    }
    let bytes = std::fs::read(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    bytes
}

/// A mutation of `bytes`: `kind` 0 flips a bit, 1 overwrites a byte, 2 cuts the file, 3 zeroes
/// 4 KiB; the place is taken among the bytes that are not zero when `kind`'s high bit is set
/// (most of a small redb file is zero: flips there rarely meet a structure).
fn mutate(bytes: &mut Vec<u8>, at: usize, kind: u8, value: u8) {
    let live: Vec<usize> = if kind & 0x80 != 0 {
        (0..bytes.len()).filter(|&i| bytes[i] != 0).collect()
    } else {
        Vec::new()
    };
    let at = if live.is_empty() {
        at % bytes.len().max(1)
    } else {
        live[at % live.len()]
    };
    if bytes.is_empty() {
        return;
    }
    match kind % 4 {
        0 => bytes[at] ^= 1 << (value % 8),
        1 => bytes[at] = value,
        2 => bytes.truncate(at),
        _ => {
            let start = at & !4095;
            let end = (start + 4096).min(bytes.len());
            bytes[start..end].fill(0);
        }
    }
}

fn bytes_and_time(path: &Path) -> (Vec<u8>, SystemTime) {
    (
        std::fs::read(path).unwrap(),
        std::fs::metadata(path).unwrap().modified().unwrap(),
    )
}

/// What `chronomap export parquet` reads: the store opened read-only, verified, and every log
/// entry decoded. `Ok` with the observations read, or the error's store and reason.
fn read_as_export(path: &Path) -> Result<u64, (String, String)> {
    let store = RedbStore::open_read_only(path).map_err(|e| (e.store, e.reason))?;
    let verified = verify(&store).map_err(|e| (e.store, e.reason))?;
    if !verified.report.damage.is_empty() {
        return Err((verified.report.store.clone(), verified.report.failure()));
    }
    let mut observations = 0;
    store
        .scan(1, &mut |seq, bytes| {
            if let Ok(records) = decode_group(seq, bytes) {
                observations += records.iter().map(|r| r.observations() as u64).sum::<u64>();
            }
            Ok(())
        })
        .map_err(|e| (e.store, e.reason))?;
    Ok(observations)
}

/// Runs `read` on the mutated file: no panic (redb's or ours), an error naming the file, and
/// the file as it was.
fn check_mutated(bytes: &[u8], name: &str) {
    let path = scratch().join(name);
    std::fs::write(&path, bytes).unwrap();
    let before = bytes_and_time(&path);
    let shown = path.display().to_string();
    let exported = std::panic::catch_unwind(|| read_as_export(&path));
    match exported {
        Err(_) => panic!("reading the mutated store panicked"),
        Ok(Ok(observations)) => assert!(observations <= 50, "{observations}"),
        Ok(Err((store, reason))) => {
            assert!(
                store == shown || store == format!("redb {shown}"),
                "{store}: {reason}"
            );
            assert!(!reason.is_empty());
        }
    }
    assert!(bytes_and_time(&path) == before, "reading changed the file");
    let checked = std::panic::catch_unwind(|| verify_redb(&path).map(|v| v.report));
    match checked {
        Err(_) => panic!("checking the mutated store panicked"),
        Ok(Ok(report)) => assert_eq!(report.store, format!("redb {shown}")),
        Ok(Err(e)) => assert_eq!(e.store, shown, "{e}"),
    }
    assert!(bytes_and_time(&path) == before, "checking changed the file");
    std::fs::remove_file(&path).unwrap();
}

/// The unmutated store reads whole: 2 models, 26 observations in 11 entries.
#[test]
fn the_seed_store_reads_whole_read_only() {
    let path = scratch().join("whole.redb");
    std::fs::write(&path, store_bytes()).unwrap();
    let before = bytes_and_time(&path);
    // door 6 × 3 + 2, lab 6 × 2.
    assert_eq!(read_as_export(&path), Ok(32));
    let report = verify_redb(&path).unwrap().report;
    assert_eq!(report.entries, 11);
    assert_eq!(report.observations, 32);
    assert_eq!(report.checkpoint, 9);
    assert_eq!(report.snapshots, 2);
    assert!(report.damage.is_empty(), "{:?}", report.damage);
    assert!(bytes_and_time(&path) == before);
    std::fs::remove_file(&path).unwrap();
}

proptest! {
    // Fewer cases: each writes and reads a store file.
    #![proptest_config(proptest_config(64, 20_261_205))]

    #[test]
    fn mutated_stores_are_read_or_refused_by_name_and_left_unchanged(
        edits in proptest::collection::vec((any::<usize>(), any::<u8>(), any::<u8>()), 1..4),
    ) {
        let mut bytes = store_bytes();
        for (at, kind, value) in edits {
            mutate(&mut bytes, at, kind, value);
        }
        check_mutated(&bytes, "mutated.redb");
    }
}
