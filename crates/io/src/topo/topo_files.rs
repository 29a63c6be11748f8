//! Topological-map files: edge-traversal statistics (`<From>_<To>.data` files, as in the Witham
//! Wharf dataset), STRANDS / LCAS `tmap2` YAML maps, and Nav2 route-server GeoJSON graphs.
//!
//! ```
//! use chronomap_io::topo_files::{
//!     RouteEdgeMetadata, decode_tmap2, encode_route_geojson, encode_tmap2, read_edge_file_from,
//! };
//! use chronomap_topo::map::TopoMap;
//!
//! // One edge file: `t duration_s success` per line.
//! let attempts = read_edge_file_from("LabDoor1_LabDoor2.data",
//!     "1404836670 6.549558 1\n1404841253 7.027835 0\n".as_bytes())?;
//! assert_eq!((attempts.len(), attempts[1].success), (2, false));
//!
//! // A map with poses, written as tmap2 and read back.
//! let mut map = TopoMap::new();
//! map.add_node("LabDoor1", Some([1.0, 2.0, 0.0]))?;
//! map.add_node("LabDoor2", Some([4.0, 2.0, std::f64::consts::FRAC_PI_2]))?;
//! map.add_edge("LabDoor1_LabDoor2", "LabDoor1", "LabDoor2")?;
//! let yaml = encode_tmap2(&map, "witham", "01-01-2026_00-00-00")?;
//! let read = decode_tmap2("witham.tmap2.yaml", yaml.as_bytes())?;
//! assert_eq!(read.map.edges(), map.edges());
//! assert_eq!(read.actions, [Some("NavigateToPose".to_string())]);
//!
//! // The same map as a Nav2 route graph, with success probability and time per edge (and,
//! // if known, an interval of the time).
//! let metadata = RouteEdgeMetadata::new(0.2, 6.5).with_time_interval(Some((4.0, 11.0)), 0.9);
//! let json = encode_route_geojson(&map, &[metadata])?;
//! assert!(json.contains("\"success_probability\": 0.2"));
//! assert!(json.contains("\"abs_time_taken_upper\": 11.0"));
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
//! # STRANDS / LCAS `tmap2` YAML ([`read_tmap2`], [`write_tmap2`])
//! The ROS 2 topological map of LCAS `topological_navigation` (from the project's notes on
//! `topological_navigation/test/conf/network_autogen.tmap2.yaml`, humble-dev @0217c0e):
//!
//! ```yaml
//! meta: {last_updated: 01-01-2026_00-00-00}
//! metric_map: witham
//! name: witham
//! pointset: witham
//! transformation: {child: topo_map, parent: map, rotation: {...}, translation: {...}}
//! nodes:
//! - meta: {map: witham, node: LabDoor1, pointset: witham}
//!   node:
//!     name: LabDoor1
//!     parent_frame: map
//!     pose: {position: {x: 1.0, y: 2.0, z: 0.0}, orientation: {x: 0.0, y: 0.0, z: 0.0, w: 1.0}}
//!     edges:
//!     - {edge_id: LabDoor1_LabDoor2, node: LabDoor2, action: NavigateToPose, ...}
//!     ...
//! ```
//!
//! **Reading** ([`decode_tmap2`]) uses only: `nodes[].node.name` (a string, or an integer
//! taken as its decimal text), `nodes[].node.pose.position.x` and `.y` (numbers; `z` is
//! ignored), `nodes[].node.pose.orientation` (`x`, `y`, `z`, `w`; optional, identity if
//! absent; yaw = `atan2(2(wz + xy), 1 − 2(y² + z²))`), and per edge `edge_id` (the edge's id),
//! `node` (the target; may be a node defined later) and `action` (optional). Edges are
//! directed and belong to the node they are listed under. The top-level `name`, `metric_map`
//! and `pointset` are read if present; everything else is ignored. Anchors and aliases
//! (`&id001` … `*id001`, which PyYAML writes when one Python object appears twice, e.g. a
//! shared `verts` list or `properties` dict) are resolved. The older STRANDS ROS 1 export — a
//! top-level **list** of `{meta, node}` entries with the same `node` structure — is read too
//! (name, metric map and pointset then come from the first node's `pointset` and `map`). A
//! node whose `properties` has `synthetic_pose: true` (as [`encode_tmap2`] writes for nodes it
//! had to place) is read without a pose. Errors ([`TopoFileError`]) name the file, the line
//! and the key path, e.g. `map.yaml:12: nodes[1].node.pose.position.x: "a" is invalid
//! (expected a finite number)`.
//!
//! **Writing** ([`encode_tmap2`]) produces the keys above in PyYAML's order (sorted), with
//! the values of the LCAS example for everything chronomap does not model: per node
//! `parent_frame: map`, `properties: {xy_goal_tolerance: 0.3, yaw_goal_tolerance: 0.1}`,
//! `restrictions_planning: 'True'`, `restrictions_runtime: obstacleFree_1`,
//! `localise_by_topic: ''`, `verts` (a regular octagon of radius 0.75 m around the node);
//! per edge `action: NavigateToPose`, `action_type: geometry_msgs/PoseStamped`, the goal
//! template `{target_pose: {header: {frame_id: $node.parent_frame}, pose: $node.pose}}`,
//! `config: []`, `fail_policy: fail`, `fluid_navigation: true`,
//! `recovery_behaviours_config: ''` and the same restrictions. Orientation is the quaternion
//! `(0, 0, sin(yaw/2), cos(yaw/2))`. Numbers are written so that PyYAML (YAML 1.1) reads them
//! as floats (`1.0`, `1.0e+16`, `2.5e-7`); strings are written plain when that is unambiguous, else
//! double-quoted. Nodes without a pose get the synthetic layout of [`node_poses`] and
//! `synthetic_pose: true` in their `properties`.
//!
//! # Nav2 route-server GeoJSON ([`write_route_geojson`], [`read_route_geojson`])
//! A `FeatureCollection` (with the `crs` member `urn:ogc:def:crs:EPSG::3857` that Nav2's
//! example graphs carry, although coordinates are metres in the map frame) of:
//! * one `Point` feature per node: properties `id` (the node index, `0..n`), `frame`
//!   (`"map"`) and `metadata` `{name, synthetic_position}`; coordinates `[x, y]` from the
//!   node's pose, or from the synthetic layout of [`node_poses`] (then
//!   `synthetic_position: true`);
//! * one `MultiLineString` feature per edge, from the start node's position to the end
//!   node's: properties `id` (`n + edge index`, so ids are unique across nodes and edges, as
//!   the route server requires), `startid`, `endid` and `metadata` `{name,
//!   success_probability, abs_time_taken}` (probability in `[0, 1]`, seconds; Nav2's
//!   `TimeScorer` reads `abs_time_taken`, `success_probability` is chronomap's own), plus,
//!   where an interval of the time is known ([`RouteEdgeMetadata`]), `abs_time_taken_lower`,
//!   `abs_time_taken_upper` (seconds) and `abs_time_taken_coverage` (the probability that
//!   the time taken falls between them, e.g. `0.9`): flat numbers, as `abs_time_taken` is,
//!   so that a route-server plugin can read them by key from the edge's metadata (see *Not
//!   verified*). The bounds are quantiles, so `abs_time_taken` (an expectation) need not lie
//!   between them.
//!
//! **Reading** ([`decode_route_geojson`]) takes any `FeatureCollection` of this kind, such as
//! Nav2's sample graphs whose features carry only ids. It uses only: the top-level `type`
//! (`"FeatureCollection"`) and `features`; per feature `geometry.type` — `Point` is a node,
//! `LineString` or `MultiLineString` an edge, anything else is an error — and `properties`.
//! A node needs an integer `properties.id` (unique among nodes) and `geometry.coordinates`
//! `[x, y]` (finite numbers; a third, `z`, is ignored): its pose is `[x, y, 0.0]`, or none if
//! `properties.metadata.synthetic_position` is `true` (as written for nodes that had no pose).
//! Its name is `properties.metadata.name` if that is a string, else the id in decimal (`"0"`,
//! `"17"`). An edge needs integer `properties.startid` and `properties.endid`, the ids of
//! nodes (in any order in the file: nodes need not come first); its geometry is not read. Its
//! id is `properties.metadata.name` if that is a string, else `<from>_<to>` of the node names,
//! or `<from>_<to>_<properties.id>` if another edge has (or names) that id, as parallel edges
//! do. Nodes and edges are in file order; everything else (`crs`, `frame`, costs, other
//! metadata, operations) is ignored, and writing then reading gives the same nodes, poses and
//! edges. Errors ([`TopoFileError`]) name the file and the JSON path, e.g.
//! `graph.geojson: features[3].properties.startid: no node with id 17`; a file that is not
//! JSON, the line too.
//!
//! # Not verified
//! These formats were written from the project's notes (`ecosystem.md` §2), not checked
//! against the loaders themselves:
//! * tmap2: the exact `transformation` block (`child`, `parent`, `rotation`, `translation`),
//!   the `meta.last_updated` format (`%d-%m-%Y_%H-%M-%S` is assumed), the default `verts`
//!   polygon and tolerances, and whether LCAS tools accept the extra `synthetic_pose`
//!   property. Files written here were read back by this module and by no other tool.
//! * GeoJSON: the node property is `frame` (as in the notes; not `frameid`); that the route
//!   server accepts node id 0, ignores the edge geometry, and keeps the extra metadata
//!   members (`name`, `synthetic_position`, `success_probability`, `abs_time_taken_lower`,
//!   `abs_time_taken_upper`, `abs_time_taken_coverage`) as edge/node metadata.
//!   The reader was tested on files this module writes and on a hand-written graph in the
//!   style of Nav2's sample graphs (ids, `startid`/`endid`, `MultiLineString` edges), not on
//!   Nav2's own files.

