//! Models by name (`fremen:4`, `hist:24`, `auto`, ...) and [`AnyModel`], the union of all
//! models that files, the command line and services pass around.
//!
//! Like RustFFT's planner, [`ModelSpec::fit`] chooses and builds a model from a description,
//! but hides nothing: every model is also constructible directly.
//!
//! | spec | model |
//! |---|---|
//! | `mean` | [`MeanModel`], long-term memory ([Santos 2017] §4.3.1) |
//! | `hist:N[:PERIOD]` | [`HistogramModel`], N bins over PERIOD s (default one week) |
//! | `recent:N[:PERIOD[:CYCLES]]` | [`RecentHistogram`], the same of the last CYCLES periods only (default 4) |
//! | `fremen:K`, `fremen:auto` | [`FremenModel`] of order K, or K chosen on held-back data |
//! | `persistence[:K\|:auto]` | [`PersistenceModel`], FreMEn + persistence ([Krajník 2017] eq. (12)–(13)) |
//! | `stm` | [`MarkovModel`], short-term memory ([Santos 2017] eq. (5)–(6)) |
//! | `pergam:K[:PERIOD]`, `pergam:auto` | [`PergamModel`], periodic Gaussian mixture ([Santos 2017] eq. (7)–(9)) |
//! | `fft:L`, `fft:auto` | [`FftFremen`], FFT FreMEn with outlier set (uniformly sampled binary data only) |
//! | `auto` | [`StackedModel`]: a weighted average of many candidates, the weights fitted by rolling-origin cross-validation ([`crate::stack`]) |

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::calendar::OnCalendar;

use chronomap_core::error::{BuildError, ConfigError, ObservationError};
use chronomap_core::fft::{FftFremen, FftFremenConfig};
use chronomap_core::fremen::{FremenConfig, FremenModel};
use chronomap_core::hist::HistogramModel;
use chronomap_core::mean::MeanModel;
use chronomap_core::model::{Ordered, TemporalModel};
use chronomap_core::observe::ObservedSpan;
use chronomap_core::par::Parallelism;
use chronomap_core::pergam::{PergamConfig, PergamModel};
use chronomap_core::periods::{DAY, PeriodSet, WEEK};
use chronomap_core::persistence::PersistenceModel;
use chronomap_core::recent::RecentHistogram;
use chronomap_core::select::{
    Criterion, OrderSelection, fit_with_order_selection, holdout_split, select_order_online,
};
use chronomap_core::stm::MarkovModel;

use crate::stack::{StackSelection, StackedModel, fit_stacked};
#[cfg(feature = "hypertime")]
use chronomap_hypertime::hypertime::{Clustering, Components, HypertimeConfig, HypertimeModel};

/// A model order: fixed, or chosen on held-back data.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum OrderSpec {
    /// This order.
    Fixed(usize),
    /// Chosen by [`chronomap_core::select`].
    Auto,
}

impl fmt::Display for OrderSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OrderSpec::Fixed(k) => write!(f, "{k}"),
            OrderSpec::Auto => f.write_str("auto"),
        }
    }
}

/// A model described by name and parameters (see the [module docs](self)).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ModelSpec {
    /// `mean`.
    Mean,
    /// `hist:N[:PERIOD]`.
    Histogram {
        /// Number of bins.
        bins: usize,
        /// Period in seconds.
        period_secs: f64,
    },
    /// `recent:N[:PERIOD[:CYCLES]]`.
    Recent {
        /// Number of bins.
        bins: usize,
        /// Period in seconds.
        period_secs: f64,
        /// Periods remembered, the current one included.
        cycles: usize,
    },
    /// `fremen:K` / `fremen:auto`.
    Fremen(OrderSpec),
    /// `persistence:K` / `persistence:auto`.
    Persistence(OrderSpec),
    /// `stm`.
    Markov,
    /// `pergam:K[:PERIOD]` / `pergam:auto`.
    Pergam {
        /// Number of components.
        components: OrderSpec,
        /// Period in seconds.
        period_secs: f64,
    },
    /// `fft:L` / `fft:auto`.
    Fft(OrderSpec),
    /// `auto`.
    Auto,
    #[cfg(feature = "hypertime")]
    /// `hyt-em:K` / `hyt-em:auto`: Warped Hypertime with EM clustering ([Krajník 2019], HyT-EM_k).
    HypertimeEm(OrderSpec),
    #[cfg(feature = "hypertime")]
    /// `hyt-km`: Warped Hypertime with k-means-initialised clustering, `k` by eq. 9 (HyT-KM).
    HypertimeKm,
}

