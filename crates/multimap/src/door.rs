//! Door-passage detection on 2-D laser scans ([Stüde 2024] §3.3.2, "Environment Transitions
//! and Configuration Changes").
//!
//! A doorway is passed when at least two of three criteria hold:
//!
//! * **(C1) front door posts**: two characteristic steps of the spatial derivative of the
//!   ranges in front of the robot — the near posts on either side and a gap of door width
//!   between them through which the beams reach farther;
//! * **(C2) back door posts**: the same behind the robot, after the doorway was traversed;
//! * **(C3) significant change in wall distances**: the bounding box `𝓑` of the
//!   average-low-pass-filtered scan, transformed into the map frame, changes one of its
//!   minimum or maximum `x` or `y` values by more than a threshold within a time window.
//!
//! The text does not print its thresholds (nor does its appendix); the defaults of
//! [`DoorParams`] are this crate's, chosen from door sizes (clear widths of 0.6–1.6 m cover
//! single doors and narrow double doors) and stated with each field.
//!
//! Two readings of the text are made concrete here. (1) "Passing" is geometric: a door whose
//! posts were seen in front (C1) is tracked in the map frame by odometry, and the robot has
//! passed it when its path crosses the segment between the posts; posts seen behind (C2) count
//! for a crossing the robot made. (2) (C3) holds for a crossing when the bounding box changed
//! within `confirm_window_s` before or after it. With a scanner that sees only forward (the
//! 180° SICK of the Málaga log), (C2) can never hold, so a passage there needs (C1) and (C3).
//!
//! ```
//! use chronomap_multimap::door::{DoorDetector, DoorParams};
//! use chronomap_multimap::se2::Pose2;
//! use chronomap_multimap::synth::{FloorPlan, Scanner};
//!
//! // A corridor 2 m wide with a 0.9 m door in its upper wall into a 5 m × 4 m room.
//! let plan = FloorPlan::corridor_and_room();
//! let scanner = Scanner::full_circle(720, 30.0)?;
//! let mut detector = DoorDetector::new(DoorParams::default())?;
//! let mut passages = Vec::new();
//! for (k, pose) in plan.door_run(0.1)?.iter().enumerate() {
//!     let scan = scanner.scan(&plan, pose, 0.1 * k as f64)?;
//!     if let Some(p) = detector.update(&scan, pose)?.passage {
//!         passages.push(p);
//!     }
//! }
//! assert_eq!(passages.len(), 1);
//! assert!(passages[0].criteria.iter().filter(|c| **c).count() >= 2);
//! assert!((passages[0].door.width() - 0.9).abs() < 0.1);
//! # Ok::<(), chronomap_multimap::MultimapError>(())
//! ```
//!
//! [Stüde 2024]: M. Stüde, dissertation, Leibniz Universität Hannover, 2024.

use std::collections::VecDeque;
use std::f64::consts::PI;

use chronomap_geometry::Scan2d;
use serde::{Deserialize, Serialize};

use crate::MultimapError;
use crate::se2::{Pose2, wrap_angle};

/// The most doors seen ahead that are tracked at once. These three bounds are sliding
/// windows, not clamps of a result: past them the detector forgets the door seen longest ago
/// (the crossing waiting longest, the oldest path point or bounding box), which the windows
/// `pending_travel` and `confirm_window_s` would drop soon anyway.
pub const MAX_PENDING: usize = 32;
/// The most crossings waiting for confirmation at once (the oldest is forgotten).
pub const MAX_TRAVERSALS: usize = 32;
/// The most robot positions, and bounding boxes of (C3), kept (the oldest are forgotten).
pub const MAX_PATH: usize = 4096;
/// The share of the beams in a door's gap that must reach past the line between its posts
/// by `min_step` (the rest may hit clutter or a person in the doorway).
pub const GAP_FRACTION: f64 = 0.8;

