//! The module's exception and the guard that keeps Rust panics from reaching Python.

use pyo3::exceptions::PyException;
use pyo3::prelude::*;

pyo3::create_exception!(
    lucent,
    LucentError,
    PyException,
    "An error lucent reports: a file it cannot read (with the place), a scene it cannot build."
);

/// Runs `f`, turning a panic into a `LucentError` that names the operation.
pub(crate) fn guard<T>(what: &str, f: impl FnOnce() -> T) -> PyResult<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|p| {
        let msg = p.downcast_ref::<&str>().map(|s| (*s).to_string()).or_else(|| p.downcast_ref::<String>().cloned()).unwrap_or_default();
        LucentError::new_err(format!("{what}: internal error ({msg}); please report it"))
    })
}
