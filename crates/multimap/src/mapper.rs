//! The map manager of [Stüde 2024] §3.3: scans and odometry in, a graph of linked maps out.
//!
//! Each update composes the odometry increment onto the robot's pose in the current map and
//! propagates its covariance (eq. (3.13) with the increment's noise, [`OdometryNoise`]), runs
//! the [`DoorDetector`], saves a link-point candidate for every
//! new door seen ahead, and on a declared passage starts a new map — with the configuration
//! its bounding box chooses (§3.3.2) — linked to the old one at the robot's pose: the link
//! point's pose in the old map carries the odometry covariance accumulated there, its pose in
//! the new map is the new map's origin, and the covariance is reset ("the uncertainty is
//! reset for each new map", §3.3.3).
//!
//! ```
//! use chronomap_multimap::mapper::{Mapper, MapperParams};
//! use chronomap_multimap::se2::Pose2;
//! use chronomap_multimap::synth::{FloorPlan, Scanner};
//!
//! let plan = FloorPlan::corridor_and_room();
//! let scanner = Scanner::full_circle(720, 30.0)?;
//! let mut mapper = Mapper::new(MapperParams::default())?;
//! let mut previous = Pose2::IDENTITY;
//! for (k, pose) in plan.door_run(0.1)?.iter().enumerate() {
//!     let increment = if k == 0 { Pose2::IDENTITY } else { previous.between(pose) };
//!     mapper.step(&scanner.scan(&plan, pose, 0.1 * k as f64)?, &increment)?;
//!     previous = *pose;
//! }
//! assert_eq!(mapper.graph().maps().len(), 2);
//! assert_eq!(mapper.graph().links().len(), 1);
//! # Ok::<(), chronomap_multimap::MultimapError>(())
//! ```
//!
//! [Stüde 2024]: M. Stüde, dissertation, Leibniz Universität Hannover, 2024.

use chronomap_geometry::Scan2d;
use serde::{Deserialize, Serialize};

use crate::MultimapError;
use crate::config::{ConfigParams, choose_config};
use crate::door::{DetectorOutput, DoorDetector, DoorParams, DoorPassage};
use crate::graph::{MAX_LINKS, MapGraph};
use crate::se2::{Mat3, Pose2, UncertainPose};

/// Odometry noise growing with the distance and angle driven (a random walk: variances
/// proportional to them, so the result does not depend on how often increments come).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OdometryNoise {
    /// Variance of `x` and of `y` per metre driven (m²/m). Default 0.0025 (5 cm after 1 m).
    pub trans_var_per_m: f64,
    /// Variance of the heading per radian turned (rad²/rad). Default 0.0025.
    pub rot_var_per_rad: f64,
    /// Variance of the heading per metre driven (rad²/m). Default 0.0004 (1.1° after 1 m).
    pub rot_var_per_m: f64,
}

impl Default for OdometryNoise {
    fn default() -> Self {
        OdometryNoise {
            trans_var_per_m: 0.0025,
            rot_var_per_rad: 0.0025,
            rot_var_per_m: 0.0004,
        }
    }
}

impl OdometryNoise {
    /// Checks that all three are finite and non-negative.
    pub fn validate(&self) -> Result<(), MultimapError> {
        for (field, value) in [
            ("trans_var_per_m", self.trans_var_per_m),
            ("rot_var_per_rad", self.rot_var_per_rad),
            ("rot_var_per_m", self.rot_var_per_m),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(MultimapError::Parameter {
                    field,
                    value,
                    why: "must be finite and non-negative",
                });
            }
        }
        Ok(())
    }

    /// The covariance of the increment `u` (in the robot frame, diagonal).
    pub fn covariance(&self, u: &Pose2) -> Mat3 {
        let d = u.x.hypot(u.y);
        let t = self.trans_var_per_m * d;
        let r = self.rot_var_per_rad * u.theta.abs() + self.rot_var_per_m * d;
        [[t, 0.0, 0.0], [0.0, t, 0.0], [0.0, 0.0, r]]
    }
}

/// The parameters of the map manager.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MapperParams {
    /// The door detector's.
    pub door: DoorParams,
    /// The configuration choice's.
    pub config: ConfigParams,
    /// The odometry's noise.
    pub noise: OdometryNoise,
}

/// What one update did.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct StepReport {
    /// The detector's output for this scan.
    pub detector: DetectorOutput,
    /// The door passage declared, if any.
    pub passage: Option<DoorPassage>,
    /// The map started by it.
    pub new_map: Option<usize>,
    /// The link point joining it to the previous map.
    pub link: Option<usize>,
    /// Candidates added for doors seen ahead for the first time.
    pub candidates: Vec<usize>,
}

