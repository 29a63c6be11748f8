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
//! constants); the others get a *slot* with their run sums (allocated on their first change),
//! and an unknown-run accumulator only if they were ever unknown. Grids over disjoint cell
//! ranges that saw the same frame times can be built on separate threads and
//! [concatenated](FremenGrid::concat).
//!
//! [`build`] builds grids from sequences of frames (with the snapshots of a chronological
//! hold-out) and from sources that stream parts of the cells on separate threads; [`report`]
//! computes the error table of [Krajník 2017] §VI and other views of a built grid.
#![deny(missing_docs)]

pub mod build;
mod fitted;
pub mod report;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use chronomap_core::error::{ConfigError, ObservationError};
use chronomap_core::exact::{ExactSum, SCALE, quantize};
use chronomap_core::fremen::{FremenConfig, FremenModel};
use chronomap_core::observe::{ObservedSpan, check_time};
use chronomap_core::spectrum::{PeriodSums, SpectralSums, phasors};

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
/// fractionally or sparsely).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Slot {
    cell: u32,
    /// Index of the unknown-run accumulator in `unknown_pool`, or NONE.
    unknown: u32,
    /// Occupied frames, as run sums: `Σ_runs (b − a)` with the open run pending.
    ones: i64,
    /// Unknown frames minus sparse observations, as run sums.
    unknown_frames: i64,
    /// Σ s of fractional and sparse observations.
    extra_value: ExactSum,
    /// First observation time (NaN while never observed).
    first: f64,
    /// Latest observation time known before the cell's current unknown run.
    last: f64,
    /// Change history: `(frame << 2) | new state`, if the grid keeps history.
    history: Vec<u64>,
}

