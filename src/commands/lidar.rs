//! `chronomap lidar`: scan descriptors, the loop classifier (cross-validation, training,
//! detection along a log) and the registration of clouds ([Stüde 2024] §3.2); the jobs and
//! their reports are [`chronomap_app_range::lidar_study`] and [`chronomap_app_range::registration`].

use std::path::Path;

use anyhow::{Result, anyhow};
use chronomap_app_range::lidar_study::{
    LoopStudyError, LoopTraining, MAX_FOLDS, SettingsError, cloud_descriptors, cloud_params,
    detect_report, evaluate_loops, log_descriptors, read_classifier, train_loops,
};
use chronomap_app_range::registration::{
    CloudSettings, read_cloud, read_transform, register_cloud_files, register_keyframes,
};
use chronomap_io::{write_data_file, write_model_file};
use chronomap_lidar::classifier::MODEL_KIND;
use chronomap_lidar::evaluation::{
    Detection, MAX_BOOSTING_ROUNDS, MAX_TRAININGS, cv_rounds, cv_trainings,
};
use chronomap_plot::plane::{PlaneLayer, PlanePlot, PlaneShape, render_plane_png};

use super::laser_log;
use crate::cli::{
    BenchRegistrationArgs, LidarDescriptorsArgs, LidarDetectArgs, LidarEvalArgs, LidarRegisterArgs,
    LidarTrainArgs, LoopTrainingFlags,
};
use crate::output::{ProgressBar, print_bench, print_json, usage};
use crate::{out, outln};

/// `chronomap lidar descriptors`.
pub fn descriptors(args: &LidarDescriptorsArgs) -> Result<()> {
    let report = match &args.cloud {
        Some(path) => cloud_descriptors(path)?,
        None => log_descriptors(&laser_log::read(&args.source)?, &ProgressBar::new())?,
    };
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    match &args.output {
        Some(path) => {
            write_data_file(path, report.csv().as_bytes())?;
            Ok(out!("{}", report.written(path))?)
        }
        None => Ok(out!("{}", report.csv())?),
    }
}

/// `chronomap lidar register`.
pub fn register_clouds(args: &LidarRegisterArgs) -> Result<()> {
    if let Some(keyframes) = &args.keyframes {
        return register_keyframe_pairs(keyframes, args);
    }
    let (Some(source), Some(target)) = (&args.source, &args.target) else {
        return Err(usage("give SOURCE and TARGET clouds, or --keyframes"));
    };
    let settings = CloudSettings {
        voxel: args.voxel,
        fine_voxel: args.fine_voxel,
        max_range: args.max_range,
        seed: args.seed,
    };
    let report = register_cloud_files(
        source,
        target,
        args.truth.as_deref(),
        &settings,
        &ProgressBar::new(),
    )?;
    if let Some(path) = &args.output {
        let text = chronomap_app_range::registration::matrix_text(&report.transform);
        write_data_file(path, text.as_bytes())?;
    }
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    Ok(out!("{}", report.text())?)
}

/// `chronomap bench registration`: the default parameters of `lidar register` against a bare
/// nearest-neighbour pass ([`chronomap_bench::registration`] measures, this reads and prints).
pub fn bench_registration(args: &BenchRegistrationArgs) -> Result<()> {
    let source = read_cloud(&args.source, "registration")?;
    let target = read_cloud(&args.target, "registration")?;
    let truth = read_transform(&args.truth)?;
    let bench = chronomap_bench::registration::run(
        &source,
        &target,
        &truth,
        &cloud_params(0.25, 0.05, 30.0),
        args.repeats as usize,
    )?;
    print_bench(args.json, &bench, |b| {
        outln!(
            "{} ({} points) onto {} ({} points), median of {}: registration {:.0} ms (FPFH, RANSAC, ICP; {} inliers, {} ICP iterations) = {:.1} x a bare nearest-neighbour pass ({:.0} ms: one k-d tree, one query per source point); error {:.3}°, {:.2} cm",
            args.source.display(),
            b.points.0,
            args.target.display(),
            b.points.1,
            b.repeats,
            b.registration_ms,
            b.inliers,
            b.icp_iterations,
            b.ratio,
            b.bare_nn_ms,
            b.rotation_error_deg,
            100.0 * b.translation_error_m
        )?;
        Ok(())
    })
}

