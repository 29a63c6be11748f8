//! Plots: figures from real data render to non-trivial PNG files; bad input gives errors that
//! name the output file.
//!
//! The PNGs are left in cargo's temporary directory for integration tests (`target/tmp/`) so
//! that they can be looked at.

use std::path::{Path, PathBuf};

use chronomap_core::{FremenModel, TemporalModel};
use chronomap_io::{read_pairs, read_test_set};
use chronomap_plot::{
    HEATMAP_NO_VALUE, Heatmap, HeatmapLayout, Panel, PlotError, PlotErrorKind, Series, SeriesStyle,
    SpectrumBar, heatmap_colour, render_heatmap_png, render_panels_png, render_spectrum_png,
};
use chronomap_testutil::{data_path as data, shared_dir};

/// Where a test's PNG goes: `target/tmp/chronomap-io-plots/NAME` (kept, to be looked at).
fn out(name: &str) -> PathBuf {
    shared_dir(Path::new(env!("CARGO_TARGET_TMPDIR")).join("chronomap-io-plots")).join(name)
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
    let spectrum = model.spectrum();
    let bars = SpectrumBar::from_spectrum(
        spectrum.iter().map(|c| (c.period_secs, c.amplitude)),
        &chosen,
    );
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

    // Renders `panels`, which must fail with an error of a kind `is_kind` accepts.
    let panels_err = |panels: &[Panel], width, height, is_kind: fn(&PlotErrorKind) -> bool| {
        let err = render_panels_png(panels, &path, width, height).unwrap_err();
        assert!(is_kind(err.kind()), "{err}");
        err
    };

    let err = panels_err(&[], 800, 400, |k| matches!(k, PlotErrorKind::NoPanels));
    assert_eq!(err.path(), path);
    assert_eq!(
        err.to_string(),
        format!("{}: nothing to plot: no panels", path.display())
    );

    let invalid_size = |k: &PlotErrorKind| matches!(k, PlotErrorKind::InvalidSize { .. });
    panels_err(std::slice::from_ref(&panel), 0, 400, invalid_size);
    panels_err(&vec![panel.clone(); 10], 800, 400, invalid_size);

    let flat = Panel {
        y_range: (1.0, 1.0),
        ..panel.clone()
    };
    panels_err(&[flat], 800, 400, |k| {
        matches!(k, PlotErrorKind::InvalidYRange { panel: 0, .. })
    });

    let empty = Panel {
        series: vec![],
        ..panel.clone()
    };
    panels_err(&[empty], 800, 400, |k| matches!(k, PlotErrorKind::NoData));

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
    assert_no_temporary_file(&err);
    assert!(
        err.to_string()
            .starts_with(&in_missing_dir.display().to_string()),
        "{err}"
    );
}

/// `err` is the failure to create the temporary file beside the image (the one output writer
/// writes it there and renames it over the image), as in a folder that does not exist.
fn assert_no_temporary_file(err: &PlotError) {
    assert!(
        matches!(
            err.kind(),
            PlotErrorKind::Write {
                action: "create a temporary file for",
                ..
            }
        ),
        "{err}"
    );
}

/// A decoded 8-bit RGB or RGBA PNG: width, height and one `[r, g, b]` per pixel.
struct Decoded {
    width: u32,
    height: u32,
    rgb: Vec<[u8; 3]>,
}

impl Decoded {
    fn read(path: &Path) -> Decoded {
        let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
        let mut reader = decoder.read_info().unwrap();
        let mut buffer = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buffer).unwrap();
        assert_eq!(info.bit_depth, png::BitDepth::Eight);
        let channels = match info.color_type {
            png::ColorType::Rgb => 3,
            png::ColorType::Rgba => 4,
            other => panic!("unexpected colour type {other:?}"),
        };
        let rgb = buffer[..info.buffer_size()]
            .chunks_exact(channels)
            .map(|p| [p[0], p[1], p[2]])
            .collect();
        Decoded {
            width: info.width,
            height: info.height,
            rgb,
        }
    }

    fn at(&self, (x, y): (u32, u32)) -> [u8; 3] {
        assert!(x < self.width && y < self.height, "({x}, {y}) is outside");
        self.rgb[(y * self.width + x) as usize]
    }
}

