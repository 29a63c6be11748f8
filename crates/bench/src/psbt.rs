//! Person search tree synthesis ([Stüde 2024] §5.4.3) for 6 and 10 places, timed against the
//! straightforward reference (one dense generator per candidate tree, dense uniformisation:
//! `Candidates::reference_value`) and a naive per-tree sparse solve
//! (`Candidates::per_tree_value`), in the same run.

use std::time::Instant;

use chronomap_activity::disturbance::PlanningGrid;
use chronomap_core::Parallelism;
use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_psbt::{PsbtConfig, PsbtError, RateField, SearchContext, synthesize};
use serde::Serialize;
use thiserror::Error;

/// The numbers of places `n_pl` the benchmark synthesises for.
pub const PLACES: [usize; 2] = [6, 10];

/// The seed of the synthesis (place sampling, genetic TSP).
const SEED: u64 = 0;

/// The seed of the sample of candidates the dense reference solves.
const SAMPLE_SEED: u64 = 7;

/// Where and when help is requested, and how often each part is timed.
#[derive(Clone, Debug, PartialEq)]
pub struct PsbtBenchConfig {
    /// Help location `x, y` (metres).
    pub from: [f64; 2],
    /// Time of the request (unix seconds).
    pub time: f64,
    /// Timed repetitions of the synthesis and of the walk (the median is reported; at least 1).
    pub repeats: usize,
    /// At most this many candidates are solved by the dense reference (a seeded sample; the
    /// time of the rest is extrapolated).
    pub reference_sample: usize,
}

/// Why the benchmark could not run.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum PsbtBenchError {
    /// No person search tree could be synthesised from the help location.
    #[error("person search from ({}, {}) at {time}", .from[0], .from[1])]
    Synthesis {
        /// The help location.
        from: [f64; 2],
        /// The time of the request.
        time: f64,
        /// What went wrong.
        source: PsbtError,
    },
    /// A candidate tree could not be built or solved.
    #[error("candidate trees for {places} places")]
    Candidates {
        /// `n_pl`.
        places: usize,
        /// What went wrong.
        source: PsbtError,
    },
}

/// The measurements of one number of places.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PsbtRow {
    /// `n_pl`.
    pub places: usize,
    /// Candidate trees: `3^n_pl + 1`.
    pub candidates: usize,
    /// The whole synthesis as `chronomap psbt` runs it (one thread), median, ms.
    pub synthesis_ms: f64,
    /// The comparison of all candidates alone by the fast walk, median, ms.
    pub walk_ms: f64,
    /// One sparse solve per candidate tree, ms.
    pub per_tree_ms: f64,
    /// One dense generator per candidate tree, ms (extrapolated from a sample).
    pub dense_reference_ms: f64,
    /// Candidates the dense reference solved.
    pub dense_reference_extrapolated_from: usize,
    /// `dense_reference_ms / walk_ms`.
    pub ratio_dense_to_walk: f64,
    /// `per_tree_ms / walk_ms`.
    pub ratio_per_tree_to_walk: f64,
    /// `dense_reference_ms / synthesis_ms`.
    pub ratio_dense_to_synthesis: f64,
    /// Largest `|fast − dense|` over the sampled candidates.
    pub max_abs_difference_to_dense: f64,
    /// Whether the per-tree solve picks the same best candidate as the walk.
    pub same_best_as_per_tree: bool,
    /// `|best value of the per-tree solve − best value of the walk|`.
    pub best_value_difference_to_per_tree: f64,
    /// `p_{s,T}(t_max)` of the synthesised tree.
    pub p_success: f64,
}

/// The benchmark's measurements.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PsbtBench {
    /// The help location.
    pub from: [f64; 2],
    /// The time of the request.
    pub time: f64,
    /// Timed repetitions.
    pub repeats: usize,
    /// One row per entry of [`PLACES`].
    pub rows: Vec<PsbtRow>,
}

