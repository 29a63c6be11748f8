//! The global range-data descriptor of [Granström 2009] as [Stüde 2024] §3.2.1 uses it
//! (eq. (3.7)): `χ = (χ^I, χ^II)`, 32 scalar features `χ^I` and 9 range histograms `χ^II`, and
//! the pair comparison that the loop classifier sees.
//!
//! ```
//! use chronomap_lidar::Scan2d;
//! use chronomap_lidar::descriptor::{DescriptorParams, PAIR_FEATURES, compare, describe_scan};
//!
//! // A robot in a 4 m wide corridor, and the same place seen from 0.1 m further on.
//! let corridor = |shift: f64| {
//!     let n = 181;
//!     let ranges = (0..n).map(|k| {
//!         let a = -std::f64::consts::FRAC_PI_2 + k as f64 * std::f64::consts::PI / 180.0;
//!         let wall = 2.0 / a.sin().abs().max(1e-3);   // walls at y = ±2
//!         let end = (20.0 - shift) / a.cos().max(1e-3); // the corridor ends 20 m ahead
//!         wall.min(end)
//!     }).collect();
//!     Scan2d::new(0.0, -std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2, 80.0, ranges)
//! };
//! let params = DescriptorParams::default();
//! let a = describe_scan(&corridor(0.0)?, &params)?;
//! let b = describe_scan(&corridor(0.1)?, &params)?;
//! let pair = compare(&a, &b)?;
//! assert_eq!(pair.len(), PAIR_FEATURES);
//! // Similar scans: small scalar differences, histogram correlations near 1.
//! assert!(pair[4] < 0.1);          // |Δ mean range| (m)
//! assert!(pair[32] > 0.9);         // correlation of the 0.1 m range histograms
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # The features
//! The paper's exact list could not be consulted for this implementation: the list below is a
//! reconstruction from [Stüde 2024] §3.2.1 (32 scalar features, 9 histograms, `n_χ = 843`) and
//! the features [Granström 2009] and Granström & Schön (IROS 2010) describe (area, perimeter,
//! range statistics, range differences, curvature, kurtosis, gaps, range histograms). The
//! histogram bin sizes `0.1, 0.25, 0.5, 0.75, 1, 1.5, 2, 2.5, 3` m with `r_max = 40` m give
//! `Σ ⌈40/b⌉ = 811` bins, and `811 + 32 = 843 = n_χ` as the dissertation states — that is how
//! the defaults of [`DescriptorParams`] were chosen.
//!
//! Two range sets are used. *All beams*: every beam, its range clipped to `r_max`, a no-return
//! counting as `r_max` (open space, as [Granström 2009] sets max-range readings). *Returns*:
//! the beams that returned a range below `r_max`. Consecutive means neighbouring beams.
//!
//! | # | feature | set |
//! |---|---|---|
//! | 0 | area swept by the scan, `Σ ½ r_k r_{k+1} sin Δθ`, over the area at `r_max` | all beams |
//! | 1 | the same, only pairs of neighbouring returns | returns |
//! | 2 | perimeter `Σ ‖p_{k+1} − p_k‖` (m) | all beams |
//! | 3 | perimeter, neighbouring returns only (m) | returns |
//! | 4, 5 | mean and standard deviation of the ranges (m) | all beams |
//! | 6, 7 | mean and standard deviation of the ranges (m) | returns |
//! | 8, 9 | excess kurtosis of the ranges | all beams / returns |
//! | 10, 11 | mean and sd of `|r_{k+1} − r_k|` (m) | all beams |
//! | 12, 13 | mean and sd of `|r_{k+1} − r_k|` (m) | neighbouring returns |
//! | 14, 15 | mean and sd of the distance between successive return points (m) | returns |
//! | 16, 17 | mean and sd of the curvature `4·A/(abc)` of successive return triples (1/m) | returns |
//! | 18–20 | fraction of neighbouring beams with a gap `|r_{k+1} − r_k|` above 0.5, 1.5, 2.5 m | all beams |
//! | 21 | fraction of beams that returned | — |
//! | 22 | distance of the returns' centroid from the sensor (m) | returns |
//! | 23, 24 | mean and sd of the returns' distances to their centroid (m) | returns |
//! | 25, 26 | square roots of the larger and smaller eigenvalue of the returns' covariance (m) | returns |
//! | 27–29 | algebraic circle fit (Kåsa): radius, rms residual, distance of the centre (m) | returns |
//! | 30 | circularity `4π·A/P²` of the polygon of neighbouring returns | returns |
//! | 31 | mean `|r_{k+1} − 2r_k + r_{k−1}|` (range roughness, m) | all beams |
//!
//! Histograms (`χ^II`): for each bin size `b_j`, `⌈r_max/b_j⌉` annular bins counting the returns
//! by range, a range at or beyond `r_max` moved to `r_max` (last bin) as §3.2.1 prescribes;
//! normalised to sum to 1. No-returns are not points and are not counted.
//!
//! Every feature is invariant to rotations of the sensor about its vertical axis (a shift of
//! the beam order changes only the wrap-around pair at the ends of a 360° scan).
//!
//! ## 3-D clouds
//! [`describe_cloud`] adapts the features that need beam order as follows (Granström & Schön,
//! IROS 2010, compute their 3-D features on the structured range image, which an unordered
//! `&[[f64; 3]]` cloud does not have). The range statistics (4–9) and the histograms use the
//! Euclidean 3-D ranges `‖p‖` (§3.2.1). Every other feature is computed on a *virtual 2-D
//! scan*: 360 azimuth sectors of 1°, each holding the largest horizontal range
//! `√(x² + y²)` of its points (the outline of the space seen from above; the largest, so that
//! floor and ceiling points in front of a wall do not hide it), an empty sector being a
//! no-return.
//!
//! # Pair comparison
//! [`compare`]: the absolute differences of the 32 scalar features and the Pearson correlation
//! of the 9 pairs of corresponding histograms, 41 values ([`PAIR_FEATURES`]); similar scans
//! give scalars near 0 and correlations near 1 (§3.2.1). A histogram with no spread (all its
//! mass in one bin of a one-bin histogram, or empty) has no correlation; it counts as 0.
//!
//! [Granström 2009]: K. Granström, J. Callmer, F. Ramos, J. Nieto, "Learning to detect loop
//! closure from range data", ICRA 2009.
//! [Stüde 2024]: M. Stüde, dissertation, Hannover 2024.

