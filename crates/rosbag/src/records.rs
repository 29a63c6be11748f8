//! What chronomap learns from a bag: states (door open or not), occupancy maps, people,
//! laser scans and odometry, taken from the decoded messages of one topic.
//!
//! | kind | message types | becomes |
//! |---|---|---|
//! | [`RecordKind::State`] | `std_msgs/msg/Bool`, `Float32`, `Float64` | a time series of values in `[0, 1]` |
//! | [`RecordKind::Map`] | `nav_msgs/msg/OccupancyGrid` | map frames (cells `-1`, `0..=100`) |
//! | [`RecordKind::People`] | `geometry_msgs/msg/PoseArray`, `people_msgs/msg/People` | detections at a time and place |
//! | [`RecordKind::Scan`] | `sensor_msgs/msg/LaserScan` | scans |
//! | [`RecordKind::Odometry`] | `nav_msgs/msg/Odometry` | poses |
//!
//! Times come from the message's `header.stamp` when it has a header, else from the time
//! the recorder logged it ([`TimeSource`]); they must not go backwards within a topic. Every
//! problem is a [`BagError`] naming the message (bag position, topic position, log time) and
//! the field.

use chronomap_core::progress::Progress;

use crate::bag::{Bag, BagError, BagMessage};
use crate::cdr::Value;
use crate::msgdef::canonical_type_name;
use crate::time::{nanos_seconds, stamp_seconds};

/// Where a message's time comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TimeSource {
    /// `header.stamp` if the message has a header, else the log time.
    #[default]
    Auto,
    /// `header.stamp` (an error for messages without a header).
    Header,
    /// When the recorder received the message.
    Log,
    /// When the publisher sent it, as the recorder stored it (else the log time).
    Publish,
}

/// What a message type becomes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecordKind {
    /// A state in `[0, 1]`: a temporal model.
    State,
    /// An occupancy map: a frame of a grid.
    Map,
    /// People seen at places: events or tracks.
    People,
    /// A 2-D laser scan.
    Scan,
    /// Odometry.
    Odometry,
}

impl RecordKind {
    /// The kind of a message type (`pkg/msg/Type` or `pkg/Type`), if chronomap reads it.
    pub fn of(type_name: &str) -> Option<RecordKind> {
        let name = canonical_type_name(type_name)?;
        Some(match name.as_str() {
            "std_msgs/msg/Bool" | "std_msgs/msg/Float32" | "std_msgs/msg/Float64" => {
                RecordKind::State
            }
            "nav_msgs/msg/OccupancyGrid" => RecordKind::Map,
            "geometry_msgs/msg/PoseArray" | "people_msgs/msg/People" => RecordKind::People,
            "sensor_msgs/msg/LaserScan" => RecordKind::Scan,
            "nav_msgs/msg/Odometry" => RecordKind::Odometry,
            _ => return None,
        })
    }

    /// The types of this kind, for messages.
    pub fn types(self) -> &'static str {
        match self {
            RecordKind::State => "std_msgs/msg/Bool, Float32 or Float64",
            RecordKind::Map => "nav_msgs/msg/OccupancyGrid",
            RecordKind::People => "geometry_msgs/msg/PoseArray or people_msgs/msg/People",
            RecordKind::Scan => "sensor_msgs/msg/LaserScan",
            RecordKind::Odometry => "nav_msgs/msg/Odometry",
        }
    }

    /// A word for the kind.
    pub fn name(self) -> &'static str {
        match self {
            RecordKind::State => "state",
            RecordKind::Map => "map",
            RecordKind::People => "people",
            RecordKind::Scan => "scan",
            RecordKind::Odometry => "odometry",
        }
    }
}

/// States of one topic, in time order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StateSeries {
    /// Times (s), never going backwards.
    pub times: Vec<f64>,
    /// Values in `[0, 1]` (`Bool`: 0 or 1).
    pub values: Vec<f64>,
}

/// One occupancy map.
#[derive(Clone, Debug, PartialEq)]
pub struct MapFrame {
    /// Its time (s).
    pub time: f64,
    /// `header.frame_id`.
    pub frame_id: String,
    /// Cells per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Cell size (m).
    pub resolution: f32,
    /// `[x, y, yaw]` of the lower-left corner of cell (0, 0).
    pub origin: [f64; 3],
    /// Row-major cells, row 0 at the bottom: `-1` unknown, `0..=100` occupancy in percent.
    pub data: Vec<i8>,
}

