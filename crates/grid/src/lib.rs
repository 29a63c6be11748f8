//! Spatio-temporal occupancy grids: a FreMEn model in every cell, at office scale
//! ([Krajník 2017] §III-C, §VI, §VIII).
//!
//! # Model
//! Every cell of a 2-D or 3-D grid is a [`FremenModel`] of its occupancy: the grid observes
//! whole frames (dense occupancy arrays with unknown cells, or bit-packed frames) at arbitrary
//! irregular times, and sparse single-cell observations in between, and [`FremenGrid::cell_model`]
//! returns, for any cell, *exactly* the model (same exact sums, same span) that a
//! [`FremenModel`] would have built from that cell's observations alone.
//!
//! # Cost follows changes
//! A cell's spectrum needs `S_k = Σ s·e^{-jω_k t}` over its observations. With the frame
//! phasor prefix `P_k(f) = Σ_{f' < f} e^{-jω_k t_f'}`, shared by all cells, a run of frames
//! `[a, b)` in which a cell is occupied contributes `P_k(b) − P_k(a)` — so a cell's sums only
//! change when its state changes: entering a state at frame `f` subtracts `P(f)`, leaving it adds
//! `P(f)`. The same holds for runs of unknown frames (subtracted from `E_k = Σ e^{-jω_k t}` and
//! the count). Per frame the grid computes one set of phasors (the exact arithmetic of
//! [`chronomap_core::spectrum::phasors`]) and compares the new frame with the cells' states 64 cells at
//! a time; only cells whose state changed — and cells with fractional values, which are
//! accumulated frame by frame — cost more. All sums are exact ([`ExactSum`] units), so the
//! shortcut is not an approximation: it is tested against cell-by-cell FreMEn.
//!
//! # Layout
//! Struct of arrays: three bit planes (occupied, unknown, fractional) hold every cell's current
//! state; cells whose state never changed since the first frame have no other storage (they are
//! constants); the others get a *slot* (allocated on their first change) with two
//! accumulators, the run sums of their occupied and of their unknown frames. Grids over
//! disjoint cell ranges that saw the same frame times can be built on separate threads and
//! [concatenated](FremenGrid::concat).
//!
//! # Memory
//! An accumulator is a signed sum of prefixes, one `±P(f)` per run edge. Until its third edge
//! it holds just those edges, inline in the slot (4 bytes each); the prefixes `P(f)` of their
//! frames are kept once for the whole grid, shared by every cell that changed in that frame.
//! From its third edge (or first fractional or sparse observation) it owns a block of `K + 1`
//! exact sums, as 64-bit integers while every stored value fits (a sum of `n` phasors needs
//! `51 + log2 n` bits: at least 8,000 frames; more in sparse series), widened once, in place, to
//! 128 bits for the whole grid when one would not (long, dense series: the sums of a cell with
//! a rhythm grow with every frame). A cell that changed a few times costs its 64-byte slot; one
//! that keeps changing costs 64 bytes and two blocks of `16 (K + 1)` bytes (`32 (K + 1)` once
//! widened); //! a cell that never changed costs 4 bytes and 3 bits. The snapshots never
//! outnumber the accumulators held as edges, so blocks in use never exceed two per changing
//! cell: [`FremenGrid::memory_estimate`] gives these bounds for a geometry and configuration
//! before a grid is built, [`FremenGrid::heap_bytes`] what a live grid holds. Every value is
//! exact in every representation: a cell's model is the same bits whichever way it is held.
//!
//! [`build`] builds grids from sequences of frames (with the snapshots of a chronological
//! hold-out) and from sources that stream parts of the cells on separate threads; [`report`]
//! computes the error table of [Krajník 2017] §VI and other views of a built grid.
#![deny(missing_docs)]

mod any;
pub mod build;
mod fitted;
pub mod format1;
pub mod report;
mod store;

use std::collections::{BTreeMap, BTreeSet};

use serde::{Deserialize, Serialize};
use thiserror::Error;

use store::{Acc, BlockAt, EDGE_FRAMES, Edge, Pool, Snapshot, Which, reserve_within};

use chronomap_core::error::{ConfigError, ObservationError};
use chronomap_core::exact::{ExactSum, SCALE, quantize};
use chronomap_core::fremen::{FremenConfig, FremenModel};
use chronomap_core::observe::{ObservedSpan, check_time};
use chronomap_core::spectrum::{PeriodSums, SpectralSums, phasors};

pub use any::{AnyGrid, AnyGridError, GridStore};
pub use fitted::{
    CompactComponent, EstimationError, FittedCell, FittedGrid, GridHistory, LosslessGrid,
    OrderChoice,
};

/// Largest number of cells a grid may have (2^32 − 1: cells are indexed by `u32`).
pub const MAX_CELLS: usize = u32::MAX as usize;
const NONE: u32 = u32::MAX;

/// Size, resolution and placement of a grid. Cell `(x, y, z)` has index
/// `x + width·(y + height·z)`; its lower corner is at `origin + resolution·(x, y, z)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GridGeometry {
    /// Cells along x.
    pub width: u32,
    /// Cells along y.
    pub height: u32,
    /// Cells along z (1 for a 2-D grid).
    pub depth: u32,
    /// Edge length of a cell in metres.
    pub resolution: f64,
    /// Position of the lower corner of cell (0, 0, 0) in metres.
    pub origin: [f64; 3],
}

impl GridGeometry {
    /// A 2-D grid.
    ///
    /// # Errors
    /// See [`GridGeometry::validate`].
    pub fn planar(
        width: u32,
        height: u32,
        resolution: f64,
        origin: [f64; 2],
    ) -> Result<Self, GridError> {
        let g = GridGeometry {
            width,
            height,
            depth: 1,
            resolution,
            origin: [origin[0], origin[1], 0.0],
        };
        g.validate()?;
        Ok(g)
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.width as usize * self.height as usize * self.depth as usize
    }

    /// Number of `u64` words of a bit-packed frame.
    pub fn words(&self) -> usize {
        self.cells().div_ceil(64)
    }

    /// Checks the geometry.
    ///
    /// # Errors
    /// A zero dimension, more than [`MAX_CELLS`] cells, or a resolution or origin that is not a
    /// positive / finite number.
    pub fn validate(&self) -> Result<(), GridError> {
        let cells = self.width as u128 * self.height as u128 * self.depth as u128;
        if cells == 0 || cells > MAX_CELLS as u128 {
            return Err(GridError::Geometry {
                reason: format!(
                    "{}×{}×{} cells; each dimension must be >= 1 and the total <= {MAX_CELLS}",
                    self.width, self.height, self.depth
                ),
            });
        }
        if !(self.resolution.is_finite() && self.resolution > 0.0) {
            return Err(GridError::Geometry {
                reason: format!(
                    "resolution {} is not a positive number of metres",
                    self.resolution
                ),
            });
        }
        if self.origin.iter().any(|o| !o.is_finite()) {
            return Err(GridError::Geometry {
                reason: format!("origin {:?} is not finite", self.origin),
            });
        }
        Ok(())
    }
}

/// Why a grid rejected an input. A rejected input leaves the grid unchanged.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum GridError {
    /// The geometry is invalid.
    #[error("invalid grid geometry: {reason}")]
    Geometry {
        /// What is wrong.
        reason: String,
    },
    /// The model configuration is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// A frame has the wrong size (truncated, or for another grid).
    #[error("{what} has {found} elements but the grid needs {expected}")]
    FrameLength {
        /// Which input.
        what: &'static str,
        /// Elements expected.
        expected: usize,
        /// Elements given.
        found: usize,
    },
    /// A dense frame holds a value other than −1 (unknown) or 0..=100.
    #[error("cell {cell}: occupancy {value} is not -1 (unknown) or 0..=100")]
    CellValue {
        /// Cell index.
        cell: usize,
        /// The value.
        value: i8,
    },
    /// A sparse observation names a cell outside the grid.
    #[error("cell {cell} is outside the grid of {cells} cells")]
    CellIndex {
        /// The index given.
        cell: u64,
        /// Number of cells.
        cells: usize,
    },
    /// A frame in which every cell is unknown (usually a sensor failure).
    #[error("the frame at {time} observes no cell (every cell is unknown)")]
    NothingObserved {
        /// Time of the frame.
        time: f64,
    },
    /// A time or a sparse value violates the observation contract.
    #[error(transparent)]
    Observation(#[from] ObservationError),
    /// Grids cannot be combined.
    #[error("cannot combine grids: {reason}")]
    Incompatible {
        /// Why.
        reason: String,
    },
    /// An operation needs something the grid was not built with.
    #[error("{0}")]
    Unsupported(String),
}

