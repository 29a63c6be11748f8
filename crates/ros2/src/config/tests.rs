use super::*;
use crate::params::MAX_FILE_BYTES;
use crate::ros_args::RosArgs;

/// The text checked without its files and folders: `cfg/` does not exist, and nothing is
/// created beside the crate (the file-system checks have tests of their own below, in a
/// scratch folder).
fn parse(text: &str) -> Result<NodeConfig, ConfigError> {
    NodeConfig::parse_text(Path::new("cfg/node.yaml"), text.as_bytes(), None)
}

fn error(text: &str) -> String {
    match parse(text) {
        Ok(_) => panic!("accepted: {text}"),
        Err(e) => e.to_string(),
    }
}

/// Every section and kind of value the reader knows (shared with the property tests).
const FULL: &str = include_str!("../../tests/full.yaml");

#[test]
fn a_full_file_is_read_with_its_defaults_resolved() {
    let c = parse(FULL).unwrap();
    assert_eq!(
        (c.namespace.as_str(), c.node_name.as_str()),
        ("/robot1", "chronomap")
    );
    assert_eq!(c.fully_qualified_name(), "/robot1/chronomap");
    assert!(c.use_sim_time && c.record_observations);
    assert_eq!(
        (c.publish_period, c.map_period, c.horizon, c.save_period),
        (2.0, 10.0, 600.0, 30.0)
    );
    assert_eq!(c.save_dir.as_deref(), Some(Path::new("cfg/state")));
    assert_eq!(c.max_map_cells, 1_000_000);
    // states in name order
    let light = &c.states[1];
    assert_eq!(light.topic, "/robot1/sensors/light");
    assert_eq!(light.message, StateType::Float32);
    assert_eq!(light.model.to_string(), "hist:24");
    assert_eq!(
        light.qos,
        InputQos {
            reliability: Reliability::BestEffort,
            depth: 5,
            transient_local: false
        }
    );
    assert_eq!(light.probability_topic, "/robot1/chronomap/light_p");
    assert_eq!(light.entropy_topic, "/robot1/chronomap/light/entropy");
    let door = &c.states[0];
    assert_eq!(door.model.to_string(), "fremen:3");
    assert_eq!(door.qos.reliability, Reliability::Reliable);
    let office = &c.grids[0];
    assert_eq!(office.source, GridSource::Map);
    assert_eq!(
        (office.fremen.order, office.values),
        (1, MapValues::Probability)
    );
    assert_eq!(office.fremen.periods, "day".parse::<PeriodSet>().unwrap());
    assert!(!office.qos.transient_local);
    assert_eq!(
        office.predicted_topic,
        "/robot1/chronomap/office/predicted_map"
    );
    let filter = office.filter.as_ref().unwrap();
    assert_eq!(filter.mask_topic, "/robot1/chronomap/office/mask");
    assert_eq!(filter.info_topic, "/robot1/chronomap/office/filter_info");
    assert_eq!(
        (filter.filter_type, filter.base, filter.multiplier),
        (1, 100.0, -1.0)
    );
    let lobby = &c.grids[1];
    assert_eq!(
        lobby.source,
        GridSource::People {
            width: 40,
            height: 30,
            resolution: 0.5,
            origin: [-10.0, -7.5],
            bin_secs: 900.0
        }
    );
    assert_eq!(lobby.values, MapValues::Probability);
    assert!(lobby.filter.is_none());
    assert_eq!(lobby.fremen.order, 2);
    let edges = c.edges.as_ref().unwrap();
    assert_eq!(edges.models, Path::new("cfg/witham.cmt"));
    assert_eq!(edges.geojson, Path::new("cfg/out/route.geojson"));
    assert_eq!(edges.period, 60.0);
    let inputs: Vec<String> = c.inputs().into_iter().map(|i| i.0).collect();
    assert_eq!(
        inputs,
        [
            "/clock",
            "/door",
            "/robot1/sensors/light",
            "/observed_map",
            "/people"
        ]
    );
    // Per state p, entropy and the stamped prediction; per grid its map (and mask, info).
    assert_eq!(c.outputs().len(), 6 + 3 + 1);
}

