//! Prediction intervals of traversal durations: how long an edge may take, not only how long it
//! takes on average.
//!
//! [Fentanes 2015] predicts an edge's duration at time `t` as the expectation of a FreMEn model
//! (eq. (2)); users of topological navigation asked for years for a confidence interval on
//! travel times. Durations have long right tails (a person in the way, a replanned path), and
//! edges differ in length by orders of magnitude, so the spread is described on the log scale,
//! where it is shared across edges: the *residual* of a successful traversal of duration `d`
//! at time `t` is
//!
//! ```text
//!     r = ln(max(d, ε) / max(d̂(t), ε)),   ε = 0.01 s
//! ```
//!
//! with `d̂(t)` the edge's expected duration. Each edge keeps the empirical quantiles of its
//! residuals on its training traversals ([`ResidualQuantiles`], levels 0.005, 0.010, …, 0.995);
//! all edges together give the pooled quantiles. An edge with `n` traversals uses the quantile
//! function `w q_edge + (1 − w) q_pooled` with `w = n / (n + k)`, `k` =
//! [`DURATION_PSEUDO_TRAVERSALS`] (a mixture of quantile functions, "Vincentization",
//! Ratcliff 1979): an edge traversed 5 times borrows most of its spread from the others, one
//! traversed 500 times has its own. Each quantile function is read at levels stretched away
//! from the median by `(n + 1)/n` for its `n` residuals ([`ResidualQuantiles::at_stretched`],
//! the finite-sample widening of conformal prediction). The interval of coverage `1 − α` at `t`
//! is `d̂(t) · exp(q(α/2)) … d̂(t) · exp(q(1 − α/2))`.
//!
//! A robot that keeps travelling sees each traversal's duration after it predicted it. Routes drift
//! (an edge is crossed faster in later weeks than in the training weeks), and a spread fitted once
//! holds less or more than its nominal share. [`DurationSpread::adapt`] corrects that online by
//! adaptive conformal inference ([Gibbs 2021] eq. 2), once for every stored level `u` and all edges
//! together: the level `v` read from the quantile functions in place of `u` moves after each
//! traversal with residual `r` by
//!
//! ```text
//!     v ← v + γ (u − 1[r ≤ q(v)]),   γ = 0.005 (their experiments' step)
//! ```
//!
//! so that, whatever the drift, the long-run share of residuals at or below `q(v)` tends to `u`
//! ([Gibbs 2021] Proposition 4.1: within `(max(v₁, 1 − v₁) + γ) / (γ T)` after `T` traversals), and
//! the central intervals between two adapted levels hold their nominal share. Before the first
//! traversal is adapted to, `v = u`. A drift may call for levels beyond the stored ones (a route
//! become more erratic than any training traversal): there the quantile function goes on with an
//! exponential tail through its two outermost stored levels, one more spacing `q(0.010) − q(0.005)`
//! for each halving of the level (a Pareto tail of the durations), to `q(v) = −∞` at `v ≤ 0` and
//! `+∞` at `v ≥ 1`, as in adaptive conformal inference, whose levels then stay within `[−γ, 1 + γ]`
//! ([Gibbs 2021] Lemma 4.1). An interval's lower end at `v ≤ 0` is 0 s; its upper end is read at
//! most at [`ADAPTED_LEVEL_CAP`], so that it stays finite.

use serde::{Deserialize, Serialize};

/// Durations below this (s) count as this much in residuals (a duration of 0 has no logarithm).
pub const DURATION_FLOOR_SECS: f64 = 0.01;

/// Weight `k` of the pooled residuals in an edge's quantiles, in traversals (see the
/// [module docs](self)); fixed a priori, not tuned to any split.
pub const DURATION_PSEUDO_TRAVERSALS: f64 = 20.0;

/// Levels of the stored quantiles: `i / 200` for `i = 1..=199`.
const LEVELS: usize = 199;

/// Step `γ` of the online adaptation of the levels ([`DurationSpread::adapt`]): the value of
/// [Gibbs 2021]'s experiments, fixed a priori, not tuned to any split.
pub const ADAPTATION_STEP: f64 = 0.005;

