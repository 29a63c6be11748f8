//! Learning any model online: [`Learner`], made by [`ModelSpec::learner`].
//!
//! Most specs learn observation by observation ([`ModelSpec::online_model`]): their learner
//! is that model ([`Learner::Online`]), bit for bit. The others choose an order or a
//! combination on held-back data (`fremen:auto`, `pergam:auto`, `auto` = [`StackedModel`],
//! rolling-origin stacking) or need a whole series (`fft`, hypertime): they are fitted
//! offline by [`ModelSpec::fit`]. Their learner ([`Learner::Refitting`], a [`Refitting`])
//! keeps the observations and refits on request:
//!
//! * It keeps at most `keep` observations (16 bytes each; [`DEFAULT_KEEP`]): when more
//!   arrive, the oldest are dropped, so that a fit describes the most recent `keep`
//!   observations and memory stays bounded however long the robot runs.
//! * It predicts with its last fit: the model [`ModelSpec::fit`] made from the kept
//!   observations, which then goes on observing what arrives after it where the fitted model
//!   learns online (the members of `auto`, the FreMEn model of the order `fremen:auto`
//!   chose; `fft` and hypertime models stay as fitted). Before the first fit it predicts
//!   `0.5`, as every model that has seen nothing does.
//! * A refit on the kept observations gives bit for bit the model `chronomap fit --model
//!   SPEC` makes of them ([`ModelSpec::fit`] with the same [`FitOptions`]).
//! * When to refit is the caller's choice: [`Learner::is_due`] compares what arrived since the
//!   last fit (observations, and seconds of data time — never a clock) with a
//!   [`RefitPolicy`].
//! * A refit is split so that the heavy part can run on another thread while the learner
//!   goes on observing: [`Learner::refit_job`] takes the kept observations (cheaply: they are
//!   shared, not copied), [`RefitJob::run`] fits them (pure, seconds for `auto` on weeks of
//!   data), [`Learner::install`] puts the result in place and lets the fitted model observe
//!   what arrived meanwhile. [`Learner::refit`] does all three at once.
//!
//! A learner serialises (serde) with its kept observations and its model, so a restored
//! learner predicts, observes and refits exactly as the one saved.

use std::collections::VecDeque;
use std::fmt;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use chronomap_core::error::{BuildError, ConfigError, ObservationError};
use chronomap_core::model::TemporalModel;
use chronomap_core::observe::ObservedSpan;

use crate::spec::{AnyModel, FitOptions, ModelSpec, OnlineError, Selection};
#[cfg(doc)]
use crate::stack::StackedModel;

/// Observations a [`Refitting`] learner keeps unless told otherwise: 2^21 = 2,097,152
/// (32 MiB). That is 24 days of a state observed every second, four years at one observation
/// a minute — several weeks, which weekly rhythms need — and a refit of `auto` on that many
/// took 11.5 s (release build, two shared cores; 0.47 s on the 96,480 of the Greg door).
pub const DEFAULT_KEEP: usize = 1 << 21;

/// Observations per shared chunk of the kept observations: a copy of a learner shares the
/// full chunks and copies at most this many when it observes.
const CHUNK: usize = 4096;

/// When a [`Refitting`] learner is due for a refit: when either limit is reached since the
/// last fit (since the first observation before any fit). A limit of 0 never triggers.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RefitPolicy {
    /// New observations since the last fit.
    pub observations: u64,
    /// Seconds of data time: from the last observation of the last fit (the first
    /// observation before any fit) to the latest observation.
    pub data_secs: f64,
}

impl Default for RefitPolicy {
    /// Once a day of data time, or after 100,000 new observations (28 hours at 1 Hz).
    fn default() -> Self {
        RefitPolicy {
            observations: 100_000,
            data_secs: 86_400.0,
        }
    }
}

impl RefitPolicy {
    /// Only on request: never due.
    pub const NEVER: RefitPolicy = RefitPolicy {
        observations: 0,
        data_secs: 0.0,
    };

    /// Whether `observations` new observations spanning `data_secs` of data time call for a
    /// refit (never without a new observation).
    pub fn is_due(&self, observations: u64, data_secs: f64) -> bool {
        observations > 0
            && ((self.observations > 0 && observations >= self.observations)
                || (self.data_secs > 0.0 && data_secs >= self.data_secs))
    }
}

