//! An evaluation as `synthgen eval` runs it: a BOP results CSV, or a trained checkpoint, scored
//! against a dataset (the per-object table, BOP's Average Recall, the centre table of a TNet,
//! the stability report), the tables returned as the text the CLI prints on stdout, the JSON
//! and results files written where asked.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result};
use synthgen_detect::detections::{
    crop_boxes, crop_masks, join_detections, provenance_path, read_detections, read_provenance,
};
use synthgen_formats::identity::{describe_mismatches, frames_key, mismatched_objects};
use synthgen_formats::layout::open_source;
use synthgen_formats::source::FrameSource;
use synthgen_train::bop::{load_render_models, prepare_bop, BopOptions, BopReport, TargetsFrom};
use synthgen_train::data::{load_source_instances, CropBoxes, CropMasks, DataOptions, Instance};
use synthgen_train::eval::{
    eval_objects, evaluate, load_eval_objects, pick_split, prediction_estimates, read_gt,
    score_predictions,
};
use synthgen_train::models::ModelKind;
use synthgen_train::pose_model::{load_dataset_objects, Prediction};
use synthgen_train::results::{read_results_csv, write_results_csv, Estimate};
use synthgen_train::stability::{stability, to_markdown as stability_markdown, Sample};
use synthgen_train::train::{self, centre_error_m, load_model, read_config, CONFIG_FILE};

use synthgen_render::ObjectRenderer;

use std::path::PathBuf;

use synthgen_core::Progress;
use synthgen_fit::edge_refine::EdgeRefineOptions;
use synthgen_train::metrics::Rotations;

use crate::rgb_refine::{refine_estimates, BoxSource, VisibleBoxes};

use crate::{user_error, Printer, Stdout};

/// What to evaluate: `synthgen eval`'s arguments as data.
#[derive(Debug, Clone)]
pub struct EvalRequest {
    /// The dataset with the GT (BOP, Linemod or YCB-Video).
    pub data: PathBuf,
    /// A BOP results CSV to score (or `checkpoint`).
    pub results: Option<PathBuf>,
    /// A trained model to run and score (or `results`).
    pub checkpoint: Option<PathBuf>,
    pub split: Option<String>,
    pub min_visib_fract: f64,
    /// Write the scores as JSON here.
    pub json: Option<PathBuf>,
    pub seed: u64,
    /// Write the checkpoint's estimates as a BOP results CSV here.
    pub save_results: Option<PathBuf>,
    /// Also BOP's Average Recall (VSD, MSSD, MSPD).
    pub bop: bool,
    pub targets: Option<PathBuf>,
    /// Write the per-estimate BOP errors here.
    pub bop_errors: Option<PathBuf>,
    pub visib_gt_min: f64,
    /// The stability report instead of the scores.
    pub stability: bool,
    pub rotations: Rotations,
    /// Run the checkpoint on the GPU.
    pub cuda: bool,
    /// Refine the estimates on the RGB images before scoring ([`crate::rgb_refine`]): the
    /// results CSV's, or the checkpoint's (RGB models).
    pub refine: Option<EdgeRefineOptions>,
    /// With `refine`: the colours from these meshes (one folder per object, in the dataset's
    /// frame) instead of the dataset's models ([`refine_estimates`]).
    pub refine_models: Option<PathBuf>,
    /// With `refine`: what of each instance shows, when the refinement keeps to it.
    pub visible_boxes: VisibleBoxes,
    /// A BOP detections file: the RGB checkpoint's crops come from its boxes instead of the
    /// GT boxes (instances without one get no estimate), and `VisibleBoxes::Detected` reads
    /// them.
    pub detections: Option<PathBuf>,
    /// A detector (`synthgen detector train` run folder): the checkpoint runs as `synthgen
    /// predict` runs it — the detector on each frame, no GT box or mask read, the refinement
    /// where asked — and its results are scored: `eval` is `predict` followed by scoring
    /// ([`crate::predict::predict`], then the `results` path).
    pub detector: Option<PathBuf>,
}

