//! docs/limits.md states every input limit; this checks that each number there is the one in
//! the code, so that the page cannot drift from what the readers do.

/// Formats an integer with thousands separators, as docs/limits.md writes it.
fn grouped(n: u128) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[test]
fn every_limit_in_docs_limits_is_the_one_in_the_code() {
    let doc = include_str!("../../docs/limits.md");
    // (constant as the page names it, the module in its `where` column, value)
    let mut limits: Vec<(&str, &str, u128)> = vec![
        (
            "MAX_FILE_BYTES",
            "`chronomap_io`",
            chronomap_io::MAX_FILE_BYTES.into(),
        ),
        (
            "MAX_LINE_BYTES",
            "chronomap_io::text",
            chronomap_io::text::MAX_LINE_BYTES as u128,
        ),
        (
            "MAX_DECOMPRESSED_BYTES",
            "chronomap_io::text",
            chronomap_io::text::MAX_DECOMPRESSED_BYTES.into(),
        ),
        (
            "MAX_IMAGE_BYTES",
            "chronomap_io::navmap",
            chronomap_io::navmap::MAX_IMAGE_BYTES.into(),
        ),
        (
            "MAX_MAP_CELLS",
            "chronomap_io::navmap",
            chronomap_io::navmap::MAX_MAP_CELLS.into(),
        ),
        (
            "MAX_KIND_LEN",
            "chronomap_io::model_file",
            chronomap_io::model_file::MAX_KIND_LEN as u128,
        ),
        (
            "MAX_TIME_SECS",
            "chronomap_core",
            chronomap_core::observe::MAX_TIME_SECS as u128,
        ),
        (
            "MAX_BYTES",
            "chronomap_io::bt_xml",
            chronomap_io::bt_xml::MAX_BYTES.into(),
        ),
        (
            "MAX_FILES",
            "chronomap_io::bt_xml",
            chronomap_io::bt_xml::MAX_FILES as u128,
        ),
        (
            "MAX_DEPTH",
            "chronomap_io::bt_xml",
            chronomap_io::bt_xml::MAX_DEPTH as u128,
        ),
        (
            "MAX_NODES",
            "chronomap_io::bt_xml",
            chronomap_io::bt_xml::MAX_NODES.into(),
        ),
        (
            "MAX_ATTRIBUTES",
            "chronomap_io::bt_xml",
            chronomap_io::bt_xml::MAX_ATTRIBUTES as u128,
        ),
        (
            "MAX_DEPTH",
            "chronomap_bt::runtime",
            chronomap_bt::runtime::MAX_DEPTH as u128,
        ),
        (
            "MAX_NESTING",
            "chronomap_bt::scripting",
            chronomap_bt::scripting::MAX_NESTING as u128,
        ),
        (
            "MAX_DEPTH",
            "chronomap_topo::ltl",
            chronomap_topo::ltl::MAX_DEPTH as u128,
        ),
        (
            "MAX_STATES",
            "chronomap_topo::ltl",
            chronomap_topo::ltl::MAX_STATES as u128,
        ),
        (
            "MAX_CLAUSES",
            "chronomap_topo::ltl",
            chronomap_topo::ltl::MAX_CLAUSES as u128,
        ),
        (
            "MAX_STRESS_NODES",
            "chronomap_topo::layout",
            chronomap_topo::layout::MAX_STRESS_NODES as u128,
        ),
        (
            "DEFAULT_MAX_CELLS",
            "chronomap_topo::deadline",
            chronomap_topo::deadline::DEFAULT_MAX_CELLS as u128,
        ),
        (
            "MAX_PERIODS",
            "chronomap_core::periods",
            chronomap_core::periods::MAX_PERIODS as u128,
        ),
        (
            "MAX_BINS",
            "chronomap_core::hist",
            chronomap_core::hist::MAX_BINS as u128,
        ),
        (
            "MAX_CYCLES",
            "chronomap_core::recent",
            chronomap_core::recent::MAX_CYCLES as u128,
        ),
        (
            "MAX_RECENT_DAYS",
            "chronomap_models::stack",
            chronomap_models::stack::MAX_RECENT_DAYS as u128,
        ),
        (
            "MAX_COMPONENTS",
            "chronomap_core::pergam",
            chronomap_core::pergam::MAX_COMPONENTS as u128,
        ),
        (
            "MAX_LEN",
            "chronomap_core::fft",
            chronomap_core::fft::MAX_LEN.into(),
        ),
        (
            "MAX_CELLS",
            "`chronomap_grid`",
            chronomap_grid::MAX_CELLS as u128,
        ),
        (
            "MAX_REGION_CELLS",
            "chronomap_activity::grids",
            chronomap_activity::grids::MAX_REGION_CELLS as u128,
        ),
        (
            "MAX_COUNT",
            "chronomap_psbt::world",
            chronomap_psbt::world::MAX_COUNT as u128,
        ),
        (
            "MAX_SAMPLES",
            "chronomap_psbt::path",
            chronomap_psbt::path::MAX_SAMPLES as u128,
        ),
        (
            "MAX_STEPS_PER_DAY",
            "`chronomap_explore`",
            chronomap_explore::MAX_STEPS_PER_DAY as u128,
        ),
        (
            "MAX_VERTICES",
            "chronomap_io::ply",
            chronomap_io::ply::MAX_VERTICES.into(),
        ),
        (
            "MAX_ELEMENT_COUNT",
            "chronomap_io::ply",
            chronomap_io::ply::MAX_ELEMENT_COUNT.into(),
        ),
        (
            "MAX_HEADER_BYTES",
            "chronomap_io::ply",
            chronomap_io::ply::MAX_HEADER_BYTES as u128,
        ),
        (
            "MAX_LINE_BYTES",
            "chronomap_io::ply",
            chronomap_io::ply::MAX_LINE_BYTES as u128,
        ),
        (
            "MAX_LINE_BYTES",
            "chronomap_io::laser_text",
            chronomap_io::laser_text::MAX_LINE_BYTES as u128,
        ),
        (
            "MAX_BEAMS",
            "chronomap_lidar::scan",
            chronomap_lidar::scan::MAX_BEAMS as u128,
        ),
        (
            "MAX_LENGTH_M",
            "chronomap_io::laser_text",
            chronomap_io::laser_text::MAX_LENGTH_M as u128,
        ),
        (
            "MAX_ANGLE_RAD",
            "chronomap_io::laser_text",
            chronomap_io::laser_text::MAX_ANGLE_RAD as u128,
        ),
        (
            "MAX_POINTS",
            "chronomap_registration::cloud",
            chronomap_registration::cloud::MAX_POINTS as u128,
        ),
        (
            "MAX_FEATURE_POINTS",
            "chronomap_registration::pipeline",
            chronomap_registration::pipeline::MAX_FEATURE_POINTS as u128,
        ),
        (
            "MAX_ICP_POINTS",
            "chronomap_registration::pipeline",
            chronomap_registration::pipeline::MAX_ICP_POINTS as u128,
        ),
        (
            "MAX_INPUT_POINTS",
            "chronomap_registration::pipeline",
            chronomap_registration::pipeline::MAX_INPUT_POINTS as u128,
        ),
        (
            "MAX_TRAININGS",
            "chronomap_lidar::evaluation",
            chronomap_lidar::evaluation::MAX_TRAININGS as u128,
        ),
        (
            "MAX_BOOSTING_ROUNDS",
            "chronomap_lidar::evaluation",
            chronomap_lidar::evaluation::MAX_BOOSTING_ROUNDS as u128,
        ),
        (
            "MAX_RECORD_BYTES",
            "chronomap_rosbag::bag",
            chronomap_rosbag::bag::MAX_RECORD_BYTES as u128,
        ),
        (
            "MAX_DECOMPRESSED_BYTES",
            "chronomap_rosbag::bag",
            chronomap_rosbag::bag::MAX_DECOMPRESSED_BYTES as u128,
        ),
        (
            "MAX_DEFINITION_BYTES",
            "chronomap_rosbag::bag",
            chronomap_rosbag::bag::MAX_DEFINITION_BYTES as u128,
        ),
        (
            "MAX_NAME_BYTES",
            "chronomap_rosbag::bag",
            chronomap_rosbag::bag::MAX_NAME_BYTES as u128,
        ),
        (
            "MAX_METADATA_BYTES",
            "chronomap_rosbag::bag",
            chronomap_rosbag::bag::MAX_METADATA_BYTES.into(),
        ),
        (
            "METADATA_VERSIONS",
            "chronomap_rosbag::bag",
            (*chronomap_rosbag::bag::METADATA_VERSIONS.end()).into(),
        ),
        (
            "MAX_MAP_CELLS",
            "chronomap_rosbag::records",
            chronomap_rosbag::records::MAX_MAP_CELLS.into(),
        ),
        (
            "MAX_DEPTH",
            "chronomap_rosbag::msgdef",
            chronomap_rosbag::msgdef::MAX_DEPTH as u128,
        ),
        (
            "MAX_FIELDS",
            "chronomap_rosbag::msgdef",
            chronomap_rosbag::msgdef::MAX_FIELDS as u128,
        ),
        (
            "VALUES_PER_BYTE",
            "chronomap_rosbag::cdr",
            chronomap_rosbag::cdr::VALUES_PER_BYTE as u128,
        ),
        (
            "MAX_VALUES",
            "chronomap_rosbag::cdr",
            chronomap_rosbag::cdr::MAX_VALUES as u128,
        ),
        (
            "MAX_REQUEST_PART_SIZE",
            "chronomap_groot2::protocol",
            chronomap_groot2::protocol::MAX_REQUEST_PART_SIZE as u128,
        ),
        (
            "MAX_REQUEST_PARTS",
            "chronomap_groot2::protocol",
            chronomap_groot2::protocol::MAX_REQUEST_PARTS as u128,
        ),
        (
            "MAX_MSGPACK_DEPTH",
            "chronomap_groot2::protocol",
            chronomap_groot2::protocol::MAX_MSGPACK_DEPTH as u128,
        ),
        (
            "MAX_RECORDED_TRANSITIONS",
            "chronomap_groot2::protocol",
            chronomap_groot2::protocol::MAX_RECORDED_TRANSITIONS as u128,
        ),
        (
            "DEFAULT_MAX_HEARTBEAT_DELAY",
            "chronomap_groot2::publisher",
            chronomap_groot2::publisher::DEFAULT_MAX_HEARTBEAT_DELAY.as_millis(),
        ),
        (
            "DEFAULT_MAX_REPLY_BYTES",
            "chronomap_groot2::client",
            chronomap_groot2::client::DEFAULT_MAX_REPLY_BYTES as u128,
        ),
        (
            "MAX_REPLY_PARTS",
            "chronomap_groot2::client",
            chronomap_groot2::client::MAX_REPLY_PARTS as u128,
        ),
        (
            "MAX_XML_NODES",
            "chronomap_groot2::client",
            chronomap_groot2::client::MAX_XML_NODES.into(),
        ),
        (
            "DEFAULT_TIMEOUT",
            "chronomap_groot2::client",
            chronomap_groot2::client::DEFAULT_TIMEOUT.as_secs().into(),
        ),
    ];
    #[cfg(feature = "ros2")]
    limits.push((
        "SCAN_CHUNK",
        "chronomap_ros2::journal",
        chronomap_ros2::journal::SCAN_CHUNK as u128,
    ));
    #[cfg(feature = "serve")]
    limits.extend([
        (
            "DEFAULT_MAX_BODY_BYTES",
            "chronomap_serve::server",
            chronomap_serve::server::DEFAULT_MAX_BODY_BYTES as u128,
        ),
        (
            "MAX_ID_BYTES",
            "chronomap_client::api",
            chronomap_client::api::MAX_ID_BYTES as u128,
        ),
        (
            "MAX_RESPONSE_BYTES",
            "`chronomap_client` `http`",
            chronomap_client::MAX_RESPONSE_BYTES as u128,
        ),
        (
            "MAX_PLAN_TIMES",
            "chronomap_serve::maps",
            chronomap_serve::maps::MAX_PLAN_TIMES as u128,
        ),
        (
            "MAX_DEADLINE_CELLS",
            "chronomap_serve::maps",
            chronomap_serve::maps::MAX_DEADLINE_CELLS as u128,
        ),
        (
            "MAX_DEADLINE_SECS",
            "chronomap_serve::maps",
            chronomap_serve::maps::MAX_DEADLINE_SECS as u128,
        ),
        (
            "MAX_CELL_TIMES",
            "chronomap_serve::maps",
            chronomap_serve::maps::MAX_CELL_TIMES as u128,
        ),
        (
            "MAX_ACTIVITY_CELLS",
            "chronomap_serve::maps",
            chronomap_serve::maps::MAX_ACTIVITY_CELLS as u128,
        ),
        (
            "PREDICT_CHUNK",
            "chronomap_serve::maps",
            chronomap_serve::maps::PREDICT_CHUNK as u128,
        ),
        (
            "DEFAULT_HEAVY_QUEUE",
            "chronomap_serve::heavy",
            chronomap_serve::heavy::DEFAULT_HEAVY_QUEUE as u128,
        ),
        (
            "DEFAULT_LIGHT_QUEUE",
            "chronomap_serve::heavy",
            chronomap_serve::heavy::DEFAULT_LIGHT_QUEUE as u128,
        ),
        (
            "LIGHT_MAX_PREDICTIONS",
            "chronomap_serve::heavy",
            chronomap_serve::heavy::LIGHT_MAX_PREDICTIONS.into(),
        ),
        (
            "LIGHT_MAX_BODY_BYTES",
            "chronomap_serve::heavy",
            chronomap_serve::heavy::LIGHT_MAX_BODY_BYTES as u128,
        ),
        (
            "MAX_REQUEST_PREDICTIONS",
            "chronomap_serve::server",
            chronomap_serve::server::MAX_REQUEST_PREDICTIONS.into(),
        ),
        (
            "MODEL_CHUNK",
            "chronomap_serve::server",
            chronomap_serve::server::MODEL_CHUNK as u128,
        ),
        (
            "MAX_ACTIVITY_WORK",
            "chronomap_serve::maps",
            chronomap_serve::maps::MAX_ACTIVITY_WORK.into(),
        ),
        (
            "RETRY_AFTER_SECS",
            "chronomap_serve::heavy",
            chronomap_serve::heavy::RETRY_AFTER_SECS.into(),
        ),
    ]);
    for (name, module, value) in limits {
        let row = doc
            .lines()
            .find(|l| l.starts_with(&format!("| `{name}`")) && l.contains(module))
            .unwrap_or_else(|| panic!("docs/limits.md has no row for {name} in {module}"));
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        assert!(
            cells[2].starts_with(&grouped(value)),
            "docs/limits.md says {name} ({module}) is {:?}, the code {}",
            cells[2],
            grouped(value)
        );
    }
}
