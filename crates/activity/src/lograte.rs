//! Log-AM: rates in the log domain, an additive model of place and hour of the day with a
//! shrunken interaction ("log_additive"). Not in the dissertation: the answer to a measured
//! weakness of CoPA-Map on whole-hour ground truth (see `docs/activity.md`, "Beyond the
//! original: rates in the log domain").
//!
//! A robot's rates are heavy-tailed (a cell glimpsed for seconds with one person in it reads
//! hundreds of people per hour), so the model works on `z = ln(1 + y)`, where the glimpses are
//! moderate, and predicts the typical hour rather than the glimpse-laden mean:
//!
//! ```text
//! (L1)  z_i = ln(1 + y_i)
//! (L2)  z_i = a_c(i) + b_h(i) + γ_c(i),h(i) + ε_i,   ε_i ~ N(0, σ²/w_i),  γ_c,h ~ N(0, σ²/κ)
//! (L3)  h(t) = ⌊H · frac(t / P)⌋                     (phase bin of the day: P = period, H = bins)
//! (L4)  γ_c,h = Σ_{i ∈ (c,h)} w_i r_i / (Σ_{i ∈ (c,h)} w_i + κ),   r_i = z_i − a_c(i) − b_h(i)
//! (L5)  (τ, κ) = argmin over the candidates of the RMSE of ln(1 + ŷ) on the last 20 % of the
//!       training times, the model fitted on the rest
//! (L6)  ŷ(x, t) = exp(a_c + b_h + γ_c,h) − 1 (clipped at 0)
//! (L7)  w_i = exp(−⌊(t_max − t_i) / P⌋ / τ)            (memory: whole days before the last)
//! ```
//!
//! `a_c` (one level per cell) and `b_h` (one profile of the day shared by all cells) are the
//! weighted least-squares fit of `z = a_c + b_h` (a two-way additive model, in the rate domain a product
//! `rate ≈ level(cell) × rhythm(hour)`), found by backfitting: each sweep sets every `a_c` to
//! the `w`-weighted mean of `z_i − b_h(i)` over its cell and every `b_h` to that of
//! `z_i − a_c(i)` over its bin (block coordinate descent on the weighted squared error, which
//! converges to a least-squares solution). The profile is centred, `Σ_i w_i b_h(i) = 0`. (L4)
//! is the posterior mean of the cell-and-hour interaction under the Gaussian prior of (L2)
//! given `a` and `b`: a cell's own rhythm, shrunk towards the shared one by `κ`
//! pseudo-observations; `κ = ∞` leaves it out. The weights (L7) are a memory of `τ` days: the
//! noise of (L2) grows by `e^{1/τ}` per day before the last training day, so a place whose
//! activity drifts is led by its recent days; `τ = ∞` weighs every day alike.
//! (L6) is the median of `1 + y` under (L2), minus one: on the ATC grid it follows whole-hour
//! counts, where the arithmetic mean of the robot's rates is about twice too high.
//!
//! Cells never seen in training get the mean level of the training samples and no
//! interaction; phase bins never seen get `b = 0` (the average hour).
//!
//! ```
//! use chronomap_activity::{LogAdditive, LogAdditiveConfig, RatePredictor, RateSamples};
//!
//! // One cell, two days of 2 bins: ln(1 + y) is 1 in the first bin and 3 in the second.
//! let e = std::f64::consts::E;
//! let mut s = RateSamples::default();
//! for t in 0..4 {
//!     let z = if t % 2 == 0 { 1.0 } else { 3.0 };
//!     s.push([0.25, 0.25], f64::from(t), f64::exp(z) - 1.0)?;
//! }
//! let config = LogAdditiveConfig { period: 2.0, bins: 2, ..LogAdditiveConfig::default() };
//! let m = LogAdditive::fit(&s, &config)?;
//! assert!((m.predict([0.25, 0.25], 4.0) - (e - 1.0)).abs() < 1e-9);
//! assert!((m.predict([0.25, 0.25], 5.0) - (e.powi(3) - 1.0)).abs() < 1e-9);
//! # Ok::<(), chronomap_activity::ActivityError>(())
//! ```

use serde::{Deserialize, Serialize};

use super::{ActivityError, CellKey, RatePredictor, RateSamples};
use crate::nugget::{BinResidual, process_variance};

/// How [`LogAdditive`] is fitted.
#[derive(Clone, Debug, PartialEq)]
pub struct LogAdditiveConfig {
    /// Length of a day in units of `t` (default 12: the ATC grid's 12 recorded hours).
    pub period: f64,
    /// Phase bins per period `H` of (L3) (default 12: one per hour on the ATC grid).
    pub bins: usize,
    /// Candidate shrinkages `κ` of (L4), tried in this order on the hold-out (L5); ties keep
    /// the earlier. `f64::INFINITY` leaves the interaction out. Default
    /// `[∞, 100, 50, 20, 10, 5, 2, 1]`. With one candidate there is no hold-out.
    pub shrinkage: Vec<f64>,
    /// Candidate memories `τ` of (L7), in periods (days), tried in this order with every `κ`
    /// (the outer loop). `f64::INFINITY` weighs all days alike. Default `[∞, 8, 4, 2, 1]`.
    pub memory: Vec<f64>,
    /// Fraction of the distinct training times held out to choose `τ` and `κ` (default 0.2,
    /// as `--model auto`).
    pub holdout: f64,
    /// Most backfitting sweeps (default 100; they stop when no term moves by 1e-12).
    pub max_sweeps: usize,
}

