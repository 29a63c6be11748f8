//! Readers of navigation-scenario files: named patrols through waypoints for the
//! service-disturbance benchmark of CoPA-Map ([Stüde 2024] §4.3.5, see
//! [`chronomap_activity::disturbance`]), such as the *hallway* and *shops* scenarios in
//! `data/atc_20121024_1hz/disturbance_scenarios.csv` (see `data/README.md`).
//!
//! ```
//! use chronomap_io::scenarios::read_scenarios_from;
//!
//! let text = "scenario,waypoint,x,y\n\
//!             hall,A,4.75,1.25\nhall,B,12.25,-6.25\n\
//!             shops,A,15.25,-10.75\nshops,B,21.25,-11.25\n";
//! let scenarios = read_scenarios_from("scenarios.csv", text.as_bytes())?;
//! assert_eq!(scenarios.len(), 2);
//! assert_eq!(scenarios[0].name, "hall");
//! assert_eq!(scenarios[0].waypoints[1].label, "B");
//! assert_eq!(scenarios[0].waypoints[1].at, [12.25, -6.25]);
//!
//! // Errors name the file, line and column.
//! let err = read_scenarios_from("s.csv", "scenario,waypoint,x,y\nhall,A,1,nan\n".as_bytes())
//!     .unwrap_err();
//! assert_eq!(err.to_string(), r#"s.csv:2: y: "nan" is not a finite number"#);
//! # Ok::<(), chronomap_io::DataError>(())
//! ```
//!
//! # Format
//! CSV with the header `scenario,waypoint,x,y`, then one waypoint per line: the scenario's
//! name, the waypoint's label (both made of ASCII letters, digits, `_` and `-`) and its
//! position `x`, `y` in metres (map frame). A scenario's waypoints are consecutive lines, in
//! the order the patrol visits them; a scenario has two or more waypoints with distinct labels.
//! As in [`crate::text`], blank lines and `#` comments are skipped, line numbers count every
//! line, and plain, `.xz` and `.gz` files are read. Problems are [`DataError`]s:
//!
//! ```text
//! scenarios.csv:1: expected the header `scenario,waypoint,x,y`, found "name,x,y"
//! scenarios.csv:5: waypoint: "A" appears twice in scenario "hallway"
//! scenarios.csv:9: scenario: "hallway" continues after the lines of scenario "shops" (a scenario's waypoints are consecutive lines)
//! scenarios.csv:7: scenario: "shops" has one waypoint (a patrol needs two or more)
//! ```

use std::io::Read;
use std::path::Path;

use chronomap_activity::disturbance::{Scenario, Waypoint};

use crate::text::{
    DataError, DataErrorKind, Field, Fields, for_each_csv_row, is_name, parse_finite, quote,
    read_data_file, required,
};

/// What a data line must look like.
const EXPECTED: &str = "expected four fields: scenario,waypoint,x,y";

/// The header.
const HEADER: [&str; 4] = ["scenario", "waypoint", "x", "y"];

/// Reads a scenario file (plain, `.xz` or `.gz`; see the [module docs](self)); scenarios come
/// in file order.
///
/// # Errors
/// A [`DataError`] naming `path` if the file cannot be read, lacks the header, has no
/// waypoint, or breaks the rules of the [module docs](self).
pub fn read_scenarios(path: impl AsRef<Path>) -> Result<Vec<Scenario>, DataError> {
    read_data_file(path.as_ref(), read_scenarios_from)
}

