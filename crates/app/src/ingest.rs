//! People detected in a ROS 2 bag (`people_msgs`, `geometry_msgs/msg/PoseArray` and the like,
//! read by `chronomap-rosbag`) as the files the other jobs learn from: events `t x y`
//! ([Krajník 2019] §V-D) or tracks with identities, speed and heading ([Stüde 2024] §4.2.2).
//!
//! Beside them, what `chronomap ingest` makes of a bag: the list of its topics with what each
//! becomes ([`BagListing`]), a topic's kind ([`topic_kind`]), and people, scans and odometry
//! written as files ([`ingest_records`]); each report renders itself as text and as JSON.
//!
//! Files in, result structs out: the faces choose the topic and the format and print.

use std::collections::HashMap;
use std::path::Path;

use chronomap_activity::truth::TrackPoint;
use chronomap_core::TimeSeries;
use chronomap_core::progress::Progress;
use chronomap_hypertime::events::Event;
use chronomap_io::tracks::{TrackRow, write_tracks};
use chronomap_io::{DataError, write_data_file, write_events};
use chronomap_rosbag::records::{self, Detection, encode_poses, encode_scans};
use chronomap_rosbag::{Bag, BagError, BagSummary, DefinitionSource, RecordKind, TimeSource};
use serde_json::{Value, json};

use crate::model::Training;
use crate::report::{Table, time};

/// The people detections of a topic.
#[derive(Clone, Debug, PartialEq)]
pub struct People {
    /// Messages read.
    pub messages: usize,
    /// Every detection of every message, in message order.
    pub detections: Vec<Detection>,
}

/// Reads every detection of the people topic `topic` of `bag`, timed by `time`, reporting to
/// `progress`.
///
/// # Errors
/// [`BagError`] naming the bag and message: a topic of another kind, times going backwards, a
/// message that is not a detection.
pub fn read_people(
    bag: &Bag,
    topic: &str,
    time: TimeSource,
    progress: &dyn Progress,
) -> Result<People, BagError> {
    let mut detections = Vec::new();
    let mut messages = 0;
    bag.for_each_record(topic, RecordKind::People, time, progress, |_, t, v| {
        messages += 1;
        detections.extend(records::detections(v, t)?);
        Ok(())
    })?;
    Ok(People {
        messages,
        detections,
    })
}

/// The detections as events `t x y`.
pub fn events_of(detections: &[Detection]) -> Vec<Event> {
    detections
        .iter()
        .map(|d| Event {
            t: d.time,
            x: d.x,
            y: d.y,
        })
        .collect()
}

/// Detections without an identity or a velocity (poses only) cannot be tracks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("detection {index} has no identity or no velocity")]
pub struct NoIdentity {
    /// The first such detection, counted from 0.
    pub index: usize,
}

/// Track rows of people detections: ids from the names (a name that is a whole number is that
/// id, others are numbered from 1 in order of first appearance), speed and heading from the
/// velocity.
///
/// # Errors
/// [`NoIdentity`] for the first detection without a name or a velocity.
pub fn track_rows(detections: &[Detection]) -> Result<Vec<TrackRow>, NoIdentity> {
    let mut ids: HashMap<String, u64> = HashMap::new();
    let mut next = 1u64;
    detections
        .iter()
        .enumerate()
        .map(|(index, d)| {
            let (Some(name), Some([vx, vy])) = (&d.person, d.velocity) else {
                return Err(NoIdentity { index });
            };
            let person = match name.parse::<u64>() {
                Ok(id) => id,
                Err(_) => *ids.entry(name.clone()).or_insert_with(|| {
                    next += 1;
                    next - 1
                }),
            };
            Ok(TrackRow {
                point: TrackPoint {
                    t: d.time,
                    person,
                    x: d.x,
                    y: d.y,
                },
                speed: vx.hypot(vy),
                heading: vy.atan2(vx),
            })
        })
        .collect()
}

/// Why a topic of a bag cannot be ingested.
#[derive(Debug, thiserror::Error)]
pub enum IngestError {
    /// The bag cannot be read.
    #[error(transparent)]
    Bag(#[from] BagError),
    /// The bag has no such topic.
    #[error("{bag}: there is no topic {topic} (list the topics: chronomap ingest {bag})")]
    NoTopic {
        /// The bag.
        bag: String,
        /// The topic.
        topic: String,
    },
    /// The topic's type is none chronomap learns from.
    #[error(
        "{bag}: topic {topic} is {type_name}, which chronomap does not learn from (it reads {})",
        known_kinds()
    )]
    Unknown {
        /// The bag.
        bag: String,
        /// The topic.
        topic: String,
        /// Its message type.
        type_name: String,
    },
    /// Tracks asked of detections without identities.
    #[error(
        "--people tracks: {bag} {topic} has poses without identities \
         (geometry_msgs/msg/PoseArray); write events instead"
    )]
    NoIdentity {
        /// The bag.
        bag: String,
        /// The topic.
        topic: String,
    },
    /// The output cannot be written.
    #[error(transparent)]
    Data(#[from] DataError),
}

