//! numpy arrays (and sequences) in, numpy arrays out.
//!
//! Inputs are borrowed without copying when they already are what Rust needs (a contiguous
//! `float64` array); anything else that is clearly numbers (integers, booleans, `float32`, a
//! non-contiguous view, a list) is converted once by numpy; anything that is not numbers is a
//! `TypeError` naming the argument, and a wrong number of dimensions a `ValueError` naming it
//! and the shape.

use numpy::{
    PyArray1, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyReadonlyArray1, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

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
