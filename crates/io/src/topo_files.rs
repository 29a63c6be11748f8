//! Topological-map files: edge-traversal statistics (`<From>_<To>.data` files, as in the Witham
//! Wharf dataset).
//!
//! ```
//! use chronomap_io::topo_files::read_edge_file_from;
//!
//! // One edge file: `t duration_s success` per line.
//! let attempts = read_edge_file_from("LabDoor1_LabDoor2.data",
//!     "1404836670 6.549558 1\n1404841253 7.027835 0\n".as_bytes())?;
//! assert_eq!((attempts.len(), attempts[1].success), (2, false));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Edge files
//! An edge file ([`read_edge_file`]) holds every attempt a robot made to traverse one directed
//! edge: one line `time duration success` per attempt, the fields separated by whitespace (or
//! by one comma, as in the other text formats of this crate; see [`crate::text`]). `time` is
//! in unix seconds, finite, `>= 0` and never going backwards; `duration` is in seconds, finite
//! and `>= 0`; `success` is exactly `0` or `1`. Blank lines and `#` comments are skipped; a
//! file without any attempt is an error. Files ending in `.xz` or `.gz` are decompressed.
//! Every problem is a [`DataError`] naming the file, the line and the field, e.g.
//! `Ramp1_Ramp2.data:7: duration: "-1.5" is negative (durations are seconds >= 0)`.
//!
//! # Directories of edge files
//! [`read_edge_directory`] reads every edge file of a directory into one [`EdgeStatistics`]:
//! a [`TopoMap`] with an edge per file and the attempts of each edge.
//!
//! * **Files.** `<From>_<To>.data`, `.data.xz` or `.data.gz` (extensions `xz`/`gz` in any
//!   case). The edge id is the file stem `<From>_<To>`; two files with one stem (`A_B.data` and
//!   `A_B.data.xz`) are an error. Files named `path*.txt` are ignored: in the Witham dataset
//!   they are lists of edge file names that the authors' programs take as input (see
//!   `data/README.md`), not data. Hidden files (names starting with `.`) are ignored. Any other
//!   file, or a subdirectory, is an error ([`DataErrorKind::UnexpectedFile`]): nothing is
//!   skipped silently.
//! * **Splitting a stem into `From` and `To`.** Node names may contain underscores, so a stem
//!   with several underscores can be ambiguous. The *known* node names are the `nodes` given
//!   to [`read_edge_directory_with_nodes`] and both halves of every stem with exactly one
//!   underscore. A stem is split at the underscore that leaves two known names on its sides;
//!   if none does, at the one that leaves one known name (so listing only the names with
//!   underscores is enough); if none leaves any known name, at the first underscore. If
//!   several underscores tie, the file is an error listing them. A stem without an
//!   underscore, or whose split leaves an empty name (`_A`, `A_`), is an error
//!   ([`DataErrorKind::EdgeFileName`]). In the Witham data no node name contains an
//!   underscore, so every stem has exactly one.
//! * **Order.** Edges are in the order of their ids (byte order). Nodes are the given `nodes`
//!   in the order given, then the other nodes in byte order of their names. Nodes have no
//!   pose. `attempts[i]` belongs to `map.edges()[i]`.
//!

use std::collections::HashSet;
use std::fs;
use std::io::Read;
use std::path::{Path, PathBuf};

use chronomap_core::topo::TopoMap;

use crate::text::{DataError, DataErrorKind, TimeSeries, open_data_file, read_timed_lines};

// ---------------------------------------------------------------------------------------------
// Edge files

/// One attempt to traverse an edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeAttempt {
    /// When the attempt started (unix seconds).
    pub time: f64,
    /// How long it took (seconds, `>= 0`).
    pub duration_secs: f64,
    /// Whether the robot reached the target node.
    pub success: bool,
}

/// A topological map and every recorded attempt to traverse each of its edges.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EdgeStatistics {
    /// The map: the nodes, and one edge per edge file.
    pub map: TopoMap,
    /// `attempts[i]` are the attempts on `map.edges()[i]`, in time order.
    pub attempts: Vec<Vec<EdgeAttempt>>,
}

impl EdgeStatistics {
    /// Number of attempts over all edges.
    pub fn total_attempts(&self) -> usize {
        self.attempts.iter().map(Vec::len).sum()
    }

    /// The attempts on the edge with id `edge_id`, if the map has that edge.
    pub fn attempts_of(&self, edge_id: &str) -> Option<&[EdgeAttempt]> {
        let index = self.map.edges().iter().position(|e| e.id == edge_id)?;
        self.attempts.get(index).map(Vec::as_slice)
    }

