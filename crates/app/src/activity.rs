//! Maps of human activity ([Stüde 2024] chapter 4) as the faces use them: a model file opened
//! by its content ([`open_activity_model`]: CoPA-Map or Log-AM, by the kind its header names)
//! and the baselines' settings from the few numbers the command line takes
//! ([`baseline_config`]); the extraction job of §4.2.2 (eqs. 4.5–4.6: training samples from
//! pedestrian detections as simulated patrol robots see them, [`extract_samples`]) with its
//! setup ([`robots_on_map`]), or the ground truth of §4.3.2; and the evaluation of §4.3.2
//! ([`evaluate`]: every baseline and the chosen model scored by eqs. 4.20–4.21 on later data);
//! maps of a model's predicted rate over a grid of cells at several times ([`predict_maps`]).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_activity::extract::{
    ExtractConfig, Extraction, ObstacleGrid, RobotPath, extract_with_progress, ground_truth,
};
use chronomap_activity::grids::{RegionGrid, check_aligned, detection_bins, distinct_cells};
use chronomap_activity::lograte::LogAdditiveWithoutProcessSigma;
use chronomap_activity::truth::{TruthGrid, person_counts};
use chronomap_activity::{
    AnyActivityModel, Baseline, BaselineConfig, BaselineSelection, CopaConfig, CopaMap,
    FrAamConfig, GpHomConfig, LogAdditive, LogAdditiveConfig, PeriodInit, PeriodInitMode,
    RatePredictor, RateSamples, RateScale, Scores, WhyteConfig, score, select_baseline,
};
use chronomap_core::Parallelism;
use chronomap_core::calibration::{CURVE_LEVELS, Coverage};
use chronomap_core::num::{count_of, fmt_number};
use chronomap_core::progress::Progress;
use chronomap_hypertime::events::Event;
use chronomap_io::DataError;
use chronomap_io::model_file::{ModelFileError, read_model_file_or_older};
use chronomap_io::navmap::{LoadSemantics, NavMapError, load_map};
use chronomap_io::rate_predictions::RatePrediction;
use chronomap_io::{
    LOG_ADDITIVE_KIND, read_copa_map, read_rate_samples, read_robot_paths, read_track_files,
    read_track_point_files,
};
use chronomap_spatial::OccupancyMap;
use chronomap_spatial::occupancy::WALL_PERCENT;
use serde::Serialize;
use serde_json::{Value, json};
use thiserror::Error;

use crate::open::FileKind;
use crate::report::Table;

