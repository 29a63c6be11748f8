//! Topological-map files: the bundled Witham Wharf edge statistics, edge files and directories
//! with every kind of bad input (errors name file, line and field, never a panic), tmap2 YAML
//! round trips and PyYAML-style anchors, and Nav2 route-server GeoJSON.

use std::f64::consts::{FRAC_PI_2, PI};
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use chronomap_io::text::{DataError, DataErrorKind, Field};
use chronomap_io::topo_files::{
    RouteEdgeMetadata, RouteTimeInterval, TopoFileError, TopoFileErrorKind, decode_tmap2,
    encode_route_geojson, encode_tmap2, read_edge_directory, read_edge_directory_with_nodes,
    read_edge_file, read_edge_file_from, read_edge_files, read_route_geojson, read_tmap2,
    write_route_geojson, write_tmap2,
};
use chronomap_topo::map::{TopoError, TopoMap};
use serde_json::Value;

use crate::common::check;
use chronomap_testutil::data_path;

fn witham_edges() -> PathBuf {
    data_path("witham_topological_nav/edges")
}

/// A fresh scratch folder for one test.
fn scratch(test: &str) -> PathBuf {
    chronomap_testutil::scratch!("chronomap-io-topo", test)
}

/// A folder with the given files.
fn folder(test: &str, files: &[(&str, &str)]) -> PathBuf {
    let dir = scratch(test);
    for (name, text) in files {
        fs::write(dir.join(name), text).unwrap();
    }
    dir
}

fn edge_err(text: &str) -> DataError {
    read_edge_file_from("A_B.data", text.as_bytes()).expect_err(text)
}

/// Checks every `(text, line, field, message)` row: reading `text` as `A_B.data` fails on that
/// line and field with exactly that message.
fn check_edge_rows(rows: &[(&str, usize, Option<Field>, &str)]) {
    for &(text, line, field, message) in rows {
        check(&edge_err(text), "A_B.data", Some(line), field, message);
    }
}

/// Checks that `err` names `file` of `dir`, the line and the field, and that its message is
/// the file's path followed by `rest`.
fn check_in_dir(
    err: &DataError,
    dir: &Path,
    file: &str,
    line: Option<usize>,
    field: Option<Field>,
    rest: &str,
) {
    let path = dir.join(file).display().to_string();
    check(err, &path, line, field, &format!("{path}{rest}"));
}

// ---------------------------------------------------------------------------------------------
// The bundled Witham Wharf data

#[test]
fn witham_reads_61_edges_between_18_nodes_with_25316_attempts() {
    let stats = read_edge_directory(witham_edges()).unwrap();
    let (map, attempts) = (&stats.map, &stats.attempts);
    // 61 edge files; `path0.txt` lists a 62nd edge, WayPoint2_Printer, that has no file.
    assert_eq!(map.edges().len(), 61);
    assert_eq!(attempts.len(), 61);
    assert!(stats.attempts_of("WayPoint2_Printer").is_none());
    assert_eq!(map.nodes().len(), 18);
    let names: Vec<&str> = map.nodes().iter().map(|n| n.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "Aisle1",
            "Aisle2",
            "ChargingPoint",
            "GroundCentral",
            "Kitchen",
            "LabCentral",
            "LabDesk",
            "LabDoor1",
            "LabDoor2",
            "Printer",
            "Ramp1",
            "Ramp2",
            "Sofas",
            "Station",
            "WayPoint1",
            "WayPoint2",
            "WayPoint3",
            "WayPoint4",
        ]
    );
    assert!(map.nodes().iter().all(|n| n.pose.is_none()));
    // Edges in id order, each from its file name's first node to its second.
    assert_eq!(map.edges()[0].id, "Aisle1_Aisle2");
    assert!(map.edges().windows(2).all(|w| w[0].id < w[1].id));
    for edge in map.edges() {
        let from = &map.nodes()[edge.from].name;
        let to = &map.nodes()[edge.to].name;
        assert_eq!(edge.id, format!("{from}_{to}"));
    }

    assert_eq!(stats.total_attempts(), 25_316);
    let counts: Vec<usize> = attempts.iter().map(Vec::len).collect();
    assert_eq!(counts.iter().min(), Some(&1));
    assert_eq!(counts.iter().max(), Some(&3780));
    assert_eq!(counts.iter().filter(|&&c| c == 1).count(), 5);
    assert_eq!(stats.time_span(), Some((1_404_836_638.0, 1_409_788_722.0)));

    // The door edge: 3780 attempts, 760 successes (20.1 %).
    let door = stats.attempts_of("LabDoor1_LabDoor2").unwrap();
    assert_eq!(door.len(), 3780);
    assert_eq!(door.iter().filter(|a| a.success).count(), 760);
    let index = map
        .edges()
        .iter()
        .position(|e| e.id == "LabDoor1_LabDoor2")
        .unwrap();
    let rate = stats.success_rate(index).unwrap();
    assert!((rate - 0.2011).abs() < 1e-4, "{rate}");
    assert_eq!(door[0].time, 1_404_836_670.0);
    assert_eq!(door[0].duration_secs, 6.549558);
    assert!(door[0].success && !door[3].success);
    let series = stats.success_series(index);
    assert_eq!((series.len(), series.values[3]), (3780, 0.0));

    // Every attempt is in time order with a duration >= 0.
    for edge in attempts {
        assert!(edge.windows(2).all(|w| w[0].time <= w[1].time));
        assert!(edge.iter().all(|a| a.duration_secs >= 0.0));
    }
}

#[test]
fn witham_splits_chronologically() {
    let stats = read_edge_directory(witham_edges()).unwrap();
    let split = 1_407_715_200.0; // 2014-08-11 00:00 UTC
    let (before, after) = stats.split_at(split);
    assert_eq!(before.map, stats.map);
    assert_eq!(after.map, stats.map);
    assert_eq!(
        before.total_attempts() + after.total_attempts(),
        stats.total_attempts()
    );
    assert!(before.attempts.iter().flatten().all(|a| a.time < split));
    assert!(after.attempts.iter().flatten().all(|a| a.time >= split));
    // 4,786 attempts in July (before a gap from 2014-07-22 to 2014-08-07), 20,530 after.
    assert_eq!(
        (before.total_attempts(), after.total_attempts()),
        (4786, 20_530)
    );
    // Some edges have attempts on one side only; they stay in both maps.
    assert!(before.attempts.iter().any(Vec::is_empty) || after.attempts.iter().any(Vec::is_empty));
    // Splitting at an attempt's time puts that attempt after.
    let first = stats.time_span().unwrap().0;
    let (none, all) = stats.split_at(first);
    assert_eq!((none.total_attempts(), all.total_attempts()), (0, 25_316));
}

