use std::path::Path;
use std::time::Instant;

use chronomap_core::TemporalModel;
use chronomap_grid::{CellState, OrderChoice};
use chronomap_io::navmap::{load_map, save_map};
use chronomap_io::read_pairs;
use chronomap_models::spec::FitOptions;

use chronomap_grid::AnyGrid;

use super::store::next_name;
use super::*;
use crate::msgs::Time;

/// A scratch folder for one test, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!(
            "chronomap-ros2-world-{test}-{}",
            std::process::id()
        ));
        Scratch(chronomap_testutil::fresh_dir(dir))
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn config(dir: &Path, params: &str) -> NodeConfig {
    let text = format!("chronomap:\n  ros__parameters:\n{params}");
    NodeConfig::parse(&dir.join("node.yaml"), text.as_bytes(), None).unwrap()
}

const DOOR: &str =
    "    states:\n      door: {topic: /door, type: std_msgs/msg/Bool, model: fremen:2}\n";

fn map_message(stamp: i32, frame: &str, width: u32, height: u32, data: Vec<i8>) -> OccupancyGrid {
    OccupancyGrid {
        header: Header {
            stamp: Time {
                sec: stamp,
                nanosec: 0,
            },
            frame_id: frame.into(),
        },
        info: MapMetaData {
            map_load_time: Time::default(),
            resolution: 0.25,
            width,
            height,
            origin: Pose {
                position: Point {
                    x: -1.0,
                    y: 0.5,
                    z: 0.0,
                },
                orientation: Quaternion::default(),
            },
        },
        data,
    }
}

/// A 6 x 4 map at hour `h`: a door (cell 9) closed at night, a wall, a cell that fades, one
/// never seen.
fn office_frame(h: i32) -> Vec<i8> {
    let mut data = vec![0i8; 24];
    data[0] = 100;
    data[9] = if (8..18).contains(&(h % 24)) { 0 } else { 100 };
    data[14] = (h % 5 * 20) as i8;
    data[23] = -1;
    data
}

#[test]
fn a_state_learned_message_by_message_is_the_model_fit_makes() {
    let dir = Scratch::new("state");
    let params = format!("    save_dir: saved\n    record_observations: true\n{DOOR}");
    let mut world = World::new(config(&dir.0, &params)).unwrap();
    let door = read_pairs(chronomap_testutil::data_path(
        "door_greg_2016/training_data.txt.xz",
    ))
    .unwrap();
    let n = 3000;
    for (&t, &v) in door.times[..n].iter().zip(&door.values[..n]) {
        world.observe_state(0, t, v).unwrap();
    }
    let fitted = "fremen:2"
        .parse::<chronomap_models::ModelSpec>()
        .unwrap()
        .fit(&door.times[..n], &door.values[..n], &FitOptions::default())
        .unwrap()
        .model;
    for t in [door.times[n], door.times[n] + 3600.0, 1_458_565_200.0] {
        let (p, h) = world.predict_state(0, t);
        assert_eq!(p.to_bits(), fitted.predict(t).to_bits(), "{t}");
        assert_eq!(h.to_bits(), fitted.entropy(t).to_bits(), "{t}");
    }
    // Refused: out of range, NaN, earlier than the last observation; nothing changes.
    let last = door.times[n - 1];
    for (t, v, part) in [
        (last + 1.0, 1.5, "value 1.5 is not in [0, 1]"),
        (last + 1.0, f64::NAN, "value NaN is not in [0, 1]"),
        (last - 1.0, 1.0, "is earlier than the previous observation"),
    ] {
        let e = world.observe_state(0, t, v).unwrap_err().to_string();
        assert!(e.contains(part), "{e}");
    }
    assert_eq!(world.learned().0[0].observations, n as u64);
    // Saved and restored: the same model; the record holds what was learned.
    world.save(true).unwrap();
    let restored = World::new(config(&dir.0, &params)).unwrap();
    let t = 1_458_565_200.0;
    assert_eq!(
        restored.predict_state(0, t).0.to_bits(),
        world.predict_state(0, t).0.to_bits()
    );
    assert_eq!(restored.learned().0[0].total, n as u64);
    let record = read_pairs(dir.0.join("saved/states/door.txt")).unwrap();
    assert_eq!(record.times, door.times[..n]);
    assert_eq!(record.values, door.values[..n]);
    // A saved model of another spec is not silently replaced.
    let other = "    save_dir: saved\n    states:\n      door: {topic: /door, type: std_msgs/msg/Bool, model: fremen:3}\n";
    let e = World::new(config(&dir.0, other)).err().unwrap().to_string();
    assert!(
        e.contains("door.cmm: it holds a `fremen:2` model, but states.door.model is `fremen:3`; move the file away"),
        "{e}"
    );
}