/// Why an activity model file cannot be opened.
#[derive(Debug, Error)]
pub enum OpenActivityError {
    /// The container or its payload is wrong (as [`chronomap_io::read_model_file`] and
    /// [`chronomap_io::read_copa_map`] say).
    #[error(transparent)]
    ModelFile(#[from] ModelFileError),
    /// A Log-AM whose invariants do not hold.
    #[error("{path}: an inconsistent Log-AM: {reason}")]
    InconsistentLogAdditive {
        /// The file.
        path: String,
        /// The broken invariant.
        reason: String,
    },
}

/// The activity model in `path`: Log-AM if the header names [`LOG_ADDITIVE_KIND`], else
/// CoPA-Map (whose reader names what is wrong with anything else), each checked.
///
/// # Errors
/// [`OpenActivityError`].
pub fn open_activity_model(path: &Path) -> Result<AnyActivityModel, OpenActivityError> {
    let log_additive =
        FileKind::of(path).is_ok_and(|kind| kind.model_kind() == Some(LOG_ADDITIVE_KIND));
    if !log_additive {
        return Ok(AnyActivityModel::Copa(Box::new(read_copa_map(path)?)));
    }
    // Files written before Log-AM knew the spread of whole hours read without it.
    let (_, model): (String, LogAdditive) =
        read_model_file_or_older::<_, LogAdditiveWithoutProcessSigma>(path)?;
    model
        .check()
        .map_err(|e| OpenActivityError::InconsistentLogAdditive {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
    Ok(AnyActivityModel::LogAdditive(model))
}

/// A model's predicted rate over the cells of a grid at several times.
#[derive(Clone, Debug, PartialEq)]
pub struct RateMaps {
    /// Per cell (row-major, as [`RegionGrid::centres`]): whether a wall of the map covers it.
    pub blocked: Vec<bool>,
    /// Every cell off the walls at every time, time by time.
    pub rows: Vec<RatePrediction>,
    /// Per time: the time, and the mean and standard deviation at every cell.
    pub panels: Vec<(f64, Vec<f64>, Vec<f64>)>,
}

impl RateMaps {
    /// The mean and the standard deviation at every time as images for a plot: a title and
    /// per cell the value over the largest of its kind off the walls at any time (NaN on a
    /// wall), means and deviations alternating.
    pub fn scaled_panels(&self) -> Vec<(String, Vec<f32>)> {
        let blocked = &self.blocked;
        let visible = |v: &[f64]| {
            v.iter()
                .zip(blocked)
                .filter(|(_, b)| !**b)
                .map(|(v, _)| *v)
                .fold(0.0f64, f64::max)
        };
        let max_mean = self
            .panels
            .iter()
            .map(|p| visible(&p.1))
            .fold(0.0, f64::max);
        let max_std = self
            .panels
            .iter()
            .map(|p| visible(&p.2))
            .fold(0.0, f64::max);
        let scaled = |values: &[f64], max: f64| -> Vec<f32> {
            values
                .iter()
                .zip(blocked)
                .map(|(v, b)| {
                    if *b {
                        f32::NAN
                    } else {
                        (v / max.max(1e-12)) as f32
                    }
                })
                .collect()
        };
        let mut images = Vec::new();
        for (t, mean, std) in &self.panels {
            images.push((
                format!("mean at t = {t} (max {max_mean:.0} per h)"),
                scaled(mean, max_mean),
            ));
            images.push((
                format!("std at t = {t} (max {max_std:.0} per h)"),
                scaled(std, max_std),
            ));
        }
        images
    }
}

/// The rate `model` predicts at the centre of every cell of `grid` at every one of `times`;
/// cells at least [`WALL_PERCENT`] occupied on `map` are kept out of the rows.
///
/// # Errors
/// The model's ([`AnyActivityModel::predict`]).
pub fn predict_maps(
    model: &AnyActivityModel,
    grid: &RegionGrid,
    times: &[f64],
    map: Option<&OccupancyMap>,
    parallelism: Parallelism,
) -> Result<RateMaps, chronomap_activity::ActivityError> {
    let centres = grid.centres();
    let blocked: Vec<bool> = centres
        .iter()
        .map(|&c| map.is_some_and(|m| m.is_occupied_at(c, WALL_PERCENT)))
        .collect();
    let mut rows = Vec::new();
    let mut panels = Vec::new();
    for &t in times {
        let points: Vec<([f64; 2], f64)> = centres.iter().map(|&c| (c, t)).collect();
        let (mean, std) = model.predict(&points, parallelism)?;
        for (i, &x) in centres.iter().enumerate() {
            if !blocked[i] {
                rows.push(RatePrediction {
                    x,
                    t,
                    mean: mean[i],
                    std: std[i],
                });
            }
        }
        panels.push((t, mean, std));
    }
    Ok(RateMaps {
        blocked,
        rows,
        panels,
    })
}

/// The baselines' settings ([Stüde 2024] §4.3.2) from the command line's numbers: Fr-AAM's
/// base period, GP-Hom trained like CoPA-Map (day period, inducing points, iterations) and
/// WHyTe on the threads `parallelism` allows, Log-AM with the day `period`.
pub fn baseline_config(
    period: f64,
    inducing: usize,
    iterations: usize,
    parallelism: Parallelism,
) -> BaselineConfig {
    BaselineConfig {
        fr_aam: FrAamConfig {
            period,
            ..FrAamConfig::default()
        },
        gp_hom: GpHomConfig {
            inducing,
            iterations,
            day_period: period,
            parallelism,
            ..GpHomConfig::default()
        },
        whyte: WhyteConfig {
            day_period: period,
            parallelism,
            ..WhyteConfig::default()
        },
        log_additive: LogAdditiveConfig {
            period,
            ..LogAdditiveConfig::default()
        },
    }
}

/// Why an activity job (extraction, evaluation) cannot run.
#[derive(Debug, Error)]
pub enum ActivityJobError {
    /// The map cannot be read.
    #[error("cannot load the map")]
    Map(#[source] NavMapError),
    /// The robot paths cannot be read.
    #[error("cannot read the robot paths")]
    Paths(#[source] DataError),
    /// A file of rates or tracks cannot be read.
    #[error("cannot read the {what}")]
    Rates {
        /// What the file holds.
        what: &'static str,
        /// Why.
        #[source]
        source: Box<DataError>,
    },
    /// More time bins than [`MAX_BINS`] over the detections.
    #[error(
        "--bin {}: gives {} bins from t0 {} over the detections; at most {MAX_BINS}",
        fmt_number(*bin),
        fmt_number(*span),
        fmt_number(*t0)
    )]
    TooManyBins {
        /// The bin (s).
        bin: f64,
        /// Bins from `t0` over the detections.
        span: f64,
        /// The start of bin 0.
        t0: f64,
    },
    /// A file that cannot be read.
    #[error(transparent)]
    Data(#[from] DataError),
    /// A folder that cannot be listed.
    #[error("cannot list {dir} (run from the repository root, or give --tracks)")]
    List {
        /// The folder.
        dir: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A map that cannot be read.
    #[error(transparent)]
    MapFile(#[from] NavMapError),
    /// The model refused its input.
    #[error(transparent)]
    Model(#[from] chronomap_activity::ActivityError),
    /// Anything else, as a message naming the file, path or step.
    #[error("{0}")]
    Message(String),
}

/// The obstacle grid of a ROS map (cells of at least `min_occupancy` percent block sight) and
/// the paths of a robot-path file (all, or those named in `names`) at `speed` m/s, each checked
/// to stay on free cells: the setup of the extraction of [Stüde 2024] §4.2.2.
///
/// # Errors
/// [`ActivityJobError`] naming the map, the path file and line, or an unknown name.
pub fn robots_on_map(
    map_file: &Path,
    paths_file: &Path,
    speed: f64,
    min_occupancy: i8,
    names: &[String],
) -> Result<(ObstacleGrid, Vec<(String, RobotPath)>), ActivityJobError> {
    let message = ActivityJobError::Message;
    let map_name = map_file.display().to_string();
    let map = load_map(map_file, LoadSemantics::Nav2).map_err(ActivityJobError::Map)?;
    let grid = map
        .obstacle_grid(min_occupancy)
        .map_err(|e| message(format!("{map_name}: {e}")))?;
    let paths_name = paths_file.display().to_string();
    let all = read_robot_paths(paths_file, speed).map_err(ActivityJobError::Paths)?;
    for name in names {
        if !all.iter().any(|p| &p.name == name) {
            let known: Vec<&str> = all.iter().map(|p| p.name.as_str()).collect();
            return Err(message(format!(
                "{paths_name}: no path named {name:?} (--robot); the file has {}",
                known.join(", ")
            )));
        }
    }
    let mut robots = Vec::new();
    for named in all {
        if !names.is_empty() && !names.contains(&named.name) {
            continue;
        }
        if let Some((at, outside)) = named.path.first_blocked(&grid, grid.resolution() / 2.0) {
            return Err(message(format!(
                "{paths_name}:{}: path {:?} passes ({:.3}, {:.3}), which is {} of {map_name}",
                named.line,
                named.name,
                at[0],
                at[1],
                if outside {
                    "outside the map"
                } else {
                    "an obstacle"
                }
            )));
        }
        robots.push((named.name, named.path));
    }
    Ok((grid, robots))
}

/// Where the samples of [`extract_samples`] come from.
#[derive(Clone, Copy, Debug)]
pub enum SampleSource<'a> {
    /// The ground truth of §4.3.2 in these cells (every detection counts).
    TruthIn(&'a [[f64; 2]]),
    /// What these robots see on this obstacle grid (§4.2.2); with `truth`, the ground truth in
    /// the cells they observed instead.
    Robots {
        /// Obstacles that block sight.
        grid: &'a ObstacleGrid,
        /// The robots' paths.
        paths: &'a [RobotPath],
        /// Whether to count the ground truth in the observed cells.
        truth: bool,
    },
}

/// The samples of `detections` in `bins` ([Stüde 2024] eqs. 4.5–4.6, or the ground truth of
/// §4.3.2): from the simulated robots' field of view, or from every detection; the robots'
/// simulation reports to `progress`.
///
/// # Errors
/// [`ActivityJobError::Message`] `extraction: …` or `ground truth: …`.
pub fn extract_samples(
    detections: &[Event],
    source: SampleSource,
    bins: &[i64],
    config: &ExtractConfig,
    progress: &dyn Progress,
) -> Result<Extraction, ActivityJobError> {
    let truth = |cells: &[[f64; 2]]| {
        ground_truth(detections, cells, bins, config)
            .map_err(|e| ActivityJobError::Message(format!("ground truth: {e}")))
    };
    match source {
        SampleSource::TruthIn(cells) => truth(cells),
        SampleSource::Robots {
            grid,
            paths,
            truth: counted,
        } => {
            let seen = extract_with_progress(grid, paths, detections, bins, config, progress)
                .map_err(|e| ActivityJobError::Message(format!("extraction: {e}")))?;
            if counted {
                truth(&seen.cells())
            } else {
                Ok(seen)
            }
        }
    }
}

/// Fraction of the distinct training times that [`EvalChoice::Auto`] holds out to choose a
/// model.
pub const HOLDOUT: f64 = 0.2;

/// The model [`evaluate`] reports at the top.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EvalChoice {
    /// The baseline of least NRMSE on the last [`HOLDOUT`] of the training times
    /// ([`select_baseline`]).
    Auto,
    /// This baseline.
    Baseline(Baseline),
    /// CoPA-Map ([Stüde 2024] §4.2), with these initial periods and this target scale.
    Copa {
        /// How the periods start (Algorithm 4.1 or the day).
        init: PeriodInitMode,
        /// The rate or ln(1 + rate).
        scale: RateScale,
    },
}

/// How [`evaluate`] trains.
#[derive(Clone, Copy, Debug)]
pub struct EvalSettings {
    /// The day's length in the samples' time (hour bins).
    pub period: f64,
    /// Inducing points of CoPA-Map and GP-Hom.
    pub inducing: usize,
    /// Training iterations of CoPA-Map and GP-Hom.
    pub iterations: usize,
    /// The model at the top.
    pub choice: EvalChoice,
    /// Threads of the fits.
    pub parallelism: Parallelism,
}

/// The scores of [Stüde 2024] §4.3.2: every baseline, and the model at the top.
pub struct Evaluation {
    /// Every baseline of [`Baseline::ALL`] with its scores and training seconds.
    pub baselines: Vec<(Baseline, Scores, f64)>,
    /// How [`EvalChoice::Auto`] chose (`None` for another choice).
    pub selection: Option<BaselineSelection>,
    /// The model at the top.
    pub model: Box<dyn RatePredictor + Send + Sync>,
    /// Its scores.
    pub scores: Scores,
    /// Seconds from the training samples to it fitted (the choice of `auto` included).
    pub train_seconds: f64,
    /// With CoPA-Map at the top: what Algorithm 4.1 found (`None`: started from the day).
    pub copa_init: Option<Option<PeriodInit>>,
}

/// Fits every baseline and the chosen model on `train` and scores each on `test` with the
/// NRMSE of eq. (4.20) and the χ²-distance of eq. (4.21); fits report to `progress`.
/// `train_name` and `test_name` name the data in errors.
///
/// # Errors
/// [`ActivityJobError::Message`] naming the data and the model that failed.
pub fn evaluate(
    train: &RateSamples,
    test: &RateSamples,
    settings: &EvalSettings,
    names: [&str; 2],
    progress: &dyn Progress,
) -> Result<Evaluation, ActivityJobError> {
    let [train_name, test_name] = names;
    let message = ActivityJobError::Message;
    let config = baseline_config(
        settings.period,
        settings.inducing,
        settings.iterations,
        settings.parallelism,
    );
    // Every baseline, fitted once and timed; the top-level model reuses its fit.
    let mut baselines = Vec::new();
    let mut fitted = Vec::new();
    for baseline in Baseline::ALL {
        progress.stage(baseline.name(), 0);
        let start = Instant::now();
        let model = baseline
            .fit_with_progress(train, &config, progress)
            .map_err(|e| message(format!("{train_name}: {}: {e}", baseline.name())))?;
        let seconds = start.elapsed().as_secs_f64();
        let scores =
            score(model.as_ref(), test).map_err(|e| message(format!("{test_name}: {e}")))?;
        baselines.push((baseline, scores, seconds));
        fitted.push(Some(model));
    }

    // The top-level model, timed from the training samples to a fitted model (including the
    // choice of `auto`).
    let start = Instant::now();
    let (chosen, selection) = match settings.choice {
        EvalChoice::Auto => {
            let selection = select_baseline(train, HOLDOUT, &config)
                .map_err(|e| message(format!("{train_name}: cannot choose a model: {e}")))?;
            (Some(selection.chosen), Some(selection))
        }
        EvalChoice::Baseline(baseline) => (Some(baseline), None),
        EvalChoice::Copa { .. } => (None, None),
    };
    let mut copa_init = None;
    let (model, train_seconds): (Box<dyn RatePredictor + Send + Sync>, f64) = match chosen {
        Some(baseline) => {
            let i = Baseline::ALL
                .iter()
                .position(|&b| b == baseline)
                .expect("every baseline is in Baseline::ALL");
            let model = fitted[i].take().expect("each baseline is chosen once");
            (model, start.elapsed().as_secs_f64() + baselines[i].2)
        }
        None => {
            let EvalChoice::Copa { init, scale } = settings.choice else {
                unreachable!("only CoPA-Map is not a baseline")
            };
            let copa = CopaConfig {
                inducing: settings.inducing,
                iterations: settings.iterations,
                day_period: settings.period,
                init,
                parallelism: settings.parallelism,
                target: scale,
                ..CopaConfig::default()
            };
            let map = CopaMap::fit_with_progress(train, &copa, progress)
                .map_err(|e| message(format!("{train_name}: CoPA-Map: {e}")))?;
            copa_init = Some(map.period_init.clone());
            (Box::new(map), start.elapsed().as_secs_f64())
        }
    };
    let scores = score(model.as_ref(), test).map_err(|e| message(format!("{test_name}: {e}")))?;
    Ok(Evaluation {
        baselines,
        selection,
        model,
        scores,
        train_seconds,
        copa_init,
    })
}

/// What [`evaluate_files`] tests on.
#[derive(Clone, Copy, Debug)]
pub enum EvalTest<'a> {
    /// The rates of this file.
    File(&'a Path),
    /// The training file's samples from this time on (the earlier ones train).
    SplitAt(f64),
}

/// A set of rates in a report: its file and what it holds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RatesSummary {
    /// The file (with the part used, for a split).
    pub file: String,
    /// Samples.
    pub samples: usize,
    /// Distinct cells.
    pub cells: usize,
    /// The first time.
    pub t_first: f64,
    /// The last time.
    pub t_last: f64,
    /// The mean rate (people per hour).
    pub mean_rate: f64,
}

impl RatesSummary {
    /// The summary of `samples` read from `file`.
    pub fn of(file: &str, samples: &RateSamples) -> RatesSummary {
        let (t_first, t_last) = samples
            .t()
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| {
                (lo.min(t), hi.max(t))
            });
        RatesSummary {
            file: file.to_string(),
            samples: samples.len(),
            cells: samples.cell_count(),
            t_first,
            t_last,
            mean_rate: samples.mean_rate(),
        }
    }

    /// `: 61131 samples (t < 96), 652 cells, t 0 .. 95, mean rate 42.10 per hour`.
    fn line(&self, part: Option<String>) -> String {
        let part = part.map(|p| format!(" ({p})")).unwrap_or_default();
        format!(
            ": {} samples{part}, {} cells, t {} .. {}, mean rate {:.2} per hour",
            self.samples, self.cells, self.t_first, self.t_last, self.mean_rate
        )
    }
}

/// The evaluation of [Stüde 2024] §4.3.2 on files, as `chronomap activity eval` reports it:
/// every baseline and the chosen model scored by eqs. 4.20–4.21.
#[derive(Clone, Debug)]
pub struct ActivityEvalReport {
    /// The training rates.
    pub train: RatesSummary,
    /// The test rates.
    pub test: RatesSummary,
    /// The split time, if the test is the training file's later part.
    pub split_at: Option<f64>,
    /// Every baseline with its scores and training seconds.
    pub baselines: Vec<(Baseline, Scores, f64)>,
    /// How `auto` chose (`None` for another choice).
    pub selection: Option<BaselineSelection>,
    /// The model at the top.
    pub model: String,
    /// Its scores.
    pub scores: Scores,
    /// Seconds from the training samples to it fitted.
    pub train_seconds: f64,
    /// With CoPA-Map at the top: what Algorithm 4.1 found (`None`: started from the day).
    pub copa_init: Option<Option<PeriodInit>>,
    /// How the model's 90 % predictive intervals of whole bins ([`RatePredictor::interval`])
    /// held the test rates (`None`: the model has none).
    pub interval: Option<Coverage>,
    /// How its 90 % intervals of one observation like the training samples
    /// ([`RatePredictor::observation_interval`]) held them.
    pub observation_interval: Option<Coverage>,
    /// Both kinds of interval at every level of [`CURVE_LEVELS`]: how well the model's
    /// predictive distribution is calibrated across levels (empty without intervals).
    pub interval_curve: Vec<IntervalLevel>,
}

/// How a model's intervals of one nominal coverage held the test rates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntervalLevel {
    /// The nominal coverage.
    pub nominal: f64,
    /// Intervals of whole bins ([`RatePredictor::interval`]).
    pub whole: Option<Coverage>,
    /// Intervals of one observation ([`RatePredictor::observation_interval`]).
    pub observation: Option<Coverage>,
}

/// Nominal coverage of the predictive intervals `activity eval` scores.
pub const INTERVAL_COVERAGE: f64 = 0.9;

/// Both kinds of `model`'s intervals on `test` at `level` (each computed for all samples at
/// once: [`RatePredictor::interval_samples`]), scored against its rates.
fn interval_level(model: &dyn RatePredictor, test: &RateSamples, level: f64) -> IntervalLevel {
    let score = |intervals: Option<Vec<(f64, f64)>>| Some(Coverage::of(&intervals?, test.y()));
    IntervalLevel {
        nominal: level,
        whole: score(model.interval_samples(test, level)),
        observation: score(model.observation_interval_samples(test, level)),
    }
}

impl ActivityEvalReport {
    /// The calibration of the model's predictive intervals, as `chronomap activity eval --plot`
    /// draws it: above, the share of test rates inside the intervals against their nominal
    /// coverage (the diagonal is perfect calibration); below, their mean width. `None` when the
    /// model has no intervals.
    #[cfg(feature = "plot")]
    pub fn interval_panels(&self) -> Option<Vec<chronomap_plot::Panel>> {
        if self.interval_curve.is_empty() {
            return None;
        }
        let curve = |whole: bool| -> Vec<(f64, Coverage)> {
            self.interval_curve
                .iter()
                .filter_map(|l| {
                    let kind = if whole { l.whole } else { l.observation };
                    kind.map(|c| (l.nominal, c))
                })
                .collect()
        };
        Some(crate::calibration_plots::coverage_panels(
            format!(
                "Predictive intervals on {} test rates: share inside against nominal coverage",
                self.test.samples
            ),
            "people per hour",
            &[
                (
                    format!("{} intervals of whole hours", self.model),
                    curve(true),
                ),
                (
                    format!("{} intervals of one observation", self.model),
                    curve(false),
                ),
            ],
        ))
    }
}

/// A coverage as `activity eval --json` prints it.
fn coverage_json(c: Coverage) -> Value {
    json!({
        "nominal": INTERVAL_COVERAGE,
        "coverage": c.coverage,
        "mean_width": c.mean_width,
        "below": c.below,
        "above": c.above,
    })
}

impl ActivityEvalReport {
    /// The report as `chronomap activity eval --json` prints it.
    pub fn json(&self) -> Value {
        let scores = |s: &Scores| json!({ "nrmse": s.nrmse, "chi2": s.chi2 });
        let copa_init = match &self.copa_init {
            None => Value::Null,
            Some(Some(init)) => json!({
                "mode": "spectral",
                "psi": init.psi,
                "periods": init.periods,
                "variances": init.variances,
                "fallback": init.none.as_ref().map(|why| format!("{why:?}")),
            }),
            Some(None) => json!({"mode": "day"}),
        };
        let mut table = serde_json::Map::new();
        for (baseline, s, seconds) in &self.baselines {
            let mut entry = scores(s);
            entry["train_seconds"] = json!(seconds);
            table.insert(baseline.name().into(), entry);
        }
        let selected_by = match &self.selection {
            Some(sel) => json!({
                "holdout_from_t": sel.cut,
                "scores": sel.scores.iter().map(|(b, s)| (b.name().to_string(), scores(s))).collect::<serde_json::Map<_, _>>(),
            }),
            None => Value::String("--model".into()),
        };
        json!({
            "model": self.model,
            "selected_by": selected_by,
            "nrmse": self.scores.nrmse,
            "chi2": self.scores.chi2,
            "train_seconds": self.train_seconds,
            "copa_init": copa_init,
            "interval": self.interval.map(coverage_json),
            "observation_interval": self.observation_interval.map(coverage_json),
            "interval_curve": self.interval_curve.iter().map(|l| json!({
                "nominal": l.nominal,
                "coverage": l.whole.map(|c| c.coverage),
                "mean_width": l.whole.map(|c| c.mean_width),
                "observation_coverage": l.observation.map(|c| c.coverage),
                "observation_mean_width": l.observation.map(|c| c.mean_width),
            })).collect::<Vec<_>>(),
            "train": self.train,
            "test": self.test,
            "split_at": self.split_at,
            "baselines": table,
        })
    }

    /// The report as `chronomap activity eval` prints it.
    pub fn text(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "training: {}{}",
            self.train.file,
            self.train.line(self.split_at.map(|at| format!("t < {at}")))
        );
        let _ = writeln!(out, "test: {}{}", self.test.file, self.test.line(None));
        out.push('\n');
        let mut table = Table::new(["model", "NRMSE", "chi2", "train s"]);
        for (baseline, s, seconds) in &self.baselines {
            table.row([
                baseline.name().to_string(),
                format!("{:.4}", s.nrmse),
                format!("{:.1}", s.chi2),
                format!("{seconds:.3}"),
            ]);
        }
        out.push_str(&table.render());
        let why = match &self.selection {
            Some(sel) => {
                let scores: Vec<String> = sel
                    .scores
                    .iter()
                    .map(|(b, s)| format!("{} {:.4}", b.name(), s.nrmse))
                    .collect();
                format!(
                    "chosen by --model auto: least NRMSE on the training samples with t >= {} \
                     held out ({})",
                    sel.cut,
                    scores.join(", ")
                )
            }
            None => "chosen by --model".to_string(),
        };
        let _ = writeln!(
            out,
            "\nmodel: {} ({why}); NRMSE {:.4}, chi2 {:.1}, trained in {:.3} s",
            self.model, self.scores.nrmse, self.scores.chi2, self.train_seconds
        );
        for (what, interval) in [
            ("whole hours", &self.interval),
            ("one observation", &self.observation_interval),
        ] {
            if let Some(c) = interval {
                let _ = writeln!(
                    out,
                    "90 % predictive intervals of {what}: {:.1} % of the test rates inside ({} \
                     below, {} above), mean width {:.1} per hour",
                    100.0 * c.coverage,
                    c.below,
                    c.above,
                    c.mean_width
                );
            }
        }
        let _ = writeln!(
            out,
            "NRMSE: eq. (4.20), root mean square error over the mean test rate; chi2: eq. (4.21), \
             chi-square distance (lower is better for both). gp_hom is trained with --inducing and \
             --iterations as CoPA-Map (`--model copa`); `--model auto` chooses among the others."
        );
        out
    }
}

/// Reads the training rates of `train` and the test of `test` and runs [`evaluate`].
///
/// # Errors
/// A file that cannot be read; a split that leaves nothing to train or test on; test rates all
/// 0 (the NRMSE is undefined); as [`evaluate`].
pub fn evaluate_files(
    train_path: &Path,
    test: EvalTest,
    settings: &EvalSettings,
    progress: &dyn Progress,
) -> Result<ActivityEvalReport, ActivityJobError> {
    let train_name = train_path.display().to_string();
    let all = read_rate_samples(train_path).map_err(|source| ActivityJobError::Rates {
        what: "training rates",
        source: Box::new(source),
    })?;
    let message = ActivityJobError::Message;
    let (train, test, test_name, split_at) = match test {
        EvalTest::File(path) => {
            let test = read_rate_samples(path).map_err(|source| ActivityJobError::Rates {
                what: "test rates",
                source: Box::new(source),
            })?;
            (all, test, path.display().to_string(), None)
        }
        EvalTest::SplitAt(at) => {
            let (train, test) = all.split_at(at);
            if train.is_empty() {
                return Err(message(format!(
                    "{train_name}: no sample has t < {at} (--split-at): nothing to train on"
                )));
            }
            if test.is_empty() {
                return Err(message(format!(
                    "{train_name}: no sample has t >= {at} (--split-at): nothing to test on"
                )));
            }
            (train, test, format!("{train_name} (t >= {at})"), Some(at))
        }
    };
    if test.mean_rate() == 0.0 {
        return Err(message(format!(
            "{test_name}: every test rate is 0, so the NRMSE (eq. 4.20) is undefined"
        )));
    }
    let evaluation = evaluate(&train, &test, settings, [&train_name, &test_name], progress)?;
    let mut interval_curve: Vec<IntervalLevel> = CURVE_LEVELS
        .iter()
        .map(|&level| interval_level(evaluation.model.as_ref(), &test, level))
        .collect();
    // CURVE_LEVELS holds INTERVAL_COVERAGE: the headline is its point of the curve.
    let headline = interval_curve
        .iter()
        .find(|l| l.nominal == INTERVAL_COVERAGE)
        .copied()
        .unwrap_or(IntervalLevel {
            nominal: INTERVAL_COVERAGE,
            whole: None,
            observation: None,
        });
    if headline.whole.is_none() && headline.observation.is_none() {
        interval_curve.clear();
    }
    Ok(ActivityEvalReport {
        train: RatesSummary::of(&train_name, &train),
        test: RatesSummary::of(&test_name, &test),
        split_at,
        baselines: evaluation.baselines,
        selection: evaluation.selection,
        model: evaluation.model.name().to_string(),
        interval: headline.whole,
        observation_interval: headline.observation,
        interval_curve,
        scores: evaluation.scores,
        train_seconds: evaluation.train_seconds,
        copa_init: evaluation.copa_init,
    })
}

/// The most time bins [`extract_job`] counts from `t0` over the detections (2^24).
pub const MAX_BINS: usize = 1 << 24;

/// Reads pedestrian detections from track files.
///
/// # Errors
/// A file that cannot be read; no detection at all.
pub fn read_detections(tracks: &[PathBuf]) -> Result<Vec<Event>, ActivityJobError> {
    let detections = read_track_files(tracks).map_err(|source| ActivityJobError::Rates {
        what: "tracks",
        source: Box::new(source),
    })?;
    if detections.is_empty() {
        return Err(ActivityJobError::Message(
            "the track files have no detection".into(),
        ));
    }
    Ok(detections)
}

/// Where [`extract_job`] counts.
#[derive(Clone, Copy, Debug)]
pub enum ExtractWhere<'a> {
    /// The ground truth of §4.3.2 in the cells of this rate grid.
    TruthInCellsOf(&'a Path),
    /// What the patrol robots of a path file see on a ROS map ([`robots_on_map`]); with
    /// `truth`, the ground truth in the cells they observed.
    Robots {
        /// The map (Nav2 YAML).
        map: &'a Path,
        /// The robot-path file.
        paths: &'a Path,
        /// The robots' speed (m/s).
        speed: f64,
        /// Cells of at least this occupancy (percent) block sight.
        min_occupancy: i8,
        /// The robots to simulate (all if empty).
        robots: &'a [String],
        /// Whether to count the ground truth in the observed cells.
        truth: bool,
    },
}

/// How [`extract_job`] bins and where it counts.
#[derive(Clone, Debug)]
pub struct ExtractRequest<'a> {
    /// Field of view radius (m).
    pub fov: f64,
    /// Cell size (m).
    pub cell: f64,
    /// Time bin (s).
    pub bin: f64,
    /// Robot step (s).
    pub step: f64,
    /// Start of bin 0 (default: the first detection's bin).
    pub t0: Option<f64>,
    /// The bins to count (default: every bin with a detection).
    pub bins: &'a [i64],
    /// Where.
    pub source: ExtractWhere<'a>,
}

/// A robot of an extraction, as the report shows it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RobotSummary {
    /// Its name in the path file.
    pub name: String,
    /// The length of its loop (m).
    pub length_m: f64,
    /// The time of one loop (s).
    pub loop_s: f64,
    /// Its waypoints.
    pub waypoints: usize,
    /// Its speed (m/s).
    #[serde(skip)]
    pub speed: f64,
}

