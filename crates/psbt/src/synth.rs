//! Synthesis of the person search tree (§5.4.3) and the baselines of §5.4.4.

use std::collections::HashMap;

use rayon::prelude::*;

use super::actions::{MIN_RATE, SearchAction, WaitAction, move_to};
use super::path::{CellPath, DistanceTree, astar, sample_cells};
use super::places::{open_tsp, sample_places, sample_uniform};
use super::{PersonSearchTree, Phase, PsbtConfig, PsbtError, RateField, Step, phase_chain};
use chronomap_bt_stochastic::dense::DenseGenerator;
use chronomap_bt_stochastic::{Action, SbtError, poisson_survival, poisson_truncation};
use chronomap_core::Parallelism;
use chronomap_core::rng::{Xoshiro256StarStar, derive_seed};
use chronomap_spatial::PlanningGrid;

/// Paths between the start (node 0) and the places (nodes `1..`), all pairs; `None` on the
/// diagonal.
type Paths = Vec<Vec<Option<CellPath>>>;

/// Memoised `∫_D λ` (eqs. 5.9, 5.14) at planning-cell centres, for one field and time.
#[derive(Clone, Debug, Default)]
pub struct DiscCache {
    radius: f64,
    rates: HashMap<usize, f64>,
}

impl DiscCache {
    /// An empty cache for the detection radius `radius`.
    pub fn new(radius: f64) -> Self {
        DiscCache {
            radius,
            rates: HashMap::new(),
        }
    }

    /// `∫_D λ(x, t) dx` over the detection disc at the centre of `cell`.
    ///
    /// # Errors
    /// [`PsbtError::BadRate`] if the field's value is not finite and `≥ 0`.
    pub fn rate<F: RateField + ?Sized>(
        &mut self,
        grid: &PlanningGrid,
        field: &F,
        t: f64,
        _config: &PsbtConfig,
        cell: usize,
    ) -> Result<f64, PsbtError> {
        if let Some(&r) = self.rates.get(&cell) {
            return Ok(r);
        }
        let at = grid.centre(cell);
        let value = field.disc_rate(at, self.radius, t);
        if !(value.is_finite() && value >= 0.0) {
            return Err(PsbtError::BadRate { at, value });
        }
        self.rates.insert(cell, value);
        Ok(value)
    }
}

/// The search action along `path` (eqs. 5.13–5.17): the rates at `t_k = kΔt`.
pub(crate) fn search_action<F: RateField + ?Sized>(
    grid: &PlanningGrid,
    field: &F,
    t: f64,
    config: &PsbtConfig,
    cache: &mut DiscCache,
    path: &CellPath,
) -> Result<SearchAction, PsbtError> {
    let cells = sample_cells(grid, path, config.speed_mps * config.time_step_s)?;
    let rates = cells
        .iter()
        .map(|&c| cache.rate(grid, field, t, config, c))
        .collect::<Result<Vec<f64>, _>>()?;
    Ok(SearchAction::new(path.length, rates, config))
}

/// What the robot does at a place of a candidate tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Choice {
    /// Leave the place out.
    Skip,
    /// Search the way to it.
    Search,
    /// Search the way to it, then wait there.
    SearchWait,
}

impl Choice {
    /// The choice as reports name it: `skip`, `search`, `search+wait`.
    pub fn name(self) -> &'static str {
        match self {
            Choice::Skip => "skip",
            Choice::Search => "search",
            Choice::SearchWait => "search+wait",
        }
    }
}

/// The `3^n + 1` candidate trees over `n` ordered places (Fig. 5.9): node 0 is the help
/// location, nodes `1..=n` the places in visiting order. Candidate `i < 3^n` chooses
/// `Choice` digit `⌊i / 3^{j−1}⌋ mod 3` (0 skip, 1 search, 2 search and wait) at place `j`;
/// candidate `3^n` is W (wait at node 0).
#[derive(Clone, Debug, PartialEq)]
pub struct Candidates {
    /// `search[i][j]`: the search from node `i` to node `j`, for `i < j` (else `None`).
    pub search: Vec<Vec<Option<Action>>>,
    /// `wait[j]`: waiting at node `j` (`wait[0]`: W).
    pub wait: Vec<Action>,
    /// `ret[j]`: moving back to node 0 from node `j` (`None`: already there).
    pub ret: Vec<Option<Action>>,
}

