//! `chronomap activity fit|predict`: CoPA-Map (seed 002 §4.2) trained once, saved as a model
//! file, and queried for maps of the predicted rate of people and its uncertainty.

use std::fmt::Write as _;
use std::io::Write;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use chronomap_activity::{CopaConfig, CopaMap, RateScale};
use chronomap_core::Parallelism;
use chronomap_io::navmap::{LoadSemantics, OccupancyMap, load_map};
use chronomap_io::{read_model_file, read_rate_samples, write_model_file};
use chronomap_plot::{MapImage, render_scaled_maps_png};

use crate::cli::{ActivityFitArgs, ActivityPredictArgs, CopaScale};

/// The kind written into CoPA-Map model files.
const KIND: &str = "copa-map";

/// Largest grid `predict` evaluates (cells × times), to keep a mistyped `--cell` from running
/// for hours.
const MAX_PREDICTIONS: usize = 20_000_000;

pub fn fit(args: &ActivityFitArgs) -> Result<()> {
    let name = args.train.display().to_string();
    let train = read_rate_samples(&args.train).context("cannot read the training rates")?;
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
    eprintln!(
        "fitting CoPA-Map to {} samples ({} inducing points, {} iterations)...",
        train.len(),
        args.inducing,
        args.iterations
    );
    let start = Instant::now();
    let model = CopaMap::fit(&train, &config).map_err(|e| anyhow!("{name}: CoPA-Map: {e}"))?;
    let seconds = start.elapsed().as_secs_f64();
    write_model_file(&args.output, KIND, &model)?;
    let periods: Vec<String> = model.periods().iter().map(|p| format!("{p:.3}")).collect();
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "{}: CoPA-Map fitted in {seconds:.1} s on {} samples, {} cells; periods {} (units of t); \
         final minibatch ELBO {:.1}",
        args.output.display(),
        train.len(),
        train.cell_count(),
        periods.join(", "),
        model.trace.last().copied().unwrap_or(f64::NAN)
    )?;
    Ok(())
}

pub fn predict(args: &ActivityPredictArgs) -> Result<()> {
    let model_name = args.model.display().to_string();
    let (kind, model): (String, CopaMap) = read_model_file(&args.model)?;
    if kind != KIND {
        bail!("{model_name}: a model of kind {kind:?}, not a CoPA-Map ({KIND:?})");
    }
    model.check().map_err(|e| anyhow!("{model_name}: {e}"))?;
    if let Some(t) = args.times.iter().find(|t| !t.is_finite()) {
        bail!("--t {t}: times must be finite");
    }
    let [x0, y0, x1, y1] = match &args.region {
        Some(r) => [r[0], r[1], r[2], r[3]],
        // The training square spans cell centres: widen it by half a cell to cell edges.
        None => {
            let [x0, y0, x1, y1] = model.domain();
            let h = args.cell / 2.0;
            [x0 - h, y0 - h, x1 + h, y1 + h]
        }
    };
    if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite())
        || x1 <= x0
        || y1 <= y0
    {
        bail!("--region {x0},{y0},{x1},{y1}: needs finite x_min < x_max and y_min < y_max");
    }
    let nx = ((x1 - x0) / args.cell).ceil() as usize;
    let ny = ((y1 - y0) / args.cell).ceil() as usize;
    if nx.saturating_mul(ny).saturating_mul(args.times.len()) > MAX_PREDICTIONS {
        bail!(
            "--region and --cell give {nx} × {ny} cells at {} times: more than {MAX_PREDICTIONS} \
             predictions; use a larger --cell or a smaller --region",
            args.times.len()
        );
    }
    let map = match &args.map {
        Some(path) => Some(load_map(path, LoadSemantics::Nav2)?),
        None => None,
    };
    // Cells row by row from the top (y_max) down, as images are drawn.
    let mut centres = Vec::with_capacity(nx * ny);
    let mut blocked = Vec::with_capacity(nx * ny);
    for r in 0..ny {
        for c in 0..nx {
            let x = x0 + (c as f64 + 0.5) * args.cell;
            let y = y1 - (r as f64 + 0.5) * args.cell;
            centres.push([x, y]);
            blocked.push(map.as_ref().is_some_and(|m| occupied(m, x, y)));
        }
    }
    let mut csv = String::from("x1,x2,t,mean,std\n");
    let mut panels = Vec::new();
    for &t in &args.times {
        let points: Vec<([f64; 2], f64)> = centres.iter().map(|&c| (c, t)).collect();
        let (mean, std) = model
            .predict_with_std(&points, Parallelism::Rayon(0))
            .map_err(|e| anyhow!("{model_name}: {e}"))?;
        for (i, c) in centres.iter().enumerate() {
            if !blocked[i] {
                writeln!(csv, "{},{},{t},{},{}", c[0], c[1], mean[i], std[i])?;
            }
        }
        panels.push((t, mean, std));
    }
    let mut out = std::io::stdout().lock();
    if let Some(path) = &args.csv {
        std::fs::write(path, &csv).with_context(|| format!("cannot write {}", path.display()))?;
        writeln!(
            out,
            "{}: {} predictions",
            path.display(),
            csv.lines().count() - 1
        )?;
    }
    if let Some(path) = &args.png {
        let visible = |v: &[f64]| {
            v.iter()
                .zip(&blocked)
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
                .zip(&blocked)
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
        for (t, mean, std) in &panels {
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
        writeln!(
            out,
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
    if args.csv.is_none() && args.png.is_none() {
        write!(out, "{csv}")?;
    }
    Ok(())
}

/// Whether the map cell under `(x, y)` is occupied (> 50 %); unknown and outside cells are not.
fn occupied(map: &OccupancyMap, x: f64, y: f64) -> bool {
    let res = f64::from(map.resolution);
    let c = ((x - map.origin[0]) / res).floor();
    let r = ((y - map.origin[1]) / res).floor();
    if c < 0.0 || r < 0.0 || c >= f64::from(map.width) || r >= f64::from(map.height) {
        return false;
    }
    map.cell(c as u32, r as u32).is_some_and(|v| v > 50)
}
