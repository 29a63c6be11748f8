//! `chronomap maps build`: the map manager of [Stüde 2024] §3.3 along a laser log
//! ([`chronomap_app_range::maps`] runs it and reports).

use anyhow::Result;
use chronomap_app_range::maps::{MapsReport, build_maps};
use chronomap_plot::plane::{PlaneLayer, PlanePlot, PlaneShape, render_plane_png};

use super::laser_log;
use crate::cli::MapsBuildArgs;
use crate::out;
use crate::output::{ProgressBar, print_json};

pub fn build(args: &MapsBuildArgs) -> Result<()> {
    let log = laser_log::read(&args.source)?;
    let report = build_maps(&log, &ProgressBar::new())?;
    if let Some(path) = &args.output {
        let text = serde_json::to_string_pretty(&report.graph)?;
        chronomap_io::write_data_file(path, text.as_bytes())?;
    }
    if let Some(path) = &args.plot {
        plot(&log, &report, path)?;
    }
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    Ok(out!("{}", report.text())?)
}

/// The odometry trajectory, one colour per map, with the doors passed.
fn plot(log: &laser_log::LaserLog, report: &MapsReport, path: &std::path::Path) -> Result<()> {
    let maps = report.map_of_scan.iter().max().map_or(0, |m| m + 1);
    let mut layers = Vec::new();
    for m in 0..maps {
        let points: Vec<[f64; 2]> = log
            .odometry
            .iter()
            .zip(&report.map_of_scan)
            .map(|(p, &k)| if k == m { [p[0], p[1]] } else { [f64::NAN; 2] })
            .collect();
        layers.push(PlaneLayer {
            label: format!("map {m}"),
            shape: PlaneShape::Path(points),
        });
    }
    let passages = &report.door_passages;
    if !passages.is_empty() {
        layers.push(PlaneLayer {
            label: "doors passed".into(),
            shape: PlaneShape::Segments(
                passages
                    .iter()
                    .map(|p| [p.door.left, p.door.right])
                    .collect(),
            ),
        });
    }
    let plot = PlanePlot {
        title: format!("{} maps along {}", maps, short_name(&log.name)),
        x_label: "x [m] (odometry)".into(),
        y_label: "y [m]".into(),
        equal_aspect: true,
        x_range: None,
        y_range: None,
        layers,
    };
    render_plane_png(&[plot], path, 1000, 800)?;
    Ok(())
}

/// The last component of a path, for titles.
pub fn short_name(name: &str) -> &str {
    name.rsplit('/').next().unwrap_or(name)
}
