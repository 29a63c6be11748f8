//! Pose-tolerant pair features of two 2-D scans — **our extension beyond the paper**, not part
//! of [Stüde 2024] §3.2.1 or [Granström 2009]. The paper-exact pair vector is
//! [`descriptor::compare`](crate::descriptor::compare) (41 values); [`compare_extended`]
//! appends the [`PROFILE_FEATURES`] values below to it (44 values).
//!
//! Why: the descriptor's features are invariant to rotations of a full 360° scan, but a 180°
//! scanner (the SICK of the Málaga log: 361 beams of 0.5°) sees a *different part* of the
//! room when a revisit differs in heading (Málaga: median 14°, up to 84°), and 3 m apart it
//! sees the same walls at other ranges. These features compare the range profiles directly,
//! allowing for a change in heading:
//!
//! | # | feature | meaning |
//! |---|---|---|
//! | 0 | `max_s ρ(a_k, b_{k+s})` | best Pearson correlation of the range profiles over bearing shifts `s`, `|s·Δθ| ≤ max_shift`, on the overlap of the two fields of view |
//! | 1 | `min_s mean_k |a_k − b_{k+s}|` (m) | smallest mean absolute range difference over the same shifts |
//! | 2 | `mean_q |a_(q) − b_(q)|` (m) | mean difference of the *sorted* ranges: the 1-D Wasserstein distance of the two range distributions, independent of heading |
//!
//! Ranges are those of the descriptor's "all beams" set: clipped to `r_max`, a no-return
//! counting as `r_max`. A shift is used only if the overlap keeps at least `min_overlap` of the
//! beams.
//!
//! ```
//! use chronomap_lidar::Scan2d;
//! use chronomap_lidar::profile::{ProfileParams, compare_profiles, range_profile};
//!
//! // A 180° scan of a wall pattern, and the same place seen with the heading turned by 10°.
//! let room = |a: f64| 4.0 + 2.0 * (3.0 * a).sin() + (7.0 * a).cos();
//! let scan = |turn: f64| {
//!     let ranges = (0..361).map(|k| room(-1.5708 + k as f64 * 0.5f64.to_radians() + turn));
//!     Scan2d::new(0.0, -1.5708, 1.5708, 80.0, ranges.collect())
//! };
//! let p = ProfileParams::default();
//! let a = range_profile(&scan(0.0)?, &p)?;
//! let b = range_profile(&scan(10f64.to_radians())?, &p)?;
//! let f = compare_profiles(&a, &b, &p)?;
//! assert!(f[0] > 0.999);   // shifted by 20 beams, the profiles agree
//! assert!(f[1] < 1e-9);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! [Granström 2009]: K. Granström, J. Callmer, F. Ramos, J. Nieto, "Learning to detect loop
//! closure from range data", ICRA 2009.
//! [Stüde 2024]: M. Stüde, dissertation, Hannover 2024.

use serde::{Deserialize, Serialize};

use crate::descriptor::{
    Descriptor, DescriptorError, PAIR_FEATURE_NAMES, PAIR_FEATURES, compare, pearson,
};
use crate::scan::Scan2d;

/// Number of profile features ([module table](self)).
pub const PROFILE_FEATURES: usize = 3;
/// Length of an extended pair vector: the paper's 41 and the profile features.
pub const EXTENDED_PAIR_FEATURES: usize = PAIR_FEATURES + PROFILE_FEATURES;
/// Names of the profile features, in order.
pub const PROFILE_FEATURE_NAMES: [&str; PROFILE_FEATURES] = [
    "best shifted range correlation",
    "least shifted mean |dr|",
    "sorted range distance",
];

/// Names of the extended pair features, in the order of [`compare_extended`].
pub fn extended_feature_names() -> [&'static str; EXTENDED_PAIR_FEATURES] {
    std::array::from_fn(|k| {
        if k < PAIR_FEATURES {
            PAIR_FEATURE_NAMES[k]
        } else {
            PROFILE_FEATURE_NAMES[k - PAIR_FEATURES]
        }
    })
}

/// Parameters of the profile features.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProfileParams {
    /// `r_max` (m), as the descriptor's (40 m).
    pub max_range: f64,
    /// The largest change of heading tried (rad; 60°).
    pub max_shift: f64,
    /// The least fraction of beams two shifted profiles must share (0.5).
    pub min_overlap: f64,
}