impl Default for LogAdditiveConfig {
    fn default() -> Self {
        LogAdditiveConfig {
            period: 12.0,
            bins: 12,
            shrinkage: vec![f64::INFINITY, 100.0, 50.0, 20.0, 10.0, 5.0, 2.0, 1.0],
            memory: vec![f64::INFINITY, 8.0, 4.0, 2.0, 1.0],
            holdout: 0.2,
            max_sweeps: 100,
        }
    }
}

impl LogAdditiveConfig {
    fn check(&self) -> Result<(), ActivityError> {
        let bad = |what: String| Err(ActivityError::Config(what));
        if !(self.period.is_finite() && self.period > 0.0) {
            return bad(format!("period {} must be a positive number", self.period));
        }
        if self.bins == 0 || self.bins > 100_000 {
            return bad(format!("bins {} must be in 1..=100000", self.bins));
        }
        if self.shrinkage.is_empty() {
            return bad("give at least one shrinkage candidate".into());
        }
        if let Some(k) = self.shrinkage.iter().find(|k| k.is_nan() || **k <= 0.0) {
            return bad(format!("shrinkage {k} must be > 0 (∞: no interaction)"));
        }
        if self.memory.is_empty() {
            return bad("give at least one memory candidate".into());
        }
        if let Some(m) = self.memory.iter().find(|m| m.is_nan() || **m <= 0.0) {
            return bad(format!("memory {m} must be > 0 (∞: every day alike)"));
        }
        if !(self.holdout > 0.0 && self.holdout < 1.0) {
            return bad(format!(
                "hold-out fraction {} must be in (0, 1)",
                self.holdout
            ));
        }
        if self.max_sweeps == 0 {
            return bad("max_sweeps must be at least 1".into());
        }
        Ok(())
    }
}

/// The terms of one training cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LogCell {
    /// Cell centre `[x1, x2]`.
    pub x: [f64; 2],
    /// Level `a_c` of (L2).
    pub level: f64,
    /// Interaction `γ_c,h` of (L4) per phase bin (0 where the cell was never seen in a bin,
    /// all 0 for `κ = ∞`).
    pub interaction: Vec<f64>,
}

/// The hold-out score of one candidate of (L5).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct HoldoutScore {
    /// Memory `τ` of (L7), in periods.
    pub memory: f64,
    /// Shrinkage `κ` of (L4).
    pub shrinkage: f64,
    /// RMSE of ln(1 + ŷ) against ln(1 + y) on the held-out training times.
    pub rmse: f64,
}

/// A fitted Log-AM, eqs. (L1)–(L7) of the [module](self).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LogAdditive {
    period: f64,
    /// Profile `b_h` of the day, `H` entries.
    profile: Vec<f64>,
    /// Training cells, sorted by [`CellKey`].
    cells: Vec<LogCell>,
    /// Level of unseen cells: the mean of `a_c(i)` over the training samples.
    fallback: f64,
    /// The chosen `κ` (`∞`: no interaction).
    shrinkage: f64,
    /// The chosen memory `τ` in periods (`∞`: every day alike).
    memory: f64,
    /// Residual standard deviation `σ` of (L2) on the training samples.
    sigma: f64,
    /// Hold-out RMSE of ln(1 + ŷ) of every candidate `(τ, κ)`, in the order tried (empty
    /// without a hold-out).
    holdout_scores: Vec<HoldoutScore>,
    /// Standard deviation of a whole bin's `ln(1 + rate)` around the model: the correlated part
    /// of `σ`, the glimpses' noise left out ([`crate::nugget`], (N3)). `None` where the
    /// training samples do not tell the two apart, and in files written before it existed.
    process_sigma: Option<f64>,
}

/// The layout of [`LogAdditive`] in files written before it had `process_sigma`: read as a
/// model without intervals of whole bins.
#[derive(Deserialize)]
pub struct LogAdditiveWithoutProcessSigma {
    period: f64,
    profile: Vec<f64>,
    cells: Vec<LogCell>,
    fallback: f64,
    shrinkage: f64,
    memory: f64,
    sigma: f64,
    holdout_scores: Vec<HoldoutScore>,
}

impl From<LogAdditiveWithoutProcessSigma> for LogAdditive {
    fn from(old: LogAdditiveWithoutProcessSigma) -> Self {
        LogAdditive {
            period: old.period,
            profile: old.profile,
            cells: old.cells,
            fallback: old.fallback,
            shrinkage: old.shrinkage,
            memory: old.memory,
            sigma: old.sigma,
            holdout_scores: old.holdout_scores,
            process_sigma: None,
        }
    }
}

