//! FFT FreMEn: the spectral model of a *uniformly sampled* binary state, with the outlier
//! set that makes it lossless ([Krajník 2017] §III-B, §IV).
//!
//! # Model
//! A binary series `s(n)`, `n = 0..N`, sampled every `step` seconds from `start`, is
//! represented by two finite sets:
//!
//! * `P` — the mean `α_0` and the `l` DFT coefficients `X_k = Σ_n s(n) e^{-j2πkn/N}` of largest
//!   magnitude ([Krajník 2017] eq. (1)–(2)), giving
//!   `p(n) = α_0 + Σ_{k∈P} 2|X_k|/N · cos(2πkn/N + arg X_k)` (eq. (10));
//! * `O` — the outlier set: the samples where the thresholded prediction
//!   `s'(n) = p(n) ≥ 0.5` differs from `s(n)`, Δ-encoded as the sorted positions where the
//!   mismatch starts or stops ("toggles").
//!
//! Then `s(n) = s'(n) ⊕ (n ∈ O)` exactly (eq. (7), [`FftFremen::retrieve`]); a new
//! measurement adds a toggle only when it disagrees with that reconstruction (eq. (8),
//! [`FftFremen::add_measurement`]); a model update reconstructs the series, recomputes the
//! spectrum and the outlier set (§III-B-3, [`FftFremen::update`]); `s'(t, c) = p(t) ≥ c` is
//! the prediction at confidence `c` (eq. (9), [`FftFremen::predict_state`]); the estimation
//! and prediction errors are read off the outlier set (eq. (14)–(15),
//! [`FftFremen::error_between`]).
//!
//! # Algorithms
//! Binary series are handled as run lengths throughout: the series is the list of positions
//! where it changes. Two spectra are available and give the same coefficients up to
//! rounding:
//!
//! * the real FFT of the whole series ([`realfft`]), `O(N log N)`, for candidate bins up to
//!   `N/2`;
//! * the *run-length spectrum*: a run `[a, b)` of ones contributes
//!   `(w^{ka} − w^{kb}) / (1 − w^k)` with `w = e^{-j2π/N}`, so `X_k = D_k / (1 − w^k)` where
//!   `D_k = Σ_edges ±w^{k·e}` — `O(E·M)` for `E` edges and bins `1..=M`; far faster when the
//!   series changes rarely and only the slower components are candidates (the original
//!   FROctoMap code used bins 1..99).
//!
//! The thresholded prediction `s'` is found without evaluating `p` at every sample: `p` is a
//! sum of `l` cosines whose derivative is bounded by `L = Σ 2A_k·2πk/N` per sample, so an
//! interval whose ends are on the same side of the threshold by more than `L·len/2` cannot
//! cross it; other intervals are bisected down to single samples. Crossing positions are
//! therefore exactly those of the point-wise test `p(n) ≥ 0.5` evaluated with the same
//! arithmetic as [`FftFremen::retrieve`], which keeps reconstruction bit-exact.

use std::f64::consts::TAU;

use realfft::RealFftPlanner;
use rustfft::num_complex::Complex64;
use serde::{Deserialize, Serialize};

use crate::error::{BuildError, ConfigError, ObservationError};
use crate::model::{Ordered, TemporalModel, saturate};
use crate::observe::ObservedSpan;

/// Largest series length supported (2^40 samples: 35,000 years at 1 s).
pub const MAX_LEN: u64 = 1 << 40;

/// Configuration of an [`FftFremen`] model.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FftFremenConfig {
    /// Number of spectral components kept (the order `l`).
    pub order: usize,
    /// Candidate components are the DFT bins whose period `N·step/k` is at least this many
    /// seconds (default 7200 s: two hours, as the default period set of
    /// [`FremenModel`](crate::FremenModel)); `None` = the whole spectrum up to the Nyquist
    /// bin (excluded). The original FROctoMap code used bins 1..99 whatever the length.
    pub shortest_period_secs: Option<f64>,
}

impl Default for FftFremenConfig {
    fn default() -> Self {
        FftFremenConfig {
            order: 2,
            shortest_period_secs: Some(7200.0),
        }
    }
}

impl FftFremenConfig {
    /// The given order with the default candidate periods.
    pub fn with_order(order: usize) -> Self {
        FftFremenConfig {
            order,
            ..FftFremenConfig::default()
        }
    }
}

/// One component of the spectral set `P`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FftComponent {
    /// DFT bin `k`: the component has period `N·step / k`.
    pub bin: u64,
    /// `|X_k| / N`; the cosine amplitude is twice this.
    pub amplitude: f64,
    /// `arg X_k` in radians: the component is `2A cos(2πkn/N + phase)`.
    pub phase: f64,
}

