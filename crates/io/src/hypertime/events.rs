//! Readers of event files: people detected at a time and a position (the Lincoln pedestrian
//! data bundled in `data/lincoln_pedestrians_2017/`, see `data/README.md`).
//!
//! ```
//! use chronomap_io::events::read_events_from;
//! use chronomap_io::Field;
//!
//! // `t x y` and any further fields (ignored): a weight, a waypoint name, ...
//! let text = "1495617883.77 16.4862 -1.0019 1.0000\n1495617883.77 2.5 -0.9 WP4\n";
//! let events = read_events_from("people.txt", text.as_bytes())?;
//! assert_eq!(events.len(), 2);
//! assert_eq!((events[1].x, events[1].y), (2.5, -0.9));
//!
//! // Times must not go backwards; errors name the file, line and field.
//! let err = read_events_from("people.txt", "10 0 0\n9 1 1\n".as_bytes()).unwrap_err();
//! assert_eq!((err.line(), err.field()), (Some(2), Some(Field::Time)));
//! # Ok::<(), chronomap_io::DataError>(())
//! ```
//!
//! # Formats
//! * **Events**: one detection per line, `t x y`, separated by whitespace or a comma; fields
//!   after `y` are ignored (the bundled files carry a weight `1` or two further numbers and a
//!   waypoint name). `t` is in seconds (unix time), `x` and `y` in metres.
//! * **Events with a range header** (the Warped Hypertime ICRA 2019 files such as
//!   `kontrolni_ctvrtek.txt`): three lines `min max` (the ranges of t, x and y), then events as
//!   above. A file is read this way when its first data line has exactly two fields. The
//!   header is checked (`min <= max`) and so is every event against it; the events are
//!   returned as they are (the authors padded that file with two detections at (0, 0) at the
//!   ends of the day; they are kept).
//!
//! As in [`crate::text`], blank lines and `#` comments are skipped, line numbers count every
//! line, and plain, `.xz` and `.gz` files are read. Times must be finite, `>= 0` and never go
//! backwards (detections of several people share a time: equal times are fine); coordinates
//! must be finite. Every problem is a [`DataError`] naming the file, line and field:
//!
//! ```text
//! 2017_05_26.txt.xz:17: x: "nan" is not a finite number
//! 2017_05_26.txt.xz:18: time: "1495792639.1" is earlier than the time 1495792639.92 on line 17 (times must not go backwards)
//! 2017_05_26.txt.xz:19: y: missing (expected at least three fields: t x y)
//! ```

use std::io::Read;
use std::path::Path;

use chronomap_hypertime::events::Event;

use crate::text::{
    DataError, DataErrorKind, Field, Fields, for_each_data_line, parse_finite, parse_time, quote,
    read_data_file, read_merged, required,
};

/// What an event line must look like.
const EXPECTED: &str = "expected at least three fields: t x y";

/// Reads an event file (plain, `.xz` or `.gz`; see the [module docs](self) for the formats).
///
/// ```no_run
/// let friday = chronomap_io::read_events("data/lincoln_pedestrians_2017/raw_days/2017_05_26.txt.xz")?;
/// assert_eq!(friday.len(), 22_449);
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
///
/// # Errors
/// A [`DataError`] naming `path` if the file cannot be read, has no event, or a line is not an
/// event satisfying the rules of the [module docs](self).
pub fn read_events(path: impl AsRef<Path>) -> Result<Vec<Event>, DataError> {
    read_data_file(path.as_ref(), read_events_from)
}

/// Reads several event files and merges them in time order (a stable merge: events of equal
/// times keep the order of the files). Each file is checked on its own as [`read_events`]
/// does; the files may overlap in time.
///
/// # Errors
/// The first error of [`read_events`].
pub fn read_event_files(paths: &[impl AsRef<Path>]) -> Result<Vec<Event>, DataError> {
    read_merged(paths, |path| read_events(path), |e| e.t)
}

/// Events as an event file: one `t x y` line each, every number written as the shortest text
/// that reads back to the same `f64`, so that [`read_events_from`] returns them unchanged.
///
/// ```
/// use chronomap_hypertime::events::Event;
/// use chronomap_io::events::{encode_events, read_events_from};
///
/// let events = [Event { t: 1495617883.77, x: 16.4862, y: -1.0019 }];
/// let text = encode_events(&events);
/// assert_eq!(text, "# t x y\n1495617883.77 16.4862 -1.0019\n");
/// assert_eq!(read_events_from("e.txt", text.as_bytes())?, events);
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
pub fn encode_events(events: &[Event]) -> String {
    let mut text = String::from("# t x y\n");
    for e in events {
        text.push_str(&format!("{} {} {}\n", e.t, e.x, e.y));
    }
    text
}

