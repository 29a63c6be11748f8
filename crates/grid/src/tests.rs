use super::*;
use chronomap_core::Parallelism;
use chronomap_core::model::TemporalModel;
use chronomap_core::periods::PeriodSet;

/// xorshift64* — deterministic test randomness.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// A frame as the grid receives it, and the observations it means per cell.
enum Input {
    Occupancy(Vec<i8>),
    Bits(Vec<u64>, Option<Vec<u64>>),
    Sparse(Vec<u32>, Vec<f64>),
}

/// Per-cell behaviours: static, flipping, sometimes unknown, fractional, never seen, late.
fn cell_value(rng: &mut Rng, cell: usize, frame: usize, binary: bool) -> i8 {
    match cell % 9 {
        0 => 0,
        1 => 100,
        2 => {
            if (frame / 7 + cell).is_multiple_of(3) {
                100
            } else {
                0
            }
        }
        3 => {
            if rng.below(5) == 0 {
                -1
            } else if rng.below(2) == 0 {
                100
            } else {
                0
            }
        }
        4 if !binary => [0, 35, 100, 70][rng.below(4) as usize],
        5 => -1,
        6 => {
            if frame < 40 {
                -1
            } else if (frame / 5).is_multiple_of(2) {
                100
            } else {
                0
            }
        }
        7 => {
            if frame % 50 == 49 {
                -1
            } else {
                100
            }
        }
        _ => {
            if rng.below(10) == 0 {
                100
            } else {
                0
            }
        }
    }
}

fn scenario(cells: usize, frames: usize, binary: bool, seed: u64) -> Vec<(f64, Input)> {
    let mut rng = Rng(seed);
    let mut t = 1_451_865_600.0;
    let mut out = Vec::new();
    for frame in 0..frames {
        t += 600.0 + rng.below(3000) as f64;
        let values: Vec<i8> = (0..cells)
            .map(|c| cell_value(&mut rng, c, frame, binary))
            .collect();
        if frame % 3 == 1 {
            let words = cells.div_ceil(64);
            let (mut occ, mut known) = (vec![0u64; words], vec![0u64; words]);
            for (c, &v) in values.iter().enumerate() {
                if v >= 0 {
                    known[c / 64] |= 1 << (c % 64);
                }
                if v >= 50 {
                    occ[c / 64] |= 1 << (c % 64);
                }
            }
            out.push((t, Input::Bits(occ, Some(known))));
        } else {
            out.push((t, Input::Occupancy(values)));
        }
        if !binary && frame % 17 == 5 {
            t += 10.0;
            let picked: Vec<u32> = (0..4).map(|_| rng.below(cells as u64) as u32).collect();
            let values = picked.iter().map(|&c| f64::from(c % 3) / 2.0).collect();
            out.push((t, Input::Sparse(picked, values)));
        }
    }
    out
}

/// Feeds the scenario to a grid, and each cell's own observations to its own FremenModel.
fn build(
    geometry: GridGeometry,
    config: GridConfig,
    inputs: &[(f64, Input)],
) -> (FremenGrid, Vec<FremenModel>) {
    let cells = geometry.cells();
    let mut grid = FremenGrid::new(geometry, config.clone()).unwrap();
    let mut models: Vec<FremenModel> = (0..cells)
        .map(|_| FremenModel::new(config.fremen.clone()).unwrap())
        .collect();
    for (t, input) in inputs {
        // The storage invariants (blocks, snapshots, their bound) hold after every input.
        assert!(grid.is_consistent(), "before the input at {t}");
        match input {
            Input::Occupancy(values) => {
                grid.observe_occupancy(*t, values).unwrap();
                for (c, &v) in values.iter().enumerate() {
                    if v >= 0 {
                        models[c].observe(&[*t], &[f64::from(v) / 100.0]).unwrap();
                    }
                }
            }
            Input::Bits(occ, known) => {
                grid.observe_bits(*t, occ, known.as_deref()).unwrap();
                for (c, model) in models.iter_mut().enumerate() {
                    let bit = 1u64 << (c % 64);
                    if known.as_ref().is_none_or(|k| k[c / 64] & bit != 0) {
                        let v = if occ[c / 64] & bit != 0 { 1.0 } else { 0.0 };
                        model.observe(&[*t], &[v]).unwrap();
                    }
                }
            }
            Input::Sparse(picked, values) => {
                grid.observe_cells(*t, picked, values).unwrap();
                for (&c, &v) in picked.iter().zip(values) {
                    models[c as usize].observe(&[*t], &[v]).unwrap();
                }
            }
        }
    }
    assert!(grid.is_consistent());
    (grid, models)
}