#[test]
fn predicted_maps_are_what_map_server_loads_from_grid_predicts_files() {
    let dir = Scratch::new("maps");
    let params = "    maps:\n      office: {topic: /m, order: 2}\n      raw: {topic: /r, values: probability}\n      scaled: {topic: /s, values: scale}\n";
    let mut world = World::new(config(&dir.0, params)).unwrap();
    assert!(world.predict_grid(0, 0.0, Time::default()).is_none());
    let mut reference = FremenGrid::new(
        GridGeometry::planar(6, 4, 0.25, [-1.0, 0.5]).unwrap(),
        world.config().grids[0].fremen.clone().into_grid(),
    )
    .unwrap();
    for h in 0..24 * 9 {
        let msg = map_message(3600 * h, "map", 6, 4, office_frame(h));
        for index in 0..3 {
            world.observe_map(index, &msg).unwrap();
        }
        reference
            .observe_occupancy(f64::from(3600 * h), &msg.data)
            .unwrap();
    }
    let stamp = Time {
        sec: 123,
        nanosec: 4,
    };
    for hour in [3.0, 12.0, 20.5] {
        let t = 9.0 * 86400.0 + hour * 3600.0;
        let fitted = reference.fitted(
            OrderChoice::Fixed(2),
            chronomap_core::Parallelism::Sequential,
        );
        let map =
            OccupancyMap::from_probabilities(6, 4, 0.25, [-1.0, 0.5, 0.0], &fitted.predict_map(t));
        let raw = world.predict_grid(1, t, stamp).unwrap();
        assert_eq!(raw.map.data, map.data, "probability values at {hour} h");
        assert!(map.data.iter().any(|&v| v > 0 && v < 100), "{:?}", map.data);
        assert_eq!(map.data[23], -1);
        // The files `grid predict` writes, loaded as nav2_map_server loads them.
        for (mode, index) in [(MapMode::Trinary, 0), (MapMode::Scale, 2)] {
            let options = SaveOptions {
                mode,
                free_thresh: FREE_THRESH,
                ..SaveOptions::default()
            };
            let saved = save_map(&dir.0.join(format!("m{index}")), &map, &options).unwrap();
            let loaded = load_map(&saved.yaml, LoadSemantics::Nav2).unwrap();
            let predicted = world.predict_grid(index, t, stamp).unwrap();
            assert_eq!(predicted.map.data, loaded.data, "{mode} at {hour} h");
            let scale = if mode == MapMode::Scale {
                loaded.data.clone()
            } else {
                predicted.mask.as_ref().unwrap().data.clone()
            };
            assert_eq!(predicted.mask.unwrap().data, scale, "mask at {hour} h");
            let m = predicted.map;
            assert_eq!((m.header.stamp, m.header.frame_id.as_str()), (stamp, "map"));
            assert_eq!(
                (m.info.width, m.info.height, m.info.resolution),
                (6, 4, 0.25)
            );
            assert_eq!(
                (m.info.origin.position.x, m.info.origin.position.y),
                (-1.0, 0.5)
            );
        }
    }
    // The trinary map really is trinary and differs from the mask.
    let p = world
        .predict_grid(0, 9.0 * 86400.0 + 3.0 * 3600.0, stamp)
        .unwrap();
    assert!(p.map.data.iter().all(|v| [-1, 0, 100].contains(v)));
    assert_ne!(Some(p.map.data), p.mask.map(|m| m.data));
    let info = world.filter_info(0, stamp).unwrap();
    assert_eq!(info.filter_mask_topic, "/chronomap/office/mask");
    assert_eq!(
        (info.filter_type, info.base, info.multiplier),
        (0, 0.0, 1.0)
    );
}

trait IntoGrid {
    fn into_grid(self) -> GridConfig;
}

impl IntoGrid for chronomap_core::FremenConfig {
    fn into_grid(self) -> GridConfig {
        GridConfig {
            fremen: self,
            keep_history: false,
        }
    }
}

#[test]
fn bad_maps_are_refused_with_reasons_and_change_nothing() {
    let dir = Scratch::new("bad-maps");
    let params = "    max_map_cells: 100\n    maps:\n      office: {topic: /m}\n";
    let mut world = World::new(config(&dir.0, params)).unwrap();
    world
        .observe_map(0, &map_message(100, "map", 6, 4, office_frame(0)))
        .unwrap();
    let mut rotated = map_message(200, "map", 6, 4, office_frame(1));
    rotated.info.origin.orientation.z = 1.0;
    rotated.info.origin.orientation.w = 0.0;
    let mut moved = map_message(200, "map", 6, 4, office_frame(1));
    moved.info.origin.position.x = 3.0;
    let mut bad_value = office_frame(1);
    bad_value[5] = 101;
    let cases = [
        (
            map_message(200, "map", 20, 20, vec![0; 400]),
            "20 x 20 cells is more than max_map_cells (100)",
        ),
        (
            map_message(200, "map", 6, 4, vec![0; 23]),
            "width 6 x height 4 is 24 cells but data holds 23 values",
        ),
        (
            map_message(200, "odom", 6, 4, office_frame(1)),
            "frame_id \"odom\" is not the configured \"map\"",
        ),
        (rotated, "the map's origin is rotated"),
        (
            moved,
            "the map is 6 x 4 cells of 0.25 m at (3, 0.5), but this grid is 6 x 4 cells of 0.25 m at (-1, 0.5)",
        ),
        (
            map_message(5, "map", 6, 3, office_frame(1)[..18].to_vec()),
            "the map is 6 x 3 cells",
        ),
        (
            map_message(100, "map", 6, 4, office_frame(1)),
            "stamp 100 is not after the last learned frame at 100",
        ),
        (
            map_message(200, "map", 6, 4, bad_value),
            "cell 5: occupancy 101 is not -1 (unknown) or 0..=100",
        ),
    ];
    for (msg, part) in cases {
        let e = world.observe_map(0, &msg).unwrap_err().to_string();
        assert!(e.contains(part), "{e}\nexpected {part}");
    }
    assert_eq!(world.grid(0).unwrap().frames(), 1);
    assert_eq!(world.learned().1[0].observations, 1);
}

#[test]
fn people_become_one_frame_per_bin_with_the_cells_someone_was_in() {
    let dir = Scratch::new("people");
    let params = "    save_dir: saved\n    people:\n      lobby: {topic: /p, width: 4, height: 2, resolution: 1.0, origin: [10, 20], bin: 100}\n";
    let mut world = World::new(config(&dir.0, params)).unwrap();
    let people = detections;
    // Bin 1 (100..200): cells 1 and 6; a pose outside the grid is ignored.
    world
        .observe_people(0, &people(110.0, &[(11.5, 20.5)]))
        .unwrap();
    world
        .observe_people(0, &people(190.0, &[(12.2, 21.9), (30.0, 20.0)]))
        .unwrap();
    assert_eq!(world.grid(0).unwrap().frames(), 0);
    // Bin 3 closes bin 1 as a frame at 150; bin 2 saw no message: no frame.
    world.observe_people(0, &people(350.0, &[])).unwrap();
    let grid = world.grid(0).unwrap();
    assert_eq!(grid.frames(), 1);
    assert_eq!(grid.frame_span().last, 150.0);
    let states: Vec<CellState> = (0..8).map(|c| grid.cell_state(c)).collect();
    use CellState::{Free, Occupied};
    assert_eq!(
        states,
        [Free, Occupied, Free, Free, Free, Free, Occupied, Free]
    );
    // Late messages of a closed bin are refused.
    let e = world.observe_people(0, &people(199.0, &[])).unwrap_err();
    assert!(
        e.to_string().contains("not after the last learned bin"),
        "{e}"
    );
    let e = world.observe_people(0, &people(350.0, &[])).map(|_| ());
    assert!(e.is_ok());
    // Bin 3 stays open during bin 4 and closes at 500.
    world.close_stale_bins(499.0).unwrap();
    assert_eq!(world.grid(0).unwrap().frames(), 1);
    world.close_stale_bins(500.0).unwrap();
    let grid = world.grid(0).unwrap();
    assert_eq!((grid.frames(), grid.frame_span().last), (2, 350.0));
    assert_eq!(grid.cell_state(1), Free);
    // The predicted people map: probabilities, -1 nowhere (every cell was observed).
    let p = world.predict_grid(0, 1000.0, Time::default()).unwrap();
    assert!(p.map.data.iter().all(|v| (0..=100).contains(v)));
    let cell = grid.cell_model(1).unwrap();
    assert_eq!(
        f64::from(p.map.data[1]),
        (100.0 * cell.predict(1000.0) as f32).round() as f64
    );
    assert!(p.map.data[1] > 0 && p.map.data[0] == 0, "{:?}", p.map.data);
    // The open bin is learned at shutdown and restored.
    world
        .observe_people(0, &people(610.0, &[(13.0, 21.0)]))
        .unwrap();
    world.save(true).unwrap();
    let restored = World::new(config(&dir.0, params)).unwrap();
    let grid = restored.grid(0).unwrap();
    assert_eq!((grid.frames(), grid.frame_span().last), (3, 650.0));
    assert_eq!(grid.cell_state(7), Occupied);
    let other = params.replace("width: 4", "width: 5");
    let e = World::new(config(&dir.0, &other))
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("it is 4 x 2 cells of 1 m at (10, 20), but people.lobby is 5 x 2"),
        "{e}"
    );
}

