//! `chronomap bench grid-memory` on small grids: every cell of each grid is a changing cell,
//! the baseline costs what format 1 stored per cell (hand-computed), the grid what its slots and
//! shared prefixes hold, and the text report prints the same rows. (Memory itself is measured by
//! the command at its default sizes, never by a test.)

use crate::common::{chronomap, json, stdout, usage_error};

#[test]
fn bench_grid_memory_reports_every_cell_changing_against_format_1() {
    let report = json(&chronomap(&[
        "bench",
        "grid-memory",
        "--cells",
        "4096,16384",
        "--periods",
        "day",
        "--json",
    ]));
    assert_eq!(report["period_count"], 24);
    assert_eq!(report["frames"], 3);
    assert_eq!(report["checked_cells"], 4096);
    let rows = report["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 2);
    for (row, cells) in rows.iter().zip([4096u64, 16384]) {
        let number = |key: &str| row[key].as_f64().unwrap_or_else(|| panic!("{key}: {row}"));
        assert_eq!(row["cells"].as_u64(), Some(cells));
        assert_eq!(row["changing_cells"].as_u64(), Some(cells));
        // Format 1: an 80-byte slot and 24 rows of 32 bytes of occupied sums per cell, 24 more
        // for the quarter of the cells that were unknown, 4 bytes of slot index, 3 bits of planes.
        let baseline = 80.0 + 24.0 * 32.0 * 1.25 + 4.0 + 3.0 / 8.0;
        assert_eq!(number("baseline_bytes_per_cell"), baseline);
        // Now: the fixed part, a 64-byte slot per cell (every cell changed), the first 64
        // blocks of 25 16-byte sums (two hold the prefixes of frames 1 and 2, which every cell
        // names) and one node of the snapshot index.
        let storage = &row["storage"];
        assert_eq!(storage["slots"].as_u64(), Some(cells));
        assert_eq!(storage["owned_accumulators"], 0);
        assert_eq!(storage["snapshots"], 2);
        assert_eq!(storage["sum_bits"], 64);
        assert_eq!(storage["pool_bytes"].as_u64(), Some(64 * 25 * 16));
        let fixed = row["estimate"]["fixed_bytes"].as_u64().unwrap();
        let heap = fixed + 64 * cells + 64 * 25 * 16 + 328;
        assert_eq!(row["heap_bytes"].as_u64(), Some(heap));
        assert_eq!(number("bytes_per_cell"), heap as f64 / cells as f64);
        assert_eq!(
            number("memory_ratio"),
            baseline / (heap as f64 / cells as f64)
        );
        assert!(number("memory_ratio") > 10.0, "{row}");
        assert!(
            number("file_bytes_per_cell") * 10.0 < number("baseline_file_bytes_per_cell"),
            "{row}"
        );
        assert!(heap <= row["estimate"]["worst_case_bytes"].as_u64().unwrap());
    }
    let text = stdout(&chronomap(&[
        "bench",
        "grid-memory",
        "--cells",
        "4096",
        "--periods",
        "day",
    ]));
    assert!(text.contains("24 periods (86400/24), 3 frames"), "{text}");
    assert!(text.contains("     4096       64x64 |"), "{text}");
    let e = usage_error(&chronomap(&["bench", "grid-memory", "--cells", "0"]));
    assert!(e.contains("--cells"), "{e}");
}
