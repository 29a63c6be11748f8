//! `chronomap bench psbt`: person search tree synthesis ([Stüde 2024] §5.4.3) for 6 and 10 places
//! on the bundled ATC day, against the dense reference and a per-tree solve in the same run —
//! [`chronomap_bench::psbt`] measures, this loads the world as `chronomap psbt` does and prints.

use anyhow::{Result, anyhow};
use chronomap_bench::psbt::{PsbtBench, PsbtBenchConfig};

use super::psbt::{fit_model, load_world};
use crate::cli::BenchPsbtArgs;
use crate::outln;
use crate::output::print_bench;

pub fn psbt(args: &BenchPsbtArgs) -> Result<()> {
    let world = load_world(&args.map, &args.activity, 0.5, 0.3)?;
    let model = fit_model(&world, 1.0, 3600.0, |_| true)?
        .ok_or_else(|| anyhow!("the tracks hold no detection"))?;
    let bench = chronomap_bench::psbt::run(
        &world.grid,
        &model,
        &PsbtBenchConfig {
            from: args.from,
            time: args.time,
            repeats: args.repeats,
            reference_sample: args.reference_sample,
        },
    )?;
    print_bench(args.json, &bench, print)
}

fn print(b: &PsbtBench) -> Result<()> {
    outln!(
        "person search synthesis from ({}, {}) at {} on the bundled ATC tracks, one thread, median of {}",
        b.from[0],
        b.from[1],
        crate::format::time(b.time),
        b.repeats
    )?;
    for r in &b.rows {
        outln!(
            "n_pl = {}: {} candidates; whole synthesis {:.2} ms (walk over the candidates {:.2} ms); \
             per-tree sparse solve {:.1} ms = {:.0} x the walk; dense reference {:.1} ms{} = {:.0} x the walk, \
             {:.0} x the whole synthesis; max |fast - dense| {:.1e}; same best tree as per-tree: {} \
             (best values {:.1e} apart)",
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
        )?;
    }
    outln!("(the dissertation: 4.8 s for n_pl = 6 on an i7-7700T)")?;
    Ok(())
}
