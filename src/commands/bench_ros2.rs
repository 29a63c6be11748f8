//! `chronomap bench ros2`: the ROS 2 node's predicted maps to an rclpy subscriber against Fast DDS
//! to Fast DDS in the same run — [`chronomap_bench::ros2`] measures, this prints.

use anyhow::{Context, Result};
use chronomap_bench::ros2::MapsConfig;

use crate::cli::BenchRos2Args;
use crate::out;
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
    print_bench(args.json, &bench, |b| Ok(out!("{}", b.text())?))
}