/// The highest level an interval's upper end is read at after adaptation, `1 − 0.0005` (a
/// tenth of the lowest stored level from 1): above it the end would be unbounded.
pub const ADAPTED_LEVEL_CAP: f64 = 0.9995;

/// The lowest stored level, `1 / 200`.
const LOWEST_LEVEL: f64 = 1.0 / (LEVELS + 1) as f64;

/// Widest coverage an interval can have: 99 % (the stored quantiles end at 0.005 and 0.995).
pub const MAX_COVERAGE: f64 = 0.99;

/// The value at `level` of `values` stored at the levels `i / 200`, `i = 1..=199`, linearly
/// interpolated between them (clamped to the first and last).
fn at_level(values: &[f64], level: f64) -> f64 {
    let position = (level * (LEVELS + 1) as f64 - 1.0).clamp(0.0, (LEVELS - 1) as f64);
    let low = position.floor() as usize;
    let high = (low + 1).min(LEVELS - 1);
    let fraction = position - low as f64;
    values[low] + fraction * (values[high] - values[low])
}

/// The log residual of a duration `d` against the prediction `expected` (see the
/// [module docs](self)).
pub fn residual(duration_secs: f64, expected_secs: f64) -> f64 {
    (duration_secs.max(DURATION_FLOOR_SECS) / expected_secs.max(DURATION_FLOOR_SECS)).ln()
}

/// Empirical quantiles of a sample of residuals at the levels `i / 200`, `i = 1..=199`
/// (linear interpolation between order statistics, numpy's default "linear" method).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ResidualQuantiles {
    /// Residuals the quantiles were computed from.
    pub count: usize,
    /// The quantiles, increasing (empty when `count` is 0).
    pub quantiles: Vec<f64>,
}

impl ResidualQuantiles {
    /// The quantiles of `residuals` (non-finite ones are left out).
    pub fn of(residuals: &[f64]) -> Self {
        let mut sorted: Vec<f64> = residuals
            .iter()
            .copied()
            .filter(|r| r.is_finite())
            .collect();
        sorted.sort_by(f64::total_cmp);
        if sorted.is_empty() {
            return ResidualQuantiles::default();
        }
        let quantiles = (1..=LEVELS)
            .map(|i| {
                let position = i as f64 / (LEVELS + 1) as f64 * (sorted.len() - 1) as f64;
                let low = position.floor() as usize;
                let high = (low + 1).min(sorted.len() - 1);
                let fraction = position - low as f64;
                sorted[low] + fraction * (sorted[high] - sorted[low])
            })
            .collect();
        ResidualQuantiles {
            count: sorted.len(),
            quantiles,
        }
    }

    /// The quantile at `level` in `[0.005, 0.995]` (clamped), interpolated between the stored
    /// levels; `None` without residuals.
    pub fn at(&self, level: f64) -> Option<f64> {
        (self.quantiles.len() == LEVELS).then(|| at_level(&self.quantiles, level))
    }

    /// The quantile at `level` stretched away from the median for a sample of `count`
    /// residuals: at `1/2 + (level − 1/2)(n + 1)/n`. A central interval between the empirical
    /// quantiles of `n` residuals holds a fresh one less often than its nominal coverage; split
    /// conformal prediction takes the `⌈(n + 1)(1 − α)⌉`-th smallest of `n` (Vovk, Gammerman
    /// and Shafer 2005; Lei et al., JASA 2018), about this stretch. It matters for an edge
    /// traversed a few times and vanishes for many.
    pub fn at_stretched(&self, level: f64) -> Option<f64> {
        let n = self.count as f64;
        self.at(0.5 + (level - 0.5) * (n + 1.0) / n)
    }

    /// Whether the stored values can be used (for models read from files).
    pub fn is_consistent(&self) -> bool {
        (self.count == 0 && self.quantiles.is_empty())
            || (self.count > 0
                && self.quantiles.len() == LEVELS
                && self.quantiles.iter().all(|q| q.is_finite())
                && self.quantiles.windows(2).all(|w| w[0] <= w[1]))
    }
}

/// The stored level `i / 200` for the index `i − 1`.
fn nominal_level(index: usize) -> f64 {
    (index + 1) as f64 / (LEVELS + 1) as f64
}

