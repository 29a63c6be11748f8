//! The person search behavior tree, PSBT ([Stüde 2024] §5.4): when a robot needs a person's help,
//! synthesise the stochastic behavior tree of searching and waiting that most likely finds
//! someone within a look-ahead time, from a model of human activity `λ(x, t)`.
//!
//! ```
//! use chronomap_spatial::PlanningGrid;
//! use chronomap_psbt::{GammaPrior, GridPoisson, GridSpec, PsbtConfig, synthesize, Step};
//! use chronomap_core::Parallelism;
//!
//! // A corridor of 40 x 4 m (0.5 m planning cells); people pass its east end, 30 m away.
//! let grid = PlanningGrid::new([0.0, 0.0], 0.5, 80, 8)?;
//! let spec = GridSpec { origin: [0.0, 0.0], cell: 1.0, cols: 40, rows: 4, t0: 0.0,
//!                       interval: 3600.0, intervals: 1 };
//! let mut model = GridPoisson::new(spec, GammaPrior::default())?;
//! for x in 34..40 {
//!     for y in 0..4 {
//!         model.observe([x as f64 + 0.5, y as f64 + 0.5], 0.0, 180.0, 3600.0)?; // 1 per 20 s
//!     }
//! }
//! let config = PsbtConfig::default();
//! let found = synthesize(&grid, &model, [2.0, 2.0], 100.0, &config, 1, Parallelism::Sequential)?;
//! // Waiting at the empty west end is hopeless: the tree drives east and waits there.
//! assert!(found.p_success > 0.5);
//! assert!(matches!(found.tree.phases.last().unwrap().step, Step::Wait { at, .. } if at[0] > 30.0));
//! # Ok::<(), chronomap_psbt::PsbtError>(())
//! ```
//!
//! # The model (§5.4.1–§5.4.3)
//! * **Activity** ([`RateField`]): `λ(x, t)`, people per second and square metre; the grid
//!   Poisson model of eq. 5.7 is [`GridPoisson`]. Every rate is taken at the time help is
//!   requested (`t = t₀` in eqs. 5.9 and 5.14).
//! * **Actions** ([`actions`]): *wait at x_i* (eqs. 5.9–5.12), *search from x_i to x_j* along
//!   the A* path of the planning grid (eqs. 5.13–5.19, [`path`]), and *move to x₀*, a search
//!   that can only fail by navigation. Each becomes an SBT action `⟨p_s, μ, ν⟩`
//!   ([`chronomap_bt_stochastic`]).
//! * **Places** ([`places`]): `n_pl` cells within `max_distance_m` of path from the help
//!   location `x₀`, sampled `∝ ∫_cell λ`, one per detection radius `r_D` (the larger rate
//!   kept); their order is an open TSP over the expected times to fail `ν_{sp,i→j}⁻¹`.
//! * **Candidate trees** (Fig. 5.9, [`Candidates`]): at each place, in order, the robot skips
//!   it, searches its way to it, or searches to it and waits there; `3^{n_pl}` trees, plus
//!   waiting at `x₀` (W): `3^{n_pl} + 1`. A tree is
//!   `Sequence(Fallback(a₁, a₂, …), MoveTo x₀)`: the actions run until one finds a person, then
//!   the robot returns. The return is analysed from the place of the action that succeeded
//!   (its target place), so each action's success leads to its own *move to x₀*; a failed
//!   return fails the tree.
//! * **Choice**: the tree of maximum `p_{s,T}(t_max)` (eq. 5.1). Its expected time to success
//!   is `E[T | S]` of its chain ([`chronomap_bt_stochastic::Chain::means`]).
//!
//! # Fast synthesis
//! Every candidate is a chain of phases, and candidates share prefixes. [`Candidates::best`]
//! walks the tree of choices depth first with one uniformisation rate `Λ` for all candidate
//! actions: the probability mass entering an action at jump `k` of the uniformised chain
//! passes through the action's two phases (first-order recursions in `k`); what leaves by
//! failure enters the next action, what leaves by success passes the return and is absorbed
//! in `S` at jump `k`, where it counts `P(N(Λ t_max) ≥ k)` towards `p_{s,T}(t_max)`. Each
//! action costs `O(K)` (`K ≈ Λ t_max`), each choice of the walk one or two actions, so all
//! `3^n` candidates cost `O(3^n K)` instead of `3^n` dense chains. The straightforward
//! reference (one dense generator per tree, [`chronomap_bt_stochastic::dense`]) is
//! [`Candidates::reference_values`]; the tests assert both agree.
//!
//! # Evaluation (§5.4.4)
//! [`world::grid_poisson_from_tracks`] learns the grid Poisson model of eq. 5.7 from
//! pedestrian tracks over a map; [`eval`] plans every strategy from one help location;
//! [`compare`] runs Fig. 5.11's comparison over many random help locations and summarises it.
#![deny(missing_docs)]