impl fmt::Display for ModelSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ModelSpec::Mean => f.write_str("mean"),
            ModelSpec::Histogram { bins, period_secs } if *period_secs == WEEK => {
                write!(f, "hist:{bins}")
            }
            ModelSpec::Histogram { bins, period_secs } => write!(f, "hist:{bins}:{period_secs}"),
            ModelSpec::Recent {
                bins,
                period_secs,
                cycles,
            } => write!(f, "recent:{bins}:{period_secs}:{cycles}"),
            ModelSpec::Fremen(order) => write!(f, "fremen:{order}"),
            ModelSpec::Persistence(order) => write!(f, "persistence:{order}"),
            ModelSpec::Markov => f.write_str("stm"),
            ModelSpec::Pergam {
                components,
                period_secs,
            } if *period_secs == DAY => write!(f, "pergam:{components}"),
            ModelSpec::Pergam {
                components,
                period_secs,
            } => write!(f, "pergam:{components}:{period_secs}"),
            ModelSpec::Fft(order) => write!(f, "fft:{order}"),
            ModelSpec::Auto => f.write_str("auto"),
            #[cfg(feature = "hypertime")]
            ModelSpec::HypertimeEm(order) => write!(f, "hyt-em:{order}"),
            #[cfg(feature = "hypertime")]
            ModelSpec::HypertimeKm => f.write_str("hyt-km"),
        }
    }
}

const ACCEPTED: &str = "mean, hist:N[:PERIOD], recent:N[:PERIOD[:CYCLES]], fremen:K|auto, persistence[:K|auto], stm, \
                        pergam:K|auto[:PERIOD], fft:L|auto, hyt-em:K|auto, hyt-km, auto";

impl FromStr for ModelSpec {
    type Err = ConfigError;

    fn from_str(text: &str) -> Result<Self, ConfigError> {
        let error = |reason: String| ConfigError::Parse {
            what: "model",
            text: text.to_string(),
            reason: format!("{reason}; accepted: {ACCEPTED}"),
        };
        let parts: Vec<&str> = text.trim().split(':').map(str::trim).collect();
        let order = |index: usize, default: OrderSpec| -> Result<OrderSpec, ConfigError> {
            match parts.get(index) {
                None => Ok(default),
                Some(&"auto") => Ok(OrderSpec::Auto),
                Some(k) => k
                    .parse()
                    .map(OrderSpec::Fixed)
                    .map_err(|_| error(format!("order {k:?} is not a whole number or 'auto'"))),
            }
        };
        let period = |index: usize, default: f64| -> Result<f64, ConfigError> {
            match parts.get(index) {
                None => Ok(default),
                Some(p) => match p.parse::<f64>() {
                    Ok(p) if p.is_finite() && p > 0.0 => Ok(p),
                    _ => Err(error(format!(
                        "period {p:?} is not a positive number of seconds"
                    ))),
                },
            }
        };
        // The most ':'-separated fields of each model, checked before any field is parsed.
        let max_parts = match parts[0] {
            "mean" | "stm" | "auto" => 1,
            "fremen" | "persistence" | "fft" => 2,
            "hist" | "pergam" => 3,
            "recent" => 4,
            #[cfg(feature = "hypertime")]
            "hyt-km" => 1,
            #[cfg(feature = "hypertime")]
            "hyt-em" => 2,
            // Unknown, or a model of a missing feature: reported below.
            _ => usize::MAX,
        };
        if parts.len() > max_parts {
            return Err(error(format!("too many ':' fields for {}", parts[0])));
        }
        let bins = || match parts.get(1) {
            None => Ok(24),
            Some(n) => n
                .parse()
                .ok()
                .filter(|&n| (1..=chronomap_core::hist::MAX_BINS).contains(&n))
                .ok_or_else(|| error(format!("bins {n:?} is not in 1..=1048576"))),
        };
        let spec = match parts[0] {
            "mean" => ModelSpec::Mean,
            "hist" => ModelSpec::Histogram {
                bins: bins()?,
                period_secs: period(2, WEEK)?,
            },
            "recent" => {
                let bins = bins()?;
                let cycles = match parts.get(3) {
                    None => 4,
                    Some(k) => k
                        .parse()
                        .map_err(|_| error(format!("cycles {k:?} is not a whole number")))?,
                };
                let period_secs = period(2, WEEK)?;
                // The model's own limits (cycles, bins × cycles), said as a spec error.
                RecentHistogram::new(bins, period_secs, cycles)
                    .map_err(|e| error(e.to_string()))?;
                ModelSpec::Recent {
                    bins,
                    period_secs,
                    cycles,
                }
            }
            "fremen" => ModelSpec::Fremen(order(1, OrderSpec::Auto)?),
            "persistence" => ModelSpec::Persistence(order(1, OrderSpec::Auto)?),
            "stm" => ModelSpec::Markov,
            "pergam" => {
                let components = order(1, OrderSpec::Fixed(2))?;
                if let OrderSpec::Fixed(k) = components
                    && !(1..=chronomap_core::pergam::MAX_COMPONENTS).contains(&k)
                {
                    return Err(error(format!("{k} components; use 1..=16")));
                }
                ModelSpec::Pergam {
                    components,
                    period_secs: period(2, DAY)?,
                }
            }
            "fft" => ModelSpec::Fft(order(1, OrderSpec::Auto)?),
            "auto" => ModelSpec::Auto,
            #[cfg(feature = "hypertime")]
            "hyt-em" => {
                let components = order(1, OrderSpec::Auto)?;
                if components == OrderSpec::Fixed(0) {
                    return Err(error("0 components; use 1 or more, or auto".into()));
                }
                ModelSpec::HypertimeEm(components)
            }
            #[cfg(feature = "hypertime")]
            "hyt-km" => ModelSpec::HypertimeKm,
            #[cfg(not(feature = "hypertime"))]
            "hyt-em" | "hyt-km" => {
                return Err(error(
                    "Warped Hypertime models need the `hypertime` feature of chronomap-models"
                        .into(),
                ));
            }
            other => return Err(error(format!("unknown model {other:?}"))),
        };
        Ok(spec)
    }
}