/// What an evaluation printed and whether it counts as failed.
#[derive(Debug, Clone, Default)]
pub struct EvalOutcome {
    /// The tables, in order: what the CLI prints on stdout.
    pub stdout: String,
    /// Why the evaluation counts as failed though it scored (results rows that could not be
    /// read): the CLI prints it as an error and exits with 1.
    pub failed: Option<String>,
}

/// Evaluates `req`; messages go to `progress`, the tables into the outcome.
pub fn evaluate_request(req: &EvalRequest, progress: &dyn Progress) -> Result<EvalOutcome> {
    let stdout = Stdout::default();
    let printer = &Printer::new(progress, &stdout);
    let args = req;
    let failed = match (&args.results, &args.checkpoint) {
        (Some(csv), None) => run_results(args, csv, printer)?,
        (None, Some(ckpt)) if args.detector.is_some() => {
            let det = args.detector.as_deref().unwrap_or(Path::new(""));
            run_predicted(args, ckpt, det, printer)?
        }
        (None, Some(ckpt)) => {
            run_checkpoint(args, ckpt, printer)?;
            None
        }
        _ => {
            return Err(user_error(
                "give one of --results and --checkpoint",
                "synthgen eval --results results.csv --data DIR",
            ))
        }
    };
    Ok(EvalOutcome {
        stdout: stdout.take(),
        failed,
    })
}

/// The dataset in --data, BOP or Linemod (detected).
fn open_dataset(dir: &Path) -> Result<Box<dyn FrameSource>> {
    open_source(dir).with_context(|| format!("cannot open the dataset {}", dir.display()))
}

fn write_json(path: &Path, value: &serde_json::Value) -> Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    synthgen_formats::io::atomic_write(path, (text + "\n").as_bytes())?;
    Ok(())
}

/// A scratch folder removed when dropped (on errors too).
struct Scratch(PathBuf);

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// `eval --checkpoint --detector`: `predict` on the dataset's frames (its GT unread) into a
/// scratch folder, then its `results.csv` scored as `--results` scores one.
fn run_predicted(
    args: &EvalRequest,
    ckpt: &Path,
    detector: &Path,
    printer: &Printer<'_>,
) -> Result<Option<String>> {
    if args.detections.is_some() {
        return Err(user_error(
            "--detector runs the detector on each frame, and --detections gives a detector's boxes from a file: one or the other",
            "drop --detections (or --detector)",
        ));
    }
    if args.visible_boxes != VisibleBoxes::None {
        return Err(user_error(
            "with --detector the refinement keeps each estimate to its own detection's box: --visible-box does not apply",
            "drop --visible-box",
        ));
    }
    let config_path = ckpt.with_file_name(CONFIG_FILE);
    if config_path.is_file() {
        let cfg = read_config(&config_path)?;
        if !cfg.model.predicts_rotation() || cfg.model == ModelKind::Rnet {
            return Err(user_error(
                format!(
                    "--detector scores whole poses as `synthgen predict` writes them, and a {} checkpoint predicts {} only",
                    cfg.model.name(),
                    if cfg.model == ModelKind::Tnet { "the object centre" } else { "the rotation" }
                ),
                "score it from a detector's masks with --detections FILE (`synthgen detector run` writes one)",
            ));
        }
    }
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    let scratch = Scratch(std::env::temp_dir().join(format!(
        "synthgen-eval-predict-{}-{nanos}",
        std::process::id()
    )));
    crate::predict::predict(
        &crate::predict::PredictRequest {
            model: ckpt.to_path_buf(),
            detector: detector.to_path_buf(),
            input: crate::predict::PredictInput::Data {
                dir: args.data.clone(),
                split: args.split.clone(),
            },
            out: scratch.0.clone(),
            min_score: crate::predict::DEFAULT_MIN_SCORE,
            per_object: 1,
            draw: None,
            jobs: None,
            cuda: args.cuda,
            refine: args.refine.clone(),
            refine_models: args.refine_models.clone(),
            force: false,
        },
        printer.progress(),
    )?;
    let csv = scratch.0.join(crate::predict::RESULTS_FILE);
    if let Some(save) = &args.save_results {
        let bytes =
            std::fs::read(&csv).with_context(|| format!("cannot read {}", csv.display()))?;
        synthgen_formats::io::atomic_write(save, &bytes)?;
        printer.info(format!("wrote the estimates to {}", save.display()));
    }
    // Scored as they are: the refinement, if asked, ran inside predict.
    let scoring = EvalRequest {
        results: Some(csv.clone()),
        checkpoint: None,
        refine: None,
        refine_models: None,
        save_results: None,
        detector: None,
        ..args.clone()
    };
    run_results(&scoring, &csv, printer)
}