impl Candidates {
    /// Number of places `n`.
    pub fn places(&self) -> usize {
        self.wait.len().saturating_sub(1)
    }

    /// Number of candidates, `3^n + 1`.
    pub fn count(&self) -> usize {
        3usize.pow(self.places() as u32) + 1
    }

    /// The choices of candidate `index` (`None` for W, or an index out of range).
    pub fn choices(&self, index: usize) -> Option<Vec<Choice>> {
        let n = self.places();
        if index >= 3usize.pow(n as u32) {
            return None;
        }
        let mut rest = index;
        Some(
            (0..n)
                .map(|_| {
                    let d = rest % 3;
                    rest /= 3;
                    [Choice::Skip, Choice::Search, Choice::SearchWait][d]
                })
                .collect(),
        )
    }

    /// The index of a list of choices.
    pub fn index_of(choices: &[Choice]) -> usize {
        choices.iter().rev().fold(0, |acc, c| {
            acc * 3
                + match c {
                    Choice::Skip => 0,
                    Choice::Search => 1,
                    Choice::SearchWait => 2,
                }
        })
    }

    /// The phases (action, return) of candidate `index`.
    ///
    /// # Panics
    /// If `index ≥ count()` or a needed search is `None`.
    pub fn phases(&self, index: usize) -> Vec<(Action, Option<Action>)> {
        let Some(choices) = self.choices(index) else {
            assert!(index < self.count(), "candidate {index} out of range");
            return vec![(self.wait[0], self.ret[0])];
        };
        let mut phases = Vec::new();
        let mut prev = 0;
        for (k, choice) in choices.iter().enumerate() {
            let j = k + 1;
            if *choice == Choice::Skip {
                continue;
            }
            phases.push((
                self.search[prev][j].expect("a search for every i < j"),
                self.ret[j],
            ));
            if *choice == Choice::SearchWait {
                phases.push((self.wait[j], self.ret[j]));
            }
            prev = j;
        }
        phases
    }

    /// `p_{s,T}(horizon)` of every candidate, fast ([module docs](super#fast-synthesis)).
    pub fn values(&self, horizon: f64, tolerance: f64) -> Vec<f64> {
        let walker = Walker::new(self, horizon, tolerance);
        let mut values = vec![0.0; self.count()];
        let mut bufs = walker.buffers();
        let entry = walker.unit();
        walker.walk(1, 0, &entry, 0.0, 0, 1, &mut bufs, &mut |i, v| {
            values[i] = v
        });
        values[self.count() - 1] = walker.w();
        values
    }

    /// The candidate of maximum `p_{s,T}(horizon)` and that value; ties go to the smaller
    /// index. The result does not depend on `parallelism`.
    pub fn best(&self, horizon: f64, tolerance: f64, parallelism: Parallelism) -> (usize, f64) {
        let walker = Walker::new(self, horizon, tolerance);
        let n = self.places();
        let mut best = (self.count() - 1, walker.w());
        let better = |a: (usize, f64), b: (usize, f64)| a.1 > b.1 || (a.1 == b.1 && a.0 < b.0);
        let depth = if parallelism.tasks() > 1 { n.min(3) } else { 0 };
        let starts = walker.prefixes(depth);
        let results: Vec<(usize, f64)> = if depth > 0 {
            starts
                .par_iter()
                .map(|p| walker.best_from(p, &better))
                .collect()
        } else {
            starts
                .iter()
                .map(|p| walker.best_from(p, &better))
                .collect()
        };
        for r in results {
            if better(r, best) {
                best = r;
            }
        }
        best
    }

    /// The reference: `p_{s,T}(horizon)` of candidate `index` from its dense generator by
    /// dense uniformisation ([`chronomap_bt_stochastic::dense`]).
    ///
    /// # Errors
    /// As [`phase_chain`].
    pub fn reference_value(
        &self,
        index: usize,
        horizon: f64,
        tolerance: f64,
    ) -> Result<f64, SbtError> {
        let chain = phase_chain(&self.phases(index))?;
        Ok(DenseGenerator::of(&chain).transient(&[horizon], tolerance)?[0].p_success)
    }

