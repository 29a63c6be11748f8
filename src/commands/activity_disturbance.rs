//! `chronomap activity disturbance`: the service-disturbance benchmark of CoPA-Map
//! (dissertation chapter 4, [Stüde 2024] eq. 4.22, §4.3.2 and §4.3.5): patrols planned on every
//! model's predicted rates of people, driven through a test day of pedestrian tracks.

use std::path::Path;
use std::time::Instant;

use anyhow::{Result, bail};
use chronomap_activity::disturbance::{Detections, PlanningGrid, Scenario};
use chronomap_activity::disturbance_day::{Outcome, RATIOS, SLOT_SECS, reduction_percent};
use chronomap_app::disturbance::{
    Contender, DisturbanceFiles, DisturbanceSettings, DisturbanceStudy, map_obstacle_points,
    run_disturbance,
};
use chronomap_core::Parallelism;
use chronomap_plot::{
    Panel, PathMap, PathMapPath, Series, SeriesStyle, render_panels_png, render_path_maps_png,
};
use chronomap_spatial::OccupancyMap;
use serde_json::{Value, json};

use crate::cli::ActivityDisturbanceArgs;
use crate::format::Table;
use crate::output::{ProgressBar, print_json};
use crate::{out, outln};

/// A map cell is an obstacle if its occupancy is at least this (percent) or unknown.
pub(super) use chronomap_app::disturbance::OCCUPIED_PERCENT;

pub fn run(args: &ActivityDisturbanceArgs) -> Result<()> {
    let started = Instant::now();
    let train_name = args.train.display().to_string();
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
    let DisturbanceStudy {
        train,
        detections,
        map,
        grid,
        day,
        contenders,
        results,
        config,
        bench_seconds,
    } = &study;

    if let Some(path) = &args.plot {
        plot_curves(results, contenders, path)?;
    }
    if let Some(path) = &args.plot_paths {
        plot_paths(results, contenders, grid, map, detections, path)?;
    }

    if args.json {
        let scenarios: Vec<Value> = results
            .iter()
            .map(|(scenario, outcomes)| scenario_json(scenario, outcomes, contenders))
            .collect();
        return print_json(&json!({
            "train": train_name,
            "tracks": args.tracks.len(),
            "detections": detections.events().len(),
            "day_start": day.day_start,
            "t0": day.t0,
            "n_nav": day.slots.len(),
            "starts": day.starts,
            "free_cells": grid.free_count(),
            "cell_m": grid.cell_size(),
            "clearance_m": args.clearance,
            "epsilon": args.epsilon,
            "speed_m_s": config.speed,
            "radius_m": config.radius,
            "ratios": RATIOS,
            "fit_seconds": contenders.iter().map(|c| (c.name.clone(), json!(c.fit_seconds))).collect::<serde_json::Map<_, _>>(),
            "benchmark_seconds": bench_seconds,
            "total_seconds": started.elapsed().as_secs_f64(),
            "scenarios": scenarios,
        }));
    }

    outln!(
        "training: {train_name}: {} samples over {} cells; test: {} detections in {} track files",
        train.len(),
        train.cell_count(),
        detections.events().len(),
        args.tracks.len()
    )?;
    outln!(
        "planning: {} free cells of {} m (training cells at least {} m from obstacles); model \
         time t = {} + hour from {}",
        grid.free_count(),
        grid.cell_size(),
        args.clearance,
        day.t0,
        crate::format::time(day.day_start)
    )?;
    outln!(
        "patrols: n_nav = {} per scenario, every 15 min where the slot is tracked ({} .. {})",
        day.slots.len(),
        crate::format::time(day.starts[0]),
        crate::format::time(day.starts[day.starts.len() - 1])
    )?;
    for (scenario, outcomes) in results {
        let route: Vec<String> = scenario
            .waypoints
            .iter()
            .map(|w| format!("{} ({}, {})", w.label, w.at[0], w.at[1]))
            .collect();
        outln!("\nscenario {}: {}", scenario.name, route.join(" -> "))?;
        let mut header = vec!["model".to_string()];
        header.extend(RATIOS.iter().map(|r| format!("E({r})")));
        header.push("vs occupancy".into());
        header.push("mean path m".into());
        let mut table = Table::new(header);
        let baseline = outcomes[0].at_one();
        for (contender, outcome) in contenders.iter().zip(outcomes) {
            let mut row = vec![contender.name.clone()];
            row.extend(outcome.curve.iter().map(|e| e.to_string()));
            row.push(
                reduction_percent(baseline, outcome.at_one())
                    .map_or_else(|| "-".into(), |r| format!("{r:.1} %")),
            );
            row.push(format!("{:.1}", outcome.mean_length()));
            table.row(row);
        }
        out!("{}", table.render())?;
    }
    let fits: Vec<String> = contenders
        .iter()
        .filter(|c| c.model.is_some())
        .map(|c| format!("{} {:.1} s", c.name, c.fit_seconds))
        .collect();
    outln!(
        "\nE(rho): eq. (4.22), encounters (detections within {} m of the robot at {} m/s) of the \
         floor(n_nav rho) patrols of least predicted cost (lower is better); vs occupancy: fewer \
         encounters than the shortest route at rho = 1. Fitting: {}; benchmark {:.1} s, total \
         {:.1} s.",
        config.radius,
        config.speed,
        fits.join(", "),
        bench_seconds,
        started.elapsed().as_secs_f64()
    )?;
    Ok(())
}

