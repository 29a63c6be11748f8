//! `chronomap events eval`: the experiment of [Krajník 2019] §V-D on event files (people detected
//! by a robot): MSE per cell of every model's expected counts on a spatio-temporal grid of
//! the test day, its reduction against the static map and a paired t-test; `chronomap
//! hypertime`: the Warped Hypertime intensity drawn as density maps (`chronomap_app::events`
//! runs and reports, this prints and draws).

use anyhow::{Result, bail};
use chronomap_app::events::{
    EventsJobError, EventsReport, Experiment, hypertime_maps, read_named_training, read_test_events,
};
use chronomap_hypertime::events::SpatialGrid;
use chronomap_hypertime::events::density::DensityMap;
use chronomap_plot::{MapImage, render_scaled_maps_png};

use crate::cli::{EventsEvalArgs, HypertimeArgs};
use crate::format::time;
use crate::outln;
use crate::output::{ProgressBar, print_json, usage};

pub fn eval(args: &EventsEvalArgs) -> Result<()> {
    let (train_names, train) = read_named_training(
        &args.train,
        args.train_before,
        "training detections (before --train-before?)",
    )?;
    let test_name = args.test.display().to_string();
    let test = read_test_events(&args.test, args.test_from)?;
    if test.is_empty() {
        bail!("{test_name}: no test detections (at or after --test-from?)");
    }
    let experiment = Experiment {
        train_name: &train_names,
        train: &train,
        test_name: &test_name,
        test: &test,
        gap_secs: args.gap,
        cells: &args.cells,
        bins: &args.bins,
    };
    let result = {
        let bar = ProgressBar::new();
        experiment.run(chronomap_core::Parallelism::Rayon(0), &bar)?
    };
    let report = EventsReport {
        experiment,
        result,
        train_files: args.train.iter().map(|p| p.display().to_string()).collect(),
        train_before: args.train_before,
        test_from: args.test_from,
    };
    if args.json {
        return print_json(&report.json());
    }
    Ok(outln!("{}", report.text())?)
}

/// `chronomap hypertime`: fit the Warped Hypertime event intensity and draw it.
pub fn hypertime(args: &HypertimeArgs) -> Result<()> {
    let (names, events) = read_named_training(
        &args.train,
        args.train_before,
        "detections (before --train-before?)",
    )?;
    let report = {
        let bar = ProgressBar::new();
        let maps = hypertime_maps(
            &names,
            &events,
            args.gap,
            args.components,
            args.cell,
            &args.at,
            &bar,
        );
        maps.map_err(|e| match e {
            EventsJobError::TooManyCells { .. } => usage(e.to_string()),
            e => e.into(),
        })?
    };
    if let Some(path) = &args.plot {
        plot_density(&report.maps, &report.space, path)?;
    }
    if args.json {
        return print_json(&report.json());
    }
    outln!("{}", report.text())?;
    if let Some(path) = &args.plot {
        outln!("wrote {}", path.display())?;
    }
    Ok(())
}

/// The density maps side by side, on one square-root colour scale (black = the largest value,
/// so that quiet places stay visible beside the busiest one).
fn plot_density(maps: &[DensityMap], space: &SpatialGrid, path: &std::path::Path) -> Result<()> {
    let max = maps
        .iter()
        .map(|m| m.max_per_m2_hour())
        .fold(0.0f64, f64::max)
        .max(f64::MIN_POSITIVE);
    let images: Vec<MapImage> = maps
        .iter()
        .map(|map| MapImage {
            title: format!("{} (max {:.1}/m²/h)", time(map.time), max),
            width: space.nx as u32,
            height: space.ny as u32,
            // Row 0 is the bottom (the smallest y), as the renderer draws maps.
            values: (0..space.ny)
                .flat_map(|r| (0..space.nx).map(move |c| (r, c)))
                .map(|(r, c)| (map.per_m2_hour[space.index(r, c)] / max).sqrt() as f32)
                .collect(),
        })
        .collect();
    let pixels = (480 / space.nx.max(space.ny).max(1)).clamp(1, 16) as u32;
    let quarter = format!("{:.1}/m²/h", max / 4.0);
    let legend = [("none", 0.0), (quarter.as_str(), 0.5), ("the maximum", 1.0)];
    render_scaled_maps_png(&images, path, pixels, &legend)?;
    Ok(())
}
