//! PNG plots: observations and predictions over time, and amplitude spectra.
//!
//! Plain data in, a PNG file out. Text is drawn with an embedded DejaVu Sans font (see
//! `assets/fonts/LICENSE-DejaVu.txt`), so no system fonts or fontconfig are needed.
//!
//! ```no_run
//! use std::path::Path;
//! use chronomap_plot::{render_panels_png, Panel, Series, SeriesStyle};
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
//! # Ok::<(), chronomap_plot::PlotError>(())
//! ```

pub mod plane;

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

/// Colours of the series, in order: the Okabe–Ito palette (readable with colour blindness), its
/// yellow replaced by a mid grey that stays visible on white. Eight series get eight colours.
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),   // blue
    RGBColor(213, 94, 0),    // vermillion
    RGBColor(0, 158, 115),   // bluish green
    RGBColor(204, 121, 167), // reddish purple
    RGBColor(230, 159, 0),   // orange
    RGBColor(86, 180, 233),  // sky blue
    RGBColor(0, 0, 0),       // black
    RGBColor(128, 128, 128), // grey
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

impl SpectrumBar {
    /// The bars of a spectrum of `(period in seconds, amplitude)` components; those whose
    /// period is one of `chosen_secs` are chosen.
    pub fn from_spectrum(
        spectrum: impl IntoIterator<Item = (f64, f64)>,
        chosen_secs: &[f64],
    ) -> Vec<SpectrumBar> {
        spectrum
            .into_iter()
            .map(|(period_secs, amplitude)| SpectrumBar {
                period_hours: period_secs / 3600.0,
                amplitude,
                chosen: chosen_secs.contains(&period_secs),
            })
            .collect()
    }
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
    /// A heat map without rows or without columns.
    #[error("nothing to plot: the heat map has {rows} rows and {columns} columns")]
    EmptyGrid {
        /// Number of row labels.
        rows: usize,
        /// Number of column labels.
        columns: usize,
    },
    /// A heat map whose number of values is not rows × columns.
    #[error("the heat map has {found} values for {rows} rows × {columns} columns")]
    ValueCount {
        /// Number of row labels.
        rows: usize,
        /// Number of column labels.
        columns: usize,
        /// Number of values.
        found: usize,
    },
    /// A heat map whose cell texts are neither empty nor one per cell.
    #[error(
        "the heat map has {found} cell texts for {rows} rows × {columns} columns (give none or one per cell)"
    )]
    CellTextCount {
        /// Number of row labels.
        rows: usize,
        /// Number of column labels.
        columns: usize,
        /// Number of cell texts.
        found: usize,
    },
    /// A heat-map value outside `[0, 1]` that is not NaN.
    #[error(
        "heat-map cell at row {row} ({row_label:?}), column {column} ({column_label:?}): value {value} is outside [0, 1] (NaN marks a cell without a value)"
    )]
    ValueOutOfRange {
        /// 0-based row.
        row: usize,
        /// 0-based column.
        column: usize,
        /// Label of the row.
        row_label: String,
        /// Label of the column.
        column_label: String,
        /// The value.
        value: f64,
    },
    /// The embedded font could not be loaded.
    #[error("the embedded font could not be loaded")]
    Font,
    /// Drawing or encoding the image failed.
    #[error("cannot draw or write the image: {reason}")]
    Drawing {
        /// The message of the drawing library.
        reason: String,
    },
    /// The image could not be written ([`chronomap_io::output`]).
    #[error("cannot {action}: {io}")]
    Write {
        /// What was being done (`"write"`, `"replace"`, …).
        action: &'static str,
        /// The underlying error.
        io: std::io::Error,
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

/// Draws an image of `size` pixels in memory with `draw` and writes it to `path` as PNG
/// through the one output writer ([`chronomap_io::output::write_output`]: a regular file is
/// replaced atomically, a device or pipe written through, a directory refused).
fn draw_png(
    path: &Path,
    (width, height): (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<(), PlotErrorKind>,
) -> Result<(), PlotErrorKind> {
    let mut pixels = vec![0u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, (width, height)).into_drawing_area();
        draw(&root)?;
        root.present().map_err(drawing)?;
    }
    let png = encode_png(&pixels, width, height)?;
    chronomap_io::output::write_output(path, &png).map_err(|e| PlotErrorKind::Write {
        action: e.action,
        io: e.io,
    })
}

/// The RGB `pixels` as PNG, encoded as the drawing library encodes the files it saves (the
/// `image` crate's PNG encoder with its default compression and filter).
fn encode_png(pixels: &[u8], width: u32, height: u32) -> Result<Vec<u8>, PlotErrorKind> {
    use image::ImageEncoder;
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(pixels, width, height, image::ColorType::Rgb8)
        .map_err(drawing)?;
    Ok(png)
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
    draw_png(path, (width, height), |root| {
        root.fill(&WHITE).map_err(drawing)?;
        let legend_width =
            legend_width(root, scale, panels.iter().flat_map(|p| &p.series)).min(width * 2 / 5);
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
        Ok(())
    })
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
    draw_png(path, (width, height), |root| {
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
        Ok(())
    })
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
    let legend = [
        ("free (p = 0)", 0.0),
        ("p = 0.5", 0.5),
        ("occupied (p = 1)", 1.0),
        ("unknown", f32::NAN),
    ];
    render_maps(maps, path, cell_pixels, &legend).map_err(|kind| PlotError::new(path, kind))
}

/// As [`render_maps_png`] for maps of other quantities scaled into `[0, 1]` (e.g. a predicted
/// density divided by its maximum): the legend shows `legend` — `(label, value)` pairs —
/// instead of the occupancy legend.
///
/// # Errors
/// As [`render_maps_png`].
pub fn render_scaled_maps_png(
    maps: &[MapImage],
    path: &Path,
    cell_pixels: u32,
    legend: &[(&str, f32)],
) -> Result<(), PlotError> {
    render_maps(maps, path, cell_pixels, legend).map_err(|kind| PlotError::new(path, kind))
}

fn render_maps(
    maps: &[MapImage],
    path: &Path,
    cell_pixels: u32,
    legend: &[(&str, f32)],
) -> Result<(), PlotErrorKind> {
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
    draw_png(path, (width, height), |root| {
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
        // Legend: e.g. free, occupied, unknown.
        let y = (title_height + map_height + 12) as i32;
        let mut x = margin as i32;
        for &(label, value) in legend {
            let colour = occupancy_colour(value);
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
        Ok(())
    })
}

/// A labelled grid of values in `[0, 1]` with an optional short text per cell, drawn by
/// [`render_heatmap_png`].
///
/// Typical use: the "now or later?" table of a navigation planner ([Fentanes 2015] Table III): one
/// row per start time, one column per day, the value the maximum probability of completing the
/// task when starting then, the text a code for the first action (explained in `legend`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Heatmap {
    /// Title above the grid (empty: none).
    pub title: String,
    /// Title of the rows, written above the row labels (e.g. `"start time (UTC)"`; empty:
    /// none).
    pub row_label: String,
    /// Title of the columns, written centred above the column labels (e.g. `"day"`; empty:
    /// none).
    pub column_label: String,
    /// Row labels, top to bottom (e.g. `"00:00"`).
    pub rows: Vec<String>,
    /// Column labels, left to right (e.g. `"Mon 09-08"`).
    pub columns: Vec<String>,
    /// `rows.len() × columns.len()` values in `[0, 1]`, row-major (row 0 first); NaN marks a
    /// cell without a value.
    pub values: Vec<f64>,
    /// Empty, or one short text per cell (same order as `values`), written after the value
    /// (e.g. a one- or two-letter code of the first action).
    pub cell_text: Vec<String>,
    /// Title of the colour bar (e.g. `"Pmax"`; empty: none).
    pub value_label: String,
    /// Lines written under the grid (e.g. `"a = Station_LabDoor1"`).
    pub legend: Vec<String>,
}

/// Where [`render_heatmap_png`] puts things, in pixels from the top-left corner of the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HeatmapLayout {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Width of a cell, including the 1-pixel white separator on its right.
    pub cell_width: u32,
    /// Height of a cell, including the 1-pixel white separator at its bottom.
    pub cell_height: u32,
    /// Left edge of the grid (of column 0).
    pub grid_left: u32,
    /// Top edge of the grid (of row 0).
    pub grid_top: u32,
    /// Left edge of the colour bar.
    pub bar_left: u32,
    /// Top edge of the colour bar (the colour of 1).
    pub bar_top: u32,
    /// Height of the colour bar; its last pixel row has the colour of 0.
    pub bar_height: u32,
    /// Top edge of the first legend line.
    pub legend_top: u32,
}

