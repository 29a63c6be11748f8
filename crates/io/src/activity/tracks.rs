//! Readers of pedestrian track files: the ATC shopping-centre tracks bundled in
//! `data/atc_20121024_1hz/` (see `data/README.md`), one detection of a tracked person per line.
//!
//! ```
//! use chronomap_io::tracks::read_tracks_from;
//! use chronomap_io::Field;
//!
//! // t, person, x, y, speed, heading — sorted by person in the file, by time when read.
//! let text = "1351040401.9,9551000,-22.19,2.28,0.66,-2.09\n\
//!             1351040400.9,9551000,-22.17,2.54,0.78,1.97\n";
//! let tracks = read_tracks_from("atc.csv", text.as_bytes())?;
//! assert_eq!(tracks.len(), 2);
//! assert_eq!((tracks[0].t, tracks[0].x, tracks[0].y), (1351040400.9, -22.17, 2.54));
//!
//! // Errors name the file, line and field.
//! let err = read_tracks_from("atc.csv", "1,-5,0,0,0,0\n".as_bytes()).unwrap_err();
//! assert_eq!(err.to_string(), r#"atc.csv:1: person: "-5" is not a number"#);
//! assert_eq!(err.field(), Some(Field::Person));
//! # Ok::<(), chronomap_io::DataError>(())
//! ```
//!
//! # Format
//! CSV without a header, six fields per line: `t` (unix seconds), `person` (an id, an integer
//! `0 ..= 2⁶⁴−1`), `x`, `y` (metres, map frame), `speed` (m/s, `>= 0`) and `heading`
//! (radians). Lines may come in any order (the ATC files are sorted by person); the reader
//! returns the detections sorted by time (a stable sort: equal times keep the file order).
//! Speed and heading are checked but not returned: the activity models use where and when
//! people were, not how they moved.
//!
//! As in [`crate::text`], blank lines and `#` comments are skipped, line numbers count every
//! line, and plain, `.xz` and `.gz` files are read. Every problem is a [`DataError`]:
//!
//! ```text
//! atc-1024-10_train.csv.xz:17: x: "nan" is not a finite number
//! atc-1024-10_train.csv.xz:18: time: "-3" is negative (times are seconds >= 0)
//! atc-1024-10_train.csv.xz:19: heading: missing (expected six fields: t,person,x,y,speed,heading)
//! ```

use std::io::Read;
use std::path::Path;

use chronomap_activity::truth::TrackPoint;
use chronomap_hypertime::events::Event;

use crate::text::{
    DataError, DataErrorKind, Field, Fields, for_each_data_line, parse_finite, parse_non_negative,
    parse_person, quote, read_data_file, read_merged, required,
};

/// What a track line must look like.
const EXPECTED: &str = "expected six fields: t,person,x,y,speed,heading";

/// Reads a pedestrian track file (plain, `.xz` or `.gz`; see the [module docs](self)) and
/// returns its detections sorted by time.
///
/// ```no_run
/// let ten = chronomap_io::read_tracks("data/atc_20121024_1hz/atc-1024-10_train.csv.xz")?;
/// assert_eq!(ten.len(), 38_633);
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
///
/// # Errors
/// A [`DataError`] naming `path` if the file cannot be read, has no detection, or a line
/// breaks the rules of the [module docs](self).
pub fn read_tracks(path: impl AsRef<Path>) -> Result<Vec<Event>, DataError> {
    read_data_file(path.as_ref(), read_tracks_from)
}

/// Reads several track files and merges their detections in time order (stable: equal times
/// keep the order of the files).
///
/// # Errors
/// The first error of [`read_tracks`].
pub fn read_track_files(paths: &[impl AsRef<Path>]) -> Result<Vec<Event>, DataError> {
    read_merged(paths, |path| read_tracks(path), |e| e.t)
}

/// Reads pedestrian tracks (uncompressed text) from `reader`; `name` is used in errors.
///
/// # Errors
/// As [`read_tracks`].
pub fn read_tracks_from(name: &str, reader: impl Read) -> Result<Vec<Event>, DataError> {
    Ok(read_track_points_from(name, reader)?
        .into_iter()
        .map(|p| Event {
            t: p.t,
            x: p.x,
            y: p.y,
        })
        .collect())
}

/// As [`read_tracks`], keeping the person ids: what counting distinct people needs
/// ([`chronomap_activity::truth::person_counts`]).
///
/// # Errors
/// As [`read_tracks`].
pub fn read_track_points(path: impl AsRef<Path>) -> Result<Vec<TrackPoint>, DataError> {
    read_data_file(path.as_ref(), read_track_points_from)
}

/// As [`read_track_files`], keeping the person ids.
///
/// # Errors
/// The first error of [`read_track_points`].
pub fn read_track_point_files(paths: &[impl AsRef<Path>]) -> Result<Vec<TrackPoint>, DataError> {
    read_merged(paths, |path| read_track_points(path), |p| p.t)
}

