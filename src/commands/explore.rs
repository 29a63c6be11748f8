//! `chronomap explore`: lifelong spatio-temporal exploration on a real dataset, every strategy
//! with every temporal model, beside the paper's table (seed 000 §7).

use std::path::Path;

use anyhow::{Context, Result};
use chronomap_core::{FremenModel, MarkovModel, MeanModel, PergamConfig, PergamModel};
use chronomap_explore::{
    AutoOrder, DailyModel, ExploreConfig, ExploreResult, Strategy, World, explore,
};
use chronomap_io::datasets::{load_aruba, load_brayford};
use chronomap_plot::{Panel, Series, SeriesStyle, render_panels_png};
use rayon::prelude::*;
use serde_json::json;

use crate::cli::{DatasetArg, ExploreArgs};
use crate::format::{Table, time};

/// The temporal models of seed 000 §4 as the tables name them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelKind {
    /// SM: short-term memory (continuous-time Markov chain).
    ShortTerm,
    /// LM: long-term memory (the mean).
    Mean,
    /// FT: FreMEn with its order chosen every day.
    Fremen,
    /// GM: periodic Gaussian mixture over the day.
    Pergam,
}

impl ModelKind {
    pub const ALL: [ModelKind; 4] = [
        ModelKind::ShortTerm,
        ModelKind::Mean,
        ModelKind::Fremen,
        ModelKind::Pergam,
    ];

    /// Name in JSON.
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::ShortTerm => "stm",
            ModelKind::Mean => "mean",
            ModelKind::Fremen => "fremen",
            ModelKind::Pergam => "pergam",
        }
    }

    /// Column title of the paper's tables.
    fn column(self) -> &'static str {
        match self {
            ModelKind::ShortTerm => "SM",
            ModelKind::Mean => "LM",
            ModelKind::Fremen => "FT",
            ModelKind::Pergam => "GM",
        }
    }

    /// A fresh model of one state.
    pub fn make(self) -> Box<dyn DailyModel> {
        match self {
            ModelKind::ShortTerm => Box::new(MarkovModel::new()),
            ModelKind::Mean => Box::new(MeanModel::new()),
            ModelKind::Fremen => Box::new(AutoOrder::new(FremenModel::with_order(0))),
            // One bin per 10-minute observation slot: the finest time the schedule resolves.
            ModelKind::Pergam => Box::new(
                PergamModel::new(PergamConfig {
                    components: 2,
                    bins: 144,
                    ..PergamConfig::default()
                })
                .expect("a valid configuration"),
            ),
        }
    }
}

/// Row title of the paper's tables.
fn row_title(strategy: Strategy) -> &'static str {
    match strategy {
        Strategy::RoundRobin => "Round Robin",
        Strategy::Random => "Random",
        Strategy::Greedy => "Greedy",
        Strategy::MonteCarlo { .. } => "Monte-Carlo",
        Strategy::Novelty { .. } => "Novelty-driven",
    }
}

/// Seed 000 Table 1 (Aruba, symbolic) and Table 2 (Brayford, people presence), in percent:
/// rows Round Robin, Random, Greedy, Monte-Carlo, Novelty; columns SM, LM, FT, GM.
const PAPER_ARUBA: [[f64; 4]; 5] = [
    [9.3, 9.7, 6.5, 7.5],
    [8.9, 9.5, 9.2, 7.5],
    [8.5, 8.7, 7.0, 9.4],
    [8.5, 8.9, 5.8, 6.4],
    [8.5, 8.9, 5.7, 6.1],
];
const PAPER_BRAYFORD: [[f64; 4]; 5] = [
    [23.7, 23.7, 16.3, 20.2],
    [23.7, 23.8, 23.0, 23.8],
    [20.2, 22.3, 19.2, 20.1],
    [23.5, 23.5, 16.4, 19.3],
    [23.4, 23.5, 15.2, 19.4],
];

fn load(args: &ExploreArgs) -> Result<World> {
    Ok(match args.dataset {
        DatasetArg::Aruba => load_aruba(&args.data)?,
        DatasetArg::Brayford => load_brayford(&args.data)?,
    })
}

/// Runs every strategy with every model.
pub fn table(
    world: &World,
    config: &ExploreConfig,
) -> Result<Vec<(Strategy, ModelKind, ExploreResult)>> {
    let combos: Vec<(Strategy, ModelKind)> = Strategy::all()
        .into_iter()
        .flat_map(|s| ModelKind::ALL.map(|m| (s, m)))
        .collect();
    combos
        .into_par_iter()
        .map(|(strategy, model)| {
            let result = explore(world, strategy, &move || model.make(), config)?;
            Ok((strategy, model, result))
        })
        .collect()
}

