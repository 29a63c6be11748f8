//! Opening rosbag2 bags and reading their messages in order, decoded by the bag's own
//! message definitions.
//!
//! A bag is a folder with `metadata.yaml` and its storage files, or one storage file. MCAP
//! storage (the rosbag2 default since Iron) is read as a stream: memory follows the largest
//! chunk, not the file. Files compressed by rosbag2 (`compression_mode: file`, `.mcap.zstd`)
//! and messages compressed one by one (`compression_mode: message`) are decompressed on the
//! way. SQLite storage (`.db3`, the default up to Humble) is read too, in time order as
//! rosbag2 plays it, with the definitions the bag stores since Iron (older bags: the built-in
//! ones).
//!
//! ```no_run
//! use chronomap_core::progress::NoProgress;
//! use chronomap_rosbag::Bag;
//!
//! let bag = Bag::open("data/malaga_laser_2006/rosbag2/malaga_2006_bag")?;
//! for topic in bag.summary(&NoProgress)?.topics {
//!     println!("{} {} {}", topic.name, topic.type_name, topic.count);
//! }
//! # Ok::<(), chronomap_rosbag::BagError>(())
//! ```

use std::cell::RefCell;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt;
use std::fs::File;
use std::io::{self, BufReader, Read};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use chronomap_core::progress::Progress;
use serde::Deserialize;
use thiserror::Error;

use crate::builtin;
use crate::cdr::{self, Value};
use crate::msgdef::{Schema, canonical_type_name};
use crate::time::nanos_seconds;

/// Largest `metadata.yaml` read (bytes): 16 MiB.
pub const MAX_METADATA_BYTES: u64 = 16 << 20;

/// Largest record of an MCAP file: 1 GiB. A record must also fit in what remains of its file
/// (checked before it is read).
pub const MAX_RECORD_BYTES: usize = 1 << 30;

/// Most bytes that decompression may produce at once: a compressed MCAP chunk (its declared
/// uncompressed size is checked, and decompression stops one byte past it), a record of a
/// compressed file (`.mcap.zstd`) or a message compressed by rosbag2: 256 MiB.
pub const MAX_DECOMPRESSED_BYTES: usize = 256 << 20;

/// Longest topic, type, schema or encoding name (bytes), in MCAP records, SQLite tables and
/// `metadata.yaml`: ROS 2 names are far shorter (DDS allows 256 bytes for a topic).
pub const MAX_NAME_BYTES: usize = 4096;

/// Most bytes of the distinct schema and channel records one MCAP file may define: 64 MiB.
pub const MAX_DEFINITION_BYTES: usize = 64 << 20;

/// The `metadata.yaml` format versions chronomap reads: 1 (rosbag2 in Dashing) to 9 (Jazzy,
/// Kilted).
pub const METADATA_VERSIONS: std::ops::RangeInclusive<u32> = 1..=9;

/// An error reading a bag: which bag, file and message, and what is wrong.
#[derive(Clone, Debug, Error)]
pub struct BagError {
    /// The bag as it was named.
    pub bag: String,
    /// Where in the bag: a file, a message, a record.
    pub place: Option<String>,
    /// What is wrong.
    pub problem: String,
}

impl fmt::Display for BagError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.bag)?;
        if let Some(place) = &self.place {
            write!(f, ": {place}")?;
        }
        write!(f, ": {}", self.problem)
    }
}

impl BagError {
    pub(crate) fn new(bag: &str, place: Option<String>, problem: impl Into<String>) -> Self {
        BagError {
            bag: bag.to_string(),
            place,
            problem: problem.into(),
        }
    }
}

/// How a bag stores its messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Storage {
    /// MCAP files (the rosbag2 default since Iron).
    Mcap,
    /// SQLite 3 files (`.db3`, the default up to Humble).
    Sqlite,
}

/// How rosbag2 compressed a bag.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Compression {
    None,
    /// Each storage file is one zstd stream.
    File,
    /// Each message's data is one zstd frame.
    Message,
}

/// The parts of rosbag2's `metadata.yaml` that reading needs.
#[derive(Debug, Default, Deserialize)]
struct MetadataFile {
    rosbag2_bagfile_information: Metadata,
}

