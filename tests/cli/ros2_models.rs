//! The node's models from rclpy (`tests/ros2/drive_models.py`, Fast DDS, in a private network
//! namespace): two states learn one topic — `door` with `fremen:2`, `door_auto` with `auto`,
//! chronomap's stacked model, which is fitted on the kept observations — and the node's own
//! interfaces (`ros/chronomap_msgs`, built for rclpy from the PyPI wheels by `.ci/run`) carry
//! stamped predictions and `~/predict`; `~/refit` and `~/save` are `std_srvs/srv/Trigger`.
//!
//! Checked bit for bit against the command line: `~/predict` of `door` is `chronomap fit
//! --model fremen:2` + `predict` of the observations the node recorded, and of `door_auto`,
//! after `~/refit`, `chronomap fit --model auto` + `predict`; the stamped predictions carry the
//! time they are for (clock + horizon), the time they were made, the model and its count.
//! A continuous state (`level`, `std_msgs/msg/Float64`, `fremen:2`) carries its 90 % interval
//! in both, rclpy decoding the new fields: `beta_interval` of `chronomap fit` of its values and
//! of their squares; the door's (`Bool`) is NaN with coverage 0 and `~/predict` gives it none.
//!
//! Runs when `CHRONOMAP_ROS_PYTHON` names a Python with rclpy and `std_srvs`, and
//! `CHRONOMAP_ROS_MSGS` the built interfaces (`.ci/run` sets both).

use std::path::Path;

use chronomap_core::spread::beta_interval;
use serde_json::{Value, json};

use crate::common::{assert_mentions, greg_training, oracle_python, scratch, write};
use crate::ros2_node::{HORIZON, fit_and_predict, private_network_or_skip};

/// A JSON list of numbers.
pub(crate) fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// `CHRONOMAP_ROS_MSGS`, the chronomap_msgs built for rclpy, or `None` (the test skips), unless
/// `CHRONOMAP_REQUIRE_ROS=1`, under which its absence fails the test.
pub(crate) fn ros_msgs_or_skip(test: &str, enable: &str) -> Option<String> {
    let Ok(ros_msgs) = std::env::var("CHRONOMAP_ROS_MSGS") else {
        assert!(
            std::env::var("CHRONOMAP_REQUIRE_ROS").as_deref() != Ok("1"),
            "CHRONOMAP_REQUIRE_ROS=1 but CHRONOMAP_ROS_MSGS is not set: {enable}"
        );
        eprintln!("{test}: SKIPPED: {enable}");
        return None;
    };
    Some(ros_msgs)
}

/// The mean and the second moment at `times` of a continuous state that learned
/// `observations` (time, value) with `spec`: `chronomap fit --model SPEC` + `predict` of the
/// values and of their squares (written to `NAME_values.txt`, `NAME_squares.txt` in `dir`).
/// `beta_interval` of the two is the interval the node must publish.
pub(crate) fn fitted_moments(
    dir: &Path,
    name: &str,
    observations: &[(f64, f64)],
    spec: &str,
    times: &[i64],
) -> Vec<(f64, f64)> {
    let fit = |what: &str, f: fn(f64) -> f64| {
        let text: String = observations
            .iter()
            .map(|&(t, v)| format!("{t} {}\n", f(v)))
            .collect();
        let file = format!("{name}_{what}.txt");
        write(dir, &file, text);
        fit_and_predict(dir, &file, spec, times)
    };
    let mean = fit("values", |v| v);
    let second = fit("squares", |v| v * v);
    mean.iter().zip(&second).map(|(m, s)| (m.0, s.0)).collect()
}

