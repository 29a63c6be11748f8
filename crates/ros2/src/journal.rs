//! The node's write-ahead log: every message the node learned, in the order it learned them,
//! made durable in batches, so that a crash (`kill -9`, power) loses at most the last batch.
//!
//! The journal is a folder of *segments* (`journal/<first position>.cmj`), each a format
//! header followed by records:
//!
//! | bytes | field |
//! |---|---|
//! | 4 | record magic `CMJR` |
//! | 4 | payload length `n` (u32, little endian) |
//! | 8 | position (u64 LE): 0, 1, 2, … across segments, without gaps |
//! | 1 | flags: bit 0 set when the payload is deflate-compressed |
//! | 4 | CRC-32 of position, flags and payload |
//! | n | payload: an [`Entry`] in postcard |
//!
//! Appends go to a buffer; [`Journal::sync_if_due`] writes it and `fdatasync`s the segment
//! once the oldest unsynced record is older than the sync period or enough records wait
//! ([`JournalSettings`]). A checkpoint ([`crate::world::World::save`]) writes every model,
//! starts a new segment and deletes the segments it covers.
//!
//! Reading back ([`Journal::open`]) verifies every record: a damaged or torn record at the end
//! of the last segment is what a crash during a write leaves, and is cut off (logged); a
//! damaged record with intact records after it, a position out of sequence or an unknown
//! format is an error that names the file and byte, and the node does not start.

use std::borrow::Cow;
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use thiserror::Error;

use chronomap_models::learner::Refit;

use crate::msgs::{OccupancyGrid, PoseArray};

/// First bytes of every segment: the format and its version.
const SEGMENT_MAGIC: &[u8; 8] = b"CMJRNL1\n";
/// First bytes of every record.
const RECORD_MAGIC: &[u8; 4] = b"CMJR";
/// Bytes of a record before its payload.
const RECORD_HEADER: usize = 4 + 4 + 8 + 1 + 4;
/// Payloads larger than this are compressed (maps).
const COMPRESS_ABOVE: usize = 4096;
/// Flag: the payload is deflate-compressed.
const FLAG_DEFLATE: u8 = 1;
/// Extension of segment files.
const SEGMENT_EXTENSION: &str = "cmj";

/// One learned message.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub enum Entry<'a> {
    /// A state observation (`states.NAME`) at the node's time of receipt.
    State {
        /// The state's name.
        name: Cow<'a, str>,
        /// When (s).
        time: f64,
        /// The value in [0, 1].
        value: f64,
    },
    /// A map learned as a frame (`maps.NAME`).
    Map {
        /// The grid's name.
        name: Cow<'a, str>,
        /// The message as received.
        message: Cow<'a, OccupancyGrid>,
    },
    /// Detections added to the open bin of a people grid (`people.NAME`).
    People {
        /// The grid's name.
        name: Cow<'a, str>,
        /// The message as received.
        message: Cow<'a, PoseArray>,
    },
    /// The open bin of a people grid was learned because time passed it or the node stopped
    /// (bins closed by a later message need no entry: replaying the message closes them).
    BinClosed {
        /// The grid's name.
        name: Cow<'a, str>,
    },
    /// A state's model fitted on a whole series was refitted: the fit itself, installed again
    /// at this place on replay (a fit may take seconds; a replay does not repeat it).
    Refit {
        /// The state's name.
        name: Cow<'a, str>,
        /// The fit.
        refit: Box<Refit>,
    },
    /// As [`Entry::Refit`], for a state with a prediction interval (`auto` of a continuous
    /// state): the fit of its kept observations and the fit of their squares, installed
    /// together (both or neither). Appended after the other variants, so journals of nodes
    /// before intervals still read.
    RefitWithSpread {
        /// The state's name.
        name: Cow<'a, str>,
        /// The fit of the values.
        refit: Box<Refit>,
        /// The fit of their squares (the second moment, [`chronomap_core::spread`]).
        spread: Box<Refit>,
    },
}

/// Entries are equal when they encode to the same bytes (what the journal holds).
impl PartialEq for Entry<'_> {
    fn eq(&self, other: &Self) -> bool {
        postcard::to_allocvec(self).ok() == postcard::to_allocvec(other).ok()
    }
}

