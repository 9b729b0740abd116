//! The extension module `pathwave._pathwave`: thin wrappers over the library and its command line's options, so that
//! Python renders, saves and compares exactly as `pathwave render` and `pathwave diff` do.
use pyo3::prelude::*;

mod argv;
mod compare;
mod errors;
mod film;
mod renderer;
mod scene;

#[pymodule]
fn _pathwave(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<scene::Scene>()?;
    m.add_class::<renderer::Renderer>()?;
    m.add_class::<film::Film>()?;
    m.add_class::<compare::DiffResult>()?;
    m.add_function(wrap_pyfunction!(compare::diff, m)?)?;
    m.add_function(wrap_pyfunction!(renderer::devices, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
