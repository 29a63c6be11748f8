//! The models the service holds, and the one function that changes them:
//! [`Registry::apply`] of a [`LogRecord`]. The live service and recovery after a crash apply
//! the same records in the same order, so a restarted service holds exactly the models an
//! uninterrupted one would.

use std::collections::HashMap;

use chronomap_core::calendar::DaysOff;
use chronomap_core::{ObservationError, Ordered, TemporalModel};
use chronomap_models::learner::{FitRecord, RefitError};
use chronomap_models::spec::Selection;
use chronomap_models::{AnyModel, Learner, ModelSpec};
use serde::{Deserialize, Serialize};

use crate::api::{
    Component, DaysOffInfo, FitInfo, MAX_DAYS_OFF, MAX_ID_BYTES, ModelInfo, RefitInfo, StackWeight,
};
use crate::log::LogRecord;

/// Observations the service keeps per model fitted on a whole series (`auto`, `fremen:auto`,
/// ...) for its refits: [`chronomap_models::learner::DEFAULT_KEEP`] (2^21, 32 MiB; the oldest
/// are dropped). Fixed, so that replaying a log always makes the same learners.
pub const KEEP: usize = chronomap_models::learner::DEFAULT_KEEP;

/// How a model was created: what it is, the range of its values and its calendar of days off.
///
/// Serialised whole (a [`LogRecord::Create`] of a model with a calendar, snapshots of version
/// 4). A configuration without a calendar is written as services before calendars wrote it,
/// [`ConfigV1`]: their records and snapshots load as they did (see [`crate::log`] and
/// [`crate::store`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelConfig {
    /// The model.
    pub spec: ModelSpec,
    /// Range `[lo, hi]` of continuous values, mapped onto `[0, 1]`.
    pub range: Option<[f64; 2]>,
    /// Days off: observations on them are not learned, and a time on one is predicted at its
    /// [stand-in](DaysOff::stand_in). Empty: no calendar.
    pub days_off: DaysOff,
}

/// The layout of a configuration before calendars of days off (log records of every format,
/// snapshots of versions 1 to 3), still written for configurations without one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConfigV1 {
    /// The model.
    pub spec: ModelSpec,
    /// Range of continuous values.
    pub range: Option<[f64; 2]>,
}

impl From<ConfigV1> for ModelConfig {
    fn from(old: ConfigV1) -> Self {
        ModelConfig {
            spec: old.spec,
            range: old.range,
            days_off: DaysOff::default(),
        }
    }
}

/// Parses a calendar of days off as a client gives it: UTC dates `YYYY-MM-DD`, at most
/// [`MAX_DAYS_OFF`] (a date given twice is one day).
///
/// # Errors
/// A sentence naming the field `days_off` and the index of the first date that is not one, or
/// the number of dates when there are too many.
pub fn parse_days_off(dates: &[String]) -> Result<DaysOff, String> {
    if dates.len() > MAX_DAYS_OFF {
        return Err(format!(
            "field `days_off`: {} dates, more than {MAX_DAYS_OFF} (a calendar of days off \
             holds holidays and closures, not every day)",
            dates.len()
        ));
    }
    let mut days = Vec::with_capacity(dates.len());
    for (i, date) in dates.iter().enumerate() {
        let day = chronomap_core::time::parse_date(date)
            .filter(|&day| {
                (0.0..=chronomap_core::observe::MAX_TIME_SECS).contains(&(day as f64 * DAY))
            })
            .ok_or_else(|| {
                format!(
                    "field `days_off`, element {i}: {date:?} is not a UTC date YYYY-MM-DD \
                     between 1970-01-01 and the largest time (about the year 5138)"
                )
            })?;
        days.push(day);
    }
    Ok(DaysOff::new(days))
}

/// Seconds in a day.
const DAY: f64 = 86_400.0;