/// Configuration of a [`FremenGrid`].
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct GridConfig {
    /// The FreMEn model of every cell (periods, default order).
    pub fremen: FremenConfig,
    /// Keep every cell's change history and the frame times (needed for lossless storage and
    /// for estimation errors; costs memory proportional to the number of changes).
    pub keep_history: bool,
}

/// State of a cell in the current frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[repr(u8)]
pub enum CellState {
    /// Observed free (0).
    Free = 0,
    /// Observed occupied (1).
    Occupied = 1,
    /// Not observed in the current frame (or never).
    Unknown = 2,
    /// Observed with an occupancy strictly between 0 and 1.
    Fraction = 3,
}

impl CellState {
    fn from_bits(occ: bool, unk: bool, frac: bool) -> CellState {
        if unk {
            CellState::Unknown
        } else if frac {
            CellState::Fraction
        } else if occ {
            CellState::Occupied
        } else {
            CellState::Free
        }
    }
}

/// Per-cell storage of a cell whose state changed at least once (or that was observed late,
/// fractionally or sparsely): 64 bytes, plus blocks of the pool for accumulators that changed
/// more than twice (see [`store`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Slot {
    cell: u32,
    /// Sums `S` of the occupied runs, and of fractional and sparse observations.
    occupied: Acc,
    /// Sums of the unknown runs, less sparse observations.
    unknown: Acc,
    /// Occupied frames, as run sums: `Σ_runs (b − a)` with the open run pending.
    ones: i64,
    /// Unknown frames minus sparse observations, as run sums.
    unknown_frames: i64,
    /// First observation time (NaN while never observed).
    first: f64,
    /// Latest observation time known before the cell's current unknown run.
    last: f64,
}

impl Slot {
    fn acc(&self, which: Which) -> Acc {
        match which {
            Which::Occupied => self.occupied,
            Which::Unknown => self.unknown,
        }
    }

    fn acc_mut(&mut self, which: Which) -> &mut Acc {
        match which {
            Which::Occupied => &mut self.occupied,
            Which::Unknown => &mut self.unknown,
        }
    }
}

/// Edges of the frame being applied: their prefix is the current one, turned into a snapshot
/// when the frame ends (always empty between calls).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Pending {
    refs: u32,
    codes: u64,
}

/// Bytes of an internal node of the snapshot index (a `BTreeMap` of `u32` keys and 16-byte
/// values, 11 to a node, 12 edges), the largest of its nodes.
const SNAPSHOT_NODE_BYTES: usize = 8 + 4 + 11 * 4 + 11 * 16 + 12 * 8;

/// Bytes of an internal node of the set of singly referenced snapshots (`u32` keys).
const SINGLETON_NODE_BYTES: usize = 8 + 4 + 11 * 4 + 12 * 8;

/// An upper bound of the heap bytes of a B-tree of `n` entries with nodes of at most
/// `node_bytes`: every node but the root holds at least 5 entries, so there are at most
/// `1 + n / 5` (none when empty: the grid drops the root of an emptied tree).
const fn btree_bytes(n: usize, node_bytes: usize) -> usize {
    if n == 0 { 0 } else { (1 + n / 5) * node_bytes }
}

/// A spatio-temporal occupancy grid with a FreMEn model in every cell (see the
/// [module docs](self)).
///
/// ```
/// use chronomap_grid::{FremenGrid, GridConfig, GridGeometry};
/// use chronomap_core::{Parallelism, TemporalModel};
///
/// // A 4×2 room; cell 5 is a door, occupied (closed) every night from 18:00 to 8:00.
/// let geometry = GridGeometry::planar(4, 2, 0.5, [0.0, 0.0])?;
/// let mut grid = FremenGrid::new(geometry, GridConfig::default())?;
/// for i in 0..14 * 24 {
///     let t = 3600.0 * i as f64;
///     let hour = (i % 24) as f64;
///     let mut frame = vec![0i8; 8];
///     frame[0] = 100; // a wall
///     frame[5] = if (8.0..18.0).contains(&hour) { 0 } else { 100 };
///     frame[7] = -1; // never seen
///     grid.observe_occupancy(t, &frame)?;
/// }
/// // 3:00 two weeks later, the changing cells fitted on the calling thread
/// let map = grid.predict_map(15.0 * 86_400.0 + 3.0 * 3600.0, Parallelism::Sequential);
/// assert_eq!(map[0], 1.0);
/// assert!(map[5] > 0.8 && map[1] == 0.0 && map[7].is_nan());
/// assert_eq!(grid.cell_model(5).unwrap().span().count, 14 * 24);
/// # Ok::<(), chronomap_grid::GridError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "StoredGrid")]
pub struct FremenGrid {
    geometry: GridGeometry,
    config: GridConfig,
    /// Number of dense frames.
    frames: u64,
    /// Times of the dense frames.
    frame_span: ObservedSpan,
    /// Latest time of any input.
    latest: Option<f64>,
    /// `P(f)`: Σ over dense frames of the quantized phasors, `[re, im]` per period.
    prefix: Vec<[i128; 2]>,
    occupied: Vec<u64>,
    unknown: Vec<u64>,
    fraction: Vec<u64>,
    /// Slot of each cell, or NONE (rebuilt from the slots when read).
    #[serde(skip)]
    slot_of: Vec<u32>,
    slots: Vec<Slot>,
    /// Change history of each slot, `(frame << 2) | new state`, if the grid keeps history.
    histories: Vec<Vec<u64>>,
    /// Blocks of `K + 1` exact sums: owned accumulators and snapshots.
    pool: Pool,
    /// Blocks of the pool not in use (zero).
    free_blocks: Vec<u32>,
    /// `P(f)` of every frame some inline edge names, by frame.
    snapshots: BTreeMap<u32, Snapshot>,
    /// Frame times, if the grid keeps history.
    frame_times: Vec<f64>,
    /// Whether sparse observations were made (they are outside the frame history).
    had_sparse: bool,
    /// Cells currently unknown (including never seen) and currently fractional: when both are
    /// zero, binary frames take a fast path that compares one bit plane.
    unknown_cells: u64,
    fraction_cells: u64,
    /// Accumulators held as edges (derived).
    #[serde(skip)]
    edge_accs: u64,
    /// Snapshots that exactly one edge references (derived).
    #[serde(skip)]
    singletons: BTreeSet<u32>,
    #[serde(skip)]
    pending: Pending,
    #[serde(skip)]
    scratch: FramePhasors,
    /// Room for one accumulator's sums (reused).
    #[serde(skip)]
    sums: Sums,
}

/// What a grid file holds of a [`FremenGrid`] (format 2): everything but what is derived.
#[derive(Deserialize)]
struct StoredGrid {
    geometry: GridGeometry,
    config: GridConfig,
    frames: u64,
    frame_span: ObservedSpan,
    latest: Option<f64>,
    prefix: Vec<[i128; 2]>,
    occupied: Vec<u64>,
    unknown: Vec<u64>,
    fraction: Vec<u64>,
    slots: Vec<Slot>,
    histories: Vec<Vec<u64>>,
    pool: Pool,
    free_blocks: Vec<u32>,
    snapshots: BTreeMap<u32, Snapshot>,
    frame_times: Vec<f64>,
    had_sparse: bool,
    unknown_cells: u64,
    fraction_cells: u64,
}

impl TryFrom<StoredGrid> for FremenGrid {
    type Error = String;

