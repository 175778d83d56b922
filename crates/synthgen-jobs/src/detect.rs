//! The box detector's jobs as `synthgen detector train` and `synthgen detector run` run them:
//! the run folder's guards (a new run, `--force` over an old one, `--resume`), the training
//! with its epochs on the caller's `Progress`, and a trained detector over a dataset's frames
//! into a BOP detections file, with the recall per object where the frames have GT.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use synthgen_core::paths::resolve;
use synthgen_core::Progress;
use synthgen_detect::detections::{
    provenance_path, write_detections, write_provenance, Provenance,
};
use synthgen_detect::detector::{
    dataset_classes, detect_frames, train_detector, DetectSummary, Detector, DetectorConfig,
    DetectorOutcome,
};
use synthgen_formats::identity::{dataset_objects, describe_mismatches, mismatched_objects};
use synthgen_formats::layout::open_source;
use synthgen_formats::output::{check_apart, OutputLock};
use synthgen_train::eval::pick_split;
use synthgen_train::train::{self, RunKind, CONFIG_FILE};

use crate::{user_error, Log};

/// A detector training run: `synthgen detector train`'s arguments as data.
#[derive(Debug, Clone)]
pub struct DetectorTrainRequest {
    /// The run's configuration (`data`, and `split` empty for the dataset's only split); its
    /// `classes` empty for every object of the dataset. With `resume` only `epochs` counts:
    /// the rest is the run's own `config.json`, and a `data` given (not empty) must be the
    /// run's dataset.
    pub config: DetectorConfig,
    pub out: PathBuf,
    pub resume: bool,
    pub force: bool,
    pub jobs: Option<usize>,
    pub cuda: bool,
    /// The settings the command line gave, as (flag, `config.json` key): with `resume` each
    /// must equal the run's own.
    pub explicit: Vec<(String, String)>,
}

/// Trains `req`; the epochs and the summary go to `progress`.
pub fn train_detector_run(
    req: &DetectorTrainRequest,
    progress: &dyn Progress,
) -> Result<DetectorOutcome> {
    let log = Log::new(progress);
    let started = Instant::now();
    crate::use_threads(req.jobs);
    // Before any data is read: a bad --input must not cost a dataset load.
    req.config.validate_settings()?;
    if !req.resume || !req.config.data.as_os_str().is_empty() {
        check_apart(&req.out, &[("dataset", &req.config.data)])?;
    }
    let _lock = OutputLock::acquire(&req.out)?;
    crate::train::check_run_folder(&req.out, req.resume, req.force)?;
    let cfg = if req.resume {
        let saved: DetectorConfig =
            train::read_run_config(&req.out.join(CONFIG_FILE), RunKind::Detector)?;
        let given = &req.config.data;
        if !given.as_os_str().is_empty() && resolve(given) != resolve(&saved.data) {
            return Err(user_error(
                format!(
                    "--resume continues the run in {} on its own dataset {}, and --data is {}",
                    req.out.display(),
                    saved.data.display(),
                    given.display()
                ),
                "drop --data to resume, or train on the other dataset into a new --out",
            ));
        }
        check_apart(&req.out, &[("dataset", &saved.data)])?;
        crate::train::check_resumed_settings(&req.out, &saved, &req.config, &req.explicit)?;
        DetectorConfig {
            epochs: req.config.epochs,
            ..saved
        }
    } else {
        req.config.clone()
    };
    let source = open_source(&cfg.data)
        .with_context(|| format!("cannot open the dataset {}", cfg.data.display()))?;
    let cfg = if req.resume {
        cfg
    } else {
        let split = pick_split(
            source.as_ref(),
            (!cfg.split.is_empty()).then_some(cfg.split.as_str()),
        )?;
        let classes = if cfg.classes.is_empty() {
            dataset_classes(source.as_ref(), &split)?
        } else {
            cfg.classes.clone()
        };
        let known = dataset_objects(source.as_ref());
        let objects = classes
            .iter()
            .filter_map(|c| known.get(c).cloned())
            .collect();
        DetectorConfig {
            split,
            classes,
            objects,
            ..cfg
        }
    };
    cfg.validate()?;
    let device = train::device(req.cuda)?;
    log.info(format!(
        "training a detector of objects {:?} on {}/{} at {}x{}",
        cfg.classes,
        cfg.data.display(),
        cfg.split,
        cfg.input[0],
        cfg.input[1]
    ));
    let outcome = train_detector(
        &cfg,
        source.as_ref(),
        &req.out,
        req.resume,
        &device,
        progress,
    )?;
    if req.resume {
        log.info(format!(
            "resumed after epoch {} (AdamW moments restarted)",
            outcome.resumed_from_epoch
        ));
    }
    if let Some(last) = outcome.history.last() {
        log.info(format!(
            "detector after {} epochs: {:.1}% of {} boxes of the {} held-out frames found at IoU 0.5 ({} frames trained on)",
            last.epoch,
            100.0 * last.val_recall_50,
            last.val_boxes,
            outcome.val_frames,
            outcome.train_frames
        ));
    }
    log.info(format!(
        "wrote {} in {:.1} s",
        req.out.display(),
        started.elapsed().as_secs_f64()
    ));
    Ok(outcome)
}

