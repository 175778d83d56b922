//! `synthgen train`: a skin over `synthgen_jobs::train` (flags → the run's
//! configuration → the run, its epochs and summary on the printer).

use anyhow::Result;
use synthgen_jobs::train::{train_run, TrainRequest};
use synthgen_train::models::rgb::{Translation, DEFAULT_RGB_CROP};
use synthgen_train::models::rnet::DEFAULT_CROP;
use synthgen_train::models::tnet::DEFAULT_SCALE;
use synthgen_train::models::ModelKind;
use synthgen_train::train::{Schedule, TrainConfig};

use crate::cli::{DeviceArg, ScheduleArg, TrainArgs, TrainModelArg, TranslationArg};
use crate::commands::explicit_settings;
use crate::{ExitStatus, Printer};

pub fn run(args: TrainArgs, printer: &Printer) -> Result<ExitStatus> {
    let model = match args.model {
        TrainModelArg::Tnet => ModelKind::Tnet,
        TrainModelArg::Rnet => ModelKind::Rnet,
        TrainModelArg::Full => ModelKind::Full,
        TrainModelArg::Rgb => ModelKind::Rgb,
        TrainModelArg::RgbDense => ModelKind::RgbDense,
    };
    let config = TrainConfig {
        objects: Vec::new(),
        model,
        width: args.width,
        n_points: args.points,
        normalization_scale: DEFAULT_SCALE,
        epochs: args.epochs,
        batch: args.batch,
        lr: args.lr,
        weight_decay: args.weight_decay,
        schedule: match args.schedule {
            ScheduleArg::Cosine => Schedule::Cosine,
            ScheduleArg::Step => Schedule::Step,
            ScheduleArg::Constant => Schedule::Constant,
        },
        seed: args.seed,
        val_fraction: args.val_fraction,
        min_visib_fract: args.min_visib_fract,
        data: args.data.clone(),
        split: args.split.clone().unwrap_or_default(),
        crop_size: match model {
            ModelKind::Tnet => 0,
            ModelKind::Rgb | ModelKind::RgbDense => args.crop_size.unwrap_or(DEFAULT_RGB_CROP),
            _ => args.crop_size.unwrap_or(DEFAULT_CROP),
        },
        loss_points: args.loss_points,
        init: args.init.clone(),
        plain_add_loss: args.no_symmetric_loss,
        translation: (model == ModelKind::Rgb).then_some(match args.translation {
            TranslationArg::CentreTz => Translation::CentreTz,
            TranslationArg::Xyz => Translation::Xyz,
        }),
        // The training set's objects, once it is loaded.
        classes: Vec::new(),
    };
    let request = TrainRequest {
        config,
        out: args.out.clone(),
        resume: args.resume,
        force: args.force,
        per_object: args.per_object,
        jobs: args.jobs,
        cuda: args.device == DeviceArg::Cuda,
        explicit: explicit_settings(&["train"], SETTINGS),
    };
    train_run(&request, printer)?;
    Ok(ExitStatus::Success)
}

/// The flags that make a run (clap's id, `config.json`'s key): `--resume` refuses another
/// value than the run's.
const SETTINGS: &[(&str, &str)] = &[
    ("model", "model"),
    ("translation", "translation"),
    ("batch", "batch"),
    ("lr", "lr"),
    ("weight_decay", "weight_decay"),
    ("schedule", "schedule"),
    ("seed", "seed"),
    ("points", "n_points"),
    ("width", "width"),
    ("crop_size", "crop_size"),
    ("loss_points", "loss_points"),
    ("no_symmetric_loss", "plain_add_loss"),
    ("val_fraction", "val_fraction"),
    ("min_visib_fract", "min_visib_fract"),
    ("split", "split"),
];