/// The parameters of the door-passage detector. None is printed in [Stüde 2024]; the
/// defaults are this crate's choice.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DoorParams {
    /// Smallest range step at a door post (m): the spatial derivative of the ranges between
    /// a post and the first beam through the gap. Default 0.5 m.
    pub min_step: f64,
    /// Door posts are at "close range": no farther than this from the sensor (m). Default 3 m.
    pub max_post_range: f64,
    /// Narrowest door, the distance of the two posts (m). Default 0.6 m.
    pub min_door_width: f64,
    /// Widest door (m). Default 1.6 m.
    pub max_door_width: f64,
    /// A door is in front (C1) when the bearing of its centre from the robot is within this
    /// angle of straight ahead, and behind (C2) when within it of straight back (rad).
    /// Default 30° (0.5236).
    pub cone_half_angle: f64,
    /// The sensor's pose on the robot (the Málaga SICK sits 0.78 m ahead of the origin).
    /// Default the identity.
    pub sensor: Pose2,
    /// Beams averaged by the low-pass filter of (C3), an odd number. Default 5.
    pub filter_window: usize,
    /// The time over which the change of the bounding box is measured for (C3) (s).
    /// Default 1 s.
    pub bbox_window_s: f64,
    /// Smallest change of a bounding-box extreme within `bbox_window_s` for (C3) (m).
    /// Default 1.5 m.
    pub bbox_change: f64,
    /// A door seen ahead is tracked until the robot has travelled this far without seeing it
    /// again (m); crossings are also looked for this far back along the path. Default 4 m.
    pub pending_travel: f64,
    /// Criteria count for a crossing if they hold within this time of it (s). Default 3 s.
    pub confirm_window_s: f64,
    /// Two detections are the same door when their centres are this close (m). Default 0.4 m.
    pub match_tolerance: f64,
    /// How many of (C1)–(C3) must hold. Default 2 ("at least two must be met").
    pub min_criteria: usize,
}

impl Default for DoorParams {
    fn default() -> Self {
        DoorParams {
            min_step: 0.5,
            max_post_range: 3.0,
            min_door_width: 0.6,
            max_door_width: 1.6,
            cone_half_angle: 30f64.to_radians(),
            sensor: Pose2::IDENTITY,
            filter_window: 5,
            bbox_window_s: 1.0,
            bbox_change: 1.5,
            pending_travel: 4.0,
            confirm_window_s: 3.0,
            match_tolerance: 0.4,
            min_criteria: 2,
        }
    }
}

impl DoorParams {
    /// Checks every field (finite, positive where a size, ordered door widths, an odd filter
    /// window of at most 101 beams, 1 to 3 criteria).
    pub fn validate(&self) -> Result<(), MultimapError> {
        let bad = |field, value, why| Err(MultimapError::Parameter { field, value, why });
        for (field, value) in [
            ("min_step", self.min_step),
            ("max_post_range", self.max_post_range),
            ("min_door_width", self.min_door_width),
            ("max_door_width", self.max_door_width),
            ("bbox_window_s", self.bbox_window_s),
            ("bbox_change", self.bbox_change),
            ("pending_travel", self.pending_travel),
            ("confirm_window_s", self.confirm_window_s),
            ("match_tolerance", self.match_tolerance),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return bad(field, value, "must be finite and positive");
            }
        }
        if self.max_door_width < self.min_door_width {
            return bad(
                "max_door_width",
                self.max_door_width,
                "must be at least min_door_width",
            );
        }
        if !(self.cone_half_angle > 0.0 && self.cone_half_angle < PI / 2.0) {
            return bad(
                "cone_half_angle",
                self.cone_half_angle,
                "must lie in (0, π/2)",
            );
        }
        self.sensor.validate("sensor")?;
        if self.filter_window.is_multiple_of(2) || self.filter_window > 101 {
            return bad(
                "filter_window",
                self.filter_window as f64,
                "must be odd and at most 101",
            );
        }
        if !(1..=3).contains(&self.min_criteria) {
            return bad(
                "min_criteria",
                self.min_criteria as f64,
                "must be 1, 2 or 3",
            );
        }
        Ok(())
    }
}

/// Two door posts: `right` at the smaller bearing, `left` at the larger, in whatever frame
/// the detection was transformed to.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DoorPosts {
    /// The post at the smaller bearing (the robot's right when the door is ahead).
    pub right: [f64; 2],
    /// The post at the larger bearing.
    pub left: [f64; 2],
}

impl DoorPosts {
    /// The door's width, the distance of its posts (m).
    pub fn width(&self) -> f64 {
        (self.left[0] - self.right[0]).hypot(self.left[1] - self.right[1])
    }

