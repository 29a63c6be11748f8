//! `chronomap ros2` killed with SIGKILL: what it acknowledged survives. rclpy on Fast DDS
//! (`tests/ros2/drive_node.py`, in a private network namespace) drives the node with simulated
//! time, door states (the real Greg door), a continuous state (`level`, `std_msgs/msg/Float64`
//! with a daily rhythm, `fremen:2`), observed maps and people, waiting every few steps
//! until the node has published a prediction at that step's clock (the node acknowledged
//! everything before it). After the last acknowledgement and a wait longer than the journal's
//! sync period, the driver sends a few more steps without waiting and kills the node with
//! SIGKILL. A second run restarts the node on the same `save_dir`, sends the rest and stops it
//! with SIGINT.
//!
//! Every acknowledged observation must be there after the restart, each once, at the clock
//! sent before it; of the steps in flight at the kill, what survived is a prefix; and what the
//! restarted node publishes equals, bit for bit, `chronomap fit` + `predict` of the observations
//! it holds and `grid build --frames` + `grid predict` of the frames it holds. The level's
//! interval — its stamped prediction (`chronomap_msgs/msg/Prediction`, decoded by rclpy), its
//! `~/predict` and the learner of its squares the restarted node saves — is `beta_interval` of
//! `chronomap fit` of its values and of their squares: the squares came back from the journal.
//!
//! It runs when `CHRONOMAP_ROS_PYTHON` names a Python with rclpy and `CHRONOMAP_ROS_MSGS` the
//! built chronomap_msgs (as `ros2_models.rs`; `.ci/run` sets both).

use std::time::Instant;

use chronomap_core::spread::beta_interval;
use chronomap_io::navmap::{MapMode, SaveOptions, save_map};
use chronomap_io::read_pairs;
use chronomap_spatial::OccupancyMap;
use serde_json::{Value, json};

use crate::common::{
    assert_mentions, chronomap, greg_training, oracle_python, scratch, stdout, write,
};
use crate::ros2_models::{fitted_moments, floats, ros_msgs_or_skip};
use crate::ros2_node::{
    FLOW_EVERY, HEIGHT, HORIZON, WIDTH, cells, fit_and_predict, grid_predict, office_frame,
    predict, private_network_or_skip,
};

/// Steps acknowledged before the kill, steps in flight at the kill, steps after the restart.
const ACKNOWLEDGED: usize = 400;
const IN_FLIGHT: usize = 30;
const AFTER: usize = 170;
/// Of the level's interval (`states.level.coverage` in the parameter file below).
const COVERAGE: f64 = 0.8;