/// The kinds of records and their message types, `; `-separated.
fn known_kinds() -> String {
    [
        RecordKind::State,
        RecordKind::Map,
        RecordKind::People,
        RecordKind::Scan,
        RecordKind::Odometry,
    ]
    .iter()
    .map(|k| k.types())
    .collect::<Vec<_>>()
    .join("; ")
}

/// What `ingest --topic` makes of a topic of `kind`.
fn makes(kind: Option<RecordKind>) -> &'static str {
    match kind {
        Some(RecordKind::State) => "a model (--model SPEC)",
        Some(RecordKind::Map) => "a grid",
        Some(RecordKind::People) => "events or tracks",
        Some(RecordKind::Scan) => "scans",
        Some(RecordKind::Odometry) => "poses",
        None => "nothing (not a type chronomap learns from)",
    }
}

/// The name of a time source as the JSON reports say it.
pub fn time_name(time: TimeSource) -> &'static str {
    match time {
        TimeSource::Auto => "auto",
        TimeSource::Header => "header",
        TimeSource::Log => "log",
        TimeSource::Publish => "publish",
    }
}

/// The message type of `topic` and the kind of record it becomes.
///
/// # Errors
/// [`IngestError::NoTopic`], [`IngestError::Unknown`], or the bag's error.
pub fn topic_kind(
    bag: &Bag,
    topic: &str,
    progress: &dyn Progress,
) -> Result<(String, RecordKind), IngestError> {
    let type_name = bag
        .topic_type(topic, progress)?
        .ok_or_else(|| IngestError::NoTopic {
            bag: bag.name().to_string(),
            topic: topic.to_string(),
        })?;
    match RecordKind::of(&type_name) {
        Some(kind) => Ok((type_name, kind)),
        None => Err(IngestError::Unknown {
            bag: bag.name().to_string(),
            topic: topic.to_string(),
            type_name,
        }),
    }
}

/// Every topic of a bag (unknown ones too, with the reason they are not used).
#[derive(Clone, Debug)]
pub struct BagListing {
    /// The bag's name.
    pub bag: String,
    /// What it holds.
    pub summary: BagSummary,
}

impl BagListing {
    /// Reads the summary of `bag`.
    ///
    /// # Errors
    /// The bag's error.
    pub fn of(bag: &Bag, progress: &dyn Progress) -> Result<BagListing, BagError> {
        Ok(BagListing {
            bag: bag.name().to_string(),
            summary: bag.summary(progress)?,
        })
    }

    /// The listing as `chronomap ingest BAG --json` prints it.
    pub fn json(&self) -> Value {
        let summary = &self.summary;
        let topics: Vec<Value> = summary
            .topics
            .iter()
            .map(|t| {
                json!({
                    "topic": t.name,
                    "type": t.type_name,
                    "encoding": t.encoding,
                    "messages": t.count,
                    "first": t.first,
                    "last": t.last,
                    "kind": RecordKind::of(&t.type_name).map(RecordKind::name),
                    "definition": match &t.definition {
                        DefinitionSource::Bag => "bag".to_string(),
                        DefinitionSource::BuiltIn => "built-in".to_string(),
                        DefinitionSource::Missing(why) => format!("missing: {why}"),
                    },
                })
            })
            .collect();
        json!({
            "bag": self.bag,
            "messages": summary.messages,
            "bytes": summary.bytes,
            "topics": topics,
            "warnings": summary.warnings,
        })
    }

    /// The listing as `chronomap ingest BAG` prints it: a line and a table of the topics.
    pub fn text(&self) -> String {
        let summary = &self.summary;
        let topics = summary.topics.len();
        let mut table =
            Table::new(["topic", "type", "messages", "from", "to", "ingest makes"]).left(&[1, 5]);
        for t in &summary.topics {
            let makes = match &t.definition {
                DefinitionSource::Missing(why) => format!("nothing: {why}"),
                _ => makes(RecordKind::of(&t.type_name)).to_string(),
            };
            table.row([
                t.name.clone(),
                t.type_name.clone(),
                t.count.to_string(),
                time(t.first),
                time(t.last),
                makes,
            ]);
        }
        format!(
            "{}: {} messages on {topics} topic{}\n{}",
            self.bag,
            summary.messages,
            if topics == 1 { "" } else { "s" },
            table.render().trim_end()
        )
    }
}

