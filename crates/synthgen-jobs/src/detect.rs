//! The box detector's jobs as `synthgen detector train` and `synthgen detector run` run them:
//! the run folder's guards (a new run, `--force` over an old one, `--resume`), the training
//! with its epochs on the caller's `Progress`, and a trained detector over a dataset's frames
//! into a BOP detections file, with the recall per object where the frames have GT.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use synthgen_core::Progress;
use synthgen_detect::detections::write_detections;
use synthgen_detect::detector::{
    dataset_classes, detect_frames, train_detector, DetectSummary, Detector, DetectorConfig,
    DetectorOutcome,
};
use synthgen_formats::layout::open_source;
use synthgen_formats::output::{check_apart, OutputLock};
use synthgen_train::eval::pick_split;
use synthgen_train::train::{self, CONFIG_FILE};

use crate::{user_error, Log};

/// A detector training run: `synthgen detector train`'s arguments as data.
#[derive(Debug, Clone)]
pub struct DetectorTrainRequest {
    /// The run's configuration (`data`, and `split` empty for the dataset's only split); its
    /// `classes` empty for every object of the dataset; with `resume` only `epochs` counts,
    /// the rest is the run's own `config.json`.
    pub config: DetectorConfig,
    pub out: PathBuf,
    pub resume: bool,
    pub force: bool,
    pub jobs: Option<usize>,
    pub cuda: bool,
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
    check_apart(&req.out, &[("dataset", &req.config.data)])?;
    let _lock = OutputLock::acquire(&req.out)?;
    crate::train::check_run_folder(&req.out, req.resume, req.force)?;
    let source = open_source(&req.config.data)
        .with_context(|| format!("cannot open the dataset {}", req.config.data.display()))?;
    let cfg = if req.resume {
        let saved: DetectorConfig =
            train::read_json(&req.out.join(CONFIG_FILE), "detector config.json")?;
        DetectorConfig {
            epochs: req.config.epochs,
            ..saved
        }
    } else {
        let split = pick_split(
            source.as_ref(),
            (!req.config.split.is_empty()).then_some(req.config.split.as_str()),
        )?;
        let classes = if req.config.classes.is_empty() {
            dataset_classes(source.as_ref(), &split)?
        } else {
            req.config.classes.clone()
        };
        DetectorConfig {
            split,
            classes,
            ..req.config.clone()
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
    /// The detections file to write.
    pub out: PathBuf,
    pub min_score: f64,
    pub per_class: usize,
    pub jobs: Option<usize>,
    pub cuda: bool,
}

/// Runs `req`; returns the summary and the recall table (markdown, empty without GT).
pub fn detect_run(req: &DetectRequest, progress: &dyn Progress) -> Result<(DetectSummary, String)> {
    let log = Log::new(progress);
    crate::use_threads(req.jobs);
    if !(0.0..=1.0).contains(&req.min_score) || req.per_class == 0 {
        return Err(user_error(
            format!(
                "--min-score {} must be in 0..1 and --per-class {} at least 1",
                req.min_score, req.per_class
            ),
            "e.g. --min-score 0.05 --per-class 10",
        ));
    }
    let device = train::device(req.cuda)?;
    let det = Detector::load(&req.checkpoint, &device)
        .with_context(|| format!("cannot load the detector {}", req.checkpoint.display()))?;
    let source = open_source(&req.data)
        .with_context(|| format!("cannot open the dataset {}", req.data.display()))?;
    let split = pick_split(source.as_ref(), req.split.as_deref())?;
    let (found, summary) = detect_frames(
        &det,
        source.as_ref(),
        &split,
        req.min_score,
        req.per_class,
        progress,
    )?;
    write_detections(&req.out, &found)?;
    log.info(format!(
        "wrote {} detections of {} frames of {}/{} to {} in {:.1} s",
        found.len(),
        summary.frames,
        req.data.display(),
        split,
        req.out.display(),
        summary.seconds
    ));
    Ok((summary.clone(), recall_table(&summary.recall)))
}

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
