//! Histogram of the most recent cycles: a periodic histogram that forgets, for routines that
//! drift.
//!
//! A [`HistogramModel`](crate::hist::HistogramModel) averages every cycle it has seen, so a door
//! opened less as the weeks go by is predicted at its old rate for ever. A
//! [`RecentHistogram`] averages only the last `cycles` periods (the current one, however far it
//! has got, and the `cycles − 1` before it): a hard window, the simplest of the "forgetting"
//! treatments of concept drift (Gama et al. 2014, "A survey on concept drift adaptation", ACM
//! Computing Surveys 46(4), §3.2: sliding windows of fixed size). Alone it is noisier than the
//! full histogram; as a candidate of `auto`'s stack it lets the rolling origins decide how much
//! of the recent rate to trust.
//!
//! ```
//! use chronomap_core::recent::RecentHistogram;
//! use chronomap_core::{TemporalModel, periods::DAY};
//!
//! // A door open all morning for 20 days, then never: the last 7 days say "closed".
//! let times: Vec<f64> = (0..28 * 24).map(|h| 3600.0 * h as f64).collect();
//! let open: Vec<f64> = times.iter()
//!     .map(|&t| f64::from(u8::from(t < 20.0 * DAY && (t % DAY) < 43_200.0)))
//!     .collect();
//! let mut week = RecentHistogram::new(2, DAY, 7)?;
//! week.observe(&times, &open)?;
//! assert_eq!(week.predict(28.0 * DAY + 3600.0), 0.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Every observation lands in the slot of its cycle (`⌊t / period⌋`), kept as exact sums
//! ([`ExactSum`]): predictions do not depend on how the observations were batched, and the
//! memory is `cycles × bins` whatever the length of the series.

use serde::{Deserialize, Serialize};

use crate::error::{ConfigError, ObservationError};
use crate::exact::ExactSum;
use crate::hist::{MAX_BINS, check_bins_and_period};
use crate::model::TemporalModel;
use crate::observe::ObservedSpan;
use crate::periods::cycle_fraction;

/// Largest `bins × cycles` of a [`RecentHistogram`] (its memory, as a histogram's bins).
pub const MAX_CELLS: usize = MAX_BINS;

/// Most periods a [`RecentHistogram`] remembers (eleven years of days; each costs a slot even
/// before it is observed).
pub const MAX_CYCLES: usize = 4096;

/// One cycle's sums (bins allocated when the cycle is first observed).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Slot {
    /// `⌊t / period⌋` of the observations in this slot; `None` if never used.
    cycle: Option<i64>,
    sums: Vec<ExactSum>,
    counts: Vec<u64>,
    total: ExactSum,
    count: u64,
}

impl Slot {
    fn empty() -> Self {
        Slot {
            cycle: None,
            sums: Vec::new(),
            counts: Vec::new(),
            total: ExactSum::default(),
            count: 0,
        }
    }

    fn is_consistent(&self, index: usize, cycles: usize, bins: usize) -> bool {
        match self.cycle {
            None => self.sums.is_empty() && self.counts.is_empty() && self.count == 0,
            Some(cycle) => {
                cycle.rem_euclid(cycles as i64) as usize == index
                    && self.sums.len() == bins
                    && self.counts.len() == bins
                    && self.counts.iter().try_fold(0u64, |a, &c| a.checked_add(c))
                        == Some(self.count)
                    && self.sums.iter().map(|s| s.units()).sum::<i128>() == self.total.units()
                    && self
                        .sums
                        .iter()
                        .zip(&self.counts)
                        .all(|(s, &c)| s.fits_terms(c, true))
            }
        }
    }
}

/// A periodic histogram of the last `cycles` periods only ([module docs](self)): the
/// prediction at `t` is the mean of the recent observations in the bin of `t mod period`; a
/// bin the window has not seen predicts the window's mean, and before any observation the
/// model predicts 0.5.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RecentHistogram {
    period_secs: f64,
    bins: usize,
    span: ObservedSpan,
    /// `cycles` slots; cycle `c` lives in slot `c mod cycles`.
    slots: Vec<Slot>,
}

impl RecentHistogram {
    /// An empty histogram of `bins` bins over `period_secs` seconds that remembers the last
    /// `cycles` periods.
    ///
    /// # Errors
    /// If `bins` or `cycles` is 0, `cycles` is above [`MAX_CYCLES`], `bins × cycles` is above
    /// [`MAX_CELLS`], or the period is not positive and finite.
    pub fn new(bins: usize, period_secs: f64, cycles: usize) -> Result<Self, ConfigError> {
        check_bins_and_period(bins, period_secs)?;
        if !(1..=MAX_CYCLES).contains(&cycles) || bins.saturating_mul(cycles) > MAX_CELLS {
            return Err(ConfigError::OutOfRange {
                name: "cycles",
                value: cycles.to_string(),
                expected: "1 ..= 4096, with bins × cycles at most 1048576",
            });
        }
        Ok(RecentHistogram {
            period_secs,
            bins,
            span: ObservedSpan::default(),
            slots: vec![Slot::empty(); cycles],
        })
    }

