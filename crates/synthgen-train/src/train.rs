//! The training loop: AdamW with a learning-rate schedule, a train/val split by frame,
//! per-epoch metrics as JSON lines, safetensors checkpoints, resume, and the curve PNG.

use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use candle_core::Device;
use candle_nn::{Optimizer, ParamsAdamW};

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use synthgen_core::rng::splitmix64;
use synthgen_core::Progress;
use synthgen_nn::optim::FusedAdamW;

use crate::data::{DataOptions, Instance, InstanceSet};
use crate::error::{Error, Result};
use crate::metrics::is_5cm5deg;
pub use crate::metrics::EpochMetrics;
use crate::models::rgb::Translation;
use crate::models::ModelKind;
use crate::pose_model::{Objects, PoseModel, Prediction};
use rayon::prelude::*;

pub const MODEL_FILE: &str = "model.safetensors";
pub const CONFIG_FILE: &str = "config.json";
pub const STATE_FILE: &str = "state.json";
pub const METRICS_FILE: &str = "metrics.jsonl";
pub const CURVE_FILE: &str = "curve.png";

/// Learning-rate schedule over the whole run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Schedule {
    /// Cosine from `lr` down to `lr / 100`, per step.
    Cosine,
    /// `lr`, then `lr / 10` from 2/3 of the epochs on.
    Step,
    Constant,
}

impl Schedule {
    /// The learning rate at `step` of `total_steps` (in `epoch`, 0-based, of `epochs`) for a
    /// run whose rate is `lr`.
    pub fn lr_at(
        self,
        lr: f64,
        epochs: usize,
        step: usize,
        total_steps: usize,
        epoch: usize,
    ) -> f64 {
        match self {
            Schedule::Constant => lr,
            Schedule::Step => {
                if 3 * epoch >= 2 * epochs {
                    lr / 10.0
                } else {
                    lr
                }
            }
            Schedule::Cosine => {
                let t = step as f64 / total_steps.max(1) as f64;
                let min = lr / 100.0;
                min + (lr - min) * 0.5 * (1.0 + (std::f64::consts::PI * t).cos())
            }
        }
    }
}

/// Everything that defines a run; written to `config.json` beside the checkpoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    pub model: ModelKind,
    pub width: usize,
    pub n_points: usize,
    /// Points are centred on their mean and multiplied by this (1/m).
    pub normalization_scale: f32,
    pub epochs: usize,
    pub batch: usize,
    pub lr: f64,
    pub weight_decay: f64,
    pub schedule: Schedule,
    pub seed: u64,
    /// Fraction of frames held out for validation.
    pub val_fraction: f64,
    pub min_visib_fract: f64,
    pub data: PathBuf,
    pub split: String,
    /// Side of the RGB crop (RNet, Full; 0 for TNet).
    #[serde(default)]
    pub crop_size: u32,
    /// Model points per object in Full's ADD loss.
    #[serde(default = "default_loss_points")]
    pub loss_points: usize,
    /// Checkpoints the run was initialized from (`--init`), in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub init: Vec<PathBuf>,
    /// Full: the plain ADD loss (identity only) even for symmetric objects, instead of the
    /// minimum over their symmetries (`--no-symmetric-loss`, for ablations).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub plain_add_loss: bool,
    /// The RGB model's translation parametrization (`--translation`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation: Option<Translation>,
    /// The RGB model's object classes (ids, sorted), one head each: the training set's
    /// objects. For TNet (`--per-object`): the classes it is conditioned on (empty: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub classes: Vec<u32>,
    /// What the training data's objects are (model name, diameter, extents), so that a
    /// checkpoint scored on a dataset whose ids are other objects is refused (empty in
    /// configs written before, and where the trainer was not given the dataset).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub objects: Vec<synthgen_formats::identity::ObjectIdentity>,
}

fn default_loss_points() -> usize {
    100
}

/// The largest sizes a training run may ask for (far above anything useful on a CPU).
pub struct Limits {
    pub epochs: usize,
    pub batch: usize,
    pub width: usize,
    pub points: usize,
    pub crop_size: usize,
}

pub const LIMITS: Limits = Limits {
    epochs: 10_000,
    batch: 4096,
    width: 4096,
    points: 100_000,
    crop_size: 1024,
};

