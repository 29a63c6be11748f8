//! `chronomap bt check` and `chronomap bt run` on the bundled door tree (tests/data/bt): the
//! printed structure with uids, the tick-by-tick trace of a scripted run, the Groot2 log it
//! writes, and exit code 1 with located messages for bad files.

use std::process::Output;

use crate::common;

use common::{chronomap, close, error, repo, scratch, stdout, write, write_arg};

/// The script of a run of the door tree that succeeds at tick 5.
const DOOR_SCRIPT: &str = "tests/data/bt/door.script";

/// `chronomap bt run` of the door tree with `script` and `extra` flags.
fn run_door(script: &str, extra: &[&str]) -> Output {
    let door = repo("tests/data/bt/door.xml");
    chronomap(&[&["bt", "run", &door, "--script", script][..], extra].concat())
}

#[test]
fn check_prints_the_door_tree_with_uids_depth_first_through_the_subtree() {
    let door = repo("tests/data/bt/door.xml");
    let text = stdout(&chronomap(&["bt", "check", &door]));
    let expected = format!(
        "{door}: BehaviorTree.CPP 4, 2 trees (MainTree, DoorClosed); MainTree has 11 nodes, 5 of them leaves
 uid  node
   1  Sequence \"cross_door\"
   2    Fallback
   3      Inverter
   4        IsDoorClosed (Condition)
   5      SubTree DoorClosed \"open_it\" door={{door}}
   6        Fallback \"try_to_open\"
   7          OpenDoor (Action) door={{door}}
   8          RetryUntilSuccessful num_attempts=3
   9            PickLock (Action) door={{door}}
  10          SmashDoor (Action) door={{door}}
  11    PassThroughDoor (Action) door={{door}}
"
    );
    assert_eq!(text, expected);
}

#[test]
fn check_can_print_another_tree_and_save_the_canonical_form() {
    let dir = scratch("bt_check_save");
    let saved = dir.join("door_canonical.xml").display().to_string();
    let door = repo("tests/data/bt/door.xml");
    let text = stdout(&chronomap(&[
        "bt",
        "check",
        &door,
        "--tree",
        "DoorClosed",
        "--save",
        &saved,
    ]));
    assert!(
        text.contains("DoorClosed has 5 nodes, 3 of them leaves"),
        "{text}"
    );
    assert!(text.contains("   1  Fallback \"try_to_open\"\n"), "{text}");
    // The saved file checks again, with the same structure.
    let again = stdout(&chronomap(&["bt", "check", &saved]));
    let original = stdout(&chronomap(&["bt", "check", &door]));
    let table = |t: &str| t.split_once('\n').unwrap().1.to_owned();
    assert_eq!(table(&again), table(&original));
    let xml = std::fs::read_to_string(&saved).unwrap();
    assert!(xml.contains("<IsDoorClosed/>"), "compact form: {xml}");
}

#[test]
fn run_prints_every_transition_of_every_tick_and_writes_a_btlog() {
    let dir = scratch("bt_run_door");
    let log = dir.join("door.btlog").display().to_string();
    let text = stdout(&run_door(&repo(DOOR_SCRIPT), &["--btlog", &log]));
    let expected = format!(
        "\
tick 1 @ 0 ms: RUNNING
    1 cross_door            IDLE -> RUNNING
    2 Fallback              IDLE -> RUNNING
    3 Inverter              IDLE -> RUNNING
    4 IsDoorClosed          IDLE -> SUCCESS
    4 IsDoorClosed          SUCCESS -> IDLE
    3 Inverter              RUNNING -> FAILURE
    5 open_it               IDLE -> RUNNING
    6 try_to_open           IDLE -> RUNNING
    7 OpenDoor              IDLE -> FAILURE
    8 RetryUntilSuccessful  IDLE -> RUNNING
    9 PickLock              IDLE -> RUNNING
tick 2 @ 100 ms: RUNNING
    9 PickLock              RUNNING -> FAILURE
    9 PickLock              FAILURE -> IDLE
    9 PickLock              IDLE -> FAILURE
    9 PickLock              FAILURE -> IDLE
tick 3 @ 200 ms: RUNNING
    9 PickLock              IDLE -> RUNNING
tick 4 @ 1000 ms: RUNNING
    9 PickLock              RUNNING -> SUCCESS
    9 PickLock              SUCCESS -> IDLE
    8 RetryUntilSuccessful  RUNNING -> SUCCESS
    7 OpenDoor              FAILURE -> IDLE
    8 RetryUntilSuccessful  SUCCESS -> IDLE
    6 try_to_open           RUNNING -> SUCCESS
    6 try_to_open           SUCCESS -> IDLE
    5 open_it               RUNNING -> SUCCESS
    3 Inverter              FAILURE -> IDLE
    5 open_it               SUCCESS -> IDLE
    2 Fallback              RUNNING -> SUCCESS
   11 PassThroughDoor       IDLE -> RUNNING
tick 5 @ 1100 ms: SUCCESS
   11 PassThroughDoor       RUNNING -> SUCCESS
    2 Fallback              SUCCESS -> IDLE
   11 PassThroughDoor       SUCCESS -> IDLE
    1 cross_door            RUNNING -> SUCCESS
    1 cross_door            SUCCESS -> IDLE
result: SUCCESS at tick 5 (1100 ms)
wrote {log} (33 transitions of 11 nodes)
"
    );
    assert_eq!(text, expected);
    let bytes = std::fs::read(&log).unwrap();
    assert_eq!(&bytes[..19], b"BTCPP4-FileLogger2\x01");
    let parsed = chronomap_io::read_btlog(&log).unwrap();
    assert_eq!(parsed.transitions.len(), 33);
    assert_eq!(parsed.first_timestamp_us, 0);
    let last = parsed.transitions.last().unwrap();
    assert_eq!((last.delta_us, last.uid, last.status), (1_100_000, 1, 0));
}