/// A person (or anything a people topic reports) seen at a time and place.
#[derive(Clone, Debug, PartialEq)]
pub struct Detection {
    /// Its time (s).
    pub time: f64,
    /// Position (m, in `frame_id`).
    pub x: f64,
    /// Position (m).
    pub y: f64,
    /// `people_msgs/Person.name`; `None` for poses without identity.
    pub person: Option<String>,
    /// `people_msgs/Person.velocity` (m/s); `None` for poses.
    pub velocity: Option<[f64; 2]>,
    /// `header.frame_id`.
    pub frame_id: String,
}

/// A 2-D laser scan (`sensor_msgs/msg/LaserScan`, REP 117: `+inf` is no return).
#[derive(Clone, Debug, PartialEq)]
pub struct Scan {
    /// Its time (s).
    pub time: f64,
    /// `header.frame_id`.
    pub frame_id: String,
    /// Angle of the first beam (rad, counter-clockwise, 0 ahead).
    pub angle_min: f32,
    /// Angle of the last beam (rad).
    pub angle_max: f32,
    /// Angle between beams (rad).
    pub angle_increment: f32,
    /// Time between beams (s).
    pub time_increment: f32,
    /// Time between scans (s).
    pub scan_time: f32,
    /// Shortest valid range (m).
    pub range_min: f32,
    /// Longest valid range (m).
    pub range_max: f32,
    /// Ranges (m).
    pub ranges: Vec<f32>,
    /// Intensities (device units; may be empty).
    pub intensities: Vec<f32>,
}

/// A pose and velocity from odometry (`nav_msgs/msg/Odometry`).
#[derive(Clone, Debug, PartialEq)]
pub struct OdometryPose {
    /// Its time (s).
    pub time: f64,
    /// `header.frame_id` (the odometry frame).
    pub frame_id: String,
    /// `child_frame_id` (the robot).
    pub child_frame_id: String,
    /// Position (m).
    pub position: [f64; 3],
    /// Heading about z (rad), from the orientation quaternion.
    pub yaw: f64,
    /// Linear velocity (m/s, robot frame).
    pub linear: [f64; 3],
    /// Angular velocity (rad/s).
    pub angular: [f64; 3],
}

/// The `f64` at `path`, or a "wrong schema" problem.
fn number(v: &Value<'_>, path: &str) -> Result<f64, String> {
    match v.path(path) {
        Some(x) => x
            .as_f64()
            .ok_or_else(|| format!("field `{path}` is {}, not a number", x.kind())),
        None => Err(format!("the message has no field `{path}`")),
    }
}

/// The finite `f64` at `path`.
fn finite(v: &Value<'_>, path: &str) -> Result<f64, String> {
    let x = number(v, path)?;
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("field `{path}` is {x}, not a finite number"))
    }
}

fn string(v: &Value<'_>, path: &str) -> Result<String, String> {
    match v.path(path) {
        Some(Value::String(s)) => Ok(s.to_string()),
        Some(x) => Err(format!("field `{path}` is {}, not a string", x.kind())),
        None => Err(format!("the message has no field `{path}`")),
    }
}

fn floats(v: &Value<'_>, path: &str) -> Result<Vec<f32>, String> {
    match v.path(path) {
        Some(Value::Array(items)) => items
            .iter()
            .map(|x| match x {
                Value::F32(f) => Ok(*f),
                other => Err(format!(
                    "field `{path}` holds {}, not float32",
                    other.kind()
                )),
            })
            .collect(),
        Some(x) => Err(format!(
            "field `{path}` is {}, not a float32 array",
            x.kind()
        )),
        None => Err(format!("the message has no field `{path}`")),
    }
}

/// Heading about z of the quaternion at `path` (`x, y, z, w`).
fn yaw(v: &Value<'_>, path: &str) -> Result<f64, String> {
    let q = |c: &str| finite(v, &format!("{path}.{c}"));
    let (x, y, z, w) = (q("x")?, q("y")?, q("z")?, q("w")?);
    Ok((2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z)))
}

