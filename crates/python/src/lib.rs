//! # chronomap-python
//!
//! The `chronomap._native` extension module behind the `chronomap` Python package
//! (`python/`, built by maturin: `pip install ./python`). It only translates: numpy arrays to
//! slices and back, Python arguments to the specs and settings of the Rust crates, Rust errors
//! to Python exceptions (module `errors`). Every algorithm lives in the crates it calls.
//!
//! Long computations run without the GIL ([`Python::detach`]); a Ctrl-C during one is seen
//! when it returns (Rust code does not poll Python's signal handlers).

mod activity;
mod arrays;
mod bench;
mod client;
mod errors;
mod events;
mod grid;
mod models;
mod psbt;
mod topo;

use pyo3::prelude::*;

/// The native part of the `chronomap` package; import `chronomap`, not this.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    models::register(m)?;
    grid::register(m)?;
    topo::register(m)?;
    client::register(m)?;
    activity::register(m)?;
    events::register(m)?;
    psbt::register(m)?;
    bench::register(m)?;
    Ok(())
}
