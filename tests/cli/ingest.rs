//! `chronomap ingest` and `grid build --bag`: ROS 2 bags written by others give the same models,
//! grids and files as the text inputs they were written from.
//!
//! The bags are written by the PyPI `rosbags` package (real ROS 2 message definitions, no ROS
//! installation) and the CDR bytes by rclpy's `serialize_message`, through
//! `tests/oracle/ros2_bags.py`, when `CHRONOMAP_ROS_PYTHON` names a Python with `rosbags` and
//! rclpy (`.ci/run` sets it up); without it those comparisons are skipped with a message,
//! unless `CHRONOMAP_REQUIRE_ROS=1`. The real bag of `data/malaga_laser_2006` needs nothing.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};

use chronomap_io::navmap::{LoadSemantics, SaveOptions, load_map, save_map};
use chronomap_io::tracks::read_track_points;
use chronomap_io::{Field, read_column, read_events};
use chronomap_rosbag::cdr::{Value, decode};
use chronomap_rosbag::{builtin, time::stamp_seconds};
use chronomap_spatial::OccupancyMap;
use serde_json::json;

use crate::common::{
    assert_mentions, chronomap, data, error, json, oracle_python, run_oracle, scratch, stdout,
    usage_error,
};

const ENABLE: &str = "set CHRONOMAP_ROS_PYTHON to a Python with rosbags==0.11.9 and \
                      ros-kilted-rclpy (.ci/run makes target/ros-venv)";

/// The Python that writes bags, if there is one.
fn ros_python(test: &str) -> Option<String> {
    oracle_python("ROS", test, "rosbags/rclpy", ENABLE)
}

/// Runs `tests/oracle/ros2_bags.py MODE ARGS...`.
fn write_bag(python: &str, mode: &str, args: &[&Path], extra: &[&str]) -> serde_json::Value {
    let mut all: Vec<&OsStr> = vec![OsStr::new(mode)];
    all.extend(args.iter().map(|p| p.as_os_str()));
    all.extend(extra.iter().map(OsStr::new));
    run_oracle(
        python,
        "CHRONOMAP_ROS_PYTHON",
        "ros2_bags.py",
        &all,
        &format!("rosbags {mode}"),
    )
}

fn arg(p: &Path) -> String {
    p.display().to_string()
}

#[test]
fn greg_door_bags_fit_the_same_model_bit_for_bit() {
    let Some(python) = ros_python("greg_door_bags") else {
        return;
    };
    let dir = scratch("ingest_greg");
    let train = PathBuf::from(data("door_greg_2016/training_data.txt.xz"));
    let at = "1458565200,1458568800,1459000000"; // the week after, and later
    for spec in [
        "fremen:0",
        "fremen:2",
        "fremen:4",
        "fremen:auto",
        "hist:24",
        "auto",
    ] {
        let reference = dir.join(format!("text_{spec}.cmm"));
        stdout(&chronomap(&[
            "fit",
            "--train",
            &arg(&train),
            "--model",
            spec,
            "-o",
            &arg(&reference),
        ]));
        // Bool as rosbag2 records it by default (zstd chunks), and the other compressions.
        let cases: &[(&str, &str)] = if spec == "fremen:2" {
            &[
                ("std_msgs/msg/Bool", "none"),
                ("std_msgs/msg/Bool", "storage"),
                ("std_msgs/msg/Bool", "file"),
                ("std_msgs/msg/Bool", "message"),
                ("std_msgs/msg/Bool", "sqlite"),
                ("std_msgs/msg/Bool", "sqlite-humble"),
                ("std_msgs/msg/Float64", "none"),
            ]
        } else {
            &[("std_msgs/msg/Bool", "storage")]
        };
        for (ty, compression) in cases {
            let bag = dir.join(format!(
                "door_{}_{compression}",
                ty.rsplit('/').next().unwrap()
            ));
            if !bag.exists() {
                let written = write_bag(
                    &python,
                    "states",
                    &[&train, &bag],
                    &["/door/open", ty, compression],
                );
                assert_eq!(written["messages"], 96_480);
                // Bags before Iron carry no definitions: the built-in one decodes them.
                let listing = json(&chronomap(&["ingest", &arg(&bag), "--json"]));
                let expected = if *compression == "sqlite-humble" {
                    "built-in"
                } else {
                    "bag"
                };
                assert_eq!(listing["topics"][0]["definition"], expected, "{bag:?}");
            }
            let model = dir.join(format!("bag_{spec}_{compression}.cmm"));
            let out = json(&chronomap(&[
                "ingest",
                &arg(&bag),
                "--topic",
                "/door/open",
                "--model",
                spec,
                "-o",
                &arg(&model),
                "--json",
            ]));
            assert_eq!(out["train"]["observations"], 96_480);
            assert_eq!(out["train"]["topic"], "/door/open");
            assert_eq!(
                std::fs::read(&model).unwrap(),
                std::fs::read(&reference).unwrap(),
                "{spec} from {bag:?}: the model file differs from `chronomap fit`'s"
            );
            let predict = |file: &Path| {
                json(&chronomap(&["predict", &arg(file), "--at", at, "--json"]))["predictions"]
                    .clone()
            };
            assert_eq!(predict(&model), predict(&reference));
        }
    }
}

