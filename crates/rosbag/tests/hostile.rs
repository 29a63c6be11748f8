//! Bags written to break the reader: sizes that the file does not hold, decompression bombs,
//! damaged chunks under stale CRCs, schemas built to be slow, names of 70,000 characters and
//! `metadata.yaml` files that point outside their bag or contradict it. Each is a clear error
//! naming the file, the record and the byte — with the memory the reader held measured, never
//! from what the file declares.

mod support;

use std::io::{Read as _, Write};
use std::path::{Path, PathBuf};

use chronomap_core::progress::NoProgress;
use chronomap_rosbag::bag::{MAX_DECOMPRESSED_BYTES, MAX_NAME_BYTES};
use chronomap_rosbag::msgdef::{MAX_FIELDS, Schema};
use chronomap_rosbag::{Bag, TimeSource};
use chronomap_testutil::scratch;
use support::*;

#[global_allocator]
static ALLOCATOR: Counting = Counting;

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// The error of listing the bag at `path`, and the most memory the listing held.
fn list_error(path: &Path) -> (String, usize) {
    let (result, peak) = peak_bytes(|| Bag::open(path).and_then(|b| b.summary(&NoProgress)));
    (result.unwrap_err().to_string(), peak)
}

/// `n` zero bytes compressed by zstd as one stream (a decompression bomb: 1 GiB is 33 KB).
fn zstd_zeros(prefix: &[u8], n: u64) -> Vec<u8> {
    let mut encoder = zstd::stream::write::Encoder::new(Vec::new(), 3).unwrap();
    encoder.write_all(prefix).unwrap();
    std::io::copy(&mut std::io::repeat(0).take(n), &mut encoder).unwrap();
    encoder.finish().unwrap()
}

const BOOL: &str = "bool data\n";

#[test]
fn a_record_longer_than_the_rest_of_the_file_is_refused_before_it_is_read() {
    let dir = scratch!("rosbag_hostile_long_record");
    // A message record that declares 1 GiB, in a file of a few hundred bytes.
    let mut bytes = [
        MAGIC.to_vec(),
        header(),
        schema(1, "std_msgs/msg/Bool", BOOL),
        channel(1, 1, "/door"),
    ]
    .concat();
    let at = bytes.len();
    bytes.push(0x05);
    bytes.extend((1u64 << 30).to_le_bytes());
    bytes.extend([0u8; 100]);
    let path = write(&dir, "huge_message.mcap", &bytes);
    let (err, peak) = list_error(&path);
    // Magic 8, header 9 + 8 + 19, schema 9 + 2 + 21 + 11 + 14, channel 9 + 2 + 2 + 9 + 7 + 4.
    assert_eq!(at, 134);
    assert_eq!(
        err,
        format!(
            "{}: the record before the first message, read up to byte 134: the message record \
             at byte 134 declares 1073741824 bytes, but only 100 remain in the file: it is \
             truncated or damaged",
            path.display()
        )
    );
    assert!(peak < MIB, "{peak} bytes held");
}

#[test]
fn a_zstd_bomb_in_a_chunk_is_refused_from_its_declared_size() {
    let dir = scratch!("rosbag_hostile_bomb");
    // One message of 1 GiB of zeros: 33 KB compressed, declared as it is (not a lie).
    let n = (1u64 << 30) - 100;
    let mut head = vec![0x05];
    head.extend((22 + n).to_le_bytes());
    head.extend(1u16.to_le_bytes());
    head.extend(0u32.to_le_bytes());
    head.extend(T0.to_le_bytes());
    head.extend(T0.to_le_bytes());
    let compressed = zstd_zeros(&head, n);
    assert!(compressed.len() < 64 * 1024, "{}", compressed.len());
    let declared = head.len() as u64 + n;
    let body = [
        schema(1, "std_msgs/msg/Bool", BOOL),
        channel(1, 1, "/door"),
        chunk(declared, 0, "zstd", &compressed),
    ]
    .concat();
    let path = write(&dir, "bomb.mcap", &mcap(&body));
    let (err, peak) = list_error(&path);
    assert_eq!(declared, 1_073_741_755);
    assert!(
        err.ends_with(&format!(
            "read up to byte 134: the chunk record at byte 134: the chunk declares 1073741755 \
             bytes uncompressed, more than the {MAX_DECOMPRESSED_BYTES} a compressed chunk may \
             have"
        )),
        "{err}"
    );
    assert!(peak < 2 * compressed.len() + MIB, "{peak} bytes held");
}

