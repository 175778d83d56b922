//! One row of the experiment: mix, train, evaluate; `row.json` written last marks it done.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use synthgen_core::NoProgress;
use synthgen_curate::mix::{
    write_mix, Completion, MixCounts, MixOptions, PROVENANCE_FILE, TEST_SPLIT, TRAIN_SPLIT,
};
use synthgen_formats::bop::BopDataset;
use synthgen_formats::io::atomic_write;
use synthgen_formats::source::FrameSource;
use synthgen_train::data::{load_instances, DataOptions, Instance};
use synthgen_train::eval::{read_gt, score_predictions, EvalReport, GtInstance};
use synthgen_train::metrics::Rotations;
use synthgen_train::models::tnet::DEFAULT_SCALE;
use synthgen_train::models::ModelKind;
use synthgen_train::pose_model::{load_dataset_objects, Objects, Prediction};
use synthgen_train::train::{
    self, centre_error_m, load_model, val_frames, EpochMetrics, Schedule, TrainConfig,
    TrainObserver, MODEL_FILE,
};

use super::{Settings, TEST_SPLIT_FILE};
use crate::settings::{read_row_file, row_dir, ROW_FILE};
use crate::Log;
use synthgen_core::Progress;

/// Instances below this visible fraction are neither trained on nor scored.
const MIN_VISIB_FRACT: f64 = 0.1;
/// Model points per object in the full model's loss.
const LOSS_POINTS: usize = 100;

/// Which row: its counts and its training seed.
#[derive(Debug, Clone, PartialEq)]
pub struct RowSpec {
    pub name: String,
    pub real: usize,
    pub synth: usize,
    /// K of a `--plus-synth` row.
    pub plus: Option<usize>,
    pub repeat: usize,
    pub train_seed: u64,
}

/// The rows × repeats of an experiment, in table order.
pub fn specs(s: &Settings) -> Vec<RowSpec> {
    let mut out = Vec::new();
    for row in s.row_defs() {
        let (real, synth) = (row.real, row.synth);
        for repeat in 0..s.repeats {
            let mut name = format!("r{real:05}_s{synth:05}");
            if let Some(k) = row.plus {
                name += &format!("_x{k}");
            }
            if s.repeats > 1 {
                name += &format!("_rep{repeat}");
            }
            out.push(RowSpec {
                name,
                real,
                synth,
                plus: row.plus,
                repeat,
                train_seed: s.seed.wrapping_add(repeat as u64),
            });
        }
    }
    out
}

/// Errors of a model on a set of instances.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Errors {
    /// Instances scored (GT instances for the ADD(-S) and 5cm5° accuracies of `full`).
    pub n: usize,
    /// Mean distance between the predicted and the GT object centre, cm.
    pub centre_error_cm: f64,
    /// Fraction with ADD(-S) below 10% of the diameter (full).
    pub add_s_acc: Option<f64>,
    /// Fraction within 5 cm and 5° (full).
    pub acc_5cm5deg: Option<f64>,
}

/// The test errors of one object, and how often the row trained on it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectErrors {
    pub obj_id: u32,
    /// Test instances scored (centre error).
    pub n: usize,
    /// Mean centre error over them, cm.
    pub centre_error_cm: f64,
    /// Full: the object's ADD(-S) and 5cm5° accuracy over its GT test instances.
    pub add_s_acc: Option<f64>,
    pub acc_5cm5deg: Option<f64>,
    /// Instances of the object loaded for training (validation frames included) from real
    /// and from synthetic frames; 0 real: the row never saw it in a real frame.
    pub n_train_real: usize,
    pub n_train_synth: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Seconds {
    pub mix: f64,
    pub load: f64,
    pub train: f64,
    pub eval: f64,
    pub total: f64,
}

/// `row.json`: the row's settings and results.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RowRecord {
    pub name: String,
    pub real: usize,
    pub synth: usize,
    /// K of a `--plus-synth` row (all the real training frames + K× as many synthetic).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plus_synth: Option<usize>,
    pub repeat: usize,
    pub train_seed: u64,
    pub mix_seed: u64,
    pub model: String,
    pub epochs: usize,
    /// FNV-1a (64 bit) of the sorted test frame list (source, split, scene, image).
    pub test_split_hash: String,
    pub test_frames: usize,
    /// Instances trained on and held out for validation (by frame, inside the training set).
    pub n_train: usize,
    pub n_val: usize,
    /// Errors on the instances trained on.
    pub train: Errors,
    /// Errors on the held-out real test frames.
    pub test: Errors,
    /// The test errors per object, by obj_id.
    #[serde(default)]
    pub test_per_object: Vec<ObjectErrors>,
    pub last_epoch: Option<EpochMetrics>,
    pub seconds: Seconds,
}

