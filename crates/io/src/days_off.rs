//! Calendars of days off: one date `YYYY-MM-DD` per line, optionally followed by a name
//! (`2016-03-25 Good Friday`); `#` starts a comment line. Read into
//! [`chronomap_core::calendar::DaysOff`].

use std::collections::BTreeSet;
use std::io::Read;
use std::path::Path;

use chronomap_core::calendar::DaysOff;
use chronomap_core::time::parse_date;

use crate::text::{DataError, DataErrorKind, Fields, for_each_data_line, quote, read_data_file};

/// Reads a calendar of days off from `path` (plain, `.xz` or `.gz`).
///
/// # Errors
/// [`DataError`] naming the file and line of a date that is not `YYYY-MM-DD` or does not exist.
pub fn read_days_off(path: impl AsRef<Path>) -> Result<DaysOff, DataError> {
    read_data_file(path.as_ref(), read_days_off_from)
}

/// Reads a calendar of days off from `reader`; `name` is used in errors.
///
/// ```
/// let days = chronomap_io::read_days_off_from("uk", "# England\n2016-03-25 Good Friday\n".as_bytes())?;
/// assert_eq!(days.days().collect::<Vec<_>>(), [16_885]);
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
pub fn read_days_off_from(name: &str, reader: impl Read) -> Result<DaysOff, DataError> {
    // A set, not a list: a file repeating one date a billion times holds one day (at most
    // 3,652,425 distinct dates YYYY-MM-DD exist).
    let mut days = BTreeSet::new();
    for_each_data_line(name, reader, |_, line| {
        let date = Fields::new(line).next().unwrap_or_default();
        let day = std::str::from_utf8(date)
            .ok()
            .and_then(parse_date)
            .ok_or_else(|| DataErrorKind::BadDate { text: quote(date) })?;
        days.insert(day);
        Ok(())
    })?;
    Ok(DaysOff::new(days))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_that_do_not_exist_are_named_with_their_line() {
        let error =
            read_days_off_from("cal", "2016-03-25\n2016-02-30 nope\n".as_bytes()).unwrap_err();
        assert_eq!(
            error.to_string(),
            "cal:2: date: \"2016-02-30\" is not a date YYYY-MM-DD"
        );
        for bad in [
            "25.03.2016",
            "2016-3-25",
            "2016-03-25x",
            "-016-03-25",
            "2016-13-01",
        ] {
            assert!(read_days_off_from("cal", bad.as_bytes()).is_err(), "{bad}");
        }
        let days = read_days_off_from(
            "cal",
            "\u{feff}2016-12-26\n# c\n\n2016-12-26 again\n".as_bytes(),
        )
        .unwrap();
        assert_eq!(days.len(), 1);
    }

    #[test]
    fn a_long_line_of_garbage_is_quoted_shortened() {
        let garbage = "\u{1}x".repeat(5000);
        let error = read_days_off_from("cal", garbage.as_bytes()).unwrap_err();
        assert!(error.to_string().len() < 200, "{error}");
        assert!(
            error.to_string().contains("…\" is not a date YYYY-MM-DD"),
            "{error}"
        );
    }
}
