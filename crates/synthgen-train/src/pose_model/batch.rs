//! A batch made ready for a model's network: every tensor it reads (points, crops, box
//! geometry, classes) and every target its loss compares with, built from the instances on
//! the CPU (clouds normalized, crops cut, jittered and augmented, coordinate targets cut,
//! poses turned into the loss's frame), each instance on its own in parallel.
//!
//! Preparing is apart from the step ([`PoseModel::prepare`], [`PoseModel::loss_of`]) so that
//! the trainer prepares the next batch while the network runs on this one
//! (`train::train`): the step's serial parts leave a core idle that the preparation uses.
//! What a batch holds depends only on the instances and the jitter seed, so a batch
//! prepared ahead is the one the step would have prepared itself.

use candle_core::Tensor;
use rayon::prelude::*;
use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::Pose;

use super::{class_one_hot, quaternion_wxyz, Objects, PoseModel, TrainObject};
use crate::data::Instance;
use crate::error::{Error, Result};
use crate::losses::symmetric_targets;
use crate::models::rgb::{
    box_geometry, class_indices, crops_nhwc, ray_rotation, Translation, TARGET_SCALE,
};
use crate::models::rgb_dense::{canonical_coords, dense_out};
use crate::models::rnet::pixel_indices;
use crate::models::tnet::{make_batch, TNetBatch};
use crate::models::ModelKind;
use crate::rgb_input::{self, RgbSample};

/// A batch ready for [`PoseModel::loss_of`] (and, with its instances' samples, for the
/// predictions).
pub struct PreparedBatch {
    pub(crate) len: usize,
    pub(crate) inner: Prepared,
}

impl PreparedBatch {
    /// The instances in the batch.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// The RGB models' head targets: the rays through the crops' centres, the translation
/// targets (B, 3), the rotation's model points (B, M, 3) and targets (B, K, M, 3).
pub(crate) struct BoxTargets {
    pub rays: Vec<DMat3>,
    pub t_target: Tensor,
    pub model_pts: Tensor,
    pub r_target: Tensor,
}

pub(crate) enum Prepared {
    /// TNet, RNet, Full: the normalized clouds; TNet's class rows; the crops and each
    /// point's pixel (RNet, Full); the targets.
    Points {
        b: TNetBatch,
        class: Option<Tensor>,
        rgb: Option<(Tensor, Tensor)>,
        target: PointTarget,
    },
    /// The RGB model: crops, box geometry, class indices, head targets.
    Rgb {
        samples: Vec<RgbSample>,
        crops: Tensor,
        geometry: Tensor,
        class: Tensor,
        targets: BoxTargets,
    },
    /// The dense RGB model: as the RGB model's, and the coordinate targets over each
    /// object's radius (B, S, S, 3) with their visibility (B, S, S).
    Dense {
        samples: Vec<RgbSample>,
        crops: Tensor,
        class: Tensor,
        coords: Tensor,
        visible: Tensor,
        radii: Vec<f64>,
        targets: BoxTargets,
    },
}

pub(crate) enum PointTarget {
    /// TNet's offsets are in the cloud batch.
    Offsets,
    /// RNet: the GT rotations as quaternions (B, 4).
    Quats(Tensor),
    /// Full: model points (B, M, 3) and their targets (B, K, M, 3) in the normalized frame.
    Posed(Tensor, Tensor),
}

fn needs_objects<'a>(objects: Option<&'a Objects>, what: &str) -> Result<&'a Objects> {
    objects
        .ok_or_else(|| Error::InvalidOption(format!("the {what} model needs the objects' models")))
}

impl PoseModel {
    /// `batch` made ready for the network ([`PreparedBatch`]); with `jitter_seed` (training)
    /// the RGB models' boxes and colours jittered and augmented, TNet's classes dropped out,
    /// drawn from (seed, instance). Full and the RGB models need `objects`.
    pub fn prepare(
        &self,
        batch: &[&Instance],
        objects: Option<&Objects>,
        jitter_seed: Option<u64>,
    ) -> Result<PreparedBatch> {
        let inner = match self.kind {
            ModelKind::Rgb => {
                self.prepare_rgb(batch, needs_objects(objects, "rgb")?, jitter_seed)?
            }
            ModelKind::RgbDense => {
                self.prepare_dense(batch, needs_objects(objects, "rgb-dense")?, jitter_seed)?
            }
            ModelKind::Tnet | ModelKind::Rnet | ModelKind::Full => {
                self.prepare_points(batch, objects, jitter_seed)?
            }
        };
        Ok(PreparedBatch {
            len: batch.len(),
            inner,
        })
    }