/// Durable learning: the parameters of a node that learns states, a map and people, with a
/// journal that syncs only when told to.
const DURABLE: &str = "    save_dir: saved\n    record_observations: true\n    states:\n      door: {topic: /door, type: std_msgs/msg/Bool, model: fremen:2}\n      light: {topic: /light, type: std_msgs/msg/Float64, model: hist:24}\n    maps:\n      office: {topic: /m, order: 2}\n    people:\n      lobby: {topic: /p, width: 4, height: 2, resolution: 1.0, origin: [10, 20], bin: 100}\n";

/// Syncs only when `sync` is called (or at a checkpoint).
fn manual_sync() -> JournalSettings {
    JournalSettings {
        sync_period: std::time::Duration::from_secs(3600),
        sync_records: usize::MAX,
        ..JournalSettings::default()
    }
}

/// People detected at `xy` at time `t`, in `map`.
fn detections(t: f64, xy: &[(f64, f64)]) -> PoseArray {
    PoseArray {
        header: Header {
            stamp: Time::from_seconds(t),
            frame_id: "map".into(),
        },
        poses: xy
            .iter()
            .map(|&(x, y)| Pose {
                position: Point { x, y, z: 0.0 },
                orientation: Quaternion::default(),
            })
            .collect(),
    }
}

/// One learned message of the durability tests.
#[derive(Clone)]
enum Message {
    State(usize, f64, f64),
    Map(OccupancyGrid),
    People(PoseArray),
    CloseBins(f64),
}

/// Hour `k` of three days: door and light states (the real Greg door for the door), an
/// observed map every hour, people in the lobby every few minutes.
fn messages(hours: std::ops::Range<i32>) -> Vec<Message> {
    let door = read_pairs(chronomap_testutil::data_path(
        "door_greg_2016/training_data.txt.xz",
    ))
    .unwrap();
    let t0 = door.times[0];
    let mut out = Vec::new();
    for h in hours {
        let start = t0 + f64::from(h) * 3600.0;
        for (&t, &v) in door.times.iter().zip(&door.values) {
            if t >= start && t < start + 3600.0 && (t as i64) % 60 == 0 {
                out.push(Message::State(0, t, v));
            }
        }
        out.push(Message::State(
            1,
            start + 1.5,
            f64::from((h * 7) % 11) / 10.0,
        ));
        let mut map = map_message(0, "map", 6, 4, office_frame(h));
        map.header.stamp = Time::from_seconds(start + 2.0);
        out.push(Message::Map(map));
        for m in 0..6 {
            let t = start + 10.0 + f64::from(m) * 590.0;
            let x = 10.5 + f64::from((h + m) % 4);
            out.push(Message::People(detections(
                t,
                &[(x, 20.5 + f64::from(m % 2))],
            )));
        }
        out.push(Message::CloseBins(start + 3599.0));
    }
    out
}

fn learn(world: &mut World, messages: &[Message]) {
    for m in messages {
        match m {
            Message::State(i, t, v) => {
                world.observe_state(*i, *t, *v).unwrap();
            }
            Message::Map(msg) => world.observe_map(0, msg).unwrap(),
            Message::People(msg) => world.observe_people(1, msg).unwrap(),
            Message::CloseBins(now) => world.close_stale_bins(*now).unwrap(),
        }
    }
}

/// The bytes of every model (and model of the squared values) and grid of `world`, with open
/// people bins learned (as the node does at shutdown), for bit-for-bit comparisons.
fn model_bytes(world: &mut World) -> Vec<Vec<u8>> {
    for index in 0..world.grids.len() {
        world.close_bin(index).unwrap();
    }
    let encode = |learner: &Learner| match learner {
        Learner::Online(m) => chronomap_io::model_file::encode_model(m.kind(), m).unwrap(),
        learner => chronomap_io::model_file::encode_model("learner", learner).unwrap(),
    };
    let mut bytes: Vec<Vec<u8>> = world
        .states
        .iter()
        .flat_map(|s| std::iter::once(&s.model).chain(&s.spread))
        .map(encode)
        .collect();
    for g in &world.grids {
        let grid = g.grid.clone().expect("a grid");
        bytes.push(chronomap_io::encode_grid(&AnyGrid::State(Box::new(grid))).unwrap());
    }
    bytes
}

/// Asserts that two worlds hold the same models and grids, bit for bit (naming which differs).
fn assert_same_models(restored: &mut World, expected: &mut World) {
    let (a, b) = (model_bytes(restored), model_bytes(expected));
    assert_eq!(a.len(), b.len());
    for (i, (a, b)) in a.iter().zip(&b).enumerate() {
        assert!(
            a == b,
            "model {i} differs ({} and {} bytes)",
            a.len(),
            b.len()
        );
    }
}

/// What a node without `save_dir` learns from `messages`.
fn reference(dir: &Path, messages: &[Message]) -> World {
    let params = DURABLE.replace("    save_dir: saved\n    record_observations: true\n", "");
    let mut world = World::new(config(dir, &params)).unwrap();
    learn(&mut world, messages);
    world
}