impl LogAdditive {
    /// Fits (L1)–(L4) on `train`, choosing `τ` and `κ` by (L5).
    ///
    /// Without two distinct training times there is nothing to hold out: the first candidates
    /// are used.
    ///
    /// # Errors
    /// [`ActivityError::Empty`] or [`ActivityError::Config`].
    pub fn fit(train: &RateSamples, config: &LogAdditiveConfig) -> Result<Self, ActivityError> {
        config.check()?;
        if train.is_empty() {
            return Err(ActivityError::Empty);
        }
        let mut holdout_scores = Vec::new();
        let (mut memory, mut shrinkage) = (config.memory[0], config.shrinkage[0]);
        let candidates = config.memory.len() * config.shrinkage.len();
        if candidates > 1
            && let Some((fit_part, held)) = holdout_split(train, config.holdout)
        {
            let z_held: Vec<f64> = held.y().iter().map(|y| y.ln_1p()).collect();
            let mut best = f64::INFINITY;
            for &tau in &config.memory {
                let main = MainEffects::fit(&fit_part, config, tau);
                for &kappa in &config.shrinkage {
                    let model = main.with_interaction(kappa);
                    let p = model.predict_samples(&held);
                    let sse: f64 = p
                        .iter()
                        .zip(&z_held)
                        .map(|(p, z)| (p.ln_1p() - z).powi(2))
                        .sum();
                    let rmse = (sse / p.len() as f64).sqrt();
                    holdout_scores.push(HoldoutScore {
                        memory: tau,
                        shrinkage: kappa,
                        rmse,
                    });
                    if rmse < best {
                        best = rmse;
                        (memory, shrinkage) = (tau, kappa);
                    }
                }
            }
        }
        let main = MainEffects::fit(train, config, memory);
        let mut model = main.with_interaction(shrinkage);
        model.holdout_scores = holdout_scores;
        model.process_sigma = main.process_sigma(&model);
        Ok(model)
    }

    /// The chosen memory `τ` of (L7), in periods (`∞`: every day alike).
    pub fn memory(&self) -> f64 {
        self.memory
    }

    /// The chosen shrinkage `κ` of (L4) (`∞`: no interaction).
    pub fn shrinkage(&self) -> f64 {
        self.shrinkage
    }

    /// Hold-out RMSE of ln(1 + ŷ) for every candidate `(τ, κ)`, in the order tried (L5).
    pub fn holdout_scores(&self) -> &[HoldoutScore] {
        &self.holdout_scores
    }

    /// The profile of the day `b_h` (centred; in the log domain).
    pub fn profile(&self) -> &[f64] {
        &self.profile
    }

    /// Residual standard deviation `σ` of (L2) on the training samples.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// Standard deviation of a whole bin's `ln(1 + rate)` around the model, the noise of the
    /// robot's short observations left out ([`crate::nugget`], (N3)); `None` if unknown.
    pub fn process_sigma(&self) -> Option<f64> {
        self.process_sigma
    }

    /// The training cells and their terms.
    pub fn cells(&self) -> &[LogCell] {
        &self.cells
    }

    /// The day length `P` of (L3).
    pub fn period(&self) -> f64 {
        self.period
    }

    /// The smallest square `[x_min, y_min, x_max, y_max]` of the training cell centres.
    pub fn domain(&self) -> [f64; 4] {
        let mut d = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for c in &self.cells {
            d[0] = d[0].min(c.x[0]);
            d[1] = d[1].min(c.x[1]);
            d[2] = d[2].max(c.x[0]);
            d[3] = d[3].max(c.x[1]);
        }
        d
    }

    /// The log-domain mean `m = a_c + b_h + γ_c,h` of (L2) at `(x, t)`.
    pub fn log_mean(&self, x: [f64; 2], t: f64) -> f64 {
        let h = phase_bin(t, self.period, self.profile.len());
        let key = CellKey::of(x);
        match self.cells.binary_search_by(|c| CellKey::of(c.x).cmp(&key)) {
            Ok(i) => self.cells[i].level + self.profile[h] + self.cells[i].interaction[h],
            Err(_) => self.fallback + self.profile[h],
        }
    }

    /// Prediction (L6) and the standard deviation of the rate under (L2), the log-normal
    /// `1 + y ~ LogNormal(m, σ²)`: `sqrt((e^{σ²} − 1) e^{2m + σ²})`.
    pub fn predict_with_std(&self, x: [f64; 2], t: f64) -> (f64, f64) {
        let m = self.log_mean(x, t);
        let s2 = self.sigma * self.sigma;
        let std = (s2.exp_m1() * (2.0 * m + s2).exp()).sqrt();
        (m.exp_m1().max(0.0), std)
    }

