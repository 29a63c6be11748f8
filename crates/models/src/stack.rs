//! `auto`: a weighted average of many models, the weights fitted by rolling-origin
//! cross-validation.
//!
//! The originals choose one order or one model on the most recent quarter of the training data
//! ([Krajník 2017] §IV-B). That choice overfits its single hold-out: on the greg door it picked
//! a 168-bin histogram that scored 0.0676 on the public test weeks and 0.0710 on later ones,
//! worse than a fixed FreMEn order. Here every candidate of a pool (FreMEn of orders
//! 1..=`max_order`, weekly and daily histograms, PerGaM, the mean, short-term memory, and
//! the same histograms of the last days or weeks only, [`RECENT_DAYS`]) predicts
//! the rest of the training span from several *origins* — 40 %, 50 %, …, 90 % of it — having
//! seen only what came before each ([`rolling_origin_problem`]; Tashman 2000, "Out-of-sample
//! tests of forecasting accuracy"). The non-negative weights summing to one that minimise the
//! Brier score of the combined out-of-sample predictions ([`chronomap_core::stacking`]) are
//! then applied to the candidates refitted on everything ([`StackedModel`]).
//!
//! The combination predicts a probability, is never worse on the pooled out-of-sample
//! predictions than the best single candidate, and does not overfit one hold-out: on greg's
//! public test weeks it scores 0.0591 against 0.0634 for the best fixed FreMEn order
//! (`docs/accuracy.md`; 0.0603 without the drift candidates).

use std::cell::Cell;

use serde::{Deserialize, Deserializer, Serialize};

use chronomap_core::error::{BuildError, ConfigError, ObservationError};
use chronomap_core::model::TemporalModel;
use chronomap_core::observe::ObservedSpan;
use chronomap_core::periods::{DAY, WEEK};
use chronomap_core::stacking::StackingProblem;

use crate::spec::{AnyModel, FitOptions, ModelSpec, OrderSpec};

/// The candidates `auto` combines: the mean, histograms over the week (24, 168, 336 and 672 bins) and
/// the day (24 and 48 bins), PerGaM with 1–3 components, short-term memory, the drift
/// candidates of each memory of `recent_days` ([`RECENT_DAYS`]) and FreMEn of orders
/// 1..=`max_order`.
pub fn stack_candidates(max_order: usize, recent_days: &[usize]) -> Vec<ModelSpec> {
    let hist = |bins, period_secs| ModelSpec::Histogram { bins, period_secs };
    let pergam = |k| ModelSpec::Pergam {
        components: OrderSpec::Fixed(k),
        period_secs: DAY,
    };
    let mut candidates = vec![
        ModelSpec::Mean,
        hist(24, WEEK),
        hist(168, WEEK),
        hist(336, WEEK),
        hist(672, WEEK),
        hist(24, DAY),
        hist(48, DAY),
        pergam(1),
        pergam(2),
        pergam(3),
        ModelSpec::Markov,
    ];
    candidates.extend(recent_days.iter().flat_map(|&days| {
        let recent = |bins, period_secs, cycles| ModelSpec::Recent {
            bins,
            period_secs,
            cycles,
        };
        [
            recent(1, DAY, days),
            recent(24, DAY, days),
            recent(168, WEEK, days.div_ceil(7)),
        ]
    }));
    candidates.extend((1..=max_order).map(|k| ModelSpec::Fremen(OrderSpec::Fixed(k))));
    candidates
}

/// The memories of the drift candidates by default ([`FitOptions::recent_days`]), in days: for
/// each, the mean and the daily histogram (24 bins) of the last that many days and the weekly
/// histogram (168 bins) of the last `⌈days / 7⌉` weeks ([`chronomap_core::recent::RecentHistogram`]: the current period, however
/// far it has got, and the whole ones before it). A routine that drifts (a door opened less as
/// the weeks go by) gives them weight at the rolling origins; one that does not, none. A hard
/// window is the simplest forgetting of concept drift (Gama et al. 2014, §3.2); learning
/// online, it forgets as the full histograms cannot.
pub const RECENT_DAYS: [usize; 4] = [7, 14, 28, 56];

