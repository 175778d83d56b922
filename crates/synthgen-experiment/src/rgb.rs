//! `synthgen experiment rgb`: seed 001's Table 1 in one command. The RGB model is trained
//! twice on the same set with the same seed and budget, once per translation
//! parametrization (centre + Tz, direct XYZ), and both are scored on the same held-out
//! frames: 5cm5° accuracy, mean E_te and E_re per object and their mean over objects, per
//! test scene too. A variant is done when its `scores.json` exists (written last); a re-run
//! with the same options keeps it.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use synthgen_core::Progress;
use synthgen_formats::io::atomic_write;
use synthgen_formats::layout::open_source;
use synthgen_formats::output::{check_apart, OutputLock};
use synthgen_formats::source::FrameSource;
use synthgen_train::data::{load_source_instances, Instance, InstanceSet};
use synthgen_train::eval::{eval_objects, pick_split, read_gt, score_predictions, Match};
use synthgen_train::metrics::{EvalObject, Rotations, TE_THRESHOLD_M};
use synthgen_train::models::rgb::Translation;
use synthgen_train::models::ModelKind;
use synthgen_train::pose_model::{load_dataset_objects, Objects};
use synthgen_train::train::{self, ProgressObserver, Schedule, TrainConfig, MODEL_FILE};

use crate::options::RgbOptions;
use crate::settings::check_settings_file;
use crate::user_error;
use crate::Log;

/// The settings file at the output's root; a re-run must match it to resume.
pub const SETTINGS_FILE: &str = "experiment.json";
/// A variant's scores, written last: the variant is done.
pub const SCORES_FILE: &str = "scores.json";
/// Model points per object in the rotation loss.
const LOSS_POINTS: usize = 100;
/// Crops per prediction batch.
const PREDICT_BATCH: usize = 64;

/// Everything that decides the numbers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    pub train: PathBuf,
    pub train_split: String,
    pub test: PathBuf,
    pub test_split: String,
    /// Scenes of `test` scored (all when empty).
    pub test_scenes: Vec<u32>,
    pub variants: Vec<Translation>,
    pub epochs: usize,
    pub batch: usize,
    pub lr: f64,
    pub width: usize,
    pub crop_size: u32,
    pub min_visib_fract: f64,
    pub seed: u64,
    pub quick: bool,
}

/// One cell group of the table: a variant's scores on some GT instances.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Cell {
    /// GT instances scored.
    pub n: usize,
    /// Fraction within 5 cm and 5° (a GT instance without an estimate is a miss).
    pub acc_5cm5deg: f64,
    /// Mean translation error of the estimates, cm.
    pub mean_te_cm: Option<f64>,
    /// Mean rotation error of the estimates, degrees.
    pub mean_re_deg: Option<f64>,
    /// Fraction with ADD(-S) below 10% of the diameter.
    pub add_s_acc: f64,
    /// Fraction within 5 cm, whatever the rotation: what the translation alone achieves.
    pub acc_5cm: f64,
    /// Median translation and rotation errors of the estimates.
    pub median_te_cm: Option<f64>,
    pub median_re_deg: Option<f64>,
}

/// A finished variant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VariantScores {
    pub variant: Translation,
    /// Per object id.
    pub objects: BTreeMap<u32, Cell>,
    /// Per test scene id, every object pooled.
    pub scenes: BTreeMap<u32, Cell>,
    /// Every GT instance pooled.
    pub all: Cell,
    pub train_instances: usize,
    pub epochs: usize,
    pub train_seconds: f64,
    /// Wall time of the predictions over the test crops, per crop (batches of 64).
    pub predict_ms_per_crop: f64,
}

