//! Fitted grids: the compact ("lossy") model of every cell for prediction and storage, and the
//! lossless model that adds per-cell outlier sets ([Krajník 2017] §III-B, §IV-C, §VI).

use std::f64::consts::TAU;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{CellState, FremenGrid, GridError, GridGeometry, NONE, Slot};
use chronomap_core::Parallelism;
use chronomap_core::crossings::threshold_toggles;
use chronomap_core::fft::{from_gaps, ones_in, to_gaps, xor_edges};
use chronomap_core::model::{Ordered, saturate};
use chronomap_core::observe::ObservedSpan;
use chronomap_core::periods::{PeriodSet, cycle_fraction};

/// Which order each cell's model uses.
#[derive(Clone, Debug, PartialEq)]
pub enum OrderChoice {
    /// The same order for every cell.
    Fixed(usize),
    /// One order per cell index (cells not listed use order 0).
    PerCell(Vec<u8>),
}

impl OrderChoice {
    fn order_of(&self, cell: usize) -> usize {
        match self {
            OrderChoice::Fixed(k) => *k,
            OrderChoice::PerCell(orders) => orders.get(cell).map_or(0, |&k| usize::from(k)),
        }
    }
}

/// One component of a fitted cell: `2·amplitude·cos(ω t + phase)`, stored in single precision.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompactComponent {
    /// Index of the period in the grid's period set.
    pub period: u32,
    /// `|γ|`.
    pub amplitude: f32,
    /// `arg γ`.
    pub phase: f32,
}

/// A cell with a model (all cells that ever changed or were observed late or fractionally).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FittedCell {
    /// Cell index.
    pub cell: u32,
    /// Mean `μ`.
    pub mean: f32,
    /// First of its components in [`FittedGrid::components`].
    pub start: u32,
    /// Number of components (its order).
    pub count: u8,
}

/// The compact model of a whole grid: constant cells as bits, every other cell as its mean and
/// strongest components in single precision — the "lossy" representation of [Krajník 2017] §VI. It
/// predicts the map at any time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FittedGrid {
    geometry: GridGeometry,
    periods: PeriodSet,
    /// Count and times of the frames the model was built from.
    frames: ObservedSpan,
    /// Constant cells that are occupied.
    occupied: Vec<u64>,
    /// Cells never observed.
    unknown: Vec<u64>,
    cells: Vec<FittedCell>,
    components: Vec<CompactComponent>,
}

impl FremenGrid {
    /// The compact model of every cell with the given orders ([Krajník 2017] eq. (10) per cell),
    /// fitting the changing cells on the threads `parallelism` allows (the same bits on any).
    pub fn fitted(&self, orders: OrderChoice, parallelism: Parallelism) -> FittedGrid {
        self.fitted_slots(&orders, &self.slots, parallelism)
    }

    /// Predicted occupancy probability of every cell at `time` with the configured order (NaN
    /// for cells never observed): bit for bit
    /// `self.fitted(OrderChoice::Fixed(order), parallelism).predict_map(time)`, without keeping
    /// the compact model (it holds the map and one value per changing cell,
    /// [`MemoryEstimate::predict_map_bytes`](crate::MemoryEstimate::predict_map_bytes)); the
    /// changing cells are fitted on the threads `parallelism` allows (the same bits on any).
    /// For many predictions, [`FremenGrid::fitted`] once and
    /// [`FittedGrid::predict_map`] from it; for one cell, [`FremenGrid::predict_cell`] gives
    /// the same bits.
    pub fn predict_map(&self, time: f64, parallelism: Parallelism) -> Vec<f32> {
        let order = self.config.fremen.order;
        let periods = &self.config.fremen.periods;
        let angles: Vec<f64> = (0..periods.len())
            .map(|k| angle(periods, k, time))
            .collect();
        let value = |components: &mut Vec<CompactComponent>, slot: &Slot| {
            match self.fit_slot(slot, order, components) {
                Some(mean) => saturate(cell_value(mean, components, |k| angles[k])) as f32,
                // Cleared from the constant planes: predicted free, as the compact model does.
                None => 0.0,
            }
        };
        let values: Vec<f32> = match parallelism {
            Parallelism::Sequential => {
                let mut components = Vec::new();
                self.slots
                    .iter()
                    .map(|slot| value(&mut components, slot))
                    .collect()
            }
            Parallelism::Rayon(_) => self
                .slots
                .par_iter()
                .with_min_len(min_len(self.slots.len(), parallelism))
                .map_init(Vec::new, value)
                .collect(),
        };
        let mut map: Vec<f32> = (0..self.geometry.cells())
            .map(|cell| {
                let (w, b) = (cell / 64, 1u64 << (cell % 64));
                if self.unknown[w] & b != 0 {
                    f32::NAN
                } else if self.occupied[w] & b != 0 {
                    1.0
                } else {
                    0.0
                }
            })
            .collect();
        for (slot, value) in self.slots.iter().zip(values) {
            map[slot.cell as usize] = value;
        }
        map
    }

