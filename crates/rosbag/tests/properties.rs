//! Property tests of the bag readers (proptest, seeded so that a failure reproduces): arbitrary
//! bytes and seeded mutations of real bags — the bundled MCAP bag of `data/malaga_laser_2006`,
//! an MCAP file with zstd and lz4 chunks and no CRCs (so that mutations reach the records
//! inside), one without chunks, and an SQLite bag — are an `Ok` or an `Err`, never a panic, and
//! the memory the reader holds stays within a bound set by the size of the file, not by what
//! it declares. Message definitions and CDR get arbitrary text and bytes too.
//!
//! The number of cases is small enough for CI (seconds); set `PROPTEST_CASES` for a deeper
//! run, e.g. `PROPTEST_CASES=100000 cargo test --release -p chronomap-rosbag --test properties`.

mod support;

use std::path::Path;
use std::sync::OnceLock;

use chronomap_core::progress::NoProgress;
use chronomap_rosbag::cdr::{MAX_VALUES, VALUES_PER_BYTE, Value, decode};
use chronomap_rosbag::msgdef::Schema;
use chronomap_rosbag::{Bag, BagError, TimeSource};
use chronomap_testutil::{data_path, mutate, proptest_config, scratch};
use proptest::prelude::*;
use support::*;

#[global_allocator]
static ALLOCATOR: Counting = Counting;

const LASER: &str = "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\n\
    float32 angle_increment\nfloat32 time_increment\nfloat32 scan_time\nfloat32 range_min\n\
    float32 range_max\nfloat32[] ranges\nfloat32[] intensities\n\
    ================================================================================\n\
    MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
    ================================================================================\n\
    MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";

/// An MCAP file written by the `mcap` crate: `chunks` (`None`: no chunks) compressed so, no
/// CRCs, a door and a float level.
fn written(compression: Option<mcap::Compression>, chunks: bool) -> Vec<u8> {
    let mut bytes = Vec::new();
    {
        let mut writer = mcap::WriteOptions::new()
            .compression(compression)
            .use_chunks(chunks)
            .chunk_size(Some(256))
            .calculate_chunk_crcs(false)
            .calculate_data_section_crc(false)
            .calculate_summary_section_crc(false)
            .create(std::io::Cursor::new(&mut bytes))
            .unwrap();
        let door = writer
            .add_schema("std_msgs/msg/Bool", "ros2msg", b"bool data\n")
            .unwrap();
        let level = writer
            .add_schema("std_msgs/msg/Float64", "ros2msg", b"float64 data\n")
            .unwrap();
        let door = writer
            .add_channel(door, "/door", "cdr", &Default::default())
            .unwrap();
        let level = writer
            .add_channel(level, "/level", "cdr", &Default::default())
            .unwrap();
        for i in 0..40u32 {
            let t = T0 + u64::from(i) * 60 * SECOND;
            let (channel, data) = if i % 3 == 0 {
                let mut d = vec![0, 1, 0, 0];
                d.extend((f64::from(i) / 40.0).to_le_bytes());
                (level, d)
            } else {
                (door, bool_cdr((i % 2) as u8))
            };
            let header = mcap::records::MessageHeader {
                channel_id: channel,
                sequence: i,
                log_time: t,
                publish_time: t,
            };
            writer.write_to_known_channel(&header, &data).unwrap();
        }
        writer.finish().unwrap();
    }
    bytes
}

/// An SQLite bag of the same door (rosbag2's Humble schema).
fn sqlite_bag() -> Vec<u8> {
    let dir = scratch!("rosbag_properties_sqlite");
    let path = dir.join("door.db3");
    let conn = rusqlite::Connection::open(&path).unwrap();
    conn.execute_batch(
        "CREATE TABLE topics (id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, \
         serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
         CREATE TABLE messages (id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, \
         timestamp INTEGER NOT NULL, data BLOB NOT NULL);
         INSERT INTO topics VALUES (1, '/door', 'std_msgs/msg/Bool', 'cdr', '');",
    )
    .unwrap();
    for i in 0..40i64 {
        conn.execute(
            "INSERT INTO messages VALUES (?1, 1, ?2, ?3)",
            rusqlite::params![
                i + 1,
                T0 as i64 + i * 60_000_000_000,
                bool_cdr((i % 2) as u8)
            ],
        )
        .unwrap();
    }
    drop(conn);
    std::fs::read(&path).unwrap()
}