/// What `metadata.yaml` says about a bag.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(default)]
pub struct Metadata {
    /// Format version (9 since Jazzy).
    pub version: u32,
    /// `mcap` or `sqlite3`.
    pub storage_identifier: String,
    /// Storage files, relative to the folder.
    pub relative_file_paths: Vec<String>,
    /// `zstd` or empty.
    pub compression_format: String,
    /// `FILE`, `MESSAGE` or empty.
    pub compression_mode: String,
    /// Messages in the bag.
    pub message_count: u64,
    /// Topics with their types and counts.
    pub topics_with_message_count: Vec<TopicCount>,
}

/// One topic of `metadata.yaml`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(default)]
pub struct TopicCount {
    /// Messages on the topic.
    pub message_count: u64,
    /// The topic.
    pub topic_metadata: TopicMetadata,
}

/// A topic's name, type and serialisation as `metadata.yaml` gives them.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(default)]
pub struct TopicMetadata {
    /// `/scan`.
    pub name: String,
    /// `sensor_msgs/msg/LaserScan`.
    #[serde(rename = "type")]
    pub type_name: String,
    /// `cdr`.
    pub serialization_format: String,
}

/// A rosbag2 bag, opened.
#[derive(Clone, Debug)]
pub struct Bag {
    name: String,
    files: Vec<PathBuf>,
    storage: Storage,
    compression: Compression,
    metadata: Option<Metadata>,
}

/// One message as stored: where it is, its topic and its bytes.
#[derive(Clone, Debug)]
pub struct BagMessage {
    /// Position in the bag, from 0, over all topics and files.
    pub index: u64,
    /// Position among the messages of its topic, from 0.
    pub topic_index: u64,
    /// The channel (topic, type, encoding, schema).
    pub channel: Arc<mcap::Channel<'static>>,
    /// When the recorder received it (ns since the epoch).
    pub log_time: u64,
    /// When the publisher sent it, if the recorder knew (ns), else the log time.
    pub publish_time: u64,
    /// The serialised message (CDR with its 4-byte header), decompressed.
    pub data: Vec<u8>,
}

impl BagMessage {
    /// The topic.
    pub fn topic(&self) -> &str {
        &self.channel.topic
    }

    /// The message type (`pkg/msg/Type`), from the schema or `metadata.yaml`.
    pub fn type_name(&self) -> &str {
        self.channel
            .schema
            .as_ref()
            .map(|s| s.name.as_str())
            .unwrap_or("")
    }

    /// "message 12 (/scan, log time 1137834226.1 s)", for errors.
    pub fn describe(&self) -> String {
        describe(self.index, self.topic(), self.topic_index, self.log_time)
    }
}

/// What a whole pass over a bag found.
#[derive(Clone, Debug, PartialEq)]
pub struct BagSummary {
    /// Messages in the bag.
    pub messages: u64,
    /// Bytes read (after decompression of files, before that of chunks).
    pub bytes: u64,
    /// The topics in order of first appearance.
    pub topics: Vec<TopicSummary>,
    /// Where `metadata.yaml` disagrees with what was read (its message counts), in words.
    pub warnings: Vec<String>,
}

/// One topic of a bag.
#[derive(Clone, Debug, PartialEq)]
pub struct TopicSummary {
    /// `/scan`.
    pub name: String,
    /// `sensor_msgs/msg/LaserScan`.
    pub type_name: String,
    /// `cdr`.
    pub encoding: String,
    /// Where its definition comes from.
    pub definition: DefinitionSource,
    /// Messages on it.
    pub count: u64,
    /// Log time of the first and the last (s).
    pub first: f64,
    /// Log time of the last (s).
    pub last: f64,
}

/// Where the definition used to decode a topic comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum DefinitionSource {
    /// The bag's own `ros2msg` schema.
    Bag,
    /// The bag has none (or one chronomap does not parse); chronomap's built-in definition of
    /// the type is used.
    BuiltIn,
    /// Neither: the topic cannot be decoded (the reason).
    Missing(String),
}

