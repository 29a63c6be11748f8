//! Anomaly detection at a confidence level ([Krajník 2017] §V).

use crate::error::ConfigError;
use crate::model::TemporalModel;

/// An observation the model considered very unlikely.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Anomaly {
    /// Index of the observation in the batch.
    pub index: usize,
    /// Time of the observation.
    pub time: f64,
    /// Observed value.
    pub observed: f64,
    /// Predicted probability `p(t)` of the state being 1.
    pub predicted: f64,
}

/// Observations that are anomalous at confidence `c` ([Krajník 2017] §V): with the prediction at
/// confidence `s(t, c) = p(t) ≥ c` (eq. (9)), a measurement `s^m(t)` is anomalous if
/// `s^m(t) < s(t, c)` — the state is 0 although the model was sure at level `c` that it is
/// 1 — or `s^m(t) > s(t, 1 − c)` — it is 1 although `p(t) < 1 − c`.
///
/// Values in `[0, 1]` that are not binary are read as states by thresholding at 0.5.
///
/// # Errors
/// If `confidence` is not in `[0.5, 1]` (below 0.5 the two conditions would overlap).
///
/// # Panics
/// If `times` and `values` differ in length.
pub fn detect_anomalies<M: TemporalModel + ?Sized>(
    model: &M,
    times: &[f64],
    values: &[f64],
    confidence: f64,
) -> Result<Vec<Anomaly>, ConfigError> {
    assert_eq!(times.len(), values.len());
    if !(0.5..=1.0).contains(&confidence) {
        return Err(ConfigError::OutOfRange {
            name: "confidence",
            value: confidence.to_string(),
            expected: "a level in [0.5, 1]",
        });
    }
    let predictions = model.predict_many(times);
    Ok(times
        .iter()
        .zip(values)
        .zip(predictions)
        .enumerate()
        .filter_map(|(index, ((&time, &observed), predicted))| {
            let state = observed > 0.5;
            let surely_one = predicted >= confidence;
            let surely_zero = predicted < 1.0 - confidence;
            ((!state && surely_one) || (state && surely_zero)).then_some(Anomaly {
                index,
                time,
                observed,
                predicted,
            })
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::FremenModel;
    use crate::testdata::quarter_hours;

    #[test]
    fn a_visitor_at_midnight_is_anomalous() {
        // Door open 9:00-17:00 for two weeks; then someone opens it at 0:30.
        let (times, values) =
            quarter_hours(14, |t| (9.0..17.0).contains(&((t % 86_400.0) / 3600.0)));
        let mut model = FremenModel::with_order(6);
        model.observe(&times, &values).unwrap();
        let day = 15.0 * 86_400.0;
        let probe_times = [day + 1800.0, day + 12.0 * 3600.0, day + 13.0 * 3600.0];
        let probe_values = [1.0, 1.0, 0.0];
        let found = detect_anomalies(&model, &probe_times, &probe_values, 0.9).unwrap();
        let indices: Vec<usize> = found.iter().map(|a| a.index).collect();
        // The midnight opening and the closed door at 13:00 are anomalies; noon open is not.
        assert_eq!(indices, vec![0, 2]);
        assert!(detect_anomalies(&model, &probe_times, &probe_values, 0.4).is_err());
    }
}