    /// [`Candidates::reference_value`] of every candidate.
    ///
    /// # Errors
    /// As [`phase_chain`].
    pub fn reference_values(&self, horizon: f64, tolerance: f64) -> Result<Vec<f64>, SbtError> {
        (0..self.count())
            .map(|i| self.reference_value(i, horizon, tolerance))
            .collect()
    }

    /// `p_{s,T}(horizon)` of candidate `index` from its own sparse chain
    /// ([`chronomap_bt_stochastic::Chain::transient`]): a naive per-tree solve.
    ///
    /// # Errors
    /// As [`phase_chain`].
    pub fn per_tree_value(
        &self,
        index: usize,
        horizon: f64,
        tolerance: f64,
    ) -> Result<f64, SbtError> {
        Ok(phase_chain(&self.phases(index))?.transient(&[horizon], tolerance)?[0].p_success)
    }
}

/// A partial walk: the next place, the last node visited, the mass entering the next action,
/// the success accumulated and the index digits fixed so far.
struct Prefix {
    next: usize,
    prev: usize,
    entry: Vec<f64>,
    acc: f64,
    index: usize,
    scale: usize,
}

/// The depth-first walk over the candidates, sharing prefixes (uniformisation with one rate
/// `Λ` for every action).
struct Walker<'a> {
    c: &'a Candidates,
    lambda: f64,
    /// `P(N(Λ t_max) ≥ k)`, `k = 0..=K`.
    survival: Vec<f64>,
}

impl<'a> Walker<'a> {
    fn new(c: &'a Candidates, horizon: f64, tolerance: f64) -> Self {
        let mut lambda: f64 = 0.0;
        let mut see = |a: &Action| {
            if a.p_success() > 0.0 {
                lambda = lambda.max(a.mu());
            }
            if a.p_success() < 1.0 {
                lambda = lambda.max(a.nu());
            }
        };
        c.search.iter().flatten().flatten().for_each(&mut see);
        c.wait.iter().for_each(&mut see);
        c.ret.iter().flatten().for_each(&mut see);
        let lambda = lambda.max(MIN_RATE);
        let steps = poisson_truncation(lambda * horizon, tolerance);
        let (survival, _) = poisson_survival(lambda * horizon, steps);
        Walker {
            c,
            lambda,
            survival,
        }
    }

    fn unit(&self) -> Vec<f64> {
        let mut e = vec![0.0; self.survival.len()];
        e[0] = 1.0;
        e
    }

    fn buffers(&self) -> Vec<Vec<f64>> {
        vec![vec![0.0; self.survival.len()]; 2 * self.c.places()]
    }

    /// `p_{s,T}(t_max)` of W.
    fn w(&self) -> f64 {
        let mut out = vec![0.0; self.survival.len()];
        self.apply(
            &self.c.wait[0],
            self.c.ret[0].as_ref(),
            &self.unit(),
            &mut out,
        )
    }

    /// Passes the mass `entry[k]` entering action `a` at jump `k` through its phases:
    /// `out[k]` receives what leaves it by failure at jump `k`; the return is the success
    /// of what leaves by success, absorbed in `S` at jump `k` with weight `P(N ≥ k)`.
    fn apply(&self, a: &Action, ret: Option<&Action>, entry: &[f64], out: &mut [f64]) -> f64 {
        let inv = 1.0 / self.lambda;
        let p = a.p_success();
        let (leave_f, leave_s) = (a.nu() * inv, a.mu() * inv);
        let (stay_f, stay_s) = (1.0 - leave_f, 1.0 - leave_s);
        let (mut x, mut y, mut z) = (0.0, 0.0, 0.0);
        let mut contribution = 0.0;
        let first = entry.iter().position(|&v| v != 0.0).unwrap_or(entry.len());
        out[..first].iter_mut().for_each(|v| *v = 0.0);
        match ret {
            Some(r) => {
                let pr = r.p_success();
                let leave_r = r.mu() * inv;
                let stay_r = 1.0 - leave_r;
                for k in first..entry.len() {
                    let e = entry[k];
                    out[k] = x * leave_f;
                    x = x * stay_f + (1.0 - p) * e;
                    let s_out = y * leave_s;
                    y = y * stay_s + p * e;
                    contribution += z * leave_r * self.survival[k];
                    z = z * stay_r + pr * s_out;
                }
            }
            None => {
                for k in first..entry.len() {
                    let e = entry[k];
                    out[k] = x * leave_f;
                    x = x * stay_f + (1.0 - p) * e;
                    contribution += y * leave_s * self.survival[k];
                    y = y * stay_s + p * e;
                }
            }
        }
        contribution
    }