#[test]
fn a_chunk_that_decompresses_to_more_than_it_declares_stops_one_byte_past() {
    let dir = scratch!("rosbag_hostile_lying_chunk");
    // 64 MiB of zeros under a declared size of 1,000 bytes.
    let compressed = zstd_zeros(&[], 64 << 20);
    let body = [
        schema(1, "std_msgs/msg/Bool", BOOL),
        chunk(1000, 0, "zstd", &compressed),
    ]
    .concat();
    let path = write(&dir, "lying.mcap", &mcap(&body));
    let (err, peak) = list_error(&path);
    assert!(
        err.ends_with(
            "the chunk record at byte 101: the chunk declares 1000 bytes uncompressed, but \
             decompresses to more"
        ),
        "{err}"
    );
    assert!(peak < 2 * compressed.len() + MIB, "{peak} bytes held");
}

#[test]
fn a_chunk_whose_crc_does_not_match_its_records_is_refused() {
    let dir = scratch!("rosbag_hostile_crc");
    let good = door_records(false);
    let flipped = door_records(true);
    let stale = crc32fast::hash(&good);
    let computed = crc32fast::hash(&flipped);
    let schema = schema(1, "std_msgs/msg/Bool", BOOL);

    // The intact bag: a door open half of the time.
    let path = write(
        &dir,
        "good.mcap",
        &mcap(&[schema.clone(), plain_chunk(&good)].concat()),
    );
    let states = Bag::open(&path)
        .unwrap()
        .read_states("/door", TimeSource::Log, &NoProgress)
        .unwrap();
    assert_eq!(states.values.len(), 200);
    assert_eq!(states.values.iter().sum::<f64>(), 100.0);

    // Every state flipped to open under the intact bag's CRC: refused, not a door always open.
    for (name, chunk) in [
        (
            "stale.mcap",
            chunk(flipped.len() as u64, stale, "", &flipped),
        ),
        (
            "stale_zstd.mcap",
            chunk(
                flipped.len() as u64,
                stale,
                "zstd",
                &zstd::encode_all(&flipped[..], 3).unwrap(),
            ),
        ),
    ] {
        let path = write(&dir, name, &mcap(&[schema.clone(), chunk].concat()));
        let err = Bag::open(&path)
            .unwrap()
            .read_states("/door", TimeSource::Log, &NoProgress)
            .unwrap_err()
            .to_string();
        assert_eq!(
            err,
            format!(
                "{}: the record before the first message, read up to byte 101: the chunk record \
                 at byte 101: the CRC of the chunk's records is {computed:08x}, but the chunk \
                 says {stale:08x}: the chunk is damaged",
                path.display()
            )
        );
    }
}

#[test]
fn data_and_summary_section_crcs_are_checked() {
    let dir = scratch!("rosbag_hostile_section_crc");
    let mut bytes = Vec::new();
    {
        let mut writer = mcap::WriteOptions::new()
            .library("chronomap tests")
            .create(std::io::Cursor::new(&mut bytes))
            .unwrap();
        let schema = writer
            .add_schema("std_msgs/msg/Bool", "ros2msg", BOOL.as_bytes())
            .unwrap();
        let channel = writer
            .add_channel(schema, "/door", "cdr", &Default::default())
            .unwrap();
        for i in 0..10u32 {
            let header = mcap::records::MessageHeader {
                channel_id: channel,
                sequence: i,
                log_time: T0 + u64::from(i) * SECOND,
                publish_time: T0 + u64::from(i) * SECOND,
            };
            writer
                .write_to_known_channel(&header, &bool_cdr((i % 2) as u8))
                .unwrap();
        }
        writer.finish().unwrap();
    }
    let intact = write(&dir, "intact.mcap", &bytes);
    assert_eq!(
        Bag::open(&intact)
            .unwrap()
            .summary(&NoProgress)
            .unwrap()
            .messages,
        10
    );

    // A letter of the library's name in the header: only the data section's CRC covers it.
    let library = bytes
        .windows(15)
        .position(|w| w == b"chronomap tests")
        .unwrap();
    let mut damaged = bytes.clone();
    damaged[library] = b'C';
    let path = write(&dir, "data.mcap", &damaged);
    let (err, _) = list_error(&path);
    assert!(err.contains("the CRC of the data section is "), "{err}");
    assert!(err.contains(": the file is damaged"), "{err}");

    // A byte of the summary (the first record after summary_start, in the footer).
    let footer = bytes.len() - 8 - 20;
    let summary_start = u64::from_le_bytes(bytes[footer..footer + 8].try_into().unwrap());
    assert!(summary_start > 0);
    let mut damaged = bytes.clone();
    damaged[summary_start as usize + 9] ^= 0x40;
    let path = write(&dir, "summary.mcap", &damaged);
    let (err, _) = list_error(&path);
    assert!(
        err.contains(&format!(
            "the footer record at byte {}: the CRC of the summary section is ",
            footer - 9
        )),
        "{err}"
    );
}

