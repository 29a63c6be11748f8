//! `chronomap ros2`: the ROS 2 node (`chronomap-ros2`). Reads the parameters (the parameter
//! file and the ROS arguments), installs the logger and the signal handlers, runs the node and
//! prints what it learned.

use std::io::Write;
use std::sync::OnceLock;

use anyhow::{Context, Result, anyhow};
use chronomap_ros2::config::{GridSource, NodeConfig, Reliability, Setup};
use chronomap_ros2::log::{self, Level, LevelFilter, Log, Metadata, Record};
use chronomap_ros2::node::{self, RunOptions};
use chronomap_ros2::ros_args::{RosArgs, Severity};
use chronomap_ros2::{rosout, signals};
use serde_json::{Value, json};

use crate::cli::{LogLevelArg, Ros2Args};
use crate::format::Table;
use crate::outln;
use crate::output::{print_json, usage};

/// The ROS arguments of the command line (everything after `--ros-args`).
fn ros_args(args: &Ros2Args) -> Result<RosArgs> {
    let Some(list) = &args.ros_args else {
        return Ok(RosArgs::default());
    };
    let parsed =
        RosArgs::parse(std::iter::once("--ros-args").chain(list.iter().map(String::as_str)))
            .map_err(|e| usage(e.to_string()))?;
    if let Some(extra) = parsed.other.first() {
        return Err(usage(format!(
            "--ros-args: `{extra}` after `--`: chronomap's own flags go before --ros-args"
        )));
    }
    Ok(parsed)
}

pub fn run(args: &Ros2Args) -> Result<()> {
    let ros = ros_args(args)?;
    if args.config.is_none() && args.ros_args.is_none() {
        return Err(usage(
            "the node's parameters: give --config FILE, or --ros-args with --params-file FILE \
             or -p NAME:=VALUE",
        ));
    }
    let setup = Setup::new(
        args.config.as_deref(),
        args.node_name.as_deref(),
        ros.clone(),
    )?;
    let config = if args.managed {
        setup.config_allowing_empty()?
    } else {
        setup.config()?
    };
    if args.check {
        return check(args, &config);
    }
    install_logger(&setup.fully_qualified_name(), args, &ros);
    let stop = signals::stop_on_signals().context("cannot install the signal handlers")?;
    let options = RunOptions {
        domain_id: args.domain_id,
        managed: args.managed,
        rosout: ros.rosout_logs != Some(false),
    };
    let summary = node::run(setup, &options, &stop)?;
    let refused: u64 = summary.refused.values().sum();
    let saved = summary.save_error.is_none() && config.save_dir.is_some() && summary.configured;
    if args.json {
        print_json(&json!({
            "node": config.fully_qualified_name(),
            "states": summary.states.iter().map(|(name, l)| json!({
                "name": name, "learned": l.observations, "total": l.total,
            })).collect::<Vec<_>>(),
            "grids": summary.grids.iter().map(|(section, name, l)| json!({
                "section": section, "name": name, "frames": l.observations, "total": l.total,
            })).collect::<Vec<_>>(),
            "refused": summary.refused,
            "saved": saved,
        }))?;
    } else {
        for (name, l) in &summary.states {
            outln!(
                "states.{name}: learned {} observations ({} in the model)",
                l.observations,
                l.total
            )?;
        }
        for (section, name, l) in &summary.grids {
            outln!(
                "{section}.{name}: learned {} frames ({} in the grid)",
                l.observations,
                l.total
            )?;
        }
        if refused > 0 {
            outln!("{refused} messages refused (see the log)")?;
        }
    }
    match (summary.save_error, &config.save_dir) {
        (Some(e), _) => Err(anyhow!("saving at shutdown: {e}")),
        (None, Some(dir)) if saved => {
            if !args.json {
                outln!("saved in {}", dir.display())?;
            }
            Ok(())
        }
        _ => Ok(()),
    }
}

