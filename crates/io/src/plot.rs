//! PNG plots: observations and predictions over time, and amplitude spectra.
//!
//! Plain data in, a PNG file out. Text is drawn with an embedded DejaVu Sans font (see
//! `assets/fonts/LICENSE-DejaVu.txt`), so no system fonts or fontconfig are needed.
//!
//! ```no_run
//! use std::path::Path;
//! use chronomap_io::plot::{render_panels_png, Panel, Series, SeriesStyle};
//!
//! let hours: Vec<f64> = (0..=7 * 24).map(f64::from).collect();
//! let observed: Vec<(f64, f64)> =
//!     hours.iter().map(|&h| (h, f64::from(((h % 24.0) >= 8.0 && (h % 24.0) < 18.0) as u8))).collect();
//! let panel = Panel {
//!     title: "Office door".into(),
//!     x_label: "time [h]".into(),
//!     y_label: "p(open)".into(),
//!     y_range: (-0.05, 1.05),
//!     series: vec![Series { label: "observed".into(), points: observed, style: SeriesStyle::Step }],
//! };
//! render_panels_png(&[panel], Path::new("door.png"), 1200, 400)?;
//! # Ok::<(), chronomap_io::plot::PlotError>(())
//! ```

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use thiserror::Error;

/// DejaVu Sans (Bitstream Vera license, see `assets/fonts/LICENSE-DejaVu.txt`).
static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

/// Font family name under which [`FONT`] is registered.
const FAMILY: &str = "sans-serif";

/// Smallest and largest accepted image side in pixels.
pub const SIZE_RANGE: (u32, u32) = (200, 8192);

/// Colours of the series, in order (Okabe–Ito palette, readable with colour blindness).
pub const PALETTE: [RGBColor; 7] = [
    RGBColor(0, 114, 178),   // blue
    RGBColor(213, 94, 0),    // vermillion
    RGBColor(0, 158, 115),   // bluish green
    RGBColor(204, 121, 167), // reddish purple
    RGBColor(230, 159, 0),   // orange
    RGBColor(86, 180, 233),  // sky blue
    RGBColor(0, 0, 0),       // black
];

const GRID: RGBColor = RGBColor(225, 225, 225);
const CANDIDATE: RGBColor = RGBColor(150, 150, 150);

/// How a [`Series`] is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SeriesStyle {
    /// Points joined by straight lines (e.g. a prediction `p(t)`).
    Line,
    /// A staircase: each value holds until the next point (e.g. binary observations).
    Step,
    /// Unconnected dots (e.g. sparse observations).
    Dots,
}

/// One labelled series of `(x, y)` points. Points with a non-finite coordinate are skipped
/// (lines are broken there).
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// The points, in increasing `x` for [`SeriesStyle::Line`] and [`SeriesStyle::Step`].
    pub points: Vec<(f64, f64)>,
    /// How to draw it.
    pub style: SeriesStyle,
}

/// One chart of a figure: title, axis labels, the `y` range and the series.
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    /// Title above the chart.
    pub title: String,
    /// Label of the `x` axis (empty: none).
    pub x_label: String,
    /// Label of the `y` axis (empty: none).
    pub y_label: String,
    /// Visible `y` range `(low, high)`, `low < high`.
    pub y_range: (f64, f64),
    /// The series; colours follow [`PALETTE`] in order.
    pub series: Vec<Series>,
}

/// One bar of an amplitude spectrum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpectrumBar {
    /// Period of the component in hours (> 0).
    pub period_hours: f64,
    /// Amplitude of the component (>= 0).
    pub amplitude: f64,
    /// Whether the model uses this component (drawn highlighted and labelled).
    pub chosen: bool,
}

