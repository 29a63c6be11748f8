//! The node's parameter file: ROS 2's YAML layout (`NODE: {ros__parameters: {...}}`, as
//! `ros2 run ... --ros-args --params-file` reads it), parsed with
//! [serde-saphyr](https://docs.rs/serde-saphyr) and checked completely before the node starts.
//! Every error names the file, the line and the parameter (`node.yaml:12: states.door.model:
//! ...`). The parameters are described in `docs/ros2.md`.
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
//! let bad = "chronomap:\n  ros__parameters:\n    states:\n      door:\n        topic: /door\n        type: std_msgs/msg/Bool\n        model: fremen:auto\n";
//! let error = NodeConfig::parse("node.yaml".as_ref(), bad.as_bytes(), None).unwrap_err();
//! assert!(error.to_string().starts_with("node.yaml:7: states.door.model: `fremen:auto`: learning online needs a fixed order"));
//! # Ok::<(), chronomap_ros2::config::ConfigError>(())
//! ```

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use chronomap_core::{FremenConfig, FremenModel, Ordered, PeriodSet};
use chronomap_models::{AnyModel, ModelSpec};
use serde::Deserialize;
use serde_saphyr::Spanned;

use crate::msgs::{Bool, Float32, Float64, Message, TypeName};

/// Largest parameter file read (the node's parameters fit in a few kilobytes).
const MAX_FILE_BYTES: u64 = 1 << 20;

/// Default of `max_map_cells`: 2²⁴ cells (a 4096 × 4096 map).
pub const DEFAULT_MAX_MAP_CELLS: u64 = 1 << 24;

/// Largest `max_map_cells` accepted: 2³⁰ cells.
const MAX_MAX_MAP_CELLS: u64 = 1 << 30;

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
    /// The model learned.
    pub model: ModelSpec,
    /// Subscription settings.
    pub qos: InputQos,
    /// Where p(now + horizon) is published (`std_msgs/msg/Float64`).
    pub probability_topic: String,
    /// Where its entropy in bits is published (`std_msgs/msg/Float64`).
    pub entropy_topic: String,
}

