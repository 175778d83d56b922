//! What one sampled frame holds, for the renderers: the objects to place and their placed
//! instances, lights, ground, walls, background, and the frame itself ([`FrameScene`]). The
//! sampler (`sample`) makes them; `view`, `distractor`, `bin` and `walls` fill in parts.

use std::sync::Arc;

use glam::{DMat3, DVec3, Vec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::camera::Intrinsics;
use crate::pose::Pose;
use crate::rest::{upright_rotation, UpAxis};
use crate::scene::BackgroundKind;

/// One object instance to place in every frame.
#[derive(Debug, Clone)]
pub struct SceneObject {
    /// Index into the renderer's model list.
    pub model_index: usize,
    /// BOP object id.
    pub obj_id: u32,
    pub name: String,
    /// Extreme points of the model (see `Model::support_points`), object frame, metres.
    pub support_points_m: Vec<Vec3>,
    /// With `upright` placement: the model axis that points up (`[[objects]] up`).
    pub up: UpAxis,
    /// With `upright` placement: the largest tilt from that rest pose, degrees.
    pub tilt_deg: f64,
    /// With `up = "stable"`: the model's stable rest poses and their probabilities
    /// (synthgen-physics' `stable_rest_poses`); empty otherwise.
    pub rest_poses: Arc<[RestPose]>,
}

/// A way an object rests on a table: `rotation` turns the model so that a stable face lies on
/// the table (the yaw about +z is drawn on top), drawn with `probability`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RestPose {
    pub rotation: DMat3,
    pub probability: f64,
}

impl SceneObject {
    /// How many extreme points placement uses per model (the CLI's choice too).
    pub const SUPPORT_POINTS: usize = 256;

    /// The instance of `model` (at `model_index` in the renderer's list) with BOP id `obj_id`.
    pub fn new(model_index: usize, obj_id: u32, model: &crate::Model) -> SceneObject {
        SceneObject {
            model_index,
            obj_id,
            name: model.name.clone(),
            support_points_m: model.support_points(Self::SUPPORT_POINTS),
            up: UpAxis::PlusZ,
            tilt_deg: 0.0,
            rest_poses: Arc::from([]),
        }
    }

    /// The rotation of this object's rest pose at `yaw_rad`: its fitted or given up axis and
    /// tilt ([`upright_rotation`]), or with `up = "stable"` and rest poses, one drawn by its
    /// probability, tilted likewise.
    pub fn rest_rotation(&self, yaw_rad: f64, rng: &mut ChaCha8Rng) -> DMat3 {
        if self.up != UpAxis::Stable || self.rest_poses.is_empty() {
            return upright_rotation(yaw_rad, self.up, self.tilt_deg, rng);
        }
        let u: f64 = rng.gen();
        let mut acc = 0.0;
        let rest = self
            .rest_poses
            .iter()
            .find(|r| {
                acc += r.probability;
                u < acc
            })
            .unwrap_or(&self.rest_poses[self.rest_poses.len() - 1]);
        upright_rotation(yaw_rad, UpAxis::PlusZ, self.tilt_deg, rng) * rest.rotation
    }

    /// This instance standing on `up` (upright placement), tilted by up to `tilt_deg`.
    pub fn with_rest(mut self, up: UpAxis, tilt_deg: f64) -> SceneObject {
        self.up = up;
        self.tilt_deg = tilt_deg;
        self
    }

    /// One instance per model, with ids 1, 2, ... in order (examples, tests, benches).
    pub fn one_per_model(models: &[crate::Model]) -> Vec<SceneObject> {
        models
            .iter()
            .enumerate()
            .map(|(i, m)| SceneObject::new(i, i as u32 + 1, m))
            .collect()
    }
}

/// A placed object in one frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectInstance {
    pub model_index: usize,
    pub obj_id: u32,
    pub cam_from_obj: Pose,
    /// Material jitter for this frame.
    pub brightness: f32,
    pub specular: f32,
    pub shininess: f32,
    /// Linear-light colour multiplier (distractor colours; 1, 1, 1 for targets).
    #[serde(default = "white")]
    pub tint: [f32; 3],
    /// Hue rotation of the base colour about the grey axis, degrees
    /// (`synthgen_core::color::hue_rotation`).
    #[serde(default)]
    pub hue_deg: f32,
    /// Metalness 0..1 for GGX shading (`[materials] shading = "ggx"`): the specular colour
    /// tends to the base colour and the diffuse part to black.
    #[serde(default)]
    pub metallic: f32,
}

fn white() -> [f32; 3] {
    [1.0; 3]
}

impl ObjectInstance {
    /// An instance with neutral material values (brightness 1, specular 0.2, shininess 32,
    /// no tint or hue shift).
    pub fn new(model_index: usize, obj_id: u32, cam_from_obj: Pose) -> ObjectInstance {
        ObjectInstance {
            model_index,
            obj_id,
            cam_from_obj,
            brightness: 1.0,
            specular: 0.2,
            shininess: 32.0,
            tint: white(),
            hue_deg: 0.0,
            metallic: 0.0,
        }
    }
}

