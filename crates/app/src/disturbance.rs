//! The service-disturbance experiment of CoPA-Map ([Stüde 2024] eq. 4.22, §4.3.2 and §4.3.5):
//! every model of the comparison fitted to training rates, patrols planned on each one's
//! predicted rates of people over the free cells of a map, and driven through a test day of
//! pedestrian tracks ([`chronomap_activity::disturbance_day`]).
//!
//! Files in ([`DisturbanceFiles`]), a [`DisturbanceStudy`] out; the command line prints its
//! tables and draws its plots.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_activity::disturbance::{
    Detections, DisturbanceConfig, DisturbanceError, PathCost, PlanningGrid, Scenario,
};
use chronomap_activity::disturbance_day::{
    Outcome, RATIOS, SLOT_SECS, TestDay, reduction_percent, run_scenario, test_day,
};
use chronomap_activity::planning::training_grid;
use chronomap_activity::{Baseline, CopaConfig, CopaMap, RatePredictor, RateSamples};
use chronomap_core::Parallelism;
use chronomap_core::progress::Progress;
use chronomap_core::time::format_time;
use chronomap_io::DataError;
use chronomap_io::navmap::{LoadSemantics, load_map};
use chronomap_io::read_rate_samples;
use chronomap_io::scenarios::read_scenarios;
use chronomap_io::tracks::read_track_files;
use chronomap_spatial::OccupancyMap;
use serde_json::{Value, json};
use thiserror::Error;

use crate::activity::baseline_config;
use crate::report::Table;

/// A map cell is an obstacle if its occupancy is at least this (percent) or unknown.
pub const OCCUPIED_PERCENT: i8 = 50;

/// The name of the baseline that always drives the shortest route.
pub const OCCUPANCY: &str = "occupancy";

