//! `chronomap psbt`: the person search behavior tree of [Stüde 2024] §5.4, synthesised from a
//! grid Poisson model (eq. 5.7) learned from pedestrian tracks, or from a saved CoPA-Map; `chronomap psbt eval`: the
//! model-based comparison of §5.4.4 (Fig. 5.11).

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use chronomap_activity::disturbance::PlanningGrid;
use chronomap_activity::truth::TrackPoint;
use chronomap_app::open::FileKind;
use chronomap_core::Parallelism;
use chronomap_core::num::fmt_number;
use chronomap_io::psbt_xml::psbt_to_xml;
use chronomap_io::{load_planning_grid, read_track_point_files};
use chronomap_plot::{Panel, Series, SeriesStyle, render_panels_png};
use chronomap_psbt::compare::{Comparison, MethodSummary, compare};
use chronomap_psbt::world::grid_poisson_from_tracks;
use chronomap_psbt::{Choice, GridPoisson, PsbtConfig, PsbtError, copa_field, synthesize};
use serde_json::{Value, json};

use super::activity_disturbance::OCCUPIED_PERCENT;
use crate::cli::{PsbtArgs, PsbtCommand, PsbtEvalArgs, PsbtSynthArgs, PsbtWorldArgs};
use crate::format::Table;
use crate::output::{ProgressBar, print_json, usage};
use crate::{out, outln};

/// Where the robot may drive and the tracks it learns people from.
pub(super) struct World {
    pub grid: PlanningGrid,
    pub points: Vec<TrackPoint>,
    /// Lower-left corner and size (metres) of the map.
    origin: [f64; 2],
    size: [f64; 2],
}

/// Reads the map (planning grid of free cells) and the tracks.
pub(super) fn load_world(
    map: &Path,
    activity: &[impl AsRef<Path>],
    planning_cell: f64,
    clearance: f64,
) -> Result<World> {
    let (grid, origin, size) = planning_grid(map, planning_cell, clearance)?;
    let points = read_track_point_files(activity).context("cannot read the tracks")?;
    Ok(World {
        grid,
        points,
        origin,
        size,
    })
}

/// The planning grid of the map's free cells, its lower-left corner and size (metres).
fn planning_grid(
    map: &Path,
    planning_cell: f64,
    clearance: f64,
) -> Result<(PlanningGrid, [f64; 2], [f64; 2])> {
    let planning = load_planning_grid(map, OCCUPIED_PERCENT, planning_cell, clearance)?;
    Ok((planning.grid, planning.origin, planning.size))
}

/// Whether `--activity` names a saved model rather than tracks: one file that starts with the
/// model-file magic word or ends in `.cmcopa` ([`FileKind`]).
fn is_model_source(activity: &[std::path::PathBuf]) -> Result<bool> {
    let is_model = |path: &Path| -> Result<bool> {
        Ok(FileKind::by_name(path).is_copa_map() || FileKind::of(path)?.is_model_file())
    };
    let mut models = 0;
    for path in activity {
        models += usize::from(is_model(path)?);
    }
    match (models, activity.len()) {
        (0, _) => Ok(false),
        (1, 1) => Ok(true),
        _ => bail!(
            "--activity: give one CoPA-Map model file or pedestrian track files, not both \
             ({models} of {} files are models)",
            activity.len()
        ),
    }
}

/// The activity field of a saved CoPA-Map at the request time ([`copa_field`]).
fn copa_world_field(path: &Path, args: &PsbtSynthArgs, time: f64) -> Result<(GridPoisson, f64)> {
    let name = path.display().to_string();
    let model = super::activity_model::read_copa_map(path)?;
    let model_t = match args.model_t {
        Some(t) => t,
        None => chronomap_activity::atc::model_time(time).ok_or_else(|| {
            anyhow!(
                "--time {}: outside 09:00-21:00 JST, which the ATC grid's time axis covers \
                 (give --model-t)",
                crate::format::time(time)
            )
        })?,
    };
    let field = copa_field(&model, args.model_cell, model_t, Parallelism::Rayon(0))
        .map_err(|e| anyhow!("{name}: {e}"))?;
    Ok((field, model_t))
}

/// The grid Poisson model (eq. 5.7) over the map from the tracks `keep` accepts (by time).
pub(super) fn fit_model(
    world: &World,
    cell: f64,
    interval: f64,
    keep: impl Fn(f64) -> bool,
) -> Result<Option<GridPoisson>> {
    grid_poisson_from_tracks(
        &world.points,
        world.origin,
        world.size,
        cell,
        interval,
        keep,
    )
    .map_err(|e| match e {
        // Too many cells or intervals: the flag's value is what is wrong (a usage error).
        PsbtError::TooMany {
            parameter, value, ..
        } => usage(format!(
            "--{parameter} {}: {e} (over the map and the tracked time)",
            fmt_number(value)
        )),
        e => e.into(),
    })
}

