//! Warped Hypertime for events ([Krajník 2019] §V-D): people detected by a robot, `(t, x, y)`
//! rows, modelled as a spatio-temporal intensity over [`HypertimeEvents`].

use std::path::PathBuf;

use chronomap_hypertime::events::density::hourly_density;
use chronomap_hypertime::events::{Event, SpatialGrid, TrainingData};
use chronomap_hypertime::hypertime::Components;
use chronomap_hypertime::hypertime::events::{EventModelConfig, HypertimeEvents};
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};

use crate::arrays::{self, f64_array, f64_ndarray, shape_text, to_numpy};
use crate::errors;

/// `(N, 3)` rows of `t, x, y` as events.
fn events_arg(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<Event>> {
    let array = f64_ndarray(obj, name, 2)?;
    let readonly = array.try_readonly()?;
    let view = readonly.as_array();
    if view.shape()[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape (N, 3) (t, x, y), got {}",
            shape_text(view.shape())
        )));
    }
    Ok(view
        .rows()
        .into_iter()
        .map(|r| Event {
            t: r[0],
            x: r[1],
            y: r[2],
        })
        .collect())
}

/// The Warped Hypertime intensity of events λ(t, x, y) ([Krajník 2019] §III, §V-D): a
/// Gaussian mixture over space and the circles of the periods found in the data, divided by
/// the same mixture weighted by the time the robot observed.
#[pyclass(name = "HypertimeEvents", module = "chronomap")]
pub struct PyHypertimeEvents {
    model: HypertimeEvents,
    /// Corners of the bounding box of the observed training detections (what
    /// `chronomap hypertime` covers with its maps).
    bounds: Option<[Event; 2]>,
}

#[pymethods]
impl PyHypertimeEvents {
    /// `HypertimeEvents.fit(events, *, components="auto", gap=3600.0)`
    ///
    /// Fits the model to an `(N, 3)` array of detections `t, x, y` (unix seconds, metres) in
    /// time order, as `chronomap hypertime` does: detections further apart than `gap` seconds
    /// start a new window of observation; `components` is a number >= 1 or `"auto"`.
    #[staticmethod]
    #[pyo3(signature = (events, *, components = None, gap = 3600.0))]
    fn fit(
        py: Python<'_>,
        events: &Bound<'_, PyAny>,
        components: Option<&Bound<'_, PyAny>>,
        gap: f64,
    ) -> PyResult<Self> {
        let events = events_arg(events, "events")?;
        let components = match components {
            None => Components::Auto,
            Some(c) if c.is_instance_of::<PyString>() && c.extract::<String>()? == "auto" => {
                Components::Auto
            }
            Some(c) => match c.extract::<usize>() {
                Ok(k) if k >= 1 => Components::Fixed(k),
                _ => {
                    return Err(PyTypeError::new_err(
                        "components: expected a number >= 1 or \"auto\"",
                    ));
                }
            },
        };
        let config = EventModelConfig {
            components,
            ..EventModelConfig::default()
        };
        py.detach(|| {
            let train = TrainingData::from_events(&events, gap)
                .map_err(|e| PyValueError::new_err(format!("events: {e}")))?;
            let model = HypertimeEvents::fit(&train, &config).map_err(|e| errors::build(&e))?;
            Ok(PyHypertimeEvents {
                model,
                bounds: bounds(train.observed_events()),
            })
        })
    }