/// Training data or ground truth extracted from detections (eqs. 4.5–4.6, §4.3.2), as
/// `chronomap activity extract` reports it.
#[derive(Clone, Debug, Serialize)]
pub struct ExtractReport {
    /// `training data` or `ground truth`.
    pub kind: &'static str,
    /// Where the face writes the samples.
    pub output: String,
    /// Samples.
    pub samples: usize,
    /// Cells.
    pub cells: usize,
    /// The bins counted.
    pub bins: Vec<i64>,
    /// Start of bin 0.
    pub t0: f64,
    /// Detections counted.
    pub total_count: u64,
    /// Seconds of cell observation.
    pub total_duration_s: f64,
    /// The mean rate of the samples (per hour).
    pub mean_rate_per_hour: f64,
    /// Detections per hour of observation.
    pub pooled_rate_per_hour: f64,
    /// The simulated robots.
    pub robots: Vec<RobotSummary>,
    /// Seconds the extraction took (the job times itself on purpose).
    pub seconds: f64,
    /// The time bin (s).
    #[serde(skip)]
    pub bin: f64,
    /// The samples.
    #[serde(skip)]
    pub extraction: Extraction,
}

impl ExtractReport {
    /// The report as `chronomap activity extract` prints it.
    pub fn text(&self) -> String {
        let mut out = String::new();
        for r in &self.robots {
            let _ = writeln!(
                out,
                "robot {}: {} waypoints, loop {:.1} m, {:.0} s at {} m/s",
                r.name, r.waypoints, r.length_m, r.loop_s, r.speed
            );
        }
        let _ = writeln!(
            out,
            "{}: {} samples over {} cells and {} bins (t0 = {}, {} s each), written to {}",
            self.kind,
            self.samples,
            self.cells,
            self.bins.len(),
            self.t0,
            self.bin,
            self.output
        );
        let _ = writeln!(
            out,
            "{} detections in {:.1} h of cell observation: mean rate {:.2} per hour (pooled {:.2}); computed in {:.2} s",
            self.total_count,
            self.total_duration_s / 3600.0,
            self.mean_rate_per_hour,
            self.pooled_rate_per_hour,
            self.seconds
        );
        out
    }
}