/// A point light, position in the camera frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointLight {
    pub position_cam_m: DVec3,
    pub color: [f32; 3],
    pub intensity: f32,
}

/// The ground plane: z = 0 of `cam_from_plane`, a square of `size_m` centred on its origin.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroundInstance {
    pub cam_from_plane: Pose,
    pub size_m: f64,
    pub color: [f32; 3],
    pub texture_strength: f32,
    pub texture_seed: u64,
    /// An image texture (`ground.texture_dir`) instead of the procedural tiles.
    #[serde(default)]
    pub texture: Option<SurfaceTexture>,
}

/// An image tiled over a plane: which of the renderer's images (`image` modulo their
/// count), where the tiling starts and how large a tile is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurfaceTexture {
    /// Any value; the renderer uses image `image % count`.
    pub image: u64,
    /// Offset of the tiling in the plane's (x, y), in tiles, 0..1.
    pub offset: [f64; 2],
    /// Side of one tile along the plane's x axis, metres; along y the tile keeps the image's
    /// aspect ratio.
    pub scale_m: f64,
}

/// A wall: the rectangle |x| < width / 2, |y| < height / 2 of the plane z = 0 of
/// `cam_from_wall` (x horizontal, y up, z towards the room's centre). Rendered with depth
/// and instance id 0, like the ground.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WallInstance {
    pub cam_from_wall: Pose,
    pub width_m: f64,
    pub height_m: f64,
    /// sRGB 0..1; multiplies the texture when there is one.
    pub color: [f32; 3],
    pub texture: Option<SurfaceTexture>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BackgroundSample {
    pub kind: BackgroundKind,
    pub color: [f32; 3],
    /// Seed for noise and for choosing an image and crop.
    pub seed: u64,
}

/// Everything a renderer needs for one frame. Poses are in the OpenCV camera frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameScene {
    pub frame_index: u64,
    pub intrinsics: Intrinsics,
    /// World: z up, ground plane at z = 0.
    pub world_from_cam: Pose,
    pub objects: Vec<ObjectInstance>,
    /// Rendered and occluding, but not annotated (`obj_id` 0, instance id 0 in the output).
    #[serde(default)]
    pub distractors: Vec<ObjectInstance>,
    pub lights: Vec<PointLight>,
    pub ambient: f32,
    /// The lights cast shadows (`[lights] shadows`; the embedded renderer's shadow maps).
    #[serde(default)]
    pub shadows: bool,
    /// Strength 0..1 of the screen-space ambient occlusion (`[lights] ambient_occlusion`):
    /// the ambient light a pixel loses to nearby geometry (contact shadows). 0: none.
    #[serde(default)]
    pub ambient_occlusion: f32,
    /// The objects' specular model (`[materials] shading`).
    /// Absent in records written before GGX existed: Blinn-Phong, as they were rendered.
    #[serde(default = "phong")]
    pub shading: crate::scene::Shading,
    /// Environment light: the ambient's colour from above (sky) and from below (ground),
    /// linear multipliers (`[lights] sky_color`, `ground_color`); None: uniform ambient.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment: Option<[[f32; 3]; 2]>,
    pub ground: Option<GroundInstance>,
    /// Vertical planes around the scene (`[walls]`), those the camera is inside of.
    #[serde(default)]
    pub walls: Vec<WallInstance>,
    pub background: BackgroundSample,
}

fn phong() -> crate::scene::Shading {
    crate::scene::Shading::Phong
}

impl FrameScene {
    /// A scene of only `objects` seen from the origin: no distractors, lights, ground or walls,
    /// ambient 1 and a black background. What masks and annotations need (`annotate`), and a
    /// plain scene for tests.
    pub fn bare(frame_index: u64, intrinsics: Intrinsics, objects: Vec<ObjectInstance>) -> Self {
        FrameScene {
            frame_index,
            intrinsics,
            world_from_cam: Pose::IDENTITY,
            objects,
            distractors: vec![],
            lights: vec![],
            ambient: 1.0,
            shadows: false,
            ambient_occlusion: 0.0,
            shading: crate::scene::Shading::Phong,
            environment: None,
            ground: None,
            walls: vec![],
            background: BackgroundSample {
                kind: BackgroundKind::Color,
                color: [0.0; 3],
                seed: 0,
            },
        }
    }
}

/// Names for a message, bounded whatever their number: repeats counted ("cube ×100000"), in
/// order of first appearance, at most 8 distinct ones and then "and N more".
pub fn name_summary<'a>(names: impl IntoIterator<Item = &'a str>) -> String {
    const SHOWN: usize = 8;
    let mut counts: Vec<(&str, usize)> = Vec::new();
    for n in names {
        match counts.iter_mut().find(|(k, _)| *k == n) {
            Some((_, c)) => *c += 1,
            None => counts.push((n, 1)),
        }
    }
    let mut parts: Vec<String> = counts
        .iter()
        .take(SHOWN)
        .map(|&(n, c)| {
            if c == 1 {
                n.to_string()
            } else {
                format!("{n} ×{c}")
            }
        })
        .collect();
    if counts.len() > SHOWN {
        parts.push(format!("and {} more", counts.len() - SHOWN));
    }
    parts.join(", ")
}
