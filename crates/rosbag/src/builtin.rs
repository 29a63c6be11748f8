//! Definitions of the message types chronomap reads, for bags and byte streams that carry none
//! (a bag whose schema is empty or in an encoding other than `ros2msg`, or bytes from a live
//! topic). Field for field the ROS 2 Kilted definitions (comments and constants left out);
//! a bag's own definition always wins over these.
//!
//! ```
//! use chronomap_rosbag::builtin;
//!
//! let schema = builtin::schema("nav_msgs/msg/OccupancyGrid").unwrap();
//! assert_eq!(schema.root().fields.len(), 3);
//! assert!(builtin::schema("nav_msgs/OccupancyGrid").is_some()); // either spelling
//! assert!(builtin::schema("tf2_msgs/msg/TFMessage").is_none());
//! ```

use crate::msgdef::{Schema, canonical_type_name};

/// `(pkg/msg/Type, definition)` of every type known here.
const DEFINITIONS: &[(&str, &str)] = &[
    ("std_msgs/msg/Bool", "bool data\n"),
    ("std_msgs/msg/Float32", "float32 data\n"),
    ("std_msgs/msg/Float64", "float64 data\n"),
    (
        "std_msgs/msg/Header",
        "builtin_interfaces/Time stamp\nstring frame_id\n",
    ),
    ("builtin_interfaces/msg/Time", "int32 sec\nuint32 nanosec\n"),
    (
        "nav_msgs/msg/OccupancyGrid",
        "std_msgs/Header header\nnav_msgs/MapMetaData info\nint8[] data\n",
    ),
    (
        "nav_msgs/msg/MapMetaData",
        "builtin_interfaces/Time map_load_time\nfloat32 resolution\nuint32 width\nuint32 height\n\
         geometry_msgs/Pose origin\n",
    ),
    (
        "geometry_msgs/msg/Pose",
        "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n",
    ),
    (
        "geometry_msgs/msg/Point",
        "float64 x\nfloat64 y\nfloat64 z\n",
    ),
    (
        "geometry_msgs/msg/Quaternion",
        "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    ),
    (
        "geometry_msgs/msg/Vector3",
        "float64 x\nfloat64 y\nfloat64 z\n",
    ),
    (
        "geometry_msgs/msg/PoseArray",
        "std_msgs/Header header\ngeometry_msgs/Pose[] poses\n",
    ),
    (
        "geometry_msgs/msg/PoseWithCovariance",
        "geometry_msgs/Pose pose\nfloat64[36] covariance\n",
    ),
    (
        "geometry_msgs/msg/Twist",
        "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n",
    ),
    (
        "geometry_msgs/msg/TwistWithCovariance",
        "geometry_msgs/Twist twist\nfloat64[36] covariance\n",
    ),
    (
        "sensor_msgs/msg/LaserScan",
        "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\n\
         float32 time_increment\nfloat32 scan_time\nfloat32 range_min\nfloat32 range_max\n\
         float32[] ranges\nfloat32[] intensities\n",
    ),
    (
        "nav_msgs/msg/Odometry",
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n\
         geometry_msgs/TwistWithCovariance twist\n",
    ),
    (
        "people_msgs/msg/People",
        "std_msgs/Header header\npeople_msgs/Person[] people\n",
    ),
    (
        "people_msgs/msg/Person",
        "string name\ngeometry_msgs/Point position\ngeometry_msgs/Point velocity\n\
         float64 reliability\nstring[] tagnames\nstring[] tags\n",
    ),
];

/// Line that separates the definitions of a rosbag2 schema.
const SEPARATOR: &str =
    "================================================================================";

/// The definition of one type known here.
fn definition(name: &str) -> Option<&'static str> {
    DEFINITIONS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, text)| *text)
}

/// The types one known type refers to, in the order of first use.
fn dependencies(name: &str, out: &mut Vec<String>) {
    let Some(text) = definition(name) else { return };
    for line in text.lines() {
        let ty = line.split_whitespace().next().unwrap_or_default();
        let base = ty.split('[').next().unwrap_or_default();
        if let Some(dep) = canonical_type_name(base)
            && definition(&dep).is_some()
            && !out.contains(&dep)
        {
            out.push(dep.clone());
            dependencies(&dep, out);
        }
    }
}

/// The rosbag2 schema text (`ros2msg`) of a known type, with every type it uses.
pub fn schema_text(type_name: &str) -> Option<String> {
    let name = canonical_type_name(type_name)?;
    let mut text = definition(&name)?.to_string();
    let mut deps = Vec::new();
    dependencies(&name, &mut deps);
    for dep in deps {
        let short = dep.replacen("/msg/", "/", 1);
        text.push_str(&format!("{SEPARATOR}\nMSG: {short}\n{}", definition(&dep)?));
    }
    Some(text)
}

/// The parsed schema of a known type (`pkg/msg/Type` or `pkg/Type`).
pub fn schema(type_name: &str) -> Option<Schema> {
    let text = schema_text(type_name)?;
    Schema::parse(type_name, &text).ok()
}

/// The names (`pkg/msg/Type`) of the top-level types known here.
pub fn known_types() -> impl Iterator<Item = &'static str> {
    DEFINITIONS.iter().map(|(n, _)| *n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_known_type_parses_with_its_dependencies() {
        for name in known_types() {
            let schema = schema(name).unwrap_or_else(|| panic!("{name}"));
            assert_eq!(schema.root().name, name);
        }
        let odom = schema("nav_msgs/msg/Odometry").unwrap();
        assert_eq!(odom.types().len(), 10); // with Header, Time, Pose, Point, Quaternion, ...
    }

    #[test]
    fn the_laser_scan_text_is_what_rosbags_writes() {
        // The schema of /scan in data/malaga_laser_2006's bag (rosbags 0.11.9).
        let bag = "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\n\
                   float32 time_increment\nfloat32 scan_time\nfloat32 range_min\nfloat32 range_max\n\
                   float32[] ranges\nfloat32[] intensities\n";
        let ours = schema_text("sensor_msgs/msg/LaserScan").unwrap();
        assert!(ours.starts_with(&bag.replace("                   ", "")));
        assert_eq!(
            Schema::parse("sensor_msgs/msg/LaserScan", &ours).unwrap(),
            schema("sensor_msgs/LaserScan").unwrap()
        );
    }
}
