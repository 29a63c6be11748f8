//! Flags of `chronomap ingest` (and the `--bag` source of `grid build`).

#[allow(unused_imports)]
use super::*;

pub(super) const INGEST_HELP: &str = "\
Without --topic, lists the bag's topics, their types and counts, and what chronomap makes of
each. With --topic, learns from that topic; what it writes depends on the message type:

  std_msgs/msg/Bool, Float32, Float64    a model file, as `chronomap fit --model SPEC`
  nav_msgs/msg/OccupancyGrid              a grid file, as `chronomap grid build --frames`
                                          (for every option: `chronomap grid build --bag`)
  geometry_msgs/msg/PoseArray,            events `t x y` (for `events`, `hypertime`), or with
  people_msgs/msg/People                  --people tracks the CSV `t,person,x,y,speed,heading`
                                          of `activity` (People only: it has names)
  sensor_msgs/msg/LaserScan               scans: `t angle_min angle_increment range_min
                                          range_max n r_1 .. r_n` (inf: no return, REP 117)
  nav_msgs/msg/Odometry                   poses: `t x y yaw vx vy wz`

A bag is a rosbag2 folder (metadata.yaml and MCAP or SQLite 3 files, compressed with zstd or
not) or one .mcap or .db3 file. Messages are decoded with the definitions the bag carries
(bags from before Iron carry none: the types above are known built in), so no ROS
installation is needed. Times come from header.stamp when a message has a
header, else from when the recorder logged it (--time).

Examples:
  chronomap ingest data/malaga_laser_2006/rosbag2/malaga_2006_bag
  chronomap ingest door_bag --topic /door/open --model fremen:2 -o door.cmm
  chronomap predict door.cmm --at 2016-03-21T13:00:00Z
  chronomap ingest maps_bag --topic /map -o corridor.cmg
  chronomap ingest people_bag --topic /people --people tracks -o people.csv";

/// `chronomap ingest`.
#[derive(Debug, Args)]
pub struct IngestArgs {
    /// The bag: a rosbag2 folder (metadata.yaml + MCAP or SQLite files), an .mcap or a .db3 file.
    pub bag: PathBuf,
    /// The topic to learn from (without it, the bag's topics are listed).
    #[arg(long)]
    pub topic: Option<String>,
    /// State topics: the model, as `chronomap fit --model` (fremen:2, fremen:auto, hist:24, auto).
    #[arg(long, value_parser = parse_model)]
    pub model: Option<ModelSpec>,
    /// The file to write (a model, a grid, events or tracks, scans, poses: see below).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Where a message's time comes from.
    #[arg(long, value_enum, default_value_t = TimeArg::Auto)]
    pub time: TimeArg,
    /// People topics: write events (`t x y`) or tracks (`t,person,x,y,speed,heading`).
    #[arg(long, value_enum, default_value_t = PeopleFormat::Events)]
    pub people: PeopleFormat,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Fitting options (state topics; --periods and --holdout also for map topics).
    #[command(flatten)]
    pub fit: FitFlags,
}

/// `--time` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TimeArg {
    /// header.stamp if the message has a header, else the log time.
    Auto,
    /// header.stamp (messages without a header are an error).
    Header,
    /// When the recorder received the message.
    Log,
    /// When the publisher sent it, if the recorder stored that (else the log time).
    Publish,
}

impl From<TimeArg> for chronomap_rosbag::TimeSource {
    fn from(t: TimeArg) -> Self {
        use chronomap_rosbag::TimeSource as T;
        match t {
            TimeArg::Auto => T::Auto,
            TimeArg::Header => T::Header,
            TimeArg::Log => T::Log,
            TimeArg::Publish => T::Publish,
        }
    }
}

/// `--people` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PeopleFormat {
    /// `t x y` lines (`chronomap events`, `chronomap hypertime`).
    Events,
    /// `t,person,x,y,speed,heading` rows (`chronomap activity`); needs people_msgs/msg/People.
    Tracks,
}
