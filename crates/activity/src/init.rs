//! CoPA-Map's initial hyperparameters, [Stüde 2024] §4.2.4: the periods and variances of the
//! temporal kernel (eq. 4.10) from a frequency analysis of sampled regions (Algorithm 4.1,
//! eqs. 4.17–4.18), and the inducing points from k-means of the inputs weighted by their
//! observation durations.
//!
//! Algorithm 4.1 as built here ([`initial_periods`]):
//!
//! 1. The samples are squashed onto coarse regions (`region_size` squares, 5 m in §4.3) and time
//!    bins (`bin_length`, 60 min in §4.3): one time series per region, the (duration-weighted)
//!    mean rate of its samples in every bin ([`region_series`]).
//! 2. Λ series are drawn by roulette-wheel selection without replacement, each weighted by its
//!    total count `Σ y_i Δ_i` (`Σ y_i` without durations) ([`roulette_wheel`]).
//! 3. For each series, five contiguous folds: the NUDFT of eq. (4.17) of the training part over
//!    equally spaced candidate periods ([`nudft`]), the `b = 0..=ψ_max` most prominent peaks
//!    reconstruct the signal by eq. (4.18) ([`FourierSeries`]), and the `(fold, b)` of the least
//!    test RMSE gives the series' periods and amplitudes ([`fit_series`]).
//! 4. `ψ = ⌊mean b_l⌋`; the periods of all series are clustered by k-means with `k = ψ`,
//!    weighted by their amplitudes; each cluster's summed weight, scaled so that the largest is
//!    `σ²_max`, is its variance ([`cluster_periods`]).
//!
//! Two choices follow the original implementation (`copa-map`'s `util/spectral.py`) where the
//! seed leaves them open: the "most prominent" components are the local maxima of `|ξ_k|` over
//! the candidate periods (ends of the range excluded), sorted by magnitude — the largest
//! magnitudes alone would all lie on the flank of the one strongest peak; and roulette-wheel
//! draws do not repeat a region.

use std::collections::BTreeMap;
use std::f64::consts::TAU;

use chronomap_core::Complex64;
use chronomap_core::Parallelism;
use chronomap_core::num::{count_of, fmt_number};

/// The largest region or bin index of [`region_series`] (2^53: exact as an `f64`).
const MAX_INDEX: usize = 1 << 53;
use serde::{Deserialize, Serialize};

use super::{ActivityError, RateSamples};
use crate::gp::Point;
use chronomap_core::rng::{Xoshiro256StarStar, derive_seed};
use chronomap_hypertime::mixture::{KMeansConfig, kmeans};

/// Purpose tag of the roulette-wheel stream ("ROULET").
const TAG_ROULETTE: u64 = 0x524f_554c_4554;

/// Most candidate periods [`SpectralInitConfig`] accepts (bounds the cost of the NUDFT).
pub const MAX_CANDIDATES: usize = 100_000;

/// Parameters of Algorithm 4.1 ([`initial_periods`]); the defaults are those of [Stüde 2024] §4.3
/// in the units of the bundled ATC grid (metres; `t` in hours, 12 recorded hours a day).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SpectralInitConfig {
    /// Side of the square regions whose time series are analysed, in the unit of `x`
    /// (default 5: the 5 m × 5 m grid of §4.3).
    pub region_size: f64,
    /// Length of the time bins of the series, in units of `t` (default 1: 60 min).
    pub bin_length: f64,
    /// Λ, the number of sampled series (default 10).
    pub series: usize,
    /// ψ_max, the most components per series (default 10).
    pub max_periods: usize,
    /// σ²_max, the variance of the strongest period (default 0.95).
    pub max_variance: f64,
    /// Shortest candidate period in units of `t` (default 2: the shortest period hourly bins
    /// resolve).
    pub min_period: f64,
    /// Longest candidate period in units of `t` (default 84: seven days of the ATC grid's 12
    /// recorded hours).
    pub max_period: f64,
    /// Spacing of the equally spaced candidate periods (default 0.05).
    pub period_step: f64,
    /// Contiguous cross-validation folds (default 5); a series needs `2 · folds` bins.
    pub folds: usize,
    /// How the folds choose a series' number of components.
    pub cv: CvChoice,
    /// Seed of the roulette wheel and of the k-means of periods.
    pub seed: u64,
}

impl Default for SpectralInitConfig {
    fn default() -> Self {
        SpectralInitConfig {
            region_size: 5.0,
            bin_length: 1.0,
            series: 10,
            max_periods: 10,
            max_variance: 0.95,
            min_period: 2.0,
            max_period: 84.0,
            period_step: 0.05,
            folds: 5,
            cv: CvChoice::default(),
            seed: 0,
        }
    }
}

