//! Map and frame files made to hurt: images that announce huge sizes, devices and endless
//! files given as maps, lists or models, over-long names, thresholds that cannot be, frames
//! that do not share their cells. Each is an error naming the file (and line or key), found
//! before memory or time is spent.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use chronomap_io::frame_list::{MAX_MAP_PATH_BYTES, read_frame_list, read_frame_list_from};
use chronomap_io::navmap::{
    LoadSemantics, MAX_MAP_CELLS, NavMapErrorKind, SaveOptions, decode_map_yaml, load_map, save_map,
};
use chronomap_io::text::Field;
use chronomap_io::{FrameMapError, load_frame_map, load_next_frame_map};
use chronomap_spatial::OccupancyMap;
use chronomap_testutil::write;

fn scratch(test: &str) -> PathBuf {
    chronomap_testutil::scratch!("chronomap-io-hostile-maps", test)
}

/// A PNG chunk: length, type, data, CRC-32 of type and data.
fn chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut bytes = (data.len() as u32).to_be_bytes().to_vec();
    bytes.extend_from_slice(kind);
    bytes.extend_from_slice(data);
    let mut crc = crc32fast::Hasher::new();
    crc.update(kind);
    crc.update(data);
    bytes.extend_from_slice(&crc.finalize().to_be_bytes());
    bytes
}

/// A PNG that announces a `width × height` 8-bit grey image but holds almost no data.
fn announcing_png(width: u32, height: u32) -> Vec<u8> {
    let mut header = width.to_be_bytes().to_vec();
    header.extend_from_slice(&height.to_be_bytes());
    header.extend_from_slice(&[8, 0, 0, 0, 0]);
    let mut bytes = b"\x89PNG\r\n\x1a\n".to_vec();
    bytes.extend(chunk(b"IHDR", &header));
    bytes.extend(chunk(
        b"IDAT",
        &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01],
    ));
    bytes.extend(chunk(b"IEND", &[]));
    bytes
}

const YAML: &str = "resolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n\
                    occupied_thresh: 0.65\nfree_thresh: 0.196\n";

/// Writes `dir/NAME.yaml` naming `image`; its path.
fn yaml_for(dir: &Path, name: &str, image: &str) -> PathBuf {
    write(
        dir,
        &format!("{name}.yaml"),
        format!("image: {image}\n{YAML}"),
    )
}

/// The case: a 948 KB PNG of 30,000 × 30,000 made grid build use 5.6 GB and 34 s.
/// Now the header is enough: an error naming the image and its size, at once.
#[test]
fn an_image_announcing_more_cells_than_the_limit_is_refused_from_its_header() {
    let dir = scratch("huge_image");
    write(&dir, "huge.png", announcing_png(30_000, 30_000));
    write(&dir, "huge.pgm", b"P5\n30000 30000\n255\n");
    for image in ["huge.png", "huge.pgm"] {
        let yaml = yaml_for(&dir, image, image);
        let started = Instant::now();
        let err = load_map(&yaml, LoadSemantics::Nav2).unwrap_err();
        assert!(started.elapsed() < Duration::from_secs(2));
        assert!(
            matches!(err.kind(), NavMapErrorKind::ImageSize { .. }),
            "{err}"
        );
        assert_eq!(
            err.to_string(),
            format!(
                "{}: image of 30000 x 30000 pixels is too large (900000000 cells, at most \
                 {MAX_MAP_CELLS})",
                dir.join(image).display()
            )
        );
    }
    // At the limit (8192 x 8192) the header is accepted: the decoder then finds the data short.
    write(&dir, "edge.png", announcing_png(8192, 8192));
    let err = load_map(&yaml_for(&dir, "edge", "edge.png"), LoadSemantics::Nav2).unwrap_err();
    assert!(
        matches!(err.kind(), NavMapErrorKind::MalformedImage { .. }),
        "{err}"
    );
}

