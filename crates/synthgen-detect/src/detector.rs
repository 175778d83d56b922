//! Training and running the box detector ([`crate::models::detector`]): from a dataset's
//! frames and visible boxes (`scene_gt_info`'s `bbox_visib`, else the visible masks' bounding
//! boxes) to a checkpoint, and from a checkpoint to [`Detection`]s of every frame.
//!
//! Each frame is read once and kept at twice the network's input size. A training sample is
//! a window of it (the whole frame zoomed by 1 to `zoom_max`, at a random place), resampled
//! to the input size, with the dense RGB model's photometric augmentation (colour jitter,
//! blur, noise); frames are split into training and validation as the pose models' are
//! (by frame, seeded). Validation: the loss, and the recall of the visible boxes at IoU 0.5
//! when each object's best detections are taken as many as it has instances (BOP's
//! localization setting).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use candle_core::{Device, Tensor};
use candle_nn::{Optimizer, ParamsAdamW, VarMap};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use synthgen_core::rng::splitmix64;
use synthgen_core::Progress;
use synthgen_formats::bop::read_rgb_sized;
use synthgen_formats::coco::Rle;
use synthgen_formats::identity::{frames_key, FramesKey, ObjectIdentity};
use synthgen_formats::source::{FrameSource, SourceFrame};
use synthgen_nn::optim::FusedAdamW;

use synthgen_train::train::{
    pipelined, read_json, read_run_config, save_checkpoint, write_atomic, RunKind, Schedule,
    TrainState, CONFIG_FILE, METRICS_FILE, MODEL_FILE, STATE_FILE,
};
use synthgen_train::{Error, Result};

use crate::detections::Detection;
use crate::net::{detector_loss, DetOut, DetectorNet, DET_STRIDE};

/// The largest side of the network's input (`--input`), pixels.
pub const MAX_INPUT_SIDE: u32 = 2048;
/// The most epochs and frames per step a run may ask for.
pub const MAX_EPOCHS: usize = 10_000;
pub const MAX_BATCH: usize = 1024;

/// Everything that defines a detector run; `config.json` beside the checkpoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DetectorConfig {
    /// Always "detector": tells this config from a pose model's.
    pub model: String,
    /// The object ids, one heatmap each, in this order.
    pub classes: Vec<u32>,
    /// The network's input, width and height (multiples of 8): every frame is resampled to it.
    pub input: [u32; 2],
    pub epochs: usize,
    pub batch: usize,
    pub lr: f64,
    pub weight_decay: f64,
    pub schedule: Schedule,
    pub seed: u64,
    pub val_fraction: f64,
    /// Instances whose visible fraction is below this are not boxes to find.
    pub min_visib_fract: f64,
    /// Training windows zoom the frame by 1 to this.
    pub zoom_max: f64,
    pub data: PathBuf,
    pub split: String,
    /// What each class is (its model's name and size in the training data), so that a run
    /// on a dataset whose ids are other objects is refused (empty in configs written before).
    #[serde(default)]
    pub objects: Vec<ObjectIdentity>,
    /// Whether the detector gives each detection's visible mask (a mask branch trained on
    /// the visible masks); false in configs written before masks.
    #[serde(default)]
    pub masks: bool,
}

impl DetectorConfig {
    pub fn new(data: PathBuf, split: String, classes: Vec<u32>) -> DetectorConfig {
        DetectorConfig {
            model: "detector".into(),
            classes,
            input: [160, 120],
            epochs: 30,
            batch: 16,
            lr: 2e-3,
            weight_decay: 1e-4,
            schedule: Schedule::Cosine,
            seed: 0,
            val_fraction: 0.1,
            min_visib_fract: 0.1,
            zoom_max: 1.4,
            data,
            split,
            objects: Vec::new(),
            masks: true,
        }
    }

    pub fn validate(&self) -> Result<()> {
        self.validate_settings()?;
        if self.classes.is_empty() {
            return Err(Error::InvalidOption(
                "the detector needs at least one object class".into(),
            ));
        }
        Ok(())
    }

    /// [`DetectorConfig::validate`] but for the classes (known once the data is read).
    pub fn validate_settings(&self) -> Result<()> {
        let bad = |m: String| Err(Error::InvalidOption(m));
        if self.model != "detector" {
            return bad(format!(
                "config.json is a {} model's, not a detector's",
                self.model
            ));
        }
        let [w, h] = self.input;
        if !(16..=MAX_INPUT_SIDE).contains(&w)
            || !(16..=MAX_INPUT_SIDE).contains(&h)
            || w % 8 != 0
            || h % 8 != 0
        {
            return bad(format!(
                "--input {w}x{h}: both sides must be multiples of 8, from 16 to {MAX_INPUT_SIDE}"
            ));
        }
        if !(1..=MAX_EPOCHS).contains(&self.epochs) || !(1..=MAX_BATCH).contains(&self.batch) {
            return bad(format!(
                "--epochs {} must be in 1..={MAX_EPOCHS} and --batch {} in 1..={MAX_BATCH}",
                self.epochs, self.batch
            ));
        }
        if !(self.lr > 0.0 && self.lr.is_finite()) {
            return bad(format!("--lr {} must be positive", self.lr));
        }
        if !(0.0..1.0).contains(&self.val_fraction) {
            return bad(format!(
                "--val-fraction {} must be in 0..1",
                self.val_fraction
            ));
        }
        if !(self.zoom_max >= 1.0 && self.zoom_max.is_finite()) {
            return bad(format!("zoom_max {} must be at least 1", self.zoom_max));
        }
        Ok(())
    }

    fn lr_at(&self, step: usize, total: usize, epoch: usize) -> f64 {
        self.schedule
            .lr_at(self.lr, self.epochs, step, total, epoch)
    }
}

/// A decoded peak: class index, score, `[x0, y0, x1, y1]` (pixels).
type Peak = (usize, f64, [f64; 4]);

/// A visible box: class index and `[x0, y0, x1, y1]` (pixels, the object covers x0..x1).
type ClassBox = (usize, [f64; 4]);

/// One frame kept for training: its colour at twice the input size, its size, its boxes.
struct Frame {
    scene_id: u32,
    im_id: u32,
    rgb: Vec<u8>,
    /// The stored colour's size.
    w: u32,
    h: u32,
    /// The frame's own size.
    width: u32,
    height: u32,
    boxes: Vec<ClassBox>,
    /// With masks: per stored pixel, 1 + the class index of the visible object, 0 for none.
    labels: Option<Vec<u8>>,
}

