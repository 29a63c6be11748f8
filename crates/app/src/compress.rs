//! The compression study of [Krajník 2017] §III-B, §IV-A, §IV-C on a uniformly sampled binary
//! series: the order of FFT FreMEn chosen by the prediction error on a hold-out (eq. 15,
//! §IV-B), the spectral model `P` with its outlier set `O` (lossless by eq. 7), the sizes of its
//! files with and without `O` and their compression ratios (eq. 16), and the prediction error
//! on later samples added by eq. (8).
//!
//! Files in, result structs out ([`CompressReport`] renders itself as text and JSON): the faces
//! read the series, print and write the model.

use std::time::Instant;

use std::path::Path;

use chronomap_core::fft::{FftFremen, FftFremenConfig, edges_of, uniform_binary_samples};
use chronomap_core::metrics::compression_ratio;
use chronomap_core::{BuildError, TemporalModel, TimeSeries};
use chronomap_io::ModelFileError;
use chronomap_models::AnyModel;
use serde_json::{Value, json};

use crate::model::{DataIssue, errors_by_order, fft_components_json, fft_components_table};
use crate::report::{duration, time};

/// A series compressed by FFT FreMEn: the model, whether it reconstructs the series, and the
/// sizes of its model files (as the model files of `chronomap_io::model_file`).
///
/// ```
/// use chronomap_app::compress::CompressedSeries;
/// use chronomap_core::fft::{FftFremen, FftFremenConfig};
///
/// // A door open 9:00-17:00 every day for a week, one sample a minute.
/// let samples: Vec<u8> = (0..7 * 1440).map(|m| u8::from((540..1020).contains(&(m % 1440)))).collect();
/// let model = FftFremen::build(0.0, 60.0, &samples, FftFremenConfig::with_order(2))?;
/// let compressed = CompressedSeries::measure(model, &samples)?;
/// assert!(compressed.lossless);
/// assert!(compressed.lossy_file_bytes <= compressed.file_bytes);
/// assert!(compressed.ratio(compressed.file_bytes) > 1.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug)]
pub struct CompressedSeries {
    /// The model (spectral set `P` and outlier set `O`).
    pub model: FftFremen,
    /// Whether the model reconstructs every sample (eq. (7)); it always should.
    pub lossless: bool,
    /// Bytes of the model file with the outlier set (lossless).
    pub file_bytes: usize,
    /// Bytes of the model file without the outlier set (lossy).
    pub lossy_file_bytes: usize,
}

impl CompressedSeries {
    /// Checks that `model`, built from `samples`, reconstructs them, and encodes it with and
    /// without its outlier set.
    ///
    /// # Errors
    /// A model that cannot be encoded.
    pub fn measure(model: FftFremen, samples: &[u8]) -> Result<Self, ModelFileError> {
        let lossless = model.reconstruct() == samples;
        let file_bytes = chronomap_io::encode_model("fft", &AnyModel::Fft(model.clone()))?.len();
        let lossy_file_bytes =
            chronomap_io::encode_model("fft", &AnyModel::Fft(model.without_outliers()))?.len();
        Ok(CompressedSeries {
            model,
            lossless,
            file_bytes,
            lossy_file_bytes,
        })
    }

    /// Eq. (16): `r = m·n / z` for the `m` samples of one state (`n = 1`) in a file of `bytes`
    /// bytes.
    pub fn ratio(&self, bytes: usize) -> f64 {
        compression_ratio(self.model.len() as f64, bytes)
    }
}

/// The fraction of the samples, at their end, on which [`select_order`] scores each order.
pub const ORDER_HOLDOUT: f64 = 0.25;

/// The largest order [`select_order`] tries.
pub const MAX_ORDER: usize = 20;

