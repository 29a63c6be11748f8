//! `chronomap fit`, `predict`, `inspect` and `anomalies`: working with saved models.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use chronomap_core::TimeSeries;
use chronomap_core::anomaly::detect_anomalies;
use chronomap_core::{FremenModel, FrequencyComponent, Ordered, TemporalModel, binary_entropy};
use chronomap_io::output::write_output;
use chronomap_io::{Field, encode_model, read_column, read_pairs};
use chronomap_models::AnyModel;
use chronomap_models::spec::ModelSpec;
use serde_json::{Value, json};

use super::{data_error, describe_selection, fft_components_table, load_model, read_series};
use crate::cli::{AnomaliesArgs, FitArgs, FitFlags, InspectArgs, PredictArgs};
use crate::format::{Table, duration, period, time};
use crate::output::{print_json, usage};
use crate::{out, outln};

pub fn fit(args: &FitArgs) -> Result<()> {
    let train = read_pairs(&args.train)?;
    let name = args.train.display().to_string();
    let training = Training {
        json: json!({ "file": name, "observations": train.len() }),
        name,
        series: train,
    };
    fit_and_save(&training, &args.model, &args.fit, &args.output, args.json)
}

/// Observations to fit a model on, and how to name them.
pub struct Training {
    /// The file (or bag and topic) they came from, for messages.
    pub name: String,
    /// What `--json` says about them (`"train"`).
    pub json: Value,
    /// The observations.
    pub series: TimeSeries,
}

