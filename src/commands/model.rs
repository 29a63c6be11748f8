//! `chronomap fit`, `predict`, `inspect` and `anomalies`: working with saved models
//! (`chronomap_app::model` fits and reports, this prints).

use std::fmt::Write as _;

use anyhow::Result;
use chronomap_app::model::{Inspection, Training, anomalies as find_anomalies, fit as fit_model};
use chronomap_core::calendar::DaysOff;
use chronomap_core::{TemporalModel, binary_entropy};
use chronomap_io::{Field, read_column, read_pairs};
use serde_json::json;

use super::{load_model, read_series};
use crate::cli::{AnomaliesArgs, FitArgs, InspectArgs, PredictArgs};
use crate::output::{print_json, usage};
use crate::{out, outln};

pub fn fit(args: &FitArgs) -> Result<()> {
    let series = read_pairs(&args.train)?;
    let name = args.train.display().to_string();
    let training = Training {
        json: json!({ "file": name, "observations": series.len() }),
        name,
        series,
    };
    let days_off = match &args.days_off {
        Some(path) => chronomap_io::read_days_off(path)?,
        None => DaysOff::default(),
    };
    let report = fit_model(
        &training,
        &args.model,
        &args.fit.options(),
        &days_off,
        &args.output,
    )?;
    if args.json {
        return print_json(&report.json());
    }
    Ok(outln!("{}", report.text())?)
}

/// Lines of `predict` written to stdout at once (one write per chunk, not per line).
const PREDICT_CHUNK: usize = 4096;

pub fn predict(args: &PredictArgs) -> Result<()> {
    let mut model = load_model(&args.model)?;
    if let Some(order) = args.order
        && !model.set_order(order)
    {
        return Err(usage(format!(
            "--order: a {} model has no order to change",
            model.kind()
        )));
    }
    let times = match &args.times {
        Some(path) => read_column(path, Field::Time)?,
        None => args.at.clone(),
    };
    let predictions = match &args.days_off {
        Some(path) => chronomap_io::read_days_off(path)?.predict_many(&model, &times),
        None => model.predict_many(&times),
    };
    if args.json {
        let rows: Vec<_> = times
            .iter()
            .zip(&predictions)
            .map(|(&t, &p)| json!({"time": t, "p": p, "entropy_bits": binary_entropy(p)}))
            .collect();
        return print_json(&json!({
            "model": args.model.display().to_string(),
            "spec": model.spec().to_string(),
            "order": model.order(),
            "predictions": rows,
        }));
    }
    outln!("# time\tp\tentropy_bits")?;
    let mut chunk = String::new();
    for (i, (t, p)) in times.iter().zip(predictions).enumerate() {
        writeln!(chunk, "{t}\t{p:.6}\t{:.6}", binary_entropy(p))?;
        if (i + 1) % PREDICT_CHUNK == 0 {
            out!("{chunk}")?;
            chunk.clear();
        }
    }
    out!("{chunk}")?;
    Ok(())
}

pub fn inspect(args: &InspectArgs) -> Result<()> {
    let inspection = Inspection {
        file: args.model.display().to_string(),
        model: load_model(&args.model)?,
        spectrum: args.spectrum,
    };
    if args.json {
        return print_json(&inspection.json());
    }
    Ok(outln!("{}", inspection.text())?)
}

pub fn anomalies(args: &AnomaliesArgs) -> Result<()> {
    let model = load_model(&args.model)?;
    let series = read_series(&args.test)?;
    let name = args.model.display().to_string();
    let report = find_anomalies(&name, &model, &series, args.confidence)?;
    if args.json {
        return print_json(&report.json());
    }
    Ok(outln!("{}", report.text())?)
}
