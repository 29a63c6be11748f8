//! The benchmark experiment of the FreMEn papers ([Krajník 2017] §VI, [Santos 2017] §7) on any
//! data: models fitted on a training series and scored on later test sets (MSE or Brier
//! score and binary error of each), compared by paired t-tests; the test sets from files or
//! one series split at times.
//!
//! The data are read here ([`read_study`]) and the outcome renders itself as the tables and
//! the JSON the faces print ([`EvalOutcome`]); the faces map errors to their flags.

use std::path::{Path, PathBuf};

use chronomap_core::calendar::DaysOff;
use chronomap_core::calibration::DEFAULT_BINS;
use chronomap_core::metrics::TestScore;
use chronomap_core::progress::Progress;
use chronomap_core::{BuildError, TimeSeries};
use chronomap_io::{DataError, read_pairs, read_test_set};
use chronomap_models::eval::{EvalReport, ModelEvaluation, TestSet, evaluate_on_calendar};
use chronomap_models::spec::{FitOptions, ModelSpec};
use chronomap_models::split::{SplitError, chronological_split};
#[cfg(feature = "plot")]
use chronomap_plot::Panel;
use serde_json::{Value, json};

use crate::model::describe_selection;
use crate::report::{Table, duration, time};

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
/// the days of `days_off` predicted as the Sunday before ([`evaluate_on_calendar`]; none: an
/// empty set), reporting the stage `fitting models` with one step per model to `progress`.
///
/// # Errors
/// [`FitError`] for the first model that cannot be fitted.
pub fn evaluate_models(
    specs: &[ModelSpec],
    train: &TimeSeries,
    tests: &[TimeSeries],
    options: &FitOptions,
    days_off: &DaysOff,
    progress: &dyn Progress,
) -> Result<EvalReport, FitError> {
    let sets: Vec<TestSet<'_>> = tests.iter().map(TestSet::from).collect();
    progress.stage("fitting models", specs.len() as u64);
    evaluate_on_calendar(
        specs,
        &train.times,
        &train.values,
        &sets,
        options,
        days_off,
        |_| progress.advance(1),
    )
    .map_err(|(spec, error)| FitError { spec, error })
}

/// The data of an evaluation: the training series and the test sets, each with a label for
/// its times and its values.
#[derive(Clone, Debug)]
pub struct EvalStudy {
    /// The training file, as named.
    pub train_file: String,
    /// The training series.
    pub train: TimeSeries,
    /// The test sets.
    pub tests: Vec<TimeSeries>,
    /// What each test set's times and values came from.
    pub labels: Vec<(String, String)>,
}

/// Why the data of an evaluation cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum EvalDataError {
    /// A file cannot be read.
    #[error(transparent)]
    Data(#[from] DataError),
    /// The training file cannot be split at the times asked for (`--split-at`).
    #[error("--split-at: {}", describe_split(file, error))]
    Split {
        /// The training file.
        file: String,
        /// Why.
        error: SplitError,
    },
}

/// A split error in words, with times as dates.
fn describe_split(file: &str, error: &SplitError) -> String {
    match *error {
        SplitError::NotIncreasing { previous, next } => format!(
            "{} is not after {} (times must increase)",
            time(next),
            time(previous)
        ),
        SplitError::EmptyTrain { before } => {
            format!("{file} has no observation before {}", time(before))
        }
        SplitError::EmptyTest { from, to } => format!(
            "{file} has no observation from {} to {}",
            time(from),
            until(to)
        ),
        ref e => e.to_string(),
    }
}

/// A time, or `the end` for the infinite end of the last interval.
fn until(to: f64) -> String {
    if to.is_finite() {
        time(to)
    } else {
        "the end".to_string()
    }
}

