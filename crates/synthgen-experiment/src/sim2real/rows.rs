//! The rows of `experiment sim2real`: a model trained on one dataset (synthetic or real),
//! or the naive centroid, scored on the real test instances, overall and per object.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use synthgen_core::glam::DVec3;
use synthgen_core::NoProgress;
use synthgen_formats::io::atomic_write;
use synthgen_formats::source::FrameSource;
use synthgen_physics::refine::{refine_centre, RefineOptions, Refined, Surface};
use synthgen_train::data::{load_source_instances, DataOptions, Instance};
use synthgen_train::dataset_objects::load_each_object;
use synthgen_train::eval::{read_gt, score_predictions, GtInstance};
use synthgen_train::metrics::Rotations;
use synthgen_train::models::tnet::DEFAULT_SCALE;
use synthgen_train::models::ModelKind;
use synthgen_train::pose_model::{load_dataset_objects, Objects, Prediction};
use synthgen_train::train::{
    self, centre_error_m, load_model, EpochMetrics, Schedule, TrainConfig, TrainObserver,
    MODEL_FILE,
};

use super::Settings;
use crate::options::Refine;
use crate::settings::{read_row_file, row_dir, ROW_FILE};
use crate::Log;

/// Instances below this visible fraction are neither trained on nor scored (BOP's rule).
pub const MIN_VISIB_FRACT: f64 = 0.1;
/// Model points per object in the full model's loss.
const LOSS_POINTS: usize = 100;

/// Errors on a set of instances (the names `report.json` promises).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    pub n: usize,
    /// NaN (JSON null) over no instance.
    #[serde(deserialize_with = "nan_if_null")]
    pub mean_centre_error_cm: f64,
    #[serde(deserialize_with = "nan_if_null")]
    pub median_centre_error_cm: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub add_s_acc: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acc_5cm5deg: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_te_cm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_re_deg: Option<f64>,
}

/// An f64 that JSON wrote as null (serde_json writes NaN so) read back as NaN.
fn nan_if_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// `row.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RowRecord {
    pub name: String,
    /// What the row is, in words.
    pub what: String,
    /// The training set (None: no training).
    pub trained_on: Option<PathBuf>,
    pub train_instances: usize,
    pub epochs: usize,
    pub all: Metrics,
    /// Per object id.
    pub objects: BTreeMap<String, Metrics>,
    /// Per test scene id (centre errors).
    #[serde(default)]
    pub scenes: BTreeMap<String, Metrics>,
    pub last_epoch: Option<EpochMetrics>,
    pub seconds_train: f64,
    pub seconds_eval: f64,
    /// With `--refine icp`: the centres as the model gave them, before the refinement.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub before_refine: Option<Metrics>,
    /// With `--refine icp`: the share of the instances whose refined centre was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine_accepted: Option<f64>,
}

/// The finished row's record, if one reads.
pub fn read_record(out: &Path, name: &str) -> Option<RowRecord> {
    read_row_file(out, name)
}

fn write_record(out: &Path, r: &RowRecord) -> Result<()> {
    let text = serde_json::to_string_pretty(r)? + "\n";
    atomic_write(&row_dir(out, &r.name).join(ROW_FILE), text.as_bytes())?;
    Ok(())
}

/// The real test instances, loaded once for every row.
pub struct TestSet {
    pub instances: Vec<Instance>,
    /// GT instances for the rotation metrics of `full` (every one counts).
    pub gts: Vec<GtInstance>,
    /// The objects' models for `full`'s metrics.
    pub objects: Option<Objects>,
    /// The objects' surfaces for `--refine icp`.
    pub surfaces: Option<BTreeMap<u32, Surface>>,
}

fn model_kind(s: &Settings) -> ModelKind {
    match s.model.as_str() {
        "full" => ModelKind::Full,
        "rnet" => ModelKind::Rnet,
        _ => ModelKind::Tnet,
    }
}

fn data_options(s: &Settings, seed: u64, split: Option<String>) -> DataOptions {
    DataOptions {
        n_points: s.points,
        min_visib_fract: MIN_VISIB_FRACT,
        seed,
        split,
        crop_size: if model_kind(s).needs_rgb() { 48 } else { 0 },
        ..DataOptions::default()
    }
}

