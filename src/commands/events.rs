//! `chronomap events eval`: the experiment of seed 004 §V-D on event files (people detected
//! by a robot): MSE per cell of every model's expected counts on a spatio-temporal grid of
//! the test day, its reduction against the static map and a paired t-test.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, anyhow, bail};
use chronomap_hypertime::events::{
    Event, EventModelBuilder, EventScore, TrainingData, default_builders, run_experiment,
};
use chronomap_hypertime::events::{EventIntensity, SpatialGrid};
use chronomap_hypertime::hypertime::Components;
use chronomap_hypertime::hypertime::events::{
    EventModelConfig, HypertimeEvents, HypertimeEventsBuilder,
};
use chronomap_io::{read_event_files, read_events};
use chronomap_plot::{MapImage, render_scaled_maps_png};
use serde_json::{Value, json};

use crate::cli::{EventsEvalArgs, HypertimeArgs};
use crate::format::{Table, duration, time};

/// The models of the tables, in order: static map, global mean, `Hist_n`, FreMEn per cell.
///
/// Extension point: a new event model (such as the Warped Hypertime event model of seed 004)
/// is one more [`EventModelBuilder`] pushed here; the experiment, the tables and the JSON pick
/// it up. Builders choose their parameters on the training data only.
fn model_builders() -> Vec<Box<dyn EventModelBuilder>> {
    let mut builders = default_builders();
    builders.push(Box::new(HypertimeEventsBuilder::new(
        EventModelConfig::default(),
    )));
    builders
}

fn file_list(paths: &[PathBuf]) -> String {
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(",")
}

pub fn eval(args: &EventsEvalArgs) -> Result<()> {
    let mut out = std::io::stdout().lock();
    let train_names = file_list(&args.train);
    let mut train = read_event_files(&args.train).context("cannot read the training events")?;
    if let Some(before) = args.train_before {
        train.retain(|e| e.t < before);
    }
    if train.is_empty() {
        bail!("{train_names}: no training detections (before --train-before?)");
    }
    let test_name = args.test.display().to_string();
    let mut test = read_events(&args.test).context("cannot read the test events")?;
    if let Some(from) = args.test_from {
        test.retain(|e| e.t >= from);
    }
    if test.is_empty() {
        bail!("{test_name}: no test detections (at or after --test-from?)");
    }
    let last_train = train[train.len() - 1].t;
    if test[0].t <= last_train {
        bail!(
            "{test_name}: the test starts at {} but the training data end at {}: a test must \
             come after its training data",
            time(test[0].t),
            time(last_train)
        );
    }
    let training =
        TrainingData::from_events(&train, args.gap).map_err(|e| anyhow!("{train_names}: {e}"))?;
    let rows = run_experiment(&training, &test, &args.cells, &args.bins, &model_builders())
        .map_err(|e| anyhow!("{test_name}: {e}"))?;

    if args.json {
        let windows: Vec<Value> = training
            .windows()
            .iter()
            .map(|w| json!([w.start, w.end]))
            .collect();
        let results: Vec<Value> = rows.iter().map(score_json).collect();
        writeln!(
            out,
            "{}",
            json!({
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
            })
        )?;
        return Ok(());
    }

    let before = args
        .train_before
        .map(|t| format!(" before {}", time(t)))
        .unwrap_or_default();
    writeln!(
        out,
        "training: {train_names}{before}: {} detections in {} window(s) of observation, {} observed",
        train.len(),
        training.windows().len(),
        duration(training.observed_secs()),
    )?;
    for w in training.windows() {
        writeln!(out, "  {} .. {}", time(w.start), time(w.end))?;
    }
    let from = args
        .test_from
        .map(|t| format!(" from {}", time(t)))
        .unwrap_or_default();
    writeln!(
        out,
        "test: {test_name}{from}: {} detections, {} .. {}{}",
        test.len(),
        time(test[0].t),
        time(test[test.len() - 1].t),
        extent(&test),
    )?;
    writeln!(out)?;
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
    write!(out, "{}", table.render())?;
    writeln!(
        out,
        "\nMSE: mean squared error per cell of the expected counts; vs static: reduction of the \
         MSE against the static map (positive = smaller error); p: paired t-test of the \
         per-cell squared errors against the static map's. Parameters (hist:n intervals per \
         day, fremen:order) were chosen on a chronological hold-out of the training data."
    )?;
    Ok(())
}

