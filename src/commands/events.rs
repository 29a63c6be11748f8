//! `chronomap events eval`: the experiment of [Krajník 2019] §V-D on event files (people detected
//! by a robot): MSE per cell of every model's expected counts on a spatio-temporal grid of
//! the test day, its reduction against the static map and a paired t-test.

use std::path::PathBuf;

use anyhow::{Result, bail};
use chronomap_app::events::{
    Experiment, ExperimentResult, HypertimeFit, fit_hypertime, read_test_events,
    read_training_events,
};
use chronomap_core::num::fmt_number;
use chronomap_hypertime::events::density::{Extent, hourly_density};
use chronomap_hypertime::events::{Event, EventScore, SpatialGrid};
use chronomap_plot::{MapImage, render_scaled_maps_png};
use serde_json::{Value, json};

use crate::cli::{EventsEvalArgs, HypertimeArgs};
use crate::format::{Table, duration, time};
use crate::output::{ProgressBar, print_json, usage};
use crate::{out, outln};

fn file_list(paths: &[PathBuf]) -> String {
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(",")
}

/// The training events of `files` (`--train`) before `before` (`--train-before`), with the
/// list of the files' names; an error saying there are no `what` if none is left.
fn read_training(
    files: &[PathBuf],
    before: Option<f64>,
    what: &str,
) -> Result<(String, Vec<Event>)> {
    let names = file_list(files);
    let events = read_training_events(files, before)?;
    if events.is_empty() {
        bail!("{names}: no {what} (before --train-before?)");
    }
    Ok((names, events))
}

/// ` WORD TIME` for a time bound that was given (`--train-before`, `--test-from`), else nothing.
fn bound(word: &str, t: Option<f64>) -> String {
    t.map(|t| format!(" {word} {}", time(t)))
        .unwrap_or_default()
}

pub fn eval(args: &EventsEvalArgs) -> Result<()> {
    let (train_names, train) =
        read_training(&args.train, args.train_before, "training detections")?;
    let test_name = args.test.display().to_string();
    let test = read_test_events(&args.test, args.test_from)?;
    if test.is_empty() {
        bail!("{test_name}: no test detections (at or after --test-from?)");
    }
    let experiment = Experiment {
        train_name: &train_names,
        train: &train,
        test_name: &test_name,
        test: &test,
        gap_secs: args.gap,
        cells: &args.cells,
        bins: &args.bins,
    };
    let ExperimentResult { training, rows } = {
        let bar = ProgressBar::new();
        experiment.run(chronomap_core::Parallelism::Rayon(0), &bar)?
    };

    if args.json {
        let windows: Vec<Value> = training
            .windows()
            .iter()
            .map(|w| json!([w.start, w.end]))
            .collect();
        let results: Vec<Value> = rows.iter().map(score_json).collect();
        return print_json(&json!({
            "train": {
                "files": args.train.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
                "before": args.train_before,
                "events": train.len(),
                "windows": windows,
                "observed_secs": training.observed_secs(),
            },
            "test": {
                "file": test_name,
                "from": args.test_from,
                "events": test.len(),
                "first": test[0].t,
                "last": test[test.len() - 1].t,
            },
            "results": results,
        }));
    }

    let before = bound("before", args.train_before);
    outln!(
        "training: {train_names}{before}: {} detections in {} window(s) of observation, {} observed",
        train.len(),
        training.windows().len(),
        duration(training.observed_secs()),
    )?;
    for w in training.windows() {
        outln!("  {} .. {}", time(w.start), time(w.end))?;
    }
    let from = bound("from", args.test_from);
    outln!(
        "test: {test_name}{from}: {} detections, {} .. {}{}",
        test.len(),
        time(test[0].t),
        time(test[test.len() - 1].t),
        extent(&test),
    )?;
    outln!()?;
    let mut table = Table::new([
        "cell",
        "bin",
        "cells",
        "events",
        "model",
        "MSE",
        "vs static",
        "p",
    ]);
    for r in &rows {
        table.row([
            format!("{} m", r.cell),
            format!("{} min", r.bin_secs / 60.0),
            r.cells.to_string(),
            r.test_events.to_string(),
            r.model.clone(),
            format!("{:.4}", r.mse),
            format!("{:+.1} %", r.reduction_pct),
            r.p_value.map_or("-".into(), p_value),
        ]);
    }
    out!("{}", table.render())?;
    outln!(
        "\nMSE: mean squared error per cell of the expected counts; vs static: reduction of the \
         MSE against the static map (positive = smaller error); p: paired t-test of the \
         per-cell squared errors against the static map's. Parameters (hist:n intervals per \
         day, fremen:order) were chosen on a chronological hold-out of the training data."
    )?;
    Ok(())
}