use std::collections::{HashMap, HashSet};
use std::f64::consts::PI;
use std::fs;
use std::io::{self, Read};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use chronomap_topo::edges::EdgeStatistics;
use chronomap_topo::map::{TopoError, TopoMap};
use serde_json::{Value, json};
use serde_saphyr::Spanned;
use thiserror::Error;

use crate::text::{
    DataError, DataErrorKind, decompressing_reader, read_data_file, read_timed_lines,
};
use crate::yaml::{self, Prefix, Yaml};

// ---------------------------------------------------------------------------------------------
// Edge files

/// One attempt to traverse an edge: the core's [`Attempt`](chronomap_topo::edges::Attempt),
/// so what the readers return goes straight into
/// [`EdgeModels::fit`](chronomap_topo::edges::EdgeModels::fit).
pub use chronomap_topo::edges::Attempt as EdgeAttempt;

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
    read_data_file(path.as_ref(), read_edge_file_from)
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
        // Only regular files (or links to them): a directory is not an edge file, and a pipe
        // without a writer would wait forever to be read.
        if !path.is_file() {
            return Err(unexpected());
        }
        let stem = edge_stem(&file_name).ok_or_else(unexpected)?.to_owned();
        files.push((stem, file_name, path));
    }
    files.sort();
    statistics_of_files(&dir_name, nodes, &files, |path| read_edge_file(path))
}

/// As [`read_edge_directory_with_nodes`], from edge files in memory: `(file name, contents)`
/// pairs (plain, `.xz` or `.gz` by the name's extension; names of path lists and hidden files
/// are skipped as in a directory). `source` names the collection in errors; a file's errors
/// name `source/file name`. Used for data embedded in a binary.
///
/// # Errors
/// As [`read_edge_directory_with_nodes`].
pub fn read_edge_files(
    source: &str,
    files: &[(&str, &[u8])],
    nodes: &[&str],
) -> Result<EdgeStatistics, DataError> {
    let mut listed: Vec<(String, String, PathBuf)> = Vec::new();
    for &(file_name, _) in files {
        let path = Path::new(source).join(file_name);
        if file_name.starts_with('.') || is_path_list(file_name) {
            continue;
        }
        let stem = edge_stem(file_name).ok_or_else(|| {
            DataError::new(
                path.display().to_string(),
                None,
                DataErrorKind::UnexpectedFile,
            )
        })?;
        listed.push((stem.to_owned(), file_name.to_owned(), path));
    }
    listed.sort();
    statistics_of_files(source, nodes, &listed, |path| {
        let name = path.display().to_string();
        let file_name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let bytes = files
            .iter()
            .find(|(n, _)| *n == file_name)
            .map_or(&[][..], |(_, b)| *b);
        read_edge_file_from(&name, decompressing_reader(&name, bytes))
    })
}

/// The map and attempts of sorted `(stem, file name, path)` edge files, each read by `read`.
fn statistics_of_files(
    dir_name: &str,
    nodes: &[&str],
    files: &[(String, String, PathBuf)],
    read: impl Fn(&Path) -> Result<Vec<EdgeAttempt>, DataError>,
) -> Result<EdgeStatistics, DataError> {
    let dir_name = dir_name.to_owned();
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
    for (stem, _, _) in files {
        if let Some((from, to)) = stem.split_once('_')
            && !to.contains('_')
        {
            known.insert(from);
            known.insert(to);
        }
    }
    let mut ends = Vec::with_capacity(files.len());
    for (stem, _, path) in files {
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
        attempts.push(read(path)?);
    }
    Ok(EdgeStatistics { map, attempts })
}

/// The text of an edge file: one `t duration success` line per attempt, numbers written so that
/// they read back bit for bit.
pub fn encode_edge_file(attempts: &[EdgeAttempt]) -> String {
    let mut text = String::with_capacity(32 * attempts.len());
    for a in attempts {
        text.push_str(&format!(
            "{} {} {}\n",
            a.time,
            a.duration_secs,
            u8::from(a.success)
        ));
    }
    text
}

/// Writes `stats` as a directory of edge files that [`read_edge_directory`] reads back: one
/// `<id>.data` per edge with at least one attempt (an edge file cannot be empty, and the
/// original data have no file for an edge without attempts either). Creates `dir` if needed;
/// returns the number of files written.
///
/// # Errors
/// [`TopoFileErrorKind::InvalidInput`] naming `dir` if it already holds edge files (they would
/// mix with the new ones) or `stats` does not have one attempt list per edge;
/// [`TopoFileErrorKind::Io`] if it cannot be created, listed or written.
pub fn write_edge_directory(
    dir: impl AsRef<Path>,
    stats: &EdgeStatistics,
) -> Result<usize, TopoFileError> {
    let dir = dir.as_ref();
    let name = dir.display().to_string();
    let io_error = |action: &'static str, io: io::Error| {
        TopoFileError::new(Some(&name), None, TopoFileErrorKind::Io { action, io })
    };
    if stats.attempts.len() != stats.map.edges().len() {
        return Err(TopoFileError::invalid_input(format!(
            "{} attempt lists for {} edges",
            stats.attempts.len(),
            stats.map.edges().len()
        ))
        .with_file(&name));
    }
    fs::create_dir_all(dir).map_err(|io| io_error("create the directory", io))?;
    for entry in fs::read_dir(dir).map_err(|io| io_error("list the directory", io))? {
        let entry = entry.map_err(|io| io_error("list the directory", io))?;
        if let Some(file) = entry.file_name().to_str()
            && edge_stem(file).is_some()
        {
            return Err(TopoFileError::invalid_input(format!(
                "it already holds edge files ({file}); choose an empty directory"
            ))
            .with_file(&name));
        }
    }
    let mut written = 0;
    for (edge, attempts) in stats.map.edges().iter().zip(&stats.attempts) {
        if attempts.is_empty() {
            continue;
        }
        write_file(
            &dir.join(format!("{}.data", edge.id)),
            encode_edge_file(attempts).as_bytes(),
        )?;
        written += 1;
    }
    Ok(written)
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

// ---------------------------------------------------------------------------------------------
// Errors of the map files

/// What is wrong with a tmap2 or route GeoJSON file or with a map to write (the part of a
/// [`TopoFileError`] after `file:line:`).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum TopoFileErrorKind {
    /// The file could not be read or written.
    #[error("cannot {action}: {io}")]
    Io {
        /// What was being done (`"read"`, `"create a temporary file for"`, ...).
        action: &'static str,
        /// The underlying error.
        io: io::Error,
    },
    /// The file is not valid YAML, has several documents, or its top level is neither a
    /// tmap2 mapping nor a list of nodes.
    #[error("not a topological map YAML file: {message}")]
    Yaml {
        /// What is wrong.
        message: String,
    },
    /// A required key is missing.
    #[error("missing required key `{key}`")]
    MissingKey {
        /// The key path, e.g. `nodes[2].node.pose`.
        key: String,
    },
    /// A value has the wrong type or is out of range.
    #[error("{key}: {value} is invalid (expected {expected})")]
    InvalidValue {
        /// The key path, e.g. `nodes[2].node.pose.position.x`.
        key: String,
        /// The value (shortened if long).
        value: String,
        /// What the key needs.
        expected: &'static str,
    },
    /// The nodes and edges do not make a map (a repeated node, an edge to an unknown node, ...).
    #[error("{key}: {error}")]
    Map {
        /// The key path of the offending name.
        key: String,
        /// What is wrong.
        error: TopoError,
    },
    /// The file is not JSON, or its top level is not a JSON object.
    #[error("not a Nav2 route GeoJSON file: {message}")]
    Json {
        /// What is wrong (with the column, when the parser knows it).
        message: String,
    },
    /// A value contradicts another part of the file: a node id used twice, an edge from or
    /// to a node id that no node has.
    #[error("{key}: {reason}")]
    Inconsistent {
        /// The JSON path of the value, e.g. `features[3].properties.startid`.
        key: String,
        /// What is wrong.
        reason: String,
    },
    /// The map or the data given to a writer cannot be written.
    #[error("cannot write the map: {reason}")]
    InvalidInput {
        /// What is wrong.
        reason: String,
    },
}

/// Why a topological map file could not be read or written: the file (when there is one), the
/// 1-based line (for YAML values and JSON syntax errors) and the problem.
///
/// Displays as `file:line: problem`, e.g.
/// `map.tmap2.yaml:14: nodes[0].node.edges[0].node: unknown node "Kitchn" (did you mean
/// "Kitchen"?)`, or `file: problem`, or the problem alone.
#[derive(Debug, Error)]
#[error("{}{kind}", Prefix(.file.as_deref(), *.line))]
pub struct TopoFileError {
    file: Option<String>,
    line: Option<u64>,
    kind: TopoFileErrorKind,
}

impl TopoFileError {
    fn new(file: Option<&str>, line: Option<u64>, kind: TopoFileErrorKind) -> Self {
        TopoFileError {
            file: file.map(str::to_owned),
            line: line.filter(|&l| l > 0),
            kind,
        }
    }

    fn invalid_input(reason: String) -> Self {
        TopoFileError::new(None, None, TopoFileErrorKind::InvalidInput { reason })
    }

    fn with_file(mut self, file: &str) -> Self {
        self.file = Some(file.to_owned());
        self
    }

    /// The file concerned, if any.
    pub fn file(&self) -> Option<&str> {
        self.file.as_deref()
    }

    /// The 1-based line of the YAML value concerned, if known.
    pub fn line(&self) -> Option<u64> {
        self.line
    }