#[test]
fn every_cell_equals_cell_by_cell_fremen_exactly() {
    let geometry = GridGeometry::planar(7, 11, 0.1, [-1.0, 2.0]).unwrap();
    let config = GridConfig::default();
    let inputs = scenario(geometry.cells(), 300, false, 7);
    let (grid, models) = build(geometry, config, &inputs);
    let mut seen = 0;
    for (c, model) in models.iter().enumerate() {
        match grid.cell_model(c) {
            None => assert_eq!(
                model.span().count,
                0,
                "cell {c} observed but the grid has no model"
            ),
            Some(from_grid) => {
                seen += 1;
                assert_eq!(
                    &from_grid, model,
                    "cell {c} differs from cell-by-cell FreMEn"
                );
                let t = 1_460_000_000.0 + 777.0 * c as f64;
                assert_eq!(from_grid.predict(t).to_bits(), model.predict(t).to_bits());
            }
        }
    }
    assert!(seen > 60, "{seen} cells observed");
}

#[test]
fn predicted_maps_equal_the_cell_models() {
    let geometry = GridGeometry::planar(9, 8, 0.05, [0.0, 0.0]).unwrap();
    let inputs = scenario(geometry.cells(), 200, false, 11);
    let (grid, models) = build(geometry, of_order(3, false), &inputs);
    let t = 1_461_000_000.0;
    let map = grid.predict_map(t, Parallelism::Sequential);
    for (c, model) in models.iter().enumerate() {
        if model.span().count == 0 {
            assert!(map[c].is_nan());
        } else {
            assert!(
                (f64::from(map[c]) - model.predict(t)).abs() < 1e-5,
                "cell {c}"
            );
        }
    }
}

#[test]
fn per_cell_predictions_equal_the_whole_map_bit_for_bit() {
    // Unknown, constant, changing, fractional and sparsely observed cells.
    let geometry = GridGeometry::planar(9, 8, 0.05, [0.0, 0.0]).unwrap();
    let inputs = scenario(geometry.cells(), 200, false, 11);
    let (grid, _) = build(geometry, of_order(3, false), &inputs);
    let times = [1_461_000_000.0, 1_461_003_777.5, 0.0, -86_400.0, 1e12];
    let maps: Vec<Vec<f32>> = times
        .iter()
        .map(|&t| grid.predict_map(t, Parallelism::Rayon(0)))
        .collect();
    let orders = OrderChoice::PerCell((0..geometry.cells()).map(|c| (c % 4) as u8).collect());
    let fitted = grid.fitted(orders, Parallelism::Rayon(0));
    let fitted_maps: Vec<Vec<f32>> = times.iter().map(|&t| fitted.predict_map(t)).collect();
    let bits = |v: &[f32]| v.iter().map(|p| p.to_bits()).collect::<Vec<_>>();
    let (mut nan, mut modelled) = (0, 0);
    for c in 0..geometry.cells() {
        let whole: Vec<f32> = maps.iter().map(|m| m[c]).collect();
        assert_eq!(
            bits(&grid.predict_cell(c, &times)),
            bits(&whole),
            "cell {c}"
        );
        let whole: Vec<f32> = fitted_maps.iter().map(|m| m[c]).collect();
        assert_eq!(
            bits(&fitted.predict_cell(c, &times)),
            bits(&whole),
            "cell {c}"
        );
        nan += usize::from(whole[0].is_nan());
        modelled += usize::from(grid.cell_changed(c));
    }
    assert!(
        nan > 0 && modelled > 10,
        "{nan} unknown, {modelled} changing cells"
    );
    assert!(grid.predict_cell(0, &[]).is_empty());
}

