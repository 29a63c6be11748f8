//! Known-answer tests of the registration pieces, and the real pairs.

#![allow(clippy::needless_range_loop)]

mod malaga_data;

use chronomap_registration::features::{BINS, FEATURE_LEN};
use chronomap_registration::{
    Cloud, Filters, IcpMethod, IcpParams, KdTree, RansacParams, RegistrationError,
    RegistrationParams, Rigid, estimate_normals, fpfh, icp, information, kabsch, ransac, register,
    register_scans, scan_params,
};
use chronomap_rng::Xoshiro256StarStar;

/// A closed box of 2 × 1.5 × 1 m with a tilted plate inside, 3,200 points drawn uniformly on
/// its faces (seeded): planes in every direction constrain every ICP variant, and random
/// sampling leaves no ties between neighbour distances or eigenvalues that would make the
/// neighbourhoods or normals depend on rounding.
fn box_cloud() -> Vec<[f64; 3]> {
    let mut rng = Xoshiro256StarStar::seed_from_u64(11);
    let mut pts = Vec::new();
    for _ in 0..3000 {
        let (u, v) = (rng.uniform(0.0, 1.0), rng.uniform(0.0, 1.0));
        // Faces by area: 2×1.5 (×2), 2×1 (×2), 1.5×1 (×2); total 13 m².
        let a = rng.uniform(0.0, 13.0);
        pts.push(match a {
            a if a < 3.0 => [2.0 * u, 1.5 * v, 0.0],
            a if a < 6.0 => [2.0 * u, 1.5 * v, 1.0],
            a if a < 8.0 => [2.0 * u, 0.0, v],
            a if a < 10.0 => [2.0 * u, 1.5, v],
            a if a < 11.5 => [0.0, 1.5 * u, v],
            _ => [2.0, 1.5 * u, v],
        });
    }
    for _ in 0..200 {
        let (u, v) = (rng.uniform(0.0, 0.5), rng.uniform(0.0, 0.5));
        pts.push([0.6 + u, 0.4 + v, 0.3 + 0.5 * u]);
    }
    pts
}

fn close(a: &Rigid<3>, b: &Rigid<3>, rot_deg: f64, trans: f64) -> bool {
    let (r, t) = a.error_to(b);
    r.to_degrees() < rot_deg && t < trans
}

#[test]
fn kabsch_recovers_a_hand_made_rotation() {
    // 90° about z, then (1, 2, 3): x ↦ y, y ↦ −x.
    let source = [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
    ];
    let target: Vec<[f64; 3]> = source
        .iter()
        .map(|p| [1.0 - p[1], 2.0 + p[0], 3.0 + p[2]])
        .collect();
    let t = kabsch(&source, &target).unwrap();
    let expected = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
    for i in 0..3 {
        for j in 0..3 {
            assert!(
                (t.rotation[i][j] - expected[i][j]).abs() < 1e-12,
                "{:?}",
                t.rotation
            );
        }
        assert!((t.translation[i] - [1.0, 2.0, 3.0][i]).abs() < 1e-12);
    }
    // Exactly three points (a rank-2 cross-covariance) still determine it.
    assert!(close(
        &kabsch(&source[..3], &target[..3]).unwrap(),
        &t,
        1e-9,
        1e-12
    ));
    // 2-D: 30° and (0.5, −1).
    let truth = Rigid::from_pose(0.5, -1.0, 30f64.to_radians());
    let s2 = [[0.0, 0.0], [2.0, 0.0], [1.0, 3.0]];
    let t2: Vec<[f64; 2]> = s2.iter().map(|p| truth.apply(p)).collect();
    let fit = kabsch(&s2, &t2).unwrap().to_pose();
    assert!((fit[2] - 30f64.to_radians()).abs() < 1e-12 && (fit[0] - 0.5).abs() < 1e-12);
    // A mirror image is fitted by the best rotation, never by a reflection.
    let mirrored: Vec<[f64; 3]> = source.iter().map(|p| [-p[0], p[1], p[2]]).collect();
    assert!(kabsch(&source, &mirrored).unwrap().is_valid());
    // Collinear points do not determine a rotation about their line.
    let line = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
    assert!(matches!(
        kabsch(&line, &line).map_err(RegistrationError::from),
        Err(RegistrationError::Degenerate(_))
    ));
}