/// Reads the training series of `train` and the test sets: the pairs of files `tests`, or,
/// with times `split_at`, the training file split at them ([`split_series`]).
///
/// # Errors
/// [`EvalDataError`]: a file that cannot be read, or a split without observations.
pub fn read_study(
    train: &Path,
    tests: &[(PathBuf, PathBuf)],
    split_at: &[f64],
) -> Result<EvalStudy, EvalDataError> {
    let all = read_pairs(train)?;
    let file = train.display().to_string();
    if split_at.is_empty() {
        return Ok(EvalStudy {
            train_file: file,
            train: all,
            tests: tests
                .iter()
                .map(|(t, v)| read_test_set(t, v))
                .collect::<Result<_, _>>()?,
            labels: tests
                .iter()
                .map(|(t, v)| (t.display().to_string(), v.display().to_string()))
                .collect(),
        });
    }
    let (train, tests) = split_series(&all, split_at).map_err(|error| EvalDataError::Split {
        file: file.clone(),
        error,
    })?;
    let labels = split_at
        .iter()
        .enumerate()
        .map(|(i, &from)| {
            let to = split_at.get(i + 1).copied().unwrap_or(f64::INFINITY);
            let label = format!("{file} from {} to {}", time(from), until(to));
            (label.clone(), label)
        })
        .collect();
    Ok(EvalStudy {
        train_file: file,
        train,
        tests,
        labels,
    })
}

/// An evaluation and the level its paired t-tests are judged at.
#[derive(Clone, Debug)]
pub struct EvalOutcome {
    /// The data.
    pub study: EvalStudy,
    /// What every model scored.
    pub report: EvalReport,
    /// The significance level of the paired t-tests.
    pub alpha: f64,
}

/// Whether every value is 0 or 1.
fn is_binary<'a>(values: impl IntoIterator<Item = &'a f64>) -> bool {
    values.into_iter().all(|&v| v == 0.0 || v == 1.0)
}

impl EvalOutcome {
    /// The outcome as `chronomap eval --json` prints it.
    pub fn json(&self) -> Value {
        let (study, report) = (&self.study, &self.report);
        let name = |i: usize| report.models[i].spec.to_string();
        json!({
            "train": {
                "file": study.train_file,
                "observations": study.train.len(),
            },
            "tests": study.labels.iter().zip(&study.tests).map(|((t, v), s)| json!({
                "times": t,
                "values": v,
                "samples": s.len(),
            })).collect::<Vec<_>>(),
            "models": report.models.iter().map(|m| json!({
                "name": m.spec.to_string(),
                "fitted": m.fitted.model.fitted_as(),
                "selection": m.fitted.selection.as_ref().map(describe_selection),
                "tests": m.tests.iter().zip(&m.calibration).map(|(t, c)| json!({
                    "mse": t.mse,
                    "binary_error": t.binary_error,
                    "ece": c.ece,
                })).collect::<Vec<_>>(),
                "mean_mse": m.mean_mse(),
                "mean_binary_error": m.mean_binary_error(),
                "mean_ece": m.mean_ece(),
                "calibration": m.pooled_calibration,
            })).collect::<Vec<_>>(),
            "alpha": self.alpha,
            "comparisons": report.comparisons.iter().map(|c| json!({
                "better": name(c.better),
                "worse": name(c.worse),
                "mean_difference": c.test.mean_difference,
                "t": if c.test.t.is_finite() { json!(c.test.t) } else { json!(null) },
                "p_value": c.test.p_value,
                "significant": c.test.p_value < self.alpha,
            })).collect::<Vec<_>>(),
        })
    }

