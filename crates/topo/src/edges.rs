//! Temporal models of the edges of a topological map: when a navigation action succeeds and
//! how long it takes ([Fentanes 2015] §III–IV).
//!
//! Each edge gets two models: the probability that a traversal succeeds, `p_e(t)`, from all its
//! attempts, and the duration of successful traversals, from those. Both are FreMEn models
//! ([Fentanes 2015] eqs. (1)–(2)). The original chooses each edge's order on the most recent part
//! of its history (a chronological hold-out, scored like eq. (3)); durations still do (order 0 is
//! the static mean, so an edge whose outcomes are not periodic falls back to a static model).
//! Success models, unless their order is fixed, are instead weighted averages of FreMEn of orders
//! 0..=`max_order` with weights that all edges share, fitted by rolling-origin cross-validation over every
//! edge's history ([`success_candidates`], [`chronomap_models::stack`]): on the Witham Wharf
//! splits this beats the per-edge choice, which overfits the few attempts of most edges
//! (`docs/accuracy.md`). Durations are not in `[0, 1]`: they are modelled as fractions of the
//! edge's longest training duration, and scaled back.
//!
//! Success models also carry FreMEn's persistence term ([Krajník 2017] §III-D, eqs. (12)–(13)): the
//! outcome of the latest attempt persists for a while. On the Witham Wharf data this is what
//! predicts later weeks: a closed door makes the robot fail again and again for hours, at times
//! of day that change from week to week (see `topo eval` in the README for the numbers). A model
//! kept up to date with [`EdgeModels::observe`] uses it; far from the latest attempt the
//! prediction is the periodic model's.
//!
//! Robots in the field need more than the model (their users asked for this: an edge predicted
//! at probability 0 is never tried again, and a few unlucky attempts should not condemn an
//! edge): predictions are shrunk towards a prior with the weight of a few pseudo-attempts, edges
//! with few attempts use the shrunk mean only, and success probabilities never go below a floor.

use serde::{Deserialize, Serialize};

use crate::duration_intervals::{DurationSpread, DurationSpreadWithoutAdaptation, residual};
use crate::map::{TopoError, TopoMap};
use chronomap_core::TimeSeries;
use chronomap_core::calibration::{
    CURVE_LEVELS, Calibration, Coverage, DEFAULT_BINS, ReliabilityBin,
};
use chronomap_core::error::BuildError;
use chronomap_core::model::TemporalModel;
use chronomap_core::select::Criterion;
use chronomap_core::stacking::StackingProblem;
use chronomap_models::spec::{AnyModel, FitOptions, ModelSpec, OrderSpec};
use chronomap_models::stack::{StackedModel, choose_weights, rolling_origin_problem};

/// One traversal attempt of an edge.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Attempt {
    /// When the attempt started (seconds).
    pub time: f64,
    /// How long it took (seconds, ≥ 0).
    pub duration_secs: f64,
    /// Whether the robot reached the edge's target.
    pub success: bool,
}

/// A topological map and every recorded attempt to traverse each of its edges: what the edge
/// models of [Fentanes 2015] §III learn from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EdgeStatistics {
    /// The map: the nodes and edges.
    pub map: TopoMap,
    /// `attempts[i]` are the attempts on `map.edges()[i]`, in time order.
    pub attempts: Vec<Vec<Attempt>>,
}

impl EdgeStatistics {
    /// Number of attempts over all edges.
    pub fn total_attempts(&self) -> usize {
        self.attempts.iter().map(Vec::len).sum()
    }

    /// The attempts on the edge with id `edge_id`, if the map has that edge.
    pub fn attempts_of(&self, edge_id: &str) -> Option<&[Attempt]> {
        let index = self.map.edges().iter().position(|e| e.id == edge_id)?;
        self.attempts.get(index).map(Vec::as_slice)
    }

    /// Fraction of successful attempts on edge `edge` (an index into `map.edges()`); `None` if
    /// it has no attempt (or no such edge).
    pub fn success_rate(&self, edge: usize) -> Option<f64> {
        let attempts = self.attempts.get(edge).filter(|a| !a.is_empty())?;
        let successes = attempts.iter().filter(|a| a.success).count();
        Some(successes as f64 / attempts.len() as f64)
    }

    /// Earliest and latest attempt time over all edges; `None` without attempts.
    pub fn time_span(&self) -> Option<(f64, f64)> {
        self.attempts
            .iter()
            .flatten()
            .map(|a| a.time)
            .fold(None, |span, t| match span {
                None => Some((t, t)),
                Some((lo, hi)) => Some((f64::min(lo, t), f64::max(hi, t))),
            })
    }

    /// Outcomes of the attempts on edge `edge` as a binary time series (1 = success), ready
    /// for [`TemporalModel::observe`]. Empty if the
    /// edge has no attempt or does not exist.
    ///
    /// The series satisfies the [observation contract](chronomap_core::observe) when the
    /// attempts do (times finite, `>= 0` and in order), as those the edge-file readers of
    /// `chronomap-io` return always do.
    pub fn success_series(&self, edge: usize) -> TimeSeries {
        let attempts = self.attempts.get(edge).map_or(&[][..], Vec::as_slice);
        TimeSeries {
            times: attempts.iter().map(|a| a.time).collect(),
            values: attempts
                .iter()
                .map(|a| f64::from(u8::from(a.success)))
                .collect(),
        }
    }

    /// Splits the attempts chronologically: `before` has those with `time < split`, `after`
    /// those with `time >= split`. Both keep the whole map (every node and edge), so an edge
    /// may have no attempt in one of them. A NaN `split` puts every attempt in `after`.
    ///
    /// ```
    /// use chronomap_topo::edges::{Attempt, EdgeStatistics};
    /// use chronomap_topo::map::TopoMap;
    ///
    /// let mut map = TopoMap::new();
    /// map.add_node("A", None)?;
    /// map.add_node("B", None)?;
    /// map.add_edge("A_B", "A", "B")?;
    /// let attempt = |time| Attempt { time, duration_secs: 5.0, success: true };
    /// let stats = EdgeStatistics { map, attempts: vec![vec![attempt(10.0), attempt(20.0)]] };
    /// let (before, after) = stats.split_at(20.0);
    /// assert_eq!((before.total_attempts(), after.total_attempts()), (1, 1));
    /// assert_eq!(after.attempts[0][0].time, 20.0);
    /// # Ok::<(), chronomap_topo::map::TopoError>(())
    /// ```
    pub fn split_at(&self, split: f64) -> (EdgeStatistics, EdgeStatistics) {
        let (before, after) = self
            .attempts
            .iter()
            .map(|edge| edge.iter().partition(|a| a.time < split))
            .unzip();
        (
            EdgeStatistics {
                map: self.map.clone(),
                attempts: before,
            },
            EdgeStatistics {
                map: self.map.clone(),
                attempts: after,
            },
        )
    }
}

/// How edge models are fitted and queried.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EdgeModelConfig {
    /// Edges with fewer attempts use the (shrunk) static mean only.
    pub min_attempts: usize,
    /// Prior success probability of an edge.
    pub prior_success: f64,
    /// Weight of the prior, in pseudo-attempts.
    pub prior_attempts: f64,
    /// Success probabilities never go below this.
    pub floor: f64,
    /// Fit periodic (FreMEn) models; `false` = static means only.
    pub periodic: bool,
    /// Add the persistence of the latest outcome to success models ([Krajník 2017] eqs. (12)–(13)).
    pub persistence: bool,
    /// Fraction of each edge's time span held back to choose the orders.
    pub holdout: f64,
    /// Largest order tried.
    pub max_order: usize,
    /// The order of every success model (`None`: chosen per edge on the hold-out). [Fentanes 2015]:
    /// "typically, m = 2".
    pub success_order: Option<usize>,
    /// Duration of edges that have never succeeded (seconds); `None`: the median over edges.
    pub default_duration_secs: Option<f64>,
}