/// The scores of `matches` (GT instances with their estimates, if any).
fn cell<'a>(
    matches: impl IntoIterator<Item = &'a Match>,
    objects: &BTreeMap<u32, EvalObject>,
) -> Cell {
    let (mut n, mut ok, mut add_ok, mut ok_5cm) = (0usize, 0usize, 0usize, 0usize);
    let (mut te, mut re) = (Vec::new(), Vec::new());
    for m in matches {
        n += 1;
        if let Some((_, err)) = &m.estimate {
            te.push(err.te_m * 100.0);
            re.push(err.re_deg);
            ok += usize::from(err.within_5cm5deg());
            ok_5cm += usize::from(err.te_m < TE_THRESHOLD_M);
            add_ok += usize::from(
                objects
                    .get(&m.gt.obj_id)
                    .is_some_and(|o| o.add_s_correct(err)),
            );
        }
    }
    let frac = |k: usize| if n == 0 { 0.0 } else { k as f64 / n as f64 };
    let mean = |v: &[f64]| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        match v.len() {
            0 => None,
            k if k % 2 == 1 => Some(v[k / 2]),
            k => Some(0.5 * (v[k / 2 - 1] + v[k / 2])),
        }
    };
    Cell {
        n,
        acc_5cm5deg: frac(ok),
        mean_te_cm: mean(&te),
        mean_re_deg: mean(&re),
        add_s_acc: frac(add_ok),
        acc_5cm: frac(ok_5cm),
        median_te_cm: median(&mut te),
        median_re_deg: median(&mut re),
    }
}

/// The mean of the objects' cells (seed 001's "mean" row); means of the errors over the
/// objects that have one.
fn mean_over_objects(cells: &BTreeMap<u32, Cell>) -> Cell {
    let k = cells.len().max(1) as f64;
    let avg = |f: &dyn Fn(&Cell) -> Option<f64>| {
        let v: Vec<f64> = cells.values().filter_map(f).collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    };
    Cell {
        n: cells.values().map(|c| c.n).sum(),
        acc_5cm5deg: cells.values().map(|c| c.acc_5cm5deg).sum::<f64>() / k,
        mean_te_cm: avg(&|c| c.mean_te_cm),
        mean_re_deg: avg(&|c| c.mean_re_deg),
        add_s_acc: cells.values().map(|c| c.add_s_acc).sum::<f64>() / k,
        acc_5cm: cells.values().map(|c| c.acc_5cm).sum::<f64>() / k,
        median_te_cm: avg(&|c| c.median_te_cm),
        median_re_deg: avg(&|c| c.median_re_deg),
    }
}

/// Refuses training frames that are test frames (the same file, a hard link, the same bytes:
/// `--train X --test X`, or a copy of X), before anything is written: the scores would measure
/// memorized frames.
fn refuse_shared_frames(
    train: &dyn FrameSource,
    train_split: &str,
    test: &dyn FrameSource,
    test_split: &str,
    test_scenes: &[u32],
) -> Result<()> {
    let test_frames: Vec<_> = test
        .frames(&[test_split.to_string()])?
        .into_iter()
        .filter(|f| test_scenes.is_empty() || test_scenes.contains(&f.location.scene_id))
        .collect();
    let train_frames = train.frames(&[train_split.to_string()])?;
    let t: Vec<&_> = test_frames.iter().collect();
    let tr: Vec<&_> = train_frames.iter().collect();
    let shared = synthgen_formats::shared_frames::same_images(&t, &tr)?;
    if let Some(&(j, i)) = shared.first() {
        return Err(user_error(
            format!(
                "{} of the {} training frames are the same images as test frames (the same file, a hard link or the same bytes), e.g. {} is the test frame {}: the scores would measure memorized frames",
                shared.len(),
                tr.len(),
                tr[j].rgb.display(),
                t[i].rgb.display()
            ),
            "test on frames the model does not train on: another dataset, or another split (--train-split / --test-split)",
        ));
    }
    Ok(())
}

fn open(dir: &Path, what: &str) -> Result<Box<dyn FrameSource>> {
    if !dir.exists() {
        return Err(user_error(
            format!("the {what} set {} does not exist", dir.display()),
            "render one with `synthgen render`, or pass the folder of a dataset",
        ));
    }
    open_source(dir).with_context(|| format!("cannot open the {what} set {}", dir.display()))
}

