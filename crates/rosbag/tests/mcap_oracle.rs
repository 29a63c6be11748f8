//! This crate reads MCAP with its own checking reader (`mcap_read`); the `mcap` crate, Foxglove's
//! reference implementation in Rust, is the oracle: every message of the real Málaga bag and
//! of files the `mcap` crate writes (chunked with zstd, lz4 or no compression, small and large
//! chunks, or no chunks at all) must come out of both readers identical and in the same order.

use chronomap_core::progress::NoProgress;
use chronomap_rosbag::{Bag, BagError};
use chronomap_testutil::{data_path, scratch};
use mcap::records::MessageHeader;
use mcap::{Compression, WriteOptions};

/// (topic, log time, publish time, bytes) of one message.
type Row = (String, u64, u64, Vec<u8>);

/// Every message as chronomap reads it.
fn ours(path: &std::path::Path) -> Vec<Row> {
    let bag = Bag::open(path).unwrap();
    let mut rows = Vec::new();
    bag.for_each_message(&NoProgress, |m| {
        rows.push((m.topic().to_owned(), m.log_time, m.publish_time, m.data));
        Ok::<(), BagError>(())
    })
    .unwrap();
    rows
}

/// Every message as the `mcap` crate reads it (in file order, as ours).
fn reference(bytes: &[u8]) -> Vec<Row> {
    mcap::MessageStream::new(bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            (
                m.channel.topic.clone(),
                m.log_time,
                m.publish_time,
                m.data.into_owned(),
            )
        })
        .collect()
}

#[test]
fn the_real_bag_reads_as_the_reference_reader_reads_it() {
    let dir = data_path("malaga_laser_2006/rosbag2/malaga_2006_bag");
    let file = dir.join("malaga_2006_bag.mcap");
    let expected = reference(&std::fs::read(&file).unwrap());
    assert_eq!(expected.len(), 449);
    assert_eq!(ours(&file), expected);
}

/// A small deterministic generator, so the files are the same on every run.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        self.0 >> 33
    }
}

/// A bag of `n` CDR-framed Bool and String messages on three topics, written by `mcap`.
fn written_by_the_reference(options: WriteOptions, n: u32, seed: u64) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    let mut writer = options.profile("ros2").create(&mut out).unwrap();
    let boolean = writer
        .add_schema("std_msgs/msg/Bool", "ros2msg", b"bool data")
        .unwrap();
    let string = writer
        .add_schema("std_msgs/msg/String", "ros2msg", b"string data")
        .unwrap();
    let channels = [
        writer
            .add_channel(boolean, "/door", "cdr", &Default::default())
            .unwrap(),
        writer
            .add_channel(boolean, "/light", "cdr", &Default::default())
            .unwrap(),
        writer
            .add_channel(string, "/log", "cdr", &Default::default())
            .unwrap(),
    ];
    let mut rng = Lcg(seed);
    for i in 0..n {
        let which = (rng.next() % 3) as usize;
        let data = if which == 2 {
            let len = (rng.next() % 3000) as usize;
            let mut d = vec![0, 1, 0, 0];
            d.extend_from_slice(&(len as u32 + 1).to_le_bytes());
            d.extend((0..len).map(|_| b'a' + (rng.next() % 26) as u8));
            d.push(0);
            d
        } else {
            vec![0, 1, 0, 0, (rng.next() % 2) as u8]
        };
        let header = MessageHeader {
            channel_id: channels[which],
            sequence: i,
            log_time: 1_000_000_000 + u64::from(i) * 1_000_000,
            publish_time: 1_000_000_000 + u64::from(i) * 1_000_000 - rng.next() % 1000,
        };
        writer.write_to_known_channel(&header, &data).unwrap();
    }
    writer.finish().unwrap();
    drop(writer);
    out.into_inner()
}

#[test]
fn files_the_reference_writes_read_identically_in_every_layout() {
    let dir = scratch!("mcap_oracle");
    let layouts: Vec<(&str, WriteOptions)> = vec![
        (
            "zstd, 4 KiB chunks",
            WriteOptions::new()
                .compression(Some(Compression::Zstd))
                .chunk_size(Some(4096)),
        ),
        (
            "lz4, 64 KiB chunks",
            WriteOptions::new()
                .compression(Some(Compression::Lz4))
                .chunk_size(Some(65_536)),
        ),
        (
            "uncompressed chunks",
            WriteOptions::new().compression(None).chunk_size(Some(1000)),
        ),
        (
            "zstd, one chunk",
            WriteOptions::new()
                .compression(Some(Compression::Zstd))
                .chunk_size(None),
        ),
        (
            "no chunks",
            WriteOptions::new().use_chunks(false).compression(None),
        ),
    ];
    for (seed, (name, options)) in layouts.into_iter().enumerate() {
        let bytes = written_by_the_reference(options, 2_000, seed as u64 + 1);
        let expected = reference(&bytes);
        assert_eq!(expected.len(), 2_000, "{name}");
        let file = dir.join(format!("layout_{seed}.mcap"));
        std::fs::write(&file, &bytes).unwrap();
        assert_eq!(ours(&file), expected, "{name}");
    }
}