impl HeatmapLayout {
    /// Centre pixel of the cell in `row`, `column` (0-based; not checked against the grid).
    pub fn cell_centre(&self, row: usize, column: usize) -> (u32, u32) {
        let at = |start: u32, index: usize, size: u32| {
            let offset = u64::from(size) * index as u64 + u64::from(size.saturating_sub(1) / 2);
            u32::try_from(u64::from(start) + offset).unwrap_or(u32::MAX)
        };
        (
            at(self.grid_left, column, self.cell_width),
            at(self.grid_top, row, self.cell_height),
        )
    }
}

/// The 11 anchor colours of viridis (van der Walt and Smith's colour map of matplotlib) at
/// 0, 0.1, …, 1: perceptually uniform, increasing in lightness, readable with colour
/// blindness and in greyscale.
const VIRIDIS: [RGBColor; 11] = [
    RGBColor(68, 1, 84),
    RGBColor(72, 37, 118),
    RGBColor(65, 68, 135),
    RGBColor(53, 96, 141),
    RGBColor(42, 120, 142),
    RGBColor(33, 144, 140),
    RGBColor(34, 168, 132),
    RGBColor(67, 191, 113),
    RGBColor(122, 209, 81),
    RGBColor(187, 223, 39),
    RGBColor(253, 231, 37),
];

