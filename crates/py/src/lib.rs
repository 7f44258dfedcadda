//! `lucent._lucent`: the Python extension of lucent. Scenes built from numpy arrays or
//! read from files, ray queries on arrays of any leading shape (closest hit, any hit, all
//! hits, hit counts) with the GIL released and all cores at work, cameras, and rendering
//! to numpy images. The pure-Python package `lucent` (python/lucent) wraps it: its
//! `Hits`, argument defaults and the compatibility layers live there.
//!
//! Every entry point returns a Python exception for bad input (naming the argument), and
//! runs its Rust work under `errors::guard`, so a panic becomes a `LucentError` instead of
//! tearing through the interpreter.

// PyO3's macros expand to code clippy reads as needless conversions.
#![allow(clippy::useless_conversion)]
#![deny(missing_docs)]

mod arrays;
mod camera;
mod errors;
mod query;
mod render;
mod scene;
mod threads;

use pyo3::prelude::*;

use errors::LucentError;

/// Facts about this build and machine: version, the ray kernel picked for this CPU, the
/// threads queries use.
#[pyfunction]
fn info(py: Python<'_>) -> PyResult<Bound<'_, pyo3::types::PyDict>> {
    let d = pyo3::types::PyDict::new(py);
    d.set_item("version", env!("CARGO_PKG_VERSION"))?;
    d.set_item("kernel", lucent_accel::Kernel::detect().name())?;
    d.set_item("threads", threads::current())?;
    d.set_item("cores", threads::cores())?;
    Ok(d)
}

/// Sets how many threads queries and renders use by default (0: every core).
#[pyfunction]
fn set_num_threads(n: usize) {
    threads::set_default(n);
}

/// The module.
#[pymodule]
fn _lucent(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<scene::Scene>()?;
    m.add_class::<camera::Camera>()?;
    m.add_class::<render::Renderer>()?;
    m.add_function(wrap_pyfunction!(scene::load, m)?)?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(render::denoise, m)?)?;
    m.add_function(wrap_pyfunction!(render::write_image, m)?)?;
    m.add_function(wrap_pyfunction!(render::read_image, m)?)?;
    m.add_function(wrap_pyfunction!(info, m)?)?;
    m.add_function(wrap_pyfunction!(set_num_threads, m)?)?;
    m.add("LucentError", m.py().get_type::<LucentError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