/// Bilinear samples of `rgb` (`w × h`) over the window `[x0, y0, ww, wh]` (pixels) at
/// `ow × oh`, `n × n` samples averaged per output pixel (`n` from the scale: an area filter
/// when shrinking).
pub fn resample(rgb: &[u8], w: u32, h: u32, window: [f64; 4], ow: u32, oh: u32) -> Vec<u8> {
    let [x0, y0, ww, wh] = window;
    let (sx, sy) = (ww / f64::from(ow), wh / f64::from(oh));
    let n = sx.max(sy).ceil().clamp(1.0, 4.0) as u32;
    let px = |x: i64, y: i64, c: usize| -> f32 {
        let x = x.clamp(0, i64::from(w) - 1) as usize;
        let y = y.clamp(0, i64::from(h) - 1) as usize;
        f32::from(rgb[(y * w as usize + x) * 3 + c])
    };
    let mut out = Vec::with_capacity((ow * oh * 3) as usize);
    for j in 0..oh {
        for i in 0..ow {
            let mut acc = [0f32; 3];
            for sj in 0..n {
                for si in 0..n {
                    let fx = x0 + (f64::from(i) + (f64::from(si) + 0.5) / f64::from(n)) * sx - 0.5;
                    let fy = y0 + (f64::from(j) + (f64::from(sj) + 0.5) / f64::from(n)) * sy - 0.5;
                    let (bx, by) = (fx.floor(), fy.floor());
                    let (ax, ay) = ((fx - bx) as f32, (fy - by) as f32);
                    let (xi, yi) = (bx as i64, by as i64);
                    for (c, a) in acc.iter_mut().enumerate() {
                        let top = px(xi, yi, c) * (1.0 - ax) + px(xi + 1, yi, c) * ax;
                        let bot = px(xi, yi + 1, c) * (1.0 - ax) + px(xi + 1, yi + 1, c) * ax;
                        *a += top * (1.0 - ay) + bot * ay;
                    }
                }
            }
            let k = (n * n) as f32;
            out.extend(acc.map(|a| (a / k).round().clamp(0.0, 255.0) as u8));
        }
    }
    out
}

/// The visible boxes of a frame's instances with `visib_fract >= min` whose object is one of
/// `classes` ([`SourceFrame::visible_bbox`]).
fn frame_boxes(frame: &SourceFrame, classes: &[u32], min: f64) -> Result<Vec<ClassBox>> {
    let mut out = Vec::new();
    for (gt_id, g) in frame.gt.iter().enumerate() {
        let Some(class) = classes.iter().position(|&c| c == g.obj_id) else {
            continue;
        };
        let info = frame.gt_info.as_ref().and_then(|i| i.get(gt_id));
        if info.map_or(1.0, |i| i.visib_fract) < min {
            continue;
        }
        let Some(b) = frame.visible_bbox(gt_id)? else {
            continue;
        };
        let [x, y, w, h] = b.map(f64::from);
        out.push((class, [x, y, x + w + 1.0, y + h + 1.0]));
    }
    Ok(out)
}

/// A frame's visible masks of `classes` as one label map at `w × h` (nearest pixel): 1 + the
/// class index where an instance of it is visible, 0 elsewhere. An instance of a class
/// without a visible mask is an error naming the frame.
fn frame_labels(frame: &SourceFrame, classes: &[u32], w: u32, h: u32) -> Result<Vec<u8>> {
    let mut labels = vec![0u8; (w * h) as usize];
    for (gt_id, g) in frame.gt.iter().enumerate() {
        let Some(class) = classes.iter().position(|&c| c == g.obj_id) else {
            continue;
        };
        let Some(mask) = frame.masks_visib.get(gt_id).and_then(Option::as_ref) else {
            return Err(Error::InvalidOption(format!(
                "{} image {} has no visible mask for instance {gt_id} (object {}): a detector with masks trains on visible masks (synthgen render writes them, synthgen annotate computes them from poses); or train with --no-masks",
                frame.rgb.display(),
                frame.location.im_id,
                g.obj_id
            )));
        };
        let m = mask.read()?;
        let (mw, mh) = (m.width as usize, m.height as usize);
        for y in 0..h as usize {
            let sy = ((y * 2 + 1) * mh / (2 * h as usize)).min(mh - 1);
            for x in 0..w as usize {
                let sx = ((x * 2 + 1) * mw / (2 * w as usize)).min(mw - 1);
                if m.data[sy * mw + sx] != 0 {
                    labels[y * w as usize + x] = class as u8 + 1;
                }
            }
        }
    }
    Ok(labels)
}

fn load_frames(
    ds: &dyn FrameSource,
    cfg: &DetectorConfig,
    progress: &dyn Progress,
) -> Result<Vec<Frame>> {
    let frames = ds.frames(std::slice::from_ref(&cfg.split))?;
    let cam = ds.camera();
    progress.start("reading frames", frames.len() as u64);
    let [iw, ih] = cfg.input;
    let out: Result<Vec<Frame>> = frames
        .par_iter()
        .map(|f| {
            let img = read_rgb_sized(&f.rgb, [cam.width, cam.height])?;
            let (w, h) = (2 * iw, 2 * ih);
            let rgb = resample(
                &img.rgb,
                img.width,
                img.height,
                [0.0, 0.0, f64::from(img.width), f64::from(img.height)],
                w,
                h,
            );
            let boxes = frame_boxes(f, &cfg.classes, cfg.min_visib_fract)?;
            let labels = if cfg.masks {
                Some(frame_labels(f, &cfg.classes, w, h)?)
            } else {
                None
            };
            progress.advance(1);
            Ok(Frame {
                scene_id: f.location.scene_id,
                im_id: f.location.im_id,
                rgb,
                w,
                h,
                width: img.width,
                height: img.height,
                boxes,
                labels,
            })
        })
        .collect();
    progress.finish();
    out
}

/// `(v/255 − 0.5) / 0.25`, as the RGB models.
fn normalized(rgb: &[u8]) -> impl Iterator<Item = f32> + '_ {
    rgb.iter().map(|&x| (f32::from(x) / 255.0 - 0.5) / 0.25)
}

/// One sample: the input's colour, its boxes in input pixels and, with masks, its label map
/// at half the input's size (nearest pixel of the frame's).
struct Sample {
    rgb: Vec<u8>,
    boxes: Vec<ClassBox>,
    labels: Option<Vec<u8>>,
}

