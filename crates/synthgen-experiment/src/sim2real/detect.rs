//! The detector step of `experiment sim2real` (issue 52): a detector trained on the
//! experiment's own synthetic frames (or one the user names), run on the real test frames
//! with no GT, its detections written as a BOP detections file (`detections.json`) and
//! scored as bop_toolkit's `eval_bop22_coco.py` scores them over the test scenes' images
//! (`detection_targets.json`). The pose rows read their crops or points from these
//! detections for the report's `no_gt` scores. Kept once done (`detector.json`, written
//! last), so a re-run with the same options resumes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use synthgen_core::paths::resolve;
use synthgen_detect::detector::DetectorConfig;
use synthgen_formats::io::atomic_write;
use synthgen_formats::source::SourceFrame;
use synthgen_jobs::detect::{detect_run, train_detector_run, DetectRequest, DetectorTrainRequest};
use synthgen_jobs::detect_eval::{detection_eval_run, BboxType, DetectionEvalRequest};

use crate::options::DetectorChoice;
use crate::user_error;
use crate::Log;

/// The detector trained here (a `detector train` run folder).
pub const DETECTOR_DIR: &str = "detector";
/// The detections on the test dataset's frames (BOP 2023's detections format).
pub const DETECTIONS_FILE: &str = "detections.json";
/// The images the detections are scored on: the test scenes' (BOP targets format).
pub const TARGETS_FILE: &str = "detection_targets.json";
/// The detection scores as `synthgen detector eval --out` writes them.
pub const SCORES_FILE: &str = "detection_scores.json";
/// A few test frames with the GT masks against the detections.
pub const PICTURES_DIR: &str = "detection_pictures";
/// The step's record, written last.
pub const RECORD_FILE: &str = "detector.json";
/// Everything this step writes in the experiment's folder (what `--force` removes).
pub const STALE: &[&str] = &[
    DETECTOR_DIR,
    DETECTIONS_FILE,
    "detections.provenance.json",
    TARGETS_FILE,
    SCORES_FILE,
    PICTURES_DIR,
    RECORD_FILE,
];
/// Detections below this score are not written (`detector run`'s default).
const MIN_SCORE: f64 = 0.05;
/// At most this many detections per object and image (`detector run`'s default).
const PER_CLASS: usize = 10;
/// Test frames drawn into [`PICTURES_DIR`].
const PICTURES: usize = 6;

/// What decides the detections: a re-run with the same key reuses them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectorKey {
    /// The detector's run folder.
    pub detector: PathBuf,
    /// Trained here: the synthetic set, epochs and seed (None: a detector given).
    pub trained_on: Option<PathBuf>,
    pub epochs: Option<usize>,
    pub seed: u64,
    pub test: PathBuf,
    pub test_scenes: Vec<u32>,
    /// A detector given: its checkpoint's size and modification time (seconds), so that one
    /// trained again in the same folder is run again.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checkpoint: Option<[u64; 2]>,
}

/// `detector.json`: the detector, its detections on the test frames and their scores.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectorRecord {
    pub key: DetectorKey,
    /// The training's wall time (None: a detector given, not trained here).
    pub seconds_train: Option<f64>,
    /// Detection over the test dataset's frames.
    pub seconds_detect: f64,
    pub frames: usize,
    pub detections: usize,
    /// `report.json["detection"]`: bbox and segm AP as bop_toolkit computes them (amodal
    /// boxes), over the test scenes' images, and per object.
    pub detection: serde_json::Value,
}

/// What the step needs from the experiment.
pub struct DetectorPlan<'a> {
    pub choice: &'a DetectorChoice,
    /// The synthetic set a detector is trained on (its frames must show the test objects).
    pub train_set: &'a Path,
    pub classes: Vec<u32>,
    pub epochs: usize,
    pub seed: u64,
    pub test: &'a Path,
    pub test_scenes: &'a [u32],
    /// The test frames (of the test scenes), whose GT objects make the targets when the
    /// dataset has no `test_targets_bop19.json`.
    pub test_frames: &'a [SourceFrame],
    pub jobs: Option<usize>,
}

