//! The baseline of [`grid_memory`](super): the representation of a [`FremenGrid`] up to grid-state
//! format 1, kept here as it was: every changing cell with an 80-byte slot and, from its first
//! change, its own 128-bit occupied sums for every period (and unknown sums as soon as it was
//! ever unknown), in arrays grown by doubling. It learns binary and unknown dense frames with the
//! same arithmetic (the run-edge prefix sums of [Krajník 2017] §VI as `FremenGrid` computes them),
//! and serialises as a `grid-state` payload of format 1, which `chronomap_io` still reads: the
//! benchmark checks that what it reads back equals the new grid cell for cell.
//!
//! [`FremenGrid`]: chronomap_grid::FremenGrid

use chronomap_core::exact::quantize;
use chronomap_core::observe::ObservedSpan;
use chronomap_core::spectrum::phasors;
use chronomap_grid::{GridConfig, GridGeometry};
use serde::{Serialize, Serializer};

const NONE: u32 = u32::MAX;

/// A slot of format 1 (80 bytes).
#[derive(Clone, Debug, Serialize)]
pub struct LegacySlot {
    cell: u32,
    unknown: u32,
    ones: i64,
    unknown_frames: i64,
    /// `ExactSum` of fractional values (a newtype of `i128`: the same bytes).
    extra_value: i128,
    first: f64,
    last: f64,
    history: Vec<u64>,
}

/// The grid of format 1 (field order and types as the format stores them).
#[derive(Clone, Debug, Serialize)]
pub struct LegacyGrid {
    geometry: GridGeometry,
    config: GridConfig,
    frames: u64,
    frame_span: ObservedSpan,
    latest: Option<f64>,
    prefix: Vec<[i128; 2]>,
    occupied: Vec<u64>,
    unknown: Vec<u64>,
    fraction: Vec<u64>,
    slot_of: Vec<u32>,
    slots: Vec<LegacySlot>,
    occupied_pool: Vec<[i128; 2]>,
    unknown_pool: Vec<[i128; 2]>,
    frame_times: Vec<f64>,
    had_sparse: bool,
    unknown_cells: u64,
    fraction_cells: u64,
}

/// A cell's state: occupied, unknown.
#[derive(Clone, Copy, PartialEq)]
enum State {
    Free,
    Occupied,
    Unknown,
}

impl LegacyGrid {
    /// An empty grid (no history: the configuration of the ROS node and `grid build`).
    pub fn new(geometry: GridGeometry, config: GridConfig) -> Self {
        let words = geometry.words();
        let cells = geometry.cells();
        let mut unknown = vec![u64::MAX; words];
        if !cells.is_multiple_of(64) {
            unknown[words - 1] = (1u64 << (cells % 64)) - 1;
        }
        LegacyGrid {
            prefix: vec![[0; 2]; config.fremen.periods.len()],
            occupied: vec![0; words],
            unknown,
            fraction: vec![0; words],
            slot_of: vec![NONE; cells],
            slots: Vec::new(),
            occupied_pool: Vec::new(),
            unknown_pool: Vec::new(),
            frame_times: Vec::new(),
            geometry,
            config,
            frames: 0,
            frame_span: ObservedSpan::default(),
            latest: None,
            had_sparse: false,
            unknown_cells: cells as u64,
            fraction_cells: 0,
        }
    }

    /// Heap bytes as format 1's `memory_bytes` counted them: bit planes, slot index, slots and
    /// pools by length (the resident part of their arrays).
    pub fn memory_bytes(&self) -> usize {
        3 * self.occupied.len() * 8
            + self.slot_of.len() * 4
            + self.slots.len() * std::mem::size_of::<LegacySlot>()
            + (self.occupied_pool.len() + self.unknown_pool.len()) * 32
    }

    /// Slots, their occupied-pool rows and their unknown-pool rows.
    pub fn parts(&self) -> (&[LegacySlot], &[[i128; 2]], &[[i128; 2]]) {
        (&self.slots, &self.occupied_pool, &self.unknown_pool)
    }

