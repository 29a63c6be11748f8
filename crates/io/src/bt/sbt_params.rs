//! Leaf parameters of a stochastic behavior tree ([Stüde 2024] §5.2.2) for `chronomap bt
//! analyse`: a CSV `node,p_s,p_f,mu,nu` read into the [`LeafParams`] of
//! [`chronomap_bt::stochastic::from_bt()`].
//!
//! ```text
//! # door_sbt.csv
//! node,p_s,p_f,mu,nu
//! IsDoorClosed,0.7,,,
//! OpenDoor,0.4,0.6,0.1,0.5
//! ```
//!
//! * The header comes first; `#` lines and blank lines are skipped.
//! * `node` is a leaf's instance name, or its ID for every instance of it.
//! * `p_s` is the probability of success; `p_f`, when given, must be `1 − p_s` (every leaf
//!   of the model ends in success or failure).
//! * `mu` and `nu` are the rates (1/s) of an action's success and failure times; a condition
//!   leaves both empty.
//!
//! ```
//! use chronomap_io::sbt_params::parse_leaf_params;
//!
//! let params = parse_leaf_params("door.csv", "node,p_s,p_f,mu,nu\nOpenDoor,0.4,0.6,0.1,0.5\n")?;
//! assert_eq!(params["OpenDoor"].p_success, 0.4);
//! assert_eq!((params["OpenDoor"].mu, params["OpenDoor"].nu), (Some(0.1), Some(0.5)));
//! let err = parse_leaf_params("door.csv", "node,p_s,p_f,mu,nu\nOpenDoor,0.4,0.5,,\n").unwrap_err();
//! assert_eq!(err.to_string(), "door.csv:2: field p_f: p_s + p_f = 0.9 (every leaf ends in \
//!     success or failure, so p_f = 1 - p_s)");
//! # Ok::<(), chronomap_io::sbt_params::SbtParamsError>(())
//! ```

use std::collections::BTreeMap;
use std::io;
use std::path::Path;

use chronomap_bt_stochastic::LeafParams;
use thiserror::Error;

use crate::line_error::{LineError, LineErrorKind, parse_text_file};

/// The columns, in order.
pub const HEADER: [&str; 5] = ["node", "p_s", "p_f", "mu", "nu"];

/// What is wrong with a parameters file (the part of an [`SbtParamsError`] after
/// `file:line:`).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum SbtParamsErrorKind {
    /// The file could not be read.
    #[error("cannot read {0}")]
    Io(io::Error),
    /// No line at all besides comments.
    #[error("no rows (expected the header node,p_s,p_f,mu,nu)")]
    Empty,
    /// The first line is not the header.
    #[error("header {found:?}: expected node,p_s,p_f,mu,nu")]
    Header {
        /// The line found.
        found: String,
    },
    /// A row with another number of fields.
    #[error("{found} fields, expected 5 (node,p_s,p_f,mu,nu)")]
    FieldCount {
        /// Fields on the row.
        found: usize,
    },
    /// A required field is empty.
    #[error("field {field}: empty")]
    Missing {
        /// `node` or `p_s`.
        field: &'static str,
    },
    /// A field that is not a finite number.
    #[error("field {field}: {text:?} is not a finite number")]
    NotANumber {
        /// The column.
        field: &'static str,
        /// The text.
        text: String,
    },
    /// `p_s + p_f` is not 1.
    #[error(
        "field p_f: p_s + p_f = {sum} (every leaf ends in success or failure, so p_f = 1 - p_s)"
    )]
    NotComplementary {
        /// `p_s + p_f`.
        sum: f64,
    },
    /// Only one of `mu` and `nu`.
    #[error("give both mu and nu (action) or neither (condition)")]
    HalfRates,
    /// A node given on two rows.
    #[error("field node: {node:?} appears twice")]
    Repeated {
        /// The node.
        node: String,
    },
}

/// Why a parameters file could not be read: the file, the 1-based line and the problem.
pub type SbtParamsError = LineError<SbtParamsErrorKind>;

impl LineErrorKind for SbtParamsErrorKind {
    // As before the move: "cannot read FILE: reason".
    fn cannot_read(&self) -> Option<&io::Error> {
        match self {
            SbtParamsErrorKind::Io(io) => Some(io),
            _ => None,
        }
    }
}

/// Reads a parameters file.
///
/// # Errors
/// An [`SbtParamsError`] naming the file, and the line and field at fault.
pub fn read_leaf_params(
    path: impl AsRef<Path>,
) -> Result<BTreeMap<String, LeafParams>, SbtParamsError> {
    parse_text_file(path.as_ref(), SbtParamsErrorKind::Io, parse_leaf_params)
}