/// FFT FreMEn model of a uniformly sampled binary state (see the [module docs](self)).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FftFremen {
    config: FftFremenConfig,
    start: f64,
    step: f64,
    /// Length `N` of the series the spectrum was computed over (0 = never built).
    model_len: u64,
    /// Number of samples represented (the spectrum plus measurements added since).
    len: u64,
    gain: f64,
    components: Vec<FftComponent>,
    #[serde(with = "delta_encoding")]
    outliers: Vec<u64>,
}

/// Which spectrum algorithm to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpectrumMethod {
    /// Pick the cheaper of the two for the data at hand.
    Auto,
    /// Real FFT of the whole series.
    Fft,
    /// Run-length spectrum from the change positions.
    RunLength,
}

impl FftFremen {
    /// An empty model of a series sampled every `step` seconds from `start`: it predicts 0.5
    /// until measurements are added and the model is [updated](FftFremen::update).
    ///
    /// # Errors
    /// If `start` is negative or not finite, or `step` not positive and finite.
    pub fn new(start: f64, step: f64, config: FftFremenConfig) -> Result<Self, ConfigError> {
        if !(start.is_finite() && start >= 0.0) {
            return Err(ConfigError::OutOfRange {
                name: "start",
                value: start.to_string(),
                expected: "a finite time >= 0",
            });
        }
        if !(step.is_finite() && step > 0.0) {
            return Err(ConfigError::OutOfRange {
                name: "step",
                value: step.to_string(),
                expected: "a finite number of seconds > 0",
            });
        }
        if let Some(shortest) = config.shortest_period_secs
            && !(shortest.is_finite() && shortest > 0.0)
        {
            return Err(ConfigError::PeriodNotPositive {
                period_secs: shortest,
            });
        }
        Ok(FftFremen {
            config,
            start,
            step,
            model_len: 0,
            len: 0,
            gain: 0.5,
            components: Vec::new(),
            outliers: Vec::new(),
        })
    }

    /// Builds the model of a series of 0/1 samples ([Krajník 2017] §III-B).
    ///
    /// # Errors
    /// Invalid `start`/`step`, a sample other than 0 or 1 (with its index), an empty series
    /// or one longer than [`MAX_LEN`].
    pub fn build(
        start: f64,
        step: f64,
        samples: &[u8],
        config: FftFremenConfig,
    ) -> Result<Self, BuildError> {
        Self::build_with(start, step, samples, config, SpectrumMethod::Auto)
    }

    /// [`FftFremen::build`] with an explicit choice of spectrum algorithm.
    ///
    /// # Errors
    /// As [`FftFremen::build`].
    pub fn build_with(
        start: f64,
        step: f64,
        samples: &[u8],
        config: FftFremenConfig,
        method: SpectrumMethod,
    ) -> Result<Self, BuildError> {
        let mut model = FftFremen::new(start, step, config)?;
        if samples.is_empty() {
            return Err(BuildError::NotEnoughData("the series is empty".into()));
        }
        if samples.len() as u64 > MAX_LEN {
            return Err(BuildError::NotEnoughData(format!(
                "{} samples exceed the supported {MAX_LEN}",
                samples.len()
            )));
        }
        let edges = edges_of(samples)?;
        model.rebuild(&edges, samples.len() as u64, Some(samples), method);
        Ok(model)
    }

    /// Recomputes `P` and `O` from the series given by its change positions.
    fn rebuild(&mut self, edges: &[u64], n: u64, samples: Option<&[u8]>, method: SpectrumMethod) {
        let ones = ones_in(edges, 0, n);
        self.gain = ones as f64 / n as f64;
        let max_bin = self.max_bin_for(n);
        let coefficients = if max_bin == 0 {
            Vec::new()
        } else {
            spectrum(edges, n, max_bin, samples, method)
        };
        // Top-`order` bins by magnitude; ties keep the lower bin (longer period) first.
        let magnitudes: Vec<f64> = coefficients.iter().map(|x| x.norm()).collect();
        let stronger = |a: &u64, b: &u64| {
            magnitudes[*b as usize - 1]
                .total_cmp(&magnitudes[*a as usize - 1])
                .then(a.cmp(b))
        };
        let mut bins: Vec<u64> = (1..=max_bin).collect();
        if self.config.order < bins.len() {
            bins.select_nth_unstable_by(self.config.order, stronger);
            bins.truncate(self.config.order);
        }
        bins.sort_by(stronger);
        self.components = bins
            .iter()
            .take(self.config.order)
            .map(|&k| {
                let x = coefficients[k as usize - 1];
                FftComponent {
                    bin: k,
                    amplitude: x.norm() / n as f64,
                    phase: x.arg(),
                }
            })
            .collect();
        self.model_len = n;
        self.len = n;
        let predicted = self.threshold_edges(0.5, 0, n);
        self.outliers = xor_edges(edges, &predicted);
    }

