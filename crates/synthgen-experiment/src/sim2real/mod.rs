//! `synthgen experiment sim2real`: synthetic to real, measured on real frames. The scene
//! (camera, views, rest poses, objects per frame) and the depth sensor are fitted to real
//! frames (`scene fit`, `sensor fit`); synthetic sets of the test objects are rendered with
//! them and with other sensors; one model per set is trained on synthetic frames only and
//! scored on the real test frames (their real depth and visible masks), beside the naive
//! centroid and a model trained on real frames. Every step is kept once done (a marker or
//! `row.json`, written last), so a re-run with the same options resumes.

mod detect;
mod pictures;
mod report;
mod rgb;
mod rows;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use synthgen_core::scene::{DepthModel, ObjectSpec, PlacementMode, SensorSpec, UpAxis};
use synthgen_core::SceneSpec;
use synthgen_formats::io::atomic_write;
use synthgen_formats::layout::open_source;
use synthgen_formats::output::{check_apart, OutputLock};
use synthgen_formats::source::{FrameSource, SourceFrame};
use synthgen_pipeline::{Backend, Format, RenderJob, SinkOptions, WriteOptions};
use synthgen_train::data::Augment;

use self::rows::{RowRecord, TrainSpec};
use crate::options::{Model, Refine, Sim2realOptions, TrainBudget};
use crate::user_error;
use crate::Log;
use synthgen_jobs::rgb_refine::VisibleBoxes;

/// The settings file at the output's root; a re-run must match it to resume.
pub const SETTINGS_FILE: &str = "experiment.json";

/// One object of the test set and the model file it is rendered from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TestObject {
    pub obj_id: u32,
    pub model: PathBuf,
    /// `mm` or `m`.
    pub units: String,
}

impl TestObject {
    /// The object as a scene's object entry (its model, id and units).
    fn spec(&self) -> ObjectSpec {
        let mut obj = ObjectSpec::new(&self.model);
        obj.obj_id = Some(self.obj_id);
        obj.units = Some(self.units.clone());
        obj
    }
}

/// Everything that decides the numbers. Two settings are equal when they train the same
/// models: `refine` is left out (it applies after training; a finished row whose
/// refinement differs is scored again from its models, `rows::current_record`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Settings {
    pub fit: PathBuf,
    pub test: PathBuf,
    /// Scenes of `test` scored (all when empty).
    pub test_scenes: Vec<u32>,
    /// Scenes of `fit` the fits and the real-only baseline use.
    pub fit_scenes: Vec<u32>,
    pub objects: Vec<TestObject>,
    pub model: String,
    pub frames: usize,
    pub epochs: usize,
    pub batch: usize,
    pub lr: f64,
    pub points: usize,
    pub width: usize,
    pub ablation: bool,
    /// The rest pose of test objects no fit frame shows.
    #[serde(default)]
    pub unseen_up: UpAxis,
    /// Perturbations of the synthetic training instances (not the real ones).
    #[serde(default)]
    pub augment: synthgen_train::data::Augment,
    /// TNet conditioned on the object class (`--per-object`).
    #[serde(default)]
    pub per_object: bool,
    /// TNets per trained row, their centres averaged (`--ensemble`).
    #[serde(default = "one")]
    pub ensemble: usize,
    /// The depth models' centres refined by ICP on the real depth (`--refine`).
    #[serde(default)]
    pub refine: Refine,
    pub seed: u64,
    pub quick: bool,
}

fn one() -> usize {
    1
}

impl PartialEq for Settings {
    fn eq(&self, other: &Self) -> bool {
        let training = |s: &Settings| {
            let mut v = serde_json::to_value(s).unwrap_or_default();
            if let Some(m) = v.as_object_mut() {
                m.remove("refine");
            }
            v
        };
        training(self) == training(other)
    }
}

/// A row trained on a synthetic set: how its scene differs from the fitted one, or which set
/// it trains on with other training-time perturbations.
struct Variant {
    name: &'static str,
    what: &'static str,
    ablation: bool,
    /// Trains on this variant's set (rendered once) instead of a render of its own.
    uses_set: Option<&'static str>,
    /// Its training instances' perturbations, from the settings'.
    augment: fn(Augment) -> Augment,
    /// Trains TNet with the other choice of `--per-object` than the settings'.
    flip_per_object: bool,
}

fn as_set(a: Augment) -> Augment {
    a
}

