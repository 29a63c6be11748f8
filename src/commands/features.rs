//! `chronomap features`: which features will be visible ([Krajník 2017] §VII Table I,
//! [Krajník 2019] §V-B); [`chronomap_app::features`] runs the experiment and reports.

use anyhow::Result;
use chronomap_app::features::feature_report;
use chronomap_models::features::SlotLayout;

use crate::cli::{FeaturesArgs, model_specs};
use crate::out;
use crate::output::{ProgressBar, print_json};

pub fn run(args: &FeaturesArgs) -> Result<()> {
    let layout = SlotLayout {
        slot_secs: args.slot_secs,
        lines_per_slot: args.lines_per_slot as usize,
        train_days: args.train_days,
    };
    let report = feature_report(
        &args.matrix,
        layout,
        &model_specs(&args.models),
        &args.n,
        &ProgressBar::new(),
    )?;
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    Ok(out!("{}", report.text())?)
}
