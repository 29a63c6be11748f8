//! `chronomap psbt`: the person search behavior tree of [Stüde 2024] §5.4, synthesised from a
//! grid Poisson model (eq. 5.7) learned from pedestrian tracks, or from a saved CoPA-Map;
//! `chronomap psbt eval`: the model-based comparison of §5.4.4 (Fig. 5.11). The jobs and their
//! reports are `chronomap_app_bt::psbt`; this file translates flags, prints and plots.

use anyhow::Result;
use chronomap_app_bt::psbt::{self, CopaTime, PsbtJobError, WorldSetup};
use chronomap_plot::render_panels_png;
use chronomap_psbt::PsbtConfig;

use crate::cli::{PsbtArgs, PsbtCommand, PsbtEvalArgs, PsbtSynthArgs, PsbtWorldArgs};
use crate::out;
use crate::output::{ProgressBar, print_json, usage};

/// An error of the application layer as the command reports it: a value that does not fit
/// the data is a usage error (exit code 2).
pub(super) fn job_error(e: PsbtJobError) -> anyhow::Error {
    match e {
        PsbtJobError::Usage(message) => usage(message),
        e => anyhow::Error::new(e),
    }
}

fn config_of(world: &PsbtWorldArgs) -> Result<PsbtConfig> {
    let mut config = PsbtConfig::default();
    config.places = world.places;
    config
        .validate()
        .map_err(|e| usage(format!("--places {}: {e}", world.places)))?;
    Ok(config)
}

fn world_of(w: &PsbtWorldArgs) -> WorldSetup<'_> {
    WorldSetup {
        map: &w.map,
        activity: &w.activity,
        cell: w.cell,
        interval: w.interval,
        planning_cell: w.planning_cell,
        clearance: w.clearance,
    }
}

pub fn run(args: &PsbtArgs) -> Result<()> {
    match &args.command {
        Some(PsbtCommand::Eval(eval_args)) => eval(eval_args),
        None => synth(&args.synth),
    }
}

fn synth(args: &PsbtSynthArgs) -> Result<()> {
    let (Some(world), Some(from), Some(time)) = (&args.world, args.from, args.time) else {
        return Err(usage("--map, --activity, --from and --time are needed"));
    };
    let config = config_of(world)?;
    let copa = CopaTime {
        model_t: args.model_t,
        model_cell: args.model_cell,
    };
    let report = psbt::synthesis(&world_of(world), &config, (from, time), args.seed, copa)
        .map_err(job_error)?;
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    out!("{report}")?;
    Ok(())
}

fn eval(args: &PsbtEvalArgs) -> Result<()> {
    let config = config_of(&args.world)?;
    let report = psbt::evaluation(
        &world_of(&args.world),
        &config,
        (args.time, args.train_until),
        (args.starts, args.seed),
        &ProgressBar::new(),
    )
    .map_err(job_error)?;
    if let Some(path) = &args.plot {
        render_panels_png(&report.panels(), path, 1400, 520)?;
    }
    if args.json {
        return print_json(&report.json());
    }
    out!("{report}")?;
    Ok(())
}
