//! The topics a configured node subscribes to and publishes, with their types and quality of
//! service, as `chronomap ros2 --check` lists them before the node runs.

use serde::Serialize;

use crate::config::{GridSource, NodeConfig, Reliability};

/// One topic of the node.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Topic {
    /// `in` (subscribed) or `out` (published).
    pub direction: &'static str,
    /// The topic's name, resolved.
    pub topic: String,
    /// Its message type (`nav_msgs/msg/OccupancyGrid`).
    #[serde(rename = "type")]
    pub type_name: String,
    /// Its quality of service (`reliable, keep last 1, transient local`).
    pub qos: String,
}

/// `reliable, keep last 10`, `best effort, keep last 5, transient local`.
fn qos(reliability: Reliability, depth: usize, latched: bool) -> String {
    format!(
        "{}, keep last {depth}{}",
        match reliability {
            Reliability::Reliable => "reliable",
            Reliability::BestEffort => "best effort",
        },
        if latched { ", transient local" } else { "" }
    )
}

/// The topics of `config` in the order the node makes them: `/clock` with simulated time,
/// each state's input and its probability and entropy, each grid's input, its predicted map
/// and its costmap filter's mask and info. Predictions are latched (reliable, keep last 1,
/// transient local), as Nav2 subscribes to maps.
pub fn topics(config: &NodeConfig) -> Vec<Topic> {
    let latched = qos(Reliability::Reliable, 1, true);
    let mut topics = Vec::new();
    let mut put = |direction, topic: &str, type_name: &str, qos: String| {
        topics.push(Topic {
            direction,
            topic: topic.to_owned(),
            type_name: type_name.to_owned(),
            qos,
        });
    };
    if config.use_sim_time {
        put(
            "in",
            "/clock",
            "rosgraph_msgs/msg/Clock",
            "best effort, keep last 1000".into(),
        );
    }
    for s in &config.states {
        let q = &s.qos;
        let type_name = s.message.type_name().to_string();
        put(
            "in",
            &s.topic,
            &type_name,
            qos(q.reliability, q.depth, q.transient_local),
        );
        for topic in [&s.probability_topic, &s.entropy_topic] {
            put("out", topic, "std_msgs/msg/Float64", latched.clone());
        }
    }
    for g in &config.grids {
        let type_name = match g.source {
            GridSource::Map => "nav_msgs/msg/OccupancyGrid",
            GridSource::People { .. } => "geometry_msgs/msg/PoseArray",
        };
        let q = &g.qos;
        put(
            "in",
            &g.topic,
            type_name,
            qos(q.reliability, q.depth, q.transient_local),
        );
        let grid = "nav_msgs/msg/OccupancyGrid";
        put("out", &g.predicted_topic, grid, latched.clone());
        if let Some(f) = &g.filter {
            put("out", &f.mask_topic, grid, latched.clone());
            let info = "nav2_msgs/msg/CostmapFilterInfo";
            put("out", &f.info_topic, info, latched.clone());
        }
    }
    topics
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quality_of_service_reads_as_ros_2_names_it() {
        assert_eq!(
            qos(Reliability::Reliable, 1, true),
            "reliable, keep last 1, transient local"
        );
        assert_eq!(
            qos(Reliability::BestEffort, 10, false),
            "best effort, keep last 10"
        );
    }
}