/// The time of a message.
///
/// # Errors
/// `Header` for a message without a header, a stamp before 1970 or with `nanosec >= 10⁹`.
pub fn message_time(m: &BagMessage, v: &Value<'_>, source: TimeSource) -> Result<f64, String> {
    let has_header = v.get("header").is_some();
    match source {
        TimeSource::Log => Ok(nanos_seconds(m.log_time)),
        TimeSource::Publish => Ok(nanos_seconds(m.publish_time)),
        TimeSource::Auto if !has_header => Ok(nanos_seconds(m.log_time)),
        TimeSource::Header if !has_header => Err(
            "the message has no header, so no stamp: take the time the recorder logged it instead"
                .into(),
        ),
        TimeSource::Auto | TimeSource::Header => {
            let sec = v
                .path("header.stamp.sec")
                .and_then(Value::as_i64)
                .ok_or("field `header.stamp.sec` is not an integer")?;
            let nanosec = v
                .path("header.stamp.nanosec")
                .and_then(Value::as_i64)
                .ok_or("field `header.stamp.nanosec` is not an integer")?;
            stamp_seconds(sec, nanosec as u64).ok_or_else(|| {
                format!("header.stamp {sec} s {nanosec} ns is not a time after 1970 (sec >= 0, nanosec < 10⁹)")
            })
        }
    }
}

/// A state's value: `data` as 0/1 (`Bool`) or a number in `[0, 1]`.
pub fn state_value(v: &Value<'_>) -> Result<f64, String> {
    let x = finite(v, "data")?;
    if (0.0..=1.0).contains(&x) {
        Ok(x)
    } else {
        Err(format!(
            "field `data` is {x}, outside [0, 1] (states are probabilities or 0/1)"
        ))
    }
}

/// Largest map taken from a bag, in cells (the limit of `chronomap_io::navmap` images).
pub const MAX_MAP_CELLS: u64 = 1 << 30;

/// An occupancy map (without its time).
pub fn map_frame(v: &Value<'_>, time: f64) -> Result<MapFrame, String> {
    let int = |path: &str| -> Result<u32, String> {
        let x = number(v, path)?;
        if x >= 0.0 && x <= f64::from(u32::MAX) && x.fract() == 0.0 {
            Ok(x as u32)
        } else {
            Err(format!("field `{path}` is {x}, not a size"))
        }
    };
    let (width, height) = (int("info.width")?, int("info.height")?);
    let cells = u64::from(width) * u64::from(height);
    if cells > MAX_MAP_CELLS {
        return Err(format!(
            "a map of {width} × {height} cells is larger than the {MAX_MAP_CELLS} cells chronomap takes"
        ));
    }
    let data = match v.get("data") {
        Some(Value::Bytes(b)) => b,
        Some(x) => return Err(format!("field `data` is {}, not an int8 array", x.kind())),
        None => return Err("the message has no field `data`".into()),
    };
    if data.len() as u64 != cells {
        return Err(format!(
            "field `data` has {} cells, but info says {width} × {height} = {cells}",
            data.len()
        ));
    }
    let resolution = number(v, "info.resolution")? as f32;
    if !(resolution.is_finite() && resolution > 0.0) {
        return Err(format!(
            "field `info.resolution` is {resolution}, not a positive cell size"
        ));
    }
    Ok(MapFrame {
        time,
        frame_id: string(v, "header.frame_id")?,
        width,
        height,
        resolution,
        origin: [
            finite(v, "info.origin.position.x")?,
            finite(v, "info.origin.position.y")?,
            yaw(v, "info.origin.orientation")?,
        ],
        data: data.iter().map(|&b| b as i8).collect(),
    })
}

/// The detections of one people message (`PoseArray` or `People`).
pub fn detections(v: &Value<'_>, time: f64) -> Result<Vec<Detection>, String> {
    let frame_id = string(v, "header.frame_id")?;
    if let Some(poses) = v.get("poses") {
        let poses = poses
            .as_array()
            .ok_or("field `poses` is not an array of poses")?;
        poses
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let at = |c: &str| {
                    finite(p, &format!("position.{c}")).map_err(|e| format!("poses[{i}]: {e}"))
                };
                Ok(Detection {
                    time,
                    x: at("x")?,
                    y: at("y")?,
                    person: None,
                    velocity: None,
                    frame_id: frame_id.clone(),
                })
            })
            .collect()
    } else if let Some(people) = v.get("people") {
        let people = people
            .as_array()
            .ok_or("field `people` is not an array of people")?;
        people
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let num = |path: &str| finite(p, path).map_err(|e| format!("people[{i}]: {e}"));
                Ok(Detection {
                    time,
                    x: num("position.x")?,
                    y: num("position.y")?,
                    person: Some(string(p, "name").map_err(|e| format!("people[{i}]: {e}"))?),
                    velocity: Some([num("velocity.x")?, num("velocity.y")?]),
                    frame_id: frame_id.clone(),
                })
            })
            .collect()
    } else {
        Err("the message has neither `poses` (PoseArray) nor `people` (People)".into())
    }
}