/// A learner of any spec (see the [module docs](self)).
///
/// Variants are only ever appended (their index is part of the serialised form).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[allow(clippy::large_enum_variant)]
pub enum Learner {
    /// A spec that learns online: exactly the model of [`ModelSpec::online_model`].
    Online(AnyModel),
    /// A spec fitted offline: kept observations and the last fit.
    Refitting(Box<Refitting>),
}

/// The learner of a spec fitted offline: kept observations, the last fit, the model
/// predicting (see the [module docs](self)).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(try_from = "RefittingFields")]
pub struct Refitting {
    spec: ModelSpec,
    keep: usize,
    kept: Kept,
    span: ObservedSpan,
    model: Option<AnyModel>,
    last_fit: Option<FitRecord>,
}

/// How the model of a [`Refitting`] learner was fitted.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitRecord {
    /// How many observations the learner had taken in (since it was made) when the
    /// observations were taken for the fit: the fit is of the kept ones among the first
    /// `through`.
    pub through: u64,
    /// Observations fitted on.
    pub observations: u64,
    /// Time of the first of them (s).
    pub first_time: f64,
    /// Time of the last of them (s).
    pub last_time: f64,
    /// What the fit chose: an order, or `auto`'s members and weights
    /// ([`crate::stack::StackSelection`]); `None` for specs without a choice (`fft:3`).
    pub selection: Option<Selection>,
}

/// A fit of a [`Refitting`] learner's kept observations, to [`Learner::install`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Refit {
    /// The spec fitted.
    pub spec: ModelSpec,
    /// How and on what it was fitted.
    pub record: FitRecord,
    /// The fitted model ([`ModelSpec::fit`] of the observations).
    pub model: AnyModel,
}

/// The observations of a refit, taken from a learner ([`Learner::refit_job`]).
#[derive(Clone, Debug)]
pub struct RefitJob {
    spec: ModelSpec,
    through: u64,
    kept: Kept,
}

/// Why a [`Refit`] cannot be installed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RefitError {
    /// The learner learns online: it has nothing to refit.
    #[error("`{spec}` learns online and is never refitted")]
    Online {
        /// The learner's spec.
        spec: String,
    },
    /// The fit is of another spec.
    #[error("a fit of `{fit}` cannot be installed in a learner of `{spec}`")]
    WrongSpec {
        /// The learner's spec.
        spec: String,
        /// The fit's spec.
        fit: String,
    },
    /// The fit is of observations the learner has not taken in, or not those it kept.
    #[error("the fit is not of this learner's observations: {reason}")]
    NotThisLearner {
        /// What does not match.
        reason: String,
    },
    /// The learner already has a fit of later observations.
    #[error(
        "the fit of the first {through} observations is older than the fit in place (of the \
         first {current})"
    )]
    Superseded {
        /// The fit's `through`.
        through: u64,
        /// The `through` of the fit in place.
        current: u64,
    },
    /// More observations arrived after the fit's than the learner keeps: the fitted model
    /// cannot observe them any more.
    #[error("{after} observations arrived after the fit's, more than the {kept} kept: refit again")]
    TooLate {
        /// Observations after the fit's.
        after: u64,
        /// Observations kept.
        kept: usize,
    },
    /// The fitted model is inconsistent or has not seen what the fit says.
    #[error("the fitted model is inconsistent: {0}")]
    Inconsistent(String),
    /// The fit failed ([`RefitJob::run`]).
    #[error("the fit failed: {0}")]
    Fit(#[from] BuildError),
}

impl ModelSpec {
    /// A learner of this spec having seen nothing (see [`crate::learner`]): the model of
    /// [`ModelSpec::online_model`] for specs that learn online, else a [`Refitting`] learner
    /// keeping at most `keep` observations (the oldest are dropped; [`DEFAULT_KEEP`]).
    ///
    /// # Errors
    /// Orders above the largest one and invalid parameters of specs that learn online, as
    /// [`ModelSpec::online_model`]; `keep` = 0 for other specs.
    pub fn learner(&self, keep: usize) -> Result<Learner, OnlineError> {
        match self.online_model() {
            Ok(model) => Ok(Learner::Online(model)),
            Err(OnlineError::AutoOrder { .. } | OnlineError::Offline { .. }) => {
                if keep == 0 {
                    return Err(OnlineError::Config {
                        spec: self.to_string(),
                        source: ConfigError::OutOfRange {
                            name: "keep",
                            value: "0".into(),
                            expected: "at least 1 observation kept for refits",
                        },
                    });
                }
                Ok(Learner::Refitting(Box::new(Refitting {
                    spec: self.clone(),
                    keep,
                    kept: Kept::default(),
                    span: ObservedSpan::default(),
                    model: None,
                    last_fit: None,
                })))
            }
            Err(e) => Err(e),
        }
    }