fn scenario_json(scenario: &Scenario, outcomes: &[Outcome], contenders: &[Contender]) -> Value {
    let baseline = outcomes[0].at_one();
    let models: Vec<Value> = contenders
        .iter()
        .zip(outcomes)
        .map(|(contender, outcome)| {
            let at_one = outcome.at_one();
            json!({
                "model": contender.name,
                "curve": RATIOS.iter().zip(&outcome.curve).map(|(r, e)| json!({"rho": r, "encounters": e})).collect::<Vec<_>>(),
                "encounters_at_1": at_one,
                "reduction_vs_occupancy_percent": reduction_percent(baseline, at_one),
                "mean_path_m": outcome.mean_length(),
                "patrols": outcome.runs.iter().map(|r| json!({
                    "start": r.slot.start,
                    "model_t": r.slot.model_t,
                    "cost": r.cost,
                    "length_m": r.length,
                    "encounters": r.encounters,
                })).collect::<Vec<_>>(),
            })
        })
        .collect();
    json!({
        "scenario": scenario.name,
        "waypoints": scenario.waypoints.iter().map(|w| json!({"label": w.label, "x": w.at[0], "y": w.at[1]})).collect::<Vec<_>>(),
        "models": models,
    })
}

/// E(ρ) of every model, one panel per scenario.
fn plot_curves(
    results: &[(Scenario, Vec<Outcome>)],
    contenders: &[Contender],
    path: &Path,
) -> Result<()> {
    let panels: Vec<Panel> = results
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
fn plot_paths(
    results: &[(Scenario, Vec<Outcome>)],
    contenders: &[Contender],
    grid: &PlanningGrid,
    map: &OccupancyMap,
    detections: &Detections,
    path: &Path,
) -> Result<()> {
    let Some(shown) = contenders.iter().rposition(|c| c.model.is_some()) else {
        bail!("--plot-paths needs a rate model");
    };
    let mut panels = Vec::new();
    for (scenario, outcomes) in results {
        // The busiest hour: the slot with the most encounters of the shortest route.
        let busiest = outcomes[0].busiest().unwrap_or(0);
        let slot = outcomes[0].runs[busiest].slot;
        let weights = contenders[shown]
            .cost()
            .weights(grid, slot.model_t, f64::MIN_POSITIVE)?;
        // Colours up to the 98th percentile: a few queues would otherwise darken the rest.
        let mut finite: Vec<f64> = weights.iter().copied().filter(|w| w.is_finite()).collect();
        finite.sort_by(f64::total_cmp);
        let top = finite
            .get((finite.len() * 98 / 100).min(finite.len().saturating_sub(1)))
            .copied()
            .unwrap_or(0.0)
            .max(f64::MIN_POSITIVE);
        let values: Vec<f32> = weights
            .iter()
            .map(|&w| {
                if w.is_finite() {
                    (w / top) as f32
                } else {
                    f32::NAN
                }
            })
            .collect();
        let paths = contenders
            .iter()
            .zip(outcomes)
            .map(|(c, o)| PathMapPath {
                label: c.name.clone(),
                points: o.runs[busiest]
                    .cells
                    .iter()
                    .map(|&cell| grid.centre(cell))
                    .collect(),
            })
            .collect();
        let people: Vec<[f64; 2]> = detections
            .between(slot.start, slot.start + SLOT_SECS)
            .iter()
            .map(|e| [e.x, e.y])
            .collect();
        panels.push(PathMap {
            title: format!(
                "{}: {} predicted rate at {} (yellow: >= {:.0}/h); paths of every model",
                scenario.name,
                contenders[shown].name,
                crate::format::time(slot.start),
                top
            ),
            origin: grid.origin(),
            cell: grid.cell_size(),
            cols: grid.cols(),
            rows: grid.rows(),
            values,
            obstacles: map_obstacle_points(map, grid),
            people,
            paths,
            waypoints: scenario
                .waypoints
                .iter()
                .map(|w| (w.label.clone(), w.at))
                .collect(),
        });
    }
    render_path_maps_png(&panels, path, 24)?;
    Ok(())
}