#[test]
fn minimal_files_get_the_documented_defaults() {
    let c = parse("chronomap:\n  ros__parameters:\n    maps:\n      office: {topic: map_in}\n")
        .unwrap();
    assert!(!c.use_sim_time);
    assert_eq!(
        (c.publish_period, c.map_period, c.horizon, c.save_period),
        (1.0, 30.0, 0.0, 300.0)
    );
    assert_eq!(c.max_map_cells, DEFAULT_MAX_MAP_CELLS);
    let g = &c.grids[0];
    assert_eq!(g.topic, "/map_in");
    assert_eq!(g.frame_id, "map");
    assert_eq!((g.fremen.order, g.values), (2, MapValues::Trinary));
    assert_eq!(g.fremen.periods, PeriodSet::default());
    assert_eq!(
        g.qos,
        InputQos {
            reliability: Reliability::Reliable,
            depth: 10,
            transient_local: false
        }
    );
    let f = g.filter.as_ref().unwrap();
    assert_eq!((f.filter_type, f.base, f.multiplier), (0, 0.0, 1.0));
    assert_eq!(g.predicted_topic, "/chronomap/office/predicted_map");
    // A `/**` entry takes the name given, or chronomap.
    let any =
        "/**:\n  ros__parameters:\n    states:\n      d: {topic: d, type: std_msgs/msg/Float64}\n";
    let c = NodeConfig::parse(Path::new("n.yaml"), any.as_bytes(), Some("walle")).unwrap();
    assert_eq!(c.fully_qualified_name(), "/walle");
    assert_eq!(c.states[0].model.to_string(), "fremen:2");
    assert_eq!(parse(any).unwrap().fully_qualified_name(), "/chronomap");
}

