//! Lifelong spatio-temporal exploration: where and when to observe ([Santos 2017] §3, §5, §7).
//!
//! # Problem ([Santos 2017] §3.1)
//! A world of `n` binary states `s_i(t)` is observed through *locations* (sets of states seen
//! together). Each day, at midnight, the robot schedules the next day's time slots (10 minutes
//! by default): a slot is spent observing one location, or on other tasks; a fraction `e` (the
//! exploration ratio) of the slots may be spent exploring. The observations of the scheduled
//! slots are taken from the recorded world, the temporal models of the states are updated, and
//! the day is scored by the model error of eq. (2): the fraction of (state, time) pairs whose
//! estimate `s'_i(t)` — the observation if the state was being observed (eq. (1)), else the
//! model's `p_i(t) > 0.5` — differs from the truth.
//!
//! # Strategies (§5)
//! [`Strategy::RoundRobin`] and [`Strategy::Random`] ignore the models. [`Strategy::Greedy`]
//! gives each slot the location of largest expected information `I(L, t)` (eq. (10), the sum of
//! the states' entropies) and keeps the `e·m` best slots. [`Strategy::MonteCarlo`] draws each
//! slot's location with probability proportional to `I(L, t) + ι`, the "other tasks" option
//! weighted `I'(1 − e)/(m·e)` so that `e` holds on average (eq. (11)). [`Strategy::Novelty`]
//! follows the Monte-Carlo schedule but, after each observation, compares the information the
//! short-term model of the location just seen expects in the next slot (eq. (12),
//! cross-entropy of the short-term expectation against the long-term model) with eq. (10): if it
//! is much larger (and larger than what the planned visit promises), what was seen surprised the
//! long-term model, and the next exploration slot re-observes the location ("the robot
//! re-observes the location again to obtain more information about this unexpected event").
//! Slots planned for other tasks stay so, which keeps the exploration ratio.
//!
//! Any [`TemporalModel`] plugs in through [`DailyModel`]; [`AutoOrder`] adds the daily order
//! selection of [Santos 2017] §4.1.3 to an [`Ordered`] model. [`table`] runs the experiments of §7:
//! every strategy with every model, and the sweep over exploration ratios.
#![deny(missing_docs)]

pub mod table;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use chronomap_core::model::{Ordered, TemporalModel};
use chronomap_core::num::{count_of, fmt_number};
use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_core::select::{Criterion, select_order_online};
use chronomap_core::stm::MarkovModel;

/// The most steps a day of a [`World`] (2^24, a step of about 5 ms).
pub const MAX_STEPS_PER_DAY: usize = 1 << 24;

/// A recorded world: the truth of every state at every step, and the locations.
#[derive(Clone, Debug, PartialEq)]
pub struct World {
    /// Time of step 0 (seconds).
    pub start: f64,
    /// Seconds between steps (60 for Aruba, 600 for Brayford).
    pub step_secs: f64,
    /// `truth[state][step]`: 0 or 1.
    pub truth: Vec<Vec<u8>>,
    /// The states each location observes.
    pub locations: Vec<Vec<usize>>,
    /// A name per location (for tables and plots).
    pub names: Vec<String>,
}

/// Why an exploration could not run.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ExploreError {
    /// The world is malformed.
    #[error("invalid world: {0}")]
    World(String),
    /// A parameter is out of range.
    #[error("{name} = {value} is out of range: {expected}")]
    Parameter {
        /// Parameter.
        name: &'static str,
        /// Value given.
        value: String,
        /// What is accepted.
        expected: &'static str,
    },
}

impl World {
    /// A world where every state is its own location.
    pub fn one_state_per_location(
        start: f64,
        step_secs: f64,
        truth: Vec<Vec<u8>>,
        names: Vec<String>,
    ) -> Self {
        let locations = (0..truth.len()).map(|i| vec![i]).collect();
        World {
            start,
            step_secs,
            truth,
            locations,
            names,
        }
    }

