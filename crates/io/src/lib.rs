//! # chronomap-io
//!
//! The edge of chronomap: everything that touches files. Dataset readers, versioned model
//! files, ROS maps and behavior trees, around the pure algorithms of [`chronomap_core`].
//!
//! ```
//! use chronomap_core::{FremenModel, TemporalModel};
//! use chronomap_io::read_pairs_from;
//!
//! // A door observed every 6 hours for two weeks (`time value` lines, as in the datasets):
//! // open (1) at 12:00, closed (0) at 0:00, 6:00 and 18:00.
//! let mut text = String::from("# unix seconds, state\n");
//! for i in 0..56 {
//!     let t = 1_451_865_600 + 6 * 3600 * i;
//!     text.push_str(&format!("{t} {}\n", u8::from(i % 4 == 2)));
//! }
//! let door = read_pairs_from("door.txt", text.as_bytes())?;
//! assert_eq!(door.len(), 56);
//!
//! let mut model = FremenModel::with_order(1);
//! model.observe(&door.times, &door.values)?;
//! let noon_next_week = 1_451_865_600.0 + 14.0 * 86_400.0 + 12.0 * 3600.0;
//! assert!(model.predict(noon_next_week) > 0.5);
//!
//! // Bad lines are reported with file, line and field, never silently skipped.
//! let err = read_pairs_from("door.txt", "0 1\n60 yes\n".as_bytes()).unwrap_err();
//! assert_eq!(err.to_string(), r#"door.txt:2: value: "yes" is not a number"#);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! ## Layout: a folder per cargo feature
//! | feature (folder) | modules: what they read and write |
//! |---|---|
//! | always (top level) | [`text`]: `time value` door files and test sets, plain, `.xz` or `.gz` ([`read_pairs`], [`read_test_set`]); [`model_file`]: a versioned, checksummed header and a postcard payload, written atomically ([`write_model_file`], [`read_model_file`]); [`matrix`]: state matrices; [`output`]: the one safe writer of outputs |
//! | `activity` | [`activity`]: activity-rate grids of CoPA-Map, CSV `x1,x2,t,y`; [`rate_predictions`]; [`tracks`]: pedestrian tracks; [`robot_paths`]: patrol loops; [`scenarios`]: service-disturbance patrols |
//! | `bt` | [`bt_xml`]: BehaviorTree.CPP 4 XML; [`bt_log`]: Groot2 `.btlog`; [`bt_script`]: scripted leaf outcomes; [`sbt_params`]: stochastic leaf parameters; [`monitor_faults`]: injected faults; their line errors ([`line_error::LineError`]) |
//! | `grid` | [`grid_file`]: grid files of every kind ([`read_grid_file`]) |
//! | `hypertime` | [`events`]: people detected at `t x y` ([`read_events`]) |
//! | `lidar` | [`laser_text`]: 2-D laser logs, keyframes and odometry as text; [`ply`]: point clouds, ASCII or binary |
//! | `navmap` | [`navmap`]: ROS 1 `map_server` and Nav2 maps, YAML with PGM or PNG ([`load_map`], [`save_map`]); [`frame_list`]: the `<time> <map.yaml>` lists grids are built from |
//! | `psbt` | [`psbt_xml`]: person search trees as BehaviorTree.CPP XML |
//! | `topo` | [`topo_files`]: edge statistics of `<From>_<To>.data` directories, STRANDS / LCAS `tmap2` maps, Nav2 route-server GeoJSON |
//!
//! Everything read satisfies the [observation contract](chronomap_core::observe) or is refused
//! with an error naming the file, line and field (or header, vertex, key, attribute).
//! Errors are concrete types with a matchable kind ([`DataErrorKind`], [`ModelFileErrorKind`],
//! [`NavMapErrorKind`], [`TopoFileErrorKind`]); their messages are complete on their own (they do
//! not repeat through [`std::error::Error::source`]).
#![deny(missing_docs)]

// Shared by every feature: bounded reads, atomic writes, text and model files, calendars.
mod atomic;
mod bounded;
pub use bounded::{MAX_FILE_BYTES, read_regular_at_most};
pub mod days_off;
pub use days_off::{read_days_off, read_days_off_from};
pub mod matrix;
pub mod model_file;
pub mod output;
pub mod text;
#[cfg(any(feature = "navmap", feature = "topo"))]
mod yaml;

// Feature `activity`: the files in `activity/`.
#[cfg(feature = "activity")]
#[path = "activity/activity.rs"]
pub mod activity;
#[cfg(feature = "activity")]
#[path = "activity/rate_predictions.rs"]
pub mod rate_predictions;
#[cfg(feature = "activity")]
#[path = "activity/robot_paths.rs"]
pub mod robot_paths;
#[cfg(feature = "activity")]
#[path = "activity/scenarios.rs"]
pub mod scenarios;
#[cfg(feature = "activity")]
#[path = "activity/tracks.rs"]
pub mod tracks;

// Feature `bt`: the files in `bt/`.
#[cfg(feature = "bt")]
#[path = "bt/bt_log.rs"]
pub mod bt_log;
#[cfg(feature = "bt")]
#[path = "bt/bt_script.rs"]
pub mod bt_script;
#[cfg(feature = "bt")]
#[path = "bt/bt_xml.rs"]
pub mod bt_xml;
#[cfg(feature = "bt")]
#[path = "bt/line_error.rs"]
pub mod line_error;
#[cfg(feature = "bt")]
#[path = "bt/monitor_faults.rs"]
pub mod monitor_faults;
#[cfg(feature = "bt")]
#[path = "bt/sbt_params.rs"]
pub mod sbt_params;