#[test]
fn message_definitions_count_fields_before_looking_for_duplicates() {
    // MAX_FIELDS + 1 fields, the last one a duplicate of the first: the limit speaks first
    // (so no more than MAX_FIELDS + 1 fields are ever compared), and duplicates are found in
    // linear time.
    let mut text: String = (0..MAX_FIELDS).map(|i| format!("int8 f{i}\n")).collect();
    text.push_str("int8 f0\n");
    let err = Schema::parse("a/msg/Wide", &text).unwrap_err();
    assert_eq!(
        err.to_string(),
        "a/msg/Wide: more than 100000 fields in all"
    );
    // Within the limit, a duplicate is named with its line.
    let err = Schema::parse("a/msg/B", "int8 x\nint8 y\nint8 x\n").unwrap_err();
    assert_eq!(
        err.to_string(),
        "a/msg/B:3, field `x`: the field is defined twice"
    );
    // 40,000 fields of distinct names parse.
    let text: String = (0..40_000).map(|i| format!("int8 f{i}\n")).collect();
    assert_eq!(
        Schema::parse("a/msg/Wide", &text)
            .unwrap()
            .root()
            .fields
            .len(),
        40_000
    );
}

#[test]
fn fixed_arrays_of_no_elements_are_refused() {
    // Elements that take no bytes: a sequence of 100,000 of them, each with 1,000 such
    // fields, would decode 10^8 values from 100 KB.
    let err = Schema::parse("a/msg/B", "Inner[] xs\n===\nMSG: a/Inner\nint8[0] z\n").unwrap_err();
    assert_eq!(
        err.to_string(),
        "a/msg/Inner:1, field `z`: array type \"int8[0]\" has no elements"
    );
    assert!(Schema::parse("a/msg/B", "int8[1] z\n").is_ok());
}

#[test]
fn names_longer_than_the_cap_are_refused() {
    let dir = scratch!("rosbag_hostile_names");
    let long = format!("/{}", "x".repeat(69_999));
    // MCAP: a channel with a 70,000-character topic, then 1,000 messages on it.
    let mut body = [schema(1, "std_msgs/msg/Bool", BOOL), channel(1, 1, &long)].concat();
    for i in 0..1000 {
        body.extend(message(1, i, T0 + u64::from(i) * SECOND, &bool_cdr(1)));
    }
    let path = write(&dir, "long.mcap", &mcap(&body));
    let (err, _) = list_error(&path);
    assert!(
        err.ends_with(&format!(
            "read up to byte 101: the channel record at byte 101: the topic name has 70000 bytes, \
             more than the {MAX_NAME_BYTES} a name may have"
        )),
        "{err}"
    );
    // A name of exactly the cap is read.
    let fits = format!("/{}", "x".repeat(MAX_NAME_BYTES - 1));
    let body = [
        schema(1, "std_msgs/msg/Bool", BOOL),
        channel(1, 1, &fits),
        message(1, 0, T0, &bool_cdr(1)),
    ]
    .concat();
    let path = write(&dir, "fits.mcap", &mcap(&body));
    let summary = Bag::open(&path).unwrap().summary(&NoProgress).unwrap();
    assert_eq!(summary.topics[0].name.len(), MAX_NAME_BYTES);

    // SQLite: the same name in the table `topics`.
    let db = dir.join("long.db3");
    let conn = rusqlite::Connection::open(&db).unwrap();
    conn.execute_batch(
        "CREATE TABLE topics (id INTEGER PRIMARY KEY, name TEXT, type TEXT, \
         serialization_format TEXT, offered_qos_profiles TEXT);
         CREATE TABLE messages (id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER, \
         data BLOB);",
    )
    .unwrap();
    conn.execute(
        "INSERT INTO topics VALUES (1, ?1, 'std_msgs/msg/Bool', 'cdr', '')",
        [&long],
    )
    .unwrap();
    conn.execute(
        "INSERT INTO messages VALUES (1, 1, ?1, ?2)",
        rusqlite::params![T0 as i64, bool_cdr(1)],
    )
    .unwrap();
    drop(conn);
    let (err, _) = list_error(&db);
    assert_eq!(
        err,
        format!(
            "{}: the table `topics`: the name of topic id 1 has 70000 bytes, more than the \
             {MAX_NAME_BYTES} it may have",
            db.display()
        )
    );
}

