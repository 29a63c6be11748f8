//! Exact incremental spectra of irregularly sampled states over a fixed set of periods.
//!
//! This is the non-uniform Fourier transform of FreMEn ([Krajník 2017] eq. (11), [Santos 2017]
//! eq. (3)), kept in the form that removes the mean *exactly*: instead of the running
//! update `γ_k ← (n γ_k + (s − γ_0) e^{-jω_k t}) / (n+1)`, which centres every term on the
//! mean known at the time it arrived, we keep
//!
//! * `n`, `Σ s`,
//! * `S_k = Σ s · e^{-jω_k t}` and `E_k = Σ e^{-jω_k t}` for every candidate `ω_k`,
//!
//! and compute `γ_k = (S_k − μ E_k) / n` with the final mean `μ = Σ s / n` when asked. This
//! equals `(1/n) Σ (s − μ) e^{-jω_k t}`, the spectrum of the centred signal, whatever the
//! order or grouping of the observations. All sums are [`ExactSum`]s, so the accumulators
//! are bit-identical for any chunking, any parallel split and any merge order.
//!
//! For harmonic period sets (`base/k`) the phasors `e^{-jkθ}` come from one `sin_cos` per
//! sample and a complex-multiplication recurrence, re-anchored on an exactly computed
//! phase every 64 harmonics so that rounding cannot drift.

use std::f64::consts::TAU;

use rayon::prelude::*;
use rustfft::num_complex::Complex64;
use serde::{Deserialize, Serialize};

use crate::exact::{ExactSum, quantize};
use crate::par::Parallelism;
use crate::periods::{PeriodSet, cycle_fraction};

/// Samples processed together by the accumulation kernels.
const BLOCK: usize = 64;
/// Harmonics between exact re-anchorings of the phasor recurrence.
const ANCHOR: usize = 64;

/// The four exact sums kept per candidate period.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PeriodSums {
    /// `Re Σ s e^{-jωt} = Σ s cos ωt`.
    pub weighted_re: ExactSum,
    /// `Im Σ s e^{-jωt} = −Σ s sin ωt`.
    pub weighted_im: ExactSum,
    /// `Re Σ e^{-jωt}`.
    pub unweighted_re: ExactSum,
    /// `Im Σ e^{-jωt}`.
    pub unweighted_im: ExactSum,
}

impl PeriodSums {
    fn add_block(&mut self, acc: [i64; 4]) {
        self.weighted_re.add_quantized(acc[0]);
        self.weighted_im.add_quantized(acc[1]);
        self.unweighted_re.add_quantized(acc[2]);
        self.unweighted_im.add_quantized(acc[3]);
    }

    fn add_sums(&mut self, other: &PeriodSums) {
        self.weighted_re.add_sum(other.weighted_re);
        self.weighted_im.add_sum(other.weighted_im);
        self.unweighted_re.add_sum(other.unweighted_re);
        self.unweighted_im.add_sum(other.unweighted_im);
    }
}

/// Exact spectral accumulators of one state (see the [module docs](self)).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SpectralSums {
    periods: PeriodSet,
    count: u64,
    sum: ExactSum,
    per_period: Vec<PeriodSums>,
}

impl SpectralSums {
    /// Empty accumulators for the given candidate periods.
    pub fn new(periods: PeriodSet) -> Self {
        let per_period = vec![PeriodSums::default(); periods.len()];
        SpectralSums {
            periods,
            count: 0,
            sum: ExactSum::default(),
            per_period,
        }
    }

    /// The candidate periods.
    pub fn periods(&self) -> &PeriodSet {
        &self.periods
    }

    /// Number of observations added.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Mean of the observed values `μ = Σ s / n` (`None` before any observation).
    pub fn mean(&self) -> Option<f64> {
        (self.count > 0).then(|| self.sum.to_f64() / self.count as f64)
    }

    /// Raw sums per period, in the order of [`SpectralSums::periods`].
    pub fn period_sums(&self) -> &[PeriodSums] {
        &self.per_period
    }

    /// Accumulators assembled from their parts (e.g. by a spatial container that computed them
    /// with shared per-frame phasors, see [`phasors`]). `None` if `per_period` does not have
    /// one entry per period.
    pub fn from_parts(
        periods: PeriodSet,
        count: u64,
        sum: ExactSum,
        per_period: Vec<PeriodSums>,
    ) -> Option<Self> {
        (per_period.len() == periods.len()).then_some(SpectralSums {
            periods,
            count,
            sum,
            per_period,
        })
    }

