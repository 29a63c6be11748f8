//! The learning state of a [`FremenGrid`] as grid files of format 1 hold it (written by chronomap
//! before format 2): every changing cell with its own 128-bit sums for every period, and the
//! slot index of every cell. Read only: [`GridStateV1`] converts into a [`FremenGrid`] holding
//! exactly the same sums (each accumulator in a block of its own), which then learns on as any
//! other.

use serde::Deserialize;

use crate::store::Acc;
use crate::{FremenGrid, GridConfig, GridGeometry, NONE, Slot};
use chronomap_core::exact::ExactSum;
use chronomap_core::observe::ObservedSpan;

/// A slot of format 1.
#[derive(Deserialize)]
struct SlotV1 {
    cell: u32,
    unknown: u32,
    ones: i64,
    unknown_frames: i64,
    extra_value: ExactSum,
    first: f64,
    last: f64,
    history: Vec<u64>,
}

/// A [`FremenGrid`] as format 1 stores it (the payload of a `grid-state` file of format 1).
#[derive(Deserialize)]
pub struct GridStateV1 {
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
    slots: Vec<SlotV1>,
    occupied_pool: Vec<[i128; 2]>,
    unknown_pool: Vec<[i128; 2]>,
    frame_times: Vec<f64>,
    had_sparse: bool,
    unknown_cells: u64,
    fraction_cells: u64,
}

impl GridStateV1 {
    /// The invariants of format 1 the conversion relies on (the rest is checked on the
    /// converted grid, [`FremenGrid::is_consistent`]).
    fn check(&self) -> Result<(), String> {
        self.geometry.validate().map_err(|e| e.to_string())?;
        self.config.fremen.validate().map_err(|e| e.to_string())?;
        let k = self.config.fremen.periods.len();
        let (cells, words) = (self.geometry.cells(), self.geometry.words());
        let fail = |what: &str| Err(format!("grid state of format 1: {what}"));
        if self.prefix.len() != k {
            return fail("the prefix does not have one entry per period");
        }
        if [&self.occupied, &self.unknown, &self.fraction]
            .iter()
            .any(|p| p.len() != words)
            || self.slot_of.len() != cells
        {
            return fail("the planes or the slot index do not fit the geometry");
        }
        if self.occupied_pool.len() != self.slots.len() * k
            || !self.unknown_pool.len().is_multiple_of(k)
        {
            return fail("the pools do not hold one row per period of each slot");
        }
        let unknown_rows = self.unknown_pool.len() / k;
        for (i, slot) in self.slots.iter().enumerate() {
            if self.slot_of.get(slot.cell as usize) != Some(&(i as u32))
                || (slot.unknown != NONE && slot.unknown as usize >= unknown_rows)
            {
                return fail("a slot names a cell or an accumulator it does not have");
            }
        }
        Ok(())
    }
}

impl TryFrom<GridStateV1> for FremenGrid {
    type Error = String;

    /// The same grid in the current representation: each non-zero accumulator of format 1
    /// becomes a block of its own (64-bit if its sums fit).
    ///
    /// # Errors
    /// A state that breaks the invariants of format 1, naming what is wrong.
    fn try_from(v1: GridStateV1) -> Result<Self, String> {
        v1.check()?;
        let k = v1.prefix.len();
        let mut grid = FremenGrid::new(v1.geometry, v1.config).map_err(|e| e.to_string())?;
        grid.frames = v1.frames;
        grid.frame_span = v1.frame_span;
        grid.latest = v1.latest;
        grid.prefix = v1.prefix;
        grid.occupied = v1.occupied;
        grid.unknown = v1.unknown;
        grid.fraction = v1.fraction;
        grid.frame_times = v1.frame_times;
        grid.had_sparse = v1.had_sparse;
        grid.unknown_cells = v1.unknown_cells;
        grid.fraction_cells = v1.fraction_cells;
        let keep_history = grid.config.keep_history;
        let mut rows: Vec<[i128; 2]> = Vec::with_capacity(k + 1);
        for (i, old) in v1.slots.into_iter().enumerate() {
            rows.clear();
            rows.extend_from_slice(&v1.occupied_pool[i * k..(i + 1) * k]);
            rows.push([old.extra_value.units(), 0]);
            let occupied = grid.block_of(&rows);
            let unknown = if old.unknown == NONE {
                Acc::Zero
            } else {
                let u = old.unknown as usize;
                rows.clear();
                rows.extend_from_slice(&v1.unknown_pool[u * k..(u + 1) * k]);
                rows.push([0, 0]);
                grid.block_of(&rows)
            };
            grid.slot_of[old.cell as usize] = i as u32;
            grid.slots.push(Slot {
                cell: old.cell,
                occupied,
                unknown,
                ones: old.ones,
                unknown_frames: old.unknown_frames,
                first: old.first,
                last: old.last,
            });
            if keep_history {
                grid.histories.push(old.history);
            }
        }
        Ok(grid)
    }
}

impl FremenGrid {
    /// An accumulator holding `rows` (`K + 1` entries): nothing if all are zero, else a block.
    fn block_of(&mut self, rows: &[[i128; 2]]) -> Acc {
        if rows.iter().all(|r| *r == [0; 2]) {
            return Acc::Zero;
        }
        let block = self.alloc_block();
        let at = self.block_at(block);
        self.pool.add_rows(at, rows, false);
        Acc::Owned(block)
    }
}
