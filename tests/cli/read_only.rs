//! Commands that only read a store leave it as it was: `chronomap serve --check` opens the redb
//! file read-only (redb's page check runs on a copy outside the data folder), refuses a file
//! that is no store without making a fresh one of it, and works on a read-only file system;
//! `--salvage` refuses an empty file or one without a single log entry instead of replacing
//! it with an empty store.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, SystemTime};

use crate::common::{chronomap, on_read_only_mount, scratch};
use crate::service::{Backend, Server, free_port, small_store, start};

/// Every file of the folder with its bytes and modification time, and the folder's own time.
fn snapshot(dir: &Path) -> (Vec<(String, Vec<u8>, SystemTime)>, SystemTime) {
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let path = e.unwrap().path();
            (
                path.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&path).unwrap(),
                std::fs::metadata(&path).unwrap().modified().unwrap(),
            )
        })
        .collect();
    files.sort();
    (files, std::fs::metadata(dir).unwrap().modified().unwrap())
}

/// `chronomap serve` on a new redb store in `data` that has learnt `door` (`fremen:2`) from
/// three observations, one log entry.
fn serving_a_door(data: &Path) -> Server {
    let server = start(data, free_port(), &Backend::Redb, &[]);
    let client =
        chronomap_client::Client::new(&server.url, Some(crate::service::token(data))).unwrap();
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
        .block_on(client.add_values(
            "door",
            &[0.0, 60.0, 120.0],
            &[0.0, 1.0, 1.0],
            Some("fremen:2"),
        ))
        .unwrap();
    server
}

fn serve(args: &[&str]) -> (i32, String, String) {
    let mut all = vec!["serve"];
    all.extend_from_slice(args);
    let run = chronomap(&all);
    (
        run.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&run.stdout).into_owned(),
        String::from_utf8_lossy(&run.stderr).into_owned(),
    )
}

#[test]
fn serve_check_leaves_the_store_and_its_folder_as_they_were() {
    let dir = scratch("read_only_check_clean");
    let data = small_store(&dir);
    let before = snapshot(&data);
    std::thread::sleep(Duration::from_millis(20));
    let (code, stdout, stderr) = serve(&["--data", data.to_str().unwrap(), "--check"]);
    assert_eq!(code, 0, "{stdout}{stderr}");
    assert_eq!(
        stdout,
        format!(
            "store: redb {}\nlog: 3 entries (4 observations), last position 3; checkpoint at 0, \
             0 snapshots; 1 models\nok: every snapshot and log entry is intact\nmaps: 0 \
             topological, 0 grids, 0 activity maps read\n",
            data.join("chronomap.redb").display()
        )
    );
    // Before: the store was opened to write (a new transaction changed its bytes) and its
    // page check wrote and removed a copy in the data folder.
    assert!(snapshot(&data) == before, "the data folder changed");
}

#[test]
fn serve_check_and_salvage_refuse_an_empty_or_foreign_file_and_leave_it() {
    let dir = scratch("read_only_check_foreign");
    for (name, contents) in [
        ("empty", &b""[..]),
        ("foreign", &b"id,time,state\ndoor,0,1\n"[..]),
    ] {
        let data = dir.join(name);
        std::fs::create_dir(&data).unwrap();
        let file = data.join("chronomap.redb");
        std::fs::write(&file, contents).unwrap();
        let before = snapshot(&data);
        std::thread::sleep(Duration::from_millis(20));
        let (code, stdout, stderr) = serve(&["--data", data.to_str().unwrap(), "--check"]);
        // Before: the empty file was made a fresh store and reported intact (exit 0).
        assert_eq!(code, 1, "{name}: {stdout}{stderr}");
        assert_eq!(
            stderr,
            format!(
                "error: {}: the store cannot be read; nothing was changed\n",
                file.display()
            ),
            "{name}"
        );
        if name == "empty" {
            assert!(
                stdout.contains("cannot be read: the file is empty: not a store"),
                "{stdout}"
            );
        }
        assert!(
            snapshot(&data) == before,
            "{name}: --check changed the folder"
        );

        // Before: the file was renamed to chronomap.redb.damaged-TIME and an empty store
        // took its place (exit 0, "kept: 0 models").
        let (code, stdout, stderr) = serve(&["--data", data.to_str().unwrap(), "--salvage"]);
        assert_eq!(code, 1, "{name}: {stdout}{stderr}");
        let reason = if name == "empty" {
            "the file is empty: not a store, nothing to salvage; nothing was changed"
        } else {
            "redb cannot open the file and no log entry was found in its bytes: not a chronomap \
             store, or nothing of it is left; nothing was changed"
        };
        assert_eq!(stderr, format!("error: {}: {reason}\n", file.display()));
        assert!(
            snapshot(&data) == before,
            "{name}: --salvage changed the folder"
        );
    }
}

