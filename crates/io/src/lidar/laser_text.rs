//! 2-D laser scans, odometry and keyframe poses as text (the format of the bundled Málaga log,
//! `data/malaga_laser_2006/`).
//!
//! ```
//! use chronomap_io::laser_text::{read_odometry_from, read_scans_from};
//!
//! // t aperture right_to_left max_range sensor_x sensor_y sensor_z sensor_yaw n r_1..r_n valid_1..valid_n
//! let text = "# a scan of three beams\n\
//!             100.5 3.14159 1 80 0.78 0 0.3 0 3  1.5 81.87 2.0  1 1 0\n";
//! let scans = read_scans_from("scans.txt", text.as_bytes())?;
//! assert_eq!(scans[0].sensor.x, 0.78);
//! // Beam 1 is at or beyond the maximum range and beam 2 is flagged invalid: no returns (+inf).
//! assert_eq!(scans[0].scan.ranges, vec![1.5, f64::INFINITY, f64::INFINITY]);
//!
//! // Errors name the file, the line and the field.
//! let err = read_odometry_from("odometry.txt", "1 0 0 0\n2 0.1 nan 0\n".as_bytes()).unwrap_err();
//! assert_eq!(err.to_string(), r#"odometry.txt:2: dy: "nan" is not a finite number"#);
//! # Ok::<(), chronomap_io::laser_text::LaserTextError>(())
//! ```
//!
//! # Formats
//! Whitespace-separated numbers, one record a line; blank lines and `#` comments are skipped,
//! line numbers count every line; plain, `.xz` or `.gz` files ([`crate::open_data_file`]).
//! * **Scans** (`scans.txt`): `t_unix aperture_rad right_to_left max_range_m sensor_x sensor_y
//!   sensor_z sensor_yaw n r_1 … r_n valid_1 … valid_n`. With `right_to_left = 1` beam `k` is
//!   at bearing `−aperture/2 + k·aperture/(n−1)` (counter-clockwise, as in ROS); with `0` the
//!   beams run the other way and are reversed so that every [`Scan2d`] is counter-clockwise.
//!   A beam flagged `valid = 0`, and a range at or beyond `max_range_m` (the SICK max-range
//!   artefacts near 81.87 m), is stored as `+inf`, a no-return (REP 117).
//! * **Keyframes** (`keyframes_slam.txt`): `pose_x pose_y pose_yaw` (the robot pose in the map
//!   frame estimated by SLAM, m and rad) followed by the fields of a scan.
//! * **Odometry** (`odometry.txt`): `t_unix dx dy dyaw`, increments in the robot frame.
//!
//! The sensor pose (`sensor_x … sensor_yaw`) is the laser in the robot frame: on the Málaga
//! robot it sits 0.78 m ahead of the robot origin, so the place a scan sees is
//! `pose ⊕ sensor`, not `pose` ([`SensorPose::in_map`]).
//!
//! Every number must be finite; lengths (poses, sensor offsets, increments, the maximum range)
//! at most [`MAX_LENGTH_M`] and angles at most [`MAX_ANGLE_RAD`] in magnitude (`odometry.txt:5:
//! dx: "1e300" is beyond ±1000000 m`); `n` must be an integer from 2 to [`MAX_BEAMS`] and the line
//! must hold exactly `2n` values after it; ranges must not be negative, flags must be `0` or
//! `1`, times must not go backwards. Anything else is a [`LaserTextError`] naming file, line
//! and field (`scans.txt:17: range 12: "-1" is negative`).

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use chronomap_lidar::Scan2d;
pub use chronomap_lidar::scan::MAX_BEAMS;

/// The longest line read (16 MiB: a scan of [`MAX_BEAMS`] beams written with short numbers).
pub const MAX_LINE_BYTES: usize = 16 << 20;

/// The largest magnitude of a length in these files (m): poses, sensor offsets, odometry
/// increments and the maximum range, `|x| ≤ 10⁶` (1,000 km). Larger values are no indoor or
/// outdoor robot's, and would overflow the covariances computed from them.
pub const MAX_LENGTH_M: f64 = 1e6;

