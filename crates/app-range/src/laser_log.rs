//! Laser logs: 2-D scans with where the robot was — by odometry alone (dead reckoning) and,
//! for keyframe files, by SLAM — read from the text files of the bundled Málaga log
//! (`chronomap_io::laser_text`) or from a rosbag2 bag (`sensor_msgs/msg/LaserScan` and
//! `nav_msgs/msg/Odometry`), and the keyframes a SLAM front end would pick from them. What
//! `chronomap lidar` and `chronomap maps` learn from ([Stüde 2024] §3.2–3.3).

use std::path::Path;

use chronomap_core::progress::Progress;
use chronomap_geometry::se2::{between, compose};
use chronomap_io::laser_text::{LaserTextError, read_keyframes, read_odometry, read_scans};
use chronomap_lidar::evaluation::keyframe_increments;
use chronomap_lidar::{Scan2d, ScanError};
use chronomap_rosbag::{Bag, BagError, TimeSource};

/// A laser log that cannot be read: the file or bag, and what is wrong.
#[derive(Debug, thiserror::Error)]
pub enum LaserLogError {
    /// A text file of the log breaks its format.
    #[error(transparent)]
    Text(#[from] LaserTextError),
    /// The bag cannot be read.
    #[error(transparent)]
    Bag(#[from] BagError),
    /// Scan `index` (1-based) has an earlier time than the scan before it.
    #[error(
        "{name}: scan {index} (t = {time}) comes before scan {} (t = {previous}): scans must be in time order",
        index - 1
    )]
    OutOfOrder {
        /// The file or bag.
        name: String,
        /// The 1-based index of the late scan.
        index: usize,
        /// Its time (s).
        time: f64,
        /// The time of the scan before it (s).
        previous: f64,
    },
    /// The odometry topic of a bag has no messages.
    #[error("{name}: topic {topic} has no odometry messages")]
    NoOdometry {
        /// The bag.
        name: String,
        /// The odometry topic.
        topic: String,
    },
    /// The scan topic of a bag has no messages.
    #[error("{name}: topic {topic} has no scans")]
    NoScans {
        /// The bag.
        name: String,
        /// The scan topic.
        topic: String,
    },
    /// An odometry pose of a bag that is not finite or beyond
    /// [`MAX_LENGTH_M`](chronomap_io::laser_text::MAX_LENGTH_M).
    #[error(
        "{name}: {topic} message {index}: pose ({x}, {y}, yaw {yaw}) is not finite or beyond ±{limit} m"
    )]
    BadOdometry {
        /// The bag.
        name: String,
        /// The odometry topic.
        topic: String,
        /// The 1-based message index.
        index: usize,
        /// Position `x` (m).
        x: f64,
        /// Position `y` (m).
        y: f64,
        /// Heading (rad).
        yaw: f64,
        /// The bound on lengths (m).
        limit: f64,
    },
    /// A scan message of a bag that is no valid scan.
    #[error("{name}: {topic} message {index}")]
    Scan {
        /// The bag.
        name: String,
        /// The scan topic.
        topic: String,
        /// The 1-based message index.
        index: usize,
        /// What is wrong with it.
        #[source]
        source: ScanError,
    },
}

/// A sequence of scans with where the robot was.
#[derive(Clone, Debug, PartialEq)]
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
    /// Odometry increments from scan to scan in the robot frame, `⊖p_{k−1} ⊕ p_k` ([Stüde 2024]
    /// eq. (3.11)); the first is zero.
    pub fn increments(&self) -> Vec<[f64; 3]> {
        let mut out = vec![[0.0; 3]];
        for w in self.odometry.windows(2) {
            out.push(between(w[0], w[1]));
        }
        out
    }

    /// The scans at least `distance` metres or `angle` radians of odometry apart (the first
    /// always): keyframes, as SLAM front ends choose them ([Stüde 2024] §3.2.1).
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

    /// The laser's pose in the map at scan `k` by SLAM, `robot ⊕ sensor`, if the log has SLAM
    /// poses.
    pub fn sensor_in_map(&self, k: usize) -> Option<[f64; 3]> {
        self.truth.as_ref().map(|t| compose(t[k], self.sensor))
    }
}

