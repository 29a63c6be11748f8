//! Readers of the text formats of the bundled door datasets (see `data/README.md`).
//!
//! ```
//! use chronomap_io::text::{read_test_set_from, Field};
//!
//! // A test set is two line-aligned files: times, and values.
//! let times = "# unix seconds\n1458518400\n1458518460\n1458518520\n";
//! let values = "0\n1\n1\n";
//! let set = read_test_set_from("times.txt", times.as_bytes(), "values.txt", values.as_bytes())?;
//! assert_eq!(set.values, [0.0, 1.0, 1.0]);
//!
//! // Bad input is reported with file, line and field.
//! let err = read_test_set_from("times.txt", "5\n4\n".as_bytes(), "values.txt", "0\n1\n".as_bytes())
//!     .unwrap_err();
//! assert_eq!((err.name(), err.line(), err.field()), ("times.txt", Some(2), Some(Field::Time)));
//! # Ok::<(), chronomap_io::DataError>(())
//! ```
//!
//! # Formats
//! * **Pairs** ([`read_pairs`]): one observation per line, `time value`, the two fields separated
//!   by whitespace or by a comma (`time,value`, `time, value`).
//! * **Columns** ([`read_column`]): one number per line. A **test set** ([`read_test_set`]) is a
//!   column of times and a column of values whose data lines correspond one to one.
//! * **Edge files** of topological maps (`time duration success`, see
//!   [`crate::topo_files`]) are read by the same line reader.
//!
//! In all of them, blank lines and lines whose first non-blank character is `#` are skipped; line
//! numbers in errors count every line of the file, skipped ones included (so they match what an
//! editor shows). `\r\n` line ends and a leading UTF-8 byte order mark are accepted.
//!
//! Numbers are parsed with Rust's `f64` parser (`1458518400`, `0.5`, `1e3`), then checked
//! against the [observation contract](chronomap_core::observe): times finite, `>= 0` and never
//! going backwards (equal times are allowed), values finite and in `[0, 1]`.
//!
//! Files whose name ends in `.xz` or `.gz` are decompressed on the fly (multi-stream files
//! included); any other file is read as plain text.
//!
//! # Errors
//! Every problem is a [`DataError`] that names the file, the 1-based line and the field, and
//! whose [`kind`](DataError::kind) can be matched on:
//!
//! ```text
//! training_data.txt:17: time: "abc" is not a number
//! training_data.txt:18: value: "1.5" is outside [0, 1]
//! test_times_1.txt: no data lines (the input is empty or has only blank lines and # comments)
//! ```

use std::fmt;
use std::io::{self, BufRead, BufReader, Read};
use std::path::Path;

use chronomap_core::num::fmt_number;
use chronomap_core::observe::{check_time, check_value};
use chronomap_core::{ObservationError, TimeSeries};
use thiserror::Error;

/// Longest accepted line in bytes (guards against reading a binary file as one huge line).
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// Longest excerpt of offending text quoted in an error message, in characters.
const MAX_QUOTED_CHARS: usize = 48;

/// Size of the read buffer.
const BUFFER_BYTES: usize = 64 * 1024;

/// The most bytes a compressed (`.xz`, `.gz`) file may decompress to (2 GiB), read as a stream:
/// a larger one is refused with a read error naming the file and line, so that a few kilobytes
/// of repeated text (gzip reaches 1,000:1, xz far more) cannot feed a reader without end. Plain
/// files and pipes have no such limit: their bytes are what is there to read.
pub const MAX_DECOMPRESSED_BYTES: u64 = 1 << 31;

/// Which field of a line an error concerns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Field {
    /// The time of an observation (seconds).
    Time,
    /// The observed value (state in `[0, 1]`).
    Value,
    /// How long an attempt took, in seconds (edge files of topological maps, see
    /// [`crate::topo_files`]).
    Duration,
    /// Whether an attempt succeeded, `0` or `1` (edge files of topological maps).
    Success,
    /// The x coordinate of an event, in metres (event files, see [`crate::events`]).
    X,
    /// The y coordinate of an event, in metres (event files).
    Y,
    /// The first coordinate of a cell centre, in metres (activity-rate grids, see
    /// [`crate::activity`]).
    X1,
    /// The second coordinate of a cell centre, in metres (activity-rate grids).
    X2,
    /// The time bin of a sample of an activity-rate grid (column `t`).
    BinTime,
    /// A rate of people per hour of observation (column `y` of activity-rate grids).
    Rate,
    /// The id of a tracked person (pedestrian track files, see [`crate::tracks`]).
    Person,
    /// A walking speed in m/s (pedestrian track files).
    Speed,
    /// A walking direction in radians (pedestrian track files).
    Heading,
    /// A number of detections in a cell (column `count` of extracted activity-rate grids).
    Count,
    /// How long a cell was observed, in seconds (column `duration_s` of extracted
    /// activity-rate grids).
    ObservedDuration,
    /// The name of a robot path (robot path files, see [`crate::robot_paths`]).
    PathName,
    /// How long a robot stops at a waypoint, in seconds (robot path files).
    Stop,
    /// The map file of a frame (frame lists of occupancy grids, module `frame_list`).
    MapFile,
}

impl Field {
    /// `"time"`, `"value"`, `"duration"`, `"success"`, `"x"`, `"y"`, the column names of
    /// activity-rate grids `"x1"`, `"x2"`, `"t"`, `"y"` (for [`Field::Rate`]), `"count"`,
    /// `"duration_s"`, `"person"`, `"speed"`, `"heading"` of pedestrian tracks, or `"path"`
    /// and `"stop_s"` of robot path files, or `"map"` of frame lists.
    pub fn as_str(self) -> &'static str {
        match self {
            Field::Time => "time",
            Field::Value => "value",
            Field::Duration => "duration",
            Field::Success => "success",
            Field::X => "x",
            Field::Y => "y",
            Field::X1 => "x1",
            Field::X2 => "x2",
            Field::BinTime => "t",
            Field::Rate => "y",
            Field::Person => "person",
            Field::Speed => "speed",
            Field::Heading => "heading",
            Field::Count => "count",
            Field::ObservedDuration => "duration_s",
            Field::PathName => "path",
            Field::Stop => "stop_s",
            Field::MapFile => "map",
        }
    }
}