    /// The key path concerned (e.g. `nodes[2].node.name`, `features[3].properties.startid`),
    /// if any.
    pub fn key(&self) -> Option<&str> {
        match &self.kind {
            TopoFileErrorKind::MissingKey { key }
            | TopoFileErrorKind::InvalidValue { key, .. }
            | TopoFileErrorKind::Map { key, .. }
            | TopoFileErrorKind::Inconsistent { key, .. } => Some(key),
            _ => None,
        }
    }

    /// What is wrong.
    pub fn kind(&self) -> &TopoFileErrorKind {
        &self.kind
    }
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), TopoFileError> {
    crate::atomic::write_atomically(path, bytes).map_err(|failure| {
        TopoFileError::new(
            Some(&path.display().to_string()),
            None,
            TopoFileErrorKind::Io {
                action: failure.action,
                io: failure.io,
            },
        )
    })
}

// ---------------------------------------------------------------------------------------------
// Node positions

/// Where a node is drawn or written: its pose, or a synthetic one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodePose {
    /// `[x, y, yaw]` (metres, metres, radians).
    pub pose: [f64; 3],
    /// Whether the pose was made up by [`node_poses`] (the node has none).
    pub synthetic: bool,
}

/// A pose for every node of `map`: its own where it has one, else a deterministic synthetic
/// one. Nodes without a pose are placed, in index order, counter-clockwise from angle 0 on a
/// circle around the centroid of the nodes with a pose (the origin if there is none), of
/// radius `max(1, k/π)` metres (about 2 m between neighbours, for `k` such nodes) plus the
/// largest distance of a posed node from that centroid; their yaw is 0.
pub fn node_poses(map: &TopoMap) -> Vec<NodePose> {
    let posed: Vec<[f64; 3]> = map.nodes().iter().filter_map(|n| n.pose).collect();
    let unposed = map.nodes().len() - posed.len();
    let (cx, cy) = if posed.is_empty() {
        (0.0, 0.0)
    } else {
        let n = posed.len() as f64;
        (
            posed.iter().map(|p| p[0]).sum::<f64>() / n,
            posed.iter().map(|p| p[1]).sum::<f64>() / n,
        )
    };
    let spread = posed
        .iter()
        .map(|p| (p[0] - cx).hypot(p[1] - cy))
        .fold(0.0, f64::max);
    let radius = spread + (unposed as f64 / PI).max(1.0);
    let mut k = 0usize;
    map.nodes()
        .iter()
        .map(|node| match node.pose {
            Some(pose) => NodePose {
                pose,
                synthetic: false,
            },
            None => {
                let angle = 2.0 * PI * k as f64 / unposed as f64;
                k += 1;
                NodePose {
                    pose: [cx + radius * angle.cos(), cy + radius * angle.sin(), 0.0],
                    synthetic: true,
                }
            }
        })
        .collect()
}

/// Poses of all nodes for a writer, checked finite.
fn checked_poses(map: &TopoMap) -> Result<Vec<NodePose>, TopoFileError> {
    let poses = node_poses(map);
    for (node, pose) in map.nodes().iter().zip(&poses) {
        if pose.pose.iter().any(|v| !v.is_finite()) {
            return Err(TopoFileError::invalid_input(format!(
                "node {:?} has the pose {:?}, which is not finite",
                node.name, pose.pose
            )));
        }
    }
    Ok(poses)
}

// ---------------------------------------------------------------------------------------------
// tmap2: reading

/// A topological map read from a tmap2 (or STRANDS ROS 1) YAML file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Tmap2 {
    /// The map's `name` (empty if absent).
    pub name: String,
    /// The `metric_map` it belongs to (empty if absent).
    pub metric_map: String,
    /// The `pointset` (empty if absent).
    pub pointset: String,
    /// Nodes (with poses, unless marked synthetic) and edges, in file order.
    pub map: TopoMap,
    /// `actions[i]` is the `action` of `map.edges()[i]`, if it has one (e.g.
    /// `NavigateToPose`, `move_base`, `row_traversal`).
    pub actions: Vec<Option<String>>,
}

/// Reads the map of a tmap2 file (plain, `.xz` or `.gz`; see the
/// [module docs](self#strands--lcas-tmap2-yaml-read_tmap2-write_tmap2)).
///
/// # Errors
/// [`TopoFileErrorKind::Io`] if it is not a regular file or cannot be read, else as
/// [`decode_tmap2`]; errors name `path`.
pub fn read_tmap2(path: impl AsRef<Path>) -> Result<TopoMap, TopoFileError> {
    let (name, bytes) = read_map_file(path.as_ref())?;
    Ok(decode_tmap2(&name, &bytes)?.map)
}

/// The bytes of a map file (decompressed), and its name for errors: at most
/// [`MAX_FILE_BYTES`](crate::MAX_FILE_BYTES), and only from a regular file (a directory, a
/// device such as `/dev/zero` or a pipe is refused before reading).
fn read_map_file(path: &Path) -> Result<(String, Vec<u8>), TopoFileError> {
    let name = path.display().to_string();
    let read_error = |io| {
        TopoFileError::new(
            Some(&name),
            None,
            TopoFileErrorKind::Io { action: "read", io },
        )
    };
    let file = crate::bounded::open_regular(path).map_err(read_error)?;
    let bytes = crate::bounded::read_to_end_bounded(decompressing_reader(&name, file))
        .map_err(read_error)?;
    Ok((name, bytes))
}

/// Parses a tmap2 map (or a STRANDS ROS 1 list of nodes) from YAML text; `name` is used in
/// errors.
///
/// ```
/// use chronomap_io::topo_files::decode_tmap2;
///
/// // As PyYAML writes a dict shared by two nodes: an anchor, then an alias.
/// let yaml = "name: tiny\nnodes:\n\
///   - node:\n    name: A\n    pose: &id001\n      position: {x: 1.0, y: 2.0, z: 0.0}\n\
///   \x20     orientation: {x: 0.0, y: 0.0, z: 0.0, w: 1.0}\n\
///   \x20   edges:\n    - {edge_id: A_B, node: B, action: NavigateToPose}\n\
///   - node:\n    name: B\n    pose: *id001\n";
/// let map = decode_tmap2("tiny.yaml", yaml.as_bytes())?.map;
/// assert_eq!(map.nodes()[1].pose, Some([1.0, 2.0, 0.0]));
/// assert_eq!((map.edges()[0].from, map.edges()[0].to), (0, 1));
/// # Ok::<(), chronomap_io::topo_files::TopoFileError>(())
/// ```
///
/// # Errors
/// [`TopoFileErrorKind::Yaml`] (with the line when the parser knows it),
/// [`MissingKey`](TopoFileErrorKind::MissingKey),
/// [`InvalidValue`](TopoFileErrorKind::InvalidValue) or [`Map`](TopoFileErrorKind::Map)
/// (repeated node or edge, edge to an unknown node), with the line of the value and its key
/// path.
pub fn decode_tmap2(name: &str, text: &[u8]) -> Result<Tmap2, TopoFileError> {
    // Only `true`/`false` are booleans: with YAML 1.1's `y`/`n`, the key `y` of a position
    // would be read as `true` (PyYAML does not treat `y`/`n` as booleans either).
    let root = yaml::parse(text, true).map_err(|e| {
        TopoFileError::new(
            Some(name),
            e.line,
            TopoFileErrorKind::Yaml { message: e.message },
        )
    })?;
    let root = Cursor {
        file: name,
        path: String::new(),
        node: &root,
    };
    let not_a_map = |what: &str| {
        TopoFileError::new(
            Some(name),
            Some(root.line()),
            TopoFileErrorKind::Yaml {
                message: format!(
                    "the top level is {what}, not a tmap2 mapping with `nodes` or a list of \
                     STRANDS nodes"
                ),
            },
        )
    };
    let (entries, mut result) = match &root.node.value {
        Yaml::Map(_) => {
            let text_of = |key: &str| -> Result<String, TopoFileError> {
                match root.get(key)? {
                    Some(c) if !matches!(c.node.value, Yaml::Null) => c.as_name(),
                    _ => Ok(String::new()),
                }
            };
            let result = Tmap2 {
                name: text_of("name")?,
                metric_map: text_of("metric_map")?,
                pointset: text_of("pointset")?,
                ..Tmap2::default()
            };
            (root.require("nodes")?.items()?, result)
        }
        Yaml::Seq(_) => (root.items()?, Tmap2::default()),
        Yaml::Null => return Err(not_a_map("empty")),
        _ => return Err(not_a_map("a single value")),
    };
    let legacy = matches!(root.node.value, Yaml::Seq(_));

    let mut nodes = Vec::with_capacity(entries.len());
    for entry in &entries {
        nodes.push(parse_node(entry)?);
    }
    if legacy && let Some(first) = entries.first() {
        let node = first.require("node")?;
        let optional = |key: &str| -> Result<String, TopoFileError> {
            match node.get(key)? {
                Some(c) if !matches!(c.node.value, Yaml::Null) => c.as_name(),
                _ => Ok(String::new()),
            }
        };
        result.pointset = optional("pointset")?;
        result.metric_map = optional("map")?;
        result.name = result.pointset.clone();
    }

    let mut map = TopoMap::new();
    for node in &nodes {
        map.add_node(&node.name.0, node.pose)
            .map_err(|error| node.name.1.map_error(error))?;
    }
    for node in &nodes {
        for edge in &node.edges {
            map.add_edge(&edge.id.0, &node.name.0, &edge.target.0)
                .map_err(|error| match error {
                    TopoError::UnknownNode { .. } => edge.target.1.map_error(error),
                    error => edge.id.1.map_error(error),
                })?;
            result.actions.push(edge.action.clone());
        }
    }
    result.map = map;
    Ok(result)
}

/// A value read from the file and where it was (for errors).
type Located<T> = (T, Place);

/// Where a value was: file, line and key path.
#[derive(Clone, Debug)]
struct Place {
    file: String,
    line: u64,
    path: String,
}