    #[allow(clippy::too_many_arguments)]
    fn walk(
        &self,
        j: usize,
        prev: usize,
        entry: &[f64],
        acc: f64,
        index: usize,
        scale: usize,
        bufs: &mut [Vec<f64>],
        visit: &mut dyn FnMut(usize, f64),
    ) {
        if j > self.c.places() {
            visit(index, acc);
            return;
        }
        self.walk(j + 1, prev, entry, acc, index, scale * 3, bufs, visit);
        let (mine, rest) = bufs.split_at_mut(2);
        let (a, b) = mine.split_at_mut(1);
        let ret = self.c.ret[j].as_ref();
        let search = self.c.search[prev][j]
            .as_ref()
            .expect("a search for every i < j");
        let c1 = self.apply(search, ret, entry, &mut a[0]);
        self.walk(
            j + 1,
            j,
            &a[0],
            acc + c1,
            index + scale,
            scale * 3,
            rest,
            visit,
        );
        let c2 = self.apply(&self.c.wait[j], ret, &a[0], &mut b[0]);
        self.walk(
            j + 1,
            j,
            &b[0],
            acc + c1 + c2,
            index + 2 * scale,
            scale * 3,
            rest,
            visit,
        );
    }

    /// All partial walks that fix the first `depth` places.
    fn prefixes(&self, depth: usize) -> Vec<Prefix> {
        let mut level = vec![Prefix {
            next: 1,
            prev: 0,
            entry: self.unit(),
            acc: 0.0,
            index: 0,
            scale: 1,
        }];
        for _ in 0..depth {
            let mut next_level = Vec::with_capacity(3 * level.len());
            for p in level {
                let j = p.next;
                let ret = self.c.ret[j].as_ref();
                let search = self.c.search[p.prev][j]
                    .as_ref()
                    .expect("a search for every i < j");
                let mut a = vec![0.0; p.entry.len()];
                let c1 = self.apply(search, ret, &p.entry, &mut a);
                let mut b = vec![0.0; p.entry.len()];
                let c2 = self.apply(&self.c.wait[j], ret, &a, &mut b);
                next_level.push(Prefix {
                    next: j + 1,
                    prev: j,
                    entry: a,
                    acc: p.acc + c1,
                    index: p.index + p.scale,
                    scale: p.scale * 3,
                });
                next_level.push(Prefix {
                    next: j + 1,
                    prev: j,
                    entry: b,
                    acc: p.acc + c1 + c2,
                    index: p.index + 2 * p.scale,
                    scale: p.scale * 3,
                });
                next_level.push(Prefix {
                    next: j + 1,
                    scale: p.scale * 3,
                    ..p
                });
            }
            level = next_level;
        }
        level
    }

    fn best_from(
        &self,
        p: &Prefix,
        better: &dyn Fn((usize, f64), (usize, f64)) -> bool,
    ) -> (usize, f64) {
        let mut best = (usize::MAX, f64::NEG_INFINITY);
        let mut bufs = self.buffers();
        self.walk(
            p.next,
            p.prev,
            &p.entry,
            p.acc,
            p.index,
            p.scale,
            &mut bufs,
            &mut |i, v| {
                if better((i, v), best) {
                    best = (i, v);
                }
            },
        );
        best
    }
}

/// The strategies of §5.4.4.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// The person search behavior tree.
    Psbt,
    /// Greedy to the global maximum: drive to the cell of maximum rate and wait there.
    Gm,
    /// Greedy to a close maximum: drive to the closest of the `n_λ` cells of highest rate and
    /// wait there.
    Gc,
    /// Uniformly sampled places in TSP order, waiting at each with probability ½.
    Rnd,
    /// Wait at the help location.
    W,
    /// Purely proactive: the PSBT's places and order, searching only.
    Pp,
}

