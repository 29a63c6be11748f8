//! `chronomap activity eval`: scores of models of human activity (rates of people per cell and
//! hour) on later data, eq. (4.20) NRMSE and eq. (4.21) χ²-distance of [Stüde 2024] chapter 4
//! ([`chronomap_app::activity::evaluate_files`] runs it and reports).

use anyhow::Result;
use chronomap_activity::{Baseline, PeriodInitMode, RateScale};
use chronomap_app::activity::{EvalChoice, EvalSettings, EvalTest, evaluate_files};
use chronomap_core::Parallelism;

use crate::cli::{ActivityEvalArgs, ActivityModel, CopaInit, CopaScale};
use crate::out;
use crate::output::{ProgressBar, print_json, usage};
use chronomap_plot::render_panels_png;

pub fn eval(args: &ActivityEvalArgs) -> Result<()> {
    let test = match (&args.test, args.split_at) {
        (Some(path), _) => EvalTest::File(path),
        (None, Some(at)) => EvalTest::SplitAt(at),
        (None, None) => return Err(usage("give --test or --split-at")),
    };
    let baseline = |b| EvalChoice::Baseline(b);
    let settings = EvalSettings {
        period: args.period,
        inducing: args.inducing,
        iterations: args.iterations,
        choice: match args.model {
            ActivityModel::Auto => EvalChoice::Auto,
            ActivityModel::GlobalMean => baseline(Baseline::GlobalMean),
            ActivityModel::Ml => baseline(Baseline::Ml),
            ActivityModel::MlLog => baseline(Baseline::MlLog),
            ActivityModel::FrAam => baseline(Baseline::FrAam),
            ActivityModel::GpHom => baseline(Baseline::GpHom),
            ActivityModel::Whyte => baseline(Baseline::Whyte),
            ActivityModel::LogAdditive => baseline(Baseline::LogAdditive),
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
    if args.plot.is_some()
        && !matches!(
            args.model,
            ActivityModel::LogAdditive | ActivityModel::Copa | ActivityModel::Auto
        )
    {
        return Err(usage(
            "--plot draws predictive intervals, which only Log-AM and CoPA-Map have \
             (--model log-additive or copa)",
        ));
    }
    let report = evaluate_files(&args.train, test, &settings, &ProgressBar::new())?;
    if let Some(path) = &args.plot {
        let panels = report.interval_panels().ok_or_else(|| {
            anyhow::anyhow!(
                "{}: --plot: the chosen model {} has no predictive intervals to draw",
                path.display(),
                report.model
            )
        })?;
        render_panels_png(&panels, path, 1000, 1000)?;
    }
    if args.json {
        return print_json(&report.json());
    }
    Ok(out!("{}", report.text())?)
}
