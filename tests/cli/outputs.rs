//! What chronomap writes, whatever the output path names: `-o` and `--plot` go through one
//! writer (`chronomap_io::output`) that replaces a regular file atomically, writes a device
//! or a named pipe through, keeps a symbolic link and refuses a directory; an export leaves
//! the store it reads as it was.

use std::io::Read;
use std::os::unix::fs::FileTypeExt;
use std::path::Path;
use std::process::Command;
use std::sync::mpsc;
use std::time::Duration;

use chronomap_testutil::null_device;

use crate::common::{chronomap, error, repo, scratch, stdout};

fn is_char_device(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_char_device())
}

/// A named pipe at `path` and a reader of everything written to it (`recv` it).
fn fifo_with_reader(path: &Path) -> mpsc::Receiver<Vec<u8>> {
    assert!(
        Command::new("mkfifo")
            .arg(path)
            .status()
            .is_ok_and(|s| s.success()),
        "mkfifo {}",
        path.display()
    );
    let (send, receive) = mpsc::channel();
    let path = path.to_path_buf();
    std::thread::spawn(move || {
        let mut bytes = Vec::new();
        if let Ok(mut file) = std::fs::File::open(&path) {
            file.read_to_end(&mut bytes).ok();
        }
        send.send(bytes).ok();
    });
    receive
}

/// The bytes the reader of a named pipe got, after checking it is still a pipe.
fn piped(path: &Path, reader: &mpsc::Receiver<Vec<u8>>) -> Vec<u8> {
    let kind = std::fs::symlink_metadata(path).unwrap().file_type();
    assert!(
        kind.is_fifo(),
        "{} is no longer a pipe: {kind:?}",
        path.display()
    );
    reader
        .recv_timeout(Duration::from_secs(60))
        .expect("the pipe's reader got the bytes")
}

fn series(dir: &Path) -> String {
    let path = dir.join("door.txt");
    std::fs::write(&path, "0 0\n60 1\n120 0\n180 1\n").unwrap();
    path.display().to_string()
}

fn fit(train: &str, out: &Path) -> std::process::Output {
    chronomap(&[
        "fit",
        "--train",
        train,
        "--model",
        "mean",
        "-o",
        out.to_str().unwrap(),
    ])
}

#[test]
fn fit_writes_a_device_a_pipe_and_a_links_file_and_refuses_a_directory() {
    let dir = scratch("outputs_fit");
    let train = series(&dir);
    let regular = dir.join("m.cmm");
    stdout(&fit(&train, &regular));
    let model = std::fs::read(&regular).unwrap();
    assert_eq!(&model[..12], b"chronomap-mo", "a model file");

    // A device stays a device (before: renamed over, a regular file of 96 bytes).
    let null = null_device(&dir);
    let said = stdout(&fit(&train, &null));
    assert!(
        is_char_device(&null),
        "{} is no longer a device",
        null.display()
    );
    // It says how many bytes went through (before: the device's size afterwards, 0).
    assert!(said.contains(&format!("({} bytes)", model.len())), "{said}");

    // A named pipe gets the model (before: renamed over; the reader got nothing).
    let pipe = dir.join("pipe");
    let reader = fifo_with_reader(&pipe);
    stdout(&fit(&train, &pipe));
    assert_eq!(piped(&pipe, &reader), model);

    // A link stays a link; the file it points to gets the model.
    let target = dir.join("target.cmm");
    std::fs::write(&target, "old").unwrap();
    let link = dir.join("link.cmm");
    std::os::unix::fs::symlink("target.cmm", &link).unwrap();
    stdout(&fit(&train, &link));
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(std::fs::read(&target).unwrap(), model);

    // A directory is refused by name.
    let folder = dir.join("folder");
    std::fs::create_dir(&folder).unwrap();
    let e = error(&fit(&train, &folder));
    assert_eq!(
        e,
        format!(
            "error: {}: cannot write: it is a directory, not a file\n",
            folder.display()
        )
    );
    assert!(folder.is_dir());
}

fn plot(out: &Path) -> std::process::Output {
    let door = repo("tests/data/bt/door.xml");
    let params = repo("tests/data/bt/door_sbt.csv");
    chronomap(&[
        "bt",
        "analyse",
        &door,
        "--params",
        &params,
        "--t-max",
        "120",
        "--steps",
        "4",
        "--plot",
        out.to_str().unwrap(),
    ])
}

#[test]
fn plots_write_a_device_a_pipe_and_a_links_file_and_refuse_a_directory() {
    let dir = scratch("outputs_plot");
    let png = dir.join("door.png");
    stdout(&plot(&png));
    let image = std::fs::read(&png).unwrap();
    assert_eq!(&image[..8], b"\x89PNG\r\n\x1a\n");

    // A device without a `.png` name (before: refused, the image format was not known from
    // the extension).
    let null = null_device(&dir);
    stdout(&plot(&null));
    assert!(is_char_device(&null));

    let pipe = dir.join("pipe");
    let reader = fifo_with_reader(&pipe);
    stdout(&plot(&pipe));
    assert_eq!(piped(&pipe, &reader), image);

    let link = dir.join("latest.png");
    std::os::unix::fs::symlink("door.png", &link).unwrap();
    std::fs::write(&png, "old").unwrap();
    stdout(&plot(&link));
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(std::fs::read(&png).unwrap(), image);

    let folder = dir.join("folder.png");
    std::fs::create_dir(&folder).unwrap();
    let e = error(&plot(&folder));
    assert!(
        e.contains(&format!(
            "{}: cannot write: it is a directory, not a file",
            folder.display()
        )),
        "{e}"
    );
}

