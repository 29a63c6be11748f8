//! One conformance checker for every [`TemporalModel`] (after RustFFT's
//! `check_fft_algorithm`): every implementation in this workspace runs through it, and
//! implementations outside it can too; [`check_interval_coverage`] does the same for
//! prediction intervals.

use crate::calibration::Coverage;
use crate::model::{TemporalModel, binary_entropy};

/// Checks that prediction intervals of nominal coverage `nominal` (for example 0.9) hold values
/// drawn from the distribution they claim to describe that often: `intervals[i]` against the
/// fresh draw `draws[i]`, within 4 binomial standard errors ([`Coverage::agrees_with`]).
/// Every interval-producing model in this workspace runs through it on data drawn from a known
/// distribution. Returns the coverage measured.
///
/// # Panics
/// If the coverage disagrees, naming `what`, or with fewer than 1,000 draws (too few to tell
/// 90 % from 88 %).
pub fn check_interval_coverage(
    what: &str,
    nominal: f64,
    intervals: &[(f64, f64)],
    draws: &[f64],
) -> Coverage {
    assert!(
        draws.len() >= 1000,
        "{what}: a coverage check needs at least 1,000 draws"
    );
    let c = Coverage::of(intervals, draws);
    assert_eq!(
        c.samples,
        draws.len(),
        "{what}: non-finite intervals or draws"
    );
    assert!(
        c.agrees_with(nominal, 4.0),
        "{what}: {:.4} of {} draws inside intervals of nominal coverage {nominal} \
         ({} below, {} above)",
        c.coverage,
        c.samples,
        c.below,
        c.above
    );
    c
}

/// Checks the [`TemporalModel`] contract on a model type, panicking with a precise message
/// on the first violation. `make` builds an empty model; `times`/`values` is a valid series
/// of at least 8 observations.
///
/// Checked:
/// 1. an empty model predicts 0.5;
/// 2. observing in one batch, in chunks of every size in `[1, 2, 7, n/3]`, and one by one
///    gives bit-identical predictions and spans;
/// 3. predictions are in `[0, 1]`; `predict_into`/`predict_many` equal `predict` (1e-9);
///    `entropy` equals the binary entropy of `predict`;
/// 4. a rejected batch (NaN time, backwards time, value out of range, length mismatch)
///    leaves the model bit-identical.
///
/// # Panics
/// On any violation.
pub fn check_temporal_model<M, F>(make: F, times: &[f64], values: &[f64])
where
    M: TemporalModel,
    F: Fn() -> M,
{
    assert!(
        times.len() >= 8,
        "conformance needs at least 8 observations"
    );
    let empty = make();
    assert_eq!(empty.predict(times[0]), 0.5, "empty model must predict 0.5");

    let mut batch = make();
    batch.observe(times, values).expect("valid series rejected");
    let last = *times.last().expect("non-empty");
    let span = times[times.len() - 1] - times[0];
    let probes: Vec<f64> = (0..200)
        .map(|i| times[0] + (i as f64 / 100.0) * span.max(1.0))
        .chain([last, last + 1.0, last + 3600.0])
        .collect();
    let reference: Vec<u64> = probes.iter().map(|&t| batch.predict(t).to_bits()).collect();
    // `model` (after `what`) has the one-batch model's span and predicts bit for bit as it
    // does at every probe.
    let same_as_batch = |model: &M, what: &str| {
        assert_eq!(model.span(), batch.span(), "{what}: the span differs");
        for (&t, &bits) in probes.iter().zip(&reference) {
            assert_eq!(
                model.predict(t).to_bits(),
                bits,
                "{what}: predict({t}) = {} but one batch gives {}",
                model.predict(t),
                f64::from_bits(bits)
            );
        }
    };

    for chunk in [1usize, 2, 7, times.len() / 3] {
        let mut chunked = make();
        for (t, v) in times.chunks(chunk).zip(values.chunks(chunk)) {
            chunked.observe(t, v).expect("valid chunk rejected");
        }
        same_as_batch(&chunked, &format!("chunks of {chunk}"));
    }

    let many = batch.predict_many(&probes);
    let even: Vec<f64> = (0..100).map(|i| last + 60.0 * i as f64).collect();
    let even_many = batch.predict_many(&even);
    for (&t, &p) in probes.iter().zip(&many).chain(even.iter().zip(&even_many)) {
        let single = batch.predict(t);
        assert!(
            (0.0..=1.0).contains(&single),
            "predict({t}) = {single} outside [0, 1]"
        );
        assert!(
            (single - p).abs() < 1e-9,
            "predict_many differs at {t}: {p} vs {single}"
        );
        assert_eq!(
            batch.entropy(t),
            binary_entropy(single),
            "entropy inconsistent at {t}"
        );
    }

    let bad_batches: [(&[f64], &[f64]); 4] = [
        (&[f64::NAN], &[0.0]),
        (&[last + 10.0, last - 10.0], &[0.0, 0.0]),
        (&[last + 10.0], &[1.5]),
        (&[last + 10.0, last + 20.0], &[0.0]),
    ];
    for (t, v) in bad_batches {
        let mut model = make();
        model.observe(times, values).expect("valid series rejected");
        assert!(
            model.observe(t, v).is_err(),
            "bad batch {t:?} {v:?} accepted"
        );
        same_as_batch(&model, &format!("after the rejected batch {t:?}"));
    }
}

#[cfg(test)]
mod tests {
    use super::check_interval_coverage;
    use crate::rng::Xoshiro256StarStar;

    fn uniform_draws(n: usize) -> Vec<f64> {
        let mut rng = Xoshiro256StarStar::seed_from_u64(5);
        (0..n).map(|_| rng.next_f64()).collect()
    }

    #[test]
    fn the_central_90_percent_of_a_uniform_law_covers_90_percent_of_its_draws() {
        let draws = uniform_draws(20_000);
        let c = check_interval_coverage("U(0, 1)", 0.9, &vec![(0.05, 0.95); 20_000], &draws);
        assert!((c.coverage - 0.9).abs() < 0.01 && (c.mean_width - 0.9).abs() < 1e-12);
    }

    #[test]
    #[should_panic(expected = "inside intervals of nominal coverage 0.9")]
    fn an_interval_that_claims_more_than_it_holds_fails() {
        let draws = uniform_draws(20_000);
        check_interval_coverage("too narrow", 0.9, &vec![(0.1, 0.9); 20_000], &draws);
    }
}
