//! The memory a journal holds while it looks past a damaged region for an intact record: a
//! window of the segment, not the rest of it. Its own test binary, for the allocator that
//! counts what each thread holds (the same as the hostile-bag tests of chronomap-rosbag).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::fs;
use std::io::{Seek, SeekFrom, Write};
use std::path::Path;
use std::time::Instant;

use chronomap_ros2::journal::{Entry, Journal, JournalError, JournalSettings};

/// The system allocator, counting the bytes each thread holds.
struct Counting;

thread_local! {
    static HELD: Cell<usize> = const { Cell::new(0) };
    static PEAK: Cell<usize> = const { Cell::new(0) };
}

fn grow(n: usize) {
    let _ = HELD.try_with(|held| {
        let now = held.get().saturating_add(n);
        held.set(now);
        let _ = PEAK.try_with(|peak| peak.set(peak.get().max(now)));
    });
}

fn shrink(n: usize) {
    let _ = HELD.try_with(|held| held.set(held.get().saturating_sub(n)));
}

// SAFETY: every call is passed on to `System` unchanged; only counters are updated.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract is `System`'s.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grow(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as above.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grow(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) };
        shrink(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as above.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            shrink(layout.size());
            grow(new_size);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The most bytes this thread held while `f` ran, above what it held before, with `f`'s result.
fn peak_bytes<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let before = HELD.with(Cell::get);
    PEAK.with(|p| p.set(before));
    let out = f();
    let peak = PEAK.with(Cell::get);
    (out, peak.saturating_sub(before))
}

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
