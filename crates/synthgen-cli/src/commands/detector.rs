//! `synthgen detector train|run|eval`: skins over `synthgen_jobs::detect` and
//! `synthgen_jobs::detect_eval` (flags → the request → the run; the tables on stdout).

use anyhow::Result;
use synthgen_detect::detector::DetectorConfig;
use synthgen_jobs::detect::{detect_run, train_detector_run, DetectRequest, DetectorTrainRequest};

use synthgen_jobs::detect_eval::{detection_eval_run, BboxType, DetectionEvalRequest};

use crate::cli::{BboxTypeArg, DetectorEvalArgs, DetectorRunArgs, DetectorTrainArgs, DeviceArg};
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
        masks: !args.no_masks,
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

pub fn run_eval(args: DetectorEvalArgs, printer: &Printer) -> Result<ExitStatus> {
    let request = DetectionEvalRequest {
        data: args.data,
        split: args.split,
        detections: args.detections,
        targets: args.targets,
        all_frames: args.all_frames,
        bbox_type: match args.bbox_type {
            BboxTypeArg::Amodal => BboxType::Amodal,
            BboxTypeArg::Modal => BboxType::Modal,
        },
        out: args.out,
        gt_out: args.gt_out,
        draw: args.draw.map(|d| (d, args.draw_count)),
        jobs: args.jobs,
    };
    let scores = detection_eval_run(&request, printer)?;
    printer.data(format!(
        "{} detections of {} images, {} GT instances ({} boxes{}):\n\n{}",
        scores.scored,
        scores.n_images,
        scores.n_gt,
        match scores.bbox_type {
            BboxType::Amodal => "amodal",
            BboxType::Modal => "modal",
        },
        if scores.images_with_rendered_masks > 0 {
            format!(
                "; masks of {} images rendered from the GT poses",
                scores.images_with_rendered_masks
            )
        } else {
            String::new()
        },
        scores.table()
    ))?;
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
    ("no_masks", "masks"),
];
