//! The service-disturbance benchmark of CoPA-Map (dissertation chapter 4, [Stüde 2024] §4.3.2
//! eq. 4.22 and §4.3.5): a robot patrols waypoints `A → B → C → D` on paths planned from an
//! activity model, and every person detection within 1 m of it while it drives is an
//! encounter. A model is better the fewer encounters its cheapest patrols cause.
//!
//! ```
//! use chronomap_activity::disturbance::{
//!     DisturbanceConfig, Detections, PathCost, PatrolSlot, PlanningGrid, run_patrols,
//!     service_disturbance,
//! };
//! use chronomap_hypertime::events::Event;
//!
//! // A corridor of 5 x 1 cells of 0.5 m; the robot drives from one end to the other and back.
//! let grid = PlanningGrid::new([0.0, 0.0], 0.5, 5, 1)?;
//! let waypoints = [grid.cell_at([0.25, 0.25]).unwrap(), grid.cell_at([2.25, 0.25]).unwrap()];
//! // One person stands at the far end for 10 s from t = 100.
//! let people: Vec<Event> = (0..10).map(|k| Event { t: 100.0 + f64::from(k), x: 2.25, y: 0.25 }).collect();
//! let detections = Detections::new(people)?;
//! // Patrols at t = 0 (the robot needs 4 s for 2 m, and meets nobody) and at t = 100.
//! let slots = [PatrolSlot { start: 0.0, model_t: 0.0 }, PatrolSlot { start: 100.0, model_t: 1.0 }];
//! let config = DisturbanceConfig::default();
//! let runs = run_patrols(&grid, &waypoints, &PathCost::Length, &slots, &detections, &config)?;
//! assert_eq!(runs[0].length, 2.0);
//! assert_eq!(runs[0].duration, 4.0);
//! // At 0.5 m/s the robot is within 1 m of (2.25, 0.25) from t = 102 to 104: three detections.
//! assert_eq!((runs[0].encounters, runs[1].encounters), (0, 3));
//! // Eq. (4.22): equal costs rank the earlier patrol first.
//! let costs: Vec<f64> = runs.iter().map(|r| r.cost).collect();
//! let encounters: Vec<usize> = runs.iter().map(|r| r.encounters).collect();
//! assert_eq!(service_disturbance(&costs, &encounters, 0.5)?, 0);
//! assert_eq!(service_disturbance(&costs, &encounters, 1.0)?, 3);
//! # Ok::<(), chronomap_activity::disturbance::DisturbanceError>(())
//! ```
//!
//! # The benchmark
//! * **Where the robot may drive**: a [`PlanningGrid`] of square cells over a region. A cell
//!   is free unless it was blocked: by [`PlanningGrid::block_obstacles`] (an obstacle of an
//!   [`ObstacleGrid`] within the robot's clearance of the cell centre) or by
//!   [`PlanningGrid::keep_only`] (e.g. cells where the models have no training data).
//! * **Paths**: Dijkstra on the 8-connected (Moore) graph of free cells. The directed edge
//!   `u → v` costs `|u − v| · w(v)`: its length times the weight of the cell it enters
//!   ([`shortest_path`]). A diagonal step needs both cells beside it free (no cutting of
//!   corners). [`PathCost::Length`] (all weights 1) is the *Occupancy Map* baseline of §4.3.5,
//!   the shortest route; [`PathCost::Rate`] weighs a cell by `r̂(v, t) + ε`, the model's
//!   predicted rate of people (per hour of observation) in the cell at the patrol's time plus
//!   a small constant `ε` ([`DisturbanceConfig::epsilon`]) so that among quiet cells the
//!   shorter path wins. `∫ r̂ ds` along a path is proportional to the number of people the
//!   model expects the robot to pass, so the cheapest path is the least disturbing one the
//!   model knows.
//! * **Patrols**: `A → B → C → D`, the shortest paths of the legs joined ([`plan_patrol`]),
//!   driven from cell centre to cell centre at [`DisturbanceConfig::speed`] (0.5 m/s). The
//!   cost map only changes with the model's time, so [`run_patrols`] plans once per distinct
//!   [`PatrolSlot::model_t`].
//! * **Encounters** ([`count_encounters`]): the person detections `(t, x, y)` with
//!   `|robot(t) − (x, y)| ≤ 1 m` while the robot drives, each detection counted once per
//!   patrol (a person standing next to the robot for 3 s at 1 Hz is 3 encounters).
//! * **Eq. (4.22)** ([`service_disturbance`]): the patrols are ranked by their total predicted
//!   cost, ascending, and `E(⌊n_nav ρ⌋)` is the sum of the encounters of the
//!   `⌊n_nav ρ⌋` cheapest; `ρ` is the servicing ratio. Equal costs keep the patrols' order
//!   (earlier first): the Occupancy Map baseline, whose every patrol costs the same, serves
//!   in time order.

