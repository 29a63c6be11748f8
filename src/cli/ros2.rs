//! Flags of `chronomap ros2`.

#[allow(unused_imports)]
use super::*;

pub(super) const ROS2_HELP: &str = "\
Examples:
  chronomap ros2 --config node.yaml                 # run until SIGINT/SIGTERM, then save
  chronomap ros2 --config node.yaml --check --json  # check the parameters, list the topics
  ROS_DOMAIN_ID=7 chronomap ros2 --config node.yaml --log-level debug
  chronomap ros2 --ros-args --params-file node.yaml -r __ns:=/robot1 -p horizon:=600.0
  chronomap ros2 --managed --config node.yaml       # a lifecycle node: starts unconfigured

The parameter file is a ROS 2 parameter file:
  chronomap:
    ros__parameters:
      use_sim_time: false
      horizon: 0.0            # predict for now + horizon seconds
      save_dir: chronomap-node
      states:
        door: {topic: /door, type: std_msgs/msg/Bool, model: fremen:2}
      maps:
        office: {topic: /observed_map, order: 2}
ROS arguments go last, as ros2 run and launch files pass them: --ros-args with -r FROM:=TO
(and __node:=NAME, __ns:=/NS), -p NAME:=VALUE (dotted names: -p states.door.model:=hist:24),
--params-file FILE, --log-level [LOGGER:=]LEVEL; they apply on top of --config. Parameters are
ROS parameters (ros2 param list/get/set); the node logs to stderr and /rosout. Every
parameter, topic and QoS: docs/ros2.md. The counts of what was learned are printed on stdout
when the node stops.";

/// `chronomap ros2`.
#[derive(Debug, Args)]
pub struct Ros2Args {
    /// ROS 2 parameter file of the node (`NODE: {ros__parameters: {...}}`): its only entry,
    /// or --node-name's, is the node's parameters (ROS arguments apply on top).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// The node whose entry of the file to use (default: the only entry); also the name for
    /// a `/**` entry.
    #[arg(long)]
    pub node_name: Option<String>,
    /// DDS domain (as ROS_DOMAIN_ID).
    #[arg(long, env = "ROS_DOMAIN_ID", default_value_t = 0, value_parser = clap::value_parser!(u16).range(0..=232))]
    pub domain_id: u16,
    /// Check the parameter file and list the topics, without joining the network.
    #[arg(long)]
    pub check: bool,
    /// Least severe messages of the node logged on stderr.
    #[arg(long, value_enum, default_value_t = LogLevelArg::Info)]
    pub log_level: LogLevelArg,
    /// Least severe messages of the DDS libraries (ros2-client, RustDDS) logged on stderr.
    #[arg(long, value_enum, default_value_t = LogLevelArg::Error)]
    pub dds_log_level: LogLevelArg,
    /// Print one JSON object (the topics with --check; what was learned when stopped).
    #[arg(long)]
    pub json: bool,
    /// A managed (lifecycle) node: it starts unconfigured and is configured, activated,
    /// deactivated and cleaned up through its lifecycle services (nav2_lifecycle_manager,
    /// `ros2 lifecycle set`).
    #[arg(long)]
    pub managed: bool,
    /// ROS arguments, as rcl reads them; everything after --ros-args is one (-r, -p,
    /// --params-file, --log-level, ...).
    #[arg(
        long = "ros-args",
        num_args = 0..,
        allow_hyphen_values = true,
        value_name = "ROS_ARG"
    )]
    pub ros_args: Option<Vec<String>>,
}

/// `--log-level` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, ValueEnum)]
pub enum LogLevelArg {
    /// Nothing.
    Off,
    /// Errors.
    Error,
    /// Errors and warnings.
    Warn,
    /// ... and what the node does (default).
    Info,
    /// ... and details.
    Debug,
    /// ... and every message learned.
    Trace,
}