/// What went wrong while plotting.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum PlotErrorKind {
    /// The image size is outside [`SIZE_RANGE`], or too small for the number of panels.
    #[error("image size {width}x{height} is not supported ({reason})")]
    InvalidSize {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
        /// Why.
        reason: String,
    },
    /// No panel was given.
    #[error("nothing to plot: no panels")]
    NoPanels,
    /// A panel's `y` range is empty or not finite.
    #[error(
        "panel {panel} ({title:?}): y range ({low}, {high}) is not a finite range with low < high"
    )]
    InvalidYRange {
        /// 0-based index of the panel.
        panel: usize,
        /// Its title.
        title: String,
        /// Lower end.
        low: f64,
        /// Upper end.
        high: f64,
    },
    /// No series has a finite point, or no spectrum bar was given.
    #[error("nothing to plot: no finite data points")]
    NoData,
    /// A spectrum bar has a non-positive or non-finite period or a negative or non-finite
    /// amplitude.
    #[error(
        "spectrum bar {index}: period {period_hours} h and amplitude {amplitude} must be finite, period > 0, amplitude >= 0"
    )]
    InvalidBar {
        /// 0-based index of the bar.
        index: usize,
        /// Its period.
        period_hours: f64,
        /// Its amplitude.
        amplitude: f64,
    },
    /// The embedded font could not be loaded.
    #[error("the embedded font could not be loaded")]
    Font,
    /// Drawing or writing the image failed.
    #[error("cannot draw or write the image: {reason}")]
    Drawing {
        /// The message of the drawing library.
        reason: String,
    },
}

/// Why a plot could not be rendered; names the output file.
#[derive(Debug, Error)]
#[error("{}: {kind}", .path.display())]
pub struct PlotError {
    path: PathBuf,
    kind: PlotErrorKind,
}

impl PlotError {
    fn new(path: &Path, kind: PlotErrorKind) -> Self {
        PlotError {
            path: path.to_owned(),
            kind,
        }
    }

    /// The output file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What went wrong.
    pub fn kind(&self) -> &PlotErrorKind {
        &self.kind
    }
}

/// Registers the embedded font once per process.
fn ensure_font() -> Result<(), PlotErrorKind> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok { Ok(()) } else { Err(PlotErrorKind::Font) }
}

fn drawing<E: fmt::Debug + std::error::Error>(e: E) -> PlotErrorKind {
    PlotErrorKind::Drawing {
        reason: e.to_string(),
    }
}

fn check_size(width: u32, height: u32, min_height: u32) -> Result<(), PlotErrorKind> {
    let (lo, hi) = SIZE_RANGE;
    let reason = if !(lo..=hi).contains(&width) || !(lo..=hi).contains(&height) {
        format!("each side must be {lo} to {hi} pixels")
    } else if height < min_height {
        format!("at least {min_height} pixels of height are needed")
    } else {
        return Ok(());
    };
    Err(PlotErrorKind::InvalidSize {
        width,
        height,
        reason,
    })
}

/// Sizes of text and margins for an image of the given width.
#[derive(Clone, Copy)]
struct Scale(f64);

impl Scale {
    fn for_width(width: u32) -> Self {
        Scale((f64::from(width) / 1100.0).clamp(0.9, 2.5))
    }

    fn px(self, base: f64) -> u32 {
        (base * self.0).round() as u32
    }

    fn font(self, base: f64) -> TextStyle<'static> {
        (FAMILY, base * self.0).into_font().color(&BLACK)
    }
}

/// Renders panels stacked vertically that share the `x` range (the range of all finite
/// points of all panels), each with its legend to the right of the chart.
///
/// Typical use: one week of observations with the predictions `p(t)` of several models, one
/// panel per model (like Fig. 3 of the FreMEn paper).
///
/// # Errors
/// A [`PlotError`] naming `path`: invalid size or `y` range, no data, or a drawing/writing
/// failure (e.g. the directory does not exist).
pub fn render_panels_png(
    panels: &[Panel],
    path: &Path,
    width: u32,
    height: u32,
) -> Result<(), PlotError> {
    render_panels(panels, path, width, height).map_err(|kind| PlotError::new(path, kind))
}