/// Parses a comma-separated list of model specs.
///
/// # Errors
/// The first spec that does not parse, or an empty list.
pub fn parse_model_list(text: &str) -> Result<Vec<ModelSpec>, ConfigError> {
    let specs: Vec<ModelSpec> = text
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    if specs.is_empty() {
        return Err(ConfigError::Parse {
            what: "model list",
            text: text.to_string(),
            reason: format!("no model given; accepted: {ACCEPTED}"),
        });
    }
    Ok(specs)
}

/// Options of [`ModelSpec::fit`].
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Candidate periods of FreMEn-based models (default one week / 1..=84).
    pub periods: PeriodSet,
    /// Most recent fraction of the training time span held back to choose orders and models
    /// (default 0.25, the 75/25 chronological split of the deployed FreMEn tools).
    pub holdout: f64,
    /// Largest FreMEn order tried by `fremen:auto` and combined by `auto` (default 10).
    pub max_order: usize,
    /// Largest number of mixture components tried by `pergam:auto` (default 6).
    pub max_components: usize,
    /// How held-back predictions are scored (default Brier; `auto` always combines by Brier).
    pub criterion: Criterion,
    /// Rolling origins at which `auto` scores its candidates (default 6: 40 %, 50 %, …, 90 % of
    /// the training span; [`crate::stack::origin_fractions`]).
    pub origins: usize,
    /// Memories in days of `auto`'s drift candidates (default
    /// [`RECENT_DAYS`](crate::stack::RECENT_DAYS): 7, 14, 28, 56; empty for none).
    pub recent_days: Vec<usize>,
    /// Parallelism of the spectral accumulation (results do not depend on it).
    pub parallelism: Parallelism,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            periods: PeriodSet::default(),
            holdout: 0.25,
            max_order: 10,
            max_components: 6,
            criterion: Criterion::Brier,
            origins: 6,
            recent_days: crate::stack::RECENT_DAYS.to_vec(),
            parallelism: Parallelism::Sequential,
        }
    }
}

/// How a fitted model's order or family was chosen.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Selection {
    /// The order was chosen on held-back data.
    Order(OrderSelection),
    /// The weights of a combination, fitted on rolling origins (`auto`).
    Stack(StackSelection),
    #[cfg(feature = "hypertime")]
    /// The periodicities and components of a Warped Hypertime model, chosen on the most
    /// recent part of the training data ([Krajník 2019] §III-B).
    Hypertime {
        /// Periods found, in the order found (seconds).
        periods: Vec<f64>,
        /// Mixture components.
        components: usize,
    },
}