#[test]
fn grids_built_on_parts_concatenate_to_the_whole() {
    let whole = GridGeometry::planar(141, 1, 1.0, [0.0, 0.0]).unwrap();
    let inputs = scenario(141, 120, true, 3);
    let (grid, _) = build(whole, GridConfig::default(), &inputs);
    let split = |range: std::ops::Range<usize>| -> Vec<(f64, Input)> {
        inputs
            .iter()
            .map(|(t, input)| {
                let part = match input {
                    Input::Occupancy(v) => Input::Occupancy(v[range.clone()].to_vec()),
                    Input::Bits(o, k) => {
                        let w = range.start / 64..range.end.div_ceil(64);
                        Input::Bits(o[w.clone()].to_vec(), k.as_ref().map(|k| k[w].to_vec()))
                    }
                    Input::Sparse(..) => unreachable!("binary scenario has no sparse input"),
                };
                (*t, part)
            })
            .collect()
    };
    let left_geometry = GridGeometry::planar(128, 1, 1.0, [0.0, 0.0]).unwrap();
    let right_geometry = GridGeometry::planar(13, 1, 1.0, [128.0, 0.0]).unwrap();
    let (left, _) = build(left_geometry, GridConfig::default(), &split(0..128));
    let (right, _) = build(right_geometry, GridConfig::default(), &split(128..141));
    let joined = FremenGrid::concat(whole, vec![left.clone(), right]).unwrap();
    for c in 0..141 {
        assert_eq!(joined.cell_model(c), grid.cell_model(c), "cell {c}");
    }
    assert!(FremenGrid::concat(whole, vec![left]).is_err());
}

#[test]
fn lossless_grids_reconstruct_every_frame() {
    let geometry = GridGeometry::planar(10, 9, 0.1, [0.0, 0.0]).unwrap();
    let inputs = scenario(geometry.cells(), 250, true, 5);
    let (grid, _) = build(geometry, of_order(2, true), &inputs);
    // Constant cells (classes 0 and 1) cost no per-cell storage; changing ones do.
    for c in 0..geometry.cells() {
        let constant = c % 9 <= 1;
        assert_eq!(grid.slot_of[c] == NONE, constant || c % 9 == 5, "cell {c}");
    }
    let lossless = grid
        .lossless(OrderChoice::Fixed(2), Parallelism::Rayon(0))
        .unwrap();
    assert!(lossless.is_consistent());
    for (frame, (_, input)) in inputs.iter().enumerate() {
        let states = lossless.reconstruct_frame(frame as u64);
        let expected: Vec<CellState> = match input {
            Input::Occupancy(v) => v
                .iter()
                .map(|&v| match v {
                    -1 => CellState::Unknown,
                    100 => CellState::Occupied,
                    _ => CellState::Free,
                })
                .collect(),
            Input::Bits(o, k) => (0..geometry.cells())
                .map(|c| {
                    let bit = 1u64 << (c % 64);
                    if k.as_ref().is_some_and(|k| k[c / 64] & bit == 0) {
                        CellState::Unknown
                    } else if o[c / 64] & bit != 0 {
                        CellState::Occupied
                    } else {
                        CellState::Free
                    }
                })
                .collect(),
            Input::Sparse(..) => unreachable!(),
        };
        assert_eq!(states, expected, "frame {frame}");
    }
    // Fractional frames cannot be stored losslessly.
    let (fractional, _) = build(geometry, with_history(), &scenario(90, 50, false, 1));
    assert!(
        fractional
            .lossless(OrderChoice::Fixed(1), Parallelism::Sequential)
            .is_err()
    );
}

/// Cell models of FreMEn order `order`, keeping every frame or not.
fn of_order(order: usize, keep_history: bool) -> GridConfig {
    GridConfig {
        fremen: FremenConfig::with_order(order),
        keep_history,
    }
}

/// The default configuration, keeping every frame (for estimation errors and lossless grids).
pub(crate) fn with_history() -> GridConfig {
    GridConfig {
        keep_history: true,
        ..GridConfig::default()
    }
}

/// An empty `width × 1` strip of 1 m cells that keeps its history.
fn history_strip(width: u32) -> FremenGrid {
    let geometry = GridGeometry::planar(width, 1, 1.0, [0.0, 0.0]).unwrap();
    FremenGrid::new(geometry, with_history()).unwrap()
}

/// Observes the hourly frames `hours`: frame `h`, taken at `3600 h` s, is `frame(h)`.
fn observe_hours(
    grid: &mut FremenGrid,
    hours: std::ops::Range<u32>,
    mut frame: impl FnMut(u32) -> Vec<i8>,
) {
    for h in hours {
        grid.observe_occupancy(3600.0 * f64::from(h), &frame(h))
            .unwrap();
    }
}