    fn max_bin_for(&self, n: u64) -> u64 {
        let nyquist_free = n.saturating_sub(1) / 2;
        match self.config.shortest_period_secs {
            None => nyquist_free,
            Some(shortest) => ((n as f64 * self.step / shortest) as u64).min(nyquist_free),
        }
    }

    /// The configuration.
    pub fn config(&self) -> FftFremenConfig {
        self.config
    }

    /// Mean `α_0` of the series the spectrum was computed over.
    pub fn gain(&self) -> f64 {
        self.gain
    }

    /// The spectral set `P`, strongest first.
    pub fn components(&self) -> &[FftComponent] {
        &self.components
    }

    /// Positions where the mismatch between `s'` and `s` starts or stops (the Δ-encoded `O`).
    pub fn outlier_toggles(&self) -> &[u64] {
        &self.outliers
    }

    /// Number of samples represented.
    pub fn len(&self) -> u64 {
        self.len
    }

    /// Whether the model represents no sample.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Length of the series the spectrum was last computed over.
    pub fn model_len(&self) -> u64 {
        self.model_len
    }

    /// Sampling start (s) and step (s).
    pub fn sampling(&self) -> (f64, f64) {
        (self.start, self.step)
    }

    /// Period in seconds of a DFT bin of the current spectrum.
    pub fn period_of_bin(&self, bin: u64) -> f64 {
        self.model_len as f64 * self.step / bin as f64
    }

    /// `p(n)` at an integer sample, before saturation, with the bin phase `k·n mod N`
    /// reduced exactly in integers (eq. (10)).
    #[inline]
    fn p_at(&self, n: u64) -> f64 {
        let big_n = self.model_len as u128;
        let mut p = self.gain;
        for c in &self.components {
            let r = (c.bin as u128 * n as u128 % big_n) as f64 / big_n as f64;
            p += 2.0 * c.amplitude * (TAU * r + c.phase).cos();
        }
        p
    }

    /// `p(x)` at a real sample position `x`.
    fn p_at_position(&self, x: f64) -> f64 {
        let big_n = self.model_len as f64;
        let mut p = self.gain;
        for c in &self.components {
            let r = (c.bin as f64 * x).rem_euclid(big_n) / big_n;
            p += 2.0 * c.amplitude * (TAU * r + c.phase).cos();
        }
        p
    }

    /// Thresholded prediction `s'(n, c) = p(n) ≥ c` (eq. (9)) at sample `n`.
    pub fn predicted_state_at(&self, n: u64, confidence: f64) -> bool {
        self.p_at(n) >= confidence
    }

    /// Prediction at confidence `c` at a time (eq. (9)): whether `p(t) ≥ c`.
    pub fn predict_state(&self, time: f64, confidence: f64) -> bool {
        self.predict(time) >= confidence
    }

    /// The stored state of sample `n < len` (eq. (7)): `s'(n) ⊕ (n ∈ O)`.
    ///
    /// # Panics
    /// If `n >= self.len()`.
    pub fn retrieve(&self, n: u64) -> bool {
        assert!(
            n < self.len,
            "sample {n} not in the model (len {})",
            self.len
        );
        let toggles = self.outliers.partition_point(|&o| o <= n);
        self.predicted_state_at(n, 0.5) ^ (toggles % 2 == 1)
    }

    /// Change positions of `s'(n, c)` over `[lo, hi)` (0 before `lo`), by
    /// [`crate::crossings::threshold_toggles`] with the per-sample Lipschitz bound
    /// `L = Σ 2A_k·2πk/N` of `p`.
    pub fn threshold_edges(&self, confidence: f64, lo: u64, hi: u64) -> Vec<u64> {
        if self.model_len == 0 {
            return Vec::new();
        }
        let lipschitz: f64 = self
            .components
            .iter()
            .map(|c| 2.0 * c.amplitude * TAU * c.bin as f64 / self.model_len as f64)
            .sum();
        crate::crossings::threshold_toggles(lo, hi, &|n| self.p_at(n) - confidence, &|a, b| {
            lipschitz * (b - a) as f64
        })
    }