pub mod actions;
pub mod compare;
pub mod eval;
pub mod field;
pub mod path;
pub mod places;
mod synth;
pub mod world;

pub use field::{GammaPrior, GridPoisson, GridSpec, RateField, copa_field};
pub use places::TspConfig;
pub use synth::{
    Candidates, Choice, DiscCache, Method, Plan, SearchContext, Synthesis, synthesize,
};

use thiserror::Error;

use chronomap_bt_stochastic::{Action, Chain, Means, SbtError, Target, add_scaled};
use chronomap_core::error::check_positive;
use chronomap_core::num::fmt_number;
use chronomap_spatial::PlanningGrid;
use path::CellPath;

/// Why a person search could not be planned.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum PsbtError {
    /// A parameter is out of range.
    #[error("invalid configuration: {0}")]
    Config(String),
    /// The help location lies outside the planning grid (off the map).
    #[error("the start ({}, {}) lies outside the map", fmt_number(.at[0]), fmt_number(.at[1]))]
    StartOutside {
        /// The start.
        at: [f64; 2],
    },
    /// The help location is in a blocked cell (an obstacle within the robot's clearance).
    #[error(
        "the start ({}, {}) is on an obstacle (or within the robot's clearance of one)",
        fmt_number(.at[0]),
        fmt_number(.at[1])
    )]
    StartBlocked {
        /// The start.
        at: [f64; 2],
    },
    /// Two places are not connected by free cells.
    #[error(
        "no path from ({}, {}) to ({}, {})",
        fmt_number(.from[0]),
        fmt_number(.from[1]),
        fmt_number(.to[0]),
        fmt_number(.to[1])
    )]
    Unreachable {
        /// From.
        from: [f64; 2],
        /// To.
        to: [f64; 2],
    },
    /// The activity model gave a rate that is not a finite number `≥ 0`.
    #[error(
        "the activity model gave the rate {} at ({}, {})",
        fmt_number(.value),
        fmt_number(.at[0]),
        fmt_number(.at[1])
    )]
    BadRate {
        /// Where.
        at: [f64; 2],
        /// The rate.
        value: f64,
    },
    /// A count derived from a parameter (cells across the area, intervals over the tracked
    /// time) is not a finite number within its limit.
    #[error(
        "the {parameter} {} gives {} {what}; at most {limit}",
        fmt_number(.value),
        fmt_number(.count)
    )]
    TooMany {
        /// The parameter (`cell`, `interval`).
        parameter: &'static str,
        /// Its value.
        value: f64,
        /// What is counted (`columns`, `rows`, `intervals`).
        what: &'static str,
        /// The count it gives (may be infinite).
        count: f64,
        /// The largest count allowed.
        limit: usize,
    },
    /// The stochastic analysis failed.
    #[error(transparent)]
    Sbt(#[from] SbtError),
    /// The planning grid could not be built.
    #[error(transparent)]
    Grid(#[from] chronomap_spatial::PlanningGridError),
}

/// Parameters of the person search; the defaults are those of §5.4.4.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct PsbtConfig {
    /// Detection radius `r_D` in metres (2).
    pub detection_radius_m: f64,
    /// Confidence `p'_s` of eqs. 5.11 and 5.15 (0.9).
    pub confidence: f64,
    /// Path discretisation `Δt` in seconds (1).
    pub time_step_s: f64,
    /// Expected distance to a navigation failure `l_fail` in metres (100).
    pub fail_distance_m: f64,
    /// Average speed `v̄_sp` in m/s (0.5).
    pub speed_mps: f64,
    /// Number of sampled places `n_pl` (6).
    pub places: usize,
    /// Look-ahead time `t_max` in seconds (200).
    pub horizon_s: f64,
    /// Places lie at most this path distance from the help location (50 m: the robot can go
    /// there and back within `t_max` at `v̄_sp`). The dissertation bounds the distance without a value.
    pub max_distance_m: f64,
    /// `n_λ` of the GC baseline (50).
    pub close_maxima: usize,
    /// Whether the first places are the targets of the greedy baselines GM and GC (the cell
    /// of highest rate, and the nearest of the `n_λ` highest), the others sampled `∝` rate
    /// (true). Then PSBT's candidates contain the GM, GC and W trees, so PSBT is at least as
    /// good as each of them at `t_max` under the planning model, as the dissertation argues for W
    /// alone. `false` samples all `n_pl` places, as §5.4.3 does.
    pub include_maxima: bool,
    /// Truncation error allowed in the uniformisation (1e-10).
    pub tolerance: f64,
    /// The genetic algorithm of the open TSP.
    pub tsp: TspConfig,
}

