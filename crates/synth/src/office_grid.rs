//! The synthetic office as a [`chronomap_grid`] occupancy grid: its geometry, and its frame
//! streams as a [`PartitionedFrames`] source, so that
//! [`build_partitioned`] builds the grid of [Krajník 2017]
//! §VI on several threads.
//!
//! ```
//! use chronomap_core::Parallelism;
//! use chronomap_core::progress::NoProgress;
//! use chronomap_grid::GridConfig;
//! use chronomap_grid::build::build_partitioned;
//! use chronomap_synth::office_grid::office;
//!
//! let workload = office(640, 1, 0)?;
//! let geometry = workload.geometry()?;
//! assert_eq!((geometry.width, geometry.height, geometry.depth), (32, 20, 1));
//! let built = build_partitioned(
//!     &workload, geometry, &GridConfig::default(), &[], Parallelism::Rayon(2), &NoProgress,
//! )?;
//! assert_eq!(built.grid.frames(), 17_280);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::ops::Range;

use chronomap_core::Parallelism;
use chronomap_core::progress::NoProgress;
use chronomap_grid::build::{BitFrames, PartitionError, PartitionedFrames, build_partitioned};
use chronomap_grid::{FremenGrid, GridConfig, GridError, GridGeometry};

use crate::error::SynthError;
use crate::office::{FrameStream, OfficeConfig, OfficeWorkload};

/// Edge length of a cell of the office in metres (10 cm, [Krajník 2017] §VI).
pub const CELL_METRES: f64 = 0.1;

/// The office of [`OfficeConfig::default`] with `cells` cells, `days` days and `seed`.
///
/// # Errors
/// [`SynthError::Config`] for a size out of range.
pub fn office(cells: usize, days: u32, seed: u64) -> Result<OfficeWorkload, SynthError> {
    OfficeWorkload::new(OfficeConfig {
        cells,
        days,
        seed,
        ..OfficeConfig::default()
    })
}

/// Geometry of an office of `cells` cells of 10 cm: the paper's 213,000 cells as a
/// 71 × 60 × 50 block (7.1 m × 6 m × 5 m, [Krajník 2017] §VI); any other number as the most square
/// 2-D grid `width × height` with `width · height = cells` and `height <= width`.
///
/// # Errors
/// [`GridError::Geometry`] for no cells or more than a grid holds.
pub fn office_geometry(cells: usize) -> Result<GridGeometry, GridError> {
    let geometry = if cells == 213_000 {
        GridGeometry {
            width: 71,
            height: 60,
            depth: 50,
            resolution: CELL_METRES,
            origin: [0.0, 0.0, 0.0],
        }
    } else {
        let mut height = (cells as f64).sqrt() as usize;
        while height > 1 && !cells.is_multiple_of(height) {
            height -= 1;
        }
        let height = height.max(1);
        let too_many = || GridError::Geometry {
            reason: format!("{cells} cells do not fit a grid"),
        };
        GridGeometry {
            width: u32::try_from(cells / height).map_err(|_| too_many())?,
            height: u32::try_from(height).map_err(|_| too_many())?,
            depth: 1,
            resolution: CELL_METRES,
            origin: [0.0, 0.0, 0.0],
        }
    };
    geometry.validate()?;
    Ok(geometry)
}

impl OfficeWorkload {
    /// The geometry of this office's grid ([`office_geometry`] of its cells).
    ///
    /// # Errors
    /// As [`office_geometry`].
    pub fn geometry(&self) -> Result<GridGeometry, GridError> {
        office_geometry(self.cells())
    }

    /// Every frame of this office learned by a grid with `config` (no hold-out splits), on
    /// the threads `parallelism` allows: the learning state benchmarks and load tests serve.
    ///
    /// # Errors
    /// As [`build_partitioned`].
    pub fn learned_grid(
        &self,
        config: &GridConfig,
        parallelism: Parallelism,
    ) -> Result<FremenGrid, PartitionError> {
        let geometry = self.geometry()?;
        Ok(build_partitioned(self, geometry, config, &[], parallelism, &NoProgress)?.grid)
    }
}

impl BitFrames for FrameStream<'_> {
    fn next_frame(&mut self) -> Option<(u64, f64, &[u64])> {
        FrameStream::next_frame(self)
    }
}

impl PartitionedFrames for OfficeWorkload {
    type Stream<'a> = FrameStream<'a>;
    type Error = SynthError;

    fn cells(&self) -> usize {
        OfficeWorkload::cells(self)
    }

    fn frames(&self) -> u64 {
        OfficeWorkload::frames(self)
    }

    fn stream(&self, range: Range<usize>) -> Result<FrameStream<'_>, SynthError> {
        OfficeWorkload::stream(self, range)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_grid::build::bare_scan;

    #[test]
    fn geometries_of_the_paper_and_of_other_sizes() {
        let paper = office_geometry(213_000).unwrap();
        assert_eq!((paper.width, paper.height, paper.depth), (71, 60, 50));
        assert_eq!(paper.cells(), 213_000);
        let g = office_geometry(6400).unwrap();
        assert_eq!((g.width, g.height, g.depth), (80, 80, 1));
        let g = office_geometry(6000).unwrap();
        assert_eq!((g.width, g.height), (80, 75));
        // A prime number of cells is one row.
        let g = office_geometry(7).unwrap();
        assert_eq!((g.width, g.height), (7, 1));
        assert_eq!(g.resolution, 0.1);
        assert!(office_geometry(0).is_err());
    }

    #[test]
    fn threads_do_not_change_the_office_grid() {
        let workload = office(1000, 2, 7).unwrap();
        let geometry = workload.geometry().unwrap();
        let config = GridConfig {
            keep_history: true,
            ..GridConfig::default()
        };
        let build = |parallelism| {
            build_partitioned(
                &workload,
                geometry,
                &config,
                &[20_000],
                parallelism,
                &NoProgress,
            )
            .unwrap()
        };
        let one = build(Parallelism::Sequential);
        let four = build(Parallelism::Rayon(4));
        assert_eq!(one.grid.frames(), 2 * 17_280);
        assert_eq!(one.grid.dynamic_cells(), four.grid.dynamic_cells());
        assert!(
            one.grid.dynamic_cells() > 10,
            "{}",
            one.grid.dynamic_cells()
        );
        for c in 0..1000 {
            assert_eq!(one.grid.cell_model(c), four.grid.cell_model(c), "cell {c}");
            assert_eq!(
                one.snapshots[0].cell_model(c),
                four.snapshots[0].cell_model(c),
                "cell {c}"
            );
        }
        assert_eq!(four.snapshots[0].frames(), 20_000);
        let changes = bare_scan(&workload, Parallelism::Sequential, &NoProgress).unwrap();
        assert_eq!(
            bare_scan(&workload, Parallelism::Rayon(3), &NoProgress).unwrap(),
            changes
        );
        assert!(changes > 0);
        // An unaligned part is the source's error, naming the cells.
        assert!(PartitionedFrames::stream(&workload, 10..20).is_err());
    }
}
