//! `chronomap lidar`: scan descriptors, the loop classifier (cross-validation, training,
//! detection along a log) and the registration of clouds (dissertation §3.2).

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, anyhow};
use chronomap_app::lidar_study::{
    CvSummary, LabelledKeyframes, LayoutsReport, LoopStudyError, LoopTraining, MAX_FOLDS,
    RegistrationSummary, SettingsError, cloud_params, cross_validate_layouts, describe_log,
    detect_loops, labelled_keyframes, loop_pairs, out_of_fold_pipeline, register_pairs,
    train_classifier, within_range,
};
use chronomap_io::ply::{PlyErrorKind, read_ply_at_most};
use chronomap_io::{read_model_file, write_data_file, write_model_file};
use chronomap_lidar::classifier::{ClassifierConfig, LoopClassifier, MODEL_KIND};
use chronomap_lidar::descriptor::{
    Descriptor, DescriptorParams, PAIR_FEATURE_NAMES, SCALAR_FEATURES, describe_cloud,
};
use chronomap_lidar::evaluation::{
    Balance, MAX_BOOSTING_ROUNDS, MAX_TRAININGS, PipelineReport, WeakLearner, cv_rounds,
    cv_trainings,
};
use chronomap_plot::plane::{PlaneLayer, PlanePlot, PlaneShape, render_plane_png};
use chronomap_registration::rigid::Rigid;
use chronomap_registration::{
    MAX_FEATURE_POINTS, MAX_ICP_POINTS, MAX_INPUT_POINTS, RegistrationError, register,
};
use serde_json::json;

use super::laser_log;
use crate::cli::{
    BenchRegistrationArgs, LidarDescriptorsArgs, LidarDetectArgs, LidarEvalArgs, LidarRegisterArgs,
    LidarTrainArgs, LoopTrainingFlags,
};
use crate::format::Table;
use crate::outln;
use crate::output::{ProgressBar, print_bench, print_json, usage};

