//! Maps of human activity ([Stüde 2024] chapter 4) as the faces use them: a model file opened
//! by its content ([`open_activity_model`]: CoPA-Map or Log-AM, by the kind its header names)
//! and the baselines' settings from the few numbers the command line takes
//! ([`baseline_config`]); the extraction job of §4.2.2 (eqs. 4.5–4.6: training samples from
//! pedestrian detections as simulated patrol robots see them, [`extract_samples`]) with its
//! setup ([`robots_on_map`]), or the ground truth of §4.3.2; and the evaluation of §4.3.2
//! ([`evaluate`]: every baseline and the chosen model scored by eqs. 4.20–4.21 on later data);
//! maps of a model's predicted rate over a grid of cells at several times ([`predict_maps`]).

use std::path::Path;
use std::time::Instant;

use chronomap_activity::extract::{
    ExtractConfig, Extraction, ObstacleGrid, RobotPath, extract_with_progress, ground_truth,
};
use chronomap_activity::grids::RegionGrid;
use chronomap_activity::{
    AnyActivityModel, Baseline, BaselineConfig, BaselineSelection, CopaConfig, CopaMap,
    FrAamConfig, GpHomConfig, LogAdditive, LogAdditiveConfig, PeriodInit, PeriodInitMode,
    RatePredictor, RateSamples, RateScale, Scores, WhyteConfig, score, select_baseline,
};
use chronomap_core::Parallelism;
use chronomap_core::progress::Progress;
use chronomap_hypertime::events::Event;
use chronomap_io::DataError;
use chronomap_io::model_file::ModelFileError;
use chronomap_io::navmap::{LoadSemantics, NavMapError, load_map};
use chronomap_io::rate_predictions::RatePrediction;
use chronomap_io::{LOG_ADDITIVE_KIND, read_copa_map, read_model_file, read_robot_paths};
use chronomap_spatial::OccupancyMap;
use chronomap_spatial::occupancy::WALL_PERCENT;
use thiserror::Error;

use crate::open::FileKind;

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
    let (_, model): (String, LogAdditive) = read_model_file(path)?;
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
        let missing = dir.join("missing");
        let error = open_activity_model(&missing).unwrap_err();
        assert!(matches!(error, OpenActivityError::ModelFile(_)), "{error}");
        std::fs::remove_dir_all(&dir).unwrap();
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
        let settings = EvalSettings {
            period: 12.0,
            inducing: 4,
            iterations: 5,
            choice: EvalChoice::Baseline(Baseline::Ml),
            parallelism: Parallelism::Sequential,
        };
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
    }
}
