//! `chronomap bench ros2` end to end with tiny maps: the node learns a 20 × 20 map from rclpy and
//! publishes predicted maps that reach the rclpy subscriber, every one counted, as are the
//! rclpy publisher's; the report's sizes and ratios are those of its delays. (Speed itself is
//! measured by the command, never by a test.) Runs when `CHRONOMAP_ROS_PYTHON` names a Python
//! with rclpy and nav_msgs, as tests/cli/ros2_node.rs does.

use std::process::Command;

use crate::common::{json, oracle_python};
use crate::ros2_node::private_network_or_skip;

#[test]
fn bench_ros2_counts_every_map_of_both_publishers_and_reports_their_delays() {
    let enable = "set CHRONOMAP_ROS_PYTHON to a Python with ros-kilted-rclpy[fastrtps] and \
                  ros-kilted-nav-msgs (.ci/run makes target/ros-venv)";
    let Some(python) = oracle_python("ROS", "bench_ros2", "the ROS 2 map benchmark", enable) else {
        return;
    };
    if private_network_or_skip("bench_ros2").is_none() {
        return;
    }
    let out = Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args([
            "bench", "ros2", "--python", &python, "--sides", "20", "--maps", "3", "--period",
            "0.5", "--json",
        ])
        .output()
        .expect("run chronomap");
    let report = json(&out);
    assert_eq!(report["maps"], 3);
    assert_eq!(report["period"], 0.5);
    assert!(
        report["namespace"]
            .as_str()
            .is_some_and(|n| n.starts_with("unshare -")),
        "{report}"
    );
    let sizes = report["sizes"].as_array().expect("sizes");
    assert_eq!(sizes.len(), 1);
    let size = &sizes[0];
    assert_eq!(
        (size["side"].as_u64(), size["cells"].as_u64()),
        (Some(20), Some(400))
    );
    // CDR of a 20 x 20 OccupancyGrid in frame "map": encapsulation 4, header 16 (stamp, "map"),
    // map_load_time 8, resolution, width, height 12, padding to 8 bytes 4, origin 56, cell
    // count 4, cells 400.
    assert_eq!(size["bytes"], 504);
    let delays = |who: &str| -> Vec<f64> {
        size[who]["delays_seconds"]
            .as_array()
            .expect("delays")
            .iter()
            .map(|d| d.as_f64().expect("a delay"))
            .collect()
    };
    for who in ["chronomap", "fastdds"] {
        let d = &size[who];
        // Reliable delivery of small maps on loopback: all three, none lost.
        assert_eq!(
            (
                d["published"].as_u64(),
                d["received"].as_u64(),
                d["lost"].as_u64()
            ),
            (Some(3), Some(3), Some(0)),
            "{who}: {d}"
        );
        let mut sorted = delays(who);
        assert_eq!(sorted.len(), 3);
        assert!(sorted.iter().all(|&s| s > 0.0), "{who}: {sorted:?}");
        sorted.sort_by(f64::total_cmp);
        assert_eq!(d["median_seconds"].as_f64(), Some(sorted[1]), "{who}");
        assert_eq!(d["max_seconds"].as_f64(), Some(sorted[2]), "{who}");
    }
    assert_eq!(size["fastdds"]["reference"], "publish");
    let node = &size["chronomap"];
    assert!(
        ["publish", "stamp"].contains(&node["reference"].as_str().unwrap_or("")),
        "{node}"
    );
    // A map is handed to DDS after its stamp is taken.
    let since_stamp = node["median_since_stamp_seconds"]
        .as_f64()
        .expect("since stamp");
    assert!(node["median_seconds"].as_f64().unwrap() <= since_stamp);
    let ratio = size["ratio_median"].as_f64().unwrap();
    let expected = node["median_seconds"].as_f64().unwrap()
        / size["fastdds"]["median_seconds"].as_f64().unwrap();
    assert!(
        (ratio - expected).abs() <= 1e-12 * expected,
        "{ratio} {expected}"
    );
}
