//! Scores of predictions against observations, and the paired t-test used to say which
//! differences between models are significant.

use statrs::distribution::{ContinuousCDF, StudentsT};

use crate::model::TemporalModel;

/// Mean squared error of probabilities, the Brier score: `mean((p − s)²)`.
///
/// For a state that is 1 only ~12 % of the time (the greg door), `p(t)` rarely crosses 0.5
/// and the binary error barely moves between models; the Brier score is the informative one.
///
/// # Panics
/// If the slices differ in length.
pub fn mse(predictions: &[f64], observations: &[f64]) -> f64 {
    mean_of(predictions, observations, |p, s| (p - s) * (p - s))
}

/// Mean of `loss(p, s)` over aligned predictions and observations (0 when empty).
fn mean_of(predictions: &[f64], observations: &[f64], loss: impl Fn(f64, f64) -> f64) -> f64 {
    assert_eq!(predictions.len(), observations.len());
    if predictions.is_empty() {
        return 0.0;
    }
    let total: f64 = predictions
        .iter()
        .zip(observations)
        .map(|(&p, &s)| loss(p, s))
        .sum();
    total / predictions.len() as f64
}

/// Binary error `mean(((p > 0.5) − s)²)`: the fraction of wrongly predicted binary states
/// (as computed by the original benchmark scripts).
///
/// # Panics
/// If the slices differ in length.
pub fn binary_error(predictions: &[f64], observations: &[f64]) -> f64 {
    mean_of(predictions, observations, |p, s| {
        let d = f64::from(u8::from(p > 0.5)) - s;
        d * d
    })
}

/// Mean absolute error `mean(|p − s|)` (the reconstruction criterion of [Fentanes 2015] eq. (3)).
///
/// # Panics
/// If the slices differ in length.
pub fn mean_absolute_error(predictions: &[f64], observations: &[f64]) -> f64 {
    mean_of(predictions, observations, |p, s| (p - s).abs())
}

/// Scores of one model on one test set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TestScore {
    /// Brier score ([`mse`]).
    pub mse: f64,
    /// Binary error ([`binary_error`]).
    pub binary_error: f64,
    /// Number of test samples.
    pub samples: usize,
}

/// Predicts every test time with `model` and scores the predictions.
///
/// # Panics
/// If `times` and `observations` differ in length.
pub fn score<M: TemporalModel + ?Sized>(
    model: &M,
    times: &[f64],
    observations: &[f64],
) -> TestScore {
    let predictions = model.predict_many(times);
    TestScore {
        mse: mse(&predictions, observations),
        binary_error: binary_error(&predictions, observations),
        samples: times.len(),
    }
}

/// Result of a two-sided paired t-test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairedTTest {
    /// Mean of the differences `a_i − b_i`.
    pub mean_difference: f64,
    /// The t statistic.
    pub t: f64,
    /// Degrees of freedom (`n − 1`).
    pub degrees_of_freedom: usize,
    /// Two-sided p-value.
    pub p_value: f64,
}

/// Two-sided paired t-test of `H0: mean(a − b) = 0` (e.g. the errors of two models on the
/// same test sets). `None` for fewer than two pairs.
///
/// When all differences are equal the variance is zero: the p-value is then 0 if they are
/// non-zero (a consistent difference) and 1 otherwise.
///
/// # Panics
/// If the slices differ in length.
pub fn paired_t_test(a: &[f64], b: &[f64]) -> Option<PairedTTest> {
    assert_eq!(a.len(), b.len());
    let n = a.len();
    if n < 2 {
        return None;
    }
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    let mean = d.iter().sum::<f64>() / n as f64;
    let var = d.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1) as f64;
    let df = n - 1;
    if var <= f64::EPSILON * mean.abs().max(f64::MIN_POSITIVE) {
        let p_value = if mean == 0.0 { 1.0 } else { 0.0 };
        let t = if mean == 0.0 {
            0.0
        } else {
            f64::INFINITY.copysign(mean)
        };
        return Some(PairedTTest {
            mean_difference: mean,
            t,
            degrees_of_freedom: df,
            p_value,
        });
    }
    let t = mean / (var / n as f64).sqrt();
    let dist = StudentsT::new(0.0, 1.0, df as f64).expect("df >= 1 is valid");
    let p_value = (2.0 * (1.0 - dist.cdf(t.abs()))).clamp(0.0, 1.0);
    Some(PairedTTest {
        mean_difference: mean,
        t,
        degrees_of_freedom: df,
        p_value,
    })
}

/// The compression ratio of eq. (16) of [Krajník 2017] (FreMEn, §IV-C): `r = m·n / z` for `m`
/// observations of `n` binary states stored in a file of `z` bits (`bytes` bytes). A grid
/// of `c` cells observed in `f` frames is `m·n = c·f` cell observations.
///
/// ```
/// // 604,800 one-second samples of a door in a 756-byte file: 1:100.
/// assert_eq!(chronomap_core::metrics::compression_ratio(604_800.0, 756), 100.0);
/// ```
pub fn compression_ratio(observations: f64, bytes: usize) -> f64 {
    observations / (8.0 * bytes as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scores_of_known_predictions() {
        let p = [0.2, 0.8, 0.5, 0.9];
        let s = [0.0, 1.0, 1.0, 0.0];
        assert!((mse(&p, &s) - (0.04 + 0.04 + 0.25 + 0.81) / 4.0).abs() < 1e-15);
        // p > 0.5: [0, 1, 0, 1] vs [0, 1, 1, 0] → 2 wrong of 4.
        assert_eq!(binary_error(&p, &s), 0.5);
        assert!((mean_absolute_error(&p, &s) - (0.2 + 0.2 + 0.5 + 0.9) / 4.0).abs() < 1e-15);
    }

    #[test]
    fn paired_t_test_known_answer() {
        // d = [1, 2, 3, 4, 5] - [1, 1, 1, 1, 1] = [0, 1, 2, 3, 4]: mean 2, sd sqrt(2.5),
        // t = 2 / (sqrt(2.5)/sqrt(5)) = 2.828427..., df 4, two-sided p = 0.04742...
        // (scipy.stats.ttest_rel gives statistic 2.8284271247, pvalue 0.0474207).
        let r = paired_t_test(&[1.0, 2.0, 3.0, 4.0, 5.0], &[1.0; 5]).unwrap();
        assert!((r.t - 2.828_427_124_746_19).abs() < 1e-12);
        assert_eq!(r.degrees_of_freedom, 4);
        assert!((r.p_value - 0.047_420_7).abs() < 1e-6, "{}", r.p_value);
        assert!(paired_t_test(&[1.0], &[2.0]).is_none());
        assert_eq!(
            paired_t_test(&[1.0, 2.0], &[1.0, 2.0]).unwrap().p_value,
            1.0
        );
        assert_eq!(
            paired_t_test(&[2.0, 3.0], &[1.0, 2.0]).unwrap().p_value,
            0.0
        );
    }
}
