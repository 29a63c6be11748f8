//! `chronomap bt run --groot2 PORT` against BehaviorTree.CPP 4.8.2's own `Groot2Publisher`
//! (behaviortreepy): the same trees, the same leaf outcomes, the same ticks, the same requests
//! (`tests/bt/groot2_compare.py`), and the replies must be equal byte for byte, except
//! * the 16-byte tree UUID of every reply header (BehaviorTree.CPP's is the same for every
//!   tree: a default-seeded `mt19937`; ours is random);
//! * the first 6 bytes of each 9-byte GET_TRANSITIONS record (microseconds since recording
//!   started: wall-clock times of two different runs);
//! * the payload of TOGGLE_RECORDING `start` (the server's clock), checked to be digits.
//!
//! The comparison needs `CHRONOMAP_BT_PYTHON` (a Python with behaviortreepy and pyzmq); it
//! is skipped without, and fails without when `CHRONOMAP_REQUIRE_BT=1` (CI).

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

use chronomap_testutil::free_port_pair;

use crate::common::{oracle_python, scratch};

fn python(test: &str) -> Option<String> {
    oracle_python(
        "BT",
        test,
        "BehaviorTree.CPP Groot2Publisher",
        "set CHRONOMAP_BT_PYTHON to a Python with behaviortreepy 0.1.4 and pyzmq",
    )
}

fn data(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/bt")
        .join(name)
        .display()
        .to_string()
}

fn driver() -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/bt/groot2_compare.py")
        .display()
        .to_string()
}

/// Runs the driver; its exit code and the JSON it wrote.
fn drive(python: &str, args: &[&str], out: &PathBuf) -> (Option<i32>, Option<Value>) {
    let output = Command::new(python)
        .arg(driver())
        .args(["--out", out.to_str().unwrap()])
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&output.stderr);
    assert!(!err.contains("panicked"), "{err}");
    let json = std::fs::read(out)
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok());
    if output.status.code() != Some(0) && output.status.code() != Some(3) {
        panic!("groot2_compare.py {args:?} failed: {err}");
    }
    (output.status.code(), json)
}

fn parts(entry: &Value, key: &str) -> Vec<Vec<u8>> {
    entry[key]
        .as_array()
        .unwrap()
        .iter()
        .map(|h| {
            let h = h.as_str().unwrap();
            (0..h.len())
                .step_by(2)
                .map(|i| u8::from_str_radix(&h[i..i + 2], 16).unwrap())
                .collect()
        })
        .collect()
}

/// The reply with what may differ removed (see the module documentation).
fn comparable(label: &str, mut reply: Vec<Vec<u8>>) -> Vec<Vec<u8>> {
    if reply
        .first()
        .is_some_and(|h| h.len() == 22 && h != b"error")
    {
        reply[0][6..].fill(0);
    }
    if label.starts_with("transitions") && reply.len() == 2 {
        assert_eq!(reply[1].len() % 9, 0);
        reply[1] = reply[1].chunks(9).flat_map(|r| r[6..].to_vec()).collect();
    }
    if label == "recording start" {
        assert!(reply[1].iter().all(u8::is_ascii_digit), "{:?}", reply[1]);
        reply.truncate(1);
    }
    reply
}

/// Runs `tree` with `script` in BehaviorTree.CPP and in chronomap, compares every reply;
/// returns the number of bytes compared.
fn compare(python: &str, test: &str, tree: &str, script: &str) -> usize {
    let dir = scratch(test);
    let (tree, script) = (data(tree), data(script));
    let port = free_port_pair().to_string();
    let (_, btcpp) = drive(
        python,
        &["btcpp", &tree, &script, "--port", &port],
        &dir.join("btcpp.json"),
    );
    let btcpp = btcpp.expect("BehaviorTree.CPP's session");
    let mut ours = None;
    // The session must start recording before the first tick: 3 tries on a busy machine.
    for _ in 0..3 {
        let port = free_port_pair().to_string();
        let bin = env!("CARGO_BIN_EXE_chronomap");
        let (code, json) = drive(
            python,
            &[
                "chronomap",
                "--port",
                &port,
                "--",
                bin,
                "bt",
                "run",
                &tree,
                "--script",
                &script,
                "--groot2",
                &port,
                "--tick-period",
                "300",
                "--linger",
                "30",
            ],
            &dir.join("chronomap.json"),
        );
        if code == Some(0) {
            ours = json;
            break;
        }
    }
    let ours = ours.expect("chronomap's session started before the first tick");
    assert_eq!(ours["ticks"], btcpp["ticks"], "ticks run");
    assert!(btcpp["ticks"].as_u64().unwrap() >= 3);
    let (a, b) = (
        btcpp["log"].as_array().unwrap(),
        ours["log"].as_array().unwrap(),
    );
    assert_eq!(a.len(), b.len());
    let mut compared = 0;
    for (x, y) in a.iter().zip(b) {
        let label = x["label"].as_str().unwrap();
        assert_eq!(x["label"], y["label"]);
        let (rx, ry) = (
            comparable(label, parts(x, "reply")),
            comparable(label, parts(y, "reply")),
        );
        assert_eq!(
            rx,
            ry,
            "{test}: reply to {label} differs:\nBehaviorTree.CPP: {:?}\nchronomap:        {:?}",
            rx.iter()
                .map(|p| String::from_utf8_lossy(p))
                .collect::<Vec<_>>(),
            ry.iter()
                .map(|p| String::from_utf8_lossy(p))
                .collect::<Vec<_>>()
        );
        compared += rx.iter().map(Vec::len).sum::<usize>();
    }
    // The session saw the run: status changes were recorded, the tree is not all idle.
    let transitions = a.iter().find(|e| e["label"] == "transitions").unwrap();
    assert!(parts(transitions, "reply")[1].len() >= 9 * 5);
    println!("{test}: {} replies, {compared} bytes equal", a.len());
    compared
}

