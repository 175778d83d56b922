//! `synthgen experiment sim2real --model rgb|rgb-dense`: synthetic to real for the RGB models,
//! on real test frames that need no depth (Linemod-Occluded's photographs). The scene comes
//! from a scene fit to `--fit` (from the GT poses and cameras alone where there is no depth:
//! no sensor fit, the RGB models read none) or from `--scene`; synthetic sets of the test
//! objects are rendered with the realistic raster (the result), the plain raster, and at a
//! smaller equal count with Cycles and both rasters; one RGB model per set is trained on
//! synthetic frames only and scored on the real test frames with their GT visible boxes
//! (5cm5°, ADD(-S), BOP's MSSD and MSPD) per object and per scene, beside the naive box
//! baseline and, when `--fit` frames show the objects, a model trained on real frames. Every
//! step is kept once done, so a re-run with the same options resumes.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use synthgen_core::scene::{DepthModel, Shading};
use synthgen_core::{NoProgress, SceneSpec};
use synthgen_formats::io::atomic_write;
use synthgen_formats::layout::open_source;
use synthgen_formats::output::{check_apart, OutputLock};
use synthgen_formats::source::FrameSource;
use synthgen_pipeline::{Backend, BlenderSettings};
use synthgen_train::baseline::MeanBoxPose;
use synthgen_train::bop::{prepare_bop, BopOptions, BopReport, BopSetup};
use synthgen_train::data::{load_source_instances, DataOptions, Instance};
use synthgen_train::eval::{
    eval_objects, evaluate, evaluate_per_scene, prediction_estimates, read_gt, GtInstance,
    ObjectScores,
};
use synthgen_train::metrics::Rotations;
use synthgen_train::models::rgb::{Translation, DEFAULT_RGB_CROP};
use synthgen_train::models::ModelKind;
use synthgen_train::pose_model::{load_dataset_objects, Objects, Prediction};
use synthgen_train::results::{write_results_csv, Estimate};
use synthgen_train::train::{self, load_model, Schedule, TrainConfig, MODEL_FILE};

use super::{RenderPlan, TestObject};
use crate::options::{Refine, Sim2realModel, Sim2realOptions};
use crate::settings::{read_row_file, row_dir, ROW_FILE};
use crate::user_error;
use crate::Log;
use synthgen_fit::edge_refine::EdgeRefineOptions;
use synthgen_jobs::rgb_refine::{refine_estimates, BoxSource, VisibleBoxes};

/// Instances below this visible fraction are neither trained on nor scored (BOP's rule).
const MIN_VISIB_FRACT: f64 = 0.1;
/// Model points per object in the rotation loss.
const LOSS_POINTS: usize = 100;
/// Crops per prediction batch.
const PREDICT_BATCH: usize = 64;
/// The row whose numbers are the result.
pub const MAIN_ROW: &str = "synth_realistic";
/// The naive box baseline.
pub const NAIVE_BOX: &str = "naive_box";
/// A model trained on the --fit frames.
pub const REAL_ONLY: &str = "real_only";
/// A row's estimates on the test frames, as a BOP results CSV (bop_toolkit reads it;
/// `synthgen eval --results`, `scripts/overlay_estimates.py`).
pub const RESULTS_FILE: &str = "results.csv";

/// Everything that decides the numbers of an RGB sim2real experiment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RgbSettings {
    pub model: String,
    pub fit: Option<PathBuf>,
    pub test: PathBuf,
    pub test_scenes: Vec<u32>,
    pub fit_scenes: Vec<u32>,
    /// `--scene`'s text (the scene it renders), when given.
    pub scene: Option<String>,
    pub objects: Vec<TestObject>,
    pub frames: usize,
    pub cycles_frames: usize,
    pub epochs: usize,
    pub batch: usize,
    pub lr: f64,
    pub width: usize,
    pub crop_size: u32,
    pub seed: u64,
    pub quick: bool,
    /// With `--refine views`: `--models`, whose colours the refinement compares with the real
    /// images (the dataset's own models may carry none; `edges` compares no colours).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub colour_models: Option<PathBuf>,
    /// With `--refine edges` or `views` (the latter with a view search): each trained row's
    /// estimates refined on the real RGB images with these settings (thresholds, weights, the
    /// view search), recorded whole so that resuming an experiment refined with other settings (an older
    /// synthgen's defaults) is refused rather than mixing rows refined two ways.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine_options: Option<EdgeRefineOptions>,
    /// `--refine`: none, edges or views (the options above are its settings).
    #[serde(default)]
    pub refine: Refine,
    /// With `--refine edges|views`: what of each test instance shows, which the refinement
    /// keeps to (`--visible-box`; absent: none, as before it existed).
    #[serde(default, skip_serializing_if = "no_box")]
    pub visible_box: VisibleBoxes,
}

fn no_box(b: &VisibleBoxes) -> bool {
    *b == VisibleBoxes::None
}

impl RgbSettings {
    fn kind(&self) -> ModelKind {
        if self.model == "rgb" {
            ModelKind::Rgb
        } else {
            ModelKind::RgbDense
        }
    }
}

/// The scores of a row on some GT instances (the names `report.json` promises).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scores {
    /// GT instances (visible fraction ≥ 0.1); one without an estimate is a miss.
    pub n: usize,
    /// BOP's average recall of MSPD and MSSD over the BOP targets among them (None: no target).
    pub ar_mspd: Option<f64>,
    pub ar_mssd: Option<f64>,
    pub acc_5cm5deg: f64,
    /// ADD(-S) below 10 % of the diameter.
    pub add_s_acc: f64,
    pub median_re_deg: Option<f64>,
    pub median_te_cm: Option<f64>,
}

impl Scores {
    fn new(s: &ObjectScores, mspd: Option<f64>, mssd: Option<f64>) -> Scores {
        Scores {
            n: s.n_gt,
            ar_mspd: mspd,
            ar_mssd: mssd,
            acc_5cm5deg: s.acc_5cm5deg,
            add_s_acc: s.add_s_acc,
            median_re_deg: s.median_re_deg,
            median_te_cm: s.median_te_cm,
        }
    }
}

