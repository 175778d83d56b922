//! The one place Rust errors become Python exceptions: a small hierarchy under
//! `synthgen.Error`, messages as the CLI prints them (the error and its causes, joined by
//! ": "), the hint (if any) as the exception's `hint` attribute and a PEP 678 note.

use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::PyList;
use synthgen_pipeline::error_chain;

pyo3::create_exception!(
    synthgen,
    Error,
    PyException,
    "Every error synthgen raises (the Rust library's message, with its causes)."
);
pyo3::create_exception!(
    synthgen,
    InputError,
    Error,
    "Bad input: a file that cannot be read, a malformed dataset or spec, an impossible option."
);
pyo3::create_exception!(
    synthgen,
    InternalError,
    Error,
    "A failure that is not about the input (a render that went wrong, a bug): please report it."
);

/// Whether an error is about the input (the CLI's exit code 1) or not (exit code 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Input,
    Internal,
}

/// A Python exception carrying a Rust error's chain of messages.
pub fn py_err(kind: Kind, e: &(dyn std::error::Error + 'static), hint: Option<&str>) -> PyErr {
    let message = error_chain(e);
    let err = match kind {
        Kind::Input => InputError::new_err(message),
        Kind::Internal => InternalError::new_err(message),
    };
    if let Some(hint) = hint {
        Python::attach(|py| {
            let value = err.value(py);
            // Attributes on a fresh exception instance cannot fail to be set.
            let _ = value.setattr("hint", hint);
            if let Ok(notes) = PyList::new(py, [format!("hint: {hint}")]) {
                let _ = value.setattr("__notes__", notes);
            }
        });
    }
    err
}

/// An input error from a plain message (a bad argument the bindings check themselves).
pub fn input_error(message: impl Into<String>, hint: Option<&str>) -> PyErr {
    #[derive(Debug)]
    struct Message(String);
    impl std::fmt::Display for Message {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str(&self.0)
        }
    }
    impl std::error::Error for Message {}
    py_err(Kind::Input, &Message(message.into()), hint)
}

/// Converts the library crates' errors; the kind follows the CLI's exit codes.
pub trait ToPyErr {
    fn to_py_err(&self) -> PyErr;
}

impl ToPyErr for synthgen_pipeline::Error {
    fn to_py_err(&self) -> PyErr {
        let kind = if self.is_user_error() {
            Kind::Input
        } else {
            Kind::Internal
        };
        py_err(kind, self, self.hint())
    }
}

macro_rules! input_errors {
    ($($t:ty),*) => {$(
        impl ToPyErr for $t {
            fn to_py_err(&self) -> PyErr {
                py_err(Kind::Input, self, None)
            }
        }
    )*};
}

// Reading datasets, models, specs and results: their errors are about the files read.
input_errors!(
    synthgen_core::Error,
    synthgen_formats::Error,
    synthgen_train::Error,
    synthgen_assets::Error
);

impl ToPyErr for synthgen_render::Error {
    fn to_py_err(&self) -> PyErr {
        py_err(Kind::Internal, self, None)
    }
}

/// The experiments' errors (anyhow, joining every crate's): the kind and the hint as the CLI
/// decides its exit code and prints its hint.
impl ToPyErr for anyhow::Error {
    fn to_py_err(&self) -> PyErr {
        let kind = if synthgen_jobs::is_user_error(self) {
            Kind::Input
        } else {
            Kind::Internal
        };
        let e: &(dyn std::error::Error + 'static) = self.as_ref();
        py_err(kind, e, synthgen_jobs::error_hint(self).as_deref())
    }
}

/// `result.map_err(to_py)`.
pub fn to_py<E: ToPyErr>(e: E) -> PyErr {
    e.to_py_err()
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("Error", py.get_type::<Error>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("InternalError", py.get_type::<InternalError>())?;
    Ok(())
}