/// The map manager (see the module documentation). Pure: no I/O, bounded state besides the
/// graph, which grows by at most one map, one link and the doors seen per update.
#[derive(Clone, Debug)]
pub struct Mapper {
    params: MapperParams,
    detector: DoorDetector,
    graph: MapGraph,
    current: usize,
    pose: UncertainPose,
    odom: Pose2,
    steps: usize,
    /// Door centres of the candidates, per candidate, in their map's frame.
    candidate_doors: Vec<(usize, [f64; 2])>,
}

impl Mapper {
    /// A manager with checked parameters and no maps yet (the first scan starts map 0).
    pub fn new(params: MapperParams) -> Result<Mapper, MultimapError> {
        params.config.validate()?;
        params.noise.validate()?;
        Ok(Mapper {
            detector: DoorDetector::new(params.door)?,
            params,
            graph: MapGraph::new(),
            current: 0,
            pose: UncertainPose::exact(Pose2::IDENTITY),
            odom: Pose2::IDENTITY,
            steps: 0,
            candidate_doors: Vec::new(),
        })
    }

    /// The graph built so far.
    pub fn graph(&self) -> &MapGraph {
        &self.graph
    }

    /// The map the robot is in.
    pub fn current_map(&self) -> usize {
        self.current
    }

    /// The robot's pose in the current map with its covariance.
    pub fn pose(&self) -> &UncertainPose {
        &self.pose
    }

    /// The robot's pose by odometry alone (the detector's frame).
    pub fn odometry_pose(&self) -> &Pose2 {
        &self.odom
    }

    /// One update: `increment` is the odometry from the previous scan to this one in the
    /// robot frame (ignored for the first scan).
    ///
    /// # Errors
    /// A bad scan or increment; [`MultimapError::TooLarge`] once the graph holds
    /// [`crate::graph::MAX_MAPS`] maps or [`MAX_LINKS`] link points and candidates (the
    /// scan's odometry and detector state are then already applied).
    pub fn step(&mut self, scan: &Scan2d, increment: &Pose2) -> Result<StepReport, MultimapError> {
        increment.validate("increment")?;
        scan.validate()?;
        if self.steps > 0 {
            let noisy = UncertainPose {
                mean: *increment,
                cov: self.params.noise.covariance(increment),
            };
            self.odom = self.odom.compose(increment);
            self.pose = self.pose.compose(&noisy);
        }
        let out = self.detector.update(scan, &self.odom)?;
        if self.steps == 0 {
            let config = out.bbox.map_or(crate::config::MapConfig::ShortRange, |b| {
                choose_config(&b, &self.params.config)
            });
            self.current = self.graph.add_map(config, out.bbox)?;
        }
        self.steps += 1;
        let mut report = StepReport::default();
        // Candidates: doors ahead not seen before in this map.
        let odom_to_map = self.pose.mean.compose(&self.odom.inverse());
        for door in &out.front {
            let c = odom_to_map.transform_point(door.center());
            let known = self.candidate_doors.iter().any(|&(m, q)| {
                m == self.current
                    && (q[0] - c[0]).hypot(q[1] - c[1]) <= 2.0 * self.params.door.match_tolerance
            });
            if !known {
                let id =
                    self.graph
                        .add_candidate(self.current, self.pose, self.steps as u64 - 1)?;
                self.candidate_doors.push((self.current, c));
                report.candidates.push(id);
            }
        }
        if let Some(passage) = out.passage {
            let config = passage
                .bbox
                .map_or(crate::config::MapConfig::ShortRange, |b| {
                    choose_config(&b, &self.params.config)
                });
            // Both bounds first, so that a full graph gets no map without its link.
            let linked = self.graph.links().len() + self.graph.candidates().len();
            if linked >= MAX_LINKS {
                return Err(MultimapError::TooLarge {
                    what: "link points and candidates",
                    n: linked + 1,
                    max: MAX_LINKS,
                });
            }
            let new_map = self.graph.add_map(config, passage.bbox)?;
            let origin = UncertainPose::exact(Pose2::IDENTITY);
            let link = self
                .graph
                .add_link(self.current, self.pose, new_map, origin)?;
            self.current = new_map;
            self.pose = origin;
            report.passage = Some(passage);
            report.new_map = Some(new_map);
            report.link = Some(link);
        }
        report.detector = out;
        Ok(report)
    }
}
