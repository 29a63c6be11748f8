//! The node's parameters, checked completely before the node starts (or, for a managed node,
//! configures). They come from ROS 2 parameter files (`NODE: {ros__parameters: {...}}`, the
//! `--config` file and `--ros-args --params-file` files) and `-p NAME:=VALUE` arguments, in the
//! order rcl applies them ([`crate::params`], [`crate::ros_args`]); topic names are resolved
//! and remapped as rcl does. Every error names where the value came from — the file and line,
//! or the argument — and the parameter (`node.yaml:12: states.door.model: ...`,
//! `node.yaml:9: maps.office.order: expected an integer >= 0, found the string "auto"`). The
//! parameters are described in `docs/ros2.md`.
//!
//! ```
//! use chronomap_ros2::config::{NodeConfig, StateType};
//!
//! let yaml = "chronomap:\n  ros__parameters:\n    states:\n      door:\n        topic: /door\n        type: std_msgs/msg/Bool\n        model: fremen:2\n";
//! let config = NodeConfig::parse("node.yaml".as_ref(), yaml.as_bytes(), None)?;
//! assert_eq!(config.node_name, "chronomap");
//! assert_eq!(config.states[0].topic, "/door");
//! assert_eq!(config.states[0].message, StateType::Bool);
//! assert_eq!(config.states[0].probability_topic, "/chronomap/door/probability");
//!
//! // `auto` keeps the observations and is refitted on them (`refit_observations`,
//! // `refit_period`, or `~/refit`); `keep` is for such models only.
//! let auto = yaml.replace("fremen:2", "auto");
//! let config = NodeConfig::parse("node.yaml".as_ref(), auto.as_bytes(), None)?;
//! assert!(!config.states[0].learns_online());
//! let bad = format!("{yaml}        keep: 1000\n");
//! let error = NodeConfig::parse("node.yaml".as_ref(), bad.as_bytes(), None).unwrap_err();
//! assert!(error.to_string().starts_with("node.yaml:8: states.door.keep: `fremen:2` learns online and is never refitted"));
//! # Ok::<(), chronomap_ros2::config::ConfigError>(())
//! ```

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use chronomap_core::calendar::DaysOff;
use chronomap_core::{FremenConfig, FremenModel, Ordered, PeriodSet};
use chronomap_models::ModelSpec;
use chronomap_models::learner::{DEFAULT_KEEP, Learner, RefitPolicy};

use crate::msgs::{Bool, Float32, Float64, Message, TypeName};
use crate::params::{self, Origin, ParamFile, ParamSet, Value};
use crate::ros_args::{ParamArg, RosArgs};

/// Default of `memory_limit`: 4 GiB of grids.
pub const DEFAULT_MEMORY_LIMIT: u64 = 4 << 30;

/// Default of `max_map_cells`: 2²⁴ cells (a 4096 × 4096 map).
pub const DEFAULT_MAX_MAP_CELLS: u64 = 1 << 24;

/// Largest `max_map_cells` accepted: 2³⁰ cells.
pub const MAX_MAX_MAP_CELLS: u64 = 1 << 30;

/// Most observations a refitted state may keep (2^24: 256 MiB of times and values).
const MAX_KEEP: u64 = 1 << 24;

/// Longest `sync_period` accepted (s).
const MAX_SYNC_PERIOD: f64 = 60.0;

/// Default of `sync_messages`.
const DEFAULT_SYNC_MESSAGES: u64 = 1000;

/// A parameter file that cannot be used: where and why.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigError {
    /// The file.
    pub file: String,
    /// The line of the offending value, when known.
    pub line: Option<u64>,
    /// The parameter (`states.door.model`), when known.
    pub key: Option<String>,
    /// Why.
    pub message: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        f.write_str(": ")?;
        if let Some(key) = &self.key {
            write!(f, "{key}: ")?;
        }
        f.write_str(&self.message)
    }
}

impl std::error::Error for ConfigError {}

/// Which message a state topic carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateType {
    /// `std_msgs/msg/Bool`: false 0, true 1.
    Bool,
    /// `std_msgs/msg/Float32`, a value in [0, 1].
    Float32,
    /// `std_msgs/msg/Float64`, a value in [0, 1].
    Float64,
}

impl StateType {
    /// The ROS type.
    pub fn type_name(self) -> TypeName {
        match self {
            StateType::Bool => Bool::TYPE,
            StateType::Float32 => Float32::TYPE,
            StateType::Float64 => Float64::TYPE,
        }
    }
}

/// Reliability of a subscription.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reliability {
    /// Reliable: matches reliable publishers only; nothing sent is lost.
    Reliable,
    /// Best effort: matches every publisher; samples may be lost.
    BestEffort,
}

/// What the cells of a published map hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapValues {
    /// What `nav2_map_server` publishes for the map `chronomap grid predict` writes (trinary):
    /// 100 occupied (p ≥ 0.65), 0 free (p ≤ 0.196), −1 otherwise and never observed.
    Trinary,
    /// What `nav2_map_server` publishes for the map `chronomap grid predict --mode scale`
    /// writes: a costmap-filter mask, 0..=100 scaled between the thresholds, −1 never observed.
    Scale,
    /// The prediction itself: `round(100 p)`, −1 never observed.
    Probability,
}

/// Subscription settings of an input topic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InputQos {
    /// Reliability.
    pub reliability: Reliability,
    /// Samples kept until the node takes them.
    pub depth: usize,
    /// Whether to ask publishers for samples sent before the node started (transient local).
    pub transient_local: bool,
}

/// A state topic (`states.NAME`).
#[derive(Clone, Debug)]
pub struct StateConfig {
    /// Its name (the key).
    pub name: String,
    /// The topic, fully qualified.
    pub topic: String,
    /// The message type.
    pub message: StateType,
    /// The model learned: online (`fremen:2`, `hist:24`, ...) or refitted on the kept
    /// observations (`auto`, `fremen:auto`, ...; [`chronomap_models::learner`]).
    pub model: ModelSpec,
    /// Observations kept for refits (models fitted on a whole series only).
    pub keep: usize,
    /// When a refitted model is refitted (models fitted on a whole series only).
    pub refit: RefitPolicy,
    /// Subscription settings.
    pub qos: InputQos,
    /// Where p(now + horizon) is published (`std_msgs/msg/Float64`).
    pub probability_topic: String,
    /// Where its entropy in bits is published (`std_msgs/msg/Float64`).
    pub entropy_topic: String,
    /// Where the stamped prediction is published (`chronomap_msgs/msg/Prediction`: the time it
    /// is for, p, entropy, the model), if anywhere.
    pub prediction_topic: Option<String>,
    /// Coverage of the prediction intervals of a state with an interval
    /// ([`StateConfig::has_interval`]): strictly between 0 and 1, [`DEFAULT_COVERAGE`] unless
    /// set.
    pub coverage: f64,
}

/// Coverage of the prediction intervals of continuous states unless `states.NAME.coverage`
/// says otherwise.
pub const DEFAULT_COVERAGE: f64 = 0.9;

impl StateConfig {
    /// The learner of this state having seen nothing.
    pub fn empty_learner(&self) -> Learner {
        self.model
            .learner(self.keep)
            .expect("checked when the configuration was read")
    }

    /// Whether its model learns online (else it is refitted on the kept observations).
    pub fn learns_online(&self) -> bool {
        self.model.online_model().is_ok()
    }

    /// Whether its predictions carry an interval: a continuous state (`Float32`, `Float64`)
    /// whose spec has a second moment ([`ModelSpec::has_second_moment`]: it learns online, or
    /// is `auto`). Such a state keeps a second learner of its spec fed the squared values,
    /// and the interval is the Beta law's of the two moments
    /// ([`chronomap_core::spread::beta_interval`], [Johnson 1995] ch. 25).
    pub fn has_interval(&self) -> bool {
        self.message != StateType::Bool && self.model.has_second_moment()
    }
}

/// Where a grid's frames come from.
#[derive(Clone, Debug, PartialEq)]
pub enum GridSource {
    /// `nav_msgs/msg/OccupancyGrid` messages (`maps.NAME`): each one is a frame at its stamp;
    /// the first fixes the geometry.
    Map,
    /// `geometry_msgs/msg/PoseArray` detections (`people.NAME`) binned into frames on a fixed
    /// grid.
    People {
        /// Cells per row.
        width: u32,
        /// Rows.
        height: u32,
        /// Metres per cell.
        resolution: f64,
        /// `[x, y]` of the corner of cell (0, 0), metres.
        origin: [f64; 2],
        /// Length of a time bin, seconds.
        bin_secs: f64,
    },
}

/// A Nav2 costmap filter fed by a grid's mask.
#[derive(Clone, Debug, PartialEq)]
pub struct FilterConfig {
    /// The mask's topic (scale semantics).
    pub mask_topic: String,
    /// The `nav2_msgs/msg/CostmapFilterInfo` topic.
    pub info_topic: String,
    /// `type` of the filter info.
    pub filter_type: u8,
    /// `base` of the filter info.
    pub base: f32,
    /// `multiplier` of the filter info.
    pub multiplier: f32,
}

/// A grid (`maps.NAME` or `people.NAME`).
#[derive(Clone, Debug)]
pub struct GridEntry {
    /// Its name (the key).
    pub name: String,
    /// Where its frames come from.
    pub source: GridSource,
    /// The input topic, fully qualified.
    pub topic: String,
    /// Subscription settings.
    pub qos: InputQos,
    /// The frame of the input and the published maps.
    pub frame_id: String,
    /// Every cell's FreMEn model (periods; `order` is the order predicted with).
    pub fremen: FremenConfig,
    /// Cell values of the predicted map.
    pub values: MapValues,
    /// Where the predicted map is published.
    pub predicted_topic: String,
    /// The costmap filter, if any.
    pub filter: Option<FilterConfig>,
}

