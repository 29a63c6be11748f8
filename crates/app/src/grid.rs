//! The grid build job ([Krajník 2017] §VI): frames read from a source (the synthetic office of
//! §VI, a list of map files, the maps of a bag's topic, one series per cell), built into a
//! [`FremenGrid`] with snapshots at the hold-out splits, the orders chosen for the file, and the
//! error table of §VI (estimation and prediction errors of static, orders 1..5 and per-cell
//! orders, with the sizes of their lossy and lossless files).
//!
//! Beside the job, the reports of a grid: the build's summary and error table, what a grid
//! file holds ([`GridStats`], the compression ratio of eq. (16)) and the time-specific map a
//! grid predicts (§VIII) written as a Nav2 map ([`write_predicted_map`]); each renders itself
//! as text and as the JSON the faces print.
//!
//! Files in, result structs out: progress goes to a [`Progress`], threads are a
//! [`Parallelism`]; the faces print.

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_core::Parallelism;
use chronomap_core::PeriodSet;
use chronomap_core::fremen::FremenConfig;
use chronomap_core::metrics::compression_ratio;
use chronomap_core::progress::Progress;
#[cfg(feature = "rosbag")]
use chronomap_grid::build::GridBuilder;
use chronomap_grid::build::{
    GridBuild, PartitionError, build_from_frames, build_partitioned, holdout_splits,
    occupancy_percent,
};
use chronomap_grid::report::{OrderErrors, RowOrders, order_errors, project_layers};
use chronomap_grid::{
    AnyGrid, FittedGrid, FremenGrid, GridConfig, GridError, GridGeometry, GridStore, OrderChoice,
};
use chronomap_io::frame_list::FrameMapError;
use chronomap_io::model_file::ModelFileError;
use chronomap_io::navmap::{LoadSemantics, MapMode, NavMapError, SaveOptions, SavedMap, save_map};
use chronomap_io::output::{OutputError, write_output};
use chronomap_io::{
    DataError, encode_grid, load_frame_map, load_next_frame_map, read_frame_list, read_grid_file,
    read_pairs,
};
#[cfg(feature = "rosbag")]
use chronomap_rosbag::{Bag, BagError, MapFrame, TimeSource};
use chronomap_spatial::OccupancyMap;
use chronomap_synth::SynthError;
use chronomap_synth::office_grid::office;
use serde_json::{Value, json};
use thiserror::Error;

