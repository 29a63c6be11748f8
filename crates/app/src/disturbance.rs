//! The service-disturbance experiment of CoPA-Map ([Stüde 2024] eq. 4.22, §4.3.2 and §4.3.5):
//! every model of the comparison fitted to training rates, patrols planned on each one's
//! predicted rates of people over the free cells of a map, and driven through a test day of
//! pedestrian tracks ([`chronomap_activity::disturbance_day`]).
//!
//! Files in ([`DisturbanceFiles`]), a [`DisturbanceStudy`] out; the command line prints its
//! tables and draws its plots.

use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_activity::disturbance::{
    Detections, DisturbanceConfig, PathCost, PlanningGrid, Scenario,
};
use chronomap_activity::disturbance_day::{Outcome, SLOT_SECS, TestDay, run_scenario, test_day};
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
use thiserror::Error;

use crate::activity::baseline_config;

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
