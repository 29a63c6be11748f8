//! What the command line reports about edge models and plans, computed here so that every
//! front end reports the same: how well the fitted edge models reconstruct their training
//! attempts ([Fentanes 2015] Table II), a test map merged into a training map, the evaluation
//! protocols per map and per edge, the route a plan takes when every edge succeeds, and the
//! now-or-later table ([Fentanes 2015] Table III).

use thiserror::Error;

use crate::deadline::{DeadlineError, DeadlineOptions, DeadlinePlan, now_or_later_by_deadline};
use crate::edges::{Attempt, EdgeEvaluation, EdgeModels};
use crate::map::{TopoError, TopoMap};
use crate::mdp::SolverOptions;
use crate::plan::{PlanAt, PlanError, Planned, Task, now_or_later};
use chronomap_core::BuildError;
use chronomap_core::progress::Progress;
use chronomap_models::spec::AnyModel;

/// Attempts per edge, in the edge order of a map.
pub type AttemptsPerEdge = Vec<Vec<Attempt>>;

/// The order of each edge's models and their mean reconstruction errors ([Fentanes 2015] Table II).
#[derive(Clone, Debug, PartialEq)]
pub struct FitSummary {
    /// Edges per bucket of the success model's order: static rate (few attempts), orders 0,
    /// 1, 2, 3, ≥ 4.
    pub success_orders: [usize; 6],
    /// The same for the duration models.
    pub duration_orders: [usize; 6],
    /// The weights that every edge's success model gives FreMEn orders 0..=`max_order` when the orders
    /// are not fixed (shared by all edges, fitted by rolling-origin cross-validation), heaviest
    /// first; empty with a fixed order.
    pub success_weights: Vec<(String, f64)>,
    /// Mean over the edges with attempts of the mean absolute error of the success
    /// probability at each attempt ([Fentanes 2015] eq. 3 divided by `n`).
    pub success_error: f64,
    /// Mean over the edges with successful attempts of the mean absolute error of the
    /// expected duration (seconds).
    pub duration_error_secs: f64,
}

/// The bucket of [`FitSummary::success_orders`] of a model's order (`None`: static rate).
fn bucket(order: Option<usize>) -> usize {
    order.map_or(0, |o| 1 + o.min(4))
}

/// The order of a model; of a weighted average of models, the largest order among them.
fn order_of(model: &AnyModel) -> Option<usize> {
    match model {
        AnyModel::Stack(stack) => stack.members().filter_map(|(m, _)| m.order()).max(),
        other => other.order(),
    }
}

/// How well `models` reconstruct the `attempts` they were fitted on ([`FitSummary`]).
pub fn fit_summary(models: &EdgeModels, attempts: &[Vec<Attempt>]) -> FitSummary {
    let mut s = FitSummary {
        success_orders: [0; 6],
        duration_orders: [0; 6],
        success_weights: models
            .shared_success_weights()
            .into_iter()
            .map(|(spec, w)| (spec.to_string(), w))
            .collect(),
        success_error: 0.0,
        duration_error_secs: 0.0,
    };
    let (mut success_edges, mut duration_edges) = (0usize, 0usize);
    for (e, list) in attempts.iter().enumerate() {
        let model = models.edge(e);
        s.success_orders[bucket(model.success_model().and_then(order_of))] += 1;
        s.duration_orders[bucket(model.duration_model().and_then(order_of))] += 1;
        if !list.is_empty() {
            // [Fentanes 2015] eq. (3) divided by n: the mean absolute reconstruction error.
            let error: f64 = list
                .iter()
                .map(|a| {
                    (f64::from(u8::from(a.success)) - models.success_probability(e, a.time)).abs()
                })
                .sum();
            s.success_error += error / list.len() as f64;
            success_edges += 1;
        }
        let good: Vec<&Attempt> = list.iter().filter(|a| a.success).collect();
        if !good.is_empty() {
            let error: f64 = good
                .iter()
                .map(|a| (a.duration_secs - models.expected_duration(e, a.time)).abs())
                .sum();
            s.duration_error_secs += error / good.len() as f64;
            duration_edges += 1;
        }
    }
    s.success_error /= success_edges.max(1) as f64;
    s.duration_error_secs /= duration_edges.max(1) as f64;
    s
}

/// Why two maps could not be merged.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum MergeError {
    /// An edge id that joins other nodes in the second map.
    #[error("edge {edge} joins different nodes in the training and test directories")]
    EdgeMismatch {
        /// The edge id.
        edge: String,
    },
    /// A node or edge of the second map is not valid in the first.
    #[error(transparent)]
    Map(#[from] TopoError),
}