    /// The door's centre.
    pub fn center(&self) -> [f64; 2] {
        [
            0.5 * (self.left[0] + self.right[0]),
            0.5 * (self.left[1] + self.right[1]),
        ]
    }

    /// Both posts transformed by `pose` (from its frame to the reference frame).
    pub fn transformed(&self, pose: &Pose2) -> DoorPosts {
        DoorPosts {
            right: pose.transform_point(self.right),
            left: pose.transform_point(self.left),
        }
    }

    fn center_distance(&self, other: &DoorPosts) -> f64 {
        let (a, b) = (self.center(), other.center());
        (a[0] - b[0]).hypot(a[1] - b[1])
    }
}

/// An axis-aligned bounding box `𝓑` of the filtered scan in the map frame (§3.3.2).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BoundingBox {
    /// Smallest `x` and `y` (m).
    pub min: [f64; 2],
    /// Largest `x` and `y` (m).
    pub max: [f64; 2],
}

impl BoundingBox {
    /// Extent along `x` (m).
    pub fn width(&self) -> f64 {
        self.max[0] - self.min[0]
    }

    /// Extent along `y` (m).
    pub fn height(&self) -> f64 {
        self.max[1] - self.min[1]
    }

    /// The largest change of any of the four extremes between `self` and `other` (m): the
    /// quantity (C3) thresholds.
    pub fn max_change(&self, other: &BoundingBox) -> f64 {
        (0..2)
            .flat_map(|k| {
                [
                    (self.min[k] - other.min[k]).abs(),
                    (self.max[k] - other.max[k]).abs(),
                ]
            })
            .fold(0.0, f64::max)
    }

    fn of_points(points: &[[f64; 2]]) -> Option<BoundingBox> {
        let first = points.first()?;
        let mut b = BoundingBox {
            min: *first,
            max: *first,
        };
        for p in points {
            for k in 0..2 {
                b.min[k] = b.min[k].min(p[k]);
                b.max[k] = b.max[k].max(p[k]);
            }
        }
        Some(b)
    }
}

/// Whether the scan covers the full circle (its last beam is one increment short of the
/// first, or overlaps it).
fn is_full_circle(scan: &Scan2d) -> bool {
    scan.angle_max - scan.angle_min + 1.5 * scan.angle_increment() >= 2.0 * PI
}

/// A range with no-returns read as infinitely far.
fn range_or_far(scan: &Scan2d, k: usize) -> f64 {
    if scan.is_return(k) {
        scan.ranges[k]
    } else {
        f64::INFINITY
    }
}

/// The range along bearing `phi` from the sensor at which the line through `a` and `b` is
/// crossed, or infinity where the ray does not reach it.
fn ray_line_range(phi: f64, a: [f64; 2], b: [f64; 2]) -> f64 {
    let (s, c) = phi.sin_cos();
    let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
    // t·(c, s) = a + u·e  ⇒  solve with Cramer's rule.
    let den = c * ey - s * ex;
    if den.abs() < 1e-12 {
        return f64::INFINITY;
    }
    let t = (a[0] * ey - a[1] * ex) / den;
    if t > 0.0 { t } else { f64::INFINITY }
}