#[test]
fn a_crash_loses_only_what_was_not_synced_and_the_restart_equals_a_node_that_ran_through() {
    let dir = Scratch::new("crash");
    let all = messages(0..30);
    // The checkpoint comes right after a people message: its bin is open.
    let checkpoint_at = (0..all.len() / 2)
        .rev()
        .find(|&i| matches!(all[i], Message::People(_)))
        .unwrap()
        + 1;
    let (first, rest) = all.split_at(checkpoint_at);
    // Learned until a checkpoint, then more: synced, then a few unsynced states.
    let mut world = World::open(config(&dir.0, DURABLE), manual_sync()).unwrap();
    learn(&mut world, first);
    world.save(false).unwrap();
    // People messages of an open bin before and after the checkpoint.
    assert!(world.grids[1].open.is_some());
    let synced = rest.len();
    learn(&mut world, rest);
    let later = Instant::now() + std::time::Duration::from_secs(7200);
    world.sync_journal(later);
    // States of the next hour are learned but not synced.
    let unsynced: Vec<Message> = messages(30..31)
        .into_iter()
        .filter(|m| matches!(m, Message::State(..)))
        .collect();
    assert!(unsynced.len() > 10);
    learn(&mut world, &unsynced);
    // kill -9: nothing is flushed, nothing is saved.
    std::mem::forget(world);

    let mut restored = World::open(config(&dir.0, DURABLE), manual_sync()).unwrap();
    let learned = &all[..checkpoint_at + synced];
    let mut expected = reference(&dir.0, learned);
    let r = restored.restored().clone();
    assert_eq!((r.unknown, r.refused, r.torn_bytes), (0, 0, 0));
    // The light (Float64) has its interval back, bit for bit.
    assert!(restored.state_spread(1).is_some());
    for t in [1_451_606_400.0, 1_451_649_600.0] {
        let (a, b) = (
            restored.state_interval(1, t).unwrap(),
            expected.state_interval(1, t).unwrap(),
        );
        assert_eq!(
            (a.0.to_bits(), a.1.to_bits()),
            (b.0.to_bits(), b.1.to_bits())
        );
    }
    // The open bin of the checkpoint is replayed from its first message.
    let after_checkpoint = |pick: fn(&Message) -> bool| {
        all[checkpoint_at..checkpoint_at + synced]
            .iter()
            .filter(|m| pick(m))
            .count() as u64
    };
    assert_eq!(
        r.states[0].1,
        after_checkpoint(|m| matches!(m, Message::State(0, ..)))
    );
    assert_eq!(
        r.grids[0].1,
        after_checkpoint(|m| matches!(m, Message::Map(_)))
    );
    assert!(r.replayed > after_checkpoint(|m| !matches!(m, Message::CloseBins(_))));
    assert_eq!(restored.learned().0[0].total, expected.learned().0[0].total);
    // The record holds exactly the observations of the model: none twice, none lost.
    let record = read_pairs(dir.0.join("saved/states/door.txt")).unwrap();
    let sent: Vec<(f64, f64)> = learned
        .iter()
        .filter_map(|m| match m {
            Message::State(0, t, v) => Some((*t, *v)),
            _ => None,
        })
        .collect();
    assert_eq!(record.times.len(), sent.len());
    assert!(
        record
            .times
            .iter()
            .zip(&record.values)
            .eq(sent.iter().map(|(t, v)| (t, v)))
    );
    // Bit for bit the models of a node that learned what was synced.
    assert_same_models(&mut restored, &mut expected);
    // Learning goes on where it stopped, and a clean stop and start changes nothing.
    let mut again = World::open(config(&dir.0, DURABLE), manual_sync()).unwrap();
    learn(&mut again, &unsynced);
    again.save(true).unwrap();
    let mut third = World::new(config(&dir.0, DURABLE)).unwrap();
    let mut expected = reference(&dir.0, &[learned, &unsynced[..]].concat());
    assert_eq!(third.restored().replayed, 0);
    assert_same_models(&mut third, &mut expected);
}

#[test]
fn an_interrupted_checkpoint_is_completed_or_discarded_at_start() {
    let dir = Scratch::new("interrupted");
    let all = messages(0..12);
    let (first, rest) = all.split_at(all.len() / 2);
    let mut world = World::open(config(&dir.0, DURABLE), manual_sync()).unwrap();
    learn(&mut world, first);
    world.save(false).unwrap();
    let saved = dir.0.join("saved");
    let files = [
        "states/door.cmm",
        "states/light.cmm",
        "states/light.squares.cmm",
        "maps/office.cmg",
        "people/lobby.cmg",
    ];
    let old: Vec<Vec<u8>> = files
        .iter()
        .map(|f| std::fs::read(saved.join(f)).unwrap())
        .collect();
    learn(&mut world, rest);
    world.save(false).unwrap();
    let head = world.durable.as_ref().unwrap().journal.next_position();
    std::mem::forget(world);
    // The crash came after the checkpoint file was replaced, before the renames: the new
    // files still carry their `.next-H` names, the old ones their names.
    for (f, old) in files.iter().zip(&old) {
        let file = saved.join(f);
        std::fs::rename(&file, next_name(&file, head)).unwrap();
        std::fs::write(&file, old).unwrap();
    }
    // And a checkpoint that never counted left files of another position.
    std::fs::write(saved.join("states/door.cmm.next-999999"), "half").unwrap();
    let mut restored = World::open(config(&dir.0, DURABLE), manual_sync()).unwrap();
    assert!(!saved.join("states/door.cmm.next-999999").exists());
    for f in files {
        assert!(!next_name(&saved.join(f), head).exists(), "{f}");
    }
    let mut expected = reference(&dir.0, &all);
    assert_same_models(&mut restored, &mut expected);
}

#[test]
fn a_journal_without_its_checkpoint_file_is_refused_and_inputs_no_longer_configured_are_skipped() {
    let dir = Scratch::new("no-checkpoint");
    let all = messages(0..3);
    let mut world = World::open(config(&dir.0, DURABLE), manual_sync()).unwrap();
    learn(&mut world, &all);
    world.sync_journal(Instant::now() + std::time::Duration::from_secs(7200));
    std::mem::forget(world);
    // Without the light, its records are skipped (and counted).
    let without_light = DURABLE.replace(
        "      light: {topic: /light, type: std_msgs/msg/Float64, model: hist:24}\n",
        "",
    );
    let restored = World::open(config(&dir.0, &without_light), manual_sync()).unwrap();
    assert_eq!(restored.restored().unknown, 3);
    drop(restored);
    std::fs::remove_file(dir.0.join("saved/checkpoint")).unwrap();
    let e = World::new(config(&dir.0, DURABLE))
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("checkpoint: missing, but") && e.contains("holds a journal"),
        "{e}"
    );
}