    /// Rebuilds what is derived; [`FremenGrid::is_consistent`] checks the rest.
    fn try_from(s: StoredGrid) -> Result<Self, String> {
        s.geometry.validate().map_err(|e| e.to_string())?;
        s.config.fremen.validate().map_err(|e| e.to_string())?;
        let (cells, words) = (s.geometry.cells(), s.geometry.words());
        // The planes come from the file: checking them first keeps the slot index (4 bytes a
        // cell) in proportion to what was read.
        if [&s.occupied, &s.unknown, &s.fraction]
            .iter()
            .any(|p| p.len() != words)
        {
            return Err(format!("the bit planes do not have {words} words"));
        }
        let mut slot_of = vec![NONE; cells];
        for (i, slot) in s.slots.iter().enumerate() {
            match slot_of.get_mut(slot.cell as usize) {
                Some(entry) if *entry == NONE => *entry = i as u32,
                _ => return Err(format!("slot {i}: cell {} is outside or taken", slot.cell)),
            }
        }
        let edge_accs = s
            .slots
            .iter()
            .flat_map(|slot| [slot.occupied, slot.unknown])
            .filter(|acc| acc.is_edges())
            .count() as u64;
        let singletons = s
            .snapshots
            .iter()
            .filter(|(_, snapshot)| snapshot.refs == 1)
            .map(|(&frame, _)| frame)
            .collect();
        let k = s.config.fremen.periods.len();
        Ok(FremenGrid {
            geometry: s.geometry,
            config: s.config,
            frames: s.frames,
            frame_span: s.frame_span,
            latest: s.latest,
            prefix: s.prefix,
            occupied: s.occupied,
            unknown: s.unknown,
            fraction: s.fraction,
            slot_of,
            slots: s.slots,
            histories: s.histories,
            pool: s.pool,
            free_blocks: s.free_blocks,
            snapshots: s.snapshots,
            frame_times: s.frame_times,
            had_sparse: s.had_sparse,
            unknown_cells: s.unknown_cells,
            fraction_cells: s.fraction_cells,
            edge_accs,
            singletons,
            pending: Pending::default(),
            scratch: FramePhasors::with_periods(k),
            sums: Sums::with_periods(k),
        })
    }
}

/// Scratch space for one frame's phasors and their quantized values (reused between frames;
/// not part of the grid's value).
#[derive(Clone, Debug, Default)]
struct FramePhasors {
    re: Vec<f64>,
    im: Vec<f64>,
    q: Vec<[i64; 2]>,
}

impl PartialEq for FramePhasors {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl FramePhasors {
    /// Room for `k` periods.
    fn with_periods(k: usize) -> Self {
        FramePhasors {
            re: Vec::with_capacity(k),
            im: Vec::with_capacity(k),
            q: Vec::with_capacity(k),
        }
    }

    fn heap_bytes(&self) -> usize {
        (self.re.capacity() + self.im.capacity()) * 8 + self.q.capacity() * 16
    }

    fn compute(&mut self, config: &FremenConfig, time: f64) {
        let k = config.periods.len();
        self.re.resize(k, 0.0);
        self.im.resize(k, 0.0);
        phasors(&config.periods, time, &mut self.re, &mut self.im);
        self.q.clear();
        self.q.extend(
            self.re
                .iter()
                .zip(&self.im)
                .map(|(&r, &i)| [quantize(r), quantize(i)]),
        );
    }
}

/// Scratch space for the `K + 1` sums of one block (not part of the grid's value).
#[derive(Clone, Debug, Default)]
struct Sums(Vec<[i128; 2]>);

impl PartialEq for Sums {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Sums {
    fn with_periods(k: usize) -> Self {
        Sums(Vec::with_capacity(k + 1))
    }
}

/// Where the sums of one accumulator are, to read them period by period.
#[derive(Clone, Copy)]
enum Source {
    Zero,
    /// A block.
    Block(BlockAt),
    /// Up to two prefixes (snapshot blocks, or the current prefix if `None`) and whether each
    /// is added.
    Edges([Option<(Option<BlockAt>, bool)>; 2]),
}

/// Memory of a [`FremenGrid`] estimated from its geometry and configuration alone, in bytes (see
/// "Memory" in the [crate docs](crate)). Without history; a grid that keeps history holds 24
/// more bytes per changing cell and 8 per change.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct MemoryEstimate {
    /// Number of cells.
    pub cells: u64,
    /// Bytes every grid of this geometry holds from the start whatever changes (an empty grid
    /// holds exactly these): three bit planes, the slot index (4 bytes a cell), the frame
    /// prefix and scratch space.
    pub fixed_bytes: u64,
    /// Bytes per changing cell whose sums are held as edges (it changed at most twice per
    /// state, e.g. first seen late or a door that opened once): its slot.
    pub cell_bytes_inline: u64,
    /// Bytes per changing cell whose two accumulators both have blocks of 64-bit sums (before
    /// any sum left 64 bits: at least the first 8,000 frames).
    pub cell_bytes_narrow: u64,
    /// Bytes per changing cell whose two accumulators both have blocks of 128-bit sums: the
    /// most a changing cell can need.
    pub cell_bytes_wide: u64,
    /// The most a grid of this geometry and configuration can ever hold: every cell changing,
    /// with [`MemoryEstimate::cell_bytes_wide`], all capacities at their bounds.
    pub worst_case_bytes: u64,
    /// The most a whole-map prediction ([`FremenGrid::predict_map`]) holds while it runs and
    /// returns: the map (4 bytes a cell) and one value per changing cell (and, per thread, one
    /// cell's model at a time: a few kilobytes).
    pub predict_map_bytes: u64,
}

impl MemoryEstimate {
    /// [`MemoryEstimate::fixed_bytes`] plus `changing` cells of `cell_bytes` each: e.g. the
    /// memory of a grid of which a known fraction of cells change.
    pub fn with_changing_cells(&self, changing: u64, cell_bytes: u64) -> u64 {
        self.fixed_bytes
            .saturating_add(changing.min(self.cells).saturating_mul(cell_bytes))
    }
}

impl GridConfig {
    /// The most memory one changing cell of a grid with this configuration can take, in bytes
    /// ([`MemoryEstimate::cell_bytes_wide`]: a slot and two blocks of 128-bit sums, one per
    /// state, with their share of the snapshot index). Cells that never change take none.
    pub fn bytes_per_changing_cell(&self) -> u64 {
        let k = self.fremen.periods.len() as u64;
        wide_cell_bytes(k)
    }
}

/// Bytes a block in use can come with besides its sums: its share of the snapshot index and
/// of the set of singly referenced snapshots (if it is a snapshot), and a free-list entry.
const BLOCK_OVERHEAD_BYTES: u64 = ((SNAPSHOT_NODE_BYTES + SINGLETON_NODE_BYTES) / 5 + 4) as u64;

/// Bytes of one block of `k + 1` 128-bit sums, with what comes with it.
fn wide_block_bytes(k: u64) -> u64 {
    (k + 1) * std::mem::size_of::<[i128; 2]>() as u64 + BLOCK_OVERHEAD_BYTES
}

fn wide_cell_bytes(k: u64) -> u64 {
    std::mem::size_of::<Slot>() as u64 + 2 * wide_block_bytes(k)
}

impl FremenGrid {
    /// An empty grid: every cell unknown.
    ///
    /// # Errors
    /// Invalid geometry or FreMEn configuration.
    pub fn new(geometry: GridGeometry, config: GridConfig) -> Result<Self, GridError> {
        geometry.validate()?;
        config.fremen.validate()?;
        let words = geometry.words();
        let mut unknown = vec![u64::MAX; words];
        mask_tail(&mut unknown, geometry.cells());
        let k = config.fremen.periods.len();
        Ok(FremenGrid {
            prefix: vec![[0; 2]; k],
            occupied: vec![0; words],
            unknown,
            fraction: vec![0; words],
            slot_of: vec![NONE; geometry.cells()],
            slots: Vec::new(),
            histories: Vec::new(),
            pool: Pool::new(k + 1),
            free_blocks: Vec::new(),
            snapshots: BTreeMap::new(),
            frame_times: Vec::new(),
            geometry,
            config,
            frames: 0,
            frame_span: ObservedSpan::default(),
            latest: None,
            had_sparse: false,
            unknown_cells: geometry.cells() as u64,
            fraction_cells: 0,
            edge_accs: 0,
            singletons: BTreeSet::new(),
            pending: Pending::default(),
            scratch: FramePhasors::with_periods(k),
            sums: Sums::with_periods(k),
        })
    }