/// Scores a results CSV; returns why the evaluation counts as failed (unreadable rows), if so.
fn run_results(args: &EvalRequest, csv: &Path, printer: &Printer<'_>) -> Result<Option<String>> {
    let ds = open_dataset(&args.data)?;
    let split = pick_split(ds.as_ref(), args.split.as_deref())?;
    let detected = detections_for(args, ds.as_ref(), &split, printer)?;
    let detected = detected.as_ref().map(|d| &d.boxes);
    let gts = read_gt(ds.as_ref(), &split, args.min_visib_fract)?;
    let results = read_results_csv(csv)?;
    let mut estimates = results.estimates;
    if let Some(opts) = &args.refine {
        estimates = refined(
            args,
            ds.as_ref(),
            &split,
            &estimates,
            opts,
            detected,
            printer,
        )?;
    }
    if let Some(path) = &args.save_results {
        write_results_csv(path, &estimates)?;
        printer.info(format!(
            "wrote {} refined estimates to {}",
            estimates.len(),
            path.display()
        ));
    }
    let objects = load_eval_objects(ds.as_ref(), gts.iter().map(|g| g.obj_id))?;
    let report = evaluate(&gts, &estimates, &objects, args.rotations)?;
    printer.info(format!(
        "{} estimates from {} against {} GT instances of {}/{}",
        estimates.len(),
        csv.display(),
        gts.len(),
        args.data.display(),
        split
    ));
    if report.unmatched_estimates > 0 {
        printer.warning(format!(
            "{} estimates not scored (no GT of that object in that image, or more estimates than GT instances)",
            report.unmatched_estimates
        ));
    }
    printer.data(report.to_markdown(&objects))?;
    let mut json = report.to_json();
    if args.bop {
        let bop = bop_scores(args, ds.as_ref(), &split, &estimates, printer)?;
        json["bop"] = serde_json::to_value(&bop)?;
    }
    if let Some(path) = &args.json {
        write_json(path, &json)?;
        printer.info(format!("wrote {}", path.display()));
    }
    // Bad rows were skipped, not fatal (ripgrep-style): the scores are of the good rows, and
    // the exit code says some were left out.
    if results.skipped.is_empty() {
        return Ok(None);
    }
    for p in results.skipped.iter().take(10) {
        printer.warning(format!(
            "{}:{}: {} (row skipped)",
            csv.display(),
            p.line,
            p.message
        ));
    }
    if results.skipped.len() > 10 {
        printer.warning(format!(
            "... and {} more bad rows",
            results.skipped.len() - 10
        ));
    }
    Ok(Some(format!(
        "{} of {} rows of {} could not be read and were skipped; the scores above are of the others",
        results.skipped.len(),
        results.skipped.len() + estimates.len(),
        csv.display()
    )))
}