/// One week of the Brayford office (8 places, 10-minute slots) as 3 × 3 occupancy maps: the
/// places are cells 0..8 (occupied while someone is there), cell 8 is never seen.
fn brayford_maps() -> Vec<(f64, OccupancyMap)> {
    let places: Vec<Vec<f64>> = (0..8)
        .map(|l| {
            read_column(
                data(&format!("brayford_week/presence_{l}.txt.xz")),
                Field::Value,
            )
            .unwrap()
        })
        .collect();
    (0..places[0].len())
        .map(|k| {
            let mut map = OccupancyMap::new(3, 3, 0.5, [-1.25, 4.5, 0.0]);
            for (cell, place) in places.iter().enumerate() {
                map.data[cell] = if place[k] > 0.5 { 100 } else { 0 };
            }
            (1_451_865_600.0 + 600.0 * k as f64, map)
        })
        .collect()
}

#[test]
fn a_bag_of_occupancy_grids_builds_the_grid_of_its_map_files() {
    let Some(python) = ros_python("occupancy_grid_bag") else {
        return;
    };
    let dir = scratch("ingest_maps");
    std::fs::create_dir_all(dir.join("maps")).unwrap();
    let mut list = String::new();
    let mut frames = Vec::new();
    for (k, (t, map)) in brayford_maps().iter().enumerate() {
        let base = dir.join(format!("maps/slot_{k:04}"));
        save_map(&base, map, &SaveOptions::default()).unwrap();
        list.push_str(&format!("{t} maps/slot_{k:04}.yaml\n"));
        // What map_server would publish for that file: the map as Nav2 loads it.
        let loaded = load_map(&base.with_extension("yaml"), LoadSemantics::Nav2).unwrap();
        frames.push(json!({ "time": t, "data": loaded.data }));
    }
    std::fs::write(dir.join("frames.txt"), list).unwrap();
    let spec = json!({
        "width": 3, "height": 3, "resolution": 0.5, "origin": [-1.25, 4.5, 0.0],
        "frame_id": "map", "frames": frames,
    });
    std::fs::write(dir.join("frames.json"), spec.to_string()).unwrap();
    let bag = dir.join("maps_bag");
    let written = write_bag(
        &python,
        "maps",
        &[&dir.join("frames.json"), &bag],
        &["/chronomap/test_map"],
    );
    assert_eq!(written["messages"], 1008);

    for extra in [
        &["--order", "2"][..],
        &["--order", "auto", "--store", "lossless", "--errors"],
    ] {
        let from_files = dir.join("files.cmg");
        let from_bag = dir.join("bag.cmg");
        let files_out = json(&chronomap(
            &[
                &[
                    "grid",
                    "build",
                    "--frames",
                    &arg(&dir.join("frames.txt")),
                    "-o",
                    &arg(&from_files),
                    "--json",
                ][..],
                extra,
            ]
            .concat(),
        ));
        let bag_out = json(&chronomap(
            &[
                &[
                    "grid",
                    "build",
                    "--bag",
                    &arg(&bag),
                    "--topic",
                    "/chronomap/test_map",
                    "-o",
                    &arg(&from_bag),
                    "--json",
                ][..],
                extra,
            ]
            .concat(),
        ));
        assert_eq!(
            std::fs::read(&from_bag).unwrap(),
            std::fs::read(&from_files).unwrap(),
            "{extra:?}"
        );
        assert_eq!(bag_out["frames"], 1008);
        assert_eq!(bag_out["errors"], files_out["errors"], "{extra:?}");
    }
    // `ingest` of a map topic is `grid build --bag` with its defaults.
    let ingested = dir.join("ingested.cmg");
    stdout(&chronomap(&[
        "ingest",
        &arg(&bag),
        "--topic",
        "/chronomap/test_map",
        "-o",
        &arg(&ingested),
    ]));
    stdout(&chronomap(&[
        "grid",
        "build",
        "--frames",
        &arg(&dir.join("frames.txt")),
        "-o",
        &arg(&dir.join("files.cmg")),
    ]));
    assert_eq!(
        std::fs::read(&ingested).unwrap(),
        std::fs::read(dir.join("files.cmg")).unwrap()
    );
}

