//! `chronomap activity fit|predict`: CoPA-Map ([Stüde 2024] §4.2) or Log-AM
//! (`chronomap_activity::lograte`) trained once, saved as a model file, and queried for maps of
//! the predicted rate of people and its uncertainty.

use std::time::Instant;

use anyhow::{Result, anyhow};
use chronomap_activity::grids::{GridError, RegionGrid};
use chronomap_activity::{CopaConfig, CopaMap, LogAdditive, LogAdditiveConfig, RateScale};
use chronomap_app::activity::{RateMaps, open_activity_model, predict_maps};
use chronomap_core::Parallelism;
use chronomap_core::num::fmt_number;
use chronomap_io::navmap::{LoadSemantics, load_map};
use chronomap_io::rate_predictions::write_rate_predictions;
use chronomap_io::{LOG_ADDITIVE_KIND, read_rate_samples, write_copa_map};
use chronomap_plot::{MapImage, render_scaled_maps_png};
use serde_json::json;

use crate::cli::{ActivityFitArgs, ActivityPredictArgs, CopaScale, FitModel};
use crate::output::{ProgressBar, print_json, usage};
use crate::{out, outln};

/// Largest grid `predict` evaluates (cells × times), to keep a mistyped `--cell` from running
/// for hours.
const MAX_PREDICTIONS: usize = 20_000_000;

pub fn fit(args: &ActivityFitArgs) -> Result<()> {
    let name = args.train.display().to_string();
    let train = read_rate_samples(&args.train)?;
    if args.model == FitModel::LogAdditive {
        return fit_log_additive(args, &name, &train);
    }
    let config = CopaConfig {
        inducing: args.inducing,
        iterations: args.iterations,
        day_period: args.period,
        seed: args.seed,
        parallelism: Parallelism::Rayon(0),
        target: match args.scale {
            CopaScale::Rate => RateScale::Rate,
            CopaScale::Log1p => RateScale::Log1p,
        },
        ..CopaConfig::default()
    };
    let start = Instant::now();
    let model = CopaMap::fit_with_progress(&train, &config, &ProgressBar::new())
        .map_err(|e| anyhow!("{name}: CoPA-Map: {e}"))?;
    let seconds = start.elapsed().as_secs_f64();
    write_copa_map(&args.output, &model)?;
    let final_elbo = model.trace.last().copied().unwrap_or(f64::NAN);
    if args.json {
        return print_json(&json!({
            "model": args.output.display().to_string(),
            "train": name,
            "samples": train.len(),
            "cells": train.cell_count(),
            "inducing": args.inducing,
            "iterations": args.iterations,
            "periods": model.periods(),
            "final_elbo": final_elbo,
            "fit_seconds": seconds,
        }));
    }
    let periods: Vec<String> = model.periods().iter().map(|p| format!("{p:.3}")).collect();
    outln!(
        "{}: CoPA-Map fitted in {seconds:.1} s on {} samples, {} cells; periods {} (units of t); \
         final minibatch ELBO {:.1}",
        args.output.display(),
        train.len(),
        train.cell_count(),
        periods.join(", "),
        final_elbo
    )?;
    Ok(())
}

/// `activity fit --model log-additive`: Log-AM, saved as a model file of kind
/// [`LOG_ADDITIVE_KIND`].
fn fit_log_additive(
    args: &ActivityFitArgs,
    name: &str,
    train: &chronomap_activity::RateSamples,
) -> Result<()> {
    let config = LogAdditiveConfig {
        period: args.period,
        ..LogAdditiveConfig::default()
    };
    let start = Instant::now();
    let model = LogAdditive::fit(train, &config).map_err(|e| anyhow!("{name}: Log-AM: {e}"))?;
    let seconds = start.elapsed().as_secs_f64();
    chronomap_io::write_model_file(&args.output, LOG_ADDITIVE_KIND, &model)?;
    // ∞ (no interaction, every day alike) as the string "inf": JSON has no infinity.
    let value = |k: f64| {
        if k.is_finite() {
            json!(k)
        } else {
            json!("inf")
        }
    };
    if args.json {
        return print_json(&json!({
            "model": args.output.display().to_string(),
            "kind": LOG_ADDITIVE_KIND,
            "train": name,
            "samples": train.len(),
            "cells": train.cell_count(),
            "shrinkage": value(model.shrinkage()),
            "memory_days": value(model.memory()),
            "holdout_rmse_log1p": model.holdout_scores().iter().map(|s| json!({
                "memory_days": value(s.memory),
                "shrinkage": value(s.shrinkage),
                "rmse": s.rmse,
            })).collect::<Vec<_>>(),
            "sigma": model.sigma(),
            "profile": model.profile(),
            "fit_seconds": seconds,
        }));
    }
    outln!(
        "{}: Log-AM fitted in {seconds:.3} s on {} samples, {} cells; memory τ = {} days, \
         shrinkage κ = {} (hold-out); residual σ {:.3} in ln(1 + rate)",
        args.output.display(),
        train.len(),
        train.cell_count(),
        model.memory(),
        model.shrinkage(),
        model.sigma()
    )?;
    Ok(())
}

