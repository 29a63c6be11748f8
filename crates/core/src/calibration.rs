//! Calibration of predicted probabilities: does a predicted 0.8 come true 80 % of the time?
//!
//! The Brier score ([`crate::metrics::mse`]) mixes two things a user of a probability cares
//! about: whether it is *calibrated* (of the minutes predicted at 0.3, about 30 % had the door
//! open) and whether it *resolves* (it tells busy minutes from quiet ones). Murphy (1973)
//! split the score of forecasts that take a few distinct values into
//!
//! ```text
//!     BS = REL − RES + UNC
//!     REL = Σ_k (n_k/N) (p̄_k − ō_k)²     reliability: distance from the diagonal (lower is better)
//!     RES = Σ_k (n_k/N) (ō_k − ō)²       resolution: how far the bins' outcomes spread (higher is better)
//!     UNC = (1/N) Σ_j (s_j − ō)²         uncertainty: the outcomes' variance, ō(1 − ō) when binary
//! ```
//!
//! over bins `k` of the forecasts, with `n_k` forecasts of mean `p̄_k` whose outcomes have mean
//! `ō_k`. Forecasts that vary inside a bin add a within-bin term (Stephenson, Coelho & Jolliffe
//! 2008): `BS = REL − RES + UNC + WB`, `WB = Σ_k (n_k/N) (var_k(p) − 2 cov_k(p, s))`, which
//! [`Calibration`] reports too, so the four numbers add up to the Brier score exactly.
//!
//! The *expected calibration error* is the bins' weighted distance from the diagonal,
//! `ECE = Σ_k (n_k/N) |p̄_k − ō_k|` (Naeini, Cooper & Hauskrecht 2015), over equal-width bins
//! whose edges are those of scikit-learn's `calibration_curve(strategy="uniform")`, the oracle
//! of the tests: a forecast on an edge belongs to the bin below it (bins are `(a, b]`, the
//! first `[0, b]`).
//!
//! ```
//! use chronomap_core::calibration::Calibration;
//!
//! // Forecasts of 0.2 that came true once in four times, and of 0.9 that came true 3 of 4.
//! let p = [0.2, 0.2, 0.2, 0.2, 0.9, 0.9, 0.9, 0.9];
//! let s = [1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0];
//! let c = Calibration::of(&p, &s, 10);
//! assert!((c.ece - (0.5 * 0.05 + 0.5 * 0.15)).abs() < 1e-12);
//! assert!((c.reliability - c.resolution + c.uncertainty + c.within_bin - c.brier).abs() < 1e-12);
//! assert_eq!(c.bins.len(), 2); // only the bins that hold forecasts
//! ```
//!
//! Intervals are scored by [`Coverage`]: how often they held the value, and how wide they were.
//!
//! - A. H. Murphy, "A new vector partition of the probability score", J. Appl. Meteor. 12, 1973.
//! - D. B. Stephenson, C. A. S. Coelho, I. T. Jolliffe, "Two extra components in the Brier score
//!   decomposition", Weather and Forecasting 23, 2008.
//! - M. P. Naeini, G. F. Cooper, M. Hauskrecht, "Obtaining well calibrated probabilities using
//!   Bayesian binning", AAAI 2015.

use serde::{Deserialize, Serialize};

/// Equal-width bins of the reliability diagram and the ECE unless a caller asks for others (10,
/// the usual choice of the calibration literature).
pub const DEFAULT_BINS: usize = 10;

/// One bin of a reliability diagram: forecasts in `(lower, upper]` (the first bin includes 0).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReliabilityBin {
    /// Lower edge.
    pub lower: f64,
    /// Upper edge.
    pub upper: f64,
    /// Forecasts in the bin.
    pub count: usize,
    /// Mean forecast `p̄_k` (the diagram's x).
    pub mean_prediction: f64,
    /// Mean outcome `ō_k`, the observed frequency (the diagram's y).
    pub observed_frequency: f64,
}

