//! The range-data studies of [Stüde 2024] §3.2 along a laser log: descriptors of every scan
//! (§3.2.1, eq. 3.7), scan registration of loop pairs against the SLAM relative poses
//! (§3.2.2), the loop classifier's keyframe-disjoint cross-validation over fold layouts, the
//! `p_min` training rule, the out-of-fold loop pipeline (§3.2.1, eq. 3.8) and loop detection
//! with a trained classifier.
//!
//! Each function takes plain settings and a [`Progress`] and returns a result struct; the
//! faces print, plot and map settings errors to their own argument names.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use chronomap_core::num::median;
use chronomap_core::progress::Progress;
use chronomap_geometry::se2::{Pose2, between, compose};
use chronomap_io::model_file::ModelFileError;
use chronomap_io::read_model_file;
use chronomap_lidar::classifier::{ClassifierConfig, LoopClassifier, MODEL_KIND, ScanFeatures};
use chronomap_lidar::descriptor::{
    Descriptor, DescriptorError, DescriptorParams, PAIR_FEATURE_NAMES, SCALAR_FEATURES,
    describe_cloud, describe_scan,
};
use chronomap_lidar::evaluation::{
    Balance, CvReport, Detection as EvalDetection, EvalError, FoldResult, LabelParams,
    LabelledPair, MAX_BOOSTING_ROUNDS, MAX_TRAININGS, PipelineParams, PipelineReport, WeakLearner,
    cv_rounds, cv_trainings, label_pairs, layout_folds, run_pipeline,
};
use chronomap_lidar::search::SearchMode;
use chronomap_lidar::threshold::{MeanSd, RocPoint};
use chronomap_registration::rigid::Rigid;
use chronomap_registration::{Cloud, RegistrationParams, register_scans, scan_params};
use serde::Serialize;

use crate::laser_log::{LaserLog, LaserLogError, from_keyframes};
use crate::registration::RegistrationJobError;
use chronomap_app::report::Table;

/// The most folds a cross-validation may ask for (the sectors of [`layout_folds`]).
pub const MAX_FOLDS: usize = 1000;

/// A study that cannot run: the log, the settings, or the classifier's input.
#[derive(Debug, thiserror::Error)]
pub enum LoopStudyError {
    /// The laser log cannot be read.
    #[error(transparent)]
    Log(#[from] LaserLogError),
    /// Settings that cannot work on this log (the faces name their own arguments).
    #[error(transparent)]
    Settings(#[from] SettingsError),
    /// Labelling, training, cross-validation or the pipeline refused its input.
    #[error(transparent)]
    Eval(#[from] EvalError),
    /// The features of a log's keyframes.
    #[error("{name}: keyframe features")]
    Features {
        /// The log.
        name: String,
        /// Why.
        #[source]
        source: EvalError,
    },
    /// A pair scored by a trained classifier.
    #[error("{name}: scoring a pair")]
    Scoring {
        /// The log.
        name: String,
        /// Why.
        #[source]
        source: EvalError,
    },
    /// The descriptor of one scan (eq. 3.7).
    #[error("{name}: scan {index}")]
    Descriptor {
        /// The log.
        name: String,
        /// The 1-based scan.
        index: usize,
        /// Why.
        #[source]
        source: DescriptorError,
    },
    /// The labelled pairs hold only loops or only non-loops.
    #[error(
        "{name}: {positives} keyframe pairs are loops (closer than {near} m, more than {min_separation} keyframes apart) and {negatives} are not (farther than {far} m): training needs both"
    )]
    OneClass {
        /// The log.
        name: String,
        /// Loop pairs.
        positives: usize,
        /// Non-loop pairs.
        negatives: usize,
        /// The loop distance (m).
        near: f64,
        /// The non-loop distance (m).
        far: f64,
        /// The least keyframe separation of a pair.
        min_separation: usize,
    },
    /// A cloud that cannot be read.
    #[error(transparent)]
    Cloud(#[from] RegistrationJobError),
    /// The descriptor of a cloud (eq. 3.7).
    #[error("{file}: descriptor")]
    CloudDescriptor {
        /// The cloud's file.
        file: String,
        /// Why.
        #[source]
        source: DescriptorError,
    },
    /// A classifier file that cannot be read.
    #[error(transparent)]
    ModelFile(#[from] ModelFileError),
    /// A model file of another kind.
    #[error("{file}: holds a {kind}, not a loop classifier (chronomap lidar train writes one)")]
    NotAClassifier {
        /// The file.
        file: String,
        /// What it holds.
        kind: String,
    },
    /// A classifier file whose classifier is invalid.
    #[error("{file}: invalid classifier")]
    InvalidClassifier {
        /// The file.
        file: String,
        /// Why.
        #[source]
        source: EvalError,
    },
    /// No fold layout has a threshold that keeps the false-positive rate below the bound.
    #[error("{name}: no threshold keeps the false-positive rate below {max_fpr}")]
    NoThreshold {
        /// The log.
        name: String,
        /// The bound.
        max_fpr: f64,
    },
}

/// Loop-training settings that cannot work, alone or on a given log. Displayed without the
/// names a face gives them; the command line maps each to its flags.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SettingsError {
    /// `near` beyond `far`: pairs cannot be both loops and not.
    #[error("near {near} is beyond far {far}: pairs cannot be both loops and not")]
    NearBeyondFar {
        /// Loop distance (m).
        near: f64,
        /// Non-loop distance (m).
        far: f64,
    },
    /// No boosting rounds.
    #[error("rounds must be at least 1")]
    NoRounds,
    /// Fewer than 2 folds.
    #[error("{folds} folds: cross-validation needs at least 2 folds")]
    TooFewFolds {
        /// The folds asked for.
        folds: usize,
    },
    /// No fold layouts.
    #[error("layouts must be at least 1")]
    NoLayouts,
    /// More folds than keyframes or than [`MAX_FOLDS`].
    #[error("{folds} folds: more folds than keyframes or than {MAX_FOLDS} ({counts})")]
    TooManyFolds {
        /// The folds asked for.
        folds: usize,
        /// What the log holds.
        counts: PairCounts,
    },
    /// More than [`MAX_TRAININGS`] classifier trainings.
    #[error("{trainings} classifier trainings, at most {MAX_TRAININGS}")]
    TooManyTrainings {
        /// The trainings asked for.
        trainings: usize,
        /// Of them, the out-of-fold models (one per pair of folds), if asked for.
        out_of_fold: Option<usize>,
    },
    /// More than [`MAX_BOOSTING_ROUNDS`] boosting rounds over all trainings.
    #[error(
        "{rounds} boosting rounds ({trainings} classifier trainings), at most {MAX_BOOSTING_ROUNDS}"
    )]
    TooManyRounds {
        /// The rounds in all.
        rounds: usize,
        /// The trainings.
        trainings: usize,
    },
    /// A fold layout without a fold that can be scored (a loop and a non-loop inside it,
    /// both outside it too).
    #[error(
        "no fold of layout {layout} holds a loop and a non-loop among its own keyframes with both left to train on ({counts})"
    )]
    NoUsableFold {
        /// The layout (0-based).
        layout: usize,
        /// What the log holds.
        counts: PairCounts,
    },
}