    /// Number of bins.
    pub fn bins(&self) -> usize {
        self.bins
    }

    /// The period in seconds.
    pub fn period_secs(&self) -> f64 {
        self.period_secs
    }

    /// How many periods the model remembers (the current one included).
    pub fn cycles(&self) -> usize {
        self.slots.len()
    }

    /// Bin of a time.
    pub fn bin_of(&self, time: f64) -> usize {
        ((cycle_fraction(time, self.period_secs) * self.bins as f64) as usize).min(self.bins - 1)
    }

    /// The cycle of a time, `⌊t / period⌋` (saturating for absurd times).
    fn cycle_of(&self, time: f64) -> i64 {
        (time / self.period_secs).floor() as i64
    }

    /// The slots of the window: cycles after `latest − cycles`, `latest` the cycle of the last
    /// observation.
    fn window(&self) -> impl Iterator<Item = &Slot> {
        let latest = self.cycle_of(self.span.last);
        let oldest = latest.saturating_sub(self.cycles() as i64 - 1);
        self.slots
            .iter()
            .filter(move |s| s.cycle.is_some_and(|c| c >= oldest && c <= latest))
    }

    /// Per-bin means over the window (`None` for bins the window has not seen).
    pub fn bin_means(&self) -> Vec<Option<f64>> {
        (0..self.bins)
            .map(|bin| {
                let (sum, count) = self
                    .window()
                    .fold((ExactSum::default(), 0u64), |(s, n), w| {
                        (s + w.sums[bin], n + w.counts[bin])
                    });
                (count > 0).then(|| sum.to_f64() / count as f64)
            })
            .collect()
    }

    /// Number of observations in the window.
    pub fn window_count(&self) -> u64 {
        self.window().map(|s| s.count).sum()
    }

    /// Checks internal consistency (for models read from files).
    pub fn is_consistent(&self) -> bool {
        let cycles = self.slots.len();
        let latest = self.cycle_of(self.span.last);
        let counts = self
            .slots
            .iter()
            .try_fold(0u64, |a, s| a.checked_add(s.count));
        (1..=MAX_BINS).contains(&self.bins)
            && (1..=MAX_CYCLES).contains(&cycles)
            && self.bins.saturating_mul(cycles) <= MAX_CELLS
            && self.period_secs.is_finite()
            && self.period_secs > 0.0
            && self.span.is_consistent()
            && counts.is_some_and(|n| n <= self.span.count)
            && self
                .slots
                .iter()
                .enumerate()
                .all(|(i, s)| s.is_consistent(i, cycles, self.bins))
            && (self.span.count == 0
                || self
                    .slots
                    .iter()
                    .all(|s| s.cycle.is_none_or(|c| c <= latest))
                    && self.window_count() > 0)
    }
}

