//! `chronomap ros2`: the ROS 2 node (`chronomap-ros2`). Reads the parameters (the parameter
//! file and the ROS arguments), installs the node's logger ([`chronomap_ros2::console`]) and
//! the signal handlers, runs the node and prints what it learned.

use anyhow::{Context, Result, anyhow};
use chronomap_ros2::config::{NodeConfig, Setup};
use chronomap_ros2::log::LevelFilter;
use chronomap_ros2::node::{self, RunOptions};
use chronomap_ros2::ros_args::RosArgs;
use chronomap_ros2::{console, signals};
use serde_json::json;

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
    console::install(
        &setup.fully_qualified_name(),
        &ros,
        level(args.log_level),
        level(args.dds_log_level),
    );
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
                "days_off": l.days_off,
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
                "states.{name}: learned {} observations ({} in the model){}",
                l.observations,
                l.total,
                if l.days_off > 0 {
                    format!("; {} on days off, not learned", l.days_off)
                } else {
                    String::new()
                }
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
    let topics = chronomap_ros2::topics::topics(config);
    if args.json {
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
            "days_off": config.days_off_file.as_ref().map(|f| json!({
                "file": f.display().to_string(), "days": config.days_off.len(),
            })),
            "topics": topics,
        }));
    }
    outln!(
        "node {}: {} states, {} grids{}{}; parameters are valid",
        config.fully_qualified_name(),
        config.states.len(),
        config.grids.len(),
        if config.edges.is_some() {
            ", a route graph"
        } else {
            ""
        },
        match &config.days_off_file {
            Some(file) => format!(", {} days off ({})", config.days_off.len(), file.display()),
            None => String::new(),
        }
    )?;
    let mut table = Table::new(["", "topic", "type", "QoS"]);
    for t in topics {
        table.row([t.direction.to_owned(), t.topic, t.type_name, t.qos]);
    }
    outln!("{}", table.render())?;
    Ok(())
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