/// Keyframes and labelled pairs of a log, for messages.
#[derive(Debug, Clone, PartialEq)]
pub struct PairCounts {
    /// The log.
    pub name: String,
    /// Keyframes.
    pub keyframes: usize,
    /// Loop pairs.
    pub positives: usize,
    /// Non-loop pairs.
    pub negatives: usize,
}

impl std::fmt::Display for PairCounts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} has {} keyframes, {} loops and {} non-loops",
            self.name, self.keyframes, self.positives, self.negatives
        )
    }
}

/// How the loop classifier is trained and cross-validated ([Stüde 2024] §3.2.1).
#[derive(Debug, Clone, PartialEq)]
pub struct LoopTraining {
    /// The dissertation's classifier (41 pair values, stumps) instead of the extended one.
    pub paper: bool,
    /// Laser origins closer than this are loops (m).
    pub near: f64,
    /// Laser origins farther than this are non-loops (m).
    pub far: f64,
    /// Pairs at most this many keyframes apart are not labelled.
    pub min_separation: usize,
    /// Boosting rounds `T`.
    pub rounds: usize,
    /// The bound on the false-positive rate that chooses `p_min`.
    pub max_fpr: f64,
    /// Folds by place.
    pub folds: usize,
    /// Fold layouts (rotations of the place sectors).
    pub layouts: usize,
}

impl LoopTraining {
    /// The classifier configuration these settings ask for.
    pub fn config(&self) -> ClassifierConfig {
        let base = if self.paper {
            ClassifierConfig::paper()
        } else {
            ClassifierConfig::extended()
        };
        ClassifierConfig {
            rounds: self.rounds,
            ..base
        }
    }

    /// Checks the settings on their own (before any file is read).
    ///
    /// # Errors
    /// `near > far`, no rounds, fewer than 2 folds, no layouts.
    pub fn validate(&self) -> Result<(), SettingsError> {
        if self.near > self.far {
            return Err(SettingsError::NearBeyondFar {
                near: self.near,
                far: self.far,
            });
        }
        if self.rounds == 0 {
            return Err(SettingsError::NoRounds);
        }
        if self.folds < 2 {
            return Err(SettingsError::TooFewFolds { folds: self.folds });
        }
        if self.layouts == 0 {
            return Err(SettingsError::NoLayouts);
        }
        Ok(())
    }
}

/// Features and labelled pairs of a keyframe file: what cross-validation and training learn
/// from.
pub struct LabelledKeyframes {
    /// The keyframes, with SLAM poses.
    pub log: LaserLog,
    /// The classifier configuration.
    pub config: ClassifierConfig,
    /// The features of each keyframe.
    pub features: Vec<ScanFeatures>,
    /// The labelled pairs (by the robot's SLAM positions).
    pub pairs: Vec<LabelledPair>,
    /// The pair values of each labelled pair.
    pub rows: Vec<Vec<f64>>,
    /// How the pairs were labelled.
    pub labels: LabelParams,
    /// Sensor positions (m), for folds by place.
    pub places: Vec<[f64; 2]>,
}

impl LabelledKeyframes {
    /// The loop pairs.
    pub fn positives(&self) -> usize {
        self.pairs.iter().filter(|p| p.positive).count()
    }
}

/// Reads and labels the keyframes of `path` for a cross-validated run, after checking the
/// settings against them (with `pair_models`, the run also trains the out-of-fold models of
/// [`out_of_fold_pipeline`]).
///
/// # Errors
/// Settings that cannot work ([`LoopTraining::validate`], [`check_folds`]), a log that cannot
/// be read, pairs of one class only, features that cannot be computed.
pub fn labelled_keyframes(
    path: &Path,
    settings: &LoopTraining,
    odometry: Option<&Path>,
    pair_models: bool,
) -> Result<LabelledKeyframes, LoopStudyError> {
    settings.validate()?;
    let log = from_keyframes(path, odometry)?;
    let truth = log.truth.clone().expect("keyframe files carry poses");
    let config = settings.config();
    let labels = LabelParams {
        near: settings.near,
        far: settings.far,
        min_separation: settings.min_separation,
    };
    let robot: Vec<[f64; 2]> = truth.iter().map(|p| [p[0], p[1]]).collect();
    let pairs = label_pairs(&robot, &labels)?;
    let positives = pairs.iter().filter(|p| p.positive).count();
    if positives == 0 || positives == pairs.len() {
        return Err(LoopStudyError::OneClass {
            name: log.name,
            positives,
            negatives: pairs.len() - positives,
            near: settings.near,
            far: settings.far,
            min_separation: settings.min_separation,
        });
    }
    let places: Vec<[f64; 2]> = truth
        .iter()
        .map(|&p| {
            let s = compose(p, log.sensor);
            [s[0], s[1]]
        })
        .collect();
    check_folds(&log.name, &places, &pairs, settings, pair_models)?;
    let features = config
        .features(&log.scans)
        .map_err(|source| LoopStudyError::Features {
            name: log.name.clone(),
            source,
        })?;
    let rows = config.pair_rows(&features, &pairs)?;
    Ok(LabelledKeyframes {
        log,
        config,
        features,
        pairs,
        rows,
        labels,
        places,
    })
}

/// Checks the folds against the keyframes before any feature is computed: at most one fold per
/// keyframe (and [`MAX_FOLDS`]), at most [`MAX_TRAININGS`] classifiers to train over the
/// layouts (with `pair_models`, the out-of-fold models too) and at most
/// [`MAX_BOOSTING_ROUNDS`] rounds over them all, and in every fold layout at least one fold
/// whose own pairs hold a loop and a non-loop while the pairs outside it hold both too (else
/// nothing is scored and the ROC is empty).
///
/// # Errors
/// The first of these that fails; [`EvalError`] from [`layout_folds`].
pub fn check_folds(
    name: &str,
    places: &[[f64; 2]],
    pairs: &[LabelledPair],
    settings: &LoopTraining,
    pair_models: bool,
) -> Result<(), LoopStudyError> {
    let keyframes = places.len();
    let positives = pairs.iter().filter(|p| p.positive).count();
    let counts = PairCounts {
        name: name.to_string(),
        keyframes,
        positives,
        negatives: pairs.len() - positives,
    };
    if settings.folds > keyframes.min(MAX_FOLDS) {
        return Err(SettingsError::TooManyFolds {
            folds: settings.folds,
            counts,
        }
        .into());
    }
    let trainings = cv_trainings(settings.folds, settings.layouts, pair_models);
    if trainings > MAX_TRAININGS {
        return Err(SettingsError::TooManyTrainings {
            trainings,
            out_of_fold: pair_models.then(|| cv_trainings(settings.folds, 0, true)),
        }
        .into());
    }
    let rounds = cv_rounds(
        settings.folds,
        settings.layouts,
        pair_models,
        settings.rounds,
    );
    if rounds > MAX_BOOSTING_ROUNDS {
        return Err(SettingsError::TooManyRounds { rounds, trainings }.into());
    }
    for layout in 0..settings.layouts {
        let fold_of = layout_folds(places, settings.folds, layout, settings.layouts)?;
        let usable = (0..settings.folds).any(|f| {
            let (mut inside, mut outside) = ([false; 2], [false; 2]);
            for p in pairs {
                let within = [fold_of[p.i] == f, fold_of[p.j] == f];
                if within == [true, true] {
                    inside[usize::from(p.positive)] = true;
                } else if within == [false, false] {
                    outside[usize::from(p.positive)] = true;
                }
            }
            inside == [true, true] && outside == [true, true]
        });
        if !usable {
            return Err(SettingsError::NoUsableFold { layout, counts }.into());
        }
    }
    Ok(())
}