impl fmt::Display for Field {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// What is wrong with a data file (the part of a [`DataError`] after `file:line:`).
///
/// Offending text is quoted as it appears in the file (shortened if very long).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum DataErrorKind {
    /// The file could not be opened or read (missing file, permissions, corrupt compressed
    /// data, ...).
    #[error("cannot {action}: {io}")]
    Io {
        /// What was being done: `"open"` or `"read"`.
        action: &'static str,
        /// The underlying error.
        io: io::Error,
    },
    /// A field is not a number.
    #[error("{field}: {text:?} is not a number")]
    NotANumber {
        /// The field.
        field: Field,
        /// The offending text.
        text: String,
    },
    /// A line has fewer fields than the format requires.
    #[error("{field}: missing ({expected})")]
    MissingField {
        /// The first missing field.
        field: Field,
        /// What a line must look like.
        expected: &'static str,
    },
    /// A line has more fields than the format allows.
    #[error("unexpected extra field {text:?} ({expected})")]
    ExtraField {
        /// The first extra field.
        text: String,
        /// What a line must look like.
        expected: &'static str,
    },
    /// A time or value is NaN or infinite (`nan`, `inf`, or a number too large for `f64`).
    #[error("{field}: {text:?} is not a finite number")]
    NonFinite {
        /// The field.
        field: Field,
        /// The offending text.
        text: String,
    },
    /// A time is negative.
    #[error("time: {text:?} is negative (times are seconds >= 0)")]
    NegativeTime {
        /// The offending text.
        text: String,
    },
    /// A time is earlier than the time of the data line before it.
    #[error(
        "time: {text:?} is earlier than the time {} on line {previous_line} \
         (times must not go backwards)",
        fmt_number(.previous)
    )]
    TimeNotIncreasing {
        /// The offending text.
        text: String,
        /// The previous time.
        previous: f64,
        /// The 1-based line of the previous time.
        previous_line: usize,
    },
    /// A value lies outside `[0, 1]`.
    #[error("value: {text:?} is outside [0, 1]")]
    ValueOutOfRange {
        /// The offending text.
        text: String,
    },
    /// A duration is negative.
    #[error("duration: {text:?} is negative (durations are seconds >= 0)")]
    NegativeDuration {
        /// The offending text.
        text: String,
    },
    /// A duration is longer than [`MAX_DURATION_SECS`].
    #[error("duration: {text:?} is longer than the longest duration 1e9 s (about 32 years)")]
    DurationTooLong {
        /// The offending text.
        text: String,
    },
    /// A flag (such as [`Field::Success`]) is neither `0` nor `1`.
    #[error("{field}: {text:?} is not 0 or 1")]
    NotZeroOrOne {
        /// The field.
        field: Field,
        /// The offending text.
        text: String,
    },
    /// A file in a directory of edge files is neither an edge file nor a file the reader
    /// ignores (see [`crate::topo_files`]).
    #[error(
        "not an edge file (a directory of edges holds <From>_<To>.data files, plain, .xz or \
         .gz, and may hold path*.txt lists)"
    )]
    UnexpectedFile,
    /// The name of an edge file does not name two nodes `<From>_<To>`.
    #[error("edge file name {stem:?} does not name an edge <From>_<To>: {reason}")]
    EdgeFileName {
        /// The file name without its extensions.
        stem: String,
        /// Why it does not split.
        reason: String,
    },
    /// Two files describe the same edge (e.g. `A_B.data` and `A_B.data.xz`).
    #[error("edge {edge:?} has a second file: {other}")]
    DuplicateEdgeFile {
        /// The edge id.
        edge: String,
        /// The other file of the edge.
        other: String,
    },
    /// A range line of an event file's header (`min max`) has `min > max`.
    #[error(
        "{field}: the range {} .. {} of the header is empty (min must not exceed max)",
        fmt_number(.min),
        fmt_number(.max)
    )]
    EmptyRange {
        /// The field whose range it is.
        field: Field,
        /// The lower bound.
        min: f64,
        /// The upper bound.
        max: f64,
    },
    /// A field lies outside the range the file's header declares.
    #[error(
        "{field}: {text:?} is outside the range {} .. {} of the header",
        fmt_number(.min),
        fmt_number(.max)
    )]
    OutsideRange {
        /// The field.
        field: Field,
        /// The offending text.
        text: String,
        /// The lower bound.
        min: f64,
        /// The upper bound.
        max: f64,
    },
    /// A line of a calendar of days off does not start with a date `YYYY-MM-DD` that exists.
    #[error("date: {text:?} is not a date YYYY-MM-DD")]
    BadDate {
        /// The text found (shortened if long).
        text: String,
    },
    /// An event file starts like a file with a range header (a first data line of two fields)
    /// but does not continue like one.
    #[error("{reason}")]
    BadHeader {
        /// What is wrong.
        reason: String,
    },
    #[cfg(feature = "topo")]
    /// The topological map cannot be built (e.g. an invalid or repeated node name).
    #[error("{error}")]
    Map {
        /// What is wrong with the map.
        error: chronomap_topo::map::TopoError,
    },
    /// Another violation of the observation contract.
    #[error("{field}: {text:?} is rejected: {reason}")]
    Rejected {
        /// The field.
        field: Field,
        /// The offending text.
        text: String,
        /// The violation.
        reason: ObservationError,
    },
    /// A line of a scenario file breaks its rules (see [`crate::scenarios`]): a bad name, a
    /// repeated waypoint, a scenario split over separate blocks of lines or with fewer than
    /// two waypoints. The reason starts with the column concerned.
    #[error("{reason}")]
    Scenario {
        /// What is wrong, e.g. `waypoint: "A" appears twice in scenario "hallway"`.
        reason: String,
    },
    /// A field is longer than its format allows (a map path of a frame list).
    #[error("{field}: {text:?} is longer than {max} bytes")]
    FieldTooLong {
        /// The field.
        field: Field,
        /// The start of the offending text.
        text: String,
        /// The limit in bytes.
        max: usize,
    },
    /// A line is longer than [`MAX_LINE_BYTES`] (probably not a text file).
    #[error("line longer than {max} bytes (is this a text file?)")]
    LineTooLong {
        /// The limit in bytes.
        max: usize,
    },
    /// A field that must not be negative is (rates of people in activity-rate grids).
    #[error("{field}: {text:?} is negative (must be >= 0)")]
    Negative {
        /// The field.
        field: Field,
        /// The offending text.
        text: String,
    },
    /// A name (of a robot path) is not letters, digits, `_` and `-`.
    #[error("{field}: {text:?} is not a name (letters, digits, `_` and `-`)")]
    BadName {
        /// The field.
        field: Field,
        /// The offending text.
        text: String,
    },
    /// A field that must be positive is not (observed durations).
    #[error("{field}: {text:?} is not positive (must be > 0)")]
    NotPositive {
        /// The field.
        field: Field,
        /// The offending text.
        text: String,
    },
    /// A robot path's waypoints are not consecutive lines.
    #[error(
        "path {name:?} continues after other paths (it began on line {first_line}; the \
         waypoints of a path must be consecutive lines)"
    )]
    PathInterrupted {
        /// The path.
        name: String,
        /// The line of its first waypoint.
        first_line: usize,
    },
    #[cfg(feature = "activity")]
    /// The waypoints of a robot path do not make a path (reported at its first waypoint).
    #[error("path {name:?}: {error}")]
    RobotPath {
        /// The path.
        name: String,
        /// What is wrong.
        error: chronomap_activity::extract::ExtractError,
    },
    /// There is no data line at all.
    #[error("no data lines (the input is empty or has only blank lines and # comments)")]
    Empty,
    /// The two files of a test set have different numbers of data lines.
    #[error(
        "{values} values but {times_name} has {times} times \
         (the two files of a test set must be line-aligned)"
    )]
    LineCountMismatch {
        /// Name of the file of times.
        times_name: String,
        /// Number of data lines in the file of times.
        times: usize,
        /// Number of data lines in the file of values (the file the error is about).
        values: usize,
    },
}