/// Colour of a heat-map cell without a value (NaN): a light neutral grey, which viridis never
/// takes.
pub const HEATMAP_NO_VALUE: RGBColor = RGBColor(218, 218, 218);

/// Colour of a heat-map value: viridis (dark purple at 0 through teal to yellow at 1),
/// linearly interpolated between 11 anchor colours; values outside `[0, 1]` are clamped, NaN
/// gives [`HEATMAP_NO_VALUE`].
pub fn heatmap_colour(value: f64) -> RGBColor {
    if value.is_nan() {
        return HEATMAP_NO_VALUE;
    }
    let steps = (VIRIDIS.len() - 1) as f64;
    let position = value.clamp(0.0, 1.0) * steps;
    let index = (position.floor() as usize).min(VIRIDIS.len() - 2);
    let fraction = position - index as f64;
    let (RGBColor(r0, g0, b0), RGBColor(r1, g1, b1)) = (VIRIDIS[index], VIRIDIS[index + 1]);
    let mix =
        |a: u8, b: u8| (f64::from(a) + fraction * (f64::from(b) - f64::from(a))).round() as u8;
    RGBColor(mix(r0, r1), mix(g0, g1), mix(b0, b1))
}

/// Relative luminance of an sRGB colour (WCAG 2), 0 for black to 1 for white.
fn relative_luminance(RGBColor(r, g, b): RGBColor) -> f64 {
    let linear = |c: u8| {
        let c = f64::from(c) / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    0.2126 * linear(r) + 0.7152 * linear(g) + 0.0722 * linear(b)
}

/// Black or white, whichever contrasts more with `background` (WCAG contrast ratio).
fn text_colour_on(background: RGBColor) -> RGBColor {
    let l = relative_luminance(background);
    // (l + 0.05) / 0.05 against black, 1.05 / (l + 0.05) against white.
    if (l + 0.05) * (l + 0.05) > 0.05 * 1.05 {
        BLACK
    } else {
        WHITE
    }
}

/// Fixed sizes of the heat-map layout in pixels (the image size follows from the grid).
mod heat {
    pub const MARGIN: u32 = 14;
    pub const MIN_CELL_WIDTH: u32 = 90;
    pub const CELL_HEIGHT: u32 = 26;
    /// Free space left and right of the text in a cell, together.
    pub const CELL_PADDING: u32 = 14;
    pub const TITLE_LINE: u32 = 34;
    pub const LABEL_LINE: u32 = 24;
    pub const LEGEND_LINE: u32 = 21;
    pub const LEGEND_GAP: u32 = 16;
    pub const ROW_LABEL_GAP: u32 = 8;
    pub const BAR_GAP: u32 = 24;
    pub const BAR_WIDTH: u32 = 18;
    pub const MIN_BAR_HEIGHT: u32 = 120;
    pub const TICK: u32 = 5;
    pub const SWATCH: u32 = 16;
    /// Space under the colour bar for the "no value" swatch.
    pub const SWATCH_BLOCK: u32 = 34;
    pub const TITLE_FONT: f64 = 20.0;
    pub const AXIS_FONT: f64 = 15.0;
    pub const LABEL_FONT: f64 = 14.0;
    pub const CELL_FONT: f64 = 14.0;
    pub const LEGEND_FONT: f64 = 14.0;
}

/// Ticks of the colour bar.
const HEATMAP_TICKS: [f64; 6] = [0.0, 0.2, 0.4, 0.6, 0.8, 1.0];

/// Label of the "no value" swatch under the colour bar.
const NO_VALUE_LABEL: &str = "no value";

fn heat_font(size: f64) -> TextStyle<'static> {
    (FAMILY, size).into_font().color(&BLACK)
}

