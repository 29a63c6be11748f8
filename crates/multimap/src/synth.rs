//! Synthetic scans for tests and examples: a tiny 2-D ray caster over the wall segments of a
//! hand-made floor plan.
//!
//! ```
//! use chronomap_multimap::se2::Pose2;
//! use chronomap_multimap::synth::{FloorPlan, Scanner};
//!
//! let plan = FloorPlan::corridor_and_room();
//! // In the corridor (2 m wide), looking along it: the side walls are 1 m away.
//! let scan = Scanner::full_circle(360, 30.0)?.scan(&plan, &Pose2::new(1.0, 1.0, 0.0)?, 0.0)?;
//! let left = scan.ranges[270]; // bearing +90°
//! assert!((left - 1.0).abs() < 1e-9);
//! # Ok::<(), chronomap_multimap::MultimapError>(())
//! ```

use std::f64::consts::{FRAC_PI_2, PI};

use chronomap_geometry::{GeometryError, Scan2d};

use chronomap_geometry::scan::MAX_BEAMS;

use crate::MultimapError;
use crate::se2::Pose2;

/// The shortest step of [`FloorPlan::door_run`] (m).
pub const MIN_RUN_STEP: f64 = 1e-3;

/// Wall segments `[[x0, y0], [x1, y1]]` (m).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct FloorPlan {
    /// The walls.
    pub walls: Vec<[[f64; 2]; 2]>,
}

/// Door of the corridor plans: in the corridor's upper wall (`y = 2`) from `x = 5.5` to `6.4`.
pub const DOOR: [[f64; 2]; 2] = [[5.5, 2.0], [6.4, 2.0]];

impl FloorPlan {
    /// A corridor `x ∈ [0, 12]`, `y ∈ [0, 2]` with the door [`DOOR`] in its upper wall into a
    /// rectangular room from `room_min` to `room_max` (`room_min[1] = 2`, the room spanning
    /// the door).
    pub fn corridor_with_room(room_min: [f64; 2], room_max: [f64; 2]) -> FloorPlan {
        let [[d0, y], [d1, _]] = DOOR;
        let mut walls = vec![
            [[0.0, 0.0], [12.0, 0.0]],
            [[0.0, 0.0], [0.0, 2.0]],
            [[12.0, 0.0], [12.0, 2.0]],
            [[0.0, y], [d0, y]],
            [[d1, y], [12.0, y]],
        ];
        let (x0, x1, y1) = (room_min[0], room_max[0], room_max[1]);
        walls.extend([
            [[x0, y], [d0, y]],
            [[d1, y], [x1, y]],
            [[x0, y], [x0, y1]],
            [[x1, y], [x1, y1]],
            [[x0, y1], [x1, y1]],
        ]);
        FloorPlan { walls }
    }

    /// The corridor with a 5 m × 4 m office (`x ∈ [4, 9]`, `y ∈ [2, 6]`).
    pub fn corridor_and_room() -> FloorPlan {
        FloorPlan::corridor_with_room([4.0, 2.0], [9.0, 6.0])
    }

    /// The corridor with a 32 m × 28 m hall (`x ∈ [−10, 22]`, `y ∈ [2, 30]`).
    pub fn corridor_and_hall() -> FloorPlan {
        FloorPlan::corridor_with_room([-10.0, 2.0], [22.0, 30.0])
    }

