//! `synthgen train`: load a dataset's instances (BOP or Linemod), train a pose model, write the run.

use std::time::Instant;
use synthgen_formats::output::{check_apart, OutputLock};

use anyhow::{Context, Result};
use synthgen_core::Progress;
use synthgen_formats::layout::open_source;
use synthgen_train::data::load_source_instances;
use synthgen_train::models::rgb::{Translation, DEFAULT_RGB_CROP};
use synthgen_train::models::rnet::DEFAULT_CROP;
use synthgen_train::models::tnet::DEFAULT_SCALE;
use synthgen_train::models::ModelKind;
use synthgen_train::pose_model::load_dataset_objects;
use synthgen_train::train::{
    self, read_config, val_summary, ProgressObserver, Schedule, TrainConfig, CONFIG_FILE,
    CURVE_FILE, METRICS_FILE, MODEL_FILE,
};

use crate::cli::{DeviceArg, ScheduleArg, TrainArgs, TrainModelArg, TranslationArg};
use crate::commands::user_error;
use crate::{ExitStatus, Printer};

pub fn run(args: TrainArgs, printer: &Printer) -> Result<ExitStatus> {
    let started = Instant::now();
    let model = match args.model {
        TrainModelArg::Tnet => ModelKind::Tnet,
        TrainModelArg::Rnet => ModelKind::Rnet,
        TrainModelArg::Full => ModelKind::Full,
        TrainModelArg::Rgb => ModelKind::Rgb,
        TrainModelArg::RgbDense => ModelKind::RgbDense,
    };
    for ckpt in &args.init {
        if !ckpt.is_file() {
            return Err(user_error(
                format!("--init {} does not exist", ckpt.display()),
                "pass the model.safetensors of an earlier `synthgen train` run",
            ));
        }
    }
    if args.resume && !args.init.is_empty() {
        return Err(user_error(
            "--init and --resume do not go together",
            "--resume continues from the run's own checkpoint",
        ));
    }
    if let Some(j) = args.jobs {
        // Ignored when a pool already exists (only in tests that call run twice).
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(j)
            .build_global();
    }
    check_apart(&args.out, &[("dataset", &args.data)])?;
    let _lock = OutputLock::acquire(&args.out)?;
    let checkpoint = args.out.join(MODEL_FILE);
    let cfg = if args.resume {
        if !checkpoint.exists() {
            return Err(user_error(
                format!("nothing to resume: {} does not exist", checkpoint.display()),
                "start the run without --resume",
            ));
        }
        let saved = read_config(&args.out.join(CONFIG_FILE))?;
        TrainConfig {
            epochs: args.epochs,
            data: args.data.clone(),
            ..saved
        }
    } else {
        if checkpoint.exists() && !args.force {
            return Err(user_error(
                format!("{} already holds a run", args.out.display()),
                "continue it with --resume, overwrite it with --force, or choose another --out",
            ));
        }
        TrainConfig {
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
        }
    };
    // Before any data is read: a bad --lr must not cost a dataset load.
    cfg.validate()?;
    if args.per_object && cfg.model != ModelKind::Tnet {
        return Err(user_error(
            format!(
                "--per-object is a TNet option; the {} model has no class input",
                cfg.model.name()
            ),
            "drop --per-object, or train --model tnet",
        ));
    }
    if cfg.model.needs_rgb()
        && !cfg.model.is_rgb_only()
        && (cfg.crop_size < 2 || cfg.crop_size % 2 != 0)
    {
        return Err(user_error(
            format!("--crop-size {} must be even and at least 2", cfg.crop_size),
            "e.g. --crop-size 48",
        ));
    }
    if matches!(
        cfg.model,
        ModelKind::Full | ModelKind::Rgb | ModelKind::RgbDense
    ) && cfg.loss_points == 0
    {
        return Err(user_error(
            "--loss-points must be positive",
            "e.g. --loss-points 100",
        ));
    }
    if cfg.n_points == 0 || cfg.width == 0 || cfg.batch == 0 || cfg.epochs == 0 {
        return Err(user_error(
            "--points, --width, --batch and --epochs must be positive",
            "e.g. --points 500 --width 128 --batch 32 --epochs 30",
        ));
    }
    if !(0.0..1.0).contains(&cfg.val_fraction) {
        return Err(user_error(
            format!("--val-fraction {} is outside 0..1", cfg.val_fraction),
            "e.g. --val-fraction 0.1 holds out 10% of the frames",
        ));
    }
    let device = train::device(args.device == DeviceArg::Cuda)?;

    let opts = cfg.data_options();
    let t_load = Instant::now();
    let source = open_source(&args.data)
        .with_context(|| format!("cannot open the dataset {}", args.data.display()))?;
    let set = load_source_instances(source.as_ref(), &opts, printer)
        .with_context(|| format!("cannot load training data from {}", args.data.display()))?;
    printer.info(format!(
        "loaded {} instances from {} frames of {}/{} in {:.1} s ({} too little visible, {} with too few valid pixels)",
        set.instances.len(),
        set.frames,
        args.data.display(),
        set.split,
        t_load.elapsed().as_secs_f64(),
        set.skipped_low_visib,
        set.skipped_few_pixels
    ));
    if set.instances.is_empty() {
        return Err(user_error(
            format!("no usable object instances in {}", args.data.display()),
            "check that the dataset has depth/ and mask_visib/ images, or lower --min-visib-fract",
        ));
    }
    let wants_classes =
        cfg.model.is_rgb_only() || (cfg.model == ModelKind::Tnet && args.per_object);
    let classes = if wants_classes && cfg.classes.is_empty() {
        set.obj_ids().into_iter().collect()
    } else {
        cfg.classes.clone()
    };
    let cfg = TrainConfig {
        split: set.split.clone(),
        classes,
        ..cfg
    };
    let observer = ProgressObserver {
        printer,
        epoch: std::cell::Cell::new((0, cfg.epochs)),
    };
    let objects = if !cfg.model.predicts_rotation() {
        None
    } else {
        Some(
            load_dataset_objects(source.as_ref(), set.obj_ids(), cfg.loss_points).with_context(
                || format!("cannot load the object models of {}", args.data.display()),
            )?,
        )
    };
    let outcome = train::train(
        &cfg,
        &set,
        objects.as_ref(),
        &args.out,
        args.resume,
        &device,
        &observer,
    )?;
    printer.finish();
    if args.resume {
        printer.info(format!(
            "resumed after epoch {} (AdamW moments restarted)",
            outcome.resumed_from_epoch
        ));
    }
    if let Some(last) = outcome.history.last() {
        printer.info(format!(
            "{} after {} epochs over {} held-out instances ({} trained on): val loss {:.4}{}",
            cfg.model.name(),
            last.epoch,
            outcome.n_val,
            outcome.n_train,
            last.val_loss,
            val_summary(last)
        ));
    }
    printer.info(format!(
        "wrote {} ({}, {}, {}) in {:.1} s",
        args.out.display(),
        MODEL_FILE,
        METRICS_FILE,
        CURVE_FILE,
        started.elapsed().as_secs_f64()
    ));
    printer.hint(format!(
        "synthgen eval --checkpoint {} --data DIR",
        checkpoint.display()
    ));
    Ok(ExitStatus::Success)
}
