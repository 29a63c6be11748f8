//! The real bag of `data/malaga_laser_2006` (rosbag2 v9, MCAP, written by the `rosbags`
//! package): every scan and odometry message is read and equals the text files of the same
//! loop, and damaged copies of the bag fail with errors that name the record.

use std::io::{BufRead, BufReader};

use chronomap_core::progress::NoProgress;
use chronomap_io::open_data_file;
use chronomap_rosbag::{Bag, DefinitionSource, TimeSource};
use chronomap_testutil::{data_path, scratch};

const BAG: &str = "malaga_laser_2006/rosbag2/malaga_2006_bag";

/// Non-comment lines of a bundled text file, split into fields.
fn rows(file: &str) -> Vec<Vec<String>> {
    let reader = BufReader::new(open_data_file(data_path(file)).unwrap());
    reader
        .lines()
        .map(Result::unwrap)
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| l.split_whitespace().map(str::to_string).collect())
        .collect()
}

#[test]
fn the_summary_lists_both_topics_with_their_counts() {
    let bag = Bag::open(data_path(BAG)).unwrap();
    assert_eq!(bag.metadata().unwrap().message_count, 449);
    let summary = bag.summary(&NoProgress).unwrap();
    assert_eq!(summary.messages, 449);
    let topics: Vec<(&str, &str, u64)> = summary
        .topics
        .iter()
        .map(|t| (t.name.as_str(), t.type_name.as_str(), t.count))
        .collect();
    assert_eq!(
        topics,
        [
            ("/scan", "sensor_msgs/msg/LaserScan", 225),
            ("/odom", "nav_msgs/msg/Odometry", 224)
        ]
    );
    assert!(
        summary
            .topics
            .iter()
            .all(|t| t.definition == DefinitionSource::Bag)
    );
    // 59 s from the first to the last message, as metadata.yaml says (59.074944896 s).
    let first = summary
        .topics
        .iter()
        .map(|t| t.first)
        .fold(f64::MAX, f64::min);
    let last = summary
        .topics
        .iter()
        .map(|t| t.last)
        .fold(f64::MIN, f64::max);
    assert!(
        (last - first - 59.074_944_896).abs() < 1e-6,
        "{}",
        last - first
    );
}

#[test]
fn scans_equal_the_text_log_beam_for_beam() {
    let bag = Bag::open(data_path(BAG)).unwrap();
    let scans = bag
        .read_scans("/scan", TimeSource::Auto, &NoProgress)
        .unwrap();
    let text = rows("malaga_laser_2006/scans.txt.xz");
    assert_eq!((scans.len(), text.len()), (225, 225));
    let mut no_returns = 0;
    for (scan, row) in scans.iter().zip(&text) {
        let t: f64 = row[0].parse().unwrap();
        assert!((scan.time - t).abs() < 1e-6, "{} vs {t}", scan.time);
        assert_eq!(scan.frame_id, "laser");
        let aperture: f32 = row[1].parse().unwrap();
        assert_eq!(scan.angle_min, -aperture / 2.0);
        assert_eq!(scan.angle_max, aperture / 2.0);
        let n: usize = row[8].parse().unwrap();
        assert_eq!(scan.ranges.len(), n);
        for k in 0..n {
            let range: f32 = row[9 + k].parse().unwrap();
            let valid = row[9 + n + k] == "1";
            if valid {
                assert_eq!(scan.ranges[k], range, "scan at {t}, beam {k}");
            } else {
                assert_eq!(scan.ranges[k], f32::INFINITY, "scan at {t}, beam {k}");
                no_returns += 1;
            }
        }
    }
    assert!(no_returns > 1000, "{no_returns}");
}

#[test]
fn odometry_is_the_composed_increments_of_the_text_log() {
    let bag = Bag::open(data_path(BAG)).unwrap();
    let odometry = bag
        .read_odometry("/odom", TimeSource::Auto, &NoProgress)
        .unwrap();
    let text = rows("malaga_laser_2006/odometry.txt.xz");
    assert_eq!((odometry.len(), text.len()), (224, 224));
    let (mut x, mut y, mut yaw) = (0.0f64, 0.0f64, 0.0f64);
    for (pose, row) in odometry.iter().zip(&text) {
        let v: Vec<f64> = row.iter().map(|f| f.parse().unwrap()).collect();
        x += v[1] * yaw.cos() - v[2] * yaw.sin();
        y += v[1] * yaw.sin() + v[2] * yaw.cos();
        yaw += v[3];
        assert!((pose.time - v[0]).abs() < 1e-6);
        assert_eq!(
            (pose.frame_id.as_str(), pose.child_frame_id.as_str()),
            ("odom", "base_link")
        );
        assert!(
            (pose.position[0] - x).abs() < 1e-6,
            "{} vs {x}",
            pose.position[0]
        );
        assert!(
            (pose.position[1] - y).abs() < 1e-6,
            "{} vs {y}",
            pose.position[1]
        );
        let dyaw = (pose.yaw - yaw).sin().abs();
        assert!(dyaw < 1e-6, "{} vs {yaw}", pose.yaw);
    }
    // The loop is about 77 m long.
    let length: f64 = odometry
        .windows(2)
        .map(|w| (w[1].position[0] - w[0].position[0]).hypot(w[1].position[1] - w[0].position[1]))
        .sum();
    assert!((70.0..85.0).contains(&length), "{length}");
}