impl Method {
    /// Every method, in table order.
    pub const ALL: [Method; 6] = [
        Method::Psbt,
        Method::Gm,
        Method::Gc,
        Method::Rnd,
        Method::W,
        Method::Pp,
    ];

    /// Short name (`PSBT`, `GM`, …).
    pub fn name(self) -> &'static str {
        match self {
            Method::Psbt => "PSBT",
            Method::Gm => "GM",
            Method::Gc => "GC",
            Method::Rnd => "RND",
            Method::W => "W",
            Method::Pp => "PP",
        }
    }
}

/// A planned search.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// Which strategy planned it.
    pub method: Method,
    /// The tree.
    pub tree: PersonSearchTree,
    /// `p_{s,T}(t_max)` under the planning model.
    pub p_success: f64,
    /// `E[T | S]` in seconds under the planning model (`None` if success is impossible).
    pub expected_time_s: Option<f64>,
    /// The places considered, in visiting order.
    pub places: Vec<[f64; 2]>,
    /// Number of candidate trees compared.
    pub candidates: usize,
    /// The chosen candidate's choices (`None`: W).
    pub choices: Option<Vec<Choice>>,
}

/// The result of [`synthesize`].
pub type Synthesis = Plan;

/// Nodes of a candidate set and their geometry.
struct Geometry {
    cells: Vec<usize>,
    at: Vec<[f64; 2]>,
    /// `paths[i][j]` for `i < j`.
    paths: Vec<Vec<Option<CellPath>>>,
    timeouts: Vec<f64>,
    returns: Vec<f64>,
}

/// Everything shared by the plans for one help location: the grid, the model at time `t`,
/// the distances from the start, the cells within reach.
pub struct SearchContext<'a, F: RateField + ?Sized> {
    grid: &'a PlanningGrid,
    field: &'a F,
    t: f64,
    config: &'a PsbtConfig,
    start: [f64; 2],
    start_cell: usize,
    tree: DistanceTree,
    cache: DiscCache,
}

impl<'a, F: RateField + ?Sized> SearchContext<'a, F> {
    /// The context for a search from `from` at time `t`.
    ///
    /// # Errors
    /// [`PsbtError::Config`] for an invalid configuration or a non-finite time;
    /// [`PsbtError::StartOutside`] / [`PsbtError::StartBlocked`] for a start off the grid or
    /// on a blocked cell.
    pub fn new(
        grid: &'a PlanningGrid,
        field: &'a F,
        from: [f64; 2],
        t: f64,
        config: &'a PsbtConfig,
    ) -> Result<Self, PsbtError> {
        config.validate()?;
        if !t.is_finite() {
            return Err(PsbtError::Config(format!("the time {t} is not finite")));
        }
        let start_cell = grid
            .cell_at(from)
            .ok_or(PsbtError::StartOutside { at: from })?;
        let tree = DistanceTree::new(grid, start_cell, config.max_distance_m)
            .ok_or(PsbtError::StartBlocked { at: from })?;
        Ok(SearchContext {
            grid,
            field,
            t,
            config,
            start: from,
            start_cell,
            tree,
            cache: DiscCache::new(config.detection_radius_m),
        })
    }

    /// The cells within reach (the start included) with `∫_cell λ ≈ λ(centre)·area`.
    fn reachable(&self) -> Result<Vec<(usize, f64)>, PsbtError> {
        let area = self.grid.cell_size().powi(2);
        self.tree
            .reached()
            .map(|c| {
                let at = self.grid.centre(c);
                let d = self.field.density(at, self.t);
                if d.is_finite() && d >= 0.0 {
                    Ok((c, d * area))
                } else {
                    Err(PsbtError::BadRate { at, value: d })
                }
            })
            .collect()
    }

    fn rng(&self, seed: u64, tag: u64) -> Xoshiro256StarStar {
        Xoshiro256StarStar::seed_from_u64(derive_seed(seed, tag, 0, 0))
    }

