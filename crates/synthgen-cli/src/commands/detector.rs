//! `synthgen detector train|run`: skins over `synthgen_jobs::detect` (flags → the request →
//! the run; the recall table on stdout).

use anyhow::Result;
use synthgen_detect::detector::DetectorConfig;
use synthgen_jobs::detect::{detect_run, train_detector_run, DetectRequest, DetectorTrainRequest};

use crate::cli::{DetectorRunArgs, DetectorTrainArgs, DeviceArg};
use crate::commands::explicit_settings;
use crate::{ExitStatus, Printer};

pub fn run_train(args: DetectorTrainArgs, printer: &Printer) -> Result<ExitStatus> {
    let config = DetectorConfig {
        epochs: args.epochs,
        batch: args.batch,
        lr: args.lr,
        input: args.input,
        seed: args.seed,
        val_fraction: args.val_fraction,
        min_visib_fract: args.min_visib_fract,
        ..DetectorConfig::new(
            args.data.clone().unwrap_or_default(),
            args.split.clone().unwrap_or_default(),
            args.objects.clone(),
        )
    };
    let request = DetectorTrainRequest {
        config,
        out: args.out,
        resume: args.resume,
        force: args.force,
        jobs: args.jobs,
        cuda: args.device == DeviceArg::Cuda,
        explicit: explicit_settings(&["detector", "train"], SETTINGS),
    };
    train_detector_run(&request, printer)?;
    Ok(ExitStatus::Success)
}

pub fn run_run(args: DetectorRunArgs, printer: &Printer) -> Result<ExitStatus> {
    let request = DetectRequest {
        data: args.data,
        split: args.split,
        checkpoint: args.checkpoint,
        out: args.out,
        min_score: args.min_score,
        per_class: args.per_class,
        jobs: args.jobs,
        cuda: args.device == DeviceArg::Cuda,
    };
    let (_, table, _) = detect_run(&request, printer)?;
    printer.data(&table)?;
    Ok(ExitStatus::Success)
}

/// The flags that make a detector run (clap's id, `config.json`'s key): `--resume` refuses
/// another value than the run's.
const SETTINGS: &[(&str, &str)] = &[
    ("split", "split"),
    ("objects", "classes"),
    ("batch", "batch"),
    ("lr", "lr"),
    ("input", "input"),
    ("seed", "seed"),
    ("val_fraction", "val_fraction"),
    ("min_visib_fract", "min_visib_fract"),
];