/// The middle value of `v` (the upper middle one for an even count).
fn upper_median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Runs the benchmark on the planning grid `grid` and the activity model `model`.
///
/// # Errors
/// The synthesis fails (the help location is off the map or blocked, a place cannot be
/// reached), or a candidate cannot be solved.
pub fn run<F: RateField + ?Sized>(
    grid: &PlanningGrid,
    model: &F,
    config: &PsbtBenchConfig,
) -> Result<PsbtBench, PsbtBenchError> {
    let repeats = config.repeats.max(1);
    let (from, time) = (config.from, config.time);
    let mut rows = Vec::new();
    for places in PLACES {
        let candidates_error = |source| PsbtBenchError::Candidates { places, source };
        let mut psbt = PsbtConfig::default();
        psbt.places = places;
        let (horizon, tol) = (psbt.horizon_s, psbt.tolerance);
        // The whole synthesis, as `chronomap psbt` runs it (one thread).
        let mut whole = Vec::new();
        let mut plan = None;
        for _ in 0..repeats {
            let started = Instant::now();
            plan = Some(
                synthesize(
                    grid,
                    model,
                    from,
                    time,
                    &psbt,
                    SEED,
                    Parallelism::Sequential,
                )
                .map_err(|source| PsbtBenchError::Synthesis {
                    from,
                    time,
                    source,
                })?,
            );
            whole.push(started.elapsed().as_secs_f64());
        }
        let plan = plan.expect("repeats >= 1");
        let whole = upper_median(whole);
        let candidates = SearchContext::new(grid, model, from, time, &psbt)
            .and_then(|mut context| context.psbt_candidates(SEED))
            .map_err(candidates_error)?;
        let count = candidates.count();
        // The comparison of all candidates alone: fast walk, per-tree sparse, dense reference.
        let mut walk = Vec::new();
        let mut best = (0, 0.0);
        for _ in 0..repeats {
            let started = Instant::now();
            best = candidates.best(horizon, tol, Parallelism::Sequential);
            walk.push(started.elapsed().as_secs_f64());
        }
        let walk = upper_median(walk);
        let started = Instant::now();
        let mut per_tree_best = (0, f64::NEG_INFINITY);
        for i in 0..count {
            let v = candidates
                .per_tree_value(i, horizon, tol)
                .map_err(|e| candidates_error(e.into()))?;
            if v > per_tree_best.1 {
                per_tree_best = (i, v);
            }
        }
        let per_tree = started.elapsed().as_secs_f64();
        let sample: Vec<usize> = if count <= config.reference_sample.max(1) {
            (0..count).collect()
        } else {
            let mut rng = Xoshiro256StarStar::seed_from_u64(SAMPLE_SEED);
            (0..config.reference_sample)
                .map(|_| rng.int_in(0, count as u64 - 1) as usize)
                .collect()
        };
        let fast_values = candidates.values(horizon, tol);
        let started = Instant::now();
        let mut max_diff: f64 = 0.0;
        for &i in &sample {
            let v = candidates
                .reference_value(i, horizon, tol)
                .map_err(|e| candidates_error(e.into()))?;
            max_diff = max_diff.max((v - fast_values[i]).abs());
        }
        let dense_sampled = started.elapsed().as_secs_f64();
        let dense = dense_sampled * count as f64 / sample.len() as f64;
        rows.push(PsbtRow {
            places,
            candidates: count,
            synthesis_ms: whole * 1e3,
            walk_ms: walk * 1e3,
            per_tree_ms: per_tree * 1e3,
            dense_reference_ms: dense * 1e3,
            dense_reference_extrapolated_from: sample.len(),
            ratio_dense_to_walk: dense / walk,
            ratio_per_tree_to_walk: per_tree / walk,
            ratio_dense_to_synthesis: dense / whole,
            max_abs_difference_to_dense: max_diff,
            same_best_as_per_tree: per_tree_best.0 == best.0,
            best_value_difference_to_per_tree: (per_tree_best.1 - best.1).abs(),
            p_success: plan.p_success,
        });
    }
    Ok(PsbtBench {
        from,
        time,
        repeats,
        rows,
    })
}

impl PsbtBench {
    /// The measurements as `chronomap bench psbt` prints them.
    pub fn text(&self) -> String {
        let mut out = format!(
            "person search synthesis from ({}, {}) at {} on the bundled ATC tracks, one thread, median of {}\n",
            self.from[0],
            self.from[1],
            chronomap_core::time::format_time(self.time),
            self.repeats
        );
        for r in &self.rows {
            out.push_str(&format!(
                "n_pl = {}: {} candidates; whole synthesis {:.2} ms (walk over the candidates {:.2} ms); \
                 per-tree sparse solve {:.1} ms = {:.0} x the walk; dense reference {:.1} ms{} = {:.0} x the walk, \
                 {:.0} x the whole synthesis; max |fast - dense| {:.1e}; same best tree as per-tree: {} \
                 (best values {:.1e} apart)\n",
                r.places,
                r.candidates,
                r.synthesis_ms,
                r.walk_ms,
                r.per_tree_ms,
                r.ratio_per_tree_to_walk,
                r.dense_reference_ms,
                if r.dense_reference_extrapolated_from == r.candidates {
                    String::new()
                } else {
                    format!(
                        " (extrapolated from {} candidates)",
                        r.dense_reference_extrapolated_from
                    )
                },
                r.ratio_dense_to_walk,
                r.ratio_dense_to_synthesis,
                r.max_abs_difference_to_dense,
                r.same_best_as_per_tree,
                r.best_value_difference_to_per_tree,
            ));
        }
        out.push_str("(the dissertation: 4.8 s for n_pl = 6 on an i7-7700T)\n");
        out
    }
}

#[cfg(test)]
mod tests {
    use super::upper_median;

    #[test]
    fn upper_median_takes_the_upper_of_the_middle_two() {
        assert_eq!(upper_median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(upper_median(vec![4.0, 1.0, 3.0, 2.0]), 3.0);
    }
}