impl Default for PsbtConfig {
    fn default() -> Self {
        PsbtConfig {
            detection_radius_m: 2.0,
            confidence: 0.9,
            time_step_s: 1.0,
            fail_distance_m: 100.0,
            speed_mps: 0.5,
            places: 6,
            horizon_s: 200.0,
            max_distance_m: 50.0,
            close_maxima: 50,
            include_maxima: true,
            tolerance: 1e-10,
            tsp: TspConfig::default(),
        }
    }
}

impl PsbtConfig {
    /// Checks every parameter.
    ///
    /// # Errors
    /// [`PsbtError::Config`] naming the first parameter out of range (the places must be
    /// `1 ..= 16`: the candidates grow as `3^{n_pl}`).
    pub fn validate(&self) -> Result<(), PsbtError> {
        let positive = |name: &str, v: f64| check_positive(name, v).map_err(PsbtError::Config);
        positive("the detection radius", self.detection_radius_m)?;
        positive("the time step", self.time_step_s)?;
        positive("l_fail", self.fail_distance_m)?;
        positive("the speed", self.speed_mps)?;
        positive("the horizon", self.horizon_s)?;
        positive("the maximum distance", self.max_distance_m)?;
        if !(self.confidence > 0.0 && self.confidence < 1.0) {
            return Err(PsbtError::Config(format!(
                "the confidence {} is not in (0, 1)",
                self.confidence
            )));
        }
        if self.places == 0 {
            return Err(PsbtError::Config(
                "0 places: the search needs at least 1 place (at most 16)".into(),
            ));
        }
        if self.places > 16 {
            return Err(PsbtError::Config(format!(
                "{} places would mean 3^{} candidate trees; at most 16",
                self.places, self.places
            )));
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1e-3) {
            return Err(PsbtError::Config(format!(
                "the tolerance {} is not in (0, 1e-3)",
                self.tolerance
            )));
        }
        if self.tsp.population == 0 {
            return Err(PsbtError::Config("the TSP population is empty".into()));
        }
        Ok(())
    }
}

/// One action of a person search tree.
#[derive(Clone, Debug, PartialEq)]
pub enum Step {
    /// `S_{A,i→j}`: drive the path from `from` to `to`, looking for people.
    Search {
        /// Start place.
        from: [f64; 2],
        /// End place.
        to: [f64; 2],
        /// The cells of the path.
        path: CellPath,
    },
    /// `W_{A,i}`: wait at `at` for at most `timeout_s` (`T'` of eq. 5.11).
    Wait {
        /// The place (centre of its planning cell).
        at: [f64; 2],
        /// Its planning cell.
        cell: usize,
        /// `T'` in seconds.
        timeout_s: f64,
    },
}

/// An action of the fallback and the return that follows its success.
#[derive(Clone, Debug, PartialEq)]
pub struct Phase {
    /// The action.
    pub step: Step,
    /// Path distance from where the action ends back to the help location (metres).
    pub return_length_m: f64,
}

/// A person search tree: `Sequence(Fallback(phases…), MoveTo start)` (Fig. 5.9).
#[derive(Clone, Debug, PartialEq)]
pub struct PersonSearchTree {
    /// The help location `x₀`.
    pub start: [f64; 2],
    /// The actions in the order the fallback ticks them.
    pub phases: Vec<Phase>,
}