    /// The outcome as `chronomap eval` prints it: the data, the tables of the scores, how the
    /// automatic models chose, and the significant differences.
    pub fn text(&self) -> String {
        let (study, report) = (&self.study, &self.report);
        let train = &study.train;
        let last = train.times[train.len() - 1];
        let mean = train.values.iter().sum::<f64>() / train.len() as f64;
        let mut lines = vec![format!(
            "training: {} — {} observations, {} .. {} ({}), {}",
            study.train_file,
            train.len(),
            time(train.times[0]),
            time(last),
            duration(last - train.times[0]),
            if is_binary(&train.values) {
                format!("{:.1} % ones", 100.0 * mean)
            } else {
                format!("mean value {mean:.4}")
            }
        )];
        for (i, ((t, _), s)) in study.labels.iter().zip(&study.tests).enumerate() {
            lines.push(format!(
                "test {}: {} — {} observations from {}",
                i + 1,
                t,
                s.len(),
                time(s.times[0])
            ));
        }
        lines.push(String::new());
        lines.push(metric_table(
            report,
            if is_binary(&train.values) {
                "Mean squared error of p(t) (Brier score), lower is better"
            } else {
                "Mean squared error of the predicted value, lower is better"
            },
            |t| t.mse,
        ));
        lines.push(String::new());
        // The binary error (p > 0.5 against the state) means nothing for continuous values.
        let binary = is_binary(
            train
                .values
                .iter()
                .chain(study.tests.iter().flat_map(|t| &t.values)),
        );
        if binary {
            lines.push(metric_table(
                report,
                "Binary error (fraction of wrongly predicted states)",
                |t| t.binary_error,
            ));
            lines.push(String::new());
            lines.push(per_test_table(
                report,
                &format!(
                    "Expected calibration error of p(t) ({DEFAULT_BINS} equal-width bins), lower is better"
                ),
                |m| m.calibration.iter().map(|c| c.ece).collect(),
            ));
            lines.push(String::new());
            lines.push(calibration_table(report));
            lines.push(String::new());
        }
        let selections: Vec<String> = report
            .models
            .iter()
            .filter_map(|m| {
                let s = m.fitted.selection.as_ref()?;
                Some(format!("  {}: {}", m.spec, describe_selection(s)))
            })
            .collect();
        if !selections.is_empty() {
            lines.push("How the automatic models chose (training data only):".to_string());
            lines.extend(selections);
            lines.push(String::new());
        }
        if study.tests.len() < 2 {
            lines.push("(significance needs at least two test sets)".to_string());
            return lines.join("\n");
        }
        let mut significant: Vec<_> = report.significant(self.alpha).collect();
        significant.sort_by(|a, b| a.test.p_value.total_cmp(&b.test.p_value));
        lines.push(format!(
            "Significant differences of the {} (paired t-test over {} test sets, p < {}):",
            if binary {
                "Brier score"
            } else {
                "mean squared error"
            },
            study.tests.len(),
            self.alpha
        ));
        if significant.is_empty() {
            lines.push("  none".to_string());
        }
        for c in significant {
            lines.push(format!(
                "  {:<18} better than {:<18} by {:.4} (p = {:.3})",
                report.models[c.better].spec.to_string(),
                report.models[c.worse].spec.to_string(),
                -c.test.mean_difference,
                c.test.p_value
            ));
        }
        lines.join("\n")
    }
}

impl EvalOutcome {
    /// The reliability diagram of every model over all test sets together (above: observed
    /// frequency against mean forecast per bin, the diagonal being perfect calibration; below:
    /// the share of forecasts in each bin), as `chronomap eval --plot` draws it.
    #[cfg(feature = "plot")]
    pub fn reliability_panels(&self) -> Vec<Panel> {
        let forecasts: Vec<(String, &[chronomap_core::calibration::ReliabilityBin])> = self
            .report
            .models
            .iter()
            .map(|m| {
                let c = &m.pooled_calibration;
                (format!("{} (ECE {:.3})", m.spec, c.ece), c.bins.as_slice())
            })
            .collect();
        crate::calibration_plots::reliability_panels(
            format!(
                "Reliability diagram: all {} test sets, {DEFAULT_BINS} equal-width bins",
                self.study.tests.len()
            ),
            &forecasts,
        )
    }
}

/// A titled table of one metric per model and test set, and its mean.
fn metric_table(report: &EvalReport, title: &str, metric: impl Fn(&TestScore) -> f64) -> String {
    per_test_table(report, title, |m| m.tests.iter().map(&metric).collect())
}

/// A titled table of one value per model and test set (`values` of a model, in test order),
/// and their mean.
fn per_test_table(
    report: &EvalReport,
    title: &str,
    values: impl Fn(&ModelEvaluation) -> Vec<f64>,
) -> String {
    let tests = report.models.first().map_or(0, |m| m.tests.len());
    let mut header = vec!["model".to_string(), "fitted as".to_string()];
    header.extend((1..=tests).map(|i| format!("test {i}")));
    header.push("mean".into());
    let mut table = Table::new(header);
    for m in &report.models {
        let values = values(m);
        let mut row = vec![m.spec.to_string(), m.fitted.model.fitted_as()];
        row.extend(values.iter().map(|v| format!("{v:.4}")));
        row.push(format!(
            "{:.4}",
            values.iter().sum::<f64>() / values.len() as f64
        ));
        table.row(row);
    }
    format!("{title}\n{}", table.render())
}

