//! `synthgen._native`: the native module behind the `synthgen` Python package (thin classes
//! and functions over the pipeline, dataset and train crates; the package in `py_src/` wraps
//! them with argument coercion, docstrings and the torch adapters).
//!
//! ```python
//! import synthgen
//! gen = synthgen.Generator(objects=["driller.ply"], scene="scenes/tabletop.toml", seed=0)
//! frame = gen[0]  # rendered with the GIL released; numpy arrays
//! ```

mod commands;
mod dataset;
mod errors;
mod experiment;
mod frame;
mod gil;
mod job;
mod metrics;
mod predict;

use pyo3::prelude::*;

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    m.add_class::<job::PyRenderJob>()?;
    m.add_class::<dataset::PyDataset>()?;
    commands::register(m)?;
    experiment::register(m)?;
    metrics::register(m)?;
    predict::register(m)?;
    Ok(())
}