/// A laser scan.
pub fn scan(v: &Value<'_>, time: f64) -> Result<Scan, String> {
    let f = |path: &str| number(v, path).map(|x| x as f32);
    Ok(Scan {
        time,
        frame_id: string(v, "header.frame_id")?,
        angle_min: f("angle_min")?,
        angle_max: f("angle_max")?,
        angle_increment: f("angle_increment")?,
        time_increment: f("time_increment")?,
        scan_time: f("scan_time")?,
        range_min: f("range_min")?,
        range_max: f("range_max")?,
        ranges: floats(v, "ranges")?,
        intensities: floats(v, "intensities")?,
    })
}

/// An odometry pose.
pub fn odometry(v: &Value<'_>, time: f64) -> Result<OdometryPose, String> {
    let three = |path: &str| -> Result<[f64; 3], String> {
        Ok([
            finite(v, &format!("{path}.x"))?,
            finite(v, &format!("{path}.y"))?,
            finite(v, &format!("{path}.z"))?,
        ])
    };
    Ok(OdometryPose {
        time,
        frame_id: string(v, "header.frame_id")?,
        child_frame_id: string(v, "child_frame_id")?,
        position: three("pose.pose.position")?,
        yaw: yaw(v, "pose.pose.orientation")?,
        linear: three("twist.twist.linear")?,
        angular: three("twist.twist.angular")?,
    })
}

