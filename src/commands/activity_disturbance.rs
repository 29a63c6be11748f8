//! `chronomap activity disturbance`: the service-disturbance benchmark of CoPA-Map
//! (dissertation chapter 4, [Stüde 2024] eq. 4.22, §4.3.2 and §4.3.5): patrols planned on every
//! model's predicted rates of people, driven through a test day of pedestrian tracks
//! ([`chronomap_app::disturbance`] runs it and reports; this draws the plots).

use std::path::Path;
use std::time::Instant;

use anyhow::{Result, bail};
use chronomap_activity::disturbance_day::RATIOS;
use chronomap_app::disturbance::{
    DisturbanceFiles, DisturbanceSettings, DisturbanceStudy, map_obstacle_points, run_disturbance,
};
use chronomap_core::Parallelism;
use chronomap_plot::{
    Panel, PathMap, PathMapPath, Series, SeriesStyle, render_panels_png, render_path_maps_png,
};

use crate::cli::ActivityDisturbanceArgs;
use crate::out;
use crate::output::{ProgressBar, print_json};

pub fn run(args: &ActivityDisturbanceArgs) -> Result<()> {
    let started = Instant::now();
    let files = DisturbanceFiles {
        train: &args.train,
        tracks: &args.tracks,
        map: &args.map,
        scenarios: &args.scenarios,
        scenario: &args.scenario,
    };
    let settings = DisturbanceSettings {
        clearance: args.clearance,
        day_start: args.day_start,
        t0: args.t0,
        period: args.period,
        epsilon: args.epsilon,
        inducing: args.inducing,
        iterations: args.iterations,
        no_copa: args.no_copa,
        parallelism: Parallelism::Rayon(0),
    };
    let study = {
        let progress = ProgressBar::new();
        run_disturbance(&files, &settings, &progress)?
    };
    if let Some(path) = &args.plot {
        plot_curves(&study, path)?;
    }
    if let Some(path) = &args.plot_paths {
        plot_paths(&study, path)?;
    }
    let total = started.elapsed().as_secs_f64();
    if args.json {
        return print_json(&study.json(&files, &settings, total));
    }
    Ok(out!("{}", study.text(&files, &settings, total))?)
}

/// E(ρ) of every model, one panel per scenario.
fn plot_curves(study: &DisturbanceStudy, path: &Path) -> Result<()> {
    let contenders = &study.contenders;
    let panels: Vec<Panel> = study
        .results
        .iter()
        .map(|(scenario, outcomes)| {
            let top = outcomes
                .iter()
                .flat_map(|o| o.curve.iter().copied())
                .max()
                .unwrap_or(0)
                .max(1) as f64;
            Panel {
                title: format!(
                    "{}: service disturbance E(rho), eq. (4.22) (lower is better)",
                    scenario.name
                ),
                x_label: "servicing ratio rho".into(),
                y_label: "encounters".into(),
                y_range: (0.0, top * 1.05),
                series: contenders
                    .iter()
                    .zip(outcomes)
                    .map(|(c, o)| Series {
                        label: c.name.clone(),
                        points: std::iter::once((0.0, 0.0))
                            .chain(RATIOS.iter().zip(&o.curve).map(|(&r, &e)| (r, e as f64)))
                            .collect(),
                        style: SeriesStyle::Line,
                    })
                    .collect(),
            }
        })
        .collect();
    let height = 120 + 380 * panels.len() as u32;
    render_panels_png(&panels, path, 1100, height)?;
    Ok(())
}

/// Per scenario: the map, the cost map of the last rate model (CoPA-Map unless left out) at
/// the busiest patrol hour, and every model's path then.
fn plot_paths(study: &DisturbanceStudy, path: &Path) -> Result<()> {
    let Some(slots) = study.busiest_slots()? else {
        bail!("--plot-paths needs a rate model");
    };
    let grid = &study.grid;
    let panels: Vec<PathMap> = slots
        .into_iter()
        .map(|s| PathMap {
            title: format!(
                "{}: {} predicted rate at {} (yellow: >= {:.0}/h); paths of every model",
                s.scenario,
                s.model,
                crate::format::time(s.start),
                s.top
            ),
            origin: grid.origin(),
            cell: grid.cell_size(),
            cols: grid.cols(),
            rows: grid.rows(),
            values: s.values,
            obstacles: map_obstacle_points(&study.map, grid),
            people: s.people,
            paths: s
                .paths
                .into_iter()
                .map(|(label, points)| PathMapPath { label, points })
                .collect(),
            waypoints: s.waypoints,
        })
        .collect();
    render_path_maps_png(&panels, path, 24)?;
    Ok(())
}