/// Refuses, before anything is computed, a `--detector DIR` that holds no detector or one
/// trained on other objects than the test dataset has under the same ids.
pub fn check_choice(
    choice: &DetectorChoice,
    test: &dyn synthgen_formats::source::FrameSource,
) -> Result<()> {
    let DetectorChoice::Run(dir) = choice else {
        return Ok(());
    };
    let hint = "name the folder `synthgen detector train --out` wrote, `train` to train one on the experiment's frames, or `none`";
    if !dir.join(synthgen_train::train::MODEL_FILE).is_file() {
        return Err(user_error(
            format!(
                "--detector {}: no detector there ({} is missing)",
                dir.display(),
                synthgen_train::train::MODEL_FILE
            ),
            hint,
        ));
    }
    let cfg: DetectorConfig = synthgen_train::train::read_run_config(
        &dir.join(synthgen_train::train::CONFIG_FILE),
        synthgen_train::train::RunKind::Detector,
    )
    .with_context(|| format!("--detector {}", dir.display()))?;
    let wrong = synthgen_formats::identity::mismatched_objects(&cfg.objects, test);
    if !wrong.is_empty() {
        return Err(user_error(
            format!(
                "--detector {} was trained on other objects than the test dataset {} has under the same ids: {}",
                dir.display(),
                test.root().display(),
                synthgen_formats::identity::describe_mismatches(&wrong)
            ),
            hint,
        ));
    }
    Ok(())
}

/// The detections of the plan's detector on the test frames and their scores: the record
/// of an earlier run with the same key, else trained (where asked), detected and scored now
/// (`computed` true). None with `--detector none`.
pub fn ensure_detections(
    out: &Path,
    plan: &DetectorPlan,
    printer: &Log,
) -> Result<Option<(DetectorRecord, bool)>> {
    let detector = match plan.choice {
        DetectorChoice::None => {
            // A record of an earlier run stays out of this report.
            return Ok(None);
        }
        DetectorChoice::Train => std::path::absolute(out.join(DETECTOR_DIR))?,
        DetectorChoice::Run(dir) => resolve(dir),
    };
    let trained_here = matches!(plan.choice, DetectorChoice::Train);
    let key = DetectorKey {
        detector: detector.clone(),
        trained_on: trained_here.then(|| resolve(plan.train_set)),
        epochs: trained_here.then_some(plan.epochs),
        seed: plan.seed,
        test: resolve(plan.test),
        test_scenes: plan.test_scenes.to_vec(),
        checkpoint: (!trained_here)
            .then(|| stamp(&detector.join(synthgen_train::train::MODEL_FILE)))
            .flatten(),
    };
    let record_path = out.join(RECORD_FILE);
    if let Some(r) = std::fs::read_to_string(&record_path)
        .ok()
        .and_then(|t| serde_json::from_str::<DetectorRecord>(&t).ok())
        .filter(|r| r.key == key && out.join(DETECTIONS_FILE).is_file())
    {
        printer.info(format!(
            "reusing the detections in {}",
            out.join(DETECTIONS_FILE).display()
        ));
        return Ok(Some((r, false)));
    }
    // Whatever an earlier run left is of another detector (or unfinished).
    let _ = std::fs::remove_file(&record_path);
    let mut seconds_train = None;
    if trained_here {
        let t = Instant::now();
        train_detector(plan, &detector, printer)?;
        seconds_train = Some(t.elapsed().as_secs_f64());
    }
    let t = Instant::now();
    printer.info(format!(
        "detecting the test objects in {} (no GT read)",
        plan.test.display()
    ));
    let (summary, _, path) = detect_run(
        &DetectRequest {
            data: plan.test.to_path_buf(),
            split: None,
            checkpoint: detector.clone(),
            out: out.join(DETECTIONS_FILE),
            min_score: MIN_SCORE,
            per_class: PER_CLASS,
            jobs: plan.jobs,
            cuda: false,
        },
        printer.progress(),
    )?;
    let seconds_detect = t.elapsed().as_secs_f64();
    let targets = out.join(TARGETS_FILE);
    write_targets(&targets, plan)?;
    let scores = detection_eval_run(
        &DetectionEvalRequest {
            data: plan.test.to_path_buf(),
            split: None,
            detections: path.clone(),
            targets: Some(targets),
            all_frames: false,
            bbox_type: BboxType::Amodal,
            out: Some(out.join(SCORES_FILE)),
            gt_out: None,
            draw: Some((out.join(PICTURES_DIR), PICTURES)),
            jobs: plan.jobs,
        },
        printer.progress(),
    )?;
    let list = synthgen_detect::detections::read_detections(&path)?;
    let record = DetectorRecord {
        key,
        seconds_train,
        seconds_detect,
        frames: summary.frames,
        detections: list.len(),
        detection: scores.report_block(),
    };
    printer.info(format!(
        "detections on the test frames: bbox AP {:.3} (AP50 {:.3}), segm AP {}, over {} GT instances",
        scores.bbox.stat("AP"),
        scores.bbox.stat("AP50"),
        scores
            .segm
            .as_ref()
            .map_or("– (no masks)".to_string(), |s| format!(
                "{:.3} (AP50 {:.3})",
                s.stat("AP"),
                s.stat("AP50")
            )),
        scores.n_gt
    ));
    atomic_write(
        &record_path,
        (serde_json::to_string_pretty(&record)? + "\n").as_bytes(),
    )?;
    Ok(Some((record, true)))
}