const VARIANTS: &[Variant] = &[
    Variant {
        name: "synth_fitted",
        what: "synthetic, fitted scene and fitted sensor",
        ablation: false,
        uses_set: None,
        augment: as_set,
        flip_per_object: false,
    },
    Variant {
        name: "synth_no_sensor",
        what: "synthetic, fitted scene, clean depth (no sensor model)",
        ablation: false,
        uses_set: None,
        augment: as_set,
        flip_per_object: false,
    },
    Variant {
        name: "synth_d455",
        what: "synthetic, fitted scene, the D455 model",
        ablation: false,
        uses_set: None,
        augment: as_set,
        flip_per_object: false,
    },
    Variant {
        name: "ablation_no_scene_fit",
        what: "synthetic, synthgen's default scene (all objects every frame, standing on +z), fitted sensor",
        ablation: true,
        uses_set: None,
        augment: as_set,
        flip_per_object: false,
    },
    Variant {
        name: "ablation_distractors",
        what: "synthetic, fitted scene and sensor, 1-3 primitive distractors per frame",
        ablation: true,
        uses_set: None,
        augment: as_set,
        flip_per_object: false,
    },
    Variant {
        name: "ablation_textures",
        what: "synthetic, fitted scene and sensor, textured ground and 2-4 textured walls",
        ablation: true,
        uses_set: None,
        augment: as_set,
        flip_per_object: false,
    },
    Variant {
        name: "ablation_physics",
        what: "synthetic, fitted scene and sensor, objects dropped and settled (physics)",
        ablation: true,
        uses_set: None,
        augment: as_set,
        flip_per_object: false,
    },
    Variant {
        name: "ablation_unseen_on_z",
        what: "synthetic, fitted scene and sensor, objects no fit frame shows standing on +z instead of their stable faces",
        ablation: true,
        uses_set: None,
        augment: as_set,
        flip_per_object: false,
    },
    Variant {
        name: "ablation_no_mask_jitter",
        what: "synth_fitted's frames, trained without the mask boundary jitter",
        ablation: true,
        uses_set: Some("synth_fitted"),
        augment: |a| Augment {
            mask_jitter_px: 0,
            ..a
        },
        flip_per_object: false,
    },
    Variant {
        name: "ablation_mask_shift",
        what: "synth_fitted's frames, trained with masks shifted by up to 2 px",
        ablation: true,
        uses_set: Some("synth_fitted"),
        augment: |a| Augment {
            mask_shift_px: 2,
            ..a
        },
        flip_per_object: false,
    },
    Variant {
        name: "ablation_occlusion",
        what: "synth_fitted's frames, trained with random occlusion cuts (p 0.3)",
        ablation: true,
        uses_set: Some("synth_fitted"),
        augment: |a| Augment {
            occlusion_prob: 0.3,
            ..a
        },
        flip_per_object: false,
    },
    Variant {
        name: "ablation_dropout",
        what: "synth_fitted's frames, trained with point dropout (up to 20 %)",
        ablation: true,
        uses_set: Some("synth_fitted"),
        augment: |a| Augment { dropout: 0.2, ..a },
        flip_per_object: false,
    },
];

/// The row of a model trained on real frames only.
pub const REAL_ONLY: &str = "real_only";

