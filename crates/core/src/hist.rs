//! Periodic histogram: the mean state in each of N bins of a period.

use serde::{Deserialize, Serialize};

use crate::error::{ConfigError, ObservationError};
use crate::exact::ExactSum;
use crate::model::TemporalModel;
use crate::observe::ObservedSpan;
use crate::periods::{WEEK, cycle_fraction};

/// Largest number of bins a histogram may have.
pub const MAX_BINS: usize = 1 << 20;

/// Periodic histogram (the "Hist"/"Interval" baseline of [Krajník 2019] and the original
/// benchmarks): the period (default one week) is cut into `bins` equal bins and the
/// prediction at `t` is the mean of the observations that fell into the bin of
/// `t mod period`.
///
/// A bin that has never been observed predicts the overall mean (the original code
/// predicted 0.5 there); before any observation the model predicts 0.5.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HistogramModel {
    period_secs: f64,
    span: ObservedSpan,
    total: ExactSum,
    sums: Vec<ExactSum>,
    counts: Vec<u64>,
}

/// Checks a periodic histogram's bins (1..=[`MAX_BINS`]) and period (positive and finite).
pub(crate) fn check_bins_and_period(bins: usize, period_secs: f64) -> Result<(), ConfigError> {
    if bins == 0 || bins > MAX_BINS {
        return Err(ConfigError::OutOfRange {
            name: "bins",
            value: bins.to_string(),
            expected: "1 ..= 1048576",
        });
    }
    if !(period_secs.is_finite() && period_secs > 0.0) {
        return Err(ConfigError::PeriodNotPositive { period_secs });
    }
    Ok(())
}

impl HistogramModel {
    /// An empty histogram of `bins` bins over `period_secs` seconds.
    ///
    /// # Errors
    /// If `bins` is 0 or above [`MAX_BINS`], or the period is not positive and finite.
    pub fn new(bins: usize, period_secs: f64) -> Result<Self, ConfigError> {
        check_bins_and_period(bins, period_secs)?;
        Ok(HistogramModel {
            period_secs,
            span: ObservedSpan::default(),
            total: ExactSum::default(),
            sums: vec![ExactSum::default(); bins],
            counts: vec![0; bins],
        })
    }

    /// `bins` bins over one week.
    ///
    /// # Errors
    /// As [`HistogramModel::new`].
    pub fn weekly(bins: usize) -> Result<Self, ConfigError> {
        HistogramModel::new(bins, WEEK)
    }

    /// Number of bins.
    pub fn bins(&self) -> usize {
        self.counts.len()
    }

    /// The period in seconds.
    pub fn period_secs(&self) -> f64 {
        self.period_secs
    }

    /// Bin of a time.
    pub fn bin_of(&self, time: f64) -> usize {
        let bins = self.bins();
        ((cycle_fraction(time, self.period_secs) * bins as f64) as usize).min(bins - 1)
    }

    /// Per-bin means (`None` for bins never observed).
    pub fn bin_means(&self) -> Vec<Option<f64>> {
        self.sums
            .iter()
            .zip(&self.counts)
            .map(|(s, &c)| (c > 0).then(|| s.to_f64() / c as f64))
            .collect()
    }

    /// Number of observations per bin.
    pub fn bin_counts(&self) -> &[u64] {
        &self.counts
    }

    /// Checks internal consistency (for models read from files).
    pub fn is_consistent(&self) -> bool {
        !self.counts.is_empty()
            && self.counts.len() <= MAX_BINS
            && self.sums.len() == self.counts.len()
            && self.period_secs.is_finite()
            && self.period_secs > 0.0
            && self.counts.iter().try_fold(0u64, |a, &c| a.checked_add(c)) == Some(self.span.count)
            && self.span.is_consistent()
            && self
                .sums
                .iter()
                .zip(&self.counts)
                .all(|(s, &c)| s.fits_terms(c, true))
            && self.sums.iter().map(|s| s.units()).sum::<i128>() == self.total.units()
    }
}

impl TemporalModel for HistogramModel {
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        self.span.validate(times, values)?;
        for (&t, &v) in times.iter().zip(values) {
            let bin = self.bin_of(t);
            self.sums[bin].add(v);
            self.counts[bin] += 1;
            self.total.add(v);
        }
        self.span.extend(times);
        Ok(())
    }

    fn predict(&self, time: f64) -> f64 {
        let bin = self.bin_of(time);
        match self.counts[bin] {
            0 if self.span.count == 0 => 0.5,
            0 => self.total.to_f64() / self.span.count as f64,
            count => self.sums[bin].to_f64() / count as f64,
        }
    }

    fn span(&self) -> ObservedSpan {
        self.span
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_average_their_observations() {
        let mut h = HistogramModel::new(4, 100.0).unwrap();
        // Bin 0 = [0,25), bin 1 = [25,50), ...
        h.observe(&[0.0, 10.0, 30.0, 110.0, 130.0], &[1.0, 0.0, 1.0, 1.0, 1.0])
            .unwrap();
        // Bin 0 saw 1, 0, 1 (t = 0, 10, 110) → 2/3; bin 1 saw 1, 1 → 1.
        assert!((h.predict(205.0) - 2.0 / 3.0).abs() < 1e-15);
        assert_eq!(h.predict(40.0), 1.0);
        // Unobserved bin predicts the overall mean 4/5.
        assert!((h.predict(60.0) - 0.8).abs() < 1e-15);
        assert!(HistogramModel::new(0, 100.0).is_err());
        assert!(HistogramModel::new(3, f64::NAN).is_err());
    }
}