impl GridEntry {
    /// `"maps"` or `"people"`, the section of the parameter file.
    pub fn section(&self) -> &'static str {
        match self.source {
            GridSource::Map => "maps",
            GridSource::People { .. } => "people",
        }
    }
}

/// The Nav2 route graph rewritten with predicted edge costs (`edges`).
#[derive(Clone, Debug, PartialEq)]
pub struct EdgesConfig {
    /// Edge models (`chronomap topo fit`).
    pub models: PathBuf,
    /// The GeoJSON route graph written.
    pub geojson: PathBuf,
    /// Seconds of the node's clock between rewrites.
    pub period: f64,
}

/// The node's parameters, checked.
#[derive(Clone, Debug)]
pub struct NodeConfig {
    /// The parameter file.
    pub file: PathBuf,
    /// The node's name.
    pub node_name: String,
    /// The node's namespace (`/` or `/robot1`).
    pub namespace: String,
    /// Follow `/clock` instead of the system clock.
    pub use_sim_time: bool,
    /// Seconds of the node's clock between publications of the state predictions.
    pub publish_period: f64,
    /// Seconds of the node's clock between publications of the maps.
    pub map_period: f64,
    /// Predictions are for the node's time plus this many seconds.
    pub horizon: f64,
    /// Where the models are saved and restored from.
    pub save_dir: Option<PathBuf>,
    /// Seconds of wall-clock time between saves.
    pub save_period: f64,
    /// Append every learned state observation to `save_dir/states/NAME.txt`.
    pub record_observations: bool,
    /// Longest time (s) a learned message waits before the journal in `save_dir` is synced:
    /// the most a crash can lose.
    pub sync_period: f64,
    /// Learned messages that make a journal sync due at once.
    pub sync_messages: u64,
    /// The calendar of days off (`days_off_file`), if any.
    pub days_off_file: Option<PathBuf>,
    /// Its days: a state observed on one is not learned, and a state's prediction for a time
    /// on one is its prediction at [`DaysOff::stand_in`]. Empty without `days_off_file`, and
    /// when the configuration was checked without its files ([`NodeConfig::parse_text`]).
    pub days_off: DaysOff,
    /// Largest map accepted, in cells.
    pub max_map_cells: u64,
    /// Most heap the grids may hold (bytes): a map whose learning could bring them above it
    /// is refused ([`chronomap_grid::FremenGrid::heap_bound_after_occupancy`]); `None`: no
    /// limit (`memory_limit: 0`).
    pub memory_limit: Option<u64>,
    /// State topics, by name.
    pub states: Vec<StateConfig>,
    /// Grids (maps, then people), by name.
    pub grids: Vec<GridEntry>,
    /// The route graph, if any.
    pub edges: Option<EdgesConfig>,
    /// Where simulated time is read with `use_sim_time` (`/clock`, remapped).
    pub clock_topic: String,
}

/// Where the node's parameters come from and who the node is: what [`NodeConfig`] is checked
/// from, again whenever a parameter changes (`set_parameters`) or a managed node configures.
#[derive(Clone, Debug)]
pub struct Setup {
    /// The node's namespace (`/` or `/robot1`), after `-r __ns:=`.
    pub namespace: String,
    /// The node's name, after `-r __node:=`.
    pub name: String,
    /// The parameters, from every source in order.
    pub params: ParamSet,
    /// The ROS arguments (remap rules apply to every topic and service name).
    pub args: RosArgs,
    /// What errors about no single value name: the `--config` file, else the first
    /// `--params-file`, else `--ros-args`.
    pub source: PathBuf,
}

impl Setup {
    /// The parameters of the node: the `--config` file's entry (the only one, or `node`'s),
    /// then `args`' parameter files and `-p` arguments in order. The node is named by the
    /// entry's key, or `node`, or `chronomap` in `/`, and then renamed by `args`' `__node`
    /// and `__ns` rules.
    ///
    /// # Errors
    /// A file that cannot be read or is not a parameter file, a value that is not a
    /// parameter value, or a node name that is not valid; each naming where it is.
    pub fn new(
        config: Option<&Path>,
        node: Option<&str>,
        args: RosArgs,
    ) -> Result<Setup, ConfigError> {
        match config {
            Some(path) => Self::from_file(&ParamFile::read(path)?, node, args),
            None => {
                let name = node.unwrap_or("chronomap");
                let (namespace, name) =
                    node_identity(name, Some(name)).map_err(|m| ConfigError {
                        file: "--node-name".into(),
                        line: None,
                        key: None,
                        message: m,
                    })?;
                Self::with_args(ParamSet::default(), namespace, name, PathBuf::new(), args)
            }
        }
    }

    /// As [`Setup::new`] with the `--config` file already read.
    ///
    /// # Errors
    /// As [`Setup::new`].
    pub fn from_file(
        file: &ParamFile,
        node: Option<&str>,
        args: RosArgs,
    ) -> Result<Setup, ConfigError> {
        let error = |line: Option<u64>, message: String| ConfigError {
            file: file.path.display().to_string(),
            line,
            key: None,
            message,
        };
        let keys = || {
            file.entries
                .iter()
                .map(|e| e.key.clone())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let entry = match node {
            Some(node) => file
                .entries
                .iter()
                .find(|e| e.key == node || e.key.rsplit('/').next() == Some(node))
                .or_else(|| file.entries.iter().find(|e| e.key == "/**"))
                .ok_or_else(|| {
                    error(
                        None,
                        format!("no parameters for node {node:?} (entries: {})", keys()),
                    )
                })?,
            None => match &file.entries[..] {
                [only] => only,
                [] => {
                    return Err(error(
                        None,
                        "no node entry (expected `NODE_NAME: {ros__parameters: {...}}`)".into(),
                    ));
                }
                _ => {
                    return Err(error(
                        None,
                        format!(
                            "entries for several nodes ({}): choose one with --node-name",
                            keys()
                        ),
                    ));
                }
            },
        };
        let (namespace, name) =
            node_identity(&entry.key, node).map_err(|m| error(entry.origin.line(), m))?;
        Self::with_args(
            entry.params.clone(),
            namespace,
            name,
            file.path.clone(),
            args,
        )
    }

    fn with_args(
        mut params: ParamSet,
        namespace: String,
        name: String,
        source: PathBuf,
        args: RosArgs,
    ) -> Result<Setup, ConfigError> {
        let (namespace, name) = args.node_identity(&name, &namespace);
        let fqn = fully_qualified(&namespace, &name);
        ros2_client::NodeName::new(&namespace, &name).map_err(|e| ConfigError {
            file: "--ros-args".into(),
            line: None,
            key: None,
            message: format!("{fqn:?} is not a valid node name: {e}"),
        })?;
        let mut source = source;
        for param in &args.params {
            match param {
                ParamArg::File(path) => {
                    ParamFile::read(path)?.apply_matching(&fqn, &mut params)?;
                    if source.as_os_str().is_empty() {
                        source = path.clone();
                    }
                }
                ParamArg::Override {
                    node,
                    name: param,
                    value,
                    argument,
                } => {
                    if node.as_deref().is_none_or(|n| n == name) {
                        params.apply_override(param, value, argument)?;
                    }
                }
            }
        }
        if source.as_os_str().is_empty() {
            source = PathBuf::from("--ros-args");
        }
        Ok(Setup {
            namespace,
            name,
            params,
            args,
            source,
        })
    }

    /// The node's fully qualified name (`/chronomap`, `/robot1/chronomap`).
    pub fn fully_qualified_name(&self) -> String {
        fully_qualified(&self.namespace, &self.name)
    }

    /// The checked parameters.
    ///
    /// # Errors
    /// The first parameter that cannot be used, named with its source.
    pub fn config(&self) -> Result<NodeConfig, ConfigError> {
        self.check(&self.params, false, true)
    }

    /// As [`Setup::config`], but a node without states, maps, people or edges is accepted
    /// (a managed node that is given its parameters before it is configured).
    ///
    /// # Errors
    /// As [`Setup::config`].
    pub fn config_allowing_empty(&self) -> Result<NodeConfig, ConfigError> {
        self.check(&self.params, true, true)
    }

    /// The checked parameters if `name` were `value` (set at run time).
    ///
    /// # Errors
    /// As [`Setup::config`].
    pub fn config_with(
        &self,
        name: &str,
        value: &Value,
        allow_empty: bool,
    ) -> Result<NodeConfig, ConfigError> {
        let mut params = self.params.clone();
        params.insert(name, value.clone(), Origin::Service);
        self.check(&params, allow_empty, true)
    }

    /// Checks `params`; `files`: also the files and folders they name ([`check_save_dir`],
    /// [`check_input_file`], [`check_output_file`]).
    fn check(
        &self,
        params: &ParamSet,
        allow_empty: bool,
        files: bool,
    ) -> Result<NodeConfig, ConfigError> {
        let raw = Reader::new(params).params()?;
        let file = self.source.display().to_string();
        let checker = Checker { file: &file, files };
        checker.check(
            &raw,
            NodeIdentity {
                namespace: self.namespace.clone(),
                name: self.name.clone(),
            },
            &self.source,
            &self.args,
            allow_empty,
        )
    }
}

/// Checks that the models can be saved in `dir` (`save_dir`) before anything is learned: it is
/// a folder, or one that can be created, outside the kernel's file systems (`/proc`, `/sys`,
/// `/dev`), and a file can be created in it (or in the folder it would be created in): a
/// probe file is made and removed. Otherwise the first save, minutes or days later, would
/// fail and lose what was learned.
///
/// # Errors
/// Why the folder cannot hold the models.
pub fn check_save_dir(dir: &Path) -> Result<(), String> {
    let absolute =
        outside_the_kernel(dir).map_err(|m| format!("{m}: the models cannot be saved there"))?;
    // The folder, or the nearest folder above it that exists (where it would be created).
    let mut existing = absolute.as_path();
    loop {
        match std::fs::metadata(existing) {
            Ok(meta) if meta.is_dir() => break,
            Ok(_) if existing == absolute => {
                return Err(format!("{} is a file, not a folder", dir.display()));
            }
            Ok(_) => {
                return Err(format!(
                    "{} cannot be created: {} is a file, not a folder",
                    dir.display(),
                    existing.display()
                ));
            }
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
                ) =>
            {
                existing = existing
                    .parent()
                    .ok_or_else(|| format!("{}: no folder of it exists", dir.display()))?;
            }
            Err(e) => return Err(format!("cannot inspect {}: {e}", existing.display())),
        }
    }
    match probe(existing) {
        Ok(()) => Ok(()),
        Err(e) => Err(if existing == absolute {
            format!("{}: no file can be created in it ({e})", dir.display())
        } else {
            format!(
                "{} cannot be created: no file can be created in {} ({e})",
                dir.display(),
                existing.display()
            )
        }),
    }
}