impl Default for EdgeModelConfig {
    fn default() -> Self {
        EdgeModelConfig {
            min_attempts: 10,
            prior_success: 0.9,
            prior_attempts: 2.0,
            floor: 0.05,
            periodic: true,
            persistence: true,
            holdout: 0.25,
            max_order: 10,
            success_order: None,
            default_duration_secs: None,
        }
    }
}

/// Scores of edge models on later attempts ([`EdgeModels::evaluate`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EdgeEvaluation {
    /// Mean squared error of the success probabilities over all attempts.
    pub success_brier: f64,
    /// Mean squared error of the expected durations over successful attempts (s²).
    pub duration_mse: f64,
    /// The Brier score of the static per-edge success rates.
    pub static_success_brier: f64,
    /// The squared error of the static per-edge mean durations (s²).
    pub static_duration_mse: f64,
    /// Attempts scored.
    pub attempts: usize,
    /// Successful attempts among them (those whose durations are scored).
    pub successes: usize,
    /// Expected calibration error of the success probabilities
    /// ([`chronomap_core::calibration`], 10 equal-width bins).
    #[serde(default)]
    pub success_ece: f64,
    /// Reliability term of the success Brier score's decomposition (Murphy 1973).
    #[serde(default)]
    pub success_reliability: f64,
    /// Expected calibration error of the static per-edge success rates.
    #[serde(default)]
    pub static_success_ece: f64,
    /// Share of successful durations inside their interval of nominal coverage
    /// [`EVALUATION_COVERAGE`] ([`EdgeModels::duration_interval`]; 0 without intervals).
    #[serde(default)]
    pub duration_coverage: f64,
    /// Mean width of those intervals (s).
    #[serde(default)]
    pub duration_interval_width: f64,
    /// Successful durations shorter than their interval.
    #[serde(default)]
    pub duration_below: usize,
    /// Successful durations longer than their interval.
    #[serde(default)]
    pub duration_above: usize,
    /// The reliability bins of the success probabilities (all attempts, [`DEFAULT_BINS`]).
    #[serde(default)]
    pub success_bins: Vec<ReliabilityBin>,
    /// Those of the static per-edge success rates.
    #[serde(default)]
    pub static_success_bins: Vec<ReliabilityBin>,
    /// How the duration intervals of every nominal coverage of
    /// [`CURVE_LEVELS`] held the successful durations (empty without intervals).
    #[serde(default)]
    pub duration_curve: Vec<(f64, Coverage)>,
}

/// Nominal coverage of the duration intervals [`EdgeModels::evaluate`] scores: 90 %.
pub const EVALUATION_COVERAGE: f64 = 0.9;

/// Why [`EdgeModels::observe_all`] learned nothing.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ObserveAllError {
    /// Not one list of attempts per edge.
    #[error("{lists} attempt lists for {edges} edges")]
    Lists {
        /// Lists given.
        lists: usize,
        /// Edges of the map.
        edges: usize,
    },
    /// An attempt cannot be learned.
    #[error("attempt {} of edge {edge}: {error}", position + 1)]
    Attempt {
        /// The edge.
        edge: usize,
        /// Its position in the edge's list, from 0.
        position: usize,
        /// Why.
        error: chronomap_core::ObservationError,
    },
}

/// The intervals of every level of [`CURVE_LEVELS`] predicted for successful durations, and
/// the durations.
#[derive(Default)]
struct DurationIntervals {
    /// Per level of [`CURVE_LEVELS`], the interval of each duration.
    intervals: Vec<Vec<(f64, f64)>>,
    /// The durations (s).
    durations: Vec<f64>,
    /// Whether some duration had no interval (models without a spread).
    missing: bool,
}

impl DurationIntervals {
    /// The intervals `interval(edge, expected, level)` of every `(edge, expected, duration)`.
    fn of(
        traversals: &[(usize, f64, f64)],
        interval: impl Fn(usize, f64, f64) -> Option<(f64, f64)>,
    ) -> Self {
        let mut all = DurationIntervals::default();
        for &(edge, expected, duration) in traversals {
            all.push(duration, |level| interval(edge, expected, level));
        }
        all
    }

    /// Adds a duration and its intervals `interval(level)`.
    fn push(&mut self, duration: f64, interval: impl Fn(f64) -> Option<(f64, f64)>) {
        self.intervals.resize(CURVE_LEVELS.len(), Vec::new());
        for (level, list) in CURVE_LEVELS.iter().zip(&mut self.intervals) {
            match interval(*level) {
                Some(i) => list.push(i),
                None => self.missing = true,
            }
        }
        self.durations.push(duration);
    }
}

/// Every attempt of `test` (one list per edge, each in its own order) with its edge, merged in
/// the order of their times (ties: the lower edge first); a list out of order keeps its own
/// order, for [`EdgeModels::observe`] to refuse.
fn in_time_order(test: &[Vec<Attempt>]) -> Vec<(usize, &Attempt)> {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    // (time of the list's next attempt, edge, position in the list), smallest first.
    let mut heads: BinaryHeap<Reverse<(OrderedTime, usize, usize)>> = test
        .iter()
        .enumerate()
        .filter_map(|(e, list)| Some(Reverse((OrderedTime(list.first()?.time), e, 0))))
        .collect();
    let mut merged = Vec::with_capacity(test.iter().map(Vec::len).sum());
    while let Some(Reverse((_, edge, i))) = heads.pop() {
        merged.push((edge, &test[edge][i]));
        if let Some(next) = test[edge].get(i + 1) {
            heads.push(Reverse((OrderedTime(next.time), edge, i + 1)));
        }
    }
    merged
}

/// A time ordered by [`f64::total_cmp`].
#[derive(Clone, Copy, PartialEq)]
struct OrderedTime(f64);

impl Eq for OrderedTime {}

impl PartialOrd for OrderedTime {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for OrderedTime {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

impl EdgeEvaluation {
    /// Sets the coverage curve of the duration intervals and its headline point at
    /// [`EVALUATION_COVERAGE`] (nothing when some duration had no interval).
    fn score_durations(&mut self, all: &DurationIntervals) {
        if all.missing {
            return;
        }
        self.duration_curve = CURVE_LEVELS
            .iter()
            .enumerate()
            .map(|(i, &level)| {
                let intervals = all.intervals.get(i).map_or(&[][..], Vec::as_slice);
                (level, Coverage::of(intervals, &all.durations))
            })
            .collect();
        // CURVE_LEVELS holds EVALUATION_COVERAGE: the headline is its point of the curve.
        let coverage = self
            .duration_curve
            .iter()
            .find(|(level, _)| *level == EVALUATION_COVERAGE)
            .map(|(_, c)| *c)
            .unwrap_or_default();
        self.duration_coverage = coverage.coverage;
        self.duration_interval_width = coverage.mean_width;
        self.duration_below = coverage.below;
        self.duration_above = coverage.above;
    }

