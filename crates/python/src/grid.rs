//! Spatio-temporal occupancy grids ([Krajník 2017] §III-C, §VI, §VIII): `chronomap.Grid` over
//! [`chronomap_grid::FremenGrid`] and the grid files of [`chronomap_io::grid_file`], and
//! `chronomap.read_map` over the Nav2 / ROS map reader of [`chronomap_io::navmap`].
//!
//! Frames are `(T, H, W)` int8 arrays in the `nav_msgs/OccupancyGrid` convention: −1 unknown,
//! 0..=100 occupancy in percent, `frames[t, y, x]` with row `y = 0` at the bottom (the row at
//! the map's origin), so `frames[t].ravel()` is the message's `data`.

use std::path::{Path, PathBuf};

use chronomap_app::grid::{BuildSettings, FrameSource, GridJobError, build_grid};
use chronomap_core::periods::PeriodSet;
use chronomap_core::progress::NoProgress;
use chronomap_core::{FremenConfig, ObservationError};
use chronomap_grid::{AnyGrid, GridStore};
use chronomap_grid::{FittedGrid, FremenGrid, GridConfig, GridError, GridGeometry, OrderChoice};
use chronomap_io::navmap::{LoadSemantics, NavMapError, NavMapErrorKind, load_map};
use chronomap_io::{FrameMapError, read_grid_file, write_grid_file};
use chronomap_spatial::OccupancyMap;
use numpy::{PyArray1, PyArrayDescrMethods, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::arrays::{self, shape_text, type_name};
use crate::errors;

/// A map-file error as the matching Python exception (`FileNotFoundError` for a missing YAML
/// or image file, `ValueError` for a malformed one), with the reader's message.
fn nav_map_error(error: &NavMapError, message: String) -> PyErr {
    match error.kind() {
        NavMapErrorKind::Io { io, .. } | NavMapErrorKind::ImageUnreadable { io, .. } => {
            errors::io_error(io, message)
        }
        _ => PyValueError::new_err(message),
    }
}

/// A frame-list map error (naming the list, line and map file) as a Python exception.
fn frame_map_error(error: &FrameMapError) -> PyErr {
    match error {
        FrameMapError::Map { error: inner, .. } => nav_map_error(inner, error.to_string()),
        other => PyValueError::new_err(other.to_string()),
    }
}

/// A grid error as a `ValueError`.
fn grid_error(error: &GridError) -> PyErr {
    PyValueError::new_err(error.to_string())
}

/// An error of the grid build job of a frame list: a missing list or map is a
/// `FileNotFoundError`, anything else a `ValueError`; both name the list and its line.
fn grid_job_error(error: &GridJobError) -> PyErr {
    match error {
        GridJobError::Data(e) => errors::data(e),
        GridJobError::FrameMap(e) => frame_map_error(e),
        GridJobError::Grid(e) => grid_error(e),
        GridJobError::Frame { source, .. } => PyValueError::new_err(format!("{error}: {source}")),
        other => PyValueError::new_err(other.to_string()),
    }
}

/// The grid configuration of `chronomap grid build --periods P --order K`.
fn grid_config(periods: &str, order: usize, keep_history: bool) -> PyResult<GridConfig> {
    let periods: PeriodSet = periods
        .parse()
        .map_err(|e| PyValueError::new_err(format!("periods: {e}")))?;
    Ok(GridConfig {
        fremen: FremenConfig {
            periods,
            order,
            ..FremenConfig::default()
        },
        keep_history,
    })
}

/// `frames` as a C-contiguous int8 numpy array of shape `(T, H, W)`: int8 arrays are read in
/// place; other integer (and boolean) arrays are converted when every value is −1..=100; floats
/// are a `TypeError`, another number of dimensions a `ValueError`.
fn int8_frames<'py>(frames: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyUntypedArray>> {
    let py = frames.py();
    let numpy = py.import("numpy")?;
    let array = match frames.cast::<PyUntypedArray>() {
        Ok(a) => a.clone(),
        Err(_) => numpy
            .call_method1("asarray", (frames,))
            .and_then(|a| Ok(a.cast_into::<PyUntypedArray>()?))
            .map_err(|_| {
                PyTypeError::new_err(format!(
                    "frames: expected an int8 array of shape (T, H, W), got {}",
                    type_name(frames)
                ))
            })?,
    };
    let dtype = array.dtype();
    let is_int8 = dtype.is_equiv_to(&numpy::dtype::<i8>(py));
    if !is_int8 && !matches!(dtype.kind(), b'i' | b'u' | b'b') {
        return Err(PyTypeError::new_err(format!(
            "frames: expected integer occupancies (int8: -1 unknown, 0..100), got dtype {}",
            dtype.str()?
        )));
    }
    if array.ndim() != 3 {
        return Err(PyValueError::new_err(format!(
            "frames: expected a 3-D array (T, H, W) of occupancies, got shape {}",
            shape_text(array.shape())
        )));
    }
    // Values that int8 cannot hold would wrap: name the first of them.
    if !is_int8 && array.len() > 0 {
        {
            let as_int = array.call_method1("astype", ("int64",))?;
            let bad = numpy.call_method1(
                "logical_or",
                (
                    numpy.call_method1("less", (&as_int, -1))?,
                    numpy.call_method1("greater", (&as_int, 100))?,
                ),
            )?;
            if bad.call_method0("any")?.is_truthy()? {
                let at: Vec<usize> = numpy
                    .call_method1("argwhere", (&bad,))?
                    .get_item(0)?
                    .call_method0("tolist")?
                    .extract()?;
                let value: i64 = as_int.get_item((at[0], at[1], at[2]))?.extract()?;
                return Err(PyValueError::new_err(format!(
                    "frames[{}, {}, {}]: occupancy {value} is not -1 (unknown) or 0..=100",
                    at[0], at[1], at[2]
                )));
            }
        }
    }
    if is_int8 && array.is_c_contiguous() {
        return Ok(array);
    }
    Ok(numpy
        .call_method1("ascontiguousarray", (&array, "int8"))?
        .cast_into::<PyUntypedArray>()?)
}