    /// Checks the invariants of a model read from a file: finite terms, one profile entry per
    /// bin in every cell, cells sorted and distinct.
    ///
    /// # Errors
    /// [`ActivityError::Config`] saying what is wrong.
    pub fn check(&self) -> Result<(), ActivityError> {
        let bad = |what: String| Err(ActivityError::Config(what));
        let h = self.profile.len();
        if !(self.period.is_finite() && self.period > 0.0) {
            return bad(format!("period {} is not positive", self.period));
        }
        if h == 0 || h > 100_000 {
            return bad(format!("{h} phase bins"));
        }
        let finite = self.profile.iter().all(|b| b.is_finite())
            && self.fallback.is_finite()
            && self.sigma.is_finite()
            && self.sigma >= 0.0
            && self
                .process_sigma
                .is_none_or(|s| s.is_finite() && s >= 0.0 && s <= self.sigma)
            && self.shrinkage > 0.0
            && self.memory > 0.0;
        if !finite {
            return bad("a term is not finite".into());
        }
        for (i, c) in self.cells.iter().enumerate() {
            if c.interaction.len() != h
                || !c.level.is_finite()
                || !c.x.iter().all(|v| v.is_finite())
                || !c.interaction.iter().all(|v| v.is_finite())
            {
                return bad(format!("cell {i} is malformed"));
            }
            if i > 0 && CellKey::of(self.cells[i - 1].x) >= CellKey::of(c.x) {
                return bad(format!("cell {i} is out of order"));
            }
        }
        Ok(())
    }
}

impl RatePredictor for LogAdditive {
    fn name(&self) -> &str {
        "log_additive"
    }

    fn predict(&self, x: [f64; 2], t: f64) -> f64 {
        self.log_mean(x, t).exp_m1().max(0.0)
    }

    /// The rate over a whole bin: the central interval of `1 + y ~ LogNormal(m, σ_u²)`,
    /// `exp(m ± z σ_u) − 1` (clipped at 0), `z` the standard normal quantile of
    /// `(1 + coverage) / 2` and `σ_u` the [process deviation](LogAdditive::process_sigma)
    /// (N3) of [`crate::nugget`]: the spread of whole hours, without the glimpses' noise.
    fn interval(&self, x: [f64; 2], t: f64, coverage: f64) -> Option<(f64, f64)> {
        self.log_normal_interval(x, t, coverage, self.process_sigma?)
    }

    /// One observation like the training samples: the central interval of the log-normal of
    /// (L2), `exp(m ± z σ) − 1` (clipped at 0), `σ` the residual deviation on the training
    /// samples (process and glimpse noise together).
    fn observation_interval(&self, x: [f64; 2], t: f64, coverage: f64) -> Option<(f64, f64)> {
        self.log_normal_interval(x, t, coverage, self.sigma)
    }
}

impl LogAdditive {
    /// `exp(m ± z s) − 1` (clipped at 0), `z` the standard normal quantile of
    /// `(1 + coverage) / 2`; `None` unless `coverage` is in `(0, 1)`.
    fn log_normal_interval(
        &self,
        x: [f64; 2],
        t: f64,
        coverage: f64,
        s: f64,
    ) -> Option<(f64, f64)> {
        use statrs::distribution::{ContinuousCDF, Normal};
        if !(coverage > 0.0 && coverage < 1.0) {
            return None;
        }
        let z = Normal::standard().inverse_cdf(0.5 + coverage / 2.0);
        let m = self.log_mean(x, t);
        let bound = |k: f64| (m + k * z * s).exp_m1().max(0.0);
        Some((bound(-1.0), bound(1.0)))
    }
}

/// (L3): the phase bin of `t`, in `0..bins`.
fn phase_bin(t: f64, period: f64, bins: usize) -> usize {
    // Multiplying before dividing keeps whole phases exact (t = 13, P = 12, H = 12: bin 1).
    let bin = t.rem_euclid(period) * bins as f64 / period;
    (bin as usize).min(bins - 1)
}

/// The samples before the last `fraction` of the distinct times, and the rest; `None` with
/// fewer than two distinct times.
fn holdout_split(train: &RateSamples, fraction: f64) -> Option<(RateSamples, RateSamples)> {
    let mut times = train.t().to_vec();
    times.sort_by(f64::total_cmp);
    times.dedup();
    if times.len() < 2 {
        return None;
    }
    let first_held =
        ((times.len() as f64 * (1.0 - fraction)).ceil() as usize).clamp(1, times.len() - 1);
    Some(train.split_at(times[first_held]))
}

/// The weighted least-squares fit of `z = a_c + b_h` by backfitting, with the per-sample
/// cell index, phase bin and weight it was fitted on.
struct MainEffects {
    period: f64,
    memory: f64,
    keys: Vec<CellKey>,
    level: Vec<f64>,
    profile: Vec<f64>,
    sample_cell: Vec<usize>,
    sample_bin: Vec<usize>,
    /// The period (day) index `⌊t / P⌋` of every sample.
    sample_day: Vec<i64>,
    weight: Vec<f64>,
    z: Vec<f64>,
}