#[test]
fn errors_name_the_file_the_line_and_the_parameter() {
    let base = "chronomap:\n  ros__parameters:\n";
    let cases: &[(&str, &str)] = &[
        (
            "    horizon: -1\n",
            "cfg/node.yaml:3: horizon: -1 is not a finite number of seconds >= 0",
        ),
        (
            "    publish_period: 0\n",
            "cfg/node.yaml:3: publish_period: 0 is not a finite number of seconds > 0",
        ),
        (
            "    sync_period: 600\n",
            "cfg/node.yaml:3: sync_period: 600 s is more than 60 s of learning a crash could lose",
        ),
        (
            "    sync_messages: 0\n",
            "cfg/node.yaml:3: sync_messages: 0 is not a number of messages >= 1",
        ),
        (
            "    colour: red\n",
            "cfg/node.yaml:3: colour: unknown parameter (the node's parameters are use_sim_time,",
        ),
        (
            "    use_sim_time: 1\n",
            "cfg/node.yaml:3: use_sim_time: expected true or false, found the integer 1",
        ),
        (
            "    maps:\n      m:\n        topic: /m\n        order: auto\n",
            "cfg/node.yaml:6: maps.m.order: expected an integer >= 0, found the string \"auto\" \
             (the node learns every cell with a fixed order; `chronomap grid build --order auto` \
             chooses one offline",
        ),
        (
            "    maps:\n      m: {topic: /m, order: 2.0}\n",
            "cfg/node.yaml:4: maps.m.order: expected an integer >= 0, found the number 2.0",
        ),
        (
            "    states:\n      door: {topic: /door, type: std_msgs/msg/Bool, colour: red}\n",
            "cfg/node.yaml:4: states.door.colour: unknown parameter (a state has topic, type, model,",
        ),
        (
            "    states: 3\n",
            "cfg/node.yaml:3: states: expected a mapping of parameters",
        ),
        (
            "    states:\n      door: 3\n",
            "cfg/node.yaml:4: states.door: expected a mapping of parameters",
        ),
        (
            "    people:\n      p: {topic: /p, width: -3, height: 10, resolution: 1}\n",
            "cfg/node.yaml:4: people.p.width: expected an integer in 0..=4294967295, found the integer -3",
        ),
        (
            "    horizon: \"soon\"\n",
            "cfg/node.yaml:3: horizon: expected a number, found the string \"soon\"",
        ),
        (
            "    states:\n      door: {topic: /door, type: nav_msgs/msg/OccupancyGrid}\n",
            "cfg/node.yaml:4: states.door.type: \"nav_msgs/OccupancyGrid\" is not a state type",
        ),
        (
            "    states:\n      door: {type: std_msgs/msg/Bool}\n",
            "cfg/node.yaml:4: states.door.topic: missing (required)",
        ),
        (
            "    states:\n      door:\n        topic: /door\n        type: std_msgs/msg/Bool\n        model: fremen:99\n",
            "cfg/node.yaml:7: states.door.model: ",
        ),
        (
            "    states:\n      level: {topic: /level, type: std_msgs/msg/Float64, coverage: 1.0}\n",
            "cfg/node.yaml:4: states.level.coverage: 1 is not strictly between 0 and 1",
        ),
        (
            "    states:\n      level: {topic: /level, type: std_msgs/msg/Float32, coverage: 0}\n",
            "cfg/node.yaml:4: states.level.coverage: 0 is not strictly between 0 and 1",
        ),
        (
            "    states:\n      door: {topic: /door, type: std_msgs/msg/Bool, coverage: 0.9}\n",
            "cfg/node.yaml:4: states.door.coverage: a std_msgs/msg/Bool state has no prediction interval",
        ),
        (
            "    states:\n      level: {topic: /level, type: std_msgs/msg/Float64, model: \"fremen:auto\", coverage: 0.9}\n",
            "cfg/node.yaml:4: states.level.coverage: `fremen:auto` gives no prediction interval",
        ),
        (
            "    states:\n      level: {topic: /level, type: std_msgs/msg/Float64, coverage: \"0.9\"}\n",
            "cfg/node.yaml:4: states.level.coverage: expected a number",
        ),
        (
            "    states:\n      door:\n        topic: /door\n        type: std_msgs/msg/Bool\n        keep: 1000\n",
            "cfg/node.yaml:7: states.door.keep: `fremen:2` learns online and is never refitted",
        ),
        (
            "    states:\n      door:\n        topic: /door\n        type: std_msgs/msg/Bool\n        model: auto\n        keep: 0\n",
            "cfg/node.yaml:8: states.door.keep: 0 is not in 1..=16777216 observations",
        ),
        (
            "    states:\n      door:\n        topic: /door\n        type: std_msgs/msg/Bool\n        model: fremen:x\n",
            "cfg/node.yaml:7: states.door.model: cannot parse model \"fremen:x\"",
        ),
        (
            "    states:\n      door: {topic: /a//b, type: std_msgs/msg/Bool}\n",
            "cfg/node.yaml:4: states.door.topic: \"/a//b\" is not a valid topic name: empty token",
        ),
        (
            "    states:\n      door: {topic: /1door, type: std_msgs/msg/Bool}\n",
            "states.door.topic: \"/1door\" is not a valid topic name",
        ),
        (
            "    states:\n      door: {topic: /door, type: std_msgs/msg/Bool, reliability: sometimes}\n",
            "states.door.reliability: \"sometimes\" is not reliable or best_effort",
        ),
        (
            "    states:\n      my-door: {topic: /door, type: std_msgs/msg/Bool}\n",
            "cfg/node.yaml:4: states.my-door: the name \"my-door\" is not a ROS name token",
        ),
        (
            "    states:\n      a: {topic: /x, type: std_msgs/msg/Bool}\n      b: {topic: /x, type: std_msgs/msg/Float64}\n",
            "cfg/node.yaml: states.b.topic: /x is also the topic of states.a, with type std_msgs/msg/Bool, not std_msgs/msg/Float64 (states of one topic share its type)",
        ),
        (
            "    states:\n      a: {topic: /x, type: std_msgs/msg/Bool}\n      b: {topic: /x, type: std_msgs/msg/Bool, depth: 7}\n",
            "cfg/node.yaml: states.b.topic: /x is also the topic of states.a, with another reliability, depth or transient_local",
        ),
        (
            "    states:\n      a: {topic: /x, type: std_msgs/msg/Bool}\n    maps:\n      m: {topic: /x}\n",
            "cfg/node.yaml: maps.m.topic: /x is also the topic of states.a.topic (an input topic is read once; only states may share one)",
        ),
        (
            "    states:\n      a: {topic: /x, type: std_msgs/msg/Bool, probability_topic: /y}\n    maps:\n      m: {topic: /y}\n",
            "maps.m.topic: /y is also a topic the node publishes",
        ),
        (
            "    states:\n      a: {topic: /x, type: std_msgs/msg/Bool}\n    maps:\n      a: {topic: /y}\n",
            "cfg/node.yaml:6: maps.a: the name is used by states.a too",
        ),
        (
            "    maps:\n      m: {topic: /m, order: 85}\n",
            "cfg/node.yaml:4: maps.m.order: order 85 is above the largest order 84",
        ),
        (
            "    maps:\n      m: {topic: /m, width: 3}\n",
            "cfg/node.yaml:4: maps.m.width: only people grids have this key",
        ),
        (
            "    maps:\n      m: {topic: /m, values: fuzzy}\n",
            "maps.m.values: \"fuzzy\" is not trinary, scale or probability",
        ),
        (
            "    maps:\n      m: {topic: /m, mask_topic: \"\"}\n",
            "maps.m.mask_topic: mask_topic and filter_info_topic are disabled",
        ),
        (
            "    maps:\n      m: {topic: /m, filter_type: 7}\n",
            "maps.m.filter_type: 7 is not a Nav2 filter type",
        ),
        (
            "    people:\n      p: {topic: /p, width: 10, height: 10}\n",
            "cfg/node.yaml:4: people.p.resolution: missing (required)",
        ),
        (
            "    people:\n      p: {topic: /p, width: 100000, height: 100000, resolution: 1}\n",
            "people.p.width: 100000 x 100000 = 10000000000 cells is above max_map_cells (16777216)",
        ),
        (
            "    people:\n      p: {topic: /p, width: 10, height: 10, resolution: 1, origin: [1]}\n",
            "people.p.origin: [1.0] is not [x, y]",
        ),
        (
            "    record_observations: true\n    states:\n      a: {topic: /x, type: std_msgs/msg/Bool}\n",
            "cfg/node.yaml:3: record_observations: needs save_dir",
        ),
        (
            "    edges:\n      models: a.cmt\n",
            "cfg/node.yaml:3: edges.geojson: missing (required)",
        ),
        ("    max_map_cells: 0\n", "max_map_cells: 0 is not in 1..="),
        ("    horizon: 1\n", "cfg/node.yaml: nothing to do"),
    ];
    for (body, expected) in cases {
        let message = error(&format!("{base}{body}"));
        assert!(
            message.contains(expected),
            "{body}\n{message}\nexpected {expected}"
        );
    }
}

