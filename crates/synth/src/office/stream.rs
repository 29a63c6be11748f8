//! Streaming the frames of a range of cells, one frame in memory at a time.

use std::ops::Range;

use super::layout::Cell;
use super::{DAY_SECS, OfficeWorkload, day_of};

/// The frames of a range of cells, in order, one at a time
/// ([`OfficeWorkload::stream`]).
///
/// Holds one frame (the range's bits) and the change events of one day: when a day
/// begins, each dynamic cell's occupied intervals on that day are drawn and turned into
/// change events (frame, cell), sorted by frame; each [`next_frame`](Self::next_frame) then
/// applies the events of its frame. A frame costs time proportional to its number of events
/// (plus, once a day, to the number of dynamic cells in the range); memory is the frame, the
/// list of dynamic cells and one day of events (8 bytes each, about 1 MB a day for the
/// default office).
///
/// Frame 0 is compared with an implicit all-free frame before it: its
/// [`last_changes`](Self::last_changes) are all the cells occupied at frame 0.
#[derive(Debug)]
pub struct FrameStream<'a> {
    workload: &'a OfficeWorkload,
    range: Range<usize>,
    words: Vec<u64>,
    /// Dynamic cells of the range, increasing.
    dynamic: Vec<u32>,
    /// The next frame to emit.
    next: u64,
    /// Calendar day whose events are loaded, and its frames `day_lo..day_hi`.
    day: i64,
    day_lo: u64,
    day_hi: u64,
    /// `(frame − day_lo) << 32 | cell`, sorted; `cursor` is the first not yet applied.
    events: Vec<u64>,
    cursor: usize,
    changes: Vec<u32>,
    intervals: Vec<(u64, u64)>,
}

impl<'a> FrameStream<'a> {
    /// A stream of `range`, which the caller has checked.
    pub(super) fn new(workload: &'a OfficeWorkload, range: Range<usize>) -> Self {
        let dynamic = range
            .clone()
            .filter(|&c| workload.layout.cells[c].class().is_dynamic())
            .map(|c| c as u32)
            .collect();
        FrameStream {
            workload,
            words: vec![0; range.len().div_ceil(64)],
            range,
            dynamic,
            next: 0,
            day: day_of(workload.config.start_time) - 1,
            day_lo: 0,
            day_hi: 0,
            events: Vec::new(),
            cursor: 0,
            changes: Vec::new(),
            intervals: Vec::new(),
        }
    }

    /// The cells streamed.
    pub fn range(&self) -> Range<usize> {
        self.range.clone()
    }

    /// Advances to the next frame: returns its index, its time and the bit-packed occupancy
    /// of the range (cell `range.start + i` is bit `i % 64` of word `i / 64`, least
    /// significant bit first, 1 = occupied; bits past the range's end are 0), or `None`
    /// after the last frame.
    pub fn next_frame(&mut self) -> Option<(u64, f64, &[u64])> {
        self.changes.clear();
        let frame = self.next;
        if frame >= self.workload.frames {
            return None;
        }
        if frame == 0 {
            for cell in self.range.clone() {
                if self.workload.layout.cells[cell] == Cell::Occupied {
                    self.flip(cell as u32);
                }
            }
        }
        while frame >= self.day_hi {
            self.load_next_day();
        }
        let offset = frame - self.day_lo;
        while let Some(&event) = self.events.get(self.cursor) {
            if event >> 32 != offset {
                break;
            }
            self.flip(event as u32);
            self.cursor += 1;
        }
        if frame == 0 {
            self.changes.sort_unstable();
        }
        self.next += 1;
        Some((frame, self.workload.frame_time(frame), &self.words))
    }

    /// Cells (absolute indices, increasing) whose bit flipped between the previous frame and
    /// the current one: exactly the set bits of the XOR of the two frames. Empty before the
    /// first frame and after the last.
    pub fn last_changes(&self) -> &[u32] {
        &self.changes
    }

    /// The current frame's bits (as last returned by [`next_frame`](Self::next_frame)).
    pub fn words(&self) -> &[u64] {
        &self.words
    }

    /// Whether `cell` (an absolute index) is occupied in the current frame; `None` outside
    /// the range.
    pub fn is_occupied(&self, cell: usize) -> Option<bool> {
        if !self.range.contains(&cell) {
            return None;
        }
        let i = cell - self.range.start;
        Some(self.words[i / 64] >> (i % 64) & 1 == 1)
    }

    #[inline]
    fn flip(&mut self, cell: u32) {
        let i = cell as usize - self.range.start;
        self.words[i / 64] ^= 1 << (i % 64);
        self.changes.push(cell);
    }

    /// Draws the next calendar day's intervals of the dynamic cells and turns them into
    /// change events against the current bits (the state at the day's first frame − 1).
    fn load_next_day(&mut self) {
        self.day += 1;
        self.day_lo = self.day_hi;
        self.day_hi = self
            .workload
            .frame_ceil((self.day + 1) as f64 * DAY_SECS)
            .max(self.day_lo);
        self.events.clear();
        self.cursor = 0;
        let (lo, hi) = (self.day_lo, self.day_hi);
        if lo == hi {
            return;
        }
        for &cell in &self.dynamic {
            self.workload
                .day_intervals(cell as usize, self.day, lo, hi, &mut self.intervals);
            let i = cell as usize - self.range.start;
            let occupied = self.words[i / 64] >> (i % 64) & 1 == 1;
            let starts_occupied = self.intervals.first().is_some_and(|&(a, _)| a == lo);
            let event = |frame: u64| (frame - lo) << 32 | u64::from(cell);
            if starts_occupied != occupied {
                self.events.push(event(lo));
            }
            for &(a, b) in &self.intervals {
                if a > lo {
                    self.events.push(event(a));
                }
                if b < hi {
                    self.events.push(event(b));
                }
            }
        }
        self.events.sort_unstable();
    }
}