/// Cross-validation over several rotations of the place folds, each with its own seed.
pub struct LayoutsReport {
    /// One report per fold layout.
    pub reports: Vec<CvReport>,
}

impl LayoutsReport {
    /// Every fold of every layout.
    pub fn folds(&self) -> impl Iterator<Item = &FoldResult> {
        self.reports.iter().flat_map(|r| &r.folds)
    }

    /// `p_min` of the first layout's pooled ROC, the one [`out_of_fold_pipeline`] uses.
    pub fn first_threshold(&self) -> Option<f64> {
        self.reports.first().map(|r| r.pooled_at_max_fpr.threshold)
    }
}

/// Keyframe-disjoint cross-validation of the loop classifier over `settings.layouts` fold
/// layouts by place, layout `l` seeded with `l + 1` ([Stüde 2024] §3.2.1). Reports one stage,
/// one step per classifier trained.
///
/// # Errors
/// Settings that cannot work; [`EvalError`] from the folds and the training.
pub fn cross_validate_layouts(
    data: &LabelledKeyframes,
    settings: &LoopTraining,
    progress: &dyn Progress,
) -> Result<LayoutsReport, LoopStudyError> {
    settings.validate()?;
    progress.stage(
        "cross-validation",
        cv_trainings(settings.folds, settings.layouts, false) as u64,
    );
    let mut reports = Vec::with_capacity(settings.layouts);
    for layout in 0..settings.layouts {
        let fold_of = layout_folds(&data.places, settings.folds, layout, settings.layouts)?;
        let report = data.config.cross_validate(
            &data.pairs,
            &data.rows,
            &fold_of,
            settings.max_fpr,
            layout as u64 + 1,
        )?;
        reports.push(report);
        progress.advance(settings.folds as u64);
    }
    Ok(LayoutsReport { reports })
}

/// The loop pipeline along the keyframes ([Stüde 2024] §3.2.1: search radius of eq. 3.8,
/// classifier, verification) with fold layout 0, each pair scored by the model that saw
/// neither keyframe's fold, `p_min` from that layout's pooled ROC: detections that no model
/// was trained on. Reports one stage, one step per out-of-fold model.
///
/// # Errors
/// [`EvalError`] from the folds, the models and the pipeline.
pub fn out_of_fold_pipeline(
    data: &LabelledKeyframes,
    settings: &LoopTraining,
    cv: &LayoutsReport,
    progress: &dyn Progress,
) -> Result<PipelineReport, LoopStudyError> {
    let fold_of = layout_folds(&data.places, settings.folds, 0, settings.layouts)?;
    progress.stage(
        "out-of-fold models",
        cv_trainings(settings.folds, 0, true) as u64,
    );
    let models = data
        .config
        .pair_models(&data.pairs, &data.rows, &fold_of, &mut || {
            progress.advance(1)
        })?;
    let mut params = PipelineParams {
        min_separation: settings.min_separation,
        near: settings.near,
        ..PipelineParams::default()
    };
    params.search.p_min = cv.first_threshold().map_or(1.0, |t| t.min(1.0));
    let truth = data.log.truth.as_deref().unwrap_or(&[]);
    let positions: Vec<[f64; 2]> = truth.iter().map(|p| [p[0], p[1]]).collect();
    Ok(run_pipeline(
        &data.log.increments(),
        [data.log.sensor[0], data.log.sensor[1]],
        &positions,
        &params,
        |i, j| {
            let x = data
                .config
                .pair(&data.features[i], &data.features[j])
                .map_err(|e| EvalError::Input(e.to_string()))?;
            models.probability(i, j, &x)
        },
    )?)
}

/// What the cross-validation says, as mean ± sd over folds (per fold) or over layouts
/// (pooled).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CvSummary {
    /// Folds scored, over all layouts.
    pub folds: usize,
    /// AUC per fold.
    pub auc: MeanSd,
    /// TPR at the bound with each fold's own threshold.
    pub tpr: MeanSd,
    /// TPR with `p_min` chosen on the other folds.
    pub heldout_tpr: MeanSd,
    /// FPR with `p_min` chosen on the other folds.
    pub heldout_fpr: MeanSd,
    /// AUC pooled over the folds of a layout.
    pub pooled_auc: MeanSd,
    /// TPR at the bound, pooled over the folds of a layout.
    pub pooled_tpr: MeanSd,
    /// `p_min` of each layout's pooled ROC.
    pub p_min: MeanSd,
}

impl CvSummary {
    /// The summary of a cross-validation.
    pub fn of(cv: &LayoutsReport) -> CvSummary {
        let fold = |f: fn(&FoldResult) -> f64| MeanSd::of(cv.folds().map(f));
        CvSummary {
            folds: cv.folds().count(),
            auc: fold(|f| f.auc),
            tpr: fold(|f| f.at_max_fpr.tpr),
            heldout_tpr: fold(|f| f.heldout_rates.0),
            heldout_fpr: fold(|f| f.heldout_rates.1),
            pooled_auc: MeanSd::of(cv.reports.iter().map(|r| r.pooled_auc)),
            pooled_tpr: MeanSd::of(cv.reports.iter().map(|r| r.pooled_at_max_fpr.tpr)),
            p_min: MeanSd::of(cv.reports.iter().map(|r| r.pooled_at_max_fpr.threshold)),
        }
    }
}

/// The `p_min` training rule: the median over fold layouts of the threshold that keeps each
/// layout's pooled out-of-fold false-positive rate below the bound, at most 1 ([Stüde 2024]
/// §3.2.1, `p_min` at FPR < 1 %); `None` if no layout has one.
pub fn p_min_rule(cv: &LayoutsReport) -> Option<f64> {
    let thresholds: Vec<f64> = cv
        .reports
        .iter()
        .map(|r| r.pooled_at_max_fpr.threshold)
        .filter(|t| t.is_finite())
        .collect();
    (!thresholds.is_empty()).then(|| median(&thresholds).min(1.0))
}

/// Trains the loop classifier on every labelled pair, with `p_min` from [`p_min_rule`] over
/// the cross-validation `cv`, and keeps the labelling with it.
///
/// # Errors
/// [`LoopStudyError::NoThreshold`] if no layout has a threshold; [`EvalError`] from the
/// training.
pub fn train_classifier(
    data: &LabelledKeyframes,
    cv: &LayoutsReport,
    max_fpr: f64,
) -> Result<LoopClassifier, LoopStudyError> {
    let p_min = p_min_rule(cv).ok_or_else(|| LoopStudyError::NoThreshold {
        name: data.log.name.clone(),
        max_fpr,
    })?;
    let mut classifier =
        LoopClassifier::train(&data.config, &data.features, &data.pairs, p_min, max_fpr)?;
    classifier.labels = Some(data.labels.clone());
    Ok(classifier)
}