/// Loads the test frames' instances (the chosen scenes), with their real depth and visible
/// masks.
pub fn load_test(s: &Settings, test: &dyn FrameSource, scenes: &[u32]) -> Result<TestSet> {
    let set = load_source_instances(test, &data_options(s, s.seed, None), &NoProgress)
        .with_context(|| format!("cannot load the test frames of {}", test.root().display()))?;
    let keep = |scene: u32| scenes.is_empty() || scenes.contains(&scene);
    let instances: Vec<Instance> = set
        .instances
        .into_iter()
        .filter(|i| keep(i.scene_id))
        .collect();
    if instances.is_empty() {
        anyhow::bail!(
            "no test instance with enough depth readings in {}",
            test.root().display()
        );
    }
    let (gts, objects) = if model_kind(s) == ModelKind::Tnet {
        (Vec::new(), None)
    } else {
        let ids: BTreeSet<u32> = instances.iter().map(|i| i.obj_id).collect();
        let gts = read_gt(test, &set.split, MIN_VISIB_FRACT)?
            .into_iter()
            .filter(|g| keep(g.scene_id))
            .collect();
        (gts, Some(load_dataset_objects(test, ids, LOSS_POINTS)?))
    };
    let surfaces = match s.refine {
        Refine::None | Refine::Edges | Refine::Views => None,
        Refine::Icp => {
            let ids: BTreeSet<u32> = instances.iter().map(|i| i.obj_id).collect();
            let loaded = load_each_object(
                test.models_info(),
                &test.models_info_path(),
                &|id| test.model_file(id),
                test.model_units(),
                ids,
                |model, _| (model.name.clone(), Surface::new(model)),
            )
            .with_context(|| format!("cannot load the models of {}", test.root().display()))?;
            let mut surfaces = BTreeMap::new();
            for (id, (name, surface)) in loaded {
                let surface =
                    surface.with_context(|| format!("cannot refine on object {id} ({name})"))?;
                surfaces.insert(id, surface);
            }
            Some(surfaces)
        }
    };
    Ok(TestSet {
        instances,
        gts,
        objects,
        surfaces,
    })
}

/// With `--refine icp`: each prediction's centre refined by ICP of its object's model on the
/// instance's real depth points (in parallel over instances). Returns the centres before and
/// the share of refinements kept; `None` (nothing changed) without surfaces.
fn refine_centres(
    tested: &[&Instance],
    preds: &mut [Prediction],
    test: &TestSet,
) -> Option<(Vec<Option<[f32; 3]>>, f64)> {
    let surfaces = test.surfaces.as_ref()?;
    let before: Vec<Option<[f32; 3]>> = preds.iter().map(|p| p.centre_m).collect();
    let opts = RefineOptions::default();
    let refined: Vec<Option<Refined>> = tested
        .par_iter()
        .zip(&before)
        .map(|(inst, c)| {
            let c = (*c)?;
            let surface = surfaces.get(&inst.obj_id)?;
            let pts: Vec<DVec3> = inst
                .points_m
                .iter()
                .map(|p| DVec3::new(p[0].into(), p[1].into(), p[2].into()))
                .collect();
            let init = DVec3::new(c[0].into(), c[1].into(), c[2].into());
            refine_centre(surface, &pts, init, &opts)
        })
        .collect();
    let mut kept = 0usize;
    for (p, r) in preds.iter_mut().zip(&refined) {
        if let Some(r) = r.filter(|r| r.accepted) {
            kept += 1;
            p.centre_m = Some(r.centre_m.to_array().map(|v| v as f32));
        }
    }
    Some((before, kept as f64 / preds.len().max(1) as f64))
}

/// Advances the bar once per epoch; the message shows the row and its loss.
pub(super) struct Observer<'a> {
    pub printer: &'a Log<'a>,
    pub name: &'a str,
}

impl TrainObserver for Observer<'_> {
    fn epoch_start(&self, epoch: usize, epochs: usize, _steps: usize) {
        self.printer
            .set_message(format!("{} epoch {epoch}/{epochs}", self.name));
    }

    fn epoch_end(&self, m: &EpochMetrics) {
        self.printer.set_message(format!(
            "{} epoch {} loss {:.4}",
            self.name, m.epoch, m.train_loss
        ));
    }
}

/// What to train a row on.
pub struct TrainSpec<'a> {
    pub name: &'a str,
    pub what: String,
    pub data: &'a dyn FrameSource,
    /// Only these scenes of `data` (all when empty).
    pub scenes: &'a [u32],
    /// Epochs, or `None` for as many optimizer steps as `steps` gives.
    pub epochs: Option<usize>,
    pub steps: Option<usize>,
    /// Perturbations of the training instances (the synthetic sets').
    pub augment: synthgen_train::data::Augment,
    /// TNet conditioned on the object class (the training set's objects).
    pub per_object: bool,
}

