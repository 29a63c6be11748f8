//! rosbag2 bags without a ROS installation: the records a robot logged, as chronomap learns
//! from them.
//!
//! ```no_run
//! use chronomap_core::progress::NoProgress;
//! use chronomap_rosbag::{Bag, TimeSource};
//!
//! let bag = Bag::open("data/malaga_laser_2006/rosbag2/malaga_2006_bag")?;
//! let scans = bag.read_scans("/scan", TimeSource::Auto, &NoProgress)?;
//! let odometry = bag.read_odometry("/odom", TimeSource::Auto, &NoProgress)?;
//! assert_eq!((scans.len(), odometry.len()), (225, 224));
//! println!("{} beams, first range {} m", scans[0].ranges.len(), scans[0].ranges[0]);
//! # Ok::<(), chronomap_rosbag::BagError>(())
//! ```
//!
//! The layers, from the bytes up:
//! * [`msgdef`]: ROS 2 message definitions (`.msg` text, which rosbag2 stores in every MCAP
//!   bag as the `ros2msg` schema of a topic) parsed into a [`msgdef::Schema`];
//! * [`cdr`]: CDR, the wire format of ROS 2 messages, decoded by a schema into a
//!   [`cdr::Value`] that borrows the bytes; [`builtin`] holds the definitions of the types
//!   chronomap reads, for bags that carry none;
//! * [`bag`]: a rosbag2 folder (`metadata.yaml` + MCAP or SQLite files) or a single `.mcap`
//!   or `.db3`, read as a stream (MCAP by this crate's own reader, which checks every declared
//!   size against what remains and every CRC; SQLite by `rusqlite`), with errors that name the
//!   file, the record and the message;
//! * [`records`]: states, maps, people, scans and odometry taken from one topic, with their
//!   times ([`time`]: exact `f64` seconds from ROS stamps).
//!
//! Nothing here knows about models: the command line turns the records into temporal models,
//! grids and event files with the same code that reads text files, so that a bag and a text
//! file of the same observations give bit-identical models.

pub mod bag;
pub mod builtin;
pub mod cdr;
mod mcap_read;
pub mod msgdef;
pub mod records;
mod sqlite;
pub mod time;

pub use bag::{Bag, BagError, BagMessage, BagSummary, DefinitionSource, TopicSummary};
pub use records::{Detection, MapFrame, OdometryPose, RecordKind, Scan, StateSeries, TimeSource};