    /// Predicted occupancy probability of one cell at each of `times` with the configured
    /// order: bit for bit the value [`FremenGrid::predict_map`] gives that cell (NaN if it was
    /// never observed), without fitting the other cells.
    ///
    /// # Panics
    /// If `cell` is out of range.
    pub fn predict_cell(&self, cell: usize, times: &[f64]) -> Vec<f32> {
        let slots = match self.slot_of[cell] {
            NONE => &[][..],
            slot => std::slice::from_ref(&self.slots[slot as usize]),
        };
        self.fitted_slots(
            &OrderChoice::Fixed(self.config.fremen.order),
            slots,
            Parallelism::Sequential,
        )
        .predict_cell(cell, times)
    }

    /// The mean of the compact model of a slot's cell with its components in `components`
    /// (its `order` strongest, single precision), or `None` if the cell was never observed.
    fn fit_slot(
        &self,
        slot: &Slot,
        order: usize,
        components: &mut Vec<CompactComponent>,
    ) -> Option<f32> {
        components.clear();
        let mut model = self.cell_model(slot.cell as usize)?;
        model.set_order(order);
        let fit = model.fit();
        components.extend(
            fit.components[..model.order().min(fit.components.len())]
                .iter()
                .map(|c| CompactComponent {
                    period: period_index(&self.config.fremen.periods, c.period_secs),
                    amplitude: c.amplitude as f32,
                    phase: c.phase as f32,
                }),
        );
        Some(fit.mean as f32)
    }

