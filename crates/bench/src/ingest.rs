//! Bag ingestion (`chronomap ingest`): how fast the messages of a rosbag2 MCAP bag become
//! chronomap's records, against a bare read of the same file in the same run.
//!
//! Four passes over each bag, each timed as the median of `repeats` runs:
//! 1. **bare read**: the file's bytes into a 64 KiB buffer, nothing else (the baseline: what
//!    the disk and page cache allow);
//! 2. **records**: the MCAP records, chunks decompressed, CRCs checked (`mcap`'s stream reader);
//! 3. **decoded**: also every message of the topic decoded from CDR by the bag's own definition;
//! 4. **ingested**: also the topic's records taken out (states, maps, people, scans, odometry),
//!    which is all `chronomap ingest` does before it fits a model or builds a grid.
//!
//! The default bags: the bundled greg door training data as a bag of 96,480 `std_msgs/msg/Bool`
//! messages in zstd chunks (as `ros2 bag record` writes them), written by [`write_door_bag`], and
//! the real laser bag of `data/malaga_laser_2006` (225 `LaserScan` messages of 1.5 KB).

use std::collections::BTreeMap;
use std::io::{BufWriter, Read};
use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_core::TimeSeries;
use chronomap_core::progress::NoProgress;
use chronomap_rosbag::{Bag, RecordKind, TimeSource, builtin};
use serde::Serialize;

use crate::{BenchError, median};

/// One bag and topic to time.
#[derive(Clone, Debug)]
pub struct IngestCase {
    /// The bag (folder or `.mcap`).
    pub bag: PathBuf,
    /// The topic to ingest.
    pub topic: String,
}

/// The timings of one bag.
#[derive(Clone, Debug, Serialize)]
pub struct IngestBench {
    /// The bag.
    pub bag: String,
    /// The topic.
    pub topic: String,
    /// Its message type.
    pub type_name: String,
    /// Messages in the bag (all topics).
    pub messages: u64,
    /// Messages on the topic.
    pub topic_messages: u64,
    /// Size of the storage files (bytes, as stored).
    pub file_bytes: u64,
    /// Timed runs per pass.
    pub repeats: usize,
    /// One row per pass, the bare read first.
    pub passes: Vec<IngestPass>,
}

/// One pass over a bag.
#[derive(Clone, Debug, Serialize)]
pub struct IngestPass {
    /// `bare read`, `records`, `decoded`, `ingested`.
    pub pass: &'static str,
    /// Median wall time (s).
    pub seconds: f64,
    /// Messages of the bag per second (the bare read: as if it had yielded them).
    pub messages_per_second: f64,
    /// File megabytes (10⁶ bytes, as stored) per second.
    pub megabytes_per_second: f64,
    /// This pass's time over the bare read's.
    pub ratio_to_bare_read: f64,
}

/// The bundled real laser bag, relative to the repository (as the other benchmarks' inputs).
pub const MALAGA_BAG: &str = "data/malaga_laser_2006/rosbag2/malaga_2006_bag/malaga_2006_bag.mcap";

/// The default cases: the greg door training data `door` written by [`write_door_bag`] as
/// `greg_door.mcap` in `scratch` (topic `/door/open`), and the scans of [`MALAGA_BAG`].
///
/// # Errors
/// The door bag cannot be written.
pub fn default_cases(door: &TimeSeries, scratch: &Path) -> Result<Vec<IngestCase>, BenchError> {
    let bag = scratch.join("greg_door.mcap");
    write_door_bag(door, &bag, "/door/open")?;
    Ok(vec![
        IngestCase {
            bag,
            topic: "/door/open".into(),
        },
        IngestCase {
            bag: MALAGA_BAG.into(),
            topic: "/scan".into(),
        },
    ])
}

/// Times the four passes over each case.
///
/// # Errors
/// A bag that cannot be read, or a topic it does not have or chronomap does not ingest.
pub fn run(cases: &[IngestCase], repeats: usize) -> Result<Vec<IngestBench>, BenchError> {
    cases
        .iter()
        .map(|case| run_one(case, repeats.max(1)))
        .collect()
}

fn time_median(
    repeats: usize,
    mut f: impl FnMut() -> Result<(), BenchError>,
) -> Result<f64, BenchError> {
    let mut times = Vec::with_capacity(repeats);
    for _ in 0..repeats {
        let started = Instant::now();
        f()?;
        times.push(started.elapsed().as_secs_f64());
    }
    Ok(median(&times))
}