/// The start of bin 0 for `bin`-second bins over `detections` (that of the first detection
/// unless given) and the bins to count (every bin with a detection unless given); the set-up
/// [`extract_job`] and the activity benchmark share.
///
/// # Errors
/// [`ActivityJobError::TooManyBins`] if more than [`MAX_BINS`] bins lie from `t0` over the
/// detections (or `t0` is not finite).
pub fn bins_over(
    detections: &[Event],
    bin: f64,
    t0: Option<f64>,
    bins: &[i64],
) -> Result<(f64, Vec<i64>), ActivityJobError> {
    let first = detections.first().map_or(0.0, |d| d.t);
    let t0 = t0.unwrap_or((first / bin).floor() * bin);
    // Bin indices are counted from t0 over the detections: refuse a bin (or t0) that gives
    // more than MAX_BINS of them instead of letting `as i64` saturate them into one.
    let last = detections.iter().map(|d| d.t).fold(first, f64::max);
    let span = ((last.max(t0) - first.min(t0)) / bin).floor();
    if !t0.is_finite() || count_of(span, MAX_BINS).is_none() {
        return Err(ActivityJobError::TooManyBins { bin, span, t0 });
    }
    // By default every bin with a detection: a bin without any (an hour missing from the
    // data) would read as "nobody there".
    let bins = if bins.is_empty() {
        detection_bins(detections, t0, bin)
    } else {
        bins.to_vec()
    };
    Ok((t0, bins))
}

