//! Which features will the robot see? The localisation protocol of [Krajník 2017] §VII (Table I) and
//! [Krajník 2019] §V-B: at every test time, pick the `n` features a model predicts most likely to be
//! visible, and count how many of them are actually visible then.

/// The fraction of picked features that are visible: at every test slot `s`, the `n` features
/// with the highest `predictions[f][s]` (ties: the lower index first) are picked, and the rate
/// is (visible picked) / (picked) over all slots.
///
/// `predictions` and `truth` are `features × slots`; `n` is clamped to the number of features.
///
/// # Panics
/// If the shapes differ or there are no features.
pub fn reobservation_rate(predictions: &[Vec<f64>], truth: &[Vec<f64>], n: usize) -> f64 {
    assert!(!predictions.is_empty(), "no features");
    assert_eq!(predictions.len(), truth.len(), "feature counts differ");
    let slots = truth[0].len();
    for (p, t) in predictions.iter().zip(truth) {
        assert_eq!(p.len(), slots, "slot counts differ");
        assert_eq!(t.len(), slots, "slot counts differ");
    }
    let n = n.clamp(1, predictions.len());
    let mut order: Vec<usize> = (0..predictions.len()).collect();
    let mut seen = 0usize;
    for s in 0..slots {
        order.sort_by(|&a, &b| {
            predictions[b][s]
                .total_cmp(&predictions[a][s])
                .then(a.cmp(&b))
        });
        seen += order[..n].iter().filter(|&&f| truth[f][s] == 1.0).count();
    }
    seen as f64 / (n * slots).max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn picks_the_most_likely_and_counts_the_visible() {
        // Three features, two slots.
        let predictions = vec![vec![0.9, 0.1], vec![0.5, 0.8], vec![0.2, 0.7]];
        let truth = vec![vec![1.0, 0.0], vec![0.0, 1.0], vec![1.0, 0.0]];
        // n = 1: slot 0 picks f0 (visible), slot 1 picks f1 (visible).
        assert_eq!(reobservation_rate(&predictions, &truth, 1), 1.0);
        // n = 2: slot 0 picks f0, f1 (1 of 2), slot 1 picks f1, f2 (1 of 2).
        assert_eq!(reobservation_rate(&predictions, &truth, 2), 0.5);
        // n larger than the features: all of them, 3 of 6 visible.
        assert_eq!(reobservation_rate(&predictions, &truth, 10), 0.5);
        // Ties go to the lower index.
        let flat = vec![vec![0.5], vec![0.5]];
        assert_eq!(reobservation_rate(&flat, &[vec![0.0], vec![1.0]], 1), 0.0);
    }
}
