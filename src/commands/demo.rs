//! `chronomap demo`: the main job on bundled real data. Evaluates the temporal models on the
//! door datasets beside the original FreMEn code's published figures, compresses the one-second
//! door week with FFT FreMEn, and draws the FreMEn paper's figures 2 and 3 for these data
//! (`chronomap_app::demo` runs the studies and writes their text, this prints and draws).

use std::path::Path;

use anyhow::{Context, Result};
use chronomap_app::demo::{GREG_MODELS, TOM_MODELS, evaluate_doors, fft_text, greg_text, tom_text};
use chronomap_core::TimeSeries;
use chronomap_core::{FremenModel, Ordered, Parallelism, TemporalModel};
use chronomap_models::AnyModel;
use chronomap_models::eval::EvalReport;
use chronomap_plot::{
    Panel, Series, SeriesStyle, SpectrumBar, render_panels_png, render_spectrum_png,
};

use crate::bundled;
use crate::cli::DemoArgs;
use crate::format::{duration, time};
use crate::outln;
use crate::output::ProgressBar;

pub fn run(args: &DemoArgs) -> Result<()> {
    outln!("chronomap demo: temporal models of real doors, beside the original FreMEn code\n")?;

    // 1. Greg's door.
    let train = bundled::GREG_TRAINING.pairs()?;
    let tests = bundled::test_sets(&bundled::GREG_TESTS)?;
    let greg = evaluate_doors(
        GREG_MODELS,
        &train,
        &tests,
        "greg door: fitting",
        &ProgressBar::new(),
    )?;
    outln!("{}", greg_text(&train, &tests, &greg))?;

    // 2. Tom's door, one week at one minute.
    let tom_train = bundled::TOM_TRAINING.pairs()?;
    let tom_tests = bundled::test_sets(&bundled::TOM_TESTS)?;
    let tom = evaluate_doors(
        TOM_MODELS,
        &tom_train,
        &tom_tests,
        "tom door: fitting",
        &ProgressBar::new(),
    )?;
    outln!("{}", tom_text(&tom))?;

    // 3. FFT FreMEn on the one-second week.
    let week = bundled::test_set(&bundled::TOM_SECONDS_WEEK)?;
    let day8 = bundled::test_set(&bundled::TOM_SECONDS_DAY8)?;
    outln!("{}", fft_text(&week, &day8, &ProgressBar::new())?)?;

    if !args.no_plots {
        std::fs::create_dir_all(&args.output)
            .with_context(|| format!("cannot create {}", args.output.display()))?;
    }
    let out = (!args.no_plots).then_some(args.output.as_path());
    let mut written = super::demo_grids::run(out)?;
    written.extend(super::demo_topo::run(out)?);
    if !args.no_plots {
        let bar = ProgressBar::stage("plots", 0);
        let figures = plots(&args.output, &tom_train, &train, &tests[0], &greg)?;
        drop(bar);
        written.splice(0..0, figures);
        outln!("\n6. Files written:")?;
        for path in written {
            outln!("   {}", path)?;
        }
    }
    Ok(())
}

