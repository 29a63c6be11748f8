//! Long-term memory: the mean of all past observations.

use serde::{Deserialize, Serialize};

use crate::error::ObservationError;
use crate::exact::ExactSum;
use crate::model::TemporalModel;
use crate::observe::ObservedSpan;

/// Long-term memory ([Santos 2017] §4.3.1): "the probability of a given state simply as the
/// arithmetic mean of all its past observations". Equal to FreMEn of order 0; the baseline
/// every temporal model must beat.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MeanModel {
    span: ObservedSpan,
    sum: ExactSum,
}

impl MeanModel {
    /// An empty model (predicts 0.5).
    pub fn new() -> Self {
        MeanModel::default()
    }

    /// Checks invariants (for models read from files): a valid span and a sum of as many
    /// values in `[0, 1]` as were observed.
    pub fn is_consistent(&self) -> bool {
        self.span.is_consistent() && self.sum.fits_terms(self.span.count, true)
    }

    /// Mean of the observations, `None` before the first.
    pub fn mean(&self) -> Option<f64> {
        (self.span.count > 0).then(|| self.sum.to_f64() / self.span.count as f64)
    }
}

impl TemporalModel for MeanModel {
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        self.span.validate(times, values)?;
        values.iter().for_each(|&v| self.sum.add(v));
        self.span.extend(times);
        Ok(())
    }

    fn predict(&self, _time: f64) -> f64 {
        self.mean().unwrap_or(0.5)
    }

    fn span(&self) -> ObservedSpan {
        self.span
    }
}