/// Creates and removes a file in `dir`: whether files can be created there.
fn probe(dir: &Path) -> std::io::Result<()> {
    let probe = dir.join(format!(".chronomap-probe-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// `path` made absolute against the working folder, refused under the kernel's file systems
/// (`/proc`, `/sys`, `/dev`).
fn outside_the_kernel(path: &Path) -> Result<PathBuf, String> {
    let absolute = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .map_err(|e| format!("cannot resolve {}: {e}", path.display()))?
            .join(path)
    };
    for kernel in ["/proc", "/sys", "/dev"] {
        if absolute.starts_with(kernel) {
            return Err(format!(
                "{} is under {kernel}, a file system of the kernel",
                path.display()
            ));
        }
    }
    Ok(absolute)
}

/// Checks that the file `path` that the node reads when it starts (`edges.models`,
/// `days_off_file`) can be read: it is a regular file (not a directory, a device or a pipe), it opens read-only and
/// its first byte reads, and it has at most [`chronomap_io::MAX_FILE_BYTES`]. Its content is
/// checked when it is read.
///
/// # Errors
/// Why the file cannot be read.
pub fn check_input_file(path: &Path) -> Result<(), String> {
    use std::io::Read;
    let not_regular = || {
        format!(
            "{} is not a regular file (a directory, a device or a pipe)",
            path.display()
        )
    };
    // Checked before opening: opening a pipe waits for a writer.
    let meta =
        std::fs::metadata(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    if !meta.is_file() {
        return Err(not_regular());
    }
    let mut file =
        std::fs::File::open(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let meta = file
        .metadata()
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    if !meta.is_file() {
        return Err(not_regular());
    }
    if meta.len() > chronomap_io::MAX_FILE_BYTES {
        return Err(format!(
            "{} has {} bytes, more than the {} a file read whole may have (is this the right \
             file?)",
            path.display(),
            meta.len(),
            chronomap_io::MAX_FILE_BYTES
        ));
    }
    file.read(&mut [0u8; 1])
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    Ok(())
}

/// Checks that the file `path` that the node writes (`edges.geojson`, replaced atomically: a
/// temporary file beside it, then renamed) can be written: it is outside the kernel's file
/// systems, it is a regular file if it exists, its folder exists and a file can be created
/// in it (a probe file is made and removed).
///
/// # Errors
/// Why the file cannot be written.
pub fn check_output_file(path: &Path) -> Result<(), String> {
    let absolute =
        outside_the_kernel(path).map_err(|m| format!("{m}: nothing is written there"))?;
    match std::fs::metadata(&absolute) {
        Ok(meta) if !meta.is_file() => {
            return Err(format!(
                "{} is not a regular file (a directory, a device or a pipe): it would not be \
                 replaced",
                path.display()
            ));
        }
        Ok(_) => {}
        Err(e)
            if matches!(
                e.kind(),
                std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
            ) => {}
        Err(e) => return Err(format!("cannot inspect {}: {e}", path.display())),
    }
    let folder = absolute
        .parent()
        .ok_or_else(|| format!("{}: not a file name", path.display()))?;
    match std::fs::metadata(folder) {
        Ok(meta) if meta.is_dir() => {}
        Ok(_) => return Err(format!("{} is not a folder", folder.display())),
        Err(e) => return Err(format!("its folder {}: {e}", folder.display())),
    }
    probe(folder).map_err(|e| {
        format!(
            "{}: no file can be created in {} ({e})",
            path.display(),
            folder.display()
        )
    })
}

/// Whether the parameter `name` may change while the node runs (the others are read when the
/// node starts or, managed, configures).
pub fn is_dynamic(name: &str) -> bool {
    matches!(
        name,
        "publish_period" | "map_period" | "horizon" | "save_period" | "edges.period"
    ) || ((name.starts_with("maps.") || name.starts_with("people."))
        && (name.ends_with(".filter_type")
            || name.ends_with(".filter_base")
            || name.ends_with(".filter_multiplier")))
}

/// What the parameter `name` is (its `describe_parameters` description).
pub fn description(name: &str) -> &'static str {
    let leaf = name.rsplit('.').next().unwrap_or(name);
    let section = name.split('.').next().unwrap_or("");
    match (section, leaf) {
        ("use_sim_time", _) => {
            "follow /clock (rosgraph_msgs/msg/Clock) instead of the system clock"
        }
        ("publish_period", _) => "seconds of the node's clock between state predictions",
        ("map_period", _) => {
            "seconds of the node's clock between predicted maps, masks and people maps"
        }
        ("horizon", _) => "predictions are for the node's time plus this many seconds",
        ("save_dir", _) => "folder the models are saved to and restored from",
        ("save_period", _) => "seconds of wall-clock time between saves",
        ("record_observations", _) => "append every learned state to save_dir/states/NAME.txt",
        ("sync_period", _) => {
            "longest time in seconds a learned message waits before the journal is synced (what a crash can lose)"
        }
        ("sync_messages", _) => "learned messages that make a journal sync due at once",
        ("max_map_cells", _) => "larger OccupancyGrid messages are refused",
        ("days_off_file", _) => {
            "calendar of days off (YYYY-MM-DD per line): states observed on one are not learned and are predicted as on the last Sunday that is not one (\"\" for none)"
        }
        ("memory_limit", _) => {
            "bytes the grids may hold at most: a map that could bring them above it is refused (0: no limit)"
        }
        ("edges", "models") => "edge models (chronomap topo fit)",
        ("edges", "geojson") => "the Nav2 route graph rewritten with predicted costs",
        ("edges", "period") => "seconds of the node's clock between rewrites of the route graph",
        (_, "topic") => "the input topic",
        (_, "type") => "message type: std_msgs/msg/Bool, Float32 or Float64",
        (_, "model") => "the temporal model learned online (fremen:2, hist:24, ...)",
        (_, "reliability") => "subscription reliability: reliable or best_effort",
        (_, "depth") => "subscription depth (keep last)",
        (_, "transient_local") => "subscribe transient local (latched publishers only)",
        (_, "probability_topic") => "where p(now + horizon) is published (std_msgs/msg/Float64)",
        (_, "entropy_topic") => "where the entropy of the prediction is published (bits)",
        (_, "prediction_topic") => {
            "where the stamped prediction is published (chronomap_msgs/msg/Prediction; \"\" for none)"
        }
        (_, "coverage") => {
            "coverage of the prediction intervals of a Float32/Float64 state, strictly between 0 and 1"
        }
        (_, "frame_id") => "frame of the input and of the published maps",
        (_, "periods") => "candidate periods of every cell's FreMEn model",
        (_, "order") => "order every cell is predicted with",
        (_, "values") => "cells of the predicted map: trinary, scale or probability",
        (_, "predicted_topic") => "where the predicted map is published",
        (_, "mask_topic") => "where the costmap-filter mask is published (\"\" for none)",
        (_, "filter_info_topic") => "where the nav2_msgs/msg/CostmapFilterInfo is published",
        (_, "filter_type") => {
            "Nav2 filter type: 0 keepout, 1 speed limit %, 2 speed limit m/s, 3 binary"
        }
        (_, "filter_base") => "base of the filter value (base + multiplier * mask value)",
        (_, "filter_multiplier") => {
            "multiplier of the filter value (base + multiplier * mask value)"
        }
        (_, "width") => "cells per row of the people grid",
        (_, "height") => "rows of the people grid",
        (_, "resolution") => "metres per cell of the people grid",
        (_, "origin") => "[x, y] of the corner of cell (0, 0), metres",
        (_, "bin") => "length of a people time bin, seconds",
        _ => "",
    }
}

impl NodeConfig {
    /// Reads and checks the parameter file `path`; `node` picks the node's entry in a file
    /// for several nodes (default: the only entry).
    ///
    /// # Errors
    /// A file that cannot be read or is not a valid parameter file, naming file, line and
    /// parameter.
    pub fn read(path: &Path, node: Option<&str>) -> Result<NodeConfig, ConfigError> {
        Setup::new(Some(path), node, RosArgs::default())?.config()
    }

    /// Checks the text of the parameter file `path` (relative paths in it are relative to its
    /// folder).
    ///
    /// # Errors
    /// As [`NodeConfig::read`].
    pub fn parse(path: &Path, text: &[u8], node: Option<&str>) -> Result<NodeConfig, ConfigError> {
        let file = ParamFile::parse(path, text)?;
        Setup::from_file(&file, node, RosArgs::default())?.config()
    }

    /// As [`NodeConfig::parse`], but the files and folders the text names (`save_dir`,
    /// `edges.models`, `edges.geojson`, `days_off_file`) are not looked at: nothing on the
    /// file system is read or created (so [`NodeConfig::days_off`] is empty). For checking a
    /// configuration's text away from the machine that runs it (and for tests of arbitrary
    /// text); the node and `chronomap ros2 --check` check the files too.
    ///
    /// # Errors
    /// As [`NodeConfig::parse`], less the files.
    pub fn parse_text(
        path: &Path,
        text: &[u8],
        node: Option<&str>,
    ) -> Result<NodeConfig, ConfigError> {
        let file = ParamFile::parse(path, text)?;
        let setup = Setup::from_file(&file, node, RosArgs::default())?;
        setup.check(&setup.params, false, false)
    }

    /// The node's fully qualified name (`/chronomap`, `/robot1/chronomap`).
    pub fn fully_qualified_name(&self) -> String {
        fully_qualified(&self.namespace, &self.node_name)
    }

    /// Every topic the node subscribes to, with its type: `(topic, type, parameter)`.
    pub fn inputs(&self) -> Vec<(String, TypeName, String)> {
        let mut inputs: Vec<(String, TypeName, String)> = Vec::new();
        if self.use_sim_time {
            inputs.push((
                self.clock_topic.clone(),
                crate::msgs::Clock::TYPE,
                "use_sim_time".into(),
            ));
        }
        for s in &self.states {
            inputs.push((
                s.topic.clone(),
                s.message.type_name(),
                format!("states.{}.topic", s.name),
            ));
        }
        for g in &self.grids {
            let ty = match g.source {
                GridSource::Map => crate::msgs::OccupancyGrid::TYPE,
                GridSource::People { .. } => crate::msgs::PoseArray::TYPE,
            };
            inputs.push((
                g.topic.clone(),
                ty,
                format!("{}.{}.topic", g.section(), g.name),
            ));
        }
        inputs
    }

    /// Every topic the node publishes, with its type.
    pub fn outputs(&self) -> Vec<(String, TypeName)> {
        let mut outputs = Vec::new();
        for s in &self.states {
            outputs.push((s.probability_topic.clone(), Float64::TYPE));
            outputs.push((s.entropy_topic.clone(), Float64::TYPE));
            if let Some(topic) = &s.prediction_topic {
                outputs.push((topic.clone(), crate::msgs::Prediction::TYPE));
            }
        }
        for g in &self.grids {
            outputs.push((g.predicted_topic.clone(), crate::msgs::OccupancyGrid::TYPE));
            if let Some(f) = &g.filter {
                outputs.push((f.mask_topic.clone(), crate::msgs::OccupancyGrid::TYPE));
                outputs.push((f.info_topic.clone(), crate::msgs::CostmapFilterInfo::TYPE));
            }
        }
        outputs
    }
}

impl NodeConfig {
    /// Every parameter with its value, as the node declares them (`ros2 param list`):
    /// defaults filled in, topics resolved and remapped, paths as the node uses them.
    pub fn parameters(&self) -> Vec<(String, Value)> {
        let mut out: Vec<(String, Value)> = Vec::new();
        let mut put = |name: String, value: Value| out.push((name, value));
        let text = |s: &str| Value::String(s.to_string());
        let path = |p: &Path| Value::String(p.display().to_string());
        put("use_sim_time".into(), Value::Boolean(self.use_sim_time));
        put("publish_period".into(), Value::Double(self.publish_period));
        put("map_period".into(), Value::Double(self.map_period));
        put("horizon".into(), Value::Double(self.horizon));
        if let Some(dir) = &self.save_dir {
            put("save_dir".into(), path(dir));
        }
        put("save_period".into(), Value::Double(self.save_period));
        put(
            "record_observations".into(),
            Value::Boolean(self.record_observations),
        );
        put("sync_period".into(), Value::Double(self.sync_period));
        put(
            "sync_messages".into(),
            Value::Integer(i64::try_from(self.sync_messages).unwrap_or(i64::MAX)),
        );
        put(
            "max_map_cells".into(),
            Value::Integer(self.max_map_cells as i64),
        );
        put(
            "days_off_file".into(),
            self.days_off_file.as_deref().map_or(text(""), path),
        );
        put(
            "memory_limit".into(),
            Value::Integer(
                self.memory_limit
                    .map_or(0, |l| i64::try_from(l).unwrap_or(i64::MAX)),
            ),
        );
        let qos = |put: &mut dyn FnMut(String, Value), key: &str, q: &InputQos| {
            let r = match q.reliability {
                Reliability::Reliable => "reliable",
                Reliability::BestEffort => "best_effort",
            };
            put(format!("{key}.reliability"), text(r));
            put(format!("{key}.depth"), Value::Integer(q.depth as i64));
            put(
                format!("{key}.transient_local"),
                Value::Boolean(q.transient_local),
            );
        };
        for s in &self.states {
            let key = format!("states.{}", s.name);
            put(format!("{key}.topic"), text(&s.topic));
            put(
                format!("{key}.type"),
                text(&s.message.type_name().to_string()),
            );
            put(format!("{key}.model"), text(&s.model.to_string()));
            qos(&mut put, &key, &s.qos);
            put(
                format!("{key}.probability_topic"),
                text(&s.probability_topic),
            );
            put(format!("{key}.entropy_topic"), text(&s.entropy_topic));
            put(
                format!("{key}.prediction_topic"),
                text(s.prediction_topic.as_deref().unwrap_or("")),
            );
            if s.has_interval() {
                put(format!("{key}.coverage"), Value::Double(s.coverage));
            }
        }
        for g in &self.grids {
            let key = format!("{}.{}", g.section(), g.name);
            put(format!("{key}.topic"), text(&g.topic));
            qos(&mut put, &key, &g.qos);
            put(format!("{key}.frame_id"), text(&g.frame_id));
            put(
                format!("{key}.periods"),
                text(&g.fremen.periods.to_string()),
            );
            put(
                format!("{key}.order"),
                Value::Integer(g.fremen.order as i64),
            );
            let values = match g.values {
                MapValues::Trinary => "trinary",
                MapValues::Scale => "scale",
                MapValues::Probability => "probability",
            };
            put(format!("{key}.values"), text(values));
            put(format!("{key}.predicted_topic"), text(&g.predicted_topic));
            match &g.filter {
                Some(f) => {
                    put(format!("{key}.mask_topic"), text(&f.mask_topic));
                    put(format!("{key}.filter_info_topic"), text(&f.info_topic));
                    put(
                        format!("{key}.filter_type"),
                        Value::Integer(i64::from(f.filter_type)),
                    );
                    put(
                        format!("{key}.filter_base"),
                        Value::Double(f64::from(f.base)),
                    );
                    put(
                        format!("{key}.filter_multiplier"),
                        Value::Double(f64::from(f.multiplier)),
                    );
                }
                None => {
                    put(format!("{key}.mask_topic"), text(""));
                    put(format!("{key}.filter_info_topic"), text(""));
                }
            }
            if let GridSource::People {
                width,
                height,
                resolution,
                origin,
                bin_secs,
            } = &g.source
            {
                put(format!("{key}.width"), Value::Integer(i64::from(*width)));
                put(format!("{key}.height"), Value::Integer(i64::from(*height)));
                put(format!("{key}.resolution"), Value::Double(*resolution));
                put(format!("{key}.origin"), Value::DoubleArray(origin.to_vec()));
                put(format!("{key}.bin"), Value::Double(*bin_secs));
            }
        }
        if let Some(e) = &self.edges {
            put("edges.models".into(), path(&e.models));
            put("edges.geojson".into(), path(&e.geojson));
            put("edges.period".into(), Value::Double(e.period));
        }
        out.sort_by(|a, b| a.0.cmp(&b.0));
        out
    }
}

fn fully_qualified(namespace: &str, name: &str) -> String {
    if namespace == "/" {
        format!("/{name}")
    } else {
        format!("{namespace}/{name}")
    }
}

/// Namespace and name of the node of the entry `key` (`chronomap`, `/robot1/chronomap`, or
/// `/**`, every node, for which `node` or `chronomap` is the name).
fn node_identity(key: &str, node: Option<&str>) -> Result<(String, String), String> {
    let full = if key == "/**" {
        node.unwrap_or("chronomap").to_string()
    } else {
        key.to_string()
    };
    let (namespace, name) = match full.rsplit_once('/') {
        None => ("/".to_string(), full.clone()),
        Some(("", name)) => ("/".to_string(), name.to_string()),
        Some((ns, name)) => (ns.to_string(), name.to_string()),
    };
    let namespace = if namespace.starts_with('/') {
        namespace
    } else {
        format!("/{namespace}")
    };
    ros2_client::NodeName::new(&namespace, &name)
        .map_err(|e| format!("{full:?} is not a valid node name: {e}"))?;
    if name.contains("__") || namespace.contains("__") {
        return Err(format!(
            "{full:?} is not a valid node name: repeated underscores"
        ));
    }
    Ok((namespace, name))
}

struct NodeIdentity {
    namespace: String,
    name: String,
}

/// A typed parameter value and where it came from.
struct Spanned<T> {
    value: T,
    origin: Origin,
}

struct RawParams {
    use_sim_time: Option<Spanned<bool>>,
    publish_period: Option<Spanned<f64>>,
    map_period: Option<Spanned<f64>>,
    horizon: Option<Spanned<f64>>,
    save_dir: Option<Spanned<String>>,
    save_period: Option<Spanned<f64>>,
    record_observations: Option<Spanned<bool>>,
    sync_period: Option<Spanned<f64>>,
    sync_messages: Option<Spanned<u64>>,
    max_map_cells: Option<Spanned<u64>>,
    memory_limit: Option<Spanned<u64>>,
    days_off_file: Option<Spanned<String>>,
    states: BTreeMap<String, Spanned<RawState>>,
    maps: BTreeMap<String, Spanned<RawGrid>>,
    people: BTreeMap<String, Spanned<RawGrid>>,
    edges: Option<Spanned<RawEdges>>,
}

/// The subscription keys every input topic has.
struct RawQos<'a> {
    reliability: &'a Option<Spanned<String>>,
    depth: &'a Option<Spanned<u64>>,
    transient_local: &'a Option<Spanned<bool>>,
}

/// The parameters of a state (`states.NAME.LEAF`).
const STATE_KEYS: &[&str] = &[
    "topic",
    "type",
    "model",
    "keep",
    "refit_observations",
    "refit_period",
    "reliability",
    "depth",
    "transient_local",
    "probability_topic",
    "entropy_topic",
    "prediction_topic",
    "coverage",
];

/// The parameters of a map (`maps.NAME.LEAF`); people grids have [`PEOPLE_KEYS`] too.
const GRID_KEYS: &[&str] = &[
    "topic",
    "reliability",
    "depth",
    "transient_local",
    "frame_id",
    "periods",
    "order",
    "values",
    "predicted_topic",
    "mask_topic",
    "filter_info_topic",
    "filter_type",
    "filter_base",
    "filter_multiplier",
];

/// The geometry and bin of a people grid.
const PEOPLE_KEYS: &[&str] = &["width", "height", "resolution", "origin", "bin"];

/// The top-level parameters.
const TOP_KEYS: &[&str] = &[
    "use_sim_time",
    "publish_period",
    "map_period",
    "horizon",
    "save_dir",
    "save_period",
    "record_observations",
    "sync_period",
    "sync_messages",
    "max_map_cells",
    "memory_limit",
    "days_off_file",
];

struct RawState {
    topic: Option<Spanned<String>>,
    message: Option<Spanned<String>>,
    model: Option<Spanned<String>>,
    keep: Option<Spanned<u64>>,
    refit_observations: Option<Spanned<u64>>,
    refit_period: Option<Spanned<f64>>,
    reliability: Option<Spanned<String>>,
    depth: Option<Spanned<u64>>,
    transient_local: Option<Spanned<bool>>,
    probability_topic: Option<Spanned<String>>,
    entropy_topic: Option<Spanned<String>>,
    prediction_topic: Option<Spanned<String>>,
    coverage: Option<Spanned<f64>>,
}

/// `maps.NAME` and `people.NAME` (the geometry and bin keys are for people only).
struct RawGrid {
    topic: Option<Spanned<String>>,
    reliability: Option<Spanned<String>>,
    depth: Option<Spanned<u64>>,
    transient_local: Option<Spanned<bool>>,
    frame_id: Option<Spanned<String>>,
    periods: Option<Spanned<String>>,
    order: Option<Spanned<u64>>,
    values: Option<Spanned<String>>,
    predicted_topic: Option<Spanned<String>>,
    mask_topic: Option<Spanned<String>>,
    filter_info_topic: Option<Spanned<String>>,
    filter_type: Option<Spanned<u64>>,
    filter_base: Option<Spanned<f32>>,
    filter_multiplier: Option<Spanned<f32>>,
    width: Option<Spanned<u32>>,
    height: Option<Spanned<u32>>,
    resolution: Option<Spanned<f64>>,
    origin: Option<Spanned<Vec<f64>>>,
    bin: Option<Spanned<f64>>,
}

impl RawGrid {
    fn qos(&self) -> RawQos<'_> {
        RawQos {
            reliability: &self.reliability,
            depth: &self.depth,
            transient_local: &self.transient_local,
        }
    }
}

struct RawEdges {
    models: Option<Spanned<String>>,
    geojson: Option<Spanned<String>>,
    period: Option<Spanned<f64>>,
}

/// Typed reads of a [`ParamSet`]: each value must have its parameter's type, and every value
/// must be read (what is not is an unknown parameter).
struct Reader<'a> {
    set: &'a ParamSet,
    read: std::collections::BTreeSet<String>,
}