#[test]
fn people_bags_give_back_the_events_and_tracks_they_were_written_from() {
    let Some(python) = ros_python("people_bags") else {
        return;
    };
    let dir = scratch("ingest_people");
    // PoseArray of the Lincoln corridor detections: `t x y` events, exactly.
    let events = PathBuf::from(data("lincoln_pedestrians_2017/raw_days/2017_05_26.txt.xz"));
    let bag = dir.join("poses_bag");
    let written = write_bag(&python, "people", &[&events, &bag], &["/people"]);
    assert_eq!(written["detections"], 22_449);
    let out = dir.join("events.txt");
    let report = json(&chronomap(&[
        "ingest",
        &arg(&bag),
        "--topic",
        "/people",
        "-o",
        &arg(&out),
        "--json",
    ]));
    assert_eq!(report["read"]["detections"], 22_449);
    assert_eq!(report["messages"], written["messages"]);
    assert_eq!(read_events(&out).unwrap(), read_events(&events).unwrap());
    let err = usage_error(&chronomap(&[
        "ingest",
        &arg(&bag),
        "--topic",
        "/people",
        "--people",
        "tracks",
        "-o",
        &arg(&dir.join("x.csv")),
    ]));
    assert_mentions(&err, &["poses without identities", "write events instead"]);

    // people_msgs/People (a type the bag defines) of the ATC tracks: the same detections and ids.
    let tracks = PathBuf::from(data("atc_20121024_1hz/atc-1024-10_train.csv.xz"));
    let bag = dir.join("people_bag");
    write_bag(&python, "tracks", &[&tracks, &bag], &["/people"]);
    let listing = stdout(&chronomap(&["ingest", &arg(&bag)]));
    assert_mentions(
        &listing,
        &[
            "/people",
            "people_msgs/msg/People",
            "4817",
            "events or tracks",
        ],
    );
    let out = dir.join("tracks.csv");
    stdout(&chronomap(&[
        "ingest",
        &arg(&bag),
        "--topic",
        "/people",
        "--people",
        "tracks",
        "-o",
        &arg(&out),
    ]));
    assert_eq!(
        read_track_points(&out).unwrap(),
        read_track_points(&tracks).unwrap()
    );
}