impl Entry<'_> {
    /// The name of the input it belongs to.
    pub fn name(&self) -> &str {
        match self {
            Entry::State { name, .. }
            | Entry::Map { name, .. }
            | Entry::People { name, .. }
            | Entry::BinClosed { name }
            | Entry::Refit { name, .. }
            | Entry::RefitWithSpread { name, .. } => name,
        }
    }
}

/// When appended records are made durable.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JournalSettings {
    /// Longest time a record waits in memory before it is written and synced.
    pub sync_period: Duration,
    /// Records that make a sync due at once.
    pub sync_records: usize,
    /// Largest payload read back, bytes (a declared length above it is damage).
    pub max_payload: usize,
}

impl Default for JournalSettings {
    fn default() -> Self {
        JournalSettings {
            sync_period: Duration::from_secs(1),
            sync_records: 1000,
            max_payload: 1 << 31,
        }
    }
}

/// Why the journal cannot be read or written.
#[derive(Debug, Error)]
pub enum JournalError {
    /// A file or folder that cannot be read, written or synced.
    #[error("{path}: cannot {action}: {io}")]
    Io {
        /// The path.
        path: String,
        /// What was being done.
        action: &'static str,
        /// Why (part of the message, not a further error in the chain).
        io: io::Error,
    },
    /// Content that is not what the journal wrote.
    #[error(
        "{path}: byte {offset}: {reason}; move the journal folder away to start from the last checkpoint"
    )]
    Damaged {
        /// The segment.
        path: String,
        /// Where in it.
        offset: u64,
        /// What is wrong.
        reason: String,
    },
    /// Segments are missing between or after those found.
    #[error("{path}: {reason}; move the journal folder away to start from the last checkpoint")]
    Missing {
        /// The segment or folder.
        path: String,
        /// What is missing.
        reason: String,
    },
    /// A record that cannot be encoded.
    #[error("cannot encode a journal record: {0}")]
    Encode(String),
}

fn io_error<'p>(
    path: &'p Path,
    action: &'static str,
) -> impl FnOnce(io::Error) -> JournalError + 'p {
    move |source| JournalError::Io {
        path: path.display().to_string(),
        action,
        io: source,
    }
}

/// What reading the journal back found.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Recovered {
    /// Records read (and handed to the visitor).
    pub records: u64,
    /// The position of the first record read, if any.
    pub first: Option<u64>,
    /// Segments read.
    pub segments: usize,
    /// Bytes cut off the end of the last segment (a write torn by a crash).
    pub torn_bytes: u64,
}

/// The segment records are appended to.
struct Segment {
    path: PathBuf,
    writer: BufWriter<File>,
}

/// An open journal (see the [module docs](self)).
pub struct Journal {
    dir: PathBuf,
    settings: JournalSettings,
    /// `(first position, path)` of every segment, in order; the last is `current`'s.
    segments: Vec<(u64, PathBuf)>,
    current: Option<Segment>,
    next: u64,
    unsynced: usize,
    oldest_unsynced: Option<Instant>,
}