#[test]
fn witham_with_extra_nodes_puts_them_first() {
    let stats = read_edge_directory_with_nodes(witham_edges(), &["Entrance", "LabDoor1"]).unwrap();
    assert_eq!(stats.map.nodes().len(), 19);
    assert_eq!(stats.map.nodes()[0].name, "Entrance");
    assert_eq!(stats.map.nodes()[1].name, "LabDoor1");
    assert_eq!(stats.map.nodes()[2].name, "Aisle1");
    assert_eq!(stats.map.out_edges(0).count(), 0);
    assert_eq!(stats.map.edges().len(), 61);

    let err = read_edge_directory_with_nodes(witham_edges(), &["A", "A"]).unwrap_err();
    assert_eq!(err.name(), witham_edges().display().to_string());
    assert!(matches!(
        err.kind(),
        DataErrorKind::Map { error: TopoError::DuplicateNode(name) } if name == "A"
    ));
}

#[test]
fn witham_exports_to_geojson_and_tmap2() {
    let stats = read_edge_directory(witham_edges()).unwrap();
    let metadata: Vec<RouteEdgeMetadata> = stats
        .attempts
        .iter()
        .enumerate()
        .map(|(i, attempts)| {
            let mean =
                attempts.iter().map(|a| a.duration_secs).sum::<f64>() / attempts.len() as f64;
            RouteEdgeMetadata::new(stats.success_rate(i).unwrap(), mean)
        })
        .collect();
    let json: Value =
        serde_json::from_str(&encode_route_geojson(&stats.map, &metadata).unwrap()).unwrap();
    let features = json["features"].as_array().unwrap();
    assert_eq!(features.len(), 18 + 61);
    assert!(
        features[..18]
            .iter()
            .all(|f| f["properties"]["metadata"]["synthetic_position"] == true)
    );

    let tmap2 = encode_tmap2(&stats.map, "witham", "08-07-2014_16-23-58").unwrap();
    let read = decode_tmap2("witham.tmap2.yaml", tmap2.as_bytes()).unwrap();
    assert_eq!(read.map, stats.map);
    assert_eq!(read.name, "witham");
}

// ---------------------------------------------------------------------------------------------
// Edge files: bad input

#[test]
fn reads_edge_lines_with_comments_blank_lines_and_crlf() {
    let text = "# t duration success\n\n10 5.5 1\r\n10\t0 0\n20,7,1\n";
    let attempts = read_edge_file_from("A_B.data", text.as_bytes()).unwrap();
    assert_eq!(attempts.len(), 3);
    assert_eq!(
        (
            attempts[1].time,
            attempts[1].duration_secs,
            attempts[1].success
        ),
        (10.0, 0.0, false)
    );
    assert_eq!(attempts[2].duration_secs, 7.0);
}

#[test]
fn empty_edge_files_are_errors() {
    for text in ["", "\n\n", "# only a comment\n"] {
        check(
            &edge_err(text),
            "A_B.data",
            None,
            None,
            "A_B.data: no data lines (the input is empty or has only blank lines and # comments)",
        );
    }
}

#[test]
fn negative_durations_name_file_line_and_field() {
    let err = edge_err("10 5 1\n# x\n20 -0.5 1\n");
    check(
        &err,
        "A_B.data",
        Some(3),
        Some(Field::Duration),
        r#"A_B.data:3: duration: "-0.5" is negative (durations are seconds >= 0)"#,
    );
    assert!(matches!(err.kind(), DataErrorKind::NegativeDuration { text } if text == "-0.5"));
    // `-0` is a duration of 0.
    let attempts = read_edge_file_from("A_B.data", "1 -0 1\n".as_bytes()).unwrap();
    assert!(attempts[0].duration_secs == 0.0 && attempts[0].duration_secs.is_sign_positive());
}

#[test]
fn non_numeric_and_non_finite_fields_name_the_field() {
    check_edge_rows(&[
        (
            "10 5 1\nnoon 5 1\n",
            2,
            Some(Field::Time),
            r#"A_B.data:2: time: "noon" is not a number"#,
        ),
        (
            "10 5s 1\n",
            1,
            Some(Field::Duration),
            r#"A_B.data:1: duration: "5s" is not a number"#,
        ),
        (
            "10 inf 1\n",
            1,
            Some(Field::Duration),
            r#"A_B.data:1: duration: "inf" is not a finite number"#,
        ),
        (
            "-10 5 1\n",
            1,
            Some(Field::Time),
            r#"A_B.data:1: time: "-10" is negative (times are seconds >= 0)"#,
        ),
    ]);
}

#[test]
fn success_must_be_zero_or_one() {
    for bad in ["2", "yes", "0.5", "1.0", "true"] {
        let err = edge_err(&format!("10 5 1\n11 5 {bad}\n"));
        check(
            &err,
            "A_B.data",
            Some(2),
            Some(Field::Success),
            &format!("A_B.data:2: success: {bad:?} is not 0 or 1"),
        );
        assert!(matches!(
            err.kind(),
            DataErrorKind::NotZeroOrOne {
                field: Field::Success,
                ..
            }
        ));
    }
}

#[test]
fn times_going_backwards_are_errors() {
    let err = edge_err("10 5 1\n20 5 1\n\n15 5 0\n");
    check(
        &err,
        "A_B.data",
        Some(4),
        Some(Field::Time),
        r#"A_B.data:4: time: "15" is earlier than the time 20 on line 2 (times must not go backwards)"#,
    );
    // equal times are allowed
    assert_eq!(
        read_edge_file_from("e", "5 1 0\n5 2 1\n".as_bytes())
            .unwrap()
            .len(),
        2
    );
}

#[test]
fn missing_and_extra_fields_are_errors() {
    check_edge_rows(&[
        (
            "10 5\n",
            1,
            Some(Field::Success),
            "A_B.data:1: success: missing (expected three fields: time duration success)",
        ),
        (
            "10\n",
            1,
            Some(Field::Duration),
            "A_B.data:1: duration: missing (expected three fields: time duration success)",
        ),
        (
            "10 5 1 extra\n",
            1,
            None,
            r#"A_B.data:1: unexpected extra field "extra" (expected three fields: time duration success)"#,
        ),
    ]);
}

#[test]
fn edge_files_errors_name_the_path() {
    let dir = folder("edge_file_path", &[("A_B.data", "1 2 1\n0 2 1\n")]);
    let path = dir.join("A_B.data");
    let err = read_edge_file(&path).unwrap_err();
    assert_eq!(err.name(), path.display().to_string());
    assert_eq!(err.line(), Some(2));
    let missing = read_edge_file(dir.join("C_D.data")).unwrap_err();
    assert!(matches!(
        missing.kind(),
        DataErrorKind::Io { action: "open", .. }
    ));
}

// ---------------------------------------------------------------------------------------------
// Directories: file names