/// Fits `model` on `training` with `fit`'s options, writes the model file and reports, as
/// `chronomap fit` does (also for `chronomap ingest`: the same bits from a bag).
pub fn fit_and_save(
    training: &Training,
    model: &ModelSpec,
    fit: &FitFlags,
    output: &Path,
    json: bool,
) -> Result<()> {
    let train = &training.series;
    let fitted = model
        .fit(&train.times, &train.values, &fit.options())
        .map_err(|e| data_error(&training.name, e))
        .with_context(|| format!("cannot fit {model}"))?;
    // The size is what was written, not the output's size afterwards (0 for `-o /dev/null`
    // or a pipe, which the one output writer writes through).
    let encoded = encode_model(fitted.model.kind(), &fitted.model)?;
    write_output(output, &encoded)?;
    let size = encoded.len();
    let selection = fitted.selection.as_ref().map(describe_selection);
    if json {
        return print_json(&json!({
            "train": training.json,
            "model": model.to_string(),
            "fitted": fitted.model.spec().to_string(),
            "kind": fitted.model.kind(),
            "order": fitted.model.order(),
            "selection": selection,
            "output": output.display().to_string(),
            "bytes": size,
        }));
    }
    outln!(
        "fitted {} as {} on {} observations of {}",
        model,
        fitted.model.fitted_as(),
        train.len(),
        training.name
    )?;
    if let Some(selection) = selection {
        outln!("{selection}")?;
    }
    outln!("wrote {} ({size} bytes)", output.display())?;
    Ok(())
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
    let predictions = model.predict_many(&times);
    if args.json {
        let rows: Vec<Value> = times
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
    let model = load_model(&args.model)?;
    if args.json {
        return print_json(&inspect_json(args, &model));
    }
    let span = model.span();
    outln!("file:   {}", args.model.display())?;
    outln!("model:  {} ({})", model.spec(), model.kind())?;
    if span.count > 0 {
        outln!(
            "data:   {} observations, {} .. {} ({})",
            span.count,
            time(span.first),
            time(span.last),
            duration(span.duration())
        )?;
    } else {
        outln!("data:   none (predicts 0.5)")?;
    }
    match &model {
        AnyModel::Mean(m) => outln!("mean:   {:.6}", m.mean().unwrap_or(0.5))?,
        AnyModel::Histogram(h) => {
            outln!("bins:   {} over {}", h.bins(), period(h.period_secs()))?;
            let mut table = Table::new(["bin", "from", "mean"]);
            for (i, mean) in h.bin_means().iter().enumerate() {
                table.row([
                    i.to_string(),
                    duration(bin_start(h.period_secs(), h.bins(), i)),
                    mean.map_or("-".into(), |m| format!("{m:.4}")),
                ]);
            }
            outln!("{}", table.render())?;
        }
        AnyModel::Fremen(m) => print_fremen(m, args.spectrum)?,
        AnyModel::Persistence(m) => {
            match m.persistence_secs() {
                Some(tau) => outln!("persistence tau: {} (eq. 12)", duration(tau))?,
                None => outln!("persistence tau: infinite (no change observed)")?,
            }
            print_fremen(m.fremen(), args.spectrum)?;
        }
        AnyModel::Markov(m) => {
            outln!(
                "rates:  0->1 {:.3e}/s, 1->0 {:.3e}/s",
                m.rate_up_per_sec(),
                m.rate_down_per_sec()
            )?;
            if let Some(pi) = m.stationary() {
                outln!("stationary p: {pi:.4}")?;
            }
            if let Some((t, s)) = m.last_observation() {
                outln!("last observation: {s} at {}", time(t))?;
            }
        }
        AnyModel::Pergam(m) => {
            let fit = m.fit();
            outln!(
                "period: {}, scale A = {:.4}, {} EM iterations",
                period(m.config().period_secs),
                fit.scale,
                fit.iterations
            )?;
            let mut table = Table::new(["weight", "mean (into period)", "sigma"]);
            for c in &fit.components {
                table.row([
                    format!("{:.3}", c.weight),
                    duration(c.mean_secs),
                    duration(c.sigma_secs),
                ]);
            }
            outln!("{}", table.render())?;
        }
        AnyModel::Hypertime(m) => {
            let periods: Vec<String> = m.periods().iter().map(|&p| period(p)).collect();
            outln!(
                "{} mixture components over {} periodicities: {}",
                m.components(),
                m.periods().len(),
                if periods.is_empty() {
                    "none (the mean)".to_string()
                } else {
                    periods.join(", ")
                }
            )?;
        }
        AnyModel::Fft(m) => {
            let (start, step) = m.sampling();
            outln!(
                "series: {} samples every {step} s from {} (spectrum over the first {})",
                m.len(),
                time(start),
                m.model_len()
            )?;
            outln!(
                "gain:   {:.6}; outlier set: {} toggles; estimation error {:.4}",
                m.gain(),
                m.outlier_toggles().len(),
                m.estimation_error()
            )?;
            outln!("{}", fft_components_table(m).render())?;
        }
        AnyModel::Stack(m) => {
            outln!(
                "a weighted average of these models (weights fitted by rolling-origin cross-validation):"
            )?;
            let mut table = Table::new(["weight", "model"]);
            for (member, weight) in m.members() {
                table.row([format!("{weight:.4}"), member.spec().to_string()]);
            }
            outln!("{}", table.render())?;
        }
    }
    Ok(())
}

/// Start of histogram bin `i` of `bins` over `period` seconds.
fn bin_start(period: f64, bins: usize, i: usize) -> f64 {
    period * i as f64 / bins as f64
}

/// The rows of a FreMEn table: the components in use, or the whole spectrum.
fn fremen_rows(m: &FremenModel, full: bool) -> (Vec<FrequencyComponent>, Vec<f64>) {
    let used: Vec<f64> = m.components().iter().map(|c| c.period_secs).collect();
    let rows = if full {
        m.spectrum()
    } else {
        m.components().to_vec()
    };
    (rows, used)
}

fn print_fremen(m: &FremenModel, full: bool) -> std::io::Result<()> {
    let fit = m.fit();
    outln!(
        "FreMEn: order {} of {} candidate periods ({}), mean {:.6}",
        m.order(),
        m.max_order(),
        m.config().periods,
        fit.mean
    )?;
    let mut table = Table::new(["period", "|gamma|", "cos amplitude", "phase (rad)", "used"]);
    let (rows, used) = fremen_rows(m, full);
    for c in rows {
        table.row([
            period(c.period_secs),
            format!("{:.5}", c.amplitude),
            format!("{:.5}", 2.0 * c.amplitude),
            format!("{:+.3}", c.phase),
            if used.contains(&c.period_secs) {
                "yes"
            } else {
                ""
            }
            .to_string(),
        ]);
    }
    outln!("{}", table.render())
}

fn fremen_json(m: &FremenModel, full: bool) -> Value {
    let (rows, used) = fremen_rows(m, full);
    json!({
        "order": m.order(),
        "max_order": m.max_order(),
        "periods": m.config().periods.to_string(),
        "mean": m.fit().mean,
        "components": rows.iter().map(|c| json!({
            "period_secs": c.period_secs,
            "amplitude": c.amplitude,
            "cos_amplitude": 2.0 * c.amplitude,
            "phase": c.phase,
            "used": used.contains(&c.period_secs),
        })).collect::<Vec<_>>(),
    })
}

fn inspect_json(args: &InspectArgs, model: &AnyModel) -> Value {
    let span = model.span();
    let data = (span.count > 0).then(|| {
        json!({
            "observations": span.count,
            "first": span.first,
            "last": span.last,
            "duration_secs": span.duration(),
        })
    });
    let details = match model {
        AnyModel::Mean(m) => json!({"mean": m.mean().unwrap_or(0.5)}),
        AnyModel::Histogram(h) => json!({
            "bins": h.bins(),
            "period_secs": h.period_secs(),
            "bin_means": h.bin_means(),
            "bin_starts_secs": (0..h.bins())
                .map(|i| bin_start(h.period_secs(), h.bins(), i))
                .collect::<Vec<_>>(),
        }),
        AnyModel::Fremen(m) => json!({"fremen": fremen_json(m, args.spectrum)}),
        AnyModel::Persistence(m) => json!({
            "persistence_secs": m.persistence_secs(),
            "fremen": fremen_json(m.fremen(), args.spectrum),
        }),
        AnyModel::Markov(m) => json!({
            "rate_up_per_sec": m.rate_up_per_sec(),
            "rate_down_per_sec": m.rate_down_per_sec(),
            "stationary": m.stationary(),
            "last_observation": m.last_observation().map(|(t, s)| json!({"time": t, "state": s})),
        }),
        AnyModel::Pergam(m) => {
            let fit = m.fit();
            json!({
                "period_secs": m.config().period_secs,
                "scale": fit.scale,
                "iterations": fit.iterations,
                "components": fit.components.iter().map(|c| json!({
                    "weight": c.weight,
                    "mean_secs": c.mean_secs,
                    "sigma_secs": c.sigma_secs,
                })).collect::<Vec<_>>(),
            })
        }
        AnyModel::Hypertime(m) => json!({
            "components": m.components(),
            "periods_secs": m.periods(),
        }),
        AnyModel::Fft(m) => {
            let (start, step) = m.sampling();
            json!({
                "samples": m.len(),
                "start": start,
                "step_secs": step,
                "model_len": m.model_len(),
                "gain": m.gain(),
                "outlier_toggles": m.outlier_toggles().len(),
                "estimation_error": m.estimation_error(),
                "components": fft_components_json(m),
            })
        }
        AnyModel::Stack(m) => json!({
            "members": m.members().map(|(member, weight)| json!({
                "weight": weight,
                "model": member.spec().to_string(),
            })).collect::<Vec<_>>(),
        }),
    };
    json!({
        "file": args.model.display().to_string(),
        "model": model.spec().to_string(),
        "kind": model.kind(),
        "data": data,
        "details": details,
    })
}

/// The spectral set `P` of an FFT FreMEn model as JSON (the rows of [`fft_components_table`]).
pub(super) fn fft_components_json(m: &chronomap_core::FftFremen) -> Vec<Value> {
    m.components()
        .iter()
        .map(|c| {
            json!({
                "bin": c.bin,
                "period_secs": m.period_of_bin(c.bin),
                "amplitude": c.amplitude,
                "phase": c.phase,
            })
        })
        .collect()
}

pub fn anomalies(args: &AnomaliesArgs) -> Result<()> {
    let model = load_model(&args.model)?;
    let series = read_series(&args.test)?;
    let found = detect_anomalies(&model, &series.times, &series.values, args.confidence)?;
    if args.json {
        return print_json(&json!({
            "model": args.model.display().to_string(),
            "observations": series.len(),
            "confidence": args.confidence,
            "anomalies": found.iter().map(|a| json!({
                "time": a.time,
                "observed": a.observed,
                "p": a.predicted,
            })).collect::<Vec<_>>(),
        }));
    }
    outln!(
        "{} of {} observations are anomalous at confidence {} (observed 0 while p >= {}, or 1 while p < {:.3})",
        found.len(),
        series.len(),
        args.confidence,
        args.confidence,
        1.0 - args.confidence
    )?;
    let mut table = Table::new(["time", "observed", "p(t)"]);
    for a in &found {
        table.row([
            time(a.time),
            a.observed.to_string(),
            format!("{:.4}", a.predicted),
        ]);
    }
    if !found.is_empty() {
        outln!("{}", table.render())?;
    }
    Ok(())
}
