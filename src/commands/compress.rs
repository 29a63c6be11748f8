//! `chronomap compress`: FFT FreMEn with the outlier set on a uniformly sampled binary series
//! ([Krajník 2017] §III-B, §IV-A, §IV-C).

use anyhow::{Result, bail};
use chronomap_app::compress::{CompressedSeries, continue_with, ones_and_changes, select_order};
use chronomap_core::fft::{FftFremenConfig, uniform_binary_samples};
use chronomap_io::write_any_model;
use chronomap_models::AnyModel;
use serde_json::json;

pub use chronomap_app::compress::{Compression, compress};

use super::model::fft_components_json;
use super::{data_error, fft_components_table, read_series, source_name};
use crate::cli::{CompressArgs, OrderArg};
use crate::format::{duration, time};
use crate::outln;
use crate::output::print_json;

pub fn run(args: &CompressArgs) -> Result<()> {
    let series = read_series(&args.series)?;
    let (start, step, samples) = uniform_binary_samples(&series.times, &series.values)
        .map_err(|e| data_error(&source_name(&args.series), e))?;
    let shortest_period_secs = args.shortest_period.0;
    let mut order_errors = None;
    let order = match args.order {
        OrderArg::Auto => {
            let (best, errors) = select_order(&samples, step, shortest_period_secs)?;
            if !args.json {
                outln!(
                    "order {best} chosen by prediction error on the last 25 % (eq. 15; by order {})",
                    super::errors_by_order(&errors)
                )?;
            }
            order_errors = Some(errors);
            best
        }
        OrderArg::Fixed(k) => k,
    };
    let config = FftFremenConfig {
        order,
        shortest_period_secs,
    };
    let Compression {
        series: report,
        build_ms,
    } = compress(start, step, &samples, config)?;
    let m = &report.model;
    let (ones, changes) = ones_and_changes(&samples)?;
    let mut model = report.model.clone();
    let mut test_result = None;
    if let Some(test) = &args.test {
        let test = read_series(test)?;
        let c = continue_with(&mut model, &test)?;
        test_result = Some((c.samples, c.prediction_error, c.outlier_toggles));
    }
    if args.json {
        print_json(&json!({
            "series": {
                "source": source_name(&args.series),
                "samples": samples.len(),
                "start": start,
                "step_secs": step,
                "changes": changes,
                "ones_fraction": ones as f64 / samples.len() as f64,
            },
            "order": order,
            "order_errors": order_errors,
            "shortest_period_secs": shortest_period_secs,
            "gain": m.gain(),
            "components": fft_components_json(m),
            "outlier_toggles": m.outlier_toggles().len(),
            "estimation_error": m.estimation_error(),
            "lossless": report.lossless,
            "file_bytes": report.file_bytes,
            "lossy_file_bytes": report.lossy_file_bytes,
            "ratio_lossless": report.ratio(report.file_bytes),
            "ratio_lossy": report.ratio(report.lossy_file_bytes),
            "build_ms": build_ms,
            "test": test_result.map(|(samples, error, toggles)| json!({
                "samples": samples,
                "prediction_error": error,
                "outlier_toggles": toggles,
            })),
            "output": args.output.as_ref().map(|p| p.display().to_string()),
        }))?;
    } else {
        print_report(&report, build_ms, start, step, samples.len(), ones, changes)?;
        if let Some((samples, error, toggles)) = test_result {
            outln!(
                "next {samples} samples added by eq. 8: prediction error eps_p = {error:.4} (eq. 15), outlier set now {toggles} toggles"
            )?;
        }
    }
    if let Some(path) = &args.output {
        write_any_model(path, &AnyModel::Fft(model))?;
        if !args.json {
            outln!("wrote {}", path.display())?;
        }
    }
    if !report.lossless {
        bail!("reconstruction is not lossless");
    }
    Ok(())
}

fn print_report(
    report: &CompressedSeries,
    build_ms: f64,
    start: f64,
    step: f64,
    samples: usize,
    ones: usize,
    changes: usize,
) -> std::io::Result<()> {
    let m = &report.model;
    outln!(
        "series: {} samples every {step} s from {} ({}), {} changes, {:.1} % ones",
        samples,
        time(start),
        duration(step * samples as f64),
        changes,
        100.0 * ones as f64 / samples as f64
    )?;
    let table = fft_components_table(m);
    outln!(
        "spectral model P: mean {:.5} and {} components\n{}",
        m.gain(),
        m.components().len(),
        table.render()
    )?;
    outln!(
        "outlier set O: {} toggles ({} intervals); estimation error eps_e = {:.4} (eq. 14-15)",
        m.outlier_toggles().len(),
        m.outlier_toggles().len().div_ceil(2),
        m.estimation_error()
    )?;
    outln!(
        "reconstruction (eq. 7): {}",
        if report.lossless {
            format!("lossless, all {samples} samples equal")
        } else {
            "NOT lossless (this is a bug, please report it)".into()
        }
    )?;
    outln!(
        "model file: {} bytes, compression ratio 1:{:.0} lossless; without the outlier set {} bytes, 1:{:.0} lossy (eq. 16)",
        report.file_bytes,
        report.ratio(report.file_bytes),
        report.lossy_file_bytes,
        report.ratio(report.lossy_file_bytes)
    )?;
    outln!("build time: {build_ms:.2} ms")
}