/// Loops found along a log by a trained classifier.
pub struct Detection {
    /// The pipeline's report.
    pub report: PipelineReport,
    /// The `p_min` used.
    pub p_min: f64,
    /// The trajectory the pipeline judged against: SLAM positions if the log has them, else
    /// the odometry's.
    pub positions: Vec<[f64; 2]>,
}

/// Loop detection along `log` with a trained classifier ([Stüde 2024] §3.2.1: search radius
/// of eq. 3.8 from the odometry, classifier, verification), `p_min` given or the
/// classifier's, loops labelled with the classifier's `near` (3 m without labels).
///
/// # Errors
/// Features that cannot be computed, a pair the classifier cannot score, [`EvalError`] from
/// the pipeline.
pub fn detect_loops(
    log: &LaserLog,
    classifier: &LoopClassifier,
    p_min: Option<f64>,
    min_separation: usize,
) -> Result<Detection, LoopStudyError> {
    let features =
        classifier
            .config
            .features(&log.scans)
            .map_err(|source| LoopStudyError::Features {
                name: log.name.clone(),
                source,
            })?;
    let positions: Vec<[f64; 2]> = log
        .truth
        .as_ref()
        .unwrap_or(&log.odometry)
        .iter()
        .map(|p| [p[0], p[1]])
        .collect();
    let mut params = PipelineParams {
        min_separation,
        near: classifier.labels.as_ref().map_or(3.0, |l| l.near),
        ..PipelineParams::default()
    };
    params.search.p_min = p_min.unwrap_or(classifier.p_min);
    let mut failure = None;
    let report = run_pipeline(
        &log.increments(),
        [log.sensor[0], log.sensor[1]],
        &positions,
        &params,
        |i, j| match classifier.probability(&features[i], &features[j]) {
            Ok(p) => Ok(Some(p)),
            Err(e) => {
                failure.get_or_insert(e);
                Ok(None)
            }
        },
    )?;
    if let Some(source) = failure {
        return Err(LoopStudyError::Scoring {
            name: log.name.clone(),
            source,
        });
    }
    Ok(Detection {
        report,
        p_min: params.search.p_min,
        positions,
    })
}

/// The global descriptor (eq. 3.7) of every scan of a log, with the scan's time. Reports one
/// stage, one step per scan.
///
/// # Errors
/// [`LoopStudyError::Descriptor`] naming the first scan that has none.
pub fn describe_log(
    log: &LaserLog,
    params: &DescriptorParams,
    progress: &dyn Progress,
) -> Result<Vec<(f64, Descriptor)>, LoopStudyError> {
    progress.stage("descriptors", log.scans.len() as u64);
    let mut rows = Vec::with_capacity(log.scans.len());
    for (k, scan) in log.scans.iter().enumerate() {
        let d = describe_scan(scan, params).map_err(|source| LoopStudyError::Descriptor {
            name: log.name.clone(),
            index: k + 1,
            source,
        })?;
        rows.push((scan.time, d));
        progress.advance(1);
    }
    Ok(rows)
}

/// The loop pairs of a keyframe log by its laser positions (robot SLAM pose ⊕ sensor):
/// origins closer than `near` metres and more than `min_separation` keyframes apart, as
/// [`labelled_keyframes`] labels loops.
///
/// # Errors
/// [`EvalError`] from the labelling (positions not finite, a negative distance).
pub fn loop_pairs(
    log: &LaserLog,
    near: f64,
    min_separation: usize,
) -> Result<Vec<[usize; 2]>, LoopStudyError> {
    let places: Vec<[f64; 2]> = (0..log.scans.len())
        .filter_map(|k| log.sensor_in_map(k).map(|p| [p[0], p[1]]))
        .collect();
    let labels = LabelParams {
        near,
        far: near,
        min_separation,
    };
    Ok(label_pairs(&places, &labels)?
        .into_iter()
        .filter(|p| p.positive)
        .map(|p| [p.i, p.j])
        .collect())
}

/// One keyframe pair registered without an initial guess.
#[derive(Debug, Clone, PartialEq)]
pub struct PairRegistration {
    /// Keyframes `[i, j]`: `j`'s scan moved onto `i`'s.
    pub pair: [usize; 2],
    /// The pose of `j`'s laser in the frame of `i`'s by SLAM (`x, y, yaw`).
    pub slam_pose: [f64; 3],
    /// The registration, or why it failed.
    pub result: Result<PairResult, String>,
}

/// A registered pair against its SLAM relative pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairResult {
    /// The registered pose of `j`'s laser in the frame of `i`'s (`x, y, yaw`).
    pub pose: [f64; 3],
    /// Rotation error against SLAM (degrees).
    pub rotation_error_deg: f64,
    /// Translation error against SLAM (m).
    pub translation_error_m: f64,
    /// RANSAC inliers.
    pub inliers: usize,
    /// `σ̂` of the information matrix (m).
    pub sigma_m: f64,
}

impl PairResult {
    /// The registered pose as a homogeneous 3×3 transform (row-major).
    pub fn matrix(&self) -> [[f64; 3]; 3] {
        Pose2::from_array(self.pose).to_matrix()
    }
}

/// Registers keyframe `j`'s scan onto keyframe `i`'s for each pair, without an initial guess
/// ([Stüde 2024] §3.2.2: FPFH-2D, RANSAC, point-to-line ICP; [`scan_params`], RANSAC seeded
/// with `seed` if given), and compares each with the SLAM relative pose of the lasers. Reports
/// one stage, one step per pair.
///
/// # Panics
/// If the log has no SLAM poses or a pair names a keyframe it does not have.
pub fn register_pairs(
    log: &LaserLog,
    pairs: &[[usize; 2]],
    seed: Option<u64>,
    progress: &dyn Progress,
) -> Vec<PairRegistration> {
    let mut params = scan_params();
    if let Some(seed) = seed {
        params.ransac.seed = seed;
    }
    let sensor = |k: usize| log.sensor_in_map(k).expect("a keyframe log");
    progress.stage("registering pairs", pairs.len() as u64);
    let mut rows = Vec::with_capacity(pairs.len());
    for &[i, j] in pairs {
        // Keyframe j's scan moved onto keyframe i's: the true transform is the pose of j's
        // laser in the frame of i's.
        let truth_ij = between(sensor(i), sensor(j));
        let truth_ij = Rigid::from_pose(truth_ij[0], truth_ij[1], truth_ij[2]);
        let result = match register_scans(&log.scans[j], &log.scans[i], &params) {
            Ok(r) => {
                let (dr, dt) = r.transform.error_to(&truth_ij);
                Ok(PairResult {
                    pose: r.transform.to_pose(),
                    rotation_error_deg: dr.to_degrees(),
                    translation_error_m: dt,
                    inliers: r.inliers,
                    sigma_m: r.information.sigma,
                })
            }
            Err(e) => Err(e.to_string()),
        };
        rows.push(PairRegistration {
            pair: [i, j],
            slam_pose: truth_ij.to_pose(),
            result,
        });
        progress.advance(1);
    }
    rows
}