/// A store killed while open must be repaired by redb before it can be read: `--check`
/// verifies a repaired copy and says so, leaving the file as the kill left it.
#[test]
fn serve_check_of_a_killed_store_verifies_a_repaired_copy() {
    let dir = scratch("read_only_check_killed");
    let data = dir.join("data");
    serving_a_door(&data).kill();
    let before = snapshot(&data);
    std::thread::sleep(Duration::from_millis(20));
    let (code, stdout, stderr) = serve(&["--data", data.to_str().unwrap(), "--check"]);
    assert_eq!(code, 0, "{stdout}{stderr}");
    assert!(
        stdout
            .contains("note: the file was not closed cleanly: it was verified on a repaired copy"),
        "{stdout}"
    );
    assert!(
        stdout.contains("(3 observations)") && stdout.contains("1 models\nok:"),
        "{stdout}"
    );
    // Before: redb repaired the file itself (its bytes changed).
    assert!(snapshot(&data) == before, "--check changed the folder");
}

/// A store on a read-only file system (a read-only bind mount in a mount namespace of its
/// own, which needs root) is checked.
#[test]
fn serve_check_reads_a_store_on_a_read_only_file_system() {
    let dir = scratch("read_only_check_mount");
    let data = small_store(&dir);
    let ro = dir.join("ro");
    std::fs::create_dir(&ro).unwrap();
    let ro_text = ro.display().to_string();
    let Some(run) = on_read_only_mount(&data, &ro, &["serve", "--data", &ro_text, "--check"])
    else {
        return;
    };
    let out = String::from_utf8_lossy(&run.stdout);
    let err = String::from_utf8_lossy(&run.stderr);
    // Before: "damaged: cannot open or create the file: Read-only file system", exit 1.
    assert_eq!(run.status.code(), Some(0), "{out}{err}");
    assert!(
        out.contains("1 models\nok: every snapshot and log entry is intact\n"),
        "{out}"
    );
}

/// A schema that holds no store is refused by `--check` and `--salvage` and not created
/// (before: the check created the schema and its tables and reported an intact empty store).
#[test]
fn serve_check_does_not_create_a_postgres_schema() {
    let Some(Backend::Postgres(config, schema)) = crate::service::postgres_backend("check_ro")
    else {
        return;
    };
    let dir = scratch("read_only_check_postgres");
    let (code, stdout, stderr) = serve(&[
        "--data",
        dir.to_str().unwrap(),
        "--postgres",
        &config,
        "--postgres-schema",
        &schema,
        "--check",
    ]);
    assert_eq!(code, 1, "{stdout}{stderr}");
    assert_eq!(
        stderr,
        format!(
            "error: postgres schema {schema} (read-only): holds no chronomap store (no tables \
             log and snapshots)\n"
        )
    );
    // Nor by `--salvage` (before: both the schema and SCHEMA_salvaged were created, and an
    // empty store "salvaged" with exit 0).
    let (code, stdout, stderr) = serve(&[
        "--data",
        dir.to_str().unwrap(),
        "--postgres",
        &config,
        "--postgres-schema",
        &schema,
        "--salvage",
    ]);
    assert_eq!(code, 1, "{stdout}{stderr}");
    assert!(stderr.contains("holds no chronomap store"), "{stderr}");
    let exists = Command::new("psql")
        .args([
            &config,
            "-tAc",
            &format!(
                "SELECT count(*) FROM pg_namespace WHERE nspname IN ('{schema}', \
                 '{schema}_salvaged')"
            ),
        ])
        .output()
        .unwrap();
    assert_eq!(String::from_utf8_lossy(&exists.stdout).trim(), "0");
}