impl SpectralInitConfig {
    /// The candidate periods `o`: `min_period, min_period + period_step, …, ≤ max_period`.
    ///
    /// # Errors
    /// [`ActivityError::Config`] for a range that is not positive and finite, a step that is
    /// not, or more than [`MAX_CANDIDATES`] candidates.
    pub fn candidates(&self) -> Result<Vec<f64>, ActivityError> {
        let (lo, hi, step) = (self.min_period, self.max_period, self.period_step);
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi >= lo) {
            return Err(ActivityError::Config(format!(
                "candidate periods {lo} ..= {hi} must be positive, finite and ordered"
            )));
        }
        if !(step.is_finite() && step > 0.0) {
            return Err(ActivityError::Config(format!(
                "period step {step} must be a positive number"
            )));
        }
        // The small slack keeps `max_period` when rounding puts it a hair beyond the grid.
        let steps = ((hi - lo) / step + 1e-9).floor();
        if steps >= MAX_CANDIDATES as f64 {
            return Err(ActivityError::Config(format!(
                "{steps} candidate periods (at most {MAX_CANDIDATES})"
            )));
        }
        Ok((0..=steps as usize).map(|k| lo + k as f64 * step).collect())
    }

    fn check(&self) -> Result<Vec<f64>, ActivityError> {
        let bad = |what: String| Err(ActivityError::Config(what));
        if !(self.region_size.is_finite() && self.region_size > 0.0) {
            return bad(format!("region size {} must be > 0", self.region_size));
        }
        if !(self.bin_length.is_finite() && self.bin_length > 0.0) {
            return bad(format!("bin length {} must be > 0", self.bin_length));
        }
        if self.series == 0 {
            return bad("at least one series must be sampled".into());
        }
        if !(self.max_variance.is_finite() && self.max_variance > 0.0) {
            return bad(format!(
                "maximum variance {} must be > 0",
                self.max_variance
            ));
        }
        if self.folds < 2 {
            return bad(format!("folds {} must be at least 2", self.folds));
        }
        self.candidates()
    }
}

/// The time series of one region: the mean rate in every time bin the region was observed.
#[derive(Clone, Debug, PartialEq)]
pub struct RegionSeries {
    /// Centre of the region.
    pub centre: [f64; 2],
    /// Mean sample time of every observed bin, ascending.
    pub times: Vec<f64>,
    /// The (duration-weighted) mean rate of the region's samples in each bin.
    pub rates: Vec<f64>,
    /// Total count of the region, `Σ y_i Δ_i` over its samples (`Σ y_i` without durations):
    /// its weight on the roulette wheel.
    pub total: f64,
}

/// Squashes `samples` onto square regions of side `region_size` (aligned with the smallest
/// coordinates of the samples) and time bins of `bin_length` (aligned with the earliest time):
/// one series per region, in the order of the region's row and column. Within a bin the rate
/// is the mean of the region's samples weighted by `dwell` (equal weights without).
///
/// # Errors
/// [`ActivityError::Config`] for a size or length that is not positive, and the errors of
/// [`check_dwell`].
pub fn region_series(
    samples: &RateSamples,
    dwell: Option<&[f64]>,
    region_size: f64,
    bin_length: f64,
) -> Result<Vec<RegionSeries>, ActivityError> {
    if !(region_size.is_finite() && region_size > 0.0 && bin_length.is_finite() && bin_length > 0.0)
    {
        return Err(ActivityError::Config(format!(
            "region size {region_size} and bin length {bin_length} must be > 0"
        )));
    }
    if let Some(d) = dwell {
        check_dwell(d, samples.len())?;
    }
    let (xs, ts, ys) = (samples.x(), samples.t(), samples.y());
    let lo = |k: usize| xs.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min);
    let origin = [lo(0), lo(1)];
    let t0 = ts.iter().copied().fold(f64::INFINITY, f64::min);
    // Region and bin indices are integer keys: they must be exact (< 2^53), or distinct regions
    // or bins would silently share a saturated key.
    let hi = |k: usize| xs.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max);
    let t1 = ts.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    for (what, value, span) in [
        ("region size", region_size, hi(0) - origin[0]),
        ("region size", region_size, hi(1) - origin[1]),
        ("bin length", bin_length, t1 - t0),
    ] {
        if !samples.is_empty() && count_of((span / value).floor(), MAX_INDEX).is_none() {
            return Err(ActivityError::Config(format!(
                "{what} {} gives {} regions or bins over the samples; at most 2^53",
                fmt_number(value),
                fmt_number((span / value).floor())
            )));
        }
    }
    // region (row, column) → bin → (Σ w, Σ w t, Σ w y)
    let mut regions: BTreeMap<(i64, i64), BTreeMap<i64, [f64; 3]>> = BTreeMap::new();
    for i in 0..samples.len() {
        let cell = |k: usize| ((xs[i][k] - origin[k]) / region_size).floor() as i64;
        let bin = ((ts[i] - t0) / bin_length).floor() as i64;
        let w = dwell.map_or(1.0, |d| d[i]);
        let acc = regions
            .entry((cell(0), cell(1)))
            .or_default()
            .entry(bin)
            .or_default();
        acc[0] += w;
        acc[1] += w * ts[i];
        acc[2] += w * ys[i];
    }
    Ok(regions
        .into_iter()
        .map(|((r0, r1), bins)| {
            let centre = [
                origin[0] + (r0 as f64 + 0.5) * region_size,
                origin[1] + (r1 as f64 + 0.5) * region_size,
            ];
            let total = bins.values().map(|a| a[2]).sum();
            let (times, rates) = bins.values().map(|a| (a[1] / a[0], a[2] / a[0])).unzip();
            RegionSeries {
                centre,
                times,
                rates,
                total,
            }
        })
        .collect())
}

/// Checks observation durations: one positive finite number per sample.
///
/// # Errors
/// [`ActivityError::LengthMismatch`] (`predictions` = durations, `truth` = samples) or
/// [`ActivityError::NonFinite`] with field `"dwell"` for the first duration that is not a
/// positive finite number.
pub fn check_dwell(dwell: &[f64], samples: usize) -> Result<(), ActivityError> {
    if dwell.len() != samples {
        return Err(ActivityError::LengthMismatch {
            predictions: dwell.len(),
            truth: samples,
        });
    }
    match dwell
        .iter()
        .enumerate()
        .find(|(_, d)| !(d.is_finite() && **d > 0.0))
    {
        Some((index, &value)) => Err(ActivityError::NonFinite {
            index,
            field: "dwell",
            value,
        }),
        None => Ok(()),
    }
}