#[test]
fn a_crash_before_the_first_checkpoint_leaves_each_observation_once_in_the_record() {
    let dir = Scratch::new("crash-record");
    let all = messages(0..4);
    let mut world = World::open(config(&dir.0, DURABLE), manual_sync()).unwrap();
    learn(&mut world, &all);
    // Synced: the journal and the record hold the same observations.
    world.sync_journal(Instant::now() + std::time::Duration::from_secs(7200));
    std::mem::forget(world);
    let mut restored = World::open(config(&dir.0, DURABLE), manual_sync()).unwrap();
    restored.save(true).unwrap();
    let record = read_pairs(dir.0.join("saved/states/door.txt")).unwrap();
    let sent: Vec<(f64, f64)> = all
        .iter()
        .filter_map(|m| match m {
            Message::State(0, t, v) => Some((*t, *v)),
            _ => None,
        })
        .collect();
    assert!(sent.len() > 100);
    let recorded: Vec<(f64, f64)> = record.times.into_iter().zip(record.values).collect();
    assert_eq!(recorded, sent);
    let mut expected = reference(&dir.0, &all);
    assert_same_models(&mut restored, &mut expected);
}

#[test]
fn a_model_fitted_on_a_whole_series_is_refitted_journaled_and_restored_bit_for_bit() {
    let dir = Scratch::new("refit");
    let params = "    save_dir: saved\n    states:\n      door: {topic: /door, type: std_msgs/msg/Bool, model: \"fremen:auto\", keep: 3000, refit_observations: 2000, refit_period: 0}\n";
    let door = read_pairs(chronomap_testutil::data_path(
        "door_greg_2016/training_data.txt.xz",
    ))
    .unwrap();
    let (times, values): (Vec<f64>, Vec<f64>) = door
        .times
        .iter()
        .zip(&door.values)
        .step_by(10)
        .map(|(&t, &v)| (t, v))
        .take(5000)
        .unzip();
    let mut world = World::open(config(&dir.0, params), manual_sync()).unwrap();
    assert!(!world.config().states[0].learns_online());
    // Before a fit: 0.5, and not due before 2,000 observations.
    assert_eq!(world.predict_state(0, times[0]).0, 0.5);
    for k in 0..1999 {
        world.observe_state(0, times[k], values[k]).unwrap();
    }
    assert!(!world.refit_due(0));
    world.observe_state(0, times[1999], values[1999]).unwrap();
    assert!(world.refit_due(0));
    let job = world.refit_job(0).unwrap();
    // The node fits on another thread while learning goes on: 500 more meanwhile.
    for k in 2000..2500 {
        world.observe_state(0, times[k], values[k]).unwrap();
    }
    let refit = job
        .run(&chronomap_models::spec::FitOptions::default())
        .unwrap();
    world.install_refit(0, refit, None).unwrap();
    // The fit is `chronomap fit` of the 2,000 observations it saw, then it observed the 500.
    let mut expected = "fremen:auto"
        .parse::<chronomap_models::ModelSpec>()
        .unwrap()
        .fit(&times[..2000], &values[..2000], &FitOptions::default())
        .unwrap()
        .model;
    expected
        .observe(&times[2000..2500], &values[2000..2500])
        .unwrap();
    let later = times[2499] + 7200.0;
    assert_eq!(
        world.predict_state(0, later).0.to_bits(),
        expected.predict(later).to_bits()
    );
    assert_ne!(world.predict_state(0, later).0, 0.5);
    for k in 2500..2600 {
        world.observe_state(0, times[k], values[k]).unwrap();
    }
    world.sync_journal(Instant::now() + std::time::Duration::from_secs(7200));
    let live = world.predict_state(0, later).0;
    std::mem::forget(world);
    // After a crash the journal installs the same fit at the same place: no fit again.
    let mut restored = World::open(config(&dir.0, params), manual_sync()).unwrap();
    assert_eq!(restored.predict_state(0, later).0.to_bits(), live.to_bits());
    assert_eq!(restored.state_model(0).kept(), 2600);
    assert_eq!(
        restored.state_model(0).last_fit().map(|f| f.through),
        Some(2000)
    );
    // A checkpoint writes the kept observations and the fit (`door.cml`), restored as they were.
    restored.save(true).unwrap();
    assert!(dir.0.join("saved/states/door.cml").is_file());
    let mut again = World::new(config(&dir.0, params)).unwrap();
    assert_eq!(again.predict_state(0, later).0.to_bits(), live.to_bits());
    assert_same_models(&mut again, &mut restored);
    // keep: 3000 drops the oldest.
    for k in 2600..3500 {
        again.observe_state(0, times[k], values[k]).unwrap();
    }
    assert_eq!(again.state_model(0).kept(), 3000);
    drop(again);
    // The model changed to one learning online: the refitted one is not left behind silently.
    let online = params.replace(
        "model: \"fremen:auto\", keep: 3000, refit_observations: 2000, refit_period: 0",
        "model: \"fremen:2\"",
    );
    let e = World::new(config(&dir.0, &online))
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("door.cml: it holds a `fremen:auto` model, but states.door.model is `fremen:2`"),
        "{e}"
    );
}

#[test]
fn a_map_that_could_bring_the_grids_above_memory_limit_is_refused_and_changes_nothing() {
    let dir = Scratch::new("memory-limit");
    // Two maps: `small` (6 x 4 cells) is learned first; a 200 x 200 map of `big` could take
    // more than the 3 MB left.
    let params =
        "    memory_limit: 3000000\n    maps:\n      small: {topic: /s}\n      big: {topic: /b}\n";
    let mut world = World::new(config(&dir.0, params)).unwrap();
    for h in 0..3 {
        world
            .observe_map(0, &map_message(3600 * h, "map", 6, 4, office_frame(h)))
            .unwrap();
    }
    let side = 200;
    let frame = |k: i32| -> Vec<i8> {
        (0..side * side)
            .map(|c| if (c as i32 + k) % 3 == 0 { 100 } else { 0 })
            .collect()
    };
    // The first map of `big` makes its cells known: each may take a slot and blocks.
    let e = world
        .observe_map(1, &map_message(0, "map", side, side, frame(0)))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("learning it could bring the grids to ")
            && e.ends_with("MB, more than memory_limit (3.0 MB); not learned"),
        "{e}"
    );
    assert!(world.grid(1).is_none(), "nothing of `big` is kept");
    assert_eq!(world.grid(0).unwrap().frames(), 3);
    // Without a limit the same map is learned; the bound held.
    let unlimited = params.replace("memory_limit: 3000000", "memory_limit: 0");
    let mut world = World::new(config(&dir.0, &unlimited)).unwrap();
    let msg = map_message(0, "map", side, side, frame(0));
    world.observe_map(1, &msg).unwrap();
    let held = world.grid(1).unwrap().heap_bytes() as u64;
    assert!(
        held < 3_000_000,
        "{held}: the bound is conservative, not the use"
    );
}

