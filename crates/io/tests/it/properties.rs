//! Property tests of every reader (proptest, seeded so that a failure reproduces): arbitrary
//! bytes and mutations of real files are an `Err` or an `Ok`, never a panic, and what a writer
//! writes, its reader reads back unchanged.
//!
//! The number of cases is small enough for CI (seconds); set `PROPTEST_CASES` for a deeper
//! run, e.g. `PROPTEST_CASES=100000 cargo test -p chronomap-io --test it properties`.

use chronomap_grid::AnyGrid;
use chronomap_io::grid_file::{decode_grid, encode_grid};
use chronomap_io::laser_text::{
    MAX_ANGLE_RAD, MAX_LENGTH_M, read_keyframes_from, read_odometry_from, read_scans_from,
};
use chronomap_io::model_file::{decode_any_model, decode_model, encode_model};
use chronomap_io::ply::{PlyFormat, decode_ply, encode_ply};
use chronomap_io::topo_files::{
    RouteEdgeMetadata, decode_route_geojson, decode_tmap2, encode_edge_file, encode_route_geojson,
    encode_tmap2, read_edge_file_from,
};
use chronomap_io::{decode_map_yaml, read_events_from, read_frame_list_from, read_pairs_from};
use chronomap_lidar::classifier::{LoopClassifier, MODEL_KIND};
use chronomap_registration::Cloud;
use chronomap_testutil::{mutate, proptest_config, repo_path};
use chronomap_topo::TopoMap;
use proptest::prelude::*;

/// A reader of bytes that drops what it read: it must return, not panic, on any input.
type Reader = fn(&[u8]);

/// Every reader of bytes, by name.
fn readers() -> Vec<(&'static str, Reader)> {
    vec![
        ("time series", |b| drop(read_pairs_from("x.txt", b))),
        ("edge file", |b| drop(read_edge_file_from("x.data", b))),
        ("events", |b| drop(read_events_from("x.txt", b))),
        ("frame list", |b| {
            drop(read_frame_list_from("frames.txt", b))
        }),
        ("map YAML", |b| drop(decode_map_yaml("map.yaml", b))),
        ("tmap2", |b| drop(decode_tmap2("map.tmap2.yaml", b))),
        ("route GeoJSON", |b| {
            drop(decode_route_geojson("graph.geojson", b))
        }),
        ("model file", |b| drop(decode_any_model(b))),
        ("grid file", |b| drop(decode_grid(b))),
        ("PLY cloud", |b| drop(decode_ply("cloud.ply", b))),
        ("laser scans", |b| drop(read_scans_from("scans.txt", b))),
        ("keyframes", |b| {
            drop(read_keyframes_from("keyframes.txt", b))
        }),
        ("odometry", |b| drop(read_odometry_from("odometry.txt", b))),
        // As `chronomap lidar detect` reads it: the model file, then its own checks.
        ("loop classifier", |b| {
            if let Ok((_, c)) = decode_model::<LoopClassifier>(b) {
                drop(c.validate());
            }
        }),
    ]
}

/// The first `lines` lines of a bundled (compressed) text file.
fn head_of(path: &str, lines: usize) -> Vec<u8> {
    let mut text = String::new();
    std::io::Read::read_to_string(
        &mut chronomap_io::open_data_file(chronomap_testutil::data_path(path)).unwrap(),
        &mut text,
    )
    .unwrap();
    let head: Vec<&str> = text.lines().take(lines).collect();
    (head.join("\n") + "\n").into_bytes()
}

/// The bundled small_gicp source cloud cut to its first `n` vertices (binary, float x, y, z
/// and intensity), its header's count changed to match.
fn ply_head(n: usize) -> Vec<u8> {
    let mut bytes = Vec::new();
    std::io::Read::read_to_end(
        &mut chronomap_io::open_data_file(chronomap_testutil::data_path(
            "registration_small_gicp/source.ply.xz",
        ))
        .unwrap(),
        &mut bytes,
    )
    .unwrap();
    let body = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = String::from_utf8_lossy(&bytes[..body])
        .replace("element vertex 69792", &format!("element vertex {n}"));
    let mut out = header.into_bytes();
    out.extend_from_slice(&bytes[body..body + 16 * n]);
    out
}

