//! `chronomap activity disturbance`: the service-disturbance benchmark of CoPA-Map
//! (dissertation chapter 4, seed 002 eq. 4.22, §4.3.2 and §4.3.5): patrols planned on every
//! model's predicted rates of people, driven through a test day of pedestrian tracks.

use std::collections::HashSet;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use chronomap_activity::disturbance::{
    Detections, DisturbanceConfig, ObstacleGrid, PathCost, PatrolRun, PatrolSlot, PlanningGrid,
    Scenario, disturbance_curve, patrol_starts, run_patrols,
};
use chronomap_activity::{Baseline, CellKey, CopaConfig, CopaMap, RatePredictor, RateSamples};
use chronomap_core::Parallelism;
use chronomap_hypertime::events::observed_windows;
use chronomap_io::navmap::{LoadSemantics, OccupancyMap, load_map};
use chronomap_io::read_rate_samples;
use chronomap_io::scenarios::read_scenarios;
use chronomap_io::tracks::read_track_files;
use chronomap_plot::{
    Panel, PathMap, PathMapPath, Series, SeriesStyle, render_panels_png, render_path_maps_png,
};
use serde_json::{Value, json};

use crate::cli::ActivityDisturbanceArgs;
use crate::format::Table;

/// Servicing ratios of the table and the plot: 0.1, 0.2, … 1.0.
const RATIOS: [f64; 10] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0];

/// Patrols start every 15 minutes (four per hour, §4.3.5); a patrol must fit its slot.
const SLOT_SECS: f64 = 900.0;

/// Consecutive detections further apart than this split the tracked time.
const TRACKING_GAP_SECS: f64 = 60.0;

/// The tracks are sampled at 1 Hz: the tracked time extends one sample period before the first
/// and after the last detection of a window (files start at e.g. 13:00:00.98).
const SAMPLE_SECS: f64 = 1.0;

/// A map cell is an obstacle if its occupancy is at least this (percent) or unknown.
const OCCUPIED_PERCENT: i8 = 50;

/// The baseline that always drives the shortest route.
const OCCUPANCY: &str = "occupancy";

/// One model of the comparison: its name and how it prices a cell (`None`: by length only).
struct Contender {
    name: String,
    model: Option<Box<dyn RatePredictor + Send + Sync>>,
    fit_seconds: f64,
}

impl Contender {
    fn cost(&self) -> PathCost<'_> {
        match &self.model {
            None => PathCost::Length,
            Some(model) => PathCost::Rate(model.as_ref()),
        }
    }
}

/// One model's patrols in one scenario.
struct Outcome {
    runs: Vec<PatrolRun>,
    curve: Vec<usize>,
}