    /// The compact model of the cells of `slots` (all of the grid's, or some of them): the
    /// others of the grid's slots are left without a model, so a [`FittedGrid`] of some slots
    /// predicts those cells exactly as the [`FittedGrid`] of all slots does. Fits chunks of
    /// slots (on the threads `parallelism` allows) into arrays of the final size (one row of
    /// the largest order per slot), then closes the gaps in place.
    fn fitted_slots(
        &self,
        orders: &OrderChoice,
        slots: &[Slot],
        parallelism: Parallelism,
    ) -> FittedGrid {
        const CHUNK: usize = 1024;
        let widest = match orders {
            OrderChoice::Fixed(k) => *k,
            OrderChoice::PerCell(orders) => orders.iter().copied().max().map_or(0, usize::from),
        }
        .min(self.config.fremen.periods.len());
        let unfitted = FittedCell {
            cell: 0,
            mean: f32::NAN,
            start: 0,
            count: 0,
        };
        let blank = CompactComponent {
            period: 0,
            amplitude: 0.0,
            phase: 0.0,
        };
        let mut cells = vec![unfitted; slots.len()];
        let mut components = vec![blank; slots.len() * widest];
        let fit_chunk =
            |cells: &mut [FittedCell], rows: &mut [CompactComponent], slots: &[Slot]| {
                let mut fit = Vec::new();
                for (i, (cell, slot)) in cells.iter_mut().zip(slots).enumerate() {
                    if let Some(mean) =
                        self.fit_slot(slot, orders.order_of(slot.cell as usize), &mut fit)
                    {
                        rows[i * widest..i * widest + fit.len()].copy_from_slice(&fit);
                        *cell = FittedCell {
                            cell: slot.cell,
                            mean,
                            start: 0,
                            count: fit.len() as u8,
                        };
                    }
                }
            };
        match (parallelism, widest) {
            (Parallelism::Sequential, 0) => cells
                .chunks_mut(CHUNK)
                .zip(slots.chunks(CHUNK))
                .for_each(|(cells, slots)| fit_chunk(cells, &mut [], slots)),
            (Parallelism::Sequential, _) => cells
                .chunks_mut(CHUNK)
                .zip(components.chunks_mut(CHUNK * widest))
                .zip(slots.chunks(CHUNK))
                .for_each(|((cells, rows), slots)| fit_chunk(cells, rows, slots)),
            (Parallelism::Rayon(_), 0) => cells
                .par_chunks_mut(CHUNK)
                .zip(slots.par_chunks(CHUNK))
                .with_min_len(min_len(slots.len().div_ceil(CHUNK), parallelism))
                .for_each(|(cells, slots)| fit_chunk(cells, &mut [], slots)),
            (Parallelism::Rayon(_), _) => cells
                .par_chunks_mut(CHUNK)
                .zip(components.par_chunks_mut(CHUNK * widest))
                .zip(slots.par_chunks(CHUNK))
                .with_min_len(min_len(slots.len().div_ceil(CHUNK), parallelism))
                .for_each(|((cells, rows), slots)| fit_chunk(cells, rows, slots)),
        }
        let (mut kept, mut written) = (0, 0);
        for i in 0..cells.len() {
            let cell = cells[i];
            if cell.mean.is_nan() {
                continue;
            }
            let count = usize::from(cell.count);
            components.copy_within(i * widest..i * widest + count, written);
            cells[kept] = FittedCell {
                start: written as u32,
                ..cell
            };
            kept += 1;
            written += count;
        }
        cells.truncate(kept);
        components.truncate(written);
        cells.shrink_to_fit();
        components.shrink_to_fit();
        // Constant cells: planes of the cells without a slot.
        let mut occupied = self.occupied.clone();
        let mut unknown = self.unknown.clone();
        for slot in &self.slots {
            let (w, b) = (slot.cell as usize / 64, 1u64 << (slot.cell % 64));
            occupied[w] &= !b;
            unknown[w] &= !b;
        }
        FittedGrid {
            geometry: self.geometry,
            periods: self.config.fremen.periods.clone(),
            frames: self.frame_span,
            occupied,
            unknown,
            cells,
            components,
        }
    }

    /// Change history of a cell as `(frame, state)` pairs, starting with its state at its
    /// first frame (empty for cells constant since the first frame or never observed).
    /// Requires [`GridConfig::keep_history`](super::GridConfig::keep_history).
    pub fn history(&self, cell: usize) -> Vec<(u64, CellState)> {
        match self.slot_of[cell] {
            NONE => Vec::new(),
            slot => self.histories[slot as usize]
                .iter()
                .map(|&h| (h >> 2, state_of_code(h & 3)))
                .collect(),
        }
    }

    /// Times of the dense frames (kept with history).
    pub fn frame_times(&self) -> &[f64] {
        &self.frame_times
    }

    fn require_history(&self, what: &str) -> Result<(), GridError> {
        if !self.config.keep_history || self.frame_times.len() as u64 != self.frames {
            return Err(GridError::Unsupported(format!(
                "{what} needs a grid built with keep_history from its first frame"
            )));
        }
        Ok(())
    }
}

fn state_of_code(code: u64) -> CellState {
    match code {
        0 => CellState::Free,
        1 => CellState::Occupied,
        2 => CellState::Unknown,
        _ => CellState::Fraction,
    }
}

/// Fewest items of `items` a rayon task takes so that they split into at most
/// `parallelism.tasks()` tasks (1 for `Rayon(0)`: as many tasks as the pool wants).
fn min_len(items: usize, parallelism: Parallelism) -> usize {
    match parallelism {
        Parallelism::Rayon(0) => 1,
        _ => items.div_ceil(parallelism.tasks()).max(1),
    }
}

