//! One trained pose model of any kind (TNet, RNet, Full, RGB) with its variables: batching of
//! instances into tensors, loss, and per-instance predictions; checkpoints (strict load,
//! and partial initialization from another kind's checkpoint).

pub mod batch;

use std::collections::BTreeMap;
use std::path::Path;

use candle_core::{DType, Device, Tensor};
use candle_nn::VarMap;
use rayon::prelude::*;
use synthgen_core::glam::{DMat3, DQuat, DVec3};
use synthgen_core::Pose;
use synthgen_formats::bop::ModelInfo;
use synthgen_formats::source::FrameSource;

use crate::data::Instance;
use crate::dataset_objects::{eval_object, load_each_object};
use crate::error::{Error, Result};
use crate::losses::{
    quaternion_confidence_loss, rotation_points_loss, smooth_l1_loss, symmetry_poses,
};
use crate::metrics::{subsample_vertices, EvalObject};
use crate::models::full::{full_loss, Full};
use crate::models::rgb::{canonical_sign, quaternion_rotation, RgbNet, Translation, TARGET_SCALE};
use crate::models::rgb_dense::{dense_loss, dense_out, DenseNet};
use crate::models::rnet::{RNet, RotationOut, CONFIDENCE_WEIGHT};
use crate::models::tnet::{centres_from_offsets, offset_l1_loss, TNet};
use crate::models::ModelKind;
use crate::rgb_input;
use batch::{BoxTargets, PointTarget, Prepared, PreparedBatch};
use synthgen_nn::init::seeded_var_builder;

/// The RGB model's smooth L1 β, in the translation targets' units (decimetres, tenths of the
/// box side): quadratic below 1 cm (1% of the box), linear beyond.
pub const RGB_SMOOTH_L1_BETA: f64 = 0.1;
/// The RGB model's rotation loss weight against the translation's.
pub const RGB_ROTATION_WEIGHT: f64 = 4.0;

/// Continuous symmetries are discretized into this many rotations for Full's loss.
pub const CONTINUOUS_SYMMETRY_STEPS: usize = 36;

/// What the models need of an object: loss points, symmetries, and the evaluation model.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainObject {
    /// Model points for Full's ADD loss (object frame, metres).
    pub loss_points_m: Vec<DVec3>,
    /// Symmetry transforms, the identity first.
    pub symmetries: Vec<Pose>,
    pub eval: EvalObject,
}

pub type Objects = BTreeMap<u32, TrainObject>;

/// Loads the objects `obj_ids` from models_info and the model files (in `units`).
pub fn load_objects(
    models_info: Option<&BTreeMap<u32, ModelInfo>>,
    info_path: &Path,
    model_path: &dyn Fn(u32) -> std::path::PathBuf,
    units: synthgen_assets::Units,
    obj_ids: impl IntoIterator<Item = u32>,
    loss_points: usize,
) -> Result<Objects> {
    load_each_object(
        models_info,
        info_path,
        model_path,
        units,
        obj_ids,
        |model, info| TrainObject {
            loss_points_m: subsample_vertices(model, loss_points),
            symmetries: symmetry_poses(&info.symmetries, CONTINUOUS_SYMMETRY_STEPS),
            eval: eval_object(model, info),
        },
    )
}

/// Loads the objects of a dataset (its models_info and model files; BOP or Linemod).
pub fn load_dataset_objects(
    ds: &dyn FrameSource,
    obj_ids: impl IntoIterator<Item = u32>,
    loss_points: usize,
) -> Result<Objects> {
    let ids: Vec<u32> = obj_ids.into_iter().collect();
    let mut objects = load_objects(
        ds.models_info(),
        &ds.models_info_path(),
        &|id| ds.model_file(id),
        ds.model_units(),
        ids.iter().copied(),
        loss_points,
    )?;
    // The metrics score with what bop_toolkit scores with: `models_eval/` where it exists.
    if crate::dataset_objects::has_eval_models(ds) {
        let eval = crate::dataset_objects::load_eval_objects(ds, ids)?;
        for (id, o) in objects.iter_mut() {
            if let Some(e) = eval.get(id) {
                o.eval = e.clone();
            }
        }
    }
    Ok(objects)
}

enum Net {
    T(TNet),
    R(RNet),
    F(Full),
    G(RgbNet),
    D(DenseNet),
}

/// A model with its variables.
pub struct PoseModel {
    pub kind: ModelKind,
    pub varmap: VarMap,
    net: Net,
    /// Point normalization scale (1/m).
    pub scale: f32,
    /// RGB crop side (RNet, Full, RGB).
    pub crop_size: u32,
    /// The RGB model's translation parametrization.
    pub translation: Option<Translation>,
    /// The RGB model's classes (object ids, sorted): one head each.
    pub classes: Vec<u32>,
    pub device: Device,
}

/// One instance's prediction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prediction {
    /// Centre (metres): TNet and Full; the translation: RGB.
    pub centre_m: Option<[f32; 3]>,
    /// Rotation of the most confident pixel and its confidence: RNet and Full; RGB's
    /// rotation with confidence 1.
    pub rotation: Option<(DMat3, f32)>,
}

impl Prediction {
    /// The predicted pose; RNet predicts no translation, so `fallback_t` (for RNet's scoring:
    /// the GT translation) fills it in.
    pub fn pose(&self, fallback_t: DVec3) -> Pose {
        let t = self.centre_m.map_or(fallback_t, |c| {
            DVec3::new(c[0].into(), c[1].into(), c[2].into())
        });
        let r = self.rotation.map_or(DMat3::IDENTITY, |r| r.0);
        Pose::new(r, t)
    }

    /// A score for ranking estimates: the confidence, 1 without one.
    pub fn score(&self) -> f64 {
        self.rotation.map_or(1.0, |r| f64::from(r.1))
    }
}