#[test]
fn directories_read_plain_and_compressed_files_and_ignore_path_lists() {
    let dir = folder(
        "directory_mixed",
        &[
            ("Door_Hall.data", "1 2 1\n3 4 0\n"),
            ("path0.txt", "Door_Hall.data\nHall_Door.data\n"),
            ("path_1.txt", "whatever\n"),
            (".hidden", "not data"),
        ],
    );
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(b"5 6 1\n").unwrap();
    fs::write(dir.join("Hall_Door.data.gz"), gz.finish().unwrap()).unwrap();
    let stats = read_edge_directory(&dir).unwrap();
    let ids: Vec<&str> = stats.map.edges().iter().map(|e| e.id.as_str()).collect();
    assert_eq!(ids, ["Door_Hall", "Hall_Door"]);
    assert_eq!(stats.attempts[1][0].duration_secs, 6.0);
    assert_eq!(stats.map.nodes().len(), 2);
}

#[test]
fn file_names_that_do_not_split_into_two_nodes_are_errors() {
    let dir = folder(
        "no_underscore",
        &[("A_B.data", "1 1 1\n"), ("Kitchen.data", "1 1 1\n")],
    );
    let err = read_edge_directory(&dir).unwrap_err();
    check_in_dir(
        &err,
        &dir,
        "Kitchen.data",
        None,
        None,
        ": edge file name \"Kitchen\" does not name an edge <From>_<To>: it has no underscore",
    );
    assert!(matches!(err.kind(), DataErrorKind::EdgeFileName { stem, .. } if stem == "Kitchen"));

    for bad in ["_Kitchen.data", "Kitchen_.data"] {
        let dir = folder("empty_half", &[(bad, "1 1 1\n")]);
        let err = read_edge_directory(&dir).unwrap_err();
        assert!(err.to_string().ends_with("a node name is empty"), "{err}");
        assert_eq!(err.name(), dir.join(bad).display().to_string());
    }
}

#[test]
fn ambiguous_file_names_are_errors_and_known_nodes_resolve_underscores() {
    // Node names with underscores: the given nodes say where to split.
    let dir = folder(
        "underscores",
        &[
            ("Lab_Door_Kitchen.data", "1 1 1\n"),
            ("Kitchen_Lab_Door.data", "1 1 0\n"),
        ],
    );
    let stats = read_edge_directory_with_nodes(&dir, &["Lab_Door"]).unwrap();
    let map = &stats.map;
    assert_eq!(map.nodes().len(), 2);
    let lab_door_kitchen = &map.edges()[1];
    assert_eq!(lab_door_kitchen.id, "Lab_Door_Kitchen");
    assert_eq!(map.nodes()[lab_door_kitchen.from].name, "Lab_Door");
    assert_eq!(map.nodes()[lab_door_kitchen.to].name, "Kitchen");
    // Without them, neither split leaves two known names: the first underscore is used.
    let stats = read_edge_directory(&dir).unwrap();
    let names: Vec<&str> = stats.map.nodes().iter().map(|n| n.name.as_str()).collect();
    assert_eq!(names, ["Door_Kitchen", "Kitchen", "Lab", "Lab_Door"]);

    // Two splits leave known names: an error listing both.
    let dir = folder("ambiguous", &[("A_B_C.data", "1 1 1\n")]);
    let err = read_edge_directory_with_nodes(&dir, &["A", "B_C", "A_B", "C"]).unwrap_err();
    assert!(
        err.to_string().ends_with(
            "edge file name \"A_B_C\" does not name an edge <From>_<To>: it splits in 2 ways \
             that leave two known node names (A -> B_C, A_B -> C)"
        ),
        "{err}"
    );
}

/// A pipe named like an edge file is refused before it is opened (opening it would wait for a
/// writer forever).
#[cfg(unix)]
#[test]
fn a_pipe_among_the_edge_files_is_refused_without_waiting() {
    let dir = folder("pipe", &[("A_B.data", "1 1 1\n")]);
    let pipe = dir.join("B_C.data");
    let made = std::process::Command::new("mkfifo")
        .arg(&pipe)
        .status()
        .unwrap();
    assert!(made.success());
    let err = read_edge_directory(&dir).unwrap_err();
    assert_eq!(err.name(), pipe.display().to_string());
    assert!(matches!(err.kind(), DataErrorKind::UnexpectedFile), "{err}");
}

#[test]
fn other_files_and_repeated_edges_are_errors() {
    let dir = folder(
        "unexpected",
        &[("A_B.data", "1 1 1\n"), ("README.md", "# notes\n")],
    );
    let err = read_edge_directory(&dir).unwrap_err();
    assert_eq!(err.name(), dir.join("README.md").display().to_string());
    assert!(matches!(err.kind(), DataErrorKind::UnexpectedFile));
    assert!(err.to_string().contains("not an edge file"));

    let dir = folder("subdirectory", &[("A_B.data", "1 1 1\n")]);
    fs::create_dir(dir.join("old")).unwrap();
    let err = read_edge_directory(&dir).unwrap_err();
    assert!(matches!(err.kind(), DataErrorKind::UnexpectedFile), "{err}");

    let dir = folder("repeated", &[("A_B.data", "1 1 1\n"), ("A_B.data.xz", "")]);
    let err = read_edge_directory(&dir).unwrap_err();
    assert_eq!(err.name(), dir.join("A_B.data.xz").display().to_string());
    assert!(
        err.to_string()
            .ends_with("edge \"A_B\" has a second file: A_B.data"),
        "{err}"
    );

    let err = read_edge_directory(scratch("missing").join("nowhere")).unwrap_err();
    assert!(matches!(err.kind(), DataErrorKind::Io { .. }), "{err}");
}

#[test]
fn a_bad_line_in_a_directory_names_its_file() {
    let dir = folder(
        "bad_line",
        &[("A_B.data", "1 1 1\n"), ("B_A.data", "1 1 1\n2 -3 1\n")],
    );
    let err = read_edge_directory(&dir).unwrap_err();
    check_in_dir(
        &err,
        &dir,
        "B_A.data",
        Some(2),
        Some(Field::Duration),
        r#":2: duration: "-3" is negative (durations are seconds >= 0)"#,
    );
    let dir = folder("empty_file", &[("A_B.data", "")]);
    let err = read_edge_directory(&dir).unwrap_err();
    assert!(matches!(err.kind(), DataErrorKind::Empty), "{err}");
}

// ---------------------------------------------------------------------------------------------
// tmap2

fn three_node_map() -> TopoMap {
    let mut map = TopoMap::new();
    map.add_node("LabDoor1", Some([1.25, -2.5, 0.0])).unwrap();
    map.add_node("LabDoor2", Some([4.0, 2.0, FRAC_PI_2]))
        .unwrap();
    map.add_node("Kitchen", Some([-3.1, 0.7, -2.75])).unwrap();
    map.add_node("Station", Some([1e-7, 12345.678, PI]))
        .unwrap();
    map.add_edge("LabDoor1_LabDoor2", "LabDoor1", "LabDoor2")
        .unwrap();
    map.add_edge("LabDoor2_LabDoor1", "LabDoor2", "LabDoor1")
        .unwrap();
    map.add_edge("LabDoor2_Kitchen", "LabDoor2", "Kitchen")
        .unwrap();
    map.add_edge("Kitchen_Station", "Kitchen", "Station")
        .unwrap();
    map
}

