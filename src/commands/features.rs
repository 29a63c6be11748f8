//! `chronomap features`: which features will be visible ([Krajník 2017] §VII Table I, [Krajník 2019] §V-B).

use anyhow::{Context, Result};
use chronomap_core::Parallelism;
use chronomap_io::read_state_matrix;
use chronomap_models::features::{SlotLayout, feature_visibility};
use chronomap_models::spec::FitOptions;
use serde_json::json;

use crate::cli::{FeaturesArgs, model_specs};
use crate::format::Table;
use crate::outln;
use crate::output::{ProgressBar, print_json};

pub fn run(args: &FeaturesArgs) -> Result<()> {
    let name = args.matrix.display().to_string();
    let rows = read_state_matrix(&args.matrix)?;
    let layout = SlotLayout {
        slot_secs: args.slot_secs,
        lines_per_slot: args.lines_per_slot as usize,
        train_days: args.train_days,
    };
    let report = {
        let bar = ProgressBar::new();
        feature_visibility(
            &rows,
            layout,
            &model_specs(&args.models),
            &args.n,
            &FitOptions::default(),
            Parallelism::Rayon(0),
            &bar,
        )
        .with_context(|| format!("{name}: cannot run the experiment"))?
    };
    if args.json {
        return print_json(&json!({
            "matrix": name,
            "features": report.features,
            "train_slots": report.train_slots,
            "test_slots": report.test_slots,
            "n": args.n,
            "models": report.models,
        }));
    }
    outln!(
        "{name}: {} features, {} training slots, {} test slots of {} s",
        report.features,
        report.train_slots,
        report.test_slots,
        args.slot_secs
    )?;
    let mut header = vec!["model".to_string()];
    header.extend(args.n.iter().map(|n| format!("n = {n}")));
    header.push("Brier".to_string());
    let mut table = Table::new(header);
    for m in &report.models {
        let mut row = vec![m.model.clone()];
        row.extend(
            m.reobservation
                .iter()
                .map(|r| format!("{:.1} %", 100.0 * r)),
        );
        row.push(format!("{:.4}", m.brier));
        table.row(row);
    }
    outln!("{}", table.render())?;
    outln!(
        "n = k: of the k features each model predicts most likely visible at a test slot, the share \
         that were visible (higher is better); Brier: mean squared error of the visibility over all \
         features and test slots."
    )?;
    Ok(())
}