#[test]
fn estimation_error_counts_mispredicted_states_of_changing_cells() {
    // One cell occupied 8:00-18:00 every day, one constant, one never seen; hourly frames for
    // four weeks. Order 0 (the majority state, free) is wrong 10/24 of the time.
    let mut grid = history_strip(3);
    observe_hours(&mut grid, 0..28 * 24, |h| {
        let hour = h % 24;
        let door = if (8..18).contains(&hour) { 100 } else { 0 };
        vec![door, 100, -1]
    });
    let frames = grid.frames();
    let static_error = grid
        .estimation_error(
            &grid.fitted(OrderChoice::Fixed(0), Parallelism::Sequential),
            0,
            frames,
            Parallelism::Sequential,
        )
        .unwrap();
    assert_eq!(static_error.changed_cells, 1);
    assert!((static_error.mean_cell_error - 10.0 / 24.0).abs() < 1e-12);
    let fremen = grid
        .estimation_error(
            &grid.fitted(OrderChoice::Fixed(4), Parallelism::Rayon(0)),
            0,
            frames,
            Parallelism::Rayon(0),
        )
        .unwrap();
    assert!(
        fremen.mean_cell_error < 0.1 * static_error.mean_cell_error,
        "{fremen:?}"
    );
}

#[test]
fn per_cell_orders_are_chosen_on_held_back_frames() {
    let mut grid = history_strip(2);
    let mut rng = Rng(9);
    let mut frame = |h: u32| {
        let daily = if (8..18).contains(&(h % 24)) { 100 } else { 0 };
        // Cell 1 is noise around a low mean: no periodic component predicts it.
        let noise = if rng.below(5) == 0 { 100 } else { 0 };
        vec![daily, noise]
    };
    observe_hours(&mut grid, 0..21 * 24, &mut frame);
    let trained = grid.clone();
    observe_hours(&mut grid, 21 * 24..28 * 24, &mut frame);
    let orders = grid
        .select_cell_orders(&trained, 5, Parallelism::Rayon(0))
        .unwrap();
    assert!(orders[0] >= 1, "{orders:?}");
    assert_eq!(orders[1], 0, "{orders:?}");
}

#[test]
fn bad_frames_are_rejected_and_change_nothing() {
    let geometry = GridGeometry::planar(5, 5, 0.1, [0.0, 0.0]).unwrap();
    let mut grid = FremenGrid::new(geometry, GridConfig::default()).unwrap();
    grid.observe_occupancy(100.0, &[0; 25]).unwrap();
    let before = grid.clone();
    let errors = [
        grid.observe_occupancy(200.0, &[0; 24]).unwrap_err(),
        grid.observe_occupancy(200.0, &{
            let mut v = [0i8; 25];
            v[7] = 101;
            v
        })
        .unwrap_err(),
        grid.observe_occupancy(200.0, &[-1; 25]).unwrap_err(),
        grid.observe_occupancy(50.0, &[0; 25]).unwrap_err(),
        grid.observe_occupancy(f64::NAN, &[0; 25]).unwrap_err(),
        grid.observe_bits(200.0, &[], None).unwrap_err(),
        grid.observe_bits(200.0, &[0], Some(&[0])).unwrap_err(),
        grid.observe_cells(200.0, &[25], &[1.0]).unwrap_err(),
        grid.observe_cells(200.0, &[3], &[1.5]).unwrap_err(),
    ];
    assert!(matches!(
        errors[0],
        GridError::FrameLength {
            expected: 25,
            found: 24,
            ..
        }
    ));
    assert!(matches!(
        errors[1],
        GridError::CellValue {
            cell: 7,
            value: 101
        }
    ));
    assert!(matches!(errors[2], GridError::NothingObserved { .. }));
    assert!(matches!(
        errors[3],
        GridError::Observation(ObservationError::TimeNotIncreasing { .. })
    ));
    assert!(matches!(errors[6], GridError::NothingObserved { .. }));
    assert!(matches!(errors[7], GridError::CellIndex { cell: 25, .. }));
    assert_eq!(grid, before);
    assert!(GridGeometry::planar(0, 5, 0.1, [0.0, 0.0]).is_err());
    assert!(GridGeometry::planar(5, 5, -0.1, [0.0, 0.0]).is_err());
}