/// A spatio-temporal occupancy grid with a FreMEn model in every cell (see the
/// [module docs](self)).
///
/// ```
/// use chronomap_grid::{FremenGrid, GridConfig, GridGeometry};
/// use chronomap_core::TemporalModel;
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
/// let map = grid.predict_map(15.0 * 86_400.0 + 3.0 * 3600.0); // 3:00 two weeks later
/// assert_eq!(map[0], 1.0);
/// assert!(map[5] > 0.8 && map[1] == 0.0 && map[7].is_nan());
/// assert_eq!(grid.cell_model(5).unwrap().span().count, 14 * 24);
/// # Ok::<(), chronomap_grid::GridError>(())
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
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
    slot_of: Vec<u32>,
    slots: Vec<Slot>,
    /// Occupied-run (and fractional/sparse) phasor sums `S`, `K` entries per slot.
    occupied_pool: Vec<[i128; 2]>,
    /// Unknown-run phasor sums, `K` entries per unknown accumulator.
    unknown_pool: Vec<[i128; 2]>,
    /// Frame times, if the grid keeps history.
    frame_times: Vec<f64>,
    /// Whether sparse observations were made (they are outside the frame history).
    had_sparse: bool,
    /// Cells currently unknown (including never seen) and currently fractional: when both are
    /// zero, binary frames take a fast path that compares one bit plane.
    unknown_cells: u64,
    fraction_cells: u64,
    #[serde(skip)]
    scratch: FramePhasors,
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
        Ok(FremenGrid {
            prefix: vec![[0; 2]; config.fremen.periods.len()],
            occupied: vec![0; words],
            unknown,
            fraction: vec![0; words],
            slot_of: vec![NONE; geometry.cells()],
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
            unknown_cells: geometry.cells() as u64,
            fraction_cells: 0,
            scratch: FramePhasors::default(),
        })
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
            && self.occupied_pool.len() == self.slots.len() * k
            && (k == 0 || self.unknown_pool.len().is_multiple_of(k))
            && self.slots.iter().enumerate().all(|(i, s)| {
                (s.cell as usize) < cells
                    && self.slot_of[s.cell as usize] == i as u32
                    && (s.unknown == NONE
                        || (s.unknown as usize) < self.unknown_pool.len() / k.max(1))
            })
            && self
                .slot_of
                .iter()
                .all(|&s| s == NONE || (s as usize) < self.slots.len())
            && (!self.config.keep_history || self.frame_times.len() as u64 == self.frames)
            && self.unknown_cells == popcount(&self.unknown)
            && self.fraction_cells == popcount(&self.fraction)
            && self.frame_span.count == self.frames
            && self.frame_span.is_consistent()
            && self.latest.is_none_or(f64::is_finite)
            && self.frame_times.iter().all(|t| t.is_finite())
            && self.frame_times.windows(2).all(|w| w[0] <= w[1])
    }

    /// Approximate heap memory used, in bytes.
    pub fn memory_bytes(&self) -> usize {
        let planes = 3 * self.occupied.len() * 8;
        let slot_index = self.slot_of.len() * 4;
        let slots = self.slots.len() * std::mem::size_of::<Slot>()
            + self
                .slots
                .iter()
                .map(|s| s.history.capacity() * 8)
                .sum::<usize>();
        let pools = (self.occupied_pool.len() + self.unknown_pool.len()) * 32;
        planes + slot_index + slots + pools + self.frame_times.len() * 8
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

    /// Adds the frame's phasors to the prefix and records the frame.
    fn finish_frame(&mut self, time: f64, phasors: FramePhasors) {
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
        let k = self.prefix.len();
        self.occupied_pool
            .extend(std::iter::repeat_n([0i128; 2], k));
        self.slots.push(Slot {
            cell: cell as u32,
            unknown: NONE,
            ones: 0,
            unknown_frames: 0,
            extra_value: ExactSum::default(),
            first: if never_seen {
                f64::NAN
            } else {
                self.frame_span.first
            },
            last: f64::NEG_INFINITY,
            history: Vec::new(),
        });
        let slot = self.slots.len() - 1;
        self.slot_of[cell] = slot as u32;
        if self.config.keep_history && !never_seen {
            // The state it has had since frame 0 (a slotless cell never changed).
            let state = self.cell_state(cell) as u64;
            self.slots[slot].history.push(state);
        }
        slot
    }

    fn ensure_unknown(&mut self, slot: usize) -> usize {
        if self.slots[slot].unknown == NONE {
            let k = self.prefix.len();
            self.slots[slot].unknown = (self.unknown_pool.len() / k) as u32;
            self.unknown_pool.extend(std::iter::repeat_n([0i128; 2], k));
        }
        self.slots[slot].unknown as usize
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
            self.slots[slot].history.push((frame << 2) | new as u64);
        }
    }

    /// One end of a run of `state` in `slot` at `frame`: adds (`close`, the run ends) or
    /// subtracts (it begins) the prefix sums and the frame index to those of the state, so
    /// that a closed run contributes the sums of exactly its own frames. Free and fractional
    /// states keep no run sums.
    fn run_edge(&mut self, slot: usize, state: CellState, frame: u64, close: bool) {
        let k = self.prefix.len();
        let f = if close { frame as i64 } else { -(frame as i64) };
        match state {
            CellState::Occupied => {
                add_rows(
                    &mut self.occupied_pool[slot * k..(slot + 1) * k],
                    &self.prefix,
                    close,
                );
                self.slots[slot].ones += f;
            }
            CellState::Unknown => {
                let u = self.ensure_unknown(slot);
                add_rows(
                    &mut self.unknown_pool[u * k..(u + 1) * k],
                    &self.prefix,
                    close,
                );
                self.slots[slot].unknown_frames += f;
            }
            CellState::Free | CellState::Fraction => {}
        }
    }

    /// One fractional observation in the current frame: `S += q(v·w)`, `Σs += q(v)`.
    fn add_fraction(&mut self, cell: usize, value: f64, time: f64, phasors: &FramePhasors) {
        let slot = self.ensure_slot(cell);
        let k = self.prefix.len();
        for (row, (&re, &im)) in self.occupied_pool[slot * k..(slot + 1) * k]
            .iter_mut()
            .zip(phasors.re.iter().zip(&phasors.im))
        {
            row[0] += i128::from(quantize(value * re));
            row[1] += i128::from(quantize(value * im));
        }
        let s = &mut self.slots[slot];
        s.extra_value.add(value);
        if s.first.is_nan() {
            s.first = time;
        }
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
        let k = self.prefix.len();
        for (&cell, &value) in cells.iter().zip(values) {
            let slot = self.ensure_slot(cell as usize);
            let u = self.ensure_unknown(slot);
            for j in 0..k {
                let s = &mut self.occupied_pool[slot * k + j];
                s[0] += i128::from(quantize(value * phasors.re[j]));
                s[1] += i128::from(quantize(value * phasors.im[j]));
                let u = &mut self.unknown_pool[u * k + j];
                u[0] -= i128::from(phasors.q[j][0]);
                u[1] -= i128::from(phasors.q[j][1]);
            }
            let s = &mut self.slots[slot];
            s.unknown_frames -= 1;
            s.extra_value.add(value);
            if s.first.is_nan() {
                s.first = time;
            }
            s.last = s.last.max(time);
        }
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
                    ExactSum::default(),
                    self.frame_span.first,
                    self.frame_span.last,
                )
            }
            slot => {
                let s = &self.slots[slot as usize];
                let per_period = (0..k)
                    .map(|j| {
                        let p = self.prefix[j];
                        let mut occ = self.occupied_pool[slot as usize * k + j];
                        if occupied_now {
                            occ = [occ[0] + p[0], occ[1] + p[1]];
                        }
                        let mut unk = if s.unknown == NONE {
                            [0; 2]
                        } else {
                            self.unknown_pool[s.unknown as usize * k + j]
                        };
                        if unknown_now {
                            unk = [unk[0] + p[0], unk[1] + p[1]];
                        }
                        period_sums(occ, [p[0] - unk[0], p[1] - unk[1]])
                    })
                    .collect();
                let ones = s.ones + if occupied_now { frames } else { 0 };
                let unknown_frames = s.unknown_frames + if unknown_now { frames } else { 0 };
                let last = if unknown_now {
                    s.last
                } else {
                    s.last.max(self.frame_span.last)
                };
                (
                    per_period,
                    ones,
                    unknown_frames,
                    s.extra_value,
                    s.first,
                    last,
                )
            }
        };
        let count = frames - unknown_frames;
        if count <= 0 {
            return None;
        }
        let sum = ExactSum::from_units(i128::from(ones) * SCALE as i128 + extra.units());
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

    /// Predicted occupancy probability of every cell at `time` with the configured order (NaN
    /// for cells never observed). For many predictions, [`FremenGrid::fitted`] once and predict
    /// from the [`FittedGrid`]; for one cell, [`FremenGrid::predict_cell`] gives the same bits.
    pub fn predict_map(&self, time: f64) -> Vec<f32> {
        self.fitted(OrderChoice::Fixed(self.config.fremen.order))
            .predict(time)
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
        let k = grid.prefix.len();
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
            let unknown_base = (grid.unknown_pool.len() / k.max(1)) as u32;
            for (c, &s) in part.slot_of.iter().enumerate() {
                grid.slot_of[offset + c] = if s == NONE { NONE } else { s + slot_base };
            }
            for mut s in part.slots {
                s.cell += offset as u32;
                if s.unknown != NONE {
                    s.unknown += unknown_base;
                }
                grid.slots.push(s);
            }
            grid.unknown_cells += part.unknown_cells;
            grid.fraction_cells += part.fraction_cells;
            grid.occupied_pool.extend(part.occupied_pool);
            grid.unknown_pool.extend(part.unknown_pool);
            grid.had_sparse |= part.had_sparse;
            offset += part.geometry.cells();
        }
        Ok(grid)
    }
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

/// `rows += prefix` (`add`) or `rows -= prefix`, element-wise: closing or opening a run.
#[inline]
fn add_rows(rows: &mut [[i128; 2]], prefix: &[[i128; 2]], add: bool) {
    if add {
        for (r, p) in rows.iter_mut().zip(prefix) {
            r[0] += p[0];
            r[1] += p[1];
        }
    } else {
        for (r, p) in rows.iter_mut().zip(prefix) {
            r[0] -= p[0];
            r[1] -= p[1];
        }
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