/// A detector run over a dataset: `synthgen detector run`'s arguments as data.
#[derive(Debug, Clone)]
pub struct DetectRequest {
    pub data: PathBuf,
    pub split: Option<String>,
    /// The run folder (or its `model.safetensors`).
    pub checkpoint: PathBuf,
    /// The detections file to write; a folder (an existing one, or a path ending in `/`)
    /// gets [`DETECTIONS_FILE`] in it.
    pub out: PathBuf,
    pub min_score: f64,
    pub per_class: usize,
    pub jobs: Option<usize>,
    pub cuda: bool,
}

/// The file name `detector run --out DIR/` writes in DIR.
pub const DETECTIONS_FILE: &str = "detections.json";

/// `--out` as the file to write: a folder gets [`DETECTIONS_FILE`] in it.
pub fn detections_path(out: &Path) -> PathBuf {
    let names_folder = out.is_dir()
        || out
            .as_os_str()
            .to_string_lossy()
            .ends_with(std::path::MAIN_SEPARATOR);
    if names_folder {
        out.join(DETECTIONS_FILE)
    } else {
        out.to_path_buf()
    }
}

/// Runs `req`; returns the summary, the recall table (markdown, empty without GT) and the
/// file written.
pub fn detect_run(
    req: &DetectRequest,
    progress: &dyn Progress,
) -> Result<(DetectSummary, String, PathBuf)> {
    let log = Log::new(progress);
    crate::use_threads(req.jobs);
    if !(0.0..=1.0).contains(&req.min_score) || req.per_class == 0 || req.per_class > MAX_PER_CLASS
    {
        return Err(user_error(
            format!(
                "--min-score {} must be in 0..1 and --per-class {} in 1..={MAX_PER_CLASS}",
                req.min_score, req.per_class
            ),
            "e.g. --min-score 0.05 --per-class 10",
        ));
    }
    let out = detections_path(&req.out);
    let run_folder = if req.checkpoint.is_dir() {
        req.checkpoint.clone()
    } else {
        req.checkpoint
            .parent()
            .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
    };
    check_apart(
        &out,
        &[
            ("detector", run_folder.as_path()),
            ("dataset", req.data.as_path()),
        ],
    )?;
    let device = train::device(req.cuda)?;
    let det = Detector::load(&req.checkpoint, &device)
        .with_context(|| format!("cannot load the detector {}", req.checkpoint.display()))?;
    let source = open_source(&req.data)
        .with_context(|| format!("cannot open the dataset {}", req.data.display()))?;
    let wrong = mismatched_objects(&det.cfg.objects, source.as_ref());
    if !wrong.is_empty() {
        return Err(user_error(
            format!(
                "the detector was trained on other objects than {} has under the same ids: {}",
                req.data.display(),
                describe_mismatches(&wrong)
            ),
            "run a detector trained on this dataset's objects (detector train --data a set rendered from its models)",
        ));
    }
    if det.cfg.objects.is_empty() {
        log.warning(format!(
            "{} names no objects (written by an older synthgen): its ids are taken to be {}'s",
            run_folder.join(CONFIG_FILE).display(),
            req.data.display()
        ));
    }
    let split = pick_split(source.as_ref(), req.split.as_deref())?;
    let (found, summary) = detect_frames(
        &det,
        source.as_ref(),
        &split,
        req.min_score,
        req.per_class,
        progress,
    )?;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    write_detections(&out, &found)?;
    write_provenance(
        &out,
        &Provenance {
            written_by: format!("synthgen detector run {}", synthgen_core::VERSION),
            dataset: resolve(&req.data),
            split: split.clone(),
            frames: summary.frames_key.clone(),
            objects: det.cfg.objects.clone(),
            detector: resolve(&run_folder),
        },
    )?;
    log.info(format!(
        "wrote {} detections of {} frames of {}/{} to {} (and {}) in {:.1} s",
        found.len(),
        summary.frames,
        req.data.display(),
        split,
        out.display(),
        provenance_path(&out).display(),
        summary.seconds
    ));
    Ok((summary.clone(), recall_table(&summary.recall), out))
}

/// The most detections per object and frame `--per-class` may ask for.
pub const MAX_PER_CLASS: usize = 100;

/// The recall per object as a markdown table (empty without GT boxes).
pub fn recall_table(recall: &BTreeMap<u32, (usize, usize)>) -> String {
    if recall.is_empty() {
        return String::new();
    }
    let mut s =
        String::from("| object | GT boxes | found at IoU 0.5 | recall |\n|---:|---:|---:|---:|\n");
    let (mut n, mut hit) = (0, 0);
    for (obj, (g, h)) in recall {
        s += &format!(
            "| {obj} | {g} | {h} | {:.1}% |\n",
            100.0 * *h as f64 / (*g).max(1) as f64
        );
        n += g;
        hit += h;
    }
    s += &format!(
        "| all | {n} | {hit} | {:.1}% |\n",
        100.0 * hit as f64 / n.max(1) as f64
    );
    s
}
