//! `chronomap eval`: the benchmark experiment of the FreMEn papers on any data.

use std::io::{IsTerminal, Write};

use anyhow::{Context, Result, bail};
use chronomap_io::{TimeSeries, read_pairs, read_test_set};
use chronomap_models::eval::{EvalReport, TestSet, evaluate};
use serde_json::json;

use super::describe_selection;
use crate::cli::EvalArgs;
use crate::format::{Table, duration, time};

/// Test sets: their data and a (times, values) label each.
type Tests = (Vec<TimeSeries>, Vec<(String, String)>);

/// The training series and the test sets: from files, or one file split at times.
fn load(args: &EvalArgs) -> Result<(TimeSeries, Tests)> {
    let all = read_pairs(&args.train)?;
    if args.split_at.is_empty() {
        let tests: Vec<TimeSeries> = args
            .tests
            .iter()
            .map(|(t, v)| read_test_set(t, v))
            .collect::<Result<_, _>>()?;
        let labels = args
            .tests
            .iter()
            .map(|(t, v)| (t.display().to_string(), v.display().to_string()))
            .collect();
        return Ok((all, (tests, labels)));
    }
    if let Some(w) = args.split_at.windows(2).find(|w| w[0] >= w[1]) {
        bail!(
            "--split-at: {} is not after {} (times must increase)",
            time(w[1]),
            time(w[0])
        );
    }
    let part = |from: f64, to: f64| {
        let (times, values): (Vec<f64>, Vec<f64>) = all
            .times
            .iter()
            .zip(&all.values)
            .filter(|&(&t, _)| t >= from && t < to)
            .map(|(&t, &v)| (t, v))
            .unzip();
        TimeSeries { times, values }
    };
    let train = part(f64::NEG_INFINITY, args.split_at[0]);
    if train.is_empty() {
        bail!(
            "--split-at: {} has no observation before {}",
            args.train.display(),
            time(args.split_at[0])
        );
    }
    let mut tests = Vec::new();
    let mut labels = Vec::new();
    for (i, &from) in args.split_at.iter().enumerate() {
        let to = args.split_at.get(i + 1).copied().unwrap_or(f64::INFINITY);
        let test = part(from, to);
        let until = if to.is_finite() {
            time(to)
        } else {
            "the end".to_string()
        };
        if test.is_empty() {
            bail!(
                "--split-at: {} has no observation from {} to {until}",
                args.train.display(),
                time(from)
            );
        }
        let label = format!("{} from {} to {until}", args.train.display(), time(from));
        labels.push((label.clone(), label));
        tests.push(test);
    }
    Ok((train, (tests, labels)))
}

pub fn run(args: &EvalArgs) -> Result<()> {
    let (train, (tests, labels)) = load(args)?;
    let sets: Vec<TestSet<'_>> = tests.iter().map(TimeSeries::as_test_set).collect();
    let options = args.fit.options();
    let total = args.models.0.len();
    let mut done = 0;
    // Progress on an interactive terminal only; logs and pipes stay clean.
    let progress = std::io::stderr().is_terminal();
    let report = evaluate(
        &args.models.0,
        &train.times,
        &train.values,
        &sets,
        &options,
        |m| {
            done += 1;
            if progress {
                eprint!("\rfitted {done}/{total} models ({})        ", m.spec);
            }
        },
    )
    .map_err(|(spec, e)| match e.observation_index() {
        Some(i) => anyhow::anyhow!("model {spec}: training observation {}: {e}", i + 1),
        None => anyhow::anyhow!("model {spec}: {e}"),
    })
    .with_context(|| format!("cannot fit to {}", args.train.display()))?;
    if progress {
        eprint!("\r{}\r", " ".repeat(60));
    }
    let mut out = std::io::stdout().lock();
    if args.json {
        writeln!(out, "{}", to_json(args, &train, &tests, &labels, &report))?;
    } else {
        print_tables(&mut out, args, &train, &tests, &labels, &report)?;
    }
    Ok(())
}

fn to_json(
    args: &EvalArgs,
    train: &TimeSeries,
    tests: &[TimeSeries],
    labels: &[(String, String)],
    report: &EvalReport,
) -> serde_json::Value {
    let name = |i: usize| report.models[i].spec.to_string();
    json!({
        "train": {
            "file": args.train.display().to_string(),
            "observations": train.len(),
        },
        "tests": labels.iter().zip(tests).map(|((t, v), s)| json!({
            "times": t,
            "values": v,
            "samples": s.len(),
        })).collect::<Vec<_>>(),
        "models": report.models.iter().map(|m| json!({
            "name": m.spec.to_string(),
            "fitted": m.fitted.model.spec().to_string(),
            "selection": m.fitted.selection.as_ref().map(describe_selection),
            "tests": m.tests.iter().map(|t| json!({
                "mse": t.mse,
                "binary_error": t.binary_error,
            })).collect::<Vec<_>>(),
            "mean_mse": m.mean_mse(),
            "mean_binary_error": m.mean_binary_error(),
        })).collect::<Vec<_>>(),
        "alpha": args.alpha,
        "comparisons": report.comparisons.iter().map(|c| json!({
            "better": name(c.better),
            "worse": name(c.worse),
            "mean_difference": c.test.mean_difference,
            "t": if c.test.t.is_finite() { json!(c.test.t) } else { json!(null) },
            "p_value": c.test.p_value,
            "significant": c.test.p_value < args.alpha,
        })).collect::<Vec<_>>(),
    })
}