/// Figures 2 and 3 of the FreMEn paper for the tom door, and the same for a greg test week.
fn plots(
    out: &Path,
    tom_train: &TimeSeries,
    greg_train: &TimeSeries,
    greg_week: &TimeSeries,
    greg: &EvalReport,
) -> Result<Vec<String>> {
    let mut written = Vec::new();

    // Fig. 3: week-long model of the tom door with orders 0, 1 and 4.
    let mut tom = FremenModel::with_order(4);
    tom.observe_par(&tom_train.times, &tom_train.values, Parallelism::Rayon(0))?;
    let mut panels = Vec::new();
    for (order, title) in [
        (
            0,
            "Static model (order 0): the door is open with constant probability",
        ),
        (1, "FreMEn order 1: one daily process"),
        (4, "FreMEn order 4: daily and weekly processes"),
    ] {
        tom.set_order(order);
        let x_label = if order == 4 {
            "days since the start of the week"
        } else {
            ""
        };
        panels.push(observed_and_predicted(title, x_label, tom_train, &tom));
    }
    let path = out.join("tom_door_week.png");
    render_panels_png(&panels, &path, 1400, 1000)?;
    written.push(format!(
        "{}  (like Fig. 3 of the FreMEn paper)",
        path.display()
    ));

    // Fig. 2: amplitude spectrum with the chosen components.
    tom.set_order(4);
    let path = out.join("tom_door_spectrum.png");
    render_spectrum_png(
        "Tom door week: |gamma| per candidate period, the 4 components of order 4 highlighted",
        &spectrum_bars(&tom),
        &path,
        1200,
        600,
    )?;
    written.push(format!("{}  (like Fig. 2)", path.display()));

    // Greg: predictions for an unseen week by the models the demo evaluated.
    let mut panels = Vec::new();
    for name in ["mean", "fremen:2", "fremen:auto", "auto"] {
        let Some(m) = greg.models.iter().find(|m| m.spec.to_string() == name) else {
            continue;
        };
        let title = format!(
            "{name} (fitted as {}), Brier score {:.4} on this week",
            m.fitted.model.fitted_as(),
            m.tests[0].mse
        );
        let x_label = if name == "auto" {
            format!("days since {}", time(greg_week.times[0]))
        } else {
            String::new()
        };
        panels.push(observed_and_predicted(
            &title,
            &x_label,
            greg_week,
            &m.fitted.model,
        ));
    }
    let path = out.join("greg_door_test_week.png");
    render_panels_png(&panels, &path, 1400, 1200)?;
    written.push(format!(
        "{}  (predictions for test week 1, never seen in training)",
        path.display()
    ));

    if let Some(m) = greg
        .models
        .iter()
        .find(|m| m.spec.to_string() == "fremen:auto")
        && let AnyModel::Fremen(fremen) = &m.fitted.model
    {
        let path = out.join("greg_door_spectrum.png");
        render_spectrum_png(
            &format!(
                "Greg door, {} of training: |gamma| per period, the {} components of fremen:auto highlighted",
                duration(greg_train.times[greg_train.len() - 1] - greg_train.times[0]),
                fremen.order()
            ),
            &spectrum_bars(fremen),
            &path,
            1200,
            600,
        )?;
        written.push(path.display().to_string());
    }
    Ok(written)
}

/// A panel with the observed series as a staircase and the model's `p(t)` at the same times,
/// over days since the first observation.
fn observed_and_predicted(
    title: &str,
    x_label: &str,
    series: &TimeSeries,
    model: &dyn TemporalModel,
) -> Panel {
    let t0 = series.times[0];
    let day = |t: f64| (t - t0) / 86_400.0;
    let predictions = model.predict_many(&series.times);
    Panel {
        title: title.into(),
        x_label: x_label.into(),
        y_label: "state / p(t)".into(),
        y_range: (-0.05, 1.05),
        series: vec![
            Series {
                label: "observed s(t)".into(),
                points: series
                    .times
                    .iter()
                    .zip(&series.values)
                    .map(|(&t, &v)| (day(t), v))
                    .collect(),
                style: SeriesStyle::Step,
            },
            Series {
                label: "predicted p(t)".into(),
                points: series
                    .times
                    .iter()
                    .zip(predictions)
                    .map(|(&t, p)| (day(t), p))
                    .collect(),
                style: SeriesStyle::Line,
            },
        ],
    }
}

fn spectrum_bars(model: &FremenModel) -> Vec<SpectrumBar> {
    let used: Vec<f64> = model.components().iter().map(|c| c.period_secs).collect();
    let spectrum = model.spectrum();
    SpectrumBar::from_spectrum(spectrum.iter().map(|c| (c.period_secs, c.amplitude)), &used)
}