/// `, area x -8.0 .. 23.0 m, y -5.9 .. 15.9 m`.
fn extent(events: &[Event]) -> String {
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for e in events {
        (x0, x1, y0, y1) = (x0.min(e.x), x1.max(e.x), y0.min(e.y), y1.max(e.y));
    }
    format!(", area x {x0:.1} .. {x1:.1} m, y {y0:.1} .. {y1:.1} m")
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
    let mut out = std::io::stdout().lock();
    let names = file_list(&args.train);
    let mut events = read_event_files(&args.train).context("cannot read the training events")?;
    if let Some(before) = args.train_before {
        events.retain(|e| e.t < before);
    }
    if events.is_empty() {
        bail!("{names}: no detections (before --train-before?)");
    }
    let train =
        TrainingData::from_events(&events, args.gap).map_err(|e| anyhow!("{names}: {e}"))?;
    let components = match args.components.as_str() {
        "auto" => Components::Auto,
        k => match k.parse::<usize>() {
            Ok(k) if k >= 1 => Components::Fixed(k),
            _ => bail!("--components {k:?}: give a whole number >= 1 or auto"),
        },
    };
    let config = EventModelConfig {
        components,
        ..EventModelConfig::default()
    };
    let started = std::time::Instant::now();
    let model = HypertimeEvents::fit(&train, &config)
        .with_context(|| format!("cannot fit the hypertime model to {names}"))?;
    let seconds = started.elapsed().as_secs_f64();
    let periods: Vec<String> = model.periods().iter().map(|&p| duration(p)).collect();
    let observed: Vec<Event> = train.observed_events().copied().collect();
    let space = SpatialGrid::covering(&observed, args.cell)
        .ok_or_else(|| anyhow!("{names}: no detections in the plane"))?;
    // Expected detections per m² per hour at each time, on the cells' centres.
    let maps: Vec<Vec<f64>> = args
        .at
        .iter()
        .map(|&t| {
            let grid = space.with_bins(t - 1800.0, 3600.0, 1);
            model
                .expected_counts(&grid)
                .into_iter()
                .map(|c| c / (args.cell * args.cell))
                .collect()
        })
        .collect();
    if let Some(path) = &args.plot {
        if maps.is_empty() {
            bail!("--plot needs at least one time in --at");
        }
        let max = maps
            .iter()
            .flatten()
            .copied()
            .fold(0.0f64, f64::max)
            .max(f64::MIN_POSITIVE);
        let images: Vec<MapImage> = args
            .at
            .iter()
            .zip(&maps)
            .map(|(&t, map)| MapImage {
                title: format!("{} (max {:.1}/m²/h)", time(t), max),
                width: space.nx as u32,
                height: space.ny as u32,
                // Row 0 is the bottom (the smallest y), as the renderer draws maps. A square
                // root scale, so that quiet places stay visible beside the busiest one.
                values: (0..space.ny)
                    .flat_map(|r| (0..space.nx).map(move |c| (r, c)))
                    .map(|(r, c)| (map[space.index(r, c)] / max).sqrt() as f32)
                    .collect(),
            })
            .collect();
        let pixels = (480 / space.nx.max(space.ny).max(1)).clamp(1, 16) as u32;
        let quarter = format!("{:.1}/m²/h", max / 4.0);
        let legend = [("none", 0.0), (quarter.as_str(), 0.5), ("the maximum", 1.0)];
        render_scaled_maps_png(&images, path, pixels, &legend)?;
    }
    if args.json {
        writeln!(
            out,
            "{}",
            json!({
                "train": {"files": names, "events": events.len(), "observed_secs": train.observed_secs()},
                "periods_secs": model.periods(),
                "components": model.mixture().components(),
                "fit_seconds": seconds,
                "maps": args.at.iter().zip(&maps).map(|(&t, m)| json!({
                    "time": t,
                    "total_per_hour": m.iter().sum::<f64>() * args.cell * args.cell,
                    "max_per_m2_hour": m.iter().copied().fold(0.0f64, f64::max),
                })).collect::<Vec<_>>(),
            })
        )?;
        return Ok(());
    }
    writeln!(
        out,
        "{names}: {} detections, {} observed; fitted in {seconds:.1} s",
        events.len(),
        duration(train.observed_secs())
    )?;
    writeln!(
        out,
        "{} mixture components over [x, y{}]; periodicities: {}",
        model.mixture().components(),
        ", cos, sin".repeat(model.periods().len()),
        if periods.is_empty() {
            "none (the spatial distribution does not change with time)".to_string()
        } else {
            periods.join(", ")
        }
    )?;
    for (&t, map) in args.at.iter().zip(&maps) {
        writeln!(
            out,
            "{}: {:.0} detections per hour expected, at most {:.1} per m² per hour",
            time(t),
            map.iter().sum::<f64>() * args.cell * args.cell,
            map.iter().copied().fold(0.0f64, f64::max)
        )?;
    }
    if let Some(path) = &args.plot {
        writeln!(out, "wrote {}", path.display())?;
    }
    Ok(())
}