impl Bag {
    /// Opens a bag: a rosbag2 folder (with `metadata.yaml`, or just `.mcap` or `.db3` files),
    /// an `.mcap`, `.mcap.zstd` or `.db3` file.
    ///
    /// # Errors
    /// A [`BagError`]: the path does not exist or is not a regular file or folder, the
    /// metadata cannot be read, the storage is neither MCAP nor SQLite 3, the compression is
    /// unknown.
    pub fn open(path: impl AsRef<Path>) -> Result<Bag, BagError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let err = |problem: String| BagError::new(&name, None, problem);
        let meta = std::fs::metadata(path).map_err(|e| err(io_problem(&e)))?;
        if meta.is_dir() {
            let yaml = path.join("metadata.yaml");
            if yaml.exists() {
                let metadata = read_metadata(&name, &yaml)?;
                let info = &metadata;
                let storage = match info.storage_identifier.as_str() {
                    "mcap" => Storage::Mcap,
                    "sqlite3" => Storage::Sqlite,
                    other => {
                        return Err(err(format!(
                            "storage `{other}` is not supported (chronomap reads MCAP and SQLite 3 bags)"
                        )));
                    }
                };
                let compression = match (
                    info.compression_mode.to_ascii_lowercase().as_str(),
                    info.compression_format.as_str(),
                ) {
                    ("" | "none", _) => Compression::None,
                    ("file", "zstd") if storage == Storage::Sqlite => {
                        return Err(err(
                            "an SQLite bag compressed file by file is not supported: decompress it \
                             (`ros2 bag decompress`) or convert it to MCAP (`ros2 bag convert`)"
                                .into(),
                        ));
                    }
                    ("file", "zstd") => Compression::File,
                    ("message", "zstd") => Compression::Message,
                    (mode, format) => {
                        return Err(err(format!(
                            "compression `{format}` in mode `{mode}` is not supported (zstd is)"
                        )));
                    }
                };
                if info.relative_file_paths.is_empty() {
                    return Err(err("metadata.yaml lists no storage files".into()));
                }
                let files = info
                    .relative_file_paths
                    .iter()
                    .map(|f| path.join(f))
                    .collect();
                Ok(Bag {
                    name,
                    files,
                    storage,
                    compression,
                    metadata: Some(metadata),
                })
            } else {
                let mut files: Vec<PathBuf> = std::fs::read_dir(path)
                    .map_err(|e| err(io_problem(&e)))?
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.extension().is_some_and(|e| e == "mcap" || e == "db3"))
                    .collect();
                files.sort();
                let storage = match files.first() {
                    None => {
                        return Err(err(
                            "no metadata.yaml and no .mcap or .db3 file: not a rosbag2 bag".into(),
                        ));
                    }
                    Some(f) if f.extension().is_some_and(|e| e == "db3") => Storage::Sqlite,
                    Some(_) => Storage::Mcap,
                };
                if files.iter().any(|f| {
                    f.extension().is_some_and(|e| e == "db3") != (storage == Storage::Sqlite)
                }) {
                    return Err(err(
                        "both .mcap and .db3 files and no metadata.yaml: which is the bag?".into(),
                    ));
                }
                Ok(Bag {
                    name,
                    files,
                    storage,
                    compression: Compression::None,
                    metadata: None,
                })
            }
        } else if meta.is_file() {
            let file_name = path.file_name().unwrap_or_default().to_string_lossy();
            let storage = if file_name.ends_with(".db3") {
                Storage::Sqlite
            } else {
                Storage::Mcap
            };
            let compression = if file_name.ends_with(".zstd") {
                if file_name.ends_with(".db3.zstd") {
                    return Err(err(
                        "a compressed SQLite bag file is not supported: decompress it first".into(),
                    ));
                }
                Compression::File
            } else {
                Compression::None
            };
            Ok(Bag {
                name,
                files: vec![path.to_path_buf()],
                storage,
                compression,
                metadata: None,
            })
        } else {
            Err(err(
                "not a regular file or folder (a bag is a folder or an .mcap file)".into(),
            ))
        }
    }

    /// The bag as it was named.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// What `metadata.yaml` says, if the bag has one.
    pub fn metadata(&self) -> Option<&Metadata> {
        self.metadata.as_ref()
    }

    /// Total size of the storage files (bytes; compressed files as stored).
    pub fn size(&self) -> u64 {
        self.files
            .iter()
            .filter_map(|f| std::fs::metadata(f).ok())
            .map(|m| m.len())
            .sum()
    }

    /// Calls `each` with every message in storage order (file by file), reporting bytes read
    /// to `progress`. Stops at the first error, `each`'s or the bag's.
    ///
    /// # Errors
    /// A damaged or truncated file ([`BagError`] naming the file, the last good message and
    /// the byte offset), or the error `each` returned.
    pub fn for_each_message<E: From<BagError>>(
        &self,
        progress: &dyn Progress,
        mut each: impl FnMut(BagMessage) -> Result<(), E>,
    ) -> Result<(), E> {
        progress.stage(&format!("reading {}", self.name), self.size());
        let sequence = RefCell::new(Sequence::default());
        // The types metadata.yaml gives its topics (the first entry of a topic).
        let mut listed: HashMap<&str, (usize, &str)> = HashMap::new();
        if let Some(meta) = &self.metadata {
            for (i, t) in meta.topics_with_message_count.iter().enumerate() {
                listed
                    .entry(t.topic_metadata.name.as_str())
                    .or_insert((i, t.topic_metadata.type_name.as_str()));
            }
        }
        for file in &self.files {
            let file_name = file.display().to_string();
            // A bag that is one file is named once.
            let whole = file_name == self.name;
            let file_err = |place: Option<String>, problem: String| BagError {
                bag: self.name.clone(),
                place: match place {
                    Some(p) if whole => Some(p),
                    Some(p) => Some(format!("{file_name}: {p}")),
                    None if whole => None,
                    None => Some(file_name.clone()),
                },
                problem,
            };
            // The channels of this file already checked against metadata.yaml.
            let mut checked: HashSet<u16> = HashSet::new();
            let mut next = |channel: Arc<mcap::Channel<'static>>,
                            log_time,
                            publish_time,
                            data: Vec<u8>|
             -> Result<(), E> {
                if checked.insert(channel.id) {
                    self.check_listed_type(&listed, &channel)?;
                }
                let data = if self.compression == Compression::Message {
                    decompress_message(&data).map_err(|problem| {
                        file_err(
                            Some(format!("message {}", sequence.borrow().index)),
                            problem,
                        )
                    })?
                } else {
                    data
                };
                let message = sequence
                    .borrow_mut()
                    .next(channel, log_time, publish_time, data);
                each(message)
            };
            if self.storage == Storage::Sqlite {
                crate::sqlite::read_messages(file, progress, &file_err, &mut next)?;
                continue;
            }
            let opened = File::open(file).map_err(|e| file_err(None, io_problem(&e)))?;
            let meta = opened
                .metadata()
                .map_err(|e| file_err(None, io_problem(&e)))?;
            if !meta.is_file() {
                return Err(file_err(None, "not a regular file".into()).into());
            }
            let counter = Counting {
                inner: opened,
                read: 0,
                progress,
            };
            let (mut source, len): (Box<dyn Read + '_>, _) = match self.compression {
                Compression::File => (
                    Box::new(
                        zstd::stream::read::Decoder::new(counter)
                            .map_err(|e| file_err(None, format!("zstd: {e}")))?,
                    ),
                    None,
                ),
                _ => (
                    Box::new(BufReader::with_capacity(1 << 16, counter)),
                    Some(meta.len()),
                ),
            };
            let of = if len.is_some() {
                ""
            } else {
                " of the decompressed file"
            };
            crate::mcap_read::read_messages(&mut source, len, &mut |(
                channel,
                log_time,
                publish_time,
                data,
            )| {
                next(channel, log_time, publish_time, data)
            })
            .map_err(|e| match e {
                Ok(e) => e,
                Err((at, problem)) => file_err(
                    Some(format!(
                        "the record {}, read up to byte {at}{of}",
                        sequence.borrow().after()
                    )),
                    problem,
                )
                .into(),
            })?;
        }
        Ok(())
    }

    /// A storage file's channel against the type `metadata.yaml` gives its topic: the storage
    /// is the source of truth (its messages were written, and are decoded, with its type), so
    /// a `metadata.yaml` that says otherwise is an error, not a type to trust.
    fn check_listed_type(
        &self,
        listed: &HashMap<&str, (usize, &str)>,
        channel: &mcap::Channel<'_>,
    ) -> Result<(), BagError> {
        let stored = channel.schema.as_ref().map_or("", |s| s.name.as_str());
        let Some(&(i, said)) = listed.get(channel.topic.as_str()) else {
            return Ok(());
        };
        let canonical = |n: &str| canonical_type_name(n).unwrap_or_else(|| n.to_string());
        if stored.is_empty() || canonical(stored) == canonical(said) {
            return Ok(());
        }
        Err(BagError::new(
            &self.name,
            Some(format!(
                "metadata.yaml, topics_with_message_count[{i}].topic_metadata.type"
            )),
            format!(
                "topic {} is {} in metadata.yaml but {} in the storage files, whose type its \
                 messages were written with: the bag is inconsistent",
                channel.topic,
                excerpt(said),
                excerpt(stored)
            ),
        ))
    }

    /// The type (`pkg/msg/Type`) of `topic`: that of its first message in the storage files
    /// (the type its data were written with), else — for a topic without messages, or a channel
    /// without a schema — the type `metadata.yaml` gives it; `None` if the bag has no such
    /// topic. A `metadata.yaml` that contradicts the storage is an error (see
    /// [`Bag::for_each_message`]).
    ///
    /// # Errors
    /// A damaged or truncated file (before the topic's first message), or a `metadata.yaml`
    /// that gives the topic another type.
    pub fn topic_type(
        &self,
        topic: &str,
        progress: &dyn Progress,
    ) -> Result<Option<String>, BagError> {
        let listed = || {
            self.metadata.as_ref().and_then(|meta| {
                meta.topics_with_message_count
                    .iter()
                    .find(|t| t.topic_metadata.name == topic)
                    .map(|t| {
                        let name = &t.topic_metadata.type_name;
                        canonical_type_name(name).unwrap_or_else(|| name.clone())
                    })
            })
        };
        /// Ends the pass at the first message of the topic.
        enum Stop {
            Found(String),
            Failed(BagError),
        }
        impl From<BagError> for Stop {
            fn from(e: BagError) -> Self {
                Stop::Failed(e)
            }
        }
        let decoders = Decoders::new(self);
        match self.for_each_message(progress, |m: BagMessage| {
            if m.topic() == topic {
                Err(Stop::Found(decoders.type_name(&m)))
            } else {
                Ok(())
            }
        }) {
            Ok(()) => Ok(listed()),
            Err(Stop::Found(name)) => Ok(Some(name)),
            Err(Stop::Failed(e)) => Err(e),
        }
    }

    /// The number of messages on `topic` (a pass over the bag that decodes nothing).
    ///
    /// # Errors
    /// A damaged or truncated file.
    pub fn count_messages(&self, topic: &str, progress: &dyn Progress) -> Result<u64, BagError> {
        let mut count = 0;
        self.for_each_message(progress, |m: BagMessage| -> Result<(), BagError> {
            count += u64::from(m.topic() == topic);
            Ok(())
        })?;
        Ok(count)
    }

    /// Reads the whole bag once: its topics with types, counts and times, checking every
    /// record (CRCs included) and every topic's definition.
    ///
    /// # Errors
    /// A damaged or truncated file.
    pub fn summary(&self, progress: &dyn Progress) -> Result<BagSummary, BagError> {
        let mut topics: Vec<TopicSummary> = Vec::new();
        let mut by_name: BTreeMap<String, usize> = BTreeMap::new();
        let mut messages = 0u64;
        let mut bytes = 0u64;
        let mut decoders = Decoders::new(self);
        self.for_each_message(progress, |m: BagMessage| -> Result<(), BagError> {
            messages += 1;
            bytes += m.data.len() as u64;
            let t = nanos_seconds(m.log_time);
            if let Some(&i) = by_name.get(m.topic()) {
                let topic = &mut topics[i];
                topic.count += 1;
                topic.first = topic.first.min(t);
                topic.last = topic.last.max(t);
            } else {
                let definition = match decoders.schema(&m) {
                    Ok((_, source)) => source,
                    Err(e) => DefinitionSource::Missing(e.problem),
                };
                by_name.insert(m.topic().to_string(), topics.len());
                topics.push(TopicSummary {
                    name: m.topic().to_string(),
                    type_name: decoders.type_name(&m),
                    encoding: m.channel.message_encoding.clone(),
                    definition,
                    count: 1,
                    first: t,
                    last: t,
                });
            }
            Ok(())
        })?;
        let warnings = self.count_warnings(messages, &topics);
        Ok(BagSummary {
            messages,
            bytes,
            topics,
            warnings,
        })
    }

    /// The message counts of `metadata.yaml` that disagree with those read (nothing is
    /// allocated from them: they are only compared).
    fn count_warnings(&self, messages: u64, topics: &[TopicSummary]) -> Vec<String> {
        let Some(meta) = &self.metadata else {
            return Vec::new();
        };
        let mut warnings = Vec::new();
        if meta.message_count != messages {
            warnings.push(format!(
                "{}: metadata.yaml, message_count: {} messages, but the storage files hold {messages}",
                self.name, meta.message_count
            ));
        }
        let read: HashMap<&str, u64> = topics.iter().map(|t| (t.name.as_str(), t.count)).collect();
        for (i, listed) in meta.topics_with_message_count.iter().enumerate() {
            let name = &listed.topic_metadata.name;
            let found = read.get(name.as_str()).copied().unwrap_or(0);
            if listed.message_count != found {
                warnings.push(self.count_disagreement(i, listed, found));
            }
            if warnings.len() >= 10 {
                warnings.push("(more disagreements are not listed)".into());
                break;
            }
        }
        warnings
    }

    fn count_disagreement(&self, i: usize, listed: &TopicCount, found: u64) -> String {
        format!(
            "{}: metadata.yaml, topics_with_message_count[{i}].message_count: {} messages on \
             {}, but the storage files hold {found}",
            self.name,
            listed.message_count,
            excerpt(&listed.topic_metadata.name)
        )
    }

    /// Whether `metadata.yaml` gives `topic` another number of messages than the `found`
    /// ones read: the disagreement in words, for a warning.
    pub fn count_warning(&self, topic: &str, found: u64) -> Option<String> {
        let meta = self.metadata.as_ref()?;
        let (i, listed) = meta
            .topics_with_message_count
            .iter()
            .enumerate()
            .find(|(_, t)| t.topic_metadata.name == topic)?;
        (listed.message_count != found).then(|| self.count_disagreement(i, listed, found))
    }

    /// Calls `each` with every message on `topic`, decoded, in storage order.
    ///
    /// # Errors
    /// The topic is not in the bag (the error lists those that are), its messages cannot be
    /// decoded (naming the message and field), the bag is damaged, or `each` failed.
    pub fn for_each_decoded<E: From<BagError>>(
        &self,
        topic: &str,
        progress: &dyn Progress,
        mut each: impl FnMut(&BagMessage, &Value<'_>) -> Result<(), E>,
    ) -> Result<(), E> {
        let mut decoders = Decoders::new(self);
        let mut seen = 0u64;
        let mut others: BTreeMap<String, String> = BTreeMap::new();
        self.for_each_message(progress, |m: BagMessage| -> Result<(), E> {
            if m.topic() != topic {
                if others.len() < 1000 && !others.contains_key(m.topic()) {
                    others.insert(m.topic().to_string(), decoders.type_name(&m));
                }
                return Ok(());
            }
            seen += 1;
            let (schema, _) = decoders.schema(&m)?;
            let value = cdr::decode(&schema, &m.data).map_err(|e| {
                BagError::new(
                    &self.name,
                    Some(m.describe()),
                    format!("{} ({})", e, schema.root().name),
                )
            })?;
            each(&m, &value)
        })?;
        if seen == 0 {
            let list = if others.is_empty() {
                "the bag has no messages".to_string()
            } else {
                let names: Vec<String> = others
                    .iter()
                    .map(|(name, ty)| format!("{name} ({ty})"))
                    .collect();
                format!("the bag has {}", names.join(", "))
            };
            return Err(BagError::new(
                &self.name,
                None,
                format!("no message on topic {topic}: {list}"),
            )
            .into());
        }
        Ok(())
    }
}