    /// Sets the success scores from the model's and the static rates' predictions of every
    /// attempt, and the attempts' outcomes.
    fn score_success(&mut self, model: &[f64], fixed: &[f64], outcomes: &[f64]) {
        let model = Calibration::of(model, outcomes, DEFAULT_BINS);
        let fixed = Calibration::of(fixed, outcomes, DEFAULT_BINS);
        self.success_brier = model.brier;
        self.static_success_brier = fixed.brier;
        self.success_ece = model.ece;
        self.success_reliability = model.reliability;
        self.static_success_ece = fixed.ece;
        self.success_bins = model.bins;
        self.static_success_bins = fixed.bins;
    }
}

/// The models of one edge.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EdgeModel {
    /// Number of attempts the models learned from.
    pub attempts: usize,
    /// Number of successful ones.
    pub successes: usize,
    /// `p_e(t)` before shrinking (`None` with fewer than `min_attempts` attempts).
    success: Option<AnyModel>,
    /// Successful durations as fractions of `duration_scale`.
    duration: Option<AnyModel>,
    duration_scale: f64,
    mean_duration_secs: Option<f64>,
    /// Time of the latest attempt seen (fitted or observed).
    last_time: Option<f64>,
}

impl EdgeModel {
    /// The model of the success probability (`None`: too few attempts, the static rate is used).
    pub fn success_model(&self) -> Option<&AnyModel> {
        self.success.as_ref()
    }

    /// The model of successful durations, as fractions of [`EdgeModel::duration_scale`].
    pub fn duration_model(&self) -> Option<&AnyModel> {
        self.duration.as_ref()
    }

    /// The longest successful training duration (seconds): the unit of the duration model.
    pub fn duration_scale(&self) -> f64 {
        self.duration_scale
    }

    /// The mean successful duration (seconds), if any attempt succeeded.
    pub fn mean_duration_secs(&self) -> Option<f64> {
        self.mean_duration_secs
    }
}

/// Models of every edge of a map.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct EdgeModels {
    map: TopoMap,
    config: EdgeModelConfig,
    edges: Vec<EdgeModel>,
    default_duration_secs: f64,
    /// The spread of durations around the models (empty in files written before it existed,
    /// read through [`EdgeModelsWithoutSpread`]: no intervals then).
    duration_spread: DurationSpread,
}

/// The layout of [`EdgeModels`] in files written before they kept the spread of their
/// durations: read as models without duration intervals.
#[derive(Deserialize)]
pub struct EdgeModelsWithoutSpread {
    map: TopoMap,
    config: EdgeModelConfig,
    edges: Vec<EdgeModel>,
    default_duration_secs: f64,
}

impl From<EdgeModelsWithoutSpread> for EdgeModels {
    fn from(old: EdgeModelsWithoutSpread) -> Self {
        EdgeModels {
            map: old.map,
            config: old.config,
            edges: old.edges,
            default_duration_secs: old.default_duration_secs,
            duration_spread: DurationSpread::default(),
        }
    }
}

/// The layout of [`EdgeModels`] in files written after they kept the spread of their durations
/// and before the spread adapted online: read as models whose spread has not adapted yet.
#[derive(Deserialize)]
pub struct EdgeModelsWithoutAdaptation {
    map: TopoMap,
    config: EdgeModelConfig,
    edges: Vec<EdgeModel>,
    default_duration_secs: f64,
    duration_spread: DurationSpreadWithoutAdaptation,
}

impl From<EdgeModelsWithoutAdaptation> for EdgeModels {
    fn from(old: EdgeModelsWithoutAdaptation) -> Self {
        EdgeModels {
            map: old.map,
            config: old.config,
            edges: old.edges,
            default_duration_secs: old.default_duration_secs,
            duration_spread: old.duration_spread.into(),
        }
    }
}

/// The model of success probabilities the configuration asks for.
fn success_spec(config: &EdgeModelConfig) -> ModelSpec {
    let order = config
        .success_order
        .map_or(OrderSpec::Auto, OrderSpec::Fixed);
    match (config.periodic, config.persistence) {
        (true, true) => ModelSpec::Persistence(order),
        (true, false) => ModelSpec::Fremen(order),
        (false, true) => ModelSpec::Persistence(OrderSpec::Fixed(0)),
        (false, false) => ModelSpec::Mean,
    }
}

/// The model of durations: persistence does not help there (a slow traversal says little
/// about the next one).
/// The duration model of successful traversals `good` (`None` with fewer than
/// `min_attempts` or no positive duration), the scale its values are fractions of, and the mean
/// duration (`None` without successes).
fn fit_duration(
    good: &[&Attempt],
    config: &EdgeModelConfig,
) -> Result<(Option<AnyModel>, f64, Option<f64>), BuildError> {
    let scale = good.iter().map(|a| a.duration_secs).fold(0.0f64, f64::max);
    // Σ d / n where Σ d overflows (durations near f64::MAX): a finite mean either way.
    let mean_duration_secs = (!good.is_empty()).then(|| {
        let n = good.len() as f64;
        let sum = good.iter().map(|a| a.duration_secs).sum::<f64>();
        if sum.is_finite() {
            sum / n
        } else {
            good.iter().map(|a| a.duration_secs / n).sum::<f64>()
        }
    });
    let duration = if good.len() >= config.min_attempts && scale > 0.0 {
        let t: Vec<f64> = good.iter().map(|a| a.time).collect();
        let v: Vec<f64> = good.iter().map(|a| a.duration_secs / scale).collect();
        Some(fit_series(
            duration_spec(config),
            &t,
            &v,
            config,
            Criterion::AbsoluteError,
        )?)
    } else {
        None
    };
    Ok((duration, scale, mean_duration_secs))
}

fn duration_spec(config: &EdgeModelConfig) -> ModelSpec {
    if config.periodic {
        ModelSpec::Fremen(OrderSpec::Auto)
    } else {
        ModelSpec::Mean
    }
}

fn options(config: &EdgeModelConfig, criterion: Criterion) -> FitOptions {
    FitOptions {
        holdout: config.holdout,
        max_order: config.max_order,
        criterion,
        ..FitOptions::default()
    }
}

/// Fits a model of `values` at `times`, falling back to the static mean when the history is
/// too short to hold part of it back.
fn fit_series(
    spec: ModelSpec,
    times: &[f64],
    values: &[f64],
    config: &EdgeModelConfig,
    criterion: Criterion,
) -> Result<AnyModel, BuildError> {
    match spec.fit(times, values, &options(config, criterion)) {
        Ok(fitted) => Ok(fitted.model),
        Err(BuildError::NotEnoughData(_)) => Ok(ModelSpec::Mean
            .fit(times, values, &FitOptions::default())?
            .model),
        Err(e) => Err(e),
    }
}

/// The candidates whose weights all edges share when success orders are not fixed: FreMEn of
/// orders 0..=`max_order` (with persistence if configured) — order 0 is the static rate.
pub fn success_candidates(config: &EdgeModelConfig) -> Vec<ModelSpec> {
    // Orders above the number of periods would repeat the largest one.
    let orders = 0..=config
        .max_order
        .min(chronomap_core::periods::PeriodSet::default().len());
    orders
        .map(|k| {
            if config.persistence {
                ModelSpec::Persistence(OrderSpec::Fixed(k))
            } else {
                ModelSpec::Fremen(OrderSpec::Fixed(k))
            }
        })
        .collect()
}

