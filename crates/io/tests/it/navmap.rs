//! ROS map files: byte-exact map_saver output, round trips through the loader with Nav2 and
//! ROS 1 semantics, and errors that name the file, line and key, never a panic.
//!
//! Expected bytes were checked against a C++ program that saves the same map the way
//! `nav2_map_server` `saveMapToFile` does, with GraphicsMagick++ 1.3.40 and yaml-cpp 0.7.0
//! (Debian 12), and the `format_g` table against `std::cout << std::setprecision(3)`.

use std::fs;
use std::path::{Path, PathBuf};

use chronomap_io::navmap::{
    LoadSemantics, MapMetadata, MapMode, NavMapErrorKind, SaveOptions, SavedMap, decode_map_image,
    decode_map_yaml, encode_map_image, encode_map_yaml, format_g, image_path, load_map,
    read_map_yaml, save_map,
};
use chronomap_spatial::OccupancyMap;
use chronomap_testutil::write;

/// A fresh scratch folder for one test.
fn scratch(test: &str) -> PathBuf {
    chronomap_testutil::scratch!("chronomap-io-navmap", test)
}

/// The hand-made 4 x 3 map (row 0 at the bottom) with free, occupied, unknown, out-of-range
/// and in-between cells around the default thresholds (free <= 25, occupied >= 65).
fn four_by_three() -> OccupancyMap {
    OccupancyMap {
        width: 4,
        height: 3,
        resolution: 0.05,
        origin: [-1.5, 2.25, 0.0],
        data: vec![
            -1, 101, 10, 90, // bottom row: unknown, out of range, free, occupied
            25, 26, 64, 65, // middle row: the thresholds' neighbours
            0, 100, -128, 50, // top row: free, occupied, unknown, in between
        ],
    }
}

/// map_saver's YAML for [`four_by_three`] saved as `office` with default options: no final
/// newline (yaml-cpp's emitter writes none).
const OFFICE_YAML: &str = "image: office.pgm
mode: trinary
resolution: 0.05
origin: [-1.5, 2.25, 0]
negate: 0
occupied_thresh: 0.65
free_thresh: 0.25";

/// Saves [`four_by_three`] as `office` in `dir`.
fn save_office(dir: &Path, options: &SaveOptions) -> SavedMap {
    save_map(&dir.join("office"), &four_by_three(), options).unwrap()
}

/// Checks that the map saved as `yaml` loads as `expected` with both semantics.
fn assert_loads_as(yaml: &Path, expected: &[i8]) {
    for semantics in [LoadSemantics::Nav2, LoadSemantics::Ros1] {
        let data = load_map(yaml, semantics).unwrap().data;
        assert_eq!(data, expected, "{semantics:?}");
    }
}

fn metadata(mode: MapMode, occupied_thresh: f64, free_thresh: f64) -> MapMetadata {
    MapMetadata {
        image: "map.pgm".into(),
        mode,
        resolution: 0.05,
        origin: [0.0; 3],
        negate: false,
        occupied_thresh,
        free_thresh,
    }
}

/// A one-row binary PGM of the given grey values.
fn pgm_row(values: &[u8]) -> Vec<u8> {
    let mut bytes = format!("P5\n{} 1\n255\n", values.len()).into_bytes();
    bytes.extend_from_slice(values);
    bytes
}

fn png_bytes(
    width: u32,
    height: u32,
    colour: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(colour);
    encoder.set_depth(depth);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(data).unwrap();
    writer.finish().unwrap();
    bytes
}

// ---------------------------------------------------------------------------------------------
// Saving

#[test]
fn trinary_save_matches_map_saver_byte_for_byte() {
    let dir = scratch("trinary_bytes");
    let saved = save_office(&dir, &SaveOptions::default());
    assert_eq!(saved.yaml, dir.join("office.yaml"));
    assert_eq!(saved.image, dir.join("office.pgm"));

    // Image rows top first; 254 free (<= 25), 0 occupied (>= 65), 205 unknown and in between.
    let expected_pgm: &[u8] = b"P5\n4 3\n255\n\
        \xfe\x00\xcd\xcd\
        \xfe\xcd\xcd\x00\
        \xcd\xcd\xfe\x00";
    assert_eq!(fs::read(&saved.image).unwrap(), expected_pgm);
    assert_eq!(fs::read_to_string(&saved.yaml).unwrap(), OFFICE_YAML);

    // Saving again replaces both files and leaves no temporary file behind.
    save_office(&dir, &SaveOptions::default());
    let mut names: Vec<String> = fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["office.pgm", "office.yaml"]);
}

#[test]
fn raw_save_writes_cell_values_and_255_for_unknown() {
    let raw = SaveOptions {
        mode: MapMode::Raw,
        ..SaveOptions::default()
    };
    let expected: &[u8] = b"P5\n4 3\n255\n\
        \x00\x64\xff\x32\
        \x19\x1a\x40\x41\
        \xff\xff\x0a\x5a";
    assert_eq!(encode_map_image(&four_by_three(), &raw).unwrap(), expected);
    let yaml = encode_map_yaml("office.pgm", &four_by_three(), &raw).unwrap();
    assert_eq!(yaml, OFFICE_YAML.replace("trinary", "raw"));
}