/// Trains a model on `spec.data` and scores it on `test` (a row from scratch; `row.json`
/// last).
pub fn train_row(
    s: &Settings,
    out: &Path,
    spec: &TrainSpec,
    test: &TestSet,
    printer: &Log,
) -> Result<RowRecord> {
    let dir = row_dir(out, spec.name);
    if dir.exists() {
        std::fs::remove_dir_all(&dir)
            .with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let t0 = Instant::now();
    let opts = DataOptions {
        augment: spec.augment,
        ..data_options(s, s.seed, None)
    };
    let set = load_source_instances(spec.data, &opts, &NoProgress)
        .with_context(|| format!("cannot load {}", spec.data.root().display()))?;
    let mut set = set;
    if !spec.scenes.is_empty() {
        set.instances.retain(|i| spec.scenes.contains(&i.scene_id));
    }
    if set.instances.is_empty() {
        anyhow::bail!(
            "no usable training instance in {}",
            spec.data.root().display()
        );
    }
    let model = model_kind(s);
    let objects = if model == ModelKind::Tnet {
        None
    } else {
        Some(load_dataset_objects(spec.data, set.obj_ids(), LOSS_POINTS)?)
    };
    let per_epoch = set.instances.len().div_ceil(s.batch).max(1);
    let epochs = match (spec.epochs, spec.steps) {
        (Some(e), _) => e,
        (None, Some(steps)) => steps.div_ceil(per_epoch).clamp(1, 2000),
        (None, None) => s.epochs,
    };
    let cfg = TrainConfig {
        objects: Vec::new(),
        model,
        width: s.width,
        n_points: s.points,
        normalization_scale: DEFAULT_SCALE,
        epochs,
        batch: s.batch,
        lr: s.lr,
        weight_decay: 1e-4,
        schedule: Schedule::Cosine,
        seed: s.seed,
        val_fraction: 0.1,
        min_visib_fract: MIN_VISIB_FRACT,
        data: spec.data.root().to_path_buf(),
        split: set.split.clone(),
        crop_size: if model.needs_rgb() { 48 } else { 0 },
        loss_points: LOSS_POINTS,
        init: Vec::new(),
        plain_add_loss: false,
        translation: None,
        classes: if spec.per_object && model == ModelKind::Tnet {
            set.obj_ids().into_iter().collect()
        } else {
            Vec::new()
        },
    };
    let device = train::device(false)?;
    // An ensemble of `s.ensemble` TNets on the same frames, each from its own training seed
    // (member 0 is the single model's run, in train/), their centres averaged.
    let members = if model == ModelKind::Tnet {
        s.ensemble.max(1)
    } else {
        1
    };
    let tested: Vec<&Instance> = test.instances.iter().collect();
    let mut outcome = None;
    let mut sums: Vec<[f64; 3]> = vec![[0.0; 3]; tested.len()];
    let mut preds = Vec::new();
    let mut seconds_eval = 0.0;
    for k in 0..members {
        let cfg = TrainConfig {
            objects: Vec::new(),
            seed: member_seed(s.seed, k),
            ..cfg.clone()
        };
        let run_dir = if k == 0 {
            dir.join("train")
        } else {
            dir.join(format!("train_{k}"))
        };
        let o = train::train(
            &cfg,
            &set,
            objects.as_ref(),
            &run_dir,
            false,
            &device,
            &Observer {
                printer,
                name: spec.name,
            },
        )?;
        outcome.get_or_insert(o);
        let t1 = Instant::now();
        let net = load_model(&run_dir.join(MODEL_FILE), &cfg, &device)?;
        preds = net.predict(&tested, test.objects.as_ref(), 64)?;
        for (sum, p) in sums.iter_mut().zip(&preds) {
            if let Some(c) = p.centre_m {
                for (a, v) in sum.iter_mut().zip(c) {
                    *a += f64::from(v);
                }
            }
        }
        seconds_eval += t1.elapsed().as_secs_f64();
    }
    if members > 1 {
        for (p, sum) in preds.iter_mut().zip(&sums) {
            p.centre_m = Some(sum.map(|v| (v / members as f64) as f32));
        }
    }
    let outcome = outcome.context("no ensemble member trained")?;
    let seconds_train = t0.elapsed().as_secs_f64() - seconds_eval;
    let t1 = Instant::now();
    let (before_refine, refine_accepted) = match refine_centres(&tested, &mut preds, test) {
        Some((before, kept)) => {
            let unrefined: Vec<Prediction> = preds
                .iter()
                .zip(before)
                .map(|(p, c)| Prediction { centre_m: c, ..*p })
                .collect();
            (Some(score(&tested, &unrefined, test)?.0), Some(kept))
        }
        None => (None, None),
    };
    let (all, objects_m, scenes) = score(&tested, &preds, test)?;
    let record = RowRecord {
        name: spec.name.to_string(),
        what: spec.what.clone(),
        trained_on: Some(spec.data.root().to_path_buf()),
        train_instances: outcome.n_train,
        epochs,
        all,
        objects: objects_m,
        scenes,
        last_epoch: outcome.history.last().cloned(),
        seconds_train,
        seconds_eval: seconds_eval + t1.elapsed().as_secs_f64(),
        before_refine,
        refine_accepted,
    };
    write_record(out, &record)?;
    Ok(record)
}

/// With `--refine icp`, the naive baseline refined the same way: the ICP started from the
/// mean of the masked depth points instead of a model's centre (what the network adds to
/// the refinement). `None` without `--refine icp`.
pub fn naive_icp_row(out: &Path, test: &TestSet) -> Result<Option<RowRecord>> {
    let t0 = Instant::now();
    let tested: Vec<&Instance> = test.instances.iter().collect();
    let mut preds: Vec<Prediction> = tested
        .iter()
        .map(|i| Prediction {
            centre_m: Some(centroid(&i.points_m)),
            rotation: None,
        })
        .collect();
    let Some((_, kept)) = refine_centres(&tested, &mut preds, test) else {
        return Ok(None);
    };
    std::fs::create_dir_all(row_dir(out, NAIVE_ICP))?;
    let (all, objects, scenes) = score(&tested, &preds, test)?;
    let record = RowRecord {
        name: NAIVE_ICP.into(),
        what: "ICP of the object's model on the real depth from the naive centroid (no training)"
            .into(),
        trained_on: None,
        train_instances: 0,
        epochs: 0,
        all,
        objects,
        scenes,
        last_epoch: None,
        seconds_train: 0.0,
        seconds_eval: t0.elapsed().as_secs_f64(),
        before_refine: None,
        refine_accepted: Some(kept),
    };
    write_record(out, &record)?;
    Ok(Some(record))
}

pub const NAIVE_ICP: &str = "naive_icp";

/// The training seed of ensemble member `k` (member 0: the experiment's seed).
fn member_seed(seed: u64, k: usize) -> u64 {
    seed.wrapping_add(1_000_003 * k as u64)
}

/// The naive baseline: the centre is the mean of the instance's masked depth points.
pub fn naive_row(out: &Path, test: &TestSet) -> Result<RowRecord> {
    let t0 = Instant::now();
    std::fs::create_dir_all(row_dir(out, NAIVE))?;
    let errors: Vec<(u32, f64)> = test
        .instances
        .iter()
        .map(|i| (i.obj_id, centre_error_m(centroid(&i.points_m), i)))
        .collect();
    let by_scene: Vec<(u32, f64)> = test
        .instances
        .iter()
        .zip(&errors)
        .map(|(i, e)| (i.scene_id, e.1))
        .collect();
    let record = RowRecord {
        name: NAIVE.into(),
        what: "the mean of the masked real depth points as the centre (no training)".into(),
        trained_on: None,
        train_instances: 0,
        epochs: 0,
        all: centre_metrics(errors.iter().map(|e| e.1)),
        objects: per_object(&errors)
            .into_iter()
            .map(|(id, v)| (id.to_string(), centre_metrics(v.into_iter())))
            .collect(),
        scenes: per_object(&by_scene)
            .into_iter()
            .map(|(id, v)| (id.to_string(), centre_metrics(v.into_iter())))
            .collect(),
        last_epoch: None,
        seconds_train: 0.0,
        seconds_eval: t0.elapsed().as_secs_f64(),
        before_refine: None,
        refine_accepted: None,
    };
    write_record(out, &record)?;
    Ok(record)
}

pub const NAIVE: &str = "naive_centroid";

fn centroid(points: &[[f32; 3]]) -> [f32; 3] {
    let n = points.len().max(1) as f64;
    let mut c = [0f64; 3];
    for p in points {
        for k in 0..3 {
            c[k] += f64::from(p[k]);
        }
    }
    [(c[0] / n) as f32, (c[1] / n) as f32, (c[2] / n) as f32]
}

/// Errors grouped by their key (object or scene id).
fn per_object(errors: &[(u32, f64)]) -> BTreeMap<u32, Vec<f64>> {
    let mut m: BTreeMap<u32, Vec<f64>> = BTreeMap::new();
    for &(id, e) in errors {
        m.entry(id).or_default().push(e);
    }
    m
}

/// Mean and median of centre errors given in metres, reported in cm.
fn centre_metrics(errors_m: impl Iterator<Item = f64>) -> Metrics {
    let mut v: Vec<f64> = errors_m.filter(|e| e.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let mean = if n == 0 {
        f64::NAN
    } else {
        100.0 * v.iter().sum::<f64>() / n as f64
    };
    let median = if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        100.0 * v[n / 2]
    } else {
        50.0 * (v[n / 2 - 1] + v[n / 2])
    };
    Metrics {
        n,
        mean_centre_error_cm: mean,
        median_centre_error_cm: median,
        add_s_acc: None,
        acc_5cm5deg: None,
        mean_te_cm: None,
        mean_re_deg: None,
    }
}

/// Centre errors (all models that predict a centre) and, for rotation models, the ADD(-S),
/// 5cm5° and mean errors as `synthgen eval --checkpoint` scores them.
#[allow(clippy::type_complexity)]
fn score(
    tested: &[&Instance],
    preds: &[Prediction],
    test: &TestSet,
) -> Result<(
    Metrics,
    BTreeMap<String, Metrics>,
    BTreeMap<String, Metrics>,
)> {
    let with_scene: Vec<(u32, u32, f64)> = preds
        .iter()
        .zip(tested)
        .filter_map(|(p, i)| {
            p.centre_m
                .map(|c| (i.scene_id, i.obj_id, centre_error_m(c, i)))
        })
        .collect();
    let errors: Vec<(u32, f64)> = with_scene.iter().map(|e| (e.1, e.2)).collect();
    let scenes: BTreeMap<String, Metrics> =
        per_object(&with_scene.iter().map(|e| (e.0, e.2)).collect::<Vec<_>>())
            .into_iter()
            .map(|(id, v)| (id.to_string(), centre_metrics(v.into_iter())))
            .collect();
    let mut all = centre_metrics(errors.iter().map(|e| e.1));
    let mut objects: BTreeMap<String, Metrics> = per_object(&errors)
        .into_iter()
        .map(|(id, v)| (id.to_string(), centre_metrics(v.into_iter())))
        .collect();
    if let Some(objs) = &test.objects {
        let report = score_predictions(
            preds,
            tested.iter().copied(),
            &test.gts,
            objs,
            Rotations::default(),
        )?;
        let fill = |m: &mut Metrics, s: &synthgen_train::eval::ObjectScores| {
            m.add_s_acc = Some(s.add_s_acc);
            m.acc_5cm5deg = Some(s.acc_5cm5deg);
            m.mean_te_cm = s.mean_te_cm;
            m.mean_re_deg = s.mean_re_deg;
        };
        fill(&mut all, &report.all);
        for (id, sc) in &report.per_object {
            if let Some(m) = objects.get_mut(&id.to_string()) {
                fill(m, sc);
            }
        }
    }
    Ok((all, objects, scenes))
}

/// `rows/<main row>/no_gt.json`: the main row's model(s) from raw frames (issue 52), each
/// instance's points from the detector's mask of its object in its image (BOP's localization
/// protocol: the objects and their counts per image are known, not where they are), refined
/// as the row is; instances without a detection are misses, counted in `detected`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoGtRecord {
    pub row: String,
    /// The detector's run folder.
    pub detector: PathBuf,
    /// The GT test instances the row is scored on with GT masks, and of them those a
    /// detection's mask gave enough depth readings (the others are misses).
    pub n_gt: usize,
    pub detected: usize,
    /// Errors over the detected instances.
    pub all: Metrics,
    pub objects: BTreeMap<String, Metrics>,
    pub scenes: BTreeMap<String, Metrics>,
    /// Per object: GT instances and those detected.
    pub objects_detected: BTreeMap<String, [usize; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub before_refine: Option<Metrics>,
    pub seconds: f64,
}

/// The file of [`NoGtRecord`] in the main row's folder.
pub const NO_GT_FILE: &str = "no_gt.json";

/// The main row's trained model(s) (every ensemble member, their centres averaged) on the
/// test frames' instances (of the test scenes) with their points from the experiment's
/// detections (masks and boxes), refined as the row is, scored on the test scenes; written to [`NO_GT_FILE`].
pub fn no_gt_row(
    s: &Settings,
    out: &Path,
    row: &str,
    test_src: &dyn FrameSource,
    test: &TestSet,
    detector: &Path,
    printer: &Log,
) -> Result<NoGtRecord> {
    let t0 = Instant::now();
    let scenes = &s.test_scenes;
    let detections = &out.join(super::detect::DETECTIONS_FILE);
    let kept = super::detect::joined_detections(out, test_src, &[], printer)?;
    if !kept.iter().any(|d| d.segmentation.is_some()) && !kept.is_empty() {
        anyhow::bail!(
            "the detections in {} have no masks: the depth models read each instance's points from its mask (train the detector with masks)",
            detections.display()
        );
    }
    let opts = DataOptions {
        crop_boxes: Some(std::sync::Arc::new(
            synthgen_detect::detections::crop_boxes(&kept),
        )),
        crop_masks: Some(std::sync::Arc::new(
            synthgen_detect::detections::crop_masks(&kept),
        )),
        ..data_options(s, s.seed, None)
    };
    let set = load_source_instances(test_src, &opts, &NoProgress).with_context(|| {
        format!(
            "cannot load the test frames of {}",
            test_src.root().display()
        )
    })?;
    let keep = |scene: u32| scenes.is_empty() || scenes.contains(&scene);
    let tested: Vec<&Instance> = set.instances.iter().filter(|i| keep(i.scene_id)).collect();
    let dir = row_dir(out, row);
    let device = train::device(false)?;
    let mut sums: Vec<[f64; 3]> = vec![[0.0; 3]; tested.len()];
    let mut preds = Vec::new();
    let mut members = 0usize;
    for k in 0.. {
        let run_dir = if k == 0 {
            dir.join("train")
        } else {
            dir.join(format!("train_{k}"))
        };
        if !run_dir.join(MODEL_FILE).is_file() {
            break;
        }
        let cfg: TrainConfig =
            train::read_run_config(&run_dir.join(train::CONFIG_FILE), train::RunKind::Pose)?;
        let net = load_model(&run_dir.join(MODEL_FILE), &cfg, &device)?;
        preds = net.predict(&tested, test.objects.as_ref(), 64)?;
        for (sum, p) in sums.iter_mut().zip(&preds) {
            if let Some(c) = p.centre_m {
                for (a, v) in sum.iter_mut().zip(c) {
                    *a += f64::from(v);
                }
            }
        }
        members += 1;
    }
    if members == 0 {
        anyhow::bail!("no trained model in {}", dir.display());
    }
    if members > 1 {
        for (p, sum) in preds.iter_mut().zip(&sums) {
            p.centre_m = Some(sum.map(|v| (v / members as f64) as f32));
        }
    }
    let before_refine = match refine_centres(&tested, &mut preds, test) {
        Some((before, _)) => {
            let unrefined: Vec<Prediction> = preds
                .iter()
                .zip(before)
                .map(|(p, c)| Prediction { centre_m: c, ..*p })
                .collect();
            Some(score(&tested, &unrefined, test)?.0)
        }
        None => None,
    };
    let (all, objects, scenes_m) = score(&tested, &preds, test)?;
    let mut objects_detected: BTreeMap<String, [usize; 2]> = BTreeMap::new();
    for i in &test.instances {
        objects_detected.entry(i.obj_id.to_string()).or_default()[0] += 1;
    }
    for i in &tested {
        objects_detected.entry(i.obj_id.to_string()).or_default()[1] += 1;
    }
    let record = NoGtRecord {
        row: row.to_string(),
        detector: detector.to_path_buf(),
        n_gt: test.instances.len(),
        detected: tested.len(),
        all,
        objects,
        scenes: scenes_m,
        objects_detected,
        before_refine,
        seconds: t0.elapsed().as_secs_f64(),
    };
    atomic_write(
        &dir.join(NO_GT_FILE),
        (serde_json::to_string_pretty(&record)? + "\n").as_bytes(),
    )?;
    Ok(record)
}
