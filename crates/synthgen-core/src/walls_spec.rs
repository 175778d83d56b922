//! The `[walls]` section of a scene spec (vertical planes of a square room around the
//! scene), the checks of the ground-texture fields, and the per-frame sampling of both
//! (kept apart from scene.rs and sample.rs to keep those files small).

use std::path::PathBuf;

use glam::{DMat3, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::pose::Pose;
use crate::rng::{frame_rng, Stream};
use crate::sample::{SurfaceTexture, WallInstance};
use crate::scene::{Range, SceneSpec};
use crate::Error;

/// Walls: up to four vertical rectangles, the sides of a square room centred on the scene
/// centre (the ground's centre), rendered as geometry (they have depth and occlude) with
/// instance id 0, never annotated. A wall the camera is not inside of is culled (not drawn).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WallSpec {
    /// Walls per frame, inclusive range, 0..4; `n` walls are `n` consecutive sides of the
    /// room. Default 0..0 (no walls).
    pub count: [u32; 2],
    /// Distance from the scene centre to each wall (half the room's side), metres. Drawn
    /// once per frame. Default 2.0..3.0.
    pub distance_m: Range,
    /// Wall height above the ground plane, metres. Default 1.0..2.5.
    pub height_m: Range,
    /// sRGB colour range per channel; one colour per frame for every wall (it multiplies
    /// the texture when `texture_dir` is set). Default a light grey-beige.
    pub color_min: [f32; 3],
    pub color_max: [f32; 3],
    /// Folder of PNG/JPEG images (relative to the spec file); each frame draws one for all
    /// its walls, each wall with its own offset. Default: none (plain colour).
    pub texture_dir: Option<PathBuf>,
    /// Side of one texture tile along the wall, metres (vertically it keeps the image's
    /// aspect ratio). Default 1.0.
    pub texture_scale_m: f64,
}

impl Default for WallSpec {
    fn default() -> Self {
        Self {
            count: [0, 0],
            distance_m: [2.0, 3.0],
            height_m: [1.0, 2.5],
            color_min: [0.55, 0.52, 0.48],
            color_max: [0.9, 0.88, 0.85],
            texture_dir: None,
            texture_scale_m: 1.0,
        }
    }
}

fn check_range(name: &str, [lo, hi]: Range, min: f64, max: f64) -> Result<(), Error> {
    if !(lo.is_finite() && hi.is_finite() && min <= lo && lo <= hi && hi <= max) {
        return Err(Error::InvalidSpec(format!(
            "{name} must be [min, max] with {min} <= min <= max <= {max}, got [{lo}, {hi}]"
        )));
    }
    Ok(())
}

fn check_colors(name: &str, lo: [f32; 3], hi: [f32; 3]) -> Result<(), Error> {
    for c in 0..3 {
        let (a, b) = (lo[c], hi[c]);
        if !(a.is_finite() && b.is_finite() && (0.0..=1.0).contains(&a) && a <= b && b <= 1.0) {
            return Err(Error::InvalidSpec(format!(
                "{name}.color_min and color_max must lie within 0..1 with min <= max per channel, got {lo:?} and {hi:?}"
            )));
        }
    }
    Ok(())
}

fn check_scale(name: &str, v: f64) -> Result<(), Error> {
    if !(v.is_finite() && (1e-3..=100.0).contains(&v)) {
        return Err(Error::InvalidSpec(format!(
            "{name} must lie within 0.001..100 metres, got {v}"
        )));
    }
    Ok(())
}

fn uniform(rng: &mut ChaCha8Rng, [lo, hi]: Range) -> f64 {
    if hi > lo {
        rng.gen_range(lo..=hi)
    } else {
        lo
    }
}

impl SceneSpec {
    /// Checks the ground texture and `[walls]` fields.
    pub(crate) fn validate_surfaces(&self) -> Result<(), Error> {
        check_scale("ground.texture_scale_m", self.ground.texture_scale_m)?;
        check_colors("ground", self.ground.color_min, self.ground.color_max)?;
        let bg = &self.background;
        check_colors("background", bg.color_min, bg.color_max)?;
        let w = &self.walls;
        if w.count[0] > w.count[1] || w.count[1] > 4 {
            return Err(Error::InvalidSpec(format!(
                "walls.count must be [min, max] with min <= max <= 4, got {:?}",
                w.count
            )));
        }
        check_range("walls.distance_m", w.distance_m, 0.05, 1000.0)?;
        check_range("walls.height_m", w.height_m, 0.01, 1000.0)?;
        check_colors("walls", w.color_min, w.color_max)?;
        check_scale("walls.texture_scale_m", w.texture_scale_m)?;
        Ok(())
    }
}

/// The ground texture draw of frame `frame` (its own stream, so the ground colour and tile
/// draws are those of a spec without a texture).
pub(crate) fn ground_texture(spec: &SceneSpec, seed: u64, frame: u64) -> Option<SurfaceTexture> {
    spec.ground.texture_dir.as_ref()?;
    let mut rng = frame_rng(seed, frame, Stream::GroundTexture);
    Some(SurfaceTexture {
        image: rng.gen(),
        offset: [rng.gen(), rng.gen()],
        scale_m: spec.ground.texture_scale_m,
    })
}