fn assert_same_map(read: &TopoMap, written: &TopoMap) {
    assert_eq!(read.edges(), written.edges());
    assert_eq!(read.nodes().len(), written.nodes().len());
    for (r, w) in read.nodes().iter().zip(written.nodes()) {
        assert_eq!(r.name, w.name);
        match (r.pose, w.pose) {
            (Some(r), Some(w)) => {
                assert_eq!((r[0], r[1]), (w[0], w[1]), "x, y are exact");
                let d = (r[2] - w[2]).rem_euclid(2.0 * PI);
                assert!(d.min(2.0 * PI - d) < 1e-12, "yaw {} vs {}", r[2], w[2]);
            }
            (r, w) => assert_eq!(r, w),
        }
    }
}

#[test]
fn tmap2_round_trips_nodes_poses_and_edges() {
    let map = three_node_map();
    let dir = scratch("tmap2_round_trip");
    let path = dir.join("lab.tmap2.yaml");
    write_tmap2(&path, &map, "lab").unwrap();
    assert_same_map(&read_tmap2(&path).unwrap(), &map);
    // no temporary file left behind
    assert_eq!(fs::read_dir(&dir).unwrap().count(), 1);

    let text = fs::read_to_string(&path).unwrap();
    let read = decode_tmap2("lab", text.as_bytes()).unwrap();
    assert_eq!(
        (read.name.as_str(), read.metric_map.as_str()),
        ("lab", "lab")
    );
    assert_eq!(read.pointset, "lab");
    assert_eq!(read.actions, vec![Some("NavigateToPose".to_owned()); 4]);
    assert!(text.starts_with("meta:\n  last_updated: "));
    assert!(
        text.contains(
            "    - action: NavigateToPose\n      action_type: geometry_msgs/PoseStamped\n"
        )
    );
    assert!(text.contains("          pose: $node.pose\n      node: LabDoor2\n"));
    assert!(text.contains("      position:\n        x: 1.0e-7\n        y: 12345.678\n"));
    assert!(text.ends_with("translation:\n    x: 0.0\n    y: 0.0\n    z: 0.0\n"));

    // Nodes without a pose are written with a synthetic one and read back without.
    let mut map = map;
    map.add_node("Nowhere", None).unwrap();
    map.add_edge("Station_Nowhere", "Station", "Nowhere")
        .unwrap();
    let text = encode_tmap2(&map, "lab", "01-01-2026_00-00-00").unwrap();
    assert_eq!(text.matches("synthetic_pose: true").count(), 1);
    assert_same_map(&decode_tmap2("lab", text.as_bytes()).unwrap().map, &map);

    // Odd names are quoted and survive.
    let mut odd = TopoMap::new();
    odd.add_node("yes", Some([0.0, 0.0, 0.0])).unwrap();
    odd.add_node("12", Some([1.0, 0.0, 0.0])).unwrap();
    odd.add_node("a:b#c", Some([2.0, 0.0, 0.0])).unwrap();
    odd.add_edge("yes_12", "yes", "12").unwrap();
    odd.add_edge("x\"y", "12", "a:b#c").unwrap();
    let text = encode_tmap2(&odd, "on", "now").unwrap();
    let read = decode_tmap2("odd", text.as_bytes()).unwrap();
    assert_same_map(&read.map, &odd);
    assert_eq!(read.name, "on");
}

/// A tmap2 file the way PyYAML (`yaml.dump`, sorted keys, block style) writes one whose nodes
/// share Python objects: `properties`, `verts` and the `goal` template are anchored once
/// (`&id001`, ...) and aliased after (`*id001`). Node B's edge targets node C, defined later;
/// C has no orientation and its edges are `null`.
const PYYAML_TMAP2: &str = "\
meta:
  last_updated: 24-07-2026_13-05-00
metric_map: riseholme
name: riseholme
nodes:
- meta:
    map: riseholme
    node: WayPoint1
    pointset: riseholme
  node:
    edges:
    - action: NavigateToPose
      action_type: geometry_msgs/PoseStamped
      config: []
      edge_id: WayPoint1_WayPoint2
      fail_policy: fail
      fluid_navigation: true
      goal: &id002
        target_pose:
          header:
            frame_id: $node.parent_frame
          pose: $node.pose
      node: WayPoint2
      recovery_behaviours_config: ''
      restrictions_planning: 'True'
      restrictions_runtime: obstacleFree_1
    localise_by_topic: ''
    name: WayPoint1
    parent_frame: map
    pose:
      orientation:
        w: 0.7071067811865476
        x: 0.0
        y: 0.0
        z: 0.7071067811865476
      position:
        x: -1.5
        y: 3.25
        z: 0.0
    properties: &id001
      xy_goal_tolerance: 0.3
      yaw_goal_tolerance: 0.1
    restrictions_planning: 'True'
    restrictions_runtime: obstacleFree_1
    verts: &id003
    - x: 0.689
      y: 0.285
    - x: -0.689
      y: -0.285
- meta:
    map: riseholme
    node: WayPoint2
    pointset: riseholme
  node:
    edges:
    - action: row_traversal
      action_type: geometry_msgs/PoseStamped
      config: []
      edge_id: WayPoint2_WayPoint1
      fail_policy: fail
      fluid_navigation: true
      goal: *id002
      node: WayPoint1
      recovery_behaviours_config: ''
      restrictions_planning: 'True'
      restrictions_runtime: obstacleFree_1
    - edge_id: WayPoint2_WayPoint3
      goal: *id002
      node: WayPoint3
    localise_by_topic: ''
    name: WayPoint2
    parent_frame: map
    pose:
      orientation:
        w: 1.0
        x: 0.0
        y: 0.0
        z: 0.0
      position:
        x: 2
        y: 3.25
        z: 0.0
    properties: *id001
    verts: *id003
- meta:
    map: riseholme
    node: WayPoint3
    pointset: riseholme
  node:
    edges: null
    name: WayPoint3
    pose:
      position: {x: 4.5, y: -1.0e-3, z: 0.0}
    properties: *id001
    verts: *id003
pointset: riseholme
transformation:
  child: topo_map
  parent: map
  rotation:
    w: 1.0
    x: 0.0
    y: 0.0
    z: 0.0
  translation:
    x: 0.0
    y: 0.0
    z: 0.0
";