use serde::{Deserialize, Serialize};

use crate::scan::Scan2d;

/// Number of scalar features `χ^I` ([Stüde 2024] §3.2.1).
pub const SCALAR_FEATURES: usize = 32;
/// Number of range histograms `χ^II` ([Stüde 2024] §3.2.1).
pub const HISTOGRAMS: usize = 9;
/// Length of a pair feature vector ([`compare`]): 32 differences and 9 correlations.
pub const PAIR_FEATURES: usize = SCALAR_FEATURES + HISTOGRAMS;
/// The most bins one histogram may have (a 1 mm bin over 100 m).
pub const MAX_BINS: usize = 100_000;
/// The most points [`describe_cloud`] takes (a few sweeps of a 128-beam lidar).
pub const MAX_POINTS: usize = 1 << 24;

/// Names of the pair features, in the order of [`compare`].
pub const PAIR_FEATURE_NAMES: [&str; PAIR_FEATURES] = [
    "area",
    "area (returns)",
    "perimeter",
    "perimeter (returns)",
    "mean range",
    "sd range",
    "mean range (returns)",
    "sd range (returns)",
    "kurtosis",
    "kurtosis (returns)",
    "mean |dr|",
    "sd |dr|",
    "mean |dr| (returns)",
    "sd |dr| (returns)",
    "mean point spacing",
    "sd point spacing",
    "mean curvature",
    "sd curvature",
    "gaps > 0.5 m",
    "gaps > 1.5 m",
    "gaps > 2.5 m",
    "return fraction",
    "centroid distance",
    "mean distance to centroid",
    "sd distance to centroid",
    "major spread",
    "minor spread",
    "circle radius",
    "circle residual",
    "circle centre distance",
    "circularity",
    "range roughness",
    "corr hist 0.1 m",
    "corr hist 0.25 m",
    "corr hist 0.5 m",
    "corr hist 0.75 m",
    "corr hist 1 m",
    "corr hist 1.5 m",
    "corr hist 2 m",
    "corr hist 2.5 m",
    "corr hist 3 m",
];