use crate::report::{Table, duration, time};

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
    #[cfg(feature = "rosbag")]
    #[error(transparent)]
    Bag(#[from] BagError),
    /// A bag's topic holds no map.
    #[cfg(feature = "rosbag")]
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
    /// A grid cannot be encoded (for the sizes of the error table), or a grid file cannot be
    /// read.
    #[error(transparent)]
    ModelFile(#[from] ModelFileError),
    /// The grid file cannot be written.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// A file's size cannot be read.
    #[error("{path}: cannot read")]
    Read {
        /// The file.
        path: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The folder of a map cannot be made.
    #[error("cannot create {folder}")]
    CreateFolder {
        /// The folder.
        folder: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A predicted map cannot be written.
    #[error(transparent)]
    Map(#[from] NavMapError),
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
    #[cfg(feature = "rosbag")]
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
    /// Whether the grid keeps every cell's history although nothing of this build needs it
    /// (a learning state that may later be stored lossless, as Python's `keep_history=True`).
    pub keep_history: bool,
}

impl BuildSettings {
    /// Whether the build takes snapshots at the hold-out splits, keeping the history: for the
    /// error table, a lossless file or per-cell orders.
    pub fn needs_snapshots(&self) -> bool {
        self.errors || self.store == GridStore::Lossless || self.order.is_none()
    }

    /// Whether the grid keeps its history: when it takes snapshots, or is asked to.
    pub fn needs_history(&self) -> bool {
        self.needs_snapshots() || self.keep_history
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
        snapshots: settings.needs_snapshots(),
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
        #[cfg(feature = "rosbag")]
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

/// The grid file written by [`write_grid`]: its form and size.
#[derive(Clone, Copy, Debug)]
pub struct WrittenGrid {
    /// The form's name in the file (`grid-state`, `grid-lossy`, …).
    pub kind: &'static str,
    /// Bytes written.
    pub bytes: usize,
}

/// Stores the grid of `built` as `store` with `orders` and writes it to `output` (a device or
/// a pipe is written through, so the size is what was written, for eq. (16)).
///
/// # Errors
/// [`GridJobError`]: a lossless file of a grid without history, encoding or writing.
pub fn write_grid(
    built: &BuiltGrid,
    store: GridStore,
    orders: OrderChoice,
    output: &Path,
) -> Result<WrittenGrid, GridJobError> {
    let file = AnyGrid::store(&built.build.grid, store, orders, Parallelism::Rayon(0))?;
    let encoded = encode_grid(&file)?;
    write_output(output, &encoded)?;
    Ok(WrittenGrid {
        kind: chronomap_io::grid_kind(&file),
        bytes: encoded.len(),
    })
}

impl BuiltGrid {
    /// The two lines `chronomap grid build` prints once the grid is built: its frames and
    /// geometry, the build time and memory.
    pub fn summary(&self) -> String {
        let grid = &self.build.grid;
        let g = grid.geometry();
        let span = grid.frame_span();
        format!(
            "{}: {} frames from {} to {} ({}), {} cells ({}x{}x{} at {} m)\n\
             built in {:.2} s: {} cells changed or needed storage, grid memory {:.1} MB",
            self.source,
            grid.frames(),
            time(span.first),
            time(span.last),
            duration(span.duration()),
            g.cells(),
            g.width,
            g.height,
            g.depth,
            g.resolution,
            self.seconds,
            grid.dynamic_cells(),
            megabytes(grid.memory_bytes())
        )
    }

    /// `chronomap grid build --json`: the grid, its error table and the file written.
    pub fn json(&self, errors: Option<&ErrorTable>, output: &Path, written: &WrittenGrid) -> Value {
        let grid = &self.build.grid;
        let span = grid.frame_span();
        json!({
            "source": self.source,
            "frames": grid.frames(),
            "first": span.first,
            "last": span.last,
            "geometry": geometry_json(grid.geometry()),
            "seconds": self.seconds,
            "dynamic_cells": grid.dynamic_cells(),
            "memory_mb": megabytes(grid.memory_bytes()),
            "errors": errors.map(|t| t.json(self.split, grid.frames())),
            "output": output.display().to_string(),
            "kind": written.kind,
            "bytes": written.bytes,
            "compression_ratio": compression_ratio(self.observations(), written.bytes),
        })
    }

    /// The last line of `chronomap grid build`: the file written and its compression ratio
    /// (eq. (16)).
    pub fn written_text(&self, output: &Path, written: &WrittenGrid) -> String {
        format!(
            "wrote {} ({}, {} bytes, compression 1:{:.0} by eq. 16)",
            output.display(),
            written.kind,
            written.bytes,
            compression_ratio(self.observations(), written.bytes)
        )
    }
}

impl ErrorTable {
    /// The table as JSON, for a grid of `frames` frames held back from `split` on.
    pub fn json(&self, split: u64, frames: u64) -> Value {
        json!({
            "changed_cells": self.changed_cells(),
            "split": split,
            "frames": frames,
            "rows": self.rows.iter().map(|r| json!({
                "model": ErrorTable::name(r.errors.orders),
                "order": match r.errors.orders {
                    RowOrders::Fixed(k) => json!(k),
                    RowOrders::PerCell => json!("auto"),
                },
                "estimation_error": r.errors.estimation.mean_cell_error,
                "prediction_error": r.errors.prediction.mean_cell_error,
                "lossy_bytes": r.lossy_bytes,
                "lossy_ratio": self.ratio(r.lossy_bytes),
                "lossless_bytes": r.lossless_bytes,
                "lossless_ratio": self.ratio(r.lossless_bytes),
            })).collect::<Vec<_>>(),
        })
    }

    /// The table as text with what it means, beside the figures of [Krajník 2017] §VI
    /// (a blank line before and after).
    pub fn text(&self, built: &BuiltGrid) -> String {
        let (split, frames) = (built.split, built.build.grid.frames());
        let mut table = Table::new([
            "model",
            "estimation error",
            "prediction error",
            "lossy bytes",
            "lossy ratio",
            "lossless bytes",
            "lossless ratio",
        ]);
        for r in &self.rows {
            table.row([
                ErrorTable::name(r.errors.orders),
                format!("{:.2} %", 100.0 * r.errors.estimation.mean_cell_error),
                format!("{:.2} %", 100.0 * r.errors.prediction.mean_cell_error),
                r.lossy_bytes.to_string(),
                format!("1:{:.0}", self.ratio(r.lossy_bytes)),
                r.lossless_bytes.to_string(),
                format!("1:{:.0}", self.ratio(r.lossless_bytes)),
            ]);
        }
        let changed = self.changed_cells().unwrap_or(0);
        format!(
            "\nErrors over the {changed} cells that changed ([Krajník 2017] §VI: mean over those cells of the fraction of \
             wrongly estimated states). Estimation: models built on all {frames} frames. Prediction: models \
             built on the first {split} frames, tested on the {} after them.\n{}\n\
             ([Krajník 2017] §VI: static ~6 %, lossy FreMEn 3-4 %, lossless 1:250; computed in {:.1} s)\n",
            frames - split,
            table.render(),
            self.seconds
        )
    }
}

fn megabytes(bytes: usize) -> f64 {
    bytes as f64 / 1048576.0
}

fn geometry_json(g: &GridGeometry) -> Value {
    json!({
        "width": g.width,
        "height": g.height,
        "depth": g.depth,
        "cells": g.cells(),
        "resolution": g.resolution,
        "origin": g.origin,
    })
}

/// What a grid file holds: its form, geometry, frames and compression ratio (eq. (16)).
#[derive(Clone, Debug)]
pub struct GridStats {
    /// The file, as named.
    pub file: String,
    /// Its size.
    pub bytes: u64,
    /// The grid it holds.
    pub grid: AnyGrid,
}

/// Reads the grid file `path` for [`GridStats`].
///
/// # Errors
/// [`GridJobError::Read`] for a file that cannot be read, or the file's error.
pub fn grid_stats(path: &Path) -> Result<GridStats, GridJobError> {
    let file = path.display().to_string();
    let bytes = std::fs::metadata(path)
        .map_err(|source| GridJobError::Read {
            path: file.clone(),
            source,
        })?
        .len();
    let grid = read_grid_file(path)?;
    Ok(GridStats { file, bytes, grid })
}

impl GridStats {
    /// Cell observations (cells × frames) and the ratio of eq. (16), if there are frames.
    fn compression(&self) -> (f64, Option<f64>) {
        let frames = self.grid.frame_span().count;
        let observations = self.grid.geometry().cells() as f64 * frames as f64;
        let ratio = (frames > 0).then(|| compression_ratio(observations, self.bytes as usize));
        (observations, ratio)
    }

    /// The report as `chronomap grid stats --json` prints it.
    pub fn json(&self) -> Value {
        let frames = self.grid.frame_span();
        let (observations, ratio) = self.compression();
        let contents = match &self.grid {
            AnyGrid::State(grid) => json!({
                "dynamic_cells": grid.dynamic_cells(),
                "memory_mb": megabytes(grid.memory_bytes()),
                "periods": grid.config().fremen.periods.to_string(),
                "order": grid.config().fremen.order,
            }),
            AnyGrid::Lossy(fitted) => fitted_json(fitted),
            AnyGrid::Lossless(lossless) => {
                let mut value = fitted_json(&lossless.fitted);
                value["outlier_toggles"] = json!(lossless.outlier_toggles());
                value
            }
        };
        json!({
            "file": self.file,
            "kind": chronomap_io::grid_kind(&self.grid),
            "bytes": self.bytes,
            "geometry": geometry_json(self.grid.geometry()),
            "frames": (frames.count > 0).then(|| json!({
                "count": frames.count,
                "first": frames.first,
                "last": frames.last,
            })),
            "cell_observations": observations,
            "compression_ratio": ratio,
            "contents": contents,
        })
    }

    /// The report as `chronomap grid stats` prints it.
    pub fn text(&self) -> String {
        let (g, frames) = (self.grid.geometry(), self.grid.frame_span());
        let (observations, ratio) = self.compression();
        let mut lines = vec![
            format!(
                "file: {} ({}, {} bytes)",
                self.file,
                chronomap_io::grid_kind(&self.grid),
                self.bytes
            ),
            format!(
                "grid: {}x{}x{} cells at {} m, origin {:?}",
                g.width, g.height, g.depth, g.resolution, g.origin
            ),
        ];
        if let Some(ratio) = ratio {
            lines.push(format!(
                "frames: {} from {} to {} ({})",
                frames.count,
                time(frames.first),
                time(frames.last),
                duration(frames.duration())
            ));
            lines.push(format!(
                "compression (eq. 16): {observations:.3e} cell observations in {} bytes = 1:{ratio:.0}",
                self.bytes
            ));
        }
        lines.push(match &self.grid {
            AnyGrid::State(grid) => format!(
                "{} cells with storage, {:.1} MB in memory, periods {}",
                grid.dynamic_cells(),
                megabytes(grid.memory_bytes()),
                grid.config().fremen.periods
            ),
            AnyGrid::Lossy(fitted) => describe_fitted(fitted),
            AnyGrid::Lossless(lossless) => format!(
                "{}; {} outlier toggles",
                describe_fitted(&lossless.fitted),
                lossless.outlier_toggles()
            ),
        });
        lines.join("\n")
    }
}

fn fitted_json(fitted: &FittedGrid) -> Value {
    json!({
        "fitted_cells": fitted.cells().len(),
        "orders": fitted
            .order_counts()
            .into_iter()
            .map(|(order, cells)| json!({"order": order, "cells": cells}))
            .collect::<Vec<_>>(),
    })
}

fn describe_fitted(fitted: &FittedGrid) -> String {
    let listed: Vec<String> = fitted
        .order_counts()
        .into_iter()
        .map(|(k, n)| format!("{n} of order {k}"))
        .collect();
    format!(
        "{} cells with a model: {}",
        fitted.cells().len(),
        listed.join(", ")
    )
}

/// The map a fitted grid predicts for `time` ([Krajník 2017] §VIII: a time-specific map),
/// its `layers` projected onto one plane ([`project_layers`]), as an occupancy map.
pub fn predicted_map(fitted: &FittedGrid, time: f64, layers: Range<u32>) -> OccupancyMap {
    let g = fitted.geometry();
    let values = project_layers(g, &fitted.predict_map(time), layers);
    OccupancyMap::from_probabilities(
        g.width,
        g.height,
        g.resolution as f32,
        [g.origin[0], g.origin[1], 0.0],
        &values,
    )
}

/// A predicted map written as a Nav2 map: where, and how many cells of each kind.
#[derive(Clone, Debug)]
pub struct MapReport {
    /// The grid file it was predicted from, as named.
    pub grid: String,
    /// The time it was predicted for.
    pub time: f64,
    /// Cells along x.
    pub width: u32,
    /// Cells along y.
    pub height: u32,
    /// Cells of occupancy 65 % and more.
    pub occupied: usize,
    /// Cells never observed.
    pub unknown: usize,
    /// The other cells.
    pub free: usize,
    /// The image mode.
    pub mode: MapMode,
    /// The files written.
    pub saved: SavedMap,
}

/// Writes the map `fitted` predicts for `time` (`layers` projected) as a Nav2 map at `output`
/// (`map.yaml` or `map`: both write `map.yaml` and its image), in the image `mode`, with ROS 1
/// map_saver's free threshold (the unknown grey stays unknown when loaded back).
///
/// # Errors
/// [`GridJobError`]: the folder or the map cannot be written.
pub fn write_predicted_map(
    grid: &str,
    fitted: &FittedGrid,
    time: f64,
    layers: Range<u32>,
    output: &Path,
    mode: MapMode,
) -> Result<MapReport, GridJobError> {
    let map = predicted_map(fitted, time, layers);
    // `-o map.yaml` and `-o map` both mean map.yaml + map.pgm/png.
    let base = if output
        .extension()
        .is_some_and(|e| e == "yaml" || e == "yml")
    {
        output.with_extension("")
    } else {
        output.to_path_buf()
    };
    if let Some(folder) = base.parent().filter(|f| !f.as_os_str().is_empty()) {
        std::fs::create_dir_all(folder).map_err(|source| GridJobError::CreateFolder {
            folder: folder.display().to_string(),
            source,
        })?;
    }
    let options = SaveOptions {
        mode,
        comment: Some(format!(
            "map predicted by chronomap {} for t = {time} ({})",
            env!("CARGO_PKG_VERSION"),
            crate::report::time(time)
        )),
        // ROS 1 map_saver's free threshold: with Nav2's default 0.25 the unknown grey (205,
        // p = 0.196) would be read back as free.
        free_thresh: 0.196,
        ..SaveOptions::default()
    };
    let saved = save_map(&base, &map, &options)?;
    let occupied = map.data.iter().filter(|&&v| v >= 65).count();
    let unknown = map.data.iter().filter(|&&v| v < 0).count();
    Ok(MapReport {
        grid: grid.to_string(),
        time,
        width: map.width,
        height: map.height,
        occupied,
        unknown,
        free: map.data.len() - occupied - unknown,
        mode,
        saved,
    })
}

impl MapReport {
    /// The report as `chronomap grid predict --json` prints it.
    pub fn json(&self) -> Value {
        json!({
            "grid": self.grid,
            "time": self.time,
            "width": self.width,
            "height": self.height,
            "occupied": self.occupied,
            "unknown": self.unknown,
            "free": self.free,
            "mode": self.mode.as_str(),
            "yaml": self.saved.yaml.display().to_string(),
            "image": self.saved.image.display().to_string(),
        })
    }

    /// The report as `chronomap grid predict` prints it.
    pub fn text(&self) -> String {
        format!(
            "predicted {}x{} map for {}: {} occupied, {} unknown cells; wrote {} and {}",
            self.width,
            self.height,
            time(self.time),
            self.occupied,
            self.unknown,
            self.saved.yaml.display(),
            self.saved.image.display()
        )
    }
}

/// The times `chronomap grid plot` draws when none are asked for: 3:00 and 14:00 of the day
/// after the grid's last frame.
pub fn default_plot_times(fitted: &FittedGrid) -> Vec<f64> {
    let day = (fitted.frames().last / 86_400.0).floor() * 86_400.0 + 86_400.0;
    vec![day + 3.0 * 3600.0, day + 14.0 * 3600.0]
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
    #[cfg(feature = "rosbag")]
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
            keep_history: false,
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
        let text = table.text(&built);
        assert!(
            text.starts_with("\nErrors over the 1 cells that changed"),
            "{text}"
        );
        assert!(
            text.contains(
                "Prediction: models built on the first 12 frames, tested on the 4 after them."
            ),
            "{text}"
        );
        let static_row = text
            .lines()
            .find(|l| l.starts_with("static (order 0)"))
            .unwrap();
        assert!(static_row.contains(" 50.00 %"), "{text}");
        assert_eq!(
            table.json(built.split, 16)["rows"][1]["estimation_error"],
            0.0
        );
        assert!(
            built
                .summary()
                .starts_with("2 cell series: 16 frames from "),
            "{}",
            built.summary()
        );
        assert!(
            built
                .summary()
                .contains(", 2 cells (2x1x1 at 1 m)\nbuilt in ")
        );

        // The lossy file of order 1, what it holds, and the map it predicts at 03:00 of the
        // fifth day: the door open (as in every first half of a day), the other cell free.
        let output = dir.join("door.cmg");
        let written = write_grid(&built, GridStore::Lossy, OrderChoice::Fixed(1), &output).unwrap();
        assert_eq!(written.kind, "grid-lossy");
        assert_eq!(
            built.written_text(&output, &written),
            format!(
                "wrote {} (grid-lossy, {} bytes, compression 1:{:.0} by eq. 16)",
                output.display(),
                written.bytes,
                compression_ratio(32.0, written.bytes)
            )
        );
        let stats = grid_stats(&output).unwrap();
        assert_eq!(stats.bytes as usize, written.bytes);
        let lines: Vec<String> = stats.text().lines().map(str::to_string).collect();
        assert_eq!(lines[1], "grid: 2x1x1 cells at 1 m, origin [0.0, 0.0, 0.0]");
        assert_eq!(lines[4], "1 cells with a model: 1 of order 1");
        assert_eq!(stats.json()["cell_observations"], 32.0);
        assert_eq!(stats.json()["contents"]["fitted_cells"], 1);
        let AnyGrid::Lossy(fitted) = stats.grid else {
            panic!("not a lossy grid")
        };
        let t = 4.0 * 86_400.0 + 3.0 * 3600.0;
        let report = write_predicted_map(
            "door.cmg",
            &fitted,
            t,
            0..1,
            &dir.join("maps/door.yaml"),
            MapMode::Trinary,
        )
        .unwrap();
        assert_eq!((report.occupied, report.unknown, report.free), (1, 0, 1));
        assert_eq!(report.saved.yaml, dir.join("maps/door.yaml"));
        assert!(report.text().starts_with("predicted 2x1 map for "));
        assert_eq!(report.json()["mode"], "trinary");
        assert_eq!(
            default_plot_times(&fitted),
            [
                4.0 * 86_400.0 + 3.0 * 3600.0,
                4.0 * 86_400.0 + 14.0 * 3600.0
            ]
        );

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
