//! The `[bin]` section of a scene spec: an open box (four walls on the ground plane) centred
//! on the world origin, around the placement area. Physics keeps settling objects inside it
//! (static cuboid colliders, synthgen-physics); the renderer draws its walls as unannotated
//! geometry (they join `FrameScene::distractors` with obj_id 0).

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

use crate::mesh::Model;
use crate::Error;

/// A bin: four walls standing on z = 0 around the rectangle `size_m` centred on the world
/// origin (the placement area's centre). Default off.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BinSpec {
    /// Draw and simulate the bin. Default false.
    pub enabled: bool,
    /// Inner size (x, y), metres. Default 0.4 x 0.3.
    pub size_m: [f64; 2],
    /// Wall height above the ground, metres. Default 0.12.
    pub height_m: f64,
    /// Wall thickness, metres. Default 0.01.
    pub thickness_m: f64,
    /// sRGB colour range per channel, one colour per frame. Default a blue-grey plastic.
    pub color_min: [f32; 3],
    pub color_max: [f32; 3],
}

impl Default for BinSpec {
    fn default() -> Self {
        Self {
            enabled: false,
            size_m: [0.4, 0.3],
            height_m: 0.12,
            thickness_m: 0.01,
            color_min: [0.2, 0.3, 0.45],
            color_max: [0.35, 0.45, 0.65],
        }
    }
}

/// One wall of the bin: an axis-aligned box in the world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BinWall {
    /// Centre of the box, world frame, metres.
    pub center_m: DVec3,
    /// Full size of the box along x, y, z, metres.
    pub size_m: DVec3,
    /// 0 for the two walls across x (at ±x), 1 for those across y: the index of its model
    /// among [`BinSpec::models`].
    pub model: usize,
}

impl BinSpec {
    /// The four walls (at -x, +x, -y, +y). The x walls are as long as the bin's outside so
    /// the corners are closed.
    pub fn walls(&self) -> Vec<BinWall> {
        let [x, y] = self.size_m;
        let (t, h) = (self.thickness_m, self.height_m);
        let xw = DVec3::new(t, y + 2.0 * t, h);
        let yw = DVec3::new(x, t, h);
        let ox = 0.5 * (x + t);
        let oy = 0.5 * (y + t);
        vec![
            BinWall {
                center_m: DVec3::new(-ox, 0.0, 0.5 * h),
                size_m: xw,
                model: 0,
            },
            BinWall {
                center_m: DVec3::new(ox, 0.0, 0.5 * h),
                size_m: xw,
                model: 0,
            },
            BinWall {
                center_m: DVec3::new(0.0, -oy, 0.5 * h),
                size_m: yw,
                model: 1,
            },
            BinWall {
                center_m: DVec3::new(0.0, oy, 0.5 * h),
                size_m: yw,
                model: 1,
            },
        ]
    }

    /// The two wall meshes (x walls, y walls), white: each frame's colour is the instance
    /// tint.
    pub fn models(&self) -> Vec<Model> {
        let walls = self.walls();
        [0, 2]
            .iter()
            .map(|&i| {
                let s = walls[i].size_m.as_vec3();
                let mut m = Model::cuboid(
                    &format!("bin_wall_{}", if i == 0 { "x" } else { "y" }),
                    Vec3::new(s.x, s.y, s.z),
                );
                for p in &mut m.primitives {
                    p.material.base_color = [1.0; 3];
                }
                m
            })
            .collect()
    }

    pub(crate) fn validate(&self) -> Result<(), Error> {
        let [x, y] = self.size_m;
        let ok = |v: f64| v.is_finite() && v > 0.0 && v <= 100.0;
        if !(ok(x) && ok(y) && ok(self.height_m) && ok(self.thickness_m)) {
            return Err(Error::InvalidSpec(format!(
                "bin.size_m, bin.height_m and bin.thickness_m must be finite, > 0 and <= 100 metres, got {:?}, {}, {}",
                self.size_m, self.height_m, self.thickness_m
            )));
        }
        for c in 0..3 {
            let (a, b) = (self.color_min[c], self.color_max[c]);
            if !(a.is_finite() && b.is_finite() && (0.0..=1.0).contains(&a) && a <= b && b <= 1.0) {
                return Err(Error::InvalidSpec(format!(
                    "bin.color_min and color_max must lie within 0..1 with min <= max per channel, got {:?} and {:?}",
                    self.color_min, self.color_max
                )));
            }
        }
        Ok(())
    }
}
