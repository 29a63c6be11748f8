//! Groot2 execution logs (`.btlog`), as BehaviorTree.CPP 4's `FileLogger2` writes them, from
//! the status transitions a [`Tree`] records.
//!
//! # Format
//! Little-endian throughout:
//!
//! | bytes | content |
//! |---|---|
//! | 18 | ASCII `BTCPP4-FileLogger2` |
//! | 1 | protocol version, 1 |
//! | 4 | `i32` length *n* of the XML |
//! | *n* | the tree as `WriteTreeToXML(tree, true, true)` writes it ([`encode_tree_xml`]: subtree instances with `_fullpath`, nodes with `_uid`, `<TreeNodesModel>`) |
//! | 8 | `i64` first timestamp, microseconds |
//! | 9 each | transitions: 6 bytes of the `u64` time since the first timestamp in microseconds (low bytes), `u16` node uid, `u8` new status (0 idle, 1 running, 2 success, 3 failure) |
//!
//! Transitions to idle are included (`FileLogger2` enables them). BehaviorTree.CPP takes the
//! timestamps from the system clock at each status change and the first timestamp when the
//! logger is created; here they are the tick times of the injected clock and a start time the
//! caller gives, in the same clock.
//!
//! # What is and is not verified
//! The layout above follows a reading of BehaviorTree.CPP 4.x's `FileLogger2` (constructor,
//! `callback`, `writerLoop`) and is checked here by writing and reading back
//! ([`decode_btlog`]). It has **not** been checked against a file written by BehaviorTree.CPP
//! or opened in Groot2: no such file or tool was available. Not verified in particular:
//! that uids start at 1 in depth-first order of creation (what this crate assigns), that
//! Groot2 accepts the XML as written by [`encode_tree_xml`] (BehaviorTree.CPP writes it with
//! TinyXML2, whose formatting differs, and lists the models of *all* registered node types,
//! here only those used), and how Groot2 displays a first timestamp that is not a unix time.

use std::fmt;
use std::io::{self, Write};
use std::path::Path;
use std::time::Duration;

use chronomap_bt::{Transition, Tree};
use thiserror::Error;

use crate::bt_xml::encode_tree_xml;

/// The first 18 bytes of a `.btlog` file.
pub const BTLOG_MAGIC: &[u8; 18] = b"BTCPP4-FileLogger2";

/// The protocol byte that follows.
pub const BTLOG_PROTOCOL: u8 = 1;

/// Largest time offset a transition can have: 6 bytes of microseconds (about 8.9 years).
const MAX_DELTA_US: u64 = (1 << 48) - 1;

/// What is wrong with a `.btlog` file or with what is to be written.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum BtLogErrorKind {
    /// The file could not be read or written.
    #[error("cannot {action}: {io}")]
    Io {
        /// What was being done.
        action: &'static str,
        /// The underlying error.
        io: io::Error,
    },
    /// Groot2 (and BehaviorTree.CPP's `FileLogger2`) only accept the `.btlog` extension.
    #[error("the file name must end in .btlog (Groot2 opens only those)")]
    Extension,
    /// A transition earlier than the log's start.
    #[error("a transition of node {uid} at {time:?} is earlier than the log's start {start:?}")]
    BeforeStart {
        /// The node.
        uid: u16,
        /// Its time.
        time: Duration,
        /// The start.
        start: Duration,
    },
    /// A transition too late for 6 bytes of microseconds.
    #[error("a transition of node {uid} is {delta_us} µs after the start (at most 2^48 - 1)")]
    TooLate {
        /// The node.
        uid: u16,
        /// Its offset.
        delta_us: u128,
    },
    /// The start time does not fit the header's `i64` microseconds.
    #[error("the start time {start:?} does not fit in an i64 of microseconds")]
    StartTooLate {
        /// The start.
        start: Duration,
    },
    /// Not a `.btlog` file, or a damaged one.
    #[error("not a BehaviorTree.CPP FileLogger2 log: {reason}")]
    Format {
        /// What is wrong, with the byte offset.
        reason: String,
    },
}

/// Why a `.btlog` file could not be read or written: the file (when there is one) and the
/// problem.
#[derive(Debug, Error)]
pub struct BtLogError {
    file: Option<String>,
    kind: BtLogErrorKind,
}

impl fmt::Display for BtLogError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.file {
            Some(file) => write!(f, "{file}: {}", self.kind),
            None => write!(f, "{}", self.kind),
        }
    }
}

impl BtLogError {
    fn new(kind: BtLogErrorKind) -> BtLogError {
        BtLogError { file: None, kind }
    }