#[test]
fn a_topic_of_another_kind_or_absent_is_a_clear_error() {
    let bag = Bag::open(data_path(BAG)).unwrap();
    let err = bag
        .read_states("/scan", TimeSource::Auto, &NoProgress)
        .unwrap_err()
        .to_string();
    assert!(
        err.ends_with("topic /scan: its messages are sensor_msgs/msg/LaserScan, not state (std_msgs/msg/Bool, Float32 or Float64)"),
        "{err}"
    );
    let err = bag
        .read_scans("/door", TimeSource::Auto, &NoProgress)
        .unwrap_err()
        .to_string();
    assert!(
        err.ends_with(
            "no message on topic /door: the bag has /odom (nav_msgs/msg/Odometry), /scan (sensor_msgs/msg/LaserScan)"
        ),
        "{err}"
    );
    // The scans have a header: asking for it works, asking for log times too.
    let logged = bag
        .read_scans("/scan", TimeSource::Log, &NoProgress)
        .unwrap();
    assert_eq!(logged.len(), 225);
}

#[test]
fn truncated_and_damaged_bags_name_the_record() {
    let dir = scratch!("rosbag_damaged");
    let mcap = std::fs::read(data_path(&format!("{BAG}/malaga_2006_bag.mcap"))).unwrap();

    // Cut in the middle: the bag's one chunk (all 449 messages) runs past the end, which is
    // found from its declared length before anything of it is read or decoded.
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &mcap[..mcap.len() / 2]).unwrap();
    let err = Bag::open(&cut)
        .unwrap()
        .summary(&NoProgress)
        .unwrap_err()
        .to_string();
    assert_eq!(mcap.len() / 2, 263_823);
    assert!(
        err.ends_with(
            "cut.mcap: the record before the first message, read up to byte 43: the chunk \
             record at byte 43 declares 516751 bytes, but only 263771 remain in the file: it is \
             truncated or damaged"
        ),
        "{err}"
    );

    // One byte changed inside the data section: a CRC or a record fails, never a panic.
    let mut flips = 0;
    for at in (200..mcap.len() - 200).step_by(mcap.len() / 37) {
        let mut bad = mcap.clone();
        bad[at] ^= 0x5a;
        let path = dir.join(format!("flip_{at}.mcap"));
        std::fs::write(&path, &bad).unwrap();
        let bag = Bag::open(&path).unwrap();
        if let Err(e) = bag.summary(&NoProgress).and_then(|_| {
            bag.read_scans("/scan", TimeSource::Log, &NoProgress)
                .map(|_| ())
        }) {
            flips += 1;
            let e = e.to_string();
            assert!(e.starts_with(&path.display().to_string()), "{e}");
        }
    }
    assert!(flips > 0);

    // Not an MCAP file at all, and not a regular file.
    let text = dir.join("notes.mcap");
    std::fs::write(&text, "hello, this is not a bag\n").unwrap();
    let err = Bag::open(&text)
        .unwrap()
        .summary(&NoProgress)
        .unwrap_err()
        .to_string();
    assert!(err.contains("not an MCAP file"), "{err}");
    #[cfg(unix)]
    {
        let err = Bag::open("/dev/zero").unwrap_err().to_string();
        assert!(err.contains("not a regular file or folder"), "{err}");
    }
    let err = Bag::open(dir.join("missing")).unwrap_err().to_string();
    assert!(err.ends_with("missing: no such file or folder"), "{err}");
}

#[test]
fn foreign_files_and_unknown_compression_are_refused_with_advice() {
    let dir = scratch!("rosbag_metadata");
    // An empty file is an empty SQLite database: no rosbag2 tables.
    std::fs::write(dir.join("bag_0.db3"), "").unwrap();
    let err = Bag::open(dir.join("bag_0.db3"))
        .unwrap()
        .summary(&NoProgress)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(
            "bag_0.db3: the table `topics`: not a rosbag2 SQLite bag: no such table: topics"
        ),
        "{err}"
    );
    // Text that is not SQLite at all.
    std::fs::write(dir.join("notes.db3"), "a rosbag2 bag? no.".repeat(100)).unwrap();
    let err = Bag::open(dir.join("notes.db3"))
        .unwrap()
        .summary(&NoProgress)
        .unwrap_err()
        .to_string();
    assert!(err.contains("notes.db3: not an SQLite database"), "{err}");
    std::fs::write(
        dir.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n  relative_file_paths: [bag_0.db3]\n",
    )
    .unwrap();
    let err = Bag::open(&dir)
        .unwrap()
        .summary(&NoProgress)
        .unwrap_err()
        .to_string();
    assert!(err.contains("no such table: topics"), "{err}");
    std::fs::write(
        dir.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n  compression_format: lz4\n  compression_mode: FILE\n  relative_file_paths: [a.mcap]\n",
    )
    .unwrap();
    let err = Bag::open(&dir).unwrap_err().to_string();
    assert!(
        err.contains("compression `lz4` in mode `file` is not supported"),
        "{err}"
    );
    std::fs::write(dir.join("metadata.yaml"), "[[[[[[").unwrap();
    let err = Bag::open(&dir).unwrap_err().to_string();
    assert!(err.contains("metadata.yaml: not rosbag2 metadata"), "{err}");
}