/// `estimates` refined on the RGB images of `split` (`--refine edges|views`; `detected`: the
/// boxes of `--detections`), with a line on what it did.
fn refined(
    args: &EvalRequest,
    ds: &dyn FrameSource,
    split: &str,
    estimates: &[Estimate],
    opts: &EdgeRefineOptions,
    detected: Option<&Arc<CropBoxes>>,
    printer: &Printer<'_>,
) -> Result<Vec<Estimate>> {
    let (out, summary) = refine_estimates(
        ds,
        split,
        estimates,
        opts,
        args.refine_models.as_deref(),
        BoxSource::new(args.visible_boxes, detected.map(|d| d.as_ref()))?,
        printer.progress(),
    )
    .with_context(|| format!("cannot refine the estimates on {}", args.data.display()))?;
    printer.info(format!(
        "refined {} of {} estimates on the RGB images, {} of them refused (too little of the contour on the image's edges; kept as estimated); cost {:.2} -> {:.2} px, {:.1} s",
        summary.refined,
        summary.estimates,
        summary.refused,
        summary.mean_cost_before_px,
        summary.mean_cost_after_px,
        summary.seconds
    ));
    match args.visible_boxes {
        VisibleBoxes::Gt => printer.info(format!(
            "{} of {} refined estimates kept to their GT visible box (the others: no GT instance of their object in their image)",
            summary.with_box, summary.refined
        )),
        VisibleBoxes::Detected => printer.info(format!(
            "{} of {} refined estimates kept to a detection's box (the others: no detection of their object in their image)",
            summary.with_box, summary.refined
        )),
        VisibleBoxes::None => {}
    }
    if let Some(dir) = &args.refine_models {
        printer.info(format!(
            "colours of {} of {} objects from {} (the others: their dataset models' colours, if any)",
            summary.colours_from_folder.len(),
            estimates
                .iter()
                .map(|e| e.obj_id)
                .collect::<std::collections::BTreeSet<_>>()
                .len(),
            dir.display()
        ));
    }
    Ok(out)
}

#[derive(Default)]
struct CentreAcc {
    errors_m: Vec<f64>,
}

impl CentreAcc {
    fn json(&self) -> serde_json::Value {
        let mut e = self.errors_m.clone();
        e.sort_by(f64::total_cmp);
        let n = e.len();
        let mean = e.iter().sum::<f64>() / n.max(1) as f64;
        let q = |p: f64| {
            e.get(((n as f64 - 1.0) * p).round() as usize)
                .copied()
                .unwrap_or(f64::NAN)
        };
        let frac = |t: f64| e.iter().filter(|&&v| v < t).count() as f64 / n.max(1) as f64;
        serde_json::json!({
            "n": n,
            "mean_centre_error_cm": mean * 100.0,
            "median_centre_error_cm": q(0.5) * 100.0,
            "p90_centre_error_cm": q(0.9) * 100.0,
            "acc_1cm": frac(0.01),
            "acc_2cm": frac(0.02),
        })
    }
}

