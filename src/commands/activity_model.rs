//! `chronomap activity fit|predict`: CoPA-Map ([Stüde 2024] §4.2) or Log-AM
//! (`chronomap_activity::lograte`) trained once, saved as a model file, and queried for maps of
//! the predicted rate of people and its uncertainty ([`chronomap_app::activity`] fits,
//! predicts and reports; this writes the files and draws the maps).

use anyhow::{Result, anyhow};
use chronomap_activity::grids::{GridError, RegionGrid};
use chronomap_activity::{CopaConfig, RateScale};
use chronomap_app::activity::{
    RatePredictReport, fit_copa, fit_log_additive, open_activity_model, predict_report,
};
use chronomap_core::Parallelism;
use chronomap_core::num::fmt_number;
use chronomap_io::rate_predictions::write_rate_predictions;
use chronomap_io::{LOG_ADDITIVE_KIND, write_copa_map};
use chronomap_plot::{MapImage, render_scaled_maps_png};

use crate::cli::{ActivityFitArgs, ActivityPredictArgs, CopaScale, FitModel};
use crate::out;
use crate::output::{ProgressBar, print_json, usage};

/// Largest grid `predict` evaluates (cells × times), to keep a mistyped `--cell` from running
/// for hours.
const MAX_PREDICTIONS: usize = 20_000_000;

pub fn fit(args: &ActivityFitArgs) -> Result<()> {
    if args.model == FitModel::LogAdditive {
        let report = fit_log_additive(&args.train, args.period, &args.output)?;
        chronomap_io::write_model_file(&args.output, LOG_ADDITIVE_KIND, &report.fitted)?;
        if args.json {
            return print_json(&report.json());
        }
        return Ok(out!("{}", report.text())?);
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
    let report = fit_copa(&args.train, &config, &args.output, &ProgressBar::new())?;
    write_copa_map(&args.output, &report.fitted)?;
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    Ok(out!("{}", report.text())?)
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
    let report = predict_report(
        &model,
        &model_name,
        &grid,
        &args.times,
        args.map.as_deref(),
        [args.output.as_deref(), args.plot.as_deref()],
    )?;
    if let Some(path) = &args.output {
        write_rate_predictions(path, &report.maps.rows)?;
    }
    if let Some(path) = &args.plot {
        plot(path, &report)?;
    }
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    Ok(out!("{}", report.text())?)
}

/// The predicted mean and standard deviation at every time, each scaled to its largest value
/// off the walls, walls drawn apart.
fn plot(path: &std::path::Path, report: &RatePredictReport) -> Result<()> {
    let (nx, ny) = (report.cols, report.rows);
    let maps: Vec<MapImage> = report
        .maps
        .scaled_panels()
        .into_iter()
        .map(|(title, values)| MapImage {
            title,
            width: nx as u32,
            height: ny as u32,
            values,
        })
        .collect();
    let cell_pixels = (600 / nx.max(ny)).clamp(1, 12) as u32;
    render_scaled_maps_png(
        &maps,
        path,
        cell_pixels,
        &[("0", 0.0), ("max/2", 0.5), ("max", 1.0), ("wall", f32::NAN)],
    )?;
    Ok(())
}
