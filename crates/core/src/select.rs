//! Order selection on held-back data ([Krajník 2017] §IV-B, [Santos 2017] §4.1.3).
//!
//! "To select the proper value of the model order l, we evaluate the model's predictive
//! capability for different values of l, choose the order l' with the lowest prediction
//! error ε_p and then perform the model update with the value l'." The observations used to
//! evaluate are ones the model has not seen yet — in a deployment, those gathered since the
//! last update; when fitting a data set, its most recent part.

use serde::{Deserialize, Serialize};

use crate::error::{BuildError, ConfigError, ObservationError};
use crate::metrics::{binary_error, mean_absolute_error, mse};
use crate::model::{Ordered, TemporalModel};

/// How prediction error is measured when choosing between orders or models.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Criterion {
    /// Brier score (mean squared error of the probability): informative even for states
    /// that are rarely 1. The default.
    #[default]
    Brier,
    /// Mean absolute error ([Fentanes 2015] eq. (3)).
    AbsoluteError,
    /// Fraction of wrongly predicted binary states ([Krajník 2017] eq. (14); [Santos 2017] eq. (2)).
    BinaryError,
}

impl Criterion {
    /// The error of `predictions` against `observations` under this criterion.
    pub fn error(self, predictions: &[f64], observations: &[f64]) -> f64 {
        match self {
            Criterion::Brier => mse(predictions, observations),
            Criterion::AbsoluteError => mean_absolute_error(predictions, observations),
            Criterion::BinaryError => binary_error(predictions, observations),
        }
    }
}

/// Outcome of an order selection.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OrderSelection {
    /// The chosen order.
    pub order: usize,
    /// Error of each order `0..=max` on the held-back observations.
    pub errors: Vec<f64>,
    /// Number of held-back observations the errors were measured on.
    pub held_back: usize,
}

/// Online order selection ([Krajník 2017] §IV-B): evaluates orders `0..=max_order` of `model` on
/// observations it has not seen, sets the order with the lowest error (the smallest such
/// order on ties), then adds the observations to the model.
///
/// # Errors
/// If the observations violate the observation contract (the model is then unchanged).
pub fn select_order_online<M: TemporalModel + Ordered>(
    model: &mut M,
    times: &[f64],
    values: &[f64],
    max_order: usize,
    criterion: Criterion,
) -> Result<OrderSelection, ObservationError> {
    model.span().validate(times, values)?;
    let max_order = max_order.min(model.max_order());
    let mut predictions = vec![0.0; times.len()];
    let mut errors = Vec::with_capacity(max_order + 1);
    for order in 0..=max_order {
        model.set_order(order);
        model.predict_into(times, &mut predictions);
        errors.push(criterion.error(&predictions, values));
    }
    let order = (0..errors.len())
        .min_by(|&a, &b| errors[a].total_cmp(&errors[b]))
        .unwrap_or(0);
    model.set_order(order);
    model.observe(times, values)?;
    Ok(OrderSelection {
        order,
        errors,
        held_back: times.len(),
    })
}

/// Checks a held-back fraction ([Krajník 2017] §IV-B: the orders are chosen on the most recent part
/// of the data): it must lie strictly between 0 and 1.
///
/// # Errors
/// [`ConfigError::OutOfRange`] naming `holdout` otherwise.
pub fn check_holdout(fraction: f64) -> Result<(), ConfigError> {
    if fraction > 0.0 && fraction < 1.0 {
        Ok(())
    } else {
        Err(ConfigError::OutOfRange {
            name: "holdout",
            value: fraction.to_string(),
            expected: "a fraction strictly between 0 and 1",
        })
    }
}

/// Index of the first observation of the most recent `fraction` of the time spanned by
/// `times` (sorted): the split between training and held-back data.
///
/// # Errors
/// If `fraction` is not strictly between 0 and 1, or either side would be empty.
pub fn holdout_split(times: &[f64], fraction: f64) -> Result<usize, BuildError> {
    check_holdout(fraction)?;
    let (Some(&first), Some(&last)) = (times.first(), times.last()) else {
        return Err(BuildError::NotEnoughData("no observations".into()));
    };
    let cut = first + (1.0 - fraction) * (last - first);
    let split = times.partition_point(|&t| t <= cut);
    if split == 0 || split == times.len() {
        return Err(BuildError::NotEnoughData(format!(
            "{} observations over {} s cannot be split {:.0}/{:.0} % in time",
            times.len(),
            last - first,
            100.0 * (1.0 - fraction),
            100.0 * fraction
        )));
    }
    Ok(split)
}

/// Fits an empty `model` to a data set choosing its order on the most recent `holdout`
/// fraction of the time span: observes the earlier part, selects the order on the held-back
/// part with [`select_order_online`] (which then adds it), so the result has seen every
/// observation.
///
/// # Errors
/// Invalid `holdout`, too few observations to split, or data violating the observation
/// contract.
pub fn fit_with_order_selection<M: TemporalModel + Ordered>(
    mut model: M,
    times: &[f64],
    values: &[f64],
    holdout: f64,
    max_order: usize,
    criterion: Criterion,
) -> Result<(M, OrderSelection), BuildError> {
    crate::observe::validate(None, times, values)?;
    let split = holdout_split(times, holdout)?;
    model.observe(&times[..split], &values[..split])?;
    let selection = select_order_online(
        &mut model,
        &times[split..],
        &values[split..],
        max_order,
        criterion,
    )?;
    Ok((model, selection))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::FremenModel;
    use crate::testdata::quarter_hours;

    #[test]
    fn picks_the_order_that_predicts_and_keeps_every_observation() {
        // Weekday door (daily + weekly structure) over four weeks, sampled every 15 min.
        let (times, values) = quarter_hours(28, |t| {
            let weekday = ((t / 86_400.0) as u64 % 7) < 5;
            let hour = (t % 86_400.0) / 3600.0;
            weekday && (9.0..17.0).contains(&hour)
        });
        let (model, selection) = fit_with_order_selection(
            FremenModel::with_order(0),
            &times,
            &values,
            0.25,
            10,
            Criterion::Brier,
        )
        .unwrap();
        assert_eq!(selection.errors.len(), 11);
        assert!(selection.order >= 2, "{selection:?}");
        assert!(selection.errors[selection.order] < 0.5 * selection.errors[0]);
        assert_eq!(model.order(), selection.order);
        assert_eq!(model.span().count, times.len() as u64);
        assert!(holdout_split(&times, 0.0).is_err());
        assert!(holdout_split(&times[..1], 0.25).is_err());
    }
}