/// One line of a track file: a detection of a person, with its speed and heading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackRow {
    /// When and where, and who.
    pub point: TrackPoint,
    /// Speed (m/s, `>= 0`).
    pub speed: f64,
    /// Heading (rad).
    pub heading: f64,
}

/// Rows as a track file (the [format](self#format) the readers take), every number written as
/// the shortest text that reads back to the same `f64`.
///
/// ```
/// use chronomap_activity::truth::TrackPoint;
/// use chronomap_io::tracks::{TrackRow, encode_tracks, read_track_points_from};
///
/// let point = TrackPoint { t: 1351040400.9, person: 9551000, x: -22.17, y: 2.54 };
/// let text = encode_tracks(&[TrackRow { point, speed: 0.78, heading: 1.97 }]);
/// assert_eq!(text, "1351040400.9,9551000,-22.17,2.54,0.78,1.97\n");
/// assert_eq!(read_track_points_from("t.csv", text.as_bytes())?, [point]);
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
pub fn encode_tracks(rows: &[TrackRow]) -> String {
    let mut text = String::new();
    for r in rows {
        let p = r.point;
        text.push_str(&format!(
            "{},{},{},{},{},{}\n",
            p.t, p.person, p.x, p.y, r.speed, r.heading
        ));
    }
    text
}

/// Writes [`encode_tracks`] to `path` atomically.
///
/// # Errors
/// A [`DataError`] naming `path` if it cannot be written.
pub fn write_tracks(path: impl AsRef<Path>, rows: &[TrackRow]) -> Result<(), DataError> {
    crate::text::write_data_file(path.as_ref(), encode_tracks(rows).as_bytes())
}

/// As [`read_tracks_from`], keeping the person ids.
///
/// # Errors
/// As [`read_tracks`].
pub fn read_track_points_from(name: &str, reader: impl Read) -> Result<Vec<TrackPoint>, DataError> {
    let mut events = Vec::new();
    for_each_data_line(name, reader, |_, line| {
        let mut fields = Fields::new(line);
        let mut next = |field| required(fields.next(), field, EXPECTED);
        let t_text = next(Field::Time)?;
        let t = parse_finite(t_text, Field::Time)?;
        if t < 0.0 {
            return Err(DataErrorKind::NegativeTime {
                text: quote(t_text),
            });
        }
        let person = parse_person(next(Field::Person)?)?;
        let x = parse_finite(next(Field::X)?, Field::X)?;
        let y = parse_finite(next(Field::Y)?, Field::Y)?;
        parse_non_negative(next(Field::Speed)?, Field::Speed)?;
        parse_finite(next(Field::Heading)?, Field::Heading)?;
        fields.finish(EXPECTED)?;
        events.push(TrackPoint { t, person, x, y });
        Ok(())
    })?;
    if events.is_empty() {
        return Err(DataError::new(name, None, DataErrorKind::Empty));
    }
    events.sort_by(|a, b| a.t.total_cmp(&b.t));
    Ok(events)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::text::test_support::assert_errors;

    fn error(text: &str) -> DataError {
        read_tracks_from("atc.csv", text.as_bytes()).unwrap_err()
    }

    #[test]
    fn sorts_by_time_and_keeps_equal_times_in_file_order() {
        let text = "# ATC\n5,1,0,0,0,0\r\n3,2,1,1,0.5,1\n\n5,3,2,2,0,0\n";
        let e = read_tracks_from("atc.csv", text.as_bytes()).unwrap();
        let got: Vec<(f64, f64)> = e.iter().map(|e| (e.t, e.x)).collect();
        assert_eq!(got, [(3.0, 1.0), (5.0, 0.0), (5.0, 2.0)]);
    }

    #[test]
    fn errors_name_file_line_and_field() {
        let cases = [
            (
                "1,1,nan,0,0,0\n",
                1,
                Some(Field::X),
                "x: \"nan\" is not a finite number",
            ),
            (
                "1,1,0,0,0,0\n-3,1,0,0,0,0\n",
                2,
                Some(Field::Time),
                "time: \"-3\" is negative",
            ),
            (
                "1,99999999999999999999999,0,0,0,0\n",
                1,
                Some(Field::Person),
                "person:",
            ),
            ("1,1.5,0,0,0,0\n", 1, Some(Field::Person), "person: \"1.5\""),
            (
                "1,1,0,0,-1,0\n",
                1,
                Some(Field::Speed),
                "speed: \"-1\" is negative",
            ),
            ("1,1,0,0,0\n", 1, Some(Field::Heading), "heading: missing"),
            ("1,1,0,0,0,0,7\n", 1, None, "unexpected extra field \"7\""),
            (
                "1,1,0,inf,0,0\n",
                1,
                Some(Field::Y),
                "y: \"inf\" is not a finite number",
            ),
        ];
        assert_errors("atc.csv", read_tracks_from, &cases);
        assert!(matches!(error("# nothing\n").kind(), DataErrorKind::Empty));
    }
}