    /// The targets of the greedy baselines (§5.4.4): GM the reachable cell of highest rate, GC
    /// the nearest (by path) of the `n_λ` highest. Equal rates: the nearer, then the lower index.
    /// `reachable` is [`Self::reachable`]'s list.
    fn greedy_targets(&self, reachable: &[(usize, f64)]) -> (usize, usize) {
        let mut cells = reachable.to_vec();
        cells.sort_by(|a, b| {
            b.1.total_cmp(&a.1)
                .then_with(|| self.tree.distance(a.0).total_cmp(&self.tree.distance(b.0)))
                .then_with(|| a.0.cmp(&b.0))
        });
        let global = cells[0].0;
        let close = cells
            .iter()
            .take(self.config.close_maxima.max(1))
            .min_by(|a, b| {
                self.tree
                    .distance(a.0)
                    .total_cmp(&self.tree.distance(b.0))
                    .then_with(|| a.0.cmp(&b.0))
            })
            .expect("the start is reachable")
            .0;
        (global, close)
    }

    /// PSBT's places: sampled `∝` rate, thinned by `r_D` (§5.4.3); with
    /// [`PsbtConfig::include_maxima`], the targets of GM and GC first.
    fn psbt_places(&self, seed: u64) -> Result<Vec<usize>, PsbtError> {
        let reachable = self.reachable()?;
        let cells: Vec<(usize, f64)> = reachable
            .iter()
            .copied()
            .filter(|&(c, _)| c != self.start_cell)
            .collect();
        let candidates: Vec<([f64; 2], f64)> = cells
            .iter()
            .map(|&(c, r)| (self.grid.centre(c), r))
            .collect();
        let fixed: Vec<usize> = if self.config.include_maxima {
            let (global, close) = self.greedy_targets(&reachable);
            [global, close]
                .into_iter()
                .filter_map(|target| cells.iter().position(|&(c, _)| c == target))
                .collect()
        } else {
            Vec::new()
        };
        let picked = sample_places(
            &candidates,
            &fixed,
            self.config.places,
            self.config.detection_radius_m,
            &mut self.rng(seed, 1),
        );
        Ok(picked.into_iter().map(|i| cells[i].0).collect())
    }

    /// The paths between the start (node 0) and `cells` (nodes `1..`), all pairs.
    #[allow(clippy::needless_range_loop)] // i and j name nodes of a symmetric table
    fn pair_paths(&self, cells: &[usize]) -> Result<Paths, PsbtError> {
        let n = cells.len();
        let mut paths = vec![vec![None; n + 1]; n + 1];
        let node = |i: usize| {
            if i == 0 {
                self.start_cell
            } else {
                cells[i - 1]
            }
        };
        for j in 1..=n {
            let p = self.tree.path_to(node(j)).ok_or(PsbtError::Unreachable {
                from: self.start,
                to: self.grid.centre(node(j)),
            })?;
            paths[0][j] = Some(p);
            for i in 1..j {
                let p = astar(self.grid, node(i), node(j)).ok_or(PsbtError::Unreachable {
                    from: self.grid.centre(node(i)),
                    to: self.grid.centre(node(j)),
                })?;
                paths[j][i] = Some(p.reversed());
                paths[i][j] = Some(p);
            }
        }
        for j in 1..=n {
            paths[j][0] = paths[0][j].as_ref().map(CellPath::reversed);
        }
        Ok(paths)
    }

    /// Orders `cells` by the open TSP over the expected times to fail `ν_sp⁻¹` (eq. 5.17).
    /// Returns the ordered cells and their paths (all pairs, nodes in the new order).
    fn order(
        &self,
        cells: &[usize],
        seed: u64,
        tag: u64,
    ) -> Result<(Vec<usize>, Paths), PsbtError> {
        let paths = self.pair_paths(cells)?;
        let n = cells.len();
        let cost: Vec<Vec<f64>> = (0..=n)
            .map(|i| {
                (0..=n)
                    .map(|j| match &paths[i][j] {
                        Some(p) => {
                            1.0 / SearchAction::new(p.length, vec![], self.config).failure_rate()
                        }
                        None => 0.0,
                    })
                    .collect()
            })
            .collect();
        let order = open_tsp(&cost, &self.config.tsp, &mut self.rng(seed, tag));
        // Node k of the new order is node `old[k]` of the table (the start stays node 0).
        let old: Vec<usize> = std::iter::once(0).chain(order.iter().copied()).collect();
        let reordered = old
            .iter()
            .map(|&i| old.iter().map(|&j| paths[i][j].clone()).collect())
            .collect();
        Ok((order.into_iter().map(|k| cells[k - 1]).collect(), reordered))
    }