    /// Fraction of successful attempts on edge `edge` (an index into `map.edges()`); `None` if
    /// it has no attempt (or no such edge).
    pub fn success_rate(&self, edge: usize) -> Option<f64> {
        let attempts = self.attempts.get(edge).filter(|a| !a.is_empty())?;
        let successes = attempts.iter().filter(|a| a.success).count();
        Some(successes as f64 / attempts.len() as f64)
    }

    /// Earliest and latest attempt time over all edges; `None` without attempts.
    pub fn time_span(&self) -> Option<(f64, f64)> {
        self.attempts
            .iter()
            .flatten()
            .map(|a| a.time)
            .fold(None, |span, t| match span {
                None => Some((t, t)),
                Some((lo, hi)) => Some((f64::min(lo, t), f64::max(hi, t))),
            })
    }

    /// Outcomes of the attempts on edge `edge` as a binary time series (1 = success), ready
    /// for [`TemporalModel::observe`](chronomap_core::TemporalModel::observe). Empty if the
    /// edge has no attempt or does not exist.
    ///
    /// The series satisfies the [observation contract](chronomap_core::observe) when the
    /// attempts do, as those read by [`read_edge_directory`] always do.
    pub fn success_series(&self, edge: usize) -> TimeSeries {
        let attempts = self.attempts.get(edge).map_or(&[][..], Vec::as_slice);
        TimeSeries {
            times: attempts.iter().map(|a| a.time).collect(),
            values: attempts
                .iter()
                .map(|a| f64::from(u8::from(a.success)))
                .collect(),
        }
    }

    /// Splits the attempts chronologically: `before` has those with `time < split`, `after`
    /// those with `time >= split`. Both keep the whole map (every node and edge), so an edge
    /// may have no attempt in one of them. A NaN `split` puts every attempt in `after`.
    ///
    /// ```
    /// use chronomap_io::topo_files::{EdgeAttempt, EdgeStatistics};
    /// use chronomap_core::topo::TopoMap;
    ///
    /// let mut map = TopoMap::new();
    /// map.add_node("A", None)?;
    /// map.add_node("B", None)?;
    /// map.add_edge("A_B", "A", "B")?;
    /// let attempt = |time| EdgeAttempt { time, duration_secs: 5.0, success: true };
    /// let stats = EdgeStatistics { map, attempts: vec![vec![attempt(10.0), attempt(20.0)]] };
    /// let (before, after) = stats.split_at(20.0);
    /// assert_eq!((before.total_attempts(), after.total_attempts()), (1, 1));
    /// assert_eq!(after.attempts[0][0].time, 20.0);
    /// # Ok::<(), chronomap_core::topo::TopoError>(())
    /// ```
    pub fn split_at(&self, split: f64) -> (EdgeStatistics, EdgeStatistics) {
        let (before, after) = self
            .attempts
            .iter()
            .map(|edge| edge.iter().partition(|a| a.time < split))
            .unzip();
        (
            EdgeStatistics {
                map: self.map.clone(),
                attempts: before,
            },
            EdgeStatistics {
                map: self.map.clone(),
                attempts: after,
            },
        )
    }
}

/// What a line of an edge file must look like (quoted in errors).
const EDGE_LINE: &str = "expected three fields: time duration success";

/// Reads an edge file (plain, `.xz` or `.gz`): one `time duration success` line per attempt
/// (see the [module docs](self#edge-files)).
///
/// # Errors
/// A [`DataError`] naming `path`, the line and the field if the file cannot be read, has no
/// attempt, or a line is malformed: a field that is not a number, a time that is negative,
/// not finite or earlier than the previous one, a duration that is negative or not finite, a
/// success that is not `0` or `1`, a missing or extra field.
pub fn read_edge_file(path: impl AsRef<Path>) -> Result<Vec<EdgeAttempt>, DataError> {
    let path = path.as_ref();
    let name = path.display().to_string();
    read_edge_file_from(&name, open_data_file(path)?)
}

/// Reads the lines of an edge file (uncompressed text) from `reader`; `name` is used in
/// errors.
///
/// ```
/// use chronomap_io::topo_files::read_edge_file_from;
/// use chronomap_io::text::Field;
///
/// let err = read_edge_file_from("A_B.data", "10 5.0 1\n20 -1 0\n".as_bytes()).unwrap_err();
/// assert_eq!(err.to_string(), r#"A_B.data:2: duration: "-1" is negative (durations are seconds >= 0)"#);
/// assert_eq!((err.line(), err.field()), (Some(2), Some(Field::Duration)));
/// ```
///
/// # Errors
/// As [`read_edge_file`].
pub fn read_edge_file_from(name: &str, reader: impl Read) -> Result<Vec<EdgeAttempt>, DataError> {
    let (times, rest) = read_timed_lines(name, reader, EDGE_LINE, |fields| {
        Ok((fields.next_duration()?, fields.next_success()?))
    })?;
    Ok(times
        .into_iter()
        .zip(rest)
        .map(|(time, (duration_secs, success))| EdgeAttempt {
            time,
            duration_secs,
            success,
        })
        .collect())
}