    /// Change positions of the stored series `s` over `[0, len)` (eq. (7) in bulk).
    pub fn reconstruct_edges(&self) -> Vec<u64> {
        xor_edges(&self.threshold_edges(0.5, 0, self.len), &self.outliers)
    }

    /// The stored series as 0/1 samples (eq. (7)); lossless.
    pub fn reconstruct(&self) -> Vec<u8> {
        expand_edges(&self.reconstruct_edges(), self.len)
    }

    /// Adds the measurement of the next sample (index `len`) (eq. (8)): a toggle is appended
    /// to `O` only if `state` differs from the reconstruction. Predictions do not change
    /// until the next [update](FftFremen::update).
    ///
    /// # Panics
    /// If the model would exceed [`MAX_LEN`] samples.
    pub fn add_measurement(&mut self, state: bool) {
        assert!(self.len < MAX_LEN, "series too long");
        let n = self.len;
        let reconstructed = if self.model_len == 0 {
            self.outliers.len() % 2 == 1
        } else {
            self.predicted_state_at(n, 0.5) ^ (self.outliers.len() % 2 == 1)
        };
        if reconstructed != state {
            self.outliers.push(n);
        }
        self.len += 1;
    }

    /// Model update ([Krajník 2017] §III-B-3): reconstructs the whole series, recomputes the spectrum
    /// over it, keeps the `order` strongest components and rebuilds the outlier set. Lossless:
    /// the series represented is unchanged.
    pub fn update(&mut self) {
        if self.len == 0 {
            return;
        }
        let edges = if self.model_len == 0 {
            // Never built: `s'` is all zeros, so the toggles are the series itself.
            self.outliers.clone()
        } else {
            self.reconstruct_edges()
        };
        self.rebuild(&edges, self.len, None, SpectrumMethod::Auto);
    }

    /// Changes the order and updates the model (lossless).
    pub fn update_with_order(&mut self, order: usize) {
        self.config.order = order;
        self.update();
    }

    /// Fraction of samples in `[a, b)` where `s'` differs from `s` (eq. (15)): the estimation
    /// error over data the spectrum was computed from, the prediction error over samples added
    /// after the last update (§IV-A).
    pub fn error_between(&self, a: u64, b: u64) -> f64 {
        let b = b.min(self.len);
        if b <= a {
            return 0.0;
        }
        ones_in(&self.outliers, a, b) as f64 / (b - a) as f64
    }

    /// The lossy model: the same spectrum without the outlier set ([Krajník 2017] §IV-C). It
    /// predicts identically but no longer reconstructs the series exactly.
    pub fn without_outliers(&self) -> Self {
        FftFremen {
            outliers: Vec::new(),
            ..self.clone()
        }
    }

    /// Estimation error `ε_e = ε(0, N)` over the data of the last update.
    pub fn estimation_error(&self) -> f64 {
        self.error_between(0, self.model_len)
    }

    /// Chooses the order by prediction error ([Krajník 2017] §IV-A/B): builds the spectrum on the
    /// first `1 − holdout` of the series, predicts the rest with orders `0..=max_order`, and
    /// returns the order with the fewest mispredicted samples with all the errors (eq. (15)).
    /// `config.order` is ignored.
    ///
    /// # Errors
    /// As [`FftFremen::build`], or if the holdout leaves fewer than 2 samples on either side.
    pub fn select_order(
        samples: &[u8],
        step: f64,
        holdout: f64,
        max_order: usize,
        config: FftFremenConfig,
    ) -> Result<(usize, Vec<f64>), BuildError> {
        crate::select::check_holdout(holdout)?;
        let n = samples.len() as u64;
        let split = ((n as f64) * (1.0 - holdout)).round() as u64;
        if split < 2 || n - split < 2 {
            return Err(BuildError::NotEnoughData(format!(
                "{n} samples cannot be split {:.0}/{:.0} %",
                100.0 * (1.0 - holdout),
                100.0 * holdout
            )));
        }
        let config = FftFremenConfig {
            order: max_order,
            ..config
        };
        let prefix = FftFremen::build(0.0, step, &samples[..split as usize], config)?;
        let actual = restrict(&edges_of(samples)?, split, n);
        let all = prefix.components.clone();
        let mut errors = Vec::with_capacity(max_order + 1);
        let mut model = prefix;
        for order in 0..=max_order.min(all.len()) {
            model.components = all[..order].to_vec();
            let predicted = model.threshold_edges(0.5, split, n);
            errors.push(
                ones_in(&xor_edges(&actual, &predicted), split, n) as f64 / (n - split) as f64,
            );
        }
        let best = (0..errors.len())
            .min_by(|&a, &b| errors[a].total_cmp(&errors[b]))
            .unwrap_or(0);
        Ok((best, errors))
    }