impl MainEffects {
    fn fit(train: &RateSamples, config: &LogAdditiveConfig, memory: f64) -> Self {
        let (h, period) = (config.bins, config.period);
        let mut cells: Vec<(CellKey, Vec<usize>)> = train.cells().into_iter().collect();
        cells.sort_by_key(|c| c.0);
        let n = train.len();
        let mut sample_cell = vec![0; n];
        for (c, (_, idx)) in cells.iter().enumerate() {
            for &i in idx {
                sample_cell[i] = c;
            }
        }
        let t = train.t();
        let sample_bin: Vec<usize> = t.iter().map(|&t| phase_bin(t, period, h)).collect();
        // Saturating: a day index beyond ±2^63 (absurd times) only merges far-away days.
        let sample_day: Vec<i64> = t.iter().map(|&t| (t / period).floor() as i64).collect();
        // (L7): whole periods before the last training time.
        let t_max = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let weight: Vec<f64> = t
            .iter()
            .map(|&t| {
                if memory.is_finite() {
                    (-((t_max - t) / period).floor() / memory).exp()
                } else {
                    1.0
                }
            })
            .collect();
        let z: Vec<f64> = train.y().iter().map(|y| y.ln_1p()).collect();
        let mut cell_w = vec![0.0; cells.len()];
        let mut bin_w = vec![0.0; h];
        for i in 0..n {
            cell_w[sample_cell[i]] += weight[i];
            bin_w[sample_bin[i]] += weight[i];
        }
        let mut level = vec![0.0; cells.len()];
        let mut profile = vec![0.0; h];
        for _ in 0..config.max_sweeps {
            let mut sum = vec![0.0; cells.len()];
            for i in 0..n {
                sum[sample_cell[i]] += weight[i] * (z[i] - profile[sample_bin[i]]);
            }
            let mut moved: f64 = 0.0;
            for c in 0..cells.len() {
                let a = sum[c] / cell_w[c];
                moved = moved.max((a - level[c]).abs());
                level[c] = a;
            }
            let mut sum = vec![0.0; h];
            for i in 0..n {
                sum[sample_bin[i]] += weight[i] * (z[i] - level[sample_cell[i]]);
            }
            for b in 0..h {
                if bin_w[b] > 0.0 {
                    let v = sum[b] / bin_w[b];
                    moved = moved.max((v - profile[b]).abs());
                    profile[b] = v;
                }
            }
            if moved < 1e-12 {
                break;
            }
        }
        // Centre the profile over the samples, Σ_i w_i b_h(i) = 0, moving its mean into the
        // levels.
        let shift = (0..h).map(|b| bin_w[b] * profile[b]).sum::<f64>() / bin_w.iter().sum::<f64>();
        for b in 0..h {
            if bin_w[b] > 0.0 {
                profile[b] -= shift;
            }
        }
        for a in &mut level {
            *a += shift;
        }
        MainEffects {
            period,
            memory,
            keys: cells.into_iter().map(|c| c.0).collect(),
            level,
            profile,
            sample_cell,
            sample_bin,
            sample_day,
            weight,
            z,
        }
    }

    /// The model with the interaction (L4) for shrinkage `kappa`, and the weighted `σ` of its
    /// residuals.
    fn with_interaction(&self, kappa: f64) -> LogAdditive {
        let h = self.profile.len();
        let n = self.z.len();
        let mut sum = vec![vec![0.0; h]; self.keys.len()];
        let mut weight = vec![vec![0.0; h]; self.keys.len()];
        let residual = |i: usize| {
            self.z[i] - self.level[self.sample_cell[i]] - self.profile[self.sample_bin[i]]
        };
        for i in 0..n {
            let (c, b) = (self.sample_cell[i], self.sample_bin[i]);
            sum[c][b] += self.weight[i] * residual(i);
            weight[c][b] += self.weight[i];
        }
        let cells: Vec<LogCell> = self
            .keys
            .iter()
            .enumerate()
            .map(|(c, key)| LogCell {
                x: key.centre(),
                level: self.level[c],
                interaction: if kappa.is_finite() {
                    (0..h).map(|b| sum[c][b] / (weight[c][b] + kappa)).collect()
                } else {
                    vec![0.0; h]
                },
            })
            .collect();
        let total: f64 = self.weight.iter().sum();
        let sse: f64 = (0..n)
            .map(|i| {
                let r = residual(i) - cells[self.sample_cell[i]].interaction[self.sample_bin[i]];
                self.weight[i] * r * r
            })
            .sum();
        let fallback = (0..n)
            .map(|i| self.weight[i] * self.level[self.sample_cell[i]])
            .sum::<f64>()
            / total;
        LogAdditive {
            period: self.period,
            profile: self.profile.clone(),
            cells,
            fallback,
            shrinkage: kappa,
            memory: self.memory,
            sigma: (sse / total).sqrt(),
            holdout_scores: Vec::new(),
            process_sigma: None,
        }
    }