/// Reads every edge file of a directory into a map and its attempts (see the
/// [module docs](self#directories-of-edge-files)).
///
/// ```no_run
/// let stats = chronomap_io::read_edge_directory("data/witham_topological_nav/edges")?;
/// assert_eq!((stats.map.edges().len(), stats.map.nodes().len()), (61, 18));
/// # Ok::<(), chronomap_io::DataError>(())
/// ```
///
/// # Errors
/// As [`read_edge_directory_with_nodes`].
pub fn read_edge_directory(dir: impl AsRef<Path>) -> Result<EdgeStatistics, DataError> {
    read_edge_directory_with_nodes(dir, &[])
}

/// As [`read_edge_directory`], with extra nodes: `nodes` come first in the map, in this
/// order, whether or not an edge file names them (places the robot never left or reached),
/// and they help split file names whose node names contain underscores.
///
/// # Errors
/// A [`DataError`] naming the directory if it cannot be listed
/// ([`DataErrorKind::Io`]) or `nodes` has an invalid or repeated name
/// ([`DataErrorKind::Map`]); naming a file if it is not an edge file
/// ([`DataErrorKind::UnexpectedFile`]), its name does not split into two nodes
/// ([`DataErrorKind::EdgeFileName`]), it repeats an edge ([`DataErrorKind::DuplicateEdgeFile`])
/// or names an invalid node ([`DataErrorKind::Map`]); and any error of [`read_edge_file`].
pub fn read_edge_directory_with_nodes(
    dir: impl AsRef<Path>,
    nodes: &[&str],
) -> Result<EdgeStatistics, DataError> {
    let dir = dir.as_ref();
    let dir_name = dir.display().to_string();
    let list_error = |io| {
        DataError::new(
            &dir_name,
            None,
            DataErrorKind::Io {
                action: "list the files of the directory",
                io,
            },
        )
    };
    // (stem, file name, path)
    let mut files: Vec<(String, String, PathBuf)> = Vec::new();
    for entry in fs::read_dir(dir).map_err(list_error)? {
        let path = entry.map_err(list_error)?.path();
        let unexpected = || {
            DataError::new(
                path.display().to_string(),
                None,
                DataErrorKind::UnexpectedFile,
            )
        };
        let file_name = path
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(unexpected)?
            .to_owned();
        if file_name.starts_with('.') || is_path_list(&file_name) {
            continue;
        }
        if path.is_dir() {
            return Err(unexpected());
        }
        let stem = edge_stem(&file_name).ok_or_else(unexpected)?.to_owned();
        files.push((stem, file_name, path));
    }
    files.sort();
    for pair in files.windows(2) {
        if pair[0].0 == pair[1].0 {
            return Err(DataError::new(
                pair[1].2.display().to_string(),
                None,
                DataErrorKind::DuplicateEdgeFile {
                    edge: pair[1].0.clone(),
                    other: pair[0].1.clone(),
                },
            ));
        }
    }

    let mut known: HashSet<&str> = nodes.iter().copied().collect();
    for (stem, _, _) in &files {
        if let Some((from, to)) = stem.split_once('_')
            && !to.contains('_')
        {
            known.insert(from);
            known.insert(to);
        }
    }
    let mut ends = Vec::with_capacity(files.len());
    for (stem, _, path) in &files {
        let split = split_edge_stem(stem, &known).map_err(|reason| {
            DataError::new(
                path.display().to_string(),
                None,
                DataErrorKind::EdgeFileName {
                    stem: stem.clone(),
                    reason,
                },
            )
        })?;
        ends.push(split);
    }

    let mut map = TopoMap::new();
    let map_error = |name: &str, error| DataError::new(name, None, DataErrorKind::Map { error });
    for node in nodes {
        map.add_node(node, None)
            .map_err(|e| map_error(&dir_name, e))?;
    }
    let mut other_nodes: Vec<&str> = ends
        .iter()
        .flat_map(|&(from, to)| [from, to])
        .filter(|name| !nodes.contains(name))
        .collect();
    other_nodes.sort_unstable();
    other_nodes.dedup();
    for node in &other_nodes {
        map.add_node(node, None).map_err(|e| {
            // An invalid name: report the first file that has it.
            let file = files
                .iter()
                .zip(&ends)
                .find(|(_, (from, to))| from == node || to == node)
                .map_or(dir_name.clone(), |((_, _, path), _)| {
                    path.display().to_string()
                });
            map_error(&file, e)
        })?;
    }
    let mut attempts = Vec::with_capacity(files.len());
    for ((stem, _, path), &(from, to)) in files.iter().zip(&ends) {
        map.add_edge(stem, from, to)
            .map_err(|e| map_error(&path.display().to_string(), e))?;
        attempts.push(read_edge_file(path)?);
    }
    Ok(EdgeStatistics { map, attempts })
}

