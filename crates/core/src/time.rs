//! Calendar time without a clock: unix seconds to and from Gregorian dates, ISO 8601 parsing
//! and a compact display of times.
//!
//! Pure conversions (no time zone database, no system clock): every time is UTC unless an
//! ISO 8601 text carries an explicit offset. The day arithmetic is H. Hinnant's
//! `days_from_civil` / `civil_from_days` ("chrono-Compatible Low-Level Date Algorithms",
//! 2013), exact for every proleptic Gregorian date representable in an `i64` count of days.
//!
//! ```
//! use chronomap_core::time::{format_time, parse_iso8601};
//!
//! let t = parse_iso8601("2016-03-21T13:00:00Z")?;
//! assert_eq!(t, 1_458_565_200.0);
//! assert_eq!(format_time(t), "2016-03-21 13:00 UTC");
//! assert_eq!(parse_iso8601("2016-03-21 14:00+01:00")?, t);
//! assert!(parse_iso8601("2016-02-30").is_err());
//! # Ok::<(), chronomap_core::time::Iso8601Error>(())
//! ```

use thiserror::Error;

/// Seconds in a day.
pub const DAY_SECS: i64 = 86_400;

/// Times at or after this are shown as UTC dates by [`format_time`] (2001-09-09); smaller ones
/// are relative seconds (datasets such as the tom door count from their start).
pub const UNIX_THRESHOLD: f64 = 1e9;

/// Why a text is not an ISO 8601 date-time. Displays as `"TEXT" is not an ISO 8601 date-time
/// (REASON); e.g. 2014-07-21T09:30Z`.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{text:?} is not an ISO 8601 date-time ({reason}); e.g. 2014-07-21T09:30Z")]
pub struct Iso8601Error {
    /// The text given.
    pub text: String,
    /// What is wrong with it, e.g. `day out of range for the month`.
    pub reason: String,
}

/// Whether `year` is a Gregorian leap year.
pub fn is_leap_year(year: i64) -> bool {
    (year % 4 == 0 && year % 100 != 0) || year % 400 == 0
}

/// Number of days of `month` (1..=12) in `year`; `None` for another month.
pub fn days_in_month(year: i64, month: u32) -> Option<u32> {
    Some(match month {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        2 if is_leap_year(year) => 29,
        2 => 28,
        _ => return None,
    })
}

/// Gregorian date `(year, month, day)` of a count of days since 1970-01-01 (Hinnant's
/// `civil_from_days`; negative counts are days before 1970).
pub fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let y = yoe + era * 400;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    (if m <= 2 { y + 1 } else { y }, m, d)
}

/// A date (days since 1970-01-01) as `YYYY-MM-DD`.
///
/// ```
/// assert_eq!(chronomap_core::time::format_date(16_885), "2016-03-25");
/// ```
pub fn format_date(days: i64) -> String {
    let (year, month, day) = civil_from_days(days);
    format!("{year:04}-{month:02}-{day:02}")
}

/// Days since 1970-01-01 of a date written exactly `YYYY-MM-DD` (a UTC date, as calendars of
/// days off give them); `None` for anything else or a date that does not exist.
///
/// ```
/// use chronomap_core::time::parse_date;
/// assert_eq!(parse_date("2016-03-25"), Some(16_885));
/// assert_eq!(parse_date("2016-02-30"), None);
/// assert_eq!(parse_date("2016-03-25T00:00Z"), None);
/// ```
pub fn parse_date(text: &str) -> Option<i64> {
    (text.len() == "YYYY-MM-DD".len())
        .then(|| parse_iso8601(text).ok())
        .flatten()
        // A date alone is its midnight UTC: a whole number of days.
        .map(|t| (t / DAY_SECS as f64).floor() as i64)
}

/// Days since 1970-01-01 of the Gregorian date `year-month-day` (Hinnant's
/// `days_from_civil`). The date is not checked: see [`days_in_month`].
pub fn days_from_civil(year: i64, month: u32, day: u32) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let yoe = y.rem_euclid(400);
    let mp = (i64::from(month) + 9) % 12;
    let doy = (153 * mp + 2) / 5 + i64::from(day) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// `2016-03-21 13:30 UTC` for unix times (at or after [`UNIX_THRESHOLD`]), `day 9 00:00
/// (+691200 s)` for relative ones (seconds from the start of a dataset, day 1 first). Seconds
/// are truncated to the minute.
pub fn format_time(t: f64) -> String {
    let whole = t.floor() as i64;
    let days = whole.div_euclid(DAY_SECS);
    let secs = whole.rem_euclid(DAY_SECS);
    let (h, m) = (secs / 3600, (secs % 3600) / 60);
    if t >= UNIX_THRESHOLD {
        let (y, mo, d) = civil_from_days(days);
        format!("{y:04}-{mo:02}-{d:02} {h:02}:{m:02} UTC")
    } else {
        format!("day {} {h:02}:{m:02} (+{t} s)", days + 1)
    }
}