/// Why a data file was rejected: the file, the 1-based line (when the problem is on a line) and
/// the problem.
///
/// Displays as `file:line: problem`, e.g. `training_data.txt:17: time: "abc" is not a number`,
/// or `file: problem` when no line is concerned.
#[derive(Debug, Error)]
#[error("{name}{}: {kind}", LineSuffix(*.line))]
pub struct DataError {
    name: String,
    line: Option<usize>,
    kind: DataErrorKind,
}

struct LineSuffix(Option<usize>);

impl fmt::Display for LineSuffix {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(line) => write!(f, ":{line}"),
            None => Ok(()),
        }
    }
}

impl DataError {
    /// An error about `name` (a path or another name of the input), optionally at a line.
    pub fn new(name: impl Into<String>, line: Option<usize>, kind: DataErrorKind) -> Self {
        DataError {
            name: name.into(),
            line,
            kind,
        }
    }

    /// The file (as given to the reader) or the name of the input.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The 1-based line, if the error concerns one line.
    pub fn line(&self) -> Option<usize> {
        self.line
    }

    /// What is wrong.
    pub fn kind(&self) -> &DataErrorKind {
        &self.kind
    }

    /// The field concerned, if any.
    pub fn field(&self) -> Option<Field> {
        match self.kind {
            DataErrorKind::NotANumber { field, .. }
            | DataErrorKind::MissingField { field, .. }
            | DataErrorKind::NonFinite { field, .. }
            | DataErrorKind::NotZeroOrOne { field, .. }
            | DataErrorKind::EmptyRange { field, .. }
            | DataErrorKind::OutsideRange { field, .. }
            | DataErrorKind::Negative { field, .. }
            | DataErrorKind::BadName { field, .. }
            | DataErrorKind::NotPositive { field, .. }
            | DataErrorKind::FieldTooLong { field, .. }
            | DataErrorKind::Rejected { field, .. } => Some(field),
            DataErrorKind::NegativeDuration { .. } | DataErrorKind::DurationTooLong { .. } => {
                Some(Field::Duration)
            }
            DataErrorKind::NegativeTime { .. } | DataErrorKind::TimeNotIncreasing { .. } => {
                Some(Field::Time)
            }
            DataErrorKind::ValueOutOfRange { .. } => Some(Field::Value),
            DataErrorKind::PathInterrupted { .. } => Some(Field::PathName),
            _ => None,
        }
    }
}

/// Reads a file of `time value` lines (plain, `.xz` or `.gz`).
///
/// ```no_run
/// let training = chronomap_io::read_pairs("data/door_greg_2016/training_data.txt.xz")?;
/// assert_eq!(training.len(), 96_480);
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
///
/// # Errors
/// A [`DataError`] naming `path` if the file cannot be read, has no data line, or a line is not
/// `time value` with a time and a value satisfying the
/// [observation contract](chronomap_core::observe).
pub fn read_pairs(path: impl AsRef<Path>) -> Result<TimeSeries, DataError> {
    read_data_file(path.as_ref(), read_pairs_from)
}

/// Reads `time value` lines (uncompressed text) from `reader`; `name` is used in errors.
///
/// ```
/// let series = chronomap_io::read_pairs_from("door", "0 1\n60,0\n120, 1\n".as_bytes())?;
/// assert_eq!(series.times, [0.0, 60.0, 120.0]);
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
///
/// # Errors
/// As [`read_pairs`].
pub fn read_pairs_from(name: &str, reader: impl Read) -> Result<TimeSeries, DataError> {
    const EXPECTED: &str = "expected two fields: time value";
    let (times, values) = read_timed_lines(name, reader, EXPECTED, |fields| fields.next_value())?;
    Ok(TimeSeries { times, values })
}