fn render_panels(
    panels: &[Panel],
    path: &Path,
    width: u32,
    height: u32,
) -> Result<(), PlotErrorKind> {
    if panels.is_empty() {
        return Err(PlotErrorKind::NoPanels);
    }
    check_size(width, height, 120 * panels.len() as u32)?;
    for (index, panel) in panels.iter().enumerate() {
        let (low, high) = panel.y_range;
        if !(low.is_finite() && high.is_finite() && low < high) {
            return Err(PlotErrorKind::InvalidYRange {
                panel: index,
                title: panel.title.clone(),
                low,
                high,
            });
        }
    }
    let x_range = x_range(panels).ok_or(PlotErrorKind::NoData)?;
    ensure_font()?;

    let scale = Scale::for_width(width);
    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(drawing)?;
    let legend_width =
        legend_width(&root, scale, panels.iter().flat_map(|p| &p.series)).min(width * 2 / 5);
    for (panel, area) in panels.iter().zip(root.split_evenly((panels.len(), 1))) {
        let (chart_area, legend_area) = area.split_horizontally(width - legend_width);
        draw_panel(panel, &chart_area, x_range.clone(), scale)?;
        let entries: Vec<LegendEntry> = panel
            .series
            .iter()
            .enumerate()
            .map(|(i, s)| LegendEntry {
                label: &s.label,
                color: PALETTE[i % PALETTE.len()],
                style: s.style,
            })
            .collect();
        draw_legend(&legend_area, &entries, scale)?;
    }
    root.present().map_err(drawing)
}

/// Smallest and largest finite `x` of all panels (widened if they are equal).
fn x_range(panels: &[Panel]) -> Option<Range<f64>> {
    let mut range: Option<(f64, f64)> = None;
    for &(x, y) in panels
        .iter()
        .flat_map(|p| &p.series)
        .flat_map(|s| &s.points)
    {
        if x.is_finite() && y.is_finite() {
            range = Some(range.map_or((x, x), |(lo, hi)| (lo.min(x), hi.max(x))));
        }
    }
    let (lo, hi) = range?;
    if lo < hi {
        Some(lo..hi)
    } else {
        let pad = if lo == 0.0 { 1.0 } else { lo.abs() * 1e-3 };
        Some(lo - pad..hi + pad)
    }
}

fn draw_panel(
    panel: &Panel,
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    x_range: Range<f64>,
    scale: Scale,
) -> Result<(), PlotErrorKind> {
    let (y_low, y_high) = panel.y_range;
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, scale.font(20.0))
        .margin(scale.px(10.0))
        .x_label_area_size(scale.px(if panel.x_label.is_empty() { 28.0 } else { 48.0 }))
        .y_label_area_size(scale.px(if panel.y_label.is_empty() { 48.0 } else { 70.0 }))
        .build_cartesian_2d(x_range, y_low..y_high)
        .map_err(drawing)?;
    chart
        .configure_mesh()
        .x_desc(panel.x_label.as_str())
        .y_desc(panel.y_label.as_str())
        .axis_desc_style(scale.font(16.0))
        .label_style(scale.font(14.0))
        .x_labels(10)
        .y_labels(6)
        .x_label_formatter(&|x| format_tick(*x))
        .y_label_formatter(&|y| format_tick(*y))
        .bold_line_style(GRID)
        .light_line_style(WHITE)
        .draw()
        .map_err(drawing)?;
    let line_width = scale.px(2.0).max(1);
    let base = area.get_base_pixel();
    for (i, series) in panel.series.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        match series.style {
            SeriesStyle::Line | SeriesStyle::Step => {
                for run in finite_runs(&series.points) {
                    let run = if series.style == SeriesStyle::Step {
                        steps(run)
                    } else {
                        run.to_vec()
                    };
                    for part in clip_to_y(&run, y_low, y_high) {
                        // Thick polylines are drawn segment by segment in pixel space: whole
                        // paths get miter spikes at reversals and at repeated pixels.
                        let pixels = dedup_pixels(part.iter().map(|p| {
                            let (x, y) = chart.as_coord_spec().translate(p);
                            (x - base.0, y - base.1)
                        }));
                        let style = color.stroke_width(line_width);
                        let segments: Vec<_> = if pixels.len() == 1 {
                            vec![PathElement::new(vec![pixels[0], pixels[0]], style)]
                        } else {
                            pixels
                                .windows(2)
                                .map(|w| PathElement::new(vec![w[0], w[1]], style))
                                .collect()
                        };
                        for segment in &segments {
                            area.draw(segment).map_err(drawing)?;
                        }
                    }
                }
            }
            SeriesStyle::Dots => {
                let radius = scale.px(2.0).max(1);
                chart
                    .draw_series(
                        series
                            .points
                            .iter()
                            .filter(|(x, y)| x.is_finite() && (y_low..=y_high).contains(y))
                            .map(|&p| Circle::new(p, radius, color.filled())),
                    )
                    .map_err(drawing)?;
            }
        }
    }
    Ok(())
}

