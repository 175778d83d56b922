//! The walls and the ground texture of one frame, drawn from the `[walls]` and `[ground]`
//! sections of the spec (the sampler's part; the sections themselves are `walls_spec`).

use glam::{DMat3, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::frame_scene::{SurfaceTexture, WallInstance};
use crate::pose::Pose;
use crate::range::Range;
use crate::rng::{frame_rng, Stream};
use crate::scene::SceneSpec;

fn uniform(rng: &mut ChaCha8Rng, [lo, hi]: Range) -> f64 {
    if hi > lo {
        rng.gen_range(lo..=hi)
    } else {
        lo
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