/// Unix time of an ISO 8601 (RFC 3339 style) date-time: `2014-07-21T09:30`,
/// `2014-07-21 09:30:15Z`, `2014-07-21T09:30:15.5+01:00`, `2014-07-21T08:00-0130`, or a date
/// alone (midnight). `T`, `t` or a space separates date and time; without an offset (`Z`,
/// `±hh:mm`, `±hhmm`, `±hh`) the time is UTC.
///
/// # Errors
/// An [`Iso8601Error`] saying what is wrong: a date that is not `YYYY-MM-DD` or does not
/// exist (2014-02-30, 2013-02-29), a time that is not `hh:mm[:ss[.fff]]` within 00:00 ..
/// 23:59:59.999, a bad offset, or an offset without a time.
pub fn parse_iso8601(text: &str) -> Result<f64, Iso8601Error> {
    let bad = |why: &str| Iso8601Error {
        text: text.to_string(),
        reason: why.to_string(),
    };
    let number = |s: &str, what: &str| -> Result<i64, Iso8601Error> {
        if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad(&format!("bad {what} {s:?}")));
        }
        s.parse::<i64>()
            .map_err(|_| bad(&format!("bad {what} {s:?}")))
    };
    let (date, rest) = match text.find(['T', 't', ' ']) {
        Some(i) => (&text[..i], &text[i + 1..]),
        None => (text, ""),
    };
    let mut parts = date.split('-');
    let (Some(y), Some(mo), Some(d), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(bad("the date must be YYYY-MM-DD"));
    };
    if y.len() != 4 || mo.len() != 2 || d.len() != 2 {
        return Err(bad("the date must be YYYY-MM-DD"));
    }
    let (y, mo, d) = (number(y, "year")?, number(mo, "month")?, number(d, "day")?);
    if !(1..=12).contains(&mo) {
        return Err(bad("month out of 01..12"));
    }
    let month_days = days_in_month(y, mo as u32).expect("a month of 1..=12");
    if d < 1 || d > i64::from(month_days) {
        return Err(bad("day out of range for the month"));
    }
    // Split the clock from its offset: Z, +hh:mm, -hh:mm, +hhmm, +hh.
    let (clock, offset_secs) = if let Some(c) = rest.strip_suffix(['Z', 'z']) {
        (c, 0)
    } else if let Some(i) = rest.rfind(['+', '-']) {
        let (c, off) = (&rest[..i], &rest[i..]);
        let sign = if off.starts_with('-') { -1 } else { 1 };
        let digits: String = off[1..].chars().filter(|&ch| ch != ':').collect();
        if digits.len() != 4 && digits.len() != 2 {
            return Err(bad("the offset must be ±hh:mm"));
        }
        let h = number(&digits[..2], "offset hour")?;
        let m = if digits.len() == 4 {
            number(&digits[2..], "offset minute")?
        } else {
            0
        };
        if h > 23 || m > 59 {
            return Err(bad("offset out of range"));
        }
        (c, sign * (h * 3600 + m * 60))
    } else {
        (rest, 0)
    };
    let mut secs_of_day = 0.0;
    if !clock.is_empty() {
        let fields: Vec<&str> = clock.split(':').collect();
        if !(2..=3).contains(&fields.len()) {
            return Err(bad("the time must be hh:mm or hh:mm:ss"));
        }
        let h = number(fields[0], "hour")?;
        let m = number(fields[1], "minute")?;
        let s = match fields.get(2) {
            Some(s) if s.len() >= 2 && s.as_bytes()[..2].iter().all(u8::is_ascii_digit) => s
                .parse::<f64>()
                .ok()
                .filter(|s| (0.0..60.0).contains(s))
                .ok_or_else(|| bad("bad seconds"))?,
            Some(_) => return Err(bad("bad seconds")),
            None => 0.0,
        };
        if fields[0].len() != 2 || fields[1].len() != 2 || h > 23 || m > 59 {
            return Err(bad(
                "the time must be hh:mm with hour 00..23 and minute 00..59",
            ));
        }
        secs_of_day = (h * 3600 + m * 60) as f64 + s;
    } else if offset_secs != 0 || rest.len() > clock.len() {
        return Err(bad("an offset needs a time"));
    }
    let days = days_from_civil(y, mo as u32, d as u32);
    Ok((days * DAY_SECS - offset_secs) as f64 + secs_of_day)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn civil_days_of_known_dates() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        // `date -u -d 2016-01-04 +%s` = 1451865600 = 16804 days.
        assert_eq!(days_from_civil(2016, 1, 4), 16_804);
        assert_eq!(civil_from_days(16_804), (2016, 1, 4));
        assert_eq!(days_from_civil(1969, 12, 31), -1);
        assert_eq!(civil_from_days(-1), (1969, 12, 31));
        // 2000-03-01 follows 2000-02-29 (a leap year divisible by 400).
        assert_eq!(
            days_from_civil(2000, 2, 29) + 1,
            days_from_civil(2000, 3, 1)
        );
        assert_eq!(days_from_civil(2000, 3, 1), 11_017);
        // 1900 was not a leap year: 1900-02-28 is followed by 1900-03-01.
        assert_eq!(
            days_from_civil(1900, 2, 28) + 1,
            days_from_civil(1900, 3, 1)
        );
        assert_eq!(days_from_civil(1900, 1, 1), -25_567);
        // A round trip over four centuries of days, both ways across the epoch.
        for days in (-146_097..146_097).step_by(37) {
            let (y, m, d) = civil_from_days(days);
            assert!(d >= 1 && d <= days_in_month(y, m).unwrap(), "{y}-{m}-{d}");
            assert_eq!(days_from_civil(y, m, d), days, "{y}-{m}-{d}");
        }
    }

    #[test]
    fn leap_years_and_month_lengths() {
        assert!(is_leap_year(2016) && is_leap_year(2000) && is_leap_year(2024));
        assert!(!is_leap_year(1900) && !is_leap_year(2013) && !is_leap_year(2100));
        assert_eq!(days_in_month(2016, 2), Some(29));
        assert_eq!(days_in_month(2013, 2), Some(28));
        assert_eq!(days_in_month(2013, 4), Some(30));
        assert_eq!(days_in_month(2013, 12), Some(31));
        assert_eq!(days_in_month(2013, 13), None);
        assert_eq!(days_in_month(2013, 0), None);
    }

    #[test]
    fn formats_known_times() {
        for (t, text) in [
            (1_451_865_600.0, "2016-01-04 00:00 UTC"),
            (1_458_518_400.0 + 3600.0 * 13.5, "2016-03-21 13:30 UTC"),
            (951_782_400.0 - 1.0, "day 11016 23:59 (+951782399 s)"),
            (1_000_000_000.0, "2001-09-09 01:46 UTC"),
        ] {
            assert_eq!(format_time(t), text, "{t}");
        }
        assert_eq!(format_time(691_200.0), "day 9 00:00 (+691200 s)");
        assert_eq!(format_time(59.9), "day 1 00:00 (+59.9 s)");
    }

    #[test]
    fn parses_iso8601_against_known_unix_times() {
        // `date -u -d 2014-07-21T09:30:00Z +%s` = 1405935000.
        assert_eq!(parse_iso8601("2014-07-21T09:30:00Z"), Ok(1_405_935_000.0));
        assert_eq!(parse_iso8601("2014-07-21T09:30"), Ok(1_405_935_000.0));
        assert_eq!(parse_iso8601("2014-07-21t09:30z"), Ok(1_405_935_000.0));
        assert_eq!(parse_iso8601("2014-07-21 10:30+01:00"), Ok(1_405_935_000.0));
        assert_eq!(parse_iso8601("2014-07-21T11:30+02"), Ok(1_405_935_000.0));
        assert_eq!(parse_iso8601("2014-07-21T08:00-0130"), Ok(1_405_935_000.0));
        assert_eq!(parse_iso8601("2014-07-21"), Ok(1_405_900_800.0));
        assert_eq!(parse_iso8601("2000-02-29T00:00:00.5Z"), Ok(951_782_400.5));
        assert_eq!(parse_iso8601("2016-02-29"), Ok(1_456_704_000.0));
        assert_eq!(parse_iso8601("1970-01-01T00:00Z"), Ok(0.0));
        assert_eq!(parse_iso8601("1969-12-31T23:00Z"), Ok(-3600.0));
        for t in [1_405_935_000.0, 1_405_900_800.0, 1_458_518_400.0] {
            let shown = format_time(t);
            let iso = shown.trim_end_matches(" UTC").replacen(' ', "T", 1);
            assert_eq!(parse_iso8601(&iso), Ok(t), "{shown}");
        }
    }

    #[test]
    fn rejects_bad_iso8601_with_the_reason() {
        for (bad, reason) in [
            ("", "YYYY-MM-DD"),
            ("2014-7-21", "YYYY-MM-DD"),
            ("2014-02-30", "day out of range"),
            ("2013-02-29", "day out of range"),
            ("1900-02-29", "day out of range"),
            ("2014-13-01", "month out of 01..12"),
            ("2014-00-01", "month out of 01..12"),
            ("2014-07-21T24:00", "hour 00..23"),
            ("2014-07-21T09:60", "minute 00..59"),
            ("2014-07-21T09", "hh:mm or hh:mm:ss"),
            ("2014-07-21T09:30:61", "bad seconds"),
            ("2014-07-21T09:30+5", "the offset must be"),
            ("2014-07-21T09:30+24:00", "offset out of range"),
            ("yesterday", "YYYY-MM-DD"),
            ("2014-07-21T09:30:-1", "the offset must be"),
            ("2014-07-21T09:30:5x", "bad seconds"),
            ("2014-07-21Z", "YYYY-MM-DD"),
            ("2014-07-21TZ", "an offset needs a time"),
            ("2o14-07-21", "bad year"),
        ] {
            let e = parse_iso8601(bad).unwrap_err();
            assert_eq!(e.text, bad);
            assert!(e.reason.contains(reason), "{bad}: {e}");
            let message = e.to_string();
            assert!(
                message.contains("ISO 8601") && message.contains(bad),
                "{message}"
            );
        }
    }
}
