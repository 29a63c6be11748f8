//! `chronomap events eval`: the experiment of seed 004 §V-D on event files (people detected
//! by a robot): MSE per cell of every model's expected counts on a spatio-temporal grid of
//! the test day, its reduction against the static map and a paired t-test.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, anyhow, bail};
use chronomap_core::events::{
    Event, EventModelBuilder, EventScore, TrainingData, default_builders, run_experiment,
};
use chronomap_core::hypertime::events::{EventModelConfig, HypertimeEventsBuilder};
use chronomap_io::{read_event_files, read_events};
use serde_json::{Value, json};

use crate::cli::EventsEvalArgs;
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
