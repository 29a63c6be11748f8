//! Dataset readers: every kind of bad input is reported with file, line and field, and every
//! bundled data file reads with its documented number of lines.

use crate::common::check;
use chronomap_testutil::data_path as data;
use std::io::Write;

use chronomap_io::text::{
    DataError, DataErrorKind, Field, read_column, read_column_from, read_pairs, read_pairs_from,
    read_test_set, read_test_set_from,
};

fn pairs_err(text: &str) -> DataError {
    read_pairs_from("pairs.txt", text.as_bytes()).expect_err(text)
}

/// Reads `text` as `pairs.txt`, checks that it fails with this line, field and whole
/// message, and returns the error.
fn pairs_rejected(
    text: &str,
    line: Option<usize>,
    field: Option<Field>,
    message: &str,
) -> DataError {
    let err = pairs_err(text);
    check(&err, "pairs.txt", line, field, message);
    err
}

#[test]
fn reads_pairs_with_comments_blank_lines_commas_and_crlf() {
    let text = "\u{feff}# door\n\n0 0\r\n60\t1\n120,0.5\n  180 , 1  \n# end\n";
    let series = read_pairs_from("door", text.as_bytes()).unwrap();
    assert_eq!(series.times, [0.0, 60.0, 120.0, 180.0]);
    assert_eq!(series.values, [0.0, 1.0, 0.5, 1.0]);
    // equal times are allowed (two observations at one instant)
    assert_eq!(
        read_pairs_from("d", "5 0\n5 1\n".as_bytes()).unwrap().len(),
        2
    );
    // a last line without a line end
    assert_eq!(
        read_pairs_from("d", "5 0\n6 1".as_bytes()).unwrap().len(),
        2
    );
}

/// A bad input of `pairs.txt`: the text, the line and field of the error, its whole message and
/// a test of its kind.
type BadPairs<'a> = (&'a str, usize, Field, &'a str, fn(&DataErrorKind) -> bool);