/// Runs `experiment sim2real`; returns the report (Markdown) it also wrote to `report.md`.
pub fn run(args: Sim2realOptions, printer: &Log) -> Result<String> {
    let Some(model) = args.model.depth_model() else {
        return rgb::run(args, printer);
    };
    for (set, flag) in [
        (args.scene.is_some(), "--scene"),
        (args.cycles_frames.is_some(), "--cycles-frames"),
        (args.visible_box != VisibleBoxes::None, "--visible-box"),
    ] {
        if set {
            return Err(user_error(
                format!(
                    "{flag} applies to the RGB models (--model rgb|rgb-dense), not {}",
                    model.name()
                ),
                "the depth models fit the scene and the sensor to --fit: drop the flag",
            ));
        }
    }
    let Some(fit_arg) = args.fit.clone() else {
        return Err(user_error(
            "--fit is required: the depth models fit the scene and the sensor to real frames",
            "pass --fit DIR (real frames with depth and GT poses)",
        ));
    };
    let started = Instant::now();
    let out = args.out.clone();
    let frames = args.frames.unwrap_or(if args.quick { 48 } else { 1500 });
    let budget = args.budget.resolve(args.quick);
    let TrainBudget {
        epochs,
        batch,
        lr,
        points,
        width,
    } = budget;
    if frames == 0 || !budget.is_positive() {
        return Err(user_error(
            "--frames, --epochs, --batch, --points and --width must be positive",
            "e.g. --frames 1500 --epochs 8",
        ));
    }
    synthgen_jobs::use_threads(args.jobs);
    let fit_dir = existing(&fit_arg, "fit")?;
    let test_dir = existing(&args.test, "test")?;
    let mut apart = vec![
        ("--fit dataset", fit_dir.as_path()),
        ("--test dataset", &test_dir),
    ];
    if let crate::options::DetectorChoice::Run(d) = &args.detector {
        apart.push(("--detector", d.as_path()));
    }
    check_apart(&out, &apart)?;
    let fit_src = open_source(&fit_dir)
        .with_context(|| format!("cannot open the --fit dataset {}", fit_dir.display()))?;
    let test_src = open_source(&test_dir)
        .with_context(|| format!("cannot open the --test dataset {}", test_dir.display()))?;
    let (test_frames, fit_frames, fit_scenes) = select_frames(
        test_src.as_ref(),
        Some(fit_src.as_ref()),
        fit_dir == test_dir,
        &args.test_scenes,
        "name the test scenes, e.g. --test-scenes 0; they are left out of the scene and sensor \
         fits and of the real-only baseline",
    )?;
    for (what, frames, dir) in [
        ("--test", &test_frames, &test_dir),
        ("--fit", &fit_frames, &fit_dir),
    ] {
        if let Some(f) = frames.iter().find(|f| f.depth.is_none()) {
            return Err(user_error(
                format!(
                    "the {what} dataset {} has no depth images ({}/{:06} image {} has none)",
                    dir.display(),
                    f.location.split,
                    f.location.scene_id,
                    f.location.im_id
                ),
                "sim2real fits the sensor to real depth and tests on it: use frames with depth",
            ));
        }
    }
    detect::check_choice(&args.detector, test_src.as_ref())?;
    let mut objects = test_objects(test_src.as_ref(), fit_src.as_ref(), &test_frames)?;
    let mut model_notes = Vec::new();
    if let Some(dir) = &args.models {
        rgb::replace_models(test_src.as_ref(), dir, &mut objects, &mut model_notes)?;
    }
    refuse_shared_frames(
        &test_frames,
        &fit_frames,
        "the scene and sensor fits and the real-only baseline",
    )?;
    let settings = Settings {
        fit: fit_dir.clone(),
        test: test_dir.clone(),
        test_scenes: args.test_scenes.clone(),
        fit_scenes: fit_scenes.clone(),
        objects,
        model: model.name().into(),
        frames,
        epochs,
        batch,
        lr,
        points,
        width,
        ablation: args.ablation,
        unseen_up: args.unseen_up,
        augment: synthgen_train::data::Augment {
            mask_jitter_px: args.mask_jitter_px,
            occlusion_prob: args.occlusion_prob,
            dropout: args.point_dropout,
            mask_shift_px: args.mask_shift_px,
        },
        per_object: args.per_object,
        ensemble: args.ensemble.unwrap_or(if args.quick { 1 } else { 3 }),
        // TNet's centre and Full's whole pose; RNet gives no centre to start from.
        refine: if matches!(model, Model::Tnet | Model::Full) {
            if matches!(args.refine, Refine::Edges | Refine::Views) {
                return Err(user_error(
                    "--refine edges and views refine the RGB models' poses on the RGB images; a depth model's pose is refined with icp",
                    "--refine icp (the default) or --refine none; --refine edges or views with --model rgb or rgb-dense",
                ));
            }
            args.refine
        } else {
            Refine::None
        },
        seed: args.seed,
        quick: args.quick,
    };
    // Before anything is written or fitted: a misspelt row must not cost a fit.
    let names: Vec<&str> = VARIANTS
        .iter()
        .map(|v| v.name)
        .chain([REAL_ONLY, rows::NAIVE, rows::NAIVE_ICP])
        .collect();
    let ablation_rows: Vec<&str> = VARIANTS
        .iter()
        .filter(|v| v.ablation && !settings.ablation)
        .map(|v| v.name)
        .collect();
    check_rows(&args.rows, &names, &ablation_rows)?;
    let _lock = OutputLock::acquire(&out)?;
    check_settings(&out, &settings, args.force)?;
    printer.info(format!(
        "objects: {} (from the test frames' GT); test frames: {}{}; fit frames: {}",
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
            format!(" (scenes {})", list(&args.test_scenes))
        },
        fit_frames.len()
    ));

    // 1. The scene and the sensor, fitted to the --fit frames.
    let mut timing = read_timing(&out);
    let t_fit = Instant::now();
    let fit_out = out.join("fit");
    if ensure_fits(&settings, &fit_out, printer)? {
        timing.fit_s = t_fit.elapsed().as_secs_f64();
        write_timing(&out, &timing)?;
    }

    // 2. The synthetic sets.
    let test_k = most_common_k(
        &test_frames,
        test_src.camera().width,
        test_src.camera().height,
    );
    let mut notes = model_notes;
    let mut base = base_scene(
        &settings.objects,
        settings.unseen_up,
        &fit_out,
        &test_k,
        &mut notes,
    )?;
    widen_distances(&mut base, &test_frames, &mut notes)?;
    let wanted = |name: &str| args.rows.is_empty() || args.rows.iter().any(|r| r == name);
    let variants: Vec<&Variant> = VARIANTS
        .iter()
        .filter(|v| (!v.ablation || settings.ablation) && wanted(v.name))
        .collect();
    let mut sets: Vec<(&Variant, PathBuf)> = Vec::new();
    // Each set rendered once: a row that trains on another's set (`uses_set`) shares it.
    let mut rendered: BTreeMap<&str, PathBuf> = BTreeMap::new();
    for v in &variants {
        let set_name = v.uses_set.unwrap_or(v.name);
        if let Some(dir) = rendered.get(set_name) {
            sets.push((v, dir.clone()));
            continue;
        }
        let of = VARIANTS.iter().find(|x| x.name == set_name).unwrap_or(v);
        let Some(spec) = variant_scene(of, &base, &settings, &test_k, &mut notes)? else {
            continue;
        };
        let t = Instant::now();
        let (dir, computed) = ensure_render(
            &RenderPlan {
                frames: settings.frames,
                seed: settings.seed,
                quick: settings.quick,
                backend: Backend::Cpu,
                command_line: args.command_line.clone(),
            },
            &out,
            set_name,
            &spec,
            args.max_failed_fraction,
            printer,
        )?;
        if computed {
            timing
                .render_s
                .insert(set_name.to_string(), t.elapsed().as_secs_f64());
            write_timing(&out, &timing)?;
        }
        rendered.insert(set_name, dir.clone());
        sets.push((v, dir));
    }

    // 3. Train and score.
    let test = rows::load_test(&settings, test_src.as_ref(), &args.test_scenes)?;
    printer.info(format!(
        "{} real test instances with enough depth readings",
        test.instances.len()
    ));
    let mut records: Vec<RowRecord> = Vec::new();
    let mut computed = 0;
    let naive = match rows::current_record(&settings, &out, rows::NAIVE, &test, printer)? {
        Some(r) => r,
        None => {
            computed += 1;
            rows::naive_row(&settings, &out, &test)?
        }
    };
    let mut synth_steps = None;
    let mut main_computed = false;
    for (v, dir) in &sets {
        let record = match rows::current_record(&settings, &out, v.name, &test, printer)? {
            Some(r) => r,
            None => {
                let src =
                    open_source(dir).with_context(|| format!("cannot open {}", dir.display()))?;
                printer.info(format!("training {} on {}", v.name, dir.display()));
                computed += 1;
                let r = rows::train_row(
                    &settings,
                    &out,
                    &TrainSpec {
                        name: v.name,
                        what: v.what.to_string(),
                        data: src.as_ref(),
                        scenes: &[],
                        epochs: Some(settings.epochs),
                        steps: None,
                        augment: (v.augment)(settings.augment),
                        per_object: settings.per_object != v.flip_per_object,
                    },
                    &test,
                    printer,
                )?;
                printer.info(format!(
                    "{}: mean centre error {:.2} cm on the real test frames",
                    v.name, r.all.mean_centre_error_cm
                ));
                main_computed |= v.name == report::MAIN_ROW;
                r
            }
        };
        if v.name == "synth_fitted" {
            synth_steps =
                Some(settings.epochs * (record.train_instances.div_ceil(settings.batch)).max(1));
        }
        records.push(record);
    }
    let real_only = match rows::current_record(&settings, &out, REAL_ONLY, &test, printer)? {
        Some(r) => Some(r),
        None if !wanted(REAL_ONLY) => None,
        None => Some({
            computed += 1;
            printer.info(format!(
                "training {REAL_ONLY} on the real frames of {}",
                if fit_scenes.is_empty() {
                    fit_dir.display().to_string()
                } else {
                    format!("{} scenes {}", fit_dir.display(), list(&fit_scenes))
                }
            ));
            rows::train_row(
                &settings,
                &out,
                &TrainSpec {
                    name: REAL_ONLY,
                    what: format!(
                        "real frames only ({}), as many optimizer steps as the synthetic rows",
                        if fit_scenes.is_empty() {
                            "every --fit frame".to_string()
                        } else {
                            format!("--fit scenes {}", list(&fit_scenes))
                        }
                    ),
                    data: fit_src.as_ref(),
                    scenes: &fit_scenes,
                    epochs: None,
                    steps: synth_steps,
                    augment: Default::default(),
                    per_object: settings.per_object,
                },
                &test,
                printer,
            )?
        }),
    };
    records.extend(real_only);
    records.push(naive);
    if settings.refine == Refine::Icp {
        match rows::current_record(&settings, &out, rows::NAIVE_ICP, &test, printer)? {
            Some(r) => records.push(r),
            None => {
                computed += 1;
                records.extend(rows::naive_icp_row(&settings, &out, &test)?);
            }
        }
    }

    // From raw frames: the main row's points from the detector's masks.
    let main_set = sets
        .iter()
        .find(|(v, _)| v.name == report::MAIN_ROW)
        .map(|(_, d)| d.clone());
    let mut detection = None;
    let mut no_gt = None;
    match main_set {
        Some(set) => {
            let plan = detect::DetectorPlan {
                choice: &args.detector,
                train_set: &set,
                classes: settings.objects.iter().map(|o| o.obj_id).collect(),
                epochs: detect::epochs(args.detector_epochs, args.quick),
                seed: settings.seed,
                test: &test_dir,
                test_scenes: &settings.test_scenes,
                test_frames: &test_frames,
                jobs: args.jobs,
            };
            if let Some((det, fresh)) = detect::ensure_detections(&out, &plan, printer)? {
                let path = crate::settings::row_dir(&out, report::MAIN_ROW).join(rows::NO_GT_FILE);
                let earlier = std::fs::read_to_string(&path)
                    .ok()
                    .and_then(|t| serde_json::from_str::<rows::NoGtRecord>(&t).ok())
                    .filter(|r| {
                        !fresh
                            && !main_computed
                            && r.detector == det.key.detector
                            && r.scoring == rows::scoring_key(&settings)
                    });
                let row = match earlier {
                    Some(r) => r,
                    None => {
                        computed += 1;
                        rows::no_gt_row(
                            &settings,
                            &out,
                            report::MAIN_ROW,
                            test_src.as_ref(),
                            &test,
                            &det.key.detector,
                            printer,
                        )?
                    }
                };
                printer.info(format!(
                    "{} from raw frames: mean centre error {:.2} cm on the {} of {} instances detected",
                    report::MAIN_ROW,
                    row.all.mean_centre_error_cm,
                    row.detected,
                    row.n_gt
                ));
                detection = Some(det);
                no_gt = Some(row);
            }
        }
        None if args.detector != crate::options::DetectorChoice::None => notes.push(format!(
            "no_gt skipped: the scores from raw frames are {}'s, and this run has no {} row",
            report::MAIN_ROW,
            report::MAIN_ROW
        )),
        None => {}
    }

    // Rows an earlier run finished stay in the report when this run asks for others.
    for name in &names {
        let ablation_off = ablation_rows.contains(name);
        if !wanted(name) && !ablation_off && !records.iter().any(|r| r.name == *name) {
            records.extend(rows::current_record(&settings, &out, name, &test, printer)?);
        }
    }
    records.sort_by_key(|r| names.iter().position(|n| *n == r.name));
    let elapsed = started.elapsed().as_secs_f64();
    timing
        .render_s
        .retain(|k, _| sets.iter().any(|(v, _)| v.uses_set.unwrap_or(v.name) == k));
    timing.rows_s = records
        .iter()
        .map(|r| (r.name.clone(), r.seconds_train + r.seconds_eval))
        .collect();
    timing.steps_total_s =
        timing.fit_s + timing.render_s.values().sum::<f64>() + timing.rows_s.values().sum::<f64>();
    timing.this_run_s = elapsed;
    write_timing(&out, &timing)?;
    // The frames each set's render left out (its synthgen.json's failed_frames).
    let skipped: BTreeMap<String, Vec<u64>> = sets
        .iter()
        .map(|(v, dir)| (v.uses_set.unwrap_or(v.name).to_string(), failed_frames(dir)))
        .collect();
    // Pictures of the main row's poses over real frames, with GT masks and from raw frames.
    let mut pictures = Vec::new();
    if let Some(objs) = &test.objects {
        let frames = pictures::test_frames(test_src.as_ref(), &test.split, &settings.test_scenes)?;
        let objs = synthgen_train::eval::eval_objects(objs);
        let row = crate::settings::row_dir(&out, report::MAIN_ROW);
        for (file, tag) in [
            (rows::RESULTS_FILE, "gt_masks"),
            (rows::NO_GT_RESULTS_FILE, "no_gt"),
        ] {
            let path = row.join(file);
            if !path.is_file() {
                continue;
            }
            let est = synthgen_train::results::read_results_csv(&path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            pictures.extend(pictures::draw_estimates(
                &out,
                tag,
                &frames,
                &est.estimates,
                &objs,
            )?);
        }
    }
    let mut rep = report::Report::new(&settings, records, timing, notes, skipped);
    rep.pictures = pictures
        .iter()
        .map(|p| p.strip_prefix(&out).unwrap_or(p).to_path_buf())
        .collect();
    rep.set_no_gt(detection, no_gt);
    rep.write(&out)?;
    let md = rep.markdown();
    printer.info(format!(
        "{} rows ({computed} computed now) in {elapsed:.0} s; wrote report.md, report.json, plot.png in {}",
        rep.rows.len(),
        out.display()
    ));
    Ok(md)
}