/// Gap thresholds of features 18–20 (m).
const GAPS: [f64; 3] = [0.5, 1.5, 2.5];

/// Parameters of the descriptor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DescriptorParams {
    /// `r_max` (m): ranges are clipped here, and the histograms end here.
    pub max_range: f64,
    /// The bin sizes `b_1..b_9` of the range histograms (m).
    pub bin_sizes: [f64; HISTOGRAMS],
}

impl Default for DescriptorParams {
    /// `r_max = 40` m and bins `0.1, 0.25, 0.5, 0.75, 1, 1.5, 2, 2.5, 3` m: 843 numbers in all,
    /// the `n_χ` of [Stüde 2024] §3.2.1 (see the [module docs](self)).
    fn default() -> Self {
        DescriptorParams {
            max_range: 40.0,
            bin_sizes: [0.1, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0],
        }
    }
}

impl DescriptorParams {
    /// Checks the parameters: `r_max` positive and finite, bin sizes positive, each histogram
    /// at most [`MAX_BINS`] bins.
    pub fn validate(&self) -> Result<(), DescriptorError> {
        if !(self.max_range.is_finite() && self.max_range > 0.0) {
            return Err(DescriptorError::Param {
                field: "max_range",
                value: self.max_range,
            });
        }
        for &b in &self.bin_sizes {
            if !(b.is_finite() && b > 0.0) || (self.max_range / b).ceil() > MAX_BINS as f64 {
                return Err(DescriptorError::Param {
                    field: "bin_sizes",
                    value: b,
                });
            }
        }
        Ok(())
    }

    /// Number of bins of each histogram, `⌈r_max/b_j⌉`.
    pub fn bins(&self) -> [usize; HISTOGRAMS] {
        self.bin_sizes
            .map(|b| ((self.max_range / b).ceil() as usize).max(1))
    }

    /// Length `n_χ` of a descriptor: 32 plus the bins of all histograms (843 by default).
    pub fn descriptor_len(&self) -> usize {
        SCALAR_FEATURES + self.bins().iter().sum::<usize>()
    }
}

/// Why a descriptor cannot be computed or compared.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DescriptorError {
    /// A parameter is out of its range.
    #[error("descriptor parameter {field}: {value} is not valid")]
    Param {
        /// The parameter.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// The scan breaks its invariants (its message is part of this one's, not a source).
    #[error("scan: {0}")]
    Scan(crate::scan::ScanError),
    /// A point of a cloud is not finite.
    #[error("point {index}: a coordinate is not finite")]
    Point {
        /// The point.
        index: usize,
    },
    /// A cloud has more than [`MAX_POINTS`] points.
    #[error("a cloud may have at most {MAX_POINTS} points, this one has {0}")]
    TooManyPoints(usize),
    /// Two descriptors (or a descriptor and its parameters) do not match.
    #[error("descriptors do not match: {0}")]
    Mismatch(&'static str),
}

impl From<crate::scan::ScanError> for DescriptorError {
    fn from(e: crate::scan::ScanError) -> Self {
        DescriptorError::Scan(e)
    }
}

/// A descriptor `χ = (χ^I, χ^II)` ([Stüde 2024] eq. (3.7)).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Descriptor {
    /// `χ^I`: the 32 scalar features of the [module table](self).
    pub scalars: [f64; SCALAR_FEATURES],
    /// `χ^II`: the 9 normalised range histograms.
    pub histograms: [Vec<f64>; HISTOGRAMS],
}

impl Descriptor {
    /// Checks that every value is finite and the histograms are non-empty and non-negative.
    pub fn validate(&self) -> Result<(), DescriptorError> {
        if self.scalars.iter().any(|v| !v.is_finite()) {
            return Err(DescriptorError::Mismatch("a scalar feature is not finite"));
        }
        for h in &self.histograms {
            if h.is_empty() || h.len() > MAX_BINS || h.iter().any(|v| !(v.is_finite() && *v >= 0.0))
            {
                return Err(DescriptorError::Mismatch(
                    "a histogram is empty, too long or has a negative or non-finite bin",
                ));
            }
        }
        Ok(())
    }
}