    /// The robot's poses on a drive through the door: along the corridor's middle (`y = 1`)
    /// from `x = 1` to the door's centre, a quarter turn on the spot in steps of 0.2 rad,
    /// then `+y` through the door to `y = 4.5`; `step` metres between poses.
    ///
    /// # Errors
    /// A `step` that is not finite or is below [`MIN_RUN_STEP`] (the run would not end, or
    /// not in bounded memory).
    pub fn door_run(&self, step: f64) -> Result<Vec<Pose2>, MultimapError> {
        if !(step.is_finite() && step >= MIN_RUN_STEP) {
            return Err(MultimapError::Parameter {
                field: "step",
                value: step,
                why: "must be finite and at least MIN_RUN_STEP (1 mm)",
            });
        }
        let xd = 0.5 * (DOOR[0][0] + DOOR[1][0]);
        let mut poses = Vec::new();
        let mut x = 1.0;
        while x < xd {
            poses.push(Pose2 {
                x,
                y: 1.0,
                theta: 0.0,
            });
            x += step;
        }
        let mut th = 0.0;
        while th < FRAC_PI_2 {
            poses.push(Pose2 {
                x: xd,
                y: 1.0,
                theta: th,
            });
            th += 0.2;
        }
        let mut y = 1.0;
        while y <= 4.5 {
            poses.push(Pose2 {
                x: xd,
                y,
                theta: FRAC_PI_2,
            });
            y += step;
        }
        Ok(poses)
    }

    /// The range from `origin` along `bearing` (world frame) to the nearest wall, if any.
    pub fn cast(&self, origin: [f64; 2], bearing: f64) -> Option<f64> {
        let (s, c) = bearing.sin_cos();
        self.walls
            .iter()
            .filter_map(|[a, b]| {
                let e = [b[0] - a[0], b[1] - a[1]];
                let den = c * e[1] - s * e[0];
                if den.abs() < 1e-12 {
                    return None;
                }
                let w = [a[0] - origin[0], a[1] - origin[1]];
                let t = (w[0] * e[1] - w[1] * e[0]) / den;
                let u = (w[0] * s - w[1] * c) / den;
                (t > 1e-9 && (0.0..=1.0).contains(&u)).then_some(t)
            })
            .min_by(f64::total_cmp)
    }
}

/// A simulated 2-D scanner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scanner {
    /// Bearing of the first beam (rad).
    pub angle_min: f64,
    /// Bearing of the last beam (rad).
    pub angle_max: f64,
    /// Number of beams.
    pub beams: usize,
    /// Maximum range (m); walls beyond it give no return (`+inf`).
    pub max_range: f64,
    /// The sensor's pose on the robot.
    pub mount: Pose2,
}

impl Scanner {
    /// A 360° scanner at the robot's origin (`beams` beams from −π, one increment short of
    /// +π).
    ///
    /// # Errors
    /// As [`Scanner::validate`]: fewer than 2 or more than [`MAX_BEAMS`] beams, a maximum
    /// range that is not finite and positive.
    pub fn full_circle(beams: usize, max_range: f64) -> Result<Scanner, MultimapError> {
        let scanner = Scanner {
            angle_min: -PI,
            angle_max: PI - 2.0 * PI / beams.max(1) as f64,
            beams,
            max_range,
            mount: Pose2::IDENTITY,
        };
        scanner.validate()?;
        Ok(scanner)
    }

    /// A 180° scanner looking forward (like the Málaga SICK), mounted at `mount`.
    ///
    /// # Errors
    /// As [`Scanner::full_circle`], and a mount that is not finite.
    pub fn front_half(
        beams: usize,
        max_range: f64,
        mount: Pose2,
    ) -> Result<Scanner, MultimapError> {
        let scanner = Scanner {
            angle_min: -FRAC_PI_2,
            angle_max: FRAC_PI_2,
            beams,
            max_range,
            mount,
        };
        scanner.validate()?;
        Ok(scanner)
    }

    /// Checks the scanner: 2 to [`MAX_BEAMS`] beams, finite bearings with
    /// `angle_min < angle_max`, a finite positive maximum range, a finite mount.
    pub fn validate(&self) -> Result<(), MultimapError> {
        if !(2..=MAX_BEAMS).contains(&self.beams) {
            return Err(MultimapError::Parameter {
                field: "beams",
                value: self.beams as f64,
                why: "must be from 2 to chronomap_geometry::scan::MAX_BEAMS",
            });
        }
        for (field, value) in [("angle_min", self.angle_min), ("angle_max", self.angle_max)] {
            if !value.is_finite() {
                return Err(GeometryError::NotFinite { field, value }.into());
            }
        }
        if self.angle_max <= self.angle_min {
            return Err(MultimapError::Parameter {
                field: "angle_max",
                value: self.angle_max,
                why: "must exceed angle_min",
            });
        }
        if !(self.max_range.is_finite() && self.max_range > 0.0) {
            return Err(MultimapError::Parameter {
                field: "max_range",
                value: self.max_range,
                why: "must be finite and positive",
            });
        }
        Ok(self.mount.validate("mount")?)
    }