/// The largest magnitude of an angle in these files (rad): yaws and odometry rotations,
/// `|θ| ≤ 10⁴` (about 1,600 turns, room for unwrapped headings).
pub const MAX_ANGLE_RAD: f64 = 1e4;

/// A file of this module that cannot be read, or a line that breaks its format: the file, the
/// 1-based line (none for problems of the whole file), the field and what is wrong with it.
/// Displays as `file:line: field: reason`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{file}{}: {field}: {reason}", line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct LaserTextError {
    /// The file as it was named.
    pub file: String,
    /// The 1-based line, if the problem is on a line.
    pub line: Option<usize>,
    /// The field (`t_unix`, `n`, `range 12`, `valid 3`, `pose_x`, `dx`, …, or `file`).
    pub field: String,
    /// What is wrong.
    pub reason: String,
}

/// Where the laser sits on the robot (robot frame): position (m) and yaw (rad).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorPose {
    /// Forward offset (m).
    pub x: f64,
    /// Leftward offset (m).
    pub y: f64,
    /// Height (m).
    pub z: f64,
    /// Yaw of the first beam's zero bearing relative to the robot heading (rad).
    pub yaw: f64,
}

impl SensorPose {
    /// The planar pose `(x, y, yaw)` of the sensor on the robot.
    pub fn planar(&self) -> [f64; 3] {
        [self.x, self.y, self.yaw]
    }

    /// The planar pose `(x, y, yaw)` of the sensor in the map for the robot pose
    /// `(x, y, yaw)`: `robot ⊕ sensor` ([Stüde 2024] eq. (3.11), the geometry crate's
    /// `se2::compose`).
    pub fn in_map(&self, robot: [f64; 3]) -> [f64; 3] {
        chronomap_lidar::evaluation::compose(robot, self.planar())
    }
}

/// One scan line: the scan in the sensor frame and the sensor's pose on the robot.
#[derive(Clone, Debug, PartialEq)]
pub struct LaserScan {
    /// The scan (counter-clockwise, no-returns `+inf`).
    pub scan: Scan2d,
    /// The sensor on the robot.
    pub sensor: SensorPose,
}

/// One keyframe: the robot pose estimated by SLAM and the scan taken there.
#[derive(Clone, Debug, PartialEq)]
pub struct Keyframe {
    /// Robot pose `(x, y, yaw)` in the map frame (m, rad).
    pub pose: [f64; 3],
    /// The scan.
    pub scan: LaserScan,
}

impl Keyframe {
    /// The sensor's planar pose in the map frame ([`SensorPose::in_map`]).
    pub fn sensor_pose(&self) -> [f64; 3] {
        self.scan.sensor.in_map(self.pose)
    }
}

/// An odometry increment in the robot frame between two scans.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OdometryIncrement {
    /// When (unix s).
    pub time: f64,
    /// Forward motion (m).
    pub dx: f64,
    /// Leftward motion (m).
    pub dy: f64,
    /// Rotation (rad).
    pub dyaw: f64,
}

/// Reads a scan file (plain, `.xz` or `.gz`; [module docs](self)).
///
/// # Errors
/// A [`LaserTextError`] if the file cannot be read, holds no scan or a line breaks the format.
pub fn read_scans(path: impl AsRef<Path>) -> Result<Vec<LaserScan>, LaserTextError> {
    read_file(path.as_ref(), read_scans_from)
}

/// Reads scans from `reader`; `name` is the file name of the errors.
///
/// # Errors
/// As [`read_scans`].
pub fn read_scans_from(name: &str, reader: impl Read) -> Result<Vec<LaserScan>, LaserTextError> {
    let mut clock = Clock::default();
    let mut scans = Vec::new();
    for_each_line(name, reader, |line, fields| {
        let scan = parse_scan(fields, 0)?;
        clock.check(scan.scan.time, line)?;
        scans.push(scan);
        Ok(())
    })?;
    Ok(scans)
}