/// `rows/NAME/row.json` of an RGB row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RgbRow {
    pub name: String,
    pub what: String,
    /// Synthetic frames rendered for it (None: real frames or no training).
    pub frames: Option<usize>,
    pub trained_on: Option<PathBuf>,
    pub train_instances: usize,
    pub epochs: usize,
    pub all: Scores,
    pub objects: BTreeMap<String, Scores>,
    pub scenes: BTreeMap<String, Scores>,
    pub seconds_train: f64,
    pub seconds_eval: f64,
    /// With `--refine edges`: the scores before the refinement.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub before_refine: Option<Scores>,
    /// With `--refine edges`: the share of the estimates whose refined pose was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine_accepted: Option<f64>,
    /// With `--visible-box gt`: the refined estimates kept to a GT visible box (the others
    /// had no GT instance of their object in their image).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refined_in_box: Option<usize>,
}

/// `rows/<main row>/no_gt.json`: the main row's model from raw frames (issue 52), each
/// instance's crop from the detector's box of its object in its image (BOP's localization
/// protocol: the objects and their counts per image are known, not where they are), with the
/// refinement kept to that box; instances without a detection are misses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoGtRow {
    pub row: String,
    /// The detector's run folder.
    pub detector: PathBuf,
    /// GT instances (visible fraction >= 0.1) given a detection's crop.
    pub detected: usize,
    pub all: Scores,
    pub objects: BTreeMap<String, Scores>,
    pub scenes: BTreeMap<String, Scores>,
    /// With `--refine edges|views`: the scores before the refinement.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub before_refine: Option<Scores>,
    pub seconds: f64,
}

/// The file of [`NoGtRow`] in the main row's folder.
pub const NO_GT_FILE: &str = "no_gt.json";
/// The main row's estimates from raw frames, as a BOP results CSV.
pub const NO_GT_RESULTS_FILE: &str = "results_no_gt.csv";

/// The real test frames, loaded once: instances with their GT visible boxes, the GT, the
/// objects' models and the BOP setup (targets in the test scenes).
struct TestSet {
    split: String,
    instances: Vec<Instance>,
    gts: Vec<GtInstance>,
    objects: Objects,
    bop: BopSetup,
}

/// A synthetic set of a row: its look and its size.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Look {
    Realistic,
    Plain,
    Cycles,
}

struct SynthRow {
    name: &'static str,
    look: Look,
    /// The Cycles row's count (`--cycles-frames`) instead of `--frames`.
    small: bool,
}

const SYNTH_ROWS: &[SynthRow] = &[
    SynthRow {
        name: MAIN_ROW,
        look: Look::Realistic,
        small: false,
    },
    SynthRow {
        name: "synth_plain",
        look: Look::Plain,
        small: false,
    },
    SynthRow {
        name: "synth_cycles",
        look: Look::Cycles,
        small: true,
    },
    SynthRow {
        name: "synth_realistic_small",
        look: Look::Realistic,
        small: true,
    },
    SynthRow {
        name: "synth_plain_small",
        look: Look::Plain,
        small: true,
    },
];

impl SynthRow {
    fn what(&self, frames: usize) -> String {
        let look = match self.look {
            Look::Realistic => {
                "realistic raster (shadows, ambient occlusion, environment light, GGX)"
            }
            Look::Plain => "plain raster (no shadows, no ambient occlusion, Phong)",
            Look::Cycles => "Blender Cycles, 16 samples",
        };
        format!("synthetic, {frames} frames, {look}")
    }
}