/// `chronomap lidar descriptors`.
pub fn descriptors(args: &LidarDescriptorsArgs) -> Result<()> {
    let params = DescriptorParams::default();
    let (name, rows): (String, Vec<(f64, Descriptor)>) = match &args.cloud {
        Some(path) => {
            let cloud = read_cloud(path, "a descriptor")?;
            let d = describe_cloud(cloud.points(), &params)
                .with_context(|| format!("{}: descriptor", path.display()))?;
            (path.display().to_string(), vec![(0.0, d)])
        }
        None => {
            let log = laser_log::read(&args.source)?;
            let rows = describe_log(&log, &params, &ProgressBar::new())?;
            (log.name, rows)
        }
    };
    if args.json {
        return print_json(&json!({
            "source": name,
            "params": params,
            "features": &PAIR_FEATURE_NAMES[..SCALAR_FEATURES],
            "descriptors": rows.iter().map(|(t, d)| json!({"time": t, "descriptor": d})).collect::<Vec<_>>(),
        }));
    }
    let mut text = String::from("index,time");
    for name in &PAIR_FEATURE_NAMES[..SCALAR_FEATURES] {
        text.push(',');
        text.push_str(&csv_name(name));
    }
    text.push('\n');
    for (k, (t, d)) in rows.iter().enumerate() {
        text.push_str(&format!("{k},{t}"));
        for v in &d.scalars {
            text.push_str(&format!(",{v}"));
        }
        text.push('\n');
    }
    match &args.output {
        Some(path) => {
            write_data_file(path, text.as_bytes())?;
            outln!(
                "{}: {} descriptor(s) of {} scalar features written to {}",
                name,
                rows.len(),
                SCALAR_FEATURES,
                path.display()
            )?;
        }
        None => crate::out!("{text}")?,
    }
    Ok(())
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

/// `chronomap lidar register`.
pub fn register_clouds(args: &LidarRegisterArgs) -> Result<()> {
    if let Some(keyframes) = &args.keyframes {
        return register_keyframes(keyframes, args);
    }
    let (Some(source_path), Some(target_path)) = (&args.source, &args.target) else {
        return Err(usage("give SOURCE and TARGET clouds, or --keyframes"));
    };
    let source = read_cloud(source_path, "registration")?;
    let target = read_cloud(target_path, "registration")?;
    let truth = match &args.truth {
        Some(path) => Some(read_transform(path)?),
        None => None,
    };
    let mut params = cloud_params(args.voxel, args.fine_voxel, args.max_range);
    if let Some(seed) = args.seed {
        params.ransac.seed = seed;
    }
    for (path, cloud) in [(source_path, &source), (target_path, &target)] {
        check_range(path, cloud, args.max_range)?;
    }
    let bar = ProgressBar::stage("registering", 0);
    let start = Instant::now();
    let result = register(&source, &target, &params).map_err(|e| {
        let file = |what: &str| {
            if what.ends_with("source") {
                source_path.display()
            } else {
                target_path.display()
            }
        };
        // A grid that stopped after `seen` of `points` points with `max` cells: about
        // max·points/seen cells in all, for points spread evenly; on a surface the cells go
        // as 1/leaf², so a leaf larger by the square root of the excess (and a margin).
        let larger = |leaf: f64, max: usize, seen: usize, points: usize| {
            leaf * (points as f64 / seen.max(1) as f64).sqrt()
                * 1.2
                * ((max + 1) as f64 / max as f64).sqrt()
        };
        match e {
            RegistrationError::TooManyFeaturePoints {
                what,
                voxel,
                seen,
                points,
            } => anyhow!(
                "{}: more than {MAX_FEATURE_POINTS} points remain on the --voxel {voxel} m grid, \
                 at most {MAX_FEATURE_POINTS} enter feature computation (FPFH keeps about 2 KB \
                 a point; counted in the first {seen} of the {points} points left after \
                 --fine-voxel and --max-range): give a larger --voxel (about {:.2} m)",
                file(what),
                larger(voxel, MAX_FEATURE_POINTS, seen, points)
            ),
            RegistrationError::TooManyIcpPoints {
                what, seen, points, ..
            } => anyhow!(
                "{}: more than {MAX_ICP_POINTS} points remain on the --fine-voxel {} m grid \
                 within --max-range {} m, at most {MAX_ICP_POINTS} enter ICP (counted in the \
                 first {seen} of its {points} points): give a larger --fine-voxel (about {:.2} m)",
                file(what),
                args.fine_voxel,
                args.max_range,
                larger(args.fine_voxel, MAX_ICP_POINTS, seen, points)
            ),
            RegistrationError::TooFewPoints { what, got, need } if what.starts_with("filtered") => {
                anyhow!(
                    "{}: {got} points left after the --fine-voxel {} m grid and --max-range {} m, \
                     at least {need} needed",
                    file(what),
                    args.fine_voxel,
                    args.max_range
                )
            }
            e => anyhow::Error::new(e).context(format!(
                "cannot register {} to {}",
                source_path.display(),
                target_path.display()
            )),
        }
    })?;
    let seconds = start.elapsed().as_secs_f64();
    drop(bar);
    let matrix = result.transform.to_matrix4();
    if let Some(path) = &args.output {
        write_data_file(path, matrix_text(&matrix).as_bytes())?;
    }
    let errors = truth.map(|t| result.transform.error_to(&t));
    let coarse_errors = truth.map(|t| result.coarse.error_to(&t));
    if args.json {
        return print_json(&json!({
            "source": source_path, "target": target_path,
            "points": [source.len(), target.len()],
            "transform": matrix,
            "coarse_transform": result.coarse.to_matrix4(),
            "correspondences": result.correspondences,
            "inliers": result.inliers,
            "ransac_iterations": result.ransac_iterations,
            "icp": { "iterations": result.icp.iterations, "converged": result.icp.converged,
                     "fitness": result.icp.fitness, "rmse_m": result.icp.rmse },
            "information": { "sigma_m": result.information.sigma, "dof": result.information.dof,
                             "correspondences": result.information.correspondences },
            "rotation_error_deg": errors.map(|e| e.0.to_degrees()),
            "translation_error_m": errors.map(|e| e.1),
            "coarse_rotation_error_deg": coarse_errors.map(|e| e.0.to_degrees()),
            "coarse_translation_error_m": coarse_errors.map(|e| e.1),
            "seconds": seconds,
        }));
    }
    outln!(
        "{} ({} points) onto {} ({} points) in {:.2} s",
        source_path.display(),
        source.len(),
        target_path.display(),
        target.len(),
        seconds
    )?;
    outln!(
        "coarse (FPFH + RANSAC): {} correspondences, {} inliers, {} samples; fine (ICP): {} iterations, fitness {:.3}, RMSE {:.3} m",
        result.correspondences,
        result.inliers,
        result.ransac_iterations,
        result.icp.iterations,
        result.icp.fitness,
        result.icp.rmse
    )?;
    outln!(
        "information matrix: I / σ̂² with σ̂ = {:.4} m (median absolute deviation of {} residuals)",
        result.information.sigma,
        result.information.correspondences
    )?;
    outln!(
        "transform (target ← source):\n{}",
        matrix_text(&matrix).trim_end()
    )?;
    if let (Some((r, t)), Some((cr, ct))) = (errors, coarse_errors) {
        outln!(
            "error against the truth: rotation {:.4}°, translation {:.2} cm (coarse: {:.3}°, {:.2} cm)",
            r.to_degrees(),
            t * 100.0,
            cr.to_degrees(),
            ct * 100.0
        )?;
    }
    Ok(())
}

/// A PLY cloud for `purpose` (registration, a descriptor): at most [`MAX_INPUT_POINTS`],
/// checked from its header before any vertex is read, so that a compressed cloud announcing
/// 10^8 points is refused before it is decompressed.
fn read_cloud(path: &Path, purpose: &str) -> Result<chronomap_registration::Cloud<3>> {
    read_ply_at_most(path, MAX_INPUT_POINTS as u64).map_err(|e| match e.kind {
        PlyErrorKind::TooManyVertices { line, count, .. } => anyhow!(
            "{}: line {line}: element vertex: {count} points, {purpose} takes at most \
             {MAX_INPUT_POINTS} a cloud (24 bytes each): thin the cloud first",
            path.display()
        ),
        _ => anyhow::Error::new(e),
    })
}

/// Too few points of a cloud within `max_range` of its sensor (the origin) for registration:
/// an error naming the file and --max-range, with the distance of its nearest point (a cloud
/// in a far frame, e.g. UTM, is all beyond the default 30 m).
fn check_range(
    path: &Path,
    cloud: &chronomap_registration::Cloud<3>,
    max_range: f64,
) -> Result<()> {
    let (within, nearest) = within_range(cloud, max_range);
    // The 9 points `register` needs at least (3 per dimension).
    if within >= 9 {
        return Ok(());
    }
    Err(anyhow!(
        "{}: {within} of its {} points lie within --max-range {max_range} m of the sensor (the \
         origin), at least 9 are needed; its nearest point is {nearest:.1} m away: give a \
         larger --max-range",
        path.display(),
        cloud.len()
    ))
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
fn register_keyframes(path: &Path, args: &LidarRegisterArgs) -> Result<()> {
    let log = laser_log::read_keyframes_file(path, None)?;
    let n = log.scans.len();
    let pairs: Vec<[usize; 2]> = match args.pair {
        Some([i, j]) => {
            if i >= n || j >= n {
                return Err(usage(format!(
                    "--pair {i},{j}: {} has keyframes 0 to {}",
                    log.name,
                    n.saturating_sub(1)
                )));
            }
            vec![[i, j]]
        }
        // The loop pairs of the laser positions, labelled as `lidar eval` labels them.
        None => loop_pairs(&log, args.near, args.min_separation)?,
    };
    if pairs.is_empty() {
        return Err(anyhow!(
            "{}: no keyframes are closer than {} m and more than {} apart",
            log.name,
            args.near,
            args.min_separation
        ));
    }
    let bar = ProgressBar::new();
    let start = Instant::now();
    let rows = register_pairs(&log, &pairs, args.seed, &bar);
    drop(bar);
    let seconds = start.elapsed().as_secs_f64();
    let summary = RegistrationSummary::of(&rows);
    if let (Some(path), [row]) = (&args.output, rows.as_slice())
        && let Ok(r) = &row.result
    {
        let m = r.matrix();
        let text = format!(
            "{:.9} {:.9} {:.9}\n{:.9} {:.9} {:.9}\n0 0 1\n",
            m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2]
        );
        write_data_file(path, text.as_bytes())?;
    }
    if args.json {
        return print_json(&json!({
            "keyframes": log.name,
            "pairs": rows.iter().map(|row| match &row.result {
                Ok(x) => json!({"pair": row.pair, "pose": x.pose, "slam_pose": row.slam_pose,
                                "rotation_error_deg": x.rotation_error_deg,
                                "translation_error_m": x.translation_error_m,
                                "inliers": x.inliers, "sigma_m": x.sigma_m}),
                Err(e) => json!({"pair": row.pair, "slam_pose": row.slam_pose, "error": e}),
            }).collect::<Vec<_>>(),
            "within_2_deg_and_20_cm": summary.within,
            "failed": summary.failed,
            "median_rotation_error_deg": summary.median_rotation_deg,
            "median_translation_error_m": summary.median_translation_m,
            "median_rotation_error_deg_within": summary.median_rotation_within_deg,
            "median_translation_error_m_within": summary.median_translation_within_m,
            "seconds_per_pair": seconds / rows.len() as f64,
        }));
    }
    if let [row] = rows.as_slice() {
        let ([i, j], t) = (row.pair, row.slam_pose);
        return match &row.result {
            Ok(x) => outln!(
                "keyframe {j} onto keyframe {i}: ({:.3} m, {:.3} m, {:.2}°); SLAM: ({:.3} m, {:.3} m, {:.2}°); error {:.3}°, {:.1} cm; {} inliers, σ̂ = {:.3} m",
                x.pose[0], x.pose[1], x.pose[2].to_degrees(), t[0], t[1], t[2].to_degrees(),
                x.rotation_error_deg, 100.0 * x.translation_error_m, x.inliers, x.sigma_m
            ).map_err(Into::into),
            Err(e) => Err(anyhow!("keyframe {j} onto keyframe {i}: {e}")),
        };
    }
    outln!(
        "{}: {} loop pairs (laser origins closer than {} m, more than {} keyframes apart), registered without an initial guess (FPFH-2D, RANSAC, point-to-line ICP) in {:.1} ms per pair",
        log.name,
        rows.len(),
        args.near,
        args.min_separation,
        1e3 * seconds / rows.len() as f64
    )?;
    outln!(
        "against the SLAM relative poses: median error {:.3}° and {:.1} cm over all pairs; {} within 2° and 20 cm (median {:.3}°, {:.1} cm); {} failed",
        summary.median_rotation_deg,
        100.0 * summary.median_translation_m,
        summary.within,
        summary.median_rotation_within_deg,
        100.0 * summary.median_translation_within_m,
        summary.failed
    )?;
    Ok(())
}

/// A 4×4 row-major matrix as four lines of text.
fn matrix_text(m: &[[f64; 4]; 4]) -> String {
    m.iter()
        .map(|row| {
            row.iter()
                .map(|v| format!("{v:.9}"))
                .collect::<Vec<_>>()
                .join(" ")
                + "\n"
        })
        .collect()
}

/// Reads a 4×4 rigid transform: 16 numbers, row-major, whitespace-separated.
fn read_transform(path: &Path) -> Result<Rigid<3>> {
    let mut bytes = Vec::new();
    std::io::Read::read_to_end(
        &mut std::io::Read::take(chronomap_io::open_data_file(path)?, 1 << 16),
        &mut bytes,
    )
    .with_context(|| format!("cannot read {}", path.display()))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| anyhow!("{}: not a text file of numbers", path.display()))?;
    let mut values = Vec::with_capacity(16);
    for (line_no, line) in text.lines().enumerate() {
        for field in line.split_whitespace() {
            let v: f64 = field.parse().map_err(|_| {
                anyhow!(
                    "{}:{}: {field:?} is not a number",
                    path.display(),
                    line_no + 1
                )
            })?;
            values.push(v);
        }
    }
    if values.len() != 16 {
        return Err(anyhow!(
            "{}: a 4×4 transform has 16 numbers, this file has {}",
            path.display(),
            values.len()
        ));
    }
    let mut m = [[0.0; 4]; 4];
    for (i, v) in values.iter().enumerate() {
        m[i / 4][i % 4] = *v;
    }
    Rigid::from_matrix4(&m).with_context(|| format!("{}: not a rigid transform", path.display()))
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

/// Reads and labels the keyframes and cross-validates over the fold layouts: what `eval` and
/// `train` share (with `pair_models`, eval's out-of-fold models are counted in the checks).
fn cross_validated(
    path: &Path,
    flags: &LoopTrainingFlags,
    odometry: Option<&Path>,
    pair_models: bool,
) -> Result<(LabelledKeyframes, LayoutsReport)> {
    let settings = training(flags);
    let data = labelled_keyframes(path, &settings, odometry, pair_models)
        .map_err(|e| study_error(e, flags, pair_models))?;
    let cv = cross_validate_layouts(&data, &settings, &ProgressBar::new())
        .map_err(|e| study_error(e, flags, pair_models))?;
    Ok((data, cv))
}

/// `chronomap lidar eval`.
pub fn eval(args: &LidarEvalArgs) -> Result<()> {
    let (data, cv) = cross_validated(
        &args.keyframes,
        &args.training,
        args.odometry.as_deref(),
        true,
    )?;
    let pipeline =
        out_of_fold_pipeline(&data, &training(&args.training), &cv, &ProgressBar::new())?;
    let CvSummary {
        folds,
        auc,
        tpr,
        heldout_tpr: held_tpr,
        heldout_fpr: held_fpr,
        pooled_auc,
        pooled_tpr,
        p_min,
    } = CvSummary::of(&cv);
    let positives = data.positives();
    if let Some(path) = &args.plot {
        plot_eval(&data, &cv, &pipeline, args.training.max_fpr, path)?;
    }
    if args.json {
        return print_json(&json!({
            "keyframes": data.log.scans.len(),
            "loops": positives,
            "non_loops": data.pairs.len() - positives,
            "folds": folds,
            "layouts": args.training.layouts,
            "auc": auc, "tpr_at_max_fpr": tpr,
            "heldout_p_min_tpr": held_tpr, "heldout_p_min_fpr": held_fpr,
            "pooled_auc": pooled_auc, "pooled_tpr_at_max_fpr": pooled_tpr, "p_min": p_min,
            "max_fpr": args.training.max_fpr,
            "classifier": describe_config(&data.config),
            "pipeline": {
                "p_min": cv.first_threshold(),
                "loops": pipeline.detections.len(),
                "correct": pipeline.correct(),
                "wrong": pipeline.wrong(),
                "revisiting_keyframes": pipeline.queries_with_loop,
                "revisiting_keyframes_closed": pipeline.queries_closed,
                "detections": &pipeline.detections,
            },
            "pooled_roc": cv.reports.iter().map(|r| &r.pooled_roc).collect::<Vec<_>>(),
        }));
    }
    outln!(
        "{}: {} keyframes, {} loops (closer than {} m, more than {} keyframes apart), {} non-loops (farther than {} m)",
        data.log.name,
        data.log.scans.len(),
        positives,
        args.training.near,
        args.training.min_separation,
        data.pairs.len() - positives,
        args.training.far
    )?;
    outln!(
        "cross-validation: {} fold layouts × {} folds by place ({} folds with loops and non-loops to score); {}, T = {}",
        args.training.layouts,
        args.training.folds,
        folds,
        describe_config(&data.config),
        args.training.rounds
    )?;
    let pct = 100.0 * args.training.max_fpr;
    let mut table = Table::new(["measure", "mean ± sd"]).left(&[0]);
    table.row(["AUC (per fold)".to_string(), format!("{auc:.3}")]);
    table.row([
        format!("TPR at FPR < {pct} % (each fold's own threshold)"),
        format!("{tpr:.3}"),
    ]);
    table.row([
        "TPR with p_min chosen on the other folds".to_string(),
        format!("{held_tpr:.3}"),
    ]);
    table.row([
        "FPR with p_min chosen on the other folds".to_string(),
        format!("{held_fpr:.4}"),
    ]);
    table.row([
        "AUC (pooled over folds, per layout)".to_string(),
        format!("{pooled_auc:.3}"),
    ]);
    table.row([
        format!("TPR at FPR < {pct} % (pooled, per layout)"),
        format!("{pooled_tpr:.3}"),
    ]);
    table.row([
        "p_min (pooled, per layout)".to_string(),
        format!("{p_min:.4}"),
    ]);
    outln!("{}", table.render().trim_end())?;
    outln!(
        "loop detection along the keyframes (search radius, classifier, verification; fold layout 0, each pair scored by the model trained without both keyframes' folds, p_min {:.4}): {} loops, {} correct, {} wrong; {} of {} revisiting keyframes closed",
        cv.first_threshold().unwrap_or(f64::NAN),
        pipeline.detections.len(),
        pipeline.correct(),
        pipeline.wrong(),
        pipeline.queries_closed,
        pipeline.queries_with_loop
    )?;
    Ok(())
}

/// ROC curves (pooled, one per layout) beside the trajectory with its labelled loops.
fn plot_eval(
    data: &LabelledKeyframes,
    cv: &LayoutsReport,
    pipeline: &PipelineReport,
    max_fpr: f64,
    path: &Path,
) -> Result<()> {
    let mut roc_layers: Vec<PlaneLayer> = cv
        .reports
        .iter()
        .enumerate()
        .map(|(k, r)| PlaneLayer {
            label: if k == 0 {
                format!("pooled ROC, {} fold layouts", cv.reports.len())
            } else {
                String::new()
            },
            shape: PlaneShape::Path(r.pooled_roc.iter().map(|p| [p.fpr, p.tpr]).collect()),
        })
        .collect();
    // Every layout in the first colour: re-colour by putting them in one layer each would
    // cycle the palette, so the later ones are drawn as one layer of separate paths.
    let first = roc_layers.remove(0);
    let mut paths = match first.shape {
        PlaneShape::Path(p) => p,
        _ => Vec::new(),
    };
    for layer in roc_layers {
        if let PlaneShape::Path(p) = layer.shape {
            paths.push([f64::NAN, f64::NAN]);
            paths.extend(p);
        }
    }
    let roc = PlanePlot {
        title: "Loop classifier, keyframe-disjoint cross-validation".into(),
        x_label: "false-positive rate".into(),
        y_label: "true-positive rate".into(),
        equal_aspect: false,
        x_range: Some((0.0, 1.0)),
        y_range: Some((0.0, 1.0)),
        layers: vec![
            PlaneLayer {
                label: first.label,
                shape: PlaneShape::Path(paths),
            },
            PlaneLayer {
                label: "chance".into(),
                shape: PlaneShape::Path(vec![[0.0, 0.0], [1.0, 1.0]]),
            },
            PlaneLayer {
                label: format!("FPR = {} %", 100.0 * max_fpr),
                shape: PlaneShape::Path(vec![[max_fpr, 0.0], [max_fpr, 1.0]]),
            },
        ],
    };
    let truth = data.log.truth.as_deref().unwrap_or(&[]);
    let positions: Vec<[f64; 2]> = truth.iter().map(|p| [p[0], p[1]]).collect();
    let trajectory = detections_plot(
        &format!(
            "Loops found, each pair scored by a model that saw neither keyframe ({} keyframes)",
            positions.len()
        ),
        &positions,
        true,
        pipeline,
    );
    render_plane_png(&[roc, trajectory], path, 1600, 720)?;
    Ok(())
}

/// `chronomap lidar train`.
pub fn train(args: &LidarTrainArgs) -> Result<()> {
    let (data, cv) = cross_validated(&args.keyframes, &args.training, None, false)?;
    // p_min: the median over fold layouts of the threshold that keeps the pooled
    // out-of-fold false-positive rate below the bound.
    let classifier = train_classifier(&data, &cv, args.training.max_fpr)?;
    let p_min = classifier.p_min;
    let positives = classifier.trained_on.0;
    write_model_file(&args.output, MODEL_KIND, &classifier)?;
    let pooled_tpr = CvSummary::of(&cv).pooled_tpr;
    if args.json {
        return print_json(&json!({
            "output": args.output,
            "keyframes": data.log.scans.len(),
            "loops": positives,
            "non_loops": data.pairs.len() - positives,
            "rounds": classifier.model.rounds(),
            "classifier": describe_config(&classifier.config),
            "p_min": p_min,
            "max_fpr": args.training.max_fpr,
            "cv_tpr_at_max_fpr": pooled_tpr,
        }));
    }
    outln!(
        "{}: trained on {} loops and {} non-loops of {} keyframes ({}, T = {}); p_min = {:.4} keeps the out-of-fold false-positive rate below {} % (TPR there {:.3}); written to {}",
        data.log.name,
        positives,
        data.pairs.len() - positives,
        data.log.scans.len(),
        describe_config(&classifier.config),
        classifier.model.rounds(),
        p_min,
        100.0 * args.training.max_fpr,
        pooled_tpr,
        args.output.display()
    )?;
    Ok(())
}

/// `chronomap lidar detect`.
pub fn detect(args: &LidarDetectArgs) -> Result<()> {
    let (kind, classifier): (String, LoopClassifier) = read_model_file(&args.classifier)?;
    if kind != MODEL_KIND {
        return Err(anyhow!(
            "{}: holds a {kind}, not a loop classifier (chronomap lidar train writes one)",
            args.classifier.display()
        ));
    }
    classifier
        .validate()
        .with_context(|| format!("{}: invalid classifier", args.classifier.display()))?;
    let full = laser_log::read(&args.source)?;
    let log = if args.source.keyframes.is_some() {
        full
    } else {
        full.keyframes(args.keyframe_distance, args.keyframe_angle)
    };
    let has_truth = log.truth.is_some();
    let detection = detect_loops(&log, &classifier, args.p_min, args.min_separation)?;
    let (report, positions) = (&detection.report, &detection.positions);
    if let Some(path) = &args.output {
        let mut csv = String::from("query,target,probability,radius_m,mode\n");
        for d in &report.detections {
            csv.push_str(&format!(
                "{},{},{},{},{:?}\n",
                d.query, d.target, d.probability, d.radius, d.mode
            ));
        }
        write_data_file(path, csv.as_bytes())?;
    }
    if let Some(path) = &args.plot {
        plot_detections(&log, positions, has_truth, report, path)?;
    }
    if args.json {
        return print_json(&json!({
            "log": log.name,
            "keyframes": log.scans.len(),
            "p_min": detection.p_min,
            "detections": report.detections.iter().map(|d| json!({
                "query": d.query, "target": d.target, "probability": d.probability,
                "radius_m": d.radius, "mode": d.mode, "candidates": d.candidates,
                "true_distance_m": if has_truth { Some(d.true_distance) } else { None },
                "correct": if has_truth { Some(d.correct) } else { None },
            })).collect::<Vec<_>>(),
            "scored_pairs": report.scored_pairs,
            "rejected_by_verification": report.rejected_by_verification,
            "true_loop_pairs": if has_truth { Some(report.true_pairs) } else { None },
            "true_loop_pairs_in_search_space": if has_truth { Some(report.true_pairs_in_space) } else { None },
        }));
    }
    outln!(
        "{}: {} keyframes, {} pairs scored within the search radius (eq. 3.8), p_min = {:.4}: {} loop(s), {} rejected by verification",
        log.name,
        log.scans.len(),
        report.scored_pairs,
        detection.p_min,
        report.detections.len(),
        report.rejected_by_verification
    )?;
    if has_truth {
        outln!(
            "against the SLAM poses: {} correct, {} wrong; {} true loop pairs, {} of them inside the search radius when their second keyframe came",
            report.correct(),
            report.wrong(),
            report.true_pairs,
            report.true_pairs_in_space
        )?;
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
                if has_truth {
                    format!("{:.2}", d.true_distance)
                } else {
                    "-".into()
                },
            ]);
        }
        outln!("{}", table.render().trim_end())?;
    }
    Ok(())
}