use std::collections::HashMap;

use thiserror::Error;

use super::{RatePredictor, RateSamples};
use chronomap_hypertime::events::{Event, Window};
pub use chronomap_spatial::{ObstacleGrid, PlanningGrid, PlanningGridError};

/// Why the benchmark could not run.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum DisturbanceError {
    /// A parameter is out of range (a grid size, cell size, speed, radius, `ρ`, ...).
    #[error("invalid configuration: {0}")]
    Config(String),
    /// The planning grid refused its size or a waypoint (outside it, or in a blocked cell).
    #[error(transparent)]
    Grid(#[from] PlanningGridError),
    /// No path joins two consecutive waypoints.
    #[error("no path through free cells from ({}, {}) to ({}, {})", .from[0], .from[1], .to[0], .to[1])]
    Unreachable {
        /// Centre of the start cell.
        from: [f64; 2],
        /// Centre of the goal cell.
        to: [f64; 2],
    },
    /// A detection has a non-finite time or position, or comes before the one preceding it.
    #[error("detection {index}: {reason}")]
    BadDetection {
        /// Index of the detection.
        index: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// A model predicted a rate that is not a finite number.
    #[error("the model predicted {value} at ({}, {}), t = {t}: not a finite rate", .at[0], .at[1])]
    BadPrediction {
        /// Where.
        at: [f64; 2],
        /// The model's time.
        t: f64,
        /// The prediction.
        value: f64,
    },
    /// A patrol takes longer than [`DisturbanceConfig::max_duration`], so it would leave the
    /// time in which people were tracked.
    #[error(
        "the patrol starting at {start} takes {duration:.1} s, longer than the {max} s its slot \
         allows"
    )]
    PatrolTooLong {
        /// Start of the patrol.
        start: f64,
        /// Its duration in seconds.
        duration: f64,
        /// The limit.
        max: f64,
    },
    /// Costs and encounters of eq. (4.22) differ in length.
    #[error("{costs} patrol costs but {encounters} encounter counts")]
    LengthMismatch {
        /// Number of costs.
        costs: usize,
        /// Number of encounter counts.
        encounters: usize,
    },
}

/// A place a patrol visits.
#[derive(Clone, Debug, PartialEq)]
pub struct Waypoint {
    /// Its label (`"A"`, `"B"`, ...).
    pub label: String,
    /// Position in metres (map frame).
    pub at: [f64; 2],
}

/// A navigation scenario of §4.3.5: a named patrol through waypoints, visited in order.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// Its name (`"hallway"`, `"shops"`).
    pub name: String,
    /// The waypoints in the order they are visited (two or more).
    pub waypoints: Vec<Waypoint>,
}

fn check_positive(what: &str, value: f64) -> Result<(), DisturbanceError> {
    chronomap_core::error::check_positive(what, value).map_err(DisturbanceError::Config)
}

/// A path through the planning grid and its cost.
#[derive(Clone, Debug, PartialEq)]
pub struct GridPath {
    /// The cells from start to goal, both included.
    pub cells: Vec<usize>,
    /// Sum of the edge costs `|u − v| · w(v)`.
    pub cost: f64,
}

/// The least-cost path from cell `from` to cell `to` (Dijkstra on the Moore graph of free
/// cells, [module docs](self); [`PlanningGrid::shortest_path`] with weights): entering cell `v` from its neighbour `u` costs
/// `|u − v| · weights[v]`. Among equally cheap paths the first one found wins (neighbours are
/// visited in a fixed order), so the result is deterministic. `None` if either cell is blocked
/// or no path joins them.
///
/// `weights` has one entry per cell of the grid; weights of free cells must be finite and
/// `> 0` (not checked here: [`run_patrols`] builds them so).
pub fn shortest_path(
    grid: &PlanningGrid,
    weights: &[f64],
    from: usize,
    to: usize,
) -> Option<GridPath> {
    let (cells, cost) = grid.shortest_path(Some(weights), from, to)?;
    Some(GridPath { cells, cost })
}

/// A planned patrol through waypoints.
#[derive(Clone, Debug, PartialEq)]
pub struct Patrol {
    /// The cells visited in order, from the first waypoint to the last (a waypoint between
    /// two legs appears once).
    pub cells: Vec<usize>,
    /// Total predicted cost, the sum of the legs' costs.
    pub cost: f64,
    /// Length in metres (cell centre to cell centre).
    pub length: f64,
}

