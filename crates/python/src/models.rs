//! Temporal models: `chronomap.model("fremen:auto")`, the typed classes (`Fremen`, `Mean`, ...),
//! `chronomap.load`, `chronomap.evaluate` and anomaly detection, over
//! [`chronomap_models::ModelSpec`] and [`chronomap_models::AnyModel`].

use std::path::PathBuf;

use chronomap_core::anomaly::detect_anomalies;
use chronomap_core::calendar::DaysOff;
use chronomap_core::periods::{DAY, PeriodSet, WEEK};
use chronomap_core::select::Criterion;
use chronomap_core::{ObservationError, Parallelism, TemporalModel, binary_entropy};
use chronomap_models::eval::{TestSet, evaluate_on_calendar};
use chronomap_models::spec::{OrderSpec, Selection};
use chronomap_models::stack::{MAX_RECENT_DAYS, RECENT_DAYS};
use chronomap_models::{AnyModel, FitOptions, ModelSpec};
use numpy::PyArray1;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyDict, PyFloat, PyList, PyString};

use crate::arrays::{self, ArrayPair, to_numpy};
use crate::errors;

/// The `recent_days` argument: memories in days of `auto`'s drift candidates (the command
/// line's `--recent-days`). A sequence of whole days from 1 to 3650 (a list, tuple, range or
/// integer array); `None` or an empty sequence for no drift candidates; by default
/// [`RECENT_DAYS`] (7, 14, 28, 56). Anything else is a `ValueError` naming `recent_days`.
#[derive(Clone, Debug, PartialEq)]
pub struct RecentDays(pub Vec<usize>);

impl Default for RecentDays {
    fn default() -> Self {
        RecentDays(RECENT_DAYS.to_vec())
    }
}

impl<'a, 'py> FromPyObject<'a, 'py> for RecentDays {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        if obj.is_none() {
            return Ok(RecentDays(Vec::new()));
        }
        let not_a_sequence = || {
            PyValueError::new_err(format!(
                "recent_days: expected a sequence of whole days from 1 to {MAX_RECENT_DAYS} \
                 (e.g. [7, 14]) or None, got {}",
                crate::arrays::type_name(&obj)
            ))
        };
        // A string is a sequence too, of characters: `"7,14"` is the command line's form.
        if obj.is_instance_of::<PyString>() || obj.is_instance_of::<PyBytes>() {
            return Err(not_a_sequence());
        }
        let items = obj.try_iter().map_err(|_| not_a_sequence())?;
        let mut days = Vec::new();
        for (index, item) in items.enumerate() {
            let item = item?;
            // Booleans are ints to Python, floats (7.0, nan) and strings are not days.
            let whole = if item.is_instance_of::<PyBool>() {
                None
            } else {
                item.extract::<i64>().ok()
            };
            match whole.and_then(|d| usize::try_from(d).ok()) {
                Some(d) if (1..=MAX_RECENT_DAYS).contains(&d) => days.push(d),
                _ => {
                    let shown = item
                        .repr()
                        .map(|r| r.to_string())
                        .unwrap_or_else(|_| "?".into());
                    return Err(PyValueError::new_err(format!(
                        "recent_days[{index}]: {shown} ({}) is not a whole number of days \
                         from 1 to {MAX_RECENT_DAYS}",
                        crate::arrays::type_name(&item)
                    )));
                }
            }
        }
        Ok(RecentDays(days))
    }
}

/// Settings of how models choose orders and families (the command line's `--periods`,
/// `--holdout`, `--max-order`, `--criterion` and `--recent-days`).
pub fn fit_options(
    periods: &str,
    holdout: f64,
    max_order: usize,
    criterion: &str,
    recent_days: RecentDays,
) -> PyResult<FitOptions> {
    let periods: PeriodSet = periods
        .parse()
        .map_err(|e| errors::config(&e).with_prefix("periods"))?;
    if !(holdout > 0.0 && holdout < 1.0) {
        return Err(PyValueError::new_err(format!(
            "holdout: {holdout} is not a fraction in (0, 1)"
        )));
    }
    let criterion = match criterion {
        "brier" => Criterion::Brier,
        "absolute" => Criterion::AbsoluteError,
        "binary" => Criterion::BinaryError,
        other => {
            return Err(PyValueError::new_err(format!(
                "criterion: '{other}' is not one of 'brier', 'absolute', 'binary'"
            )));
        }
    };
    Ok(FitOptions {
        periods,
        holdout,
        max_order,
        criterion,
        recent_days: recent_days.0,
        parallelism: Parallelism::Rayon(0),
        ..FitOptions::default()
    })
}

/// Adds `prefix: ` to a `ValueError`'s message.
trait WithPrefix {
    fn with_prefix(self, prefix: &str) -> PyErr;
}

impl WithPrefix for PyErr {
    fn with_prefix(self, prefix: &str) -> PyErr {
        Python::attach(|py| PyValueError::new_err(format!("{prefix}: {}", self.value(py))))
    }
}

/// A model spec from its text (`fremen:auto`, `hist:24`, ...).
pub fn parse_spec(text: &str) -> PyResult<ModelSpec> {
    text.parse::<ModelSpec>().map_err(|e| errors::config(&e))
}