#[cfg(feature = "serve")]
mod export {
    use std::path::Path;
    use std::time::SystemTime;

    use super::*;
    use crate::common::{json, on_read_only_mount, usage_error};
    use crate::service::small_store;

    fn export(data: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
        let mut args = vec![
            "export",
            "parquet",
            "--data",
            data.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        chronomap(&args)
    }

    fn bytes_and_mtime(path: &Path) -> (Vec<u8>, SystemTime) {
        (
            std::fs::read(path).unwrap(),
            std::fs::metadata(path).unwrap().modified().unwrap(),
        )
    }

    #[test]
    fn an_export_leaves_the_store_as_it_was() {
        let dir = scratch("outputs_export_store");
        let data = small_store(&dir);
        let redb = data.join("chronomap.redb");
        let before = bytes_and_mtime(&redb);
        std::thread::sleep(Duration::from_millis(20));
        let out = dir.join("out");
        let summary = json(&export(&data, &out, &["--no-predictions", "--json"]));
        assert_eq!(summary["observations"]["rows"], 4);
        // Before: opened to write, the store's bytes changed (a new transaction).
        assert!(bytes_and_mtime(&redb) == before, "the store changed");

        // An empty file is no store: refused by name, and still empty (before: made a fresh
        // store of it, exported nothing, exit 0).
        let empty = dir.join("empty");
        std::fs::create_dir(&empty).unwrap();
        std::fs::write(empty.join("chronomap.redb"), "").unwrap();
        let e = error(&export(&empty, &dir.join("out2"), &["--no-predictions"]));
        assert_eq!(
            e,
            format!(
                "error: {}: the file is empty: not a store (a store is made by `chronomap \
                 serve`)\n",
                empty.join("chronomap.redb").display()
            )
        );
        assert_eq!(
            std::fs::metadata(empty.join("chronomap.redb"))
                .unwrap()
                .len(),
            0
        );
        assert!(!dir.join("out2").exists(), "no output of a failed export");
    }

    /// A store on a read-only file system (a read-only bind mount in a mount namespace of its
    /// own, which needs root) is exported.
    #[test]
    fn a_store_on_a_read_only_file_system_is_exported() {
        let dir = scratch("outputs_export_read_only");
        let data = small_store(&dir);
        let ro = dir.join("ro");
        std::fs::create_dir(&ro).unwrap();
        let out = dir.join("out");
        let (ro_text, out_text) = (ro.display().to_string(), out.display().to_string());
        let Some(run) = on_read_only_mount(
            &data,
            &ro,
            &[
                "export",
                "parquet",
                "--data",
                &ro_text,
                "-o",
                &out_text,
                "--no-predictions",
                "--json",
            ],
        ) else {
            return;
        };
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(0), "{err}");
        let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
        assert_eq!(summary["observations"]["rows"], 4);
    }

    #[test]
    fn export_tables_go_to_a_pipe_a_device_or_a_links_file_never_over_them() {
        let dir = scratch("outputs_export_targets");
        let data = small_store(&dir);

        // A named pipe gets the table, without --force (it replaces nothing).
        let out = dir.join("piped");
        std::fs::create_dir(&out).unwrap();
        let pipe = out.join("observations.parquet");
        let reader = fifo_with_reader(&pipe);
        let summary = json(&export(&data, &out, &["--no-predictions", "--json"]));
        let table = piped(&pipe, &reader);
        assert_eq!(summary["observations"]["bytes"], table.len());
        assert_eq!(&table[..4], b"PAR1");
        assert_eq!(&table[table.len() - 4..], b"PAR1");

        // A device stays a device.
        let out = dir.join("device");
        std::fs::create_dir(&out).unwrap();
        let null = null_device(&out);
        if null.starts_with(&out) {
            std::fs::rename(&null, out.join("observations.parquet")).unwrap();
            stdout(&export(&data, &out, &["--no-predictions"]));
            assert!(is_char_device(&out.join("observations.parquet")));
        }

        // A link (with --force) stays a link to the new table.
        let out = dir.join("linked");
        std::fs::create_dir(&out).unwrap();
        std::fs::write(dir.join("kept.parquet"), "old").unwrap();
        let link = out.join("observations.parquet");
        std::os::unix::fs::symlink("../kept.parquet", &link).unwrap();
        stdout(&export(&data, &out, &["--no-predictions", "--force"]));
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(
            &std::fs::read(dir.join("kept.parquet")).unwrap()[..4],
            b"PAR1"
        );

        // A directory is refused.
        let out = dir.join("folder");
        std::fs::create_dir_all(out.join("observations.parquet")).unwrap();
        let e = error(&export(&data, &out, &["--no-predictions", "--force"]));
        assert!(
            e.contains("observations.parquet: cannot write: it is a directory, not a file"),
            "{e}"
        );
    }

    /// `--from 1e308` is refused before anything is written (before: observations.parquet
    /// was written and left behind, then the predictions failed).
    #[test]
    fn a_grid_beyond_parquet_timestamps_is_refused_before_anything_is_written() {
        let dir = scratch("outputs_export_far_grid");
        let data = small_store(&dir);
        let out = dir.join("out");
        let e = usage_error(&export(&data, &out, &["--from", "1e308", "--to", "1e308"]));
        assert!(
            e.contains("--from 1e308: a prediction time must be within about 292,000 years"),
            "{e}"
        );
        assert!(!out.exists(), "nothing is created");
    }
}