#[test]
fn run_reports_a_tree_still_running_and_unused_script_ticks() {
    let dir = scratch("bt_run_partial");
    let script = write_arg(
        &dir,
        "short.script",
        "tick 1: IsDoorClosed=failure, PassThroughDoor=running\ntick 3: PassThroughDoor=success\ntick 4:\ntick 6:\n",
    );
    let text = stdout(&run_door(&script, &["--tick-ms", "250"]));
    assert!(text.starts_with("tick 1 @ 0 ms: RUNNING\n"), "{text}");
    assert!(text.contains("tick 3 @ 500 ms: SUCCESS\n"), "{text}");
    assert!(
        text.ends_with(
            "result: SUCCESS at tick 3 (500 ms)\nnote: the tree finished before script ticks 4, 6\n"
        ),
        "{text}"
    );

    write(
        &dir,
        "short.script",
        "tick 1: IsDoorClosed=failure, PassThroughDoor=running\n",
    );
    let text = stdout(&run_door(&script, &[]));
    assert!(
        text.ends_with("result: still RUNNING after tick 1 (0 ms)\n"),
        "{text}"
    );
}

#[test]
fn bad_files_and_scripts_exit_1_with_the_place_of_the_problem() {
    let dir = scratch("bt_errors");
    let bad = write_arg(
        &dir,
        "bad.xml",
        "<root BTCPP_format=\"4\">\n  <BehaviorTree ID=\"Main\">\n    <Repeat num_cycles=\"twice\">\n      <AlwaysSuccess/>\n    </Repeat>\n  </BehaviorTree>\n</root>\n",
    );
    let err = error(&chronomap(&["bt", "check", &bad]));
    assert_eq!(
        err,
        format!(
            "error: {bad}:3:13: attribute num_cycles=\"twice\" of \"Repeat\" is invalid (expected an integer)\n"
        )
    );

    let v3 = write_arg(&dir, "v3.xml", "<root BTCPP_format=\"3\">\n</root>\n");
    let err = error(&chronomap(&["bt", "check", &v3]));
    assert!(
        err.contains("v3.xml:1:7: attribute BTCPP_format=\"3\": only BehaviorTree.CPP format 4"),
        "{err}"
    );

    let two = write_arg(
        &dir,
        "two.xml",
        "<root BTCPP_format=\"4\">\n  <BehaviorTree ID=\"A\"><AlwaysSuccess/></BehaviorTree>\n  <BehaviorTree ID=\"B\"><AlwaysFailure/></BehaviorTree>\n</root>\n",
    );
    let err = error(&chronomap(&["bt", "check", &two]));
    assert!(
        err.contains("which tree? (use --tree): the document has several trees (A, B)"),
        "{err}"
    );
    let text = stdout(&chronomap(&["bt", "check", &two, "--tree", "B"]));
    assert!(text.contains("   1  AlwaysFailure (Action)\n"), "{text}");

    let err = error(&chronomap(&[
        "bt",
        "check",
        &dir.join("missing.xml").display().to_string(),
    ]));
    assert!(err.contains("missing.xml: cannot read:"), "{err}");

    // Scripts that do not fit the tree, and a log file of the wrong kind.
    let script = dir.join("typo.script").display().to_string();
    let log = dir.join("door.log").display().to_string();
    for (text, flags, says) in [
        (
            "tick 1: IsDoorClosed=success\ntick 2: PickLok=failure\n",
            &[][..],
            "typo.script: tick 2: the tree has no leaf named \"PickLok\" (its leaves: IsDoorClosed, OpenDoor, PassThroughDoor, PickLock, SmashDoor)",
        ),
        (
            "tick 1: IsDoorClosed=maybe\n",
            &[],
            "typo.script:1: outcome of \"IsDoorClosed\": \"maybe\"",
        ),
        (
            "tick 1: IsDoorClosed=failure\n",
            &[],
            "tick 1: node 11 (PassThroughDoor): ticked, but the script has given no outcome for \"PassThroughDoor\" yet",
        ),
        (
            "tick 1: IsDoorClosed=running\n",
            &[],
            "\"IsDoorClosed\" is a condition and cannot return RUNNING",
        ),
        (
            "tick 1: IsDoorClosed=failure, PassThroughDoor=success\n",
            &["--btlog", &log],
            "door.log: the file name must end in .btlog",
        ),
    ] {
        std::fs::write(&script, text).unwrap();
        let err = error(&run_door(&script, flags));
        assert!(err.contains(says), "{text}: {err}");
    }
}