impl TemporalModel for RecentHistogram {
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        self.span.validate(times, values)?;
        let cycles = self.slots.len() as i64;
        for (&t, &v) in times.iter().zip(values) {
            let cycle = self.cycle_of(t);
            let bin = self.bin_of(t);
            let bins = self.bins;
            let slot = &mut self.slots[cycle.rem_euclid(cycles) as usize];
            if slot.cycle != Some(cycle) {
                // Times only grow: a slot holding another cycle holds an older one.
                *slot = Slot {
                    cycle: Some(cycle),
                    sums: vec![ExactSum::default(); bins],
                    counts: vec![0; bins],
                    total: ExactSum::default(),
                    count: 0,
                };
            }
            slot.sums[bin].add(v);
            slot.counts[bin] += 1;
            slot.total.add(v);
            slot.count += 1;
        }
        self.span.extend(times);
        Ok(())
    }

    fn predict(&self, time: f64) -> f64 {
        if self.span.count == 0 {
            return 0.5;
        }
        let bin = self.bin_of(time);
        let (mut sum, mut count) = (ExactSum::default(), 0u64);
        let (mut total, mut all) = (ExactSum::default(), 0u64);
        for slot in self.window() {
            sum.add_sum(slot.sums[bin]);
            count += slot.counts[bin];
            total.add_sum(slot.total);
            all += slot.count;
        }
        match (count, all) {
            (0, 0) => 0.5,
            (0, all) => total.to_f64() / all as f64,
            (count, _) => sum.to_f64() / count as f64,
        }
    }

    fn span(&self) -> ObservedSpan {
        self.span
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conformance::check_temporal_model;
    use crate::hist::HistogramModel;
    use crate::periods::{DAY, WEEK};

    #[test]
    fn only_the_last_cycles_are_averaged() {
        // Period 100 s, 2 bins, remember 2 cycles. Cycles 0, 1, 2 with bin 0 seeing 1, 1, 0
        // and bin 1 seeing 0, 1, 1.
        let mut h = RecentHistogram::new(2, 100.0, 2).unwrap();
        h.observe(
            &[10.0, 60.0, 110.0, 160.0, 210.0, 260.0],
            &[1.0, 0.0, 1.0, 1.0, 0.0, 1.0],
        )
        .unwrap();
        // Cycles 1 and 2 only: bin 0 saw 1, 0 → 1/2; bin 1 saw 1, 1 → 1.
        assert_eq!(h.predict(1010.0), 0.5);
        assert_eq!(h.predict(1060.0), 1.0);
        assert_eq!(h.bin_means(), [Some(0.5), Some(1.0)]);
        assert_eq!(h.window_count(), 4);
        // A window as long as the series is the full histogram.
        let mut all = RecentHistogram::new(2, 100.0, 3).unwrap();
        let mut full = HistogramModel::new(2, 100.0).unwrap();
        let times = [10.0, 60.0, 110.0, 160.0, 210.0, 260.0];
        let values = [1.0, 0.0, 1.0, 1.0, 0.0, 1.0];
        all.observe(&times, &values).unwrap();
        full.observe(&times, &values).unwrap();
        for t in [0.0, 55.0, 1234.0] {
            assert_eq!(all.predict(t), full.predict(t));
        }
    }

    #[test]
    fn a_bin_the_window_has_not_seen_predicts_the_windows_mean() {
        let mut h = RecentHistogram::new(4, 100.0, 1).unwrap();
        // Cycle 0 fills bin 2 (forgotten later); cycle 3 sees bins 0 and 1 only.
        h.observe(&[60.0, 300.0, 330.0], &[1.0, 1.0, 0.0]).unwrap();
        assert_eq!(h.predict(60.0), 0.5);
        assert_eq!(h.predict(0.0), 1.0);
        assert_eq!(h.bin_means(), [Some(1.0), Some(0.0), None, None]);
        assert_eq!(RecentHistogram::new(4, 100.0, 1).unwrap().predict(0.0), 0.5);
    }

    #[test]
    fn a_gap_longer_than_the_window_forgets_everything_before_it() {
        let mut h = RecentHistogram::new(1, DAY, 7).unwrap();
        h.observe(&[0.0, DAY], &[1.0, 1.0]).unwrap();
        h.observe(&[30.0 * DAY], &[0.0]).unwrap();
        assert_eq!(h.predict(31.0 * DAY), 0.0);
        assert_eq!(h.window_count(), 1);
        assert!(h.is_consistent());
    }

    #[test]
    fn keeps_the_temporal_model_contract() {
        let times: Vec<f64> = (0..3000)
            .map(|i| 1_451_865_600.0 + 397.0 * i as f64)
            .collect();
        let values: Vec<f64> = times
            .iter()
            .map(|&t| f64::from(u8::from((t % DAY) < 30_000.0 || (t % WEEK) < 2.0 * DAY)))
            .collect();
        check_temporal_model(
            || RecentHistogram::new(24, DAY, 3).unwrap(),
            &times,
            &values,
        );
        check_temporal_model(
            || RecentHistogram::new(168, WEEK, 1).unwrap(),
            &times,
            &values,
        );
    }

    #[test]
    fn bad_configurations_and_inconsistent_files_are_refused() {
        assert!(RecentHistogram::new(0, DAY, 7).is_err());
        assert!(RecentHistogram::new(24, DAY, 0).is_err());
        assert!(RecentHistogram::new(1 << 20, DAY, 2).is_err());
        assert!(RecentHistogram::new(1, DAY, 4097).is_err());
        assert!(RecentHistogram::new(1, DAY, 4096).is_ok());
        assert!(RecentHistogram::new(24, f64::NAN, 7).is_err());
        assert!(RecentHistogram::new(24, -1.0, 7).is_err());
        let mut h = RecentHistogram::new(2, 100.0, 2).unwrap();
        h.observe(&[10.0, 160.0], &[1.0, 0.0]).unwrap();
        assert!(h.is_consistent());
        let mut moved = h.clone();
        moved.slots.swap(0, 1);
        assert!(!moved.is_consistent());
        let mut lying = h.clone();
        lying.slots[1].count = 7;
        assert!(!lying.is_consistent());
        let mut future = h.clone();
        future.slots[0].cycle = Some(4);
        assert!(!future.is_consistent());
    }
}