#[test]
fn scale_save_is_grey_alpha_png_with_graphicsmagick_levels() {
    let dir = scratch("scale_png");
    let scale = SaveOptions {
        mode: MapMode::Scale,
        ..SaveOptions::default()
    };
    let saved = save_office(&dir, &scale);
    assert_eq!(saved.image, dir.join("office.png"));
    assert_eq!(
        fs::read_to_string(&saved.yaml).unwrap(),
        OFFICE_YAML
            .replace("office.pgm", "office.png")
            .replace("trinary", "scale")
    );

    let bytes = fs::read(&saved.image).unwrap();
    let decoder = png::Decoder::new(bytes.as_slice());
    let mut reader = decoder.read_info().unwrap();
    assert_eq!(
        reader.output_color_type(),
        (png::ColorType::GrayscaleAlpha, png::BitDepth::Eight)
    );
    let mut pixels = vec![0; reader.output_buffer_size()];
    reader.next_frame(&mut pixels).unwrap();
    // (grey, alpha) per pixel, top row first, as GraphicsMagick writes them: grey is
    // floor(255 (100 - v) / 100), unknown is grey 127 with alpha 0.
    #[rustfmt::skip]
    let expected = [
        255, 255,   0, 255, 127, 0, 127, 255, // 0, 100, -128, 50
        191, 255, 188, 255,  91, 255, 89, 255, // 25, 26, 64, 65
        127,   0, 127,   0, 229, 255, 25, 255, // -1, 101, 10, 90
    ];
    assert_eq!(pixels, expected);
}

#[test]
fn comment_lines_come_before_the_first_key() {
    let options = SaveOptions {
        comment: Some("chronomap prediction\nfor 2016-03-21T12:00:00Z\n\nmodel: fremen:2".into()),
        ..SaveOptions::default()
    };
    let yaml = encode_map_yaml("office.pgm", &four_by_three(), &options).unwrap();
    assert_eq!(
        yaml,
        format!(
            "# chronomap prediction\n# for 2016-03-21T12:00:00Z\n#\n# model: fremen:2\n{OFFICE_YAML}"
        )
    );
    // The loader reads it like any other map file.
    let metadata = decode_map_yaml("office.yaml", yaml.as_bytes()).unwrap();
    assert_eq!(metadata.image, "office.pgm");
    assert_eq!(metadata.origin, [-1.5, 2.25, 0.0]);
}

#[test]
fn image_names_that_need_quoting_survive_the_round_trip() {
    let map = four_by_three();
    for name in ["my map.pgm", "map: v2.pgm", "#1.pgm", "a\"b\\c.pgm"] {
        let yaml = encode_map_yaml(name, &map, &SaveOptions::default()).unwrap();
        let metadata = decode_map_yaml("m.yaml", yaml.as_bytes()).unwrap();
        assert_eq!(metadata.image, name, "{yaml}");
    }
    assert!(
        encode_map_yaml("map: v2.pgm", &map, &SaveOptions::default())
            .unwrap()
            .starts_with("image: \"map: v2.pgm\"\n")
    );
}

#[test]
fn format_g_matches_cpp_setprecision_3() {
    // (value, what `std::cout << std::setprecision(3) << value` prints with libstdc++)
    let table: [(f64, &str); 20] = [
        (0.05, "0.05"),
        (-10.0, "-10"),
        (12.345, "12.3"),
        (0.196, "0.196"),
        (0.0, "0"),
        (1e-4, "0.0001"),
        (123456.0, "1.23e+05"),
        (0.65, "0.65"),
        (2.25, "2.25"),
        (-1.5, "-1.5"),
        (100.0, "100"),
        (0.0005, "0.0005"),
        (1000.0, "1e+03"),
        (5e-5, "5e-05"),
        (-0.0, "-0"),
        (1.125, "1.12"),  // an exact binary tie: to even
        (999.5, "1e+03"), // rounding carries into the exponent
        (2.675, "2.67"),  // 2.67499999... in binary
        (0.001234, "0.00123"),
        (1.0 / 3.0, "0.333"),
    ];
    for (value, expected) in table {
        assert_eq!(format_g(value, 3), expected, "{value:e}");
    }
    // The resolution is an f32 widened to f64.
    assert_eq!(format_g(f64::from(0.05f32), 3), "0.05");
    assert_eq!(format_g(f64::from(0.1f32), 9), "0.100000001");
    assert_eq!(format_g(2.5001, 1), "3");
    assert_eq!(format_g(f64::NAN, 3), "nan");
    assert_eq!(format_g(f64::NEG_INFINITY, 3), "-inf");
}

// ---------------------------------------------------------------------------------------------
// Round trips