/// The finished row's record, if it has one that reads.
pub fn read_record(out: &Path, name: &str) -> Option<RowRecord> {
    read_row_file(out, name)
}

pub struct RowContext<'a> {
    pub settings: &'a Settings,
    pub out: &'a Path,
    pub real: &'a dyn FrameSource,
    pub synth: &'a dyn FrameSource,
    /// The experiment's reproducing command, recorded in each row's mix.
    pub command_line: &'a [String],
    pub printer: &'a Log<'a>,
}

/// Advances the experiment's bar by one per epoch; the label shows the row and its loss.
struct RowObserver<'a> {
    printer: &'a Log<'a>,
    name: &'a str,
    epoch: std::cell::Cell<(usize, usize)>,
}

impl TrainObserver for RowObserver<'_> {
    fn epoch_start(&self, epoch: usize, epochs: usize, _steps: usize) {
        self.epoch.set((epoch, epochs));
        self.printer
            .set_message(format!("{} epoch {epoch}/{epochs}", self.name));
    }

    fn step(&self, running_loss: f64) {
        let (e, n) = self.epoch.get();
        self.printer.set_message(format!(
            "{} epoch {e}/{n} loss {running_loss:.4}",
            self.name
        ));
    }

    fn epoch_end(&self, _m: &EpochMetrics) {
        self.printer.advance(1);
    }
}