#[test]
fn door_tree_replies_equal_behaviortree_cpp() {
    if let Some(py) = python("door_tree_replies_equal_behaviortree_cpp") {
        assert!(compare(&py, "groot2_door", "groot2/door.xml", "groot2/door.script") > 4000);
    }
}

#[test]
fn reactive_tree_replies_equal_behaviortree_cpp() {
    if let Some(py) = python("reactive_tree_replies_equal_behaviortree_cpp") {
        compare(
            &py,
            "groot2_reactive",
            "groot2/reactive.xml",
            "groot2/reactive.script",
        );
    }
}

#[test]
fn parallel_tree_replies_equal_behaviortree_cpp() {
    if let Some(py) = python("parallel_tree_replies_equal_behaviortree_cpp") {
        compare(
            &py,
            "groot2_parallel",
            "groot2/parallel.xml",
            "groot2/parallel.script",
        );
    }
}

#[test]
fn subtree_replies_equal_behaviortree_cpp() {
    if let Some(py) = python("subtree_replies_equal_behaviortree_cpp") {
        compare(
            &py,
            "groot2_subtrees",
            "groot2/subtrees.xml",
            "groot2/subtrees.script",
        );
    }
}

#[test]
fn btcpp_check_example_replies_equal_behaviortree_cpp() {
    if let Some(py) = python("btcpp_check_example_replies_equal_behaviortree_cpp") {
        compare(
            &py,
            "groot2_check",
            "btcpp/examples/test_files/Check.xml",
            "groot2/check.script",
        );
    }
}

/// Garbage, a 100 MB frame declared (and 768 KiB of it sent), a 2 MiB part, 20 parts, a client
/// that asks and never reads, one that connects and says nothing: the offenders are dropped or
/// refused, a good client is answered, and the run ticks on to its last tick.
#[test]
fn bad_clients_do_not_stop_the_ticks() {
    let Some(py) = python("bad_clients_do_not_stop_the_ticks") else {
        return;
    };
    let dir = scratch("groot2_hostile");
    let port = free_port_pair();
    let child = Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args([
            "bt",
            "run",
            &data("groot2/subtrees.xml"),
            "--stub-all",
            "RUNNING:100000",
        ])
        .args([
            "--ticks",
            "60",
            "--tick-period",
            "100",
            "--groot2",
            &port.to_string(),
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(500));
    let (_, out) = drive(
        &py,
        &["hostile", "--port", &port.to_string()],
        &dir.join("h.json"),
    );
    let out = out.expect("the hostile session's results");
    let run = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert_eq!(
        run.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(
        stdout.contains("result: still RUNNING after tick 60"),
        "{stdout}"
    );
    assert_eq!(out["big_closed"], true, "{out}");
    assert_eq!(out["huge_answered"], false, "{out}");
    assert_eq!(
        out["many_parts"],
        serde_json::json!(["error", "20 parts, at most 8"])
    );
    // STATUS of the 8 nodes: 3 bytes each, protocol 2, type 'S'.
    assert_eq!(out["status_len"], 24 * 2);
    assert!(out["status_header"].as_str().unwrap().starts_with("0253"));
    assert_eq!(out["fulltree_starts"], "<root BTCPP_format=\"4\">");
}

// ---------------------------------------------------------------------------------------------
// Hooks and breakpoints acting on the ticks (`tests/bt/groot2_hooks.py`).

fn hooks_driver() -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/bt/groot2_hooks.py")
        .display()
        .to_string()
}

/// Runs a hooks session with `plan` against the server that `server` starts (given the
/// port); retries when the run started before the session did (exit status 3). The JSON it
/// wrote.
fn hooks_session(
    python: &str,
    out: &Path,
    plan: &str,
    server: &dyn Fn(&str) -> Vec<String>,
) -> Value {
    for _ in 0..3 {
        let port = free_port_pair().to_string();
        let output = Command::new(python)
            .arg(hooks_driver())
            .args(["session", "--port", &port, "--plan", plan, "--out"])
            .arg(out)
            .arg("--")
            .args(server(&port))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&output.stderr);
        assert!(!err.contains("panicked"), "{err}");
        match output.status.code() {
            Some(0) => return serde_json::from_slice(&std::fs::read(out).unwrap()).unwrap(),
            Some(3) => continue,
            _ => panic!("groot2_hooks.py session {plan} failed: {err}"),
        }
    }
    panic!("the hooks session never started before the first tick");
}

