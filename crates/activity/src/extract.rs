//! Training data of CoPA-Map from pedestrian detections ([Stüde 2024] §4.2.2): a simulated robot
//! drives along [`RobotPath`]s, sees a disc of radius `r` pruned at the obstacles of an
//! [`ObstacleGrid`] by ray casting, and every spatio-temporal cell `S_i` (square of side `r_s`,
//! time bin of length `τ`) it saw becomes one sample of eq. (4.5), `x_i = (x₁, x₂, t)` (the cell
//! centre and bin), with the observed rate of eq. (4.6), `y_i = c_i / Δ_i`: `c_i` detections
//! inside the cell while it was visible, `Δ_i` the time it was visible (`0 < Δ_i ≤ τ`).
//!
//! ```
//! use chronomap_activity::extract::{
//!     ExtractConfig, ObstacleGrid, RobotPath, Waypoint, extract,
//! };
//! use chronomap_hypertime::events::Event;
//!
//! // A free 10 m × 10 m room (0.05 m map cells), a robot standing at (5, 5) for good.
//! let room = ObstacleGrid::free(200, 200, 0.05, [0.0, 0.0])?;
//! let robot = RobotPath::new(vec![Waypoint::new([5.0, 5.0], 60.0)], 0.5)?;
//! // Two people in the cell [5, 5.5) × [5, 5.5) in the first hour, one 9 m away (unseen).
//! let people = [
//!     Event { t: 10.0, x: 5.2, y: 5.3 },
//!     Event { t: 20.0, x: 5.4, y: 5.1 },
//!     Event { t: 30.0, x: 9.9, y: 9.9 },
//! ];
//! let config = ExtractConfig::default(); // r = 3.5 m, r_s = 0.5 m, τ = 3600 s, t0 = 0
//! let data = extract(&room, &[robot], &people, &[0], &config)?;
//! let cell = data.observations.iter().find(|o| o.centre == [5.25, 5.25]).unwrap();
//! assert_eq!((cell.count, cell.duration), (2, 3600.0));
//! assert_eq!(cell.rate_per_hour(), 2.0);
//! assert_eq!(data.total_count(), 2);
//! # Ok::<(), chronomap_activity::extract::ExtractError>(())
//! ```
//!
//! # Model
//! * **Time** is cut into bins `[t0 + kτ, t0 + (k+1)τ)`; sample `t` is the bin index `k` (the
//!   convention of the bundled ATC grid: hour bins). Each bin is simulated in steps of
//!   `dt` ([`ExtractConfig::step_seconds`], `τ` a whole multiple of it); the robots' poses
//!   are taken at the middle of each step, and a cell visible during a step adds `dt` to its
//!   `Δ_i` and counts the detections of that step that fall inside it. So `Δ_i` is a whole
//!   number of steps and a robot that stands still for a bin sees its cells for exactly `τ`.
//! * **Robots** loop along their paths from `t0` on ([`RobotPath::pose_at`] of `t − t0`), at
//!   a constant speed with stops at waypoints. Several robots observe together: a cell seen by
//!   two robots in one step is counted once.
//! * **The field of view** (§4.2.2, Fig. 4.2a): the disc of radius `r` around the robot pruned
//!   at obstacles. A rate cell counts as visible when its *centre* is within `r` of the robot
//!   and the Bresenham line between the map cell of the robot and the map cell of the centre
//!   crosses no blocked map cell (both ends included), as the original `brescount` did on the
//!   map's own cells. Bresenham lines are 8-connected, so a ray can pass between two blocked
//!   cells that touch only at a corner. Centres outside the map are never visible.
//! * **Speed**: the robot's position is snapped to the centre of its map cell (at most half a
//!   map cell away, 0.025 m on the ATC map), so the visible cells of each map cell are computed
//!   once and cached; a day of 1 s steps costs a few hash look-ups per step and detection.
//! * **Units**: `Δ_i` in seconds ([`CellObservation::duration`]); rates in detections per hour
//!   of observation ([`CellObservation::rate_per_hour`]), the unit of [`RateSamples`]. `c_i`
//!   counts detections, not distinct people, so rates scale with the detector's rate.
//! * **Ground truth** (§4.3.2): [`ground_truth`] counts the detections of the given cells
//!   ignoring the map, with `Δ_i = τ`.

use std::collections::HashMap;

use thiserror::Error;

use super::RateSamples;
use chronomap_core::error::check_positive;
use chronomap_core::progress::{NoProgress, Progress};
use chronomap_hypertime::events::Event;
pub use chronomap_spatial::ObstacleGrid;

/// Seconds per hour: rates are per hour of observation.
const HOUR: f64 = 3600.0;

