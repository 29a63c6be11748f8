//! `chronomap eval`: the benchmark experiment of the FreMEn papers on any data
//! (`chronomap_app::eval` reads, evaluates and reports, this prints).

use anyhow::{Context, Result};
use chronomap_app::eval::{EvalDataError, EvalOutcome, evaluate_models, read_study};
use chronomap_core::calendar::DaysOff;
use chronomap_models::split::SplitError;
use chronomap_plot::render_panels_png;

use crate::cli::{EvalArgs, model_specs};
use crate::outln;
use crate::output::{ProgressBar, print_json, usage};

pub fn run(args: &EvalArgs) -> Result<()> {
    let study = read_study(&args.train, &args.tests, &args.split_at).map_err(|e| match e {
        EvalDataError::Split {
            error: SplitError::NotIncreasing { .. },
            ..
        } => usage(e.to_string()),
        e => e.into(),
    })?;
    let days_off = match &args.days_off {
        Some(path) => chronomap_io::read_days_off(path)?,
        None => DaysOff::default(),
    };
    let report = {
        let bar = ProgressBar::new();
        let specs = model_specs(&args.models);
        let options = args.fit.options();
        evaluate_models(
            &specs,
            &study.train,
            &study.tests,
            &options,
            &days_off,
            &bar,
        )
    }
    .with_context(|| format!("cannot fit to {}", args.train.display()))?;
    let outcome = EvalOutcome {
        study,
        report,
        alpha: args.alpha,
    };
    if let Some(path) = &args.plot {
        render_panels_png(&outcome.reliability_panels(), path, 1000, 1000)?;
    }
    if args.json {
        return print_json(&outcome.json());
    }
    Ok(outln!("{}", outcome.text())?)
}
