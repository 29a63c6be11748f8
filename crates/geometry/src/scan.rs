//! 2-D laser scans: ranges at evenly spaced bearings, as `sensor_msgs/LaserScan` and the
//! SICK scanners give them.
//!
//! ```
//! use chronomap_geometry::scan::Scan2d;
//!
//! // Three beams at -90°, 0° and +90°; the middle one saw nothing (REP 117: +inf).
//! let scan = Scan2d::new(0.0, -std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2,
//!     80.0, vec![1.0, f64::INFINITY, 2.0])?;
//! assert_eq!(scan.valid_count(), 2);
//! let points = scan.points();
//! assert!((points[0][1] + 1.0).abs() < 1e-12 && (points[1][1] - 2.0).abs() < 1e-12);
//! # Ok::<(), chronomap_geometry::scan::ScanError>(())
//! ```

use serde::{Deserialize, Serialize};

/// The most beams a scan may have (a 0.01° scanner over 360° has 36,000).
pub const MAX_BEAMS: usize = 1 << 20;

/// Why a scan is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScanError {
    /// A scan needs at least two beams to have an angular resolution.
    #[error("a scan needs at least 2 beams, this one has {0}")]
    TooFewBeams(usize),
    /// More beams than [`MAX_BEAMS`].
    #[error("a scan may have at most {MAX_BEAMS} beams, this one has {0}")]
    TooManyBeams(usize),
    /// An angle or the maximum range is not finite, or the angles are not increasing.
    #[error("{field}: {value} is not valid ({why})")]
    Field {
        /// The field (`angle_min`, `angle_max`, `max_range`, `time`).
        field: &'static str,
        /// Its value.
        value: f64,
        /// What is wrong with it.
        why: &'static str,
    },
    /// A range is NaN or negative.
    #[error("range {index}: {value} is not a range (NaN or negative)")]
    Range {
        /// The beam.
        index: usize,
        /// Its value.
        value: f64,
    },
}

/// One 2-D scan in the sensor frame: beam `k` of `n` points at bearing
/// `angle_min + k·(angle_max − angle_min)/(n − 1)` (counter-clockwise, 0 straight ahead).
///
/// A range is a return if it is finite, positive and shorter than `max_range`; `+inf`, `0` and
/// anything at or beyond `max_range` are no returns (REP 117, and the max-range artefacts of
/// SICK scanners).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scan2d {
    /// When it was taken (s).
    pub time: f64,
    /// Bearing of the first beam (rad).
    pub angle_min: f64,
    /// Bearing of the last beam (rad).
    pub angle_max: f64,
    /// Ranges at or beyond this are no returns (m).
    pub max_range: f64,
    /// Ranges (m), one per beam.
    pub ranges: Vec<f64>,
}

impl Scan2d {
    /// A checked scan: finite time and angles, `angle_max > angle_min`, a positive finite
    /// maximum range, 2 to [`MAX_BEAMS`] ranges, none NaN or negative.
    pub fn new(
        time: f64,
        angle_min: f64,
        angle_max: f64,
        max_range: f64,
        ranges: Vec<f64>,
    ) -> Result<Scan2d, ScanError> {
        let scan = Scan2d {
            time,
            angle_min,
            angle_max,
            max_range,
            ranges,
        };
        scan.validate()?;
        Ok(scan)
    }

    /// Checks the invariants of [`Scan2d::new`] (for scans made field by field or decoded).
    pub fn validate(&self) -> Result<(), ScanError> {
        let field = |field, value: f64, why| Err(ScanError::Field { field, value, why });
        if !self.time.is_finite() {
            return field("time", self.time, "not finite");
        }
        if !self.angle_min.is_finite() {
            return field("angle_min", self.angle_min, "not finite");
        }
        if !self.angle_max.is_finite() || self.angle_max <= self.angle_min {
            return field(
                "angle_max",
                self.angle_max,
                "must be finite and above angle_min",
            );
        }
        if !(self.max_range.is_finite() && self.max_range > 0.0) {
            return field("max_range", self.max_range, "must be positive and finite");
        }
        match self.ranges.len() {
            n if n < 2 => return Err(ScanError::TooFewBeams(n)),
            n if n > MAX_BEAMS => return Err(ScanError::TooManyBeams(n)),
            _ => {}
        }
        if let Some((index, &value)) = self
            .ranges
            .iter()
            .enumerate()
            .find(|(_, r)| r.is_nan() || **r < 0.0)
        {
            return Err(ScanError::Range { index, value });
        }
        Ok(())
    }

    /// Angle between neighbouring beams (rad).
    pub fn angle_increment(&self) -> f64 {
        (self.angle_max - self.angle_min) / (self.ranges.len() - 1) as f64
    }

    /// Bearing of beam `k` (rad).
    pub fn bearing(&self, k: usize) -> f64 {
        self.angle_min + k as f64 * self.angle_increment()
    }

    /// Whether beam `k` is a return (finite, positive, below the maximum range).
    pub fn is_return(&self, k: usize) -> bool {
        let r = self.ranges[k];
        r.is_finite() && r > 0.0 && r < self.max_range
    }

    /// Number of returns.
    pub fn valid_count(&self) -> usize {
        (0..self.ranges.len())
            .filter(|&k| self.is_return(k))
            .count()
    }

    /// The returns as points `[x, y]` in the sensor frame, in beam order.
    pub fn points(&self) -> Vec<[f64; 2]> {
        (0..self.ranges.len())
            .filter(|&k| self.is_return(k))
            .map(|k| {
                let (s, c) = self.bearing(k).sin_cos();
                [self.ranges[k] * c, self.ranges[k] * s]
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bearings_span_the_aperture_counter_clockwise() {
        let scan = Scan2d::new(0.0, -1.0, 1.0, 10.0, vec![1.0; 5]).unwrap();
        assert_eq!(scan.angle_increment(), 0.5);
        assert_eq!(scan.bearing(0), -1.0);
        assert_eq!(scan.bearing(4), 1.0);
    }

    #[test]
    fn no_returns_are_infinite_zero_or_at_the_maximum() {
        let scan = Scan2d::new(0.0, -1.0, 1.0, 10.0, vec![f64::INFINITY, 0.0, 10.0, 9.99]).unwrap();
        assert_eq!(scan.valid_count(), 1);
        assert_eq!(scan.points().len(), 1);
    }

    #[test]
    fn bad_scans_are_refused_naming_the_field() {
        assert_eq!(
            Scan2d::new(0.0, 0.0, 1.0, 10.0, vec![1.0]),
            Err(ScanError::TooFewBeams(1))
        );
        let e = Scan2d::new(0.0, 1.0, 1.0, 10.0, vec![1.0, 1.0]).unwrap_err();
        assert!(
            e.to_string().starts_with("angle_max: 1 is not valid"),
            "{e}"
        );
        let e = Scan2d::new(0.0, 0.0, 1.0, 10.0, vec![1.0, f64::NAN]).unwrap_err();
        assert!(matches!(e, ScanError::Range { index: 1, value } if value.is_nan()));
        let e = Scan2d::new(f64::NAN, 0.0, 1.0, 10.0, vec![1.0, 1.0]).unwrap_err();
        assert!(e.to_string().starts_with("time: NaN"), "{e}");
    }
}
