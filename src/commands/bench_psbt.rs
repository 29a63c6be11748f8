//! `chronomap bench psbt`: person search tree synthesis (seed 002 §5.4.3) for 6 and 10 places
//! on the bundled ATC day, timed against the straightforward reference (one dense generator
//! per candidate tree, dense uniformisation) and a naive per-tree sparse solve, in the same run.

use std::time::Instant;

use anyhow::{Result, anyhow};
use chronomap_core::Parallelism;
use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_psbt::{PsbtConfig, SearchContext, synthesize};
use serde_json::json;

use super::psbt::{fit_model, load_world};
use crate::cli::BenchPsbtArgs;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

pub fn psbt(args: &BenchPsbtArgs) -> Result<()> {
    let world = load_world(&args.map, &args.activity, 0.5, 0.3)?;
    let model = fit_model(&world, 1.0, 3600.0, |_| true)?
        .ok_or_else(|| anyhow!("the tracks hold no detection"))?;
    let repeats = args.repeats.max(1);
    let seed = 0;
    let mut rows = Vec::new();
    for places in [6usize, 10] {
        let mut config = PsbtConfig::default();
        config.places = places;
        let (horizon, tol) = (config.horizon_s, config.tolerance);
        // The whole synthesis, as `chronomap psbt` runs it (one thread).
        let mut whole = Vec::new();
        let mut plan = None;
        for _ in 0..repeats {
            let started = Instant::now();
            plan = Some(
                synthesize(
                    &world.grid,
                    &model,
                    args.from,
                    args.time,
                    &config,
                    seed,
                    Parallelism::Sequential,
                )
                .map_err(|e| anyhow!("--from: {e}"))?,
            );
            whole.push(started.elapsed().as_secs_f64());
        }
        let plan = plan.expect("repeats >= 1");
        let whole = median(whole);
        let candidates = SearchContext::new(&world.grid, &model, args.from, args.time, &config)?
            .psbt_candidates(seed)?;
        let count = candidates.count();
        // The comparison of all candidates alone: fast walk, per-tree sparse, dense reference.
        let mut walk = Vec::new();
        let mut best = (0, 0.0);
        for _ in 0..repeats {
            let started = Instant::now();
            best = candidates.best(horizon, tol, Parallelism::Sequential);
            walk.push(started.elapsed().as_secs_f64());
        }
        let walk = median(walk);
        let started = Instant::now();
        let mut per_tree_best = (0, f64::NEG_INFINITY);
        for i in 0..count {
            let v = candidates.per_tree_value(i, horizon, tol)?;
            if v > per_tree_best.1 {
                per_tree_best = (i, v);
            }
        }
        let per_tree = started.elapsed().as_secs_f64();
        let sample: Vec<usize> = if count <= args.reference_sample.max(1) {
            (0..count).collect()
        } else {
            let mut rng = Xoshiro256StarStar::seed_from_u64(7);
            (0..args.reference_sample)
                .map(|_| rng.int_in(0, count as u64 - 1) as usize)
                .collect()
        };
        let fast_values = candidates.values(horizon, tol);
        let started = Instant::now();
        let mut max_diff: f64 = 0.0;
        for &i in &sample {
            let v = candidates.reference_value(i, horizon, tol)?;
            max_diff = max_diff.max((v - fast_values[i]).abs());
        }
        let dense_sampled = started.elapsed().as_secs_f64();
        let dense = dense_sampled * count as f64 / sample.len() as f64;
        rows.push(json!({
            "places": places,
            "candidates": count,
            "synthesis_ms": whole * 1e3,
            "walk_ms": walk * 1e3,
            "per_tree_ms": per_tree * 1e3,
            "dense_reference_ms": dense * 1e3,
            "dense_reference_extrapolated_from": sample.len(),
            "ratio_dense_to_walk": dense / walk,
            "ratio_per_tree_to_walk": per_tree / walk,
            "ratio_dense_to_synthesis": dense / whole,
            "max_abs_difference_to_dense": max_diff,
            "same_best_as_per_tree": per_tree_best.0 == best.0,
            "best_value_difference_to_per_tree": (per_tree_best.1 - best.1).abs(),
            "p_success": plan.p_success,
        }));
    }
    if args.json {
        println!(
            "{}",
            json!({ "from": args.from, "time": args.time, "repeats": repeats, "rows": rows })
        );
    } else {
        println!(
            "person search synthesis from ({}, {}) at {} on the bundled ATC tracks, one thread, median of {repeats}",
            args.from[0],
            args.from[1],
            crate::format::time(args.time)
        );
        for r in &rows {
            println!(
                "n_pl = {:>2}: {:>6} candidates; whole synthesis {:.2} ms (walk over the candidates {:.2} ms); \
                 per-tree sparse solve {:.1} ms = {:.0} x the walk; dense reference {:.1} ms{} = {:.0} x the walk, \
                 {:.0} x the whole synthesis; max |fast - dense| {:.1e}; same best tree as per-tree: {} \
                 (best values {:.1e} apart)",
                r["places"],
                r["candidates"],
                r["synthesis_ms"].as_f64().unwrap_or(f64::NAN),
                r["walk_ms"].as_f64().unwrap_or(f64::NAN),
                r["per_tree_ms"].as_f64().unwrap_or(f64::NAN),
                r["ratio_per_tree_to_walk"].as_f64().unwrap_or(f64::NAN),
                r["dense_reference_ms"].as_f64().unwrap_or(f64::NAN),
                if r["dense_reference_extrapolated_from"].as_u64() == r["candidates"].as_u64() {
                    String::new()
                } else {
                    format!(
                        " (extrapolated from {} candidates)",
                        r["dense_reference_extrapolated_from"]
                    )
                },
                r["ratio_dense_to_walk"].as_f64().unwrap_or(f64::NAN),
                r["ratio_dense_to_synthesis"].as_f64().unwrap_or(f64::NAN),
                r["max_abs_difference_to_dense"]
                    .as_f64()
                    .unwrap_or(f64::NAN),
                r["same_best_as_per_tree"],
                r["best_value_difference_to_per_tree"]
                    .as_f64()
                    .unwrap_or(f64::NAN),
            );
        }
        println!("(the dissertation: 4.8 s for n_pl = 6 on an i7-7700T)");
    }
    Ok(())
}
