use std::time::{Duration, Instant};

use super::*;
use crate::msgs::{Header, MapMetaData, Point, Pose, Quaternion, Time};

/// A scratch folder for one test, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!(
            "chronomap-ros2-journal-{test}-{}",
            std::process::id()
        ));
        Scratch(chronomap_testutil::fresh_dir(dir))
    }

    fn journal(&self) -> PathBuf {
        self.0.join("journal")
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

fn state(time: f64, value: f64) -> Entry<'static> {
    Entry::State {
        name: "door".into(),
        time,
        value,
    }
}

/// A 100 x 80 map (8,000 cells: compressed in the journal).
fn map(stamp: i32) -> Entry<'static> {
    let data = (0..8000)
        .map(|i| match (i + stamp as usize) % 7 {
            0 => -1,
            1 | 2 => 100,
            k => (k * 10) as i8,
        })
        .collect();
    Entry::Map {
        name: "office".into(),
        message: Cow::Owned(OccupancyGrid {
            header: Header {
                stamp: Time {
                    sec: stamp,
                    nanosec: 7,
                },
                frame_id: "map".into(),
            },
            info: MapMetaData {
                map_load_time: Time::default(),
                resolution: 0.05,
                width: 100,
                height: 80,
                origin: Pose {
                    position: Point {
                        x: -1.5,
                        y: 2.0,
                        z: 0.0,
                    },
                    orientation: Quaternion::default(),
                },
            },
            data,
        }),
    }
}

fn people(stamp: i32) -> Entry<'static> {
    Entry::People {
        name: "lobby".into(),
        message: Cow::Owned(PoseArray {
            header: Header {
                stamp: Time {
                    sec: stamp,
                    nanosec: 0,
                },
                frame_id: "map".into(),
            },
            poses: vec![Pose {
                position: Point {
                    x: 1.25,
                    y: f64::from(stamp) / 10.0,
                    z: 0.0,
                },
                orientation: Quaternion::default(),
            }],
        }),
    }
}