/// The longest memory of a drift candidate the command line and Python accept, in days (ten
/// years; a weekly histogram of that many days is 522 periods of 168 bins).
pub const MAX_RECENT_DAYS: usize = 3650;

/// The fractions of the training span at which the rolling origins lie: `origins` of them,
/// evenly from 40 % to 90 % (one origin: 75 %, the hold-out of the originals).
pub fn origin_fractions(origins: usize) -> Vec<f64> {
    match origins {
        0 => Vec::new(),
        1 => vec![0.75],
        n => (0..n)
            .map(|k| 0.4 + 0.5 * k as f64 / (n - 1) as f64)
            .collect(),
    }
}

/// Fits every candidate on `times`/`values`. FreMEn candidates of several orders share one
/// spectrum (fitted once at the largest order, then [`AnyModel::set_order`]); a candidate that
/// cannot be fitted is `None`.
pub fn fit_candidates(
    candidates: &[ModelSpec],
    times: &[f64],
    values: &[f64],
    options: &FitOptions,
) -> Vec<Option<AnyModel>> {
    let max_fremen = candidates
        .iter()
        .filter_map(|c| match c {
            ModelSpec::Fremen(OrderSpec::Fixed(k)) => Some(*k),
            _ => None,
        })
        .max();
    let fremen = max_fremen.and_then(|k| {
        ModelSpec::Fremen(OrderSpec::Fixed(k))
            .fit(times, values, options)
            .ok()
            .map(|f| f.model)
    });
    candidates
        .iter()
        .map(|candidate| match candidate {
            ModelSpec::Fremen(OrderSpec::Fixed(k)) => fremen.clone().map(|mut m| {
                m.set_order(*k);
                m
            }),
            other => other.fit(times, values, options).ok().map(|f| f.model),
        })
        .collect()
}

/// The out-of-sample predictions of rolling origins over one series, as a stacking problem:
/// for each origin (a fraction of the span, [`origin_fractions`]), every candidate is fitted on
/// the observations before it and predicts every observation from it to the end. A candidate
/// that cannot be fitted at an origin predicts the mean of the observations before it there.
/// Returns the problem and the number of origins that had data on both sides.
pub fn rolling_origin_problem(
    candidates: &[ModelSpec],
    times: &[f64],
    values: &[f64],
    options: &FitOptions,
) -> (StackingProblem, usize) {
    let mut problem = StackingProblem::new(candidates.len());
    let mut used = 0;
    let (Some(&first), Some(&last)) = (times.first(), times.last()) else {
        return (problem, 0);
    };
    let mut predictions = vec![Vec::new(); candidates.len()];
    for fraction in origin_fractions(options.origins) {
        let origin = first + fraction * (last - first);
        let split = times.partition_point(|&t| t < origin);
        if split == 0 || split == times.len() {
            continue;
        }
        let (before_t, before_v) = (&times[..split], &values[..split]);
        let after_t = &times[split..];
        let mean = before_v.iter().sum::<f64>() / before_v.len() as f64;
        let models = fit_candidates(candidates, before_t, before_v, options);
        for (row, model) in predictions.iter_mut().zip(&models) {
            row.resize(after_t.len(), 0.0);
            match model {
                Some(m) => m.predict_into(after_t, row),
                None => row.fill(mean),
            }
        }
        let rows: Vec<&[f64]> = predictions.iter().map(Vec::as_slice).collect();
        problem.add(&rows, &values[split..]);
        used += 1;
    }
    (problem, used)
}

/// Weights below this are dropped (and the rest renormalised) so that a stacked model keeps
/// only the members that matter.
pub const MIN_WEIGHT: f64 = 1e-4;

/// A combination must predict better than its best member by this relative margin (of the
/// Brier score) to be kept as one; otherwise the best member alone is chosen.
pub const PARSIMONY_TOLERANCE: f64 = 1e-9;

/// How [`StackedModel`]'s weights were chosen.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StackSelection {
    /// The members kept and their weights, heaviest first.
    pub weights: Vec<(ModelSpec, f64)>,
    /// Out-of-sample error (by the fit's criterion, Brier) of every candidate alone.
    pub errors: Vec<(ModelSpec, f64)>,
    /// Out-of-sample error of the combination.
    pub combined_error: f64,
    /// Origins that had data before and after them.
    pub origins: usize,
    /// Out-of-sample predictions per candidate, over all origins.
    pub held_back: usize,
}

