//! The one writer of every output file (`-o`, `--plot`, exported tables): what the path names
//! decides how it is written, so that writing never replaces what is not a regular file.
//!
//! - a regular file, or nothing yet: a temporary file beside it, flushed to disk, then renamed
//!   over it, so a crash never leaves a half-written file and readers see either the previous
//!   content or the complete new one;
//! - a character device or a named pipe (`/dev/null`, `/dev/stdout`, a FIFO), or any existing
//!   path under `/dev/` or `/proc/` (`/dev/stdout` of a shell redirection): written through,
//!   opened for writing without creating, truncating or renaming anything;
//! - a symbolic link: the file it points to is written as above (replaced atomically, or
//!   created where a dangling link points); the link itself stays;
//! - a directory or anything else (a socket, a block device): refused, naming the path.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Most symbolic links followed from one output path (as the kernel's `ELOOP` limit).
const MAX_LINKS: usize = 40;

/// Why an output could not be written: the path as given, what was being done and the
/// underlying error (`PATH: cannot ACTION: ERROR`).
#[derive(Debug)]
pub struct OutputError {
    /// The output path as given.
    pub path: PathBuf,
    /// `"inspect"`, `"open"`, `"create a temporary file for"`, `"write"`, `"flush"` or
    /// `"replace"`.
    pub action: &'static str,
    /// The underlying error (for a directory or another kind of file: what it is).
    pub io: io::Error,
}

impl std::fmt::Display for OutputError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: cannot {}: {}",
            self.path.display(),
            self.action,
            self.io
        )
    }
}

impl std::error::Error for OutputError {}

/// How an output path is written (see the module documentation).
enum Plan {
    /// A temporary file renamed over `target` (the path, or where its links point).
    Replace { target: PathBuf, exists: bool },
    /// Opened for writing as it is.
    Through,
}

/// What an output path names, after following its links.
fn plan(path: &Path) -> Result<Plan, OutputError> {
    let error = |action: &'static str| {
        move |io: io::Error| OutputError {
            path: path.to_path_buf(),
            action,
            io,
        }
    };
    let refuse = |what: &str| {
        Err(error("write")(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("it is {what}, not a file"),
        )))
    };
    let mut target = path.to_path_buf();
    for _ in 0..=MAX_LINKS {
        let meta = match fs::symlink_metadata(&target) {
            Ok(meta) => meta,
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                return Ok(Plan::Replace {
                    target,
                    exists: false,
                });
            }
            Err(e) => return Err(error("inspect")(e)),
        };
        let kind = meta.file_type();
        let special = path.starts_with("/dev") || path.starts_with("/proc");
        if kind.is_symlink() {
            if special {
                // `/dev/stdout`, `/proc/self/fd/1`: the process's own streams, whatever they
                // are, are written where they are open, never replaced.
                return match fs::metadata(&target) {
                    Ok(m) if m.is_dir() => refuse("a directory"),
                    Ok(_) => Ok(Plan::Through),
                    Err(e) => Err(error("inspect")(e)),
                };
            }
            let link = fs::read_link(&target).map_err(error("inspect"))?;
            target = match target.parent() {
                Some(dir) => dir.join(link),
                None => link,
            };
            continue;
        }
        if kind.is_file() {
            return Ok(if special {
                Plan::Through
            } else {
                Plan::Replace {
                    target,
                    exists: true,
                }
            });
        }
        if kind.is_dir() {
            return refuse("a directory");
        }
        #[cfg(unix)]
        {
            use std::os::unix::fs::FileTypeExt;
            if kind.is_char_device() || kind.is_fifo() {
                return Ok(Plan::Through);
            }
            if kind.is_block_device() {
                return refuse("a block device");
            }
            if kind.is_socket() {
                return refuse("a socket");
            }
        }
        return refuse("neither a regular file, a character device nor a named pipe");
    }
    Err(error("inspect")(io::Error::new(
        io::ErrorKind::InvalidInput,
        format!("more than {MAX_LINKS} symbolic links"),
    )))
}

/// An output being written; [`Output::commit`] completes it. Dropped uncommitted, a file
/// being replaced is left as it was (its temporary file is deleted); a stream written through
/// keeps what it was sent.
pub struct Output {
    path: PathBuf,
    /// The final path of a replaced file and its temporary file; `None` when written through.
    replace: Option<(PathBuf, PathBuf)>,
    file: Option<BufWriter<File>>,
    written: u64,
}

