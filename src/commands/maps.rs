//! `chronomap maps build`: the map manager of the dissertation's §3.3 along a laser log.

use anyhow::{Context, Result, anyhow};
use chronomap_multimap::door::DoorPassage;
use chronomap_multimap::mapper::{Mapper, MapperParams};
use chronomap_multimap::se2::Pose2;
use chronomap_plot::plane::{PlaneLayer, PlanePlot, PlaneShape, render_plane_png};
use serde_json::json;

use super::laser_log;
use crate::cli::MapsBuildArgs;
use crate::format::Table;
use crate::outln;
use crate::output::{ProgressBar, print_json};

pub fn build(args: &MapsBuildArgs) -> Result<()> {
    let log = laser_log::read(&args.source)?;
    let mut mapper = Mapper::new(MapperParams::default())?;
    let increments = log.increments();
    let bar = ProgressBar::stage("door passages", log.scans.len() as u64);
    let mut passages: Vec<DoorPassage> = Vec::new();
    let mut map_of_scan = Vec::with_capacity(log.scans.len());
    let mut sides = 0;
    for (k, (scan, inc)) in log.scans.iter().zip(&increments).enumerate() {
        let increment = Pose2::new(inc[0], inc[1], inc[2])
            .with_context(|| format!("{}: odometry at scan {}", log.name, k + 1))?;
        let report = mapper
            .step(scan, &increment)
            .with_context(|| format!("{}: scan {}", log.name, k + 1))?;
        let pose = mapper.pose();
        if !pose.is_finite() {
            return Err(anyhow!(
                "{}: scan {}: the robot's pose or its covariance is no longer finite (odometry \
                 increment ({}, {}, {}))",
                log.name,
                k + 1,
                inc[0],
                inc[1],
                inc[2]
            ));
        }
        sides += usize::from(!report.detector.front.is_empty());
        passages.extend(report.passage);
        map_of_scan.push(mapper.current_map());
        chronomap_core::progress::Progress::advance(&bar, 1);
    }
    drop(bar);
    let graph = mapper.graph();
    if let Some(path) = &args.output {
        let text = serde_json::to_string_pretty(graph)?;
        chronomap_io::write_data_file(path, text.as_bytes())?;
    }
    if let Some(path) = &args.plot {
        plot(&log, &map_of_scan, &passages, path)?;
    }
    let pose = mapper.pose();
    if args.json {
        return print_json(&json!({
            "log": log.name,
            "scans": log.scans.len(),
            "door_passages": passages,
            "scans_with_a_door_ahead": sides,
            "graph": graph,
            "current_map": mapper.current_map(),
            "pose_in_current_map": pose,
        }));
    }
    outln!(
        "{}: {} scans, {} door passage(s), {} map(s), {} link point(s), {} link-point candidate(s)",
        log.name,
        log.scans.len(),
        passages.len(),
        graph.maps().len(),
        graph.links().len(),
        graph.candidates().len()
    )?;
    outln!("scans with door posts ahead (criterion C1): {sides}")?;
    let mut table = Table::new(["map", "configuration", "bounding box (m)", "scans"]);
    for (i, map) in graph.maps().iter().enumerate() {
        let size = map.bbox.map_or("-".to_string(), |b| {
            format!("{:.1} × {:.1}", b.width(), b.height())
        });
        let scans = map_of_scan.iter().filter(|&&m| m == i).count();
        table.row([
            i.to_string(),
            format!("{:?}", map.config),
            size,
            scans.to_string(),
        ]);
    }
    outln!("{}", table.render().trim_end())?;
    for p in &passages {
        outln!(
            "door passage at t = {:.2} s (scan {}): door {:.2} m wide at ({:.2}, {:.2}), criteria C1 {} C2 {} C3 {}",
            p.time,
            p.step + 1,
            p.door.width(),
            p.door.center()[0],
            p.door.center()[1],
            p.criteria[0],
            p.criteria[1],
            p.criteria[2]
        )?;
    }
    // A variance that is not a finite non-negative number is said so, never printed as 0.
    let sd = |v: f64, scale: f64, unit: &str, digits: usize| {
        if v.is_finite() && v >= 0.0 {
            format!("{:.digits$} {unit}", scale * v.sqrt())
        } else {
            format!("{v} (not a variance)")
        }
    };
    outln!(
        "robot in map {} at ({:.2}, {:.2}, {:.1}°), σ = ({}, {}, {})",
        mapper.current_map(),
        pose.mean.x,
        pose.mean.y,
        pose.mean.theta.to_degrees(),
        sd(pose.cov[0][0], 1.0, "m", 2),
        sd(pose.cov[1][1], 1.0, "m", 2),
        sd(pose.cov[2][2], 1f64.to_degrees(), "°", 1).replace(" °", "°")
    )?;
    Ok(())
}

/// The odometry trajectory, one colour per map, with the doors passed.
fn plot(
    log: &laser_log::LaserLog,
    map_of_scan: &[usize],
    passages: &[DoorPassage],
    path: &std::path::Path,
) -> Result<()> {
    let maps = map_of_scan.iter().max().map_or(0, |m| m + 1);
    let mut layers = Vec::new();
    for m in 0..maps {
        let points: Vec<[f64; 2]> = log
            .odometry
            .iter()
            .zip(map_of_scan)
            .map(|(p, &k)| if k == m { [p[0], p[1]] } else { [f64::NAN; 2] })
            .collect();
        layers.push(PlaneLayer {
            label: format!("map {m}"),
            shape: PlaneShape::Path(points),
        });
    }
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