/// A journal opened, what it found and what it replayed.
type Opened = (Journal, Recovered, Vec<(u64, Entry<'static>)>);

/// Opens the journal in `dir` at `head`, collecting what it replays.
fn open(dir: &Path, head: u64, settings: JournalSettings) -> Result<Opened, JournalError> {
    let mut seen = Vec::new();
    let (journal, recovered) = Journal::open(dir, head, settings, |seq, entry| {
        seen.push((seq, entry));
        Ok::<(), JournalError>(())
    })?;
    Ok((journal, recovered, seen))
}

fn settings() -> JournalSettings {
    JournalSettings::default()
}

fn segments(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    files
}

#[test]
fn what_was_synced_is_replayed_in_order_with_its_positions() {
    let scratch = Scratch::new("replay");
    let entries = vec![
        state(10.0, 1.0),
        map(20),
        people(30),
        Entry::BinClosed {
            name: "lobby".into(),
        },
        state(40.5, 0.25),
    ];
    let now = Instant::now();
    {
        let (mut journal, recovered, seen) = open(&scratch.journal(), 0, settings()).unwrap();
        assert_eq!((recovered, seen.len()), (Recovered::default(), 0));
        for (i, e) in entries.iter().enumerate() {
            assert_eq!(journal.append(e, now).unwrap(), i as u64);
        }
        journal.sync().unwrap();
    }
    let (journal, recovered, seen) = open(&scratch.journal(), 0, settings()).unwrap();
    assert_eq!(
        recovered,
        Recovered {
            records: 5,
            first: Some(0),
            segments: 1,
            torn_bytes: 0
        }
    );
    assert_eq!(
        seen,
        entries
            .into_iter()
            .enumerate()
            .map(|(i, e)| (i as u64, e))
            .collect::<Vec<_>>()
    );
    assert_eq!(journal.next_position(), 5);
    // The 8,000-cell map was compressed: the segment is smaller than the map.
    let size: u64 = segments(&scratch.journal())
        .iter()
        .map(|p| fs::metadata(p).unwrap().len())
        .sum();
    assert!(size < 4000, "{size} bytes");
}

#[test]
fn syncs_come_after_the_period_or_enough_records_and_only_synced_records_survive_a_crash() {
    let scratch = Scratch::new("sync");
    let settings = JournalSettings {
        sync_period: Duration::from_millis(500),
        sync_records: 3,
        ..JournalSettings::default()
    };
    let t0 = Instant::now();
    let (mut journal, _, _) = open(&scratch.journal(), 0, settings).unwrap();
    journal.append(&state(1.0, 0.0), t0).unwrap();
    assert!(
        !journal
            .sync_if_due(t0 + Duration::from_millis(499))
            .unwrap()
    );
    assert!(
        journal
            .sync_if_due(t0 + Duration::from_millis(500))
            .unwrap()
    );
    assert_eq!(journal.pending(), 0);
    for k in 0..3 {
        journal.append(&state(2.0 + f64::from(k), 1.0), t0).unwrap();
    }
    // Three records wait: due at once.
    assert!(journal.sync_if_due(t0).unwrap());
    journal.append(&state(9.0, 1.0), t0).unwrap();
    // A crash: the process ends without flushing its buffers.
    std::mem::forget(journal);
    let (journal, recovered, seen) = open(&scratch.journal(), 0, settings).unwrap();
    assert_eq!(recovered.records, 4);
    assert_eq!(seen.last().unwrap(), &(3, state(4.0, 1.0)));
    assert_eq!(journal.next_position(), 4);
}

#[test]
fn a_torn_last_record_is_cut_off_and_appending_goes_on_after_the_last_intact_one() {
    let scratch = Scratch::new("torn");
    let now = Instant::now();
    let (mut journal, _, _) = open(&scratch.journal(), 0, settings()).unwrap();
    for k in 0..3 {
        journal.append(&state(f64::from(k), 1.0), now).unwrap();
    }
    journal.sync().unwrap();
    drop(journal);
    let segment = segments(&scratch.journal()).pop().unwrap();
    let intact = fs::metadata(&segment).unwrap().len();
    // Half of a fourth record reached the disk.
    let mut record = Vec::new();
    let payload = postcard::to_allocvec(&state(3.0, 0.0)).unwrap();
    record.extend_from_slice(RECORD_MAGIC);
    record.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    record.extend_from_slice(&3u64.to_le_bytes());
    record.push(0);
    record.extend_from_slice(&checksum(3, 0, &payload).to_le_bytes());
    record.extend_from_slice(&payload);
    let mut file = OpenOptions::new().append(true).open(&segment).unwrap();
    file.write_all(&record[..record.len() - 5]).unwrap();
    drop(file);

    let (mut journal, recovered, seen) = open(&scratch.journal(), 0, settings()).unwrap();
    assert_eq!(
        (recovered.records, recovered.torn_bytes),
        (3, record.len() as u64 - 5)
    );
    assert_eq!(seen.len(), 3);
    assert_eq!(fs::metadata(&segment).unwrap().len(), intact, "cut off");
    assert_eq!(journal.append(&state(5.0, 0.5), now).unwrap(), 3);
    journal.sync().unwrap();
    drop(journal);
    let (_, recovered, seen) = open(&scratch.journal(), 0, settings()).unwrap();
    assert_eq!((recovered.records, recovered.torn_bytes), (4, 0));
    assert_eq!(seen[3], (3, state(5.0, 0.5)));
}

#[test]
fn a_damaged_record_with_intact_records_after_it_stops_the_start_naming_file_and_byte() {
    let scratch = Scratch::new("damaged");
    let now = Instant::now();
    let (mut journal, _, _) = open(&scratch.journal(), 0, settings()).unwrap();
    for k in 0..4 {
        journal.append(&state(f64::from(k), 1.0), now).unwrap();
    }
    journal.sync().unwrap();
    drop(journal);
    let segment = segments(&scratch.journal()).pop().unwrap();
    let mut bytes = fs::read(&segment).unwrap();
    let record = (bytes.len() - SEGMENT_MAGIC.len()) / 4;
    // The value of the second record (its last payload byte) flips.
    let at = SEGMENT_MAGIC.len() + 2 * record - 1;
    bytes[at] ^= 0x10;
    fs::write(&segment, &bytes).unwrap();
    let error = open(&scratch.journal(), 0, settings())
        .err()
        .unwrap()
        .to_string();
    let expected = format!(
        "{}: byte {}: checksum mismatch; an intact record (position 2) follows it; move the journal folder away",
        segment.display(),
        SEGMENT_MAGIC.len() + record
    );
    assert!(error.starts_with(&expected), "{error}");
    // Nothing was cut off or changed.
    assert_eq!(fs::read(&segment).unwrap(), bytes);
}

#[test]
fn a_flipped_bit_in_the_last_record_is_a_torn_write() {
    let scratch = Scratch::new("last-flip");
    let now = Instant::now();
    let (mut journal, _, _) = open(&scratch.journal(), 0, settings()).unwrap();
    for k in 0..2 {
        journal.append(&state(f64::from(k), 1.0), now).unwrap();
    }
    journal.sync().unwrap();
    drop(journal);
    let segment = segments(&scratch.journal()).pop().unwrap();
    let mut bytes = fs::read(&segment).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    fs::write(&segment, &bytes).unwrap();
    let (journal, recovered, _) = open(&scratch.journal(), 0, settings()).unwrap();
    assert_eq!(recovered.records, 1);
    assert_eq!(journal.next_position(), 1);
}

#[test]
fn a_declared_length_that_lies_is_refused_before_anything_is_allocated() {
    let scratch = Scratch::new("lying-length");
    let now = Instant::now();
    let (mut journal, _, _) = open(&scratch.journal(), 0, settings()).unwrap();
    journal.append(&state(1.0, 1.0), now).unwrap();
    journal.append(&state(2.0, 1.0), now).unwrap();
    journal.sync().unwrap();
    drop(journal);
    let segment = segments(&scratch.journal()).pop().unwrap();
    let mut bytes = fs::read(&segment).unwrap();
    let first = SEGMENT_MAGIC.len();
    // The first record claims 4 GiB - 1.
    bytes[first + 4..first + 8].copy_from_slice(&u32::MAX.to_le_bytes());
    fs::write(&segment, &bytes).unwrap();
    let error = open(&scratch.journal(), 0, settings())
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains(&format!(
            "byte {first}: a declared length of 4294967295 bytes"
        )) && error.contains("an intact record (position 1) follows it"),
        "{error}"
    );
}

#[test]
fn checkpoints_rotate_segments_and_forget_the_covered_ones() {
    let scratch = Scratch::new("rotate");
    let now = Instant::now();
    let (mut journal, _, _) = open(&scratch.journal(), 0, settings()).unwrap();
    for k in 0..3 {
        journal.append(&state(f64::from(k), 1.0), now).unwrap();
    }
    journal.rotate().unwrap();
    journal.append(&state(3.0, 1.0), now).unwrap();
    journal.rotate().unwrap();
    journal.append(&state(4.0, 1.0), now).unwrap();
    journal.sync().unwrap();
    assert_eq!(segments(&scratch.journal()).len(), 3);
    // A checkpoint at position 4 (an open bin from position 3 kept): the first segment goes.
    assert_eq!(journal.forget_before(3).unwrap(), 1);
    assert_eq!(journal.forget_before(3).unwrap(), 0);
    drop(journal);
    let names: Vec<String> = segments(&scratch.journal())
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        ["00000000000000000003.cmj", "00000000000000000004.cmj"]
    );
    let (journal, recovered, seen) = open(&scratch.journal(), 4, settings()).unwrap();
    assert_eq!((recovered.first, seen.len()), (Some(3), 2));
    assert_eq!(journal.next_position(), 5);
}

