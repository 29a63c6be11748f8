//! Frame lists: the occupancy maps a grid is built from, one `<time> <map.yaml>` line per
//! frame (`chronomap grid build --frames`).
//!
//! ```text
//! # unix seconds, ROS map_server / Nav2 map (relative to this file)
//! 1451865600 maps/frame_0000.yaml
//! 1451869200 maps/frame_0001.yaml
//! ```
//!
//! Blank lines and `#` comments are skipped, as in the other text formats ([`crate::text`]);
//! times are seconds, finite, `>= 0` and never going backwards. Map paths are relative to the
//! folder of the list (or absolute). Every map must have the size of the first one.
//!
//! ```
//! use chronomap_io::frame_list::read_frame_list_from;
//! use chronomap_io::Field;
//!
//! let frames = read_frame_list_from("frames.txt", "# t map\n100 a.yaml\n200 b.yaml\n".as_bytes())?;
//! assert_eq!((frames[1].time, frames[1].line), (200.0, 3));
//! assert_eq!(frames[1].map, std::path::Path::new("b.yaml"));
//!
//! let err = read_frame_list_from("frames.txt", "100 a.yaml\nsoon b.yaml\n".as_bytes()).unwrap_err();
//! assert_eq!(err.to_string(), r#"frames.txt:2: time: "soon" is not a number"#);
//! let err = read_frame_list_from("frames.txt", "100\n".as_bytes()).unwrap_err();
//! assert_eq!(err.field(), Some(Field::MapFile));
//! # Ok::<(), chronomap_io::DataError>(())
//! ```

use std::io::Read;
use std::path::{Path, PathBuf};

use thiserror::Error;

use chronomap_spatial::OccupancyMap;

use crate::navmap::{LoadSemantics, NavMapError, load_map};
use crate::text::{
    DataError, DataErrorKind, Field, Fields, for_each_data_line, open_data_file, parse_time,
    required, shorten,
};

/// What a line of a frame list must look like (quoted in errors).
const FRAME_LINE: &str = "`<time> <map.yaml>`";

/// One frame of a list.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Time of the frame (seconds).
    pub time: f64,
    /// The map's YAML file: relative to the list's folder as [`read_frame_list`] returns it,
    /// as written by [`read_frame_list_from`].
    pub map: PathBuf,
    /// The 1-based line of the list.
    pub line: usize,
}

/// Reads a frame list (plain, `.xz` or `.gz`); map paths are made relative to its folder.
///
/// # Errors
/// A [`DataError`] naming the list and line: a time that is not a number, negative or going
/// backwards, a missing map or an extra field, no frame at all.
pub fn read_frame_list(path: impl AsRef<Path>) -> Result<Vec<Frame>, DataError> {
    let path = path.as_ref();
    let mut frames = read_frame_list_from(&path.display().to_string(), open_data_file(path)?)?;
    let folder = path.parent().unwrap_or(Path::new("."));
    for frame in &mut frames {
        frame.map = folder.join(&frame.map);
    }
    Ok(frames)
}

/// Reads a frame list from `reader` (plain text; `name` is used in errors); map paths as
/// written.
///
/// # Errors
/// As [`read_frame_list`].
pub fn read_frame_list_from(name: &str, reader: impl Read) -> Result<Vec<Frame>, DataError> {
    let mut frames: Vec<Frame> = Vec::new();
    for_each_data_line(name, reader, |line, text| {
        let mut fields = Fields::new(text);
        let time_text = required(fields.next(), Field::Time, FRAME_LINE)?;
        let previous = frames.last().map(|f| (f.time, f.line));
        let time = parse_time(time_text, previous, frames.len())?;
        let map = required(fields.next(), Field::MapFile, FRAME_LINE)?;
        fields.finish(FRAME_LINE)?;
        if map.len() > MAX_MAP_PATH_BYTES {
            return Err(DataErrorKind::FieldTooLong {
                field: Field::MapFile,
                text: shorten(&String::from_utf8_lossy(map), 40),
                max: MAX_MAP_PATH_BYTES,
            });
        }
        frames.push(Frame {
            time,
            map: PathBuf::from(String::from_utf8_lossy(map).into_owned()),
            line,
        });
        Ok(())
    })?;
    Ok(frames)
}

/// Why the map of a frame cannot be used.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum FrameMapError {
    /// The map cannot be read (the error names its file, and the line or key).
    #[error("{list}:{line}: {error}")]
    Map {
        /// The frame list.
        list: String,
        /// The line of the frame.
        line: usize,
        /// What is wrong with the map.
        error: Box<NavMapError>,
    },
    /// The map does not have the size of the first map of the list.
    #[error(
        "{list}:{line}: {map} is {width}x{height} but the first map is {first_width}x{first_height}"
    )]
    Size {
        /// The frame list.
        list: String,
        /// The line of the frame.
        line: usize,
        /// The map's file.
        map: String,
        /// Its width in cells.
        width: u32,
        /// Its height in cells.
        height: u32,
        /// Width of the first map.
        first_width: u32,
        /// Height of the first map.
        first_height: u32,
    },
    /// The map has the size of the first map but another resolution or origin: its cells are
    /// elsewhere in the world, so they cannot be merged with the first map's.
    #[error("{list}:{line}: {reason} (every frame must have the cells of the first one)")]
    Geometry {
        /// The frame list.
        list: String,
        /// The line of the frame.
        line: usize,
        /// Both maps and their values: `MAP has resolution 0.1 m but FIRST has 0.05 m`.
        reason: String,
    },
}

