//! `chronomap eval`: the benchmark experiment of the FreMEn papers on any data.

use anyhow::{Context, Result, anyhow};
use chronomap_app::eval::{evaluate_models, split_series};
use chronomap_core::TimeSeries;
use chronomap_io::{read_pairs, read_test_set};
use chronomap_models::eval::EvalReport;
use chronomap_models::split::SplitError;
use serde_json::json;

use super::describe_selection;
use crate::cli::{EvalArgs, model_specs};
use crate::format::{Table, duration, time};
use crate::outln;
use crate::output::{ProgressBar, print_json, usage};

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
    let until = |to: f64| {
        if to.is_finite() {
            time(to)
        } else {
            "the end".to_string()
        }
    };
    let file = args.train.display();
    let (train, tests) = split_series(&all, &args.split_at).map_err(|e| match e {
        SplitError::NotIncreasing { previous, next } => usage(format!(
            "--split-at: {} is not after {} (times must increase)",
            time(next),
            time(previous)
        )),
        SplitError::EmptyTrain { before } => anyhow!(
            "--split-at: {file} has no observation before {}",
            time(before)
        ),
        SplitError::EmptyTest { from, to } => anyhow!(
            "--split-at: {file} has no observation from {} to {}",
            time(from),
            until(to)
        ),
        e => anyhow!("--split-at: {e}"),
    })?;
    let mut labels = Vec::new();
    for (i, &from) in args.split_at.iter().enumerate() {
        let to = args.split_at.get(i + 1).copied().unwrap_or(f64::INFINITY);
        let label = format!("{file} from {} to {}", time(from), until(to));
        labels.push((label.clone(), label));
    }
    Ok((train, (tests, labels)))
}

pub fn run(args: &EvalArgs) -> Result<()> {
    let (train, (tests, labels)) = load(args)?;
    let options = args.fit.options();
    let specs = model_specs(&args.models);
    let report = {
        let bar = ProgressBar::new();
        evaluate_models(&specs, &train, &tests, &options, &bar)
    }
    .with_context(|| format!("cannot fit to {}", args.train.display()))?;
    if args.json {
        print_json(&to_json(args, &train, &tests, &labels, &report))
    } else {
        print_tables(args, &train, &tests, &labels, &report)
    }
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
            "fitted": m.fitted.model.fitted_as(),
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
    args: &EvalArgs,
    train: &TimeSeries,
    tests: &[TimeSeries],
    labels: &[(String, String)],
    report: &EvalReport,
) -> Result<()> {
    let span = train.times[train.len() - 1] - train.times[0];
    let mean = train.values.iter().sum::<f64>() / train.len() as f64;
    outln!(
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
        outln!(
            "test {}: {} — {} observations from {}",
            i + 1,
            t,
            s.len(),
            time(s.times[0])
        )?;
    }
    outln!()?;
    write_metric_table(
        report,
        if train.values.iter().all(|&v| v == 0.0 || v == 1.0) {
            "Mean squared error of p(t) (Brier score), lower is better"
        } else {
            "Mean squared error of the predicted value, lower is better"
        },
        |t| t.mse,
    )?;
    outln!()?;
    // The binary error (p > 0.5 against the state) means nothing for continuous values.
    let binary = train
        .values
        .iter()
        .chain(tests.iter().flat_map(|t| &t.values))
        .all(|&v| v == 0.0 || v == 1.0);
    if binary {
        write_metric_table(
            report,
            "Binary error (fraction of wrongly predicted states)",
            |t| t.binary_error,
        )?;
        outln!()?;
    }
    let selections: Vec<_> = report
        .models
        .iter()
        .filter_map(|m| m.fitted.selection.as_ref().map(|s| (m, s)))
        .collect();
    if !selections.is_empty() {
        outln!("How the automatic models chose (training data only):")?;
        for (m, s) in selections {
            outln!("  {}: {}", m.spec, describe_selection(s))?;
        }
        outln!()?;
    }
    if tests.len() < 2 {
        outln!("(significance needs at least two test sets)")?;
        return Ok(());
    }
    let mut significant: Vec<_> = report.significant(args.alpha).collect();
    significant.sort_by(|a, b| a.test.p_value.total_cmp(&b.test.p_value));
    outln!(
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
        outln!("  none")?;
    }
    for c in significant {
        outln!(
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
        let mut row = vec![m.spec.to_string(), m.fitted.model.fitted_as()];
        row.extend(values.iter().map(|v| format!("{v:.4}")));
        row.push(format!(
            "{:.4}",
            values.iter().sum::<f64>() / values.len() as f64
        ));
        table.row(row);
    }
    outln!("{title}\n{}", table.render())?;
    Ok(())
}