impl Place {
    fn map_error(&self, error: TopoError) -> TopoFileError {
        TopoFileError::new(
            Some(&self.file),
            Some(self.line),
            TopoFileErrorKind::Map {
                key: self.path.clone(),
                error,
            },
        )
    }
}

struct ParsedNode {
    name: Located<String>,
    pose: Option<[f64; 3]>,
    edges: Vec<ParsedEdge>,
}

struct ParsedEdge {
    id: Located<String>,
    target: Located<String>,
    action: Option<String>,
}

fn parse_node(entry: &Cursor<'_>) -> Result<ParsedNode, TopoFileError> {
    let node = entry.require("node")?;
    let name = node.require("name")?;
    let name = (name.as_name()?, name.place());
    let pose = node.require("pose")?;
    let position = pose.require("position")?;
    let (x, y) = (
        position.require("x")?.as_number()?,
        position.require("y")?.as_number()?,
    );
    let yaw = match pose.get("orientation")? {
        None => 0.0,
        Some(q) if matches!(q.node.value, Yaml::Null) => 0.0,
        Some(q) => {
            let [qx, qy, qz, qw] = [
                q.require("x")?.as_number()?,
                q.require("y")?.as_number()?,
                q.require("z")?.as_number()?,
                q.require("w")?.as_number()?,
            ];
            (2.0 * (qw * qz + qx * qy)).atan2(1.0 - 2.0 * (qy * qy + qz * qz))
        }
    };
    let synthetic = match node.get("properties")? {
        Some(p) if matches!(p.node.value, Yaml::Map(_)) => p
            .get("synthetic_pose")?
            .is_some_and(|s| matches!(s.node.value, Yaml::Bool(true))),
        _ => false,
    };
    let mut edges = Vec::new();
    if let Some(list) = node.get("edges")? {
        for edge in list.items()? {
            let id = edge.require("edge_id")?;
            let target = edge.require("node")?;
            let action = match edge.get("action")? {
                Some(a) if !matches!(a.node.value, Yaml::Null) => Some(a.as_name()?),
                _ => None,
            };
            edges.push(ParsedEdge {
                id: (id.as_name()?, id.place()),
                target: (target.as_name()?, target.place()),
                action,
            });
        }
    }
    Ok(ParsedNode {
        name,
        pose: (!synthetic).then_some([x, y, yaw]),
        edges,
    })
}

/// A YAML value being read, with its file and key path for errors.
struct Cursor<'a> {
    file: &'a str,
    path: String,
    node: &'a Spanned<Yaml>,
}

impl<'a> Cursor<'a> {
    fn line(&self) -> u64 {
        self.node.referenced.line()
    }

    fn place(&self) -> Place {
        Place {
            file: self.file.to_owned(),
            line: self.line(),
            path: self.path.clone(),
        }
    }

    fn invalid(&self, expected: &'static str) -> TopoFileError {
        let mut value = self.node.value.to_string();
        if value.chars().count() > 40 {
            value = value.chars().take(40).collect::<String>() + "…";
        }
        TopoFileError::new(
            Some(self.file),
            Some(self.line()),
            TopoFileErrorKind::InvalidValue {
                key: if self.path.is_empty() {
                    "(top level)".to_owned()
                } else {
                    self.path.clone()
                },
                value,
                expected,
            },
        )
    }

    fn child(&self, key: String, node: &'a Spanned<Yaml>) -> Cursor<'a> {
        Cursor {
            file: self.file,
            path: key,
            node,
        }
    }

    /// The value of `key`, if this is a mapping that has it.
    fn get(&self, key: &str) -> Result<Option<Cursor<'a>>, TopoFileError> {
        match &self.node.value {
            Yaml::Map(entries) => Ok(entries.iter().find(|(k, _)| k == key).map(|(_, v)| {
                let path = if self.path.is_empty() {
                    key.to_owned()
                } else {
                    format!("{}.{key}", self.path)
                };
                self.child(path, v)
            })),
            _ => Err(self.invalid("a mapping")),
        }
    }

    /// The value of `key`, which must be present and not null.
    fn require(&self, key: &str) -> Result<Cursor<'a>, TopoFileError> {
        match self.get(key)? {
            Some(c) if !matches!(c.node.value, Yaml::Null) => Ok(c),
            _ => Err(TopoFileError::new(
                Some(self.file),
                Some(self.line()),
                TopoFileErrorKind::MissingKey {
                    key: if self.path.is_empty() {
                        key.to_owned()
                    } else {
                        format!("{}.{key}", self.path)
                    },
                },
            )),
        }
    }

    /// The items of a sequence (none for null).
    fn items(&self) -> Result<Vec<Cursor<'a>>, TopoFileError> {
        match &self.node.value {
            Yaml::Seq(items) => Ok(items
                .iter()
                .enumerate()
                .map(|(i, item)| self.child(format!("{}[{i}]", self.path), item))
                .collect()),
            Yaml::Null => Ok(Vec::new()),
            _ => Err(self.invalid("a list")),
        }
    }

    /// A name: a string, or an integer as its decimal text.
    fn as_name(&self) -> Result<String, TopoFileError> {
        match &self.node.value {
            Yaml::Str(s) => Ok(s.clone()),
            Yaml::Int(i) => Ok(i.to_string()),
            _ => Err(self.invalid("a name")),
        }
    }

    /// A finite number.
    fn as_number(&self) -> Result<f64, TopoFileError> {
        let number = match self.node.value {
            Yaml::Int(i) => i as f64,
            Yaml::Float(x) => x,
            _ => f64::NAN,
        };
        if number.is_finite() {
            Ok(number)
        } else {
            Err(self.invalid("a finite number"))
        }
    }
}

// ---------------------------------------------------------------------------------------------
// tmap2: writing

/// Writes `map` as a tmap2 YAML file named `name` (atomically), stamped with the current UTC
/// time (see the [module docs](self#strands--lcas-tmap2-yaml-read_tmap2-write_tmap2)).
///
/// # Errors
/// As [`encode_tmap2`], or [`TopoFileErrorKind::Io`] naming `path`.
pub fn write_tmap2(path: impl AsRef<Path>, map: &TopoMap, name: &str) -> Result<(), TopoFileError> {
    let path = path.as_ref();
    let file = path.display().to_string();
    let now = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let text =
        encode_tmap2(map, name, &format_last_updated(now)).map_err(|e| e.with_file(&file))?;
    write_file(path, text.as_bytes())
}

/// The text of a tmap2 file for `map`, with map, metric map and pointset name `name` and
/// `meta.last_updated` set to `last_updated` (LCAS writes the local time as
/// `%d-%m-%Y_%H-%M-%S`, e.g. `24-07-2026_13-05-00`; unverified).
///
/// # Errors
/// [`TopoFileErrorKind::InvalidInput`] if a pose is not finite.
pub fn encode_tmap2(
    map: &TopoMap,
    name: &str,
    last_updated: &str,
) -> Result<String, TopoFileError> {
    let poses = checked_poses(map)?;
    let name = yaml_scalar(name);
    let mut out = String::with_capacity(2048 + 1500 * map.nodes().len());
    out.push_str(&format!(
        "meta:\n  last_updated: {}\nmetric_map: {name}\nname: {name}\nnodes:\n",
        yaml_scalar(last_updated)
    ));
    for (index, (node, pose)) in map.nodes().iter().zip(&poses).enumerate() {
        let node_name = yaml_scalar(&node.name);
        let [x, y, yaw] = pose.pose;
        out.push_str(&format!(
            "- meta:\n    map: {name}\n    node: {node_name}\n    pointset: {name}\n  node:\n"
        ));
        let edges: Vec<_> = map.out_edges(index).collect();
        if edges.is_empty() {
            out.push_str("    edges: []\n");
        } else {
            out.push_str("    edges:\n");
        }
        for edge in edges {
            let edge = &map.edges()[edge];
            out.push_str(&format!(
                "    - action: NavigateToPose\n      action_type: geometry_msgs/PoseStamped\n      \
                 config: []\n      edge_id: {}\n      fail_policy: fail\n      \
                 fluid_navigation: true\n      goal:\n        target_pose:\n          \
                 header:\n            frame_id: $node.parent_frame\n          \
                 pose: $node.pose\n      node: {}\n      recovery_behaviours_config: ''\n      \
                 restrictions_planning: 'True'\n      restrictions_runtime: obstacleFree_1\n",
                yaml_scalar(&edge.id),
                yaml_scalar(&map.nodes()[edge.to].name),
            ));
        }
        out.push_str(&format!(
            "    localise_by_topic: ''\n    name: {node_name}\n    parent_frame: map\n    \
             pose:\n      orientation:\n        w: {}\n        x: 0.0\n        y: 0.0\n        \
             z: {}\n      position:\n        x: {}\n        y: {}\n        z: 0.0\n    \
             properties:\n",
            yaml_float((yaw / 2.0).cos()),
            yaml_float((yaw / 2.0).sin()),
            yaml_float(x),
            yaml_float(y),
        ));
        if pose.synthetic {
            out.push_str("      synthetic_pose: true\n");
        }
        out.push_str(
            "      xy_goal_tolerance: 0.3\n      yaw_goal_tolerance: 0.1\n    \
             restrictions_planning: 'True'\n    restrictions_runtime: obstacleFree_1\n    \
             verts:\n",
        );
        for k in 0..8 {
            let angle = PI / 8.0 + PI / 4.0 * f64::from(k);
            out.push_str(&format!(
                "    - x: {}\n      y: {}\n",
                yaml_float(round_to(0.75 * angle.cos(), 6)),
                yaml_float(round_to(0.75 * angle.sin(), 6)),
            ));
        }
    }
    out.push_str(&format!(
        "pointset: {name}\ntransformation:\n  child: topo_map\n  parent: map\n  rotation:\n    \
         w: 1.0\n    x: 0.0\n    y: 0.0\n    z: 0.0\n  translation:\n    x: 0.0\n    y: 0.0\n    \
         z: 0.0\n"
    ));
    Ok(out)
}