/// How well a set of probability forecasts is calibrated, with the Brier score's decomposition
/// (see the [module docs](self)).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// The bins that hold at least one forecast, in increasing order.
    pub bins: Vec<ReliabilityBin>,
    /// Number of equal-width bins the forecasts were sorted into.
    pub bin_count: usize,
    /// Forecast–outcome pairs scored.
    pub samples: usize,
    /// Pairs left out because the forecast or the outcome was not finite.
    pub skipped: usize,
    /// Brier score `mean((p − s)²)`.
    pub brier: f64,
    /// Expected calibration error `Σ (n_k/N) |p̄_k − ō_k|`.
    pub ece: f64,
    /// Reliability `Σ (n_k/N) (p̄_k − ō_k)²` (0 for a calibrated forecast).
    pub reliability: f64,
    /// Resolution `Σ (n_k/N) (ō_k − ō)²`.
    pub resolution: f64,
    /// Uncertainty: the variance of the outcomes, `ō(1 − ō)` when they are binary.
    pub uncertainty: f64,
    /// Within-bin term `Σ (n_k/N) (var_k(p) − 2 cov_k(p, s))`, so that
    /// `brier = reliability − resolution + uncertainty + within_bin`.
    pub within_bin: f64,
    /// Mean forecast.
    pub mean_prediction: f64,
    /// Mean outcome `ō` (the base rate).
    pub base_rate: f64,
}

impl Calibration {
    /// Sorts the forecasts into `bins` equal-width bins over `[0, 1]` and measures their
    /// calibration against the outcomes (each in `[0, 1]`; fractions are allowed, as for a grid
    /// cell seen partly occupied). Forecasts below 0 count in the first bin and above 1 in the
    /// last; pairs with a non-finite forecast or outcome are skipped and counted. With no pairs
    /// every score is 0.
    ///
    /// # Panics
    /// If the slices differ in length or `bins` is 0.
    pub fn of(predictions: &[f64], observations: &[f64], bins: usize) -> Calibration {
        assert_eq!(predictions.len(), observations.len());
        assert!(bins > 0, "at least one bin");
        let pairs = || {
            predictions
                .iter()
                .zip(observations)
                .filter(|(p, s)| p.is_finite() && s.is_finite())
                .map(|(&p, &s)| (p, s))
        };
        // The edges as numpy's `linspace(0, 1, bins + 1)` computes them (`i · (1 / bins)`), and
        // the bin as `searchsorted(edges[1:-1], p)` finds it: the number of inner edges below
        // `p`. A forecast on an edge falls where scikit-learn puts it.
        let step = 1.0 / bins as f64;
        let bin_of = |p: f64| (1..bins).take_while(|&i| (i as f64 * step) < p).count();
        let mut count = vec![0usize; bins];
        let mut sum_p = vec![0.0; bins];
        let mut sum_s = vec![0.0; bins];
        let mut samples = 0usize;
        for (p, s) in pairs() {
            let k = bin_of(p);
            count[k] += 1;
            sum_p[k] += p;
            sum_s[k] += s;
            samples += 1;
        }
        let skipped = predictions.len() - samples;
        let empty = Calibration {
            bins: Vec::new(),
            bin_count: bins,
            samples: 0,
            skipped,
            brier: 0.0,
            ece: 0.0,
            reliability: 0.0,
            resolution: 0.0,
            uncertainty: 0.0,
            within_bin: 0.0,
            mean_prediction: 0.0,
            base_rate: 0.0,
        };
        if samples == 0 {
            return empty;
        }
        let n = samples as f64;
        let mean_p: Vec<f64> = (0..bins)
            .map(|k| sum_p[k] / count[k].max(1) as f64)
            .collect();
        let mean_s: Vec<f64> = (0..bins)
            .map(|k| sum_s[k] / count[k].max(1) as f64)
            .collect();
        let base_rate = sum_s.iter().sum::<f64>() / n;
        // Second pass, centred in each bin: the variance and covariance terms without the
        // cancellation of raw sums of squares.
        let (mut brier, mut uncertainty, mut within_bin) = (0.0, 0.0, 0.0);
        for (p, s) in pairs() {
            let k = bin_of(p);
            let (dp, ds) = (p - mean_p[k], s - mean_s[k]);
            brier += (p - s) * (p - s);
            uncertainty += (s - base_rate) * (s - base_rate);
            within_bin += dp * dp - 2.0 * dp * ds;
        }
        let mut c = Calibration {
            samples,
            brier: brier / n,
            uncertainty: uncertainty / n,
            within_bin: within_bin / n,
            mean_prediction: sum_p.iter().sum::<f64>() / n,
            base_rate,
            ..empty
        };
        for k in (0..bins).filter(|&k| count[k] > 0) {
            let weight = count[k] as f64 / n;
            let gap = mean_p[k] - mean_s[k];
            c.ece += weight * gap.abs();
            c.reliability += weight * gap * gap;
            c.resolution += weight * (mean_s[k] - base_rate) * (mean_s[k] - base_rate);
            c.bins.push(ReliabilityBin {
                lower: k as f64 * step,
                upper: if k + 1 == bins {
                    1.0
                } else {
                    (k + 1) as f64 * step
                },
                count: count[k],
                mean_prediction: mean_p[k],
                observed_frequency: mean_s[k],
            });
        }
        c
    }
}

