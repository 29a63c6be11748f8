//! Warped Hypertime for events in the plane ([Krajník 2019] §V-D): a Gaussian mixture over
//! `[x, y, cos(2πt/T₁), sin(2πt/T₁), …]`, scaled into an intensity (events per m² per second),
//! with the periodicities found in the error of the predicted number of events over time.
//!
//! The stages are those of [`super`] ([Krajník 2019] §III-B): cluster, estimate the error (eqs. 3–6),
//! find the strongest periodicity of the error series (eq. 7), extend (eq. 8), while the error
//! on the held-back most recent part of the training data falls. The error series is the
//! predicted minus the observed number of events per time bin of the training span; the
//! held-back error is the mean squared error of counts on a grid of
//! [`EventModelConfig::check_cell`] metres × [`EventModelConfig::check_bin_secs`] over the
//! last observed day (or the last quarter of a single day: [`TrainingData::holdout`]).
//!
//! Scaling (eq. 3): the mixture is a density over the warped space, not over time; the factor
//! `c` makes the expected number of events over the training span equal the number observed:
//! `c · ∫ f_φ(φ(t)) dt = N`, with `f_φ` the marginal of the mixture over the hypertime
//! dimensions. The intensity is then `λ(t, x, y) = c · f(x, y, φ(t))`.

use serde::{Deserialize, Serialize};

use super::{Components, check_candidate_periods, out_of_range, project, strongest_period};
use crate::events::{Event, EventGrid, EventIntensity, Holdout, SpatialGrid, TrainingData};
use crate::mixture::{EmConfig, EmInit, GaussianMixture, fit_em_at_most};
use chronomap_core::error::{BuildError, ConfigError};
use chronomap_core::periods::DAY;

/// Settings of [`HypertimeEvents`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EventModelConfig {
    /// Mixture components (`Auto`: chosen on the hold-out among `1..=max_components`).
    pub components: Components,
    /// Most components tried by `Auto`. Default 6.
    pub max_components: usize,
    /// Candidate periods (s). Default: one day divided by `1..=24` (data of a few days cannot
    /// show longer rhythms).
    pub candidate_periods: Vec<f64>,
    /// Most periodicities. Default 4 (as HyT-KM's `number_of_periods`).
    pub max_periods: usize,
    /// Time bin of the error series (s). Default 600.
    pub residual_bin_secs: f64,
    /// Cell side of the hold-out grid (m). Default 1.
    pub check_cell: f64,
    /// Time bin of the hold-out grid (s). Default 1800.
    pub check_bin_secs: f64,
    /// EM starts per fit. Default 2.
    pub starts: usize,
    /// Seed.
    pub seed: u64,
}

impl Default for EventModelConfig {
    fn default() -> Self {
        EventModelConfig {
            components: Components::Auto,
            max_components: 6,
            candidate_periods: (1..=24).map(|k| DAY / f64::from(k)).collect(),
            max_periods: 4,
            residual_bin_secs: 600.0,
            check_cell: 1.0,
            check_bin_secs: 1800.0,
            starts: 2,
            seed: 0,
        }
    }
}

impl EventModelConfig {
    fn validate(&self) -> Result<(), ConfigError> {
        check_candidate_periods(&self.candidate_periods)?;
        if self.components == Components::Fixed(0) || self.max_components == 0 {
            return out_of_range("components", "0".into(), "at least 1");
        }
        for (name, v) in [
            ("residual_bin_secs", self.residual_bin_secs),
            ("check_cell", self.check_cell),
            ("check_bin_secs", self.check_bin_secs),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return out_of_range(name, v.to_string(), "a positive number");
            }
        }
        if self.starts == 0 {
            return out_of_range("starts", "0".into(), "at least 1");
        }
        Ok(())
    }
}

/// A fitted event intensity `λ(t, x, y)` (events per m² per second).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HypertimeEvents {
    periods: Vec<f64>,
    mixture: GaussianMixture,
    /// The mixture over the hypertime dimensions only (`None` without periodicities).
    time_marginal: Option<GaussianMixture>,
    scale: f64,
    name: String,
}

