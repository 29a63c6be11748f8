//! `chronomap ros2` started, configured, logged and managed as ROS 2 tools do it with any node.
//!
//! Without DDS: the ROS arguments of `ros2 run` and launch files (`--ros-args` with `-r`
//! remaps, `__node`/`__ns`, `-p` parameters, `--params-file` files with `/**`, node and
//! dotted entries, as `launch_ros` writes them) configure the node as rcl reads them (the
//! values rclpy 9.1.2 gives, probed, are in `chronomap_ros2::ros_args`' and `params`' unit
//! tests); wrong arguments are usage errors (exit 2) naming the argument, wrong values failures
//! (exit 1) naming the file and line, or the argument, and the parameter.
//!
//! With rclpy on Fast DDS (`tests/ros2/drive_conventions.py`, in a private network namespace as
//! `ros2_node.rs` runs it): the node's topics appear under their remapped names, its parameters
//! are listed, read, described and set through the `rcl_interfaces` services with rclpy's
//! `AsyncParameterClient` (what `ros2 param` does) — a new `publish_period` changes the rate of
//! the predictions, refused values come back with their reason — changes appear on
//! `/parameter_events`, its log on `/rosout`; and a managed node answers as an rclpy
//! `LifecycleNode` (rcl_lifecycle) answers, goes through configure → activate → deactivate →
//! cleanup → shutdown with its transition events, and publishes predictions only while active.

use std::path::Path;
use std::time::Instant;

use serde_json::{Value, json};

use crate::common::{
    assert_mentions, chronomap, error, json, oracle_python, scratch, usage_error, write,
};
use crate::ros2_node::{PrivateNetwork, private_network_or_skip};

/// A parameter file as `launch_ros` writes one for `parameters=[{...}]` (every node, dotted
/// keys), with a nested entry for the node by its full name and one for another node.
const LAUNCH_PARAMS: &str = "\
/**:
  ros__parameters:
    states.door.topic: /door
    states.door.type: std_msgs/msg/Bool
    horizon: 60.0
/robot1/office_model:
  ros__parameters:
    states:
      door:
        model: hist:24
other_node:
  ros__parameters:
    colour: red
";

fn check(args: &[&str]) -> Value {
    let mut all = vec!["ros2", "--check", "--json"];
    all.extend_from_slice(args);
    json(&chronomap(&all))
}