    fn prepare_points(
        &self,
        batch: &[&Instance],
        objects: Option<&Objects>,
        jitter_seed: Option<u64>,
    ) -> Result<Prepared> {
        let clouds: Vec<&[[f32; 3]]> = batch.iter().map(|i| i.points_m.as_slice()).collect();
        let centres: Vec<[f32; 3]> = batch
            .iter()
            .map(|i| i.pose.translation_m.as_vec3().to_array())
            .collect();
        let b = make_batch(&clouds, Some(&centres), self.scale, &self.device)?;
        let rgb = || -> Result<(Tensor, Tensor)> {
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
                crops_nhwc(&crops, self.crop_size, &self.device)?,
                pixel_indices(&xys, self.crop_size, &self.device)?,
            ))
        };
        Ok(match self.kind {
            ModelKind::Rnet => {
                let q: Vec<f32> = batch
                    .iter()
                    .flat_map(|i| quaternion_wxyz(&i.pose.rotation).map(|v| v as f32))
                    .collect();
                let q = Tensor::from_vec(q, (batch.len(), 4), &self.device)?;
                Prepared::Points {
                    b,
                    class: None,
                    rgb: Some(rgb()?),
                    target: PointTarget::Quats(q),
                }
            }
            ModelKind::Full => {
                let objects = needs_objects(objects, "full")?;
                // The GT poses in the normalized frame: centred on the cloud's mean, scaled.
                let s = f64::from(self.scale);
                let poses: Vec<Pose> = batch
                    .iter()
                    .zip(&b.means_m)
                    .map(|(i, m)| {
                        let mean = DVec3::new(m[0].into(), m[1].into(), m[2].into());
                        Pose::new(i.pose.rotation, (i.pose.translation_m - mean) * s)
                    })
                    .collect();
                let (model_pts, targets) = self.posed_targets(batch, &poses, s, objects)?;
                Prepared::Points {
                    b,
                    class: None,
                    rgb: Some(rgb()?),
                    target: PointTarget::Posed(model_pts, targets),
                }
            }
            _ => {
                let class = (!self.classes.is_empty())
                    .then(|| class_one_hot(batch, &self.classes, jitter_seed, &self.device))
                    .transpose()?;
                Prepared::Points {
                    b,
                    class,
                    rgb: None,
                    target: PointTarget::Offsets,
                }
            }
        })
    }

    fn samples(&self, batch: &[&Instance], jitter_seed: Option<u64>) -> Result<Vec<RgbSample>> {
        batch
            .par_iter()
            .map(|i| {
                rgb_input::sample(i, self.crop_size, jitter_seed).ok_or_else(|| {
                    Error::InvalidOption(format!(
                        "instance (scene {}, image {}, gt {}) has no box region; load the data with an rgb box size",
                        i.scene_id, i.im_id, i.gt_id
                    ))
                })
            })
            .collect()
    }

    fn prepare_rgb(
        &self,
        batch: &[&Instance],
        objects: &Objects,
        jitter_seed: Option<u64>,
    ) -> Result<Prepared> {
        let translation = self.translation.unwrap_or(Translation::CentreTz);
        let samples = self.samples(batch, jitter_seed)?;
        let crops: Vec<&[u8]> = samples.iter().map(|s| s.crop.as_slice()).collect();
        let crops = crops_nhwc(&crops, self.crop_size, &self.device)?;
        let geometry: Vec<f32> = samples
            .iter()
            .flat_map(|s| box_geometry(&s.bbox, &s.camera))
            .collect();
        let geometry = Tensor::from_vec(geometry, (batch.len(), 3), &self.device)?;
        let obj_ids: Vec<u32> = batch.iter().map(|i| i.obj_id).collect();
        let class = class_indices(&obj_ids, &self.classes, &self.device)?;
        let targets = self.box_targets(batch, &samples, translation, objects)?;
        Ok(Prepared::Rgb {
            samples,
            crops,
            geometry,
            class,
            targets,
        })
    }

    /// The dense model's crops (with `jitter_seed`, jittered boxes and colours and
    /// [`rgb_input::dense_augment`]), the targets cut from each instance's
    /// [`rgb_input::CoordRegion`] over the same box (canonical for symmetric objects, over the
    /// object's radius). Instances without targets (real frames without depth) add nothing to
    /// the loss; a training step needs them all.
    fn prepare_dense(
        &self,
        batch: &[&Instance],
        objects: &Objects,
        jitter_seed: Option<u64>,
    ) -> Result<Prepared> {
        let out = dense_out(self.crop_size);
        let cells = (out * out) as usize;
        // Each instance's crop, augmentation and targets on its own (seeded by the instance):
        // in parallel, in the batch's order.
        let per_instance: Vec<(RgbSample, Vec<[f32; 3]>, f64)> = batch
            .par_iter()
            .map(|i| {
                let what = || {
                    format!(
                        "instance (scene {}, image {}, gt {})",
                        i.scene_id, i.im_id, i.gt_id
                    )
                };
                let mut s = rgb_input::sample(i, self.crop_size, jitter_seed).ok_or_else(|| {
                    Error::InvalidOption(format!(
                        "{} has no box region; load the data with an rgb box size",
                        what()
                    ))
                })?;
                let obj = objects.get(&i.obj_id).ok_or_else(|| {
                    Error::InvalidOption(format!("no model loaded for object {}", i.obj_id))
                })?;
                let radius = (0.5 * obj.eval.diameter_m).max(1e-6);
                let region = i
                    .region
                    .as_ref()
                    .ok_or_else(|| Error::InvalidOption(what()))?;
                let mut t = match &region.target {
                    Some(t) => t.cut(&region.region, &s.bbox, out),
                    None if jitter_seed.is_some() => {
                        return Err(Error::InvalidOption(format!(
                            "{} has no coordinate targets: the rgb-dense model trains on frames with depth (every synthgen render has it)",
                            what()
                        )))
                    }
                    None => vec![[f32::NAN; 3]; cells],
                };
                if let Some(seed) = jitter_seed {
                    rgb_input::dense_augment(&mut s.crop, self.crop_size, &mut t, out, seed, i);
                }
                canonical_coords(&mut t, &i.pose, &obj.symmetries);
                Ok((s, t, radius))
            })
            .collect::<Result<_>>()?;
        let mut samples = Vec::with_capacity(batch.len());
        let mut coords = Vec::with_capacity(batch.len() * cells * 3);
        let mut visible = Vec::with_capacity(batch.len() * cells);
        let mut radii = Vec::with_capacity(batch.len());
        for (s, t, radius) in per_instance {
            for c in &t {
                let v = c[0].is_finite();
                visible.push(if v { 1f32 } else { 0.0 });
                coords.extend(c.map(|x| {
                    if v {
                        (f64::from(x) / radius) as f32
                    } else {
                        0.0
                    }
                }));
            }
            radii.push(radius);
            samples.push(s);
        }
        let crops: Vec<&[u8]> = samples.iter().map(|s| s.crop.as_slice()).collect();
        let crops = crops_nhwc(&crops, self.crop_size, &self.device)?;
        let ids: Vec<u32> = batch.iter().map(|i| i.obj_id).collect();
        let class = class_indices(&ids, &self.classes, &self.device)?;
        let o = out as usize;
        let targets = self.box_targets(batch, &samples, Translation::CentreTz, objects)?;
        Ok(Prepared::Dense {
            crops,
            class,
            coords: Tensor::from_vec(coords, (batch.len(), o, o, 3), &self.device)?,
            visible: Tensor::from_vec(visible, (batch.len(), o, o), &self.device)?,
            radii,
            samples,
            targets,
        })
    }

    /// The RGB models' head targets for crops `samples` of `batch`: the rays through the
    /// crops' centres ([`ray_rotation`]), the translation targets (B, 3) in `translation`'s
    /// parametrization, and the rotation's model points and targets ([`Self::posed_targets`]
    /// at [`TARGET_SCALE`]) for the GT's allocentric rotation (as seen along the ray) about
    /// the model's origin.
    fn box_targets(
        &self,
        batch: &[&Instance],
        samples: &[RgbSample],
        translation: Translation,
        objects: &Objects,
    ) -> Result<BoxTargets> {
        let t_target: Vec<f32> = batch
            .iter()
            .zip(samples)
            .flat_map(|(i, s)| {
                translation
                    .target(i.pose.translation_m, &s.bbox, &s.camera)
                    .map(|v| v as f32)
            })
            .collect();
        let t_target = Tensor::from_vec(t_target, (batch.len(), 3), &self.device)?;
        let rays: Vec<DMat3> = samples
            .iter()
            .map(|s| ray_rotation(&s.bbox, &s.camera))
            .collect();
        let poses: Vec<Pose> = batch
            .iter()
            .zip(&rays)
            .map(|(i, ray)| Pose::new(ray.transpose() * i.pose.rotation, DVec3::ZERO))
            .collect();
        let (model_pts, r_target) = self.posed_targets(batch, &poses, TARGET_SCALE, objects)?;
        Ok(BoxTargets {
            rays,
            t_target,
            model_pts,
            r_target,
        })
    }

    /// Model points scaled by `scale` (B, M, 3) and their targets (B, K, M, 3) under `poses`
    /// (one per instance, already in the frame the loss works in: Full's normalized frame,
    /// the RGB model's rotation-only one), composed with each of the object's symmetries.
    /// Objects with fewer symmetries repeat their identity target (that leaves the minimum
    /// unchanged).
    fn posed_targets(
        &self,
        batch: &[&Instance],
        poses: &[Pose],
        scale: f64,
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
        let s = scale;
        let mut pts = Vec::with_capacity(batch.len() * m * 3);
        let mut tgt = Vec::with_capacity(batch.len() * k * m * 3);
        for (obj, pose) in objs.iter().zip(poses) {
            let p = &obj.loss_points_m[..m];
            pts.extend(p.iter().flat_map(|v| (*v * s).to_array().map(|x| x as f32)));
            // Scale the object too: y = s·(R S x + t − mean) = R S (s x) + s (t − mean) for
            // the rotation part of S; S's translation scales with the points.
            let scaled_syms: Vec<Pose> = obj
                .symmetries
                .iter()
                .map(|sym| Pose::new(sym.rotation, sym.translation_m * s))
                .collect();
            let scaled_pts: Vec<DVec3> = p.iter().map(|v| *v * s).collect();
            let mut t = symmetric_targets(&scaled_pts, pose, &scaled_syms);
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
}
