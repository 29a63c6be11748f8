//! ROC curves and the loop threshold `p_min` ([Stüde 2024] §3.2.1): a pair is a loop if its
//! probability exceeds `p_min`, and `p_min` is raised until the false-positive rate is below
//! 1 % ("since adding incorrect loop closures is significantly more fatal … FPR < 1 % is set as
//! the target"), which keeps the largest true-positive rate under that bound.
//!
//! ```
//! use chronomap_lidar::threshold::{auc, roc, threshold_for_fpr};
//!
//! let scores = [0.9, 0.8, 0.7, 0.6, 0.4, 0.3];
//! let labels = [true, true, false, true, false, false];
//! let curve = roc(&scores, &labels)?;
//! assert!((auc(&curve) - 8.0 / 9.0).abs() < 1e-12);
//! // No false positive allowed: p_min between 0.8 and 0.7, two of three loops found.
//! let best = threshold_for_fpr(&curve, 0.01);
//! assert!((best.threshold - 0.75).abs() < 1e-12 && (best.tpr - 2.0 / 3.0).abs() < 1e-12);
//! # Ok::<(), chronomap_lidar::threshold::ThresholdError>(())
//! ```
//!
//! [Stüde 2024]: M. Stüde, dissertation, Hannover 2024.

use serde::{Deserialize, Serialize};

/// Why a ROC curve cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ThresholdError {
    /// Scores and labels differ in number.
    #[error("{scores} scores for {labels} labels")]
    Length {
        /// Number of scores.
        scores: usize,
        /// Number of labels.
        labels: usize,
    },
    /// A score is NaN or infinite.
    #[error("score {0} is not finite")]
    NonFinite(usize),
    /// The labels lack positives or negatives.
    #[error("a ROC curve needs positives and negatives")]
    OneClass,
}

/// One point of a ROC curve: the rates of the rule `score > threshold`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RocPoint {
    /// The threshold (`p_min`).
    pub threshold: f64,
    /// True-positive rate: positives above the threshold over positives.
    pub tpr: f64,
    /// False-positive rate: negatives above the threshold over negatives.
    pub fpr: f64,
}

/// The ROC curve of `scores` for `labels`, from the strictest threshold (the largest score:
/// nothing positive) down: one point between each pair of successive distinct scores (their
/// midpoint) and a last one below the smallest score (minus 1: everything positive).
///
/// # Errors
/// [`ThresholdError`] for different lengths, a non-finite score or a single class.
pub fn roc(scores: &[f64], labels: &[bool]) -> Result<Vec<RocPoint>, ThresholdError> {
    if scores.len() != labels.len() {
        return Err(ThresholdError::Length {
            scores: scores.len(),
            labels: labels.len(),
        });
    }
    if let Some(i) = scores.iter().position(|s| !s.is_finite()) {
        return Err(ThresholdError::NonFinite(i));
    }
    let positives = labels.iter().filter(|&&l| l).count();
    let negatives = labels.len() - positives;
    if positives == 0 || negatives == 0 {
        return Err(ThresholdError::OneClass);
    }
    let mut order: Vec<usize> = (0..scores.len()).collect();
    order.sort_by(|&a, &b| scores[b].total_cmp(&scores[a]));
    let mut points = vec![RocPoint {
        threshold: scores[order[0]],
        tpr: 0.0,
        fpr: 0.0,
    }];
    let (mut tp, mut fp) = (0usize, 0usize);
    let mut k = 0;
    while k < order.len() {
        let s = scores[order[k]];
        while k < order.len() && scores[order[k]] == s {
            if labels[order[k]] {
                tp += 1;
            } else {
                fp += 1;
            }
            k += 1;
        }
        let threshold = if k < order.len() {
            s / 2.0 + scores[order[k]] / 2.0
        } else {
            s - 1.0
        };
        points.push(RocPoint {
            threshold,
            tpr: tp as f64 / positives as f64,
            fpr: fp as f64 / negatives as f64,
        });
    }
    Ok(points)
}

/// Area under a ROC curve of [`roc`] (trapezoids; ties count half).
pub fn auc(curve: &[RocPoint]) -> f64 {
    curve
        .windows(2)
        .map(|w| (w[1].fpr - w[0].fpr) * (w[1].tpr + w[0].tpr) / 2.0)
        .sum()
}