#[test]
fn missing_segments_stop_the_start() {
    let scratch = Scratch::new("missing");
    let now = Instant::now();
    let (mut journal, _, _) = open(&scratch.journal(), 0, settings()).unwrap();
    for k in 0..3 {
        journal.append(&state(f64::from(k), 1.0), now).unwrap();
        journal.rotate().unwrap();
    }
    drop(journal);
    let files = segments(&scratch.journal());
    fs::remove_file(&files[1]).unwrap();
    let error = open(&scratch.journal(), 0, settings())
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains("00000000000000000002.cmj: the segment starts at position 2, but position 1 comes next: segments are missing"),
        "{error}"
    );
    // A journal that ends before the checkpoint's position lost its newest segments.
    let other = Scratch::new("missing-tail");
    let (mut journal, _, _) = open(&other.journal(), 0, settings()).unwrap();
    journal.append(&state(1.0, 1.0), now).unwrap();
    journal.sync().unwrap();
    drop(journal);
    let error = open(&other.journal(), 7, settings())
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains("the journal ends at position 1, before the checkpoint's 7"),
        "{error}"
    );
    // An empty journal (moved away by hand) starts at the checkpoint's position.
    let empty = Scratch::new("missing-empty");
    let (journal, _, _) = open(&empty.journal(), 7, settings()).unwrap();
    assert_eq!(journal.next_position(), 7);
}

