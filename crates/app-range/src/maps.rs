//! The map manager of [Stüde 2024] §3.3 along a laser log as a job with a report: door
//! passages from the scans (criteria C1–C3), a new map per room, link points between them and
//! the robot's pose with its uncertainty across maps, as `chronomap maps build` reports them.

use std::fmt::Write as _;

use chronomap_core::progress::Progress;
use chronomap_geometry::GeometryError;
use chronomap_geometry::se2::{Pose2, UncertainPose};
use chronomap_multimap::MultimapError;
use chronomap_multimap::door::DoorPassage;
use chronomap_multimap::graph::MapGraph;
use chronomap_multimap::mapper::{Mapper, MapperParams};
use serde::Serialize;

use crate::laser_log::LaserLog;
use chronomap_app::report::Table;

/// A log the map manager cannot follow.
#[derive(Debug, thiserror::Error)]
pub enum MapsError {
    /// The map manager's parameters.
    #[error(transparent)]
    Params(#[from] MultimapError),
    /// An odometry increment that is no pose.
    #[error("{name}: odometry at scan {index}")]
    Odometry {
        /// The log.
        name: String,
        /// The 1-based scan.
        index: usize,
        /// Why.
        #[source]
        source: GeometryError,
    },
    /// A scan the map manager refuses.
    #[error("{name}: scan {index}")]
    Scan {
        /// The log.
        name: String,
        /// The 1-based scan.
        index: usize,
        /// Why.
        #[source]
        source: MultimapError,
    },
    /// The pose or its covariance ran off to infinity.
    #[error(
        "{name}: scan {index}: the robot's pose or its covariance is no longer finite (odometry \
         increment ({}, {}, {}))",
        increment[0],
        increment[1],
        increment[2]
    )]
    NotFinite {
        /// The log.
        name: String,
        /// The 1-based scan.
        index: usize,
        /// The odometry increment of that scan.
        increment: [f64; 3],
    },
}

/// The maps built along a log, as `chronomap maps build` reports them.
#[derive(Debug, Clone, Serialize)]
pub struct MapsReport {
    /// The log.
    pub log: String,
    /// Scans.
    pub scans: usize,
    /// Door passages declared, in order.
    pub door_passages: Vec<DoorPassage>,
    /// Scans with door posts ahead (criterion C1).
    pub scans_with_a_door_ahead: usize,
    /// Maps, link points and link-point candidates.
    pub graph: MapGraph,
    /// The map the robot is in at the end.
    pub current_map: usize,
    /// Its pose there, with its covariance.
    pub pose_in_current_map: UncertainPose,
    /// The map of each scan.
    #[serde(skip)]
    pub map_of_scan: Vec<usize>,
}

impl MapsReport {
    /// The report as `chronomap maps build` prints it.
    pub fn text(&self) -> String {
        let graph = &self.graph;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{}: {} scans, {} door passage(s), {} map(s), {} link point(s), {} link-point candidate(s)",
            self.log,
            self.scans,
            self.door_passages.len(),
            graph.maps().len(),
            graph.links().len(),
            graph.candidates().len()
        );
        let _ = writeln!(
            out,
            "scans with door posts ahead (criterion C1): {}",
            self.scans_with_a_door_ahead
        );
        let mut table = Table::new(["map", "configuration", "bounding box (m)", "scans"]);
        for (i, map) in graph.maps().iter().enumerate() {
            let size = map.bbox.map_or("-".to_string(), |b| {
                format!("{:.1} × {:.1}", b.width(), b.height())
            });
            let scans = self.map_of_scan.iter().filter(|&&m| m == i).count();
            table.row([
                i.to_string(),
                format!("{:?}", map.config),
                size,
                scans.to_string(),
            ]);
        }
        let _ = writeln!(out, "{}", table.render().trim_end());
        for p in &self.door_passages {
            let _ = writeln!(
                out,
                "door passage at t = {:.2} s (scan {}): door {:.2} m wide at ({:.2}, {:.2}), criteria C1 {} C2 {} C3 {}",
                p.time,
                p.step + 1,
                p.door.width(),
                p.door.center()[0],
                p.door.center()[1],
                p.criteria[0],
                p.criteria[1],
                p.criteria[2]
            );
        }
        // A variance that is not a finite non-negative number is said so, never printed as 0.
        let sd = |v: f64, scale: f64, unit: &str, digits: usize| {
            if v.is_finite() && v >= 0.0 {
                format!("{:.digits$} {unit}", scale * v.sqrt())
            } else {
                format!("{v} (not a variance)")
            }
        };
        let pose = &self.pose_in_current_map;
        let _ = writeln!(
            out,
            "robot in map {} at ({:.2}, {:.2}, {:.1}°), σ = ({}, {}, {})",
            self.current_map,
            pose.mean.x,
            pose.mean.y,
            pose.mean.theta.to_degrees(),
            sd(pose.cov[0][0], 1.0, "m", 2),
            sd(pose.cov[1][1], 1.0, "m", 2),
            sd(pose.cov[2][2], 1f64.to_degrees(), "°", 1).replace(" °", "°")
        );
        out
    }
}