/// `bt analyse` on the door tree with tests/data/bt/door_sbt.csv. Hand computation: the
/// subtree fails only if OpenDoor, three PickLock attempts and SmashDoor all fail,
/// 0.6 · 0.5³ · 0.2 = 0.015; the fallback succeeds with 0.3 + 0.7 · 0.985 = 0.9895 (the door is
/// open, or the subtree opens it); the sequence with 0.9895 · 0.95 = 0.940025.
#[test]
fn analyse_gives_the_hand_computed_probabilities_of_the_door_tree() {
    let dir = scratch("bt_analyse_door");
    let png = dir.join("door_sbt.png").display().to_string();
    let door = repo("tests/data/bt/door.xml");
    let params = repo("tests/data/bt/door_sbt.csv");
    let args = [
        "bt", "analyse", &door, "--params", &params, "--t-max", "120", "--steps", "4", "--json",
        "--plot", &png,
    ];
    let json: serde_json::Value = serde_json::from_str(&stdout(&chronomap(&args))).unwrap();
    close(&json["p_success"], 0.940025, 1e-12);
    close(&json["p_failure"], 0.059975, 1e-12);
    assert_eq!(json["tree"], "MainTree");
    let curve = json["curve"].as_array().unwrap();
    assert_eq!(curve.len(), 5);
    close(&curve[0]["t"], 0.0, 0.0);
    close(&curve[0]["p_success"], 0.0, 1e-15);
    close(&curve[4]["t"], 120.0, 1e-12);
    // Increasing towards the eventual values.
    let ps: Vec<f64> = curve
        .iter()
        .map(|p| p["p_success"].as_f64().unwrap())
        .collect();
    assert!(ps.windows(2).all(|w| w[0] < w[1]), "{ps:?}");
    assert!(ps[4] < 0.940025 && ps[4] > 0.93, "{ps:?}");
    let (ts, mu) = (
        json["time_to_success"].as_f64().unwrap(),
        json["mu_t"].as_f64().unwrap(),
    );
    assert!((ts * mu - 1.0).abs() < 1e-12);
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);

    let text = stdout(&chronomap(&args[..args.len() - 3]));
    assert!(
        text.contains("eventually: p_s = 0.940025, p_f = 0.059975\n"),
        "{text}"
    );
    assert!(
        text.contains("       0.000    0.000000    0.000000\n"),
        "{text}"
    );
}

/// A Fallback of two actions, hand-made: p_s = p1 + (1 − p1) p2 and
/// p_s,T(t) = p1 (1 − e^{−μ1 t}) + (1 − p1) p2 Hypo(ν1, μ2)(t).
#[test]
fn analyse_follows_the_closed_form_of_a_fallback_of_two_actions() {
    let dir = scratch("bt_analyse_fallback");
    let xml = write_arg(
        &dir,
        "search.xml",
        r#"<root BTCPP_format="4">
  <BehaviorTree ID="Search">
    <Fallback>
      <Action ID="SearchCorridor"/>
      <Action ID="WaitAtDoor"/>
    </Fallback>
  </BehaviorTree>
</root>
"#,
    );
    let params = write_arg(
        &dir,
        "search.csv",
        "node,p_s,p_f,mu,nu\nSearchCorridor,0.6,,0.05,0.025\nWaitAtDoor,0.9,0.1,0.02,0.01\n",
    );
    let out = chronomap(&[
        "bt", "analyse", &xml, "--params", &params, "--t-max", "60", "--steps", "1", "--json",
    ]);
    let json: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    close(&json["p_success"], 0.6 + 0.4 * 0.9, 1e-12);
    let t: f64 = 60.0;
    let hypo = |a: f64, b: f64| 1.0 - (b * (-a * t).exp() - a * (-b * t).exp()) / (b - a);
    let expected = 0.6 * (1.0 - (-0.05 * t).exp()) + 0.4 * 0.9 * hypo(0.025, 0.02);
    close(&json["curve"][1]["p_success"], expected, 1e-11);
    close(
        &json["time_to_success"],
        (0.6 * 20.0 + 0.36 * (40.0 + 50.0)) / 0.96,
        1e-9,
    );
}

