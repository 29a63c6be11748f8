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
//! Grids extracted from detections (`chronomap activity extract`, [`write_rate_grid`]) may
//! carry what is behind each rate: the header `x1,x2,t,y,count,duration_s` adds the number of
//! detections `c_i` (`>= 0`) and the observed duration `Δ_i` in seconds (`> 0`) of eq. (4.6).
//! [`read_rate_samples`] reads both layouts and returns the rates; [`read_rate_grid`] also
//! returns the two extra columns when the file has them.
//!
//! As in [`crate::text`], blank lines and `#` comments are skipped, line numbers count every
//! line, and plain, `.xz` and `.gz` files are read. Every problem is a [`DataError`]:
//!
//! ```text
//! train.csv:1: expected the header `x1,x2,t,y` or `x1,x2,t,y,count,duration_s`, found "x,y,t,rate"
//! train.csv:17: x2: "nan" is not a finite number
//! train.csv:18: t: missing (expected four fields: x1,x2,t,y)
//! ```

use std::io::Read;
use std::path::Path;

use chronomap_activity::RateSamples;
use chronomap_activity::extract::Extraction;

use crate::text::{
    DataError, DataErrorKind, Field, Fields, for_each_data_line, parse_finite, parse_non_negative,
    parse_rate, quote, read_data_file, required, write_data_file,
};

/// What a data line must look like.
const EXPECTED: &str = "expected four fields: x1,x2,t,y";

/// What a data line of the extended layout must look like.
const EXPECTED_EXTENDED: &str = "expected six fields: x1,x2,t,y,count,duration_s";

/// The header.
const HEADER: [&str; 4] = ["x1", "x2", "t", "y"];

/// The header of the extended layout.
const HEADER_EXTENDED: [&str; 6] = ["x1", "x2", "t", "y", "count", "duration_s"];

/// An activity-rate grid with, if the file has them, the counts and observed durations behind
/// the rates (the extended layout of the [module docs](self)).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RateGrid {
    /// The rates.
    pub samples: RateSamples,
    /// Detections `c_i` per sample (extended layout only).
    pub counts: Option<Vec<f64>>,
    /// Observed durations `Δ_i` in seconds per sample (extended layout only).
    pub durations: Option<Vec<f64>>,
}

impl RateGrid {
    /// Observed durations in hours (the dwell times of
    /// [`FrAam::fit_with_dwell`](chronomap_activity::FrAam::fit_with_dwell)), if the file
    /// has them.
    pub fn dwell_hours(&self) -> Option<Vec<f64>> {
        self.durations
            .as_ref()
            .map(|d| d.iter().map(|s| s / 3600.0).collect())
    }
}

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
    Ok(read_rate_grid(path)?.samples)
}

/// Reads an activity-rate grid (uncompressed text) from `reader`; `name` is used in errors.
///
/// # Errors
/// As [`read_rate_samples`].
pub fn read_rate_samples_from(name: &str, reader: impl Read) -> Result<RateSamples, DataError> {
    Ok(read_rate_grid_from(name, reader)?.samples)
}

/// Reads an activity-rate grid with the counts and durations of the extended layout, if the
/// file has them (plain, `.xz` or `.gz`; see the [module docs](self)).
///
/// # Errors
/// As [`read_rate_samples`]; in the extended layout also a negative or non-finite count or a
/// duration that is not positive.
pub fn read_rate_grid(path: impl AsRef<Path>) -> Result<RateGrid, DataError> {
    read_data_file(path.as_ref(), read_rate_grid_from)
}

