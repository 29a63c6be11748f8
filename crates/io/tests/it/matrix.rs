//! State matrices: the bundled Brayford feature week and clear errors for bad lines.

use chronomap_io::{read_state_matrix, read_state_matrix_from};

#[test]
fn the_brayford_feature_week() {
    let path = chronomap_testutil::data_path("brayford_week/features_0.txt.xz");
    let rows = read_state_matrix(path).unwrap();
    assert_eq!((rows.len(), rows[0].len()), (10_080, 111));
    // Every slot is written on 10 identical lines.
    assert!((0..rows.len()).all(|i| rows[i] == rows[i - i % 10]));
    let ones: f64 = rows.iter().step_by(10).flatten().sum();
    assert!((ones / (1008.0 * 111.0) - 0.168).abs() < 0.0005);
}

#[test]
fn bad_lines_name_the_line_and_field() {
    let read = |text: &str| {
        read_state_matrix_from("m.txt", text.as_bytes())
            .unwrap_err()
            .to_string()
    };
    let e = read("0 1 0\n1 2 0\n");
    assert!(
        e.contains("m.txt:2") && e.contains("value") && e.contains("\"2\""),
        "{e}"
    );
    let e = read("0 1 0\n1 1\n");
    assert!(e.contains("m.txt:2") && e.contains("missing"), "{e}");
    let e = read("0 1 0\n1 1 0 1\n");
    assert!(e.contains("m.txt:2") && e.contains("extra"), "{e}");
    let e = read("# nothing\n\n");
    assert!(e.contains("no data lines"), "{e}");
    assert_eq!(
        read_state_matrix_from("m.txt", "1 0\n# c\n0 1\n".as_bytes()).unwrap(),
        vec![vec![1.0, 0.0], vec![0.0, 1.0]]
    );
}