/// rcl's spellings of booleans (`yes`, `On`, ...), accepted where a boolean is expected.
fn rcl_boolean(text: &str) -> Option<bool> {
    match text {
        "true" | "True" | "TRUE" | "yes" | "Yes" | "YES" | "on" | "On" | "ON" => Some(true),
        "false" | "False" | "FALSE" | "no" | "No" | "NO" | "off" | "Off" | "OFF" => Some(false),
        _ => None,
    }
}

/// What an integer parameter is, for the message when it is not one.
fn integer_hint(key: &str) -> &'static str {
    if key.ends_with(".order") {
        " (the node learns every cell with a fixed order; `chronomap grid build --order auto` \
         chooses one offline on a whole series)"
    } else {
        ""
    }
}

impl<'a> Reader<'a> {
    fn new(set: &'a ParamSet) -> Self {
        Reader {
            set,
            read: std::collections::BTreeSet::new(),
        }
    }

    fn get(&mut self, key: &str) -> Option<&'a params::Entry> {
        let entry = self.set.values.get(key)?;
        self.read.insert(key.to_string());
        Some(entry)
    }

    fn typed<T>(
        &mut self,
        key: &str,
        expected: &str,
        convert: impl FnOnce(&Value) -> Option<T>,
    ) -> Result<Option<Spanned<T>>, ConfigError> {
        let Some(entry) = self.get(key) else {
            return Ok(None);
        };
        match convert(&entry.value) {
            Some(value) => Ok(Some(Spanned {
                value,
                origin: entry.origin.clone(),
            })),
            None => Err(entry.origin.error(
                Some(key),
                format!(
                    "expected {expected}, found {}{}",
                    params::describe(&entry.value),
                    if expected.contains("integer") {
                        integer_hint(key)
                    } else {
                        ""
                    }
                ),
            )),
        }
    }

    fn boolean(&mut self, key: &str) -> Result<Option<Spanned<bool>>, ConfigError> {
        self.typed(key, "true or false", |v| match v {
            Value::Boolean(b) => Some(*b),
            Value::String(s) => rcl_boolean(s),
            _ => None,
        })
    }

    fn number(&mut self, key: &str) -> Result<Option<Spanned<f64>>, ConfigError> {
        self.typed(key, "a number", |v| match v {
            Value::Double(d) => Some(*d),
            Value::Integer(i) => Some(*i as f64),
            _ => None,
        })
    }

    fn float(&mut self, key: &str) -> Result<Option<Spanned<f32>>, ConfigError> {
        Ok(self.number(key)?.map(|v| Spanned {
            value: v.value as f32,
            origin: v.origin,
        }))
    }

    fn integer(&mut self, key: &str) -> Result<Option<Spanned<u64>>, ConfigError> {
        self.typed(key, "an integer >= 0", |v| match v {
            Value::Integer(i) => u64::try_from(*i).ok(),
            _ => None,
        })
    }

    fn integer32(&mut self, key: &str) -> Result<Option<Spanned<u32>>, ConfigError> {
        self.typed(key, "an integer in 0..=4294967295", |v| match v {
            Value::Integer(i) => u32::try_from(*i).ok(),
            _ => None,
        })
    }

    fn text(&mut self, key: &str) -> Result<Option<Spanned<String>>, ConfigError> {
        self.typed(key, "a string", |v| match v {
            Value::String(s) => Some(s.clone()),
            // `periods: 86400` is the text of a period.
            Value::Integer(i) => Some(i.to_string()),
            Value::Double(d) => Some(d.to_string()),
            _ => None,
        })
    }

    fn numbers(&mut self, key: &str) -> Result<Option<Spanned<Vec<f64>>>, ConfigError> {
        self.typed(key, "a list of numbers", |v| match v {
            Value::DoubleArray(a) => Some(a.clone()),
            Value::IntegerArray(a) => Some(a.iter().map(|&i| i as f64).collect()),
            _ => None,
        })
    }

    /// The names of the entries of a section (`states` → `door`, `light`), with where each
    /// was first given.
    fn names(&self, section: &str) -> Result<BTreeMap<String, Origin>, ConfigError> {
        let mut names = BTreeMap::new();
        for (key, entry) in &self.set.values {
            let mut tokens = key.splitn(3, '.');
            if tokens.next() != Some(section) {
                continue;
            }
            match (tokens.next(), tokens.next()) {
                (Some(name), Some(_)) => {
                    let origin = self
                        .set
                        .sections
                        .get(&format!("{section}.{name}"))
                        .unwrap_or(&entry.origin);
                    names
                        .entry(name.to_string())
                        .or_insert_with(|| origin.clone());
                }
                _ => {
                    return Err(entry.origin.error(
                        Some(key),
                        format!(
                            "expected a mapping of parameters (`{section}: {{NAME: {{topic: ..., ...}}}}` \
                             or `{section}.NAME.topic: ...`), found {}",
                            params::describe(&entry.value)
                        ),
                    ));
                }
            }
        }
        Ok(names)
    }

    fn state(&mut self, key: &str) -> Result<RawState, ConfigError> {
        let k = |leaf: &str| format!("{key}.{leaf}");
        Ok(RawState {
            topic: self.text(&k("topic"))?,
            message: self.text(&k("type"))?,
            model: self.text(&k("model"))?,
            keep: self.integer(&k("keep"))?,
            refit_observations: self.integer(&k("refit_observations"))?,
            refit_period: self.number(&k("refit_period"))?,
            reliability: self.text(&k("reliability"))?,
            depth: self.integer(&k("depth"))?,
            transient_local: self.boolean(&k("transient_local"))?,
            probability_topic: self.text(&k("probability_topic"))?,
            entropy_topic: self.text(&k("entropy_topic"))?,
            prediction_topic: self.text(&k("prediction_topic"))?,
            coverage: self.number(&k("coverage"))?,
        })
    }

    fn grid(&mut self, key: &str) -> Result<RawGrid, ConfigError> {
        let k = |leaf: &str| format!("{key}.{leaf}");
        Ok(RawGrid {
            topic: self.text(&k("topic"))?,
            reliability: self.text(&k("reliability"))?,
            depth: self.integer(&k("depth"))?,
            transient_local: self.boolean(&k("transient_local"))?,
            frame_id: self.text(&k("frame_id"))?,
            periods: self.text(&k("periods"))?,
            order: self.integer(&k("order"))?,
            values: self.text(&k("values"))?,
            predicted_topic: self.text(&k("predicted_topic"))?,
            mask_topic: self.text(&k("mask_topic"))?,
            filter_info_topic: self.text(&k("filter_info_topic"))?,
            filter_type: self.integer(&k("filter_type"))?,
            filter_base: self.float(&k("filter_base"))?,
            filter_multiplier: self.float(&k("filter_multiplier"))?,
            width: self.integer32(&k("width"))?,
            height: self.integer32(&k("height"))?,
            resolution: self.number(&k("resolution"))?,
            origin: self.numbers(&k("origin"))?,
            bin: self.number(&k("bin"))?,
        })
    }

    /// Reads every parameter; anything left is an unknown parameter.
    fn params(mut self) -> Result<RawParams, ConfigError> {
        let section_of = |names: &BTreeMap<String, Origin>, name: &str| {
            names.get(name).cloned().unwrap_or(Origin::Service)
        };
        let mut states = BTreeMap::new();
        let state_names = self.names("states")?;
        for name in state_names.keys() {
            let raw = self.state(&format!("states.{name}"))?;
            states.insert(
                name.clone(),
                Spanned {
                    value: raw,
                    origin: section_of(&state_names, name),
                },
            );
        }
        let mut maps = BTreeMap::new();
        let map_names = self.names("maps")?;
        for name in map_names.keys() {
            let raw = self.grid(&format!("maps.{name}"))?;
            maps.insert(
                name.clone(),
                Spanned {
                    value: raw,
                    origin: section_of(&map_names, name),
                },
            );
        }
        let mut people = BTreeMap::new();
        let people_names = self.names("people")?;
        for name in people_names.keys() {
            let raw = self.grid(&format!("people.{name}"))?;
            people.insert(
                name.clone(),
                Spanned {
                    value: raw,
                    origin: section_of(&people_names, name),
                },
            );
        }
        let edges_origin = self
            .set
            .values
            .iter()
            .find(|(k, _)| k.starts_with("edges.") || k.as_str() == "edges")
            .map(|(_, e)| self.set.sections.get("edges").unwrap_or(&e.origin).clone());
        if let Some(e) = self.set.values.get("edges") {
            return Err(e.origin.error(
                Some("edges"),
                format!(
                    "expected a mapping (`edges: {{models: ..., geojson: ...}}`), found {}",
                    params::describe(&e.value)
                ),
            ));
        }
        let edges = match edges_origin {
            None => None,
            Some(origin) => Some(Spanned {
                value: RawEdges {
                    models: self.text("edges.models")?,
                    geojson: self.text("edges.geojson")?,
                    period: self.number("edges.period")?,
                },
                origin,
            }),
        };
        let raw = RawParams {
            use_sim_time: self.boolean("use_sim_time")?,
            publish_period: self.number("publish_period")?,
            map_period: self.number("map_period")?,
            horizon: self.number("horizon")?,
            save_dir: self.text("save_dir")?,
            save_period: self.number("save_period")?,
            record_observations: self.boolean("record_observations")?,
            sync_period: self.number("sync_period")?,
            sync_messages: self.integer("sync_messages")?,
            max_map_cells: self.integer("max_map_cells")?,
            memory_limit: self.integer("memory_limit")?,
            days_off_file: self.text("days_off_file")?,
            states,
            maps,
            people,
            edges,
        };
        for (key, entry) in &self.set.values {
            if self.read.contains(key) {
                continue;
            }
            let tokens: Vec<&str> = key.split('.').collect();
            let known = match tokens[0] {
                "states" => format!("a state has {}", STATE_KEYS.join(", ")),
                "maps" => format!("a map has {}", GRID_KEYS.join(", ")),
                "people" => format!(
                    "a people grid has {}, {}",
                    GRID_KEYS.join(", "),
                    PEOPLE_KEYS.join(", ")
                ),
                "edges" => "edges has models, geojson, period".to_string(),
                _ => format!(
                    "the node's parameters are {}, states, maps, people, edges",
                    TOP_KEYS.join(", ")
                ),
            };
            return Err(entry
                .origin
                .error(Some(key), format!("unknown parameter ({known})")));
        }
        Ok(raw)
    }
}
struct Checker<'a> {
    file: &'a str,
    /// Whether the files and folders the parameters name are checked too.
    files: bool,
}