/// The longest map path a frame list may give, in bytes (the usual `PATH_MAX`).
pub const MAX_MAP_PATH_BYTES: usize = 4096;

/// Loads the map of `frame` of the list `list` with `semantics`, checking that it has the
/// size of `first` (the list's first map) if given.
///
/// # Errors
/// [`FrameMapError::Map`] if the map cannot be read, [`FrameMapError::Size`] if it has
/// another size; both name the list and the line.
pub fn load_frame_map(
    list: &str,
    frame: &Frame,
    semantics: LoadSemantics,
    first: Option<&OccupancyMap>,
) -> Result<OccupancyMap, FrameMapError> {
    load(
        list,
        frame,
        semantics,
        first.map(|m| ("the first map".to_owned(), m)),
    )
}

/// [`load_frame_map`] of a frame after the first, `first` (whose map is `first_map`): errors
/// name both map files.
///
/// # Errors
/// As [`load_frame_map`].
pub fn load_next_frame_map(
    list: &str,
    frame: &Frame,
    semantics: LoadSemantics,
    first: &Frame,
    first_map: &OccupancyMap,
) -> Result<OccupancyMap, FrameMapError> {
    let name = format!("{} (line {})", first.map.display(), first.line);
    load(list, frame, semantics, Some((name, first_map)))
}

fn load(
    list: &str,
    frame: &Frame,
    semantics: LoadSemantics,
    first: Option<(String, &OccupancyMap)>,
) -> Result<OccupancyMap, FrameMapError> {
    let map = load_map(&frame.map, semantics).map_err(|error| FrameMapError::Map {
        list: list.to_string(),
        line: frame.line,
        error: Box::new(error),
    })?;
    let Some((first_name, first)) = first else {
        return Ok(map);
    };
    if (map.width, map.height) != (first.width, first.height) {
        return Err(FrameMapError::Size {
            list: list.to_string(),
            line: frame.line,
            map: frame.map.display().to_string(),
            width: map.width,
            height: map.height,
            first_width: first.width,
            first_height: first.height,
        });
    }
    let differs = |what: &str, value: String, first_value: String| FrameMapError::Geometry {
        list: list.to_string(),
        line: frame.line,
        reason: format!(
            "{} has {what} {value} but {first_name} has {first_value}",
            frame.map.display()
        ),
    };
    if map.resolution.to_bits() != first.resolution.to_bits() {
        return Err(differs(
            "resolution",
            format!("{} m", map.resolution),
            format!("{} m", first.resolution),
        ));
    }
    if map.origin.map(f64::to_bits) != first.origin.map(f64::to_bits) {
        return Err(differs(
            "origin",
            format!("{:?}", map.origin),
            format!("{:?}", first.origin),
        ));
    }
    Ok(map)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::navmap::{SaveOptions, save_map};

    #[test]
    fn lists_name_their_lines_and_maps_of_another_size() {
        let dir = std::env::temp_dir().join(format!("chronomap-frame-list-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("maps")).unwrap();
        let small = OccupancyMap::new(4, 3, 0.05, [0.0; 3]);
        let wide = OccupancyMap::new(6, 3, 0.05, [0.0; 3]);
        let options = SaveOptions::default();
        save_map(&dir.join("maps/small"), &small, &options).unwrap();
        save_map(&dir.join("maps/wide"), &wide, &options).unwrap();
        let list = dir.join("frames.txt");
        std::fs::write(
            &list,
            "# frames\n\n100 maps/small.yaml\n160 maps/wide.yaml\n",
        )
        .unwrap();
        let frames = read_frame_list(&list).unwrap();
        assert_eq!(frames.len(), 2);
        assert_eq!((frames[0].time, frames[0].line), (100.0, 3));
        assert_eq!((frames[1].time, frames[1].line), (160.0, 4));
        assert_eq!(frames[1].map, dir.join("maps/wide.yaml"));
        let name = list.display().to_string();
        let first = load_frame_map(&name, &frames[0], LoadSemantics::Nav2, None).unwrap();
        assert_eq!((first.width, first.height), (4, 3));
        let err = load_frame_map(&name, &frames[1], LoadSemantics::Nav2, Some(&first))
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with(&format!("{name}:4: "))
                && err.ends_with("is 6x3 but the first map is 4x3"),
            "{err}"
        );
        let missing = Frame {
            time: 200.0,
            map: dir.join("maps/none.yaml"),
            line: 5,
        };
        let err = load_frame_map(&name, &missing, LoadSemantics::Nav2, None)
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with(&format!("{name}:5: ")) && err.contains("none.yaml"),
            "{err}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bad_lines_are_data_errors() {
        for (text, expected) in [
            (
                "100 a.yaml\n50 b.yaml\n",
                "f:2: time: \"50\" is earlier than the time 100 on line 1",
            ),
            ("-1 a.yaml\n", "f:1: time: \"-1\" is negative"),
            ("100\n", "f:1: map: missing (`<time> <map.yaml>`)"),
            (
                "100 a.yaml b.yaml\n",
                "f:1: unexpected extra field \"b.yaml\"",
            ),
            ("# nothing\n", "f: no data lines"),
        ] {
            let err = read_frame_list_from("f", text.as_bytes())
                .unwrap_err()
                .to_string();
            assert!(err.starts_with(expected), "{text:?}: {err}");
        }
    }
}