/// `, area x -8.0 .. 23.0 m, y -5.9 .. 15.9 m`.
fn extent(events: &[Event]) -> String {
    match Extent::of(events) {
        Some(e) => format!(
            ", area x {:.1} .. {:.1} m, y {:.1} .. {:.1} m",
            e.x_min, e.x_max, e.y_min, e.y_max
        ),
        None => String::new(),
    }
}

fn p_value(p: f64) -> String {
    if p < 1e-4 {
        format!("{p:.0e}")
    } else {
        format!("{p:.4}")
    }
}

fn score_json(r: &EventScore) -> Value {
    json!({
        "cell_m": r.cell,
        "bin_secs": r.bin_secs,
        "model": r.model,
        "mse": r.mse,
        "reduction_pct": r.reduction_pct,
        "t": r.t,
        "p_value": r.p_value,
        "test_events": r.test_events,
        "cells": r.cells,
        "predicted_total": r.predicted_total,
        "grid": {
            "x0": r.grid.x0,
            "y0": r.grid.y0,
            "nx": r.grid.nx,
            "ny": r.grid.ny,
            "t0": r.grid.t0,
            "nt": r.grid.nt,
        },
    })
}

/// `chronomap hypertime`: fit the Warped Hypertime event intensity and draw it.
pub fn hypertime(args: &HypertimeArgs) -> Result<()> {
    let (names, events) = read_training(&args.train, args.train_before, "detections")?;
    let HypertimeFit {
        training: train,
        model,
        seconds,
    } = {
        let bar = ProgressBar::new();
        fit_hypertime(&names, &events, args.gap, args.components, &bar)?
    };
    let periods: Vec<String> = model.periods().iter().map(|&p| duration(p)).collect();
    let observed: Vec<Event> = train.observed_events().copied().collect();
    if observed.is_empty() {
        bail!("{names}: no detections in the plane");
    }
    let space = SpatialGrid::covering(&observed, args.cell).ok_or_else(|| {
        usage(format!(
            "--cell {}: more than {} cells along an axis over the detections",
            fmt_number(args.cell),
            chronomap_hypertime::events::MAX_COUNT
        ))
    })?;
    // Expected detections per m² per hour at each time, on the cells' centres.
    let maps = hourly_density(&model, &space, &args.at);
    if let Some(path) = &args.plot {
        plot_density(&maps, &space, path)?;
    }
    if args.json {
        return print_json(&json!({
            "train": {"files": names, "events": events.len(), "observed_secs": train.observed_secs()},
            "periods_secs": model.periods(),
            "components": model.mixture().components(),
            "fit_seconds": seconds,
            "maps": maps.iter().map(|m| json!({
                "time": m.time,
                "total_per_hour": m.total_per_hour(&space),
                "max_per_m2_hour": m.max_per_m2_hour(),
            })).collect::<Vec<_>>(),
        }));
    }
    outln!(
        "{names}: {} detections, {} observed; fitted in {seconds:.1} s",
        events.len(),
        duration(train.observed_secs())
    )?;
    outln!(
        "{} mixture components over [x, y{}]; periodicities: {}",
        model.mixture().components(),
        ", cos, sin".repeat(model.periods().len()),
        if periods.is_empty() {
            "none (the spatial distribution does not change with time)".to_string()
        } else {
            periods.join(", ")
        }
    )?;
    for map in &maps {
        outln!(
            "{}: {:.0} detections per hour expected, at most {:.1} per m² per hour",
            time(map.time),
            map.total_per_hour(&space),
            map.max_per_m2_hour()
        )?;
    }
    if let Some(path) = &args.plot {
        outln!("wrote {}", path.display())?;
    }
    Ok(())
}

/// The density maps side by side, on one square-root colour scale (black = the largest value,
/// so that quiet places stay visible beside the busiest one).
fn plot_density(
    maps: &[chronomap_hypertime::events::density::DensityMap],
    space: &SpatialGrid,
    path: &std::path::Path,
) -> Result<()> {
    let max = maps
        .iter()
        .map(|m| m.max_per_m2_hour())
        .fold(0.0f64, f64::max)
        .max(f64::MIN_POSITIVE);
    let images: Vec<MapImage> = maps
        .iter()
        .map(|map| MapImage {
            title: format!("{} (max {:.1}/m²/h)", time(map.time), max),
            width: space.nx as u32,
            height: space.ny as u32,
            // Row 0 is the bottom (the smallest y), as the renderer draws maps.
            values: (0..space.ny)
                .flat_map(|r| (0..space.nx).map(move |c| (r, c)))
                .map(|(r, c)| (map.per_m2_hour[space.index(r, c)] / max).sqrt() as f32)
                .collect(),
        })
        .collect();
    let pixels = (480 / space.nx.max(space.ny).max(1)).clamp(1, 16) as u32;
    let quarter = format!("{:.1}/m²/h", max / 4.0);
    let legend = [("none", 0.0), (quarter.as_str(), 0.5), ("the maximum", 1.0)];
    render_scaled_maps_png(&images, path, pixels, &legend)?;
    Ok(())
}
