//! `synthgen.experiment.mix|sim2real|rgb`: the experiments of `synthgen_experiment`, their
//! options handed over as JSON (the Python wrappers in `py_src/synthgen/experiment.py` build
//! it from their keyword arguments, with the CLI flags' defaults), run with the GIL released.

use pyo3::prelude::*;
use serde::de::DeserializeOwned;
use synthgen_experiment::options::{MixOptions, RgbOptions, Sim2realOptions};
use synthgen_experiment::Log;

use crate::errors::input_error;
use crate::gil::{detached, PyProgress};

fn options<T: DeserializeOwned>(kind: &str, json: &str) -> PyResult<T> {
    serde_json::from_str(json).map_err(|e| {
        input_error(
            format!("bad options for synthgen.experiment.{kind}: {e}"),
            Some("see help(synthgen.experiment) for the options and their values"),
        )
    })
}

/// Runs experiment `kind` (`"mix"`, `"sim2real"` or `"rgb"`) with `options` (JSON: the
/// fields of `synthgen_experiment::options`); returns its report as Markdown.
#[pyfunction]
#[pyo3(signature = (kind, options, *, progress=None))]
fn run_experiment(
    py: Python<'_>,
    kind: &str,
    options: &str,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let progress = PyProgress::new(progress);
    match kind {
        "mix" => {
            let o: MixOptions = self::options(kind, options)?;
            detached(py, || synthgen_experiment::run_mix(o, &Log::new(&progress)))
        }
        "sim2real" => {
            let o: Sim2realOptions = self::options(kind, options)?;
            detached(py, || {
                synthgen_experiment::sim2real::run(o, &Log::new(&progress))
            })
        }
        "rgb" => {
            let o: RgbOptions = self::options(kind, options)?;
            detached(py, || {
                synthgen_experiment::rgb::run(o, &Log::new(&progress))
            })
        }
        other => Err(input_error(
            format!("unknown experiment {other:?}"),
            Some("one of \"mix\", \"sim2real\", \"rgb\""),
        )),
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(run_experiment, m)?)?;
    Ok(())
}