#[test]
fn cdr_written_by_rclpy_decodes_with_the_built_in_definitions() {
    let Some(python) = ros_python("rclpy_cdr") else {
        return;
    };
    let dir = scratch("ingest_cdr");
    let out = dir.join("cdr.json");
    write_bag(&python, "cdr", &[&out], &[]);
    let messages: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let bytes = |name: &str| -> Vec<u8> {
        let hex = messages[name].as_str().unwrap();
        (0..hex.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap())
            .collect()
    };
    let check = |name: &str, f: &dyn Fn(&Value<'_>)| {
        let schema = builtin::schema(name).unwrap();
        let data = bytes(name);
        f(&decode(&schema, &data).unwrap_or_else(|e| panic!("{name}: {e}")));
    };
    let num = |v: &Value<'_>, path: &str| {
        v.path(path)
            .and_then(Value::as_f64)
            .unwrap_or_else(|| panic!("{path}"))
    };
    check("std_msgs/msg/Bool", &|v| {
        assert_eq!(v.get("data"), Some(&Value::Bool(true)))
    });
    check("std_msgs/msg/Float64", &|v| {
        assert_eq!(num(v, "data"), 0.25)
    });
    check("nav_msgs/msg/OccupancyGrid", &|v| {
        let sec = v.path("header.stamp.sec").and_then(Value::as_i64).unwrap();
        let ns = v
            .path("header.stamp.nanosec")
            .and_then(Value::as_i64)
            .unwrap();
        assert_eq!(stamp_seconds(sec, ns as u64), Some(1_451_865_600.5));
        assert_eq!(v.path("header.frame_id").unwrap().as_str(), Some("map"));
        assert_eq!((num(v, "info.width"), num(v, "info.height")), (3.0, 2.0));
        assert_eq!(num(v, "info.resolution") as f32, 0.05f32);
        assert_eq!(
            (
                num(v, "info.origin.position.x"),
                num(v, "info.origin.position.y")
            ),
            (-1.5, 2.25)
        );
        let data: Vec<i8> = v
            .get("data")
            .unwrap()
            .as_bytes()
            .unwrap()
            .iter()
            .map(|&b| b as i8)
            .collect();
        assert_eq!(data, [0, 100, -1, 50, 0, 100]);
    });
    check("geometry_msgs/msg/PoseArray", &|v| {
        let poses = v.get("poses").unwrap().as_array().unwrap();
        assert_eq!(poses.len(), 2);
        assert_eq!(
            (num(&poses[0], "position.x"), num(&poses[0], "position.y")),
            (16.4862, -1.0019)
        );
        assert_eq!(num(&poses[1], "orientation.w"), 1.0);
    });
    check("sensor_msgs/msg/LaserScan", &|v| {
        let ranges: Vec<f64> = v
            .get("ranges")
            .unwrap()
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r.as_f64().unwrap())
            .collect();
        assert_eq!(ranges, [f64::from(1.69f32), f64::INFINITY, 2.5]);
        assert_eq!(num(v, "range_max"), 80.0);
        assert_eq!(v.path("header.frame_id").unwrap().as_str(), Some("laser"));
    });
    check("nav_msgs/msg/Odometry", &|v| {
        assert_eq!(v.get("child_frame_id").unwrap().as_str(), Some("base_link"));
        assert_eq!(num(v, "pose.pose.position.y"), -21.2);
        assert_eq!(num(v, "twist.twist.angular.z"), -0.1);
        assert_eq!(num(v, "pose.pose.orientation.w"), 0.5f64.cos());
    });
}