impl Journal {
    /// Opens the journal in `dir` (created if missing), hands every record to `visit` in order
    /// with its position, cuts off a torn last record, and starts a new segment for appending.
    /// `head` is the position the last checkpoint reached: the journal must reach it (an empty
    /// or missing journal starts there).
    ///
    /// # Errors
    /// A folder or segment that cannot be read or written, damaged records or missing segments
    /// (see the [module docs](self)), or what `visit` returns.
    pub fn open<E: From<JournalError>>(
        dir: &Path,
        head: u64,
        settings: JournalSettings,
        mut visit: impl FnMut(u64, Entry<'static>) -> Result<(), E>,
    ) -> Result<(Journal, Recovered), E> {
        fs::create_dir_all(dir).map_err(io_error(dir, "create the folder"))?;
        let segments = list_segments(dir)?;
        let mut recovered = Recovered::default();
        let mut next: Option<u64> = None;
        for (i, (start, path)) in segments.iter().enumerate() {
            let last = i + 1 == segments.len();
            if let Some(expected) = next
                && *start != expected
            {
                return Err(JournalError::Missing {
                    path: path.display().to_string(),
                    reason: format!(
                        "the segment starts at position {start}, but position {expected} comes \
                         next: segments are missing"
                    ),
                }
                .into());
            }
            let read = read_segment(path, *start, last, settings.max_payload, &mut visit)?;
            recovered.segments += 1;
            recovered.records += read.records;
            recovered.torn_bytes += read.torn_bytes;
            if recovered.first.is_none() && read.records > 0 {
                recovered.first = Some(*start);
            }
            next = Some(start + read.records);
        }
        let next = match next {
            None => head,
            Some(next) if next >= head => next,
            Some(next) => {
                return Err(JournalError::Missing {
                    path: dir.display().to_string(),
                    reason: format!(
                        "the journal ends at position {next}, before the checkpoint's {head}: \
                         segments are missing"
                    ),
                }
                .into());
            }
        };
        let mut journal = Journal {
            dir: dir.to_path_buf(),
            settings,
            segments,
            current: None,
            next,
            unsynced: 0,
            oldest_unsynced: None,
        };
        journal.start_segment()?;
        Ok((journal, recovered))
    }

    /// The position the next record gets.
    pub fn next_position(&self) -> u64 {
        self.next
    }

    /// Appends `entry` (buffered; durable after the next sync); returns its position.
    ///
    /// # Errors
    /// The record cannot be encoded or written.
    pub fn append(&mut self, entry: &Entry<'_>, now: Instant) -> Result<u64, JournalError> {
        let payload =
            postcard::to_allocvec(entry).map_err(|e| JournalError::Encode(e.to_string()))?;
        let (flags, payload) = if payload.len() > COMPRESS_ABOVE {
            (FLAG_DEFLATE, deflate(&payload))
        } else {
            (0, payload)
        };
        let len = u32::try_from(payload.len())
            .ok()
            .filter(|&n| n as usize <= self.settings.max_payload)
            .ok_or_else(|| {
                JournalError::Encode(format!("a record of {} bytes is too large", payload.len()))
            })?;
        let seq = self.next;
        let segment = match &mut self.current {
            Some(segment) => segment,
            None => {
                self.start_segment()?;
                self.current.as_mut().expect("just started")
            }
        };
        let mut header = Vec::with_capacity(RECORD_HEADER);
        header.extend_from_slice(RECORD_MAGIC);
        header.extend_from_slice(&len.to_le_bytes());
        header.extend_from_slice(&seq.to_le_bytes());
        header.push(flags);
        header.extend_from_slice(&checksum(seq, flags, &payload).to_le_bytes());
        let written = segment
            .writer
            .write_all(&header)
            .and_then(|()| segment.writer.write_all(&payload));
        if let Err(source) = written {
            // What was buffered may be partly written: this segment ends here.
            let path = segment.path.clone();
            self.current = None;
            return Err(io_error(&path, "append to")(source));
        }
        self.next += 1;
        self.unsynced += 1;
        self.oldest_unsynced.get_or_insert(now);
        Ok(seq)
    }

    /// Whether records wait to be synced.
    pub fn pending(&self) -> usize {
        self.unsynced
    }

    /// Writes and syncs what was appended if the oldest record has waited the sync period or
    /// enough records wait; returns whether it synced.
    ///
    /// # Errors
    /// As [`Journal::sync`].
    pub fn sync_if_due(&mut self, now: Instant) -> Result<bool, JournalError> {
        let due = self.unsynced >= self.settings.sync_records
            || self
                .oldest_unsynced
                .is_some_and(|t| now.saturating_duration_since(t) >= self.settings.sync_period);
        if due {
            self.sync()?;
        }
        Ok(due)
    }

    /// Writes and syncs everything appended.
    ///
    /// # Errors
    /// The segment cannot be written or synced; it is then closed and the next append starts
    /// a new one.
    pub fn sync(&mut self) -> Result<(), JournalError> {
        if self.unsynced == 0 {
            return Ok(());
        }
        let Some(segment) = &mut self.current else {
            return Ok(());
        };
        let result = segment
            .writer
            .flush()
            .and_then(|()| segment.writer.get_ref().sync_data());
        if let Err(source) = result {
            let path = segment.path.clone();
            self.current = None;
            return Err(io_error(&path, "sync")(source));
        }
        self.unsynced = 0;
        self.oldest_unsynced = None;
        Ok(())
    }

    /// Syncs, then starts a new segment at the next position (a checkpoint's first step).
    ///
    /// # Errors
    /// As [`Journal::sync`], or a segment that cannot be created.
    pub fn rotate(&mut self) -> Result<(), JournalError> {
        self.sync()?;
        self.current = None;
        self.start_segment()
    }

    /// Deletes the segments whose records all lie before position `keep` (a checkpoint covers
    /// them); returns how many.
    ///
    /// # Errors
    /// A segment that cannot be deleted.
    pub fn forget_before(&mut self, keep: u64) -> Result<usize, JournalError> {
        let mut removed = 0;
        while self.segments.len() > 1 && self.segments[1].0 <= keep {
            let (_, path) = self.segments.remove(0);
            fs::remove_file(&path).map_err(io_error(&path, "delete"))?;
            removed += 1;
        }
        if removed > 0 {
            sync_dir(&self.dir)?;
        }
        Ok(removed)
    }

    /// Starts a segment at the next position, unless the current one is still empty.
    fn start_segment(&mut self) -> Result<(), JournalError> {
        if let Some((start, path)) = self.segments.last()
            && *start == self.next
        {
            // The last segment holds no record: append to it (after its header).
            let path = path.clone();
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .open(&path)
                .map_err(io_error(&path, "open"))?;
            file.set_len(SEGMENT_MAGIC.len() as u64)
                .and_then(|()| file.seek(SeekFrom::End(0)).map(drop))
                .map_err(io_error(&path, "reset"))?;
            self.current = Some(Segment {
                path,
                writer: BufWriter::with_capacity(1 << 16, file),
            });
            return Ok(());
        }
        let path = self
            .dir
            .join(format!("{:020}.{SEGMENT_EXTENSION}", self.next));
        let mut file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)
            .map_err(io_error(&path, "create"))?;
        file.write_all(SEGMENT_MAGIC)
            .and_then(|()| file.sync_all())
            .map_err(io_error(&path, "write"))?;
        sync_dir(&self.dir)?;
        self.segments.push((self.next, path.clone()));
        self.current = Some(Segment {
            path,
            writer: BufWriter::with_capacity(1 << 16, file),
        });
        Ok(())
    }
}