impl ModelConfig {
    /// Parses and checks a spec and range as a client gives them.
    ///
    /// # Errors
    /// A sentence naming the field: unparsable spec, an order above the largest, or a range
    /// that is not finite and increasing. Every spec is accepted: those that learn online
    /// are that model, the others (`auto`, `fremen:auto`, `fft`, hypertime) keep their
    /// observations and are refitted ([`chronomap_models::learner`]).
    pub fn parse(model: Option<&str>, range: Option<[f64; 2]>) -> Result<Self, String> {
        let text = model.unwrap_or(crate::api::DEFAULT_MODEL);
        let spec: ModelSpec = text.parse().map_err(|e| format!("field `model`: {e}"))?;
        empty_model(&spec).map_err(|e| format!("field `model`: {e}"))?;
        if let Some([lo, hi]) = range
            && !(lo.is_finite() && hi.is_finite() && lo < hi && (hi - lo).is_finite())
        {
            return Err(format!(
                "field `range`: [{lo:e}, {hi:e}] is not a finite interval with lo < hi \
                 and a finite width hi - lo"
            ));
        }
        Ok(ModelConfig {
            spec,
            range,
            days_off: DaysOff::default(),
        })
    }

    /// This configuration with the calendar `days_off`.
    pub fn with_days_off(self, days_off: DaysOff) -> Self {
        ModelConfig { days_off, ..self }
    }

    /// The learner this configuration describes, having seen nothing.
    ///
    /// # Errors
    /// As [`ModelConfig::parse`].
    pub fn empty_model(&self) -> Result<Learner, String> {
        empty_model(&self.spec)
    }

    /// Whether models of this configuration keep a model of the second moment
    /// ([`Entry::spread`]): those of continuous values whose spec learns online, or is `auto`.
    pub fn has_second_moment(&self) -> bool {
        self.range.is_some() && self.spec.has_second_moment()
    }

    /// Maps a value as given onto `[0, 1]`.
    pub fn normalise(&self, value: f64) -> f64 {
        match self.range {
            Some([lo, hi]) => (value - lo) / (hi - lo),
            None => value,
        }
    }

    /// Maps a prediction in `[0, 1]` back onto the range.
    pub fn scale(&self, p: f64) -> f64 {
        match self.range {
            Some([lo, hi]) => lo + p * (hi - lo),
            None => p,
        }
    }
}

/// The learner of a spec having seen nothing ([`ModelSpec::learner`], keeping [`KEEP`]).
fn empty_model(spec: &ModelSpec) -> Result<Learner, String> {
    spec.learner(KEEP).map_err(|e| e.to_string())
}

/// Whether `c` is a Unicode format character (general category Cf: bidirectional controls
/// such as U+202E, zero-width characters, the byte order mark, tags) or a line or paragraph
/// separator: characters that make an id display as another one.
fn is_invisible(c: char) -> bool {
    matches!(c as u32,
        0x00AD | 0x0600..=0x0605 | 0x061C | 0x06DD | 0x070F | 0x0890..=0x0891 | 0x08E2
        | 0x180E | 0x200B..=0x200F | 0x2028..=0x202E | 0x2060..=0x2064 | 0x2066..=0x206F
        | 0xFEFF | 0xFFF9..=0xFFFB | 0x110BD | 0x110CD | 0x13430..=0x1343F
        | 0x1BCA0..=0x1BCA3 | 0x1D173..=0x1D17A | 0xE0001 | 0xE0020..=0xE007F)
}

/// Checks a model id: 1 to [`MAX_ID_BYTES`] bytes of UTF-8 without control characters,
/// format characters (bidirectional controls, zero-width characters) or line separators.
///
/// # Errors
/// A sentence saying what is wrong.
pub fn check_id(id: &str) -> Result<(), String> {
    if id.is_empty() {
        return Err("model id is empty".into());
    }
    if id.len() > MAX_ID_BYTES {
        return Err(format!(
            "model id is {} bytes long; at most {MAX_ID_BYTES} bytes of UTF-8 are allowed",
            id.len()
        ));
    }
    if let Some(c) = id.chars().find(|c| c.is_control()) {
        return Err(format!(
            "model id contains the control character U+{:04X}",
            c as u32
        ));
    }
    if let Some(c) = id.chars().find(|&c| is_invisible(c)) {
        return Err(format!(
            "model id contains the invisible format character U+{:04X} (bidirectional \
             controls, zero-width characters and separators would let one id look like another)",
            c as u32
        ));
    }
    Ok(())
}