/// The boxes of `--detections` that belong to `split` of `ds`, as the crops and the
/// refinement read them (read once: a checkpoint's crops and its refinement share them).
/// A file written by `detector run` must be of these frames and objects (its provenance);
/// entries of other images, of objects not in the image, or with boxes that do not fit the
/// image are counted and skipped; a file none of whose entries is of this split is refused.
fn detections_for(
    args: &EvalRequest,
    ds: &dyn FrameSource,
    split: &str,
    printer: &Printer<'_>,
) -> Result<Option<Detected>> {
    let Some(path) = &args.detections else {
        return Ok(None);
    };
    let list = read_detections(path)
        .with_context(|| format!("cannot read the detections {}", path.display()))?;
    let frames = ds.frames(&[split.to_string()])?;
    let cam = ds.camera();
    match read_provenance(path)? {
        Some(prov) => {
            let here = frames_key(&frames, [cam.width, cam.height]);
            if prov.frames != here {
                return Err(user_error(
                    format!(
                        "the detections in {} are of other frames: {}/{} ({} frames, {}x{}), and {}/{split} has {} frames ({}x{}){}",
                        path.display(),
                        prov.dataset.display(),
                        prov.split,
                        prov.frames.frames,
                        prov.frames.image_size[0],
                        prov.frames.image_size[1],
                        args.data.display(),
                        here.frames,
                        here.image_size[0],
                        here.image_size[1],
                        if prov.frames.frames == here.frames {
                            ": the same ids, other images"
                        } else {
                            ""
                        }
                    ),
                    format!(
                        "run the detector on this dataset: synthgen detector run --checkpoint {} --data {} --out FILE",
                        prov.detector.display(),
                        args.data.display()
                    ),
                ));
            }
            let wrong = mismatched_objects(&prov.objects, ds);
            if !wrong.is_empty() {
                return Err(user_error(
                    format!(
                        "the detections in {} name other objects than {} under the same ids: {}",
                        path.display(),
                        args.data.display(),
                        describe_mismatches(&wrong)
                    ),
                    "use detections of a detector trained on this dataset's objects",
                ));
            }
        }
        None => printer.info(format!(
            "{} has no provenance beside it ({}, which `synthgen detector run` writes): its entries are joined to the frames by scene, image and object ids alone",
            path.display(),
            provenance_path(path).display()
        )),
    }
    let shown: BTreeMap<(u32, u32), Option<std::collections::BTreeSet<u32>>> = frames
        .iter()
        .map(|f| {
            (
                (f.location.scene_id, f.location.im_id),
                Some(f.object_set().into_iter().collect()),
            )
        })
        .collect();
    let (kept, report) = join_detections(&list, &shown, [cam.width, cam.height]);
    if list.is_empty() {
        printer.warning(format!(
            "{} holds no detections: every instance is a miss",
            path.display()
        ));
    } else if report.kept == 0 && report.other_frames == report.entries {
        return Err(user_error(
            format!(
                "none of the {} detections in {} is of an image of {}/{split}: they are of another dataset or split",
                report.entries,
                path.display(),
                args.data.display()
            ),
            "give the detections `synthgen detector run` wrote for this dataset (and --split)",
        ));
    } else if report.skipped() > 0 {
        printer.warning(format!("{}: {}", path.display(), report.describe()));
    }
    Ok(Some(Detected {
        boxes: Arc::new(crop_boxes(&kept)),
        masks: Arc::new(crop_masks(&kept)),
        with_masks: kept.iter().filter(|d| d.segmentation.is_some()).count(),
        entries: kept.len(),
    }))
}

/// A detections file's entries of a split: boxes for the RGB models' crops, masks for the
/// depth models' points.
struct Detected {
    boxes: Arc<CropBoxes>,
    masks: Arc<CropMasks>,
    /// Entries kept, and those of them with a mask.
    with_masks: usize,
    entries: usize,
}

