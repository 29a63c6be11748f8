//! Topological-map files: the bundled Witham Wharf edge statistics, edge files and directories
//! with every kind of bad input (errors name file, line and field, never a panic).

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use chronomap_core::topo::TopoError;
use chronomap_io::text::{DataError, DataErrorKind, Field};
use chronomap_io::topo_files::{
    read_edge_directory, read_edge_directory_with_nodes, read_edge_file, read_edge_file_from,
};

fn witham_edges() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/witham_topological_nav/edges")
}

/// A fresh scratch folder for one test.
fn scratch(test: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("chronomap-io-topo")
        .join(test);
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

/// A folder with the given files.
fn folder(test: &str, files: &[(&str, &str)]) -> PathBuf {
    let dir = scratch(test);
    for (name, text) in files {
        fs::write(dir.join(name), text).unwrap();
    }
    dir
}

/// Checks name, line, field and the whole message of an error.
fn check(err: &DataError, name: &str, line: Option<usize>, field: Option<Field>, message: &str) {
    assert_eq!(err.name(), name, "{err}");
    assert_eq!(err.line(), line, "{err}");
    assert_eq!(err.field(), field, "{err}");
    assert_eq!(err.to_string(), message);
}

fn edge_err(text: &str) -> DataError {
    read_edge_file_from("A_B.data", text.as_bytes()).expect_err(text)
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
    check(
        &edge_err("10 5 1\nnoon 5 1\n"),
        "A_B.data",
        Some(2),
        Some(Field::Time),
        r#"A_B.data:2: time: "noon" is not a number"#,
    );
    check(
        &edge_err("10 5s 1\n"),
        "A_B.data",
        Some(1),
        Some(Field::Duration),
        r#"A_B.data:1: duration: "5s" is not a number"#,
    );
    check(
        &edge_err("10 inf 1\n"),
        "A_B.data",
        Some(1),
        Some(Field::Duration),
        r#"A_B.data:1: duration: "inf" is not a finite number"#,
    );
    check(
        &edge_err("-10 5 1\n"),
        "A_B.data",
        Some(1),
        Some(Field::Time),
        r#"A_B.data:1: time: "-10" is negative (times are seconds >= 0)"#,
    );
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
    check(
        &edge_err("10 5\n"),
        "A_B.data",
        Some(1),
        Some(Field::Success),
        "A_B.data:1: success: missing (expected three fields: time duration success)",
    );
    check(
        &edge_err("10\n"),
        "A_B.data",
        Some(1),
        Some(Field::Duration),
        "A_B.data:1: duration: missing (expected three fields: time duration success)",
    );
    check(
        &edge_err("10 5 1 extra\n"),
        "A_B.data",
        Some(1),
        None,
        r#"A_B.data:1: unexpected extra field "extra" (expected three fields: time duration success)"#,
    );
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
    check(
        &err,
        &dir.join("Kitchen.data").display().to_string(),
        None,
        None,
        &format!(
            "{}: edge file name \"Kitchen\" does not name an edge <From>_<To>: it has no underscore",
            dir.join("Kitchen.data").display()
        ),
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
    check(
        &err,
        &dir.join("B_A.data").display().to_string(),
        Some(2),
        Some(Field::Duration),
        &format!(
            "{}:2: duration: \"-3\" is negative (durations are seconds >= 0)",
            dir.join("B_A.data").display()
        ),
    );
    let dir = folder("empty_file", &[("A_B.data", "")]);
    let err = read_edge_directory(&dir).unwrap_err();
    assert!(matches!(err.kind(), DataErrorKind::Empty), "{err}");
}