#[test]
fn trinary_round_trip_keeps_free_occupied_and_unknown_with_free_thresh_0_196() {
    let dir = scratch("trinary_round_trip");
    let options = SaveOptions {
        free_thresh: 0.196,
        ..SaveOptions::default()
    };
    let saved = save_office(&dir, &options);
    // Saved: v <= 20 free (254), v >= 65 occupied (0), the rest 205.
    #[rustfmt::skip]
    let expected = [
        -1, -1, 0, 100,
        -1, -1, -1, 100,
        0, 100, -1, -1,
    ];
    for semantics in [LoadSemantics::Nav2, LoadSemantics::Ros1] {
        let map = load_map(&saved.yaml, semantics).unwrap();
        assert_eq!((map.width, map.height), (4, 3));
        assert_eq!(map.resolution, 0.05);
        assert_eq!(map.origin, [-1.5, 2.25, 0.0]);
        assert_eq!(map.data, expected, "{semantics:?}");
    }
}

#[test]
fn default_free_thresh_0_25_loads_unknown_cells_back_as_free() {
    // The unknown grey 205 is p = 50/255 = 0.196 <= 0.25: map_saver's default thresholds turn
    // unknown space into free space on reload (with either semantics).
    let dir = scratch("trinary_default_thresholds");
    let saved = save_office(&dir, &SaveOptions::default());
    #[rustfmt::skip]
    let expected = [
        0, 0, 0, 100,
        0, 0, 0, 100,
        0, 100, 0, 0,
    ];
    assert_loads_as(&saved.yaml, &expected);
}

#[test]
fn scale_round_trip_gives_the_values_back() {
    let mut map = OccupancyMap::new(103, 1, 0.1, [1.0, -2.0, 0.5]);
    map.data = (-1..=101).collect();
    // With thresholds 0 and 1, p is the occupancy itself: GraphicsMagick's truncation puts
    // 100 p in [v, v + 0.4), and rint gives v back exactly.
    let options = SaveOptions {
        mode: MapMode::Scale,
        occupied_thresh: 1.0,
        free_thresh: 0.0,
        comment: None,
    };
    let dir = scratch("scale_round_trip");
    let saved = save_map(&dir.join("gradient"), &map, &options).unwrap();
    let loaded = load_map(&saved.yaml, LoadSemantics::Nav2).unwrap();
    assert_eq!(loaded.origin, [1.0, -2.0, 0.5]);
    assert_eq!(loaded.data[0], -1, "unknown is transparent");
    assert_eq!(
        loaded.data[102], -1,
        "101 is out of range, saved as unknown"
    );
    for v in 0..=100i8 {
        let back = loaded.data[(v + 1) as usize];
        assert!((back - v).abs() <= 1, "{v} came back as {back}");
        assert_eq!(back, v);
    }

    // With map_saver's default thresholds the gradient is re-spread between them.
    let saved = save_map(
        &dir.join("default"),
        &map,
        &SaveOptions {
            mode: MapMode::Scale,
            ..SaveOptions::default()
        },
    )
    .unwrap();
    let loaded = load_map(&saved.yaml, LoadSemantics::Nav2).unwrap();
    let at = |v: i8| loaded.data[(v + 1) as usize];
    assert_eq!(
        (at(0), at(25), at(26), at(50), at(64), at(65), at(100)),
        (0, 0, 3, 63, 98, 100, 100)
    );
}

#[test]
fn raw_round_trip_is_exact() {
    let mut map = OccupancyMap::new(11, 11, 0.025, [0.0; 3]);
    map.data = (-1..=100)
        .chain([
            -128, 127, -2, 101, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        ])
        .collect();
    assert_eq!(map.data.len(), 121);
    let dir = scratch("raw_round_trip");
    let options = SaveOptions {
        mode: MapMode::Raw,
        ..SaveOptions::default()
    };
    let saved = save_map(&dir.join("raw"), &map, &options).unwrap();
    let expected: Vec<i8> = map
        .data
        .iter()
        .map(|&v| if (0..=100).contains(&v) { v } else { -1 })
        .collect();
    // ROS 1 reads the unknown byte 255 as -1 too (it wraps instead of clamping).
    assert_loads_as(&saved.yaml, &expected);
}

// ---------------------------------------------------------------------------------------------
// Loading

/// A map as ROS 1's map_saver writes it: `# CREATOR` line in the PGM, `%f` floats in the YAML.
fn ros1_map(dir: &Path) -> PathBuf {
    let mut pgm = b"P5\n# CREATOR: map_saver.cpp 0.050 m/pix\n3 2\n255\n".to_vec();
    pgm.extend_from_slice(&[0, 254, 205, 205, 0, 254]);
    write(dir, "ros1.pgm", &pgm);
    write(
        dir,
        "ros1.yaml",
        b"image: ros1.pgm\nresolution: 0.050000\norigin: [-10.000000, -10.000000, 0.000000]\n\
          negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n\n",
    )
}

