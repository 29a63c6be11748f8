//! Plots in the plane: robot trajectories, the pairs of poses a loop-closure detector links,
//! and ROC curves — anything whose two axes are coordinates rather than time.
//!
//! ```no_run
//! use std::path::Path;
//! use chronomap_plot::plane::{render_plane_png, PlaneLayer, PlanePlot, PlaneShape};
//!
//! let square = vec![[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0], [0.2, 0.1]];
//! let plot = PlanePlot {
//!     title: "Trajectory and loops".into(),
//!     x_label: "x [m]".into(),
//!     y_label: "y [m]".into(),
//!     equal_aspect: true,
//!     x_range: None,
//!     y_range: None,
//!     layers: vec![
//!         PlaneLayer { label: "path".into(), shape: PlaneShape::Path(square) },
//!         PlaneLayer {
//!             label: "loop".into(),
//!             shape: PlaneShape::Segments(vec![[[0.0, 0.0], [0.2, 0.1]]]),
//!         },
//!     ],
//! };
//! render_plane_png(&[plot], Path::new("loops.png"), 900, 700)?;
//! # Ok::<(), chronomap_plot::PlotError>(())
//! ```

use std::ops::Range;
use std::path::Path;

use plotters::prelude::*;

use crate::{
    LegendEntry, PALETTE, PlotError, PlotErrorKind, Scale, SeriesStyle, check_size, draw_legend,
    draw_png, drawing, ensure_font, format_tick,
};

/// What a layer draws.
#[derive(Clone, Debug, PartialEq)]
pub enum PlaneShape {
    /// A polyline through the points in order (a trajectory, a ROC curve). Points with a
    /// non-finite coordinate break the line.
    Path(Vec<[f64; 2]>),
    /// Unconnected dots (keyframes, detections).
    Points(Vec<[f64; 2]>),
    /// Separate segments from one point to another (the two poses of a loop closure).
    Segments(Vec<[[f64; 2]; 2]>),
}

impl PlaneShape {
    fn points(&self) -> Box<dyn Iterator<Item = [f64; 2]> + '_> {
        match self {
            PlaneShape::Path(p) | PlaneShape::Points(p) => Box::new(p.iter().copied()),
            PlaneShape::Segments(s) => Box::new(s.iter().flat_map(|[a, b]| [*a, *b])),
        }
    }

    fn legend_style(&self) -> SeriesStyle {
        match self {
            PlaneShape::Points(_) => SeriesStyle::Dots,
            _ => SeriesStyle::Line,
        }
    }
}

/// One labelled layer; colours follow [`PALETTE`] in layer order.
#[derive(Clone, Debug, PartialEq)]
pub struct PlaneLayer {
    /// Legend text (empty: not in the legend).
    pub label: String,
    /// What to draw.
    pub shape: PlaneShape,
}

/// One chart in the plane.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanePlot {
    /// Title above the chart.
    pub title: String,
    /// Label of the `x` axis.
    pub x_label: String,
    /// Label of the `y` axis.
    pub y_label: String,
    /// One metre is as long across as up (maps, trajectories); the ranges are widened to keep
    /// it.
    pub equal_aspect: bool,
    /// Visible `x` range; `None`: the data's, with a margin.
    pub x_range: Option<(f64, f64)>,
    /// Visible `y` range; `None`: the data's, with a margin.
    pub y_range: Option<(f64, f64)>,
    /// Layers, drawn in order (later ones on top).
    pub layers: Vec<PlaneLayer>,
}

/// Renders plots side by side, each with its legend below the chart.
///
/// # Errors
/// A [`PlotError`] naming `path`: no plots, a plot without finite points, an invalid range
/// or size, or a drawing/writing failure.
pub fn render_plane_png(
    plots: &[PlanePlot],
    path: &Path,
    width: u32,
    height: u32,
) -> Result<(), PlotError> {
    render(plots, path, width, height).map_err(|kind| PlotError::new(path, kind))
}

/// The smallest and largest finite coordinate along `axis` of every layer.
fn data_range(plot: &PlanePlot, axis: usize) -> Option<(f64, f64)> {
    plot.layers
        .iter()
        .flat_map(|l| l.shape.points())
        .filter(|p| p[0].is_finite() && p[1].is_finite())
        .map(|p| p[axis])
        .fold(None, |r, v| {
            Some(r.map_or((v, v), |(lo, hi): (f64, f64)| (lo.min(v), hi.max(v))))
        })
}