/// Checks that prediction times are finite and not negative (as the command line's `predict`
/// does for its time files), naming the first that is not.
fn check_prediction_times(times: &[f64]) -> PyResult<()> {
    // A branch-free scan first: almost every call is fine.
    if times.iter().all(|t| t.is_finite() && *t >= 0.0) {
        return Ok(());
    }
    for (index, &time) in times.iter().enumerate() {
        let error = if !time.is_finite() {
            ObservationError::NonFiniteTime { index, time }
        } else if time < 0.0 {
            ObservationError::NegativeTime { index, time }
        } else {
            continue;
        };
        return Err(PyValueError::new_err(format!("times[{index}]: {error}")));
    }
    Ok(())
}

/// A model of one state over time ([Krajník 2017], [Santos 2017], [Krajník 2019]): it learns
/// from observations made at irregular times and predicts p(t), the probability that the
/// state is 1 (or its expected value for states in [0, 1]) at any time.
///
/// Create one with `chronomap.model(spec)` or a typed class (`Fremen(order=2)`, `Mean()`, ...);
/// the first `observe` fits it (choosing orders or families where the spec says `auto`, on
/// the most recent part of that batch, exactly as `chronomap fit` does), later ones add to it.
#[pyclass(name = "TemporalModel", module = "chronomap", subclass)]
pub struct PyTemporalModel {
    /// The spec as requested.
    spec: ModelSpec,
    options: FitOptions,
    /// The model; `None` only for specs that choose on data and have seen none.
    model: Option<AnyModel>,
    selection: Option<Selection>,
}

impl PyTemporalModel {
    fn new(spec: ModelSpec, options: FitOptions) -> PyResult<Self> {
        let chooses = matches!(
            spec,
            ModelSpec::Auto
                | ModelSpec::Fremen(OrderSpec::Auto)
                | ModelSpec::Persistence(OrderSpec::Auto)
                | ModelSpec::Fft(_)
                | ModelSpec::HypertimeEm(_)
                | ModelSpec::HypertimeKm
                | ModelSpec::Pergam {
                    components: OrderSpec::Auto,
                    ..
                }
        );
        let model = if chooses {
            None
        } else {
            // A fixed spec is a model with no observations (it predicts 0.5).
            Some(
                spec.fit(&[], &[], &options)
                    .map_err(|e| errors::build(&e))?
                    .model,
            )
        };
        Ok(PyTemporalModel {
            spec,
            options,
            model,
            selection: None,
        })
    }

    /// The model as the Python class of its family (`fremen` → `Fremen`, ...): the family of
    /// the fitted model if there is one, else of the spec (`auto` has none: `TemporalModel`).
    pub fn into_typed(self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let family = match &self.model {
            Some(model) => Some(model.kind()),
            None => spec_family(&self.spec),
        };
        let init = PyClassInitializer::from(self);
        let object = match family {
            Some("mean") => Py::new(py, init.add_subclass(PyMean))?.into_any(),
            Some("hist") => Py::new(py, init.add_subclass(PyHist))?.into_any(),
            Some("fremen") => Py::new(py, init.add_subclass(PyFremen))?.into_any(),
            Some("persistence") => Py::new(py, init.add_subclass(PyPersistence))?.into_any(),
            Some("stm") => Py::new(py, init.add_subclass(PyStm))?.into_any(),
            Some("pergam") => Py::new(py, init.add_subclass(PyPergam))?.into_any(),
            Some("fft") => Py::new(py, init.add_subclass(PyFft))?.into_any(),
            Some("hyt-em" | "hyt-km") => Py::new(py, init.add_subclass(PyHypertime))?.into_any(),
            _ => Py::new(py, init)?.into_any(),
        };
        Ok(object)
    }

    /// The model, for other parts of the bindings (e.g. grids and services).
    pub fn model(&self) -> Option<&AnyModel> {
        self.model.as_ref()
    }

    fn fitted_or_err(&self, what: &str) -> PyResult<&AnyModel> {
        self.model.as_ref().ok_or_else(|| {
            PyValueError::new_err(format!(
                "cannot {what}: the {} model has observed nothing yet (it chooses its order or family on its first observe)",
                self.spec
            ))
        })
    }
}

/// Predictions of `model` (0.5 for a model that has seen nothing) at `times`, without the GIL:
/// a float for one time, an array for an array, a `pandas.Series` named `name` if `as_series`.
fn predict_array<'py>(
    py: Python<'py>,
    model: Option<&AnyModel>,
    times: &Bound<'py, PyAny>,
    map: Option<fn(f64) -> f64>,
    as_series: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    let times = arrays::times(times, "times")?;
    let one = times.is_one();
    let times = times.as_slice();
    check_prediction_times(times)?;
    let predict = || {
        let mut out = vec![0.5; times.len()];
        if let Some(m) = model {
            m.predict_into(times, &mut out);
        }
        if let Some(f) = map {
            out.iter_mut().for_each(|p| *p = f(*p));
        }
        out
    };
    let out = if one { predict() } else { py.detach(predict) };
    match as_series {
        Some(name) => arrays::series(py, times, out, name),
        None if one => Ok(PyFloat::new(py, out[0]).into_any()),
        None => Ok(to_numpy(py, out).into_any()),
    }
}