/// `f` of every item, in order, on the threads `parallelism` allows.
fn map_items<T: Sync, R: Send>(
    items: &[T],
    parallelism: Parallelism,
    f: impl Fn(&T) -> R + Sync + Send,
) -> Vec<R> {
    match parallelism {
        Parallelism::Sequential => items.iter().map(f).collect(),
        Parallelism::Rayon(_) => items
            .par_iter()
            .with_min_len(min_len(items.len(), parallelism))
            .map(f)
            .collect(),
    }
}

fn period_index(periods: &PeriodSet, period_secs: f64) -> u32 {
    (0..periods.len())
        .find(|&k| periods.period(k) == period_secs)
        .expect("component periods come from the set") as u32
}

/// `p(t)` of a compact cell model before saturation, given the phase angle `ω_k t` of each
/// period index `k`: one formula for whole maps, compact grids and single evaluations, so that
/// all give the same bits.
fn cell_value(mean: f32, components: &[CompactComponent], angle_of: impl Fn(usize) -> f64) -> f64 {
    f64::from(mean)
        + components
            .iter()
            .map(|c| {
                let a = angle_of(c.period as usize);
                2.0 * f64::from(c.amplitude) * (a + f64::from(c.phase)).cos()
            })
            .sum::<f64>()
}

/// Phase angle `ω_k t` of period `k` at `time`, reduced as FreMEn reduces it.
fn angle(periods: &PeriodSet, k: usize, time: f64) -> f64 {
    match periods {
        PeriodSet::Harmonics { base_secs, .. } => {
            TAU * ((k + 1) as f64 * cycle_fraction(time, *base_secs)).fract()
        }
        PeriodSet::List(list) => TAU * cycle_fraction(time, list[k]),
    }
}

impl FittedGrid {
    /// The geometry.
    pub fn geometry(&self) -> &GridGeometry {
        &self.geometry
    }

    /// Count and times of the frames the model was built from.
    pub fn frames(&self) -> ObservedSpan {
        self.frames
    }

    /// The cells with a model.
    pub fn cells(&self) -> &[FittedCell] {
        &self.cells
    }

    /// The position in [`FittedGrid::cells`] of each cell with a model, by cell index.
    fn cell_positions(&self) -> std::collections::HashMap<u32, usize> {
        self.cells
            .iter()
            .enumerate()
            .map(|(i, c)| (c.cell, i))
            .collect()
    }

    /// All components, referenced by [`FittedCell::start`].
    pub fn components(&self) -> &[CompactComponent] {
        &self.components
    }

    /// `p(t)` of a fitted cell before saturation, given the phase angle `ω_k t` of each
    /// period index `k`.
    fn value_with(&self, cell: &FittedCell, angle_of: impl Fn(usize) -> f64) -> f64 {
        let start = cell.start as usize;
        cell_value(
            cell.mean,
            &self.components[start..start + cell.count as usize],
            angle_of,
        )
    }

    /// `p(t)` of a fitted cell before saturation, from precomputed angles of every period.
    fn value(&self, cell: &FittedCell, angles: &[f64]) -> f64 {
        self.value_with(cell, |k| angles[k])
    }

    /// `p(t)` of a fitted cell before saturation at one time.
    fn value_at(&self, cell: &FittedCell, time: f64) -> f64 {
        self.value_with(cell, |k| angle(&self.periods, k, time))
    }

    /// The constant state of a cell as the planes hold it (meaningless for cells with a model).
    fn constant_cell(&self, cell: usize) -> CellState {
        let (w, b) = (cell / 64, 1u64 << (cell % 64));
        if self.unknown[w] & b != 0 {
            CellState::Unknown
        } else if self.occupied[w] & b != 0 {
            CellState::Occupied
        } else {
            CellState::Free
        }
    }

    /// The state of a cell the model holds as constant (`None` if it has a model of its own or
    /// was never observed).
    pub fn constant_state(&self, cell: usize) -> Option<bool> {
        let (w, b) = (cell / 64, 1u64 << (cell % 64));
        if self.unknown[w] & b != 0 || self.cells.iter().any(|c| c.cell as usize == cell) {
            return None;
        }
        Some(self.occupied[w] & b != 0)
    }