#[test]
fn fully_observed_binary_frames_take_the_fast_path_exactly() {
    let geometry = GridGeometry::planar(200, 1, 1.0, [0.0, 0.0]).unwrap();
    let config = GridConfig::default();
    let mut rng = Rng(21);
    let mut inputs = Vec::new();
    let mut bits = vec![0u64; 4];
    let mut t = 1_000_000.0;
    for frame in 0..400 {
        t += 5.0;
        for _ in 0..3 {
            let c = rng.below(40) as usize * 5; // a fifth of the cells change
            bits[c / 64] ^= 1 << (c % 64);
        }
        if frame == 200 {
            // One frame with an unknown cell and a fraction leaves the fast path for a while.
            let mut values: Vec<i8> = (0..200)
                .map(|c| {
                    if bits[c / 64] >> (c % 64) & 1 == 1 {
                        100
                    } else {
                        0
                    }
                })
                .collect();
            values[3] = -1;
            values[4] = 50;
            inputs.push((t, Input::Occupancy(values)));
        } else {
            // Garbage past the last cell must be ignored.
            let mut frame_bits = bits.clone();
            frame_bits[3] |= 1 << 63;
            inputs.push((t, Input::Bits(frame_bits, None)));
        }
    }
    let (grid, models) = build(geometry, config, &inputs);
    assert_eq!((grid.unknown_cells, grid.fraction_cells), (0, 0));
    for (c, model) in models.iter().enumerate() {
        assert_eq!(grid.cell_model(c).as_ref(), Some(model), "cell {c}");
    }
    assert!(grid.dynamic_cells() <= 42, "{} slots", grid.dynamic_cells());
}

/// Heap bytes allocated and not freed by the current thread (a counting global allocator for
/// this test binary), to check [`FremenGrid::heap_bytes`] against.
mod counting {
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::cell::Cell;

    thread_local! {
        static LIVE: Cell<isize> = const { Cell::new(0) };
    }

    fn count(bytes: isize) {
        let _ = LIVE.try_with(|live| live.set(live.get() + bytes));
    }

    /// The live heap bytes of this thread.
    pub fn live() -> isize {
        LIVE.with(Cell::get)
    }

    struct Counting;

    // SAFETY: every call is forwarded to `System` unchanged; only sizes are counted.
    unsafe impl GlobalAlloc for Counting {
        unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
            count(layout.size() as isize);
            // SAFETY: as the caller guarantees for this call.
            unsafe { System.alloc(layout) }
        }
        unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
            count(layout.size() as isize);
            // SAFETY: as the caller guarantees for this call.
            unsafe { System.alloc_zeroed(layout) }
        }
        unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
            count(-(layout.size() as isize));
            // SAFETY: as the caller guarantees for this call.
            unsafe { System.dealloc(ptr, layout) }
        }
        unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
            count(new_size as isize - layout.size() as isize);
            // SAFETY: as the caller guarantees for this call.
            unsafe { System.realloc(ptr, layout, new_size) }
        }
    }

    #[global_allocator]
    static COUNTING: Counting = Counting;
}

/// `(heap_bytes, its part counted exactly, the heap the allocator saw)` of the grid `make`
/// builds on this thread.
fn measured(make: impl FnOnce() -> FremenGrid) -> (usize, usize, usize, FremenGrid) {
    let before = counting::live();
    let grid = make();
    let allocated = (counting::live() - before) as usize;
    let heap = grid.heap_bytes();
    (heap, heap - grid.index_bytes(), allocated, grid)
}

#[test]
fn heap_bytes_are_what_the_allocator_holds() {
    // Late, changing, fractional and sparse cells, with and without history.
    for config in [GridConfig::default(), of_order(3, true)] {
        let geometry = GridGeometry::planar(23, 9, 0.1, [0.0, 0.0]).unwrap();
        let inputs = scenario(geometry.cells(), 150, false, 13);
        let (heap, exact, allocated, grid) = measured(|| build(geometry, config, &inputs).0);
        assert!(
            exact <= allocated && allocated <= heap,
            "exact part {exact} <= allocated {allocated} <= heap_bytes {heap}"
        );
        assert!(grid.storage().owned_accumulators > 0);
    }
    // An empty grid holds exactly its fixed part, and so does one whose cells never change.
    let geometry = GridGeometry::planar(300, 7, 0.1, [0.0, 0.0]).unwrap();
    let config = of_order(2, false);
    let estimate = FremenGrid::memory_estimate(&geometry, &config);
    let (heap, exact, allocated, _) = measured(|| {
        let mut grid = FremenGrid::new(geometry, config.clone()).unwrap();
        for f in 0..5 {
            grid.observe_occupancy(60.0 * f as f64, &vec![0; 2100])
                .unwrap();
        }
        grid
    });
    let fixed = estimate.fixed_bytes as usize;
    assert_eq!((heap, exact, allocated), (fixed, fixed, fixed));
}

/// A `cells × 1` grid over `frames` frames in which every cell changes in every frame, every
/// third frame through unknown, so that both accumulators of every cell take blocks.
fn churning(cells: u32, frames: u32, config: GridConfig) -> FremenGrid {
    let geometry = GridGeometry::planar(cells, 1, 1.0, [0.0, 0.0]).unwrap();
    let mut grid = FremenGrid::new(geometry, config).unwrap();
    for f in 0..frames {
        let frame: Vec<i8> = (0..cells)
            .map(|c| match (f + c) % 3 {
                0 => 100,
                1 => 0,
                _ => -1,
            })
            .collect();
        grid.observe_occupancy(1e9 + 300.0 * f64::from(f), &frame)
            .unwrap();
    }
    grid
}

