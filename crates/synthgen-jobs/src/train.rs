//! A training run as `synthgen train` runs it: the run folder's guards (a new run, `--force`
//! over an old one, or `--resume` from its checkpoint), the configuration's checks before any
//! data is read, the instances loaded, `synthgen_train::train::train` with the epochs on the
//! caller's `Progress`, and the summary.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use synthgen_core::Progress;
use synthgen_formats::identity::{dataset_objects, describe_mismatches, mismatched_objects};
use synthgen_formats::layout::open_source;
use synthgen_formats::output::{check_apart, OutputLock};
use synthgen_train::data::load_source_instances;
use synthgen_train::models::ModelKind;
use synthgen_train::pose_model::load_dataset_objects;
use synthgen_train::train::{
    self, read_config, val_summary, ProgressObserver, TrainConfig, TrainOutcome, CONFIG_FILE,
    CURVE_FILE, METRICS_FILE, MODEL_FILE,
};

use crate::{user_error, Log};

/// A training run: `synthgen train`'s arguments as data.
#[derive(Debug, Clone)]
pub struct TrainRequest {
    /// The run's configuration (the dataset in `config.data`); with `resume`, only its
    /// `epochs` and `data` count, the rest is the run's own `config.json`.
    pub config: TrainConfig,
    /// The run folder.
    pub out: PathBuf,
    /// Continue the run in `out` from its checkpoint.
    pub resume: bool,
    /// Replace a run already in `out`.
    pub force: bool,
    /// TNet conditioned on the object class.
    pub per_object: bool,
    /// Worker threads (None: all cores).
    pub jobs: Option<usize>,
    /// Train on the GPU (candle's CUDA backend).
    pub cuda: bool,
    /// The settings the command line gave, as (flag, `config.json` key): with `resume` each
    /// must equal the run's own ([`check_resumed_settings`]).
    pub explicit: Vec<(String, String)>,
}

/// `--resume` continues a run as it was configured: each setting the command line gave
/// (`explicit`: flag and `config.json` key) must equal the run's (`saved`); a different one is
/// refused, naming both values, rather than silently ignored.
pub(crate) fn check_resumed_settings<T: serde::Serialize>(
    out: &Path,
    saved: &T,
    asked: &T,
    explicit: &[(String, String)],
) -> Result<()> {
    let (saved, asked) = (serde_json::to_value(saved)?, serde_json::to_value(asked)?);
    let differ: Vec<String> = explicit
        .iter()
        .filter(|(_, key)| saved.get(key) != asked.get(key))
        .map(|(flag, key)| {
            let show =
                |v: Option<&serde_json::Value>| v.map_or("none".to_string(), |v| v.to_string());
            format!(
                "{flag} {} (the run's: {})",
                show(asked.get(key)),
                show(saved.get(key))
            )
        })
        .collect();
    if differ.is_empty() {
        return Ok(());
    }
    Err(user_error(
        format!(
            "--resume continues the run in {} as it was configured, and the command line asks for other settings: {}",
            out.display(),
            differ.join(", ")
        ),
        format!(
            "drop them (only --epochs may change), or start a new run with --force or another --out; the run's settings are in {}",
            out.join(CONFIG_FILE).display()
        ),
    ))
}

/// The guards of a run folder: `--resume` needs its checkpoint; a new run into a folder that
/// holds one needs `--force`.
pub(crate) fn check_run_folder(out: &Path, resume: bool, force: bool) -> Result<()> {
    let checkpoint = out.join(MODEL_FILE);
    if resume && !checkpoint.exists() {
        return Err(user_error(
            format!("nothing to resume: {} does not exist", checkpoint.display()),
            "start the run without --resume",
        ));
    }
    if !resume && checkpoint.exists() && !force {
        return Err(user_error(
            format!("{} already holds a run", out.display()),
            "continue it with --resume, overwrite it with --force, or choose another --out",
        ));
    }
    Ok(())
}

/// Trains `req`; the epochs, the summary and a hint go to `progress`.
pub fn train_run(req: &TrainRequest, progress: &dyn Progress) -> Result<TrainOutcome> {
    let printer = &Log::new(progress);
    let args = req;
    let started = Instant::now();
    for ckpt in &args.config.init {
        if !ckpt.is_file() {
            return Err(user_error(
                format!("--init {} does not exist", ckpt.display()),
                "pass the model.safetensors of an earlier `synthgen train` run",
            ));
        }
    }
    if args.resume && !args.config.init.is_empty() {
        return Err(user_error(
            "--init and --resume do not go together",
            "--resume continues from the run's own checkpoint",
        ));
    }
    crate::use_threads(args.jobs);
    check_apart(&args.out, &[("dataset", &args.config.data)])?;
    let _lock = OutputLock::acquire(&args.out)?;
    check_run_folder(&args.out, args.resume, args.force)?;
    let cfg = if args.resume {
        let saved = read_config(&args.out.join(CONFIG_FILE))?;
        check_resumed_settings(&args.out, &saved, &req.config, &req.explicit)?;
        TrainConfig {
            epochs: req.config.epochs,
            data: req.config.data.clone(),
            ..saved
        }
    } else {
        req.config.clone()
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
    let device = train::device(args.cuda)?;

    let opts = cfg.data_options();
    let t_load = Instant::now();
    let source = open_source(&args.config.data)
        .with_context(|| format!("cannot open the dataset {}", args.config.data.display()))?;
    let set = load_source_instances(source.as_ref(), &opts, printer).with_context(|| {
        format!(
            "cannot load training data from {}",
            args.config.data.display()
        )
    })?;
    printer.info(format!(
        "loaded {} instances from {} frames of {}/{} in {:.1} s ({} too little visible, {} with too few valid pixels)",
        set.instances.len(),
        set.frames,
        args.config.data.display(),
        set.split,
        t_load.elapsed().as_secs_f64(),
        set.skipped_low_visib,
        set.skipped_few_pixels
    ));
    if set.instances.is_empty() {
        return Err(user_error(
            format!(
                "no usable object instances in {}",
                args.config.data.display()
            ),
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
    // What the ids stand for: a resumed run on other data must be of the same objects.
    let known = dataset_objects(source.as_ref());
    let objects = set
        .obj_ids()
        .iter()
        .filter_map(|id| known.get(id).cloned())
        .collect();
    let wrong = mismatched_objects(&cfg.objects, source.as_ref());
    if !wrong.is_empty() {
        return Err(user_error(
            format!(
                "the run in {} was trained on other objects than {} has under the same ids: {}",
                args.out.display(),
                args.config.data.display(),
                describe_mismatches(&wrong)
            ),
            "resume on a dataset of the same objects, or start a new run",
        ));
    }
    let cfg = TrainConfig {
        split: set.split.clone(),
        classes,
        objects,
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
                || {
                    format!(
                        "cannot load the object models of {}",
                        args.config.data.display()
                    )
                },
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
        args.out.join(MODEL_FILE).display()
    ));
    Ok(outcome)
}