fn run_checkpoint(args: &EvalRequest, ckpt: &Path, printer: &Printer<'_>) -> Result<()> {
    let config_path = ckpt.with_file_name(CONFIG_FILE);
    if !config_path.exists() {
        return Err(user_error(
            format!("no {CONFIG_FILE} beside {}", ckpt.display()),
            "pass the model.safetensors of a folder written by `synthgen train`",
        ));
    }
    let cfg = read_config(&config_path)?;
    if args.save_results.is_some()
        && !matches!(
            cfg.model,
            ModelKind::Full | ModelKind::Rgb | ModelKind::RgbDense
        )
    {
        return Err(user_error(
            format!(
                "--save-results needs whole poses, and a {} checkpoint predicts {} only",
                cfg.model.name(),
                if cfg.model == ModelKind::Tnet {
                    "the object centre"
                } else {
                    "the rotation"
                }
            ),
            "save the results of a full or rgb checkpoint",
        ));
    }
    let device = train::device(args.cuda)?;
    let model = load_model(ckpt, &cfg, &device)?;
    let ds = open_dataset(&args.data)?;
    let wrong = mismatched_objects(&cfg.objects, ds.as_ref());
    if !wrong.is_empty() {
        return Err(user_error(
            format!(
                "the checkpoint {} was trained on other objects than {} has under the same ids: {}",
                ckpt.display(),
                args.data.display(),
                describe_mismatches(&wrong)
            ),
            "score a model trained on this dataset's objects",
        ));
    }
    let split = pick_split(ds.as_ref(), args.split.as_deref())?;
    let detected = detections_for(args, ds.as_ref(), &split, printer)?;
    let rgb_only = cfg.model.is_rgb_only();
    if detected
        .as_ref()
        .is_some_and(|d| !rgb_only && d.with_masks == 0 && d.entries > 0)
    {
        return Err(user_error(
            format!(
                "the depth models read each instance's points from its mask, and the detections in {} have none (\"segmentation\")",
                args.detections.as_deref().unwrap_or(Path::new("")).display()
            ),
            "run a detector trained with masks (detector train without --no-masks), or score an rgb / rgb-dense checkpoint",
        ));
    }
    let opts = DataOptions {
        min_visib_fract: args.min_visib_fract,
        seed: args.seed,
        split: Some(split),
        crop_boxes: detected
            .as_ref()
            .filter(|_| rgb_only)
            .map(|d| d.boxes.clone()),
        crop_masks: detected
            .as_ref()
            .filter(|_| !rgb_only)
            .map(|d| d.masks.clone()),
        ..cfg.data_options()
    };
    let mut set = load_source_instances(ds.as_ref(), &opts, printer)
        .with_context(|| format!("cannot load {}", args.data.display()))?;
    if let Some(path) = &args.detections {
        printer.info(format!(
            "{} instances {} {}; {} without a detection of their object get no estimate (scored as misses)",
            set.instances.len(),
            if rgb_only {
                "cropped from the boxes of"
            } else {
                "read from the masks of"
            },
            path.display(),
            set.skipped_undetected
        ));
    }
    if cfg.model.is_rgb_only() {
        // One head per trained object: others get no estimate (and so count as misses).
        let before = set.instances.len();
        set.instances.retain(|i| cfg.classes.contains(&i.obj_id));
        if set.instances.len() < before {
            printer.warning(format!(
                "{} instances of objects the {} model was not trained on (its classes: {:?}) get no estimate",
                before - set.instances.len(),
                cfg.model.name(),
                cfg.classes
            ));
        }
    }
    // With detections, instances without one are misses; none detected is a score of 0,
    // not an error.
    if set.instances.is_empty() && (args.detections.is_none() || set.skipped_undetected == 0) {
        return Err(user_error(
            format!("no usable object instances in {}", args.data.display()),
            if cfg.model.is_rgb_only() {
                "the RGB models need the colour images (rgb/) and each instance's visible box (scene_gt_info.json's bbox_visib, or mask_visib/) of the model's objects"
            } else {
                "the depth models need the depth images (depth/) and the visible masks (mask_visib/, or YCB-Video's -label.png)"
            },
        ));
    }
    // The models of every object with GT in the split: those the model has no class for are
    // scored as misses.
    let (objects, gts) = if !cfg.model.predicts_rotation() {
        (None, Vec::new())
    } else {
        let gts = read_gt(ds.as_ref(), &set.split, args.min_visib_fract)?;
        let mut ids = set.obj_ids();
        ids.extend(gts.iter().map(|g| g.obj_id));
        let objects = load_dataset_objects(ds.as_ref(), ids, cfg.loss_points)
            .with_context(|| format!("cannot load the object models of {}", args.data.display()))?;
        (Some(objects), gts)
    };
    let refs: Vec<_> = set.instances.iter().collect();
    let mut preds = if refs.is_empty() {
        Vec::new()
    } else {
        model.predict(&refs, objects.as_ref(), 64)?
    };
    if let Some(opts) = &args.refine {
        if !cfg.model.is_rgb_only() {
            return Err(user_error(
                format!(
                    "--refine edges and views refine the RGB models' estimates, and this is a {} checkpoint",
                    cfg.model.name()
                ),
                "drop --refine, or evaluate an rgb or rgb-dense checkpoint",
            ));
        }
        let estimates = prediction_estimates(&preds, &set.instances);
        let estimates = refined(
            args,
            ds.as_ref(),
            &set.split,
            &estimates,
            opts,
            detected.as_ref().map(|d| &d.boxes),
            printer,
        )?;
        for (p, e) in preds.iter_mut().zip(&estimates) {
            p.centre_m = Some(e.pose.translation_m.as_vec3().to_array());
            p.rotation = Some((e.pose.rotation, p.rotation.map_or(1.0, |r| r.1)));
        }
    }
    if let Some(path) = &args.save_results {
        write_results_csv(path, &prediction_estimates(&preds, &set.instances))?;
        printer.info(format!(
            "wrote {} estimates to {}",
            preds.len(),
            path.display()
        ));
    }
    printer.info(format!(
        "{} on {} instances of {}/{} ({} skipped: too few valid pixels)",
        cfg.model.name(),
        set.instances.len(),
        args.data.display(),
        set.split,
        set.skipped_few_pixels
    ));
    if cfg.model.is_rgb_only() {
        printer.info(match &args.detections {
            Some(path) => format!(
                "{}: each instance's crop is cut around a detection of its object ({}; no GT box)",
                cfg.model.name(),
                path.display()
            ),
            None => format!(
                "{}: each instance's crop is cut around its GT visible box (bbox_visib; no detector)",
                cfg.model.name()
            ),
        });
    }
    if cfg.model == ModelKind::Rnet {
        printer.warning(
            "rnet predicts rotation only: its poses take the GT translation (E_te = 0, ADD(-S) measures rotation alone)",
        );
    }
    if args.stability {
        let samples: Vec<Sample> = preds
            .iter()
            .zip(&set.instances)
            .map(|(p, i)| Sample {
                obj_id: i.obj_id,
                gt: i.pose,
                est: p.pose(i.pose.translation_m),
            })
            .collect();
        let groups = stability(&samples, 2);
        if groups.is_empty() {
            return Err(user_error(
                format!(
                    "no object has the same GT pose in two or more frames of {}",
                    args.data.display()
                ),
                "--stability needs repeated frames of a static object (same GT pose)",
            ));
        }
        printer.info(format!(
            "{} groups of frames with the same GT pose",
            groups.len()
        ));
        printer.data(stability_markdown(&groups))?;
        if let Some(path) = &args.json {
            write_json(path, &serde_json::json!({ "stability": groups }))?;
            printer.info(format!("wrote {}", path.display()));
        }
        return Ok(());
    }
    if cfg.model == ModelKind::Tnet {
        if args.bop {
            return Err(user_error(
                "--bop needs whole poses, and a tnet checkpoint predicts the object centre only",
                "evaluate a full (or rnet) checkpoint with --bop, or drop --bop for the centre error",
            ));
        }
        return centre_table(args, &set.instances, &preds, printer);
    }
    // Rotation models: score the estimates like a results CSV against the split's GT.
    let Some(objects) = objects else {
        return Err(anyhow::anyhow!("internal: objects not loaded"));
    };
    let report = score_predictions(&preds, &set.instances, &gts, &objects, args.rotations)?;
    printer.data(report.to_markdown(&eval_objects(&objects)))?;
    let mut json = report.to_json();
    if args.bop {
        let estimates = prediction_estimates(&preds, &set.instances);
        let bop = bop_scores(args, ds.as_ref(), &set.split, &estimates, printer)?;
        json["bop"] = serde_json::to_value(&bop)?;
    }
    if let Some(path) = &args.json {
        write_json(path, &json)?;
        printer.info(format!("wrote {}", path.display()));
    }
    Ok(())
}