/// How people detections are written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PeopleFiles {
    /// Events `t x y` ([Krajník 2019] §V-D).
    Events,
    /// Tracks `t,person,x,y,speed,heading` ([Stüde 2024] §4.2.2).
    Tracks,
}

/// A topic read from a bag and written as a file.
#[derive(Clone, Debug)]
pub struct Ingested {
    /// The bag.
    pub bag: String,
    /// The topic.
    pub topic: String,
    /// Its message type.
    pub type_name: String,
    /// Where times came from.
    pub time: TimeSource,
    /// Messages read.
    pub messages: usize,
    /// What was read, in words (`120 scans of 361 beams`).
    pub what: String,
    /// What was read, as JSON (`"read"`).
    pub details: Value,
    /// The file written.
    pub output: String,
    /// What the bag's metadata says against the messages read, if they differ.
    pub warning: Option<String>,
}

impl Ingested {
    /// The report as `chronomap ingest --json` prints it.
    pub fn json(&self) -> Value {
        json!({
            "bag": self.bag,
            "topic": self.topic,
            "type": self.type_name,
            "time": time_name(self.time),
            "messages": self.messages,
            "read": self.details,
            "output": self.output,
        })
    }

    /// The report as `chronomap ingest` prints it.
    pub fn text(&self) -> String {
        format!(
            "{}: {} ({}): {}\nwrote {}",
            self.bag, self.topic, self.type_name, self.what, self.output
        )
    }
}

/// Reads the people, scans or odometry of `topic` (of `kind`, message type `type_name`) and
/// writes them to `output`: people as `people` files, scans and poses as text.
///
/// # Errors
/// [`IngestError`]: the bag, tracks without identities, or the output.
#[allow(clippy::too_many_arguments)]
pub fn ingest_records(
    bag: &Bag,
    topic: &str,
    type_name: &str,
    kind: RecordKind,
    time: TimeSource,
    people: PeopleFiles,
    output: &Path,
    progress: &dyn Progress,
) -> Result<Ingested, IngestError> {
    let (messages, what, details) = match kind {
        RecordKind::People => {
            let People {
                messages,
                detections,
            } = read_people(bag, topic, time, progress)?;
            let written = match people {
                PeopleFiles::Events => {
                    write_events(output, &events_of(&detections))?;
                    "events"
                }
                PeopleFiles::Tracks => {
                    let rows = track_rows(&detections).map_err(|_| IngestError::NoIdentity {
                        bag: bag.name().to_string(),
                        topic: topic.to_string(),
                    })?;
                    write_tracks(output, &rows)?;
                    "tracks"
                }
            };
            let first_frame = detections.first().map(|d| d.frame_id.clone());
            (
                messages,
                format!(
                    "{} detections in {messages} messages as {written}",
                    detections.len()
                ),
                json!({ "detections": detections.len(), "format": written, "frame_id": first_frame }),
            )
        }
        RecordKind::Scan => {
            let scans = bag.read_scans(topic, time, progress)?;
            write_data_file(output, encode_scans(&scans).as_bytes())?;
            let beams = scans.first().map_or(0, |s| s.ranges.len());
            (
                scans.len(),
                format!("{} scans of {beams} beams", scans.len()),
                json!({ "scans": scans.len(), "beams": beams }),
            )
        }
        _ => {
            let poses = bag.read_odometry(topic, time, progress)?;
            write_data_file(output, encode_poses(&poses).as_bytes())?;
            (
                poses.len(),
                format!("{} poses", poses.len()),
                json!({ "poses": poses.len() }),
            )
        }
    };
    Ok(Ingested {
        bag: bag.name().to_string(),
        topic: topic.to_string(),
        type_name: type_name.to_string(),
        time,
        messages,
        what,
        details,
        output: output.display().to_string(),
        warning: bag.count_warning(topic, messages as u64),
    })
}