/// Reads `time value` lines whose values are any finite numbers — measurements of a continuous
/// state in its own units (a temperature, a speed), for a model created with a range that
/// checks them itself — from `path` (plain, `.xz` or `.gz`). Times follow the
/// [observation contract](chronomap_core::observe) as in [`read_pairs`].
///
/// ```
/// let series = chronomap_io::read_measurements_from("temperature", "0 21.5\n60 -3\n".as_bytes())?;
/// assert_eq!(series.values, [21.5, -3.0]);
/// let err = chronomap_io::read_measurements_from("temperature", "0 21.5\n60 inf\n".as_bytes())
///     .unwrap_err();
/// assert_eq!(err.line(), Some(2));
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
///
/// # Errors
/// A [`DataError`] naming `path` if the file cannot be read, has no data line, or a line is not
/// `time value` with a valid time and a finite value.
pub fn read_measurements(path: impl AsRef<Path>) -> Result<TimeSeries, DataError> {
    read_data_file(path.as_ref(), read_measurements_from)
}

/// [`read_measurements`] from `reader` (uncompressed text); `name` is used in errors.
///
/// # Errors
/// As [`read_measurements`].
pub fn read_measurements_from(name: &str, reader: impl Read) -> Result<TimeSeries, DataError> {
    const EXPECTED: &str = "expected two fields: time value";
    let (times, values) = read_timed_lines(name, reader, EXPECTED, |fields| {
        parse_finite(fields.next_text(Field::Value)?, Field::Value)
    })?;
    Ok(TimeSeries { times, values })
}

/// The fields after the time of one data line, for [`read_timed_lines`].
pub(crate) struct LineFields<'a> {
    fields: Fields<'a>,
    expected: &'static str,
    index: usize,
}

impl<'a> LineFields<'a> {
    /// The next field as text; [`DataErrorKind::MissingField`] if it is absent or empty.
    pub(crate) fn next_text(&mut self, field: Field) -> Result<&'a [u8], DataErrorKind> {
        required(self.fields.next(), field, self.expected)
    }

    /// The next field as a duration in seconds (finite, `>= 0`, at most
    /// [`MAX_DURATION_SECS`]).
    #[cfg_attr(not(feature = "topo"), allow(dead_code))]
    pub(crate) fn next_duration(&mut self) -> Result<f64, DataErrorKind> {
        parse_duration(self.next_text(Field::Duration)?)
    }

    /// The next field as a success flag (`0` or `1`).
    #[cfg_attr(not(feature = "topo"), allow(dead_code))]
    pub(crate) fn next_success(&mut self) -> Result<bool, DataErrorKind> {
        parse_success(self.next_text(Field::Success)?)
    }

    /// The next field as an observed value (the [`Field::Value`] part of the observation
    /// contract).
    pub(crate) fn next_value(&mut self) -> Result<f64, DataErrorKind> {
        let text = self.next_text(Field::Value)?;
        parse_value(text, self.index)
    }
}