    /// The process deviation (N3) of `model`'s residuals on these samples
    /// ([`crate::nugget::process_variance`]), at most `σ`.
    fn process_sigma(&self, model: &LogAdditive) -> Option<f64> {
        let residuals: Vec<BinResidual> = (0..self.z.len())
            .map(|i| {
                let (c, b) = (self.sample_cell[i], self.sample_bin[i]);
                BinResidual {
                    cell: c,
                    day: self.sample_day[i],
                    bin: b,
                    residual: self.z[i]
                        - self.level[c]
                        - self.profile[b]
                        - model.cells[c].interaction[b],
                    weight: self.weight[i],
                }
            })
            .collect();
        let variance = process_variance(&residuals)?.variance;
        Some(variance.sqrt().min(model.sigma))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The conformance check of Log-AM's observation intervals: rates drawn from the law of
    /// (L2) itself (`ln(1 + y) = a_c + b_h + ε`, `ε ~ N(0, 0.5²)`, 10 cells, 12 bins of a
    /// 12-hour day, 20 days) are held by the intervals of 50, 90 and 99 % that often.
    #[test]
    fn observation_intervals_cover_draws_from_the_models_own_law() {
        let mut rng = chronomap_core::rng::Xoshiro256StarStar::seed_from_u64(9);
        let mut normal = move || rng.standard_normal();
        let mut draw = |days: std::ops::Range<u32>, repeats: u32| {
            let mut s = RateSamples::default();
            for day in days {
                for h in 0..12u32 {
                    for c in 0..10u32 {
                        for _ in 0..repeats {
                            let z = 1.0
                                + 0.2 * f64::from(c)
                                + (f64::from(h) * 0.5).sin()
                                + 0.5 * normal();
                            let x = [0.25 + 0.5 * f64::from(c), 0.25];
                            s.push(x, f64::from(day * 12 + h), z.exp_m1().max(0.0))
                                .unwrap();
                        }
                    }
                }
            }
            s
        };
        let train = draw(0..20, 1);
        let fresh = draw(20..30, 10);
        let config = LogAdditiveConfig {
            shrinkage: vec![f64::INFINITY],
            memory: vec![f64::INFINITY],
            ..LogAdditiveConfig::default()
        };
        let model = LogAdditive::fit(&train, &config).unwrap();
        assert!((model.sigma() - 0.5).abs() < 0.05, "σ {}", model.sigma());
        for coverage in [0.5, 0.9, 0.99] {
            let intervals: Vec<(f64, f64)> = fresh
                .x()
                .iter()
                .zip(fresh.t())
                .map(|(&x, &t)| model.observation_interval(x, t, coverage).unwrap())
                .collect();
            chronomap_core::conformance::check_interval_coverage(
                &format!("Log-AM, {coverage}"),
                coverage,
                &intervals,
                fresh.y(),
            );
        }
        assert_eq!(model.observation_interval([0.25, 0.25], 0.0, 1.0), None);
    }

    /// The conformance check of Log-AM's intervals of whole bins, on the law of
    /// [`crate::nugget`] (N1): per cell and day an AR(1) process over the 12 hourly bins
    /// (deviation 0.5, correlation 0.8 from hour to hour) on `a_c + b_h`; a training sample
    /// is a glimpse, the process plus white noise of deviation 0.8. Fresh days' whole bins
    /// (the process alone) are held by the intervals of 50, 90 and 99 % that often, fresh
    /// glimpses by the observation intervals.
    #[test]
    fn whole_bin_intervals_cover_the_process_under_glimpse_noise() {
        let mut rng = chronomap_core::rng::Xoshiro256StarStar::seed_from_u64(11);
        let mut draw = |days: std::ops::Range<u32>, glimpse: bool| {
            let mut s = RateSamples::default();
            for c in 0..30u32 {
                for day in days.clone() {
                    let mut u = 0.5 * rng.standard_normal();
                    for h in 0..12u32 {
                        if h > 0 {
                            u = 0.8 * u + 0.3 * rng.standard_normal(); // 0.5 · sqrt(1 − 0.8²)
                        }
                        let e = if glimpse {
                            0.8 * rng.standard_normal()
                        } else {
                            0.0
                        };
                        let z = 1.5 + 0.05 * f64::from(c) + (f64::from(h) * 0.5).sin() + u + e;
                        let x = [0.25 + 0.5 * f64::from(c), 0.25];
                        s.push(x, f64::from(day * 12 + h), z.exp_m1().max(0.0))
                            .unwrap();
                    }
                }
            }
            s
        };
        let train = draw(0..60, true);
        let whole_bins = draw(60..160, false);
        let glimpses = draw(60..160, true);
        let config = LogAdditiveConfig {
            shrinkage: vec![f64::INFINITY],
            memory: vec![f64::INFINITY],
            ..LogAdditiveConfig::default()
        };
        let model = LogAdditive::fit(&train, &config).unwrap();
        let process = model.process_sigma().unwrap();
        assert!((process - 0.5).abs() < 0.03, "σ_u {process}");
        assert!(
            (model.sigma() - 0.5f64.hypot(0.8)).abs() < 0.03,
            "σ {}",
            model.sigma()
        );
        for coverage in [0.5, 0.9, 0.99] {
            for (what, fresh) in [("whole bins", &whole_bins), ("glimpses", &glimpses)] {
                let intervals: Vec<(f64, f64)> = fresh
                    .x()
                    .iter()
                    .zip(fresh.t())
                    .map(|(&x, &t)| {
                        if what == "glimpses" {
                            model.observation_interval(x, t, coverage)
                        } else {
                            model.interval(x, t, coverage)
                        }
                        .unwrap()
                    })
                    .collect();
                chronomap_core::conformance::check_interval_coverage(
                    &format!("Log-AM {what}, {coverage}"),
                    coverage,
                    &intervals,
                    fresh.y(),
                );
            }
        }
    }

    fn samples(rows: &[([f64; 2], f64, f64)]) -> RateSamples {
        let mut s = RateSamples::default();
        for &(x, t, y) in rows {
            s.push(x, t, y).unwrap();
        }
        s
    }

    /// Period, bins and shrinkage candidates; every day weighed alike.
    fn config(period: f64, bins: usize, shrinkage: &[f64]) -> LogAdditiveConfig {
        LogAdditiveConfig {
            period,
            bins,
            shrinkage: shrinkage.to_vec(),
            memory: vec![f64::INFINITY],
            ..LogAdditiveConfig::default()
        }
    }

    const A: [f64; 2] = [0.25, 0.25];
    const B: [f64; 2] = [0.75, 0.25];

    /// `y` with `ln(1 + y) = z`.
    fn rate(z: f64) -> f64 {
        z.exp_m1()
    }

    #[test]
    fn additive_data_are_recovered_exactly_and_the_interaction_is_left_out() {
        // z = a_c + b_h with a_A = 2, a_B = 1.5, b = (−1, 1) over period 2, four days.
        let mut rows = Vec::new();
        for t in 0..8 {
            let b = if t % 2 == 0 { -1.0 } else { 1.0 };
            rows.push((A, f64::from(t), rate(2.0 + b)));
            rows.push((B, f64::from(t), rate(1.5 + b)));
        }
        let m = LogAdditive::fit(&samples(&rows), &config(2.0, 2, &[f64::INFINITY, 1.0])).unwrap();
        // Every candidate fits the hold-out (up to rounding): no residual to shrink.
        assert_eq!(m.holdout_scores().len(), 2);
        assert!(m.holdout_scores().iter().all(|s| s.rmse < 1e-12));
        assert!((m.profile()[0] + 1.0).abs() < 1e-12 && (m.profile()[1] - 1.0).abs() < 1e-12);
        assert!(m.sigma() < 1e-12);
        assert!((m.predict(A, 10.0) - rate(1.0)).abs() < 1e-9);
        assert!((m.predict(B, 11.0) - rate(2.5)).abs() < 1e-9);
        // An unseen cell: the mean level (1.75) with the hour's profile.
        assert!((m.predict([9.0, 9.0], 11.0) - rate(2.75)).abs() < 1e-9);
        // Time is folded by the period, negative times too; whole phases land in their bin.
        assert_eq!(phase_bin(13.0, 12.0, 12), 1);
        assert_eq!(phase_bin(-1.0, 12.0, 12), 11);
        assert_eq!(phase_bin(11.999, 12.0, 12), 11);
        assert_eq!(m.predict(A, -1.0).to_bits(), m.predict(A, 1.0).to_bits());
    }

    #[test]
    fn the_interaction_is_the_shrunken_mean_residual_by_hand() {
        // A is busy in bin 0, B in bin 1: z = (A0 0, A1 2, B0 2, B1 0). Main effects a = 1, b = 0;
        // residuals ±1; with κ = 1 and one sample per cell and bin, γ = ±1 / (1 + 1) = ±0.5
        // and the remaining residuals ∓0.5: σ = 0.5.
        let rows = [
            (A, 0.0, rate(0.0)),
            (A, 1.0, rate(2.0)),
            (B, 0.0, rate(2.0)),
            (B, 1.0, rate(0.0)),
        ];
        let m = LogAdditive::fit(&samples(&rows), &config(2.0, 2, &[1.0])).unwrap();
        assert!(m.holdout_scores().is_empty());
        assert!((m.predict(A, 2.0) - rate(0.5)).abs() < 1e-12);
        assert!((m.predict(A, 3.0) - rate(1.5)).abs() < 1e-12);
        assert!((m.predict(B, 2.0) - rate(1.5)).abs() < 1e-12);
        assert!((m.sigma() - 0.5).abs() < 1e-12);
        // The std of the log-normal 1 + y: sqrt((e^σ² − 1) e^{2m + σ²}) at m = 0.5.
        let (p, std) = m.predict_with_std(A, 2.0);
        assert!((p - rate(0.5)).abs() < 1e-12);
        let want = ((0.25f64).exp_m1() * (1.0f64 + 0.25).exp()).sqrt();
        assert!((std - want).abs() < 1e-12, "{std} {want}");
        // κ = ∞: the shared profile alone, a = 1 everywhere.
        let m = LogAdditive::fit(&samples(&rows), &config(2.0, 2, &[f64::INFINITY])).unwrap();
        assert!((m.predict(A, 2.0) - rate(1.0)).abs() < 1e-12);
        assert!((m.sigma() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_hold_out_chooses_a_persistent_interaction_and_rejects_noise() {
        // Ten days of two bins. Persistent: A's rhythm is the opposite of B's every day, so the
        // interaction predicts the held-out days and the smallest κ wins.
        let mut rows = Vec::new();
        for t in 0..20 {
            let even = t % 2 == 0;
            rows.push((A, f64::from(t), rate(if even { 0.0 } else { 2.0 })));
            rows.push((B, f64::from(t), rate(if even { 2.0 } else { 0.0 })));
        }
        let cands = [f64::INFINITY, 10.0, 1.0, 0.1];
        let m = LogAdditive::fit(&samples(&rows), &config(2.0, 2, &cands)).unwrap();
        assert_eq!(m.shrinkage(), 0.1);
        // Noise: the same pattern in the first eight days, reversed in the last two; fitting
        // it does worse on the hold-out than leaving it out.
        let mut rows = Vec::new();
        for t in 0..20 {
            let flip = (t % 2 == 0) != (t >= 16);
            rows.push((A, f64::from(t), rate(if flip { 0.0 } else { 2.0 })));
            rows.push((B, f64::from(t), rate(if flip { 2.0 } else { 0.0 })));
        }
        let m = LogAdditive::fit(&samples(&rows), &config(2.0, 2, &cands)).unwrap();
        assert_eq!(m.shrinkage(), f64::INFINITY);
        let scores = m.holdout_scores();
        assert_eq!(
            scores.iter().map(|s| s.shrinkage).collect::<Vec<_>>(),
            cands
        );
        assert!(
            scores.windows(2).all(|w| w[0].rmse < w[1].rmse),
            "{scores:?}"
        );
    }

    #[test]
    fn memory_weighs_the_days_before_the_last_by_e_to_the_minus_days_over_tau() {
        // One cell, one bin a day: z = 0, 0, 3 on days 0, 1, 2. With τ = 1 the weights are
        // e^−2, e^−1, 1 (L7) and the level is their weighted mean of z.
        let rows = [(A, 0.0, 0.0), (A, 1.0, 0.0), (A, 2.0, rate(3.0))];
        let c = LogAdditiveConfig {
            memory: vec![1.0],
            ..config(1.0, 1, &[f64::INFINITY])
        };
        let m = LogAdditive::fit(&samples(&rows), &c).unwrap();
        let e = std::f64::consts::E;
        let level = 3.0 / (1.0 + 1.0 / e + 1.0 / (e * e));
        assert!((m.predict(A, 3.0) - rate(level)).abs() < 1e-12);
        assert_eq!(m.memory(), 1.0);
        // A steady trend: the hold-out (days 8 and 9) prefers the shortest memory.
        let rows: Vec<_> = (0..10)
            .map(|d| (A, f64::from(d), rate(0.2 * f64::from(d))))
            .collect();
        let c = LogAdditiveConfig {
            memory: vec![f64::INFINITY, 4.0, 1.0, 0.25],
            ..config(1.0, 1, &[f64::INFINITY])
        };
        let m = LogAdditive::fit(&samples(&rows), &c).unwrap();
        assert_eq!(m.memory(), 0.25);
        let scores: Vec<f64> = m.holdout_scores().iter().map(|s| s.rmse).collect();
        assert!(scores.windows(2).all(|w| w[0] > w[1]), "{scores:?}");
    }

    #[test]
    fn bad_configs_and_empty_data_are_refused() {
        let s = samples(&[(A, 0.0, 1.0)]);
        let bad: [fn(&mut LogAdditiveConfig); 8] = [
            |c| c.period = 0.0,
            |c| c.bins = 0,
            |c| c.shrinkage = vec![],
            |c| c.shrinkage = vec![0.0],
            |c| c.memory = vec![],
            |c| c.memory = vec![f64::NAN],
            |c| c.holdout = 1.0,
            |c| c.max_sweeps = 0,
        ];
        for edit in bad {
            let mut c = LogAdditiveConfig::default();
            edit(&mut c);
            assert!(matches!(
                LogAdditive::fit(&s, &c),
                Err(ActivityError::Config(_))
            ));
        }
        assert_eq!(
            LogAdditive::fit(&RateSamples::default(), &LogAdditiveConfig::default()),
            Err(ActivityError::Empty)
        );
        // One time only: nothing to hold out, the first candidate.
        let m = LogAdditive::fit(&s, &LogAdditiveConfig::default()).unwrap();
        assert_eq!(m.shrinkage(), f64::INFINITY);
        assert!((m.predict(A, 5.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_model_survives_serialisation_and_check_refuses_damage() {
        let rows = [(A, 0.0, 1.0), (A, 1.0, 3.0), (B, 0.0, 2.0), (B, 1.0, 0.0)];
        let m = LogAdditive::fit(&samples(&rows), &config(2.0, 2, &[1.0])).unwrap();
        m.check().unwrap();
        let bytes = postcard::to_allocvec(&m).unwrap();
        let back: LogAdditive = postcard::from_bytes(&bytes).unwrap();
        assert_eq!(back, m);
        assert_eq!(back.predict(B, 7.0).to_bits(), m.predict(B, 7.0).to_bits());
        let mut damaged = m.clone();
        damaged.cells.swap(0, 1);
        assert!(damaged.check().is_err());
        let mut damaged = m.clone();
        damaged.cells[0].interaction.pop();
        assert!(damaged.check().is_err());
        let mut damaged = m;
        damaged.profile[1] = f64::NAN;
        assert!(damaged.check().is_err());
    }
}