/// Registration against SLAM over many pairs: medians over all pairs (a failed registration
/// counts as an unbounded error) and over those within 2° and 20 cm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegistrationSummary {
    /// Median rotation error over all pairs (degrees).
    pub median_rotation_deg: f64,
    /// Median translation error over all pairs (m).
    pub median_translation_m: f64,
    /// Pairs within 2° and 20 cm.
    pub within: usize,
    /// Median rotation error of those (degrees).
    pub median_rotation_within_deg: f64,
    /// Median translation error of those (m).
    pub median_translation_within_m: f64,
    /// Pairs whose registration failed.
    pub failed: usize,
}

impl RegistrationSummary {
    /// The summary of registered pairs.
    pub fn of(rows: &[PairRegistration]) -> RegistrationSummary {
        let all = |f: fn(&PairResult) -> f64| {
            median(
                &rows
                    .iter()
                    .map(|r| r.result.as_ref().map_or(f64::INFINITY, f))
                    .collect::<Vec<_>>(),
            )
        };
        let within: Vec<&PairResult> = rows
            .iter()
            .filter_map(|r| r.result.as_ref().ok())
            .filter(|x| x.rotation_error_deg < 2.0 && x.translation_error_m < 0.2)
            .collect();
        let of_within =
            |f: fn(&PairResult) -> f64| median(&within.iter().map(|x| f(x)).collect::<Vec<_>>());
        RegistrationSummary {
            median_rotation_deg: all(|x| x.rotation_error_deg),
            median_translation_m: all(|x| x.translation_error_m),
            within: within.len(),
            median_rotation_within_deg: of_within(|x| x.rotation_error_deg),
            median_translation_within_m: of_within(|x| x.translation_error_m),
            failed: rows.iter().filter(|r| r.result.is_err()).count(),
        }
    }
}

/// Registration parameters for 3-D clouds ([Stüde 2024] §3.2.2): features and RANSAC on a
/// `voxel` grid, ICP on a `fine_voxel` grid, points beyond `max_range` of the sensor dropped
/// (appendix A: 30 m).
pub fn cloud_params(voxel: f64, fine_voxel: f64, max_range: f64) -> RegistrationParams {
    let mut params = RegistrationParams::for_voxel(voxel);
    params.filters.voxel = Some(fine_voxel);
    params.filters.range = Some((0.0, max_range));
    params
}

/// The points of a cloud within `max_range` of its sensor (the origin), and the distance of
/// its nearest point (+inf for an empty cloud): a cloud in a far frame (e.g. UTM) has none.
pub fn within_range(cloud: &Cloud<3>, max_range: f64) -> (usize, f64) {
    let ranges = cloud
        .points()
        .iter()
        .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt());
    let within = ranges.clone().filter(|&r| r <= max_range).count();
    (within, ranges.fold(f64::INFINITY, f64::min))
}

/// The descriptors of a cloud or of every scan of a log, as `chronomap lidar descriptors`
/// reports them ([Stüde 2024] §3.2.1, eq. 3.7).
#[derive(Debug, Clone, Serialize)]
pub struct DescriptorsReport {
    /// The cloud's file or the log.
    pub source: String,
    /// The descriptor's parameters.
    pub params: DescriptorParams,
    /// The names of the scalar features, in the order of each descriptor's scalars.
    pub features: Vec<&'static str>,
    /// One descriptor per cloud or scan, with the scan's time (0 for a cloud).
    pub descriptors: Vec<TimedDescriptor>,
}

/// A descriptor with the time of its scan.
#[derive(Debug, Clone, Serialize)]
pub struct TimedDescriptor {
    /// The scan's time (s).
    pub time: f64,
    /// The descriptor.
    pub descriptor: Descriptor,
}

impl DescriptorsReport {
    fn new(source: String, params: DescriptorParams, rows: Vec<(f64, Descriptor)>) -> Self {
        DescriptorsReport {
            source,
            params,
            features: PAIR_FEATURE_NAMES[..SCALAR_FEATURES].to_vec(),
            descriptors: rows
                .into_iter()
                .map(|(time, descriptor)| TimedDescriptor { time, descriptor })
                .collect(),
        }
    }

    /// The scalar features as CSV: `index,time` and one column per feature (lower case, words
    /// joined by `_`), one line per descriptor.
    pub fn csv(&self) -> String {
        let mut text = String::from("index,time");
        for name in &self.features {
            text.push(',');
            text.push_str(&csv_name(name));
        }
        text.push('\n');
        for (k, d) in self.descriptors.iter().enumerate() {
            let _ = write!(text, "{k},{}", d.time);
            for v in &d.descriptor.scalars {
                let _ = write!(text, ",{v}");
            }
            text.push('\n');
        }
        text
    }

    /// The line saying the CSV was written to `path`.
    pub fn written(&self, path: &Path) -> String {
        format!(
            "{}: {} descriptor(s) of {} scalar features written to {}\n",
            self.source,
            self.descriptors.len(),
            SCALAR_FEATURES,
            path.display()
        )
    }
}

/// A feature name as a CSV column: lower case, words joined by `_`.
fn csv_name(name: &str) -> String {
    let mut out = String::new();
    for c in name.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('_') {
            out.push('_');
        }
    }
    out.trim_matches('_').to_string()
}

/// The descriptor (eq. 3.7) of a PLY cloud, with the default parameters.
///
/// # Errors
/// The file cannot be read, or the cloud has no descriptor.
pub fn cloud_descriptors(path: &Path) -> Result<DescriptorsReport, LoopStudyError> {
    let params = DescriptorParams::default();
    let cloud = crate::registration::read_cloud(path, "a descriptor")?;
    let d = describe_cloud(cloud.points(), &params).map_err(|source| {
        LoopStudyError::CloudDescriptor {
            file: path.display().to_string(),
            source,
        }
    })?;
    Ok(DescriptorsReport::new(
        path.display().to_string(),
        params,
        vec![(0.0, d)],
    ))
}

/// The descriptors (eq. 3.7) of every scan of a log ([`describe_log`]), with the default
/// parameters.
///
/// # Errors
/// The first scan without a descriptor.
pub fn log_descriptors(
    log: &LaserLog,
    progress: &dyn Progress,
) -> Result<DescriptorsReport, LoopStudyError> {
    let params = DescriptorParams::default();
    let rows = describe_log(log, &params, progress)?;
    Ok(DescriptorsReport::new(log.name.clone(), params, rows))
}

/// One line naming a classifier configuration ([Stüde 2024] §3.2.1: the paper's classifier,
/// the extended one, or another).
pub fn describe_config(config: &ClassifierConfig) -> String {
    let features = match config.profile {
        Some(_) => "44 pair values (41 of the descriptor, 3 of the range profiles)",
        None => "41 pair values of the descriptor",
    };
    let learner = match config.learner {
        WeakLearner::Stump => "AdaBoost with stumps",
        WeakLearner::Depth2 => "boosted depth-2 trees",
    };
    let balance = match config.balance {
        Balance::Subsample => "loops and as many random non-loops",
        Balance::Weighted => "all pairs, classes weighted equally",
    };
    let fixed = ClassifierConfig {
        rounds: 50,
        ..config.clone()
    };
    let which = if fixed == ClassifierConfig::paper() {
        "the paper's classifier"
    } else if fixed == ClassifierConfig::extended() {
        "the extended classifier"
    } else {
        "classifier"
    };
    format!("{which}: {features}, {learner}, {balance}")
}