/// Events merged into weighted points `[x, y, hypertime…]` (5 cm, 30 s of the day).
fn merged_points(events: &[Event], periods: &[f64], day_aligned: bool) -> (Vec<f64>, Vec<f64>) {
    let dim = 2 + 2 * periods.len();
    if !day_aligned {
        let mut data = Vec::with_capacity(events.len() * dim);
        for e in events {
            data.push(e.x);
            data.push(e.y);
            project(e.t, periods, &mut data);
        }
        return (data, vec![1.0; events.len()]);
    }
    let mut keys: Vec<(i64, i64, i64)> = events
        .iter()
        .map(|e| {
            (
                (e.x / 0.05).round() as i64,
                (e.y / 0.05).round() as i64,
                (e.t.rem_euclid(DAY) / 30.0).round() as i64,
            )
        })
        .collect();
    keys.sort_unstable();
    let mut data = Vec::new();
    let mut weights: Vec<f64> = Vec::new();
    let mut last = None;
    for key in keys {
        if last == Some(key) {
            *weights.last_mut().expect("non-empty") += 1.0;
            continue;
        }
        last = Some(key);
        data.push(key.0 as f64 * 0.05);
        data.push(key.1 as f64 * 0.05);
        project(key.2 as f64 * 30.0, periods, &mut data);
        weights.push(1.0);
    }
    (data, weights)
}

impl HypertimeEvents {
    /// Fits the intensity to training events observed in `train`'s windows (nights without
    /// observation do not count as time without events).
    ///
    /// # Errors
    /// An invalid configuration, fewer than 10 observed events, or a clustering failure.
    pub fn fit(train: &TrainingData<'_>, config: &EventModelConfig) -> Result<Self, BuildError> {
        config.validate()?;
        let observed: Vec<Event> = train.observed_events().copied().collect();
        if observed.len() < 10 {
            return Err(BuildError::NotEnoughData(format!(
                "{} observed events; at least 10 are needed",
                observed.len()
            )));
        }
        let space = SpatialGrid::covering(&observed, config.check_cell)
            .ok_or_else(|| BuildError::NotEnoughData("no events in the plane".into()))?;
        let chosen = match train.holdout(space, config.check_bin_secs) {
            None => (Vec::new(), 1),
            Some(holdout) => {
                let ks: Vec<usize> = match config.components {
                    Components::Fixed(k) => vec![k],
                    Components::Auto => (1..=config.max_components).collect(),
                };
                let mut best: Option<(f64, Vec<f64>, usize)> = None;
                for k in ks {
                    let (periods, error) = grow(&holdout, k, config)?;
                    if best.as_ref().is_none_or(|b| error < b.0 * (1.0 - 1e-9)) {
                        best = Some((error, periods, k));
                    }
                }
                let (_, periods, k) = best.expect("at least one k");
                (periods, k)
            }
        };
        Self::fit_with(train, &chosen.0, chosen.1, config)
    }

    /// The mixture with `periods` and `k` components, scaled over the observed windows.
    fn fit_with(
        train: &TrainingData<'_>,
        periods: &[f64],
        k: usize,
        config: &EventModelConfig,
    ) -> Result<Self, BuildError> {
        let events: Vec<Event> = train.observed_events().copied().collect();
        let events = &events[..];
        let day_aligned = config.candidate_periods.iter().all(|&p| {
            let n = DAY / p;
            (n - n.round()).abs() < 1e-9
        });
        let (data, weights) = merged_points(events, periods, day_aligned);
        let dim = 2 + 2 * periods.len();
        let em = |k: usize| EmConfig {
            components: k,
            starts: config.starts,
            init: EmInit::KMeansPlusPlus,
            seed: chronomap_core::rng::derive_seed(
                config.seed,
                0x4556,
                periods.len() as u64,
                k as u64,
            ),
            ..EmConfig::default()
        };
        let mixture = fit_em_at_most(&data, dim, Some(&weights), k, em)
            .map_err(|e| BuildError::NotEnoughData(e.to_string()))?
            .mixture;
        let k = mixture.components();
        let time_dims: Vec<usize> = (2..dim).collect();
        let time_marginal = (!periods.is_empty()).then(|| mixture.marginal(&time_dims));
        let mut model = HypertimeEvents {
            periods: periods.to_vec(),
            mixture,
            time_marginal,
            scale: 1.0,
            name: if periods.is_empty() {
                format!("hyt-em:{k}")
            } else {
                let hours: Vec<String> = periods
                    .iter()
                    .map(|p| format!("{}h", (p / 360.0).round() / 10.0))
                    .collect();
                format!("hyt-em:{k}@{}", hours.join(","))
            },
        };
        // Eq. (3): c · ∫ f_φ(φ(t)) dt over the observed time = number of observed events.
        let mut integral = 0.0;
        for w in train.windows() {
            let steps = (w.secs() / 60.0).ceil().max(1.0) as usize;
            let dt = w.secs() / steps as f64;
            integral += (0..steps)
                .map(|i| model.time_density(w.start + (i as f64 + 0.5) * dt) * dt)
                .sum::<f64>();
        }
        if integral > 0.0 && integral.is_finite() {
            model.scale = events.len() as f64 / integral;
        }
        Ok(model)
    }

