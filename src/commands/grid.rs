//! `chronomap grid build | predict | stats | plot`: spatio-temporal occupancy grids and the
//! time-specific maps they predict (seed 001 §VI, §VIII).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail, ensure};
use chronomap_core::FremenConfig;
use chronomap_grid::{FittedGrid, FremenGrid, GridConfig, GridGeometry, OrderChoice};
use chronomap_io::navmap::{LoadSemantics, MapMode, OccupancyMap, SaveOptions, load_map, save_map};
use chronomap_io::{GridFile, encode_grid, read_grid_file, read_pairs, write_grid_file};
use chronomap_plot::{MapImage, render_maps_png};

use super::synthetic::{build as build_synthetic, office, office_geometry, with_progress};
use crate::cli::{
    GridBuildArgs, GridPlotArgs, GridPredictArgs, GridStatsArgs, MapModeArg, StoreArg,
};
use crate::format::{Table, duration, time};

/// Largest order `auto` and the error table consider.
const MAX_ORDER: usize = 5;

/// The order flag: a number or `auto`.
enum OrderFlag {
    Fixed(usize),
    Auto,
}

fn parse_order(text: &str) -> Result<OrderFlag> {
    match text {
        "auto" => Ok(OrderFlag::Auto),
        k => Ok(OrderFlag::Fixed(k.parse().with_context(|| {
            format!("--order {k:?} is not a whole number or 'auto'")
        })?)),
    }
}

/// A built grid with the snapshots taken at the held-back splits.
struct BuiltGrid {
    grid: FremenGrid,
    /// The grid before frame `split_inner` and before `split` (if requested).
    snapshots: Vec<FremenGrid>,
    split: u64,
    seconds: f64,
    source: String,
}

pub fn build(args: &GridBuildArgs) -> Result<()> {
    let order = parse_order(&args.order)?;
    let needs_history =
        args.errors || args.store == StoreArg::Lossless || matches!(order, OrderFlag::Auto);
    let fremen = FremenConfig {
        periods: args.periods.clone(),
        order: match order {
            OrderFlag::Fixed(k) => k,
            OrderFlag::Auto => 2,
        },
        ..FremenConfig::default()
    };
    let config = GridConfig {
        fremen,
        keep_history: needs_history,
    };
    let built = if args.source.synthetic {
        build_from_synthetic(args, &config, needs_history)?
    } else if let Some(list) = &args.source.frames {
        build_from_map_list(list, args, &config, needs_history)?
    } else {
        build_from_cell_series(&args.source.cell_series, args, &config, needs_history)?
    };
    let grid = &built.grid;
    let geometry = grid.geometry();
    let span = grid.frame_span();
    println!(
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
    );
    println!(
        "built in {:.2} s: {} cells changed or needed storage, grid memory {:.1} MB",
        built.seconds,
        grid.dynamic_cells(),
        grid.memory_bytes() as f64 / 1048576.0
    );
    let observations = geometry.cells() as f64 * grid.frames() as f64;
    let ratio = |bytes: usize| observations / (8.0 * bytes as f64);

    let choice = match order {
        OrderFlag::Fixed(k) => OrderChoice::Fixed(k),
        OrderFlag::Auto => {
            let trained = built.snapshots.last().context("no held-back snapshot")?;
            OrderChoice::PerCell(grid.select_cell_orders(trained, MAX_ORDER)?)
        }
    };
    if args.errors {
        report_errors(&built, ratio)?;
    }
    let file = match args.store {
        StoreArg::State => GridFile::State(Box::new(built.grid.clone())),
        StoreArg::Lossy => GridFile::Lossy(Box::new(grid.fitted(choice))),
        StoreArg::Lossless => GridFile::Lossless(Box::new(grid.lossless(choice)?)),
    };
    write_grid_file(&args.output, &file)?;
    let bytes = std::fs::metadata(&args.output)?.len() as usize;
    println!(
        "wrote {} ({}, {} bytes, compression 1:{:.0} by eq. 16)",
        args.output.display(),
        file.kind(),
        bytes,
        ratio(bytes)
    );
    Ok(())
}

