//! The pictures of calibration every `--plot` of an evaluation draws: reliability diagrams of
//! probabilities ([`chronomap_core::calibration::Calibration`]) and coverage curves of
//! intervals ([`chronomap_core::calibration::Coverage`] at the [`CURVE_LEVELS`]).
//!
//! [`CURVE_LEVELS`]: chronomap_core::calibration::CURVE_LEVELS

use chronomap_core::calibration::{Coverage, ReliabilityBin};
use chronomap_plot::{Panel, Series, SeriesStyle};

/// Lines, or dots where a series has one point (a line needs two).
fn style(points: &[(f64, f64)]) -> SeriesStyle {
    if points.len() == 1 {
        SeriesStyle::Dots
    } else {
        SeriesStyle::Line
    }
}

/// The largest `y` of any point of `series` (0 without points).
fn highest(series: &[Series]) -> f64 {
    series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .fold(0.0, f64::max)
}

/// The diagonal `y = x` from 0 to 1, labelled "calibrated".
fn diagonal() -> Series {
    Series {
        label: "calibrated".into(),
        points: vec![(0.0, 0.0), (1.0, 1.0)],
        style: SeriesStyle::Line,
    }
}

/// A reliability diagram (above: observed frequency against mean forecast per bin, the
/// diagonal being perfect calibration; below: the share of forecasts in each bin) of every
/// `(label, bins)` in `forecasts`, one colour per forecaster in both panels.
pub fn reliability_panels(title: String, forecasts: &[(String, &[ReliabilityBin])]) -> Vec<Panel> {
    let mut diagram = Vec::new();
    let mut shares = Vec::new();
    for (label, bins) in forecasts {
        let samples: usize = bins.iter().map(|b| b.count).sum();
        let points: Vec<(f64, f64)> = bins
            .iter()
            .map(|b| (b.mean_prediction, b.observed_frequency))
            .collect();
        diagram.push(Series {
            label: label.clone(),
            style: style(&points),
            points,
        });
        let points: Vec<(f64, f64)> = bins
            .iter()
            .map(|b| (b.mean_prediction, b.count as f64 / samples.max(1) as f64))
            .collect();
        shares.push(Series {
            label: label.clone(),
            style: style(&points),
            points,
        });
    }
    diagram.push(diagonal());
    let top_share = highest(&shares);
    vec![
        Panel {
            title,
            x_label: String::new(),
            y_label: "observed frequency".into(),
            y_range: (-0.02, 1.02),
            series: diagram,
        },
        Panel {
            title: "Share of forecasts per bin".into(),
            x_label: "mean predicted probability in the bin".into(),
            y_label: "share".into(),
            y_range: (0.0, (1.1 * top_share).max(0.01)),
            series: shares,
        },
    ]
}

/// The calibration of intervals (above: the share of values inside the intervals of each
/// nominal coverage against that coverage, the diagonal being perfect calibration; below:
/// their mean width in `width_unit`) of every `(label, [(nominal, coverage)])` in `curves`.
pub fn coverage_panels(
    title: String,
    width_unit: &str,
    curves: &[(String, Vec<(f64, Coverage)>)],
) -> Vec<Panel> {
    let series = |value: fn(&Coverage) -> f64| -> Vec<Series> {
        curves
            .iter()
            .filter(|(_, curve)| !curve.is_empty())
            .map(|(label, curve)| {
                let points: Vec<(f64, f64)> = curve.iter().map(|(n, c)| (*n, value(c))).collect();
                Series {
                    label: label.clone(),
                    style: style(&points),
                    points,
                }
            })
            .collect()
    };
    let mut coverage = series(|c| c.coverage);
    coverage.push(diagonal());
    let widths = series(|c| c.mean_width);
    let widest = highest(&widths);
    vec![
        Panel {
            title,
            x_label: String::new(),
            y_label: "share inside".into(),
            y_range: (-0.02, 1.02),
            series: coverage,
        },
        Panel {
            title: "Mean width of the intervals".into(),
            x_label: "nominal coverage".into(),
            y_label: width_unit.into(),
            y_range: (0.0, (1.1 * widest).max(1e-9)),
            series: widths,
        },
    ]
}
