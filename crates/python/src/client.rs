//! `chronomap.Client`: blocking calls to a running world-model service (`chronomap serve`)
//! through [`chronomap_client::blocking::Client`] (no async runtime), without the GIL while
//! waiting.
//!
//! The service's errors are `chronomap.ServiceError` (a `RuntimeError`) with its message and
//! the `status` and `kind` of the answer; no answer at all (refused, reset) is a
//! `ConnectionError`.

use chronomap_client::ClientError;
use chronomap_client::api::{ForecastRequest, ModelInfo, WriteAck};
use chronomap_client::blocking::Client;
use pyo3::exceptions::{PyConnectionError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyFloat, PyList};

use crate::arrays::{self, Times, to_numpy};

pyo3::create_exception!(
    chronomap,
    ServiceError,
    PyRuntimeError,
    "The service answered with an error: `str(e)` is its status and message (`404 Not Found: \
     no model \"door\"`), `e.status` the HTTP status (int), `e.kind` its kind (`not_found`, \
     `bad_request`, `unauthorized`, ...) and `e.reason` its message."
);

/// A client error as a Python exception.
fn client_error(py: Python<'_>, error: ClientError) -> PyErr {
    match error {
        ClientError::Api { status, body } => {
            let err = ServiceError::new_err(format!("{status}: {}", body.reason));
            let value = err.value(py);
            // Attributes for programs; a failure to set them leaves the message.
            let _ = value.setattr("status", status.as_u16());
            let _ = value.setattr("kind", body.error);
            let _ = value.setattr("reason", body.reason);
            err
        }
        ClientError::Transport(text) => PyConnectionError::new_err(text),
    }
}

/// A client of a chronomap world-model service ([Krajník 2017]: the FreMEn server's operations
/// as JSON over HTTP).
///
/// `Client(url="http://127.0.0.1:8470", token=None)`: `token` is the bearer token writes need
/// (the contents of the service's token file; `chronomap serve` prints where it is). Every
/// method blocks until the service answers and releases the GIL meanwhile. Times are float64
/// seconds (unix time), arrays go in and come out as numpy arrays.
#[pyclass(name = "Client", module = "chronomap", frozen)]
pub struct PyClient {
    client: Client,
    url: String,
}

impl PyClient {
    /// Runs `call` (a request to the service) without the GIL.
    fn block<T: Send>(
        &self,
        py: Python<'_>,
        call: impl FnOnce(&Client) -> Result<T, ClientError> + Send,
    ) -> PyResult<T> {
        py.detach(|| call(&self.client))
            .map_err(|e| client_error(py, e))
    }
}

/// The JSON text of an answer as Python objects (dicts, lists, numbers, strings).
fn from_json(py: Python<'_>, text: serde_json::Result<String>) -> PyResult<Bound<'_, PyAny>> {
    let text = text.map_err(|e| PyValueError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

fn ack<'py>(py: Python<'py>, ack: &WriteAck) -> PyResult<Bound<'py, PyAny>> {
    from_json(py, serde_json::to_string(ack))
}

fn info<'py>(py: Python<'py>, info: &ModelInfo) -> PyResult<Bound<'py, PyAny>> {
    from_json(py, serde_json::to_string(info))
}

/// Values as the service answered, shaped as the times were asked (a float or an array), or
/// a `pandas.Series` named `series` indexed by the times.
fn values_out<'py>(
    py: Python<'py>,
    times: &Times<'py>,
    values: Vec<f64>,
    series: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    if values.len() != times.as_slice().len() {
        return Err(PyValueError::new_err(format!(
            "the service answered with {} values for {} times",
            values.len(),
            times.as_slice().len()
        )));
    }
    match series {
        Some(name) => arrays::series(py, times.as_slice(), values, name),
        None if times.is_one() => Ok(PyFloat::new(py, values[0]).into_any()),
        None => Ok(to_numpy(py, values).into_any()),
    }
}

#[pymethods]
impl PyClient {
    #[new]
    #[pyo3(signature = (url = "http://127.0.0.1:8470", token = None))]
    fn py_new(url: &str, token: Option<String>) -> PyResult<Self> {
        let client = Client::new(url, token).map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(PyClient {
            client,
            url: url.trim_end_matches('/').to_owned(),
        })
    }