/// The error table of seed 001 §VI: estimation error over all frames, prediction error on the
/// held-back frames, and file sizes, for static, orders 1..5 and per-cell auto.
fn report_errors(built: &BuiltGrid, ratio: impl Fn(usize) -> f64) -> Result<()> {
    let grid = &built.grid;
    let [inner, trained] = &built.snapshots[..] else {
        bail!("the error report needs two held-back snapshots");
    };
    let (split, frames) = (built.split, grid.frames());
    let mut table = Table::new([
        "model",
        "estimation error",
        "prediction error",
        "lossy bytes",
        "lossy ratio",
        "lossless bytes",
        "lossless ratio",
    ]);
    let started = Instant::now();
    let auto_final = OrderChoice::PerCell(grid.select_cell_orders(trained, MAX_ORDER)?);
    // For the prediction error, choose the orders without the frames they are tested on.
    let auto_trained = OrderChoice::PerCell(trained.select_cell_orders(inner, MAX_ORDER)?);
    let mut rows: Vec<(String, OrderChoice, OrderChoice)> = (0..=MAX_ORDER)
        .map(|k| {
            let name = if k == 0 {
                "static (order 0)".to_string()
            } else {
                format!("FreMEn order {k}")
            };
            (name, OrderChoice::Fixed(k), OrderChoice::Fixed(k))
        })
        .collect();
    rows.push(("FreMEn auto (per cell)".into(), auto_final, auto_trained));
    let mut changed = 0;
    for (name, final_orders, trained_orders) in rows {
        let fitted = grid.fitted(final_orders.clone());
        let estimation = grid.estimation_error(&fitted, 0, frames)?;
        let prediction = grid.estimation_error(&trained.fitted(trained_orders), split, frames)?;
        changed = estimation.changed_cells;
        let lossy = encode_grid(&GridFile::Lossy(Box::new(fitted)))?.len();
        let lossless =
            encode_grid(&GridFile::Lossless(Box::new(grid.lossless(final_orders)?)))?.len();
        table.row([
            name,
            format!("{:.2} %", 100.0 * estimation.mean_cell_error),
            format!("{:.2} %", 100.0 * prediction.mean_cell_error),
            lossy.to_string(),
            format!("1:{:.0}", ratio(lossy)),
            lossless.to_string(),
            format!("1:{:.0}", ratio(lossless)),
        ]);
    }
    println!(
        "\nErrors over the {changed} cells that changed (seed 001 §VI: mean over those cells of the fraction of \
         wrongly estimated states). Estimation: models built on all {frames} frames. Prediction: models \
         built on the first {split} frames, tested on the {} after them.",
        frames - split
    );
    println!("{}", table.render());
    println!(
        "(seed 001 §VI: static ~6 %, lossy FreMEn 3-4 %, lossless 1:250; computed in {:.1} s)\n",
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Frame indices of the two held-back splits: `inner` then `split`.
fn splits(frames: u64, holdout: f64) -> [u64; 2] {
    let split = ((frames as f64) * (1.0 - holdout)).round() as u64;
    let inner = ((split as f64) * (1.0 - holdout)).round() as u64;
    [inner, split]
}

fn build_from_synthetic(
    args: &GridBuildArgs,
    config: &GridConfig,
    snapshots: bool,
) -> Result<BuiltGrid> {
    let workload = office(args.cells, args.days, args.seed)?;
    let geometry = office_geometry(args.cells)?;
    let threads = args
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let frames = workload.frames();
    let at = if snapshots {
        splits(frames, args.holdout).to_vec()
    } else {
        Vec::new()
    };
    let total = frames * super::synthetic::partition(args.cells, threads).len() as u64;
    let built = with_progress("building", total, |p| {
        build_synthetic(&workload, geometry, config, threads, &at, p)
    })?;
    Ok(BuiltGrid {
        grid: built.grid,
        snapshots: built.snapshots,
        split: at.get(1).copied().unwrap_or(frames),
        seconds: built.seconds,
        source: format!("synthetic office (seed {})", args.seed),
    })
}

/// Builds from frames given one at a time, taking snapshots before the split frames.
fn build_from_frames(
    geometry: GridGeometry,
    config: &GridConfig,
    frames: usize,
    snapshots: bool,
    holdout: f64,
    mut next: impl FnMut(usize, &mut FremenGrid) -> Result<()>,
) -> Result<(FremenGrid, Vec<FremenGrid>, u64)> {
    let mut grid = FremenGrid::new(geometry, config.clone())?;
    let at = splits(frames as u64, holdout);
    let mut taken = Vec::new();
    for f in 0..frames {
        if snapshots && at.contains(&(f as u64)) {
            taken.push(grid.clone());
        }
        next(f, &mut grid)?;
    }
    Ok((grid, taken, at[1]))
}

/// Reads a frame list: `<time> <map.yaml>` per line, paths relative to the list's folder.
fn read_frame_list(list: &Path) -> Result<Vec<(f64, PathBuf, usize)>> {
    let text = std::fs::read_to_string(list)
        .with_context(|| format!("{}: cannot read", list.display()))?;
    let folder = list.parent().unwrap_or(Path::new("."));
    let mut frames = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut fields = line.split_whitespace();
        let (Some(t), Some(path), None) = (fields.next(), fields.next(), fields.next()) else {
            bail!("{}:{}: expected `<time> <map.yaml>`", list.display(), i + 1);
        };
        let t: f64 = t
            .parse()
            .ok()
            .filter(|t: &f64| t.is_finite())
            .with_context(|| {
                format!("{}:{}: time: {t:?} is not a number", list.display(), i + 1)
            })?;
        frames.push((t, folder.join(path), i + 1));
    }
    ensure!(!frames.is_empty(), "{}: no frames listed", list.display());
    Ok(frames)
}

fn build_from_map_list(
    list: &Path,
    args: &GridBuildArgs,
    config: &GridConfig,
    snapshots: bool,
) -> Result<BuiltGrid> {
    let started = Instant::now();
    let frames = read_frame_list(list)?;
    let semantics = if args.ros1 {
        LoadSemantics::Ros1
    } else {
        LoadSemantics::Nav2
    };
    let first = load_map(&frames[0].1, semantics)?;
    let geometry = GridGeometry::planar(
        first.width,
        first.height,
        f64::from(first.resolution),
        [first.origin[0], first.origin[1]],
    )?;
    let (grid, snapshots, split) = build_from_frames(
        geometry,
        config,
        frames.len(),
        snapshots,
        args.holdout,
        |f, grid| {
            let (t, path, line) = &frames[f];
            let map = if f == 0 {
                first.clone()
            } else {
                load_map(path, semantics)?
            };
            ensure!(
                map.width == first.width && map.height == first.height,
                "{}:{line}: {} is {}x{} but the first map is {}x{}",
                list.display(),
                path.display(),
                map.width,
                map.height,
                first.width,
                first.height
            );
            grid.observe_occupancy(*t, &map.data)
                .with_context(|| format!("{}:{line}: {}", list.display(), path.display()))
        },
    )?;
    Ok(BuiltGrid {
        grid,
        snapshots,
        split,
        seconds: started.elapsed().as_secs_f64(),
        source: list.display().to_string(),
    })
}

fn build_from_cell_series(
    files: &[PathBuf],
    args: &GridBuildArgs,
    config: &GridConfig,
    snapshots: bool,
) -> Result<BuiltGrid> {
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
    let (grid, snapshots, split) = build_from_frames(
        geometry,
        config,
        reference.len(),
        snapshots,
        args.holdout,
        |f, grid| {
            let frame: Vec<i8> = series
                .iter()
                .map(|s| (100.0 * s.values[f]).round() as i8)
                .collect();
            Ok(grid.observe_occupancy(reference.times[f], &frame)?)
        },
    )?;
    Ok(BuiltGrid {
        grid,
        snapshots,
        split,
        seconds: started.elapsed().as_secs_f64(),
        source: format!("{} cell series", files.len()),
    })
}

/// The compact model in a grid file (learning-state files are fitted with `order`).
fn fitted_of(file: GridFile, order: Option<usize>) -> Result<FittedGrid> {
    Ok(match file {
        GridFile::State(grid) => {
            let k = order.unwrap_or(grid.config().fremen.order);
            grid.fitted(OrderChoice::Fixed(k))
        }
        GridFile::Lossy(_) | GridFile::Lossless(_) if order.is_some() => {
            bail!("--order needs a learning-state grid file (this one stores a fitted model)")
        }
        GridFile::Lossy(fitted) => *fitted,
        GridFile::Lossless(lossless) => lossless.fitted,
    })
}

/// Parses `a..b` layers of a grid `depth` layers deep (default all).
fn layers(text: Option<&str>, depth: u32) -> Result<std::ops::Range<u32>> {
    let Some(text) = text else {
        return Ok(0..depth);
    };
    let (a, b) = text
        .split_once("..")
        .with_context(|| format!("--layers {text:?} is not a..b"))?;
    let (a, b): (u32, u32) = (a.parse()?, b.parse()?);
    ensure!(
        a < b && b <= depth,
        "--layers {a}..{b} is not within 0..{depth}"
    );
    Ok(a..b)
}

/// A 2-D map of the prediction: for a 3-D grid, each column takes its most occupied known cell
/// in `layers`; NaN where every cell is unknown.
fn project(fitted: &FittedGrid, values: &[f32], layers: std::ops::Range<u32>) -> Vec<f32> {
    let g = fitted.geometry();
    let (w, h) = (g.width as usize, g.height as usize);
    let mut out = vec![f32::NAN; w * h];
    for z in layers {
        let layer = &values[z as usize * w * h..(z as usize + 1) * w * h];
        for (o, &v) in out.iter_mut().zip(layer) {
            if !v.is_nan() && (o.is_nan() || v > *o) {
                *o = v;
            }
        }
    }
    out
}

pub fn predict(args: &GridPredictArgs) -> Result<()> {
    let fitted = fitted_of(read_grid_file(&args.grid)?, args.order)?;
    let g = *fitted.geometry();
    let values = project(
        &fitted,
        &fitted.predict(args.time),
        layers(args.layers.as_deref(), g.depth)?,
    );
    let map = OccupancyMap::from_probabilities(
        g.width,
        g.height,
        g.resolution as f32,
        [g.origin[0], g.origin[1], 0.0],
        &values,
    );
    // `--out map.yaml` and `--out map` both mean map.yaml + map.pgm/png.
    let base = if args
        .out
        .extension()
        .is_some_and(|e| e == "yaml" || e == "yml")
    {
        args.out.with_extension("")
    } else {
        args.out.clone()
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
    println!(
        "predicted {}x{} map for {}: {occupied} occupied, {unknown} unknown cells; wrote {} and {}",
        map.width,
        map.height,
        time(args.time),
        saved.yaml.display(),
        saved.image.display()
    );
    Ok(())
}

pub fn stats(args: &GridStatsArgs) -> Result<()> {
    let bytes = std::fs::metadata(&args.grid)
        .with_context(|| format!("{}: cannot read", args.grid.display()))?
        .len();
    let file = read_grid_file(&args.grid)?;
    println!(
        "file: {} ({}, {bytes} bytes)",
        args.grid.display(),
        file.kind()
    );
    let (geometry, frames, extra) = match &file {
        GridFile::State(grid) => (
            *grid.geometry(),
            grid.frame_span(),
            format!(
                "{} cells with storage, {:.1} MB in memory, periods {}",
                grid.dynamic_cells(),
                grid.memory_bytes() as f64 / 1048576.0,
                grid.config().fremen.periods
            ),
        ),
        GridFile::Lossy(fitted) => (*fitted.geometry(), fitted.frames(), describe_fitted(fitted)),
        GridFile::Lossless(lossless) => (
            *lossless.fitted.geometry(),
            lossless.fitted.frames(),
            format!(
                "{}; {} outlier toggles",
                describe_fitted(&lossless.fitted),
                lossless.outlier_toggles()
            ),
        ),
    };
    println!(
        "grid: {}x{}x{} cells at {} m, origin {:?}",
        geometry.width, geometry.height, geometry.depth, geometry.resolution, geometry.origin
    );
    if frames.count > 0 {
        println!(
            "frames: {} from {} to {} ({})",
            frames.count,
            time(frames.first),
            time(frames.last),
            duration(frames.duration())
        );
        let observations = geometry.cells() as f64 * frames.count as f64;
        println!(
            "compression (eq. 16): {:.3e} cell observations in {bytes} bytes = 1:{:.0}",
            observations,
            observations / (8.0 * bytes as f64)
        );
    }
    println!("{extra}");
    Ok(())
}

fn describe_fitted(fitted: &FittedGrid) -> String {
    let mut orders = [0usize; 256];
    for c in fitted.cells() {
        orders[usize::from(c.count)] += 1;
    }
    let listed: Vec<String> = orders
        .iter()
        .enumerate()
        .filter(|&(_, &n)| n > 0)
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
    let range = layers(args.layers.as_deref(), g.depth)?;
    let maps: Vec<MapImage> = times
        .iter()
        .map(|&t| MapImage {
            title: format!("predicted for {}", time(t)),
            width: g.width,
            height: g.height,
            values: project(&fitted, &fitted.predict(t), range.clone()),
        })
        .collect();
    let cell_pixels = (700 / g.width.max(g.height)).clamp(1, 40);
    render_maps_png(&maps, &args.output, cell_pixels)?;
    println!("wrote {}", args.output.display());
    Ok(())
}