/// The generic line reader behind [`read_pairs_from`] and the edge files of
/// [`crate::topo_files`]: every data line starts with a time (checked against the
/// [observation contract](chronomap_core::observe): finite, `>= 0`, never going backwards),
/// `rest` parses the remaining fields into a record, and a field left over is an
/// [`DataErrorKind::ExtraField`] error. `expected` describes a line for error messages.
///
/// Returns the times and the records, or the first error, naming `name` and the line.
pub(crate) fn read_timed_lines<T>(
    name: &str,
    reader: impl Read,
    expected: &'static str,
    mut rest: impl FnMut(&mut LineFields<'_>) -> Result<T, DataErrorKind>,
) -> Result<(Vec<f64>, Vec<T>), DataError> {
    let mut times = Vec::new();
    let mut records = Vec::new();
    let mut previous: Option<(f64, usize)> = None;
    for_each_data_line(name, reader, |line_number, line| {
        let mut fields = LineFields {
            fields: Fields::new(line),
            expected,
            index: times.len(),
        };
        let time_text = fields.next_text(Field::Time)?;
        let time = parse_time(time_text, previous, times.len())?;
        let record = rest(&mut fields)?;
        fields.fields.finish(expected)?;
        times.push(time);
        records.push(record);
        previous = Some((time, line_number));
        Ok(())
    })?;
    Ok((times, records))
}

/// Reads a file with one time (`field == Field::Time`) or one value (`Field::Value`) per line
/// (plain, `.xz` or `.gz`).
///
/// The field decides which part of the [observation contract](chronomap_core::observe) is
/// checked and what errors call the numbers. Durations ([`Field::Duration`]) must be finite,
/// `>= 0` and at most [`MAX_DURATION_SECS`]; success flags ([`Field::Success`]) exactly `0` or `1` (read as `0.0`, `1.0`).
///
/// # Errors
/// A [`DataError`] naming `path` if the file cannot be read, has no data line, or a line is not
/// exactly one number satisfying the contract.
pub fn read_column(path: impl AsRef<Path>, field: Field) -> Result<Vec<f64>, DataError> {
    read_data_file(path.as_ref(), |name, reader| {
        read_column_from(name, reader, field)
    })
}

/// Reads one number per line (uncompressed text) from `reader`; `name` is used in errors.
///
/// ```
/// use chronomap_io::text::{read_column_from, DataErrorKind, Field};
///
/// assert_eq!(read_column_from("v", "0\n\n# gap\n0.5\n".as_bytes(), Field::Value)?, [0.0, 0.5]);
/// let err = read_column_from("v", "0\n\n2\n".as_bytes(), Field::Value).unwrap_err();
/// assert_eq!(err.to_string(), r#"v:3: value: "2" is outside [0, 1]"#);
/// assert!(matches!(err.kind(), DataErrorKind::ValueOutOfRange { .. }));
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
///
/// # Errors
/// As [`read_column`].
pub fn read_column_from(
    name: &str,
    reader: impl Read,
    field: Field,
) -> Result<Vec<f64>, DataError> {
    let expected = match field {
        Field::Time => "expected one time per line",
        Field::Value => "expected one value per line",
        Field::Duration => "expected one duration per line",
        Field::Success => "expected one success flag (0 or 1) per line",
        Field::X | Field::Y | Field::X1 | Field::X2 => "expected one coordinate per line",
        Field::BinTime => "expected one time bin per line",
        Field::Rate => "expected one rate per line",
        Field::Person => "expected one person id per line",
        Field::Speed => "expected one speed per line",
        Field::Heading => "expected one heading per line",
        Field::Count => "expected one count per line",
        Field::ObservedDuration => "expected one observed duration per line",
        Field::PathName | Field::MapFile => {
            "expected one number per line (path names are not numbers)"
        }
        Field::Stop => "expected one stop duration per line",
    };
    let mut numbers = Vec::new();
    let mut previous: Option<(f64, usize)> = None;
    for_each_data_line(name, reader, |line_number, line| {
        let mut fields = Fields::new(line);
        let text = required(fields.next(), field, expected)?;
        let number = match field {
            Field::Time => parse_time(text, previous, numbers.len())?,
            Field::Value => parse_value(text, numbers.len())?,
            Field::Duration => parse_duration(text)?,
            Field::Success => f64::from(u8::from(parse_success(text)?)),
            Field::X | Field::Y | Field::X1 | Field::X2 | Field::BinTime | Field::Heading => {
                parse_finite(text, field)?
            }
            Field::Rate | Field::Speed | Field::Count | Field::Stop => {
                parse_non_negative(text, field)?
            }
            Field::ObservedDuration => {
                let duration = parse_finite(text, field)?;
                if duration <= 0.0 {
                    return Err(DataErrorKind::NotPositive {
                        field,
                        text: quote(text),
                    });
                }
                duration
            }
            Field::PathName | Field::MapFile => parse_number(text, field)?,
            Field::Person => parse_person(text)? as f64,
        };
        fields.finish(expected)?;
        numbers.push(number);
        previous = Some((number, line_number));
        Ok(())
    })?;
    Ok(numbers)
}

/// Reads a test set: a file of times and a line-aligned file of values (each plain, `.xz` or
/// `.gz`).
///
/// ```no_run
/// let week = chronomap_io::read_test_set(
///     "data/door_greg_2016/test_times_1.txt.xz",
///     "data/door_greg_2016/test_data_1.txt.xz",
/// )?;
/// assert_eq!(week.len(), 10_081);
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
///
/// # Errors
/// As [`read_column`] for either file, and [`DataErrorKind::LineCountMismatch`] (naming both
/// files) if they have different numbers of data lines.
pub fn read_test_set(
    times_path: impl AsRef<Path>,
    values_path: impl AsRef<Path>,
) -> Result<TimeSeries, DataError> {
    let (times_path, values_path) = (times_path.as_ref(), values_path.as_ref());
    let times_name = times_path.display().to_string();
    let values_name = values_path.display().to_string();
    let times = read_column_from(&times_name, open_data_file(times_path)?, Field::Time)?;
    let values = read_column_from(&values_name, open_data_file(values_path)?, Field::Value)?;
    aligned(times_name, times, values_name, values)
}

/// Reads a test set from two readers of uncompressed text; the names are used in errors.
///
/// # Errors
/// As [`read_test_set`].
pub fn read_test_set_from(
    times_name: &str,
    times_reader: impl Read,
    values_name: &str,
    values_reader: impl Read,
) -> Result<TimeSeries, DataError> {
    let times = read_column_from(times_name, times_reader, Field::Time)?;
    let values = read_column_from(values_name, values_reader, Field::Value)?;
    aligned(times_name.to_owned(), times, values_name.to_owned(), values)
}

fn aligned(
    times_name: String,
    times: Vec<f64>,
    values_name: String,
    values: Vec<f64>,
) -> Result<TimeSeries, DataError> {
    if times.len() != values.len() {
        return Err(DataError::new(
            values_name,
            None,
            DataErrorKind::LineCountMismatch {
                times_name,
                times: times.len(),
                values: values.len(),
            },
        ));
    }
    Ok(TimeSeries { times, values })
}

/// Opens a data file for reading, decompressing `.xz` and `.gz` files on the fly.
///
/// # Errors
/// [`DataErrorKind::Io`] naming `path` if the file cannot be opened or is a directory or a
/// device (`/dev/zero` would never end; a pipe may). Errors in compressed data surface later,
/// as read errors.
pub fn open_data_file(path: impl AsRef<Path>) -> Result<Box<dyn Read + Send>, DataError> {
    let path = path.as_ref();
    let file = crate::bounded::open_stream(path).map_err(|io| {
        DataError::new(
            path.display().to_string(),
            None,
            DataErrorKind::Io { action: "open", io },
        )
    })?;
    Ok(decompressing_reader(&path.to_string_lossy(), file))
}

/// Reads the data file `path` ([`open_data_file`]: plain, `.xz` or `.gz`) with `read`, which
/// gets the name of the file for its errors and the decompressed text.
pub(crate) fn read_data_file<T>(
    path: &Path,
    read: impl FnOnce(&str, Box<dyn Read + Send>) -> Result<T, DataError>,
) -> Result<T, DataError> {
    read(&path.display().to_string(), open_data_file(path)?)
}

/// Reads every file of `paths` with `read` and merges their records in the order of `time`
/// (a stable sort: records of equal times keep the order of the files).
#[cfg(feature = "hypertime")]
pub(crate) fn read_merged<T>(
    paths: &[impl AsRef<Path>],
    read: impl Fn(&Path) -> Result<Vec<T>, DataError>,
    time: impl Fn(&T) -> f64,
) -> Result<Vec<T>, DataError> {
    let mut all = Vec::new();
    for path in paths {
        all.extend(read(path.as_ref())?);
    }
    all.sort_by(|a, b| time(a).total_cmp(&time(b)));
    Ok(all)
}

/// Writes `bytes` to `path` atomically (a temporary file renamed over the target: a crash
/// never leaves half a file).
///
/// # Errors
/// [`DataErrorKind::Io`] naming `path` if it cannot be written.
pub fn write_data_file(path: &Path, bytes: &[u8]) -> Result<(), DataError> {
    crate::atomic::write_atomically(path, bytes).map_err(|failure| {
        DataError::new(
            path.display().to_string(),
            None,
            DataErrorKind::Io {
                action: failure.action,
                io: failure.io,
            },
        )
    })
}

/// Wraps `reader` in a decompressor chosen by the extension of `name`: `.xz` and `.gz` are
/// decompressed on the fly, anything else is read as it is (used for embedded data).
pub fn decompressing_reader<'a>(
    name: &str,
    reader: impl Read + Send + 'a,
) -> Box<dyn Read + Send + 'a> {
    let extension = Path::new(name)
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("");
    if extension.eq_ignore_ascii_case("xz") {
        Box::new(EndOfInput {
            inner: lzma_rust2::XzReader::new(BufReader::with_capacity(BUFFER_BYTES, reader), true),
            format: "xz",
            left: MAX_DECOMPRESSED_BYTES,
        })
    } else if extension.eq_ignore_ascii_case("gz") {
        Box::new(EndOfInput {
            inner: flate2::read::MultiGzDecoder::new(BufReader::with_capacity(
                BUFFER_BYTES,
                reader,
            )),
            format: "gz",
            left: MAX_DECOMPRESSED_BYTES,
        })
    } else {
        Box::new(reader)
    }
}

