//! Laser logs for `chronomap lidar` and `chronomap maps`: scans with the robot's odometry (and,
//! for keyframe files, the SLAM poses), from the text files of the bundled Málaga log or from a
//! rosbag2 bag (`sensor_msgs/msg/LaserScan` and `nav_msgs/msg/Odometry`).

use std::path::Path;

use anyhow::{Context, Result, anyhow};
use chronomap_io::laser_text::{read_keyframes, read_odometry, read_scans};
use chronomap_lidar::Scan2d;
use chronomap_lidar::evaluation::{between, compose, keyframe_increments};
use chronomap_rosbag::{Bag, TimeSource};

use crate::cli::LaserSourceArgs;
use crate::output::{ProgressBar, usage};

/// A sequence of scans with where the robot was.
pub struct LaserLog {
    /// What it was read from (for messages).
    pub name: String,
    /// The scans, in time order (sensor frame).
    pub scans: Vec<Scan2d>,
    /// The robot's pose at each scan by odometry alone (`x, y, yaw`; the first scan at the
    /// origin).
    pub odometry: Vec<[f64; 3]>,
    /// The robot's pose at each scan estimated by SLAM (keyframe files only).
    pub truth: Option<Vec<[f64; 3]>>,
    /// The laser's pose on the robot (`x, y, yaw`).
    pub sensor: [f64; 3],
}

impl LaserLog {
    /// Odometry increments from scan to scan in the robot frame (the first is zero).
    pub fn increments(&self) -> Vec<[f64; 3]> {
        let mut out = vec![[0.0; 3]];
        for w in self.odometry.windows(2) {
            out.push(between(w[0], w[1]));
        }
        out
    }

    /// The scans at least `distance` metres or `angle` radians of odometry apart (the first
    /// always): keyframes, as SLAM front ends choose them.
    pub fn keyframes(&self, distance: f64, angle: f64) -> LaserLog {
        let mut keep = Vec::new();
        for (k, pose) in self.odometry.iter().enumerate() {
            let far = keep.last().is_none_or(|&last: &usize| {
                let d = between(self.odometry[last], *pose);
                d[0].hypot(d[1]) >= distance || d[2].abs() >= angle
            });
            if far {
                keep.push(k);
            }
        }
        LaserLog {
            name: self.name.clone(),
            scans: keep.iter().map(|&k| self.scans[k].clone()).collect(),
            odometry: keep.iter().map(|&k| self.odometry[k]).collect(),
            truth: self
                .truth
                .as_ref()
                .map(|t| keep.iter().map(|&k| t[k]).collect()),
            sensor: self.sensor,
        }
    }
}

/// Reads the log the flags name.
pub fn read(args: &LaserSourceArgs) -> Result<LaserLog> {
    match (&args.keyframes, &args.scans, &args.bag) {
        (Some(keyframes), None, None) => from_keyframes(keyframes, args.odometry.as_deref()),
        (None, Some(scans), None) => {
            let odometry = args.odometry.as_deref().ok_or_else(|| {
                usage("--scans needs --odometry (the robot's motion between the scans)")
            })?;
            from_scans(scans, odometry)
        }
        (None, None, Some(bag)) => from_bag(bag, args),
        (None, None, None) => Err(usage(
            "say where the scans are: --keyframes FILE, --scans FILE --odometry FILE, or --bag BAG",
        )),
        _ => Err(usage(
            "give one of --keyframes, --scans and --bag, not several",
        )),
    }
}

/// Reads a keyframe file (SLAM poses and scans) with its odometry, if given (else the motion
/// between keyframes is the SLAM estimate's).
pub fn read_keyframes_file(path: &Path, odometry: Option<&Path>) -> Result<LaserLog> {
    from_keyframes(path, odometry)
}

/// Dead reckoning: the robot's pose at each of `times` from odometry increments `(time,
/// increment)` in time order, each the motion up to its time.
fn dead_reckon(increments: &[(f64, [f64; 3])], times: &[f64]) -> Vec<[f64; 3]> {
    let mut pose = [0.0; 3];
    keyframe_increments(increments, times)
        .into_iter()
        .map(|inc| {
            pose = compose(pose, inc);
            pose
        })
        .collect()
}

fn from_scans(scans: &Path, odometry: &Path) -> Result<LaserLog> {
    let lines = read_scans(scans)?;
    let increments: Vec<(f64, [f64; 3])> = read_odometry(odometry)?
        .iter()
        .map(|o| (o.time, [o.dx, o.dy, o.dyaw]))
        .collect();
    let times: Vec<f64> = lines.iter().map(|l| l.scan.time).collect();
    check_order(&scans.display().to_string(), &times)?;
    let sensor = lines
        .first()
        .map_or([0.0; 3], |l| [l.sensor.x, l.sensor.y, l.sensor.yaw]);
    Ok(LaserLog {
        name: scans.display().to_string(),
        odometry: dead_reckon(&increments, &times),
        scans: lines.into_iter().map(|l| l.scan).collect(),
        truth: None,
        sensor,
    })
}