/// The descriptor of a 2-D scan ([Granström 2009]; [Stüde 2024] §3.2.1, eq. (3.7)).
///
/// # Errors
/// [`DescriptorError::Param`] for bad parameters, [`DescriptorError::Scan`] for a scan that
/// breaks the invariants of [`Scan2d::validate`].
pub fn describe_scan(
    scan: &Scan2d,
    params: &DescriptorParams,
) -> Result<Descriptor, DescriptorError> {
    params.validate()?;
    scan.validate()?;
    let r_max = params.max_range;
    let returns: Vec<Option<f64>> = (0..scan.ranges.len())
        .map(|k| {
            let r = scan.ranges[k];
            (scan.is_return(k) && r < r_max).then_some(r)
        })
        .collect();
    let ranges: Vec<f64> = (0..scan.ranges.len())
        .map(|k| {
            if scan.is_return(k) {
                scan.ranges[k].min(r_max)
            } else {
                r_max
            }
        })
        .collect();
    let mut scalars = planar_features(
        &ranges,
        &returns,
        scan.angle_increment(),
        scan.angle_min,
        r_max,
    );
    let hist_ranges: Vec<f64> = (0..scan.ranges.len())
        .filter(|&k| scan.is_return(k))
        .map(|k| scan.ranges[k].min(r_max))
        .collect();
    let (all, ret): (Vec<f64>, Vec<f64>) = (ranges, returns.iter().flatten().copied().collect());
    range_statistics(&mut scalars, &all, &ret);
    Ok(Descriptor {
        scalars,
        histograms: histograms(&hist_ranges, params),
    })
}

/// The descriptor of a 3-D point cloud in the sensor frame (z up), with the adaptations of the
/// [module docs](self#3-d-clouds).
///
/// # Errors
/// [`DescriptorError::Param`] for bad parameters, [`DescriptorError::Point`] for a non-finite
/// point, [`DescriptorError::TooManyPoints`].
pub fn describe_cloud(
    points: &[[f64; 3]],
    params: &DescriptorParams,
) -> Result<Descriptor, DescriptorError> {
    params.validate()?;
    if points.len() > MAX_POINTS {
        return Err(DescriptorError::TooManyPoints(points.len()));
    }
    if let Some(index) = points.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(DescriptorError::Point { index });
    }
    let r_max = params.max_range;
    const SECTORS: usize = 360;
    let step = std::f64::consts::TAU / SECTORS as f64;
    let mut outline = vec![f64::NAN; SECTORS];
    for p in points {
        let h = p[0].hypot(p[1]);
        if h <= 0.0 {
            continue;
        }
        let a = p[1].atan2(p[0]) + std::f64::consts::PI; // [0, 2π]
        let s = ((a / step) as usize).min(SECTORS - 1);
        if outline[s].is_nan() || h > outline[s] {
            outline[s] = h;
        }
    }
    let returns: Vec<Option<f64>> = outline
        .iter()
        .map(|&h| (h.is_finite() && h < r_max).then_some(h))
        .collect();
    let ranges: Vec<f64> = outline
        .iter()
        .map(|&h| if h.is_finite() { h.min(r_max) } else { r_max })
        .collect();
    let angle_min = -std::f64::consts::PI + step / 2.0;
    let mut scalars = planar_features(&ranges, &returns, step, angle_min, r_max);
    let euclid: Vec<f64> = points
        .iter()
        .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
        .filter(|&r| r > 0.0)
        .collect();
    let all: Vec<f64> = euclid.iter().map(|&r| r.min(r_max)).collect();
    let ret: Vec<f64> = euclid.iter().copied().filter(|&r| r < r_max).collect();
    range_statistics(&mut scalars, &all, &ret);
    Ok(Descriptor {
        scalars,
        histograms: histograms(&all, params),
    })
}

/// The pair feature vector of two descriptors ([Stüde 2024] §3.2.1): `|χ^I_i − χ^I_j|`
/// element-wise, then the Pearson correlation of each pair of histograms.
///
/// # Errors
/// [`DescriptorError::Mismatch`] if the descriptors' histograms differ in length (made with
/// different parameters) or a descriptor is not finite.
pub fn compare(a: &Descriptor, b: &Descriptor) -> Result<[f64; PAIR_FEATURES], DescriptorError> {
    a.validate()?;
    b.validate()?;
    let mut out = [0.0; PAIR_FEATURES];
    for (o, (x, y)) in out.iter_mut().zip(a.scalars.iter().zip(&b.scalars)) {
        *o = (x - y).abs();
    }
    for (j, (ha, hb)) in a.histograms.iter().zip(&b.histograms).enumerate() {
        if ha.len() != hb.len() {
            return Err(DescriptorError::Mismatch(
                "histograms of different lengths (different descriptor parameters)",
            ));
        }
        out[SCALAR_FEATURES + j] = pearson(ha, hb);
    }
    Ok(out)
}