/// `--check` reads every file the flags name as the start does (before: it read only the
/// store, so a missing map passed `--check` and stopped the start), and a token file is read
/// only if it is a regular file of at most 4,096 bytes (before: `--token-file /dev/zero` was
/// read without end).
#[test]
fn serve_check_reads_the_maps_and_the_token_file_the_flags_name() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch("read_only_check_flags");
    let data = small_store(&dir);
    let missing = dir.join("missing.cmt");
    let topo = format!("door={}", missing.display());
    let (code, stdout, stderr) =
        serve(&["--data", data.to_str().unwrap(), "--check", "--topo", &topo]);
    assert_eq!(code, 1, "{stdout}{stderr}");
    assert!(
        stderr.starts_with("error: --topo door: ")
            && stderr.contains(&missing.display().to_string()),
        "{stderr}"
    );
    assert_eq!(stdout, "");

    let big = dir.join("big_token");
    std::fs::write(&big, "a".repeat(4097)).unwrap();
    std::fs::set_permissions(&big, std::fs::Permissions::from_mode(0o600)).unwrap();
    for (token, reason) in [
        (
            PathBuf::from("/dev/zero"),
            "the token file is not a regular file (a directory, a device or a pipe)".to_owned(),
        ),
        (
            big.clone(),
            "the token file has more than 4096 bytes (is this the right file?)".to_owned(),
        ),
    ] {
        let (code, stdout, stderr) = serve(&[
            "--data",
            data.to_str().unwrap(),
            "--check",
            "--token-file",
            token.to_str().unwrap(),
        ]);
        assert_eq!(code, 1, "{stdout}{stderr}");
        assert_eq!(stderr, format!("error: {}: {reason}\n", token.display()));
        // The start refuses it the same way, before listening.
        let (code, stdout, stderr) = serve(&[
            "--data",
            data.to_str().unwrap(),
            "--listen",
            "127.0.0.1:0",
            "--token-file",
            token.to_str().unwrap(),
        ]);
        assert_eq!(code, 1, "{stdout}{stderr}");
        assert_eq!(stderr, format!("error: {}: {reason}\n", token.display()));
    }
}