/// The point of `curve` with the largest TPR whose FPR stays below `max_fpr` (strictly): the
/// lowest such threshold, found by raising `p_min` as [Stüde 2024] §3.2.1 does. The first
/// point (nothing positive, FPR 0) qualifies when nothing else does.
pub fn threshold_for_fpr(curve: &[RocPoint], max_fpr: f64) -> RocPoint {
    curve
        .iter()
        .take_while(|p| p.fpr < max_fpr)
        .last()
        .copied()
        .unwrap_or(RocPoint {
            threshold: f64::INFINITY,
            tpr: 0.0,
            fpr: 0.0,
        })
}

/// The true- and false-positive rates of the rule `score > threshold` (NaN for a class that
/// has no member).
pub fn rates_at(scores: &[f64], labels: &[bool], threshold: f64) -> (f64, f64) {
    let (mut tp, mut p, mut fp, mut n) = (0usize, 0usize, 0usize, 0usize);
    for (&s, &l) in scores.iter().zip(labels) {
        if l {
            p += 1;
            tp += usize::from(s > threshold);
        } else {
            n += 1;
            fp += usize::from(s > threshold);
        }
    }
    (tp as f64 / p as f64, fp as f64 / n as f64)
}

/// Mean and sample standard deviation of some values.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeanSd {
    /// The mean (NaN for no values).
    pub mean: f64,
    /// The sample standard deviation (`n − 1`; 0 for one value, NaN for none).
    pub sd: f64,
    /// The number of values.
    pub n: usize,
}

impl MeanSd {
    /// Of the finite values of `values`.
    pub fn of(values: impl IntoIterator<Item = f64>) -> MeanSd {
        let v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
        let n = v.len();
        if n == 0 {
            return MeanSd {
                mean: f64::NAN,
                sd: f64::NAN,
                n,
            };
        }
        let mean = v.iter().sum::<f64>() / n as f64;
        let sd = if n > 1 {
            (v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1) as f64).sqrt()
        } else {
            0.0
        };
        MeanSd { mean, sd, n }
    }
}

impl std::fmt::Display for MeanSd {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p = f.precision().unwrap_or(3);
        write!(f, "{:.p$} ± {:.p$}", self.mean, self.sd)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roc_of_tied_scores_steps_diagonally() {
        let curve = roc(&[0.5, 0.5, 0.5, 0.5], &[true, false, true, false]).unwrap();
        assert_eq!(curve.len(), 2);
        assert_eq!((curve[1].tpr, curve[1].fpr), (1.0, 1.0));
        assert_eq!(auc(&curve), 0.5);
    }

    #[test]
    fn perfect_scores_have_auc_one_and_full_tpr_at_zero_fpr() {
        let curve = roc(&[0.1, 0.9, 0.8, 0.2], &[false, true, true, false]).unwrap();
        assert_eq!(auc(&curve), 1.0);
        let p = threshold_for_fpr(&curve, 0.01);
        assert_eq!((p.tpr, p.fpr, p.threshold), (1.0, 0.0, 0.5));
        assert_eq!(
            rates_at(&[0.1, 0.9, 0.8, 0.2], &[false, true, true, false], 0.5),
            (1.0, 0.0)
        );
    }

    #[test]
    fn bad_input_is_refused() {
        assert_eq!(
            roc(&[1.0], &[true, false]),
            Err(ThresholdError::Length {
                scores: 1,
                labels: 2
            })
        );
        assert_eq!(
            roc(&[1.0, f64::NAN], &[true, false]),
            Err(ThresholdError::NonFinite(1))
        );
        assert_eq!(
            roc(&[1.0, 2.0], &[true, true]),
            Err(ThresholdError::OneClass)
        );
    }

    #[test]
    fn mean_and_sample_sd() {
        let m = MeanSd::of([1.0, 2.0, 3.0, f64::NAN]);
        assert_eq!((m.mean, m.sd, m.n), (2.0, 1.0, 3));
        assert_eq!(format!("{m:.1}"), "2.0 ± 1.0");
    }
}