/// Fits the success model of every edge in `series`: with a fixed order (or no periodic
/// model), each edge on its own; otherwise a [`StackedModel`] per edge whose weights all edges
/// share, fitted by rolling-origin cross-validation over every edge's history at once — an
/// edge tried a few dozen times borrows the evidence of the busy ones about how much of the
/// daily rhythm transfers to later weeks ([`chronomap_models::stack`]).
fn fit_success_models(
    map: &TopoMap,
    edges: &mut [EdgeModel],
    series: &[(usize, Vec<f64>, Vec<f64>)],
    config: &EdgeModelConfig,
) -> Result<(), (String, BuildError)> {
    let named = |edge: usize| {
        let id = map.edges()[edge].id.clone();
        move |e: BuildError| (id, e)
    };
    let stacked = config.periodic && config.success_order.is_none();
    if !stacked {
        for (edge, times, outcomes) in series {
            let model = fit_series(
                success_spec(config),
                times,
                outcomes,
                config,
                Criterion::Brier,
            )
            .map_err(named(*edge))?;
            edges[*edge].success = Some(model);
        }
        return Ok(());
    }
    let candidates = success_candidates(config);
    let options = options(config, Criterion::Brier);
    let mut problem = StackingProblem::new(candidates.len());
    let mut origins = 0;
    for (_, times, outcomes) in series {
        let (edge_problem, used) = rolling_origin_problem(&candidates, times, outcomes, &options);
        problem.merge(&edge_problem);
        origins = origins.max(used);
    }
    let weights = choose_weights(&candidates, &problem, origins).weights;
    for (edge, times, outcomes) in series {
        let model = match StackedModel::refit(&weights, times, outcomes, &options) {
            Ok(stack) => AnyModel::Stack(Box::new(stack)),
            Err(BuildError::NotEnoughData(_)) => {
                fit_series(ModelSpec::Mean, times, outcomes, config, Criterion::Brier)
                    .map_err(named(*edge))?
            }
            Err(e) => return Err(named(*edge)(e)),
        };
        edges[*edge].success = Some(model);
    }
    Ok(())
}

impl EdgeModels {
    /// Fits the models of every edge of `map` from `attempts[e]` (in time order per edge).
    /// Success probabilities are chosen by the Brier score on the held-back attempts, durations
    /// by the absolute error ([Fentanes 2015] eq. (3)), which is robust to the long tail of durations.
    ///
    /// # Errors
    /// `attempts` not one list per edge, or attempts violating the observation contract (times
    /// going backwards, negative or non-finite durations), with the edge named.
    pub fn fit(
        map: TopoMap,
        attempts: &[Vec<Attempt>],
        config: EdgeModelConfig,
    ) -> Result<Self, (String, BuildError)> {
        if attempts.len() != map.edges().len() {
            return Err((
                "the map".into(),
                BuildError::NotEnoughData(format!(
                    "{} attempt lists for {} edges",
                    attempts.len(),
                    map.edges().len()
                )),
            ));
        }
        let mut edges = Vec::with_capacity(attempts.len());
        // (edge index, attempt times, outcomes) of the edges with enough attempts for a model.
        let mut series: Vec<(usize, Vec<f64>, Vec<f64>)> = Vec::new();
        for (edge, list) in map.edges().iter().zip(attempts) {
            let named = |e: BuildError| (edge.id.clone(), e);
            if let Some(bad) = list
                .iter()
                .position(|a| !(a.duration_secs.is_finite() && a.duration_secs >= 0.0))
            {
                return Err(named(BuildError::Observation(
                    chronomap_core::ObservationError::ValueOutOfRange {
                        index: bad,
                        value: list[bad].duration_secs,
                    },
                )));
            }
            let times: Vec<f64> = list.iter().map(|a| a.time).collect();
            let outcomes: Vec<f64> = list
                .iter()
                .map(|a| f64::from(u8::from(a.success)))
                .collect();
            chronomap_core::observe::validate(None, &times, &outcomes)
                .map_err(|e| named(e.into()))?;
            let successes = list.iter().filter(|a| a.success).count();
            // Success models are fitted below, when every edge's history is known.
            let success = None;
            if list.len() >= config.min_attempts {
                series.push((edges.len(), times, outcomes));
            }
            let good: Vec<&Attempt> = list.iter().filter(|a| a.success).collect();
            let (duration, scale, mean_duration_secs) =
                fit_duration(&good, &config).map_err(named)?;
            edges.push(EdgeModel {
                attempts: list.len(),
                successes,
                success,
                duration,
                duration_scale: scale,
                mean_duration_secs,
                last_time: list.last().map(|a| a.time),
            });
        }
        fit_success_models(&map, &mut edges, &series, &config)?;
        let mut means: Vec<f64> = edges.iter().filter_map(|e| e.mean_duration_secs).collect();
        means.sort_by(f64::total_cmp);
        let median = means.get(means.len() / 2).copied().unwrap_or(60.0);
        let default_duration_secs = config.default_duration_secs.unwrap_or(median);
        let mut models = EdgeModels {
            map,
            config,
            edges,
            default_duration_secs,
            duration_spread: DurationSpread::default(),
        };
        // The spread of the training durations around the fitted models
        // ([`crate::duration_intervals`]).
        let residuals: Vec<Vec<f64>> = attempts
            .iter()
            .enumerate()
            .map(|(edge, list)| {
                list.iter()
                    .filter(|a| a.success)
                    .map(|a| residual(a.duration_secs, models.expected_duration(edge, a.time)))
                    .collect()
            })
            .collect();
        models.duration_spread = DurationSpread::fit(&residuals);
        Ok(models)
    }

    /// The interval that holds a successful traversal's duration of `edge` started at `time`
    /// with probability `coverage` (in `(0, 0.99]`), in seconds, around
    /// [`EdgeModels::expected_duration`] ([`crate::duration_intervals`]); `None` for models
    /// without the spread of their durations (files written before it existed, or no
    /// successful traversal at all).
    pub fn duration_interval(&self, edge: usize, time: f64, coverage: f64) -> Option<(f64, f64)> {
        self.duration_spread
            .interval(edge, self.expected_duration(edge, time), coverage)
    }

    /// The spread of durations around the models.
    pub fn duration_spread(&self) -> &DurationSpread {
        &self.duration_spread
    }

    /// The map.
    pub fn map(&self) -> &TopoMap {
        &self.map
    }

    /// The configuration.
    pub fn config(&self) -> &EdgeModelConfig {
        &self.config
    }

    /// Time of the latest attempt the models have seen, over all edges.
    pub fn last_time(&self) -> Option<f64> {
        self.edges
            .iter()
            .filter_map(|e| e.last_time)
            .max_by(f64::total_cmp)
    }

    /// The weights all edges' success models share ([`success_candidates`]), heaviest first:
    /// empty when the orders are fixed or no edge has a model.
    pub fn shared_success_weights(&self) -> Vec<(ModelSpec, f64)> {
        let stack = self.edges.iter().find_map(|e| match &e.success {
            Some(AnyModel::Stack(stack)) => Some(stack),
            _ => None,
        });
        let mut weights: Vec<(ModelSpec, f64)> = stack
            .map(|s| s.members().map(|(m, w)| (m.spec(), w)).collect())
            .unwrap_or_default();
        weights.sort_by(|a, b| b.1.total_cmp(&a.1));
        weights
    }

    /// The models of one edge.
    pub fn edge(&self, edge: usize) -> &EdgeModel {
        &self.edges[edge]
    }

    /// Probability that traversing `edge` at `time` succeeds: the edge's model (or its static
    /// mean with few attempts), shrunk towards the prior by `prior_attempts` pseudo-attempts,
    /// never below the floor.
    pub fn success_probability(&self, edge: usize, time: f64) -> f64 {
        let e = &self.edges[edge];
        let c = &self.config;
        let observed = match &e.success {
            Some(model) => model.predict(time),
            None if e.attempts > 0 => e.successes as f64 / e.attempts as f64,
            None => c.prior_success,
        };
        let n = e.attempts as f64;
        let shrunk = (n * observed + c.prior_attempts * c.prior_success) / (n + c.prior_attempts);
        shrunk.clamp(c.floor, 1.0)
    }