/// `--check`: the topics the node would subscribe to and publish.
fn check(args: &Ros2Args, config: &NodeConfig) -> Result<()> {
    let qos = |r: Reliability, depth: usize, latched: bool| {
        format!(
            "{}, keep last {depth}{}",
            match r {
                Reliability::Reliable => "reliable",
                Reliability::BestEffort => "best effort",
            },
            if latched { ", transient local" } else { "" }
        )
    };
    let latched = "reliable, keep last 1, transient local".to_string();
    let mut rows: Vec<[String; 4]> = Vec::new();
    if config.use_sim_time {
        rows.push([
            "in".into(),
            "/clock".into(),
            "rosgraph_msgs/msg/Clock".into(),
            "best effort, keep last 1000".into(),
        ]);
    }
    for s in &config.states {
        rows.push([
            "in".into(),
            s.topic.clone(),
            s.message.type_name().to_string(),
            qos(s.qos.reliability, s.qos.depth, s.qos.transient_local),
        ]);
        for topic in [&s.probability_topic, &s.entropy_topic] {
            rows.push([
                "out".into(),
                topic.clone(),
                "std_msgs/msg/Float64".into(),
                latched.clone(),
            ]);
        }
    }
    for g in &config.grids {
        let ty = match g.source {
            GridSource::Map => "nav_msgs/msg/OccupancyGrid",
            GridSource::People { .. } => "geometry_msgs/msg/PoseArray",
        };
        rows.push([
            "in".into(),
            g.topic.clone(),
            ty.into(),
            qos(g.qos.reliability, g.qos.depth, g.qos.transient_local),
        ]);
        rows.push([
            "out".into(),
            g.predicted_topic.clone(),
            "nav_msgs/msg/OccupancyGrid".into(),
            latched.clone(),
        ]);
        if let Some(f) = &g.filter {
            rows.push([
                "out".into(),
                f.mask_topic.clone(),
                "nav_msgs/msg/OccupancyGrid".into(),
                latched.clone(),
            ]);
            rows.push([
                "out".into(),
                f.info_topic.clone(),
                "nav2_msgs/msg/CostmapFilterInfo".into(),
                latched.clone(),
            ]);
        }
    }
    if args.json {
        let topics: Vec<Value> = rows
            .iter()
            .map(|[direction, topic, ty, qos]| {
                json!({"direction": direction, "topic": topic, "type": ty, "qos": qos})
            })
            .collect();
        return print_json(&json!({
            "node": config.fully_qualified_name(),
            "use_sim_time": config.use_sim_time,
            "horizon": config.horizon,
            "states": config.states.iter().map(|s| json!({
                "name": s.name, "topic": s.topic, "model": s.model.to_string(),
            })).collect::<Vec<_>>(),
            "grids": config.grids.iter().map(|g| json!({
                "section": g.section(), "name": g.name, "topic": g.topic,
                "order": g.fremen.order, "periods": g.fremen.periods.to_string(),
            })).collect::<Vec<_>>(),
            "edges": config.edges.as_ref().map(|e| json!({
                "models": e.models.display().to_string(),
                "geojson": e.geojson.display().to_string(),
                "period": e.period,
            })),
            "save_dir": config.save_dir.as_ref().map(|d| d.display().to_string()),
            "topics": topics,
        }));
    }
    outln!(
        "node {}: {} states, {} grids{}; parameters are valid",
        config.fully_qualified_name(),
        config.states.len(),
        config.grids.len(),
        if config.edges.is_some() {
            ", a route graph"
        } else {
            ""
        }
    )?;
    let mut table = Table::new(["", "topic", "type", "QoS"]);
    for row in rows {
        table.row(row);
    }
    outln!("{}", table.render())?;
    Ok(())
}

/// Log lines on stderr, as ROS 2 console output looks: `[LEVEL] [unix time] [logger]: text`;
/// the node's lines also go to `/rosout` while the node runs.
struct NodeLogger {
    node: String,
    node_level: LevelFilter,
    dds_level: LevelFilter,
    stderr: bool,
}

impl NodeLogger {
    fn ours(target: &str) -> bool {
        target.starts_with("chronomap")
    }
}

impl Log for NodeLogger {
    fn enabled(&self, metadata: &Metadata) -> bool {
        // ros2-client's /rosout publisher enters a `tracing` span and repeats each line as a
        // `tracing` event, which `tracing` reports through `log` when nothing subscribes to
        // it: the line is on stderr already.
        if metadata.target().starts_with("tracing::") || metadata.target() == "ros2_client::rosout"
        {
            return false;
        }
        let level = if Self::ours(metadata.target()) {
            self.node_level
        } else {
            self.dds_level
        };
        metadata.level() <= level
    }

    fn log(&self, record: &Record) {
        if !self.enabled(record.metadata()) {
            return;
        }
        let ours = Self::ours(record.target());
        if ours {
            rosout::forward(record);
        }
        if !self.stderr {
            return;
        }
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        let logger = if ours {
            self.node.as_str()
        } else {
            record.target()
        };
        let level = match record.level() {
            Level::Error => "ERROR",
            Level::Warn => "WARN",
            Level::Info => "INFO",
            Level::Debug => "DEBUG",
            Level::Trace => "TRACE",
        };
        // One write per line, so that lines of threads do not interleave; a closed stderr
        // is not worth dying for.
        let line = format!("[{level}] [{now:.3}] [{logger}]: {}\n", record.args());
        let _ = std::io::stderr().lock().write_all(line.as_bytes());
    }

    fn flush(&self) {}
}

fn level(arg: LogLevelArg) -> LevelFilter {
    match arg {
        LogLevelArg::Off => LevelFilter::Off,
        LogLevelArg::Error => LevelFilter::Error,
        LogLevelArg::Warn => LevelFilter::Warn,
        LogLevelArg::Info => LevelFilter::Info,
        LogLevelArg::Debug => LevelFilter::Debug,
        LogLevelArg::Trace => LevelFilter::Trace,
    }
}

/// `--ros-args --log-level` as a filter (the node logs nothing more severe than errors, so
/// `fatal` shows nothing).
fn severity(severity: Severity) -> LevelFilter {
    match severity {
        Severity::Debug => LevelFilter::Debug,
        Severity::Info => LevelFilter::Info,
        Severity::Warn => LevelFilter::Warn,
        Severity::Error => LevelFilter::Error,
        Severity::Fatal => LevelFilter::Off,
    }
}

fn install_logger(fqn: &str, args: &Ros2Args, ros: &RosArgs) {
    static LOGGER: OnceLock<NodeLogger> = OnceLock::new();
    let name = rosout::logger_name(fqn);
    let node_level = ros
        .severity(&name)
        .map_or_else(|| level(args.log_level), severity);
    let dds_level = match ros.external_lib_logs {
        Some(false) => LevelFilter::Off,
        _ => level(args.dds_log_level),
    };
    let logger = LOGGER.get_or_init(|| NodeLogger {
        node: name,
        node_level,
        dds_level,
        stderr: ros.stdout_logs != Some(false),
    });
    if log::set_logger(logger).is_ok() {
        log::set_max_level(node_level.max(dds_level));
    }
}