/// Why a map, path, configuration or detection was rejected.
#[derive(Clone, Debug, PartialEq, Error)]
#[non_exhaustive]
pub enum ExtractError {
    /// The obstacle grid is malformed.
    #[error("invalid obstacle grid: {0}")]
    Grid(String),
    /// A robot path is malformed.
    #[error("invalid robot path: {0}")]
    Path(String),
    /// A point of a robot path lies on an obstacle or outside the map.
    #[error(
        "robot {robot}: the path passes ({:.3}, {:.3}), which is {}",
        at[0], at[1], if *.outside { "outside the map" } else { "an obstacle of the map" }
    )]
    PathBlocked {
        /// Index of the robot.
        robot: usize,
        /// The first such point along the path.
        at: [f64; 2],
        /// Whether the point is outside the map (else it is on an obstacle).
        outside: bool,
    },
    /// The configuration is invalid.
    #[error("invalid configuration: {0}")]
    Config(String),
    /// A detection has a NaN or infinite time or coordinate.
    #[error("detection {index}: {field} {value} is not a finite number")]
    NonFinite {
        /// Index of the detection.
        index: usize,
        /// `"t"`, `"x"` or `"y"`.
        field: &'static str,
        /// The offending value.
        value: f64,
    },
}

impl From<chronomap_spatial::ObstacleGridError> for ExtractError {
    fn from(error: chronomap_spatial::ObstacleGridError) -> Self {
        ExtractError::Grid(error.0)
    }
}

/// A point of a robot path and how long the robot stops there (seconds) when it arrives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Waypoint {
    /// Position in metres (map frame).
    pub position: [f64; 2],
    /// Stop on arrival, seconds `>= 0`.
    pub stop: f64,
}

impl Waypoint {
    /// A waypoint at `position` with a stop of `stop` seconds.
    pub fn new(position: [f64; 2], stop: f64) -> Self {
        Waypoint { position, stop }
    }
}

/// One piece of a loop: from `start` to `end` (seconds since the loop began) the robot moves
/// from `from` to `to` (a stop has `from == to`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Leg {
    start: f64,
    end: f64,
    from: [f64; 2],
    to: [f64; 2],
}

/// A robot that patrols a closed loop of waypoints at constant speed, again and again: it
/// starts at waypoint 0, stops there, drives straight to waypoint 1, stops, …, and from the
/// last waypoint back to waypoint 0. (To go back and forth, list the way back.)
#[derive(Clone, Debug, PartialEq)]
pub struct RobotPath {
    waypoints: Vec<Waypoint>,
    speed: f64,
    legs: Vec<Leg>,
    period: f64,
    length: f64,
}

impl RobotPath {
    /// The speed of the simulated robots of §4.3.1, m/s.
    pub const DEFAULT_SPEED: f64 = 0.5;

    /// A loop through `waypoints` at `speed` (m/s).
    ///
    /// # Errors
    /// [`ExtractError::Path`] without waypoints, for a non-finite position, a stop that is
    /// negative or not finite, a speed that is not positive and finite, or a loop that takes
    /// no time (a single waypoint without a stop).
    pub fn new(waypoints: Vec<Waypoint>, speed: f64) -> Result<Self, ExtractError> {
        if waypoints.is_empty() {
            return Err(ExtractError::Path("no waypoints".into()));
        }
        if !(speed.is_finite() && speed > 0.0) {
            return Err(ExtractError::Path(format!(
                "speed {speed} m/s is not a positive number"
            )));
        }
        for (i, w) in waypoints.iter().enumerate() {
            if !(w.position[0].is_finite() && w.position[1].is_finite()) {
                return Err(ExtractError::Path(format!(
                    "waypoint {i}: position {:?} is not finite",
                    w.position
                )));
            }
            if !(w.stop.is_finite() && w.stop >= 0.0) {
                return Err(ExtractError::Path(format!(
                    "waypoint {i}: stop {} s is not a number >= 0",
                    w.stop
                )));
            }
        }
        let mut legs = Vec::with_capacity(2 * waypoints.len());
        let (mut clock, mut length) = (0.0, 0.0);
        for (i, w) in waypoints.iter().enumerate() {
            if w.stop > 0.0 {
                legs.push(Leg {
                    start: clock,
                    end: clock + w.stop,
                    from: w.position,
                    to: w.position,
                });
                clock += w.stop;
            }
            let next = waypoints[(i + 1) % waypoints.len()].position;
            let distance = (next[0] - w.position[0]).hypot(next[1] - w.position[1]);
            if distance > 0.0 {
                legs.push(Leg {
                    start: clock,
                    end: clock + distance / speed,
                    from: w.position,
                    to: next,
                });
                clock += distance / speed;
                length += distance;
            }
        }
        if !(clock > 0.0 && clock.is_finite()) {
            return Err(ExtractError::Path(format!(
                "a loop takes {clock} s (a single waypoint needs a stop > 0)"
            )));
        }
        Ok(RobotPath {
            waypoints,
            speed,
            legs,
            period: clock,
            length,
        })
    }

    /// The waypoints.
    pub fn waypoints(&self) -> &[Waypoint] {
        &self.waypoints
    }

    /// Speed in m/s.
    pub fn speed(&self) -> f64 {
        self.speed
    }

    /// Length of one loop in metres.
    pub fn length(&self) -> f64 {
        self.length
    }

    /// Duration of one loop in seconds (driving plus stops).
    pub fn period(&self) -> f64 {
        self.period
    }

