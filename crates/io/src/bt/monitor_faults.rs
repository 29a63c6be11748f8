//! Fault files for `chronomap monitor sim`: the faults injected into the monitoring
//! simulation of [Stüde 2024] §5.3 ([`chronomap_bt_monitor::sim`]), one a line.
//!
//! ```text
//! # faults.txt
//! 0:15:00 cpu_overload for=90
//! 1800    node_crash camera
//! 1:00:05 topic_slow /scan fails=2
//! ```
//!
//! * `TIME KIND [TARGET] [fails=N] [for=SECONDS]`, separated by white space.
//! * TIME is seconds, `m:ss` or `h:mm:ss` (minutes and seconds below 60; only the last part
//!   may have a fraction).
//! * KIND is one of [`FaultKind::ALL`] by name (`node_crash`, `topic_slow`, `cpu_overload`,
//!   `localization_lost`, `navigation_failure`, `stuck`); `node_crash` needs a node and
//!   `topic_slow` a topic of [`FaultKind::targets`], the others take no target.
//! * `fails=N` makes the first N recoveries on the fault fail; `for=` sets a CPU overload's
//!   length (a time as above, default [`Fault::DEFAULT_LASTS`]).
//! * `#` starts a comment; blank lines are ignored.
//!
//! ```
//! use std::time::Duration;
//! use chronomap_bt_monitor::sim::FaultKind;
//! use chronomap_io::monitor_faults::parse_faults;
//!
//! let faults = parse_faults("faults.txt", "1:00:05 topic_slow /scan fails=2 # comment\n")?;
//! assert_eq!(faults[0].at, Duration::from_secs(3605));
//! assert_eq!((faults[0].kind, faults[0].target.as_str(), faults[0].fails),
//!            (FaultKind::TopicSlow, "/scan", 2));
//! let err = parse_faults("faults.txt", "\n10 node_crash lidar\n").unwrap_err();
//! assert_eq!(err.to_string(), "faults.txt:2: target: node_crash needs one of localization, \
//!     move_base, camera (got \"lidar\")");
//! # Ok::<(), chronomap_io::monitor_faults::FaultFileError>(())
//! ```

use std::io;
use std::path::Path;
use std::time::Duration;

use chronomap_bt_monitor::sim::{Fault, FaultKind};
use thiserror::Error;

use crate::line_error::{LineError, LineErrorKind, content_lines, parse_text_file};

/// What is wrong with a fault file (the part of a [`FaultFileError`] after `file:line:`).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum FaultFileErrorKind {
    /// The file could not be read.
    #[error("cannot read: {0}")]
    Io(io::Error),
    /// A field of a line is missing or wrong.
    #[error("{field}: {message}")]
    Field {
        /// `time`, `kind`, `target`, `fails` or `for`.
        field: &'static str,
        /// What is wrong.
        message: String,
    },
}

/// Why a fault file could not be read: the file, the 1-based line and the problem.
pub type FaultFileError = LineError<FaultFileErrorKind>;

impl LineErrorKind for FaultFileErrorKind {}

impl FaultFileError {
    /// The field at fault (`time`, `kind`, `target`, `fails`, `for`), if any.
    pub fn field(&self) -> Option<&'static str> {
        match self.kind() {
            FaultFileErrorKind::Field { field, .. } => Some(field),
            FaultFileErrorKind::Io(_) => None,
        }
    }
}

/// Reads a fault file.
///
/// # Errors
/// A [`FaultFileError`] naming the file, and the line and field at fault.
pub fn read_fault_file(path: impl AsRef<Path>) -> Result<Vec<Fault>, FaultFileError> {
    parse_text_file(path.as_ref(), FaultFileErrorKind::Io, parse_faults)
}

/// A time of a fault file: seconds, `m:ss` or `h:mm:ss`.
fn parse_time(text: &str) -> Option<Duration> {
    let parts: Vec<&str> = text.split(':').collect();
    if parts.len() > 3 {
        return None;
    }
    let mut total = 0.0f64;
    for (i, p) in parts.iter().enumerate() {
        let v: f64 = p.parse().ok()?;
        if !v.is_finite()
            || v < 0.0
            || (i + 1 < parts.len() && v.fract() != 0.0)
            || (i > 0 && v >= 60.0)
        {
            return None;
        }
        total = total * 60.0 + v;
    }
    Duration::try_from_secs_f64(total).ok()
}

