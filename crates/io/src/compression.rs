//! How small a model file makes a series: FFT FreMEn with its outlier set ([Krajník 2017] §III-B,
//! §IV-C) encoded as the model files of [`crate::model_file`], with and without the outlier
//! set, and the compression ratios of eq. (16).
//!
//! ```
//! use chronomap_core::fft::{FftFremen, FftFremenConfig};
//! use chronomap_io::compression::CompressedSeries;
//!
//! // A door open 9:00-17:00 every day for a week, one sample a minute.
//! let samples: Vec<u8> = (0..7 * 1440).map(|m| u8::from((540..1020).contains(&(m % 1440)))).collect();
//! let model = FftFremen::build(0.0, 60.0, &samples, FftFremenConfig::with_order(2))?;
//! let compressed = CompressedSeries::measure(model, &samples)?;
//! assert!(compressed.lossless);
//! assert!(compressed.lossy_file_bytes <= compressed.file_bytes);
//! assert!(compressed.ratio(compressed.file_bytes) > 1.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use chronomap_core::fft::FftFremen;
use chronomap_core::metrics::compression_ratio;
use chronomap_models::AnyModel;

use crate::model_file::{ModelFileError, encode_model};

/// A series compressed by FFT FreMEn: the model, whether it reconstructs the series, and the
/// sizes of its model files.
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
        let file_bytes = encode_model("fft", &AnyModel::Fft(model.clone()))?.len();
        let lossy_file_bytes = encode_model("fft", &AnyModel::Fft(model.without_outliers()))?.len();
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