/// The extraction of [Stüde 2024] §4.2.2 (or the ground truth of §4.3.2) of `detections` as
/// `request` asks, timed (on purpose) from the set-up to the samples; `output` only names
/// where the face writes them. The robots' simulation reports to `progress`.
///
/// # Errors
/// Too many bins; a map, path or cell file that cannot be read; no cell observed.
pub fn extract_job(
    detections: &[Event],
    request: &ExtractRequest,
    output: &Path,
    progress: &dyn Progress,
) -> Result<ExtractReport, ActivityJobError> {
    let (t0, bins) = bins_over(detections, request.bin, request.t0, request.bins)?;
    let config = ExtractConfig {
        fov_radius: request.fov,
        cell_size: request.cell,
        bin_seconds: request.bin,
        step_seconds: request.step,
        t0,
    };
    let start = Instant::now();
    let (extraction, robots, truth) = match request.source {
        ExtractWhere::TruthInCellsOf(cells_file) => {
            let cells: Vec<[f64; 2]> = read_rate_samples(cells_file)
                .map_err(|source| ActivityJobError::Rates {
                    what: "cells of --cells-from",
                    source: Box::new(source),
                })?
                .x()
                .to_vec();
            let source = SampleSource::TruthIn(&cells);
            let truth = extract_samples(detections, source, &bins, &config, progress)?;
            (truth, Vec::new(), true)
        }
        ExtractWhere::Robots {
            map,
            paths,
            speed,
            min_occupancy,
            robots,
            truth,
        } => {
            let (grid, robots) = robots_on_map(map, paths, speed, min_occupancy, robots)?;
            let paths: Vec<RobotPath> = robots.iter().map(|(_, p)| p.clone()).collect();
            let source = SampleSource::Robots {
                grid: &grid,
                paths: &paths,
                truth,
            };
            let samples = extract_samples(detections, source, &bins, &config, progress)?;
            (samples, robots, truth)
        }
    };
    let seconds = start.elapsed().as_secs_f64();
    if extraction.is_empty() {
        return Err(ActivityJobError::Message(format!(
            "no cell was observed in bins {bins:?}: nothing to write"
        )));
    }
    let count = extraction.total_count();
    let duration = extraction.total_duration();
    Ok(ExtractReport {
        kind: if truth {
            "ground truth"
        } else {
            "training data"
        },
        output: output.display().to_string(),
        samples: extraction.len(),
        cells: extraction.cells().len(),
        bins,
        t0,
        total_count: count,
        total_duration_s: duration,
        mean_rate_per_hour: extraction.to_rate_samples().mean_rate(),
        pooled_rate_per_hour: count as f64 * 3600.0 / duration,
        robots: robots
            .iter()
            .map(|(name, p)| RobotSummary {
                name: name.clone(),
                length_m: p.length(),
                loop_s: p.period(),
                waypoints: p.waypoints().len(),
                speed: p.speed(),
            })
            .collect(),
        seconds,
        bin: request.bin,
        extraction,
    })
}

/// The ground truth of §4.3.2 in the cells of a grid, as `chronomap activity truth` reports it.
#[derive(Clone, Debug, Serialize)]
pub struct TruthReport {
    /// Where the face writes the samples.
    pub output: String,
    /// Samples (cells × bins).
    pub samples: usize,
    /// Cells.
    pub cells: usize,
    /// Bins.
    pub bins: Vec<i64>,
    /// Track points read.
    pub detections: usize,
    /// The mean rate (people per hour).
    pub mean_rate_per_hour: f64,
    /// The samples.
    #[serde(skip)]
    pub truth: RateSamples,
}

impl TruthReport {
    /// The report as `chronomap activity truth` prints it.
    pub fn text(&self) -> String {
        format!(
            "{}: {} samples ({} cells × {} bins) from {} detections; mean {:.3} people per hour\n",
            self.output,
            self.samples,
            self.cells,
            self.bins.len(),
            self.detections,
            self.mean_rate_per_hour
        )
    }
}

