//! Grid-state files across format versions: a file of format 1 (written by chronomap before
//! the compact format 2, bundled in `tests/data/grid/`) still loads, and holds cell for cell
//! the grid that the current code builds from the same frames; writing it again gives format 2.

use chronomap_core::periods::{DAY, PeriodSet};
use chronomap_core::{FremenConfig, TemporalModel};
use chronomap_grid::AnyGrid;
use chronomap_grid::{FremenGrid, GridConfig, GridGeometry};
use chronomap_io::grid_file::{
    decode_grid, encode_grid, encode_grid_state, read_grid_file, write_grid_state,
};
use chronomap_testutil::repo_path;

/// xorshift64*: deterministic frames.
struct Rng(u64);

impl Rng {
    fn below(&mut self, n: u64) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) % n
    }
}

/// The grid of `tests/data/grid/state-format1.cmg`: 8×4 cells, periods of one day, history
/// kept; 80 frames mixing constant, flipping, unknown, fractional, never seen and late cells,
/// bit-packed frames with unknown cells, and sparse single-cell observations.
pub fn format1_scenario() -> FremenGrid {
    let geometry = GridGeometry::planar(8, 4, 0.25, [-1.0, 0.5]).unwrap();
    let config = GridConfig {
        fremen: FremenConfig {
            periods: PeriodSet::harmonics(DAY, 24).unwrap(),
            order: 2,
            ..FremenConfig::default()
        },
        keep_history: true,
    };
    let mut grid = FremenGrid::new(geometry, config).unwrap();
    let mut rng = Rng(5);
    let mut t = 1_451_865_600.0;
    for frame in 0..80u64 {
        t += 600.0 + rng.below(3000) as f64;
        let values: Vec<i8> = (0..32u64)
            .map(|c| match c % 7 {
                0 => 100,
                1 if (frame / 6 + c) % 3 == 0 => 100,
                1 => 0,
                2 => [0, 100, -1, 0][rng.below(4) as usize],
                3 => [0, 35, 100, 70][rng.below(4) as usize],
                4 => -1,
                5 if frame < 30 => -1,
                5 => 100 * (frame % 2) as i8,
                _ => 0,
            })
            .collect();
        if frame % 4 == 1 {
            let (mut occupied, mut known) = (0u64, 0u64);
            for (c, &v) in values.iter().enumerate() {
                known |= u64::from(v >= 0) << c;
                occupied |= u64::from(v >= 50) << c;
            }
            grid.observe_bits(t, &[occupied], Some(&[known])).unwrap();
        } else {
            grid.observe_occupancy(t, &values).unwrap();
        }
        if frame % 13 == 6 {
            t += 10.0;
            let cells: Vec<u32> = (0..3).map(|_| rng.below(32) as u32).collect();
            let values: Vec<f64> = cells.iter().map(|&c| f64::from(c % 3) / 2.0).collect();
            grid.observe_cells(t, &cells, &values).unwrap();
        }
    }
    grid
}

/// The grid state of the bundled format-1 file.
fn format1_file() -> FremenGrid {
    match read_grid_file(repo_path("tests/data/grid/state-format1.cmg")).unwrap() {
        AnyGrid::State(grid) => *grid,
        other => panic!("a {} grid", chronomap_io::grid_kind(&other)),
    }
}

/// The byte after the header line: the payload's variant index (postcard varint).
fn payload_index(bytes: &[u8]) -> u8 {
    bytes[bytes.iter().position(|&b| b == b'\n').unwrap() + 1]
}

#[test]
fn grid_states_of_format_1_load_exactly() {
    let bytes = std::fs::read(repo_path("tests/data/grid/state-format1.cmg")).unwrap();
    assert!(bytes.starts_with(b"chronomap-model 1 kind=grid-state "));
    assert_eq!(payload_index(&bytes), 0, "the file is of format 1");
    let old = format1_file();
    assert!(old.is_consistent());
    // What the format-1 code predicted from this grid (observation count, bits of p(t) at
    // t = 1,460,000,000 with order 2), recorded when the file was written.
    let t = 1_460_000_000.0;
    for (cell, count, bits) in [
        (0, 82, 4_606_549_542_234_303_777u64),
        (2, 66, 4_605_234_648_234_677_334),
        (9, 59, 4_600_848_541_913_082_429),
        (23, 57, 4_573_461_765_229_406_912),
        (25, 1, 4_602_678_819_172_646_902),
        (27, 81, 0),
    ] {
        let model = old.cell_model(cell).unwrap();
        assert_eq!(model.span().count, count, "cell {cell}");
        assert_eq!(model.predict(t).to_bits(), bits, "cell {cell}");
    }
    for cell in [4, 11, 18] {
        assert!(old.cell_model(cell).is_none(), "cell {cell} was never seen");
    }
    // Every cell equals the grid the current code builds from the same frames.
    let new = format1_scenario();
    for cell in 0..32 {
        assert_eq!(old.cell_sums(cell), new.cell_sums(cell), "cell {cell}");
        assert_eq!(old.history(cell), new.history(cell), "cell {cell}");
    }
    let bits = |v: Vec<f32>| v.iter().map(|p| p.to_bits()).collect::<Vec<_>>();
    let sequential = chronomap_core::Parallelism::Sequential;
    assert_eq!(
        bits(old.predict_map(t, sequential)),
        bits(new.predict_map(t, sequential))
    );
    // It learns on as the new grid does.
    let (mut old, mut new) = (old, new);
    for f in 0..5 {
        let frame: Vec<i8> = (0..32)
            .map(|c| if (c + f) % 3 == 0 { 100 } else { 0 })
            .collect();
        let t = 1_460_000_000.0 + 600.0 * f64::from(f as u8);
        old.observe_occupancy(t, &frame).unwrap();
        new.observe_occupancy(t, &frame).unwrap();
    }
    for cell in 0..32 {
        assert_eq!(old.cell_model(cell), new.cell_model(cell), "cell {cell}");
    }
}

#[test]
fn grid_states_are_written_in_format_2_without_a_copy() {
    let old = std::fs::read(repo_path("tests/data/grid/state-format1.cmg")).unwrap();
    let grid = format1_file();
    let file = AnyGrid::State(Box::new(grid.clone()));
    let bytes = encode_grid(&file).unwrap();
    assert_eq!(payload_index(&bytes), 3, "format 2");
    assert!(bytes.len() < old.len(), "{} >= {}", bytes.len(), old.len());
    assert_eq!(decode_grid(&bytes).unwrap(), file);
    assert_eq!(encode_grid_state(&grid).unwrap(), bytes);
    let dir = chronomap_testutil::scratch!("chronomap-io-grid-format");
    write_grid_state(dir.join("state.cmg"), &grid).unwrap();
    assert_eq!(std::fs::read(dir.join("state.cmg")).unwrap(), bytes);
    // Built by the current code, the same grid is smaller still (edges, not blocks).
    let built = encode_grid_state(&format1_scenario()).unwrap();
    assert!(
        built.len() < bytes.len(),
        "{} >= {}",
        built.len(),
        bytes.len()
    );
}