/// A training window of `f` (seeded), or the whole frame (`rng` None).
fn sample_of(f: &Frame, cfg: &DetectorConfig, rng: Option<&mut ChaCha8Rng>) -> Sample {
    let [iw, ih] = cfg.input;
    let (fw, fh) = (f64::from(f.w), f64::from(f.h));
    let (window, rng) = match rng {
        Some(rng) => {
            let z = rng.gen_range(1.0..=cfg.zoom_max);
            let (ww, wh) = (fw / z, fh / z);
            let x0 = rng.gen_range(0.0..=fw - ww);
            let y0 = rng.gen_range(0.0..=fh - wh);
            ([x0, y0, ww, wh], Some(rng))
        }
        None => ([0.0, 0.0, fw, fh], None),
    };
    let mut rgb = resample(&f.rgb, f.w, f.h, window, iw, ih);
    // Frame pixels → input pixels.
    let (ax, ay) = (
        f64::from(iw) / window[2] * fw / f64::from(f.width),
        f64::from(ih) / window[3] * fh / f64::from(f.height),
    );
    let (bx, by) = (
        window[0] * f64::from(iw) / window[2],
        window[1] * f64::from(ih) / window[3],
    );
    let mut boxes = Vec::new();
    for &(c, [x0, y0, x1, y1]) in &f.boxes {
        let b = [x0 * ax - bx, y0 * ay - by, x1 * ax - bx, y1 * ay - by];
        let clipped = [
            b[0].max(0.0),
            b[1].max(0.0),
            b[2].min(f64::from(iw)),
            b[3].min(f64::from(ih)),
        ];
        let area = |b: [f64; 4]| (b[2] - b[0]).max(0.0) * (b[3] - b[1]).max(0.0);
        // A box mostly cut off by the window is no longer a box to find.
        if area(clipped) >= 0.5 * area(b) && area(clipped) > 0.0 {
            boxes.push((c, clipped));
        }
    }
    let labels = f.labels.as_ref().map(|l| {
        let (ow, oh) = ((iw / 2) as usize, (ih / 2) as usize);
        let mut out = vec![0u8; ow * oh];
        for y in 0..oh {
            let sy = window[1] + (y as f64 + 0.5) * window[3] / oh as f64;
            let sy = (sy.floor().max(0.0) as usize).min(f.h as usize - 1);
            for x in 0..ow {
                let sx = window[0] + (x as f64 + 0.5) * window[2] / ow as f64;
                let sx = (sx.floor().max(0.0) as usize).min(f.w as usize - 1);
                out[y * ow + x] = l[sy * f.w as usize + sx];
            }
        }
        out
    });
    if let Some(rng) = rng {
        synthgen_train::rgb_input::photometric_augment(&mut rgb, iw, ih, rng);
    }
    Sample { rgb, boxes, labels }
}

/// The mask targets of a batch (B, H/2, W/2, C): 1 where the class is visible; None when the
/// samples have no label maps.
fn mask_targets(samples: &[Sample], cfg: &DetectorConfig, dev: &Device) -> Result<Option<Tensor>> {
    if !cfg.masks {
        return Ok(None);
    }
    let [iw, ih] = cfg.input;
    let (ow, oh, nc) = ((iw / 2) as usize, (ih / 2) as usize, cfg.classes.len());
    let mut t = vec![0f32; samples.len() * oh * ow * nc];
    for (bi, s) in samples.iter().enumerate() {
        let Some(labels) = &s.labels else { continue };
        for (p, &l) in labels.iter().enumerate() {
            if l > 0 {
                t[(bi * oh * ow + p) * nc + usize::from(l - 1)] = 1.0;
            }
        }
    }
    Ok(Some(Tensor::from_vec(t, (samples.len(), oh, ow, nc), dev)?))
}

/// The targets of a batch of samples: heatmaps (B, h, w, C), offset + log size (B, h, w, C,
/// 4), centre cells (B, h, w, C).
fn targets(
    samples: &[Sample],
    cfg: &DetectorConfig,
    dev: &Device,
) -> Result<(Tensor, Tensor, Tensor)> {
    let [iw, ih] = cfg.input;
    let (mw, mh) = ((iw / DET_STRIDE) as usize, (ih / DET_STRIDE) as usize);
    let nc = cfg.classes.len();
    let b = samples.len();
    let mut heat = vec![0f32; b * mh * mw * nc];
    let mut reg = vec![0f32; b * mh * mw * nc * 4];
    let mut centres = vec![0f32; b * mh * mw * nc];
    let s = f64::from(DET_STRIDE);
    for (bi, sample) in samples.iter().enumerate() {
        for &(c, [x0, y0, x1, y1]) in &sample.boxes {
            let (cx, cy) = ((x0 + x1) / 2.0 / s, (y0 + y1) / 2.0 / s);
            let (bw, bh) = ((x1 - x0) / s, (y1 - y0) / s);
            let (ix, iy) = (
                (cx.floor() as usize).min(mw - 1),
                (cy.floor() as usize).min(mh - 1),
            );
            // TTFNet's elliptical Gaussian: σ = 0.54 · side / 6, at least half a cell.
            let (sgx, sgy) = ((0.09 * bw).max(0.5), (0.09 * bh).max(0.5));
            let (rx, ry) = ((3.0 * sgx).ceil() as i64, (3.0 * sgy).ceil() as i64);
            for y in (iy as i64 - ry).max(0)..=(iy as i64 + ry).min(mh as i64 - 1) {
                for x in (ix as i64 - rx).max(0)..=(ix as i64 + rx).min(mw as i64 - 1) {
                    let (dx, dy) = (x as f64 - ix as f64, y as f64 - iy as f64);
                    let g = (-(dx * dx) / (2.0 * sgx * sgx) - (dy * dy) / (2.0 * sgy * sgy)).exp();
                    let at = ((bi * mh + y as usize) * mw + x as usize) * nc + c;
                    heat[at] = heat[at].max(g as f32);
                }
            }
            let at = ((bi * mh + iy) * mw + ix) * nc + c;
            heat[at] = 1.0;
            centres[at] = 1.0;
            reg[at * 4..at * 4 + 4].copy_from_slice(&[
                (cx - ix as f64) as f32,
                (cy - iy as f64) as f32,
                bw.max(1e-3).ln() as f32,
                bh.max(1e-3).ln() as f32,
            ]);
        }
    }
    Ok((
        Tensor::from_vec(heat, (b, mh, mw, nc), dev)?,
        Tensor::from_vec(reg, (b, mh, mw, nc, 4), dev)?,
        Tensor::from_vec(centres, (b, mh, mw, nc), dev)?,
    ))
}