/// Visibility probability above which a cell of the dense model is a correspondence.
pub const DENSE_VISIBLE: f32 = 0.5;
/// RANSAC's inlier threshold for the dense model, in output cells (scaled to pixels by the
/// box: a cell spans side / out pixels).
pub const DENSE_INLIER_CELLS: f64 = 1.5;
/// The inlier share of the correspondences above which the dense model's rotation is PnP's
/// rather than the rotation head's.
pub const DENSE_MIN_INLIERS: f32 = 0.5;
/// The dense model's rotation-head loss weight (its point loss in decimetres) against the
/// coordinate and visibility losses.
pub const DENSE_ROTATION_WEIGHT: f64 = 1.0;

/// The pose of one instance from the dense model's output (`out × out` cells of coordinates
/// over `radius` and visibility logits) over the crop of `s`, and its heads' pose `heads`
/// (the rotation head's rotation, the centre + Tz head's translation): every cell more likely
/// visible than not is a correspondence (the 6 most likely when fewer), PnP + RANSAC (seeded,
/// deterministic) and refinement. The rotation is PnP's when at least [`DENSE_MIN_INLIERS`]
/// of the correspondences are its inliers, else the head's; the translation is the head's
/// (PnP's depth is its weak direction). The confidence is the inlier share (0 without a PnP
/// pose).
fn dense_pose(
    coords: &[f32],
    logits: &[f32],
    out: u32,
    radius: f64,
    s: &rgb_input::RgbSample,
    heads: Pose,
) -> Prediction {
    let t = heads.translation_m.as_vec3().to_array();
    match dense_pnp(coords, logits, out, radius, s) {
        Some((pose, share)) => Prediction {
            centre_m: Some(t),
            rotation: Some((
                if share >= DENSE_MIN_INLIERS {
                    pose.rotation
                } else {
                    heads.rotation
                },
                share,
            )),
        },
        None => Prediction {
            centre_m: Some(t),
            rotation: Some((heads.rotation, 0.0)),
        },
    }
}

/// PnP + RANSAC on the dense output's correspondences ([`dense_pose`]): the pose and the
/// inlier share of the correspondences; None when RANSAC finds none.
fn dense_pnp(
    coords: &[f32],
    logits: &[f32],
    out: u32,
    radius: f64,
    s: &rgb_input::RgbSample,
) -> Option<(Pose, f32)> {
    let o = out as usize;
    let cell = s.bbox.side / f64::from(out);
    let mut order: Vec<usize> = (0..o * o).collect();
    order.sort_by(|&a, &b| logits[b].total_cmp(&logits[a]));
    let threshold = (DENSE_VISIBLE / (1.0 - DENSE_VISIBLE)).ln();
    let n = order
        .iter()
        .take_while(|&&i| logits[i] > threshold)
        .count()
        .max(6)
        .min(order.len());
    let (mut model, mut pixels) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for &i in &order[..n] {
        let c = &coords[i * 3..i * 3 + 3];
        model.push(DVec3::new(c[0].into(), c[1].into(), c[2].into()) * radius);
        pixels.push(synthgen_core::glam::DVec2::new(
            s.bbox.cx - 0.5 * s.bbox.side + ((i % o) as f64 + 0.5) * cell,
            s.bbox.cy - 0.5 * s.bbox.side + ((i / o) as f64 + 0.5) * cell,
        ));
    }
    let k = synthgen_core::Intrinsics {
        width: 0,
        height: 0,
        fx: s.camera.fx,
        fy: s.camera.fy,
        cx: s.camera.cx,
        cy: s.camera.cy,
    };
    let options = synthgen_core::pnp::RansacOptions {
        inlier_px: (DENSE_INLIER_CELLS * cell).max(1.0),
        ..Default::default()
    };
    synthgen_core::pnp::ransac(&model, &pixels, &k, &options)
        .map(|sol| (sol.pose, sol.inliers.len() as f32 / n as f32))
}

/// The dense model's poses of a batch (PnP + RANSAC on the visible cells, with the heads'
/// pose: [`dense_pose`]), one instance per task.
fn dense_predictions(
    result: &crate::models::rgb_dense::DenseOut,
    samples: &[rgb_input::RgbSample],
    radii: &[f64],
    rays: &[DMat3],
    crop_size: u32,
) -> Result<Vec<Prediction>> {
    let out = dense_out(crop_size);
    let cells = (out * out) as usize;
    let quats: Vec<Vec<f32>> = result.quats.to_dtype(DType::F32)?.to_vec2()?;
    let trans: Vec<Vec<f32>> = result.translation.to_dtype(DType::F32)?.to_vec2()?;
    let coords: Vec<f32> = result
        .coords
        .to_dtype(DType::F32)?
        .flatten_all()?
        .to_vec1()?;
    let logits: Vec<f32> = result
        .logits
        .to_dtype(DType::F32)?
        .flatten_all()?
        .to_vec1()?;
    Ok(samples
        .par_iter()
        .enumerate()
        .map(|(b, s)| {
            let q = &quats[b];
            let head = rays[b] * quaternion_rotation([q[0], q[1], q[2], q[3]]);
            let t = &trans[b];
            let t_head = Translation::CentreTz.translation(
                [t[0], t[1], t[2]].map(f64::from),
                &s.bbox,
                &s.camera,
            );
            dense_pose(
                &coords[b * cells * 3..(b + 1) * cells * 3],
                &logits[b * cells..(b + 1) * cells],
                out,
                radii[b],
                s,
                Pose::new(head, t_head),
            )
        })
        .collect())
}

/// How often a training step hides an instance's class from a per-object TNet, so that the
/// class-free prediction (an object the model has no class for) stays a trained one.
pub const CLASS_DROPOUT: f64 = 0.15;

