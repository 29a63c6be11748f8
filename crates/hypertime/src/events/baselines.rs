//! The baselines of the event experiment ([Krajník 2019] §V): a static map, the global mean, a
//! histogram of the time of day per cell (`Hist_n`) and FreMEn per cell.
//!
//! Every model is fitted on [`TrainingData`] for a [`SpatialGrid`] and predicts expected
//! counts for any [`EventGrid`]: a cell of the grid asked for takes the parameters of the
//! model's cell that contains its centre (none: 0 events, except for [`GlobalMean`], which
//! has one rate everywhere). Rates are events per second of observed time, so one model
//! answers for any bin length.

use chronomap_core::fremen::{FremenConfig, FremenModel};
use chronomap_core::model::{Ordered, TemporalModel};
use chronomap_core::periods::{DAY, PeriodSet};

use super::training::{EventError, TrainingData};
use super::{EventGrid, EventIntensity, SpatialGrid};

/// Per-cell rates (events per second) times the bin length, the same in every bin.
fn constant_rates(space: &SpatialGrid, rates: &[f64], grid: &EventGrid) -> Vec<f64> {
    let lookup = space.lookup(&grid.spatial());
    let per_bin: Vec<f64> = lookup
        .iter()
        .map(|cell| cell.map_or(0.0, |c| rates[c] * grid.bin_secs))
        .collect();
    let mut out = Vec::with_capacity(grid.len());
    for _ in 0..grid.nt {
        out.extend_from_slice(&per_bin);
    }
    out
}

/// The static map: every cell's mean rate over the observed training time, the same at every
/// time (the reference of [Krajník 2019] Fig. 5).
#[derive(Clone, Debug, PartialEq)]
pub struct StaticMap {
    space: SpatialGrid,
    rates: Vec<f64>,
}

impl StaticMap {
    /// Rates = observed training events per cell / observed seconds.
    pub fn fit(train: &TrainingData<'_>, space: SpatialGrid) -> StaticMap {
        let secs = train.observed_secs();
        let rates = train.counts(&space).iter().map(|c| c / secs).collect();
        StaticMap { space, rates }
    }

    /// Events per second in every cell of the model's grid (row-major).
    pub fn rates(&self) -> &[f64] {
        &self.rates
    }
}

impl EventIntensity for StaticMap {
    fn name(&self) -> String {
        "static".into()
    }

    fn expected_counts(&self, grid: &EventGrid) -> Vec<f64> {
        constant_rates(&self.space, &self.rates, grid)
    }
}

/// The global mean: one rate for every cell and time (training events in the grid / cells /
/// observed seconds).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlobalMean {
    rate: f64,
}

impl GlobalMean {
    /// The mean rate per cell of `space` over the observed training time.
    pub fn fit(train: &TrainingData<'_>, space: SpatialGrid) -> GlobalMean {
        let total: f64 = train.counts(&space).iter().sum();
        GlobalMean {
            rate: total / (space.len().max(1) as f64 * train.observed_secs()),
        }
    }

    /// Events per second in one cell.
    pub fn rate(&self) -> f64 {
        self.rate
    }
}

impl EventIntensity for GlobalMean {
    fn name(&self) -> String {
        "mean".into()
    }

    fn expected_counts(&self, grid: &EventGrid) -> Vec<f64> {
        vec![self.rate * grid.bin_secs; grid.len()]
    }
}

/// The pieces of `[a, b)` in the `n` equal intervals of the (UTC) day: `(interval, seconds)`.
fn day_pieces(a: f64, b: f64, n: usize, mut visit: impl FnMut(usize, f64)) {
    let length = DAY / n as f64;
    let mut k = (a / length).floor() as i64;
    let mut at = a;
    while at < b {
        let end = (((k + 1) as f64) * length).min(b);
        if end > at {
            visit(k.rem_euclid(n as i64) as usize, end - at);
            at = end;
        }
        k += 1;
    }
}

/// The interval of the day of time `t` (as [`day_pieces`] counts them).
fn interval_of(t: f64, n: usize) -> usize {
    ((t / (DAY / n as f64)).floor() as i64).rem_euclid(n as i64) as usize
}