    /// Where the robot is `elapsed` seconds after it started at waypoint 0 (the loop repeats;
    /// negative times count back from the start).
    pub fn pose_at(&self, elapsed: f64) -> [f64; 2] {
        let s = elapsed.rem_euclid(self.period);
        let i = self
            .legs
            .partition_point(|leg| leg.end <= s)
            .min(self.legs.len() - 1);
        let leg = &self.legs[i];
        let f = ((s - leg.start) / (leg.end - leg.start)).clamp(0.0, 1.0);
        [
            leg.from[0] + f * (leg.to[0] - leg.from[0]),
            leg.from[1] + f * (leg.to[1] - leg.from[1]),
        ]
    }

    /// The first point of the loop (sampled every `spacing` metres along each leg, and at every
    /// waypoint) that lies on a blocked cell or off `grid`: `Some((point, outside))`.
    pub fn first_blocked(&self, grid: &ObstacleGrid, spacing: f64) -> Option<([f64; 2], bool)> {
        let spacing = if spacing.is_finite() && spacing > 0.0 {
            spacing
        } else {
            grid.resolution() / 2.0
        };
        let n = self.waypoints.len();
        for i in 0..n {
            let a = self.waypoints[i].position;
            let b = self.waypoints[(i + 1) % n].position;
            let distance = (b[0] - a[0]).hypot(b[1] - a[1]);
            let pieces = (distance / spacing).ceil().max(1.0) as usize;
            for k in 0..=pieces {
                let f = k as f64 / pieces as f64;
                let p = [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])];
                match grid.cell_of(p) {
                    None => return Some((p, true)),
                    Some((c, r)) if grid.is_blocked(c, r) => return Some((p, false)),
                    Some(_) => {}
                }
            }
        }
        None
    }
}

/// Sizes of the field of view, cells and bins.
#[derive(Clone, Debug, PartialEq)]
pub struct ExtractConfig {
    /// Radius `r` of the field of view, metres (3.5 m in the bundled ATC grid).
    pub fov_radius: f64,
    /// Side `r_s` of the square cells, metres; cells are aligned to multiples of it, so cell
    /// `(i, j)` covers `[i·r_s, (i+1)·r_s) × [j·r_s, (j+1)·r_s)`.
    pub cell_size: f64,
    /// Length `τ` of a time bin, seconds.
    pub bin_seconds: f64,
    /// Simulation step `dt`, seconds; `τ` must be a whole multiple of it.
    pub step_seconds: f64,
    /// Start of bin 0 and the time at which every robot leaves waypoint 0, seconds.
    pub t0: f64,
}

impl Default for ExtractConfig {
    fn default() -> Self {
        ExtractConfig {
            fov_radius: 3.5,
            cell_size: 0.5,
            bin_seconds: 3600.0,
            step_seconds: 1.0,
            t0: 0.0,
        }
    }
}

impl ExtractConfig {
    /// Steps per bin.
    fn steps(&self) -> Result<usize, ExtractError> {
        let positive = |name: &str, v: f64| check_positive(name, v).map_err(ExtractError::Config);
        positive("field-of-view radius", self.fov_radius)?;
        positive("cell size", self.cell_size)?;
        positive("bin length", self.bin_seconds)?;
        positive("step", self.step_seconds)?;
        if !self.t0.is_finite() {
            return Err(ExtractError::Config(format!(
                "t0 {} is not finite",
                self.t0
            )));
        }
        let steps = (self.bin_seconds / self.step_seconds).round();
        let whole = (steps * self.step_seconds - self.bin_seconds).abs() <= 1e-9 * self.bin_seconds;
        if !(steps >= 1.0 && whole && steps <= u32::MAX as f64) {
            return Err(ExtractError::Config(format!(
                "the bin length {} s is not a whole multiple of the step {} s",
                self.bin_seconds, self.step_seconds
            )));
        }
        Ok(steps as usize)
    }

    /// The index `(i, j)` of the cell containing `p`.
    fn cell_index(&self, p: [f64; 2]) -> [i64; 2] {
        [
            (p[0] / self.cell_size).floor() as i64,
            (p[1] / self.cell_size).floor() as i64,
        ]
    }

    /// The centre of cell `(i, j)`.
    fn cell_centre(&self, cell: [i64; 2]) -> [f64; 2] {
        [
            (cell[0] as f64 + 0.5) * self.cell_size,
            (cell[1] as f64 + 0.5) * self.cell_size,
        ]
    }

    /// The bin containing time `t`, and the step within it.
    fn bin_and_step(&self, t: f64, steps: usize) -> (i64, usize) {
        let since = t - self.t0;
        let bin = (since / self.bin_seconds).floor();
        let within = since - bin * self.bin_seconds;
        let step = ((within / self.step_seconds).floor().max(0.0) as usize).min(steps - 1);
        (bin as i64, step)
    }

    /// The middle of step `step` of bin `bin`.
    fn step_time(&self, bin: i64, step: usize) -> f64 {
        self.t0 + bin as f64 * self.bin_seconds + (step as f64 + 0.5) * self.step_seconds
    }
}

