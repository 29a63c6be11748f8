//! Numbers from user input turned into counts, and numbers printed in messages.
//!
//! `x as usize` on an `f64` saturates (`inf` becomes `usize::MAX`, NaN becomes 0) and a `+ 1`
//! after it wraps, so a count computed from a flag or a file value goes through [`count_of`]
//! instead: finite, `≥ 0` and within a documented limit, or `None` for the caller to name the
//! flag or field. [`fmt_number`] prints a float in the shortest form that reads back to the
//! same value, with an exponent for very large or very small magnitudes (`1e308`, not a
//! 309-digit decimal).

use std::borrow::Borrow;

/// `value` (already rounded as the caller wants) as a count, if it is finite, `≥ 0` and at
/// most `limit`; `None` otherwise (NaN, infinite, negative or too large).
///
/// ```
/// use chronomap_core::num::count_of;
///
/// assert_eq!(count_of(3.0, 10), Some(3));
/// assert_eq!(count_of(10.0, 10), Some(10));
/// assert_eq!(count_of(11.0, 10), None);
/// assert_eq!(count_of(f64::INFINITY, usize::MAX), None);
/// assert_eq!(count_of(f64::NAN, 10), None);
/// assert_eq!(count_of(-1.0, 10), None);
/// ```
pub fn count_of(value: f64, limit: usize) -> Option<usize> {
    // `limit as f64` may round up (2^64 - 1 becomes 2^64), so also compare after converting.
    if value.is_finite() && value >= 0.0 && value <= limit as f64 {
        let count = value as usize;
        (count <= limit).then_some(count)
    } else {
        None
    }
}

/// `x` in the shortest form that reads back to the same `f64`: as `{}` prints it for
/// magnitudes in `[1e-5, 1e16)` and zero, with an exponent (`{:e}`) otherwise.
///
/// ```
/// use chronomap_core::num::fmt_number;
///
/// assert_eq!(fmt_number(1e308), "1e308");
/// assert_eq!(fmt_number(1.5e-300), "1.5e-300");
/// assert_eq!(fmt_number(120.0), "120");
/// assert_eq!(fmt_number(-0.25), "-0.25");
/// assert_eq!(fmt_number(f64::NAN), "NaN");
/// assert_eq!(fmt_number(&f64::NEG_INFINITY), "-inf");
/// ```
pub fn fmt_number(x: impl Borrow<f64>) -> String {
    let x = *x.borrow();
    let magnitude = x.abs();
    if !x.is_finite() || x == 0.0 || (1e-5..1e16).contains(&magnitude) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// The median of `values`: the middle one, or the mean of the middle two for an even count
/// (NaN for none).
pub fn median(values: &[f64]) -> f64 {
    let mut values = values.to_vec();
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n == 0 {
        f64::NAN
    } else if n.is_multiple_of(2) {
        (values[n / 2 - 1] + values[n / 2]) / 2.0
    } else {
        values[n / 2]
    }
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn median_is_the_middle_value_or_the_mean_of_the_middle_two() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&[7.0]), 7.0);
        assert!(median(&[]).is_nan());
    }
}