/// The ground truth of [Stüde 2024] §4.3.2 — distinct people per cell and bin, counted over
/// whole bins — from the track files `tracks` in the cells of the rate grid `cells_file`
/// (aligned to `grid.cell`); `output` only names where the face writes it.
///
/// # Errors
/// A file that cannot be read; cells off the grid; as [`person_counts`].
pub fn truth_job(
    cells_file: &Path,
    tracks: &[PathBuf],
    bins: &[i64],
    grid: &TruthGrid,
    output: &Path,
) -> Result<TruthReport, ActivityJobError> {
    let samples = read_rate_samples(cells_file).map_err(|source| ActivityJobError::Rates {
        what: "grid of --cells",
        source: Box::new(source),
    })?;
    let cells = distinct_cells(&samples);
    check_aligned(&cells, grid.cell).map_err(|e| {
        ActivityJobError::Message(format!("{}: {e} (--cell)", cells_file.display()))
    })?;
    let points = read_track_point_files(tracks).map_err(|source| ActivityJobError::Rates {
        what: "tracks",
        source: Box::new(source),
    })?;
    let truth = person_counts(&points, &cells, bins, grid)?;
    Ok(TruthReport {
        output: output.display().to_string(),
        samples: truth.len(),
        cells: cells.len(),
        bins: bins.to_vec(),
        detections: points.len(),
        mean_rate_per_hour: truth.mean_rate(),
        truth,
    })
}

/// CoPA-Map fitted once ([Stüde 2024] §4.2), as `chronomap activity fit` reports it.
#[derive(Clone, Debug, Serialize)]
pub struct CopaFitReport {
    /// Where the face writes the model.
    pub model: String,
    /// The training file.
    pub train: String,
    /// Training samples.
    pub samples: usize,
    /// Their cells.
    pub cells: usize,
    /// Inducing points.
    pub inducing: usize,
    /// Iterations.
    pub iterations: usize,
    /// The learnt periods (units of t).
    pub periods: Vec<f64>,
    /// The last minibatch ELBO.
    pub final_elbo: f64,
    /// Seconds of the fit (the job times itself on purpose).
    pub fit_seconds: f64,
    /// The fitted model.
    #[serde(skip)]
    pub fitted: CopaMap,
}

impl CopaFitReport {
    /// The report as `chronomap activity fit` prints it.
    pub fn text(&self) -> String {
        let periods: Vec<String> = self.periods.iter().map(|p| format!("{p:.3}")).collect();
        format!(
            "{}: CoPA-Map fitted in {:.1} s on {} samples, {} cells; periods {} (units of t); \
             final minibatch ELBO {:.1}\n",
            self.model,
            self.fit_seconds,
            self.samples,
            self.cells,
            periods.join(", "),
            self.final_elbo
        )
    }
}

/// Fits CoPA-Map to the rates of `train_path` with `config`, timed; iterations report to
/// `progress`; `output` only names where the face writes the model.
///
/// # Errors
/// The file cannot be read; the fit fails (naming the file).
pub fn fit_copa(
    train_path: &Path,
    config: &CopaConfig,
    output: &Path,
    progress: &dyn Progress,
) -> Result<CopaFitReport, ActivityJobError> {
    let name = train_path.display().to_string();
    let train = read_rate_samples(train_path)?;
    let start = Instant::now();
    let fitted = CopaMap::fit_with_progress(&train, config, progress)
        .map_err(|e| ActivityJobError::Message(format!("{name}: CoPA-Map: {e}")))?;
    Ok(CopaFitReport {
        model: output.display().to_string(),
        train: name,
        samples: train.len(),
        cells: train.cell_count(),
        inducing: config.inducing,
        iterations: config.iterations,
        periods: fitted.periods(),
        final_elbo: fitted.trace.last().copied().unwrap_or(f64::NAN),
        fit_seconds: start.elapsed().as_secs_f64(),
        fitted,
    })
}

/// Log-AM fitted once, as `chronomap activity fit --model log-additive` reports it.
#[derive(Clone, Debug)]
pub struct LogAmFitReport {
    /// Where the face writes the model.
    pub model: String,
    /// The training file.
    pub train: String,
    /// Training samples.
    pub samples: usize,
    /// Their cells.
    pub cells: usize,
    /// Seconds of the fit (the job times itself on purpose).
    pub fit_seconds: f64,
    /// The fitted model.
    pub fitted: LogAdditive,
}

impl LogAmFitReport {
    /// The report as `--json` prints it; ∞ (no interaction, every day alike) as the string
    /// `"inf"`: JSON has no infinity.
    pub fn json(&self) -> Value {
        let value = |k: f64| {
            if k.is_finite() {
                json!(k)
            } else {
                json!("inf")
            }
        };
        let m = &self.fitted;
        json!({
            "model": self.model,
            "kind": LOG_ADDITIVE_KIND,
            "train": self.train,
            "samples": self.samples,
            "cells": self.cells,
            "shrinkage": value(m.shrinkage()),
            "memory_days": value(m.memory()),
            "holdout_rmse_log1p": m.holdout_scores().iter().map(|s| json!({
                "memory_days": value(s.memory),
                "shrinkage": value(s.shrinkage),
                "rmse": s.rmse,
            })).collect::<Vec<_>>(),
            "sigma": m.sigma(),
            "process_sigma": m.process_sigma(),
            "profile": m.profile(),
            "fit_seconds": self.fit_seconds,
        })
    }

    /// The report as `chronomap activity fit --model log-additive` prints it.
    pub fn text(&self) -> String {
        format!(
            "{}: Log-AM fitted in {:.3} s on {} samples, {} cells; memory τ = {} days, \
             shrinkage κ = {} (hold-out); residual σ {:.3} in ln(1 + rate), of whole hours {}\n",
            self.model,
            self.fit_seconds,
            self.samples,
            self.cells,
            self.fitted.memory(),
            self.fitted.shrinkage(),
            self.fitted.sigma(),
            self.fitted
                .process_sigma()
                .map_or_else(|| "unknown".to_string(), |s| format!("{s:.3}"))
        )
    }
}

/// Fits Log-AM to the rates of `train_path` with the day `period`, timed; `output` only names
/// where the face writes the model.
///
/// # Errors
/// The file cannot be read; the fit fails (naming the file).
pub fn fit_log_additive(
    train_path: &Path,
    period: f64,
    output: &Path,
) -> Result<LogAmFitReport, ActivityJobError> {
    let name = train_path.display().to_string();
    let train = read_rate_samples(train_path)?;
    let config = LogAdditiveConfig {
        period,
        ..LogAdditiveConfig::default()
    };
    let start = Instant::now();
    let fitted = LogAdditive::fit(&train, &config)
        .map_err(|e| ActivityJobError::Message(format!("{name}: Log-AM: {e}")))?;
    Ok(LogAmFitReport {
        model: output.display().to_string(),
        train: name,
        samples: train.len(),
        cells: train.cell_count(),
        fit_seconds: start.elapsed().as_secs_f64(),
        fitted,
    })
}

/// A prediction of [`RatePredictReport`] as `--json` shows it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PredictionRow {
    /// Cell centre `x₁`.
    pub x1: f64,
    /// Cell centre `x₂`.
    pub x2: f64,
    /// Time.
    pub t: f64,
    /// Predicted rate.
    pub mean: f64,
    /// Its standard deviation.
    pub std: f64,
}

/// A model's predicted rate over a grid at several times ([`predict_maps`]), as
/// `chronomap activity predict` reports it.
#[derive(Clone, Debug, Serialize)]
pub struct RatePredictReport {
    /// The model's file.
    pub model: String,
    /// The times.
    pub times: Vec<f64>,
    /// The grid's region (`x1 min, x2 min, x1 max, x2 max`).
    pub region: [f64; 4],
    /// The cell size (m).
    pub cell_m: f64,
    /// Cells along `x₁`.
    pub cols: usize,
    /// Cells along `x₂`.
    pub rows: usize,
    /// Where the face writes the predictions, if anywhere.
    pub output: Option<String>,
    /// Where the face draws them, if anywhere.
    pub plot: Option<String>,
    /// Every cell off the walls at every time.
    pub predictions: Vec<PredictionRow>,
    /// The maps.
    #[serde(skip)]
    pub maps: RateMaps,
}