fn topics(out: &Value) -> Vec<(String, String)> {
    out["topics"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                t["direction"].as_str().unwrap().to_string(),
                t["topic"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

#[test]
fn ros_arguments_name_and_configure_the_node_as_rcl_reads_them() {
    let dir = scratch("ros2_conventions_args");
    let params = write(&dir, "launch_params.yaml", LAUNCH_PARAMS)
        .display()
        .to_string();
    // What launch_ros passes for Node(name='office_model', namespace='robot1',
    // parameters=[file, {'horizon': 600.0}], remappings=[('/door', '/front_door')]).
    let out = check(&[
        "--ros-args",
        "-r",
        "__node:=office_model",
        "-r",
        "__ns:=/robot1",
        "--params-file",
        &params,
        "-p",
        "horizon:=600.0",
        "-r",
        "/door:=/front_door",
    ]);
    assert_eq!(out["node"], "/robot1/office_model");
    assert_eq!(out["horizon"], 600.0, "-p after the file wins");
    assert_eq!(
        out["states"][0]["model"], "hist:24",
        "the node's entry applies"
    );
    assert_eq!(out["states"][0]["topic"], "/front_door", "remapped");
    assert_eq!(
        topics(&out),
        [
            ("in", "/front_door"),
            ("out", "/robot1/office_model/door/probability"),
            ("out", "/robot1/office_model/door/entropy"),
        ]
        .map(|(a, b)| (a.to_string(), b.to_string()))
    );
    // A later source wins: the file after -p.
    let out = check(&["--ros-args", "-p", "horizon:=7.5", "--params-file", &params]);
    assert_eq!(out["horizon"], 60.0);
    assert_eq!(out["node"], "/chronomap");
    assert_eq!(
        out["states"][0]["model"], "fremen:2",
        "/robot1/office_model's entry is not this node's"
    );
    // With --config the ROS arguments apply on top; a node-specific -p for another node not.
    let config = write(
        &dir,
        "node.yaml",
        "chronomap:\n  ros__parameters:\n    horizon: 5.0\n    states:\n      door: {topic: door, type: std_msgs/msg/Float64}\n",
    )
    .display()
    .to_string();
    let out = check(&[
        "--config",
        &config,
        "--ros-args",
        "-r",
        "__ns:=/r2",
        "-p",
        "chronomap:states.door.model:=hist:12",
        "-p",
        "other:horizon:=1.0",
        "--log-level",
        "debug",
    ]);
    assert_eq!(out["node"], "/r2/chronomap");
    assert_eq!(out["horizon"], 5.0);
    assert_eq!(out["states"][0]["model"], "hist:12");
    assert_eq!(
        out["states"][0]["topic"], "/r2/door",
        "relative to the new namespace"
    );
}

#[test]
fn wrong_ros_arguments_are_usage_errors_and_wrong_values_failures_naming_them() {
    let dir = scratch("ros2_conventions_errors");
    let params = write(&dir, "p.yaml", LAUNCH_PARAMS).display().to_string();
    for (args, expected) in [
        (
            vec!["--ros-args", "--bogus"],
            "error: --ros-args: `--bogus`: not a ROS argument",
        ),
        (
            vec!["--ros-args", "-r", "a"],
            "error: --ros-args: `-r a`: not a remap rule (expected FROM:=TO)",
        ),
        (
            vec!["--ros-args", "-r", "__ns:=robot"],
            "`-r __ns:=robot`: \"robot\" is not a fully qualified namespace",
        ),
        (
            vec!["--ros-args", "-p", "horizon"],
            "`-p horizon`: not a parameter (expected NAME:=VALUE)",
        ),
        (
            vec!["--ros-args", "--log-level", "loud"],
            "\"loud\" is not a severity",
        ),
        (
            vec!["--ros-args", "-e", "/robot"],
            "`-e /robot`: this node has no DDS security",
        ),
        (
            vec![
                "--ros-args",
                "--params-file",
                params.as_str(),
                "--",
                "--check",
            ],
            "--ros-args: `--check` after `--`: chronomap's own flags go before --ros-args",
        ),
        (
            vec![],
            "give --config FILE, or --ros-args with --params-file",
        ),
    ] {
        let mut all = vec!["ros2"];
        all.extend(args.iter().copied());
        assert_mentions(&usage_error(&chronomap(&all)), &[expected]);
    }
    let missing = dir.join("missing.yaml").display().to_string();
    let config_path = write(
        &dir,
        "node.yaml",
        "chronomap:\n  ros__parameters:\n    maps:\n      office:\n        topic: /map_in\n        order: auto\n",
    );
    let config = config_path.display().to_string();
    for (args, expected) in [
        (
            vec!["--ros-args", "--params-file", params.as_str(), "-p", "publish_period:=abc"],
            "error: -p publish_period:=abc: publish_period: expected a number, found the string \"abc\"".to_string(),
        ),
        (
            vec!["--ros-args", "--params-file", params.as_str(), "-p", "states.door.model:=fremen:99"],
            "error: -p states.door.model:=fremen:99: states.door.model: `fremen:99`: order 99 is above the largest order 84".to_string(),
        ),
        (
            vec!["--ros-args", "--params-file", params.as_str(), "-p", "colour:=red"],
            "error: -p colour:=red: colour: unknown parameter".to_string(),
        ),
        (
            vec!["--ros-args", "--params-file", missing.as_str()],
            format!("error: {missing}: cannot read"),
        ),
        (
            vec!["--config", config.as_str()],
            format!(
                "error: {config}:6: maps.office.order: expected an integer >= 0, found the string \"auto\" \
                 (the node learns every cell with a fixed order; `chronomap grid build --order auto` \
                 chooses one offline on a whole series)"
            ),
        ),
    ] {
        let mut all: Vec<&str> = vec!["ros2", "--check"];
        all.extend(args.iter().copied());
        assert_mentions(&error(&chronomap(&all)), &[&expected]);
    }
}

/// The launch file example's parameter file and remaps check.
#[test]
fn the_launch_file_example_s_parameters_check() {
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/ros2");
    let launch = std::fs::read_to_string(example.join("chronomap.launch.py")).unwrap();
    assert_mentions(
        &launch,
        &[
            "executable='chronomap'",
            "arguments=['ros2']",
            "remappings=",
        ],
    );
    // launch_ros passes these for the example (its name, namespace, file, dict and remap).
    let params = example.join("chronomap.yaml").display().to_string();
    let out = check(&[
        "--ros-args",
        "-r",
        "__node:=chronomap",
        "-r",
        "__ns:=/robot1",
        "--params-file",
        &params,
        "-p",
        "horizon:=600.0",
        "-r",
        "/door:=/front_door/open",
    ]);
    assert_eq!(out["node"], "/robot1/chronomap");
    assert_eq!(out["states"][0]["topic"], "/front_door/open");
    assert_eq!(out["horizon"], 600.0);
}

/// Runs `tests/ros2/drive_conventions.py` in `mode` with `plan` in a private network namespace.
fn drive(netns: &PrivateNetwork, python: &str, dir: &Path, mode: &str, plan: &Value) -> Value {
    let plan_file = write(dir, &format!("{mode}.json"), plan.to_string());
    let started = Instant::now();
    let (result, _) = netns.drive(dir, python, "drive_conventions.py", &[&plan_file, &mode]);
    println!(
        "ros2_conventions {mode}: {:.1} s",
        started.elapsed().as_secs_f64()
    );
    result
}

fn median(values: &Value) -> f64 {
    let mut v: Vec<f64> = values
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert!(v.len() >= 3, "too few predictions: {v:?}");
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn ros_python(test: &str) -> Option<(String, PrivateNetwork)> {
    let enable = "set CHRONOMAP_ROS_PYTHON to a Python with ros-kilted-rclpy[fastrtps]==9.1.2, \
                  ros-kilted-std-msgs, ros-kilted-rcl-interfaces and ros-kilted-lifecycle-msgs \
                  (.ci/run makes target/ros-venv)";
    let python = oracle_python("ROS", test, "ROS 2 conventions", enable)?;
    let netns = private_network_or_skip(test)?;
    Some((python, netns))
}

#[test]
fn parameters_are_ros_parameters_that_rclpy_lists_gets_and_sets() {
    let Some((python, netns)) = ros_python("ros2_conventions_parameters") else {
        return;
    };
    let dir = scratch("ros2_conventions_parameters");
    let params = write(&dir, "launch_params.yaml", LAUNCH_PARAMS)
        .display()
        .to_string();
    let plan = json!({
        "command": ["ros2", "--json", "--ros-args", "-r", "__node:=office_model",
                    "-r", "__ns:=/robot1", "--params-file", params,
                    "-p", "publish_period:=0.5", "-r", "/door:=/front_door"],
        "node": "/robot1/office_model",
        "door": "/front_door",
        "probability": "/robot1/office_model/door/probability",
        "get": ["publish_period", "states.door.model", "horizon", "states.door.topic",
                "use_sim_time"],
        "set": [["publish_period", 0.1]],
        "refused": [["publish_period", -1.0], ["publish_period", "fast"],
                    ["states.door.model", "fremen:2"], ["colour", "red"]],
        "atomic": [["horizon", 30.0], ["states.door.topic", "/x"]],
    });
    let r = drive(&netns, &python, &dir, "parameters", &plan);
    let node = &r["node"];
    let log = node["stderr"].as_str().unwrap();
    assert_eq!(node["returncode"], 0, "{log}");

    // The ROS graph: the node under its new name, its topics remapped.
    let graph = &r["graph"];
    assert!(
        graph["nodes"]
            .as_array()
            .unwrap()
            .contains(&json!("/robot1/office_model")),
        "{graph}"
    );
    let topics = &graph["topics"];
    assert_eq!(
        topics["/front_door"],
        json!(["std_msgs/msg/Bool"]),
        "{topics}"
    );
    assert_eq!(
        topics["/robot1/office_model/door/probability"],
        json!(["std_msgs/msg/Float64"])
    );
    assert!(topics.get("/door").is_none(), "{topics}");

    // list / get / describe.
    assert_eq!(
        r["list"],
        json!([
            "days_off_file",
            "horizon",
            "map_period",
            "max_map_cells",
            "memory_limit",
            "publish_period",
            "record_observations",
            "save_period",
            "states.door.depth",
            "states.door.entropy_topic",
            "states.door.model",
            "states.door.prediction_topic",
            "states.door.probability_topic",
            "states.door.reliability",
            "states.door.topic",
            "states.door.transient_local",
            "states.door.type",
            "sync_messages",
            "sync_period",
            "use_sim_time"
        ])
    );
    // rcl_interfaces/msg/ParameterType: 1 bool, 3 double, 4 string.
    assert_eq!(
        r["get"],
        json!([
            [3, 0.5],
            [4, "hist:24"],
            [3, 60.0],
            [4, "/front_door"],
            [1, false]
        ])
    );
    let describe = &r["describe"];
    assert_eq!(describe[0]["name"], "publish_period");
    assert_eq!(
        (&describe[0]["type"], &describe[0]["read_only"]),
        (&json!(3), &json!(false))
    );
    assert_eq!(describe[1]["read_only"], true);
    assert_mentions(
        describe[0]["description"].as_str().unwrap(),
        &["between state predictions"],
    );

    // A new publish_period changes the rate of the predictions.
    assert_eq!(r["set"], json!([[true, ""]]));
    let (before, after) = (
        median(&r["intervals_before"]),
        median(&r["intervals_after"]),
    );
    assert!((0.35..0.65).contains(&before), "every 0.5 s: {before}");
    assert!((0.05..0.16).contains(&after), "every 0.1 s: {after}");

    // Refused values come back with the reason, naming the parameter.
    let refused = r["refused"].as_array().unwrap();
    let reasons: Vec<&str> = refused.iter().map(|x| x[1].as_str().unwrap()).collect();
    assert!(refused.iter().all(|x| x[0] == false), "{refused:?}");
    assert_eq!(
        reasons[..3],
        [
            "publish_period: -1 is not a finite number of seconds > 0",
            "publish_period: expected a number, found the string \"fast\"",
            "states.door.model: read only: restart the node with the new value",
        ]
    );
    assert!(
        reasons[3].starts_with("colour: unknown parameter"),
        "{}",
        reasons[3]
    );
    // All or nothing: horizon stays 60 because the topic is read only.
    assert_eq!(
        r["atomic"],
        json!([
            false,
            "states.door.topic: read only: restart the node with the new value"
        ])
    );
    assert_eq!(r["get_after"][0], json!([3, 0.1]));
    assert_eq!(r["get_after"][2], json!([3, 60.0]));

    // /parameter_events and /rosout.
    let events = r["parameter_events"].as_array().unwrap();
    assert!(
        events.iter().any(|e| e["node"] == "/robot1/office_model"
            && e["changed"] == json!([["publish_period", [3, 0.1]]])),
        "{events:?}"
    );
    let rosout = r["rosout"].as_array().unwrap();
    let set_line = rosout
        .iter()
        .find(|m| m["msg"] == "parameter publish_period set to 0.1")
        .unwrap_or_else(|| panic!("not on /rosout: {rosout:?}"));
    assert_eq!(set_line["name"], "robot1.office_model");
    assert_eq!(set_line["level"], 20, "INFO");
    assert!(set_line["file"].as_str().unwrap().ends_with("node/mod.rs"));
    assert_eq!(set_line["function"], "chronomap_ros2::node");
    assert!(set_line["line"].as_u64().unwrap() > 0);
    assert!(
        rosout.iter().any(|m| m["level"] == 30
            && m["msg"]
                .as_str()
                .unwrap()
                .contains("refused: publish_period: -1 is not")),
        "{rosout:?}"
    );
    // stderr has the same lines, as before.
    assert_mentions(
        log,
        &[
            "[INFO]",
            "[robot1.office_model]: parameter publish_period set to 0.1",
        ],
    );
    let summary: Value = serde_json::from_str(node["stdout"].as_str().unwrap()).unwrap();
    assert_eq!(summary["node"], "/robot1/office_model");
    assert_eq!(summary["states"][0]["learned"], 30, "{summary}");
}

#[test]
fn a_managed_node_goes_through_the_lifecycle_as_rcl_lifecycle_defines_it() {
    let Some((python, netns)) = ros_python("ros2_conventions_lifecycle") else {
        return;
    };
    let dir = scratch("ros2_conventions_lifecycle");
    let config = write(
        &dir,
        "node.yaml",
        "chronomap:\n  ros__parameters:\n    publish_period: 0.1\n    save_dir: saved\n    \
         states:\n      door: {topic: /door, type: std_msgs/msg/Bool, model: fremen:2}\n",
    );
    let plan = json!({
        "command": ["ros2", "--managed", "--json", "--config", config.display().to_string()],
        "node": "/chronomap",
        "door": "/door",
        "probability": "/chronomap/door/probability",
        "window": 0.6,
        "steps": [
            {"id": 3},
            {"id": 1},
            {"label": "activate"},
            {"id": 4},
            {"id": 2},
            {"set": [["states.door.model", "hist:24"]]},
            {"id": 1},
            {"set": [["states.door.model", "fremen:2"]]},
            {"id": 1},
            {"label": "shutdown"},
        ],
    });
    let r = drive(&netns, &python, &dir, "lifecycle", &plan);
    let log = r["node"]["stderr"].as_str().unwrap();
    assert_eq!(r["node"]["returncode"], 0, "{log}");
    // The node's states, transitions and graph are an rclpy LifecycleNode's.
    let (expected, actual) = (&r["expected"], &r["actual"]);
    assert_eq!(actual["state"], 1, "unconfigured at start");
    for key in ["states", "transitions", "graph"] {
        assert_eq!(actual[key], expected[key], "{key}");
    }
    assert_eq!(expected["graph"].as_array().unwrap().len(), 25);

    let steps = r["steps"].as_array().unwrap();
    let step = |k: usize| &steps[k];
    // (transition id, label, start, goal, stamped) of the events of a step.
    let events = |k: usize| step(k)["events"].clone();
    // Activate before configure: refused, nothing happens.
    assert_eq!(
        (&step(0)["success"], &step(0)["state"]),
        (&json!(false), &json!(1))
    );
    assert_eq!(events(0), json!([]));
    assert_eq!(step(0)["publishers"], 0);
    // Configure: inactive, publishers made, no predictions.
    assert_eq!(step(1)["success"], true);
    assert_eq!(step(1)["state"], 2);
    assert_eq!(
        events(1),
        json!([
            [1, "configure", 1, 10, true],
            [10, "transition_success", 10, 2, true]
        ])
    );
    assert_eq!(step(1)["publishers"], 1);
    assert_eq!(step(1)["predictions"], 0, "inactive: nothing published");
    // Activate (by label): predictions flow.
    assert_eq!(step(2)["state"], 3);
    assert_eq!(
        events(2),
        json!([
            [3, "activate", 2, 13, true],
            [30, "transition_success", 13, 3, true]
        ])
    );
    let active = step(2)["predictions"].as_u64().unwrap();
    assert!(active >= 3, "every 0.1 s for 0.6 s: {active}");
    // Deactivate: they stop.
    assert_eq!(step(3)["state"], 2);
    assert_eq!(
        events(3),
        json!([
            [4, "deactivate", 3, 14, true],
            [40, "transition_success", 14, 2, true]
        ])
    );
    assert_eq!(step(3)["predictions"], 0);
    // Cleanup: saved (the publishers are dropped; Fast DDS still lists them, see
    // docs/ros2.md).
    assert_eq!(step(4)["state"], 1);
    assert_eq!(
        events(4),
        json!([
            [2, "cleanup", 2, 11, true],
            [20, "transition_success", 11, 1, true]
        ])
    );
    assert_mentions(log, &["cleanup: saving the models"]);
    // Unconfigured, a read-only parameter may be set; the saved model (fremen:2) then stops
    // configure, which fails back to unconfigured.
    assert_eq!(step(5)["set"], json!([[true, ""]]));
    assert_eq!(
        (&step(6)["success"], &step(6)["state"]),
        (&json!(false), &json!(1))
    );
    assert_eq!(
        events(6),
        json!([
            [1, "configure", 1, 10, true],
            [11, "transition_failure", 10, 1, true]
        ])
    );
    assert_mentions(log, &["configure: cannot restore the models"]);
    assert_eq!(step(7)["set"], json!([[true, ""]]));
    assert_eq!(step(8)["state"], 2);
    // Shutdown by label from inactive (transition 6), saving.
    assert_eq!(step(9)["state"], 4);
    assert_eq!(
        events(9),
        json!([
            [6, "shutdown", 2, 12, true],
            [50, "transition_success", 12, 4, true]
        ])
    );
    // What the first active period learned was saved at cleanup and restored.
    let summary: Value = serde_json::from_str(r["node"]["stdout"].as_str().unwrap()).unwrap();
    let total = summary["states"][0]["total"].as_u64().unwrap();
    assert!(total >= 10, "{summary}");
    assert!(dir.join("saved/states/door.cmm").is_file());
}