#[pymethods]
impl PyTemporalModel {
    /// `TemporalModel(spec, *, periods="week", holdout=0.25, max_order=10, criterion="brier",
    /// recent_days=(7, 14, 28, 56))`
    ///
    /// A model described by its spec, the names `chronomap fit --model` accepts: `mean`,
    /// `hist:N[:PERIOD]`, `recent:N[:PERIOD[:CYCLES]]`, `fremen:K`, `fremen:auto`,
    /// `persistence[:K|:auto]`, `stm`, `pergam:K[:PERIOD]`, `fft:L`, `hyt-em:K`, `hyt-km`,
    /// `auto`. `recent_days`: memories in days of `auto`'s drift candidates (`--recent-days`;
    /// `None` for none).
    #[new]
    #[pyo3(signature = (spec, *, periods = "week", holdout = 0.25, max_order = 10, criterion = "brier", recent_days = RecentDays::default()))]
    fn py_new(
        spec: &str,
        periods: &str,
        holdout: f64,
        max_order: usize,
        criterion: &str,
        recent_days: RecentDays,
    ) -> PyResult<Self> {
        PyTemporalModel::new(
            parse_spec(spec)?,
            fit_options(periods, holdout, max_order, criterion, recent_days)?,
        )
    }

    /// Adds observations: `times` in seconds (unix time, float64, never going backwards) and
    /// `values` in [0, 1] (0/1 for binary states). A rejected batch leaves the model as it was;
    /// the `ValueError` names the observation (`observation 4 (times[3]): ...`).
    ///
    /// Contiguous float64 arrays are read in place, without a copy; the work runs without
    /// the GIL. Returns the model, so that calls chain.
    fn observe<'py>(
        mut slf: PyRefMut<'py, Self>,
        times: &Bound<'py, PyAny>,
        values: &Bound<'py, PyAny>,
    ) -> PyResult<PyRefMut<'py, Self>> {
        let py = slf.py();
        let times = arrays::time_array(times, "times")?;
        let values = arrays::value_array(values, "values")?;
        let (t, v) = (times.as_slice(), values.as_slice());
        if t.len() != v.len() {
            return Err(PyValueError::new_err(format!(
                "{} times but {} values",
                t.len(),
                v.len()
            )));
        }
        let this = &mut *slf;
        match &mut this.model {
            // The first batch is fitted as `chronomap fit` fits its training file (orders
            // chosen, spectra accumulated in parallel); later batches are added.
            Some(model) if model.span().count > 0 => py
                .detach(|| model.observe(t, v))
                .map_err(|e| errors::observation(&e))?,
            _ => {
                let fitted = py
                    .detach(|| this.spec.fit(t, v, &this.options))
                    .map_err(|e| errors::build(&e))?;
                this.model = Some(fitted.model);
                this.selection = fitted.selection;
            }
        }
        Ok(slf)
    }

    /// p(t) at `times` (an array, or one time): a float64 array of the same length, or a
    /// float; with `as_series=True` a `pandas.Series` named `p` indexed by the times (a UTC
    /// `DatetimeIndex` named `time`). A model that has seen nothing predicts 0.5.
    #[pyo3(signature = (times, *, as_series = false))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        times: &Bound<'py, PyAny>,
        as_series: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let name = as_series.then_some("p");
        predict_array(py, self.model.as_ref(), times, None, name)
    }

    /// Binary entropy of p(t) in bits at `times`: how uncertain the state is then (1 at p = 0.5).
    /// `as_series=True`: a `pandas.Series` named `entropy`, as for `predict`.
    #[pyo3(signature = (times, *, as_series = false))]
    fn entropy<'py>(
        &self,
        py: Python<'py>,
        times: &Bound<'py, PyAny>,
        as_series: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let name = as_series.then_some("entropy");
        predict_array(py, self.model.as_ref(), times, Some(binary_entropy), name)
    }

    /// Observations that contradict a confident prediction ([Krajník 2017] §V, eq. (9)): state
    /// 0 while p(t) >= `confidence`, or 1 while p(t) < 1 - `confidence`. A dict of arrays
    /// `index`, `time`, `observed`, `p` (what `chronomap anomalies` prints); with
    /// `as_frame=True` a `pandas.DataFrame` of those columns, `time` as UTC datetimes.
    #[pyo3(signature = (times, values, confidence = 0.99, *, as_frame = false))]
    fn anomalies<'py>(
        &self,
        py: Python<'py>,
        times: &Bound<'py, PyAny>,
        values: &Bound<'py, PyAny>,
        confidence: f64,
        as_frame: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let model = self.fitted_or_err("detect anomalies")?;
        let times = arrays::time_array(times, "times")?;
        let values = arrays::value_array(values, "values")?;
        let (t, v) = (times.as_slice(), values.as_slice());
        if t.len() != v.len() {
            return Err(PyValueError::new_err(format!(
                "{} times but {} values",
                t.len(),
                v.len()
            )));
        }
        chronomap_core::observe::validate(None, t, v).map_err(|e| errors::observation(&e))?;
        let found = py
            .detach(|| detect_anomalies(model, t, v, confidence))
            .map_err(|e| errors::config(&e).with_prefix("confidence"))?;
        let dict = PyDict::new(py);
        let index: Vec<i64> = found.iter().map(|a| a.index as i64).collect();
        dict.set_item("index", PyArray1::from_vec(py, index))?;
        dict.set_item("time", to_numpy(py, found.iter().map(|a| a.time).collect()))?;
        dict.set_item(
            "observed",
            to_numpy(py, found.iter().map(|a| a.observed).collect()),
        )?;
        dict.set_item(
            "p",
            to_numpy(py, found.iter().map(|a| a.predicted).collect()),
        )?;
        if as_frame {
            return py.import("chronomap._time")?.call_method1("frame", (dict,));
        }
        Ok(dict.into_any())
    }

    /// Writes the model to `path` in chronomap's model file format (versioned, checksummed,
    /// written atomically): the file `chronomap fit -o` writes and `chronomap predict` reads.
    fn save(&self, path: PathBuf) -> PyResult<()> {
        let model = self.fitted_or_err("save")?;
        chronomap_io::write_any_model(&path, model).map_err(|e| errors::model_file(&e))
    }

    /// The model file's bytes (what `save` writes): for sending a model elsewhere, e.g. to
    /// `chronomap.loads` in another process. Pickling uses them too.
    fn to_bytes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let model = self.fitted_or_err("encode")?;
        let bytes =
            chronomap_io::encode_model(model.kind(), model).map_err(|e| errors::model_file(&e))?;
        Ok(PyBytes::new(py, &bytes))
    }

    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyBytes>,))> {
        let loads = py.import("chronomap._native")?.getattr("loads")?;
        Ok((loads, (self.to_bytes(py)?,)))
    }

    /// The spec as requested (`fremen:auto`).
    #[getter]
    fn spec(&self) -> String {
        self.spec.to_string()
    }

    /// The spec of the model as fitted, orders resolved (`fremen:2`); None before an `auto`
    /// spec has observed anything.
    #[getter]
    fn fitted(&self) -> Option<String> {
        self.model.as_ref().map(|m| m.spec().to_string())
    }

    /// The model family (`fremen`, `hist`, ...), None before an `auto` spec has observed.
    #[getter]
    fn kind(&self) -> Option<&'static str> {
        self.model.as_ref().map(AnyModel::kind)
    }

    /// The order (FreMEn components, mixture components), for models that have one. Setting
    /// it changes the predictions without re-observing (`chronomap predict --order`).
    #[getter]
    fn get_order(&self) -> Option<usize> {
        self.model.as_ref().and_then(AnyModel::order)
    }

    #[setter]
    fn set_order(&mut self, order: usize) -> PyResult<()> {
        let model = self.fitted_or_err("set the order")?;
        let kind = model.kind();
        let model = self.model.as_mut().expect("checked above");
        if model.set_order(order) {
            Ok(())
        } else {
            Err(PyTypeError::new_err(format!(
                "a {kind} model has no order to change"
            )))
        }
    }

    /// Number of observations seen.
    #[getter]
    fn observations(&self) -> u64 {
        self.model.as_ref().map_or(0, |m| m.span().count)
    }

    /// `(first, last)` time observed, or None.
    #[getter]
    fn span(&self) -> Option<(f64, f64)> {
        let span = self.model.as_ref()?.span();
        (span.count > 0).then_some((span.first, span.last))
    }

    /// How the order or family was chosen on held-back training data (a dict, as in
    /// `chronomap fit --json`), or None for fixed specs.
    #[getter]
    fn selection<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let Some(selection) = &self.selection else {
            return Ok(None);
        };
        let text =
            serde_json::to_string(selection).map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(Some(py.import("json")?.call_method1("loads", (text,))?))
    }

    /// The model's components as a dict of float64 arrays:
    ///
    /// * FreMEn, persistence: `period` (s), `amplitude` (|γ|; the cosine's amplitude is 2|γ|)
    ///   and `phase` (rad), so that p(t) = mean + Σ 2|γ| cos(2πt/period + phase) before
    ///   saturation ([Krajník 2017] eq. (2)); `mean` is an array of one;
    /// * FFT FreMEn: `period`, `amplitude` (|X|/N), `phase`;
    /// * PerGaM: `weight`, `mean` (s into the period) and `sigma` (s);
    /// * Warped Hypertime: `period` (the periodicities found);
    /// * `auto` (a weighted average of models): `weight` and `model` (their specs);
    /// * mean, histogram, stm: an empty dict.
    #[getter]
    fn components<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        let Some(model) = &self.model else {
            return Ok(dict);
        };
        let fremen = |m: &chronomap_core::FremenModel| -> PyResult<()> {
            let c = m.components();
            dict.set_item(
                "period",
                to_numpy(py, c.iter().map(|c| c.period_secs).collect()),
            )?;
            dict.set_item(
                "amplitude",
                to_numpy(py, c.iter().map(|c| c.amplitude).collect()),
            )?;
            dict.set_item("phase", to_numpy(py, c.iter().map(|c| c.phase).collect()))?;
            dict.set_item("mean", to_numpy(py, vec![m.fit().mean]))?;
            Ok(())
        };
        // A model with a calendar of days off: the components of its model of working days.
        let model = match model {
            AnyModel::Calendar(c) => c.model(),
            other => other,
        };
        match model {
            AnyModel::Fremen(m) => fremen(m)?,
            AnyModel::Persistence(m) => fremen(m.fremen())?,
            AnyModel::Fft(m) => {
                let c = m.components();
                dict.set_item(
                    "period",
                    to_numpy(py, c.iter().map(|c| m.period_of_bin(c.bin)).collect()),
                )?;
                dict.set_item(
                    "amplitude",
                    to_numpy(py, c.iter().map(|c| c.amplitude).collect()),
                )?;
                dict.set_item("phase", to_numpy(py, c.iter().map(|c| c.phase).collect()))?;
            }
            AnyModel::Pergam(m) => {
                let c = &m.fit().components;
                dict.set_item("weight", to_numpy(py, c.iter().map(|c| c.weight).collect()))?;
                dict.set_item(
                    "mean",
                    to_numpy(py, c.iter().map(|c| c.mean_secs).collect()),
                )?;
                dict.set_item(
                    "sigma",
                    to_numpy(py, c.iter().map(|c| c.sigma_secs).collect()),
                )?;
            }
            AnyModel::Hypertime(m) => {
                dict.set_item("period", to_numpy(py, m.periods().to_vec()))?;
            }
            AnyModel::Stack(m) => {
                dict.set_item(
                    "weight",
                    to_numpy(py, m.members().map(|(_, w)| w).collect()),
                )?;
                let specs: Vec<String> = m.members().map(|(m, _)| m.spec().to_string()).collect();
                dict.set_item("model", specs)?;
            }
            AnyModel::Mean(_)
            | AnyModel::Histogram(_)
            | AnyModel::Recent(_)
            | AnyModel::Markov(_)
            | AnyModel::Calendar(_) => {}
        }
        Ok(dict)
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let class = slf.get_type().name()?.to_string();
        let this = slf.borrow();
        Ok(match &this.model {
            Some(m) => format!(
                "{class}(spec={:?}, fitted={:?}, observations={})",
                this.spec.to_string(),
                m.spec().to_string(),
                m.span().count
            ),
            None => format!("{class}(spec={:?}, observations=0)", this.spec.to_string()),
        })
    }
}