#[test]
fn tmap2_with_pyyaml_anchors_and_aliases_reads() {
    let dir = folder("pyyaml", &[("riseholme.tmap2.yaml", PYYAML_TMAP2)]);
    let map = read_tmap2(dir.join("riseholme.tmap2.yaml")).unwrap();
    let names: Vec<&str> = map.nodes().iter().map(|n| n.name.as_str()).collect();
    assert_eq!(names, ["WayPoint1", "WayPoint2", "WayPoint3"]);
    let [x, y, yaw] = map.nodes()[0].pose.unwrap();
    assert_eq!((x, y), (-1.5, 3.25));
    assert!((yaw - FRAC_PI_2).abs() < 1e-12);
    assert_eq!(map.nodes()[1].pose, Some([2.0, 3.25, 0.0]));
    assert_eq!(map.nodes()[2].pose, Some([4.5, -0.001, 0.0]));
    let edges: Vec<(&str, usize, usize)> = map
        .edges()
        .iter()
        .map(|e| (e.id.as_str(), e.from, e.to))
        .collect();
    assert_eq!(
        edges,
        [
            ("WayPoint1_WayPoint2", 0, 1),
            ("WayPoint2_WayPoint1", 1, 0),
            ("WayPoint2_WayPoint3", 1, 2),
        ]
    );
    let full = decode_tmap2("riseholme", PYYAML_TMAP2.as_bytes()).unwrap();
    assert_eq!(
        full.actions,
        [
            Some("NavigateToPose".to_owned()),
            Some("row_traversal".to_owned()),
            None
        ]
    );
    assert_eq!(full.metric_map, "riseholme");

    // Compressed files are read too.
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(PYYAML_TMAP2.as_bytes()).unwrap();
    fs::write(dir.join("riseholme.tmap2.yaml.gz"), gz.finish().unwrap()).unwrap();
    assert_eq!(
        read_tmap2(dir.join("riseholme.tmap2.yaml.gz")).unwrap(),
        map
    );
}

#[test]
fn strands_ros1_node_lists_read() {
    // The STRANDS ROS 1 export: a top-level list of {meta, node}, aliases included.
    let yaml = "\
- meta: {map: witham, node: ChargingPoint, pointset: witham}
  node:
    name: ChargingPoint
    map: witham
    pointset: witham
    pose:
      position: {x: 0.1, y: 0.2, z: 0.0}
      orientation: {x: 0.0, y: 0.0, z: 1.0, w: 0.0}
    yaw_goal_tolerance: 0.1
    verts: &id001 [{x: 0.5, y: 0.5}, {x: -0.5, y: 0.5}]
    edges:
    - {edge_id: ChargingPoint_Station, node: Station, action: undocking, top_vel: 0.55}
- meta: {map: witham, node: Station, pointset: witham}
  node:
    name: Station
    map: witham
    pointset: witham
    pose:
      position: {x: 1.0, y: 0.2, z: 0.0}
      orientation: {x: 0.0, y: 0.0, z: 0.0, w: 1.0}
    verts: *id001
    edges:
    - {edge_id: Station_ChargingPoint, node: ChargingPoint, action: docking}
";
    let read = decode_tmap2("witham.yaml", yaml.as_bytes()).unwrap();
    assert_eq!(
        (read.name.as_str(), read.metric_map.as_str()),
        ("witham", "witham")
    );
    assert_eq!(read.map.nodes().len(), 2);
    assert_eq!(read.map.edges().len(), 2);
    let yaw = read.map.nodes()[0].pose.unwrap()[2];
    assert!((yaw - PI).abs() < 1e-12, "{yaw}");
    assert_eq!(
        read.actions,
        [Some("undocking".to_owned()), Some("docking".to_owned())]
    );
}

fn tmap2_err(yaml: &str) -> TopoFileError {
    decode_tmap2("map.yaml", yaml.as_bytes()).expect_err(yaml)
}

#[test]
fn tmap2_errors_name_file_line_and_key() {
    let node = |pose: &str, edges: &str| {
        format!("name: m\nnodes:\n- node:\n    name: A\n    pose:\n{pose}    edges:\n{edges}")
    };
    let good_pose = "      position: {x: 1.0, y: 2.0}\n";
    let edge_to = |target: &str| format!("    - {{edge_id: A_X, node: {target}}}\n");
    decode_tmap2("map.yaml", node(good_pose, &edge_to("A")).as_bytes()).unwrap();

    let err = tmap2_err(&node("      orientation: {x: 0, y: 0, z: 0, w: 1}\n", ""));
    assert_eq!(
        err.to_string(),
        "map.yaml:6: missing required key `nodes[0].node.pose.position`"
    );
    assert_eq!(
        (err.file(), err.key()),
        (Some("map.yaml"), Some("nodes[0].node.pose.position"))
    );

    let err = tmap2_err(&node("      position: {x: one, y: 2.0}\n", ""));
    assert_eq!(
        err.to_string(),
        r#"map.yaml:6: nodes[0].node.pose.position.x: "one" is invalid (expected a finite number)"#
    );
    assert!(matches!(err.kind(), TopoFileErrorKind::InvalidValue { .. }));

    let err = tmap2_err(&node(good_pose, &edge_to("a")));
    assert_eq!(
        err.to_string(),
        r#"map.yaml:8: nodes[0].node.edges[0].node: unknown node "a" (did you mean "A"?)"#
    );
    assert_eq!(err.line(), Some(8));

    let err = tmap2_err(&node(good_pose, "    - {node: A}\n"));
    assert_eq!(err.key(), Some("nodes[0].node.edges[0].edge_id"));

    let err = tmap2_err(&node(
        good_pose,
        "    - {edge_id: A_A, node: A}\n    - {edge_id: A_A, node: A}\n",
    ));
    assert_eq!(
        err.to_string(),
        r#"map.yaml:9: nodes[0].node.edges[1].edge_id: edge "A_A" is defined twice"#
    );

    let twice = "nodes:\n- node: {name: A, pose: {position: {x: 0, y: 0}}}\n\
                 - node: {name: A, pose: {position: {x: 1, y: 0}}}\n";
    let err = tmap2_err(twice);
    assert_eq!(
        err.to_string(),
        r#"map.yaml:3: nodes[1].node.name: node "A" is defined twice"#
    );

    let err = tmap2_err("nodes: 5\n");
    assert_eq!(
        err.to_string(),
        "map.yaml:1: nodes: 5 is invalid (expected a list)"
    );
    let err = tmap2_err("name: m\n");
    assert_eq!(err.to_string(), "map.yaml:1: missing required key `nodes`");
    let err = tmap2_err("nodes:\n- node: [1, 2]\n");
    assert_eq!(err.key(), Some("nodes[0].node"));

    for (yaml, message) in [
        ("", "the top level is empty"),
        ("42\n", "the top level is a single value"),
    ] {
        let err = tmap2_err(yaml);
        assert!(
            matches!(err.kind(), TopoFileErrorKind::Yaml { .. }),
            "{err}"
        );
        assert!(err.to_string().contains(message), "{err}");
    }
    let err = tmap2_err("nodes:\n- node: {name: A\n");
    assert!(
        matches!(err.kind(), TopoFileErrorKind::Yaml { .. }),
        "{err}"
    );
    assert!(err.line().is_some(), "{err}");
    let err = tmap2_err("nodes: []\nnodes: []\n");
    assert_eq!(
        err.to_string(),
        "map.yaml:2: not a topological map YAML file: the key `nodes` appears twice"
    );
    let err = tmap2_err("nodes:\n- node: {name: A, pose: {position: {x: 1, y: .nan}}}\n");
    assert_eq!(
        err.to_string(),
        "map.yaml:2: nodes[0].node.pose.position.y: NaN is invalid (expected a finite number)"
    );
    let err = tmap2_err("nodes: *nothing\n");
    assert!(
        matches!(err.kind(), TopoFileErrorKind::Yaml { .. }),
        "{err}"
    );

    // Deep nesting is refused, not a stack overflow.
    let deep = format!("nodes: {}{}\n", "[".repeat(200), "]".repeat(200));
    let err = tmap2_err(&deep);
    assert!(
        err.to_string().ends_with("collections nested too deeply"),
        "{err}"
    );

    let err = read_tmap2(scratch("tmap2_missing").join("none.yaml")).unwrap_err();
    assert!(
        matches!(err.kind(), TopoFileErrorKind::Io { action: "read", .. }),
        "{err}"
    );
}