/// A fitted model and how it was chosen.
#[derive(Clone, Debug)]
pub struct Fitted {
    /// The model, having observed all the training data.
    pub model: AnyModel,
    /// How its order or family was chosen (`None` for fixed specs).
    pub selection: Option<Selection>,
}

impl ModelSpec {
    /// Builds the model this spec describes from training observations, choosing orders and
    /// models on held-back data where the spec says `auto`.
    ///
    /// # Errors
    /// Data violating the observation contract, too few data to hold some back, or (for
    /// `fft`) data that are not a uniformly sampled binary series.
    pub fn fit(
        &self,
        times: &[f64],
        values: &[f64],
        options: &FitOptions,
    ) -> Result<Fitted, BuildError> {
        chronomap_core::observe::validate(None, times, values)?;
        let fremen_config = |order: usize| FremenConfig {
            periods: options.periods.clone(),
            order,
            ..FremenConfig::default()
        };
        let training = Training {
            times,
            values,
            options,
        };
        let fixed = |model: AnyModel| Fitted {
            model,
            selection: None,
        };
        let fitted = match *self {
            ModelSpec::Mean => {
                let mut m = MeanModel::new();
                m.observe(times, values)?;
                fixed(AnyModel::Mean(m))
            }
            ModelSpec::Histogram { bins, period_secs } => {
                let mut m = HistogramModel::new(bins, period_secs)?;
                m.observe(times, values)?;
                fixed(AnyModel::Histogram(m))
            }
            ModelSpec::Recent {
                bins,
                period_secs,
                cycles,
            } => {
                let mut m = RecentHistogram::new(bins, period_secs, cycles)?;
                m.observe(times, values)?;
                fixed(AnyModel::Recent(m))
            }
            ModelSpec::Fremen(order) => {
                let model = FremenModel::new(fremen_config(0))?;
                training.fit_ordered(model, order, FremenModel::observe_par, AnyModel::Fremen)?
            }
            ModelSpec::Persistence(order) => {
                let model = PersistenceModel::new(fremen_config(0))?;
                training.fit_ordered(
                    model,
                    order,
                    PersistenceModel::observe_par,
                    AnyModel::Persistence,
                )?
            }
            ModelSpec::Markov => {
                let mut m = MarkovModel::new();
                m.observe(times, values)?;
                fixed(AnyModel::Markov(m))
            }
            ModelSpec::Pergam {
                components,
                period_secs,
            } => {
                let config = |k: usize| PergamConfig {
                    components: k,
                    period_secs,
                    ..PergamConfig::default()
                };
                match components {
                    OrderSpec::Fixed(k) => {
                        let mut m = PergamModel::new(config(k))?;
                        m.observe(times, values)?;
                        fixed(AnyModel::Pergam(m))
                    }
                    OrderSpec::Auto => {
                        let mut m = PergamModel::new(config(1))?;
                        let split = holdout_split(times, options.holdout)?;
                        m.observe(&times[..split], &values[..split])?;
                        // Order 0 is not a mixture; try 1..=max.
                        let mut s = select_order_online(
                            &mut m,
                            &times[split..],
                            &values[split..],
                            options.max_components,
                            options.criterion,
                        )?;
                        if s.order == 0 {
                            s.order = 1;
                            m.set_order(1);
                        }
                        Fitted {
                            model: AnyModel::Pergam(m),
                            selection: Some(Selection::Order(s)),
                        }
                    }
                }
            }
            ModelSpec::Fft(order) => fit_fft(order, times, values, options)?,
            ModelSpec::Auto => {
                let (model, selection) = fit_stacked(times, values, options)?;
                Fitted {
                    model: AnyModel::Stack(Box::new(model)),
                    selection: Some(Selection::Stack(selection)),
                }
            }
            #[cfg(feature = "hypertime")]
            ModelSpec::HypertimeEm(components) => {
                let components = match components {
                    OrderSpec::Fixed(k) => Components::Fixed(k),
                    OrderSpec::Auto => Components::Auto,
                };
                fit_hypertime(Clustering::Em(components), times, values, options)?
            }
            #[cfg(feature = "hypertime")]
            ModelSpec::HypertimeKm => fit_hypertime(Clustering::KMeans, times, values, options)?,
        };
        Ok(fitted)
    }
}