/// (B, classes) one-hot rows of the batch's object ids; an id outside `classes` is an all-zero
/// row, and so (with `jitter_seed`, training) is a [`CLASS_DROPOUT`] share of the instances,
/// drawn from (seed, scene, image, gt).
pub(crate) fn class_one_hot(
    batch: &[&Instance],
    classes: &[u32],
    jitter_seed: Option<u64>,
    device: &Device,
) -> Result<Tensor> {
    let n = classes.len();
    let mut v = vec![0f32; batch.len() * n];
    for (row, i) in batch.iter().enumerate() {
        let dropped = jitter_seed.is_some_and(|seed| {
            let h = synthgen_core::rng::splitmix64(
                synthgen_core::rng::splitmix64(
                    synthgen_core::rng::splitmix64(seed ^ 0x0063_6c61_7373) ^ u64::from(i.scene_id),
                ) ^ (u64::from(i.im_id) << 20 | i.gt_id as u64),
            );
            ((h >> 11) as f64 / (1u64 << 53) as f64) < CLASS_DROPOUT
        });
        if let (false, Some(k)) = (dropped, classes.iter().position(|c| *c == i.obj_id)) {
            v[row * n + k] = 1.0;
        }
    }
    Ok(Tensor::from_vec(v, (batch.len(), n), device)?)
}

/// The GT rotation as a quaternion (w, x, y, z) with w ≥ 0.
pub fn quaternion_wxyz(r: &DMat3) -> [f64; 4] {
    let q = DQuat::from_mat3(r).normalize();
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    [s * q.w, s * q.x, s * q.y, s * q.z]
}

fn best_rotations(rot: &RotationOut) -> Result<Vec<(DMat3, f32)>> {
    let q: Vec<Vec<Vec<f32>>> = rot.quats.to_dtype(DType::F32)?.to_vec3()?;
    let c: Vec<Vec<f32>> = rot.conf.to_dtype(DType::F32)?.to_vec2()?;
    Ok(q.iter()
        .zip(&c)
        .map(|(qs, cs)| {
            let (i, conf) =
                cs.iter()
                    .enumerate()
                    .fold((0, f32::MIN), |a, (i, &v)| if v > a.1 { (i, v) } else { a });
            let [w, x, y, z] = [qs[i][0], qs[i][1], qs[i][2], qs[i][3]].map(f64::from);
            let quat = DQuat::from_xyzw(x, y, z, w).normalize();
            (DMat3::from_quat(quat), conf)
        })
        .collect())
}

impl PoseModel {
    pub fn new(
        kind: ModelKind,
        width: usize,
        scale: f32,
        crop_size: u32,
        seed: u64,
        device: &Device,
    ) -> Result<PoseModel> {
        if kind.is_rgb_only() {
            return Err(Error::InvalidOption(format!(
                "the {} model is made by PoseModel::rgb or rgb_dense (it needs its classes)",
                kind.name()
            )));
        }
        if kind.needs_rgb() && (crop_size < 2 || !crop_size.is_multiple_of(2)) {
            return Err(Error::InvalidOption(format!(
                "the crop size must be even and at least 2 (got {crop_size})"
            )));
        }
        let varmap = VarMap::new();
        let vb = seeded_var_builder(&varmap, seed, device);
        let net = match kind {
            ModelKind::Tnet => Net::T(TNet::new(width, 0, vb)?),
            ModelKind::Rnet => Net::R(RNet::new(width, vb)?),
            ModelKind::Full => Net::F(Full::new(width, vb)?),
            ModelKind::Rgb | ModelKind::RgbDense => unreachable!("returned above"),
        };
        Ok(PoseModel {
            kind,
            varmap,
            net,
            scale,
            crop_size,
            translation: None,
            classes: Vec::new(),
            device: device.clone(),
        })
    }

    /// A TNet conditioned on the object class (`classes`: object ids, sorted and deduplicated
    /// here); objects outside `classes` are predicted without a class.
    pub fn tnet_per_object(
        width: usize,
        scale: f32,
        classes: &[u32],
        seed: u64,
        device: &Device,
    ) -> Result<PoseModel> {
        let mut classes = classes.to_vec();
        classes.sort_unstable();
        classes.dedup();
        if classes.is_empty() {
            return Err(Error::InvalidOption(
                "a per-object tnet needs at least one object class".into(),
            ));
        }
        let varmap = VarMap::new();
        let vb = seeded_var_builder(&varmap, seed, device);
        let net = Net::T(TNet::new(width, classes.len(), vb)?);
        Ok(PoseModel {
            kind: ModelKind::Tnet,
            varmap,
            net,
            scale,
            crop_size: 0,
            translation: None,
            classes,
            device: device.clone(),
        })
    }

    /// The RGB model: `crop`-pixel inputs, fully connected `width`, one head per class
    /// (object ids; sorted and deduplicated here).
    pub fn rgb(
        translation: Translation,
        classes: &[u32],
        width: usize,
        crop: u32,
        seed: u64,
        device: &Device,
    ) -> Result<PoseModel> {
        if crop < 16 {
            return Err(Error::InvalidOption(format!(
                "the rgb model's crop size must be at least 16 (got {crop})"
            )));
        }
        let mut classes = classes.to_vec();
        classes.sort_unstable();
        classes.dedup();
        if classes.is_empty() {
            return Err(Error::InvalidOption(
                "the rgb model needs at least one object class".into(),
            ));
        }
        let varmap = VarMap::new();
        let vb = seeded_var_builder(&varmap, seed, device);
        let net = Net::G(RgbNet::new(crop, width, classes.len(), vb)?);
        Ok(PoseModel {
            kind: ModelKind::Rgb,
            varmap,
            net,
            scale: TARGET_SCALE as f32,
            crop_size: crop,
            translation: Some(translation),
            classes,
            device: device.clone(),
        })
    }