fn run_one(case: &IngestCase, repeats: usize) -> Result<IngestBench, BenchError> {
    let bag = Bag::open(&case.bag)?;
    let files = storage_files(&bag, &case.bag)?;
    let summary = bag.summary(&NoProgress)?;
    let topic = summary
        .topics
        .iter()
        .find(|t| t.name == case.topic)
        .ok_or_else(|| BenchError::Topic {
            bag: bag.name().to_string(),
            problem: format!("no topic {}", case.topic),
        })?;
    let kind = RecordKind::of(&topic.type_name).ok_or_else(|| BenchError::Topic {
        bag: bag.name().to_string(),
        problem: format!(
            "chronomap does not ingest {} ({})",
            case.topic, topic.type_name
        ),
    })?;
    let file_bytes = bag.size();

    let mut buffer = vec![0u8; 1 << 16];
    let bare = time_median(repeats, || {
        for file in &files {
            let read = |source| BenchError::Read {
                path: file.clone(),
                source,
            };
            let mut f = std::fs::File::open(file).map_err(read)?;
            while f.read(&mut buffer).map_err(read)? > 0 {}
        }
        Ok(())
    })?;
    let records = time_median(repeats, || {
        let mut n = 0u64;
        bag.for_each_message(&NoProgress, |m| -> Result<(), chronomap_rosbag::BagError> {
            n += m.data.len() as u64;
            Ok(())
        })?;
        std::hint::black_box(n);
        Ok(())
    })?;
    let decoded = time_median(repeats, || {
        let mut n = 0u64;
        bag.for_each_decoded(
            &case.topic,
            &NoProgress,
            |_, v| -> Result<(), chronomap_rosbag::BagError> {
                n += u64::from(v.get("header").is_some());
                Ok(())
            },
        )?;
        std::hint::black_box(n);
        Ok(())
    })?;
    let time = TimeSource::Auto;
    let ingested = time_median(repeats, || {
        let n = match kind {
            RecordKind::State => bag.read_states(&case.topic, time, &NoProgress)?.times.len(),
            RecordKind::Map => {
                let mut cells = 0;
                bag.for_each_map(&case.topic, time, &NoProgress, |m| {
                    cells += m.data.len();
                    Ok(())
                })?;
                cells
            }
            RecordKind::People => bag.read_detections(&case.topic, time, &NoProgress)?.len(),
            RecordKind::Scan => bag.read_scans(&case.topic, time, &NoProgress)?.len(),
            RecordKind::Odometry => bag.read_odometry(&case.topic, time, &NoProgress)?.len(),
        };
        std::hint::black_box(n);
        Ok(())
    })?;
    let pass = |pass, seconds: f64| IngestPass {
        pass,
        seconds,
        messages_per_second: summary.messages as f64 / seconds,
        megabytes_per_second: file_bytes as f64 / 1e6 / seconds,
        ratio_to_bare_read: seconds / bare,
    };
    Ok(IngestBench {
        bag: bag.name().to_string(),
        topic: case.topic.clone(),
        type_name: topic.type_name.clone(),
        messages: summary.messages,
        topic_messages: topic.count,
        file_bytes,
        repeats,
        passes: vec![
            pass("bare read", bare),
            pass("records", records),
            pass("decoded", decoded),
            pass("ingested", ingested),
        ],
    })
}

/// The storage files of a bag: the `.mcap` file itself, or those its folder lists.
fn storage_files(bag: &Bag, path: &Path) -> Result<Vec<PathBuf>, BenchError> {
    if path.is_file() {
        return Ok(vec![path.to_path_buf()]);
    }
    match bag.metadata() {
        Some(meta) => Ok(meta
            .relative_file_paths
            .iter()
            .map(|f| path.join(f))
            .collect()),
        None => Err(BenchError::Topic {
            bag: path.display().to_string(),
            problem: "a folder without metadata.yaml: give its .mcap file".into(),
        }),
    }
}

/// Writes a series (the greg door training data) as a rosbag2-style MCAP file of
/// `std_msgs/msg/Bool` messages on `topic`, logged at their times, in zstd chunks with the
/// `ros2` profile and the message definition as the schema, as `ros2 bag record` writes it.
///
/// # Errors
/// The file cannot be written.
pub fn write_door_bag(series: &TimeSeries, output: &Path, topic: &str) -> Result<u64, BenchError> {
    let io = |e: mcap::McapError| BenchError::Write {
        path: output.to_path_buf(),
        source: std::io::Error::other(e),
    };
    let file = std::fs::File::create(output).map_err(|source| BenchError::Write {
        path: output.to_path_buf(),
        source,
    })?;
    let mut writer = mcap::WriteOptions::new()
        .profile("ros2")
        .compression(Some(mcap::Compression::Zstd))
        .create(BufWriter::new(file))
        .map_err(io)?;
    let definition = builtin::schema_text("std_msgs/msg/Bool").unwrap_or_default();
    let schema = writer
        .add_schema("std_msgs/msg/Bool", "ros2msg", definition.as_bytes())
        .map_err(io)?;
    let channel = writer
        .add_channel(schema, topic, "cdr", &BTreeMap::new())
        .map_err(io)?;
    for (i, (&t, &v)) in series.times.iter().zip(&series.values).enumerate() {
        let ns = (t * 1e9).round() as u64;
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: i as u32,
            log_time: ns,
            publish_time: ns,
        };
        writer
            .write_to_known_channel(&header, &[0, 1, 0, 0, u8::from(v > 0.5), 0, 0, 0])
            .map_err(io)?;
    }
    writer.finish().map_err(io)?;
    Ok(series.times.len() as u64)
}