#[test]
fn loads_a_ros1_map_saver_map() {
    let dir = scratch("ros1_map");
    let yaml = ros1_map(&dir);
    let metadata = read_map_yaml(&yaml).unwrap();
    assert_eq!(
        metadata,
        MapMetadata {
            image: "ros1.pgm".into(),
            mode: MapMode::Trinary,
            resolution: 0.05,
            origin: [-10.0, -10.0, 0.0],
            negate: false,
            occupied_thresh: 0.65,
            free_thresh: 0.196,
        }
    );
    for semantics in [LoadSemantics::Nav2, LoadSemantics::Ros1] {
        let map = load_map(&yaml, semantics).unwrap();
        assert_eq!((map.width, map.height, map.resolution), (3, 2, 0.05));
        assert_eq!(map.origin, [-10.0, -10.0, 0.0]);
        // Bottom row first: the last image row (205, 0, 254), then (0, 254, 205).
        assert_eq!(map.data, [-1, 100, 0, 100, 0, -1], "{semantics:?}");
        assert_eq!(map.cell(0, 1), Some(100));
        assert_eq!(map.cell(3, 0), None);
    }
}

#[test]
fn ros1_and_nav2_differ_on_a_pixel_exactly_at_a_threshold() {
    // Black is p = 1 and white p = 0 in both; thresholds 1 and 0 are then hit exactly.
    let yaml = b"image: t.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 0\n\
                 occupied_thresh: 1.0\nfree_thresh: 0.0\n";
    let metadata = decode_map_yaml("t.yaml", yaml).unwrap();
    let pgm = pgm_row(&[0, 255, 128]);
    let nav2 = decode_map_image("t.pgm", &pgm, &metadata, LoadSemantics::Nav2).unwrap();
    let ros1 = decode_map_image("t.pgm", &pgm, &metadata, LoadSemantics::Ros1).unwrap();
    assert_eq!(nav2.data, [100, 0, -1], "Nav2: p >= occupied, p <= free");
    assert_eq!(ros1.data, [-1, -1, -1], "ROS 1: p > occupied, p < free");
}

#[test]
fn scale_mode_formulas_of_nav2_and_ros1() {
    let m = metadata(MapMode::Scale, 0.65, 0.196);
    let pgm = pgm_row(&[128, 100, 180, 0, 255]);
    let nav2 = decode_map_image("s.pgm", &pgm, &m, LoadSemantics::Nav2).unwrap();
    let ros1 = decode_map_image("s.pgm", &pgm, &m, LoadSemantics::Ros1).unwrap();
    // Nav2: rint(100 (p - free) / (occ - free)), p = 1 - x/255: 66.53, 90.71, 21.61.
    assert_eq!(nav2.data, [67, 91, 22, 100, 0]);
    // ROS 1: 99 (p - free) / (occ - free) truncated: 65.86, 89.81, 21.40.
    assert_eq!(ros1.data, [65, 89, 21, 100, 0]);
}

#[test]
fn raw_mode_ros1_wraps_and_nav2_clamps_to_unknown() {
    let m = metadata(MapMode::Raw, 0.65, 0.196);
    let pgm = pgm_row(&[0, 42, 100, 101, 205, 255]);
    let nav2 = decode_map_image("r.pgm", &pgm, &m, LoadSemantics::Nav2).unwrap();
    let ros1 = decode_map_image("r.pgm", &pgm, &m, LoadSemantics::Ros1).unwrap();
    assert_eq!(nav2.data, [0, 42, 100, -1, -1, -1]);
    assert_eq!(ros1.data, [0, 42, 100, 101, -51, -1]);
}

#[test]
fn negate_makes_dark_pixels_free() {
    let mut m = metadata(MapMode::Trinary, 0.65, 0.196);
    m.negate = true;
    let pgm = pgm_row(&[0, 254, 205]);
    for semantics in [LoadSemantics::Nav2, LoadSemantics::Ros1] {
        let map = decode_map_image("n.pgm", &pgm, &m, semantics).unwrap();
        assert_eq!(map.data, [0, 100, 100], "{semantics:?}");
    }
    // The YAML may say `negate: true` or `negate: 1`.
    for negate in ["true", "1", "\"1\""] {
        let yaml = format!(
            "image: n.pgm\nresolution: 1\norigin: [0, 0, 0]\nnegate: {negate}\n\
             occupied_thresh: 0.65\nfree_thresh: 0.196\n"
        );
        assert!(decode_map_yaml("n.yaml", yaml.as_bytes()).unwrap().negate);
    }
}

