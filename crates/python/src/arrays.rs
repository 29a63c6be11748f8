//! numpy arrays (and sequences) in, numpy arrays out.
//!
//! Inputs are borrowed without copying when they already are what Rust needs (a contiguous
//! `float64` array); anything else that is clearly numbers (integers, booleans, `float32`, a
//! non-contiguous view, a list) is converted once by numpy; anything that is not numbers is a
//! `TypeError` naming the argument, and a wrong number of dimensions a `ValueError` naming it
//! and the shape.
//!
//! Times ([`times`], [`time_array`], [`time_scalar`]) are unix seconds; anything that is not
//! already numbers (numpy `datetime64`, pandas `Timestamp` / `Series` / `DatetimeIndex`,
//! Python `datetime`) is converted to seconds in one place, `chronomap._time.seconds`, which
//! names the argument and element in its errors (`NaT`, mixed object arrays). Observed
//! states ([`value_array`]) may be pandas objects with nullable dtypes. Plain numbers and real
//! numpy arrays never leave Rust.

use numpy::{
    PyArray1, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArray1, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyFloat, PyInt};

/// A one-dimensional `float64` input: a borrowed numpy array (no copy) or a converted one.
pub struct F64Array<'py> {
    array: PyReadonlyArray1<'py, f64>,
}

impl<'py> F64Array<'py> {
    /// The values, contiguous.
    pub fn as_slice(&self) -> &[f64] {
        self.array
            .as_slice()
            .expect("F64Array holds only contiguous arrays")
    }
}

/// Formats a shape as Python does: `(3, 2)`, `(4,)`, `()`.
pub fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// `obj` as a numpy array of any dtype and shape (lists and tuples through `numpy.asarray`).
fn as_ndarray<'py>(obj: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyUntypedArray>> {
    if let Ok(array) = obj.cast::<PyUntypedArray>() {
        return Ok(array.clone());
    }
    let numpy = obj.py().import("numpy")?;
    let array = numpy.call_method1("asarray", (obj,))?;
    Ok(array.cast_into::<PyUntypedArray>()?)
}

/// Whether a numpy dtype kind holds real numbers (`b`ool, `i`nt, `u`int, `f`loat).
fn is_real_kind(kind: u8) -> bool {
    matches!(kind, b'b' | b'i' | b'u' | b'f')
}

/// `obj` as a C-contiguous `float64` numpy array of exactly `ndim` dimensions, converted by
/// numpy only if it is not one already; `name` is the argument's name in error messages.
pub fn f64_ndarray<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    ndim: usize,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let array = as_ndarray(obj).map_err(|_| {
        PyTypeError::new_err(format!(
            "{name}: expected an array of numbers, got {}",
            type_name(obj)
        ))
    })?;
    let py = obj.py();
    let dtype = array.dtype();
    if !is_real_kind(dtype.kind()) {
        return Err(PyTypeError::new_err(
            if obj.is_instance_of::<PyUntypedArray>() {
                format!(
                    "{name}: expected an array of real numbers (float64), got dtype {}",
                    dtype.str()?
                )
            } else {
                format!(
                    "{name}: expected an array of numbers, got {}",
                    type_name(obj)
                )
            },
        ));
    }
    if array.ndim() != ndim {
        return Err(PyValueError::new_err(format!(
            "{name}: expected a {ndim}-D array, got shape {}",
            shape_text(array.shape())
        )));
    }
    let ready = dtype.is_equiv_to(&numpy::dtype::<f64>(py)) && array.is_c_contiguous();
    let array = if ready {
        array
    } else {
        // One conversion by numpy: another dtype, a strided view, or a non-native byte order.
        py.import("numpy")?
            .call_method1("ascontiguousarray", (&array, "float64"))?
            .cast_into::<PyUntypedArray>()?
    };
    Ok(array.cast_into::<PyArrayDyn<f64>>()?)
}

/// `obj` as a one-dimensional `float64` array (see the [module docs](self)).
pub fn f64_array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<F64Array<'py>> {
    let array = f64_ndarray(obj, name, 1)?.cast_into::<PyArray1<f64>>()?;
    Ok(F64Array {
        array: array.try_readonly()?,
    })
}

/// Python's name of the type of `obj`, for messages.
pub fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "an object".into())
}