    /// Whether a learner of this spec fed values in `[0, 1]` can have a twin fed their squares
    /// that predicts the second moment, from which [`chronomap_core::spread`] makes prediction
    /// intervals: specs that learn online, and `auto`, whose stack of averages averages the
    /// squares as it averages the values. Not the other specs fitted on a whole series
    /// (`fremen:auto`, ...: the order chosen for the squares cannot hold the square of the
    /// values' rhythm, and the variance collapses).
    pub fn has_second_moment(&self) -> bool {
        *self == ModelSpec::Auto || !self.learner(1).is_ok_and(|l| l.is_refitting())
    }
}

impl Learner {
    /// The spec it learns: as asked (`auto`, `fremen:auto`) for refitting learners, that of
    /// the model for those learning online.
    pub fn spec(&self) -> ModelSpec {
        match self {
            Learner::Online(m) => m.spec(),
            Learner::Refitting(r) => r.spec.clone(),
        }
    }

    /// The model predicting: the online model, or the last fit (`None` before the first).
    pub fn model(&self) -> Option<&AnyModel> {
        match self {
            Learner::Online(m) => Some(m),
            Learner::Refitting(r) => r.model.as_ref(),
        }
    }

    /// Whether it is refitted (a spec fitted offline) rather than learning online.
    pub fn is_refitting(&self) -> bool {
        matches!(self, Learner::Refitting(_))
    }

    /// Observations kept for refits (0 for online learners).
    pub fn kept(&self) -> usize {
        match self {
            Learner::Online(_) => 0,
            Learner::Refitting(r) => r.kept.len(),
        }
    }

    /// The most observations it keeps (`None` for online learners).
    pub fn keep(&self) -> Option<usize> {
        match self {
            Learner::Online(_) => None,
            Learner::Refitting(r) => Some(r.keep),
        }
    }

    /// How the model predicting was fitted (`None` for online learners and before the first
    /// fit).
    pub fn last_fit(&self) -> Option<&FitRecord> {
        match self {
            Learner::Online(_) => None,
            Learner::Refitting(r) => r.last_fit.as_ref(),
        }
    }

    /// New observations since the last fit (since it was made, before any fit), and the data
    /// time they span (s) from the last fit's last observation (from the first observation,
    /// before any fit). `(0, 0.0)` for online learners.
    pub fn since_fit(&self) -> (u64, f64) {
        match self {
            Learner::Online(_) => (0, 0.0),
            Learner::Refitting(r) => match &r.last_fit {
                Some(fit) => (r.span.count - fit.through, r.span.last - fit.last_time),
                None => (r.span.count, r.span.duration()),
            },
        }
    }

    /// Whether `policy` calls for a refit now (never for online learners).
    pub fn is_due(&self, policy: &RefitPolicy) -> bool {
        let (observations, secs) = self.since_fit();
        self.is_refitting() && policy.is_due(observations, secs)
    }

    /// The kept observations for a refit ([`RefitJob::run`]), shared with the learner rather
    /// than copied; `None` for online learners.
    pub fn refit_job(&self) -> Option<RefitJob> {
        match self {
            Learner::Online(_) => None,
            Learner::Refitting(r) => Some(RefitJob {
                spec: r.spec.clone(),
                through: r.span.count,
                kept: r.kept.clone(),
            }),
        }
    }

    /// Puts a fit of this learner's observations in place: it predicts with `refit.model`
    /// from now on, which first observes what the learner took in after the fit's
    /// observations (where the model learns online).
    ///
    /// # Errors
    /// An online learner, a fit of another spec or of other observations, one older than the
    /// fit in place, or one followed by more observations than are kept. The learner is then
    /// unchanged.
    pub fn install(&mut self, refit: Refit) -> Result<(), RefitError> {
        match self {
            Learner::Online(m) => Err(RefitError::Online {
                spec: m.spec().to_string(),
            }),
            Learner::Refitting(r) => r.install(refit),
        }
    }