/// Plans the patrol `waypoints[0] → waypoints[1] → …` (cells of the grid): the least-cost
/// path of every leg ([`shortest_path`]), joined.
///
/// # Errors
/// [`DisturbanceError::Config`] for fewer than two waypoints or `weights` of the wrong length,
/// [`PlanningGridError::WaypointBlocked`] for a blocked waypoint cell,
/// [`DisturbanceError::Unreachable`] if a leg has no path.
pub fn plan_patrol(
    grid: &PlanningGrid,
    weights: &[f64],
    waypoints: &[usize],
) -> Result<Patrol, DisturbanceError> {
    if waypoints.len() < 2 {
        return Err(DisturbanceError::Config(format!(
            "a patrol needs two or more waypoints, not {}",
            waypoints.len()
        )));
    }
    if weights.len() != grid.len() {
        return Err(DisturbanceError::Config(format!(
            "{} cell weights for a grid of {} cells",
            weights.len(),
            grid.len()
        )));
    }
    if let Some(&blocked) = waypoints.iter().find(|&&w| !grid.is_free(w)) {
        let at = grid.centre(blocked);
        return Err(PlanningGridError::WaypointBlocked { at }.into());
    }
    let mut cells = vec![waypoints[0]];
    let mut cost = 0.0;
    for leg in waypoints.windows(2) {
        let path =
            shortest_path(grid, weights, leg[0], leg[1]).ok_or(DisturbanceError::Unreachable {
                from: grid.centre(leg[0]),
                to: grid.centre(leg[1]),
            })?;
        cost += path.cost;
        cells.extend_from_slice(&path.cells[1..]);
    }
    let points: Vec<[f64; 2]> = cells.iter().map(|&c| grid.centre(c)).collect();
    Ok(Patrol {
        cells,
        cost,
        length: polyline_length(&points),
    })
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

fn polyline_length(points: &[[f64; 2]]) -> f64 {
    points.windows(2).map(|w| distance(w[0], w[1])).sum()
}

/// Person detections in time order, checked once so that [`count_encounters`] can search them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Detections(Vec<Event>);

impl Detections {
    /// Checks that every time and position is finite and that times never go backwards.
    ///
    /// # Errors
    /// [`DisturbanceError::BadDetection`] naming the first offending detection.
    pub fn new(events: Vec<Event>) -> Result<Self, DisturbanceError> {
        for (index, e) in events.iter().enumerate() {
            if !(e.t.is_finite() && e.x.is_finite() && e.y.is_finite()) {
                return Err(DisturbanceError::BadDetection {
                    index,
                    reason: "time or position is not a finite number",
                });
            }
            if index > 0 && e.t < events[index - 1].t {
                return Err(DisturbanceError::BadDetection {
                    index,
                    reason: "earlier than the detection before it (detections must be in time order)",
                });
            }
        }
        Ok(Detections(events))
    }

    /// The detections.
    pub fn events(&self) -> &[Event] {
        &self.0
    }

    /// The detections with `from <= t <= until`.
    pub fn between(&self, from: f64, until: f64) -> &[Event] {
        let lo = self.0.partition_point(|e| e.t < from);
        let hi = self.0.partition_point(|e| e.t <= until);
        &self.0[lo..hi.max(lo)]
    }
}

/// Encounters of a robot that leaves `path[0]` at time `start` and follows the polyline `path`
/// at `speed` m/s until its end: the detections with `start <= t <= start + length/speed` that
/// lie within `radius` (inclusive) of the robot's position at their time `t`. Each detection
/// counts once.
pub fn count_encounters(
    path: &[[f64; 2]],
    start: f64,
    speed: f64,
    radius: f64,
    detections: &Detections,
) -> usize {
    let Some(&first) = path.first() else {
        return 0;
    };
    // Arc length at every vertex.
    let mut arc = Vec::with_capacity(path.len());
    let mut s = 0.0;
    arc.push(0.0);
    for w in path.windows(2) {
        s += distance(w[0], w[1]);
        arc.push(s);
    }
    let length = s;
    let end = start + length / speed;
    let position = |t: f64| -> [f64; 2] {
        let s = ((t - start) * speed).clamp(0.0, length);
        // The segment [arc[k], arc[k+1]] containing s.
        let k = arc.partition_point(|&a| a <= s).saturating_sub(1);
        if k + 1 >= path.len() {
            return path[path.len() - 1];
        }
        let span = arc[k + 1] - arc[k];
        if span <= 0.0 {
            return path[k];
        }
        let f = (s - arc[k]) / span;
        [
            path[k][0] + f * (path[k + 1][0] - path[k][0]),
            path[k][1] + f * (path[k + 1][1] - path[k][1]),
        ]
    };
    if path.len() == 1 {
        return detections
            .between(start, start)
            .iter()
            .filter(|e| distance(first, [e.x, e.y]) <= radius)
            .count();
    }
    detections
        .between(start, end)
        .iter()
        .filter(|e| distance(position(e.t), [e.x, e.y]) <= radius)
        .count()
}

/// Eq. (4.22): `E(⌊n_nav ρ⌋)`, the encounters of the `⌊n_nav ρ⌋` patrols of least predicted
/// cost (`n_nav = costs.len()`). Costs are ranked ascending with `f64::total_cmp`; equal costs
/// keep the given order (earlier patrols first). `⌊n_nav ρ⌋` is taken with a tolerance of
/// `1e-9` so that e.g. `ρ = 0.29`, `n_nav = 100` serves 29 patrols although `0.29 · 100` is
/// `28.999999999999996` in `f64`.
///
/// ```
/// use chronomap_activity::disturbance::service_disturbance;
/// // Costs 3, 1, 2, 1: ranked patrols 1, 3 (tie: earlier first), 2, 0.
/// let (costs, encounters) = ([3.0, 1.0, 2.0, 1.0], [100, 1, 10, 5]);
/// assert_eq!(service_disturbance(&costs, &encounters, 0.25)?, 1);
/// assert_eq!(service_disturbance(&costs, &encounters, 0.5)?, 6);
/// assert_eq!(service_disturbance(&costs, &encounters, 1.0)?, 116);
/// # Ok::<(), chronomap_activity::disturbance::DisturbanceError>(())
/// ```
///
/// # Errors
/// [`DisturbanceError::LengthMismatch`], or [`DisturbanceError::Config`] if `ρ` is not in
/// `[0, 1]`.
pub fn service_disturbance(
    costs: &[f64],
    encounters: &[usize],
    ratio: f64,
) -> Result<usize, DisturbanceError> {
    Ok(disturbance_curve(costs, encounters, &[ratio])?[0])
}

/// [`service_disturbance`] at several servicing ratios (ranked once).
///
/// # Errors
/// As [`service_disturbance`].
pub fn disturbance_curve(
    costs: &[f64],
    encounters: &[usize],
    ratios: &[f64],
) -> Result<Vec<usize>, DisturbanceError> {
    if costs.len() != encounters.len() {
        return Err(DisturbanceError::LengthMismatch {
            costs: costs.len(),
            encounters: encounters.len(),
        });
    }
    if let Some(bad) = ratios.iter().find(|r| !(0.0..=1.0).contains(*r)) {
        return Err(DisturbanceError::Config(format!(
            "the servicing ratio {bad} is not in [0, 1]"
        )));
    }
    let mut order: Vec<usize> = (0..costs.len()).collect();
    order.sort_by(|&a, &b| costs[a].total_cmp(&costs[b]));
    let mut cumulative = Vec::with_capacity(order.len() + 1);
    cumulative.push(0usize);
    for &i in &order {
        cumulative.push(cumulative[cumulative.len() - 1] + encounters[i]);
    }
    let n = costs.len() as f64;
    Ok(ratios
        .iter()
        .map(|&rho| cumulative[((n * rho + 1e-9).floor() as usize).min(costs.len())])
        .collect())
}

/// What a patrol's path is planned with.
#[derive(Clone, Copy)]
pub enum PathCost<'a> {
    /// Every cell weighs 1: the shortest path (the *Occupancy Map* baseline of §4.3.5).
    Length,
    /// A cell weighs `max(r̂(centre, t), 0) + ε` for the model's predicted rate `r̂`.
    Rate(&'a dyn RatePredictor),
}

impl std::fmt::Debug for PathCost<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PathCost::Length => f.write_str("Length"),
            PathCost::Rate(model) => write!(f, "Rate({})", model.name()),
        }
    }
}