    /// The memory a grid of `geometry` and `config` holds at the start and can come to hold,
    /// without building it: a pure function to check before accepting a map (see
    /// [`MemoryEstimate`]; [`FremenGrid::heap_bytes`] is what a live grid holds).
    ///
    /// ```
    /// use chronomap_grid::{FremenGrid, GridConfig, GridGeometry};
    ///
    /// let geometry = GridGeometry::planar(2000, 2000, 0.05, [0.0, 0.0])?;
    /// let config = GridConfig::default(); // one week of 84 periods
    /// let estimate = FremenGrid::memory_estimate(&geometry, &config);
    /// assert_eq!(estimate.cells, 4_000_000);
    /// assert!(estimate.fixed_bytes < 20_000_000);
    /// assert_eq!(estimate.cell_bytes_inline, 64);
    /// assert!(estimate.worst_case_bytes > 4_000_000 * 2 * 85 * 32);
    /// let empty = FremenGrid::new(geometry, config)?;
    /// assert_eq!(empty.heap_bytes() as u64, estimate.fixed_bytes);
    /// # Ok::<(), chronomap_grid::GridError>(())
    /// ```
    pub fn memory_estimate(geometry: &GridGeometry, config: &GridConfig) -> MemoryEstimate {
        let cells = geometry.cells() as u64;
        let k = config.fremen.periods.len() as u64;
        let words = geometry.words() as u64;
        let slot = std::mem::size_of::<Slot>() as u64;
        // Planes, slot index, prefix; scratch: phasors (re, im, quantized) and one block.
        let fixed = 3 * words * 8 + 4 * cells + k * 32 + k * 32 + (k + 1) * 32;
        let narrow_block = (k + 1) * std::mem::size_of::<[i64; 2]>() as u64 + BLOCK_OVERHEAD_BYTES;
        MemoryEstimate {
            cells,
            fixed_bytes: fixed,
            cell_bytes_inline: slot,
            cell_bytes_narrow: slot + 2 * narrow_block,
            cell_bytes_wide: wide_cell_bytes(k),
            // Blocks in use never exceed two per cell, plus the snapshot of the frame ending.
            // and the roots of the two B-trees.
            worst_case_bytes: fixed
                .saturating_add(cells.saturating_mul(wide_cell_bytes(k)))
                .saturating_add(wide_block_bytes(k))
                .saturating_add((SNAPSHOT_NODE_BYTES + SINGLETON_NODE_BYTES) as u64),
            predict_map_bytes: 4 * cells + 4 * cells,
        }
    }

    /// The heap memory this grid holds, in bytes: the capacities of its arrays, exactly, and
    /// the snapshot index at an upper bound per entry. Its process's resident memory grows by
    /// about as much (untouched capacity is not resident).
    pub fn heap_bytes(&self) -> usize {
        let planes =
            (self.occupied.capacity() + self.unknown.capacity() + self.fraction.capacity()) * 8;
        let histories = self.histories.capacity() * std::mem::size_of::<Vec<u64>>()
            + self
                .histories
                .iter()
                .map(|h| h.capacity() * 8)
                .sum::<usize>();
        planes
            + self.slot_of.capacity() * 4
            + self.prefix.capacity() * 32
            + self.slots.capacity() * std::mem::size_of::<Slot>()
            + histories
            + self.pool.heap_bytes()
            + self.free_blocks.capacity() * 4
            + self.index_bytes()
            + self.frame_times.capacity() * 8
            + self.scratch.heap_bytes()
            + self.sums.0.capacity() * 32
    }

    /// An upper bound of [`FremenGrid::heap_bytes`] after [`FremenGrid::observe_occupancy`]
    /// of `data`, without observing it: what to check before accepting a map (the node's
    /// `memory_limit`). Every cell the frame touches — whose state it changes, or that it
    /// observes as a fraction — is charged what it could come to hold: a slot if it has none,
    /// and a block of sums for each of its two accumulators not yet held in one (at 128 bits
    /// if the grid could widen with this frame: only from 8,192 frames on, when a 64-bit sum
    /// of up to `frames · 2⁵⁰` units can overflow); the frame's prefix snapshot; the step by
    /// which full arrays grow (an eighth, at least 64 entries); and, when it may widen, the
    /// pool twice over.
    /// `data` as `observe_occupancy` takes it (a value out of range counts as touching its
    /// cell; the frame is checked when observed). O(cells).
    pub fn heap_bound_after_occupancy(&self, data: &[i8]) -> u64 {
        let k = self.config.fremen.periods.len() as u64;
        let stride = k + 1;
        let may_widen = !self.pool.is_wide() && self.frames + 1 >= 8192;
        let entry_bytes: u64 = if self.pool.is_wide() || may_widen {
            32
        } else {
            16
        };
        let block = stride * entry_bytes + BLOCK_OVERHEAD_BYTES;
        let slot = std::mem::size_of::<Slot>() as u64;
        let mut growth = 0u64;
        for (cell, &v) in data.iter().enumerate().take(self.geometry.cells()) {
            let state = self.cell_state(cell);
            let touched = match v {
                100 => state != CellState::Occupied,
                0 => state != CellState::Free,
                -1 => state != CellState::Unknown,
                _ => true,
            };
            if !touched {
                continue;
            }
            growth += match self.slot_of[cell] {
                NONE => slot + 2 * block,
                s => {
                    let s = &self.slots[s as usize];
                    [s.occupied, s.unknown]
                        .iter()
                        .filter(|a| !matches!(a, Acc::Owned(_)))
                        .count() as u64
                        * block
                }
            };
        }
        let now = self.heap_bytes() as u64;
        let pool = self.pool.heap_bytes() as u64;
        let slots = (self.slots.capacity() * std::mem::size_of::<Slot>()) as u64;
        let snapshot = block + (SNAPSHOT_NODE_BYTES + SINGLETON_NODE_BYTES) as u64;
        let widen = if may_widen { pool } else { 0 };
        // The frame times grow as a `Vec` does: doubling when full.
        let frame_times = if self.frame_times.len() == self.frame_times.capacity() {
            (self.frame_times.capacity().max(4) * 8) as u64
        } else {
            0
        };
        // Arrays that run full grow by an eighth of their length, at least 64 entries
        // (`store::reserve_within`): the pool by blocks, the slots, the free list.
        let step = (pool + growth) / 8 + 64 * stride * entry_bytes + slots / 8 + 64 * slot + 64 * 4;
        now.saturating_add(growth)
            .saturating_add(step)
            .saturating_add(snapshot)
            .saturating_add(widen)
            .saturating_add(frame_times)
    }

    /// The upper bound [`FremenGrid::heap_bytes`] counts for the snapshot index and the set of
    /// singly referenced snapshots.
    fn index_bytes(&self) -> usize {
        btree_bytes(self.snapshots.len(), SNAPSHOT_NODE_BYTES)
            + btree_bytes(self.singletons.len(), SINGLETON_NODE_BYTES)
    }

    /// Heap memory used, in bytes: [`FremenGrid::heap_bytes`].
    pub fn memory_bytes(&self) -> usize {
        self.heap_bytes()
    }

    /// How the grid holds its changing cells (what [`FremenGrid::heap_bytes`] is made of).
    pub fn storage(&self) -> GridStorage {
        let owned = self
            .slots
            .iter()
            .flat_map(|s| [s.occupied, s.unknown])
            .filter(|a| matches!(a, Acc::Owned(_)))
            .count();
        GridStorage {
            slots: self.slots.len(),
            edge_accumulators: self.edge_accs as usize,
            owned_accumulators: owned,
            snapshots: self.snapshots.len(),
            free_blocks: self.free_blocks.len(),
            sum_bits: if self.pool.is_wide() { 128 } else { 64 },
            pool_bytes: self.pool.heap_bytes(),
            slot_bytes: self.slots.capacity() * std::mem::size_of::<Slot>(),
        }
    }

    /// The geometry.
    pub fn geometry(&self) -> &GridGeometry {
        &self.geometry
    }

    /// The configuration.
    pub fn config(&self) -> &GridConfig {
        &self.config
    }

    /// Number of dense frames observed.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Times of the dense frames (count, first, last).
    pub fn frame_span(&self) -> ObservedSpan {
        self.frame_span
    }

    /// Number of cells that needed per-cell storage (they changed, or were observed late,
    /// fractionally or sparsely); all others are constants.
    pub fn dynamic_cells(&self) -> usize {
        self.slots.len()
    }

    /// Current state of a cell.
    ///
    /// # Panics
    /// If `cell` is out of range.
    pub fn cell_state(&self, cell: usize) -> CellState {
        let (w, b) = (cell / 64, 1u64 << (cell % 64));
        CellState::from_bits(
            self.occupied[w] & b != 0,
            self.unknown[w] & b != 0,
            self.fraction[w] & b != 0,
        )
    }