    /// The grid with no cell storage and empty arrays (what its file holds besides them).
    pub fn skeleton(&self) -> LegacyGrid {
        LegacyGrid {
            geometry: self.geometry,
            config: self.config.clone(),
            frames: self.frames,
            frame_span: self.frame_span,
            latest: self.latest,
            prefix: Vec::new(),
            occupied: Vec::new(),
            unknown: Vec::new(),
            fraction: Vec::new(),
            slot_of: Vec::new(),
            slots: Vec::new(),
            occupied_pool: Vec::new(),
            unknown_pool: Vec::new(),
            frame_times: Vec::new(),
            had_sparse: self.had_sparse,
            unknown_cells: self.unknown_cells,
            fraction_cells: self.fraction_cells,
        }
    }

    /// The skeleton of the whole grid of which this is a part: `geometry` and the whole
    /// grid's count of unknown cells.
    pub fn with_whole(mut self, geometry: GridGeometry, unknown_cells: u64) -> LegacyGrid {
        self.geometry = geometry;
        self.unknown_cells = unknown_cells;
        self
    }

    /// Cells unknown in the last frame.
    pub fn unknown_cells(&self) -> u64 {
        self.unknown_cells
    }

    /// The arrays its file holds besides the skeleton's: prefix, planes, slot index, frame
    /// times (the slots and pools are [`LegacyGrid::parts`]).
    pub fn prefix_and_planes(&self) -> (&[[i128; 2]], [&[u64]; 3], &[u32]) {
        (
            &self.prefix,
            [&self.occupied, &self.unknown, &self.fraction],
            &self.slot_of,
        )
    }

    fn state(&self, cell: usize) -> State {
        let (w, b) = (cell / 64, 1u64 << (cell % 64));
        if self.unknown[w] & b != 0 {
            State::Unknown
        } else if self.occupied[w] & b != 0 {
            State::Occupied
        } else {
            State::Free
        }
    }

    /// Learns a dense frame of −1 (unknown), 0 (free) and 100 (occupied) at `time` (after the
    /// last one; the caller checks).
    pub fn observe(&mut self, time: f64, data: &[i8]) {
        let k = self.prefix.len();
        let (mut re, mut im) = (vec![0.0; k], vec![0.0; k]);
        phasors(&self.config.fremen.periods, time, &mut re, &mut im);
        let frame = self.frames;
        let previous = self.frame_span.last_time();
        for (cell, &v) in data.iter().enumerate() {
            let new = match v {
                -1 => State::Unknown,
                100 => State::Occupied,
                _ => State::Free,
            };
            let old = self.state(cell);
            let first_sight = frame == 0
                && old == State::Unknown
                && self.slot_of[cell] == NONE
                && new != State::Unknown;
            if old != new && !first_sight {
                self.transition(cell, old, new, frame, time, previous);
            }
            let (w, b) = (cell / 64, 1u64 << (cell % 64));
            match new {
                State::Occupied => {
                    self.occupied[w] |= b;
                    self.unknown[w] &= !b;
                }
                State::Unknown => {
                    self.occupied[w] &= !b;
                    self.unknown[w] |= b;
                }
                State::Free => {
                    self.occupied[w] &= !b;
                    self.unknown[w] &= !b;
                }
            }
        }
        self.unknown_cells = self.unknown.iter().map(|w| u64::from(w.count_ones())).sum();
        for (p, (&r, &i)) in self.prefix.iter_mut().zip(re.iter().zip(&im)) {
            p[0] += i128::from(quantize(r));
            p[1] += i128::from(quantize(i));
        }
        self.frames += 1;
        self.frame_span.extend(&[time]);
        self.latest = Some(time);
    }

    fn ensure_slot(&mut self, cell: usize) -> usize {
        if self.slot_of[cell] != NONE {
            return self.slot_of[cell] as usize;
        }
        let never_seen = self.state(cell) == State::Unknown;
        let k = self.prefix.len();
        self.occupied_pool
            .extend(std::iter::repeat_n([0i128; 2], k));
        self.slots.push(LegacySlot {
            cell: cell as u32,
            unknown: NONE,
            ones: 0,
            unknown_frames: 0,
            extra_value: 0,
            first: if never_seen {
                f64::NAN
            } else {
                self.frame_span.first
            },
            last: f64::NEG_INFINITY,
            history: Vec::new(),
        });
        self.slot_of[cell] = (self.slots.len() - 1) as u32;
        self.slots.len() - 1
    }

