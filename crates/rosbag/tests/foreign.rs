//! Bags that do not say what their data are, or say it wrongly: MCAP files written here with
//! the `mcap` crate, each with one defect, must fail with an error naming the topic, the message
//! and the field — or, where a bag only lacks a definition chronomap knows, be read.

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use chronomap_core::progress::NoProgress;
use chronomap_rosbag::records::{RecordKind, message_time};
use chronomap_rosbag::{Bag, DefinitionSource, TimeSource};
use chronomap_testutil::scratch;
use mcap::records::MessageHeader;

/// One channel of a test bag: its schema and its messages `(log time ns, bytes)`.
struct Channel<'a> {
    topic: &'a str,
    schema: Option<(&'a str, &'a str, &'a str)>,
    encoding: &'a str,
    messages: Vec<(u64, Vec<u8>)>,
}

fn write_mcap(path: &Path, channels: &[Channel<'_>]) -> PathBuf {
    let mut writer =
        mcap::Writer::new(BufWriter::new(std::fs::File::create(path).unwrap())).unwrap();
    for ch in channels {
        let schema_id = match ch.schema {
            Some((name, encoding, text)) => {
                writer.add_schema(name, encoding, text.as_bytes()).unwrap()
            }
            None => 0,
        };
        let id = writer
            .add_channel(schema_id, ch.topic, ch.encoding, &BTreeMap::new())
            .unwrap();
        for (seq, (t, data)) in ch.messages.iter().enumerate() {
            let header = MessageHeader {
                channel_id: id,
                sequence: seq as u32,
                log_time: *t,
                publish_time: *t,
            };
            writer.write_to_known_channel(&header, data).unwrap();
        }
    }
    writer.finish().unwrap();
    path.to_path_buf()
}

/// std_msgs/Bool `value` in CDR (little-endian).
fn bool_cdr(value: u8) -> Vec<u8> {
    vec![0, 1, 0, 0, value, 0, 0, 0]
}

/// std_msgs/Float64 `value` in CDR.
fn f64_cdr(value: f64) -> Vec<u8> {
    let mut v = vec![0, 1, 0, 0];
    v.extend(value.to_le_bytes());
    v
}

const SECOND: u64 = 1_000_000_000;

/// A bag of one CDR topic with a `ros2msg` schema.
fn one_topic(
    path: &Path,
    topic: &str,
    ty: &str,
    definition: &str,
    messages: Vec<(u64, Vec<u8>)>,
) -> PathBuf {
    write_mcap(
        path,
        &[Channel {
            topic,
            schema: Some((ty, "ros2msg", definition)),
            encoding: "cdr",
            messages,
        }],
    )
}

#[test]
fn data_that_do_not_match_their_definition_name_the_message() {
    let dir = scratch!("rosbag_wrong_schema");
    // The schema says Bool, the data are Float64.
    let bag = one_topic(
        &dir.join("wrong.mcap"),
        "/door",
        "std_msgs/msg/Bool",
        "bool data\n",
        vec![(100 * SECOND, bool_cdr(1)), (160 * SECOND, f64_cdr(0.25))],
    );
    let err = Bag::open(&bag)
        .unwrap()
        .read_states("/door", TimeSource::Auto, &NoProgress)
        .unwrap_err();
    assert_eq!(
        err.place.as_deref(),
        Some("message 1 (/door #1, log time 160 s)")
    );
    assert_eq!(
        err.problem,
        "7 bytes are left after the last field: the data do not match the definition (std_msgs/msg/Bool)"
    );
    // A definition that does not even parse, and a state out of range.
    let bag = write_mcap(
        &dir.join("malformed.mcap"),
        &[
            Channel {
                topic: "/door",
                schema: Some(("std_msgs/msg/Bool", "ros2msg", "bool data\nfloat33[ x\n")),
                encoding: "cdr",
                messages: vec![(SECOND, bool_cdr(1))],
            },
            Channel {
                topic: "/level",
                schema: Some(("std_msgs/msg/Float64", "ros2msg", "float64 data\n")),
                encoding: "cdr",
                messages: vec![(SECOND, f64_cdr(0.5)), (2 * SECOND, f64_cdr(1.5))],
            },
        ],
    );
    let bag = Bag::open(&bag).unwrap();
    let err = bag
        .read_states("/door", TimeSource::Auto, &NoProgress)
        .unwrap_err()
        .to_string();
    assert!(
        err.ends_with("topic /door: its message definition is malformed: std_msgs/msg/Bool:2, field `x`: array type \"float33[\" has no closing `]`"),
        "{err}"
    );
    let err = bag
        .read_states("/level", TimeSource::Auto, &NoProgress)
        .unwrap_err()
        .to_string();
    assert!(err.ends_with("message 2 (/level #1, log time 2 s): field `data` is 1.5, outside [0, 1] (states are probabilities or 0/1)"), "{err}");
    // The listing says which topics cannot be decoded and why, and still lists them.
    let summary = bag.summary(&NoProgress).unwrap();
    assert!(
        matches!(&summary.topics[0].definition, DefinitionSource::Missing(why) if why.contains("malformed"))
    );
    assert_eq!(summary.topics[1].definition, DefinitionSource::Bag);
}

#[test]
fn unknown_encodings_and_missing_definitions() {
    let dir = scratch!("rosbag_encodings");
    let bag = write_mcap(
        &dir.join("mixed.mcap"),
        &[
            // JSON messages (Foxglove's own bags): not ROS 2 CDR.
            Channel {
                topic: "/json",
                schema: Some(("foo.Bar", "jsonschema", "{}")),
                encoding: "json",
                messages: vec![(SECOND, b"{\"data\": true}".to_vec())],
            },
            // No definition at all, or one in IDL: the built-in Bool is used.
            Channel {
                topic: "/bare",
                schema: Some(("std_msgs/msg/Bool", "ros2msg", "")),
                encoding: "cdr",
                messages: vec![(SECOND, bool_cdr(1)), (2 * SECOND, bool_cdr(0))],
            },
            Channel {
                topic: "/idl",
                schema: Some((
                    "std_msgs/msg/Bool",
                    "ros2idl",
                    "module std_msgs { module msg { struct Bool { boolean data; }; }; };",
                )),
                encoding: "cdr",
                messages: vec![(SECOND, bool_cdr(1))],
            },
            // A type nobody here knows, defined in IDL only.
            Channel {
                topic: "/custom",
                schema: Some(("acme_msgs/msg/Door", "ros2idl", "module acme_msgs { };")),
                encoding: "cdr",
                messages: vec![(SECOND, bool_cdr(1))],
            },
        ],
    );
    let bag = Bag::open(&bag).unwrap();
    let summary = bag.summary(&NoProgress).unwrap();
    let definitions: Vec<(&str, &DefinitionSource)> = summary
        .topics
        .iter()
        .map(|t| (t.name.as_str(), &t.definition))
        .collect();
    assert!(
        matches!(definitions[0], ("/json", DefinitionSource::Missing(why)) if why == "message encoding `json` is not supported (ROS 2 bags use `cdr`)")
    );
    assert_eq!(definitions[1], ("/bare", &DefinitionSource::BuiltIn));
    assert_eq!(definitions[2], ("/idl", &DefinitionSource::BuiltIn));
    assert!(
        matches!(definitions[3], ("/custom", DefinitionSource::Missing(why)) if why.contains("`ros2idl` encoding"))
    );
    assert_eq!(RecordKind::of(&summary.topics[3].type_name), None);
    let states = bag
        .read_states("/bare", TimeSource::Auto, &NoProgress)
        .unwrap();
    assert_eq!(
        (states.times, states.values),
        (vec![1.0, 2.0], vec![1.0, 0.0])
    );
    let err = bag
        .read_states("/json", TimeSource::Auto, &NoProgress)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("topic /json: message encoding `json` is not supported"),
        "{err}"
    );
}