/// `experiment sim2real` with the RGB models; returns the report (Markdown) it also wrote to
/// `report.md`.
pub fn run(args: Sim2realOptions, printer: &Log) -> Result<String> {
    let started = Instant::now();
    let model = match args.model {
        Sim2realModel::Rgb => "rgb",
        _ => "rgb-dense",
    };
    for (set, flag) in [
        (args.ablation, "--ablation"),
        (args.per_object, "--per-object"),
        (args.ensemble.is_some(), "--ensemble"),
        (args.mask_jitter_px != 3, "--mask-jitter-px"),
        (args.mask_shift_px != 0, "--mask-shift-px"),
        (args.occlusion_prob != 0.0, "--occlusion-prob"),
        (args.point_dropout != 0.0, "--point-dropout"),
    ] {
        if set {
            return Err(user_error(
                format!("{flag} is a depth-model option; --model {model} does not take it"),
                "drop the flag (the RGB models augment their crops themselves: colour, blur, noise, occluders, box jitter)",
            ));
        }
    }
    if args.visible_box == VisibleBoxes::Detected {
        return Err(user_error(
            "--visible-box detected: the experiment's rows crop and refine with GT boxes, and its no_gt scores with the detections already",
            "use --visible-box gt (the rows with GT boxes; the no_gt scores keep to the detections' boxes either way)",
        ));
    }
    if args.visible_box != VisibleBoxes::None
        && !matches!(args.refine, Refine::Edges | Refine::Views)
    {
        return Err(user_error(
            "--visible-box is what the refinement of the RGB models' estimates keeps to, and nothing is refined",
            "add --refine views (or edges), or drop --visible-box",
        ));
    }
    let out = args.out.clone();
    let frames = args.frames.unwrap_or(if args.quick { 48 } else { 1500 });
    let cycles_frames = args
        .cycles_frames
        .unwrap_or(if args.quick { 4 } else { 200 });
    let budget = args.budget.resolve_rgb(args.quick);
    if frames == 0 || budget.epochs == 0 || budget.batch == 0 || budget.width == 0 {
        return Err(user_error(
            "--frames, --epochs, --batch and --width must be positive",
            "e.g. --frames 1500 --epochs 20",
        ));
    }
    let names: Vec<&str> = SYNTH_ROWS
        .iter()
        .map(|r| r.name)
        .chain([NAIVE_BOX, REAL_ONLY])
        .collect();
    super::check_rows(&args.rows, &names, &[])?;
    synthgen_jobs::use_threads(args.jobs);
    let test_dir = super::existing(&args.test, "test")?;
    let fit_dir = args
        .fit
        .as_ref()
        .map(|f| super::existing(f, "fit"))
        .transpose()?;
    let mut apart = vec![("--test dataset", test_dir.as_path())];
    if let Some(f) = &fit_dir {
        apart.push(("--fit dataset", f.as_path()));
    }
    if let crate::options::DetectorChoice::Run(d) = &args.detector {
        apart.push(("--detector", d.as_path()));
    }
    check_apart(&out, &apart)?;
    let test_src = open_source(&test_dir)
        .with_context(|| format!("cannot open the --test dataset {}", test_dir.display()))?;
    let fit_src = fit_dir
        .as_ref()
        .map(|f| {
            open_source(f).with_context(|| format!("cannot open the --fit dataset {}", f.display()))
        })
        .transpose()?;
    let (test_frames, fit_frames, fit_scenes) = super::select_frames(
        test_src.as_ref(),
        fit_src.as_deref(),
        fit_dir.as_ref() == Some(&test_dir),
        &args.test_scenes,
        "name the test scenes, e.g. --test-scenes 2, or render from a scene file with --scene instead of --fit",
    )?;
    if !fit_frames.is_empty() {
        super::refuse_shared_frames(
            &test_frames,
            &fit_frames,
            "the scene fit and the real-only row",
        )?;
    }
    let scene_text = match &args.scene {
        Some(p) => {
            let spec = SceneSpec::from_toml_file(p)
                .with_context(|| format!("cannot read the --scene file {}", p.display()))?;
            Some((spec, std::fs::read_to_string(p)?))
        }
        None => None,
    };
    super::detect::check_choice(&args.detector, test_src.as_ref())?;
    let fit_ref = fit_src.as_deref().unwrap_or(test_src.as_ref());
    let mut objects = super::test_objects(test_src.as_ref(), fit_ref, &test_frames)?;
    let mut notes = Vec::new();
    if let Some(dir) = &args.models {
        replace_models(test_src.as_ref(), dir, &mut objects, &mut notes)?;
    }
    let settings = RgbSettings {
        model: model.to_string(),
        fit: fit_dir.clone(),
        test: test_dir.clone(),
        test_scenes: args.test_scenes.clone(),
        fit_scenes: fit_scenes.clone(),
        scene: scene_text.as_ref().map(|(_, t)| t.clone()),
        objects,
        frames,
        cycles_frames,
        epochs: budget.epochs,
        batch: budget.batch,
        lr: budget.lr,
        width: budget.width,
        crop_size: DEFAULT_RGB_CROP,
        seed: args.seed,
        quick: args.quick,
        colour_models: args
            .models
            .as_ref()
            .filter(|_| args.refine == Refine::Views)
            .map(|p| p.canonicalize().unwrap_or_else(|_| p.clone())),
        // `icp` (the depth models' default) does not apply to the RGB models.
        refine_options: match args.refine {
            Refine::Views => Some(EdgeRefineOptions::with_view_search()),
            Refine::Edges => Some(EdgeRefineOptions::default()),
            _ => None,
        },
        refine: match args.refine {
            r @ (Refine::Views | Refine::Edges) => r,
            _ => Refine::None,
        },
        visible_box: args.visible_box,
    };
    let _lock = OutputLock::acquire(&out)?;
    let mut inputs: Vec<(&str, &Path)> = vec![("--test", &settings.test)];
    if let Some(f) = &settings.fit {
        inputs.push(("--fit", f));
    }
    crate::settings::check_settings_file(
        &out,
        super::SETTINGS_FILE,
        &settings,
        &inputs,
        args.force,
        &[&["rows", "sources", "fit"], super::detect::STALE].concat(),
        true,
    )?;
    printer.info(format!(
        "{model}: objects {} (from the test frames' GT); test frames: {}{}; {}",
        settings
            .objects
            .iter()
            .map(|o| o.obj_id.to_string())
            .collect::<Vec<_>>()
            .join(", "),
        test_frames.len(),
        if args.test_scenes.is_empty() {
            String::new()
        } else {
            format!(" (scenes {})", super::list(&args.test_scenes))
        },
        match (&settings.scene, &fit_dir) {
            (Some(_), _) => format!(
                "scene from {}",
                args.scene.as_deref().unwrap_or(Path::new("")).display()
            ),
            (None, Some(f)) => format!(
                "scene fitted to {} frames of {}",
                fit_frames.len(),
                f.display()
            ),
            (None, None) => String::new(),
        }
    ));

    // 1. The scene: --scene, else fitted to --fit (GT poses and cameras; depth where there).
    let test_k = super::most_common_k(
        &test_frames,
        test_src.camera().width,
        test_src.camera().height,
    );
    let mut base = match scene_text {
        Some((mut spec, _)) => {
            spec.objects = settings.objects.iter().map(TestObject::spec).collect();
            notes.push(
                "the scene is --scene's (not fitted); its objects are the test objects".into(),
            );
            super::set_camera(&mut spec, &test_k);
            spec
        }
        None => {
            let (Some(fit), Some(_)) = (&settings.fit, &fit_src) else {
                return Err(anyhow::anyhow!("internal: neither --scene nor --fit"));
            };
            let dir = out.join("fit");
            ensure_scene_fit(fit, &settings.fit_scenes, &dir, printer)?;
            let mut spec = super::base_scene(
                &settings.objects,
                synthgen_core::scene::UpAxis::Stable,
                &dir,
                &test_k,
                &mut notes,
            )?;
            if test_frames.iter().all(|f| f.depth.is_some()) {
                super::widen_distances(&mut spec, &test_frames, &mut notes)?;
            }
            spec
        }
    };
    // The dense model's targets come from the rendered depth: clean, whatever the scene says.
    base.sensor.depth = DepthModel::None;
    base.validate()?;

    // 2. The synthetic sets.
    let wanted = |name: &str| args.rows.is_empty() || args.rows.iter().any(|r| r == name);
    let blender = cfg!(feature = "blender");
    let mut sets: Vec<(&SynthRow, usize, PathBuf)> = Vec::new();
    for row in SYNTH_ROWS {
        // The naive row reads the main row's set.
        let needed = wanted(row.name) || (row.name == MAIN_ROW && wanted(NAIVE_BOX));
        if !needed {
            continue;
        }
        let n = if row.small { cycles_frames } else { frames };
        if n == 0 {
            continue;
        }
        if row.look == Look::Cycles && !blender {
            notes.push(format!(
                "{} skipped: this synthgen was built without the `blender` feature (docs/blender.md)",
                row.name
            ));
            continue;
        }
        let mut spec = base.clone();
        if row.look == Look::Plain {
            plain_look(&mut spec);
        }
        let t = Instant::now();
        let (dir, computed) = super::ensure_render(
            &RenderPlan {
                frames: n,
                seed: settings.seed,
                quick: settings.quick,
                backend: if row.look == Look::Cycles {
                    Backend::Blender(BlenderSettings::default())
                } else {
                    Backend::Cpu
                },
                command_line: args.command_line.clone(),
            },
            &out,
            row.name,
            &spec,
            args.max_failed_fraction,
            printer,
        )?;
        if computed {
            printer.info(format!(
                "{}: rendered in {:.1} s",
                row.name,
                t.elapsed().as_secs_f64()
            ));
        }
        sets.push((row, n, dir));
    }

    // 3. Train and score.
    let test = load_test(&settings, test_src.as_ref())?;
    printer.info(format!(
        "{} real test instances (GT visible boxes: no detector), {} BOP targets",
        test.gts.len(),
        test.bop.targets.len()
    ));
    let mut rows: Vec<RgbRow> = Vec::new();
    let mut computed = 0;
    let mut main_computed = false;
    for (row, n, dir) in &sets {
        if !wanted(row.name) {
            continue;
        }
        let record = match read_row_file::<RgbRow>(&out, row.name) {
            Some(r) => r,
            None => {
                computed += 1;
                let src =
                    open_source(dir).with_context(|| format!("cannot open {}", dir.display()))?;
                printer.info(format!("training {} on {}", row.name, dir.display()));
                let r = train_row(
                    &settings,
                    &out,
                    row.name,
                    row.what(*n),
                    Some(*n),
                    src.as_ref(),
                    &[],
                    &test,
                    printer,
                )?;
                printer.info(format!("{}: {}", row.name, summary(&r.all)));
                main_computed |= row.name == MAIN_ROW;
                r
            }
        };
        rows.push(record);
    }
    if wanted(NAIVE_BOX) {
        let record = match read_row_file::<RgbRow>(&out, NAIVE_BOX) {
            Some(r) => r,
            None => {
                let Some((_, _, dir)) = sets.iter().find(|(r, _, _)| r.name == MAIN_ROW) else {
                    return Err(anyhow::anyhow!("internal: the naive row needs {MAIN_ROW}"));
                };
                computed += 1;
                naive_row(&settings, &out, dir, &test)?
            }
        };
        rows.push(record);
    }
    if wanted(REAL_ONLY) {
        match (&fit_src, &fit_dir) {
            (Some(src), Some(dir)) => {
                let record = match read_row_file::<RgbRow>(&out, REAL_ONLY) {
                    Some(r) => Some(r),
                    None => {
                        let has_depth = fit_frames.iter().all(|f| f.depth.is_some());
                        if settings.kind() == ModelKind::RgbDense && !has_depth {
                            notes.push(format!(
                                "{REAL_ONLY} skipped: the dense model's targets need depth, and the --fit frames have none"
                            ));
                            None
                        } else {
                            computed += 1;
                            printer.info(format!("training {REAL_ONLY} on the --fit frames"));
                            Some(train_row(
                                &settings,
                                &out,
                                REAL_ONLY,
                                format!(
                                    "real frames only ({}{})",
                                    dir.display(),
                                    if fit_scenes.is_empty() {
                                        String::new()
                                    } else {
                                        format!(" scenes {}", super::list(&fit_scenes))
                                    }
                                ),
                                None,
                                src.as_ref(),
                                &fit_scenes,
                                &test,
                                printer,
                            )?)
                        }
                    }
                };
                rows.extend(record);
            }
            _ => notes.push(format!("{REAL_ONLY} skipped: no --fit frames to train on")),
        }
    }

    // Rows an earlier run finished stay in the report when this run asks for others.
    for name in &names {
        if !wanted(name) {
            rows.extend(read_row_file::<RgbRow>(&out, name));
        }
    }
    rows.sort_by_key(|r| names.iter().position(|n| *n == r.name));

    // 4. From raw frames: the detector's boxes instead of the GT boxes.
    let main_set = sets
        .iter()
        .find(|(r, _, _)| r.name == MAIN_ROW)
        .map(|(_, _, d)| d.clone());
    let mut detection = None;
    let mut no_gt = None;
    match (&main_set, rows.iter().any(|r| r.name == MAIN_ROW)) {
        (Some(set), true) => {
            let plan = super::detect::DetectorPlan {
                choice: &args.detector,
                train_set: set,
                classes: settings.objects.iter().map(|o| o.obj_id).collect(),
                epochs: super::detect::epochs(args.detector_epochs, args.quick),
                seed: settings.seed,
                test: &test_dir,
                test_scenes: &settings.test_scenes,
                test_frames: &test_frames,
                jobs: args.jobs,
            };
            if let Some((det, fresh)) = super::detect::ensure_detections(&out, &plan, printer)? {
                let path = row_dir(&out, MAIN_ROW).join(NO_GT_FILE);
                let earlier = std::fs::read_to_string(&path)
                    .ok()
                    .and_then(|t| serde_json::from_str::<NoGtRow>(&t).ok())
                    .filter(|r| !fresh && !main_computed && r.detector == det.key.detector);
                let row = match earlier {
                    Some(r) => r,
                    None => {
                        computed += 1;
                        no_gt_row(
                            &settings,
                            &out,
                            test_src.as_ref(),
                            &test,
                            &det.key.detector,
                            printer,
                        )?
                    }
                };
                printer.info(format!("{MAIN_ROW} from raw frames: {}", summary(&row.all)));
                detection = Some(det);
                no_gt = Some(row);
            }
        }
        _ if args.detector != crate::options::DetectorChoice::None => notes.push(format!(
            "no_gt skipped: the scores from raw frames are {MAIN_ROW}'s, and this run has no {MAIN_ROW} row"
        )),
        _ => {}
    }
    let skipped: BTreeMap<String, Vec<u64>> = sets
        .iter()
        .map(|(row, _, dir)| (row.name.to_string(), super::failed_frames(dir)))
        .collect();
    let report = report_json(
        &settings,
        &rows,
        &notes,
        &skipped,
        detection.as_ref(),
        no_gt.as_ref(),
    );
    atomic_write(
        &out.join("report.json"),
        (serde_json::to_string_pretty(&report)? + "\n").as_bytes(),
    )?;
    let md = markdown(&settings, &rows, &notes, detection.as_ref(), no_gt.as_ref());
    atomic_write(&out.join("report.md"), md.as_bytes())?;
    printer.info(format!(
        "{} rows ({computed} computed now) in {:.0} s; wrote report.md and report.json in {}",
        rows.len(),
        started.elapsed().as_secs_f64(),
        out.display()
    ));
    Ok(md)
}