/// Runs a row from scratch (anything an interrupted attempt left is removed first).
pub fn run(ctx: &RowContext, spec: &RowSpec) -> Result<RowRecord> {
    let t0 = Instant::now();
    let s = ctx.settings;
    let dir = row_dir(ctx.out, &spec.name);
    if dir.exists() {
        std::fs::remove_dir_all(&dir)
            .with_context(|| format!("cannot remove {}", dir.display()))?;
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;

    let mix_dir = dir.join("mix");
    let by_scenes = !s.test_scenes.is_empty();
    let opts = MixOptions {
        counts: MixCounts {
            real: spec.real,
            synth: spec.synth,
            // With test scenes the test split is all their frames.
            test: (!by_scenes).then_some(s.test_count),
        },
        seed: s.seed,
        command_line: ctx.command_line.to_vec(),
        force: false,
        exclude_shared: false,
        test_scenes: s.test_scenes.clone(),
    };
    // The sources are BOP datasets with scene_gt_info (sources.rs converts other layouts).
    let report = write_mix(
        ctx.real,
        ctx.synth,
        &mix_dir,
        &opts,
        Completion::default(),
        &NoProgress,
    )?;
    for w in &report.warnings {
        // Same warnings every row (cameras, models): show them once.
        if spec.name == specs(s)[0].name {
            ctx.printer.warning(w);
        }
    }
    let provenance = read_provenance(&mix_dir)?;
    let (hash, test_list) = test_split(&provenance);
    record_test_split(ctx.out, &hash, &test_list)?;
    let t_mix = t0.elapsed().as_secs_f64();

    let t1 = Instant::now();
    let model = match s.model.as_str() {
        "full" => ModelKind::Full,
        "rnet" => ModelKind::Rnet,
        _ => ModelKind::Tnet,
    };
    let crop_size = if model.needs_rgb() { 48 } else { 0 };
    let data_opts = |split: &str, seed: u64| DataOptions {
        n_points: s.points,
        min_visib_fract: MIN_VISIB_FRACT,
        seed,
        split: Some(split.to_string()),
        crop_size,
        ..DataOptions::default()
    };
    let set = load_instances(
        &mix_dir,
        &data_opts(TRAIN_SPLIT, spec.train_seed),
        &NoProgress,
    )
    .with_context(|| format!("cannot load the training frames of {}", mix_dir.display()))?;
    // The test points are sampled with the experiment's seed: the same for every row.
    let test_set = load_instances(&mix_dir, &data_opts(TEST_SPLIT, s.seed), &NoProgress)
        .with_context(|| format!("cannot load the test frames of {}", mix_dir.display()))?;
    if set.instances.is_empty() || test_set.instances.is_empty() {
        return Err(anyhow::anyhow!(
            "no usable instances in {} ({} training, {} test)",
            mix_dir.display(),
            set.instances.len(),
            test_set.instances.len()
        ));
    }
    let obj_ids: BTreeSet<u32> = set.obj_ids().union(&test_set.obj_ids()).copied().collect();
    let objects = if model == ModelKind::Tnet {
        None
    } else {
        let source = synthgen_formats::layout::open_source(&mix_dir)
            .with_context(|| format!("cannot open {}", mix_dir.display()))?;
        Some(load_dataset_objects(source.as_ref(), obj_ids, LOSS_POINTS)?)
    };
    let t_load = t1.elapsed().as_secs_f64();

    let t2 = Instant::now();
    let run_dir = dir.join("train");
    let cfg = TrainConfig {
        objects: Vec::new(),
        model,
        width: s.width,
        n_points: s.points,
        normalization_scale: DEFAULT_SCALE,
        epochs: s.epochs,
        batch: s.batch,
        lr: s.lr,
        weight_decay: 1e-4,
        schedule: Schedule::Cosine,
        seed: spec.train_seed,
        val_fraction: 0.1,
        min_visib_fract: MIN_VISIB_FRACT,
        data: mix_dir.clone(),
        split: set.split.clone(),
        crop_size,
        loss_points: LOSS_POINTS,
        init: Vec::new(),
        plain_add_loss: false,
        translation: None,
        classes: Vec::new(),
    };
    let observer = RowObserver {
        printer: ctx.printer,
        name: &spec.name,
        epoch: std::cell::Cell::new((0, s.epochs)),
    };
    let device = train::device(false)?;
    let outcome = train::train(
        &cfg,
        &set,
        objects.as_ref(),
        &run_dir,
        false,
        &device,
        &observer,
    )?;
    let t_train = t2.elapsed().as_secs_f64();

    let t3 = Instant::now();
    let net = load_model(&run_dir.join(MODEL_FILE), &cfg, &device)?;
    let val = val_frames(&set.instances, cfg.val_fraction, cfg.seed);
    let trained: Vec<&Instance> = set
        .instances
        .iter()
        .filter(|i| !val.contains(&i.frame()))
        .collect();
    let train_preds = net.predict(&trained, objects.as_ref(), 64)?;
    let train_gts: Vec<GtInstance> = trained.iter().map(|i| gt_of(i)).collect();
    let (train_err, _) = errors(&trained, &train_preds, objects.as_ref(), &train_gts)?;
    let tested: Vec<&Instance> = test_set.instances.iter().collect();
    let test_preds = net.predict(&tested, objects.as_ref(), 64)?;
    // Full: every GT test instance counts (one without enough valid pixels counts as wrong).
    let test_gts = read_gt(&BopDataset::open(&mix_dir)?, TEST_SPLIT, MIN_VISIB_FRACT)?;
    let (test_err, scores) = errors(&tested, &test_preds, objects.as_ref(), &test_gts)?;
    let trained_on = train_counts(&set.instances, &provenance);
    let test_per_object = per_object(&tested, &test_preds, scores.as_ref(), &trained_on);
    let t_eval = t3.elapsed().as_secs_f64();

    let record = RowRecord {
        name: spec.name.clone(),
        real: spec.real,
        synth: spec.synth,
        plus_synth: spec.plus,
        repeat: spec.repeat,
        train_seed: spec.train_seed,
        mix_seed: s.seed,
        model: s.model.clone(),
        epochs: s.epochs,
        test_split_hash: hash,
        test_frames: report.test,
        n_train: outcome.n_train,
        n_val: outcome.n_val,
        train: train_err,
        test: test_err,
        test_per_object,
        last_epoch: outcome.history.last().cloned(),
        seconds: Seconds {
            mix: t_mix,
            load: t_load,
            train: t_train,
            eval: t_eval,
            total: t0.elapsed().as_secs_f64(),
        },
    };
    let text = serde_json::to_string_pretty(&record)? + "\n";
    atomic_write(&dir.join(ROW_FILE), text.as_bytes())?;
    Ok(record)
}

fn gt_of(i: &Instance) -> GtInstance {
    GtInstance {
        scene_id: i.scene_id,
        im_id: i.im_id,
        gt_id: i.gt_id,
        obj_id: i.obj_id,
        pose: i.pose,
        // Training instances keep the nearest rotation only; it is what they were trained on.
        stored: i.pose,
        visib_fract: 1.0,
    }
}

/// Mean centre error of the predictions, cm (NaN for none).
fn mean_centre_cm<'a>(pairs: impl Iterator<Item = (&'a Prediction, &'a Instance)>) -> f64 {
    let centres: Vec<f64> = pairs
        .filter_map(|(p, i)| p.centre_m.map(|c| centre_error_m(c, i)))
        .collect();
    if centres.is_empty() {
        f64::NAN
    } else {
        100.0 * centres.iter().sum::<f64>() / centres.len() as f64
    }
}