    /// Occupancy probability of every cell at `time` (NaN for cells never observed): the map
    /// of [Krajník 2017] §VIII at one time, bit for bit [`FremenGrid::predict_map`] of the grid
    /// it was fitted from with the same orders.
    pub fn predict_map(&self, time: f64) -> Vec<f32> {
        let cells = self.geometry.cells();
        let mut map: Vec<f32> = (0..cells).map(|c| self.constant_value(c)).collect();
        let angles = self.angles(time);
        for cell in &self.cells {
            map[cell.cell as usize] = self.fitted_value(cell, &angles);
        }
        map
    }

    /// Occupancy probability of one cell at each of `times`: bit for bit the values
    /// [`FittedGrid::predict_map`] gives that cell (NaN if it was never observed).
    ///
    /// # Panics
    /// If `cell` is out of range.
    pub fn predict_cell(&self, cell: usize, times: &[f64]) -> Vec<f32> {
        match self.cells.iter().find(|c| c.cell as usize == cell) {
            Some(fitted) => times
                .iter()
                .map(|&t| self.fitted_value(fitted, &self.angles(t)))
                .collect(),
            None => vec![self.constant_value(cell); times.len()],
        }
    }

    /// The phase angle of every period at `time`.
    fn angles(&self, time: f64) -> Vec<f64> {
        (0..self.periods.len())
            .map(|k| angle(&self.periods, k, time))
            .collect()
    }

    /// The prediction of a cell without a model of its own.
    fn constant_value(&self, cell: usize) -> f32 {
        match self.constant_cell(cell) {
            CellState::Unknown => f32::NAN,
            CellState::Occupied => 1.0,
            _ => 0.0,
        }
    }

    /// The prediction of a fitted cell, given the angles of [`FittedGrid::angles`].
    fn fitted_value(&self, cell: &FittedCell, angles: &[f64]) -> f32 {
        saturate(self.value(cell, angles)) as f32
    }

    /// A `nav_msgs/OccupancyGrid`-style map of the prediction at `time`: −1 for cells never
    /// observed, else `round(100·p)`.
    pub fn predict_occupancy(&self, time: f64) -> Vec<i8> {
        self.predict_map(time)
            .iter()
            .map(|&p| {
                if p.is_nan() {
                    -1
                } else {
                    (100.0 * p).round() as i8
                }
            })
            .collect()
    }

    /// Toggles of `s'(t_f) = p(t_f) ≥ 0.5` of a fitted cell over frames `[lo, hi)`.
    fn predicted_toggles(&self, cell: &FittedCell, times: &[f64], lo: u64, hi: u64) -> Vec<u64> {
        let comps =
            &self.components[cell.start as usize..(cell.start as usize + cell.count as usize)];
        let rate: f64 = comps
            .iter()
            .map(|c| 2.0 * f64::from(c.amplitude) * TAU / self.periods.period(c.period as usize))
            .sum();
        threshold_toggles(
            lo,
            hi,
            &|f| self.value_at(cell, times[f as usize]) - 0.5,
            &|a, b| rate * (times[b as usize] - times[a as usize]),
        )
    }
}

/// The observed history of a grid as change lists per fitted cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GridHistory {
    /// Frame times.
    pub frame_times: Vec<f64>,
    /// Per fitted cell (same order as [`FittedGrid::cells`]): toggles of "occupied".
    pub occupied: Vec<Vec<u64>>,
    /// Per fitted cell: toggles of "unknown".
    pub unknown: Vec<Vec<u64>>,
}

impl FremenGrid {
    /// The history of the cells of `fitted` as toggle lists.
    ///
    /// # Errors
    /// Without history, or if a cell had fractional or sparse observations (lossless storage
    /// and estimation errors are defined for binary frames).
    pub fn grid_history(&self, fitted: &FittedGrid) -> Result<GridHistory, GridError> {
        self.require_history("a history")?;
        let (mut occupied, mut unknown) = (Vec::new(), Vec::new());
        for cell in &fitted.cells {
            let (occ, unk) = self.cell_toggles(cell.cell as usize)?;
            occupied.push(occ);
            unknown.push(unk);
        }
        Ok(GridHistory {
            frame_times: self.frame_times.clone(),
            occupied,
            unknown,
        })
    }

