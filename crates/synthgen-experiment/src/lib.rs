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
//!
//! The single steps they chain (a render, a conversion, the fits, a training run, an
//! evaluation) are `synthgen_jobs`, which the CLI's own commands run too.
//!
//! Messages and progress go to the caller's `synthgen_core::Progress` (through [`Log`]);
//! errors are `anyhow` errors, those about the request itself carrying a
//! `synthgen_core::UserError` with a hint. Each run returns its report as Markdown (what the
//! CLI prints). What an experiment records as its reproducing command is the options'
//! `command_line`.

pub mod mix;
pub mod options;
pub mod rgb;
mod settings;
pub mod sim2real;

pub use mix::run_mix;
pub use options::{
    MixOptions, Model, Refine, RgbOptions, Sim2realModel, Sim2realOptions, TrainBudget,
};
pub use synthgen_jobs::{user_error, Log};