fn input_tensor(samples: &[&[u8]], cfg: &DetectorConfig, dev: &Device) -> Result<Tensor> {
    let [iw, ih] = cfg.input;
    let mut v = Vec::with_capacity(samples.len() * (iw * ih * 3) as usize);
    for s in samples {
        v.extend(normalized(s));
    }
    Ok(Tensor::from_vec(
        v,
        (samples.len(), ih as usize, iw as usize, 3),
        dev,
    )?)
}

/// A trained (or loading) detector.
pub struct Detector {
    pub cfg: DetectorConfig,
    pub varmap: VarMap,
    net: DetectorNet,
    device: Device,
}

impl Detector {
    pub fn new(cfg: DetectorConfig, device: &Device) -> Result<Detector> {
        cfg.validate()?;
        let varmap = VarMap::new();
        // Seeded: the same --seed gives the same initial weights (candle's own init draws
        // from the unseeded thread RNG).
        let vb =
            synthgen_nn::init::seeded_var_builder(&varmap, splitmix64(cfg.seed ^ 0xde7e), device);
        let net = DetectorNet::new(cfg.classes.len(), cfg.masks, vb)?;
        Ok(Detector {
            cfg,
            varmap,
            net,
            device: device.clone(),
        })
    }

    /// The detector of a run folder (`config.json` and `model.safetensors`), or of a
    /// checkpoint file with `config.json` beside it.
    pub fn load(path: &Path, device: &Device) -> Result<Detector> {
        let model = synthgen_train::train::checkpoint_in(path);
        let dir = model
            .parent()
            .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
        let cfg: DetectorConfig = read_run_config(&dir.join(CONFIG_FILE), RunKind::Detector)?;
        let mut d = Detector::new(cfg, device)?;
        d.varmap.load(&model).map_err(|e| Error::Malformed {
            what: "checkpoint",
            message: e.to_string(),
            path: model.clone(),
        })?;
        Ok(d)
    }

    fn forward(&self, x: &Tensor) -> Result<DetOut> {
        Ok(self.net.forward(x)?)
    }

    /// The detections of one frame's colour (`width × height` RGB): per class, the local
    /// maxima (3 × 3) of its heatmap scoring at least `min_score`, at most `per_class`, best
    /// first; with masks, each with its visible mask ([`instance_mask`]).
    pub fn detect_image(
        &self,
        rgb: &[u8],
        width: u32,
        height: u32,
        min_score: f64,
        per_class: usize,
    ) -> Result<Vec<Found>> {
        let [iw, ih] = self.cfg.input;
        let input = resample(
            rgb,
            width,
            height,
            [0.0, 0.0, f64::from(width), f64::from(height)],
            iw,
            ih,
        );
        let x = input_tensor(&[&input], &self.cfg, &self.device)?;
        let out = self.forward(&x)?;
        let decoded = decode(&out, &self.cfg, min_score, per_class)?;
        let probs: Option<(Vec<f32>, usize, usize)> = match &out.mask {
            Some(m) => {
                let (_, mh, mw, _) = m.dims4()?;
                let p = candle_nn::ops::sigmoid(m)?.flatten_all()?.to_vec1()?;
                Some((p, mw, mh))
            }
            None => None,
        };
        let nc = self.cfg.classes.len();
        let (sx, sy) = (
            f64::from(width) / f64::from(iw),
            f64::from(height) / f64::from(ih),
        );
        Ok(decoded
            .into_iter()
            .next()
            .unwrap_or_default()
            .into_iter()
            .filter_map(|(c, score, [x0, y0, x1, y1])| {
                let b = [
                    (x0 * sx).max(0.0),
                    (y0 * sy).max(0.0),
                    (x1 * sx).min(f64::from(width)),
                    (y1 * sy).min(f64::from(height)),
                ];
                // A box that the frame's edges leave empty is no detection.
                (b[2] > b[0] && b[3] > b[1]).then(|| {
                    let bbox = [b[0], b[1], b[2] - b[0], b[3] - b[1]];
                    let mask = probs.as_ref().map(|(p, mw, mh)| {
                        let at = |x: usize, y: usize| p[(y * mw + x) * nc + c];
                        instance_mask(&at, *mw, *mh, bbox, width, height)
                    });
                    (self.cfg.classes[c], score, bbox, mask)
                })
            })
            .collect())
    }
}

/// A detection: object id, score, `[x, y, width, height]` (frame pixels), and its visible
/// mask when the detector gives masks.
pub type Found = (u32, f64, [f64; 4], Option<Rle>);

/// An instance's visible mask in a `width × height` frame: the pixels inside its box
/// `[x, y, w, h]` where the class's mask probability (`prob(x, y)` on an `mw × mh` map over
/// the frame, sampled bilinearly) is above one half.
pub fn instance_mask(
    prob: &dyn Fn(usize, usize) -> f32,
    mw: usize,
    mh: usize,
    bbox: [f64; 4],
    width: u32,
    height: u32,
) -> Rle {
    let (w, h) = (width as usize, height as usize);
    let x0 = (bbox[0].floor().max(0.0) as usize).min(w);
    let y0 = (bbox[1].floor().max(0.0) as usize).min(h);
    let x1 = ((bbox[0] + bbox[2]).ceil().max(0.0) as usize)
        .min(w)
        .max(x0);
    let y1 = ((bbox[1] + bbox[3]).ceil().max(0.0) as usize)
        .min(h)
        .max(y0);
    // Only the box's pixels are set: the mask is made (and run-length coded) over it.
    let bw = x1 - x0;
    let mut mask = vec![0u8; bw * (y1 - y0)];
    let (kx, ky) = (mw as f64 / w as f64, mh as f64 / h as f64);
    for y in y0..y1 {
        let v = ((y as f64 + 0.5) * ky - 0.5).clamp(0.0, (mh - 1) as f64);
        let (vi, va) = (v.floor() as usize, (v - v.floor()) as f32);
        let vj = (vi + 1).min(mh - 1);
        for x in x0..x1 {
            let u = ((x as f64 + 0.5) * kx - 0.5).clamp(0.0, (mw - 1) as f64);
            let (ui, ua) = (u.floor() as usize, (u - u.floor()) as f32);
            let uj = (ui + 1).min(mw - 1);
            let top = prob(ui, vi) * (1.0 - ua) + prob(uj, vi) * ua;
            let bot = prob(ui, vj) * (1.0 - ua) + prob(uj, vj) * ua;
            if top * (1.0 - va) + bot * va > 0.5 {
                mask[(y - y0) * bw + (x - x0)] = 1;
            }
        }
    }
    Rle::from_window(
        &mask,
        [x0, y0, bw, y1 - y0].map(|v| v as u32),
        width,
        height,
    )
}