/// The chain of a sequence of phases: phase `k`'s action fails into phase `k + 1` (the last
/// into `F`), succeeds into its return, whose success is `S` and failure `F`.
///
/// # Errors
/// As [`Chain::new`].
pub fn phase_chain(phases: &[(Action, Option<Action>)]) -> Result<Chain, SbtError> {
    let mut exits: Vec<Vec<(Target, f64)>> = Vec::new();
    let mut next = vec![(Target::Failure, 1.0)];
    let split = |a: &Action,
                 on_s: &[(Target, f64)],
                 on_f: &[(Target, f64)],
                 exits: &mut Vec<Vec<(Target, f64)>>| {
        let mut entry = Vec::new();
        if a.p_success() > 0.0 {
            let mut out = Vec::new();
            add_scaled(&mut out, on_s, a.mu());
            exits.push(out);
            entry.push((Target::State(exits.len() - 1), a.p_success()));
        }
        if a.p_success() < 1.0 {
            let mut out = Vec::new();
            add_scaled(&mut out, on_f, a.nu());
            exits.push(out);
            entry.push((Target::State(exits.len() - 1), 1.0 - a.p_success()));
        }
        entry
    };
    for (action, ret) in phases.iter().rev() {
        let ret_entry = match ret {
            Some(r) => split(
                r,
                &[(Target::Success, 1.0)],
                &[(Target::Failure, 1.0)],
                &mut exits,
            ),
            None => vec![(Target::Success, 1.0)],
        };
        next = split(action, &ret_entry, &next, &mut exits);
    }
    Chain::new(exits, next)
}

/// What a tree achieves under an activity model.
#[derive(Clone, Debug, PartialEq)]
pub struct Analysis {
    /// `p_{s,T}(t)` at each requested time.
    pub p_success: Vec<f64>,
    /// Eventual probabilities and `E[T | S]`.
    pub means: Means,
}

impl PersonSearchTree {
    /// The SBT tuples of the phases (and their returns) under `field` at time `t`. Wait
    /// timeouts are those of the tree (planned), so a tree planned on one model can be scored
    /// on another.
    ///
    /// # Errors
    /// [`PsbtError::BadRate`] if the field gives a rate that is not finite and `≥ 0`.
    pub fn actions<F: RateField + ?Sized>(
        &self,
        grid: &PlanningGrid,
        field: &F,
        t: f64,
        config: &PsbtConfig,
        cache: &mut DiscCache,
    ) -> Result<Vec<(Action, Option<Action>)>, PsbtError> {
        let mut out = Vec::with_capacity(self.phases.len());
        for phase in &self.phases {
            let action = match &phase.step {
                Step::Search { path, .. } => {
                    synth::search_action(grid, field, t, config, cache, path)?.sbt()?
                }
                Step::Wait {
                    cell, timeout_s, ..
                } => actions::WaitAction {
                    mu_w: cache
                        .rate(grid, field, t, config, *cell)?
                        .max(actions::MIN_RATE),
                    timeout: *timeout_s,
                }
                .sbt()?,
            };
            out.push((action, actions::move_to(phase.return_length_m, config)?));
        }
        Ok(out)
    }

    /// `p_{s,T}(t_k)` at each of `times` (seconds from the start of the search) and the means,
    /// under `field` at time `t`.
    ///
    /// # Errors
    /// As [`PersonSearchTree::actions`]; [`PsbtError::Sbt`] for invalid times.
    pub fn analyse<F: RateField + ?Sized>(
        &self,
        grid: &PlanningGrid,
        field: &F,
        t: f64,
        config: &PsbtConfig,
        times: &[f64],
    ) -> Result<Analysis, PsbtError> {
        let mut cache = DiscCache::new(config.detection_radius_m);
        let actions = self.actions(grid, field, t, config, &mut cache)?;
        let chain = phase_chain(&actions)?;
        let p_success = chain
            .transient(times, config.tolerance)?
            .iter()
            .map(|o| o.p_success)
            .collect();
        Ok(Analysis {
            p_success,
            means: chain.means(),
        })
    }
}

#[cfg(test)]
mod tests;