/// One model and its configuration.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Entry {
    /// How it was created.
    pub config: ModelConfig,
    /// The model: the online model, or kept observations and the last fit.
    pub model: Learner,
    /// For models of continuous values (with a `range`) whose spec learns online, or is
    /// `auto`: the same model fed the squares of the normalised values, the second moment that
    /// prediction intervals come from ([`chronomap_core::spread`]); `auto`'s is refitted with
    /// it, on the same observations squared ([`LogRecord::Refit`]). `None` for binary models;
    /// for the other specs fitted on a whole series (`fremen:auto`, ...: the order chosen for
    /// the squares cannot hold the square of the values' rhythm, and the variance collapses;
    /// `auto`'s histograms average the squares as they average the values; see
    /// `docs/service.md`); and for models restored from a snapshot written before intervals
    /// were served (they never learnt the squares, so they have no interval until they are
    /// created again).
    pub spread: Option<Learner>,
    /// Observations made on a day off of the model's calendar ([`ModelConfig::days_off`]):
    /// accepted and logged, not learned.
    pub skipped: u64,
}

impl Entry {
    /// A model of this configuration that has seen nothing.
    ///
    /// # Errors
    /// As [`ModelConfig::parse`].
    pub fn new(config: ModelConfig) -> Result<Self, String> {
        let model = config.empty_model()?;
        let spread = if config.has_second_moment() {
            Some(config.empty_model()?)
        } else {
            None
        };
        Ok(Entry {
            config,
            model,
            spread,
            skipped: 0,
        })
    }

