//! `chronomap psbt`: the person search behavior tree of seed 002 §5.4, synthesised from a
//! grid Poisson model (eq. 5.7) learned from pedestrian tracks, or from a saved CoPA-Map; `chronomap psbt eval`: the
//! model-based comparison of §5.4.4 (Fig. 5.11).

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use chronomap_activity::CopaMap;
use chronomap_activity::disturbance::PlanningGrid;
use chronomap_activity::truth::TrackPoint;
use chronomap_core::Parallelism;
use chronomap_core::rng::{Xoshiro256StarStar, derive_seed};
use chronomap_io::navmap::{LoadSemantics, load_map};
use chronomap_io::psbt_xml::psbt_to_xml;
use chronomap_io::{read_model_file, read_track_point_files};
use chronomap_plot::{Panel, Series, SeriesStyle, render_panels_png};
use chronomap_psbt::eval::{MethodOutcome, evaluate_start, sample_starts};
use chronomap_psbt::{
    Choice, GammaPrior, GridPoisson, GridSpec, Method, PsbtConfig, copa_field, synthesize,
};
use rayon::prelude::*;
use serde_json::{Value, json};

use super::activity_disturbance::obstacles_of;
use crate::cli::{PsbtArgs, PsbtCommand, PsbtEvalArgs, PsbtSynthArgs, PsbtWorldArgs};
use crate::format::Table;

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
    let map_name = map.display().to_string();
    let occupancy = load_map(map, LoadSemantics::Nav2)?;
    let obstacles = obstacles_of(&occupancy).map_err(|e| anyhow!("{map_name}: {e}"))?;
    let resolution = f64::from(occupancy.resolution);
    let size = [
        f64::from(occupancy.width) * resolution,
        f64::from(occupancy.height) * resolution,
    ];
    let origin = [occupancy.origin[0], occupancy.origin[1]];
    let cols = (size[0] / planning_cell).floor() as usize;
    let rows = (size[1] / planning_cell).floor() as usize;
    let mut grid = PlanningGrid::new(origin, planning_cell, cols, rows)
        .map_err(|e| anyhow!("{map_name}: {e}"))?;
    grid.block_obstacles(&obstacles, clearance);
    if grid.free_count() == 0 {
        bail!("{map_name}: no planning cell is {clearance} m away from every obstacle");
    }
    Ok((grid, origin, size))
}

/// The kind written into CoPA-Map model files (as `activity fit` writes them).
const COPA_KIND: &str = "copa-map";

/// The ATC grid's time axis (data/README.md): `t` counts hours from 2012-10-24 09:00 JST
/// (unix 1351036800), 12 recorded hours (09:00–21:00) a day, nights removed.
const ATC_T0: f64 = 1_351_036_800.0;
const ATC_HOURS_PER_DAY: f64 = 12.0;

/// The model time of the unix time `time` on the ATC grid's axis: `12·d + h` on day `d` at
/// `h` hours after 09:00 JST; `None` outside 09:00–21:00 JST (the model has no night).
fn atc_model_time(time: f64) -> Option<f64> {
    let since = time - ATC_T0;
    let day = (since / 86_400.0).floor();
    let hours = (since - day * 86_400.0) / 3600.0;
    (hours < ATC_HOURS_PER_DAY).then_some(ATC_HOURS_PER_DAY * day + hours)
}

