//! The grid build job ([Krajník 2017] §VI): frames read from a source (the synthetic office of
//! §VI, a list of map files, the maps of a bag's topic, one series per cell), built into a
//! [`FremenGrid`] with snapshots at the hold-out splits, the orders chosen for the file, and the
//! error table of §VI (estimation and prediction errors of static, orders 1..5 and per-cell
//! orders, with the sizes of their lossy and lossless files).
//!
//! Files in, result structs out: progress goes to a [`Progress`], threads are a
//! [`Parallelism`]; the command line prints and writes.

use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_core::Parallelism;
use chronomap_core::PeriodSet;
use chronomap_core::fremen::FremenConfig;
use chronomap_core::metrics::compression_ratio;
use chronomap_core::progress::Progress;
use chronomap_grid::build::{
    GridBuild, GridBuilder, PartitionError, build_from_frames, build_partitioned, holdout_splits,
    occupancy_percent,
};
use chronomap_grid::report::{OrderErrors, RowOrders, order_errors};
use chronomap_grid::{
    AnyGrid, FremenGrid, GridConfig, GridError, GridGeometry, GridStore, OrderChoice,
};
use chronomap_io::frame_list::FrameMapError;
use chronomap_io::model_file::ModelFileError;
use chronomap_io::navmap::LoadSemantics;
use chronomap_io::{
    DataError, encode_grid, load_frame_map, load_next_frame_map, read_frame_list, read_pairs,
};
use chronomap_rosbag::{Bag, BagError, MapFrame, TimeSource};
use chronomap_synth::SynthError;
use chronomap_synth::office_grid::office;
use thiserror::Error;

/// Largest order `auto` and the error table consider.
pub const MAX_ORDER: usize = 5;

