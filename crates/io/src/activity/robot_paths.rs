//! Readers of robot path files: the patrol loops of simulated robots that collect CoPA-Map's
//! training data ([Stüde 2024] §4.2.2, §4.3.1), such as `data/atc_20121024_1hz/robot_paths.csv`
//! (see `data/README.md`).
//!
//! ```
//! use chronomap_io::robot_paths::read_robot_paths_from;
//! use chronomap_io::Field;
//!
//! let text = "path,x,y,stop_s\n\
//!             hall,0,0,30\n\
//!             hall,10,0,0\n\
//!             door,5,5,60\n";
//! let paths = read_robot_paths_from("paths.csv", text.as_bytes(), 0.5)?;
//! assert_eq!(paths.len(), 2);
//! assert_eq!((paths[0].name.as_str(), paths[0].line), ("hall", 2));
//! // 30 s stop, 10 m there and 10 m back at 0.5 m/s.
//! assert_eq!(paths[0].path.period(), 70.0);
//!
//! // Errors name the file, line and field.
//! let err = read_robot_paths_from("paths.csv", "path,x,y,stop_s\nhall,0,0,-5\n".as_bytes(), 0.5)
//!     .unwrap_err();
//! assert_eq!(err.to_string(), r#"paths.csv:2: stop_s: "-5" is negative (must be >= 0)"#);
//! assert_eq!(err.field(), Some(Field::Stop));
//! # Ok::<(), chronomap_io::DataError>(())
//! ```
//!
//! # Format
//! CSV; the first data line is the header `path,x,y,stop_s`. Every further data line is a
//! waypoint: the name of its path (letters, digits, `_`, `-`), its position `x`, `y` (metres,
//! map frame) and how long the robot stops there, `stop_s` (seconds, `>= 0`). A path's
//! waypoints are consecutive lines in driving order; the robot drives the closed loop
//! (from the last waypoint back to the first) again and again at a constant speed given to the
//! reader (see [`RobotPath`]). To patrol back and forth, list the way back.
//!
//! As in [`crate::text`], blank lines and `#` comments are skipped, line numbers count every
//! line, and plain, `.xz` and `.gz` files are read. Every problem is a [`DataError`]:
//!
//! ```text
//! robot_paths.csv:1: expected the header `path,x,y,stop_s`, found "name,x,y"
//! robot_paths.csv:7: x: "abc" is not a number
//! robot_paths.csv:9: path "a" continues after other paths (it began on line 2; ...)
//! robot_paths.csv:4: path "b": invalid robot path: a loop takes 0 s (...)
//! ```

use std::io::Read;
use std::path::Path;

use chronomap_activity::extract::{RobotPath, Waypoint};

use crate::text::{
    DataError, DataErrorKind, Field, Fields, for_each_csv_row, is_name, parse_finite,
    parse_non_negative, quote, read_data_file, required,
};

/// What a waypoint line must look like.
const EXPECTED: &str = "expected four fields: path,x,y,stop_s";

/// The header.
const HEADER: [&str; 4] = ["path", "x", "y", "stop_s"];

/// A robot path read from a file.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedRobotPath {
    /// The name in the file.
    pub name: String,
    /// The line of its first waypoint.
    pub line: usize,
    /// The loop.
    pub path: RobotPath,
}

/// Reads a robot path file (plain, `.xz` or `.gz`; see the [module docs](self)); the robots
/// drive at `speed` m/s (0.5 in §4.3.1, [`RobotPath::DEFAULT_SPEED`]).
///
/// ```no_run
/// let paths = chronomap_io::read_robot_paths("data/atc_20121024_1hz/robot_paths.csv", 0.5)?;
/// assert_eq!(paths.len(), 3);
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
///
/// # Errors
/// A [`DataError`] naming `path` if the file cannot be read, lacks the header, has no
/// waypoint, or a line breaks the rules of the [module docs](self); a path that is not a
/// valid [`RobotPath`] (e.g. a single waypoint without a stop, or a bad `speed`) is reported
/// at its first line.
pub fn read_robot_paths(
    path: impl AsRef<Path>,
    speed: f64,
) -> Result<Vec<NamedRobotPath>, DataError> {
    read_data_file(path.as_ref(), |name, reader| {
        read_robot_paths_from(name, reader, speed)
    })
}

