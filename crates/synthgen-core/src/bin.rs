//! The bin of one frame (`[bin]`): its walls as unannotated instances, tinted per frame (the
//! sampler's part; the section itself is `bin_spec`).

use glam::DMat3;
use rand::Rng;

use crate::color::srgb_to_linear;
use crate::frame_scene::ObjectInstance;
use crate::pose::Pose;
use crate::rng::{frame_rng, Stream};
use crate::scene::SceneSpec;

/// The bin walls of frame `frame` as unannotated instances (world frame in `cam_from_obj`),
/// their models at `first_model` (x walls) and `first_model + 1` (y walls).
pub(crate) fn bin_instances(
    spec: &SceneSpec,
    seed: u64,
    frame: u64,
    first_model: usize,
) -> Vec<ObjectInstance> {
    let b = &spec.bin;
    let mut rng = frame_rng(seed, frame, Stream::Bin);
    let t: f32 = rng.gen();
    let tint = std::array::from_fn(|i| {
        srgb_to_linear(b.color_min[i] + t * (b.color_max[i] - b.color_min[i]))
    });
    b.walls()
        .iter()
        .map(|w| ObjectInstance {
            specular: 0.1,
            shininess: 16.0,
            tint,
            ..ObjectInstance::new(
                first_model + w.model,
                0,
                Pose::new(DMat3::IDENTITY, w.center_m),
            )
        })
        .collect()
}