/// Roulette-wheel selection without replacement: up to `count` distinct indices, each drawn
/// with probability proportional to its weight among those not drawn yet. Entries of weight
/// `<= 0` (or not finite) are never drawn, so fewer than `count` come back when fewer have a
/// positive weight.
pub fn roulette_wheel(weights: &[f64], count: usize, rng: &mut Xoshiro256StarStar) -> Vec<usize> {
    let mut left: Vec<f64> = weights
        .iter()
        .map(|&w| if w.is_finite() && w > 0.0 { w } else { 0.0 })
        .collect();
    let mut chosen = Vec::with_capacity(count.min(weights.len()));
    while chosen.len() < count {
        let total: f64 = left.iter().sum();
        if total <= 0.0 {
            break;
        }
        let u = rng.next_f64() * total;
        let mut cumulative = 0.0;
        let mut pick = None;
        for (i, &w) in left.iter().enumerate() {
            if w > 0.0 {
                cumulative += w;
                pick = Some(i);
                if cumulative > u {
                    break;
                }
            }
        }
        let Some(i) = pick else { break };
        left[i] = 0.0;
        chosen.push(i);
    }
    chosen
}

/// The non-uniform discrete Fourier transform of eq. (4.17) at candidate periods `o_k`:
/// `ξ_k = Σ_j y_j exp(−i 2π t_j / o_k)` (the dissertation's `2π/(T o_k)` with the periods in units
/// of `t`, i.e. `T = 1`).
pub fn nudft(times: &[f64], values: &[f64], periods: &[f64]) -> Vec<Complex64> {
    periods
        .iter()
        .map(|&o| {
            times
                .iter()
                .zip(values)
                .fold(Complex64::new(0.0, 0.0), |acc, (&t, &y)| {
                    let (s, c) = (TAU * t / o).sin_cos();
                    acc + Complex64::new(y * c, -y * s)
                })
        })
        .collect()
}

/// The indices of the local maxima of `magnitudes` (strictly above the left neighbour, at
/// least the right one; the two ends never count), largest first (lower index on ties).
pub fn spectral_peaks(magnitudes: &[f64]) -> Vec<usize> {
    let mut peaks: Vec<usize> = (1..magnitudes.len().saturating_sub(1))
        .filter(|&k| magnitudes[k] > magnitudes[k - 1] && magnitudes[k] >= magnitudes[k + 1])
        .collect();
    peaks.sort_by(|&a, &b| magnitudes[b].total_cmp(&magnitudes[a]).then(a.cmp(&b)));
    peaks
}

/// A signal reconstructed from a few Fourier components, eq. (4.18):
/// `ŷ(t) = mean + Σ_u amplitude_u cos(2π t / period_u + phase_u)`.
///
/// The dissertation writes `|ξ_0| + Σ |ξ_u| cos(2π t/o_u + arg ξ_u)` with the raw sums `ξ` of
/// eq. (4.17). As a Fourier series of a real signal of `J` samples that is
/// `|ξ_0| / J + Σ (2 |ξ_u| / J) cos(…)`: `ξ_0 = Σ y_j = J · mean`, and a cosine of amplitude
/// `a` and phase `φ` sampled evenly over whole cycles has `ξ = (J a / 2) e^{iφ}` (the other
/// half of its energy is at `−1/o`). [`FourierSeries::from_spectrum`] builds it so, with the
/// `ξ_u` taken of the mean-removed samples: otherwise the mean leaks into every candidate with
/// `Σ_j e^{−i2π t_j/o} ≠ 0`, most of all into periods near the length of the series.
#[derive(Clone, Debug, PartialEq)]
pub struct FourierSeries {
    /// `|ξ_0| / J`, the mean of the samples.
    pub mean: f64,
    /// `(period, amplitude 2|ξ_u|/J, phase arg ξ_u)` of every component.
    pub components: Vec<(f64, f64, f64)>,
}

impl FourierSeries {
    /// The series of the given components `(period, ξ)` of `samples` mean-removed samples of
    /// mean `mean`.
    pub fn from_spectrum(mean: f64, samples: usize, components: &[(f64, Complex64)]) -> Self {
        let scale = 2.0 / samples.max(1) as f64;
        FourierSeries {
            mean,
            components: components
                .iter()
                .map(|&(period, xi)| (period, scale * xi.norm(), xi.arg()))
                .collect(),
        }
    }

    /// `ŷ(t)`.
    pub fn at(&self, t: f64) -> f64 {
        self.mean
            + self
                .components
                .iter()
                .map(|&(period, amplitude, phase)| amplitude * (TAU * t / period + phase).cos())
                .sum::<f64>()
    }
}

/// One sampled series of Algorithm 4.1 and what was found in it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SeriesPeriods {
    /// Centre of the region.
    pub centre: [f64; 2],
    /// Bins of the series (`J`).
    pub bins: usize,
    /// Its weight on the roulette wheel (total count).
    pub total: f64,
    /// Its components (lines 2–12).
    pub fit: SeriesFit,
}