#[cfg(feature = "hypertime")]
/// A Warped Hypertime model of all the data (it chooses its periodicities, and for `Auto` its
/// components, on the most recent `options.holdout` itself).
fn fit_hypertime(
    clustering: Clustering,
    times: &[f64],
    values: &[f64],
    options: &FitOptions,
) -> Result<Fitted, BuildError> {
    let mut config = HypertimeConfig::new(clustering);
    config.holdout = options.holdout;
    let mut model = HypertimeModel::new(config)?;
    model.observe_and_fit(times, values)?;
    let selection = Selection::Hypertime {
        periods: model.periods().to_vec(),
        components: model.components(),
    };
    Ok(Fitted {
        model: AnyModel::Hypertime(Box::new(model)),
        selection: Some(selection),
    })
}

/// An `observe_par` method (of [`FremenModel`] or [`PersistenceModel`]): observes `times`,
/// `values` splitting the work as the [`Parallelism`] says.
type ObservePar<M> = fn(&mut M, &[f64], &[f64], Parallelism) -> Result<(), ObservationError>;

/// The training data of [`ModelSpec::fit`] and its options.
struct Training<'a> {
    times: &'a [f64],
    values: &'a [f64],
    options: &'a FitOptions,
}

impl Training<'_> {
    /// A model of fixed order observing everything with `observe_par` (on
    /// `options.parallelism`), or one whose order is chosen on the most recent
    /// `options.holdout` of the data.
    fn fit_ordered<M: TemporalModel + Ordered>(
        &self,
        mut model: M,
        order: OrderSpec,
        observe_par: ObservePar<M>,
        wrap: fn(M) -> AnyModel,
    ) -> Result<Fitted, BuildError> {
        let Training {
            times,
            values,
            options,
        } = self;
        Ok(match order {
            OrderSpec::Fixed(k) => {
                model.set_order(k);
                observe_par(&mut model, times, values, options.parallelism)?;
                Fitted {
                    model: wrap(model),
                    selection: None,
                }
            }
            OrderSpec::Auto => {
                let (model, selection) = fit_with_order_selection(
                    model,
                    times,
                    values,
                    options.holdout,
                    options.max_order,
                    options.criterion,
                )?;
                Fitted {
                    model: wrap(model),
                    selection: Some(Selection::Order(selection)),
                }
            }
        })
    }
}

/// `fft:L`: the data must be a uniformly sampled binary series.
fn fit_fft(
    order: OrderSpec,
    times: &[f64],
    values: &[f64],
    options: &FitOptions,
) -> Result<Fitted, BuildError> {
    let (start, step, samples) = chronomap_core::fft::uniform_binary_samples(times, values)?;
    let (order, selection) = match order {
        OrderSpec::Fixed(k) => (k, None),
        OrderSpec::Auto => {
            let (best, errors) = FftFremen::select_order(
                &samples,
                step,
                options.holdout,
                options.max_order,
                FftFremenConfig::default(),
            )?;
            let held_back =
                samples.len() - ((samples.len() as f64) * (1.0 - options.holdout)).round() as usize;
            (
                best,
                Some(Selection::Order(OrderSelection {
                    order: best,
                    errors,
                    held_back,
                })),
            )
        }
    };
    let model = FftFremen::build(start, step, &samples, FftFremenConfig::with_order(order))?;
    Ok(Fitted {
        model: AnyModel::Fft(model),
        selection,
    })
}

/// Any model of this crate: what model files store and services hold.
///
/// Variants are only ever appended (their index is part of the model file format).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub enum AnyModel {
    /// [`MeanModel`].
    Mean(MeanModel),
    /// [`HistogramModel`].
    Histogram(HistogramModel),
    /// [`FremenModel`].
    Fremen(FremenModel),
    /// [`PersistenceModel`].
    Persistence(PersistenceModel),
    /// [`MarkovModel`].
    Markov(MarkovModel),
    /// [`PergamModel`].
    Pergam(PergamModel),
    /// [`FftFremen`].
    Fft(FftFremen),
    #[cfg(feature = "hypertime")]
    /// [`HypertimeModel`].
    Hypertime(Box<HypertimeModel>),
    /// [`StackedModel`] (`auto`).
    Stack(Box<StackedModel>),
    /// A model with its calendar of days off ([`OnCalendar`]; after the others, so that their
    /// files keep their layout).
    Calendar(Box<OnCalendar>),
    /// [`RecentHistogram`] (appended after [`AnyModel::Calendar`]).
    Recent(RecentHistogram),
}