/// The levels read from the quantile functions in place of the stored ones, adapted online to
/// the traversals seen after the fit ([`DurationSpread::adapt`], the [module docs](self)).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AdaptedLevels {
    /// Traversals adapted to.
    pub count: u64,
    /// For the stored level `i / 200`, the level read (`i = 1..=199`; empty: none adapted to
    /// yet, the stored levels themselves).
    pub levels: Vec<f64>,
}

impl AdaptedLevels {
    /// The level read in place of the nominal `level` (in `[0.005, 0.995]`), interpolated
    /// between the stored levels.
    pub fn read(&self, level: f64) -> f64 {
        if self.levels.len() != LEVELS {
            return level;
        }
        at_level(&self.levels, level)
    }

    /// Whether the stored values can be used (for models read from files).
    pub fn is_consistent(&self) -> bool {
        (self.count == 0 && self.levels.is_empty())
            || (self.count > 0
                && self.levels.len() == LEVELS
                && self
                    .levels
                    .iter()
                    .all(|v| (-ADAPTATION_STEP..=1.0 + ADAPTATION_STEP).contains(v)))
    }
}

/// The spread of every edge's durations around its model, and of all edges together.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DurationSpread {
    /// Per edge, in the map's order.
    pub edges: Vec<ResidualQuantiles>,
    /// All edges' residuals together.
    pub pooled: ResidualQuantiles,
    /// The levels adapted online to later traversals ([`DurationSpread::adapt`]).
    pub adapted: AdaptedLevels,
}

/// The layout of [`DurationSpread`] in files written before it adapted online: read as a
/// spread not adapted yet.
#[derive(Deserialize)]
pub struct DurationSpreadWithoutAdaptation {
    edges: Vec<ResidualQuantiles>,
    pooled: ResidualQuantiles,
}

impl From<DurationSpreadWithoutAdaptation> for DurationSpread {
    fn from(old: DurationSpreadWithoutAdaptation) -> Self {
        DurationSpread {
            edges: old.edges,
            pooled: old.pooled,
            adapted: AdaptedLevels::default(),
        }
    }
}

impl DurationSpread {
    /// The spread of `residuals[e]`, the residuals of edge `e`'s successful traversals.
    pub fn fit(residuals: &[Vec<f64>]) -> Self {
        let all: Vec<f64> = residuals.iter().flatten().copied().collect();
        DurationSpread {
            edges: residuals.iter().map(|r| ResidualQuantiles::of(r)).collect(),
            pooled: ResidualQuantiles::of(&all),
            adapted: AdaptedLevels::default(),
        }
    }