/// A bag folder: `metadata.yaml` with these lines under `rosbag2_bagfile_information`, and
/// `door.mcap` (200 states of a door) beside it.
fn bag_folder(dir: &Path, name: &str, metadata: &str) -> PathBuf {
    let bag = dir.join(name);
    std::fs::create_dir_all(&bag).unwrap();
    let door = mcap(
        &[
            schema(1, "std_msgs/msg/Bool", BOOL),
            plain_chunk(&door_records(false)),
        ]
        .concat(),
    );
    std::fs::write(bag.join("door.mcap"), &door).unwrap();
    std::fs::write(
        bag.join("metadata.yaml"),
        format!("rosbag2_bagfile_information:\n{metadata}"),
    )
    .unwrap();
    bag
}

fn metadata(version: u32, path: &str, count: u64, ty: &str) -> String {
    format!(
        "  version: {version}\n  storage_identifier: mcap\n  relative_file_paths: [{path}]\n  \
         message_count: {count}\n  topics_with_message_count:\n  - message_count: {count}\n    \
         topic_metadata: {{name: /door, type: {ty}, serialization_format: cdr}}\n"
    )
}

#[test]
fn metadata_paths_outside_the_bag_folder_are_refused() {
    let dir = scratch!("rosbag_hostile_paths");
    let ok = bag_folder(
        &dir,
        "ok",
        &metadata(9, "door.mcap", 200, "std_msgs/msg/Bool"),
    );
    assert_eq!(
        Bag::open(&ok)
            .unwrap()
            .summary(&NoProgress)
            .unwrap()
            .messages,
        200
    );
    // A real bag file outside the folder: not followed.
    let outside = dir.join("outside.mcap");
    std::fs::copy(ok.join("door.mcap"), &outside).unwrap();
    for (name, path) in [
        ("up", "../outside.mcap".to_string()),
        ("absolute", outside.display().to_string()),
        ("inner_up", "sub/../../outside.mcap".to_string()),
        ("empty", "''".to_string()),
    ] {
        let bag = bag_folder(&dir, name, &metadata(9, &path, 200, "std_msgs/msg/Bool"));
        let err = Bag::open(&bag).unwrap_err().to_string();
        // Error messages quote at most 60 characters of a path (the absolute one here is as
        // long as the checkout's location makes it).
        let mut shown: String = if path == "''" { "" } else { path.as_str() }
            .chars()
            .take(60)
            .collect();
        if shown.len() < path.len() && path != "''" {
            shown.push('…');
        }
        assert_eq!(
            err,
            format!(
                "{}: metadata.yaml: relative_file_paths[0]: {shown:?} is not a relative path \
                 inside the bag's folder (no `..`, no absolute path)",
                bag.display()
            )
        );
    }
}

#[test]
fn metadata_versions_outside_1_to_9_are_refused() {
    let dir = scratch!("rosbag_hostile_versions");
    for version in [1, 5, 9] {
        let bag = bag_folder(
            &dir,
            &format!("v{version}"),
            &metadata(version, "door.mcap", 200, "std_msgs/msg/Bool"),
        );
        assert!(Bag::open(&bag).is_ok());
    }
    for (version, shown) in [(99, "99"), (10, "10"), (0, "missing (or 0)")] {
        let bag = bag_folder(
            &dir,
            &format!("v{version}"),
            &metadata(version, "door.mcap", 200, "std_msgs/msg/Bool"),
        );
        assert_eq!(
            Bag::open(&bag).unwrap_err().to_string(),
            format!(
                "{}: metadata.yaml: version: {shown} is not a rosbag2 metadata version \
                 chronomap reads (1 to 9); without metadata.yaml the storage files of the \
                 folder are read alone",
                bag.display()
            )
        );
    }
}