// Feature `grid`: the files in `grid/`.
#[cfg(feature = "grid")]
#[path = "grid/grid_file.rs"]
pub mod grid_file;

// Feature `hypertime`: the files in `hypertime/`.
#[cfg(feature = "hypertime")]
#[path = "hypertime/events.rs"]
pub mod events;

// Feature `lidar`: the files in `lidar/`.
#[cfg(feature = "lidar")]
#[path = "lidar/laser_text.rs"]
pub mod laser_text;
#[cfg(feature = "lidar")]
#[path = "lidar/ply.rs"]
pub mod ply;

// Feature `navmap`: the files in `navmap/`.
#[cfg(feature = "navmap")]
#[path = "navmap/frame_list.rs"]
pub mod frame_list;
#[cfg(feature = "navmap")]
#[path = "navmap/navmap.rs"]
pub mod navmap;
#[cfg(all(feature = "navmap", feature = "activity"))]
#[path = "navmap/navmap_obstacles.rs"]
mod navmap_obstacles;

// Feature `psbt`: the files in `psbt/`.
#[cfg(feature = "psbt")]
#[path = "psbt/psbt_xml.rs"]
pub mod psbt_xml;

// Feature `topo`: the files in `topo/`.
#[cfg(feature = "topo")]
#[path = "topo/topo_files.rs"]
pub mod topo_files;

#[cfg(feature = "activity")]
pub use activity::{
    COPA_MAP_KIND, LOG_ADDITIVE_KIND, RateGrid, encode_rate_samples, format_rate_grid,
    read_copa_map, read_rate_grid, read_rate_grid_from, read_rate_samples, read_rate_samples_from,
    write_copa_map, write_rate_grid, write_rate_samples,
};
#[cfg(feature = "bt")]
pub use bt_log::{BtLogError, BtLogErrorKind, read_btlog, write_btlog};
#[cfg(feature = "bt")]
pub use bt_script::{BtScriptError, parse_bt_script, read_bt_script};
#[cfg(feature = "bt")]
pub use bt_xml::{
    BtNodeModels, BtReadOptions, BtXml, BtXmlError, BtXmlErrorKind, encode_bt_xml, parse_bt_xml,
    parse_bt_xml_in, read_bt_xml, read_bt_xml_with, read_node_models, write_bt_xml,
};
#[cfg(feature = "hypertime")]
pub use events::{read_event_files, read_events, read_events_from, write_events};
#[cfg(feature = "navmap")]
pub use frame_list::{
    Frame, FrameMapError, load_frame_map, load_next_frame_map, read_frame_list,
    read_frame_list_from,
};
#[cfg(feature = "grid")]
pub use grid_file::{
    GRID_STATE_FORMAT, decode_grid, encode_grid, encode_grid_state, grid_kind, read_grid_file,
    write_grid_file, write_grid_state,
};
#[cfg(feature = "lidar")]
pub use laser_text::{
    Keyframe, LaserScan, LaserTextError, OdometryIncrement, SensorPose, read_keyframes,
    read_odometry, read_scans,
};
pub use matrix::{read_state_matrix, read_state_matrix_from};
#[cfg(feature = "topo")]
pub use model_file::{EDGE_MODELS_KIND, decode_edge_models, read_edge_models, write_edge_models};
pub use model_file::{
    ModelFileError, ModelFileErrorKind, decode_model, decode_model_or_older, encode_model,
    read_model_file, read_model_file_or_older, write_model_file,
};
#[cfg(feature = "models")]
pub use model_file::{decode_any_model, read_any_model, write_any_model};
#[cfg(feature = "bt")]
pub use monitor_faults::{FaultFileError, read_fault_file};
#[cfg(feature = "navmap")]
pub use navmap::{
    LoadSemantics, MapMetadata, MapMode, NavMapError, NavMapErrorKind, SaveOptions, SavedMap,
    decode_map_image, decode_map_yaml, encode_map_image, encode_map_yaml, load_map, read_map_yaml,
    save_map,
};
#[cfg(all(feature = "navmap", feature = "activity"))]
pub use navmap_obstacles::{PlanningMapError, load_planning_grid};
#[cfg(feature = "lidar")]
pub use ply::{PlyError, PlyErrorKind, PlyFormat, decode_ply, encode_ply, read_ply, write_ply};
#[cfg(feature = "activity")]
pub use robot_paths::{NamedRobotPath, read_robot_paths, read_robot_paths_from};
#[cfg(feature = "bt")]
pub use sbt_params::{SbtParamsError, read_leaf_params};
pub use text::{
    DataError, DataErrorKind, Field, decompressing_reader, open_data_file, read_column,
    read_column_from, read_measurements, read_measurements_from, read_pairs, read_pairs_from,
    read_test_set, read_test_set_from, write_data_file,
};
#[cfg(feature = "topo")]
pub use topo_files::{
    EdgeAttempt, NodePose, RouteEdgeMetadata, RouteTimeInterval, Tmap2, TopoFileError,
    TopoFileErrorKind, decode_tmap2, encode_edge_file, encode_route_geojson, encode_tmap2,
    node_poses, read_edge_directory, read_edge_directory_with_nodes, read_edge_file,
    read_edge_file_from, read_edge_files, read_tmap2, write_edge_directory, write_route_geojson,
    write_tmap2,
};
#[cfg(feature = "activity")]
pub use tracks::{
    read_track_files, read_track_point_files, read_track_points, read_tracks, read_tracks_from,
};