    /// The static (time-independent) success probability of an edge with the same prior and
    /// floor: the baseline the periodic models must beat.
    pub fn static_success_probability(&self, edge: usize) -> f64 {
        let e = &self.edges[edge];
        let c = &self.config;
        let n = e.attempts as f64;
        let mean = if e.attempts > 0 {
            e.successes as f64 / n
        } else {
            c.prior_success
        };
        ((n * mean + c.prior_attempts * c.prior_success) / (n + c.prior_attempts))
            .clamp(c.floor, 1.0)
    }

    /// Expected duration of a successful traversal of `edge` at `time` (seconds).
    pub fn expected_duration(&self, edge: usize, time: f64) -> f64 {
        let e = &self.edges[edge];
        match (&e.duration, e.mean_duration_secs) {
            (Some(model), _) => model.predict(time) * e.duration_scale,
            (None, Some(mean)) => mean,
            (None, None) => self.default_duration_secs,
        }
    }

    /// The static expected duration of an edge (its mean successful duration).
    pub fn static_duration(&self, edge: usize) -> f64 {
        self.edges[edge]
            .mean_duration_secs
            .unwrap_or(self.default_duration_secs)
    }

    /// A rough confidence in an edge's prediction: the standard deviation of a Beta posterior
    /// with the edge's attempts and the prior's pseudo-attempts.
    pub fn success_uncertainty(&self, edge: usize, time: f64) -> f64 {
        let p = self.success_probability(edge, time);
        let n = self.edges[edge].attempts as f64 + self.config.prior_attempts;
        (p * (1.0 - p) / (n + 1.0)).sqrt()
    }

    /// Success probabilities and expected durations of every edge at `time` (the inputs of a
    /// navigation MDP at that time).
    pub fn at(&self, time: f64) -> (Vec<f64>, Vec<f64>) {
        (0..self.edges.len())
            .map(|e| {
                (
                    self.success_probability(e, time),
                    self.expected_duration(e, time),
                )
            })
            .unzip()
    }

    /// Scores the models, frozen as fitted, on later attempts (`test[e]` for edge `e`): the Brier
    /// score of the success probabilities over all attempts, the mean squared error of the expected durations
    /// over the successful ones, and the same for the static per-edge means, the baseline the
    /// periodic models must beat ([Fentanes 2015] §VI).
    ///
    /// # Errors
    /// `test` not one list per edge.
    pub fn evaluate(&self, test: &[Vec<Attempt>]) -> Result<EdgeEvaluation, BuildError> {
        if test.len() != self.edges.len() {
            return Err(BuildError::NotEnoughData(format!(
                "{} attempt lists for {} edges",
                test.len(),
                self.edges.len()
            )));
        }
        let mut score = EdgeEvaluation::default();
        let (mut mse, mut static_mse) = (0.0, 0.0);
        let (mut model, mut fixed, mut outcomes) = (Vec::new(), Vec::new(), Vec::new());
        // (edge, expected duration, duration) of every successful attempt, for the intervals.
        let mut traversals = Vec::new();
        for (edge, list) in test.iter().enumerate() {
            let p_static = self.static_success_probability(edge);
            let d_static = self.static_duration(edge);
            for a in list {
                model.push(self.success_probability(edge, a.time));
                fixed.push(p_static);
                outcomes.push(f64::from(u8::from(a.success)));
                score.attempts += 1;
                if a.success {
                    let expected = self.expected_duration(edge, a.time);
                    traversals.push((edge, expected, a.duration_secs));
                    mse += (expected - a.duration_secs).powi(2);
                    static_mse += (d_static - a.duration_secs).powi(2);
                    score.successes += 1;
                }
            }
        }
        score.score_success(&model, &fixed, &outcomes);
        let intervals = DurationIntervals::of(&traversals, |edge, expected, level| {
            self.duration_spread.interval(edge, expected, level)
        });
        score.score_durations(&intervals);
        if score.successes > 0 {
            score.duration_mse = mse / score.successes as f64;
            score.static_duration_mse = static_mse / score.successes as f64;
        }
        Ok(score)
    }

    /// Learns from one more attempt of `edge`, as a robot does after each traversal: the counts
    /// behind the static rate, the success model (its persistence term now starts from this
    /// outcome), and, after a success, the levels of the duration intervals
    /// ([`DurationSpread::adapt`], adaptive conformal inference). Duration models stay as
    /// fitted.
    ///
    /// # Errors
    /// An attempt earlier than the edge's latest one, with a non-finite time, or with a
    /// duration that is not a finite number >= 0; the models are then unchanged.
    pub fn observe(
        &mut self,
        edge: usize,
        attempt: &Attempt,
    ) -> Result<(), chronomap_core::ObservationError> {
        let e = &mut self.edges[edge];
        let y = f64::from(u8::from(attempt.success));
        chronomap_core::observe::validate(e.last_time, &[attempt.time], &[y])?;
        // As `fit` refuses them: a duration must be a finite number of seconds >= 0.
        if !(attempt.duration_secs.is_finite() && attempt.duration_secs >= 0.0) {
            return Err(chronomap_core::ObservationError::ValueOutOfRange {
                index: 0,
                value: attempt.duration_secs,
            });
        }
        if let Some(model) = &mut e.success {
            model.observe(&[attempt.time], &[y])?;
        }
        e.attempts += 1;
        e.successes += usize::from(attempt.success);
        e.last_time = Some(attempt.time);
        if attempt.success {
            let r = residual(
                attempt.duration_secs,
                self.expected_duration(edge, attempt.time),
            );
            self.duration_spread.adapt(edge, r);
        }
        Ok(())
    }

    /// Adds an edge the models have not seen, `from → to` (nodes added as needed, without a
    /// pose), modelled as [`EdgeModels::fit`] models an edge without attempts: the prior
    /// success rate, the default duration and the pooled spread of the durations. It learns
    /// from there ([`EdgeModels::observe`]). Returns its index.
    ///
    /// # Errors
    /// An id the map already has, or a name the map refuses; the models are then unchanged.
    pub fn add_edge(&mut self, id: &str, from: &str, to: &str) -> Result<usize, TopoError> {
        let mut map = self.map.clone();
        for node in [from, to] {
            if map.node(node).is_err() {
                map.add_node(node, None)?;
            }
        }
        let index = map.add_edge(id, from, to)?;
        self.map = map;
        self.edges.push(EdgeModel {
            attempts: 0,
            successes: 0,
            success: None,
            duration: None,
            duration_scale: 0.0,
            mean_duration_secs: None,
            last_time: None,
        });
        // A spread that exists keeps one entry per edge; an old file's empty one stays empty.
        if self.duration_spread != DurationSpread::default() {
            self.duration_spread
                .edges
                .push(crate::duration_intervals::ResidualQuantiles::default());
        }
        Ok(index)
    }