#[test]
fn colour_alpha_palette_and_16_bit_pngs_are_read() {
    use png::{BitDepth, ColorType};
    let m = metadata(MapMode::Trinary, 0.65, 0.196);
    let nav2 = |bytes: &[u8]| {
        decode_map_image("c.png", bytes, &m, LoadSemantics::Nav2)
            .unwrap()
            .data
    };
    let ros1 = |bytes: &[u8]| {
        decode_map_image("c.png", bytes, &m, LoadSemantics::Ros1)
            .unwrap()
            .data
    };

    // RGB: the average of the channels. Red (85) is p = 0.667 -> occupied; (254, 254, 255)
    // averages 254.33 -> free; (205, 205, 205) unknown.
    let rgb = png_bytes(
        3,
        1,
        ColorType::Rgb,
        BitDepth::Eight,
        &[255, 0, 0, 254, 254, 255, 205, 205, 205],
    );
    assert_eq!(nav2(&rgb), [100, 0, -1]);
    assert_eq!(ros1(&rgb), [100, 0, -1]);

    // Grey + alpha: Nav2 makes any transparency unknown; ROS 1 averages alpha in (trinary).
    let grey_alpha = png_bytes(
        3,
        1,
        ColorType::GrayscaleAlpha,
        BitDepth::Eight,
        &[60, 255, 60, 254, 254, 0],
    );
    assert_eq!(nav2(&grey_alpha), [100, -1, -1]);
    // ROS 1: (3 * 60 + 255) / 4 = 108.75 -> p = 0.574 (unknown); (3 * 60 + 254) / 4 likewise;
    // (3 * 254 + 0) / 4 = 190.5 -> p = 0.253 (unknown).
    assert_eq!(ros1(&grey_alpha), [-1, -1, -1]);

    // 16-bit grey: 0 and 65535 are black and white.
    let wide = png_bytes(
        2,
        1,
        ColorType::Grayscale,
        BitDepth::Sixteen,
        &[0, 0, 255, 255],
    );
    assert_eq!(nav2(&wide), [100, 0]);

    // 1-bit grey (expanded to 0 and 255) and a palette image.
    let bits = png_bytes(8, 1, ColorType::Grayscale, BitDepth::One, &[0b1010_0000]);
    assert_eq!(nav2(&bits), [0, 100, 0, 100, 100, 100, 100, 100]);
    let mut bytes = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut bytes, 3, 1);
        encoder.set_color(ColorType::Indexed);
        encoder.set_depth(BitDepth::Eight);
        encoder.set_palette(vec![0, 0, 0, 254, 254, 254, 205, 205, 205]);
        let mut writer = encoder.write_header().unwrap();
        writer.write_image_data(&[2, 1, 0]).unwrap();
    }
    assert_eq!(nav2(&bytes), [-1, 0, 100]);
}

#[test]
fn ascii_pgm_and_binary_ppm_are_read() {
    let m = metadata(MapMode::Trinary, 0.65, 0.196);
    let p2 = b"P2\n# a comment\n3 2\n# another\n15\n0 15 7\n15 0\n# inside\n0\n";
    let map = decode_map_image("a.pgm", p2, &m, LoadSemantics::Nav2).unwrap();
    // maxval 15: 15 is white, 7 is 119/255 -> p = 0.53 (unknown).
    assert_eq!(map.data, [0, 100, 100, 100, 0, -1]);

    let mut p6 = b"P6 2 1 255\n".to_vec();
    p6.extend_from_slice(&[0, 0, 0, 255, 255, 255]);
    let map = decode_map_image("c.ppm", &p6, &m, LoadSemantics::Nav2).unwrap();
    assert_eq!(map.data, [100, 0]);

    // Two-byte samples for maxval > 255.
    let mut wide = b"P5 2 1 65535\n".to_vec();
    wide.extend_from_slice(&[0, 0, 255, 255]);
    let map = decode_map_image("w.pgm", &wide, &m, LoadSemantics::Nav2).unwrap();
    assert_eq!(map.data, [100, 0]);
}

#[test]
fn yaml_with_mode_block_origin_quotes_and_unknown_keys() {
    let yaml = b"# saved by hand\nimage: \"scaled.png\"\nmode: scale\nresolution: '0.1'\n\
                 origin:\n  - 1.5\n  - -2\n  - 0.25\nnegate: false\noccupied_thresh: 0.9\n\
                 free_thresh: 0.1\nextra: {nested: [1, 2]}\nsampling_rate: 3\n";
    let metadata = decode_map_yaml("scaled.yaml", yaml).unwrap();
    assert_eq!(
        metadata,
        MapMetadata {
            image: "scaled.png".into(),
            mode: MapMode::Scale,
            resolution: 0.1,
            origin: [1.5, -2.0, 0.25],
            negate: false,
            occupied_thresh: 0.9,
            free_thresh: 0.1,
        }
    );
}

#[test]
fn image_paths_are_relative_to_the_yaml_folder() {
    let yaml = Path::new("/maps/site/office.yaml");
    assert_eq!(
        image_path(yaml, "office.pgm"),
        Path::new("/maps/site/office.pgm")
    );
    assert_eq!(
        image_path(yaml, "img/office.pgm"),
        Path::new("/maps/site/img/office.pgm")
    );
    assert_eq!(
        image_path(yaml, "/data/office.pgm"),
        Path::new("/data/office.pgm")
    );
    assert_eq!(
        image_path(Path::new("office.yaml"), "office.pgm"),
        Path::new("office.pgm")
    );
}

// ---------------------------------------------------------------------------------------------
// Errors

const GOOD_YAML: &str = "image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n\
                         occupied_thresh: 0.65\nfree_thresh: 0.196\n";