/// The states of `topic` as observations to fit a model on (named `BAG TOPIC`), and what the
/// bag's metadata says against their count, if it differs.
///
/// # Errors
/// The bag's error.
pub fn state_training(
    bag: &Bag,
    topic: &str,
    time: TimeSource,
    progress: &dyn Progress,
) -> Result<(Training, Option<String>), BagError> {
    let states = bag.read_states(topic, time, progress)?;
    let count = states.times.len();
    let training = Training {
        json: json!({
            "bag": bag.name(),
            "topic": topic,
            "time": time_name(time),
            "observations": count,
        }),
        name: format!("{} {topic}", bag.name()),
        series: TimeSeries {
            times: states.times,
            values: states.values,
        },
    };
    Ok((training, bag.count_warning(topic, count as u64)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seen(time: f64, person: Option<&str>, velocity: Option<[f64; 2]>) -> Detection {
        Detection {
            time,
            x: 1.0,
            y: -2.0,
            person: person.map(str::to_string),
            velocity,
            frame_id: "map".to_string(),
        }
    }

    #[test]
    fn names_become_ids_and_velocities_speed_and_heading() {
        let detections = [
            seen(1.0, Some("7"), Some([3.0, 4.0])),
            seen(2.0, Some("alice"), Some([0.0, -1.0])),
            seen(3.0, Some("bob"), Some([-2.0, 0.0])),
            seen(4.0, Some("alice"), Some([0.0, 0.0])),
        ];
        let rows = track_rows(&detections).unwrap();
        let ids: Vec<u64> = rows.iter().map(|r| r.point.person).collect();
        assert_eq!(ids, [7, 1, 2, 1]);
        assert_eq!(rows[0].speed, 5.0);
        assert_eq!(rows[0].heading, 4f64.atan2(3.0));
        assert_eq!(rows[1].heading, -std::f64::consts::FRAC_PI_2);
        assert_eq!(rows[2].heading, std::f64::consts::PI);
        assert_eq!(
            (rows[3].point.t, rows[3].point.x, rows[3].point.y),
            (4.0, 1.0, -2.0)
        );
        assert_eq!(
            events_of(&detections[..1]),
            [Event {
                t: 1.0,
                x: 1.0,
                y: -2.0
            }]
        );
    }

    #[test]
    fn the_malaga_bag_lists_its_topics_and_writes_its_scans() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../data/malaga_laser_2006/rosbag2/malaga_2006_bag");
        let bag = Bag::open(&path).unwrap();
        let progress = chronomap_core::progress::NoProgress;
        let listing = BagListing::of(&bag, &progress).unwrap();
        let json = listing.json();
        assert_eq!(json["messages"], 449);
        assert_eq!(json["topics"][0]["topic"], "/scan");
        assert_eq!(json["topics"][0]["kind"], "scan");
        assert_eq!(json["topics"][1]["messages"], 224);
        let text = listing.text();
        assert!(
            text.starts_with(&format!("{}: 449 messages on 2 topics\ntopic", bag.name())),
            "{text}"
        );
        assert!(text.contains("  scans\n"), "{text}");

        let (type_name, kind) = topic_kind(&bag, "/scan", &progress).unwrap();
        assert_eq!(
            (type_name.as_str(), kind),
            ("sensor_msgs/msg/LaserScan", RecordKind::Scan)
        );
        let missing = topic_kind(&bag, "/door", &progress)
            .unwrap_err()
            .to_string();
        assert_eq!(
            missing,
            format!(
                "{0}: there is no topic /door (list the topics: chronomap ingest {0})",
                bag.name()
            )
        );

        let dir = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-app-ingest-{}", std::process::id())),
        );
        let output = dir.join("scans.txt");
        let ingested = ingest_records(
            &bag,
            "/scan",
            &type_name,
            kind,
            TimeSource::Auto,
            PeopleFiles::Events,
            &output,
            &progress,
        )
        .unwrap();
        assert_eq!(ingested.messages, 225);
        assert_eq!(ingested.warning, None);
        assert_eq!(
            ingested.text(),
            format!(
                "{}: /scan (sensor_msgs/msg/LaserScan): 225 scans of 361 beams\nwrote {}",
                bag.name(),
                output.display()
            )
        );
        assert_eq!(ingested.json()["read"]["beams"], 361);
        assert_eq!(ingested.json()["time"], "auto");
        let written = std::fs::read_to_string(&output).unwrap();
        assert_eq!(written.lines().count(), 1 + 225);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn poses_without_identities_are_not_tracks() {
        let detections = [
            seen(1.0, Some("7"), Some([3.0, 4.0])),
            seen(2.0, None, None),
        ];
        assert_eq!(track_rows(&detections), Err(NoIdentity { index: 1 }));
    }
}
