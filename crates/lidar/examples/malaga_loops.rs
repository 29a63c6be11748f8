//! Loop classification ([Stüde 2024] §3.2.1) on the Málaga 2006 keyframes: descriptors of the
//! 99 keyframe scans, labelled pairs, keyframe-disjoint cross-validation over several fold
//! layouts and seeds (TPR at FPR < 1 %, AUC), and the whole pipeline (search radius,
//! classifier, verification) along the loop, in one session and as a second session that
//! must find the first by a global search.
//!
//! ```text
//! cargo run --release -p chronomap-lidar --example malaga_loops [-- --json out.json]
//! ```
//!
//! Then the extended classifier (`docs/lidar.md`): the configuration — training pairs, paper or
//! extended pair features, stumps or depth-2 trees, balancing, `T` — chosen by cross-validation
//! over the keyframes, its cross-validation over the same layouts (optimistic: chosen on these
//! folds; `examples/loop_study.rs` gives the nested, honest estimate) and the pipeline with it.
//!
//! With `--json` it writes the pooled ROC points, the per-fold ROC points of the first layout
//! and the detected loops for a plotting front end.

use chronomap_io::laser_text::{read_keyframes, read_odometry};
use chronomap_lidar::descriptor::{DescriptorParams, PAIR_FEATURES, compare, describe_scan};
use chronomap_lidar::evaluation::{
    Balance, Candidate, CvParams, EvalError, LabelParams, LabelledPair, LoopModel, NestedParams,
    PairModels, PipelineParams, PipelineReport, WeakLearner, cross_validate, keyframe_increments,
    label_pairs, nested_cross_validate, run_pipeline, sector_folds, select_candidate,
};
use chronomap_lidar::profile::{ProfileParams, compare_extended, range_profile};
use chronomap_lidar::threshold::MeanSd;