#[test]
fn missing_keys_are_named() {
    for key in [
        "image",
        "resolution",
        "origin",
        "negate",
        "occupied_thresh",
        "free_thresh",
    ] {
        let yaml: String = GOOD_YAML
            .lines()
            .filter(|line| !line.starts_with(&format!("{key}:")))
            .map(|line| format!("{line}\n"))
            .collect();
        let err = decode_map_yaml("maps/office.yaml", yaml.as_bytes()).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!("maps/office.yaml: missing required key `{key}`")
        );
        assert_eq!(
            (err.file(), err.key()),
            (Some("maps/office.yaml"), Some(key))
        );
    }
    // An empty file, or one with only comments, misses the first key.
    for text in ["", "# nothing\n"] {
        let err = decode_map_yaml("e.yaml", text.as_bytes()).unwrap_err();
        assert!(
            matches!(err.kind(), NavMapErrorKind::MissingKey { key: "image" }),
            "{err}"
        );
    }
}

#[test]
fn ill_typed_values_are_named_with_line_and_value() {
    let cases = [
        (
            "origin: [0, 0, 0]",
            "origin: [1, 2]",
            "o.yaml:3: origin: [1, 2] is invalid (expected a list of exactly 3 numbers [x, y, yaw])",
        ),
        (
            "origin: [0, 0, 0]",
            "origin: [1, 2, x]",
            "o.yaml:3: origin: [1, 2, \"x\"] is invalid (expected a list of exactly 3 numbers [x, y, yaw])",
        ),
        (
            "resolution: 0.05",
            "resolution: fine",
            "o.yaml:2: resolution: \"fine\" is invalid (expected a finite number)",
        ),
        (
            "resolution: 0.05",
            "resolution: -0.05",
            "o.yaml:2: resolution: -0.05 is invalid (expected a positive number)",
        ),
        (
            "resolution: 0.05",
            "resolution: .nan",
            "o.yaml:2: resolution: NaN is invalid (expected a finite number)",
        ),
        (
            "negate: 0",
            "negate: 0.0",
            "o.yaml:4: negate: 0.0 is invalid (expected 0, 1, true or false)",
        ),
        (
            "image: map.pgm",
            "image: [a.pgm]",
            "o.yaml:1: image: [\"a.pgm\"] is invalid (expected a file name)",
        ),
        (
            "free_thresh: 0.196",
            "free_thresh:",
            "o.yaml:6: free_thresh: null is invalid (expected a finite number)",
        ),
        (
            "free_thresh: 0.196",
            "free_thresh: 0.196\nmode: Trinary",
            "o.yaml:7: mode: \"Trinary\" is invalid (expected trinary, scale or raw)",
        ),
    ];
    for (from, to, expected) in cases {
        let yaml = GOOD_YAML.replace(from, to);
        let err = decode_map_yaml("o.yaml", yaml.as_bytes()).unwrap_err();
        assert_eq!(err.to_string(), expected);
        assert!(err.line().is_some() && err.key().is_some());
    }
}

#[test]
fn yaml_syntax_errors_and_non_mappings_name_the_line() {
    let err = decode_map_yaml("s.yaml", b"image: map.pgm\norigin: [1, 2\n").unwrap_err();
    assert!(matches!(err.kind(), NavMapErrorKind::Yaml { .. }), "{err}");
    assert_eq!(err.file(), Some("s.yaml"));
    assert!(err.line().is_some(), "{err}");
    assert!(err.to_string().starts_with("s.yaml:"), "{err}");

    let cases = [
        (
            "- a\n- b\n",
            "s.yaml:1: not a map_server YAML file: the top level is not a mapping of keys to values",
        ),
        (
            "just text\n",
            "s.yaml:1: not a map_server YAML file: the top level is not a mapping of keys to values",
        ),
        (
            "image: a\nimage: b\n",
            "s.yaml:2: not a map_server YAML file: the key `image` appears twice",
        ),
        (
            "image: a\n---\nimage: b\n",
            "s.yaml:3: not a map_server YAML file: several YAML documents (a map file has one)",
        ),
    ];
    for (text, expected) in cases {
        let err = decode_map_yaml("s.yaml", text.as_bytes()).unwrap_err();
        assert!(
            matches!(err.kind(), NavMapErrorKind::Yaml { .. }),
            "{text:?}: {err}"
        );
        assert_eq!(err.to_string(), expected);
    }
}