/// Pearson's correlation coefficient; 0 when either side has no spread.
pub fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n == 0 {
        return 0.0;
    }
    let ma = a[..n].iter().sum::<f64>() / n as f64;
    let mb = b[..n].iter().sum::<f64>() / n as f64;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for k in 0..n {
        let (da, db) = (a[k] - ma, b[k] - mb);
        sab += da * db;
        saa += da * da;
        sbb += db * db;
    }
    if saa <= 0.0 || sbb <= 0.0 {
        return 0.0;
    }
    (sab / (saa * sbb).sqrt()).clamp(-1.0, 1.0)
}

fn mean_sd(values: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let (mut n, mut sum) = (0usize, 0.0);
    for v in values.clone() {
        n += 1;
        sum += v;
    }
    if n == 0 {
        return (0.0, 0.0);
    }
    let mean = sum / n as f64;
    let var = values.map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64;
    (mean, var.sqrt())
}

/// Excess kurtosis `m4/m2² − 3` (0 without spread).
fn kurtosis(values: &[f64]) -> f64 {
    let n = values.len();
    if n == 0 {
        return 0.0;
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    let (mut m2, mut m4) = (0.0, 0.0);
    for v in values {
        let d = (v - mean) * (v - mean);
        m2 += d;
        m4 += d * d;
    }
    let (m2, m4) = (m2 / n as f64, m4 / n as f64);
    if m2 <= 1e-300 {
        0.0
    } else {
        m4 / (m2 * m2) - 3.0
    }
}

/// Features 4–9 from the ranges of all beams and of the returns.
fn range_statistics(scalars: &mut [f64; SCALAR_FEATURES], all: &[f64], returns: &[f64]) {
    let (m, s) = mean_sd(all.iter().copied());
    let (mr, sr) = mean_sd(returns.iter().copied());
    scalars[4] = m;
    scalars[5] = s;
    scalars[6] = mr;
    scalars[7] = sr;
    scalars[8] = kurtosis(all);
    scalars[9] = kurtosis(returns);
}

/// The normalised range histograms of `ranges` (already clipped to `r_max`).
fn histograms(ranges: &[f64], params: &DescriptorParams) -> [Vec<f64>; HISTOGRAMS] {
    let bins = params.bins();
    std::array::from_fn(|j| {
        let mut h = vec![0.0; bins[j]];
        for &r in ranges {
            let k = ((r / params.bin_sizes[j]) as usize).min(bins[j] - 1);
            h[k] += 1.0;
        }
        if !ranges.is_empty() {
            let n = ranges.len() as f64;
            h.iter_mut().for_each(|v| *v /= n);
        }
        h
    })
}

/// The beam-order and point-set features (all but 4–9) of a scan given as clipped ranges
/// (`ranges`), returns (`returns`), the angle between beams and the first bearing.
fn planar_features(
    ranges: &[f64],
    returns: &[Option<f64>],
    step: f64,
    angle_min: f64,
    r_max: f64,
) -> [f64; SCALAR_FEATURES] {
    let mut f = [0.0; SCALAR_FEATURES];
    let n = ranges.len();
    let sin = step.sin().abs();
    let full_area = 0.5 * r_max * r_max * sin * (n - 1) as f64;
    let point = |k: usize, r: f64| {
        let (s, c) = (angle_min + k as f64 * step).sin_cos();
        [r * c, r * s]
    };
    let dist = |p: [f64; 2], q: [f64; 2]| (p[0] - q[0]).hypot(p[1] - q[1]);

    // Consecutive beams.
    let (mut area, mut area_ret, mut perim, mut perim_ret) = (0.0, 0.0, 0.0, 0.0);
    let mut diffs = Vec::with_capacity(n);
    let mut diffs_ret = Vec::new();
    for k in 0..n - 1 {
        let (a, b) = (ranges[k], ranges[k + 1]);
        area += 0.5 * a * b * sin;
        perim += dist(point(k, a), point(k + 1, b));
        diffs.push((b - a).abs());
        if let (Some(a), Some(b)) = (returns[k], returns[k + 1]) {
            area_ret += 0.5 * a * b * sin;
            perim_ret += dist(point(k, a), point(k + 1, b));
            diffs_ret.push((b - a).abs());
        }
    }
    f[0] = area / full_area;
    f[1] = area_ret / full_area;
    f[2] = perim;
    f[3] = perim_ret;
    (f[10], f[11]) = mean_sd(diffs.iter().copied());
    (f[12], f[13]) = mean_sd(diffs_ret.iter().copied());
    for (g, &threshold) in GAPS.iter().enumerate() {
        f[18 + g] = diffs.iter().filter(|&&d| d > threshold).count() as f64 / diffs.len() as f64;
    }
    let pts: Vec<[f64; 2]> = returns
        .iter()
        .enumerate()
        .filter_map(|(k, r)| r.map(|r| point(k, r)))
        .collect();
    f[21] = pts.len() as f64 / n as f64;
    (f[14], f[15]) = mean_sd(pts.windows(2).map(|w| dist(w[0], w[1])));
    (f[16], f[17]) = mean_sd(pts.windows(3).map(|w| {
        let (a, b, c) = (dist(w[0], w[1]), dist(w[1], w[2]), dist(w[0], w[2]));
        let cross =
            (w[1][0] - w[0][0]) * (w[2][1] - w[0][1]) - (w[1][1] - w[0][1]) * (w[2][0] - w[0][0]);
        let denominator = a * b * c;
        // 4·A/(abc) with A = |cross|/2; coincident points have no curvature.
        if denominator > 1e-12 {
            2.0 * cross.abs() / denominator
        } else {
            0.0
        }
    }));
    // Point set.
    if !pts.is_empty() {
        let m = pts.len() as f64;
        let cx = pts.iter().map(|p| p[0]).sum::<f64>() / m;
        let cy = pts.iter().map(|p| p[1]).sum::<f64>() / m;
        f[22] = cx.hypot(cy);
        (f[23], f[24]) = mean_sd(pts.iter().map(|p| (p[0] - cx).hypot(p[1] - cy)));
        let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
        for p in &pts {
            let (dx, dy) = (p[0] - cx, p[1] - cy);
            sxx += dx * dx;
            syy += dy * dy;
            sxy += dx * dy;
        }
        let (sxx, syy, sxy) = (sxx / m, syy / m, sxy / m);
        let half_trace = 0.5 * (sxx + syy);
        let root = (0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy).sqrt();
        f[25] = (half_trace + root).max(0.0).sqrt();
        f[26] = (half_trace - root).max(0.0).sqrt();
        let (radius, residual, centre) = circle_fit(&pts, cx, cy, r_max);
        f[27] = radius;
        f[28] = residual;
        f[29] = centre;
    }
    f[30] = if perim_ret > 0.0 {
        4.0 * std::f64::consts::PI * area_ret / (perim_ret * perim_ret)
    } else {
        0.0
    };
    f[31] = mean_sd(ranges.windows(3).map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())).0;
    f
}