/// The nominal coverages at which calibration curves of intervals are drawn (`chronomap
/// activity eval --plot`, `chronomap topo eval --plot`): the share of values inside the
/// intervals of each coverage against the coverage itself.
pub const CURVE_LEVELS: [f64; 11] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99];

/// How prediction intervals held up against what happened: the share of values inside their
/// interval (its *empirical coverage*, to compare with the nominal level) and the intervals'
/// mean width — an interval is only as useful as it is narrow at its coverage.
///
/// ```
/// use chronomap_core::calibration::Coverage;
///
/// let intervals = [(10.0, 20.0), (10.0, 20.0), (0.0, 4.0), (5.0, 5.0)];
/// let values = [15.0, 21.0, 4.0, 5.0]; // ends belong to the interval
/// let c = Coverage::of(&intervals, &values);
/// assert_eq!((c.covered, c.samples), (3, 4));
/// assert_eq!(c.coverage, 0.75);
/// assert_eq!(c.mean_width, (10.0 + 10.0 + 4.0 + 0.0) / 4.0);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Coverage {
    /// Values scored.
    pub samples: usize,
    /// Values inside their interval (ends included).
    pub covered: usize,
    /// `covered / samples` (0 when there are none).
    pub coverage: f64,
    /// Mean `upper − lower`.
    pub mean_width: f64,
    /// Values below their interval.
    pub below: usize,
    /// Values above their interval.
    pub above: usize,
}

impl Coverage {
    /// Scores `intervals[i] = (lower, upper)` against `values[i]`; pairs with a non-finite
    /// value or bound are left out.
    ///
    /// # Panics
    /// If the slices differ in length.
    pub fn of(intervals: &[(f64, f64)], values: &[f64]) -> Coverage {
        assert_eq!(intervals.len(), values.len());
        let mut c = Coverage::default();
        let mut width = 0.0;
        for (&(lower, upper), &v) in intervals.iter().zip(values) {
            if !(lower.is_finite() && upper.is_finite() && v.is_finite()) {
                continue;
            }
            c.samples += 1;
            width += upper - lower;
            if v < lower {
                c.below += 1;
            } else if v > upper {
                c.above += 1;
            } else {
                c.covered += 1;
            }
        }
        if c.samples > 0 {
            c.coverage = c.covered as f64 / c.samples as f64;
            c.mean_width = width / c.samples as f64;
        }
        c
    }