/// The error of frame `f` as Python names it: times by `times[f]`, cells by `frames[f, y, x]`.
fn frame_error(error: &GridError, f: usize, geometry: &GridGeometry) -> PyErr {
    match error {
        GridError::Observation(
            e @ (ObservationError::NonFiniteTime { .. }
            | ObservationError::NegativeTime { .. }
            | ObservationError::TimeNotIncreasing { .. }),
        ) => PyValueError::new_err(format!("frame {} (times[{f}]): {e}", f + 1)),
        GridError::CellValue { cell, value } => {
            let (w, h) = (geometry.width as usize, geometry.height as usize);
            let (x, y, z) = (cell % w, (cell / w) % h, cell / (w * h));
            let at = if geometry.depth > 1 {
                format!("{f}, {z}, {y}, {x}")
            } else {
                format!("{f}, {y}, {x}")
            };
            PyValueError::new_err(format!(
                "frames[{at}]: occupancy {value} is not -1 (unknown) or 0..=100"
            ))
        }
        GridError::NothingObserved { .. } => PyValueError::new_err(format!(
            "frames[{f}]: every cell is unknown (-1); a frame must observe at least one cell"
        )),
        other => PyValueError::new_err(format!("frames[{f}]: {other}")),
    }
}

/// Observes `frames` (`T` frames of `geometry.cells()` cells, row-major) at `times` into
/// `grid`, without the GIL.
fn observe_all(
    py: Python<'_>,
    grid: &mut FremenGrid,
    frames: &[i8],
    times: &[f64],
) -> PyResult<()> {
    let geometry = *grid.geometry();
    let cells = geometry.cells();
    py.detach(|| {
        for (f, (frame, &time)) in frames.chunks_exact(cells).zip(times).enumerate() {
            grid.observe_occupancy(time, frame).map_err(|e| (f, e))?;
        }
        Ok(())
    })
    .map_err(|(f, e): (usize, GridError)| frame_error(&e, f, &geometry))
}