    /// The periodicities found (s).
    #[getter]
    fn periods<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_numpy(py, self.model.periods().to_vec())
    }

    /// Number of mixture components.
    #[getter]
    fn components(&self) -> usize {
        self.model.mixture().components()
    }

    /// Expected events per second over the whole plane at `times`.
    fn rate<'py>(
        &self,
        py: Python<'py>,
        times: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let times = arrays::time_array(times, "times")?;
        let t = times.as_slice();
        check_finite(t, "times")?;
        Ok(to_numpy(
            py,
            py.detach(|| t.iter().map(|&t| self.model.rate(t)).collect()),
        ))
    }

    /// The intensity λ(t, x, y) in events per m² per second, for arrays of equal length.
    fn intensity<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
        x: &Bound<'py, PyAny>,
        y: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (t, x, y) = (
            arrays::time_array(t, "t")?,
            f64_array(x, "x")?,
            f64_array(y, "y")?,
        );
        let (t, x, y) = (t.as_slice(), x.as_slice(), y.as_slice());
        if t.len() != x.len() || x.len() != y.len() {
            return Err(PyValueError::new_err(format!(
                "t, x and y differ in length ({}, {}, {})",
                t.len(),
                x.len(),
                y.len()
            )));
        }
        check_finite(t, "t")?;
        check_finite(x, "x")?;
        check_finite(y, "y")?;
        let out = py.detach(|| {
            (0..t.len())
                .map(|i| self.model.intensity(t[i], x[i], y[i]))
                .collect()
        });
        Ok(to_numpy(py, out))
    }

    /// `density(times, cell=0.25)`: expected detections per m² per hour on a grid of `cell`
    /// metres covering the training detections, at each time (what `chronomap hypertime --at`
    /// draws). A dict: `per_m2_hour` of shape `(len(times), rows, cols)` (row 0 the smallest
    /// y), `total_per_hour` per time, and the grid's `x0`, `y0` and `cell`.
    #[pyo3(signature = (times, cell = 0.25))]
    fn density<'py>(
        &self,
        py: Python<'py>,
        times: &Bound<'py, PyAny>,
        cell: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let times = arrays::time_array(times, "times")?;
        let t = times.as_slice();
        check_finite(t, "times")?;
        if !(cell.is_finite() && cell > 0.0) {
            return Err(PyValueError::new_err(format!(
                "cell: {cell} is not a positive number"
            )));
        }
        let space = self
            .bounds
            .and_then(|corners| SpatialGrid::covering(&corners, cell))
            .ok_or_else(|| PyValueError::new_err("no training detection in the plane"))?;
        let maps = py.detach(|| hourly_density(&self.model, &space, t));
        let dict = PyDict::new(py);
        let totals: Vec<f64> = maps.iter().map(|m| m.total_per_hour(&space)).collect();
        let flat: Vec<f64> = maps.into_iter().flat_map(|m| m.per_m2_hour).collect();
        let cube: Bound<'py, PyArray3<f64>> =
            PyArray1::from_vec(py, flat).reshape([t.len(), space.ny, space.nx])?;
        dict.set_item("per_m2_hour", cube)?;
        dict.set_item("total_per_hour", to_numpy(py, totals))?;
        dict.set_item("x0", space.x0)?;
        dict.set_item("y0", space.y0)?;
        dict.set_item("cell", space.cell)?;
        Ok(dict)
    }
}

/// Names the first non-finite element.
fn check_finite(values: &[f64], name: &str) -> PyResult<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(PyValueError::new_err(format!(
            "{name}[{i}]: {} is not a finite number",
            values[i]
        ))),
        None => Ok(()),
    }
}

/// The corners of the bounding box of `events` (a grid covering them covers the events).
fn bounds<'a>(events: impl Iterator<Item = &'a Event>) -> Option<[Event; 2]> {
    let mut corners: Option<[Event; 2]> = None;
    for e in events {
        let [lo, hi] = corners.get_or_insert([*e, *e]);
        lo.x = lo.x.min(e.x);
        lo.y = lo.y.min(e.y);
        hi.x = hi.x.max(e.x);
        hi.y = hi.y.max(e.y);
    }
    corners
}

/// `read_events(path) -> (N, 3) array`: an event file (`t x y ...` lines, plain, .xz or .gz).
#[pyfunction]
fn read_events(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyArray2<f64>>> {
    let events = py
        .detach(|| chronomap_io::read_events(&path))
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let flat: Vec<f64> = events.iter().flat_map(|e| [e.t, e.x, e.y]).collect();
    PyArray1::from_vec(py, flat).reshape([events.len(), 3])
}

/// Registers this module's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyHypertimeEvents>()?;
    m.add_function(wrap_pyfunction!(read_events, m)?)?;
    Ok(())
}