/// Per batch item, the peaks of each class's heatmap as (class, score, [x0, y0, x1, y1] in
/// input pixels).
fn decode(
    out: &DetOut,
    cfg: &DetectorConfig,
    min_score: f64,
    per_class: usize,
) -> Result<Vec<Vec<Peak>>> {
    let (b, mh, mw, nc) = out.heat.dims4()?;
    let heat: Vec<f32> = candle_nn::ops::sigmoid(&out.heat)?
        .flatten_all()?
        .to_vec1()?;
    let reg: Vec<f32> = out.boxes.flatten_all()?.to_vec1()?;
    let s = f64::from(DET_STRIDE);
    let [iw, ih] = cfg.input;
    let mut all = Vec::with_capacity(b);
    for bi in 0..b {
        let mut found = Vec::new();
        for c in 0..nc {
            let at = |x: usize, y: usize| ((bi * mh + y) * mw + x) * nc + c;
            let mut peaks: Vec<(f64, usize, usize)> = Vec::new();
            for y in 0..mh {
                for x in 0..mw {
                    let v = heat[at(x, y)];
                    if f64::from(v) < min_score {
                        continue;
                    }
                    let mut is_max = true;
                    for yy in y.saturating_sub(1)..=(y + 1).min(mh - 1) {
                        for xx in x.saturating_sub(1)..=(x + 1).min(mw - 1) {
                            let u = heat[at(xx, yy)];
                            // Ties go to the first cell in reading order.
                            if u > v || (u == v && (yy, xx) < (y, x)) {
                                is_max = false;
                            }
                        }
                    }
                    if is_max {
                        peaks.push((f64::from(v), x, y));
                    }
                }
            }
            peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
            for &(score, x, y) in peaks.iter().take(per_class) {
                let r = &reg[at(x, y) * 4..at(x, y) * 4 + 4];
                let cx = (x as f64 + f64::from(r[0])) * s;
                let cy = (y as f64 + f64::from(r[1])) * s;
                let w = f64::from(r[2]).clamp(-5.0, 6.0).exp() * s;
                let h = f64::from(r[3]).clamp(-5.0, 6.0).exp() * s;
                let b = [
                    (cx - w / 2.0).max(0.0),
                    (cy - h / 2.0).max(0.0),
                    (cx + w / 2.0).min(f64::from(iw)),
                    (cy + h / 2.0).min(f64::from(ih)),
                ];
                found.push((c, score, b));
            }
        }
        all.push(found);
    }
    Ok(all)
}

/// Intersection over union of two `[x0, y0, x1, y1]` boxes.
pub fn iou(a: [f64; 4], b: [f64; 4]) -> f64 {
    let iw = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let ih = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let inter = iw * ih;
    let area = |b: [f64; 4]| (b[2] - b[0]).max(0.0) * (b[3] - b[1]).max(0.0);
    let union = area(a) + area(b) - inter;
    if union > 0.0 {
        inter / union
    } else {
        0.0
    }
}

/// Of `gt` boxes, how many are found at IoU ≥ 0.5 when each class's best detections are
/// taken, as many as the class has GT boxes, each matched to the GT box it overlaps most
/// (greedy, best score first).
pub fn recall_at_half(gt: &[ClassBox], found: &[Peak]) -> usize {
    let mut hits = 0;
    let classes: std::collections::BTreeSet<usize> = gt.iter().map(|g| g.0).collect();
    for c in classes {
        let mut left: Vec<[f64; 4]> = gt.iter().filter(|g| g.0 == c).map(|g| g.1).collect();
        let n = left.len();
        let mut dets: Vec<&Peak> = found.iter().filter(|d| d.0 == c).collect();
        dets.sort_by(|a, b| b.1.total_cmp(&a.1));
        for d in dets.into_iter().take(n) {
            let best = left
                .iter()
                .enumerate()
                .map(|(i, g)| (i, iou(*g, d.2)))
                .max_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((i, v)) = best {
                if v >= 0.5 {
                    hits += 1;
                    left.swap_remove(i);
                }
            }
        }
    }
    hits
}

/// One epoch's numbers (`metrics.jsonl`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectorEpoch {
    pub epoch: usize,
    pub train_loss: f64,
    /// None without validation frames (`null` in `metrics.jsonl`).
    pub val_loss: Option<f64>,
    /// Share of the validation frames' visible boxes found at IoU ≥ 0.5 ([`recall_at_half`]).
    pub val_recall_50: f64,
    pub val_boxes: usize,
    pub lr: f64,
    pub seconds: f64,
}

/// What a finished run reports.
#[derive(Debug, Clone)]
pub struct DetectorOutcome {
    pub history: Vec<DetectorEpoch>,
    pub train_frames: usize,
    pub val_frames: usize,
    pub resumed_from_epoch: usize,
}

/// The object ids with at least one visible box in `split` of `ds` (a detector's classes
/// when none are given).
pub fn dataset_classes(ds: &dyn FrameSource, split: &str) -> Result<Vec<u32>> {
    let mut ids = std::collections::BTreeSet::new();
    for f in ds.annotation_frames(&[split.to_string()])? {
        ids.extend(f.gt.iter().map(|g| g.obj_id));
    }
    Ok(ids.into_iter().collect())
}