    /// The dense RGB model: `crop`-pixel inputs (a multiple of 8), a global feature of
    /// `width`, one head per class (object ids; sorted and deduplicated here).
    pub fn rgb_dense(
        classes: &[u32],
        width: usize,
        crop: u32,
        seed: u64,
        device: &Device,
    ) -> Result<PoseModel> {
        let mut classes = classes.to_vec();
        classes.sort_unstable();
        classes.dedup();
        if classes.is_empty() {
            return Err(Error::InvalidOption(
                "the rgb-dense model needs at least one object class".into(),
            ));
        }
        if crop < 16 || !crop.is_multiple_of(8) {
            return Err(Error::InvalidOption(format!(
                "the rgb-dense model's crop size must be a multiple of 8, at least 16 (got {crop})"
            )));
        }
        let varmap = VarMap::new();
        let vb = seeded_var_builder(&varmap, seed, device);
        let net = Net::D(DenseNet::new(crop, width, classes.len(), vb)?);
        Ok(PoseModel {
            kind: ModelKind::RgbDense,
            varmap,
            net,
            scale: 1.0,
            crop_size: crop,
            translation: None,
            classes,
            device: device.clone(),
        })
    }

    /// Loads every variable from `checkpoint` (it must be of the same kind and size).
    pub fn load_strict(&mut self, checkpoint: &Path) -> Result<()> {
        self.varmap.load(checkpoint).map_err(|e| Error::Malformed {
            what: "checkpoint",
            message: e.to_string(),
            path: checkpoint.to_path_buf(),
        })
    }

    /// Sets the variables that `checkpoint` holds under the same name and shape (a TNet or
    /// RNet checkpoint into Full, say); returns how many were set. None matching is an error.
    pub fn init_from(&mut self, checkpoint: &Path) -> Result<usize> {
        let malformed = |message: String| Error::Malformed {
            what: "checkpoint",
            message,
            path: checkpoint.to_path_buf(),
        };
        let tensors = candle_core::safetensors::load(checkpoint, &self.device)
            .map_err(|e| malformed(e.to_string()))?;
        let data = self
            .varmap
            .data()
            .lock()
            .map_err(|_| malformed("variable map poisoned".into()))?;
        let mut set = 0;
        for (name, var) in data.iter() {
            if let Some(t) = tensors.get(name) {
                if t.shape() == var.shape() {
                    var.set(t)?;
                    set += 1;
                }
            }
        }
        if set == 0 {
            return Err(malformed(
                "no variable matches this model's names and shapes (different --width?)".into(),
            ));
        }
        Ok(set)
    }

    /// Loss and (with `predict`) per-instance predictions of a batch. Full and RGB need
    /// `objects`.
    pub fn run(
        &self,
        batch: &[&Instance],
        objects: Option<&Objects>,
        predict: bool,
    ) -> Result<(Tensor, Vec<Prediction>)> {
        self.compute(&self.prepare(batch, objects, None)?, predict)
    }

    /// The loss of a training step: as [`PoseModel::run`], and the RGB model sees its boxes
    /// and colours jittered, drawn from (`jitter_seed`, instance).
    pub fn run_training(
        &self,
        batch: &[&Instance],
        objects: Option<&Objects>,
        jitter_seed: u64,
    ) -> Result<Tensor> {
        self.loss_of(&self.prepare(batch, objects, Some(jitter_seed))?)
    }

    /// The loss of a batch [`PoseModel::prepare`]d: the network's step alone.
    pub fn loss_of(&self, batch: &PreparedBatch) -> Result<Tensor> {
        Ok(self.compute(batch, false)?.0)
    }

    /// The network on a prepared batch: its loss and (with `predict`) the per-instance
    /// predictions.
    fn compute(&self, batch: &PreparedBatch, predict: bool) -> Result<(Tensor, Vec<Prediction>)> {
        let none = || Prediction {
            centre_m: None,
            rotation: None,
        };
        match (&self.net, &batch.inner) {
            (Net::T(net), Prepared::Points { b, class, .. }) => {
                let pred = net.forward(&b.points, class.as_ref())?;
                let loss = offset_l1_loss(&pred, &b.offsets)?;
                let preds = if predict {
                    centres_from_offsets(b, &pred, self.scale)?
                        .into_iter()
                        .map(|c| Prediction {
                            centre_m: Some(c),
                            ..none()
                        })
                        .collect()
                } else {
                    Vec::new()
                };
                Ok((loss, preds))
            }
            (
                Net::R(net),
                Prepared::Points {
                    b,
                    rgb: Some((crops, pix)),
                    target: PointTarget::Quats(q),
                    ..
                },
            ) => {
                let out = net.forward(&b.points, crops, pix)?;
                let loss = quaternion_confidence_loss(q, &out.quats, &out.conf, CONFIDENCE_WEIGHT)?;
                let preds = if predict {
                    best_rotations(&out)?
                        .into_iter()
                        .map(|r| Prediction {
                            rotation: Some(r),
                            ..none()
                        })
                        .collect()
                } else {
                    Vec::new()
                };
                Ok((loss, preds))
            }
            (
                Net::F(net),
                Prepared::Points {
                    b,
                    rgb: Some((crops, pix)),
                    target: PointTarget::Posed(model_pts, targets),
                    ..
                },
            ) => {
                let out = net.forward(&b.points, crops, pix)?;
                let loss = full_loss(
                    &out,
                    &b.points,
                    model_pts,
                    targets,
                    f64::from(self.scale),
                    CONFIDENCE_WEIGHT,
                )?;
                let preds = if predict {
                    let centres = centres_from_offsets(b, &out.offsets, self.scale)?;
                    centres
                        .into_iter()
                        .zip(best_rotations(&out.rotation)?)
                        .map(|(c, r)| Prediction {
                            centre_m: Some(c),
                            rotation: Some(r),
                        })
                        .collect()
                } else {
                    Vec::new()
                };
                Ok((loss, preds))
            }
            (
                Net::G(net),
                Prepared::Rgb {
                    samples,
                    crops,
                    geometry,
                    class,
                    targets,
                },
            ) => self.compute_rgb(net, samples, crops, geometry, class, targets, predict),
            (
                Net::D(net),
                Prepared::Dense {
                    samples,
                    crops,
                    class,
                    coords,
                    visible,
                    radii,
                    targets,
                },
            ) => {
                let result = net.forward(crops, class)?;
                let loss = ((dense_loss(&result, coords, visible)?
                    + (rotation_points_loss(
                        &result.quats,
                        &targets.model_pts,
                        &targets.r_target,
                    )? * DENSE_ROTATION_WEIGHT)?)?
                    + smooth_l1_loss(&result.translation, &targets.t_target, RGB_SMOOTH_L1_BETA)?)?;
                if !predict {
                    return Ok((loss, Vec::new()));
                }
                Ok((
                    loss,
                    dense_predictions(&result, samples, radii, &targets.rays, self.crop_size)?,
                ))
            }
            _ => Err(Error::InvalidOption(format!(
                "internal: a batch prepared for another model than this {} model",
                self.kind.name()
            ))),
        }
    }