#[test]
fn memory_estimates_bound_what_grids_hold() {
    for config in [
        GridConfig::default(),
        GridConfig {
            fremen: FremenConfig {
                periods: "day".parse().unwrap(),
                order: 2,
                ..FremenConfig::default()
            },
            keep_history: false,
        },
    ] {
        let k = config.fremen.periods.len() as u64;
        // A few changes: slots only, every accumulator held as edges.
        let few = churning(1000, 3, config.clone());
        let storage = few.storage();
        assert_eq!(
            (storage.slots, storage.owned_accumulators, storage.sum_bits),
            (1000, 0, 64)
        );
        let estimate = FremenGrid::memory_estimate(few.geometry(), few.config());
        assert_eq!(estimate.cell_bytes_inline, 64);
        assert_eq!(config.bytes_per_changing_cell(), estimate.cell_bytes_wide);
        // Slots, and the two snapshots (frames 1 and 2) every cell shares.
        let snapshots = 2 * (k + 1) * 16 + SNAPSHOT_NODE_BYTES as u64;
        let expected = estimate.fixed_bytes + 1000 * 64 + snapshots;
        let heap = few.heap_bytes() as u64;
        assert!(
            heap >= expected && heap <= expected + 63 * 64 + 64 * (k + 1) * 16,
            "{heap} vs {expected}"
        );
        // Many changes: two blocks per cell, within the narrow and the worst-case bounds.
        let many = churning(1000, 40, config.clone());
        let storage = many.storage();
        assert_eq!((storage.owned_accumulators, storage.sum_bits), (2000, 64));
        let heap = many.heap_bytes() as u64;
        let narrow = estimate.with_changing_cells(1000, estimate.cell_bytes_narrow);
        assert!(
            heap <= narrow && narrow < estimate.worst_case_bytes,
            "{heap} {narrow}"
        );
        assert!(heap >= estimate.fixed_bytes + 1000 * (64 + 2 * (k + 1) * 16));
    }
}

#[test]
fn sums_widen_to_128_bits_exactly_when_they_leave_64() {
    // One period of a year sampled every second: its prefix grows by almost 2^50 a frame and
    // leaves 64 bits after about 8,200 frames.
    let config = GridConfig {
        fremen: FremenConfig {
            periods: PeriodSet::from_periods(vec![365.25 * 86_400.0, 3600.0]).unwrap(),
            order: 2,
            ..FremenConfig::default()
        },
        keep_history: false,
    };
    let geometry = GridGeometry::planar(4, 1, 1.0, [0.0, 0.0]).unwrap();
    let mut grid = FremenGrid::new(geometry, config.clone()).unwrap();
    let mut models: Vec<FremenModel> = (0..4)
        .map(|_| FremenModel::new(config.fremen.clone()).unwrap())
        .collect();
    let mut narrow_until = None;
    for f in 0..9000u32 {
        let t = 1e6 + f64::from(f);
        let frame = [
            // Toggles every 1,000 frames: a block of its own from its third change.
            if (f / 1000).is_multiple_of(2) { 0 } else { 100 },
            // Changes once, late: an edge whose snapshot is too large for 64 bits.
            if f < 8500 { 0 } else { 100 },
            // Unknown for a stretch, then seen.
            if (3000..4000).contains(&f) { -1 } else { 100 },
            0,
        ];
        grid.observe_occupancy(t, &frame).unwrap();
        for (model, &v) in models.iter_mut().zip(&frame) {
            if v >= 0 {
                model.observe(&[t], &[f64::from(v) / 100.0]).unwrap();
            }
        }
        if narrow_until.is_none() && grid.storage().sum_bits == 128 {
            narrow_until = Some(f);
        }
    }
    let widened = narrow_until.expect("the sums left 64 bits");
    assert!(
        (8000..9000).contains(&widened),
        "widened at frame {widened}"
    );
    assert!(grid.is_consistent());
    for (c, model) in models.iter().enumerate() {
        assert_eq!(grid.cell_model(c).as_ref(), Some(model), "cell {c}");
    }
    // A wide grid survives a round trip.
    let bytes = postcard::to_allocvec(&grid).unwrap();
    let back: FremenGrid = postcard::from_bytes(&bytes).unwrap();
    assert!(back.is_consistent());
    assert_eq!(back, grid);
}