impl TrainConfig {
    /// Checks the hyper-parameters: what AdamW and the data pipeline can work with.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::InvalidOption(m));
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return bad(format!("--lr must be a positive number, got {}", self.lr));
        }
        if !(self.weight_decay.is_finite() && self.weight_decay >= 0.0) {
            return bad(format!(
                "--weight-decay must be a number >= 0, got {}",
                self.weight_decay
            ));
        }
        if !(0.0..1.0).contains(&self.val_fraction) {
            return bad(format!(
                "--val-fraction must lie in 0..1, got {}",
                self.val_fraction
            ));
        }
        if !(0.0..=1.0).contains(&self.min_visib_fract) {
            return bad(format!(
                "--min-visib-fract must lie in 0..1, got {}",
                self.min_visib_fract
            ));
        }
        let points_ok = self.n_points > 0 || !self.model.needs_depth();
        if self.batch == 0 || self.epochs == 0 || self.width == 0 || !points_ok {
            return bad("--batch, --epochs, --width and --points must be positive".into());
        }
        // Sizes that only a typo reaches: refused with their limit instead of an allocation
        // abort (a width of 100000 asks for 10^10 weights).
        for (flag, v, max) in [
            ("--epochs", self.epochs, LIMITS.epochs),
            ("--batch", self.batch, LIMITS.batch),
            ("--width", self.width, LIMITS.width),
            ("--points", self.n_points, LIMITS.points),
            ("--loss-points", self.loss_points, LIMITS.points),
            ("--crop-size", self.crop_size as usize, LIMITS.crop_size),
        ] {
            if v > max {
                return bad(format!("{flag} {v} is over its limit of {max}"));
            }
        }
        if self.model == ModelKind::Rgb && self.crop_size < 16 {
            return bad(format!(
                "--crop-size {} is too small for the rgb model (at least 16)",
                self.crop_size
            ));
        }
        if self.model == ModelKind::RgbDense
            && (self.crop_size < 16 || !self.crop_size.is_multiple_of(8))
        {
            return bad(format!(
                "--crop-size {} does not suit the rgb-dense model (a multiple of 8, at least 16)",
                self.crop_size
            ));
        }
        if !(self.normalization_scale.is_finite() && self.normalization_scale > 0.0) {
            return bad(format!(
                "the normalization scale must be positive, got {}",
                self.normalization_scale
            ));
        }
        Ok(())
    }

    /// How the run's model loads a dataset's instances (points and RNet crops, or the RGB
    /// model's box regions without depth), with its seed, split and visibility threshold.
    pub fn data_options(&self) -> DataOptions {
        let rgb = self.model.is_rgb_only();
        DataOptions {
            n_points: self.n_points,
            min_visib_fract: self.min_visib_fract,
            seed: self.seed,
            split: (!self.split.is_empty()).then(|| self.split.clone()),
            crop_size: if rgb { 0 } else { self.crop_size },
            rgb_box: if rgb { self.crop_size } else { 0 },
            dense_targets: self.model == ModelKind::RgbDense,
            depth_points: self.model.needs_depth(),
            ..DataOptions::default()
        }
    }

    pub fn lr_at(&self, step: usize, total_steps: usize, epoch: usize) -> f64 {
        self.schedule
            .lr_at(self.lr, self.epochs, step, total_steps, epoch)
    }
}

/// `state.json`: where a run stands, for `--resume`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainState {
    pub epochs_done: usize,
    pub steps_done: usize,
}

/// Callbacks for progress display; all optional.
pub trait TrainObserver {
    fn epoch_start(&self, _epoch: usize, _epochs: usize, _steps: usize) {}
    /// After each step, with the epoch's running mean loss.
    fn step(&self, _running_loss: f64) {}
    fn epoch_end(&self, _m: &EpochMetrics) {}
    /// `--init`: `set` of the model's `total` variables came from `checkpoint`.
    fn initialized(&self, _checkpoint: &Path, _set: usize, _total: usize) {}
}

/// A [`TrainObserver`] that shows each epoch on a [`Progress`]: a bar per epoch labelled with
/// the running loss, and a line per finished epoch (what `synthgen train` prints).
pub struct ProgressObserver<'a> {
    pub printer: &'a dyn Progress,
    /// (epoch, epochs) of the running epoch.
    pub epoch: std::cell::Cell<(usize, usize)>,
}