/// A `(T, H, W)` int8 frames argument and its times, checked against each other.
struct FramesArg<'py> {
    array: Bound<'py, PyUntypedArray>,
    times: crate::arrays::F64Array<'py>,
}

impl<'py> FramesArg<'py> {
    fn new(frames: &Bound<'py, PyAny>, times: &Bound<'py, PyAny>) -> PyResult<Self> {
        let array = int8_frames(frames)?;
        let times = arrays::time_array(times, "times")?;
        let count = array.shape()[0];
        if count != times.as_slice().len() {
            return Err(PyValueError::new_err(format!(
                "frames has {count} frames (shape {}) but times has {} values",
                shape_text(array.shape()),
                times.as_slice().len()
            )));
        }
        Ok(FramesArg { array, times })
    }

    /// `(H, W)`.
    fn size(&self) -> PyResult<(u32, u32)> {
        let shape = self.array.shape();
        let dim = |n: usize, name: &str| {
            u32::try_from(n).map_err(|_| {
                PyValueError::new_err(format!("frames: {n} cells along {name} is too many"))
            })
        };
        Ok((dim(shape[1], "H")?, dim(shape[2], "W")?))
    }

    fn observe_into(&self, py: Python<'py>, grid: &mut FremenGrid) -> PyResult<()> {
        let array = self.array.cast::<numpy::PyArray3<i8>>()?.try_readonly()?;
        let data = array
            .as_slice()
            .map_err(|e| PyValueError::new_err(format!("frames: {e}")))?;
        observe_all(py, grid, data, self.times.as_slice())
    }
}

/// A FreMEn occupancy grid ([Krajník 2017] §III-C): a FreMEn model of every cell's occupancy,
/// learnt from whole frames at irregular times, predicting the map at any time.
///
/// Build one with `Grid.from_frames(frames, times, ...)` (numpy arrays) or
/// `Grid.from_nav2(frame_list)` (the Nav2 / ROS maps `chronomap grid build --frames` reads),
/// or read a grid file with `chronomap.load_grid(path)`. A grid built here holds the learning
/// state (it can `observe` more frames and predict with any order); a file may instead hold the
/// compact ("lossy") or lossless model, which only predicts. `save` writes the files
/// `chronomap grid build -o` writes and `chronomap grid predict` reads.
#[pyclass(name = "Grid", module = "chronomap")]
pub struct PyGrid {
    file: AnyGrid,
}

impl PyGrid {
    fn geometry(&self) -> &GridGeometry {
        self.file.geometry()
    }

    /// The compact model that predicts, as `chronomap grid predict --order` chooses it.
    fn fitted_for(&self, order: Option<usize>) -> PyResult<std::borrow::Cow<'_, FittedGrid>> {
        self.file
            .fitted(order, chronomap_core::Parallelism::Rayon(0))
            .map_err(|_| {
                PyValueError::new_err(
                    "order: needs a learning-state grid (this one holds a fitted model; predict without order)",
                )
            })
    }

    /// The numpy shape of a map: `(H, W)`, or `(D, H, W)` for a 3-D grid.
    fn map_shape(&self) -> Vec<usize> {
        let g = self.geometry();
        let mut shape = vec![g.height as usize, g.width as usize];
        if g.depth > 1 {
            shape.insert(0, g.depth as usize);
        }
        shape
    }

    fn state_or_err(&mut self, what: &str) -> PyResult<&mut FremenGrid> {
        let kind = chronomap_io::grid_kind(&self.file);
        self.file.learning_state_mut().ok_or_else(|| {
            PyValueError::new_err(format!(
                "cannot {what}: this grid holds a fitted model ({kind}), not a learning state"
            ))
        })
    }
}

/// Checks a prediction time.
fn check_time(time: f64) -> PyResult<()> {
    if time.is_finite() {
        Ok(())
    } else {
        Err(PyValueError::new_err(format!(
            "time: {time} is not a finite number"
        )))
    }
}

