//! Baselines for `python/bench/bench_numpy.py`: the same Rust calls the Python methods make,
//! timed in Rust on Rust vectors, so that the benchmark prints the cost of the Python face
//! (argument conversion, GIL release, output arrays) as a ratio measured in one run.

use std::time::Instant;

use chronomap_core::TemporalModel;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::models::{PyTemporalModel, parse_spec};

/// Seconds that `predict_into` of the model takes for `times` (copied into a `Vec` first,
/// untimed), the output allocated inside the timed part as `predict` does.
#[pyfunction]
fn _rust_predict_seconds(
    py: Python<'_>,
    model: PyRef<'_, PyTemporalModel>,
    times: Vec<f64>,
) -> PyResult<f64> {
    let model = model
        .model()
        .ok_or_else(|| PyValueError::new_err("the model has observed nothing"))?;
    Ok(py.detach(|| {
        let start = Instant::now();
        let mut out = vec![0.5; times.len()];
        model.predict_into(&times, &mut out);
        let seconds = start.elapsed().as_secs_f64();
        std::hint::black_box(out);
        seconds
    }))
}

/// Seconds that building the model of `spec` and observing `(times, values)` take in Rust,
/// as the first `TemporalModel(spec).observe(times, values)` does (`ModelSpec::fit`).
#[pyfunction]
fn _rust_observe_seconds(
    py: Python<'_>,
    spec: &str,
    times: Vec<f64>,
    values: Vec<f64>,
) -> PyResult<f64> {
    let spec = parse_spec(spec)?;
    let options = crate::models::fit_options(
        "week",
        0.25,
        10,
        "brier",
        crate::models::RecentDays::default(),
    )?;
    py.detach(|| {
        let start = Instant::now();
        let model = spec
            .fit(&times, &values, &options)
            .map_err(|e| PyValueError::new_err(e.to_string()))?
            .model;
        let seconds = start.elapsed().as_secs_f64();
        std::hint::black_box(model);
        Ok(seconds)
    })
}

/// Registers this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(_rust_predict_seconds, m)?)?;
    m.add_function(wrap_pyfunction!(_rust_observe_seconds, m)?)?;
    Ok(())
}