/// Builds a typed model from a spec and the fit settings.
fn typed(spec: ModelSpec, options: FitOptions) -> PyResult<PyClassInitializer<PyTemporalModel>> {
    Ok(PyClassInitializer::from(PyTemporalModel::new(
        spec, options,
    )?))
}

/// A model of the FreMEn family from the arguments its Python constructor takes.
fn ordered(
    spec: fn(OrderSpec) -> ModelSpec,
    order: Option<&Bound<'_, PyAny>>,
    periods: &str,
    holdout: f64,
    max_order: usize,
    criterion: &str,
) -> PyResult<PyClassInitializer<PyTemporalModel>> {
    let order = order.map_or(Ok(OrderSpec::Auto), |o| order_spec(o, "order"))?;
    typed(
        spec(order),
        fit_options(
            periods,
            holdout,
            max_order,
            criterion,
            RecentDays::default(),
        )?,
    )
}

/// An order argument: an int or the string "auto".
fn order_spec(order: &Bound<'_, PyAny>, name: &str) -> PyResult<OrderSpec> {
    if order.is_instance_of::<PyString>() {
        let text: String = order.extract()?;
        return if text == "auto" {
            Ok(OrderSpec::Auto)
        } else {
            Err(PyValueError::new_err(format!(
                "{name}: '{text}' is neither a number nor \"auto\""
            )))
        };
    }
    let k: i64 = order.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name}: expected an int or \"auto\", got {}",
            crate::arrays::type_name(order)
        ))
    })?;
    usize::try_from(k)
        .map(OrderSpec::Fixed)
        .map_err(|_| PyValueError::new_err(format!("{name}: {k} is negative")))
}