#[test]
fn icp_converges_from_a_known_perturbation() {
    let target = box_cloud();
    // The source is the target moved by the inverse of a 4° / 8 cm motion.
    let motion = Rigid::<3>::identity()
        .compose(&rotation_about([0.3, -0.5, 0.8], 4f64.to_radians()))
        .compose(&Rigid {
            rotation: Rigid::<3>::identity().rotation,
            translation: [0.05, -0.04, 0.045],
        });
    let source: Vec<[f64; 3]> = target.iter().map(|p| motion.inverse().apply(p)).collect();
    let tree = KdTree::new(&target);
    let normals = estimate_normals(&target, &tree, 12, 0.15, [1.0, 0.75, 0.5]).unwrap();
    let src_normals =
        estimate_normals(&source, &KdTree::new(&source), 12, 0.15, [1.0, 0.75, 0.5]).unwrap();
    for method in [
        IcpMethod::PointToPoint,
        IcpMethod::PointToPlane,
        IcpMethod::Symmetric,
    ] {
        let params = IcpParams {
            method,
            max_iterations: 100,
            ..IcpParams::point_to_plane(0.3)
        };
        let result = icp(
            &source,
            Some(&src_normals),
            &target,
            &tree,
            Some(&normals),
            Rigid::identity(),
            &params,
        )
        .unwrap();
        assert!(result.converged, "{method:?}");
        assert!(
            close(&result.transform, &motion, 1e-3, 1e-4),
            "{method:?}: {:?}",
            result.transform.error_to(&motion)
        );
        assert!(
            result.rmse < 1e-4 && result.fitness > 0.99,
            "{method:?}: {result:?}"
        );
        // Ω = I/σ̂² with σ̂ at its floor: the residuals vanish.
        let info = information(&source, &tree, &result.transform, 0.1, 1e-4).unwrap();
        assert_eq!((info.sigma, info.dof), (1e-4, 6));
    }
    // 2-D point-to-line on a room outline.
    let room: Vec<[f64; 2]> = (0..400)
        .map(|i| {
            let s = f64::from(i % 100) * 0.04;
            match i / 100 {
                0 => [s, 0.0],
                1 => [4.0, 0.75 * s],
                2 => [s, 3.0],
                _ => [0.0, 0.75 * s],
            }
        })
        .chain((0..30).map(|k| {
            [
                1.0 + 0.5 * (f64::from(k) * 0.2).cos(),
                1.5 + 0.5 * (f64::from(k) * 0.2).sin(),
            ]
        }))
        .collect();
    let motion2 = Rigid::from_pose(0.1, -0.07, 3f64.to_radians());
    let source2: Vec<[f64; 2]> = room.iter().map(|p| motion2.inverse().apply(p)).collect();
    let tree2 = KdTree::new(&room);
    let normals2 = estimate_normals(&room, &tree2, 6, 0.2, [2.0, 1.5]).unwrap();
    let result = icp(
        &source2,
        None,
        &room,
        &tree2,
        Some(&normals2),
        Rigid::identity(),
        &IcpParams::point_to_plane(0.5),
    )
    .unwrap();
    let (r, t) = result.transform.error_to(&motion2);
    assert!(r.to_degrees() < 1e-3 && t < 1e-4, "{r} {t}");
}

/// The rotation by `angle` about `axis`.
fn rotation_about(axis: [f64; 3], angle: f64) -> Rigid<3> {
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let k = axis.map(|a| a / n);
    let (s, c) = angle.sin_cos();
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = k[i] * k[j] * (1.0 - c) + if i == j { c } else { 0.0 };
        }
    }
    r[0][1] -= k[2] * s;
    r[0][2] += k[1] * s;
    r[1][0] += k[2] * s;
    r[1][2] -= k[0] * s;
    r[2][0] -= k[1] * s;
    r[2][1] += k[0] * s;
    Rigid {
        rotation: r,
        translation: [0.0; 3],
    }
}