/// `--models DIR`: each test object with a folder `DIR/<its name>/` holding one mesh is
/// rendered from that mesh (units decided per file).
pub(super) fn replace_models(
    test: &dyn FrameSource,
    dir: &Path,
    objects: &mut [TestObject],
    notes: &mut Vec<String>,
) -> Result<()> {
    let ids: Vec<u32> = objects.iter().map(|o| o.obj_id).collect();
    let (meshes, kept) = synthgen_jobs::models::replacement_meshes(test, dir, ids, "--models")?;
    for (o, mesh) in objects.iter_mut().zip(meshes) {
        let Some(mesh) = mesh else { continue };
        let l = synthgen_assets::load_model(&mesh, synthgen_assets::Units::Auto, &NoProgress)
            .with_context(|| format!("cannot load the --models mesh of object {}", o.obj_id))?;
        synthgen_jobs::models::check_replacement(test, o.obj_id, &mesh, &l.model, "--models")?;
        o.model = mesh.canonicalize().unwrap_or(mesh);
        o.units = "auto".into();
    }
    if !kept.is_empty() {
        notes.push(format!(
            "--models: no folder for {} in {}; their dataset models are rendered",
            kept.join(", "),
            dir.display()
        ));
    }
    Ok(())
}

/// `scenes/plain.toml`'s look: no shadows, no ambient occlusion, a white environment, Phong,
/// no metal.
fn plain_look(spec: &mut SceneSpec) {
    spec.lights.shadows = false;
    spec.lights.ambient_occlusion = 0.0;
    spec.lights.sky_color = Some([1.0; 3]);
    spec.lights.ground_color = Some([1.0; 3]);
    spec.materials.shading = Shading::Phong;
    spec.materials.metallic = [0.0, 0.0];
}