/// `(lo, hi)` widened by 5 % on each side (by 1 if it is a single value).
fn padded((lo, hi): (f64, f64)) -> (f64, f64) {
    let pad = if hi > lo { 0.05 * (hi - lo) } else { 1.0 };
    (lo - pad, hi + pad)
}

fn check_range(plot: usize, title: &str, (lo, hi): (f64, f64)) -> Result<(), PlotErrorKind> {
    if lo.is_finite() && hi.is_finite() && lo < hi {
        Ok(())
    } else {
        Err(PlotErrorKind::InvalidYRange {
            panel: plot,
            title: title.to_owned(),
            low: lo,
            high: hi,
        })
    }
}

/// The ranges of one plot: given or padded data ranges, widened for an equal aspect ratio in
/// a chart of `width × height` pixels.
fn ranges(
    index: usize,
    plot: &PlanePlot,
    width: f64,
    height: f64,
) -> Result<(Range<f64>, Range<f64>), PlotErrorKind> {
    let x = match plot.x_range {
        Some(r) => r,
        None => padded(data_range(plot, 0).ok_or(PlotErrorKind::NoData)?),
    };
    let y = match plot.y_range {
        Some(r) => r,
        None => padded(data_range(plot, 1).ok_or(PlotErrorKind::NoData)?),
    };
    check_range(index, &plot.title, x)?;
    check_range(index, &plot.title, y)?;
    let (mut x, mut y) = (x, y);
    if plot.equal_aspect && width > 0.0 && height > 0.0 {
        // Metres per pixel along each axis; widen the tighter one to the looser.
        let (sx, sy) = ((x.1 - x.0) / width, (y.1 - y.0) / height);
        if sx > sy {
            let grow = (sx * height - (y.1 - y.0)) / 2.0;
            y = (y.0 - grow, y.1 + grow);
        } else {
            let grow = (sy * width - (x.1 - x.0)) / 2.0;
            x = (x.0 - grow, x.1 + grow);
        }
    }
    Ok((x.0..x.1, y.0..y.1))
}