/// Kåsa's algebraic circle fit: minimises `Σ (x² + y² + Dx + Ey + F)²` (centred at the
/// centroid for conditioning). Returns the radius, the rms of `|‖p − c‖ − R|` and the distance
/// of the centre from the sensor; a degenerate (collinear or single-point) set gives
/// `(10·r_max, 0, 10·r_max)`, a circle too large to tell from a line. Radius and centre
/// distance are capped at `10·r_max`.
fn circle_fit(pts: &[[f64; 2]], cx: f64, cy: f64, r_max: f64) -> (f64, f64, f64) {
    let cap = 10.0 * r_max;
    if pts.len() < 3 {
        return (cap, 0.0, cap);
    }
    // Normal equations of [x y 1]·[D E F]ᵀ = −(x² + y²) in centred coordinates.
    let mut a = [[0.0; 3]; 3];
    let mut rhs = [0.0; 3];
    for p in pts {
        let (x, y) = (p[0] - cx, p[1] - cy);
        let row = [x, y, 1.0];
        let z = -(x * x + y * y);
        for i in 0..3 {
            for j in 0..3 {
                a[i][j] += row[i] * row[j];
            }
            rhs[i] += row[i] * z;
        }
    }
    let Some([d, e, f]) = solve3(a, rhs) else {
        return (cap, 0.0, cap);
    };
    let r2 = 0.25 * (d * d + e * e) - f;
    if r2.is_nan() || r2 <= 0.0 {
        return (cap, 0.0, cap);
    }
    let (ux, uy) = (-0.5 * d, -0.5 * e);
    let radius = r2.sqrt();
    if radius > cap {
        return (cap, 0.0, cap);
    }
    let residual = (pts
        .iter()
        .map(|p| {
            let r = (p[0] - cx - ux).hypot(p[1] - cy - uy) - radius;
            r * r
        })
        .sum::<f64>()
        / pts.len() as f64)
        .sqrt();
    (radius, residual, (cx + ux).hypot(cy + uy).min(cap))
}