/// The union of the training map and a test map: the training map, plus the nodes and edges
/// only the test map has (they get no training attempts, so their prior answers for them).
/// Returns the map, the training attempts and the test attempts, both in its edge order.
///
/// # Errors
/// [`MergeError::EdgeMismatch`] for an edge id joining other nodes in the two maps.
pub fn merge_maps(
    train_map: TopoMap,
    train_attempts: AttemptsPerEdge,
    test_map: &TopoMap,
    test_attempts: &[Vec<Attempt>],
) -> Result<(TopoMap, AttemptsPerEdge, AttemptsPerEdge), MergeError> {
    let mut map = train_map;
    let mut train_attempts = train_attempts;
    for node in test_map.nodes() {
        if map.node(&node.name).is_err() {
            map.add_node(&node.name, node.pose)?;
        }
    }
    let mut merged_test = vec![Vec::new(); map.edges().len()];
    for (edge, attempts) in test_map.edges().iter().zip(test_attempts) {
        let from = &test_map.nodes()[edge.from].name;
        let to = &test_map.nodes()[edge.to].name;
        let index = match map.edges().iter().position(|e| e.id == edge.id) {
            Some(i) => {
                let known = &map.edges()[i];
                if map.nodes()[known.from].name != *from || map.nodes()[known.to].name != *to {
                    return Err(MergeError::EdgeMismatch {
                        edge: edge.id.clone(),
                    });
                }
                i
            }
            None => {
                let i = map.add_edge(&edge.id, from, to)?;
                train_attempts.push(Vec::new());
                merged_test.push(Vec::new());
                i
            }
        };
        merged_test[index] = attempts.clone();
    }
    Ok((map, train_attempts, merged_test))
}

/// How test attempts are predicted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Protocol {
    /// Each test attempt is predicted from everything before it, then learned
    /// ([`EdgeModels::evaluate_online`]).
    Online,
    /// The models stay as fitted ([`EdgeModels::evaluate`]).
    Frozen,
}

impl Protocol {
    /// `online` or `frozen`.
    pub fn name(self) -> &'static str {
        match self {
            Protocol::Online => "online",
            Protocol::Frozen => "frozen",
        }
    }

    /// Scores `models` on `test` (attempts per edge of its map) by this protocol.
    ///
    /// # Errors
    /// As [`EdgeModels::evaluate`].
    pub fn evaluate(
        self,
        models: &EdgeModels,
        test: &[Vec<Attempt>],
    ) -> Result<EdgeEvaluation, BuildError> {
        match self {
            Protocol::Online => models.evaluate_online(test),
            Protocol::Frozen => models.evaluate(test),
        }
    }
}

/// The scores of one edge alone.
#[derive(Clone, Debug, PartialEq)]
pub struct EdgeScore {
    /// Index of the edge in the map.
    pub edge: usize,
    /// Its training attempts.
    pub train_attempts: usize,
    /// Its scores on its test attempts.
    pub score: EdgeEvaluation,
}

/// Every edge with test attempts scored alone by `protocol`, in edge order. Reports the stage
/// `edges` with one step per edge scored to `progress`.
///
/// # Errors
/// As [`Protocol::evaluate`].
pub fn per_edge_scores(
    models: &EdgeModels,
    train: &[Vec<Attempt>],
    test: &[Vec<Attempt>],
    protocol: Protocol,
    progress: &dyn Progress,
) -> Result<Vec<EdgeScore>, BuildError> {
    progress.stage(
        "edges",
        test.iter().filter(|l| !l.is_empty()).count() as u64,
    );
    let mut scores = Vec::new();
    for (e, list) in test.iter().enumerate() {
        if list.is_empty() {
            continue;
        }
        let mut only = vec![Vec::new(); test.len()];
        only[e] = list.clone();
        scores.push(EdgeScore {
            edge: e,
            train_attempts: train.get(e).map_or(0, Vec::len),
            score: protocol.evaluate(models, &only)?,
        });
        progress.advance(1);
    }
    Ok(scores)
}

/// The route of a plan if every edge succeeds: the policy followed through the product from
/// its initial state, as edge indices (at most as many steps as the product has states).
pub fn success_route(planned: &Planned, map: &TopoMap) -> Vec<usize> {
    let mut route = Vec::new();
    let (product, solution) = (&planned.product, &planned.solution);
    let mut state = solution.initial;
    while let Some(choice) = solution.policy_choice[state] {
        let edge = product.mdp().action(choice);
        route.push(edge);
        let target = map.edges()[edge].to;
        match product.successor(state, choice, Some(target)) {
            Some(next) if route.len() <= product.states().len() => state = next,
            _ => break,
        }
    }
    route
}

