//! Plots: figures from real data render to non-trivial PNG files; bad input gives errors that
//! name the output file.
//!
//! The PNGs are left in cargo's temporary directory for integration tests (`target/tmp/`) so
//! that they can be looked at.

use std::path::{Path, PathBuf};

use chronomap_core::{FremenModel, TemporalModel};
use chronomap_io::plot::{
    Panel, PlotErrorKind, Series, SeriesStyle, SpectrumBar, render_panels_png, render_spectrum_png,
};
use chronomap_io::{read_pairs, read_test_set};

fn data(relative: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../data")
        .join(relative)
}

fn out(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("chronomap-io-plots");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn assert_png(path: &Path, min_bytes: u64) {
    let bytes = std::fs::read(path).unwrap();
    assert!(
        bytes.starts_with(b"\x89PNG\r\n\x1a\n"),
        "{} is not a PNG",
        path.display()
    );
    assert!(
        bytes.len() as u64 >= min_bytes,
        "{} has only {} bytes",
        path.display(),
        bytes.len()
    );
    eprintln!("{}: {} bytes", path.display(), bytes.len());
}

fn greg_models() -> Vec<(String, FremenModel)> {
    let training = read_pairs(data("door_greg_2016/training_data.txt.xz")).unwrap();
    [0, 2, 4]
        .into_iter()
        .map(|order| {
            let mut model = FremenModel::with_order(order);
            model.observe(&training.times, &training.values).unwrap();
            (format!("FreMEn order {order}"), model)
        })
        .collect()
}

#[test]
fn week_of_observations_and_predictions_renders() {
    let week = read_test_set(
        data("door_greg_2016/test_times_1.txt.xz"),
        data("door_greg_2016/test_data_1.txt.xz"),
    )
    .unwrap();
    let t0 = week.times[0];
    let days = |t: f64| (t - t0) / 86_400.0;
    let observed: Vec<(f64, f64)> = week
        .times
        .iter()
        .zip(&week.values)
        .map(|(&t, &v)| (days(t), v))
        .collect();
    let mut panels = vec![Panel {
        title: "Office door, test week 1 (from Monday 2016-03-21)".into(),
        x_label: String::new(),
        y_label: "state".into(),
        y_range: (-0.05, 1.05),
        series: vec![Series {
            label: "observed (1 = open)".into(),
            points: observed.clone(),
            style: SeriesStyle::Step,
        }],
    }];
    let models = greg_models();
    let last = models.len() - 1;
    for (i, (name, model)) in models.iter().enumerate() {
        let prediction: Vec<(f64, f64)> = week
            .times
            .iter()
            .step_by(10)
            .map(|&t| (days(t), model.predict(t)))
            .collect();
        panels.push(Panel {
            title: name.clone(),
            x_label: if i == last {
                "time [days]".into()
            } else {
                String::new()
            },
            y_label: "p(open)".into(),
            y_range: (-0.05, 1.05),
            series: vec![
                Series {
                    label: "observed".into(),
                    points: observed.clone(),
                    style: SeriesStyle::Step,
                },
                Series {
                    label: "prediction p(t)".into(),
                    points: prediction,
                    style: SeriesStyle::Line,
                },
            ],
        });
    }
    let path = out("greg_week1_panels.png");
    render_panels_png(&panels, &path, 1400, 1000).unwrap();
    assert_png(&path, 20_000);
}

#[test]
fn spectrum_of_a_trained_model_renders() {
    let models = greg_models();
    let (_, model) = &models[2];
    let chosen: Vec<f64> = model.components().iter().map(|c| c.period_secs).collect();
    let bars: Vec<SpectrumBar> = model
        .spectrum()
        .iter()
        .map(|c| SpectrumBar {
            period_hours: c.period_secs / 3600.0,
            amplitude: c.amplitude,
            chosen: chosen.contains(&c.period_secs),
        })
        .collect();
    assert_eq!(bars.iter().filter(|b| b.chosen).count(), 4);
    let path = out("greg_spectrum.png");
    render_spectrum_png(
        "Office door (greg 2016): FreMEn spectrum, 4 components chosen",
        &bars,
        &path,
        1100,
        550,
    )
    .unwrap();
    assert_png(&path, 15_000);
}

#[test]
fn all_styles_gaps_and_out_of_range_points_render() {
    let xs: Vec<f64> = (0..200).map(|i| i as f64 * 0.05).collect();
    let mut wave: Vec<(f64, f64)> = xs.iter().map(|&x| (x, 0.5 + 0.6 * x.sin())).collect();
    wave[50].1 = f64::NAN; // a gap in the line
    let dots: Vec<(f64, f64)> = xs
        .iter()
        .step_by(7)
        .map(|&x| (x, (x * 0.3).cos().abs()))
        .collect();
    let steps: Vec<(f64, f64)> = xs
        .iter()
        .step_by(20)
        .map(|&x| (x, f64::from((x as u32) % 2)))
        .collect();
    let panel = Panel {
        title: "Styles".into(),
        x_label: "x".into(),
        y_label: "y".into(),
        y_range: (0.0, 1.0),
        series: vec![
            Series {
                label: "line with a gap, leaving the range".into(),
                points: wave,
                style: SeriesStyle::Line,
            },
            Series {
                label: "dots".into(),
                points: dots,
                style: SeriesStyle::Dots,
            },
            Series {
                label: "steps".into(),
                points: steps,
                style: SeriesStyle::Step,
            },
        ],
    };
    let path = out("styles.png");
    render_panels_png(&[panel], &path, 900, 400).unwrap();
    assert_png(&path, 5_000);
}

#[test]
fn bad_input_gives_errors_naming_the_file() {
    let path = out("never_written.png");
    let panel = Panel {
        title: "p".into(),
        x_label: String::new(),
        y_label: String::new(),
        y_range: (0.0, 1.0),
        series: vec![Series {
            label: "s".into(),
            points: vec![(0.0, 0.5), (1.0, 0.5)],
            style: SeriesStyle::Line,
        }],
    };

    let err = render_panels_png(&[], &path, 800, 400).unwrap_err();
    assert!(matches!(err.kind(), PlotErrorKind::NoPanels));
    assert_eq!(err.path(), path);
    assert_eq!(
        err.to_string(),
        format!("{}: nothing to plot: no panels", path.display())
    );

    let err = render_panels_png(std::slice::from_ref(&panel), &path, 0, 400).unwrap_err();
    assert!(
        matches!(err.kind(), PlotErrorKind::InvalidSize { .. }),
        "{err}"
    );
    let err = render_panels_png(&vec![panel.clone(); 10], &path, 800, 400).unwrap_err();
    assert!(
        matches!(err.kind(), PlotErrorKind::InvalidSize { .. }),
        "{err}"
    );

    let flat = Panel {
        y_range: (1.0, 1.0),
        ..panel.clone()
    };
    let err = render_panels_png(&[flat], &path, 800, 400).unwrap_err();
    assert!(
        matches!(err.kind(), PlotErrorKind::InvalidYRange { panel: 0, .. }),
        "{err}"
    );

    let empty = Panel {
        series: vec![],
        ..panel.clone()
    };
    let err = render_panels_png(&[empty], &path, 800, 400).unwrap_err();
    assert!(matches!(err.kind(), PlotErrorKind::NoData), "{err}");

    let err = render_spectrum_png("s", &[], &path, 800, 400).unwrap_err();
    assert!(matches!(err.kind(), PlotErrorKind::NoData), "{err}");
    let bad = SpectrumBar {
        period_hours: 0.0,
        amplitude: 0.1,
        chosen: false,
    };
    let err = render_spectrum_png("s", &[bad], &path, 800, 400).unwrap_err();
    assert!(
        matches!(err.kind(), PlotErrorKind::InvalidBar { index: 0, .. }),
        "{err}"
    );
    assert!(!path.exists());

    let in_missing_dir = out("no/such/dir/plot.png");
    let err = render_panels_png(&[panel], &in_missing_dir, 800, 400).unwrap_err();
    assert!(matches!(err.kind(), PlotErrorKind::Drawing { .. }), "{err}");
    assert!(
        err.to_string()
            .starts_with(&in_missing_dir.display().to_string()),
        "{err}"
    );
}