    /// Checks internal invariants (for grids read from files).
    pub fn is_consistent(&self) -> bool {
        let k = self.config.fremen.periods.len();
        let words = self.geometry.words();
        let cells = self.geometry.cells();
        let popcount = |plane: &[u64]| plane.iter().map(|w| u64::from(w.count_ones())).sum::<u64>();
        self.geometry.validate().is_ok()
            && self.config.fremen.validate().is_ok()
            && self.prefix.len() == k
            && self.occupied.len() == words
            && self.unknown.len() == words
            && self.fraction.len() == words
            && self.slot_of.len() == cells
            && self.slots.iter().enumerate().all(|(i, s)| {
                (s.cell as usize) < cells && self.slot_of[s.cell as usize] == i as u32
            })
            && self
                .slot_of
                .iter()
                .all(|&s| s == NONE || (s as usize) < self.slots.len())
            && (!self.config.keep_history || self.frame_times.len() as u64 == self.frames)
            && self.histories.len()
                == if self.config.keep_history {
                    self.slots.len()
                } else {
                    0
                }
            && self.unknown_cells == popcount(&self.unknown)
            && self.fraction_cells == popcount(&self.fraction)
            && self.frame_span.count == self.frames
            && self.frame_span.is_consistent()
            && self.latest.is_none_or(f64::is_finite)
            && self.frame_times.iter().all(|t| t.is_finite())
            && self.frame_times.windows(2).all(|w| w[0] <= w[1])
            && self.storage_is_consistent()
    }

    /// Every block is used once (by an owned accumulator or a snapshot) or free and zero; the
    /// snapshots are exactly those the edges name, with their counts and codes; no more
    /// snapshots than accumulators held as edges.
    fn storage_is_consistent(&self) -> bool {
        let stride = self.stride();
        if self.pool.stride() != stride || self.pending != Pending::default() {
            return false;
        }
        let blocks = self.pool.len() / stride;
        let mut used = vec![false; blocks];
        let mut claim = |block: u32| {
            let b = block as usize;
            b < blocks && !std::mem::replace(&mut used[b], true)
        };
        let mut named: BTreeMap<u32, (u32, u64)> = BTreeMap::new();
        let mut edge_accs = 0u64;
        for (i, slot) in self.slots.iter().enumerate() {
            for which in [Which::Occupied, Which::Unknown] {
                let acc = slot.acc(which);
                match acc {
                    Acc::Zero => {}
                    Acc::Owned(block) => {
                        if !claim(block) {
                            return false;
                        }
                    }
                    Acc::One(_) | Acc::Two(..) => {
                        edge_accs += 1;
                        if let Acc::Two(a, b) = acc
                            && a.frame() >= b.frame()
                        {
                            return false;
                        }
                        for edge in acc.edges() {
                            let frame = edge.frame();
                            if frame == 0 || u64::from(frame) >= self.frames {
                                return false;
                            }
                            let entry = named.entry(frame).or_insert((0, 0));
                            entry.0 += 1;
                            entry.1 ^= which.code(i);
                        }
                    }
                }
            }
        }
        if edge_accs != self.edge_accs
            || named.len() != self.snapshots.len()
            || self.snapshots.len() as u64 > edge_accs
        {
            return false;
        }
        for ((frame, snapshot), (named_frame, &(refs, codes))) in self.snapshots.iter().zip(&named)
        {
            if frame != named_frame
                || snapshot.refs != refs
                || snapshot.codes != codes
                || !claim(snapshot.block)
                || (refs == 1) != self.singletons.contains(frame)
            {
                return false;
            }
        }
        for &block in &self.free_blocks {
            if !claim(block) {
                return false;
            }
        }
        used.iter().all(|&u| u)
            && self.singletons.len() == self.snapshots.values().filter(|s| s.refs == 1).count()
            && self.free_blocks.iter().all(|&b| {
                let at = b as usize * stride;
                (at..at + stride).all(|i| self.pool.get(i) == [0; 2])
            })
    }

    fn check_frame_time(&self, time: f64) -> Result<(), GridError> {
        check_time(0, time, self.latest)?;
        Ok(())
    }

    /// Observes a bit-packed frame: bit `i % 64` of word `i / 64` is cell `i` (1 = occupied).
    /// `known` (same layout) marks the observed cells; `None` = every cell observed. Bits past
    /// the last cell are ignored.
    ///
    /// # Errors
    /// A bad or earlier time, wrong lengths, or a frame that observes no cell.
    pub fn observe_bits(
        &mut self,
        time: f64,
        occupied: &[u64],
        known: Option<&[u64]>,
    ) -> Result<(), GridError> {
        self.check_frame_time(time)?;
        let words = self.geometry.words();
        check_length("the occupancy bit frame", words, occupied.len())?;
        if let Some(known) = known {
            check_length("the known-cell mask", words, known.len())?;
            let cells = self.geometry.cells();
            let any = known
                .iter()
                .enumerate()
                .any(|(w, &k)| k & tail_mask(w, cells) != 0);
            if !any {
                return Err(GridError::NothingObserved { time });
            }
        }
        let cells = self.geometry.cells();
        if known.is_none() && self.unknown_cells == 0 && self.fraction_cells == 0 {
            self.apply_binary_frame(time, occupied);
            return Ok(());
        }
        self.apply_frame(
            time,
            |w| {
                let valid = tail_mask(w, cells);
                let k = known.map_or(u64::MAX, |k| k[w]) & valid;
                (occupied[w] & k, !k & valid, 0)
            },
            |_| 0.0,
        );
        Ok(())
    }

    /// Observes a dense occupancy frame as `nav_msgs/OccupancyGrid` holds it: one `i8` per cell,
    /// −1 unknown, 0..=100 occupancy in percent (read as `s = v / 100`).
    ///
    /// # Errors
    /// A bad or earlier time, a wrong length, a value outside −1..=100 (naming the cell), or a
    /// frame that observes no cell.
    pub fn observe_occupancy(&mut self, time: f64, data: &[i8]) -> Result<(), GridError> {
        self.check_frame_time(time)?;
        let cells = self.geometry.cells();
        check_length("the occupancy frame", cells, data.len())?;
        if let Some(cell) = data.iter().position(|&v| !(-1..=100).contains(&v)) {
            return Err(GridError::CellValue {
                cell,
                value: data[cell],
            });
        }
        if data.iter().all(|&v| v == -1) {
            return Err(GridError::NothingObserved { time });
        }
        self.apply_frame(
            time,
            |w| {
                let mut planes = (0u64, 0u64, 0u64);
                let start = w * 64;
                for (j, &v) in data[start..cells.min(start + 64)].iter().enumerate() {
                    let bit = 1u64 << j;
                    match v {
                        100 => planes.0 |= bit,
                        -1 => planes.1 |= bit,
                        0 => {}
                        _ => planes.2 |= bit,
                    }
                }
                planes
            },
            |cell| f64::from(data[cell]) / 100.0,
        );
        Ok(())
    }

    /// The common case of a frame in which every cell is observed and binary while no cell is
    /// unknown or fractional: only the occupied plane changes, so one XOR per 64 cells finds
    /// the cells to update.
    fn apply_binary_frame(&mut self, time: f64, occupied: &[u64]) {
        let mut phasors = std::mem::take(&mut self.scratch);
        phasors.compute(&self.config.fremen, time);
        let frame = self.frames;
        let previous_time = self.frame_span.last_time();
        let cells = self.geometry.cells();
        let last = self.occupied.len() - 1;
        // Skip unchanged stretches 8 words (512 cells) at a time with a vectorised OR of XORs.
        const CHUNK: usize = 8;
        let mut w0 = 0;
        while w0 <= last {
            let w1 = (w0 + CHUNK).min(last + 1);
            if w1 <= last
                && occupied[w0..w1]
                    .iter()
                    .zip(&self.occupied[w0..w1])
                    .fold(0u64, |acc, (a, b)| acc | (a ^ b))
                    == 0
            {
                w0 = w1;
                continue;
            }
            for (w, &bits) in occupied.iter().enumerate().take(w1).skip(w0) {
                let new = if w == last {
                    bits & tail_mask(w, cells)
                } else {
                    bits
                };
                let mut changed = new ^ self.occupied[w];
                while changed != 0 {
                    let j = changed.trailing_zeros() as usize;
                    changed &= changed - 1;
                    let (old_state, new_state) = if new & (1u64 << j) != 0 {
                        (CellState::Free, CellState::Occupied)
                    } else {
                        (CellState::Occupied, CellState::Free)
                    };
                    self.transition(w * 64 + j, old_state, new_state, frame, time, previous_time);
                }
                self.occupied[w] = new;
            }
            w0 = w1;
        }
        self.finish_frame(time, phasors);
    }