#[test]
fn writers_reject_maps_they_cannot_write() {
    let mut map = TopoMap::new();
    map.add_node("A", Some([f64::NAN, 0.0, 0.0])).unwrap();
    let err = encode_tmap2(&map, "m", "now").unwrap_err();
    assert!(
        matches!(err.kind(), TopoFileErrorKind::InvalidInput { .. }),
        "{err}"
    );
    let path = scratch("bad_write").join("m.tmap2.yaml");
    let err = write_tmap2(&path, &map, "m").unwrap_err();
    assert_eq!(err.file(), Some(path.display().to_string().as_str()));
    assert!(!path.exists());
    let err = encode_route_geojson(&map, &[]).unwrap_err();
    assert!(err.to_string().contains("not finite"), "{err}");
}

// ---------------------------------------------------------------------------------------------
// Nav2 route graph GeoJSON

#[test]
fn route_geojson_has_nodes_edges_and_metadata() {
    let mut map = three_node_map();
    map.add_node("Nowhere", None).unwrap();
    map.add_edge("Station_Nowhere", "Station", "Nowhere")
        .unwrap();
    // Intervals on some edges: one around the time, one that does not hold it (quantile
    // bounds need not), one of zero width, none.
    let metadata = [
        RouteEdgeMetadata::new(0.2, 12.5).with_time_interval(Some((9.75, 17.0)), 0.9),
        RouteEdgeMetadata::new(0.99, 8.0),
        RouteEdgeMetadata::new(1.0, 0.0).with_time_interval(Some((0.0, 0.0)), 0.9),
        RouteEdgeMetadata::new(0.5, 30.25).with_time_interval(Some((31.0, 62.5)), 0.5),
        RouteEdgeMetadata::new(0.0, 1.0),
    ];
    let path = scratch("geojson").join("route.geojson");
    write_route_geojson(&path, &map, &metadata).unwrap();
    // Read back with the new keys: the same edges (poses lose their yaw).
    assert_eq!(read_route_geojson(&path).unwrap().edges(), map.edges());
    let json: Value = serde_json::from_str(&fs::read_to_string(&path).unwrap()).unwrap();

    assert_eq!(json["type"], "FeatureCollection");
    assert_eq!(
        json["crs"]["properties"]["name"],
        "urn:ogc:def:crs:EPSG::3857"
    );
    let features = json["features"].as_array().unwrap();
    assert_eq!(features.len(), 5 + 5);
    let points: Vec<&Value> = features
        .iter()
        .filter(|f| f["geometry"]["type"] == "Point")
        .collect();
    let lines: Vec<&Value> = features
        .iter()
        .filter(|f| f["geometry"]["type"] == "MultiLineString")
        .collect();
    assert_eq!((points.len(), lines.len()), (5, 5));

    // ids are unique across nodes and edges
    let mut ids: Vec<u64> = features
        .iter()
        .map(|f| f["properties"]["id"].as_u64().unwrap())
        .collect();
    ids.sort_unstable();
    ids.dedup();
    assert_eq!(ids.len(), 10);

    let door = &points[0]["properties"];
    assert_eq!(
        (door["id"].as_u64(), door["frame"].as_str()),
        (Some(0), Some("map"))
    );
    assert_eq!(door["metadata"]["name"], "LabDoor1");
    assert_eq!(door["metadata"]["synthetic_position"], false);
    assert_eq!(
        points[0]["geometry"]["coordinates"],
        serde_json::json!([1.25, -2.5])
    );
    assert_eq!(
        points[4]["properties"]["metadata"]["synthetic_position"],
        true
    );

    let first = &lines[0]["properties"];
    assert_eq!(first["id"].as_u64(), Some(5));
    assert_eq!(
        (first["startid"].as_u64(), first["endid"].as_u64()),
        (Some(0), Some(1))
    );
    assert_eq!(first["metadata"]["name"], "LabDoor1_LabDoor2");
    assert_eq!(first["metadata"]["success_probability"].as_f64(), Some(0.2));
    assert_eq!(first["metadata"]["abs_time_taken"].as_f64(), Some(12.5));
    assert_eq!(
        first["metadata"]["abs_time_taken_lower"].as_f64(),
        Some(9.75)
    );
    assert_eq!(
        first["metadata"]["abs_time_taken_upper"].as_f64(),
        Some(17.0)
    );
    assert_eq!(
        first["metadata"]["abs_time_taken_coverage"].as_f64(),
        Some(0.9)
    );
    assert_eq!(
        lines[0]["geometry"]["coordinates"],
        serde_json::json!([[[1.25, -2.5], [4.0, 2.0]]])
    );
    for (line, m) in lines.iter().zip(&metadata) {
        let written = &line["properties"]["metadata"];
        assert_eq!(
            written["success_probability"].as_f64(),
            Some(m.success_probability)
        );
        assert_eq!(written["abs_time_taken"].as_f64(), Some(m.time_taken_secs));
        // Flat numbers (Nav2 reads scalar metadata), or no key at all without an interval.
        let key = |k: &str| written.get(k).map(|v| v.as_f64().expect("a number"));
        assert_eq!(
            key("abs_time_taken_lower").zip(key("abs_time_taken_upper")),
            m.time_taken_interval.map(|i| (i.lower_secs, i.upper_secs))
        );
        assert_eq!(
            key("abs_time_taken_coverage"),
            m.time_taken_interval.map(|i| i.coverage)
        );
        let keys = written.as_object().unwrap().len();
        assert_eq!(
            keys,
            if m.time_taken_interval.is_some() {
                6
            } else {
                3
            }
        );
    }
}