macro_rules! delegate {
    ($self:expr, $m:ident => $body:expr) => {
        match $self {
            AnyModel::Mean($m) => $body,
            AnyModel::Histogram($m) => $body,
            AnyModel::Fremen($m) => $body,
            AnyModel::Persistence($m) => $body,
            AnyModel::Markov($m) => $body,
            AnyModel::Pergam($m) => $body,
            AnyModel::Fft($m) => $body,
            #[cfg(feature = "hypertime")]
            AnyModel::Hypertime($m) => $body,
            AnyModel::Stack($m) => $body,
            AnyModel::Calendar($m) => $body,
            AnyModel::Recent($m) => $body,
        }
    };
}

impl TemporalModel for AnyModel {
    fn observe(&mut self, times: &[f64], values: &[f64]) -> Result<(), ObservationError> {
        delegate!(self, m => m.observe(times, values))
    }

    fn predict(&self, time: f64) -> f64 {
        delegate!(self, m => m.predict(time))
    }

    fn predict_into(&self, times: &[f64], out: &mut [f64]) {
        delegate!(self, m => m.predict_into(times, out))
    }

    fn span(&self) -> ObservedSpan {
        delegate!(self, m => m.span())
    }
}

impl AnyModel {
    /// Short name of the model family (the first field of its spec).
    pub fn kind(&self) -> &'static str {
        match self {
            AnyModel::Mean(_) => "mean",
            AnyModel::Histogram(_) => "hist",
            AnyModel::Fremen(_) => "fremen",
            AnyModel::Persistence(_) => "persistence",
            AnyModel::Markov(_) => "stm",
            AnyModel::Pergam(_) => "pergam",
            AnyModel::Fft(_) => "fft",
            #[cfg(feature = "hypertime")]
            AnyModel::Hypertime(m) => match m.config().clustering {
                Clustering::Em(_) => "hyt-em",
                Clustering::KMeans => "hyt-km",
            },
            AnyModel::Stack(_) => "stack",
            AnyModel::Calendar(_) => "calendar",
            AnyModel::Recent(_) => "recent",
        }
    }

    /// The spec that describes this model as it is now (orders resolved).
    pub fn spec(&self) -> ModelSpec {
        match self {
            AnyModel::Mean(_) => ModelSpec::Mean,
            AnyModel::Histogram(h) => ModelSpec::Histogram {
                bins: h.bins(),
                period_secs: h.period_secs(),
            },
            AnyModel::Fremen(m) => ModelSpec::Fremen(OrderSpec::Fixed(m.order())),
            AnyModel::Persistence(m) => ModelSpec::Persistence(OrderSpec::Fixed(m.order())),
            AnyModel::Markov(_) => ModelSpec::Markov,
            AnyModel::Pergam(m) => ModelSpec::Pergam {
                components: OrderSpec::Fixed(m.order()),
                period_secs: m.config().period_secs,
            },
            AnyModel::Fft(m) => ModelSpec::Fft(OrderSpec::Fixed(m.order())),
            #[cfg(feature = "hypertime")]
            AnyModel::Hypertime(m) => match m.config().clustering {
                Clustering::Em(_) => {
                    ModelSpec::HypertimeEm(OrderSpec::Fixed(m.components().max(1)))
                }
                Clustering::KMeans => ModelSpec::HypertimeKm,
            },
            // What `auto` fits; its members and weights: [`AnyModel::Stack`].
            AnyModel::Stack(_) => ModelSpec::Auto,
            // The calendar is not part of a spec: the model of the working days is.
            AnyModel::Calendar(m) => m.model().spec(),
            AnyModel::Recent(h) => ModelSpec::Recent {
                bins: h.bins(),
                period_secs: h.period_secs(),
                cycles: h.cycles(),
            },
        }
    }

    /// What a spec was fitted as, for tables: the resolved spec (`fremen:10` for
    /// `fremen:auto`), or for `auto` the number of models it combines (`stack of 7`).
    pub fn fitted_as(&self) -> String {
        match self {
            AnyModel::Stack(stack) => format!("stack of {}", stack.members().count()),
            AnyModel::Calendar(m) => format!(
                "{} on a calendar of {} days off",
                m.model().fitted_as(),
                m.days_off().len()
            ),
            other => other.spec().to_string(),
        }
    }

    /// The order, for models that have one.
    pub fn order(&self) -> Option<usize> {
        match self {
            AnyModel::Fremen(m) => Some(m.order()),
            AnyModel::Persistence(m) => Some(m.order()),
            AnyModel::Pergam(m) => Some(m.order()),
            AnyModel::Fft(m) => Some(m.order()),
            AnyModel::Calendar(m) => m.model().order(),
            _ => None,
        }
    }

    /// Changes the order of models that have one; returns whether it did.
    pub fn set_order(&mut self, order: usize) -> bool {
        match self {
            AnyModel::Fremen(m) => m.set_order(order),
            AnyModel::Persistence(m) => m.set_order(order),
            AnyModel::Pergam(m) => m.set_order(order.max(1)),
            AnyModel::Fft(m) => m.set_order(order),
            AnyModel::Calendar(m) => return m.model_mut().set_order(order),
            _ => return false,
        }
        true
    }

    /// Checks internal invariants (for models read from files, which may have been written by
    /// other versions or by hand).
    pub fn is_consistent(&self) -> bool {
        match self {
            AnyModel::Mean(m) => m.is_consistent(),
            AnyModel::Markov(m) => m.is_consistent(),
            AnyModel::Histogram(m) => m.is_consistent(),
            AnyModel::Fremen(m) => m.is_consistent(),
            AnyModel::Persistence(m) => m.is_consistent(),
            AnyModel::Pergam(m) => m.is_consistent(),
            AnyModel::Fft(m) => m.is_consistent(),
            #[cfg(feature = "hypertime")]
            AnyModel::Hypertime(m) => m.is_consistent(),
            AnyModel::Stack(m) => m.is_consistent(),
            AnyModel::Calendar(m) => m.is_consistent(),
            AnyModel::Recent(m) => m.is_consistent(),
        }
    }
}