/// Solves the stacking problem over `candidates` and describes the solution: the weights (those
/// of at least [`MIN_WEIGHT`], renormalised) with their candidates, and every candidate's own
/// out-of-sample error.
pub fn choose_weights(
    candidates: &[ModelSpec],
    problem: &StackingProblem,
    origins: usize,
) -> StackSelection {
    let mut raw = problem.solve();
    // A combination that predicts no better than its best member is that member: when the
    // candidates cannot be told apart (two observations, a constant series) the solver keeps
    // its equal-weight start point, and a file of 20 identical members helps nobody. Ties go to
    // the earliest, simplest candidate.
    let best_single = (0..candidates.len())
        .map(|i| (problem.candidate_error(i), i))
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    if let Some((best_error, best)) = best_single
        && problem.error(&raw) >= best_error * (1.0 - PARSIMONY_TOLERANCE)
    {
        raw = vec![0.0; candidates.len()];
        raw[best] = 1.0;
    }
    // Candidates that predicted alike at every origin (a window longer than the data is the
    // full histogram) cannot be told apart either: the solver splits their weight evenly, and
    // it goes to the earliest of them instead.
    for later in 1..raw.len() {
        if raw[later] > 0.0
            && let Some(first) = (0..later).find(|&i| problem.predicted_alike(i, later))
        {
            raw[first] += raw[later];
            raw[later] = 0.0;
        }
    }
    let kept: f64 = raw.iter().filter(|&&w| w >= MIN_WEIGHT).sum();
    let mut full = vec![0.0; raw.len()];
    let mut weights = Vec::new();
    for (i, &w) in raw.iter().enumerate() {
        if w >= MIN_WEIGHT {
            full[i] = w / kept;
            weights.push((candidates[i].clone(), w / kept));
        }
    }
    weights.sort_by(|a, b| b.1.total_cmp(&a.1));
    StackSelection {
        errors: candidates
            .iter()
            .enumerate()
            .map(|(i, c)| (c.clone(), problem.candidate_error(i)))
            .collect(),
        combined_error: problem.error(&full),
        weights,
        origins,
        held_back: problem.count(),
    }
}

/// `auto` on one series: rolling-origin stacking of [`stack_candidates`], members refitted on
/// everything.
///
/// # Errors
/// If no origin has data on both sides (too few observations), or no member can be refitted.
pub fn fit_stacked(
    times: &[f64],
    values: &[f64],
    options: &FitOptions,
) -> Result<(StackedModel, StackSelection), BuildError> {
    // Orders above the number of candidate periods would repeat the largest one (and an
    // absurd --max-order would make the weights' statistics quadratic in it).
    let candidates = stack_candidates(
        options.max_order.min(options.periods.len()),
        &options.recent_days,
    );
    let (problem, origins) = rolling_origin_problem(&candidates, times, values, options);
    if origins == 0 {
        return Err(BuildError::NotEnoughData(format!(
            "{} observations cannot be split at rolling origins (40–90 % of their time span)",
            times.len()
        )));
    }
    let selection = choose_weights(&candidates, &problem, origins);
    let model = StackedModel::refit(&selection.weights, times, values, options)?;
    Ok((model, selection))
}

/// A weighted average of models' predictions: `p(t) = Σ_i w_i p_i(t)` with `w ≥ 0`,
/// `Σ w = 1` — what `auto` fits ([module docs](self)). Every member has seen the same
/// observations; observing adds them to every member.
#[derive(Clone, Debug, Serialize)]
pub struct StackedModel {
    members: Vec<AnyModel>,
    weights: Vec<f64>,
}