    /// Refits on the kept observations now ([`Learner::refit_job`], [`RefitJob::run`],
    /// [`Learner::install`]); returns whether it did (online learners are not refitted).
    ///
    /// # Errors
    /// The fit failed (too few observations, data the spec cannot fit: [`RefitError::Fit`]);
    /// the learner is then unchanged.
    pub fn refit(&mut self, options: &FitOptions) -> Result<bool, RefitError> {
        let Some(job) = self.refit_job() else {
            return Ok(false);
        };
        self.install(job.run(options)?)?;
        Ok(true)
    }

    /// Checks internal invariants (for learners read from files and snapshots).
    pub fn is_consistent(&self) -> bool {
        match self {
            Learner::Online(m) => m.is_consistent(),
            Learner::Refitting(r) => r.check().is_ok(),
        }
    }
}

impl TemporalModel for Learner {
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        match self {
            Learner::Online(m) => m.observe(times, values),
            Learner::Refitting(r) => r.observe(times, values),
        }
    }

    fn predict(&self, time: f64) -> f64 {
        self.model().map_or(0.5, |m| m.predict(time))
    }

    fn predict_into(&self, times: &[f64], out: &mut [f64]) {
        match self.model() {
            Some(m) => m.predict_into(times, out),
            None => {
                assert_eq!(times.len(), out.len(), "predict_into: length mismatch");
                out.fill(0.5);
            }
        }
    }

    fn span(&self) -> ObservedSpan {
        match self {
            Learner::Online(m) => m.span(),
            Learner::Refitting(r) => r.span,
        }
    }
}

/// Whether a fitted model goes on learning online after its fit (every model but FFT FreMEn,
/// whose samples must lie on its grid, and Warped Hypertime, which refits on every batch).
fn learns_online(model: &AnyModel) -> bool {
    match model {
        AnyModel::Mean(_)
        | AnyModel::Histogram(_)
        | AnyModel::Recent(_)
        | AnyModel::Fremen(_)
        | AnyModel::Persistence(_)
        | AnyModel::Markov(_)
        | AnyModel::Pergam(_)
        | AnyModel::Stack(_) => true,
        AnyModel::Fft(_) => false,
        #[cfg(feature = "hypertime")]
        AnyModel::Hypertime(_) => false,
        AnyModel::Calendar(m) => learns_online(m.model()),
    }
}