impl PathCost<'_> {
    /// The weight of every cell of `grid` at model time `t` (blocked cells: `+∞`).
    ///
    /// # Errors
    /// [`DisturbanceError::BadPrediction`] if the model predicts a non-finite rate at a free
    /// cell.
    pub fn weights(
        &self,
        grid: &PlanningGrid,
        t: f64,
        epsilon: f64,
    ) -> Result<Vec<f64>, DisturbanceError> {
        let mut weights = vec![f64::INFINITY; grid.len()];
        let free: Vec<usize> = (0..grid.len()).filter(|&i| grid.is_free(i)).collect();
        match self {
            PathCost::Length => {
                for &i in &free {
                    weights[i] = 1.0;
                }
            }
            PathCost::Rate(model) => {
                let mut at = RateSamples::default();
                for &i in &free {
                    at.push(grid.centre(i), t, 0.0)
                        .map_err(|e| DisturbanceError::Config(e.to_string()))?;
                }
                for (&i, value) in free.iter().zip(model.predict_samples(&at)) {
                    if !value.is_finite() {
                        return Err(DisturbanceError::BadPrediction {
                            at: grid.centre(i),
                            t,
                            value,
                        });
                    }
                    weights[i] = value.max(0.0) + epsilon;
                }
            }
        }
        Ok(weights)
    }
}