/// `--order` of `chronomap grid build`: a number of components.
fn store_file(grid: &FremenGrid, store: &str, order: Option<usize>) -> PyResult<AnyGrid> {
    let k = OrderChoice::Fixed(order.unwrap_or(grid.config().fremen.order));
    let form = match store {
        "state" => GridStore::State,
        "lossy" => GridStore::Lossy,
        "lossless" => GridStore::Lossless,
        other => {
            return Err(PyValueError::new_err(format!(
                "store: {other:?} is not one of 'state', 'lossy', 'lossless'"
            )));
        }
    };
    AnyGrid::store(grid, form, k, chronomap_core::Parallelism::Rayon(0)).map_err(|e| {
        PyValueError::new_err(format!(
            "store='lossless': {e} (build the grid with keep_history=True)"
        ))
    })
}

#[pymethods]
impl PyGrid {
    /// `Grid.from_frames(frames, times, *, resolution=1.0, origin=(0.0, 0.0), periods="week",
    /// order=2, keep_history=False)`
    ///
    /// A grid learnt from `frames`, a `(T, H, W)` int8 array of `nav_msgs/OccupancyGrid` frames
    /// (−1 unknown, 0..100 percent; row 0 at the bottom), observed at `times` (`T` float64
    /// seconds, never going backwards). `resolution` (m per cell) and `origin` (x, y of the
    /// lower-left corner of cell (0, 0), m) place it; `periods` are the candidate periods of
    /// every cell's FreMEn model and `order` its default order (`chronomap grid build
    /// --periods --order`). `keep_history` keeps the frame history that `save(store="lossless")`
    /// needs.
    ///
    /// Integer arrays of another dtype are converted when every value fits; float arrays are a
    /// `TypeError`. A bad time or cell value is a `ValueError` naming it (`times[3]`,
    /// `frames[3, 0, 7]`).
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (frames, times, *, resolution = 1.0, origin = (0.0, 0.0), periods = "week", order = 2, keep_history = false))]
    fn from_frames(
        py: Python<'_>,
        frames: &Bound<'_, PyAny>,
        times: &Bound<'_, PyAny>,
        resolution: f64,
        origin: (f64, f64),
        periods: &str,
        order: usize,
        keep_history: bool,
    ) -> PyResult<Self> {
        let arg = FramesArg::new(frames, times)?;
        let (height, width) = arg.size()?;
        let geometry = GridGeometry::planar(width, height, resolution, [origin.0, origin.1])
            .map_err(|e| grid_error(&e))?;
        let config = grid_config(periods, order, keep_history)?;
        let mut grid = FremenGrid::new(geometry, config).map_err(|e| grid_error(&e))?;
        arg.observe_into(py, &mut grid)?;
        Ok(PyGrid {
            file: AnyGrid::State(Box::new(grid)),
        })
    }

    /// `Grid.from_nav2(frame_list, *, ros1=False, periods="week", order=2, keep_history=False)`
    ///
    /// A grid learnt from the maps of a frame list, as `chronomap grid build --frames
    /// frame_list` builds it: lines `<unix time> <map.yaml>` (ROS map_server / Nav2 maps, paths
    /// relative to the list; all maps of the size of the first). Maps are read with Nav2's
    /// rules, or ROS 1 map_server's with `ros1=True`; the first map gives the resolution and
    /// origin. Errors name the list, the line and the map file.
    #[staticmethod]
    #[pyo3(signature = (frame_list, *, ros1 = false, periods = "week", order = 2, keep_history = false))]
    fn from_nav2(
        py: Python<'_>,
        frame_list: PathBuf,
        ros1: bool,
        periods: &str,
        order: usize,
        keep_history: bool,
    ) -> PyResult<Self> {
        // The job `chronomap grid build --frames` runs (chronomap-app), with nothing held back.
        let settings = BuildSettings {
            periods: grid_config(periods, order, keep_history)?.fremen.periods,
            order: Some(order),
            holdout: 0.0,
            errors: false,
            store: GridStore::State,
            keep_history,
        };
        let semantics = if ros1 {
            LoadSemantics::Ros1
        } else {
            LoadSemantics::Nav2
        };
        let source = FrameSource::MapList {
            list: &frame_list,
            semantics,
        };
        let built = py
            .detach(|| build_grid(&source, &settings, &NoProgress))
            .map_err(|e| grid_job_error(&e))?;
        Ok(PyGrid {
            file: AnyGrid::State(Box::new(built.build.grid)),
        })
    }

    /// Observes more frames (`(T, H, W)` int8, at `times` not before the last frame) into a
    /// learning-state grid. A rejected batch leaves the grid as it was. Returns the grid.
    fn observe<'py>(
        mut slf: PyRefMut<'py, Self>,
        frames: &Bound<'py, PyAny>,
        times: &Bound<'py, PyAny>,
    ) -> PyResult<PyRefMut<'py, Self>> {
        let py = slf.py();
        let shape = slf.map_shape();
        let arg = FramesArg::new(frames, times)?;
        let grid = slf.state_or_err("observe")?;
        let (height, width) = arg.size()?;
        if shape != [height as usize, width as usize] {
            return Err(PyValueError::new_err(format!(
                "frames: expected frames of shape (T, {}) for this grid, got shape {}",
                shape
                    .iter()
                    .map(usize::to_string)
                    .collect::<Vec<_>>()
                    .join(", "),
                shape_text(arg.array.shape())
            )));
        }
        // On a copy: a bad frame in the middle must not leave half a batch behind.
        let mut updated = grid.clone();
        arg.observe_into(py, &mut updated)?;
        *grid = updated;
        Ok(slf)
    }

    /// The occupancy probability of every cell at `time` (seconds, `datetime`,
    /// `numpy.datetime64` or `pandas.Timestamp`): a float32 array of shape
    /// `(H, W)` (`(D, H, W)` for a 3-D grid), NaN for cells never observed — the map
    /// `chronomap grid predict` writes (as `round(100 p)`). `order` predicts a learning-state
    /// grid with another order (`grid predict --order`).
    #[pyo3(signature = (time, *, order = None))]
    fn predict_map<'py>(
        &self,
        py: Python<'py>,
        time: &Bound<'py, PyAny>,
        order: Option<usize>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let time = arrays::time_scalar(time, "time")?;
        check_time(time)?;
        let values =
            py.detach(|| -> PyResult<Vec<f32>> { Ok(self.fitted_for(order)?.predict_map(time)) })?;
        Ok(PyArray1::from_vec(py, values)
            .reshape(self.map_shape())?
            .into_any())
    }

    /// The compact ("lossy") model of this grid with `order` components per cell (default the
    /// grid's order): a grid that predicts the same maps as `predict_map(t, order=order)`
    /// without refitting every cell on each call.
    #[pyo3(signature = (order = None))]
    fn compact(&self, py: Python<'_>, order: Option<usize>) -> PyResult<PyGrid> {
        let fitted =
            py.detach(|| -> PyResult<FittedGrid> { Ok(self.fitted_for(order)?.into_owned()) })?;
        Ok(PyGrid {
            file: AnyGrid::Lossy(Box::new(fitted)),
        })
    }

    /// Writes the grid to `path` (versioned, checksummed, atomic): the file `chronomap grid
    /// build -o` writes. `store` is what a learning-state grid stores (`grid build --store`):
    /// `"state"` (default; can learn further), `"lossy"` (the compact model of `order`
    /// components) or `"lossless"` (plus outlier sets; needs `keep_history=True`). A grid read
    /// from a compact file is written as it is.
    #[pyo3(signature = (path, *, store = None, order = None))]
    fn save(
        &self,
        py: Python<'_>,
        path: PathBuf,
        store: Option<&str>,
        order: Option<usize>,
    ) -> PyResult<()> {
        let file = match self.file.learning_state() {
            Some(grid) => {
                let store = store.unwrap_or("state");
                Some(py.detach(|| store_file(grid, store, order))?)
            }
            None => {
                let other = &self.file;
                if store.is_some_and(|s| {
                    s != chronomap_io::grid_kind(other).trim_start_matches("grid-")
                }) || order.is_some()
                {
                    return Err(PyValueError::new_err(format!(
                        "this grid holds a fitted model ({}): it is saved as it is (no store or order)",
                        chronomap_io::grid_kind(other)
                    )));
                }
                None
            }
        };
        let file = file.as_ref().unwrap_or(&self.file);
        py.detach(|| write_grid_file(&path, file))
            .map_err(|e| errors::model_file(&e))
    }

    /// `(H, W)` (`(D, H, W)` for a 3-D grid): the shape of `predict_map`.
    #[getter]
    fn shape<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        PyTuple::new(py, self.map_shape())
    }

    /// Edge length of a cell in metres.
    #[getter]
    fn resolution(&self) -> f64 {
        self.geometry().resolution
    }

    /// `(x, y)` of the lower-left corner of cell (0, 0) in metres (`(x, y, z)` for 3-D grids).
    #[getter]
    fn origin<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let g = self.geometry();
        let n = if g.depth > 1 { 3 } else { 2 };
        PyTuple::new(py, &g.origin[..n])
    }

    /// Number of frames learnt from.
    #[getter]
    fn frames(&self) -> u64 {
        self.file.frames()
    }

    /// `(first, last)` frame time, or None before any frame.
    #[getter]
    fn span(&self) -> Option<(f64, f64)> {
        let span = self.file.frame_span();
        (span.count > 0).then_some((span.first, span.last))
    }

    /// What the grid holds, as in its file header: `grid-state`, `grid-lossy` or
    /// `grid-lossless`.
    #[getter]
    fn kind(&self) -> &'static str {
        chronomap_io::grid_kind(&self.file)
    }

    /// The default order of a learning-state grid (None for fitted grids).
    #[getter]
    fn order(&self) -> Option<usize> {
        self.file.learned_order()
    }

    fn __repr__(&self) -> String {
        let g = self.geometry();
        format!(
            "<chronomap.Grid {} {}x{}x{} at {} m, {} frames>",
            chronomap_io::grid_kind(&self.file),
            g.width,
            g.height,
            g.depth,
            g.resolution,
            self.frames()
        )
    }
}