impl RatePredictReport {
    /// The report as `chronomap activity predict` prints it: what was written and drawn, or
    /// the predictions as text when neither.
    pub fn text(&self) -> String {
        let mut out = String::new();
        if let Some(path) = &self.output {
            let _ = writeln!(out, "{path}: {} predictions", self.maps.rows.len());
        }
        if let Some(path) = &self.plot {
            let times: Vec<String> = self.times.iter().map(|t| t.to_string()).collect();
            let _ = writeln!(
                out,
                "{path}: mean and std of the rate at t = {} ({} × {} cells of {} m)",
                times.join(", "),
                self.cols,
                self.rows,
                self.cell_m
            );
        }
        if self.output.is_none() && self.plot.is_none() {
            out = chronomap_io::rate_predictions::encode_rate_predictions(&self.maps.rows);
        }
        out
    }
}

/// The rate `model` (read from `model_name`) predicts over `grid` at `times`, walls of the
/// ROS map `map` kept out; `output` and `plot` only name where the face writes and draws.
///
/// # Errors
/// The map cannot be read; the model cannot predict (naming its file).
pub fn predict_report(
    model: &AnyActivityModel,
    model_name: &str,
    grid: &RegionGrid,
    times: &[f64],
    map: Option<&Path>,
    [output, plot]: [Option<&Path>; 2],
) -> Result<RatePredictReport, ActivityJobError> {
    let map = map.map(|p| load_map(p, LoadSemantics::Nav2)).transpose()?;
    let maps = predict_maps(model, grid, times, map.as_ref(), Parallelism::Rayon(0))
        .map_err(|e| ActivityJobError::Message(format!("{model_name}: {e}")))?;
    Ok(RatePredictReport {
        model: model_name.to_string(),
        times: times.to_vec(),
        region: [grid.min[0], grid.min[1], grid.max[0], grid.max[1]],
        cell_m: grid.cell,
        cols: grid.cols,
        rows: grid.rows,
        output: output.map(|p| p.display().to_string()),
        plot: plot.map(|p| p.display().to_string()),
        predictions: maps
            .rows
            .iter()
            .map(|r| PredictionRow {
                x1: r.x[0],
                x2: r.x[1],
                t: r.t,
                mean: r.mean,
                std: r.std,
            })
            .collect(),
        maps,
    })
}

/// The bundled ATC tracks of 2012-10-24 ([Stüde 2024] §4.3.1), one file per hour, relative to
/// the repository root.
pub const ATC_TRACK_DIR: &str = "data/atc_20121024_1hz";

/// The hour of the ATC day a quick run extracts from.
pub const ATC_QUICK_TRACKS: &str = "atc-1024-10_train.csv.xz";

/// Map cells of at least this occupancy (percent) block sight (`activity extract`'s default).
pub const ATC_MIN_OCCUPANCY: i8 = 50;

/// The track files of the ATC day: `given` if any, else the quick hour of [`ATC_TRACK_DIR`]
/// with `quick`, else every `atc-1024-*_train.csv.xz` there, sorted by name.
///
/// # Errors
/// The folder cannot be listed or holds no such file.
pub fn atc_tracks(given: &[PathBuf], quick: bool) -> Result<Vec<PathBuf>, ActivityJobError> {
    let dir = Path::new(ATC_TRACK_DIR);
    if !given.is_empty() {
        return Ok(given.to_vec());
    }
    if quick {
        return Ok(vec![dir.join(ATC_QUICK_TRACKS)]);
    }
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|source| ActivityJobError::List {
            dir: dir.display().to_string(),
            source,
        })?
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("atc-1024-") && n.ends_with("_train.csv.xz"))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(ActivityJobError::Message(format!(
            "no atc-1024-*_train.csv.xz in {}",
            dir.display()
        )));
    }
    Ok(files)
}

/// What the extraction of [Stüde 2024] §4.2.2 runs on with `activity extract`'s defaults
/// (3.5 m field of view, 0.5 m cells, hour bins from the first detection's hour, 1 s steps,
/// every bin with a detection) and every robot of a path file at the default speed.
pub struct ExtractionSetup {
    /// The detections.
    pub detections: Vec<Event>,
    /// Obstacles that block sight.
    pub grid: ObstacleGrid,
    /// The robots.
    pub robots: Vec<(String, RobotPath)>,
    /// The bins counted.
    pub bins: Vec<i64>,
    /// The extraction's settings.
    pub config: ExtractConfig,
}

