//! Whole-file writes shared by the writers of this crate, through the one output writer
//! ([`crate::output`]).

use std::io;
use std::path::Path;

/// Why a write failed: what was being done and the underlying error.
#[derive(Debug)]
pub(crate) struct WriteFailure {
    /// `"inspect"`, `"open"`, `"create a temporary file for"`, `"write"`, `"flush"` or
    /// `"replace"`.
    pub action: &'static str,
    /// The underlying error.
    pub io: io::Error,
}

/// Writes `bytes` to `path` with [`crate::output::write_output`]: a regular file (or none) is
/// replaced atomically (a temporary file in the same directory, flushed to disk, then renamed
/// over it, so a crash never leaves a half-written file), a device or pipe is written
/// through, a link's file is written and the link kept, a directory is refused.
pub(crate) fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), WriteFailure> {
    crate::output::write_output(path, bytes).map_err(|e| WriteFailure {
        action: e.action,
        io: e.io,
    })
}