/// Reads a keyframe file (plain, `.xz` or `.gz`; [module docs](self)).
///
/// # Errors
/// A [`LaserTextError`] if the file cannot be read, holds no keyframe or a line breaks the
/// format.
pub fn read_keyframes(path: impl AsRef<Path>) -> Result<Vec<Keyframe>, LaserTextError> {
    read_file(path.as_ref(), read_keyframes_from)
}

/// Reads keyframes from `reader`; `name` is the file name of the errors.
///
/// # Errors
/// As [`read_keyframes`].
pub fn read_keyframes_from(name: &str, reader: impl Read) -> Result<Vec<Keyframe>, LaserTextError> {
    let mut clock = Clock::default();
    let mut keyframes = Vec::new();
    for_each_line(name, reader, |line, fields| {
        let pose = [
            length(fields, 0, "pose_x")?,
            length(fields, 1, "pose_y")?,
            angle(fields, 2, "pose_yaw")?,
        ];
        let scan = parse_scan(fields, 3)?;
        clock.check(scan.scan.time, line)?;
        keyframes.push(Keyframe { pose, scan });
        Ok(())
    })?;
    Ok(keyframes)
}

/// Reads an odometry file (plain, `.xz` or `.gz`; [module docs](self)).
///
/// # Errors
/// A [`LaserTextError`] if the file cannot be read, holds no increment or a line breaks the
/// format.
pub fn read_odometry(path: impl AsRef<Path>) -> Result<Vec<OdometryIncrement>, LaserTextError> {
    read_file(path.as_ref(), read_odometry_from)
}

/// Reads odometry increments from `reader`; `name` is the file name of the errors.
///
/// # Errors
/// As [`read_odometry`].
pub fn read_odometry_from(
    name: &str,
    reader: impl Read,
) -> Result<Vec<OdometryIncrement>, LaserTextError> {
    let mut clock = Clock::default();
    let mut rows = Vec::new();
    for_each_line(name, reader, |line, fields| {
        if fields.len() != 4 {
            return Err(field_error(
                "line",
                format!("{} fields, expected 4: t_unix dx dy dyaw", fields.len()),
            ));
        }
        let time = finite(fields, 0, "t_unix")?;
        clock.check(time, line)?;
        rows.push(OdometryIncrement {
            time,
            dx: length(fields, 1, "dx")?,
            dy: length(fields, 2, "dy")?,
            dyaw: angle(fields, 3, "dyaw")?,
        });
        Ok(())
    })?;
    Ok(rows)
}

/// A field error of a line, before the file and line are known.
struct FieldError {
    field: String,
    reason: String,
}

fn field_error(field: impl Into<String>, reason: impl Into<String>) -> FieldError {
    FieldError {
        field: field.into(),
        reason: reason.into(),
    }
}

/// Times must not go backwards.
#[derive(Default)]
struct Clock {
    last: Option<(f64, usize)>,
}

impl Clock {
    fn check(&mut self, time: f64, line: usize) -> Result<(), FieldError> {
        if let Some((previous, previous_line)) = self.last
            && time < previous
        {
            return Err(field_error(
                "t_unix",
                format!(
                    "{time} is earlier than {previous} on line {previous_line} \
                     (times must not go backwards)"
                ),
            ));
        }
        self.last = Some((time, line));
        Ok(())
    }
}

fn read_file<T>(
    path: &Path,
    read: impl FnOnce(&str, Box<dyn Read + Send>) -> Result<T, LaserTextError>,
) -> Result<T, LaserTextError> {
    let name = path.display().to_string();
    let reader = crate::text::open_data_file(path).map_err(|e| LaserTextError {
        file: name.clone(),
        line: None,
        field: "file".into(),
        reason: e.kind().to_string(),
    })?;
    read(&name, reader)
}