/// Width in pixels of `text` in the embedded font at `size`.
fn text_width(text: &str, size: f64) -> Result<u32, PlotErrorKind> {
    if text.is_empty() {
        return Ok(0);
    }
    (FAMILY, size)
        .into_font()
        .box_size(text)
        .map(|(w, _)| w)
        .map_err(|_| PlotErrorKind::Font)
}

/// Width in pixels of the widest of `texts` at `size`.
fn max_text_width(
    texts: impl IntoIterator<Item = impl AsRef<str>>,
    size: f64,
) -> Result<u32, PlotErrorKind> {
    texts
        .into_iter()
        .try_fold(0, |widest, t| Ok(widest.max(text_width(t.as_ref(), size)?)))
}

/// Horizontal centre of the column title: over the middle of the grid, or further right if a
/// title wider than the grid would otherwise cross the left margin.
fn column_title_centre(grid_left: u64, grid_width: u64, title_width: u64) -> u64 {
    (grid_left + grid_width / 2).max(u64::from(heat::MARGIN) + title_width.div_ceil(2))
}

/// Text of a cell: the value with two decimals (none for NaN), then the cell's text.
fn cell_label(map: &Heatmap, index: usize) -> String {
    let value = map.values[index];
    let text = map.cell_text.get(index).map_or("", |t| t.as_str());
    match (value.is_nan(), text.is_empty()) {
        (true, _) => text.to_owned(),
        (false, true) => format!("{value:.2}"),
        (false, false) => format!("{value:.2} {text}"),
    }
}

impl Heatmap {
    /// Checks the grid: at least one row and one column, one value per cell, each in `[0, 1]`
    /// or NaN, and no cell text or one per cell.
    ///
    /// # Errors
    /// [`PlotErrorKind::EmptyGrid`], [`PlotErrorKind::ValueCount`],
    /// [`PlotErrorKind::CellTextCount`] or [`PlotErrorKind::ValueOutOfRange`].
    pub fn validate(&self) -> Result<(), PlotErrorKind> {
        let (rows, columns) = (self.rows.len(), self.columns.len());
        if rows == 0 || columns == 0 {
            return Err(PlotErrorKind::EmptyGrid { rows, columns });
        }
        let cells = rows.checked_mul(columns);
        if cells != Some(self.values.len()) {
            return Err(PlotErrorKind::ValueCount {
                rows,
                columns,
                found: self.values.len(),
            });
        }
        if !self.cell_text.is_empty() && cells != Some(self.cell_text.len()) {
            return Err(PlotErrorKind::CellTextCount {
                rows,
                columns,
                found: self.cell_text.len(),
            });
        }
        if let Some(index) = self
            .values
            .iter()
            .position(|v| !(v.is_nan() || (0.0..=1.0).contains(v)))
        {
            let (row, column) = (index / columns, index % columns);
            return Err(PlotErrorKind::ValueOutOfRange {
                row,
                column,
                row_label: self.rows[row].clone(),
                column_label: self.columns[column].clone(),
                value: self.values[index],
            });
        }
        Ok(())
    }