    /// Turns the edges of the frame into a snapshot of the prefix, adds the frame's phasors to
    /// the prefix and records the frame.
    fn finish_frame(&mut self, time: f64, phasors: FramePhasors) {
        if self.pending.refs > 0 {
            let block = self.alloc_block();
            let at = self.block_at(block);
            let prefix = std::mem::take(&mut self.prefix);
            self.pool.add_rows(at, &prefix, false);
            self.prefix = prefix;
            // Edges are only held inline below frame 2^31.
            let frame = self.frames as u32;
            let Pending { refs, codes } = std::mem::take(&mut self.pending);
            self.snapshots
                .insert(frame, Snapshot { block, refs, codes });
            if refs == 1 {
                self.singletons.insert(frame);
            }
        }
        for (p, q) in self.prefix.iter_mut().zip(&phasors.q) {
            p[0] += i128::from(q[0]);
            p[1] += i128::from(q[1]);
        }
        self.scratch = phasors;
        self.frames += 1;
        self.frame_span.extend(&[time]);
        self.latest = Some(time);
        if self.config.keep_history {
            self.frame_times.push(time);
        }
        self.rebalance();
    }

    /// Applies one dense frame given, per word, its new (occupied, unknown, fraction) planes
    /// and the fractional value of a cell.
    fn apply_frame(
        &mut self,
        time: f64,
        planes: impl Fn(usize) -> (u64, u64, u64),
        fraction_value: impl Fn(usize) -> f64,
    ) {
        let mut phasors = std::mem::take(&mut self.scratch);
        phasors.compute(&self.config.fremen, time);
        let frame = self.frames;
        let previous_time = self.frame_span.last_time();
        for w in 0..self.occupied.len() {
            let (occ, unk, frac) = planes(w);
            let (old_occ, old_unk, old_frac) =
                (self.occupied[w], self.unknown[w], self.fraction[w]);
            let mut touched = (occ ^ old_occ) | (unk ^ old_unk) | frac | old_frac;
            if touched == 0 {
                continue;
            }
            while touched != 0 {
                let j = touched.trailing_zeros() as usize;
                touched &= touched - 1;
                let bit = 1u64 << j;
                let cell = w * 64 + j;
                let old = CellState::from_bits(
                    old_occ & bit != 0,
                    old_unk & bit != 0,
                    old_frac & bit != 0,
                );
                let new = CellState::from_bits(occ & bit != 0, unk & bit != 0, frac & bit != 0);
                // A cell first seen in the first frame in a binary state is a constant until it
                // changes: its (empty) unknown run needs no storage.
                let first_sight = frame == 0
                    && old == CellState::Unknown
                    && self.slot_of[cell] == NONE
                    && matches!(new, CellState::Free | CellState::Occupied);
                if old != new && !first_sight {
                    self.transition(cell, old, new, frame, time, previous_time);
                }
                if new == CellState::Fraction {
                    let value = fraction_value(cell);
                    self.add_fraction(cell, value, time, &phasors);
                }
            }
            self.unknown_cells =
                self.unknown_cells + u64::from(unk.count_ones()) - u64::from(old_unk.count_ones());
            self.fraction_cells = self.fraction_cells + u64::from(frac.count_ones())
                - u64::from(old_frac.count_ones());
            self.occupied[w] = occ;
            self.unknown[w] = unk;
            self.fraction[w] = frac;
        }
        self.finish_frame(time, phasors);
    }

    /// Slot of a cell, allocated (with the current run opened at frame 0) if needed.
    fn ensure_slot(&mut self, cell: usize) -> usize {
        if self.slot_of[cell] != NONE {
            return self.slot_of[cell] as usize;
        }
        let never_seen = self.cell_state(cell) == CellState::Unknown;
        let cells = self.geometry.cells();
        reserve_within(&mut self.slots, 1, 64, cells);
        self.slots.push(Slot {
            cell: cell as u32,
            occupied: Acc::Zero,
            unknown: Acc::Zero,
            ones: 0,
            unknown_frames: 0,
            first: if never_seen {
                f64::NAN
            } else {
                self.frame_span.first
            },
            last: f64::NEG_INFINITY,
        });
        let slot = self.slots.len() - 1;
        self.slot_of[cell] = slot as u32;
        if self.config.keep_history {
            // The state it has had since frame 0 (a slotless cell never changed).
            let history = if never_seen {
                Vec::new()
            } else {
                vec![self.cell_state(cell) as u64]
            };
            reserve_within(&mut self.histories, 1, 64, cells);
            self.histories.push(history);
        }
        slot
    }

    /// Closes the run of `old` and opens the run of `new` at `frame`.
    fn transition(
        &mut self,
        cell: usize,
        old: CellState,
        new: CellState,
        frame: u64,
        time: f64,
        previous_time: Option<f64>,
    ) {
        let slot = self.ensure_slot(cell);
        self.run_edge(slot, old, frame, true);
        if old == CellState::Unknown {
            let s = &mut self.slots[slot];
            if s.first.is_nan() {
                s.first = time;
            }
        }
        self.run_edge(slot, new, frame, false);
        if new == CellState::Unknown
            && let Some(previous) = previous_time
        {
            let s = &mut self.slots[slot];
            s.last = s.last.max(previous);
        }
        if self.config.keep_history {
            self.histories[slot].push((frame << 2) | new as u64);
        }
    }

    /// One end of a run of `state` in `slot` at `frame`: adds (`close`, the run ends) or
    /// subtracts (it begins) the prefix sums and the frame index to those of the state, so
    /// that a closed run contributes the sums of exactly its own frames. Free and fractional
    /// states keep no run sums.
    fn run_edge(&mut self, slot: usize, state: CellState, frame: u64, close: bool) {
        let f = if close { frame as i64 } else { -(frame as i64) };
        match state {
            CellState::Occupied => {
                self.edge(slot, Which::Occupied, frame, close);
                self.slots[slot].ones += f;
            }
            CellState::Unknown => {
                self.edge(slot, Which::Unknown, frame, close);
                self.slots[slot].unknown_frames += f;
            }
            CellState::Free | CellState::Fraction => {}
        }
    }

    /// `±P(frame)` (the current prefix) into accumulator `which` of `slot`: as an inline edge
    /// if it has room, else into its own block.
    fn edge(&mut self, slot: usize, which: Which, frame: u64, close: bool) {
        if frame == 0 {
            return; // P(0) = 0
        }
        let acc = self.slots[slot].acc(which);
        let inline = (frame < EDGE_FRAMES)
            .then(|| {
                let e = Edge::new(frame, close);
                match acc {
                    Acc::Zero => Some(Acc::One(e)),
                    Acc::One(a) => Some(Acc::Two(a, e)),
                    Acc::Two(..) | Acc::Owned(_) => None,
                }
            })
            .flatten();
        match inline {
            Some(new) => {
                if acc == Acc::Zero {
                    self.edge_accs += 1;
                }
                self.pending.refs += 1;
                self.pending.codes ^= which.code(slot);
                *self.slots[slot].acc_mut(which) = new;
            }
            None => {
                let at = self.own(slot, which);
                let prefix = std::mem::take(&mut self.prefix);
                self.pool.add_rows(at, &prefix, !close);
                self.prefix = prefix;
                self.rebalance();
            }
        }
    }

    /// The first entry of block `block`.
    fn block_at(&self, block: u32) -> usize {
        block as usize * self.stride()
    }

    /// Entries per block: one per period, and the sum of fractional and sparse values.
    fn stride(&self) -> usize {
        self.prefix.len() + 1
    }

    /// The most blocks in use at any time: two per cell, plus the snapshot of the frame ending.
    fn block_limit(&self) -> usize {
        2 * self.geometry.cells() + 1
    }

    /// A zero block.
    fn alloc_block(&mut self) -> u32 {
        if let Some(block) = self.free_blocks.pop() {
            return block;
        }
        let stride = self.stride();
        let block = self.pool.len() / stride;
        self.pool
            .grow(stride, 64 * stride, self.block_limit() * stride);
        block as u32
    }

    fn free_block(&mut self, block: u32) {
        let at = self.block_at(block);
        self.pool.zero(at, self.stride());
        let limit = self.block_limit();
        reserve_within(&mut self.free_blocks, 1, 64, limit);
        self.free_blocks.push(block);
    }