impl StateConfig {
    /// The empty model of this state.
    pub fn empty_model(&self) -> AnyModel {
        self.model
            .online_model()
            .expect("checked when the configuration was read")
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
    /// Largest map accepted, in cells.
    pub max_map_cells: u64,
    /// State topics, by name.
    pub states: Vec<StateConfig>,
    /// Grids (maps, then people), by name.
    pub grids: Vec<GridEntry>,
    /// The route graph, if any.
    pub edges: Option<EdgesConfig>,
}

impl NodeConfig {
    /// Reads and checks the parameter file `path`; `node` picks the node's entry in a file
    /// for several nodes (default: the only entry).
    ///
    /// # Errors
    /// A file that cannot be read or is not a valid parameter file, naming file, line and
    /// parameter.
    pub fn read(path: &Path, node: Option<&str>) -> Result<NodeConfig, ConfigError> {
        let name = path.display().to_string();
        let error = |message: String| ConfigError {
            file: name.clone(),
            line: None,
            key: None,
            message,
        };
        let file = std::fs::File::open(path).map_err(|e| error(format!("cannot read: {e}")))?;
        let mut bytes = Vec::new();
        use std::io::Read;
        file.take(MAX_FILE_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(|e| error(format!("cannot read: {e}")))?;
        if bytes.len() as u64 > MAX_FILE_BYTES {
            return Err(error(format!(
                "larger than {MAX_FILE_BYTES} bytes: not a parameter file"
            )));
        }
        Self::parse(path, &bytes, node)
    }

    /// Checks the text of the parameter file `path` (relative paths in it are relative to its
    /// folder).
    ///
    /// # Errors
    /// As [`NodeConfig::read`].
    pub fn parse(path: &Path, text: &[u8], node: Option<&str>) -> Result<NodeConfig, ConfigError> {
        let file = path.display().to_string();
        let options = serde_saphyr::options! {
            strict_booleans: true,
            with_snippet: false,
        };
        let top: BTreeMap<String, Spanned<RawNode>> =
            serde_saphyr::from_slice_with_options(text, options).map_err(|e| ConfigError {
                file: file.clone(),
                line: e.location().map(|l| l.line()),
                key: None,
                message: parser_message(&e),
            })?;
        let checker = Checker { file: &file };
        let (key, entry) = match node {
            Some(node) => top
                .iter()
                .find(|(k, _)| k.as_str() == node || k.rsplit('/').next() == Some(node))
                .or_else(|| top.iter().find(|(k, _)| k.as_str() == "/**"))
                .ok_or_else(|| {
                    checker.error(
                        None,
                        None,
                        format!(
                            "no parameters for node {node:?} (entries: {})",
                            top.keys().cloned().collect::<Vec<_>>().join(", ")
                        ),
                    )
                })?,
            None => {
                let mut entries = top.iter();
                match (entries.next(), entries.next()) {
                    (Some(only), None) => only,
                    (None, _) => {
                        return Err(checker.error(
                            None,
                            None,
                            "no node entry (expected `NODE_NAME: {ros__parameters: {...}}`)".into(),
                        ));
                    }
                    (Some(_), Some(_)) => {
                        return Err(checker.error(
                            None,
                            None,
                            format!(
                                "entries for several nodes ({}): choose one with --node-name",
                                top.keys().cloned().collect::<Vec<_>>().join(", ")
                            ),
                        ));
                    }
                }
            }
        };
        let (namespace, node_name) = node_identity(key, node)
            .map_err(|m| checker.error(Some(entry.referenced.line()), None, m))?;
        let folder = path.parent().unwrap_or(Path::new("")).to_path_buf();
        checker.check(
            &entry.value.params,
            NodeIdentity {
                namespace,
                name: node_name,
            },
            path,
            &folder,
        )
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
                "/clock".into(),
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

fn fully_qualified(namespace: &str, name: &str) -> String {
    if namespace == "/" {
        format!("/{name}")
    } else {
        format!("{namespace}/{name}")
    }
}

/// The parser's message without its location (the error carries the line).
fn parser_message(error: &serde_saphyr::Error) -> String {
    let mut message = error.without_snippet().to_string();
    if let Some(at) = message.rfind(" at line ") {
        message.truncate(at);
    }
    if let Some(rest) = message.strip_prefix("duplicate mapping key: ") {
        let key = rest.split(',').next().unwrap_or(rest);
        format!("the key `{key}` appears twice")
    } else if message.starts_with("multiple YAML documents") {
        "several YAML documents (a parameter file has one)".to_owned()
    } else {
        message
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

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNode {
    #[serde(rename = "ros__parameters")]
    params: RawParams,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawParams {
    use_sim_time: Option<Spanned<bool>>,
    publish_period: Option<Spanned<f64>>,
    map_period: Option<Spanned<f64>>,
    horizon: Option<Spanned<f64>>,
    save_dir: Option<Spanned<String>>,
    save_period: Option<Spanned<f64>>,
    record_observations: Option<Spanned<bool>>,
    max_map_cells: Option<Spanned<u64>>,
    #[serde(default)]
    states: BTreeMap<String, Spanned<RawState>>,
    #[serde(default)]
    maps: BTreeMap<String, Spanned<RawGrid>>,
    #[serde(default)]
    people: BTreeMap<String, Spanned<RawGrid>>,
    edges: Option<Spanned<RawEdges>>,
}

/// The subscription keys every input topic has.
struct RawQos<'a> {
    reliability: &'a Option<Spanned<String>>,
    depth: &'a Option<Spanned<u64>>,
    transient_local: &'a Option<Spanned<bool>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawState {
    topic: Option<Spanned<String>>,
    #[serde(rename = "type")]
    message: Option<Spanned<String>>,
    model: Option<Spanned<String>>,
    reliability: Option<Spanned<String>>,
    depth: Option<Spanned<u64>>,
    transient_local: Option<Spanned<bool>>,
    probability_topic: Option<Spanned<String>>,
    entropy_topic: Option<Spanned<String>>,
}

/// `maps.NAME` and `people.NAME` (the geometry and bin keys are for people only).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
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
    filter_type: Option<Spanned<u8>>,
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

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEdges {
    models: Option<Spanned<String>>,
    geojson: Option<Spanned<String>>,
    period: Option<Spanned<f64>>,
}

struct Checker<'a> {
    file: &'a str,
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
        self.error(
            Some(value.referenced.line()),
            Some(key.to_string()),
            message,
        )
    }

    fn required<'v, T>(
        &self,
        value: &'v Option<Spanned<T>>,
        section: &Spanned<impl Sized>,
        key: &str,
    ) -> Result<&'v Spanned<T>, ConfigError> {
        value.as_ref().ok_or_else(|| {
            self.error(
                Some(section.referenced.line()),
                Some(key.to_string()),
                "missing (required)".into(),
            )
        })
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
        folder: &Path,
    ) -> Result<NodeConfig, ConfigError> {
        let names = Names {
            namespace: node.namespace.clone(),
            node: fully_qualified(&node.namespace, &node.name),
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
                (map.value.width.as_ref().map(|v| &v.referenced), "width"),
                (map.value.height.as_ref().map(|v| &v.referenced), "height"),
                (
                    map.value.resolution.as_ref().map(|v| &v.referenced),
                    "resolution",
                ),
                (map.value.origin.as_ref().map(|v| &v.referenced), "origin"),
                (map.value.bin.as_ref().map(|v| &v.referenced), "bin"),
            ] {
                if let Some(at) = value {
                    return Err(self.error(
                        Some(at.line()),
                        Some(format!("{key}.{leaf}")),
                        "only people grids have this key (a map's geometry comes from its messages)"
                            .into(),
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
                Some(EdgesConfig {
                    models: folder.join(&models.value),
                    geojson: folder.join(&geojson.value),
                    period: self.seconds(&e.value.period, "edges.period", 60.0, false)?,
                })
            }
        };
        let save_dir = match &raw.save_dir {
            Some(d) if d.value.is_empty() => {
                return Err(self.at(d, "save_dir", "an empty folder name".into()));
            }
            Some(d) => Some(folder.join(&d.value)),
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
        let config = NodeConfig {
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
            max_map_cells,
            states,
            grids,
            edges,
        };
        self.distinct_topics(&config)?;
        if config.states.is_empty() && config.grids.is_empty() && config.edges.is_none() {
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
                spec.online_model()
                    .map_err(|e| self.at(m, &format!("{key}.model"), e.to_string()))?;
                spec
            }
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
        Ok(StateConfig {
            name: name.to_string(),
            topic,
            message,
            model,
            qos,
            probability_topic: output(&s.probability_topic, "probability")?,
            entropy_topic: output(&s.entropy_topic, "entropy")?,
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
                    filter_type,
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
        resolve_topic(&value.value, &names.namespace, &names.node)
            .map_err(|m| self.at(value, key, m))
    }

    fn distinct_topics(&self, config: &NodeConfig) -> Result<(), ConfigError> {
        let mut seen: BTreeMap<String, String> = BTreeMap::new();
        for (topic, _, key) in config.inputs() {
            if let Some(other) = seen.insert(topic.clone(), key.clone()) {
                return Err(self.error(
                    None,
                    Some(key),
                    format!("{topic} is also the topic of {other} (each input topic once)"),
                ));
            }
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

struct Names {
    namespace: String,
    node: String,
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