const FOLDS: usize = 5;
const LAYOUTS: u64 = 10;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let json_out = args
        .iter()
        .position(|a| a == "--json")
        .and_then(|k| args.get(k + 1));
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/malaga_laser_2006");
    let keyframes = read_keyframes(dir.join("keyframes_slam.txt.xz"))?;
    let odometry = read_odometry(dir.join("odometry.txt.xz"))?;
    let params = DescriptorParams::default();
    let descriptors = keyframes
        .iter()
        .map(|k| describe_scan(&k.scan.scan, &params))
        .collect::<Result<Vec<_>, _>>()?;
    let robot: Vec<[f64; 2]> = keyframes.iter().map(|k| [k.pose[0], k.pose[1]]).collect();
    let sensor: Vec<[f64; 2]> = keyframes
        .iter()
        .map(|k| {
            let p = k.sensor_pose();
            [p[0], p[1]]
        })
        .collect();
    let labels = LabelParams::default();
    let pairs = label_pairs(&robot, &labels)?;
    let positives = pairs.iter().filter(|p| p.positive).count();
    let sensor_positives = label_pairs(&sensor, &labels)?
        .iter()
        .filter(|p| p.positive)
        .count();
    let all = keyframes.len() * (keyframes.len() - 1) / 2;
    println!(
        "Málaga 2006: {} keyframes, {all} pairs: {positives} loops (robot poses < {} m, > {} keyframes apart; {sensor_positives} by sensor poses), {} non-loops (> {} m), {} ambiguous left out",
        keyframes.len(),
        labels.near,
        labels.min_separation,
        pairs.len() - positives,
        labels.far,
        all - pairs.len()
    );
    let x: Vec<[f64; PAIR_FEATURES]> = pairs
        .iter()
        .map(|p| compare(&descriptors[p.i], &descriptors[p.j]))
        .collect::<Result<_, _>>()?;

    // Cross-validation over fold layouts (rotated sectors) and seeds (balanced subsets).
    let (mut tpr, mut auc, mut held_tpr, mut held_fpr, mut pooled_tpr, mut pooled_auc, mut p_min) =
        (vec![], vec![], vec![], vec![], vec![], vec![], vec![]);
    let mut first = None;
    for layout in 0..LAYOUTS {
        let width = std::f64::consts::TAU / (2 * FOLDS) as f64;
        let rotation = width * layout as f64 / LAYOUTS as f64;
        let fold_of = sector_folds(&sensor, FOLDS, rotation)?;
        let cv = cross_validate(
            &pairs,
            &x,
            &fold_of,
            &CvParams {
                seed: layout + 1,
                ..CvParams::default()
            },
        )?;
        for f in &cv.folds {
            tpr.push(f.at_max_fpr.tpr);
            auc.push(f.auc);
            held_tpr.push(f.heldout_rates.0);
            held_fpr.push(f.heldout_rates.1);
        }
        pooled_tpr.push(cv.pooled_at_max_fpr.tpr);
        pooled_auc.push(cv.pooled_auc);
        p_min.push(cv.pooled_at_max_fpr.threshold);
        if layout == 0 {
            println!("\nlayout 0 (sectors from 0 rad), seed 1: per fold");
            println!(
                "fold  train +/-   test +/-   AUC    TPR@FPR<1%  p_min   held-out p_min  TPR    FPR"
            );
            for f in &cv.folds {
                println!(
                    "{:>4}  {:>4}/{:<4}  {:>4}/{:<4}  {:.3}  {:>9.3}  {:.4}  {:>14.4}  {:.3}  {:.3}",
                    f.fold,
                    f.trained_on.0,
                    f.trained_on.1,
                    f.tested_on.0,
                    f.tested_on.1,
                    f.auc,
                    f.at_max_fpr.tpr,
                    f.at_max_fpr.threshold,
                    f.heldout_threshold,
                    f.heldout_rates.0,
                    f.heldout_rates.1
                );
            }
            first = Some((cv, fold_of));
        }
    }
    println!(
        "\n{LAYOUTS} fold layouts x {FOLDS} folds (mean ± sd over the {} folds):",
        tpr.len()
    );
    println!(
        "  AUC                                {:.3}",
        MeanSd::of(auc)
    );
    println!(
        "  TPR at FPR < 1 % (own threshold)   {:.3}",
        MeanSd::of(tpr)
    );
    println!(
        "  held-out p_min: TPR                {:.3}",
        MeanSd::of(held_tpr)
    );
    println!(
        "  held-out p_min: FPR                {:.4}",
        MeanSd::of(held_fpr)
    );
    println!("pooled over folds (mean ± sd over the {LAYOUTS} layouts):");
    println!(
        "  AUC                                {:.3}",
        MeanSd::of(pooled_auc)
    );
    println!(
        "  TPR at FPR < 1 %                   {:.3}",
        MeanSd::of(pooled_tpr)
    );
    println!(
        "  p_min                              {:.4}",
        MeanSd::of(p_min.clone())
    );

    // The pipeline: models that never saw the keyframes of the pair they score.
    let (cv, fold_of) = first.expect("layout 0 ran");
    let models = PairModels::train(
        &pairs,
        &x,
        &fold_of,
        &CvParams {
            seed: 1,
            ..CvParams::default()
        },
    )?;
    let times: Vec<f64> = keyframes.iter().map(|k| k.scan.scan.time).collect();
    let odo: Vec<(f64, [f64; 3])> = odometry
        .iter()
        .map(|o| (o.time, [o.dx, o.dy, o.dyaw]))
        .collect();
    let increments = keyframe_increments(&odo, &times);
    let s = keyframes[0].scan.sensor;
    let mut pipeline = PipelineParams::default();
    pipeline.search.p_min = cv.pooled_at_max_fpr.threshold;
    let score = |i: usize, j: usize| {
        let f = compare(&descriptors[i], &descriptors[j])
            .map_err(|e| chronomap_lidar::evaluation::EvalError::Input(e.to_string()))?;
        models.probability(i, j, &f)
    };
    let single = run_pipeline(&increments, [s.x, s.y], &robot, &pipeline, score)?;
    print_pipeline("one session", &single, pipeline.search.p_min, 50);
    let wake = PipelineParams {
        session_start: 60,
        ..pipeline.clone()
    };
    let second = run_pipeline(&increments, [s.x, s.y], &robot, &wake, score)?;
    print_pipeline(
        "keyframes 60-98 as a second session (global search until linked)",
        &second,
        pipeline.search.p_min,
        50,
    );

    // The extended classifier: choose the configuration by cross-validation over all
    // keyframes (layout 0), then measure it over the layouts and run the pipeline with it.
    let pp = ProfileParams::default();
    let profiles = keyframes
        .iter()
        .map(|k| range_profile(&k.scan.scan, &pp))
        .collect::<Result<Vec<_>, _>>()?;
    let near = |near: f64| LabelParams {
        near,
        far: labels.far,
        min_separation: 0,
    };
    let train_sets: Vec<(&str, Vec<LabelledPair>)> = vec![
        ("revisits<3m", pairs.clone()),
        ("all<3m", label_pairs(&robot, &near(3.0))?),
        ("all<1.5m", label_pairs(&robot, &near(1.5))?),
    ];
    let extended = |i: usize, j: usize| {
        compare_extended(
            (&descriptors[i], &profiles[i]),
            (&descriptors[j], &profiles[j]),
            &pp,
        )
        .map(|a| a.to_vec())
        .map_err(|e| EvalError::Input(e.to_string()))
    };
    let paper = |i: usize, j: usize| {
        compare(&descriptors[i], &descriptors[j])
            .map(|a| a.to_vec())
            .map_err(|e| EvalError::Input(e.to_string()))
    };
    let rows = |ps: &[LabelledPair], ext: bool| -> Result<Vec<Vec<f64>>, EvalError> {
        ps.iter()
            .map(|p| {
                if ext {
                    extended(p.i, p.j)
                } else {
                    paper(p.i, p.j)
                }
            })
            .collect()
    };
    let score_x = [rows(&pairs, false)?, rows(&pairs, true)?];
    let train_x: Vec<[Vec<Vec<f64>>; 2]> = train_sets
        .iter()
        .map(|(_, ps)| Ok([rows(ps, false)?, rows(ps, true)?]))
        .collect::<Result<_, EvalError>>()?;
    let mut candidates = Vec::new();
    for (ti, (tname, tp)) in train_sets.iter().enumerate() {
        for (fi, fname) in ["paper41", "ext44"].iter().enumerate() {
            for learner in [WeakLearner::Stump, WeakLearner::Depth2] {
                for balance in [Balance::Subsample, Balance::Weighted] {
                    candidates.push(Candidate {
                        name: format!("{tname} {fname} {learner:?} {balance:?}"),
                        train_pairs: tp,
                        train_x: &train_x[ti][fi],
                        score_x: &score_x[fi],
                        learner,
                        balance,
                    });
                }
            }
        }
    }
    let nested = NestedParams::default();
    let choice = select_candidate(&pairs, &candidates, &fold_of, None, &nested)?;
    let chosen = candidates[choice.candidate].clone();
    println!(
        "\nextended: chosen by CV over all keyframes (layout 0) among {} configurations x T in {:?}: {} T = {} (inner TPR {:.3}, AUC {:.3})",
        candidates.len(),
        nested.rounds,
        chosen.name,
        choice.rounds,
        choice.inner.0,
        choice.inner.1
    );
    let fixed = NestedParams {
        rounds: vec![choice.rounds],
        ..nested.clone()
    };
    let (mut e_auc, mut e_tpr, mut e_held, mut e_held_fpr, mut e_pauc, mut e_ptpr) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    let mut e_first = None;
    for layout in 0..LAYOUTS {
        let width = std::f64::consts::TAU / (2 * FOLDS) as f64;
        let folds = sector_folds(&sensor, FOLDS, width * layout as f64 / LAYOUTS as f64)?;
        let r = nested_cross_validate(
            &pairs,
            std::slice::from_ref(&chosen),
            &folds,
            &NestedParams {
                seed: layout + 1,
                ..fixed.clone()
            },
        )?;
        for f in &r.report.folds {
            e_auc.push(f.auc);
            e_tpr.push(f.at_max_fpr.tpr);
            e_held.push(f.heldout_rates.0);
            e_held_fpr.push(f.heldout_rates.1);
        }
        e_pauc.push(r.report.pooled_auc);
        e_ptpr.push(r.report.pooled_at_max_fpr.tpr);
        if layout == 0 {
            e_first = Some(r.report);
        }
    }
    println!(
        "{LAYOUTS} fold layouts x {FOLDS} folds (mean ± sd over the {} folds):",
        e_auc.len()
    );
    println!(
        "  AUC                                {:.3}",
        MeanSd::of(e_auc)
    );
    println!(
        "  TPR at FPR < 1 % (own threshold)   {:.3}",
        MeanSd::of(e_tpr)
    );
    println!(
        "  held-out p_min: TPR                {:.3}",
        MeanSd::of(e_held)
    );
    println!(
        "  held-out p_min: FPR                {:.4}",
        MeanSd::of(e_held_fpr)
    );
    println!("pooled over folds (mean ± sd over the {LAYOUTS} layouts):");
    println!(
        "  AUC                                {:.3}",
        MeanSd::of(e_pauc)
    );
    println!(
        "  TPR at FPR < 1 %                   {:.3}",
        MeanSd::of(e_ptpr)
    );
    let e_first = e_first.expect("layout 0 ran");
    // Pipeline: one model per pair of folds, trained without both.
    let mut e_models: Vec<Option<LoopModel>> = vec![None; FOLDS * FOLDS];
    for a in 0..FOLDS {
        for b in a..FOLDS {
            let keep = |p: &LabelledPair| {
                ![a, b].contains(&fold_of[p.i]) && ![a, b].contains(&fold_of[p.j])
            };
            e_models[a * FOLDS + b] = LoopModel::train(
                chosen.train_pairs,
                chosen.train_x,
                keep,
                chosen.learner,
                chosen.balance,
                choice.rounds,
                (a * FOLDS + b) as u64 + 1,
            )
            .ok();
        }
    }
    let ext_index = chosen.name.contains("ext44");
    let e_score = |i: usize, j: usize| -> Result<Option<f64>, EvalError> {
        let (a, b) = (fold_of[i].min(fold_of[j]), fold_of[i].max(fold_of[j]));
        let Some(m) = &e_models[a * FOLDS + b] else {
            return Ok(None);
        };
        let f = if ext_index {
            extended(i, j)?
        } else {
            paper(i, j)?
        };
        m.probability(&f).map(Some)
    };
    let mut e_pipeline = pipeline.clone();
    e_pipeline.search.p_min = e_first.pooled_at_max_fpr.threshold;
    let e_single = run_pipeline(&increments, [s.x, s.y], &robot, &e_pipeline, e_score)?;
    print_pipeline(
        &format!("extended, one session ({})", chosen.name),
        &e_single,
        e_pipeline.search.p_min,
        choice.rounds,
    );
    let e_wake = PipelineParams {
        session_start: 60,
        ..e_pipeline.clone()
    };
    let e_second = run_pipeline(&increments, [s.x, s.y], &robot, &e_wake, e_score)?;
    print_pipeline(
        "extended, keyframes 60-98 as a second session",
        &e_second,
        e_pipeline.search.p_min,
        choice.rounds,
    );

    if let Some(path) = json_out {
        let out = serde_json::json!({
            "pooled_roc_layout0": cv.pooled_roc,
            "folds_layout0": cv.folds,
            "scored_layout0": cv.scored,
            "pipeline_one_session": single,
            "pipeline_two_sessions": second,
            "extended_choice": chosen.name,
            "extended_rounds": choice.rounds,
            "extended_pooled_roc_layout0": e_first.pooled_roc,
            "extended_pipeline_one_session": e_single,
            "extended_pipeline_two_sessions": e_second,
        });
        std::fs::write(path, serde_json::to_string(&out)?)?;
        println!("\nwrote {path}");
    }
    Ok(())
}