/// Why the experiment cannot run.
#[derive(Debug, Error)]
pub enum DisturbanceJobError {
    /// The training rates cannot be read.
    #[error("cannot read the training rates")]
    Train(#[source] DataError),
    /// The track files cannot be read.
    #[error("cannot read the tracks")]
    Tracks(#[source] DataError),
    /// A file cannot be read (the scenarios).
    #[error(transparent)]
    Data(#[from] DataError),
    /// The map cannot be read.
    #[error(transparent)]
    Map(#[from] chronomap_io::navmap::NavMapError),
    /// Anything else, as a message naming the file, scenario or model.
    #[error("{0}")]
    Message(String),
}

/// The files of the experiment.
#[derive(Clone, Debug)]
pub struct DisturbanceFiles<'a> {
    /// Training rates (`x1,x2,t,y`).
    pub train: &'a Path,
    /// Pedestrian tracks of the test day.
    pub tracks: &'a [PathBuf],
    /// The map the robot drives on (Nav2 YAML).
    pub map: &'a Path,
    /// The scenarios (waypoints of each patrol).
    pub scenarios: &'a Path,
    /// The scenario to run, or `all`.
    pub scenario: &'a str,
}

/// The experiment's settings.
#[derive(Clone, Copy, Debug)]
pub struct DisturbanceSettings {
    /// Least distance (m) of a training cell from obstacles for the robot to drive on it.
    pub clearance: f64,
    /// Start of the test day in the time of the detections (default: the first detection's
    /// hour).
    pub day_start: Option<f64>,
    /// The model time of the first hour (default: the first whole day after training).
    pub t0: Option<f64>,
    /// The day's length in model time (hour bins).
    pub period: f64,
    /// The least cost of a cell ([`DisturbanceConfig::epsilon`]).
    pub epsilon: f64,
    /// Inducing points of CoPA-Map and GP-Hom.
    pub inducing: usize,
    /// Training iterations of CoPA-Map and GP-Hom.
    pub iterations: usize,
    /// Leave out CoPA-Map and GP-Hom (the slow fits).
    pub no_copa: bool,
    /// Threads of the fits.
    pub parallelism: Parallelism,
}

/// One model of the comparison: its name and how it prices a cell (`None`: by length only).
pub struct Contender {
    /// The model's name.
    pub name: String,
    /// The fitted model, `None` for the shortest route.
    pub model: Option<Box<dyn RatePredictor + Send + Sync>>,
    /// Seconds its fit took.
    pub fit_seconds: f64,
}

impl Contender {
    /// How this model prices a cell.
    pub fn cost(&self) -> PathCost<'_> {
        match &self.model {
            None => PathCost::Length,
            Some(model) => PathCost::Rate(model.as_ref()),
        }
    }
}

/// What the experiment found, and what it ran on.
pub struct DisturbanceStudy {
    /// The training rates.
    pub train: RateSamples,
    /// The test day's detections.
    pub detections: Detections,
    /// The map.
    pub map: OccupancyMap,
    /// Where the robot may drive: the training grid's cells that are free on the map.
    pub grid: PlanningGrid,
    /// The test day: its slots of patrols.
    pub day: TestDay,
    /// The models, in table order.
    pub contenders: Vec<Contender>,
    /// Every scenario with every model's outcome (in the order of `contenders`).
    pub results: Vec<(Scenario, Vec<Outcome>)>,
    /// The settings of the patrols.
    pub config: DisturbanceConfig,
    /// Seconds the patrols took (fits excluded).
    pub bench_seconds: f64,
}

impl DisturbanceStudy {
    /// The study as `chronomap activity disturbance --json` prints it: the files and settings
    /// it ran with, the seconds of the fits, the patrols and the whole run (`total_seconds`,
    /// timed by the face), and per scenario every model's E(ρ) curve of eq. (4.22) with its
    /// patrols.
    pub fn json(
        &self,
        files: &DisturbanceFiles,
        settings: &DisturbanceSettings,
        total_seconds: f64,
    ) -> Value {
        let scenarios: Vec<Value> = self
            .results
            .iter()
            .map(|(scenario, outcomes)| self.scenario_json(scenario, outcomes))
            .collect();
        json!({
            "train": files.train.display().to_string(),
            "tracks": files.tracks.len(),
            "detections": self.detections.events().len(),
            "day_start": self.day.day_start,
            "t0": self.day.t0,
            "n_nav": self.day.slots.len(),
            "starts": self.day.starts,
            "free_cells": self.grid.free_count(),
            "cell_m": self.grid.cell_size(),
            "clearance_m": settings.clearance,
            "epsilon": settings.epsilon,
            "speed_m_s": self.config.speed,
            "radius_m": self.config.radius,
            "ratios": RATIOS,
            "fit_seconds": self.contenders.iter().map(|c| (c.name.clone(), json!(c.fit_seconds))).collect::<serde_json::Map<_, _>>(),
            "benchmark_seconds": self.bench_seconds,
            "total_seconds": total_seconds,
            "scenarios": scenarios,
        })
    }

    fn scenario_json(&self, scenario: &Scenario, outcomes: &[Outcome]) -> Value {
        let baseline = outcomes[0].at_one();
        let models: Vec<Value> = self
            .contenders
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

    /// The study as `chronomap activity disturbance` prints it: the data, the planning grid
    /// and the test day, one table of E(ρ) per scenario, and what the columns mean.
    pub fn text(
        &self,
        files: &DisturbanceFiles,
        settings: &DisturbanceSettings,
        total_seconds: f64,
    ) -> String {
        let (day, grid) = (&self.day, &self.grid);
        let mut out = String::new();
        let _ = writeln!(
            out,
            "training: {}: {} samples over {} cells; test: {} detections in {} track files",
            files.train.display(),
            self.train.len(),
            self.train.cell_count(),
            self.detections.events().len(),
            files.tracks.len()
        );
        let _ = writeln!(
            out,
            "planning: {} free cells of {} m (training cells at least {} m from obstacles); model \
             time t = {} + hour from {}",
            grid.free_count(),
            grid.cell_size(),
            settings.clearance,
            day.t0,
            format_time(day.day_start)
        );
        let _ = writeln!(
            out,
            "patrols: n_nav = {} per scenario, every 15 min where the slot is tracked ({} .. {})",
            day.slots.len(),
            format_time(day.starts[0]),
            format_time(day.starts[day.starts.len() - 1])
        );
        for (scenario, outcomes) in &self.results {
            let route: Vec<String> = scenario
                .waypoints
                .iter()
                .map(|w| format!("{} ({}, {})", w.label, w.at[0], w.at[1]))
                .collect();
            let _ = writeln!(out, "\nscenario {}: {}", scenario.name, route.join(" -> "));
            let mut header = vec!["model".to_string()];
            header.extend(RATIOS.iter().map(|r| format!("E({r})")));
            header.push("vs occupancy".into());
            header.push("mean path m".into());
            let mut table = Table::new(header);
            let baseline = outcomes[0].at_one();
            for (contender, outcome) in self.contenders.iter().zip(outcomes) {
                let mut row = vec![contender.name.clone()];
                row.extend(outcome.curve.iter().map(|e| e.to_string()));
                row.push(
                    reduction_percent(baseline, outcome.at_one())
                        .map_or_else(|| "-".into(), |r| format!("{r:.1} %")),
                );
                row.push(format!("{:.1}", outcome.mean_length()));
                table.row(row);
            }
            out.push_str(&table.render());
        }
        let fits: Vec<String> = self
            .contenders
            .iter()
            .filter(|c| c.model.is_some())
            .map(|c| format!("{} {:.1} s", c.name, c.fit_seconds))
            .collect();
        let _ = writeln!(
            out,
            "\nE(rho): eq. (4.22), encounters (detections within {} m of the robot at {} m/s) of the \
             floor(n_nav rho) patrols of least predicted cost (lower is better); vs occupancy: fewer \
             encounters than the shortest route at rho = 1. Fitting: {}; benchmark {:.1} s, total \
             {:.1} s.",
            self.config.radius,
            self.config.speed,
            fits.join(", "),
            self.bench_seconds,
            total_seconds
        );
        out
    }
}

/// A scenario's busiest patrol slot for a plot: the cost map of one rate model then, every
/// model's path, and the people tracked then.
#[derive(Clone, Debug, PartialEq)]
pub struct BusiestSlot {
    /// The scenario.
    pub scenario: String,
    /// The model whose cost map is shown.
    pub model: String,
    /// The slot's start (time of the detections).
    pub start: f64,
    /// The cost the colours end at (the 98th percentile of the finite costs).
    pub top: f64,
    /// Per cell of the planning grid: cost / `top` (NaN where the robot cannot drive).
    pub values: Vec<f32>,
    /// Every model's path then (cell centres).
    pub paths: Vec<(String, Vec<[f64; 2]>)>,
    /// The people detected during the slot.
    pub people: Vec<[f64; 2]>,
    /// The scenario's waypoints.
    pub waypoints: Vec<(String, [f64; 2])>,
}

impl DisturbanceStudy {
    /// Per scenario, its busiest slot (the most encounters of the shortest route) with the
    /// cost map of the last rate model (CoPA-Map unless left out); `None` without a rate model.
    ///
    /// # Errors
    /// The model cannot price the cells.
    pub fn busiest_slots(&self) -> Result<Option<Vec<BusiestSlot>>, DisturbanceError> {
        let Some(shown) = self.contenders.iter().rposition(|c| c.model.is_some()) else {
            return Ok(None);
        };
        let grid = &self.grid;
        let mut slots = Vec::new();
        for (scenario, outcomes) in &self.results {
            let busiest = outcomes[0].busiest().unwrap_or(0);
            let slot = outcomes[0].runs[busiest].slot;
            let weights =
                self.contenders[shown]
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
            slots.push(BusiestSlot {
                scenario: scenario.name.clone(),
                model: self.contenders[shown].name.clone(),
                start: slot.start,
                top,
                values: weights
                    .iter()
                    .map(|&w| {
                        if w.is_finite() {
                            (w / top) as f32
                        } else {
                            f32::NAN
                        }
                    })
                    .collect(),
                paths: self
                    .contenders
                    .iter()
                    .zip(outcomes)
                    .map(|(c, o)| {
                        let cells = &o.runs[busiest].cells;
                        (
                            c.name.clone(),
                            cells.iter().map(|&c| grid.centre(c)).collect(),
                        )
                    })
                    .collect(),
                people: self
                    .detections
                    .between(slot.start, slot.start + SLOT_SECS)
                    .iter()
                    .map(|e| [e.x, e.y])
                    .collect(),
                waypoints: scenario
                    .waypoints
                    .iter()
                    .map(|w| (w.label.clone(), w.at))
                    .collect(),
            });
        }
        Ok(Some(slots))
    }
}

/// Reads the files, fits every model and drives every scenario's patrols through the test
/// day; fits and patrols report to `progress`. Everything is checked (waypoints on free cells,
/// a tracked slot) before the models are fitted.
///
/// # Errors
/// [`DisturbanceJobError`] naming the file, scenario, waypoint or model.
pub fn run_disturbance(
    files: &DisturbanceFiles,
    settings: &DisturbanceSettings,
    progress: &dyn Progress,
) -> Result<DisturbanceStudy, DisturbanceJobError> {
    let message = DisturbanceJobError::Message;
    let train_name = files.train.display().to_string();
    let train = read_rate_samples(files.train).map_err(DisturbanceJobError::Train)?;
    let events = read_track_files(files.tracks).map_err(DisturbanceJobError::Tracks)?;
    let detections = Detections::new(events).map_err(|e| message(format!("the tracks: {e}")))?;
    let map_name = files.map.display().to_string();
    let map = load_map(files.map, LoadSemantics::Nav2)?;
    let obstacles = map
        .planning_obstacles(OCCUPIED_PERCENT)
        .map_err(|e| message(format!("{map_name}: {e}")))?;
    let mut scenarios = read_scenarios(files.scenarios)?;
    if files.scenario != "all" {
        scenarios.retain(|s| s.name == files.scenario);
        if scenarios.is_empty() {
            return Err(message(format!(
                "{}: no scenario {:?} (use a name from the file or `all`)",
                files.scenarios.display(),
                files.scenario
            )));
        }
    }

    let grid = training_grid(&train, &obstacles, settings.clearance)
        .map_err(|e| message(format!("{train_name}: {e}")))?;

    // Every waypoint must be a free cell.
    let waypoint_cells = scenarios
        .iter()
        .map(|scenario| {
            scenario
                .waypoints
                .iter()
                .map(|w| {
                    grid.waypoint(w.at).map_err(|e| {
                        message(format!(
                            "scenario {:?}, waypoint {}: {e}",
                            scenario.name, w.label
                        ))
                    })
                })
                .collect::<Result<Vec<usize>, _>>()
        })
        .collect::<Result<Vec<_>, _>>()?;

    // When: four patrols per hour, each slot wholly inside the tracked time.
    let day = test_day(
        &detections,
        &train,
        settings.day_start,
        settings.t0,
        settings.period,
    );
    if day.starts.is_empty() {
        return Err(message(format!(
            "no 15-minute slot between {} and {} lies inside the tracked time of the tracks",
            format_time(day.day_start),
            format_time(day.day_end)
        )));
    }

    let contenders = fit_models(&train, settings, progress)
        .map_err(|e| message(format!("{train_name}: {e}")))?;
    let config = DisturbanceConfig {
        epsilon: settings.epsilon,
        max_duration: SLOT_SECS,
        ..DisturbanceConfig::default()
    };

    let bench_start = Instant::now();
    let costs: Vec<(&str, PathCost<'_>)> = contenders
        .iter()
        .map(|c| (c.name.as_str(), c.cost()))
        .collect();
    let mut results = Vec::new();
    for (scenario, waypoints) in scenarios.into_iter().zip(waypoint_cells) {
        let outcomes = run_scenario(
            &grid,
            &waypoints,
            &costs,
            &day.slots,
            &detections,
            &config,
            progress,
        )
        .map_err(|e| message(format!("scenario {:?}, {e}", scenario.name)))?;
        results.push((scenario, outcomes));
    }
    let bench_seconds = bench_start.elapsed().as_secs_f64();
    Ok(DisturbanceStudy {
        train,
        detections,
        map,
        grid,
        day,
        contenders,
        results,
        config,
        bench_seconds,
    })
}

/// The models of the comparison, in table order: the shortest route first, then every
/// baseline of [`Baseline::ALL`], then CoPA-Map. Any other [`RatePredictor`] joins with one
/// more `push`. Each fit is timed; the long ones report their iterations to `progress`.
fn fit_models(
    train: &RateSamples,
    settings: &DisturbanceSettings,
    progress: &dyn Progress,
) -> Result<Vec<Contender>, String> {
    let mut contenders = vec![Contender {
        name: OCCUPANCY.into(),
        model: None,
        fit_seconds: 0.0,
    }];
    let config = baseline_config(
        settings.period,
        settings.inducing,
        settings.iterations,
        settings.parallelism,
    );
    for baseline in Baseline::ALL {
        if settings.no_copa && baseline == Baseline::GpHom {
            continue;
        }
        progress.stage(baseline.name(), 0);
        let start = Instant::now();
        let model = baseline
            .fit_with_progress(train, &config, progress)
            .map_err(|e| format!("{}: {e}", baseline.name()))?;
        contenders.push(Contender {
            name: baseline.name().into(),
            model: Some(model),
            fit_seconds: start.elapsed().as_secs_f64(),
        });
    }
    if !settings.no_copa {
        let start = Instant::now();
        let copa = CopaConfig {
            inducing: settings.inducing,
            iterations: settings.iterations,
            day_period: settings.period,
            parallelism: settings.parallelism,
            ..CopaConfig::default()
        };
        let model = CopaMap::fit_with_progress(train, &copa, progress)
            .map_err(|e| format!("CoPA-Map: {e}"))?;
        contenders.push(Contender {
            name: model.name().into(),
            model: Some(Box::new(model)),
            fit_seconds: start.elapsed().as_secs_f64(),
        });
    }
    Ok(contenders)
}

/// The centres of the map's occupied pixels inside the planning grid (for plots).
pub fn map_obstacle_points(map: &OccupancyMap, grid: &PlanningGrid) -> Vec<[f64; 2]> {
    let [gx, gy] = grid.origin();
    let top = [
        gx + grid.cols() as f64 * grid.cell_size(),
        gy + grid.rows() as f64 * grid.cell_size(),
    ];
    map.occupied_centres(OCCUPIED_PERCENT, [gx, gy], top)
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_core::progress::NoProgress;
    use chronomap_testutil::data_path;

    /// The hallway of the bundled ATC scenarios over two hours of tracks (13:00–15:00 JST),
    /// the cheap models only: the measured encounters of the command line's test, as text and
    /// JSON, and the busiest slot for the plot.
    #[test]
    fn the_atc_hallway_study_reports_its_encounters_as_text_and_json() {
        let tracks = [
            data_path("atc_20121024_1hz/atc-1024-13_train.csv.xz"),
            data_path("atc_20121024_1hz/atc-1024-14_train.csv.xz"),
        ];
        let train = data_path("atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz");
        let map = data_path("atc_copa_map_grid/atc_map.yaml");
        let scenarios = data_path("atc_20121024_1hz/disturbance_scenarios.csv");
        let files = DisturbanceFiles {
            train: &train,
            tracks: &tracks,
            map: &map,
            scenarios: &scenarios,
            scenario: "hallway",
        };
        let settings = DisturbanceSettings {
            clearance: 0.3,
            // 2012-10-24 09:00 JST.
            day_start: Some(1_351_036_800.0),
            t0: None,
            period: 12.0,
            epsilon: 1.0,
            inducing: 200,
            iterations: 300,
            no_copa: true,
            parallelism: Parallelism::Sequential,
        };
        let study = run_disturbance(&files, &settings, &NoProgress).unwrap();
        let json = study.json(&files, &settings, 2.5);
        assert_eq!(json["n_nav"], 8);
        assert_eq!(json["free_cells"], 523);
        assert_eq!(json["tracks"], 2);
        assert_eq!(json["total_seconds"], 2.5);
        let models = &json["scenarios"][0]["models"];
        assert_eq!(models[0]["model"], OCCUPANCY);
        assert_eq!(models[0]["encounters_at_1"], 67);
        assert_eq!(models[2]["encounters_at_1"], 81);
        assert_eq!(models[0]["reduction_vs_occupancy_percent"], 0.0);

        let text = study.text(&files, &settings, 2.5);
        let lines: Vec<&str> = text.lines().collect();
        assert!(
            lines[2].starts_with("patrols: n_nav = 8 per scenario, every 15 min where the slot is tracked (2012-10-24 04:00 UTC .. "),
            "{text}"
        );
        let row = lines.iter().find(|l| l.starts_with("occupancy ")).unwrap();
        let cells: Vec<&str> = row.split_whitespace().collect();
        // The curve E(ρ) at every ratio of RATIOS, the reduction against itself, the mean path.
        assert_eq!(
            cells,
            [
                "occupancy",
                "0",
                "8",
                "15",
                "23",
                "29",
                "29",
                "37",
                "41",
                "46",
                "67",
                "0.0",
                "%",
                "27.5"
            ]
        );
        assert!(text.ends_with("total 2.5 s.\n"), "{text}");

        let slots = study.busiest_slots().unwrap().unwrap();
        assert_eq!(slots.len(), 1);
        assert_eq!(slots[0].scenario, "hallway");
        assert_eq!(slots[0].model, "log_additive");
        assert_eq!(slots[0].paths.len(), 7);
        assert_eq!(slots[0].values.len(), study.grid.len());
    }
}