fn print_tables(
    out: &mut impl Write,
    args: &EvalArgs,
    train: &TimeSeries,
    tests: &[TimeSeries],
    labels: &[(String, String)],
    report: &EvalReport,
) -> Result<()> {
    let span = train.times[train.len() - 1] - train.times[0];
    let mean = train.values.iter().sum::<f64>() / train.len() as f64;
    writeln!(
        out,
        "training: {} — {} observations, {} .. {} ({}), {}",
        args.train.display(),
        train.len(),
        time(train.times[0]),
        time(train.times[train.len() - 1]),
        duration(span),
        if train.values.iter().all(|&v| v == 0.0 || v == 1.0) {
            format!("{:.1} % ones", 100.0 * mean)
        } else {
            format!("mean value {mean:.4}")
        }
    )?;
    for (i, ((t, _), s)) in labels.iter().zip(tests).enumerate() {
        writeln!(
            out,
            "test {}: {} — {} observations from {}",
            i + 1,
            t,
            s.len(),
            time(s.times[0])
        )?;
    }
    writeln!(out)?;
    write_metric_table(
        out,
        report,
        if train.values.iter().all(|&v| v == 0.0 || v == 1.0) {
            "Mean squared error of p(t) (Brier score), lower is better"
        } else {
            "Mean squared error of the predicted value, lower is better"
        },
        |t| t.mse,
    )?;
    writeln!(out)?;
    // The binary error (p > 0.5 against the state) means nothing for continuous values.
    let binary = train
        .values
        .iter()
        .chain(tests.iter().flat_map(|t| &t.values))
        .all(|&v| v == 0.0 || v == 1.0);
    if binary {
        write_metric_table(
            out,
            report,
            "Binary error (fraction of wrongly predicted states)",
            |t| t.binary_error,
        )?;
        writeln!(out)?;
    }
    let selections: Vec<_> = report
        .models
        .iter()
        .filter_map(|m| m.fitted.selection.as_ref().map(|s| (m, s)))
        .collect();
    if !selections.is_empty() {
        writeln!(out, "How the automatic models chose (training data only):")?;
        for (m, s) in selections {
            writeln!(out, "  {}: {}", m.spec, describe_selection(s))?;
        }
        writeln!(out)?;
    }
    if tests.len() < 2 {
        writeln!(out, "(significance needs at least two test sets)")?;
        return Ok(());
    }
    let mut significant: Vec<_> = report.significant(args.alpha).collect();
    significant.sort_by(|a, b| a.test.p_value.total_cmp(&b.test.p_value));
    writeln!(
        out,
        "Significant differences of the {} (paired t-test over {} test sets, p < {}):",
        if binary {
            "Brier score"
        } else {
            "mean squared error"
        },
        tests.len(),
        args.alpha
    )?;
    if significant.is_empty() {
        writeln!(out, "  none")?;
    }
    for c in significant {
        writeln!(
            out,
            "  {:<18} better than {:<18} by {:.4} (p = {:.3})",
            report.models[c.better].spec.to_string(),
            report.models[c.worse].spec.to_string(),
            -c.test.mean_difference,
            c.test.p_value
        )?;
    }
    Ok(())
}

fn write_metric_table(
    out: &mut impl Write,
    report: &EvalReport,
    title: &str,
    metric: impl Fn(&chronomap_core::metrics::TestScore) -> f64,
) -> Result<()> {
    let tests = report.models.first().map_or(0, |m| m.tests.len());
    let mut header = vec!["model".to_string(), "fitted as".to_string()];
    header.extend((1..=tests).map(|i| format!("test {i}")));
    header.push("mean".into());
    let mut table = Table::new(header);
    for m in &report.models {
        let values: Vec<f64> = m.tests.iter().map(&metric).collect();
        let mut row = vec![m.spec.to_string(), m.fitted.model.spec().to_string()];
        row.extend(values.iter().map(|v| format!("{v:.4}")));
        row.push(format!(
            "{:.4}",
            values.iter().sum::<f64>() / values.len() as f64
        ));
        table.row(row);
    }
    writeln!(out, "{title}\n{}", table.render())?;
    Ok(())
}