impl Refitting {
    /// The spec as asked.
    pub fn spec(&self) -> &ModelSpec {
        &self.spec
    }

    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        self.span.validate(times, values)?;
        // The fitted model has seen no later time than the learner, so it accepts what the
        // learner accepts; it is unchanged if it refuses.
        if let Some(model) = self.model.as_mut().filter(|m| learns_online(m)) {
            model.observe(times, values)?;
        }
        self.kept.push(times, values);
        self.kept.keep_last(self.keep);
        self.span.extend(times);
        Ok(())
    }

    /// Observations taken in after the first `through` (they are the newest kept ones).
    fn after(&self, through: u64) -> u64 {
        self.span.count - through
    }

    fn install(&mut self, refit: Refit) -> Result<(), RefitError> {
        let Refit {
            spec,
            record,
            mut model,
        } = refit;
        if spec != self.spec {
            return Err(RefitError::WrongSpec {
                spec: self.spec.to_string(),
                fit: spec.to_string(),
            });
        }
        let not_this = |reason: String| Err(RefitError::NotThisLearner { reason });
        if record.through > self.span.count {
            return not_this(format!(
                "it covers {} observations, the learner has taken in {}",
                record.through, self.span.count
            ));
        }
        if let Some(current) = &self.last_fit
            && record.through < current.through
        {
            return Err(RefitError::Superseded {
                through: record.through,
                current: current.through,
            });
        }
        let after = self.after(record.through);
        if after > self.kept.len() as u64 {
            return Err(RefitError::TooLate {
                after,
                kept: self.kept.len(),
            });
        }
        // The kept observations among the first `through`: the last `keep` of them.
        let expected = record.through.min(self.keep as u64);
        if record.observations != expected {
            return not_this(format!(
                "it is of {} observations, the learner kept {expected} of the first {}",
                record.observations, record.through
            ));
        }
        let split = self.kept.len() - after as usize;
        if split > 0 && self.kept.time(split - 1) != record.last_time {
            return not_this(format!(
                "its last observation is at {} s, the learner's at {} s",
                record.last_time,
                self.kept.time(split - 1)
            ));
        }
        if !model.is_consistent() || model.span().count != record.observations {
            return Err(RefitError::Inconsistent(format!(
                "a {} model that has seen {} observations, fitted on {}",
                model.kind(),
                model.span().count,
                record.observations
            )));
        }
        if after > 0 && learns_online(&model) {
            let (times, values) = self.kept.range(split, self.kept.len());
            model
                .observe(&times, &values)
                .map_err(|e| RefitError::Inconsistent(e.to_string()))?;
        }
        self.model = Some(model);
        self.last_fit = Some(record);
        Ok(())
    }

    /// Every invariant, or the first broken one.
    fn check(&self) -> Result<(), String> {
        if self.keep == 0 {
            return Err("keeps no observation".into());
        }
        if !self.span.is_consistent() {
            return Err("inconsistent span".into());
        }
        let kept = self.kept.len();
        if kept > self.keep || kept as u64 > self.span.count {
            return Err(format!(
                "{kept} observations kept of {} seen, at most {}",
                self.span.count, self.keep
            ));
        }
        if kept as u64 != self.span.count.min(self.keep as u64) {
            return Err(format!(
                "{kept} observations kept of {} seen, keeping {}",
                self.span.count, self.keep
            ));
        }
        if kept > 0 {
            chronomap_core::observe::validate(None, &self.kept.times(), &self.kept.values())
                .map_err(|e| format!("kept observations: {e}"))?;
            let (first, last) = (self.kept.time(0), self.kept.time(kept - 1));
            if first < self.span.first || last != self.span.last {
                return Err("kept observations outside the span".into());
            }
        }
        match (&self.model, &self.last_fit) {
            (None, None) => Ok(()),
            (Some(model), Some(fit)) => {
                let online = learns_online(model);
                let seen = fit.observations + if online { self.after(fit.through) } else { 0 };
                if fit.through > self.span.count
                    || fit.observations > fit.through
                    || !model.is_consistent()
                    || model.span().count != seen
                    || (online && self.after(fit.through) > kept as u64)
                {
                    return Err("the model does not match its fit".into());
                }
                Ok(())
            }
            _ => Err("a model without a fit, or a fit without a model".into()),
        }
    }
}

impl RefitJob {
    /// How many observations the learner had taken in when the job was made.
    pub fn through(&self) -> u64 {
        self.through
    }

    /// Observations to fit on.
    pub fn observations(&self) -> usize {
        self.kept.len()
    }

    /// The spec to fit.
    pub fn spec(&self) -> &ModelSpec {
        &self.spec
    }

    /// Fits the spec on the observations ([`ModelSpec::fit`]; pure, and on
    /// `options.parallelism`): bit for bit the model `chronomap fit` makes of them with the
    /// same options.
    ///
    /// # Errors
    /// No observations kept, or the fit's errors (too few observations for its hold-out or
    /// rolling origins, data `fft` cannot fit).
    pub fn run(&self, options: &FitOptions) -> Result<Refit, BuildError> {
        if self.kept.len() == 0 {
            return Err(BuildError::NotEnoughData("no observations kept".into()));
        }
        let (times, values) = (self.kept.times(), self.kept.values());
        let fitted = self.spec.fit(&times, &values, options)?;
        Ok(Refit {
            spec: self.spec.clone(),
            record: FitRecord {
                through: self.through,
                observations: times.len() as u64,
                first_time: times[0],
                last_time: times[times.len() - 1],
                selection: fitted.selection,
            },
            model: fitted.model,
        })
    }
}

/// The fields of a serialised [`Refitting`], checked before they become one.
#[derive(Deserialize)]
struct RefittingFields {
    spec: ModelSpec,
    keep: usize,
    kept: Kept,
    span: ObservedSpan,
    model: Option<AnyModel>,
    last_fit: Option<FitRecord>,
}

impl TryFrom<RefittingFields> for Refitting {
    type Error = String;

    fn try_from(f: RefittingFields) -> Result<Self, String> {
        let learner = Refitting {
            spec: f.spec,
            keep: f.keep,
            kept: f.kept,
            span: f.span,
            model: f.model,
            last_fit: f.last_fit,
        };
        learner
            .check()
            .map_err(|e| format!("learner of `{}`: {e}", learner.spec))?;
        Ok(learner)
    }
}

