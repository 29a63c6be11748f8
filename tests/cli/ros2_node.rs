//! `chronomap ros2` against a real ROS 2 stack: rclpy on Fast DDS (`tests/ros2/drive_node.py`)
//! drives the node binary in a private network namespace, so that DDS discovery never leaves
//! the machine. The driver publishes simulated time on `/clock`, door states (every 10th
//! observation of the first days of the real Greg door data), observed maps, people and a
//! message of the wrong type on a state topic; it stops the node with SIGINT after 60 % of the
//! data and starts it again for the rest (the node saves and restores its models).
//!
//! What the node published (received by rclpy) must equal, **bit for bit**, what the command
//! line computes from the same observations: `chronomap fit` + `predict --json` on the
//! observations the node recorded (which must be the ones sent, at the times sent),
//! `chronomap grid build --frames` + `grid predict` (trinary map and scale mask, loaded as
//! nav2_map_server loads them) on the map frames sent, `grid predict` of the saved people
//! grid, and `chronomap topo predict --geojson` for the route graph the node rewrote (whose
//! edges carry the 90 % duration intervals of `EdgeModels::duration_interval` at that time).
//!
//! It runs when `CHRONOMAP_ROS_PYTHON` names a Python with ros-kilted-rclpy (and std_msgs,
//! nav_msgs, geometry_msgs); `.ci/run` makes one in `target/ros-venv` and sets
//! `CHRONOMAP_REQUIRE_ROS=1`, under which a missing interpreter or a machine where no private
//! network namespace can be made (`unshare -n`, or `unshare -rn` without root) fails the
//! test instead of skipping it.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use chronomap_io::navmap::{LoadSemantics, MapMode, SaveOptions, load_map, save_map};
use chronomap_io::read_pairs;
use chronomap_spatial::OccupancyMap;
use serde_json::{Value, json};

use crate::common::{
    assert_mentions, chronomap, data, error, greg_training, json, oracle_python, scratch, stdout,
    usage_error, write,
};

/// DDS domain of the test (inside its own network namespace).
const DOMAIN: &str = "77";
/// Steps of the simulated clock between flow-control waits.
pub(crate) const FLOW_EVERY: usize = 50;
/// The node predicts for its time plus this horizon (seconds).
pub(crate) const HORIZON: i64 = 3600;
/// The observed map: 30 x 20 cells of 0.1 m.
pub(crate) const WIDTH: u32 = 30;
pub(crate) const HEIGHT: u32 = 20;

/// A private network namespace with loopback up and multicast on it: the command that runs a
/// program in one. Root uses `unshare -n`; others `unshare -rn` (a user namespace) or, where
/// that is not allowed, `sudo -n unshare -n` and then `setpriv` back to their own user.
pub(crate) struct PrivateNetwork {
    prefix: Vec<String>,
}

impl PrivateNetwork {
    /// The first way that works here, or `None`.
    pub(crate) fn new() -> Option<Self> {
        let setup = "ip link set lo up && ip link set lo multicast on";
        let words = |w: &[&str]| w.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let script = format!("{setup} && exec \"$0\" \"$@\"");
        let mut candidates = vec![
            words(&["unshare", "-n", "sh", "-c", &script]),
            words(&["unshare", "-rn", "sh", "-c", &script]),
        ];
        let id = |flag: &str| {
            Command::new("id")
                .arg(flag)
                .output()
                .ok()
                .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        };
        if let (Some(uid), Some(gid)) = (id("-u"), id("-g"))
            && uid != "0"
        {
            let script = format!(
                "{setup} && exec setpriv --reuid={uid} --regid={gid} --init-groups \"$0\" \"$@\""
            );
            candidates.push(words(&["sudo", "-n", "unshare", "-n", "sh", "-c", &script]));
        }
        candidates.into_iter().find_map(|prefix| {
            let ok = Command::new(&prefix[0])
                .args(&prefix[1..])
                .arg("true")
                .output()
                .is_ok_and(|o| o.status.success());
            ok.then_some(PrivateNetwork { prefix })
        })
    }

