//! Loop classification on the real Málaga 2006 keyframes (`data/malaga_laser_2006/`): the
//! labelled pairs the README states, a keyframe-disjoint cross-validation whose classifier
//! ranks loops above non-loops clearly better than chance, and a trained classifier that
//! survives a model file.

use chronomap_io::laser_text::read_keyframes;
use chronomap_io::{decode_model, encode_model};
use chronomap_lidar::adaboost::{AdaBoost, AdaBoostParams, MODEL_KIND};
use chronomap_lidar::descriptor::{DescriptorParams, PAIR_FEATURES, compare, describe_scan};
use chronomap_lidar::evaluation::{
    CvParams, LabelParams, cross_validate, label_pairs, sector_folds,
};

#[test]
fn malaga_keyframes_cross_validate_above_chance() {
    let keyframes = read_keyframes(chronomap_testutil::data_path(
        "malaga_laser_2006/keyframes_slam.txt.xz",
    ))
    .unwrap();
    assert_eq!(keyframes.len(), 99);
    let params = DescriptorParams::default();
    let d: Vec<_> = keyframes
        .iter()
        .map(|k| describe_scan(&k.scan.scan, &params).unwrap())
        .collect();
    let robot: Vec<[f64; 2]> = keyframes.iter().map(|k| [k.pose[0], k.pose[1]]).collect();
    let pairs = label_pairs(&robot, &LabelParams::default()).unwrap();
    // The README's count: 184 pairs closer than 3 m and more than 20 keyframes apart.
    assert_eq!(pairs.iter().filter(|p| p.positive).count(), 184);
    assert_eq!(pairs.iter().filter(|p| !p.positive).count(), 2847);
    let x: Vec<[f64; PAIR_FEATURES]> = pairs
        .iter()
        .map(|p| compare(&d[p.i], &d[p.j]).unwrap())
        .collect();
    let sensor: Vec<[f64; 2]> = keyframes
        .iter()
        .map(|k| {
            let p = k.sensor_pose();
            [p[0], p[1]]
        })
        .collect();
    let fold_of = sector_folds(&sensor, 5, 0.0).unwrap();
    let cv = cross_validate(&pairs, &x, &fold_of, &CvParams::default()).unwrap();
    // No scored pair has a keyframe in its model's training folds.
    for s in &cv.scored {
        assert_eq!(fold_of[s.pair.i], s.fold);
        assert_eq!(fold_of[s.pair.j], s.fold);
    }
    // Clearly better than chance (0.5), far from perfect on 99 keyframes (docs/lidar.md).
    assert!(
        cv.pooled_auc > 0.6 && cv.pooled_auc < 0.95,
        "AUC {}",
        cv.pooled_auc
    );
    assert!(cv.pooled_at_max_fpr.fpr < 0.01);

    // A classifier on all pairs, through a model file and back.
    let model = AdaBoost::fit(
        &x,
        &pairs.iter().map(|p| p.positive).collect::<Vec<_>>(),
        None,
        &AdaBoostParams::default(),
    )
    .unwrap();
    let bytes = encode_model(MODEL_KIND, &model).unwrap();
    let (kind, back): (String, AdaBoost) = decode_model(&bytes).unwrap();
    assert_eq!(kind, MODEL_KIND);
    back.validate().unwrap();
    assert_eq!(back, model);
    assert_eq!(back.stumps.len(), 50);
}
