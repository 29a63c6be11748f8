//! One conformance checker for every [`TemporalModel`] (after RustFFT's
//! `check_fft_algorithm`): every implementation in this workspace runs through it, and
//! implementations outside it can too.

use crate::model::{TemporalModel, binary_entropy};

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