/// Edge models of a three-node map, fitted on a few weeks of made-up traversals: `spread`
/// with successful ones (durations have a spread), else only failures (no interval).
fn edge_models(spread: bool) -> chronomap_topo::edges::EdgeModels {
    use chronomap_topo::edges::{Attempt, EdgeModelConfig, EdgeModels};
    let mut map = chronomap_topo::TopoMap::new();
    for (name, x) in [("Station", 0.0), ("Door", 4.0), ("Lab", 9.5)] {
        map.add_node(name, Some([x, 1.0, 0.0])).unwrap();
    }
    map.add_edge("Station_Door", "Station", "Door").unwrap();
    map.add_edge("Door_Lab", "Door", "Lab").unwrap();
    map.add_edge("Lab_Station", "Lab", "Station").unwrap();
    let attempts = |edge: usize, n: usize| -> Vec<Attempt> {
        (0..n)
            .map(|i| Attempt {
                time: 1_404_000_000.0 + 3_600.0 * i as f64,
                duration_secs: 10.0 * (edge + 1) as f64 + ((i * 7 + edge) % 13) as f64,
                success: spread && i % 9 != 4,
            })
            .collect()
    };
    let all = [attempts(0, 400), attempts(1, 60), Vec::new()];
    EdgeModels::fit(map, &all, EdgeModelConfig::default()).unwrap()
}

#[test]
fn the_route_graph_carries_each_edge_s_duration_interval_as_flat_metadata() {
    let dir = Scratch::new("route_graph");
    let params = "    edges: {models: witham.cmt, geojson: route.geojson, period: 1.0}\n";
    let time = 1_404_000_000.0 + 3_600.0 * 430.5;
    for spread in [true, false] {
        let models = edge_models(spread);
        chronomap_io::write_edge_models(dir.0.join("witham.cmt"), &models).unwrap();
        let world = World::new(config(&dir.0, params)).unwrap();
        assert!(world.write_route_graph(time).unwrap());
        let text = std::fs::read_to_string(dir.0.join("route.geojson")).unwrap();
        let graph: serde_json::Value = serde_json::from_str(&text).unwrap();
        let edges: Vec<&serde_json::Value> = graph["features"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["geometry"]["type"] == "MultiLineString")
            .map(|f| &f["properties"]["metadata"])
            .collect();
        assert_eq!(edges.len(), 3);
        let (success, duration) = models.at(time);
        for (e, metadata) in edges.iter().enumerate() {
            assert_eq!(metadata["name"], models.map().edges()[e].id);
            let number = |key: &str| metadata.get(key).map(|v| v.as_f64().unwrap().to_bits());
            assert_eq!(number("success_probability"), Some(success[e].to_bits()));
            assert_eq!(number("abs_time_taken"), Some(duration[e].to_bits()));
            // The library's interval at the same time, bit for bit, or no keys without one.
            let interval = models.duration_interval(e, time, EVALUATION_COVERAGE);
            assert_eq!(interval.is_some(), spread, "edge {e}");
            assert_eq!(
                number("abs_time_taken_lower").zip(number("abs_time_taken_upper")),
                interval.map(|(lo, hi)| (lo.to_bits(), hi.to_bits())),
                "edge {e}"
            );
            assert_eq!(
                number("abs_time_taken_coverage"),
                spread.then_some(0.9f64.to_bits()),
                "edge {e}"
            );
            if let Some((lo, hi)) = interval {
                assert!(0.0 < lo && lo < hi, "edge {e}: {lo} {hi}");
            }
        }
    }
}

/// With `days_off_file`, a state observed on a day off learns nothing (not journaled, not
/// recorded, counted), and its prediction for a time on a day off is its prediction at the
/// stand-in Sunday (`DaysOff::stand_in`); the calendar is configuration, not saved state:
/// the models restore with or without it.
#[test]
fn a_state_on_a_day_off_learns_nothing_and_is_predicted_as_its_sunday() {
    use chronomap_core::time::days_from_civil;
    let dir = Scratch::new("days-off");
    std::fs::write(
        dir.0.join("holidays.txt"),
        "# England\n2016-03-25 Good Friday\n",
    )
    .unwrap();
    let week =
        "    states:\n      door: {topic: /door, type: std_msgs/msg/Bool, model: hist:168}\n";
    let saved = "    save_dir: saved\n    record_observations: true\n";
    let calendar = "    days_off_file: holidays.txt\n";
    let mut world = World::new(config(&dir.0, &format!("{saved}{calendar}{week}"))).unwrap();
    let mut plain = World::new(config(&dir.0, week)).unwrap();
    // Hourly, three weeks from Monday 2016-03-07: open (1) on weekdays 8-18 h, and open on
    // Good Friday too (someone came in), which the calendar keeps out.
    let day = |d: u32| 86_400.0 * days_from_civil(2016, 3, d) as f64;
    let good_friday = day(25);
    for h in 0..21 * 24 {
        let t = day(7) + 3600.0 * f64::from(h);
        let hour = f64::from(h % 24);
        let weekday = h / 24 % 7 < 5;
        let v = f64::from(u8::from(weekday && (8.0..18.0).contains(&hour)));
        let on_day_off = (good_friday..good_friday + 86_400.0).contains(&t);
        assert_eq!(world.observe_state(0, t, v).unwrap(), !on_day_off, "{t}");
        if !on_day_off {
            assert!(plain.observe_state(0, t, v).unwrap());
        }
    }
    // A bad value on a day off is still refused.
    assert!(world.observe_state(0, good_friday + 1.0, 2.0).is_err());
    let learned = Learned {
        observations: 20 * 24,
        total: 20 * 24,
        days_off: 24,
    };
    assert_eq!(world.learned().0[0], learned);
    // Working days are predicted as the model learned them (the plain world saw the same).
    let noon = 12.0 * 3600.0;
    for t in [
        day(24) + noon,
        day(18) + noon,
        day(20) + noon,
        day(26) + 3.0,
    ] {
        assert_eq!(world.predict_state(0, t), plain.predict_state(0, t), "{t}");
    }
    // Good Friday noon is predicted as Sunday 2016-03-20 noon: shut; without the calendar,
    // as a Friday: open.
    let friday_noon = good_friday + noon;
    let (p, h) = world.predict_state(0, friday_noon);
    let sunday = plain.predict_state(0, day(20) + noon);
    assert_eq!(
        (p.to_bits(), h.to_bits()),
        (sunday.0.to_bits(), sunday.1.to_bits())
    );
    assert_eq!(p, 0.0);
    assert_eq!(plain.predict_state(0, friday_noon).0, 1.0);
    let message = world.state_prediction(0, friday_noon, Time::default());
    assert_eq!(message.header.stamp, Time::from_seconds(friday_noon));
    assert_eq!(message.probability.to_bits(), p.to_bits());
    assert_eq!(message.observations, 20 * 24);
    // Nothing of the day off was recorded; restored with the calendar, the same model and
    // predictions; restored without it (it is not saved), the same model predicting Good
    // Friday as a Friday.
    world.save(true).unwrap();
    let record = read_pairs(dir.0.join("saved/states/door.txt")).unwrap();
    assert_eq!(record.times.len(), 20 * 24);
    assert!(
        !record
            .times
            .iter()
            .any(|&t| t >= good_friday && t < good_friday + 86_400.0)
    );
    let again = World::new(config(&dir.0, &format!("{saved}{calendar}{week}"))).unwrap();
    assert_eq!(again.learned().0[0].total, 20 * 24);
    assert_eq!(again.predict_state(0, friday_noon), (p, h));
    drop(again);
    let without = World::new(config(&dir.0, &format!("{saved}{week}"))).unwrap();
    assert_eq!(without.learned().0[0].total, 20 * 24);
    assert_eq!(without.predict_state(0, friday_noon).0, 1.0);
}