    /// `program` in the namespace, on the test's DDS domain, with ROS's files in `dir` (sudo
    /// does not pass the environment on, so it is given with `env`).
    pub(crate) fn command(&self, dir: &Path, program: impl AsRef<std::ffi::OsStr>) -> Command {
        let mut command = Command::new(&self.prefix[0]);
        command
            .args(&self.prefix[1..])
            .arg("env")
            .arg(format!("ROS_DOMAIN_ID={DOMAIN}"))
            .arg(format!("ROS_HOME={}", dir.join("ros-home").display()))
            .arg(program)
            .current_dir(dir);
        command
    }

    /// Runs the rclpy driver `tests/ros2/SCRIPT` with `python` in the namespace, giving it the
    /// node binary and `args`: the JSON it prints and the last line of its stderr (its
    /// timing). Fails the test, with the driver's stderr, if it fails or prints no JSON.
    pub(crate) fn drive(
        &self,
        dir: &Path,
        python: &str,
        script: &str,
        args: &[&dyn AsRef<std::ffi::OsStr>],
    ) -> (Value, String) {
        let driver = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/ros2")
            .join(script);
        let mut command = self.command(dir, python);
        command.arg(&driver).arg(env!("CARGO_BIN_EXE_chronomap"));
        for arg in args {
            command.arg(arg);
        }
        let output = command.output().unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(output.status.success(), "{script} failed:\n{stderr}");
        let result: Value = serde_json::from_slice(&output.stdout)
            .unwrap_or_else(|e| panic!("{script} printed no JSON ({e}):\n{stderr}"));
        (result, stderr.lines().last().unwrap_or("").to_string())
    }
}

/// Frame `k` of the observed office at hour-of-day `hour`: walls, a door closed at night, a
/// desk whose occupancy fades over the day, a corner never seen.
pub(crate) fn office_frame(k: usize, hour: u32) -> Vec<i8> {
    let mut data = vec![0i8; (WIDTH * HEIGHT) as usize];
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let cell = (y * WIDTH + x) as usize;
            data[cell] = if x == 0 || y == 0 || x == WIDTH - 1 || y == HEIGHT - 1 {
                100
            } else if (10..13).contains(&x) && y == 6 {
                if (8..18).contains(&hour) { 0 } else { 100 }
            } else if (20..24).contains(&x) && (10..14).contains(&y) {
                (hour * 4 % 100) as i8
            } else if x > 24 && y > 14 {
                -1
            } else if (x + y + k as u32).is_multiple_of(17) {
                100
            } else {
                0
            };
        }
    }
    data
}

/// A map's cells as JSON numbers.
pub(crate) fn cells(value: &Value) -> Vec<i8> {
    value
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_i64().unwrap() as i8)
        .collect()
}

/// `grid predict GRID --time T` in `mode`, loaded as nav2_map_server loads it.
pub(crate) fn grid_predict(grid: &Path, time: i64, mode: &str, out: &Path) -> OccupancyMap {
    let yaml = out.with_extension("yaml");
    stdout(&chronomap(&[
        "grid",
        "predict",
        &grid.display().to_string(),
        "--time",
        &time.to_string(),
        "--mode",
        mode,
        "-o",
        &yaml.display().to_string(),
    ]));
    load_map(&yaml, LoadSemantics::Nav2).unwrap()
}

/// `chronomap fit --model SPEC` of `record` (in `dir`), then `predict --at T --json` at each
/// of `times`: p and entropy.
pub(crate) fn fit_and_predict(
    dir: &Path,
    record: &str,
    spec: &str,
    times: &[i64],
) -> Vec<(f64, f64)> {
    let model = dir.join(format!("{}.cmm", spec.replace(':', "_")));
    stdout(&chronomap(&[
        "fit",
        "--train",
        &dir.join(record).display().to_string(),
        "--model",
        spec,
        "-o",
        &model.display().to_string(),
    ]));
    times.iter().map(|&t| predict(&model, t)).collect()
}

/// `predict MODEL --at T --json`: p and entropy.
pub(crate) fn predict(model: &Path, time: i64) -> (f64, f64) {
    let out = json(&chronomap(&[
        "predict",
        &model.display().to_string(),
        "--at",
        &time.to_string(),
        "--json",
    ]));
    let row = &out["predictions"][0];
    (
        row["p"].as_f64().unwrap(),
        row["entropy_bits"].as_f64().unwrap(),
    )
}

