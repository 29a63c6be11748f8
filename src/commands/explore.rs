//! `chronomap explore`: lifelong spatio-temporal exploration on a real dataset, every strategy
//! with every temporal model, beside the paper's table ([Santos 2017] §7).

use std::path::Path;

use anyhow::{Context, Result};
use chronomap_app::explore::{Behaviour, Dataset, behaviour as behaviour_of, load_world};
use chronomap_core::Parallelism;
use chronomap_explore::table::{
    ModelKind, PAPER_TABLE_1_ARUBA, PAPER_TABLE_2_BRAYFORD, SWEEP_SEEDS, exploration_sweep,
    explore_table, row_title,
};
use chronomap_explore::{ExploreConfig, Strategy, World};
use chronomap_plot::{Panel, Series, SeriesStyle, render_panels_png};
use serde_json::json;

use crate::cli::{DatasetArg, ExploreArgs};
use crate::format::{Table, time};
use crate::outln;
use crate::output::{ProgressBar, print_json};

fn dataset(arg: DatasetArg) -> Dataset {
    match arg {
        DatasetArg::Aruba => Dataset::Aruba,
        DatasetArg::Brayford => Dataset::Brayford,
    }
}

pub fn run(args: &ExploreArgs) -> Result<()> {
    let world = load_world(dataset(args.dataset), &args.data)
        .with_context(|| format!("cannot load the {:?} dataset", args.dataset))?;
    let config = ExploreConfig {
        ratio: args.ratio,
        days: args.days,
        seed: args.seed,
        ..ExploreConfig::default()
    };
    let results = {
        let bar = ProgressBar::new();
        explore_table(&world, &config, Parallelism::Rayon(0), &bar)?
    };
    let paper = match args.dataset {
        DatasetArg::Aruba => &PAPER_TABLE_1_ARUBA,
        DatasetArg::Brayford => &PAPER_TABLE_2_BRAYFORD,
    };
    let days = results[0].result.daily_error_percent.len();
    if args.json {
        print_json(&json!({
            "dataset": format!("{:?}", args.dataset).to_lowercase(),
            "ratio": args.ratio,
            "seed": args.seed,
            "days": days,
            "results": results.iter().map(|e| json!({
                "strategy": e.strategy.name(),
                "model": e.model.name(),
                "error_percent": e.result.error_percent,
                "explored_fraction": e.result.explored_fraction,
                "redirects": e.result.redirects,
            })).collect::<Vec<_>>(),
        }))?;
    } else {
        outln!(
            "{}: {} locations, {} days from {}, exploration ratio e = {}, 10-minute observations, seed {}",
            args.data.display(),
            world.locations.len(),
            days,
            time(world.start),
            args.ratio,
            args.seed
        )?;
        outln!(
            "Model error of eq. (2) [%], ours (paper{}):\n",
            if args.ratio == 0.5 {
                ", Table 1 / Table 2"
            } else {
                " at e = 0.5"
            }
        )?;
        let mut header = vec!["strategy".to_string()];
        header.extend(ModelKind::ALL.map(|m| m.column().to_string()));
        let mut t = Table::new(header);
        for (row, strategy) in Strategy::all().into_iter().enumerate() {
            let mut cells = vec![row_title(strategy).to_string()];
            for (col, model) in ModelKind::ALL.into_iter().enumerate() {
                let r = results
                    .iter()
                    .find(|e| e.strategy == strategy && e.model == model)
                    .map(|e| &e.result)
                    .context("missing result")?;
                cells.push(format!("{:4.1} ({:4.1})", r.error_percent, paper[row][col]));
            }
            t.row(cells);
        }
        outln!("{}", t.render())?;
        let best = results
            .iter()
            .min_by(|a, b| a.result.error_percent.total_cmp(&b.result.error_percent))
            .context("no results")?;
        outln!(
            "\nbest: {} + {} at {:.2} %; explored {:.1} % of the slots; novelty redirected {} slots",
            best.strategy.name(),
            best.model.name(),
            best.result.error_percent,
            100.0 * best.result.explored_fraction,
            results
                .iter()
                .filter(|e| matches!(e.strategy, Strategy::Novelty { .. })
                    && e.model == ModelKind::Fremen)
                .map(|e| e.result.redirects)
                .sum::<usize>()
        )?;
    }
    if let Some(path) = &args.plot_sweep {
        sweep(&world, args.seed, path)?;
        crate::errln!("wrote {}", path.display());
    }
    if let Some(path) = &args.plot_behaviour {
        behaviour(&world, args.ratio, args.seed, path)?;
        crate::errln!("wrote {}", path.display());
    }
    Ok(())
}

