//! `chronomap bench ros2`: the ROS 2 node's predicted maps to an rclpy subscriber against Fast DDS
//! to Fast DDS in the same run — [`chronomap_bench::ros2`] measures, this prints.

use anyhow::{Context, Result};
use chronomap_bench::ros2::{Delivery, MapsBench, MapsConfig};

use crate::cli::BenchRos2Args;
use crate::outln;
use crate::output::print_bench;

pub fn ros2(args: &BenchRos2Args) -> Result<()> {
    let node = std::env::current_exe().context("cannot find this program to run its node")?;
    let bench = chronomap_bench::ros2::run(&MapsConfig {
        python: args.python.clone(),
        node,
        sides: args.sides.clone(),
        maps: args.maps as usize,
        period: args.period,
    })?;
    print_bench(args.json, &bench, print)
}

fn seconds(s: f64) -> String {
    if s.is_nan() {
        "-".into()
    } else {
        format!("{s:.3} s")
    }
}

fn row(map: &str, publisher: &str, d: &Delivery) -> String {
    format!(
        "{map:<20} {publisher:<26} {:>5}/{:<5} {:>9} {:>9}",
        d.received,
        d.published,
        seconds(d.median_seconds),
        seconds(d.max_seconds)
    )
}

fn print(b: &MapsBench) -> Result<()> {
    outln!(
        "predicted maps, {} per size after {} warm-up maps, one every {} s; subscriber: rclpy \
         (Python {}, {}) with Nav2's map QoS (reliable, transient local, keep last 1); private \
         network namespace ({})",
        b.maps,
        b.warmup,
        b.period,
        b.python,
        b.rmw,
        b.namespace
    )?;
    outln!(
        "{:<20} {:<26} {:>11} {:>9} {:>9}   ratio (median, max)",
        "map",
        "publisher",
        "received",
        "median",
        "max"
    )?;
    for s in &b.sizes {
        let map = format!("{}x{} {:.1} MB", s.side, s.side, s.bytes as f64 / 1e6);
        outln!(
            "{}   {:.1}, {:.1}",
            row(&map, "chronomap ros2 (RustDDS)", &s.chronomap),
            s.ratio_median,
            s.ratio_max
        )?;
        outln!("{}", row("", "rclpy (Fast DDS)", &s.fastdds))?;
    }
    let stamped = b.sizes.iter().any(|s| s.chronomap.reference == "stamp");
    if stamped {
        outln!(
            "the node logs no moment it hands a map to DDS: its delays start at the map's stamp, \
             taken before predicting (prediction included)"
        )?;
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
        outln!(
            "delays from the moment the map is handed to DDS (the node's debug log; Fast DDS: \
             the publish call); the node's median from the map's stamp, prediction included: {}",
            since.join(", ")
        )?;
    }
    Ok(())
}
