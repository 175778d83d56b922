//! The jobs a user runs, as library calls: the single steps of synthgen's pipeline with their
//! guards, messages and files, exactly as the CLI's commands run them (the CLI and the Python
//! package only map their arguments onto the requests here), and which the experiments
//! (`synthgen-experiment`) chain.
//!
//! - [`render`] — `synthgen render`: a [`render::RenderRequest`] (scene file and overrides,
//!   objects, frames or a shard, output) → `synthgen_pipeline::RenderJob` → `write`.
//! - [`replay`] — `synthgen render --replay`: real frames rendered again at their GT poses.
//! - [`align`] — `synthgen model align`: scans aligned onto their models and written.
//! - [`annotate`] — `synthgen annotate`: masks and `scene_gt_info` from the GT poses, or
//!   their comparison with a dataset's own masks.
//! - [`convert`] — `synthgen convert`: BOP, Linemod and YCB-Video into one another.
//! - [`fit`] — `synthgen scene fit` and `sensor fit`: the fits written as TOML files.
//! - [`merge`] — `synthgen merge`: the shards of one `render --shard I/N` run into one
//!   dataset.
//! - [`mix`] — `synthgen mix`: real and synthetic frames drawn into one dataset, the frames
//!   YCB-Video and Linemod sets lack completed from their poses.
//! - [`train`] — `synthgen train`: a training run in a run folder.
//! - [`eval`] — `synthgen eval`: a results CSV or a checkpoint scored against a dataset.
//! - [`predict`] — `synthgen predict`: the detector and a pose model on frames with no GT
//!   (photographs with their intrinsics, or a dataset) into BOP results and JSON lines.
//! - [`models`] — a dataset's object models in an `ObjectRenderer`, replacement meshes.
//!
//! Messages and progress go to the caller's `synthgen_core::Progress` (through [`Log`]);
//! errors are `anyhow` errors, those about the request carrying a `synthgen_core::UserError`
//! with a hint; [`is_user_error`] and [`error_hint`] tell the CLI's exit code and hint (and
//! Python's exception) from any of them.

mod log;

pub mod align;
pub mod annotate;
pub mod convert;
pub mod detect;
pub mod detect_eval;
pub mod eval;
pub mod fit;
pub mod merge;
pub mod mix;
pub mod models;
pub mod predict;
pub mod render;
pub mod replay;
pub mod rgb_refine;
pub mod ros;
pub mod train;

use log::Printer;
pub use log::{Log, Stdout};

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

/// `--jobs N`: the process's rayon pool gets N threads (None: all cores, or
/// `RAYON_NUM_THREADS`). The global pool can be set once per process; a second call (only
/// tests run several jobs in one process) keeps the first pool. candle's CPU matrix products
/// split their work by `RAYON_NUM_THREADS` (else the core count), so it is set to N as well:
/// a training's products then split into as many parts as there are threads to run them.
pub fn use_threads(jobs: Option<usize>) {
    if let Some(j) = jobs {
        // Set before the pool starts its threads, while this is the only thread that reads
        // the environment.
        std::env::set_var("RAYON_NUM_THREADS", j.to_string());
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(j)
            .build_global();
    }
}