/// Solves a 3×3 system by Gaussian elimination with partial pivoting; `None` if it is
/// (numerically) singular.
fn solve3(mut a: [[f64; 3]; 3], mut b: [f64; 3]) -> Option<[f64; 3]> {
    let scale = a.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    if scale.is_nan() || scale <= 0.0 {
        return None;
    }
    for col in 0..3 {
        let pivot = (col..3).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() <= 1e-12 * scale {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let pivot_row = a[col];
        for row in col + 1..3 {
            let factor = a[row][col] / pivot_row[col];
            for (v, p) in a[row][col..].iter_mut().zip(&pivot_row[col..]) {
                *v -= factor * p;
            }
            b[row] -= factor * b[col];
        }
    }
    let mut x = [0.0; 3];
    for row in (0..3).rev() {
        let s: f64 = (row + 1..3).map(|k| a[row][k] * x[k]).sum();
        x[row] = (b[row] - s) / a[row][row];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{PI, TAU};

    /// A 360° scan (n beams) of a circle of radius `r` around the sensor.
    fn ring(n: usize, r: f64) -> Scan2d {
        let step = TAU / n as f64;
        Scan2d::new(0.0, -PI, -PI + step * (n - 1) as f64, 80.0, vec![r; n]).unwrap()
    }

    #[test]
    fn default_parameters_give_the_dissertations_843_numbers() {
        let p = DescriptorParams::default();
        assert_eq!(p.bins(), [400, 160, 80, 54, 40, 27, 20, 16, 14]);
        assert_eq!(p.descriptor_len(), 843);
    }

    #[test]
    fn a_ring_has_known_features() {
        let n = 720;
        let d = describe_scan(&ring(n, 5.0), &DescriptorParams::default()).unwrap();
        let s = &d.scalars;
        let step = TAU / n as f64;
        // Area of the polygon over the area at r_max = 40 m: (5/40)².
        assert!((s[0] - 25.0 / 1600.0).abs() < 1e-12, "{}", s[0]);
        // Perimeter of the open 719-gon: 719 chords of 2·5·sin(step/2).
        let chord = 10.0 * (step / 2.0).sin();
        assert!((s[2] - 719.0 * chord).abs() < 1e-9);
        assert_eq!((s[4], s[5], s[6], s[7]), (5.0, 0.0, 5.0, 0.0));
        assert_eq!((s[8], s[10], s[18], s[21]), (0.0, 0.0, 0.0, 1.0));
        // Curvature of a circle: 1/r.
        assert!((s[16] - 0.2).abs() < 1e-9 && s[17] < 1e-9);
        // The circle fit finds it: radius 5, centred on the sensor.
        assert!((s[27] - 5.0).abs() < 1e-9 && s[28] < 1e-9 && s[29] < 1e-9);
        // Circularity of an (almost closed) circle: ≈ 1.
        assert!((s[30] - 1.0).abs() < 0.01, "{}", s[30]);
        // Every range in one bin: the 1 m histogram has all its mass in bin 5.
        assert_eq!(d.histograms[4][5], 1.0);
    }

    #[test]
    fn no_returns_count_as_open_space_and_gaps() {
        let mut ranges = vec![2.0; 10];
        ranges[4] = f64::INFINITY;
        let scan = Scan2d::new(0.0, -1.0, 1.0, 80.0, ranges).unwrap();
        let d = describe_scan(&scan, &DescriptorParams::default()).unwrap();
        // 9 returns of 10; two gaps of 38 m among 9 neighbour pairs.
        assert!((d.scalars[21] - 0.9).abs() < 1e-15);
        assert!((d.scalars[20] - 2.0 / 9.0).abs() < 1e-15);
        assert!((d.scalars[4] - (9.0 * 2.0 + 40.0) / 10.0).abs() < 1e-12);
        assert_eq!(d.scalars[6], 2.0);
        // The histograms count the 9 returns only.
        assert_eq!(d.histograms[0][20], 1.0);
    }

    #[test]
    fn features_do_not_change_when_a_full_scan_is_rotated() {
        let n = 360;
        let ranges: Vec<f64> = (0..n)
            .map(|k| 3.0 + 2.0 * ((k as f64) * 0.05).sin() + (k % 7) as f64 * 0.1)
            .collect();
        let step = TAU / n as f64;
        let scan =
            |r: Vec<f64>| Scan2d::new(0.0, -PI, -PI + step * (n - 1) as f64, 80.0, r).unwrap();
        let mut rotated = ranges.clone();
        rotated.rotate_left(90);
        let p = DescriptorParams::default();
        let a = describe_scan(&scan(ranges), &p).unwrap();
        let pair = compare(&a, &describe_scan(&scan(rotated), &p).unwrap()).unwrap();
        // Only the wrap-around neighbour pair (1 of 359) differs: scalar differences stay tiny.
        for k in [4, 5, 6, 7, 8, 9, 21, 22, 25, 26, 27] {
            assert!(pair[k] < 1e-9, "feature {k}: {}", pair[k]);
        }
        for k in [0, 2, 10, 16] {
            assert!(pair[k] < 0.05 * a.scalars[k], "feature {k}: {}", pair[k]);
        }
        assert!(
            pair[SCALAR_FEATURES..]
                .iter()
                .all(|&c| (c - 1.0).abs() < 1e-12)
        );
    }

    #[test]
    fn a_cloud_of_a_cylinder_matches_its_ring() {
        // A cylindrical room of radius 5, sampled every 1° at heights -0.5, 0, 0.5 m.
        let mut cloud = Vec::new();
        for k in 0..360 {
            let a = (k as f64 + 0.5).to_radians();
            for z in [-0.5, 0.0, 0.5] {
                cloud.push([5.0 * a.cos(), 5.0 * a.sin(), z]);
            }
        }
        let d = describe_cloud(&cloud, &DescriptorParams::default()).unwrap();
        assert!((d.scalars[27] - 5.0).abs() < 1e-9);
        assert!((d.scalars[21] - 1.0).abs() < 1e-15);
        // Euclidean 3-D ranges: 5 and √25.25.
        let mean = (5.0 + 2.0 * 25.25f64.sqrt()) / 3.0;
        assert!((d.scalars[4] - mean).abs() < 1e-12);
        assert!(describe_cloud(&[[f64::NAN, 0.0, 0.0]], &DescriptorParams::default()).is_err());
    }

    #[test]
    fn comparison_checks_its_inputs() {
        let p = DescriptorParams::default();
        let a = describe_scan(&ring(36, 2.0), &p).unwrap();
        let q = DescriptorParams {
            max_range: 20.0,
            ..p.clone()
        };
        let b = describe_scan(&ring(36, 2.0), &q).unwrap();
        assert!(matches!(compare(&a, &b), Err(DescriptorError::Mismatch(_))));
        let mut bad = a.clone();
        bad.scalars[3] = f64::NAN;
        assert!(compare(&a, &bad).is_err());
        assert_eq!(pearson(&[1.0, 2.0, 3.0], &[2.0, 4.0, 6.0]), 1.0);
        assert_eq!(pearson(&[1.0, 1.0], &[2.0, 4.0]), 0.0);
        let bad = DescriptorParams {
            max_range: 0.0,
            ..p
        };
        assert!(matches!(
            describe_scan(&ring(36, 2.0), &bad),
            Err(DescriptorError::Param {
                field: "max_range",
                ..
            })
        ));
    }
}
