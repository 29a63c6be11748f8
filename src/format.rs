//! Human-readable formatting of times, durations, periods and tables.

/// Times at or after this are shown as UTC dates (2001-09-09); smaller ones are relative
/// seconds (datasets such as the tom door count from their start).
const UNIX_THRESHOLD: f64 = 1e9;

/// `2016-03-21 00:00 UTC` for unix times, `day 8 00:00 (+691200 s)` for relative ones.
pub fn time(t: f64) -> String {
    let whole = t.floor() as i64;
    let days = whole.div_euclid(86_400);
    let secs = whole.rem_euclid(86_400);
    let (h, m) = (secs / 3600, (secs % 3600) / 60);
    if t >= UNIX_THRESHOLD {
        let (y, mo, d) = civil_from_days(days);
        format!("{y:04}-{mo:02}-{d:02} {h:02}:{m:02} UTC")
    } else {
        format!("day {} {h:02}:{m:02} (+{t} s)", days + 1)
    }
}

/// Gregorian date of a count of days since 1970-01-01 (H. Hinnant's `civil_from_days`).
fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
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

/// Days since 1970-01-01 of a Gregorian date (H. Hinnant's `days_from_civil`).
fn days_from_civil(y: i64, m: u32, d: u32) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y.rem_euclid(400);
    let mp = (i64::from(m) + 9) % 12;
    let doy = (153 * mp + 2) / 5 + i64::from(d) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// Unix time of an ISO 8601 date-time: `2014-07-21T09:30`, `2014-07-21 09:30:15Z`,