/// Where the scans and the odometry of a rosbag2 bag are.
#[derive(Clone, Debug, PartialEq)]
pub struct BagTopics {
    /// The `sensor_msgs/msg/LaserScan` topic.
    pub scans: String,
    /// The `nav_msgs/msg/Odometry` topic.
    pub odometry: String,
    /// The laser's position on the robot (`x, y`, m; the bag's scans carry no offset).
    pub sensor_offset: [f64; 2],
}

/// Dead reckoning: the robot's pose at each of `times` from odometry increments `(time,
/// increment)` in time order, each the motion up to its time, composed by [Stüde 2024]
/// eq. (3.11) from the origin at the first time.
pub fn dead_reckon(increments: &[(f64, [f64; 3])], times: &[f64]) -> Vec<[f64; 3]> {
    let mut pose = [0.0; 3];
    keyframe_increments(increments, times)
        .into_iter()
        .map(|inc| {
            pose = compose(pose, inc);
            pose
        })
        .collect()
}

/// The increments of an odometry file (`t dx dy dyaw`, robot frame).
fn odometry_increments(path: &Path) -> Result<Vec<(f64, [f64; 3])>, LaserLogError> {
    Ok(read_odometry(path)?
        .iter()
        .map(|o| (o.time, [o.dx, o.dy, o.dyaw]))
        .collect())
}

/// Reads a scan file with the odometry file of the same run: the robot's pose at each scan
/// by dead reckoning ([`dead_reckon`]).
///
/// # Errors
/// A file that breaks its format, or scans out of time order.
pub fn from_scans(scans: &Path, odometry: &Path) -> Result<LaserLog, LaserLogError> {
    let lines = read_scans(scans)?;
    let increments = odometry_increments(odometry)?;
    let times: Vec<f64> = lines.iter().map(|l| l.scan.time).collect();
    check_order(&scans.display().to_string(), &times)?;
    let sensor = lines.first().map_or([0.0; 3], |l| l.sensor.planar());
    Ok(LaserLog {
        name: scans.display().to_string(),
        odometry: dead_reckon(&increments, &times),
        scans: lines.into_iter().map(|l| l.scan).collect(),
        truth: None,
        sensor,
    })
}

