//! `chronomap fit`, `predict`, `inspect` and `anomalies`: working with saved models.

use std::io::{BufWriter, Write};

use anyhow::{Context, Result, bail};
use chronomap_core::anomaly::detect_anomalies;
use chronomap_core::{FremenModel, Ordered, TemporalModel};
use chronomap_io::{Field, read_column, read_pairs, write_any_model};
use chronomap_models::AnyModel;

use super::{data_error, describe_selection, fft_components_table, load_model, read_series};
use crate::cli::{AnomaliesArgs, FitArgs, InspectArgs, PredictArgs};
use crate::format::{Table, duration, period, time};

pub fn fit(args: &FitArgs) -> Result<()> {
    let train = read_pairs(&args.train)?;
    let fitted = args
        .model
        .fit(&train.times, &train.values, &args.fit.options())
        .map_err(|e| data_error(&args.train.display().to_string(), e))
        .with_context(|| format!("cannot fit {}", args.model))?;
    write_any_model(&args.output, &fitted.model)?;
    let size = std::fs::metadata(&args.output)
        .map(|m| m.len())
        .unwrap_or(0);
    println!(
        "fitted {} as {} on {} observations of {}",
        args.model,
        fitted.model.spec(),
        train.len(),
        args.train.display()
    );
    if let Some(selection) = &fitted.selection {
        println!("{}", describe_selection(selection));
    }
    println!("wrote {} ({size} bytes)", args.output.display());
    Ok(())
}

pub fn predict(args: &PredictArgs) -> Result<()> {
    let mut model = load_model(&args.model)?;
    if let Some(order) = args.order
        && !model.set_order(order)
    {
        bail!("a {} model has no order to change", model.kind());
    }
    let times = match &args.times {
        Some(path) => read_column(path, Field::Time)?,
        None => args.at.clone(),
    };
    let predictions = model.predict_many(&times);
    let mut out = BufWriter::new(std::io::stdout().lock());
    writeln!(out, "# time\tp\tentropy_bits")?;
    for (t, p) in times.iter().zip(predictions) {
        writeln!(out, "{t}\t{p:.6}\t{:.6}", chronomap_core::binary_entropy(p))?;
    }
    out.flush()?;
    Ok(())
}

pub fn inspect(args: &InspectArgs) -> Result<()> {
    let model = load_model(&args.model)?;
    let span = model.span();
    println!("file:   {}", args.model.display());
    println!("model:  {} ({})", model.spec(), model.kind());
    if span.count > 0 {
        println!(
            "data:   {} observations, {} .. {} ({})",
            span.count,
            time(span.first),
            time(span.last),
            duration(span.duration())
        );
    } else {
        println!("data:   none (predicts 0.5)");
    }
    match &model {
        AnyModel::Mean(m) => println!("mean:   {:.6}", m.mean().unwrap_or(0.5)),
        AnyModel::Histogram(h) => {
            println!("bins:   {} over {}", h.bins(), period(h.period_secs()));
            let mut table = Table::new(["bin", "from", "mean"]);
            for (i, mean) in h.bin_means().iter().enumerate() {
                let from = h.period_secs() * i as f64 / h.bins() as f64;
                table.row([
                    i.to_string(),
                    duration(from),
                    mean.map_or("-".into(), |m| format!("{m:.4}")),
                ]);
            }
            println!("{}", table.render());
        }
        AnyModel::Fremen(m) => print_fremen(m, args.spectrum),
        AnyModel::Persistence(m) => {
            match m.persistence_secs() {
                Some(tau) => println!("persistence tau: {} (eq. 12)", duration(tau)),
                None => println!("persistence tau: infinite (no change observed)"),
            }
            print_fremen(m.fremen(), args.spectrum);
        }
        AnyModel::Markov(m) => {
            println!(
                "rates:  0->1 {:.3e}/s, 1->0 {:.3e}/s",
                m.rate_up_per_sec(),
                m.rate_down_per_sec()
            );
            if let Some(pi) = m.stationary() {
                println!("stationary p: {pi:.4}");
            }
            if let Some((t, s)) = m.last_observation() {
                println!("last observation: {s} at {}", time(t));
            }
        }
        AnyModel::Pergam(m) => {
            let fit = m.fit();
            println!(
                "period: {}, scale A = {:.4}, {} EM iterations",
                period(m.config().period_secs),
                fit.scale,
                fit.iterations
            );
            let mut table = Table::new(["weight", "mean (into period)", "sigma"]);
            for c in &fit.components {
                table.row([
                    format!("{:.3}", c.weight),
                    duration(c.mean_secs),
                    duration(c.sigma_secs),
                ]);
            }
            println!("{}", table.render());
        }
        AnyModel::Hypertime(m) => {
            let periods: Vec<String> = m.periods().iter().map(|&p| period(p)).collect();
            println!(
                "{} mixture components over {} periodicities: {}",
                m.components(),
                m.periods().len(),
                if periods.is_empty() {
                    "none (the mean)".to_string()
                } else {
                    periods.join(", ")
                }
            );
        }
        AnyModel::Fft(m) => {
            let (start, step) = m.sampling();
            println!(
                "series: {} samples every {step} s from {} (spectrum over the first {})",
                m.len(),
                time(start),
                m.model_len()
            );
            println!(
                "gain:   {:.6}; outlier set: {} toggles; estimation error {:.4}",
                m.gain(),
                m.outlier_toggles().len(),
                m.estimation_error()
            );
            println!("{}", fft_components_table(m).render());
        }
    }
    Ok(())
}

fn print_fremen(m: &FremenModel, full: bool) {
    let fit = m.fit();
    println!(
        "FreMEn: order {} of {} candidate periods ({}), mean {:.6}",
        m.order(),
        m.max_order(),
        m.config().periods,
        fit.mean
    );
    let mut table = Table::new(["period", "|gamma|", "cos amplitude", "phase (rad)", "used"]);
    let used: Vec<f64> = m.components().iter().map(|c| c.period_secs).collect();
    let rows = if full {
        m.spectrum()
    } else {
        m.components().to_vec()
    };
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
    println!("{}", table.render());
}

pub fn anomalies(args: &AnomaliesArgs) -> Result<()> {
    let model = load_model(&args.model)?;
    let series = read_series(&args.test)?;
    let found = detect_anomalies(&model, &series.times, &series.values, args.confidence)?;
    println!(
        "{} of {} observations are anomalous at confidence {} (observed 0 while p >= {}, or 1 while p < {:.3})",
        found.len(),
        series.len(),
        args.confidence,
        args.confidence,
        1.0 - args.confidence
    );
    let mut table = Table::new(["time", "observed", "p(t)"]);
    for a in &found {
        table.row([
            time(a.time),
            a.observed.to_string(),
            format!("{:.4}", a.predicted),
        ]);
    }
    if !found.is_empty() {
        println!("{}", table.render());
    }
    Ok(())
}