impl TrainObserver for ProgressObserver<'_> {
    fn epoch_start(&self, epoch: usize, epochs: usize, steps: usize) {
        self.epoch.set((epoch, epochs));
        self.printer
            .start(&format!("epoch {epoch}/{epochs}"), steps as u64);
    }

    fn step(&self, running_loss: f64) {
        let (e, n) = self.epoch.get();
        self.printer
            .set_message(&format!("epoch {e}/{n} loss {running_loss:.4}"));
        self.printer.advance(1);
    }

    fn epoch_end(&self, m: &EpochMetrics) {
        self.printer.finish();
        self.printer.info(&format!(
            "epoch {:>3}: train loss {:.4}, val loss {:.4}{}, lr {:.2e}, {:.1} s",
            m.epoch,
            m.train_loss,
            m.val_loss,
            val_summary(m),
            m.lr,
            m.seconds
        ));
    }

    fn initialized(&self, checkpoint: &Path, set: usize, total: usize) {
        self.printer.info(&format!(
            "initialized {set} of {total} variables from {}",
            checkpoint.display()
        ));
    }
}

/// ", val centre error 0.24 cm, val ADD(-S) acc 93.0%, val E_re 3.1°" (what the run has).
pub fn val_summary(m: &EpochMetrics) -> String {
    let mut s = String::new();
    if let Some(e) = m.val_centre_error_m {
        s += &format!(", val centre error {:.2} cm", e * 100.0);
    }
    if let Some(a) = m.val_add_s_acc {
        s += &format!(", val ADD(-S) acc {:.1}%", a * 100.0);
    }
    if let Some(r) = m.val_mean_re_deg {
        s += &format!(", val E_re {r:.1}°");
    }
    if let Some(a) = m.val_acc_5cm5deg {
        s += &format!(", val 5cm5° {:.1}%", a * 100.0);
    }
    s
}

pub struct NoObserver;
impl TrainObserver for NoObserver {}

/// Frames held out for validation: a seeded shuffle of the sorted frame list, the first
/// `ceil(val_fraction × frames)` of it (at least one frame when there are two or more).
pub fn val_frames(instances: &[Instance], val_fraction: f64, seed: u64) -> BTreeSet<(u32, u32)> {
    let mut frames: Vec<(u32, u32)> = instances
        .iter()
        .map(Instance::frame)
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(splitmix64(seed ^ 0x5eed_5b17));
    frames.shuffle(&mut rng);
    let mut n = (val_fraction * frames.len() as f64).ceil() as usize;
    if frames.len() >= 2 {
        n = n.clamp(1, frames.len() - 1);
    } else {
        n = 0;
    }
    frames.into_iter().take(n).collect()
}

/// The device: CPU, or the first CUDA GPU (needs the `cuda` feature).
pub fn device(cuda: bool) -> Result<Device> {
    if cuda {
        Ok(Device::new_cuda(0)?)
    } else {
        Ok(Device::Cpu)
    }
}

/// A fresh model for `cfg`.
pub fn new_model(cfg: &TrainConfig, device: &Device) -> Result<PoseModel> {
    if cfg.model == ModelKind::Rgb {
        return PoseModel::rgb(
            cfg.translation.unwrap_or(Translation::CentreTz),
            &cfg.classes,
            cfg.width,
            cfg.crop_size,
            cfg.seed,
            device,
        );
    }
    if cfg.model == ModelKind::RgbDense {
        return PoseModel::rgb_dense(&cfg.classes, cfg.width, cfg.crop_size, cfg.seed, device);
    }
    if cfg.model == ModelKind::Tnet && !cfg.classes.is_empty() {
        return PoseModel::tnet_per_object(
            cfg.width,
            cfg.normalization_scale,
            &cfg.classes,
            cfg.seed,
            device,
        );
    }
    PoseModel::new(
        cfg.model,
        cfg.width,
        cfg.normalization_scale,
        cfg.crop_size,
        cfg.seed,
        device,
    )
}

/// The model of `cfg` with the weights of `checkpoint`.
pub fn load_model(checkpoint: &Path, cfg: &TrainConfig, device: &Device) -> Result<PoseModel> {
    let mut m = new_model(cfg, device)?;
    m.load_strict(checkpoint)?;
    Ok(m)
}

