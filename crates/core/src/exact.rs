//! Exact, order-independent sums of reals.
//!
//! FreMEn's spectrum is a sum over all observations. Summing in `f64` makes the result
//! depend on the order and grouping of the additions, so a model built on two threads, or
//! from two merged halves, would differ in its last bits from one built sequentially.
//! [`ExactSum`] instead rounds each term once to a fixed-point grid of `2^-50` and adds
//! integers: the sum is then *exactly* the same whatever the order, chunking or
//! parallelism, and two models can be merged by adding their sums.
//!
//! The price is an absolute rounding of at most `2^-51 ≈ 4.4e-16` per term (less than the
//! rounding of an `f64` addition of terms near 1) and terms must satisfy `|x| < 2`.

use serde::{Deserialize, Serialize};

/// Resolution of the fixed-point grid: terms are multiples of `1 / SCALE`.
pub const SCALE: f64 = (1u64 << 50) as f64;
const MAGIC: f64 = 6_755_399_441_055_744.0; // 1.5 * 2^52

/// Rounds `x` (with `|x| < 2`) to the nearest multiple of `2^-50`, as an integer count.
///
/// Uses the "magic number" trick: adding `1.5·2^52` to `x·2^50` forces rounding to an
/// integer, whose value can be read from the bits. It is branch-free and vectorises.
#[inline(always)]
pub fn quantize(x: f64) -> i64 {
    ((x * SCALE + MAGIC).to_bits() as i64) - (MAGIC.to_bits() as i64)
}

/// A real number kept as an exact multiple of `2^-50` (see the [module docs](self)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct ExactSum(i128);

impl ExactSum {
    /// The sum from its integer count of `2^-50` units.
    pub const fn from_units(units: i128) -> Self {
        ExactSum(units)
    }

    /// The integer count of `2^-50` units.
    pub const fn units(self) -> i128 {
        self.0
    }

    /// Adds one term (`|x| < 2`).
    #[inline]
    pub fn add(&mut self, x: f64) {
        self.0 += i128::from(quantize(x));
    }

    /// Adds a sum of already quantized terms.
    #[inline]
    pub fn add_quantized(&mut self, q: i64) {
        self.0 += i128::from(q);
    }

    /// Adds another exact sum.
    #[inline]
    pub fn add_sum(&mut self, other: ExactSum) {
        self.0 += other.0;
    }

    /// The sum as the nearest `f64`.
    #[inline]
    pub fn to_f64(self) -> f64 {
        self.0 as f64 / SCALE
    }

    /// Whether this can be a sum of `count` terms in `[-1, 1]` (`[0, 1]` if `nonnegative`):
    /// the bound a sum read from a file must keep (each term rounds to at most `2^50` units).
    pub fn fits_terms(self, count: u64, nonnegative: bool) -> bool {
        self.0.unsigned_abs() <= u128::from(count) << 50 && (!nonnegative || self.0 >= 0)
    }
}

impl std::ops::Add for ExactSum {
    type Output = ExactSum;
    fn add(self, rhs: ExactSum) -> ExactSum {
        ExactSum(self.0 + rhs.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantize_rounds_to_nearest_grid_point() {
        assert_eq!(quantize(0.0), 0);
        assert_eq!(quantize(1.0), 1 << 50);
        assert_eq!(quantize(-1.0), -(1 << 50));
        assert_eq!(quantize(0.5), 1 << 49);
        let tiny = 1.0 / SCALE;
        assert_eq!(quantize(3.4 * tiny), 3);
        assert_eq!(quantize(-3.6 * tiny), -4);
        assert_eq!(quantize(1.999_999), (1.999_999 * SCALE).round() as i64);
    }

    #[test]
    fn sums_do_not_depend_on_order() {
        let xs: Vec<f64> = (0..1000).map(|i| ((i as f64) * 0.7).sin()).collect();
        let mut forward = ExactSum::default();
        xs.iter().for_each(|&x| forward.add(x));
        let mut backward = ExactSum::default();
        xs.iter().rev().for_each(|&x| backward.add(x));
        assert_eq!(forward, backward);
        let naive: f64 = xs.iter().sum();
        assert!((forward.to_f64() - naive).abs() < 1e-12);
    }
}