/// Parameters of [`run_patrols`].
#[derive(Clone, Debug, PartialEq)]
pub struct DisturbanceConfig {
    /// Robot speed in m/s (§4.3.2: 0.5).
    pub speed: f64,
    /// Encounter radius in metres (§4.3.2: 1).
    pub radius: f64,
    /// `ε` added to every predicted rate (people per hour of observation) in
    /// [`PathCost::Rate`]; keeps weights positive and makes quiet detours cost their length.
    pub epsilon: f64,
    /// The longest a patrol may take in seconds (its slot; a longer one could run beyond the
    /// tracked time).
    pub max_duration: f64,
}

impl Default for DisturbanceConfig {
    /// 0.5 m/s, 1 m, `ε = 1` person per hour, 15-minute slots (four patrols per hour).
    fn default() -> Self {
        DisturbanceConfig {
            speed: 0.5,
            radius: 1.0,
            epsilon: 1.0,
            max_duration: 900.0,
        }
    }
}

impl DisturbanceConfig {
    fn check(&self) -> Result<(), DisturbanceError> {
        check_positive("the speed", self.speed)?;
        check_positive("the encounter radius", self.radius)?;
        check_positive("the patrol slot", self.max_duration)?;
        check_positive("epsilon", self.epsilon)
    }
}

/// When a patrol starts and the time its cost map is predicted for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatrolSlot {
    /// Start of the patrol, in the time of the detections (unix seconds for ATC).
    pub start: f64,
    /// The model's time of the patrol (for the ATC grid: the hour-bin index).
    pub model_t: f64,
}

/// One driven patrol.
#[derive(Clone, Debug, PartialEq)]
pub struct PatrolRun {
    /// Its slot.
    pub slot: PatrolSlot,
    /// Total predicted cost (the ranking key of eq. 4.22).
    pub cost: f64,
    /// Length in metres.
    pub length: f64,
    /// Duration in seconds.
    pub duration: f64,
    /// Person detections within the radius while driving.
    pub encounters: usize,
    /// The cells driven through (shared by all patrols of the same model time).
    pub cells: std::sync::Arc<Vec<usize>>,
}

/// Plans and drives one patrol through `waypoints` (cells of `grid`) per slot, planning once
/// per distinct [`PatrolSlot::model_t`], and counts its encounters ([`count_encounters`]).
///
/// # Errors
/// An invalid `config`, a bad prediction ([`PathCost::weights`]), an error of
/// [`plan_patrol`], or [`DisturbanceError::PatrolTooLong`].
pub fn run_patrols(
    grid: &PlanningGrid,
    waypoints: &[usize],
    cost: &PathCost<'_>,
    slots: &[PatrolSlot],
    detections: &Detections,
    config: &DisturbanceConfig,
) -> Result<Vec<PatrolRun>, DisturbanceError> {
    config.check()?;
    let mut plans: HashMap<u64, (std::sync::Arc<Vec<usize>>, f64, f64)> = HashMap::new();
    let mut runs = Vec::with_capacity(slots.len());
    for &slot in slots {
        let key = (slot.model_t + 0.0).to_bits();
        let (cells, patrol_cost, length) = match plans.get(&key) {
            Some(plan) => plan.clone(),
            None => {
                let weights = cost.weights(grid, slot.model_t, config.epsilon)?;
                let patrol = plan_patrol(grid, &weights, waypoints)?;
                let plan = (
                    std::sync::Arc::new(patrol.cells),
                    patrol.cost,
                    patrol.length,
                );
                plans.insert(key, plan.clone());
                plan
            }
        };
        let duration = length / config.speed;
        if duration > config.max_duration {
            return Err(DisturbanceError::PatrolTooLong {
                start: slot.start,
                duration,
                max: config.max_duration,
            });
        }
        let points: Vec<[f64; 2]> = cells.iter().map(|&c| grid.centre(c)).collect();
        let encounters =
            count_encounters(&points, slot.start, config.speed, config.radius, detections);
        runs.push(PatrolRun {
            slot,
            cost: patrol_cost,
            length,
            duration,
            encounters,
            cells,
        });
    }
    Ok(runs)
}