/// The frames a set's render left out (its synthgen.json's `failed_frames`).
fn failed_frames(dir: &Path) -> Vec<u64> {
    synthgen_formats::read_manifest(dir)
        .ok()
        .and_then(|m| {
            m.extra["failed_frames"]
                .as_array()
                .map(|a| a.iter().filter_map(serde_json::Value::as_u64).collect())
        })
        .unwrap_or_default()
}

fn list(ids: &[u32]) -> String {
    ids.iter().map(u32::to_string).collect::<Vec<_>>().join(",")
}

fn existing(path: &Path, flag: &str) -> Result<PathBuf> {
    path.canonicalize().map_err(|_| {
        user_error(
            format!("--{flag} not found: {}", path.display()),
            "check the path",
        )
    })
}

fn scenes_of(frames: &[SourceFrame]) -> Vec<u32> {
    let s: BTreeSet<u32> = frames.iter().map(|f| f.location.scene_id).collect();
    s.into_iter().collect()
}

/// The test frames (of `test_scenes`, all when empty), the fit frames and the fit scenes
/// (when `fit` is the test dataset, `same`: its scenes outside `test_scenes`, which must be
/// named; none without `fit`). `held_out_hint` says how to name them.
#[allow(clippy::type_complexity)]
fn select_frames(
    test: &dyn FrameSource,
    fit: Option<&dyn FrameSource>,
    same: bool,
    test_scenes: &[u32],
    held_out_hint: &str,
) -> Result<(Vec<SourceFrame>, Vec<SourceFrame>, Vec<u32>)> {
    if same && test_scenes.is_empty() {
        return Err(user_error(
            "--test is the --fit dataset but no --test-scenes are held out",
            held_out_hint,
        ));
    }
    let test_frames = frames_in(test, test_scenes, "--test")?;
    let Some(fit) = fit else {
        return Ok((test_frames, Vec::new(), Vec::new()));
    };
    let fit_scenes: Vec<u32> = if same {
        scenes_of(&fit.frames(&[])?)
            .into_iter()
            .filter(|s| !test_scenes.contains(s))
            .collect()
    } else {
        Vec::new()
    };
    if same && fit_scenes.is_empty() {
        return Err(user_error(
            "every scene of the dataset is a test scene: nothing is left to fit to",
            "hold out fewer scenes with --test-scenes",
        ));
    }
    let fit_frames = frames_in(fit, &fit_scenes, "--fit")?;
    Ok((test_frames, fit_frames, fit_scenes))
}