/// What lines 2–12 of Algorithm 4.1 find in one series ([`fit_series`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SeriesFit {
    /// `b_l`: components of the least test RMSE (0: the mean alone).
    pub components: usize,
    /// `i_l`: the fold of the least test RMSE (0-based; `None` with
    /// [`CvChoice::MeanOverFolds`]).
    pub fold: Option<usize>,
    /// The least test RMSE `e_{i_l, b_l}` (the least mean over the folds with
    /// [`CvChoice::MeanOverFolds`]).
    pub rmse: f64,
    /// `o_l`: the periods of the `b_l` components, strongest first.
    pub periods: Vec<f64>,
    /// `a_l`: their amplitudes `2|ξ_u|/J` (rate units).
    pub amplitudes: Vec<f64>,
}

/// How lines 9–12 of Algorithm 4.1 pick a series' number of components `b_l` from the test
/// RMSEs `e_{i,b}` of the folds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum CvChoice {
    /// As line 10 writes it: the `(i, b)` of the least single-fold RMSE; the components are
    /// those of fold `i`'s training spectrum.
    #[default]
    BestFold,
    /// Ordinary k-fold model selection: the `b` of the least RMSE averaged over the folds;
    /// the components are the `b` largest peaks of the spectrum of the whole series.
    MeanOverFolds,
}

/// The `b` most prominent components `(period, ξ)` of a spectrum.
fn top_components(
    xi: &[Complex64],
    candidates: &[f64],
    peaks: &[usize],
    b: usize,
) -> Vec<(f64, Complex64)> {
    peaks[..b].iter().map(|&p| (candidates[p], xi[p])).collect()
}

/// Lines 2–12 of Algorithm 4.1 for one series (`times` ascending): for each of `folds`
/// contiguous test blocks, the NUDFT (eq. 4.17) of the other samples, less their mean, over
/// `candidates`; for `b = 0..=max_components` the `b` largest spectral peaks
/// ([`spectral_peaks`]) reconstruct the signal (eq. 4.18, [`FourierSeries`]) and are scored by
/// their RMSE on the test block (a `b` beyond a fold's number of peaks scores `∞`). `choice`
/// picks `b_l` and its components from these errors (the first in fold-major, then `b`,
/// order on ties).
///
/// `None` for fewer than `2 · folds` samples or `folds < 2`.
pub fn fit_series(
    times: &[f64],
    rates: &[f64],
    candidates: &[f64],
    max_components: usize,
    folds: usize,
    choice: CvChoice,
) -> Option<SeriesFit> {
    let n = times.len().min(rates.len());
    if folds < 2 || n < 2 * folds {
        return None;
    }
    // Per fold block: Σ y e^{−iωt} and Σ e^{−iωt} at every candidate; a training spectrum is
    // the total less its test block, so every phasor is computed once.
    let k = candidates.len();
    let mut block_sums = vec![Complex64::new(0.0, 0.0); folds * k];
    let mut block_phasors = vec![Complex64::new(0.0, 0.0); folds * k];
    let bounds: Vec<(usize, usize)> = (0..folds)
        .map(|f| (f * n / folds, (f + 1) * n / folds))
        .collect();
    for (f, &(lo, hi)) in bounds.iter().enumerate() {
        for (c, &o) in candidates.iter().enumerate() {
            for (&t, &y) in times[lo..hi].iter().zip(&rates[lo..hi]) {
                let (s, cos) = (TAU * t / o).sin_cos();
                let e = Complex64::new(cos, -s);
                block_sums[f * k + c] += e * y;
                block_phasors[f * k + c] += e;
            }
        }
    }
    let total_rate: f64 = rates[..n].iter().sum();
    // The spectrum (ξ of the samples less their mean) of every block but `held`, with the
    // mean and the number of samples.
    let spectrum = |held: Option<usize>| {
        let (lo, hi) = held.map_or((0, 0), |f| bounds[f]);
        let count = n - (hi - lo);
        let mean = (total_rate - rates[lo..hi].iter().sum::<f64>()) / count as f64;
        let xi: Vec<Complex64> = (0..k)
            .map(|c| {
                let (mut s, mut e) = (Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0));
                for g in (0..folds).filter(|&g| Some(g) != held) {
                    s += block_sums[g * k + c];
                    e += block_phasors[g * k + c];
                }
                s - e * mean
            })
            .collect();
        let magnitudes: Vec<f64> = xi.iter().map(|z| z.norm()).collect();
        let peaks = spectral_peaks(&magnitudes);
        (mean, count, xi, peaks)
    };
    let mut errors = vec![vec![f64::INFINITY; max_components + 1]; folds];
    let mut fold_spectra = Vec::with_capacity(folds);
    for (f, (&(lo, hi), row)) in bounds.iter().zip(&mut errors).enumerate() {
        let (mean, count, xi, peaks) = spectrum(Some(f));
        let available = max_components.min(peaks.len()) + 1;
        for (b, error) in row.iter_mut().enumerate().take(available) {
            let components = top_components(&xi, candidates, &peaks, b);
            let series = FourierSeries::from_spectrum(mean, count, &components);
            let sse: f64 = (lo..hi)
                .map(|j| (series.at(times[j]) - rates[j]).powi(2))
                .sum();
            *error = (sse / (hi - lo) as f64).sqrt();
        }
        fold_spectra.push((mean, count, xi, peaks));
    }
    let (fold, b, rmse, series) = match choice {
        CvChoice::BestFold => {
            let (mut fold, mut b) = (0, 0);
            for (f, row) in errors.iter().enumerate() {
                for (c, &e) in row.iter().enumerate() {
                    if e < errors[fold][b] {
                        (fold, b) = (f, c);
                    }
                }
            }
            let (mean, count, xi, peaks) = &fold_spectra[fold];
            let components = top_components(xi, candidates, peaks, b);
            let series = FourierSeries::from_spectrum(*mean, *count, &components);
            (Some(fold), b, errors[fold][b], series)
        }
        CvChoice::MeanOverFolds => {
            let mean_error = |b: usize| errors.iter().map(|row| row[b]).sum::<f64>() / folds as f64;
            let mut b = 0;
            for c in 1..=max_components {
                if mean_error(c) < mean_error(b) {
                    b = c;
                }
            }
            let (mean, count, xi, peaks) = spectrum(None);
            let b = b.min(peaks.len());
            let components = top_components(&xi, candidates, &peaks, b);
            let series = FourierSeries::from_spectrum(mean, count, &components);
            (None, b, mean_error(b), series)
        }
    };
    let (periods, amplitudes) = series.components.iter().map(|c| (c.0, c.1)).unzip();
    Some(SeriesFit {
        components: b,
        fold,
        rmse,
        periods,
        amplitudes,
    })
}