    /// The exact sum of the observed values `Σ s`.
    pub fn value_sum(&self) -> ExactSum {
        self.sum
    }

    /// Checks invariants (for accumulators read from files): every sum must be one of `count`
    /// terms in range (values in `[0, 1]`, unit phasors).
    pub fn is_consistent(&self) -> bool {
        let n = self.count;
        self.periods.clone().validated().is_ok()
            && self.per_period.len() == self.periods.len()
            && self.sum.fits_terms(n, true)
            && self.per_period.iter().all(|p| {
                [
                    p.weighted_re,
                    p.weighted_im,
                    p.unweighted_re,
                    p.unweighted_im,
                ]
                .iter()
                .all(|s| s.fits_terms(n, false))
            })
    }

    /// Adds observations (values must already satisfy the observation contract: `|s| <= 1`).
    ///
    /// # Panics
    /// If `times` and `values` have different lengths.
    pub fn add(&mut self, times: &[f64], values: &[f64], par: Parallelism) {
        assert_eq!(
            times.len(),
            values.len(),
            "SpectralSums::add: length mismatch"
        );
        let tasks = par.tasks();
        if tasks <= 1 || times.len() < 4 * BLOCK {
            accumulate(&self.periods, times, values, &mut self.per_period);
        } else {
            let chunk = times.len().div_ceil(tasks).next_multiple_of(BLOCK);
            let partials: Vec<Vec<PeriodSums>> = times
                .par_chunks(chunk)
                .zip(values.par_chunks(chunk))
                .map(|(t, v)| {
                    let mut local = vec![PeriodSums::default(); self.periods.len()];
                    accumulate(&self.periods, t, v, &mut local);
                    local
                })
                .collect();
            for partial in &partials {
                for (mine, theirs) in self.per_period.iter_mut().zip(partial) {
                    mine.add_sums(theirs);
                }
            }
        }
        for &v in values {
            self.sum.add(v);
        }
        self.count += times.len() as u64;
    }

    /// Adds the observations summarised by `other` (same period set), as if they had been
    /// observed by `self`. Returns `false`, changing nothing, if the period sets differ.
    pub fn merge(&mut self, other: &SpectralSums) -> bool {
        if self.periods != other.periods {
            return false;
        }
        for (mine, theirs) in self.per_period.iter_mut().zip(&other.per_period) {
            mine.add_sums(theirs);
        }
        self.sum.add_sum(other.sum);
        self.count += other.count;
        true
    }

    /// The centred spectrum `γ_k = (S_k − μ E_k) / n`, one coefficient per candidate period
    /// ([Santos 2017] eq. (3)–(4) with the exact final mean). Empty accumulators give zeros.
    pub fn coefficients(&self) -> Vec<Complex64> {
        let Some(mean) = self.mean() else {
            return vec![Complex64::new(0.0, 0.0); self.per_period.len()];
        };
        let n = self.count as f64;
        self.per_period
            .iter()
            .map(|p| {
                let re = (p.weighted_re.to_f64() - mean * p.unweighted_re.to_f64()) / n;
                let im = (p.weighted_im.to_f64() - mean * p.unweighted_im.to_f64()) / n;
                Complex64::new(re, im)
            })
            .collect()
    }
}

/// Sequential accumulation of all blocks of a batch into `out`.
fn accumulate(periods: &PeriodSet, times: &[f64], values: &[f64], out: &mut [PeriodSums]) {
    for (t, v) in times.chunks(BLOCK).zip(values.chunks(BLOCK)) {
        match periods {
            PeriodSet::Harmonics { base_secs, count } => {
                harmonic_block(*base_secs, *count as usize, t, v, out)
            }
            PeriodSet::List(list) => list_block(list, t, v, out),
        }
    }
}