/// A channel's schema and where it came from, or why there is none.
type Resolved = Result<(Arc<Schema>, DefinitionSource), BagError>;

/// The schemas of a bag's channels, parsed once each.
pub struct Decoders<'b> {
    bag: &'b Bag,
    by_channel: HashMap<(String, u16), Resolved>,
}

impl<'b> Decoders<'b> {
    /// No schema parsed yet.
    pub fn new(bag: &'b Bag) -> Self {
        Decoders {
            bag,
            by_channel: HashMap::new(),
        }
    }

    /// The type of a message: its schema's name, else the type `metadata.yaml` gives its topic.
    pub fn type_name(&self, m: &BagMessage) -> String {
        let from_schema = m.type_name();
        if !from_schema.is_empty() {
            return canonical_type_name(from_schema).unwrap_or_else(|| from_schema.to_string());
        }
        self.bag
            .metadata
            .as_ref()
            .and_then(|meta| {
                meta.topics_with_message_count
                    .iter()
                    .find(|t| t.topic_metadata.name == m.topic())
                    .map(|t| t.topic_metadata.type_name.clone())
            })
            .unwrap_or_else(|| "unknown type".into())
    }

    /// The schema that decodes a message, and where it came from.
    ///
    /// # Errors
    /// The message encoding is not CDR, the bag's definition is malformed, or there is no
    /// definition at all.
    pub fn schema(&mut self, m: &BagMessage) -> Resolved {
        let key = (m.topic().to_string(), m.channel.id);
        if let Some(found) = self.by_channel.get(&key) {
            return found.clone();
        }
        let found = self.resolve(m);
        self.by_channel.insert(key, found.clone());
        found
    }

