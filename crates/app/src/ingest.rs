//! People detected in a ROS 2 bag (`people_msgs`, `geometry_msgs/msg/PoseArray` and the like,
//! read by `chronomap-rosbag`) as the files the other jobs learn from: events `t x y`
//! ([Krajník 2019] §V-D) or tracks with identities, speed and heading ([Stüde 2024] §4.2.2).
//!
//! Files in, result structs out: the faces choose the topic and the format and write the file.

use std::collections::HashMap;

use chronomap_activity::truth::TrackPoint;
use chronomap_core::progress::Progress;
use chronomap_hypertime::events::Event;
use chronomap_io::tracks::TrackRow;
use chronomap_rosbag::records::{self, Detection};
use chronomap_rosbag::{Bag, BagError, RecordKind, TimeSource};

/// The people detections of a topic.
#[derive(Clone, Debug, PartialEq)]
pub struct People {
    /// Messages read.
    pub messages: usize,
    /// Every detection of every message, in message order.
    pub detections: Vec<Detection>,
}

/// Reads every detection of the people topic `topic` of `bag`, timed by `time`, reporting to
/// `progress`.
///
/// # Errors
/// [`BagError`] naming the bag and message: a topic of another kind, times going backwards, a
/// message that is not a detection.
pub fn read_people(
    bag: &Bag,
    topic: &str,
    time: TimeSource,
    progress: &dyn Progress,
) -> Result<People, BagError> {
    let mut detections = Vec::new();
    let mut messages = 0;
    bag.for_each_record(topic, RecordKind::People, time, progress, |_, t, v| {
        messages += 1;
        detections.extend(records::detections(v, t)?);
        Ok(())
    })?;
    Ok(People {
        messages,
        detections,
    })
}

/// The detections as events `t x y`.
pub fn events_of(detections: &[Detection]) -> Vec<Event> {
    detections
        .iter()
        .map(|d| Event {
            t: d.time,
            x: d.x,
            y: d.y,
        })
        .collect()
}

/// Detections without an identity or a velocity (poses only) cannot be tracks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("detection {index} has no identity or no velocity")]
pub struct NoIdentity {
    /// The first such detection, counted from 0.
    pub index: usize,
}

/// Track rows of people detections: ids from the names (a name that is a whole number is that
/// id, others are numbered from 1 in order of first appearance), speed and heading from the
/// velocity.
///
/// # Errors
/// [`NoIdentity`] for the first detection without a name or a velocity.
pub fn track_rows(detections: &[Detection]) -> Result<Vec<TrackRow>, NoIdentity> {
    let mut ids: HashMap<String, u64> = HashMap::new();
    let mut next = 1u64;
    detections
        .iter()
        .enumerate()
        .map(|(index, d)| {
            let (Some(name), Some([vx, vy])) = (&d.person, d.velocity) else {
                return Err(NoIdentity { index });
            };
            let person = match name.parse::<u64>() {
                Ok(id) => id,
                Err(_) => *ids.entry(name.clone()).or_insert_with(|| {
                    next += 1;
                    next - 1
                }),
            };
            Ok(TrackRow {
                point: TrackPoint {
                    t: d.time,
                    person,
                    x: d.x,
                    y: d.y,
                },
                speed: vx.hypot(vy),
                heading: vy.atan2(vx),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seen(time: f64, person: Option<&str>, velocity: Option<[f64; 2]>) -> Detection {
        Detection {
            time,
            x: 1.0,
            y: -2.0,
            person: person.map(str::to_string),
            velocity,
            frame_id: "map".to_string(),
        }
    }

    #[test]
    fn names_become_ids_and_velocities_speed_and_heading() {
        let detections = [
            seen(1.0, Some("7"), Some([3.0, 4.0])),
            seen(2.0, Some("alice"), Some([0.0, -1.0])),
            seen(3.0, Some("bob"), Some([-2.0, 0.0])),
            seen(4.0, Some("alice"), Some([0.0, 0.0])),
        ];
        let rows = track_rows(&detections).unwrap();
        let ids: Vec<u64> = rows.iter().map(|r| r.point.person).collect();
        assert_eq!(ids, [7, 1, 2, 1]);
        assert_eq!(rows[0].speed, 5.0);
        assert_eq!(rows[0].heading, 4f64.atan2(3.0));
        assert_eq!(rows[1].heading, -std::f64::consts::FRAC_PI_2);
        assert_eq!(rows[2].heading, std::f64::consts::PI);
        assert_eq!(
            (rows[3].point.t, rows[3].point.x, rows[3].point.y),
            (4.0, 1.0, -2.0)
        );
        assert_eq!(
            events_of(&detections[..1]),
            [Event {
                t: 1.0,
                x: 1.0,
                y: -2.0
            }]
        );
    }

    #[test]
    fn poses_without_identities_are_not_tracks() {
        let detections = [
            seen(1.0, Some("7"), Some([3.0, 4.0])),
            seen(2.0, None, None),
        ];
        assert_eq!(track_rows(&detections), Err(NoIdentity { index: 1 }));
    }
}