/// A decompressor whose "unexpected end of input" errors (which read "failed to fill whole
/// buffer") say what happened: the compressed file is truncated or empty; and which fails once
/// it has produced more than [`MAX_DECOMPRESSED_BYTES`] (`left` counts down).
struct EndOfInput<R> {
    inner: R,
    format: &'static str,
    left: u64,
}

impl<R: Read> EndOfInput<R> {
    fn read_inner(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.inner.read(buf).map_err(|e| {
            if e.kind() == io::ErrorKind::UnexpectedEof {
                io::Error::new(
                    io::ErrorKind::UnexpectedEof,
                    format!("truncated or empty .{} file", self.format),
                )
            } else {
                e
            }
        })
    }
}

impl<R: Read> Read for EndOfInput<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        if self.left == 0 {
            // One byte past the limit tells a larger stream from one of exactly the limit.
            if self.read_inner(&mut [0u8; 1])? > 0 {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidData,
                    format!(
                        "the .{} file decompresses to more than {MAX_DECOMPRESSED_BYTES} bytes, \
                         the most a compressed data file may hold (decompress it and pass the \
                         plain file)",
                        self.format
                    ),
                ));
            }
            return Ok(0);
        }
        let room = buf
            .len()
            .min(usize::try_from(self.left).unwrap_or(usize::MAX));
        let read = self.read_inner(&mut buf[..room])?;
        self.left -= read as u64;
        Ok(read)
    }
}

/// Calls `handle(line_number, line)` for every data line (not blank, not a comment), with the
/// line end and surrounding whitespace removed. Returns the number of data lines, or an error
/// for the first failing line.
pub(crate) fn for_each_data_line(
    name: &str,
    reader: impl Read,
    mut handle: impl FnMut(usize, &[u8]) -> Result<(), DataErrorKind>,
) -> Result<usize, DataError> {
    let mut reader = BufReader::with_capacity(BUFFER_BYTES, reader);
    let mut buffer = Vec::with_capacity(256);
    let mut line_number = 0usize;
    let mut data_lines = 0usize;
    loop {
        buffer.clear();
        let limit = MAX_LINE_BYTES as u64 + 2; // room for "\r\n"
        let read = (&mut reader)
            .take(limit)
            .read_until(b'\n', &mut buffer)
            .map_err(|io| {
                DataError::new(
                    name,
                    Some(line_number + 1),
                    DataErrorKind::Io { action: "read", io },
                )
            })?;
        if read == 0 {
            break;
        }
        line_number += 1;
        let mut line = buffer.as_slice();
        if line_number == 1 {
            line = line.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(line);
        }
        let line = line.trim_ascii();
        if line.len() > MAX_LINE_BYTES {
            let kind = DataErrorKind::LineTooLong {
                max: MAX_LINE_BYTES,
            };
            return Err(DataError::new(name, Some(line_number), kind));
        }
        if line.is_empty() || line[0] == b'#' {
            continue;
        }
        handle(line_number, line).map_err(|kind| DataError::new(name, Some(line_number), kind))?;
        data_lines += 1;
    }
    if data_lines == 0 {
        return Err(DataError::new(name, None, DataErrorKind::Empty));
    }
    Ok(data_lines)
}

/// As [`for_each_data_line`] for a CSV file whose first data line is the header `header`
/// ([`check_header`]): `handle` gets the data lines after it. `row` names what a data line
/// holds, for the error of a header without any line after it.
#[cfg(feature = "activity")]
pub(crate) fn for_each_csv_row(
    name: &str,
    reader: impl Read,
    header: &[&str],
    row: &str,
    mut handle: impl FnMut(usize, &[u8]) -> Result<(), DataErrorKind>,
) -> Result<(), DataError> {
    let mut header_seen = false;
    let lines = for_each_data_line(name, reader, |line_number, line| {
        if header_seen {
            handle(line_number, line)
        } else {
            header_seen = true;
            check_header(line, header)
        }
    })?;
    if lines == 1 {
        let kind = DataErrorKind::BadHeader {
            reason: format!("a header `{}` without any {row} after it", header.join(",")),
        };
        return Err(DataError::new(name, None, kind));
    }
    Ok(())
}