    /// The scan of `plan` taken at time `time` by the robot at `pose`.
    ///
    /// # Errors
    /// As [`Scanner::validate`], and a pose or time that is not finite.
    pub fn scan(&self, plan: &FloorPlan, pose: &Pose2, time: f64) -> Result<Scan2d, MultimapError> {
        self.validate()?;
        pose.validate("pose")?;
        if !time.is_finite() {
            return Err(GeometryError::NotFinite {
                field: "time",
                value: time,
            }
            .into());
        }
        let sensor = pose.compose(&self.mount);
        let inc = (self.angle_max - self.angle_min) / (self.beams - 1) as f64;
        let ranges = (0..self.beams)
            .map(|k| {
                let bearing = sensor.theta + self.angle_min + k as f64 * inc;
                match plan.cast([sensor.x, sensor.y], bearing) {
                    Some(r) if r < self.max_range => r,
                    _ => f64::INFINITY,
                }
            })
            .collect();
        Ok(Scan2d {
            time,
            angle_min: self.angle_min,
            angle_max: self.angle_max,
            max_range: self.max_range,
            ranges,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_scanners_are_refused_not_clamped() {
        assert_eq!(
            Scanner::full_circle(1, 30.0).unwrap_err().to_string(),
            "parameter beams = 1: must be from 2 to chronomap_geometry::scan::MAX_BEAMS"
        );
        assert!(Scanner::full_circle(0, 30.0).is_err());
        assert!(Scanner::full_circle(MAX_BEAMS + 1, 30.0).is_err());
        assert!(Scanner::front_half(361, f64::NAN, Pose2::IDENTITY).is_err());
        assert!(Scanner::front_half(361, -1.0, Pose2::IDENTITY).is_err());
        // A scanner made by hand is checked when it scans.
        let mut s = Scanner::full_circle(4, 30.0).unwrap();
        s.beams = 1;
        let plan = FloorPlan::corridor_and_room();
        assert!(s.scan(&plan, &Pose2::IDENTITY, 0.0).is_err());
        s.beams = 4;
        // Four beams at −180°, −90°, 0°, 90° from (1, 1) in the 2 m corridor x ∈ [0, 12].
        let scan = s
            .scan(&plan, &Pose2::new(1.0, 1.0, 0.0).unwrap(), 0.0)
            .unwrap();
        let expected = [1.0, 1.0, 11.0, 1.0];
        for (r, e) in scan.ranges.iter().zip(expected) {
            assert!((r - e).abs() < 1e-9, "{:?}", scan.ranges);
        }
        assert!(s.scan(&plan, &Pose2::IDENTITY, f64::NAN).is_err());
    }

    #[test]
    fn door_run_steps_are_bounded() {
        let plan = FloorPlan::corridor_and_room();
        assert!(plan.door_run(0.0).is_err());
        assert!(plan.door_run(f64::NAN).is_err());
        // x = 1.0, 1.5, …, 5.5 (< 5.95): 10; θ = 0, 0.2, …, 1.4: 8; y = 1.0, 1.5, …, 4.5: 8.
        let run = plan.door_run(0.5).unwrap();
        assert_eq!(run.len(), 10 + 8 + 8);
        assert_eq!(
            run[9],
            Pose2 {
                x: 5.5,
                y: 1.0,
                theta: 0.0
            }
        );
        assert_eq!(
            run[25],
            Pose2 {
                x: 0.5 * (DOOR[0][0] + DOOR[1][0]),
                y: 4.5,
                theta: FRAC_PI_2
            }
        );
    }
}