fn rgb(colour: plotters::style::RGBColor) -> [u8; 3] {
    [colour.0, colour.1, colour.2]
}

/// A point of the cell's background: the middle of its left padding, where no text is drawn.
fn background_of(layout: &HeatmapLayout, row: usize, column: usize) -> (u32, u32) {
    let (_, y) = layout.cell_centre(row, column);
    let x = layout.grid_left + layout.cell_width * column as u32 + 3;
    (x, y)
}

/// The pixels of a cell (without its white separators).
fn cell_pixels(image: &Decoded, layout: &HeatmapLayout, row: usize, column: usize) -> Vec<[u8; 3]> {
    let left = layout.grid_left + layout.cell_width * column as u32;
    let top = layout.grid_top + layout.cell_height * row as u32;
    (top..top + layout.cell_height - 1)
        .flat_map(|y| (left..left + layout.cell_width - 1).map(move |x| (x, y)))
        .map(|p| image.at(p))
        .collect()
}

fn small_heatmap() -> Heatmap {
    Heatmap {
        title: "Small".into(),
        row_label: "time".into(),
        column_label: "day".into(),
        rows: vec!["00:00".into(), "12:00".into()],
        columns: vec!["Mon".into(), "Tue".into(), "Wed".into()],
        values: vec![0.0, 1.0, f64::NAN, 0.5, 0.25, 0.75],
        cell_text: ["a", "b", "", "a", "ab", "b"].map(String::from).to_vec(),
        value_label: "Pmax".into(),
        legend: vec!["a = Station_LabDoor1".into(), "b = LabDesk_LabDoor1".into()],
    }
}

/// Renders `map` as `name` and checks that the image has the size of the map's layout, that
/// the layout has 90 × 26-pixel cells below a grid top at 96 (both test tables have the same
/// titles and widest cell text) and that it is `height` pixels high; returns the layout, the
/// file and the image.
fn render_heatmap(map: &Heatmap, name: &str, height: u32) -> (HeatmapLayout, PathBuf, Decoded) {
    let layout = map.layout().unwrap();
    let path = out(name);
    render_heatmap_png(map, &path).unwrap();
    let image = Decoded::read(&path);
    assert_eq!((image.width, image.height), (layout.width, layout.height));
    assert_eq!((layout.cell_width, layout.cell_height), (90, 26));
    assert_eq!(layout.grid_top, 96);
    assert_eq!(layout.height, height);
    (layout, path, image)
}