fn centre_table(
    args: &EvalRequest,
    instances: &[Instance],
    preds: &[Prediction],
    printer: &Printer<'_>,
) -> Result<()> {
    let mut per_obj: BTreeMap<u32, CentreAcc> = BTreeMap::new();
    let mut all = CentreAcc::default();
    for (p, inst) in preds.iter().zip(instances) {
        let Some(c) = p.centre_m else { continue };
        let e = centre_error_m(c, inst);
        per_obj.entry(inst.obj_id).or_default().errors_m.push(e);
        all.errors_m.push(e);
    }
    let mut json = serde_json::Map::new();
    let mut md = String::from(
        "| object | n | mean centre error cm | median cm | p90 cm | < 1 cm | < 2 cm |\n|---|---:|---:|---:|---:|---:|---:|\n",
    );
    let rows = per_obj
        .iter()
        .map(|(id, a)| (id.to_string(), a))
        .chain(std::iter::once(("all".to_string(), &all)));
    for (name, a) in rows {
        let j = a.json();
        md += &format!(
            "| {name} | {} | {:.2} | {:.2} | {:.2} | {:.1}% | {:.1}% |\n",
            j["n"],
            j["mean_centre_error_cm"].as_f64().unwrap_or(f64::NAN),
            j["median_centre_error_cm"].as_f64().unwrap_or(f64::NAN),
            j["p90_centre_error_cm"].as_f64().unwrap_or(f64::NAN),
            100.0 * j["acc_1cm"].as_f64().unwrap_or(0.0),
            100.0 * j["acc_2cm"].as_f64().unwrap_or(0.0),
        );
        json.insert(name, j);
    }
    printer.data(&md)?;
    if let Some(path) = &args.json {
        write_json(path, &serde_json::Value::Object(json))?;
        printer.info(format!("wrote {}", path.display()));
    }
    Ok(())
}

