//! `chronomap features`: which features will be visible (seed 001 §VII Table I, seed 004 §V-B).

use std::io::Write;

use anyhow::{Context, Result, anyhow, bail};
use chronomap_core::TemporalModel;
use chronomap_core::metrics::mse;
use chronomap_core::visibility::reobservation_rate;
use chronomap_io::read_state_matrix;
use chronomap_models::spec::FitOptions;
use rayon::prelude::*;
use serde_json::json;

use crate::cli::FeaturesArgs;
use crate::format::Table;

pub fn run(args: &FeaturesArgs) -> Result<()> {
    let name = args.matrix.display().to_string();
    if args.lines_per_slot == 0 {
        bail!("--lines-per-slot must be at least 1");
    }
    let rows = read_state_matrix(&args.matrix)?;
    if !rows.len().is_multiple_of(args.lines_per_slot) {
        bail!(
            "{name}: {} lines are not whole slots of {} lines",
            rows.len(),
            args.lines_per_slot
        );
    }
    let slots: Vec<&Vec<f64>> = rows.iter().step_by(args.lines_per_slot).collect();
    let features = slots[0].len();
    let times: Vec<f64> = (0..slots.len())
        .map(|k| k as f64 * args.slot_secs)
        .collect();
    let split = times.partition_point(|&t| t < args.train_days * 86_400.0);
    if split == 0 || split == times.len() {
        bail!(
            "{name}: {} slots of {} s; --train-days {} leaves no {} slot",
            slots.len(),
            args.slot_secs,
            args.train_days,
            if split == 0 { "training" } else { "test" }
        );
    }
    // features × slots
    let series: Vec<Vec<f64>> = (0..features)
        .map(|f| slots.iter().map(|row| row[f]).collect())
        .collect();
    let truth: Vec<Vec<f64>> = series.iter().map(|s| s[split..].to_vec()).collect();
    let options = FitOptions::default();
    let mut results = Vec::new();
    for spec in &args.models.0 {
        let predictions: Vec<Vec<f64>> = series
            .par_iter()
            .enumerate()
            .map(|(f, s)| {
                let fitted = spec
                    .fit(&times[..split], &s[..split], &options)
                    .map_err(|e| anyhow!("model {spec}, feature {}: {e}", f + 1))?;
                Ok(fitted.model.predict_many(&times[split..]))
            })
            .collect::<Result<_>>()
            .with_context(|| format!("cannot fit to {name}"))?;
        let rates: Vec<f64> = args
            .n
            .iter()
            .map(|&n| reobservation_rate(&predictions, &truth, n))
            .collect();
        let brier = predictions
            .iter()
            .zip(&truth)
            .map(|(p, t)| mse(p, t))
            .sum::<f64>()
            / features as f64;
        results.push((spec.to_string(), rates, brier));
    }
    let mut out = std::io::stdout().lock();
    if args.json {
        writeln!(
            out,
            "{}",
            json!({
                "matrix": name,
                "features": features,
                "train_slots": split,
                "test_slots": times.len() - split,
                "n": args.n,
                "models": results.iter().map(|(m, r, b)| json!({
                    "model": m, "reobservation": r, "brier": b,
                })).collect::<Vec<_>>(),
            })
        )?;
        return Ok(());
    }
    writeln!(
        out,
        "{name}: {features} features, {} training slots, {} test slots of {} s",
        split,
        times.len() - split,
        args.slot_secs
    )?;
    let mut header = vec!["model".to_string()];
    header.extend(args.n.iter().map(|n| format!("n = {n}")));
    header.push("Brier".to_string());
    let mut table = Table::new(header);
    for (m, rates, brier) in &results {
        let mut row = vec![m.clone()];
        row.extend(rates.iter().map(|r| format!("{:.1} %", 100.0 * r)));
        row.push(format!("{brier:.4}"));
        table.row(row);
    }
    writeln!(out, "{}", table.render())?;
    writeln!(
        out,
        "n = k: of the k features each model predicts most likely visible at a test slot, the share \
         that were visible (higher is better); Brier: mean squared error of the visibility over all \
         features and test slots."
    )?;
    Ok(())
}