/// A now-or-later table ([Fentanes 2015] Table III): the plans of `days` days × [`WeekTable::per_day`]
/// start times, `step_mins` apart from midnight UTC of the first day.
#[derive(Clone, Debug, PartialEq)]
pub struct WeekTable {
    /// Midnight (UTC, seconds) of the first day.
    pub first_day: f64,
    /// Days (columns).
    pub days: usize,
    /// Start times per day (rows).
    pub per_day: usize,
    /// Minutes between start times.
    pub step_mins: usize,
    /// The plans, day-major.
    pub plans: Vec<PlanAt>,
    /// The plans most likely to fulfil the task within a deadline, day-major like
    /// [`WeekTable::plans`] ([`WeekTable::add_deadline`]); empty without a deadline.
    pub deadline_plans: Vec<DeadlinePlan>,
    /// The first edges that occur (of the deadline plans once there are any), in edge order:
    /// the legend of [`WeekTable::code`].
    pub first_edges: Vec<usize>,
}

impl WeekTable {
    /// Plans `task` from node `start` at every start time of `days` days from midnight UTC of
    /// the day of `first_day`, `step_mins` apart (`1440 / step_mins` a day).
    ///
    /// # Errors
    /// As [`now_or_later`].
    pub fn compute(
        models: &EdgeModels,
        start: usize,
        task: &Task,
        first_day: f64,
        days: usize,
        step_mins: usize,
    ) -> Result<Self, PlanError> {
        let first_day = (first_day / 86_400.0).floor() * 86_400.0;
        let per_day = 1440 / step_mins.max(1);
        let times: Vec<f64> = (0..days)
            .flat_map(|d| {
                (0..per_day)
                    .map(move |k| first_day + 86_400.0 * d as f64 + 60.0 * (k * step_mins) as f64)
            })
            .collect();
        let plans = now_or_later(models, start, task, &times, &SolverOptions::default())?;
        let first_edges = distinct_edges(plans.iter().map(|p| p.first_edge));
        Ok(WeekTable {
            first_day,
            days,
            per_day,
            step_mins,
            plans,
            deadline_plans: Vec::new(),
            first_edges,
        })
    }

    /// Adds the plan most likely to fulfil `task` from `start` within `deadline_secs` of every
    /// start time ([`now_or_later_by_deadline`]): "when to leave to be there in time?", the now-or-later
    /// question of [Fentanes 2015] Table III asked of a deadline instead of the expected time.
    /// The codes then name the deadline plans' first edges. `planned` is called after each
    /// start time (for progress: one deadline plan can take seconds).
    ///
    /// # Errors
    /// As [`crate::deadline::plan_deadline`], for the first start time that cannot be
    /// planned; the table is then unchanged.
    pub fn add_deadline(
        &mut self,
        models: &EdgeModels,
        start: usize,
        task: &Task,
        deadline_secs: f64,
        options: &DeadlineOptions,
        planned: impl FnMut(),
    ) -> Result<(), DeadlineError> {
        let times: Vec<f64> = self.plans.iter().map(|p| p.time).collect();
        let plans =
            now_or_later_by_deadline(models, start, task, &times, deadline_secs, options, planned)?;
        self.first_edges = distinct_edges(plans.iter().map(|p| p.first_edge));
        self.deadline_plans = plans;
        Ok(())
    }

    /// The plan of start time `k` on day `day`.
    pub fn at(&self, day: usize, k: usize) -> &PlanAt {
        &self.plans[day * self.per_day + k]
    }

    /// The deadline plan of start time `k` on day `day`, once [`WeekTable::add_deadline`] made
    /// them.
    pub fn deadline_at(&self, day: usize, k: usize) -> Option<&DeadlinePlan> {
        self.deadline_plans.get(day * self.per_day + k)
    }

    /// Minutes after midnight of start time `k`.
    pub fn minutes(&self, k: usize) -> usize {
        k * self.step_mins
    }

    /// Midnight (UTC) of day `day`.
    pub fn day(&self, day: usize) -> f64 {
        self.first_day + 86_400.0 * day as f64
    }

    /// The short code of a plan's first edge (its position in [`WeekTable::first_edges`]
    /// as [`letters`]); `-` for none.
    pub fn code(&self, first_edge: Option<usize>) -> String {
        first_edge
            .and_then(|e| self.first_edges.iter().position(|&c| c == e))
            .map_or_else(|| "-".to_string(), letters)
    }
}

