//! The node's log lines on stderr, as ROS 2 console output looks (`[LEVEL] [unix time]
//! [logger]: text`), and on `/rosout` while the node runs ([`crate::rosout`]): the logger a
//! program installs before it runs the node, with the levels of its flags and of the ROS
//! arguments (`--log-level`, `--disable-stdout-logs`, `--disable-external-lib-logs`).

use std::io::Write as _;
use std::sync::OnceLock;

use log::{Level, LevelFilter, Log, Metadata, Record};

use crate::ros_args::{RosArgs, Severity};
use crate::rosout;

/// The logger: the node's records (targets `chronomap…`) at `node_level`, those of the DDS
/// libraries at `dds_level`.
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
        // One write per line, so that lines of threads do not interleave; a closed stderr
        // is not worth dying for.
        let line = format!(
            "[{}] [{now:.3}] [{logger}]: {}\n",
            label(record.level()),
            record.args()
        );
        let _ = std::io::stderr().lock().write_all(line.as_bytes());
    }

    fn flush(&self) {}
}

/// `ERROR`, `WARN`, `INFO`, `DEBUG`, `TRACE`.
fn label(level: Level) -> &'static str {
    match level {
        Level::Error => "ERROR",
        Level::Warn => "WARN",
        Level::Info => "INFO",
        Level::Debug => "DEBUG",
        Level::Trace => "TRACE",
    }
}

/// `--ros-args --log-level` as a filter (the node logs nothing more severe than errors, so
/// `fatal` shows nothing).
pub fn filter(severity: Severity) -> LevelFilter {
    match severity {
        Severity::Debug => LevelFilter::Debug,
        Severity::Info => LevelFilter::Info,
        Severity::Warn => LevelFilter::Warn,
        Severity::Error => LevelFilter::Error,
        Severity::Fatal => LevelFilter::Off,
    }
}

/// The levels of the node's lines and of the DDS libraries' lines: `node_level` and
/// `dds_level` unless the ROS arguments set the node's logger's level (by its name, rcl's
/// [`rosout::logger_name`] of `fqn`) or turn the libraries' lines off.
pub fn levels(
    fqn: &str,
    ros: &RosArgs,
    node_level: LevelFilter,
    dds_level: LevelFilter,
) -> (LevelFilter, LevelFilter) {
    let node = ros
        .severity(&rosout::logger_name(fqn))
        .map_or(node_level, filter);
    let dds = match ros.external_lib_logs {
        Some(false) => LevelFilter::Off,
        _ => dds_level,
    };
    (node, dds)
}

/// Installs the logger of the node `fqn` for this process, at the [`levels`] of `ros`,
/// `node_level` and `dds_level`; lines go to stderr unless the ROS arguments turn them off
/// (`--disable-stdout-logs`). A second call (or another logger installed before) changes
/// nothing.
pub fn install(fqn: &str, ros: &RosArgs, node_level: LevelFilter, dds_level: LevelFilter) {
    static LOGGER: OnceLock<NodeLogger> = OnceLock::new();
    let (node_level, dds_level) = levels(fqn, ros, node_level, dds_level);
    let logger = LOGGER.get_or_init(|| NodeLogger {
        node: rosout::logger_name(fqn),
        node_level,
        dds_level,
        stderr: ros.stdout_logs != Some(false),
    });
    if log::set_logger(logger).is_ok() {
        log::set_max_level(node_level.max(dds_level));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ros_arguments_override_the_levels_of_the_flags() {
        let info = (LevelFilter::Info, LevelFilter::Warn);
        assert_eq!(
            levels("/chronomap", &RosArgs::default(), info.0, info.1),
            info
        );
        let parse = |args: &[&str]| {
            RosArgs::parse(std::iter::once("--ros-args").chain(args.iter().copied())).unwrap()
        };
        // By the logger name of the node, in a namespace too.
        let ros = parse(&["--log-level", "robot1.chronomap:=debug"]);
        assert_eq!(
            levels("/robot1/chronomap", &ros, info.0, info.1),
            (LevelFilter::Debug, LevelFilter::Warn)
        );
        assert_eq!(levels("/chronomap", &ros, info.0, info.1), info);
        let ros = parse(&["--log-level", "fatal", "--disable-external-lib-logs"]);
        assert_eq!(
            levels("/chronomap", &ros, info.0, info.1),
            (LevelFilter::Off, LevelFilter::Off)
        );
    }
}