/// Reads the text of a fault file (see the [module docs](self)); `name` is used in messages.
///
/// # Errors
/// A [`FaultFileError`] naming `name`, the line and the field: a bad time, an unknown kind, a
/// missing, unknown or unexpected target, a bad count or length.
pub fn parse_faults(name: &str, text: &str) -> Result<Vec<Fault>, FaultFileError> {
    let mut faults = Vec::new();
    for (line, content) in content_lines(text) {
        let err = |field: &'static str, message: String| {
            FaultFileError::new(
                name,
                Some(line),
                FaultFileErrorKind::Field { field, message },
            )
        };
        let mut words = content.split_whitespace();
        let time = words.next().unwrap_or("");
        let at = parse_time(time).ok_or_else(|| {
            err(
                "time",
                format!("{time:?} is not a time (seconds or h:mm:ss)"),
            )
        })?;
        let kind_word = words
            .next()
            .ok_or_else(|| err("kind", "missing fault kind".into()))?;
        let kind: FaultKind = kind_word.parse().map_err(|m| err("kind", m))?;
        let mut fault = Fault::new(at, kind);
        for word in words {
            if let Some(v) = word.strip_prefix("fails=") {
                fault.fails = v
                    .parse()
                    .map_err(|_| err("fails", format!("{v:?} is not a count")))?;
            } else if let Some(v) = word.strip_prefix("for=") {
                fault.lasts = parse_time(v)
                    .filter(|d| !d.is_zero())
                    .ok_or_else(|| err("for", format!("{v:?} is not a positive duration")))?;
            } else if fault.target.is_empty() && !word.contains('=') {
                fault.target = word.to_owned();
            } else {
                return Err(err("target", format!("unexpected {word:?}")));
            }
        }
        let targets = kind.targets();
        if targets.is_empty() {
            if !fault.target.is_empty() {
                return Err(err(
                    "target",
                    format!("{} takes no target (got {:?})", kind.as_str(), fault.target),
                ));
            }
        } else if !targets.contains(&fault.target.as_str()) {
            return Err(err(
                "target",
                format!(
                    "{} needs one of {} (got {:?})",
                    kind.as_str(),
                    targets.join(", "),
                    fault.target
                ),
            ));
        }
        faults.push(fault);
    }
    Ok(faults)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(x: u64) -> Duration {
        Duration::from_secs(x)
    }

    #[test]
    fn bad_fault_files_name_the_line_and_field() {
        let e = |text: &str| parse_faults("f.txt", text).unwrap_err();
        assert_eq!(e("# c\n\nx node_crash camera").line(), Some(3));
        assert_eq!(e("x node_crash camera").field(), Some("time"));
        assert_eq!(e("1:70:00 stuck").field(), Some("time"));
        assert_eq!(e("10 meltdown").field(), Some("kind"));
        assert_eq!(e("10").field(), Some("kind"));
        assert_eq!(e("10 node_crash").field(), Some("target"));
        assert_eq!(e("10 node_crash lidar").field(), Some("target"));
        assert_eq!(e("10 stuck camera").field(), Some("target"));
        assert_eq!(e("10 stuck fails=x").field(), Some("fails"));
        assert_eq!(e("10 cpu_overload for=0").field(), Some("for"));
        assert_eq!(
            e("10 stuck camera").to_string(),
            "f.txt:1: target: stuck takes no target (got \"camera\")"
        );
        assert_eq!(
            e("1.5:00 stuck").to_string(),
            "f.txt:1: time: \"1.5:00\" is not a time (seconds or h:mm:ss)"
        );
    }

    #[test]
    fn times_counts_and_lengths_are_read() {
        let f = parse_faults("f.txt", "1:00:05 topic_slow /scan fails=2 # comment\n").unwrap();
        assert_eq!(f[0].at, s(3605));
        assert_eq!((f[0].target.as_str(), f[0].fails), ("/scan", 2));
        let f = parse_faults("f.txt", "2:30.5 cpu_overload for=1:30\n\n90 stuck\n").unwrap();
        assert_eq!(f.len(), 2);
        assert_eq!(f[0].at, Duration::from_millis(150_500));
        assert_eq!((f[0].kind, f[0].lasts), (FaultKind::CpuOverload, s(90)));
        assert_eq!((f[1].at, f[1].lasts), (s(90), Fault::DEFAULT_LASTS));
    }
}