#[test]
fn grids_survive_a_round_trip_and_learn_on_identically() {
    let geometry = GridGeometry::planar(9, 8, 0.05, [0.0, 0.0]).unwrap();
    let inputs = scenario(geometry.cells(), 120, false, 17);
    let (half, _) = build(geometry, with_history(), &inputs[..60]);
    let bytes = postcard::to_allocvec(&half).unwrap();
    let mut back: FremenGrid = postcard::from_bytes(&bytes).unwrap();
    assert!(back.is_consistent());
    assert_eq!(back, half);
    let (whole, _) = build(geometry, with_history(), &inputs);
    for (t, input) in &inputs[60..] {
        match input {
            Input::Occupancy(v) => back.observe_occupancy(*t, v).unwrap(),
            Input::Bits(o, k) => back.observe_bits(*t, o, k.as_deref()).unwrap(),
            Input::Sparse(c, v) => back.observe_cells(*t, c, v).unwrap(),
        }
    }
    assert_eq!(back, whole);
    // A grid file with the slot index of a cell taken twice, or damaged storage, is refused.
    let mut twice = half.clone();
    twice.slots[1].cell = twice.slots[0].cell;
    let bytes = postcard::to_allocvec(&twice).unwrap();
    assert!(postcard::from_bytes::<FremenGrid>(&bytes).is_err());
    let mut lost = half.clone();
    let slot = lost
        .slots
        .iter()
        .position(|s| s.occupied.is_edges())
        .unwrap();
    lost.slots[slot].occupied = Acc::Zero;
    let bytes = postcard::to_allocvec(&lost).unwrap();
    let read: FremenGrid = postcard::from_bytes(&bytes).unwrap();
    assert!(!read.is_consistent());
}

#[test]
fn predicted_maps_are_the_compact_models_predictions() {
    let geometry = GridGeometry::planar(9, 8, 0.05, [0.0, 0.0]).unwrap();
    let inputs = scenario(geometry.cells(), 200, false, 11);
    for order in [0, 2, 5] {
        let (grid, _) = build(geometry, of_order(order, false), &inputs);
        let fitted = grid.fitted(OrderChoice::Fixed(order), Parallelism::Sequential);
        for t in [1_461_000_000.0, 1_461_003_777.5, 0.0] {
            let bits = |v: Vec<f32>| v.iter().map(|p| p.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                bits(grid.predict_map(t, Parallelism::Sequential)),
                bits(fitted.predict_map(t)),
                "{order} {t}"
            );
        }
    }
}

#[test]
fn sequential_and_parallel_fits_agree_bit_for_bit() {
    // More changing cells than one chunk of the fit (1024 slots), so that parallel runs split.
    let mut grid = history_strip(3000);
    let mut rng = Rng(17);
    let mut frame = |h: u32| -> Vec<i8> {
        (0..3000u32)
            .map(|c| match c % 3 {
                // Daily rhythms of different phases, noise, and walls.
                0 => {
                    if ((h + c) % 24) < 10 {
                        100
                    } else {
                        0
                    }
                }
                1 => {
                    if rng.below(4) == 0 {
                        100
                    } else {
                        0
                    }
                }
                _ => 100,
            })
            .collect()
    };
    observe_hours(&mut grid, 0..14 * 24, &mut frame);
    let trained = grid.clone();
    observe_hours(&mut grid, 14 * 24..18 * 24, &mut frame);
    assert_eq!(grid.dynamic_cells(), 2000);
    let frames = grid.frames();
    let t = 1_461_003_777.5;
    let orders = OrderChoice::PerCell((0..3000).map(|c| (c % 5) as u8).collect());
    let run = |parallelism: Parallelism| {
        let fitted = grid.fitted(orders.clone(), parallelism);
        (
            postcard::to_allocvec(&fitted).unwrap(),
            grid.predict_map(t, parallelism)
                .iter()
                .map(|p| p.to_bits())
                .collect::<Vec<_>>(),
            grid.estimation_error(&fitted, 0, frames, parallelism)
                .unwrap(),
            grid.select_cell_orders(&trained, 4, parallelism).unwrap(),
            postcard::to_allocvec(&grid.lossless(orders.clone(), parallelism).unwrap()).unwrap(),
        )
    };
    let sequential = run(Parallelism::Sequential);
    // The per-cell orders chose something beyond the static map for the daily cells.
    assert!(sequential.3.iter().step_by(3).any(|&k| k >= 1));
    assert!(sequential.2.changed_cells == 2000, "{:?}", sequential.2);
    for parallelism in [Parallelism::Rayon(0), Parallelism::Rayon(3)] {
        assert!(run(parallelism) == sequential, "{parallelism:?}");
    }
}