#[test]
fn route_geojson_rejects_bad_metadata() {
    let map = three_node_map();
    let err = encode_route_geojson(&map, &[RouteEdgeMetadata::new(0.5, 1.0)]).unwrap_err();
    assert_eq!(
        err.to_string(),
        "cannot write the map: 1 edge metadata entries for 4 edges"
    );
    let good = [RouteEdgeMetadata::new(0.5, 1.0); 4];
    encode_route_geojson(&map, &good).unwrap();
    let interval = |lower_secs, upper_secs, coverage| RouteEdgeMetadata {
        time_taken_interval: Some(RouteTimeInterval {
            lower_secs,
            upper_secs,
            coverage,
        }),
        ..RouteEdgeMetadata::new(0.5, 1.0)
    };
    // The time taken need not be inside its interval: quantiles do not promise it.
    for fine in [interval(2.0, 3.0, 0.9), interval(0.0, 0.5, 1.0)] {
        let mut metadata = good;
        metadata[2] = fine;
        encode_route_geojson(&map, &metadata).unwrap();
    }
    for bad in [
        RouteEdgeMetadata::new(1.5, 1.0),
        RouteEdgeMetadata::new(-0.1, 1.0),
        RouteEdgeMetadata::new(f64::NAN, 1.0),
        RouteEdgeMetadata::new(0.5, -1.0),
        RouteEdgeMetadata::new(0.5, f64::INFINITY),
        interval(2.0, 1.0, 0.9),
        interval(-0.5, 1.0, 0.9),
        interval(f64::NAN, 1.0, 0.9),
        interval(0.5, f64::INFINITY, 0.9),
        interval(0.5, f64::NAN, 0.9),
        interval(0.5, 1.5, 0.0),
        interval(0.5, 1.5, 1.5),
        interval(0.5, 1.5, f64::NAN),
    ] {
        let mut metadata = good;
        metadata[2] = bad;
        let err = encode_route_geojson(&map, &metadata).unwrap_err();
        assert!(err.to_string().contains("LabDoor2_Kitchen"), "{err}");
        assert!(
            matches!(err.kind(), TopoFileErrorKind::InvalidInput { .. }),
            "{err}"
        );
    }
    let mut metadata = good;
    metadata[2] = interval(2.0, 1.0, 0.9);
    assert_eq!(
        encode_route_geojson(&map, &metadata)
            .unwrap_err()
            .to_string(),
        "cannot write the map: edge \"LabDoor2_Kitchen\": time interval [2, 1] is not finite \
         seconds with 0 <= lower <= upper"
    );
    metadata[2] = interval(0.5, 1.5, 1.5);
    assert_eq!(
        encode_route_geojson(&map, &metadata)
            .unwrap_err()
            .to_string(),
        "cannot write the map: edge \"LabDoor2_Kitchen\": time interval coverage 1.5 is not in \
         (0, 1]"
    );
    let path = scratch("geojson_bad").join("route.geojson");
    let err = write_route_geojson(&path, &map, &[]).unwrap_err();
    assert_eq!(err.file(), Some(path.display().to_string().as_str()));
    assert!(!path.exists());
}

#[test]
fn witham_edge_models_round_trip_through_a_checked_model_file() {
    use chronomap_io::model_file::{
        decode_edge_models, encode_model, read_edge_models, write_edge_models,
    };
    use chronomap_topo::edges::{EdgeModelConfig, EdgeModels};

    let stats = read_edge_directory(witham_edges()).unwrap();
    let models = EdgeModels::fit(stats.map, &stats.attempts, EdgeModelConfig::default()).unwrap();
    let dir = scratch("edge_models");
    let path = dir.join("witham.cmt");
    write_edge_models(&path, &models).unwrap();
    let loaded = read_edge_models(&path).unwrap();
    let door = loaded
        .map()
        .edges()
        .iter()
        .position(|e| e.id == "LabDoor1_LabDoor2");
    let door = door.unwrap();
    for t in [1_409_788_800.0, 1_409_810_400.0, 1_409_850_000.0] {
        for e in 0..models.map().edges().len() {
            assert_eq!(
                models.success_probability(e, t).to_bits(),
                loaded.success_probability(e, t).to_bits()
            );
            assert_eq!(
                models.expected_duration(e, t).to_bits(),
                loaded.expected_duration(e, t).to_bits()
            );
        }
    }
    // Names resolve after loading (the index is rebuilt).
    assert_eq!(loaded.map().node("Kitchen"), models.map().node("Kitchen"));
    assert!(loaded.success_probability(door, 1_409_788_800.0) < 1.0);
    // Any changed byte is caught by the checksum; another kind of model is refused by name.
    let mut bytes = fs::read(&path).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    assert!(decode_edge_models(&bytes).is_err());
    let other = encode_model("fremen", &chronomap_core::FremenModel::with_order(1)).unwrap();
    let err = decode_edge_models(&other).unwrap_err().to_string();
    assert!(err.contains("\"fremen\""), "{err}");
    fs::remove_dir_all(dir).unwrap();
}

/// The payload of `bytes` with `suffix` cut from its end, in a new container of the same
/// kind: the file a model whose layout lacked its last field would have been.
fn without_last_field(bytes: &[u8], suffix: &[u8]) -> Vec<u8> {
    let header_end = bytes.iter().position(|&b| b == b'\n').unwrap() + 1;
    let header = std::str::from_utf8(&bytes[..header_end]).unwrap();
    let kind = header
        .split_whitespace()
        .nth(2)
        .unwrap()
        .strip_prefix("kind=")
        .unwrap();
    let payload = &bytes[header_end..];
    assert!(
        payload.ends_with(suffix),
        "the last field is not at the end"
    );
    let older = payload[..payload.len() - suffix.len()].to_vec();
    chronomap_io::model_file::encode_payload(kind, older).unwrap()
}

/// An edge-model file written before the models kept the spread of their durations (the
/// same layout without its last field) still reads: the same predictions, no intervals.
#[test]
fn edge_models_written_before_their_duration_spread_read_without_intervals() {
    use chronomap_io::model_file::{decode_edge_models, encode_model};
    use chronomap_topo::edges::{EdgeModelConfig, EdgeModels};

    let stats = read_edge_directory(witham_edges()).unwrap();
    let models = EdgeModels::fit(stats.map, &stats.attempts, EdgeModelConfig::default()).unwrap();
    let t = 1_409_788_800.0;
    assert!(models.duration_interval(0, t, 0.9).is_some());
    let current = encode_model(chronomap_io::EDGE_MODELS_KIND, &models).unwrap();
    let spread = postcard::to_allocvec(models.duration_spread()).unwrap();
    let older = without_last_field(&current, &spread);
    let loaded = decode_edge_models(&older).unwrap();
    for e in 0..models.map().edges().len() {
        assert_eq!(
            models.expected_duration(e, t).to_bits(),
            loaded.expected_duration(e, t).to_bits()
        );
        assert_eq!(loaded.duration_interval(e, t, 0.9), None);
    }
    // A payload cut short anywhere else is still an error, not an older file.
    let broken = without_last_field(&current, &current[current.len() - spread.len() - 1..]);
    assert!(decode_edge_models(&broken).is_err());
}