/// `tick K ...: STATUS` and `result: STATUS at tick K` of a run's output, without the times
/// (BehaviorTree.CPP's server prints none).
fn tick_lines(run: &Value) -> Vec<String> {
    run["stdout"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|l| {
            let l = l.as_str().unwrap().trim();
            if let Some(rest) = l.strip_prefix("tick ") {
                let (k, status) = rest.split_once(" @ ").unwrap();
                Some(format!("tick {k}: {}", status.rsplit(": ").next().unwrap()))
            } else {
                l.strip_prefix("result: ")
                    .map(|r| r.split(" (").next().unwrap().to_owned())
            }
        })
        .collect()
}

/// A BREAKPOINT_REACHED notification without its random request id: the protocol, the type
/// and the node uid.
fn notification(n: &Value) -> (Vec<u8>, String) {
    let parts = parts(n, "notification");
    assert_eq!(parts.len(), 2);
    assert_eq!(parts[0].len(), 6);
    (
        parts[0][..2].to_vec(),
        String::from_utf8(parts[1].clone()).unwrap(),
    )
}

/// Runs `tree` with `script` and the hooks of `plan` in BehaviorTree.CPP and in chronomap;
/// compares every reply (as [`compare`]; STATUS while a tick is held below the root is only
/// checked for its size: ours shows the last whole tick), the notifications (all but their
/// random request id) and the ticks. Returns the uids notified.
fn compare_hooks(python: &str, test: &str, tree: &str, script: &str, plan: &str) -> Vec<String> {
    let dir = scratch(test);
    let (tree, script, plan) = (data(tree), data(script), data(plan));
    let btcpp = hooks_session(python, &dir.join("btcpp.json"), &plan, &|port| {
        [
            python,
            &hooks_driver(),
            "serve",
            &tree,
            &script,
            "--port",
            port,
        ]
        .into_iter()
        .chain(["--tick-period", "300", "--heartbeat", "30000"])
        .map(str::to_owned)
        .collect()
    });
    let bin = env!("CARGO_BIN_EXE_chronomap");
    let ours = hooks_session(python, &dir.join("chronomap.json"), &plan, &|port| {
        [
            bin, "bt", "run", &tree, "--script", &script, "--groot2", port,
        ]
        .into_iter()
        .chain([
            "--tick-period",
            "300",
            "--groot2-heartbeat",
            "30000",
            "--linger",
            "30",
        ])
        .map(str::to_owned)
        .collect()
    });
    assert_eq!(tick_lines(&ours), tick_lines(&btcpp), "{test}: ticks");
    assert_eq!(
        ours["reached"], btcpp["reached"],
        "{test}: breakpoints reached"
    );
    let notified = |run: &Value| -> Vec<(Vec<u8>, String)> {
        run["notifications"]
            .as_array()
            .unwrap()
            .iter()
            .map(|n| notification(&serde_json::json!({ "notification": n })))
            .collect()
    };
    let (na, nb) = (notified(&btcpp), notified(&ours));
    assert_eq!(nb, na, "{test}: BREAKPOINT_REACHED notifications");
    assert!(na.iter().all(|(h, _)| h == &[2, b'N']));
    let (a, b) = (
        btcpp["log"].as_array().unwrap(),
        ours["log"].as_array().unwrap(),
    );
    assert_eq!(a.len(), b.len(), "{test}: requests");
    let mut compared = 0;
    for (x, y) in a.iter().zip(b) {
        let label = x["label"].as_str().unwrap();
        assert_eq!(x["label"], y["label"]);
        let (rx, ry) = (
            comparable(label, parts(x, "reply")),
            comparable(label, parts(y, "reply")),
        );
        if label.starts_with("uncompared") {
            assert_eq!(rx[1].len(), ry[1].len(), "{test}: {label}");
            continue;
        }
        assert_eq!(
            rx,
            ry,
            "{test}: reply to {label} differs:\nBehaviorTree.CPP: {:?}\nchronomap:        {:?}",
            rx.iter()
                .map(|p| String::from_utf8_lossy(p))
                .collect::<Vec<_>>(),
            ry.iter()
                .map(|p| String::from_utf8_lossy(p))
                .collect::<Vec<_>>()
        );
        compared += rx.iter().map(Vec::len).sum::<usize>();
    }
    println!(
        "{test}: {} replies, {compared} bytes and {} notifications equal",
        a.len(),
        na.len()
    );
    na.into_iter().map(|(_, uid)| uid).collect()
}

