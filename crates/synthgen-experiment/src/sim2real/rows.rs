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
use synthgen_physics::refine::{refine_centre, refine_pose, RefineOptions, Refined, Surface};
use synthgen_render::ObjectRenderer;
use synthgen_train::bop::{
    load_render_models, prepare_bop, BopOptions, BopSetup, ErrorRecall, Target,
};
use synthgen_train::data::{load_source_instances, DataOptions, Instance};
use synthgen_train::dataset_objects::load_each_object;
use synthgen_train::eval::{
    eval_objects, evaluate, evaluate_per_scene, prediction_estimates, read_gt, GtInstance,
    ObjectScores,
};
use synthgen_train::metrics::Rotations;
use synthgen_train::models::tnet::DEFAULT_SCALE;
use synthgen_train::models::ModelKind;
use synthgen_train::pose_model::{load_dataset_objects, Objects, Prediction};
use synthgen_train::results::{write_results_csv, Estimate};
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
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub median_te_cm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub median_re_deg: Option<f64>,
    /// BOP 2019's Average Recall, the mean of `ar_vsd` (on the real depth), `ar_mssd` and
    /// `ar_mspd` (fractions), as bop_toolkit scores it; the targets are the GT instances at
    /// least 10 % visible. Models that give a rotation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ar: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ar_vsd: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ar_mssd: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ar_mspd: Option<f64>,
    /// The area under the ADD-S accuracy curve up to 10 cm, percent, as PoseCNN and
    /// DenseFusion report YCB-Video (every GT instance; a miss counts as wrong).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub add_s_auc: Option<f64>,
    /// The share of GT instances with ADD(-S) below 10 % of the diameter (ADD-S for the
    /// symmetric objects): `add_s_acc` under the name of the tables.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acc_add: Option<f64>,
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
    /// How the row was scored ([`scoring_key`]); a row scored otherwise is scored again
    /// from its trained models, without training.
    #[serde(default)]
    pub scoring: String,
}

/// What decides a row's scores once its models are trained: the metrics' version and the
/// refinement. A finished row whose `scoring` differs is rescored ([`current_record`]).
pub fn scoring_key(s: &Settings) -> String {
    format!("bop-ar-auc-2 refine={:?}", s.refine).to_lowercase()
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
    /// The test dataset's split the instances are of.
    pub split: String,
    pub instances: Vec<Instance>,
    /// GT instances for the rotation metrics of `full` (every one counts).
    pub gts: Vec<GtInstance>,
    /// The objects' models for `full`'s metrics.
    pub objects: Option<Objects>,
    /// The objects' surfaces for `--refine icp`.
    pub surfaces: Option<BTreeMap<u32, Surface>>,
    /// BOP's AR of the rotations (models that give one, and TNet with ICP's rotation).
    pub bop: Option<BopScoring>,
}

/// The test frames as BOP scores them: images, targets (the GT instances scored, at least
/// 10 % visible), the objects' models and VSD's renderer.
pub struct BopScoring {
    setup: BopSetup,
    renderer: ObjectRenderer,
}

/// Whether the rows get rotation scores: the rotation models, and TNet with ICP (the fit's
/// rotation).
fn scores_rotations(s: &Settings) -> bool {
    model_kind(s) != ModelKind::Tnet || s.refine == Refine::Icp
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
    let (gts, objects, bop) = if !scores_rotations(s) {
        (Vec::new(), None, None)
    } else {
        let ids: BTreeSet<u32> = instances.iter().map(|i| i.obj_id).collect();
        let gts: Vec<GtInstance> = read_gt(test, &set.split, MIN_VISIB_FRACT)?
            .into_iter()
            .filter(|g| keep(g.scene_id))
            .collect();
        let objects = load_dataset_objects(test, ids, LOSS_POINTS)?;
        (
            gts.clone(),
            Some(objects),
            Some(bop_scoring(test, &set.split, &gts)?),
        )
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
        split: set.split.clone(),
        instances,
        gts,
        objects,
        surfaces,
        bop,
    })
}

/// BOP's scoring of `split` of `test` with the GT instances `gts` as its targets (those at
/// least 10 % visible in the test scenes, as BOP's own target files choose them).
fn bop_scoring(test: &dyn FrameSource, split: &str, gts: &[GtInstance]) -> Result<BopScoring> {
    let mut setup = prepare_bop(test, split, None, &BopOptions::default())
        .with_context(|| format!("cannot prepare BOP scoring of {}", test.root().display()))?;
    let mut counts: BTreeMap<(u32, u32, u32), usize> = BTreeMap::new();
    for g in gts {
        *counts.entry((g.scene_id, g.im_id, g.obj_id)).or_default() += 1;
    }
    setup.targets = counts
        .into_iter()
        .map(|((scene_id, im_id, obj_id), inst_count)| Target {
            scene_id,
            im_id,
            obj_id,
            inst_count,
        })
        .collect();
    let models = load_render_models(test, setup.obj_ids())
        .with_context(|| format!("cannot load the models of {}", test.root().display()))?;
    let renderer = ObjectRenderer::new(models)
        .with_context(|| format!("cannot render the models of {}", test.root().display()))?;
    Ok(BopScoring { setup, renderer })
}