#[test]
fn foreign_files_and_foreign_segments_are_refused() {
    let scratch = Scratch::new("foreign");
    fs::create_dir_all(scratch.journal()).unwrap();
    fs::write(scratch.journal().join("notes.txt"), "hello").unwrap();
    let error = open(&scratch.journal(), 0, settings())
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains("notes.txt: byte 0: not a journal segment"),
        "{error}"
    );
    fs::remove_file(scratch.journal().join("notes.txt")).unwrap();
    let bad = scratch.journal().join("00000000000000000000.cmj");
    fs::write(&bad, "CMJRNL9\nxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx").unwrap();
    fs::write(
        scratch.journal().join("00000000000000000001.cmj"),
        SEGMENT_MAGIC,
    )
    .unwrap();
    let error = open(&scratch.journal(), 0, settings())
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains("00000000000000000000.cmj: byte 0: not a journal segment of a known version (starts with \"CMJRNL9\\n\")"),
        "{error}"
    );
}

#[test]
fn a_segment_created_without_its_header_is_reused() {
    let scratch = Scratch::new("empty-segment");
    fs::create_dir_all(scratch.journal()).unwrap();
    fs::write(scratch.journal().join("00000000000000000000.cmj"), b"CMJ").unwrap();
    let (mut journal, recovered, _) = open(&scratch.journal(), 0, settings()).unwrap();
    assert_eq!((recovered.records, recovered.torn_bytes), (0, 3));
    journal.append(&state(1.0, 1.0), Instant::now()).unwrap();
    journal.sync().unwrap();
    drop(journal);
    assert_eq!(segments(&scratch.journal()).len(), 1);
    let (_, recovered, _) = open(&scratch.journal(), 0, settings()).unwrap();
    assert_eq!(recovered.records, 1);
}

#[test]
fn a_compressed_record_that_inflates_beyond_the_limit_is_damage() {
    let scratch = Scratch::new("bomb");
    let settings = JournalSettings {
        max_payload: 10_000,
        ..JournalSettings::default()
    };
    let now = Instant::now();
    let (mut journal, _, _) = open(&scratch.journal(), 0, JournalSettings::default()).unwrap();
    // 8,000 cells and some headers: more than 4 KiB, compressed to a few hundred bytes.
    journal.append(&map(1), now).unwrap();
    journal.append(&state(1.0, 1.0), now).unwrap();
    journal.sync().unwrap();
    drop(journal);
    // Read back with a limit below the map's decoded size, the map is refused.
    let small = JournalSettings {
        max_payload: 5_000,
        ..settings
    };
    let error = open(&scratch.journal(), 0, small)
        .err()
        .unwrap()
        .to_string();
    assert!(
        error.contains("a compressed record inflating to more than 5000 bytes"),
        "{error}"
    );
    let (_, recovered, _) = open(&scratch.journal(), 0, settings).unwrap();
    assert_eq!(recovered.records, 2);
}