/// `chronomap export parquet` on seeded mutations of a real store (bit flips, overwritten
/// bytes, cuts and zeroed pages among its bytes that are not zero): exit 0 with its tables, or
/// 1 with an error naming the store; never a panic (redb panics on some altered pages: the
/// store guards its reads) and never a changed store; `serve --check` reports each without
/// changing it either. The library property test
/// (`chronomap-serve` `check::tests`) runs many more.
#[test]
fn export_of_mutated_stores_reads_or_refuses_by_name_and_changes_nothing() {
    let dir = scratch("read_only_export_mutated");
    let seed = std::fs::read(small_store(&dir).join("chronomap.redb")).unwrap();
    let live: Vec<usize> = (0..seed.len()).filter(|&i| seed[i] != 0).collect();
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        // SplitMix64.
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let (mut exported, mut refused) = (0, 0);
    for case in 0..40 {
        let mut bytes = seed.clone();
        let at = live[next() as usize % live.len()];
        match case % 4 {
            0 => bytes[at] ^= 1 << (next() % 8),
            1 => bytes[at] = next() as u8,
            2 => bytes.truncate(at),
            _ => {
                let start = at & !4095;
                let end = (start + 4096).min(bytes.len());
                bytes[start..end].fill(0);
            }
        }
        let data = dir.join(format!("case{case}"));
        std::fs::create_dir(&data).unwrap();
        let file = data.join("chronomap.redb");
        std::fs::write(&file, &bytes).unwrap();
        let before = snapshot(&data);
        let out = dir.join(format!("out{case}"));
        let run = chronomap(&[
            "export",
            "parquet",
            "--data",
            data.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--no-predictions",
        ]);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(!stderr.contains("panicked"), "case {case}: {stderr}");
        match run.status.code() {
            Some(0) => {
                exported += 1;
                let table = std::fs::read(out.join("observations.parquet")).unwrap();
                assert_eq!(&table[..4], b"PAR1", "case {case}");
            }
            Some(1) => {
                refused += 1;
                assert!(
                    stderr.starts_with(&format!("error: {}", file.display()))
                        || stderr.starts_with(&format!("error: redb {}", file.display())),
                    "case {case}: {stderr}"
                );
                assert!(!out.exists(), "case {case}: a failed export left {out:?}");
            }
            other => panic!("case {case}: exit {other:?}: {stderr}"),
        }
        assert!(snapshot(&data) == before, "case {case}: the store changed");
        // `serve --check` on the same file: intact, or damage listed, or a file it cannot
        // read named; the file unchanged.
        let (code, stdout, stderr) = serve(&["--data", data.to_str().unwrap(), "--check"]);
        assert!(!stderr.contains("panicked"), "case {case}: {stderr}");
        match code {
            0 => assert!(
                stdout.contains("\nok: every snapshot"),
                "case {case}: {stdout}"
            ),
            1 => assert!(
                stdout.contains("\ndamaged: ") || stdout.contains("\ncannot be read: "),
                "case {case}: {stdout}{stderr}"
            ),
            other => panic!("case {case}: serve --check exit {other}: {stderr}"),
        }
        assert!(
            snapshot(&data) == before,
            "case {case}: --check changed the store"
        );
    }
    // Both outcomes occur: the mutations reach the store's structures.
    assert!(
        exported > 0 && refused > 0,
        "{exported} exported, {refused} refused"
    );
}

/// `--salvage` keeps the damaged file exactly as it was (redb reads a copy, which it may
/// repair; before, the file kept as `chronomap.redb.damaged-TIME` was the one redb had
/// repaired in place), and refuses a store a running service holds (before: it salvaged from
/// the raw bytes and renamed the file under the service).
#[test]
fn serve_salvage_keeps_the_damaged_file_as_it_was_and_leaves_a_held_store_alone() {
    let dir = scratch("read_only_salvage_kept");
    let data = dir.join("data");
    let server = serving_a_door(&data);

    let before = snapshot(&data);
    let (code, stdout, stderr) = serve(&["--data", data.to_str().unwrap(), "--salvage"]);
    assert_eq!(code, 1, "{stdout}{stderr}");
    assert!(
        stderr.contains("stop the service that holds it before salvaging"),
        "{stderr}"
    );
    assert!(snapshot(&data) == before, "--salvage changed a held store");

    server.kill();
    let killed = std::fs::read(data.join("chronomap.redb")).unwrap();
    let (code, stdout, stderr) = serve(&["--data", data.to_str().unwrap(), "--salvage"]);
    assert_eq!(code, 0, "{stdout}{stderr}");
    assert!(
        stdout.starts_with("kept: 1 models, 3 observations in 1 log entries\n"),
        "{stdout}"
    );
    let kept: Vec<PathBuf> = std::fs::read_dir(&data)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().contains("chronomap.redb.damaged-"))
        .collect();
    assert_eq!(kept.len(), 1, "{kept:?}");
    assert!(
        std::fs::read(&kept[0]).unwrap() == killed,
        "the kept file is not the one salvaged"
    );
}