/// Makes created, renamed and deleted entries of `dir` durable.
pub(crate) fn sync_dir(dir: &Path) -> Result<(), JournalError> {
    File::open(dir)
        .and_then(|d| d.sync_all())
        .map_err(io_error(dir, "sync the folder"))
}

/// The segments in `dir`, by first position; other files are an error (the journal folder is
/// the node's own).
fn list_segments(dir: &Path) -> Result<Vec<(u64, PathBuf)>, JournalError> {
    let mut segments = Vec::new();
    for item in fs::read_dir(dir).map_err(io_error(dir, "list"))? {
        let item = item.map_err(io_error(dir, "list"))?;
        let path = item.path();
        let name = item.file_name();
        let name = name.to_string_lossy();
        let start = name
            .strip_suffix(&format!(".{SEGMENT_EXTENSION}"))
            .filter(|digits| digits.len() == 20 && digits.bytes().all(|b| b.is_ascii_digit()))
            .and_then(|digits| digits.parse::<u64>().ok());
        match start {
            Some(start) => {
                let kind = item.file_type().map_err(io_error(&path, "inspect"))?;
                if !kind.is_file() {
                    return Err(JournalError::Damaged {
                        path: path.display().to_string(),
                        offset: 0,
                        reason: "not a regular file".into(),
                    });
                }
                segments.push((start, path));
            }
            None => {
                return Err(JournalError::Damaged {
                    path: path.display().to_string(),
                    offset: 0,
                    reason: "not a journal segment (the folder is the node's own)".into(),
                });
            }
        }
    }
    segments.sort();
    Ok(segments)
}

