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

use serde::{Deserialize, Serialize};

/// Durations below this (s) count as this much in residuals (a duration of 0 has no logarithm).
pub const DURATION_FLOOR_SECS: f64 = 0.01;

/// Weight `k` of the pooled residuals in an edge's quantiles, in traversals (see the
/// [module docs](self)); fixed a priori, not tuned to any split.
pub const DURATION_PSEUDO_TRAVERSALS: f64 = 20.0;

/// Levels of the stored quantiles: `i / 200` for `i = 1..=199`.
const LEVELS: usize = 199;

/// Widest coverage an interval can have: 99 % (the stored quantiles end at 0.005 and 0.995).
pub const MAX_COVERAGE: f64 = 0.99;

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
        if self.quantiles.len() != LEVELS {
            return None;
        }
        let position = (level * (LEVELS + 1) as f64 - 1.0).clamp(0.0, (LEVELS - 1) as f64);
        let low = position.floor() as usize;
        let high = (low + 1).min(LEVELS - 1);
        let fraction = position - low as f64;
        Some(self.quantiles[low] + fraction * (self.quantiles[high] - self.quantiles[low]))
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

/// The spread of every edge's durations around its model, and of all edges together.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DurationSpread {
    /// Per edge, in the map's order.
    pub edges: Vec<ResidualQuantiles>,
    /// All edges' residuals together.
    pub pooled: ResidualQuantiles,
}

impl DurationSpread {
    /// The spread of `residuals[e]`, the residuals of edge `e`'s successful traversals.
    pub fn fit(residuals: &[Vec<f64>]) -> Self {
        let all: Vec<f64> = residuals.iter().flatten().copied().collect();
        DurationSpread {
            edges: residuals.iter().map(|r| ResidualQuantiles::of(r)).collect(),
            pooled: ResidualQuantiles::of(&all),
        }
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

    /// The interval of `coverage` (in `(0, 0.99]`) around the expected duration `expected_secs`
    /// of `edge`: `(lower, upper)` in seconds; `None` when no edge had a residual.
    pub fn interval(&self, edge: usize, expected_secs: f64, coverage: f64) -> Option<(f64, f64)> {
        let alpha = 1.0 - coverage.clamp(0.0, MAX_COVERAGE);
        let base = expected_secs.max(DURATION_FLOOR_SECS);
        let lower = base * self.quantile(edge, alpha / 2.0)?.exp();
        let upper = base * self.quantile(edge, 1.0 - alpha / 2.0)?.exp();
        Some((lower, upper))
    }

    /// The durations (seconds) of `edge` at the stored levels `i / 200`, `i = 1..=199`, around
    /// the expected duration `expected_secs`: its quantile function where it is known,
    /// increasing; `None` when no edge had a residual.
    pub fn durations(&self, edge: usize, expected_secs: f64) -> Option<Vec<f64>> {
        let base = expected_secs.max(DURATION_FLOOR_SECS);
        (1..=LEVELS)
            .map(|i| {
                let level = i as f64 / (LEVELS + 1) as f64;
                Some(base * self.quantile(edge, level)?.exp())
            })
            .collect()
    }

    /// Whether the stored values can be used (for models read from files), with `edges` edges.
    pub fn is_consistent(&self, edges: usize) -> bool {
        self.edges.len() == edges
            && self.pooled.is_consistent()
            && self.edges.iter().all(ResidualQuantiles::is_consistent)
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
}