#[test]
fn analyse_names_the_line_of_an_unsupported_node_and_bad_parameters() {
    let params = repo("tests/data/bt/door_sbt.csv");
    for (tree, says) in [
        (
            "parallel.xml",
            &["parallel.xml:7:5: Timeout is not supported by the stochastic analysis"][..],
        ),
        ("monitor.xml", &["monitor.xml:", "is not supported"]),
    ] {
        let tree = repo(&format!("tests/data/bt/{tree}"));
        let err = error(&chronomap(&["bt", "analyse", &tree, "--params", &params]));
        assert!(says.iter().all(|s| err.contains(s)), "{says:?}: {err}");
    }

    let dir = scratch("bt_analyse_bad");
    let bad = dir.join("bad.csv").display().to_string();
    let door = repo("tests/data/bt/door.xml");
    for (row, says) in [
        (
            "OpenDoor,0.4,0.5,0.2,0.5",
            &["bad.csv:2: field p_f: p_s + p_f = 0.9"][..],
        ),
        (
            "OpenDoor,0.4,0.6,fast,0.5",
            &["bad.csv:2: field mu: \"fast\""],
        ),
        (
            "OpenDoor,0.4,0.6,0.2,0.5",
            &["door.xml:", "no parameters for Condition \"IsDoorClosed\""],
        ),
    ] {
        std::fs::write(&bad, format!("node,p_s,p_f,mu,nu\n{row}\n")).unwrap();
        let err = error(&chronomap(&["bt", "analyse", &door, "--params", &bad]));
        assert!(says.iter().all(|s| err.contains(s)), "{row}: {err}");
    }
}

#[test]
fn check_and_run_print_json_and_write_with_output() {
    let dir = scratch("bt_json");
    let door = repo("tests/data/bt/door.xml");
    let saved = dir.join("door.xml").display().to_string();
    let text = stdout(&chronomap(&["bt", "check", &door, "--json", "-o", &saved]));
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["trees"], serde_json::json!(["MainTree", "DoorClosed"]));
    assert_eq!(v["tree"], "MainTree");
    assert_eq!(v["leaves"], 5);
    let nodes = v["nodes"].as_array().unwrap();
    assert_eq!(nodes.len(), 11);
    // Depth first, as the table: uid 5 is the subtree, 9 the lock under the retry.
    assert_eq!(nodes[4]["uid"], 5);
    assert_eq!(nodes[4]["category"], "SubTree");
    assert_eq!(nodes[4]["name"], "open_it");
    assert_eq!(nodes[4]["children"], serde_json::json!([6]));
    assert_eq!(nodes[8]["id"], "PickLock");
    assert_eq!(nodes[8]["depth"], 5);
    assert_eq!(nodes[8]["attributes"]["door"], "{door}");
    assert_eq!(nodes[7]["attributes"]["num_attempts"], "3");
    assert!(
        std::fs::read_to_string(&saved)
            .unwrap()
            .contains("<IsDoorClosed/>")
    );

    let text = stdout(&run_door(&repo(DOOR_SCRIPT), &["--json"]));
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["finished"], true);
    assert_eq!(v["status"], "SUCCESS");
    assert_eq!(
        (v["last_tick"].as_u64(), v["last_time_ms"].as_u64()),
        (Some(5), Some(1100))
    );
    assert_eq!(v["transitions"], 33);
    let ticks = v["ticks"].as_array().unwrap();
    assert_eq!(ticks.len(), 5);
    assert_eq!(ticks[2]["time_ms"], 200);
    assert_eq!(
        ticks[2]["transitions"][0],
        serde_json::json!({"uid": 9, "name": "PickLock", "from": "IDLE", "to": "RUNNING"})
    );
    assert!(v["unused_ticks"].as_array().unwrap().is_empty());
}

#[test]
fn analyse_refuses_impossible_tables_as_usage_errors() {
    let door = repo("tests/data/bt/door.xml");
    let params = repo("tests/data/bt/door_sbt.csv");
    for (flag, value) in [("--steps", "0"), ("--t-max", "-1"), ("--t-max", "0")] {
        let arg = format!("{flag}={value}");
        let out = chronomap(&["bt", "analyse", &door, "--params", &params, &arg]);
        let err = common::usage_error(&out);
        assert!(err.contains(flag), "{err}");
    }
}

// ---------------------------------------------------------------------------------------------
// Trees written by others: BehaviorTree.CPP's repository files, Nav2's navigators