    fn resolve(&self, m: &BagMessage) -> Resolved {
        let place = Some(format!("topic {}", m.topic()));
        let err = |problem: String| BagError::new(&self.bag.name, place.clone(), problem);
        if m.channel.message_encoding != "cdr" {
            return Err(err(format!(
                "message encoding `{}` is not supported (ROS 2 bags use `cdr`)",
                m.channel.message_encoding
            )));
        }
        let type_name = self.type_name(m);
        let mut why_not_bag = String::from("the bag has no definition of it");
        if let Some(schema) = &m.channel.schema {
            if schema.encoding == "ros2msg" && !schema.data.is_empty() {
                let text = std::str::from_utf8(&schema.data)
                    .map_err(|_| err("its message definition is not UTF-8 text".into()))?;
                let parsed = Schema::parse(&schema.name, text)
                    .map_err(|e| err(format!("its message definition is malformed: {e}")))?;
                return Ok((Arc::new(parsed), DefinitionSource::Bag));
            }
            if !schema.data.is_empty() {
                why_not_bag = format!(
                    "the bag defines it in the `{}` encoding, which chronomap does not parse",
                    schema.encoding
                );
            }
        }
        match builtin::schema(&type_name) {
            Some(schema) => Ok((Arc::new(schema), DefinitionSource::BuiltIn)),
            None => Err(err(format!(
                "cannot decode {type_name}: {why_not_bag}, and it is not one of the types chronomap knows"
            ))),
        }
    }
}

