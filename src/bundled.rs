//! Real data embedded in the binary for `chronomap demo` (see `data/README.md` for provenance),
//! so that the demo runs from any directory.

use anyhow::Result;
use chronomap_core::TimeSeries;
use chronomap_io::{decompressing_reader, read_pairs_from, read_test_set_from};

/// One embedded file.
pub struct Bundled {
    /// Path below `data/`.
    pub name: &'static str,
    bytes: &'static [u8],
}

macro_rules! bundled {
    ($path:expr) => {
        Bundled {
            name: $path,
            bytes: include_bytes!(concat!("../data/", $path)),
        }
    };
}

/// The test set `N` of `DIR`: (`DIR/test_times_N.txt.xz`, `DIR/test_data_N.txt.xz`).
macro_rules! test_set {
    ($dir:literal, $n:literal) => {
        (
            bundled!(concat!($dir, "/test_times_", $n, ".txt.xz")),
            bundled!(concat!($dir, "/test_data_", $n, ".txt.xz")),
        )
    };
}

pub const GREG_TRAINING: Bundled = bundled!("door_greg_2016/training_data.txt.xz");
pub const GREG_TESTS: [(Bundled, Bundled); 5] = [
    test_set!("door_greg_2016", 1),
    test_set!("door_greg_2016", 2),
    test_set!("door_greg_2016", 3),
    test_set!("door_greg_2016", 4),
    test_set!("door_greg_2016", 5),
];
pub const TOM_TRAINING: Bundled = bundled!("door_tom_2013/min/training_data.txt.xz");
pub const TOM_TESTS: [(Bundled, Bundled); 3] = [
    test_set!("door_tom_2013/min", 1),
    test_set!("door_tom_2013/min", 2),
    test_set!("door_tom_2013/min", 3),
];
pub const TOM_SECONDS_WEEK: (Bundled, Bundled) = test_set!("door_tom_2013/sec", 0);
pub const TOM_SECONDS_DAY8: (Bundled, Bundled) = test_set!("door_tom_2013/sec", 1);

/// Presence of the Aruba resident in each of the 10 areas, one file per area.
pub const ARUBA_ROOMS: [Bundled; 10] = [
    bundled!("aruba_rooms_1min/presence_minutes_0.txt.xz"),
    bundled!("aruba_rooms_1min/presence_minutes_1.txt.xz"),
    bundled!("aruba_rooms_1min/presence_minutes_2.txt.xz"),
    bundled!("aruba_rooms_1min/presence_minutes_3.txt.xz"),
    bundled!("aruba_rooms_1min/presence_minutes_4.txt.xz"),
    bundled!("aruba_rooms_1min/presence_minutes_5.txt.xz"),
    bundled!("aruba_rooms_1min/presence_minutes_6.txt.xz"),
    bundled!("aruba_rooms_1min/presence_minutes_7.txt.xz"),
    bundled!("aruba_rooms_1min/presence_minutes_8.txt.xz"),
    bundled!("aruba_rooms_1min/presence_minutes_9.txt.xz"),
];

impl Bundled {
    /// Reads a `t value` file.
    pub fn pairs(&self) -> Result<TimeSeries> {
        Ok(read_pairs_from(
            self.name,
            decompressing_reader(self.name, self.bytes),
        )?)
    }
}

/// Reads a test set of two embedded files.
pub fn test_set((times, values): &(Bundled, Bundled)) -> Result<TimeSeries> {
    Ok(read_test_set_from(
        times.name,
        decompressing_reader(times.name, times.bytes),
        values.name,
        decompressing_reader(values.name, values.bytes),
    )?)
}

/// Reads every test set of `sets`.
pub fn test_sets(sets: &[(Bundled, Bundled)]) -> Result<Vec<TimeSeries>> {
    sets.iter().map(test_set).collect()
}