    /// Learns later attempts (`attempts[e]` for edge `e`, each list in time order) as a robot
    /// would have, one after the other in the order of their times ([`EdgeModels::observe`]):
    /// all of them, or, on an error, none.
    ///
    /// # Errors
    /// `attempts` not one list per edge, or `(edge, position in its list, why)` of the first
    /// attempt that cannot be learned (out of order, or earlier than what the edge learned
    /// last).
    pub fn observe_all(&mut self, attempts: &[Vec<Attempt>]) -> Result<(), ObserveAllError> {
        if attempts.len() != self.edges.len() {
            return Err(ObserveAllError::Lists {
                lists: attempts.len(),
                edges: self.edges.len(),
            });
        }
        let mut next = self.clone();
        let mut seen = vec![0; attempts.len()];
        for (edge, a) in in_time_order(attempts) {
            next.observe(edge, a)
                .map_err(|error| ObserveAllError::Attempt {
                    edge,
                    position: seen[edge],
                    error,
                })?;
            seen[edge] += 1;
        }
        *self = next;
        Ok(())
    }

    /// Scores the models as they would have served a robot over the test period: every attempt
    /// of every edge, in the order of their times, is predicted from everything before it, then
    /// learned ([`EdgeModels::observe`]). The static baseline is the running per-edge rate,
    /// updated the same way. The expected durations are scored as in
    /// [`EdgeModels::evaluate`] (the duration models do not learn online); their intervals as
    /// they adapt.
    ///
    /// # Errors
    /// `test` not one list per edge, or attempts out of order.
    pub fn evaluate_online(&self, test: &[Vec<Attempt>]) -> Result<EdgeEvaluation, BuildError> {
        let mut score = self.evaluate(test)?;
        let mut live = self.clone();
        let (mut model, mut fixed, mut outcomes) = (Vec::new(), Vec::new(), Vec::new());
        let mut intervals = DurationIntervals::default();
        for (edge, a) in in_time_order(test) {
            model.push(live.success_probability(edge, a.time));
            fixed.push(live.static_success_probability(edge));
            outcomes.push(f64::from(u8::from(a.success)));
            if a.success {
                let expected = live.expected_duration(edge, a.time);
                intervals.push(a.duration_secs, |level| {
                    live.duration_spread.interval(edge, expected, level)
                });
            }
            live.observe(edge, a)?;
        }
        score.score_success(&model, &fixed, &outcomes);
        score.score_durations(&intervals);
        Ok(score)
    }

    /// Restores the map's name index after deserialisation.
    pub fn reindex(&mut self) {
        self.map.reindex();
    }