/// Pixels with consecutive repetitions removed.
fn dedup_pixels(pixels: impl Iterator<Item = (i32, i32)>) -> Vec<(i32, i32)> {
    let mut out: Vec<(i32, i32)> = Vec::new();
    for p in pixels {
        if out.last() != Some(&p) {
            out.push(p);
        }
    }
    out
}

/// The parts of a polyline with `y_low <= y <= y_high`; segments that cross a border are cut
/// at it, so lines leaving the range end at the border instead of running along it.
fn clip_to_y(points: &[(f64, f64)], y_low: f64, y_high: f64) -> Vec<Vec<(f64, f64)>> {
    let mut parts = Vec::new();
    if let [only] = points {
        if (y_low..=y_high).contains(&only.1) {
            parts.push(vec![*only]);
        }
        return parts;
    }
    let mut current: Vec<(f64, f64)> = Vec::new();
    for pair in points.windows(2) {
        match clip_segment(pair[0], pair[1], y_low, y_high) {
            Some((a, b)) => {
                if current.last() != Some(&a) {
                    if !current.is_empty() {
                        parts.push(std::mem::take(&mut current));
                    }
                    current.push(a);
                }
                current.push(b);
            }
            None => {
                if !current.is_empty() {
                    parts.push(std::mem::take(&mut current));
                }
            }
        }
    }
    if !current.is_empty() {
        parts.push(current);
    }
    parts
}

/// The part of segment `a`–`b` with `y_low <= y <= y_high`, if any.
fn clip_segment(
    a: (f64, f64),
    b: (f64, f64),
    y_low: f64,
    y_high: f64,
) -> Option<((f64, f64), (f64, f64))> {
    let dy = b.1 - a.1;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    if dy == 0.0 {
        if !(y_low..=y_high).contains(&a.1) {
            return None;
        }
    } else {
        let (ta, tb) = ((y_low - a.1) / dy, (y_high - a.1) / dy);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
        if t0 > t1 {
            return None;
        }
    }
    let at = |t: f64| {
        if t == 0.0 {
            a
        } else if t == 1.0 {
            b
        } else {
            (a.0 + t * (b.0 - a.0), (a.1 + t * dy).clamp(y_low, y_high))
        }
    };
    Some((at(t0), at(t1)))
}

/// Maximal runs of consecutive points with finite coordinates.
fn finite_runs(points: &[(f64, f64)]) -> impl Iterator<Item = &[(f64, f64)]> {
    points
        .split(|(x, y)| !(x.is_finite() && y.is_finite()))
        .filter(|run| !run.is_empty())
}

/// A staircase through `points`: each `y` holds until the next `x`.
fn steps(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(points.len() * 2);
    for pair in points.windows(2) {
        let ((x0, y0), (x1, _)) = (pair[0], pair[1]);
        out.push((x0, y0));
        out.push((x1, y0));
    }
    if let Some(&last) = points.last() {
        out.push(last);
    }
    out
}