/// `Hist_n` of [Krajník 2019] §V per cell: the day is cut into `n` equal intervals and every cell
/// has one rate per interval (its events in that interval of every training day / the seconds
/// of that interval observed). An interval never observed takes the cell's static rate.
/// Expected counts integrate the piecewise constant rate over each bin exactly.
#[derive(Clone, Debug, PartialEq)]
pub struct CellHistogram {
    space: SpatialGrid,
    intervals: usize,
    /// `rates[cell * intervals + k]`, events per second.
    rates: Vec<f64>,
}

impl CellHistogram {
    /// Fits `intervals` rates per cell.
    ///
    /// # Errors
    /// [`EventError::OutOfRange`] unless `1 <= intervals <= 86400`.
    pub fn fit(
        train: &TrainingData<'_>,
        space: SpatialGrid,
        intervals: usize,
    ) -> Result<CellHistogram, EventError> {
        if !(1..=86_400).contains(&intervals) {
            return Err(EventError::OutOfRange {
                name: "intervals per day",
                value: intervals as f64,
                expected: "an integer in 1..=86400",
            });
        }
        let mut observed = vec![0.0; intervals];
        for w in train.windows() {
            day_pieces(w.start, w.end, intervals, |k, secs| observed[k] += secs);
        }
        let mut counts = vec![0.0; space.len() * intervals];
        let mut totals = vec![0.0; space.len()];
        for e in train.observed_events() {
            if let Some((r, c)) = space.cell_of(e.x, e.y) {
                let cell = space.index(r, c);
                counts[cell * intervals + interval_of(e.t, intervals)] += 1.0;
                totals[cell] += 1.0;
            }
        }
        let secs = train.observed_secs();
        let mut rates = counts;
        for (cell, row) in rates.chunks_mut(intervals).enumerate() {
            for (k, rate) in row.iter_mut().enumerate() {
                *rate = if observed[k] > 0.0 {
                    *rate / observed[k]
                } else {
                    totals[cell] / secs
                };
            }
        }
        Ok(CellHistogram {
            space,
            intervals,
            rates,
        })
    }

    /// Intervals per day.
    pub fn intervals(&self) -> usize {
        self.intervals
    }
}

impl EventIntensity for CellHistogram {
    fn name(&self) -> String {
        format!("hist:{}", self.intervals)
    }

    fn expected_counts(&self, grid: &EventGrid) -> Vec<f64> {
        let lookup = self.space.lookup(&grid.spatial());
        let n = self.intervals;
        let mut out = Vec::with_capacity(grid.len());
        let mut pieces = Vec::new();
        for bin in 0..grid.nt {
            let a = grid.t0 + bin as f64 * grid.bin_secs;
            pieces.clear();
            day_pieces(a, a + grid.bin_secs, n, |k, secs| pieces.push((k, secs)));
            for cell in &lookup {
                out.push(cell.map_or(0.0, |c| {
                    let rates = &self.rates[c * n..(c + 1) * n];
                    pieces.iter().map(|&(k, secs)| rates[k] * secs).sum()
                }));
            }
        }
        out
    }
}

/// Training bins observed for less than this fraction of their length are not fed to the
/// spectra (their few counts, scaled up, would be noise); they still count in the correction.
const MIN_OBSERVED_FRACTION: f64 = 0.5;

/// One cell of [`CellFremen`]: its FreMEn model of the scaled counts and the training counts.
#[derive(Clone, Debug)]
struct FremenCell {
    /// `None` if no well-observed bin of the cell has an event.
    model: Option<FremenModel>,
    /// The cell's largest count per fully observed bin (values / scale are in `[0, 1]`).
    scale: f64,
    /// Counts per training bin.
    counts: Vec<f64>,
    /// Σ counts / Σ (prediction × observed fraction) over the training bins.
    correction: f64,
    /// Mean count per fully observed bin, used if the model predicts nothing over the
    /// training bins.
    fallback: Option<f64>,
}

