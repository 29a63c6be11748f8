//! The compression study of [Krajník 2017] §III-B, §IV-A, §IV-C on a uniformly sampled binary
//! series: the order of FFT FreMEn chosen by the prediction error on a hold-out (eq. 15,
//! §IV-B), the spectral model `P` with its outlier set `O` (lossless by eq. 7), the sizes of its
//! files with and without `O` and their compression ratios (eq. 16), and the prediction error
//! on later samples added by eq. (8).
//!
//! Files in, result structs out: the faces read the series, print and write the model.

use std::time::Instant;

use chronomap_core::fft::{FftFremen, FftFremenConfig, edges_of};
use chronomap_core::metrics::compression_ratio;
use chronomap_core::{BuildError, TemporalModel, TimeSeries};
use chronomap_io::ModelFileError;
use chronomap_models::AnyModel;

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

#[cfg(test)]
mod tests {
    use super::*;

    /// One day sampled hourly: on from 08:00 to 17:59 (10 of 24 hours), two changes.
    fn office_day() -> Vec<u8> {
        (0..24).map(|h| u8::from((8..18).contains(&h))).collect()
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