pub fn centre_error_m(pred: [f32; 3], inst: &Instance) -> f64 {
    let t = inst.pose.translation_m;
    let d = [
        f64::from(pred[0]) - t.x,
        f64::from(pred[1]) - t.y,
        f64::from(pred[2]) - t.z,
    ];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// Runs `step(k, item k)` for k in 0..n in order while `prepare(k + 1)` runs on another
/// thread: a training step's data (crops, augmentation, targets) made ready during the step
/// before. The items and their order are those of a plain loop; only the timing overlaps.
/// The first error (from either side) stops the loop.
pub fn pipelined<P: Send>(
    n: usize,
    prepare: impl Fn(usize) -> Result<P> + Sync,
    mut step: impl FnMut(usize, P) -> Result<()>,
) -> Result<()> {
    let prepare = &prepare;
    std::thread::scope(|scope| {
        let mut next = (n > 0).then(|| scope.spawn(move || prepare(0)));
        for k in 0..n {
            let Some(handle) = next.take() else { break };
            let item = handle.join().map_err(|_| {
                Error::InvalidOption("internal: a batch preparation panicked".into())
            })??;
            if k + 1 < n {
                next = Some(scope.spawn(move || prepare(k + 1)));
            }
            step(k, item)?;
        }
        Ok(())
    })
}

/// `bytes` written to `path` atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    synthgen_core::atomic::write_atomic(path, bytes, false)
        .map_err(|(_, e)| Error::io("write", path, e))
}

/// `path` read as JSON (`what` names it in the error).
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path, what: &'static str) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io("read", path, e))?;
    serde_json::from_str(&text).map_err(|e| Error::Malformed {
        what,
        message: e.to_string(),
        path: path.to_path_buf(),
    })
}

/// A pose model's `config.json`; a detector's is refused by name (not as serde's "unknown
/// variant").
/// The checkpoint a path names: a run folder's `model.safetensors`, or the file itself
/// (`config.json` beside it either way).
pub fn checkpoint_in(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.join(MODEL_FILE)
    } else {
        path.to_path_buf()
    }
}

pub fn read_config(path: &Path) -> Result<TrainConfig> {
    read_run_config(path, RunKind::Pose)
}

/// What a run folder holds: a pose model (`synthgen train`) or a detector (`synthgen detector
/// train`); its `config.json` says which in `"model"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunKind {
    Pose,
    Detector,
}

impl RunKind {
    /// The kind `config.json`'s `"model"` names ("detector", else a pose model).
    pub fn of_model(model: &str) -> RunKind {
        if model == "detector" {
            RunKind::Detector
        } else {
            RunKind::Pose
        }
    }

    fn describe(self) -> &'static str {
        match self {
            RunKind::Pose => "a pose model's run (synthgen train)",
            RunKind::Detector => "a detector's run (synthgen detector train)",
        }
    }
}

/// The `config.json` at `path` read as `T`, the config of a `want` run: one of the other kind
/// is an error that says what the folder holds and what takes it.
pub fn read_run_config<T: serde::de::DeserializeOwned>(path: &Path, want: RunKind) -> Result<T> {
    let value: serde_json::Value = read_json(path, "config.json")?;
    let model = value.get("model").and_then(|m| m.as_str()).unwrap_or("");
    let found = RunKind::of_model(model);
    if found != want {
        return Err(Error::Malformed {
            what: "config.json",
            message: format!(
                "this folder holds {} (model \"{model}\"), and {} is needed here{}",
                found.describe(),
                want.describe(),
                match found {
                    RunKind::Detector =>
                        "; a detector's run feeds `synthgen detector run --checkpoint`",
                    RunKind::Pose => "; a pose model's run feeds `synthgen eval --checkpoint`",
                }
            ),
            path: path.to_path_buf(),
        });
    }
    serde_json::from_value(value).map_err(|e| Error::Malformed {
        what: "config.json",
        message: e.to_string(),
        path: path.to_path_buf(),
    })
}

/// The metrics lines of a run folder, at most `keep` of them.
pub fn read_metrics(out: &Path, keep: usize) -> Result<Vec<EpochMetrics>> {
    let path = out.join(METRICS_FILE);
    if !path.exists() {
        return Ok(Vec::new());
    }
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io("read", &path, e))?;
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .take(keep)
        .map(|l| {
            serde_json::from_str(l).map_err(|e| Error::Malformed {
                what: "metrics.jsonl",
                message: e.to_string(),
                path: path.clone(),
            })
        })
        .collect()
}

/// What a finished (or resumed and finished) run reports.
#[derive(Debug, Clone)]
pub struct TrainOutcome {
    pub history: Vec<EpochMetrics>,
    pub n_train: usize,
    pub n_val: usize,
    pub resumed_from_epoch: usize,
}