/// The scan before it was bounded: the whole rest of the segment in memory.
fn find_in_memory(bytes: &[u8], max_payload: usize) -> Option<u64> {
    let mut at = 0;
    while let Some(i) = bytes[at..]
        .windows(RECORD_MAGIC.len())
        .position(|w| w == RECORD_MAGIC)
    {
        if let Ok((seq, _, _)) = split_record(&bytes[at + i..], max_payload) {
            return Some(seq);
        }
        at += i + 1;
    }
    None
}

/// A record of position `seq` with `payload`, as `Journal::append` writes an uncompressed one.
fn raw_record(seq: u64, payload: &[u8]) -> Vec<u8> {
    let mut out = RECORD_MAGIC.to_vec();
    out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    out.extend_from_slice(&seq.to_le_bytes());
    out.push(0);
    out.extend_from_slice(&checksum(seq, 0, payload).to_le_bytes());
    out.extend_from_slice(payload);
    out
}

#[test]
fn the_windowed_scan_finds_the_record_the_whole_segment_scan_found() {
    let small = raw_record(7, b"door open");
    // A payload longer than the window: its checksum is read from the file.
    let large = raw_record(9, &vec![0x5a; SCAN_CHUNK + 1000]);
    // A fake header whose checksum fails, one with unknown flags, one with a length past the
    // end, and a bare magic: candidates that are not records.
    let mut bad_crc = raw_record(3, b"x");
    bad_crc[20] ^= 1;
    let mut bad_flags = raw_record(4, b"y");
    bad_flags[16] = 2;
    let past_end = raw_record(5, &[1; 64])[..40].to_vec();
    let mut cases: Vec<(Vec<u8>, Option<u64>)> = Vec::new();
    // The small record at every place around the first and second window boundaries, after
    // a fake magic that straddles the boundary.
    for gap in (SCAN_CHUNK - 30..SCAN_CHUNK + 30).chain(2 * SCAN_CHUNK - 25..2 * SCAN_CHUNK + 3) {
        let mut bytes = vec![0xee; gap];
        bytes[gap - 10..gap - 6].copy_from_slice(RECORD_MAGIC);
        bytes.extend_from_slice(&small);
        bytes.extend_from_slice(&large);
        cases.push((bytes, Some(7)));
    }
    for (junk, expected) in [
        (vec![bad_crc.clone(), large.clone()], Some(9)),
        (
            vec![bad_flags.clone(), bad_crc.clone(), small.clone()],
            Some(7),
        ),
        (vec![vec![0; SCAN_CHUNK - 5], large.clone()], Some(9)),
        // The large record cut short: the file ends inside its payload.
        (vec![large[..SCAN_CHUNK + 100].to_vec()], None),
        (vec![bad_crc, bad_flags, past_end.clone()], None),
        (vec![vec![0; 3 * SCAN_CHUNK], RECORD_MAGIC.to_vec()], None),
        (vec![past_end], None),
        (vec![], None),
    ] {
        cases.push((junk.concat(), expected));
    }
    for (k, (bytes, expected)) in cases.iter().enumerate() {
        assert_eq!(find_in_memory(bytes, 1 << 20), *expected, "case {k}");
        for from in [0, 1].into_iter().filter(|&f| f <= bytes.len()) {
            let mut file = io::Cursor::new([b"ab".as_slice(), bytes].concat());
            let found = scan_for_record(&mut file, 2 + from as u64, 1 << 20).unwrap();
            let reference = find_in_memory(&bytes[from..], 1 << 20);
            assert_eq!(found, reference, "case {k} from {from}");
        }
    }
    // A declared length above the caller's limit is no record, in the window or not.
    let mut file = io::Cursor::new(large.clone());
    assert_eq!(scan_for_record(&mut file, 0, SCAN_CHUNK).unwrap(), None);
    assert_eq!(find_in_memory(&large, SCAN_CHUNK), None);
}