    /// Number of steps.
    pub fn steps(&self) -> usize {
        self.truth.first().map_or(0, Vec::len)
    }

    /// Time of a step.
    pub fn time(&self, step: usize) -> f64 {
        self.start + step as f64 * self.step_secs
    }

    /// Checks the world.
    ///
    /// # Errors
    /// No states, states of different lengths, non-binary truths, a bad step (or one that gives
    /// more than [`MAX_STEPS_PER_DAY`] steps a day), empty locations,
    /// locations naming missing states, or names not one per location.
    pub fn validate(&self) -> Result<(), ExploreError> {
        let bad = |m: String| Err(ExploreError::World(m));
        if self.truth.is_empty() || self.steps() == 0 {
            return bad("no states or no steps".into());
        }
        if let Some(i) = self.truth.iter().position(|t| t.len() != self.steps()) {
            return bad(format!(
                "state {i} has {} steps, state 0 has {}",
                self.truth[i].len(),
                self.steps()
            ));
        }
        if let Some(i) = self.truth.iter().position(|t| t.iter().any(|&v| v > 1)) {
            return bad(format!("state {i} has a value other than 0 or 1"));
        }
        if !(self.step_secs.is_finite()
            && self.step_secs > 0.0
            && self.start.is_finite()
            && self.start >= 0.0)
        {
            return bad(format!(
                "step {} s from {} is not a valid clock",
                fmt_number(self.step_secs),
                fmt_number(self.start)
            ));
        }
        // Steps are counted per day and per slot as integers: a step too short for that count
        // is refused here, so no `as usize` of it can saturate later.
        if count_of((86_400.0 / self.step_secs).round(), MAX_STEPS_PER_DAY).is_none() {
            return bad(format!(
                "step {} s gives {} steps a day; at most {MAX_STEPS_PER_DAY}",
                fmt_number(self.step_secs),
                fmt_number((86_400.0 / self.step_secs).round())
            ));
        }
        if self.locations.is_empty() || self.locations.iter().any(Vec::is_empty) {
            return bad("every location must observe at least one state".into());
        }
        if let Some(l) = self
            .locations
            .iter()
            .position(|l| l.iter().any(|&s| s >= self.truth.len()))
        {
            return bad(format!("location {l} names a state that does not exist"));
        }
        if self.names.len() != self.locations.len() {
            return bad(format!(
                "{} names for {} locations",
                self.names.len(),
                self.locations.len()
            ));
        }
        Ok(())
    }
}

/// A temporal model as the exploration uses it: updated once a day with the day's
/// observations, and queried for probabilities.
pub trait DailyModel: Send {
    /// Adds one day's observations (in time order).
    fn update_day(&mut self, times: &[f64], values: &[f64]);
    /// `p(t)`.
    fn predict(&self, time: f64) -> f64;
}

impl<M: TemporalModel> DailyModel for M {
    fn update_day(&mut self, times: &[f64], values: &[f64]) {
        self.observe(times, values)
            .expect("the exploration feeds observations in time order");
    }

    fn predict(&self, time: f64) -> f64 {
        TemporalModel::predict(self, time)
    }
}

/// A model whose order is chosen every day on the day's observations before they are added
/// ([Santos 2017] §4.1.3: "initially m equals 0 and is increased only after the robot obtains enough
/// data to verify the prediction accuracy").
///
/// The paper compares orders by the model error of eq. (2) on the last day; [`AutoOrder::new`]
/// uses the Brier score like the rest of chronomap instead, because for rarely occupied states
/// the binary error barely moves between orders (a person is in a given room 1–30 % of the
/// time). (Choosing by the score accumulated over all days instead of the last day's was tried
/// and is worse on Aruba — 6.4 % instead of 6.0 % with Monte-Carlo: the best order grows as data
/// accumulate, and old scores hold it back.)
#[derive(Clone, Debug)]
pub struct AutoOrder<M> {
    /// The model.
    pub model: M,
    /// Largest order tried.
    pub max_order: usize,
    /// How a day's observations score the orders.
    pub criterion: Criterion,
}