    /// The service's health: a dict with `status` (`ok`; a fleet node also `behind` or
    /// `failed`), `models`, `store`, `seq` (last log position applied), `auth` (whether writes
    /// need a token), and for a fleet node `fleet`, `head`, `lag` and `behind_secs`.
    fn health<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let health = self.block(py, |c| c.health())?;
        from_json(py, serde_json::to_string(&health))
    }

    /// All models: a list of dicts (`id`, `model` spec, `observations`, `first_time`,
    /// `last_time`, ...), by id.
    fn list<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let list = self.block(py, |c| c.list())?;
        from_json(py, serde_json::to_string(&list.models))
    }

    /// A model's description: a dict with `id`, `model`, `observations`, `first_time`,
    /// `last_time` and, for spectral models, `mean` and `components` (`period_secs`,
    /// `amplitude`, `phase`).
    fn view<'py>(&self, py: Python<'py>, id: &str) -> PyResult<Bound<'py, PyAny>> {
        let view = self.block(py, |c| c.view(id))?;
        info(py, &view)
    }

    /// Creates model `id` with spec `model` (`fremen:K`, `persistence:K`, `hist:N[:PERIOD]`,
    /// `pergam:K[:PERIOD]`, `stm`, `mean`); `range=(lo, hi)` for continuous values. Returns
    /// the write's acknowledgement (`observations`, `seq`), sent once it is durable.
    #[pyo3(signature = (id, model = "fremen:2", *, range = None))]
    fn create<'py>(
        &self,
        py: Python<'py>,
        id: &str,
        model: &str,
        range: Option<(f64, f64)>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let range = range.map(|(lo, hi)| [lo, hi]);
        let done = self.block(py, |c| c.create(id, Some(model), range))?;
        ack(py, &done)
    }

    /// Removes model `id`.
    fn remove<'py>(&self, py: Python<'py>, id: &str) -> PyResult<Bound<'py, PyAny>> {
        let done = self.block(py, |c| c.remove(id))?;
        ack(py, &done)
    }

    /// Adds observations to model `id`: `times` (float64 seconds, not going backwards, not
    /// before the model's last observation) and `values` (in [0, 1], 0/1 for binary states,
    /// or in the model's `range`), in one request; `model` is the spec to create the model with
    /// if it does not exist (else the service answers 404). Returns the acknowledgement
    /// (`observations` added, `seq`), sent once the observations are durable. The service
    /// checks them and names the element at fault (`ServiceError`).
    #[pyo3(signature = (id, times, values, *, model = None))]
    fn add<'py>(
        &self,
        py: Python<'py>,
        id: &str,
        times: &Bound<'py, PyAny>,
        values: &Bound<'py, PyAny>,
        model: Option<&str>,
    ) -> PyResult<Bound<'py, PyAny>> {
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
        let done = self.block(py, |c| c.add_values(id, t, v, model))?;
        ack(py, &done)
    }

    /// p(t) of model `id` at `times` (an array, or one time: seconds, `datetime64`, pandas):
    /// a float64 array, or a float; with `as_series=True` a `pandas.Series` named `p` indexed
    /// by the times (UTC). `order` predicts with another order (models with one).
    #[pyo3(signature = (id, times, *, order = None, as_series = false))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        id: &str,
        times: &Bound<'py, PyAny>,
        order: Option<usize>,
        as_series: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let times = arrays::times(times, "times")?;
        let t = times.as_slice();
        let answer = self.block(py, |c| c.predict(id, t, order))?;
        values_out(py, &times, answer.values, as_series.then_some("p"))
    }

    /// The central prediction interval of coverage `coverage` (strictly between 0 and 1,
    /// default 0.9) of model `id`, a model of continuous values (created with a `range`), at
    /// `times` (an array, or one time): `(lower, upper)` in the model's range, two float64
    /// arrays (or two floats); with `as_frame=True` a `pandas.DataFrame` with columns `time`
    /// (UTC datetimes), `lower` and `upper`. A model without intervals (binary models, `auto`
    /// before its first fit, the other models fitted on a whole series such as `fremen:auto`)
    /// is a `ValueError` naming it.
    #[pyo3(signature = (id, times, *, coverage = 0.9, order = None, as_frame = false))]
    fn interval<'py>(
        &self,
        py: Python<'py>,
        id: &str,
        times: &Bound<'py, PyAny>,
        coverage: f64,
        order: Option<usize>,
        as_frame: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        if !(coverage > 0.0 && coverage < 1.0) {
            return Err(PyValueError::new_err(format!(
                "coverage: {coverage} is not strictly between 0 and 1"
            )));
        }
        let times = arrays::times(times, "times")?;
        let t = times.as_slice();
        let answer = self.block(py, |c| c.predict_interval(id, t, order, coverage))?;
        let (Some(lower), Some(upper)) = (answer.lower, answer.upper) else {
            return Err(PyValueError::new_err(format!(
                "model {id:?} has no prediction intervals: only models of continuous values \
                 (created with a range) whose spec learns online, or `auto` once fitted, have \
                 them"
            )));
        };
        if as_frame {
            let columns = pyo3::types::PyDict::new(py);
            columns.set_item("time", to_numpy(py, t.to_vec()))?;
            columns.set_item("lower", to_numpy(py, lower))?;
            columns.set_item("upper", to_numpy(py, upper))?;
            return py
                .import("chronomap._time")?
                .call_method1("frame", (columns,));
        }
        Ok(pyo3::types::PyTuple::new(
            py,
            [
                values_out(py, &times, lower, None)?,
                values_out(py, &times, upper, None)?,
            ],
        )?
        .into_any())
    }

    /// The binary entropy (bits) of model `id`'s p(t) at `times` (an array or one time); with
    /// `as_series=True` a `pandas.Series` named `entropy`.
    #[pyo3(signature = (id, times, *, order = None, as_series = false))]
    fn entropy<'py>(
        &self,
        py: Python<'py>,
        id: &str,
        times: &Bound<'py, PyAny>,
        order: Option<usize>,
        as_series: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let times = arrays::times(times, "times")?;
        let t = times.as_slice();
        let answer = self.block(py, |c| c.entropy(id, t, order))?;
        values_out(py, &times, answer.values, as_series.then_some("entropy"))
    }

    /// p(t) of the models `ids` (a list of ids) at one `time` (seconds, `datetime`,
    /// `numpy.datetime64` or `pandas.Timestamp`): a float64 array in the order of `ids`.
    /// `order` predicts every model with that order.
    #[pyo3(signature = (ids, time, *, order = None))]
    fn forecast<'py>(
        &self,
        py: Python<'py>,
        ids: &Bound<'py, PyAny>,
        time: &Bound<'py, PyAny>,
        order: Option<usize>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let time = arrays::time_scalar(time, "time")?;
        if ids.is_instance_of::<pyo3::types::PyString>() {
            return Err(PyTypeError::new_err(
                "ids: expected a list of model ids, got one str (write [id])",
            ));
        }
        let ids: Vec<String> = ids.extract().map_err(|_| {
            PyTypeError::new_err(format!(
                "ids: expected a list of model ids (str), got {}",
                crate::arrays::type_name(ids)
            ))
        })?;
        let request = ForecastRequest {
            ids,
            time,
            order,
            orders: None,
        };
        let answer = self.block(py, |c| c.forecast(&request))?;
        Ok(to_numpy(py, answer.values).into_any())
    }

    /// Every observation model `id` holds, from the service's durable log: `(times, values)`,
    /// two float64 arrays; with `as_frame=True` a `pandas.DataFrame` with columns `time` (UTC
    /// datetimes) and `value`.
    #[pyo3(signature = (id, *, as_frame = false))]
    fn observations<'py>(
        &self,
        py: Python<'py>,
        id: &str,
        as_frame: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let answer = self.block(py, |c| c.observations(id))?;
        let (times, values) = (to_numpy(py, answer.times), to_numpy(py, answer.values));
        if as_frame {
            let columns = pyo3::types::PyDict::new(py);
            columns.set_item("time", times)?;
            columns.set_item("value", values)?;
            return py
                .import("chronomap._time")?
                .call_method1("frame", (columns,));
        }
        Ok((times, values).into_pyobject(py)?.into_any())
    }

    /// The ids of all models (a list of str).
    fn ids<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = self.block(py, |c| c.list())?;
        PyList::new(py, list.models.into_iter().map(|m| m.id))
    }

    /// The service's address.
    #[getter]
    fn url(&self) -> &str {
        &self.url
    }

    fn __repr__(&self) -> String {
        format!("<chronomap.Client {}>", self.url)
    }
}

/// Registers this module's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyClient>()?;
    m.add("ServiceError", m.py().get_type::<ServiceError>())?;
    Ok(())
}