/// Runs `experiment rgb`; returns the table (Markdown) it also wrote to `table.md`.
pub fn run(args: RgbOptions, printer: &Log) -> Result<String> {
    let started = Instant::now();
    let q = args.quick;
    let pick =
        |v: Option<usize>, small: usize, normal: usize| v.unwrap_or(if q { small } else { normal });
    let (epochs, batch, width) = (
        pick(args.epochs, 2, 40),
        pick(args.batch, 8, 32),
        pick(args.width, 32, 256),
    );
    let crop_size = args.crop_size.unwrap_or(if q { 32 } else { 64 });
    if epochs == 0 || batch == 0 || width == 0 {
        return Err(user_error(
            "--epochs, --batch and --width must be positive",
            "e.g. --epochs 30 --batch 32 --width 256",
        ));
    }
    if crop_size < 16 {
        return Err(user_error(
            format!("--crop-size {crop_size} is too small"),
            "e.g. --crop-size 64 (at least 16)",
        ));
    }
    let mut variants: Vec<Translation> = Vec::new();
    for v in args.variants.iter().copied() {
        if !variants.contains(&v) {
            variants.push(v);
        }
    }
    if variants.is_empty() {
        return Err(user_error(
            "no --variants given",
            "e.g. --variants centre-tz,xyz",
        ));
    }
    synthgen_jobs::use_threads(args.jobs);
    let out = std::path::absolute(&args.out).unwrap_or_else(|_| args.out.clone());
    check_apart(
        &out,
        &[("training set", &args.train), ("test set", &args.test)],
    )?;
    let train_src = open(&args.train, "training")?;
    let test_src = open(&args.test, "test")?;
    let train_split = pick_split(train_src.as_ref(), args.train_split.as_deref())?;
    let test_split = pick_split(test_src.as_ref(), args.test_split.as_deref())?;
    refuse_shared_frames(
        train_src.as_ref(),
        &train_split,
        test_src.as_ref(),
        &test_split,
        &args.test_scenes,
    )?;
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let _lock = OutputLock::acquire(&out)?;
    let settings = Settings {
        train: std::path::absolute(&args.train)?,
        train_split,
        test: std::path::absolute(&args.test)?,
        test_split,
        test_scenes: args.test_scenes.clone(),
        variants: variants.clone(),
        epochs,
        batch,
        lr: args.lr,
        width,
        crop_size,
        min_visib_fract: args.min_visib_fract,
        seed: args.seed,
        quick: q,
    };
    check_settings_file(
        &out,
        SETTINGS_FILE,
        &settings,
        &[("--train", &settings.train), ("--test", &settings.test)],
        args.force,
        &["variants", "table.md", "table.csv", "report.json"],
        true,
    )?;

    // One configuration per variant; they differ only in the translation.
    let config = |v: Translation, classes: Vec<u32>| TrainConfig {
        objects: Vec::new(),
        model: ModelKind::Rgb,
        width,
        n_points: 0,
        normalization_scale: synthgen_train::models::rgb::TARGET_SCALE as f32,
        epochs,
        batch,
        lr: args.lr,
        weight_decay: 1e-4,
        schedule: Schedule::Cosine,
        seed: args.seed,
        val_fraction: 0.1,
        min_visib_fract: args.min_visib_fract,
        data: settings.train.clone(),
        split: settings.train_split.clone(),
        crop_size,
        loss_points: LOSS_POINTS,
        init: Vec::new(),
        plain_add_loss: false,
        translation: Some(v),
        classes,
    };
    let probe = config(Translation::CentreTz, Vec::new());
    cfg_valid(&probe)?;

    let mut done: BTreeMap<Translation, VariantScores> = BTreeMap::new();
    for &v in &variants {
        let path = out.join("variants").join(v.name()).join(SCORES_FILE);
        if let Ok(text) = std::fs::read_to_string(&path) {
            if let Ok(s) = serde_json::from_str::<VariantScores>(&text) {
                printer.info(format!("{}: done earlier ({})", v.name(), path.display()));
                done.insert(v, s);
            }
        }
    }
    if done.len() < variants.len() {
        let t = Instant::now();
        let train_set = load_source_instances(train_src.as_ref(), &probe.data_options(), printer)
            .with_context(|| {
            format!("cannot load the training set {}", args.train.display())
        })?;
        if train_set.instances.is_empty() {
            return Err(user_error(
                format!("no usable object instances in {}", args.train.display()),
                "check that the training set has rgb/ and mask_visib/ images",
            ));
        }
        let classes: Vec<u32> = train_set.obj_ids().into_iter().collect();
        printer.info(format!(
            "training set: {} instances of objects {:?} from {} frames ({:.1} s)",
            train_set.instances.len(),
            classes,
            train_set.frames,
            t.elapsed().as_secs_f64()
        ));
        let train_objects = load_dataset_objects(train_src.as_ref(), classes.clone(), LOSS_POINTS)
            .with_context(|| {
                format!("cannot load the object models of {}", args.train.display())
            })?;
        let test = load_test(&settings, test_src.as_ref(), &probe, &classes, printer)?;
        for &v in &variants {
            if done.contains_key(&v) {
                continue;
            }
            let scores = run_variant(
                &out,
                &config(v, classes.clone()),
                &train_set,
                &train_objects,
                &test,
                printer,
            )?;
            done.insert(v, scores);
        }
    }
    let ordered: Vec<&VariantScores> = variants.iter().filter_map(|v| done.get(v)).collect();
    let md = table_markdown(&settings, &ordered);
    atomic_write(&out.join("table.md"), md.as_bytes())?;
    atomic_write(&out.join("table.csv"), table_csv(&ordered).as_bytes())?;
    let verdict = verdict(&ordered);
    let report = serde_json::json!({
        "settings": settings,
        "variants": ordered,
        "mean_over_objects": ordered.iter().map(|s| (s.variant.name(), mean_over_objects(&s.objects))).collect::<BTreeMap<_, _>>(),
        "verdict": verdict,
        "seconds": started.elapsed().as_secs_f64(),
    });
    atomic_write(
        &out.join("report.json"),
        (serde_json::to_string_pretty(&report)? + "\n").as_bytes(),
    )?;
    if let Some(v) = &verdict {
        printer.info(v.clone());
    }
    printer.info(format!(
        "wrote {} (table.md, table.csv, report.json) in {:.1} s",
        out.display(),
        started.elapsed().as_secs_f64()
    ));
    Ok(md)
}