impl<M> AutoOrder<M> {
    /// `model` with orders up to 10 chosen daily by the Brier score (the defaults of
    /// [`FitOptions`](chronomap_models::spec::FitOptions)).
    pub fn new(model: M) -> Self {
        AutoOrder {
            model,
            max_order: 10,
            criterion: Criterion::Brier,
        }
    }
}

impl<M: TemporalModel + Ordered> DailyModel for AutoOrder<M> {
    fn update_day(&mut self, times: &[f64], values: &[f64]) {
        select_order_online(
            &mut self.model,
            times,
            values,
            self.max_order,
            self.criterion,
        )
        .expect("the exploration feeds observations in time order");
    }

    fn predict(&self, time: f64) -> f64 {
        self.model.predict(time)
    }
}

/// An exploration strategy ([Santos 2017] §5).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Strategy {
    /// Visits the locations in turn, exploring in a fraction `e` of evenly spread slots.
    RoundRobin,
    /// Explores each slot with probability `e`, a uniformly chosen location.
    Random,
    /// Each slot's most informative location; the `e·m` most informative slots (eq. (10)).
    Greedy,
    /// Locations drawn in proportion to their information plus `iota` (eq. (11)).
    MonteCarlo {
        /// The constant ι that keeps certain locations occasionally visited (nats).
        iota: f64,
    },
    /// Monte-Carlo; after each observation, the next exploration slot re-observes the same
    /// location if what was seen makes its short-term expectation differ much from the
    /// long-term model (eq. (12)) and promises more than the planned visit.
    Novelty {
        /// ι of the Monte-Carlo schedule.
        iota: f64,
        /// A location is novel when eq. (12) exceeds `factor ×` eq. (10) there.
        factor: f64,
    },
}

impl Strategy {
    /// The five strategies of the paper with default parameters.
    pub fn all() -> [Strategy; 5] {
        [
            Strategy::RoundRobin,
            Strategy::Random,
            Strategy::Greedy,
            Strategy::MonteCarlo { iota: 0.01 },
            Strategy::Novelty {
                iota: 0.01,
                factor: 3.0,
            },
        ]
    }

    /// Short name (`round-robin`, `random`, `greedy`, `monte-carlo`, `novelty`).
    pub fn name(&self) -> &'static str {
        self.labels().0
    }

    /// The short name and the row title of [Santos 2017]'s tables ([`table::row_title`]).
    pub(crate) fn labels(&self) -> (&'static str, &'static str) {
        match self {
            Strategy::RoundRobin => ("round-robin", "Round Robin"),
            Strategy::Random => ("random", "Random"),
            Strategy::Greedy => ("greedy", "Greedy"),
            Strategy::MonteCarlo { .. } => ("monte-carlo", "Monte-Carlo"),
            Strategy::Novelty { .. } => ("novelty", "Novelty-driven"),
        }
    }
}

/// Parameters of an exploration run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExploreConfig {
    /// Exploration ratio `e` in `(0, 1]`.
    pub ratio: f64,
    /// Length of a slot (an observation) in seconds (default 600).
    pub slot_secs: f64,
    /// Days to explore (`None`: every whole day of the world).
    pub days: Option<usize>,
    /// Seed of every random choice.
    pub seed: u64,
    /// Record the model and information of the first days for plots.
    pub trace_days: usize,
}

impl Default for ExploreConfig {
    fn default() -> Self {
        ExploreConfig {
            ratio: 0.5,
            slot_secs: 600.0,
            days: None,
            seed: 0,
            trace_days: 0,
        }
    }
}

/// What the robot believed and did on the traced days.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    /// Start time of every traced slot.
    pub slot_times: Vec<f64>,
    /// `probability[state][slot]`: the model's `p` at the slot's middle when it was planned.
    pub probability: Vec<Vec<f64>>,
    /// `information[location][slot]`: eq. (10) used for planning (nats).
    pub information: Vec<Vec<f64>>,
    /// Location observed in each slot (`None`: other tasks).
    pub visits: Vec<Option<usize>>,
}