#[test]
fn fpfh_is_invariant_to_rigid_motions() {
    let points = box_cloud();
    // Off the plate's plane (which passes through the box centre), so every normal has a side.
    let viewpoint = [1.0, 0.7, 0.8];
    let motion = rotation_about([1.0, 2.0, -0.5], 1.1).compose(&Rigid {
        rotation: Rigid::<3>::identity().rotation,
        translation: [3.0, -2.0, 0.7],
    });
    let moved: Vec<[f64; 3]> = points.iter().map(|p| motion.apply(p)).collect();
    let features = |pts: &[[f64; 3]], view: [f64; 3]| {
        let tree = KdTree::new(pts);
        let normals = estimate_normals(pts, &tree, 1000, 0.15, view).unwrap();
        fpfh(pts, &normals, &tree, 0.25, 1000).unwrap()
    };
    let a = features(&points, viewpoint);
    let b = features(&moved, motion.apply(&viewpoint));
    let mut informative = 0;
    // Equal up to rounding, except where rounding moves a pair feature that lies on a bin edge
    // (or a tie of the source-point choice) into the neighbouring bin: rare, and small.
    let mut moved = 0;
    for (ha, hb) in a.iter().zip(&b) {
        let l1: f64 = (0..FEATURE_LEN).map(|k| (ha[k] - hb[k]).abs()).sum();
        assert!(l1 < 2.0, "{ha:?}\n{hb:?}");
        moved += usize::from(l1 > 1e-6);
        // Each sub-histogram sums to 200 (neighbours 100 + own 100).
        for part in ha.chunks(BINS) {
            assert!((part.iter().sum::<f64>() - 200.0).abs() < 1e-9);
        }
        informative += usize::from(ha.iter().filter(|&&x| x > 0.0).count() > 3);
    }
    assert!(
        moved * 100 < points.len(),
        "{moved} of {} histograms moved",
        points.len()
    );
    assert!(informative > points.len() / 2);
    // A corner and a plane's middle differ.
    let tree = KdTree::new(&points);
    let corner = tree.nearest(&[0.0, 0.0, 0.0]).unwrap().0;
    let middle = tree.nearest(&[1.0, 0.75, 0.0]).unwrap().0;
    assert!(chronomap_registration::chi_squared(&a[corner], &a[middle]) > 10.0);
    // 2-D: the room outline rotated and shifted.
    let room: Vec<[f64; 2]> = (0..200)
        .map(|i| f64::from(i) * 0.03)
        .map(|s| [s.cos() * (2.0 + 0.3 * (3.0 * s).sin()), s.sin() * 2.0])
        .collect();
    let m2 = Rigid::from_pose(-1.0, 2.5, 2.0);
    let moved2: Vec<[f64; 2]> = room.iter().map(|p| m2.apply(p)).collect();
    let f2 = |pts: &[[f64; 2]], view: [f64; 2]| {
        let tree = KdTree::new(pts);
        let normals = estimate_normals(pts, &tree, 1000, 0.3, view).unwrap();
        fpfh(pts, &normals, &tree, 0.6, 1000).unwrap()
    };
    let (a2, b2) = (f2(&room, [0.0, 0.0]), f2(&moved2, m2.apply(&[0.0, 0.0])));
    let moved2 = a2
        .iter()
        .zip(&b2)
        .filter(|(ha, hb)| ha.iter().zip(hb.iter()).any(|(x, y)| (x - y).abs() > 1e-6))
        .count();
    assert!(moved2 * 100 < room.len(), "{moved2}");
}

