//! Groot2 `.btlog` files from a scripted run of the bundled door tree, byte by byte, and the
//! outcome-script reader.

use std::path::PathBuf;
use std::time::Duration;

use chronomap_bt::script::{run_script, scripted_registry};
use chronomap_bt::{Registry, Status, Transition, Tree};
use chronomap_io::bt_log::{
    BtLogErrorKind, LoggedTransition, decode_btlog, encode_btlog, encode_transition, read_btlog,
    write_btlog,
};
use chronomap_io::bt_script::{BtScriptErrorKind, parse_bt_script, read_bt_script};
use chronomap_io::bt_xml::{encode_tree_xml, read_bt_xml};

use crate::common::bt_example as example;

/// Runs door.xml through door.script: the tree and every transition.
fn door_run() -> (Tree, Vec<Transition>, Vec<Status>) {
    let doc = read_bt_xml(example("door.xml"), &Registry::new())
        .unwrap()
        .document;
    let script = read_bt_script(example("door.script")).unwrap();
    let (registry, outcomes) = scripted_registry(&doc).unwrap();
    let mut tree = Tree::new(&doc, &registry).unwrap();
    let run = run_script(&mut tree, &outcomes, &script, Duration::from_millis(100)).unwrap();
    assert!(run.finished);
    let statuses = run.ticks.iter().map(|t| t.status).collect();
    let transitions = run.ticks.into_iter().flat_map(|t| t.transitions).collect();
    (tree, transitions, statuses)
}

#[test]
fn door_script_succeeds_on_the_third_attempt_at_the_lock() {
    let (tree, transitions, statuses) = door_run();
    use Status::{Running as R, Success as S};
    assert_eq!(statuses, [R, R, R, R, S]);
    let pick_lock = tree
        .nodes()
        .iter()
        .find(|n| n.id() == "PickLock")
        .unwrap()
        .uid();
    assert_eq!(pick_lock, 9);
    let starts: Vec<u128> = transitions
        .iter()
        .filter(|t| t.uid == pick_lock && t.from == Status::Idle)
        .map(|t| t.time.as_millis())
        .collect();
    // Attempt 1 runs at tick 1 and fails at tick 2, attempt 2 fails at once at tick 2 (then
    // the retry yields), attempt 3 runs at tick 3 and succeeds at tick 4 (1000 ms).
    assert_eq!(starts, [0, 100, 200]);
    let done = transitions
        .iter()
        .find(|t| t.uid == pick_lock && t.to == Status::Success)
        .unwrap();
    assert_eq!(done.time, Duration::from_millis(1000));
}

#[test]
fn btlog_has_the_file_logger2_layout() {
    let (tree, transitions, _) = door_run();
    let start = Duration::from_micros(1_700_000_000_000_000);
    let shifted: Vec<Transition> = transitions
        .iter()
        .map(|t| Transition {
            time: t.time + start,
            ..*t
        })
        .collect();
    let bytes = encode_btlog(&tree, start, &shifted).unwrap();
    assert_eq!(&bytes[..18], b"BTCPP4-FileLogger2");
    assert_eq!(bytes[18], 1, "protocol");
    let length = i32::from_le_bytes(bytes[19..23].try_into().unwrap()) as usize;
    let xml = encode_tree_xml(&tree);
    assert_eq!(length, xml.len());
    assert_eq!(&bytes[23..23 + length], xml.as_bytes());
    let first = i64::from_le_bytes(bytes[23 + length..31 + length].try_into().unwrap());
    assert_eq!(first, 1_700_000_000_000_000);
    let records = &bytes[31 + length..];
    assert_eq!(records.len(), 9 * transitions.len());
    // The first transition: the root (uid 1) goes IDLE -> RUNNING at the start.
    assert_eq!(records[..9], [0, 0, 0, 0, 0, 0, 1, 0, 1]);
    // PickLock (uid 9) succeeds at 1000 ms = 0x0F4240 µs; status SUCCESS = 2.
    assert!(
        records
            .chunks(9)
            .any(|r| r == [0x40, 0x42, 0x0F, 0, 0, 0, 9, 0, 2]),
        "no PickLock success record"
    );
    // Every transition to IDLE is logged too (FileLogger2 enables them).
    assert!(records.chunks(9).any(|r| r[8] == 0));

    let log = decode_btlog(&bytes).unwrap();
    assert_eq!(log.xml, xml);
    assert_eq!(log.first_timestamp_us, 1_700_000_000_000_000);
    let expected: Vec<LoggedTransition> = transitions
        .iter()
        .map(|t| LoggedTransition {
            delta_us: t.time.as_micros() as u64,
            uid: t.uid,
            status: t.to.code(),
        })
        .collect();
    assert_eq!(log.transitions, expected);
}