macro_rules! typed_model {
    ($rust:ident, $python:literal, $doc:literal) => {
        #[doc = $doc]
        #[pyclass(name = $python, module = "chronomap", extends = PyTemporalModel)]
        pub struct $rust;
    };
}

typed_model!(
    PyMean,
    "Mean",
    "Long-term memory: the mean of all observations ([Santos 2017] §4.3.1)."
);
typed_model!(
    PyHist,
    "Hist",
    "Histogram: the mean per bin of a period ([Santos 2017] §4.3.2)."
);
typed_model!(
    PyFremen,
    "Fremen",
    "Frequency Map Enhancement ([Krajník 2017] eq. (1)-(3)): the mean plus the `order` strongest periodic components."
);
typed_model!(
    PyPersistence,
    "Persistence",
    "FreMEn with persistence ([Krajník 2017] eq. (12)-(13)): recent observations weigh more for a while."
);
typed_model!(
    PyStm,
    "Stm",
    "Short-term memory: a two-state Markov chain ([Santos 2017] eq. (5)-(6))."
);
typed_model!(
    PyPergam,
    "PerGaM",
    "Periodic Gaussian mixture ([Santos 2017] eq. (7)-(9))."
);
typed_model!(
    PyFft,
    "Fft",
    "FFT FreMEn with an outlier set (uniformly sampled binary series only)."
);
typed_model!(
    PyHypertime,
    "Hypertime",
    "Warped Hypertime ([Krajník 2019]): a mixture over time projected onto circles of the periods found."
);