    /// The periodicities chosen (s).
    pub fn periods(&self) -> &[f64] {
        &self.periods
    }

    /// The mixture over `[x, y, hypertime…]`.
    pub fn mixture(&self) -> &GaussianMixture {
        &self.mixture
    }

    /// `f_φ(φ(t))`: the density of the hypertime dimensions at `t` (1 without periodicities).
    fn time_density(&self, t: f64) -> f64 {
        match &self.time_marginal {
            None => 1.0,
            Some(m) => {
                let mut x = Vec::with_capacity(2 * self.periods.len());
                project(t, &self.periods, &mut x);
                m.log_density(&x).exp()
            }
        }
    }

    /// Expected events per second over the whole plane at `t`.
    pub fn rate(&self, t: f64) -> f64 {
        self.scale * self.time_density(t)
    }

    /// The intensity `λ(t, x, y)`: expected events per m² per second.
    pub fn intensity(&self, t: f64, x: f64, y: f64) -> f64 {
        let mut v = Vec::with_capacity(2 + 2 * self.periods.len());
        v.push(x);
        v.push(y);
        project(t, &self.periods, &mut v);
        self.scale * self.mixture.log_density(&v).exp()
    }
}

/// Quadrature points per cell side and per time bin of [`EventIntensity::expected_counts`].
const QUADRATURE: usize = 3;

impl EventIntensity for HypertimeEvents {
    fn name(&self) -> String {
        self.name.clone()
    }

    /// `∫∫∫ λ` over each cell by the midpoint rule on a 3 × 3 × 3 sub-grid.
    fn expected_counts(&self, grid: &EventGrid) -> Vec<f64> {
        let q = QUADRATURE as f64;
        let mut out = vec![0.0; grid.len()];
        let volume = grid.cell * grid.cell * grid.bin_secs / (q * q * q);
        for b in 0..grid.nt {
            for r in 0..grid.ny {
                for c in 0..grid.nx {
                    let (t0, x0, y0) = (
                        grid.t0 + b as f64 * grid.bin_secs,
                        grid.x0 + c as f64 * grid.cell,
                        grid.y0 + r as f64 * grid.cell,
                    );
                    let mut sum = 0.0;
                    for i in 0..QUADRATURE {
                        let t = t0 + (i as f64 + 0.5) / q * grid.bin_secs;
                        for j in 0..QUADRATURE {
                            let x = x0 + (j as f64 + 0.5) / q * grid.cell;
                            for l in 0..QUADRATURE {
                                let y = y0 + (l as f64 + 0.5) / q * grid.cell;
                                sum += self.intensity(t, x, y);
                            }
                        }
                    }
                    out[grid.index(b, r, c)] = sum * volume;
                }
            }
        }
        out
    }
}