    /// Where the sums of `acc` are.
    fn source(&self, acc: Acc) -> Source {
        match acc {
            Acc::Zero => Source::Zero,
            Acc::Owned(block) => Source::Block(self.pool.block(self.block_at(block))),
            Acc::One(_) | Acc::Two(..) => {
                let mut edges = [None; 2];
                for (slot, edge) in edges.iter_mut().zip(acc.edges()) {
                    let frame = edge.frame();
                    let at = (u64::from(frame) != self.frames)
                        .then(|| self.pool.block(self.block_at(self.snapshots[&frame].block)));
                    *slot = Some((at, edge.adds()));
                }
                Source::Edges(edges)
            }
        }
    }

    /// The sums of period `j` of an accumulator.
    #[inline]
    fn source_value(&self, source: &Source, j: usize) -> [i128; 2] {
        match source {
            Source::Zero => [0; 2],
            Source::Block(block) => self.pool.entry(*block, j),
            Source::Edges(edges) => {
                let mut sum = [0i128; 2];
                for &(at, adds) in edges.iter().flatten() {
                    let p = match at {
                        Some(block) => self.pool.entry(block, j),
                        None => self.prefix[j],
                    };
                    if adds {
                        sum = [sum[0] + p[0], sum[1] + p[1]];
                    } else {
                        sum = [sum[0] - p[0], sum[1] - p[1]];
                    }
                }
                sum
            }
        }
    }

    /// One fewer edge names the snapshot of `edge`'s frame (`code` named it): frees it when
    /// none does.
    fn release(&mut self, edge: Edge, code: u64) {
        let frame = edge.frame();
        if u64::from(frame) == self.frames {
            self.pending.refs -= 1;
            self.pending.codes ^= code;
            return;
        }
        let snapshot = self
            .snapshots
            .get_mut(&frame)
            .expect("every inline edge has its snapshot");
        snapshot.refs -= 1;
        snapshot.codes ^= code;
        match snapshot.refs {
            0 => {
                let block = snapshot.block;
                self.snapshots.remove(&frame);
                self.singletons.remove(&frame);
                // An emptied B-tree keeps its root node: drop it, as `heap_bytes` assumes.
                if self.snapshots.is_empty() {
                    self.snapshots = BTreeMap::new();
                }
                if self.singletons.is_empty() {
                    self.singletons = BTreeSet::new();
                }
                self.free_block(block);
            }
            1 => {
                self.singletons.insert(frame);
            }
            _ => {}
        }
    }

    /// Gives accumulator `which` of `slot` a block of its own, with the sums of its edges, and
    /// returns the block's first entry. Callers [rebalance](Self::rebalance) after.
    fn own(&mut self, slot: usize, which: Which) -> usize {
        let acc = self.slots[slot].acc(which);
        if let Acc::Owned(block) = acc {
            return self.block_at(block);
        }
        let k = self.prefix.len();
        let mut sums = std::mem::take(&mut self.sums);
        let source = self.source(acc);
        sums.0.clear();
        sums.0.extend((0..k).map(|j| self.source_value(&source, j)));
        if acc.is_edges() {
            let code = which.code(slot);
            for edge in acc.edges() {
                self.release(edge, code);
            }
            self.edge_accs -= 1;
        }
        // After the release, so that a snapshot freed by it is reused.
        let block = self.alloc_block();
        let at = self.block_at(block);
        self.pool.add_rows(at, &sums.0, false);
        self.sums = sums;
        *self.slots[slot].acc_mut(which) = Acc::Owned(block);
        at
    }

    /// Keeps the snapshots no more numerous than the accumulators held as edges: while they
    /// are more, an accumulator that alone names a snapshot takes a block of its own, which
    /// frees that snapshot's block (there is one: fewer than two edges per snapshot then).
    fn rebalance(&mut self) {
        while self.snapshots.len() as u64 > self.edge_accs {
            let Some(&frame) = self.singletons.first() else {
                break;
            };
            let (slot, which) = Which::of_code(self.snapshots[&frame].codes);
            self.own(slot, which);
        }
    }

    /// One fractional observation in the current frame: `S += q(v·w)`, `Σs += q(v)`.
    fn add_fraction(&mut self, cell: usize, value: f64, time: f64, phasors: &FramePhasors) {
        let slot = self.ensure_slot(cell);
        let at = self.own(slot, Which::Occupied);
        let mut rows = std::mem::take(&mut self.sums);
        rows.0.clear();
        rows.0
            .extend(phasors.re.iter().zip(&phasors.im).map(|(&re, &im)| {
                [
                    i128::from(quantize(value * re)),
                    i128::from(quantize(value * im)),
                ]
            }));
        rows.0.push([i128::from(quantize(value)), 0]);
        self.pool.add_rows(at, &rows.0, false);
        self.sums = rows;
        let s = &mut self.slots[slot];
        if s.first.is_nan() {
            s.first = time;
        }
        self.rebalance();
    }

    /// Observes single cells at `time` (e.g. from a local map), outside any frame: each
    /// `(cells[i], values[i])` is one more observation of that cell, with `values` in `[0, 1]`.
    ///
    /// # Errors
    /// A bad or earlier time, lengths that differ, a cell outside the grid or a value outside
    /// `[0, 1]` (naming its index).
    pub fn observe_cells(
        &mut self,
        time: f64,
        cells: &[u32],
        values: &[f64],
    ) -> Result<(), GridError> {
        self.check_frame_time(time)?;
        if cells.len() != values.len() {
            return Err(ObservationError::LengthMismatch {
                times: cells.len(),
                values: values.len(),
            }
            .into());
        }
        let n = self.geometry.cells();
        if let Some(&cell) = cells.iter().find(|&&c| c as usize >= n) {
            return Err(GridError::CellIndex {
                cell: u64::from(cell),
                cells: n,
            });
        }
        for (index, &v) in values.iter().enumerate() {
            chronomap_core::observe::check_value(index, v)?;
        }
        let mut phasors = FramePhasors::default();
        phasors.compute(&self.config.fremen, time);
        let mut rows = Vec::with_capacity(self.stride());
        let quantized: Vec<[i128; 2]> = phasors
            .q
            .iter()
            .map(|q| [i128::from(q[0]), i128::from(q[1])])
            .collect();
        for (&cell, &value) in cells.iter().zip(values) {
            let slot = self.ensure_slot(cell as usize);
            let occupied = self.own(slot, Which::Occupied);
            let unknown = self.own(slot, Which::Unknown);
            rows.clear();
            rows.extend(phasors.re.iter().zip(&phasors.im).map(|(&re, &im)| {
                [
                    i128::from(quantize(value * re)),
                    i128::from(quantize(value * im)),
                ]
            }));
            rows.push([i128::from(quantize(value)), 0]);
            self.pool.add_rows(occupied, &rows, false);
            self.pool.add_rows(unknown, &quantized, true);
            let s = &mut self.slots[slot];
            s.unknown_frames -= 1;
            if s.first.is_nan() {
                s.first = time;
            }
            s.last = s.last.max(time);
        }
        self.rebalance();
        self.latest = Some(time);
        self.had_sparse = true;
        Ok(())
    }

    /// The exact accumulators and span of one cell (`None` if it was never observed).
    ///
    /// # Panics
    /// If `cell` is out of range.
    pub fn cell_sums(&self, cell: usize) -> Option<(ObservedSpan, SpectralSums)> {
        let k = self.prefix.len();
        let frames = self.frames as i64;
        let state = self.cell_state(cell);
        let (occupied_now, unknown_now) =
            (state == CellState::Occupied, state == CellState::Unknown);
        let (per_period, ones, unknown_frames, extra, first, last) = match self.slot_of[cell] {
            NONE => {
                if unknown_now {
                    return None;
                }
                let per_period = self
                    .prefix
                    .iter()
                    .map(|p| period_sums(if occupied_now { *p } else { [0; 2] }, *p))
                    .collect();
                let ones = if occupied_now { frames } else { 0 };
                (
                    per_period,
                    ones,
                    0,
                    0,
                    self.frame_span.first,
                    self.frame_span.last,
                )
            }
            slot => {
                let s = &self.slots[slot as usize];
                let (occupied, unknown) = (self.source(s.occupied), self.source(s.unknown));
                let per_period = (0..k)
                    .map(|j| {
                        let p = self.prefix[j];
                        let mut occ = self.source_value(&occupied, j);
                        if occupied_now {
                            occ = [occ[0] + p[0], occ[1] + p[1]];
                        }
                        let mut unk = self.source_value(&unknown, j);
                        if unknown_now {
                            unk = [unk[0] + p[0], unk[1] + p[1]];
                        }
                        period_sums(occ, [p[0] - unk[0], p[1] - unk[1]])
                    })
                    .collect();
                let extra = match occupied {
                    Source::Block(block) => self.pool.entry(block, k)[0],
                    _ => 0,
                };
                let ones = s.ones + if occupied_now { frames } else { 0 };
                let unknown_frames = s.unknown_frames + if unknown_now { frames } else { 0 };
                let last = if unknown_now {
                    s.last
                } else {
                    s.last.max(self.frame_span.last)
                };
                (per_period, ones, unknown_frames, extra, s.first, last)
            }
        };
        let count = frames - unknown_frames;
        if count <= 0 {
            return None;
        }
        let sum = ExactSum::from_units(i128::from(ones) * SCALE as i128 + extra);
        let span = ObservedSpan {
            count: count as u64,
            first,
            last,
        };
        let sums = SpectralSums::from_parts(
            self.config.fremen.periods.clone(),
            count as u64,
            sum,
            per_period,
        )
        .expect("one entry per period");
        Some((span, sums))
    }