/// The law of a continuous state at `t`: a Beta law whose mean and concentration (so its
/// variance) follow the time of day (as `crates/serve/tests/intervals.rs`).
fn beta_law_at(t: f64) -> statrs::distribution::Beta {
    let phase = std::f64::consts::TAU * t / 86_400.0;
    let m = 0.5 + 0.3 * phase.cos();
    let k = 12.0 + 6.0 * phase.sin();
    statrs::distribution::Beta::new(m * k, (1.0 - m) * k).unwrap()
}

fn beta_draw(rng: &mut chronomap_core::rng::Xoshiro256StarStar, t: f64) -> f64 {
    use statrs::distribution::ContinuousCDF;
    beta_law_at(t).inverse_cdf(rng.next_f64())
}

/// Four states of one `Float64` topic (`fremen:2` at 90 % and 50 %, `auto`, `fremen:auto`)
/// and a `Bool` one; values of [`beta_law_at`].
const LEVEL: &str = "    save_dir: saved\n    states:\n      level: {topic: /level, type: std_msgs/msg/Float64, model: fremen:2}\n      half: {topic: /level, type: std_msgs/msg/Float64, model: fremen:2, coverage: 0.5}\n      stack: {topic: /level, type: std_msgs/msg/Float64, model: auto, refit_observations: 0, refit_period: 0}\n      order: {topic: /level, type: std_msgs/msg/Float64, model: \"fremen:auto\", refit_observations: 0, refit_period: 0}\n      door: {topic: /door, type: std_msgs/msg/Bool, model: fremen:2}\n";