    /// Where [`render_heatmap_png`] will draw things, and the image size.
    ///
    /// Cells are 26 pixels tall and as wide as the widest
    /// cell text or column label needs (text plus 14 pixels), at least 90 pixels. Left of the
    /// grid are the row labels, above it the title, the column title and the column labels,
    /// right of it the colour bar (at least 120 pixels tall) with its ticks, under it the
    /// legend lines. Each side is at least [`SIZE_RANGE`]`.0`.
    ///
    /// # Errors
    /// As [`Heatmap::validate`]; [`PlotErrorKind::InvalidSize`] if the image would be larger
    /// than [`SIZE_RANGE`]`.1` on a side.
    pub fn layout(&self) -> Result<HeatmapLayout, PlotErrorKind> {
        use heat::*;
        self.validate()?;
        ensure_font()?;
        let cell_text_width = max_text_width(
            (0..self.values.len()).map(|i| cell_label(self, i)),
            CELL_FONT,
        )?;
        let column_label_width = max_text_width(&self.columns, LABEL_FONT)?;
        let cell_width = MIN_CELL_WIDTH.max(cell_text_width.max(column_label_width) + CELL_PADDING);
        let row_labels_width =
            max_text_width(&self.rows, LABEL_FONT)?.max(text_width(&self.row_label, AXIS_FONT)?);

        // Everything in u64: absurd grids must give a size error, not an overflow.
        let wide = u64::from;
        let has_nan = self.values.iter().any(|v| v.is_nan());
        let grid_width = wide(cell_width) * self.columns.len() as u64;
        let grid_height = wide(CELL_HEIGHT) * self.rows.len() as u64;
        let swatch_block = if has_nan { wide(SWATCH_BLOCK) } else { 0 };
        let bar_height = grid_height
            .saturating_sub(swatch_block)
            .max(wide(MIN_BAR_HEIGHT));
        let body_height = grid_height.max(bar_height + swatch_block);

        let mut grid_top = wide(MARGIN);
        if !self.title.is_empty() {
            grid_top += wide(TITLE_LINE);
        }
        if !self.column_label.is_empty() {
            grid_top += wide(LABEL_LINE);
        }
        grid_top += wide(LABEL_LINE); // column labels, and the row and colour-bar titles
        let grid_left = wide(MARGIN) + wide(row_labels_width) + wide(ROW_LABEL_GAP);
        let bar_left = grid_left + grid_width + wide(BAR_GAP);
        let tick_label_width = max_text_width(HEATMAP_TICKS.map(format_tick), LABEL_FONT)?;
        let bar_area_width = wide(BAR_WIDTH + TICK + 4 + tick_label_width)
            .max(wide(text_width(&self.value_label, AXIS_FONT)?))
            .max(if has_nan {
                wide(SWATCH + 6 + text_width(NO_VALUE_LABEL, LABEL_FONT)?)
            } else {
                0
            });
        let legend_top = grid_top + body_height + wide(LEGEND_GAP);
        let legend_width = max_text_width(&self.legend, LEGEND_FONT)?;
        let title_width = text_width(&self.title, TITLE_FONT)?;
        let column_title_width = wide(text_width(&self.column_label, AXIS_FONT)?);
        let column_title_right =
            column_title_centre(grid_left, grid_width, column_title_width) + column_title_width / 2;
        let width = (bar_left + bar_area_width + wide(MARGIN))
            .max(column_title_right + wide(MARGIN))
            .max(wide(legend_width) + 2 * wide(MARGIN))
            .max(wide(title_width) + 2 * wide(MARGIN))
            .max(wide(SIZE_RANGE.0));
        let height = if self.legend.is_empty() {
            grid_top + body_height + wide(MARGIN)
        } else {
            legend_top + wide(LEGEND_LINE) * self.legend.len() as u64 + wide(MARGIN)
        }
        .max(wide(SIZE_RANGE.0));
        let narrow = |v: u64| u32::try_from(v).unwrap_or(u32::MAX);
        let (width, height) = (narrow(width), narrow(height));
        check_size(width, height, SIZE_RANGE.0)?;
        // Every position is below the checked image size from here on.
        Ok(HeatmapLayout {
            width,
            height,
            cell_width,
            cell_height: CELL_HEIGHT,
            grid_left: narrow(grid_left),
            grid_top: narrow(grid_top),
            bar_left: narrow(bar_left),
            bar_top: narrow(grid_top),
            bar_height: narrow(bar_height),
            legend_top: narrow(legend_top),
        })
    }
}

/// Renders a heat map: a grid of coloured cells, each with its value (two decimals) and text,
/// row and column labels, a colour bar of the value scale (with a "no value" swatch if a value
/// is NaN) and legend lines under the grid. The image size follows from the grid (see
/// [`Heatmap::layout`]); for 24 rows × 7 columns with short labels it is about 900 × 830
/// pixels.
///
/// Cells are coloured with [`heatmap_colour`] (viridis; [`HEATMAP_NO_VALUE`] grey for NaN);
/// their text is black or white, whichever contrasts more with the cell.
///
/// # Errors
/// A [`PlotError`] naming `path`: no rows or columns, a wrong number of values or cell texts,
/// a value outside `[0, 1]` that is not NaN, an image larger than [`SIZE_RANGE`] allows, or a
/// drawing/writing failure (e.g. the directory does not exist).
pub fn render_heatmap_png(map: &Heatmap, path: &Path) -> Result<(), PlotError> {
    render_heatmap(map, path).map_err(|kind| PlotError::new(path, kind))
}

/// Anchor of text: horizontal `h`, vertically centred on the given `y`.
fn anchored(
    style: TextStyle<'static>,
    h: plotters::style::text_anchor::HPos,
) -> TextStyle<'static> {
    style.pos(plotters::style::text_anchor::Pos::new(
        h,
        plotters::style::text_anchor::VPos::Center,
    ))
}

