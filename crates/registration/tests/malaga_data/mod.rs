//! The Málaga 2006 keyframes (`data/malaga_laser_2006/keyframes_slam.txt.xz`): SLAM poses and
//! their 2-D scans, read by a few lines of test code.

#![allow(dead_code)]

use std::io::Read;

use chronomap_geometry::scan::Scan2d;
use chronomap_registration::Rigid;

/// A keyframe: the laser's pose in the map (robot pose ⊕ mounting) and its scan.
pub struct Keyframe {
    pub laser_in_map: Rigid<2>,
    pub scan: Scan2d,
}

/// Every keyframe of the loop.
pub fn keyframes() -> Vec<Keyframe> {
    let path = chronomap_testutil::data_path("malaga_laser_2006/keyframes_slam.txt.xz");
    let mut text = String::new();
    chronomap_io::open_data_file(&path)
        .unwrap()
        .read_to_string(&mut text)
        .unwrap();
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|line| {
            let v: Vec<f64> = line
                .split_whitespace()
                .map(|w| w.parse().unwrap())
                .collect();
            let (aperture, right_to_left, max_range) = (v[4], v[5], v[6]);
            assert_eq!(right_to_left, 1.0);
            let n = v[11] as usize;
            assert_eq!(v.len(), 12 + 2 * n);
            let ranges = (0..n)
                .map(|k| {
                    if v[12 + n + k] != 0.0 {
                        v[12 + k]
                    } else {
                        f64::INFINITY
                    }
                })
                .collect();
            let scan =
                Scan2d::new(v[3], -aperture / 2.0, aperture / 2.0, max_range, ranges).unwrap();
            let robot = Rigid::from_pose(v[0], v[1], v[2]);
            let mount = Rigid::from_pose(v[7], v[8], v[10]);
            Keyframe {
                laser_in_map: robot.compose(&mount),
                scan,
            }
        })
        .collect()
}

/// The SLAM estimate of the transform from `source`'s laser frame to `target`'s.
pub fn relative(source: &Keyframe, target: &Keyframe) -> Rigid<2> {
    target.laser_in_map.inverse().compose(&source.laser_in_map)
}

/// Loop pairs `(i, j)`: keyframes whose laser origins are closer than 3 m, more than 20 apart.
pub fn loop_pairs(frames: &[Keyframe]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for i in 0..frames.len() {
        for j in (i + 21)..frames.len() {
            let d = relative(&frames[i], &frames[j]).translation_norm();
            if d < 3.0 {
                out.push((i, j));
            }
        }
    }
    out
}