/// Lines 14–15 of Algorithm 4.1: k-means of `periods` (one dimension) with `k` clusters,
/// each period weighted by `weights`; returns `(centres, variances)` sorted by variance
/// (strongest first), the variance of a cluster being its summed weight scaled so that the
/// largest is `max_variance`. `k` is reduced to the number of distinct periods of positive
/// weight; no such period (or `k = 0`) gives empty vectors.
///
/// # Errors
/// [`ActivityError::Config`] if the clustering rejects the data (a non-finite period or
/// weight, or lengths that differ).
pub fn cluster_periods(
    periods: &[f64],
    weights: &[f64],
    k: usize,
    max_variance: f64,
    seed: u64,
) -> Result<(Vec<f64>, Vec<f64>), ActivityError> {
    let mut distinct: Vec<f64> = periods
        .iter()
        .zip(weights)
        .filter(|(_, w)| **w > 0.0)
        .map(|(p, _)| *p)
        .collect();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    let k = k.min(distinct.len());
    if k == 0 {
        return Ok((Vec::new(), Vec::new()));
    }
    let fit = kmeans(
        periods,
        1,
        Some(weights),
        &KMeansConfig {
            clusters: k,
            max_iterations: 100,
            starts: 10,
            seed,
            parallelism: Parallelism::Rayon(0),
        },
    )
    .map_err(|e| ActivityError::Config(format!("clustering periods: {e}")))?;
    let mut sums = vec![0.0; k];
    for (&label, &w) in fit.labels.iter().zip(weights) {
        sums[label] += w;
    }
    let largest = sums.iter().copied().fold(0.0, f64::max);
    let mut clusters: Vec<(f64, f64)> = fit
        .centres
        .iter()
        .zip(&sums)
        .filter(|(_, s)| **s > 0.0)
        .map(|(&c, &s)| (c, max_variance * (s / largest)))
        .collect();
    clusters.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.total_cmp(&b.0)));
    Ok(clusters.into_iter().unzip())
}

/// Why [`initial_periods`] found no period.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum NoPeriods {
    /// No region has `2 · folds` observed bins and a positive total count.
    NoSeries,
    /// `ψ = ⌊mean b_l⌋ = 0`: most series are best described by their mean.
    NotPeriodic,
}

/// The result of Algorithm 4.1 ([`initial_periods`]), with what each series contributed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PeriodInit {
    /// `γ̂_{1:ψ}` in units of `t`, strongest first (empty when `none` is set).
    pub periods: Vec<f64>,
    /// `σ̂²_{1:ψ}`, the largest `σ²_max`.
    pub variances: Vec<f64>,
    /// `ψ = ⌊mean b_l⌋` (more than `periods.len()` when fewer distinct periods were found).
    pub psi: usize,
    /// The sampled series, in the order drawn.
    pub per_series: Vec<SeriesPeriods>,
    /// Why no period was found (then a caller falls back, e.g. to the day).
    pub none: Option<NoPeriods>,
}

/// Algorithm 4.1: the periods and variances of the temporal kernel from a frequency analysis
/// of Λ regions drawn by their activity (see the [module documentation](self)). `dwell`
/// optionally gives every sample's observation duration (weights of the bin means and of the
/// roulette wheel).
///
/// Deterministic for a given `config.seed`.
///
/// # Errors
/// [`ActivityError::Empty`], [`ActivityError::Config`] or the errors of [`check_dwell`].
pub fn initial_periods(
    samples: &RateSamples,
    dwell: Option<&[f64]>,
    config: &SpectralInitConfig,
) -> Result<PeriodInit, ActivityError> {
    let candidates = config.check()?;
    if samples.is_empty() {
        return Err(ActivityError::Empty);
    }
    let regions = region_series(samples, dwell, config.region_size, config.bin_length)?;
    let weights: Vec<f64> = regions
        .iter()
        .map(|r| {
            if r.times.len() >= 2 * config.folds {
                r.total
            } else {
                0.0
            }
        })
        .collect();
    let mut rng = Xoshiro256StarStar::seed_from_u64(derive_seed(config.seed, TAG_ROULETTE, 0, 0));
    let drawn = roulette_wheel(&weights, config.series, &mut rng);
    let per_series: Vec<SeriesPeriods> = drawn
        .iter()
        .filter_map(|&i| {
            let r = &regions[i];
            let fit = fit_series(
                &r.times,
                &r.rates,
                &candidates,
                config.max_periods,
                config.folds,
                config.cv,
            )?;
            Some(SeriesPeriods {
                centre: r.centre,
                bins: r.times.len(),
                total: r.total,
                fit,
            })
        })
        .collect();
    let empty = |psi, none| PeriodInit {
        periods: Vec::new(),
        variances: Vec::new(),
        psi,
        per_series: per_series.clone(),
        none: Some(none),
    };
    if per_series.is_empty() {
        return Ok(empty(0, NoPeriods::NoSeries));
    }
    let psi = per_series.iter().map(|s| s.fit.components).sum::<usize>() / per_series.len();
    if psi == 0 {
        return Ok(empty(0, NoPeriods::NotPeriodic));
    }
    let pooled_periods: Vec<f64> = per_series
        .iter()
        .flat_map(|s| s.fit.periods.clone())
        .collect();
    let pooled_weights: Vec<f64> = per_series
        .iter()
        .flat_map(|s| s.fit.amplitudes.clone())
        .collect();
    let (periods, variances) = cluster_periods(
        &pooled_periods,
        &pooled_weights,
        psi,
        config.max_variance,
        config.seed,
    )?;
    if periods.is_empty() {
        return Ok(empty(psi, NoPeriods::NotPeriodic));
    }
    Ok(PeriodInit {
        periods,
        variances,
        psi,
        per_series,
        none: None,
    })
}

