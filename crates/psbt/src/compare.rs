//! The model-based comparison of §5.4.4 (Fig. 5.11) over many help locations: random starts
//! where the planning model saw people, every strategy of [`Method::ALL`] planned from each
//! ([`evaluate_start`]), and the statistics the dissertation reports: the mean and standard
//! deviation of `p_{s,T}(t_k)` every 20 s up to `t_max` and of `E[T | S]`, PSBT's gain over GM
//! after 140 s (+5.7 % in the dissertation), and how often PSBT is at least as good as every
//! baseline at `t_max`.

use chronomap_activity::disturbance::PlanningGrid;
use chronomap_core::par::Parallelism;
use chronomap_core::progress::Progress;
use chronomap_core::rng::{Xoshiro256StarStar, derive_seed};
use rayon::prelude::*;
use thiserror::Error;

use super::eval::{MethodOutcome, evaluate_start, sample_starts};
use super::{GridPoisson, Method, PsbtConfig, PsbtError};

/// Spacing of the scored times `t_k` (Fig. 5.11).
pub const SCORE_STEP_S: f64 = 20.0;

/// The time after which the dissertation compares PSBT with GM.
pub const GM_COMPARISON_S: f64 = 140.0;

/// The times `t_k = 20 s, 40 s, …` up to `horizon_s` (within `1e-9`).
///
/// ```
/// assert_eq!(chronomap_psbt::compare::score_times(100.0), [20.0, 40.0, 60.0, 80.0, 100.0]);
/// ```
pub fn score_times(horizon_s: f64) -> Vec<f64> {
    (1..)
        .map(|k| SCORE_STEP_S * f64::from(k))
        .take_while(|&t| t <= horizon_s + 1e-9)
        .collect()
}

/// Why a comparison could not be run.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum CompareError {
    /// The planning model saw nobody on a free planning cell.
    #[error("no free planning cell where the tracks saw anybody")]
    NoStart,
    /// Planning or analysing from one start failed.
    #[error("start {index} ({}, {}): {source}", .at[0], .at[1])]
    Start {
        /// Index of the start.
        index: usize,
        /// The start.
        at: [f64; 2],
        /// What failed.
        #[source]
        source: PsbtError,
    },
}

/// Every strategy's outcome from every start.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// The help locations.
    pub starts: Vec<[f64; 2]>,
    /// The scored times `t_k` ([`score_times`] of the horizon).
    pub times: Vec<f64>,
    /// Per start, one outcome per method of [`Method::ALL`], in that order.
    pub outcomes: Vec<Vec<MethodOutcome>>,
}

/// Mean and sample standard deviation over the starts of one method.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodSummary {
    /// The method.
    pub method: Method,
    /// Mean `p_{s,T}(t_k)`, per scored time.
    pub p_mean: Vec<f64>,
    /// Standard deviation of `p_{s,T}(t_k)`.
    pub p_std: Vec<f64>,
    /// Mean `E[T | S]` in seconds over the starts where it exists (NaN for none).
    pub time_mean_s: f64,
    /// Its standard deviation.
    pub time_std_s: f64,
}