#[test]
fn stamps_that_go_backwards_are_refused_unless_log_times_are_asked_for() {
    let dir = scratch!("rosbag_backwards");
    let stamped = "std_msgs/Header header\nbool data\n\
        ================================================================================\n\
        MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
        ================================================================================\n\
        MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";
    let message = |sec: i32, value: u8| {
        let mut v = vec![0, 1, 0, 0];
        v.extend(sec.to_le_bytes());
        v.extend(0u32.to_le_bytes());
        v.extend(1u32.to_le_bytes()); // frame_id "" (just the NUL)
        v.extend([0, value]);
        v
    };
    let bag = write_mcap(
        &dir.join("stamped.mcap"),
        &[Channel {
            topic: "/door",
            schema: Some(("door_msgs/msg/StampedBool", "ros2msg", stamped)),
            encoding: "cdr",
            messages: vec![
                (10 * SECOND, message(100, 1)),
                (11 * SECOND, message(90, 0)),
            ],
        }],
    );
    let bag = Bag::open(&bag).unwrap();
    // Not a state type by name: chronomap learns states from std_msgs only.
    let err = bag
        .read_states("/door", TimeSource::Auto, &NoProgress)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("its messages are door_msgs/msg/StampedBool, not state"),
        "{err}"
    );
    // Its stamps go backwards while the log times go forwards.
    let mut stamps = Vec::new();
    let mut logged = Vec::new();
    bag.for_each_decoded(
        "/door",
        &NoProgress,
        |m, v| -> Result<(), chronomap_rosbag::BagError> {
            stamps.push(message_time(m, v, TimeSource::Auto).unwrap());
            logged.push(message_time(m, v, TimeSource::Log).unwrap());
            Ok(())
        },
    )
    .unwrap();
    assert_eq!((stamps, logged), (vec![100.0, 90.0], vec![10.0, 11.0]));

    // States whose log times go backwards: refused, naming the message.
    let bag = one_topic(
        &dir.join("backwards.mcap"),
        "/level",
        "std_msgs/msg/Float64",
        "float64 data\n",
        vec![(5 * SECOND, f64_cdr(0.5)), (3 * SECOND, f64_cdr(0.25))],
    );
    let err = Bag::open(&bag)
        .unwrap()
        .read_states("/level", TimeSource::Auto, &NoProgress)
        .unwrap_err()
        .to_string();
    assert!(
        err.ends_with("message 1 (/level #1, log time 3 s): its time 3 s is earlier than the previous message's 5 s (times must not go backwards)"),
        "{err}"
    );
}