pub fn predict(args: &ActivityPredictArgs) -> Result<()> {
    if let Some(t) = args.times.iter().find(|t| !t.is_finite()) {
        return Err(usage(format!("--t {t}: times must be finite")));
    }
    // An explicit region is checked before any file is read.
    let region = match &args.region {
        Some(r) => Some(
            RegionGrid::new([r[0], r[1]], [r[2], r[3]], args.cell).map_err(|e| match e {
                GridError::TooManyCells { cell, .. } => {
                    usage(format!("--cell {}: {e}", fmt_number(cell)))
                }
                e => usage(format!("--region {e}")),
            })?,
        ),
        None => None,
    };
    let model_name = args.model.display().to_string();
    let model = open_activity_model(&args.model)?;
    // By default the training square, widened from the cell centres to the cell edges.
    let grid = match region {
        Some(grid) => grid,
        None => RegionGrid::around_centres(model.domain(), args.cell)
            .map_err(|e| anyhow!("{model_name}: the model's domain {e}"))?,
    };
    let (nx, ny) = (grid.cols, grid.rows);
    if nx.saturating_mul(ny).saturating_mul(args.times.len()) > MAX_PREDICTIONS {
        return Err(usage(format!(
            "--region and --cell give {nx} × {ny} cells at {} times: more than \
             {MAX_PREDICTIONS} predictions; use a larger --cell or a smaller --region",
            args.times.len()
        )));
    }
    let map = match &args.map {
        Some(path) => Some(load_map(path, LoadSemantics::Nav2)?),
        None => None,
    };
    let RateMaps {
        blocked,
        rows,
        panels,
    } = predict_maps(
        &model,
        &grid,
        &args.times,
        map.as_ref(),
        Parallelism::Rayon(0),
    )
    .map_err(|e| anyhow!("{model_name}: {e}"))?;
    if let Some(path) = &args.output {
        write_rate_predictions(path, &rows)?;
    }
    if let Some(path) = &args.plot {
        plot(path, &panels, &blocked, &grid)?;
    }
    if args.json {
        return print_json(&json!({
            "model": model_name,
            "times": args.times,
            "region": [grid.min[0], grid.min[1], grid.max[0], grid.max[1]],
            "cell_m": grid.cell,
            "cols": nx,
            "rows": ny,
            "output": args.output.as_ref().map(|p| p.display().to_string()),
            "plot": args.plot.as_ref().map(|p| p.display().to_string()),
            "predictions": rows.iter().map(|r| json!({
                "x1": r.x[0], "x2": r.x[1], "t": r.t, "mean": r.mean, "std": r.std,
            })).collect::<Vec<_>>(),
        }));
    }
    if let Some(path) = &args.output {
        outln!("{}: {} predictions", path.display(), rows.len())?;
    }
    if let Some(path) = &args.plot {
        outln!(
            "{}: mean and std of the rate at t = {} ({nx} × {ny} cells of {} m)",
            path.display(),
            args.times
                .iter()
                .map(|t| t.to_string())
                .collect::<Vec<_>>()
                .join(", "),
            args.cell
        )?;
    }
    if args.output.is_none() && args.plot.is_none() {
        out!(
            "{}",
            chronomap_io::rate_predictions::encode_rate_predictions(&rows)
        )?;
    }
    Ok(())
}

/// Reads a CoPA-Map model file and checks the model.
pub(super) fn read_copa_map(path: &std::path::Path) -> Result<CopaMap> {
    Ok(chronomap_io::read_copa_map(path)?)
}

/// The predicted mean and standard deviation at every time, each scaled to its largest value
/// off the walls, walls drawn apart.
fn plot(
    path: &std::path::Path,
    panels: &[(f64, Vec<f64>, Vec<f64>)],
    blocked: &[bool],
    grid: &RegionGrid,
) -> Result<()> {
    let (nx, ny) = (grid.cols, grid.rows);
    let visible = |v: &[f64]| {
        v.iter()
            .zip(blocked)
            .filter(|(_, b)| !**b)
            .map(|(v, _)| *v)
            .fold(0.0f64, f64::max)
    };
    let max_mean = panels.iter().map(|p| visible(&p.1)).fold(0.0, f64::max);
    let max_std = panels.iter().map(|p| visible(&p.2)).fold(0.0, f64::max);
    let image = |title: String, values: &[f64], max: f64| MapImage {
        title,
        width: nx as u32,
        height: ny as u32,
        values: values
            .iter()
            .zip(blocked)
            .map(|(v, b)| {
                if *b {
                    f32::NAN
                } else {
                    (v / max.max(1e-12)) as f32
                }
            })
            .collect(),
    };
    let mut maps = Vec::new();
    for (t, mean, std) in panels {
        maps.push(image(
            format!("mean at t = {t} (max {max_mean:.0} per h)"),
            mean,
            max_mean,
        ));
        maps.push(image(
            format!("std at t = {t} (max {max_std:.0} per h)"),
            std,
            max_std,
        ));
    }
    let cell_pixels = (600 / nx.max(ny)).clamp(1, 12) as u32;
    render_scaled_maps_png(
        &maps,
        path,
        cell_pixels,
        &[("0", 0.0), ("max/2", 0.5), ("max", 1.0), ("wall", f32::NAN)],
    )?;
    Ok(())
}