/// Real files of each format, to mutate.
fn seeds() -> Vec<Vec<u8>> {
    let mut seeds = vec![
        b"1451865600 0\n1451865660 1\n1451865720 1\n".to_vec(),
        b"1404836638 32.1 1\n1404836900 40.0 0\n".to_vec(),
        b"1495618000.5 1.25 -3.5\n1495618001 2 3\n".to_vec(),
        b"1451865600 map.yaml\n1451866200 map.yaml\n".to_vec(),
        b"image: map.pgm\nresolution: 0.05\norigin: [-1.0, 2.0, 0.0]\nnegate: 0\n\
          occupied_thresh: 0.65\nfree_thresh: 0.196\n"
            .to_vec(),
    ];
    let mut map = TopoMap::new();
    map.add_node("Station", Some([0.0, 0.0, 0.0])).unwrap();
    map.add_node("Kitchen", Some([4.0, 1.5, 1.0])).unwrap();
    map.add_node("Lab", None).unwrap();
    map.add_edge("Station_Kitchen", "Station", "Kitchen")
        .unwrap();
    map.add_edge("Kitchen_Lab", "Kitchen", "Lab").unwrap();
    seeds.push(
        encode_tmap2(&map, "witham", "01-01-2026_00-00-00")
            .unwrap()
            .into_bytes(),
    );
    seeds.push(
        encode_route_geojson(
            &map,
            &[
                RouteEdgeMetadata::new(0.9, 30.0).with_time_interval(Some((21.5, 44.0)), 0.9),
                RouteEdgeMetadata::new(0.5, 12.0),
            ],
        )
        .unwrap()
        .into_bytes(),
    );
    // A real model file and a real grid file.
    seeds.push(std::fs::read(repo_path("tests/hostile/door.cmm")).unwrap());
    let geometry = chronomap_grid::GridGeometry::planar(3, 2, 0.5, [0.0, 0.0]).unwrap();
    let mut grid =
        chronomap_grid::FremenGrid::new(geometry, chronomap_grid::GridConfig::default()).unwrap();
    for k in 0..48u32 {
        let open = if k % 24 < 12 { 0 } else { 100 };
        grid.observe_occupancy(1e9 + 1800.0 * f64::from(k), &[open, 100, 0, 0, open, 100])
            .unwrap();
    }
    seeds.push(encode_grid(&AnyGrid::State(Box::new(grid))).unwrap());
    // The lidar files: a real cloud, laser log, keyframes, odometry and loop classifier.
    seeds.push(ply_head(64));
    seeds.push(head_of("malaga_laser_2006/scans.txt.xz", 3));
    seeds.push(head_of("malaga_laser_2006/keyframes_slam.txt.xz", 3));
    seeds.push(head_of("malaga_laser_2006/odometry.txt.xz", 20));
    seeds.push(std::fs::read(repo_path("tests/hostile/lidar_classifier.cml")).unwrap());
    seeds
}