/// Trains `cfg.model` on `data`, writing into `out`. With `resume`, continues from the
/// checkpoint in `out` (weights and epoch count; AdamW's moments restart from zero).
/// `objects` (models, symmetries) are needed by Full's loss and by the rotation metrics of
/// RNet and Full; `cfg.init` checkpoints initialize a fresh run's matching variables.
pub fn train(
    cfg: &TrainConfig,
    data: &InstanceSet,
    objects: Option<&Objects>,
    out: &Path,
    resume: bool,
    device: &Device,
    observer: &dyn TrainObserver,
) -> Result<TrainOutcome> {
    if cfg.model != ModelKind::Tnet && objects.is_none() {
        return Err(Error::InvalidOption(format!(
            "model {} needs the objects' models (models_info.json and the model files)",
            cfg.model.name()
        )));
    }
    cfg.validate()?;
    if cfg.model.is_rgb_only() {
        if let Some(id) = data
            .obj_ids()
            .into_iter()
            .find(|id| !cfg.classes.contains(id))
        {
            return Err(Error::InvalidOption(format!(
                "object {id} of the training data is not one of the {} model's classes {:?}",
                cfg.model.name(),
                cfg.classes
            )));
        }
    }
    let plain: Option<Objects>;
    let objects = if cfg.plain_add_loss {
        // Symmetry transforms start with the identity: keep only it.
        plain = objects.map(|o| {
            o.iter()
                .map(|(&id, t)| {
                    let mut t = t.clone();
                    t.symmetries.truncate(1);
                    (id, t)
                })
                .collect()
        });
        plain.as_ref()
    } else {
        objects
    };
    std::fs::create_dir_all(out).map_err(|e| Error::io("create directory", out, e))?;
    let val = val_frames(&data.instances, cfg.val_fraction, cfg.seed);
    let (val_set, train_set): (Vec<&Instance>, Vec<&Instance>) = data
        .instances
        .iter()
        .partition(|i| val.contains(&i.frame()));
    if train_set.is_empty() || val_set.is_empty() {
        let frames: BTreeSet<(u32, u32)> = data.instances.iter().map(Instance::frame).collect();
        return Err(Error::NoInstances {
            reason: format!(
                "{} frame{} with usable instances: training holds whole frames out for validation, so it needs at least 2 (render or select more frames, or lower --min-visib-fract)",
                frames.len(),
                if frames.len() == 1 { "" } else { "s" }
            ),
            path: cfg.data.clone(),
        });
    }

    let model_path = out.join(MODEL_FILE);
    let (model, state, mut history) = if resume {
        let state: TrainState = read_json(&out.join(STATE_FILE), "state.json")?;
        let model = load_model(&model_path, cfg, device)?;
        let history = read_metrics(out, state.epochs_done)?;
        (model, state, history)
    } else {
        let mut model = new_model(cfg, device)?;
        for ckpt in &cfg.init {
            let n = model.init_from(ckpt)?;
            observer.initialized(ckpt, n, model.varmap.all_vars().len());
        }
        let state = TrainState {
            epochs_done: 0,
            steps_done: 0,
        };
        (model, state, Vec::new())
    };
    let config_json =
        serde_json::to_vec_pretty(cfg).map_err(|e| Error::InvalidOption(e.to_string()))?;
    write_atomic(&out.join(CONFIG_FILE), &config_json)?;
    // metrics.jsonl holds exactly the finished epochs.
    let mut lines = String::new();
    for m in &history {
        lines += &serde_json::to_string(m).map_err(|e| Error::InvalidOption(e.to_string()))?;
        lines.push('\n');
    }
    write_atomic(&out.join(METRICS_FILE), lines.as_bytes())?;

    let mut opt = FusedAdamW::new(
        model.varmap.all_vars(),
        ParamsAdamW {
            lr: cfg.lr,
            weight_decay: cfg.weight_decay,
            ..Default::default()
        },
    )?;
    let steps_per_epoch = train_set.len().div_ceil(cfg.batch);
    let total_steps = steps_per_epoch * cfg.epochs;
    let mut step = state.steps_done;
    let resumed_from_epoch = state.epochs_done;
    for epoch in state.epochs_done..cfg.epochs {
        let started = Instant::now();
        observer.epoch_start(epoch + 1, cfg.epochs, steps_per_epoch);
        let mut order = train_set.clone();
        let mut rng = ChaCha8Rng::seed_from_u64(splitmix64(cfg.seed ^ (epoch as u64 + 1)));
        order.shuffle(&mut rng);
        let (mut sum, mut count) = (0.0f64, 0usize);
        let mut lr = cfg.lr;
        let batches: Vec<&[&Instance]> = order.chunks(cfg.batch).collect();
        let first_step = step;
        // The next batch is prepared (crops cut and jittered, targets built) while the network
        // runs on this one; each batch's jitter is its step's, as without the overlap.
        let prepare = |k: usize| {
            let jitter =
                splitmix64(cfg.seed ^ 0x6a17_7e25 ^ ((first_step + k) as u64).wrapping_mul(0x9e37));
            model.prepare(batches[k], objects, Some(jitter))
        };
        pipelined(batches.len(), prepare, |k, prepared| {
            lr = cfg.lr_at(step, total_steps, epoch);
            opt.set_learning_rate(lr);
            let loss = model.loss_of(&prepared)?;
            // A non-finite loss would poison the weights: stop, keeping the last epoch's
            // checkpoint (written only after a finite validation).
            let value = f64::from(loss.to_scalar::<f32>()?);
            if !value.is_finite() {
                return Err(diverged(out, value, epoch + 1, step + 1, epoch));
            }
            opt.backward_step(&loss)?;
            sum += value * batches[k].len() as f64;
            count += batches[k].len();
            step += 1;
            observer.step(sum / count as f64);
            Ok(())
        })?;
        let v = validate(&model, &val_set, objects, cfg.batch)?;
        if !v.loss.is_finite() {
            return Err(diverged(out, v.loss, epoch + 1, step, epoch));
        }
        let m = EpochMetrics {
            epoch: epoch + 1,
            train_loss: sum / count.max(1) as f64,
            val_loss: v.loss,
            val_centre_error_m: v.centre_error_m,
            val_add_s_acc: v.add_s_acc,
            val_mean_re_deg: v.mean_re_deg,
            val_acc_5cm5deg: v.acc_5cm5deg,
            lr,
            seconds: started.elapsed().as_secs_f64(),
        };
        save_checkpoint(&model.varmap, out, epoch + 1, step)?;
        let path = out.join(METRICS_FILE);
        let mut f = std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .map_err(|e| Error::io("open", &path, e))?;
        let line = serde_json::to_string(&m).map_err(|e| Error::InvalidOption(e.to_string()))?;
        writeln!(f, "{line}").map_err(|e| Error::io("write", &path, e))?;
        observer.epoch_end(&m);
        history.push(m);
        // After every epoch, so that a run stopped early still has its curve.
        crate::plot::write_curve(&out.join(CURVE_FILE), &history)?;
    }
    if history.is_empty() {
        crate::plot::write_curve(&out.join(CURVE_FILE), &history)?;
    }
    Ok(TrainOutcome {
        history,
        n_train: train_set.len(),
        n_val: val_set.len(),
        resumed_from_epoch,
    })
}