/// Writes [`encode_events`] to `path` atomically (a crash never leaves half a file).
///
/// # Errors
/// A [`DataError`] naming `path` if it cannot be written.
pub fn write_events(path: impl AsRef<Path>, events: &[Event]) -> Result<(), DataError> {
    crate::text::write_data_file(path.as_ref(), encode_events(events).as_bytes())
}

/// Where the reader is in a file.
enum State {
    /// Before the first data line.
    Start,
    /// Inside a range header: the ranges read so far and the line of the first one.
    Header(Vec<(f64, f64)>, usize),
    /// Reading events, with the header's ranges of t, x, y if the file had one.
    Events(Option<[(f64, f64); 3]>),
}

const RANGE_FIELDS: [Field; 3] = [Field::Time, Field::X, Field::Y];

/// Reads events (uncompressed text) from `reader`; `name` is used in errors.
///
/// ```
/// use chronomap_io::events::read_events_from;
///
/// // A range header (t, x, y), then events inside the ranges.
/// let text = "1495670400 1495756800\n-8 12\n-3 17\n1495706022.77 2.54 -0.89\n";
/// assert_eq!(read_events_from("ctvrtek.txt", text.as_bytes())?.len(), 1);
/// let outside = "0 100\n-8 12\n-3 17\n50 13 0\n";
/// let err = read_events_from("ctvrtek.txt", outside.as_bytes()).unwrap_err();
/// assert_eq!(err.to_string(), r#"ctvrtek.txt:4: x: "13" is outside the range -8 .. 12 of the header"#);
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
///
/// # Errors
/// As [`read_events`].
pub fn read_events_from(name: &str, reader: impl Read) -> Result<Vec<Event>, DataError> {
    let mut events = Vec::new();
    let mut previous: Option<(f64, usize)> = None;
    let mut state = State::Start;
    for_each_data_line(name, reader, |line_number, line| {
        let mut fields = Fields::new(line);
        if let State::Start = state {
            let count = Fields::new(line).count();
            state = if count == 2 {
                State::Header(Vec::with_capacity(3), line_number)
            } else {
                State::Events(None)
            };
        }
        match &mut state {
            State::Header(ranges, first_line) => {
                let field = RANGE_FIELDS[ranges.len()];
                let all: Vec<&[u8]> = Fields::new(line).collect();
                if all.len() != 2 {
                    return Err(DataErrorKind::BadHeader {
                        reason: format!(
                            "expected the {field} range `min max` of a range header (line \
                             {first_line} has two fields, so the file must start with three \
                             range lines: t, x, y), found {} fields; or is y missing on line \
                             {first_line}?",
                            all.len()
                        ),
                    });
                }
                let min = parse_finite(all[0], field)?;
                let max = parse_finite(all[1], field)?;
                if min > max {
                    return Err(DataErrorKind::EmptyRange { field, min, max });
                }
                ranges.push((min, max));
                if ranges.len() == 3 {
                    state = State::Events(Some([ranges[0], ranges[1], ranges[2]]));
                }
                Ok(())
            }
            State::Events(ranges) => {
                let t_text = required(fields.next(), Field::Time, EXPECTED)?;
                let t = parse_time(t_text, previous, events.len())?;
                let x_text = required(fields.next(), Field::X, EXPECTED)?;
                let x = parse_finite(x_text, Field::X)?;
                let y_text = required(fields.next(), Field::Y, EXPECTED)?;
                let y = parse_finite(y_text, Field::Y)?;
                if let Some(ranges) = ranges {
                    for ((value, text), (field, &(min, max))) in
                        [(t, t_text), (x, x_text), (y, y_text)]
                            .into_iter()
                            .zip(RANGE_FIELDS.iter().zip(ranges.iter()))
                    {
                        if !(min <= value && value <= max) {
                            return Err(DataErrorKind::OutsideRange {
                                field: *field,
                                text: quote(text),
                                min,
                                max,
                            });
                        }
                    }
                }
                events.push(Event { t, x, y });
                previous = Some((t, line_number));
                Ok(())
            }
            State::Start => unreachable!("the state was set above"),
        }
    })?;
    if events.is_empty() {
        let kind = match state {
            State::Start | State::Events(None) => DataErrorKind::Empty,
            State::Header(..) | State::Events(Some(_)) => DataErrorKind::BadHeader {
                reason: "a range header (t, x, y) without any event after it".into(),
            },
        };
        return Err(DataError::new(name, None, kind));
    }
    Ok(events)
}