    fn transition(
        &mut self,
        cell: usize,
        old: State,
        new: State,
        frame: u64,
        time: f64,
        previous: Option<f64>,
    ) {
        let slot = self.ensure_slot(cell);
        self.run_edge(slot, old, frame, true);
        if old == State::Unknown && self.slots[slot].first.is_nan() {
            self.slots[slot].first = time;
        }
        self.run_edge(slot, new, frame, false);
        if new == State::Unknown
            && let Some(previous) = previous
        {
            let s = &mut self.slots[slot];
            s.last = s.last.max(previous);
        }
    }

    fn run_edge(&mut self, slot: usize, state: State, frame: u64, close: bool) {
        let k = self.prefix.len();
        let f = if close { frame as i64 } else { -(frame as i64) };
        let rows = match state {
            State::Occupied => {
                self.slots[slot].ones += f;
                &mut self.occupied_pool[slot * k..(slot + 1) * k]
            }
            State::Unknown => {
                if self.slots[slot].unknown == NONE {
                    self.slots[slot].unknown = (self.unknown_pool.len() / k) as u32;
                    self.unknown_pool.extend(std::iter::repeat_n([0i128; 2], k));
                }
                self.slots[slot].unknown_frames += f;
                let u = self.slots[slot].unknown as usize;
                &mut self.unknown_pool[u * k..(u + 1) * k]
            }
            State::Free => return,
        };
        for (r, p) in rows.iter_mut().zip(&self.prefix) {
            if close {
                r[0] += p[0];
                r[1] += p[1];
            } else {
                r[0] -= p[0];
                r[1] -= p[1];
            }
        }
    }
}

/// A legacy grid serialised as the `grid-state` payload of format 1 (variant 0 of the file's
/// enum).
pub struct Format1File<'a>(pub &'a LegacyGrid);

impl Serialize for Format1File<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_newtype_variant("GridFile", 0, "State", self.0)
    }
}

/// Bytes of a postcard varint of `x`.
pub fn varint_len(x: u128) -> usize {
    (128 - x.leading_zeros() as usize).div_ceil(7).max(1)
}

/// Bytes of a postcard signed integer (zigzag varint).
pub fn signed_len(x: i128) -> usize {
    varint_len(((x << 1) ^ (x >> 127)) as u128)
}

/// Bytes of a slot of format 1 whose cell and unknown-row index are moved by `cell_base` and
/// `unknown_base` (a slot of a part of the grid, in the whole grid's file).
pub fn slot_len(slot: &LegacySlot, cell_base: u32, unknown_base: u32) -> usize {
    let unknown = if slot.unknown == NONE {
        NONE
    } else {
        slot.unknown + unknown_base
    };
    varint_len(u128::from(slot.cell + cell_base))
        + varint_len(u128::from(unknown))
        + signed_len(i128::from(slot.ones))
        + signed_len(i128::from(slot.unknown_frames))
        + signed_len(slot.extra_value)
        + 16
        + varint_len(slot.history.len() as u128)
}

/// Bytes of a row of two 128-bit sums.
pub fn row_len(row: &[i128; 2]) -> usize {
    signed_len(row[0]) + signed_len(row[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_are_postcards() {
        assert_eq!(std::mem::size_of::<LegacySlot>(), 80);
        assert_eq!(varint_len(0), 1);
        assert_eq!(varint_len(127), 1);
        assert_eq!(varint_len(128), 2);
        assert_eq!(varint_len(u128::from(u32::MAX)), 5);
        assert_eq!(signed_len(-1), 1);
        assert_eq!(signed_len(-64), 1);
        assert_eq!(signed_len(64), 2);
        assert_eq!(signed_len(i128::MIN), 19);
    }
}