    /// Toggles of "occupied" and of "unknown" of one cell over the frames, from its history.
    fn cell_toggles(&self, cell: usize) -> Result<(Vec<u64>, Vec<u64>), GridError> {
        if self.had_sparse {
            return Err(GridError::Unsupported(
                "the grid had sparse observations, which are not part of the frame history".into(),
            ));
        }
        let mut history = self.history(cell);
        if history.is_empty() {
            // A cell without history is constant since frame 0 (or never seen).
            history.push((0, self.cell_state(cell)));
        } else if history[0].0 > 0 {
            // Not observed before its first entry: unknown from frame 0.
            history.insert(0, (0, CellState::Unknown));
        }
        let (mut occ, mut unk) = (Vec::new(), Vec::new());
        let (mut was_occ, mut was_unk) = (false, false);
        for (frame, state) in history {
            if state == CellState::Fraction {
                return Err(GridError::Unsupported(format!(
                    "cell {cell} had fractional occupancy; lossless storage and estimation errors keep binary states"
                )));
            }
            let (is_occ, is_unk) = (state == CellState::Occupied, state == CellState::Unknown);
            if is_occ != was_occ {
                occ.push(frame);
            }
            if is_unk != was_unk {
                unk.push(frame);
            }
            (was_occ, was_unk) = (is_occ, is_unk);
        }
        Ok((occ, unk))
    }

    /// Estimation error of [Krajník 2017] §VI: for every cell whose observed state changed at least
    /// once, the fraction of its observed frames where `s'(t) = p(t) ≥ 0.5` of the fitted model
    /// differs from the observed state (eq. (14)), averaged over those cells. Frames in
    /// `[from, to)` only (e.g. held-back days for a prediction error). Cells are compared on
    /// the threads `parallelism` allows (the same result on any).
    ///
    /// # Errors
    /// As [`FremenGrid::grid_history`].
    pub fn estimation_error(
        &self,
        fitted: &FittedGrid,
        from: u64,
        to: u64,
        parallelism: Parallelism,
    ) -> Result<EstimationError, GridError> {
        self.require_history("an estimation error")?;
        let to = to.min(self.frames);
        let index = fitted.cell_positions();
        let per_cell: Vec<Result<Option<(u64, u64)>, GridError>> =
            map_items(&self.slots, parallelism, |slot| {
                let (occ, unk) = self.cell_toggles(slot.cell as usize)?;
                let known = to.saturating_sub(from) - ones_in(&unk, from, to);
                let occupied = ones_in(&occ, from, to);
                // Cells that changed within the range are the ones §VI averages over.
                if known == 0 || occupied == 0 || occupied == known {
                    return Ok(None);
                }
                let predicted = match index.get(&slot.cell) {
                    Some(&i) => {
                        fitted.predicted_toggles(&fitted.cells[i], &self.frame_times, from, to)
                    }
                    // Constant in the fitted model (e.g. it changed only after the model was
                    // trained): its constant state, or unknown (not counted).
                    None => match fitted.constant_state(slot.cell as usize) {
                        Some(true) => vec![from],
                        Some(false) => Vec::new(),
                        None => return Ok(None),
                    },
                };
                let mismatch = xor_edges(&occ, &predicted);
                // Mismatches on known frames: |m| − |m ∧ unknown|.
                let wrong = ones_in(&mismatch, from, to) - intersection(&mismatch, &unk, from, to);
                Ok(Some((wrong, known)))
            });
        let mut counted = Vec::new();
        for result in per_cell {
            if let Some(pair) = result? {
                counted.push(pair);
            }
        }
        let cells = counted.len();
        let mean = if cells == 0 {
            0.0
        } else {
            counted
                .iter()
                .map(|&(w, k)| w as f64 / k as f64)
                .sum::<f64>()
                / cells as f64
        };
        let (wrong, known) = counted
            .iter()
            .fold((0, 0), |(a, b), &(w, k)| (a + w, b + k));
        Ok(EstimationError {
            changed_cells: cells,
            mean_cell_error: mean,
            wrong_states: wrong,
            observed_states: known,
        })
    }