/// Mean and sample standard deviation (0 for one value, NaN for none).
pub fn mean_std(values: &[f64]) -> (f64, f64) {
    if values.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = if values.len() > 1 {
        values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    (mean, var.sqrt())
}

/// Draws `starts` help locations uniformly (with replacement) from the free planning cells
/// where `plan` saw somebody, and plans and analyses every method of [`Method::ALL`] from each
/// at `time` on `plan`, scoring the plans on `score` too if given ([`evaluate_start`]). The
/// starts come from `seed` (stream 11), each start's plans from stream 12 of its index, so
/// the result does not depend on `parallelism`. Reports the stage `help locations` with one
/// step per start to `progress`.
///
/// # Errors
/// [`CompareError::NoStart`] when there is no start, [`CompareError::Start`] naming a start
/// whose planning failed.
#[allow(clippy::too_many_arguments)]
pub fn compare(
    grid: &PlanningGrid,
    plan: &GridPoisson,
    score: Option<&GridPoisson>,
    time: f64,
    config: &PsbtConfig,
    starts: usize,
    seed: u64,
    parallelism: Parallelism,
    progress: &dyn Progress,
) -> Result<Comparison, CompareError> {
    let mut rng = Xoshiro256StarStar::seed_from_u64(derive_seed(seed, 11, 0, 0));
    let starts = sample_starts(grid, starts, |c| plan.has_detections(c), &mut rng);
    if starts.is_empty() {
        return Err(CompareError::NoStart);
    }
    let times = score_times(config.horizon_s);
    progress.stage("help locations", starts.len() as u64);
    let one = |(index, &at): (usize, &[f64; 2])| {
        let outcome = evaluate_start(
            grid,
            plan,
            score,
            at,
            time,
            config,
            derive_seed(seed, 12, index as u64, 0),
            &times,
        )
        .map_err(|source| CompareError::Start { index, at, source });
        progress.advance(1);
        outcome
    };
    let outcomes: Result<Vec<Vec<MethodOutcome>>, CompareError> = if parallelism.tasks() > 1 {
        starts.par_iter().enumerate().map(one).collect()
    } else {
        starts.iter().enumerate().map(one).collect()
    };
    let outcomes = outcomes?;
    Ok(Comparison {
        starts,
        times,
        outcomes,
    })
}

impl Comparison {
    /// `p_{s,T}(t_k)` of `outcome` under the planning model, or under the scoring model
    /// (`scored`; NaN if it has none).
    fn p_at(outcome: &MethodOutcome, k: usize, scored: bool) -> f64 {
        if scored {
            outcome.scored.as_ref().map_or(f64::NAN, |s| s[k])
        } else {
            outcome.p_success[k]
        }
    }

    /// Whether the plans were scored on a second model.
    pub fn is_scored(&self) -> bool {
        self.outcomes
            .iter()
            .all(|r| r.iter().all(|o| o.scored.is_some()))
    }

    /// Every method's summary under the planning model, or under the scoring model
    /// (`scored`; `None` without one), in the order of [`Method::ALL`].
    pub fn summaries(&self, scored: bool) -> Option<Vec<MethodSummary>> {
        (0..Method::ALL.len())
            .map(|m| self.summary(m, scored))
            .collect()
    }

    /// The summary of method `m` (an index of [`Method::ALL`]).
    fn summary(&self, m: usize, scored: bool) -> Option<MethodSummary> {
        let series = |k: usize| -> Option<Vec<f64>> {
            self.outcomes
                .iter()
                .map(|r| {
                    if scored {
                        r[m].scored.as_ref().map(|s| s[k])
                    } else {
                        Some(r[m].p_success[k])
                    }
                })
                .collect()
        };
        let mut p_mean = Vec::with_capacity(self.times.len());
        let mut p_std = Vec::with_capacity(self.times.len());
        for k in 0..self.times.len() {
            let (mean, std) = mean_std(&series(k)?);
            p_mean.push(mean);
            p_std.push(std);
        }
        let expected: Vec<f64> = self
            .outcomes
            .iter()
            .filter_map(|r| {
                if scored {
                    r[m].scored_expected_time_s
                } else {
                    r[m].expected_time_s
                }
            })
            .collect();
        let (time_mean_s, time_std_s) = mean_std(&expected);
        Some(MethodSummary {
            method: Method::ALL[m],
            p_mean,
            p_std,
            time_mean_s,
            time_std_s,
        })
    }

    /// PSBT's mean `p_{s,T}` after [`GM_COMPARISON_S`] relative to GM's, in percent, from
    /// `summaries` (of [`Comparison::summaries`]); `None` if 140 s is not a scored time.
    pub fn gain_over_gm_percent(&self, summaries: &[MethodSummary]) -> Option<f64> {
        let k = self
            .times
            .iter()
            .position(|&t| (t - GM_COMPARISON_S).abs() < 1e-9)?;
        Some((summaries[0].p_mean[k] - summaries[1].p_mean[k]) / summaries[1].p_mean[k] * 100.0)
    }

    /// The share of starts where PSBT's `p_{s,T}(t_max)` is at least every baseline's (within
    /// `1e-9`), under the planning or the scoring model.
    pub fn psbt_at_least_all_fraction(&self, scored: bool) -> f64 {
        let last = self.times.len() - 1;
        let ok = self
            .outcomes
            .iter()
            .filter(|r| {
                r[1..]
                    .iter()
                    .all(|o| Self::p_at(&r[0], last, scored) >= Self::p_at(o, last, scored) - 1e-9)
            })
            .count();
        ok as f64 / self.outcomes.len() as f64
    }

    /// Per baseline (every method but PSBT, in order), the share of starts where it beats
    /// PSBT at `t_max` by more than `1e-9`.
    pub fn beats_psbt_fraction(&self, scored: bool) -> Vec<(Method, f64)> {
        let last = self.times.len() - 1;
        (1..Method::ALL.len())
            .map(|m| {
                let n = self
                    .outcomes
                    .iter()
                    .filter(|r| {
                        Self::p_at(&r[m], last, scored) > Self::p_at(&r[0], last, scored) + 1e-9
                    })
                    .count();
                (Method::ALL[m], n as f64 / self.outcomes.len() as f64)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(method: Method, p: [f64; 2], scored: Option<[f64; 2]>, e: f64) -> MethodOutcome {
        MethodOutcome {
            method,
            p_success: p.to_vec(),
            expected_time_s: Some(e),
            scored: scored.map(|s| s.to_vec()),
            scored_expected_time_s: scored.map(|_| e + 1.0),
        }
    }

    /// Two starts, the six methods; PSBT best from the first start, RND from the second.
    fn comparison(scored: bool) -> Comparison {
        let start = |psbt: f64, rnd: f64| -> Vec<MethodOutcome> {
            Method::ALL
                .iter()
                .map(|&m| {
                    let p = match m {
                        Method::Psbt => psbt,
                        Method::Rnd => rnd,
                        Method::Gm => 0.4,
                        _ => 0.1,
                    };
                    outcome(
                        m,
                        [p / 2.0, p],
                        scored.then_some([p / 4.0, p / 2.0]),
                        100.0 * p,
                    )
                })
                .collect()
        };
        Comparison {
            starts: vec![[0.0, 0.0], [1.0, 0.0]],
            times: vec![20.0, 140.0],
            outcomes: vec![start(0.8, 0.5), start(0.6, 0.7)],
        }
    }

    #[test]
    fn summaries_are_means_and_sample_deviations_over_the_starts() {
        let c = comparison(false);
        let s = c.summaries(false).unwrap();
        assert_eq!(s[0].method, Method::Psbt);
        assert!((s[0].p_mean[1] - 0.7).abs() < 1e-12);
        assert!((s[0].p_std[1] - 0.02f64.sqrt()).abs() < 1e-12);
        assert!((s[0].time_mean_s - 70.0).abs() < 1e-9);
        // GM 0.4 everywhere: no spread.
        assert_eq!((s[1].p_mean[1], s[1].p_std[1]), (0.4, 0.0));
        // PSBT 0.7 against GM 0.4 after 140 s: +75 %.
        assert!((c.gain_over_gm_percent(&s).unwrap() - 75.0).abs() < 1e-9);
        assert!(c.summaries(true).is_none());
        assert!(!c.is_scored());
    }

    #[test]
    fn psbt_is_compared_with_each_baseline_at_t_max() {
        let c = comparison(true);
        assert!(c.is_scored());
        assert_eq!(c.psbt_at_least_all_fraction(false), 0.5);
        let beats = c.beats_psbt_fraction(false);
        assert_eq!(beats.len(), 5);
        assert_eq!(beats[0], (Method::Gm, 0.0));
        assert_eq!(beats[2], (Method::Rnd, 0.5));
        // Scored: the same ranking at half the probabilities.
        assert_eq!(c.psbt_at_least_all_fraction(true), 0.5);
        let scored = c.summaries(true).unwrap();
        assert!((scored[0].p_mean[1] - 0.35).abs() < 1e-12);
        assert!((scored[0].time_mean_s - 71.0).abs() < 1e-9);
    }

    #[test]
    fn sample_statistics() {
        assert_eq!(mean_std(&[2.0]), (2.0, 0.0));
        let (m, s) = mean_std(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(m, 2.5);
        assert!((s - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert!(mean_std(&[]).0.is_nan());
        assert_eq!(score_times(200.0).len(), 10);
        assert_eq!(score_times(19.0), Vec::<f64>::new());
    }
}
