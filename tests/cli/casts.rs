//! Counts computed from flags and file values (cells, intervals, bins, steps a day) are checked,
//! never wrapped or saturated by a float-to-integer cast; tiny or absurd numbers are refused
//! with the flag or the file named, and numbers in messages are printed short (`1e308`).

use crate::common;

use common::{assert_mentions, chronomap, error, repo, scratch, usage_error, write_arg};

/// `chronomap psbt` on the bundled ATC map and one hour of tracks with `extra` flags.
fn psbt(extra: &[&str]) -> std::process::Output {
    psbt_from("--from=21.25,-18.25", extra)
}

/// [`psbt`] with help requested at `from` (`--from=x,y`).
fn psbt_from(from: &str, extra: &[&str]) -> std::process::Output {
    let map = repo("data/atc_copa_map_grid/atc_map.yaml");
    let tracks = repo("data/atc_20121024_1hz/atc-1024-13_train.csv.xz");
    let args = [
        "psbt",
        "--map",
        &map,
        "--activity",
        &tracks,
        from,
        "--time",
        "2012-10-24T05:30Z",
    ];
    chronomap(&[&args[..], extra].concat())
}

/// A tiny `--interval` or `--cell` gave "0 intervals" (the count saturated and `+ 1` wrapped)
/// or a grid of 18446744073709551615 columns; now a usage error names the flag.
#[test]
fn psbt_refuses_a_tiny_interval_or_cell_naming_the_flag() {
    let err = usage_error(&psbt(&["--interval", "1e-300"]));
    assert_mentions(&err, &["--interval 1e-300", "intervals", "at most"]);
    assert!(!err.contains("0 intervals"), "{err}");
    let err = usage_error(&psbt(&["--interval", "1e-6"]));
    assert_mentions(&err, &["--interval 1e-6", "intervals; at most 268435456"]);
    let err = usage_error(&psbt(&["--cell", "1e-300"]));
    assert_mentions(&err, &["--cell 1e-300", "columns; at most 268435456"]);
    assert!(!err.contains("18446744073709551615"), "{err}");
}

/// `--places 0` was accepted (a tree of no places); now 1 to 16, a usage error otherwise.
#[test]
fn psbt_refuses_zero_places() {
    for places in ["0", "17"] {
        let err = usage_error(&psbt(&["--places", places]));
        assert_mentions(&err, &["--places", "1..=16"]);
    }
}

/// A region of 1e300 × 1e300 cells was reported as 18446744073709551615 × … cells (saturated);
/// now the cell count is checked and printed as it is, naming `--cell`.
#[test]
fn activity_predict_refuses_a_tiny_cell_naming_the_flag() {
    let err = usage_error(&chronomap(&[
        "activity",
        "predict",
        "--model",
        "unread.cmcopa",
        "--t",
        "1",
        "--region",
        "0",
        "0",
        "1",
        "1",
        "--cell",
        "1e-300",
    ]));
    assert_mentions(&err, &["--cell 1e-300", "e299 x", "at most 268435456"]);
    assert!(!err.contains("18446744073709551615"), "{err}");
}

/// A tiny `--bin` made every bin index saturate to one (t0 was infinite); now refused.
#[test]
fn activity_extract_refuses_a_tiny_bin_naming_the_flag() {
    let err = usage_error(&chronomap(&[
        "activity",
        "extract",
        "--tracks",
        &repo("data/atc_20121024_1hz/atc-1024-10_train.csv.xz"),
        "--map",
        &repo("data/atc_copa_map_grid/atc_map.yaml"),
        "--paths",
        &repo("data/atc_20121024_1hz/robot_paths.csv"),
        "--bin",
        "1e-300",
        "-o",
        &scratch("casts_extract").join("x.csv").display().to_string(),
    ]));
    assert_mentions(&err, &["--bin 1e-300", "bins", "at most 16777216"]);
}

/// An Aruba directory whose step is 1e-300 s: steps a day saturated to usize::MAX and the
/// error blamed the slot length; now the file's step is named (a file value: exit 1).
#[test]
fn explore_refuses_a_step_too_short_for_a_count_of_steps_a_day() {
    let dir = scratch("casts_explore");
    write_arg(&dir, "presence_minutes_0.txt", "0 0\n1e-300 1\n2e-300 0\n");
    let err = error(&chronomap(&[
        "explore",
        "--dataset",
        "aruba",
        "--data",
        &dir.display().to_string(),
        "--ratio",
        "0.5",
    ]));
    assert_mentions(
        &err,
        &["step 1e-300 s gives", "steps a day; at most 16777216"],
    );
}

/// `fit --periods 1e-300` was accepted; now a usage error names the flag and the shortest
/// period.
#[test]
fn fit_refuses_periods_shorter_than_a_millisecond() {
    let dir = scratch("casts_periods");
    let train = write_arg(&dir, "train.txt", "0 0\n60 1\n120 0\n");
    let model = dir.join("m.cmm").display().to_string();
    for periods in ["1e-300", "60,1e-300", "1/10000"] {
        let err = usage_error(&chronomap(&[
            "fit",
            "--train",
            &train,
            "--model",
            "fremen:2",
            "--periods",
            periods,
            "-o",
            &model,
        ]));
        assert_mentions(
            &err,
            &["--periods", "shorter than the shortest period 0.001 s"],
        );
    }
}

/// Numbers in errors print in their shortest form, not as 309-digit decimals.
#[test]
fn errors_print_huge_numbers_short() {
    let err = error(&chronomap(&["monitor", "sim", "--hours", "1e308"]));
    assert_mentions(&err, &["--hours 1e308:"]);
    let err = error(&psbt_from("--from=1e308,0", &[]));
    assert_mentions(&err, &["(1e308, 0)"]);
    assert!(!err.contains("00000000000000000000"), "{err}");
}

/// An empty or truncated `.xz` said "failed to fill whole buffer"; now it says what it is.
#[test]
fn an_empty_or_truncated_xz_file_says_so() {
    let dir = scratch("casts_xz");
    let empty = write_arg(&dir, "empty.txt.xz", "");
    let whole = std::fs::read(repo("data/door_greg_2016/training_data.txt.xz")).unwrap();
    let cut = write_arg(&dir, "cut.txt.xz", &whole[..whole.len() / 2]);
    let model = dir.join("m.cmm").display().to_string();
    for file in [&empty, &cut] {
        let err = error(&chronomap(&[
            "fit", "--train", file, "--model", "fremen:2", "-o", &model,
        ]));
        assert_mentions(&err, &[file.as_str(), "truncated or empty .xz file"]);
        assert!(!err.contains("failed to fill whole buffer"), "{err}");
    }
}

/// `hypertime --cell 1e-300` made the map's cell count saturate and `+ 1` wrap; now refused
/// naming the flag.
#[test]
fn hypertime_refuses_a_tiny_map_cell_naming_the_flag() {
    let err = usage_error(&chronomap(&[
        "hypertime",
        "--train",
        &repo(
            "data/lincoln_pedestrians_2017/whytes/wednesday_thursday_days_nights_only_ones.txt.xz",
        ),
        "--at",
        "2017-05-26T10:00Z",
        "--cell",
        "1e-300",
    ]));
    assert_mentions(
        &err,
        &["--cell 1e-300", "more than 268435456 cells along an axis"],
    );
}