fn config_of(world: &PsbtWorldArgs) -> Result<PsbtConfig> {
    let mut config = PsbtConfig::default();
    config.places = world.places;
    config
        .validate()
        .map_err(|e| usage(format!("--places {}: {e}", world.places)))?;
    Ok(config)
}

pub fn run(args: &PsbtArgs) -> Result<()> {
    match &args.command {
        Some(PsbtCommand::Eval(eval_args)) => eval(eval_args),
        None => synth(&args.synth),
    }
}

fn describe(choices: &Option<Vec<Choice>>) -> Value {
    match choices {
        None => json!("wait at the start (W)"),
        Some(c) => json!(c.iter().map(|c| c.name()).collect::<Vec<_>>()),
    }
}

fn synth(args: &PsbtSynthArgs) -> Result<()> {
    let (Some(world_args), Some(from), Some(time)) = (&args.world, args.from, args.time) else {
        return Err(usage("--map, --activity, --from and --time are needed"));
    };
    let config = config_of(world_args)?;
    let (grid, model, model_t) = if is_model_source(&world_args.activity)? {
        let (grid, _, _) = planning_grid(
            &world_args.map,
            world_args.planning_cell,
            world_args.clearance,
        )?;
        let (field, model_t) = copa_world_field(&world_args.activity[0], args, time)?;
        (grid, field, Some(model_t))
    } else {
        let world = load_world(
            &world_args.map,
            &world_args.activity,
            world_args.planning_cell,
            world_args.clearance,
        )?;
        let model = fit_model(&world, world_args.cell, world_args.interval, |_| true)?
            .ok_or_else(|| anyhow!("the tracks hold no detection"))?;
        (world.grid, model, None)
    };
    let started = Instant::now();
    let plan = synthesize(
        &grid,
        &model,
        from,
        time,
        &config,
        args.seed,
        Parallelism::Sequential,
    )
    .map_err(|e| {
        anyhow!(
            "--from {},{}: {e}",
            fmt_number(from[0]),
            fmt_number(from[1])
        )
    })?;
    let synthesis_ms = started.elapsed().as_secs_f64() * 1e3;
    let xml = psbt_to_xml(&plan.tree);
    if args.json {
        return print_json(&json!({
            "tree_xml": xml,
            "p_success": plan.p_success,
            "expected_time_s": plan.expected_time_s,
            "synthesis_ms": synthesis_ms,
            "candidates": plan.candidates,
            "places": plan.places,
            "choices": describe(&plan.choices),
            "horizon_s": config.horizon_s,
            "seed": args.seed,
            "model_t": model_t,
        }));
    }
    outln!(
        "person search from ({}, {}) at {}: {} candidate trees over {} places in {:.1} ms",
        from[0],
        from[1],
        crate::format::time(time),
        plan.candidates,
        plan.places.len(),
        synthesis_ms
    )?;
    outln!(
        "p_s,T({} s) = {:.4}; expected time to success E[T|S] = {}",
        config.horizon_s,
        plan.p_success,
        plan.expected_time_s
            .map_or("-".into(), |t| format!("{t:.1} s"))
    )?;
    if let Some(t) = model_t {
        outln!("activity: CoPA-Map at model t = {t:.3}")?;
    }
    out!("{xml}")?;
    Ok(())
}