/// Reads an activity-rate grid (uncompressed text, either layout) from `reader`; `name` is
/// used in errors.
///
/// # Errors
/// As [`read_rate_grid`].
pub fn read_rate_grid_from(name: &str, reader: impl Read) -> Result<RateGrid, DataError> {
    let mut grid = RateGrid::default();
    // None before the header, then whether the layout is the extended one.
    let mut extended: Option<bool> = None;
    for_each_data_line(name, reader, |_, line| {
        let Some(extended) = extended else {
            let fields: Vec<&[u8]> = Fields::new(line).collect();
            let matches = |header: &[&str]| {
                fields.len() == header.len()
                    && fields.iter().zip(header).all(|(f, h)| *f == h.as_bytes())
            };
            if matches(&HEADER) {
                extended = Some(false);
            } else if matches(&HEADER_EXTENDED) {
                extended = Some(true);
                grid.counts = Some(Vec::new());
                grid.durations = Some(Vec::new());
            } else {
                return Err(DataErrorKind::BadHeader {
                    reason: format!(
                        "expected the header `x1,x2,t,y` or `x1,x2,t,y,count,duration_s`, \
                         found {:?}",
                        quote(line)
                    ),
                });
            }
            return Ok(());
        };
        let expected = if extended {
            EXPECTED_EXTENDED
        } else {
            EXPECTED
        };
        let mut fields = Fields::new(line);
        let mut next = |field| -> Result<f64, DataErrorKind> {
            parse_finite(required(fields.next(), field, expected)?, field)
        };
        let x1 = next(Field::X1)?;
        let x2 = next(Field::X2)?;
        let t = next(Field::BinTime)?;
        let y = parse_rate(required(fields.next(), Field::Rate, expected)?)?;
        let behind = if extended {
            let count_text = required(fields.next(), Field::Count, expected)?;
            let count = parse_non_negative(count_text, Field::Count)?;
            let duration_text = required(fields.next(), Field::ObservedDuration, expected)?;
            let duration = parse_finite(duration_text, Field::ObservedDuration)?;
            if duration <= 0.0 {
                return Err(DataErrorKind::NotPositive {
                    field: Field::ObservedDuration,
                    text: quote(duration_text),
                });
            }
            Some((count, duration))
        } else {
            None
        };
        fields.finish(expected)?;
        grid.samples
            .push([x1, x2], t, y)
            .expect("every value was checked above");
        if let (Some((count, duration)), Some(counts), Some(durations)) =
            (behind, &mut grid.counts, &mut grid.durations)
        {
            counts.push(count);
            durations.push(duration);
        }
        Ok(())
    })?;
    if grid.samples.is_empty() {
        let kind = if extended.is_some() {
            DataErrorKind::BadHeader {
                reason: "a header `x1,x2,t,y` without any sample after it".into(),
            }
        } else {
            DataErrorKind::Empty
        };
        return Err(DataError::new(name, None, kind));
    }
    Ok(grid)
}

/// The extended layout of the [module docs](self) for `extraction`: header
/// `x1,x2,t,y,count,duration_s`, one line per observation in its order, `t` the bin index, `y`
/// the rate in detections per hour of observation, except that `zero_rate` is written where
/// the count is 0 (the bundled ATC grid writes `1e-6` there; `0.0` keeps `y = c/Δ` exact).
///
/// ```
/// use chronomap_activity::extract::{CellObservation, Extraction};
/// use chronomap_io::activity::{format_rate_grid, read_rate_grid_from};
///
/// let cell = |bin, count| CellObservation { centre: [3.75, -1.25], bin, count, duration: 1800.0 };
/// let extraction = Extraction { observations: vec![cell(0, 3), cell(1, 0)] };
/// let text = format_rate_grid(&extraction, 1e-6);
/// assert_eq!(text, "x1,x2,t,y,count,duration_s\n3.75,-1.25,0,6,3,1800\n3.75,-1.25,1,0.000001,0,1800\n");
/// let back = read_rate_grid_from("grid.csv", text.as_bytes())?;
/// assert_eq!(back.samples.y(), [6.0, 1e-6]);
/// assert_eq!(back.dwell_hours(), Some(vec![0.5, 0.5]));
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
pub fn format_rate_grid(extraction: &Extraction, zero_rate: f64) -> String {
    use std::fmt::Write;
    let mut text = String::with_capacity(40 * (extraction.len() + 1));
    text.push_str("x1,x2,t,y,count,duration_s\n");
    for o in &extraction.observations {
        let y = if o.count == 0 {
            zero_rate
        } else {
            o.rate_per_hour()
        };
        writeln!(
            text,
            "{},{},{},{},{},{}",
            o.centre[0], o.centre[1], o.bin, y, o.count, o.duration
        )
        .expect("writing to a String cannot fail");
    }
    text
}

/// Writes [`format_rate_grid`] to `path` atomically (a temporary file renamed over it).
///
/// # Errors
/// A [`DataError`] naming `path` if it cannot be written.
pub fn write_rate_grid(
    path: impl AsRef<Path>,
    extraction: &Extraction,
    zero_rate: f64,
) -> Result<(), DataError> {
    write_data_file(
        path.as_ref(),
        format_rate_grid(extraction, zero_rate).as_bytes(),
    )
}