/// Result of an exploration run.
#[derive(Clone, Debug, PartialEq)]
pub struct ExploreResult {
    /// Model error of eq. (2) over all days, in percent (mean of the daily errors).
    pub error_percent: f64,
    /// Model error of each day, in percent.
    pub daily_error_percent: Vec<f64>,
    /// Fraction of slots spent exploring.
    pub explored_fraction: f64,
    /// Visits per location.
    pub visits: Vec<usize>,
    /// Slots redirected by the novelty strategy.
    pub redirects: usize,
    /// The traced days.
    pub trace: Trace,
}

/// Binary entropy in nats (eq. (10) uses natural logarithms).
fn entropy_nats(p: f64) -> f64 {
    if p <= 0.0 || p >= 1.0 {
        0.0
    } else {
        -p * p.ln() - (1.0 - p) * (1.0 - p).ln()
    }
}

/// Cross-entropy of eq. (12): `−p_e ln p_i − (1 − p_e) ln(1 − p_i)`, with `p_i` kept away from 0
/// and 1 so that a certain model meets a surprise with a large but finite value.
fn cross_entropy_nats(expected: f64, info: f64) -> f64 {
    let q = info.clamp(1e-6, 1.0 - 1e-6);
    -expected * q.ln() - (1.0 - expected) * (1.0 - q).ln()
}