/// Validation numbers of one pass over a set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Validation {
    pub loss: f64,
    pub centre_error_m: Option<f64>,
    pub add_s_acc: Option<f64>,
    pub mean_re_deg: Option<f64>,
    pub acc_5cm5deg: Option<f64>,
}

/// Mean loss, mean centre error (metres; TNet, Full; RGB's translation error), ADD(-S)
/// accuracy and mean rotation error (RNet with the GT translation, Full, RGB) and 5cm5°
/// accuracy (RGB) over `set`; NaN when it is empty.
pub fn validate(
    model: &PoseModel,
    set: &[&Instance],
    objects: Option<&Objects>,
    batch: usize,
) -> Result<Validation> {
    let mut loss_sum = 0.0;
    let mut preds: Vec<Prediction> = Vec::with_capacity(set.len());
    for chunk in set.chunks(batch.max(1)) {
        let (loss, p) = model.run(chunk, objects, true)?;
        loss_sum += f64::from(loss.to_scalar::<f32>()?) * chunk.len() as f64;
        preds.extend(p);
    }
    let n = set.len() as f64;
    let centre_error_m = (model.kind != ModelKind::Rnet).then(|| {
        preds
            .iter()
            .zip(set)
            .filter_map(|(p, i)| p.centre_m.map(|c| centre_error_m(c, i)))
            .sum::<f64>()
            / n
    });
    let (mut add_s_acc, mut mean_re_deg, mut acc_5cm5deg) = (None, None, None);
    if let (ModelKind::Rnet | ModelKind::Full | ModelKind::Rgb | ModelKind::RgbDense, Some(objs)) =
        (model.kind, objects)
    {
        let scored: Vec<(bool, f64, bool)> = preds
            .par_iter()
            .zip(set)
            .filter_map(|(p, i)| {
                let obj = &objs.get(&i.obj_id)?.eval;
                let est = p.pose(i.pose.translation_m);
                let e = obj.scoring_errors(&i.pose, &est);
                Some((obj.add_s_correct(&e), e.re_deg, is_5cm5deg(&i.pose, &est)))
            })
            .collect();
        add_s_acc = Some(scored.iter().filter(|s| s.0).count() as f64 / n);
        mean_re_deg = Some(scored.iter().map(|s| s.1).sum::<f64>() / n);
        if model.kind.is_rgb_only() {
            acc_5cm5deg = Some(scored.iter().filter(|s| s.2).count() as f64 / n);
        }
    }
    Ok(Validation {
        loss: loss_sum / n,
        centre_error_m,
        add_s_acc,
        mean_re_deg,
        acc_5cm5deg,
    })
}

