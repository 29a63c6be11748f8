//! Event files (people detected at `t x y`): bad input is reported with file, line and field,
//! the range-header format is read and checked, and the bundled Lincoln files read with their
//! documented numbers of detections.

use std::io::Write;
use std::path::PathBuf;

use chronomap_hypertime::events::Event;
use chronomap_io::events::{read_event_files, read_events, read_events_from};
use chronomap_io::text::{DataError, DataErrorKind, Field};

fn data(relative: &str) -> PathBuf {
    chronomap_testutil::data_path("lincoln_pedestrians_2017").join(relative)
}

fn err(text: &str) -> DataError {
    read_events_from("people.txt", text.as_bytes()).expect_err(text)
}

/// Checks line, field and the whole message of an error about `people.txt`.
fn check(err: &DataError, line: Option<usize>, field: Option<Field>, message: &str) {
    crate::common::check(err, "people.txt", line, field, message);
}

/// Checks every `(text, line, field, message)` row: reading `text` fails on that line and
/// field with exactly that message.
fn check_rows(rows: &[(&str, usize, Field, &str)]) {
    for &(text, line, field, message) in rows {
        check(&err(text), Some(line), Some(field), message);
    }
}

#[test]
fn reads_events_with_extra_fields_comments_commas_and_equal_times() {
    let text = "# t x y weight\n\n10 1.5 -2 1.0000\r\n10,2,3\n11 0 0 7.9 1.1 WP4\n";
    let events = read_events_from("people.txt", text.as_bytes()).unwrap();
    assert_eq!(
        events,
        [
            Event {
                t: 10.0,
                x: 1.5,
                y: -2.0
            },
            Event {
                t: 10.0,
                x: 2.0,
                y: 3.0
            },
            Event {
                t: 11.0,
                x: 0.0,
                y: 0.0
            },
        ]
    );
}

#[test]
fn nan_inf_and_non_numeric_fields_name_line_and_field() {
    check_rows(&[
        (
            "1 0 0\n2 nan 0\n",
            2,
            Field::X,
            r#"people.txt:2: x: "nan" is not a finite number"#,
        ),
        (
            "1 0 0\n2 0 -inf\n",
            2,
            Field::Y,
            r#"people.txt:2: y: "-inf" is not a finite number"#,
        ),
        (
            "NaN 0 0\n",
            1,
            Field::Time,
            r#"people.txt:1: time: "NaN" is not a finite number"#,
        ),
        (
            "1 0 0\n\n2 0 north\n",
            3,
            Field::Y,
            r#"people.txt:3: y: "north" is not a number"#,
        ),
        (
            "1e400 0 0\n",
            1,
            Field::Time,
            r#"people.txt:1: time: "1e400" is not a finite number"#,
        ),
    ]);
}

#[test]
fn negative_and_backwards_times_are_rejected() {
    check(
        &err("-1 0 0\n"),
        Some(1),
        Some(Field::Time),
        r#"people.txt:1: time: "-1" is negative (times are seconds >= 0)"#,
    );
    let e = err("# header\n5 0 0\n5 1 1\n4.5 0 0\n");
    check(
        &e,
        Some(4),
        Some(Field::Time),
        r#"people.txt:4: time: "4.5" is earlier than the time 5 on line 3 (times must not go backwards)"#,
    );
    assert!(matches!(
        e.kind(),
        DataErrorKind::TimeNotIncreasing {
            previous_line: 3,
            ..
        }
    ));
}

#[test]
fn missing_fields_are_named() {
    check_rows(&[
        (
            "1 0 0\n2 0\n",
            2,
            Field::Y,
            "people.txt:2: y: missing (expected at least three fields: t x y)",
        ),
        (
            "1 0 0\n2,,3\n",
            2,
            Field::X,
            "people.txt:2: x: missing (expected at least three fields: t x y)",
        ),
    ]);
    // A first line of two fields starts a range header; if the next line is an event, the
    // message says both what was expected and what was probably meant.
    let e = err("0 1\n2 0 0\n");
    assert_eq!(e.line(), Some(2));
    assert!(e.to_string().contains("or is y missing on line 1?"), "{e}");
    check(
        &err("\n# nothing\n"),
        None,
        None,
        "people.txt: no data lines (the input is empty or has only blank lines and # comments)",
    );
}

#[test]
fn range_headers_are_read_and_checked() {
    let text = "0 100\n-8 12\n-3 17\n1 0 0\n50 2.5 -1.9\n99 0 0\n";
    let events = read_events_from("people.txt", text.as_bytes()).unwrap();
    assert_eq!(events.len(), 3);
    check_rows(&[
        (
            "0 100\n-8 12\n-3 17\n101 0 0\n",
            4,
            Field::Time,
            r#"people.txt:4: time: "101" is outside the range 0 .. 100 of the header"#,
        ),
        (
            "0 100\n12 -8\n-3 17\n1 0 0\n",
            2,
            Field::X,
            "people.txt:2: x: the range 12 .. -8 of the header is empty (min must not exceed max)",
        ),
        (
            "0 100\n-8 12\n-3 x\n1 0 0\n",
            3,
            Field::Y,
            r#"people.txt:3: y: "x" is not a number"#,
        ),
    ]);
    let e = err("0 100\n-8 12\n-3 17\n");
    assert!(matches!(e.kind(), DataErrorKind::BadHeader { .. }), "{e}");
}

#[test]
fn plain_gzip_and_xz_files_read_the_same_and_merge_in_time_order() {
    let dir = std::env::temp_dir().join(format!("chronomap-io-events-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let plain = dir.join("a.txt");
    std::fs::write(&plain, "1 0 0\n3 1 1\n").unwrap();
    let gz = dir.join("b.txt.gz");
    let mut encoder =
        flate2::write::GzEncoder::new(std::fs::File::create(&gz).unwrap(), Default::default());
    encoder.write_all(b"2 5 5\n4 6 6\n").unwrap();
    encoder.finish().unwrap();
    let merged = read_event_files(&[&plain, &gz]).unwrap();
    let times: Vec<f64> = merged.iter().map(|e| e.t).collect();
    assert_eq!(times, [1.0, 2.0, 3.0, 4.0]);
    let missing = dir.join("missing.txt");
    let e = read_event_files(&[&plain, &missing]).unwrap_err();
    assert_eq!(e.name(), missing.display().to_string());
    assert!(matches!(e.kind(), DataErrorKind::Io { action: "open", .. }));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bundled_lincoln_files_have_documented_counts() {
    let whytes = read_events(data(
        "whytes/wednesday_thursday_days_nights_only_ones.txt.xz",
    ))
    .unwrap();
    assert_eq!(whytes.len(), 61_489);
    // Wednesday 2017-05-24 (UTC) has 29,938 detections, Thursday 31,551.
    let thursday = 1_495_670_400.0;
    assert_eq!(whytes.iter().filter(|e| e.t < thursday).count(), 29_938);
    let raw_thursday = read_events(data("raw_days/2017_05_25.txt.xz")).unwrap();
    assert_eq!(raw_thursday.len(), 34_429);
    let friday = read_events(data("raw_days/2017_05_26.txt.xz")).unwrap();
    assert_eq!(friday.len(), 22_449);
    assert_eq!(friday[0].t, 1_495_792_639.39);
    assert_eq!(friday[friday.len() - 1].t, 1_495_817_745.59);
}