/// What was seen of one spatio-temporal cell `S_i`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellObservation {
    /// Cell centre `(x₁, x₂)`, metres.
    pub centre: [f64; 2],
    /// Time bin `k` (the bin `[t0 + kτ, t0 + (k+1)τ)`).
    pub bin: i64,
    /// Detections `c_i` inside the cell while it was visible.
    pub count: u64,
    /// Observed duration `Δ_i`, seconds (`0 < Δ_i ≤ τ`).
    pub duration: f64,
}

impl CellObservation {
    /// The rate of eq. (4.6), `c_i / Δ_i`, in detections per hour of observation.
    pub fn rate_per_hour(&self) -> f64 {
        self.count as f64 * HOUR / self.duration
    }
}

/// The samples of eqs. (4.5)–(4.6): one [`CellObservation`] per observed cell and bin, sorted
/// by bin, then `x₁`, then `x₂`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Extraction {
    /// The observed cells.
    pub observations: Vec<CellObservation>,
}

impl Extraction {
    /// The samples as rates: `x` the cell centre, `t` the bin index, `y` detections per hour
    /// of observation ([`CellObservation::rate_per_hour`]).
    pub fn to_rate_samples(&self) -> RateSamples {
        let mut samples = RateSamples::default();
        for o in &self.observations {
            samples
                .push(o.centre, o.bin as f64, o.rate_per_hour())
                .expect("centres, bins and rates are finite and rates >= 0");
        }
        samples
    }

    /// Observed durations in hours (the dwell times of
    /// [`FrAam::fit_with_dwell`](super::FrAam::fit_with_dwell)), aligned with
    /// [`Extraction::to_rate_samples`].
    pub fn dwell_hours(&self) -> Vec<f64> {
        self.observations
            .iter()
            .map(|o| o.duration / HOUR)
            .collect()
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.observations.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.observations.is_empty()
    }

    /// Sum of the counts.
    pub fn total_count(&self) -> u64 {
        self.observations.iter().map(|o| o.count).sum()
    }

    /// Sum of the observed durations, seconds.
    pub fn total_duration(&self) -> f64 {
        self.observations.iter().map(|o| o.duration).sum()
    }

    /// The distinct cell centres, sorted by `x₁`, then `x₂`.
    pub fn cells(&self) -> Vec<[f64; 2]> {
        let mut cells: Vec<[f64; 2]> = self.observations.iter().map(|o| o.centre).collect();
        cells.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
        cells.dedup();
        cells
    }
}

/// The rate cells visible from the centre of one map cell, as dense ids, sorted.
type VisibleSet = Vec<u32>;

/// Visible sets per robot map cell, and the dense numbering of the rate cells met so far.
struct FieldOfView<'a> {
    grid: &'a ObstacleGrid,
    config: &'a ExtractConfig,
    cache: HashMap<(usize, usize), VisibleSet>,
    ids: HashMap<[i64; 2], u32>,
    cells: Vec<[i64; 2]>,
}

impl<'a> FieldOfView<'a> {
    fn new(grid: &'a ObstacleGrid, config: &'a ExtractConfig) -> Self {
        FieldOfView {
            grid,
            config,
            cache: HashMap::new(),
            ids: HashMap::new(),
            cells: Vec::new(),
        }
    }

    /// The visible set of map cell `key`, computed on first use.
    fn visible(&mut self, key: (usize, usize)) -> &VisibleSet {
        if !self.cache.contains_key(&key) {
            let cells = visible_cells_from(self.grid, key, self.config);
            let mut set: VisibleSet = cells
                .into_iter()
                .map(|cell| {
                    *self.ids.entry(cell).or_insert_with(|| {
                        self.cells.push(cell);
                        (self.cells.len() - 1) as u32
                    })
                })
                .collect();
            set.sort_unstable();
            self.cache.insert(key, set);
        }
        &self.cache[&key]
    }
}

/// The rate cells `(i, j)` whose centres are visible from the centre of map cell `from`.
fn visible_cells_from(
    grid: &ObstacleGrid,
    from: (usize, usize),
    config: &ExtractConfig,
) -> Vec<[i64; 2]> {
    let o = grid.centre(from.0, from.1);
    let r = config.fov_radius;
    let rs = config.cell_size;
    let lo = config.cell_index([o[0] - r, o[1] - r]);
    let hi = config.cell_index([o[0] + r, o[1] + r]);
    let mut cells = Vec::new();
    for i in lo[0]..=hi[0] {
        for j in lo[1]..=hi[1] {
            let c = [(i as f64 + 0.5) * rs, (j as f64 + 0.5) * rs];
            let (dx, dy) = (c[0] - o[0], c[1] - o[1]);
            if dx * dx + dy * dy > r * r {
                continue;
            }
            if let Some(to) = grid.cell_of(c)
                && grid.line_of_sight(from, to)
            {
                cells.push([i, j]);
            }
        }
    }
    cells
}