/// The Witham Wharf edge-traversal files ([Fentanes 2015]; `data/witham_topological_nav/edges`).
pub const WITHAM_EDGES: [Bundled; 61] = [
    bundled!("witham_topological_nav/edges/Aisle1_Aisle2.data.xz"),
    bundled!("witham_topological_nav/edges/Aisle1_Ramp2.data.xz"),
    bundled!("witham_topological_nav/edges/Aisle2_Aisle1.data.xz"),
    bundled!("witham_topological_nav/edges/Aisle2_Ramp2.data.xz"),
    bundled!("witham_topological_nav/edges/ChargingPoint_Station.data.xz"),
    bundled!("witham_topological_nav/edges/GroundCentral_Kitchen.data.xz"),
    bundled!("witham_topological_nav/edges/GroundCentral_Ramp2.data.xz"),
    bundled!("witham_topological_nav/edges/GroundCentral_Sofas.data.xz"),
    bundled!("witham_topological_nav/edges/GroundCentral_WayPoint3.data.xz"),
    bundled!("witham_topological_nav/edges/GroundCentral_WayPoint4.data.xz"),
    bundled!("witham_topological_nav/edges/Kitchen_GroundCentral.data.xz"),
    bundled!("witham_topological_nav/edges/Kitchen_Ramp2.data.xz"),
    bundled!("witham_topological_nav/edges/Kitchen_Sofas.data.xz"),
    bundled!("witham_topological_nav/edges/Kitchen_WayPoint3.data.xz"),
    bundled!("witham_topological_nav/edges/LabCentral_LabDesk.data.xz"),
    bundled!("witham_topological_nav/edges/LabCentral_LabDoor1.data.xz"),
    bundled!("witham_topological_nav/edges/LabCentral_Station.data.xz"),
    bundled!("witham_topological_nav/edges/LabDesk_LabCentral.data.xz"),
    bundled!("witham_topological_nav/edges/LabDesk_LabDoor1.data.xz"),
    bundled!("witham_topological_nav/edges/LabDesk_Station.data.xz"),
    bundled!("witham_topological_nav/edges/LabDoor1_LabCentral.data.xz"),
    bundled!("witham_topological_nav/edges/LabDoor1_LabDesk.data.xz"),
    bundled!("witham_topological_nav/edges/LabDoor1_LabDoor2.data.xz"),
    bundled!("witham_topological_nav/edges/LabDoor1_Station.data.xz"),
    bundled!("witham_topological_nav/edges/LabDoor2_LabDoor1.data.xz"),
    bundled!("witham_topological_nav/edges/LabDoor2_Printer.data.xz"),
    bundled!("witham_topological_nav/edges/LabDoor2_WayPoint1.data.xz"),
    bundled!("witham_topological_nav/edges/LabDoor2_WayPoint2.data.xz"),
    bundled!("witham_topological_nav/edges/Printer_LabDoor2.data.xz"),
    bundled!("witham_topological_nav/edges/Printer_Ramp1.data.xz"),
    bundled!("witham_topological_nav/edges/Printer_WayPoint1.data.xz"),
    bundled!("witham_topological_nav/edges/Ramp1_Printer.data.xz"),
    bundled!("witham_topological_nav/edges/Ramp1_Ramp2.data.xz"),
    bundled!("witham_topological_nav/edges/Ramp1_WayPoint2.data.xz"),
    bundled!("witham_topological_nav/edges/Ramp2_Aisle1.data.xz"),
    bundled!("witham_topological_nav/edges/Ramp2_Aisle2.data.xz"),
    bundled!("witham_topological_nav/edges/Ramp2_GroundCentral.data.xz"),
    bundled!("witham_topological_nav/edges/Ramp2_Kitchen.data.xz"),
    bundled!("witham_topological_nav/edges/Ramp2_Ramp1.data.xz"),
    bundled!("witham_topological_nav/edges/Ramp2_Sofas.data.xz"),
    bundled!("witham_topological_nav/edges/Ramp2_WayPoint4.data.xz"),
    bundled!("witham_topological_nav/edges/Sofas_GroundCentral.data.xz"),
    bundled!("witham_topological_nav/edges/Sofas_Kitchen.data.xz"),
    bundled!("witham_topological_nav/edges/Sofas_Ramp2.data.xz"),
    bundled!("witham_topological_nav/edges/Sofas_WayPoint3.data.xz"),
    bundled!("witham_topological_nav/edges/Station_ChargingPoint.data.xz"),
    bundled!("witham_topological_nav/edges/Station_LabCentral.data.xz"),
    bundled!("witham_topological_nav/edges/Station_LabDesk.data.xz"),
    bundled!("witham_topological_nav/edges/Station_LabDoor1.data.xz"),
    bundled!("witham_topological_nav/edges/WayPoint1_LabDoor2.data.xz"),
    bundled!("witham_topological_nav/edges/WayPoint1_Printer.data.xz"),
    bundled!("witham_topological_nav/edges/WayPoint2_LabDoor2.data.xz"),
    bundled!("witham_topological_nav/edges/WayPoint2_Ramp1.data.xz"),
    bundled!("witham_topological_nav/edges/WayPoint3_Kitchen.data.xz"),
    bundled!("witham_topological_nav/edges/WayPoint3_Sofas.data.xz"),
    bundled!("witham_topological_nav/edges/WayPoint3_WayPoint4.data.xz"),
    bundled!("witham_topological_nav/edges/WayPoint4_GroundCentral.data.xz"),
    bundled!("witham_topological_nav/edges/WayPoint4_Kitchen.data.xz"),
    bundled!("witham_topological_nav/edges/WayPoint4_Ramp2.data.xz"),
    bundled!("witham_topological_nav/edges/WayPoint4_Sofas.data.xz"),
    bundled!("witham_topological_nav/edges/WayPoint4_WayPoint3.data.xz"),
];

/// Reads the embedded Witham edge files as `read_edge_directory` reads the directory.
pub fn witham_edges() -> Result<chronomap_topo::edges::EdgeStatistics> {
    let files: Vec<(&str, &[u8])> = WITHAM_EDGES
        .iter()
        .map(|b| {
            let file_name = b.name.rsplit('/').next().unwrap_or(b.name);
            (file_name, b.bytes)
        })
        .collect();
    Ok(chronomap_io::read_edge_files(
        "witham_topological_nav/edges",
        &files,
        &[],
    )?)
}