/// Whether `--activity` names a saved model rather than tracks: one file that starts with the
/// model-file magic word or ends in `.cmcopa`.
fn is_model_source(activity: &[std::path::PathBuf]) -> Result<bool> {
    let is_model = |path: &Path| -> Result<bool> {
        if path.extension().is_some_and(|e| e == "cmcopa") {
            return Ok(true);
        }
        let mut start = [0u8; 16];
        let mut file = std::fs::File::open(path)
            .with_context(|| format!("{}: cannot open", path.display()))?;
        let n = std::io::Read::read(&mut file, &mut start)
            .with_context(|| format!("{}: cannot read", path.display()))?;
        Ok(start[..n].starts_with(chronomap_io::model_file::MAGIC.as_bytes()))
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
    let (kind, model): (String, CopaMap) = read_model_file(path)?;
    if kind != COPA_KIND {
        bail!("{name}: a model of kind {kind:?}, not a CoPA-Map ({COPA_KIND:?})");
    }
    model.check().map_err(|e| anyhow!("{name}: {e}"))?;
    let model_t = match args.model_t {
        Some(t) => t,
        None => atc_model_time(time).ok_or_else(|| {
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
    let points: Vec<TrackPoint> = world.points.iter().copied().filter(|p| keep(p.t)).collect();
    let (Some(first), Some(last)) = (points.first(), points.last()) else {
        return Ok(None);
    };
    let t0 = (first.t / interval).floor() * interval;
    let spec = GridSpec {
        origin: world.origin,
        cell,
        cols: (world.size[0] / cell).ceil() as usize,
        rows: (world.size[1] / cell).ceil() as usize,
        t0,
        interval,
        intervals: ((last.t - t0) / interval).floor() as usize + 1,
    };
    Ok(Some(GridPoisson::from_tracks(
        &points,
        spec,
        GammaPrior::default(),
    )?))
}

fn config_of(world: &PsbtWorldArgs) -> Result<PsbtConfig> {
    let mut config = PsbtConfig::default();
    config.places = world.places;
    config.validate().context("--places")?;
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
        Some(c) => json!(
            c.iter()
                .map(|c| match c {
                    Choice::Skip => "skip",
                    Choice::Search => "search",
                    Choice::SearchWait => "search+wait",
                })
                .collect::<Vec<_>>()
        ),
    }
}

fn synth(args: &PsbtSynthArgs) -> Result<()> {
    let (Some(world_args), Some(from), Some(time)) = (&args.world, args.from, args.time) else {
        bail!("--map, --activity, --from and --time are needed");
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
    .map_err(|e| anyhow!("--from {},{}: {e}", from[0], from[1]))?;
    let synthesis_ms = started.elapsed().as_secs_f64() * 1e3;
    let xml = psbt_to_xml(&plan.tree);
    if args.json {
        println!(
            "{}",
            json!({
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
            })
        );
    } else {
        println!(
            "person search from ({}, {}) at {}: {} candidate trees over {} places in {:.1} ms",
            from[0],
            from[1],
            crate::format::time(time),
            plan.candidates,
            plan.places.len(),
            synthesis_ms
        );
        println!(
            "p_s,T({} s) = {:.4}; expected time to success E[T|S] = {}",
            config.horizon_s,
            plan.p_success,
            plan.expected_time_s
                .map_or("-".into(), |t| format!("{t:.1} s"))
        );
        if let Some(t) = model_t {
            println!("activity: CoPA-Map at model t = {t:.3}");
        }
        print!("{xml}");
    }
    Ok(())
}

/// Mean and sample standard deviation.
fn mean_std(values: &[f64]) -> (f64, f64) {
    if values.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = if values.len() > 1 {
        values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    (mean, var.sqrt())
}

/// Per method: mean and std of `p_s,T(t_k)` over the starts, and of `E[T|S]`.
struct Summary {
    p_mean: Vec<f64>,
    p_std: Vec<f64>,
    time: (f64, f64),
}

fn summarise(
    results: &[Vec<MethodOutcome>],
    m: usize,
    times: usize,
    scored: bool,
) -> Option<Summary> {
    let series = |k: usize| -> Option<Vec<f64>> {
        results
            .iter()
            .map(|r| {
                if scored {
                    r[m].scored.as_ref().map(|s| s[k])
                } else {
                    Some(r[m].p_success[k])
                }
            })
            .collect()
    };
    let mut p_mean = Vec::with_capacity(times);
    let mut p_std = Vec::with_capacity(times);
    for k in 0..times {
        let (mean, std) = mean_std(&series(k)?);
        p_mean.push(mean);
        p_std.push(std);
    }
    let expected: Vec<f64> = results
        .iter()
        .filter_map(|r| {
            if scored {
                r[m].scored_expected_time_s
            } else {
                r[m].expected_time_s
            }
        })
        .collect();
    Some(Summary {
        p_mean,
        p_std,
        time: mean_std(&expected),
    })
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
    let mut rng = Xoshiro256StarStar::seed_from_u64(derive_seed(args.seed, 11, 0, 0));
    let starts = sample_starts(
        &world.grid,
        args.starts,
        |c| plan_model.has_detections(c),
        &mut rng,
    );
    if starts.is_empty() {
        bail!("no free planning cell where the tracks saw anybody");
    }
    let times: Vec<f64> = (1..)
        .map(|k| 20.0 * f64::from(k))
        .take_while(|&t| t <= config.horizon_s + 1e-9)
        .collect();
    let started = Instant::now();
    let results: Vec<Vec<MethodOutcome>> = starts
        .par_iter()
        .enumerate()
        .map(|(i, &from)| {
            evaluate_start(
                &world.grid,
                &plan_model,
                score_model.as_ref(),
                from,
                args.time,
                &config,
                derive_seed(args.seed, 12, i as u64, 0),
                &times,
            )
            .map_err(|e| anyhow!("start {i} ({}, {}): {e}", from[0], from[1]))
        })
        .collect::<Result<_>>()?;
    let seconds = started.elapsed().as_secs_f64();

    let methods = Method::ALL;
    let planned: Vec<Summary> = (0..methods.len())
        .map(|m| summarise(&results, m, times.len(), false).expect("always planned"))
        .collect();
    let scored: Option<Vec<Summary>> = (0..methods.len())
        .map(|m| summarise(&results, m, times.len(), true))
        .collect();
    // The dissertation's claim: PSBT >= every baseline; +5.7 % over GM after 140 s.
    let k140 = times.iter().position(|&t| (t - 140.0).abs() < 1e-9);
    let ge_all = |scored_side: bool| -> f64 {
        let last = times.len() - 1;
        let ok = results
            .iter()
            .filter(|r| {
                let p = |o: &MethodOutcome| {
                    if scored_side {
                        o.scored.as_ref().map_or(f64::NAN, |s| s[last])
                    } else {
                        o.p_success[last]
                    }
                };
                r[1..].iter().all(|o| p(&r[0]) >= p(o) - 1e-9)
            })
            .count();
        ok as f64 / results.len() as f64
    };

    // Per baseline: the share of starts where it beats PSBT at t_max (by more than 1e-9).
    let beaten_by = |scored_side: bool| -> Vec<(String, f64)> {
        let last = times.len() - 1;
        let p = |o: &MethodOutcome| {
            if scored_side {
                o.scored.as_ref().map_or(f64::NAN, |s| s[last])
            } else {
                o.p_success[last]
            }
        };
        (1..methods.len())
            .map(|m| {
                let n = results
                    .iter()
                    .filter(|r| p(&r[m]) > p(&r[0]) + 1e-9)
                    .count();
                (
                    methods[m].name().to_string(),
                    n as f64 / results.len() as f64,
                )
            })
            .collect()
    };
    let beaten_text = |scored_side: bool| {
        beaten_by(scored_side)
            .iter()
            .map(|(name, f)| format!("{name} {:.1} %", 100.0 * f))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let table = |summaries: &[Summary]| {
        let mut header = vec!["method".to_string()];
        header.extend(times.iter().map(|t| format!("t={t:.0} s")));
        header.push("E[T|S] (s)".into());
        let mut table = Table::new(header);
        for (m, s) in methods.iter().zip(summaries) {
            let mut row = vec![m.name().to_string()];
            row.extend(
                s.p_mean
                    .iter()
                    .zip(&s.p_std)
                    .map(|(a, b)| format!("{a:.3}±{b:.3}")),
            );
            row.push(format!("{:.1}±{:.1}", s.time.0, s.time.1));
            table.row(row);
        }
        table.render()
    };
    let relative_to_gm =
        |s: &[Summary]| k140.map(|k| (s[0].p_mean[k] - s[1].p_mean[k]) / s[1].p_mean[k] * 100.0);

    if let Some(path) = &args.plot {
        let panel = |title: &str, summaries: &[Summary]| Panel {
            title: title.into(),
            x_label: "t [s]".into(),
            y_label: "mean p_s,T(t)".into(),
            y_range: (0.0, 1.0),
            series: methods
                .iter()
                .zip(summaries)
                .map(|(m, s)| Series {
                    label: m.name().into(),
                    points: times
                        .iter()
                        .copied()
                        .zip(s.p_mean.iter().copied())
                        .collect(),
                    style: SeriesStyle::Line,
                })
                .collect(),
        };
        let mut panels = vec![panel(
            &format!("planning model ({} starts)", results.len()),
            &planned,
        )];
        if let Some(scored) = &scored {
            panels.push(panel("scored on the model of the evaluated hour", scored));
        }
        render_panels_png(&panels, path, 1400, 520)?;
    }

    if args.json {
        let summary_json = |summaries: &[Summary]| -> Value {
            methods
                .iter()
                .zip(summaries)
                .map(|(m, s)| {
                    (
                        m.name().to_string(),
                        json!({
                            "p_success_mean": s.p_mean,
                            "p_success_std": s.p_std,
                            "expected_time_mean_s": s.time.0,
                            "expected_time_std_s": s.time.1,
                        }),
                    )
                })
                .collect::<serde_json::Map<String, Value>>()
                .into()
        };
        println!(
            "{}",
            json!({
                "starts": results.len(),
                "time": args.time,
                "train_until": train_until,
                "times_s": times,
                "planning_model": summary_json(&planned),
                "scoring_model": scored.as_deref().map(summary_json),
                "psbt_over_gm_at_140_percent": relative_to_gm(&planned),
                "psbt_over_gm_at_140_percent_scored": scored.as_deref().and_then(relative_to_gm),
                "psbt_ge_all_at_tmax_fraction": ge_all(false),
                "psbt_ge_all_at_tmax_fraction_scored": scored.as_ref().map(|_| ge_all(true)),
                "beats_psbt_at_tmax_fraction": beaten_by(false).into_iter().map(|(k, v)| (k, json!(v))).collect::<serde_json::Map<String, Value>>(),
                "beats_psbt_at_tmax_fraction_scored": scored.as_ref().map(|_| beaten_by(true).into_iter().map(|(k, v)| (k, json!(v))).collect::<serde_json::Map<String, Value>>()),
                "seconds": seconds,
            })
        );
    } else {
        println!(
            "{} help locations at {} (planning model: tracks before {}; scoring model: the \
             tracks of that hour), {} places, {:.1} s",
            results.len(),
            crate::format::time(args.time),
            crate::format::time(train_until),
            config.places,
            seconds
        );
        println!("\np_s,T(t), mean ± std over the starts, on the planning model:");
        println!("{}", table(&planned));
        if let Some(p) = relative_to_gm(&planned) {
            println!("PSBT vs GM at 140 s: {p:+.1} % (the dissertation: +5.7 %)");
        }
        println!(
            "PSBT >= every baseline at t_max from {:.1} % of the starts; a baseline beats it from: {}",
            100.0 * ge_all(false),
            beaten_text(false)
        );
        if let Some(scored) = &scored {
            println!("\nthe same plans scored on the model of the evaluated hour:");
            println!("{}", table(scored));
            if let Some(p) = relative_to_gm(scored) {
                println!("PSBT vs GM at 140 s: {p:+.1} %");
            }
            println!(
                "PSBT >= every baseline at t_max from {:.1} % of the starts; a baseline beats it from: {}",
                100.0 * ge_all(true),
                beaten_text(true)
            );
        }
    }
    Ok(())
}