    /// Chooses each cell's order (0..=`max_order`) by its prediction error on frames
    /// `[split, frames)` ([Krajník 2017] §IV-B), predicting them with `trained` — the same grid
    /// as it was at frame `split` (a clone taken then) — and returns the orders by cell. Fits
    /// and compares on the threads `parallelism` allows (the same orders on any).
    ///
    /// # Errors
    /// As [`FremenGrid::grid_history`], or if `trained` is not this grid at an earlier frame.
    pub fn select_cell_orders(
        &self,
        trained: &FremenGrid,
        max_order: usize,
        parallelism: Parallelism,
    ) -> Result<Vec<u8>, GridError> {
        self.require_history("choosing orders")?;
        let split = trained.frames;
        if trained.geometry != self.geometry
            || trained.config.fremen.periods != self.config.fremen.periods
            || split > self.frames
        {
            return Err(GridError::Incompatible {
                reason: "the trained grid is not an earlier state of this grid".into(),
            });
        }
        let candidate = trained.fitted(OrderChoice::Fixed(max_order), parallelism);
        let full = self.fitted(OrderChoice::Fixed(0), parallelism);
        let history = self.grid_history(&full)?;
        let mut orders = vec![0u8; self.geometry.cells()];
        let index_of = candidate.cell_positions();
        let positions: Vec<usize> = (0..full.cells.len()).collect();
        let chosen: Vec<Option<(usize, u8)>> = map_items(&positions, parallelism, |&i| {
            let cell = &full.cells[i];
            let &j = index_of.get(&cell.cell)?;
            let trained_cell = candidate.cells[j];
            let occ = &history.occupied[i];
            let unk = &history.unknown[i];
            let mut best = (u64::MAX, 0u8);
            for order in 0..=usize::from(trained_cell.count) {
                let limited = FittedCell {
                    count: order as u8,
                    ..trained_cell
                };
                let predicted =
                    candidate.predicted_toggles(&limited, &history.frame_times, split, self.frames);
                let mismatch = xor_edges(occ, &predicted);
                let wrong = ones_in(&mismatch, split, self.frames)
                    - intersection(&mismatch, unk, split, self.frames);
                if wrong < best.0 {
                    best = (wrong, order as u8);
                }
            }
            Some((cell.cell as usize, best.1))
        });
        for (cell, order) in chosen.into_iter().flatten() {
            orders[cell] = order;
        }
        Ok(orders)
    }

    /// The lossless model: the compact model plus, per fitted cell, the frames where its
    /// thresholded prediction differs from the observation (Δ-encoded outlier set, eq. (7)) and
    /// its unknown runs. Fits and compares on the threads `parallelism` allows (the same
    /// bits on any).
    ///
    /// # Errors
    /// As [`FremenGrid::grid_history`].
    pub fn lossless(
        &self,
        orders: OrderChoice,
        parallelism: Parallelism,
    ) -> Result<LosslessGrid, GridError> {
        let fitted = self.fitted(orders, parallelism);
        let history = self.grid_history(&fitted)?;
        let frames = self.frames;
        let positions: Vec<usize> = (0..fitted.cells.len()).collect();
        let outliers: Vec<Vec<u64>> = map_items(&positions, parallelism, |&i| {
            xor_edges(
                &history.occupied[i],
                &fitted.predicted_toggles(&fitted.cells[i], &history.frame_times, 0, frames),
            )
        });
        Ok(LosslessGrid {
            fitted,
            frame_times: history.frame_times,
            outliers: outliers.into_iter().map(Toggles::from).collect(),
            unknown: history.unknown.into_iter().map(Toggles::from).collect(),
        })
    }
}

/// Number of positions in `[lo, hi)` where both toggle-encoded signals are 1.
fn intersection(a: &[u64], b: &[u64], lo: u64, hi: u64) -> u64 {
    // |a ∧ b| = (|a| + |b| − |a ⊕ b|) / 2.
    (ones_in(a, lo, hi) + ones_in(b, lo, hi) - ones_in(&xor_edges(a, b), lo, hi)) / 2
}

/// The estimation error of [Krajník 2017] §VI.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EstimationError {
    /// Cells whose observed state changed at least once in the range.
    pub changed_cells: usize,
    /// Mean over those cells of their fraction of wrongly estimated frames.
    pub mean_cell_error: f64,
    /// Wrongly estimated states, all those cells together.
    pub wrong_states: u64,
    /// Observed states of those cells.
    pub observed_states: u64,
}