proptest! {
    #![proptest_config(proptest_config(256, 20_261_203))]

    #[test]
    fn arbitrary_bytes_never_panic_a_reader(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        for (_, read) in readers() {
            read(&bytes);
        }
    }

    #[test]
    fn mutated_real_files_never_panic_a_reader(
        seed in 0usize..16,
        edits in proptest::collection::vec((any::<usize>(), any::<u8>(), any::<u8>()), 1..8),
    ) {
        let seeds = seeds();
        let bytes = mutate(seeds[seed % seeds.len()].clone(), &edits);
        for (_, read) in readers() {
            read(&bytes);
        }
    }

    #[test]
    fn time_series_round_trip(
        steps in proptest::collection::vec((0u32..100_000, 0.0f64..=1.0), 1..64),
        start in 0u32..2_000_000_000,
    ) {
        let mut t = f64::from(start);
        let mut text = String::new();
        let mut expected = Vec::new();
        for (dt, v) in steps {
            t += f64::from(dt);
            // Rust prints the shortest text that reads back as the same f64.
            text.push_str(&format!("{t} {v}\n"));
            expected.push((t, v));
        }
        let series = read_pairs_from("x.txt", text.as_bytes()).unwrap();
        prop_assert_eq!(series.len(), expected.len());
        for (i, (t, v)) in expected.into_iter().enumerate() {
            prop_assert_eq!((series.times[i], series.values[i]), (t, v));
        }
    }

    #[test]
    fn edge_files_round_trip(
        attempts in proptest::collection::vec((0u32..1_000_000, 0.0f64..1e6, any::<bool>()), 1..32),
    ) {
        let mut t = 1.4e9;
        let rows: Vec<chronomap_io::topo_files::EdgeAttempt> = attempts
            .into_iter()
            .map(|(dt, duration, success)| {
                t += f64::from(dt);
                chronomap_io::topo_files::EdgeAttempt { time: t, duration_secs: duration, success }
            })
            .collect();
        let read = read_edge_file_from("x.data", encode_edge_file(&rows).as_bytes()).unwrap();
        prop_assert_eq!(read, rows);
    }

    #[test]
    fn route_geojson_and_tmap2_round_trip(
        poses in proptest::collection::vec((-1e4f64..1e4, -1e4f64..1e4), 1..12),
        edges in proptest::collection::vec((any::<usize>(), any::<usize>()), 0..24),
        interval in proptest::option::of((0.0f64..1e4, 0.0f64..1e4, 0.01f64..=1.0)),
    ) {
        let mut map = TopoMap::new();
        for (i, &(x, y)) in poses.iter().enumerate() {
            map.add_node(&format!("N{i}"), Some([x, y, 0.0])).unwrap();
        }
        let n = poses.len();
        let mut added = std::collections::HashSet::new();
        for (a, b) in edges {
            let (a, b) = (a % n, b % n);
            if a != b && added.insert((a, b)) {
                map.add_edge(&format!("N{a}_N{b}"), &format!("N{a}"), &format!("N{b}")).unwrap();
            }
        }
        // With or without an interval of the time taken (its bounds need not hold the time).
        let interval = interval.map(|(a, b, coverage)| ((a.min(b), a.max(b)), coverage));
        let metadata = RouteEdgeMetadata::new(0.5, 10.0)
            .with_time_interval(interval.map(|i| i.0), interval.map_or(0.9, |i| i.1));
        let json = encode_route_geojson(&map, &vec![metadata; map.edges().len()]).unwrap();
        let value: serde_json::Value = serde_json::from_str(&json).unwrap();
        for feature in value["features"].as_array().unwrap() {
            if feature["geometry"]["type"] == "MultiLineString" {
                let m = &feature["properties"]["metadata"];
                let bounds =
                    m["abs_time_taken_lower"].as_f64().zip(m["abs_time_taken_upper"].as_f64());
                prop_assert_eq!(bounds, interval.map(|i| i.0));
                prop_assert_eq!(m["abs_time_taken_coverage"].as_f64(), interval.map(|i| i.1));
            }
        }
        let from_json = decode_route_geojson("g.geojson", json.as_bytes()).unwrap();
        let yaml = encode_tmap2(&map, "m", "01-01-2026_00-00-00").unwrap();
        let from_yaml = decode_tmap2("m.tmap2.yaml", yaml.as_bytes()).unwrap().map;
        for read in [&from_json, &from_yaml] {
            prop_assert_eq!(read.nodes().len(), map.nodes().len());
            for (a, b) in read.nodes().iter().zip(map.nodes()) {
                prop_assert_eq!(&a.name, &b.name);
                let (pa, pb) = (a.pose.unwrap(), b.pose.unwrap());
                prop_assert_eq!([pa[0], pa[1]], [pb[0], pb[1]]);
            }
            // tmap2 keeps edges under their start node, so compare them as a set.
            let ends = |m: &TopoMap| {
                let mut e: Vec<_> = m.edges().iter().map(|e| (e.id.clone(), e.from, e.to)).collect();
                e.sort();
                e
            };
            prop_assert_eq!(ends(read), ends(&map));
        }
    }

    #[test]
    fn ply_clouds_round_trip_in_every_format(
        points in proptest::collection::vec((-1e6f64..1e6, -1e6f64..1e6, -1e3f64..1e3, 0.0f64..1e4), 1..64),
        with_intensity in any::<bool>(),
    ) {
        let xyz: Vec<[f64; 3]> = points.iter().map(|p| [p.0, p.1, p.2]).collect();
        let intensity = with_intensity.then(|| points.iter().map(|p| p.3).collect());
        let cloud = Cloud::new(xyz, intensity).unwrap();
        for format in [PlyFormat::Ascii, PlyFormat::BinaryLittleEndian, PlyFormat::BinaryBigEndian] {
            let back = decode_ply("c.ply", &encode_ply(&cloud, format)[..]).unwrap();
            prop_assert_eq!(&back, &cloud);
        }
    }

    #[test]
    fn odometry_within_the_bounds_reads_back_and_beyond_them_names_the_field(
        rows in proptest::collection::vec((0u32..1000, -2e6f64..2e6, -2e6f64..2e6, -2e4f64..2e4), 1..32),
    ) {
        let mut t = 1.1e9;
        let mut text = String::new();
        let mut first_bad = None;
        for (line, &(dt, dx, dy, dyaw)) in rows.iter().enumerate() {
            t += f64::from(dt);
            text.push_str(&format!("{t} {dx} {dy} {dyaw}\n"));
            let bad = [
                ("dx", dx.abs() > MAX_LENGTH_M),
                ("dy", dy.abs() > MAX_LENGTH_M),
                ("dyaw", dyaw.abs() > MAX_ANGLE_RAD),
            ];
            if first_bad.is_none()
                && let Some((field, _)) = bad.iter().find(|b| b.1)
            {
                first_bad = Some((line + 1, *field));
            }
        }
        match (read_odometry_from("o.txt", text.as_bytes()), first_bad) {
            (Ok(read), None) => {
                for (o, &(_, dx, dy, dyaw)) in read.iter().zip(&rows) {
                    prop_assert_eq!((o.dx, o.dy, o.dyaw), (dx, dy, dyaw));
                }
            }
            (Err(e), Some((line, field))) => {
                prop_assert_eq!((e.line, e.field.as_str()), (Some(line), field));
                prop_assert!(e.reason.contains("is beyond ±"), "{}", e);
            }
            (got, expected) => prop_assert!(false, "{:?} for {:?}", got.map(|r| r.len()), expected),
        }
    }

    #[test]
    fn model_files_round_trip(
        observations in proptest::collection::vec(any::<bool>(), 8..200),
        order in 0usize..4,
    ) {
        use chronomap_core::{FremenConfig, FremenModel, TemporalModel};
        let mut model = FremenModel::new(FremenConfig::with_order(order)).unwrap();
        let times: Vec<f64> = (0..observations.len()).map(|k| 3600.0 * k as f64).collect();
        let values: Vec<f64> = observations.iter().map(|&o| f64::from(u8::from(o))).collect();
        model.observe(&times, &values).unwrap();
        let any = chronomap_models::AnyModel::Fremen(model.clone());
        let bytes = encode_model(any.kind(), &any).unwrap();
        let read = decode_any_model(&bytes).unwrap();
        let probe = [0.0, 1234.5, 86_400.0 * 3.5];
        prop_assert_eq!(read.predict_many(&probe), model.predict_many(&probe));
    }
}