fn render_heatmap(map: &Heatmap, path: &Path) -> Result<(), PlotErrorKind> {
    use heat::*;
    use plotters::style::text_anchor::HPos;
    let layout = map.layout()?;
    draw_png(path, (layout.width, layout.height), |root| {
        root.fill(&WHITE).map_err(drawing)?;
        let (cw, ch) = (layout.cell_width as i32, layout.cell_height as i32);
        let (grid_left, grid_top) = (layout.grid_left as i32, layout.grid_top as i32);
        let columns = map.columns.len();
        let margin = MARGIN as i32;

        // Title, column title, then the line of column labels (with the row and bar titles).
        let mut y = margin;
        if !map.title.is_empty() {
            root.draw(&Text::new(
                map.title.clone(),
                (layout.width as i32 / 2, y + TITLE_LINE as i32 / 2 - 2),
                anchored(heat_font(TITLE_FONT), HPos::Center),
            ))
            .map_err(drawing)?;
            y += TITLE_LINE as i32;
        }
        if !map.column_label.is_empty() {
            root.draw(&Text::new(
                map.column_label.clone(),
                (
                    column_title_centre(
                        u64::from(layout.grid_left),
                        u64::from(layout.cell_width) * columns as u64,
                        u64::from(text_width(&map.column_label, AXIS_FONT)?),
                    ) as i32,
                    y + LABEL_LINE as i32 / 2,
                ),
                anchored(heat_font(AXIS_FONT), HPos::Center),
            ))
            .map_err(drawing)?;
            y += LABEL_LINE as i32;
        }
        let header_y = y + LABEL_LINE as i32 / 2;
        for (c, label) in map.columns.iter().enumerate() {
            root.draw(&Text::new(
                label.clone(),
                (grid_left + cw * c as i32 + (cw - 1) / 2, header_y),
                anchored(heat_font(LABEL_FONT), HPos::Center),
            ))
            .map_err(drawing)?;
        }
        let row_label_right = grid_left - ROW_LABEL_GAP as i32;
        if !map.row_label.is_empty() {
            root.draw(&Text::new(
                map.row_label.clone(),
                (row_label_right, header_y),
                anchored(heat_font(AXIS_FONT), HPos::Right),
            ))
            .map_err(drawing)?;
        }

        // Cells, separated by 1-pixel white lines.
        for (r, label) in map.rows.iter().enumerate() {
            let top = grid_top + ch * r as i32;
            root.draw(&Text::new(
                label.clone(),
                (row_label_right, top + (ch - 1) / 2),
                anchored(heat_font(LABEL_FONT), HPos::Right),
            ))
            .map_err(drawing)?;
            for c in 0..columns {
                let index = r * columns + c;
                let left = grid_left + cw * c as i32;
                let colour = heatmap_colour(map.values[index]);
                root.draw(&Rectangle::new(
                    [(left, top), (left + cw - 1, top + ch - 1)],
                    colour.filled(),
                ))
                .map_err(drawing)?;
                let text = cell_label(map, index);
                if !text.is_empty() {
                    let font = (FAMILY, CELL_FONT)
                        .into_font()
                        .color(&text_colour_on(colour));
                    root.draw(&Text::new(
                        text,
                        (left + (cw - 1) / 2, top + (ch - 1) / 2),
                        anchored(font, HPos::Center),
                    ))
                    .map_err(drawing)?;
                }
            }
        }

        // Colour bar: 1 at the top, 0 at the bottom, ticks and labels on its right.
        let (bar_left, bar_top) = (layout.bar_left as i32, layout.bar_top as i32);
        let bar_height = layout.bar_height as i32;
        let bar_right = bar_left + BAR_WIDTH as i32;
        if !map.value_label.is_empty() {
            root.draw(&Text::new(
                map.value_label.clone(),
                (bar_left, header_y),
                anchored(heat_font(AXIS_FONT), HPos::Left),
            ))
            .map_err(drawing)?;
        }
        let bar_value = |offset: i32| 1.0 - f64::from(offset) / f64::from((bar_height - 1).max(1));
        for offset in 0..bar_height {
            let y = bar_top + offset;
            root.draw(&Rectangle::new(
                [(bar_left, y), (bar_right, y + 1)],
                heatmap_colour(bar_value(offset)).filled(),
            ))
            .map_err(drawing)?;
        }
        for tick in HEATMAP_TICKS {
            let y = bar_top + ((1.0 - tick) * f64::from(bar_height - 1)).round() as i32;
            root.draw(&PathElement::new(
                vec![(bar_right, y), (bar_right + TICK as i32, y)],
                BLACK.stroke_width(1),
            ))
            .map_err(drawing)?;
            root.draw(&Text::new(
                format_tick(tick),
                (bar_right + TICK as i32 + 4, y),
                anchored(heat_font(LABEL_FONT), HPos::Left),
            ))
            .map_err(drawing)?;
        }
        if map.values.iter().any(|v| v.is_nan()) {
            let top = bar_top + bar_height + (SWATCH_BLOCK - SWATCH) as i32 / 2 + 2;
            let swatch = [
                (bar_left, top),
                (bar_left + SWATCH as i32, top + SWATCH as i32),
            ];
            root.draw(&Rectangle::new(swatch, HEATMAP_NO_VALUE.filled()))
                .map_err(drawing)?;
            root.draw(&Text::new(
                NO_VALUE_LABEL,
                (bar_left + SWATCH as i32 + 6, top + SWATCH as i32 / 2),
                anchored(heat_font(LABEL_FONT), HPos::Left),
            ))
            .map_err(drawing)?;
        }

        // Legend lines.
        for (i, line) in map.legend.iter().enumerate() {
            let y =
                layout.legend_top as i32 + LEGEND_LINE as i32 * i as i32 + LEGEND_LINE as i32 / 2;
            root.draw(&Text::new(
                line.clone(),
                (margin, y),
                anchored(heat_font(LEGEND_FONT), HPos::Left),
            ))
            .map_err(drawing)?;
        }
        Ok(())
    })
}