impl Default for ProfileParams {
    /// `r_max = 40` m (as [`DescriptorParams`](crate::descriptor::DescriptorParams)), shifts up
    /// to 60°, at least half the beams shared. Fixed before any measurement, not tuned.
    fn default() -> Self {
        ProfileParams {
            max_range: 40.0,
            max_shift: std::f64::consts::FRAC_PI_3,
            min_overlap: 0.5,
        }
    }
}

impl ProfileParams {
    /// Checks the parameters: `r_max` positive and finite, `max_shift` in `[0, 2π]`,
    /// `min_overlap` in `(0, 1]`.
    pub fn validate(&self) -> Result<(), DescriptorError> {
        let bad = |field, value| Err(DescriptorError::Param { field, value });
        if !(self.max_range.is_finite() && self.max_range > 0.0) {
            return bad("max_range", self.max_range);
        }
        if !(self.max_shift >= 0.0 && self.max_shift <= std::f64::consts::TAU) {
            return bad("max_shift", self.max_shift);
        }
        if !(self.min_overlap > 0.0 && self.min_overlap <= 1.0) {
            return bad("min_overlap", self.min_overlap);
        }
        Ok(())
    }
}

/// The range profile of a scan: its clipped ranges in beam order and sorted.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RangeProfile {
    /// The angle between beams (rad).
    pub angle_increment: f64,
    /// Ranges in beam order, clipped to `r_max`, a no-return as `r_max` (m).
    pub ranges: Vec<f64>,
    /// The same, sorted ascending.
    pub sorted: Vec<f64>,
}

/// The profile of a scan.
///
/// # Errors
/// [`DescriptorError::Param`] for bad parameters, [`DescriptorError::Scan`] for a scan that
/// breaks the invariants of [`Scan2d::validate`].
pub fn range_profile(
    scan: &Scan2d,
    params: &ProfileParams,
) -> Result<RangeProfile, DescriptorError> {
    params.validate()?;
    scan.validate()?;
    let ranges: Vec<f64> = (0..scan.ranges.len())
        .map(|k| {
            if scan.is_return(k) {
                scan.ranges[k].min(params.max_range)
            } else {
                params.max_range
            }
        })
        .collect();
    let mut sorted = ranges.clone();
    sorted.sort_by(f64::total_cmp);
    Ok(RangeProfile {
        angle_increment: scan.angle_increment(),
        ranges,
        sorted,
    })
}

/// The [profile features](self) of two profiles.
///
/// # Errors
/// [`DescriptorError::Param`] for bad parameters; [`DescriptorError::Mismatch`] if the
/// profiles differ in beam count or angular step (by more than 1e-9 rad), are empty, or hold a
/// non-finite range.
pub fn compare_profiles(
    a: &RangeProfile,
    b: &RangeProfile,
    params: &ProfileParams,
) -> Result<[f64; PROFILE_FEATURES], DescriptorError> {
    params.validate()?;
    let n = a.ranges.len();
    if n == 0
        || b.ranges.len() != n
        || a.sorted.len() != n
        || b.sorted.len() != n
        || (a.angle_increment - b.angle_increment).abs().is_nan()
        || (a.angle_increment - b.angle_increment).abs() > 1e-9
    {
        return Err(DescriptorError::Mismatch(
            "range profiles of different beam counts or steps",
        ));
    }
    let finite = |p: &RangeProfile| p.ranges.iter().chain(&p.sorted).all(|v| v.is_finite());
    if !(finite(a) && finite(b)) {
        return Err(DescriptorError::Mismatch("a range profile is not finite"));
    }
    let step = a.angle_increment.abs();
    let by_angle = if step > 0.0 {
        (params.max_shift / step).floor() as usize
    } else {
        0
    };
    let min_len = ((params.min_overlap * n as f64).ceil() as usize).max(2);
    let max_shift = by_angle.min(n.saturating_sub(min_len));
    let (mut best_corr, mut best_diff) = (f64::NEG_INFINITY, f64::INFINITY);
    for s in 0..=max_shift {
        let len = n - s;
        if len < 2 {
            continue;
        }
        // b shifted by +s beams against a, and by −s.
        for (x, y) in [
            (&a.ranges[..len], &b.ranges[s..]),
            (&a.ranges[s..], &b.ranges[..len]),
        ] {
            best_corr = best_corr.max(pearson(x, y));
            let diff = x.iter().zip(y).map(|(p, q)| (p - q).abs()).sum::<f64>() / len as f64;
            best_diff = best_diff.min(diff);
        }
    }
    let sorted = a
        .sorted
        .iter()
        .zip(&b.sorted)
        .map(|(p, q)| (p - q).abs())
        .sum::<f64>()
        / n as f64;
    Ok([best_corr.max(-1.0), best_diff.min(1e300), sorted])
}

