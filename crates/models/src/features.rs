//! Which features will be visible? The localisation experiment of [Krajník 2017] §VII (Table I) and
//! [Krajník 2019] §V-B over any model spec: every model is fitted per feature on the first days of
//! a state matrix, and at every later slot the `n` features it predicts most likely visible
//! are picked; the score is the share of them that were visible
//! ([`reobservation_rate`]).
//!
//! ```
//! use chronomap_core::Parallelism;
//! use chronomap_core::progress::NoProgress;
//! use chronomap_models::features::{SlotLayout, feature_visibility};
//! use chronomap_models::spec::{FitOptions, parse_model_list};
//!
//! // Two features over 8 days of hourly slots: one visible by day, one by night.
//! let rows: Vec<Vec<f64>> = (0..8 * 24)
//!     .map(|h| {
//!         let day = (8..20).contains(&(h % 24));
//!         vec![f64::from(u8::from(day)), f64::from(u8::from(!day))]
//!     })
//!     .collect();
//! let layout = SlotLayout { slot_secs: 3600.0, lines_per_slot: 1, train_days: 6.0 };
//! let specs = parse_model_list("mean,fremen:2")?;
//! let report = feature_visibility(
//!     &rows, layout, &specs, &[1], &FitOptions::default(), Parallelism::Rayon(0), &NoProgress,
//! )?;
//! assert_eq!((report.features, report.train_slots, report.test_slots), (2, 144, 48));
//! // FreMEn knows which feature the time of day shows; the mean does not.
//! assert!(report.models[1].reobservation[0] > 0.9);
//! assert!(report.models[0].reobservation[0] < 0.6);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use chronomap_core::Parallelism;
use chronomap_core::TemporalModel;
use chronomap_core::error::BuildError;
use chronomap_core::metrics::mse;
use chronomap_core::progress::Progress;
use chronomap_core::visibility::reobservation_rate;
use rayon::prelude::*;
use serde::Serialize;
use thiserror::Error;

use crate::spec::{FitOptions, ModelSpec};

/// How the rows of a state matrix make time slots.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlotLayout {
    /// Length of a slot in seconds; slot `k` starts at `k × slot_secs`.
    pub slot_secs: f64,
    /// Rows per slot (the rows of a slot repeat one state; the first is used).
    pub lines_per_slot: usize,
    /// Days of slots to train on; the later slots are the test.
    pub train_days: f64,
}

/// The scores of one model.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FeatureScores {
    /// The model spec.
    pub model: String,
    /// For each `n`, the share of the picked features that were visible.
    pub reobservation: Vec<f64>,
    /// Mean squared error of the predicted visibility over all features and test slots.
    pub brier: f64,
}

/// What [`feature_visibility`] measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FeatureReport {
    /// Number of features (columns of the matrix).
    pub features: usize,
    /// Slots trained on.
    pub train_slots: usize,
    /// Slots tested on.
    pub test_slots: usize,
    /// One entry per model, in the order given.
    pub models: Vec<FeatureScores>,
}

/// Why the experiment could not run.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum FeatureError {
    /// `lines_per_slot` is 0.
    #[error("a slot must have at least one line (lines per slot = 0)")]
    NoLinesPerSlot,
    /// The rows are not whole slots.
    #[error("{rows} lines are not whole slots of {lines_per_slot} lines")]
    PartialSlot {
        /// Rows of the matrix.
        rows: usize,
        /// Rows per slot.
        lines_per_slot: usize,
    },
    /// The matrix has no rows or no features.
    #[error("the matrix has no features")]
    NoFeatures,
    /// The training days leave no training or no test slot.
    #[error("{slots} slots of {slot_secs} s; {train_days} training days leave no {which} slot")]
    Split {
        /// Number of slots.
        slots: usize,
        /// Length of a slot.
        slot_secs: f64,
        /// Days of training.
        train_days: f64,
        /// `"training"` or `"test"`.
        which: &'static str,
    },
    /// A model cannot be fitted to a feature.
    #[error("model {spec}, feature {feature}: {error}")]
    Fit {
        /// The model.
        spec: String,
        /// The feature (1-based column).
        feature: usize,
        /// Why.
        error: BuildError,
    },
}

