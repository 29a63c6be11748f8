//! The memory a journal holds while it looks past a damaged region for an intact record: a
//! window of the segment, not the rest of it. Its own test binary, for the allocator that
//! counts what each thread holds (chronomap-testutil's, as the hostile-bag tests of chronomap-rosbag use it).

use std::fs;
use std::io::{Seek, SeekFrom, Write};
use std::path::Path;
use std::time::Instant;

use chronomap_ros2::journal::{Entry, Journal, JournalError, JournalSettings};
use chronomap_testutil::memory::{Counting, peak_bytes};

#[global_allocator]
static ALLOCATOR: Counting = Counting;

fn state(time: f64) -> Entry<'static> {
    Entry::State {
        name: "door".into(),
        time,
        value: 1.0,
    }
}

fn open(dir: &Path) -> Result<u64, JournalError> {
    let (journal, _) = Journal::open(dir, 0, JournalSettings::default(), |_, _| {
        Ok::<(), JournalError>(())
    })?;
    Ok(journal.next_position())
}

const DAMAGE: u64 = 64 << 20;

#[test]
fn a_64_mib_damaged_region_is_scanned_in_a_window_and_the_intact_record_after_it_found() {
    let dir = chronomap_testutil::fresh_dir(std::env::temp_dir().join(format!(
        "chronomap-ros2-journal-memory-{}",
        std::process::id()
    )));
    let journal_dir = dir.join("journal");
    let (mut journal, _) = Journal::open(&journal_dir, 0, JournalSettings::default(), |_, _| {
        Ok::<(), JournalError>(())
    })
    .unwrap();
    let now = Instant::now();
    journal.append(&state(1.0), now).unwrap();
    journal.append(&state(2.0), now).unwrap();
    journal.sync().unwrap();
    drop(journal);
    let segment = fs::read_dir(&journal_dir)
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let bytes = fs::read(&segment).unwrap();
    // The segment header (8 bytes) and two records of the same size.
    let record = (bytes.len() - 8) / 2;
    let (first, second) = bytes.split_at(8 + record);
    // 64 MiB of zeros (a hole: nothing is written) between the two records.
    let mut file = fs::File::create(&segment).unwrap();
    file.write_all(first).unwrap();
    file.seek(SeekFrom::Current(DAMAGE as i64)).unwrap();
    file.write_all(second).unwrap();
    drop(file);
    let (result, peak) = peak_bytes(|| open(&journal_dir));
    let error = result.unwrap_err().to_string();
    assert!(
        error.contains(&format!(
            "byte {}: no record starts here; an intact record (position 1) follows it",
            8 + record
        )),
        "{error}"
    );
    // The window (64 KiB and a record header) and the journal's own buffers; reading the
    // rest of the segment would hold 64 MiB.
    eprintln!("held at most {peak} bytes");
    assert!(peak < 1 << 20, "held {peak} bytes");
    let _ = fs::remove_dir_all(&dir);
}