/// Whether `text` is a name: ASCII letters, digits, `_` and `-` only.
#[cfg(feature = "activity")]
pub(crate) fn is_name(text: &[u8]) -> bool {
    text.iter()
        .all(|&b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
}

/// Fields of a trimmed line: separated by whitespace, or by one comma with optional whitespace
/// around it. An empty field (`1,,2`, a leading or trailing comma) is returned as `b""`.
pub(crate) struct Fields<'a> {
    rest: &'a [u8],
    first: bool,
}

impl<'a> Fields<'a> {
    pub(crate) fn new(line: &'a [u8]) -> Self {
        Fields {
            rest: line,
            first: true,
        }
    }

    /// Checks that no field is left: the first one left over is a
    /// [`DataErrorKind::ExtraField`] error; `expected` describes a line.
    pub(crate) fn finish(mut self, expected: &'static str) -> Result<(), DataErrorKind> {
        match self.next() {
            Some(extra) => Err(DataErrorKind::ExtraField {
                text: quote(extra),
                expected,
            }),
            None => Ok(()),
        }
    }
}

impl<'a> Iterator for Fields<'a> {
    type Item = &'a [u8];

    fn next(&mut self) -> Option<&'a [u8]> {
        let mut rest = self.rest.trim_ascii_start();
        let mut after_comma = false;
        if !self.first
            && let Some(stripped) = rest.strip_prefix(b",")
        {
            rest = stripped.trim_ascii_start();
            after_comma = true;
        }
        if rest.is_empty() && !after_comma && !self.first {
            self.rest = rest;
            return None;
        }
        self.first = false;
        let end = rest
            .iter()
            .position(|&b| b == b',' || b.is_ascii_whitespace())
            .unwrap_or(rest.len());
        let (field, tail) = rest.split_at(end);
        self.rest = tail;
        Some(field)
    }
}

pub(crate) fn required<'a>(
    field_text: Option<&'a [u8]>,
    field: Field,
    expected: &'static str,
) -> Result<&'a [u8], DataErrorKind> {
    match field_text {
        Some(text) if !text.is_empty() => Ok(text),
        _ => Err(DataErrorKind::MissingField { field, expected }),
    }
}

/// A finite rate `>= 0` (column `y` of activity-rate grids).
#[cfg_attr(not(feature = "activity"), allow(dead_code))]
pub(crate) fn parse_rate(text: &[u8]) -> Result<f64, DataErrorKind> {
    parse_non_negative(text, Field::Rate)
}

/// A finite number `>= 0` (rates, speeds).
pub(crate) fn parse_non_negative(text: &[u8], field: Field) -> Result<f64, DataErrorKind> {
    let value = parse_finite(text, field)?;
    if value < 0.0 {
        return Err(DataErrorKind::Negative {
            field,
            text: quote(text),
        });
    }
    Ok(value)
}

/// A person id: an integer `0 ..= 2⁶⁴−1` (no sign, no fraction).
pub(crate) fn parse_person(text: &[u8]) -> Result<u64, DataErrorKind> {
    std::str::from_utf8(text)
        .ok()
        .filter(|s| s.bytes().all(|b| b.is_ascii_digit()))
        .and_then(|s| s.parse::<u64>().ok())
        .ok_or_else(|| DataErrorKind::NotANumber {
            field: Field::Person,
            text: quote(text),
        })
}

pub(crate) fn parse_number(text: &[u8], field: Field) -> Result<f64, DataErrorKind> {
    std::str::from_utf8(text)
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .ok_or_else(|| DataErrorKind::NotANumber {
            field,
            text: quote(text),
        })
}

pub(crate) fn parse_time(
    text: &[u8],
    previous: Option<(f64, usize)>,
    index: usize,
) -> Result<f64, DataErrorKind> {
    let time = parse_number(text, Field::Time)?;
    check_time(index, time, previous.map(|(t, _)| t)).map_err(|reason| match reason {
        ObservationError::NonFiniteTime { .. } => DataErrorKind::NonFinite {
            field: Field::Time,
            text: quote(text),
        },
        ObservationError::NegativeTime { .. } => DataErrorKind::NegativeTime { text: quote(text) },
        ObservationError::TimeNotIncreasing { previous: t, .. } => {
            DataErrorKind::TimeNotIncreasing {
                text: quote(text),
                previous: t,
                previous_line: previous.map_or(0, |(_, line)| line),
            }
        }
        reason => DataErrorKind::Rejected {
            field: Field::Time,
            text: quote(text),
            reason,
        },
    })?;
    Ok(time)
}

fn parse_value(text: &[u8], index: usize) -> Result<f64, DataErrorKind> {
    let value = parse_number(text, Field::Value)?;
    check_value(index, value).map_err(|reason| match reason {
        ObservationError::NonFiniteValue { .. } => DataErrorKind::NonFinite {
            field: Field::Value,
            text: quote(text),
        },
        ObservationError::ValueOutOfRange { .. } => {
            DataErrorKind::ValueOutOfRange { text: quote(text) }
        }
        reason => DataErrorKind::Rejected {
            field: Field::Value,
            text: quote(text),
            reason,
        },
    })?;
    Ok(value)
}

/// A coordinate in metres, or any other finite number.
pub(crate) fn parse_finite(text: &[u8], field: Field) -> Result<f64, DataErrorKind> {
    let value = parse_number(text, field)?;
    if !value.is_finite() {
        return Err(DataErrorKind::NonFinite {
            field,
            text: quote(text),
        });
    }
    Ok(value)
}