#[test]
fn node_entries_are_chosen_by_name() {
    let two = "a:\n  ros__parameters:\n    horizon: 1\nb:\n  ros__parameters:\n    states:\n      d: {topic: d, type: std_msgs/msg/Bool}\n";
    assert!(error(two).contains("entries for several nodes (a, b): choose one with --node-name"));
    let b = NodeConfig::parse(Path::new("n.yaml"), two.as_bytes(), Some("b")).unwrap();
    assert_eq!(b.node_name, "b");
    let missing = NodeConfig::parse(Path::new("n.yaml"), two.as_bytes(), Some("c")).unwrap_err();
    assert_eq!(
        missing.to_string(),
        "n.yaml: no parameters for node \"c\" (entries: a, b)"
    );
    assert!(error("").contains("no node entry"));
    assert!(error("chronomap: {}\n").contains("cfg/node.yaml:1: chronomap: no `ros__parameters`"));
    assert!(error("bad name:\n  ros__parameters: {}\n").contains("is not a valid node name"));
    let twice = error("a:\n  ros__parameters: {}\na:\n  ros__parameters: {}\n");
    assert!(twice.contains("the key `a` appears twice"), "{twice}");
}

#[test]
fn topics_resolve_as_ros_2_resolves_them() {
    assert_eq!(resolve_topic("/a/b", "/ns", "/ns/n").unwrap(), "/a/b");
    assert_eq!(resolve_topic("a/b", "/ns", "/ns/n").unwrap(), "/ns/a/b");
    assert_eq!(resolve_topic("a", "/", "/n").unwrap(), "/a");
    assert_eq!(resolve_topic("~/a", "/ns", "/ns/n").unwrap(), "/ns/n/a");
    for bad in ["", "~", "/", "a/", "a b", "{x}", "/a__b", "~a"] {
        assert!(resolve_topic(bad, "/", "/n").is_err(), "{bad:?}");
    }
}

