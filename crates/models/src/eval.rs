//! Evaluation of models on test sets: the experiment of the FreMEn benchmarks, as a pure
//! function (the command line prints it).

use crate::spec::{FitOptions, Fitted, ModelSpec};
use chronomap_core::calendar::DaysOff;
use chronomap_core::calibration::{Calibration, DEFAULT_BINS};
use chronomap_core::error::BuildError;
use chronomap_core::metrics::{PairedTTest, TestScore, binary_error, mse, paired_t_test};

/// One test set: times and observed values.
#[derive(Clone, Copy, Debug)]
pub struct TestSet<'a> {
    /// Times of the test observations.
    pub times: &'a [f64],
    /// Observed values.
    pub values: &'a [f64],
}

impl<'a> From<&'a chronomap_core::TimeSeries> for TestSet<'a> {
    /// The series as a test set.
    fn from(series: &'a chronomap_core::TimeSeries) -> Self {
        TestSet {
            times: &series.times,
            values: &series.values,
        }
    }
}

/// A model fitted on the training data and scored on every test set.
#[derive(Clone, Debug)]
pub struct ModelEvaluation {
    /// The spec as requested.
    pub spec: ModelSpec,
    /// The fitted model and how it was chosen.
    pub fitted: Fitted,
    /// Scores per test set, in the order given.
    pub tests: Vec<TestScore>,
    /// Calibration per test set ([`DEFAULT_BINS`] equal-width bins), in the order given.
    pub calibration: Vec<Calibration>,
    /// Calibration of the predictions of all test sets together.
    pub pooled_calibration: Calibration,
}

impl ModelEvaluation {
    /// Mean Brier score over the test sets.
    pub fn mean_mse(&self) -> f64 {
        mean(self.tests.iter().map(|t| t.mse))
    }

    /// Mean binary error over the test sets.
    pub fn mean_binary_error(&self) -> f64 {
        mean(self.tests.iter().map(|t| t.binary_error))
    }

    /// Mean expected calibration error over the test sets.
    pub fn mean_ece(&self) -> f64 {
        mean(self.calibration.iter().map(|c| c.ece))
    }

    /// Brier scores per test set.
    pub fn mses(&self) -> Vec<f64> {
        self.tests.iter().map(|t| t.mse).collect()
    }
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { f64::NAN } else { sum / n as f64 }
}

/// A paired comparison of two models over the test sets.
#[derive(Clone, Copy, Debug)]
pub struct Comparison {
    /// Index of the model with the lower mean Brier score.
    pub better: usize,
    /// Index of the other model.
    pub worse: usize,
    /// Paired t-test of their per-test Brier scores (`better − worse`).
    pub test: PairedTTest,
}

/// Result of [`evaluate`].
#[derive(Clone, Debug)]
pub struct EvalReport {
    /// One entry per requested model, in the order requested.
    pub models: Vec<ModelEvaluation>,
    /// Every pair of models compared by a paired t-test over the test sets (empty with fewer
    /// than two test sets).
    pub comparisons: Vec<Comparison>,
}

impl EvalReport {
    /// Comparisons significant at level `alpha`.
    pub fn significant(&self, alpha: f64) -> impl Iterator<Item = &Comparison> {
        self.comparisons
            .iter()
            .filter(move |c| c.test.p_value < alpha)
    }
}