/// Whether a file of an edge directory is one of the ignored `path*.txt` lists.
fn is_path_list(file_name: &str) -> bool {
    file_name.starts_with("path") && file_name.ends_with(".txt")
}

/// The stem of an edge file name (`A_B` for `A_B.data`, `A_B.data.xz`, `A_B.data.gz`).
fn edge_stem(file_name: &str) -> Option<&str> {
    let lower = file_name.to_ascii_lowercase();
    let base_len = if lower.ends_with(".xz") || lower.ends_with(".gz") {
        file_name.len() - 3
    } else {
        file_name.len()
    };
    file_name[..base_len]
        .strip_suffix(".data")
        .filter(|stem| !stem.is_empty())
}

/// Splits an edge id `<From>_<To>` (see the [module docs](self#directories-of-edge-files)).
fn split_edge_stem<'a>(stem: &'a str, known: &HashSet<&str>) -> Result<(&'a str, &'a str), String> {
    let underscores: Vec<usize> = stem.match_indices('_').map(|(i, _)| i).collect();
    let Some(&first) = underscores.first() else {
        return Err("it has no underscore".to_owned());
    };
    let halves = |i: usize| (&stem[..i], &stem[i + 1..]);
    let known_halves = |(from, to): (&str, &str)| {
        usize::from(known.contains(from)) + usize::from(known.contains(to))
    };
    let best = underscores
        .iter()
        .map(|&i| known_halves(halves(i)))
        .max()
        .unwrap_or(0);
    let candidates: Vec<(&str, &str)> = underscores
        .iter()
        .map(|&i| halves(i))
        .filter(|&split| best > 0 && known_halves(split) == best)
        .collect();
    let (from, to) = match candidates.as_slice() {
        [] => halves(first),
        [one] => *one,
        several => {
            return Err(format!(
                "it splits in {} ways that leave {} known node name{} ({})",
                several.len(),
                if best == 2 { "two" } else { "one" },
                if best == 2 { "s" } else { "" },
                several
                    .iter()
                    .map(|(from, to)| format!("{from} -> {to}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    };
    if from.is_empty() || to.is_empty() {
        return Err("a node name is empty".to_owned());
    }
    Ok((from, to))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_edge_stems_by_known_names() {
        let known: HashSet<&str> = ["A", "B", "Lab_Door", "C_D"].into_iter().collect();
        assert_eq!(split_edge_stem("A_B", &known), Ok(("A", "B")));
        assert_eq!(split_edge_stem("Lab_Door_A", &known), Ok(("Lab_Door", "A")));
        // no split leaves two known names: the first underscore
        assert_eq!(split_edge_stem("X_Y_Z", &known), Ok(("X", "Y_Z")));
        assert!(
            split_edge_stem("AB", &known)
                .unwrap_err()
                .contains("no underscore")
        );
        assert!(split_edge_stem("_A", &known).unwrap_err().contains("empty"));
        assert!(split_edge_stem("A_", &known).unwrap_err().contains("empty"));
        let ambiguous: HashSet<&str> = ["A", "B_C", "A_B", "C"].into_iter().collect();
        let err = split_edge_stem("A_B_C", &ambiguous).unwrap_err();
        assert!(
            err.contains("2 ways that leave two known node names (A -> B_C, A_B -> C)"),
            "{err}"
        );
        // one known half is enough when no split leaves two
        let lab: HashSet<&str> = ["Lab_Door"].into_iter().collect();
        assert_eq!(
            split_edge_stem("Lab_Door_Kitchen", &lab),
            Ok(("Lab_Door", "Kitchen"))
        );
        assert_eq!(
            split_edge_stem("Kitchen_Lab_Door", &lab),
            Ok(("Kitchen", "Lab_Door"))
        );
        let a: HashSet<&str> = ["A"].into_iter().collect();
        let err = split_edge_stem("A_B_A", &a).unwrap_err();
        assert!(
            err.contains("2 ways that leave one known node name (A -> B_A, A_B -> A)"),
            "{err}"
        );
    }

    #[test]
    fn recognises_edge_file_names() {
        assert_eq!(edge_stem("A_B.data"), Some("A_B"));
        assert_eq!(edge_stem("A_B.data.xz"), Some("A_B"));
        assert_eq!(edge_stem("A_B.data.GZ"), Some("A_B"));
        assert_eq!(edge_stem("A_B.txt"), None);
        assert_eq!(edge_stem(".data"), None);
        assert!(is_path_list("path0.txt") && is_path_list("path_2.txt"));
        assert!(!is_path_list("paths.data"));
    }
}