#[test]
fn two_models_of_one_topic_stamped_predictions_and_the_node_s_services_from_rclpy() {
    let enable = "set CHRONOMAP_ROS_PYTHON to a Python with ros-kilted-rclpy[fastrtps]==9.1.2, \
                  ros-kilted-std-srvs==5.5.1 and the message packages, and CHRONOMAP_ROS_MSGS \
                  to chronomap_msgs built by tests/ros2/build_chronomap_msgs.sh (.ci/run does both)";
    let Some(python) = oracle_python("ROS", "ros2_models", "ROS 2 models", enable) else {
        return;
    };
    let Some(ros_msgs) = ros_msgs_or_skip("ros2_models", enable) else {
        return;
    };
    let Some(netns) = private_network_or_skip("ros2_models") else {
        return;
    };
    let dir = scratch("ros2_models");

    // Two weeks of the Greg door, one observation every 10 minutes.
    let greg = greg_training();
    let steps: Vec<Value> = greg
        .times
        .iter()
        .zip(&greg.values)
        .step_by(10)
        .take(2016)
        .enumerate()
        .map(|(i, (&t, &v))| json!({"clock": t as i64, "door": v, "level": level(i, v)}))
        .collect();
    let last = steps.last().unwrap()["clock"].as_i64().unwrap();
    let times: Vec<i64> = [0, 3600, 7 * 3600, 86_400 + 1800]
        .iter()
        .map(|d| last + d)
        .collect();
    let config = "\
chronomap:
  ros__parameters:
    use_sim_time: true
    publish_period: 1.0
    map_period: 60.0
    horizon: 3600.0
    save_dir: saved
    record_observations: true
    states:
      door: {topic: /door, type: std_msgs/msg/Bool, model: \"fremen:2\", depth: 5000}
      door_auto: {topic: /door, type: std_msgs/msg/Bool, model: auto, depth: 5000, refit_observations: 0, refit_period: 0}
      level: {topic: /level, type: std_msgs/msg/Float64, model: \"fremen:2\", depth: 5000}
";
    let config_file = write(&dir, "node.yaml", config);
    let plan = json!({
        "config": config_file.display().to_string(),
        "ros_msgs": ros_msgs,
        "states": ["door", "door_auto", "level"],
        "steps": steps,
        "flow_every": 100,
        "horizon": HORIZON,
        "times": times,
    });
    let plan_file = write(&dir, "plan.json", plan.to_string());
    let (r, _) = netns.drive(&dir, &python, "drive_models.py", &[&plan_file]);
    let log = r["stderr"].as_str().unwrap();
    assert_eq!(r["returncode"], 0, "{log}");

    // Both states learned every observation sent, each once, at the clock sent before it.
    let sent: Vec<(f64, f64)> = greg
        .times
        .iter()
        .zip(&greg.values)
        .step_by(10)
        .take(2016)
        .map(|(&t, &v)| (t, v))
        .collect();
    for name in ["door", "door_auto"] {
        let record =
            chronomap_io::read_pairs(dir.join(format!("saved/states/{name}.txt"))).unwrap();
        let recorded: Vec<(f64, f64)> = record.times.into_iter().zip(record.values).collect();
        assert_eq!(recorded.len(), sent.len(), "{name}");
        assert!(
            recorded == sent,
            "{name}: recorded observations differ from those sent"
        );
    }

    // The stamped predictions before the refit: for clock + horizon, made at the clock.
    let before = &r["before_refit"];
    let door = &before["door"];
    assert_eq!(door["stamp"], json!([last + HORIZON, 0]));
    assert_eq!(door["made"], json!([last, 0]));
    assert_eq!(
        (door["name"].as_str(), door["model"].as_str()),
        (Some("door"), Some("fremen:2"))
    );
    assert_eq!(door["observations"], sent.len());
    assert_eq!(door["frame_id"], "");
    let fremen = fit_and_predict(&dir, "saved/states/door.txt", "fremen:2", &[last + HORIZON]);
    assert_eq!(
        door["probability"].as_f64().unwrap().to_bits(),
        fremen[0].0.to_bits()
    );
    assert_eq!(
        door["entropy"].as_f64().unwrap().to_bits(),
        fremen[0].1.to_bits()
    );
    // `auto` predicts nothing before its first fit.
    let auto = &before["door_auto"];
    assert_eq!(
        (auto["model"].as_str(), auto["probability"].as_f64()),
        (Some("auto"), Some(0.5))
    );
    assert_eq!(auto["observations"], sent.len());

    // ~/refit, then ~/predict: bit for bit the command line's fit of the same observations.
    assert_eq!(r["refit"]["success"], true, "{}", r["refit"]);
    assert_mentions(
        r["refit"]["message"].as_str().unwrap(),
        &["refits of states.door_auto start now"],
    );
    assert_mentions(
        log,
        &[
            "refit of states.door_auto (auto, requested): weights ",
            &format!("on {} observations", sent.len()),
        ],
    );
    for (name, record, spec) in [
        ("door", "saved/states/door.txt", "fremen:2"),
        ("door_auto", "saved/states/door_auto.txt", "auto"),
    ] {
        let answer = &r["answers"][name];
        assert_eq!(answer["success"], true, "{answer}");
        assert_eq!(answer["model"], spec);
        let expected = fit_and_predict(&dir, record, spec, &times);
        let (p, h) = (floats(&answer["probability"]), floats(&answer["entropy"]));
        for (i, (ep, eh)) in expected.iter().enumerate() {
            assert_eq!(p[i].to_bits(), ep.to_bits(), "{name} p at {}", times[i]);
            assert_eq!(
                h[i].to_bits(),
                eh.to_bits(),
                "{name} entropy at {}",
                times[i]
            );
        }
        assert!(p.iter().any(|&x| x != p[0]), "{name}: {p:?}");
    }
    let unknown = &r["answers"]["unknown"];
    assert_eq!(unknown["success"], false);
    assert_eq!(
        unknown["message"],
        "no state \"window\" (the states: door, door_auto, level)"
    );
    // The refitted model's stamped prediction at the next clock.
    let after = &r["after_refit"];
    let at = r["after_clock"].as_i64().unwrap() + HORIZON;
    let expected = fit_and_predict(&dir, "saved/states/door_auto.txt", "auto", &[at]);
    assert_eq!(after["stamp"], json!([at, 0]));
    assert_eq!(
        after["probability"].as_f64().unwrap().to_bits(),
        expected[0].0.to_bits()
    );

    // The continuous state: its values recorded as sent; the interval of its stamped
    // prediction (of as many observations as it says it had learned) and of ~/predict is the
    // Beta law's of `chronomap fit` of the values and of their squares, bit for bit.
    let levels: Vec<(f64, f64)> = sent
        .iter()
        .enumerate()
        .map(|(i, &(t, v))| (t, level(i, v)))
        .collect();
    let record = chronomap_io::read_pairs(dir.join("saved/states/level.txt")).unwrap();
    let recorded: Vec<(f64, f64)> = record.times.into_iter().zip(record.values).collect();
    assert!(recorded == levels, "level: recorded observations differ");
    // Mean and second moment at `times` of `chronomap fit` of the first `n` values.
    let moments =
        |n: usize, times: &[i64]| fitted_moments(&dir, "level", &levels[..n], "fremen:2", times);
    let stamped = &before["level"];
    assert_eq!(stamped["stamp"], json!([last + HORIZON, 0]));
    let n = stamped["observations"].as_u64().unwrap() as usize;
    assert!(n + 5 >= sent.len(), "{n} of {}", sent.len());
    let (m, s) = moments(n, &[last + HORIZON])[0];
    let (lo, hi) = beta_interval(m, s, 0.9);
    assert_eq!(
        stamped["probability"].as_f64().unwrap().to_bits(),
        m.to_bits()
    );
    assert_eq!(stamped["lower"].as_f64().unwrap().to_bits(), lo.to_bits());
    assert_eq!(stamped["upper"].as_f64().unwrap().to_bits(), hi.to_bits());
    assert_eq!(stamped["coverage"], 0.9);
    assert!(0.0 < lo && lo < m && m < hi && hi < 1.0, "{lo} {m} {hi}");
    let answer = &r["answers"]["level"];
    assert_eq!(
        (answer["success"].as_bool(), answer["coverage"].as_f64()),
        (Some(true), Some(0.9))
    );
    let (lower, upper) = (floats(&answer["lower"]), floats(&answer["upper"]));
    assert_eq!((lower.len(), upper.len()), (times.len(), times.len()));
    for (i, (m, s)) in moments(sent.len(), &times).into_iter().enumerate() {
        let (lo, hi) = beta_interval(m, s, 0.9);
        assert_eq!(
            lower[i].to_bits(),
            lo.to_bits(),
            "level lower at {}",
            times[i]
        );
        assert_eq!(
            upper[i].to_bits(),
            hi.to_bits(),
            "level upper at {}",
            times[i]
        );
    }
    assert!(
        lower
            .iter()
            .zip(&upper)
            .any(|(l, u)| u - l != upper[0] - lower[0])
    );
    // A Bool state has no interval: NaN (null in the driver's JSON) and coverage 0 in the
    // stamped prediction, empty lists from ~/predict.
    for name in ["door", "door_auto"] {
        let stamped = &before[name];
        assert!(
            stamped["lower"].is_null() && stamped["upper"].is_null(),
            "{stamped}"
        );
        assert_eq!(stamped["coverage"], 0.0);
        let answer = &r["answers"][name];
        assert_eq!(answer["coverage"], 0.0);
        assert!(floats(&answer["lower"]).is_empty() && floats(&answer["upper"]).is_empty());
    }

    // ~/save made a checkpoint: the refitted learner is saved with its kept observations.
    assert_eq!(r["save"]["success"], true, "{}", r["save"]);
    assert_mentions(
        r["save"]["message"].as_str().unwrap(),
        &["checkpoint 1 at journal position", "4 files"],
    );
    assert!(dir.join("saved/states/door.cmm").is_file());
    assert!(dir.join("saved/states/door_auto.cml").is_file());
    assert!(dir.join("saved/states/level.squares.cmm").is_file());
}

/// The continuous state of step `i` with door state `door`: eighths, exact in binary and in
/// text, following the door and a weekly-ish cycle of the steps.
fn level(i: usize, door: f64) -> f64 {
    (i % 7) as f64 / 8.0 + door / 8.0
}