impl StackedModel {
    /// A combination of `members` with `weights`.
    ///
    /// # Errors
    /// [`ConfigError::OutOfRange`] (field `stack`) if there are no members, the counts
    /// differ, a weight is negative or not finite, the weights do not sum to 1, a member is
    /// itself a stacked model, or the members have seen different observations.
    pub fn new(members: Vec<AnyModel>, weights: Vec<f64>) -> Result<Self, BuildError> {
        let model = StackedModel { members, weights };
        if model.is_consistent() {
            Ok(model)
        } else {
            Err(BuildError::Config(ConfigError::OutOfRange {
                name: "stack",
                value: format!(
                    "{} members with weights {:?}",
                    model.members.len(),
                    model.weights
                ),
                expected: "members that are not stacks and have seen the same observations, \
                           one non-negative weight each, summing to 1",
            }))
        }
    }

    /// Fits each spec of `weights` on all the data and combines them.
    ///
    /// # Errors
    /// If a member cannot be fitted, or as [`StackedModel::new`].
    pub fn refit(
        weights: &[(ModelSpec, f64)],
        times: &[f64],
        values: &[f64],
        options: &FitOptions,
    ) -> Result<Self, BuildError> {
        let specs: Vec<ModelSpec> = weights.iter().map(|(s, _)| s.clone()).collect();
        let members = fit_candidates(&specs, times, values, options)
            .into_iter()
            .zip(&specs)
            .map(|(m, s)| {
                m.ok_or_else(|| {
                    BuildError::NotEnoughData(format!("{s} cannot be fitted on all the data"))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        StackedModel::new(members, weights.iter().map(|(_, w)| *w).collect())
    }

    /// The members and their weights.
    pub fn members(&self) -> impl Iterator<Item = (&AnyModel, f64)> {
        self.members.iter().zip(self.weights.iter().copied())
    }

    /// Checks the invariants (for models read from files).
    pub fn is_consistent(&self) -> bool {
        let sum: f64 = self.weights.iter().sum();
        !self.members.is_empty()
            && self.members.len() == self.weights.len()
            && self.weights.iter().all(|w| w.is_finite() && *w >= 0.0)
            && (sum - 1.0).abs() < 1e-9
            && self
                .members
                .iter()
                .all(|m| !matches!(m, AnyModel::Stack(_)) && m.is_consistent())
            && self
                .members
                .windows(2)
                .all(|pair| pair[0].span() == pair[1].span())
    }
}

impl TemporalModel for StackedModel {
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        // Validate once, so that no member can fail after another has changed.
        self.span().validate(times, values)?;
        for member in &mut self.members {
            member.observe(times, values)?;
        }
        Ok(())
    }

    fn predict(&self, time: f64) -> f64 {
        let p: f64 = self.members().map(|(m, w)| w * m.predict(time)).sum();
        p.clamp(0.0, 1.0)
    }

    fn predict_into(&self, times: &[f64], out: &mut [f64]) {
        assert_eq!(times.len(), out.len(), "predict_into: length mismatch");
        out.fill(0.0);
        let mut buffer = vec![0.0; times.len()];
        for (member, weight) in self.members() {
            member.predict_into(times, &mut buffer);
            for (o, p) in out.iter_mut().zip(&buffer) {
                *o += weight * p;
            }
        }
        for o in out.iter_mut() {
            *o = o.clamp(0.0, 1.0);
        }
    }

    fn span(&self) -> ObservedSpan {
        self.members
            .first()
            .map_or_else(ObservedSpan::default, TemporalModel::span)
    }
}

thread_local! {
    /// Stacked models being deserialised on this thread: a file may not nest them (a hostile
    /// file nesting thousands would otherwise overflow the stack).
    static DESERIALISING: Cell<bool> = const { Cell::new(false) };
}

impl<'de> Deserialize<'de> for StackedModel {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        struct Raw {
            members: Vec<AnyModel>,
            weights: Vec<f64>,
        }
        struct Reset;
        impl Drop for Reset {
            fn drop(&mut self) {
                DESERIALISING.with(|d| d.set(false));
            }
        }
        if DESERIALISING.with(|d| d.replace(true)) {
            return Err(serde::de::Error::custom(
                "a stacked model inside a stacked model",
            ));
        }
        let _reset = Reset;
        let raw = Raw::deserialize(deserializer)?;
        Ok(StackedModel {
            members: raw.members,
            weights: raw.weights,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_core::conformance::check_temporal_model;

    /// A door open 9:00–17:00 on weekdays, seen every 10 minutes for `weeks` weeks, each
    /// observation flipped with probability 1/7 (so that no single rhythm is exact).
    fn office(weeks: usize) -> (Vec<f64>, Vec<f64>) {
        let mut rng = chronomap_core::rng::Xoshiro256StarStar::seed_from_u64(3);
        let times: Vec<f64> = (0..weeks * 7 * 144).map(|i| 600.0 * i as f64).collect();
        let values = times
            .iter()
            .map(|&t| {
                let hour = (t % DAY) / 3600.0;
                let weekday = (t % WEEK) / DAY < 5.0;
                let open = weekday && (9.0..17.0).contains(&hour);
                f64::from(u8::from(open != rng.bernoulli(1.0 / 7.0)))
            })
            .collect();
        (times, values)
    }

    #[test]
    fn origins_lie_from_40_to_90_percent() {
        assert_eq!(origin_fractions(1), [0.75]);
        let six = origin_fractions(6);
        assert_eq!(six.len(), 6);
        assert!((six[0] - 0.4).abs() < 1e-15 && (six[5] - 0.9).abs() < 1e-15);
        assert!((six[1] - 0.5).abs() < 1e-15);
    }

    #[test]
    fn auto_weighs_the_rhythm_it_sees_and_beats_every_candidate_out_of_sample() {
        let (times, values) = office(6);
        let options = FitOptions::default();
        let (model, selection) = fit_stacked(&times, &values, &options).unwrap();
        assert_eq!(selection.origins, 6);
        let best_single = selection
            .errors
            .iter()
            .map(|(_, e)| *e)
            .fold(f64::INFINITY, f64::min);
        assert!(selection.combined_error <= best_single + 1e-12);
        // Weekdays differ from weekends: the weekly histograms carry most of the weight,
        // and the daily-only ones (which cannot tell Saturday from Monday) little.
        let weekly: f64 = selection
            .weights
            .iter()
            .filter(|(s, _)| matches!(s, ModelSpec::Histogram { period_secs, .. } if *period_secs == WEEK))
            .map(|(_, w)| w)
            .sum();
        assert!(weekly > 0.5, "{:?}", selection.weights);
        // Working hours of the next first weekday (open but for the flips: 6/7) and of the
        // next weekend day (closed but for the flips: 1/7), averaged over 9:00–17:00.
        let working_hours = |day: f64| -> f64 {
            let times: Vec<f64> = (0..48)
                .map(|i| 6.0 * WEEK + day * DAY + 9.0 * 3600.0 + 600.0 * i as f64)
                .collect();
            model.predict_many(&times).iter().sum::<f64>() / 48.0
        };
        // (A model of the day alone would say (5·6/7 + 2·1/7)/7 ≈ 0.65 for both; the mean and
        // short-term memory in the mix pull both a little towards the overall rate.)
        let (weekday, weekend) = (working_hours(0.0), working_hours(5.0));
        assert!((weekday - 6.0 / 7.0).abs() < 0.07, "{weekday}");
        assert!((weekend - 1.0 / 7.0).abs() < 0.07, "{weekend}");
        let sum: f64 = model.members().map(|(_, w)| w).sum();
        assert!((sum - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_door_opened_less_week_by_week_gives_the_drift_candidates_weight() {
        // Working hours of weekdays, seen every 10 minutes for 8 weeks: open with probability
        // 0.9 in week 1, 0.1 less each week (0.2 in week 8, 0.1 in the week after).
        let mut rng = chronomap_core::rng::Xoshiro256StarStar::seed_from_u64(5);
        let times: Vec<f64> = (0..8 * 7 * 144).map(|i| 600.0 * i as f64).collect();
        let working =
            |t: f64| (t % WEEK) / DAY < 5.0 && (9.0..17.0).contains(&((t % DAY) / 3600.0));
        let values: Vec<f64> = times
            .iter()
            .map(|&t| {
                let rate = 0.9 - 0.1 * (t / WEEK).floor();
                f64::from(u8::from(working(t) && rng.bernoulli(rate)))
            })
            .collect();
        let next_week: Vec<f64> = (0..7 * 144)
            .map(|i| 8.0 * WEEK + 600.0 * i as f64)
            .filter(|&t| working(t))
            .collect();
        let level = |options: &FitOptions| {
            let (model, selection) = fit_stacked(&times, &values, options).unwrap();
            let p = model.predict_many(&next_week);
            (p.iter().sum::<f64>() / p.len() as f64, selection)
        };
        let (with, selection) = level(&FitOptions::default());
        let (without, _) = level(&FitOptions {
            recent_days: Vec::new(),
            ..FitOptions::default()
        });
        let recent: f64 = selection
            .weights
            .iter()
            .filter(|(s, _)| matches!(s, ModelSpec::Recent { .. }))
            .map(|(_, w)| w)
            .sum();
        // The eight weeks average 0.55 and the truth next week is 0.1. Without forgetting the
        // stack predicts 0.31 (measured: the origins already prefer what predicts low), with the
        // windows 0.18, the last week's mean alone carrying half of the weight.
        assert!(recent > 0.5, "{:?}", selection.weights);
        assert!(without > 0.25, "{without}");
        assert!(with < 0.2, "{with} ({:?})", selection.weights);
    }

    #[test]
    fn a_stacked_model_keeps_the_temporal_model_contract() {
        let (times, values) = office(1);
        let make = || {
            let members = vec![
                ModelSpec::Mean.online_model().unwrap(),
                "hist:24:86400"
                    .parse::<ModelSpec>()
                    .unwrap()
                    .online_model()
                    .unwrap(),
                "fremen:2"
                    .parse::<ModelSpec>()
                    .unwrap()
                    .online_model()
                    .unwrap(),
            ];
            StackedModel::new(members, vec![0.2, 0.3, 0.5]).unwrap()
        };
        check_temporal_model(make, &times[..500], &values[..500]);
    }

    #[test]
    fn inconsistent_stacks_are_refused() {
        let member = || ModelSpec::Mean.online_model().unwrap();
        assert!(StackedModel::new(vec![], vec![]).is_err());
        let err = StackedModel::new(vec![member()], vec![0.5]).unwrap_err();
        assert!(
            err.to_string()
                .starts_with("stack = 1 members with weights [0.5] is out of range"),
            "{err}"
        );
        assert!(StackedModel::new(vec![member(), member()], vec![1.5, -0.5]).is_err());
        assert!(StackedModel::new(vec![member()], vec![f64::NAN]).is_err());
        let mut seen = member();
        seen.observe(&[0.0], &[1.0]).unwrap();
        assert!(StackedModel::new(vec![seen, member()], vec![0.5, 0.5]).is_err());
        let inner = AnyModel::Stack(Box::new(
            StackedModel::new(vec![member()], vec![1.0]).unwrap(),
        ));
        assert!(StackedModel::new(vec![inner], vec![1.0]).is_err());
    }

    #[test]
    fn fremen_orders_are_capped_at_the_number_of_periods() {
        let (times, values) = office(1);
        let options = FitOptions {
            max_order: 1_000_000,
            ..FitOptions::default()
        };
        let (_, selection) = fit_stacked(&times, &values, &options).unwrap();
        let periods = options.periods.len();
        assert_eq!(
            selection.errors.len(),
            stack_candidates(periods, &RECENT_DAYS).len()
        );
    }

    #[test]
    fn candidates_that_cannot_be_told_apart_give_the_simplest_alone() {
        // Two observations: at every origin each candidate predicts the one value before it,
        // so no combination beats a single member, and the first (the mean) is chosen.
        let (model, selection) =
            fit_stacked(&[0.0, 3600.0], &[1.0, 1.0], &FitOptions::default()).unwrap();
        assert_eq!(selection.weights, vec![(ModelSpec::Mean, 1.0)]);
        assert_eq!(model.members().count(), 1);
        // A combination that does help is kept (the office week of the test above).
        let (times, values) = office(4);
        let (_, selection) = fit_stacked(&times, &values, &FitOptions::default()).unwrap();
        assert!(selection.weights.len() > 1, "{:?}", selection.weights);
    }

    #[test]
    fn too_short_a_series_is_not_enough_data() {
        let err = fit_stacked(&[0.0], &[1.0], &FitOptions::default()).unwrap_err();
        assert!(matches!(err, BuildError::NotEnoughData(_)), "{err}");
    }
}
