//! What a job found, for a person: plain-text tables and the units people read
//! (`70.0 days`, `24 h`), shared by every face that shows a report as text. A job of this crate
//! returns a result that serialises as JSON (`--json`, the service, Python) and renders itself
//! as text with these; the faces only choose which and print it.
//!
//! ```
//! use chronomap_app::report::{Table, period};
//!
//! let mut table = Table::new(["model", "period"]);
//! table.row(["fremen:1".to_string(), period(86_400.0)]);
//! assert_eq!(table.render(), "model     period\n----------------\nfremen:1    24 h");
//! ```

/// `2016-03-21 00:00 UTC` for unix times, `day 8 00:00 (+691200 s)` for relative ones
/// ([`chronomap_core::time::format_time`]).
pub fn time(t: f64) -> String {
    chronomap_core::time::format_time(t)
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

/// Most characters a table cell (or another padded name) shows: a longer text (a topic, type
/// or node name read from a file) is cut to its first [`ELIDED_PREFIX_CHARS`] characters, `…`
/// and its length ([`elide`]), so a hostile name neither floods the terminal nor becomes a
/// padding width.
pub const MAX_CELL_CHARS: usize = 200;

/// Characters of an elided text kept before the `…`.
pub const ELIDED_PREFIX_CHARS: usize = 160;

/// `text` itself when it has at most [`MAX_CELL_CHARS`] characters, else its first
/// [`ELIDED_PREFIX_CHARS`] characters, `…` and how many characters it has
/// (`abc…(70000 chars)`), at most [`MAX_CELL_CHARS`] characters either way.
pub fn elide(text: &str) -> std::borrow::Cow<'_, str> {
    let chars = text.chars().count();
    if chars <= MAX_CELL_CHARS {
        return text.into();
    }
    let prefix: String = text.chars().take(ELIDED_PREFIX_CHARS).collect();
    format!("{prefix}…({chars} chars)").into()
}

/// `text` followed by spaces up to `width` characters (nothing added when it is as wide or
/// wider); never a formatting width, which panics from 65,535 on.
pub fn pad_right(text: &str, width: usize) -> String {
    let chars = text.chars().count();
    let mut out = String::with_capacity(text.len() + width.saturating_sub(chars));
    out.push_str(text);
    out.extend(std::iter::repeat_n(' ', width.saturating_sub(chars)));
    out
}

/// Spaces up to `width` characters, then `text` (see [`pad_right`]).
pub fn pad_left(text: &str, width: usize) -> String {
    let chars = text.chars().count();
    let mut out: String = std::iter::repeat_n(' ', width.saturating_sub(chars)).collect();
    out.push_str(text);
    out
}

/// A plain-text table: the first column left-aligned, the others right-aligned (numbers)
/// unless marked with [`Table::left`]. Cells longer than [`MAX_CELL_CHARS`] are shown
/// elided ([`elide`]).
pub struct Table {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
    left: Vec<usize>,
}

impl Table {
    /// A table with these column headers.
    pub fn new(header: impl IntoIterator<Item = impl Into<String>>) -> Self {
        Table {
            header: header
                .into_iter()
                .map(|h| elide(&h.into()).into_owned())
                .collect(),
            rows: Vec::new(),
            left: vec![0],
        }
    }

    /// Left-aligns the columns `columns` too (text rather than numbers).
    pub fn left(mut self, columns: &[usize]) -> Self {
        self.left.extend_from_slice(columns);
        self
    }

    /// Adds a row (a cell per column).
    pub fn row(&mut self, cells: impl IntoIterator<Item = impl Into<String>>) {
        self.rows.push(
            cells
                .into_iter()
                .map(|cell| {
                    let cell: String = cell.into();
                    match elide(&cell) {
                        std::borrow::Cow::Borrowed(_) => cell,
                        std::borrow::Cow::Owned(short) => short,
                    }
                })
                .collect(),
        );
    }

    /// The table as text: header, a rule, one line per row.
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
                    if self.left.contains(&c) {
                        pad_right(s, width[c])
                    } else {
                        pad_left(s, width[c])
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
    fn formats_known_periods_and_durations() {
        assert_eq!(time(1_451_865_600.0), "2016-01-04 00:00 UTC");
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

    #[test]
    fn a_cell_of_70000_characters_is_shown_elided_not_padded_to_its_width() {
        // A format width of 65,535 or more panics; a topic name read from a bag can be longer.
        let topic = format!("/{}", "t".repeat(69_999));
        let mut t = Table::new(["topic", "messages"]);
        t.row([topic.as_str(), "3"]);
        t.row(["/door", "12"]);
        let shown = format!("/{}…(70000 chars)", "t".repeat(159));
        // 160 characters, `…` and `(70000 chars)`.
        assert_eq!(shown.chars().count(), 174);
        let rendered = t.render();
        let lines: Vec<&str> = rendered.lines().collect();
        assert_eq!(lines[0], format!("topic{}  messages", " ".repeat(169)));
        assert_eq!(lines[1], "-".repeat(174 + 2 + 8));
        assert_eq!(lines[2], format!("{shown}  {}3", " ".repeat(7)));
        assert_eq!(
            lines[3],
            format!("/door{}  {}12", " ".repeat(169), " ".repeat(6))
        );
    }

    /// docs/limits.md names the cell cap in its table rows as `tests/cli/limits.rs` checks
    /// the library's limits (that test cannot see the binary's constants).
    #[test]
    fn the_cell_limits_in_docs_limits_are_the_ones_here() {
        let doc = include_str!("../../../docs/limits.md");
        for (name, value) in [
            ("MAX_CELL_CHARS", MAX_CELL_CHARS),
            ("ELIDED_PREFIX_CHARS", ELIDED_PREFIX_CHARS),
        ] {
            let row = doc
                .lines()
                .find(|l| {
                    l.starts_with(&format!("| `{name}`"))
                        && l.contains("`crates/app/src/report.rs`")
                })
                .unwrap_or_else(|| panic!("docs/limits.md has no row for {name}"));
            let cells: Vec<&str> = row.split('|').map(str::trim).collect();
            let digits: String = cells[2]
                .split(' ')
                .next()
                .unwrap()
                .chars()
                .filter(|c| *c != ',')
                .collect();
            assert_eq!(digits, value.to_string(), "docs/limits.md row of {name}");
        }
    }

    #[test]
    fn elision_keeps_texts_up_to_the_cap_and_counts_characters_not_bytes() {
        let at_cap = "é".repeat(MAX_CELL_CHARS);
        assert_eq!(elide(&at_cap), at_cap.as_str());
        let over = "é".repeat(MAX_CELL_CHARS + 1);
        assert_eq!(elide(&over), format!("{}…(201 chars)", "é".repeat(160)));
        assert_eq!(pad_right("ab", 4), "ab  ");
        assert_eq!(pad_left("ab", 4), "  ab");
        assert_eq!(pad_right("abcdef", 4), "abcdef");
        assert_eq!(pad_right("x", 70_000).len(), 70_000);
    }
}
