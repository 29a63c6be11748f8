//! Naive reference implementations: slow, obviously correct, used as test oracles and as
//! benchmark baselines (like RustFFT's `Dft`).

use std::f64::consts::TAU;

use rustfft::num_complex::Complex64;

use crate::periods::phase_angle;

/// Direct non-uniform DFT of a centred signal: returns the mean `μ` and, for every period
/// `T_k`, `γ_k = (1/n) Σ_i (s_i − μ) e^{-j 2π t_i / T_k}` (two passes, one `sin_cos` per
/// sample and period).
///
/// # Panics
/// If `times` and `values` differ in length or are empty.
pub fn naive_spectrum(times: &[f64], values: &[f64], periods: &[f64]) -> (f64, Vec<Complex64>) {
    assert_eq!(times.len(), values.len());
    assert!(!times.is_empty());
    let n = times.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let gammas = periods
        .iter()
        .map(|&period| {
            let mut acc = Complex64::new(0.0, 0.0);
            for (&t, &s) in times.iter().zip(values) {
                let (sin, cos) = phase_angle(t, period).sin_cos();
                acc += Complex64::new(cos, -sin) * (s - mean);
            }
            acc / n
        })
        .collect();
    (mean, gammas)
}

/// Textbook DFT `X_k = Σ_n x_n e^{-j 2π k n / N}` for `k = 0..bins`, in O(N · bins).
pub fn naive_dft(signal: &[f64], bins: usize) -> Vec<Complex64> {
    let len = signal.len() as u64;
    (0..bins as u64)
        .map(|k| {
            let mut acc = Complex64::new(0.0, 0.0);
            for (n, &x) in signal.iter().enumerate() {
                // Reduce k·n modulo N exactly in integers before forming the angle.
                let angle = TAU * ((k * n as u64) % len) as f64 / len as f64;
                let (sin, cos) = angle.sin_cos();
                acc += Complex64::new(cos, -sin) * x;
            }
            acc
        })
        .collect()
}

/// FreMEn prediction evaluated directly from a spectrum, for oracle comparisons:
/// `p(t) = ς(μ + Σ_{k ∈ chosen} 2|γ_k| cos(ω_k t + arg γ_k))` ([Santos 2017] eq. (4)).
pub fn naive_fremen_predict(
    mean: f64,
    gammas: &[Complex64],
    periods: &[f64],
    chosen: &[usize],
    time: f64,
) -> f64 {
    let mut p = mean;
    for &k in chosen {
        p += 2.0 * gammas[k].norm() * (phase_angle(time, periods[k]) + gammas[k].arg()).cos();
    }
    p.clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dft_of_known_signals() {
        // x = [1, 2, 3, 4]: X0 = 10, X1 = -2 + 2j, X2 = -2, X3 = -2 - 2j.
        let x = naive_dft(&[1.0, 2.0, 3.0, 4.0], 4);
        let expected = [(10.0, 0.0), (-2.0, 2.0), (-2.0, 0.0), (-2.0, -2.0)];
        for (got, (re, im)) in x.iter().zip(expected) {
            assert!(
                (got.re - re).abs() < 1e-12 && (got.im - im).abs() < 1e-12,
                "{got}"
            );
        }
    }

    #[test]
    fn spectrum_of_a_pure_cosine() {
        // s(t) = 0.5 + 0.25 cos(2π t / 100 + 0.3), sampled uniformly over whole periods:
        // mean 0.5 and γ = (0.25 / 2) e^{j 0.3} at period 100; nothing at period 50.
        let times: Vec<f64> = (0..1000).map(|i| i as f64).collect();
        let values: Vec<f64> = times
            .iter()
            .map(|t| 0.5 + 0.25 * (TAU * t / 100.0 + 0.3).cos())
            .collect();
        let (mean, g) = naive_spectrum(&times, &values, &[100.0, 50.0]);
        assert!((mean - 0.5).abs() < 1e-12);
        assert!((g[0].norm() - 0.125).abs() < 1e-12);
        assert!((g[0].arg() - 0.3).abs() < 1e-12);
        assert!(g[1].norm() < 1e-12);
        // And the prediction reproduces the signal.
        let p = naive_fremen_predict(mean, &g, &[100.0, 50.0], &[0], 1234.5);
        assert!((p - (0.5 + 0.25 * (TAU * 1234.5 / 100.0 + 0.3).cos())).abs() < 1e-12);
    }
}