pub fn run(args: &ExploreArgs) -> Result<()> {
    let world =
        load(args).with_context(|| format!("cannot load the {:?} dataset", args.dataset))?;
    let config = ExploreConfig {
        ratio: args.ratio,
        days: args.days,
        seed: args.seed,
        ..ExploreConfig::default()
    };
    let results = table(&world, &config)?;
    let paper = match args.dataset {
        DatasetArg::Aruba => &PAPER_ARUBA,
        DatasetArg::Brayford => &PAPER_BRAYFORD,
    };
    let days = results[0].2.daily_error_percent.len();
    if args.json {
        println!(
            "{}",
            json!({
                "dataset": format!("{:?}", args.dataset).to_lowercase(),
                "ratio": args.ratio,
                "seed": args.seed,
                "days": days,
                "results": results.iter().map(|(s, m, r)| json!({
                    "strategy": s.name(),
                    "model": m.name(),
                    "error_percent": r.error_percent,
                    "explored_fraction": r.explored_fraction,
                    "redirects": r.redirects,
                })).collect::<Vec<_>>(),
            })
        );
    } else {
        println!(
            "{}: {} locations, {} days from {}, exploration ratio e = {}, 10-minute observations, seed {}",
            args.data.display(),
            world.locations.len(),
            days,
            time(world.start),
            args.ratio,
            args.seed
        );
        println!(
            "Model error of eq. (2) [%], ours (paper{}):\n",
            if args.ratio == 0.5 {
                ", Table 1 / Table 2"
            } else {
                " at e = 0.5"
            }
        );
        let mut header = vec!["strategy".to_string()];
        header.extend(ModelKind::ALL.map(|m| m.column().to_string()));
        let mut t = Table::new(header);
        for (row, strategy) in Strategy::all().into_iter().enumerate() {
            let mut cells = vec![row_title(strategy).to_string()];
            for (col, model) in ModelKind::ALL.into_iter().enumerate() {
                let r = results
                    .iter()
                    .find(|(s, m, _)| *s == strategy && *m == model)
                    .map(|(_, _, r)| r)
                    .context("missing result")?;
                cells.push(format!("{:4.1} ({:4.1})", r.error_percent, paper[row][col]));
            }
            t.row(cells);
        }
        println!("{}", t.render());
        let best = results
            .iter()
            .min_by(|a, b| a.2.error_percent.total_cmp(&b.2.error_percent))
            .context("no results")?;
        println!(
            "\nbest: {} + {} at {:.2} %; explored {:.1} % of the slots; novelty redirected {} slots",
            best.0.name(),
            best.1.name(),
            best.2.error_percent,
            100.0 * best.2.explored_fraction,
            results
                .iter()
                .filter(|(s, m, _)| matches!(s, Strategy::Novelty { .. }) && *m == ModelKind::Fremen)
                .map(|(_, _, r)| r.redirects)
                .sum::<usize>()
        );
    }
    if let Some(path) = &args.sweep {
        sweep(&world, args.seed, path)?;
        eprintln!("wrote {}", path.display());
    }
    if let Some(path) = &args.behaviour {
        behaviour(&world, args.ratio, args.seed, path)?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// Ratios of the exploration-ratio sweep (seed 000 Fig. 5).
const SWEEP: [f64; 7] = [0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 0.9];
/// Runs (seeds `seed..seed + SWEEP_SEEDS`) averaged per point of the sweep.
const SWEEP_SEEDS: u64 = 5;

/// Seed 000 Fig. 5: the model error of FreMEn with each strategy over two weeks, against the
/// exploration ratio, with the static model (round robin) for reference.
pub fn sweep(world: &World, seed: u64, path: &Path) -> Result<()> {
    let runs: Vec<(Strategy, ModelKind)> = Strategy::all()
        .into_iter()
        .map(|s| (s, ModelKind::Fremen))
        .chain([(Strategy::RoundRobin, ModelKind::Mean)])
        .collect();
    // Each point is the mean of SWEEP_SEEDS runs: the random strategies vary from run to run,
    // most at low ratios.
    let jobs: Vec<(usize, f64, u64)> = (0..runs.len())
        .flat_map(|r| {
            SWEEP
                .into_iter()
                .flat_map(move |e| (0..SWEEP_SEEDS).map(move |k| (r, e, seed + k)))
        })
        .collect();
    let single: Vec<(usize, f64, f64)> = jobs
        .into_par_iter()
        .map(|(r, e, seed)| {
            let (strategy, model) = runs[r];
            let config = ExploreConfig {
                ratio: e,
                days: Some(14),
                seed,
                ..ExploreConfig::default()
            };
            explore(world, strategy, &move || model.make(), &config)
                .map(|x| (r, e, x.error_percent))
        })
        .collect::<Result<_, _>>()?;
    let errors: Vec<(usize, f64, f64)> = (0..runs.len())
        .flat_map(|r| SWEEP.map(|e| (r, e)))
        .map(|(r, e)| {
            let runs = single.iter().filter(|x| x.0 == r && x.1 == e);
            (r, e, runs.map(|x| x.2).sum::<f64>() / SWEEP_SEEDS as f64)
        })
        .collect();
    let series = runs
        .iter()
        .enumerate()
        .map(|(r, (strategy, model))| Series {
            label: if *model == ModelKind::Fremen {
                format!("{} + FreMEn", row_title(*strategy))
            } else {
                format!("{} + static (mean)", row_title(*strategy))
            },
            points: errors
                .iter()
                .filter(|(i, _, _)| *i == r)
                .map(|&(_, e, err)| (e, err))
                .collect(),
            style: SeriesStyle::Line,
        })
        .collect();
    let top = errors.iter().map(|e| e.2).fold(0.0, f64::max) * 1.1;
    let panel = Panel {
        title: format!(
            "Model error after two weeks of exploration by exploration ratio (seed 000 Fig. 5, mean of {SWEEP_SEEDS} seeds)"
        ),
        x_label: "exploration ratio e".into(),
        y_label: "model error [%]".into(),
        y_range: (0.0, top.max(1.0)),
        series,
    };
    render_panels_png(&[panel], path, 1200, 650)?;
    Ok(())
}

/// Seed 000 Fig. 6: the truth, the model, the expected information and the visits of three
/// areas over the first four days of FreMEn with the Monte-Carlo strategy.
pub fn behaviour(world: &World, ratio: f64, seed: u64, path: &Path) -> Result<()> {
    let days = 4usize;
    let config = ExploreConfig {
        ratio,
        days: Some(days),
        seed,
        trace_days: days,
        ..ExploreConfig::default()
    };
    let result = explore(
        world,
        Strategy::MonteCarlo { iota: 0.01 },
        &|| ModelKind::Fremen.make(),
        &config,
    )?;
    let trace = &result.trace;
    // The three busiest areas (one state per location in these datasets).
    let mut areas: Vec<usize> = (0..world.locations.len()).collect();
    areas.sort_by_key(|&l| {
        std::cmp::Reverse(
            world.truth[world.locations[l][0]]
                .iter()
                .map(|&v| u64::from(v))
                .sum::<u64>(),
        )
    });
    areas.truncate(3);
    let day = |t: f64| (t - world.start) / 86_400.0;
    let steps = days * (86_400.0 / world.step_secs) as usize;
    let offset = |k: usize| 1.5 * (2 - k) as f64;
    let truth = areas
        .iter()
        .enumerate()
        .map(|(k, &l)| Series {
            label: world.names[l].clone(),
            points: (0..steps)
                .map(|s| {
                    (
                        day(world.time(s)),
                        offset(k) + f64::from(world.truth[world.locations[l][0]][s]),
                    )
                })
                .collect(),
            style: SeriesStyle::Step,
        })
        .collect();
    let per_slot = |values: &dyn Fn(usize, usize) -> f64| -> Vec<Series> {
        areas
            .iter()
            .enumerate()
            .map(|(k, &l)| Series {
                label: world.names[l].clone(),
                points: trace
                    .slot_times
                    .iter()
                    .enumerate()
                    .map(|(s, &t)| (day(t), offset(k) + values(l, s)))
                    .collect(),
                style: SeriesStyle::Step,
            })
            .collect()
    };
    let probability = per_slot(&|l, s| trace.probability[world.locations[l][0]][s]);
    let top_info = areas
        .iter()
        .flat_map(|&l| trace.information[l].iter().copied())
        .fold(0.0f64, f64::max)
        .max(1e-9);
    let information = per_slot(&|l, s| trace.information[l][s] / top_info);
    let visits = areas
        .iter()
        .enumerate()
        .map(|(k, &l)| Series {
            label: world.names[l].clone(),
            points: trace
                .visits
                .iter()
                .zip(&trace.slot_times)
                .filter(|(v, _)| **v == Some(l))
                .map(|(_, &t)| (day(t), offset(k) + 0.5))
                .collect(),
            style: SeriesStyle::Dots,
        })
        .collect();
    let panel = |title: &str, series: Vec<Series>, x_label: &str| Panel {
        title: title.into(),
        x_label: x_label.into(),
        y_label: String::new(),
        y_range: (-0.2, 4.2),
        series,
    };
    render_panels_png(
        &[
            panel(
                "True states s_i(t) of the three busiest areas (stacked)",
                truth,
                "",
            ),
            panel(
                "The robot's model p_i(t) when it planned each day (FreMEn, order chosen daily)",
                probability,
                "",
            ),
            panel(
                "Expected information I(L, t) of eq. (10) (scaled to the largest)",
                information,
                "",
            ),
            panel(
                &format!("Visits chosen by the Monte-Carlo strategy (e = {ratio})"),
                visits,
                "days since the start",
            ),
        ],
        path,
        1400,
        1200,
    )?;
    Ok(())
}
