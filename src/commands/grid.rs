//! `chronomap grid build | predict | stats | plot`: spatio-temporal occupancy grids and the
//! time-specific maps they predict ([Krajník 2017] §VI, §VIII).

use anyhow::{Context, Result};
use chronomap_app::grid::{
    BuildSettings, BuiltGrid, ErrorTable, FrameSource, build_grid, error_table,
};
use chronomap_core::Parallelism;
use chronomap_core::metrics::compression_ratio;
use chronomap_grid::report::{RowOrders, project_layers};
use chronomap_grid::{AnyGrid, FittedGrid, FremenGrid, GridGeometry, GridStore};
use chronomap_io::navmap::{LoadSemantics, MapMode, SaveOptions, save_map};
use chronomap_io::output::write_output;
use chronomap_io::{encode_grid, read_grid_file};
use chronomap_plot::{MapImage, render_maps_png};
use chronomap_spatial::OccupancyMap;
use serde_json::{Value, json};

use crate::cli::{
    GridBuildArgs, GridPlotArgs, GridPredictArgs, GridStatsArgs, Layers, MapModeArg, OrderArg,
    StoreArg,
};
use crate::format::{Table, duration, time};
use crate::outln;
use crate::output::{ProgressBar, closed_pipe, print_json, usage};

pub fn build(args: &GridBuildArgs) -> Result<()> {
    let settings = BuildSettings {
        periods: args.periods.clone(),
        order: match args.order {
            OrderArg::Fixed(k) => Some(k),
            OrderArg::Auto => None,
        },
        holdout: args.holdout,
        errors: args.errors,
        store: match args.store {
            StoreArg::State => GridStore::State,
            StoreArg::Lossy => GridStore::Lossy,
            StoreArg::Lossless => GridStore::Lossless,
        },
    };
    let source = if args.source.synthetic {
        FrameSource::Synthetic {
            cells: args.cells,
            days: args.days,
            seed: args.seed,
            threads: args.threads.map(|n| n as usize),
        }
    } else if let Some(list) = &args.source.frames {
        FrameSource::MapList {
            list,
            semantics: if args.ros1 {
                LoadSemantics::Ros1
            } else {
                LoadSemantics::Nav2
            },
        }
    } else if let Some(bag) = &args.source.bag {
        FrameSource::Bag {
            bag,
            topic: args
                .topic
                .as_deref()
                .ok_or_else(|| usage("--bag needs --topic"))?,
            time: args.time.into(),
        }
    } else {
        FrameSource::CellSeries(&args.source.cell_series)
    };
    let built = build_grid(&source, &settings, &ProgressBar::new())?;
    let grid = &built.build.grid;
    let geometry = *grid.geometry();
    let span = grid.frame_span();
    let observations = built.observations();
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
    let choice = built.orders(settings.order, Parallelism::Rayon(0))?;
    let errors = if args.errors {
        let table = error_table(&built, Parallelism::Rayon(0), &ProgressBar::new())?;
        if !(args.json || closed) {
            closed |= closed_pipe(print_error_table(&built, &table))?;
        }
        Some(table)
    } else {
        None
    };
    let file = AnyGrid::store(grid, settings.store, choice, Parallelism::Rayon(0))?;
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
            "errors": errors.map(|t| error_table_json(&t, built.split, grid.frames())),
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

/// The error table of [Krajník 2017] §VI as JSON.
fn error_table_json(table: &ErrorTable, split: u64, frames: u64) -> Value {
    json!({
        "changed_cells": table.changed_cells(),
        "split": split,
        "frames": frames,
        "rows": table.rows.iter().map(|r| json!({
            "model": ErrorTable::name(r.errors.orders),
            "order": match r.errors.orders {
                RowOrders::Fixed(k) => json!(k),
                RowOrders::PerCell => json!("auto"),
            },
            "estimation_error": r.errors.estimation.mean_cell_error,
            "prediction_error": r.errors.prediction.mean_cell_error,
            "lossy_bytes": r.lossy_bytes,
            "lossy_ratio": table.ratio(r.lossy_bytes),
            "lossless_bytes": r.lossless_bytes,
            "lossless_ratio": table.ratio(r.lossless_bytes),
        })).collect::<Vec<_>>(),
    })
}

fn print_error_table(built: &BuiltGrid, errors: &ErrorTable) -> Result<()> {
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
    for r in &errors.rows {
        table.row([
            ErrorTable::name(r.errors.orders),
            format!("{:.2} %", 100.0 * r.errors.estimation.mean_cell_error),
            format!("{:.2} %", 100.0 * r.errors.prediction.mean_cell_error),
            r.lossy_bytes.to_string(),
            format!("1:{:.0}", errors.ratio(r.lossy_bytes)),
            r.lossless_bytes.to_string(),
            format!("1:{:.0}", errors.ratio(r.lossless_bytes)),
        ]);
    }
    let changed = errors.changed_cells().unwrap_or(0);
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
