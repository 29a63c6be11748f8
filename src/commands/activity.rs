//! `chronomap activity eval`: scores of models of human activity (rates of people per cell and
//! hour) on later data, eq. (4.20) NRMSE and eq. (4.21) χ²-distance of dissertation chapter 4.

use anyhow::{Context, Result, bail};
use chronomap_activity::{Baseline, PeriodInitMode, RateSamples, RateScale, Scores};
use chronomap_app::activity::{EvalChoice, EvalSettings, Evaluation, evaluate};
use chronomap_core::Parallelism;
use chronomap_io::read_rate_samples;
use serde_json::{Map, Value, json};

use crate::cli::{ActivityEvalArgs, ActivityModel, CopaInit, CopaScale};
use crate::format::Table;
use crate::output::{ProgressBar, print_json, usage};
use crate::{out, outln};

pub fn eval(args: &ActivityEvalArgs) -> Result<()> {
    let train_name = args.train.display().to_string();
    let all = read_rate_samples(&args.train).context("cannot read the training rates")?;
    let (train, test, test_name) = match (&args.test, args.split_at) {
        (Some(path), _) => {
            let name = path.display().to_string();
            let test = read_rate_samples(path).context("cannot read the test rates")?;
            (all, test, name)
        }
        (None, Some(at)) => {
            let (train, test) = all.split_at(at);
            if train.is_empty() {
                bail!("{train_name}: no sample has t < {at} (--split-at): nothing to train on");
            }
            if test.is_empty() {
                bail!("{train_name}: no sample has t >= {at} (--split-at): nothing to test on");
            }
            (train, test, format!("{train_name} (t >= {at})"))
        }
        (None, None) => return Err(usage("give --test or --split-at")),
    };
    if test.mean_rate() == 0.0 {
        bail!("{test_name}: every test rate is 0, so the NRMSE (eq. 4.20) is undefined");
    }
    let settings = EvalSettings {
        period: args.period,
        inducing: args.inducing,
        iterations: args.iterations,
        choice: match args.model {
            ActivityModel::Auto => EvalChoice::Auto,
            ActivityModel::GlobalMean => EvalChoice::Baseline(Baseline::GlobalMean),
            ActivityModel::Ml => EvalChoice::Baseline(Baseline::Ml),
            ActivityModel::MlLog => EvalChoice::Baseline(Baseline::MlLog),
            ActivityModel::FrAam => EvalChoice::Baseline(Baseline::FrAam),
            ActivityModel::GpHom => EvalChoice::Baseline(Baseline::GpHom),
            ActivityModel::Whyte => EvalChoice::Baseline(Baseline::Whyte),
            ActivityModel::LogAdditive => EvalChoice::Baseline(Baseline::LogAdditive),
            ActivityModel::Copa => EvalChoice::Copa {
                init: match args.init {
                    CopaInit::Spectral => PeriodInitMode::Spectral,
                    CopaInit::Day => PeriodInitMode::Day,
                },
                scale: match args.scale {
                    CopaScale::Log1p => RateScale::Log1p,
                    CopaScale::Rate => RateScale::Rate,
                },
            },
        },
        parallelism: Parallelism::Rayon(0),
    };
    let Evaluation {
        baselines,
        selection,
        model,
        scores: top,
        train_seconds,
        copa_init,
    } = {
        let progress = ProgressBar::new();
        evaluate(
            &train,
            &test,
            &settings,
            [&train_name, &test_name],
            &progress,
        )?
    };
    // CoPA-Map's initial periods, for the JSON output.
    let copa_init = match copa_init {
        None => Value::Null,
        Some(Some(init)) => json!({
            "mode": "spectral",
            "psi": init.psi,
            "periods": init.periods,
            "variances": init.variances,
            "fallback": init.none.map(|why| format!("{why:?}")),
        }),
        Some(None) => json!({"mode": "day"}),
    };
    let chosen_name = model.name().to_string();

    if args.json {
        let mut table = Map::new();
        for (baseline, s, seconds) in &baselines {
            let mut entry = scores_json(s);
            entry["train_seconds"] = json!(seconds);
            table.insert(baseline.name().into(), entry);
        }
        let selected_by = match &selection {
            Some(sel) => json!({
                "holdout_from_t": sel.cut,
                "scores": sel.scores.iter().map(|(b, s)| (b.name().to_string(), scores_json(s))).collect::<Map<_, _>>(),
            }),
            None => Value::String("--model".into()),
        };
        return print_json(&json!({
            "model": chosen_name,
            "selected_by": selected_by,
            "nrmse": top.nrmse,
            "chi2": top.chi2,
            "train_seconds": train_seconds,
            "copa_init": copa_init,
            "train": summary_json(&train_name, &train),
            "test": summary_json(&test_name, &test),
            "split_at": args.split_at,
            "baselines": table,
        }));
    }

    outln!(
        "training: {train_name}{}",
        summary(&train, args.split_at.map(|at| format!("t < {at}")))
    )?;
    outln!("test: {test_name}{}", summary(&test, None))?;
    outln!()?;
    let mut table = Table::new(["model", "NRMSE", "chi2", "train s"]);
    for (baseline, s, seconds) in &baselines {
        table.row([
            baseline.name().to_string(),
            format!("{:.4}", s.nrmse),
            format!("{:.1}", s.chi2),
            format!("{seconds:.3}"),
        ]);
    }
    out!("{}", table.render())?;
    let why = match &selection {
        Some(sel) => {
            let scores: Vec<String> = sel
                .scores
                .iter()
                .map(|(b, s)| format!("{} {:.4}", b.name(), s.nrmse))
                .collect();
            format!(
                "chosen by --model auto: least NRMSE on the training samples with t >= {} held \
                 out ({})",
                sel.cut,
                scores.join(", ")
            )
        }
        None => "chosen by --model".to_string(),
    };
    outln!(
        "\nmodel: {} ({why}); NRMSE {:.4}, chi2 {:.1}, trained in {:.3} s",
        chosen_name,
        top.nrmse,
        top.chi2,
        train_seconds
    )?;
    outln!(
        "NRMSE: eq. (4.20), root mean square error over the mean test rate; chi2: eq. (4.21), \
         chi-square distance (lower is better for both). gp_hom is trained with --inducing and \
         --iterations as CoPA-Map (`--model copa`); `--model auto` chooses among the others."
    )?;
    Ok(())
}

fn scores_json(s: &Scores) -> Value {
    json!({ "nrmse": s.nrmse, "chi2": s.chi2 })
}

fn time_range(samples: &RateSamples) -> (f64, f64) {
    samples
        .t()
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| {
            (lo.min(t), hi.max(t))
        })
}

fn summary_json(name: &str, samples: &RateSamples) -> Value {
    let (first, last) = time_range(samples);
    json!({
        "file": name,
        "samples": samples.len(),
        "cells": samples.cell_count(),
        "t_first": first,
        "t_last": last,
        "mean_rate": samples.mean_rate(),
    })
}

/// `: 61131 samples (t < 96), 652 cells, t 0 .. 95, mean rate 42.1 per hour`.
fn summary(samples: &RateSamples, part: Option<String>) -> String {
    let (first, last) = time_range(samples);
    let part = part.map(|p| format!(" ({p})")).unwrap_or_default();
    format!(
        ": {} samples{part}, {} cells, t {first} .. {last}, mean rate {:.2} per hour",
        samples.len(),
        samples.cell_count(),
        samples.mean_rate()
    )
}