#[test]
fn the_node_on_a_ros_2_stack_predicts_bit_for_bit_what_the_command_line_predicts() {
    let started = Instant::now();
    let enable = "set CHRONOMAP_ROS_PYTHON to a Python with ros-kilted-rclpy[fastrtps]==9.1.2, \
                  ros-kilted-std-msgs, -nav-msgs and -geometry-msgs 5.5.1 (.ci/run makes \
                  target/ros-venv)";
    let Some(python) = oracle_python("ROS", "ros2_node", "ROS 2 interoperability", enable) else {
        return;
    };
    let Some(netns) = private_network_or_skip("ros2_node") else {
        return;
    };
    let dir = scratch("ros2_node");
    let path = |name: &str| dir.join(name).display().to_string();

    // The door: every 10th observation (10 minutes apart) of the Greg door, 900 of them.
    let greg = greg_training();
    let door: Vec<(i64, f64)> = greg
        .times
        .iter()
        .zip(&greg.values)
        .step_by(10)
        .take(900)
        .map(|(&t, &v)| {
            assert_eq!(t.fract(), 0.0, "whole seconds, as /clock carries them here");
            (t as i64, v)
        })
        .collect();
    let split = 540;
    // 24 map frames stamped at every 37th step, saved as raw maps (exact cell values) for
    // `grid build --frames`.
    let mut frames = Vec::new();
    let mut frame_list = String::new();
    for k in 0..24 {
        let time = door[k * 37].0;
        let hour = (time % 86400 / 3600) as u32;
        let data = office_frame(k, hour);
        let mut map = OccupancyMap::new(WIDTH, HEIGHT, 0.1, [-1.5, 2.0, 0.0]);
        map.data = data.clone();
        let options = SaveOptions {
            mode: MapMode::Raw,
            ..SaveOptions::default()
        };
        save_map(&dir.join(format!("frame{k}")), &map, &options).unwrap();
        frame_list.push_str(&format!("{time} frame{k}.yaml\n"));
        frames.push(json!({"time": time, "data": data}));
    }
    write(&dir, "frames.txt", &frame_list);
    // The route graph's edge models.
    stdout(&chronomap(&[
        "topo",
        "fit",
        "--edges",
        &data("witham_topological_nav/edges"),
        "-o",
        &path("witham.cmt"),
    ]));

    let steps: Vec<Value> = door
        .iter()
        .enumerate()
        .map(|(i, &(t, v))| {
            let mut step = json!({"clock": t, "door": v});
            if i % 37 == 0 && i / 37 < 24 {
                step["map"] = json!(i / 37);
            }
            if i < split && i % 3 == 0 {
                let h = (t % 86400 / 3600) as f64;
                let mut people = vec![[2.25 + 0.25 * (h % 12.0), 1.25]];
                if (9.0..17.0).contains(&h) {
                    people.push([7.5, 3.75]);
                }
                step["people"] = json!(people);
            }
            if i % 50 == 1 {
                step["wrong"] = json!(true);
            }
            // A 400 x 400 map (160,000 cells) where max_map_cells is 10,000: RustDDS drops
            // it at its first fragment, before allocating it, with one line.
            if i == 100 {
                step["oversized"] = json!(400);
            }
            step
        })
        .collect();
    let config = "\
chronomap:
  ros__parameters:
    use_sim_time: true
    max_map_cells: 10000
    publish_period: 1.0
    map_period: 1.0
    horizon: 3600.0
    save_dir: saved
    record_observations: true
    states:
      door: {topic: /door, type: std_msgs/msg/Bool, model: fremen:2, depth: 5000}
      window: {topic: /window, type: std_msgs/msg/Bool}
    maps:
      office: {topic: /observed_map, depth: 100}
    people:
      lobby: {topic: /people, width: 20, height: 10, resolution: 0.5, origin: [0, 0], bin: 3600, values: scale, depth: 1000}
    edges: {models: witham.cmt, geojson: route.geojson, period: 1.0}
";
    let config_file = write(&dir, "node.yaml", config);
    let topics = json!({
        "door": "/door", "map": "/observed_map", "people": "/people", "wrong": "/window",
        "predicted_map": "/chronomap/office/predicted_map", "mask": "/chronomap/office/mask",
        "people_map": "/chronomap/lobby/predicted_map",
        "probability": "/chronomap/door/probability", "entropy": "/chronomap/door/entropy",
    });
    let plan = json!({
        "config": config_file.display().to_string(),
        "topics": topics,
        "flow_every": FLOW_EVERY,
        "map_info": {"width": WIDTH, "height": HEIGHT, "resolution": 0.1, "origin": [-1.5, 2.0]},
        "frames": frames.clone(),
        "phases": [{"steps": steps[..split]}, {"steps": steps[split..]}],
    });
    let plan_file = write(&dir, "plan.json", plan.to_string());

    let driving = Instant::now();
    let mut phases = Vec::new();
    let mut timings = Vec::new();
    for phase in ["0", "1"] {
        let (result, timing) = netns.drive(&dir, &python, "drive_node.py", &[&plan_file, &phase]);
        timings.push(timing);
        phases.push(result);
    }
    println!(
        "ros2_node: DDS part {:.1} s ({})",
        driving.elapsed().as_secs_f64(),
        timings.join("; ")
    );

    // Each run stopped cleanly on SIGINT, learned what was sent, refused the wrong type.
    let mut people_bins = std::collections::BTreeSet::new();
    for s in &steps[..split] {
        if s.get("people").is_some() {
            people_bins.insert(s["clock"].as_i64().unwrap() / 3600);
        }
    }
    for (phase, range, people) in [
        (&phases[0], 0..split, people_bins.len() as u64),
        (&phases[1], split..door.len(), 0),
    ] {
        let log = phase["stderr"].as_str().unwrap();
        assert_eq!(phase["returncode"], 0, "{log}");
        assert!(!log.contains("panicked"), "{log}");
        assert_mentions(
            log,
            &[
                "/window: a publisher sends nav_msgs/msg/OccupancyGrid, but this node expects \
                 std_msgs/msg/Bool (states.window.type); its messages are ignored",
                "stopping: saving the models",
            ],
        );
        // The oversized map (first run): one line, from DDS, naming topic and size; nothing
        // else about it (no reassembly, no repair errors), and it is not learned.
        let dropped = log
            .lines()
            .filter(|l| l.contains("(max_sample_size)"))
            .collect::<Vec<_>>();
        if range.contains(&100) {
            assert_eq!(phase["sent"]["oversized"], 1);
            assert_eq!(dropped.len(), 1, "{log}");
            assert_mentions(
                dropped[0],
                &[
                    "topic \"rt/observed_map\": dropped sample",
                    "bytes, more than the 75536 bytes this participant accepts",
                ],
            );
            assert!(!log.contains("max size (256)"), "{log}");
        } else {
            assert!(dropped.is_empty(), "{log}");
        }
        let summary: Value = serde_json::from_str(phase["stdout"].as_str().unwrap()).unwrap();
        let sent = &phase["sent"];
        assert_eq!(sent["door"], range.len());
        let frames_sent = steps[range.clone()]
            .iter()
            .filter(|s| s.get("map").is_some())
            .count();
        assert_eq!(sent["maps"], frames_sent);
        assert!(sent["wrong"].as_u64().unwrap() >= 5, "{sent}");
        assert_eq!(summary["states"][0]["name"], "door");
        assert_eq!(summary["states"][0]["learned"], range.len(), "{summary}");
        assert_eq!(summary["states"][0]["total"], range.end, "{summary}");
        assert_eq!(summary["states"][1]["name"], "window");
        assert_eq!(summary["states"][1]["total"], 0, "{summary}");
        assert_eq!(summary["grids"][0]["frames"], frames_sent, "{summary}");
        assert_eq!(summary["grids"][1]["frames"], people, "{summary}");
        assert_eq!(summary["refused"], json!({}), "{summary}");
        assert_eq!(summary["saved"], true);
    }
    let last = phases[1]["final"]["clock"].as_i64().unwrap();
    assert_eq!(last, door[door.len() - 1].0);
    let target = last + HORIZON;
    let last_phase = &phases[1]["final"];

    // The door: the record is what was sent, at the times sent; the predictions published
    // are `chronomap fit` + `predict` of it, and of the saved model, bit for bit.
    let record = read_pairs(dir.join("saved/states/door.txt")).unwrap();
    let sent_times: Vec<f64> = door.iter().map(|&(t, _)| t as f64).collect();
    let sent_values: Vec<f64> = door.iter().map(|&(_, v)| v).collect();
    assert_eq!(record.values, sent_values);
    let late: Vec<(usize, f64, f64)> = (0..door.len())
        .filter(|&i| record.times[i] != sent_times[i])
        .map(|i| (i, record.times[i], sent_times[i]))
        .collect();
    assert!(
        late.is_empty(),
        "{} states not stamped with the clock sent before them (step, stamp, clock): {:?}",
        late.len(),
        &late[..late.len().min(10)]
    );
    let (p, h) = fit_and_predict(&dir, "saved/states/door.txt", "fremen:2", &[target])[0];
    let published = (
        last_phase["probability"].as_f64().unwrap(),
        last_phase["entropy"].as_f64().unwrap(),
    );
    assert_eq!(published.0.to_bits(), p.to_bits(), "{published:?} vs {p}");
    assert_eq!(published.1.to_bits(), h.to_bits(), "{published:?} vs {h}");
    assert!(p > 0.0 && p < 1.0, "{p}");
    assert_eq!(predict(&dir.join("saved/states/door.cmm"), target), (p, h));

    // The office: `grid build --frames` of the frames sent, `grid predict` as trinary map and
    // as scale mask, loaded as nav2_map_server loads them.
    stdout(&chronomap(&[
        "grid",
        "build",
        "--frames",
        &path("frames.txt"),
        "-o",
        &path("built.cmg"),
    ]));
    let map = &last_phase["map"];
    let mask = &last_phase["mask"];
    for (message, mode, grid, out) in [
        (map, "trinary", "built.cmg", "map"),
        (mask, "scale", "built.cmg", "mask"),
        (map, "trinary", "saved/maps/office.cmg", "saved-map"),
    ] {
        let expected = grid_predict(&dir.join(grid), target, mode, &dir.join(out));
        assert_eq!(cells(&message["data"]), expected.data, "{mode} of {grid}");
        assert_eq!(message["stamp"], json!([last, 0]));
        assert_eq!(message["frame_id"], "map");
        assert_eq!(
            (message["width"].as_u64(), message["height"].as_u64()),
            (Some(30), Some(20))
        );
        assert_eq!(message["resolution"].as_f64(), Some(f64::from(0.1f32)));
        assert_eq!(
            message["origin"],
            json!([-1.5, 2.0, 0.0, 0.0, 0.0, 0.0, 1.0])
        );
    }
    let map_cells = cells(&map["data"]);
    assert!(map_cells.contains(&100) && map_cells.contains(&0) && map_cells.contains(&-1));
    assert_ne!(map_cells, cells(&mask["data"]));

    // The people map is the saved people grid's prediction; the route graph is
    // `topo predict --geojson` at the same time, byte for byte.
    let people_map = &last_phase["people_map"];
    let expected = grid_predict(
        &dir.join("saved/people/lobby.cmg"),
        target,
        "scale",
        &dir.join("people"),
    );
    assert_eq!(cells(&people_map["data"]), expected.data);
    assert!(expected.data.iter().any(|&v| v > 0), "{:?}", expected.data);
    stdout(&chronomap(&[
        "topo",
        "predict",
        &path("witham.cmt"),
        "--time",
        &target.to_string(),
        "--geojson",
        &path("expected.geojson"),
    ]));
    let route = std::fs::read_to_string(dir.join("route.geojson")).unwrap();
    assert_eq!(
        route,
        std::fs::read_to_string(dir.join("expected.geojson")).unwrap()
    );
    // Each edge carries the 90 % interval of its duration that the library gives at that
    // time, as flat numbers.
    let models = chronomap_io::read_edge_models(dir.join("witham.cmt")).unwrap();
    let route: Value = serde_json::from_str(&route).unwrap();
    let edges: Vec<&Value> = route["features"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["geometry"]["type"] == "MultiLineString")
        .map(|f| &f["properties"]["metadata"])
        .collect();
    assert_eq!(edges.len(), models.map().edges().len());
    let coverage = chronomap_topo::edges::EVALUATION_COVERAGE;
    for (e, metadata) in edges.iter().enumerate() {
        let (lower, upper) = models
            .duration_interval(e, target as f64, coverage)
            .expect("models fitted now have intervals");
        assert_eq!(metadata["name"], models.map().edges()[e].id);
        assert_eq!(metadata["abs_time_taken_lower"].as_f64(), Some(lower));
        assert_eq!(metadata["abs_time_taken_upper"].as_f64(), Some(upper));
        assert_eq!(metadata["abs_time_taken_coverage"].as_f64(), Some(coverage));
    }

    // The ROS graph shows the filter info with Nav2's type (rclpy has no nav2_msgs to read it).
    let types = &phases[1]["topic_types"];
    assert_eq!(
        types["/chronomap/office/filter_info"],
        json!(["nav2_msgs/msg/CostmapFilterInfo"])
    );
    assert_eq!(
        types["/chronomap/door/probability"],
        json!(["std_msgs/msg/Float64"])
    );
    println!(
        "ros2_node: {} door states, {} maps, {} people messages in two runs; took {:.1} s",
        door.len(),
        frames.len(),
        steps.iter().filter(|s| s.get("people").is_some()).count(),
        started.elapsed().as_secs_f64()
    );
}