/// Fits every model of `specs` to every feature (column) of `rows` on the training slots of
/// `layout`, predicts the test slots, and scores the `n` most likely features at every test
/// slot for each `n` of `ns` ([`reobservation_rate`]) and the Brier score. Features are fitted
/// as tasks of `parallelism` (the results do not depend on it); one progress step per model.
///
/// # Errors
/// A layout that does not fit the rows or leaves no training or test slot, or a model that
/// cannot be fitted (naming model and feature).
pub fn feature_visibility(
    rows: &[Vec<f64>],
    layout: SlotLayout,
    specs: &[ModelSpec],
    ns: &[usize],
    options: &FitOptions,
    parallelism: Parallelism,
    progress: &dyn Progress,
) -> Result<FeatureReport, FeatureError> {
    if layout.lines_per_slot == 0 {
        return Err(FeatureError::NoLinesPerSlot);
    }
    if !rows.len().is_multiple_of(layout.lines_per_slot) {
        return Err(FeatureError::PartialSlot {
            rows: rows.len(),
            lines_per_slot: layout.lines_per_slot,
        });
    }
    let slots: Vec<&Vec<f64>> = rows.iter().step_by(layout.lines_per_slot).collect();
    let features = slots.first().map_or(0, |s| s.len());
    if features == 0 {
        return Err(FeatureError::NoFeatures);
    }
    let times: Vec<f64> = (0..slots.len())
        .map(|k| k as f64 * layout.slot_secs)
        .collect();
    let split = times.partition_point(|&t| t < layout.train_days * 86_400.0);
    if split == 0 || split == times.len() {
        return Err(FeatureError::Split {
            slots: slots.len(),
            slot_secs: layout.slot_secs,
            train_days: layout.train_days,
            which: if split == 0 { "training" } else { "test" },
        });
    }
    // features × slots
    let series: Vec<Vec<f64>> = (0..features)
        .map(|f| slots.iter().map(|row| row[f]).collect())
        .collect();
    let truth: Vec<Vec<f64>> = series.iter().map(|s| s[split..].to_vec()).collect();
    progress.stage("fitting models", specs.len() as u64);
    let mut models = Vec::with_capacity(specs.len());
    for spec in specs {
        let predict = |(f, s): (usize, &Vec<f64>)| {
            let fitted = spec
                .fit(&times[..split], &s[..split], options)
                .map_err(|error| FeatureError::Fit {
                    spec: spec.to_string(),
                    feature: f + 1,
                    error,
                })?;
            Ok::<_, FeatureError>(fitted.model.predict_many(&times[split..]))
        };
        let predictions: Vec<Vec<f64>> = match parallelism {
            Parallelism::Sequential => series
                .iter()
                .enumerate()
                .map(predict)
                .collect::<Result<_, _>>(),
            Parallelism::Rayon(_) => series.par_iter().enumerate().map(predict).collect(),
        }?;
        let reobservation = ns
            .iter()
            .map(|&n| reobservation_rate(&predictions, &truth, n))
            .collect();
        let brier = predictions
            .iter()
            .zip(&truth)
            .map(|(p, t)| mse(p, t))
            .sum::<f64>()
            / features as f64;
        models.push(FeatureScores {
            model: spec.to_string(),
            reobservation,
            brier,
        });
        progress.advance(1);
    }
    Ok(FeatureReport {
        features,
        train_slots: split,
        test_slots: times.len() - split,
        models,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::parse_model_list;
    use chronomap_core::progress::NoProgress;

    fn layout(lines_per_slot: usize, train_days: f64) -> SlotLayout {
        SlotLayout {
            slot_secs: 3600.0,
            lines_per_slot,
            train_days,
        }
    }

    #[test]
    fn repeated_lines_are_one_slot_and_bad_layouts_are_errors() {
        // Three features over 3 days of hourly slots, each slot written twice: feature 0
        // visible by day, 1 always, 2 never.
        let rows: Vec<Vec<f64>> = (0..3 * 24)
            .flat_map(|h| {
                let row = vec![f64::from(u8::from((8..20).contains(&(h % 24)))), 1.0, 0.0];
                [row.clone(), row]
            })
            .collect();
        let specs = parse_model_list("mean").unwrap();
        let run = |layout, parallelism| {
            feature_visibility(
                &rows,
                layout,
                &specs,
                &[1, 2, 3],
                &FitOptions::default(),
                parallelism,
                &NoProgress,
            )
        };
        let report = run(layout(2, 2.0), Parallelism::Sequential).unwrap();
        assert_eq!(
            (report.features, report.train_slots, report.test_slots),
            (3, 48, 24)
        );
        // The mean ranks "always" first (p = 1), then "by day" (p = 0.5), then "never".
        let scores = &report.models[0];
        assert_eq!(
            scores.reobservation,
            [1.0, (24.0 + 12.0) / 48.0, 36.0 / 72.0]
        );
        // Brier: "by day" is predicted 0.5 and is 0 or 1 (0.25 per slot), the others exactly.
        assert!(
            (scores.brier - 0.25 / 3.0).abs() < 1e-12,
            "{}",
            scores.brier
        );
        assert_eq!(run(layout(2, 2.0), Parallelism::Rayon(3)).unwrap(), report);

        let err = run(layout(0, 2.0), Parallelism::Sequential).unwrap_err();
        assert!(matches!(err, FeatureError::NoLinesPerSlot), "{err}");
        let err = run(layout(5, 2.0), Parallelism::Sequential).unwrap_err();
        assert_eq!(err.to_string(), "144 lines are not whole slots of 5 lines");
        let err = run(layout(2, 3.0), Parallelism::Sequential).unwrap_err();
        assert_eq!(
            err.to_string(),
            "72 slots of 3600 s; 3 training days leave no test slot"
        );
        let err = run(layout(2, 0.0), Parallelism::Sequential).unwrap_err();
        assert!(err.to_string().ends_with("leave no training slot"), "{err}");
    }
}