/// The trajectory (SLAM poses when known, else odometry) with the loops found.
fn plot_detections(
    log: &laser_log::LaserLog,
    positions: &[[f64; 2]],
    has_truth: bool,
    report: &PipelineReport,
    path: &Path,
) -> Result<()> {
    let plot = detections_plot(
        &format!("Loops found along {}", super::maps::short_name(&log.name)),
        positions,
        has_truth,
        report,
    );
    render_plane_png(&[plot], path, 1000, 800)?;
    Ok(())
}

/// A trajectory with its keyframes and the loops a pipeline accepted (correct and wrong ones
/// apart when the positions are the truth).
fn detections_plot(
    title: &str,
    positions: &[[f64; 2]],
    has_truth: bool,
    report: &PipelineReport,
) -> PlanePlot {
    let segment =
        |d: &&chronomap_lidar::evaluation::Detection| [positions[d.query], positions[d.target]];
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
    ];
    let (right, wrong): (Vec<_>, Vec<_>) = report
        .detections
        .iter()
        .partition(|d| !has_truth || d.correct);
    layers.push(PlaneLayer {
        label: format!(
            "{} loops{}",
            right.len(),
            if has_truth { " (correct)" } else { "" }
        ),
        shape: PlaneShape::Segments(right.iter().map(segment).collect()),
    });
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

/// One line naming a classifier configuration.
fn describe_config(config: &ClassifierConfig) -> String {
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