/// The centres of the cells visible from the point `from` (the field of view of §4.2.2, as
/// [`extract`] computes it: `from` snapped to the centre of its map cell, cells whose centre
/// is within the radius and in sight), sorted by `x₁`, then `x₂`. Empty if `from` is off the
/// map or on an obstacle.
///
/// # Errors
/// [`ExtractError::Config`] for an invalid configuration.
pub fn visible_cells(
    grid: &ObstacleGrid,
    from: [f64; 2],
    config: &ExtractConfig,
) -> Result<Vec<[f64; 2]>, ExtractError> {
    config.steps()?;
    let Some(key) = grid.cell_of(from) else {
        return Ok(Vec::new());
    };
    if grid.is_blocked(key.0, key.1) {
        return Ok(Vec::new());
    }
    let mut cells = visible_cells_from(grid, key, config);
    cells.sort_unstable();
    Ok(cells.into_iter().map(|c| config.cell_centre(c)).collect())
}

fn check_detections(detections: &[Event]) -> Result<(), ExtractError> {
    match detections
        .iter()
        .enumerate()
        .find_map(|(index, d)| Some((index, d.non_finite()?)))
    {
        Some((index, (field, value))) => Err(ExtractError::NonFinite {
            index,
            field,
            value,
        }),
        None => Ok(()),
    }
}

/// Sorted distinct bins.
fn distinct_bins(bins: &[i64]) -> Result<Vec<i64>, ExtractError> {
    if bins.is_empty() {
        return Err(ExtractError::Config("no time bins".into()));
    }
    let mut bins = bins.to_vec();
    bins.sort_unstable();
    bins.dedup();
    Ok(bins)
}

/// The training data of §4.2.2, eqs. (4.5)–(4.6): what `robots` (observing together) see of the
/// `detections` (any order) during the time bins `bins` (indices `k` of
/// `[t0 + kτ, t0 + (k+1)τ)`, any order, repeats ignored). See the [module docs](self) for the
/// model; cells never visible in a bin have no sample.
///
/// # Errors
/// [`ExtractError::Config`] for an invalid configuration or no bins,
/// [`ExtractError::Path`] without robots, [`ExtractError::PathBlocked`] if a path leaves the map
/// or crosses an obstacle (checked every half map cell), [`ExtractError::NonFinite`] for a bad
/// detection.
pub fn extract(
    grid: &ObstacleGrid,
    robots: &[RobotPath],
    detections: &[Event],
    bins: &[i64],
    config: &ExtractConfig,
) -> Result<Extraction, ExtractError> {
    extract_with_progress(grid, robots, detections, bins, config, &NoProgress)
}

/// [`extract`], reporting the stage `bins` with one step per time bin simulated to
/// `progress`. The result is the same.
///
/// # Errors
/// As [`extract`].
pub fn extract_with_progress(
    grid: &ObstacleGrid,
    robots: &[RobotPath],
    detections: &[Event],
    bins: &[i64],
    config: &ExtractConfig,
    progress: &dyn Progress,
) -> Result<Extraction, ExtractError> {
    let steps = config.steps()?;
    let bins = distinct_bins(bins)?;
    if robots.is_empty() {
        return Err(ExtractError::Path("no robots".into()));
    }
    for (robot, path) in robots.iter().enumerate() {
        if let Some((at, outside)) = path.first_blocked(grid, grid.resolution() / 2.0) {
            return Err(ExtractError::PathBlocked { robot, at, outside });
        }
    }
    check_detections(detections)?;

    let mut fov = FieldOfView::new(grid, config);
    // The map cells of the robots in a step (a pose off the map, which the check above rules
    // out up to rounding, sees nothing).
    let pose_keys = |bin: i64, step: usize| -> Vec<(usize, usize)> {
        let elapsed = config.step_time(bin, step) - config.t0;
        robots
            .iter()
            .filter_map(|path| grid.cell_of(path.pose_at(elapsed)))
            .collect()
    };

    // Δ: visible steps per (bin, cell); a cell seen by several robots in one step counts once.
    let mut visible_steps: Vec<Vec<u32>> = vec![Vec::new(); bins.len()];
    let mut stamp: Vec<u64> = Vec::new();
    let mut clock: u64 = 0;
    progress.stage("bins", bins.len() as u64);
    for (b, &bin) in bins.iter().enumerate() {
        let row = &mut visible_steps[b];
        for step in 0..steps {
            clock += 1;
            for key in pose_keys(bin, step) {
                for &id in fov.visible(key) {
                    let id = id as usize;
                    if stamp.len() <= id {
                        stamp.resize(id + 1, 0);
                    }
                    if row.len() <= id {
                        row.resize(id + 1, 0);
                    }
                    if stamp[id] != clock {
                        stamp[id] = clock;
                        row[id] += 1;
                    }
                }
            }
        }
        progress.advance(1);
    }

    // c: detections inside a cell visible in the detection's step (every pose of that step
    // is in the cache already).
    let mut counts: Vec<Vec<u64>> = visible_steps.iter().map(|r| vec![0; r.len()]).collect();
    for d in detections {
        let (bin, step) = config.bin_and_step(d.t, steps);
        let Ok(b) = bins.binary_search(&bin) else {
            continue;
        };
        let Some(&id) = fov.ids.get(&config.cell_index([d.x, d.y])) else {
            continue;
        };
        let seen = pose_keys(bin, step)
            .into_iter()
            .any(|key| fov.visible(key).binary_search(&id).is_ok());
        if seen && (id as usize) < counts[b].len() {
            counts[b][id as usize] += 1;
        }
    }

    let mut observations = Vec::new();
    for (b, &bin) in bins.iter().enumerate() {
        let mut row: Vec<CellObservation> = visible_steps[b]
            .iter()
            .enumerate()
            .filter(|&(_, &n)| n > 0)
            .map(|(id, &n)| CellObservation {
                centre: config.cell_centre(fov.cells[id]),
                bin,
                count: counts[b][id],
                duration: f64::from(n) * config.step_seconds,
            })
            .collect();
        row.sort_by(|a, b| {
            a.centre[0]
                .total_cmp(&b.centre[0])
                .then(a.centre[1].total_cmp(&b.centre[1]))
        });
        observations.extend(row);
    }
    Ok(Extraction { observations })
}

