//! One module per command; each exposes `run(args, printer) -> anyhow::Result<ExitStatus>`.

pub mod annotate;
pub mod convert;
pub mod detector;
pub mod eval;
pub mod experiment;
pub mod export;
pub mod merge;
pub mod mix;
pub mod model;
pub mod predict;
pub mod preview;
pub mod render;
mod render_flags;
mod replay;
pub mod ros;
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
    let user =
        synthgen_jobs::is_user_error(err) || err.chain().any(|c| c.is::<synthgen_view::Error>());
    if user {
        ExitStatus::Failure
    } else {
        ExitStatus::Error
    }
}

pub use synthgen_core::UserError;

pub use synthgen_jobs::user_error;

pub fn hint_for(err: &anyhow::Error) -> Option<String> {
    synthgen_jobs::error_hint(err)
}

/// The settings of `table` (clap id, `config.json` key) that the command line of
/// `subcommands` gave, as (flag, key), for `--resume`'s comparison with the run.
pub fn explicit_settings(subcommands: &[&str], table: &[(&str, &str)]) -> Vec<(String, String)> {
    let given = crate::cli::explicit_flags(subcommands);
    table
        .iter()
        .filter(|(id, _)| given.iter().any(|g| g == id))
        .map(|(id, key)| (format!("--{}", id.replace('_', "-")), (*key).to_string()))
        .collect()
}