/// Observations in chunks of at most [`CHUNK`], shared between copies: cloning copies one
/// pointer per chunk, observing copies at most the last chunk.
#[derive(Clone, Default)]
struct Kept {
    chunks: VecDeque<Arc<Chunk>>,
    /// Observations of the first chunk already dropped.
    skip: usize,
    len: usize,
}

#[derive(Clone, Default)]
struct Chunk {
    times: Vec<f64>,
    values: Vec<f64>,
}

impl Kept {
    fn len(&self) -> usize {
        self.len
    }

    fn push(&mut self, times: &[f64], values: &[f64]) {
        let mut at = 0;
        while at < times.len() {
            if self.chunks.back().is_none_or(|c| c.times.len() == CHUNK) {
                self.chunks.push_back(Arc::new(Chunk {
                    times: Vec::with_capacity(CHUNK),
                    values: Vec::with_capacity(CHUNK),
                }));
            }
            let last = Arc::make_mut(self.chunks.back_mut().expect("a chunk"));
            let n = (CHUNK - last.times.len()).min(times.len() - at);
            last.times.extend_from_slice(&times[at..at + n]);
            last.values.extend_from_slice(&values[at..at + n]);
            at += n;
        }
        self.len += times.len();
    }

    /// Drops the oldest observations beyond `keep`.
    fn keep_last(&mut self, keep: usize) {
        let mut excess = self.len.saturating_sub(keep);
        self.len -= excess;
        while excess > 0 {
            let first = self.chunks.front().expect("kept observations").times.len() - self.skip;
            if first <= excess {
                self.chunks.pop_front();
                self.skip = 0;
                excess -= first;
            } else {
                self.skip += excess;
                excess = 0;
            }
        }
    }

    /// The slices of the kept observations in order: (times, values).
    fn slices(&self) -> impl Iterator<Item = (&[f64], &[f64])> {
        self.chunks.iter().enumerate().map(|(i, c)| {
            let from = if i == 0 { self.skip } else { 0 };
            (&c.times[from..], &c.values[from..])
        })
    }

    fn time(&self, index: usize) -> f64 {
        let mut index = index + self.skip;
        for chunk in &self.chunks {
            if index < chunk.times.len() {
                return chunk.times[index];
            }
            index -= chunk.times.len();
        }
        panic!("kept observation out of range")
    }

    fn times(&self) -> Vec<f64> {
        self.range(0, self.len).0
    }

    fn values(&self) -> Vec<f64> {
        self.range(0, self.len).1
    }

    /// Copies of the observations `from..to`.
    fn range(&self, from: usize, to: usize) -> (Vec<f64>, Vec<f64>) {
        let mut times = Vec::with_capacity(to - from);
        let mut values = Vec::with_capacity(to - from);
        let mut start = 0;
        for (t, v) in self.slices() {
            let end = start + t.len();
            let (a, b) = (from.clamp(start, end) - start, to.clamp(start, end) - start);
            times.extend_from_slice(&t[a..b]);
            values.extend_from_slice(&v[a..b]);
            start = end;
        }
        (times, values)
    }
}

impl fmt::Debug for Kept {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Kept({} observations)", self.len)
    }
}

impl Serialize for Kept {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        struct Column<'a>(&'a Kept, bool);
        impl Serialize for Column<'_> {
            fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                use serde::ser::SerializeSeq;
                let mut seq = serializer.serialize_seq(Some(self.0.len))?;
                for (times, values) in self.0.slices() {
                    for x in if self.1 { times } else { values } {
                        seq.serialize_element(x)?;
                    }
                }
                seq.end()
            }
        }
        let mut state = serializer.serialize_struct("Kept", 2)?;
        state.serialize_field("times", &Column(self, true))?;
        state.serialize_field("values", &Column(self, false))?;
        state.end()
    }
}

impl<'de> Deserialize<'de> for Kept {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(rename = "Kept")]
        struct Columns {
            times: Vec<f64>,
            values: Vec<f64>,
        }
        let Columns { times, values } = Columns::deserialize(deserializer)?;
        if times.len() != values.len() {
            return Err(serde::de::Error::custom(format!(
                "{} kept times but {} values",
                times.len(),
                values.len()
            )));
        }
        let mut kept = Kept::default();
        kept.push(&times, &values);
        Ok(kept)
    }
}

#[cfg(test)]
mod tests;