/// The start times `from + k · every` (`k = 0, 1, …`, before `until`) whose whole slot
/// `[start, start + every]` lies inside one window of tracked time, so that every patrol that
/// fits its slot is watched by the trackers from start to end.
///
/// ```
/// use chronomap_activity::disturbance::patrol_starts;
/// use chronomap_hypertime::events::Window;
///
/// // Tracked 0..2000 s and 2700..4000 s; slots of 900 s.
/// let tracked = [Window { start: 0.0, end: 2000.0 }, Window { start: 2700.0, end: 4000.0 }];
/// assert_eq!(patrol_starts(&tracked, 0.0, 4000.0, 900.0), [0.0, 900.0, 2700.0]);
/// ```
pub fn patrol_starts(tracked: &[Window], from: f64, until: f64, every: f64) -> Vec<f64> {
    let mut starts = Vec::new();
    if !(every > 0.0 && from.is_finite() && until.is_finite()) {
        return starts;
    }
    let mut k = 0u32;
    loop {
        let start = from + f64::from(k) * every;
        if start >= until {
            break;
        }
        if tracked
            .iter()
            .any(|w| w.start <= start && start + every <= w.end)
        {
            starts.push(start);
        }
        k += 1;
    }
    starts
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid from rows of text, top row first: `#` blocked, anything else free.
    fn grid(rows: &[&str]) -> PlanningGrid {
        let (cols, n) = (rows[0].len(), rows.len());
        let mut g = PlanningGrid::new([0.0, 0.0], 1.0, cols, n).unwrap();
        g.keep_only(|c| {
            let (column, row) = (c[0] as usize, c[1] as usize);
            rows[n - 1 - row].as_bytes()[column] != b'#'
        });
        g
    }

    fn cell(g: &PlanningGrid, column: usize, row: usize) -> usize {
        g.cell_at([column as f64 + 0.5, row as f64 + 0.5]).unwrap()
    }

    #[test]
    fn an_obstacle_forces_a_detour() {
        // 5 x 3 cells of 1 m; a wall in column 2 except the top row.
        //   row 2: .....
        //   row 1: ..#..
        //   row 0: ..#..
        let g = grid(&[".....", "..#..", "..#.."]);
        let ones = vec![1.0; g.len()];
        let path = shortest_path(&g, &ones, cell(&g, 0, 0), cell(&g, 4, 0)).unwrap();
        // Over the top: (0,0) → (1,1) √2, → (1,2) 1 (the diagonal to (2,2) would cut the
        // wall's corner), → (2,2) 1, → (3,2) 1, → (4,1) √2, → (4,0) 1.
        let expected = 2.0 * std::f64::consts::SQRT_2 + 4.0;
        assert!((path.cost - expected).abs() < 1e-12, "{}", path.cost);
        assert_eq!(path.cells.len(), 7);
        assert_eq!(path.cells[0], cell(&g, 0, 0));
        assert_eq!(path.cells[6], cell(&g, 4, 0));
        assert!(path.cells.iter().all(|&c| g.is_free(c)));
        // A closed wall: no path.
        let closed = grid(&["..#..", "..#..", "..#.."]);
        let ones = vec![1.0; closed.len()];
        assert_eq!(
            shortest_path(&closed, &ones, cell(&closed, 0, 0), cell(&closed, 4, 0)),
            None
        );
    }

    #[test]
    fn a_costly_cell_is_avoided_when_a_cheaper_detour_exists() {
        // 3 x 2 cells; straight along row 0 passes the busy middle cell (weight 10).
        let g = grid(&["...", "..."]);
        let mut w = vec![1.0; g.len()];
        w[cell(&g, 1, 0)] = 10.0;
        let path = shortest_path(&g, &w, cell(&g, 0, 0), cell(&g, 2, 0)).unwrap();
        // Detour via (1,1): √2 · 1 + √2 · 1.
        assert_eq!(path.cells, [cell(&g, 0, 0), cell(&g, 1, 1), cell(&g, 2, 0)]);
        assert!((path.cost - 2.0 * std::f64::consts::SQRT_2).abs() < 1e-12);
        // If the detour is dearer (weight 10 → 1.2 is cheaper than 2√2 − 1 ≈ 1.83), go straight.
        w[cell(&g, 1, 0)] = 1.2;
        let path = shortest_path(&g, &w, cell(&g, 0, 0), cell(&g, 2, 0)).unwrap();
        assert_eq!(path.cells, [cell(&g, 0, 0), cell(&g, 1, 0), cell(&g, 2, 0)]);
        assert!((path.cost - 2.2).abs() < 1e-12);
    }

    #[test]
    fn patrols_join_their_legs_and_report_unreachable_waypoints() {
        let g = grid(&["....", "...."]);
        let ones = vec![1.0; g.len()];
        let wps = [cell(&g, 0, 0), cell(&g, 3, 0), cell(&g, 3, 1)];
        let p = plan_patrol(&g, &ones, &wps).unwrap();
        assert_eq!(p.cells.len(), 5);
        assert_eq!((p.cost, p.length), (4.0, 4.0));
        let split = grid(&[".#..", ".#.."]);
        let ones = vec![1.0; split.len()];
        assert_eq!(
            plan_patrol(&split, &ones, &[cell(&split, 0, 0), cell(&split, 3, 0)]),
            Err(DisturbanceError::Unreachable {
                from: [0.5, 0.5],
                to: [3.5, 0.5]
            })
        );
        assert_eq!(
            split.waypoint([1.5, 1.5]),
            Err(PlanningGridError::WaypointBlocked { at: [1.5, 1.5] })
        );
        assert_eq!(
            split.waypoint([9.0, 0.0]),
            Err(PlanningGridError::WaypointOutside { at: [9.0, 0.0] })
        );
        assert!(plan_patrol(&split, &ones, &[cell(&split, 0, 0)]).is_err());
    }

    #[test]
    fn encounters_by_hand() {
        // The robot drives (0,0) → (4,0) → (4,2) at 1 m/s from t = 10: at (t − 10, 0) until
        // t = 14, then (4, t − 14) until t = 16.
        let path = [[0.0, 0.0], [4.0, 0.0], [4.0, 2.0]];
        let d = Detections::new(vec![
            Event {
                t: 9.0,
                x: 0.0,
                y: 0.0,
            }, // before the start
            Event {
                t: 10.0,
                x: 0.0,
                y: 1.0,
            }, // at the start, exactly 1 m away: counts
            Event {
                t: 11.0,
                x: 3.0,
                y: 0.0,
            }, // robot at (1, 0): 2 m away
            Event {
                t: 12.0,
                x: 2.5,
                y: 0.5,
            }, // robot at (2, 0): 0.71 m
            Event {
                t: 12.0,
                x: 2.0,
                y: -1.01,
            }, // 1.01 m
            Event {
                t: 15.5,
                x: 3.0,
                y: 1.5,
            }, // robot at (4, 1.5): 1 m
            Event {
                t: 16.0,
                x: 4.0,
                y: 2.0,
            }, // at the end: counts
            Event {
                t: 16.5,
                x: 4.0,
                y: 2.0,
            }, // after the end
        ])
        .unwrap();
        assert_eq!(count_encounters(&path, 10.0, 1.0, 1.0, &d), 4);
        // Half the speed: at t = 12 the robot is at (1, 0) and at 15.5 at (2.75, 0).
        assert_eq!(count_encounters(&path, 10.0, 0.5, 1.0, &d), 1);
        assert_eq!(count_encounters(&[], 10.0, 1.0, 1.0, &d), 0);
        assert_eq!(
            Detections::new(vec![
                Event {
                    t: 2.0,
                    x: 0.0,
                    y: 0.0
                },
                Event {
                    t: 1.0,
                    x: 0.0,
                    y: 0.0
                }
            ])
            .unwrap_err(),
            DisturbanceError::BadDetection {
                index: 1,
                reason: "earlier than the detection before it (detections must be in time order)"
            }
        );
        assert!(
            Detections::new(vec![Event {
                t: 0.0,
                x: f64::NAN,
                y: 0.0
            }])
            .is_err()
        );
    }

    #[test]
    fn eq_4_22_ranks_by_cost_and_keeps_ties_in_order() {
        let costs = [5.0, 2.0, 2.0, 9.0, 2.0];
        let enc = [50, 3, 7, 900, 1];
        // ranked: 1 (3), 2 (7), 4 (1), 0 (50), 3 (900)
        let curve = disturbance_curve(&costs, &enc, &[0.0, 0.2, 0.4, 0.6, 0.8, 1.0]).unwrap();
        assert_eq!(curve, [0, 3, 10, 11, 61, 961]);
        // ⌊5 · 0.5⌋ = 2
        assert_eq!(service_disturbance(&costs, &enc, 0.5).unwrap(), 10);
        // 0.29 · 100 = 28.999999999999996 in f64: still 29 patrols.
        let hundred = [1.0; 100];
        let ones = [1usize; 100];
        assert_eq!(service_disturbance(&hundred, &ones, 0.29).unwrap(), 29);
        assert!(service_disturbance(&costs, &enc, 1.5).is_err());
        assert_eq!(
            service_disturbance(&costs, &enc[..2], 1.0),
            Err(DisturbanceError::LengthMismatch {
                costs: 5,
                encounters: 2
            })
        );
    }

    #[test]
    fn obstacles_block_cells_within_the_clearance() {
        // 2 m raster of 0.1 m pixels: one obstacle pixel centred at (1.05, 1.05).
        let mut blocked = vec![false; 400];
        blocked[10 * 20 + 10] = true;
        let obstacles = ObstacleGrid::new(20, 20, 0.1, [0.0, 0.0], blocked).unwrap();
        assert!(obstacles.obstacle_within([1.05, 0.76], 0.3));
        assert!(!obstacles.obstacle_within([1.05, 0.74], 0.3));
        // Beyond the raster is unknown: blocked.
        assert!(obstacles.obstacle_within([0.1, 0.1], 0.3));
        // Cell centres 0.625, 0.875, 1.125, 1.375: within 0.2 m of the obstacle are
        // (1.125, 1.125) (0.106 m), (0.875, 1.125) and (1.125, 0.875) (0.19 m each).
        let mut g = PlanningGrid::new([0.5, 0.5], 0.25, 4, 4).unwrap();
        g.block_obstacles(&obstacles, 0.2);
        let blocked: Vec<usize> = (0..16).filter(|&i| !g.is_free(i)).collect();
        assert_eq!(blocked, [6, 9, 10]);
        assert_eq!(g.free_count(), 13);
        assert!(ObstacleGrid::new(2, 2, 0.1, [0.0, 0.0], vec![false; 3]).is_err());
    }

    #[test]
    fn plans_are_cached_per_model_time() {
        struct Busy;
        impl RatePredictor for Busy {
            fn name(&self) -> &str {
                "busy"
            }
            // Row 0 is busy at t = 1, quiet at t = 0.
            fn predict(&self, x: [f64; 2], t: f64) -> f64 {
                if x[1] < 1.0 { 100.0 * t } else { 0.0 }
            }
        }
        let g = grid(&["...", "..."]);
        let wps = [cell(&g, 0, 0), cell(&g, 2, 0)];
        let d = Detections::new(vec![Event {
            t: 1.0,
            x: 1.0,
            y: 0.5,
        }])
        .unwrap();
        let slots = [
            PatrolSlot {
                start: 0.0,
                model_t: 0.0,
            },
            PatrolSlot {
                start: 0.0,
                model_t: 1.0,
            },
            PatrolSlot {
                start: 10.0,
                model_t: 0.0,
            },
        ];
        let config = DisturbanceConfig {
            speed: 1.0,
            radius: 0.5,
            epsilon: 1.0,
            max_duration: 10.0,
        };
        let runs = run_patrols(&g, &wps, &PathCost::Rate(&Busy), &slots, &d, &config).unwrap();
        // t = 0: straight (cost 2 · 1). t = 1: up the diagonal to (1,1) (√2 · ε), along the
        // quiet top row to (2,1) (1 · ε) and down into the busy goal (1 · (100 + ε)), which is
        // cheaper than entering it diagonally (√2 · 101).
        assert_eq!(runs[0].cost, 2.0);
        assert_eq!(runs[0].encounters, 1);
        assert_eq!(
            *runs[1].cells,
            [
                cell(&g, 0, 0),
                cell(&g, 1, 1),
                cell(&g, 2, 1),
                cell(&g, 2, 0)
            ]
        );
        assert!((runs[1].cost - (std::f64::consts::SQRT_2 + 102.0)).abs() < 1e-9);
        assert_eq!(runs[1].encounters, 0);
        assert!(std::sync::Arc::ptr_eq(&runs[0].cells, &runs[2].cells));
        let short = DisturbanceConfig {
            max_duration: 1.0,
            ..config
        };
        assert!(matches!(
            run_patrols(&g, &wps, &PathCost::Length, &slots, &d, &short),
            Err(DisturbanceError::PatrolTooLong { .. })
        ));
    }
}