/// Two float64 arrays, e.g. `(times, values)` or `(mean, std)`.
pub type ArrayPair<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// A new numpy array owning `values` (no copy).
pub fn to_numpy(py: Python<'_>, values: Vec<f64>) -> Bound<'_, PyArray1<f64>> {
    PyArray1::from_vec(py, values)
}

/// Whether `obj` is a numpy array of real numbers (read by [`f64_array`] without Python).
fn is_real_ndarray(obj: &Bound<'_, PyAny>) -> bool {
    obj.cast::<PyUntypedArray>()
        .is_ok_and(|a| is_real_kind(a.dtype().kind()))
}

/// Whether `obj` is a Python `int` or `float` (or a subclass such as `bool`, `numpy.float64`).
fn is_number(obj: &Bound<'_, PyAny>) -> bool {
    obj.is_instance_of::<PyFloat>() || obj.is_instance_of::<PyInt>()
}

/// `chronomap._time.FUNCTION(obj, name)`: `None` where there is nothing to convert.
fn convert<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    function: &str,
) -> PyResult<Option<Bound<'py, PyAny>>> {
    let converted = obj
        .py()
        .import("chronomap._time")?
        .call_method1(function, (obj, name))?;
    Ok((!converted.is_none()).then_some(converted))
}

/// One time or an array of times, in unix seconds.
pub enum Times<'py> {
    /// A number or a single datetime: the answer is a number too.
    One(f64),
    /// An array.
    Many(F64Array<'py>),
}

impl Times<'_> {
    /// The times, one or many.
    pub fn as_slice(&self) -> &[f64] {
        match self {
            Times::One(t) => std::slice::from_ref(t),
            Times::Many(a) => a.as_slice(),
        }
    }

    /// Whether one time was given (not an array).
    pub fn is_one(&self) -> bool {
        matches!(self, Times::One(_))
    }
}

/// Times from Python: one (a number, `datetime`, `numpy.datetime64`, `pandas.Timestamp`) or
/// an array of them (see the [module docs](self)).
pub fn times<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Times<'py>> {
    if is_number(obj) {
        return Ok(Times::One(obj.extract()?));
    }
    if is_real_ndarray(obj) {
        return Ok(Times::Many(f64_array(obj, name)?));
    }
    match convert(obj, name, "seconds")? {
        Some(t) if t.is_instance_of::<PyFloat>() => Ok(Times::One(t.extract()?)),
        Some(array) => Ok(Times::Many(f64_array(&array, name)?)),
        None => Ok(Times::Many(f64_array(obj, name)?)),
    }
}

/// A one-dimensional array of times in unix seconds (see [`times`]).
pub fn time_array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<F64Array<'py>> {
    if is_number(obj) || is_real_ndarray(obj) {
        return f64_array(obj, name);
    }
    match convert(obj, name, "seconds")? {
        Some(t) if t.is_instance_of::<PyFloat>() => Err(PyValueError::new_err(format!(
            "{name}: expected a 1-D array of times, got one time ({})",
            type_name(obj)
        ))),
        Some(array) => f64_array(&array, name),
        None => f64_array(obj, name),
    }
}

/// One time in unix seconds: a number, `datetime`, `numpy.datetime64` or `pandas.Timestamp`.
pub fn time_scalar(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    if is_number(obj) {
        return obj.extract();
    }
    let expected = || {
        PyTypeError::new_err(format!(
            "{name}: expected one time (unix seconds, datetime, numpy.datetime64 or \
             pandas.Timestamp), got {}",
            type_name(obj)
        ))
    };
    match convert(obj, name, "seconds")? {
        Some(t) if t.is_instance_of::<PyFloat>() => t.extract(),
        Some(_) => Err(expected()),
        // numpy's and other number types that Python can read as a float.
        None => obj.extract::<f64>().map_err(|_| expected()),
    }
}

/// A one-dimensional array of observed states (floats, ints, booleans; pandas objects with
/// nullable dtypes, a missing value as NaN), as [`f64_array`].
pub fn value_array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<F64Array<'py>> {
    if is_real_ndarray(obj) {
        return f64_array(obj, name);
    }
    match convert(obj, name, "values")? {
        Some(array) => f64_array(&array, name),
        None => f64_array(obj, name),
    }
}

/// `data` at `times` as a `pandas.Series` named `name`, indexed by the times as a UTC
/// `DatetimeIndex` (`as_series=True`).
pub fn series<'py>(
    py: Python<'py>,
    times: &[f64],
    data: Vec<f64>,
    name: &str,
) -> PyResult<Bound<'py, PyAny>> {
    py.import("chronomap._time")?.call_method1(
        "series",
        (PyArray1::from_slice(py, times), to_numpy(py, data), name),
    )
}
