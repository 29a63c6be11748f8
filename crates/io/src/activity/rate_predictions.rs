//! Predicted rates of people with their uncertainty, as `chronomap activity predict` writes
//! them from a fitted CoPA-Map: CSV `x1,x2,t,mean,std` (cell centre in metres, the model's
//! time, the predicted rate and its standard deviation in people per hour), numbers in their
//! shortest form that reads back to the same `f64`.
//!
//! ```
//! use chronomap_io::rate_predictions::{RatePrediction, encode_rate_predictions};
//!
//! let rows = [RatePrediction { x: [3.75, 4.25], t: 123.0, mean: 12.5, std: 0.75 }];
//! assert_eq!(encode_rate_predictions(&rows), "x1,x2,t,mean,std\n3.75,4.25,123,12.5,0.75\n");
//! ```

use std::fmt::Write;
use std::path::Path;

use crate::text::{DataError, write_data_file};

/// The header of the file.
pub const HEADER: &str = "x1,x2,t,mean,std";

/// One predicted cell at one time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RatePrediction {
    /// Cell centre (metres).
    pub x: [f64; 2],
    /// The model's time.
    pub t: f64,
    /// Predicted rate (people per hour).
    pub mean: f64,
    /// Its standard deviation.
    pub std: f64,
}

/// The text of a predictions file: the header and one line per row.
pub fn encode_rate_predictions(rows: &[RatePrediction]) -> String {
    let mut text = format!("{HEADER}\n");
    for r in rows {
        writeln!(text, "{},{},{},{},{}", r.x[0], r.x[1], r.t, r.mean, r.std)
            .expect("writing to a String");
    }
    text
}

/// Writes [`encode_rate_predictions`] to `path` atomically (a temporary file renamed over the
/// target).
///
/// # Errors
/// A [`DataError`] naming `path` if it cannot be written.
pub fn write_rate_predictions(
    path: impl AsRef<Path>,
    rows: &[RatePrediction],
) -> Result<(), DataError> {
    write_data_file(path.as_ref(), encode_rate_predictions(rows).as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_are_written_in_shortest_round_trip_form() {
        let rows = [
            RatePrediction {
                x: [0.25, -1.25],
                t: 129.0,
                mean: 0.1 + 0.2,
                std: 1e-6,
            },
            RatePrediction {
                x: [27.75, 3.75],
                t: 123.5,
                mean: 0.0,
                std: 42.0,
            },
        ];
        assert_eq!(
            encode_rate_predictions(&rows),
            "x1,x2,t,mean,std\n0.25,-1.25,129,0.30000000000000004,0.000001\n27.75,3.75,123.5,0,42\n"
        );
        assert_eq!(encode_rate_predictions(&[]), "x1,x2,t,mean,std\n");
    }

    #[test]
    fn an_unwritable_path_names_itself() {
        let error = write_rate_predictions("no-such-dir/p.csv", &[]).unwrap_err();
        assert!(
            error.to_string().starts_with("no-such-dir/p.csv"),
            "{error}"
        );
    }
}