/// `chronomap lidar register --keyframes`: one pair, or every loop pair against the SLAM
/// relative poses.
fn register_keyframe_pairs(path: &Path, args: &LidarRegisterArgs) -> Result<()> {
    let log = laser_log::read_keyframes_file(path, None)?;
    let n = log.scans.len();
    if let Some([i, j]) = args.pair
        && (i >= n || j >= n)
    {
        return Err(usage(format!(
            "--pair {i},{j}: {} has keyframes 0 to {}",
            log.name,
            n.saturating_sub(1)
        )));
    }
    let report = register_keyframes(
        &log,
        args.pair,
        args.near,
        args.min_separation,
        args.seed,
        &ProgressBar::new(),
    )?;
    if let (Some(path), Some(text)) = (&args.output, report.single_matrix_text()) {
        write_data_file(path, text.as_bytes())?;
    }
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    if let Some(failure) = report.single_failure() {
        return Err(anyhow!(failure));
    }
    Ok(out!("{}", report.text())?)
}

/// The loop-training settings of the flags.
fn training(flags: &LoopTrainingFlags) -> LoopTraining {
    LoopTraining {
        paper: flags.paper,
        near: flags.near,
        far: flags.far,
        min_separation: flags.min_separation,
        rounds: flags.rounds,
        max_fpr: flags.max_fpr,
        folds: flags.folds,
        layouts: flags.layouts,
    }
}

/// A study's error, its settings named by their flags (a usage error).
fn study_error(e: LoopStudyError, flags: &LoopTrainingFlags, pair_models: bool) -> anyhow::Error {
    let LoopStudyError::Settings(settings) = e else {
        return anyhow::Error::new(e);
    };
    usage(match settings {
        SettingsError::NearBeyondFar { near, far } => {
            format!("--near {near} is beyond --far {far}: pairs cannot be both loops and not")
        }
        SettingsError::NoRounds => "--rounds must be at least 1".into(),
        SettingsError::TooFewFolds { folds } => {
            format!("--folds {folds}: cross-validation needs at least 2 folds")
        }
        SettingsError::NoLayouts => "--layouts must be at least 1".into(),
        SettingsError::TooManyFolds { folds, counts } => format!(
            "--folds {folds}: more folds than keyframes or than {MAX_FOLDS} ({counts}); the \
             default is 5"
        ),
        SettingsError::TooManyTrainings {
            trainings,
            out_of_fold,
        } => {
            let models = out_of_fold.map_or(String::new(), |m| {
                format!(" + {m} out-of-fold models, one per pair of folds")
            });
            format!(
                "--folds {} --layouts {}: {trainings} classifier trainings ({} layouts × {} \
                 folds{models}), at most {MAX_TRAININGS}: use fewer folds or layouts (the \
                 defaults, 5 and 10, need {})",
                flags.folds,
                flags.layouts,
                flags.layouts,
                flags.folds,
                cv_trainings(5, 10, pair_models)
            )
        }
        SettingsError::TooManyRounds { rounds, trainings } => format!(
            "--rounds {} --folds {} --layouts {}: {rounds} boosting rounds ({trainings} \
             classifier trainings × {} rounds), at most {MAX_BOOSTING_ROUNDS}: use fewer rounds, \
             folds or layouts (the defaults, 50, 5 and 10, need {})",
            flags.rounds,
            flags.folds,
            flags.layouts,
            flags.rounds,
            cv_rounds(5, 10, pair_models, 50)
        ),
        SettingsError::NoUsableFold { layout, counts } => format!(
            "--folds {}: no fold of layout {layout} holds a loop and a non-loop among its own \
             keyframes with both left to train on ({counts}); use fewer folds (the default is 5)",
            flags.folds
        ),
    })
}