/// Why a spec cannot learn online ([`ModelSpec::online_model`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OnlineError {
    /// An order or number of components chosen on held-back data (`fremen:auto`, ...).
    #[error(
        "`{spec}`: learning online needs a fixed {what}; choose one offline (`chronomap eval`, \
         or the error per order of the service's `evaluate`)"
    )]
    AutoOrder {
        /// The spec as written.
        spec: String,
        /// `"order"` or `"number of components"`.
        what: &'static str,
    },
    /// A model fitted on a whole series (`auto`, `fft`, hypertime).
    #[error(
        "`{spec}` is fitted offline on a whole series (`chronomap fit`); models that learn online \
         are fremen:K, persistence:K, hist:N[:PERIOD], recent:N[:PERIOD[:CYCLES]], pergam:K[:PERIOD], \
         stm, mean"
    )]
    Offline {
        /// The spec as written.
        spec: String,
    },
    /// An order above the largest the model's periods allow (it would be clamped silently).
    #[error("`{spec}`: order {order} is above the largest order {max}")]
    OrderTooLarge {
        /// The spec as written.
        spec: String,
        /// The order asked for.
        order: usize,
        /// The largest order.
        max: usize,
    },
    /// The model's parameters are invalid.
    #[error("`{spec}`: {source}")]
    Config {
        /// The spec as written.
        spec: String,
        /// Why.
        source: ConfigError,
    },
}