/// The paper's pair vector ([`compare`], [Stüde 2024] §3.2.1) followed by the profile
/// features ([`compare_profiles`], our extension): [`EXTENDED_PAIR_FEATURES`] values.
///
/// # Errors
/// As [`compare`] and [`compare_profiles`].
pub fn compare_extended(
    a: (&Descriptor, &RangeProfile),
    b: (&Descriptor, &RangeProfile),
    params: &ProfileParams,
) -> Result<[f64; EXTENDED_PAIR_FEATURES], DescriptorError> {
    let paper = compare(a.0, b.0)?;
    let extra = compare_profiles(a.1, b.1, params)?;
    let mut out = [0.0; EXTENDED_PAIR_FEATURES];
    out[..PAIR_FEATURES].copy_from_slice(&paper);
    out[PAIR_FEATURES..].copy_from_slice(&extra);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan(ranges: Vec<f64>) -> Scan2d {
        let n = ranges.len();
        let step = 1f64.to_radians();
        Scan2d::new(0.0, 0.0, step * (n - 1) as f64, 80.0, ranges).unwrap()
    }

    #[test]
    fn hand_computed_profile_features() {
        let p = ProfileParams {
            max_range: 10.0,
            max_shift: 2.5f64.to_radians(),
            min_overlap: 0.5,
        };
        // a: 1 2 3 4 5 6; b = a shifted by two beams: 3 4 5 6 7 8.
        let a = range_profile(&scan(vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]), &p).unwrap();
        let b = range_profile(&scan(vec![3.0, 4.0, 5.0, 6.0, 7.0, 8.0]), &p).unwrap();
        let f = compare_profiles(&a, &b, &p).unwrap();
        // Any shift correlates perfectly (both linear); a[k+2] = b[k] gives |Δr| = 0.
        assert!((f[0] - 1.0).abs() < 1e-12);
        assert_eq!(f[1], 0.0);
        // Sorted: every range differs by 2.
        assert_eq!(f[2], 2.0);
        // Only one beam of shift allowed: the best mean |Δr| is 1 (b[k] vs a[k+1]).
        let p1 = ProfileParams {
            max_shift: 1.5f64.to_radians(),
            ..p.clone()
        };
        assert_eq!(compare_profiles(&a, &b, &p1).unwrap()[1], 1.0);
        // No-returns and long ranges count as r_max = 10.
        let c = range_profile(&scan(vec![f64::INFINITY, 2.0, 30.0, 4.0, 5.0, 90.0]), &p).unwrap();
        assert_eq!(c.ranges, vec![10.0, 2.0, 10.0, 4.0, 5.0, 10.0]);
        assert_eq!(c.sorted, vec![2.0, 4.0, 5.0, 10.0, 10.0, 10.0]);
    }

    #[test]
    fn mismatched_or_bad_input_is_refused() {
        let p = ProfileParams::default();
        let a = range_profile(&scan(vec![1.0; 10]), &p).unwrap();
        let b = range_profile(&scan(vec![1.0; 11]), &p).unwrap();
        assert!(matches!(
            compare_profiles(&a, &b, &p),
            Err(DescriptorError::Mismatch(_))
        ));
        let mut bad = a.clone();
        bad.ranges[3] = f64::NAN;
        assert!(compare_profiles(&a, &bad, &p).is_err());
        let q = ProfileParams {
            min_overlap: 0.0,
            ..p
        };
        assert!(matches!(
            range_profile(&scan(vec![1.0; 10]), &q),
            Err(DescriptorError::Param {
                field: "min_overlap",
                ..
            })
        ));
        // Flat profiles have no correlation (0), but equal ranges.
        let f = compare_profiles(&a, &a, &ProfileParams::default()).unwrap();
        assert_eq!(f, [0.0, 0.0, 0.0]);
    }
}