/// Phasors `e^{-jkθ_i}`, `k = 1..=count`, of up to [`BLOCK`] samples by recurrence.
fn harmonic_block(base: f64, count: usize, t: &[f64], v: &[f64], out: &mut [PeriodSums]) {
    let n = t.len();
    debug_assert!(n <= BLOCK);
    let mut r = [0.0f64; BLOCK];
    let mut zr = [0.0f64; BLOCK];
    let mut zi = [0.0f64; BLOCK];
    let mut s = [0.0f64; BLOCK];
    for i in 0..n {
        r[i] = cycle_fraction(t[i], base);
        let (sin, cos) = (TAU * r[i]).sin_cos();
        zr[i] = cos;
        zi[i] = -sin;
        s[i] = v[i];
    }
    let mut wr = zr;
    let mut wi = zi;
    for (k, sums) in out.iter_mut().enumerate().take(count) {
        if k > 0 {
            if k % ANCHOR == 0 {
                // Re-anchor on the exact phase of harmonic k+1.
                let m = (k + 1) as f64;
                for i in 0..n {
                    let (sin, cos) = (TAU * (m * r[i]).fract()).sin_cos();
                    wr[i] = cos;
                    wi[i] = -sin;
                }
            } else {
                rotate_block(&mut wr, &mut wi, &zr, &zi);
            }
        }
        sums.add_block(block_sums(&s[..n], &wr[..n], &wi[..n]));
    }
}

/// The phasors `e^{-jω_k t}` of one time for every candidate period, written to `re`/`im`.
///
/// The arithmetic is exactly that of the accumulation kernels of [`SpectralSums::add`]
/// (same reductions, same recurrence, same re-anchoring), so sums of
/// [`quantize`]d phasors built from these values are bit-identical to the
/// accumulators of a [`SpectralSums`] fed the same times. Spatial containers use this to
/// share one set of phasors per frame among many cells.
///
/// # Panics
/// If `re` or `im` is shorter than the period set.
pub fn phasors(periods: &PeriodSet, time: f64, re: &mut [f64], im: &mut [f64]) {
    match periods {
        PeriodSet::Harmonics { base_secs, count } => {
            let count = *count as usize;
            let r = cycle_fraction(time, *base_secs);
            let (sin, cos) = (TAU * r).sin_cos();
            let (zr, zi) = (cos, -sin);
            let (mut wr, mut wi) = (zr, zi);
            for k in 0..count {
                if k > 0 {
                    if k % ANCHOR == 0 {
                        let m = (k + 1) as f64;
                        let (sin, cos) = (TAU * (m * r).fract()).sin_cos();
                        wr = cos;
                        wi = -sin;
                    } else {
                        let next_re = wr * zr - wi * zi;
                        let next_im = wr * zi + wi * zr;
                        wr = next_re;
                        wi = next_im;
                    }
                }
                re[k] = wr;
                im[k] = wi;
            }
        }
        PeriodSet::List(list) => {
            for (k, &period) in list.iter().enumerate() {
                let (sin, cos) = (TAU * cycle_fraction(time, period)).sin_cos();
                re[k] = cos;
                im[k] = -sin;
            }
        }
    }
}

/// `w ← w·z` element-wise for a block of complex numbers in split (re, im) form: the step of
/// the phasor recurrence `e^{-j(k+1)θ} = e^{-jkθ}·e^{-jθ}`, written so that it vectorises.
#[inline(always)]
pub(crate) fn rotate_block<const B: usize>(
    wr: &mut [f64; B],
    wi: &mut [f64; B],
    zr: &[f64; B],
    zi: &[f64; B],
) {
    for i in 0..B {
        let re = wr[i] * zr[i] - wi[i] * zi[i];
        let im = wr[i] * zi[i] + wi[i] * zr[i];
        wr[i] = re;
        wi[i] = im;
    }
}

/// Phasors of an arbitrary period list, one `sin_cos` per sample and period.
fn list_block(periods: &[f64], t: &[f64], v: &[f64], out: &mut [PeriodSums]) {
    let n = t.len();
    let mut wr = [0.0f64; BLOCK];
    let mut wi = [0.0f64; BLOCK];
    for (&period, sums) in periods.iter().zip(out.iter_mut()) {
        for i in 0..n {
            let (sin, cos) = (TAU * cycle_fraction(t[i], period)).sin_cos();
            wr[i] = cos;
            wi[i] = -sin;
        }
        sums.add_block(block_sums(v, &wr[..n], &wi[..n]));
    }
}