#[pymethods]
impl PyMean {
    #[new]
    fn new() -> PyResult<PyClassInitializer<Self>> {
        Ok(typed(ModelSpec::Mean, FitOptions::default())?.add_subclass(PyMean))
    }
}

#[pymethods]
impl PyHist {
    /// `Hist(bins=24, period=604800.0)`: `bins` bins over `period` seconds.
    #[new]
    #[pyo3(signature = (bins = 24, period = WEEK))]
    fn new(bins: usize, period: f64) -> PyResult<PyClassInitializer<Self>> {
        let spec = ModelSpec::Histogram {
            bins,
            period_secs: period,
        };
        Ok(typed(spec, FitOptions::default())?.add_subclass(PyHist))
    }
}

#[pymethods]
impl PyFremen {
    /// `Fremen(order="auto", *, periods="week", holdout=0.25, max_order=10, criterion="brier")`:
    /// `order` periodic components, or the order chosen on the most recent `holdout` of the
    /// first batch observed.
    #[new]
    #[pyo3(signature = (order = None, *, periods = "week", holdout = 0.25, max_order = 10, criterion = "brier"))]
    fn new(
        order: Option<&Bound<'_, PyAny>>,
        periods: &str,
        holdout: f64,
        max_order: usize,
        criterion: &str,
    ) -> PyResult<PyClassInitializer<Self>> {
        Ok(ordered(
            ModelSpec::Fremen,
            order,
            periods,
            holdout,
            max_order,
            criterion,
        )?
        .add_subclass(PyFremen))
    }
}

#[pymethods]
impl PyPersistence {
    /// `Persistence(order="auto", *, periods="week", holdout=0.25, max_order=10, criterion="brier")`.
    #[new]
    #[pyo3(signature = (order = None, *, periods = "week", holdout = 0.25, max_order = 10, criterion = "brier"))]
    fn new(
        order: Option<&Bound<'_, PyAny>>,
        periods: &str,
        holdout: f64,
        max_order: usize,
        criterion: &str,
    ) -> PyResult<PyClassInitializer<Self>> {
        Ok(ordered(
            ModelSpec::Persistence,
            order,
            periods,
            holdout,
            max_order,
            criterion,
        )?
        .add_subclass(PyPersistence))
    }
}

#[pymethods]
impl PyStm {
    #[new]
    fn new() -> PyResult<PyClassInitializer<Self>> {
        Ok(typed(ModelSpec::Markov, FitOptions::default())?.add_subclass(PyStm))
    }
}

#[pymethods]
impl PyPergam {
    /// `PerGaM(components="auto", period=86400.0, *, holdout=0.25)`.
    #[new]
    #[pyo3(signature = (components = None, period = DAY, *, holdout = 0.25))]
    fn new(
        components: Option<&Bound<'_, PyAny>>,
        period: f64,
        holdout: f64,
    ) -> PyResult<PyClassInitializer<Self>> {
        let components = components.map_or(Ok(OrderSpec::Auto), |o| order_spec(o, "components"))?;
        let spec = ModelSpec::Pergam {
            components,
            period_secs: period,
        };
        let options = fit_options("week", holdout, 10, "brier", RecentDays::default())?;
        Ok(typed(spec, options)?.add_subclass(PyPergam))
    }
}

#[pymethods]
impl PyFft {
    /// `Fft(order="auto")`: for uniformly sampled binary series.
    #[new]
    #[pyo3(signature = (order = None))]
    fn new(order: Option<&Bound<'_, PyAny>>) -> PyResult<PyClassInitializer<Self>> {
        let order = order.map_or(Ok(OrderSpec::Auto), |o| order_spec(o, "order"))?;
        Ok(typed(ModelSpec::Fft(order), FitOptions::default())?.add_subclass(PyFft))
    }
}

#[pymethods]
impl PyHypertime {
    /// `Hypertime(components="auto", clustering="em")`: Warped Hypertime with EM clustering
    /// of `components` components (HyT-EM), or `clustering="kmeans"` (HyT-KM, `components`
    /// by eq. 9).
    #[new]
    #[pyo3(signature = (components = None, clustering = "em"))]
    fn new(
        components: Option<&Bound<'_, PyAny>>,
        clustering: &str,
    ) -> PyResult<PyClassInitializer<Self>> {
        let spec = match clustering {
            "em" => ModelSpec::HypertimeEm(
                components.map_or(Ok(OrderSpec::Auto), |o| order_spec(o, "components"))?,
            ),
            "kmeans" => ModelSpec::HypertimeKm,
            other => {
                return Err(PyValueError::new_err(format!(
                    "clustering: '{other}' is not 'em' or 'kmeans'"
                )));
            }
        };
        Ok(typed(spec, FitOptions::default())?.add_subclass(PyHypertime))
    }
}