/// A file's size and modification time (seconds since the epoch), if it reads.
fn stamp(path: &Path) -> Option<[u64; 2]> {
    let m = std::fs::metadata(path).ok()?;
    let t = m
        .modified()
        .ok()?
        .duration_since(std::time::UNIX_EPOCH)
        .ok()?;
    Some([m.len(), t.as_secs()])
}

/// The experiment's detections ([`DETECTIONS_FILE`] in `out`) of the test dataset's frames of
/// `splits` (all when empty), joined to them as `eval --detections` joins a file: entries of
/// other images, of objects an image has no instance of, or with boxes or masks that do not
/// fit the image are left out (the count said on `printer`).
pub fn joined_detections(
    out: &Path,
    test: &dyn synthgen_formats::source::FrameSource,
    splits: &[String],
    printer: &Log,
) -> Result<Vec<synthgen_detect::detections::Detection>> {
    let path = out.join(DETECTIONS_FILE);
    let list = synthgen_detect::detections::read_detections(&path)?;
    let shown: BTreeMap<(u32, u32), Option<std::collections::BTreeSet<u32>>> = test
        .frames(splits)?
        .iter()
        .map(|f| {
            (
                (f.location.scene_id, f.location.im_id),
                Some(f.object_set().into_iter().collect()),
            )
        })
        .collect();
    let cam = test.camera();
    let (kept, report) =
        synthgen_detect::detections::join_detections(&list, &shown, [cam.width, cam.height]);
    if report.skipped() > 0 {
        printer.info(format!("{}: {}", path.display(), report.describe()));
    }
    Ok(kept)
}

/// Epochs of a detector trained here: `--detector-epochs`, else 30 (2 with `--quick`).
pub fn epochs(given: Option<usize>, quick: bool) -> usize {
    given.unwrap_or(if quick { 2 } else { 30 })
}

/// Trains the detector into `dir` on the plan's synthetic set (resuming an unfinished
/// training of the same set there).
fn train_detector(plan: &DetectorPlan, dir: &Path, printer: &Log) -> Result<()> {
    let config = DetectorConfig {
        epochs: plan.epochs,
        seed: plan.seed,
        ..DetectorConfig::new(
            plan.train_set.to_path_buf(),
            String::new(),
            plan.classes.clone(),
        )
    };
    let saved = dir.join(synthgen_train::train::CONFIG_FILE);
    let resume = std::fs::read_to_string(&saved)
        .ok()
        .and_then(|t| serde_json::from_str::<DetectorConfig>(&t).ok())
        .is_some_and(|c| {
            dir.join(synthgen_train::train::MODEL_FILE).is_file()
                && resolve(&c.data) == resolve(&config.data)
                && c.classes == config.classes
                && c.seed == config.seed
                && c.epochs <= config.epochs
        });
    if !resume && dir.exists() {
        std::fs::remove_dir_all(dir).with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    printer.info(format!(
        "{} the detector on {} ({} epochs) into {}",
        if resume { "resuming" } else { "training" },
        plan.train_set.display(),
        plan.epochs,
        dir.display()
    ));
    train_detector_run(
        &DetectorTrainRequest {
            config: if resume {
                DetectorConfig {
                    data: PathBuf::new(),
                    ..config
                }
            } else {
                config
            },
            out: dir.to_path_buf(),
            resume,
            force: false,
            jobs: plan.jobs,
            cuda: false,
            explicit: Vec::new(),
        },
        printer.progress(),
    )?;
    Ok(())
}

/// One entry of a BOP targets file.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Target {
    scene_id: u32,
    im_id: u32,
    obj_id: u32,
    inst_count: u32,
}