    /// The RGB model on a prepared batch: smooth L1 on the translation targets plus the
    /// rotation's point loss; the poses along each crop's ray.
    #[allow(clippy::too_many_arguments)]
    fn compute_rgb(
        &self,
        net: &RgbNet,
        samples: &[rgb_input::RgbSample],
        crops: &Tensor,
        geometry: &Tensor,
        class: &Tensor,
        targets: &BoxTargets,
        predict: bool,
    ) -> Result<(Tensor, Vec<Prediction>)> {
        let translation = self.translation.unwrap_or(Translation::CentreTz);
        let out = net.forward(crops, geometry, class)?;
        let loss = (smooth_l1_loss(&out.translation, &targets.t_target, RGB_SMOOTH_L1_BETA)?
            + (rotation_points_loss(&out.quats, &targets.model_pts, &targets.r_target)?
                * RGB_ROTATION_WEIGHT)?)?;
        if !predict {
            return Ok((loss, Vec::new()));
        }
        let t: Vec<Vec<f32>> = out.translation.to_dtype(DType::F32)?.to_vec2()?;
        let q: Vec<Vec<f32>> = out.quats.to_dtype(DType::F32)?.to_vec2()?;
        let preds = t
            .iter()
            .zip(&q)
            .zip(samples.iter().zip(&targets.rays))
            .map(|((t, q), (s, ray))| {
                let t =
                    translation.translation([t[0], t[1], t[2]].map(f64::from), &s.bbox, &s.camera);
                let q = canonical_sign([q[0], q[1], q[2], q[3]]);
                Prediction {
                    centre_m: Some(t.as_vec3().to_array()),
                    rotation: Some((*ray * quaternion_rotation(q), 1.0)),
                }
            })
            .collect();
        Ok((loss, preds))
    }

