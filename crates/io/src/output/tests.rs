use std::io::Read;
use std::os::unix::fs::FileTypeExt;
use std::process::Command;

use super::*;

/// A directory of its own for each test, under the system's temporary directory.
fn scratch(test: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("chronomap-io-output-{}-{test}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn a_regular_file_is_created_or_replaced_whole_and_no_temporary_file_stays() {
    let dir = scratch("regular");
    let path = dir.join("m.cmm");
    write_output(&path, b"first").unwrap();
    assert_eq!(fs::read(&path).unwrap(), b"first");
    write_output(&path, b"second, longer").unwrap();
    assert_eq!(fs::read(&path).unwrap(), b"second, longer");
    assert_eq!(names(&dir), ["m.cmm"]);
    // Dropped before its commit, an output changes nothing.
    let mut pending = Output::create(&path).unwrap();
    pending.write_all(b"half").unwrap();
    drop(pending);
    assert_eq!(fs::read(&path).unwrap(), b"second, longer");
    assert_eq!(names(&dir), ["m.cmm"]);
    let error = Output::create_or_refuse(&path, false).err().unwrap();
    assert_eq!(
        error.to_string(),
        format!("{}: cannot write: it exists already", path.display())
    );
    assert_eq!(error.io.kind(), io::ErrorKind::AlreadyExists);
    let missing = dir.join("no/such/dir/m.cmm");
    let error = write_output(&missing, b"x").unwrap_err();
    assert_eq!(error.action, "create a temporary file for");
    fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_directory_is_refused_by_name_and_left_alone() {
    let dir = scratch("directory");
    let error = write_output(&dir, b"x").unwrap_err();
    assert_eq!(
        error.to_string(),
        format!(
            "{}: cannot write: it is a directory, not a file",
            dir.display()
        )
    );
    assert!(fs::symlink_metadata(&dir).unwrap().is_dir());
    // Also through a link to it.
    let link = std::env::temp_dir().join(format!(
        "chronomap-io-output-{}-dirlink",
        std::process::id()
    ));
    let _ = fs::remove_file(&link);
    std::os::unix::fs::symlink(&dir, &link).unwrap();
    let error = write_output(&link, b"x").unwrap_err();
    assert!(
        error.to_string().ends_with("it is a directory, not a file"),
        "{error}"
    );
    assert!(
        fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    fs::remove_file(link).unwrap();
    fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_symbolic_link_stays_a_link_and_the_file_it_points_to_is_replaced() {
    let dir = scratch("symlink");
    fs::create_dir(dir.join("real")).unwrap();
    let file = dir.join("real/model.cmm");
    fs::write(&file, "old").unwrap();
    let link = dir.join("latest.cmm");
    std::os::unix::fs::symlink("real/model.cmm", &link).unwrap();
    write_output(&link, b"new").unwrap();
    assert!(
        fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(fs::read_link(&link).unwrap(), Path::new("real/model.cmm"));
    assert_eq!(fs::read(&file).unwrap(), b"new");
    assert_eq!(names(&dir.join("real")), ["model.cmm"]);
    // A dangling link: the file it names is created, the link kept.
    let dangling = dir.join("next.cmm");
    std::os::unix::fs::symlink("real/next.cmm", &dangling).unwrap();
    write_output(&dangling, b"created").unwrap();
    assert!(
        fs::symlink_metadata(&dangling)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(fs::read(dir.join("real/next.cmm")).unwrap(), b"created");
    // A loop of links is refused.
    let a = dir.join("a");
    std::os::unix::fs::symlink("b", &a).unwrap();
    std::os::unix::fs::symlink("a", dir.join("b")).unwrap();
    let error = write_output(&a, b"x").unwrap_err();
    assert_eq!(
        error.to_string(),
        format!(
            "{}: cannot inspect: more than 40 symbolic links",
            a.display()
        )
    );
    fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_character_device_is_written_through_and_stays_a_device() {
    let dir = scratch("device");
    let null = chronomap_testutil::null_device(&dir);
    write_output(&null, b"nothing to keep").unwrap();
    let mut output = Output::create(&null).unwrap();
    assert!(output.is_stream());
    output.write_all(&[0; 100_000]).unwrap();
    assert_eq!(output.commit().unwrap(), 100_000);
    let kind = fs::symlink_metadata(&null).unwrap().file_type();
    assert!(kind.is_char_device(), "{}: {kind:?}", null.display());
    assert_eq!(fs::metadata(&null).unwrap().len(), 0);
    assert!(names(&dir).iter().all(|n| n == "null"), "{:?}", names(&dir));
    fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_named_pipe_gets_the_bytes_and_stays_a_pipe() {
    let dir = scratch("fifo");
    let fifo = dir.join("pipe");
    let made = Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    assert!(made, "mkfifo {}", fifo.display());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            File::open(&fifo).unwrap().read_to_end(&mut bytes).unwrap();
            bytes
        })
    };
    let payload: Vec<u8> = (0..200_000u32).map(|i| (i % 251) as u8).collect();
    write_output(&fifo, &payload).unwrap();
    assert_eq!(reader.join().unwrap(), payload);
    assert!(fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
    assert_eq!(names(&dir), ["pipe"]);
    fs::remove_dir_all(dir).unwrap();
}