/// The out-of-fold loop pipeline of [`LoopEvalReport`].
#[derive(Debug, Clone, Serialize)]
pub struct PipelineSummary {
    /// `p_min` of fold layout 0's pooled ROC.
    pub p_min: Option<f64>,
    /// Loops accepted.
    pub loops: usize,
    /// Of them, true loops.
    pub correct: usize,
    /// Of them, false loops.
    pub wrong: usize,
    /// Keyframes with a true loop partner.
    pub revisiting_keyframes: usize,
    /// Of those, keyframes with a correct loop.
    pub revisiting_keyframes_closed: usize,
    /// The loops accepted, in sequence order.
    pub detections: Vec<EvalDetection>,
}

/// The cross-validation of the loop classifier over fold layouts and its out-of-fold pipeline
/// ([Stüde 2024] §3.2.1), as `chronomap lidar eval` reports it.
#[derive(Debug, Clone, Serialize)]
pub struct LoopEvalReport {
    /// Keyframes.
    pub keyframes: usize,
    /// Loop pairs.
    pub loops: usize,
    /// Non-loop pairs.
    pub non_loops: usize,
    /// Folds scored, over all layouts.
    pub folds: usize,
    /// Fold layouts.
    pub layouts: usize,
    /// AUC per fold.
    pub auc: MeanSd,
    /// TPR at the bound with each fold's own threshold.
    pub tpr_at_max_fpr: MeanSd,
    /// TPR with `p_min` chosen on the other folds.
    pub heldout_p_min_tpr: MeanSd,
    /// FPR with `p_min` chosen on the other folds.
    pub heldout_p_min_fpr: MeanSd,
    /// AUC pooled over the folds of a layout.
    pub pooled_auc: MeanSd,
    /// TPR at the bound, pooled per layout.
    pub pooled_tpr_at_max_fpr: MeanSd,
    /// `p_min` of each layout's pooled ROC.
    pub p_min: MeanSd,
    /// The bound on the false-positive rate.
    pub max_fpr: f64,
    /// The classifier ([`describe_config`]).
    pub classifier: String,
    /// The out-of-fold loop pipeline.
    pub pipeline: PipelineSummary,
    /// The pooled ROC of every layout.
    pub pooled_roc: Vec<Vec<RocPoint>>,
    /// The log.
    #[serde(skip)]
    pub name: String,
    /// The settings.
    #[serde(skip)]
    pub settings: LoopTraining,
    /// The SLAM positions of the keyframes (m), for plots.
    #[serde(skip)]
    pub trajectory: Vec<[f64; 2]>,
}

impl LoopEvalReport {
    /// The report as `chronomap lidar eval` prints it.
    pub fn text(&self) -> String {
        let s = &self.settings;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{}: {} keyframes, {} loops (closer than {} m, more than {} keyframes apart), {} non-loops (farther than {} m)",
            self.name, self.keyframes, self.loops, s.near, s.min_separation, self.non_loops, s.far
        );
        let _ = writeln!(
            out,
            "cross-validation: {} fold layouts × {} folds by place ({} folds with loops and non-loops to score); {}, T = {}",
            s.layouts, s.folds, self.folds, self.classifier, s.rounds
        );
        let pct = 100.0 * s.max_fpr;
        let mut table = Table::new(["measure", "mean ± sd"]).left(&[0]);
        let rows = [
            ("AUC (per fold)".to_string(), format!("{:.3}", self.auc)),
            (
                format!("TPR at FPR < {pct} % (each fold's own threshold)"),
                format!("{:.3}", self.tpr_at_max_fpr),
            ),
            (
                "TPR with p_min chosen on the other folds".to_string(),
                format!("{:.3}", self.heldout_p_min_tpr),
            ),
            (
                "FPR with p_min chosen on the other folds".to_string(),
                format!("{:.4}", self.heldout_p_min_fpr),
            ),
            (
                "AUC (pooled over folds, per layout)".to_string(),
                format!("{:.3}", self.pooled_auc),
            ),
            (
                format!("TPR at FPR < {pct} % (pooled, per layout)"),
                format!("{:.3}", self.pooled_tpr_at_max_fpr),
            ),
            (
                "p_min (pooled, per layout)".to_string(),
                format!("{:.4}", self.p_min),
            ),
        ];
        for (measure, value) in rows {
            table.row([measure, value]);
        }
        let _ = writeln!(out, "{}", table.render().trim_end());
        let p = &self.pipeline;
        let _ = writeln!(
            out,
            "loop detection along the keyframes (search radius, classifier, verification; fold layout 0, each pair scored by the model trained without both keyframes' folds, p_min {:.4}): {} loops, {} correct, {} wrong; {} of {} revisiting keyframes closed",
            p.p_min.unwrap_or(f64::NAN),
            p.loops,
            p.correct,
            p.wrong,
            p.revisiting_keyframes_closed,
            p.revisiting_keyframes
        );
        out
    }
}

/// `chronomap lidar eval`: reads and labels the keyframes, cross-validates the classifier over
/// the fold layouts ([`cross_validate_layouts`]) and runs the out-of-fold pipeline
/// ([`out_of_fold_pipeline`]).
///
/// # Errors
/// As [`labelled_keyframes`], [`cross_validate_layouts`] and [`out_of_fold_pipeline`].
pub fn evaluate_loops(
    path: &Path,
    settings: &LoopTraining,
    odometry: Option<&Path>,
    progress: &dyn Progress,
) -> Result<LoopEvalReport, LoopStudyError> {
    let data = labelled_keyframes(path, settings, odometry, true)?;
    let cv = cross_validate_layouts(&data, settings, progress)?;
    let pipeline = out_of_fold_pipeline(&data, settings, &cv, progress)?;
    let summary = CvSummary::of(&cv);
    let loops = data.positives();
    let truth = data.log.truth.as_deref().unwrap_or(&[]);
    Ok(LoopEvalReport {
        keyframes: data.log.scans.len(),
        loops,
        non_loops: data.pairs.len() - loops,
        folds: summary.folds,
        layouts: settings.layouts,
        auc: summary.auc,
        tpr_at_max_fpr: summary.tpr,
        heldout_p_min_tpr: summary.heldout_tpr,
        heldout_p_min_fpr: summary.heldout_fpr,
        pooled_auc: summary.pooled_auc,
        pooled_tpr_at_max_fpr: summary.pooled_tpr,
        p_min: summary.p_min,
        max_fpr: settings.max_fpr,
        classifier: describe_config(&data.config),
        pipeline: PipelineSummary {
            p_min: cv.first_threshold(),
            loops: pipeline.detections.len(),
            correct: pipeline.correct(),
            wrong: pipeline.wrong(),
            revisiting_keyframes: pipeline.queries_with_loop,
            revisiting_keyframes_closed: pipeline.queries_closed,
            detections: pipeline.detections,
        },
        pooled_roc: cv.reports.into_iter().map(|r| r.pooled_roc).collect(),
        name: data.log.name.clone(),
        settings: settings.clone(),
        trajectory: truth.iter().map(|p| [p[0], p[1]]).collect(),
    })
}