/// Fits every spec on the training data and scores it on every test set; compares every pair
/// of models by a paired t-test over the test sets' Brier scores.
///
/// `on_fitted` is called after each model is evaluated (for progress reporting).
///
/// # Errors
/// The first model that cannot be fitted, with its spec.
pub fn evaluate(
    specs: &[ModelSpec],
    train_times: &[f64],
    train_values: &[f64],
    tests: &[TestSet<'_>],
    options: &FitOptions,
    on_fitted: impl FnMut(&ModelEvaluation),
) -> Result<EvalReport, (ModelSpec, BuildError)> {
    evaluate_on_calendar(
        specs,
        train_times,
        train_values,
        tests,
        options,
        &DaysOff::default(),
        on_fitted,
    )
}

/// [`evaluate`] with a calendar of days off ([`chronomap_core::calendar`]): training
/// observations on days off are left out, and test times on days off are predicted by their
/// stand-ins (the Sunday before). With no days off this is [`evaluate`].
///
/// # Errors
/// The first model that cannot be fitted, with its spec.
pub fn evaluate_on_calendar(
    specs: &[ModelSpec],
    train_times: &[f64],
    train_values: &[f64],
    tests: &[TestSet<'_>],
    options: &FitOptions,
    days_off: &DaysOff,
    mut on_fitted: impl FnMut(&ModelEvaluation),
) -> Result<EvalReport, (ModelSpec, BuildError)> {
    // Training observations on days off are left out (a copy only when there are days off).
    let (train_times, train_values) = days_off.working_days(train_times, train_values);
    let mut models = Vec::with_capacity(specs.len());
    for spec in specs {
        let fitted = spec
            .fit(&train_times, &train_values, options)
            .map_err(|e| (spec.clone(), e))?;
        let (mut scores, mut calibration) = (Vec::new(), Vec::new());
        let (mut all_predictions, mut all_values) = (Vec::new(), Vec::new());
        for test in tests {
            let predictions = days_off.predict_many(&fitted.model, test.times);
            scores.push(TestScore {
                mse: mse(&predictions, test.values),
                binary_error: binary_error(&predictions, test.values),
                samples: test.times.len(),
            });
            calibration.push(Calibration::of(&predictions, test.values, DEFAULT_BINS));
            all_predictions.extend(predictions);
            all_values.extend_from_slice(test.values);
        }
        let evaluation = ModelEvaluation {
            spec: spec.clone(),
            fitted,
            tests: scores,
            calibration,
            pooled_calibration: Calibration::of(&all_predictions, &all_values, DEFAULT_BINS),
        };
        on_fitted(&evaluation);
        models.push(evaluation);
    }
    let mut comparisons = Vec::new();
    for i in 0..models.len() {
        for j in i + 1..models.len() {
            let (better, worse) = if models[i].mean_mse() <= models[j].mean_mse() {
                (i, j)
            } else {
                (j, i)
            };
            let (a, b) = (models[better].mses(), models[worse].mses());
            // Scores equal up to rounding (e.g. two models that both predict the training
            // mean): no difference to test, whatever the rounding noise's variance.
            let scale = a.iter().chain(&b).fold(0.0f64, |m, x| m.max(x.abs()));
            let equal = a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= 1e-9 * scale);
            if let Some(mut test) = paired_t_test(&a, &b) {
                if equal {
                    test.t = 0.0;
                    test.p_value = 1.0;
                }
                comparisons.push(Comparison {
                    better,
                    worse,
                    test,
                });
            }
        }
    }
    Ok(EvalReport {
        models,
        comparisons,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::parse_model_list;

    /// Two models with the same predictions are never "significantly" different, even when
    /// rounding makes their scores differ in the last bits.
    #[test]
    fn equal_scores_are_not_significant() {
        let times: Vec<f64> = (0..200).map(|i| 600.0 * f64::from(i)).collect();
        // Continuous values without a rhythm: hypertime keeps no periodicity and predicts the
        // mean through its mixture's moments, equal to the mean up to rounding.
        let values: Vec<f64> = (0..200)
            .map(|i| 0.3 + 0.4 * f64::from(u8::from(i % 7 == 0)))
            .collect();
        let test_times: Vec<Vec<f64>> = (0..3)
            .map(|k| {
                (0..50)
                    .map(|i| 200_000.0 + 1e5 * f64::from(k) + 600.0 * f64::from(i))
                    .collect()
            })
            .collect();
        let test_values: Vec<Vec<f64>> = (0..3)
            .map(|k| {
                (0..50)
                    .map(|i| f64::from(u8::from((i + k) % 5 == 0)))
                    .collect()
            })
            .collect();
        let tests: Vec<TestSet<'_>> = test_times
            .iter()
            .zip(&test_values)
            .map(|(t, v)| TestSet {
                times: t,
                values: v,
            })
            .collect();
        let report = evaluate(
            &parse_model_list("mean,hyt-km").unwrap(),
            &times,
            &values,
            &tests,
            &FitOptions::default(),
            |_| {},
        )
        .unwrap();
        assert_eq!(report.comparisons.len(), 1);
        assert_eq!(report.comparisons[0].test.p_value, 1.0);
        assert_eq!(report.significant(0.05).count(), 0);
    }
}