/// The walls of frame `frame` in the world frame (z up) around `center` (on the plane):
/// wall k's plane is z = 0 of `cam_from_wall` (here world_from_wall), its x axis horizontal
/// along the wall, y up, z towards the room's centre, origin at the wall's centre.
pub(crate) fn sample_walls(
    spec: &SceneSpec,
    seed: u64,
    frame: u64,
    center: DVec3,
) -> Vec<WallInstance> {
    let w = &spec.walls;
    if w.count[1] == 0 {
        return Vec::new();
    }
    let mut rng = frame_rng(seed, frame, Stream::Walls);
    let n = rng.gen_range(w.count[0]..=w.count[1]);
    let dist = uniform(&mut rng, w.distance_m);
    let height = uniform(&mut rng, w.height_m);
    let yaw = rng.gen_range(0.0..std::f64::consts::TAU);
    let t: f32 = rng.gen();
    let color = std::array::from_fn(|i| w.color_min[i] + t * (w.color_max[i] - w.color_min[i]));
    let image: u64 = rng.gen();
    (0..n)
        .map(|k| {
            let a = yaw + f64::from(k) * std::f64::consts::FRAC_PI_2;
            let outward = DVec3::new(a.cos(), a.sin(), 0.0);
            let x = DVec3::new(a.sin(), -a.cos(), 0.0);
            let rotation = DMat3::from_cols(x, DVec3::Z, -outward);
            let origin = DVec3::new(center.x, center.y, 0.0)
                + dist * outward
                + DVec3::new(0.0, 0.0, height * 0.5);
            let offset = [rng.gen(), rng.gen()];
            WallInstance {
                cam_from_wall: Pose::new(rotation, origin),
                width_m: 2.0 * dist,
                height_m: height,
                color,
                texture: w.texture_dir.as_ref().map(|_| SurfaceTexture {
                    image,
                    offset,
                    scale_m: w.texture_scale_m,
                }),
            }
        })
        .collect()
}

/// Whether a camera at `eye` (world) is inside wall `world_from_wall`'s half-space (the
/// room's side), at least 1 mm from its plane.
pub(crate) fn camera_inside(world_from_wall: &Pose, eye: DVec3) -> bool {
    let n = world_from_wall.rotation.z_axis;
    n.dot(eye - world_from_wall.translation_m) > 1e-3
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Model;
    use crate::sample::SceneObject;
    use crate::SceneSampler;

    fn sampler(toml: &str) -> SceneSampler {
        let spec = SceneSpec::from_toml_str(toml).unwrap();
        let m = Model::cuboid("box", glam::Vec3::splat(0.1));
        SceneSampler::new(spec, SceneObject::one_per_model(&[m.clone(), m]), 3).unwrap()
    }

    #[test]
    fn fields_parse_and_are_checked() {
        let s = SceneSpec::from_toml_str(
            "[ground]\ntexture_dir = \"t\"\ntexture_scale_m = 0.25\n[walls]\ncount = [1, 4]\n",
        )
        .unwrap();
        assert_eq!(s.ground.texture_scale_m, 0.25);
        assert_eq!(s.walls.count, [1, 4]);
        assert_eq!(s.walls.distance_m, [2.0, 3.0]);
        for (bad, field) in [
            ("[walls]\ncount = [1, 5]\n", "walls.count"),
            ("[walls]\ndistance_m = [0.0, 1.0]\n", "walls.distance_m"),
            ("[walls]\ncolor_max = [1.0, 2.0, 1.0]\n", "walls.color_min"),
            (
                "[ground]\ntexture_scale_m = 0.0\n",
                "ground.texture_scale_m",
            ),
            ("[walls]\ndoors = 1\n", "doors"),
        ] {
            let e = SceneSpec::from_toml_str(bad).unwrap_err().to_string();
            assert!(e.contains(field), "{bad}: {e}");
        }
    }

    #[test]
    fn textures_and_walls_use_their_own_streams() {
        let plain = sampler("");
        let textured = sampler(
            "[ground]\ntexture_dir = \"t\"\n[walls]\ncount = [2, 4]\ntexture_dir = \"w\"\n",
        );
        for f in 0..10 {
            let (a, b) = (plain.sample(f).unwrap(), textured.sample(f).unwrap());
            assert_eq!(a.objects, b.objects);
            assert_eq!(a.world_from_cam, b.world_from_cam);
            assert_eq!(a.lights, b.lights);
            let (ga, gb) = (a.ground.clone().unwrap(), b.ground.clone().unwrap());
            assert_eq!((ga.color, ga.texture_seed), (gb.color, gb.texture_seed));
            assert!(ga.texture.is_none() && gb.texture.is_some());
            assert!(a.walls.is_empty() && !b.walls.is_empty());
            // The ground reaches the walls.
            assert!(gb.size_m >= b.walls[0].width_m * std::f64::consts::SQRT_2 - 1e-9);
            assert_eq!(b, textured.sample(f).unwrap());
        }
    }

    #[test]
    fn walls_stand_on_the_plane_around_the_scene_with_the_camera_inside() {
        // Walls close enough that the camera is often outside some: those are culled.
        let s =
            sampler("[walls]\ncount = [4, 4]\ndistance_m = [0.3, 0.7]\nheight_m = [1.0, 1.0]\n");
        let (mut drawn, mut culled) = (0, 0);
        for f in 0..40 {
            let fr = s.sample(f).unwrap();
            for w in &fr.walls {
                // The camera (the origin of its frame) is on the inner side of every wall.
                let n = w.cam_from_wall.rotation.z_axis;
                assert!(n.dot(-w.cam_from_wall.translation_m) > 0.0);
                // Vertical, standing on z = 0, 1 m high, facing the scene centre.
                let world = fr.world_from_cam.compose(&w.cam_from_wall);
                assert!(world.rotation.z_axis.z.abs() < 1e-9);
                assert!((world.translation_m.z - 0.5).abs() < 1e-9);
                assert_eq!(w.height_m, 1.0);
            }
            drawn += fr.walls.len();
            culled += 4 - fr.walls.len();
        }
        assert!(drawn > 40 && culled > 5, "drawn {drawn}, culled {culled}");
    }
}
