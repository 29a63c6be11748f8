//! Large maps over DDS: how long the predicted `nav_msgs/msg/OccupancyGrid` maps of chronomap's
//! ROS 2 node (`chronomap ros2`, ros2-client on RustDDS) take to reach an rclpy subscriber with
//! Nav2's map QoS, against maps of the same size from an rclpy publisher to the same subscriber
//! (Fast DDS to Fast DDS) in the same run.
//!
//! The Python driver `tests/ros2/bench_maps.py` (embedded here) runs both inside a private
//! network namespace made here, starts the node binary it is given with a parameter file of one
//! map (`map_period` of the config), feeds it one observed map of each size and records when
//! each predicted map arrives; see its doc for what a delay is measured from. This module
//! makes the namespace, runs the driver and reduces its raw delays to medians, maxima, losses
//! and ratios.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};

use crate::{BenchError, median};

/// The Python driver.
const BENCH_MAPS_PY: &str = include_str!("../../../tests/ros2/bench_maps.py");

/// What the map benchmark runs.
#[derive(Clone, Debug, PartialEq)]
pub struct MapsConfig {
    /// A Python with rclpy (Fast DDS) and nav_msgs.
    pub python: PathBuf,
    /// The `chronomap` binary whose `ros2` node is measured.
    pub node: PathBuf,
    /// Map sides in cells (a side of 1000 is a 1 MB map, 2000 a 4 MB one).
    pub sides: Vec<u32>,
    /// Maps measured per side and publisher (after the driver's warm-up maps).
    pub maps: usize,
    /// Seconds between maps (the node's `map_period`, and the Fast DDS publisher's).
    pub period: f64,
}

/// Delivery of the maps of one publisher.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Delivery {
    /// Maps published in the measured span.
    pub published: usize,
    /// Maps received of them.
    pub received: usize,
    /// `published - received`.
    pub lost: usize,
    /// Median delay, seconds (receipt − publish; NaN if none arrived).
    pub median_seconds: f64,
    /// Largest delay, seconds.
    pub max_seconds: f64,
    /// Every delay, in order of receipt.
    pub delays_seconds: Vec<f64>,
    /// What the node's delays start at: `publish` (the moment the node handed the map to DDS,
    /// from its log) or `stamp` (its header stamp, taken before predicting). Fast DDS: `publish`.
    pub reference: String,
    /// The node only: median of receipt − header stamp, i.e. prediction and delivery.
    pub median_since_stamp_seconds: Option<f64>,
}

/// One map size.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MapSize {
    /// Cells per side.
    pub side: u32,
    /// Cells.
    pub cells: u64,
    /// Serialized size of one map (CDR, encapsulation included).
    pub bytes: u64,
    /// From the node.
    pub chronomap: Delivery,
    /// From the rclpy publisher.
    pub fastdds: Delivery,
    /// Median delay of the node's maps over that of Fast DDS's.
    pub ratio_median: f64,
    /// Largest delay of the node's maps over that of Fast DDS's.
    pub ratio_max: f64,
}

/// The result of `chronomap bench ros2`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MapsBench {
    /// Maps measured per size and publisher.
    pub maps: usize,
    /// Maps received before the measured ones.
    pub warmup: usize,
    /// Seconds between maps.
    pub period: f64,
    /// The subscriber's ROS middleware.
    pub rmw: String,
    /// The driver's Python version.
    pub python: String,
    /// How the private network namespace was made.
    pub namespace: String,
    /// Per size.
    pub sizes: Vec<MapSize>,
}

/// The driver's report (raw delays).
#[derive(Deserialize)]
struct Report {
    maps: usize,
    warmup: usize,
    period: f64,
    rmw: String,
    python: String,
    sides: Vec<SideReport>,
}

#[derive(Deserialize)]
struct SideReport {
    side: u32,
    cells: u64,
    bytes: u64,
    chronomap: PublisherReport,
    fastdds: PublisherReport,
}

#[derive(Deserialize)]
struct PublisherReport {
    published: Option<usize>,
    maps: Vec<MapReport>,
    #[serde(default)]
    reference: Option<String>,
}

#[derive(Deserialize)]
struct MapReport {
    delay: f64,
    #[serde(default)]
    since_stamp: Option<f64>,
}

/// A command prefix that runs a program in a new network namespace with only loopback, up and
/// with multicast (`PREFIX program args...`): `unshare -n` as root, else `unshare -rn` (a user
/// namespace). `None` if neither works here.
fn private_network() -> Option<Vec<String>> {
    let script = "ip link set lo up && ip link set lo multicast on && exec \"$0\" \"$@\"";
    [["unshare", "-n"], ["unshare", "-rn"]]
        .into_iter()
        .map(|unshare| {
            let mut prefix: Vec<String> = unshare.iter().map(|s| s.to_string()).collect();
            prefix.extend(["sh".into(), "-c".into(), script.into()]);
            prefix
        })
        .find(|prefix| {
            Command::new(&prefix[0])
                .args(&prefix[1..])
                .arg("true")
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .status()
                .is_ok_and(|s| s.success())
        })
}