/// The error of a run whose loss stopped being a number at `epoch` (1-based), `step`;
/// `kept` epochs are in the checkpoint on disk.
fn diverged(out: &Path, value: f64, epoch: usize, step: usize, kept: usize) -> Error {
    let kept = if kept == 0 {
        "no checkpoint was written".to_string()
    } else {
        format!("the checkpoint after epoch {kept}, the last finite one, is kept")
    };
    Error::Diverged {
        value,
        epoch,
        step,
        kept,
        path: out.to_path_buf(),
    }
}

/// `varmap` as `out`/model.safetensors (through a temporary file), then `out`/state.json.
pub fn save_checkpoint(
    varmap: &candle_nn::VarMap,
    out: &Path,
    epochs_done: usize,
    steps_done: usize,
) -> Result<()> {
    let path = out.join(MODEL_FILE);
    let tmp = synthgen_core::atomic::temp_path(&path);
    varmap.save(&tmp).map_err(|e| Error::Malformed {
        what: "checkpoint",
        message: e.to_string(),
        path: tmp.clone(),
    })?;
    std::fs::rename(&tmp, &path).map_err(|e| Error::io("rename", &path, e))?;
    let state = serde_json::to_vec_pretty(&TrainState {
        epochs_done,
        steps_done,
    })
    .map_err(|e| Error::InvalidOption(e.to_string()))?;
    write_atomic(&out.join(STATE_FILE), &state)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use synthgen_core::glam::{DMat3, DVec3};
    use synthgen_core::Pose;

    fn inst(im_id: u32) -> Instance {
        Instance {
            scene_id: 0,
            im_id,
            gt_id: 0,
            obj_id: 1,
            points_m: vec![],
            crop_xy: vec![],
            crop_rgb: vec![],
            region: None,
            pose: Pose::new(DMat3::IDENTITY, DVec3::ZERO),
        }
    }

    #[test]
    fn val_split_is_by_frame_and_seeded() {
        let insts: Vec<Instance> = (0..40).flat_map(|i| [inst(i), inst(i)]).collect();
        let a = val_frames(&insts, 0.1, 3);
        assert_eq!(a.len(), 4);
        assert_eq!(a, val_frames(&insts, 0.1, 3));
        assert_ne!(a, val_frames(&insts, 0.1, 4));
    }

    #[test]
    fn cosine_schedule_ends_at_a_hundredth() {
        let cfg = TrainConfig {
            objects: Vec::new(),
            model: ModelKind::Tnet,
            width: 8,
            n_points: 4,
            normalization_scale: 10.0,
            epochs: 10,
            batch: 2,
            lr: 1e-3,
            weight_decay: 0.0,
            schedule: Schedule::Cosine,
            seed: 0,
            val_fraction: 0.1,
            min_visib_fract: 0.1,
            data: PathBuf::new(),
            split: String::new(),
            crop_size: 0,
            loss_points: 100,
            init: Vec::new(),
            plain_add_loss: false,
            translation: None,
            classes: Vec::new(),
        };
        assert!((cfg.lr_at(0, 100, 0) - 1e-3).abs() < 1e-12);
        assert!((cfg.lr_at(100, 100, 9) - 1e-5).abs() < 1e-12);
        assert!(cfg.lr_at(50, 100, 5) < 1e-3);
    }
}