/// The loop classifier trained on every labelled pair with `p_min` from [`p_min_rule`], as
/// `chronomap lidar train` reports it.
#[derive(Debug, Clone, Serialize)]
pub struct LoopTrainReport {
    /// Where the classifier is written.
    pub output: PathBuf,
    /// Keyframes.
    pub keyframes: usize,
    /// Loop pairs trained on.
    pub loops: usize,
    /// Non-loop pairs.
    pub non_loops: usize,
    /// Boosting rounds trained.
    pub rounds: usize,
    /// The classifier ([`describe_config`]).
    pub classifier: String,
    /// The threshold.
    pub p_min: f64,
    /// The bound on the false-positive rate it was chosen for.
    pub max_fpr: f64,
    /// The pooled out-of-fold TPR at the bound.
    pub cv_tpr_at_max_fpr: MeanSd,
    /// The log.
    #[serde(skip)]
    pub name: String,
    /// The trained classifier.
    #[serde(skip)]
    pub model: LoopClassifier,
}

impl LoopTrainReport {
    /// The report as `chronomap lidar train` prints it.
    pub fn text(&self) -> String {
        format!(
            "{}: trained on {} loops and {} non-loops of {} keyframes ({}, T = {}); p_min = {:.4} keeps the out-of-fold false-positive rate below {} % (TPR there {:.3}); written to {}\n",
            self.name,
            self.loops,
            self.non_loops,
            self.keyframes,
            self.classifier,
            self.rounds,
            self.p_min,
            100.0 * self.max_fpr,
            self.cv_tpr_at_max_fpr,
            self.output.display()
        )
    }
}

/// `chronomap lidar train`: reads and labels the keyframes, cross-validates over the fold
/// layouts and trains the classifier on every pair with `p_min` by [`p_min_rule`]
/// ([`train_classifier`]); `output` is where the face writes it.
///
/// # Errors
/// As [`labelled_keyframes`], [`cross_validate_layouts`] and [`train_classifier`].
pub fn train_loops(
    path: &Path,
    settings: &LoopTraining,
    output: &Path,
    progress: &dyn Progress,
) -> Result<LoopTrainReport, LoopStudyError> {
    let data = labelled_keyframes(path, settings, None, false)?;
    let cv = cross_validate_layouts(&data, settings, progress)?;
    let model = train_classifier(&data, &cv, settings.max_fpr)?;
    let loops = model.trained_on.0;
    Ok(LoopTrainReport {
        output: output.to_path_buf(),
        keyframes: data.log.scans.len(),
        loops,
        non_loops: data.pairs.len() - loops,
        rounds: model.model.rounds(),
        classifier: describe_config(&model.config),
        p_min: model.p_min,
        max_fpr: settings.max_fpr,
        cv_tpr_at_max_fpr: CvSummary::of(&cv).pooled_tpr,
        name: data.log.name.clone(),
        model,
    })
}

/// Reads a loop classifier file ([`MODEL_KIND`]) and checks the classifier.
///
/// # Errors
/// The file cannot be read, holds another kind, or an invalid classifier.
pub fn read_classifier(path: &Path) -> Result<LoopClassifier, LoopStudyError> {
    let (kind, classifier): (String, LoopClassifier) = read_model_file(path)?;
    let file = path.display().to_string();
    if kind != MODEL_KIND {
        return Err(LoopStudyError::NotAClassifier { file, kind });
    }
    classifier
        .validate()
        .map_err(|source| LoopStudyError::InvalidClassifier { file, source })?;
    Ok(classifier)
}

/// A loop found by [`detect_report`], as `--json` shows it.
#[derive(Debug, Clone, Serialize)]
pub struct DetectionRow {
    /// The new keyframe.
    pub query: usize,
    /// The keyframe it closes the loop with.
    pub target: usize,
    /// The loop probability.
    pub probability: f64,
    /// The search radius (m; infinite for a global search).
    pub radius_m: f64,
    /// Where the search looked.
    pub mode: SearchMode,
    /// Candidates scored.
    pub candidates: usize,
    /// The true distance of the pair (m), if the log has SLAM poses.
    pub true_distance_m: Option<f64>,
    /// Whether it is a true loop, if the log has SLAM poses.
    pub correct: Option<bool>,
}

/// Loops found along a log by a trained classifier ([`detect_loops`]), as
/// `chronomap lidar detect` reports them.
#[derive(Debug, Clone, Serialize)]
pub struct LoopDetectReport {
    /// The log.
    pub log: String,
    /// Keyframes.
    pub keyframes: usize,
    /// The threshold used.
    pub p_min: f64,
    /// The loops accepted.
    pub detections: Vec<DetectionRow>,
    /// Pairs scored within the search radius.
    pub scored_pairs: usize,
    /// Loops rejected by verification.
    pub rejected_by_verification: usize,
    /// True loop pairs, if the log has SLAM poses.
    pub true_loop_pairs: Option<usize>,
    /// Of those, pairs inside the search radius when their second keyframe came.
    pub true_loop_pairs_in_search_space: Option<usize>,
    /// The pipeline's report.
    #[serde(skip)]
    pub pipeline: PipelineReport,
    /// The trajectory judged against (SLAM if known, else odometry; m).
    #[serde(skip)]
    pub positions: Vec<[f64; 2]>,
    /// Whether the log has SLAM poses.
    #[serde(skip)]
    pub has_truth: bool,
}

impl LoopDetectReport {
    /// The loops as CSV: `query,target,probability,radius_m,mode`.
    pub fn csv(&self) -> String {
        let mut csv = String::from("query,target,probability,radius_m,mode\n");
        for d in &self.pipeline.detections {
            let _ = writeln!(
                csv,
                "{},{},{},{},{:?}",
                d.query, d.target, d.probability, d.radius, d.mode
            );
        }
        csv
    }

    /// The report as `chronomap lidar detect` prints it.
    pub fn text(&self) -> String {
        let report = &self.pipeline;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{}: {} keyframes, {} pairs scored within the search radius (eq. 3.8), p_min = {:.4}: {} loop(s), {} rejected by verification",
            self.log,
            self.keyframes,
            report.scored_pairs,
            self.p_min,
            report.detections.len(),
            report.rejected_by_verification
        );
        if self.has_truth {
            let _ = writeln!(
                out,
                "against the SLAM poses: {} correct, {} wrong; {} true loop pairs, {} of them inside the search radius when their second keyframe came",
                report.correct(),
                report.wrong(),
                report.true_pairs,
                report.true_pairs_in_space
            );
        }
        if !report.detections.is_empty() {
            let mut table = Table::new([
                "keyframe",
                "loop with",
                "p",
                "radius (m)",
                "search",
                "true distance (m)",
            ]);
            for d in &report.detections {
                table.row([
                    d.query.to_string(),
                    d.target.to_string(),
                    format!("{:.3}", d.probability),
                    if d.radius.is_finite() {
                        format!("{:.2}", d.radius)
                    } else {
                        "all".into()
                    },
                    format!("{:?}", d.mode),
                    if self.has_truth {
                        format!("{:.2}", d.true_distance)
                    } else {
                        "-".into()
                    },
                ]);
            }
            let _ = writeln!(out, "{}", table.render().trim_end());
        }
        out
    }
}