#[test]
fn heat_map_cells_have_the_colours_of_the_colour_map() {
    let map = small_heatmap();
    // 90-pixel cells (the minimum: "0.25 ab" is narrower), 26-pixel rows; 2 rows are shorter
    // than the colour bar (120 pixels + 34 for the "no value" swatch), which sets the height:
    // top margin 14 + title 34 + column title 24 + column labels 24 = grid top 96, + 154,
    // + gap 16 + 2 legend lines of 21 + bottom margin 14 = 322.
    let (layout, _, image) = render_heatmap(&map, "heatmap_small.png", 322);
    assert_eq!(layout.bar_left, layout.grid_left + 3 * 90 + 24);

    let zero = image.at(background_of(&layout, 0, 0));
    let one = image.at(background_of(&layout, 0, 1));
    assert_ne!(zero, one);
    assert_eq!(zero, rgb(heatmap_colour(0.0)));
    assert_eq!(zero, [68, 1, 84]); // viridis' dark purple
    assert_eq!(one, rgb(heatmap_colour(1.0)));
    assert_eq!(one, [253, 231, 37]); // viridis' yellow
    assert_eq!(
        image.at(background_of(&layout, 0, 2)),
        rgb(HEATMAP_NO_VALUE)
    );
    for (row, column, value) in [(1, 0, 0.5), (1, 1, 0.25), (1, 2, 0.75)] {
        assert_eq!(
            image.at(background_of(&layout, row, column)),
            rgb(heatmap_colour(value))
        );
    }
    // The 1-pixel separator between cells is white.
    let (x, y) = layout.cell_centre(0, 0);
    assert_eq!(image.at((layout.grid_left + 89, y)), [255, 255, 255]);
    assert_eq!(image.at((x, layout.grid_top + 25)), [255, 255, 255]);

    // Text contrasts with its cell: white on the dark cell, black on the light one, and the
    // cell without value or text is plain grey.
    let dark = cell_pixels(&image, &layout, 0, 0);
    assert!(
        dark.contains(&[255, 255, 255]),
        "no white text on the 0 cell"
    );
    assert!(!dark.iter().any(|p| p.iter().all(|&c| c < 40)));
    let light = cell_pixels(&image, &layout, 0, 1);
    assert!(light.contains(&[0, 0, 0]), "no black text on the 1 cell");
    assert!(!light.contains(&[255, 255, 255]));
    let empty = cell_pixels(&image, &layout, 0, 2);
    assert!(empty.iter().all(|&p| p == rgb(HEATMAP_NO_VALUE)));

    // The colour bar runs from 1 at the top to 0 at the bottom.
    let bar_x = layout.bar_left + 9;
    assert_eq!(image.at((bar_x, layout.bar_top)), one);
    assert_eq!(
        image.at((bar_x, layout.bar_top + layout.bar_height - 1)),
        zero
    );
}

/// A "now or later?" table like [Fentanes 2015] Table III: 24 start times × 7 days, the maximum
/// probability of completing the task and a code for the first edge.
fn week_table() -> Heatmap {
    let days = ["Mon", "Tue", "Wed", "Thu", "Fri", "Sat", "Sun"];
    let mut values = Vec::new();
    let mut cell_text = Vec::new();
    for hour in 0..24 {
        for (day, _) in days.iter().enumerate() {
            let office_hours = day < 5 && (8..18).contains(&hour);
            let (value, code) = if day == 6 && hour < 6 {
                (f64::NAN, "")
            } else if office_hours {
                (0.9 + 0.01 * f64::from((hour + day as u32) % 9), "a")
            } else if day >= 5 {
                (0.35 + 0.02 * f64::from(hour % 12), "c")
            } else if (6..22).contains(&hour) {
                (0.6 + 0.015 * f64::from(hour % 10), "b")
            } else {
                (0.05 * f64::from(hour % 6), "d")
            };
            values.push(value);
            cell_text.push(code.to_owned());
        }
    }
    Heatmap {
        title: "Now or later? Pmax of \"F LabDesk\" from Station, week of 2014-09-08".into(),
        row_label: "start time (UTC)".into(),
        column_label: "day".into(),
        rows: (0..24).map(|h| format!("{h:02}:00")).collect(),
        columns: days
            .iter()
            .enumerate()
            .map(|(i, d)| format!("{d} 09-{:02}", 8 + i))
            .collect(),
        values,
        cell_text,
        value_label: "Pmax".into(),
        legend: vec![
            "a = Station_LabDoor1".into(),
            "b = LabDesk_LabDoor1".into(),
            "c = Station_Corridor2".into(),
            "d = Station_Kitchen (wait)".into(),
        ],
    }
}