#[test]
fn a_continuous_state_s_interval_is_the_beta_law_of_its_two_moments_and_holds_its_coverage() {
    use chronomap_core::conformance::check_interval_coverage;
    use chronomap_core::rng::Xoshiro256StarStar;
    let dir = Scratch::new("intervals");
    let mut world = World::open(config(&dir.0, LEVEL), manual_sync()).unwrap();
    // States are in the order of their names.
    let states = &world.config().states;
    let names: Vec<&str> = states.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["door", "half", "level", "order", "stack"]);
    let (door, half, level, order, stack) = (0, 1, 2, 3, 4);
    let with: Vec<bool> = states.iter().map(|s| s.has_interval()).collect();
    assert_eq!(with, [false, true, true, false, true]);
    assert_eq!((states[level].coverage, states[half].coverage), (0.9, 0.5));
    // Four weeks, one value every two minutes, into every state of /level.
    let mut rng = Xoshiro256StarStar::seed_from_u64(41);
    let start = 1.7e9;
    let n = 28 * 720;
    let times: Vec<f64> = (0..n).map(|i| start + 120.0 * f64::from(i)).collect();
    let values: Vec<f64> = times.iter().map(|&t| beta_draw(&mut rng, t)).collect();
    for (&t, &v) in times.iter().zip(&values) {
        for index in [half, level, order, stack] {
            assert!(world.observe_state(index, t, v).unwrap());
        }
        world
            .observe_state(door, t, f64::from(u8::from(v > 0.5)))
            .unwrap();
    }
    // The interval is `beta_interval` of the two learners' predictions, bit for bit; and they
    // are `chronomap fit` of the values and of their squares.
    let squares: Vec<f64> = values.iter().map(|v| v * v).collect();
    let fit = |values: &[f64]| {
        "fremen:2"
            .parse::<chronomap_models::ModelSpec>()
            .unwrap()
            .fit(&times, values, &FitOptions::default())
            .unwrap()
            .model
    };
    let (mean, second) = (fit(&values), fit(&squares));
    let after = start + 28.0 * 86_400.0;
    for t in [after, after + 7_000.0, after + 50_000.0] {
        let m = world.state_model(level).predict(t);
        let s = world.state_spread(level).unwrap().predict(t);
        assert_eq!(m.to_bits(), mean.predict(t).to_bits());
        assert_eq!(s.to_bits(), second.predict(t).to_bits());
        for (index, coverage) in [(level, 0.9), (half, 0.5)] {
            let (lo, hi) = world.state_interval(index, t).unwrap();
            let (elo, ehi) = chronomap_core::spread::beta_interval(m, s, coverage);
            assert_eq!((lo.to_bits(), hi.to_bits()), (elo.to_bits(), ehi.to_bits()));
            assert!(lo < m && m < hi, "{lo} {m} {hi}");
            let msg = world.state_prediction(index, t, Time::default());
            assert_eq!(
                (msg.lower.to_bits(), msg.upper.to_bits(), msg.coverage),
                (lo.to_bits(), hi.to_bits(), coverage)
            );
        }
    }
    // No interval: the Bool state, `fremen:auto`, and `auto` before its fit.
    for index in [door, order, stack] {
        assert_eq!(world.state_interval(index, after), None, "{index}");
        let msg = world.state_prediction(index, after, Time::default());
        assert!(msg.lower.is_nan() && msg.upper.is_nan() && msg.coverage == 0.0);
    }
    assert!(world.spread_refit_job(order).is_none() && world.state_spread(order).is_none());
    // `auto` refits its squares with its values: then it has an interval.
    let options = FitOptions::default();
    for index in [stack, order] {
        let refit = world.refit_job(index).unwrap().run(&options).unwrap();
        let spread = world
            .spread_refit_job(index)
            .map(|job| job.run(&options).unwrap());
        world.install_refit(index, refit, spread).unwrap();
    }
    assert!(world.state_interval(stack, after).is_some());
    assert_eq!(world.state_interval(order, after), None);
    // Fresh values of the next week fall inside as often as the coverage says.
    let fresh_times: Vec<f64> = (0..4000)
        .map(|_| after + rng.uniform(0.0, 7.0 * 86_400.0))
        .collect();
    let fresh: Vec<f64> = fresh_times
        .iter()
        .map(|&t| beta_draw(&mut rng, t))
        .collect();
    for (index, coverage, what) in [
        (level, 0.9, "fremen:2"),
        (half, 0.5, "fremen:2"),
        (stack, 0.9, "auto"),
    ] {
        let intervals: Vec<(f64, f64)> = fresh_times
            .iter()
            .map(|&t| world.state_interval(index, t).unwrap())
            .collect();
        let c = check_interval_coverage(
            &format!("node, {what}, {coverage}"),
            coverage,
            &intervals,
            &fresh,
        );
        println!("{what}, {coverage}: {c:?}");
    }
    // After a crash (journal replay, the refit of `auto` with its squares included) and after
    // a checkpoint, the intervals are the same, bit for bit.
    let probe: Vec<f64> = (0..50).map(|i| after + 3000.0 * f64::from(i)).collect();
    let intervals = |w: &World| -> Vec<u64> {
        (0..5)
            .flat_map(|index| probe.iter().map(move |&t| (index, t)))
            .flat_map(|(index, t)| {
                let p = w.state_prediction(index, t, Time::default());
                [p.probability, p.lower, p.upper, p.coverage].map(f64::to_bits)
            })
            .collect()
    };
    let live = intervals(&world);
    world.sync_journal(Instant::now() + std::time::Duration::from_secs(7200));
    std::mem::forget(world);
    let mut restored = World::open(config(&dir.0, LEVEL), manual_sync()).unwrap();
    assert_eq!(intervals(&restored), live);
    restored.save(true).unwrap();
    for f in ["level.squares.cmm", "half.squares.cmm", "stack.squares.cml"] {
        assert!(dir.0.join("saved/states").join(f).is_file(), "{f}");
    }
    assert!(!dir.0.join("saved/states/order.squares.cml").exists());
    assert!(!dir.0.join("saved/states/door.squares.cmm").exists());
    let mut again = World::open(config(&dir.0, LEVEL), manual_sync()).unwrap();
    assert_eq!(again.restored().replayed, 0);
    assert_eq!(intervals(&again), live);
    assert_same_models(&mut again, &mut restored);
}

#[test]
fn files_of_a_node_before_intervals_still_load_and_give_no_interval() {
    let dir = Scratch::new("before-intervals");
    let params = "    save_dir: saved\n    states:\n      level: {topic: /level, type: std_msgs/msg/Float64, model: hist:24}\n";
    let mut world = World::open(config(&dir.0, params), manual_sync()).unwrap();
    for k in 0..500 {
        let t = 1.7e9 + 600.0 * f64::from(k);
        world.observe_state(0, t, f64::from(k % 7) / 6.0).unwrap();
    }
    world.save(true).unwrap();
    let at = 1.7e9 + 400_000.0;
    let live = world.predict_state(0, at);
    assert!(world.state_interval(0, at).is_some());
    drop(world);
    // What a node before intervals left: the model alone, in a checkpoint naming it alone.
    let saved = dir.0.join("saved");
    std::fs::remove_file(saved.join("states/level.squares.cmm")).unwrap();
    let (kind, mut manifest): (String, super::store::Manifest) =
        chronomap_io::model_file::read_model_file(saved.join("checkpoint")).unwrap();
    manifest.files.retain(|f| !f.path.contains(".squares."));
    chronomap_io::model_file::write_model_file(saved.join("checkpoint"), &kind, &manifest).unwrap();
    let mut old = World::open(config(&dir.0, params), manual_sync()).unwrap();
    assert_eq!(old.predict_state(0, at), live);
    assert_eq!(old.state_interval(0, at), None);
    let msg = old.state_prediction(0, at, Time::default());
    assert!(msg.lower.is_nan() && msg.upper.is_nan() && msg.coverage == 0.0);
    // It goes on learning, and stays without an interval (it never learned the squares).
    old.observe_state(0, at, 0.5).unwrap();
    old.save(true).unwrap();
    assert!(!saved.join("states/level.squares.cmm").exists());
    drop(old);
    // A file of squares the checkpoint does not name (left over) is not taken either, and a
    // model of squares that learned another count than the model is refused.
    let again = World::open(config(&dir.0, params), manual_sync()).unwrap();
    assert_eq!(again.state_interval(0, at), None);
    drop(again);
    let fresh = Scratch::new("before-intervals-count");
    let mut world = World::open(config(&fresh.0, params), manual_sync()).unwrap();
    world.observe_state(0, 1.7e9, 0.5).unwrap();
    world.save(true).unwrap();
    drop(world);
    let other = fresh.0.join("saved/states/level.squares.cmm");
    let mut squares = chronomap_io::read_any_model(&other).unwrap();
    squares.observe(&[1.7e9 + 1.0], &[0.25]).unwrap();
    chronomap_io::write_any_model(&other, &squares).unwrap();
    let e = World::open(config(&fresh.0, params), manual_sync())
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("level.squares.cmm: it learned 2 squared values, but")
            && e.contains("learned 1 values"),
        "{e}"
    );
}