/// One labelled path of a [`PathMap`]: points in metres (map frame), joined by lines.
#[derive(Clone, Debug, PartialEq)]
pub struct PathMapPath {
    /// Legend text (e.g. the model that planned it).
    pub label: String,
    /// The points in order.
    pub points: Vec<[f64; 2]>,
}

/// A cost map with paths over it, drawn by [`render_path_maps_png`]: a `cols × rows` grid of
/// square cells of `cell` metres from `origin` (row 0 at the bottom), each coloured by a
/// value in `[0, 1]` (viridis; NaN: a cell the robot may not enter), with obstacle points,
/// people, labelled waypoints and paths on top.
///
/// Typical use: Figure 4.12 of the CoPA-Map chapter, a model's predicted rates at a busy hour
/// and the patrols every model plans then.
#[derive(Clone, Debug, PartialEq)]
pub struct PathMap {
    /// Title above the map.
    pub title: String,
    /// Lower-left corner of cell (0, 0), metres.
    pub origin: [f64; 2],
    /// Cell size in metres (> 0).
    pub cell: f64,
    /// Cells along x.
    pub cols: usize,
    /// Cells along y.
    pub rows: usize,
    /// `cols × rows` values in `[0, 1]`, row 0 at the bottom; NaN for cells without one.
    pub values: Vec<f32>,
    /// Obstacle points (e.g. occupied map pixels), drawn black.
    pub obstacles: Vec<[f64; 2]>,
    /// People (e.g. detections during the patrol), drawn as small white dots.
    pub people: Vec<[f64; 2]>,
    /// Paths, coloured by [`PALETTE`] in order; earlier paths are drawn wider so that paths
    /// that coincide stay visible.
    pub paths: Vec<PathMapPath>,
    /// Labelled waypoints.
    pub waypoints: Vec<(String, [f64; 2])>,
}

/// Draws path maps side by side, each cell a square of `cell_pixels` pixels, with a legend of
/// the paths (the labels of the first map) below.
///
/// # Errors
/// A [`PlotError`] naming `path`: no maps, a map without cells, whose `values` do not have
/// `cols × rows` entries or whose cell size is not positive, an image too large or small, or
/// a drawing/writing failure.
pub fn render_path_maps_png(
    maps: &[PathMap],
    path: &Path,
    cell_pixels: u32,
) -> Result<(), PlotError> {
    render_path_maps(maps, path, cell_pixels).map_err(|kind| PlotError::new(path, kind))
}