/// Tick label: integers without decimals, others with about 4 significant digits (at most
/// one decimal from 100 on); scientific notation below 0.001 and from 10^12 on.
fn format_tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let magnitude = v.abs();
    if !(1e-3..1e12).contains(&magnitude) {
        return format!("{v:.3e}");
    }
    let decimals = if magnitude >= 100.0 {
        1
    } else {
        (3 - magnitude.log10().floor() as i32).clamp(1, 6) as usize
    };
    let text = format!("{v:.decimals$}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".into()
    } else {
        text.into()
    }
}

struct LegendEntry<'a> {
    label: &'a str,
    color: RGBColor,
    style: SeriesStyle,
}

fn legend_width<'a>(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    scale: Scale,
    series: impl Iterator<Item = &'a Series>,
) -> u32 {
    let font = scale.font(14.0);
    let text = series
        .map(|s| {
            area.estimate_text_size(&s.label, &font)
                .map_or(0, |(w, _)| w)
        })
        .max()
        .unwrap_or(0);
    text + scale.px(60.0)
}

/// Draws a legend: one row per entry (sample glyph, then label), at the top of `area`.
fn draw_legend(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    entries: &[LegendEntry<'_>],
    scale: Scale,
) -> Result<(), PlotErrorKind> {
    if entries.is_empty() {
        return Ok(());
    }
    let font = scale.font(14.0);
    let row = scale.px(22.0) as i32;
    let (left, top) = (scale.px(6.0) as i32, scale.px(44.0) as i32);
    let glyph = scale.px(26.0) as i32;
    let line_width = scale.px(2.0).max(1);
    let (area_width, _) = area.dim_in_pixel();
    let pad = scale.px(5.0) as i32;
    area.draw(&Rectangle::new(
        [
            (left - pad, top - pad),
            (
                area_width as i32 - scale.px(6.0) as i32,
                top + row * entries.len() as i32 + pad,
            ),
        ],
        RGBColor(190, 190, 190).stroke_width(1),
    ))
    .map_err(drawing)?;
    for (i, entry) in entries.iter().enumerate() {
        let y = top + row * i as i32 + row / 2;
        let x = left + scale.px(4.0) as i32;
        match entry.style {
            SeriesStyle::Line => area.draw(&PathElement::new(
                vec![(x, y), (x + glyph, y)],
                entry.color.stroke_width(line_width),
            )),
            SeriesStyle::Step => {
                let h = row / 4;
                area.draw(&PathElement::new(
                    vec![
                        (x, y + h),
                        (x + glyph / 2, y + h),
                        (x + glyph / 2, y - h),
                        (x + glyph, y - h),
                    ],
                    entry.color.stroke_width(line_width),
                ))
            }
            SeriesStyle::Dots => area.draw(&Circle::new(
                (x + glyph / 2, y),
                scale.px(3.0),
                entry.color.filled(),
            )),
        }
        .map_err(drawing)?;
        let text_x = x + glyph + scale.px(8.0) as i32;
        area.draw(&Text::new(
            entry.label.to_owned(),
            (text_x, y),
            font.pos(plotters::style::text_anchor::Pos::new(
                plotters::style::text_anchor::HPos::Left,
                plotters::style::text_anchor::VPos::Center,
            )),
        ))
        .map_err(drawing)?;
    }
    Ok(())
}

/// Periods (hours) used as ticks of the spectrum's log axis when they are in range.
const PERIOD_TICKS_HOURS: [f64; 16] = [
    0.25, 0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 24.0, 48.0, 84.0, 168.0, 336.0, 720.0, 8766.0,
];

/// Renders an amplitude spectrum: one vertical bar per component at its period (hours, log
/// axis), the components a model uses highlighted and labelled with their period (like Fig. 2
/// of the FreMEn paper).
///
/// # Errors
/// A [`PlotError`] naming `path`: invalid size, no bars, a bar with a non-positive or
/// non-finite period or a negative or non-finite amplitude, or a drawing/writing failure.
pub fn render_spectrum_png(
    title: &str,
    bars: &[SpectrumBar],
    path: &Path,
    width: u32,
    height: u32,
) -> Result<(), PlotError> {
    render_spectrum(title, bars, path, width, height).map_err(|kind| PlotError::new(path, kind))
}

fn render_spectrum(
    title: &str,
    bars: &[SpectrumBar],
    path: &Path,
    width: u32,
    height: u32,
) -> Result<(), PlotErrorKind> {
    check_size(width, height, SIZE_RANGE.0)?;
    if bars.is_empty() {
        return Err(PlotErrorKind::NoData);
    }
    for (index, bar) in bars.iter().enumerate() {
        let ok = bar.period_hours.is_finite()
            && bar.period_hours > 0.0
            && bar.amplitude.is_finite()
            && bar.amplitude >= 0.0;
        if !ok {
            return Err(PlotErrorKind::InvalidBar {
                index,
                period_hours: bar.period_hours,
                amplitude: bar.amplitude,
            });
        }
    }
    ensure_font()?;
    let (p_min, p_max) = bars.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), b| {
        (lo.min(b.period_hours), hi.max(b.period_hours))
    });
    let x_range = p_min / 1.3..p_max * 1.3;
    let a_max = bars.iter().map(|b| b.amplitude).fold(0.0, f64::max);
    let y_high = if a_max > 0.0 { a_max * 1.18 } else { 1.0 };
    let mut ticks: Vec<f64> = PERIOD_TICKS_HOURS
        .into_iter()
        .filter(|p| x_range.contains(p))
        .collect();
    if ticks.len() < 3 {
        ticks = log_ticks(&x_range);
    }

    let scale = Scale::for_width(width);
    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(drawing)?;
    let entries = [
        LegendEntry {
            label: "candidate component",
            color: CANDIDATE,
            style: SeriesStyle::Line,
        },
        LegendEntry {
            label: "chosen component",
            color: PALETTE[1],
            style: SeriesStyle::Line,
        },
    ];
    let legend_width = {
        let font = scale.font(14.0);
        let text = entries
            .iter()
            .map(|e| {
                root.estimate_text_size(e.label, &font)
                    .map_or(0, |(w, _)| w)
            })
            .max()
            .unwrap_or(0);
        (text + scale.px(60.0)).min(width * 2 / 5)
    };
    let (chart_area, legend_area) = root.split_horizontally(width - legend_width);
    let mut chart = ChartBuilder::on(&chart_area)
        .caption(title, scale.font(20.0))
        .margin(scale.px(10.0))
        .x_label_area_size(scale.px(48.0))
        .y_label_area_size(scale.px(70.0))
        .build_cartesian_2d(x_range.log_scale().with_key_points(ticks), 0.0..y_high)
        .map_err(drawing)?;
    chart
        .configure_mesh()
        .x_desc("period [h] (log scale)")
        .y_desc("amplitude")
        .axis_desc_style(scale.font(16.0))
        .label_style(scale.font(14.0))
        .y_labels(6)
        .x_label_formatter(&|x| format_tick(*x))
        .y_label_formatter(&|y| format_tick(*y))
        .bold_line_style(GRID)
        .light_line_style(WHITE)
        .draw()
        .map_err(drawing)?;
    let bar_width = scale.px(3.0).max(2);
    // Candidates first, so that chosen bars are drawn on top.
    for chosen in [false, true] {
        let color = if chosen { PALETTE[1] } else { CANDIDATE };
        chart
            .draw_series(bars.iter().filter(|b| b.chosen == chosen).map(|b| {
                PathElement::new(
                    vec![(b.period_hours, 0.0), (b.period_hours, b.amplitude)],
                    color.stroke_width(bar_width),
                )
            }))
            .map_err(drawing)?;
    }
    let label_font = scale.font(13.0).pos(plotters::style::text_anchor::Pos::new(
        plotters::style::text_anchor::HPos::Center,
        plotters::style::text_anchor::VPos::Bottom,
    ));
    chart
        .draw_series(bars.iter().filter(|b| b.chosen).map(|b| {
            Text::new(
                format!("{} h", format_tick(b.period_hours)),
                (b.period_hours, b.amplitude + y_high * 0.015),
                label_font.clone(),
            )
        }))
        .map_err(drawing)?;
    draw_legend(&legend_area, &entries, scale)?;
    root.present().map_err(drawing)
}

