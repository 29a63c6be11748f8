//! CoPA-Map ([Stüde 2024] §4.2): the rate of people over space and time as a heteroscedastic
//! sparse variational Gaussian process, fitted on numpy arrays of `(x, t, y)` samples and
//! queried for the mean and standard deviation of the rate, over [`chronomap_activity::CopaMap`].

use std::path::PathBuf;

use chronomap_activity::{CopaConfig, CopaMap, RateSamples, RateScale};
use chronomap_core::Parallelism;
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyFloat, PyInt};

use crate::arrays::{ArrayPair, f64_array, f64_ndarray, shape_text, to_numpy};
use crate::errors;

/// `(N, 2)` positions as pairs.
fn points_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<[f64; 2]>> {
    let array = f64_ndarray(obj, name, 2)?;
    let readonly = array.try_readonly()?;
    let view = readonly.as_array();
    if view.shape()[1] != 2 {
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape (N, 2) (x1, x2 in metres), got {}",
            shape_text(view.shape())
        )));
    }
    Ok(view.rows().into_iter().map(|r| [r[0], r[1]]).collect())
}

/// A fitted CoPA-Map: the rate of people (per hour of observation, the units of the training
/// samples) at any place and time, with its uncertainty.
///
/// Fit with `CopaMap.fit(x, t, y)` or read a model `chronomap activity fit -o` wrote with
/// `chronomap.load_copa_map(path)`.
#[pyclass(name = "CopaMap", module = "chronomap")]
pub struct PyCopaMap {
    model: CopaMap,
}

impl PyCopaMap {
    /// The fitted model.
    pub fn model(&self) -> &CopaMap {
        &self.model
    }
}

#[pymethods]
impl PyCopaMap {
    /// `CopaMap.fit(x, t, y, *, inducing=200, iterations=300, period=12.0, scale="rate", seed=0)`
    ///
    /// Fits CoPA-Map to rate samples: `x` an `(N, 2)` array of cell centres (m), `t` the `N`
    /// times (in the units of `period`, the day's length: the ATC grid uses hours 0..12), `y`
    /// the `N` rates (>= 0). The settings are those of `chronomap activity fit`; the fit runs
    /// without the GIL (about a minute with the defaults on two cores) and is not interruptible.
    #[staticmethod]
    #[pyo3(signature = (x, t, y, *, inducing = 200, iterations = 300, period = 12.0, scale = "rate", seed = 0))]
    #[allow(clippy::too_many_arguments)]
    fn fit(
        py: Python<'_>,
        x: &Bound<'_, PyAny>,
        t: &Bound<'_, PyAny>,
        y: &Bound<'_, PyAny>,
        inducing: usize,
        iterations: usize,
        period: f64,
        scale: &str,
        seed: u64,
    ) -> PyResult<Self> {
        let x = points_arg(x, "x")?;
        let t = f64_array(t, "t")?.as_slice().to_vec();
        let y = f64_array(y, "y")?.as_slice().to_vec();
        let samples =
            RateSamples::new(x, t, y).map_err(|e| PyValueError::new_err(e.to_string()))?;
        if !(period.is_finite() && period > 0.0) {
            return Err(PyValueError::new_err(format!(
                "period: {period} is not a positive number"
            )));
        }
        let target = match scale {
            "rate" => RateScale::Rate,
            "log1p" => RateScale::Log1p,
            other => {
                return Err(PyValueError::new_err(format!(
                    "scale: '{other}' is not 'rate' or 'log1p'"
                )));
            }
        };
        let config = CopaConfig {
            inducing,
            iterations,
            day_period: period,
            seed,
            parallelism: Parallelism::Rayon(0),
            target,
            ..CopaConfig::default()
        };
        let model = py
            .detach(|| CopaMap::fit(&samples, &config))
            .map_err(|e| PyValueError::new_err(format!("CoPA-Map: {e}")))?;
        Ok(PyCopaMap { model })
    }

    /// `predict(x, t) -> (mean, std)`: the predicted rate and its standard deviation at the
    /// `(M, 2)` positions `x`, at one time `t` (a number) or at `M` times (an array).
    fn predict<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        t: &Bound<'py, PyAny>,
    ) -> PyResult<ArrayPair<'py>> {
        let x = points_arg(x, "x")?;
        let times: Vec<f64> = if t.is_instance_of::<PyFloat>() || t.is_instance_of::<PyInt>() {
            vec![t.extract::<f64>()?; x.len()]
        } else {
            let t = f64_array(t, "t")?;
            if t.as_slice().len() != x.len() {
                return Err(PyValueError::new_err(format!(
                    "{} positions but {} times",
                    x.len(),
                    t.as_slice().len()
                )));
            }
            t.as_slice().to_vec()
        };
        if let Some(i) = times.iter().position(|t| !t.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "t[{i}]: time {} is not a finite number",
                times[i]
            )));
        }
        let points: Vec<([f64; 2], f64)> = x.into_iter().zip(times).collect();
        let (mean, std) = py
            .detach(|| self.model.predict_with_std(&points, Parallelism::Rayon(0)))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok((to_numpy(py, mean), to_numpy(py, std)))
    }

    /// The periods of the temporal kernel (units of t), as fitted.
    #[getter]
    fn periods<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_numpy(py, self.model.periods())
    }

    /// The training domain `[x1_min, x2_min, x1_max, x2_max]` (cell centres, m).
    #[getter]
    fn domain(&self) -> [f64; 4] {
        self.model.domain()
    }

    /// The ELBO after each iteration of the fit.
    #[getter]
    fn trace<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_numpy(py, self.model.trace.clone())
    }

    /// Writes the model in the file format of `chronomap activity fit -o` (kind `copa-map`).
    fn save(&self, path: PathBuf) -> PyResult<()> {
        chronomap_io::write_copa_map(&path, &self.model).map_err(|e| errors::model_file(&e))
    }

    fn __repr__(&self) -> String {
        format!("CopaMap(periods={:?})", self.model.periods())
    }
}

/// `load_copa_map(path)`: a CoPA-Map model file (`chronomap activity fit -o`), checked.
#[pyfunction]
fn load_copa_map(path: PathBuf) -> PyResult<PyCopaMap> {
    let model = chronomap_io::read_copa_map(&path).map_err(|e| errors::model_file(&e))?;
    Ok(PyCopaMap { model })
}

/// `read_rate_samples(path) -> (x, t, y)`: a CoPA-Map `x1,x2,t,y` CSV file (plain, .xz or
/// .gz, as bundled in `data/atc_copa_map_grid/`): `x` as an `(N, 2)` array.
#[pyfunction]
#[allow(clippy::type_complexity)]
fn read_rate_samples(
    py: Python<'_>,
    path: PathBuf,
) -> PyResult<(
    Bound<'_, PyArray2<f64>>,
    Bound<'_, PyArray1<f64>>,
    Bound<'_, PyArray1<f64>>,
)> {
    let samples = py
        .detach(|| chronomap_io::read_rate_samples(&path))
        .map_err(|e| errors::data(&e))?;
    let flat: Vec<f64> = samples.x().iter().flatten().copied().collect();
    let x = PyArray1::from_vec(py, flat).reshape([samples.len(), 2])?;
    Ok((
        x,
        to_numpy(py, samples.t().to_vec()),
        to_numpy(py, samples.y().to_vec()),
    ))
}

/// Registers this module's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyCopaMap>()?;
    m.add_function(wrap_pyfunction!(load_copa_map, m)?)?;
    m.add_function(wrap_pyfunction!(read_rate_samples, m)?)?;
    Ok(())
}