/// The family of the models a spec builds (the kind of [`AnyModel::kind`]); `None` for `auto`.
fn spec_family(spec: &ModelSpec) -> Option<&'static str> {
    Some(match spec {
        ModelSpec::Mean => "mean",
        ModelSpec::Histogram { .. } => "hist",
        ModelSpec::Recent { .. } => "recent",
        ModelSpec::Fremen(_) => "fremen",
        ModelSpec::Persistence(_) => "persistence",
        ModelSpec::Markov => "stm",
        ModelSpec::Pergam { .. } => "pergam",
        ModelSpec::Fft(_) => "fft",
        ModelSpec::HypertimeEm(_) => "hyt-em",
        ModelSpec::HypertimeKm => "hyt-km",
        ModelSpec::Auto => return None,
    })
}

/// `model(spec, **settings)`: the model a spec describes, as the class of its family
/// (`TemporalModel` for `auto`, whose family is chosen on the data). The settings are
/// `TemporalModel`'s: `periods`, `holdout`, `max_order`, `criterion`, `recent_days`.
#[pyfunction]
#[pyo3(signature = (spec, *, periods = "week", holdout = 0.25, max_order = 10, criterion = "brier", recent_days = RecentDays::default()))]
pub fn model(
    py: Python<'_>,
    spec: &str,
    periods: &str,
    holdout: f64,
    max_order: usize,
    criterion: &str,
    recent_days: RecentDays,
) -> PyResult<Py<PyAny>> {
    let options = fit_options(periods, holdout, max_order, criterion, recent_days)?;
    let model = PyTemporalModel::new(parse_spec(spec)?, options)?;
    // An `auto` model stays a `TemporalModel` even after it has chosen a family.
    if model.spec == ModelSpec::Auto {
        return Ok(Py::new(py, model)?.into_any());
    }
    model.into_typed(py)
}

/// `load(path)`: a model file written by `chronomap fit` or `TemporalModel.save`, checked (version, checksum, invariants), as its typed class.
#[pyfunction]
pub fn load(py: Python<'_>, path: PathBuf) -> PyResult<Py<PyAny>> {
    let model = chronomap_io::read_any_model(&path).map_err(|e| errors::model_file(&e))?;
    PyTemporalModel {
        spec: model.spec(),
        options: FitOptions::default(),
        model: Some(model),
        selection: None,
    }
    .into_typed(py)
}

/// `loads(data)`: a model from the bytes of a model file (`TemporalModel.to_bytes`, or a
/// file's content), checked like `load`.
#[pyfunction]
pub fn loads(py: Python<'_>, data: &[u8]) -> PyResult<Py<PyAny>> {
    let model = chronomap_io::decode_any_model(data).map_err(|e| errors::model_file(&e))?;
    PyTemporalModel {
        spec: model.spec(),
        options: FitOptions::default(),
        model: Some(model),
        selection: None,
    }
    .into_typed(py)
}

/// A `(times, values)` pair of float64 arrays from Python.
fn series_arg<'py>(
    pair: &Bound<'py, PyAny>,
    name: &str,
) -> PyResult<(crate::arrays::F64Array<'py>, crate::arrays::F64Array<'py>)> {
    let (times, values): (Bound<'py, PyAny>, Bound<'py, PyAny>) = pair.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name}: expected a (times, values) pair of arrays, got {}",
            crate::arrays::type_name(pair)
        ))
    })?;
    let times = arrays::time_array(&times, &format!("{name} times"))?;
    let values = arrays::value_array(&values, &format!("{name} values"))?;
    if times.as_slice().len() != values.as_slice().len() {
        return Err(PyValueError::new_err(format!(
            "{name}: {} times but {} values",
            times.as_slice().len(),
            values.as_slice().len()
        )));
    }
    Ok((times, values))
}

