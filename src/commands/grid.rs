//! `chronomap grid build | predict | stats | plot`: spatio-temporal occupancy grids and the
//! time-specific maps they predict ([Krajník 2017] §VI, §VIII).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, anyhow, ensure};
use chronomap_core::metrics::compression_ratio;
use chronomap_core::progress::Progress;
use chronomap_core::{FremenConfig, Parallelism};
use chronomap_grid::build::{
    GridBuild, GridBuilder, build_from_frames, build_partitioned, holdout_splits, occupancy_percent,
};
use chronomap_grid::report::{OrderErrors, RowOrders, order_errors, project_layers};
use chronomap_grid::{
    AnyGrid, FittedGrid, FremenGrid, GridConfig, GridGeometry, GridStore, OrderChoice,
};
use chronomap_io::navmap::{LoadSemantics, MapMode, SaveOptions, save_map};
use chronomap_io::output::write_output;
use chronomap_io::{
    encode_grid, load_frame_map, load_next_frame_map, read_frame_list, read_grid_file, read_pairs,
};
use chronomap_plot::{MapImage, render_maps_png};
use chronomap_rosbag::{Bag, MapFrame};
use chronomap_spatial::OccupancyMap;
use chronomap_synth::office_grid::office;
use serde_json::{Value, json};

use crate::cli::{
    GridBuildArgs, GridPlotArgs, GridPredictArgs, GridStatsArgs, Layers, MapModeArg, OrderArg,
    StoreArg,
};
use crate::format::{Table, duration, time};
use crate::outln;
use crate::output::{ProgressBar, closed_pipe, print_json, usage};

/// Largest order `auto` and the error table consider.
const MAX_ORDER: usize = 5;

/// A built grid, where it came from and how long it took.
struct Built {
    build: GridBuild,
    /// The first held-back frame.
    split: u64,
    seconds: f64,
    source: String,
}

impl Built {
    /// `build`, held back from the second of `splits`, built since `started` from `source`.
    fn new(build: GridBuild, splits: [u64; 2], started: Instant, source: String) -> Self {
        Self {
            build,
            split: splits[1],
            seconds: started.elapsed().as_secs_f64(),
            source,
        }
    }
}

/// What every source of frames builds with: the flags, the grid's configuration, whether to
/// snapshot the grid at the hold-out splits (for the error table) and where to show progress.
struct BuildJob<'a> {
    args: &'a GridBuildArgs,
    config: &'a GridConfig,
    snapshots: bool,
    progress: &'a dyn Progress,
}

impl BuildJob<'_> {
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
        next: impl FnMut(usize, &mut FremenGrid) -> Result<()>,
    ) -> Result<GridBuild> {
        let at = self.snapshot_at(splits);
        build_from_frames(geometry, self.config, frames, at, self.progress, next)
    }
}