fn cfg_valid(cfg: &TrainConfig) -> Result<()> {
    cfg.validate()
        .map_err(|e| user_error(e.to_string(), "see `synthgen experiment rgb --help`"))
}

/// The test instances and GT of the scored scenes and trained objects, with their models.
struct TestSet {
    instances: Vec<Instance>,
    gts: Vec<synthgen_train::eval::GtInstance>,
    objects: Objects,
}

fn load_test(
    s: &Settings,
    src: &dyn FrameSource,
    probe: &TrainConfig,
    classes: &[u32],
    printer: &Log,
) -> Result<TestSet> {
    let opts = synthgen_train::data::DataOptions {
        split: Some(s.test_split.clone()),
        ..probe.data_options()
    };
    let set: InstanceSet = load_source_instances(src, &opts, printer)
        .with_context(|| format!("cannot load the test set {}", s.test.display()))?;
    let scored = |scene: u32, obj: u32| {
        (s.test_scenes.is_empty() || s.test_scenes.contains(&scene)) && classes.contains(&obj)
    };
    let all_gts = read_gt(src, &s.test_split, s.min_visib_fract)?;
    let scenes_present: std::collections::BTreeSet<u32> =
        all_gts.iter().map(|g| g.scene_id).collect();
    if let Some(missing) = s.test_scenes.iter().find(|id| !scenes_present.contains(id)) {
        return Err(user_error(
            format!(
                "--test-scenes {missing}: {} has no such scene (scenes: {:?})",
                s.test.display(),
                scenes_present
            ),
            "pass scene ids of the test set",
        ));
    }
    let untrained = all_gts
        .iter()
        .filter(|g| !classes.contains(&g.obj_id))
        .count();
    if untrained > 0 {
        printer.warning(format!(
            "{untrained} GT instances of the test set are of objects the training set lacks; they are not scored"
        ));
    }
    let gts: Vec<_> = all_gts
        .into_iter()
        .filter(|g| scored(g.scene_id, g.obj_id))
        .collect();
    let instances: Vec<Instance> = set
        .instances
        .into_iter()
        .filter(|i| scored(i.scene_id, i.obj_id))
        .collect();
    if gts.is_empty() {
        return Err(user_error(
            format!(
                "nothing to score: no GT instance of the training set's objects {classes:?} in the chosen scenes of {}",
                s.test.display()
            ),
            "test on frames of the objects you trained on",
        ));
    }
    let objects = load_dataset_objects(src, gts.iter().map(|g| g.obj_id), LOSS_POINTS)
        .with_context(|| format!("cannot load the object models of {}", s.test.display()))?;
    printer.info(format!(
        "test set: {} GT instances ({} with a usable crop) of {}/{}",
        gts.len(),
        instances.len(),
        s.test.display(),
        s.test_split
    ));
    Ok(TestSet {
        instances,
        gts,
        objects,
    })
}