/// The ground truth of §4.3.2: for every bin of `bins` and every cell whose centre is in
/// `cells` (the cells visited during training; repeats ignored), the number of `detections`
/// inside the cell during the bin, ignoring the map, with `Δ_i = τ`. Sorted by bin, then `x₁`,
/// then `x₂`; every (bin, cell) pair has a sample, counts of 0 included.
///
/// # Errors
/// [`ExtractError::Config`] for an invalid configuration, no bins or a non-finite cell centre;
/// [`ExtractError::NonFinite`] for a bad detection.
pub fn ground_truth(
    detections: &[Event],
    cells: &[[f64; 2]],
    bins: &[i64],
    config: &ExtractConfig,
) -> Result<Extraction, ExtractError> {
    let steps = config.steps()?;
    let bins = distinct_bins(bins)?;
    check_detections(detections)?;
    let mut indices = Vec::with_capacity(cells.len());
    for c in cells {
        if !(c[0].is_finite() && c[1].is_finite()) {
            return Err(ExtractError::Config(format!(
                "cell centre {c:?} is not finite"
            )));
        }
        indices.push(config.cell_index(*c));
    }
    indices.sort_unstable();
    indices.dedup();
    let ids: HashMap<[i64; 2], usize> = indices.iter().enumerate().map(|(i, &c)| (c, i)).collect();
    let mut counts = vec![vec![0u64; indices.len()]; bins.len()];
    for d in detections {
        let (bin, _) = config.bin_and_step(d.t, steps);
        if let (Ok(b), Some(&id)) = (
            bins.binary_search(&bin),
            ids.get(&config.cell_index([d.x, d.y])),
        ) {
            counts[b][id] += 1;
        }
    }
    let observations = bins
        .iter()
        .zip(&counts)
        .flat_map(|(&bin, row)| {
            indices
                .iter()
                .zip(row)
                .map(move |(&cell, &count)| CellObservation {
                    centre: config.cell_centre(cell),
                    bin,
                    count,
                    duration: config.bin_seconds,
                })
        })
        .collect();
    Ok(Extraction { observations })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A free 10 m × 10 m room of 0.05 m cells, origin (0, 0).
    fn room() -> ObstacleGrid {
        ObstacleGrid::free(200, 200, 0.05, [0.0, 0.0]).unwrap()
    }

    /// A valid loop through `(position, stop seconds)` waypoints at `speed` m/s.
    fn robot_path(waypoints: &[([f64; 2], f64)], speed: f64) -> RobotPath {
        let waypoints = waypoints.iter().map(|&(at, stop)| Waypoint::new(at, stop));
        RobotPath::new(waypoints.collect(), speed).unwrap()
    }

    fn standing(at: [f64; 2]) -> RobotPath {
        robot_path(&[(at, 10.0)], 0.5)
    }

    fn event(t: f64, x: f64, y: f64) -> Event {
        Event { t, x, y }
    }

    #[test]
    fn bresenham_is_blocked_by_a_wall_and_passes_beside_it() {
        let mut g = room();
        // A wall at x ∈ [5, 5.1], y ∈ [3, 7].
        g.block_rectangle([5.0, 3.0], [5.1, 7.0]);
        assert_eq!(g.blocked_count(), 2 * 80);
        assert!(!g.visible([4.0, 5.0], [6.0, 5.0]));
        assert!(!g.visible([6.0, 5.0], [4.0, 5.0]));
        assert!(g.visible([4.0, 5.0], [4.9, 5.0]));
        // Passing below the wall's end.
        assert!(g.visible([4.0, 2.0], [6.0, 2.5]));
        // Off the map or onto the wall itself: not visible.
        assert!(!g.visible([4.0, 5.0], [10.5, 5.0]));
        assert!(!g.visible([4.0, 5.0], [5.05, 5.0]));
        // Bresenham lines are 8-connected: the anti-diagonal from cell (70, 91) to (91, 70)
        // slips between the cells (80, 80) and (81, 81) of a diagonal chain ...
        let mut d = room();
        for k in 0..40 {
            d.set_blocked(60 + k, 60 + k, true);
        }
        assert_eq!(d.cell_of([3.525, 4.575]), Some((70, 91)));
        assert!(d.visible([3.525, 4.575], [4.575, 3.525]));
        // ... but not through a 4-connected one, nor along a line through a chain cell.
        assert!(!d.visible([3.525, 4.525], [4.525, 3.525]));
        for k in 0..40 {
            d.set_blocked(61 + k, 60 + k, true);
        }
        assert!(!d.visible([3.525, 4.575], [4.575, 3.525]));
    }

    #[test]
    fn field_of_view_is_a_disc_of_centres_pruned_by_the_wall() {
        let mut g = room();
        let config = ExtractConfig {
            fov_radius: 1.0,
            ..ExtractConfig::default()
        };
        // The robot snaps to the map cell centre (5.025, 5.025). The 0.5 m cells centred at
        // x, y ∈ {4.25, 4.75, 5.25, 5.75} are within 1 m (0.32 to 0.82 m) except the four
        // corners (1.03 to 1.10 m): 12 cells.
        let open = visible_cells(&g, [5.03, 5.03], &config).unwrap();
        assert_eq!(open.len(), 12);
        assert!(open.contains(&[5.75, 5.25]));
        assert!(!open.contains(&[5.75, 5.75]));
        // A wall x ∈ [5.4, 5.5] hides the two cells centred at x = 5.75.
        g.block_rectangle([5.4, 0.0], [5.5, 10.0]);
        let walled = visible_cells(&g, [5.03, 5.03], &config).unwrap();
        assert_eq!(walled.len(), 10);
        assert!(!walled.contains(&[5.75, 5.25]) && !walled.contains(&[5.75, 4.75]));
        assert!(walled.contains(&[5.25, 5.25]));
        // From inside the wall or off the map nothing is seen.
        assert!(visible_cells(&g, [5.45, 5.0], &config).unwrap().is_empty());
        assert!(visible_cells(&g, [-1.0, 5.0], &config).unwrap().is_empty());
    }

    #[test]
    fn path_poses_loop_with_stops() {
        // 0 → (4, 0), stop 2 s at both ends, 2 m/s: stop 2, drive 2, stop 2, drive 2.
        let p = robot_path(&[([0.0, 0.0], 2.0), ([4.0, 0.0], 2.0)], 2.0);
        assert_eq!((p.period(), p.length()), (8.0, 8.0));
        assert_eq!(p.pose_at(1.0), [0.0, 0.0]);
        assert_eq!(p.pose_at(3.0), [2.0, 0.0]);
        assert_eq!(p.pose_at(5.0), [4.0, 0.0]);
        assert_eq!(p.pose_at(7.5), [1.0, 0.0]);
        assert_eq!(p.pose_at(9.0), [0.0, 0.0]);
        assert_eq!(p.pose_at(-1.0), [2.0, 0.0]);
        assert!(RobotPath::new(vec![], 0.5).is_err());
        assert!(RobotPath::new(vec![Waypoint::new([0.0, 0.0], 0.0)], 0.5).is_err());
        assert!(RobotPath::new(vec![Waypoint::new([0.0, 0.0], -1.0)], 0.5).is_err());
        assert!(RobotPath::new(vec![Waypoint::new([0.0, 0.0], 1.0)], 0.0).is_err());
        let mut g = room();
        g.block_rectangle([2.0, -1.0], [2.1, 1.0]);
        let through = robot_path(&[([1.0, 0.5], 0.0), ([4.0, 0.5], 0.0)], 0.5);
        let (at, outside) = through.first_blocked(&g, 0.025).unwrap();
        assert!(!outside && (2.0..=2.1).contains(&at[0]), "{at:?}");
        let off = robot_path(&[([1.0, 0.5], 0.0), ([1.0, -0.5], 0.0)], 0.5);
        assert!(off.first_blocked(&g, 0.025).unwrap().1);
    }

    #[test]
    fn standing_robot_sees_its_cells_for_exactly_a_bin() {
        let config = ExtractConfig {
            fov_radius: 1.0,
            bin_seconds: 60.0,
            t0: 1000.0,
            ..ExtractConfig::default()
        };
        let people = [
            event(1000.0, 5.1, 5.1),  // bin 0, seen
            event(1059.9, 5.6, 5.2),  // bin 0, seen (cell (5.75, 5.25))
            event(1060.0, 5.1, 5.1),  // bin 1, not extracted
            event(999.0, 5.1, 5.1),   // bin -1, not extracted
            event(1010.0, 8.0, 8.0),  // out of sight
            event(1020.0, 5.75, 5.9), // (5.75, 5.75): centre 1.03 m away, out of sight
        ];
        let data = extract(&room(), &[standing([5.03, 5.03])], &people, &[0], &config).unwrap();
        assert_eq!(data.len(), 12);
        assert!(data.observations.iter().all(|o| o.duration == 60.0));
        assert_eq!(data.total_duration(), 12.0 * 60.0);
        assert_eq!(data.total_count(), 2);
        let samples = data.to_rate_samples();
        assert_eq!(samples.y().iter().filter(|&&y| y == 60.0).count(), 2);
        assert_eq!(data.dwell_hours()[0], 60.0 / 3600.0);
        // Two robots at the same place see every cell once per step.
        let twice = extract(
            &room(),
            &[standing([5.03, 5.03]), standing([5.01, 5.04])],
            &people,
            &[0, 0],
            &config,
        )
        .unwrap();
        assert_eq!(twice, data);
    }

    #[test]
    fn moving_robot_accumulates_partial_durations_and_counts_only_while_visible() {
        // Along y = 5.025 from x = 1.025 to 9.025 and back at 1 m/s: a loop of 16 s. Step
        // middles put the robot on the map-cell centres x = 1.525 + k (k = 0..7), each once
        // forward and once back. With r = 0.5 m the pose 1.525 + k sees exactly the cells
        // centred at x ∈ {1.25 + k, 1.75 + k}, y ∈ {4.75, 5.25} (0.32 to 0.39 m away; the next
        // ones are 0.73 m away), so the 32 cells x 1.25 .. 8.75 are each seen for 2 s a loop.
        let path = robot_path(&[([1.025, 5.025], 0.0), ([9.025, 5.025], 0.0)], 1.0);
        assert_eq!(path.period(), 16.0);
        let config = ExtractConfig {
            fov_radius: 0.5,
            bin_seconds: 16.0,
            ..ExtractConfig::default()
        };
        let people = [
            event(3.7, 4.7, 5.2),  // step 3: robot at 4.525 sees (4.75, 5.25)
            event(6.5, 4.7, 5.2),  // step 6: robot at 7.525, cell out of sight
            event(11.2, 5.3, 4.9), // step 11: robot back at 5.525 sees (5.25, 4.75)
            event(12.0, 4.7, 5.2), // step 12: robot at 4.525 again
            event(20.0, 4.7, 5.2), // bin 1, step 4: robot at 5.525, out of sight
        ];
        let data = extract(&room(), &[path], &people, &[1, 0], &config).unwrap();
        assert_eq!(data.len(), 2 * 32);
        assert!(data.observations.iter().all(|o| o.duration == 2.0));
        assert_eq!(data.total_duration(), 128.0);
        let cells = data.cells();
        assert_eq!(
            (cells.len(), cells[0], cells[31]),
            (32, [1.25, 4.75], [8.75, 5.25])
        );
        let seen: Vec<(i64, [f64; 2], u64)> = data
            .observations
            .iter()
            .filter(|o| o.count > 0)
            .map(|o| (o.bin, o.centre, o.count))
            .collect();
        assert_eq!(seen, [(0, [4.75, 5.25], 2), (0, [5.25, 4.75], 1)]);
        assert_eq!(data.observations[0].bin, 0);
        let busy = data.observations.iter().find(|o| o.count == 2).unwrap();
        assert_eq!(busy.rate_per_hour(), 3600.0);
    }

    #[test]
    fn ground_truth_counts_every_cell_for_the_whole_bin() {
        let config = ExtractConfig {
            bin_seconds: 100.0,
            ..ExtractConfig::default()
        };
        let people = [
            event(5.0, 0.1, 0.1),
            event(50.0, 0.4, 0.2),
            event(150.0, 0.1, 0.1),
            event(150.0, 3.0, 3.0),
        ];
        let gt = ground_truth(
            &people,
            &[[0.25, 0.25], [0.75, 0.25], [0.25, 0.25]],
            &[1, 0],
            &config,
        )
        .unwrap();
        let got: Vec<(i64, [f64; 2], u64, f64)> = gt
            .observations
            .iter()
            .map(|o| (o.bin, o.centre, o.count, o.duration))
            .collect();
        assert_eq!(
            got,
            [
                (0, [0.25, 0.25], 2, 100.0),
                (0, [0.75, 0.25], 0, 100.0),
                (1, [0.25, 0.25], 1, 100.0),
                (1, [0.75, 0.25], 0, 100.0),
            ]
        );
        assert_eq!(gt.observations[0].rate_per_hour(), 72.0);
    }

    #[test]
    fn bad_configuration_and_detections_are_errors() {
        let g = room();
        let robots = [standing([5.0, 5.0])];
        let bad = ExtractConfig {
            step_seconds: 7.0,
            ..ExtractConfig::default()
        };
        assert!(matches!(
            extract(&g, &robots, &[], &[0], &bad),
            Err(ExtractError::Config(_))
        ));
        let config = ExtractConfig::default();
        assert!(extract(&g, &robots, &[], &[], &config).is_err());
        assert!(extract(&g, &[], &[], &[0], &config).is_err());
        let nan = [event(0.0, f64::NAN, 0.0)];
        assert_eq!(
            extract(&g, &robots, &nan, &[0], &config)
                .unwrap_err()
                .to_string(),
            "detection 0: x NaN is not a finite number"
        );
        let outside = [standing([11.0, 5.0])];
        assert!(matches!(
            extract(&g, &outside, &[], &[0], &config),
            Err(ExtractError::PathBlocked {
                robot: 0,
                outside: true,
                ..
            })
        ));
        assert!(ObstacleGrid::new(2, 2, 0.05, [0.0, 0.0], vec![false; 3]).is_err());
        assert!(ObstacleGrid::new(2, 2, 0.0, [0.0, 0.0], vec![false; 4]).is_err());
    }
}