    /// The FreMEn model of one cell: exactly the model a [`FremenModel`] with the grid's
    /// configuration builds from that cell's observations (`None` if never observed).
    ///
    /// # Panics
    /// If `cell` is out of range.
    pub fn cell_model(&self, cell: usize) -> Option<FremenModel> {
        let (span, sums) = self.cell_sums(cell)?;
        Some(
            FremenModel::from_parts(self.config.fremen.clone(), span, sums)
                .expect("consistent parts"),
        )
    }

    /// Whether a cell's observed values were not all equal (the cells §VI averages errors over).
    pub fn cell_changed(&self, cell: usize) -> bool {
        match self.cell_sums(cell) {
            None => false,
            Some((span, sums)) => {
                let units = sums.value_sum().units();
                units != 0 && units != i128::from(span.count as i64) * SCALE as i128
            }
        }
    }

    /// Combines grids over consecutive cell ranges (in order) that observed the same frames at
    /// the same times, e.g. built on separate threads, into one grid of `geometry`.
    ///
    /// # Errors
    /// If the parts' frames, configurations or sizes do not fit together, or the first parts do
    /// not cover whole 64-cell words.
    pub fn concat(geometry: GridGeometry, parts: Vec<FremenGrid>) -> Result<FremenGrid, GridError> {
        let incompatible = |reason: String| GridError::Incompatible { reason };
        let Some(first) = parts.first() else {
            return Err(incompatible("no parts".into()));
        };
        let total: usize = parts.iter().map(|p| p.geometry.cells()).sum();
        if total != geometry.cells() {
            return Err(incompatible(format!(
                "the parts have {total} cells, the grid {}",
                geometry.cells()
            )));
        }
        let mut grid = FremenGrid::new(geometry, first.config.clone())?;
        grid.unknown_cells = 0;
        grid.frames = first.frames;
        grid.frame_span = first.frame_span;
        grid.latest = first.latest;
        grid.prefix = first.prefix.clone();
        grid.frame_times = first.frame_times.clone();
        let stride = grid.stride();
        let mut offset = 0usize;
        for (i, part) in parts.into_iter().enumerate() {
            if part.config != grid.config
                || part.frames != grid.frames
                || part.prefix != grid.prefix
                || part.frame_span != grid.frame_span
                || part.frame_times != grid.frame_times
            {
                return Err(incompatible(format!(
                    "part {i} saw other frames or has another configuration"
                )));
            }
            if !offset.is_multiple_of(64) {
                return Err(incompatible(format!(
                    "part {i} starts at cell {offset}, not a multiple of 64"
                )));
            }
            let w0 = offset / 64;
            for (w, ((&o, &u), &f)) in part
                .occupied
                .iter()
                .zip(&part.unknown)
                .zip(&part.fraction)
                .enumerate()
            {
                grid.occupied[w0 + w] = o;
                grid.unknown[w0 + w] = u;
                grid.fraction[w0 + w] = f;
            }
            let slot_base = grid.slots.len() as u32;
            let block_base = (grid.pool.len() / stride) as u32;
            for (c, &s) in part.slot_of.iter().enumerate() {
                grid.slot_of[offset + c] = if s == NONE { NONE } else { s + slot_base };
            }
            let rebase = |acc: Acc| match acc {
                Acc::Owned(block) => Acc::Owned(block + block_base),
                other => other,
            };
            grid.slots.extend(part.slots.into_iter().map(|mut s| {
                s.cell += offset as u32;
                s.occupied = rebase(s.occupied);
                s.unknown = rebase(s.unknown);
                s
            }));
            grid.histories.extend(part.histories);
            grid.pool.append(part.pool);
            grid.free_blocks
                .extend(part.free_blocks.iter().map(|&b| b + block_base));
            for (frame, snapshot) in part.snapshots {
                let block = snapshot.block + block_base;
                match grid.snapshots.get(&frame).copied() {
                    None => {
                        grid.snapshots.insert(frame, Snapshot { block, ..snapshot });
                    }
                    Some(kept) => {
                        let (a, b) = (grid.block_at(kept.block), grid.block_at(block));
                        if (0..stride).any(|j| grid.pool.get(a + j) != grid.pool.get(b + j)) {
                            return Err(incompatible(format!(
                                "part {i} has another prefix at frame {frame}"
                            )));
                        }
                        let kept = grid.snapshots.get_mut(&frame).expect("just found");
                        kept.refs += snapshot.refs;
                        grid.free_block(block);
                    }
                }
            }
            grid.unknown_cells += part.unknown_cells;
            grid.fraction_cells += part.fraction_cells;
            grid.had_sparse |= part.had_sparse;
            offset += part.geometry.cells();
        }
        // Codes name slots, which moved: count them again.
        grid.edge_accs = 0;
        for snapshot in grid.snapshots.values_mut() {
            snapshot.codes = 0;
        }
        for (i, slot) in grid.slots.iter().enumerate() {
            for which in [Which::Occupied, Which::Unknown] {
                let acc = slot.acc(which);
                if acc.is_edges() {
                    grid.edge_accs += 1;
                }
                for edge in acc.edges() {
                    let snapshot = grid
                        .snapshots
                        .get_mut(&edge.frame())
                        .expect("parts are consistent");
                    snapshot.codes ^= which.code(i);
                }
            }
        }
        grid.singletons = grid
            .snapshots
            .iter()
            .filter(|(_, s)| s.refs == 1)
            .map(|(&f, _)| f)
            .collect();
        grid.rebalance();
        Ok(grid)
    }
}

/// How a [`FremenGrid`] holds its changing cells ([`FremenGrid::storage`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct GridStorage {
    /// Cells with a slot (changing cells).
    pub slots: usize,
    /// Accumulators (two per slot) held as inline edges.
    pub edge_accumulators: usize,
    /// Accumulators with a block of their own.
    pub owned_accumulators: usize,
    /// Frame prefixes kept for inline edges.
    pub snapshots: usize,
    /// Blocks not in use.
    pub free_blocks: usize,
    /// Width of the stored sums: 64 until a sum needed more, then 128.
    pub sum_bits: u32,
    /// Heap bytes of the blocks.
    pub pool_bytes: usize,
    /// Heap bytes of the slots.
    pub slot_bytes: usize,
}

fn period_sums(weighted: [i128; 2], unweighted: [i128; 2]) -> PeriodSums {
    PeriodSums {
        weighted_re: ExactSum::from_units(weighted[0]),
        weighted_im: ExactSum::from_units(weighted[1]),
        unweighted_re: ExactSum::from_units(unweighted[0]),
        unweighted_im: ExactSum::from_units(unweighted[1]),
    }
}

/// [`GridError::FrameLength`] for `what` unless it has the `expected` number of elements.
fn check_length(what: &'static str, expected: usize, found: usize) -> Result<(), GridError> {
    if found == expected {
        Ok(())
    } else {
        Err(GridError::FrameLength {
            what,
            expected,
            found,
        })
    }
}

/// Bits of word `w` that are cells of a grid of `cells` cells.
#[inline]
fn tail_mask(w: usize, cells: usize) -> u64 {
    let start = w * 64;
    if start + 64 <= cells {
        u64::MAX
    } else if start >= cells {
        0
    } else {
        (1u64 << (cells - start)) - 1
    }
}

fn mask_tail(words: &mut [u64], cells: usize) {
    for (w, word) in words.iter_mut().enumerate() {
        *word &= tail_mask(w, cells);
    }
}

#[cfg(test)]
mod tests;