#[test]
fn a_week_of_now_or_later_renders() {
    let map = week_table();
    // grid 24 × 26 = 624, + gap 16 + 4 legend lines of 21 + margin 14
    let height = 96 + 624 + 16 + 4 * 21 + 14;
    let (layout, path, image) = render_heatmap(&map, "heatmap_week.png", height);
    assert_png(&path, 20_000);
    assert_eq!(
        image.at(background_of(&layout, 0, 6)),
        rgb(HEATMAP_NO_VALUE)
    );
    assert_eq!(
        image.at(background_of(&layout, 12, 2)),
        rgb(heatmap_colour(map.values[12 * 7 + 2]))
    );
}

#[test]
fn bad_heat_maps_give_errors_naming_the_file() {
    let path = out("never_written_heatmap.png");
    let good = small_heatmap();
    // Renders `map`, which must fail naming the file with an error of a kind `is_kind` accepts.
    let check = |map: &Heatmap, is_kind: fn(&PlotErrorKind) -> bool| {
        let err = render_heatmap_png(map, &path).unwrap_err();
        assert!(is_kind(err.kind()), "{err}");
        assert_eq!(err.path(), path);
        assert!(
            err.to_string().starts_with(&path.display().to_string()),
            "{err}"
        );
        err
    };

    let no_rows = Heatmap {
        rows: vec![],
        values: vec![],
        cell_text: vec![],
        ..good.clone()
    };
    let err = check(&no_rows, |k| {
        matches!(
            k,
            PlotErrorKind::EmptyGrid {
                rows: 0,
                columns: 3
            }
        )
    });
    assert_eq!(
        err.to_string(),
        format!(
            "{}: nothing to plot: the heat map has 0 rows and 3 columns",
            path.display()
        )
    );
    let no_columns = Heatmap {
        columns: vec![],
        ..no_rows.clone()
    };
    check(&no_columns, |k| {
        matches!(k, PlotErrorKind::EmptyGrid { columns: 0, .. })
    });

    let mut short = good.clone();
    short.values.pop();
    let err = check(&short, |k| {
        matches!(
            k,
            PlotErrorKind::ValueCount {
                rows: 2,
                columns: 3,
                found: 5
            }
        )
    });
    assert!(
        err.to_string()
            .ends_with("the heat map has 5 values for 2 rows × 3 columns")
    );

    let mut texts = good.clone();
    texts.cell_text.push("x".into());
    check(&texts, |k| {
        matches!(k, PlotErrorKind::CellTextCount { found: 7, .. })
    });
    let no_texts = Heatmap {
        cell_text: vec![],
        ..good.clone()
    };
    no_texts.validate().unwrap();

    for bad in [1.5, -0.01, f64::INFINITY, f64::NEG_INFINITY] {
        let mut map = good.clone();
        map.values[4] = bad;
        let err = check(&map, |k| matches!(k, PlotErrorKind::ValueOutOfRange { .. }));
        match err.kind() {
            PlotErrorKind::ValueOutOfRange {
                row: 1,
                column: 1,
                row_label,
                column_label,
                value,
            } => {
                assert_eq!(
                    (row_label.as_str(), column_label.as_str()),
                    ("12:00", "Tue")
                );
                assert_eq!(*value, bad);
            }
            other => panic!("{other}"),
        }
        assert!(
            err.to_string()
                .contains(r#"row 1 ("12:00"), column 1 ("Tue")"#),
            "{err}"
        );
    }

    // 400 rows of 26 pixels are more than the 8192 an image may have.
    let tall = Heatmap {
        rows: (0..400).map(|i| i.to_string()).collect(),
        columns: vec!["x".into()],
        values: vec![0.5; 400],
        cell_text: vec![],
        ..good.clone()
    };
    check(
        &tall,
        |k| matches!(k, PlotErrorKind::InvalidSize { height, .. } if *height > 8192),
    );
    assert!(!path.exists());

    let in_missing_dir = out("no/such/dir/heatmap.png");
    let err = render_heatmap_png(&good, &in_missing_dir).unwrap_err();
    assert_no_temporary_file(&err);
    assert_eq!(err.path(), in_missing_dir);
}