fn eval(args: &PsbtEvalArgs) -> Result<()> {
    let config = config_of(&args.world)?;
    if is_model_source(&args.world.activity)? {
        bail!(
            "--activity: psbt eval needs pedestrian tracks (it learns a planning model from the \
             hours before --time and scores on the hour itself); a saved model serves synthesis"
        );
    }
    let world = load_world(
        &args.world.map,
        &args.world.activity,
        args.world.planning_cell,
        args.world.clearance,
    )?;
    let interval = args.world.interval;
    let hour = (args.time / interval).floor() * interval;
    let train_until = args.train_until.unwrap_or(hour);
    let plan_model = fit_model(&world, args.world.cell, interval, |t| t < train_until)?
        .ok_or_else(|| anyhow!("no detection before --train-until {train_until}"))?;
    let score_model = fit_model(&world, args.world.cell, interval, |t| {
        t >= hour && t < hour + interval
    })?;
    let started = Instant::now();
    let comparison = compare(
        &world.grid,
        &plan_model,
        score_model.as_ref(),
        args.time,
        &config,
        args.starts,
        args.seed,
        Parallelism::Rayon(0),
        &ProgressBar::new(),
    )?;
    let seconds = started.elapsed().as_secs_f64();
    let planned = comparison
        .summaries(false)
        .expect("the planning model scores every plan");
    let scored = comparison.summaries(true);
    let times = &comparison.times;
    let starts = comparison.outcomes.len();

    if let Some(path) = &args.plot {
        plot(path, &comparison, &planned, scored.as_deref())?;
    }

    let beaten = |scored_side: bool| {
        comparison
            .beats_psbt_fraction(scored_side)
            .into_iter()
            .map(|(m, f)| (m.name().to_string(), json!(f)))
            .collect::<serde_json::Map<String, Value>>()
    };
    if args.json {
        let summary_json = |summaries: &[MethodSummary]| -> Value {
            summaries
                .iter()
                .map(|s| {
                    (
                        s.method.name().to_string(),
                        json!({
                            "p_success_mean": s.p_mean,
                            "p_success_std": s.p_std,
                            "expected_time_mean_s": s.time_mean_s,
                            "expected_time_std_s": s.time_std_s,
                        }),
                    )
                })
                .collect::<serde_json::Map<String, Value>>()
                .into()
        };
        return print_json(&json!({
            "starts": starts,
            "time": args.time,
            "train_until": train_until,
            "times_s": times,
            "planning_model": summary_json(&planned),
            "scoring_model": scored.as_deref().map(summary_json),
            "psbt_over_gm_at_140_percent": comparison.gain_over_gm_percent(&planned),
            "psbt_over_gm_at_140_percent_scored": scored.as_deref().and_then(|s| comparison.gain_over_gm_percent(s)),
            "psbt_ge_all_at_tmax_fraction": comparison.psbt_at_least_all_fraction(false),
            "psbt_ge_all_at_tmax_fraction_scored": scored.as_ref().map(|_| comparison.psbt_at_least_all_fraction(true)),
            "beats_psbt_at_tmax_fraction": beaten(false),
            "beats_psbt_at_tmax_fraction_scored": scored.as_ref().map(|_| beaten(true)),
            "seconds": seconds,
        }));
    }

    let table = |summaries: &[MethodSummary]| {
        let mut header = vec!["method".to_string()];
        header.extend(times.iter().map(|t| format!("t={t:.0} s")));
        header.push("E[T|S] (s)".into());
        let mut table = Table::new(header);
        for s in summaries {
            let mut row = vec![s.method.name().to_string()];
            row.extend(
                s.p_mean
                    .iter()
                    .zip(&s.p_std)
                    .map(|(a, b)| format!("{a:.3}±{b:.3}")),
            );
            row.push(format!("{:.1}±{:.1}", s.time_mean_s, s.time_std_s));
            table.row(row);
        }
        table.render()
    };
    let beaten_text = |scored_side: bool| {
        comparison
            .beats_psbt_fraction(scored_side)
            .iter()
            .map(|(m, f)| format!("{} {:.1} %", m.name(), 100.0 * f))
            .collect::<Vec<_>>()
            .join(", ")
    };
    outln!(
        "{} help locations at {} (planning model: tracks before {}; scoring model: the \
         tracks of that hour), {} places, {:.1} s",
        starts,
        crate::format::time(args.time),
        crate::format::time(train_until),
        config.places,
        seconds
    )?;
    outln!("\np_s,T(t), mean ± std over the starts, on the planning model:")?;
    outln!("{}", table(&planned))?;
    if let Some(p) = comparison.gain_over_gm_percent(&planned) {
        outln!("PSBT vs GM at 140 s: {p:+.1} % (the dissertation: +5.7 %)")?;
    }
    outln!(
        "PSBT >= every baseline at t_max from {:.1} % of the starts; a baseline beats it from: {}",
        100.0 * comparison.psbt_at_least_all_fraction(false),
        beaten_text(false)
    )?;
    if let Some(scored) = &scored {
        outln!("\nthe same plans scored on the model of the evaluated hour:")?;
        outln!("{}", table(scored))?;
        if let Some(p) = comparison.gain_over_gm_percent(scored) {
            outln!("PSBT vs GM at 140 s: {p:+.1} %")?;
        }
        outln!(
            "PSBT >= every baseline at t_max from {:.1} % of the starts; a baseline beats it from: {}",
            100.0 * comparison.psbt_at_least_all_fraction(true),
            beaten_text(true)
        )?;
    }
    Ok(())
}

/// Mean `p_s,T(t)` of every method over the starts: on the planning model, and on the
/// scoring model if there is one.
fn plot(
    path: &Path,
    comparison: &Comparison,
    planned: &[MethodSummary],
    scored: Option<&[MethodSummary]>,
) -> Result<()> {
    let panel = |title: &str, summaries: &[MethodSummary]| Panel {
        title: title.into(),
        x_label: "t [s]".into(),
        y_label: "mean p_s,T(t)".into(),
        y_range: (0.0, 1.0),
        series: summaries
            .iter()
            .map(|s| Series {
                label: s.method.name().into(),
                points: comparison
                    .times
                    .iter()
                    .copied()
                    .zip(s.p_mean.iter().copied())
                    .collect(),
                style: SeriesStyle::Line,
            })
            .collect(),
    };
    let mut panels = vec![panel(
        &format!("planning model ({} starts)", comparison.outcomes.len()),
        planned,
    )];
    if let Some(scored) = scored {
        panels.push(panel("scored on the model of the evaluated hour", scored));
    }
    render_panels_png(&panels, path, 1400, 520)?;
    Ok(())
}
