//! `chronomap compress`: FFT FreMEn with the outlier set on a uniformly sampled binary series
//! (seed 001 §III-B, §IV-A, §IV-C).

use std::time::Instant;

use anyhow::{Result, bail};
use chronomap_core::TemporalModel;
use chronomap_core::fft::{FftFremen, FftFremenConfig, edges_of, uniform_binary_samples};
use chronomap_io::{encode_model, write_any_model};
use chronomap_models::AnyModel;

use super::{data_error, fft_components_table, read_series, source_name};
use crate::cli::CompressArgs;
use crate::format::{duration, time};

/// What a compressed series looks like.
pub struct CompressionReport {
    pub model: FftFremen,
    pub lossless: bool,
    pub file_bytes: usize,
    pub lossy_file_bytes: usize,
    pub build_ms: f64,
}

impl CompressionReport {
    /// Eq. (16): `r = m·n / z` with `m` observations of `n = 1` state in a file of `z` bits.
    pub fn ratio(&self, bytes: usize) -> f64 {
        self.model.len() as f64 / (8.0 * bytes as f64)
    }
}

/// Builds the model, checks that it is lossless and measures its encoded size.
pub fn compress(
    start: f64,
    step: f64,
    samples: &[u8],
    config: FftFremenConfig,
) -> Result<CompressionReport> {
    let clock = Instant::now();
    let model = FftFremen::build(start, step, samples, config)?;
    let build_ms = clock.elapsed().as_secs_f64() * 1e3;
    let lossless = model.reconstruct() == samples;
    let file_bytes = encode_model("fft", &AnyModel::Fft(model.clone()))?.len();
    let lossy_file_bytes = encode_model("fft", &AnyModel::Fft(model.without_outliers()))?.len();
    Ok(CompressionReport {
        model,
        lossless,
        file_bytes,
        lossy_file_bytes,
        build_ms,
    })
}

pub fn run(args: &CompressArgs) -> Result<()> {
    let series = read_series(&args.series)?;
    let (start, step, samples) = uniform_binary_samples(&series.times, &series.values)
        .map_err(|e| data_error(&source_name(&args.series), e))?;
    let shortest_period_secs = match args.shortest_period.as_str() {
        "none" => None,
        text => match text.parse::<f64>() {
            Ok(p) if p.is_finite() && p > 0.0 => Some(p),
            _ => bail!("--shortest-period {text:?} is not a positive number of seconds or 'none'"),
        },
    };
    let order = match args.order.as_str() {
        "auto" => {
            let config = FftFremenConfig {
                order: 0,
                shortest_period_secs,
            };
            let (best, errors) = FftFremen::select_order(&samples, step, 0.25, 20, config)?;
            let listed: Vec<String> = errors
                .iter()
                .enumerate()
                .map(|(k, e)| format!("{k}:{e:.4}"))
                .collect();
            println!(
                "order {best} chosen by prediction error on the last 25 % (eq. 15; by order {})",
                listed.join(" ")
            );
            best
        }
        text => match text.parse::<usize>() {
            Ok(k) => k,
            Err(_) => bail!("--order {text:?} is not a whole number or 'auto'"),
        },
    };
    let config = FftFremenConfig {
        order,
        shortest_period_secs,
    };
    let report = compress(start, step, &samples, config)?;
    let m = &report.model;
    let ones = samples.iter().filter(|&&s| s == 1).count();
    println!(
        "series: {} samples every {step} s from {} ({}), {} changes, {:.1} % ones",
        samples.len(),
        time(start),
        duration(step * samples.len() as f64),
        edges_of(&samples)?.len(),
        100.0 * ones as f64 / samples.len() as f64
    );
    let table = fft_components_table(m);
    println!(
        "spectral model P: mean {:.5} and {} components\n{}",
        m.gain(),
        m.components().len(),
        table.render()
    );
    println!(
        "outlier set O: {} toggles ({} intervals); estimation error eps_e = {:.4} (eq. 14-15)",
        m.outlier_toggles().len(),
        m.outlier_toggles().len().div_ceil(2),
        m.estimation_error()
    );
    println!(
        "reconstruction (eq. 7): {}",
        if report.lossless {
            format!("lossless, all {} samples equal", samples.len())
        } else {
            "NOT lossless (this is a bug, please report it)".into()
        }
    );
    println!(
        "model file: {} bytes, compression ratio 1:{:.0} lossless; without the outlier set {} bytes, 1:{:.0} lossy (eq. 16)",
        report.file_bytes,
        report.ratio(report.file_bytes),
        report.lossy_file_bytes,
        report.ratio(report.lossy_file_bytes)
    );
    println!("build time: {:.2} ms", report.build_ms);
    let mut model = report.model;
    if let Some(test) = &args.test {
        let test = read_series(test)?;
        let before = model.len();
        model.observe(&test.times, &test.values)?;
        println!(
            "next {} samples added by eq. 8: prediction error eps_p = {:.4} (eq. 15), outlier set now {} toggles",
            test.len(),
            model.error_between(before, model.len()),
            model.outlier_toggles().len()
        );
    }
    if let Some(path) = &args.output {
        write_any_model(path, &AnyModel::Fft(model))?;
        println!("wrote {}", path.display());
    }
    if !report.lossless {
        bail!("reconstruction is not lossless");
    }
    Ok(())
}