impl Bag {
    /// Calls `each` with the time and decoded value of every message on `topic`, after
    /// checking that the topic's type is of `kind` and that times never go backwards.
    ///
    /// # Errors
    /// See [`Bag::for_each_decoded`]; also a topic of another kind, a time going backwards,
    /// or `each`'s error (a `String`, turned into a [`BagError`] naming the message).
    pub fn for_each_record(
        &self,
        topic: &str,
        kind: RecordKind,
        time: TimeSource,
        progress: &dyn Progress,
        mut each: impl FnMut(&BagMessage, f64, &Value<'_>) -> Result<(), String>,
    ) -> Result<(), BagError> {
        let mut previous: Option<f64> = None;
        let mut checked = false;
        self.for_each_decoded(topic, progress, |m, v| -> Result<(), BagError> {
            let err = |problem: String| BagError::new(self.name(), Some(m.describe()), problem);
            if !checked {
                let name = match v {
                    Value::Struct(s) => s.def.name.clone(),
                    _ => String::new(),
                };
                if RecordKind::of(&name) != Some(kind) {
                    return Err(BagError::new(
                        self.name(),
                        Some(format!("topic {topic}")),
                        format!(
                            "its messages are {name}, not {} ({})",
                            kind.name(),
                            kind.types()
                        ),
                    ));
                }
                checked = true;
            }
            let t = message_time(m, v, time).map_err(err)?;
            if let Some(p) = previous
                && t < p
            {
                return Err(err(format!(
                    "its time {t} s is earlier than the previous message's {p} s (times must not go \
                     backwards{})",
                    if matches!(time, TimeSource::Auto | TimeSource::Header)
                        && v.get("header").is_some()
                    {
                        "; the times the recorder logged can be used instead"
                    } else {
                        ""
                    }
                )));
            }
            previous = Some(t);
            each(m, t, v).map_err(err)
        })
    }

    /// The states on `topic`.
    ///
    /// # Errors
    /// See [`Bag::for_each_record`]; a value that is not finite or outside `[0, 1]`.
    pub fn read_states(
        &self,
        topic: &str,
        time: TimeSource,
        progress: &dyn Progress,
    ) -> Result<StateSeries, BagError> {
        let mut series = StateSeries::default();
        self.for_each_record(topic, RecordKind::State, time, progress, |_, t, v| {
            series.values.push(state_value(v)?);
            series.times.push(t);
            Ok(())
        })?;
        Ok(series)
    }

    /// Calls `each` with every map on `topic` (maps can be large: they are not collected).
    ///
    /// # Errors
    /// See [`Bag::for_each_record`]; a map whose data do not match its size, or `each`'s
    /// error.
    pub fn for_each_map(
        &self,
        topic: &str,
        time: TimeSource,
        progress: &dyn Progress,
        mut each: impl FnMut(MapFrame) -> Result<(), String>,
    ) -> Result<(), BagError> {
        self.for_each_record(topic, RecordKind::Map, time, progress, |_, t, v| {
            each(map_frame(v, t)?)
        })
    }

    /// The detections on a people topic, in time order.
    ///
    /// # Errors
    /// See [`Bag::for_each_record`]; a position that is not finite.
    pub fn read_detections(
        &self,
        topic: &str,
        time: TimeSource,
        progress: &dyn Progress,
    ) -> Result<Vec<Detection>, BagError> {
        let per_message = self.collect(topic, RecordKind::People, time, progress, detections)?;
        Ok(per_message.into_iter().flatten().collect())
    }

    /// The laser scans on `topic`.
    ///
    /// # Errors
    /// See [`Bag::for_each_record`].
    pub fn read_scans(
        &self,
        topic: &str,
        time: TimeSource,
        progress: &dyn Progress,
    ) -> Result<Vec<Scan>, BagError> {
        self.collect(topic, RecordKind::Scan, time, progress, scan)
    }

    /// The odometry on `topic`.
    ///
    /// # Errors
    /// See [`Bag::for_each_record`]; a pose that is not finite.
    pub fn read_odometry(
        &self,
        topic: &str,
        time: TimeSource,
        progress: &dyn Progress,
    ) -> Result<Vec<OdometryPose>, BagError> {
        self.collect(topic, RecordKind::Odometry, time, progress, odometry)
    }

    /// `take(value, time)` of every message on `topic`.
    fn collect<T>(
        &self,
        topic: &str,
        kind: RecordKind,
        time: TimeSource,
        progress: &dyn Progress,
        take: fn(&Value<'_>, f64) -> Result<T, String>,
    ) -> Result<Vec<T>, BagError> {
        let mut out = Vec::new();
        self.for_each_record(topic, kind, time, progress, |_, t, v| {
            out.push(take(v, t)?);
            Ok(())
        })?;
        Ok(out)
    }
}

/// Scans as text, one a line: `t angle_min angle_increment range_min range_max n r_1 .. r_n`
/// (`inf` for no return), every number the shortest text that reads back to the same value.
///
/// ```
/// use chronomap_rosbag::records::{Scan, encode_scans};
///
/// let scan = Scan {
///     time: 1137834225.713386, frame_id: "laser".into(), angle_min: -1.5707964,
///     angle_max: 1.5707964, angle_increment: 1.5707964, time_increment: 0.0,
///     scan_time: 0.0, range_min: 0.0, range_max: 80.0,
///     ranges: vec![1.69, f32::INFINITY, 2.5], intensities: vec![],
/// };
/// assert_eq!(
///     encode_scans(&[scan]),
///     "# t angle_min angle_increment range_min range_max n ranges...\n\
///      1137834225.713386 -1.5707964 1.5707964 0 80 3 1.69 inf 2.5\n"
/// );
/// ```
pub fn encode_scans(scans: &[Scan]) -> String {
    use std::fmt::Write as _;
    let mut text = String::from("# t angle_min angle_increment range_min range_max n ranges...\n");
    for s in scans {
        let _ = write!(
            text,
            "{} {} {} {} {} {}",
            s.time,
            s.angle_min,
            s.angle_increment,
            s.range_min,
            s.range_max,
            s.ranges.len()
        );
        for r in &s.ranges {
            let _ = write!(text, " {r}");
        }
        text.push('\n');
    }
    text
}

/// Odometry as text, one pose a line: `t x y yaw vx vy wz` (m, rad, m/s, rad/s).
pub fn encode_poses(poses: &[OdometryPose]) -> String {
    use std::fmt::Write as _;
    let mut text = String::from("# t x y yaw vx vy wz\n");
    for p in poses {
        let _ = writeln!(
            text,
            "{} {} {} {} {} {} {}",
            p.time, p.position[0], p.position[1], p.yaw, p.linear[0], p.linear[1], p.angular[2]
        );
    }
    text
}