impl FremenCell {
    fn raw(&self, t: f64) -> f64 {
        let Some(model) = &self.model else {
            return 0.0;
        };
        let p = model.predict_unsaturated(t) * self.scale;
        if p.is_finite() { p.max(0.0) } else { 0.0 }
    }

    /// Expected count in a training-length bin centred at `t`.
    fn predict(&self, t: f64) -> f64 {
        match self.fallback {
            Some(mean) => mean,
            None => self.raw(t) * self.correction,
        }
    }

    fn correct(&mut self, times: &[f64], fractions: &[f64]) {
        let predicted: f64 = times
            .iter()
            .zip(fractions)
            .map(|(&t, f)| self.raw(t) * f)
            .sum();
        let observed: f64 = self.counts.iter().sum();
        if predicted > 0.0 && predicted.is_finite() {
            self.correction = observed / predicted;
            self.fallback = None;
        } else {
            self.correction = 1.0;
            self.fallback = Some(observed / fractions.iter().sum::<f64>());
        }
    }
}

/// FreMEn per cell ([Krajník 2019] §V-D, as the original `CFremenGrid`): every cell's counts per
/// training bin, scaled into `[0, 1]` by the cell's largest count, are modelled by a
/// [`FremenModel`] over the periods one day / k, k = 1..=24 ([`CellFremen::periods`]: with
/// one or two days of data no longer period can be seen). Predictions are scaled back,
/// clipped at 0 and multiplied per cell by Σ counts / Σ predictions over the training bins,
/// so that each cell's (and the grid's) training total is reproduced.
///
/// The training bins are the bins of `bin_secs` (aligned to multiples of it) that overlap a
/// window of observation. A bin observed for a fraction `f` of its length (the first and
/// last of a day) has its count divided by `f` before it enters the spectrum (bins with
/// `f < 0.5` are left out of it), and its prediction weighs `f` in the correction: the
/// expected count over the observed training time equals the training count. Order 0 is
/// therefore exactly the [`StaticMap`]. A bin of another length than `bin_secs` is predicted
/// at its centre and scaled by the ratio of the lengths.
#[derive(Clone, Debug)]
pub struct CellFremen {
    space: SpatialGrid,
    bin_secs: f64,
    order: usize,
    /// Centres of the training bins.
    times: Vec<f64>,
    /// Observed fraction of every training bin.
    fractions: Vec<f64>,
    cells: Vec<Option<FremenCell>>,
}

impl CellFremen {
    /// The candidate periods: one day / k, k = 1..=24 (24 h down to 1 h).
    pub fn periods() -> PeriodSet {
        PeriodSet::Harmonics {
            base_secs: DAY,
            count: 24,
        }
    }