    /// Predictions for instances, in batches.
    pub fn predict(
        &self,
        instances: &[&Instance],
        objects: Option<&Objects>,
        batch: usize,
    ) -> Result<Vec<Prediction>> {
        let mut out = Vec::with_capacity(instances.len());
        for chunk in instances.chunks(batch.max(1)) {
            out.extend(self.run(chunk, objects, true)?.1);
        }
        Ok(out)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use candle_nn::{AdamW, Optimizer, ParamsAdamW};
    use rand::{Rng, SeedableRng};
    use synthgen_core::glam::DVec3;

    /// An asymmetric "L" of model points (metres) and instances of it seen from the camera:
    /// the points facing the camera (z below the centre's), their crop positions, and a
    /// crop coloured by the model x coordinate so colour carries orientation.
    fn object() -> Vec<DVec3> {
        let mut p = Vec::new();
        for i in 0..10 {
            let s = f64::from(i) / 10.0;
            p.push(DVec3::new(-0.05 + 0.1 * s, -0.03, 0.0));
            p.push(DVec3::new(-0.05, -0.03 + 0.08 * s, 0.01));
            p.push(DVec3::new(0.02 * s, 0.01, 0.03 * s));
        }
        p
    }

    fn instance(rng: &mut rand_chacha::ChaCha8Rng, im_id: u32, crop: u32, n: usize) -> Instance {
        let r = DMat3::from_rotation_z(rng.gen_range(-0.6..0.6))
            * DMat3::from_rotation_x(rng.gen_range(-0.4..0.4));
        let t = DVec3::new(rng.gen_range(-0.1..0.1), rng.gen_range(-0.1..0.1), 0.8);
        let pose = Pose::new(r, t);
        let model = object();
        let mut points_m = Vec::new();
        let mut crop_xy = Vec::new();
        let mut crop_rgb = vec![0u8; (crop * crop * 3) as usize];
        for k in 0..n {
            let x = model[k % model.len()];
            let c = pose.transform_point(x);
            points_m.push(c.as_vec3().to_array());
            let px = (((c.x - t.x) / 0.2 + 0.5) * f64::from(crop)).clamp(0.0, f64::from(crop - 1));
            let py = (((c.y - t.y) / 0.2 + 0.5) * f64::from(crop)).clamp(0.0, f64::from(crop - 1));
            crop_xy.push([px as f32, py as f32]);
            let i = ((py as u32 * crop + px as u32) * 3) as usize;
            crop_rgb[i] = ((x.x + 0.05) * 2500.0) as u8;
            crop_rgb[i + 1] = ((x.y + 0.03) * 3000.0) as u8;
        }
        Instance {
            scene_id: 0,
            im_id,
            gt_id: 0,
            obj_id: 1,
            points_m,
            crop_xy,
            crop_rgb,
            region: None,
            pose,
        }
    }

    fn objects() -> Objects {
        let pts = object();
        BTreeMap::from([(
            1,
            TrainObject {
                loss_points_m: pts.clone(),
                symmetries: vec![Pose::IDENTITY],
                eval: EvalObject {
                    points_m: pts,
                    diameter_m: 0.12,
                    symmetric: false,
                },
            },
        )])
    }

    fn adamw(model: &PoseModel, lr: f64) -> AdamW {
        AdamW::new(
            model.varmap.all_vars(),
            ParamsAdamW {
                lr,
                ..Default::default()
            },
        )
        .unwrap()
    }

    /// The loss without jitter (the evaluation pass), as a number.
    fn eval_loss(m: &PoseModel, refs: &[&Instance], objs: &Objects) -> f32 {
        m.run(refs, Some(objs), false)
            .unwrap()
            .0
            .to_scalar::<f32>()
            .unwrap()
    }

    fn loss_after(kind: ModelKind, steps: usize) -> (f32, f32, PoseModel, Vec<Instance>) {
        let dev = Device::Cpu;
        let model = PoseModel::new(kind, 32, 10.0, 8, 0, &dev).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let insts: Vec<Instance> = (0..6).map(|i| instance(&mut rng, i, 8, 40)).collect();
        let refs: Vec<&Instance> = insts.iter().collect();
        let objs = objects();
        let mut opt = adamw(&model, 3e-3);
        let loss = |m: &PoseModel| eval_loss(m, &refs, &objs);
        let first = loss(&model);
        for _ in 0..steps {
            let (l, _) = model.run(&refs, Some(&objs), false).unwrap();
            opt.backward_step(&l).unwrap();
        }
        let last = loss(&model);
        (first, last, model, insts)
    }

    #[test]
    fn full_loss_falls_and_predicts_poses() {
        let (first, last, model, insts) = loss_after(ModelKind::Full, 60);
        assert!(last < 0.7 * first, "full loss {first} -> {last}");
        let refs: Vec<&Instance> = insts.iter().collect();
        let preds = model.predict(&refs, Some(&objects()), 4).unwrap();
        assert_eq!(preds.len(), 6);
        for p in &preds {
            assert!(p.centre_m.is_some());
            let (r, c) = p.rotation.unwrap();
            assert!((r.determinant() - 1.0).abs() < 1e-6);
            assert!(c > 0.0 && c < 1.0);
        }
    }

    #[test]
    fn rnet_loss_falls() {
        let (first, last, _, _) = loss_after(ModelKind::Rnet, 60);
        assert!(last < 0.8 * first, "rnet loss {first} -> {last}");
    }

    /// An RGB instance: the object's points projected into a 160x120 image as dots coloured
    /// by their model coordinates, the box their bounding box.
    fn rgb_instance(rng: &mut rand_chacha::ChaCha8Rng, im_id: u32) -> Instance {
        use crate::models::rgb::Pinhole;
        let r = DMat3::from_rotation_z(rng.gen_range(-0.8..0.8))
            * DMat3::from_rotation_x(rng.gen_range(-0.5..0.5));
        let t = DVec3::new(
            rng.gen_range(-0.08..0.08),
            rng.gen_range(-0.06..0.06),
            rng.gen_range(0.6..1.0),
        );
        let pose = Pose::new(r, t);
        let cam = Pinhole {
            fx: 200.0,
            fy: 190.0,
            cx: 80.0,
            cy: 60.0,
        };
        let (w, h) = (160u32, 120u32);
        let mut img = vec![20u8; (w * h * 3) as usize];
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for x in object() {
            let c = pose.transform_point(x);
            let (u, v) = (cam.fx * c.x / c.z + cam.cx, cam.fy * c.y / c.z + cam.cy);
            (x0, y0, x1, y1) = (x0.min(u), y0.min(v), x1.max(u), y1.max(v));
            for (du, dv) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (pu, pv) = (u as i64 + du, v as i64 + dv);
                if (0..i64::from(w)).contains(&pu) && (0..i64::from(h)).contains(&pv) {
                    let i = ((pv as u32 * w + pu as u32) * 3) as usize;
                    img[i] = ((x.x + 0.05) * 2500.0) as u8;
                    img[i + 1] = ((x.y + 0.03) * 3000.0) as u8;
                    img[i + 2] = ((x.z + 0.01) * 5000.0) as u8;
                }
            }
        }
        let region = crate::rgb_input::BoxRegion::from_image(
            &img,
            w,
            h,
            [x0, y0, x1 - x0, y1 - y0],
            16,
            cam,
        );
        Instance {
            scene_id: 0,
            im_id,
            gt_id: 0,
            obj_id: 1,
            points_m: vec![],
            crop_xy: vec![],
            crop_rgb: vec![],
            region: Some(region),
            pose,
        }
    }

    #[test]
    fn rgb_loss_falls_predicts_poses_and_round_trips() {
        let dev = Device::Cpu;
        let objs = objects();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let insts: Vec<Instance> = (0..6).map(|i| rgb_instance(&mut rng, i)).collect();
        let refs: Vec<&Instance> = insts.iter().collect();
        for translation in [Translation::CentreTz, Translation::Xyz] {
            let model = PoseModel::rgb(translation, &[1], 32, 16, 0, &dev).unwrap();
            let mut opt = adamw(&model, 2e-3);
            let loss = |m: &PoseModel| eval_loss(m, &refs, &objs);
            let first = loss(&model);
            for step in 0..80 {
                let l = model.run_training(&refs, Some(&objs), step).unwrap();
                opt.backward_step(&l).unwrap();
            }
            let last = loss(&model);
            assert!(last < 0.5 * first, "{translation:?}: {first} -> {last}");
            let preds = model.predict(&refs, Some(&objs), 4).unwrap();
            for p in &preds {
                let (r, c) = p.rotation.unwrap();
                assert!((r.determinant() - 1.0).abs() < 1e-6);
                assert_eq!(c, 1.0);
                assert!(p.centre_m.unwrap().iter().all(|v| v.is_finite()));
            }
            // The jittered training input differs from the evaluation input.
            let jittered = model.run_training(&refs, Some(&objs), 99).unwrap();
            assert_ne!(jittered.to_scalar::<f32>().unwrap(), last);
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("rgb.safetensors");
            model.varmap.save(&path).unwrap();
            let mut again = PoseModel::rgb(translation, &[1], 32, 16, 5, &dev).unwrap();
            again.load_strict(&path).unwrap();
            assert_eq!(again.predict(&refs, Some(&objs), 4).unwrap(), preds);
        }
        // An object without a head is an error, not a silent wrong class.
        let model = PoseModel::rgb(Translation::CentreTz, &[2], 32, 16, 0, &dev).unwrap();
        assert!(model.run(&refs, Some(&objs), false).is_err());
    }