fn print_pipeline(name: &str, r: &PipelineReport, p_min: f64, rounds: usize) {
    let radii: Vec<f64> = r.radii.iter().copied().filter(|v| v.is_finite()).collect();
    println!("\npipeline, {name}: p_min = {p_min:.4}, T = {rounds}");
    println!(
        "  keyframes with a true loop partner: {}; partner in the search space: {}; closed by a correct loop: {}",
        r.queries_with_loop, r.queries_with_loop_in_space, r.queries_closed
    );
    println!(
        "  true loop pairs: {}; in the search space: {}; pairs scored: {}",
        r.true_pairs, r.true_pairs_in_space, r.scored_pairs
    );
    println!(
        "  accepted loops: {} correct, {} wrong; {} rejected by verification; radius {:.2} m (max {:.2} m, {} global searches)",
        r.correct(),
        r.wrong(),
        r.rejected_by_verification,
        MeanSd::of(radii.iter().copied()),
        radii.iter().copied().fold(0.0, f64::max),
        r.radii.len() - radii.len()
    );
    for d in &r.detections {
        println!(
            "    {:>2} -> {:>2}  p = {:.3}  {:?} r = {:.2}  {} candidates  true distance {:.2} m  {}",
            d.query,
            d.target,
            d.probability,
            d.mode,
            d.radius,
            d.candidates,
            d.true_distance,
            if d.correct { "ok" } else { "WRONG" }
        );
    }
}