#[test]
fn a_missing_image_names_the_image_and_the_yaml_file() {
    let dir = scratch("missing_image");
    let yaml = write(
        &dir,
        "m.yaml",
        GOOD_YAML.replace("map.pgm", "nowhere.pgm").as_bytes(),
    );
    let err = load_map(&yaml, LoadSemantics::Nav2).unwrap_err();
    let image = dir.join("nowhere.pgm").display().to_string();
    assert_eq!(err.file(), Some(image.as_str()));
    match err.kind() {
        NavMapErrorKind::ImageUnreadable { yaml: named, io } => {
            assert_eq!(named, &yaml.display().to_string());
            assert_eq!(io.kind(), std::io::ErrorKind::NotFound);
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(err.to_string().starts_with(&format!(
        "{image}: cannot read the image named in {}",
        yaml.display()
    )));

    let err = load_map(&dir.join("absent.yaml"), LoadSemantics::Nav2).unwrap_err();
    assert!(matches!(
        err.kind(),
        NavMapErrorKind::Io { action: "read", .. }
    ));
    assert_eq!(
        err.file(),
        Some(dir.join("absent.yaml").display().to_string().as_str())
    );
}

#[test]
fn malformed_pgm_files_are_rejected_with_the_file_name() {
    let dir = scratch("bad_pgm");
    let yaml = write(&dir, "map.yaml", GOOD_YAML.as_bytes());
    let image = dir.join("map.pgm");
    let load = |bytes: &[u8]| {
        fs::write(&image, bytes).unwrap();
        let err = load_map(&yaml, LoadSemantics::Nav2).unwrap_err();
        assert_eq!(
            err.file(),
            Some(image.display().to_string().as_str()),
            "{err}"
        );
        err
    };

    let err = load(b"P5\n4 3\n255\n\x00\x01\x02\x03\x04\x05\x06");
    assert_eq!(
        err.to_string(),
        format!(
            "{}: truncated image: the header announces 12 bytes of pixel data but only 7 follow",
            image.display()
        )
    );
    // (image, whether its error is of the right kind)
    type IsExpected = fn(&NavMapErrorKind) -> bool;
    let kinds: [(&[u8], IsExpected); 7] = [
        (b"P5\n4 3\n255\n\x00\x01\x02\x03\x04\x05\x06", |kind| {
            matches!(
                kind,
                NavMapErrorKind::TruncatedImage {
                    expected: 12,
                    actual: 7,
                    unit: "bytes"
                }
            )
        }),
        (b"P5\n2 1\n255\n\x00\x01\x02", |kind| {
            matches!(
                kind,
                NavMapErrorKind::TrailingData {
                    expected: 2,
                    actual: 3,
                    ..
                }
            )
        }),
        (b"P5\n4 3\n255", |kind| {
            matches!(kind, NavMapErrorKind::TruncatedImage { actual: 0, .. })
        }),
        (b"P5\n0 3\n255\n", |kind| {
            matches!(
                kind,
                NavMapErrorKind::ImageSize {
                    width: 0,
                    height: 3,
                    ..
                }
            )
        }),
        (b"P2\n2 2\n255\n1 2 3\n", |kind| {
            matches!(
                kind,
                NavMapErrorKind::TruncatedImage {
                    expected: 4,
                    actual: 3,
                    unit: "samples"
                }
            )
        }),
        (b"P5 100000 100000 255\n", |kind| {
            matches!(kind, NavMapErrorKind::ImageSize { .. })
        }),
        (b"", |kind| matches!(kind, NavMapErrorKind::EmptyImage)),
    ];
    for (bytes, is_expected) in kinds {
        let err = load(bytes);
        assert!(is_expected(err.kind()), "{err}");
    }
    // (image, the end of its message)
    let ends: [(&[u8], &str); 2] = [
        (
            b"P5\n4",
            "malformed PGM image: the header ends before the height",
        ),
        (
            b"P5\n99999999999 1 255\n",
            "malformed PGM image: width: 99999999999 is too large",
        ),
    ];
    for (bytes, end) in ends {
        let err = load(bytes);
        assert!(err.to_string().ends_with(end), "{err}");
    }
    // (image, a part of its message)
    let parts: [(&[u8], &str); 3] = [
        (b"P5\n4x3 255\n", "width: \"4x3\" is not a number"),
        (b"P5\n2 1\n0\n\x00\x00", "maxval 0 is not in 1..=65535"),
        (b"P5\n2 1\n15\n\x00\x10", "sample 16 of pixel (1, 0)"),
    ];
    for (bytes, part) in parts {
        let err = load(bytes);
        assert!(err.to_string().contains(part), "{err}");
    }
}

#[test]
fn wrong_magic_and_unsupported_formats_are_named() {
    let m = metadata(MapMode::Trinary, 0.65, 0.196);
    let cases: [(&[u8], &str); 5] = [
        (
            b"XY\n4 3\n255\n",
            "unknown (the file starts with \"XY\\n4 3\\n2\")",
        ),
        (b"P4\n8 1\n\x00", "PBM bitmap (P1/P4)"),
        (b"BM\x00\x00", "BMP"),
        (b"\xff\xd8\xff\xe0", "JPEG"),
        (b"P7\nWIDTH 1\n", "PAM (P7)"),
    ];
    for (bytes, format) in cases {
        let err = decode_map_image("x.img", bytes, &m, LoadSemantics::Nav2).unwrap_err();
        match err.kind() {
            NavMapErrorKind::UnsupportedImageFormat { format: found } => assert_eq!(found, format),
            other => panic!("unexpected {other:?}"),
        }
        assert!(
            err.to_string()
                .starts_with("x.img: unsupported image format: "),
            "{err}"
        );
    }
}

#[test]
fn invalid_and_truncated_pngs_are_rejected() {
    let m = metadata(MapMode::Trinary, 0.65, 0.196);
    let good = png_bytes(
        2,
        2,
        png::ColorType::Grayscale,
        png::BitDepth::Eight,
        &[0, 255, 255, 0],
    );
    assert!(decode_map_image("g.png", &good, &m, LoadSemantics::Nav2).is_ok());

    // Bit depth 3 does not exist (IHDR byte 24), even with a correct CRC.
    let mut bad_depth = good.clone();
    bad_depth[24] = 3;
    let crc = crc32fast::hash(&bad_depth[12..29]);
    bad_depth[29..33].copy_from_slice(&crc.to_be_bytes());
    let err = decode_map_image("d.png", &bad_depth, &m, LoadSemantics::Nav2).unwrap_err();
    assert!(
        matches!(
            err.kind(),
            NavMapErrorKind::MalformedImage { format: "PNG", .. }
        ),
        "{err}"
    );
    assert!(
        err.to_string().starts_with("d.png: malformed PNG image: "),
        "{err}"
    );

    // Cut inside the image data.
    let cut = &good[..good.len() - 20];
    let err = decode_map_image("t.png", cut, &m, LoadSemantics::Nav2).unwrap_err();
    assert!(
        matches!(
            err.kind(),
            NavMapErrorKind::MalformedImage { format: "PNG", .. }
        ),
        "{err}"
    );
    assert_eq!(err.file(), Some("t.png"));
}

#[test]
fn invalid_maps_options_and_paths_are_rejected_on_save() {
    let dir = scratch("bad_save");
    let base = dir.join("m");
    let mut short = four_by_three();
    short.data.pop();
    let err = save_map(&base, &short, &SaveOptions::default()).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "{}: invalid map: data has 11 cells but width x height = 4 x 3 = 12",
            dir.join("m.pgm").display()
        )
    );

    let empty = OccupancyMap::new(0, 3, 0.05, [0.0; 3]);
    assert!(matches!(
        save_map(&base, &empty, &SaveOptions::default())
            .unwrap_err()
            .kind(),
        NavMapErrorKind::InvalidMap { .. }
    ));
    let mut nan = four_by_three();
    nan.origin[1] = f64::NAN;
    assert!(matches!(
        encode_map_yaml("m.pgm", &nan, &SaveOptions::default())
            .unwrap_err()
            .kind(),
        NavMapErrorKind::InvalidMap { .. }
    ));

    for (occupied_thresh, free_thresh) in [(0.5, 0.5), (0.65, -0.1), (1.5, 0.25), (f64::NAN, 0.25)]
    {
        let options = SaveOptions {
            occupied_thresh,
            free_thresh,
            ..SaveOptions::default()
        };
        let err = encode_map_image(&four_by_three(), &options).unwrap_err();
        assert!(
            matches!(err.kind(), NavMapErrorKind::InvalidOptions { .. }),
            "{err}"
        );
    }

    let err = save_map(Path::new("/"), &four_by_three(), &SaveOptions::default()).unwrap_err();
    assert!(
        matches!(err.kind(), NavMapErrorKind::InvalidPath { .. }),
        "{err}"
    );
    let err = save_map(
        &dir.join("no/such/folder/m"),
        &four_by_three(),
        &SaveOptions::default(),
    )
    .unwrap_err();
    assert!(matches!(err.kind(), NavMapErrorKind::Io { .. }), "{err}");
    assert_eq!(
        err.file(),
        Some(
            dir.join("no/such/folder/m.pgm")
                .display()
                .to_string()
                .as_str()
        )
    );
    // Nothing was written for any of these.
    assert_eq!(fs::read_dir(&dir).unwrap().count(), 0);
}