    /// A dense-model instance: an ellipsoid (semi-axes 5, 3, 2 cm: no symmetry) ray-cast into
    /// a 200x160 image, coloured by its model coordinates, with its coordinate targets.
    fn dense_instance(rng: &mut rand_chacha::ChaCha8Rng, im_id: u32, crop: u32) -> Instance {
        use crate::models::rgb::Pinhole;
        use crate::rgb_input::{BoxRegion, CoordRegion};
        let axes = DVec3::new(0.05, 0.03, 0.02);
        let r = DMat3::from_rotation_z(rng.gen_range(-3.0..3.0))
            * DMat3::from_rotation_x(rng.gen_range(-1.2..1.2));
        let t = DVec3::new(
            rng.gen_range(-0.05..0.05),
            rng.gen_range(-0.04..0.04),
            rng.gen_range(0.5..0.8),
        );
        let pose = Pose::new(r, t);
        let cam = Pinhole {
            fx: 300.0,
            fy: 300.0,
            cx: 100.0,
            cy: 80.0,
        };
        let (w, h) = (200u32, 160u32);
        let inv = pose.inverse();
        // The ray through pixel (x, y) meets the ellipsoid at model point p (or misses).
        let hit = |x: usize, y: usize| -> Option<DVec3> {
            let d = DVec3::new(
                (x as f64 - cam.cx) / cam.fx,
                (y as f64 - cam.cy) / cam.fy,
                1.0,
            );
            let (o, d) = (
                inv.transform_point(DVec3::ZERO) / axes,
                (inv.rotation * d) / axes,
            );
            let (a, b, c) = (d.dot(d), 2.0 * o.dot(d), o.dot(o) - 1.0);
            let disc = b * b - 4.0 * a * c;
            (disc >= 0.0).then(|| (o + d * ((-b - disc.sqrt()) / (2.0 * a))) * axes)
        };
        let mut img = vec![30u8; (w * h * 3) as usize];
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for y in 0..h as usize {
            for x in 0..w as usize {
                if let Some(p) = hit(x, y) {
                    let i = (y * w as usize + x) * 3;
                    let c = (p / axes).to_array();
                    for k in 0..3 {
                        img[i + k] = (128.0 + 120.0 * c[k]) as u8;
                    }
                    (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
                }
            }
        }
        let bbox = [x0 as f64, y0 as f64, (x1 - x0) as f64, (y1 - y0) as f64];
        let mut region = BoxRegion::from_image(&img, w, h, bbox, crop, cam);
        let at = |x: usize, y: usize| hit(x, y).map_or([f32::NAN; 3], |p| p.as_vec3().to_array());
        region.target = Some(CoordRegion::sample(
            at,
            w,
            h,
            &region.region,
            crate::data::dense_target_res(crop),
        ));
        Instance {
            scene_id: 0,
            im_id,
            gt_id: 0,
            obj_id: 1,
            points_m: vec![],
            crop_xy: vec![],
            crop_rgb: vec![],
            region: Some(region),
            pose,
        }
    }

    fn ellipsoid_objects() -> Objects {
        let pts: Vec<DVec3> = (0..200)
            .map(|i| {
                let (a, b) = (f64::from(i) * 0.7, f64::from(i) * 0.31);
                DVec3::new(
                    0.05 * a.cos() * b.sin(),
                    0.03 * a.sin() * b.sin(),
                    0.02 * b.cos(),
                )
            })
            .collect();
        BTreeMap::from([(
            1,
            TrainObject {
                loss_points_m: pts.clone(),
                symmetries: vec![Pose::IDENTITY],
                eval: EvalObject {
                    points_m: pts,
                    diameter_m: 0.1,
                    symmetric: false,
                },
            },
        )])
    }

    /// The targets cut over the nominal crop, taken as a perfect network's output, give the
    /// GT pose back through PnP: the cells, boxes and pixel centres agree.
    #[test]
    fn dense_targets_as_outputs_give_the_pose_back() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for im in 0..5 {
            let inst = dense_instance(&mut rng, im, 128);
            let s = rgb_input::sample(&inst, 128, None).unwrap();
            let r = inst.region.as_ref().unwrap();
            let cells = r.target.as_ref().unwrap().cut(&r.region, &s.bbox, 32);
            let visible = cells.iter().filter(|c| c[0].is_finite()).count();
            assert!(visible > 150, "{visible} visible cells");
            let radius = 0.05;
            let coords: Vec<f32> = cells
                .iter()
                .flat_map(|c| {
                    if c[0].is_finite() {
                        c.map(|v| v / radius as f32)
                    } else {
                        [0.0; 3]
                    }
                })
                .collect();
            let logits: Vec<f32> = cells
                .iter()
                .map(|c| if c[0].is_finite() { 5.0 } else { -5.0 })
                .collect();
            // Each visible cell's target projects (GT pose) onto the cell's centre: no offset on
            // average, at most a quarter of a cell (nearest of the stored cells, two per output
            // cell) plus half a pixel (the image pixel nearest to the stored cell).
            let cell = s.bbox.side / 32.0;
            let (mut mean, mut worst) = (synthgen_core::glam::DVec2::ZERO, 0.0f64);
            for (i, c) in cells.iter().enumerate().filter(|(_, c)| c[0].is_finite()) {
                let q =
                    inst.pose
                        .transform_point(DVec3::new(c[0].into(), c[1].into(), c[2].into()));
                let d = synthgen_core::glam::DVec2::new(
                    s.camera.fx * q.x / q.z + s.camera.cx
                        - (s.bbox.cx - 0.5 * s.bbox.side + ((i % 32) as f64 + 0.5) * cell),
                    s.camera.fy * q.y / q.z + s.camera.cy
                        - (s.bbox.cy - 0.5 * s.bbox.side + ((i / 32) as f64 + 0.5) * cell),
                );
                mean += d / visible as f64;
                worst = worst.max(d.x.abs()).max(d.y.abs());
            }
            assert!(
                mean.length() < 0.05 * cell && worst < 0.25 * cell + 0.5 + 1e-9,
                "image {im}: offset {mean}, worst {worst:.2} px, cell {cell:.2} px"
            );
            let (est, conf) = dense_pnp(&coords, &logits, 32, radius, &s).unwrap();
            let re = crate::metrics::re_deg(&inst.pose.rotation, &est.rotation);
            let te = (est.translation_m - inst.pose.translation_m).length();
            // A 5 cm object over 32x32 cells with targets up to a third of a cell off: PnP's
            // depth is the weak direction (over 16x16 cells the least-squares pose of one image
            // was 37 mm deeper than the GT, at a lower reprojection error); the projection is good.
            let centre = |p: &Pose| {
                let c = p.translation_m;
                synthgen_core::glam::DVec2::new(s.camera.fx * c.x / c.z, s.camera.fy * c.y / c.z)
            };
            let centre_px = centre(&est).distance(centre(&inst.pose));
            assert!(
                re < 5.0 && te < 0.07 * inst.pose.translation_m.z && centre_px < 1.0,
                "image {im}: {re:.2}°, {:.1} mm, centre {centre_px:.2} px",
                te * 1000.0
            );
            assert!(conf > 0.9, "inlier share {conf}");
        }
    }