/// `fit/scene.toml` fitted to the --fit frames (GT poses and cameras; the depth's plane where
/// the frames have depth), unless a finished fit of the same frames is there.
fn ensure_scene_fit(fit: &Path, scenes: &[u32], dir: &Path, printer: &Log) -> Result<()> {
    let record = serde_json::to_string_pretty(&serde_json::json!({
        "fit": fit, "scenes": scenes, "sensor": null
    }))? + "\n";
    let marker = dir.join("fit.done");
    if std::fs::read_to_string(&marker).is_ok_and(|t| t == record) {
        printer.info(format!("reusing the scene fit in {}", dir.display()));
        return Ok(());
    }
    if dir.exists() {
        std::fs::remove_dir_all(dir).with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    printer.info(format!("fitting the scene to {}", fit.display()));
    let scene = synthgen_jobs::fit::fit_scene_to_file(
        fit,
        scenes,
        None::<&Path>,
        &dir.join("scene.toml"),
        printer,
    )?;
    atomic_write(
        &dir.join("scene_report.json"),
        (serde_json::to_string_pretty(&scene)? + "\n").as_bytes(),
    )?;
    atomic_write(&marker, record.as_bytes())?;
    Ok(())
}

/// The training configuration of every trained row (`data`: the set it trains on).
fn train_config(s: &RgbSettings, data: &Path, split: String) -> TrainConfig {
    let kind = s.kind();
    TrainConfig {
        objects: Vec::new(),
        model: kind,
        width: s.width,
        n_points: 1,
        normalization_scale: synthgen_train::models::tnet::DEFAULT_SCALE,
        epochs: s.epochs,
        batch: s.batch,
        lr: s.lr,
        weight_decay: 1e-4,
        schedule: Schedule::Cosine,
        seed: s.seed,
        val_fraction: 0.1,
        min_visib_fract: MIN_VISIB_FRACT,
        data: data.to_path_buf(),
        split,
        crop_size: s.crop_size,
        loss_points: LOSS_POINTS,
        init: Vec::new(),
        plain_add_loss: false,
        translation: (kind == ModelKind::Rgb).then_some(Translation::CentreTz),
        // One head per test object, whatever the training set shows.
        classes: s.objects.iter().map(|o| o.obj_id).collect(),
    }
}

/// The test frames' instances (their GT visible boxes), GT and models, and the BOP targets
/// of the test scenes.
fn load_test(s: &RgbSettings, test: &dyn FrameSource) -> Result<TestSet> {
    let opts = DataOptions {
        dense_targets: false,
        split: None,
        ..train_config(s, test.root(), String::new()).data_options()
    };
    let keep = |scene: u32| s.test_scenes.is_empty() || s.test_scenes.contains(&scene);
    let set = load_source_instances(test, &opts, &NoProgress)
        .with_context(|| format!("cannot load the test frames of {}", test.root().display()))?;
    let instances: Vec<Instance> = set
        .instances
        .into_iter()
        .filter(|i| keep(i.scene_id))
        .collect();
    let gts: Vec<GtInstance> = read_gt(test, &set.split, MIN_VISIB_FRACT)?
        .into_iter()
        .filter(|g| keep(g.scene_id))
        .collect();
    if gts.is_empty() {
        anyhow::bail!(
            "no test instance with a visible fraction of at least {MIN_VISIB_FRACT} in {}",
            test.root().display()
        );
    }
    let ids: BTreeSet<u32> = gts.iter().map(|g| g.obj_id).collect();
    let objects = load_dataset_objects(test, ids, LOSS_POINTS)
        .with_context(|| format!("cannot load the object models of {}", test.root().display()))?;
    let mut bop = prepare_bop(test, &set.split, None, &BopOptions::default())
        .with_context(|| format!("cannot prepare BOP scoring of {}", test.root().display()))?;
    bop.targets.retain(|t| keep(t.scene_id));
    Ok(TestSet {
        split: set.split.clone(),
        instances,
        gts,
        objects,
        bop,
    })
}

/// Trains the RGB model on `data` (the `scenes` of it, all when empty) and scores it on the
/// test set (a row from scratch; `row.json` last).
#[allow(clippy::too_many_arguments)]
fn train_row(
    s: &RgbSettings,
    out: &Path,
    name: &str,
    what: String,
    frames: Option<usize>,
    data: &dyn FrameSource,
    scenes: &[u32],
    test: &TestSet,
    printer: &Log,
) -> Result<RgbRow> {
    let dir = row_dir(out, name);
    if dir.exists() {
        std::fs::remove_dir_all(&dir)
            .with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let t0 = Instant::now();
    let cfg = train_config(s, data.root(), String::new());
    let mut set = load_source_instances(data, &cfg.data_options(), &NoProgress)
        .with_context(|| format!("cannot load {}", data.root().display()))?;
    if !scenes.is_empty() {
        set.instances.retain(|i| scenes.contains(&i.scene_id));
    }
    let classes: BTreeSet<u32> = cfg.classes.iter().copied().collect();
    set.instances.retain(|i| classes.contains(&i.obj_id));
    if set.instances.is_empty() {
        anyhow::bail!(
            "no usable training instance of the test objects in {}",
            data.root().display()
        );
    }
    let objects = load_dataset_objects(data, set.obj_ids(), LOSS_POINTS)
        .with_context(|| format!("cannot load the object models of {}", data.root().display()))?;
    // Test objects the training set never shows keep untrained heads: say so in the row.
    let unseen: Vec<String> = classes
        .difference(&set.obj_ids())
        .map(u32::to_string)
        .collect();
    let what = if unseen.is_empty() {
        what
    } else {
        format!(
            "{what}; no training instance of objects {} (their heads are untrained)",
            unseen.join(", ")
        )
    };
    let cfg = TrainConfig {
        objects: Vec::new(),
        split: set.split.clone(),
        ..cfg
    };
    let device = train::device(false)?;
    let run_dir = dir.join("train");
    let outcome = train::train(
        &cfg,
        &set,
        Some(&objects),
        &run_dir,
        false,
        &device,
        &super::rows::Observer { printer, name },
    )?;
    let seconds_train = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let net = load_model(&run_dir.join(MODEL_FILE), &cfg, &device)?;
    let tested: Vec<&Instance> = test
        .instances
        .iter()
        .filter(|i| classes.contains(&i.obj_id))
        .collect();
    let preds = net.predict(&tested, Some(&test.objects), PREDICT_BATCH)?;
    let mut estimates = prediction_estimates(&preds, tested.iter().copied());
    let (mut before_refine, mut refine_accepted, mut refined_in_box) = (None, None, None);
    if let Some(opts) = &s.refine_options {
        before_refine = Some(score(&estimates, test)?.0);
        let src =
            open_source(&s.test).with_context(|| format!("cannot open {}", s.test.display()))?;
        let (refined, summary) = refine_estimates(
            src.as_ref(),
            &test.split,
            &estimates,
            opts,
            s.colour_models.as_deref(),
            BoxSource::new(s.visible_box, None)?,
            &NoProgress,
        )?;
        estimates = refined;
        refine_accepted = Some(1.0 - summary.refused as f64 / summary.refined.max(1) as f64);
        refined_in_box = (s.visible_box != VisibleBoxes::None).then_some(summary.with_box);
    }
    write_results_csv(&dir.join(RESULTS_FILE), &estimates)?;
    let (all, objects_s, scenes_s) = score(&estimates, test)?;
    let record = RgbRow {
        name: name.to_string(),
        what,
        frames,
        trained_on: Some(data.root().to_path_buf()),
        train_instances: outcome.n_train,
        epochs: cfg.epochs,
        all,
        objects: objects_s,
        scenes: scenes_s,
        seconds_train,
        seconds_eval: t1.elapsed().as_secs_f64(),
        before_refine,
        refine_accepted,
        refined_in_box,
    };
    write_row(out, &record)?;
    Ok(record)
}

/// The main row's model on the test frames with no GT box: each GT instance's crop from the
/// detections of its object in its image (best first), the refinement kept to that box;
/// writes [`NO_GT_RESULTS_FILE`] and [`NO_GT_FILE`].
fn no_gt_row(
    s: &RgbSettings,
    out: &Path,
    test_src: &dyn FrameSource,
    test: &TestSet,
    detector: &Path,
    printer: &Log,
) -> Result<NoGtRow> {
    let t0 = Instant::now();
    let dir = row_dir(out, MAIN_ROW);
    let kept = super::detect::joined_detections(
        out,
        test_src,
        std::slice::from_ref(&test.split),
        printer,
    )?;
    let boxes = std::sync::Arc::new(synthgen_detect::detections::crop_boxes(&kept));
    let opts = DataOptions {
        dense_targets: false,
        split: None,
        crop_boxes: Some(boxes.clone()),
        ..train_config(s, test_src.root(), String::new()).data_options()
    };
    let keep = |scene: u32| s.test_scenes.is_empty() || s.test_scenes.contains(&scene);
    let set = load_source_instances(test_src, &opts, &NoProgress).with_context(|| {
        format!(
            "cannot load the test frames of {}",
            test_src.root().display()
        )
    })?;
    let classes: BTreeSet<u32> = s.objects.iter().map(|o| o.obj_id).collect();
    let tested: Vec<&Instance> = set
        .instances
        .iter()
        .filter(|i| keep(i.scene_id) && classes.contains(&i.obj_id))
        .collect();
    let run_dir = dir.join("train");
    let cfg: TrainConfig =
        train::read_run_config(&run_dir.join(train::CONFIG_FILE), train::RunKind::Pose)?;
    let device = train::device(false)?;
    let net = load_model(&run_dir.join(MODEL_FILE), &cfg, &device)?;
    let preds = net.predict(&tested, Some(&test.objects), PREDICT_BATCH)?;
    let mut estimates = prediction_estimates(&preds, tested.iter().copied());
    let mut before_refine = None;
    if let Some(ro) = &s.refine_options {
        before_refine = Some(score(&estimates, test)?.0);
        let (refined, _) = refine_estimates(
            test_src,
            &test.split,
            &estimates,
            ro,
            s.colour_models.as_deref(),
            BoxSource::Detected(&boxes),
            &NoProgress,
        )?;
        estimates = refined;
    }
    write_results_csv(&dir.join(NO_GT_RESULTS_FILE), &estimates)?;
    let (all, objects, scenes) = score(&estimates, test)?;
    let record = NoGtRow {
        row: MAIN_ROW.to_string(),
        detector: detector.to_path_buf(),
        detected: tested.len(),
        all,
        objects,
        scenes,
        before_refine,
        seconds: t0.elapsed().as_secs_f64(),
    };
    atomic_write(
        &dir.join(NO_GT_FILE),
        (serde_json::to_string_pretty(&record)? + "\n").as_bytes(),
    )?;
    Ok(record)
}

/// The naive box baseline: per object the mean allocentric rotation and centre + Tz target
/// of the main row's training instances, read back through each test box.
fn naive_row(s: &RgbSettings, out: &Path, main_set: &Path, test: &TestSet) -> Result<RgbRow> {
    let t0 = Instant::now();
    let src =
        open_source(main_set).with_context(|| format!("cannot open {}", main_set.display()))?;
    let opts = DataOptions {
        dense_targets: false,
        ..train_config(s, main_set, String::new()).data_options()
    };
    let set = load_source_instances(src.as_ref(), &opts, &NoProgress)
        .with_context(|| format!("cannot load {}", main_set.display()))?;
    let mean = MeanBoxPose::fit(&set.instances);
    let (preds, tested): (Vec<Prediction>, Vec<&Instance>) = test
        .instances
        .iter()
        .filter_map(|i| Some((mean.predict(i)?, i)))
        .unzip();
    let estimates = prediction_estimates(&preds, tested.iter().copied());
    std::fs::create_dir_all(row_dir(out, NAIVE_BOX))?;
    write_results_csv(&row_dir(out, NAIVE_BOX).join(RESULTS_FILE), &estimates)?;
    let (all, objects, scenes) = score(&estimates, test)?;
    let record = RgbRow {
        name: NAIVE_BOX.into(),
        what: format!(
            "no image content: per object the mean rotation relative to the box's ray and the mean centre + Tz of the box, over {MAIN_ROW}'s instances"
        ),
        frames: None,
        trained_on: Some(main_set.to_path_buf()),
        train_instances: set.instances.len(),
        epochs: 0,
        all,
        objects,
        scenes,
        seconds_train: 0.0,
        seconds_eval: t0.elapsed().as_secs_f64(),
        before_refine: None,
        refine_accepted: None,
        refined_in_box: None,
    };
    write_row(out, &record)?;
    Ok(record)
}

fn write_row(out: &Path, r: &RgbRow) -> Result<()> {
    let dir = row_dir(out, &r.name);
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    atomic_write(
        &row_dir(out, &r.name).join(ROW_FILE),
        (serde_json::to_string_pretty(r)? + "\n").as_bytes(),
    )?;
    Ok(())
}

/// Scores the estimates against the test GT: overall, per object and per scene (the
/// 5cm5°/ADD(-S) matching of `synthgen eval`, and BOP's MSPD/MSSD over the targets).
#[allow(clippy::type_complexity)]
fn score(
    estimates: &[Estimate],
    test: &TestSet,
) -> Result<(Scores, BTreeMap<String, Scores>, BTreeMap<String, Scores>)> {
    let objs = eval_objects(&test.objects);
    let report = evaluate(&test.gts, estimates, &objs, Rotations::default())?;
    let bop: BopReport = test
        .bop
        .evaluate(estimates, None, &BopOptions::default(), &NoProgress)?;
    let all = Scores::new(
        &report.all,
        Some(bop.mspd.mean_recall),
        Some(bop.mssd.mean_recall),
    );
    let objects = report
        .per_object
        .iter()
        .map(|(id, r)| {
            (
                id.to_string(),
                Scores::new(
                    r,
                    bop.mspd.per_object_mean_recall.get(id).copied(),
                    bop.mssd.per_object_mean_recall.get(id).copied(),
                ),
            )
        })
        .collect();
    let scenes = evaluate_per_scene(&test.gts, estimates, &objs, Rotations::default())?
        .into_iter()
        .map(|(sc, r)| {
            (
                sc.to_string(),
                Scores::new(
                    &r.all,
                    bop.mspd.per_scene_mean_recall.get(&sc).copied(),
                    bop.mssd.per_scene_mean_recall.get(&sc).copied(),
                ),
            )
        })
        .collect();
    Ok((all, objects, scenes))
}

fn summary(s: &Scores) -> String {
    format!(
        "AR_MSPD {} AR_MSSD {} 5cm5° {:.1}% ADD(-S) {:.1}% on {} real instances",
        opt(s.ar_mspd, 3),
        opt(s.ar_mssd, 3),
        100.0 * s.acc_5cm5deg,
        100.0 * s.add_s_acc,
        s.n
    )
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("–".to_string(), |v| format!("{v:.digits$}"))
}

/// `report.json`: `all` / `objects` / `scenes` of the main row (the realistic raster), every
/// row under `rows`, the settings, notes and skipped frames.
fn report_json(
    s: &RgbSettings,
    rows: &[RgbRow],
    notes: &[String],
    skipped: &BTreeMap<String, Vec<u64>>,
    detection: Option<&super::detect::DetectorRecord>,
    no_gt: Option<&NoGtRow>,
) -> serde_json::Value {
    let main = rows.iter().find(|r| r.name == MAIN_ROW);
    serde_json::json!({
        "model": s.model,
        "gt_boxes": true,
        "detection": detection.map(|d| &d.detection),
        "no_gt": no_gt.map(|r| &r.all),
        "no_gt_objects": no_gt.map(|r| &r.objects),
        "no_gt_scenes": no_gt.map(|r| &r.scenes),
        "no_gt_row": no_gt,
        "detector": detection,
        "refine": s.refine,
        "main_row": MAIN_ROW,
        "all": main.map(|r| &r.all),
        "objects": main.map(|r| &r.objects),
        "scenes": main.map(|r| &r.scenes),
        "rows": rows.iter().map(|r| (r.name.clone(), r)).collect::<BTreeMap<_, _>>(),
        "skipped_frames": skipped,
        "notes": notes,
        "settings": s,
    })
}

fn markdown(
    s: &RgbSettings,
    rows: &[RgbRow],
    notes: &[String],
    detection: Option<&super::detect::DetectorRecord>,
    no_gt: Option<&NoGtRow>,
) -> String {
    let mut md = format!(
        "# sim2real, {} (trained on synthetic frames only; scored on the real test frames with their GT visible boxes, no detector)\n\n",
        s.model
    );
    md += "| row | frames | n | AR_MSPD | AR_MSSD | 5cm5° | ADD(-S) | median E_re | median E_te | train s |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {:.1}% | {:.1}% | {} | {} | {:.0} |",
            r.name,
            r.frames.map_or("–".into(), |f| f.to_string()),
            r.all.n,
            opt(r.all.ar_mspd, 3),
            opt(r.all.ar_mssd, 3),
            100.0 * r.all.acc_5cm5deg,
            100.0 * r.all.add_s_acc,
            r.all
                .median_re_deg
                .map_or("–".into(), |v| format!("{v:.0}°")),
            r.all
                .median_te_cm
                .map_or("–".into(), |v| format!("{v:.1} cm")),
            r.seconds_train
        );
    }
    let refined: Vec<&RgbRow> = rows.iter().filter(|r| r.before_refine.is_some()).collect();
    if !refined.is_empty() {
        md += &format!("\nThe trained rows' estimates were refined on the real RGB images (`--refine {}`{}); before the refinement, and the share of estimates whose refined pose was kept:\n\n| row | AR_MSPD before | 5cm5° before | median E_re before | kept |\n|---|---:|---:|---:|---:|\n",
            if s.refine_options.as_ref().is_some_and(|o| o.view_search.is_some()) {
                "views"
            } else {
                "edges"
            },
            match s.visible_box {
                VisibleBoxes::None => "",
                VisibleBoxes::Gt => ", `--visible-box gt`: each kept to its instance's GT visible box",
                VisibleBoxes::Detected => ", `--visible-box detected`: each kept to its detection",
            }
        );
        for r in refined {
            if let Some(b) = &r.before_refine {
                let _ = writeln!(
                    md,
                    "| {} | {} | {:.1}% | {} | {:.0}% |",
                    r.name,
                    opt(b.ar_mspd, 3),
                    100.0 * b.acc_5cm5deg,
                    b.median_re_deg.map_or("–".into(), |v| format!("{v:.0}°")),
                    100.0 * r.refine_accepted.unwrap_or(0.0)
                );
            }
        }
    }
    // Per object and per scene: AR_MSPD of every row.
    for (title, pick) in [
        (
            "object",
            (|r: &RgbRow| &r.objects) as fn(&RgbRow) -> &BTreeMap<String, Scores>,
        ),
        ("scene", |r: &RgbRow| &r.scenes),
    ] {
        let keys: BTreeSet<&String> = rows.iter().flat_map(|r| pick(r).keys()).collect();
        // Ids in numeric order (1, 5, 10, not 1, 10, 5).
        let mut keys: Vec<&String> = keys.into_iter().collect();
        keys.sort_by_key(|k| (k.parse::<u64>().unwrap_or(u64::MAX), (*k).clone()));
        if keys.is_empty() {
            continue;
        }
        let _ = write!(md, "\nAR_MSPD / 5cm5° per {title}:\n\n| {title} | n |");
        for r in rows {
            let _ = write!(md, " {} |", r.name);
        }
        md += "\n|---|---:|";
        md += &"---:|".repeat(rows.len());
        md += "\n";
        for k in keys {
            let n = rows
                .iter()
                .find_map(|r| pick(r).get(k).map(|v| v.n))
                .unwrap_or(0);
            let _ = write!(md, "| {k} | {n} |");
            for r in rows {
                let cell = pick(r).get(k).map_or("–".into(), |v| {
                    format!("{} / {:.1}%", opt(v.ar_mspd, 3), 100.0 * v.acc_5cm5deg)
                });
                let _ = write!(md, " {cell} |");
            }
            md += "\n";
        }
    }
    if let (Some(d), Some(r)) = (detection, no_gt) {
        let main = rows.iter().find(|x| x.name == MAIN_ROW);
        md += &super::detect::markdown(d);
        let _ = write!(
            md,
            "\n{MAIN_ROW} from raw frames (no GT box anywhere: each instance's crop{} from the detection of its object in its image, best first; {} of {} GT instances got one, the others are misses):\n\n| boxes | AR_MSPD | AR_MSSD | 5cm5° | ADD(-S) | median E_re | median E_te |\n|---|---:|---:|---:|---:|---:|---:|\n",
            if s.refine_options.is_some() { " and the refinement's box" } else { "" },
            r.detected,
            r.all.n
        );
        let line = |name: &str, v: &Scores| {
            format!(
                "| {name} | {} | {} | {:.1}% | {:.1}% | {} | {} |\n",
                opt(v.ar_mspd, 3),
                opt(v.ar_mssd, 3),
                100.0 * v.acc_5cm5deg,
                100.0 * v.add_s_acc,
                v.median_re_deg.map_or("–".into(), |x| format!("{x:.0}°")),
                v.median_te_cm.map_or("–".into(), |x| format!("{x:.1} cm")),
            )
        };
        md += &line("detected (no GT)", &r.all);
        if let Some(m) = main {
            md += &line("GT visible boxes", &m.all);
        }
        md += "\nAR_MSPD per object, from raw frames and with GT boxes:\n\n| object | n | no GT | GT boxes |\n|---|---:|---:|---:|\n";
        let mut ids: Vec<&String> = r.objects.keys().collect();
        ids.sort_by_key(|k| (k.parse::<u64>().unwrap_or(u64::MAX), (*k).clone()));
        for k in ids {
            let v = &r.objects[k];
            let gt = main
                .and_then(|m| m.objects.get(k))
                .map_or("–".into(), |x| opt(x.ar_mspd, 3));
            let _ = writeln!(md, "| {k} | {} | {} | {gt} |", v.n, opt(v.ar_mspd, 3));
        }
    }
    if !notes.is_empty() {
        md += "\nNotes:\n";
        for n in notes {
            let _ = writeln!(md, "- {n}");
        }
    }
    md
}
