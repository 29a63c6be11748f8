//! Laser logs for `chronomap lidar` and `chronomap maps`: the source flags translated into
//! [`chronomap_app_range::laser_log`], which reads the text files of the bundled Málaga log or a
//! rosbag2 bag.

use std::path::Path;

use anyhow::Result;
pub use chronomap_app_range::laser_log::LaserLog;
use chronomap_app_range::laser_log::{BagTopics, from_bag, from_keyframes, from_scans};

use crate::cli::LaserSourceArgs;
use crate::output::{ProgressBar, usage};

/// Reads the log the flags name.
pub fn read(args: &LaserSourceArgs) -> Result<LaserLog> {
    match (&args.keyframes, &args.scans, &args.bag) {
        (Some(keyframes), None, None) => read_keyframes_file(keyframes, args.odometry.as_deref()),
        (None, Some(scans), None) => {
            let odometry = args.odometry.as_deref().ok_or_else(|| {
                usage("--scans needs --odometry (the robot's motion between the scans)")
            })?;
            Ok(from_scans(scans, odometry)?)
        }
        (None, None, Some(bag)) => {
            let topics = BagTopics {
                scans: args.scan_topic.clone(),
                odometry: args.odom_topic.clone(),
                sensor_offset: args.sensor_offset,
            };
            Ok(from_bag(bag, &topics, &ProgressBar::new())?)
        }
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
    Ok(from_keyframes(path, odometry)?)
}
