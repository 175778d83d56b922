//! Running library code from Python: the GIL released for the duration, errors mapped, Ctrl-C
//! checked on the way back; progress reported to a Python callback.

use pyo3::prelude::*;
use synthgen_core::Progress;

use crate::errors::{to_py, ToPyErr};

/// Runs `f` with the GIL released (other Python threads run meanwhile), then raises a pending
/// `KeyboardInterrupt` or maps `f`'s error.
pub fn detached<T, E>(py: Python<'_>, f: impl FnOnce() -> Result<T, E> + Send) -> PyResult<T>
where
    T: Send,
    E: ToPyErr + Send,
{
    let result = py.detach(f);
    py.check_signals()?;
    result.map_err(to_py)
}

/// [`Progress`] for Python: each event is a call `callback(event, text, n)` with event one of
/// `"start"` (text = label, n = total), `"advance"` (n steps), `"warn"`, `"info"` (text = the
/// message) and `"finish"`. The callback runs with the GIL taken, from whichever thread the
/// library reports on; an exception it raises is reported as unraisable, not propagated
/// (the library cannot stop on it).
pub struct PyProgress {
    callback: Option<Py<PyAny>>,
}

impl PyProgress {
    pub fn new(callback: Option<Py<PyAny>>) -> PyProgress {
        PyProgress { callback }
    }

    fn call(&self, event: &str, text: &str, n: u64) {
        let Some(cb) = &self.callback else {
            return;
        };
        Python::attach(|py| {
            if let Err(e) = cb.call1(py, (event, text, n)) {
                e.write_unraisable(py, Some(cb.bind(py)));
            }
        });
    }
}

impl Progress for PyProgress {
    fn start(&self, label: &str, total: u64) {
        self.call("start", label, total);
    }
    fn advance(&self, n: u64) {
        self.call("advance", "", n);
    }
    fn warn(&self, message: &str) {
        self.call("warn", message, 0);
    }
    fn info(&self, message: &str) {
        self.call("info", message, 0);
    }
    fn hint(&self, message: &str) {
        self.call("info", &format!("hint: {message}"), 0);
    }
    fn finish(&self) {
        self.call("finish", "", 0);
    }
}