/// Runs the map manager of [Stüde 2024] §3.3 (default parameters) along `log`, scan by scan
/// with its odometry increments. Reports one stage, one step per scan.
///
/// # Errors
/// An increment that is no pose, a scan the manager refuses, a pose that is no longer finite.
pub fn build_maps(log: &LaserLog, progress: &dyn Progress) -> Result<MapsReport, MapsError> {
    let mut mapper = Mapper::new(MapperParams::default())?;
    let increments = log.increments();
    progress.stage("door passages", log.scans.len() as u64);
    let mut door_passages = Vec::new();
    let mut map_of_scan = Vec::with_capacity(log.scans.len());
    let mut sides = 0;
    for (k, (scan, inc)) in log.scans.iter().zip(&increments).enumerate() {
        let increment =
            Pose2::new(inc[0], inc[1], inc[2]).map_err(|source| MapsError::Odometry {
                name: log.name.clone(),
                index: k + 1,
                source,
            })?;
        let report = mapper
            .step(scan, &increment)
            .map_err(|source| MapsError::Scan {
                name: log.name.clone(),
                index: k + 1,
                source,
            })?;
        if !mapper.pose().is_finite() {
            return Err(MapsError::NotFinite {
                name: log.name.clone(),
                index: k + 1,
                increment: *inc,
            });
        }
        sides += usize::from(!report.detector.front.is_empty());
        door_passages.extend(report.passage);
        map_of_scan.push(mapper.current_map());
        progress.advance(1);
    }
    Ok(MapsReport {
        log: log.name.clone(),
        scans: log.scans.len(),
        door_passages,
        scans_with_a_door_ahead: sides,
        graph: mapper.graph().clone(),
        current_map: mapper.current_map(),
        pose_in_current_map: *mapper.pose(),
        map_of_scan,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_core::progress::NoProgress;

    /// The Málaga 2006 loop (225 scans): corridors and a hall, no door crossed ahead of a 180°
    /// scanner, so one map for a large space, every scan in it.
    #[test]
    fn the_malaga_loop_is_one_long_range_map_without_doors() {
        let log = crate::laser_log::from_scans(
            &chronomap_testutil::data_path("malaga_laser_2006/scans.txt.xz"),
            &chronomap_testutil::data_path("malaga_laser_2006/odometry.txt.xz"),
        )
        .unwrap();
        let report = build_maps(&log, &NoProgress).unwrap();
        assert_eq!(report.scans, 225);
        assert_eq!(report.door_passages.len(), 0);
        assert_eq!(report.graph.maps().len(), 1);
        assert_eq!(report.map_of_scan, vec![0; 225]);
        let text = report.text();
        let mut lines = text.lines();
        assert_eq!(
            lines.next().unwrap(),
            format!(
                "{}: 225 scans, 0 door passage(s), 1 map(s), 0 link point(s), 0 link-point candidate(s)",
                log.name
            )
        );
        assert_eq!(
            lines.next().unwrap(),
            "scans with door posts ahead (criterion C1): 0"
        );
        let row = lines.nth(2).unwrap();
        assert!(
            row.starts_with("0 ") && row.contains(" LongRange "),
            "{text}"
        );
        assert!(
            text.lines()
                .last()
                .unwrap()
                .starts_with("robot in map 0 at (")
        );
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["graph"]["maps"][0]["config"], "LongRange");
        assert_eq!(json["current_map"], 0);
        assert!(json.get("map_of_scan").is_none());
    }
}