    /// Adapts the levels to one more successful traversal of `edge` whose residual against the
    /// prediction made before it was `residual` (see the [module docs](self)): every stored
    /// level's `v` moves by `γ (u − 1[r ≤ q(v)])`. Nothing happens for a
    /// non-finite residual or a spread without residuals.
    pub fn adapt(&mut self, edge: usize, residual: f64) {
        if !residual.is_finite() || self.pooled.count == 0 {
            return;
        }
        let current: Vec<f64> = (0..LEVELS)
            .map(|i| self.adapted.read(nominal_level(i)))
            .collect();
        let moved = current
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                let at_or_below = self.tailed_quantile(edge, v).is_some_and(|q| residual <= q);
                let miss = if at_or_below { 1.0 } else { 0.0 };
                // Within [−γ, 1 + γ] by the rule itself; the clamp only absorbs rounding.
                (v + ADAPTATION_STEP * (nominal_level(i) - miss))
                    .clamp(-ADAPTATION_STEP, 1.0 + ADAPTATION_STEP)
            })
            .collect();
        self.adapted.levels = moved;
        self.adapted.count = self.adapted.count.saturating_add(1);
    }

    /// The residual quantile of `edge` at `level`: the edge's own and the pooled quantile
    /// weighted `n / (n + k)` and `k / (n + k)`; `None` when no edge had a residual.
    pub fn quantile(&self, edge: usize, level: f64) -> Option<f64> {
        let pooled = self.pooled.at_stretched(level)?;
        let Some(own) = self.edges.get(edge).filter(|q| q.count > 0) else {
            return Some(pooled);
        };
        let n = own.count as f64;
        let w = n / (n + DURATION_PSEUDO_TRAVERSALS);
        Some(w * own.at_stretched(level)? + (1.0 - w) * pooled)
    }

    /// The residual quantile of `edge` at a level read after adaptation:
    /// [`DurationSpread::quantile`] within the stored levels, beyond them an exponential tail
    /// through the two outermost, `−∞` at `level ≤ 0` and `+∞` at `level ≥ 1` (see the
    /// [module docs](self)); `None` when no edge had a residual.
    pub fn tailed_quantile(&self, edge: usize, level: f64) -> Option<f64> {
        let spacing = std::f64::consts::LN_2;
        if level <= 0.0 {
            self.quantile(edge, LOWEST_LEVEL).map(|_| f64::NEG_INFINITY)
        } else if level >= 1.0 {
            self.quantile(edge, LOWEST_LEVEL).map(|_| f64::INFINITY)
        } else if level < LOWEST_LEVEL {
            let (q1, q2) = (
                self.quantile(edge, LOWEST_LEVEL)?,
                self.quantile(edge, 2.0 * LOWEST_LEVEL)?,
            );
            Some(q1 + (q2 - q1) / spacing * (level / LOWEST_LEVEL).ln())
        } else if level > 1.0 - LOWEST_LEVEL {
            let (q1, q2) = (
                self.quantile(edge, 1.0 - LOWEST_LEVEL)?,
                self.quantile(edge, 1.0 - 2.0 * LOWEST_LEVEL)?,
            );
            Some(q1 + (q1 - q2) / spacing * (LOWEST_LEVEL / (1.0 - level)).ln())
        } else {
            self.quantile(edge, level)
        }
    }

    /// The interval of `coverage` (in `(0, 0.99]`) around the expected duration `expected_secs`
    /// of `edge`: `(lower, upper)` in seconds; `None` when no edge had a residual.
    pub fn interval(&self, edge: usize, expected_secs: f64, coverage: f64) -> Option<(f64, f64)> {
        let alpha = 1.0 - coverage.clamp(0.0, MAX_COVERAGE);
        let base = expected_secs.max(DURATION_FLOOR_SECS);
        let read = |level: f64| {
            self.tailed_quantile(edge, self.adapted.read(level).min(ADAPTED_LEVEL_CAP))
        };
        let lower = base * read(alpha / 2.0)?.exp();
        let upper = base * read(1.0 - alpha / 2.0)?.exp();
        // Adapted levels move one by one and may cross by a step: the interval is their span.
        Some((lower.min(upper), lower.max(upper)))
    }

    /// The durations (seconds) of `edge` at the stored levels `i / 200`, `i = 1..=199`, around
    /// the expected duration `expected_secs`: its quantile function where it is known,
    /// increasing; `None` when no edge had a residual.
    pub fn durations(&self, edge: usize, expected_secs: f64) -> Option<Vec<f64>> {
        let base = expected_secs.max(DURATION_FLOOR_SECS);
        let mut highest = f64::NEG_INFINITY;
        (0..LEVELS)
            .map(|i| {
                let level = self.adapted.read(nominal_level(i)).min(ADAPTED_LEVEL_CAP);
                // Adapted levels may cross by a step: the durations stay increasing.
                highest = highest.max(base * self.tailed_quantile(edge, level)?.exp());
                Some(highest)
            })
            .collect()
    }

    /// Whether the stored values can be used (for models read from files), with `edges` edges.
    pub fn is_consistent(&self, edges: usize) -> bool {
        self.edges.len() == edges
            && self.pooled.is_consistent()
            && self.edges.iter().all(ResidualQuantiles::is_consistent)
            && self.adapted.is_consistent()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_interpolate_like_numpy() {
        // numpy.quantile([0, 1, 2, 3, 4], 0.1) = 0.4, 0.5 → 2.0, 0.995 → 3.98.
        let q = ResidualQuantiles::of(&[4.0, 0.0, 2.0, 1.0, 3.0, f64::NAN]);
        assert_eq!(q.count, 5);
        assert!((q.at(0.1).unwrap() - 0.4).abs() < 1e-12);
        assert!((q.at(0.5).unwrap() - 2.0).abs() < 1e-12);
        assert!((q.at(0.995).unwrap() - 3.98).abs() < 1e-12);
        // Between stored levels: 0.1025 lies halfway between 0.100 and 0.105.
        assert!((q.at(0.1025).unwrap() - 0.41).abs() < 1e-12);
        assert!(q.is_consistent());
        assert_eq!(ResidualQuantiles::of(&[]).at(0.5), None);
        // Stretched for 5 residuals: 0.9 is read at 0.5 + 0.4 · 6/5 = 0.98 → 3.92, 0.1 at 0.02
        // → 0.08; the median stays.
        assert!((q.at_stretched(0.9).unwrap() - 3.92).abs() < 1e-12);
        assert!((q.at_stretched(0.1).unwrap() - 0.08).abs() < 1e-12);
        assert!((q.at_stretched(0.5).unwrap() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn an_edge_with_few_traversals_borrows_from_the_pool() {
        // Edge 0: 20 residuals all 0 (w = 1/2); edge 1: many spread ones; edge 2: none.
        let spread_out: Vec<f64> = (0..=1000).map(|i| f64::from(i) / 1000.0 - 0.5).collect();
        let spread = DurationSpread::fit(&[vec![0.0; 20], spread_out, Vec::new()]);
        let pooled = spread.pooled.at_stretched(0.95).unwrap();
        assert!((spread.quantile(0, 0.95).unwrap() - 0.5 * pooled).abs() < 1e-12);
        assert_eq!(spread.quantile(2, 0.95).unwrap(), pooled);
        // Edge 1's own: read at 0.5 + 0.45 · 1002/1001, where its residuals (evenly spread
        // from −0.5 to 0.5) have the quantile 0.45 · 1002/1001; weighted 1001/1021.
        let w = 1001.0 / 1021.0;
        let expected = w * (0.45 * 1002.0 / 1001.0) + (1.0 - w) * pooled;
        assert!((spread.quantile(1, 0.95).unwrap() - expected).abs() < 1e-12);
        let (lo, hi) = spread.interval(2, 30.0, 0.9).unwrap();
        assert!((lo - 30.0 * spread.pooled.at_stretched(0.05).unwrap().exp()).abs() < 1e-9);
        assert!((hi - 30.0 * pooled.exp()).abs() < 1e-9);
        assert!(spread.is_consistent(3) && !spread.is_consistent(2));
        assert_eq!(
            DurationSpread::fit(&[Vec::new()]).interval(0, 1.0, 0.9),
            None
        );
    }

    #[test]
    fn one_traversal_moves_every_level_by_the_step() {
        // One edge, 1,001 residuals evenly from −0.5 to 0.5: the median is 0, the quantile at
        // u is above 0 for u > 1/2. A residual of 0 lies at or below q(u) for u ≥ 1/2.
        let spread_out: Vec<f64> = (0..=1000).map(|i| f64::from(i) / 1000.0 - 0.5).collect();
        let mut spread = DurationSpread::fit(&[spread_out]);
        assert_eq!(spread.adapted.read(0.05), 0.05);
        let before = spread.interval(0, 30.0, 0.9).unwrap();
        spread.adapt(0, 0.0);
        let g = ADAPTATION_STEP;
        // v ← v + γ (u − 1[r ≤ q(v)]): 0.005 → 0.005 + 0.005γ; 0.5 → 0.5 − 0.5γ;
        // 0.995 → 0.995 − 0.005γ.
        let v = &spread.adapted.levels;
        assert!((v[0] - (0.005 + 0.005 * g)).abs() < 1e-15, "{}", v[0]);
        assert!((v[99] - (0.5 - 0.5 * g)).abs() < 1e-15, "{}", v[99]);
        assert!((v[198] - (0.995 - 0.005 * g)).abs() < 1e-15, "{}", v[198]);
        assert_eq!(spread.adapted.count, 1);
        // Read between the stored levels: 0.0525 halfway between 0.050 and 0.055.
        assert!((spread.adapted.read(0.0525) - 0.5 * (v[9] + v[10])).abs() < 1e-15);
        // The 90 % interval now reads 0.05(1 + γ) and 0.95 − 0.05γ: a little narrower.
        let (lo, hi) = spread.interval(0, 30.0, 0.9).unwrap();
        let q = |level: f64| 30.0 * spread.quantile(0, level).unwrap().exp();
        assert!((lo - q(0.05 * (1.0 + g))).abs() < 1e-9 && (hi - q(0.95 - 0.05 * g)).abs() < 1e-9);
        assert!(lo > before.0 && hi < before.1);
        // A residual beyond every quantile raises every level by γ u: the median back to 1/2.
        spread.adapt(0, 10.0);
        assert!((spread.adapted.levels[99] - 0.5).abs() < 1e-15);
        // Below the lowest stored level the quantile goes on by one spacing per halving:
        // q(0.0025) = q(0.005) − (q(0.010) − q(0.005)); residuals far below every quantile
        // push the lowest level there and on below 0 (an interval from 0 s), never below −γ.
        let (q005, q010) = (
            spread.quantile(0, 0.005).unwrap(),
            spread.quantile(0, 0.010).unwrap(),
        );
        let tail = spread.tailed_quantile(0, 0.0025).unwrap();
        assert!((tail - (2.0 * q005 - q010)).abs() < 1e-12, "{tail}");
        spread.adapt(0, -10.0);
        let lowest = spread.adapted.levels[0];
        assert!(lowest < 0.005 && lowest > 0.0, "{lowest}");
        let (lo, _) = spread.interval(0, 30.0, 0.99).unwrap();
        assert!(lo > 0.0 && lo < 30.0 * q005.exp(), "{lo}");
        for _ in 0..1000 {
            spread.adapt(0, -10.0);
        }
        let lowest = spread.adapted.levels[0];
        assert!((-g..=0.0).contains(&lowest), "{lowest}");
        assert_eq!(spread.interval(0, 30.0, 0.99).unwrap().0, 0.0);
        // Residuals far above push the highest level beyond 1; the upper end stays finite,
        // read at the cap.
        for _ in 0..2000 {
            spread.adapt(0, 10.0);
        }
        let highest = spread.adapted.levels[198];
        assert!((1.0..=1.0 + g).contains(&highest), "{highest}");
        let (_, hi) = spread.interval(0, 30.0, 0.99).unwrap();
        let capped = 30.0 * spread.tailed_quantile(0, ADAPTED_LEVEL_CAP).unwrap().exp();
        assert!(
            hi.is_finite() && (hi - capped).abs() < 1e-9,
            "{hi} {capped}"
        );
        assert_eq!(spread.tailed_quantile(0, 1.0), Some(f64::INFINITY));
        assert!(spread.is_consistent(1));
        // Nothing is learned from a non-finite residual, nor without residuals at all.
        let kept = spread.clone();
        spread.adapt(0, f64::NAN);
        assert_eq!(spread, kept);
        let mut empty = DurationSpread::fit(&[Vec::new()]);
        empty.adapt(0, 0.1);
        assert_eq!(empty.adapted, AdaptedLevels::default());
    }

    #[test]
    fn adapted_levels_out_of_range_are_inconsistent() {
        let mut spread = DurationSpread::fit(&[vec![0.1, -0.2, 0.3]]);
        assert!(spread.is_consistent(1));
        spread.adapt(0, 0.0);
        assert!(spread.is_consistent(1));
        for broken in [
            AdaptedLevels {
                count: 1,
                levels: vec![0.5; LEVELS - 1],
            },
            AdaptedLevels {
                count: 1,
                levels: vec![1.5; LEVELS],
            },
            AdaptedLevels {
                count: 1,
                levels: vec![-0.5; LEVELS],
            },
            AdaptedLevels {
                count: 1,
                levels: vec![f64::NAN; LEVELS],
            },
            AdaptedLevels {
                count: 0,
                levels: vec![0.5; LEVELS],
            },
        ] {
            let mut bad = spread.clone();
            bad.adapted = broken;
            assert!(!bad.is_consistent(1), "{:?}", bad.adapted);
        }
    }
}