/// Quantized sums `[Σ s·wr, Σ s·wi, Σ wr, Σ wi]` over one block (at most 64 terms of
/// magnitude < 2, so they fit an `i64`).
#[inline(always)]
fn block_sums(s: &[f64], wr: &[f64], wi: &[f64]) -> [i64; 4] {
    let mut acc = [0i64; 4];
    for ((&s, &wr), &wi) in s.iter().zip(wr).zip(wi) {
        acc[0] += quantize(s * wr);
        acc[1] += quantize(s * wi);
        acc[2] += quantize(wr);
        acc[3] += quantize(wi);
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::naive::naive_spectrum;

    fn irregular_series(n: usize) -> (Vec<f64>, Vec<f64>) {
        let mut t = 1_451_865_600.0;
        let mut times = Vec::with_capacity(n);
        let mut values = Vec::with_capacity(n);
        for i in 0..n {
            t += 37.0 + ((i * 7919) % 600) as f64 * 1.37;
            times.push(t);
            let day = cycle_fraction(t, 86_400.0);
            values.push(if (0.3..0.7).contains(&day) ^ (i % 13 == 0) {
                1.0
            } else {
                0.0
            });
        }
        (times, values)
    }

    #[test]
    fn harmonic_recurrence_matches_naive_dft() {
        let (times, values) = irregular_series(5000);
        let periods = PeriodSet::harmonics(604_800.0, 200).unwrap();
        let mut sums = SpectralSums::new(periods.clone());
        sums.add(&times, &values, Parallelism::Sequential);
        let (mean, naive) = naive_spectrum(&times, &values, &periods.periods());
        assert!((sums.mean().unwrap() - mean).abs() < 1e-15);
        // Periods week/k are not exact in binary; at t ≈ 1.45e9 s the oracle's own
        // `t mod T` then carries a phase error of up to ~1e-10 rad (the recurrence, which
        // reduces modulo the exact week, does not).
        for (k, (fast, slow)) in sums.coefficients().iter().zip(&naive).enumerate() {
            assert!((fast - slow).norm() < 1e-10, "period {k}: {fast} vs {slow}");
        }
    }

    #[test]
    fn scalar_phasors_reproduce_the_kernel_bit_for_bit() {
        let (times, values) = irregular_series(300);
        for periods in [
            PeriodSet::harmonics(604_800.0, 200).unwrap(),
            PeriodSet::from_periods(vec![86_400.0, 3_600.0 * 7.3]).unwrap(),
        ] {
            let mut kernel = SpectralSums::new(periods.clone());
            kernel.add(&times, &values, Parallelism::Sequential);
            let k = periods.len();
            let (mut re, mut im) = (vec![0.0; k], vec![0.0; k]);
            let mut scalar = vec![PeriodSums::default(); k];
            for (&t, &s) in times.iter().zip(&values) {
                phasors(&periods, t, &mut re, &mut im);
                for (j, sums) in scalar.iter_mut().enumerate() {
                    sums.add_block([
                        quantize(s * re[j]),
                        quantize(s * im[j]),
                        quantize(re[j]),
                        quantize(im[j]),
                    ]);
                }
            }
            assert_eq!(kernel.period_sums(), &scalar[..]);
        }
    }

    #[test]
    fn list_periods_match_naive_dft() {
        let (times, values) = irregular_series(3000);
        let list = vec![86_400.0, 43_200.0, 604_800.0, 3_600.0 * 7.3];
        let periods = PeriodSet::from_periods(list.clone()).unwrap();
        let mut sums = SpectralSums::new(periods);
        sums.add(&times, &values, Parallelism::Sequential);
        let (_, naive) = naive_spectrum(&times, &values, &list);
        for (fast, slow) in sums.coefficients().iter().zip(&naive) {
            assert!((fast - slow).norm() < 1e-12);
        }
    }

    #[test]
    fn chunked_parallel_and_merged_sums_are_bit_identical() {
        let (times, values) = irregular_series(10_000);
        let periods = PeriodSet::week_harmonics();
        let mut batch = SpectralSums::new(periods.clone());
        batch.add(&times, &values, Parallelism::Sequential);

        let mut chunked = SpectralSums::new(periods.clone());
        for (t, v) in times.chunks(777).zip(values.chunks(777)) {
            chunked.add(t, v, Parallelism::Sequential);
        }
        assert_eq!(batch, chunked);

        let mut parallel = SpectralSums::new(periods.clone());
        parallel.add(&times, &values, Parallelism::Rayon(3));
        assert_eq!(batch, parallel);

        let (a, b) = times.split_at(4321);
        let (va, vb) = values.split_at(4321);
        let mut left = SpectralSums::new(periods.clone());
        left.add(a, va, Parallelism::Sequential);
        let mut right = SpectralSums::new(periods);
        right.add(b, vb, Parallelism::Sequential);
        assert!(right.merge(&left));
        assert_eq!(batch, right);
    }
}