/// What one segment held.
struct SegmentRead {
    records: u64,
    torn_bytes: u64,
}

/// Reads the segment `path` starting at position `start`, handing records to `visit` one by
/// one (memory: one record). A bad record with nothing intact after it ends the segment (in the
/// `last` one it is cut off); one with an intact record after it is damage.
fn read_segment<E: From<JournalError>>(
    path: &Path,
    start: u64,
    last: bool,
    max_payload: usize,
    visit: &mut dyn FnMut(u64, Entry<'static>) -> Result<(), E>,
) -> Result<SegmentRead, E> {
    let name = path.display().to_string();
    let damaged = |offset: u64, reason: String| JournalError::Damaged {
        path: name.clone(),
        offset,
        reason,
    };
    let file = File::open(path).map_err(io_error(path, "open"))?;
    let size = file.metadata().map_err(io_error(path, "inspect"))?.len();
    let mut reader = io::BufReader::with_capacity(1 << 16, file);
    let mut magic = Vec::with_capacity(SEGMENT_MAGIC.len());
    (&mut reader)
        .take(SEGMENT_MAGIC.len() as u64)
        .read_to_end(&mut magic)
        .map_err(io_error(path, "read"))?;
    if magic != SEGMENT_MAGIC {
        if last && size < SEGMENT_MAGIC.len() as u64 && SEGMENT_MAGIC.starts_with(&magic) {
            // Created but its header never reached the disk: nothing was written to it.
            drop(reader);
            rewrite_header(path)?;
            return Ok(SegmentRead {
                records: 0,
                torn_bytes: size,
            });
        }
        let found = String::from_utf8_lossy(&magic).into_owned();
        return Err(damaged(
            0,
            format!("not a journal segment of a known version (starts with {found:?})"),
        )
        .into());
    }
    let mut offset = SEGMENT_MAGIC.len() as u64;
    let mut seq = start;
    let mut record = Vec::new();
    while offset < size {
        let parsed = read_record(&mut reader, size - offset, max_payload, &mut record)
            .map_err(io_error(path, "read"))?
            .and_then(|used| parse_record(&record, seq, max_payload).map(|e| (e, used)));
        match parsed {
            Ok((entry, used)) => {
                visit(seq, entry)?;
                seq += 1;
                offset += used;
            }
            Err(reason) => {
                // A bad record with nothing intact after it is a write that did not complete:
                // a crash (in the last segment) or a failed write after which the node went on
                // in a new segment (whose first position then follows this one's last record,
                // which `Journal::open` checks).
                if let Some(p) = find_intact_record(path, offset + 1, max_payload)? {
                    return Err(damaged(
                        offset,
                        format!("{reason}; an intact record (position {p}) follows it"),
                    )
                    .into());
                }
                let torn = size - offset;
                log::warn!(
                    "{name}: {torn} bytes at byte {offset} after position {} are not an intact \
                     record ({reason}): a write torn by a crash or a failed write; what was \
                     synced before it is kept",
                    seq.saturating_sub(1)
                );
                if last {
                    drop(reader);
                    truncate(path, offset)?;
                }
                return Ok(SegmentRead {
                    records: seq - start,
                    torn_bytes: torn,
                });
            }
        }
    }
    Ok(SegmentRead {
        records: seq - start,
        torn_bytes: 0,
    })
}

/// Reads the next record (header and payload) into `record`, if `remaining` bytes hold it:
/// the bytes it used, or why it is not there. The declared length is checked against what
/// remains before anything is allocated.
fn read_record(
    reader: &mut impl Read,
    remaining: u64,
    max_payload: usize,
    record: &mut Vec<u8>,
) -> io::Result<Result<u64, String>> {
    record.clear();
    if remaining < RECORD_HEADER as u64 {
        return Ok(Err(format!(
            "{remaining} bytes, less than a record header ({RECORD_HEADER})"
        )));
    }
    record.resize(RECORD_HEADER, 0);
    reader.read_exact(record)?;
    if &record[..4] != RECORD_MAGIC {
        return Ok(Err("no record starts here".into()));
    }
    let len = u32::from_le_bytes(record[4..8].try_into().expect("4 bytes")) as u64;
    if len > max_payload as u64 {
        return Ok(Err(format!(
            "a declared length of {len} bytes (at most {max_payload})"
        )));
    }
    if len > remaining - RECORD_HEADER as u64 {
        return Ok(Err(format!(
            "a declared length of {len} bytes, but {} follow",
            remaining - RECORD_HEADER as u64
        )));
    }
    reader.take(len).read_to_end(record)?;
    Ok(Ok(RECORD_HEADER as u64 + len))
}

/// Decodes a whole record, which must have position `seq`: its entry, or why it is not intact.
fn parse_record(record: &[u8], seq: u64, max_payload: usize) -> Result<Entry<'static>, String> {
    let (found, flags, payload) = split_record(record, max_payload)?;
    if found != seq {
        return Err(format!("position {found} where {seq} was expected"));
    }
    let decoded;
    let payload = if flags & FLAG_DEFLATE != 0 {
        decoded = inflate(payload, max_payload)?;
        &decoded[..]
    } else {
        payload
    };
    postcard::from_bytes(payload).map_err(|e| format!("a record that does not decode: {e}"))
}