/// `load_grid(path)`: a grid file written by `chronomap grid build` or `Grid.save`, checked
/// (version, checksum, kind, invariants). A missing file is a `FileNotFoundError`, a damaged
/// or foreign one a `ValueError`; both name the file.
#[pyfunction]
fn load_grid(py: Python<'_>, path: PathBuf) -> PyResult<PyGrid> {
    let file = py
        .detach(|| read_grid_file(&path))
        .map_err(|e| errors::model_file(&e))?;
    Ok(PyGrid { file })
}

/// What `read_map` returns: data, resolution, origin.
type MapTuple<'py> = (Bound<'py, PyAny>, f64, (f64, f64, f64));

/// `read_map(yaml, *, ros1=False)`: a ROS map_server / Nav2 map (YAML + PGM/PNG) as
/// `(data, resolution, origin)`: `data` an int8 array `(H, W)` of occupancies (−1 unknown,
/// 0..100; row 0 at the bottom, as `nav_msgs/OccupancyGrid`), `resolution` in m per cell,
/// `origin` `(x, y, yaw)`. Pixels are read with Nav2's rules, or ROS 1's with `ros1=True`.
#[pyfunction]
#[pyo3(signature = (yaml, *, ros1 = false))]
fn read_map<'py>(py: Python<'py>, yaml: PathBuf, ros1: bool) -> PyResult<MapTuple<'py>> {
    let semantics = if ros1 {
        LoadSemantics::Ros1
    } else {
        LoadSemantics::Nav2
    };
    let map: OccupancyMap = py
        .detach(|| load_map(Path::new(&yaml), semantics))
        .map_err(|e| nav_map_error(&e, e.to_string()))?;
    let shape = [map.height as usize, map.width as usize];
    let data = PyArray1::from_vec(py, map.data).reshape(shape)?.into_any();
    Ok((
        data,
        f64::from(map.resolution),
        (map.origin[0], map.origin[1], map.origin[2]),
    ))
}

/// Registers this module's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyGrid>()?;
    m.add_function(wrap_pyfunction!(load_grid, m)?)?;
    m.add_function(wrap_pyfunction!(read_map, m)?)?;
    Ok(())
}
