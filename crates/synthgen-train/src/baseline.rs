//! The naive RGB baseline: what a box alone says about a pose. Per object, the mean of what
//! the RGB models' heads are trained to predict — the rotation relative to the ray through
//! the box centre (allocentric) and the centre + Tz target of the box — over training
//! instances; at test time that mean, read back through each test box. No image content is
//! used: a model that does not beat it has learned nothing from the pixels.

use std::collections::BTreeMap;

use synthgen_core::glam::DMat3;
use synthgen_core::pose::nearest_rotation;

use crate::data::Instance;
use crate::models::rgb::{ray_rotation, Translation};
use crate::pose_model::Prediction;

/// Per object: the chordal mean of the allocentric rotations and the mean centre + Tz target.
#[derive(Debug, Clone, PartialEq)]
pub struct MeanBoxPose {
    per_object: BTreeMap<u32, (DMat3, [f64; 3])>,
}

impl MeanBoxPose {
    /// The means over `instances` with a box region (others are ignored). Objects whose
    /// rotations average to nothing (a degenerate sum) get the identity.
    pub fn fit<'a>(instances: impl IntoIterator<Item = &'a Instance>) -> MeanBoxPose {
        let mut sums: BTreeMap<u32, (DMat3, [f64; 3], usize)> = BTreeMap::new();
        for inst in instances {
            let Some(r) = &inst.region else { continue };
            let allo = ray_rotation(&r.nominal, &r.camera).transpose() * inst.pose.rotation;
            let t = Translation::CentreTz.target(inst.pose.translation_m, &r.nominal, &r.camera);
            let e = sums
                .entry(inst.obj_id)
                .or_insert((DMat3::ZERO, [0.0; 3], 0));
            e.0 += allo;
            for (a, v) in e.1.iter_mut().zip(t) {
                *a += v;
            }
            e.2 += 1;
        }
        let per_object = sums
            .into_iter()
            .map(|(id, (r, t, n))| {
                let r = nearest_rotation(&(r * (1.0 / n as f64))).unwrap_or(DMat3::IDENTITY);
                (id, (r, t.map(|v| v / n as f64)))
            })
            .collect();
        MeanBoxPose { per_object }
    }

    /// The objects it has a mean for.
    pub fn obj_ids(&self) -> Vec<u32> {
        self.per_object.keys().copied().collect()
    }

    /// The baseline's pose for a test instance: its object's means through its box; `None`
    /// for an object without training instances or an instance without a box region.
    pub fn predict(&self, inst: &Instance) -> Option<Prediction> {
        let r = inst.region.as_ref()?;
        let (allo, t) = self.per_object.get(&inst.obj_id)?;
        let rotation = ray_rotation(&r.nominal, &r.camera) * *allo;
        let t = Translation::CentreTz.translation(*t, &r.nominal, &r.camera);
        Some(Prediction {
            centre_m: Some(t.to_array().map(|v| v as f32)),
            rotation: Some((rotation, 1.0)),
        })
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use crate::models::rgb::{Pinhole, SquareBox};
    use crate::rgb_input::BoxRegion;
    use synthgen_core::glam::DVec3;
    use synthgen_core::Pose;

    fn instance(obj_id: u32, pose: Pose, b: SquareBox) -> Instance {
        let camera = Pinhole {
            fx: 600.0,
            fy: 600.0,
            cx: 320.0,
            cy: 240.0,
        };
        Instance {
            scene_id: 0,
            im_id: 0,
            gt_id: 0,
            obj_id,
            points_m: Vec::new(),
            crop_xy: Vec::new(),
            crop_rgb: Vec::new(),
            region: Some(BoxRegion {
                rgb: Vec::new(),
                res: 0,
                nominal: b,
                region: b,
                camera,
                target: None,
            }),
            pose,
        }
    }

    /// The box a pose's centre projects to the middle of, `side` px.
    fn box_of(pose: &Pose, side: f64) -> SquareBox {
        let t = pose.translation_m;
        SquareBox {
            cx: 600.0 * t.x / t.z + 320.0,
            cy: 600.0 * t.y / t.z + 240.0,
            side,
        }
    }

    #[test]
    fn one_view_seen_from_elsewhere_keeps_its_allocentric_rotation_and_depth() {
        // Trained on an object straight ahead at 0.8 m (box 100 px): a test box elsewhere in
        // the image, twice as large, gets the same rotation relative to its ray and half the
        // depth.
        let r = DMat3::from_rotation_y(0.4) * DMat3::from_rotation_x(0.3);
        let train = Pose::new(r, DVec3::new(0.0, 0.0, 0.8));
        let m = MeanBoxPose::fit([&instance(3, train, box_of(&train, 100.0))]);
        assert_eq!(m.obj_ids(), vec![3]);
        let t_test = DVec3::new(0.1, -0.05, 0.4);
        let b = box_of(&Pose::new(DMat3::IDENTITY, t_test), 200.0);
        let test = instance(3, Pose::new(DMat3::IDENTITY, t_test), b);
        let p = m.predict(&test).unwrap();
        let c = p.centre_m.unwrap();
        let c = DVec3::new(c[0].into(), c[1].into(), c[2].into());
        assert!((c - t_test).length() < 1e-5, "{c} vs {t_test}");
        let ray = ray_rotation(&b, &test.region.as_ref().unwrap().camera);
        let allo = ray.transpose() * p.rotation.unwrap().0;
        assert!((allo - r).to_cols_array().iter().all(|v| v.abs() < 1e-9));
        // No mean for an object it never saw.
        assert!(m.predict(&instance(4, train, b)).is_none());
    }

    #[test]
    fn the_mean_of_two_rotations_lies_between_them() {
        let t = DVec3::new(0.0, 0.0, 1.0);
        let a = Pose::new(DMat3::from_rotation_z(0.2), t);
        let b = Pose::new(DMat3::from_rotation_z(-0.6), t);
        let m = MeanBoxPose::fit([
            &instance(1, a, box_of(&a, 80.0)),
            &instance(1, b, box_of(&b, 120.0)),
        ]);
        let p = m.predict(&instance(1, a, box_of(&a, 100.0))).unwrap();
        let r = p.rotation.unwrap().0;
        let angle = r.x_axis.y.atan2(r.x_axis.x);
        assert!((angle - -0.2).abs() < 1e-9, "{angle}");
        // Tz: box 80 at 1 m and 120 at 1 m average to Tz·side = 100 → 1 m at side 100.
        assert!((f64::from(p.centre_m.unwrap()[2]) - 1.0).abs() < 1e-6);
    }
}