/// Counts the bytes read from a file and reports them as progress.
struct Counting<'p, R> {
    inner: R,
    read: u64,
    progress: &'p dyn Progress,
}

impl<R: Read> Read for Counting<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.read += n as u64;
        self.progress.advance(n as u64);
        Ok(n)
    }
}

/// Numbers the messages of a bag as they come, over all its files.
#[derive(Default)]
struct Sequence {
    index: u64,
    per_topic: HashMap<String, u64>,
    /// The last message's index, topic, index on its topic and log time (formatted only for an
    /// error).
    last: Option<(u64, String, u64, u64)>,
}

impl Sequence {
    /// The next message.
    fn next(
        &mut self,
        channel: Arc<mcap::Channel<'static>>,
        log_time: u64,
        publish_time: u64,
        data: Vec<u8>,
    ) -> BagMessage {
        let topic_index = match self.per_topic.get_mut(&channel.topic) {
            Some(count) => count,
            None => self.per_topic.entry(channel.topic.clone()).or_insert(0),
        };
        let message = BagMessage {
            index: self.index,
            topic_index: *topic_index,
            channel,
            log_time,
            publish_time: if publish_time == 0 {
                log_time
            } else {
                publish_time
            },
            data,
        };
        *topic_index += 1;
        self.index += 1;
        match &mut self.last {
            Some((index, topic, topic_index, time)) => {
                *index = message.index;
                if *topic != message.channel.topic {
                    topic.clone_from(&message.channel.topic);
                }
                *topic_index = message.topic_index;
                *time = log_time;
            }
            None => {
                self.last = Some((
                    message.index,
                    message.channel.topic.clone(),
                    message.topic_index,
                    log_time,
                ));
            }
        }
        message
    }