/// Reads the tracks, the map and the robot paths for an extraction with the defaults
/// ([`ExtractionSetup`]).
///
/// # Errors
/// A file that cannot be read; no detection; a robot off the map.
pub fn extraction_setup(
    tracks: &[PathBuf],
    map: &Path,
    paths: &Path,
) -> Result<ExtractionSetup, ActivityJobError> {
    let detections = read_detections(tracks)?;
    let (grid, robots) =
        robots_on_map(map, paths, RobotPath::DEFAULT_SPEED, ATC_MIN_OCCUPANCY, &[])?;
    let defaults = ExtractConfig::default();
    let (t0, bins) = bins_over(&detections, defaults.bin_seconds, None, &[])?;
    Ok(ExtractionSetup {
        detections,
        grid,
        robots,
        bins,
        config: ExtractConfig { t0, ..defaults },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_activity::RateSamples;

    fn log_additive() -> LogAdditive {
        let mut samples = RateSamples::default();
        for t in 0..48 {
            samples.push([0.25, 0.25], f64::from(t), 10.0).unwrap();
            samples.push([0.75, 0.25], f64::from(t), 1.0).unwrap();
        }
        let config = LogAdditiveConfig {
            period: 12.0,
            ..LogAdditiveConfig::default()
        };
        LogAdditive::fit(&samples, &config).unwrap()
    }

    #[test]
    fn opens_log_am_by_its_header_and_refuses_other_kinds_as_copa_maps() {
        let dir = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-app-activity-{}", std::process::id())),
        );
        let model = log_additive();
        // The name says nothing: the header does.
        let path = dir.join("model.bin");
        chronomap_io::write_model_file(&path, LOG_ADDITIVE_KIND, &model).unwrap();
        let opened = open_activity_model(&path).unwrap();
        assert!(matches!(&opened, AnyActivityModel::LogAdditive(m) if *m == model));
        assert_eq!(opened.domain(), [0.25, 0.25, 0.75, 0.25]);

        let other = dir.join("other.cmm");
        chronomap_io::write_model_file(&other, "fremen", &1u8).unwrap();
        let error = open_activity_model(&other).unwrap_err().to_string();
        assert_eq!(
            error,
            format!(
                "{}: the payload of kind \"fremen\" does not decode as the requested model \
                 type: Hit the end of buffer, expected more data",
                other.display()
            )
        );
        // A file written before Log-AM had its process deviation (the same payload without
        // its last field, an `Option<f64>`: 9 bytes when set) opens as the same model
        // without it.
        assert!(model.process_sigma().is_some());
        let current = std::fs::read(&path).unwrap();
        let header_end = current.iter().position(|&b| b == b'\n').unwrap() + 1;
        let older = current[header_end..current.len() - 9].to_vec();
        let older_path = dir.join("older.cmlog");
        let older = chronomap_io::model_file::encode_payload(LOG_ADDITIVE_KIND, older).unwrap();
        std::fs::write(&older_path, older).unwrap();
        let AnyActivityModel::LogAdditive(opened) = open_activity_model(&older_path).unwrap()
        else {
            panic!("not Log-AM");
        };
        assert_eq!(opened.process_sigma(), None);
        assert_eq!(opened.sigma(), model.sigma());
        assert_eq!(opened.cells(), model.cells());
        assert_eq!(opened.interval([0.25, 0.25], 3.0, 0.9), None);

        let missing = dir.join("missing");
        let error = open_activity_model(&missing).unwrap_err();
        assert!(matches!(error, OpenActivityError::ModelFile(_)), "{error}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The per-cell mean (the `ML` baseline) over a 12-hour period, sequentially.
    fn ml_settings() -> EvalSettings {
        EvalSettings {
            period: 12.0,
            inducing: 4,
            iterations: 5,
            choice: EvalChoice::Baseline(Baseline::Ml),
            parallelism: Parallelism::Sequential,
        }
    }

    #[test]
    fn evaluate_scores_every_baseline_and_names_the_data_in_errors() {
        let mut train = RateSamples::default();
        let mut test = RateSamples::default();
        for t in 0..36 {
            let samples = if t < 24 { &mut train } else { &mut test };
            samples.push([0.25, 0.25], f64::from(t), 10.0).unwrap();
            samples.push([0.75, 0.25], f64::from(t), 1.0).unwrap();
        }
        let settings = ml_settings();
        let progress = chronomap_core::progress::NoProgress;
        let names = ["train.csv", "test.csv"];
        let eval = evaluate(&train, &test, &settings, names, &progress).unwrap();
        assert_eq!(eval.baselines.len(), Baseline::ALL.len());
        assert_eq!(eval.model.name(), Baseline::Ml.name());
        // Every cell keeps its rate: the per-cell mean predicts the later days exactly.
        assert!(eval.scores.nrmse < 1e-12, "{:?}", eval.scores);
        assert!(eval.selection.is_none() && eval.copa_init.is_none());

        let mut empty = RateSamples::default();
        empty.push([0.25, 0.25], 30.0, 0.0).unwrap();
        let error = evaluate(&train, &empty, &settings, names, &progress)
            .err()
            .unwrap();
        assert_eq!(
            error.to_string(),
            "test.csv: the mean ground-truth rate is 0: the NRMSE is undefined"
        );
    }

    #[test]
    fn rate_maps_keep_walls_out_of_the_rows() {
        let model = AnyActivityModel::LogAdditive(log_additive());
        // The two training cells, 0.5 m each: centres (0.25, 0.25) and (0.75, 0.25).
        let grid = RegionGrid::around_centres(model.domain(), 0.5).unwrap();
        assert_eq!((grid.cols, grid.rows), (2, 1));
        // A map of two 0.5 m pixels from the origin, the second a wall.
        let map = OccupancyMap::from_probabilities(2, 1, 0.5, [0.0, 0.0, 0.0], &[0.0, 1.0]);
        let times = [48.0, 49.0];
        let maps =
            predict_maps(&model, &grid, &times, Some(&map), Parallelism::Sequential).unwrap();
        assert_eq!(maps.blocked, [false, true]);
        assert_eq!(maps.panels.len(), 2);
        assert_eq!(maps.rows.len(), 2);
        for (row, t) in maps.rows.iter().zip(times) {
            assert_eq!((row.x, row.t), ([0.25, 0.25], t));
            assert!((row.mean - 10.0).abs() < 1e-6, "{row:?}");
        }
        // The wall's cell is still predicted for plots: the quiet cell's rate, 1 per hour.
        assert!((maps.panels[0].1[1] - 1.0).abs() < 1e-6);
        let open = predict_maps(&model, &grid, &times, None, Parallelism::Sequential).unwrap();
        assert_eq!(open.rows.len(), 4);
        // For plots: means over the busiest cell off the walls (10 per hour), the wall NaN.
        let images = maps.scaled_panels();
        assert_eq!(images.len(), 4);
        assert_eq!(images[0].0, "mean at t = 48 (max 10 per h)");
        assert!((images[0].1[0] - 1.0).abs() < 1e-6 && images[0].1[1].is_nan());
        assert!(images[1].0.starts_with("std at t = 48 (max "));
    }

    #[test]
    fn evaluate_files_splits_one_file_and_reports_text_and_json() {
        let dir = chronomap_testutil::fresh_dir(std::env::temp_dir().join(format!(
            "chronomap-app-activity-eval-{}",
            std::process::id()
        )));
        let mut all = RateSamples::default();
        for t in 0..36 {
            all.push([0.25, 0.25], f64::from(t), 10.0).unwrap();
            all.push([0.75, 0.25], f64::from(t), 1.0).unwrap();
        }
        let path = dir.join("rates.csv");
        chronomap_io::write_rate_samples(&path, &all).unwrap();
        let settings = ml_settings();
        let progress = chronomap_core::progress::NoProgress;
        let report = evaluate_files(&path, EvalTest::SplitAt(24.0), &settings, &progress).unwrap();
        let name = path.display();
        let text = report.text();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            format!(
                "training: {name}: 48 samples (t < 24), 2 cells, t 0 .. 23, mean rate 5.50 per hour"
            )
        );
        assert_eq!(
            lines[1],
            format!(
                "test: {name} (t >= 24): 24 samples, 2 cells, t 24 .. 35, mean rate 5.50 per hour"
            )
        );
        assert_eq!(lines[2], "");
        assert!(lines[3].starts_with("model") && lines[3].ends_with("train s"));
        assert_eq!(lines.len(), 5 + Baseline::ALL.len() + 2);
        assert!(
            lines[5 + Baseline::ALL.len()]
                .starts_with("model: ml (chosen by --model); NRMSE 0.0000, chi2 0.0,"),
            "{text}"
        );
        let json = report.json();
        assert_eq!(json["model"], "ml");
        assert_eq!(json["selected_by"], "--model");
        assert_eq!(json["split_at"], 24.0);
        assert_eq!(json["train"]["samples"], 48);
        assert_eq!(json["test"]["t_first"], 24.0);
        assert_eq!(json["copa_init"], Value::Null);
        assert_eq!(
            json["baselines"].as_object().unwrap().len(),
            Baseline::ALL.len()
        );
        let error = evaluate_files(&path, EvalTest::SplitAt(0.0), &settings, &progress)
            .err()
            .unwrap();
        assert_eq!(
            error.to_string(),
            format!("{name}: no sample has t < 0 (--split-at): nothing to train on")
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bins_start_at_the_first_detections_bin_and_are_bounded() {
        let at = |t: f64| Event { t, x: 0.0, y: 0.0 };
        let detections = [at(3600.5), at(3700.0), at(10_900.0)];
        // Hour bins from 01:00: the first and the third hour have detections.
        assert_eq!(
            bins_over(&detections, 3600.0, None, &[]).unwrap(),
            (3600.0, vec![0, 2])
        );
        assert_eq!(
            bins_over(&detections, 3600.0, Some(0.0), &[5]).unwrap(),
            (0.0, vec![5])
        );
        // 7,300 s in bins of a millisecond: 7.3 million bins, within 2^24; of a microsecond:
        // 7.3 billion, refused.
        assert!(bins_over(&detections, 1e-3, None, &[7]).is_ok());
        assert!(matches!(
            bins_over(&detections, 1e-6, None, &[]),
            Err(ActivityJobError::TooManyBins { .. })
        ));
    }

    /// Two hours of the bundled ATC tracks in the 652 cells of the bundled training grid:
    /// 1,304 samples, their text and JSON; a cell size the grid is not aligned to is refused
    /// naming the file and the flag.
    #[test]
    fn the_truth_of_two_atc_hours_is_a_sample_per_cell_and_hour() {
        let cells =
            chronomap_testutil::data_path("atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz");
        let tracks = [10, 11].map(|h| {
            chronomap_testutil::data_path(&format!("atc_20121024_1hz/atc-1024-{h}_train.csv.xz"))
        });
        let grid = TruthGrid {
            cell: 0.5,
            t0: 1_351_036_800.0,
            bin: 3600.0,
            t_offset: 120.0,
        };
        let out = Path::new("truth.csv");
        let report = truth_job(&cells, &tracks, &[1, 2], &grid, out).unwrap();
        assert_eq!((report.samples, report.cells), (1304, 652));
        assert_eq!(report.truth.t()[0], 121.0);
        assert_eq!(
            report.text(),
            format!(
                "truth.csv: 1304 samples (652 cells × 2 bins) from {} detections; mean {:.3} people per hour\n",
                report.detections,
                report.truth.mean_rate()
            )
        );
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["bins"], json!([1, 2]));
        assert_eq!(json["mean_rate_per_hour"], report.truth.mean_rate());
        assert!(json.get("truth").is_none());
        let off = TruthGrid { cell: 0.3, ..grid };
        let error = truth_job(&cells, &tracks, &[1], &off, out).err().unwrap();
        let message = error.to_string();
        assert!(
            message.starts_with(&format!("{}: cell centre", cells.display()))
                && message.ends_with("(--cell)"),
            "{message}"
        );
    }
}