    #[test]
    fn dense_loss_falls_predicts_poses_and_round_trips() {
        let dev = Device::Cpu;
        let objs = ellipsoid_objects();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let insts: Vec<Instance> = (0..8).map(|i| dense_instance(&mut rng, i, 32)).collect();
        let refs: Vec<&Instance> = insts.iter().collect();
        let model = PoseModel::rgb_dense(&[1], 16, 32, 0, &dev).unwrap();
        let mut opt = adamw(&model, 3e-3);
        let first = eval_loss(&model, &refs, &objs);
        for step in 0..60 {
            let l = model.run_training(&refs, Some(&objs), step).unwrap();
            opt.backward_step(&l).unwrap();
        }
        let last = eval_loss(&model, &refs, &objs);
        assert!(last < 0.6 * first, "{first} -> {last}");
        let preds = model.predict(&refs, Some(&objs), 4).unwrap();
        assert_eq!(preds.len(), 8);
        for p in &preds {
            let (r, c) = p.rotation.unwrap();
            assert!((r.determinant() - 1.0).abs() < 1e-6);
            assert!((0.0..=1.0).contains(&c));
            assert!(p.centre_m.unwrap().iter().all(|v| v.is_finite()));
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("dense.safetensors");
        model.varmap.save(&path).unwrap();
        let mut again = PoseModel::rgb_dense(&[1], 16, 32, 9, &dev).unwrap();
        again.load_strict(&path).unwrap();
        assert_eq!(again.predict(&refs, Some(&objs), 4).unwrap(), preds);
        // Training needs targets; evaluation without them (real RGB) scores no loss but predicts.
        let mut bare = insts[0].clone();
        bare.region.as_mut().unwrap().target = None;
        assert!(model.run_training(&[&bare], Some(&objs), 0).is_err());
        assert_eq!(model.predict(&[&bare], Some(&objs), 1).unwrap().len(), 1);
        assert!(PoseModel::rgb_dense(&[1], 16, 20, 0, &dev).is_err());
    }

    #[test]
    fn checkpoint_round_trip_and_partial_init() {
        let (_, _, full, insts) = loss_after(ModelKind::Full, 3);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.safetensors");
        full.varmap.save(&path).unwrap();
        let refs: Vec<&Instance> = insts.iter().collect();
        let objs = objects();
        let mut again = PoseModel::new(ModelKind::Full, 32, 10.0, 8, 0, &Device::Cpu).unwrap();
        again.load_strict(&path).unwrap();
        let a = full.predict(&refs, Some(&objs), 8).unwrap();
        let b = again.predict(&refs, Some(&objs), 8).unwrap();
        assert_eq!(a, b);
        // A TNet takes Full's translation part (7 layers × weight + bias, one without bias).
        let mut tnet = PoseModel::new(ModelKind::Tnet, 32, 10.0, 0, 0, &Device::Cpu).unwrap();
        let n = tnet.init_from(&path).unwrap();
        assert_eq!(n, tnet.varmap.all_vars().len());
        let t = tnet.predict(&refs, None, 8).unwrap();
        for (p, q) in t.iter().zip(&a) {
            assert_eq!(p.centre_m, q.centre_m);
        }
        // Another width still shares the point stem and the CNN; a strict load refuses it.
        let mut wide = PoseModel::new(ModelKind::Rnet, 64, 10.0, 8, 0, &Device::Cpu).unwrap();
        let shared = wide.init_from(&path).unwrap();
        assert!(shared > 0 && shared < wide.varmap.all_vars().len());
        let mut strict = PoseModel::new(ModelKind::Full, 64, 10.0, 8, 0, &Device::Cpu).unwrap();
        assert!(strict.load_strict(&path).is_err());
        // A file with nothing in common is an error, not a silent no-op.
        let other = dir.path().join("other.safetensors");
        candle_core::safetensors::save(
            &std::collections::HashMap::from([(
                "unrelated".to_string(),
                Tensor::zeros(3, DType::F32, &Device::Cpu).unwrap(),
            )]),
            &other,
        )
        .unwrap();
        assert!(tnet.init_from(&other).is_err());
    }
}