/// The experiment of `chronomap eval` (the FreMEn benchmarks): every model fitted on `train`
/// and scored on every test set. Returns the columns of the command line's tables.
#[pyfunction]
#[pyo3(signature = (train, tests, models, *, periods = "week", holdout = 0.25, max_order = 10, criterion = "brier", recent_days = RecentDays::default(), days_off = None))]
#[allow(clippy::too_many_arguments)]
pub fn evaluate_table<'py>(
    py: Python<'py>,
    train: &Bound<'py, PyAny>,
    tests: &Bound<'py, PyAny>,
    models: Vec<String>,
    periods: &str,
    holdout: f64,
    max_order: usize,
    criterion: &str,
    recent_days: RecentDays,
    days_off: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let days_off = match days_off {
        Some(path) => py
            .detach(|| chronomap_io::read_days_off(&path))
            .map_err(|e| errors::data(&e))?,
        None => DaysOff::default(),
    };
    let specs: Vec<ModelSpec> = models
        .iter()
        .map(|m| parse_spec(m))
        .collect::<PyResult<_>>()?;
    if specs.is_empty() {
        return Err(PyValueError::new_err("models: no model given"));
    }
    let options = fit_options(periods, holdout, max_order, criterion, recent_days)?;
    let (train_t, train_v) = series_arg(train, "train")?;
    let tests: Vec<Bound<'py, PyAny>> = tests.try_iter()?.collect::<PyResult<_>>()?;
    if tests.is_empty() {
        return Err(PyValueError::new_err("tests: no test set given"));
    }
    let test_arrays = tests
        .iter()
        .enumerate()
        .map(|(i, t)| series_arg(t, &format!("tests[{i}]")))
        .collect::<PyResult<Vec<_>>>()?;
    let sets: Vec<TestSet<'_>> = test_arrays
        .iter()
        .map(|(t, v)| TestSet {
            times: t.as_slice(),
            values: v.as_slice(),
        })
        .collect();
    let (t, v) = (train_t.as_slice(), train_v.as_slice());
    let report = py
        .detach(|| evaluate_on_calendar(&specs, t, v, &sets, &options, &days_off, |_| {}))
        .map_err(|(spec, e)| match e.observation_index() {
            Some(i) => PyValueError::new_err(format!(
                "model {spec}: training observation {} (train times[{i}]): {e}",
                i + 1
            )),
            None => PyValueError::new_err(format!("model {spec}: {e}")),
        })?;
    let dict = PyDict::new(py);
    let column = |f: &dyn Fn(&chronomap_models::eval::ModelEvaluation) -> f64| {
        to_numpy(py, report.models.iter().map(f).collect())
    };
    dict.set_item(
        "model",
        PyList::new(py, report.models.iter().map(|m| m.spec.to_string()))?,
    )?;
    dict.set_item(
        "fitted",
        PyList::new(py, report.models.iter().map(|m| m.fitted.model.fitted_as()))?,
    )?;
    for i in 0..sets.len() {
        dict.set_item(format!("mse_{}", i + 1), column(&|m| m.tests[i].mse))?;
    }
    dict.set_item("mean_mse", column(&|m| m.mean_mse()))?;
    for i in 0..sets.len() {
        dict.set_item(
            format!("binary_error_{}", i + 1),
            column(&|m| m.tests[i].binary_error),
        )?;
    }
    dict.set_item("mean_binary_error", column(&|m| m.mean_binary_error()))?;
    for i in 0..sets.len() {
        dict.set_item(format!("ece_{}", i + 1), column(&|m| m.calibration[i].ece))?;
    }
    dict.set_item("mean_ece", column(&|m| m.mean_ece()))?;
    dict.set_item("ece", column(&|m| m.pooled_calibration.ece))?;
    dict.set_item("reliability", column(&|m| m.pooled_calibration.reliability))?;
    dict.set_item("resolution", column(&|m| m.pooled_calibration.resolution))?;
    dict.set_item("uncertainty", column(&|m| m.pooled_calibration.uncertainty))?;
    dict.set_item("within_bins", column(&|m| m.pooled_calibration.within_bin))?;
    dict.set_item(
        "mean_prediction",
        column(&|m| m.pooled_calibration.mean_prediction),
    )?;
    dict.set_item("base_rate", column(&|m| m.pooled_calibration.base_rate))?;
    Ok(dict)
}

/// `read_pairs(path)`: a "time value" file (plain, .xz or .gz) as `(times, values)` arrays,
/// checked as `chronomap fit` checks its training file.
#[pyfunction]
pub fn read_pairs(py: Python<'_>, path: PathBuf) -> PyResult<ArrayPair<'_>> {
    let series = py
        .detach(|| chronomap_io::read_pairs(&path))
        .map_err(|e| errors::data(&e))?;
    Ok((to_numpy(py, series.times), to_numpy(py, series.values)))
}

/// `read_test_set(times_path, values_path)`: a FreMEn test set (two line-aligned files).
#[pyfunction]
pub fn read_test_set(
    py: Python<'_>,
    times_path: PathBuf,
    values_path: PathBuf,
) -> PyResult<ArrayPair<'_>> {
    let series = py
        .detach(|| chronomap_io::read_test_set(&times_path, &values_path))
        .map_err(|e| errors::data(&e))?;
    Ok((to_numpy(py, series.times), to_numpy(py, series.values)))
}

/// Registers this module's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyTemporalModel>()?;
    m.add_class::<PyMean>()?;
    m.add_class::<PyHist>()?;
    m.add_class::<PyFremen>()?;
    m.add_class::<PyPersistence>()?;
    m.add_class::<PyStm>()?;
    m.add_class::<PyPergam>()?;
    m.add_class::<PyFft>()?;
    m.add_class::<PyHypertime>()?;
    m.add_function(wrap_pyfunction!(model, m)?)?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(loads, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate_table, m)?)?;
    m.add_function(wrap_pyfunction!(read_pairs, m)?)?;
    m.add_function(wrap_pyfunction!(read_test_set, m)?)?;
    Ok(())
}
