//! rosbag2's SQLite 3 storage (`.db3`): the default up to ROS 2 Humble, so most bags recorded on
//! Humble robots are in it. Tables `topics` (`id, name, type, serialization_format, ...`),
//! `messages` (`id, topic_id, timestamp, data`) and, since Iron, `message_definitions`
//! (`topic_type, encoding, encoded_message_definition`). Messages are read in time order (the
//! order `ros2 bag play` uses), each topic becoming a channel like those of an MCAP file, so
//! that everything above reads both storages the same way.
//!
//! The file is opened read-only and immutable (nothing is written beside it, and a bag on a
//! read-only disk opens); a damaged file is an error naming it and the message before the
//! damage.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use std::sync::Arc;

use chronomap_core::progress::Progress;
use rusqlite::{Connection, OpenFlags};

use crate::bag::{BagError, MAX_DEFINITION_BYTES, MAX_NAME_BYTES, MAX_RECORD_BYTES};

/// Calls `each(channel, log_time, publish_time, data)` for every message of the SQLite bag
/// file `path`, in time order; `err(place, problem)` makes this file's errors.
pub(crate) fn read_messages<E: From<BagError>>(
    path: &Path,
    progress: &dyn Progress,
    err: &dyn Fn(Option<String>, String) -> BagError,
    each: &mut dyn FnMut(Arc<mcap::Channel<'static>>, u64, u64, Vec<u8>) -> Result<(), E>,
) -> Result<(), E> {
    let meta = std::fs::metadata(path).map_err(|e| err(None, e.to_string()))?;
    if !meta.is_file() {
        return Err(err(None, "not a regular file".into()).into());
    }
    let file_size = meta.len();
    let db = open(path).map_err(|e| err(None, problem(&e)))?;
    let channels = channels(&db).map_err(|e| err(Some("the table `topics`".into()), e))?;
    let mut statement = db
        .prepare(
            "SELECT topic_id, timestamp, octet_length(data), data FROM messages \
             ORDER BY timestamp, id",
        )
        .map_err(|e| err(Some("the table `messages`".into()), problem(&e)))?;
    let mut rows = statement
        .query([])
        .map_err(|e| err(Some("the table `messages`".into()), problem(&e)))?;
    let mut count = 0u64;
    loop {
        let row = match rows.next() {
            Ok(Some(row)) => row,
            Ok(None) => break,
            Err(e) => {
                return Err(err(Some(format!("after {count} messages")), problem(&e)).into());
            }
        };
        let place = || Some(format!("the row of message {count} in `messages`"));
        let topic_id: i64 = row.get(0).map_err(|e| err(place(), problem(&e)))?;
        let timestamp: i64 = row.get(1).map_err(|e| err(place(), problem(&e)))?;
        // SQLite keeps a blob's size in the row's header: checked before the blob is copied.
        let size: Option<i64> = row.get(2).map_err(|e| err(place(), problem(&e)))?;
        let size = u64::try_from(size.unwrap_or(0)).unwrap_or(u64::MAX);
        if size > file_size || size > MAX_RECORD_BYTES as u64 {
            return Err(err(
                place(),
                format!(
                    "its data declare {size} bytes, more than {}",
                    if size > file_size {
                        format!("the whole file ({file_size} bytes)")
                    } else {
                        format!("the {MAX_RECORD_BYTES} a message may have")
                    }
                ),
            )
            .into());
        }
        let data: Vec<u8> = row.get(3).map_err(|e| err(place(), problem(&e)))?;
        let channel = channels.get(&topic_id).ok_or_else(|| {
            err(
                place(),
                format!("topic_id {topic_id} is not in the table `topics`"),
            )
        })?;
        let log_time = u64::try_from(timestamp)
            .map_err(|_| err(place(), format!("timestamp {timestamp} ns is before 1970")))?;
        progress.advance(data.len() as u64);
        count += 1;
        each(channel.clone(), log_time, log_time, data)?;
    }
    Ok(())
}

fn open(path: &Path) -> rusqlite::Result<Connection> {
    let flags = OpenFlags::SQLITE_OPEN_READ_ONLY
        | OpenFlags::SQLITE_OPEN_URI
        | OpenFlags::SQLITE_OPEN_NO_MUTEX;
    // `immutable=1`: no locks, no -wal/-shm files beside the bag.
    let uri = format!("file:{}?immutable=1", uri_path(path));
    let db = Connection::open_with_flags(uri, flags)?;
    // A damaged header is found here, not at the first row.
    db.query_row("SELECT count(*) FROM sqlite_master", [], |_| Ok(()))?;
    Ok(db)
}

/// `path` with the characters that URIs reserve escaped.
fn uri_path(path: &Path) -> String {
    let text = path.to_string_lossy();
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '%' | '?' | '#' => out.push_str(&format!("%{:02X}", c as u32)),
            c => out.push(c),
        }
    }
    out
}