/// Trains a detector on `ds` into `out` (`config.json`, `model.safetensors` and `state.json`
/// after every epoch, `metrics.jsonl`). With `resume`, continues the run in `out` (weights
/// and epoch count; AdamW's moments restart from zero): `cfg` is then the run's own
/// `config.json` (its `epochs` may be raised).
pub fn train_detector(
    cfg: &DetectorConfig,
    ds: &dyn FrameSource,
    out: &Path,
    resume: bool,
    device: &Device,
    progress: &dyn Progress,
) -> Result<DetectorOutcome> {
    cfg.validate()?;
    std::fs::create_dir_all(out).map_err(|e| Error::io("create directory", out, e))?;
    // A resumed run's checks before the frames are read: a bad --epochs costs no load.
    let model_path = out.join(MODEL_FILE);
    let (det, state, mut history) = if resume {
        let state: TrainState = read_json(&out.join(STATE_FILE), "state.json")?;
        if cfg.epochs <= state.epochs_done {
            return Err(Error::InvalidOption(format!(
                "the run in {} has trained {} epochs already: --epochs {} leaves nothing to train (raise --epochs above {})",
                out.display(),
                state.epochs_done,
                cfg.epochs,
                state.epochs_done
            )));
        }
        let det = Detector::load(&model_path, device)?;
        let history = read_history(&out.join(METRICS_FILE), state.epochs_done)?;
        (det, state, history)
    } else {
        (
            Detector::new(cfg.clone(), device)?,
            TrainState {
                epochs_done: 0,
                steps_done: 0,
            },
            Vec::new(),
        )
    };
    let frames = load_frames(ds, cfg, progress)?;
    let mut order: Vec<usize> = (0..frames.len()).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(splitmix64(
        cfg.seed ^ 0x7a1d,
    )));
    let n_val = if frames.len() >= 2 {
        ((cfg.val_fraction * frames.len() as f64).ceil() as usize).clamp(1, frames.len() - 1)
    } else {
        0
    };
    let (val, train): (Vec<usize>, Vec<usize>) = (order[..n_val].to_vec(), order[n_val..].to_vec());
    if train.iter().all(|&i| frames[i].boxes.is_empty()) {
        return Err(Error::NoInstances {
            reason: format!(
                "no visible boxes of the objects {:?} in the training frames",
                cfg.classes
            ),
            path: cfg.data.clone(),
        });
    }
    let json = serde_json::to_vec_pretty(cfg).map_err(|e| Error::InvalidOption(e.to_string()))?;
    write_atomic(&out.join(CONFIG_FILE), &json)?;
    let mut lines = String::new();
    for m in &history {
        lines += &serde_json::to_string(m).map_err(|e| Error::InvalidOption(e.to_string()))?;
        lines.push('\n');
    }
    write_atomic(&out.join(METRICS_FILE), lines.as_bytes())?;
    let mut opt = FusedAdamW::new(
        det.varmap.all_vars(),
        ParamsAdamW {
            lr: cfg.lr,
            weight_decay: cfg.weight_decay,
            ..Default::default()
        },
    )?;
    let steps_per_epoch = train.len().div_ceil(cfg.batch);
    let total = steps_per_epoch * cfg.epochs;
    let mut step = state.steps_done;
    for epoch in state.epochs_done..cfg.epochs {
        let started = Instant::now();
        progress.start(
            &format!("epoch {}/{}", epoch + 1, cfg.epochs),
            steps_per_epoch as u64,
        );
        let mut ord = train.clone();
        ord.shuffle(&mut ChaCha8Rng::seed_from_u64(splitmix64(
            cfg.seed ^ (epoch as u64 + 1),
        )));
        let (mut sum, mut count) = (0.0, 0usize);
        let mut lr = cfg.lr;
        let batches: Vec<&[usize]> = ord.chunks(cfg.batch).collect();
        let first_step = step;
        // The next batch's windows, augmentation and targets are made while the network runs
        // on this one; each batch's randomness is its step's, as without the overlap.
        type Batch = (Tensor, Tensor, Tensor, Tensor, Option<Tensor>);
        let prepare = |k: usize| -> Result<Batch> {
            let at = first_step + k;
            let samples: Vec<Sample> = batches[k]
                .par_iter()
                .map(|&i| {
                    let f = &frames[i];
                    let mut rng = ChaCha8Rng::seed_from_u64(splitmix64(
                        splitmix64(cfg.seed ^ (at as u64).wrapping_mul(0x9e37_79b9))
                            ^ (u64::from(f.scene_id) << 32 | u64::from(f.im_id)),
                    ));
                    sample_of(f, cfg, Some(&mut rng))
                })
                .collect();
            let x = input_tensor(
                &samples.iter().map(|s| s.rgb.as_slice()).collect::<Vec<_>>(),
                cfg,
                device,
            )?;
            let (heat, reg, centres) = targets(&samples, cfg, device)?;
            let masks = mask_targets(&samples, cfg, device)?;
            Ok((x, heat, reg, centres, masks))
        };
        pipelined(
            batches.len(),
            prepare,
            |k, (x, heat, reg, centres, masks)| {
                lr = cfg.lr_at(step, total, epoch);
                opt.set_learning_rate(lr);
                let loss = detector_loss(&det.forward(&x)?, &heat, &reg, &centres, masks.as_ref())?;
                let value = f64::from(loss.to_scalar::<f32>()?);
                if !value.is_finite() {
                    return Err(Error::Diverged {
                        value,
                        epoch: epoch + 1,
                        step: step + 1,
                        kept: format!("the checkpoint of epoch {epoch} is kept"),
                        path: out.to_path_buf(),
                    });
                }
                opt.backward_step(&loss)?;
                sum += value * batches[k].len() as f64;
                count += batches[k].len();
                step += 1;
                progress.set_message(&format!(
                    "epoch {}/{} loss {:.4}",
                    epoch + 1,
                    cfg.epochs,
                    sum / count as f64
                ));
                progress.advance(1);
                Ok(())
            },
        )?;
        progress.finish();
        let (val_loss, found, boxes) = validate(&det, &frames, &val)?;
        let m = DetectorEpoch {
            epoch: epoch + 1,
            train_loss: sum / count.max(1) as f64,
            val_loss,
            val_recall_50: found as f64 / boxes.max(1) as f64,
            val_boxes: boxes,
            lr,
            seconds: started.elapsed().as_secs_f64(),
        };
        save_checkpoint(&det.varmap, out, epoch + 1, step)?;
        let path = out.join(METRICS_FILE);
        let mut f = std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .map_err(|e| Error::io("open", &path, e))?;
        let line = serde_json::to_string(&m).map_err(|e| Error::InvalidOption(e.to_string()))?;
        writeln!(f, "{line}").map_err(|e| Error::io("write", &path, e))?;
        progress.info(&format!(
            "epoch {:>3}: train loss {:.4}, val loss {}, val recall@0.5 {:.1}% of {} boxes, lr {:.2e}, {:.1} s",
            m.epoch,
            m.train_loss,
            m.val_loss
                .map_or_else(|| "- (no validation frames)".to_string(), |v| format!("{v:.4}")),
            100.0 * m.val_recall_50,
            m.val_boxes,
            m.lr,
            m.seconds
        ));
        history.push(m);
    }
    Ok(DetectorOutcome {
        history,
        train_frames: train.len(),
        val_frames: val.len(),
        resumed_from_epoch: state.epochs_done,
    })
}