/// `2014-07-21T09:30+01:00`, or a date alone (midnight). Without an offset the time is UTC.
pub fn parse_iso8601(text: &str) -> Result<f64, String> {
    let bad = |why: &str| {
        format!("{text:?} is not an ISO 8601 date-time ({why}); e.g. 2014-07-21T09:30Z")
    };
    let number = |s: &str, what: &str| -> Result<i64, String> {
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
    let leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
    let month_days = [
        31,
        if leap { 29 } else { 28 },
        31,
        30,
        31,
        30,
        31,
        31,
        30,
        31,
        30,
        31,
    ];
    if !(1..=12).contains(&mo) {
        return Err(bad("month out of 01..12"));
    }
    if d < 1 || d > month_days[mo as usize - 1] {
        return Err(bad("day out of range for the month"));
    }
    // Split the clock from its offset: Z, +hh:mm, -hh:mm, +hhmm.
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
    Ok((days * 86_400 - offset_secs) as f64 + secs_of_day)
}

/// `70.0 days`, `5.2 h`, `42 s`.
pub fn duration(secs: f64) -> String {
    if secs >= 2.0 * 86_400.0 {
        format!("{:.1} days", secs / 86_400.0)
    } else if secs >= 2.0 * 3600.0 {
        format!("{:.1} h", secs / 3600.0)
    } else if secs >= 120.0 {
        format!("{:.1} min", secs / 60.0)
    } else {
        format!("{secs:.0} s")
    }
}

/// A period in the most natural unit: `1 week`, `3.5 days`, `24 h`, `2.4 h`.
pub fn period(secs: f64) -> String {
    if (secs - 604_800.0).abs() < 1e-6 {
        "1 week".into()
    } else if secs > 86_400.0 * 1.5 {
        format!("{:.2} days", secs / 86_400.0)
    } else {
        let h = secs / 3600.0;
        if (h - h.round()).abs() < 1e-9 {
            format!("{h:.0} h")
        } else {
            format!("{h:.2} h")
        }
    }
}

/// A plain-text table with right-aligned numeric columns.
pub struct Table {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Table {
    pub fn new(header: impl IntoIterator<Item = impl Into<String>>) -> Self {
        Table {
            header: header.into_iter().map(Into::into).collect(),
            rows: Vec::new(),
        }
    }

    pub fn row(&mut self, cells: impl IntoIterator<Item = impl Into<String>>) {
        self.rows.push(cells.into_iter().map(Into::into).collect());
    }

    pub fn render(&self) -> String {
        let columns = self.header.len();
        let width: Vec<usize> = (0..columns)
            .map(|c| {
                self.rows
                    .iter()
                    .filter_map(|r| r.get(c))
                    .chain(std::iter::once(&self.header[c]))
                    .map(|s| s.chars().count())
                    .max()
                    .unwrap_or(0)
            })
            .collect();
        let line = |cells: &[String]| {
            cells
                .iter()
                .enumerate()
                .map(|(c, s)| {
                    if c == 0 {
                        format!("{s:<w$}", w = width[c])
                    } else {
                        format!("{s:>w$}", w = width[c])
                    }
                })
                .collect::<Vec<_>>()
                .join("  ")
                .trim_end()
                .to_string()
        };
        let mut out = line(&self.header);
        out.push('\n');
        out.push_str(&"-".repeat(width.iter().sum::<usize>() + 2 * (columns - 1)));
        for row in &self.rows {
            out.push('\n');
            out.push_str(&line(row));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_known_times() {
        assert_eq!(time(1_451_865_600.0), "2016-01-04 00:00 UTC");
        assert_eq!(
            time(1_458_518_400.0 + 3600.0 * 13.5),
            "2016-03-21 13:30 UTC"
        );
        assert_eq!(time(691_200.0), "day 9 00:00 (+691200 s)");
        assert_eq!(period(86_400.0), "24 h");
        assert_eq!(period(604_800.0), "1 week");
        assert_eq!(period(302_400.0), "3.50 days");
        assert_eq!(duration(70.0 * 86_400.0), "70.0 days");
    }

    #[test]
    fn parses_iso8601_against_known_unix_times() {
        // `date -u -d 2014-07-21T09:30:00Z +%s` = 1405935000.
        assert_eq!(parse_iso8601("2014-07-21T09:30:00Z"), Ok(1_405_935_000.0));
        assert_eq!(parse_iso8601("2014-07-21T09:30"), Ok(1_405_935_000.0));
        assert_eq!(parse_iso8601("2014-07-21 10:30+01:00"), Ok(1_405_935_000.0));
        assert_eq!(parse_iso8601("2014-07-21T08:00-0130"), Ok(1_405_935_000.0));
        assert_eq!(parse_iso8601("2014-07-21"), Ok(1_405_900_800.0));
        assert_eq!(parse_iso8601("2000-02-29T00:00:00.5Z"), Ok(951_782_400.5));
        assert_eq!(parse_iso8601("1970-01-01T00:00Z"), Ok(0.0));
        for t in [1_405_935_000.0, 1_405_900_800.0, 1_458_518_400.0] {
            let shown = time(t);
            let iso = shown.trim_end_matches(" UTC").replacen(' ', "T", 1);
            assert_eq!(parse_iso8601(&iso), Ok(t), "{shown}");
        }
        for bad in [
            "",
            "2014-7-21",
            "2014-02-30",
            "2013-02-29",
            "2014-13-01",
            "2014-07-21T24:00",
            "2014-07-21T09:60",
            "2014-07-21T09",
            "2014-07-21T09:30:61",
            "2014-07-21T09:30+5",
            "yesterday",
            "2014-07-21T09:30:-1",
            "2014-07-21Z",
        ] {
            let e = parse_iso8601(bad).unwrap_err();
            assert!(e.contains("ISO 8601"), "{bad}: {e}");
        }
    }

    #[test]
    fn tables_align() {
        let mut t = Table::new(["model", "mse"]);
        t.row(["fremen:4", "0.0670"]);
        t.row(["mean", "0.0807"]);
        assert_eq!(
            t.render(),
            "model        mse\n----------------\nfremen:4  0.0670\nmean      0.0807"
        );
    }
}