    /// Adds observations given in the model's range (`id` is for errors). Those made on a day
    /// off of its calendar are checked like the others and counted ([`Entry::skipped`]), not
    /// learned: neither the model, nor the kept observations of one fitted on a whole series,
    /// nor the second moment see them.
    ///
    /// # Errors
    /// The first violation of the observation contract, or a value outside the model's range
    /// (with its index in the batch as given); the entry is then unchanged.
    pub fn observe(&mut self, id: &str, times: &[f64], values: &[f64]) -> Result<(), ApplyError> {
        use std::borrow::Cow;
        let normalised: Cow<'_, [f64]> = match self.config.range {
            None => Cow::Borrowed(values),
            Some([lo, hi]) => {
                if let Some(index) = values.iter().position(|v| !(lo..=hi).contains(v)) {
                    return Err(ApplyError::OutOfRange {
                        id: id.to_owned(),
                        index,
                        value: values[index],
                        range: [lo, hi],
                    });
                }
                Cow::Owned(values.iter().map(|&v| self.config.normalise(v)).collect())
            }
        };
        let observation = |e| ApplyError::Observation(id.to_owned(), e);
        let days_off = &self.config.days_off;
        let batch = times.len();
        let (times, normalised) = if days_off.is_empty() {
            (Cow::Borrowed(times), Cow::Borrowed(&*normalised))
        } else {
            // The whole batch is checked (one value per time among it), so that an error
            // names the index the client gave (and an observation on a day off is held to the
            // contract too).
            chronomap_core::observe::validate(self.model.span().last_time(), times, &normalised)
                .map_err(observation)?;
            days_off.working_days(times, &normalised)
        };
        let skipped = (batch - times.len()) as u64;
        self.model
            .observe(&times, &normalised)
            .and_then(|()| {
                // The same times and values in [0, 1] that the model accepted: the squares
                // are accepted too.
                let Some(spread) = &mut self.spread else {
                    return Ok(());
                };
                let squares: Vec<f64> = normalised.iter().map(|x| x * x).collect();
                spread.observe(&times, &squares)
            })
            .map_err(observation)?;
        self.skipped += skipped;
        Ok(())
    }

    /// The model of the second moment with `order` (as [`Entry::with_order`]), when it has
    /// one ([`Entry::spread`]); `None` for every other model.
    pub fn spread_with_order(
        &self,
        order: Option<usize>,
    ) -> Option<std::borrow::Cow<'_, AnyModel>> {
        let model = self.spread.as_ref()?.model()?;
        match order {
            Some(order) if model.order() != Some(order) => {
                if order > max_order(model)? {
                    return None;
                }
                let mut copy = model.clone();
                copy.set_order(order);
                Some(std::borrow::Cow::Owned(copy))
            }
            _ => Some(std::borrow::Cow::Borrowed(model)),
        }
    }

    /// Puts a fit of its kept observations in place, and of their squares for the model of the
    /// second moment (`spread`; `id` is for errors).
    ///
    /// # Errors
    /// A fit that does not belong to its learner, or an older one than its own
    /// ([`Learner::install`]), or a fit of the second moment for a model without one; the entry
    /// is then unchanged.
    pub fn install(
        &mut self,
        id: &str,
        refit: &chronomap_models::learner::Refit,
        spread: Option<&chronomap_models::learner::Refit>,
    ) -> Result<(), ApplyError> {
        let refused = |e| ApplyError::Refit(id.to_owned(), e);
        // Both or neither: the second moment's fit goes into a copy first.
        let spread = match (spread, &self.spread) {
            (None, _) => None,
            (Some(fit), Some(learner)) => {
                let mut learner = learner.clone();
                learner.install(fit.clone()).map_err(refused)?;
                Some(learner)
            }
            (Some(_), None) => {
                return Err(refused(RefitError::NotThisLearner {
                    reason: format!(
                        "a fit of the second moment, and this `{}` model has no model of it",
                        self.config.spec
                    ),
                }));
            }
        };
        self.model.install(refit.clone()).map_err(refused)?;
        if spread.is_some() {
            self.spread = spread;
        }
        Ok(())
    }

    /// The model predicting with `order` (a copy when the order differs from its own). A model
    /// fitted on a whole series that has not been fitted yet is an empty model (it predicts
    /// 0.5, as every model that knows nothing).
    ///
    /// # Errors
    /// An order above the model's largest, or an order for a model without one (or not
    /// fitted yet).
    pub fn with_order(
        &self,
        order: Option<usize>,
    ) -> Result<std::borrow::Cow<'_, AnyModel>, String> {
        let Some(model) = self.model.model() else {
            if order.is_some() {
                return Err(format!(
                    "field `order`: the `{}` model has not been fitted yet (POST \
                     /v1/models/{{id}}/refit fits it)",
                    self.config.spec
                ));
            }
            return Ok(std::borrow::Cow::Owned(AnyModel::Mean(
                chronomap_core::MeanModel::new(),
            )));
        };
        let Some(order) = order else {
            return Ok(std::borrow::Cow::Borrowed(model));
        };
        if model.order() == Some(order) {
            return Ok(std::borrow::Cow::Borrowed(model));
        }
        let max = max_order(model)
            .ok_or_else(|| format!("field `order`: a `{}` model has no order", self.config.spec))?;
        if order > max {
            return Err(format!(
                "field `order`: {order} is above this model's largest order {max}"
            ));
        }
        let mut copy = model.clone();
        copy.set_order(order);
        Ok(std::borrow::Cow::Owned(copy))
    }

    /// The description `view` and `list` return.
    pub fn info(&self, id: &str) -> ModelInfo {
        let span = self.model.span();
        let fremen = match self.model.model() {
            Some(AnyModel::Fremen(m)) => Some(m),
            Some(AnyModel::Persistence(m)) => Some(m.fremen()),
            _ => None,
        };
        ModelInfo {
            id: id.to_owned(),
            model: self.config.spec.to_string(),
            range: self.config.range,
            observations: span.count,
            first_time: (span.count > 0).then_some(span.first),
            last_time: (span.count > 0).then_some(span.last),
            mean: fremen.map(|m| m.fit().mean),
            components: fremen
                .map(|m| {
                    m.components()
                        .iter()
                        .map(|c| Component {
                            period_secs: c.period_secs,
                            amplitude: c.amplitude,
                            phase: c.phase,
                        })
                        .collect()
                })
                .unwrap_or_default(),
            refit: self.refit_info(),
            days_off: self.days_off_info(),
        }
    }

    /// The model's calendar of days off in brief (`None` without one).
    pub fn days_off_info(&self) -> Option<DaysOffInfo> {
        let days = &self.config.days_off;
        Some(DaysOffInfo {
            days: days.len() as u64,
            first: chronomap_core::time::format_date(days.days().next()?),
            last: chronomap_core::time::format_date(days.days().last()?),
            skipped: self.skipped,
        })
    }

    /// What a model fitted on a whole series keeps, and its last fit (`None` for models that
    /// learn online).
    pub fn refit_info(&self) -> Option<RefitInfo> {
        let keep = self.model.keep()?;
        Some(RefitInfo {
            kept: self.model.kept() as u64,
            keep: keep as u64,
            since_fit: self.model.since_fit().0,
            last_fit: self.fit_info(),
        })
    }

    /// The last fit of a model fitted on a whole series.
    pub fn fit_info(&self) -> Option<FitInfo> {
        let (record, model) = (self.model.last_fit()?, self.model.model()?);
        Some(fit_info(record, model))
    }
}

