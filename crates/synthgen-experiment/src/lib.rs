//! synthgen's experiments as library calls: what a model trained on synthgen's frames is
//! worth, measured end to end. Each experiment joins the renderer
//! (`synthgen_pipeline::RenderJob`), the fits of real data (`synthgen_fit`), the mixer
//! (`synthgen_curate::mix`) and the trainer (`synthgen_train`); the CLI (`synthgen experiment
//! ...`) and the Python package (`synthgen.experiment`) only map their arguments onto the
//! [`options`] and print what comes back.
//!
//! - [`run_mix`] — `experiment mix`: the real/synthetic mixing table. For each composition of
//!   a fixed-size training set: mix (the same held-out real test split for every row), train,
//!   then the errors on the trained frames and on the real test frames. Rows are resumable: a
//!   row is done when its `row.json` exists (written atomically, last); an unfinished row is
//!   redone from scratch. With `test_scenes` the test split is whole scenes of the real set,
//!   and `plus_synth` adds rows "all the real training frames + K× as many synthetic".
//! - [`sim2real::run`] — `experiment sim2real`: fit the scene (and the sensor) to real frames,
//!   render, train on synthetic frames only, test on real frames; the depth models, or with
//!   `Sim2realModel::Rgb`/`RgbDense` the RGB models on RGB-only real photographs.
//! - [`rgb::run`] — `experiment rgb`: seed 001's Table 1, the RGB model's two translation
//!   parametrizations on the same crops.
//! - [`steps`] — the single steps they chain, which the CLI's own commands (`convert`,
//!   `scene fit`, `sensor fit`, `annotate`, `render --replay`) run too.
//!
//! Messages and progress go to the caller's `synthgen_core::Progress` (through [`Log`]);
//! errors are `anyhow` errors, those about the request itself carrying a
//! `synthgen_core::UserError` with a hint. Each run returns its report as Markdown (what the
//! CLI prints). What an experiment records as its reproducing command is the options'
//! `command_line`.

mod log;
pub mod mix;
pub mod options;
pub mod rgb;
mod settings;
pub mod sim2real;
pub mod steps;

pub use log::Log;
pub use mix::run_mix;
pub use options::{MixOptions, Model, RgbOptions, Sim2realModel, Sim2realOptions, TrainBudget};

/// An error about the request (a flag, a file, a combination of options) with a hint on what
/// to do instead: a `synthgen_core::UserError` (the CLI exits with 1 on it and prints the hint).
pub fn user_error(message: impl Into<String>, hint: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(synthgen_core::UserError::new(message, hint))
}

/// Whether an error is about the request or the input (a file, a flag, a dataset) rather
/// than a bug: the CLI's exit code 1 (else 2), Python's `InputError` (else `InternalError`).
pub fn is_user_error(err: &anyhow::Error) -> bool {
    err.chain().any(|c| {
        c.is::<synthgen_core::Error>()
            || c.is::<synthgen_assets::Error>()
            || c.is::<synthgen_formats::Error>()
            || c.downcast_ref::<synthgen_train::Error>()
                .is_some_and(|e| !matches!(e, synthgen_train::Error::Candle(_)))
            || c.is::<std::io::Error>()
            || c.is::<synthgen_core::UserError>()
            || c.downcast_ref::<synthgen_pipeline::Error>()
                .is_some_and(synthgen_pipeline::Error::is_user_error)
    })
}

/// What the user can do about an error: the hint of a `UserError` or a pipeline error in its
/// chain; for a rotation beyond the reading tolerance, how to accept it.
pub fn error_hint(err: &anyhow::Error) -> Option<String> {
    let given = err.chain().find_map(|c| {
        if let Some(u) = c.downcast_ref::<synthgen_core::UserError>() {
            return u.hint.clone();
        }
        c.downcast_ref::<synthgen_pipeline::Error>()
            .and_then(|e| e.hint().map(str::to_string))
    });
    given.or_else(|| {
        // A rotation beyond the reading tolerance: say how to accept it if it is real data.
        err.chain()
            .any(|c| {
                let s = c.to_string();
                s.contains("rotation") && s.contains("(tolerance ")
            })
            .then(|| {
                format!(
                    "real annotations store approximate rotations; if this one is acceptable, raise \
                     --rotation-tolerance (now {})",
                    synthgen_core::pose::rotation_tolerance()
                )
            })
    })
}