/// Stages 2–5 for `k` components on the fitted part of `holdout`, judged by the mean squared
/// error of counts on its validation grid (eq. 6): the periods kept and that error.
fn grow(
    holdout: &Holdout<'_>,
    k: usize,
    config: &EventModelConfig,
) -> Result<(Vec<f64>, f64), BuildError> {
    let observed = holdout.validation_grid.count(holdout.validation_events);
    let error_of = |model: &HypertimeEvents| {
        let predicted = model.expected_counts(&holdout.validation_grid);
        predicted
            .iter()
            .zip(&observed)
            .map(|(p, o)| (p - o) * (p - o))
            .sum::<f64>()
            / observed.len().max(1) as f64
    };
    // The error series (eq. 5): predicted minus observed events per bin of the observed time.
    let fit = &holdout.fit;
    let mut bin_times = Vec::new();
    let mut bin_secs = Vec::new();
    for w in fit.windows() {
        let bins = (w.secs() / config.residual_bin_secs).ceil().max(1.0) as usize;
        let len = w.secs() / bins as f64;
        for b in 0..bins {
            bin_times.push(w.start + (b as f64 + 0.5) * len);
            bin_secs.push(len);
        }
    }
    let mut observed_series = vec![0.0; bin_times.len()];
    for e in fit.observed_events() {
        // The bin whose centre is nearest (bins are contiguous within a window).
        let i = bin_times.partition_point(|&c| c < e.t);
        let i = match i {
            0 => 0,
            i if i == bin_times.len() => i - 1,
            i if e.t - bin_times[i - 1] <= bin_times[i] - e.t => i - 1,
            i => i,
        };
        observed_series[i] += 1.0;
    }
    let mut periods = Vec::new();
    let mut model = HypertimeEvents::fit_with(fit, &periods, k, config)?;
    let mut error = error_of(&model);
    while periods.len() < config.max_periods {
        let residuals: Vec<f64> = bin_times
            .iter()
            .zip(&bin_secs)
            .zip(&observed_series)
            .map(|((&t, &len), &o)| model.rate(t) * len - o)
            .collect();
        let weights = vec![1.0; residuals.len()];
        let (next, _) = strongest_period(
            &bin_times,
            &residuals,
            &weights,
            &config.candidate_periods,
            &periods,
        );
        let Some(next) = next else { break };
        let mut extended = periods.clone();
        extended.push(next);
        let candidate = HypertimeEvents::fit_with(fit, &extended, k, config)?;
        let candidate_error = error_of(&candidate);
        if candidate_error >= error {
            break;
        }
        periods = extended;
        model = candidate;
        error = candidate_error;
    }
    Ok((periods, error))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::events::Window;

    #[test]
    fn configuration_and_input_are_checked() {
        let events: Vec<Event> = (0..20)
            .map(|i| Event {
                t: f64::from(i),
                x: 0.0,
                y: 0.0,
            })
            .collect();
        let train = TrainingData::new(
            &events,
            vec![Window {
                start: 0.0,
                end: 20.0,
            }],
        )
        .unwrap();
        let config = EventModelConfig {
            check_cell: 0.0,
            ..EventModelConfig::default()
        };
        assert!(HypertimeEvents::fit(&train, &config).is_err());
        let few = TrainingData::new(
            &events[..5],
            vec![Window {
                start: 0.0,
                end: 20.0,
            }],
        )
        .unwrap();
        assert!(HypertimeEvents::fit(&few, &EventModelConfig::default()).is_err());
    }
}

/// Builds [`HypertimeEvents`] for the event experiment ([`crate::events::run_experiment`]).
///
/// The model does not depend on the grid it is scored on, so one fit per training set serves
/// every cell size and bin length (it is cached).
#[derive(Debug, Default)]
pub struct HypertimeEventsBuilder {
    config: EventModelConfig,
    cache: std::sync::Mutex<Option<(Vec<u64>, std::sync::Arc<HypertimeEvents>)>>,
}

impl HypertimeEventsBuilder {
    /// A builder with these settings.
    pub fn new(config: EventModelConfig) -> Self {
        HypertimeEventsBuilder {
            config,
            cache: std::sync::Mutex::new(None),
        }
    }
}

/// A shared fitted model.
struct Shared(std::sync::Arc<HypertimeEvents>);

impl EventIntensity for Shared {
    fn name(&self) -> String {
        self.0.name()
    }

    fn expected_counts(&self, grid: &EventGrid) -> Vec<f64> {
        self.0.expected_counts(grid)
    }
}

impl crate::events::EventModelBuilder for HypertimeEventsBuilder {
    fn family(&self) -> String {
        "hyt-em".into()
    }

    fn build(&self, train: &TrainingData<'_>, _: SpatialGrid, _: f64) -> crate::events::Built {
        // The key: every event and window, bit for bit.
        let key: Vec<u64> = train
            .events()
            .iter()
            .flat_map(|e| [e.t.to_bits(), e.x.to_bits(), e.y.to_bits()])
            .chain(
                train
                    .windows()
                    .iter()
                    .flat_map(|w| [w.start.to_bits(), w.end.to_bits()]),
            )
            .collect();
        let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((cached, model)) = cache.as_ref()
            && *cached == key
        {
            return Ok(Box::new(Shared(model.clone())));
        }
        let model = std::sync::Arc::new(
            HypertimeEvents::fit(train, &self.config)
                .map_err(|e| crate::events::EventError::Fit(e.to_string()))?,
        );
        *cache = Some((key, model.clone()));
        Ok(Box::new(Shared(model)))
    }
}
