//! Readers of activity-rate grids: rates of people per hour of observation at spatio-temporal
//! cells, the `x1,x2,t,y` CSV files of CoPA-Map (the ATC grid bundled in
//! `data/atc_copa_map_grid/`, see `data/README.md`).
//!
//! ```
//! use chronomap_io::activity::read_rate_samples_from;
//! use chronomap_io::Field;
//!
//! let text = "x1,x2,t,y\n3.75,-1.25,0.0,1e-06\n3.75,-0.75,0.0,12.5\n";
//! let samples = read_rate_samples_from("grid.csv", text.as_bytes())?;
//! assert_eq!(samples.len(), 2);
//! assert_eq!(samples.y(), [1e-6, 12.5]);
//!
//! // Errors name the file, line and column.
//! let err = read_rate_samples_from("grid.csv", "x1,x2,t,y\n0,0,0,-1\n".as_bytes()).unwrap_err();
//! assert_eq!(err.to_string(), r#"grid.csv:2: y: "-1" is negative (must be >= 0)"#);
//! assert_eq!(err.field(), Some(Field::Rate));
//! # Ok::<(), chronomap_io::DataError>(())
//! ```
//!
//! # Format
//! The first data line is the header `x1,x2,t,y` (required: it tells this format from others);
//! every further data line has exactly four numbers: the cell centre `x1`, `x2` (metres), the
//! time `t` (in the ATC grid, the hour-bin index: 12 recorded hours per day, nights removed)
//! and the rate `y` (people per hour of observation, `>= 0`; the ATC grid writes `1e-6` for
//! "observed, nobody seen"). Fields are separated by a comma (and/or whitespace). All numbers
//! must be finite; lines need not be in time order.
//!
//! As in [`crate::text`], blank lines and `#` comments are skipped, line numbers count every
//! line, and plain, `.xz` and `.gz` files are read. Every problem is a [`DataError`]:
//!
//! ```text
//! train.csv:1: expected the header `x1,x2,t,y`, found "x,y,t,rate"
//! train.csv:17: x2: "nan" is not a finite number
//! train.csv:18: t: missing (expected four fields: x1,x2,t,y)
//! ```

use std::io::Read;
use std::path::Path;

use chronomap_core::activity::RateSamples;

use crate::text::{
    DataError, DataErrorKind, Field, Fields, for_each_data_line, open_data_file, parse_coordinate,
    parse_rate, quote, required,
};

/// What a data line must look like.
const EXPECTED: &str = "expected four fields: x1,x2,t,y";

/// The header.
const HEADER: [&str; 4] = ["x1", "x2", "t", "y"];

/// Reads an activity-rate grid (plain, `.xz` or `.gz`; see the [module docs](self)).
///
/// ```no_run
/// let atc = chronomap_io::read_rate_samples(
///     "data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz",
/// )?;
/// assert_eq!(atc.len(), 76_456);
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
///
/// # Errors
/// A [`DataError`] naming `path` if the file cannot be read, lacks the header, has no sample,
/// or a line breaks the rules of the [module docs](self).
pub fn read_rate_samples(path: impl AsRef<Path>) -> Result<RateSamples, DataError> {
    let path = path.as_ref();
    let name = path.display().to_string();
    read_rate_samples_from(&name, open_data_file(path)?)
}

/// Reads an activity-rate grid (uncompressed text) from `reader`; `name` is used in errors.
///
/// # Errors
/// As [`read_rate_samples`].
pub fn read_rate_samples_from(name: &str, reader: impl Read) -> Result<RateSamples, DataError> {
    let mut samples = RateSamples::default();
    let mut header_seen = false;
    for_each_data_line(name, reader, |_, line| {
        if !header_seen {
            let fields: Vec<&[u8]> = Fields::new(line).collect();
            if fields.len() != 4 || fields.iter().zip(HEADER).any(|(f, h)| *f != h.as_bytes()) {
                return Err(DataErrorKind::BadHeader {
                    reason: format!("expected the header `x1,x2,t,y`, found {:?}", quote(line)),
                });
            }
            header_seen = true;
            return Ok(());
        }
        let mut fields = Fields::new(line);
        let mut next = |field| -> Result<f64, DataErrorKind> {
            parse_coordinate(required(fields.next(), field, EXPECTED)?, field)
        };
        let x1 = next(Field::X1)?;
        let x2 = next(Field::X2)?;
        let t = next(Field::BinTime)?;
        let y = parse_rate(required(fields.next(), Field::Rate, EXPECTED)?)?;
        if let Some(extra) = fields.next() {
            return Err(DataErrorKind::ExtraField {
                text: quote(extra),
                expected: EXPECTED,
            });
        }
        samples
            .push([x1, x2], t, y)
            .expect("every value was checked above");
        Ok(())
    })?;
    if samples.is_empty() {
        let kind = if header_seen {
            DataErrorKind::BadHeader {
                reason: "a header `x1,x2,t,y` without any sample after it".into(),
            }
        } else {
            DataErrorKind::Empty
        };
        return Err(DataError::new(name, None, kind));
    }
    Ok(samples)
}