/// One channel per row of `topics`, with the definition of its type when the bag has one.
fn channels(db: &Connection) -> Result<HashMap<i64, Arc<mcap::Channel<'static>>>, String> {
    read_channels(db).map_err(|e| match e {
        Read::Db(e) => problem(&e),
        Read::Bad(p) => p,
    })
}

/// Why the channels could not be read.
enum Read {
    Db(rusqlite::Error),
    Bad(String),
}

impl From<rusqlite::Error> for Read {
    fn from(e: rusqlite::Error) -> Self {
        Read::Db(e)
    }
}

/// `text` if it is at most `max` bytes long.
fn bounded(text: String, what: &str, max: usize) -> Result<String, Read> {
    if text.len() > max {
        return Err(Read::Bad(format!(
            "{what} has {} bytes, more than the {max} it may have",
            text.len()
        )));
    }
    Ok(text)
}

fn read_channels(db: &Connection) -> Result<HashMap<i64, Arc<mcap::Channel<'static>>>, Read> {
    let has_definitions: bool = db.query_row(
        "SELECT count(*) > 0 FROM sqlite_master WHERE type = 'table' AND name = 'message_definitions'",
        [],
        |row| row.get(0),
    )?;
    let mut definitions: HashMap<String, (String, String)> = HashMap::new();
    if has_definitions {
        let mut statement = db.prepare(
            "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions",
        )?;
        let rows = statement.query_map([], |row| {
            Ok((
                row.get::<_, String>(0)?,
                row.get::<_, String>(1)?,
                row.get::<_, String>(2)?,
            ))
        })?;
        let mut total = 0usize;
        for row in rows {
            let (ty, encoding, text) = row?;
            total = total.saturating_add(text.len());
            if total > MAX_DEFINITION_BYTES {
                return Err(Read::Bad(format!(
                    "the message definitions have more than the {MAX_DEFINITION_BYTES} bytes \
                     they may have"
                )));
            }
            let ty = bounded(ty, "a topic_type of `message_definitions`", MAX_NAME_BYTES)?;
            definitions.entry(ty).or_insert((encoding, text));
        }
    }
    let mut statement = db.prepare("SELECT id, name, type, serialization_format FROM topics")?;
    let rows = statement.query_map([], |row| {
        Ok((
            row.get::<_, i64>(0)?,
            row.get::<_, String>(1)?,
            row.get::<_, String>(2)?,
            row.get::<_, String>(3)?,
        ))
    })?;
    let mut channels = HashMap::new();
    for (i, row) in rows.enumerate() {
        let (id, name, ty, format) = row?;
        let name = bounded(name, &format!("the name of topic id {id}"), MAX_NAME_BYTES)?;
        let ty = bounded(ty, &format!("the type of topic id {id}"), MAX_NAME_BYTES)?;
        let format = bounded(
            format,
            &format!("the serialization_format of topic id {id}"),
            MAX_NAME_BYTES,
        )?;
        let (encoding, text) = definitions.get(&ty).cloned().unwrap_or_default();
        let schema = mcap::Schema {
            id: u16::try_from(i + 1).unwrap_or(u16::MAX),
            name: ty,
            encoding,
            data: text.into_bytes().into(),
        };
        channels.insert(
            id,
            Arc::new(mcap::Channel {
                id: u16::try_from(i).unwrap_or(u16::MAX),
                topic: name,
                schema: Some(Arc::new(schema)),
                message_encoding: format,
                metadata: BTreeMap::new(),
            }),
        );
    }
    Ok(channels)
}

fn problem(e: &rusqlite::Error) -> String {
    match e {
        rusqlite::Error::SqliteFailure(f, _) if f.code == rusqlite::ErrorCode::NotADatabase => {
            "not an SQLite database (damaged, or not a rosbag2 .db3 file)".into()
        }
        rusqlite::Error::SqliteFailure(f, _) if f.code == rusqlite::ErrorCode::DatabaseCorrupt => {
            format!("the database is damaged: {e}")
        }
        other => format!("not a rosbag2 SQLite bag: {other}"),
    }
}