/// An edge-model file written before the spread of the durations adapted online (the same
/// layout without the adapted levels at its end) reads as models not adapted yet; models that
/// adapted read back with their levels.
#[test]
fn edge_models_written_before_their_spread_adapted_read_as_not_adapted() {
    use chronomap_io::model_file::{decode_edge_models, encode_model};
    use chronomap_topo::edges::{Attempt, EdgeModelConfig, EdgeModels};

    let stats = read_edge_directory(witham_edges()).unwrap();
    let fitted = EdgeModels::fit(stats.map, &stats.attempts, EdgeModelConfig::default()).unwrap();
    let t = 1_409_788_800.0;
    let mut adapted = fitted.clone();
    for i in 0..50 {
        let attempt = Attempt {
            time: t + f64::from(i) * 600.0,
            duration_secs: 3.0 * fitted.expected_duration(0, t),
            success: true,
        };
        adapted.observe(0, &attempt).unwrap();
    }
    assert_eq!(adapted.duration_spread().adapted.count, 50);
    let (lo, hi) = fitted.duration_interval(0, t, 0.9).unwrap();
    let (lo_adapted, hi_adapted) = adapted.duration_interval(0, t, 0.9).unwrap();
    assert!(
        lo_adapted > lo && hi_adapted > hi,
        "{lo} {hi} {lo_adapted} {hi_adapted}"
    );

    let current = encode_model(chronomap_io::EDGE_MODELS_KIND, &adapted).unwrap();
    let back = decode_edge_models(&current).unwrap();
    assert_eq!(back.duration_spread(), adapted.duration_spread());
    assert_eq!(
        back.duration_interval(0, t, 0.9),
        Some((lo_adapted, hi_adapted))
    );

    let levels = postcard::to_allocvec(&adapted.duration_spread().adapted).unwrap();
    let older = without_last_field(&current, &levels);
    let loaded = decode_edge_models(&older).unwrap();
    assert_eq!(loaded.duration_spread().adapted.count, 0);
    for e in 0..fitted.map().edges().len() {
        assert_eq!(
            loaded.duration_interval(e, t, 0.9),
            fitted.duration_interval(e, t, 0.9)
        );
    }
}

#[test]
fn witham_split_writes_directories_that_read_back_exactly() {
    use chronomap_io::topo_files::write_edge_directory;

    let stats = read_edge_directory(witham_edges()).unwrap();
    let (before, after) = stats.split_at(1_408_492_800.0);
    let dir = scratch("split_write");
    let written = write_edge_directory(dir.join("before"), &before).unwrap();
    assert_eq!(
        written,
        before.attempts.iter().filter(|a| !a.is_empty()).count()
    );
    write_edge_directory(dir.join("after"), &after).unwrap();
    for (part, original) in [("before", &before), ("after", &after)] {
        let back = read_edge_directory(dir.join(part)).unwrap();
        assert_eq!(back.total_attempts(), original.total_attempts());
        for (edge, attempts) in back.map.edges().iter().zip(&back.attempts) {
            assert_eq!(
                Some(attempts.as_slice()),
                original.attempts_of(&edge.id),
                "{part} {}",
                edge.id
            );
        }
    }
    assert_eq!(
        before.total_attempts() + after.total_attempts(),
        stats.total_attempts()
    );
    // Writing into a directory that already holds edge files would mix two data sets.
    let err = write_edge_directory(dir.join("before"), &before).unwrap_err();
    assert!(
        err.to_string().contains("already holds edge files"),
        "{err}"
    );
    fs::remove_dir_all(dir).unwrap();
}

#[test]
fn edge_files_in_memory_read_as_the_directory() {
    let dir = witham_edges();
    let from_dir = read_edge_directory(&dir).unwrap();
    let mut contents: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|entry| {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_str().unwrap().to_owned();
            (name, std::fs::read(&path).unwrap())
        })
        .collect();
    contents.reverse();
    let files: Vec<(&str, &[u8])> = contents
        .iter()
        .map(|(n, b)| (n.as_str(), b.as_slice()))
        .collect();
    let from_memory = read_edge_files("witham", &files, &[]).unwrap();
    assert_eq!(from_memory.map, from_dir.map);
    assert_eq!(from_memory.attempts, from_dir.attempts);
    assert_eq!(from_memory.total_attempts(), 25_316);
    // Errors name the source and the file.
    let bad: [(&str, &[u8]); 2] = [("A_B.data", b"1 -2 1\n"), ("B_A.data", b"1 2 1\n")];
    let err = read_edge_files("embedded", &bad, &[])
        .unwrap_err()
        .to_string();
    assert!(err.contains("embedded/A_B.data:1: duration"), "{err}");
}

#[test]
fn edge_models_that_would_be_refused_when_read_are_not_written() {
    use chronomap_io::model_file::{ModelFileErrorKind, write_edge_models};
    use chronomap_topo::edges::{Attempt, EdgeModelConfig, EdgeModels};

    let mut map = TopoMap::new();
    map.add_node("A", None).unwrap();
    map.add_node("B", None).unwrap();
    map.add_edge("A_B", "A", "B").unwrap();
    let attempts: Vec<Attempt> = (0..12)
        .map(|i| Attempt {
            time: 1_404_836_670.0 + 60.0 * f64::from(i),
            duration_secs: 1.7e308,
            success: true,
        })
        .collect();
    // Durations that sum past f64::MAX still have a finite mean: the models are consistent.
    let huge = EdgeModels::fit(
        map.clone(),
        std::slice::from_ref(&attempts),
        EdgeModelConfig::default(),
    );
    let huge = huge.unwrap();
    let mean = huge.edge(0).mean_duration_secs().unwrap();
    assert!((mean / 1.7e308 - 1.0).abs() < 1e-15, "{mean}");
    assert_eq!(huge.check(), Ok(()));
    // A prior success of 2 fits, but breaks what the reader checks: nothing is written.
    let config = EdgeModelConfig {
        prior_success: 2.0,
        ..EdgeModelConfig::default()
    };
    let bad = EdgeModels::fit(map, &[attempts], config).unwrap();
    let path = scratch("edge_models_unwritten").join("bad.cmt");
    let err = write_edge_models(&path, &bad).unwrap_err();
    assert!(
        matches!(err.kind(), ModelFileErrorKind::Inconsistent { .. }),
        "{err}"
    );
    assert_eq!(err.path(), Some(path.as_path()));
    assert!(!path.exists());
}

#[test]
fn durations_longer_than_the_limit_are_refused_on_their_line() {
    let text = "10 5.0 1\n20 1.7e308 1\n";
    let err = read_edge_file_from("A_B.data", text.as_bytes()).unwrap_err();
    check(
        &err,
        "A_B.data",
        Some(2),
        Some(Field::Duration),
        r#"A_B.data:2: duration: "1.7e308" is longer than the longest duration 1e9 s (about 32 years)"#,
    );
    assert!(read_edge_file_from("A_B.data", "10 1e9 1\n".as_bytes()).is_ok());
}