#[test]
fn every_seed_is_read_by_its_own_reader() {
    // The mutation test starts from valid files: check that they are valid.
    let seeds = seeds();
    assert!(read_pairs_from("x.txt", &seeds[0][..]).is_ok());
    assert!(read_edge_file_from("x.data", &seeds[1][..]).is_ok());
    assert!(read_events_from("x.txt", &seeds[2][..]).is_ok());
    assert!(read_frame_list_from("frames.txt", &seeds[3][..]).is_ok());
    assert!(decode_map_yaml("map.yaml", &seeds[4]).is_ok());
    assert!(decode_tmap2("m.yaml", &seeds[5]).is_ok());
    assert!(decode_route_geojson("g.geojson", &seeds[6]).is_ok());
    assert!(decode_any_model(&seeds[7]).is_ok());
    assert!(decode_grid(&seeds[8]).is_ok());
    assert_eq!(decode_ply("c.ply", &seeds[9][..]).unwrap().len(), 64);
    assert_eq!(read_scans_from("s.txt", &seeds[10][..]).unwrap().len(), 2);
    assert_eq!(
        read_keyframes_from("k.txt", &seeds[11][..]).unwrap().len(),
        2
    );
    assert_eq!(
        read_odometry_from("o.txt", &seeds[12][..]).unwrap().len(),
        19
    );
    let (kind, classifier) = decode_model::<LoopClassifier>(&seeds[13]).unwrap();
    assert_eq!(kind, MODEL_KIND);
    classifier.validate().unwrap();
    // What the classifier's writer writes, its reader reads back.
    let again = encode_model(MODEL_KIND, &classifier).unwrap();
    assert_eq!(
        decode_model::<LoopClassifier>(&again).unwrap().1,
        classifier
    );
}