    /// The candidate set over places `cells` (in visiting order).
    fn candidates(&mut self, cells: &[usize]) -> Result<(Candidates, Geometry), PsbtError> {
        let paths = self.pair_paths(cells)?;
        self.candidates_on(cells, paths)
    }

    /// [`Self::candidates`] with the paths between the places already planned.
    fn candidates_on(
        &mut self,
        cells: &[usize],
        paths: Paths,
    ) -> Result<(Candidates, Geometry), PsbtError> {
        let n = cells.len();
        let mut all_cells = vec![self.start_cell];
        all_cells.extend_from_slice(cells);
        let mut at = vec![self.start];
        at.extend(cells.iter().map(|&c| self.grid.centre(c)));
        let mut search = vec![vec![None; n + 1]; n + 1];
        for i in 0..=n {
            for j in i + 1..=n {
                let path = paths[i][j].as_ref().expect("all pairs");
                let action = search_action(
                    self.grid,
                    self.field,
                    self.t,
                    self.config,
                    &mut self.cache,
                    path,
                )?;
                search[i][j] = Some(action.sbt()?);
            }
        }
        let mut wait = Vec::with_capacity(n + 1);
        let mut timeouts = Vec::with_capacity(n + 1);
        let mut ret = Vec::with_capacity(n + 1);
        let mut returns = Vec::with_capacity(n + 1);
        for &cell in &all_cells {
            let mu = self
                .cache
                .rate(self.grid, self.field, self.t, self.config, cell)?;
            let w = WaitAction::planned(mu, self.config.confidence);
            wait.push(w.sbt()?);
            timeouts.push(w.timeout);
            let length = if cell == self.start_cell {
                0.0
            } else {
                self.tree.distance(cell)
            };
            ret.push(move_to(length, self.config)?);
            returns.push(length);
        }
        Ok((
            Candidates { search, wait, ret },
            Geometry {
                cells: all_cells,
                at,
                paths,
                timeouts,
                returns,
            },
        ))
    }

    fn tree_of(
        &self,
        candidates: &Candidates,
        geometry: &Geometry,
        index: usize,
    ) -> PersonSearchTree {
        let wait_at = |j: usize| Phase {
            step: Step::Wait {
                at: if j == 0 { self.start } else { geometry.at[j] },
                cell: geometry.cells[j],
                timeout_s: geometry.timeouts[j],
            },
            return_length_m: geometry.returns[j],
        };
        let mut phases = Vec::new();
        match candidates.choices(index) {
            None => phases.push(wait_at(0)),
            Some(choices) => {
                let mut prev = 0;
                for (k, choice) in choices.iter().enumerate() {
                    let j = k + 1;
                    if *choice == Choice::Skip {
                        continue;
                    }
                    phases.push(Phase {
                        step: Step::Search {
                            from: geometry.at[prev],
                            to: geometry.at[j],
                            path: geometry.paths[prev][j].clone().expect("all pairs"),
                        },
                        return_length_m: geometry.returns[j],
                    });
                    if *choice == Choice::SearchWait {
                        phases.push(wait_at(j));
                    }
                    prev = j;
                }
            }
        }
        PersonSearchTree {
            start: self.start,
            phases,
        }
    }

    fn finish(
        &self,
        method: Method,
        candidates: &Candidates,
        geometry: &Geometry,
        index: usize,
        p_success: Option<f64>,
    ) -> Result<Plan, PsbtError> {
        let chain = phase_chain(&candidates.phases(index))?;
        let p_success = match p_success {
            Some(p) => p,
            None => chain.transient(&[self.config.horizon_s], self.config.tolerance)?[0].p_success,
        };
        Ok(Plan {
            method,
            tree: self.tree_of(candidates, geometry, index),
            p_success,
            expected_time_s: chain.means().time_to_success,
            places: geometry.at[1..].to_vec(),
            candidates: candidates.count(),
            choices: candidates.choices(index),
        })
    }