/// Position, flags and payload of the record at the start of `bytes`, checksum verified.
fn split_record(bytes: &[u8], max_payload: usize) -> Result<(u64, u8, &[u8]), String> {
    if bytes.len() < RECORD_HEADER || &bytes[..4] != RECORD_MAGIC {
        return Err("no record starts here".into());
    }
    let len = u32::from_le_bytes(bytes[4..8].try_into().expect("4 bytes")) as usize;
    let seq = u64::from_le_bytes(bytes[8..16].try_into().expect("8 bytes"));
    let flags = bytes[16];
    let crc = u32::from_le_bytes(bytes[17..21].try_into().expect("4 bytes"));
    if len > max_payload {
        return Err(format!(
            "a declared length of {len} bytes (at most {max_payload})"
        ));
    }
    if flags & !FLAG_DEFLATE != 0 {
        return Err(format!("unknown flags {flags:#04x}"));
    }
    let Some(payload) = bytes.get(RECORD_HEADER..RECORD_HEADER + len) else {
        return Err(format!(
            "a declared length of {len} bytes, but {} follow",
            bytes.len() - RECORD_HEADER
        ));
    };
    if checksum(seq, flags, payload) != crc {
        return Err("checksum mismatch".into());
    }
    Ok((seq, flags, payload))
}

/// Bytes `find_intact_record` reads from a segment at once: with the few bytes of a record
/// header that straddle two reads, its window never holds more than
/// `SCAN_CHUNK + RECORD_HEADER` bytes, however long the damaged region or large the records.
pub const SCAN_CHUNK: usize = 64 * 1024;

/// The position of an intact record in `path` at or after byte `from`, if there is one (only
/// on the path of a damaged record). It scans the rest of the segment through a window of at
/// most [`SCAN_CHUNK`]` + RECORD_HEADER` bytes, and checks the checksum of a candidate whose
/// payload runs past the window by streaming the payload from the file, so that its memory
/// does not grow with the segment or with `max_payload`.
fn find_intact_record(
    path: &Path,
    from: u64,
    max_payload: usize,
) -> Result<Option<u64>, JournalError> {
    File::open(path)
        .and_then(|mut file| scan_for_record(&mut file, from, max_payload))
        .map_err(io_error(path, "read"))
}

/// [`find_intact_record`] in `file`: the position of the first record at or after byte `from`
/// that [`split_record`] would take (magic, declared length at most `max_payload` and within
/// the file, known flags, checksum).
fn scan_for_record(
    file: &mut (impl Read + Seek),
    from: u64,
    max_payload: usize,
) -> io::Result<Option<u64>> {
    let mut window: Vec<u8> = Vec::with_capacity(SCAN_CHUNK + RECORD_HEADER);
    // The byte of the file at `window[0]`.
    let mut window_at = from;
    loop {
        let kept = window.len();
        window.resize(kept + SCAN_CHUNK, 0);
        file.seek(SeekFrom::Start(window_at + kept as u64))?;
        let read = read_full(file, &mut window[kept..])?;
        window.truncate(kept + read);
        let end = read == 0;
        let mut i = 0;
        while i + RECORD_MAGIC.len() <= window.len() {
            if &window[i..i + RECORD_MAGIC.len()] == RECORD_MAGIC {
                if i + RECORD_HEADER > window.len() && !end {
                    // Its header straddles this read and the next.
                    break;
                }
                if let Some(seq) =
                    check_candidate(file, window_at + i as u64, &window[i..], max_payload)?
                {
                    return Ok(Some(seq));
                }
            }
            i += 1;
        }
        if end {
            return Ok(None);
        }
        window.drain(..i);
        window_at += i as u64;
    }
}