/// A private network namespace, or `None` after saying why `test` skips (a failure with
/// `CHRONOMAP_REQUIRE_ROS=1`).
pub(crate) fn private_network_or_skip(test: &str) -> Option<PrivateNetwork> {
    let netns = PrivateNetwork::new();
    if netns.is_none() {
        let why = "cannot make a private network namespace (`unshare -n` as root; `unshare -rn` \
                   or `sudo -n unshare -n` otherwise; iproute2's `ip`): the DDS tests must not \
                   reach the network";
        assert!(
            std::env::var("CHRONOMAP_REQUIRE_ROS").as_deref() != Ok("1"),
            "CHRONOMAP_REQUIRE_ROS=1 but {why}"
        );
        eprintln!("{test}: SKIPPED: {why}");
    }
    netns
}

const PEOPLE_NODE: &str = "\
chronomap:
  ros__parameters:
    save_dir: saved
    states:
      door: {topic: /door, type: std_msgs/msg/Float64, model: hist:24}
    people:
      lobby: {topic: /people, width: 4, height: 3, resolution: 1.0, origin: [0, 0]}
";

#[test]
fn check_lists_the_topics_and_bad_parameter_files_are_refused_by_file_line_and_parameter() {
    let dir = scratch("ros2_check");
    let good = write(&dir, "node.yaml", PEOPLE_NODE).display().to_string();
    let out = json(&chronomap(&[
        "ros2", "--config", &good, "--check", "--json",
    ]));
    assert_eq!(out["node"], "/chronomap");
    assert_eq!(out["states"][0]["model"], "hist:24");
    let topics: Vec<(String, String, String)> = out["topics"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            let text = |k: &str| t[k].as_str().unwrap().to_string();
            (text("direction"), text("topic"), text("type"))
        })
        .collect();
    let expected = [
        ("in", "/door", "std_msgs/msg/Float64"),
        ("out", "/chronomap/door/probability", "std_msgs/msg/Float64"),
        ("out", "/chronomap/door/entropy", "std_msgs/msg/Float64"),
        ("in", "/people", "geometry_msgs/msg/PoseArray"),
        (
            "out",
            "/chronomap/lobby/predicted_map",
            "nav_msgs/msg/OccupancyGrid",
        ),
        ("out", "/chronomap/lobby/mask", "nav_msgs/msg/OccupancyGrid"),
        (
            "out",
            "/chronomap/lobby/filter_info",
            "nav2_msgs/msg/CostmapFilterInfo",
        ),
    ];
    let expected: Vec<(String, String, String)> = expected
        .iter()
        .map(|(a, b, c)| (a.to_string(), b.to_string(), c.to_string()))
        .collect();
    assert_eq!(topics, expected);
    let text = stdout(&chronomap(&["ros2", "--config", &good, "--check"]));
    assert_mentions(
        &text,
        &[
            "node /chronomap: 1 states, 1 grids; parameters are valid",
            "/chronomap/lobby/filter_info",
        ],
    );

    // A bad file is a failure (exit 1) naming file, line and parameter; bad flags are usage
    // errors (exit 2).
    let bad = write(
        &dir,
        "bad.yaml",
        PEOPLE_NODE.replace("model: hist:24", "model: \"fremen:99\""),
    );
    let message = error(&chronomap(&[
        "ros2",
        "--config",
        &bad.display().to_string(),
        "--check",
    ]));
    assert_mentions(
        &message,
        &[&format!(
            "error: {}:5: states.door.model: `fremen:99`: order 99 is above the largest order 84",
            bad.display()
        )],
    );
    // A calendar of days off is read with the parameters: a date that is not one names the
    // parameter's file, line and name and the calendar's file and line.
    let with_days_off = |calendar: &str, days: &str| {
        write(&dir, calendar, days);
        let text = PEOPLE_NODE.replace(
            "    save_dir: saved\n",
            &format!("    save_dir: saved\n    days_off_file: {calendar}\n"),
        );
        write(&dir, "days_off.yaml", text).display().to_string()
    };
    let good_days = with_days_off("uk.txt", "2016-03-25 Good Friday\n2016-03-28\n");
    let out = json(&chronomap(&[
        "ros2", "--config", &good_days, "--check", "--json",
    ]));
    assert_eq!(out["days_off"]["days"], 2, "{out}");
    let bad_days = with_days_off("bad.txt", "2016-03-25\n2016-02-30 nope\n");
    assert_mentions(
        &error(&chronomap(&["ros2", "--config", &bad_days, "--check"])),
        &[&format!(
            "error: {bad_days}:4: days_off_file: {}:2: date: \"2016-02-30\" is not a date \
             YYYY-MM-DD",
            dir.join("bad.txt").display()
        )],
    );
    let missing = dir.join("missing.yaml").display().to_string();
    assert_mentions(
        &error(&chronomap(&["ros2", "--config", &missing])),
        &[&format!("{missing}: cannot read")],
    );
    usage_error(&chronomap(&["ros2"]));
    usage_error(&chronomap(&[
        "ros2",
        "--config",
        &good,
        "--domain-id",
        "300",
    ]));
}