impl ModelSpec {
    /// The model this spec describes having seen nothing, for learning online: observation by
    /// observation, where every chunking gives the model a single batch would (the service and
    /// the ROS 2 node learn this way). FreMEn-family orders use the default periods (one week
    /// / 1..=84), as [`FitOptions::default`] does.
    ///
    /// # Errors
    /// Orders chosen on held-back data (`fremen:auto`), models fitted offline on a whole series
    /// (`auto`, `fft`, hypertime), and orders above the largest one.
    pub fn online_model(&self) -> Result<AnyModel, OnlineError> {
        let spec = || self.to_string();
        let fixed = |order: &OrderSpec, what: &'static str| match order {
            OrderSpec::Fixed(k) => Ok(*k),
            OrderSpec::Auto => Err(OnlineError::AutoOrder { spec: spec(), what }),
        };
        let config = |source: ConfigError| OnlineError::Config {
            spec: spec(),
            source,
        };
        let model = match self {
            ModelSpec::Mean => AnyModel::Mean(MeanModel::new()),
            ModelSpec::Histogram { bins, period_secs } => {
                AnyModel::Histogram(HistogramModel::new(*bins, *period_secs).map_err(config)?)
            }
            ModelSpec::Recent {
                bins,
                period_secs,
                cycles,
            } => AnyModel::Recent(
                RecentHistogram::new(*bins, *period_secs, *cycles).map_err(config)?,
            ),
            ModelSpec::Fremen(order) => AnyModel::Fremen(
                FremenModel::new(FremenConfig::with_order(fixed(order, "order")?))
                    .map_err(config)?,
            ),
            ModelSpec::Persistence(order) => AnyModel::Persistence(
                PersistenceModel::new(FremenConfig::with_order(fixed(order, "order")?))
                    .map_err(config)?,
            ),
            ModelSpec::Markov => AnyModel::Markov(MarkovModel::new()),
            ModelSpec::Pergam {
                components,
                period_secs,
            } => AnyModel::Pergam(
                PergamModel::new(PergamConfig {
                    components: fixed(components, "number of components")?,
                    period_secs: *period_secs,
                    ..PergamConfig::default()
                })
                .map_err(config)?,
            ),
            _ => return Err(OnlineError::Offline { spec: spec() }),
        };
        // A too-large order would silently be clamped; say so instead (the original FreMEn
        // server refused orders above its number of periodicities too).
        let max = match &model {
            AnyModel::Fremen(m) => Some(m.max_order()),
            AnyModel::Persistence(m) => Some(m.max_order()),
            _ => None,
        };
        if let (
            Some(max),
            ModelSpec::Fremen(OrderSpec::Fixed(k)) | ModelSpec::Persistence(OrderSpec::Fixed(k)),
        ) = (max, self)
            && (*k > max || model.order() != Some(*k))
        {
            return Err(OnlineError::OrderTooLarge {
                spec: spec(),
                order: *k,
                max,
            });
        }
        Ok(model)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn online_models_are_empty_and_offline_specs_are_refused_by_name() {
        let door: ModelSpec = "fremen:2".parse().unwrap();
        let model = door.online_model().unwrap();
        assert_eq!(model.spec(), door);
        assert_eq!(model.span().count, 0);
        assert_eq!(model.predict(0.0), 0.5);
        for (text, part) in [
            ("fremen:auto", "needs a fixed order"),
            ("pergam:auto", "needs a fixed number of components"),
            ("auto", "fitted offline"),
            ("fft:3", "fitted offline"),
            ("fremen:85", "order 85 is above the largest order 84"),
        ] {
            let spec: ModelSpec = text.parse().unwrap();
            let error = spec.online_model().unwrap_err().to_string();
            assert!(
                error.contains(part) && error.contains(text),
                "{text}: {error}"
            );
        }
    }

    #[test]
    fn specs_round_trip_through_text() {
        for text in [
            "mean",
            "hist:24",
            "hist:48:86400",
            "recent:24:86400:14",
            "fremen:4",
            "fremen:auto",
            "persistence:2",
            "persistence:auto",
            "stm",
            "pergam:2",
            "pergam:auto",
            "pergam:3:604800",
            "fft:5",
            "fft:auto",
            "auto",
        ] {
            let spec: ModelSpec = text.parse().unwrap();
            assert_eq!(spec.to_string(), text);
        }
        assert_eq!(
            "fremen".parse::<ModelSpec>().unwrap(),
            ModelSpec::Fremen(OrderSpec::Auto)
        );
        assert_eq!(parse_model_list("mean, fremen:2").unwrap().len(), 2);
    }

    #[test]
    fn bad_specs_say_what_is_accepted() {
        for text in [
            "",
            "fremen:x",
            "hist:0",
            "pergam:40",
            "mean:3",
            "hist:24:-5",
            "recent:24:86400:0",
            "recent:1:86400:4097",
            "recent:1024:86400:2048",
            "recent:24:86400:7:1",
            "nope",
        ] {
            let err = text.parse::<ModelSpec>().unwrap_err().to_string();
            assert!(err.contains("accepted: mean"), "{text}: {err}");
        }
        assert!(parse_model_list(" , ").is_err());
    }

    #[test]
    fn fft_spec_refuses_irregular_data() {
        let times = [0.0, 60.0, 120.0, 200.0];
        let err = ModelSpec::Fft(OrderSpec::Fixed(1))
            .fit(&times, &[0.0, 1.0, 1.0, 0.0], &FitOptions::default())
            .unwrap_err();
        assert!(matches!(
            err,
            BuildError::Observation(ObservationError::OffGrid { index: 3, .. })
        ));
    }
}