#[test]
fn ransac_finds_the_motion_among_outliers() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(3);
    let source: Vec<[f64; 3]> = (0..200)
        .map(|_| std::array::from_fn(|_| rng.uniform(-5.0, 5.0)))
        .collect();
    let truth = rotation_about([0.2, 1.0, 0.1], 0.7).compose(&Rigid {
        rotation: Rigid::<3>::identity().rotation,
        translation: [1.0, -0.5, 2.0],
    });
    let target: Vec<[f64; 3]> = source.iter().map(|p| truth.apply(p)).collect();
    // 40 true correspondences, 160 wrong ones (80 % outliers).
    let mut corr: Vec<(usize, usize)> = (0..40).map(|i| (i, i)).collect();
    for i in 40..200 {
        corr.push((i, rng.int_in(0, 199) as usize));
    }
    let result = ransac(
        &source,
        &target,
        &corr,
        &RansacParams::with_inlier_distance(0.05),
    )
    .unwrap();
    assert!(close(&result.transform, &truth, 1e-6, 1e-9));
    let wrong_but_close = (40..200).filter(|&c| {
        let (s, t) = corr[c];
        let d = truth.apply(&source[s]);
        (0..3).map(|a| (d[a] - target[t][a]).powi(2)).sum::<f64>() <= 0.05 * 0.05
    });
    assert_eq!(result.inliers.len(), 40 + wrong_but_close.count());
    assert!(result.iterations < 100_000);
    // Without any true correspondence there is no consensus of more than a few.
    let noise: Vec<(usize, usize)> = (0..200).map(|i| (i, (i * 7 + 3) % 200)).collect();
    let junk = ransac(
        &source,
        &target,
        &noise,
        &RansacParams::with_inlier_distance(0.05),
    )
    .unwrap();
    assert!(junk.inliers.len() < 10, "{}", junk.inliers.len());
    let e = ransac(
        &source,
        &target,
        &corr[..2],
        &RansacParams::with_inlier_distance(0.05),
    )
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "correspondences: 2 points, at least 3 needed"
    );
}

#[test]
fn small_gicp_pair_without_initial_guess() {
    // The real pair on a 10 cm grid within 30 m ([Stüde 2024] appendix A's range limit), the
    // shipped transform as the answer; goal < 0.1° and < 2 cm.
    let data = chronomap_testutil::data_path("registration_small_gicp");
    let filters = Filters {
        voxel: Some(0.1),
        height: None,
        intensity: None,
        range: Some((0.0, 30.0)),
        max_points: None,
    };
    let source = filters
        .apply(&chronomap_io::read_ply(data.join("source.ply.xz")).unwrap())
        .unwrap();
    let target = filters
        .apply(&chronomap_io::read_ply(data.join("target.ply.xz")).unwrap())
        .unwrap();
    let text = std::fs::read_to_string(data.join("T_target_source.txt")).unwrap();
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|w| w.parse().unwrap())
        .collect();
    let axes = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let columns = [
        [0.0; 3],
        [v[0], v[4], v[8]],
        [v[1], v[5], v[9]],
        [v[2], v[6], v[10]],
    ];
    let mut truth = kabsch(&axes, &columns).unwrap();
    truth.translation = [v[3], v[7], v[11]];

    let result = register(&source, &target, &RegistrationParams::for_voxel(0.25)).unwrap();
    let (r, t) = result.transform.error_to(&truth);
    assert!(
        r.to_degrees() < 0.1 && t < 0.02,
        "{}° {} m",
        r.to_degrees(),
        t
    );
    // The coarse alignment alone is within a few cm and tenths of a degree.
    let (cr, ct) = result.coarse.error_to(&truth);
    assert!(
        cr.to_degrees() < 1.0 && ct < 0.15,
        "{}° {} m",
        cr.to_degrees(),
        ct
    );
    // σ̂ of a sparse lidar pair: centimetres, not millimetres or metres.
    assert!(result.information.sigma > 0.01 && result.information.sigma < 0.2);
    let omega = result.information.matrix();
    assert_eq!(
        (omega.len(), omega[0][0], omega[0][1]),
        (6, 1.0 / result.information.variance(), 0.0)
    );
}

/// The bundled small_gicp pair on a 10 cm grid within 30 m, and its shipped transform.
fn small_gicp_pair() -> (Cloud<3>, Cloud<3>, Rigid<3>) {
    let data = chronomap_testutil::data_path("registration_small_gicp");
    let filters = Filters {
        voxel: Some(0.1),
        height: None,
        intensity: None,
        range: Some((0.0, 30.0)),
        max_points: None,
    };
    let read = |name: &str| {
        filters
            .apply(&chronomap_io::read_ply(data.join(name)).unwrap())
            .unwrap()
    };
    let text = std::fs::read_to_string(data.join("T_target_source.txt")).unwrap();
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|w| w.parse().unwrap())
        .collect();
    let m: [[f64; 4]; 4] = std::array::from_fn(|i| std::array::from_fn(|j| v[4 * i + j]));
    let truth = Rigid::from_matrix4(&m).unwrap();
    (read("source.ply.xz"), read("target.ply.xz"), truth)
}