/// Runs an exploration of `world` with `strategy`, one model per state made by `make_model`.
///
/// # Errors
/// A malformed world, a ratio outside `(0, 1]`, or a slot that is not a whole number of steps
/// dividing a day.
pub fn explore(
    world: &World,
    strategy: Strategy,
    make_model: &dyn Fn() -> Box<dyn DailyModel>,
    config: &ExploreConfig,
) -> Result<ExploreResult, ExploreError> {
    world.validate()?;
    if !(config.ratio > 0.0 && config.ratio <= 1.0) {
        return Err(ExploreError::Parameter {
            name: "ratio",
            value: config.ratio.to_string(),
            expected: "an exploration ratio in (0, 1]",
        });
    }
    let steps_per_slot = (config.slot_secs / world.step_secs).round() as usize;
    let steps_per_day = (86_400.0 / world.step_secs).round() as usize;
    if steps_per_slot == 0
        || (steps_per_slot as f64 * world.step_secs - config.slot_secs).abs()
            > 1e-9 * config.slot_secs
        || !steps_per_day.is_multiple_of(steps_per_slot)
    {
        return Err(ExploreError::Parameter {
            name: "slot_secs",
            value: config.slot_secs.to_string(),
            expected: "a whole number of steps that divides a day",
        });
    }
    let slots = steps_per_day / steps_per_slot;
    let days = config
        .days
        .unwrap_or(world.steps() / steps_per_day)
        .min(world.steps() / steps_per_day);
    if days == 0 {
        return Err(ExploreError::World(
            "the world is shorter than a day".into(),
        ));
    }
    let n_states = world.truth.len();
    let mut models: Vec<Box<dyn DailyModel>> = (0..n_states).map(|_| make_model()).collect();
    let mut short_term: Vec<MarkovModel> = (0..n_states).map(|_| MarkovModel::new()).collect();
    let mut rng = Xoshiro256StarStar::seed_from_u64(config.seed);
    let mut planner = Planner {
        strategy,
        ratio: config.ratio,
        next_location: 0,
        slot_counter: 0,
    };
    let mut daily = Vec::with_capacity(days);
    let mut visits = vec![0usize; world.locations.len()];
    let (mut explored, mut redirects) = (0usize, 0usize);
    let mut trace = Trace {
        probability: vec![Vec::new(); n_states],
        information: vec![Vec::new(); world.locations.len()],
        ..Trace::default()
    };
    for day in 0..days {
        let first_step = day * steps_per_day;
        let slot_step = |s: usize| first_step + s * steps_per_slot;
        // Expected information of every (location, slot) from the models as of midnight:
        // the mean over the slot's steps of eq. (10).
        let probability: Vec<Vec<f64>> = (0..n_states)
            .map(|i| {
                (0..steps_per_day)
                    .map(|k| models[i].predict(world.time(first_step + k)))
                    .collect()
            })
            .collect();
        let information: Vec<Vec<f64>> = world
            .locations
            .iter()
            .map(|states| {
                (0..slots)
                    .map(|s| {
                        let range = s * steps_per_slot..(s + 1) * steps_per_slot;
                        states
                            .iter()
                            .map(|&i| {
                                range
                                    .clone()
                                    .map(|k| entropy_nats(probability[i][k]))
                                    .sum::<f64>()
                            })
                            .sum::<f64>()
                            / steps_per_slot as f64
                    })
                    .collect()
            })
            .collect();
        let mut plan = planner.plan(&information, slots, &mut rng);

        // Execute the day slot by slot; the novelty strategy may redirect the next exploration
        // slot.
        let mut observed = vec![vec![false; steps_per_day]; n_states];
        let mut day_times: Vec<Vec<f64>> = vec![Vec::new(); n_states];
        let mut day_values: Vec<Vec<f64>> = vec![Vec::new(); n_states];
        for s in 0..slots {
            if let Some(location) = plan[s] {
                visits[location] += 1;
                explored += 1;
                for &i in &world.locations[location] {
                    for k in slot_step(s)..slot_step(s) + steps_per_slot {
                        let (t, v) = (world.time(k), f64::from(world.truth[i][k]));
                        observed[i][k - first_step] = true;
                        day_times[i].push(t);
                        day_values[i].push(v);
                        short_term[i].observe(&[t], &[v]).expect("time order");
                    }
                }
                if let Strategy::Novelty { factor, .. } = strategy
                    && s + 1 < slots
                    && let Some(planned) = plan[s + 1]
                    && planned != location
                {
                    let surprise = expected_information(
                        world,
                        location,
                        &models,
                        &short_term,
                        slot_step(s + 1),
                        steps_per_slot,
                    );
                    // Re-observe when what was seen surprised the long-term model (eq. (12) much
                    // larger than eq. (10) there) and promises more than the planned visit.
                    if surprise > factor * information[location][s + 1]
                        && surprise > information[planned][s + 1]
                    {
                        plan[s + 1] = Some(location);
                        redirects += 1;
                    }
                }
            }
        }
        if day < config.trace_days {
            for s in 0..slots {
                trace.slot_times.push(world.time(slot_step(s)));
                trace.visits.push(plan[s]);
                for (i, p) in probability.iter().enumerate() {
                    trace.probability[i].push(p[s * steps_per_slot + steps_per_slot / 2]);
                }
                for (l, info) in information.iter().enumerate() {
                    trace.information[l].push(info[s]);
                }
            }
        }
        // Midnight: update the long-term models with the day's observations, then score the day
        // with them (eq. (1)–(2)).
        for ((model, times), values) in models.iter_mut().zip(&day_times).zip(&day_values) {
            model.update_day(times, values);
        }
        let mut wrong = 0usize;
        for ((model, seen), truth) in models.iter().zip(&observed).zip(&world.truth) {
            for (k, &was_observed) in seen.iter().enumerate() {
                if !was_observed {
                    let step = first_step + k;
                    let estimate = model.predict(world.time(step)) > 0.5;
                    wrong += usize::from((truth[step] == 1) != estimate);
                }
            }
        }
        daily.push(100.0 * wrong as f64 / (n_states * steps_per_day) as f64);
    }
    Ok(ExploreResult {
        error_percent: daily.iter().sum::<f64>() / daily.len() as f64,
        daily_error_percent: daily,
        explored_fraction: explored as f64 / (days * slots) as f64,
        visits,
        redirects,
        trace,
    })
}