fn delivery(report: &PublisherReport, fallback_reference: &str) -> Delivery {
    let delays: Vec<f64> = report.maps.iter().map(|m| m.delay).collect();
    let since: Vec<f64> = report.maps.iter().filter_map(|m| m.since_stamp).collect();
    let received = delays.len();
    let published = report.published.unwrap_or(received).max(received);
    Delivery {
        published,
        received,
        lost: published - received,
        median_seconds: median(&delays),
        max_seconds: delays.iter().copied().fold(f64::NAN, f64::max),
        delays_seconds: delays,
        reference: report
            .reference
            .clone()
            .unwrap_or_else(|| fallback_reference.to_string()),
        median_since_stamp_seconds: (!since.is_empty()).then(|| median(&since)),
    }
}

fn reduce(report: Report, namespace: String) -> MapsBench {
    let sizes = report
        .sides
        .into_iter()
        .map(|s| {
            let chronomap = delivery(&s.chronomap, "stamp");
            let fastdds = delivery(&s.fastdds, "publish");
            MapSize {
                side: s.side,
                cells: s.cells,
                bytes: s.bytes,
                ratio_median: chronomap.median_seconds / fastdds.median_seconds,
                ratio_max: chronomap.max_seconds / fastdds.max_seconds,
                chronomap,
                fastdds,
            }
        })
        .collect();
    MapsBench {
        maps: report.maps,
        warmup: report.warmup,
        period: report.period,
        rmw: report.rmw,
        python: report.python,
        namespace,
        sizes,
    }
}