/// BOP's Average Recall of `estimates` on `split` of `ds` (`--bop`), printed as a table.
fn bop_scores(
    args: &EvalRequest,
    ds: &dyn FrameSource,
    split: &str,
    estimates: &[Estimate],
    printer: &Printer<'_>,
) -> Result<BopReport> {
    let opts = BopOptions {
        visib_gt_min: args.visib_gt_min,
        ..BopOptions::default()
    };
    let setup = prepare_bop(ds, split, args.targets.as_deref(), &opts)
        .with_context(|| format!("cannot prepare BOP scoring of {}", args.data.display()))?;
    if let TargetsFrom::DatasetFile(p) = &setup.targets_from {
        printer.info(format!("BOP targets from {}", p.display()));
    }
    let renderer = ObjectRenderer::new(load_render_models(ds, setup.obj_ids())?)?;
    let report = setup.evaluate(estimates, Some(&renderer), &opts, printer)?;
    let c = &report.counts;
    printer.info(format!(
        "BOP 2019: {} targets ({} instances), {} estimates scored",
        c.targets, c.target_instances, c.estimates_scored
    ));
    for (n, what) in [
        (
            c.estimates_beyond_top_n,
            "beyond the inst_count best of their target (dropped, as bop_toolkit does)",
        ),
        (
            c.estimates_not_target,
            "for an (image, object) that is not a target",
        ),
        (
            c.estimates_unknown_image,
            "for an image the dataset does not have",
        ),
        (
            c.estimates_unknown_object,
            "for an object the dataset has no model of",
        ),
    ] {
        if n > 0 {
            printer.warning(format!("{n} estimates not scored: {what}"));
        }
    }
    if c.targets_repeated > 0 {
        printer.warning(format!(
            "{} entries of the targets file repeat an (image, object) listed before: the last one's inst_count counts, as bop_toolkit reads them",
            c.targets_repeated
        ));
    }
    if let Some(note) = &report.note {
        printer.warning(note.clone());
    }
    if let Some(path) = &args.bop_errors {
        write_json(path, &serde_json::to_value(&report.errors)?)?;
        printer.info(format!("wrote {}", path.display()));
    }
    printer.data(format!("\n{}", report.to_markdown()))?;
    Ok(report)
}