    /// "after message 12 (...)" or "before the first message".
    fn after(&self) -> String {
        match &self.last {
            Some((index, topic, topic_index, time)) => {
                format!("after {}", describe(*index, topic, *topic_index, *time))
            }
            None => "before the first message".into(),
        }
    }
}

/// "message 12 (/scan #5, log time 1137834226.1 s)".
fn describe(index: u64, topic: &str, topic_index: u64, log_time: u64) -> String {
    format!(
        "message {index} ({topic} #{topic_index}, log time {} s)",
        nanos_seconds(log_time)
    )
}

fn read_metadata(bag: &str, path: &Path) -> Result<Metadata, BagError> {
    let place = Some("metadata.yaml".to_string());
    let err = |problem: String| BagError::new(bag, place.clone(), problem);
    let file = File::open(path).map_err(|e| err(io_problem(&e)))?;
    let meta = file.metadata().map_err(|e| err(io_problem(&e)))?;
    if !meta.is_file() {
        return Err(err("not a regular file".into()));
    }
    if meta.len() > MAX_METADATA_BYTES {
        return Err(err(format!(
            "{} bytes is more than the {MAX_METADATA_BYTES} a metadata file may have",
            meta.len()
        )));
    }
    let mut text = Vec::new();
    file.take(MAX_METADATA_BYTES + 1)
        .read_to_end(&mut text)
        .map_err(|e| err(io_problem(&e)))?;
    let parsed: MetadataFile = serde_saphyr::from_slice(&text).map_err(|e| {
        let message = e.to_string();
        let first = message.lines().next().unwrap_or("").to_string();
        err(format!("not rosbag2 metadata: {first}"))
    })?;
    let info = parsed.rosbag2_bagfile_information;
    check_metadata(&info).map_err(err)?;
    Ok(info)
}