/// `chronomap lidar eval`.
pub fn eval(args: &LidarEvalArgs) -> Result<()> {
    let report = evaluate_loops(
        &args.keyframes,
        &training(&args.training),
        args.odometry.as_deref(),
        &ProgressBar::new(),
    )
    .map_err(|e| study_error(e, &args.training, true))?;
    if let Some(path) = &args.plot {
        // ROC curves (pooled, one per layout) beside the trajectory with its loops found.
        let mut paths = Vec::new();
        for (k, roc) in report.pooled_roc.iter().enumerate() {
            if k > 0 {
                paths.push([f64::NAN, f64::NAN]);
            }
            paths.extend(roc.iter().map(|p| [p.fpr, p.tpr]));
        }
        let max_fpr = args.training.max_fpr;
        let line = |label: String, points: Vec<[f64; 2]>| PlaneLayer {
            label,
            shape: PlaneShape::Path(points),
        };
        let roc = PlanePlot {
            title: "Loop classifier, keyframe-disjoint cross-validation".into(),
            x_label: "false-positive rate".into(),
            y_label: "true-positive rate".into(),
            equal_aspect: false,
            x_range: Some((0.0, 1.0)),
            y_range: Some((0.0, 1.0)),
            layers: vec![
                line(
                    format!("pooled ROC, {} fold layouts", report.pooled_roc.len()),
                    paths,
                ),
                line("chance".into(), vec![[0.0, 0.0], [1.0, 1.0]]),
                line(
                    format!("FPR = {} %", 100.0 * max_fpr),
                    vec![[max_fpr, 0.0], [max_fpr, 1.0]],
                ),
            ],
        };
        let trajectory = detections_plot(
            &format!(
                "Loops found, each pair scored by a model that saw neither keyframe ({} keyframes)",
                report.trajectory.len()
            ),
            &report.trajectory,
            true,
            &report.pipeline.detections,
        );
        render_plane_png(&[roc, trajectory], path, 1600, 720)?;
    }
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    Ok(out!("{}", report.text())?)
}

/// `chronomap lidar train`.
pub fn train(args: &LidarTrainArgs) -> Result<()> {
    let report = train_loops(
        &args.keyframes,
        &training(&args.training),
        &args.output,
        &ProgressBar::new(),
    )
    .map_err(|e| study_error(e, &args.training, false))?;
    write_model_file(&args.output, MODEL_KIND, &report.model)?;
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    Ok(out!("{}", report.text())?)
}

/// `chronomap lidar detect`.
pub fn detect(args: &LidarDetectArgs) -> Result<()> {
    let classifier = read_classifier(&args.classifier)?;
    let full = laser_log::read(&args.source)?;
    let log = if args.source.keyframes.is_some() {
        full
    } else {
        full.keyframes(args.keyframe_distance, args.keyframe_angle)
    };
    let report = detect_report(&log, &classifier, args.p_min, args.min_separation)?;
    if let Some(path) = &args.output {
        write_data_file(path, report.csv().as_bytes())?;
    }
    if let Some(path) = &args.plot {
        let plot = detections_plot(
            &format!("Loops found along {}", super::maps::short_name(&log.name)),
            &report.positions,
            report.has_truth,
            &report.pipeline.detections,
        );
        render_plane_png(&[plot], path, 1000, 800)?;
    }
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    Ok(out!("{}", report.text())?)
}

/// A trajectory with its keyframes and the loops a pipeline accepted (correct and wrong ones
/// apart when the positions are the truth).
fn detections_plot(
    title: &str,
    positions: &[[f64; 2]],
    has_truth: bool,
    detections: &[Detection],
) -> PlanePlot {
    let segment = |d: &&Detection| [positions[d.query], positions[d.target]];
    let (right, wrong): (Vec<_>, Vec<_>) = detections.iter().partition(|d| !has_truth || d.correct);
    let mut layers = vec![
        PlaneLayer {
            label: if has_truth {
                "SLAM trajectory"
            } else {
                "odometry"
            }
            .into(),
            shape: PlaneShape::Path(positions.to_vec()),
        },
        PlaneLayer {
            label: "keyframes".into(),
            shape: PlaneShape::Points(positions.to_vec()),
        },
        PlaneLayer {
            label: format!(
                "{} loops{}",
                right.len(),
                if has_truth { " (correct)" } else { "" }
            ),
            shape: PlaneShape::Segments(right.iter().map(segment).collect()),
        },
    ];
    if has_truth {
        layers.push(PlaneLayer {
            label: format!("{} wrong loops", wrong.len()),
            shape: PlaneShape::Segments(wrong.iter().map(segment).collect()),
        });
    }
    PlanePlot {
        title: title.to_string(),
        x_label: "x [m]".into(),
        y_label: "y [m]".into(),
        equal_aspect: true,
        x_range: None,
        y_range: None,
        layers,
    }
}