#[test]
fn a_metadata_type_that_contradicts_the_storage_is_an_error_for_listing_and_ingest_alike() {
    let dir = scratch!("rosbag_hostile_types");
    let bag = bag_folder(
        &dir,
        "odometry",
        &metadata(9, "door.mcap", 200, "nav_msgs/msg/Odometry"),
    );
    let expected = format!(
        "{}: metadata.yaml, topics_with_message_count[0].topic_metadata.type: topic /door is \
         nav_msgs/msg/Odometry in metadata.yaml but std_msgs/msg/Bool in the storage files, \
         whose type its messages were written with: the bag is inconsistent",
        bag.display()
    );
    let bag = Bag::open(&bag).unwrap();
    assert_eq!(bag.summary(&NoProgress).unwrap_err().to_string(), expected);
    assert_eq!(
        bag.topic_type("/door", &NoProgress)
            .unwrap_err()
            .to_string(),
        expected
    );
    assert_eq!(
        bag.read_states("/door", TimeSource::Log, &NoProgress)
            .unwrap_err()
            .to_string(),
        expected
    );
    // `pkg/Type` and `pkg/msg/Type` are the same type.
    let same = bag_folder(
        &dir,
        "short",
        &metadata(9, "door.mcap", 200, "std_msgs/Bool"),
    );
    let same = Bag::open(&same).unwrap();
    assert_eq!(
        same.topic_type("/door", &NoProgress).unwrap().as_deref(),
        Some("std_msgs/msg/Bool")
    );
}

#[test]
fn message_counts_that_disagree_with_the_storage_are_reported() {
    let dir = scratch!("rosbag_hostile_counts");
    let bag = bag_folder(
        &dir,
        "count",
        &metadata(9, "door.mcap", 99_999_999, "std_msgs/msg/Bool"),
    );
    let name = bag.display().to_string();
    let bag = Bag::open(&bag).unwrap();
    let summary = bag.summary(&NoProgress).unwrap();
    assert_eq!(summary.messages, 200);
    assert_eq!(
        summary.warnings,
        [
            format!(
                "{name}: metadata.yaml, message_count: 99999999 messages, but the storage files \
                 hold 200"
            ),
            format!(
                "{name}: metadata.yaml, topics_with_message_count[0].message_count: 99999999 \
                 messages on /door, but the storage files hold 200"
            ),
        ]
    );
    assert_eq!(
        bag.count_warning("/door", 200),
        Some(summary.warnings[1].clone())
    );
    let right = bag_folder(
        &dir,
        "right",
        &metadata(9, "door.mcap", 200, "std_msgs/msg/Bool"),
    );
    let right = Bag::open(&right).unwrap();
    assert!(right.summary(&NoProgress).unwrap().warnings.is_empty());
    assert_eq!(right.count_warning("/door", 200), None);
}

#[test]
fn a_message_compressed_by_rosbag2_decompresses_to_at_most_the_cap() {
    let dir = scratch!("rosbag_hostile_message_bomb");
    // compression_mode: message, one message whose zstd frame holds 1 GiB of zeros.
    let bomb = zstd_zeros(&[], 1 << 30);
    let bag = dir.join("bomb");
    std::fs::create_dir_all(&bag).unwrap();
    let body = [
        schema(1, "std_msgs/msg/Bool", BOOL),
        channel(1, 1, "/door"),
        message(1, 0, T0, &bomb),
    ]
    .concat();
    std::fs::write(bag.join("door.mcap"), mcap(&body)).unwrap();
    std::fs::write(
        bag.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n  \
         relative_file_paths: [door.mcap]\n  compression_format: zstd\n  \
         compression_mode: MESSAGE\n",
    )
    .unwrap();
    let (err, peak) = list_error(&bag);
    assert!(
        err.ends_with(&format!(
            "door.mcap: message 0: the compressed message decompresses to more than the \
             {MAX_DECOMPRESSED_BYTES} bytes a message may have"
        )),
        "{err}"
    );
    // The output grows by doubling up to the cap and one byte.
    assert!(
        peak <= 2 * MAX_DECOMPRESSED_BYTES + 2 * MIB,
        "{peak} bytes held"
    );
}
