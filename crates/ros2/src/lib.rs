//! # chronomap-ros2
//!
//! chronomap as a ROS 2 node, on [ros2-client](https://docs.rs/ros2-client) (RustDDS, pure
//! Rust: no ROS installation is needed to build or run it; it talks to any DDS-based ROS 2
//! node on the same domain). It learns online from topics and publishes predictions:
//!
//! * **states** (`std_msgs/msg/Bool`, `Float32`, `Float64` in [0, 1]) each learn a temporal
//!   model (`fremen:2`, ...; [Krajník 2017]) and publish p(now + Δ) and its entropy;
//! * **maps** (`nav_msgs/msg/OccupancyGrid`) are the frames of a spatio-temporal occupancy
//!   grid, one FreMEn model per cell ([Krajník 2017] §VI), which publishes the predicted map
//!   for now + Δ, a Nav2 costmap-filter mask and its `nav2_msgs/msg/CostmapFilterInfo`;
//! * **people** (`geometry_msgs/msg/PoseArray`) become a grid of "someone is here during this
//!   time bin", published as a predicted people map;
//! * **edges** of a topological map ([Fentanes 2015]) rewrite a Nav2 route graph (GeoJSON)
//!   with predicted success probabilities and durations.
//!
//! Models are saved to and restored from a folder (atomically, on a schedule and at shutdown).
//!
//! The crate only translates and schedules: [`world`] turns messages into observations and
//! predictions into messages with the domain crates (`chronomap-models`, `chronomap-grid`,
//! `chronomap-topo`) and files with `chronomap-io`; [`node`] moves messages over DDS. It logs
//! through the [`log`] facade (as ros2-client and RustDDS do) and prints nothing; the
//! `chronomap ros2` command installs the [`console`] logger and prints ([`topics`] lists what
//! `--check` shows). Parameters, topics and QoS are
//! described in `docs/ros2.md`.
//!
//! ```no_run
//! use chronomap_ros2::{config::Setup, node, ros_args::RosArgs, signals};
//!
//! // `chronomap ros2 --config node.yaml --ros-args -p horizon:=600.0`
//! let args = RosArgs::parse(["--ros-args", "-p", "horizon:=600.0"])?;
//! let setup = Setup::new(Some("node.yaml".as_ref()), None, args)?;
//! let stop = signals::stop_on_signals()?;
//! let summary = node::run(setup, &node::RunOptions::default(), &stop)?;
//! for (name, learned) in &summary.states {
//!     println!("{name}: {} observations", learned.observations);
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

pub mod config;
pub mod console;
pub mod journal;
pub mod lifecycle;
pub mod msgs;
pub mod node;
pub mod params;
pub mod ros_args;
pub mod rosout;
pub mod signals;
pub mod topics;
pub mod world;

pub use config::{ConfigError, NodeConfig};
/// The logging facade the node logs through (re-exported for the logger of the command line).
pub use log;
pub use node::{NodeError, Summary};
pub use world::{LearnError, Saved, StoreError, World};