/// Refuses a `--fit` set that holds test frames (the same file, a hard link or the same
/// bytes): `would_see` would see them.
fn refuse_shared_frames(test: &[SourceFrame], fit: &[SourceFrame], would_see: &str) -> Result<()> {
    let t: Vec<&_> = test.iter().collect();
    let f: Vec<&_> = fit.iter().collect();
    let shared = synthgen_formats::shared_frames::same_images(&t, &f)?;
    if let Some(&(j, i)) = shared.first() {
        return Err(user_error(
            format!(
                "the --fit dataset shares {} of its {} frames with the --test frames (the same file, a hard link or the same bytes), e.g. {} is the test frame {}: {would_see} would see the test frames",
                shared.len(),
                f.len(),
                f[j].rgb.display(),
                t[i].rgb.display()
            ),
            "pass one folder as --fit and --test with --test-scenes (those scenes are left out of the fits), or fit to other frames",
        ));
    }
    Ok(())
}

/// The frames with GT of `scenes` (all when empty); unknown scenes and no GT are errors.
fn frames_in(src: &dyn FrameSource, scenes: &[u32], flag: &str) -> Result<Vec<SourceFrame>> {
    let all = src.frames(&[])?;
    let known = scenes_of(&all);
    for s in scenes {
        if !known.contains(s) {
            return Err(user_error(
                format!(
                    "scene {s} is not in the {flag} dataset {} (scenes: {})",
                    src.root().display(),
                    list(&known)
                ),
                "name scenes the dataset has",
            ));
        }
    }
    let frames: Vec<SourceFrame> = all
        .into_iter()
        .filter(|f| scenes.is_empty() || scenes.contains(&f.location.scene_id))
        .filter(|f| !f.gt.is_empty())
        .collect();
    if frames.is_empty() {
        return Err(user_error(
            format!(
                "the {flag} dataset {} has no frames with GT poses{}",
                src.root().display(),
                if scenes.is_empty() {
                    String::new()
                } else {
                    format!(" in scenes {}", list(scenes))
                }
            ),
            "sim2real needs annotated real frames",
        ));
    }
    Ok(frames)
}

