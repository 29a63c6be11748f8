//! `chronomap explore`: lifelong spatio-temporal exploration on a real dataset, every strategy
//! with every temporal model, beside the paper's table ([Santos 2017] §7). The jobs, reports
//! and figures are `chronomap_app::explore`; this file translates flags, prints and draws.

use anyhow::{Context, Result};
use chronomap_app::explore::{Dataset, behaviour_panels, explore_report, load_world, sweep_panel};
use chronomap_plot::render_panels_png;

use crate::cli::{DatasetArg, ExploreArgs};
use crate::output::{ProgressBar, print_json};
use crate::{errln, out};

fn dataset(arg: DatasetArg) -> Dataset {
    match arg {
        DatasetArg::Aruba => Dataset::Aruba,
        DatasetArg::Brayford => Dataset::Brayford,
    }
}

pub fn run(args: &ExploreArgs) -> Result<()> {
    let set = dataset(args.dataset);
    let world = load_world(set, &args.data)
        .with_context(|| format!("cannot load the {:?} dataset", args.dataset))?;
    let report = explore_report(
        (set, &args.data, &world),
        args.ratio,
        args.days,
        args.seed,
        &ProgressBar::new(),
    )?;
    if args.json {
        print_json(&report.json())?;
    } else {
        out!("{report}")?;
    }
    if let Some(path) = &args.plot_sweep {
        let panel = sweep_panel(&world, args.seed, &ProgressBar::new())?;
        render_panels_png(&[panel], path, 1200, 650)?;
        errln!("wrote {}", path.display());
    }
    if let Some(path) = &args.plot_behaviour {
        let panels = behaviour_panels(&world, args.ratio, args.seed)?;
        render_panels_png(&panels, path, 1400, 1200)?;
        errln!("wrote {}", path.display());
    }
    Ok(())
}