/// Reads a keyframe file (SLAM poses and scans) with its odometry, if given (else the motion
/// between keyframes is the SLAM estimate's).
///
/// # Errors
/// A file that breaks its format, or keyframes out of time order.
pub fn from_keyframes(
    keyframes: &Path,
    odometry: Option<&Path>,
) -> Result<LaserLog, LaserLogError> {
    let frames = read_keyframes(keyframes)?;
    let times: Vec<f64> = frames.iter().map(|k| k.scan.scan.time).collect();
    check_order(&keyframes.display().to_string(), &times)?;
    let truth: Vec<[f64; 3]> = frames.iter().map(|k| k.pose).collect();
    let odometry = match odometry {
        Some(path) => dead_reckon(&odometry_increments(path)?, &times),
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
    let sensor = frames.first().map_or([0.0; 3], |k| k.scan.sensor.planar());
    Ok(LaserLog {
        name: keyframes.display().to_string(),
        scans: frames.into_iter().map(|k| k.scan.scan).collect(),
        odometry,
        truth: Some(truth),
        sensor,
    })
}

/// Reads the scans and odometry of a rosbag2 bag: the robot's pose at each scan is the latest
/// odometry pose not after it (or the first), relative to the first scan's.
///
/// # Errors
/// A bag that cannot be read, topics without messages, an odometry pose that is not finite or
/// beyond [`MAX_LENGTH_M`](chronomap_io::laser_text::MAX_LENGTH_M) (the bound of the text
/// logs), a scan that is no valid [`Scan2d`], scans out of time order.
pub fn from_bag(
    path: &Path,
    topics: &BagTopics,
    progress: &dyn Progress,
) -> Result<LaserLog, LaserLogError> {
    let bag = Bag::open(path)?;
    let scans = bag.read_scans(&topics.scans, TimeSource::Auto, progress)?;
    let odometry = bag.read_odometry(&topics.odometry, TimeSource::Auto, progress)?;
    if odometry.is_empty() {
        return Err(LaserLogError::NoOdometry {
            name: bag.name().to_string(),
            topic: topics.odometry.clone(),
        });
    }
    // The same bounds as the text logs: a pose beyond ±1e6 m or a non-finite one is refused.
    let limit = chronomap_io::laser_text::MAX_LENGTH_M;
    if let Some((k, o)) = odometry.iter().enumerate().find(|(_, o)| {
        !(o.position[0].abs() <= limit && o.position[1].abs() <= limit && o.yaw.is_finite())
    }) {
        return Err(LaserLogError::BadOdometry {
            name: bag.name().to_string(),
            topic: topics.odometry.clone(),
            index: k + 1,
            x: o.position[0],
            y: o.position[1],
            yaw: o.yaw,
            limit,
        });
    }
    let mut log = LaserLog {
        name: bag.name().to_string(),
        scans: Vec::with_capacity(scans.len()),
        odometry: Vec::with_capacity(scans.len()),
        truth: None,
        sensor: [topics.sensor_offset[0], topics.sensor_offset[1], 0.0],
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
        .map_err(|source| LaserLogError::Scan {
            name: log.name.clone(),
            topic: topics.scans.clone(),
            index: k + 1,
            source,
        })?;
        log.scans.push(converted);
    }
    if log.scans.is_empty() {
        return Err(LaserLogError::NoScans {
            name: log.name,
            topic: topics.scans.clone(),
        });
    }
    Ok(log)
}

/// Scans must come in time order.
fn check_order(name: &str, times: &[f64]) -> Result<(), LaserLogError> {
    match times.windows(2).position(|w| w[1] < w[0] || w[1].is_nan()) {
        Some(k) => Err(LaserLogError::OutOfOrder {
            name: name.to_string(),
            index: k + 2,
            time: times[k + 1],
            previous: times[k],
        }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log(odometry: Vec<[f64; 3]>) -> LaserLog {
        let scans = (0..odometry.len())
            .map(|k| Scan2d::new(k as f64, -1.0, 1.0, 10.0, vec![1.0; 3]).unwrap())
            .collect();
        LaserLog {
            name: "test".into(),
            scans,
            odometry,
            truth: None,
            sensor: [0.78, 0.0, 0.0],
        }
    }

    #[test]
    fn dead_reckoning_composes_the_increments_up_to_each_time() {
        // 1 m ahead, a quarter turn left, 1 m ahead: the robot ends at (1, 1) facing +y.
        let quarter = std::f64::consts::FRAC_PI_2;
        let increments = [
            (1.0, [1.0, 0.0, 0.0]),
            (2.0, [0.0, 0.0, quarter]),
            (3.0, [1.0, 0.0, 0.0]),
        ];
        let poses = dead_reckon(&increments, &[0.5, 2.0, 3.0]);
        assert_eq!(poses[0], [0.0; 3]);
        assert_eq!(poses[1], [1.0, 0.0, quarter]);
        assert!((poses[2][0] - 1.0).abs() < 1e-12 && (poses[2][1] - 1.0).abs() < 1e-12);
        assert_eq!(poses[2][2], quarter);
    }

    #[test]
    fn keyframes_keep_scans_far_enough_apart_by_distance_or_angle() {
        let l = log(vec![
            [0.0, 0.0, 0.0],
            [0.4, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.2, 0.0, 0.0],
            [1.2, 0.0, 0.6],
        ]);
        let k = l.keyframes(1.0, 0.5);
        // Scan 2 is 1 m from scan 0, scan 4 has turned 0.6 rad since scan 2.
        assert_eq!(
            k.odometry,
            vec![l.odometry[0], l.odometry[2], l.odometry[4]]
        );
        assert_eq!(k.scans.len(), 3);
        assert_eq!(k.scans[1].time, 2.0);
        let inc = l.increments();
        assert_eq!(inc.len(), 5);
        assert_eq!(inc[0], [0.0; 3]);
        for (got, want) in inc.iter().zip([
            [0.0; 3],
            [0.4, 0.0, 0.0],
            [0.6, 0.0, 0.0],
            [0.2, 0.0, 0.0],
            [0.0, 0.0, 0.6],
        ]) {
            for (g, w) in got.iter().zip(want) {
                assert!((g - w).abs() < 1e-12, "{got:?} {want:?}");
            }
        }
    }

    #[test]
    fn scans_out_of_time_order_are_refused_naming_both() {
        let e = check_order("scans.txt", &[1.0, 2.0, 1.5]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "scans.txt: scan 3 (t = 1.5) comes before scan 2 (t = 2): scans must be in time order"
        );
        assert!(check_order("scans.txt", &[1.0, 1.0, 2.0]).is_ok());
    }
}
