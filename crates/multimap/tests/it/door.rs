//! Door-passage detection ([Stüde 2024] §3.3.2) on scans ray-cast from a hand-made floor plan.

use chronomap_multimap::config::{ConfigParams, MapConfig, choose_config};
use chronomap_multimap::door::{DoorDetector, DoorParams, DoorPassage, detect_door_posts};
use chronomap_multimap::se2::Pose2;
use chronomap_multimap::synth::{DOOR, FloorPlan, Scanner};
use chronomap_rng::Xoshiro256StarStar;

/// Runs the detector along `poses` (5 scans a second) and returns its passages and how often
/// each criterion fired.
fn run(
    plan: &FloorPlan,
    scanner: &Scanner,
    params: DoorParams,
    poses: &[Pose2],
    noise: f64,
) -> Vec<DoorPassage> {
    let mut rng = Xoshiro256StarStar::seed_from_u64(11);
    let mut detector = DoorDetector::new(params).unwrap();
    let mut out = Vec::new();
    for (k, pose) in poses.iter().enumerate() {
        let mut scan = scanner.scan(plan, pose, 0.2 * k as f64).unwrap();
        for r in scan.ranges.iter_mut().filter(|r| r.is_finite()) {
            // Box–Muller normal noise.
            let (u1, u2) = (1.0 - rng.next_f64(), rng.next_f64());
            *r += noise * (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos();
            *r = r.max(0.01);
        }
        if let Some(p) = detector.update(&scan, pose).unwrap().passage {
            out.push(p);
        }
    }
    out
}

fn door_center() -> [f64; 2] {
    [0.5 * (DOOR[0][0] + DOOR[1][0]), DOOR[0][1]]
}

/// The 360° scanner sees the posts ahead (C1) and, after the crossing, behind (C2).
#[test]
fn a_full_circle_scanner_detects_the_one_passage_by_front_and_back_posts() {
    let plan = FloorPlan::corridor_and_room();
    let poses = plan.door_run(0.2).unwrap();
    let passages = run(
        &plan,
        &Scanner::full_circle(720, 30.0).unwrap(),
        DoorParams::default(),
        &poses,
        0.0,
    );
    assert_eq!(passages.len(), 1, "{passages:?}");
    let p = &passages[0];
    assert!(p.criteria[0] && p.criteria[1], "{:?}", p.criteria);
    // The door's posts are where the plan has them, to the beam spacing (0.5° at 1–2 m).
    let c = p.door.center();
    assert!(
        (c[0] - door_center()[0]).abs() < 0.03 && (c[1] - 2.0).abs() < 1e-9,
        "{c:?}"
    );
    assert!((p.door.width() - 0.9).abs() < 0.05, "{}", p.door.width());
    // Declared just behind the door: the link point lies in the room within a step.
    assert!(
        p.pose.y > 2.0 && p.pose.y <= 2.0 + 0.2 + 1e-9,
        "{:?}",
        p.pose
    );
    // The room seen from behind the door is small: short-range configuration.
    assert_eq!(
        choose_config(&p.bbox.unwrap(), &ConfigParams::default()),
        MapConfig::ShortRange
    );
}

/// A forward-looking 180° scanner mounted ahead of the robot (the Málaga SICK's geometry)
/// never sees posts behind, so the passage needs (C1) and (C3).
#[test]
fn a_forward_scanner_needs_the_bounding_box_change() {
    let plan = FloorPlan::corridor_and_room();
    let poses = plan.door_run(0.2).unwrap();
    let params = DoorParams {
        sensor: Pose2::new(0.78, 0.0, 0.0).unwrap(),
        ..DoorParams::default()
    };
    let scanner = Scanner::front_half(361, 80.0, params.sensor).unwrap();
    let passages = run(&plan, &scanner, params, &poses, 0.0);
    assert_eq!(passages.len(), 1, "{passages:?}");
    assert_eq!(passages[0].criteria, [true, false, true]);
    // With (C3) switched off by a threshold no box change reaches, nothing is declared.
    let strict = DoorParams {
        bbox_change: 100.0,
        ..params
    };
    assert!(run(&plan, &scanner, strict, &poses, 0.0).is_empty());
}

/// Range noise of 1 cm (a SICK LMS's) neither hides the door nor adds passages.
#[test]
fn noisy_ranges_give_the_same_single_passage() {
    let plan = FloorPlan::corridor_and_room();
    let poses = plan.door_run(0.2).unwrap();
    for scanner in [
        Scanner::full_circle(720, 30.0).unwrap(),
        Scanner::front_half(361, 80.0, Pose2::new(0.78, 0.0, 0.0).unwrap()).unwrap(),
    ] {
        let params = DoorParams {
            sensor: scanner.mount,
            ..DoorParams::default()
        };
        let passages = run(&plan, &scanner, params, &poses, 0.01);
        assert_eq!(passages.len(), 1, "{passages:?}");
        assert!((passages[0].door.width() - 0.9).abs() < 0.08);
    }
}

/// Driving past the open door along the corridor sees its posts and a change of the box
/// (the room appears through the door) but never crosses it: no passage.
#[test]
fn driving_past_the_door_is_no_passage() {
    let plan = FloorPlan::corridor_and_room();
    let poses: Vec<Pose2> = (0..50)
        .map(|k| Pose2::new(1.0 + 0.2 * k as f64, 1.0, 0.0).unwrap())
        .collect();
    let scanner = Scanner::full_circle(720, 30.0).unwrap();
    assert!(run(&plan, &scanner, DoorParams::default(), &poses, 0.01).is_empty());
    // Turning towards the door and stopping short of it: posts ahead, no crossing.
    let mut short = plan.door_run(0.2).unwrap();
    short.retain(|p| p.y < 1.7);
    assert!(run(&plan, &scanner, DoorParams::default(), &short, 0.0).is_empty());
}

/// Into the 32 m × 28 m hall: the long-range configuration is chosen.
#[test]
fn a_hall_behind_the_door_gets_the_long_range_configuration() {
    let plan = FloorPlan::corridor_and_hall();
    let mut poses = plan.door_run(0.2).unwrap();
    // Drive on into the hall: the box is read when the passage is declared.
    let last = *poses.last().unwrap();
    poses.extend((1..20).map(|k| Pose2::new(last.x, last.y + 0.2 * k as f64, last.theta).unwrap()));
    let passages = run(
        &plan,
        &Scanner::full_circle(720, 60.0).unwrap(),
        DoorParams::default(),
        &poses,
        0.0,
    );
    assert_eq!(passages.len(), 1, "{passages:?}");
    let bbox = passages[0].bbox.unwrap();
    assert!(bbox.width() > 10.0 && bbox.height() > 10.0, "{bbox:?}");
    assert_eq!(
        choose_config(&bbox, &ConfigParams::default()),
        MapConfig::LongRange
    );
}

/// One scan in front of the door: one pair of posts, at the plan's door corners.
#[test]
fn posts_of_a_single_scan_are_the_door_corners() {
    let plan = FloorPlan::corridor_and_room();
    let scanner = Scanner::full_circle(720, 30.0).unwrap();
    let pose = Pose2::new(door_center()[0], 1.0, std::f64::consts::FRAC_PI_2).unwrap();
    let scan = scanner.scan(&plan, &pose, 0.0).unwrap();
    let doors = detect_door_posts(&scan, &DoorParams::default()).unwrap();
    assert_eq!(doors.len(), 1, "{doors:?}");
    // Sensor frame: x ahead (+y of the world), y to the left (−x of the world).
    let d = doors[0];
    assert!((d.right[0] - 1.0).abs() < 1e-9 && (d.left[0] - 1.0).abs() < 1e-9);
    assert!(
        (d.right[1] + 0.45).abs() < 0.01 && (d.left[1] - 0.45).abs() < 0.01,
        "{d:?}"
    );
    // A door too narrow for the parameters is none.
    let narrow = DoorParams {
        min_door_width: 1.0,
        ..DoorParams::default()
    };
    assert!(detect_door_posts(&scan, &narrow).unwrap().is_empty());
}

/// Bad input is refused with a typed error, never a panic.
#[test]
fn bad_input_is_refused() {
    let plan = FloorPlan::corridor_and_room();
    let scanner = Scanner::full_circle(90, 30.0).unwrap();
    let mut detector = DoorDetector::new(DoorParams::default()).unwrap();
    let scan = scanner
        .scan(&plan, &Pose2::new(1.0, 1.0, 0.0).unwrap(), 5.0)
        .unwrap();
    detector
        .update(&scan, &Pose2::new(1.0, 1.0, 0.0).unwrap())
        .unwrap();
    let earlier = scanner
        .scan(&plan, &Pose2::new(1.0, 1.0, 0.0).unwrap(), 4.0)
        .unwrap();
    let e = detector
        .update(&earlier, &Pose2::new(1.0, 1.0, 0.0).unwrap())
        .unwrap_err();
    assert!(e.to_string().starts_with("time: scan at 4 s"), "{e}");
    let nan_pose = Pose2 {
        x: f64::NAN,
        y: 0.0,
        theta: 0.0,
    };
    assert!(
        detector
            .update(&scan, &nan_pose)
            .unwrap_err()
            .to_string()
            .contains("not finite")
    );
    let mut bad = scan.clone();
    bad.ranges[3] = f64::NAN;
    assert!(
        detector
            .update(&bad, &Pose2::IDENTITY)
            .unwrap_err()
            .to_string()
            .starts_with("scan: range 3")
    );
    for params in [
        DoorParams {
            min_step: f64::NAN,
            ..DoorParams::default()
        },
        DoorParams {
            max_door_width: 0.5,
            ..DoorParams::default()
        },
        DoorParams {
            filter_window: 4,
            ..DoorParams::default()
        },
        DoorParams {
            min_criteria: 0,
            ..DoorParams::default()
        },
    ] {
        assert!(DoorDetector::new(params).is_err(), "{params:?}");
    }
}