/// The information the short-term models of a location's states expect from observing it in
/// the slot starting at `step` (eq. (12): cross-entropy of the short-term expectation against the
/// long-term model), mean over the slot's steps.
fn expected_information(
    world: &World,
    location: usize,
    models: &[Box<dyn DailyModel>],
    short_term: &[MarkovModel],
    step: usize,
    steps_per_slot: usize,
) -> f64 {
    world.locations[location]
        .iter()
        .map(|&i| {
            (step..step + steps_per_slot)
                .map(|k| {
                    let t = world.time(k);
                    cross_entropy_nats(
                        TemporalModel::predict(&short_term[i], t),
                        models[i].predict(t),
                    )
                })
                .sum::<f64>()
        })
        .sum::<f64>()
        / steps_per_slot as f64
}

/// Schedules one day.
struct Planner {
    strategy: Strategy,
    ratio: f64,
    /// Round-robin: the next location in turn.
    next_location: usize,
    /// Round-robin: slots scheduled so far (to spread exploration evenly across days).
    slot_counter: u64,
}

impl Planner {
    /// `information[location][slot]` → a location or `None` per slot.
    fn plan(
        &mut self,
        information: &[Vec<f64>],
        slots: usize,
        rng: &mut Xoshiro256StarStar,
    ) -> Vec<Option<usize>> {
        let locations = information.len();
        let e = self.ratio;
        match self.strategy {
            Strategy::RoundRobin => (0..slots)
                .map(|_| {
                    let g = self.slot_counter;
                    self.slot_counter += 1;
                    // Explore when the running count of e·slots steps up: exactly ⌊e·g⌋ so far.
                    (((g + 1) as f64 * e).floor() > (g as f64 * e).floor()).then(|| {
                        let l = self.next_location;
                        self.next_location = (l + 1) % locations;
                        l
                    })
                })
                .collect(),
            Strategy::Random => (0..slots)
                .map(|_| {
                    rng.bernoulli(e)
                        .then(|| rng.int_in(0, locations as u64 - 1) as usize)
                })
                .collect(),
            Strategy::Greedy => {
                // Best location per slot (ties broken at random), then the e·m best slots.
                let best: Vec<(usize, f64)> = (0..slots)
                    .map(|s| {
                        (0..locations)
                            .map(|l| (l, information[l][s] + rng.uniform(0.0, 1e-9)))
                            .max_by(|a, b| a.1.total_cmp(&b.1))
                            .expect("at least one location")
                    })
                    .collect();
                let keep = (e * slots as f64).round() as usize;
                let mut order: Vec<usize> = (0..slots).collect();
                order.sort_by(|&a, &b| best[b].1.total_cmp(&best[a].1));
                let mut plan = vec![None; slots];
                for &s in &order[..keep.min(slots)] {
                    plan[s] = Some(best[s].0);
                }
                plan
            }
            Strategy::MonteCarlo { iota } | Strategy::Novelty { iota, .. } => {
                let total: f64 = information.iter().flatten().sum();
                if total <= 0.0 || e >= 1.0 {
                    // Nothing is uncertain (or nothing else to do): explore like Random.
                    return (0..slots)
                        .map(|_| {
                            rng.bernoulli(e)
                                .then(|| rng.int_in(0, locations as u64 - 1) as usize)
                        })
                        .collect();
                }
                // Eq. (11): "other tasks" carry I'(1 − e)/(m·e) so that e holds on average.
                let other = total * (1.0 - e) / (slots as f64 * e);
                (0..slots)
                    .map(|s| {
                        let weights: Vec<f64> =
                            (0..locations).map(|l| information[l][s] + iota).collect();
                        let sum = other + iota + weights.iter().sum::<f64>();
                        let mut pick = rng.uniform(0.0, sum) - (other + iota);
                        if pick < 0.0 {
                            return None;
                        }
                        for (l, w) in weights.iter().enumerate() {
                            if pick < *w {
                                return Some(l);
                            }
                            pick -= w;
                        }
                        Some(locations - 1)
                    })
                    .collect()
            }
        }
    }
}

#[cfg(test)]
mod tests;