    fn next_time(&self, offset: u64) -> f64 {
        self.start + (self.len + offset) as f64 * self.step
    }
}

impl TemporalModel for FftFremen {
    /// Appends measurements (eq. (8)). Each time must be the next sample time
    /// `start + len·step` (within 1e-6 of a step) and each value 0 or 1.
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        self.span().validate(times, values)?;
        crate::observe::check_binary(values)?;
        for (index, &time) in times.iter().enumerate() {
            let expected = self.next_time(index as u64);
            if (time - expected).abs() > 1e-6 * self.step {
                return Err(ObservationError::OffGrid {
                    index,
                    time,
                    expected,
                });
            }
        }
        for &v in values {
            self.add_measurement(v == 1.0);
        }
        Ok(())
    }

    /// `p(t)` of eq. (10) at `t`, repeating with period `N·step` (0.5 before the first update).
    fn predict(&self, time: f64) -> f64 {
        if self.model_len == 0 {
            return 0.5;
        }
        saturate(self.p_at_position((time - self.start) / self.step))
    }

    fn span(&self) -> ObservedSpan {
        ObservedSpan {
            count: self.len,
            first: self.start,
            last: self.start + (self.len.max(1) - 1) as f64 * self.step,
        }
    }
}

impl Ordered for FftFremen {
    fn order(&self) -> usize {
        self.config.order
    }

    fn max_order(&self) -> usize {
        self.max_bin_for(self.len) as usize
    }

    /// Changes the order and [updates](FftFremen::update) the model.
    fn set_order(&mut self, order: usize) {
        self.update_with_order(order.min(self.max_order()));
    }
}

/// Checks that `(times, values)` is a uniformly sampled binary series and returns its start,
/// step and samples.
///
/// # Errors
/// Fewer than two samples, a value other than 0/1, or a time off the grid
/// `times[0] + i·step` (by more than 1e-6 of a step), with its index.
pub fn uniform_binary_samples(
    times: &[f64],
    values: &[f64],
) -> Result<(f64, f64, Vec<u8>), BuildError> {
    crate::observe::validate(None, times, values)?;
    if times.len() < 2 {
        return Err(BuildError::NotEnoughData(
            "a uniformly sampled series needs at least two samples".into(),
        ));
    }
    crate::observe::check_binary(values)?;
    let (start, step) = (times[0], times[1] - times[0]);
    for (index, &time) in times.iter().enumerate() {
        let expected = start + index as f64 * step;
        if step <= 0.0 || (time - expected).abs() > 1e-6 * step {
            return Err(ObservationError::OffGrid {
                index,
                time,
                expected,
            }
            .into());
        }
    }
    let samples = values.iter().map(|&v| u8::from(v == 1.0)).collect();
    Ok((start, step, samples))
}

/// Change positions of a 0/1 series: `n` such that `s(n) ≠ s(n−1)`, with `s(−1) = 0`.
///
/// # Errors
/// [`ObservationError::NonBinaryValue`] for a sample other than 0 or 1.
pub fn edges_of(samples: &[u8]) -> Result<Vec<u64>, ObservationError> {
    let mut edges = Vec::new();
    let mut previous = 0u8;
    let mut index = 0usize;
    // Skip runs 64 bytes at a time with a branch-free (vectorised) OR of differences;
    // look closer only where something changes.
    for chunk in samples.chunks(64) {
        if chunk.iter().fold(0u8, |acc, &b| acc | (b ^ previous)) == 0 {
            index += chunk.len();
            continue;
        }
        for &b in chunk {
            if b != previous {
                if b > 1 {
                    return Err(ObservationError::NonBinaryValue {
                        index,
                        value: f64::from(b),
                    });
                }
                edges.push(index as u64);
                previous = b;
            }
            index += 1;
        }
    }
    Ok(edges)
}

/// The 0/1 series of length `len` whose change positions are `edges`.
pub fn expand_edges(edges: &[u64], len: u64) -> Vec<u8> {
    let mut out = vec![0u8; len as usize];
    for pair in edges.chunks(2) {
        let from = pair[0].min(len) as usize;
        let to = pair.get(1).map_or(len, |&e| e.min(len)) as usize;
        out[from..to].fill(1);
    }
    out
}

