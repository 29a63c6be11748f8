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