/// The bags to mutate, with their file names: `(name, bytes)`.
fn seeds() -> &'static [(&'static str, Vec<u8>)] {
    static SEEDS: OnceLock<Vec<(&'static str, Vec<u8>)>> = OnceLock::new();
    SEEDS.get_or_init(|| {
        vec![
            (
                "malaga.mcap",
                std::fs::read(data_path(
                    "malaga_laser_2006/rosbag2/malaga_2006_bag/malaga_2006_bag.mcap",
                ))
                .unwrap(),
            ),
            ("zstd.mcap", written(Some(mcap::Compression::Zstd), true)),
            ("lz4.mcap", written(Some(mcap::Compression::Lz4), true)),
            ("plain.mcap", written(None, false)),
            ("door.db3", sqlite_bag()),
        ]
    })
}

/// Everything a command does with a bag: list it, read every topic's records.
fn read_all(path: &Path) -> Result<(), BagError> {
    let bag = Bag::open(path)?;
    let summary = bag.summary(&NoProgress)?;
    for topic in summary.topics.iter().take(4) {
        let _ = bag.read_states(&topic.name, TimeSource::Log, &NoProgress);
        let _ = bag.read_scans(&topic.name, TimeSource::Auto, &NoProgress);
        let _ = bag.topic_type(&topic.name, &NoProgress);
    }
    Ok(())
}

/// Reads the bytes as the bag `name` (in this thread's scratch file); the most memory held.
fn read_bytes(name: &str, bytes: &[u8]) -> usize {
    let dir = std::env::temp_dir().join(format!(
        "chronomap-rosbag-properties-{}-{:?}",
        std::process::id(),
        std::thread::current().id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    let (result, peak) = peak_bytes(|| read_all(&path));
    if let Err(e) = result {
        // An error names the bag.
        assert!(
            e.to_string().starts_with(&path.display().to_string()),
            "{e}"
        );
    }
    peak
}

/// The memory a reader may hold for a file of `len` bytes: a few times the file (its largest
/// record, a decompressed chunk of it, one message, decoded values) and a fixed allowance for
/// buffers and SQLite's page cache — never anything from a declared size.
fn bound(len: usize) -> usize {
    16 * MIB + 16 * len
}

proptest! {
    #![proptest_config(proptest_config(256, 20_261_205))]

    #[test]
    fn arbitrary_bytes_never_panic_a_bag_reader(
        bytes in proptest::collection::vec(any::<u8>(), 0..2048),
        mcap_start in any::<bool>(),
    ) {
        // Half of the cases start like an MCAP file, so that records are parsed at all.
        let bytes = if mcap_start { [MAGIC, &bytes[..]].concat() } else { bytes };
        for name in ["x.mcap", "x.db3", "x.mcap.zstd"] {
            let peak = read_bytes(name, &bytes);
            prop_assert!(peak < bound(bytes.len()), "{name}: {peak} bytes held");
        }
    }

    #[test]
    fn mutated_bags_never_panic_a_reader(
        seed in 0usize..5,
        edits in proptest::collection::vec((any::<usize>(), any::<u8>(), any::<u8>()), 1..6),
    ) {
        let (name, bytes) = &seeds()[seed];
        let bytes = mutate(bytes.clone(), &edits);
        let peak = read_bytes(name, &bytes);
        prop_assert!(peak < bound(bytes.len()), "{name}: {peak} bytes held");
    }

    #[test]
    fn arbitrary_definitions_never_panic_the_parser(text in "[a-zA-Z0-9_/\\[\\]<=# \n]{0,400}") {
        let _ = Schema::parse("a/msg/B", &text);
        let _ = Schema::parse("a/msg/B", &format!("{LASER}{text}"));
    }

    #[test]
    fn arbitrary_bytes_never_panic_the_cdr_decoder(
        bytes in proptest::collection::vec(any::<u8>(), 0..1024),
    ) {
        static SCHEMAS: OnceLock<Vec<Schema>> = OnceLock::new();
        let schemas = SCHEMAS.get_or_init(|| {
            vec![
                Schema::parse("sensor_msgs/msg/LaserScan", LASER).unwrap(),
                Schema::parse("a/msg/Nested", "string[] names\nInner[<=3] inner\n\
                    ================================================================================\n\
                    MSG: a/Inner\nfloat64[2] xy\nstring<=4 tag\nbool flag\n").unwrap(),
            ]
        });
        for schema in schemas {
            let (result, peak) = peak_bytes(|| decode(schema, &bytes).map(|v| format!("{v:?}").len()));
            drop(result);
            // Decoded values and their Debug text: a small multiple of the bytes.
            prop_assert!(peak < 64 * 1024 + 512 * bytes.len(), "{peak} bytes held");
        }
    }

    #[test]
    fn arbitrary_bytes_of_deeply_nested_messages_stay_within_the_budget(
        bytes in proptest::collection::vec(any::<u8>(), 0..4096),
    ) {
        static SCHEMA: OnceLock<Schema> = OnceLock::new();
        let schema = SCHEMA.get_or_init(|| nested_definition(60));
        // Mostly ones (bools that decode), so that the sequence goes on long enough to matter.
        let mut message = vec![0, 1, 0, 0];
        message.extend((bytes.len() as u32).to_le_bytes());
        message.extend(bytes.iter().map(|&b| u8::from(b < 250)));
        let (result, peak) = peak_bytes(|| decode(schema, &message).map(|_| ()));
        drop(result);
        prop_assert!(peak < 1024 + HELD_PER_BYTE * message.len(), "{peak} bytes held");
    }
}

/// A definition whose root holds a sequence of messages nested `levels` deep around one
/// `bool`: each element is one byte on the wire and `levels` messages in memory.
fn nested_definition(levels: usize) -> Schema {
    let sep = "================================================================================";
    let mut text = String::from("N1[] items\n");
    for i in 1..levels {
        text.push_str(&format!("{sep}\nMSG: a/N{i}\nN{} x\n", i + 1));
    }
    text.push_str(&format!("{sep}\nMSG: a/N{levels}\nbool b\n"));
    Schema::parse("a/msg/Deep", &text).unwrap()
}

/// The most a decoded message may hold (values, their vectors and the allocator's rounding),
/// as a multiple of its bytes: [`VALUES_PER_BYTE`] values of 40 bytes a byte, and the vector
/// of each message value.
const HELD_PER_BYTE: usize = 4 * VALUES_PER_BYTE * std::mem::size_of::<Value<'static>>();

#[test]
fn nested_one_byte_messages_stay_within_a_small_multiple_of_the_message() {
    // 60 levels (the parser allows 64) around each of 64 Ki one-byte elements: before values
    // were counted this decoded, holding 128 MB (1,950 bytes a byte of the message); now it is
    // refused holding about 4 MB.
    let schema = nested_definition(60);
    let n = 1 << 16;
    let mut bytes = vec![0, 1, 0, 0];
    bytes.extend((n as u32).to_le_bytes());
    bytes.extend(std::iter::repeat_n(1u8, n));
    let (result, peak) = peak_bytes(|| decode(&schema, &bytes).map(|_| ()));
    let err = result.unwrap_err();
    assert!(
        err.problem.contains(&format!(
            "more values than its {} bytes allow ({VALUES_PER_BYTE} a byte, at most {MAX_VALUES})",
            bytes.len()
        )),
        "{err}"
    );
    assert!(
        peak < HELD_PER_BYTE * bytes.len(),
        "{peak} bytes held for a message of {}",
        bytes.len()
    );
    // One level (a sequence of messages of one bool) is 2 values a byte: the budget holds it.
    let schema = nested_definition(1);
    let (result, peak) = peak_bytes(|| {
        decode(&schema, &bytes).map(|v| v.get("items").map(|a| a.as_array().map(<[_]>::len)))
    });
    assert_eq!(result.unwrap(), Some(Some(n)));
    assert!(peak < HELD_PER_BYTE * bytes.len(), "{peak}");
}

#[test]
fn the_seeds_are_valid_bags() {
    for (name, bytes) in seeds() {
        let dir = scratch!("rosbag_properties_seeds");
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let bag = Bag::open(&path).unwrap();
        let summary = bag.summary(&NoProgress).unwrap();
        let expected = if *name == "malaga.mcap" { 449 } else { 40 };
        assert_eq!(summary.messages, expected, "{name}");
        if *name != "malaga.mcap" {
            let states = bag
                .read_states("/door", TimeSource::Log, &NoProgress)
                .unwrap();
            let expected = if *name == "door.db3" { 40 } else { 26 };
            assert_eq!(states.values.len(), expected, "{name}");
        }
    }
}