#[test]
fn sigterm_stops_the_node_which_saves_what_it_has() {
    let Some(netns) = private_network_or_skip("ros2_sigterm") else {
        return;
    };
    let dir = scratch("ros2_sigterm");
    let config = write(&dir, "node.yaml", PEOPLE_NODE);
    let mut child = netns
        .command(&dir, env!("CARGO_BIN_EXE_chronomap"))
        .args(["ros2", "--config"])
        .arg(&config)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The node runs once it says so on stderr.
    let stderr = child.stderr.take().unwrap();
    let (lines, seen) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        use std::io::BufRead;
        for line in std::io::BufReader::new(stderr)
            .lines()
            .map_while(Result::ok)
        {
            let _ = lines.send(line);
        }
    });
    let mut log = Vec::new();
    while !log.iter().any(|l: &String| l.contains("on DDS domain")) {
        match seen.recv_timeout(std::time::Duration::from_secs(30)) {
            Ok(line) => log.push(line),
            Err(e) => {
                let _ = child.kill();
                panic!("the node did not start ({e}): {log:?}");
            }
        }
    }
    let killed = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let out = child.wait_with_output().unwrap();
    log.extend(seen.iter());
    let log = log.join("\n");
    assert_eq!(out.status.code(), Some(0), "{log}");
    assert_mentions(
        &log,
        &["[INFO]", "[chronomap]: stopping: saving the models"],
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert_mentions(
        &text,
        &[
            "states.door: learned 0 observations (0 in the model)",
            "people.lobby: learned 0 frames (0 in the grid)",
            "saved in",
        ],
    );
    assert!(dir.join("saved/people/lobby.cmg").is_file());
    assert!(dir.join("saved/states/door.cmm").is_file());
    let model = json(&chronomap(&[
        "inspect",
        &dir.join("saved/states/door.cmm").display().to_string(),
        "--json",
    ]));
    assert_eq!(model["model"], "hist:24", "{model}");
}