/// The distinct edges among `first_edges`, in edge order.
fn distinct_edges(first_edges: impl Iterator<Item = Option<usize>>) -> Vec<usize> {
    let mut edges: Vec<usize> = first_edges.flatten().collect();
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// Short codes `a`, `b`, …, `z`, `aa`, `ab`, … for position `i`.
///
/// ```
/// use chronomap_topo::report::letters;
/// assert_eq!([letters(0), letters(25), letters(26), letters(27), letters(52)], ["a", "z", "aa", "ab", "ba"]);
/// ```
pub fn letters(i: usize) -> String {
    let letters = b"abcdefghijklmnopqrstuvwxyz";
    if i < 26 {
        (letters[i] as char).to_string()
    } else {
        format!(
            "{}{}",
            letters[(i / 26 - 1) % 26] as char,
            letters[i % 26] as char
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::edges::EdgeModelConfig;

    fn attempt(time: f64, duration_secs: f64, success: bool) -> Attempt {
        Attempt {
            time,
            duration_secs,
            success,
        }
    }

    /// A → B (always works, 10 s) and B → A (never), four attempts each.
    fn two_way() -> (TopoMap, AttemptsPerEdge) {
        let mut map = TopoMap::new();
        map.add_node("A", None).unwrap();
        map.add_node("B", None).unwrap();
        map.add_edge("A_B", "A", "B").unwrap();
        map.add_edge("B_A", "B", "A").unwrap();
        let ab = (0..4)
            .map(|i| attempt(f64::from(i) * 600.0, 10.0, true))
            .collect();
        let ba = (0..4)
            .map(|i| attempt(f64::from(i) * 600.0, 30.0, false))
            .collect();
        (map, vec![ab, ba])
    }

    #[test]
    fn few_attempts_give_static_rates_and_small_errors() {
        let (map, attempts) = two_way();
        let models = EdgeModels::fit(map, &attempts, EdgeModelConfig::default()).unwrap();
        let s = fit_summary(&models, &attempts);
        // Fewer than 10 attempts: both edges have a static rate only.
        assert_eq!(s.success_orders, [2, 0, 0, 0, 0, 0]);
        assert_eq!(s.duration_orders[0], 2);
        // The shrunk rates (prior 0.9 with weight 2): (4 + 1.8) / 6 and 1.8 / 6.
        assert!(
            (s.success_error - (1.0 - 5.8 / 6.0 + 1.8 / 6.0) / 2.0).abs() < 1e-9,
            "{s:?}"
        );
        // Only A → B has successful attempts, all of 10 s.
        assert!(s.duration_error_secs.abs() < 1e-9, "{s:?}");
        assert_eq!(letters(1), "b");
    }

    #[test]
    fn a_test_map_adds_its_nodes_and_edges_and_keeps_the_training_order() {
        let (train_map, train) = two_way();
        let mut test_map = TopoMap::new();
        for n in ["B", "C", "A"] {
            test_map.add_node(n, None).unwrap();
        }
        test_map.add_edge("B_C", "B", "C").unwrap();
        test_map.add_edge("A_B", "A", "B").unwrap();
        let test = vec![
            vec![attempt(5000.0, 12.0, true)],
            vec![attempt(5100.0, 9.0, true)],
        ];
        let (map, train, test) = merge_maps(train_map, train, &test_map, &test).unwrap();
        let ids: Vec<&str> = map.edges().iter().map(|e| e.id.as_str()).collect();
        assert_eq!(ids, ["A_B", "B_A", "B_C"]);
        assert_eq!(map.nodes().len(), 3);
        assert_eq!(train.iter().map(Vec::len).collect::<Vec<_>>(), [4, 4, 0]);
        assert_eq!(test[0][0].time, 5100.0);
        assert!(test[1].is_empty());
        assert_eq!(test[2][0].time, 5000.0);

        // The same id between other nodes is refused.
        let (train_map, train) = two_way();
        let mut other = TopoMap::new();
        other.add_node("B", None).unwrap();
        other.add_node("C", None).unwrap();
        other.add_edge("A_B", "B", "C").unwrap();
        let error = merge_maps(train_map, train, &other, &[vec![]]).unwrap_err();
        assert_eq!(
            error.to_string(),
            "edge A_B joins different nodes in the training and test directories"
        );
    }

    #[test]
    fn edges_are_scored_alone_by_either_protocol() {
        let (map, attempts) = two_way();
        let models = EdgeModels::fit(map, &attempts, EdgeModelConfig::default()).unwrap();
        let test = vec![vec![attempt(3000.0, 10.0, true)], Vec::new()];
        let scores = per_edge_scores(
            &models,
            &attempts,
            &test,
            Protocol::Frozen,
            &chronomap_core::progress::NoProgress,
        )
        .unwrap();
        assert_eq!(scores.len(), 1);
        assert_eq!((scores[0].edge, scores[0].train_attempts), (0, 4));
        // Frozen: the shrunk rate (4 + 1.8) / 6 predicts the success.
        let p = 5.8 / 6.0;
        assert!((scores[0].score.success_brier - (1.0 - p) * (1.0 - p)).abs() < 1e-9);
        let whole = Protocol::Frozen.evaluate(&models, &test).unwrap();
        assert_eq!(whole.success_brier, scores[0].score.success_brier);
        assert_eq!(Protocol::Online.name(), "online");
    }
}