/// The objects annotated in the test frames, each with a model file (the test dataset's,
/// else the fit dataset's). A test object without any model, or no test object that the fit
/// frames show, is an error naming them.
fn test_objects(
    test: &dyn FrameSource,
    fit: &dyn FrameSource,
    test_frames: &[SourceFrame],
) -> Result<Vec<TestObject>> {
    let ids: BTreeSet<u32> = test_frames.iter().flat_map(|f| f.object_set()).collect();
    let mut out = Vec::new();
    let mut missing = Vec::new();
    for id in ids {
        let found = [test, fit]
            .into_iter()
            .find_map(|src| src.model_path(id).map(|p| (p, src.model_units())));
        match found {
            Some((model, units)) => out.push(TestObject {
                obj_id: id,
                model: model.canonicalize().unwrap_or(model),
                units: units.to_string(),
            }),
            None => missing.push(format!(
                "{id} (looked for {} and {})",
                test.model_file(id).display(),
                fit.model_file(id).display()
            )),
        }
    }
    if !missing.is_empty() {
        return Err(user_error(
            format!("test objects without a model file: {}", missing.join("; ")),
            "every object scored must be rendered: add its model to the --test or --fit dataset",
        ));
    }
    // Objects no fit frame shows get --unseen-up: base_scene notes which.
    Ok(out)
}

/// The intrinsics most test frames share (what the renders use: the test camera is known
/// without looking at any label).
fn most_common_k(frames: &[SourceFrame], w: u32, h: u32) -> synthgen_core::Intrinsics {
    let mut counts: BTreeMap<String, (usize, synthgen_core::Intrinsics)> = BTreeMap::new();
    for f in frames {
        let k = f.camera.intrinsics(w, h);
        let key = format!("{:.3},{:.3},{:.3},{:.3}", k.fx, k.fy, k.cx, k.cy);
        counts.entry(key).or_insert((0, k)).0 += 1;
    }
    counts
        .into_values()
        .max_by_key(|(n, _)| *n)
        .map(|(_, k)| k)
        .unwrap_or_else(|| synthgen_core::Intrinsics::YCBV)
}

/// Writes the settings, or checks them (and the fit and test data) against those of the
/// experiment already in `out`.
fn check_settings(out: &Path, settings: &Settings, force: bool) -> Result<()> {
    crate::settings::check_settings_file(
        out,
        SETTINGS_FILE,
        settings,
        &[("--fit", &settings.fit), ("--test", &settings.test)],
        force,
        &[&["rows", "sources", "fit", TIMING_FILE], detect::STALE].concat(),
        true,
    )?;
    // The same training with another `--refine`: the file says which one the rows have now.
    atomic_write(
        &out.join(SETTINGS_FILE),
        (serde_json::to_string_pretty(settings)? + "\n").as_bytes(),
    )?;
    Ok(())
}

/// Where the steps' times are kept between runs.
const TIMING_FILE: &str = "timing.json";

fn read_timing(out: &Path) -> report::Timing {
    std::fs::read_to_string(out.join(TIMING_FILE))
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or_default()
}

fn write_timing(out: &Path, t: &report::Timing) -> Result<()> {
    atomic_write(
        &out.join(TIMING_FILE),
        (serde_json::to_string_pretty(t)? + "\n").as_bytes(),
    )?;
    Ok(())
}

/// `--rows`: every name must be a row of this experiment; an ablation row needs
/// `--ablation` (`ablation_rows`: those not run without it).
pub(crate) fn check_rows(asked: &[String], names: &[&str], ablation_rows: &[&str]) -> Result<()> {
    for r in asked {
        if ablation_rows.contains(&r.as_str()) {
            return Err(user_error(
                format!(
                    "--rows {r} is an ablation row, and this experiment runs without --ablation"
                ),
                "add --ablation, or leave the row out",
            ));
        }
        if !names.contains(&r.as_str()) {
            return Err(user_error(
                format!("--rows: no row is called {r:?}"),
                format!("the rows of this experiment: {}", names.join(", ")),
            ));
        }
    }
    Ok(())
}