/// Change positions of the XOR of two series given by their change positions
/// (the symmetric difference of two sorted lists).
pub fn xor_edges(a: &[u64], b: &[u64]) -> Vec<u64> {
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => {
                out.push(a[i]);
                i += 1;
            }
            std::cmp::Ordering::Greater => {
                out.push(b[j]);
                j += 1;
            }
            std::cmp::Ordering::Equal => {
                i += 1;
                j += 1;
            }
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}

/// Number of samples in `[lo, hi)` where the series given by its change positions is 1.
pub fn ones_in(edges: &[u64], lo: u64, hi: u64) -> u64 {
    let mut count = 0;
    let first = edges.partition_point(|&e| e <= lo);
    let mut on = first % 2 == 1;
    let mut position = lo;
    for &e in &edges[first..] {
        if e >= hi {
            break;
        }
        if on {
            count += e - position;
        }
        on = !on;
        position = e;
    }
    if on {
        count += hi - position;
    }
    count
}

/// The same series on `[lo, hi)` and 0 elsewhere.
fn restrict(edges: &[u64], lo: u64, hi: u64) -> Vec<u64> {
    let first = edges.partition_point(|&e| e <= lo);
    let mut out = Vec::new();
    if first % 2 == 1 {
        out.push(lo);
    }
    out.extend(edges[first..].iter().copied().take_while(|&e| e < hi));
    if out.len() % 2 == 1 {
        out.push(hi);
    }
    out
}

/// DFT bins `1..=max_bin` of the series of length `n` given by its change positions.
fn spectrum(
    edges: &[u64],
    n: u64,
    max_bin: u64,
    samples: Option<&[u8]>,
    method: SpectrumMethod,
) -> Vec<Complex64> {
    let run_length_cost = edges.len() as f64 * max_bin as f64;
    let fft_cost = 4.0 * n as f64 * (n as f64).log2().max(1.0);
    let use_fft = match method {
        SpectrumMethod::Fft => true,
        SpectrumMethod::RunLength => false,
        SpectrumMethod::Auto => run_length_cost > fft_cost,
    };
    if use_fft {
        let owned;
        let samples = match samples {
            Some(s) => s,
            None => {
                owned = expand_edges(edges, n);
                &owned
            }
        };
        fft_spectrum(samples, max_bin)
    } else {
        run_length_spectrum(edges, n, max_bin)
    }
}

/// Bins `1..=max_bin` by a real FFT of the whole series.
pub fn fft_spectrum(samples: &[u8], max_bin: u64) -> Vec<Complex64> {
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(samples.len());
    let mut input: Vec<f64> = samples.iter().map(|&s| f64::from(s)).collect();
    let mut output = fft.make_output_vec();
    fft.process(&mut input, &mut output)
        .expect("buffer lengths come from the plan");
    output[1..=max_bin as usize].to_vec()
}

/// Bins `1..=max_bin` from the change positions: `X_k = D_k / (1 − w^k)` with
/// `D_k = Σ_e ±w^{k·e}`, `w = e^{-j2π/n}` (see the [module docs](self)).
pub fn run_length_spectrum(edges: &[u64], n: u64, max_bin: u64) -> Vec<Complex64> {
    const BLOCK: usize = 64;
    const ANCHOR: u64 = 64;
    let bins = max_bin as usize;
    let mut d = vec![Complex64::new(0.0, 0.0); bins];
    let angle = |k: u64, e: u64| TAU * ((k as u128 * e as u128 % n as u128) as f64 / n as f64);
    for (block_index, block) in edges.chunks(BLOCK).enumerate() {
        let m = block.len();
        let mut sign = [0.0f64; BLOCK];
        let (mut zr, mut zi) = ([0.0f64; BLOCK], [0.0f64; BLOCK]);
        for i in 0..m {
            // Rising edges (even positions in the list) add, falling ones subtract.
            sign[i] = if (block_index * BLOCK + i).is_multiple_of(2) {
                1.0
            } else {
                -1.0
            };
            let (s, c) = angle(1, block[i]).sin_cos();
            zr[i] = c;
            zi[i] = -s;
        }
        let (mut wr, mut wi) = (zr, zi);
        for (k0, dk) in d.iter_mut().enumerate() {
            let k = k0 as u64 + 1;
            if k > 1 {
                if (k - 1).is_multiple_of(ANCHOR) {
                    for i in 0..m {
                        let (s, c) = angle(k, block[i]).sin_cos();
                        wr[i] = c;
                        wi[i] = -s;
                    }
                } else {
                    crate::spectrum::rotate_block(&mut wr, &mut wi, &zr, &zi);
                }
            }
            let (mut re, mut im) = (0.0, 0.0);
            for i in 0..m {
                re += sign[i] * wr[i];
                im += sign[i] * wi[i];
            }
            *dk += Complex64::new(re, im);
        }
    }
    let ends_high = edges.len() % 2 == 1;
    d.iter()
        .enumerate()
        .map(|(k0, &dk)| {
            let k = k0 as u64 + 1;
            // A series that ends high has its last run closed at n, where w^{kn} = 1.
            let dk = if ends_high { dk - 1.0 } else { dk };
            let (s, c) = angle(k, 1).sin_cos();
            dk / (Complex64::new(1.0, 0.0) - Complex64::new(c, -s))
        })
        .collect()
}