/// Initial inducing points (§4.2.4): `count` k-means centres of the inputs, each input
/// weighted by its observation duration `dwell[i]` (equal weights without), so that the
/// inducing points start where observations were long. One k-means++ start, at most 30
/// Lloyd iterations.
///
/// # Errors
/// [`ActivityError::Config`] for `count = 0`, fewer distinct inputs than `count`, or inputs
/// that are not finite; the errors of [`check_dwell`].
pub fn inducing_points(
    inputs: &[Point],
    dwell: Option<&[f64]>,
    count: usize,
    seed: u64,
) -> Result<Vec<Point>, ActivityError> {
    if let Some(d) = dwell {
        check_dwell(d, inputs.len())?;
    }
    let flat: Vec<f64> = inputs.iter().flatten().copied().collect();
    let fit = kmeans(
        &flat,
        3,
        dwell,
        &KMeansConfig {
            clusters: count,
            max_iterations: 30,
            starts: 1,
            seed,
            parallelism: Parallelism::Rayon(0),
        },
    )
    .map_err(|e| ActivityError::Config(format!("inducing points: {e}")))?;
    Ok(fit
        .centres
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn nudft_by_hand() {
        // Period 4 at t = 0, 1, 3: 1 + 2 e^{−iπ/2} + 4 e^{−i3π/2} = 1 − 2i + 4i = 1 + 2i.
        // Period 2: e^{−iπt} = 1, −1, −1: 1 − 2 − 4 = −5.
        let xi = nudft(&[0.0, 1.0, 3.0], &[1.0, 2.0, 4.0], &[4.0, 2.0]);
        assert!(
            close(xi[0].re, 1.0, 1e-12) && close(xi[0].im, 2.0, 1e-12),
            "{xi:?}"
        );
        assert!(
            close(xi[1].re, -5.0, 1e-12) && close(xi[1].im, 0.0, 1e-12),
            "{xi:?}"
        );
    }

    #[test]
    fn a_cosine_at_irregular_times_is_recovered_exactly() {
        // y = 3 + 2 cos(2π t / 7 + 0.5) at 64 phases evenly around the cycle, each in a
        // random one of 40 cycles: irregular times whose phasors still cancel, so the
        // Fourier series of eq. (4.18) (with the 2/J normalisation) is exact.
        let period = 7.0;
        let mut rng = Xoshiro256StarStar::seed_from_u64(7);
        let mut times: Vec<f64> = (0..64)
            .map(|j| (j as f64 + 64.0 * rng.int_in(0, 39) as f64) * period / 64.0)
            .collect();
        times.sort_by(f64::total_cmp);
        let truth = |t: f64| 3.0 + 2.0 * (TAU * t / period + 0.5).cos();
        let values: Vec<f64> = times.iter().map(|&t| truth(t)).collect();
        let mean = values.iter().sum::<f64>() / 64.0;
        assert!(close(mean, 3.0, 1e-12));
        let centred: Vec<f64> = values.iter().map(|v| v - mean).collect();
        let candidates = SpectralInitConfig {
            min_period: 2.0,
            max_period: 20.0,
            period_step: 0.05,
            ..SpectralInitConfig::default()
        }
        .candidates()
        .unwrap();
        assert_eq!(candidates.len(), 361);
        let xi = nudft(&times, &centred, &candidates);
        let magnitudes: Vec<f64> = xi.iter().map(|z| z.norm()).collect();
        let top = spectral_peaks(&magnitudes)[0];
        assert!(close(candidates[top], period, 1e-9), "{}", candidates[top]);
        let series = FourierSeries::from_spectrum(mean, 64, &[(candidates[top], xi[top])]);
        let (_, amplitude, phase) = series.components[0];
        assert!(close(amplitude, 2.0, 1e-9), "{amplitude}");
        assert!(close(phase, 0.5, 1e-9), "{phase}");
        for t in [0.0, 1.3, 50.0, 123.4] {
            assert!(close(series.at(t), truth(t), 1e-9));
        }
    }

    #[test]
    fn peaks_are_interior_local_maxima_largest_first() {
        assert_eq!(
            spectral_peaks(&[5.0, 1.0, 3.0, 2.0, 4.0, 4.0, 0.0, 9.0]),
            [4, 2]
        );
        assert!(spectral_peaks(&[1.0, 2.0]).is_empty());
        assert!(spectral_peaks(&[0.0; 5]).is_empty());
    }

    #[test]
    fn cross_validation_picks_one_component_for_a_noisy_cosine() {
        let mut rng = Xoshiro256StarStar::seed_from_u64(1);
        let times: Vec<f64> = (0..120).map(f64::from).collect();
        let rates: Vec<f64> = times
            .iter()
            .map(|t| 5.0 + 3.0 * (TAU * t / 12.0).cos() + 0.6 * (rng.next_f64() - 0.5))
            .collect();
        let candidates = SpectralInitConfig::default().candidates().unwrap();
        let fit = fit_series(&times, &rates, &candidates, 10, 5, CvChoice::BestFold).unwrap();
        assert_eq!(fit.components, 1, "{fit:?}");
        assert!(close(fit.periods[0], 12.0, 0.1), "{fit:?}");
        assert!(close(fit.amplitudes[0], 3.0, 0.1), "{fit:?}");
        assert!(fit.rmse < 0.3, "{fit:?}");
        assert!(fit.fold.is_some());
        // Ordinary k-fold selection agrees; its component comes from the whole series.
        let mean = fit_series(&times, &rates, &candidates, 10, 5, CvChoice::MeanOverFolds).unwrap();
        assert_eq!((mean.components, mean.fold), (1, None), "{mean:?}");
        assert!(close(mean.periods[0], 12.0, 0.05), "{mean:?}");
        // Too short for five folds of two bins each.
        assert!(
            fit_series(
                &times[..9],
                &rates[..9],
                &candidates,
                10,
                5,
                CvChoice::BestFold
            )
            .is_none()
        );
    }

    #[test]
    fn weighted_period_clustering_by_hand() {
        // {11 (w 1), 13 (w 3)} → 12.5 with weight 4; {6, 6.5} (w 1 each) → 6.25 with weight
        // 2; variances 0.95 · 4/4 and 0.95 · 2/4.
        let (periods, variances) =
            cluster_periods(&[11.0, 6.0, 13.0, 6.5], &[1.0, 1.0, 3.0, 1.0], 2, 0.95, 0).unwrap();
        assert_eq!(periods, [12.5, 6.25]);
        assert_eq!(variances, [0.95, 0.475]);
        // k is capped by the distinct periods; k = 0 gives nothing.
        let (periods, variances) = cluster_periods(&[12.0, 12.0], &[1.0, 2.0], 3, 0.95, 0).unwrap();
        assert_eq!((periods, variances), (vec![12.0], vec![0.95]));
        assert_eq!(
            cluster_periods(&[12.0], &[1.0], 0, 0.95, 0).unwrap(),
            (vec![], vec![])
        );
    }

    #[test]
    fn roulette_wheel_draws_by_weight_without_repeats() {
        let mut rng = Xoshiro256StarStar::seed_from_u64(3);
        let mut drawn = roulette_wheel(&[0.0, 5.0, f64::NAN, 1.0, -2.0], 10, &mut rng);
        drawn.sort_unstable();
        assert_eq!(drawn, [1, 3]);
        let first_is_heavy = (0..4000)
            .filter(|_| roulette_wheel(&[1.0, 3.0], 1, &mut rng) == [1])
            .count();
        assert!((2880..3120).contains(&first_is_heavy), "{first_is_heavy}");
    }

    #[test]
    fn region_series_average_by_dwell() {
        // Region (0, 0): t = 0 twice (y 1 for 3 h, y 4 for 1 h) and t = 1.4; region (1, 0)
        // at t = 0.5.
        let samples = RateSamples::new(
            vec![[0.0, 0.0], [4.0, 1.0], [1.0, 1.0], [6.0, 0.0]],
            vec![0.0, 0.0, 1.4, 0.5],
            vec![1.0, 4.0, 2.0, 8.0],
        )
        .unwrap();
        let dwell = [3.0, 1.0, 2.0, 1.0];
        let series = region_series(&samples, Some(&dwell), 5.0, 1.0).unwrap();
        assert_eq!(series.len(), 2);
        assert_eq!(series[0].centre, [2.5, 2.5]);
        assert_eq!(series[0].times, [0.0, 1.4]);
        assert_eq!(series[0].rates, [1.75, 2.0]);
        assert_eq!(series[0].total, 3.0 + 4.0 + 4.0);
        assert_eq!(series[1].centre, [7.5, 2.5]);
        assert_eq!((series[1].rates.clone(), series[1].total), (vec![8.0], 8.0));
        let plain = region_series(&samples, None, 5.0, 1.0).unwrap();
        assert_eq!(plain[0].rates, [2.5, 2.0]);
        assert_eq!(
            region_series(&samples, Some(&[1.0; 3]), 5.0, 1.0),
            Err(ActivityError::LengthMismatch {
                predictions: 3,
                truth: 4
            })
        );
        assert!(region_series(&samples, Some(&[1.0, 0.0, 1.0, 1.0]), 5.0, 1.0).is_err());
        assert!(region_series(&samples, None, 0.0, 1.0).is_err());
    }

    /// 8 regions of 5 m × 5 m (1 m cells), hourly for 8 days of 12 h; every region busy by
    /// `rate(region, t)`, each hour observed in a random half of the cells.
    fn synthetic(rate: impl Fn(usize, f64) -> f64) -> RateSamples {
        let mut rng = Xoshiro256StarStar::seed_from_u64(11);
        let mut samples = RateSamples::default();
        for t in 0..96 {
            for cx in 0..20 {
                for cy in 0..10 {
                    if rng.next_f64() < 0.5 {
                        let region = cx / 5 + 4 * (cy / 5);
                        let x = [cx as f64 + 0.5, cy as f64 + 0.5];
                        samples
                            .push(x, f64::from(t), rate(region, f64::from(t)))
                            .unwrap();
                    }
                }
            }
        }
        samples
    }

    #[test]
    fn initial_periods_find_the_synthetic_day_deterministically() {
        let samples = synthetic(|region, t| {
            let busy = 1.0 + region as f64;
            busy * (1.0 + 0.6 * (TAU * t / 12.0).cos() + 0.3 * (TAU * t / 6.0).sin())
        });
        let config = SpectralInitConfig {
            series: 6,
            ..SpectralInitConfig::default()
        };
        let init = initial_periods(&samples, None, &config).unwrap();
        assert_eq!(init.none, None);
        assert_eq!(init.per_series.len(), 6);
        assert_eq!(init.psi, 2, "{init:?}");
        assert!(close(init.periods[0], 12.0, 0.1), "{init:?}");
        assert!(close(init.periods[1], 6.0, 0.1), "{init:?}");
        assert_eq!(init.variances[0], 0.95);
        // amplitudes 0.6 and 0.3 of the same busy levels
        assert!(close(init.variances[1], 0.95 * 0.3 / 0.6, 0.05), "{init:?}");
        assert_eq!(initial_periods(&samples, None, &config).unwrap(), init);
        let other = initial_periods(
            &samples,
            None,
            &SpectralInitConfig {
                seed: 1,
                ..config.clone()
            },
        )
        .unwrap();
        assert_ne!(
            other
                .per_series
                .iter()
                .map(|s| s.centre)
                .collect::<Vec<_>>(),
            init.per_series.iter().map(|s| s.centre).collect::<Vec<_>>()
        );
    }

    #[test]
    fn initial_periods_without_periodicity_or_series_say_why() {
        let flat = synthetic(|region, _| 1.0 + region as f64);
        let config = SpectralInitConfig::default();
        let init = initial_periods(&flat, None, &config).unwrap();
        assert_eq!(init.none, Some(NoPeriods::NotPeriodic));
        assert!(init.periods.is_empty() && init.variances.is_empty());
        assert_eq!(init.per_series.len(), 8);
        assert!(init.per_series.iter().all(|s| s.fit.components == 0));
        // Nine hourly bins are fewer than five folds of two.
        let (short, _) = flat.split_at(9.0);
        let init = initial_periods(&short, None, &config).unwrap();
        assert_eq!(init.none, Some(NoPeriods::NoSeries));
        assert!(init.per_series.is_empty());
        assert_eq!(
            initial_periods(&RateSamples::default(), None, &config),
            Err(ActivityError::Empty)
        );
        let bad = SpectralInitConfig {
            period_step: 0.0,
            ..config
        };
        assert!(matches!(
            initial_periods(&flat, None, &bad),
            Err(ActivityError::Config(_))
        ));
    }

    #[test]
    fn inducing_points_follow_the_durations() {
        let inputs = [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]];
        let z = inducing_points(&inputs, Some(&[3.0, 1.0]), 1, 0).unwrap();
        assert_eq!(z, [[0.25, 0.25, 0.25]]);
        let z = inducing_points(&inputs, None, 1, 0).unwrap();
        assert_eq!(z, [[0.5, 0.5, 0.5]]);
        assert!(inducing_points(&inputs, Some(&[1.0, f64::NAN]), 1, 0).is_err());
        assert!(inducing_points(&inputs, None, 3, 0).is_err());
        assert!(inducing_points(&inputs, None, 0, 0).is_err());
    }
}

