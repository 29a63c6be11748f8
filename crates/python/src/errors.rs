//! Rust errors as Python exceptions, with the messages the command line prints.
//!
//! | Rust | Python |
//! |---|---|
//! | a file that cannot be opened or read | `FileNotFoundError`, `PermissionError` or `OSError` |
//! | bad observations, bad settings, a damaged or foreign file | `ValueError` |
//! | the service answering with an error | `chronomap.ServiceError` (a `RuntimeError`) |

use std::io;

use chronomap_core::{BuildError, ConfigError, ObservationError};
use chronomap_io::{DataError, DataErrorKind, ModelFileError, ModelFileErrorKind};
use pyo3::PyErr;
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyPermissionError, PyValueError};

/// An I/O error as the matching `OSError` subclass, with `message` as its text.
pub fn io_error(io: &io::Error, message: String) -> PyErr {
    match io.kind() {
        io::ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
        io::ErrorKind::PermissionDenied => PyPermissionError::new_err(message),
        _ => PyOSError::new_err(message),
    }
}

/// A rejected batch of observations: the command line's message (`observation 4: time NaN
/// is not a finite number`) and the Python element it is about (`times[3]`).
pub fn observation(error: &ObservationError) -> PyErr {
    PyValueError::new_err(observation_message(error))
}

/// The text of [`observation`].
pub fn observation_message(error: &ObservationError) -> String {
    match error.index() {
        Some(i) => {
            let field = if error.is_about_time() {
                "times"
            } else {
                "values"
            };
            format!("observation {} ({field}[{i}]): {error}", i + 1)
        }
        None => error.to_string(),
    }
}

/// A model that could not be built.
pub fn build(error: &BuildError) -> PyErr {
    match error {
        BuildError::Observation(e) => observation(e),
        e => PyValueError::new_err(e.to_string()),
    }
}

/// An invalid setting or model spec.
pub fn config(error: &ConfigError) -> PyErr {
    PyValueError::new_err(error.to_string())
}

/// A model file that could not be read or written.
pub fn model_file(error: &ModelFileError) -> PyErr {
    match error.kind() {
        ModelFileErrorKind::Io { io, .. } => io_error(io, error.to_string()),
        _ => PyValueError::new_err(error.to_string()),
    }
}

/// A data file that could not be read (its message names the file, line and field).
pub fn data(error: &DataError) -> PyErr {
    match error.kind() {
        DataErrorKind::Io { io, .. } => io_error(io, error.to_string()),
        _ => PyValueError::new_err(error.to_string()),
    }
}