/// [Santos 2017] Fig. 5 ([`exploration_sweep`]) drawn into `path`.
pub fn sweep(world: &World, seed: u64, path: &Path) -> Result<()> {
    let curves = {
        let bar = ProgressBar::new();
        exploration_sweep(world, seed, Parallelism::Rayon(0), &bar)?
    };
    let series = curves
        .iter()
        .map(|curve| Series {
            label: if curve.model == ModelKind::Fremen {
                format!("{} + FreMEn", row_title(curve.strategy))
            } else {
                format!("{} + static (mean)", row_title(curve.strategy))
            },
            points: curve.points.clone(),
            style: SeriesStyle::Line,
        })
        .collect();
    let top = curves
        .iter()
        .flat_map(|c| c.points.iter().map(|p| p.1))
        .fold(0.0, f64::max)
        * 1.1;
    let panel = Panel {
        title: format!(
            "Model error after two weeks of exploration by exploration ratio ([Santos 2017] Fig. 5, mean of {SWEEP_SEEDS} seeds)"
        ),
        x_label: "exploration ratio e".into(),
        y_label: "model error [%]".into(),
        y_range: (0.0, top.max(1.0)),
        series,
    };
    render_panels_png(&[panel], path, 1200, 650)?;
    Ok(())
}

/// [Santos 2017] Fig. 6: the truth, the model, the expected information and the visits of three
/// areas over the first four days of FreMEn with the Monte-Carlo strategy.
pub fn behaviour(world: &World, ratio: f64, seed: u64, path: &Path) -> Result<()> {
    let Behaviour {
        result,
        areas,
        steps,
    } = behaviour_of(world, ratio, seed)?;
    let trace = &result.trace;
    let day = |t: f64| (t - world.start) / 86_400.0;
    let offset = |k: usize| 1.5 * (2 - k) as f64;
    // One series per area, stacked by its rank `k`.
    let per_area = |style: SeriesStyle, points: &dyn Fn(usize, usize) -> Vec<(f64, f64)>| {
        areas
            .iter()
            .enumerate()
            .map(|(k, &l)| Series {
                label: world.names[l].clone(),
                points: points(k, l),
                style,
            })
            .collect::<Vec<_>>()
    };
    let truth = per_area(SeriesStyle::Step, &|k, l| {
        (0..steps)
            .map(|s| {
                (
                    day(world.time(s)),
                    offset(k) + f64::from(world.truth[world.locations[l][0]][s]),
                )
            })
            .collect()
    });
    let per_slot = |values: &dyn Fn(usize, usize) -> f64| {
        per_area(SeriesStyle::Step, &|k, l| {
            trace
                .slot_times
                .iter()
                .enumerate()
                .map(|(s, &t)| (day(t), offset(k) + values(l, s)))
                .collect()
        })
    };
    let probability = per_slot(&|l, s| trace.probability[world.locations[l][0]][s]);
    let top_info = areas
        .iter()
        .flat_map(|&l| trace.information[l].iter().copied())
        .fold(0.0f64, f64::max)
        .max(1e-9);
    let information = per_slot(&|l, s| trace.information[l][s] / top_info);
    let visits = per_area(SeriesStyle::Dots, &|k, l| {
        trace
            .visits
            .iter()
            .zip(&trace.slot_times)
            .filter(|(v, _)| **v == Some(l))
            .map(|(_, &t)| (day(t), offset(k) + 0.5))
            .collect()
    });
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