#[test]
fn the_malaga_bag_lists_and_exports_its_scans_and_odometry() {
    let dir = scratch("ingest_malaga");
    let bag = data("malaga_laser_2006/rosbag2/malaga_2006_bag");
    let listing = json(&chronomap(&["ingest", &bag, "--json"]));
    assert_eq!(listing["messages"], 449);
    let topics: Vec<(String, String, u64)> = listing["topics"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                t["topic"].as_str().unwrap().into(),
                t["kind"].as_str().unwrap().into(),
                t["messages"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        topics,
        [
            ("/scan".into(), "scan".into(), 225),
            ("/odom".into(), "odometry".into(), 224)
        ]
    );

    let scans = dir.join("scans.txt");
    let out = json(&chronomap(&[
        "ingest",
        &bag,
        "--topic",
        "/scan",
        "-o",
        &arg(&scans),
        "--json",
    ]));
    assert_eq!(
        (out["read"]["scans"].as_u64(), out["read"]["beams"].as_u64()),
        (Some(225), Some(361))
    );
    let text = std::fs::read_to_string(&scans).unwrap();
    let first: Vec<&str> = text.lines().nth(1).unwrap().split(' ').collect();
    assert_eq!(first.len(), 6 + 361);
    assert_eq!(
        first[..6],
        [
            "1137834225.713386",
            "-1.5707964",
            "0.008726646",
            "0",
            "80",
            "361"
        ][..]
    );
    assert_eq!(first[6..9], ["1.69", "1.66", "1.66"]);
    assert_eq!(text.lines().count(), 1 + 225);

    let poses = dir.join("poses.txt");
    stdout(&chronomap(&[
        "ingest",
        &bag,
        "--topic",
        "/odom",
        "-o",
        &arg(&poses),
    ]));
    assert_eq!(
        std::fs::read_to_string(&poses).unwrap().lines().count(),
        1 + 224
    );

    // Usage errors: no output, a model for a topic that carries no states, no such topic.
    let err = usage_error(&chronomap(&["ingest", &bag, "--topic", "/scan"]));
    assert_mentions(&err, &["-o/--output", "sensor_msgs/msg/LaserScan"]);
    let err = usage_error(&chronomap(&[
        "ingest", &bag, "--topic", "/scan", "--model", "fremen:2", "-o", "x",
    ]));
    assert_mentions(&err, &["--model", "not states"]);
    let err = error(&chronomap(&["ingest", &bag, "--topic", "/door", "-o", "x"]));
    assert_mentions(&err, &["there is no topic /door"]);
    let err = error(&chronomap(&[
        "grid",
        "build",
        "--bag",
        &bag,
        "--topic",
        "/scan",
        "-o",
        &arg(&dir.join("g.cmg")),
    ]));
    assert_mentions(
        &err,
        &["its messages are sensor_msgs/msg/LaserScan, not map"],
    );
}

#[test]
fn truncated_and_foreign_bags_fail_naming_the_file_and_record() {
    let dir = scratch("ingest_bad");
    let mcap = std::fs::read(data(
        "malaga_laser_2006/rosbag2/malaga_2006_bag/malaga_2006_bag.mcap",
    ))
    .unwrap();
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &mcap[..mcap.len() * 2 / 3]).unwrap();
    // The bag's one chunk holds all 449 messages: its declared length runs past the cut, which
    // is refused before anything of it is read.
    assert_eq!(mcap.len() * 2 / 3, 351_764);
    let err = error(&chronomap(&["ingest", &arg(&cut)]));
    assert_mentions(
        &err,
        &[
            "cut.mcap: the record before the first message, read up to byte 43: the chunk \
             record at byte 43 declares 516751 bytes, but only 351712 remain in the file: it is \
             truncated or damaged",
        ],
    );
    let err = error(&chronomap(&[
        "ingest",
        &arg(&cut),
        "--topic",
        "/scan",
        "-o",
        &arg(&dir.join("s.txt")),
    ]));
    assert_mentions(&err, &["cut.mcap", "truncated"]);
    assert!(
        !dir.join("s.txt").exists(),
        "nothing is written when the bag is damaged"
    );
    let err = error(&chronomap(&["ingest", "/dev/zero"]));
    assert_mentions(&err, &["/dev/zero", "not a regular file or folder"]);
    let notes = dir.join("notes.mcap");
    std::fs::write(&notes, "not a bag").unwrap();
    let err = error(&chronomap(&["ingest", &arg(&notes)]));
    assert_mentions(&err, &["notes.mcap", "not an MCAP file"]);
}