/// Calls `handle(line_number, fields)` for every data line; errors get the file and line.
fn for_each_line(
    name: &str,
    reader: impl Read,
    mut handle: impl FnMut(usize, &[&str]) -> Result<(), FieldError>,
) -> Result<(), LaserTextError> {
    let error = |line: Option<usize>, e: FieldError| LaserTextError {
        file: name.to_string(),
        line,
        field: e.field,
        reason: e.reason,
    };
    let mut reader = BufReader::new(reader);
    let mut buffer = Vec::new();
    let mut number = 0usize;
    let mut records = 0usize;
    loop {
        buffer.clear();
        let read = (&mut reader)
            .take(MAX_LINE_BYTES as u64 + 2)
            .read_until(b'\n', &mut buffer)
            .map_err(|e| error(Some(number + 1), field_error("file", e.to_string())))?;
        if read == 0 {
            break;
        }
        number += 1;
        if buffer.len() > MAX_LINE_BYTES + 1 {
            let reason = format!("longer than {MAX_LINE_BYTES} bytes (is this a laser log?)");
            return Err(error(Some(number), field_error("line", reason)));
        }
        let text = std::str::from_utf8(&buffer)
            .map_err(|_| error(Some(number), field_error("line", "not UTF-8 text")))?;
        let text = text.trim();
        if text.is_empty() || text.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = text.split_ascii_whitespace().collect();
        handle(number, &fields).map_err(|e| error(Some(number), e))?;
        records += 1;
    }
    if records == 0 {
        return Err(error(None, field_error("file", "no data line")));
    }
    Ok(())
}

/// The field `index` as a finite number.
fn finite(fields: &[&str], index: usize, field: &str) -> Result<f64, FieldError> {
    let text = fields
        .get(index)
        .ok_or_else(|| field_error(field, "missing"))?;
    let value: f64 = text
        .parse()
        .map_err(|_| field_error(field, format!("{} is not a number", quote(text))))?;
    if !value.is_finite() {
        return Err(field_error(
            field,
            format!("{} is not a finite number", quote(text)),
        ));
    }
    Ok(value)
}

/// The field `index` as a finite number of magnitude at most `limit` (`unit` for the message).
fn bounded(
    fields: &[&str],
    index: usize,
    field: &str,
    limit: f64,
    unit: &str,
) -> Result<f64, FieldError> {
    let value = finite(fields, index, field)?;
    if value.abs() > limit {
        return Err(field_error(
            field,
            format!("{} is beyond ±{limit} {unit}", quote(fields[index])),
        ));
    }
    Ok(value)
}

/// A length (m), at most [`MAX_LENGTH_M`] in magnitude.
fn length(fields: &[&str], index: usize, field: &str) -> Result<f64, FieldError> {
    bounded(fields, index, field, MAX_LENGTH_M, "m")
}

/// An angle (rad), at most [`MAX_ANGLE_RAD`] in magnitude.
fn angle(fields: &[&str], index: usize, field: &str) -> Result<f64, FieldError> {
    bounded(fields, index, field, MAX_ANGLE_RAD, "rad")
}

fn quote(text: &str) -> String {
    let short: String = text.chars().take(40).collect();
    format!("{short:?}")
}