/// Ticks at 1, 2 and 5 times powers of ten within `range` (for unusual period ranges).
fn log_ticks(range: &Range<f64>) -> Vec<f64> {
    let mut ticks = Vec::new();
    let mut decade = 10f64.powf(range.start.log10().floor());
    while decade <= range.end {
        for m in [1.0, 2.0, 5.0] {
            let t = m * decade;
            if range.contains(&t) {
                ticks.push(t);
            }
        }
        decade *= 10.0;
    }
    ticks
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(format_tick(0.0), "0");
        assert_eq!(format_tick(0.5), "0.5");
        assert_eq!(format_tick(0.25), "0.25");
        assert_eq!(format_tick(24.0), "24");
        assert_eq!(format_tick(8.4), "8.4");
        assert_eq!(format_tick(168.0), "168");
        assert_eq!(format_tick(1_458_518_400.0), "1458518400");
        assert_eq!(format_tick(1_458_518_400.25), "1458518400.2");
        assert_eq!(format_tick(2e13), "2.000e13");
        assert_eq!(format_tick(-1e-9), "-1.000e-9");
    }

    #[test]
    fn steps_hold_each_value_until_the_next_point() {
        assert_eq!(
            steps(&[(0.0, 1.0), (1.0, 0.0), (3.0, 1.0)]),
            [(0.0, 1.0), (1.0, 1.0), (1.0, 0.0), (3.0, 0.0), (3.0, 1.0)]
        );
        assert!(steps(&[]).is_empty());
    }

    #[test]
    fn clipping_cuts_lines_at_the_borders() {
        // inside, then up through the top border, back down, then a flat part outside
        let points = [(0.0, 0.5), (1.0, 1.5), (2.0, 0.5), (3.0, 2.0), (4.0, 2.0)];
        assert_eq!(
            clip_to_y(&points, 0.0, 1.0),
            [
                vec![(0.0, 0.5), (0.5, 1.0)],
                vec![(1.5, 1.0), (2.0, 0.5), (2.0 + 1.0 / 3.0, 1.0)]
            ]
        );
        assert_eq!(clip_to_y(&[(0.0, 3.0)], 0.0, 1.0), Vec::<Vec<_>>::new());
        assert_eq!(
            clip_to_y(&[(0.0, 1.0), (1.0, 1.0)], 0.0, 1.0),
            [vec![(0.0, 1.0), (1.0, 1.0)]]
        );
        assert_eq!(
            dedup_pixels([(1, 1), (1, 1), (2, 1), (1, 1)].into_iter()),
            [(1, 1), (2, 1), (1, 1)]
        );
    }

    #[test]
    fn log_ticks_cover_the_range() {
        assert_eq!(log_ticks(&(0.9..60.0)), [1.0, 2.0, 5.0, 10.0, 20.0, 50.0]);
    }
}