/// All door-post pairs in a scan, in the sensor frame, by the two range steps of (C1)/(C2):
/// a rising step `r[a+1] − r[a] ≥ min_step` at the right post and a falling one
/// `r[b−1] − r[b] ≥ min_step` at the left post, both posts within `max_post_range`, their
/// distance a door width, and at least [`GAP_FRACTION`] of the beams between them reaching
/// `min_step` past the line between the posts. No-returns count as far. A full-circle scan is
/// searched circularly (a door straight behind spans its first and last beams). Time and
/// memory are linear in the number of beams.
pub fn detect_door_posts(
    scan: &Scan2d,
    params: &DoorParams,
) -> Result<Vec<DoorPosts>, MultimapError> {
    scan.validate()?;
    params.validate()?;
    let n = scan.ranges.len();
    let circular = is_full_circle(scan);
    let m = if circular { 2 * n } else { n };
    let r = |i: usize| range_or_far(scan, i % n);
    let post = |i: usize| {
        let v = r(i);
        v.is_finite() && v <= params.max_post_range
    };
    let falling = |j: usize| j >= 1 && j < m && post(j) && r(j - 1) - r(j) >= params.min_step;
    // next_falling[i]: the first falling step at index ≥ i.
    let mut next_falling = vec![usize::MAX; m + 1];
    for i in (0..m).rev() {
        next_falling[i] = if falling(i) { i } else { next_falling[i + 1] };
    }
    let point = |i: usize| {
        let (s, c) = scan.bearing(i % n).sin_cos();
        let v = r(i);
        [v * c, v * s]
    };
    let bearing = |i: usize| scan.bearing(i % n);
    let mut doors = Vec::new();
    for a in 0..n {
        if !(post(a) && a + 1 < m && r(a + 1) - r(a) >= params.min_step) {
            continue;
        }
        let b = next_falling[(a + 2).min(m)];
        if b == usize::MAX || b - a >= n {
            continue;
        }
        let door = DoorPosts {
            right: point(a),
            left: point(b),
        };
        let w = door.width();
        if !(params.min_door_width..=params.max_door_width).contains(&w) {
            continue;
        }
        let gap = (a + 1..b)
            .filter(|&g| {
                r(g) >= ray_line_range(bearing(g), door.right, door.left) + params.min_step
            })
            .count();
        if gap as f64 >= GAP_FRACTION * (b - a - 1) as f64 {
            doors.push(door);
        }
    }
    Ok(doors)
}

/// The returns of `scan` after the average low-pass filter of (C3) (each range replaced by
/// the mean of the returns among the `window` beams centred on it), as points in the sensor
/// frame.
pub fn filtered_points(scan: &Scan2d, window: usize) -> Vec<[f64; 2]> {
    let n = scan.ranges.len();
    let half = window / 2;
    (0..n)
        .filter(|&k| scan.is_return(k))
        .map(|k| {
            let (sum, count) = (k.saturating_sub(half)..(k + half + 1).min(n))
                .filter(|&j| scan.is_return(j))
                .fold((0.0, 0usize), |(s, c), j| (s + scan.ranges[j], c + 1));
            let v = sum / count as f64;
            let (s, c) = scan.bearing(k).sin_cos();
            [v * c, v * s]
        })
        .collect()
}

/// The bounding box `𝓑` of the filtered scan in the frame where the sensor has pose
/// `sensor_pose` (§3.3.2), or `None` for a scan without returns.
pub fn filtered_bounding_box(
    scan: &Scan2d,
    window: usize,
    sensor_pose: &Pose2,
) -> Option<BoundingBox> {
    let points: Vec<[f64; 2]> = filtered_points(scan, window)
        .into_iter()
        .map(|p| sensor_pose.transform_point(p))
        .collect();
    BoundingBox::of_points(&points)
}

/// Whether the segments `p1–p2` and `a–b` intersect (end points included).
fn segments_cross(p1: [f64; 2], p2: [f64; 2], a: [f64; 2], b: [f64; 2]) -> bool {
    let d = [p2[0] - p1[0], p2[1] - p1[1]];
    let e = [b[0] - a[0], b[1] - a[1]];
    let den = d[0] * e[1] - d[1] * e[0];
    if den.abs() < 1e-15 {
        return false;
    }
    let w = [a[0] - p1[0], a[1] - p1[1]];
    let s = (w[0] * e[1] - w[1] * e[0]) / den;
    let u = (w[0] * d[1] - w[1] * d[0]) / den;
    (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&u)
}

/// A declared door passage.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DoorPassage {
    /// The update (0-based scan count) at which the passage was declared.
    pub step: usize,
    /// Time of that scan (s).
    pub time: f64,
    /// Time of the first scan after the robot crossed the doorway (s).
    pub crossing_time: f64,
    /// The door's posts in the detector's frame.
    pub door: DoorPosts,
    /// The robot's pose at the declaration, behind the doorway: where the link point goes.
    pub pose: Pose2,
    /// Which of (C1), (C2), (C3) held.
    pub criteria: [bool; 3],
    /// The bounding box of the scan at the declaration (the new room's extent), if the
    /// scan had returns.
    pub bbox: Option<BoundingBox>,
}

/// What one update of the detector saw.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct DetectorOutput {
    /// Door posts in front of the robot (C1), in the detector's frame.
    pub front: Vec<DoorPosts>,
    /// Door posts behind the robot (C2), in the detector's frame.
    pub back: Vec<DoorPosts>,
    /// The bounding box of this scan, if it had returns.
    pub bbox: Option<BoundingBox>,
    /// Whether the bounding box changed enough for (C3) at this scan.
    pub c3: bool,
    /// A door passage declared at this scan.
    pub passage: Option<DoorPassage>,
}