/// The scan fields starting at `first` (the time); they must end the line.
fn parse_scan(fields: &[&str], first: usize) -> Result<LaserScan, FieldError> {
    let f = |offset: usize, name: &str| finite(fields, first + offset, name);
    let time = f(0, "t_unix")?;
    let aperture = f(1, "aperture_rad")?;
    if !(aperture > 0.0 && aperture <= 2.0 * std::f64::consts::PI + 1e-6) {
        return Err(field_error(
            "aperture_rad",
            format!("{aperture} is not in (0, 2π]"),
        ));
    }
    let right_to_left = f(2, "right_to_left")?;
    if right_to_left != 0.0 && right_to_left != 1.0 {
        return Err(field_error(
            "right_to_left",
            format!("{right_to_left} is not 0 or 1"),
        ));
    }
    let max_range = length(fields, first + 3, "max_range_m")?;
    if max_range <= 0.0 {
        return Err(field_error(
            "max_range_m",
            format!("{max_range} is not positive"),
        ));
    }
    let sensor = SensorPose {
        x: length(fields, first + 4, "sensor_x")?,
        y: length(fields, first + 5, "sensor_y")?,
        z: length(fields, first + 6, "sensor_z")?,
        yaw: angle(fields, first + 7, "sensor_yaw")?,
    };
    let n = f(8, "n")?;
    if n.fract() != 0.0 || n < 2.0 || n > MAX_BEAMS as f64 {
        return Err(field_error(
            "n",
            format!("{n} is not a whole number of beams from 2 to {MAX_BEAMS}"),
        ));
    }
    let n = n as usize;
    let start = first + 9;
    let found = fields.len().saturating_sub(start);
    if found != 2 * n {
        return Err(field_error(
            "n",
            format!(
                "{n} beams need {} values (n ranges, n validity flags) after it, the line has {found}",
                2 * n
            ),
        ));
    }
    let mut ranges = Vec::with_capacity(n);
    for k in 0..n {
        let name = format!("range {k}");
        let r = finite(fields, start + k, &name)?;
        if r < 0.0 {
            return Err(field_error(
                name,
                format!("{} is negative", quote(fields[start + k])),
            ));
        }
        let text = fields[start + n + k];
        let valid = match text {
            "1" => true,
            "0" => false,
            _ => {
                return Err(field_error(
                    format!("valid {k}"),
                    format!("{} is not 0 or 1", quote(text)),
                ));
            }
        };
        ranges.push(if valid && r < max_range {
            r
        } else {
            f64::INFINITY
        });
    }
    if right_to_left == 0.0 {
        ranges.reverse();
    }
    let scan = Scan2d::new(time, -aperture / 2.0, aperture / 2.0, max_range, ranges)
        .map_err(|e| field_error("scan", e.to_string()))?;
    Ok(LaserScan { scan, sensor })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan_line(n: usize) -> String {
        let ranges: Vec<String> = (0..n).map(|k| format!("{}", 1.0 + k as f64)).collect();
        let valid = vec!["1"; n];
        format!(
            "5 3.14159274 1 80 0.78 0 0.3 0 {n} {} {}",
            ranges.join(" "),
            valid.join(" ")
        )
    }

    fn scan_error(text: &str) -> String {
        read_scans_from("s.txt", text.as_bytes())
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn reads_a_scan_and_its_sensor() {
        let scans = read_scans_from("s.txt", format!("{}\n", scan_line(4)).as_bytes()).unwrap();
        let s = &scans[0];
        assert_eq!(s.scan.ranges, vec![1.0, 2.0, 3.0, 4.0]);
        assert!((s.scan.angle_min + 3.14159274 / 2.0).abs() < 1e-15);
        assert_eq!(s.sensor.z, 0.3);
        assert_eq!(s.scan.time, 5.0);
    }

    #[test]
    fn left_to_right_scans_are_reversed() {
        let text = "0 2 0 10 0 0 0 0 3 1 2 3 1 1 1";
        let scans = read_scans_from("s.txt", text.as_bytes()).unwrap();
        assert_eq!(scans[0].scan.ranges, vec![3.0, 2.0, 1.0]);
    }

    #[test]
    fn sensor_pose_composes_with_the_robot_pose() {
        let sensor = SensorPose {
            x: 0.78,
            y: 0.0,
            z: 0.3,
            yaw: 0.0,
        };
        let p = sensor.in_map([1.0, 2.0, std::f64::consts::FRAC_PI_2]);
        assert!((p[0] - 1.0).abs() < 1e-12 && (p[1] - 2.78).abs() < 1e-12);
    }

    #[test]
    fn malformed_scan_lines_name_the_field() {
        let good = scan_line(3);
        assert_eq!(
            scan_error(&good.replace(" 3 1 2 3", " 4 1 2 3")),
            "s.txt:1: n: 4 beams need 8 values (n ranges, n validity flags) after it, the line has 6"
        );
        assert_eq!(
            scan_error(&good.replace(" 3 1 2 3", " 3 1 nan 3")),
            r#"s.txt:1: range 1: "nan" is not a finite number"#
        );
        assert_eq!(
            scan_error(&good.replace(" 3 1 2 3", " 3 1 2 -3")),
            r#"s.txt:1: range 2: "-3" is negative"#
        );
        assert_eq!(
            scan_error(&format!("\n# c\n{}", good.replace("1 1 1", "1 2 1"))),
            r#"s.txt:3: valid 1: "2" is not 0 or 1"#
        );
        assert_eq!(
            scan_error(&good.replace(" 3 1 2 3", " 2.5 1 2 3")),
            "s.txt:1: n: 2.5 is not a whole number of beams from 2 to 1048576"
        );
        assert_eq!(
            scan_error(&good.replace(" 3 1 2 3", " 2000000 1 2 3")),
            "s.txt:1: n: 2000000 is not a whole number of beams from 2 to 1048576"
        );
        assert_eq!(scan_error("5 3.1 1 80 0.78"), "s.txt:1: sensor_y: missing");
        assert_eq!(
            scan_error(&good.replace(" 80 ", " -80 ")),
            "s.txt:1: max_range_m: -80 is not positive"
        );
        assert_eq!(scan_error("# nothing\n\n"), "s.txt: file: no data line");
        let two = format!("{good}\n{}", good.replacen('5', "4", 1));
        assert_eq!(
            scan_error(&two),
            "s.txt:2: t_unix: 4 is earlier than 5 on line 1 (times must not go backwards)"
        );
    }

    #[test]
    fn keyframes_and_odometry_name_their_fields() {
        let line = format!("1 2 x {}", scan_line(3));
        let e = read_keyframes_from("k.txt", line.as_bytes()).unwrap_err();
        assert_eq!(e.to_string(), r#"k.txt:1: pose_yaw: "x" is not a number"#);
        assert_eq!((e.line, e.field.as_str()), (Some(1), "pose_yaw"));
        let e = read_odometry_from("o.txt", "1 2 3\n".as_bytes()).unwrap_err();
        assert_eq!(
            e.to_string(),
            "o.txt:1: line: 3 fields, expected 4: t_unix dx dy dyaw"
        );
    }

    /// The bundled Málaga log: 225 scans of 361 beams, 99 keyframes, 224 increments.
    #[test]
    fn reads_the_bundled_malaga_log() {
        let dir = chronomap_testutil::data_path("malaga_laser_2006");
        let scans = read_scans(dir.join("scans.txt.xz")).unwrap();
        let keyframes = read_keyframes(dir.join("keyframes_slam.txt.xz")).unwrap();
        let odometry = read_odometry(dir.join("odometry.txt.xz")).unwrap();
        assert_eq!(
            (scans.len(), keyframes.len(), odometry.len()),
            (225, 99, 224)
        );
        assert!(scans.iter().all(|s| s.scan.ranges.len() == 361));
        let first = &scans[0];
        assert_eq!(first.scan.ranges[0], 1.69);
        // 81.87 m readings are max-range artefacts: no returns.
        assert_eq!(first.scan.ranges[21], f64::INFINITY);
        assert_eq!(first.sensor.x, 0.78);
        assert_eq!(keyframes[0].pose, [0.0, 0.0, 0.0]);
        assert!((keyframes[0].sensor_pose()[0] - 0.78).abs() < 1e-12);
        // Every stored range is a return below 80 m or a no-return.
        for k in &keyframes {
            assert!(
                k.scan
                    .scan
                    .ranges
                    .iter()
                    .all(|&r| r < 80.0 || r == f64::INFINITY)
            );
        }
        // Odometry composes to a loop of about 77 m (README).
        let length: f64 = odometry.iter().map(|o| o.dx.hypot(o.dy)).sum();
        assert!((70.0..85.0).contains(&length), "{length}");
    }

    /// Damaged copies of the bundled files are refused at the damaged line.
    #[test]
    fn damaged_copies_of_the_malaga_log_are_refused() {
        let dir = chronomap_testutil::data_path("malaga_laser_2006");
        let mut text = String::new();
        crate::open_data_file(dir.join("keyframes_slam.txt.xz"))
            .unwrap()
            .read_to_string(&mut text)
            .unwrap();
        let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
        // Line 6 (a comment is line 1): drop the last validity flag.
        let cut = lines[5].rfind(' ').unwrap();
        lines[5].truncate(cut);
        let e = read_keyframes_from("k.txt", lines.join("\n").as_bytes()).unwrap_err();
        assert_eq!((e.line, e.field.as_str()), (Some(6), "n"));
        // A truncated .xz file is an error naming the file.
        let bytes = std::fs::read(dir.join("odometry.txt.xz")).unwrap();
        let tmp = std::env::temp_dir().join(format!("laser_text_{}.txt.xz", std::process::id()));
        std::fs::write(&tmp, &bytes[..bytes.len() / 2]).unwrap();
        let e = read_odometry(&tmp).unwrap_err();
        std::fs::remove_file(&tmp).ok();
        assert!(e.file.ends_with(".txt.xz"), "{e}");
        assert_eq!(e.field, "file");
    }

    #[test]
    fn absurd_lengths_and_angles_are_refused_at_their_field() {
        // 1e300 m increments made the covariance of the pose infinite, then NaN, which the map
        // manager printed as σ = 0.00 m.
        let e = read_odometry_from("o.txt", "1 0 0 0\n2 1e300 0 0\n".as_bytes()).unwrap_err();
        assert_eq!(
            e.to_string(),
            r#"o.txt:2: dx: "1e300" is beyond ±1000000 m"#
        );
        let e = read_odometry_from("o.txt", "1 0 -1000000.5 0\n".as_bytes()).unwrap_err();
        assert_eq!((e.line, e.field.as_str()), (Some(1), "dy"));
        let e = read_odometry_from("o.txt", "1 0 0 2e4\n".as_bytes()).unwrap_err();
        assert_eq!(
            e.to_string(),
            r#"o.txt:1: dyaw: "2e4" is beyond ±10000 rad"#
        );
        // The bounds themselves are accepted.
        let ok = read_odometry_from("o.txt", "1 1e6 -1e6 -1e4\n".as_bytes()).unwrap();
        assert_eq!((ok[0].dx, ok[0].dy, ok[0].dyaw), (1e6, -1e6, -1e4));
        let good = scan_line(3);
        assert_eq!(
            scan_error(&good.replacen(" 0.78 ", " 1e300 ", 1)),
            r#"s.txt:1: sensor_x: "1e300" is beyond ±1000000 m"#
        );
        assert_eq!(
            scan_error(&good.replacen(" 80 ", " 1e7 ", 1))
                .split(':')
                .nth(2),
            Some(" max_range_m")
        );
        let e = read_keyframes_from("k.txt", format!("1e200 0 0 {good}").as_bytes()).unwrap_err();
        assert_eq!((e.line, e.field.as_str()), (Some(1), "pose_x"));
        let e = read_keyframes_from("k.txt", format!("0 0 -1e5 {good}").as_bytes()).unwrap_err();
        assert_eq!((e.line, e.field.as_str()), (Some(1), "pose_yaw"));
    }

    #[test]
    fn too_long_lines_are_refused() {
        let mut text = "1 ".repeat(MAX_LINE_BYTES / 2 + 10);
        text.push('\n');
        let e = read_odometry_from("o.txt", text.as_bytes()).unwrap_err();
        assert_eq!(e.field, "line");
        assert!(e.reason.starts_with("longer than"), "{e}");
    }
}