impl Output {
    /// Starts writing `path` (see the module documentation for what each kind of path gets).
    ///
    /// # Errors
    /// `path` is a directory or another kind of file that is not written, its links cannot
    /// be followed, or it (or the temporary file beside it) cannot be opened.
    pub fn create(path: &Path) -> Result<Output, OutputError> {
        Self::start(path, true)
    }

    /// As [`Output::create`], but with `replace` false an existing file (a regular file, or
    /// one a link points to) is refused with [`io::ErrorKind::AlreadyExists`]; character
    /// devices and named pipes are still written through.
    ///
    /// # Errors
    /// As [`Output::create`], and the file exists when `replace` is false.
    pub fn create_or_refuse(path: &Path, replace: bool) -> Result<Output, OutputError> {
        Self::start(path, replace)
    }

    fn start(path: &Path, replace: bool) -> Result<Output, OutputError> {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let error = |action: &'static str| {
            move |io: io::Error| OutputError {
                path: path.to_path_buf(),
                action,
                io,
            }
        };
        match plan(path)? {
            Plan::Through => {
                let file = OpenOptions::new()
                    .write(true)
                    .open(path)
                    .map_err(error("open"))?;
                Ok(Output {
                    path: path.to_path_buf(),
                    replace: None,
                    file: Some(BufWriter::with_capacity(1 << 16, file)),
                    written: 0,
                })
            }
            Plan::Replace { target, exists } => {
                if exists && !replace {
                    return Err(error("write")(io::Error::new(
                        io::ErrorKind::AlreadyExists,
                        "it exists already",
                    )));
                }
                let file_name = target.file_name().ok_or_else(|| {
                    error("write")(io::Error::new(
                        io::ErrorKind::InvalidInput,
                        "the path does not name a file",
                    ))
                })?;
                let dir = match target.parent() {
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
                let file = OpenOptions::new()
                    .write(true)
                    .create_new(true)
                    .open(&temp)
                    .map_err(error("create a temporary file for"))?;
                Ok(Output {
                    path: path.to_path_buf(),
                    replace: Some((target, temp)),
                    file: Some(BufWriter::with_capacity(1 << 16, file)),
                    written: 0,
                })
            }
        }
    }

    /// The output path as given.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether the output is written through (a device, a pipe) rather than replaced.
    pub fn is_stream(&self) -> bool {
        self.replace.is_none()
    }

    /// Flushes what was written; a replaced file is synced to disk and renamed over its final
    /// path. Returns the number of bytes written.
    ///
    /// # Errors
    /// The bytes cannot be written, synced or renamed (a replaced file is then left as it
    /// was).
    pub fn commit(mut self) -> Result<u64, OutputError> {
        let error = |action: &'static str| {
            let path = self.path.clone();
            move |io: io::Error| OutputError { path, action, io }
        };
        let writer = self
            .file
            .take()
            .expect("an output has its writer until committed");
        let file = writer
            .into_inner()
            .map_err(|e| error("write")(e.into_error()))?;
        let Some((target, temp)) = self.replace.take() else {
            return Ok(self.written);
        };
        let result = (|| {
            file.sync_all().map_err(error("flush"))?;
            drop(file);
            fs::rename(&temp, &target).map_err(error("replace"))
        })();
        if let Err(e) = result {
            let _ = fs::remove_file(&temp);
            return Err(e);
        }
        // Make the rename itself durable where directories can be synced (best effort).
        let dir = match target.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => parent,
            _ => Path::new("."),
        };
        if let Ok(dir) = File::open(dir) {
            let _ = dir.sync_all();
        }
        Ok(self.written)
    }
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.file.as_mut().expect("open").write(buf)?;
        self.written += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.file.as_mut().expect("open").flush()
    }
}

impl Drop for Output {
    fn drop(&mut self) {
        if let (Some(file), Some((_, temp))) = (self.file.take(), &self.replace) {
            drop(file.into_parts());
            let _ = fs::remove_file(temp);
        }
    }
}

/// Writes `bytes` to the output `path` at once ([`Output::create`], then
/// [`Output::commit`]).
///
/// # Errors
/// As [`Output::create`] and [`Output::commit`].
pub fn write_output(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let mut output = Output::create(path)?;
    output.write_all(bytes).map_err(|io| OutputError {
        path: path.to_path_buf(),
        action: "write",
        io,
    })?;
    output.commit().map(|_| ())
}

#[cfg(test)]
mod tests;