fn render(plots: &[PlanePlot], path: &Path, width: u32, height: u32) -> Result<(), PlotErrorKind> {
    if plots.is_empty() {
        return Err(PlotErrorKind::NoPanels);
    }
    check_size(width, height, 200)?;
    ensure_font()?;
    let scale = Scale::for_width(width / plots.len() as u32);
    draw_png(path, (width, height), |root| {
        root.fill(&WHITE).map_err(drawing)?;
        for (index, (plot, area)) in plots
            .iter()
            .zip(root.split_evenly((1, plots.len())))
            .enumerate()
        {
            let legend_rows = plot.layers.iter().filter(|l| !l.label.is_empty()).count() as u32;
            let legend_height = if legend_rows == 0 {
                0
            } else {
                scale.px(22.0) * legend_rows + scale.px(56.0)
            };
            let (_, area_height) = area.dim_in_pixel();
            let (chart_area, legend_area) =
                area.split_vertically(area_height.saturating_sub(legend_height).max(1));
            let (cw, ch) = chart_area.dim_in_pixel();
            // The plotting area is the chart less its labels and margins (approximately).
            let inner_w = f64::from(cw) - f64::from(scale.px(90.0));
            let inner_h = f64::from(ch) - f64::from(scale.px(100.0));
            let (xr, yr) = ranges(index, plot, inner_w, inner_h)?;
            let mut chart = ChartBuilder::on(&chart_area)
                .caption(&plot.title, scale.font(20.0))
                .margin(scale.px(10.0))
                .x_label_area_size(scale.px(48.0))
                .y_label_area_size(scale.px(70.0))
                .build_cartesian_2d(xr, yr)
                .map_err(drawing)?;
            chart
                .configure_mesh()
                .x_desc(plot.x_label.as_str())
                .y_desc(plot.y_label.as_str())
                .axis_desc_style(scale.font(16.0))
                .label_style(scale.font(14.0))
                .x_label_formatter(&|v| format_tick(*v))
                .y_label_formatter(&|v| format_tick(*v))
                .bold_line_style(RGBColor(225, 225, 225))
                .light_line_style(WHITE)
                .draw()
                .map_err(drawing)?;
            let line = scale.px(2.0).max(1);
            for (i, layer) in plot.layers.iter().enumerate() {
                let colour = PALETTE[i % PALETTE.len()];
                let finite = |p: &[f64; 2]| p[0].is_finite() && p[1].is_finite();
                match &layer.shape {
                    PlaneShape::Path(points) => {
                        for run in points.split(|p| !finite(p)).filter(|r| r.len() > 1) {
                            chart
                                .draw_series(std::iter::once(PathElement::new(
                                    run.iter().map(|p| (p[0], p[1])).collect::<Vec<_>>(),
                                    colour.stroke_width(line),
                                )))
                                .map_err(drawing)?;
                        }
                    }
                    PlaneShape::Points(points) => {
                        let radius = scale.px(2.0).max(1);
                        chart
                            .draw_series(
                                points
                                    .iter()
                                    .filter(|p| finite(p))
                                    .map(|p| Circle::new((p[0], p[1]), radius, colour.filled())),
                            )
                            .map_err(drawing)?;
                    }
                    PlaneShape::Segments(segments) => {
                        chart
                            .draw_series(
                                segments.iter().filter(|[a, b]| finite(a) && finite(b)).map(
                                    |[a, b]| {
                                        PathElement::new(
                                            vec![(a[0], a[1]), (b[0], b[1])],
                                            colour.stroke_width(line),
                                        )
                                    },
                                ),
                            )
                            .map_err(drawing)?;
                    }
                }
            }
            let entries: Vec<LegendEntry> = plot
                .layers
                .iter()
                .enumerate()
                .filter(|(_, l)| !l.label.is_empty())
                .map(|(i, l)| LegendEntry {
                    label: &l.label,
                    color: PALETTE[i % PALETTE.len()],
                    style: l.shape.legend_style(),
                })
                .collect();
            if !entries.is_empty() {
                draw_legend(&legend_area, &entries, scale)?;
            }
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plot(layers: Vec<PlaneLayer>) -> PlanePlot {
        PlanePlot {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            equal_aspect: true,
            x_range: None,
            y_range: None,
            layers,
        }
    }

    #[test]
    fn equal_aspect_widens_the_tighter_axis() {
        let p = plot(vec![PlaneLayer {
            label: String::new(),
            shape: PlaneShape::Path(vec![[0.0, 0.0], [10.0, 1.0]]),
        }]);
        let (x, y) = ranges(0, &p, 1000.0, 500.0).unwrap();
        // x: 0..10 padded to -0.5..10.5 (11 m over 1000 px); y grows to 5.5 m over 500 px.
        assert!((x.end - x.start - 11.0).abs() < 1e-12);
        assert!((y.end - y.start - 5.5).abs() < 1e-12);
        assert!(((y.start + y.end) / 2.0 - 0.5).abs() < 1e-12);
    }

    #[test]
    fn no_finite_point_or_a_bad_range_is_an_error() {
        let p = plot(vec![PlaneLayer {
            label: "a".into(),
            shape: PlaneShape::Points(vec![[f64::NAN, 0.0]]),
        }]);
        assert!(matches!(
            ranges(0, &p, 100.0, 100.0),
            Err(PlotErrorKind::NoData)
        ));
        let mut q = plot(vec![PlaneLayer {
            label: "a".into(),
            shape: PlaneShape::Points(vec![[0.0, 0.0]]),
        }]);
        q.x_range = Some((1.0, 1.0));
        assert!(matches!(
            ranges(0, &q, 100.0, 100.0),
            Err(PlotErrorKind::InvalidYRange { .. })
        ));
    }

    #[test]
    fn a_trajectory_with_loops_is_written() {
        let dir = std::env::temp_dir().join(format!("chronomap-plane-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("loops.png");
        let p = plot(vec![
            PlaneLayer {
                label: "path".into(),
                shape: PlaneShape::Path(vec![[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.1, 0.2]]),
            },
            PlaneLayer {
                label: "loop".into(),
                shape: PlaneShape::Segments(vec![[[0.0, 0.0], [0.1, 0.2]]]),
            },
        ]);
        render_plane_png(&[p.clone(), p], &file, 800, 400).unwrap();
        let bytes = std::fs::read(&file).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
