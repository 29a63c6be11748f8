//! What the hostile-bag and property tests share: the allocator that measures the peak memory a
//! thread holds (chronomap-testutil's), and an MCAP writer of single records, so that a test can write exactly the
//! (wrong) bytes it needs — lengths, sizes and CRCs that the `mcap` crate's writer would never
//! produce.
#![allow(dead_code)] // each test file uses a part

pub use chronomap_testutil::memory::{Counting, peak_bytes};

pub const MIB: usize = 1 << 20;

pub const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// A `u32`-prefixed string.
pub fn string(s: &[u8]) -> Vec<u8> {
    let mut out = (s.len() as u32).to_le_bytes().to_vec();
    out.extend_from_slice(s);
    out
}

/// A record: opcode, `u64` length, body.
pub fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
    let mut out = vec![opcode];
    out.extend((body.len() as u64).to_le_bytes());
    out.extend_from_slice(body);
    out
}

pub fn header() -> Vec<u8> {
    record(
        0x01,
        &[string(b"ros2"), string(b"chronomap tests")].concat(),
    )
}

pub fn schema(id: u16, name: &str, text: &str) -> Vec<u8> {
    let body = [
        id.to_le_bytes().to_vec(),
        string(name.as_bytes()),
        string(b"ros2msg"),
        string(text.as_bytes()),
    ]
    .concat();
    record(0x03, &body)
}

pub fn channel(id: u16, schema_id: u16, topic: &str) -> Vec<u8> {
    let body = [
        id.to_le_bytes().to_vec(),
        schema_id.to_le_bytes().to_vec(),
        string(topic.as_bytes()),
        string(b"cdr"),
        0u32.to_le_bytes().to_vec(),
    ]
    .concat();
    record(0x04, &body)
}

pub fn message(channel: u16, sequence: u32, time: u64, data: &[u8]) -> Vec<u8> {
    let body = [
        channel.to_le_bytes().to_vec(),
        sequence.to_le_bytes().to_vec(),
        time.to_le_bytes().to_vec(),
        time.to_le_bytes().to_vec(),
        data.to_vec(),
    ]
    .concat();
    record(0x05, &body)
}

/// A chunk record: `declared` uncompressed size, `crc` of the records, `compressed` bytes.
pub fn chunk(declared: u64, crc: u32, compression: &str, compressed: &[u8]) -> Vec<u8> {
    let body = [
        0u64.to_le_bytes().to_vec(),
        0u64.to_le_bytes().to_vec(),
        declared.to_le_bytes().to_vec(),
        crc.to_le_bytes().to_vec(),
        string(compression.as_bytes()),
        (compressed.len() as u64).to_le_bytes().to_vec(),
        compressed.to_vec(),
    ]
    .concat();
    record(0x06, &body)
}

/// An uncompressed chunk of `records` with their right CRC.
pub fn plain_chunk(records: &[u8]) -> Vec<u8> {
    chunk(records.len() as u64, crc32fast::hash(records), "", records)
}

/// Data End (no CRC), Footer (no summary) and the closing magic.
pub fn tail() -> Vec<u8> {
    [
        record(0x0F, &0u32.to_le_bytes()),
        record(0x02, &[0u8; 20]),
        MAGIC.to_vec(),
    ]
    .concat()
}

/// A whole file: magic, header, `body`, tail.
pub fn mcap(body: &[u8]) -> Vec<u8> {
    [MAGIC.to_vec(), header(), body.to_vec(), tail()].concat()
}

pub const SECOND: u64 = 1_000_000_000;
pub const T0: u64 = 1_700_000_000 * SECOND;

/// std_msgs/Bool in CDR.
pub fn bool_cdr(value: u8) -> Vec<u8> {
    vec![0, 1, 0, 0, value, 0, 0, 0]
}

/// A door that opens every other half hour: 200 states, `flip` = all of them open.
pub fn door_records(all_open: bool) -> Vec<u8> {
    let mut records = channel(1, 1, "/door");
    for i in 0..200u32 {
        let value = if all_open { 1 } else { (i % 2) as u8 };
        records.extend(message(
            1,
            i,
            T0 + u64::from(i) * 1800 * SECOND,
            &bool_cdr(value),
        ));
    }
    records
}