/// The epochs of a run's `metrics.jsonl` (the first `epochs_done` lines; a missing file is
/// none); a line that does not read is an error naming it, not a line silently dropped.
fn read_history(path: &Path, epochs_done: usize) -> Result<Vec<DetectorEpoch>> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(Error::io("read", path, e)),
    };
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .take(epochs_done)
        .enumerate()
        .map(|(i, l)| {
            serde_json::from_str(l).map_err(|e| Error::Malformed {
                what: "metrics.jsonl",
                message: format!("line {}: {e}", i + 1),
                path: path.to_path_buf(),
            })
        })
        .collect()
}

/// The validation frames' loss (None without any) and (found, GT) boxes at IoU 0.5.
fn validate(
    det: &Detector,
    frames: &[Frame],
    val: &[usize],
) -> Result<(Option<f64>, usize, usize)> {
    let cfg = &det.cfg;
    let (mut loss, mut n, mut found, mut boxes) = (0.0, 0usize, 0usize, 0usize);
    for chunk in val.chunks(cfg.batch) {
        let samples: Vec<Sample> = chunk
            .iter()
            .map(|&i| sample_of(&frames[i], cfg, None))
            .collect();
        let x = input_tensor(
            &samples.iter().map(|s| s.rgb.as_slice()).collect::<Vec<_>>(),
            cfg,
            &det.device,
        )?;
        let (heat, reg, centres) = targets(&samples, cfg, &det.device)?;
        let masks = mask_targets(&samples, cfg, &det.device)?;
        let out = det.forward(&x)?;
        let l = detector_loss(&out, &heat, &reg, &centres, masks.as_ref())?;
        loss += f64::from(l.to_scalar::<f32>()?) * chunk.len() as f64;
        n += chunk.len();
        for (s, d) in samples.iter().zip(decode(&out, cfg, 0.0, 10)?) {
            found += recall_at_half(&s.boxes, &d);
            boxes += s.boxes.len();
        }
    }
    Ok(((n > 0).then(|| loss / n as f64), found, boxes))
}

/// What [`detect_frames`] found beside the detections.
#[derive(Debug, Clone, Default)]
pub struct DetectSummary {
    pub frames: usize,
    /// GT visible boxes of the detector's classes (visible fraction ≥ the config's) and how
    /// many were found at IoU ≥ 0.5 ([`recall_at_half`]), per object id; empty without GT.
    pub recall: std::collections::BTreeMap<u32, (usize, usize)>,
    pub seconds: f64,
    /// The frames detected in (a detections file's provenance).
    pub frames_key: FramesKey,
}