/// Checks the header line of a CSV file whose fields must be `header`, in that order.
#[cfg(feature = "activity")]
fn check_header(line: &[u8], header: &[&str]) -> Result<(), DataErrorKind> {
    let fields: Vec<&[u8]> = Fields::new(line).collect();
    if fields.len() != header.len() || fields.iter().zip(header).any(|(f, h)| *f != h.as_bytes()) {
        return Err(DataErrorKind::BadHeader {
            reason: format!(
                "expected the header `{}`, found {:?}",
                header.join(","),
                quote(line)
            ),
        });
    }
    Ok(())
}

/// The longest duration a file may give (seconds): 10^9 s, about 32 years. Any longer one is
/// a unit error, and sums and means of durations up to it stay finite.
pub const MAX_DURATION_SECS: f64 = 1e9;

/// A duration in seconds: finite, `>= 0` and at most [`MAX_DURATION_SECS`] (`-0` is read as
/// `0`).
fn parse_duration(text: &[u8]) -> Result<f64, DataErrorKind> {
    let duration = parse_number(text, Field::Duration)?;
    if !duration.is_finite() {
        return Err(DataErrorKind::NonFinite {
            field: Field::Duration,
            text: quote(text),
        });
    }
    if duration < 0.0 {
        return Err(DataErrorKind::NegativeDuration { text: quote(text) });
    }
    if duration > MAX_DURATION_SECS {
        return Err(DataErrorKind::DurationTooLong { text: quote(text) });
    }
    Ok(duration + 0.0)
}

/// A success flag: exactly `0` or `1`.
fn parse_success(text: &[u8]) -> Result<bool, DataErrorKind> {
    match text {
        b"0" => Ok(false),
        b"1" => Ok(true),
        _ => Err(DataErrorKind::NotZeroOrOne {
            field: Field::Success,
            text: quote(text),
        }),
    }
}

/// The offending text for an error message (lossy UTF-8, shortened if long).
pub(crate) fn quote(text: &[u8]) -> String {
    shorten(&String::from_utf8_lossy(text), MAX_QUOTED_CHARS)
}

/// `text` for an error message: its first `max` characters and `…` if it is longer.
pub(crate) fn shorten(text: &str, max: usize) -> String {
    if text.chars().count() <= max {
        text.to_owned()
    } else {
        let mut short: String = text.chars().take(max).collect();
        short.push('…');
        short
    }
}

/// Helpers for the tests of the readers built on this module.
#[cfg(all(test, feature = "activity"))]
pub(crate) mod test_support {
    use super::{DataError, Field};

    /// Checks every `(text, line, field, message)` of `cases`: `read(name, text)` fails naming
    /// the file `name`, the 1-based `line` and `field`, with a message that contains `message`.
    pub(crate) fn assert_errors<'a, T: std::fmt::Debug>(
        name: &str,
        read: impl Fn(&str, &'a [u8]) -> Result<T, DataError>,
        cases: &[(&'a str, usize, Option<Field>, &str)],
    ) {
        for &(text, line, field, message) in cases {
            let err = read(name, text.as_bytes()).unwrap_err();
            assert_eq!(err.name(), name, "{text}");
            assert_eq!(err.line(), Some(line), "{text}: {err}");
            assert_eq!(err.field(), field, "{text}: {err}");
            assert!(err.to_string().contains(message), "{text}: {err}");
            assert!(err.to_string().starts_with(&format!("{name}:")), "{err}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decompression_stops_one_byte_past_the_limit() {
        // 10 bytes of gzip-decompressed comment lines, read through a limit of 8 and of 10.
        let gz = |text: &[u8]| {
            let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
            io::Write::write_all(&mut e, text).unwrap();
            e.finish().unwrap()
        };
        let bytes = gz(b"#abc\n#def\n");
        let limited = |left: u64| EndOfInput {
            inner: flate2::read::MultiGzDecoder::new(&bytes[..]),
            format: "gz",
            left,
        };
        let mut out = Vec::new();
        let err = limited(8).read_to_end(&mut out).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidData);
        assert_eq!(
            err.to_string(),
            "the .gz file decompresses to more than 2147483648 bytes, the most a compressed data \
             file may hold (decompress it and pass the plain file)"
        );
        assert_eq!(out, b"#abc\n#de", "what came before the limit");
        out.clear();
        limited(10).read_to_end(&mut out).unwrap();
        assert_eq!(out, b"#abc\n#def\n");
        // Through a data-line reader, the error names the file and the line it stopped in.
        let reader = EndOfInput {
            inner: flate2::read::MultiGzDecoder::new(&bytes[..]),
            format: "gz",
            left: 7,
        };
        let err = for_each_data_line("bomb.txt.gz", reader, |_, _| Ok(())).unwrap_err();
        assert!(
            err.to_string()
                .starts_with("bomb.txt.gz:2: cannot read: the .gz file decompresses to more than"),
            "{err}"
        );
    }

    fn fields(line: &str) -> Vec<&str> {
        Fields::new(line.as_bytes())
            .map(|f| std::str::from_utf8(f).unwrap())
            .collect()
    }

    #[test]
    fn splits_fields_on_whitespace_or_one_comma() {
        assert_eq!(fields("1 0"), ["1", "0"]);
        assert_eq!(fields("1\t 0"), ["1", "0"]);
        assert_eq!(fields("1,0"), ["1", "0"]);
        assert_eq!(fields("1 , 0"), ["1", "0"]);
        assert_eq!(fields("1,,0"), ["1", "", "0"]);
        assert_eq!(fields(",0"), ["", "0"]);
        assert_eq!(fields("1,"), ["1", ""]);
        assert_eq!(fields("1"), ["1"]);
        assert_eq!(fields("1 0 x"), ["1", "0", "x"]);
    }

    #[test]
    fn quotes_long_text_shortened() {
        let long = "x".repeat(100);
        let quoted = quote(long.as_bytes());
        assert_eq!(quoted.chars().count(), MAX_QUOTED_CHARS + 1);
        assert!(quoted.ends_with('…'));
        assert_eq!(quote(b"\xff1"), "\u{fffd}1");
    }
}
