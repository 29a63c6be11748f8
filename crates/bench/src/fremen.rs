//! The FreMEn benchmarks ([Krajník 2017]): FFT FreMEn model build (§III-B), FreMEn observe and
//! predict throughput, each against the textbook transform or evaluation of
//! `chronomap_core::naive` in the same run.
//!
//! ```text
//! cargo run --release -p chronomap-bench -- [all|fft|observe|predict] [--quick]
//! ```

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Instant;

use chronomap_core::TimeSeries;
use chronomap_core::fft::{FftFremen, FftFremenConfig, SpectrumMethod, edges_of};
use chronomap_core::naive::{naive_dft, naive_fremen_predict, naive_spectrum};
use chronomap_core::{FremenModel, Ordered, Parallelism, TemporalModel};
use chronomap_io::{read_pairs, read_test_set};
use serde::Serialize;

use crate::BenchError;

/// What the FreMEn benchmarks read and how long they run.
#[derive(Clone, Debug, PartialEq)]
pub struct FremenConfig {
    /// The repository's `data/` directory (the tom and greg doors).
    pub data: PathBuf,
    /// Fewer repetitions and smaller inputs, for a short run.
    pub quick: bool,
}

/// The tom door week at 1 Hz below `data/`.
const TOM_WEEK: (&str, &str) = (
    "door_tom_2013/sec/test_times_0.txt.xz",
    "door_tom_2013/sec/test_data_0.txt.xz",
);
/// The greg door training data below `data/`.
const GREG_TRAINING: &str = "door_greg_2016/training_data.txt.xz";

/// Median wall time in seconds of `runs` calls after one warm-up call.
fn time<T>(runs: usize, mut f: impl FnMut() -> T) -> f64 {
    black_box(f());
    let mut samples: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            let start = Instant::now();
            black_box(f());
            start.elapsed().as_secs_f64()
        })
        .collect();
    samples.sort_by(f64::total_cmp);
    samples[samples.len() / 2]
}

/// One timed FFT FreMEn build (run-length spectrum, periods >= 2 h).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FftBuild {
    /// Model order.
    pub order: usize,
    /// Median seconds of a build.
    pub seconds: f64,
}

/// FFT FreMEn build on the tom door week at 2 Hz: chronomap's run-length spectrum against a
/// bare scan of the input, the same model from a real FFT, the whole spectrum and the naive DFT.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FftBench {
    /// Samples of the series (1,209,600).
    pub samples: usize,
    /// Changes of state in the series.
    pub changes: usize,
    /// chronomap's builds at orders 2, 5 and 10, each checked lossless.
    pub builds: Vec<FftBuild>,
    /// The build every ratio below is relative to (order 5), in seconds.
    pub reference_seconds: f64,
    /// Median seconds of a bare memory scan of the input (XOR of all bytes).
    pub scan_seconds: f64,
    /// `scan_seconds / reference_seconds`.
    pub ratio_scan: f64,
    /// Median seconds of the same order-5 model with its spectrum from a real FFT (realfft).
    pub fft_seconds: f64,
    /// `fft_seconds / reference_seconds`.
    pub ratio_fft: f64,
    /// Median seconds of the whole spectrum up to Nyquist by real FFT, order 5.
    pub full_spectrum_seconds: f64,
    /// `full_spectrum_seconds / reference_seconds`.
    pub ratio_full_spectrum: f64,
    /// Candidate bins of the naive DFT (those of periods >= 2 h).
    pub naive_dft_bins: usize,
    /// Seconds of the naive DFT of those bins (spectrum only, one run).
    pub naive_dft_seconds: f64,
    /// `naive_dft_seconds / reference_seconds`.
    pub ratio_naive_dft: f64,
}