/// One map image of a figure: occupancy probabilities of a `width × height` grid, row 0 at the
/// bottom (as `nav_msgs/OccupancyGrid`), NaN for unknown cells.
#[derive(Clone, Debug, PartialEq)]
pub struct MapImage {
    /// Title above the map.
    pub title: String,
    /// Cells along x.
    pub width: u32,
    /// Cells along y.
    pub height: u32,
    /// `width × height` probabilities in `[0, 1]`, or NaN for unknown.
    pub values: Vec<f32>,
}

/// Colour of an occupancy probability: white (free) to black (occupied); unknown in a pale blue.
fn occupancy_colour(p: f32) -> RGBColor {
    if p.is_nan() {
        RGBColor(205, 220, 235)
    } else {
        let g = (255.0 * (1.0 - p.clamp(0.0, 1.0))).round() as u8;
        RGBColor(g, g, g)
    }
}

/// Draws several maps side by side (e.g. the map predicted for two times of day), each cell a
/// square of `cell_pixels` pixels, with titles and a legend of the colour scale.
///
/// # Errors
/// A [`PlotError`] naming `path`: no maps, a map whose `values` do not have `width × height`
/// entries, an image too large or small, or a drawing/writing failure.
pub fn render_maps_png(maps: &[MapImage], path: &Path, cell_pixels: u32) -> Result<(), PlotError> {
    render_maps(maps, path, cell_pixels).map_err(|kind| PlotError::new(path, kind))
}