/// Each of BehaviorTree.CPP's XML files (tests/data/bt/btcpp, commit 879522c7) with the
/// verdict BehaviorTree.CPP 4 gives: `None` loads, `Some(text)` is refused with that text.
const BTCPP_VERDICTS: [(&str, Option<&str>); 18] = [
    ("examples/test_files/Check.xml", None),
    ("examples/test_files/log_test.xml", None),
    (
        "examples/test_files/subtree_test.xml",
        Some(
            "subtree_test.xml:8:13: <CheckStatus> names a <BehaviorTree> of the document, not a node type: write <SubTree ID=\"CheckStatus\"/>",
        ),
    ),
    ("examples/test_files/subtrees/Talk.xml", None),
    ("fuzzing/corpus/bt_corpus/corpus1.xml", None),
    (
        "fuzzing/corpus/bt_corpus/corpus2.xml",
        Some("corpus2.xml:5:50: \"Timeout\" has no port \"timeout_ms\""),
    ),
    (
        "fuzzing/corpus/bt_corpus/corpus3.xml",
        Some("corpus3.xml:4:32: \"SetBlackboard\" has no port \"key\""),
    ),
    (
        "fuzzing/corpus/bt_corpus/corpus4.xml",
        Some("corpus4.xml:5:17: Decorator \"ForceSuccess\" needs exactly 1 child, found 0"),
    ),
    ("tests/trees/child/child/child_child_no_include.xml", None),
    ("tests/trees/child/child_include_child.xml", None),
    ("tests/trees/child/child_include_parent.xml", None),
    ("tests/trees/child/child_include_sibling.xml", None),
    ("tests/trees/child/child_no_include.xml", None),
    ("tests/trees/parent_include_child.xml", None),
    ("tests/trees/parent_include_child_include_child.xml", None),
    ("tests/trees/parent_include_child_include_parent.xml", None),
    ("tests/trees/parent_include_child_include_sibling.xml", None),
    ("tests/trees/parent_no_include.xml", None),
];

#[test]
fn btcpp_repository_files_get_the_verdicts_behaviortree_cpp_gives() {
    let mut found = Vec::new();
    collect_xml(&common::repo_path("tests/data/bt/btcpp"), &mut found);
    assert_eq!(found.len(), BTCPP_VERDICTS.len(), "{found:?}");
    for (file, verdict) in BTCPP_VERDICTS {
        let path = repo(&format!("tests/data/bt/btcpp/{file}"));
        // log_test.xml has two trees and no main_tree_to_execute: BT.CPP needs the ID too.
        let tree: &[&str] = if file.ends_with("log_test.xml") {
            &["--tree", "Main"]
        } else {
            &[]
        };
        let out = chronomap(&[&["bt", "check", &path][..], tree].concat());
        match verdict {
            None => {
                let text = stdout(&out);
                assert!(text.contains("BehaviorTree.CPP 4"), "{file}: {text}");
            }
            Some(message) => {
                let err = error(&out);
                assert!(err.contains(message), "{file}: {err}");
            }
        }
    }
    // The include chains resolve through child/, child/child/ and ../ and put every tree in.
    let text = stdout(&chronomap(&[
        "bt",
        "check",
        &repo("tests/data/bt/btcpp/tests/trees/parent_include_child_include_parent.xml"),
    ]));
    assert!(
        text.contains(
            "3 trees (ParentIncludeChildIncludeParent, ChildIncludeParent, ParentNoInclude)"
        ),
        "{text}"
    );
    assert!(
        text.contains("   2    SubTree ChildIncludeParent\n   3      Sequence\n   4        SubTree ParentNoInclude\n"),
        "{text}"
    );
}

fn collect_xml(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            collect_xml(&path, out);
        } else if path.extension().is_some_and(|e| e == "xml") {
            out.push(path);
        }
    }
}

const NAV2_NODES: &str = "tests/data/bt/nav2/nav2_tree_nodes.xml";
const NAV2_TREES: [&str; 3] = [
    "navigate_to_pose_w_replanning_and_recovery.xml",
    "navigate_through_poses_w_replanning_and_recovery.xml",
    "follow_point.xml",
];