/// The calibration of every model over all test sets together, with the Brier score's
/// decomposition ([`chronomap_core::calibration`]).
fn calibration_table(report: &EvalReport) -> String {
    let mut table = Table::new(
        [
            "model",
            "mean p",
            "observed",
            "ECE",
            "reliability",
            "resolution",
            "uncertainty",
            "within bins",
            "Brier",
        ]
        .map(String::from)
        .to_vec(),
    );
    for m in &report.models {
        let c = &m.pooled_calibration;
        table.row(vec![
            m.spec.to_string(),
            format!("{:.4}", c.mean_prediction),
            format!("{:.4}", c.base_rate),
            format!("{:.4}", c.ece),
            format!("{:.5}", c.reliability),
            format!("{:.5}", c.resolution),
            format!("{:.5}", c.uncertainty),
            format!("{:+.5}", c.within_bin),
            format!("{:.4}", c.brier),
        ]);
    }
    format!(
        "Calibration over all test sets ({DEFAULT_BINS} bins; Brier = reliability − resolution \
         + uncertainty + within bins, Murphy 1973)\n{}",
        table.render()
    )
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
    fn the_outcome_reads_as_tables_of_hand_computed_scores() {
        // Trained on 0, 1, 1, 1: the mean 0.75; test 1 (1, 0): Brier (0.0625 + 0.5625) / 2,
        // binary error 1/2; test 2 (1, 1): Brier 0.0625, binary error 0.
        let train = series(&[0.0, 1.0, 2.0, 3.0], &[0.0, 1.0, 1.0, 1.0]);
        let tests = vec![
            series(&[4.0, 5.0], &[1.0, 0.0]),
            series(&[6.0, 7.0], &[1.0, 1.0]),
        ];
        let specs: Vec<ModelSpec> = vec!["mean".parse().unwrap()];
        let report = evaluate_models(
            &specs,
            &train,
            &tests,
            &FitOptions::default(),
            &DaysOff::default(),
            &NoProgress,
        )
        .unwrap();
        let outcome = EvalOutcome {
            study: EvalStudy {
                train_file: "train.txt".into(),
                train,
                tests,
                labels: vec![("t1".into(), "v1".into()), ("t2".into(), "v2".into())],
            },
            report,
            alpha: 0.05,
        };
        let text = outcome.text();
        assert!(
            text.contains(
                "Mean squared error of p(t) (Brier score), lower is better\n\
                 model  fitted as  test 1  test 2    mean\n\
                 ----------------------------------------\n\
                 mean        mean  0.3125  0.0625  0.1875"
            ),
            "{text}"
        );
        assert!(
            text.contains("mean        mean  0.5000  0.0000  0.2500"),
            "{text}"
        );
        assert!(text.ends_with("p < 0.05):\n  none"), "{text}");
        let json = outcome.json();
        assert_eq!(json["models"][0]["mean_mse"], 0.1875);
        assert_eq!(json["tests"][1]["values"], "v2");
    }

    #[test]
    fn a_split_without_training_data_names_the_file_and_the_time() {
        let dir = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-app-eval-{}", std::process::id())),
        );
        let file = chronomap_testutil::write(&dir, "door.txt", "0 0\n60 1\n120 1\n");
        let study = read_study(&file, &[], &[60.0]).unwrap();
        assert_eq!(study.train.len(), 1);
        assert_eq!(study.tests[0].len(), 2);
        assert_eq!(
            study.labels[0].0,
            format!("{} from {} to the end", file.display(), time(60.0))
        );
        let error = read_study(&file, &[], &[0.0]).unwrap_err();
        assert_eq!(
            error.to_string(),
            format!(
                "--split-at: {} has no observation before {}",
                file.display(),
                time(0.0)
            )
        );
        std::fs::remove_dir_all(&dir).unwrap();
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
            &DaysOff::default(),
            &NoProgress,
        )
        .unwrap();
        assert_eq!(report.models[0].tests[0].mse, 0.3125);
        let bad = series(&[1.0, 0.0], &[0.0, 1.0]);
        let error = evaluate_models(
            &specs,
            &bad,
            &[test],
            &FitOptions::default(),
            &DaysOff::default(),
            &NoProgress,
        )
        .unwrap_err();
        assert!(
            error
                .to_string()
                .starts_with("model mean: training observation 2: "),
            "{error}"
        );
    }
}