    /// Checks the invariants a deserialised value must hold before it is used (a file edited by
    /// hand must give an error, not a panic or nonsense predictions). Call after
    /// [`EdgeModels::reindex`].
    ///
    /// # Errors
    /// What is wrong, in words.
    pub fn check(&self) -> Result<(), String> {
        let nodes = self.map.nodes().len();
        for (i, edge) in self.map.edges().iter().enumerate() {
            if edge.from >= nodes || edge.to >= nodes {
                return Err(format!(
                    "edge {i} ({:?}) joins nodes that do not exist",
                    edge.id
                ));
            }
        }
        let mut ids: Vec<&str> = self.map.edges().iter().map(|e| e.id.as_str()).collect();
        ids.sort_unstable();
        if ids.windows(2).any(|w| w[0] == w[1]) {
            return Err("two edges have the same id".into());
        }
        for (i, node) in self.map.nodes().iter().enumerate() {
            if self.map.node(&node.name) != Ok(i) {
                return Err(format!("node {:?} is defined twice", node.name));
            }
        }
        if self.edges.len() != self.map.edges().len() {
            return Err(format!(
                "{} edge models for {} edges",
                self.edges.len(),
                self.map.edges().len()
            ));
        }
        let c = &self.config;
        let fraction = |x: f64| (0.0..=1.0).contains(&x);
        if !(fraction(c.prior_success)
            && fraction(c.floor)
            && c.prior_attempts.is_finite()
            && c.prior_attempts >= 0.0
            && c.holdout.is_finite()
            && self.default_duration_secs.is_finite()
            && self.default_duration_secs >= 0.0)
        {
            return Err("the configuration holds values out of range".into());
        }
        for (edge, e) in self.map.edges().iter().zip(&self.edges) {
            let models_ok = [&e.success, &e.duration]
                .into_iter()
                .flatten()
                .all(AnyModel::is_consistent);
            let numbers_ok = e.successes <= e.attempts
                && e.duration_scale.is_finite()
                && e.duration_scale >= 0.0
                && e.mean_duration_secs
                    .is_none_or(|d| d.is_finite() && d >= 0.0)
                && e.last_time.is_none_or(f64::is_finite);
            if !(models_ok && numbers_ok) {
                return Err(format!(
                    "the models of edge {:?} break their invariants",
                    edge.id
                ));
            }
        }
        let spread = &self.duration_spread;
        if *spread != DurationSpread::default() && !spread.is_consistent(self.edges.len()) {
            return Err("the spread of the durations breaks its invariants".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A door closed every morning (0:00-12:00), open afternoons; attempts every 30 min for 4 weeks.
    fn door_attempts() -> Vec<Attempt> {
        (0..28 * 48)
            .map(|i| {
                let t = 1_404_000_000.0 - 1_404_000_000.0 % 86_400.0 + 1800.0 * i as f64;
                let hour = (t % 86_400.0) / 3600.0;
                Attempt {
                    time: t,
                    duration_secs: if hour < 12.0 { 40.0 } else { 20.0 },
                    success: hour >= 12.0,
                }
            })
            .collect()
    }

    fn map() -> TopoMap {
        let mut map = TopoMap::new();
        for n in ["A", "B", "C"] {
            map.add_node(n, None).unwrap();
        }
        map.add_edge("A_B", "A", "B").unwrap();
        map.add_edge("B_C", "B", "C").unwrap();
        map.add_edge("C_A", "C", "A").unwrap();
        map
    }

    /// Durations drawn from a known law, `scale · exp(σ z)` with `z` standard normal, at times
    /// spread over four weeks.
    fn lognormal_attempts(n: usize, scale: f64, sigma: f64, seed: u64) -> Vec<Attempt> {
        let mut rng = chronomap_core::rng::Xoshiro256StarStar::seed_from_u64(seed);
        let mut times: Vec<f64> = (0..n).map(|_| 28.0 * 86_400.0 * rng.next_f64()).collect();
        times.sort_by(f64::total_cmp);
        times
            .into_iter()
            .map(|time| Attempt {
                time,
                duration_secs: scale * (sigma * rng.standard_normal()).exp(),
                success: true,
            })
            .collect()
    }

    /// The conformance check of duration intervals: on an edge whose durations follow a known
    /// law, intervals of 50 %, 90 % and 99 % hold that share of fresh draws.
    /// Models of edge 0 fitted on 3,000 durations `30 s · exp(0.3 z)` over four weeks.
    fn fitted_on_lognormal_durations() -> EdgeModels {
        EdgeModels::fit(
            map(),
            &[
                lognormal_attempts(3000, 30.0, 0.3, 1),
                Vec::new(),
                Vec::new(),
            ],
            EdgeModelConfig::default(),
        )
        .unwrap()
    }

    /// `n` durations `scale · exp(σ z)` over the four weeks after the fit's.
    fn later_lognormal_attempts(n: usize, scale: f64, sigma: f64, seed: u64) -> Vec<Attempt> {
        lognormal_attempts(n, scale, sigma, seed)
            .into_iter()
            .map(|a| Attempt {
                time: a.time + 28.0 * 86_400.0,
                ..a
            })
            .collect()
    }

    #[test]
    fn duration_intervals_cover_fresh_draws_of_a_known_law_as_often_as_they_claim() {
        let models = fitted_on_lognormal_durations();
        let fresh = later_lognormal_attempts(20_000, 30.0, 0.3, 2);
        let durations: Vec<f64> = fresh.iter().map(|a| a.duration_secs).collect();
        for coverage in [0.5, 0.9, 0.99] {
            let intervals: Vec<(f64, f64)> = fresh
                .iter()
                .map(|a| models.duration_interval(0, a.time, coverage).unwrap())
                .collect();
            let c = chronomap_core::conformance::check_interval_coverage(
                &format!("lognormal durations, {coverage}"),
                coverage,
                &intervals,
                &durations,
            );
            // The exact interval of the law is 30 · exp(±σ z_{1−α/2}): 90 % → 18.3 … 49.1 s.
            if coverage == 0.9 {
                assert!(
                    (c.mean_width - 30.0 * (0.3f64 * 1.6449).exp()
                        + 30.0 * (-0.3f64 * 1.6449).exp())
                    .abs()
                        < 2.0,
                    "{c:?}"
                );
            }
        }
        // An edge never traversed borrows the pooled spread around the default duration.
        let (lo, hi) = models.duration_interval(2, 0.0, 0.9).unwrap();
        let default = models.expected_duration(2, 0.0);
        assert!(lo < default && default < hi && hi / lo > 2.0, "{lo} {hi}");
    }

    /// The conformance check of the online adaptation: fitted on one law, the edge is then
    /// crossed faster and less regularly (scale 30 → 24 s, σ 0.3 → 0.45). The frozen intervals
    /// miss that drift; predicted before each traversal and adapted after it
    /// ([`EdgeModels::observe`], adaptive conformal inference), they hold the nominal share.
    #[test]
    fn duration_intervals_adapted_online_hold_their_share_of_a_drifted_law() {
        let models = fitted_on_lognormal_durations();
        let fresh = later_lognormal_attempts(20_000, 24.0, 0.45, 3);
        let durations: Vec<f64> = fresh.iter().map(|a| a.duration_secs).collect();
        let levels = [0.5, 0.9];
        let mut live = models.clone();
        let mut online = vec![Vec::new(); levels.len()];
        for a in &fresh {
            for (list, &level) in online.iter_mut().zip(&levels) {
                list.push(live.duration_interval(0, a.time, level).unwrap());
            }
            live.observe(0, a).unwrap();
        }
        for (intervals, &level) in online.iter().zip(&levels) {
            chronomap_core::conformance::check_interval_coverage(
                &format!("drifted lognormal durations, online, {level}"),
                level,
                intervals,
                &durations,
            );
            let frozen: Vec<(f64, f64)> = fresh
                .iter()
                .map(|a| models.duration_interval(0, a.time, level).unwrap())
                .collect();
            let c = Coverage::of(&frozen, &durations);
            // The law's own: 50 % of z within ±0.674 · 0.3/0.45 with the centre moved by
            // ln(24/30)/0.45 ≈ −0.50: 0.31; 90 %: 0.65.
            assert!(c.coverage < level - 0.15, "frozen {level}: {c:?}");
        }
        assert_eq!(live.duration_spread().adapted.count, 20_000);
        // The evaluation's online protocol does the same.
        let score = models
            .evaluate_online(&[fresh, Vec::new(), Vec::new()])
            .unwrap();
        assert!((score.duration_coverage - 0.9).abs() < 0.01, "{score:?}");
    }

    /// `observe_all` learns all attempts or none; `add_edge` models a new edge as `fit` models
    /// one without attempts.
    #[test]
    fn observe_all_learns_everything_or_nothing_and_new_edges_start_from_their_prior() {
        let train = lognormal_attempts(300, 30.0, 0.3, 5);
        let models = EdgeModels::fit(
            map(),
            &[train.clone(), Vec::new(), Vec::new()],
            EdgeModelConfig::default(),
        )
        .unwrap();
        let later = |shift: f64, n: usize| -> Vec<Attempt> {
            lognormal_attempts(n, 30.0, 0.3, 6)
                .into_iter()
                .map(|a| Attempt {
                    time: a.time + shift,
                    ..a
                })
                .collect()
        };
        let month = 28.0 * 86_400.0;
        let mut backwards = later(month, 3);
        backwards.swap(1, 2);
        let mut learner = models.clone();
        let refused = learner.observe_all(&[later(month, 50), backwards, Vec::new()]);
        assert!(
            matches!(
                refused,
                Err(ObserveAllError::Attempt {
                    edge: 1,
                    position: 2,
                    ..
                })
            ),
            "{refused:?}"
        );
        assert_eq!(learner.edges[0].attempts, 300);
        assert_eq!(learner.duration_spread, models.duration_spread);
        assert!(matches!(
            learner.observe_all(&[Vec::new()]),
            Err(ObserveAllError::Lists { lists: 1, edges: 3 })
        ));
        // A duration that is not a finite number >= 0 is refused, as `fit` refuses it.
        for duration_secs in [f64::NAN, f64::INFINITY, -1.0] {
            let bad = Attempt {
                time: 3.0 * month,
                duration_secs,
                success: true,
            };
            assert!(learner.observe(0, &bad).is_err(), "{duration_secs}");
        }
        assert_eq!(learner.edges[0].attempts, 300);
        assert_eq!(learner.duration_spread, models.duration_spread);
        learner
            .observe_all(&[later(month, 50), later(month, 3), Vec::new()])
            .unwrap();
        assert_eq!(learner.edges[0].attempts, 350);
        assert_eq!(learner.duration_spread.adapted.count, 53);
        // Edge by edge in time order, the same models.
        let mut one_by_one = models.clone();
        let mut all: Vec<(usize, Attempt)> = later(month, 50)
            .into_iter()
            .map(|a| (0, a))
            .chain(later(month, 3).into_iter().map(|a| (1, a)))
            .collect();
        all.sort_by(|a, b| a.1.time.total_cmp(&b.1.time).then(a.0.cmp(&b.0)));
        for (edge, a) in &all {
            one_by_one.observe(*edge, a).unwrap();
        }
        assert_eq!(one_by_one.duration_spread, learner.duration_spread);

        // A new edge from C to a new node D: as fitted without attempts.
        let d = learner.add_edge("C_D", "C", "D").unwrap();
        assert_eq!(d, 3);
        assert_eq!(learner.map().nodes().len(), 4);
        let mut bigger = map();
        bigger.add_node("D", None).unwrap();
        bigger.add_edge("C_D", "C", "D").unwrap();
        let fitted = EdgeModels::fit(
            bigger,
            &[train, Vec::new(), Vec::new(), Vec::new()],
            EdgeModelConfig::default(),
        )
        .unwrap();
        let t = 2.0 * month;
        assert_eq!(
            learner.success_probability(d, t),
            fitted.success_probability(d, t)
        );
        assert_eq!(
            learner.expected_duration(d, t),
            learner.expected_duration(2, t)
        );
        assert!(learner.duration_interval(d, t, 0.9).is_some());
        assert_eq!(learner.check(), Ok(()));
        // An id the map has: refused, nothing changed.
        assert!(learner.add_edge("A_B", "C", "A").is_err());
        assert_eq!(learner.map().edges().len(), 4);
        assert_eq!(learner.check(), Ok(()));
    }

    #[test]
    fn periodic_edges_follow_their_rhythm_and_sparse_edges_their_prior() {
        let few = vec![
            Attempt {
                time: 10.0,
                duration_secs: 30.0,
                success: false,
            },
            Attempt {
                time: 20.0,
                duration_secs: 31.0,
                success: false,
            },
        ];
        let models = EdgeModels::fit(
            map(),
            &[door_attempts(), few, Vec::new()],
            EdgeModelConfig::default(),
        )
        .unwrap();
        let day = 1_404_000_000.0 - 1_404_000_000.0 % 86_400.0 + 30.0 * 86_400.0;
        let morning = models.success_probability(0, day + 6.0 * 3600.0);
        let afternoon = models.success_probability(0, day + 18.0 * 3600.0);
        assert!(afternoon > 0.8 && morning < 0.2, "{morning} {afternoon}");
        // Two failures and a prior of 0.9 with 2 pseudo-attempts: (0 + 1.8) / 4 = 0.45.
        assert!((models.success_probability(1, 0.0) - 0.45).abs() < 1e-12);
        // Never tried: the prior.
        assert!((models.success_probability(2, 0.0) - 0.9).abs() < 1e-12);
        // Durations of successful traversals only (afternoons: 20 s).
        assert!((models.expected_duration(0, day + 18.0 * 3600.0) - 20.0).abs() < 2.0);
        // The edge that never succeeded has no duration of its own: the median of the others.
        assert_eq!(models.expected_duration(1, 0.0), 20.0);
        let (p, d) = models.at(day);
        assert_eq!((p.len(), d.len()), (3, 3));
        // Static models ignore the time.
        let flat = EdgeModels::fit(
            map(),
            &[door_attempts(), Vec::new(), Vec::new()],
            EdgeModelConfig {
                periodic: false,
                persistence: false,
                ..EdgeModelConfig::default()
            },
        )
        .unwrap();
        assert_eq!(
            flat.success_probability(0, day),
            flat.success_probability(0, day + 43_200.0)
        );
    }

    #[test]
    fn evaluation_scores_against_hand_computed_values() {
        // A never-tried edge predicts the prior 0.9 and the default duration; score it on one
        // success (30 s) and one failure: Brier = (0.1² + 0.9²) / 2 = 0.41.
        let models = EdgeModels::fit(
            map(),
            &[door_attempts(), Vec::new(), Vec::new()],
            EdgeModelConfig::default(),
        )
        .unwrap();
        let test = [
            Vec::new(),
            vec![
                Attempt {
                    time: 0.0,
                    duration_secs: 30.0,
                    success: true,
                },
                Attempt {
                    time: 1.0,
                    duration_secs: 99.0,
                    success: false,
                },
            ],
            Vec::new(),
        ];
        let score = models.evaluate(&test).unwrap();
        assert_eq!((score.attempts, score.successes), (2, 1));
        assert!((score.success_brier - 0.41).abs() < 1e-12);
        assert_eq!(score.success_brier, score.static_success_brier);
        // One bin: forecasts of 0.9 that came true half the time: ECE 0.4, reliability 0.16.
        assert!((score.success_ece - 0.4).abs() < 1e-12);
        assert!((score.success_reliability - 0.16).abs() < 1e-12);
        assert_eq!(score.success_ece, score.static_success_ece);
        let d = models.expected_duration(1, 0.0);
        assert!((score.duration_mse - (d - 30.0).powi(2)).abs() < 1e-9);
        // On the door's own rhythm the periodic model beats the static rate by far.
        let later: Vec<Attempt> = door_attempts()
            .into_iter()
            .map(|a| Attempt {
                time: a.time + 28.0 * 86_400.0,
                ..a
            })
            .collect();
        let score = models.evaluate(&[later, Vec::new(), Vec::new()]).unwrap();
        assert!(
            score.success_brier < 0.1 * score.static_success_brier,
            "{score:?}"
        );
        // Every successful traversal took 20 s: both duration models are exact.
        assert!(
            score.duration_mse < 1e-9 && score.static_duration_mse < 1e-9,
            "{score:?}"
        );
        assert!(models.evaluate(&[]).is_err());
    }

    #[test]
    fn observed_outcomes_persist_and_online_scores_use_them() {
        // An edge that succeeds for 20 days, then fails in a burst: once a failure has been
        // observed, the next attempt a minute later is predicted to fail; days later the
        // prediction is back near the long-term rate.
        let good: Vec<Attempt> = (0..20 * 24)
            .map(|i| Attempt {
                time: 3600.0 * f64::from(i),
                duration_secs: 10.0,
                success: i % 24 != 3,
            })
            .collect();
        let mut models = EdgeModels::fit(
            map(),
            &[good.clone(), Vec::new(), Vec::new()],
            EdgeModelConfig::default(),
        )
        .unwrap();
        let end = 20.0 * 86_400.0;
        let before = models.success_probability(0, end + 60.0);
        assert!(before > 0.8, "{before}");
        let burst: Vec<Attempt> = (0..10)
            .map(|i| Attempt {
                time: end + 60.0 * f64::from(i),
                duration_secs: 5.0,
                success: false,
            })
            .collect();
        let score = models
            .evaluate_online(&[burst.clone(), Vec::new(), Vec::new()])
            .unwrap();
        // Online, only the first failure of the burst is a surprise; the static rate is
        // surprised by every one.
        assert!(
            score.success_brier < 0.5 * score.static_success_brier,
            "{score:?}"
        );
        let week_later = end + 7.0 * 86_400.0;
        let long_term = models.success_probability(0, week_later);
        for a in &burst {
            models.observe(0, a).unwrap();
        }
        assert_eq!(models.edge(0).attempts, good.len() + burst.len());
        let soon = models.success_probability(0, end + 660.0);
        let later = models.success_probability(0, week_later);
        assert!(soon < 0.2 && long_term > 0.9, "{soon} {long_term}");
        // A week on, the persistence has worn off; what remains is the burst's weight in the
        // periodic model (ten failures at one time of day: FreMEn counts each of them).
        assert!(
            later > soon + 0.3 && later < long_term,
            "{soon} {later} {long_term}"
        );
        // Attempts must not go back in time.
        let err = models.observe(0, &good[5]).unwrap_err();
        assert!(err.to_string().contains("time"), "{err}");
        // Without persistence the burst does not change the prediction much.
        let mut flat = EdgeModels::fit(
            map(),
            &[good, Vec::new(), Vec::new()],
            EdgeModelConfig {
                persistence: false,
                ..EdgeModelConfig::default()
            },
        )
        .unwrap();
        for a in &burst {
            flat.observe(0, a).unwrap();
        }
        assert!(flat.success_probability(0, end + 660.0) > soon + 0.3);
    }

    #[test]
    fn the_floor_keeps_failing_edges_alive_and_bad_attempts_are_named() {
        let failures: Vec<Attempt> = (0..50)
            .map(|i| Attempt {
                time: f64::from(i),
                duration_secs: 5.0,
                success: false,
            })
            .collect();
        let models = EdgeModels::fit(
            map(),
            &[failures.clone(), Vec::new(), Vec::new()],
            EdgeModelConfig::default(),
        )
        .unwrap();
        assert!(models.success_probability(0, 100.0) >= 0.05);
        let mut bad = failures.clone();
        bad[3].duration_secs = -1.0;
        let err = EdgeModels::fit(
            map(),
            &[bad, Vec::new(), Vec::new()],
            EdgeModelConfig::default(),
        )
        .unwrap_err();
        assert_eq!(err.0, "A_B");
        let mut backwards = failures;
        backwards[10].time = 1.0;
        assert!(
            EdgeModels::fit(
                map(),
                &[backwards, Vec::new(), Vec::new()],
                EdgeModelConfig::default()
            )
            .is_err()
        );
        assert!(EdgeModels::fit(map(), &[Vec::new()], EdgeModelConfig::default()).is_err());
    }
}