/// The BOP targets of the test scenes: the dataset's `test_targets_bop19.json` restricted to
/// them, else every test frame's GT objects (instances with a visible fraction of at least
/// 0.1 where `scene_gt_info` says, as BOP's targets count them).
fn write_targets(path: &Path, plan: &DetectorPlan) -> Result<()> {
    let keep = |scene: u32| plan.test_scenes.is_empty() || plan.test_scenes.contains(&scene);
    let dataset = plan.test.join(synthgen_jobs::detect_eval::TARGETS_FILE);
    let targets: Vec<Target> = if dataset.is_file() {
        let text = std::fs::read_to_string(&dataset)
            .with_context(|| format!("cannot read {}", dataset.display()))?;
        let all: Vec<Target> = serde_json::from_str(&text).map_err(|e| {
            user_error(
                format!("{} is not a BOP targets file: {e}", dataset.display()),
                "a JSON list of {\"scene_id\", \"im_id\", \"obj_id\", \"inst_count\"}",
            )
        })?;
        all.into_iter().filter(|t| keep(t.scene_id)).collect()
    } else {
        let mut out = Vec::new();
        for f in plan.test_frames {
            let mut counts: BTreeMap<u32, u32> = BTreeMap::new();
            for (i, g) in f.gt.iter().enumerate() {
                let visible = f
                    .gt_info
                    .as_ref()
                    .and_then(|v| v.get(i))
                    .is_none_or(|info| info.visib_fract >= 0.1);
                if visible {
                    *counts.entry(g.obj_id).or_default() += 1;
                }
            }
            out.extend(counts.into_iter().map(|(obj_id, inst_count)| Target {
                scene_id: f.location.scene_id,
                im_id: f.location.im_id,
                obj_id,
                inst_count,
            }));
        }
        out
    };
    if targets.is_empty() {
        return Err(user_error(
            format!(
                "no BOP target in the test scenes of {}",
                plan.test.display()
            ),
            "the test frames show no object with a visible fraction of at least 0.1",
        ));
    }
    atomic_write(
        path,
        (serde_json::to_string_pretty(&targets)? + "\n").as_bytes(),
    )?;
    Ok(())
}

/// The detection section of `report.md`: where the detector came from and its scores.
pub fn markdown(d: &DetectorRecord) -> String {
    let block = &d.detection;
    let num = |v: &serde_json::Value| v.as_f64().map_or("–".to_string(), |x| format!("{x:.3}"));
    let mut md = format!(
        "\n## From raw frames\n\nDetector: {} ({}); detections of {} test-dataset frames in `{DETECTIONS_FILE}` ({} entries, {:.1} s). Scored as bop_toolkit's `eval_bop22_coco.py` scores them (amodal boxes, the test scenes' images of `{TARGETS_FILE}`, {} GT instances): bbox AP {} (AP50 {}), segm AP {} (AP50 {}).\n\n| object | GT | bbox AP | bbox AP50 | segm AP | segm AP50 |\n|---:|---:|---:|---:|---:|---:|\n",
        d.key.detector.display(),
        match (&d.key.trained_on, d.seconds_train) {
            (Some(set), Some(sec)) => format!(
                "trained here on {} for {} epochs in {:.0} s",
                set.display(),
                d.key.epochs.unwrap_or(0),
                sec
            ),
            (Some(set), None) => format!("trained here on {}", set.display()),
            (None, _) => "given with --detector".to_string(),
        },
        d.frames,
        d.detections,
        d.seconds_detect,
        block["n_gt"],
        num(&block["bbox_ap"]),
        num(&block["bbox_ap50"]),
        num(&block["segm_ap"]),
        num(&block["segm_ap50"]),
    );
    if let Some(objects) = block["objects"].as_object() {
        let mut ids: Vec<&String> = objects.keys().collect();
        ids.sort_by_key(|k| (k.parse::<u64>().unwrap_or(u64::MAX), (*k).clone()));
        for k in ids {
            let o = &objects[k];
            md += &format!(
                "| {k} | {} | {} | {} | {} | {} |\n",
                o["n_gt"].as_f64().unwrap_or(0.0),
                num(&o["bbox_ap"]),
                num(&o["bbox_ap50"]),
                num(&o["segm_ap"]),
                num(&o["segm_ap50"]),
            );
        }
    }
    md
}
