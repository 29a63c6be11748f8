//! Which features of a place will be visible, as a job with a report ([Krajník 2017] §VII
//! Table I, [Krajník 2019] §V-B): each model learns every feature's visibility on the first
//! days of a state matrix and picks the features most likely visible at each later slot.

use std::fmt::Write as _;
use std::path::Path;

use chronomap_core::Parallelism;
use chronomap_core::progress::Progress;
use chronomap_io::{DataError, read_state_matrix};
use chronomap_models::features::{FeatureError, FeatureScores, SlotLayout, feature_visibility};
use chronomap_models::spec::{FitOptions, ModelSpec};
use serde::Serialize;

use crate::report::Table;

/// The experiment cannot run on a matrix.
#[derive(Debug, thiserror::Error)]
pub enum FeaturesError {
    /// The matrix cannot be read.
    #[error(transparent)]
    Read(#[from] DataError),
    /// The layout does not fit the matrix, or a model cannot be fitted.
    #[error("{matrix}: cannot run the experiment")]
    Experiment {
        /// The matrix's file.
        matrix: String,
        /// Why.
        #[source]
        source: FeatureError,
    },
}

/// The feature-visibility experiment on a state matrix, as `chronomap features` reports it.
#[derive(Debug, Clone, Serialize)]
pub struct FeaturesReport {
    /// The matrix's file.
    pub matrix: String,
    /// Features (columns).
    pub features: usize,
    /// Slots trained on.
    pub train_slots: usize,
    /// Slots tested on.
    pub test_slots: usize,
    /// How many features each model picks per test slot.
    pub n: Vec<usize>,
    /// The scores of each model, in the order given.
    pub models: Vec<FeatureScores>,
    /// The length of a slot (s).
    #[serde(skip)]
    pub slot_secs: f64,
}

impl FeaturesReport {
    /// The report as `chronomap features` prints it.
    pub fn text(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{}: {} features, {} training slots, {} test slots of {} s",
            self.matrix, self.features, self.train_slots, self.test_slots, self.slot_secs
        );
        let mut header = vec!["model".to_string()];
        header.extend(self.n.iter().map(|n| format!("n = {n}")));
        header.push("Brier".to_string());
        let mut table = Table::new(header);
        for m in &self.models {
            let mut row = vec![m.model.clone()];
            row.extend(
                m.reobservation
                    .iter()
                    .map(|r| format!("{:.1} %", 100.0 * r)),
            );
            row.push(format!("{:.4}", m.brier));
            table.row(row);
        }
        let _ = writeln!(out, "{}", table.render());
        let _ = writeln!(
            out,
            "n = k: of the k features each model predicts most likely visible at a test slot, the share \
             that were visible (higher is better); Brier: mean squared error of the visibility over all \
             features and test slots."
        );
        out
    }
}

/// Runs the experiment on the state matrix of `path` (one column per feature, `layout` rows
/// per slot) for the models `specs`, scoring the `n` features each picks per test slot.
///
/// # Errors
/// The matrix cannot be read; the layout does not fit it; a model cannot be fitted.
pub fn feature_report(
    path: &Path,
    layout: SlotLayout,
    specs: &[ModelSpec],
    n: &[usize],
    progress: &dyn Progress,
) -> Result<FeaturesReport, FeaturesError> {
    let matrix = path.display().to_string();
    let rows = read_state_matrix(path)?;
    let report = feature_visibility(
        &rows,
        layout,
        specs,
        n,
        &FitOptions::default(),
        Parallelism::Rayon(0),
        progress,
    )
    .map_err(|source| FeaturesError::Experiment {
        matrix: matrix.clone(),
        source,
    })?;
    Ok(FeaturesReport {
        matrix,
        features: report.features,
        train_slots: report.train_slots,
        test_slots: report.test_slots,
        n: n.to_vec(),
        models: report.models,
        slot_secs: layout.slot_secs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_core::progress::NoProgress;

    /// Feature 1 always visible, feature 2 never, 4 half-day slots of 2 lines: the mean model
    /// trained on the first day picks feature 1, which is visible, and predicts both exactly.
    #[test]
    fn the_mean_picks_the_feature_always_seen() {
        let dir = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-app-features-{}", std::process::id())),
        );
        let path = chronomap_testutil::write(&dir, "m.txt", "1 0\n1 0\n".repeat(4));
        let layout = SlotLayout {
            slot_secs: 43_200.0,
            lines_per_slot: 2,
            train_days: 1.0,
        };
        let specs = ["mean".parse::<ModelSpec>().unwrap()];
        let report = feature_report(&path, layout, &specs, &[1, 2], &NoProgress).unwrap();
        assert_eq!(
            (report.features, report.train_slots, report.test_slots),
            (2, 2, 2)
        );
        assert_eq!(report.models[0].reobservation, [1.0, 0.5]);
        assert_eq!(report.models[0].brier, 0.0);
        let text = report.text();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            format!(
                "{}: 2 features, 2 training slots, 2 test slots of 43200 s",
                path.display()
            )
        );
        assert_eq!(lines[1], "model    n = 1   n = 2   Brier");
        assert_eq!(lines[3], "mean   100.0 %  50.0 %  0.0000");
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["n"], serde_json::json!([1, 2]));
        assert_eq!(json["models"][0]["model"], "mean");
        assert!(json.get("slot_secs").is_none());
    }
}