    fn in_file(mut self, path: &Path) -> BtLogError {
        self.file = Some(path.display().to_string());
        self
    }

    /// The file concerned, if any.
    pub fn file(&self) -> Option<&str> {
        self.file.as_deref()
    }

    /// What is wrong.
    pub fn kind(&self) -> &BtLogErrorKind {
        &self.kind
    }
}

/// Writes a `.btlog` stream: the header at creation, then transitions as they come.
pub struct BtLogWriter<W: Write> {
    out: W,
    start: Duration,
}

impl<W: Write> BtLogWriter<W> {
    /// Writes the header for `tree` with `start` as the first timestamp (same clock as the
    /// tick times; use unix time for logs that show wall-clock times).
    ///
    /// # Errors
    /// [`BtLogErrorKind::Io`] if writing fails, [`BtLogErrorKind::StartTooLate`] for a start
    /// beyond `i64` microseconds.
    pub fn new(mut out: W, tree: &Tree, start: Duration) -> Result<BtLogWriter<W>, BtLogError> {
        let start_us = i64::try_from(start.as_micros())
            .map_err(|_| BtLogError::new(BtLogErrorKind::StartTooLate { start }))?;
        let xml = encode_tree_xml(tree);
        let length = i32::try_from(xml.len()).map_err(|_| {
            BtLogError::new(BtLogErrorKind::Io {
                action: "write",
                io: io::Error::new(io::ErrorKind::InvalidInput, "tree XML longer than 2 GiB"),
            })
        })?;
        let mut header = Vec::with_capacity(31 + xml.len());
        header.extend_from_slice(BTLOG_MAGIC);
        header.push(BTLOG_PROTOCOL);
        header.extend_from_slice(&length.to_le_bytes());
        header.extend_from_slice(xml.as_bytes());
        header.extend_from_slice(&start_us.to_le_bytes());
        out.write_all(&header).map_err(write_error)?;
        Ok(BtLogWriter { out, start })
    }

    /// Appends transitions.
    ///
    /// # Errors
    /// [`BtLogErrorKind::BeforeStart`] or [`BtLogErrorKind::TooLate`] for times that cannot be
    /// stored (nothing of the batch is written then), [`BtLogErrorKind::Io`] if writing fails.
    pub fn write(&mut self, transitions: &[Transition]) -> Result<(), BtLogError> {
        let mut bytes = Vec::with_capacity(9 * transitions.len());
        for t in transitions {
            bytes.extend_from_slice(&encode_transition(self.start, t)?);
        }
        self.out.write_all(&bytes).map_err(write_error)
    }

    /// Flushes and returns the underlying writer.
    ///
    /// # Errors
    /// [`BtLogErrorKind::Io`] if flushing fails.
    pub fn finish(mut self) -> Result<W, BtLogError> {
        self.out.flush().map_err(write_error)?;
        Ok(self.out)
    }
}

fn write_error(io: io::Error) -> BtLogError {
    BtLogError::new(BtLogErrorKind::Io {
        action: "write",
        io,
    })
}

/// One transition as 9 bytes: time since `start` (6 bytes of µs), uid, status code.
///
/// # Errors
/// [`BtLogErrorKind::BeforeStart`], [`BtLogErrorKind::TooLate`].
pub fn encode_transition(start: Duration, t: &Transition) -> Result<[u8; 9], BtLogError> {
    let delta = t.time.checked_sub(start).ok_or_else(|| {
        BtLogError::new(BtLogErrorKind::BeforeStart {
            uid: t.uid,
            time: t.time,
            start,
        })
    })?;
    let delta_us = delta.as_micros();
    let small = u64::try_from(delta_us)
        .ok()
        .filter(|&d| d <= MAX_DELTA_US)
        .ok_or_else(|| {
            BtLogError::new(BtLogErrorKind::TooLate {
                uid: t.uid,
                delta_us,
            })
        })?;
    let mut bytes = [0u8; 9];
    bytes[..6].copy_from_slice(&small.to_le_bytes()[..6]);
    bytes[6..8].copy_from_slice(&t.uid.to_le_bytes());
    bytes[8] = t.to.code();
    Ok(bytes)
}

/// A complete `.btlog` in memory.
///
/// # Errors
/// As [`BtLogWriter::new`] and [`BtLogWriter::write`].
pub fn encode_btlog(
    tree: &Tree,
    start: Duration,
    transitions: &[Transition],
) -> Result<Vec<u8>, BtLogError> {
    let mut writer = BtLogWriter::new(Vec::new(), tree, start)?;
    writer.write(transitions)?;
    writer.finish()
}