pub fn build(args: &GridBuildArgs) -> Result<()> {
    let needs_history =
        args.errors || args.store == StoreArg::Lossless || args.order == OrderArg::Auto;
    let fremen = FremenConfig {
        periods: args.periods.clone(),
        order: match args.order {
            OrderArg::Fixed(k) => k,
            OrderArg::Auto => 2,
        },
        ..FremenConfig::default()
    };
    let config = GridConfig {
        fremen,
        keep_history: needs_history,
    };
    let built = {
        let bar = ProgressBar::new();
        let job = BuildJob {
            args,
            config: &config,
            snapshots: needs_history,
            progress: &bar,
        };
        if args.source.synthetic {
            build_from_synthetic(&job)?
        } else if let Some(list) = &args.source.frames {
            build_from_map_list(list, &job)?
        } else if let Some(bag) = &args.source.bag {
            build_from_bag(bag, &job)?
        } else {
            build_from_cell_series(&args.source.cell_series, &job)?
        }
    };
    let grid = &built.build.grid;
    let geometry = *grid.geometry();
    let span = grid.frame_span();
    let observations = geometry.cells() as f64 * grid.frames() as f64;
    // A closed stdout must not keep the grid file from being written: reports before the
    // write are dropped once the pipe is closed, and the command ends after the write.
    let mut closed = false;
    if !args.json {
        closed |= closed_pipe(
            outln!(
                "{}: {} frames from {} to {} ({}), {} cells ({}x{}x{} at {} m)",
                built.source,
                grid.frames(),
                time(span.first),
                time(span.last),
                duration(span.duration()),
                geometry.cells(),
                geometry.width,
                geometry.height,
                geometry.depth,
                geometry.resolution
            )
            .map_err(Into::into),
        )?;
        if !closed {
            closed |= closed_pipe(
                outln!(
                    "built in {:.2} s: {} cells changed or needed storage, grid memory {:.1} MB",
                    built.seconds,
                    grid.dynamic_cells(),
                    grid.memory_bytes() as f64 / 1048576.0
                )
                .map_err(Into::into),
            )?;
        }
    }
    let choice = match args.order {
        OrderArg::Fixed(k) => OrderChoice::Fixed(k),
        OrderArg::Auto => {
            let trained = built
                .build
                .snapshots
                .last()
                .context("no held-back snapshot")?;
            OrderChoice::PerCell(grid.select_cell_orders(
                trained,
                MAX_ORDER,
                Parallelism::Rayon(0),
            )?)
        }
    };
    let errors = if args.errors {
        let table = error_table(&built, observations)?;
        if !(args.json || closed) {
            closed |= closed_pipe(print_error_table(&built, &table))?;
        }
        Some(table)
    } else {
        None
    };
    let form = match args.store {
        StoreArg::State => GridStore::State,
        StoreArg::Lossy => GridStore::Lossy,
        StoreArg::Lossless => GridStore::Lossless,
    };
    let file = AnyGrid::store(grid, form, choice, Parallelism::Rayon(0))?;
    // The size of eq. (16) is what was written (a device or a pipe is written through and
    // has no size afterwards).
    let encoded = encode_grid(&file)?;
    write_output(&args.output, &encoded)?;
    if closed {
        return Ok(());
    }
    let bytes = encoded.len();
    let ratio = compression_ratio(observations, bytes);
    if args.json {
        return print_json(&json!({
            "source": built.source,
            "frames": grid.frames(),
            "first": span.first,
            "last": span.last,
            "geometry": geometry_json(&geometry),
            "seconds": built.seconds,
            "dynamic_cells": grid.dynamic_cells(),
            "memory_mb": grid.memory_bytes() as f64 / 1048576.0,
            "errors": errors.map(|t| t.json(built.split, grid.frames())),
            "output": args.output.display().to_string(),
            "kind": chronomap_io::grid_kind(&file),
            "bytes": bytes,
            "compression_ratio": ratio,
        }));
    }
    outln!(
        "wrote {} ({}, {} bytes, compression 1:{:.0} by eq. 16)",
        args.output.display(),
        chronomap_io::grid_kind(&file),
        bytes,
        ratio
    )?;
    Ok(())
}

/// The rows of the error table of [Krajník 2017] §VI with the sizes of their files.
struct ErrorTable {
    rows: Vec<(OrderErrors, usize, usize)>,
    observations: f64,
    seconds: f64,
}

impl ErrorTable {
    fn name(orders: RowOrders) -> String {
        match orders {
            RowOrders::Fixed(0) => "static (order 0)".to_string(),
            RowOrders::Fixed(k) => format!("FreMEn order {k}"),
            RowOrders::PerCell => "FreMEn auto (per cell)".to_string(),
        }
    }

    fn json(&self, split: u64, frames: u64) -> Value {
        json!({
            "changed_cells": self.rows.last().map(|r| r.0.estimation.changed_cells),
            "split": split,
            "frames": frames,
            "rows": self.rows.iter().map(|(r, lossy, lossless)| json!({
                "model": Self::name(r.orders),
                "order": match r.orders {
                    RowOrders::Fixed(k) => json!(k),
                    RowOrders::PerCell => json!("auto"),
                },
                "estimation_error": r.estimation.mean_cell_error,
                "prediction_error": r.prediction.mean_cell_error,
                "lossy_bytes": lossy,
                "lossy_ratio": compression_ratio(self.observations, *lossy),
                "lossless_bytes": lossless,
                "lossless_ratio": compression_ratio(self.observations, *lossless),
            })).collect::<Vec<_>>(),
        })
    }
}