/// `chronomap lidar detect`: loop detection along `log` ([`detect_loops`]) as a report.
///
/// # Errors
/// As [`detect_loops`].
pub fn detect_report(
    log: &LaserLog,
    classifier: &LoopClassifier,
    p_min: Option<f64>,
    min_separation: usize,
) -> Result<LoopDetectReport, LoopStudyError> {
    let has_truth = log.truth.is_some();
    let Detection {
        report,
        p_min,
        positions,
    } = detect_loops(log, classifier, p_min, min_separation)?;
    let known = |v: usize| has_truth.then_some(v);
    Ok(LoopDetectReport {
        log: log.name.clone(),
        keyframes: log.scans.len(),
        p_min,
        detections: report
            .detections
            .iter()
            .map(|d| DetectionRow {
                query: d.query,
                target: d.target,
                probability: d.probability,
                radius_m: d.radius,
                mode: d.mode,
                candidates: d.candidates,
                true_distance_m: has_truth.then_some(d.true_distance),
                correct: has_truth.then_some(d.correct),
            })
            .collect(),
        scored_pairs: report.scored_pairs,
        rejected_by_verification: report.rejected_by_verification,
        true_loop_pairs: known(report.true_pairs),
        true_loop_pairs_in_search_space: known(report.true_pairs_in_space),
        pipeline: report,
        positions,
        has_truth,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(result: Result<(f64, f64), &str>) -> PairRegistration {
        PairRegistration {
            pair: [0, 1],
            slam_pose: [0.0; 3],
            result: result
                .map(|(r, t)| PairResult {
                    pose: [0.0; 3],
                    rotation_error_deg: r,
                    translation_error_m: t,
                    inliers: 10,
                    sigma_m: 0.01,
                })
                .map_err(str::to_string),
        }
    }

    #[test]
    fn registration_medians_count_failures_as_unbounded() {
        let rows = [
            pair(Ok((0.5, 0.0625))),
            pair(Ok((1.5, 0.125))),
            pair(Ok((5.0, 0.03125))),
            pair(Err("too few points")),
        ];
        let s = RegistrationSummary::of(&rows);
        // Over all four, the failure as +inf: (1.5 + 5) / 2 and (0.0625 + 0.125) / 2; within
        // 2° and 20 cm: the first two.
        assert_eq!(s.median_rotation_deg, 3.25);
        assert_eq!(s.median_translation_m, 0.09375);
        assert_eq!(s.within, 2);
        assert_eq!(s.median_rotation_within_deg, 1.0);
        assert_eq!(s.median_translation_within_m, 0.09375);
        assert_eq!(s.failed, 1);
        assert!(median(&[]).is_nan());
    }

    #[test]
    fn points_within_range_of_the_sensor_are_counted() {
        let cloud =
            Cloud::from_points(vec![[3.0, 4.0, 0.0], [0.0, 0.0, 2.0], [30.0, 40.0, 0.0]]).unwrap();
        assert_eq!(within_range(&cloud, 5.0), (2, 2.0));
        assert_eq!(within_range(&cloud, 1.0), (0, 2.0));
        let p = cloud_params(0.25, 0.05, 30.0);
        assert_eq!(
            (p.filters.voxel, p.filters.range),
            (Some(0.05), Some((0.0, 30.0)))
        );
    }

    #[test]
    fn a_registered_pose_is_its_homogeneous_matrix() {
        let r = PairResult {
            pose: [1.0, -2.0, std::f64::consts::FRAC_PI_2],
            rotation_error_deg: 0.0,
            translation_error_m: 0.0,
            inliers: 0,
            sigma_m: 0.0,
        };
        let m = r.matrix();
        assert!(m[0][0].abs() < 1e-15 && m[1][1].abs() < 1e-15);
        assert_eq!([m[0][1], m[1][0], m[0][2], m[1][2]], [-1.0, 1.0, 1.0, -2.0]);
        assert_eq!(m[2], [0.0, 0.0, 1.0]);
    }

    #[test]
    fn settings_are_checked_before_any_file_is_read() {
        let ok = LoopTraining {
            paper: true,
            near: 3.0,
            far: 10.0,
            min_separation: 20,
            rounds: 50,
            max_fpr: 0.01,
            folds: 5,
            layouts: 10,
        };
        assert_eq!(ok.validate(), Ok(()));
        assert_eq!(ok.config(), ClassifierConfig::paper());
        let bad = LoopTraining {
            near: 12.0,
            ..ok.clone()
        };
        assert_eq!(
            bad.validate(),
            Err(SettingsError::NearBeyondFar {
                near: 12.0,
                far: 10.0
            })
        );
        // One fold is refused before the (missing) file is opened.
        let result = labelled_keyframes(
            Path::new("/nothing"),
            &LoopTraining { folds: 1, ..ok },
            None,
            false,
        );
        assert!(matches!(
            result,
            Err(LoopStudyError::Settings(SettingsError::TooFewFolds {
                folds: 1
            }))
        ));
    }

    #[test]
    fn the_two_classifiers_are_named_by_what_they_learn_from() {
        assert_eq!(
            describe_config(&ClassifierConfig::paper()),
            "the paper's classifier: 41 pair values of the descriptor, AdaBoost with stumps, \
             loops and as many random non-loops"
        );
        let extended = ClassifierConfig {
            rounds: 7,
            ..ClassifierConfig::extended()
        };
        assert_eq!(
            describe_config(&extended),
            "the extended classifier: 44 pair values (41 of the descriptor, 3 of the range \
             profiles), boosted depth-2 trees, all pairs, classes weighted equally"
        );
        assert_eq!(csv_name("Range mean (m)"), "range_mean_m");
    }

    /// The 225 scans of the Málaga 2006 log: one descriptor each, 32 scalar features, as CSV
    /// and as JSON.
    #[test]
    fn the_descriptors_of_the_malaga_log_are_one_row_per_scan() {
        let log = crate::laser_log::from_scans(
            &chronomap_testutil::data_path("malaga_laser_2006/scans.txt.xz"),
            &chronomap_testutil::data_path("malaga_laser_2006/odometry.txt.xz"),
        )
        .unwrap();
        let report = log_descriptors(&log, &chronomap_core::progress::NoProgress).unwrap();
        assert_eq!(report.descriptors.len(), 225);
        let csv = report.csv();
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 226);
        assert!(lines[0].starts_with("index,time,"), "{}", lines[0]);
        assert_eq!(lines[0].split(',').count(), 2 + SCALAR_FEATURES);
        assert_eq!(lines[1].split(',').count(), 2 + SCALAR_FEATURES);
        assert!(lines[1].starts_with(&format!("0,{},", log.scans[0].time)));
        assert_eq!(
            report.written(Path::new("d.csv")),
            format!(
                "{}: 225 descriptor(s) of 32 scalar features written to d.csv\n",
                log.name
            )
        );
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["features"].as_array().unwrap().len(), SCALAR_FEATURES);
        assert_eq!(json["descriptors"][224]["time"], log.scans[224].time);
    }
}