fn round_to(value: f64, decimals: i32) -> f64 {
    let scale = 10f64.powi(decimals);
    (value * scale).round() / scale
}

/// A finite `f64` as YAML 1.1 (PyYAML) and 1.2 both read as that float: the shortest
/// round-trip digits, always with a `.`, an exponent with a sign (`1.0e+16`, `2.5e-07`).
fn yaml_float(value: f64) -> String {
    let value = value + 0.0; // no "-0.0"
    let text = format!("{value:?}");
    match text.split_once('e') {
        None => text,
        Some((mantissa, exponent)) => {
            let mantissa = if mantissa.contains('.') {
                mantissa.to_owned()
            } else {
                format!("{mantissa}.0")
            };
            let exponent = if exponent.starts_with('-') {
                exponent.to_owned()
            } else {
                format!("+{exponent}")
            };
            format!("{mantissa}e{exponent}")
        }
    }
}

/// A string as a YAML scalar: plain if that is unambiguous in YAML 1.1 and 1.2 (a letter or
/// `_` first, then letters, digits and `_ - . /`, and not a boolean or null word), else
/// double-quoted.
fn yaml_scalar(text: &str) -> String {
    let mut chars = text.chars();
    let plain = chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || "_-./".contains(c))
        && !matches!(
            text.to_ascii_lowercase().as_str(),
            "y" | "n" | "yes" | "no" | "true" | "false" | "on" | "off" | "null"
        );
    if plain {
        return text.to_owned();
    }
    yaml::double_quoted(text)
}

/// `%d-%m-%Y_%H-%M-%S` of a unix time (UTC).
fn format_last_updated(unix_secs: u64) -> String {
    let days = (unix_secs / 86_400) as i64;
    let secs = unix_secs % 86_400;
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{day:02}-{month:02}-{year:04}_{:02}-{:02}-{:02}",
        secs / 3600,
        secs / 60 % 60,
        secs % 60
    )
}

// ---------------------------------------------------------------------------------------------
// Nav2 route graph

/// What a Nav2 route graph says of one edge besides its name: the members of the edge's
/// `metadata` that [`encode_route_geojson`] writes. A plain carrier; its values are checked
/// when written.
///
/// ```
/// use chronomap_io::topo_files::{RouteEdgeMetadata, RouteTimeInterval};
///
/// let plain = RouteEdgeMetadata::new(0.93, 11.5);
/// assert_eq!(plain.time_taken_interval, None);
/// // With the 90 % interval of the duration, e.g. `EdgeModels::duration_interval`'s.
/// let spread = plain.with_time_interval(Some((7.0, 19.0)), 0.9);
/// assert_eq!(
///     spread.time_taken_interval,
///     Some(RouteTimeInterval { lower_secs: 7.0, upper_secs: 19.0, coverage: 0.9 })
/// );
/// assert_eq!(plain.with_time_interval(None, 0.9), plain);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RouteEdgeMetadata {
    /// Probability that a traversal succeeds, in `[0, 1]` (`success_probability`).
    pub success_probability: f64,
    /// Time a traversal takes, in seconds, finite and `>= 0` (`abs_time_taken`, which Nav2's
    /// `TimeScorer` reads).
    pub time_taken_secs: f64,
    /// The interval that holds the time taken with a given probability
    /// (`abs_time_taken_lower`, `abs_time_taken_upper`, `abs_time_taken_coverage`); `None`
    /// writes none of these keys.
    pub time_taken_interval: Option<RouteTimeInterval>,
}

/// An interval of an edge's traversal time in a Nav2 route graph ([`RouteEdgeMetadata`]).
/// Written only if `0 <= lower_secs <= upper_secs`, both finite, and `coverage` in `(0, 1]`;
/// the time taken need not lie inside it (it is an expectation, the bounds are quantiles).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RouteTimeInterval {
    /// Lower bound, seconds (`abs_time_taken_lower`).
    pub lower_secs: f64,
    /// Upper bound, seconds (`abs_time_taken_upper`).
    pub upper_secs: f64,
    /// Probability that the time taken is in the interval (`abs_time_taken_coverage`).
    pub coverage: f64,
}

impl RouteEdgeMetadata {
    /// Success probability and time taken (seconds), without an interval.
    pub fn new(success_probability: f64, time_taken_secs: f64) -> Self {
        RouteEdgeMetadata {
            success_probability,
            time_taken_secs,
            time_taken_interval: None,
        }
    }

    /// The same with the interval `(lower, upper)` (seconds) of probability `coverage`, or
    /// without one if `interval` is `None`.
    #[must_use]
    pub fn with_time_interval(self, interval: Option<(f64, f64)>, coverage: f64) -> Self {
        RouteEdgeMetadata {
            time_taken_interval: interval.map(|(lower_secs, upper_secs)| RouteTimeInterval {
                lower_secs,
                upper_secs,
                coverage,
            }),
            ..self
        }
    }

    /// The `metadata` object of edge `id`, or why these values cannot be written.
    fn to_json(self, id: &str) -> Result<Value, TopoFileError> {
        let bad = |what: String| TopoFileError::invalid_input(format!("edge {id:?}: {what}"));
        let RouteEdgeMetadata {
            success_probability: probability,
            time_taken_secs: time,
            time_taken_interval: interval,
        } = self;
        if !(0.0..=1.0).contains(&probability) {
            return Err(bad(format!(
                "success probability {probability} is not in [0, 1]"
            )));
        }
        if !(time.is_finite() && time >= 0.0) {
            return Err(bad(format!(
                "time taken {time} is not a finite number of seconds >= 0"
            )));
        }
        let mut metadata = json!({
            "name": id,
            "success_probability": probability,
            "abs_time_taken": time,
        });
        if let Some(RouteTimeInterval {
            lower_secs: lower,
            upper_secs: upper,
            coverage,
        }) = interval
        {
            if !(lower.is_finite() && upper.is_finite() && 0.0 <= lower && lower <= upper) {
                return Err(bad(format!(
                    "time interval [{lower}, {upper}] is not finite seconds with \
                     0 <= lower <= upper"
                )));
            }
            if !(coverage > 0.0 && coverage <= 1.0) {
                return Err(bad(format!(
                    "time interval coverage {coverage} is not in (0, 1]"
                )));
            }
            metadata["abs_time_taken_lower"] = json!(lower);
            metadata["abs_time_taken_upper"] = json!(upper);
            metadata["abs_time_taken_coverage"] = json!(coverage);
        }
        Ok(metadata)
    }
}

/// Writes `map` as a Nav2 route-server GeoJSON graph (atomically; see the
/// [module docs](self#nav2-route-server-geojson-write_route_geojson-read_route_geojson)).
/// `edge_metadata[i]` is the metadata of `map.edges()[i]`.
///
/// # Errors
/// As [`encode_route_geojson`], or [`TopoFileErrorKind::Io`] naming `path`.
pub fn write_route_geojson(
    path: impl AsRef<Path>,
    map: &TopoMap,
    edge_metadata: &[RouteEdgeMetadata],
) -> Result<(), TopoFileError> {
    let path = path.as_ref();
    let text = encode_route_geojson(map, edge_metadata)
        .map_err(|e| e.with_file(&path.display().to_string()))?;
    write_file(path, text.as_bytes())
}

/// The text of a Nav2 route-server GeoJSON graph for `map` (pretty-printed JSON ending in a
/// newline); `edge_metadata[i]` is the metadata of `map.edges()[i]`.
///
/// # Errors
/// [`TopoFileErrorKind::InvalidInput`] if `edge_metadata` does not have one entry per edge, a
/// pose is not finite, or an edge's metadata is not writable (naming the edge): a
/// probability not in `[0, 1]`, a time taken that is negative or not finite, an interval
/// whose bounds are not finite with `0 <= lower <= upper`, or whose coverage is not in
/// `(0, 1]`.
pub fn encode_route_geojson(
    map: &TopoMap,
    edge_metadata: &[RouteEdgeMetadata],
) -> Result<String, TopoFileError> {
    if edge_metadata.len() != map.edges().len() {
        return Err(TopoFileError::invalid_input(format!(
            "{} edge metadata entries for {} edges",
            edge_metadata.len(),
            map.edges().len()
        )));
    }
    let poses = checked_poses(map)?;
    let mut features = Vec::with_capacity(map.nodes().len() + map.edges().len());
    for (index, (node, pose)) in map.nodes().iter().zip(&poses).enumerate() {
        features.push(json!({
            "type": "Feature",
            "properties": {
                "id": index,
                "frame": "map",
                "metadata": {"name": node.name, "synthetic_position": pose.synthetic},
            },
            "geometry": {"type": "Point", "coordinates": [pose.pose[0], pose.pose[1]]},
        }));
    }
    let node_count = map.nodes().len();
    let xy = |node: usize| [poses[node].pose[0], poses[node].pose[1]];
    for (index, (edge, metadata)) in map.edges().iter().zip(edge_metadata).enumerate() {
        let metadata = metadata.to_json(&edge.id)?;
        let (start, end) = (xy(edge.from), xy(edge.to));
        features.push(json!({
            "type": "Feature",
            "properties": {
                "id": node_count + index,
                "startid": edge.from,
                "endid": edge.to,
                "metadata": metadata,
            },
            "geometry": {"type": "MultiLineString", "coordinates": [[start, end]]},
        }));
    }
    let collection: Value = json!({
        "type": "FeatureCollection",
        "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::3857"}},
        "features": features,
    });
    let mut text = serde_json::to_string_pretty(&collection)
        .map_err(|e| TopoFileError::invalid_input(format!("cannot encode as JSON: {e}")))?;
    text.push('\n');
    Ok(text)
}