/// Sorted positions as gaps: the first position, then each one's distance to the one before
/// (small numbers, compact as varints in model files).
pub fn to_gaps(positions: &[u64]) -> Vec<u64> {
    let mut previous = 0;
    positions
        .iter()
        .map(|&p| {
            let gap = p - previous;
            previous = p;
            gap
        })
        .collect()
}

/// The positions of `gaps` ([`to_gaps`] reversed); `None` if one overflows `u64`.
pub fn from_gaps(gaps: &[u64]) -> Option<Vec<u64>> {
    let mut position = 0u64;
    gaps.iter()
        .map(|&g| {
            position = position.checked_add(g)?;
            Some(position)
        })
        .collect()
}

/// Serialises sorted positions as gaps ([`to_gaps`]).
mod delta_encoding {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(positions: &[u64], serializer: S) -> Result<S::Ok, S::Error> {
        super::to_gaps(positions).serialize(serializer)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Vec<u64>, D::Error> {
        let gaps = Vec::<u64>::deserialize(deserializer)?;
        super::from_gaps(&gaps)
            .ok_or_else(|| serde::de::Error::custom("outlier position overflows"))
    }
}

impl FftFremen {
    /// Checks invariants of a model read from a file.
    pub fn is_consistent(&self) -> bool {
        self.step.is_finite()
            && self.step > 0.0
            && self.start.is_finite()
            && self.len <= MAX_LEN
            && self.model_len <= self.len
            && self.outliers.windows(2).all(|w| w[0] < w[1])
            && self.outliers.last().is_none_or(|&o| o < self.len)
            && self.components.iter().all(|c| {
                c.bin >= 1
                    && c.bin < self.model_len.max(1)
                    && c.amplitude.is_finite()
                    && c.phase.is_finite()
            })
            && self.gain.is_finite()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::naive::naive_dft;

    /// A week-like binary series: open in the afternoons, with noise flips.
    fn door_series(n: usize) -> Vec<u8> {
        let mut state = 0u8;
        (0..n)
            .map(|i| {
                let day = (i % 1440) as f64 / 1440.0;
                let base = u8::from((0.35..0.75).contains(&day));
                if (i * 2654435761) % 997 == 0 {
                    state ^= 1;
                }
                base ^ state
            })
            .collect()
    }

    #[test]
    fn both_spectra_equal_the_textbook_dft() {
        let samples = door_series(3000);
        let edges = edges_of(&samples).unwrap();
        let signal: Vec<f64> = samples.iter().map(|&s| f64::from(s)).collect();
        let oracle = naive_dft(&signal, 200);
        let rl = run_length_spectrum(&edges, 3000, 199);
        let fft = fft_spectrum(&samples, 199);
        for k in 1..200 {
            assert!((rl[k - 1] - oracle[k]).norm() < 1e-9, "run-length bin {k}");
            assert!((fft[k - 1] - oracle[k]).norm() < 1e-9, "fft bin {k}");
        }
    }

    #[test]
    fn edge_helpers_round_trip() {
        let samples = vec![1, 1, 0, 0, 1, 0, 1, 1, 1];
        let edges = edges_of(&samples).unwrap();
        assert_eq!(edges, vec![0, 2, 4, 5, 6]);
        assert_eq!(expand_edges(&edges, 9), samples);
        assert_eq!(ones_in(&edges, 0, 9), 6);
        assert_eq!(ones_in(&edges, 1, 5), 2);
        assert_eq!(ones_in(&edges, 3, 4), 0);
        assert_eq!(xor_edges(&[1, 4], &[2, 4, 6]), vec![1, 2, 6]);
        assert_eq!(restrict(&edges, 3, 8), vec![4, 5, 6, 8]);
        assert!(matches!(
            edges_of(&[0, 1, 2]),
            Err(ObservationError::NonBinaryValue { index: 2, .. })
        ));
    }

    #[test]
    fn reconstruction_is_lossless_and_matches_pointwise_retrieval() {
        let samples = door_series(20_000);
        for order in [0, 1, 3, 8] {
            let config = FftFremenConfig {
                order,
                shortest_period_secs: None,
            };
            let model = FftFremen::build(0.0, 60.0, &samples, config).unwrap();
            assert_eq!(model.reconstruct(), samples, "order {order}");
            for n in (0..20_000).step_by(7) {
                assert_eq!(
                    model.retrieve(n) as u8,
                    samples[n as usize],
                    "order {order} n {n}"
                );
            }
        }
    }

    #[test]
    fn thresholding_equals_brute_force() {
        let samples = door_series(10_000);
        let model = FftFremen::build(
            0.0,
            1.0,
            &samples,
            FftFremenConfig {
                order: 5,
                shortest_period_secs: Some(10_000.0 / 60.0),
            },
        )
        .unwrap();
        for c in [0.5, 0.2, 0.9] {
            let brute: Vec<u8> = (0..10_000)
                .map(|n| u8::from(model.predicted_state_at(n, c)))
                .collect();
            assert_eq!(
                model.threshold_edges(c, 0, 10_000),
                edges_of(&brute).unwrap(),
                "c = {c}"
            );
        }
    }

    #[test]
    fn measurements_add_toggles_and_update_is_lossless() {
        let samples = door_series(12_000);
        let mut model =
            FftFremen::build(0.0, 1.0, &samples[..8000], FftFremenConfig::default()).unwrap();
        let mut chunked = model.clone();
        model
            .observe(
                &(8000..12_000).map(f64::from).collect::<Vec<_>>(),
                &samples[8000..]
                    .iter()
                    .map(|&s| f64::from(s))
                    .collect::<Vec<_>>(),
            )
            .unwrap();
        for n in 8000..12_000u32 {
            chunked
                .observe(&[f64::from(n)], &[f64::from(samples[n as usize])])
                .unwrap();
        }
        assert_eq!(model, chunked);
        assert_eq!(model.reconstruct(), samples);
        // Prediction error over the appended part equals the mismatch rate of s' there.
        let mismatches = (8000..12_000u64)
            .filter(|&n| model.predicted_state_at(n, 0.5) != (samples[n as usize] == 1))
            .count();
        assert_eq!(
            model.error_between(8000, 12_000),
            mismatches as f64 / 4000.0
        );
        model.update_with_order(6);
        assert_eq!(model.model_len(), 12_000);
        assert_eq!(model.reconstruct(), samples);
        // Appending off the grid or a non-binary value is refused.
        assert!(matches!(
            model.observe(&[12_001.0], &[1.0]),
            Err(ObservationError::OffGrid { .. })
        ));
        assert!(model.observe(&[12_000.0], &[0.5]).is_err());
    }

    #[test]
    fn order_selection_prefers_the_generalising_order() {
        // A daily pattern with noise: order 0 mispredicts every afternoon, a few components
        // capture it.
        let samples = door_series(6 * 1440);
        let config = FftFremenConfig::default();
        let (best, errors) = FftFremen::select_order(&samples, 60.0, 0.25, 6, config).unwrap();
        assert_eq!(errors.len(), 7);
        assert!(best >= 1, "errors {errors:?}");
        assert!(errors[best] < errors[0]);
        assert!(FftFremen::select_order(&samples[..3], 60.0, 0.25, 6, config).is_err());
        assert!(FftFremen::select_order(&samples, 60.0, 1.5, 6, config).is_err());
    }

    #[test]
    fn empty_model_learns_after_update() {
        let samples = door_series(5000);
        let mut model = FftFremen::new(100.0, 2.0, FftFremenConfig::default()).unwrap();
        let times: Vec<f64> = (0..5000).map(|i| 100.0 + 2.0 * i as f64).collect();
        let values: Vec<f64> = samples.iter().map(|&s| f64::from(s)).collect();
        model.observe(&times, &values).unwrap();
        assert_eq!(model.predict(150.0), 0.5);
        model.update();
        assert_eq!(model.reconstruct(), samples);
        assert_ne!(model.predict(150.0), 0.5);
    }

    #[test]
    fn conformance_of_appending() {
        let times: Vec<f64> = (0..50).map(|i| 10.0 + 5.0 * i as f64).collect();
        let values: Vec<f64> = door_series(50).iter().map(|&s| f64::from(s)).collect();
        crate::conformance::check_temporal_model(
            || FftFremen::new(10.0, 5.0, FftFremenConfig::default()).unwrap(),
            &times,
            &values,
        );
    }
}