#[cfg(test)]
mod copa_tests {
    use super::*;
    use crate::{CopaConfig, CopaMap, PeriodInitMode};

    #[test]
    fn copa_map_starts_from_the_spectral_periods_or_the_day() {
        // Two 5 m regions, hourly for 8 days of 12 h, a 12 h and a 6 h cycle.
        let mut samples = RateSamples::default();
        for t in 0..96 {
            let t = f64::from(t);
            let cycle = 1.0 + 0.6 * (TAU * t / 12.0).cos() + 0.3 * (TAU * t / 6.0).sin();
            for (x, busy) in [([1.0, 1.0], 2.0), ([7.0, 1.0], 5.0)] {
                samples.push(x, t, busy * cycle).unwrap();
            }
        }
        let config = CopaConfig {
            inducing: 8,
            iterations: 2,
            batch_size: 64,
            init: PeriodInitMode::Spectral,
            ..CopaConfig::default()
        };
        let map = CopaMap::fit(&samples, &config).unwrap();
        let init = map.period_init.as_ref().unwrap();
        assert_eq!(init.per_series.len(), 2);
        assert_eq!(init.periods.len(), 2, "{init:?}");
        assert!((init.periods[0] - 12.0).abs() < 0.1 && (init.periods[1] - 6.0).abs() < 0.1);
        let trained = map.periods();
        assert_eq!(trained.len(), 2);
        assert!((trained[0] - 12.0).abs() < 1.0, "{trained:?}");
        let day = CopaMap::fit(
            &samples,
            &CopaConfig {
                init: PeriodInitMode::Day,
                ..config.clone()
            },
        )
        .unwrap();
        assert!(day.period_init.is_none());
        assert_eq!(day.periods().len(), 2);
        let dwell = vec![1.0; samples.len()];
        assert!(CopaMap::fit_with_dwell(&samples, &dwell, &config).is_ok());
        assert!(CopaMap::fit_with_dwell(&samples, &dwell[1..], &config).is_err());
    }
}
