//! The experiment of [Krajník 2019] §V-D: fit every model on the training days, count the test
//! events on a spatio-temporal grid, and compare each model's expected counts with them.

use rayon::prelude::*;

use chronomap_core::Parallelism;
use chronomap_core::metrics::{mse, paired_t_test};
use chronomap_core::progress::{NoProgress, Progress};

use super::baselines::{CellFremen, CellHistogram, GlobalMean, StaticMap};
use super::training::{EventError, Holdout, TrainingData, check_events};
use super::{Event, EventGrid, EventIntensity, SpatialGrid};

/// What [`EventModelBuilder::build`] gives: a fitted model, or why it could not be fitted.
pub type Built = Result<Box<dyn EventIntensity>, EventError>;

/// Fits one kind of event model; the experiment calls it once per cell size and bin length.
///
/// This is the extension point of the experiment: a new model (such as the Warped Hypertime
/// event model) is one more builder in the list given to [`run_experiment`]. A builder may
/// choose parameters, but only on the training data (e.g. on [`TrainingData::holdout`]),
/// never on the test events, which it does not see.
pub trait EventModelBuilder: Send + Sync {
    /// The family (`"static"`, `"hist"`, ...); the fitted model's
    /// [`name`](EventIntensity::name) says which parameters were chosen.
    fn family(&self) -> String;

    /// A model fitted on `train` for cells of `space` and bins of `bin_secs`.
    ///
    /// # Errors
    /// If the model cannot be fitted.
    fn build(&self, train: &TrainingData<'_>, space: SpatialGrid, bin_secs: f64) -> Built;
}

/// Builds [`StaticMap`]s.
#[derive(Clone, Copy, Debug, Default)]
pub struct StaticBuilder;

impl EventModelBuilder for StaticBuilder {
    fn family(&self) -> String {
        "static".into()
    }

    fn build(&self, train: &TrainingData<'_>, space: SpatialGrid, _bin_secs: f64) -> Built {
        Ok(Box::new(StaticMap::fit(train, space)))
    }
}

/// Builds [`GlobalMean`]s.
#[derive(Clone, Copy, Debug, Default)]
pub struct GlobalMeanBuilder;

impl EventModelBuilder for GlobalMeanBuilder {
    fn family(&self) -> String {
        "mean".into()
    }

    fn build(&self, train: &TrainingData<'_>, space: SpatialGrid, _bin_secs: f64) -> Built {
        Ok(Box::new(GlobalMean::fit(train, space)))
    }
}

/// Builds [`CellHistogram`]s, choosing the intervals per day among `candidates` on the
/// chronological hold-out of the training data.
#[derive(Clone, Debug)]
pub struct HistogramBuilder {
    /// Candidate numbers of intervals per day, simplest first (ties go to the earlier one).
    pub candidates: Vec<usize>,
}

impl Default for HistogramBuilder {
    /// 1, 2, 3, 4, 6, 8, 12, 24, 48 and 96 intervals per day (24 h down to 15 min).
    fn default() -> Self {
        HistogramBuilder {
            candidates: vec![1, 2, 3, 4, 6, 8, 12, 24, 48, 96],
        }
    }
}

impl EventModelBuilder for HistogramBuilder {
    fn family(&self) -> String {
        "hist".into()
    }

    fn build(&self, train: &TrainingData<'_>, space: SpatialGrid, bin_secs: f64) -> Built {
        let none = ("histogram candidates", "at least one number of intervals");
        let chosen = choose_on_holdout(train, space, bin_secs, &self.candidates, none, |h, n| {
            Ok(holdout_error(h, &CellHistogram::fit(&h.fit, space, n)?))
        })?;
        Ok(Box::new(CellHistogram::fit(train, space, chosen)?))
    }
}

/// Builds [`CellFremen`]s, choosing the order among `orders` on the chronological hold-out
/// of the training data.
#[derive(Clone, Debug)]
pub struct FremenBuilder {
    /// Candidate orders, simplest first (ties go to the earlier one).
    pub orders: Vec<usize>,
}

impl Default for FremenBuilder {
    /// Orders 0..=6.
    fn default() -> Self {
        FremenBuilder {
            orders: (0..=6).collect(),
        }
    }
}

impl EventModelBuilder for FremenBuilder {
    fn family(&self) -> String {
        "fremen".into()
    }