/// A scratch folder, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> Result<Self, BenchError> {
        let nanos = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        let dir = std::env::temp_dir().join(format!(
            "chronomap-bench-ros2-{}-{nanos}",
            std::process::id()
        ));
        std::fs::create_dir_all(&dir).map_err(|source| BenchError::Write {
            path: dir.clone(),
            source,
        })?;
        Ok(TempDir(dir))
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn write(path: &Path, contents: &str) -> Result<(), BenchError> {
    std::fs::write(path, contents).map_err(|source| BenchError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// Runs the benchmark: the driver's progress goes to this process's stderr.
///
/// # Errors
/// No private network namespace, a driver that cannot start, fails or prints no report.
pub fn run(config: &MapsConfig) -> Result<MapsBench, BenchError> {
    let prefix = private_network().ok_or(BenchError::NoPrivateNetwork)?;
    let dir = TempDir::new()?;
    let script = dir.0.join("bench_maps.py");
    write(&script, BENCH_MAPS_PY)?;
    let sides = config
        .sides
        .iter()
        .map(u32::to_string)
        .collect::<Vec<_>>()
        .join(",");
    let output = Command::new(&prefix[0])
        .args(&prefix[1..])
        .arg("env")
        .arg(format!("ROS_HOME={}", dir.0.join("ros-home").display()))
        .arg(&config.python)
        .arg(&script)
        .arg("--node")
        .arg(&config.node)
        .arg("--dir")
        .arg(&dir.0)
        .args(["--sides", &sides])
        .args(["--maps", &config.maps.to_string()])
        .args(["--period", &config.period.to_string()])
        .stdin(Stdio::null())
        .stderr(Stdio::inherit())
        .output()
        .map_err(|source| BenchError::MapsStart {
            python: config.python.clone(),
            source,
        })?;
    if !output.status.success() {
        return Err(BenchError::MapsFailed {
            python: config.python.clone(),
            status: output.status.to_string(),
        });
    }
    let report: Report = serde_json::from_slice(&output.stdout)
        .map_err(|e| BenchError::MapsOutput(e.to_string()))?;
    Ok(reduce(report, prefix[..2].join(" ")))
}

impl MapsBench {
    /// The result as `chronomap bench ros2` prints it.
    pub fn text(&self) -> String {
        let b = self;
        let mut text = String::new();
        let _ = writeln!(
            text,
            "predicted maps, {} per size after {} warm-up maps, one every {} s; subscriber: rclpy \
         (Python {}, {}) with Nav2's map QoS (reliable, transient local, keep last 1); private \
         network namespace ({})",
            b.maps, b.warmup, b.period, b.python, b.rmw, b.namespace
        );
        let _ = writeln!(
            text,
            "{:<20} {:<26} {:>11} {:>9} {:>9}   ratio (median, max)",
            "map", "publisher", "received", "median", "max"
        );
        for s in &b.sizes {
            let map = format!("{}x{} {:.1} MB", s.side, s.side, s.bytes as f64 / 1e6);
            let _ = writeln!(
                text,
                "{}   {:.1}, {:.1}",
                row(&map, "chronomap ros2 (RustDDS)", &s.chronomap),
                s.ratio_median,
                s.ratio_max
            );
            let _ = writeln!(text, "{}", row("", "rclpy (Fast DDS)", &s.fastdds));
        }
        let stamped = b.sizes.iter().any(|s| s.chronomap.reference == "stamp");
        if stamped {
            let _ = writeln!(
                text,
                "the node logs no moment it hands a map to DDS: its delays start at the map's stamp, \
             taken before predicting (prediction included)"
            );
        } else {
            let since: Vec<String> = b
                .sizes
                .iter()
                .map(|s| {
                    format!(
                        "{}x{}: {}",
                        s.side,
                        s.side,
                        s.chronomap
                            .median_since_stamp_seconds
                            .map_or("-".into(), seconds)
                    )
                })
                .collect();
            let _ = writeln!(
                text,
                "delays from the moment the map is handed to DDS (the node's debug log; Fast DDS: \
             the publish call); the node's median from the map's stamp, prediction included: {}",
                since.join(", ")
            );
        }
        text
    }
}

/// Seconds with 3 decimals, `-` for none.
fn seconds(s: f64) -> String {
    if s.is_nan() {
        "-".into()
    } else {
        format!("{s:.3} s")
    }
}

/// One line of the table: map, publisher, received of published, median and max delay.
fn row(map: &str, publisher: &str, d: &Delivery) -> String {
    format!(
        "{map:<20} {publisher:<26} {:>5}/{:<5} {:>9} {:>9}",
        d.received,
        d.published,
        seconds(d.median_seconds),
        seconds(d.max_seconds)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A report of one 1000×1000 map size: three maps from chronomap (one lost of four
    /// published), three from Fast DDS (none lost of three).
    fn hand_made_report() -> Report {
        serde_json::from_str(
            r#"{"maps": 3, "warmup": 2, "period": 1.0, "rmw": "rmw_fastrtps_cpp",
            "python": "3.11.2", "sides": [{"side": 1000, "cells": 1000000, "bytes": 1000104,
            "chronomap": {"published": 4, "reference": "publish", "maps": [
                {"delay": 0.3, "since_stamp": 0.5}, {"delay": 0.1, "since_stamp": 0.2},
                {"delay": 0.2, "since_stamp": 0.4}]},
            "fastdds": {"published": 3, "maps": [
                {"delay": 0.05}, {"delay": 0.02}, {"delay": 0.1}]}}]}"#,
        )
        .unwrap()
    }

    /// Medians, maxima, losses and ratios of a hand-made report.
    #[test]
    fn reports_reduce_to_medians_losses_and_ratios() {
        let report = hand_made_report();
        let bench = reduce(report, "unshare -n".into());
        let size = &bench.sizes[0];
        let c = &size.chronomap;
        assert_eq!((c.published, c.received, c.lost), (4, 3, 1));
        assert_eq!((c.median_seconds, c.max_seconds), (0.2, 0.3));
        assert_eq!(c.median_since_stamp_seconds, Some(0.4));
        assert_eq!(c.reference, "publish");
        let f = &size.fastdds;
        assert_eq!((f.published, f.received, f.lost), (3, 3, 0));
        assert_eq!((f.median_seconds, f.max_seconds), (0.05, 0.1));
        assert_eq!(f.reference, "publish");
        assert_eq!(f.median_since_stamp_seconds, None);
        assert!((size.ratio_median - 4.0).abs() < 1e-12);
        assert!((size.ratio_max - 3.0).abs() < 1e-12);
    }

    /// A node whose log has no publish lines: delays from the stamps, and nothing received is
    /// a NaN median, not a panic.
    #[test]
    fn stamps_are_the_fallback_and_no_map_is_nan() {
        let report: Report = serde_json::from_str(
            r#"{"maps": 2, "warmup": 2, "period": 1.0, "rmw": "x", "python": "3",
                "sides": [{"side": 10, "cells": 100, "bytes": 204,
                "chronomap": {"published": null, "maps": []},
                "fastdds": {"published": 2, "maps": [{"delay": 0.01}]}}]}"#,
        )
        .unwrap();
        let size = &reduce(report, "unshare -rn".into()).sizes[0];
        assert_eq!(size.chronomap.reference, "stamp");
        assert_eq!((size.chronomap.published, size.chronomap.lost), (0, 0));
        assert!(size.chronomap.median_seconds.is_nan() && size.ratio_median.is_nan());
        assert_eq!((size.fastdds.received, size.fastdds.lost), (1, 1));
    }

    /// The text of a hand-made report: one line per publisher and size, the node's delays
    /// since the stamp last.
    #[test]
    fn the_text_has_a_line_per_publisher_and_the_delays_since_the_stamp() {
        let report = hand_made_report();
        let text = reduce(report, "unshare -n".into()).text();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 5);
        assert!(
            lines[0].starts_with("predicted maps, 3 per size after 2 warm-up maps, one every 1 s;")
        );
        assert!(lines[0].ends_with("(Python 3.11.2, rmw_fastrtps_cpp) with Nav2's map QoS (reliable, transient local, keep last 1); private network namespace (unshare -n)"));
        assert_eq!(
            lines[2],
            "1000x1000 1.0 MB     chronomap ros2 (RustDDS)       3/4       0.200 s   0.300 s   4.0, 3.0"
        );
        assert_eq!(
            lines[3],
            "                     rclpy (Fast DDS)               3/3       0.050 s   0.100 s"
        );
        assert!(lines[4].ends_with("prediction included: 1000x1000: 0.400 s"));
    }
}