/// Estimation and prediction errors for static, orders 1..5 and per-cell auto, and the sizes
/// of their lossy and lossless files.
fn error_table(built: &Built, observations: f64) -> Result<ErrorTable> {
    let grid = &built.build.grid;
    let [inner, trained] = &built.build.snapshots[..] else {
        return Err(anyhow!("the error report needs two held-back snapshots"));
    };
    let started = Instant::now();
    let bar = ProgressBar::new();
    let rows = order_errors(grid, inner, trained, MAX_ORDER, Parallelism::Rayon(0), &bar)?;
    bar.stage("file sizes", rows.len() as u64);
    let rows = rows
        .into_iter()
        .map(|r| {
            let lossless = grid.lossless(r.final_orders.clone(), Parallelism::Rayon(0))?;
            let lossy = encode_grid(&AnyGrid::Lossy(Box::new(r.fitted.clone())))?.len();
            let lossless = encode_grid(&AnyGrid::Lossless(Box::new(lossless)))?.len();
            bar.advance(1);
            Ok((r, lossy, lossless))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(ErrorTable {
        rows,
        observations,
        seconds: started.elapsed().as_secs_f64(),
    })
}

fn print_error_table(built: &Built, errors: &ErrorTable) -> Result<()> {
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
    for (r, lossy, lossless) in &errors.rows {
        table.row([
            ErrorTable::name(r.orders),
            format!("{:.2} %", 100.0 * r.estimation.mean_cell_error),
            format!("{:.2} %", 100.0 * r.prediction.mean_cell_error),
            lossy.to_string(),
            format!("1:{:.0}", compression_ratio(errors.observations, *lossy)),
            lossless.to_string(),
            format!("1:{:.0}", compression_ratio(errors.observations, *lossless)),
        ]);
    }
    let changed = errors
        .rows
        .last()
        .map_or(0, |r| r.0.estimation.changed_cells);
    outln!(
        "\nErrors over the {changed} cells that changed ([Krajník 2017] §VI: mean over those cells of the fraction of \
         wrongly estimated states). Estimation: models built on all {frames} frames. Prediction: models \
         built on the first {split} frames, tested on the {} after them.",
        frames - split
    )?;
    outln!("{}", table.render())?;
    outln!(
        "([Krajník 2017] §VI: static ~6 %, lossy FreMEn 3-4 %, lossless 1:250; computed in {:.1} s)\n",
        errors.seconds
    )?;
    Ok(())
}

fn build_from_synthetic(job: &BuildJob) -> Result<Built> {
    let args = job.args;
    let workload = office(args.cells, args.days, args.seed)?;
    let geometry = workload.geometry()?;
    let frames = workload.frames();
    let splits = holdout_splits(frames, args.holdout);
    let at = job.snapshot_at(&splits);
    let started = Instant::now();
    let build = |parallelism| {
        build_partitioned(
            &workload,
            geometry,
            job.config,
            at,
            parallelism,
            job.progress,
        )
    };
    let build = match args.threads {
        None => build(Parallelism::Rayon(0))?,
        Some(threads) => rayon::ThreadPoolBuilder::new()
            .num_threads(threads as usize)
            .build()?
            .install(|| build(Parallelism::Rayon(0)))?,
    };
    let source = format!("synthetic office (seed {})", args.seed);
    Ok(Built::new(build, splits, started, source))
}

fn build_from_map_list(list: &Path, job: &BuildJob) -> Result<Built> {
    let started = Instant::now();
    let args = job.args;
    let name = list.display().to_string();
    let frames = read_frame_list(list)?;
    let semantics = if args.ros1 {
        LoadSemantics::Ros1
    } else {
        LoadSemantics::Nav2
    };
    let first = load_frame_map(&name, &frames[0], semantics, None)?;
    let geometry = GridGeometry::planar(
        first.width,
        first.height,
        f64::from(first.resolution),
        [first.origin[0], first.origin[1]],
    )?;
    let splits = holdout_splits(frames.len() as u64, args.holdout);
    let build = job.read_frames(geometry, frames.len(), &splits, |f, grid| {
        let frame = &frames[f];
        let map = if f == 0 {
            first.clone()
        } else {
            load_next_frame_map(&name, frame, semantics, &frames[0], &first)?
        };
        grid.observe_occupancy(frame.time, &map.data)
            .with_context(|| format!("{name}:{}: {}", frame.line, frame.map.display()))
    })?;
    Ok(Built::new(build, splits, started, name))
}

/// Frames from the `nav_msgs/msg/OccupancyGrid` messages of a bag's topic, observed as
/// `build_from_map_list` observes map files. With snapshots, a first pass counts the maps to
/// place the hold-out splits.
fn build_from_bag(bag: &Path, job: &BuildJob) -> Result<Built> {
    let started = Instant::now();
    let args = job.args;
    let topic = args
        .topic
        .as_deref()
        .ok_or_else(|| usage("--bag needs --topic"))?;
    let bag = Bag::open(bag)?;
    let count = if job.snapshots {
        bag.count_messages(topic, job.progress)?
    } else {
        0
    };
    let splits = holdout_splits(count, args.holdout);
    let at = job.snapshot_at(&splits);
    let mut builder: Option<(GridBuilder, MapFrame)> = None;
    bag.for_each_map(topic, args.time.into(), job.progress, |frame| {
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
                let new = GridBuilder::new(geometry, job.config, at).map_err(|e| e.to_string())?;
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
                "the map is {}x{} cells of {} m at {:?}, but the first map is {}x{} of {} m at {:?} \
                 (a grid needs maps of one geometry)",
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
        return Err(anyhow!("{}: topic {topic} has no map", bag.name()));
    };
    let frames = builder.frames();
    let splits = if job.snapshots {
        splits
    } else {
        holdout_splits(frames, args.holdout)
    };
    let source = format!("{} {topic}", bag.name());
    Ok(Built::new(builder.finish(), splits, started, source))
}

fn build_from_cell_series(files: &[PathBuf], job: &BuildJob) -> Result<Built> {
    let started = Instant::now();
    let series = files
        .iter()
        .map(read_pairs)
        .collect::<Result<Vec<_>, _>>()?;
    let reference = &series[0];
    for (s, file) in series.iter().zip(files).skip(1) {
        ensure!(
            s.times == reference.times,
            "{}: its times differ from those of {} (every cell series must have the same times)",
            file.display(),
            files[0].display()
        );
    }
    let geometry = GridGeometry::planar(series.len() as u32, 1, 1.0, [0.0, 0.0])?;
    let splits = holdout_splits(reference.len() as u64, job.args.holdout);
    let build = job.read_frames(geometry, reference.len(), &splits, |f, grid| {
        let frame: Vec<i8> = series
            .iter()
            .map(|s| occupancy_percent(s.values[f]))
            .collect();
        Ok(grid.observe_occupancy(reference.times[f], &frame)?)
    })?;
    let source = format!("{} cell series", files.len());
    Ok(Built::new(build, splits, started, source))
}

/// The compact model in a grid file (learning-state files are fitted with `order`).
fn fitted_of(file: AnyGrid, order: Option<usize>) -> Result<FittedGrid> {
    match file.into_fitted(order, Parallelism::Rayon(0)) {
        Ok(fitted) => Ok(fitted),
        Err(_) => Err(usage(
            "--order needs a learning-state grid file (this one stores a fitted model)",
        )),
    }
}

/// The layers of `--layers` (default all) of a grid `depth` layers deep.
fn layers(layers: Option<Layers>, depth: u32) -> Result<std::ops::Range<u32>> {
    match layers {
        None => Ok(0..depth),
        Some(Layers(a, b)) if b <= depth => Ok(a..b),
        Some(Layers(a, b)) => Err(usage(format!(
            "--layers {a}..{b} is not within 0..{depth} (the grid's layers)"
        ))),
    }
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

pub fn predict(args: &GridPredictArgs) -> Result<()> {
    let fitted = fitted_of(read_grid_file(&args.grid)?, args.order)?;
    let g = *fitted.geometry();
    let values = project_layers(
        &g,
        &fitted.predict_map(args.time),
        layers(args.layers, g.depth)?,
    );
    let map = OccupancyMap::from_probabilities(
        g.width,
        g.height,
        g.resolution as f32,
        [g.origin[0], g.origin[1], 0.0],
        &values,
    );
    // `-o map.yaml` and `-o map` both mean map.yaml + map.pgm/png.
    let base = if args
        .output
        .extension()
        .is_some_and(|e| e == "yaml" || e == "yml")
    {
        args.output.with_extension("")
    } else {
        args.output.clone()
    };
    if let Some(folder) = base.parent().filter(|f| !f.as_os_str().is_empty()) {
        std::fs::create_dir_all(folder)
            .with_context(|| format!("cannot create {}", folder.display()))?;
    }
    let options = SaveOptions {
        mode: match args.mode {
            MapModeArg::Trinary => MapMode::Trinary,
            MapModeArg::Scale => MapMode::Scale,
        },
        comment: Some(format!(
            "map predicted by chronomap {} for t = {} ({})",
            env!("CARGO_PKG_VERSION"),
            args.time,
            time(args.time)
        )),
        // ROS 1 map_saver's free threshold: with Nav2's default 0.25 the unknown grey (205,
        // p = 0.196) would be read back as free.
        free_thresh: 0.196,
        ..SaveOptions::default()
    };
    let saved = save_map(&base, &map, &options)?;
    let occupied = map.data.iter().filter(|&&v| v >= 65).count();
    let unknown = map.data.iter().filter(|&&v| v < 0).count();
    if args.json {
        return print_json(&json!({
            "grid": args.grid.display().to_string(),
            "time": args.time,
            "width": map.width,
            "height": map.height,
            "occupied": occupied,
            "unknown": unknown,
            "free": map.data.len() - occupied - unknown,
            "mode": options.mode.as_str(),
            "yaml": saved.yaml.display().to_string(),
            "image": saved.image.display().to_string(),
        }));
    }
    outln!(
        "predicted {}x{} map for {}: {occupied} occupied, {unknown} unknown cells; wrote {} and {}",
        map.width,
        map.height,
        time(args.time),
        saved.yaml.display(),
        saved.image.display()
    )?;
    Ok(())
}

pub fn stats(args: &GridStatsArgs) -> Result<()> {
    let bytes = std::fs::metadata(&args.grid)
        .with_context(|| format!("{}: cannot read", args.grid.display()))?
        .len();
    let file = read_grid_file(&args.grid)?;
    let (geometry, frames) = (*file.geometry(), file.frame_span());
    let observations = geometry.cells() as f64 * frames.count as f64;
    let ratio = (frames.count > 0).then(|| compression_ratio(observations, bytes as usize));
    if args.json {
        let contents = match &file {
            AnyGrid::State(grid) => state_json(grid),
            AnyGrid::Lossy(fitted) => fitted_json(fitted),
            AnyGrid::Lossless(lossless) => {
                let mut value = fitted_json(&lossless.fitted);
                value["outlier_toggles"] = json!(lossless.outlier_toggles());
                value
            }
        };
        return print_json(&json!({
            "file": args.grid.display().to_string(),
            "kind": chronomap_io::grid_kind(&file),
            "bytes": bytes,
            "geometry": geometry_json(&geometry),
            "frames": (frames.count > 0).then(|| json!({
                "count": frames.count,
                "first": frames.first,
                "last": frames.last,
            })),
            "cell_observations": observations,
            "compression_ratio": ratio,
            "contents": contents,
        }));
    }
    outln!(
        "file: {} ({}, {bytes} bytes)",
        args.grid.display(),
        chronomap_io::grid_kind(&file)
    )?;
    outln!(
        "grid: {}x{}x{} cells at {} m, origin {:?}",
        geometry.width,
        geometry.height,
        geometry.depth,
        geometry.resolution,
        geometry.origin
    )?;
    if let Some(ratio) = ratio {
        outln!(
            "frames: {} from {} to {} ({})",
            frames.count,
            time(frames.first),
            time(frames.last),
            duration(frames.duration())
        )?;
        outln!(
            "compression (eq. 16): {observations:.3e} cell observations in {bytes} bytes = 1:{ratio:.0}"
        )?;
    }
    let extra = match &file {
        AnyGrid::State(grid) => format!(
            "{} cells with storage, {:.1} MB in memory, periods {}",
            grid.dynamic_cells(),
            grid.memory_bytes() as f64 / 1048576.0,
            grid.config().fremen.periods
        ),
        AnyGrid::Lossy(fitted) => describe_fitted(fitted),
        AnyGrid::Lossless(lossless) => format!(
            "{}; {} outlier toggles",
            describe_fitted(&lossless.fitted),
            lossless.outlier_toggles()
        ),
    };
    outln!("{extra}")?;
    Ok(())
}

fn state_json(grid: &FremenGrid) -> Value {
    json!({
        "dynamic_cells": grid.dynamic_cells(),
        "memory_mb": grid.memory_bytes() as f64 / 1048576.0,
        "periods": grid.config().fremen.periods.to_string(),
        "order": grid.config().fremen.order,
    })
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

pub fn plot(args: &GridPlotArgs) -> Result<()> {
    let fitted = fitted_of(read_grid_file(&args.grid)?, args.order)?;
    let g = *fitted.geometry();
    let times = if args.times.is_empty() {
        let last = fitted.frames().last;
        let day = (last / 86_400.0).floor() * 86_400.0 + 86_400.0;
        vec![day + 3.0 * 3600.0, day + 14.0 * 3600.0]
    } else {
        args.times.clone()
    };
    let range = layers(args.layers, g.depth)?;
    let maps: Vec<MapImage> = times
        .iter()
        .map(|&t| MapImage {
            title: format!("predicted for {}", time(t)),
            width: g.width,
            height: g.height,
            values: project_layers(&g, &fitted.predict_map(t), range.clone()),
        })
        .collect();
    let cell_pixels = (700 / g.width.max(g.height)).clamp(1, 40);
    render_maps_png(&maps, &args.plot, cell_pixels)?;
    outln!("wrote {}", args.plot.display())?;
    Ok(())
}