    /// Whether the coverage is the `nominal` one up to sampling error: within `z` binomial
    /// standard errors `sqrt(nominal (1 − nominal) / n)` (the conformance checks use `z = 4`,
    /// so that a correct interval fails about once in 16,000 runs).
    pub fn agrees_with(&self, nominal: f64, z: f64) -> bool {
        let n = self.samples as f64;
        self.samples > 0
            && (self.coverage - nominal).abs() <= z * (nominal * (1.0 - nominal) / n).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::mse;
    use crate::rng::Xoshiro256StarStar as Rng;

    /// The decomposition by hand: two bins of constant forecasts, so WB = 0 (Murphy 1973).
    #[test]
    fn murphy_decomposition_of_discrete_forecasts() {
        // 0.1 ×4 with 1 success; 0.7 ×6 with 3 successes. ō = 4/10.
        let p = [0.1, 0.1, 0.1, 0.1, 0.7, 0.7, 0.7, 0.7, 0.7, 0.7];
        let s = [1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0];
        let c = Calibration::of(&p, &s, 10);
        let rel = 0.4 * (0.1f64 - 0.25).powi(2) + 0.6 * (0.7f64 - 0.5).powi(2);
        let res = 0.4 * (0.25f64 - 0.4).powi(2) + 0.6 * (0.5f64 - 0.4).powi(2);
        assert!((c.reliability - rel).abs() < 1e-15, "{}", c.reliability);
        assert!((c.resolution - res).abs() < 1e-15);
        assert!((c.uncertainty - 0.24).abs() < 1e-15);
        assert!(c.within_bin.abs() < 1e-15);
        assert!((c.brier - (rel - res + 0.24)).abs() < 1e-15);
        assert!((c.brier - mse(&p, &s)).abs() < 1e-15);
        assert!((c.ece - (0.4 * 0.15 + 0.6 * 0.2)).abs() < 1e-15);
        assert_eq!(c.base_rate, 0.4);
        // 0.1 sits on the edge between bins 0 and 1: it belongs to the bin below. The edge
        // numpy computes for 0.7 is 7 · 0.1 = 0.7000000000000001, so 0.7 is below it too.
        assert_eq!(c.bins[0].lower, 0.0);
        assert_eq!(c.bins[1].lower, 0.6000000000000001);
    }

    /// With forecasts that vary inside bins the four terms still add up to the Brier score.
    #[test]
    fn decomposition_adds_up_for_continuous_forecasts() {
        let mut rng = Rng::seed_from_u64(7);
        let p: Vec<f64> = (0..5000).map(|_| rng.next_f64()).collect();
        let s: Vec<f64> = p
            .iter()
            .map(|&q| f64::from(u8::from(rng.next_f64() < q * q)))
            .collect();
        for bins in [1, 3, 10, 50] {
            let c = Calibration::of(&p, &s, bins);
            let sum = c.reliability - c.resolution + c.uncertainty + c.within_bin;
            assert!(
                (sum - c.brier).abs() < 1e-12,
                "{bins}: {sum} vs {}",
                c.brier
            );
            assert!((c.brier - mse(&p, &s)).abs() < 1e-12);
            assert_eq!(c.bins.iter().map(|b| b.count).sum::<usize>(), 5000);
        }
        // Outcomes drawn with probability p² from a forecast p: over-confident at every p,
        // by ∫(p − p²)dp = 1/6 on average.
        let c = Calibration::of(&p, &s, 10);
        assert!((c.ece - 1.0 / 6.0).abs() < 0.02, "{}", c.ece);
    }

    #[test]
    fn calibrated_forecasts_have_small_error_and_one_bin_has_none_to_resolve() {
        let mut rng = Rng::seed_from_u64(3);
        let p: Vec<f64> = (0..20_000).map(|_| rng.next_f64()).collect();
        let s: Vec<f64> = p
            .iter()
            .map(|&q| f64::from(u8::from(rng.next_f64() < q)))
            .collect();
        let c = Calibration::of(&p, &s, 10);
        assert!(c.ece < 0.015, "{}", c.ece);
        assert!(c.reliability < 5e-4);
        let one = Calibration::of(&p, &s, 1);
        assert_eq!(one.resolution, 0.0);
        assert!((one.ece - (one.mean_prediction - one.base_rate).abs()).abs() < 1e-15);
    }

    #[test]
    fn edges_out_of_range_and_non_finite_values() {
        let p = [-0.5, 0.0, 1.0, 1.5, f64::NAN, 0.5];
        let s = [0.0, 0.0, 1.0, 1.0, 1.0, f64::INFINITY];
        let c = Calibration::of(&p, &s, 4);
        assert_eq!(c.samples, 4);
        assert_eq!(c.skipped, 2);
        let counts: Vec<(f64, usize)> = c.bins.iter().map(|b| (b.lower, b.count)).collect();
        assert_eq!(counts, [(0.0, 2), (0.75, 2)]);
        assert_eq!(c.bins[1].upper, 1.0);
        let none = Calibration::of(&[], &[], 10);
        assert_eq!((none.samples, none.ece, none.brier), (0, 0.0, 0.0));
    }
}