#[test]
fn a_node_killed_with_sigkill_keeps_everything_it_acknowledged() {
    let started = Instant::now();
    let enable = "set CHRONOMAP_ROS_PYTHON to a Python with ros-kilted-rclpy[fastrtps]==9.1.2 \
                  and the message packages, and CHRONOMAP_ROS_MSGS to chronomap_msgs built by \
                  tests/ros2/build_chronomap_msgs.sh (.ci/run does both)";
    let Some(python) = oracle_python("ROS", "ros2_crash", "ROS 2 crash recovery", enable) else {
        return;
    };
    let Some(ros_msgs) = ros_msgs_or_skip("ros2_crash", enable) else {
        return;
    };
    let Some(netns) = private_network_or_skip("ros2_crash") else {
        return;
    };
    let dir = scratch("ros2_crash");
    let path = |name: &str| dir.join(name).display().to_string();

    let total = ACKNOWLEDGED + IN_FLIGHT + AFTER;
    let greg = greg_training();
    let door: Vec<(i64, f64)> = greg
        .times
        .iter()
        .zip(&greg.values)
        .step_by(10)
        .take(total)
        .map(|(&t, &v)| (t as i64, v))
        .collect();
    let levels: Vec<(i64, f64)> = door
        .iter()
        .enumerate()
        .map(|(i, &(t, _))| (t, level(i, t)))
        .collect();
    // A map frame every 9th step (saved for `grid build --frames`), people every 3rd.
    let mut frames = Vec::new();
    let mut map_steps = Vec::new();
    for i in (0..total).step_by(9) {
        let time = door[i].0;
        let data = office_frame(frames.len(), (time % 86400 / 3600) as u32);
        let mut map = OccupancyMap::new(WIDTH, HEIGHT, 0.1, [-1.5, 2.0, 0.0]);
        map.data = data.clone();
        let options = SaveOptions {
            mode: MapMode::Raw,
            ..SaveOptions::default()
        };
        save_map(&dir.join(format!("frame{}", frames.len())), &map, &options).unwrap();
        map_steps.push(i);
        frames.push(json!({"time": time, "data": data}));
    }
    let steps: Vec<Value> = door
        .iter()
        .enumerate()
        .map(|(i, &(t, v))| {
            let mut step = json!({"clock": t, "door": v, "level": levels[i].1});
            if let Some(k) = map_steps.iter().position(|&s| s == i) {
                step["map"] = json!(k);
            }
            if i % 3 == 0 {
                let h = (t % 86400 / 3600) as f64;
                step["people"] = json!([[2.25 + 0.25 * (h % 12.0), 1.25]]);
            }
            step
        })
        .collect();
    // No checkpoint before the kill (`save_period` is an hour of wall-clock time): what the
    // restart has, it has from the journal, synced within `sync_period` (1 s).
    let config = "\
chronomap:
  ros__parameters:
    use_sim_time: true
    publish_period: 1.0
    map_period: 1.0
    horizon: 3600.0
    save_dir: saved
    save_period: 3600.0
    sync_period: 1.0
    record_observations: true
    states:
      door: {topic: /door, type: std_msgs/msg/Bool, model: fremen:2, depth: 5000}
      level: {topic: /level, type: std_msgs/msg/Float64, model: fremen:2, coverage: 0.8, depth: 5000}
    maps:
      office: {topic: /observed_map, depth: 100}
    people:
      lobby: {topic: /people, width: 20, height: 10, resolution: 0.5, origin: [0, 0], bin: 3600, values: scale, depth: 1000}
";
    let config_file = write(&dir, "node.yaml", config);
    let topics = json!({
        "door": "/door", "map": "/observed_map", "people": "/people", "wrong": "/window",
        "predicted_map": "/chronomap/office/predicted_map", "mask": "/chronomap/office/mask",
        "people_map": "/chronomap/lobby/predicted_map",
        "probability": "/chronomap/door/probability", "entropy": "/chronomap/door/entropy",
    });
    let killed_at = ACKNOWLEDGED + IN_FLIGHT;
    // The restarted node's level is asked at clock + Δ and at two other times of day.
    let last = door[total - 1].0;
    let target = last + HORIZON;
    let times = [target, last + 4 * 3600, last + 10 * 3600 + 1800];
    let plan = json!({
        "config": config_file.display().to_string(),
        "ros_msgs": ros_msgs,
        "interval": {
            "state": "level", "topic": "/level", "prediction": "/chronomap/level/prediction",
            "predict": "/chronomap/predict", "times": times,
        },
        "topics": topics,
        "flow_every": FLOW_EVERY,
        "map_info": {"width": WIDTH, "height": HEIGHT, "resolution": 0.1, "origin": [-1.5, 2.0]},
        "frames": frames.clone(),
        "phases": [
            {
                "steps": steps[..ACKNOWLEDGED],
                "kill": {"wait": 2.5, "in_flight": steps[ACKNOWLEDGED..killed_at]},
            },
            {"steps": steps[killed_at..]},
        ],
    });
    let plan_file = write(&dir, "plan.json", plan.to_string());
    let phases: Vec<Value> = ["0", "1"]
        .iter()
        .map(|phase| {
            netns
                .drive(&dir, &python, "drive_node.py", &[&plan_file, phase])
                .0
        })
        .collect();

    // The first run was killed: no summary, no save at exit, no checkpoint.
    let crashed = &phases[0];
    let log = crashed["stderr"].as_str().unwrap();
    assert_eq!(crashed["returncode"], -9, "{log}");
    assert_eq!(crashed["stdout"], "", "{log}");
    assert!(!log.contains("stopping: saving"), "{log}");
    assert!(!log.contains("checkpoint 1"), "{log}");
    // The restart says what it restored, and stops cleanly.
    let restarted = &phases[1];
    let log = restarted["stderr"].as_str().unwrap();
    assert_eq!(restarted["returncode"], 0, "{log}");
    assert_mentions(
        log,
        &[
            "restored states.door: fremen:2 with",
            "from the journal), the last at",
            "restored maps.office:",
            "records replayed; learning goes on at position",
        ],
    );
    assert!(!log.contains("not learned again"), "{log}");

    // The door and the level: the acknowledged states, then a prefix of those in flight, then
    // the rest, each once and at the clock sent before it, the first two from the journal.
    let summary: Value = serde_json::from_str(restarted["stdout"].as_str().unwrap()).unwrap();
    let held_states = |name: &str, sent: &[(i64, f64)]| -> (Vec<(f64, f64)>, usize) {
        let record = read_pairs(dir.join(format!("saved/states/{name}.txt"))).unwrap();
        let survived = record.times.len() as i64 - (ACKNOWLEDGED + AFTER) as i64;
        assert!(
            (0..=IN_FLIGHT as i64).contains(&survived),
            "{name}: {} observations recorded",
            record.times.len()
        );
        let survived = survived as usize;
        let expected: Vec<(f64, f64)> = sent[..ACKNOWLEDGED + survived]
            .iter()
            .chain(&sent[killed_at..])
            .map(|&(t, v)| (t as f64, v))
            .collect();
        let recorded: Vec<(f64, f64)> = record.times.into_iter().zip(record.values).collect();
        let first_difference = recorded.iter().zip(&expected).position(|(a, b)| a != b);
        assert_eq!(first_difference, None, "{name}: recorded vs sent");
        assert_mentions(
            log,
            &[&format!(
                "restored states.{name}: fremen:2 with {n} observations (0 saved, {n} from the \
                 journal)",
                n = ACKNOWLEDGED + survived
            )],
        );
        let states = summary["states"].as_array().unwrap();
        let state = states.iter().find(|s| s["name"] == name).unwrap();
        assert_eq!(state["total"], recorded.len(), "{summary}");
        (recorded, survived)
    };
    let (_, survived) = held_states("door", &door);
    let (level_held, level_survived) = held_states("level", &levels);

    // The restarted node predicts what `chronomap fit` + `predict` of those observations do.
    assert_eq!(restarted["final"]["clock"].as_i64().unwrap(), last);
    let (p, h) = fit_and_predict(&dir, "saved/states/door.txt", "fremen:2", &[target])[0];
    let published = &restarted["final"];
    assert_eq!(
        published["probability"].as_f64().unwrap().to_bits(),
        p.to_bits()
    );
    assert_eq!(
        published["entropy"].as_f64().unwrap().to_bits(),
        h.to_bits()
    );

    // The level's interval survived the kill: its stamped prediction (of as many observations
    // as it says it had learned) and ~/predict (of all it holds) carry the Beta law's interval
    // of `chronomap fit` of its values and of their squares, bit for bit; and the learners the
    // restarted node saved at SIGINT (the squares' too) predict the same moments.
    let stamped = &published["level"];
    assert_eq!(stamped["stamp"], json!([target, 0]), "{stamped}");
    assert_eq!(stamped["made"], json!([last, 0]), "{stamped}");
    assert_eq!(
        (stamped["name"].as_str(), stamped["model"].as_str()),
        (Some("level"), Some("fremen:2"))
    );
    let n = stamped["observations"].as_u64().unwrap() as usize;
    assert!(
        n <= level_held.len() && n + 5 >= level_held.len(),
        "{n} of {}",
        level_held.len()
    );
    let (m, s) = fitted_moments(&dir, "level", &level_held[..n], "fremen:2", &[target])[0];
    let (lo, hi) = beta_interval(m, s, COVERAGE);
    let bits = |v: &Value| v.as_f64().unwrap().to_bits();
    assert_eq!(bits(&stamped["probability"]), m.to_bits());
    assert_eq!(bits(&stamped["lower"]), lo.to_bits());
    assert_eq!(bits(&stamped["upper"]), hi.to_bits());
    assert_eq!(bits(&stamped["coverage"]), COVERAGE.to_bits());
    assert!(0.0 < lo && lo < m && m < hi && hi < 1.0, "{lo} {m} {hi}");
    let answer = &published["predict"];
    assert_eq!(
        (answer["success"].as_bool(), answer["model"].as_str()),
        (Some(true), Some("fremen:2")),
        "{answer}"
    );
    assert_eq!(bits(&answer["coverage"]), COVERAGE.to_bits());
    let (p, lower, upper) = (
        floats(&answer["probability"]),
        floats(&answer["lower"]),
        floats(&answer["upper"]),
    );
    assert_eq!([p.len(), lower.len(), upper.len()], [times.len(); 3]);
    let moments = fitted_moments(&dir, "level", &level_held, "fremen:2", &times);
    for (i, &(m, s)) in moments.iter().enumerate() {
        let (lo, hi) = beta_interval(m, s, COVERAGE);
        let at = times[i];
        assert_eq!(p[i].to_bits(), m.to_bits(), "level p at {at}");
        assert_eq!(lower[i].to_bits(), lo.to_bits(), "level lower at {at}");
        assert_eq!(upper[i].to_bits(), hi.to_bits(), "level upper at {at}");
    }
    assert!(
        lower
            .iter()
            .zip(&upper)
            .any(|(l, u)| u - l != upper[0] - lower[0]),
        "{lower:?} {upper:?}"
    );
    let states = dir.join("saved/states");
    let (m, s) = moments[0];
    assert_eq!(
        predict(&states.join("level.cmm"), target).0.to_bits(),
        m.to_bits()
    );
    assert_eq!(
        predict(&states.join("level.squares.cmm"), target)
            .0
            .to_bits(),
        s.to_bits()
    );

    // The office: the acknowledged frames, a prefix of those in flight, the rest.
    let frames_in =
        |range: std::ops::Range<usize>| map_steps.iter().filter(|s| range.contains(s)).count();
    let (acked, flying, after) = (
        frames_in(0..ACKNOWLEDGED),
        frames_in(ACKNOWLEDGED..killed_at),
        frames_in(killed_at..total),
    );
    let held = summary["grids"][0]["total"].as_u64().unwrap() as usize;
    assert!(
        (acked + after..=acked + flying + after).contains(&held),
        "{held} frames held; {acked} acknowledged, {flying} in flight, {after} after: {summary}"
    );
    let kept: Vec<usize> = (0..acked + (held - acked - after))
        .chain(acked + flying..acked + flying + after)
        .collect();
    let list: String = kept
        .iter()
        .map(|&k| format!("{} frame{k}.yaml\n", frames[k]["time"]))
        .collect();
    write(&dir, "frames.txt", &list);
    stdout(&chronomap(&[
        "grid",
        "build",
        "--frames",
        &path("frames.txt"),
        "-o",
        &path("built.cmg"),
    ]));
    for (key, mode) in [("map", "trinary"), ("mask", "scale")] {
        let expected = grid_predict(&dir.join("built.cmg"), target, mode, &dir.join(key));
        assert_eq!(cells(&published[key]["data"]), expected.data, "{mode}");
    }
    println!(
        "ros2_crash: {survived} of {IN_FLIGHT} door states and {level_survived} levels in flight \
         survived the kill, {} of {flying} frames; took {:.1} s",
        held - acked - after,
        started.elapsed().as_secs_f64()
    );
}

/// The level at step `i`, time `t`: sixteenths (exact in binary and in text) in [0, 1], rising
/// over the day in steps of three hours, with a wobble of the step.
fn level(i: usize, t: i64) -> f64 {
    (t % 86400 / 10800) as f64 / 8.0 + (i % 3) as f64 / 16.0
}