/// Reads into `buf` until it is full or the file ends: the bytes read.
fn read_full(file: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match file.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

/// The position of the record that starts with `head` at byte `at` of `file`, if it is intact:
/// its header from `head`, its payload from `head` where the window holds all of it, else
/// read from the file in pieces of 8 KiB into the checksum.
fn check_candidate(
    file: &mut (impl Read + Seek),
    at: u64,
    head: &[u8],
    max_payload: usize,
) -> io::Result<Option<u64>> {
    if head.len() < RECORD_HEADER {
        return Ok(None);
    }
    let len = u32::from_le_bytes(head[4..8].try_into().expect("4 bytes")) as usize;
    let seq = u64::from_le_bytes(head[8..16].try_into().expect("8 bytes"));
    let flags = head[16];
    let crc = u32::from_le_bytes(head[17..21].try_into().expect("4 bytes"));
    if len > max_payload || flags & !FLAG_DEFLATE != 0 {
        return Ok(None);
    }
    if let Some(payload) = head.get(RECORD_HEADER..RECORD_HEADER + len) {
        return Ok((checksum(seq, flags, payload) == crc).then_some(seq));
    }
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(&seq.to_le_bytes());
    hasher.update(&[flags]);
    file.seek(SeekFrom::Start(at + RECORD_HEADER as u64))?;
    let mut piece = [0u8; 8192];
    let mut left = len;
    while left > 0 {
        let n = read_full(file, &mut piece[..left.min(8192)])?;
        if n == 0 {
            // The file ends inside the declared payload.
            return Ok(None);
        }
        hasher.update(&piece[..n]);
        left -= n;
    }
    Ok((hasher.finalize() == crc).then_some(seq))
}

fn checksum(seq: u64, flags: u8, payload: &[u8]) -> u32 {
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(&seq.to_le_bytes());
    hasher.update(&[flags]);
    hasher.update(payload);
    hasher.finalize()
}

fn deflate(bytes: &[u8]) -> Vec<u8> {
    let mut encoder = flate2::write::DeflateEncoder::new(
        Vec::with_capacity(bytes.len() / 4),
        flate2::Compression::fast(),
    );
    encoder.write_all(bytes).expect("writing to memory");
    encoder.finish().expect("writing to memory")
}

/// Inflates at most `max` bytes (a payload that inflates further is damage, not a record).
fn inflate(bytes: &[u8], max: usize) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    flate2::read::DeflateDecoder::new(bytes)
        .take(max as u64 + 1)
        .read_to_end(&mut out)
        .map_err(|e| format!("a compressed record that does not inflate: {e}"))?;
    if out.len() > max {
        return Err(format!(
            "a compressed record inflating to more than {max} bytes"
        ));
    }
    Ok(out)
}

fn truncate(path: &Path, len: u64) -> Result<(), JournalError> {
    let file = OpenOptions::new()
        .write(true)
        .open(path)
        .map_err(io_error(path, "open"))?;
    file.set_len(len)
        .and_then(|()| file.sync_all())
        .map_err(io_error(path, "cut off the torn end of"))
}

fn rewrite_header(path: &Path) -> Result<(), JournalError> {
    let mut file = OpenOptions::new()
        .write(true)
        .truncate(true)
        .open(path)
        .map_err(io_error(path, "open"))?;
    file.write_all(SEGMENT_MAGIC)
        .and_then(|()| file.sync_all())
        .map_err(io_error(path, "write"))
}

#[cfg(test)]
mod tests;