#[derive(Clone, Debug)]
struct Pending {
    door: DoorPosts,
    seen_at_travel: f64,
}

#[derive(Clone, Debug)]
struct Traversal {
    door: DoorPosts,
    time: f64,
    travelled: f64,
    criteria: [bool; 3],
    declared: bool,
}

#[derive(Clone, Copy, Debug)]
struct PathPoint {
    time: f64,
    travelled: f64,
    position: [f64; 2],
}

/// The door-passage detector of [Stüde 2024] §3.3.2, fed one scan and the robot's pose in a
/// fixed frame (odometry or map) per update. Pure: it keeps bounded state and does no I/O.
#[derive(Clone, Debug)]
pub struct DoorDetector {
    params: DoorParams,
    step: usize,
    last: Option<(f64, Pose2)>,
    travelled: f64,
    pending: Vec<Pending>,
    traversals: Vec<Traversal>,
    path: VecDeque<PathPoint>,
    bboxes: VecDeque<(f64, BoundingBox)>,
    c3_times: VecDeque<f64>,
}

impl DoorDetector {
    /// A detector with checked parameters.
    pub fn new(params: DoorParams) -> Result<DoorDetector, MultimapError> {
        params.validate()?;
        Ok(DoorDetector {
            params,
            step: 0,
            last: None,
            travelled: 0.0,
            pending: Vec::new(),
            traversals: Vec::new(),
            path: VecDeque::new(),
            bboxes: VecDeque::new(),
            c3_times: VecDeque::new(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &DoorParams {
        &self.params
    }

    /// Distance the robot has travelled so far (m).
    pub fn travelled(&self) -> f64 {
        self.travelled
    }

    /// One update with `scan`, taken when the robot was at `pose` in the detector's fixed
    /// frame. Scan times must not decrease.
    pub fn update(&mut self, scan: &Scan2d, pose: &Pose2) -> Result<DetectorOutput, MultimapError> {
        scan.validate()?;
        pose.validate("pose")?;
        let p = self.params;
        let t = scan.time;
        let position = [pose.x, pose.y];
        let previous = self.last;
        if let Some((t0, _)) = previous
            && t < t0
        {
            return Err(MultimapError::TimeGoesBack {
                time: t,
                previous: t0,
            });
        }
        if let Some((_, p0)) = previous {
            self.travelled += p0.distance(pose);
        }
        self.last = Some((t, *pose));
        let step = self.step;
        self.step += 1;

        // Door posts in front (C1) and behind (C2), in the fixed frame.
        let sensor_pose = pose.compose(&p.sensor);
        let mut out = DetectorOutput::default();
        for door in detect_door_posts(scan, &p)? {
            let in_robot = door.transformed(&p.sensor);
            let c = in_robot.center();
            let bearing = c[1].atan2(c[0]);
            let fixed = door.transformed(&sensor_pose);
            if bearing.abs() <= p.cone_half_angle {
                out.front.push(fixed);
            } else if wrap_angle(bearing - PI).abs() <= p.cone_half_angle {
                out.back.push(fixed);
            }
        }

        // (C3): the bounding box's change over `bbox_window_s`.
        out.bbox = filtered_bounding_box(scan, p.filter_window, &sensor_pose);
        if let Some(bbox) = out.bbox {
            while self.bboxes.len() >= 2 && self.bboxes[1].0 <= t - p.bbox_window_s {
                self.bboxes.pop_front();
            }
            if let Some(&(t_ref, reference)) = self.bboxes.front()
                && t_ref <= t - p.bbox_window_s
                && bbox.max_change(&reference) > p.bbox_change
            {
                out.c3 = true;
                self.c3_times.push_back(t);
            }
            self.bboxes.push_back((t, bbox));
            if self.bboxes.len() > MAX_PATH {
                self.bboxes.pop_front();
            }
        }
        while self
            .c3_times
            .front()
            .is_some_and(|&tc| tc < t - 2.0 * p.confirm_window_s)
        {
            self.c3_times.pop_front();
        }

        // Crossings of doors seen ahead (C1).
        if let Some((_, p0)) = previous {
            let from = [p0.x, p0.y];
            let mut k = 0;
            while k < self.pending.len() {
                let door = self.pending[k].door;
                if segments_cross(from, position, door.right, door.left) {
                    self.pending.swap_remove(k);
                    self.add_traversal(door, t, [true, false, false]);
                } else {
                    k += 1;
                }
            }
        }
        self.path.push_back(PathPoint {
            time: t,
            travelled: self.travelled,
            position,
        });
        while self.path.len() > MAX_PATH
            || self
                .path
                .front()
                .is_some_and(|q| q.travelled < self.travelled - p.pending_travel)
        {
            self.path.pop_front();
        }

        // Posts behind (C2): a crossing already known, or one found along the recent path.
        for door in &out.back {
            if let Some(tr) = self
                .traversals
                .iter_mut()
                .find(|tr| tr.door.center_distance(door) <= p.match_tolerance)
            {
                tr.criteria[1] = true;
                continue;
            }
            let crossing = self
                .path
                .iter()
                .zip(self.path.iter().skip(1))
                .find(|(a, b)| segments_cross(a.position, b.position, door.right, door.left))
                .map(|(_, b)| *b);
            if let Some(b) = crossing {
                self.add_traversal(*door, b.time, [false, true, false]);
                if let Some(tr) = self.traversals.last_mut() {
                    tr.travelled = b.travelled;
                }
            }
        }

        // Track the doors ahead.
        for door in &out.front {
            match self
                .pending
                .iter_mut()
                .find(|q| q.door.center_distance(door) <= p.match_tolerance)
            {
                Some(q) => {
                    q.door = *door;
                    q.seen_at_travel = self.travelled;
                }
                None => {
                    if self.pending.len() >= MAX_PENDING {
                        // Forget the door seen longest ago.
                        if let Some(oldest) = (0..self.pending.len()).min_by(|&i, &j| {
                            self.pending[i]
                                .seen_at_travel
                                .total_cmp(&self.pending[j].seen_at_travel)
                        }) {
                            self.pending.swap_remove(oldest);
                        }
                    }
                    self.pending.push(Pending {
                        door: *door,
                        seen_at_travel: self.travelled,
                    });
                }
            }
        }
        let travelled = self.travelled;
        self.pending
            .retain(|q| travelled - q.seen_at_travel <= p.pending_travel);

        // (C3) for the crossings, and the decision.
        for tr in self.traversals.iter_mut() {
            if !tr.criteria[2] {
                tr.criteria[2] = self
                    .c3_times
                    .iter()
                    .any(|&tc| (tc - tr.time).abs() <= p.confirm_window_s);
            }
        }
        if let Some(tr) = self
            .traversals
            .iter_mut()
            .filter(|tr| !tr.declared)
            .find(|tr| tr.criteria.iter().filter(|c| **c).count() >= p.min_criteria)
        {
            tr.declared = true;
            out.passage = Some(DoorPassage {
                step,
                time: t,
                crossing_time: tr.time,
                door: tr.door,
                pose: *pose,
                criteria: tr.criteria,
                bbox: out.bbox,
            });
        }
        if out.passage.is_some() {
            // One doorway, one passage: crossings waiting nearby in time are the same one.
            let declared_time = out.passage.as_ref().map_or(t, |q| q.crossing_time);
            self.traversals
                .retain(|tr| tr.declared || (tr.time - declared_time).abs() > p.confirm_window_s);
        }
        self.traversals.retain(|tr| {
            t - tr.time <= p.confirm_window_s
                || (tr.declared && travelled - tr.travelled <= p.pending_travel)
        });
        Ok(out)
    }

    fn add_traversal(&mut self, door: DoorPosts, time: f64, criteria: [bool; 3]) {
        if let Some(tr) = self
            .traversals
            .iter_mut()
            .find(|tr| tr.door.center_distance(&door) <= self.params.match_tolerance)
        {
            for (c, new) in tr.criteria.iter_mut().zip(criteria) {
                *c |= new;
            }
            return;
        }
        if self.traversals.len() >= MAX_TRAVERSALS {
            self.traversals.remove(0);
        }
        self.traversals.push(Traversal {
            door,
            time,
            travelled: self.travelled,
            criteria,
            declared: false,
        });
    }
}
