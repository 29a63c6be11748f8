//! The person search behavior tree ([Stüde 2024] §5.4): synthesised from a ROS map and an
//! activity model (pedestrian tracks, or a CoPA-Map), returned as BehaviorTree.CPP 4 XML, as
//! `chronomap psbt` does.

use std::path::PathBuf;

use chronomap_core::Parallelism;
use chronomap_psbt::{PsbtConfig, copa_field, synthesize};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::activity::PyCopaMap;
use crate::errors;

/// Cells at least this occupied (percent), or unknown, are obstacles (as for the command line).
const OCCUPIED_PERCENT: i8 = 50;

/// `psbt_synthesize(map, start, time, *, tracks=None, copa=None, ...)`
///
/// The person search tree for a robot at `start` (`(x, y)` in metres, map frame) needing help
/// at `time` (unix seconds): where to search and where to wait so that it most likely meets
/// someone within the horizon, every candidate scored exactly as a continuous-time Markov
/// chain (§5.2.2, eq. 5.1). The activity comes from pedestrian track files (`tracks`: paths of
/// `t,person,x,y,speed,heading` CSVs, a grid Poisson model of eq. 5.7 is learnt from them) or
/// from a fitted `CopaMap` (`copa`, queried at `model_t`; by default `time` on the ATC grid's
/// axis). The settings are those of `chronomap psbt`. Returns a dict: `tree_xml`,
/// `p_success`, `expected_time_s` (None if success is impossible), `candidates`, `places`
/// (an `(n, 2)` array), `choices` and `model_t`.
#[pyfunction]
#[pyo3(signature = (map, start, time, *, tracks = None, copa = None, cell = 1.0, interval = 3600.0,
    planning_cell = 0.5, clearance = 0.3, places = 6, seed = 0, model_t = None, model_cell = 0.5))]
#[allow(clippy::too_many_arguments)]
fn psbt_synthesize<'py>(
    py: Python<'py>,
    map: PathBuf,
    start: (f64, f64),
    time: &Bound<'py, PyAny>,
    tracks: Option<Vec<PathBuf>>,
    copa: Option<PyRef<'py, PyCopaMap>>,
    cell: f64,
    interval: f64,
    planning_cell: f64,
    clearance: f64,
    places: usize,
    seed: u64,
    model_t: Option<f64>,
    model_cell: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let time = crate::arrays::time_scalar(time, "time")?;
    let from = [start.0, start.1];
    if !(from.iter().all(|v| v.is_finite()) && time.is_finite()) {
        return Err(PyValueError::new_err(
            "start and time must be finite numbers",
        ));
    }
    let mut config = PsbtConfig::default();
    config.places = places;
    config
        .validate()
        .map_err(|e| PyValueError::new_err(format!("places: {e}")))?;
    let planning =
        chronomap_io::load_planning_grid(&map, OCCUPIED_PERCENT, planning_cell, clearance)
            .map_err(|e| match e {
                chronomap_io::PlanningMapError::Map(e) => match e.kind() {
                    chronomap_io::NavMapErrorKind::Io { io, .. } => {
                        errors::io_error(io, e.to_string())
                    }
                    _ => PyValueError::new_err(e.to_string()),
                },
                e => PyValueError::new_err(e.to_string()),
            })?;
    let (field, model_t) = match (tracks, copa) {
        (Some(tracks), None) => {
            let points = py
                .detach(|| chronomap_io::read_track_point_files(&tracks))
                .map_err(|e| errors::data(&e))?;
            let field = chronomap_psbt::world::grid_poisson_from_tracks(
                &points,
                planning.origin,
                planning.size,
                cell,
                interval,
                |_| true,
            )
            .map_err(|e| PyValueError::new_err(e.to_string()))?
            .ok_or_else(|| PyValueError::new_err("tracks: the tracks hold no detection"))?;
            (field, None)
        }
        (None, Some(copa)) => {
            let model_t = match model_t {
                Some(t) => t,
                None => chronomap_activity::atc::model_time(time).ok_or_else(|| {
                    PyValueError::new_err(format!(
                        "time {time}: outside 09:00-21:00 JST, which the ATC grid's time axis covers (give model_t)"
                    ))
                })?,
            };
            let model = copa.model();
            let field = py
                .detach(|| copa_field(model, model_cell, model_t, Parallelism::Rayon(0)))
                .map_err(|e| PyValueError::new_err(format!("copa: {e}")))?;
            (field, Some(model_t))
        }
        _ => {
            return Err(PyTypeError::new_err(
                "give the activity as tracks=[paths] or as copa=CopaMap, one of them",
            ));
        }
    };
    let plan = py
        .detach(|| {
            synthesize(
                &planning.grid,
                &field,
                from,
                time,
                &config,
                seed,
                Parallelism::Sequential,
            )
        })
        .map_err(|e| PyValueError::new_err(format!("start {},{}: {e}", from[0], from[1])))?;
    let dict = PyDict::new(py);
    dict.set_item("tree_xml", chronomap_io::psbt_xml::psbt_to_xml(&plan.tree))?;
    dict.set_item("p_success", plan.p_success)?;
    dict.set_item("expected_time_s", plan.expected_time_s)?;
    dict.set_item("candidates", plan.candidates)?;
    let flat: Vec<f64> = plan.places.iter().flatten().copied().collect();
    dict.set_item(
        "places",
        PyArray1::from_vec(py, flat).reshape([plan.places.len(), 2])?,
    )?;
    let choices = plan
        .choices
        .as_ref()
        .map(|c| c.iter().map(|c| c.name()).collect::<Vec<_>>());
    match choices {
        Some(c) => dict.set_item("choices", PyList::new(py, c)?)?,
        None => dict.set_item("choices", "wait at the start (W)")?,
    }
    dict.set_item("horizon_s", config.horizon_s)?;
    dict.set_item("model_t", model_t)?;
    Ok(dict)
}

/// Registers this module's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(psbt_synthesize, m)?)?;
    Ok(())
}