/// Why a grid cannot be built.
#[derive(Debug, Error)]
pub enum GridJobError {
    /// The synthetic office cannot be made.
    #[error(transparent)]
    Synth(#[from] SynthError),
    /// The grid refused its geometry, a frame or a fit.
    #[error(transparent)]
    Grid(#[from] GridError),
    /// The partitioned build failed.
    #[error(transparent)]
    Partition(#[from] PartitionError),
    /// The thread pool of `threads` cannot be made.
    #[error(transparent)]
    ThreadPool(#[from] rayon::ThreadPoolBuildError),
    /// A frame list or a cell series cannot be read.
    #[error(transparent)]
    Data(#[from] DataError),
    /// A map of a frame list cannot be read, or differs from the first.
    #[error(transparent)]
    FrameMap(#[from] FrameMapError),
    /// The grid refused the map of a frame list's line.
    #[error("{list}:{line}: {map}")]
    Frame {
        /// The frame list.
        list: String,
        /// Its line.
        line: usize,
        /// The map file of that line.
        map: String,
        /// Why.
        #[source]
        source: GridError,
    },
    /// A bag cannot be read, or a map of it differs from the first.
    #[error(transparent)]
    Bag(#[from] BagError),
    /// A bag's topic holds no map.
    #[error("{bag}: topic {topic} has no map")]
    NoMap {
        /// The bag.
        bag: String,
        /// The topic.
        topic: String,
    },
    /// Cell series with different times.
    #[error(
        "{file}: its times differ from those of {first} (every cell series must have the same times)"
    )]
    SeriesTimes {
        /// The series that differs.
        file: String,
        /// The first series.
        first: String,
    },
    /// Orders chosen per cell, or an error table, of a grid built without snapshots.
    #[error("no held-back snapshot")]
    NoSnapshot,
    /// The error table of a grid built without its two snapshots.
    #[error("the error report needs two held-back snapshots")]
    NoSnapshots,
    /// A grid cannot be encoded (for the sizes of the error table).
    #[error(transparent)]
    ModelFile(#[from] ModelFileError),
}

/// Where a grid's frames come from.
#[derive(Clone, Debug)]
pub enum FrameSource<'a> {
    /// The synthetic office of [Krajník 2017] §VI (`chronomap_synth::office_grid`), built by
    /// partitions on `threads` threads (`None`: the current pool).
    Synthetic {
        /// Cells of the office.
        cells: usize,
        /// Days of frames.
        days: u32,
        /// The seed of its generator.
        seed: u64,
        /// Threads of the build.
        threads: Option<usize>,
    },
    /// A list of `<time> <map.yaml>` lines; every map of the first one's geometry.
    MapList {
        /// The list.
        list: &'a Path,
        /// How the maps' pixels are read.
        semantics: LoadSemantics,
    },
    /// The `nav_msgs/msg/OccupancyGrid` messages of a bag's topic.
    Bag {
        /// The bag.
        bag: &'a Path,
        /// The topic.
        topic: &'a str,
        /// Where a map's time comes from.
        time: TimeSource,
    },
    /// One `t value` file per cell, all with the same times.
    CellSeries(&'a [PathBuf]),
}

/// How a grid is built: its periods, the order it learns with, and what is held back.
#[derive(Clone, Debug)]
pub struct BuildSettings {
    /// The candidate periods of every cell's model.
    pub periods: PeriodSet,
    /// The order of every cell, or `None` to choose one per cell on held-back frames.
    pub order: Option<usize>,
    /// The fraction of frames held back ([`holdout_splits`]).
    pub holdout: f64,
    /// Whether the error table will be asked for.
    pub errors: bool,
    /// The form the grid is stored in.
    pub store: GridStore,
}

impl BuildSettings {
    /// Whether the grid keeps its history and snapshots: for the error table, a lossless file
    /// or per-cell orders.
    pub fn needs_history(&self) -> bool {
        self.errors || self.store == GridStore::Lossless || self.order.is_none()
    }

    /// The grid's configuration: the order learned with is `order`, or 2 while choosing.
    pub fn config(&self) -> GridConfig {
        GridConfig {
            fremen: FremenConfig {
                periods: self.periods.clone(),
                order: self.order.unwrap_or(2),
                ..FremenConfig::default()
            },
            keep_history: self.needs_history(),
        }
    }
}

/// A built grid, where it came from and how long it took.
#[derive(Clone, Debug)]
pub struct BuiltGrid {
    /// The grid and its snapshots at the hold-out splits.
    pub build: GridBuild,
    /// The first held-back frame.
    pub split: u64,
    /// Seconds from reading the source to the built grid.
    pub seconds: f64,
    /// The source in words (the file, `synthetic office (seed 7)`, `bag topic`, …).
    pub source: String,
}

impl BuiltGrid {
    fn new(build: GridBuild, splits: [u64; 2], started: Instant, source: String) -> Self {
        Self {
            build,
            split: splits[1],
            seconds: started.elapsed().as_secs_f64(),
            source,
        }
    }

    /// Cell observations: cells × frames, the numerator of [Krajník 2017] eq. (16).
    pub fn observations(&self) -> f64 {
        let grid = &self.build.grid;
        grid.geometry().cells() as f64 * grid.frames() as f64
    }

    /// The orders of the stored file: `Fixed(order)`, or with `None` every cell's order chosen
    /// on the frames held back from the last snapshot ([`FremenGrid::select_cell_orders`], up
    /// to [`MAX_ORDER`]).
    ///
    /// # Errors
    /// [`GridJobError::NoSnapshot`] for `None` on a grid built without snapshots, or the
    /// selection's error.
    pub fn orders(
        &self,
        order: Option<usize>,
        parallelism: Parallelism,
    ) -> Result<OrderChoice, GridJobError> {
        Ok(match order {
            Some(k) => OrderChoice::Fixed(k),
            None => {
                let trained = self
                    .build
                    .snapshots
                    .last()
                    .ok_or(GridJobError::NoSnapshot)?;
                OrderChoice::PerCell(self.build.grid.select_cell_orders(
                    trained,
                    MAX_ORDER,
                    parallelism,
                )?)
            }
        })
    }
}

/// One row of the error table: the errors of one choice of orders and the sizes of its files.
#[derive(Clone, Debug)]
pub struct ErrorRow {
    /// Estimation and prediction errors.
    pub errors: OrderErrors,
    /// Bytes of its lossy file.
    pub lossy_bytes: usize,
    /// Bytes of its lossless file.
    pub lossless_bytes: usize,
}

/// The error table of [Krajník 2017] §VI with the sizes of the rows' files.
#[derive(Clone, Debug)]
pub struct ErrorTable {
    /// Static, orders 1..=[`MAX_ORDER`], per-cell orders.
    pub rows: Vec<ErrorRow>,
    /// Cell observations of the whole grid (eq. 16).
    pub observations: f64,
    /// Seconds it took.
    pub seconds: f64,
}

impl ErrorTable {
    /// A row's name: `static (order 0)`, `FreMEn order k`, `FreMEn auto (per cell)`.
    pub fn name(orders: RowOrders) -> String {
        match orders {
            RowOrders::Fixed(0) => "static (order 0)".to_string(),
            RowOrders::Fixed(k) => format!("FreMEn order {k}"),
            RowOrders::PerCell => "FreMEn auto (per cell)".to_string(),
        }
    }

    /// The cells that changed (those the errors are averaged over).
    pub fn changed_cells(&self) -> Option<usize> {
        self.rows.last().map(|r| r.errors.estimation.changed_cells)
    }

    /// The compression ratio of eq. (16) of a file of `bytes` bytes.
    pub fn ratio(&self, bytes: usize) -> f64 {
        compression_ratio(self.observations, bytes)
    }
}

/// Builds the grid of `source` with `settings`, reporting frames to `progress`.
///
/// # Errors
/// [`GridJobError`] naming the file (and line) that cannot be read or built from.
pub fn build_grid(
    source: &FrameSource,
    settings: &BuildSettings,
    progress: &dyn Progress,
) -> Result<BuiltGrid, GridJobError> {
    let job = Job {
        config: settings.config(),
        holdout: settings.holdout,
        snapshots: settings.needs_history(),
        progress,
    };
    match *source {
        FrameSource::Synthetic {
            cells,
            days,
            seed,
            threads,
        } => job.synthetic(cells, days, seed, threads),
        FrameSource::MapList { list, semantics } => job.map_list(list, semantics),
        FrameSource::Bag { bag, topic, time } => job.bag(bag, topic, time),
        FrameSource::CellSeries(files) => job.cell_series(files),
    }
}

/// Estimation and prediction errors for static, orders 1..=[`MAX_ORDER`] and per-cell orders
/// ([`order_errors`]), and the sizes of their lossy and lossless files.
///
/// # Errors
/// [`GridJobError::NoSnapshots`] for a grid built without history, or a fit's error.
pub fn error_table(
    built: &BuiltGrid,
    parallelism: Parallelism,
    progress: &dyn Progress,
) -> Result<ErrorTable, GridJobError> {
    let grid = &built.build.grid;
    let [inner, trained] = &built.build.snapshots[..] else {
        return Err(GridJobError::NoSnapshots);
    };
    let started = Instant::now();
    let rows = order_errors(grid, inner, trained, MAX_ORDER, parallelism, progress)?;
    progress.stage("file sizes", rows.len() as u64);
    let rows = rows
        .into_iter()
        .map(|errors| {
            let lossless = grid.lossless(errors.final_orders.clone(), parallelism)?;
            let lossy_bytes = encode_grid(&AnyGrid::Lossy(Box::new(errors.fitted.clone())))?.len();
            let lossless_bytes = encode_grid(&AnyGrid::Lossless(Box::new(lossless)))?.len();
            progress.advance(1);
            Ok(ErrorRow {
                errors,
                lossy_bytes,
                lossless_bytes,
            })
        })
        .collect::<Result<Vec<_>, GridJobError>>()?;
    Ok(ErrorTable {
        rows,
        observations: built.observations(),
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// What every source builds with.
struct Job<'a> {
    config: GridConfig,
    holdout: f64,
    snapshots: bool,
    progress: &'a dyn Progress,
}

impl Job<'_> {
    /// The frames to snapshot the grid after: `splits`, or none without `snapshots`.
    fn snapshot_at<'s>(&self, splits: &'s [u64; 2]) -> &'s [u64] {
        if self.snapshots { &splits[..] } else { &[] }
    }

    /// The grid of `frames` frames that `next` observes in order, held back at `splits`.
    fn read_frames(
        &self,
        geometry: GridGeometry,
        frames: usize,
        splits: &[u64; 2],
        next: impl FnMut(usize, &mut FremenGrid) -> Result<(), GridJobError>,
    ) -> Result<GridBuild, GridJobError> {
        let at = self.snapshot_at(splits);
        build_from_frames(geometry, &self.config, frames, at, self.progress, next)
    }

    fn synthetic(
        &self,
        cells: usize,
        days: u32,
        seed: u64,
        threads: Option<usize>,
    ) -> Result<BuiltGrid, GridJobError> {
        let workload = office(cells, days, seed)?;
        let geometry = workload.geometry()?;
        let frames = workload.frames();
        let splits = holdout_splits(frames, self.holdout);
        let at = self.snapshot_at(&splits);
        let started = Instant::now();
        let build = |parallelism| {
            build_partitioned(
                &workload,
                geometry,
                &self.config,
                at,
                parallelism,
                self.progress,
            )
        };
        let build = match threads {
            None => build(Parallelism::Rayon(0))?,
            Some(threads) => rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()?
                .install(|| build(Parallelism::Rayon(0)))?,
        };
        let source = format!("synthetic office (seed {seed})");
        Ok(BuiltGrid::new(build, splits, started, source))
    }

    fn map_list(&self, list: &Path, semantics: LoadSemantics) -> Result<BuiltGrid, GridJobError> {
        let started = Instant::now();
        let name = list.display().to_string();
        let frames = read_frame_list(list)?;
        let first = load_frame_map(&name, &frames[0], semantics, None)?;
        let geometry = GridGeometry::planar(
            first.width,
            first.height,
            f64::from(first.resolution),
            [first.origin[0], first.origin[1]],
        )?;
        let splits = holdout_splits(frames.len() as u64, self.holdout);
        let build = self.read_frames(geometry, frames.len(), &splits, |f, grid| {
            let frame = &frames[f];
            let map = if f == 0 {
                first.clone()
            } else {
                load_next_frame_map(&name, frame, semantics, &frames[0], &first)?
            };
            grid.observe_occupancy(frame.time, &map.data)
                .map_err(|source| GridJobError::Frame {
                    list: name.clone(),
                    line: frame.line,
                    map: frame.map.display().to_string(),
                    source,
                })
        })?;
        Ok(BuiltGrid::new(build, splits, started, name))
    }

    /// Frames from the `nav_msgs/msg/OccupancyGrid` messages of a bag's topic, observed as a
    /// list of map files is. With snapshots, a first pass counts the maps to place the
    /// hold-out splits.
    fn bag(&self, bag: &Path, topic: &str, time: TimeSource) -> Result<BuiltGrid, GridJobError> {
        let started = Instant::now();
        let bag = Bag::open(bag)?;
        let count = if self.snapshots {
            bag.count_messages(topic, self.progress)?
        } else {
            0
        };
        let splits = holdout_splits(count, self.holdout);
        let at = self.snapshot_at(&splits);
        let mut builder: Option<(GridBuilder, MapFrame)> = None;
        bag.for_each_map(topic, time, self.progress, |frame| {
            let (builder, first) = match &mut builder {
                Some(b) => b,
                None => {
                    let geometry = GridGeometry::planar(
                        frame.width,
                        frame.height,
                        f64::from(frame.resolution),
                        [frame.origin[0], frame.origin[1]],
                    )
                    .map_err(|e| e.to_string())?;
                    let new =
                        GridBuilder::new(geometry, &self.config, at).map_err(|e| e.to_string())?;
                    let first = MapFrame {
                        data: Vec::new(),
                        ..frame.clone()
                    };
                    builder.insert((new, first))
                }
            };
            if (frame.width, frame.height, frame.resolution, frame.origin)
                != (first.width, first.height, first.resolution, first.origin)
            {
                return Err(format!(
                    "the map is {}x{} cells of {} m at {:?}, but the first map is {}x{} of {} m \
                     at {:?} (a grid needs maps of one geometry)",
                    frame.width,
                    frame.height,
                    frame.resolution,
                    frame.origin,
                    first.width,
                    first.height,
                    first.resolution,
                    first.origin
                ));
            }
            builder
                .next_frame()
                .observe_occupancy(frame.time, &frame.data)
                .map_err(|e| e.to_string())
        })?;
        let Some((builder, _)) = builder else {
            return Err(GridJobError::NoMap {
                bag: bag.name().to_string(),
                topic: topic.to_string(),
            });
        };
        let frames = builder.frames();
        let splits = if self.snapshots {
            splits
        } else {
            holdout_splits(frames, self.holdout)
        };
        let source = format!("{} {topic}", bag.name());
        Ok(BuiltGrid::new(builder.finish(), splits, started, source))
    }

    fn cell_series(&self, files: &[PathBuf]) -> Result<BuiltGrid, GridJobError> {
        let started = Instant::now();
        let series = files
            .iter()
            .map(read_pairs)
            .collect::<Result<Vec<_>, _>>()?;
        let reference = &series[0];
        for (s, file) in series.iter().zip(files).skip(1) {
            if s.times != reference.times {
                return Err(GridJobError::SeriesTimes {
                    file: file.display().to_string(),
                    first: files[0].display().to_string(),
                });
            }
        }
        let geometry = GridGeometry::planar(series.len() as u32, 1, 1.0, [0.0, 0.0])?;
        let splits = holdout_splits(reference.len() as u64, self.holdout);
        let build = self.read_frames(geometry, reference.len(), &splits, |f, grid| {
            let frame: Vec<i8> = series
                .iter()
                .map(|s| occupancy_percent(s.values[f]))
                .collect();
            Ok(grid.observe_occupancy(reference.times[f], &frame)?)
        })?;
        let source = format!("{} cell series", files.len());
        Ok(BuiltGrid::new(build, splits, started, source))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_core::progress::NoProgress;

    fn settings(order: Option<usize>, errors: bool) -> BuildSettings {
        BuildSettings {
            periods: "day".parse().unwrap(),
            order,
            holdout: 0.25,
            errors,
            store: GridStore::Lossy,
        }
    }

    #[test]
    fn cell_series_build_a_row_of_cells_held_back_at_the_splits() {
        let dir = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-app-grid-{}", std::process::id())),
        );
        // 16 frames of two cells: one always free, one a door open in the day's first half.
        let mut always = String::new();
        let mut door = String::new();
        for f in 0..16 {
            let t = f * 21_600;
            always.push_str(&format!("{t} 0\n"));
            door.push_str(&format!("{t} {}\n", u8::from(f % 4 < 2)));
        }
        let files = [
            chronomap_testutil::write(&dir, "a.txt", &always),
            chronomap_testutil::write(&dir, "b.txt", &door),
        ];
        let source = FrameSource::CellSeries(&files);
        let built = build_grid(&source, &settings(None, true), &NoProgress).unwrap();
        assert_eq!(built.source, "2 cell series");
        assert_eq!(built.build.grid.frames(), 16);
        // holdout_splits(16, 0.25) = [9, 12]: snapshots before frames 9 and 12.
        assert_eq!(built.split, 12);
        assert_eq!(built.build.snapshots.len(), 2);
        assert_eq!(built.build.snapshots[0].frames(), 9);
        assert_eq!(built.observations(), 32.0);
        let table = error_table(&built, Parallelism::Sequential, &NoProgress).unwrap();
        // static, orders 1..=5, per cell.
        assert_eq!(table.rows.len(), MAX_ORDER + 2);
        assert_eq!(
            ErrorTable::name(table.rows[0].errors.orders),
            "static (order 0)"
        );
        assert_eq!(table.changed_cells(), Some(1));
        // The door follows the day exactly: order 1 of the day estimates and predicts it.
        assert_eq!(table.rows[1].errors.estimation.mean_cell_error, 0.0);
        assert_eq!(table.rows[1].errors.prediction.mean_cell_error, 0.0);
        assert_eq!(table.rows[0].errors.estimation.mean_cell_error, 0.5);

        let mut other = door.clone();
        other.push_str("400000 1\n");
        let files = [
            files[0].clone(),
            chronomap_testutil::write(&dir, "c.txt", &other),
        ];
        let error = build_grid(
            &FrameSource::CellSeries(&files),
            &settings(Some(1), false),
            &NoProgress,
        )
        .unwrap_err();
        assert_eq!(
            error.to_string(),
            format!(
                "{}: its times differ from those of {} (every cell series must have the same times)",
                files[1].display(),
                files[0].display()
            )
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn without_history_there_is_no_table_and_no_per_cell_orders() {
        let built = build_grid(
            &FrameSource::Synthetic {
                cells: 64,
                days: 2,
                seed: 3,
                threads: Some(1),
            },
            &settings(Some(1), false),
            &NoProgress,
        )
        .unwrap();
        assert_eq!(built.source, "synthetic office (seed 3)");
        assert!(built.build.snapshots.is_empty());
        assert!(matches!(
            error_table(&built, Parallelism::Sequential, &NoProgress),
            Err(GridJobError::NoSnapshots)
        ));
        assert!(matches!(
            built.orders(None, Parallelism::Sequential),
            Err(GridJobError::NoSnapshot)
        ));
        assert_eq!(
            built.orders(Some(1), Parallelism::Sequential).unwrap(),
            OrderChoice::Fixed(1)
        );
    }
}