/// Why a series cannot be compressed.
#[derive(Debug, thiserror::Error)]
pub enum CompressError {
    /// The model cannot be built from these samples.
    #[error(transparent)]
    Build(#[from] BuildError),
    /// The model cannot be encoded to measure its file.
    #[error(transparent)]
    File(#[from] ModelFileError),
    /// The series is not uniformly sampled binary data.
    #[error(transparent)]
    Samples(#[from] DataIssue),
}

/// A compressed series and how long the model took to build.
#[derive(Clone, Debug)]
pub struct Compression {
    /// The model and the sizes of its files ([Krajník 2017] eq. 16).
    pub series: CompressedSeries,
    /// Milliseconds spent building the model.
    pub build_ms: f64,
}

/// Builds the FFT FreMEn model of `samples` (`step` seconds apart from `start`), timing the
/// build, and measures its files with and without the outlier set.
///
/// # Errors
/// [`CompressError::Build`] when the model cannot be built, [`CompressError::File`] when it
/// cannot be encoded.
pub fn compress(
    start: f64,
    step: f64,
    samples: &[u8],
    config: FftFremenConfig,
) -> Result<Compression, CompressError> {
    let clock = Instant::now();
    let model = FftFremen::build(start, step, samples, config)?;
    let build_ms = clock.elapsed().as_secs_f64() * 1e3;
    Ok(Compression {
        series: CompressedSeries::measure(model, samples)?,
        build_ms,
    })
}

/// The order of FFT FreMEn with the least prediction error (eq. 15) on the last
/// [`ORDER_HOLDOUT`] of `samples` when built on the rest, trying orders 0 to [`MAX_ORDER`]
/// ([Krajník 2017] §IV-B), none of a period under `shortest_period_secs`; returns it and the error of every order tried.
///
/// # Errors
/// [`BuildError`] from [`FftFremen::select_order`] (too few samples, a bad period).
pub fn select_order(
    samples: &[u8],
    step: f64,
    shortest_period_secs: Option<f64>,
) -> Result<(usize, Vec<f64>), BuildError> {
    let config = FftFremenConfig {
        order: 0,
        shortest_period_secs,
    };
    FftFremen::select_order(samples, step, ORDER_HOLDOUT, MAX_ORDER, config)
}

/// How many samples are 1 and how many times the state changes.
///
/// # Errors
/// A sample that is neither 0 nor 1.
pub fn ones_and_changes(samples: &[u8]) -> Result<(usize, usize), BuildError> {
    let ones = samples.iter().filter(|&&s| s == 1).count();
    let changes = edges_of(samples)?.len();
    Ok((ones, changes))
}

/// What adding later samples by eq. (8) did to a model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Continuation {
    /// The samples added.
    pub samples: usize,
    /// Their prediction error `eps_p` (eq. 15): the fraction that the outlier set had to
    /// correct.
    pub prediction_error: f64,
    /// Toggles in the outlier set afterwards.
    pub outlier_toggles: usize,
}

/// Adds the samples of `test` to `model` by eq. (8) and measures their prediction error.
///
/// # Errors
/// [`BuildError`] for observations the model cannot take (not after its samples, not on its
/// sampling grid, not binary).
pub fn continue_with(model: &mut FftFremen, test: &TimeSeries) -> Result<Continuation, BuildError> {
    let before = model.len();
    model.observe(&test.times, &test.values)?;
    Ok(Continuation {
        samples: test.len(),
        prediction_error: model.error_between(before, model.len()),
        outlier_toggles: model.outlier_toggles().len(),
    })
}

/// A series as uniformly spaced binary samples, the input of FFT FreMEn ([Krajník 2017]
/// §III-B).
#[derive(Clone, Debug)]
pub struct Samples {
    /// Where the series came from.
    pub source: String,
    /// Time of the first sample.
    pub start: f64,
    /// Seconds between samples.
    pub step: f64,
    /// The states, 0 or 1.
    pub samples: Vec<u8>,
}

/// The order [`select_order`] chose and the prediction error of every order tried.
#[derive(Clone, Debug, PartialEq)]
pub struct ChosenOrder {
    /// The order.
    pub order: usize,
    /// Eq. (15) on the hold-out, by order from 0 up.
    pub errors: Vec<f64>,
}

impl ChosenOrder {
    /// The line `chronomap compress --order auto` prints as soon as the order is chosen.
    pub fn text(&self) -> String {
        format!(
            "order {} chosen by prediction error on the last 25 % (eq. 15; by order {})",
            self.order,
            errors_by_order(&self.errors)
        )
    }
}

impl Samples {
    /// The samples of `series` (named `source`).
    ///
    /// # Errors
    /// [`DataIssue`] naming the observation that is not binary or not on the sampling grid.
    pub fn of(source: &str, series: &TimeSeries) -> Result<Samples, DataIssue> {
        let (start, step, samples) = uniform_binary_samples(&series.times, &series.values)
            .map_err(|error| DataIssue {
                source_name: source.to_string(),
                error,
            })?;
        Ok(Samples {
            source: source.to_string(),
            start,
            step,
            samples,
        })
    }

    /// The order with the least prediction error ([`select_order`]).
    ///
    /// # Errors
    /// Too few samples, or a bad shortest period.
    pub fn choose_order(
        &self,
        shortest_period_secs: Option<f64>,
    ) -> Result<ChosenOrder, BuildError> {
        let (order, errors) = select_order(&self.samples, self.step, shortest_period_secs)?;
        Ok(ChosenOrder { order, errors })
    }

    /// The study of these samples with FFT FreMEn of `order` (or the order `chosen`, which
    /// the report then names): the model, its files, and the later samples `test` added by
    /// eq. (8).
    ///
    /// # Errors
    /// [`CompressError`]: a model that cannot be built or encoded, test samples it cannot take.
    pub fn study(
        self,
        order: usize,
        chosen: Option<ChosenOrder>,
        shortest_period_secs: Option<f64>,
        test: Option<&TimeSeries>,
    ) -> Result<CompressReport, CompressError> {
        let config = FftFremenConfig {
            order,
            shortest_period_secs,
        };
        let compression = compress(self.start, self.step, &self.samples, config)?;
        let (ones, changes) = ones_and_changes(&self.samples)?;
        let mut model = compression.series.model.clone();
        let test = test.map(|t| continue_with(&mut model, t)).transpose()?;
        Ok(CompressReport {
            samples: self,
            ones,
            changes,
            order,
            chosen,
            shortest_period_secs,
            compression,
            test,
            model,
        })
    }
}

/// The compression study of one series, as `chronomap compress` reports it.
#[derive(Clone, Debug)]
pub struct CompressReport {
    /// The series.
    pub samples: Samples,
    /// Samples that are 1.
    pub ones: usize,
    /// Changes of state.
    pub changes: usize,
    /// The order of the model.
    pub order: usize,
    /// How the order was chosen, if it was.
    pub chosen: Option<ChosenOrder>,
    /// The shortest period considered.
    pub shortest_period_secs: Option<f64>,
    /// The model of the series and its files.
    pub compression: Compression,
    /// What the test samples did, if any were added.
    pub test: Option<Continuation>,
    /// The model with the test samples added: the one to write.
    pub model: FftFremen,
}

impl CompressReport {
    /// The report as `chronomap compress --json` prints it, naming the model file `output`.
    pub fn json(&self, output: Option<&Path>) -> Value {
        let (s, report) = (&self.samples, &self.compression.series);
        let m = &report.model;
        json!({
            "series": {
                "source": s.source,
                "samples": s.samples.len(),
                "start": s.start,
                "step_secs": s.step,
                "changes": self.changes,
                "ones_fraction": self.ones as f64 / s.samples.len() as f64,
            },
            "order": self.order,
            "order_errors": self.chosen.as_ref().map(|c| &c.errors),
            "shortest_period_secs": self.shortest_period_secs,
            "gain": m.gain(),
            "components": fft_components_json(m),
            "outlier_toggles": m.outlier_toggles().len(),
            "estimation_error": m.estimation_error(),
            "lossless": report.lossless,
            "file_bytes": report.file_bytes,
            "lossy_file_bytes": report.lossy_file_bytes,
            "ratio_lossless": report.ratio(report.file_bytes),
            "ratio_lossy": report.ratio(report.lossy_file_bytes),
            "build_ms": self.compression.build_ms,
            "test": self.test.map(|c| json!({
                "samples": c.samples,
                "prediction_error": c.prediction_error,
                "outlier_toggles": c.outlier_toggles,
            })),
            "output": output.map(|p| p.display().to_string()),
        })
    }

    /// The report as `chronomap compress` prints it (after the chosen order's line): the
    /// series, `P` and `O`, whether it is lossless (eq. 7), the files (eq. 16), the build
    /// time, and the prediction error of the test samples.
    pub fn text(&self) -> String {
        let (s, report) = (&self.samples, &self.compression.series);
        let (m, samples) = (&report.model, s.samples.len());
        let mut lines = vec![
            format!(
                "series: {} samples every {} s from {} ({}), {} changes, {:.1} % ones",
                samples,
                s.step,
                time(s.start),
                duration(s.step * samples as f64),
                self.changes,
                100.0 * self.ones as f64 / samples as f64
            ),
            format!(
                "spectral model P: mean {:.5} and {} components\n{}",
                m.gain(),
                m.components().len(),
                fft_components_table(m).render()
            ),
            format!(
                "outlier set O: {} toggles ({} intervals); estimation error eps_e = {:.4} (eq. 14-15)",
                m.outlier_toggles().len(),
                m.outlier_toggles().len().div_ceil(2),
                m.estimation_error()
            ),
            format!(
                "reconstruction (eq. 7): {}",
                if report.lossless {
                    format!("lossless, all {samples} samples equal")
                } else {
                    "NOT lossless (this is a bug, please report it)".into()
                }
            ),
            format!(
                "model file: {} bytes, compression ratio 1:{:.0} lossless; without the outlier set {} bytes, 1:{:.0} lossy (eq. 16)",
                report.file_bytes,
                report.ratio(report.file_bytes),
                report.lossy_file_bytes,
                report.ratio(report.lossy_file_bytes)
            ),
            format!("build time: {:.2} ms", self.compression.build_ms),
        ];
        if let Some(c) = &self.test {
            lines.push(format!(
                "next {} samples added by eq. 8: prediction error eps_p = {:.4} (eq. 15), outlier set now {} toggles",
                c.samples, c.prediction_error, c.outlier_toggles
            ));
        }
        lines.join("\n")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One day sampled hourly: on from 08:00 to 17:59 (10 of 24 hours), two changes.
    fn office_day() -> Vec<u8> {
        (0..24).map(|h| u8::from((8..18).contains(&h))).collect()
    }

    #[test]
    fn the_study_of_a_week_reports_its_changes_and_a_repeated_day() {
        // A week of office days sampled hourly, then the same day again.
        let times: Vec<f64> = (0..24 * 8).map(|h| h as f64 * 3600.0).collect();
        let values: Vec<f64> = (0..8).flat_map(|_| office_day()).map(f64::from).collect();
        let week = TimeSeries {
            times: times[..168].to_vec(),
            values: values[..168].to_vec(),
        };
        let day8 = TimeSeries {
            times: times[168..].to_vec(),
            values: values[168..].to_vec(),
        };
        let samples = Samples::of("week.txt", &week).unwrap();
        assert_eq!((samples.start, samples.step), (0.0, 3600.0));
        let report = samples.study(1, None, None, Some(&day8)).unwrap();
        assert_eq!((report.ones, report.changes), (70, 14));
        assert_eq!(report.model.len(), 192);
        let text = report.text();
        assert!(
            text.starts_with("series: 168 samples every 3600 s from "),
            "{text}"
        );
        assert!(text.contains("14 changes, 41.7 % ones"), "{text}");
        assert!(text.contains("reconstruction (eq. 7): lossless, all 168 samples equal"));
        assert!(text.ends_with("toggles"), "{text}");
        let json = report.json(None);
        assert_eq!(json["series"]["changes"], 14);
        assert_eq!(json["test"]["samples"], 24);
        assert_eq!(json["order_errors"], Value::Null);

        let bad = TimeSeries {
            times: vec![0.0, 1.0],
            values: vec![0.0, 0.5],
        };
        let error = Samples::of("bad.txt", &bad).unwrap_err().to_string();
        assert!(error.starts_with("bad.txt: "), "{error}");
    }

    #[test]
    fn counts_ones_and_changes() {
        assert_eq!(ones_and_changes(&office_day()).unwrap(), (10, 2));
        assert!(ones_and_changes(&[0, 2]).is_err());
    }

    #[test]
    fn a_compressed_week_is_lossless_and_later_days_cost_nothing_when_they_repeat() {
        let days = 7;
        let samples: Vec<u8> = (0..days).flat_map(|_| office_day()).collect();
        let config = FftFremenConfig {
            order: 1,
            shortest_period_secs: None,
        };
        let compressed = compress(0.0, 3600.0, &samples, config).unwrap();
        assert!(compressed.series.lossless);
        assert_eq!(compressed.series.model.len(), 24 * days as u64);
        assert!(compressed.series.lossy_file_bytes <= compressed.series.file_bytes);
        // The eighth day: the same day again, appended by eq. (8).
        let mut model = compressed.series.model.clone();
        let times: Vec<f64> = (0..24).map(|h| (24 * days + h) as f64 * 3600.0).collect();
        let values: Vec<f64> = office_day().iter().map(|&s| f64::from(s)).collect();
        let test = TimeSeries { times, values };
        let c = continue_with(&mut model, &test).unwrap();
        assert_eq!(c.samples, 24);
        assert_eq!(model.len(), 24 * (days as u64 + 1));
        // Whatever order 1 misses on a day it misses on every day: eps_p equals eps_e.
        assert_eq!(
            c.prediction_error,
            compressed.series.model.estimation_error()
        );
    }
}
