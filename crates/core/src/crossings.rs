//! Where a smooth prediction crosses a threshold, without evaluating it everywhere.
//!
//! A FreMEn prediction `p(t)` is a sum of a few cosines, so its rate of change is bounded
//! (`|p'| ≤ Σ 2A_k ω_k`). Between two positions whose values lie on the same side of the
//! threshold by more than the largest possible variation in between, the indicator
//! `p ≥ c` cannot change; elsewhere the interval is bisected, down to single positions. The
//! result is exactly the set of changes of the point-wise test `f(n) ≥ 0` — computed with the
//! caller's own evaluation function, so that reconstructions using it agree bit for bit — at
//! a cost that follows the number of crossings instead of the number of positions.

/// Margin by which an interval must clear the threshold to be skipped (covers the rounding of
/// the caller's evaluation).
pub const MARGIN: f64 = 1e-9;

/// Intervals this short are evaluated position by position.
const LEAF: u64 = 16;

/// Positions `n ∈ [lo, hi)` where the indicator `f(n) ≥ 0` changes, with the indicator taken
/// as 0 before `lo` (so `lo` itself is listed if `f(lo) ≥ 0`).
///
/// `variation(a, b)` must bound `|f(x) − f(y)|` for all real `x, y ∈ [a, b]` in the model behind
/// `f` (e.g. `L·(b − a)` for a Lipschitz constant `L` per position).
pub fn threshold_toggles(
    lo: u64,
    hi: u64,
    f: &impl Fn(u64) -> f64,
    variation: &impl Fn(u64, u64) -> f64,
) -> Vec<u64> {
    let mut out = Vec::new();
    if hi <= lo {
        return out;
    }
    let f_lo = f(lo);
    if f_lo >= 0.0 {
        out.push(lo);
    }
    let last = hi - 1;
    if last > lo {
        scan((lo, f_lo), (last, f(last)), f, variation, &mut out);
    }
    out
}

/// Appends the changes in `(a, b]`, knowing `f` at both ends.
fn scan(
    (a, fa): (u64, f64),
    (b, fb): (u64, f64),
    f: &impl Fn(u64) -> f64,
    variation: &impl Fn(u64, u64) -> f64,
    out: &mut Vec<u64>,
) {
    if b - a <= LEAF {
        let mut previous = fa >= 0.0;
        for n in a + 1..=b {
            let on = if n == b { fb } else { f(n) } >= 0.0;
            if on != previous {
                out.push(n);
            }
            previous = on;
        }
        return;
    }
    // Same side at both ends, and the function cannot travel to the threshold and back within
    // the interval: min over [a, b] >= (|fa| + |fb| − variation) / 2 > MARGIN.
    if (fa >= 0.0) == (fb >= 0.0) && (fa + fb).abs() - variation(a, b) > 2.0 * MARGIN {
        return;
    }
    let m = a + (b - a) / 2;
    let fm = f(m);
    scan((a, fa), (m, fm), f, variation, out);
    scan((m, fm), (b, fb), f, variation, out);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_every_crossing_of_a_sum_of_cosines() {
        let f = |n: u64| {
            let x = n as f64 / 10_000.0 * std::f64::consts::TAU;
            0.3 + 0.25 * (3.0 * x).cos() + 0.1 * (17.0 * x + 1.0).cos() - 0.5
        };
        let lipschitz = std::f64::consts::TAU / 10_000.0 * (0.25 * 3.0 + 0.1 * 17.0);
        let toggles = threshold_toggles(0, 10_000, &f, &|a, b| lipschitz * (b - a) as f64);
        let brute: Vec<u64> = (0..10_000)
            .filter(|&n| (f(n) >= 0.0) != (n > 0 && f(n - 1) >= 0.0))
            .collect();
        assert_eq!(toggles, brute);
        assert!(!toggles.is_empty());
        // A constant never crosses; one above the threshold is on from the start.
        assert!(threshold_toggles(5, 100, &|_| -0.2, &|_, _| 0.0).is_empty());
        assert_eq!(threshold_toggles(5, 100, &|_| 0.2, &|_, _| 0.0), vec![5]);
        assert!(threshold_toggles(5, 5, &|_| 0.2, &|_, _| 0.0).is_empty());
    }
}