#[test]
fn btlog_files_need_the_btlog_extension_and_times_after_the_start() {
    let (tree, transitions, _) = door_run();
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("bt_log_files");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("door.btlog");
    write_btlog(&path, &tree, Duration::ZERO, &transitions).unwrap();
    assert_eq!(
        read_btlog(&path).unwrap().transitions.len(),
        transitions.len()
    );

    let e = write_btlog(dir.join("door.log"), &tree, Duration::ZERO, &transitions).unwrap_err();
    assert!(matches!(e.kind(), BtLogErrorKind::Extension), "{e}");
    assert!(
        e.to_string()
            .ends_with("door.log: the file name must end in .btlog (Groot2 opens only those)")
    );

    let e = encode_btlog(&tree, Duration::from_millis(50), &transitions).unwrap_err();
    assert!(
        matches!(e.kind(), BtLogErrorKind::BeforeStart { uid: 1, .. }),
        "{e}"
    );

    let late = Transition {
        time: Duration::from_secs(300_000_000),
        ..transitions[0]
    };
    let e = encode_transition(Duration::ZERO, &late).unwrap_err();
    assert!(matches!(e.kind(), BtLogErrorKind::TooLate { .. }), "{e}");
    let edge = Transition {
        time: Duration::from_micros((1 << 48) - 1),
        ..transitions[0]
    };
    assert_eq!(
        encode_transition(Duration::ZERO, &edge).unwrap()[..6],
        [0xFF; 6]
    );
}

#[test]
fn damaged_btlogs_are_rejected_with_the_byte_offset() {
    let (tree, transitions, _) = door_run();
    let bytes = encode_btlog(&tree, Duration::ZERO, &transitions).unwrap();
    let e = decode_btlog(&bytes[..bytes.len() - 4]).unwrap_err();
    let whole = bytes.len() - 9;
    assert_eq!(
        e.to_string(),
        format!(
            "not a BehaviorTree.CPP FileLogger2 log: byte {whole}: 5 bytes left after the last whole transition"
        )
    );
    let e = decode_btlog(&bytes[..100]).unwrap_err();
    assert!(
        e.to_string()
            .contains("runs past the end of the file (100 bytes)"),
        "{e}"
    );
    let mut wrong = bytes.clone();
    wrong[18] = 2;
    assert!(
        decode_btlog(&wrong)
            .unwrap_err()
            .to_string()
            .contains("byte 18: protocol 2")
    );
    assert!(decode_btlog(b"BTCPP3").is_err());
}

// ---------------------------------------------------------------------------------------------
// Scripts

#[test]
fn scripts_read_ticks_times_outcomes_and_comments() {
    let script = parse_bt_script(
        "s.txt",
        "# header\n\ntick 1: A=success, B = Running # trailing\ntick 2@ 150ms:\ntick 5 @300: A=FAILURE\n",
    )
    .unwrap();
    let ticks: Vec<(u64, Option<u64>, usize)> = script
        .ticks
        .iter()
        .map(|t| (t.tick, t.at_ms, t.outcomes.len()))
        .collect();
    assert_eq!(ticks, [(1, None, 2), (2, Some(150), 0), (5, Some(300), 1)]);
    assert_eq!(
        script.ticks[0].outcomes,
        [
            ("A".to_owned(), Status::Success),
            ("B".to_owned(), Status::Running)
        ]
    );
    assert_eq!(
        script.ticks[2].outcomes,
        [("A".to_owned(), Status::Failure)]
    );
}

#[test]
fn script_errors_name_the_line() {
    let cases = [
        (
            "tick 1: A=success\ntock 2: A=failure\n",
            2,
            "\"tock 2: A=failure\" does not start with `tick`",
        ),
        ("tick 1 A=success\n", 1, "no `:` after the tick number"),
        (
            "tick one: A=success\n",
            1,
            "tick: \"one\" is not a whole number",
        ),
        (
            "tick 0: A=success\n",
            1,
            "tick: \"0\" is not a whole number",
        ),
        (
            "tick 1 @ -5: A=success\n",
            1,
            "time: \"-5\" is not a whole number",
        ),
        (
            "tick 1: A=idle\n",
            1,
            "outcome of \"A\": \"idle\" is not success, failure or running",
        ),
        ("tick 1: A=success, A=failure\n", 1, "\"A\" is given twice"),
        ("tick 1: A\n", 1, "\"A\" is not name=outcome"),
        ("tick 1: =success\n", 1, "\"=success\" has no name"),
        (
            "tick 2: A=success\n\ntick 2: A=failure\n",
            3,
            "tick 2 does not come after tick 2 (line 1)",
        ),
    ];
    for (text, line, message) in cases {
        let e = parse_bt_script("s.txt", text).unwrap_err();
        assert_eq!(e.line(), Some(line), "{text:?}: {e}");
        assert!(
            e.to_string()
                .starts_with(&format!("s.txt:{line}: {message}")),
            "{text:?}: {e}"
        );
    }
    assert!(matches!(
        read_bt_script("no/such/dir/s.txt").unwrap_err().kind(),
        BtScriptErrorKind::Io(_)
    ));
}