/// A fit as the API describes it.
pub fn fit_info(record: &FitRecord, model: &AnyModel) -> FitInfo {
    let (weights, error) = match &record.selection {
        Some(Selection::Stack(stack)) => (
            stack
                .weights
                .iter()
                .map(|(spec, weight)| StackWeight {
                    model: spec.to_string(),
                    weight: *weight,
                })
                .collect(),
            Some(stack.combined_error),
        ),
        Some(Selection::Order(order)) => (Vec::new(), order.errors.get(order.order).copied()),
        _ => (Vec::new(), None),
    };
    FitInfo {
        observations: record.observations,
        through: record.through,
        first_time: record.first_time,
        last_time: record.last_time,
        fitted: model.fitted_as(),
        weights,
        error,
    }
}

/// Largest order of a model that has one.
pub fn max_order(model: &AnyModel) -> Option<usize> {
    Some(match model {
        AnyModel::Fremen(m) => m.max_order(),
        AnyModel::Persistence(m) => m.max_order(),
        AnyModel::Pergam(m) => m.max_order(),
        AnyModel::Fft(m) => m.max_order(),
        _ => return None,
    })
}

/// Why a record could not be applied.
#[derive(Clone, Debug, PartialEq)]
pub enum ApplyError {
    /// The id does not exist.
    NotFound(String),
    /// The id exists with another configuration.
    Conflict(String),
    /// Observations violate the contract (index within the batch, reason).
    Observation(String, ObservationError),
    /// The configuration cannot be built.
    Config(String),
    /// A refit that cannot be put in place (model id, why).
    Refit(String, RefitError),
    /// A value outside the range of a model of continuous values.
    OutOfRange {
        /// Model id.
        id: String,
        /// Index within the batch.
        index: usize,
        /// The value.
        value: f64,
        /// The model's range.
        range: [f64; 2],
    },
}

impl std::fmt::Display for ApplyError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ApplyError::NotFound(id) => write!(f, "no model with id {id:?}"),
            ApplyError::Conflict(id) => write!(
                f,
                "model {id:?} exists with another configuration; remove it first"
            ),
            ApplyError::Observation(id, e) => match e.index() {
                Some(i) => write!(f, "model {id:?}, observation {i}: {e}"),
                None => write!(f, "model {id:?}: {e}"),
            },
            ApplyError::Config(reason) => f.write_str(reason),
            ApplyError::Refit(id, e) => write!(f, "model {id:?}: {e}"),
            ApplyError::OutOfRange {
                id,
                index,
                value,
                range: [lo, hi],
            } => write!(
                f,
                "model {id:?}, observation {index}: value {value} is outside the model's range \
                 [{lo}, {hi}]"
            ),
        }
    }
}

/// All models, by id.
#[derive(Clone, Debug, Default)]
pub struct Registry {
    models: HashMap<String, Entry>,
}

impl Registry {
    /// No models.
    pub fn new() -> Self {
        Registry::default()
    }

    /// The model with this id.
    pub fn get(&self, id: &str) -> Option<&Entry> {
        self.models.get(id)
    }

    /// Number of models.
    pub fn len(&self) -> usize {
        self.models.len()
    }

    /// Whether there is no model.
    pub fn is_empty(&self) -> bool {
        self.models.is_empty()
    }

    /// Ids, sorted.
    pub fn ids(&self) -> Vec<&str> {
        let mut ids: Vec<&str> = self.models.keys().map(String::as_str).collect();
        ids.sort_unstable();
        ids
    }

    /// Inserts or replaces (recovery from snapshots, and the writer's staged entries).
    pub fn put(&mut self, id: String, entry: Option<Entry>) {
        match entry {
            Some(entry) => {
                self.models.insert(id, entry);
            }
            None => {
                self.models.remove(&id);
            }
        }
    }