pub fn run(args: &ActivityDisturbanceArgs) -> Result<()> {
    let started = Instant::now();
    let train_name = args.train.display().to_string();
    let train = read_rate_samples(&args.train).context("cannot read the training rates")?;
    let events = read_track_files(&args.tracks).context("cannot read the tracks")?;
    let detections = Detections::new(events).map_err(|e| anyhow!("the tracks: {e}"))?;
    let map_name = args.map.display().to_string();
    let map = load_map(&args.map, LoadSemantics::Nav2)?;
    let obstacles = obstacles_of(&map).map_err(|e| anyhow!("{map_name}: {e}"))?;
    let mut scenarios = read_scenarios(&args.scenarios)?;
    if args.scenario != "all" {
        scenarios.retain(|s| s.name == args.scenario);
        if scenarios.is_empty() {
            bail!(
                "{}: no scenario {:?} (use a name from the file or `all`)",
                args.scenarios.display(),
                args.scenario
            );
        }
    }

    // Where the robot may drive: the training grid's cells that are free on the map.
    let grid = planning_grid(&train, &obstacles, args.clearance)
        .map_err(|e| anyhow!("{train_name}: {e}"))?;

    // Every waypoint must be a free cell (checked before the models are fitted).
    let waypoint_cells = scenarios
        .iter()
        .map(|scenario| {
            scenario
                .waypoints
                .iter()
                .map(|w| {
                    grid.waypoint(w.at).map_err(|e| {
                        anyhow!("scenario {:?}, waypoint {}: {e}", scenario.name, w.label)
                    })
                })
                .collect::<Result<Vec<usize>>>()
        })
        .collect::<Result<Vec<_>>>()?;

    // When: four patrols per hour, each slot wholly inside the tracked time.
    let first = detections.events()[0].t;
    let day_start = args.day_start.unwrap_or((first / 3600.0).floor() * 3600.0);
    let max_t = train.t().iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let t0 = args
        .t0
        .unwrap_or(((max_t + 1.0) / args.period).ceil() * args.period);
    let mut tracked = observed_windows(detections.events(), TRACKING_GAP_SECS);
    for window in &mut tracked {
        window.start -= SAMPLE_SECS;
        window.end += SAMPLE_SECS;
    }
    let day_end = day_start + args.period * 3600.0;
    let starts = patrol_starts(&tracked, day_start, day_end, SLOT_SECS);
    if starts.is_empty() {
        bail!(
            "no 15-minute slot between {} and {} lies inside the tracked time of the tracks",
            crate::format::time(day_start),
            crate::format::time(day_end)
        );
    }
    let slots: Vec<PatrolSlot> = starts
        .iter()
        .map(|&start| PatrolSlot {
            start,
            model_t: t0 + ((start - day_start) / 3600.0).floor(),
        })
        .collect();

    let contenders = fit_models(args, &train).map_err(|e| anyhow!("{train_name}: {e}"))?;
    let config = DisturbanceConfig {
        epsilon: args.epsilon,
        max_duration: SLOT_SECS,
        ..DisturbanceConfig::default()
    };

    let bench_start = Instant::now();
    let mut results: Vec<(Scenario, Vec<Outcome>)> = Vec::new();
    for (scenario, waypoints) in scenarios.into_iter().zip(waypoint_cells) {
        let mut outcomes = Vec::new();
        for contender in &contenders {
            let runs = run_patrols(
                &grid,
                &waypoints,
                &contender.cost(),
                &slots,
                &detections,
                &config,
            )
            .map_err(|e| anyhow!("scenario {:?}, {}: {e}", scenario.name, contender.name))?;
            let costs: Vec<f64> = runs.iter().map(|r| r.cost).collect();
            let encounters: Vec<usize> = runs.iter().map(|r| r.encounters).collect();
            let curve = disturbance_curve(&costs, &encounters, &RATIOS)?;
            outcomes.push(Outcome { runs, curve });
        }
        results.push((scenario, outcomes));
    }
    let bench_seconds = bench_start.elapsed().as_secs_f64();

    if let Some(path) = &args.plot {
        plot_curves(&results, &contenders, path)?;
    }
    if let Some(path) = &args.plot_paths {
        plot_paths(&results, &contenders, &grid, &map, &detections, path)?;
    }

    let mut out = std::io::stdout().lock();
    if args.json {
        let scenarios: Vec<Value> = results
            .iter()
            .map(|(scenario, outcomes)| scenario_json(scenario, outcomes, &contenders))
            .collect();
        writeln!(
            out,
            "{}",
            json!({
                "train": train_name,
                "tracks": args.tracks.len(),
                "detections": detections.events().len(),
                "day_start": day_start,
                "t0": t0,
                "n_nav": slots.len(),
                "starts": starts,
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
            })
        )?;
        return Ok(());
    }

    writeln!(
        out,
        "training: {train_name}: {} samples over {} cells; test: {} detections in {} track files",
        train.len(),
        train.cell_count(),
        detections.events().len(),
        args.tracks.len()
    )?;
    writeln!(
        out,
        "planning: {} free cells of {} m (training cells at least {} m from obstacles); model \
         time t = {t0} + hour from {}",
        grid.free_count(),
        grid.cell_size(),
        args.clearance,
        crate::format::time(day_start)
    )?;
    writeln!(
        out,
        "patrols: n_nav = {} per scenario, every 15 min where the slot is tracked ({} .. {})",
        slots.len(),
        crate::format::time(starts[0]),
        crate::format::time(starts[starts.len() - 1])
    )?;
    for (scenario, outcomes) in &results {
        let route: Vec<String> = scenario
            .waypoints
            .iter()
            .map(|w| format!("{} ({}, {})", w.label, w.at[0], w.at[1]))
            .collect();
        writeln!(out, "\nscenario {}: {}", scenario.name, route.join(" -> "))?;
        let mut header = vec!["model".to_string()];
        header.extend(RATIOS.iter().map(|r| format!("E({r})")));
        header.push("vs occupancy".into());
        header.push("mean path m".into());
        let mut table = Table::new(header);
        let baseline = outcomes[0].curve[RATIOS.len() - 1];
        for (contender, outcome) in contenders.iter().zip(outcomes) {
            let mut row = vec![contender.name.clone()];
            row.extend(outcome.curve.iter().map(|e| e.to_string()));
            row.push(reduction_text(baseline, outcome.curve[RATIOS.len() - 1]));
            row.push(format!("{:.1}", mean_length(&outcome.runs)));
            table.row(row);
        }
        write!(out, "{}", table.render())?;
    }
    let fits: Vec<String> = contenders
        .iter()
        .filter(|c| c.model.is_some())
        .map(|c| format!("{} {:.1} s", c.name, c.fit_seconds))
        .collect();
    writeln!(
        out,
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

/// The obstacles of a ROS map: cells at least [`OCCUPIED_PERCENT`] occupied or unknown.
pub(super) fn obstacles_of(map: &OccupancyMap) -> Result<ObstacleGrid> {
    if map.origin[2] != 0.0 {
        bail!(
            "the map is rotated (yaw {}): only maps aligned with their frame are supported",
            map.origin[2]
        );
    }
    let blocked = map
        .data
        .iter()
        .map(|&v| !(0..OCCUPIED_PERCENT).contains(&v))
        .collect();
    Ok(ObstacleGrid::new(
        map.width as usize,
        map.height as usize,
        f64::from(map.resolution),
        [map.origin[0], map.origin[1]],
        blocked,
    )?)
}

/// The planning grid over the training cells: their spacing and bounding box, every cell that
/// is a training cell and has no obstacle within `clearance` free. Every free cell then has
/// training data, so no model falls back to a global value on the robot's way.
fn planning_grid(
    train: &RateSamples,
    obstacles: &ObstacleGrid,
    clearance: f64,
) -> Result<PlanningGrid> {
    let cells: HashSet<CellKey> = train.x().iter().map(|&x| CellKey::of(x)).collect();
    let centres: Vec<[f64; 2]> = cells.iter().map(|c| c.centre()).collect();
    let spacing = |k: usize| {
        let mut v: Vec<f64> = centres.iter().map(|c| c[k]).collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        let step = v
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(f64::INFINITY, f64::min);
        (v[0], v[v.len() - 1], step)
    };
    let (x_lo, x_hi, x_step) = spacing(0);
    let (y_lo, y_hi, y_step) = spacing(1);
    if !(x_step.is_finite() && (x_step - y_step).abs() <= 1e-9 * x_step) {
        bail!(
            "the training cells do not lie on a square grid (spacing {x_step} m along x1, \
             {y_step} m along x2)"
        );
    }
    let cell = x_step;
    let cols = ((x_hi - x_lo) / cell).round() as usize + 1;
    let rows = ((y_hi - y_lo) / cell).round() as usize + 1;
    let mut grid = PlanningGrid::new([x_lo - cell / 2.0, y_lo - cell / 2.0], cell, cols, rows)?;
    grid.keep_only(|c| cells.contains(&CellKey::of(c)));
    grid.block_obstacles(obstacles, clearance);
    if grid.free_count() == 0 {
        bail!("no training cell is {clearance} m away from every obstacle of the map");
    }
    Ok(grid)
}

/// The models of the comparison, in table order: the shortest route first, then every
/// baseline of [`Baseline::ALL`], then CoPA-Map. Any other [`RatePredictor`] joins with one
/// more `push`.
fn fit_models(args: &ActivityDisturbanceArgs, train: &RateSamples) -> Result<Vec<Contender>> {
    let mut contenders = vec![Contender {
        name: OCCUPANCY.into(),
        model: None,
        fit_seconds: 0.0,
    }];
    let config = super::activity::baseline_config(args.period, args.inducing, args.iterations);
    for baseline in Baseline::ALL {
        if args.no_copa && baseline == Baseline::GpHom {
            continue;
        }
        let start = Instant::now();
        let model = baseline
            .fit(train, &config)
            .map_err(|e| anyhow!("{}: {e}", baseline.name()))?;
        contenders.push(Contender {
            name: baseline.name().into(),
            model: Some(model),
            fit_seconds: start.elapsed().as_secs_f64(),
        });
    }
    if !args.no_copa {
        let start = Instant::now();
        let copa = CopaConfig {
            inducing: args.inducing,
            iterations: args.iterations,
            day_period: args.period,
            parallelism: Parallelism::Rayon(0),
            ..CopaConfig::default()
        };
        let model = CopaMap::fit(train, &copa).map_err(|e| anyhow!("CoPA-Map: {e}"))?;
        contenders.push(Contender {
            name: model.name().into(),
            model: Some(Box::new(model)),
            fit_seconds: start.elapsed().as_secs_f64(),
        });
    }
    Ok(contenders)
}

fn mean_length(runs: &[PatrolRun]) -> f64 {
    runs.iter().map(|r| r.length).sum::<f64>() / runs.len().max(1) as f64
}

/// Fewer encounters than the baseline, in percent (`-` when the baseline has none).
fn reduction(baseline: usize, model: usize) -> Option<f64> {
    (baseline > 0).then(|| 100.0 * (baseline as f64 - model as f64) / baseline as f64)
}

fn reduction_text(baseline: usize, model: usize) -> String {
    reduction(baseline, model).map_or_else(|| "-".into(), |r| format!("{r:.1} %"))
}

fn scenario_json(scenario: &Scenario, outcomes: &[Outcome], contenders: &[Contender]) -> Value {
    let baseline = outcomes[0].curve[RATIOS.len() - 1];
    let models: Vec<Value> = contenders
        .iter()
        .zip(outcomes)
        .map(|(contender, outcome)| {
            let at_one = outcome.curve[RATIOS.len() - 1];
            json!({
                "model": contender.name,
                "curve": RATIOS.iter().zip(&outcome.curve).map(|(r, e)| json!({"rho": r, "encounters": e})).collect::<Vec<_>>(),
                "encounters_at_1": at_one,
                "reduction_vs_occupancy_percent": reduction(baseline, at_one),
                "mean_path_m": mean_length(&outcome.runs),
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
        let busiest = outcomes[0]
            .runs
            .iter()
            .enumerate()
            .max_by_key(|(i, r)| (r.encounters, std::cmp::Reverse(*i)))
            .map_or(0, |(i, _)| i);
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

/// The centres of the map's occupied pixels inside the planning grid.
fn map_obstacle_points(map: &OccupancyMap, grid: &PlanningGrid) -> Vec<[f64; 2]> {
    let r = f64::from(map.resolution);
    let [gx, gy] = grid.origin();
    let (gx1, gy1) = (
        gx + grid.cols() as f64 * grid.cell_size(),
        gy + grid.rows() as f64 * grid.cell_size(),
    );
    let mut points = Vec::new();
    for row in 0..map.height as usize {
        let y = map.origin[1] + (row as f64 + 0.5) * r;
        if y < gy || y >= gy1 {
            continue;
        }
        for column in 0..map.width as usize {
            let x = map.origin[0] + (column as f64 + 0.5) * r;
            if x >= gx && x < gx1 && map.data[row * map.width as usize + column] >= OCCUPIED_PERCENT
            {
                points.push([x, y]);
            }
        }
    }
    points
}