    /// Plans with `method` (seeded: places and TSP for PSBT, PP and RND).
    ///
    /// # Errors
    /// [`PsbtError::BadRate`] for an invalid rate of the field; [`PsbtError::Unreachable`]
    /// if places are not connected; [`PsbtError::Sbt`] should never happen.
    pub fn plan(
        &mut self,
        method: Method,
        seed: u64,
        parallelism: Parallelism,
    ) -> Result<Plan, PsbtError> {
        let horizon = self.config.horizon_s;
        let tolerance = self.config.tolerance;
        match method {
            Method::Psbt | Method::Pp => {
                let places = self.psbt_places(seed)?;
                let (ordered, paths) = self.order(&places, seed, 2)?;
                let (candidates, geometry) = self.candidates_on(&ordered, paths)?;
                if method == Method::Psbt {
                    let (index, value) = candidates.best(horizon, tolerance, parallelism);
                    self.finish(method, &candidates, &geometry, index, Some(value))
                } else {
                    let index = Candidates::index_of(&vec![Choice::Search; ordered.len()]);
                    self.finish(method, &candidates, &geometry, index, None)
                }
            }
            Method::Rnd => {
                let cells: Vec<usize> = self
                    .tree
                    .reached()
                    .filter(|&c| c != self.start_cell)
                    .collect();
                let centres: Vec<[f64; 2]> = cells.iter().map(|&c| self.grid.centre(c)).collect();
                let mut rng = self.rng(seed, 3);
                let picked: Vec<usize> = sample_uniform(
                    &centres,
                    self.config.places,
                    self.config.detection_radius_m,
                    &mut rng,
                )
                .into_iter()
                .map(|i| cells[i])
                .collect();
                let (ordered, paths) = self.order(&picked, seed, 4)?;
                let choices: Vec<Choice> = ordered
                    .iter()
                    .map(|_| {
                        if rng.bernoulli(0.5) {
                            Choice::SearchWait
                        } else {
                            Choice::Search
                        }
                    })
                    .collect();
                let (candidates, geometry) = self.candidates_on(&ordered, paths)?;
                self.finish(
                    method,
                    &candidates,
                    &geometry,
                    Candidates::index_of(&choices),
                    None,
                )
            }
            Method::W => {
                let (candidates, geometry) = self.candidates(&[])?;
                self.finish(method, &candidates, &geometry, 1, None)
            }
            Method::Gm | Method::Gc => {
                let (global, close) = self.greedy_targets(&self.reachable()?);
                let target = if method == Method::Gm { global } else { close };
                if target == self.start_cell {
                    let (candidates, geometry) = self.candidates(&[])?;
                    self.finish(method, &candidates, &geometry, 1, None)
                } else {
                    let (candidates, geometry) = self.candidates(&[target])?;
                    self.finish(method, &candidates, &geometry, 2, None)
                }
            }
        }
    }

    /// The candidate set PSBT compares for `seed` (the places sampled and ordered as
    /// [`SearchContext::plan`] does): what benchmarks time the fast walk and the reference on.
    ///
    /// # Errors
    /// As [`SearchContext::plan`].
    pub fn psbt_candidates(&mut self, seed: u64) -> Result<Candidates, PsbtError> {
        let places = self.psbt_places(seed)?;
        let (ordered, paths) = self.order(&places, seed, 2)?;
        Ok(self.candidates_on(&ordered, paths)?.0)
    }

    /// The help location's planning cell.
    pub fn start_cell(&self) -> usize {
        self.start_cell
    }
}

/// Synthesises the PSBT for a robot needing help at `from` at time `t` (§5.4.3): samples
/// places (seeded), orders them, compares all `3^{n_pl} + 1` candidate trees and returns the
/// best.
///
/// # Errors
/// As [`SearchContext::new`] and [`SearchContext::plan`].
pub fn synthesize<F: RateField + ?Sized>(
    grid: &PlanningGrid,
    field: &F,
    from: [f64; 2],
    t: f64,
    config: &PsbtConfig,
    seed: u64,
    parallelism: Parallelism,
) -> Result<Synthesis, PsbtError> {
    SearchContext::new(grid, field, from, t, config)?.plan(Method::Psbt, seed, parallelism)
}