#[test]
fn a_room_far_from_the_origin_registers_as_at_the_origin() {
    // The same pair moved 500 km east and 5,000 km north (a UTM frame): the transform between
    // the moved clouds is T' = shift ∘ T ∘ shift⁻¹, i.e. the same rotation and the translation
    // t + c − R c. Before the clouds were centred, ICP's normal equations (rotations about an
    // origin thousands of km away) were refused as "degenerate (a plane or a corridor)".
    let (source, target, truth) = small_gicp_pair();
    let params = RegistrationParams::for_voxel(0.25);
    let near = register(&source, &target, &params).unwrap();
    for c in [[1000.0, 1000.0, 0.0], [500_000.0, 5_000_000.0, 0.0]] {
        let shift = Rigid {
            rotation: Rigid::<3>::identity().rotation,
            translation: c,
        };
        let moved = |cloud: &Cloud<3>| cloud.transformed(&shift);
        let far = register(&moved(&source), &moved(&target), &params)
            .unwrap_or_else(|e| panic!("{c:?}: {e}"));
        // Back in the frame of the original clouds.
        let back = shift.inverse().compose(&far.transform).compose(&shift);
        let (r, t) = back.error_to(&truth);
        assert!(
            r.to_degrees() < 0.1 && t < 0.02,
            "{c:?}: {}° {t} m",
            r.to_degrees()
        );
        let (r, t) = back.error_to(&near.transform);
        assert!(
            r.to_degrees() < 0.01 && t < 0.002,
            "{c:?}: {}° {t} m from the near result",
            r.to_degrees()
        );
    }
}

#[test]
fn too_many_points_for_features_are_refused_before_the_work() {
    // 300,000 points of a 10 m cube on a 1 mm grid: nearly every point keeps its own voxel,
    // more than MAX_FEATURE_POINTS would get FPFH histograms (about 2 KB each).
    let mut rng = Xoshiro256StarStar::seed_from_u64(3);
    let points: Vec<[f64; 3]> = (0..300_000)
        .map(|_| std::array::from_fn(|_| rng.uniform(0.0, 10.0)))
        .collect();
    let cloud = Cloud::from_points(points).unwrap();
    let small = Cloud::from_points(box_cloud()).unwrap();
    let params = RegistrationParams::for_voxel(0.001);
    let e = register(&small, &cloud, &params).unwrap_err();
    let RegistrationError::TooManyFeaturePoints {
        what,
        voxel,
        seen,
        points,
    } = e.clone()
    else {
        panic!("{e}");
    };
    assert_eq!((what, voxel, points), ("target", 0.001, 300_000));
    // The grid stops at the point that occupies cell 250,001: no cell of 1 mm holds two of
    // these points, so that is point 250,001 (it did not finish the 300,000 before).
    assert_eq!(seen, 250_001);
    assert_eq!(
        e.to_string(),
        "target: more than 250000 points on the 0.001 m coarse voxel grid (counted in the \
         first 250001 of its 300000 filtered points), at most 250000 enter feature computation \
         (a larger coarse voxel leaves fewer)"
    );
}

#[test]
fn malaga_loop_pairs_without_initial_guess() {
    // Two loop pairs of the bundled Málaga keyframes, the second 2.5 m and 71 keyframes apart; the SLAM estimate is the reference (itself an estimate: a few cm).
    let frames = malaga_data::keyframes();
    assert_eq!(frames.len(), 99);
    let params = scan_params();
    for (i, j) in [(2, 71), (10, 81)] {
        let truth = malaga_data::relative(&frames[j], &frames[i]);
        assert!(truth.translation_norm() < 3.0);
        let result = register_scans(&frames[j].scan, &frames[i].scan, &params).unwrap();
        let (r, t) = result.transform.error_to(&truth);
        assert!(
            r.to_degrees() < 1.0 && t < 0.1,
            "pair {i}-{j}: {}° {} m",
            r.to_degrees(),
            t
        );
        assert_eq!(result.information.dof, 3);
    }
}