    /// Fits every cell of `space` on the counts per bin of `bin_secs`, with `order` periodic
    /// components.
    ///
    /// # Errors
    /// [`EventError::OutOfRange`] for a bin length that is not finite and positive.
    pub fn fit(
        train: &TrainingData<'_>,
        space: SpatialGrid,
        bin_secs: f64,
        order: usize,
    ) -> Result<CellFremen, EventError> {
        if !(bin_secs.is_finite() && bin_secs > 0.0) {
            return Err(EventError::OutOfRange {
                name: "bin_secs",
                value: bin_secs,
                expected: "a finite number of seconds > 0",
            });
        }
        // Training bins: every bin overlapping a window, in time order, without repeats.
        let mut bins: Vec<i64> = Vec::new();
        for w in train.windows() {
            let first = (w.start / bin_secs).floor() as i64;
            let last = (w.end / bin_secs).floor() as i64;
            for k in first..=last {
                if bins.last().is_none_or(|&b| b < k) {
                    bins.push(k);
                }
            }
        }
        let times: Vec<f64> = bins.iter().map(|&k| (k as f64 + 0.5) * bin_secs).collect();
        let fractions: Vec<f64> = bins
            .iter()
            .map(|&k| {
                let a = k as f64 * bin_secs;
                (train.observed_between(a, a + bin_secs) / bin_secs).min(1.0)
            })
            .collect();
        let mut counts = vec![Vec::new(); space.len()];
        for e in train.observed_events() {
            let Some((r, c)) = space.cell_of(e.x, e.y) else {
                continue;
            };
            let k = (e.t / bin_secs).floor() as i64;
            let Ok(i) = bins.binary_search(&k) else {
                continue;
            };
            let series = &mut counts[space.index(r, c)];
            if series.is_empty() {
                series.resize(bins.len(), 0.0);
            }
            series[i] += 1.0;
        }
        let config = FremenConfig {
            periods: CellFremen::periods(),
            order,
            min_span_factor: 0.0,
        };
        let used: Vec<usize> = (0..bins.len())
            .filter(|&i| fractions[i] >= MIN_OBSERVED_FRACTION)
            .collect();
        let used_times: Vec<f64> = used.iter().map(|&i| times[i]).collect();
        let cells = counts
            .into_iter()
            .map(|series| {
                if series.is_empty() {
                    return None;
                }
                let values: Vec<f64> = used.iter().map(|&i| series[i] / fractions[i]).collect();
                let scale = values.iter().copied().fold(0.0, f64::max);
                let model = (scale > 0.0).then(|| {
                    let scaled: Vec<f64> = values.iter().map(|v| v / scale).collect();
                    let mut model = FremenModel::new(config.clone()).expect("valid configuration");
                    model
                        .observe(&used_times, &scaled)
                        .expect("bin centres are ordered and scaled counts lie in [0, 1]");
                    model
                });
                let mut cell = FremenCell {
                    model,
                    scale,
                    counts: series,
                    correction: 1.0,
                    fallback: None,
                };
                cell.correct(&times, &fractions);
                Some(cell)
            })
            .collect();
        Ok(CellFremen {
            space,
            bin_secs,
            order,
            times,
            fractions,
            cells,
        })
    }

    /// The number of periodic components per cell.
    pub fn order(&self) -> usize {
        self.order
    }

    /// Changes the order of every cell (no refit of the spectra; corrections are recomputed).
    pub fn set_order(&mut self, order: usize) {
        self.order = order;
        for cell in self.cells.iter_mut().flatten() {
            if let Some(model) = &mut cell.model {
                model.set_order(order);
            }
            cell.correct(&self.times, &self.fractions);
        }
    }

    /// Expected counts in the observed part of every training bin, for every cell
    /// (`bins × cells`, row-major), and the training counts in the same layout: their
    /// per-cell sums are equal.
    pub fn training_fit(&self) -> (Vec<f64>, Vec<f64>) {
        let mut predicted = Vec::with_capacity(self.times.len() * self.cells.len());
        let mut observed = Vec::with_capacity(predicted.capacity());
        for (i, (&t, &f)) in self.times.iter().zip(&self.fractions).enumerate() {
            for cell in &self.cells {
                predicted.push(cell.as_ref().map_or(0.0, |c| c.predict(t) * f));
                observed.push(cell.as_ref().map_or(0.0, |c| c.counts[i]));
            }
        }
        (predicted, observed)
    }
}

impl EventIntensity for CellFremen {
    fn name(&self) -> String {
        format!("fremen:{}", self.order)
    }

