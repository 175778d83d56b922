//! One trained pose model of any kind (TNet, RNet, Full) with its variables: batching of
//! instances into tensors, loss, and per-instance predictions; checkpoints (strict load,
//! and partial initialization from another kind's checkpoint).

use std::collections::BTreeMap;
use std::path::Path;

use candle_core::{DType, Device, Tensor};
use candle_nn::VarMap;
use synthgen_core::glam::{DMat3, DQuat, DVec3};
use synthgen_core::Pose;
use synthgen_dataset::bop::ModelInfo;
use synthgen_dataset::source::FrameSource;

use crate::data::Instance;
use crate::error::{Error, Result};
use crate::eval::{eval_object, load_each_object};
use crate::init::seeded_var_builder;
use crate::losses::{quaternion_confidence_loss, symmetric_targets, symmetry_poses};
use crate::metrics::{subsample_vertices, EvalObject};
use crate::models::full::{full_loss, Full};
use crate::models::rnet::{crops_tensor, pixel_indices, RNet, RotationOut, CONFIDENCE_WEIGHT};
use crate::models::tnet::{centres_from_offsets, make_batch, offset_l1_loss, TNet};
use crate::models::ModelKind;

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

/// Loads the objects `obj_ids` from models_info and the model files (millimetres).
pub fn load_objects(
    models_info: Option<&BTreeMap<u32, ModelInfo>>,
    info_path: &Path,
    model_path: &dyn Fn(u32) -> std::path::PathBuf,
    obj_ids: impl IntoIterator<Item = u32>,
    loss_points: usize,
) -> Result<Objects> {
    load_each_object(
        models_info,
        info_path,
        model_path,
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
    load_objects(
        ds.models_info(),
        &ds.models_info_path(),
        &|id| ds.model_file(id),
        obj_ids,
        loss_points,
    )
}

enum Net {
    T(TNet),
    R(RNet),
    F(Full),
}

/// A model with its variables.
pub struct PoseModel {
    pub kind: ModelKind,
    pub varmap: VarMap,
    net: Net,
    /// Point normalization scale (1/m).
    pub scale: f32,
    /// RGB crop side (RNet, Full).
    pub crop_size: u32,
    pub device: Device,
}

/// One instance's prediction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prediction {
    /// Centre (metres): TNet and Full.
    pub centre_m: Option<[f32; 3]>,
    /// Rotation of the most confident pixel and its confidence: RNet and Full.
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
        if kind.needs_rgb() && (crop_size < 2 || !crop_size.is_multiple_of(2)) {
            return Err(Error::InvalidOption(format!(
                "the crop size must be even and at least 2 (got {crop_size})"
            )));
        }
        let varmap = VarMap::new();
        let vb = seeded_var_builder(&varmap, seed, device);
        let net = match kind {
            ModelKind::Tnet => Net::T(TNet::new(width, vb)?),
            ModelKind::Rnet => Net::R(RNet::new(width, vb)?),
            ModelKind::Full => Net::F(Full::new(width, vb)?),
        };
        Ok(PoseModel {
            kind,
            varmap,
            net,
            scale,
            crop_size,
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

    /// Loss and (with `predict`) per-instance predictions of a batch. Full needs `objects`.
    pub fn run(
        &self,
        batch: &[&Instance],
        objects: Option<&Objects>,
        predict: bool,
    ) -> Result<(Tensor, Vec<Prediction>)> {
        let clouds: Vec<&[[f32; 3]]> = batch.iter().map(|i| i.points_m.as_slice()).collect();
        let centres: Vec<[f32; 3]> = batch
            .iter()
            .map(|i| i.pose.translation_m.as_vec3().to_array())
            .collect();
        let b = make_batch(&clouds, Some(&centres), self.scale, &self.device)?;
        let rgb = |_: ()| -> Result<(Tensor, Tensor)> {
            let mut crops = Vec::with_capacity(batch.len());
            let mut xys = Vec::with_capacity(batch.len());
            for i in batch {
                if i.crop_rgb.is_empty() || i.crop_xy.len() != i.points_m.len() {
                    return Err(Error::InvalidOption(format!(
                        "instance (scene {}, image {}, gt {}) has no RGB crop; load the data with a crop size",
                        i.scene_id, i.im_id, i.gt_id
                    )));
                }
                crops.push(i.crop_rgb.as_slice());
                xys.push(i.crop_xy.as_slice());
            }
            Ok((
                crops_tensor(&crops, self.crop_size, &self.device)?,
                pixel_indices(&xys, self.crop_size, &self.device)?,
            ))
        };
        let none = || Prediction {
            centre_m: None,
            rotation: None,
        };
        match &self.net {
            Net::T(net) => {
                let pred = net.forward(&b.points)?;
                let loss = offset_l1_loss(&pred, &b.offsets)?;
                let preds = if predict {
                    centres_from_offsets(&b, &pred, self.scale)?
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
            Net::R(net) => {
                let (crops, pix) = rgb(())?;
                let out = net.forward(&b.points, &crops, &pix)?;
                let q: Vec<f32> = batch
                    .iter()
                    .flat_map(|i| quaternion_wxyz(&i.pose.rotation).map(|v| v as f32))
                    .collect();
                let q = Tensor::from_vec(q, (batch.len(), 4), &self.device)?;
                let loss =
                    quaternion_confidence_loss(&q, &out.quats, &out.conf, CONFIDENCE_WEIGHT)?;
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
            Net::F(net) => {
                let objects = objects.ok_or_else(|| {
                    Error::InvalidOption("the full model needs the objects' models".into())
                })?;
                let (crops, pix) = rgb(())?;
                let out = net.forward(&b.points, &crops, &pix)?;
                let (model_pts, targets) = self.full_targets(batch, &b.means_m, objects)?;
                let loss = full_loss(
                    &out,
                    &b.points,
                    &model_pts,
                    &targets,
                    f64::from(self.scale),
                    CONFIDENCE_WEIGHT,
                )?;
                let preds = if predict {
                    let centres = centres_from_offsets(&b, &out.offsets, self.scale)?;
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
        }
    }

    /// Full's model points (B, M, 3) and targets (B, K, M, 3) in the normalized frame. Objects
    /// with fewer symmetries repeat their identity target (that leaves the minimum unchanged).
    fn full_targets(
        &self,
        batch: &[&Instance],
        means_m: &[[f32; 3]],
        objects: &Objects,
    ) -> Result<(Tensor, Tensor)> {
        let objs: Vec<&TrainObject> = batch
            .iter()
            .map(|i| {
                objects.get(&i.obj_id).ok_or_else(|| {
                    Error::InvalidOption(format!("no model loaded for object {}", i.obj_id))
                })
            })
            .collect::<Result<_>>()?;
        let m = objs
            .iter()
            .map(|o| o.loss_points_m.len())
            .min()
            .unwrap_or(0);
        if m == 0 {
            return Err(Error::InvalidOption("an object model has no points".into()));
        }
        let k = objs.iter().map(|o| o.symmetries.len()).max().unwrap_or(1);
        let s = f64::from(self.scale);
        let mut pts = Vec::with_capacity(batch.len() * m * 3);
        let mut tgt = Vec::with_capacity(batch.len() * k * m * 3);
        for ((inst, obj), mean) in batch.iter().zip(&objs).zip(means_m) {
            let p = &obj.loss_points_m[..m];
            pts.extend(p.iter().flat_map(|v| (*v * s).to_array().map(|x| x as f32)));
            let mean = DVec3::new(mean[0].into(), mean[1].into(), mean[2].into());
            let shifted = Pose::new(inst.pose.rotation, (inst.pose.translation_m - mean) * s);
            // Scale the object too: y = s·(R S x + t − mean) = R S (s x) + s (t − mean) for
            // the rotation part of S; S's translation scales with the points.
            let scaled_syms: Vec<Pose> = obj
                .symmetries
                .iter()
                .map(|sym| Pose::new(sym.rotation, sym.translation_m * s))
                .collect();
            let scaled_pts: Vec<DVec3> = p.iter().map(|v| *v * s).collect();
            let mut t = symmetric_targets(&scaled_pts, &shifted, &scaled_syms);
            let one = m * 3;
            while t.len() < k * one {
                t.extend_from_within(0..one);
            }
            tgt.extend(t);
        }
        Ok((
            Tensor::from_vec(pts, (batch.len(), m, 3), &self.device)?,
            Tensor::from_vec(tgt, (batch.len(), k, m, 3), &self.device)?,
        ))
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

    fn loss_after(kind: ModelKind, steps: usize) -> (f32, f32, PoseModel, Vec<Instance>) {
        let dev = Device::Cpu;
        let model = PoseModel::new(kind, 32, 10.0, 8, 0, &dev).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let insts: Vec<Instance> = (0..6).map(|i| instance(&mut rng, i, 8, 40)).collect();
        let refs: Vec<&Instance> = insts.iter().collect();
        let objs = objects();
        let mut opt = AdamW::new(
            model.varmap.all_vars(),
            ParamsAdamW {
                lr: 3e-3,
                ..Default::default()
            },
        )
        .unwrap();
        let loss = |m: &PoseModel| {
            m.run(&refs, Some(&objs), false)
                .unwrap()
                .0
                .to_scalar::<f32>()
                .unwrap()
        };
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
