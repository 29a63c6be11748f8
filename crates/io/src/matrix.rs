//! Matrices of binary states: one line per time slot, one `0`/`1` field per state (e.g. the
//! visibility of 111 image features in every 10-minute slot of a week, `brayford_week`).

use std::io::Read;
use std::path::Path;

use crate::text::{DataError, DataErrorKind, Field, Fields, for_each_data_line, read_data_file};

/// What a line must look like (quoted in errors).
const MATRIX_LINE: &str = "one 0 or 1 per state, the same number on every line";

/// Reads a state matrix (plain, `.xz` or `.gz`): `rows[slot][state]` in `{0, 1}`.
///
/// # Errors
/// A [`DataError`] naming the file, line and field: a field that is not `0` or `1`, a line with
/// fewer or more fields than the first, no data line.
pub fn read_state_matrix(path: impl AsRef<Path>) -> Result<Vec<Vec<f64>>, DataError> {
    read_data_file(path.as_ref(), read_state_matrix_from)
}

/// As [`read_state_matrix`] from a reader of plain text (`name` is used in errors; wrap
/// compressed input in [`decompressing_reader`](crate::text::decompressing_reader)).
///
/// # Errors
/// As [`read_state_matrix`].
pub fn read_state_matrix_from(name: &str, reader: impl Read) -> Result<Vec<Vec<f64>>, DataError> {
    let mut rows: Vec<Vec<f64>> = Vec::new();
    for_each_data_line(name, reader, |_, line| {
        let mut row = Vec::with_capacity(rows.first().map_or(16, Vec::len));
        for field in Fields::new(line) {
            let text = String::from_utf8_lossy(field);
            match field {
                b"0" => row.push(0.0),
                b"1" => row.push(1.0),
                _ => {
                    return Err(DataErrorKind::NotZeroOrOne {
                        field: Field::Value,
                        text: text.into_owned(),
                    });
                }
            }
            if let Some(first) = rows.first()
                && row.len() > first.len()
            {
                return Err(DataErrorKind::ExtraField {
                    text: text.into_owned(),
                    expected: MATRIX_LINE,
                });
            }
        }
        if let Some(first) = rows.first()
            && row.len() < first.len()
        {
            return Err(DataErrorKind::MissingField {
                field: Field::Value,
                expected: MATRIX_LINE,
            });
        }
        rows.push(row);
        Ok(())
    })?;
    Ok(rows)
}