    fn expected_counts(&self, grid: &EventGrid) -> Vec<f64> {
        let lookup = self.space.lookup(&grid.spatial());
        let ratio = grid.bin_secs / self.bin_secs;
        let mut out = Vec::with_capacity(grid.len());
        for bin in 0..grid.nt {
            let t = grid.t0 + (bin as f64 + 0.5) * grid.bin_secs;
            for cell in &lookup {
                let cell = cell.and_then(|c| self.cells[c].as_ref());
                out.push(cell.map_or(0.0, |c| c.predict(t) * ratio));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::super::Event;
    use super::super::training::Window;
    use super::*;

    fn ev(t: f64, x: f64, y: f64) -> Event {
        Event { t, x, y }
    }

    /// A 2 × 1 grid of 1-m cells at the origin.
    fn two_cells() -> SpatialGrid {
        SpatialGrid {
            x0: 0.0,
            y0: 0.0,
            cell: 1.0,
            nx: 2,
            ny: 1,
        }
    }

    #[test]
    fn counting_on_a_tiny_grid() {
        // 2 bins of 10 s × 1 row × 2 columns.
        let grid = two_cells().with_bins(100.0, 10.0, 2);
        let events = [
            ev(100.0, 0.5, 0.5),  // bin 0, column 0
            ev(105.0, 0.99, 0.1), // bin 0, column 0
            ev(109.9, 1.0, 0.0),  // bin 0, column 1 (left edge belongs to the cell)
            ev(110.0, 1.5, 0.9),  // bin 1, column 1
            ev(120.0, 0.5, 0.5),  // after the grid: ignored
            ev(105.0, 2.0, 0.5),  // right of the grid: ignored
            ev(105.0, 0.5, -0.1), // below the grid: ignored
        ];
        assert_eq!(grid.count(&events), [2.0, 1.0, 0.0, 1.0]);
        let covering = EventGrid::covering(&events[..4], 1.0, 10.0).unwrap();
        assert_eq!(covering, grid);
    }

    #[test]
    fn static_map_and_global_mean_on_a_hand_made_example() {
        // Observed 0..100 s and 1000..1100 s: 200 s. Column 0 has 4 events, column 1 one;
        // the event at 500 s lies outside both windows and is not observed time.
        let events = [
            ev(0.0, 0.5, 0.5),
            ev(50.0, 0.5, 0.5),
            ev(100.0, 1.5, 0.5),
            ev(500.0, 1.5, 0.5),
            ev(1000.0, 0.5, 0.5),
            ev(1100.0, 0.5, 0.5),
        ];
        let windows = vec![
            Window {
                start: 0.0,
                end: 100.0,
            },
            Window {
                start: 1000.0,
                end: 1100.0,
            },
        ];
        let train = TrainingData::new(&events, windows).unwrap();
        let map = StaticMap::fit(&train, two_cells());
        assert_eq!(map.rates(), [4.0 / 200.0, 1.0 / 200.0]);
        let grid = two_cells().with_bins(5000.0, 50.0, 2);
        assert_eq!(map.expected_counts(&grid), [1.0, 0.25, 1.0, 0.25]);
        // A grid shifted by a quarter cell and wider, with 100-s bins: the centres at x = 0.75
        // and 1.75 take columns 0 and 1, the one at x = 2.75 lies outside the map: nothing.
        let shifted = SpatialGrid {
            x0: 0.25,
            y0: 0.0,
            cell: 1.0,
            nx: 3,
            ny: 1,
        }
        .with_bins(0.0, 100.0, 1);
        assert_eq!(map.expected_counts(&shifted), [2.0, 0.5, 0.0]);
        let mean = GlobalMean::fit(&train, two_cells());
        assert_eq!(mean.rate(), 5.0 / 2.0 / 200.0);
        assert_eq!(mean.expected_counts(&grid), [0.625; 4]);
    }

    #[test]
    fn histogram_rates_per_interval_of_the_day() {
        // Two days observed 06:00..18:00; 4 intervals per day (6 h each). Per day, column 0
        // has events at 07, 08 and 09 h, column 1 at 06 and 17 h.
        let day = |d: f64, h: f64| d * DAY + h * 3600.0;
        let mut events = Vec::new();
        let mut windows = Vec::new();
        for d in [0.0, 1.0] {
            events.push(ev(day(d, 6.0), 1.5, 0.5));
            for h in [7.0, 8.0, 9.0] {
                events.push(ev(day(d, h), 0.5, 0.5));
            }
            events.push(ev(day(d, 17.0), 1.5, 0.5));
            windows.push(Window {
                start: day(d, 6.0),
                end: day(d, 18.0),
            });
        }
        let train = TrainingData::new(&events, windows).unwrap();
        let hist = CellHistogram::fit(&train, two_cells(), 4).unwrap();
        assert_eq!(hist.name(), "hist:4");
        // Column 0: 6 events in 12 observed hours of 06-12, none in 12-18. Column 1: 2 and 2.
        // A 3-hour bin from 10:30 to 13:30 of day 2 has 1.5 h of each interval.
        let grid = two_cells().with_bins(day(2.0, 10.5), 3.0 * 3600.0, 1);
        let counts = hist.expected_counts(&grid);
        assert!((counts[0] - 6.0 / 12.0 * 1.5).abs() < 1e-12, "{counts:?}");
        assert!((counts[1] - (2.0 / 12.0 * 1.5 + 2.0 / 12.0 * 1.5)).abs() < 1e-12);
        // The night interval (00-06) was never observed: the cell's static rate, 6 / 24 h.
        let night = two_cells().with_bins(day(3.0, 1.0), 3600.0, 1);
        assert!((hist.expected_counts(&night)[0] - 6.0 / 24.0).abs() < 1e-12);
        assert!(CellHistogram::fit(&train, two_cells(), 0).is_err());
    }

    /// Two days of a daily rhythm, observed 08:00-18:00 in 10-min bins: the rate in cell 0
    /// follows 3 + 2 cos(2π (t − 13:00) / day) events per bin.
    fn rhythm() -> Vec<Event> {
        let mut events = Vec::new();
        for d in 0..2 {
            for b in 0..60 {
                let t0 = f64::from(d) * DAY + 8.0 * 3600.0 + f64::from(b) * 600.0;
                let phase = std::f64::consts::TAU * (t0 + 300.0 - 13.0 * 3600.0) / DAY;
                let n = (3.0 + 2.0 * phase.cos()).round() as usize;
                for i in 0..n {
                    events.push(ev(t0 + 1.0 + i as f64, 0.5, 0.5));
                }
            }
        }
        // One event in cell 1 at the end keeps the windows' ends at 18:00.
        events.push(ev(8.0 * 3600.0, 1.5, 0.5));
        events.sort_by(|a, b| a.t.total_cmp(&b.t));
        events
    }

    #[test]
    fn fremen_per_cell_recovers_a_daily_rhythm_and_keeps_the_training_total() {
        let events = rhythm();
        let train = TrainingData::from_events(&events, 3.0 * 3600.0).unwrap();
        let model = CellFremen::fit(&train, two_cells(), 600.0, 1).unwrap();
        assert_eq!(model.name(), "fremen:1");
        // The corrections make each cell's predictions over the training bins sum to its count.
        let (predicted, observed) = model.training_fit();
        for cell in 0..2 {
            let p: f64 = predicted.iter().skip(cell).step_by(2).sum();
            let o: f64 = observed.iter().skip(cell).step_by(2).sum();
            assert!((p - o).abs() < 1e-9 * o.max(1.0), "cell {cell}: {p} vs {o}");
        }
        let total: f64 = observed.iter().sum();
        assert_eq!(total, events.len() as f64);
        // The next day in 10-min bins: the truth is 4 events per bin at 08:00 and 17:50
        // (3 + 2 cos(±1.29) = 3.56, rounded) and 5 at 13:00.
        let at = |h: f64| {
            let grid = two_cells().with_bins(2.0 * DAY + h * 3600.0, 600.0, 1);
            model.expected_counts(&grid)[0]
        };
        let noon = at(12.0 + 55.0 / 60.0);
        let morning = at(8.0);
        let evening = at(17.0 + 50.0 / 60.0);
        assert!((morning - 4.0).abs() < 0.5, "{morning}");
        assert!((noon - 5.0).abs() < 0.5, "{noon}");
        assert!((evening - 4.0).abs() < 0.5, "{evening}");
        assert!(noon > morning + 0.5 && noon > evening + 0.5);
        // Order 0 is flat and equals the static map (events per observed second × bin).
        let mut flat = model.clone();
        flat.set_order(0);
        let grid = two_cells().with_bins(0.0, 600.0, 3);
        let static_map = StaticMap::fit(&train, two_cells()).expected_counts(&grid);
        for (f, s) in flat.expected_counts(&grid).iter().zip(&static_map) {
            assert!((f - s).abs() < 1e-9 * s.max(1.0), "{f} vs {s}");
        }
        // Predictions are finite and never negative, at any time and bin length.
        let day3 = two_cells().with_bins(3.0 * DAY, 1800.0, 48);
        assert!(
            model
                .expected_counts(&day3)
                .iter()
                .all(|c| c.is_finite() && *c >= 0.0)
        );
    }
}