fn render_path_maps(maps: &[PathMap], path: &Path, cell_pixels: u32) -> Result<(), PlotErrorKind> {
    if maps.is_empty() {
        return Err(PlotErrorKind::NoPanels);
    }
    for map in maps {
        if map.cols == 0
            || map.rows == 0
            || map.values.len() != map.cols * map.rows
            || !(map.cell.is_finite() && map.cell > 0.0)
        {
            return Err(PlotErrorKind::NoData);
        }
    }
    ensure_font()?;
    let cell = cell_pixels.max(1);
    let margin = 12u32;
    let title_height = 40u32;
    let legend_height = 40u32;
    let map_width = maps.iter().map(|m| m.cols).max().unwrap_or(1) as u32 * cell;
    let map_height = maps.iter().map(|m| m.rows).max().unwrap_or(1) as u32 * cell;
    let width = (maps.len() as u32 * (map_width + margin) + margin).max(200);
    let height = (title_height + map_height + legend_height + margin).max(120);
    check_size(width, height, 120)?;
    let scale = Scale::for_width(width.min(1600));
    draw_png(path, (width, height), |root| {
        root.fill(&WHITE).map_err(drawing)?;
        for (i, map) in maps.iter().enumerate() {
            let x0 = margin + i as u32 * (map_width + margin);
            // Metres to pixels of this panel.
            let to_px = |p: [f64; 2]| -> (i32, i32) {
                let fx = (p[0] - map.origin[0]) / map.cell;
                let fy = (p[1] - map.origin[1]) / map.cell;
                (
                    (f64::from(x0) + fx * f64::from(cell)).round() as i32,
                    (f64::from(title_height) + (map.rows as f64 - fy) * f64::from(cell)).round()
                        as i32,
                )
            };
            root.draw(&Text::new(
                map.title.clone(),
                (x0 as i32, 10),
                scale.font(14.0),
            ))
            .map_err(drawing)?;
            for row in 0..map.rows {
                for column in 0..map.cols {
                    let v = map.values[row * map.cols + column];
                    let top = title_height + (map.rows - 1 - row) as u32 * cell;
                    let left = x0 + column as u32 * cell;
                    root.draw(&Rectangle::new(
                        [
                            (left as i32, top as i32),
                            ((left + cell) as i32, (top + cell) as i32),
                        ],
                        heatmap_colour(f64::from(v)).filled(),
                    ))
                    .map_err(drawing)?;
                }
            }
            let inside = |p: &[f64; 2]| {
                p[0] >= map.origin[0]
                    && p[1] >= map.origin[1]
                    && p[0] < map.origin[0] + map.cols as f64 * map.cell
                    && p[1] < map.origin[1] + map.rows as f64 * map.cell
            };
            let dot = (cell / 12).max(1) as i32;
            for p in map.obstacles.iter().filter(|p| inside(p)) {
                let (x, y) = to_px(*p);
                root.draw(&Rectangle::new(
                    [(x - dot, y - dot), (x + dot, y + dot)],
                    BLACK.filled(),
                ))
                .map_err(drawing)?;
            }
            for p in map.people.iter().filter(|p| inside(p)) {
                root.draw(&Circle::new(to_px(*p), dot, WHITE.filled()))
                    .map_err(drawing)?;
            }
            let n = map.paths.len();
            for (k, line) in map.paths.iter().enumerate() {
                let colour = PALETTE[k % PALETTE.len()];
                let width = scale.px(2.0) + 2 * scale.px(1.5) * (n - 1 - k) as u32;
                let points: Vec<(i32, i32)> = line.points.iter().map(|&p| to_px(p)).collect();
                root.draw(&PathElement::new(points, colour.stroke_width(width)))
                    .map_err(drawing)?;
            }
            for (label, at) in &map.waypoints {
                let (x, y) = to_px(*at);
                let r = (cell / 3).max(3) as i32;
                root.draw(&Circle::new((x, y), r, WHITE.filled()))
                    .map_err(drawing)?;
                root.draw(&Circle::new((x, y), r, BLACK.stroke_width(2)))
                    .map_err(drawing)?;
                root.draw(&Text::new(
                    label.clone(),
                    (x + r + 2, y - r - 2),
                    scale.font(16.0),
                ))
                .map_err(drawing)?;
            }
        }
        // Legend: the paths of the first map.
        let y = (title_height + map_height + 14) as i32;
        let mut x = margin as i32;
        for (k, line) in maps[0].paths.iter().enumerate() {
            let colour = PALETTE[k % PALETTE.len()];
            root.draw(&PathElement::new(
                vec![(x, y + 8), (x + 28, y + 8)],
                colour.stroke_width(scale.px(4.0)),
            ))
            .map_err(drawing)?;
            root.draw(&Text::new(
                line.label.clone(),
                (x + 34, y),
                scale.font(13.0),
            ))
            .map_err(drawing)?;
            x += 60 + 9 * line.label.len() as i32;
        }
        root.draw(&Text::new(
        "colour: value 0 (dark) to 1 (yellow); grey: not drivable; black: obstacles; white dots: people",
        (x + 20, y),
        scale.font(13.0),
    ))
    .map_err(drawing)?;
        Ok(())
    })
}