fn render_maps(maps: &[MapImage], path: &Path, cell_pixels: u32) -> Result<(), PlotErrorKind> {
    if maps.is_empty() {
        return Err(PlotErrorKind::NoPanels);
    }
    for map in maps {
        if map.values.len() != map.width as usize * map.height as usize
            || map.width == 0
            || map.height == 0
        {
            return Err(PlotErrorKind::NoData);
        }
    }
    ensure_font()?;
    let cell = cell_pixels.max(1);
    let margin = 12u32;
    let title_height = 40u32;
    let legend_height = 36u32;
    let map_width = maps.iter().map(|m| m.width).max().unwrap_or(1) * cell;
    let map_height = maps.iter().map(|m| m.height).max().unwrap_or(1) * cell;
    let width = maps.len() as u32 * (map_width + margin) + margin;
    let height = title_height + map_height + legend_height + margin;
    check_size(width.max(200), height.max(120), 120)?;
    let (width, height) = (width.max(200), height.max(120));
    let scale = Scale::for_width(width.max(800));
    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(drawing)?;
    for (i, map) in maps.iter().enumerate() {
        let x0 = margin + i as u32 * (map_width + margin);
        root.draw(&Text::new(
            map.title.clone(),
            (x0 as i32, 10),
            scale.font(15.0),
        ))
        .map_err(drawing)?;
        for y in 0..map.height {
            for x in 0..map.width {
                let p = map.values[(y * map.width + x) as usize];
                // Row 0 is the bottom of the map: draw it last (lowest).
                let top = title_height + (map.height - 1 - y) * cell;
                let left = x0 + x * cell;
                root.draw(&Rectangle::new(
                    [
                        (left as i32, top as i32),
                        ((left + cell) as i32, (top + cell) as i32),
                    ],
                    occupancy_colour(p).filled(),
                ))
                .map_err(drawing)?;
            }
        }
    }
    // Legend: free, occupied, unknown.
    let y = (title_height + map_height + 12) as i32;
    let mut x = margin as i32;
    for (label, colour) in [
        ("free (p = 0)", occupancy_colour(0.0)),
        ("p = 0.5", occupancy_colour(0.5)),
        ("occupied (p = 1)", occupancy_colour(1.0)),
        ("unknown", occupancy_colour(f32::NAN)),
    ] {
        root.draw(&Rectangle::new([(x, y), (x + 16, y + 16)], colour.filled()))
            .map_err(drawing)?;
        root.draw(&Rectangle::new(
            [(x, y), (x + 16, y + 16)],
            BLACK.stroke_width(1),
        ))
        .map_err(drawing)?;
        root.draw(&Text::new(label, (x + 22, y), scale.font(13.0)))
            .map_err(drawing)?;
        x += 40 + 9 * label.len() as i32;
    }
    root.present().map_err(drawing)
}