    /// Applies one log record (recovery replays the log with this).
    ///
    /// # Errors
    /// See [`apply_to`]; the registry is then unchanged.
    pub fn apply(&mut self, record: &LogRecord) -> Result<(), ApplyError> {
        match record {
            // In place: a model observes atomically (unchanged on error).
            LogRecord::Observe { id, times, values } => self
                .models
                .get_mut(id.as_str())
                .ok_or_else(|| ApplyError::NotFound(id.clone()))?
                .observe(id, times, values),
            // In place too: a learner installs a fit atomically.
            LogRecord::Refit { id, refit, spread } => self
                .models
                .get_mut(id.as_str())
                .ok_or_else(|| ApplyError::NotFound(id.clone()))?
                .install(id, refit, spread.as_deref()),
            _ => {
                let id = record.id();
                let mut slot = self.models.remove(id);
                let before = slot.clone();
                let result = apply_to(&mut slot, record);
                self.put(id.to_owned(), if result.is_ok() { slot } else { before });
                result
            }
        }
    }
}

/// Applies one log record to the state of its id (`None`: no such model).
///
/// # Errors
/// `Create` of an existing id with another configuration, `Observe`/`Remove` of a missing id,
/// observations that violate the contract. `slot` is then unchanged.
pub fn apply_to(slot: &mut Option<Entry>, record: &LogRecord) -> Result<(), ApplyError> {
    match record {
        LogRecord::Create { id, config } => match slot {
            Some(entry) if entry.config == *config => Ok(()),
            Some(_) => Err(ApplyError::Conflict(id.clone())),
            None => {
                *slot = Some(Entry::new(config.clone()).map_err(ApplyError::Config)?);
                Ok(())
            }
        },
        LogRecord::Observe { id, times, values } => {
            let entry = slot
                .as_mut()
                .ok_or_else(|| ApplyError::NotFound(id.clone()))?;
            entry.observe(id, times, values)
        }
        LogRecord::Remove { id } => {
            if slot.take().is_none() {
                return Err(ApplyError::NotFound(id.clone()));
            }
            Ok(())
        }
        LogRecord::Refit { id, refit, spread } => slot
            .as_mut()
            .ok_or_else(|| ApplyError::NotFound(id.clone()))?
            .install(id, refit, spread.as_deref()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fit of `values` (normalised) at hourly times by a learner of `spec`.
    fn fit(spec: &str, values: &[f64]) -> chronomap_models::learner::Refit {
        let mut learner = spec.parse::<ModelSpec>().unwrap().learner(KEEP).unwrap();
        let times: Vec<f64> = (0..values.len()).map(|i| 3600.0 * i as f64).collect();
        learner.observe(&times, values).unwrap();
        learner
            .refit_job()
            .unwrap()
            .run(&chronomap_models::FitOptions::default())
            .unwrap()
    }

    #[test]
    fn auto_refits_its_second_moment_with_it_and_other_whole_series_specs_have_none() {
        let values: Vec<f64> = (0..96).map(|h| 10.0 + f64::from(h % 24)).collect();
        let normalised: Vec<f64> = values.iter().map(|v| (v - 10.0) / 30.0).collect();
        let squares: Vec<f64> = normalised.iter().map(|v| v * v).collect();
        let times: Vec<f64> = (0..96).map(|i| 3600.0 * f64::from(i)).collect();
        let entry = |spec: &str| {
            let config = ModelConfig::parse(Some(spec), Some([10.0, 40.0])).unwrap();
            assert_eq!(config.has_second_moment(), spec == "auto", "{spec}");
            let mut entry = Entry::new(config).unwrap();
            entry.observe("temp", &times, &values).unwrap();
            entry
        };
        let mut stack = entry("auto");
        stack
            .install(
                "temp",
                &fit("auto", &normalised),
                Some(&fit("auto", &squares)),
            )
            .unwrap();
        assert!(stack.spread_with_order(None).is_some());
        // A fit of the second moment for a model without one is refused, and changes nothing.
        let mut order = entry("fremen:auto");
        let error = order
            .install(
                "temp",
                &fit("fremen:auto", &normalised),
                Some(&fit("fremen:auto", &squares)),
            )
            .unwrap_err();
        assert!(error.to_string().contains("second moment"), "{error}");
        assert!(order.model.model().is_none() && order.spread.is_none());
        // A fit of the second moment that does not belong (of more observations than the
        // model has seen) leaves the model unfitted too.
        let mut stack = entry("auto");
        let more: Vec<f64> = squares.iter().chain(&squares).copied().collect();
        let error = stack
            .install("temp", &fit("auto", &normalised), Some(&fit("auto", &more)))
            .unwrap_err();
        assert!(matches!(error, ApplyError::Refit(..)), "{error}");
        assert!(stack.model.model().is_none());
    }
}
