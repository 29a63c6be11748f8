//! The map manager over the real Málaga 2006 loop (225 scans of a 180° SICK mounted 0.78 m
//! ahead, odometry increments). There is no ground truth of doors: what is checked is that
//! the whole log runs, that what is declared is consistent, and that the detector sees the
//! door-width gaps the log has. `examples/malaga_doors.rs` prints what it finds.

use chronomap_geometry::Scan2d;
use chronomap_io::laser_text::{read_odometry, read_scans};
use chronomap_multimap::door::{DoorParams, detect_door_posts};
use chronomap_multimap::mapper::{Mapper, MapperParams};
use chronomap_multimap::se2::Pose2;
use chronomap_testutil::data_path;

/// The scans, the sensor's pose on the robot (the same for every scan) and the odometry
/// increments of the bundled log, read by the io crate.
fn malaga() -> (Vec<Scan2d>, Pose2, Vec<Pose2>) {
    let scans = read_scans(data_path("malaga_laser_2006/scans.txt.xz")).unwrap();
    let s = scans[0].sensor;
    assert!(scans.iter().all(|l| l.sensor == s));
    let mount = Pose2::new(s.x, s.y, s.yaw).unwrap();
    let increments = read_odometry(data_path("malaga_laser_2006/odometry.txt.xz"))
        .unwrap()
        .iter()
        .map(|o| Pose2::new(o.dx, o.dy, o.dyaw).unwrap())
        .collect();
    (
        scans.into_iter().map(|l| l.scan).collect(),
        mount,
        increments,
    )
}

/// The Málaga scans run right to left, counter-clockwise (`right_to_left = 1`): the io reader
/// keeps their beam order, so beam 0 is the robot's right (bearing −90°), as the detector's
/// front and back cones assume. Checked against the first line of the file as text.
#[test]
fn the_malaga_scans_keep_their_counter_clockwise_beam_order() {
    let path = data_path("malaga_laser_2006/scans.txt.xz");
    let mut text = String::new();
    std::io::Read::read_to_string(&mut chronomap_io::open_data_file(&path).unwrap(), &mut text)
        .unwrap();
    let line = text.lines().find(|l| !l.starts_with('#')).unwrap();
    let f: Vec<f64> = line
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    let n = f[8] as usize;
    assert_eq!((f[2], n), (1.0, 361), "right_to_left, beams");
    let scan = &read_scans(&path).unwrap()[0].scan;
    assert!((scan.angle_min + std::f64::consts::FRAC_PI_2).abs() < 1e-6);
    assert!((scan.bearing(0) - scan.angle_min).abs() < 1e-12);
    for k in [0, 1, 180, 359, 360] {
        let expected = if f[9 + n + k] == 1.0 && f[9 + k] < f[3] {
            f[9 + k]
        } else {
            f64::INFINITY
        };
        assert_eq!(scan.ranges[k], expected, "beam {k}");
    }
    // Beams 0 and 360 differ on this line, so a reversed scan would not pass.
    assert_ne!(f[9], f[9 + n - 1]);
}

#[test]
fn the_malaga_loop_runs_and_what_it_declares_is_consistent() {
    let (scans, mount, increments) = malaga();
    assert_eq!((scans.len(), increments.len()), (225, 224));
    assert_eq!(mount, Pose2::new(0.78, 0.0, 0.0).unwrap());
    let params = MapperParams {
        door: DoorParams {
            sensor: mount,
            ..DoorParams::default()
        },
        ..MapperParams::default()
    };
    let mut mapper = Mapper::new(params).unwrap();
    let mut passages = 0;
    let mut side_gaps = 0;
    for (k, scan) in scans.iter().enumerate() {
        let inc = if k == 0 {
            Pose2::IDENTITY
        } else {
            increments[k - 1]
        };
        let r = mapper.step(scan, &inc).unwrap();
        for d in r.detector.front.iter().chain(&r.detector.back) {
            assert!((0.6..=1.6).contains(&d.width()), "scan {k}: {d:?}");
        }
        // A forward scanner sees nothing behind: (C2) never holds.
        assert!(r.detector.back.is_empty(), "scan {k}");
        if let Some(p) = r.passage {
            assert!(
                p.criteria[0] && p.criteria[2] && !p.criteria[1],
                "scan {k}: {:?}",
                p.criteria
            );
            passages += 1;
        }
        // Door-width gaps at any bearing, in the sensor frame.
        side_gaps += usize::from(!detect_door_posts(scan, &params.door).unwrap().is_empty());
    }
    let g = mapper.graph();
    assert_eq!(g.maps().len(), passages + 1);
    assert_eq!(g.links().len(), passages);
    // The corridors of the faculty have door-width openings beside the robot's path.
    assert!(side_gaps > 0);
}