/// What `metadata.yaml` may not say: a version chronomap does not know, a storage file outside
/// the bag's folder, a name longer than [`MAX_NAME_BYTES`].
fn check_metadata(info: &Metadata) -> Result<(), String> {
    if !METADATA_VERSIONS.contains(&info.version) {
        return Err(format!(
            "version: {} is not a rosbag2 metadata version chronomap reads ({} to {}); \
             without metadata.yaml the storage files of the folder are read alone",
            match info.version {
                0 => "missing (or 0)".to_string(),
                v => v.to_string(),
            },
            METADATA_VERSIONS.start(),
            METADATA_VERSIONS.end()
        ));
    }
    for (i, file) in info.relative_file_paths.iter().enumerate() {
        let path = Path::new(file);
        let inside = !file.is_empty()
            && path.components().all(|c| {
                matches!(
                    c,
                    std::path::Component::Normal(_) | std::path::Component::CurDir
                )
            });
        if !inside || file.len() > MAX_NAME_BYTES {
            return Err(format!(
                "relative_file_paths[{i}]: {:?} is not a relative path inside the bag's folder \
                 (no `..`, no absolute path)",
                excerpt(file)
            ));
        }
    }
    for (i, topic) in info.topics_with_message_count.iter().enumerate() {
        let t = &topic.topic_metadata;
        for (field, value) in [
            ("name", &t.name),
            ("type", &t.type_name),
            ("serialization_format", &t.serialization_format),
        ] {
            if value.len() > MAX_NAME_BYTES {
                return Err(format!(
                    "topics_with_message_count[{i}].topic_metadata.{field}: {} bytes, more than \
                     the {MAX_NAME_BYTES} a name may have",
                    value.len()
                ));
            }
        }
    }
    Ok(())
}

/// At most 60 characters of `s`, for error messages.
fn excerpt(s: &str) -> String {
    let mut out: String = s.chars().take(60).collect();
    if out.len() < s.len() {
        out.push('…');
    }
    out
}

/// A message that rosbag2 compressed (one zstd frame), decompressed to at most
/// [`MAX_DECOMPRESSED_BYTES`].
fn decompress_message(data: &[u8]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    zstd::stream::read::Decoder::with_buffer(data)
        .and_then(|d| {
            d.take(MAX_DECOMPRESSED_BYTES as u64 + 1)
                .read_to_end(&mut out)
        })
        .map_err(|e| format!("zstd: {e} (the bag says messages are compressed)"))?;
    if out.len() > MAX_DECOMPRESSED_BYTES {
        return Err(format!(
            "the compressed message decompresses to more than the {MAX_DECOMPRESSED_BYTES} \
             bytes a message may have"
        ));
    }
    Ok(out)
}

fn io_problem(e: &io::Error) -> String {
    match e.kind() {
        io::ErrorKind::NotFound => "no such file or folder".into(),
        io::ErrorKind::PermissionDenied => "permission denied".into(),
        _ => e.to_string(),
    }
}
