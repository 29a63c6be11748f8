//! Atomic file writes shared by the writers of this crate.

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// Why an atomic write failed: what was being done and the underlying error.
#[derive(Debug)]
pub(crate) struct WriteFailure {
    /// `"write"`, `"create a temporary file for"`, `"flush"` or `"replace"`.
    pub action: &'static str,
    /// The underlying error.
    pub io: io::Error,
}

/// Writes `bytes` to `path` atomically: a temporary file in the same directory, flushed to
/// disk, then renamed over the target, so a crash never leaves a half-written file and
/// readers see either the previous content or the complete new one.
pub(crate) fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), WriteFailure> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let failure = |action: &'static str| move |io| WriteFailure { action, io };
    let file_name = path.file_name().ok_or_else(|| {
        failure("write")(io::Error::new(
            io::ErrorKind::InvalidInput,
            "the path does not name a file",
        ))
    })?;
    let dir = match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    };
    let mut temp_name = std::ffi::OsString::from(".");
    temp_name.push(file_name);
    temp_name.push(format!(
        ".tmp-{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let temp = dir.join(temp_name);
    let result = (|| {
        let mut file: File = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temp)
            .map_err(failure("create a temporary file for"))?;
        file.write_all(bytes).map_err(failure("write"))?;
        file.sync_all().map_err(failure("flush"))?;
        drop(file);
        fs::rename(&temp, path).map_err(failure("replace"))
    })();
    if result.is_err() {
        let _ = fs::remove_file(&temp);
        return result;
    }
    // Make the rename itself durable where directories can be synced (best effort).
    if let Ok(dir) = File::open(dir) {
        let _ = dir.sync_all();
    }
    Ok(())
}