fn run_variant(
    out: &Path,
    cfg: &TrainConfig,
    train_set: &InstanceSet,
    train_objects: &Objects,
    test: &TestSet,
    printer: &Log,
) -> Result<VariantScores> {
    let v = cfg.translation.unwrap_or(Translation::CentreTz);
    let dir = out.join("variants").join(v.name());
    let run_dir = dir.join("train");
    // An interrupted variant is redone from scratch.
    if run_dir.exists() {
        std::fs::remove_dir_all(&run_dir)
            .with_context(|| format!("cannot remove {}", run_dir.display()))?;
    }
    printer.info(format!(
        "{}: training on {} instances, {} epochs",
        v.name(),
        train_set.instances.len(),
        cfg.epochs
    ));
    let t = Instant::now();
    let observer = ProgressObserver {
        printer,
        epoch: std::cell::Cell::new((0, cfg.epochs)),
    };
    let device = train::device(false)?;
    let outcome = train::train(
        cfg,
        train_set,
        Some(train_objects),
        &run_dir,
        false,
        &device,
        &observer,
    )?;
    printer.finish();
    let train_seconds = t.elapsed().as_secs_f64();
    let model = train::load_model(&run_dir.join(MODEL_FILE), cfg, &device)?;
    let refs: Vec<&Instance> = test.instances.iter().collect();
    let t = Instant::now();
    let preds = model.predict(&refs, Some(&test.objects), PREDICT_BATCH)?;
    let predict_ms_per_crop = t.elapsed().as_secs_f64() * 1000.0 / refs.len().max(1) as f64;
    let report = score_predictions(
        &preds,
        &test.instances,
        &test.gts,
        &test.objects,
        Rotations::default(),
    )?;
    let objs = eval_objects(&test.objects);
    let mut by_obj: BTreeMap<u32, Vec<&Match>> = BTreeMap::new();
    let mut by_scene: BTreeMap<u32, Vec<&Match>> = BTreeMap::new();
    for m in &report.matches {
        by_obj.entry(m.gt.obj_id).or_default().push(m);
        by_scene.entry(m.gt.scene_id).or_default().push(m);
    }
    let scores = VariantScores {
        variant: v,
        objects: by_obj
            .iter()
            .map(|(&k, ms)| (k, cell(ms.iter().copied(), &objs)))
            .collect(),
        scenes: by_scene
            .iter()
            .map(|(&k, ms)| (k, cell(ms.iter().copied(), &objs)))
            .collect(),
        all: cell(&report.matches, &objs),
        train_instances: outcome.n_train + outcome.n_val,
        epochs: cfg.epochs,
        train_seconds,
        predict_ms_per_crop,
    };
    atomic_write(
        &dir.join(SCORES_FILE),
        (serde_json::to_string_pretty(&scores)? + "\n").as_bytes(),
    )?;
    printer.info(format!(
        "{}: 5cm5° {:.1}%, E_te {} cm, E_re {}° over {} GT instances (trained in {:.0} s)",
        v.name(),
        100.0 * scores.all.acc_5cm5deg,
        fmt(scores.all.mean_te_cm, 2),
        fmt(scores.all.mean_re_deg, 1),
        scores.all.n,
        train_seconds
    ));
    Ok(scores)
}

fn fmt(v: Option<f64>, digits: usize) -> String {
    v.map_or("–".into(), |v| format!("{v:.digits$}"))
}

/// Rows of one table: per key the cells of every variant.
fn rows<'a>(
    variants: &'a [&'a VariantScores],
    pick: impl Fn(&'a VariantScores) -> &'a BTreeMap<u32, Cell>,
) -> Vec<(u32, Vec<Option<Cell>>)> {
    let mut keys: Vec<u32> = variants
        .iter()
        .flat_map(|s| pick(s).keys().copied())
        .collect();
    keys.sort_unstable();
    keys.dedup();
    keys.into_iter()
        .map(|k| {
            (
                k,
                variants.iter().map(|s| pick(s).get(&k).copied()).collect(),
            )
        })
        .collect()
}

fn header(first: &str, variants: &[&VariantScores], md: &mut String) {
    let _ = write!(md, "| {first} | n |");
    for s in variants {
        let n = s.variant.name();
        let _ = write!(md, " {n} 5cm5° | {n} E_te cm | {n} E_re ° |");
    }
    md.push_str("\n|---|---:|");
    for _ in variants {
        md.push_str("---:|---:|---:|");
    }
    md.push('\n');
}