impl Checker<'_> {
    fn error(&self, line: Option<u64>, key: Option<String>, message: String) -> ConfigError {
        ConfigError {
            file: self.file.to_string(),
            line,
            key,
            message,
        }
    }

    fn at<T>(&self, value: &Spanned<T>, key: &str, message: String) -> ConfigError {
        value.origin.error(Some(key), message)
    }

    fn required<'v, T>(
        &self,
        value: &'v Option<Spanned<T>>,
        section: &Spanned<impl Sized>,
        key: &str,
    ) -> Result<&'v Spanned<T>, ConfigError> {
        value
            .as_ref()
            .ok_or_else(|| section.origin.error(Some(key), "missing (required)"))
    }

    /// A finite number of seconds > 0 (or ≥ 0 with `zero`), or `default`.
    fn seconds(
        &self,
        value: &Option<Spanned<f64>>,
        key: &str,
        default: f64,
        zero: bool,
    ) -> Result<f64, ConfigError> {
        match value {
            None => Ok(default),
            Some(v) if v.value.is_finite() && (v.value > 0.0 || (zero && v.value == 0.0)) => {
                Ok(v.value)
            }
            Some(v) => Err(self.at(
                v,
                key,
                format!(
                    "{} is not a finite number of seconds {}",
                    v.value,
                    if zero { ">= 0" } else { "> 0" }
                ),
            )),
        }
    }

    fn check(
        &self,
        raw: &RawParams,
        node: NodeIdentity,
        path: &Path,
        args: &RosArgs,
        allow_empty: bool,
    ) -> Result<NodeConfig, ConfigError> {
        let names = Names {
            namespace: node.namespace.clone(),
            node: fully_qualified(&node.namespace, &node.name),
            name: node.name.clone(),
            args,
        };
        let max_map_cells = match &raw.max_map_cells {
            None => DEFAULT_MAX_MAP_CELLS,
            Some(v) if (1..=MAX_MAX_MAP_CELLS).contains(&v.value) => v.value,
            Some(v) => {
                return Err(self.at(
                    v,
                    "max_map_cells",
                    format!("{} is not in 1..={MAX_MAX_MAP_CELLS}", v.value),
                ));
            }
        };
        let mut kinds: BTreeMap<&str, &str> = BTreeMap::new();
        let mut states = Vec::new();
        for (name, state) in &raw.states {
            self.unique_name(&mut kinds, name, "states", state)?;
            states.push(self.state(name, state, &names)?);
        }
        let mut grids = Vec::new();
        for (name, map) in &raw.maps {
            self.unique_name(&mut kinds, name, "maps", map)?;
            let key = format!("maps.{name}");
            let topic = self.topic(
                self.required(&map.value.topic, map, &format!("{key}.topic"))?,
                &format!("{key}.topic"),
                &names,
            )?;
            for (value, leaf) in [
                (map.value.width.as_ref().map(|v| &v.origin), "width"),
                (map.value.height.as_ref().map(|v| &v.origin), "height"),
                (
                    map.value.resolution.as_ref().map(|v| &v.origin),
                    "resolution",
                ),
                (map.value.origin.as_ref().map(|v| &v.origin), "origin"),
                (map.value.bin.as_ref().map(|v| &v.origin), "bin"),
            ] {
                if let Some(at) = value {
                    return Err(at.error(
                        Some(&format!("{key}.{leaf}")),
                        "only people grids have this key (a map's geometry comes from its messages)",
                    ));
                }
            }
            let qos = self.qos(&map.value.qos(), &key, 10, false)?;
            grids.push(self.grid(
                name,
                &key,
                GridSource::Map,
                topic,
                qos,
                &map.value,
                MapValues::Trinary,
                &names,
            )?);
        }
        for (name, people) in &raw.people {
            self.unique_name(&mut kinds, name, "people", people)?;
            let key = format!("people.{name}");
            let p = &people.value;
            let topic = self.topic(
                self.required(&p.topic, people, &format!("{key}.topic"))?,
                &format!("{key}.topic"),
                &names,
            )?;
            let width = self.required(&p.width, people, &format!("{key}.width"))?;
            let height = self.required(&p.height, people, &format!("{key}.height"))?;
            for (v, k) in [(width, "width"), (height, "height")] {
                if v.value == 0 {
                    return Err(self.at(v, &format!("{key}.{k}"), "must be at least 1".into()));
                }
            }
            let cells = u64::from(width.value) * u64::from(height.value);
            if cells > max_map_cells {
                return Err(self.at(
                    width,
                    &format!("{key}.width"),
                    format!(
                        "{} x {} = {cells} cells is above max_map_cells ({max_map_cells})",
                        width.value, height.value
                    ),
                ));
            }
            let resolution = self.required(&p.resolution, people, &format!("{key}.resolution"))?;
            if !(resolution.value.is_finite() && resolution.value > 0.0) {
                return Err(self.at(
                    resolution,
                    &format!("{key}.resolution"),
                    format!("{} is not a finite number of metres > 0", resolution.value),
                ));
            }
            let origin = match &p.origin {
                None => [0.0, 0.0],
                Some(o) => match o.value[..] {
                    [x, y] if x.is_finite() && y.is_finite() => [x, y],
                    _ => {
                        return Err(self.at(
                            o,
                            &format!("{key}.origin"),
                            format!("{:?} is not [x, y] (two finite numbers)", o.value),
                        ));
                    }
                },
            };
            let bin_secs = self.seconds(&p.bin, &format!("{key}.bin"), 600.0, false)?;
            let qos = self.qos(&p.qos(), &key, 50, false)?;
            let source = GridSource::People {
                width: width.value,
                height: height.value,
                resolution: resolution.value,
                origin,
                bin_secs,
            };
            grids.push(self.grid(
                name,
                &key,
                source,
                topic,
                qos,
                p,
                MapValues::Probability,
                &names,
            )?);
        }
        let edges = match &raw.edges {
            None => None,
            Some(e) => {
                let models = self.required(&e.value.models, e, "edges.models")?;
                let geojson = self.required(&e.value.geojson, e, "edges.geojson")?;
                for (v, k) in [(models, "edges.models"), (geojson, "edges.geojson")] {
                    if v.value.is_empty() {
                        return Err(self.at(v, k, "an empty file name".into()));
                    }
                }
                let models_path = models.origin.folder().join(&models.value);
                let geojson_path = geojson.origin.folder().join(&geojson.value);
                if self.files {
                    check_input_file(&models_path)
                        .map_err(|m| self.at(models, "edges.models", m))?;
                    check_output_file(&geojson_path)
                        .map_err(|m| self.at(geojson, "edges.geojson", m))?;
                }
                Some(EdgesConfig {
                    models: models_path,
                    geojson: geojson_path,
                    period: self.seconds(&e.value.period, "edges.period", 60.0, false)?,
                })
            }
        };
        let save_dir = match &raw.save_dir {
            Some(d) if d.value.is_empty() => {
                return Err(self.at(d, "save_dir", "an empty folder name".into()));
            }
            Some(d) => {
                let dir = d.origin.folder().join(&d.value);
                if self.files {
                    check_save_dir(&dir).map_err(|m| self.at(d, "save_dir", m))?;
                }
                Some(dir)
            }
            None => None,
        };
        let record_observations = raw.record_observations.as_ref().is_some_and(|r| r.value);
        if let (true, None, Some(r)) = (record_observations, &save_dir, &raw.record_observations) {
            return Err(self.at(
                r,
                "record_observations",
                "needs save_dir (the records are written there)".into(),
            ));
        }
        let sync_period = self.seconds(&raw.sync_period, "sync_period", 1.0, false)?;
        if sync_period > MAX_SYNC_PERIOD {
            let v = raw.sync_period.as_ref().expect("not the default");
            return Err(self.at(
                v,
                "sync_period",
                format!(
                    "{sync_period} s is more than {MAX_SYNC_PERIOD} s of learning a crash could lose"
                ),
            ));
        }
        let sync_messages = match &raw.sync_messages {
            None => DEFAULT_SYNC_MESSAGES,
            Some(v) if v.value >= 1 => v.value,
            Some(v) => {
                return Err(self.at(
                    v,
                    "sync_messages",
                    "0 is not a number of messages >= 1".into(),
                ));
            }
        };
        let (days_off_file, days_off) = match &raw.days_off_file {
            Some(f) if !f.value.is_empty() => {
                let file = f.origin.folder().join(&f.value);
                let days = if self.files {
                    check_input_file(&file).map_err(|m| self.at(f, "days_off_file", m))?;
                    chronomap_io::read_days_off(&file)
                        .map_err(|e| self.at(f, "days_off_file", e.to_string()))?
                } else {
                    DaysOff::default()
                };
                (Some(file), days)
            }
            _ => (None, DaysOff::default()),
        };
        let clock_topic = args
            .remap("/clock", false, &names.namespace, &names.name)
            .map_err(|e| self.error(None, Some("use_sim_time".into()), e.to_string()))?;
        let config = NodeConfig {
            clock_topic,
            file: path.to_path_buf(),
            node_name: node.name,
            namespace: node.namespace,
            use_sim_time: raw.use_sim_time.as_ref().is_some_and(|v| v.value),
            publish_period: self.seconds(&raw.publish_period, "publish_period", 1.0, false)?,
            map_period: self.seconds(&raw.map_period, "map_period", 30.0, false)?,
            horizon: self.seconds(&raw.horizon, "horizon", 0.0, true)?,
            save_dir,
            save_period: self.seconds(&raw.save_period, "save_period", 300.0, false)?,
            record_observations,
            sync_period,
            sync_messages,
            days_off_file,
            days_off,
            max_map_cells,
            memory_limit: match raw.memory_limit.as_ref().map(|v| v.value) {
                None => Some(DEFAULT_MEMORY_LIMIT),
                Some(0) => None,
                Some(bytes) => Some(bytes),
            },
            states,
            grids,
            edges,
        };
        self.distinct_topics(&config)?;
        if !allow_empty
            && config.states.is_empty()
            && config.grids.is_empty()
            && config.edges.is_none()
        {
            return Err(self.error(
                None,
                None,
                "nothing to do: no states, maps, people or edges".into(),
            ));
        }
        Ok(config)
    }

    fn unique_name<'n>(
        &self,
        kinds: &mut BTreeMap<&'n str, &'n str>,
        name: &'n str,
        section: &'n str,
        at: &Spanned<impl Sized>,
    ) -> Result<(), ConfigError> {
        check_token(name).map_err(|m| {
            self.at(
                at,
                &format!("{section}.{name}"),
                format!("the name {m} (it is part of topic names)"),
            )
        })?;
        if let Some(other) = kinds.insert(name, section) {
            return Err(self.at(
                at,
                &format!("{section}.{name}"),
                format!("the name is used by {other}.{name} too (names are shared by states, maps and people)"),
            ));
        }
        Ok(())
    }

    fn state(
        &self,
        name: &str,
        state: &Spanned<RawState>,
        names: &Names,
    ) -> Result<StateConfig, ConfigError> {
        let key = format!("states.{name}");
        let s = &state.value;
        let topic = self.topic(
            self.required(&s.topic, state, &format!("{key}.topic"))?,
            &format!("{key}.topic"),
            names,
        )?;
        let ty = self.required(&s.message, state, &format!("{key}.type"))?;
        let message = match ty.value.replace("/msg/", "/").as_str() {
            "std_msgs/Bool" => StateType::Bool,
            "std_msgs/Float32" => StateType::Float32,
            "std_msgs/Float64" => StateType::Float64,
            other => {
                return Err(self.at(
                    ty,
                    &format!("{key}.type"),
                    format!(
                        "{other:?} is not a state type; use std_msgs/msg/Bool, std_msgs/msg/Float32 \
                         or std_msgs/msg/Float64 (maps go under `maps`, people under `people`)"
                    ),
                ));
            }
        };
        let model = match &s.model {
            None => "fremen:2".parse().expect("a valid spec"),
            Some(m) => {
                let spec: ModelSpec =
                    m.value.parse().map_err(|e: chronomap_core::ConfigError| {
                        self.at(m, &format!("{key}.model"), e.to_string())
                    })?;
                spec.learner(1)
                    .map_err(|e| self.at(m, &format!("{key}.model"), e.to_string()))?;
                spec
            }
        };
        let online = model.online_model().is_ok();
        // Keep and refit policy belong to models fitted on a whole series.
        for (value, leaf) in [
            (s.keep.as_ref().map(|v| v.origin.clone()), "keep"),
            (
                s.refit_observations.as_ref().map(|v| v.origin.clone()),
                "refit_observations",
            ),
            (
                s.refit_period.as_ref().map(|v| v.origin.clone()),
                "refit_period",
            ),
        ] {
            if let (true, Some(origin)) = (online, value) {
                return Err(origin.error(
                    Some(&format!("{key}.{leaf}")),
                    format!(
                        "`{model}` learns online and is never refitted (models fitted on a \
                         whole series are: auto, fremen:auto, pergam:auto, fft:N, hypertime)"
                    ),
                ));
            }
        }
        let keep = match &s.keep {
            None => DEFAULT_KEEP,
            Some(v) if (1..=MAX_KEEP).contains(&v.value) => v.value as usize,
            Some(v) => {
                return Err(self.at(
                    v,
                    &format!("{key}.keep"),
                    format!("{} is not in 1..={MAX_KEEP} observations", v.value),
                ));
            }
        };
        let refit = RefitPolicy {
            observations: s
                .refit_observations
                .as_ref()
                .map_or(RefitPolicy::default().observations, |v| v.value),
            data_secs: self.seconds(
                &s.refit_period,
                &format!("{key}.refit_period"),
                RefitPolicy::default().data_secs,
                true,
            )?,
        };
        let qos = self.qos(
            &RawQos {
                reliability: &s.reliability,
                depth: &s.depth,
                transient_local: &s.transient_local,
            },
            &key,
            100,
            false,
        )?;
        let output = |value: &Option<Spanned<String>>, leaf: &str| match value {
            None => Ok(format!("{}/{name}/{leaf}", names.node)),
            Some(v) => self.topic(v, &format!("{key}.{leaf}_topic"), names),
        };
        let coverage = match &s.coverage {
            None => DEFAULT_COVERAGE,
            Some(c) if message == StateType::Bool => {
                return Err(self.at(
                    c,
                    &format!("{key}.coverage"),
                    "a std_msgs/msg/Bool state has no prediction interval (only Float32 and \
                     Float64 states have one)"
                        .to_string(),
                ));
            }
            Some(c) if !model.has_second_moment() => {
                return Err(self.at(
                    c,
                    &format!("{key}.coverage"),
                    format!(
                        "`{model}` gives no prediction interval (those that learn online and \
                         `auto` do)"
                    ),
                ));
            }
            Some(c) if c.value > 0.0 && c.value < 1.0 => c.value,
            Some(c) => {
                return Err(self.at(
                    c,
                    &format!("{key}.coverage"),
                    format!("{} is not strictly between 0 and 1", c.value),
                ));
            }
        };
        Ok(StateConfig {
            name: name.to_string(),
            topic,
            message,
            model,
            keep,
            refit,
            qos,
            coverage,
            probability_topic: output(&s.probability_topic, "probability")?,
            entropy_topic: output(&s.entropy_topic, "entropy")?,
            prediction_topic: match &s.prediction_topic {
                Some(v) if v.value.is_empty() => None,
                other => Some(output(other, "prediction")?),
            },
        })
    }

    fn qos(
        &self,
        raw: &RawQos<'_>,
        key: &str,
        depth: usize,
        transient_local: bool,
    ) -> Result<InputQos, ConfigError> {
        let reliability = match raw.reliability {
            None => Reliability::Reliable,
            Some(r) => match r.value.as_str() {
                "reliable" => Reliability::Reliable,
                "best_effort" => Reliability::BestEffort,
                other => {
                    return Err(self.at(
                        r,
                        &format!("{key}.reliability"),
                        format!("{other:?} is not reliable or best_effort"),
                    ));
                }
            },
        };
        let depth = match raw.depth {
            None => depth,
            Some(d) if (1..=10_000).contains(&d.value) => d.value as usize,
            Some(d) => {
                return Err(self.at(
                    d,
                    &format!("{key}.depth"),
                    format!("{} is not in 1..=10000", d.value),
                ));
            }
        };
        Ok(InputQos {
            reliability,
            depth,
            transient_local: raw
                .transient_local
                .as_ref()
                .map_or(transient_local, |t| t.value),
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn grid(
        &self,
        name: &str,
        key: &str,
        source: GridSource,
        topic: String,
        qos: InputQos,
        raw: &RawGrid,
        default_values: MapValues,
        names: &Names,
    ) -> Result<GridEntry, ConfigError> {
        let frame_id = match &raw.frame_id {
            None => "map".to_string(),
            Some(f) if !f.value.is_empty() => f.value.clone(),
            Some(f) => return Err(self.at(f, &format!("{key}.frame_id"), "empty".into())),
        };
        let periods: PeriodSet = match &raw.periods {
            None => PeriodSet::default(),
            Some(p) => p.value.parse().map_err(|e: chronomap_core::ConfigError| {
                self.at(p, &format!("{key}.periods"), e.to_string())
            })?,
        };
        let mut fremen = FremenConfig {
            periods,
            order: 2,
            ..FremenConfig::default()
        };
        if let Some(order) = &raw.order {
            let model = FremenModel::new(fremen.clone())
                .map_err(|e| self.at(order, &format!("{key}.order"), e.to_string()))?;
            if order.value > model.max_order() as u64 {
                return Err(self.at(
                    order,
                    &format!("{key}.order"),
                    format!(
                        "order {} is above the largest order {} of these periods",
                        order.value,
                        model.max_order()
                    ),
                ));
            }
            fremen.order = order.value as usize;
        }
        FremenModel::new(fremen.clone())
            .map_err(|e| self.error(None, Some(format!("{key}.periods")), e.to_string()))?;
        let values = match &raw.values {
            None => default_values,
            Some(v) => match v.value.as_str() {
                "trinary" => MapValues::Trinary,
                "scale" => MapValues::Scale,
                "probability" => MapValues::Probability,
                other => {
                    return Err(self.at(
                        v,
                        &format!("{key}.values"),
                        format!("{other:?} is not trinary, scale or probability"),
                    ));
                }
            },
        };
        let output = |value: &Option<Spanned<String>>, leaf: &str, param: &str| match value {
            None => Ok(Some(format!("{}/{name}/{leaf}", names.node))),
            Some(v) if v.value.is_empty() => Ok(None),
            Some(v) => self.topic(v, &format!("{key}.{param}"), names).map(Some),
        };
        let predicted_topic = output(&raw.predicted_topic, "predicted_map", "predicted_topic")?
            .ok_or_else(|| {
                self.error(
                    None,
                    Some(format!("{key}.predicted_topic")),
                    "empty (the predicted map is always published)".into(),
                )
            })?;
        let mask = output(&raw.mask_topic, "mask", "mask_topic")?;
        let info = output(&raw.filter_info_topic, "filter_info", "filter_info_topic")?;
        let filter = match (mask, info) {
            (Some(mask_topic), Some(info_topic)) => {
                let filter_type = raw.filter_type.as_ref().map_or(0, |t| t.value);
                if let Some(t) = &raw.filter_type
                    && t.value > 3
                {
                    return Err(self.at(
                        t,
                        &format!("{key}.filter_type"),
                        format!(
                            "{} is not a Nav2 filter type (0 keepout, 1 speed limit in %, 2 speed limit in m/s, 3 binary)",
                            t.value
                        ),
                    ));
                }
                let finite = |v: &Option<Spanned<f32>>, leaf: &str, default: f32| match v {
                    None => Ok(default),
                    Some(x) if x.value.is_finite() => Ok(x.value),
                    Some(x) => Err(self.at(
                        x,
                        &format!("{key}.{leaf}"),
                        format!("{} is not finite", x.value),
                    )),
                };
                Some(FilterConfig {
                    mask_topic,
                    info_topic,
                    filter_type: filter_type as u8,
                    base: finite(&raw.filter_base, "filter_base", 0.0)?,
                    multiplier: finite(&raw.filter_multiplier, "filter_multiplier", 1.0)?,
                })
            }
            (None, None) => None,
            _ => {
                return Err(self.error(
                    None,
                    Some(format!("{key}.mask_topic")),
                    "mask_topic and filter_info_topic are disabled (\"\") together or not at all"
                        .into(),
                ));
            }
        };
        Ok(GridEntry {
            name: name.to_string(),
            source,
            topic,
            qos,
            frame_id,
            fremen,
            values,
            predicted_topic,
            filter,
        })
    }

    /// A topic name resolved as ROS 2 resolves it: `/abs`, `rel` (in the node's namespace) or
    /// `~/private` (under the node's name).
    fn topic(
        &self,
        value: &Spanned<String>,
        key: &str,
        names: &Names,
    ) -> Result<String, ConfigError> {
        let resolved = resolve_topic(&value.value, &names.namespace, &names.node)
            .map_err(|m| self.at(value, key, m))?;
        names
            .args
            .remap(&resolved, false, &names.namespace, &names.name)
            .map_err(|e| self.at(value, key, e.to_string()))
    }

    fn distinct_topics(&self, config: &NodeConfig) -> Result<(), ConfigError> {
        let mut seen: BTreeMap<String, String> = BTreeMap::new();
        let state_of = |key: &str| {
            config
                .states
                .iter()
                .find(|s| format!("states.{}.topic", s.name) == key)
        };
        for (topic, _, key) in config.inputs() {
            if let Some(other) = seen.get(&topic) {
                // Several states (several models) may learn one topic, read once.
                match (state_of(&key), state_of(other)) {
                    (Some(a), Some(b)) if a.message == b.message && a.qos == b.qos => continue,
                    (Some(a), Some(b)) => {
                        let why = if a.message == b.message {
                            "another reliability, depth or transient_local (states of one \
                             topic share its subscription)"
                                .to_string()
                        } else {
                            format!(
                                "type {}, not {} (states of one topic share its type)",
                                b.message.type_name(),
                                a.message.type_name()
                            )
                        };
                        return Err(self.error(
                            None,
                            Some(key.clone()),
                            format!("{topic} is also the topic of states.{}, with {why}", b.name),
                        ));
                    }
                    _ => {
                        return Err(self.error(
                            None,
                            Some(key),
                            format!(
                                "{topic} is also the topic of {other} (an input topic is read \
                                 once; only states may share one)"
                            ),
                        ));
                    }
                }
            }
            seen.insert(topic, key);
        }
        let mut outputs: BTreeMap<String, ()> = BTreeMap::new();
        for (topic, _) in config.outputs() {
            if let Some(input) = seen.get(&topic) {
                return Err(self.error(
                    None,
                    Some(input.clone()),
                    format!("{topic} is also a topic the node publishes"),
                ));
            }
            if outputs.insert(topic.clone(), ()).is_some() {
                return Err(self.error(
                    None,
                    None,
                    format!("{topic} is published twice (two outputs have this topic)"),
                ));
            }
        }
        Ok(())
    }
}

struct Names<'a> {
    namespace: String,
    node: String,
    name: String,
    args: &'a RosArgs,
}

/// `name` as a ROS name token: a letter or `_`, then letters, digits and single `_`.
fn check_token(name: &str) -> Result<(), String> {
    let mut chars = name.chars();
    let ok = matches!(chars.next(), Some(c) if c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
        && !name.contains("__");
    if ok {
        Ok(())
    } else {
        Err(format!(
            "{name:?} is not a ROS name token (a letter or '_', then letters, digits and single '_')"
        ))
    }
}

/// The fully qualified name of the topic `name` of a node `node` in `namespace`.
///
/// # Errors
/// A name that is empty, has empty, repeated-underscore or otherwise invalid tokens, or uses
/// substitutions (`{...}`).
pub fn resolve_topic(name: &str, namespace: &str, node: &str) -> Result<String, String> {
    let full = if let Some(rest) = name.strip_prefix("~/") {
        format!("{node}/{rest}")
    } else if name.starts_with('/') {
        name.to_string()
    } else if namespace == "/" {
        format!("/{name}")
    } else {
        format!("{namespace}/{name}")
    };
    let bad = |why: &str| Err(format!("{name:?} is not a valid topic name: {why}"));
    if name.is_empty() || name == "~" || name == "/" {
        return bad("empty");
    }
    for token in full[1..].split('/') {
        if token.is_empty() {
            return bad("empty token (`//` or a trailing `/`)");
        }
        if let Err(why) = check_token(token) {
            return bad(&why);
        }
    }
    ros2_client::Name::parse(&full)
        .map_err(|e| format!("{name:?} is not a valid topic name: {e}"))?;
    Ok(full)
}

#[cfg(test)]
mod tests;