    fn build(&self, train: &TrainingData<'_>, space: SpatialGrid, bin_secs: f64) -> Built {
        // One fit of the hold-out's first part: the orders share its spectra.
        let mut fitted: Option<CellFremen> = None;
        let none = ("FreMEn orders", "at least one order");
        let chosen = choose_on_holdout(train, space, bin_secs, &self.orders, none, |h, order| {
            if fitted.is_none() {
                fitted = Some(CellFremen::fit(&h.fit, space, bin_secs, self.orders[0])?);
            }
            let model = fitted.as_mut().expect("fitted above");
            model.set_order(order);
            Ok(holdout_error(h, model))
        })?;
        Ok(Box::new(CellFremen::fit(train, space, bin_secs, chosen)?))
    }
}

/// The baselines in the order of the tables: static map, global mean, `Hist_n`, FreMEn.
pub fn default_builders() -> Vec<Box<dyn EventModelBuilder>> {
    vec![
        Box::new(StaticBuilder),
        Box::new(GlobalMeanBuilder),
        Box::new(HistogramBuilder::default()),
        Box::new(FremenBuilder::default()),
    ]
}

/// The candidate of least [`holdout_error`] (`error(holdout, candidate)`) on the
/// chronological hold-out of `train`, or the first candidate without a hold-out. `none` names
/// the candidates and what they need for the error of an empty list.
fn choose_on_holdout(
    train: &TrainingData<'_>,
    space: SpatialGrid,
    bin_secs: f64,
    candidates: &[usize],
    none: (&'static str, &'static str),
    mut error: impl FnMut(&Holdout<'_>, usize) -> Result<f64, EventError>,
) -> Result<usize, EventError> {
    let &first = candidates.first().ok_or(EventError::OutOfRange {
        name: none.0,
        value: 0.0,
        expected: none.1,
    })?;
    let Some(h) = train.holdout(space, bin_secs) else {
        return Ok(first);
    };
    let mut errors = Vec::with_capacity(candidates.len());
    for &candidate in candidates {
        errors.push(error(&h, candidate)?);
    }
    Ok(candidates[argmin(&errors)])
}

/// Mean squared error per cell of `model` on the held-out counts.
fn holdout_error(h: &Holdout<'_>, model: &dyn EventIntensity) -> f64 {
    let counts = h.validation_grid.count(h.validation_events);
    mse(&model.expected_counts(&h.validation_grid), &counts)
}

/// Index of the smallest error; the first one among equals (errors within 1e-12 relative).
fn argmin(errors: &[f64]) -> usize {
    let mut best = 0;
    for (i, &e) in errors.iter().enumerate() {
        if e < errors[best] * (1.0 - 1e-12) {
            best = i;
        }
    }
    best
}

/// The score of one model for one cell size and bin length.
#[derive(Clone, Debug, PartialEq)]
pub struct EventScore {
    /// Cell side (m).
    pub cell: f64,
    /// Bin length (s).
    pub bin_secs: f64,
    /// The fitted model's name (with the parameters chosen on the hold-out, e.g. `hist:12`).
    pub model: String,
    /// Mean squared error per cell of the expected counts against the test counts.
    pub mse: f64,
    /// `100 · (1 − mse / mse of the static map)`: how much smaller the error is (in %).
    pub reduction_pct: f64,
    /// Paired t-test of the per-cell squared errors against those of the static map
    /// (`None` with fewer than two cells): its t statistic, negative for smaller errors.
    /// Squared errors equal to the static map's to 1e-9 relative (as FreMEn of order 0 has,
    /// up to rounding) are reported as identical: `t = 0`, `p = 1`, reduction 0.
    pub t: Option<f64>,
    /// Its two-sided p-value.
    pub p_value: Option<f64>,
    /// Test events counted on the grid.
    pub test_events: usize,
    /// Cells of the grid (`bins × rows × columns`).
    pub cells: usize,
    /// The grid the test was counted on.
    pub grid: EventGrid,
    /// Sum of the model's expected counts over the grid.
    pub predicted_total: f64,
}

/// Runs the experiment: for every cell size in `cells` (m) and bin length in `bins` (s), the
/// test grid is [`EventGrid::covering`] the test events (their bounding box in whole cells,
/// their time span in whole bins aligned to the clock); every builder fits a model on `train`
/// for that grid's cells and bin length, and its expected counts are scored against the test
/// counts. The [`StaticMap`] is always fitted as the reference of the reductions and t-tests.
///
/// Rows come in the order cell size, bin length, builder; the result is deterministic and
/// the same on any threads: the (cell size, bin length) pairs are scored on the threads
/// `parallelism` allows.
///
/// # Errors
/// [`EventError::NoEvents`] if there are no test events, [`EventError::NonFinite`] for a test
/// event that is not finite, [`EventError::OutOfRange`] for a cell size or bin length that is
/// not finite and positive, and any error of a builder.
pub fn run_experiment(
    train: &TrainingData<'_>,
    test: &[Event],
    cells: &[f64],
    bins: &[f64],
    builders: &[Box<dyn EventModelBuilder>],
    parallelism: Parallelism,
) -> Result<Vec<EventScore>, EventError> {
    run_experiment_reporting(train, test, cells, bins, builders, parallelism, &NoProgress)
}

/// [`run_experiment`], reporting one step per (cell size, bin length) to `progress`.
///
/// # Errors
/// As [`run_experiment`].
pub fn run_experiment_reporting(
    train: &TrainingData<'_>,
    test: &[Event],
    cells: &[f64],
    bins: &[f64],
    builders: &[Box<dyn EventModelBuilder>],
    parallelism: Parallelism,
    progress: &dyn Progress,
) -> Result<Vec<EventScore>, EventError> {
    if test.is_empty() {
        return Err(EventError::NoEvents { what: "test" });
    }
    check_events(test, false)?;
    for (name, values) in [("cell size", cells), ("bin length", bins)] {
        if let Some(&bad) = values.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            return Err(EventError::OutOfRange {
                name,
                value: bad,
                expected: "a finite number > 0",
            });
        }
    }
    let configs: Vec<(f64, f64)> = cells
        .iter()
        .flat_map(|&c| bins.iter().map(move |&b| (c, b)))
        .collect();
    progress.stage("scoring event models", configs.len() as u64);
    let score = |&(cell, bin_secs): &(f64, f64)| {
        let scores = score_grid(train, test, cell, bin_secs, builders);
        progress.advance(1);
        scores
    };
    let rows: Result<Vec<Vec<EventScore>>, EventError> = match parallelism {
        Parallelism::Sequential => configs.iter().map(score).collect(),
        Parallelism::Rayon(_) => configs.par_iter().map(score).collect(),
    };
    Ok(rows?.into_iter().flatten().collect())
}

fn score_grid(
    train: &TrainingData<'_>,
    test: &[Event],
    cell: f64,
    bin_secs: f64,
    builders: &[Box<dyn EventModelBuilder>],
) -> Result<Vec<EventScore>, EventError> {
    // Events and sizes were checked; what is left is a cell or bin too small to count.
    let grid = EventGrid::covering(test, cell, bin_secs).ok_or(EventError::OutOfRange {
        name: "cell size or bin length",
        value: cell.min(bin_secs),
        expected: "at most 2^28 cells along an axis and 2^28 bins over the test events",
    })?;
    let counts = grid.count(test);
    let test_events = counts.iter().sum::<f64>() as usize;
    let squared = |predicted: &[f64]| -> Vec<f64> {
        predicted
            .iter()
            .zip(&counts)
            .map(|(p, c)| (p - c) * (p - c))
            .collect()
    };
    let reference = squared(&StaticMap::fit(train, grid.spatial()).expected_counts(&grid));
    let reference_mse = reference.iter().sum::<f64>() / reference.len() as f64;
    let mut rows = Vec::with_capacity(builders.len());
    for builder in builders {
        let model = builder.build(train, grid.spatial(), bin_secs)?;
        let predicted = model.expected_counts(&grid);
        let errors = squared(&predicted);
        let model_mse = errors.iter().sum::<f64>() / errors.len() as f64;
        // A model that predicts what the static map predicts (FreMEn of order 0) differs
        // from it by rounding only; that is no difference, not a "significant" one.
        let same = errors
            .iter()
            .zip(&reference)
            .all(|(a, b)| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1e-9));
        let (t, p_value) = if same {
            (Some(0.0), (errors.len() >= 2).then_some(1.0))
        } else {
            let test = paired_t_test(&errors, &reference);
            (test.map(|t| t.t), test.map(|t| t.p_value))
        };
        rows.push(EventScore {
            cell,
            bin_secs,
            model: model.name(),
            mse: model_mse,
            reduction_pct: if reference_mse > 0.0 && !same {
                100.0 * (1.0 - model_mse / reference_mse)
            } else {
                0.0
            },
            t,
            p_value,
            test_events,
            cells: grid.len(),
            grid,
            predicted_total: predicted.iter().sum(),
        });
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_core::periods::DAY;

    /// Three days with a daily rhythm in one cell (busy 12-14 h, quiet otherwise) and a
    /// constant trickle in another; days 0-1 train, day 2 tests.
    fn days(range: std::ops::Range<u32>) -> Vec<Event> {
        let mut events = Vec::new();
        for d in range {
            for minute in (8 * 60..18 * 60).step_by(5) {
                let t = f64::from(d) * DAY + f64::from(minute) * 60.0;
                let busy = (12 * 60..14 * 60).contains(&minute);
                let n = if busy { 4 } else { 1 };
                for i in 0..n {
                    events.push(Event {
                        t: t + f64::from(i),
                        x: 0.5,
                        y: 0.5,
                    });
                }
                events.push(Event {
                    t: t + 10.0,
                    x: 1.5,
                    y: 0.5,
                });
            }
        }
        events
    }

    #[test]
    fn progress_counts_the_grids_and_changes_nothing() {
        use std::sync::atomic::{AtomicU64, Ordering};
        struct Count(AtomicU64);
        impl Progress for Count {
            fn advance(&self, steps: u64) {
                self.0.fetch_add(steps, Ordering::Relaxed);
            }
        }
        let train_events = days(0..2);
        let test = days(2..3);
        let train = TrainingData::from_events(&train_events, 3600.0).unwrap();
        let count = Count(AtomicU64::new(0));
        let (cells, bins) = ([1.0, 2.0], [900.0, 1800.0, 3600.0]);
        let builders = default_builders();
        let rows = run_experiment_reporting(
            &train,
            &test,
            &cells,
            &bins,
            &builders,
            Parallelism::Sequential,
            &count,
        )
        .unwrap();
        assert_eq!(count.0.load(Ordering::Relaxed), 6);
        assert_eq!(
            rows,
            run_experiment(
                &train,
                &test,
                &cells,
                &bins,
                &builders,
                Parallelism::Rayon(3)
            )
            .unwrap()
        );
    }

    #[test]
    fn temporal_baselines_beat_the_static_map_on_a_daily_rhythm() {
        let train_events = days(0..2);
        let test = days(2..3);
        let train = TrainingData::from_events(&train_events, 3600.0).unwrap();
        let rows = run_experiment(
            &train,
            &test,
            &[1.0],
            &[1800.0],
            &default_builders(),
            Parallelism::Rayon(0),
        )
        .unwrap();
        let names: Vec<&str> = rows.iter().map(|r| r.model.as_str()).collect();
        assert_eq!(names[0], "static");
        assert_eq!(names[1], "mean");
        assert!(
            names[2].starts_with("hist:") && names[2] != "hist:1",
            "{names:?}"
        );
        assert!(
            names[3].starts_with("fremen:") && names[3] != "fremen:0",
            "{names:?}"
        );
        assert_eq!(rows[0].reduction_pct, 0.0);
        assert_eq!(rows[0].p_value, Some(1.0));
        assert_eq!(rows[0].test_events, test.len());
        // 1 row × 2 columns × 20 half-hour bins (08:00-17:55).
        assert_eq!(rows[0].cells, 40);
        // A histogram of the day explains the rhythm almost exactly; FreMEn approximates it.
        assert!(rows[2].reduction_pct > 90.0, "{rows:?}");
        assert!(rows[2].p_value.unwrap() < 0.05);
        assert!(rows[3].reduction_pct > 30.0, "{rows:?}");
        // The global mean is worse than the static map here (the cells differ).
        assert!(rows[1].reduction_pct < 0.0);
        // Deterministic.
        let again = run_experiment(
            &train,
            &test,
            &[1.0],
            &[1800.0],
            &default_builders(),
            Parallelism::Sequential,
        )
        .unwrap();
        let text = |rows: &[EventScore]| format!("{rows:?}");
        assert_eq!(text(&rows), text(&again));
    }

    #[test]
    fn rejects_bad_sizes_and_empty_tests() {
        let train_events = days(0..1);
        let train = TrainingData::from_events(&train_events, 3600.0).unwrap();
        let builders = default_builders();
        assert!(matches!(
            run_experiment(
                &train,
                &[],
                &[1.0],
                &[600.0],
                &builders,
                Parallelism::Rayon(0)
            ),
            Err(EventError::NoEvents { what: "test" })
        ));
        assert!(matches!(
            run_experiment(
                &train,
                &train_events,
                &[0.0],
                &[600.0],
                &builders,
                Parallelism::Rayon(0)
            ),
            Err(EventError::OutOfRange { .. })
        ));
        assert!(matches!(
            run_experiment(
                &train,
                &train_events,
                &[1.0],
                &[f64::NAN],
                &builders,
                Parallelism::Rayon(0)
            ),
            Err(EventError::OutOfRange { .. })
        ));
    }
}