fn line(name: &str, cells: &[Option<Cell>], md: &mut String) {
    let n = cells.iter().flatten().map(|c| c.n).max().unwrap_or(0);
    let _ = write!(md, "| {name} | {n} |");
    for c in cells {
        match c {
            Some(c) => {
                let _ = write!(
                    md,
                    " {:.1}% | {} | {} |",
                    100.0 * c.acc_5cm5deg,
                    fmt(c.mean_te_cm, 2),
                    fmt(c.mean_re_deg, 1)
                );
            }
            None => md.push_str(" – | – | – |"),
        }
    }
    md.push('\n');
}

/// Seed 001's Table 1 layout (objects × variants: 5cm5°, E_te, E_re; the mean over objects),
/// then per test scene, then ADD(-S).
pub fn table_markdown(s: &Settings, variants: &[&VariantScores]) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "RGB model, trained on {} ({}), tested on {} ({}{}); GT visible boxes, no detector.\n",
        s.train.display(),
        s.train_split,
        s.test.display(),
        s.test_split,
        if s.test_scenes.is_empty() {
            String::new()
        } else {
            format!(
                ", scenes {}",
                s.test_scenes
                    .iter()
                    .map(u32::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        }
    );
    header("object", variants, &mut md);
    for (k, cells) in rows(variants, |v| &v.objects) {
        line(&k.to_string(), &cells, &mut md);
    }
    let means: Vec<Option<Cell>> = variants
        .iter()
        .map(|v| Some(mean_over_objects(&v.objects)))
        .collect();
    line("mean", &means, &mut md);
    let _ = writeln!(md, "\nPer test scene (every object pooled):\n");
    header("scene", variants, &mut md);
    for (k, cells) in rows(variants, |v| &v.scenes) {
        line(&k.to_string(), &cells, &mut md);
    }
    let all: Vec<Option<Cell>> = variants.iter().map(|v| Some(v.all)).collect();
    line("all", &all, &mut md);
    let _ = writeln!(
        md,
        "\nThe translation alone (within 5 cm, median E_te), the median E_re, and ADD(-S) accuracy (< 10% of the diameter):\n"
    );
    let _ = write!(md, "| object |");
    for v in variants {
        let n = v.variant.name();
        let _ = write!(
            md,
            " {n} 5 cm | {n} median E_te cm | {n} median E_re ° | {n} ADD(-S) |"
        );
    }
    md.push_str("\n|---|");
    md.push_str(&"---:|---:|---:|---:|".repeat(variants.len()));
    md.push('\n');
    let extra = |name: &str, cells: &[Option<Cell>], md: &mut String| {
        let _ = write!(md, "| {name} |");
        for c in cells {
            match c {
                Some(c) => {
                    let _ = write!(
                        md,
                        " {:.1}% | {} | {} | {:.1}% |",
                        100.0 * c.acc_5cm,
                        fmt(c.median_te_cm, 2),
                        fmt(c.median_re_deg, 1),
                        100.0 * c.add_s_acc
                    );
                }
                None => md.push_str(" – | – | – | – |"),
            }
        }
        md.push('\n');
    };
    for (k, cells) in rows(variants, |v| &v.objects) {
        extra(&k.to_string(), &cells, &mut md);
    }
    extra("mean", &means, &mut md);
    md
}

fn table_csv(variants: &[&VariantScores]) -> String {
    let mut csv = String::from(
        "variant,group,id,n,acc_5cm5deg,mean_te_cm,mean_re_deg,add_s_acc,acc_5cm,median_te_cm,median_re_deg\n",
    );
    let num = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6}"));
    for v in variants {
        let name = v.variant.name();
        let rows = v
            .objects
            .iter()
            .map(|(k, c)| ("object", k.to_string(), *c))
            .chain(std::iter::once((
                "object",
                "mean".to_string(),
                mean_over_objects(&v.objects),
            )))
            .chain(v.scenes.iter().map(|(k, c)| ("scene", k.to_string(), *c)))
            .chain(std::iter::once(("scene", "all".to_string(), v.all)));
        for (group, id, c) in rows {
            let _ = writeln!(
                csv,
                "{name},{group},{id},{},{:.6},{},{},{:.6},{:.6},{},{}",
                c.n,
                c.acc_5cm5deg,
                num(c.mean_te_cm),
                num(c.mean_re_deg),
                c.add_s_acc,
                c.acc_5cm,
                num(c.median_te_cm),
                num(c.median_re_deg)
            );
        }
    }
    csv
}

