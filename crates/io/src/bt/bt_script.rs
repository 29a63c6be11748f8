//! Outcome scripts for `chronomap bt run`: what each leaf of a behavior tree returns, tick by
//! tick, read into a [`Script`].
//!
//! ```text
//! # door.script: outcomes of the leaves of door.xml
//! tick 1: IsDoorOpen=failure, OpenDoor=running
//! tick 2 @ 250: OpenDoor=failure
//! tick 4: OpenDoor=success
//! ```
//!
//! * One line per tick that changes something: `tick N:` then `name=outcome` pairs separated
//!   by commas. `N` starts at 1 and increases; ticks not listed change nothing.
//! * `name` is a leaf's instance name (its `name` attribute, or its ID); `outcome` is
//!   `success`, `failure` or `running` (any case). An outcome holds until a later line
//!   changes it.
//! * `@ MS` (optional, also `@MS` or `@ MSms`) is the tick's time in milliseconds since the
//!   start; without it a tick comes a fixed period after the previous one (tick 1 at 0).
//! * `#` starts a comment; blank lines are ignored.
//!
//! ```
//! use chronomap_bt::Status;
//! use chronomap_io::bt_script::parse_bt_script;
//!
//! let script = parse_bt_script("door.script", "tick 1: OpenDoor=running\ntick 3 @ 500: OpenDoor=success\n")?;
//! assert_eq!(script.ticks[1].tick, 3);
//! assert_eq!(script.ticks[1].at_ms, Some(500));
//! assert_eq!(script.ticks[1].outcomes, [("OpenDoor".to_owned(), Status::Success)]);
//! let err = parse_bt_script("door.script", "tick 1: OpenDoor=open\n").unwrap_err();
//! assert_eq!(err.to_string(), "door.script:1: outcome of \"OpenDoor\": \"open\" is not \
//!     success, failure or running");
//! # Ok::<(), chronomap_io::bt_script::BtScriptError>(())
//! ```

use std::io;
use std::path::Path;

use chronomap_bt::Status;
use chronomap_bt::script::{Script, ScriptTick};
use thiserror::Error;

use crate::line_error::{LineError, LineErrorKind, content_lines, parse_text_file};

/// What is wrong with a script line (the part of a [`BtScriptError`] after `file:line:`).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum BtScriptErrorKind {
    /// The file could not be read.
    #[error("cannot read: {0}")]
    Io(io::Error),
    /// The line is not `tick N[ @ MS]: name=outcome, …`.
    #[error(
        "{reason} (expected `tick N: name=outcome, ...`, e.g. `tick 2 @ 200: OpenDoor=running`)"
    )]
    Syntax {
        /// What is wrong.
        reason: String,
    },
    /// A tick number or time that is not a non-negative integer.
    #[error("{field}: {text:?} is not a whole number")]
    BadNumber {
        /// `tick` or `time`.
        field: &'static str,
        /// The text.
        text: String,
    },
    /// An outcome that is not success, failure or running.
    #[error("outcome of {name:?}: {text:?} is not success, failure or running")]
    BadOutcome {
        /// The leaf name.
        name: String,
        /// The text.
        text: String,
    },
    /// A name given twice on one line.
    #[error("{name:?} is given twice")]
    Repeated {
        /// The leaf name.
        name: String,
    },
    /// Tick numbers must start at 1 and increase.
    #[error("tick {tick} does not come after tick {previous} (line {previous_line})")]
    Order {
        /// The tick.
        tick: u64,
        /// The previous tick.
        previous: u64,
        /// Its line.
        previous_line: usize,
    },
}

/// Why a script could not be read: the file, the 1-based line and the problem.
pub type BtScriptError = LineError<BtScriptErrorKind>;

impl LineErrorKind for BtScriptErrorKind {}

/// Reads a script file.
///
/// # Errors
/// A [`BtScriptError`] naming the file and line.
pub fn read_bt_script(path: impl AsRef<Path>) -> Result<Script, BtScriptError> {
    parse_text_file(path.as_ref(), BtScriptErrorKind::Io, parse_bt_script)
}

/// Reads script text; `name` is used in messages.
///
/// # Errors
/// A [`BtScriptError`] naming `name` and the line: syntax, numbers, outcomes, repeated names,
/// tick order.
pub fn parse_bt_script(name: &str, text: &str) -> Result<Script, BtScriptError> {
    let mut script = Script::default();
    let mut previous = (0u64, 0usize);
    for (line, content) in content_lines(text) {
        let error = |kind| BtScriptError::new(name, Some(line), kind);
        let tick = parse_line(content).map_err(error)?;
        if tick.tick <= previous.0 {
            return Err(error(BtScriptErrorKind::Order {
                tick: tick.tick,
                previous: previous.0,
                previous_line: previous.1,
            }));
        }
        previous = (tick.tick, line);
        script.ticks.push(tick);
    }
    Ok(script)
}

fn syntax(reason: impl Into<String>) -> BtScriptErrorKind {
    BtScriptErrorKind::Syntax {
        reason: reason.into(),
    }
}

fn number(field: &'static str, text: &str) -> Result<u64, BtScriptErrorKind> {
    let text = text.trim();
    if text.is_empty() || !text.bytes().all(|b| b.is_ascii_digit()) {
        return Err(BtScriptErrorKind::BadNumber {
            field,
            text: text.to_owned(),
        });
    }
    text.parse().map_err(|_| BtScriptErrorKind::BadNumber {
        field,
        text: text.to_owned(),
    })
}

fn parse_line(content: &str) -> Result<ScriptTick, BtScriptErrorKind> {
    let rest = content
        .strip_prefix("tick")
        .filter(|r| r.starts_with(char::is_whitespace))
        .ok_or_else(|| syntax(format!("{content:?} does not start with `tick`")))?;
    let (head, body) = rest
        .split_once(':')
        .ok_or_else(|| syntax("no `:` after the tick number"))?;
    let (tick_text, time_text) = match head.split_once('@') {
        Some((t, ms)) => (t, Some(ms.trim().strip_suffix("ms").unwrap_or(ms.trim()))),
        None => (head, None),
    };
    let tick = number("tick", tick_text)?;
    if tick == 0 {
        return Err(BtScriptErrorKind::BadNumber {
            field: "tick",
            text: "0".to_owned(),
        });
    }
    let mut line = ScriptTick::new(tick);
    if let Some(ms) = time_text {
        line.at_ms = Some(number("time", ms)?);
    }
    let body = body.trim();
    if body.is_empty() {
        return Ok(line);
    }
    for item in body.split(',') {
        let (leaf, outcome) = item
            .split_once('=')
            .ok_or_else(|| syntax(format!("{:?} is not name=outcome", item.trim())))?;
        let (leaf, outcome) = (leaf.trim(), outcome.trim());
        if leaf.is_empty() {
            return Err(syntax(format!("{:?} has no name", item.trim())));
        }
        let status = match outcome.to_ascii_lowercase().as_str() {
            "success" => Status::Success,
            "failure" => Status::Failure,
            "running" => Status::Running,
            _ => {
                return Err(BtScriptErrorKind::BadOutcome {
                    name: leaf.to_owned(),
                    text: outcome.to_owned(),
                });
            }
        };
        if line.outcomes.iter().any(|(n, _)| n == leaf) {
            return Err(BtScriptErrorKind::Repeated {
                name: leaf.to_owned(),
            });
        }
        line.outcomes.push((leaf.to_owned(), status));
    }
    Ok(line)
}