/// Checks every row: reading the text as `pairs.txt` fails on that line and field with exactly
/// that message and an error kind the test accepts.
fn check_pairs_rows(rows: &[BadPairs<'_>]) {
    for &(text, line, field, message, is_kind) in rows {
        let err = pairs_rejected(text, Some(line), Some(field), message);
        assert!(is_kind(err.kind()), "{err}");
    }
}

#[test]
fn non_numeric_fields_name_line_field_and_text() {
    check_pairs_rows(&[
        (
            "# header\n0 0\n\nabc 1\n",
            4,
            Field::Time,
            r#"pairs.txt:4: time: "abc" is not a number"#,
            |k| matches!(k, DataErrorKind::NotANumber { field: Field::Time, text } if text == "abc"),
        ),
        (
            "0 0\n1 open\n",
            2,
            Field::Value,
            r#"pairs.txt:2: value: "open" is not a number"#,
            |k| matches!(k, DataErrorKind::NotANumber { .. }),
        ),
    ]);
    // a header line is a non-numeric time
    let err = pairs_err("time,value\n0,1\n");
    assert!(matches!(
        err.kind(),
        DataErrorKind::NotANumber {
            field: Field::Time,
            ..
        }
    ));
    assert_eq!(err.line(), Some(1));
}

#[test]
fn non_finite_and_negative_times_are_rejected() {
    let non_finite = |k: &DataErrorKind| matches!(k, DataErrorKind::NonFinite { .. });
    check_pairs_rows(&[
        (
            "0 0\nnan 0\n",
            2,
            Field::Time,
            r#"pairs.txt:2: time: "nan" is not a finite number"#,
            non_finite,
        ),
        (
            "0 0\ninf 0\n",
            2,
            Field::Time,
            r#"pairs.txt:2: time: "inf" is not a finite number"#,
            non_finite,
        ),
        (
            "0 0\n1e999 0\n",
            2,
            Field::Time,
            r#"pairs.txt:2: time: "1e999" is not a finite number"#,
            non_finite,
        ),
        (
            "0 0\n1 NaN\n",
            2,
            Field::Value,
            r#"pairs.txt:2: value: "NaN" is not a finite number"#,
            non_finite,
        ),
        (
            "0 0\n1 -inf\n",
            2,
            Field::Value,
            r#"pairs.txt:2: value: "-inf" is not a finite number"#,
            non_finite,
        ),
        (
            "-1 0\n",
            1,
            Field::Time,
            r#"pairs.txt:1: time: "-1" is negative (times are seconds >= 0)"#,
            |k| matches!(k, DataErrorKind::NegativeTime { .. }),
        ),
    ]);
}

#[test]
fn times_going_backwards_name_both_lines() {
    check_pairs_rows(&[(
        "10 0\n# x\n20 1\n\n15 0\n",
        5,
        Field::Time,
        r#"pairs.txt:5: time: "15" is earlier than the time 20 on line 3 (times must not go backwards)"#,
        |k| matches!(k, DataErrorKind::TimeNotIncreasing { previous, previous_line: 3, .. } if *previous == 20.0),
    )]);
    let err = read_column_from("times.txt", "3\n2\n".as_bytes(), Field::Time).unwrap_err();
    assert!(matches!(
        err.kind(),
        DataErrorKind::TimeNotIncreasing { .. }
    ));
    assert_eq!((err.line(), err.field()), (Some(2), Some(Field::Time)));
}

#[test]
fn values_outside_unit_interval_are_rejected() {
    for (text, shown) in [("0 1.5\n", "1.5"), ("0 -0.1\n", "-0.1"), ("0 2\n", "2")] {
        let err = pairs_rejected(
            text,
            Some(1),
            Some(Field::Value),
            &format!("pairs.txt:1: value: {shown:?} is outside [0, 1]"),
        );
        assert!(matches!(err.kind(), DataErrorKind::ValueOutOfRange { .. }));
    }
}

#[test]
fn missing_and_extra_fields_are_rejected() {
    check_pairs_rows(&[(
        "0 0\n60\n",
        2,
        Field::Value,
        "pairs.txt:2: value: missing (expected two fields: time value)",
        |k| matches!(k, DataErrorKind::MissingField { .. }),
    )]);
    for (text, missing) in [
        ("0 0\n60\n", Field::Value),
        ("0,,1\n", Field::Value),
        (",1\n", Field::Time),
    ] {
        let err = pairs_err(text);
        assert!(
            matches!(err.kind(), DataErrorKind::MissingField { field, .. } if *field == missing),
            "{err}"
        );
    }
    let err = pairs_rejected(
        "0 0\n60 1 1\n",
        Some(2),
        None,
        r#"pairs.txt:2: unexpected extra field "1" (expected two fields: time value)"#,
    );
    assert!(matches!(err.kind(), DataErrorKind::ExtraField { text, .. } if text == "1"));
    let err = read_column_from("v.txt", "0\n1 1\n".as_bytes(), Field::Value).unwrap_err();
    assert_eq!(
        err.to_string(),
        r#"v.txt:2: unexpected extra field "1" (expected one value per line)"#
    );
}

#[test]
fn empty_inputs_are_rejected() {
    for text in ["", "\n\n", "# only a comment\n  \n"] {
        let err = pairs_rejected(
            text,
            None,
            None,
            "pairs.txt: no data lines (the input is empty or has only blank lines and # comments)",
        );
        assert!(matches!(err.kind(), DataErrorKind::Empty));
        let err = read_column_from("c.txt", text.as_bytes(), Field::Time).unwrap_err();
        assert!(matches!(err.kind(), DataErrorKind::Empty));
    }
}

#[test]
fn test_sets_with_different_line_counts_name_both_files() {
    let err = read_test_set_from(
        "times.txt",
        "0\n60\n120\n".as_bytes(),
        "values.txt",
        "0\n# c\n1\n".as_bytes(),
    )
    .unwrap_err();
    assert!(matches!(
        err.kind(),
        DataErrorKind::LineCountMismatch { times: 3, values: 2, times_name } if times_name == "times.txt"
    ));
    check(
        &err,
        "values.txt",
        None,
        None,
        "values.txt: 2 values but times.txt has 3 times (the two files of a test set must be line-aligned)",
    );
    // errors inside either file name that file
    let err = read_test_set_from("t", "0\n1\n".as_bytes(), "v", "0\n7\n".as_bytes()).unwrap_err();
    assert_eq!(
        (err.name(), err.line(), err.field()),
        ("v", Some(2), Some(Field::Value))
    );
}

#[test]
fn binary_garbage_and_huge_lines_give_errors_not_panics() {
    let garbage: Vec<u8> = (0..=255u8).cycle().take(5000).collect();
    let err = read_pairs_from("garbage.bin", garbage.as_slice()).unwrap_err();
    assert_eq!(err.name(), "garbage.bin");
    let long = vec![b'1'; 200_000];
    let err = read_pairs_from("long.txt", long.as_slice()).unwrap_err();
    assert!(
        matches!(err.kind(), DataErrorKind::LineTooLong { .. }),
        "{err}"
    );
    assert_eq!(err.line(), Some(1));
    // long offending text is shortened in the message
    let err = pairs_err(&format!("{} 0\n", "x".repeat(1000)));
    assert!(err.to_string().len() < 120, "{err}");
}

#[test]
fn missing_files_name_the_path() {
    let path = data("door_greg_2016/no_such_file.txt");
    let err = read_pairs(&path).unwrap_err();
    assert!(matches!(
        err.kind(),
        DataErrorKind::Io { action: "open", .. }
    ));
    assert_eq!(err.name(), path.display().to_string());
    assert!(
        err.to_string()
            .starts_with(&format!("{}: cannot open: ", path.display()))
    );
    let err = read_test_set(data("door_greg_2016/test_times_1.txt.xz"), &path).unwrap_err();
    assert_eq!(err.name(), path.display().to_string());
}

#[test]
fn plain_gzip_and_xz_files_read_the_same() {
    let dir = std::env::temp_dir().join(format!("chronomap-io-text-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = "0 0\n60 1\n120 0\n";
    let plain = dir.join("d.txt");
    std::fs::write(&plain, text).unwrap();
    let gz = dir.join("d.txt.gz");
    let mut encoder =
        flate2::write::GzEncoder::new(std::fs::File::create(&gz).unwrap(), Default::default());
    encoder.write_all(text.as_bytes()).unwrap();
    encoder.finish().unwrap();
    let expected = read_pairs_from("d", text.as_bytes()).unwrap();
    assert_eq!(read_pairs(&plain).unwrap(), expected);
    assert_eq!(read_pairs(&gz).unwrap(), expected);

    // a corrupt compressed file is a read error that names the file
    let corrupt: [(&str, &[u8]); 2] = [
        ("bad.txt.xz", b"\xFD7zXZ\0 definitely not xz"),
        ("bad.txt.gz", b"not gzip at all"),
    ];
    for (name, bytes) in corrupt {
        let bad = dir.join(name);
        std::fs::write(&bad, bytes).unwrap();
        let err = read_pairs(&bad).unwrap_err();
        assert!(
            matches!(err.kind(), DataErrorKind::Io { action: "read", .. }),
            "{err}"
        );
        assert_eq!(err.name(), bad.display().to_string());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bundled_greg_files_have_documented_line_counts() {
    let training = read_pairs(data("door_greg_2016/training_data.txt.xz")).unwrap();
    assert_eq!(training.len(), 96_480);
    let open = training.values.iter().sum::<f64>() / training.len() as f64;
    assert!((open - 0.118).abs() < 0.001, "fraction open {open}");
    for n in 1..=5 {
        let set = read_test_set(
            data(&format!("door_greg_2016/test_times_{n}.txt.xz")),
            data(&format!("door_greg_2016/test_data_{n}.txt.xz")),
        )
        .unwrap();
        assert_eq!(set.len(), 10_081, "test set {n}");
        assert!(set.times[0] > *training.times.last().unwrap());
    }
}

#[test]
fn bundled_tom_files_read() {
    let training = read_pairs(data("door_tom_2013/min/training_data.txt.xz")).unwrap();
    assert_eq!(training.times[..2], [59.0, 119.0]);
    for n in 0..=3 {
        let set = read_test_set(
            data(&format!("door_tom_2013/min/test_times_{n}.txt.xz")),
            data(&format!("door_tom_2013/min/test_data_{n}.txt.xz")),
        )
        .unwrap();
        assert!(!set.is_empty());
    }
    for (n, count) in [(1, 86_400), (2, 86_400), (3, 86_400)] {
        let set = read_test_set(
            data(&format!("door_tom_2013/sec/test_times_{n}.txt.xz")),
            data(&format!("door_tom_2013/sec/test_data_{n}.txt.xz")),
        )
        .unwrap();
        assert_eq!(set.len(), count, "sec test set {n}");
    }
}

#[test]
fn bundled_tom_second_week_has_604800_lines() {
    let start = std::time::Instant::now();
    let times = read_column(data("door_tom_2013/sec/test_times_0.txt.xz"), Field::Time).unwrap();
    let elapsed = start.elapsed();
    assert_eq!(times.len(), 604_800);
    eprintln!("read 604,800 times in {elapsed:?}");
    let set = read_test_set(
        data("door_tom_2013/sec/test_times_0.txt.xz"),
        data("door_tom_2013/sec/test_data_0.txt.xz"),
    )
    .unwrap();
    assert_eq!(set.len(), 604_800);
    let occupied = set.values.iter().sum::<f64>() / set.len() as f64;
    assert!(
        (occupied - 0.258).abs() < 0.01,
        "fraction occupied {occupied}"
    );
}
