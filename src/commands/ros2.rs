//! `chronomap ros2`: the ROS 2 node (`chronomap-ros2`). Reads the parameter file, installs the
//! logger and the signal handlers, runs the node and prints what it learned.

use std::io::Write;
use std::sync::OnceLock;

use anyhow::{Context, Result, anyhow};
use chronomap_ros2::config::{GridSource, NodeConfig, Reliability};
use chronomap_ros2::log::{self, Level, LevelFilter, Log, Metadata, Record};
use chronomap_ros2::{World, node, signals};
use serde_json::{Value, json};

use crate::cli::{LogLevelArg, Ros2Args};
use crate::format::Table;
use crate::outln;
use crate::output::print_json;

pub fn run(args: &Ros2Args) -> Result<()> {
    let config = NodeConfig::read(&args.config, args.node_name.as_deref())?;
    if args.check {
        return check(args, &config);
    }
    install_logger(&config.fully_qualified_name(), args);
    let stop = signals::stop_on_signals().context("cannot install the signal handlers")?;
    let world = World::new(config.clone()).context("cannot restore the models")?;
    let summary = node::run(world, args.domain_id, &stop)?;
    let refused: u64 = summary.refused.values().sum();
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
            "saved": summary.save_error.is_none() && config.save_dir.is_some(),
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
        (None, Some(dir)) => {
            if !args.json {
                outln!("saved in {}", dir.display())?;
            }
            Ok(())
        }
        (None, None) => Ok(()),
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

/// Log lines on stderr, as ROS 2 console output looks: `[LEVEL] [unix time] [logger]: text`.
struct StderrLogger {
    node: String,
    node_level: LevelFilter,
    dds_level: LevelFilter,
}

impl StderrLogger {
    fn ours(target: &str) -> bool {
        target.starts_with("chronomap")
    }
}

impl Log for StderrLogger {
    fn enabled(&self, metadata: &Metadata) -> bool {
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
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        let logger = if Self::ours(record.target()) {
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

fn install_logger(node: &str, args: &Ros2Args) {
    static LOGGER: OnceLock<StderrLogger> = OnceLock::new();
    let (node_level, dds_level) = (level(args.log_level), level(args.dds_log_level));
    let logger = LOGGER.get_or_init(|| StderrLogger {
        node: node.trim_start_matches('/').to_string(),
        node_level,
        dds_level,
    });
    if log::set_logger(logger).is_ok() {
        log::set_max_level(node_level.max(dds_level));
    }
}
