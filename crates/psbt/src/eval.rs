//! The model-based evaluation of §5.4.4 (Fig. 5.11): random help locations, every strategy
//! planned on one activity model, `p_{s,T}(t_k)` and `E[T | S]` of each plan, under the
//! planning model and, optionally, under a second model (e.g. one learned from the hour being
//! planned for, which the planning model has not seen).

use super::{Method, PsbtConfig, PsbtError, RateField, SearchContext};
use chronomap_core::Parallelism;
use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_spatial::PlanningGrid;

/// What one strategy's plan achieves from one help location.
#[derive(Clone, Debug, PartialEq)]
pub struct MethodOutcome {
    /// The strategy.
    pub method: Method,
    /// `p_{s,T}(t_k)` under the planning model.
    pub p_success: Vec<f64>,
    /// `E[T | S]` under the planning model.
    pub expected_time_s: Option<f64>,
    /// `p_{s,T}(t_k)` under the scoring model, if one was given.
    pub scored: Option<Vec<f64>>,
    /// `E[T | S]` under the scoring model.
    pub scored_expected_time_s: Option<f64>,
}

/// Plans every method of [`Method::ALL`] from `from` at time `t` on `plan` (seeded) and
/// analyses each plan at `times` (seconds after the request) on `plan` and on `score`.
///
/// # Errors
/// As [`SearchContext::new`] and [`SearchContext::plan`].
#[allow(clippy::too_many_arguments)]
pub fn evaluate_start<P: RateField + ?Sized, S: RateField + ?Sized>(
    grid: &PlanningGrid,
    plan: &P,
    score: Option<&S>,
    from: [f64; 2],
    t: f64,
    config: &PsbtConfig,
    seed: u64,
    times: &[f64],
) -> Result<Vec<MethodOutcome>, PsbtError> {
    let mut context = SearchContext::new(grid, plan, from, t, config)?;
    let mut out = Vec::with_capacity(Method::ALL.len());
    for method in Method::ALL {
        let planned = context.plan(method, seed, Parallelism::Sequential)?;
        let on_plan = planned.tree.analyse(grid, plan, t, config, times)?;
        let on_score = match score {
            Some(field) => Some(planned.tree.analyse(grid, field, t, config, times)?),
            None => None,
        };
        out.push(MethodOutcome {
            method,
            p_success: on_plan.p_success,
            expected_time_s: on_plan.means.time_to_success,
            scored_expected_time_s: on_score.as_ref().and_then(|a| a.means.time_to_success),
            scored: on_score.map(|a| a.p_success),
        });
    }
    Ok(out)
}

/// `count` planning cells drawn uniformly with replacement from the free cells that `keep`
/// accepts (by centre); empty if there is none.
pub fn sample_starts(
    grid: &PlanningGrid,
    count: usize,
    mut keep: impl FnMut([f64; 2]) -> bool,
    rng: &mut Xoshiro256StarStar,
) -> Vec<[f64; 2]> {
    let cells: Vec<usize> = (0..grid.len())
        .filter(|&c| grid.is_free(c) && keep(grid.centre(c)))
        .collect();
    if cells.is_empty() {
        return Vec::new();
    }
    (0..count)
        .map(|_| grid.centre(cells[rng.int_in(0, cells.len() as u64 - 1) as usize]))
        .collect()
}
