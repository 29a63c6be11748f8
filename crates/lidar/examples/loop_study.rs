//! The loop-classifier study of `docs/lidar.md` on the Málaga 2006 keyframes: every
//! configuration (training pairs × pair features × weak learner × balancing, `T = 50`) under
//! the same keyframe-disjoint folds, and nested cross-validation that *chooses* the
//! configuration and `T` on the training folds only (paper features only, and all).
//!
//! ```text
//! cargo run --release -p chronomap-lidar --example loop_study [-- layouts]
//! ```

use chronomap_io::laser_text::read_keyframes;
use chronomap_lidar::descriptor::{DescriptorParams, compare, describe_scan};
use chronomap_lidar::evaluation::{
    Balance, Candidate, LabelParams, LabelledPair, NestedParams, WeakLearner, label_pairs,
    nested_cross_validate, sector_folds,
};
use chronomap_lidar::profile::{ProfileParams, compare_extended, range_profile};
use chronomap_lidar::threshold::MeanSd;

const FOLDS: usize = 5;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let layouts: u64 = std::env::args()
        .nth(1)
        .map(|a| a.parse())
        .transpose()?
        .unwrap_or(10);
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/malaga_laser_2006");
    let keyframes = read_keyframes(dir.join("keyframes_slam.txt.xz"))?;
    let dp = DescriptorParams::default();
    let pp = ProfileParams::default();
    let desc = keyframes
        .iter()
        .map(|k| describe_scan(&k.scan.scan, &dp))
        .collect::<Result<Vec<_>, _>>()?;
    let prof = keyframes
        .iter()
        .map(|k| range_profile(&k.scan.scan, &pp))
        .collect::<Result<Vec<_>, _>>()?;
    let robot: Vec<[f64; 2]> = keyframes.iter().map(|k| [k.pose[0], k.pose[1]]).collect();
    let sensor: Vec<[f64; 2]> = keyframes
        .iter()
        .map(|k| {
            let p = k.sensor_pose();
            [p[0], p[1]]
        })
        .collect();
    let score_pairs = label_pairs(&robot, &LabelParams::default())?;
    let near = |near: f64| LabelParams {
        near,
        far: 10.0,
        min_separation: 0,
    };
    let train_sets: Vec<(&str, Vec<LabelledPair>)> = vec![
        ("revisits<3m", score_pairs.clone()),
        ("all<3m", label_pairs(&robot, &near(3.0))?),
        ("all<1.5m", label_pairs(&robot, &near(1.5))?),
    ];
    let paper = |p: &LabelledPair| compare(&desc[p.i], &desc[p.j]).map(|a| a.to_vec());
    let ext = |p: &LabelledPair| {
        compare_extended((&desc[p.i], &prof[p.i]), (&desc[p.j], &prof[p.j]), &pp)
            .map(|a| a.to_vec())
    };
    type Rows = Vec<Vec<f64>>;
    let rows = |pairs: &[LabelledPair], f: &dyn Fn(&LabelledPair) -> Result<Vec<f64>, _>| {
        pairs
            .iter()
            .map(f)
            .collect::<Result<Rows, chronomap_lidar::DescriptorError>>()
    };
    let score_x = [rows(&score_pairs, &paper)?, rows(&score_pairs, &ext)?];
    let train_x: Vec<[Rows; 2]> = train_sets
        .iter()
        .map(|(_, p)| Ok([rows(p, &paper)?, rows(p, &ext)?]))
        .collect::<Result<_, chronomap_lidar::DescriptorError>>()?;
    for (name, p) in &train_sets {
        println!(
            "training set {name}: {} positives, {} negatives",
            p.iter().filter(|p| p.positive).count(),
            p.iter().filter(|p| !p.positive).count()
        );
    }
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
    // Each configuration alone at T = 50, then nested selection.
    let fixed = NestedParams {
        rounds: vec![50],
        ..NestedParams::default()
    };
    let mut runs: Vec<(&str, Vec<usize>)> = (0..candidates.len()).map(|c| ("", vec![c])).collect();
    runs.push((
        "nested: paper features, stumps, chooses train set/balance/T",
        {
            (0..candidates.len())
                .filter(|&c| {
                    candidates[c].name.contains("paper41")
                        && candidates[c].learner == WeakLearner::Stump
                })
                .collect()
        },
    ));
    runs.push(("nested: everything", (0..candidates.len()).collect()));
    for (label, set) in &runs {
        let cs: Vec<Candidate<'_, Vec<f64>>> = set.iter().map(|&c| candidates[c].clone()).collect();
        let (mut auc, mut tpr, mut held) = (vec![], vec![], vec![]);
        let mut picks: Vec<String> = Vec::new();
        for layout in 0..layouts {
            let width = std::f64::consts::TAU / (2 * FOLDS) as f64;
            let fold_of = sector_folds(&sensor, FOLDS, width * layout as f64 / layouts as f64)?;
            let params = if cs.len() == 1 {
                NestedParams {
                    seed: layout + 1,
                    ..fixed.clone()
                }
            } else {
                NestedParams {
                    seed: layout + 1,
                    ..NestedParams::default()
                }
            };
            let r = nested_cross_validate(&score_pairs, &cs, &fold_of, &params)?;
            auc.push(r.report.pooled_auc);
            tpr.push(r.report.pooled_at_max_fpr.tpr);
            held.extend(r.report.folds.iter().map(|f| f.heldout_rates.0));
            if cs.len() > 1 {
                picks.extend(
                    r.chosen
                        .iter()
                        .map(|c| format!("{} T={}", cs[c.candidate].name, c.rounds)),
                );
            }
        }
        let name = if label.is_empty() {
            cs[0].name.clone()
        } else {
            label.to_string()
        };
        println!(
            "{name:<48} pooled AUC {:.3}  pooled TPR@1% {:.3}  held-out TPR {:.3}",
            MeanSd::of(auc.iter().copied()),
            MeanSd::of(tpr.iter().copied()),
            MeanSd::of(held.iter().copied())
        );
        if !picks.is_empty() {
            picks.sort();
            let mut counts: Vec<(String, usize)> = Vec::new();
            for p in picks {
                match counts.last_mut() {
                    Some((q, n)) if *q == p => *n += 1,
                    _ => counts.push((p, 1)),
                }
            }
            counts.sort_by_key(|c| std::cmp::Reverse(c.1));
            for (p, n) in counts.iter().take(6) {
                println!("    chosen {n:>3}x  {p}");
            }
        }
    }
    Ok(())
}
