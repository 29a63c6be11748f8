//! Maps of human activity ([Stüde 2024] chapter 4) as the faces use them: a model file opened
//! by its content ([`open_activity_model`]: CoPA-Map or Log-AM, by the kind its header names)
//! and the baselines' settings from the few numbers the command line takes
//! ([`baseline_config`]); the extraction job of §4.2.2 (eqs. 4.5–4.6: training samples from
//! pedestrian detections as simulated patrol robots see them, [`extract_samples`]) with its
//! setup ([`robots_on_map`]), or the ground truth of §4.3.2.

use std::path::Path;

use chronomap_activity::extract::{
    ExtractConfig, Extraction, ObstacleGrid, RobotPath, extract_with_progress, ground_truth,
};
use chronomap_activity::{
    AnyActivityModel, BaselineConfig, FrAamConfig, GpHomConfig, LogAdditive, LogAdditiveConfig,
    WhyteConfig,
};
use chronomap_core::Parallelism;
use chronomap_core::progress::Progress;
use chronomap_hypertime::events::Event;
use chronomap_io::DataError;
use chronomap_io::model_file::ModelFileError;
use chronomap_io::navmap::{LoadSemantics, NavMapError, load_map};
use chronomap_io::{LOG_ADDITIVE_KIND, read_copa_map, read_model_file, read_robot_paths};
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

/// Why the extraction job cannot run.
#[derive(Debug, Error)]
pub enum ExtractJobError {
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
/// [`ExtractJobError`] naming the map, the path file and line, or an unknown name.
pub fn robots_on_map(
    map_file: &Path,
    paths_file: &Path,
    speed: f64,
    min_occupancy: i8,
    names: &[String],
) -> Result<(ObstacleGrid, Vec<(String, RobotPath)>), ExtractJobError> {
    let message = ExtractJobError::Message;
    let map_name = map_file.display().to_string();
    let map = load_map(map_file, LoadSemantics::Nav2).map_err(ExtractJobError::Map)?;
    let grid = map
        .obstacle_grid(min_occupancy)
        .map_err(|e| message(format!("{map_name}: {e}")))?;
    let paths_name = paths_file.display().to_string();
    let all = read_robot_paths(paths_file, speed).map_err(ExtractJobError::Paths)?;
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
/// [`ExtractJobError::Message`] `extraction: …` or `ground truth: …`.
pub fn extract_samples(
    detections: &[Event],
    source: SampleSource,
    bins: &[i64],
    config: &ExtractConfig,
    progress: &dyn Progress,
) -> Result<Extraction, ExtractJobError> {
    let truth = |cells: &[[f64; 2]]| {
        ground_truth(detections, cells, bins, config)
            .map_err(|e| ExtractJobError::Message(format!("ground truth: {e}")))
    };
    match source {
        SampleSource::TruthIn(cells) => truth(cells),
        SampleSource::Robots {
            grid,
            paths,
            truth: counted,
        } => {
            let seen = extract_with_progress(grid, paths, detections, bins, config, progress)
                .map_err(|e| ExtractJobError::Message(format!("extraction: {e}")))?;
            if counted {
                truth(&seen.cells())
            } else {
                Ok(seen)
            }
        }
    }
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
}
