//! `chronomap monitor sim` ([Stüde 2024] §5.3): the hand-written fault scenario of
//! tests/data/monitor/faults.txt with known recovery order and one-minute-rule successes, the
//! arbiter loaded from XML behaving as the built-in one, seeded random runs, and exit code 1
//! with located messages for bad input.

use crate::common;

use chronomap_bt::Registry;
use chronomap_bt_monitor::sim::arbiter_document;
use common::{chronomap, error, repo, scratch, stdout, write_arg};
use serde_json::Value;

/// `monitor sim` on the bundled half-hour fault scenario, every recovery certain: its stdout.
fn scenario_output(extra: &[&str]) -> String {
    let faults = repo("tests/data/monitor/faults.txt");
    let mut args = vec![
        "monitor",
        "sim",
        "--hours",
        "0.5",
        "--faults",
        &faults,
        "--certain",
    ];
    args.extend_from_slice(extra);
    stdout(&chronomap(&args))
}

fn scenario(extra: &[&str]) -> Value {
    let mut args = vec!["--json"];
    args.extend_from_slice(extra);
    serde_json::from_str(&scenario_output(&args)).unwrap()
}

#[test]
fn the_hand_written_scenario_gives_the_known_interventions() {
    let v = scenario(&[]);
    let rows: Vec<(f64, f64, &str, &str, bool)> = v["interventions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            (
                r["start"].as_f64().unwrap(),
                r["end"].as_f64().unwrap(),
                r["leaf"].as_str().unwrap(),
                r["outcome"].as_str().unwrap(),
                r["success"].as_bool().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        rows,
        vec![
            (100.0, 120.0, "SlowRotate", "not_fixed", false),
            (120.0, 150.0, "RestartLocalization", "fixed", true),
            (300.0, 310.0, "WaitAndRetry", "fixed", false),
            (330.0, 340.0, "WaitAndRetry", "fixed", true),
            (600.0, 609.0, "SlowRotate", "halted", false),
            (609.0, 619.0, "RestartNode", "fixed", true),
            (620.0, 640.0, "SlowRotate", "fixed", true),
        ]
    );
    assert_eq!(v["messages"][0][0].as_f64(), Some(900.0));
    // Stuck from 1200 s, last motion at 1199 s: the supervisor comes at 1799 s.
    assert_eq!(v["unrequested"], serde_json::json!([1799.0]));
    // Moving: (0,99] + (150,299] + (310,329] + (340,599] + (640,1199] + (1799,1800] = 1086 s.
    common::close(&v["moving_h"], 1086.0 / 3600.0, 1e-9);
    common::close(&v["autonomy"], 1086.0 / 1800.0, 1e-9);
    common::close(&v["tsl_mean_h"], 900.0 / 3600.0, 1e-9);
    common::close(&v["tsl_max_h"], 1799.0 / 3600.0, 1e-9);
    let slow = &v["reactions"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["reaction"] == "Slow rotate")
        .unwrap();
    assert_eq!(
        (slow["count"].as_u64(), slow["successes"].as_u64()),
        (Some(3), Some(1))
    );
}

#[test]
fn the_table_output_lists_interventions_and_metrics() {
    let out = scenario_output(&[]);
    assert!(
        out.starts_with("7 faults injected over 0.5 h; 7 recoveries, 1 messages, 1 unrequested"),
        "{out}"
    );
    assert!(out.contains("Recoveries by category (Table 5.3)"), "{out}");
    assert!(
        out.contains("message at 0:15:00: CPU, RAM, NTP or network out of band"),
        "{out}"
    );
    assert!(
        out.contains("unrequested supervisor intervention at 0:29:59"),
        "{out}"
    );
    assert!(out.contains("A%(t_o) = t_m/t_o"), "{out}");
    assert!(out.contains("60.3 %"), "{out}");
}

#[test]
fn the_xml_arbiter_is_the_built_in_one() {
    let xml = repo("tests/data/bt/monitor_arbiter.xml");
    let doc = chronomap_io::read_bt_xml(&xml, &Registry::new())
        .unwrap()
        .document;
    assert_eq!(doc.trees, arbiter_document().trees);
    assert_eq!(scenario(&["--arbiter", &xml]), scenario(&[]));
}

#[test]
fn random_runs_depend_on_the_seed_only() {
    let run = |seed: &str| {
        stdout(&chronomap(&[
            "monitor", "sim", "--hours", "4", "--seed", seed, "--json",
        ]))
    };
    let a = run("5");
    assert_eq!(a, run("5"));
    assert_ne!(a, run("6"));
    let v: Value = serde_json::from_str(&a).unwrap();
    assert!(!v["interventions"].as_array().unwrap().is_empty());
}

#[test]
fn bad_input_is_an_error_naming_the_place() {
    let dir = scratch("monitor_bad_input");
    let bad = write_arg(
        &dir,
        "faults.txt",
        "# ok\n10 node_crash camera\n20 node_crash lidar\n",
    );
    let err = error(&chronomap(&["monitor", "sim", "--faults", &bad]));
    assert!(err.contains("faults.txt:3: target:"), "{err}");
    assert!(err.contains("lidar"), "{err}");
    let err = error(&chronomap(&["monitor", "sim", "--hours", "0"]));
    assert!(err.contains("--hours"), "{err}");
    let missing = dir.join("missing.txt").display().to_string();
    let err = error(&chronomap(&["monitor", "sim", "--faults", &missing]));
    assert!(err.contains("missing.txt"), "{err}");
    let door = repo("tests/data/bt/door.xml");
    let err = error(&chronomap(&[
        "monitor",
        "sim",
        "--hours",
        "0.1",
        "--arbiter",
        &door,
    ]));
    assert!(err.contains("door.xml"), "{err}");
}

#[test]
fn flags_clap_cannot_read_exit_2_and_the_table_survives_a_closed_pipe() {
    let err = common::usage_error(&chronomap(&["monitor", "sim", "--seed", "one"]));
    assert!(err.contains("--seed"), "{err}");
    let err = common::usage_error(&chronomap(&["monitor", "sim", "--hours"]));
    assert!(err.contains("--hours"), "{err}");
    // The hand-written scenario's report, closed after its first line.
    let faults = repo("tests/data/monitor/faults.txt");
    let (first, _) = common::closed_pipe(
        &[
            "monitor",
            "sim",
            "--hours",
            "0.5",
            "--certain",
            "--faults",
            &faults,
        ],
        1,
    );
    assert!(first.contains("faults injected over 0.5 h"), "{first}");
}