/// Reads robot paths (uncompressed text) from `reader`; `name` is used in errors.
///
/// # Errors
/// As [`read_robot_paths`].
pub fn read_robot_paths_from(
    name: &str,
    reader: impl Read,
    speed: f64,
) -> Result<Vec<NamedRobotPath>, DataError> {
    // (name, first line, waypoints) of every path in file order.
    let mut groups: Vec<(String, usize, Vec<Waypoint>)> = Vec::new();
    for_each_csv_row(name, reader, &HEADER, "waypoint", |line_number, line| {
        let mut fields = Fields::new(line);
        let path_text = required(fields.next(), Field::PathName, EXPECTED)?;
        if !is_name(path_text) {
            return Err(DataErrorKind::BadName {
                field: Field::PathName,
                text: quote(path_text),
            });
        }
        let path_name = String::from_utf8_lossy(path_text).into_owned();
        let x = parse_finite(required(fields.next(), Field::X, EXPECTED)?, Field::X)?;
        let y = parse_finite(required(fields.next(), Field::Y, EXPECTED)?, Field::Y)?;
        let stop =
            parse_non_negative(required(fields.next(), Field::Stop, EXPECTED)?, Field::Stop)?;
        fields.finish(EXPECTED)?;
        let waypoint = Waypoint::new([x, y], stop + 0.0);
        match groups.last_mut() {
            Some((last, _, waypoints)) if *last == path_name => waypoints.push(waypoint),
            _ => {
                if let Some((_, first_line, _)) = groups.iter().find(|(n, _, _)| *n == path_name) {
                    return Err(DataErrorKind::PathInterrupted {
                        name: path_name,
                        first_line: *first_line,
                    });
                }
                groups.push((path_name, line_number, vec![waypoint]));
            }
        }
        Ok(())
    })?;
    groups
        .into_iter()
        .map(|(path_name, line, waypoints)| {
            let path = RobotPath::new(waypoints, speed).map_err(|error| {
                DataError::new(
                    name,
                    Some(line),
                    DataErrorKind::RobotPath {
                        name: path_name.clone(),
                        error,
                    },
                )
            })?;
            Ok(NamedRobotPath {
                name: path_name,
                line,
                path,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::text::test_support::assert_errors;

    fn read(text: &str) -> Result<Vec<NamedRobotPath>, DataError> {
        read_robot_paths_from("paths.csv", text.as_bytes(), 0.5)
    }

    #[test]
    fn reads_paths_in_file_order_with_comments_and_crlf() {
        let text =
            "# loops\r\npath, x, y, stop_s\r\n\r\na,1,2,0\r\na,1,4,10\r\n# b\r\nb-2,5,5,3\r\n";
        let paths = read(text).unwrap();
        let got: Vec<(&str, usize, usize, f64)> = paths
            .iter()
            .map(|p| {
                (
                    p.name.as_str(),
                    p.line,
                    p.path.waypoints().len(),
                    p.path.period(),
                )
            })
            .collect();
        // a: 2 m there and back at 0.5 m/s, one stop of 10 s; b-2: stands for 3 s.
        assert_eq!(got, [("a", 4, 2, 18.0), ("b-2", 7, 1, 3.0)]);
        assert_eq!(
            paths[0].path.waypoints()[1],
            Waypoint::new([1.0, 4.0], 10.0)
        );
    }

    #[test]
    fn errors_name_file_line_and_field() {
        let cases = [
            (
                "name,x,y\na,0,0,0\n",
                1,
                None,
                "expected the header `path,x,y,stop_s`, found \"name,x,y\"",
            ),
            (
                "path,x,y,stop_s\na,0,0,0\na,abc,0,0\n",
                3,
                Some(Field::X),
                "x: \"abc\" is not a number",
            ),
            (
                "path,x,y,stop_s\na,0,inf,0\n",
                2,
                Some(Field::Y),
                "y: \"inf\" is not a finite number",
            ),
            (
                "path,x,y,stop_s\na,0,0\n",
                2,
                Some(Field::Stop),
                "stop_s: missing (expected four fields: path,x,y,stop_s)",
            ),
            (
                "path,x,y,stop_s\na,0,0,1,2\n",
                2,
                None,
                "unexpected extra field \"2\"",
            ),
            (
                "path,x,y,stop_s\n,0,0,1\n",
                2,
                Some(Field::PathName),
                "path: missing",
            ),
            (
                "path,x,y,stop_s\na b,0,0,1\n",
                2,
                Some(Field::X),
                "x: \"b\" is not a number",
            ),
            (
                "path,x,y,stop_s\nhall/1,0,0,1\n",
                2,
                Some(Field::PathName),
                "path: \"hall/1\" is not a name",
            ),
            (
                "path,x,y,stop_s\na,0,0,1\nb,1,1,1\na,2,2,1\n",
                4,
                Some(Field::PathName),
                "path \"a\" continues after other paths (it began on line 2;",
            ),
            (
                "path,x,y,stop_s\na,0,0,1\n# b stands\nb,1,1,0\n",
                4,
                None,
                "path \"b\": invalid robot path: a loop takes 0 s",
            ),
        ];
        assert_errors(
            "paths.csv",
            |name, text| read_robot_paths_from(name, text, 0.5),
            &cases,
        );
        assert!(matches!(read("").unwrap_err().kind(), DataErrorKind::Empty));
        assert_eq!(
            read("path,x,y,stop_s\n").unwrap_err().to_string(),
            "paths.csv: a header `path,x,y,stop_s` without any waypoint after it"
        );
        let slow = read_robot_paths_from("paths.csv", "path,x,y,stop_s\na,0,0,1\n".as_bytes(), 0.0);
        assert!(slow.unwrap_err().to_string().contains("speed 0 m/s"));
    }
}