#[test]
fn nav2_trees_check_with_nav2s_node_models_and_fail_clearly_without() {
    let nodes = repo(NAV2_NODES);
    for name in NAV2_TREES {
        let file = repo(&format!("tests/data/bt/nav2/{name}"));
        let out = chronomap(&["bt", "check", &file, "--nodes", &nodes]);
        let text = stdout(&out);
        assert!(
            text.contains("BehaviorTree.CPP 4, 1 tree"),
            "{name}: {text}"
        );
        assert!(
            out.stderr.is_empty(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let err = error(&chronomap(&["bt", "check", &file]));
        assert!(err.contains(": unknown node ID \""), "{name}: {err}");
        assert!(err.contains("count with --nodes FILE"), "{name}: {err}");
    }
    let file = repo("tests/data/bt/nav2/navigate_to_pose_w_replanning_and_recovery.xml");
    let text = stdout(&chronomap(&["bt", "check", &file, "--nodes", &nodes]));
    assert!(
        text.contains("   1  RecoveryNode \"NavigateRecovery\" number_of_retries=6\n"),
        "{text}"
    );
    assert!(
        text.contains("   2    PipelineSequence \"NavigateWithReplanning\"\n"),
        "{text}"
    );
    assert!(text.contains("   5      RateController hz=1.0\n"), "{text}");

    // A wrong port of a Nav2 decorator is located.
    let dir = scratch("bt_nav2_bad");
    let bad = std::fs::read_to_string(common::repo_path("tests/data/bt/nav2/follow_point.xml"))
        .unwrap()
        .replace("hz=\"1.0\"", "rate=\"1.0\"");
    let bad = write_arg(&dir, "bad.xml", bad);
    let err = error(&chronomap(&["bt", "check", &bad, "--nodes", &nodes]));
    assert!(
        err.contains("bad.xml:11:23: \"RateController\" has no port \"rate\" (its ports: hz)"),
        "{err}"
    );
}

#[test]
fn saved_files_declare_every_custom_node_used_for_groot2() {
    let dir = scratch("bt_nav2_saved");
    let saved = dir.join("saved.xml").display().to_string();
    let file = repo("tests/data/bt/nav2/navigate_to_pose_w_replanning_and_recovery.xml");
    stdout(&chronomap(&[
        "bt",
        "check",
        &file,
        "--nodes",
        &repo(NAV2_NODES),
        "-o",
        &saved,
    ]));
    let xml = std::fs::read_to_string(&saved).unwrap();
    for id in [
        "RecoveryNode",
        "PipelineSequence",
        "ControllerSelector",
        "PlannerSelector",
        "RateController",
        "ComputePathToPose",
        "WouldAPlannerRecoveryHelp",
        "ClearEntireCostmap",
        "FollowPath",
        "WouldAControllerRecoveryHelp",
        "GoalUpdated",
        "RoundRobin",
        "Spin",
        "Wait",
        "BackUp",
    ] {
        assert!(xml.contains(&format!(" ID=\"{id}\"")), "{id}: {xml}");
    }
    assert!(
        !xml.contains("ID=\"DriveOnHeading\""),
        "only the models used"
    );
    assert!(xml.contains("<input_port name=\"number_of_retries\" type=\"int\" default=\"1\">"));
    // The saved file checks without --nodes.
    stdout(&chronomap(&["bt", "check", &saved]));
}

/// A Nav2-style tree: replanning under a RateController inside a PipelineSequence, following
/// under KeepRunningUntilFailure, and a RecoveryNode that clears the costmap once.
const RECOVERY_TREE: &str = r#"<root BTCPP_format="4" main_tree_to_execute="Nav">
  <BehaviorTree ID="Nav">
    <RecoveryNode number_of_retries="1" name="Navigate">
      <PipelineSequence name="Pipeline">
        <RateController hz="1.0">
          <ComputePathToPose goal="{goal}" path="{path}"/>
        </RateController>
        <KeepRunningUntilFailure>
          <FollowPath path="{path}"/>
        </KeepRunningUntilFailure>
      </PipelineSequence>
      <ClearEntireCostmap service_name="local_costmap/clear_entirely_local_costmap"/>
    </RecoveryNode>
  </BehaviorTree>
</root>
"#;

#[test]
fn nav2_controls_run_with_the_statuses_nav2_gives() {
    let dir = scratch("bt_nav2_run");
    let tree = write_arg(&dir, "nav.xml", RECOVERY_TREE);
    let script = write_arg(
        &dir,
        "nav.script",
        "tick 1: ComputePathToPose=success, FollowPath=success, ClearEntireCostmap=success\ntick 4: FollowPath=failure\n",
    );
    let out = chronomap(&[
        "bt",
        "run",
        &tree,
        "--nodes",
        &repo(NAV2_NODES),
        "--script",
        &script,
        "--tick-ms",
        "400",
        "--json",
    ]);
    let run = common::json(&out);
    let statuses: Vec<&str> = run["ticks"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["status"].as_str().unwrap())
        .collect();
    // Ticks 1-3: the pipeline keeps FollowPath running (KeepRunningUntilFailure) while the
    // RateController holds back replanning (400 ms < 1 s); tick 4 (1200 ms): replanning
    // succeeds, FollowPath fails, the RecoveryNode clears the costmap and retries once in the
    // same tick, which fails again: FAILURE.
    assert_eq!(statuses, ["RUNNING", "RUNNING", "RUNNING", "FAILURE"]);
    let to = |name: &str, status: &str| {
        run["ticks"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|t| t["transitions"].as_array().unwrap())
            .filter(|t| t["name"] == name && t["to"] == status)
            .count()
    };
    // The RateController ticks its child (and succeeds) at tick 1, at tick 4, and again in
    // the retry after the recovery; each time ComputePathToPose succeeds from idle, since the
    // RateController, a DecoratorNode, resets its completed child after every tick of its own
    // (BehaviorTree.CPP's `DecoratorNode::executeTick`).
    assert_eq!(
        to("RateController", "SUCCESS"),
        3,
        "ticks 1, 4 and the retry"
    );
    assert_eq!(to("ComputePathToPose", "SUCCESS"), 3);
    assert_eq!(to("ClearEntireCostmap", "SUCCESS"), 1);
    assert_eq!(to("FollowPath", "FAILURE"), 2);
    let notes = String::from_utf8_lossy(&out.stderr);
    assert!(
        notes.contains("note: PipelineSequence: Nav2's behaviour (chronomap's emulation)"),
        "{notes}"
    );
}

#[test]
fn stubs_run_trees_whose_leaves_nothing_implements() {
    let file = repo("tests/data/bt/nav2/follow_point.xml");
    let nodes = repo(NAV2_NODES);
    let out = chronomap(&[
        "bt",
        "run",
        &file,
        "--nodes",
        &nodes,
        "--stub-all",
        "SUCCESS",
        "--stub",
        "FollowPath=RUNNING:2",
        "--ticks",
        "25",
        "--json",
    ]);
    let run = common::json(&out);
    assert_eq!(run["status"], "RUNNING");
    assert_eq!(run["last_tick"], 25);
    // 1 Hz replanning at 100 ms ticks: the RateController ticks its child and succeeds at 0,
    // 1000 and 2000 ms, and returns RUNNING in between.
    let replans = run["ticks"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|t| t["transitions"].as_array().unwrap())
        .filter(|t| t["name"] == "RateController" && t["to"] == "SUCCESS")
        .count();
    assert_eq!(replans, 3);
    let stubs = common::strings(&run["stubs"]);
    assert!(
        stubs.contains(&"FollowPath: stub, RUNNING for 2 ticks, then SUCCESS"),
        "{stubs:?}"
    );

    // Bad stubs are usage errors (exit 2) that say what fits.
    let navigate = repo("tests/data/bt/nav2/navigate_to_pose_w_replanning_and_recovery.xml");
    for (stub, message) in [
        ("FollowPath", "expected ID=BEHAVIOUR"),
        (
            "FollowPath=SOMETIMES",
            "expected SUCCESS, FAILURE or RUNNING:n",
        ),
        (
            "Nowhere=SUCCESS",
            "no node of the document has the ID \"Nowhere\"",
        ),
        (
            "RateController=SEQUENCE",
            "is a Decorator; its stub is PASS or NAV2",
        ),
        (
            "GoalUpdated=RUNNING:1",
            "SUCCESS or FAILURE (conditions do not run)",
        ),
        ("Sequence=SEQUENCE", "is implemented by chronomap"),
    ] {
        let err = common::usage_error(&chronomap(&[
            "bt",
            "run",
            &navigate,
            "--nodes",
            &nodes,
            "--stub-all",
            "SUCCESS",
            "--stub",
            stub,
        ]));
        assert!(err.contains(message), "{stub}: {err}");
    }
    // A declared control that nothing implements needs a stub.
    let dir = scratch("bt_stub_needed");
    let tree = write_arg(
        &dir,
        "single.xml",
        "<root BTCPP_format=\"4\">\n  <BehaviorTree ID=\"A\">\n    <SingleTrigger><Wait/></SingleTrigger>\n  </BehaviorTree>\n</root>\n",
    );
    let err = common::usage_error(&chronomap(&[
        "bt",
        "run",
        &tree,
        "--nodes",
        &nodes,
        "--stub-all",
        "SUCCESS",
    ]));
    assert!(err.contains("give --stub SingleTrigger=PASS"), "{err}");
    let text = stdout(&chronomap(&[
        "bt",
        "run",
        &tree,
        "--nodes",
        &nodes,
        "--stub-all",
        "SUCCESS",
        "--stub",
        "SingleTrigger=PASS",
    ]));
    assert!(
        text.ends_with("result: SUCCESS at tick 1 (0 ms)\n"),
        "{text}"
    );
}

#[test]
fn includes_cycles_deep_and_endless_files_are_refused_with_the_place() {
    let dir = scratch("bt_include_cycle");
    let a = write_arg(
        &dir,
        "a.xml",
        "<root BTCPP_format=\"4\" main_tree_to_execute=\"A\">\n  <include path=\"b.xml\"/>\n  <BehaviorTree ID=\"A\"><SubTree ID=\"B\"/></BehaviorTree>\n</root>\n",
    );
    write(
        &dir,
        "b.xml",
        "<root BTCPP_format=\"4\">\n  <include path=\"a.xml\"/>\n  <BehaviorTree ID=\"B\"><AlwaysSuccess/></BehaviorTree>\n</root>\n",
    );
    let err = error(&chronomap(&["bt", "check", &a]));
    let b = dir.join("b.xml").display().to_string();
    assert_eq!(
        err,
        format!(
            "error: {b}:2:12: <include path=\"a.xml\"> makes an include cycle: {a} -> {b} -> {a}\n"
        )
    );

    let ros = write_arg(
        &dir,
        "ros.xml",
        "<root BTCPP_format=\"4\">\n  <include ros_pkg=\"my_pkg\" path=\"trees/x.xml\"/>\n</root>\n",
    );
    let err = error(&chronomap(&["bt", "check", &ros]));
    assert!(err.contains("ros.xml:2:12: <include ros_pkg=\"my_pkg\">: ROS packages are not resolved here; give the file's path instead"), "{err}");

    let mut deep = String::from("<root BTCPP_format=\"4\">\n<BehaviorTree ID=\"Deep\">\n");
    deep.push_str(&"<Inverter>\n".repeat(10_000));
    deep.push_str("<AlwaysSuccess/>\n");
    deep.push_str(&"</Inverter>\n".repeat(10_000));
    deep.push_str("</BehaviorTree>\n</root>\n");
    let deep = write_arg(&dir, "deep.xml", deep);
    let err = error(&chronomap(&["bt", "check", &deep]));
    assert!(
        err.contains("deep.xml:1003:1: nodes nested deeper than 1000 levels"),
        "{err}"
    );

    #[cfg(unix)]
    {
        let err = error(&chronomap(&["bt", "check", "/dev/zero"]));
        assert!(
            err.contains("/dev/zero") && err.contains("not a regular file"),
            "{err}"
        );
    }
}

#[test]
fn script_nodes_run_and_enums_come_from_the_command_line() {
    // A Script sets an enum value that a Switch2 compares with its cases; BehaviorTree.CPP
    // registers enums in C++ (registerScriptingEnum), chronomap with --enum NAME=VALUE.
    let dir = scratch("bt_enums");
    let tree = write_arg(
        &dir,
        "enum.xml",
        r#"<root BTCPP_format="4">
  <BehaviorTree ID="Main">
    <Sequence>
      <Script code="color := BLUE"/>
      <Switch2 variable="{color}" case_1="RED" case_2="BLUE">
        <AlwaysFailure name="red"/>
        <AlwaysSuccess name="blue"/>
        <AlwaysFailure name="other"/>
      </Switch2>
    </Sequence>
  </BehaviorTree>
</root>
"#,
    );
    let text = stdout(&chronomap(&[
        "bt", "run", &tree, "--ticks", "1", "--enum", "RED=1", "--enum", "BLUE=2",
    ]));
    assert!(text.contains("blue"), "{text}");
    assert!(!text.contains("red "), "{text}");
    assert!(
        text.ends_with("result: SUCCESS at tick 1 (0 ms)\n"),
        "{text}"
    );
    // Without the enum the script names the unknown variable.
    let err = error(&chronomap(&["bt", "run", &tree, "--ticks", "1"]));
    assert!(
        err.contains("Script") && err.contains("variable not found: BLUE"),
        "{err}"
    );
    // A name scripts cannot use, or a value that is not an integer: usage errors.
    for bad in ["1X=2", "RED=one", "RED"] {
        let err = common::usage_error(&chronomap(&["bt", "run", &tree, "--enum", bad]));
        assert!(err.contains("--enum"), "{bad}: {err}");
    }
}

#[test]
fn nesting_through_subtrees_and_a_100000_deep_file_are_refused_at_their_line() {
    let dir = scratch("bt_deep_subtrees");
    // 100 trees of 900 nested sequences, each around the SubTree of the next: the limit of
    // 1,000 levels is passed in T1, which the error named only by a path of 100 child indices.
    let mut chain = String::from("<root BTCPP_format=\"4\" main_tree_to_execute=\"T0\">\n");
    for i in 0..100 {
        chain.push_str(&format!("<BehaviorTree ID=\"T{i}\">\n"));
        chain.push_str(&"<Sequence>\n".repeat(900));
        if i < 99 {
            chain.push_str(&format!("<SubTree ID=\"T{}\"/>\n", i + 1));
        } else {
            chain.push_str("<AlwaysSuccess/>\n");
        }
        chain.push_str(&"</Sequence>\n".repeat(900));
        chain.push_str("</BehaviorTree>\n");
    }
    chain.push_str("</root>\n");
    let file = write_arg(&dir, "chain.xml", chain);
    let err = error(&chronomap(&["bt", "check", &file]));
    // T0 takes lines 2 to 1,804 and 901 levels (900 sequences and the SubTree); the 100th
    // level of T1, 99 lines below its root on line 1,806, is the 1,001st.
    assert_eq!(
        err,
        format!("error: {file}:1905:1: tree \"T1\": tree nesting deeper than 1000 levels\n")
    );

    let mut deep = String::from("<root BTCPP_format=\"4\">\n<BehaviorTree ID=\"Deep\">\n");
    deep.push_str(&"<Sequence>\n".repeat(100_000));
    deep.push_str("<AlwaysSuccess/>\n");
    deep.push_str(&"</Sequence>\n".repeat(100_000));
    deep.push_str("</BehaviorTree>\n</root>\n");
    let deep = write_arg(&dir, "deep.xml", deep);
    let err = error(&chronomap(&["bt", "check", &deep]));
    assert_eq!(
        err,
        format!(
            "error: {deep}:1003:1: nodes nested deeper than 1000 levels (a limit of this reader)\n"
        )
    );
}