/// Reads a Nav2 route-server GeoJSON graph (plain, `.xz` or `.gz`; see the
/// [module docs](self#nav2-route-server-geojson-write_route_geojson-read_route_geojson)).
/// At most [`MAX_FILE_BYTES`](crate::MAX_FILE_BYTES) are read (after decompression), and
/// only a regular file (or a link to one): a directory, a device such as `/dev/zero` or a
/// pipe is refused before reading.
///
/// # Errors
/// [`TopoFileErrorKind::Io`] if it is not a regular file or cannot be read, else as
/// [`decode_route_geojson`]; errors name `path`.
pub fn read_route_geojson(path: impl AsRef<Path>) -> Result<TopoMap, TopoFileError> {
    let (name, bytes) = read_map_file(path.as_ref())?;
    decode_route_geojson(&name, &bytes)
}

/// Parses a Nav2 route-server GeoJSON graph from JSON text; `name` is used in errors (see the
/// [module docs](self#nav2-route-server-geojson-write_route_geojson-read_route_geojson)).
///
/// ```
/// use chronomap_io::topo_files::decode_route_geojson;
///
/// // As in Nav2's sample graphs: nodes and edges with ids only.
/// let json = r#"{"type": "FeatureCollection", "features": [
///   {"type": "Feature", "properties": {"id": 0}, "geometry": {"type": "Point", "coordinates": [0.0, 1.5]}},
///   {"type": "Feature", "properties": {"id": 1}, "geometry": {"type": "Point", "coordinates": [4.0, 1.5]}},
///   {"type": "Feature", "properties": {"id": 2, "startid": 0, "endid": 1},
///    "geometry": {"type": "MultiLineString", "coordinates": [[[0.0, 1.5], [4.0, 1.5]]]}}
/// ]}"#;
/// let map = decode_route_geojson("graph.geojson", json.as_bytes())?;
/// assert_eq!((map.nodes()[1].name.as_str(), map.nodes()[1].pose), ("1", Some([4.0, 1.5, 0.0])));
/// assert_eq!((map.edges()[0].id.as_str(), map.edges()[0].to), ("0_1", 1));
///
/// let err = decode_route_geojson("graph.geojson", json.replace("\"endid\": 1", "\"endid\": 17").as_bytes())
///     .unwrap_err();
/// assert_eq!(err.to_string(), "graph.geojson: features[2].properties.endid: no node with id 17");
/// # Ok::<(), chronomap_io::topo_files::TopoFileError>(())
/// ```
///
/// # Errors
/// [`TopoFileErrorKind::Json`] if the text is not JSON (with the line) or its top level is
/// not an object; [`MissingKey`](TopoFileErrorKind::MissingKey) (`features`, a feature's
/// `geometry`, `properties`, a node's `id` or `coordinates`, an edge's `startid` or `endid`);
/// [`InvalidValue`](TopoFileErrorKind::InvalidValue) (a `type` other than
/// `FeatureCollection`, an unknown geometry type, an id that is not an integer, a coordinate
/// that is not a finite number); [`Inconsistent`](TopoFileErrorKind::Inconsistent) (a node id
/// used twice, an edge to a node id that no node has); [`Map`](TopoFileErrorKind::Map) (an
/// invalid or repeated node name or edge id). Each names `name` and the JSON path.
pub fn decode_route_geojson(name: &str, text: &[u8]) -> Result<TopoMap, TopoFileError> {
    let root: Value =
        serde_json::from_slice(text).map_err(|error| json_syntax_error(name, text, &error))?;
    let root = JsonCursor {
        file: name,
        path: String::new(),
        value: &root,
    };
    if !root.value.is_object() {
        return Err(TopoFileError::new(
            Some(name),
            None,
            TopoFileErrorKind::Json {
                message: format!(
                    "the top level is {}, not a GeoJSON FeatureCollection object",
                    json_kind(root.value)
                ),
            },
        ));
    }
    let kind = root.require("type")?;
    if kind.value.as_str() != Some("FeatureCollection") {
        return Err(kind.invalid("\"FeatureCollection\""));
    }
    let (mut nodes, mut edges) = (Vec::new(), Vec::new());
    for feature in root.require("features")?.items()? {
        let geometry = feature.require("geometry")?;
        let geometry_type = geometry.require("type")?;
        match geometry_type.value.as_str() {
            Some("Point") => nodes.push((feature, geometry)),
            Some("LineString" | "MultiLineString") => edges.push(feature),
            _ => {
                return Err(geometry_type.invalid(r#""Point", "LineString" or "MultiLineString""#));
            }
        }
    }

    let mut map = TopoMap::new();
    // Node id → (node index, path of the feature that has it).
    let mut ids: HashMap<i128, (usize, String)> = HashMap::with_capacity(nodes.len());
    for (feature, geometry) in &nodes {
        let properties = feature.require("properties")?;
        let id_field = properties.require("id")?;
        let id = id_field.as_integer()?;
        if let Some((_, other)) = ids.get(&id) {
            return Err(
                id_field.inconsistent(format!("node id {id} is used twice (also by {other})"))
            );
        }
        let metadata = properties.optional_object("metadata")?;
        let named = match &metadata {
            Some(m) => m.get("name")?.filter(|n| n.value.is_string()),
            None => None,
        };
        let synthetic = match &metadata {
            Some(m) => m
                .get("synthetic_position")?
                .is_some_and(|s| s.value == &Value::Bool(true)),
            None => false,
        };
        let coordinates = geometry.require("coordinates")?;
        let position = coordinates.items()?;
        if position.len() < 2 {
            return Err(coordinates.invalid("a position [x, y]"));
        }
        let (x, y) = (position[0].as_number()?, position[1].as_number()?);
        let pose = (!synthetic).then_some([x, y, 0.0]);
        let added = match &named {
            Some(n) => map
                .add_node(n.value.as_str().unwrap_or_default(), pose)
                .map_err(|e| n.map_error(e)),
            None => map
                .add_node(&id.to_string(), pose)
                .map_err(|e| id_field.map_error(e)),
        }?;
        ids.insert(id, (added, feature.path.clone()));
    }

    // Edge ids given in the file, which generated ids must not take.
    let mut given: HashSet<&str> = HashSet::new();
    for feature in &edges {
        if let Some(properties) = feature.value.get("properties")
            && let Some(Value::String(id)) = properties.get("metadata").and_then(|m| m.get("name"))
        {
            given.insert(id);
        }
    }
    let mut taken: HashSet<String> = HashSet::with_capacity(edges.len());
    for feature in &edges {
        let properties = feature.require("properties")?;
        let end = |key: &str| -> Result<usize, TopoFileError> {
            let field = properties.require(key)?;
            let id = field.as_integer()?;
            ids.get(&id)
                .map(|&(index, _)| index)
                .ok_or_else(|| field.inconsistent(format!("no node with id {id}")))
        };
        let (from, to) = (end("startid")?, end("endid")?);
        let edge_number = match properties.get("id")? {
            Some(field) if !field.value.is_null() => Some(field.as_integer()?),
            _ => None,
        };
        let metadata = properties.optional_object("metadata")?;
        let named = match &metadata {
            Some(m) => m.get("name")?.filter(|n| n.value.is_string()),
            None => None,
        };
        let (from_name, to_name) = (&map.nodes()[from].name, &map.nodes()[to].name);
        let (id, place) = match &named {
            Some(n) => (n.value.as_str().unwrap_or_default().to_owned(), n),
            None => {
                let plain = format!("{from_name}_{to_name}");
                let id = match edge_number {
                    Some(number) if taken.contains(&plain) || given.contains(plain.as_str()) => {
                        format!("{plain}_{number}")
                    }
                    _ => plain,
                };
                (id, &properties)
            }
        };
        let (from_name, to_name) = (from_name.clone(), to_name.clone());
        map.add_edge(&id, &from_name, &to_name)
            .map_err(|e| place.map_error(e))?;
        taken.insert(id);
    }
    Ok(map)
}

/// A JSON syntax error in file terms: the parser's message, the line, and a hint for the
/// non-finite numbers that JSON cannot hold (which Python's `json` writes as `NaN`).
fn json_syntax_error(name: &str, text: &[u8], error: &serde_json::Error) -> TopoFileError {
    let (line, column) = (error.line(), error.column());
    let full = error.to_string();
    let mut message = full
        .strip_suffix(&format!(" at line {line} column {column}"))
        .unwrap_or(&full)
        .to_owned();
    if line > 0 {
        if column > 0 {
            message.push_str(&format!(" (column {column})"));
        }
        let at = text
            .split(|&b| b == b'\n')
            .nth(line - 1)
            .and_then(|l| l.get(column.saturating_sub(1)..))
            .unwrap_or_default();
        let not_finite = [&b"NaN"[..], b"Infinity", b"-Infinity"]
            .iter()
            .any(|token| at.starts_with(token));
        if not_finite || message.starts_with("number out of range") {
            message.push_str(": numbers must be finite (JSON has no NaN or Infinity)");
        }
    }
    TopoFileError::new(
        Some(name),
        u64::try_from(line).ok(),
        TopoFileErrorKind::Json { message },
    )
}

/// "an array", "a string", … for errors.
fn json_kind(value: &Value) -> &'static str {
    match value {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

/// A JSON value being read, with its file and path (`features[3].properties.startid`) for
/// errors.
struct JsonCursor<'a> {
    file: &'a str,
    path: String,
    value: &'a Value,
}

impl<'a> JsonCursor<'a> {
    fn key(&self) -> String {
        if self.path.is_empty() {
            "(top level)".to_owned()
        } else {
            self.path.clone()
        }
    }

    fn invalid(&self, expected: &'static str) -> TopoFileError {
        let mut value = self.value.to_string();
        if value.chars().count() > 40 {
            value = value.chars().take(40).collect::<String>() + "…";
        }
        TopoFileError::new(
            Some(self.file),
            None,
            TopoFileErrorKind::InvalidValue {
                key: self.key(),
                value,
                expected,
            },
        )
    }

    fn inconsistent(&self, reason: String) -> TopoFileError {
        TopoFileError::new(
            Some(self.file),
            None,
            TopoFileErrorKind::Inconsistent {
                key: self.key(),
                reason,
            },
        )
    }

    fn map_error(&self, error: TopoError) -> TopoFileError {
        TopoFileError::new(
            Some(self.file),
            None,
            TopoFileErrorKind::Map {
                key: self.key(),
                error,
            },
        )
    }

    fn child_path(&self, key: &str) -> String {
        if self.path.is_empty() {
            key.to_owned()
        } else {
            format!("{}.{key}", self.path)
        }
    }

    /// The value of `key`, if this is an object that has it.
    fn get(&self, key: &str) -> Result<Option<JsonCursor<'a>>, TopoFileError> {
        match self.value {
            Value::Object(members) => Ok(members.get(key).map(|value| JsonCursor {
                file: self.file,
                path: self.child_path(key),
                value,
            })),
            _ => Err(self.invalid("an object")),
        }
    }

    /// The value of `key`, which must be present and not null.
    fn require(&self, key: &str) -> Result<JsonCursor<'a>, TopoFileError> {
        match self.get(key)? {
            Some(c) if !c.value.is_null() => Ok(c),
            _ => Err(TopoFileError::new(
                Some(self.file),
                None,
                TopoFileErrorKind::MissingKey {
                    key: self.child_path(key),
                },
            )),
        }
    }

    /// The object at `key`, if present and not null.
    fn optional_object(&self, key: &str) -> Result<Option<JsonCursor<'a>>, TopoFileError> {
        match self.get(key)? {
            Some(c) if c.value.is_null() => Ok(None),
            Some(c) if !c.value.is_object() => Err(c.invalid("an object")),
            other => Ok(other),
        }
    }

    /// The items of an array.
    fn items(&self) -> Result<Vec<JsonCursor<'a>>, TopoFileError> {
        match self.value {
            Value::Array(items) => Ok(items
                .iter()
                .enumerate()
                .map(|(i, value)| JsonCursor {
                    file: self.file,
                    path: format!("{}[{i}]", self.path),
                    value,
                })
                .collect()),
            _ => Err(self.invalid("an array")),
        }
    }

    /// An integer (written without a fraction or exponent).
    fn as_integer(&self) -> Result<i128, TopoFileError> {
        match self.value {
            Value::Number(n) => n
                .as_i64()
                .map(i128::from)
                .or_else(|| n.as_u64().map(i128::from))
                .ok_or_else(|| self.invalid("an integer")),
            _ => Err(self.invalid("an integer")),
        }
    }

    /// A finite number.
    fn as_number(&self) -> Result<f64, TopoFileError> {
        self.value
            .as_f64()
            .filter(|x| x.is_finite())
            .ok_or_else(|| self.invalid("a finite number"))
    }
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

    #[test]
    fn floats_are_yaml_1_1_floats() {
        assert_eq!(yaml_float(1.0), "1.0");
        assert_eq!(yaml_float(-0.0), "0.0");
        assert_eq!(yaml_float(0.1), "0.1");
        assert_eq!(yaml_float(1e16), "1.0e+16");
        assert_eq!(yaml_float(2.5e-7), "2.5e-7");
        assert_eq!(yaml_float(-1.25e300), "-1.25e+300");
    }

    #[test]
    fn scalars_are_plain_only_when_unambiguous() {
        assert_eq!(yaml_scalar("LabDoor1"), "LabDoor1");
        assert_eq!(
            yaml_scalar("geometry_msgs/PoseStamped"),
            "geometry_msgs/PoseStamped"
        );
        assert_eq!(yaml_scalar("yes"), "\"yes\"");
        assert_eq!(yaml_scalar("On"), "\"On\"");
        assert_eq!(yaml_scalar("12"), "\"12\"");
        assert_eq!(yaml_scalar("0x1A"), "\"0x1A\"");
        assert_eq!(yaml_scalar("a: b"), "\"a: b\"");
        assert_eq!(yaml_scalar(""), "\"\"");
        assert_eq!(yaml_scalar("x\"y"), "\"x\\\"y\"");
    }

    #[test]
    fn formats_utc_times_as_lcas_does() {
        assert_eq!(format_last_updated(0), "01-01-1970_00-00-00");
        assert_eq!(format_last_updated(1_404_836_638), "08-07-2014_16-23-58");
        assert_eq!(format_last_updated(951_782_400), "29-02-2000_00-00-00");
    }

    #[test]
    fn synthetic_poses_surround_the_known_ones() {
        let mut map = TopoMap::new();
        map.add_node("A", Some([10.0, 0.0, 0.5])).unwrap();
        map.add_node("B", None).unwrap();
        map.add_node("C", Some([12.0, 0.0, 0.0])).unwrap();
        map.add_node("D", None).unwrap();
        let poses = node_poses(&map);
        assert_eq!(
            poses[0],
            NodePose {
                pose: [10.0, 0.0, 0.5],
                synthetic: false
            }
        );
        assert!(poses[1].synthetic && poses[3].synthetic && !poses[2].synthetic);
        // centre (11, 0), spread 1, radius 1 + max(1, 2/π) = 2
        assert!((poses[1].pose[0] - 13.0).abs() < 1e-12 && poses[1].pose[1].abs() < 1e-12);
        assert!((poses[3].pose[0] - 9.0).abs() < 1e-12);
        assert_eq!(node_poses(&map), poses);
    }

    /// A map with poses, one node without, names and ids as edge files and tmap2 have them.
    fn posed_map() -> TopoMap {
        let mut map = TopoMap::new();
        map.add_node("LabDoor1", Some([1.25, -2.0, 0.0])).unwrap();
        map.add_node("Lab-Door.2", Some([4.0e-3, 1.0e6, 0.0]))
            .unwrap();
        map.add_node("17", Some([0.1, 0.2, 0.0])).unwrap();
        map.add_node("Kitchen", None).unwrap();
        map.add_edge("LabDoor1_Lab-Door.2", "LabDoor1", "Lab-Door.2")
            .unwrap();
        map.add_edge("back", "Lab-Door.2", "LabDoor1").unwrap();
        map.add_edge("17_Kitchen", "17", "Kitchen").unwrap();
        map.add_edge("loop", "17", "17").unwrap();
        map
    }

    #[test]
    fn route_geojson_round_trips() {
        let map = posed_map();
        // With and without intervals of the time taken (files of models without them).
        let plain = RouteEdgeMetadata::new(0.5, 3.0);
        let spread = plain.with_time_interval(Some((1.25, 7.5)), 0.9);
        for metadata in [plain, spread] {
            let json = encode_route_geojson(&map, &vec![metadata; map.edges().len()]).unwrap();
            assert_eq!(
                json.contains("abs_time_taken_lower"),
                metadata.time_taken_interval.is_some()
            );
            let read = decode_route_geojson("map.geojson", json.as_bytes()).unwrap();
            // Same nodes (names, poses bit for bit; the unposed node stays unposed) and edges.
            assert_eq!(read.nodes(), map.nodes());
            assert_eq!(read.edges(), map.edges());
        }
        // Yaw is not in the format: it reads back as 0.
        let mut turned = TopoMap::new();
        turned.add_node("A", Some([1.0, 2.0, 0.7])).unwrap();
        let json = encode_route_geojson(&turned, &[]).unwrap();
        let read = decode_route_geojson("t.geojson", json.as_bytes()).unwrap();
        assert_eq!(read.nodes()[0].pose, Some([1.0, 2.0, 0.0]));
        // An empty map.
        let json = encode_route_geojson(&TopoMap::new(), &[]).unwrap();
        assert_eq!(
            decode_route_geojson("e.geojson", json.as_bytes()).unwrap(),
            TopoMap::new()
        );
    }

    /// A graph in the style of Nav2's sample graphs: ids only, an edge before the nodes it
    /// joins, parallel edges, a `LineString`, a 3-D position and extra members.
    const NAV2_STYLE: &str = r#"{
  "type": "FeatureCollection",
  "name": "graph",
  "crs": { "type": "name", "properties": { "name": "urn:ogc:def:crs:EPSG::3857" } },
  "features": [
    { "type": "Feature", "properties": { "id": 10, "startid": 2, "endid": 0, "cost": 3.0 },
      "geometry": { "type": "MultiLineString", "coordinates": [ [ [ 4.0, 0.0 ], [ 0.0, 0.0 ] ] ] } },
    { "type": "Feature", "properties": { "id": 0, "frame": "map" },
      "geometry": { "type": "Point", "coordinates": [ 0.0, 0.0 ] } },
    { "type": "Feature", "properties": { "id": 1, "frame": "map" },
      "geometry": { "type": "Point", "coordinates": [ 2.0, 0.5, 0.0 ] } },
    { "type": "Feature", "properties": { "id": 2, "frame": "map", "metadata": {} },
      "geometry": { "type": "Point", "coordinates": [ 4.0, 0.0 ] } },
    { "type": "Feature", "properties": { "id": 11, "startid": 0, "endid": 1 },
      "geometry": { "type": "MultiLineString", "coordinates": [ [ [ 0.0, 0.0 ], [ 2.0, 0.5 ] ] ] } },
    { "type": "Feature", "properties": { "id": 12, "startid": 0, "endid": 1, "overridable": false },
      "geometry": { "type": "LineString", "coordinates": [ [ 0.0, 0.0 ], [ 2.0, 0.5 ] ] } },
    { "type": "Feature", "properties": { "id": 13, "startid": 1, "endid": 2, "metadata": { "name": 7 } },
      "geometry": { "type": "MultiLineString", "coordinates": [ [ [ 2.0, 0.5 ], [ 4.0, 0.0 ] ] ] } }
  ]
}"#;

    #[test]
    fn reads_graphs_in_the_style_of_nav2() {
        let map = decode_route_geojson("graph.geojson", NAV2_STYLE.as_bytes()).unwrap();
        let nodes: Vec<(&str, Option<[f64; 3]>)> = map
            .nodes()
            .iter()
            .map(|n| (n.name.as_str(), n.pose))
            .collect();
        assert_eq!(
            nodes,
            [
                ("0", Some([0.0, 0.0, 0.0])),
                ("1", Some([2.0, 0.5, 0.0])),
                ("2", Some([4.0, 0.0, 0.0]))
            ]
        );
        let edges: Vec<(&str, usize, usize)> = map
            .edges()
            .iter()
            .map(|e| (e.id.as_str(), e.from, e.to))
            .collect();
        assert_eq!(
            edges,
            [
                ("2_0", 2, 0),
                ("0_1", 0, 1),
                ("0_1_12", 0, 1),
                ("1_2", 1, 2)
            ]
        );
        // A generated id does not take one that a later edge names.
        let named = NAV2_STYLE.replace(
            r#""metadata": { "name": 7 }"#,
            r#""metadata": { "name": "0_1" }"#,
        );
        let map = decode_route_geojson("graph.geojson", named.as_bytes()).unwrap();
        let ids: Vec<&str> = map.edges().iter().map(|e| e.id.as_str()).collect();
        assert_eq!(ids, ["2_0", "0_1_11", "0_1_12", "0_1"]);
    }

    fn route_error(text: &str) -> TopoFileError {
        decode_route_geojson("g.geojson", text.as_bytes()).unwrap_err()
    }

    #[test]
    fn route_geojson_errors_name_the_file_and_the_json_path() {
        let cases = [
            // Not a FeatureCollection.
            (
                NAV2_STYLE.replace(r#""type": "FeatureCollection""#, r#""type": "Feature""#),
                r#"g.geojson: type: "Feature" is invalid (expected "FeatureCollection")"#,
            ),
            (
                "[1, 2]".to_owned(),
                "g.geojson: not a Nav2 route GeoJSON file: the top level is an array, not a \
                 GeoJSON FeatureCollection object",
            ),
            (
                r#"{"type": "FeatureCollection"}"#.to_owned(),
                "g.geojson: missing required key `features`",
            ),
            // Unknown geometry type.
            (
                NAV2_STYLE.replace(r#""LineString""#, r#""Polygon""#),
                r#"g.geojson: features[5].geometry.type: "Polygon" is invalid (expected "Point", "LineString" or "MultiLineString")"#,
            ),
            // Duplicate node ids.
            (
                NAV2_STYLE.replace(r#""id": 2, "frame""#, r#""id": 0, "frame""#),
                "g.geojson: features[3].properties.id: node id 0 is used twice (also by \
                 features[1])",
            ),
            // An edge to a node id that no node has.
            (
                NAV2_STYLE.replace(r#""startid": 1"#, r#""startid": 17"#),
                "g.geojson: features[6].properties.startid: no node with id 17",
            ),
            (
                NAV2_STYLE.replace(r#""endid": 0"#, r#""endid": "0""#),
                r#"g.geojson: features[0].properties.endid: "0" is invalid (expected an integer)"#,
            ),
            (
                NAV2_STYLE.replace(r#""id": 1, "frame""#, r#""id": 1.5, "frame""#),
                "g.geojson: features[2].properties.id: 1.5 is invalid (expected an integer)",
            ),
            (
                NAV2_STYLE.replace(r#""startid": 0, "endid": 1 }"#, r#""endid": 1 }"#),
                "g.geojson: missing required key `features[4].properties.startid`",
            ),
            // Coordinates.
            (
                NAV2_STYLE.replace("[ 2.0, 0.5, 0.0 ]", r#"[ 2.0, "a" ]"#),
                r#"g.geojson: features[2].geometry.coordinates[1]: "a" is invalid (expected a finite number)"#,
            ),
            (
                NAV2_STYLE.replace("[ 2.0, 0.5, 0.0 ]", "[ 2.0 ]"),
                "g.geojson: features[2].geometry.coordinates: [2.0] is invalid (expected a \
                 position [x, y])",
            ),
            // Names the map refuses.
            (
                NAV2_STYLE.replace(r#""metadata": {}"#, r#""metadata": {"name": "Lab Door"}"#),
                r#"g.geojson: features[3].properties.metadata.name: invalid name "Lab Door": names are non-empty and contain no whitespace"#,
            ),
            (
                NAV2_STYLE.replace(r#""metadata": {}"#, r#""metadata": {"name": "1"}"#),
                r#"g.geojson: features[3].properties.metadata.name: node "1" is defined twice"#,
            ),
            (
                NAV2_STYLE.replace(r#""metadata": {}"#, r#""metadata": []"#),
                "g.geojson: features[3].properties.metadata: [] is invalid (expected an object)",
            ),
        ];
        for (text, expected) in cases {
            assert_eq!(route_error(&text).to_string(), expected);
        }
        let err = route_error(&NAV2_STYLE.replace(r#""startid": 1"#, r#""startid": 17"#));
        assert_eq!(err.key(), Some("features[6].properties.startid"));
        assert_eq!((err.file(), err.line()), (Some("g.geojson"), None));
        // Two edges that name the same id; parallel edges without ids.
        let twice = NAV2_STYLE
            .replace(r#""cost": 3.0"#, r#""metadata": {"name": "e"}"#)
            .replace(r#""name": 7"#, r#""name": "e""#);
        assert_eq!(
            route_error(&twice).to_string(),
            r#"g.geojson: features[6].properties.metadata.name: edge "e" is defined twice"#
        );
        let parallel = NAV2_STYLE.replace(r#""id": 12, "#, "");
        assert_eq!(
            route_error(&parallel).to_string(),
            r#"g.geojson: features[5].properties: edge "0_1" is defined twice"#
        );
    }

    #[test]
    fn route_geojson_syntax_errors_have_the_line() {
        // Non-finite coordinates cannot be JSON numbers: out of range, or NaN as Python writes.
        let err = route_error(&NAV2_STYLE.replace("[ 2.0, 0.5, 0.0 ]", "[ 2.0, 1e400 ]"));
        assert_eq!(
            err.to_string(),
            "g.geojson:11: not a Nav2 route GeoJSON file: number out of range (column 64): \
             numbers must be finite (JSON has no NaN or Infinity)"
        );
        assert!(matches!(err.kind(), TopoFileErrorKind::Json { .. }));
        let err = route_error(&NAV2_STYLE.replace("[ 2.0, 0.5, 0.0 ]", "[ 2.0, NaN ]"));
        assert_eq!(
            err.to_string(),
            "g.geojson:11: not a Nav2 route GeoJSON file: expected value (column 60): numbers \
             must be finite (JSON has no NaN or Infinity)"
        );
        let err = route_error("{\n  \"type\": \"FeatureCollection\",\n");
        assert_eq!(
            err.to_string(),
            "g.geojson:3: not a Nav2 route GeoJSON file: EOF while parsing a value"
        );
        assert_eq!(err.line(), Some(3));
        let deep = format!("{}{}", "[".repeat(200), "]".repeat(200));
        assert!(
            route_error(&deep)
                .to_string()
                .contains("recursion limit exceeded"),
            "{}",
            route_error(&deep)
        );
    }

    #[test]
    fn reads_route_geojson_files_and_refuses_other_kinds_of_file() {
        let dir = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-io-route-{}", std::process::id())),
        );
        let map = posed_map();
        let metadata = vec![
            RouteEdgeMetadata::new(1.0, 0.0)
                .with_time_interval(Some((0.0, 0.0)), 0.9);
            map.edges().len()
        ];
        let path = dir.join("map.geojson");
        write_route_geojson(&path, &map, &metadata).unwrap();
        assert_eq!(read_route_geojson(&path).unwrap(), map);
        // Compressed.
        let gz = dir.join("map.geojson.gz");
        let mut encoder = flate2::write::GzEncoder::new(
            fs::File::create(&gz).unwrap(),
            flate2::Compression::fast(),
        );
        io::Write::write_all(&mut encoder, &fs::read(&path).unwrap()).unwrap();
        encoder.finish().unwrap();
        assert_eq!(read_route_geojson(&gz).unwrap(), map);
        // Errors name the file.
        let bad = dir.join("bad.geojson");
        fs::write(&bad, "{\"type\": \"FeatureCollection\", \"features\": 3}").unwrap();
        assert_eq!(
            read_route_geojson(&bad).unwrap_err().to_string(),
            format!(
                "{}: features: 3 is invalid (expected an array)",
                bad.display()
            )
        );
        let err = read_route_geojson(&dir).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!(
                "{}: cannot read: it is not a regular file (a directory, a device or a pipe)",
                dir.display()
            )
        );
        let missing = dir.join("none.geojson");
        let err = read_route_geojson(&missing).unwrap_err();
        assert!(matches!(
            err.kind(),
            TopoFileErrorKind::Io { action: "read", .. }
        ));
        assert_eq!(err.file(), Some(missing.display().to_string().as_str()));
        #[cfg(unix)]
        {
            let err = read_route_geojson("/dev/zero").unwrap_err();
            assert_eq!(
                err.to_string(),
                "/dev/zero: cannot read: it is not a regular file (a directory, a device or a pipe)"
            );
        }
        let _ = fs::remove_dir_all(&dir);
    }
}
