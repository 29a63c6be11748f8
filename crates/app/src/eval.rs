//! The benchmark experiment of the FreMEn papers ([Krajník 2017] §VI, [Santos 2017] §7) on any
//! data: models fitted on a training series and scored on later test sets (MSE or Brier
//! score and binary error of each), compared by paired t-tests; the test sets from files or
//! one series split at times.
//!
//! Files in, result structs out: the faces print the tables and map errors to their flags.

use chronomap_core::progress::Progress;
use chronomap_core::{BuildError, TimeSeries};
use chronomap_models::eval::{EvalReport, TestSet, evaluate};
use chronomap_models::spec::{FitOptions, ModelSpec};
use chronomap_models::split::{SplitError, chronological_split};

/// One series split at increasing times `at` ([`chronological_split`]): the observations
/// before the first time, and the test set from each time to the next (the last: to the end).
///
/// # Errors
/// [`SplitError`]: times that do not increase, or a part without observations.
pub fn split_series(
    all: &TimeSeries,
    at: &[f64],
) -> Result<(TimeSeries, Vec<TimeSeries>), SplitError> {
    let split = chronological_split(&all.times, at)?;
    let part = |range: std::ops::Range<usize>| TimeSeries {
        times: all.times[range.clone()].to_vec(),
        values: all.values[range].to_vec(),
    };
    let tests = split.tests.into_iter().map(part).collect();
    Ok((part(split.train), tests))
}

/// A model that cannot be fitted to the training series.
#[derive(Debug, thiserror::Error)]
#[error(
    "model {spec}: {}{error}",
    error.observation_index().map(|i| format!("training observation {}: ", i + 1)).unwrap_or_default()
)]
pub struct FitError {
    /// The model.
    pub spec: ModelSpec,
    /// Why.
    pub error: BuildError,
}

/// Fits every model of `specs` on `train` with `options` and scores it on every test set,
/// reporting the stage `fitting models` with one step per model to `progress`.
///
/// # Errors
/// [`FitError`] for the first model that cannot be fitted.
pub fn evaluate_models(
    specs: &[ModelSpec],
    train: &TimeSeries,
    tests: &[TimeSeries],
    options: &FitOptions,
    progress: &dyn Progress,
) -> Result<EvalReport, FitError> {
    let sets: Vec<TestSet<'_>> = tests.iter().map(TestSet::from).collect();
    progress.stage("fitting models", specs.len() as u64);
    evaluate(specs, &train.times, &train.values, &sets, options, |_| {
        progress.advance(1)
    })
    .map_err(|(spec, error)| FitError { spec, error })
}

#[cfg(test)]
mod tests {
    use chronomap_core::progress::NoProgress;

    use super::*;

    fn series(times: &[f64], values: &[f64]) -> TimeSeries {
        TimeSeries {
            times: times.to_vec(),
            values: values.to_vec(),
        }
    }

    #[test]
    fn splits_at_times_into_training_and_test_sets() {
        let all = series(&[0.0, 1.0, 2.0, 3.0, 4.0], &[0.0, 1.0, 0.0, 1.0, 1.0]);
        let (train, tests) = split_series(&all, &[2.0, 4.0]).unwrap();
        assert_eq!(train, series(&[0.0, 1.0], &[0.0, 1.0]));
        assert_eq!(
            tests,
            [series(&[2.0, 3.0], &[0.0, 1.0]), series(&[4.0], &[1.0])]
        );
        assert!(matches!(
            split_series(&all, &[3.0, 2.0]),
            Err(SplitError::NotIncreasing { .. })
        ));
    }

    #[test]
    fn the_mean_scores_its_brier_score_and_a_bad_observation_is_named() {
        // Trained on 0, 1, 1, 1: the mean 0.75; tested on 1 and 0: (0.25² + 0.75²) / 2.
        let train = series(&[0.0, 1.0, 2.0, 3.0], &[0.0, 1.0, 1.0, 1.0]);
        let test = series(&[4.0, 5.0], &[1.0, 0.0]);
        let specs: Vec<ModelSpec> = vec!["mean".parse().unwrap()];
        let report = evaluate_models(
            &specs,
            &train,
            std::slice::from_ref(&test),
            &FitOptions::default(),
            &NoProgress,
        )
        .unwrap();
        assert_eq!(report.models[0].tests[0].mse, 0.3125);
        let bad = series(&[1.0, 0.0], &[0.0, 1.0]);
        let error = evaluate_models(&specs, &bad, &[test], &FitOptions::default(), &NoProgress)
            .unwrap_err();
        assert!(
            error
                .to_string()
                .starts_with("model mean: training observation 2: "),
            "{error}"
        );
    }
}