/// Reads scenarios (uncompressed text) from `reader`; `name` is used in errors.
///
/// # Errors
/// As [`read_scenarios`].
pub fn read_scenarios_from(name: &str, reader: impl Read) -> Result<Vec<Scenario>, DataError> {
    let mut scenarios: Vec<Scenario> = Vec::new();
    // The first line of the scenario being read, to name it if it ends with one waypoint.
    let mut first_line = 0usize;
    let too_short = |scenario: &Scenario, line: usize| {
        DataError::new(
            name,
            Some(line),
            DataErrorKind::Scenario {
                reason: format!(
                    "scenario: {:?} has one waypoint (a patrol needs two or more)",
                    scenario.name
                ),
            },
        )
    };
    let mut short: Option<DataError> = None;
    for_each_csv_row(name, reader, &HEADER, "waypoint", |line_number, line| {
        let mut fields = Fields::new(line);
        let scenario = parse_name(fields.next(), "scenario")?;
        let label = parse_name(fields.next(), "waypoint")?;
        let x = parse_finite(required(fields.next(), Field::X, EXPECTED)?, Field::X)?;
        let y = parse_finite(required(fields.next(), Field::Y, EXPECTED)?, Field::Y)?;
        fields.finish(EXPECTED)?;
        let waypoint = Waypoint { label, at: [x, y] };
        match scenarios.last_mut() {
            Some(current) if current.name == scenario => {
                if current.waypoints.iter().any(|w| w.label == waypoint.label) {
                    return Err(DataErrorKind::Scenario {
                        reason: format!(
                            "waypoint: {:?} appears twice in scenario {:?}",
                            waypoint.label, scenario
                        ),
                    });
                }
                current.waypoints.push(waypoint);
            }
            last => {
                if let Some(previous) = last {
                    if previous.waypoints.len() < 2 && short.is_none() {
                        short = Some(too_short(previous, first_line));
                    }
                    if scenarios.iter().any(|s| s.name == scenario) {
                        return Err(DataErrorKind::Scenario {
                            reason: format!(
                                "scenario: {scenario:?} continues after the lines of scenario \
                                 {:?} (a scenario's waypoints are consecutive lines)",
                                scenarios[scenarios.len() - 1].name
                            ),
                        });
                    }
                }
                first_line = line_number;
                scenarios.push(Scenario {
                    name: scenario,
                    waypoints: vec![waypoint],
                });
            }
        }
        Ok(())
    })?;
    if let Some(error) = short {
        return Err(error);
    }
    match scenarios.last() {
        Some(last) if last.waypoints.len() < 2 => Err(too_short(last, first_line)),
        _ => Ok(scenarios),
    }
}

/// A scenario name or waypoint label: ASCII letters, digits, `_` and `-`.
fn parse_name(text: Option<&[u8]>, column: &str) -> Result<String, DataErrorKind> {
    let text = text.unwrap_or_default();
    if text.is_empty() {
        return Err(DataErrorKind::Scenario {
            reason: format!("{column}: missing ({EXPECTED})"),
        });
    }
    if !is_name(text) {
        return Err(DataErrorKind::Scenario {
            reason: format!(
                "{column}: {:?} is not a name (ASCII letters, digits, _ and - only)",
                quote(text)
            ),
        });
    }
    Ok(String::from_utf8_lossy(text).into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_scenarios_in_file_order_with_comments() {
        let text = "# two patrols\nscenario, waypoint, x, y\n\nb,A,1,2\nb,B,3,4\r\na,P-1,0,0\na,P_2,-1.5,2e1\n";
        let s = read_scenarios_from("s.csv", text.as_bytes()).unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].name, "b");
        assert_eq!(s[1].name, "a");
        assert_eq!(
            s[1].waypoints,
            [
                Waypoint {
                    label: "P-1".into(),
                    at: [0.0, 0.0]
                },
                Waypoint {
                    label: "P_2".into(),
                    at: [-1.5, 20.0]
                }
            ]
        );
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let header = "scenario,waypoint,x,y\n";
        let cases = [
            (
                "name,x,y\n".to_string(),
                Some(1),
                "expected the header `scenario,waypoint,x,y`, found \"name,x,y\"",
            ),
            (
                format!("{header}h,A,0,0\nh,A,1,1\n"),
                Some(3),
                "waypoint: \"A\" appears twice in scenario \"h\"",
            ),
            (
                format!("{header}h,A,0,0\nh,B,1,1\ns,A,0,0\ns,B,0,0\nh,C,2,2\n"),
                Some(6),
                "scenario: \"h\" continues after the lines of scenario \"s\"",
            ),
            (
                format!("{header}h,A,0,0\ns,A,0,0\ns,B,0,0\n"),
                Some(2),
                "scenario: \"h\" has one waypoint",
            ),
            (
                format!("{header}h,A,0,0\nh,B,0,0\ns,A,0,0\n"),
                Some(4),
                "scenario: \"s\" has one waypoint",
            ),
            (
                format!("{header}h!,A,0,0\n"),
                Some(2),
                "scenario: \"h!\" is not a name",
            ),
            (
                format!("{header}h,A,x,0\n"),
                Some(2),
                "x: \"x\" is not a number",
            ),
            (
                format!("{header}h,A,0\n"),
                Some(2),
                "y: missing (expected four fields: scenario,waypoint,x,y)",
            ),
            (
                format!("{header}h,A,0,0,9\n"),
                Some(2),
                "unexpected extra field \"9\"",
            ),
            (
                header.to_string(),
                None,
                "a header `scenario,waypoint,x,y` without any waypoint",
            ),
        ];
        for (text, line, message) in cases {
            let err = read_scenarios_from("s.csv", text.as_bytes()).unwrap_err();
            assert_eq!(err.name(), "s.csv");
            assert_eq!(err.line(), line, "{err}");
            assert!(err.to_string().contains(message), "{err}");
        }
    }
}
