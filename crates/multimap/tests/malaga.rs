//! The map manager over the real Málaga 2006 loop (225 scans of a 180° SICK mounted 0.78 m
//! ahead, odometry increments). There is no ground truth of doors: what is checked is that
//! the whole log runs, that what is declared is consistent, and that the detector sees the
//! door-width gaps the log has. `examples/malaga_doors.rs` prints what it finds.

mod common;

use chronomap_multimap::door::{DoorParams, detect_door_posts};
use chronomap_multimap::mapper::{Mapper, MapperParams};
use chronomap_multimap::se2::Pose2;
use chronomap_testutil::data_path;

#[test]
fn the_malaga_loop_runs_and_what_it_declares_is_consistent() {
    let (scans, mount) = common::malaga::scans(&data_path("malaga_laser_2006/scans.txt.xz"));
    let increments = common::malaga::increments(&data_path("malaga_laser_2006/odometry.txt.xz"));
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