/// `image: /dev/zero` was read until memory ran out; frame lists and model files of
/// `/dev/zero` too. Each is refused before reading.
#[cfg(unix)]
#[test]
fn devices_given_as_image_frame_list_or_model_are_refused() {
    let dir = scratch("devices");
    let yaml = yaml_for(&dir, "zero", "/dev/zero");
    let err = load_map(&yaml, LoadSemantics::Nav2).unwrap_err();
    assert!(
        matches!(err.kind(), NavMapErrorKind::ImageUnreadable { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("/dev/zero"), "{err}");
    assert!(err.to_string().contains("not a regular file"), "{err}");
    let err = read_frame_list("/dev/zero").unwrap_err();
    assert_eq!(err.name(), "/dev/zero");
    assert!(err.to_string().contains("not a regular file"), "{err}");
    for result in [
        chronomap_io::model_file::read_any_model("/dev/zero").map(|_| ()),
        chronomap_io::read_grid_file("/dev/zero").map(|_| ()),
        chronomap_io::model_file::read_edge_models("/dev/zero").map(|_| ()),
        chronomap_io::activity::read_copa_map("/dev/zero").map(|_| ()),
    ] {
        let err = result.unwrap_err().to_string();
        assert!(err.starts_with("/dev/zero: cannot read: "), "{err}");
        assert!(err.contains("not a regular file"), "{err}");
    }
    let err = chronomap_io::navmap::read_map_yaml(Path::new("/dev/zero")).unwrap_err();
    assert!(err.to_string().contains("not a regular file"), "{err}");
}

/// A 200 MB map path was echoed whole into the error; an image name of a map YAML too.
#[test]
fn over_long_names_are_refused_and_quoted_short() {
    let long = "m".repeat(MAX_MAP_PATH_BYTES + 1);
    let err = read_frame_list_from("frames.txt", format!("100 {long}\n").as_bytes()).unwrap_err();
    assert_eq!(err.line(), Some(1));
    assert_eq!(err.field(), Some(Field::MapFile));
    assert_eq!(
        err.to_string(),
        format!(
            "frames.txt:1: map: \"{}…\" is longer than 4096 bytes",
            "m".repeat(40)
        )
    );
    let text = format!("image: {}.pgm\n{YAML}", "a".repeat(20_000));
    let err = decode_map_yaml("o.yaml", text.as_bytes()).unwrap_err();
    assert_eq!((err.line(), err.key()), (Some(1), Some("image")));
    assert!(err.to_string().len() < 200, "{err}");
}

/// Data files accept a UTF-8 byte order mark; so do frame lists.
#[test]
fn a_frame_list_may_start_with_a_byte_order_mark() {
    let frames = read_frame_list_from("frames.txt", &b"\xEF\xBB\xBF100 a.yaml\n"[..]).unwrap();
    assert_eq!((frames[0].time, frames[0].line), (100.0, 1));
}

/// Maps of the same size but another resolution or origin were merged cell by cell.
#[test]
fn frames_with_another_resolution_or_origin_are_refused_naming_both_maps() {
    let dir = scratch("geometry");
    let options = SaveOptions::default();
    let base = OccupancyMap::new(4, 3, 0.05, [0.0; 3]);
    let coarse = OccupancyMap::new(4, 3, 0.1, [0.0; 3]);
    let moved = OccupancyMap::new(4, 3, 0.05, [1.0, 0.0, 0.0]);
    for (name, map) in [("base", &base), ("coarse", &coarse), ("moved", &moved)] {
        save_map(&dir.join(name), map, &options).unwrap();
    }
    let list = write(
        &dir,
        "frames.txt",
        "100 base.yaml\n200 coarse.yaml\n300 moved.yaml\n400 base.yaml\n",
    );
    let frames = read_frame_list(&list).unwrap();
    let name = list.display().to_string();
    let nav2 = LoadSemantics::Nav2;
    let first = load_frame_map(&name, &frames[0], nav2, None).unwrap();
    let next = |i: usize| load_next_frame_map(&name, &frames[i], nav2, &frames[0], &first);
    let first_name = frames[0].map.display();
    let err = next(1).unwrap_err();
    assert!(matches!(err, FrameMapError::Geometry { .. }), "{err}");
    assert_eq!(
        err.to_string(),
        format!(
            "{name}:2: {} has resolution 0.1 m but {first_name} (line 1) has 0.05 m (every \
             frame must have the cells of the first one)",
            frames[1].map.display()
        )
    );
    let err = next(2).unwrap_err().to_string();
    assert!(
        err.contains("has origin [1.0, 0.0, 0.0] but") && err.contains("has [0.0, 0.0, 0.0]"),
        "{err}"
    );
    assert_eq!(next(3).unwrap().data, first.data);
    // The older call names the first map as such.
    let err = load_frame_map(&name, &frames[1], nav2, Some(&first)).unwrap_err();
    assert!(
        err.to_string().contains("but the first map has 0.05 m"),
        "{err}"
    );
}

/// `occupied_thresh < free_thresh` and thresholds outside [0, 1] were accepted.
#[test]
fn thresholds_outside_0_1_or_crossed_are_refused_naming_the_key() {
    for (occupied, free, key, expected) in [
        ("0.1", "0.5", "occupied_thresh", "a number >= free_thresh"),
        ("1.5", "0.2", "occupied_thresh", "a number in [0, 1]"),
        ("0.65", "-0.1", "free_thresh", "a number in [0, 1]"),
    ] {
        let text = format!(
            "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n\
             occupied_thresh: {occupied}\nfree_thresh: {free}\n"
        );
        let err = decode_map_yaml("m.yaml", text.as_bytes()).unwrap_err();
        assert_eq!(err.key(), Some(key), "{err}");
        let line = if key == "occupied_thresh" { 5 } else { 6 };
        assert_eq!(err.line(), Some(line), "{err}");
        assert!(
            err.to_string()
                .starts_with(&format!("m.yaml:{line}: {key}: ")),
            "{err}"
        );
        assert!(err.to_string().contains(expected), "{err}");
    }
    let equal = "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n\
                 occupied_thresh: 0.5\nfree_thresh: 0.5\n";
    assert!(decode_map_yaml("m.yaml", equal.as_bytes()).is_ok());
}