/// Runs `det` on every frame of `split`: each class's peaks scoring at least `min_score`, at
/// most `per_class` per frame; with the frames' GT, the recall per object.
pub fn detect_frames(
    det: &Detector,
    ds: &dyn FrameSource,
    split: &str,
    min_score: f64,
    per_class: usize,
    progress: &dyn Progress,
) -> Result<(Vec<Detection>, DetectSummary)> {
    let started = Instant::now();
    let frames = ds.frames(&[split.to_string()])?;
    let cam = ds.camera();
    progress.start("detecting", frames.len() as u64);
    // Per frame: its detections and, per object, (GT boxes, found).
    type FrameOut = (Vec<Detection>, Vec<(u32, usize, usize)>);
    let per_frame: Result<Vec<FrameOut>> = frames
        .par_iter()
        .map(|f| {
            let t0 = Instant::now();
            let img = read_rgb_sized(&f.rgb, [cam.width, cam.height])?;
            let found = det.detect_image(&img.rgb, img.width, img.height, min_score, per_class)?;
            let time = t0.elapsed().as_secs_f64();
            let dets: Vec<Detection> = found
                .iter()
                .map(|(obj, score, bbox, mask)| Detection {
                    scene_id: f.location.scene_id,
                    image_id: f.location.im_id,
                    category_id: *obj,
                    score: *score,
                    bbox: *bbox,
                    time,
                    segmentation: mask.clone(),
                })
                .collect();
            let gt = frame_boxes(f, &det.cfg.classes, det.cfg.min_visib_fract)?;
            let as_boxes: Vec<Peak> = found
                .iter()
                .filter_map(|&(obj, score, [x, y, w, h], _)| {
                    let c = det.cfg.classes.iter().position(|&id| id == obj)?;
                    Some((c, score, [x, y, x + w, y + h]))
                })
                .collect();
            let mut recall = Vec::new();
            for (c, &obj) in det.cfg.classes.iter().enumerate() {
                let g: Vec<ClassBox> = gt.iter().filter(|b| b.0 == c).copied().collect();
                if !g.is_empty() {
                    recall.push((obj, g.len(), recall_at_half(&g, &as_boxes)));
                }
            }
            progress.advance(1);
            Ok((dets, recall))
        })
        .collect();
    progress.finish();
    let mut all = Vec::new();
    let mut summary = DetectSummary {
        frames: frames.len(),
        frames_key: frames_key(&frames, [cam.width, cam.height]),
        ..Default::default()
    };
    for (d, r) in per_frame? {
        all.extend(d);
        for (obj, n, hit) in r {
            let e = summary.recall.entry(obj).or_insert((0, 0));
            e.0 += n;
            e.1 += hit;
        }
    }
    summary.seconds = started.elapsed().as_secs_f64();
    Ok((all, summary))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn cfg() -> DetectorConfig {
        DetectorConfig {
            input: [64, 48],
            ..DetectorConfig::new(PathBuf::from("d"), "train_pbr".into(), vec![3, 7])
        }
    }

    #[test]
    fn masks_are_cut_from_the_class_map_by_the_box() {
        // A 4x4 map over an 8x8 frame, the class on its left half's middle rows.
        let prob = |x: usize, y: usize| {
            if x < 2 && (1..3).contains(&y) {
                0.9
            } else {
                0.1
            }
        };
        let rle = instance_mask(&prob, 4, 4, [0.0, 0.0, 8.0, 8.0], 8, 8);
        let m = rle.decode();
        // Rows 2..6 (map rows 1..3 at twice the size), columns 0..4.
        for y in 0..8 {
            for x in 0..8 {
                let want = x < 4 && (2..6).contains(&y);
                assert_eq!(m[y * 8 + x] == 1, want, "({x}, {y})");
            }
        }
        // Outside the box nothing, though the map says the class is there.
        let cut = instance_mask(&prob, 4, 4, [2.0, 0.0, 6.0, 8.0], 8, 8);
        assert_eq!(cut.area(), 8);
        assert_eq!(cut.bbox(), [2.0, 2.0, 2.0, 4.0]);
    }

    #[test]
    fn mask_targets_follow_the_labels_through_the_window() {
        let mut cfg = cfg();
        cfg.input = [16, 8];
        // A 32x16 stored frame (twice the input): class 1 (label 2) on columns 8..16.
        let mut labels = vec![0u8; 32 * 16];
        for y in 0..16 {
            for x in 8..16 {
                labels[y * 32 + x] = 2;
            }
        }
        let f = Frame {
            scene_id: 0,
            im_id: 0,
            rgb: vec![0; 32 * 16 * 3],
            w: 32,
            h: 16,
            width: 32,
            height: 16,
            boxes: vec![],
            labels: Some(labels),
        };
        let s = sample_of(&f, &cfg, None);
        // The whole frame at 8x4: columns 2..4 are the class.
        let l = s.labels.as_ref().unwrap();
        assert_eq!(l.len(), 32);
        for (p, &v) in l.iter().enumerate() {
            assert_eq!(v, if (2..4).contains(&(p % 8)) { 2 } else { 0 }, "{p}");
        }
        let t = mask_targets(std::slice::from_ref(&s), &cfg, &Device::Cpu)
            .unwrap()
            .unwrap();
        assert_eq!(t.dims(), &[1, 4, 8, 2]);
        let v: Vec<f32> = t.flatten_all().unwrap().to_vec1().unwrap();
        // Class 1's channel, 8 pixels; class 0's none.
        assert_eq!(v.iter().skip(1).step_by(2).sum::<f32>(), 8.0);
        assert_eq!(v.iter().step_by(2).sum::<f32>(), 0.0);
        cfg.masks = false;
        assert!(mask_targets(&[s], &cfg, &Device::Cpu).unwrap().is_none());
    }

    #[test]
    fn the_targets_decode_back_to_their_boxes() {
        let cfg = cfg();
        let sample = Sample {
            rgb: vec![0; 64 * 48 * 3],
            boxes: vec![(1, [10.0, 6.0, 30.0, 22.0]), (0, [40.0, 20.0, 62.0, 46.0])],
            labels: None,
        };
        let (heat, reg, centres) =
            targets(std::slice::from_ref(&sample), &cfg, &Device::Cpu).unwrap();
        assert_eq!(centres.sum_all().unwrap().to_scalar::<f32>().unwrap(), 2.0);
        // Logits from the targets: +12 at the centres, −12 elsewhere.
        let logits = ((centres.clone() * 24.0).unwrap() - 12.0).unwrap();
        let out = DetOut {
            heat: logits,
            boxes: reg.clone(),
            mask: None,
        };
        let found = decode(&out, &cfg, 0.5, 5).unwrap().remove(0);
        assert_eq!(found.len(), 2);
        for (c, _, b) in &found {
            let want = sample.boxes.iter().find(|g| g.0 == *c).unwrap().1;
            for k in 0..4 {
                assert!((b[k] - want[k]).abs() < 1e-3, "{b:?} {want:?}");
            }
        }
        assert_eq!(recall_at_half(&sample.boxes, &found), 2);
        // The Gaussian peaks at the centre cell and falls off around it.
        let h: Vec<f32> = heat.flatten_all().unwrap().to_vec1().unwrap();
        assert_eq!(h.iter().filter(|&&v| v == 1.0).count(), 2);
        assert!(h.iter().filter(|&&v| v > 0.0 && v < 1.0).count() > 4);
    }

    #[test]
    fn recall_takes_as_many_detections_as_boxes() {
        let gt = vec![(0, [0.0, 0.0, 10.0, 10.0])];
        // The best-scoring detection is wrong: the second does not count.
        let found = vec![
            (0, 0.9, [50.0, 50.0, 60.0, 60.0]),
            (0, 0.8, [0.0, 0.0, 10.0, 10.0]),
        ];
        assert_eq!(recall_at_half(&gt, &found), 0);
        assert_eq!(recall_at_half(&gt, &found[1..]), 1);
        assert!((iou([0.0, 0.0, 10.0, 10.0], [5.0, 0.0, 15.0, 10.0]) - 1.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn resampling_a_flat_image_keeps_it_flat_and_shrinks_by_area() {
        let img: Vec<u8> = (0..8 * 8)
            .flat_map(|i| {
                if (i % 8 + i / 8) % 2 == 0 {
                    [0, 0, 0]
                } else {
                    [200, 200, 200]
                }
            })
            .collect();
        // A checkerboard shrunk 4× averages to grey, not to an alias.
        let small = resample(&img, 8, 8, [0.0, 0.0, 8.0, 8.0], 2, 2);
        assert!(
            small.iter().all(|&v| (v as i32 - 100).abs() <= 2),
            "{small:?}"
        );
        let flat = vec![77u8; 10 * 6 * 3];
        assert!(resample(&flat, 10, 6, [1.0, 1.0, 5.0, 3.0], 7, 4)
            .iter()
            .all(|&v| v == 77));
    }

    #[test]
    fn a_config_is_checked() {
        assert!(cfg().validate().is_ok());
        let mut c = cfg();
        c.input = [60, 48];
        assert!(c
            .validate()
            .unwrap_err()
            .to_string()
            .contains("multiples of 8"));
        let mut c = cfg();
        c.classes.clear();
        assert!(c.validate().is_err());
        let mut c = cfg();
        c.model = "rgb".into();
        assert!(c.validate().is_err());
    }

    /// Regression (issue 50): a run without validation frames wrote `"val_loss": null`,
    /// which `--resume` could not read back and silently dropped.
    #[test]
    fn epochs_without_validation_read_back_and_bad_lines_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(METRICS_FILE);
        let e = DetectorEpoch {
            epoch: 1,
            train_loss: 2.5,
            val_loss: None,
            val_recall_50: 0.0,
            val_boxes: 0,
            lr: 1e-3,
            seconds: 0.1,
        };
        let line = serde_json::to_string(&e).unwrap();
        assert!(line.contains("\"val_loss\":null"), "{line}");
        std::fs::write(&path, format!("{line}\n{line}\n")).unwrap();
        assert_eq!(read_history(&path, 2).unwrap(), vec![e.clone(), e]);
        std::fs::write(&path, format!("{line}\nnot json\n")).unwrap();
        let err = read_history(&path, 2).unwrap_err().to_string();
        assert!(
            err.contains("line 2") && err.contains("metrics.jsonl"),
            "{err}"
        );
    }
}