/// door.xml: PickLock replaced by FAILURE (one retry a tick), a breakpoint on the root (STATUS
/// compared while it holds each tick) unlocked twice and then removed while it holds, and a
/// breakpoint on SmashDoor unlocked early (the next time it is reached it goes on at once),
/// then with SUCCESS and removal.
#[test]
fn door_hooks_act_as_in_behaviortree_cpp() {
    let Some(py) = python("door_hooks_act_as_in_behaviortree_cpp") else {
        return;
    };
    let uids = compare_hooks(
        &py,
        "groot2_door_hooks",
        "groot2/door.xml",
        "groot2/door_hooks.script",
        "groot2/door_hooks.json",
    );
    // BehaviorTree.CPP 4.8.2's notifications: every hook that acts, replacements included.
    assert_eq!(uids, ["1", "9", "1", "9", "1", "9", "10", "10", "10"]);
}

/// reactive.xml: a hook at position POST on SetBlackboard (BehaviorTree.CPP 4.8.2 runs it
/// before the tick: "target" is never written), AtGoal replaced by FAILURE until the client
/// removes that hook while Move is held, a held breakpoint updated in place, and Move released
/// by disabling all hooks.
#[test]
fn reactive_hooks_act_as_in_behaviortree_cpp() {
    let Some(py) = python("reactive_hooks_act_as_in_behaviortree_cpp") else {
        return;
    };
    let uids = compare_hooks(
        &py,
        "groot2_reactive_hooks",
        "groot2/reactive.xml",
        "groot2/reactive_hooks.script",
        "groot2/reactive_hooks.json",
    );
    assert_eq!(uids, ["3", "7", "8", "7", "8"]);
}

/// A client sets a breakpoint on the root and goes away: the first tick is held until the
/// heartbeat delay (`--groot2-heartbeat 1500`) has passed without a request, then the run goes
/// on as it would without hooks.
#[test]
fn a_vanished_clients_breakpoint_is_released_after_the_heartbeat_delay() {
    let Some(py) = python("a_vanished_clients_breakpoint_is_released_after_the_heartbeat_delay")
    else {
        return;
    };
    let dir = scratch("groot2_vanish");
    let (tree, script) = (data("groot2/door.xml"), data("groot2/door.script"));
    let bin = env!("CARGO_BIN_EXE_chronomap");
    let run = hooks_session(
        &py,
        &dir.join("vanish.json"),
        &data("groot2/door_vanish.json"),
        &|port| {
            [
                bin, "bt", "run", &tree, "--script", &script, "--groot2", port,
            ]
            .into_iter()
            .chain(["--tick-period", "100", "--groot2-heartbeat", "1500"])
            .map(str::to_owned)
            .collect()
        },
    );
    let plain = Command::new(bin)
        .args(["bt", "run", &tree, "--script", &script])
        .output()
        .unwrap();
    let plain = serde_json::json!({
        "stdout": String::from_utf8_lossy(&plain.stdout).lines().collect::<Vec<_>>()
    });
    assert_eq!(tick_lines(&run), tick_lines(&plain));
    assert_eq!(tick_lines(&run).last().unwrap(), "SUCCESS at tick 5");
    // Held from tick 1 until 1.5 s after the last request (seen within 0.1 s), then 4 ticks
    // 0.1 s apart.
    let after = run["result_after_s"].as_f64().unwrap();
    assert!(
        (1.4..8.0).contains(&after),
        "result {after} s after the client left"
    );
    println!("vanished client: result {after:.2} s after it left");
}