/// Reads the text of a parameters file (see the [module docs](self)); `name` is used in
/// messages.
///
/// # Errors
/// An [`SbtParamsError`] naming `name` and the line: no header, a row of another length, an
/// empty node or `p_s`, a field that is not a finite number, `p_s + p_f ≠ 1`, only one of the
/// rates, a node given twice.
pub fn parse_leaf_params(
    name: &str,
    text: &str,
) -> Result<BTreeMap<String, LeafParams>, SbtParamsError> {
    let error = |line: Option<usize>, kind| SbtParamsError::new(name, line, kind);
    let mut rows = text
        .lines()
        .enumerate()
        .map(|(i, line)| (i + 1, line.trim()))
        .filter(|(_, line)| !line.is_empty() && !line.starts_with('#'));
    match rows.next() {
        Some((_, header)) if header.split(',').map(str::trim).eq(HEADER.iter().copied()) => {}
        Some((line, header)) => {
            return Err(error(
                Some(line),
                SbtParamsErrorKind::Header {
                    found: header.to_owned(),
                },
            ));
        }
        None => return Err(error(None, SbtParamsErrorKind::Empty)),
    }
    let mut params = BTreeMap::new();
    for (line, row) in rows {
        let at = |kind| error(Some(line), kind);
        let fields: Vec<&str> = row.split(',').map(str::trim).collect();
        if fields.len() != HEADER.len() {
            return Err(at(SbtParamsErrorKind::FieldCount {
                found: fields.len(),
            }));
        }
        let number = |i: usize| -> Result<Option<f64>, SbtParamsErrorKind> {
            if fields[i].is_empty() {
                return Ok(None);
            }
            match fields[i].parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(Some(v)),
                _ => Err(SbtParamsErrorKind::NotANumber {
                    field: HEADER[i],
                    text: fields[i].to_owned(),
                }),
            }
        };
        if fields[0].is_empty() {
            return Err(at(SbtParamsErrorKind::Missing { field: "node" }));
        }
        let Some(p_success) = number(1).map_err(at)? else {
            return Err(at(SbtParamsErrorKind::Missing { field: "p_s" }));
        };
        if let Some(p_failure) = number(2).map_err(at)?
            && (p_success + p_failure - 1.0).abs() > 1e-9
        {
            return Err(at(SbtParamsErrorKind::NotComplementary {
                sum: p_success + p_failure,
            }));
        }
        let (mu, nu) = (number(3).map_err(at)?, number(4).map_err(at)?);
        if mu.is_some() != nu.is_some() {
            return Err(at(SbtParamsErrorKind::HalfRates));
        }
        if params
            .insert(fields[0].to_owned(), LeafParams { p_success, mu, nu })
            .is_some()
        {
            return Err(at(SbtParamsErrorKind::Repeated {
                node: fields[0].to_owned(),
            }));
        }
    }
    Ok(params)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn error(text: &str) -> String {
        parse_leaf_params("p.csv", text).unwrap_err().to_string()
    }

    #[test]
    fn conditions_and_actions_are_read_with_comments_skipped() {
        let params = parse_leaf_params(
            "p.csv",
            "# leaves of door.xml\nnode,p_s,p_f,mu,nu\n\nIsDoorClosed, 0.7 ,,,\nOpenDoor,0.4,0.6,0.1,0.5\n",
        )
        .unwrap();
        assert_eq!(params.len(), 2);
        let closed = &params["IsDoorClosed"];
        assert_eq!((closed.p_success, closed.mu, closed.nu), (0.7, None, None));
        assert_eq!(params["OpenDoor"].nu, Some(0.5));
    }

    #[test]
    fn every_problem_names_the_line_and_field() {
        assert_eq!(
            error(""),
            "p.csv: no rows (expected the header node,p_s,p_f,mu,nu)"
        );
        assert_eq!(
            error("node,p_s\n"),
            "p.csv:1: header \"node,p_s\": expected node,p_s,p_f,mu,nu"
        );
        let rows = [
            (
                "A,0.5",
                "p.csv:2: 2 fields, expected 5 (node,p_s,p_f,mu,nu)",
            ),
            (",0.5,,,", "p.csv:2: field node: empty"),
            ("A,,,,", "p.csv:2: field p_s: empty"),
            (
                "A,0.5,,fast,1",
                "p.csv:2: field mu: \"fast\" is not a finite number",
            ),
            (
                "A,0.5,,inf,1",
                "p.csv:2: field mu: \"inf\" is not a finite number",
            ),
            (
                "A,0.5,,1,",
                "p.csv:2: give both mu and nu (action) or neither (condition)",
            ),
            (
                "A,0.5,,,\n# again\nA,0.6,,,",
                "p.csv:4: field node: \"A\" appears twice",
            ),
        ];
        for (rows, message) in rows {
            assert_eq!(error(&format!("node,p_s,p_f,mu,nu\n{rows}\n")), message);
        }
    }
}