/// FFT FreMEn model build on the tom door week at 2 Hz (1,209,600 samples), the setting of
/// [Krajník 2017] §V ("3.7 ms on an i7 with FFTW"). Every build is checked to reconstruct its input
/// bit for bit before it is timed.
///
/// # Errors
/// A data file that cannot be read, a build that fails or is not lossless.
pub fn fft(config: &FremenConfig) -> Result<FftBench, BenchError> {
    let week = read_test_set(config.data.join(TOM_WEEK.0), config.data.join(TOM_WEEK.1))?;
    // The paper subsampled the 30 Hz camera stream to 2 Hz; the published data are at 1 Hz,
    // so each second is repeated twice to get the paper's 1,209,600 samples.
    let samples: Vec<u8> = week
        .values
        .iter()
        .flat_map(|&v| [v as u8, v as u8])
        .collect();
    let changes = edges_of(&samples)?.len();
    let runs = if config.quick { 5 } else { 31 };

    // The floor: reading every input byte once (a vectorised XOR reduction).
    let scan_seconds = time(runs, || samples.iter().fold(0u8, |a, &b| a ^ b));
    let mut builds = Vec::new();
    for order in [2usize, 5, 10] {
        let fft_config = FftFremenConfig::with_order(order);
        let model = FftFremen::build(0.0, 0.5, &samples, fft_config)?;
        if model.reconstruct() != samples {
            return Err(BenchError::NotLossless {
                order,
                method: "run-length spectrum",
            });
        }
        let seconds = time(runs, || {
            FftFremen::build(0.0, 0.5, &samples, fft_config).expect("built above")
        });
        builds.push(FftBuild { order, seconds });
    }
    let base = builds[1].seconds;

    let fft_config = FftFremenConfig::with_order(5);
    let fft_seconds = time(runs.min(7), || {
        FftFremen::build_with(0.0, 0.5, &samples, fft_config, SpectrumMethod::Fft)
            .expect("the same input as the builds above")
    });
    let full = FftFremenConfig {
        order: 5,
        shortest_period_secs: None,
    };
    let full_model = FftFremen::build_with(0.0, 0.5, &samples, full, SpectrumMethod::Fft)?;
    if full_model.reconstruct() != samples {
        return Err(BenchError::NotLossless {
            order: 5,
            method: "whole spectrum by real FFT",
        });
    }
    let full_spectrum_seconds = time(runs.min(7), || {
        FftFremen::build_with(0.0, 0.5, &samples, full, SpectrumMethod::Fft).expect("built above")
    });
    let bins = 84;
    let signal: Vec<f64> = samples.iter().map(|&s| f64::from(s)).collect();
    let naive_dft_seconds = time(1, || naive_dft(&signal, bins + 1));
    Ok(FftBench {
        samples: samples.len(),
        changes,
        builds,
        reference_seconds: base,
        scan_seconds,
        ratio_scan: scan_seconds / base,
        fft_seconds,
        ratio_fft: fft_seconds / base,
        full_spectrum_seconds,
        ratio_full_spectrum: full_spectrum_seconds / base,
        naive_dft_bins: bins,
        naive_dft_seconds,
        ratio_naive_dft: naive_dft_seconds / base,
    })
}

/// Greg door training data (10 weeks at 1 min) tiled `copies` times.
fn greg_series(config: &FremenConfig, copies: usize) -> Result<TimeSeries, BenchError> {
    let train = read_pairs(config.data.join(GREG_TRAINING))?;
    let (Some(&first), Some(&last)) = (train.times.first(), train.times.last()) else {
        return Err(BenchError::Empty {
            file: GREG_TRAINING,
        });
    };
    let span = last - first + 60.0;
    let mut series = TimeSeries {
        times: Vec::new(),
        values: Vec::new(),
    };
    for copy in 0..copies {
        series
            .times
            .extend(train.times.iter().map(|t| t + copy as f64 * span));
        series.values.extend_from_slice(&train.values);
    }
    Ok(series)
}

/// One way of observing, timed.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ObserveRun {
    /// Median seconds of observing the whole series into a fresh model.
    pub seconds: f64,
    /// Observations × periods per second.
    pub rate: f64,
    /// `naive_seconds / seconds`.
    pub speedup: f64,
}

/// FreMEn observe on the greg door training data tiled to about a million observations, with
/// the default candidate periods: chronomap's exact incremental spectrum against the direct
/// `O(N·K)` transform.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ObserveBench {
    /// Observations of the series.
    pub observations: usize,
    /// Candidate periods.
    pub periods: usize,
    /// Seconds of the naive transform: one `sin_cos` per observation and period, f64 sums.
    pub naive_seconds: f64,
    /// Observations × periods per second of the naive transform.
    pub naive_rate: f64,
    /// chronomap on one thread (exact sums, harmonic recurrence).
    pub sequential: ObserveRun,
    /// chronomap on all threads.
    pub parallel: ObserveRun,
}