#[test]
fn files_that_are_not_parameter_files_are_refused_by_name() {
    let dir = chronomap_testutil::fresh_dir(
        std::env::temp_dir().join(format!("chronomap-ros2-config-{}", std::process::id())),
    );
    let missing = NodeConfig::read(&dir.join("none.yaml"), None).unwrap_err();
    assert!(
        missing
            .to_string()
            .starts_with(&format!("{}: cannot read", dir.join("none.yaml").display()))
    );
    let big =
        chronomap_testutil::write(&dir, "big.yaml", vec![b'#'; (MAX_FILE_BYTES + 1) as usize]);
    assert!(
        NodeConfig::read(&big, None)
            .unwrap_err()
            .to_string()
            .contains("larger than 1048576 bytes")
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn ros_arguments_rename_remap_and_override_the_file() {
    let file = ParamFile::parse(
        Path::new("cfg/node.yaml"),
        b"chronomap:\n  ros__parameters:\n    horizon: 5\n    states:\n      door: {topic: door, type: std_msgs/msg/Bool}\n",
    )
    .unwrap();
    let args = RosArgs::parse([
        "--ros-args",
        "-r",
        "__ns:=/r2",
        "-r",
        "/r2/door:=/front",
        "-p",
        "horizon:=7.5",
        "-p",
        "other:horizon:=1.0",
        "-p",
        "chronomap:states.door.model:=hist:24",
    ])
    .unwrap();
    let setup = Setup::from_file(&file, None, args).unwrap();
    let c = setup.config().unwrap();
    assert_eq!(c.fully_qualified_name(), "/r2/chronomap");
    assert_eq!(c.horizon, 7.5);
    assert_eq!(c.states[0].topic, "/front");
    assert_eq!(c.states[0].model.to_string(), "hist:24");
    assert_eq!(
        c.states[0].probability_topic,
        "/r2/chronomap/door/probability"
    );
    // The declared parameters: every one, defaults filled in, names resolved.
    let declared: BTreeMap<String, Value> = c.parameters().into_iter().collect();
    assert_eq!(declared.len(), 20);
    assert_eq!(declared["memory_limit"], Value::Integer(4 << 30));
    assert_eq!(declared["days_off_file"], Value::String(String::new()));
    assert_eq!(declared["horizon"], Value::Double(7.5));
    assert_eq!(declared["sync_period"], Value::Double(1.0));
    assert_eq!(declared["sync_messages"], Value::Integer(1000));
    assert_eq!(declared["publish_period"], Value::Double(1.0));
    assert_eq!(
        declared["states.door.topic"],
        Value::String("/front".into())
    );
    assert_eq!(declared["states.door.depth"], Value::Integer(100));
    // Errors name the argument, or set_parameters, and the parameter.
    let bad = RosArgs::parse(["--ros-args", "-p", "horizon:=-1"]).unwrap();
    let error = Setup::from_file(&file, None, bad)
        .unwrap()
        .config()
        .unwrap_err();
    assert_eq!(
        error.to_string(),
        "-p horizon:=-1: horizon: -1 is not a finite number of seconds >= 0"
    );
    let e = setup
        .config_with("publish_period", &Value::String("x".into()), false)
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "set_parameters: publish_period: expected a number, found the string \"x\""
    );
    let later = setup
        .config_with("publish_period", &Value::Integer(2), false)
        .unwrap();
    assert_eq!(later.publish_period, 2.0);
    assert!(is_dynamic("publish_period") && is_dynamic("maps.office.filter_base"));
    assert!(!is_dynamic("states.door.model") && !is_dynamic("use_sim_time"));
    // Without a file: `chronomap`, in `/`; empty parameters are refused unless managed.
    let empty = Setup::new(None, None, RosArgs::default()).unwrap();
    assert!(
        empty
            .config()
            .unwrap_err()
            .to_string()
            .contains("nothing to do")
    );
    assert_eq!(
        empty
            .config_allowing_empty()
            .unwrap()
            .fully_qualified_name(),
        "/chronomap"
    );
}

#[test]
fn several_models_learn_one_state_topic() {
    let config = NodeConfig::parse(
        Path::new("cfg/node.yaml"),
        b"chronomap:\n  ros__parameters:\n    states:\n      door: {topic: /door, type: std_msgs/msg/Bool}\n      door_daily: {topic: /door, type: std_msgs/msg/Bool, model: \"hist:24\", prediction_topic: \"\"}\n",
        None,
    )
    .unwrap();
    let topics: Vec<(&str, &str)> = config
        .states
        .iter()
        .map(|s| (s.name.as_str(), s.topic.as_str()))
        .collect();
    assert_eq!(topics, [("door", "/door"), ("door_daily", "/door")]);
    assert_eq!(config.states[1].model.to_string(), "hist:24");
    assert_eq!(
        config.states[0].prediction_topic.as_deref(),
        Some("/chronomap/door/prediction")
    );
    assert_eq!(config.states[1].prediction_topic, None);
    let outputs: Vec<String> = config.outputs().into_iter().map(|(t, _)| t).collect();
    assert_eq!(
        outputs,
        [
            "/chronomap/door/probability",
            "/chronomap/door/entropy",
            "/chronomap/door/prediction",
            "/chronomap/door_daily/probability",
            "/chronomap/door_daily/entropy",
        ]
    );
}

/// A `save_dir` that cannot hold the models is refused when the configuration is checked
/// (`--check`, start-up), naming file, line and parameter; before, it was found at the first
/// save, losing everything learned until then.
#[test]
fn a_save_dir_that_cannot_hold_the_models_is_refused_at_once() {
    let dir = std::env::temp_dir().join(format!("chronomap-ros2-save-dir-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("a_file"), "x").unwrap();
    let config = dir.join("node.yaml");
    let check = |save_dir: &str| {
        let text = format!(
            "chronomap:\n  ros__parameters:\n    save_dir: {save_dir}\n    states:\n      \
             door: {{topic: /door, type: std_msgs/msg/Bool}}\n"
        );
        NodeConfig::parse(&config, text.as_bytes(), None).map(|c| c.save_dir)
    };
    let at = format!("{}:3: save_dir: ", config.display());
    assert_eq!(
        check("a_file").unwrap_err().to_string(),
        format!(
            "{at}{} is a file, not a folder",
            dir.join("a_file").display()
        )
    );
    assert_eq!(
        check("a_file/models").unwrap_err().to_string(),
        format!(
            "{at}{} cannot be created: {} is a file, not a folder",
            dir.join("a_file/models").display(),
            dir.join("a_file").display()
        )
    );
    for kernel in ["/proc", "/sys", "/dev"] {
        let path = format!("{kernel}/chronomap");
        assert_eq!(
            check(&path).unwrap_err().to_string(),
            format!(
                "{at}{path} is under {kernel}, a file system of the kernel: the models cannot \
                 be saved there"
            )
        );
    }
    // A folder that exists, or can be created, is accepted; the probe leaves nothing behind.
    assert_eq!(check("."), Ok(Some(dir.join("."))));
    assert_eq!(check("new/models"), Ok(Some(dir.join("new/models"))));
    assert!(!dir.join("new").exists(), "checking creates no folder");
    let mut left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["a_file"]);
    std::fs::remove_dir_all(dir).unwrap();
}

/// `edges.models` (read at start) and `edges.geojson` (written) are checked with the
/// configuration (`--check`, start-up), naming file, line and parameter; before, a missing
/// models file passed `--check` and stopped the node at start naming only the file, and a
/// route graph that could not be written was found at the first rewrite.
#[test]
fn edge_files_that_cannot_be_read_or_written_are_refused_at_once() {
    let dir = std::env::temp_dir().join(format!("chronomap-ros2-edges-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("a_folder")).unwrap();
    std::fs::write(dir.join("witham.cmt"), "models").unwrap();
    std::fs::write(dir.join("a_file"), "x").unwrap();
    let config = dir.join("node.yaml");
    let check = |models: &str, geojson: &str| {
        let text = format!(
            "chronomap:\n  ros__parameters:\n    edges:\n      models: {models}\n      \
             geojson: {geojson}\n"
        );
        NodeConfig::parse(&config, text.as_bytes(), None)
            .map(|c| c.edges.map(|e| (e.models, e.geojson)))
            .map_err(|e| e.to_string())
    };
    let file = config.display();
    assert_eq!(
        check("witham.cmt", "route.geojson"),
        Ok(Some((dir.join("witham.cmt"), dir.join("route.geojson"))))
    );
    assert_eq!(
        check("missing.cmt", "route.geojson").unwrap_err(),
        format!(
            "{file}:4: edges.models: cannot read {}: No such file or directory (os error 2)",
            dir.join("missing.cmt").display()
        )
    );
    for models in ["a_folder", "/dev/zero"] {
        let shown = if models.starts_with('/') {
            models.into()
        } else {
            dir.join(models).display().to_string()
        };
        assert_eq!(
            check(models, "route.geojson").unwrap_err(),
            format!(
                "{file}:4: edges.models: {shown} is not a regular file (a directory, a device \
                 or a pipe)"
            )
        );
    }
    assert_eq!(
        check("witham.cmt", "a_folder").unwrap_err(),
        format!(
            "{file}:5: edges.geojson: {} is not a regular file (a directory, a device or a \
             pipe): it would not be replaced",
            dir.join("a_folder").display()
        )
    );
    assert_eq!(
        check("witham.cmt", "out/route.geojson").unwrap_err(),
        format!(
            "{file}:5: edges.geojson: its folder {}: No such file or directory (os error 2)",
            dir.join("out").display()
        )
    );
    assert_eq!(
        check("witham.cmt", "a_file/route.geojson").unwrap_err(),
        format!(
            "{file}:5: edges.geojson: {} is not a folder",
            dir.join("a_file").display()
        )
    );
    assert_eq!(
        check("witham.cmt", "/proc/route.geojson").unwrap_err(),
        format!(
            "{file}:5: edges.geojson: /proc/route.geojson is under /proc, a file system of the \
             kernel: nothing is written there"
        )
    );
    // The text alone is accepted by `parse_text`, which looks at no file.
    let text = "chronomap:\n  ros__parameters:\n    edges: {models: missing.cmt, geojson: \
                out/route.geojson}\n    save_dir: /proc/x\n";
    let c = NodeConfig::parse_text(&config, text.as_bytes(), None).unwrap();
    assert_eq!(c.edges.unwrap().models, dir.join("missing.cmt"));
    // Nothing was left behind by the probes.
    let mut left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["a_file", "a_folder", "witham.cmt"]);
    std::fs::remove_dir_all(dir).unwrap();
}

/// `days_off_file` is read with the configuration (`--check`, start-up, configure): a date
/// that is not one is refused naming the parameter file, line and parameter, and the
/// calendar's file and line; "" is no calendar; `parse_text` reads no file.
#[test]
fn a_days_off_file_is_read_with_the_configuration_and_a_bad_one_is_refused() {
    let dir = std::env::temp_dir().join(format!("chronomap-ros2-days-off-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("a_folder")).unwrap();
    std::fs::write(
        dir.join("uk.txt"),
        "# England\n2016-03-25 Good Friday\n2016-03-28\n",
    )
    .unwrap();
    std::fs::write(dir.join("bad.txt"), "2016-03-25\n2016-02-30 nope\n").unwrap();
    let config = dir.join("node.yaml");
    let text = |file: &str| {
        format!(
            "chronomap:\n  ros__parameters:\n    days_off_file: {file}\n    states:\n      \
             door: {{topic: /door, type: std_msgs/msg/Bool}}\n"
        )
    };
    let check = |file: &str| {
        NodeConfig::parse(&config, text(file).as_bytes(), None).map_err(|e| e.to_string())
    };
    let c = check("uk.txt").unwrap();
    assert_eq!(c.days_off_file, Some(dir.join("uk.txt")));
    assert_eq!(c.days_off.len(), 2);
    let declared: BTreeMap<String, Value> = c.parameters().into_iter().collect();
    assert_eq!(
        declared["days_off_file"],
        Value::String(dir.join("uk.txt").display().to_string())
    );
    assert!(!is_dynamic("days_off_file"));
    assert!(description("days_off_file").contains("days off"));
    let none = check("\"\"").unwrap();
    assert_eq!((none.days_off_file, none.days_off.len()), (None, 0));
    let at = format!("{}:3: days_off_file: ", config.display());
    assert_eq!(
        check("bad.txt").unwrap_err(),
        format!(
            "{at}{}:2: date: \"2016-02-30\" is not a date YYYY-MM-DD",
            dir.join("bad.txt").display()
        )
    );
    assert_eq!(
        check("missing.txt").unwrap_err(),
        format!(
            "{at}cannot read {}: No such file or directory (os error 2)",
            dir.join("missing.txt").display()
        )
    );
    assert_eq!(
        check("a_folder").unwrap_err(),
        format!(
            "{at}{} is not a regular file (a directory, a device or a pipe)",
            dir.join("a_folder").display()
        )
    );
    // The text alone names the file and reads nothing.
    let c = NodeConfig::parse_text(&config, text("missing.txt").as_bytes(), None).unwrap();
    assert_eq!(c.days_off_file, Some(dir.join("missing.txt")));
    assert!(c.days_off.is_empty());
    std::fs::remove_dir_all(dir).unwrap();
}