#[test]
fn damaged_files_give_errors_never_panics() {
    let m = metadata(MapMode::Scale, 0.65, 0.196);
    let map = four_by_three();
    let scale = SaveOptions {
        mode: MapMode::Scale,
        ..SaveOptions::default()
    };
    let images = [
        encode_map_image(&map, &SaveOptions::default()).unwrap(),
        encode_map_image(&map, &scale).unwrap(),
        b"P2\n# c\n2 2\n255\n0 1\n2 3\n".to_vec(),
        b"P6 1 1 65535\n\x00\x01\x02\x03\x04\x05".to_vec(),
    ];
    let replacements = [0u8, 1, 9, b'\n', b'#', b'0', b'9', b' ', 0x7f, 0xff];
    let mut outcomes = [0usize; 2];
    for image in &images {
        for pos in 0..image.len() {
            for semantics in [LoadSemantics::Nav2, LoadSemantics::Ros1] {
                let cut = &image[..pos];
                outcomes[decode_map_image("d", cut, &m, semantics).is_ok() as usize] += 1;
                for &b in &replacements {
                    let mut damaged = image.clone();
                    damaged[pos] = b;
                    outcomes[decode_map_image("d", &damaged, &m, semantics).is_ok() as usize] += 1;
                }
            }
        }
    }
    // Most damage is detected (PNG has checksums); nothing panics.
    assert!(outcomes[0] > outcomes[1], "{outcomes:?}");

    let yaml = OFFICE_YAML.as_bytes();
    for pos in 0..yaml.len() {
        let _ = decode_map_yaml("d.yaml", &yaml[..pos]);
        for &b in &[
            b'[', b']', b':', b'"', b'\'', b'\n', b' ', b'-', b'&', b'*', b'!', 0xff,
        ] {
            let mut damaged = yaml.to_vec();
            damaged[pos] = b;
            let _ = decode_map_yaml("d.yaml", &damaged);
        }
    }
}