/// Whether centre + Tz beats direct XYZ at 5cm5° (the seed's finding), when both ran.
fn verdict(variants: &[&VariantScores]) -> Option<String> {
    let get = |t: Translation| variants.iter().find(|v| v.variant == t);
    let (c, x) = (get(Translation::CentreTz)?, get(Translation::Xyz)?);
    let (mc, mx) = (mean_over_objects(&c.objects), mean_over_objects(&x.objects));
    let wins = c
        .objects
        .iter()
        .filter(|(k, a)| {
            x.objects
                .get(k)
                .is_some_and(|b| a.acc_5cm5deg > b.acc_5cm5deg)
        })
        .count();
    let holds = if mc.acc_5cm5deg > mx.acc_5cm5deg {
        "holds"
    } else if mc.acc_5cm5deg < mx.acc_5cm5deg {
        "does not hold"
    } else {
        "cannot be told"
    };
    Some(format!(
        "seed 001's finding (centre + Tz beats direct XYZ at 5cm5°) {holds} here: mean over objects {:.1}% vs {:.1}% (E_te {} vs {} cm, within 5 cm {:.1}% vs {:.1}%); centre + Tz is better at 5cm5° on {wins} of {} objects",
        100.0 * mc.acc_5cm5deg,
        100.0 * mx.acc_5cm5deg,
        fmt(mc.mean_te_cm, 2),
        fmt(mx.mean_te_cm, 2),
        100.0 * mc.acc_5cm,
        100.0 * mx.acc_5cm,
        c.objects.len()
    ))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn c(acc: f64, te: f64) -> Cell {
        Cell {
            n: 10,
            acc_5cm5deg: acc,
            mean_te_cm: Some(te),
            mean_re_deg: Some(3.0),
            add_s_acc: acc,
            acc_5cm: acc,
            median_te_cm: Some(te),
            median_re_deg: Some(2.0),
        }
    }

    #[test]
    fn the_mean_row_is_over_objects_and_the_verdict_reads_it() {
        let centre = VariantScores {
            variant: Translation::CentreTz,
            objects: BTreeMap::from([(1, c(0.8, 2.0)), (5, c(0.4, 4.0))]),
            scenes: BTreeMap::from([(0, c(0.6, 3.0))]),
            all: c(0.6, 3.0),
            train_instances: 100,
            epochs: 2,
            train_seconds: 1.0,
            predict_ms_per_crop: 1.0,
        };
        let xyz = VariantScores {
            variant: Translation::Xyz,
            objects: BTreeMap::from([(1, c(0.5, 5.0)), (5, c(0.5, 6.0))]),
            ..centre.clone()
        };
        let m = mean_over_objects(&centre.objects);
        assert!((m.acc_5cm5deg - 0.6).abs() < 1e-12);
        assert_eq!(m.mean_te_cm, Some(3.0));
        let v = verdict(&[&centre, &xyz]).unwrap();
        assert!(
            v.contains(" holds here: mean over objects 60.0% vs 50.0%"),
            "{v}"
        );
        assert!(v.contains("better at 5cm5° on 1 of 2 objects"), "{v}");
        let s = Settings {
            train: "a".into(),
            train_split: "train_pbr".into(),
            test: "b".into(),
            test_split: "train_pbr".into(),
            test_scenes: vec![],
            variants: vec![Translation::CentreTz, Translation::Xyz],
            epochs: 2,
            batch: 8,
            lr: 1e-3,
            width: 32,
            crop_size: 32,
            min_visib_fract: 0.1,
            seed: 0,
            quick: true,
        };
        let md = table_markdown(&s, &[&centre, &xyz]);
        assert!(md.contains("| object | n | centre-tz 5cm5° | centre-tz E_te cm | centre-tz E_re ° | xyz 5cm5° |"), "{md}");
        assert!(
            md.contains("| 1 | 10 | 80.0% | 2.00 | 3.0 | 50.0% | 5.00 | 3.0 |"),
            "{md}"
        );
        assert!(
            md.contains("| mean | 20 | 60.0% | 3.00 | 3.0 | 50.0% | 5.50 | 3.0 |"),
            "{md}"
        );
        let csv = table_csv(&[&centre, &xyz]);
        assert!(
            csv.contains("centre-tz,object,mean,20,0.600000,3.000000,3.000000,0.600000,0.600000,3.000000,2.000000"),
            "{csv}"
        );
    }
}