/// FreMEn observe throughput: exact incremental spectrum vs the direct O(N·K) transform
/// (`chronomap_core::naive::naive_spectrum`).
///
/// # Errors
/// The training data cannot be read or observed.
pub fn observe(config: &FremenConfig) -> Result<ObserveBench, BenchError> {
    let series = greg_series(config, if config.quick { 2 } else { 10 })?;
    let n = series.times.len();
    let periods = FremenModel::with_order(0).config().periods.periods();
    let k = periods.len();
    let runs = if config.quick { 3 } else { 7 };
    // Checked once outside the clock, so that the timed closures cannot fail.
    FremenModel::with_order(4).observe(&series.times, &series.values)?;
    let naive_seconds = time(1, || {
        naive_spectrum(&series.times, &series.values, &periods)
    });
    let rate = |t: f64| (n * k) as f64 / t;
    let [sequential, parallel] = [Parallelism::Sequential, Parallelism::Rayon(0)].map(|par| {
        let seconds = time(runs, || {
            let mut m = FremenModel::with_order(4);
            m.observe_par(&series.times, &series.values, par)
                .expect("observed above");
            m
        });
        ObserveRun {
            seconds,
            rate: rate(seconds),
            speedup: naive_seconds / seconds,
        }
    });
    Ok(ObserveBench {
        observations: n,
        periods: k,
        naive_seconds,
        naive_rate: rate(naive_seconds),
        sequential,
        parallel,
    })
}

/// How the query times of the predict benchmark are spaced.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Spacing {
    /// One a minute.
    Even,
    /// One a minute plus a pseudo-random offset of up to 52 s.
    Irregular,
}

impl Spacing {
    /// "evenly spaced" or "irregular".
    pub fn label(self) -> &'static str {
        match self {
            Spacing::Even => "evenly spaced",
            Spacing::Irregular => "irregular",
        }
    }
}

/// One order and spacing of the predict benchmark.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PredictRow {
    /// Model order.
    pub order: usize,
    /// Spacing of the query times.
    pub times: Spacing,
    /// chronomap's `predict_many`, nanoseconds per prediction (median).
    pub chronomap_ns: f64,
    /// Direct evaluation of eq. (10) (`naive_fremen_predict`), nanoseconds per prediction.
    pub naive_ns: f64,
    /// `naive_ns / chronomap_ns`.
    pub speedup: f64,
}

/// FreMEn predict on a model trained on the greg door, over evenly spaced and irregular
/// query times.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PredictBench {
    /// Query times per run.
    pub times: usize,
    /// Orders 4 and 20, each with both spacings.
    pub rows: Vec<PredictRow>,
}

/// FreMEn predict throughput over evenly spaced and irregular times vs direct evaluation of
/// eq. (10) on the same spectrum (`chronomap_core::naive::naive_fremen_predict`).
///
/// # Errors
/// The training data cannot be read or observed.
pub fn predict(config: &FremenConfig) -> Result<PredictBench, BenchError> {
    let train = read_pairs(config.data.join(GREG_TRAINING))?;
    let Some(&last) = train.times.last() else {
        return Err(BenchError::Empty {
            file: GREG_TRAINING,
        });
    };
    let start = last + 60.0;
    let count = if config.quick { 20_160 } else { 201_600 };
    let even: Vec<f64> = (0..count).map(|i| start + 60.0 * i as f64).collect();
    let irregular: Vec<f64> = (0..count)
        .map(|i| start + 60.0 * i as f64 + ((i * 7919) % 53) as f64)
        .collect();
    let runs = if config.quick { 3 } else { 11 };
    let mut rows = Vec::new();
    for order in [4usize, 20] {
        let mut model = FremenModel::with_order(order);
        model.observe(&train.times, &train.values)?;
        let periods = model.config().periods.periods();
        let (mean, gammas) = naive_spectrum(&train.times, &train.values, &periods);
        let chosen = model
            .components()
            .iter()
            .map(|c| {
                periods
                    .iter()
                    .position(|&p| p == c.period_secs)
                    .ok_or(BenchError::UnknownPeriod {
                        period_secs: c.period_secs,
                    })
            })
            .collect::<Result<Vec<usize>, _>>()?;
        assert_eq!(
            model.order(),
            chosen.len(),
            "one candidate period per component"
        );
        for (spacing, times) in [(Spacing::Even, &even), (Spacing::Irregular, &irregular)] {
            let fast = time(runs, || model.predict_many(times));
            let naive = time(runs.min(3), || {
                times
                    .iter()
                    .map(|&t| naive_fremen_predict(mean, &gammas, &periods, &chosen, t))
                    .collect::<Vec<f64>>()
            });
            let per = |t: f64| t / times.len() as f64 * 1e9;
            rows.push(PredictRow {
                order,
                times: spacing,
                chronomap_ns: per(fast),
                naive_ns: per(naive),
                speedup: naive / fast,
            });
        }
    }
    Ok(PredictBench { times: count, rows })
}