/// The text of an activity-rate grid: the header `x1,x2,t,y` and one line per sample, numbers
/// written in their shortest form that reads back to the same `f64`.
///
/// ```
/// use chronomap_core::activity::RateSamples;
/// use chronomap_io::activity::{encode_rate_samples, read_rate_samples_from};
///
/// let samples = RateSamples::new(vec![[3.75, -1.25]], vec![120.0], vec![0.1 + 0.2])?;
/// let text = encode_rate_samples(&samples);
/// assert_eq!(text, "x1,x2,t,y\n3.75,-1.25,120,0.30000000000000004\n");
/// assert_eq!(read_rate_samples_from("back.csv", text.as_bytes())?, samples);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn encode_rate_samples(samples: &RateSamples) -> String {
    use std::fmt::Write;
    let mut text = String::from("x1,x2,t,y\n");
    for ((x, t), y) in samples.x().iter().zip(samples.t()).zip(samples.y()) {
        writeln!(text, "{},{},{},{}", x[0], x[1], t, y).expect("writing to a String");
    }
    text
}

/// Writes [`encode_rate_samples`] to `path` atomically (a temporary file renamed over the
/// target: a crash never leaves half a file).
///
/// # Errors
/// A [`DataError`] naming `path` if it cannot be written.
pub fn write_rate_samples(path: impl AsRef<Path>, samples: &RateSamples) -> Result<(), DataError> {
    let path = path.as_ref();
    crate::atomic::write_atomically(path, encode_rate_samples(samples).as_bytes()).map_err(|f| {
        DataError::new(
            path.display().to_string(),
            None,
            DataErrorKind::Io {
                action: f.action,
                io: f.io,
            },
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn error(text: &str) -> DataError {
        read_rate_samples_from("grid.csv", text.as_bytes()).unwrap_err()
    }

    #[test]
    fn reads_rows_comments_and_crlf() {
        let text = "# ATC\r\nx1,x2,t,y\r\n\r\n3.75,-1.25,5,1e-06\r\n4.25, -1.25, 0, 2.5\r\n";
        let s = read_rate_samples_from("grid.csv", text.as_bytes()).unwrap();
        assert_eq!(s.x(), [[3.75, -1.25], [4.25, -1.25]]);
        assert_eq!(s.t(), [5.0, 0.0]);
        assert_eq!(s.y(), [1e-6, 2.5]);
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let cases = [
            (
                "x,y,t,rate\n0,0,0,1\n",
                1,
                None,
                "expected the header `x1,x2,t,y`, found \"x,y,t,rate\"",
            ),
            ("0,0,0,1\n", 1, None, "expected the header"),
            (
                "x1,x2,t,y\n0,nan,0,1\n",
                2,
                Some(Field::X2),
                "x2: \"nan\" is not a finite number",
            ),
            (
                "x1,x2,t,y\n0,0,0,1\n0,0,abc,1\n",
                3,
                Some(Field::BinTime),
                "t: \"abc\" is not a number",
            ),
            (
                "x1,x2,t,y\n0,0,0,inf\n",
                2,
                Some(Field::Rate),
                "y: \"inf\" is not a finite number",
            ),
            (
                "x1,x2,t,y\n0,0,0,-0.5\n",
                2,
                Some(Field::Rate),
                "y: \"-0.5\" is negative",
            ),
            (
                "x1,x2,t,y\n0,0,0\n",
                2,
                Some(Field::Rate),
                "y: missing (expected four fields: x1,x2,t,y)",
            ),
            (
                "x1,x2,t,y\n1e400,0,0,1\n",
                2,
                Some(Field::X1),
                "x1: \"1e400\" is not a finite number",
            ),
            (
                "x1,x2,t,y\n0,0,0,1,7\n",
                2,
                None,
                "unexpected extra field \"7\"",
            ),
        ];
        for (text, line, field, message) in cases {
            let err = error(text);
            assert_eq!(err.name(), "grid.csv");
            assert_eq!(err.line(), Some(line), "{err}");
            assert_eq!(err.field(), field, "{err}");
            assert!(err.to_string().contains(message), "{err}");
        }
    }

    #[test]
    fn empty_files_and_a_lone_header_are_errors() {
        assert!(matches!(error("").kind(), DataErrorKind::Empty));
        assert!(matches!(error("# nothing\n").kind(), DataErrorKind::Empty));
        let err = error("x1,x2,t,y\n");
        assert_eq!(
            err.to_string(),
            "grid.csv: a header `x1,x2,t,y` without any sample after it"
        );
    }
}
