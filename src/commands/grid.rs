//! `chronomap grid build | predict | stats | plot`: spatio-temporal occupancy grids and the
//! time-specific maps they predict ([Krajník 2017] §VI, §VIII; `chronomap_app::grid` builds
//! and reports, this prints).

use anyhow::Result;
use chronomap_app::grid::{
    BuildSettings, FrameSource, build_grid, default_plot_times, error_table, grid_stats,
    write_grid, write_predicted_map,
};
use chronomap_core::Parallelism;
use chronomap_grid::report::project_layers;
use chronomap_grid::{AnyGrid, FittedGrid, GridStore};
use chronomap_io::navmap::{LoadSemantics, MapMode};
use chronomap_io::read_grid_file;
use chronomap_plot::{MapImage, render_maps_png};

use crate::cli::{
    GridBuildArgs, GridPlotArgs, GridPredictArgs, GridStatsArgs, Layers, MapModeArg, OrderArg,
    StoreArg,
};
use crate::format::time;
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
        keep_history: false,
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
    // A closed stdout must not keep the grid file from being written: reports before the
    // write are dropped once the pipe is closed, and the command ends after the write.
    let mut closed = false;
    if !args.json {
        closed = closed_pipe(outln!("{}", built.summary()).map_err(Into::into))?;
    }
    let choice = built.orders(settings.order, Parallelism::Rayon(0))?;
    let errors = if args.errors {
        let table = error_table(&built, Parallelism::Rayon(0), &ProgressBar::new())?;
        if !(args.json || closed) {
            closed = closed_pipe(outln!("{}", table.text(&built)).map_err(Into::into))?;
        }
        Some(table)
    } else {
        None
    };
    let written = write_grid(&built, settings.store, choice, &args.output)?;
    if closed {
        return Ok(());
    }
    if args.json {
        return print_json(&built.json(errors.as_ref(), &args.output, &written));
    }
    Ok(outln!("{}", built.written_text(&args.output, &written))?)
}

/// The compact model in a grid file (learning-state files are fitted with `order`).
fn fitted_of(file: AnyGrid, order: Option<usize>) -> Result<FittedGrid> {
    file.into_fitted(order, Parallelism::Rayon(0)).map_err(|_| {
        usage("--order needs a learning-state grid file (this one stores a fitted model)")
    })
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

pub fn predict(args: &GridPredictArgs) -> Result<()> {
    let fitted = fitted_of(read_grid_file(&args.grid)?, args.order)?;
    let range = layers(args.layers, fitted.geometry().depth)?;
    let mode = match args.mode {
        MapModeArg::Trinary => MapMode::Trinary,
        MapModeArg::Scale => MapMode::Scale,
    };
    let grid = args.grid.display().to_string();
    let report = write_predicted_map(&grid, &fitted, args.time, range, &args.output, mode)?;
    if args.json {
        return print_json(&report.json());
    }
    Ok(outln!("{}", report.text())?)
}

pub fn stats(args: &GridStatsArgs) -> Result<()> {
    let stats = grid_stats(&args.grid)?;
    if args.json {
        return print_json(&stats.json());
    }
    Ok(outln!("{}", stats.text())?)
}

pub fn plot(args: &GridPlotArgs) -> Result<()> {
    let fitted = fitted_of(read_grid_file(&args.grid)?, args.order)?;
    let g = *fitted.geometry();
    let times = if args.times.is_empty() {
        default_plot_times(&fitted)
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