/// Writes a `.btlog` file (atomically).
///
/// # Errors
/// [`BtLogErrorKind::Extension`] unless the name ends in `.btlog`; as [`encode_btlog`];
/// [`BtLogErrorKind::Io`] if the file cannot be written.
pub fn write_btlog(
    path: impl AsRef<Path>,
    tree: &Tree,
    start: Duration,
    transitions: &[Transition],
) -> Result<(), BtLogError> {
    let path = path.as_ref();
    if path.extension().and_then(|e| e.to_str()) != Some("btlog") {
        return Err(BtLogError::new(BtLogErrorKind::Extension).in_file(path));
    }
    let bytes = encode_btlog(tree, start, transitions).map_err(|e| e.in_file(path))?;
    crate::atomic::write_atomically(path, &bytes).map_err(|failure| {
        BtLogError::new(BtLogErrorKind::Io {
            action: failure.action,
            io: failure.io,
        })
        .in_file(path)
    })
}

/// One transition as stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoggedTransition {
    /// Microseconds since the first timestamp.
    pub delta_us: u64,
    /// The node uid.
    pub uid: u16,
    /// The status code (0–4).
    pub status: u8,
}

/// The content of a `.btlog` file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BtLog {
    /// The tree XML.
    pub xml: String,
    /// The first timestamp, in microseconds.
    pub first_timestamp_us: i64,
    /// The transitions in file order.
    pub transitions: Vec<LoggedTransition>,
}

/// Reads a `.btlog` from bytes.
///
/// # Errors
/// [`BtLogErrorKind::Format`] naming the byte offset of the problem: wrong magic or protocol,
/// a truncated header or XML, XML that is not UTF-8, a trailing partial transition.
pub fn decode_btlog(bytes: &[u8]) -> Result<BtLog, BtLogError> {
    let format = |reason: String| BtLogError::new(BtLogErrorKind::Format { reason });
    if bytes.len() < 23 || &bytes[..18] != BTLOG_MAGIC {
        return Err(format(
            "it does not start with BTCPP4-FileLogger2".to_owned(),
        ));
    }
    if bytes[18] != BTLOG_PROTOCOL {
        return Err(format(format!(
            "byte 18: protocol {} (only 1 is known)",
            bytes[18]
        )));
    }
    let length = i32::from_le_bytes(bytes[19..23].try_into().expect("4 bytes"));
    let length = usize::try_from(length)
        .map_err(|_| format(format!("byte 19: negative XML length {length}")))?;
    let xml_end = 23usize
        .checked_add(length)
        .filter(|&end| end.checked_add(8).is_some_and(|e| e <= bytes.len()))
        .ok_or_else(|| {
            format(format!(
                "byte 19: XML length {length} runs past the end of the file ({} bytes)",
                bytes.len()
            ))
        })?;
    let xml = std::str::from_utf8(&bytes[23..xml_end])
        .map_err(|e| {
            format(format!(
                "byte {}: the XML is not UTF-8",
                23 + e.valid_up_to()
            ))
        })?
        .to_owned();
    let first_timestamp_us =
        i64::from_le_bytes(bytes[xml_end..xml_end + 8].try_into().expect("8 bytes"));
    let body = &bytes[xml_end + 8..];
    if !body.len().is_multiple_of(9) {
        return Err(format(format!(
            "byte {}: {} bytes left after the last whole transition",
            xml_end + 8 + body.len() / 9 * 9,
            body.len() % 9
        )));
    }
    let transitions = body
        .chunks_exact(9)
        .map(|c| {
            let mut delta = [0u8; 8];
            delta[..6].copy_from_slice(&c[..6]);
            LoggedTransition {
                delta_us: u64::from_le_bytes(delta),
                uid: u16::from_le_bytes([c[6], c[7]]),
                status: c[8],
            }
        })
        .collect();
    Ok(BtLog {
        xml,
        first_timestamp_us,
        transitions,
    })
}

/// Reads a `.btlog` file.
///
/// # Errors
/// [`BtLogErrorKind::Io`] if it cannot be read; as [`decode_btlog`].
pub fn read_btlog(path: impl AsRef<Path>) -> Result<BtLog, BtLogError> {
    let path = path.as_ref();
    let bytes = crate::bounded::read(path)
        .map_err(|io| BtLogError::new(BtLogErrorKind::Io { action: "read", io }).in_file(path))?;
    decode_btlog(&bytes).map_err(|e| e.in_file(path))
}