/// The text of an activity-rate grid: the header `x1,x2,t,y` and one line per sample, numbers
/// written in their shortest form that reads back to the same `f64`.
///
/// ```
/// use chronomap_activity::RateSamples;
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
    write_data_file(path.as_ref(), encode_rate_samples(samples).as_bytes())
}

/// The kind of CoPA-Map model files (`chronomap activity fit -o`).
pub const COPA_MAP_KIND: &str = "copa-map";

/// The kind of Log-AM model files (`chronomap activity fit --model log-additive -o`).
pub const LOG_ADDITIVE_KIND: &str = "log-additive";

/// Writes a fitted CoPA-Map as a model file of kind [`COPA_MAP_KIND`], atomically.
///
/// # Errors
/// As [`crate::write_model_file`].
pub fn write_copa_map(
    path: impl AsRef<Path>,
    model: &chronomap_activity::CopaMap,
) -> Result<(), crate::ModelFileError> {
    crate::write_model_file(path, COPA_MAP_KIND, model)
}

/// Reads a file written by [`write_copa_map`], checking its kind and the model's invariants.
///
/// # Errors
/// As [`crate::read_model_file`], or [`crate::ModelFileErrorKind::Inconsistent`] for a model
/// of another kind or one whose invariants do not hold.
pub fn read_copa_map(
    path: impl AsRef<Path>,
) -> Result<chronomap_activity::CopaMap, crate::ModelFileError> {
    use crate::model_file::{ModelFileError, ModelFileErrorKind};
    let path = path.as_ref();
    let (kind, model): (String, chronomap_activity::CopaMap) = crate::read_model_file(path)?;
    let inconsistent = |reason: String| {
        ModelFileError::new(ModelFileErrorKind::Inconsistent { reason }).in_file(path)
    };
    if kind != COPA_MAP_KIND {
        return Err(inconsistent(format!(
            "a model of kind {kind:?}, not a CoPA-Map ({COPA_MAP_KIND:?})"
        )));
    }
    model.check().map_err(|e| inconsistent(e.to_string()))?;
    Ok(model)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::text::test_support::assert_errors;

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
                "expected the header `x1,x2,t,y` or `x1,x2,t,y,count,duration_s`, found \"x,y,t,rate\"",
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
        assert_errors("grid.csv", read_rate_samples_from, &cases);
    }

    #[test]
    fn reads_the_extended_layout_and_keeps_rates_compatible() {
        let text = "x1,x2,t,y,count,duration_s\n3.75,-1.25,0,7200,2,1\n4.25,-1.25,1,0,0,3600\n";
        let grid = read_rate_grid_from("grid.csv", text.as_bytes()).unwrap();
        assert_eq!(grid.samples.y(), [7200.0, 0.0]);
        assert_eq!(grid.counts, Some(vec![2.0, 0.0]));
        assert_eq!(grid.durations, Some(vec![1.0, 3600.0]));
        assert_eq!(grid.dwell_hours().unwrap()[1], 1.0);
        let samples = read_rate_samples_from("grid.csv", text.as_bytes()).unwrap();
        assert_eq!(samples, grid.samples);
        // The plain layout has no counts; one file cannot mix the layouts.
        let plain = read_rate_grid_from("grid.csv", "x1,x2,t,y\n0,0,0,1\n".as_bytes()).unwrap();
        assert_eq!((plain.counts, plain.durations), (None, None));
        let mixed = read_rate_samples_from("grid.csv", "x1,x2,t,y\n0,0,0,1,2,3\n".as_bytes());
        assert!(
            mixed
                .unwrap_err()
                .to_string()
                .contains("unexpected extra field \"2\"")
        );
        let cases = [
            (
                "0,0,0,1\n",
                Some(Field::Count),
                "count: missing (expected six fields",
            ),
            (
                "0,0,0,1,-1,5\n",
                Some(Field::Count),
                "count: \"-1\" is negative",
            ),
            (
                "0,0,0,1,1,0\n",
                Some(Field::ObservedDuration),
                "duration_s: \"0\" is not positive",
            ),
            (
                "0,0,0,1,1,nan\n",
                Some(Field::ObservedDuration),
                "duration_s: \"nan\" is not a finite",
            ),
            (
                "0,0,0,1,1,1,1\n",
                None,
                "unexpected extra field \"1\" (expected six fields",
            ),
        ];
        for (line, field, message) in cases {
            let text = format!("x1,x2,t,y,count,duration_s\n{line}");
            let err = error(&text);
            assert_eq!(err.line(), Some(2), "{err}");
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