/// With `--refine icp`: each prediction refined by ICP of its object's model on the
/// instance's real depth points (in parallel over instances): a whole pose (the Full model's)
/// from its rotation and centre ([`refine_pose`]), a centre alone (TNet's) from the spread of
/// starting rotations ([`refine_centre`]), the fit's rotation then becoming the prediction's
/// (kept or not: there is no other); a refused whole-pose fit leaves the network's pose, and
/// a prediction without a centre (RNet's) is left as it is. Returns the predictions before
/// and the share of refinements kept; `None` (nothing changed) without surfaces.
fn refine_predictions(
    tested: &[&Instance],
    preds: &mut [Prediction],
    test: &TestSet,
) -> Option<(Vec<Prediction>, f64)> {
    let surfaces = test.surfaces.as_ref()?;
    let before: Vec<Prediction> = preds.to_vec();
    let opts = RefineOptions::default();
    let refined: Vec<Option<Refined>> = tested
        .par_iter()
        .zip(&before)
        .map(|(inst, p)| {
            let c = p.centre_m?;
            let surface = surfaces.get(&inst.obj_id)?;
            let pts: Vec<DVec3> = inst
                .points_m
                .iter()
                .map(|p| DVec3::new(p[0].into(), p[1].into(), p[2].into()))
                .collect();
            let init = DVec3::new(c[0].into(), c[1].into(), c[2].into());
            match p.rotation {
                Some((r, _)) => {
                    refine_pose(surface, &pts, &synthgen_core::Pose::new(r, init), &opts)
                }
                None => refine_centre(surface, &pts, init, &opts),
            }
        })
        .collect();
    let mut kept = 0usize;
    for ((p, r), b) in preds.iter_mut().zip(&refined).zip(&before) {
        let Some(r) = r else { continue };
        match b.rotation {
            // A whole pose: the fit's when it is kept, else the network's as it was.
            Some((_, confidence)) if r.accepted => p.rotation = Some((r.pose.rotation, confidence)),
            Some(_) => {}
            // A centre alone: the fit's rotation is the only one there is.
            None => p.rotation = Some((r.pose.rotation, 1.0)),
        }
        if r.accepted {
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
    let mut outcome = None;
    for k in 0..members {
        let cfg = TrainConfig {
            objects: Vec::new(),
            seed: member_seed(s.seed, k),
            ..cfg.clone()
        };
        let o = train::train(
            &cfg,
            &set,
            objects.as_ref(),
            &member_dir(&dir, k),
            false,
            &device,
            &Observer {
                printer,
                name: spec.name,
            },
        )?;
        outcome.get_or_insert(o);
    }
    let outcome = outcome.context("no ensemble member trained")?;
    let seconds_train = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let tested: Vec<&Instance> = test.instances.iter().collect();
    let preds = predict_members(&dir, &tested, test)?;
    let scores = score_row(&tested, preds, test)?;
    write_results(&dir.join(RESULTS_FILE), scores.estimates.as_deref())?;
    let record = RowRecord {
        name: spec.name.to_string(),
        what: spec.what.clone(),
        trained_on: Some(spec.data.root().to_path_buf()),
        train_instances: outcome.n_train,
        epochs,
        all: scores.all,
        objects: scores.objects,
        scenes: scores.scenes,
        last_epoch: outcome.history.last().cloned(),
        seconds_train,
        seconds_eval: t1.elapsed().as_secs_f64(),
        before_refine: scores.before_refine,
        refine_accepted: scores.refine_accepted,
        scoring: scoring_key(s),
    };
    write_record(out, &record)?;
    Ok(record)
}

/// The run folder of ensemble member `k` of a row (member 0: `train/`).
fn member_dir(row: &Path, k: usize) -> PathBuf {
    if k == 0 {
        row.join("train")
    } else {
        row.join(format!("train_{k}"))
    }
}

/// The predictions of the trained models in the row folder `dir` (every ensemble member
/// there, their centres averaged) for `tested`.
fn predict_members(dir: &Path, tested: &[&Instance], test: &TestSet) -> Result<Vec<Prediction>> {
    let device = train::device(false)?;
    let mut sums: Vec<[f64; 3]> = vec![[0.0; 3]; tested.len()];
    let mut preds = Vec::new();
    let mut members = 0usize;
    for k in 0.. {
        let run_dir = member_dir(dir, k);
        if !run_dir.join(MODEL_FILE).is_file() {
            break;
        }
        let cfg: TrainConfig =
            train::read_run_config(&run_dir.join(train::CONFIG_FILE), train::RunKind::Pose)?;
        let net = load_model(&run_dir.join(MODEL_FILE), &cfg, &device)?;
        preds = net.predict(tested, test.objects.as_ref(), 64)?;
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
    Ok(preds)
}

/// A row's scores: overall, per object and per test scene, after the refinement the test set
/// asks for, with the scores before it and the share of fits kept.
struct RowScores {
    /// The final (refined) poses as BOP results, when they have rotations.
    estimates: Option<Vec<Estimate>>,
    all: Metrics,
    objects: BTreeMap<String, Metrics>,
    scenes: BTreeMap<String, Metrics>,
    before_refine: Option<Metrics>,
    refine_accepted: Option<f64>,
}

fn score_row(
    tested: &[&Instance],
    mut preds: Vec<Prediction>,
    test: &TestSet,
) -> Result<RowScores> {
    let (before_refine, refine_accepted) = match refine_predictions(tested, &mut preds, test) {
        Some((before, kept)) => (Some(score(tested, &before, test)?.0), Some(kept)),
        None => (None, None),
    };
    let (all, objects, scenes) = score(tested, &preds, test)?;
    let estimates = preds
        .iter()
        .any(|p| p.rotation.is_some())
        .then(|| prediction_estimates(&preds, tested.iter().copied()));
    Ok(RowScores {
        estimates,
        all,
        objects,
        scenes,
        before_refine,
        refine_accepted,
    })
}

/// A row's final poses in BOP's results format (`rows/NAME/results.csv`: the refined ones,
/// what bop_toolkit or `synthgen eval --results` scores again; RNet's carry the GT
/// translation it borrows), for the rows that give rotations.
pub const RESULTS_FILE: &str = "results.csv";
/// The main row's poses from raw frames, as [`RESULTS_FILE`].
pub const NO_GT_RESULTS_FILE: &str = "no_gt_results.csv";

/// Writes `estimates` to `path` (nothing when there are none: no rotations), replacing an
/// older file either way.
fn write_results(path: &Path, estimates: Option<&[Estimate]>) -> Result<()> {
    match estimates {
        Some(e) if !e.is_empty() => {
            write_results_csv(path, e).with_context(|| format!("cannot write {}", path.display()))
        }
        _ => {
            let _ = std::fs::remove_file(path);
            Ok(())
        }
    }
}

/// The finished row `name`'s record as this run scores it: read back when it was scored the
/// same way ([`scoring_key`]); otherwise scored again from its trained models without
/// training (the baselines recomputed). `None` when the row has to be trained.
pub fn current_record(
    s: &Settings,
    out: &Path,
    name: &str,
    test: &TestSet,
    printer: &Log,
) -> Result<Option<RowRecord>> {
    let Some(mut rec) = read_record(out, name) else {
        return Ok(None);
    };
    if rec.scoring == scoring_key(s) {
        return Ok(Some(rec));
    }
    match name {
        NAIVE => return naive_row(s, out, test).map(Some),
        NAIVE_ICP => return naive_icp_row(s, out, test),
        _ => {}
    }
    let dir = row_dir(out, name);
    if !member_dir(&dir, 0).join(MODEL_FILE).is_file() {
        return Ok(None);
    }
    printer.info(format!(
        "{name}: scoring its trained model again ({})",
        scoring_key(s)
    ));
    let t0 = Instant::now();
    let tested: Vec<&Instance> = test.instances.iter().collect();
    let preds = predict_members(&dir, &tested, test)?;
    let scores = score_row(&tested, preds, test)?;
    write_results(&dir.join(RESULTS_FILE), scores.estimates.as_deref())?;
    rec.all = scores.all;
    rec.objects = scores.objects;
    rec.scenes = scores.scenes;
    rec.before_refine = scores.before_refine;
    rec.refine_accepted = scores.refine_accepted;
    rec.seconds_eval = t0.elapsed().as_secs_f64();
    rec.scoring = scoring_key(s);
    write_record(out, &rec)?;
    Ok(Some(rec))
}

/// With `--refine icp`, the naive baseline refined the same way: the ICP started from the
/// mean of the masked depth points instead of a model's centre (what the network adds to
/// the refinement). `None` without `--refine icp`.
pub fn naive_icp_row(s: &Settings, out: &Path, test: &TestSet) -> Result<Option<RowRecord>> {
    let t0 = Instant::now();
    let tested: Vec<&Instance> = test.instances.iter().collect();
    let mut preds: Vec<Prediction> = tested
        .iter()
        .map(|i| Prediction {
            centre_m: Some(centroid(&i.points_m)),
            rotation: None,
        })
        .collect();
    let Some((_, kept)) = refine_predictions(&tested, &mut preds, test) else {
        return Ok(None);
    };
    std::fs::create_dir_all(row_dir(out, NAIVE_ICP))?;
    let (all, objects, scenes) = score(&tested, &preds, test)?;
    write_results(
        &row_dir(out, NAIVE_ICP).join(RESULTS_FILE),
        Some(&prediction_estimates(&preds, tested.iter().copied())),
    )?;
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
        scoring: scoring_key(s),
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
pub fn naive_row(s: &Settings, out: &Path, test: &TestSet) -> Result<RowRecord> {
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
        scoring: scoring_key(s),
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
        median_te_cm: None,
        median_re_deg: None,
        ar: None,
        ar_vsd: None,
        ar_mssd: None,
        ar_mspd: None,
        add_s_auc: None,
        acc_add: None,
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
    // Rotation scores when the predictions have rotations (TNet's before its ICP has none).
    let Some(objs) = test
        .objects
        .as_ref()
        .filter(|_| preds.iter().any(|p| p.rotation.is_some()))
    else {
        return Ok((all, objects, scenes));
    };
    let mut scenes = scenes;
    let eval_objs = eval_objects(objs);
    let estimates = prediction_estimates(preds, tested.iter().copied());
    let rotations = Rotations::default();
    let report = evaluate(&test.gts, &estimates, &eval_objs, rotations)?;
    let auc = report.add_s_auc(&eval_objs, rotations);
    let bop = match &test.bop {
        Some(b) => Some(b.setup.evaluate(
            &estimates,
            Some(&b.renderer),
            &BopOptions::default(),
            &NoProgress,
        )?),
        None => None,
    };
    let fill = |m: &mut Metrics, s: &ObjectScores| {
        m.add_s_acc = Some(s.add_s_acc);
        m.acc_add = Some(s.add_s_acc);
        m.acc_5cm5deg = Some(s.acc_5cm5deg);
        m.mean_te_cm = s.mean_te_cm;
        m.mean_re_deg = s.mean_re_deg;
        m.median_te_cm = s.median_te_cm;
        m.median_re_deg = s.median_re_deg;
    };
    // BOP's AR and its parts for one key (an object or a scene; None: all).
    let fill_bop = |m: &mut Metrics, key: Option<(bool, u32)>| {
        let Some(b) = &bop else { return };
        let of = |e: &ErrorRecall| match key {
            None => Some(e.mean_recall),
            Some((true, id)) => e.per_object_mean_recall.get(&id).copied(),
            Some((false, id)) => e.per_scene_mean_recall.get(&id).copied(),
        };
        m.ar_mssd = of(&b.mssd);
        m.ar_mspd = of(&b.mspd);
        m.ar_vsd = b.vsd.as_ref().and_then(of);
        m.ar = match (m.ar_vsd, m.ar_mssd, m.ar_mspd) {
            (Some(v), Some(s), Some(p)) => Some((v + s + p) / 3.0),
            _ => None,
        };
    };
    fill(&mut all, &report.all);
    fill_bop(&mut all, None);
    all.add_s_auc = auc.all;
    for (id, sc) in &report.per_object {
        let m = objects
            .entry(id.to_string())
            .or_insert_with(|| centre_metrics(std::iter::empty()));
        fill(m, sc);
        fill_bop(m, Some((true, *id)));
        m.add_s_auc = auc.per_object.get(id).copied();
    }
    for (sc, r) in evaluate_per_scene(&test.gts, &estimates, &eval_objs, rotations)? {
        let m = scenes
            .entry(sc.to_string())
            .or_insert_with(|| centre_metrics(std::iter::empty()));
        fill(m, &r.all);
        fill_bop(m, Some((false, sc)));
        m.add_s_auc = auc.per_scene.get(&sc).copied();
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
    /// How it was scored ([`scoring_key`]).
    #[serde(default)]
    pub scoring: String,
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
    let preds = predict_members(&dir, &tested, test)?;
    let RowScores {
        estimates,
        all,
        objects,
        scenes: scenes_m,
        before_refine,
        ..
    } = score_row(&tested, preds, test)?;
    write_results(&dir.join(NO_GT_RESULTS_FILE), estimates.as_deref())?;
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
        scoring: scoring_key(s),
    };
    atomic_write(
        &dir.join(NO_GT_FILE),
        (serde_json::to_string_pretty(&record)? + "\n").as_bytes(),
    )?;
    Ok(record)
}