fn from_keyframes(keyframes: &Path, odometry: Option<&Path>) -> Result<LaserLog> {
    let frames = read_keyframes(keyframes)?;
    let times: Vec<f64> = frames.iter().map(|k| k.scan.scan.time).collect();
    check_order(&keyframes.display().to_string(), &times)?;
    let truth: Vec<[f64; 3]> = frames.iter().map(|k| k.pose).collect();
    let odometry = match odometry {
        Some(path) => {
            let increments: Vec<(f64, [f64; 3])> = read_odometry(path)?
                .iter()
                .map(|o| (o.time, [o.dx, o.dy, o.dyaw]))
                .collect();
            dead_reckon(&increments, &times)
        }
        // Without odometry, the motion between keyframes is the SLAM estimate's.
        None => {
            let mut pose = [0.0; 3];
            let mut out = vec![pose];
            for w in truth.windows(2) {
                pose = compose(pose, between(w[0], w[1]));
                out.push(pose);
            }
            out
        }
    };
    let sensor = frames.first().map_or([0.0; 3], |k| {
        [k.scan.sensor.x, k.scan.sensor.y, k.scan.sensor.yaw]
    });
    Ok(LaserLog {
        name: keyframes.display().to_string(),
        scans: frames.into_iter().map(|k| k.scan.scan).collect(),
        odometry,
        truth: Some(truth),
        sensor,
    })
}

fn from_bag(path: &Path, args: &LaserSourceArgs) -> Result<LaserLog> {
    let bag = Bag::open(path)?;
    let progress = ProgressBar::new();
    let scans = bag.read_scans(&args.scan_topic, TimeSource::Auto, &progress)?;
    let odometry = bag.read_odometry(&args.odom_topic, TimeSource::Auto, &progress)?;
    if odometry.is_empty() {
        return Err(anyhow!(
            "{}: topic {} has no odometry messages",
            bag.name(),
            args.odom_topic
        ));
    }
    // The same bounds as the text logs: a pose beyond ±1e6 m or a non-finite one is refused.
    let limit = chronomap_io::laser_text::MAX_LENGTH_M;
    if let Some((k, o)) = odometry.iter().enumerate().find(|(_, o)| {
        !(o.position[0].abs() <= limit && o.position[1].abs() <= limit && o.yaw.is_finite())
    }) {
        return Err(anyhow!(
            "{}: {} message {}: pose ({}, {}, yaw {}) is not finite or beyond ±{limit} m",
            bag.name(),
            args.odom_topic,
            k + 1,
            o.position[0],
            o.position[1],
            o.yaw
        ));
    }
    let mut log = LaserLog {
        name: bag.name().to_string(),
        scans: Vec::with_capacity(scans.len()),
        odometry: Vec::with_capacity(scans.len()),
        truth: None,
        sensor: [args.sensor_offset[0], args.sensor_offset[1], 0.0],
    };
    let times: Vec<f64> = scans.iter().map(|s| s.time).collect();
    check_order(&log.name, &times)?;
    let mut origin = None;
    for (k, scan) in scans.into_iter().enumerate() {
        // The odometry pose at the scan: the latest one not after it (or the first).
        let at = odometry.partition_point(|o| o.time <= scan.time).max(1) - 1;
        let o = &odometry[at];
        let pose = [o.position[0], o.position[1], o.yaw];
        let origin = *origin.get_or_insert(pose);
        log.odometry.push(between(origin, pose));
        let ranges: Vec<f64> = scan.ranges.iter().map(|&r| f64::from(r)).collect();
        let converted = Scan2d::new(
            scan.time,
            f64::from(scan.angle_min),
            f64::from(scan.angle_max),
            f64::from(scan.range_max),
            ranges,
        )
        .with_context(|| format!("{}: {} message {}", log.name, args.scan_topic, k + 1))?;
        log.scans.push(converted);
    }
    if log.scans.is_empty() {
        return Err(anyhow!(
            "{}: topic {} has no scans",
            log.name,
            args.scan_topic
        ));
    }
    Ok(log)
}

/// Scans must come in time order.
fn check_order(name: &str, times: &[f64]) -> Result<()> {
    match times.windows(2).position(|w| w[1] < w[0] || w[1].is_nan()) {
        Some(k) => Err(anyhow!(
            "{name}: scan {} (t = {}) comes before scan {} (t = {}): scans must be in time order",
            k + 2,
            times[k + 1],
            k + 1,
            times[k]
        )),
        None => Ok(()),
    }
}
