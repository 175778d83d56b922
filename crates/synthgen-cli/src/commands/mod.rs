//! One module per command; each exposes `run(args, printer) -> anyhow::Result<ExitStatus>`.

pub mod annotate;
pub mod convert;
pub mod eval;
pub mod experiment;
pub mod export;
pub mod merge;
pub mod mix;
pub mod model;
mod object_models;
pub mod preview;
pub mod render;
mod render_extras;
mod render_resume;
mod render_sink;
mod replay;
pub mod scene;
pub mod sensor;
pub mod stats;
pub mod train;
pub mod validate;
pub mod view;

use crate::ExitStatus;

/// Bad input (a broken mesh, a malformed spec, an unwritable folder) exits with 1; anything
/// else is an internal error (2).
pub fn exit_status_for(err: &anyhow::Error) -> ExitStatus {
    let user = err.chain().any(|c| {
        c.is::<synthgen_core::Error>()
            || c.is::<synthgen_assets::Error>()
            || c.is::<synthgen_formats::Error>()
            || c.is::<synthgen_view::Error>()
            || is_train_user_error(c)
            || c.is::<std::io::Error>()
            || c.is::<UserError>()
            || c.downcast_ref::<synthgen_pipeline::Error>()
                .is_some_and(synthgen_pipeline::Error::is_user_error)
    });
    if user {
        ExitStatus::Failure
    } else {
        ExitStatus::Error
    }
}

/// Errors of the trainer that come from the input (files, options), not from a bug.
fn is_train_user_error(c: &(dyn std::error::Error + 'static)) -> bool {
    c.downcast_ref::<synthgen_train::Error>()
        .is_some_and(|e| !matches!(e, synthgen_train::Error::Candle(_)))
}

pub use synthgen_core::UserError;

pub fn user_error(message: impl Into<String>, hint: impl Into<String>) -> anyhow::Error {
    anyhow::Error::new(UserError::new(message, hint))
}

pub fn hint_for(err: &anyhow::Error) -> Option<String> {
    let given = err.chain().find_map(|c| {
        if let Some(u) = c.downcast_ref::<UserError>() {
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