#[test]
fn bad_input_is_an_error_naming_what() {
    let cloud = Cloud::from_points(box_cloud()).unwrap();
    let few = Cloud::from_points(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]).unwrap();
    let params = RegistrationParams::for_voxel(0.25);
    let e = register(&few, &cloud, &params).unwrap_err();
    assert_eq!(
        e.to_string(),
        "filtered source: 2 points, at least 9 needed"
    );
    let mut bad = params.clone();
    bad.coarse_voxel = f64::NAN;
    assert_eq!(
        register(&cloud, &cloud, &bad).unwrap_err().to_string(),
        "coarse_voxel: NaN is not valid (must be positive and finite)"
    );
    bad = params.clone();
    bad.feature_radii.clear();
    assert!(matches!(
        register(&cloud, &cloud, &bad),
        Err(RegistrationError::Parameter {
            field: "feature_radii",
            ..
        })
    ));
    // A tree or normals of other points are refused, not indexed out of bounds.
    let points = cloud.points();
    let other = KdTree::new(&points[..10]);
    assert_eq!(
        estimate_normals(points, &other, 5, 1.0, [0.0; 3])
            .unwrap_err()
            .to_string(),
        format!("normals: k-d tree: 10 does not fit {} points", points.len())
    );
    let tree = KdTree::new(points);
    assert!(fpfh(points, &[[0.0; 3]; 3], &tree, 0.2, 10).is_err());
    let h = [[0.0; FEATURE_LEN]; 2];
    assert!(
        chronomap_registration::match_features(&h, &[0, 5], &h, &[0], &Default::default()).is_err()
    );
}

#[test]
fn too_many_points_for_icp_are_refused_before_the_features() {
    // 1,200,000 points of a 10 m cube: on a 1 mm fine grid nearly every point keeps its own
    // cell, more than MAX_ICP_POINTS would enter ICP. The coarse grid (0.5 m) is small, but
    // the refusal comes first, from the fine grid, which stops at cell 1,000,001.
    let mut rng = Xoshiro256StarStar::seed_from_u64(4);
    let points: Vec<[f64; 3]> = (0..1_200_000)
        .map(|_| std::array::from_fn(|_| rng.uniform(0.0, 10.0)))
        .collect();
    let cloud = Cloud::from_points(points).unwrap();
    let small = Cloud::from_points(box_cloud()).unwrap();
    let mut params = RegistrationParams::for_voxel(0.5);
    params.fine_voxel = Some(0.001);
    let e = register(&cloud, &small, &params).unwrap_err();
    let RegistrationError::TooManyIcpPoints {
        what,
        counted,
        seen,
        points,
    } = e.clone()
    else {
        panic!("{e}");
    };
    assert_eq!((what, counted, points), ("source", 1_000_001, 1_200_000));
    assert!((1_000_001..1_000_100).contains(&seen), "{seen}");
    assert!(
        e.to_string()
            .starts_with("source: more than 1000000 points would enter ICP (1000001 counted"),
        "{e}"
    );
    // The same through the filters (ICP on the filtered clouds): the filters' grid stops.
    params.fine_voxel = None;
    params.filters.voxel = Some(0.001);
    params.filters.range = Some((0.0, 30.0));
    let e = register(&small, &cloud, &params).unwrap_err();
    assert!(
        matches!(
            e,
            RegistrationError::TooManyIcpPoints {
                what: "target",
                counted: 1_000_001,
                points: 1_200_000,
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn a_cloud_beyond_the_input_bound_is_refused_before_any_work() {
    let points = vec![[1.0, 2.0, 3.0]; chronomap_registration::MAX_INPUT_POINTS + 1];
    let cloud = Cloud::from_points(points).unwrap();
    let small = Cloud::from_points(box_cloud()).unwrap();
    let e = register(&small, &cloud, &RegistrationParams::for_voxel(0.5)).unwrap_err();
    assert_eq!(
        e,
        RegistrationError::TooManyInputPoints {
            what: "target",
            got: 10_000_001
        }
    );
    assert_eq!(
        e.to_string(),
        "target: 10000001 points, at most 10000000 may be registered"
    );
}