/// Centre error over the instances; for rotation models also ADD(-S) and 5cm5° accuracy
/// over `gts`, scored as `synthgen eval` scores a checkpoint (the report is returned too).
fn errors(
    instances: &[&Instance],
    preds: &[Prediction],
    objects: Option<&Objects>,
    gts: &[GtInstance],
) -> Result<(Errors, Option<EvalReport>)> {
    let centre_error_cm = mean_centre_cm(preds.iter().zip(instances.iter().copied()));
    let Some(objects) = objects else {
        let e = Errors {
            n: instances.len(),
            centre_error_cm,
            add_s_acc: None,
            acc_5cm5deg: None,
        };
        return Ok((e, None));
    };
    let report = score_predictions(
        preds,
        instances.iter().copied(),
        gts,
        objects,
        Rotations::default(),
    )?;
    let e = Errors {
        n: report.all.n_gt,
        centre_error_cm,
        add_s_acc: Some(report.all.add_s_acc),
        acc_5cm5deg: Some(report.all.acc_5cm5deg),
    };
    Ok((e, Some(report)))
}

/// Training instances per object from (real, synthetic) frames; the mix's provenance says
/// which frame came from where.
fn train_counts(
    instances: &[Instance],
    provenance: &[serde_json::Value],
) -> BTreeMap<u32, (usize, usize)> {
    let real: HashMap<(u64, u64), bool> = provenance
        .iter()
        .filter(|e| e["split"] == TRAIN_SPLIT)
        .filter_map(|e| {
            let key = (e["scene_id"].as_u64()?, e["im_id"].as_u64()?);
            Some((key, e["origin"] == "real"))
        })
        .collect();
    let mut out: BTreeMap<u32, (usize, usize)> = BTreeMap::new();
    for i in instances {
        let c = out.entry(i.obj_id).or_default();
        match real.get(&(u64::from(i.scene_id), u64::from(i.im_id))) {
            Some(true) => c.0 += 1,
            _ => c.1 += 1,
        }
    }
    out
}

/// The test errors of each object (sorted by id).
fn per_object(
    tested: &[&Instance],
    preds: &[Prediction],
    report: Option<&EvalReport>,
    trained_on: &BTreeMap<u32, (usize, usize)>,
) -> Vec<ObjectErrors> {
    let ids: BTreeSet<u32> = tested.iter().map(|i| i.obj_id).collect();
    ids.into_iter()
        .map(|id| {
            let pairs = preds
                .iter()
                .zip(tested.iter().copied())
                .filter(|(_, i)| i.obj_id == id);
            let scores = report.and_then(|r| r.per_object.get(&id));
            let (n_train_real, n_train_synth) = trained_on.get(&id).copied().unwrap_or_default();
            ObjectErrors {
                obj_id: id,
                n: tested.iter().filter(|i| i.obj_id == id).count(),
                centre_error_cm: mean_centre_cm(pairs),
                add_s_acc: scores.map(|s| s.add_s_acc),
                acc_5cm5deg: scores.map(|s| s.acc_5cm5deg),
                n_train_real,
                n_train_synth,
            }
        })
        .collect()
}

/// The entries of the mix's `provenance.json`.
fn read_provenance(mix_dir: &Path) -> Result<Vec<serde_json::Value>> {
    let path = mix_dir.join(PROVENANCE_FILE);
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("malformed {}", path.display()))
}

/// The mix's test frames as sorted "source|split|scene|image" lines, and their hash.
fn test_split(entries: &[serde_json::Value]) -> (String, Vec<String>) {
    let mut lines: Vec<String> = entries
        .iter()
        .filter(|e| e["split"] == TEST_SPLIT)
        .map(|e| {
            format!(
                "{}|{}|{}|{}",
                e["source"].as_str().unwrap_or(""),
                e["source_split"].as_str().unwrap_or(""),
                e["source_scene_id"],
                e["source_im_id"]
            )
        })
        .collect();
    lines.sort();
    (
        format!(
            "{:016x}",
            synthgen_formats::fingerprint::fnv1a(lines.join("\n").as_bytes())
        ),
        lines,
    )
}

/// Writes the test frame list on the first row; later rows must match it.
fn record_test_split(out: &Path, hash: &str, lines: &[String]) -> Result<()> {
    let path = out.join(TEST_SPLIT_FILE);
    let value = serde_json::json!({ "hash": hash, "frames": lines });
    if let Ok(text) = std::fs::read_to_string(&path) {
        let old: serde_json::Value =
            serde_json::from_str(&text).with_context(|| format!("malformed {}", path.display()))?;
        if old["hash"] != hash {
            return Err(anyhow::anyhow!(
                "internal: this row's test split ({hash}) differs from the experiment's ({}) in {}",
                old["hash"],
                path.display()
            ));
        }
        return Ok(());
    }
    let text = serde_json::to_string_pretty(&value)? + "\n";
    atomic_write(&path, text.as_bytes())?;
    Ok(())
}