/// Sorted positions stored as gaps (compact as varints).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Toggles(Vec<u64>);

impl From<Vec<u64>> for Toggles {
    fn from(v: Vec<u64>) -> Self {
        Toggles(v)
    }
}

impl Serialize for Toggles {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        to_gaps(&self.0).serialize(serializer)
    }
}

impl<'de> Deserialize<'de> for Toggles {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let gaps = Vec::<u64>::deserialize(deserializer)?;
        // A zero gap after the first repeats a position; an overflow before it is reported first.
        let repeat = gaps
            .iter()
            .skip(1)
            .position(|&g| g == 0)
            .map_or(gaps.len(), |i| i + 1);
        let positions = from_gaps(&gaps[..repeat])
            .ok_or_else(|| serde::de::Error::custom("toggle position overflows"))?;
        if repeat < gaps.len() {
            return Err(serde::de::Error::custom("toggle positions must increase"));
        }
        Ok(Toggles(positions))
    }
}

/// A grid stored losslessly: the compact model and per-cell outlier sets reproduce every
/// observed frame exactly ([`LosslessGrid::reconstruct_frame`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LosslessGrid {
    /// The compact model.
    pub fitted: FittedGrid,
    /// Times of the frames.
    pub frame_times: Vec<f64>,
    outliers: Vec<Toggles>,
    unknown: Vec<Toggles>,
}

impl LosslessGrid {
    /// Number of frames represented.
    pub fn frames(&self) -> u64 {
        self.frame_times.len() as u64
    }

    /// Total number of outlier toggles.
    pub fn outlier_toggles(&self) -> usize {
        self.outliers.iter().map(|t| t.0.len()).sum()
    }

    /// The observed state of every cell in frame `frame` (eq. (7) per cell).
    ///
    /// # Panics
    /// If `frame` is out of range.
    pub fn reconstruct_frame(&self, frame: u64) -> Vec<CellState> {
        assert!(frame < self.frames(), "frame {frame} out of range");
        let fitted = &self.fitted;
        let cells = fitted.geometry.cells();
        let mut states: Vec<CellState> = (0..cells).map(|c| fitted.constant_cell(c)).collect();
        let time = self.frame_times[frame as usize];
        for (i, cell) in fitted.cells.iter().enumerate() {
            let parity = |t: &Toggles| t.0.partition_point(|&p| p <= frame) % 2 == 1;
            states[cell.cell as usize] = if parity(&self.unknown[i]) {
                CellState::Unknown
            } else if (fitted.value_at(cell, time) - 0.5 >= 0.0) ^ parity(&self.outliers[i]) {
                CellState::Occupied
            } else {
                CellState::Free
            };
        }
        states
    }

    /// Checks invariants (for grids read from files).
    pub fn is_consistent(&self) -> bool {
        let n = self.fitted.cells.len();
        self.outliers.len() == n
            && self.unknown.len() == n
            && self.fitted.is_consistent()
            && self.frame_times.iter().all(|t| t.is_finite())
            && self.frame_times.windows(2).all(|w| w[0] <= w[1])
    }
}

impl FittedGrid {
    /// Checks invariants (for grids read from files).
    pub fn is_consistent(&self) -> bool {
        let words = self.geometry.words();
        let cells = self.geometry.cells();
        self.geometry.validate().is_ok()
            && self.occupied.len() == words
            && self.unknown.len() == words
            && self.cells.iter().all(|c| {
                (c.cell as usize) < cells
                    && (c.start as usize + c.count as usize) <= self.components.len()
            })
            && self
                .components
                .iter()
                .all(|c| (c.period as usize) < self.periods.len())
            && self.frames.is_consistent()
            && self.periods.clone().validated().is_ok()
            && self
                .cells
                .iter()
                .all(|c| c.mean.is_finite() && (0.0..=1.0).contains(&c.mean))
            && self
                .components
                .iter()
                .all(|c| c.amplitude.is_finite() && c.phase.is_finite())
    }
}