#[test]
fn concatenated_parts_share_their_snapshots() {
    // Every cell toggles at the same frames: in each part, two snapshots shared by all cells.
    let whole = GridGeometry::planar(192, 1, 1.0, [0.0, 0.0]).unwrap();
    let frames: Vec<Vec<i8>> = (0..3)
        .map(|f| {
            (0..192)
                .map(|c| if (f + c) % 2 == 0 { 100 } else { 0 })
                .collect()
        })
        .collect();
    let build_range = |range: std::ops::Range<usize>| {
        let geometry = GridGeometry::planar(range.len() as u32, 1, 1.0, [0.0, 0.0]).unwrap();
        let mut grid = FremenGrid::new(geometry, GridConfig::default()).unwrap();
        for (f, frame) in frames.iter().enumerate() {
            grid.observe_occupancy(600.0 * f as f64, &frame[range.clone()])
                .unwrap();
        }
        grid
    };
    let serial = build_range(0..192);
    let joined = FremenGrid::concat(whole, vec![build_range(0..64), build_range(64..192)]).unwrap();
    assert!(joined.is_consistent());
    assert_eq!(joined.storage().snapshots, 2);
    assert_eq!(joined.storage().free_blocks, 2);
    for c in 0..192 {
        assert_eq!(joined.cell_model(c), serial.cell_model(c), "cell {c}");
    }
}

#[test]
fn the_heap_bound_before_a_frame_holds_after_it_and_is_small_for_a_quiet_frame() {
    // Occupancy frames only (what the ROS node learns), many cells changing, fractions,
    // unknown stretches; past the frame (30,826 here) where the sums widen to 128 bits.
    let cells = 200;
    let mut rng = Rng(7);
    let mut grid = FremenGrid::new(
        GridGeometry::planar(20, 10, 0.1, [0.0, 0.0]).unwrap(),
        GridConfig::default(),
    )
    .unwrap();
    let mut t = 1_451_865_600.0;
    let mut widened_at = None;
    for frame in 0..31_000 {
        t += 60.0;
        let data: Vec<i8> = (0..cells)
            .map(|c| cell_value(&mut rng, c, frame, false))
            .collect();
        let before = grid.heap_bytes() as u64;
        let bound = grid.heap_bound_after_occupancy(&data);
        assert!(bound >= before, "frame {frame}");
        grid.observe_occupancy(t, &data).unwrap();
        let after = grid.heap_bytes() as u64;
        assert!(
            after <= bound,
            "frame {frame}: {after} bytes after, bound {bound} (before {before})"
        );
        if widened_at.is_none() && grid.storage().sum_bits == 128 {
            widened_at = Some(frame);
        }
    }
    assert!(widened_at.is_some(), "the test must cross a widening");
    // A frame equal to the last one of a binary grid touches no cell: its bound is the arrays'
    // growth step (an eighth, or 64 blocks of 85 128-bit sums and 64 slots), not the cells.
    let mut binary = FremenGrid::new(
        GridGeometry::planar(20, 10, 0.1, [0.0, 0.0]).unwrap(),
        GridConfig::default(),
    )
    .unwrap();
    let mut last = Vec::new();
    for frame in 0..500 {
        t += 60.0;
        last = (0..cells)
            .map(|c| cell_value(&mut rng, c, frame, true))
            .collect();
        binary.observe_occupancy(t, &last).unwrap();
    }
    let heap = binary.heap_bytes() as u64;
    let slack = binary.heap_bound_after_occupancy(&last) - heap;
    assert!(
        slack <= heap / 8 + 64 * 85 * 32 + 64 * 64 + 20_000,
        "{slack} of {heap}"
    );
    // A first map of 2000 x 2000 cells all different from unknown: the bound is what the
    // estimate says a cell may take at most, for every cell.
    let big = FremenGrid::new(
        GridGeometry::planar(2000, 2000, 0.05, [0.0, 0.0]).unwrap(),
        GridConfig::default(),
    )
    .unwrap();
    let estimate = FremenGrid::memory_estimate(big.geometry(), big.config());
    let bound = big.heap_bound_after_occupancy(&vec![0; 4_000_000]);
    assert!(bound >= estimate.fixed_bytes + 4_000_000 * estimate.cell_bytes_narrow);
}