/// `fit/scene.toml` and `fit/sensor.toml` (with their reports), unless a finished fit of
/// the same frames is there (`fit/fit.done`). True when they were fitted now.
fn ensure_fits(s: &Settings, dir: &Path, printer: &Log) -> Result<bool> {
    let record = serde_json::to_string_pretty(&serde_json::json!({
        "fit": s.fit, "scenes": s.fit_scenes
    }))? + "\n";
    let marker = dir.join("fit.done");
    if std::fs::read_to_string(&marker).is_ok_and(|t| t == record) {
        printer.info(format!("reusing the fits in {}", dir.display()));
        return Ok(false);
    }
    if dir.exists() {
        std::fs::remove_dir_all(dir).with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    printer.info(format!("fitting the sensor to {}", s.fit.display()));
    let sensor = synthgen_jobs::fit::fit_sensor_to_file(
        &s.fit,
        &s.fit_scenes,
        0.02,
        synthgen_core::scene::StructuredLightSpec::default(),
        &dir.join("sensor.toml"),
        printer,
    )?;
    atomic_write(
        &dir.join("sensor_report.json"),
        (serde_json::to_string_pretty(&sensor)? + "\n").as_bytes(),
    )?;
    printer.info(format!("fitting the scene to {}", s.fit.display()));
    let scene = synthgen_jobs::fit::fit_scene_to_file(
        &s.fit,
        &s.fit_scenes,
        Some(&dir.join("sensor.toml")),
        &dir.join("scene.toml"),
        printer,
    )?;
    atomic_write(
        &dir.join("scene_report.json"),
        (serde_json::to_string_pretty(&scene)? + "\n").as_bytes(),
    )?;
    atomic_write(&marker, record.as_bytes())?;
    Ok(true)
}

/// The fitted scene with the test objects and the test camera. Rest poses come from the fit
/// where it saw the object; an object no fit frame shows gets `--unseen-up` (default +z, as
/// scanned: chosen over `any` on the validation scene, docs/experiments.md).
fn base_scene(
    objects: &[TestObject],
    unseen_up: UpAxis,
    fit: &Path,
    k: &synthgen_core::Intrinsics,
    notes: &mut Vec<String>,
) -> Result<SceneSpec> {
    let path = fit.join("scene.toml");
    let mut spec = SceneSpec::from_toml_file(&path)
        .with_context(|| format!("cannot read the fitted scene {}", path.display()))?;
    let fitted: BTreeMap<u32, ObjectSpec> = spec
        .objects
        .iter()
        .filter_map(|o| Some((o.obj_id?, o.clone())))
        .collect();
    spec.objects = objects
        .iter()
        .map(|o| {
            let mut obj = o.spec();
            match fitted.get(&o.obj_id) {
                Some(f) => {
                    obj.up = f.up;
                    obj.tilt_deg = f.tilt_deg;
                }
                None => obj.up = unseen_up,
            }
            obj
        })
        .collect();
    let unseen: Vec<String> = objects
        .iter()
        .filter(|o| !fitted.contains_key(&o.obj_id))
        .map(|o| o.obj_id.to_string())
        .collect();
    if !unseen.is_empty() {
        notes.push(format!(
            "objects {}: no fit frame shows them, so their rest pose is --unseen-up {} in the synthetic sets",
            unseen.join(", "),
            unseen_up
        ));
    }
    set_camera(&mut spec, k);
    Ok(spec)
}

/// The camera distances of the test frames, read from their depth alone (no label): per frame
/// the median reading in the central fifth of the image, where the views look at; [p5, p95]
/// over the frames, widened by 10 %. None without readings.
fn test_view_distances(frames: &[SourceFrame]) -> Result<Option<[f64; 2]>> {
    use rayon::prelude::*;
    let mut d: Vec<f64> = frames
        .par_iter()
        .filter_map(|f| {
            let path = f.depth.as_ref()?;
            Some(
                synthgen_formats::bop::read_depth_m(path, f.camera.depth_scale).map(|img| {
                    let (w, h) = (img.width as usize, img.height as usize);
                    let mut v: Vec<f32> = (2 * h / 5..3 * h / 5)
                        .flat_map(|y| (2 * w / 5..3 * w / 5).map(move |x| (x, y)))
                        .map(|(x, y)| img.data[y * w + x])
                        .filter(|&z| z > 0.0)
                        .collect();
                    (!v.is_empty()).then(|| {
                        let mid = v.len() / 2;
                        f64::from(*v.select_nth_unstable_by(mid, f32::total_cmp).1)
                    })
                }),
            )
        })
        .collect::<std::result::Result<Vec<Option<f64>>, _>>()?
        .into_iter()
        .flatten()
        .collect();
    if d.is_empty() {
        return Ok(None);
    }
    d.sort_by(f64::total_cmp);
    let at = |q: f64| d[((d.len() - 1) as f64 * q).round() as usize];
    Ok(Some([at(0.05) * 0.9, at(0.95) * 1.1]))
}

/// The fitted camera distances, widened to cover the test frames' own (their depth, read
/// without labels, as their intrinsics are): a scene fitted to frames taken at 0.6 m says
/// nothing of test frames taken at 1.1 m.
fn widen_distances(
    spec: &mut SceneSpec,
    test_frames: &[SourceFrame],
    notes: &mut Vec<String>,
) -> Result<()> {
    let Some([lo, hi]) = test_view_distances(test_frames)? else {
        return Ok(());
    };
    let fitted = spec.camera_pose.distance_m;
    let round = |v: f64| (v * 1000.0).round() / 1000.0;
    let wide = [round(fitted[0].min(lo)), round(fitted[1].max(hi))];
    if wide != fitted {
        notes.push(format!(
            "camera distances {:.3}..{:.3} m (fitted {:.3}..{:.3} m, widened to the test frames' depth at the image centre, {:.3}..{:.3} m with a 10 % margin: read without labels)",
            wide[0], wide[1], fitted[0], fitted[1], lo, hi
        ));
        spec.camera_pose.distance_m = wide;
    }
    Ok(())
}

fn set_camera(spec: &mut SceneSpec, k: &synthgen_core::Intrinsics) {
    spec.camera.width = Some(k.width);
    spec.camera.height = Some(k.height);
    spec.camera.fx = Some(k.fx);
    spec.camera.fy = Some(k.fy);
    spec.camera.cx = Some(k.cx);
    spec.camera.cy = Some(k.cy);
}

/// The scene of a variant (`None`: skipped, with a note why).
fn variant_scene(
    v: &Variant,
    base: &SceneSpec,
    s: &Settings,
    k: &synthgen_core::Intrinsics,
    notes: &mut Vec<String>,
) -> Result<Option<SceneSpec>> {
    let mut spec = base.clone();
    match v.name {
        "synth_fitted" => {}
        "synth_no_sensor" => {
            spec.sensor.depth = DepthModel::None;
        }
        "synth_d455" => {
            let rgb = spec.sensor.rgb.clone();
            spec.sensor = SensorSpec::builtin("d455").unwrap_or_default();
            spec.sensor.rgb = rgb;
        }
        "ablation_no_scene_fit" => {
            let mut d = SceneSpec {
                sensor: base.sensor.clone(),
                objects: base.objects.clone(),
                ..SceneSpec::default()
            };
            for o in &mut d.objects {
                o.up = UpAxis::default();
                o.tilt_deg = 0.0;
            }
            set_camera(&mut d, k);
            spec = d;
        }
        "ablation_unseen_on_z" => {
            for o in &mut spec.objects {
                if o.up == UpAxis::Stable {
                    o.up = UpAxis::default();
                }
            }
        }
        "ablation_distractors" => spec.distractors.count = [1, 3],
        "ablation_textures" => match textures_dir() {
            Some(t) => {
                spec.ground.texture_dir = Some(t.join("ground"));
                spec.walls.count = [2, 4];
                spec.walls.texture_dir = Some(t.join("walls"));
            }
            None => {
                notes.push(
                    "ablation_textures skipped: no textures/ folder here (run from the repository)"
                        .into(),
                );
                return Ok(None);
            }
        },
        "ablation_physics" => spec.placement.mode = PlacementMode::Physics,
        _ => {}
    }
    let _ = s;
    spec.validate()?;
    Ok(Some(spec))
}

/// The shipped procedural textures: `./textures`, else the repository's.
fn textures_dir() -> Option<PathBuf> {
    [
        PathBuf::from("textures"),
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../textures"),
    ]
    .into_iter()
    .find(|p| p.join("ground").is_dir() && p.join("walls").is_dir())
    .and_then(|p| p.canonicalize().ok())
}

/// Renders a variant's set into `sources/NAME` (BOP) through the pipeline library, unless a
/// finished render of the same scene, frames and seed is there (`sources/NAME.done`). The
/// flag: rendered now. Up to `max_failed_fraction` of the frames may fail (they are left
/// out, listed in the set's synthgen.json and the report's `skipped_frames`).
/// How a synthetic set is rendered: frames `0..frames` of `seed`, at a quarter of the
/// camera's resolution with `quick`, through `backend`.
struct RenderPlan {
    frames: usize,
    seed: u64,
    quick: bool,
    backend: Backend,
    /// The experiment's reproducing command, recorded in the set's manifest.
    command_line: Vec<String>,
}

fn ensure_render(
    s: &RenderPlan,
    out: &Path,
    name: &str,
    spec: &SceneSpec,
    max_failed_fraction: f64,
    printer: &Log,
) -> Result<(PathBuf, bool)> {
    let sources = out.join("sources");
    std::fs::create_dir_all(&sources)
        .with_context(|| format!("cannot create {}", sources.display()))?;
    let dir = std::path::absolute(sources.join(name))?;
    let mut spec = spec.clone();
    if s.quick {
        // A quarter of the camera's resolution, the same field of view.
        let k = spec.camera.intrinsics()?;
        spec.camera.width = Some((k.width / 4).max(8));
        spec.camera.height = Some((k.height / 4).max(8));
        spec.camera.fx = Some(k.fx / 4.0);
        spec.camera.fy = Some(k.fy / 4.0);
        spec.camera.cx = Some(k.cx / 4.0);
        spec.camera.cy = Some(k.cy / 4.0);
        spec.validate()?;
    }
    let scene_path = sources.join(format!("{name}.toml"));
    let scene_text = spec.to_toml();
    let record = match s.backend {
        Backend::Cpu => serde_json::json!({
            "scene": scene_text, "frames": s.frames, "seed": s.seed
        }),
        ref b => serde_json::json!({
            "scene": scene_text, "frames": s.frames, "seed": s.seed, "backend": b.name()
        }),
    };
    let record = serde_json::to_string_pretty(&record)? + "\n";
    let marker = sources.join(format!("{name}.done"));
    if std::fs::read_to_string(&marker).is_ok_and(|t| t == record) && dir.is_dir() {
        printer.info(format!("reusing {} (rendered earlier)", dir.display()));
        return Ok((dir, false));
    }
    if dir.exists() {
        std::fs::remove_dir_all(&dir)
            .with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    atomic_write(&scene_path, scene_text.as_bytes())?;
    printer.info(format!(
        "rendering {name}: {} frames of {}, seed {}{}",
        s.frames,
        scene_path.display(),
        s.seed,
        match s.backend {
            Backend::Cpu => "",
            Backend::Blender(_) => ", Blender Cycles",
        }
    ));
    let t = Instant::now();
    let job = RenderJob::new(spec)
        .frames(0..s.frames as u64)
        .seed(s.seed)
        .backend(s.backend.clone())
        .build(printer)
        .with_context(|| format!("cannot prepare the render of {name}"))?;
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let _lock = OutputLock::acquire(&dir)?;
    let mut options = WriteOptions::new(&dir, SinkOptions::new(Format::Bop));
    options.command_line = s.command_line.clone();
    let report = job.write(&options, printer)?;
    if let Some((i, e)) = report.failures.first() {
        let share = report.failures.len() as f64 / s.frames.max(1) as f64;
        let what = format!(
            "{} of {} frames of {} failed to render (first: frame {i}: {e})",
            report.failures.len(),
            s.frames,
            dir.display()
        );
        if share > max_failed_fraction {
            return Err(user_error(
                what,
                "check the objects' models and the scene, or allow more with --max-failed-fraction",
            ));
        }
        printer.warning(format!(
            "{what}; left out (within --max-failed-fraction {max_failed_fraction})"
        ));
    }
    if !report.resampled.is_empty() {
        printer.info(format!(
            "{name}: {} frames placed on another draw ({} with fewer objects)",
            report.resampled.len(),
            report
                .resampled
                .iter()
                .filter(|r| !r.dropped.is_empty())
                .count()
        ));
    }
    printer.info(format!(
        "rendered {} frames into {} in {:.1} s",
        report.written,
        dir.display(),
        t.elapsed().as_secs_f64()
    ));
    atomic_write(&marker, record.as_bytes())?;
    Ok((dir, true))
}
