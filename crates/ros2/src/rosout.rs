//! The node's log lines on `/rosout` (`rcl_interfaces/msg/Log`), as every ROS 2 node
//! publishes them: `ros2 topic echo /rosout`, rqt_console and rosbag see them with the node's
//! logger name (`chronomap`, `robot1.chronomap` in a namespace), the level, and the file,
//! function (the Rust module) and line of the log call.
//!
//! The crate logs through the [`log`] facade and prints nothing; the program's logger (the
//! `chronomap ros2` command's) calls [`forward`] with each record of this crate it logs. The
//! node installs its `/rosout` publisher here while it runs (`install`); before and after,
//! [`forward`] does nothing.

use std::sync::Mutex;

use ros2_client::NodeLoggingHandle;
use ros2_client::builtin_interfaces::Time;
use ros2_client::ros2::LogLevel;
use ros2_client::rosout::RosoutRaw;

/// The node's `/rosout` publisher and logger name, while the node runs.
static SINK: Mutex<Option<(NodeLoggingHandle, String)>> = Mutex::new(None);

/// The logger name rcl gives the node `fqn` (`/robot1/chronomap` → `robot1.chronomap`).
pub fn logger_name(fqn: &str) -> String {
    fqn.trim_start_matches('/').replace('/', ".")
}

/// Publishes the node's log records on `/rosout` through `handle` from now on.
pub(crate) fn install(handle: NodeLoggingHandle, logger: String) {
    if let Ok(mut sink) = SINK.lock() {
        *sink = Some((handle, logger));
    }
}

/// Stops publishing log records (the node is going away).
pub(crate) fn remove() {
    if let Ok(mut sink) = SINK.lock() {
        *sink = None;
    }
}

/// The `rcl_interfaces/msg/Log` level of a record's level (trace is debug).
pub fn level(level: log::Level) -> LogLevel {
    match level {
        log::Level::Error => LogLevel::Error,
        log::Level::Warn => LogLevel::Warn,
        log::Level::Info => LogLevel::Info,
        log::Level::Debug | log::Level::Trace => LogLevel::Debug,
    }
}

/// Publishes `record` on `/rosout` if the node runs with `/rosout` logging. Records logged
/// while one is being published (by the DDS libraries, on this thread) are not forwarded.
pub fn forward(record: &log::Record) {
    let Ok(sink) = SINK.try_lock() else {
        return;
    };
    if let Some((handle, logger)) = sink.as_ref() {
        handle.rosout_raw(
            Time::now(),
            level(record.level()),
            logger,
            &record.args().to_string(),
            record.file().unwrap_or(""),
            record.module_path().unwrap_or(""),
            record.line().unwrap_or(0),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logger_names_and_levels_are_rcl_s() {
        assert_eq!(logger_name("/chronomap"), "chronomap");
        assert_eq!(
            logger_name("/robot1/office/chronomap"),
            "robot1.office.chronomap"
        );
        // rcl_interfaces/msg/Log: DEBUG 10, INFO 20, WARN 30, ERROR 40.
        let ids: Vec<u8> = [
            log::Level::Trace,
            log::Level::Debug,
            log::Level::Info,
            log::Level::Warn,
            log::Level::Error,
        ]
        .iter()
        .map(|&l| level(l) as u8)
        .collect();
        assert_eq!(ids, [10, 10, 20, 30, 40]);
    }
}
