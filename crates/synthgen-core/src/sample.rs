//! Per-frame scene sampling: object placement on a ground plane, camera on a shell, lights,
//! materials and background, all from (seed, frame index).

use std::sync::{Arc, Mutex};

use glam::{DMat3, DQuat, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::bin::bin_instances;
use crate::camera::Intrinsics;
use crate::color::kelvin_to_rgb;
use crate::distractor::{Chosen, DistractorPool};
pub use crate::frame_scene::{
    name_summary, BackgroundSample, FrameScene, GroundInstance, ObjectInstance, PointLight,
    RestPose, SceneObject, SurfaceTexture, WallInstance,
};
use crate::pose::Pose;
use crate::rng::{derive_seed, frame_rng, Stream};
use crate::scene::{Orientation, PlacementMode, Range, SceneSpec};
use crate::view::{targets_inside_image, ViewCheck};
use crate::walls::{camera_inside, ground_texture, sample_walls};
use crate::Error;

/// Settles dropped objects on the plane z = 0 (world z up). Implemented by synthgen-physics,
/// so that core needs no physics engine.
pub trait Settle: Send + Sync {
    /// `world_from_objs[i]` is the drop pose of `objects[i]`; returns the resting poses, or
    /// why settling failed. Must be a pure function of its inputs.
    fn settle(
        &self,
        objects: &[SceneObject],
        world_from_objs: &[Pose],
    ) -> Result<Vec<Pose>, String>;
}

/// A `Settle` behind an `Arc`, with a `Debug` that names it only.
#[derive(Clone)]
struct SettleHook(Arc<dyn Settle>);

impl std::fmt::Debug for SettleHook {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Settle")
    }
}

/// A `ViewCheck` behind an `Arc`, with a `Debug` that names it only.
#[derive(Clone)]
struct ViewHook(Arc<dyn ViewCheck>);

impl std::fmt::Debug for ViewHook {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ViewCheck")
    }
}

/// Samples frames of a scene spec deterministically.
#[derive(Debug, Clone)]
pub struct SceneSampler {
    pub spec: SceneSpec,
    pub intrinsics: Intrinsics,
    pub objects: Vec<SceneObject>,
    pub seed: u64,
    settle: Option<SettleHook>,
    view_check: Option<ViewHook>,
    distractors: DistractorPool,
    /// Model index of the bin's x walls (y walls at the next index), for `[bin]`.
    bin_models: Option<usize>,
    /// Frames whose physics placement failed and fell back to the footprint poses, with why.
    fallbacks: Arc<Mutex<Vec<(u64, String)>>>,
    /// Frames whose targets were placed on another draw, or with fewer of them.
    resamples: Arc<Mutex<Vec<Resample>>>,
}

/// A frame whose targets did not fit on the first draw: placed after `redraws` other draws
/// (from the frame's own placement stream), leaving out `dropped` (the largest targets first).
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub struct Resample {
    pub frame: u64,
    pub redraws: u32,
    pub dropped: Vec<String>,
}

/// Other draws a frame whose targets do not fit gets before it leaves its largest target out
/// (at most half of its targets are left out).
pub const PLACEMENT_REDRAWS: u32 = 4;
/// The placement stream's redraws use ChaCha streams from here on (stream 1 is physics').
const REDRAW_STREAM: u64 = 0x100;

fn uniform(rng: &mut ChaCha8Rng, [lo, hi]: Range) -> f64 {
    if hi > lo {
        rng.gen_range(lo..=hi)
    } else {
        lo
    }
}

fn random_rotation(rng: &mut ChaCha8Rng) -> DMat3 {
    // Shoemake's uniform random unit quaternion.
    let (u1, u2, u3): (f64, f64, f64) = (rng.gen(), rng.gen(), rng.gen());
    let tau = std::f64::consts::TAU;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    let q = DQuat::from_xyzw(
        a * (tau * u2).sin(),
        a * (tau * u2).cos(),
        b * (tau * u3).sin(),
        b * (tau * u3).cos(),
    );
    DMat3::from_quat(q.normalize())
}

/// Rounds of placement, the area growing by 25% after each failed one.
const PLACE_ROUNDS: u32 = 4;

/// A placed footprint: disc on the plane.
struct Footprint {
    center: [f64; 2],
    radius: f64,
    /// Height of the object's top above the table, metres.
    top_z: f64,
    /// Stands on the table with nothing on it yet (another target may rest on it).
    free_top: bool,
}

/// An object in a drawn rest rotation: the rotation, its bounding box's low and high
/// corners, its footprint's centre offset from the origin in x, y, and the footprint's
/// radius.
struct Rested {
    rotation: DMat3,
    lo: DVec3,
    hi: DVec3,
    off: [f64; 2],
    radius: f64,
}

impl SceneSampler {
    pub fn new(
        spec: SceneSpec,
        objects: Vec<SceneObject>,
        seed: u64,
    ) -> Result<SceneSampler, Error> {
        spec.validate()?;
        let intrinsics = spec.camera.intrinsics()?;
        if let Some(o) = objects.iter().find(|o| o.support_points_m.is_empty()) {
            return Err(Error::InvalidSpec(format!(
                "object {} has no vertices to place",
                o.name
            )));
        }
        Ok(SceneSampler {
            spec,
            intrinsics,
            objects,
            seed,
            settle: None,
            view_check: None,
            distractors: DistractorPool::default(),
            bin_models: None,
            fallbacks: Arc::default(),
            resamples: Arc::default(),
        })
    }

    /// Uses `settle` for `placement.mode = "physics"`.
    pub fn with_settle(mut self, settle: Arc<dyn Settle>) -> SceneSampler {
        self.settle = Some(SettleHook(settle));
        self
    }

    /// Uses `check` to count target pixels when `camera.min_visib_fract > 0` (the view is
    /// re-sampled until every target is visible enough).
    pub fn with_view_check(mut self, check: Arc<dyn ViewCheck>) -> SceneSampler {
        self.view_check = Some(ViewHook(check));
        self
    }

    /// The objects `[distractors]` draws from (their `model_index` points into the
    /// renderer's model list, after the targets' models).
    pub fn with_distractors(mut self, pool: DistractorPool) -> SceneSampler {
        self.distractors = pool;
        self
    }

    /// Where the renderer holds the `[bin]` wall models (`BinSpec::models`, in order):
    /// `first` and `first + 1`.
    pub fn with_bin_models(mut self, first: usize) -> SceneSampler {
        self.bin_models = Some(first);
        self
    }

    pub fn distractor_pool(&self) -> &DistractorPool {
        &self.distractors
    }

    /// Frames (index, reason) whose physics placement failed so far and used the footprint
    /// poses instead, sorted by frame.
    pub fn physics_fallbacks(&self) -> Vec<(u64, String)> {
        let mut v = match self.fallbacks.lock() {
            Ok(v) => v.clone(),
            Err(p) => p.into_inner().clone(),
        };
        v.sort();
        v
    }

    /// Frames that were placed on another draw or with fewer targets, in frame order.
    pub fn resamples(&self) -> Vec<Resample> {
        let mut v = match self.resamples.lock() {
            Ok(v) => v.clone(),
            Err(p) => p.into_inner().clone(),
        };
        v.sort();
        v
    }

    /// Samples frame `frame_index`. The same (seed, index) always gives the same frame.
    pub fn sample(&self, frame_index: u64) -> Result<FrameScene, Error> {
        let spec = &self.spec;
        let d = &spec.distractors;
        let mut drng = frame_rng(self.seed, frame_index, Stream::Distractors);
        let chosen = if d.count[1] > 0 {
            if self.distractors.is_empty() {
                return Err(Error::InvalidSpec(
                    "distractors.count > 0 but the sampler was given no distractor objects (with_distractors)".into(),
                ));
            }
            self.distractors.choose(d, &mut drng)
        } else {
            Vec::new()
        };
        let (objects, (targets, mut footprints)) =
            self.place_robustly(frame_index, self.frame_objects(frame_index))?;
        let placed = self.place_distractors(chosen, &mut drng, &mut footprints);
        let (chosen, distractor_poses): (Vec<Chosen>, Vec<Pose>) = placed.into_iter().unzip();
        let all: Vec<&SceneObject> = objects
            .iter()
            .copied()
            .chain(chosen.iter().map(|c| c.object))
            .collect();
        let mut world_from_all = targets;
        world_from_all.extend(distractor_poses);
        if spec.placement.mode == PlacementMode::Physics {
            world_from_all = self.settle_objects(frame_index, &all, world_from_all)?;
        }
        let (world_from_objs, world_from_distractors) = world_from_all.split_at(objects.len());

        let mut mat_rng = frame_rng(self.seed, frame_index, Stream::Materials);
        let material = |rng: &mut ChaCha8Rng| {
            let m = &spec.materials;
            let brightness = uniform(rng, m.brightness) as f32;
            let specular = uniform(rng, m.specular) as f32;
            let shininess = match m.roughness {
                // Beckmann alpha = r^2, Blinn-Phong n = 2 / alpha^2 - 2.
                Some(r) => (2.0 / uniform(rng, r).powi(4) - 2.0).max(0.0) as f32,
                None => uniform(rng, m.shininess) as f32,
            };
            let hue_deg = uniform(rng, m.hue_deg) as f32;
            // Drawn only when asked for, so that specs without it keep their streams.
            let metallic = if m.metallic[1] > 0.0 {
                uniform(rng, m.metallic) as f32
            } else {
                0.0
            };
            (brightness, specular, shininess, hue_deg, metallic)
        };
        // World-frame instances: cam_from_obj holds world_from_obj until the camera is known.
        let world_objects: Vec<ObjectInstance> = objects
            .iter()
            .zip(world_from_objs)
            .map(|(o, w)| {
                let (brightness, specular, shininess, hue_deg, metallic) = material(&mut mat_rng);
                ObjectInstance {
                    brightness,
                    specular,
                    shininess,
                    hue_deg,
                    metallic,
                    ..ObjectInstance::new(o.model_index, o.obj_id, *w)
                }
            })
            .collect();
        let bin = if spec.bin.enabled {
            let Some(first) = self.bin_models else {
                return Err(Error::InvalidSpec(
                    "bin.enabled but the sampler was given no bin models (with_bin_models)".into(),
                ));
            };
            bin_instances(spec, self.seed, frame_index, first)
        } else {
            Vec::new()
        };
        let mut world_distractors: Vec<ObjectInstance> = chosen
            .iter()
            .zip(world_from_distractors)
            .map(|(c, w)| {
                let (brightness, specular, shininess, hue_deg, metallic) = material(&mut drng);
                ObjectInstance {
                    brightness,
                    specular,
                    shininess,
                    hue_deg,
                    metallic,
                    tint: c.tint,
                    ..ObjectInstance::new(c.object.model_index, 0, *w)
                }
            })
            .collect();
        // The bin's walls: rendered and occluding like distractors, after them.
        world_distractors.extend(bin);

        let center = scene_center(world_from_objs);
        let (world_lights, ambient) = self.sample_lights(frame_index, center);

        let world_walls = sample_walls(spec, self.seed, frame_index, center);
        // With walls the ground reaches them: a square room of half side d turned by any yaw
        // fits in the axis-aligned square of half side d sqrt 2.
        let ground_size = world_walls.first().map_or(spec.ground.size_m, |w| {
            spec.ground.size_m.max(w.width_m * std::f64::consts::SQRT_2)
        });
        let g = &spec.ground;
        let ground = g.visible.then(|| {
            let mut rng = frame_rng(self.seed, frame_index, Stream::Ground);
            let t: f32 = rng.gen();
            let color =
                std::array::from_fn(|i| g.color_min[i] + t * (g.color_max[i] - g.color_min[i]));
            GroundInstance {
                cam_from_plane: Pose::new(DMat3::IDENTITY, DVec3::new(center.x, center.y, 0.0)),
                size_m: ground_size,
                color,
                texture_strength: g.texture_strength,
                texture_seed: rng.gen(),
                texture: ground_texture(spec, self.seed, frame_index),
            }
        });

        let b = &spec.background;
        let mut rng = frame_rng(self.seed, frame_index, Stream::Background);
        let color = std::array::from_fn(|i| {
            let t: f32 = rng.gen();
            b.color_min[i] + t * (b.color_max[i] - b.color_min[i])
        });
        let background = BackgroundSample {
            kind: b.kind,
            color,
            seed: derive_seed(self.seed, frame_index, Stream::Background) ^ rng.gen::<u64>(),
        };

        let c = &spec.camera;
        let check_visib = c.min_visib_fract > 0.0;
        let hook = match (&self.view_check, check_visib) {
            (Some(ViewHook(h)), true) => Some(h),
            (None, true) => {
                return Err(Error::InvalidSpec(
                    "camera.min_visib_fract > 0 needs a view check (synthgen-render), which this program did not provide".into(),
                ))
            }
            _ => None,
        };
        let to_cam = |cam_from_world: &Pose, v: &[ObjectInstance]| -> Vec<ObjectInstance> {
            v.iter()
                .map(|o| ObjectInstance {
                    cam_from_obj: cam_from_world.compose(&o.cam_from_obj),
                    ..o.clone()
                })
                .collect()
        };
        for attempt in 0..c.max_view_tries {
            let world_from_cam = self.sample_camera(frame_index, attempt, world_from_objs);
            let cam_from_world = world_from_cam.inverse();
            let scene = FrameScene {
                frame_index,
                intrinsics: self.intrinsics,
                world_from_cam,
                objects: to_cam(&cam_from_world, &world_objects),
                distractors: to_cam(&cam_from_world, &world_distractors),
                lights: world_lights
                    .iter()
                    .map(|l| PointLight {
                        position_cam_m: cam_from_world.transform_point(l.position_cam_m),
                        ..l.clone()
                    })
                    .collect(),
                ambient,
                shadows: self.spec.lights.shadows,
                ambient_occlusion: self.spec.lights.ambient_occlusion as f32,
                shading: self.spec.materials.shading,
                environment: environment(&self.spec.lights),
                ground: ground.as_ref().map(|g| GroundInstance {
                    cam_from_plane: cam_from_world.compose(&g.cam_from_plane),
                    ..g.clone()
                }),
                walls: world_walls
                    .iter()
                    .filter(|w| camera_inside(&w.cam_from_wall, world_from_cam.translation_m))
                    .map(|w| WallInstance {
                        cam_from_wall: cam_from_world.compose(&w.cam_from_wall),
                        ..w.clone()
                    })
                    .collect(),
                background: background.clone(),
            };
            if !c.allow_truncation && !targets_inside_image(&scene, &objects) {
                continue;
            }
            let Some(hook) = hook else {
                return Ok(scene);
            };
            let vis = hook.visibility(&scene).map_err(Error::ViewCheck)?;
            let ok = vis.iter().take(objects.len()).all(|v| {
                v.visib_fract() >= c.min_visib_fract
                    && (c.allow_truncation || v.px_in_image == v.px_all)
            });
            if ok {
                return Ok(scene);
            }
        }
        Err(Error::View {
            frame: frame_index,
            tries: c.max_view_tries,
            what: match (check_visib, c.allow_truncation) {
                (true, true) => format!("every target at least {} visible", c.min_visib_fract),
                (true, false) => format!(
                    "every target inside the image and at least {} visible",
                    c.min_visib_fract
                ),
                _ => "every target inside the image".into(),
            },
        })
    }

    /// Lifts the footprint poses by the drop heights and lets the physics engine settle them;
    /// on failure keeps the footprint poses and records the frame.
    fn settle_objects(
        &self,
        frame_index: u64,
        objects: &[&SceneObject],
        placed: Vec<Pose>,
    ) -> Result<Vec<Pose>, Error> {
        let Some(SettleHook(settle)) = &self.settle else {
            return Err(Error::InvalidSpec(
                "placement.mode = \"physics\" needs the physics engine (synthgen-physics), which this program did not provide".into(),
            ));
        };
        let mut rng = frame_rng(self.seed, frame_index, Stream::Placement);
        // A separate stream: the footprint draws stay those of mode "sample".
        rng.set_stream(1);
        let drop = self.spec.placement.physics.drop_height_m;
        let lifted: Vec<Pose> = placed
            .iter()
            .map(|p| {
                let mut p = *p;
                p.translation_m.z += uniform(&mut rng, drop);
                p
            })
            .collect();
        // The frame's targets and distractors (not necessarily `self.objects`).
        let objects: Vec<SceneObject> = objects.iter().map(|o| (*o).clone()).collect();
        match settle.settle(&objects, &lifted) {
            Ok(poses) if poses.len() == placed.len() => Ok(poses),
            Ok(poses) => Err(Error::InvalidSpec(format!(
                "physics returned {} poses for {} objects",
                poses.len(),
                placed.len()
            ))),
            Err(why) => {
                match self.fallbacks.lock() {
                    Ok(mut v) => v.push((frame_index, why)),
                    Err(p) => p.into_inner().push((frame_index, why)),
                }
                Ok(placed)
            }
        }
    }

    /// The targets frame `frame_index` places, in their order in `objects`: all of them, or
    /// with `placement.objects_per_frame` a random subset of a random size (its own stream,
    /// so that the placement draws of specs without it stay as they were).
    pub fn frame_objects(&self, frame_index: u64) -> Vec<&SceneObject> {
        let n = self.objects.len();
        let Some([lo, hi]) = self.spec.placement.objects_per_frame else {
            return self.objects.iter().collect();
        };
        let (lo, hi) = ((lo as usize).min(n), (hi as usize).min(n));
        if lo >= n {
            return self.objects.iter().collect();
        }
        let mut rng = frame_rng(self.seed, frame_index, Stream::Objects);
        let k = rng.gen_range(lo..=hi);
        let mut chosen = rand::seq::index::sample(&mut rng, n, k).into_vec();
        chosen.sort_unstable();
        chosen.into_iter().map(|i| &self.objects[i]).collect()
    }

    /// Places the frame's targets; when they do not fit, tries [`PLACEMENT_REDRAWS`] other
    /// draws (the frame's placement stream, other ChaCha streams), then leaves out the largest
    /// target and tries again, down to half of the targets (a frame that would lose more fails:
    /// the spec asks for what the area cannot hold). A frame that fits on the first draw is sampled
    /// exactly as before; every outcome stays a pure function of (seed, frame). Resampled
    /// frames are recorded ([`SceneSampler::resamples`]).
    #[allow(clippy::type_complexity)]
    fn place_robustly<'a>(
        &self,
        frame_index: u64,
        mut objects: Vec<&'a SceneObject>,
    ) -> Result<(Vec<&'a SceneObject>, (Vec<Pose>, Vec<Footprint>)), Error> {
        let mut dropped = Vec::new();
        let min_kept = objects.len().div_ceil(2).max(1);
        let mut first_error: Option<Error> = None;
        let mut draw: u64 = 0;
        loop {
            let mut rng = frame_rng(self.seed, frame_index, Stream::Placement);
            if draw > 0 {
                rng.set_stream(REDRAW_STREAM + draw);
            }
            match self.place_objects(&objects, &mut rng) {
                Ok(placed) => {
                    if draw > 0 {
                        let r = Resample {
                            frame: frame_index,
                            redraws: draw as u32,
                            dropped,
                        };
                        match self.resamples.lock() {
                            Ok(mut v) => v.push(r),
                            Err(p) => p.into_inner().push(r),
                        }
                    }
                    return Ok((objects, placed));
                }
                Err(e) => {
                    draw += 1;
                    let drop_one = draw.is_multiple_of(u64::from(PLACEMENT_REDRAWS) + 1);
                    if drop_one && objects.len() <= min_kept {
                        // The first draw's error names every target the spec asked for.
                        return Err(first_error.unwrap_or(e));
                    }
                    first_error.get_or_insert(e);
                    if drop_one {
                        // The largest footprints go first: they are the ones that do not fit
                        // (one at a time, an eighth of a crowd).
                        let radius = |o: &SceneObject| {
                            o.support_points_m
                                .iter()
                                .map(|p| p.length())
                                .fold(0.0f32, f32::max)
                        };
                        let step = (objects.len() / 8).clamp(1, objects.len() - min_kept);
                        for _ in 0..step {
                            let i = objects
                                .iter()
                                .enumerate()
                                .max_by(|a, b| radius(a.1).total_cmp(&radius(b.1)))
                                .map_or(0, |(i, _)| i);
                            dropped.push(objects.remove(i).name.clone());
                        }
                    }
                }
            }
        }
    }

    /// Places the targets: each round that cannot fit every one widens the area by 25%; the
    /// result stays a pure function of `rng`'s state. Returns the poses and footprints.
    fn place_objects(
        &self,
        objects: &[&SceneObject],
        rng: &mut ChaCha8Rng,
    ) -> Result<(Vec<Pose>, Vec<Footprint>), Error> {
        let p = &self.spec.placement;
        let mut area = p.area_m;
        for round in 0..PLACE_ROUNDS {
            let mut placed = Vec::with_capacity(objects.len());
            let poses: Option<Vec<Pose>> = objects
                .iter()
                .map(|o| {
                    // Drawn only when stacking is on, so other specs keep their streams.
                    if p.stack_prob > 0.0 && !placed.is_empty() && rng.gen_bool(p.stack_prob) {
                        if let Some(pose) = self.stack_one(o, rng, &mut placed) {
                            return Some(pose);
                        }
                    }
                    self.place_one(o, rng, area, &mut placed)
                })
                .collect();
            match poses {
                Some(poses) => return Ok((poses, placed)),
                None if round + 1 < PLACE_ROUNDS => area = [area[0] * 1.25, area[1] * 1.25],
                None => {}
            }
        }
        Err(Error::Placement {
            name: name_summary(objects.iter().map(|o| o.name.as_str())),
            tries: p.max_tries,
            area_m: area,
        })
    }

    /// Places distractors around the placed targets (whose poses they never change): each
    /// gets `max_tries` per area, the area growing by 25% up to three times; one that still
    /// does not fit is left out of the frame.
    fn place_distractors<'a>(
        &self,
        chosen: Vec<Chosen<'a>>,
        rng: &mut ChaCha8Rng,
        placed: &mut Vec<Footprint>,
    ) -> Vec<(Chosen<'a>, Pose)> {
        chosen
            .into_iter()
            .filter_map(|c| {
                let mut area = self.spec.placement.area_m;
                for _ in 0..PLACE_ROUNDS {
                    if let Some(pose) = self.place_one(c.object, rng, area, placed) {
                        return Some((c, pose));
                    }
                    area = [area[0] * 1.25, area[1] * 1.25];
                }
                None
            })
            .collect()
    }

    /// One object's footprint pose clear of `placed` within `area` (pushed onto it), or
    /// None after `max_tries`.
    fn place_one(
        &self,
        o: &SceneObject,
        rng: &mut ChaCha8Rng,
        area: [f64; 2],
        placed: &mut Vec<Footprint>,
    ) -> Option<Pose> {
        let p = &self.spec.placement;
        for _ in 0..p.max_tries {
            let Rested {
                lo,
                hi,
                off,
                radius,
                rotation,
            } = self.rested(o, rng);
            let center = [
                rng.gen_range(-0.5..=0.5) * area[0],
                rng.gen_range(-0.5..=0.5) * area[1],
            ];
            // With a bin, the footprint must lie inside it (so nothing starts in a wall).
            let [bx, by] = self.spec.bin.size_m;
            if self.spec.bin.enabled
                && (center[0].abs() + radius > 0.5 * bx || center[1].abs() + radius > 0.5 * by)
            {
                continue;
            }
            let clear = placed.iter().all(|f| {
                let d =
                    ((f.center[0] - center[0]).powi(2) + (f.center[1] - center[1]).powi(2)).sqrt();
                d >= f.radius + radius + p.min_gap_m
            });
            if clear {
                placed.push(Footprint {
                    center,
                    radius,
                    top_z: hi.z - lo.z,
                    free_top: true,
                });
                return Some(Pose::new(
                    rotation,
                    DVec3::new(center[0] - off[0], center[1] - off[1], -lo.z),
                ));
            }
        }
        None
    }

    /// A rest rotation for `o` (its `up`, `tilt_deg` or stable faces, a random yaw; or a
    /// uniform rotation) and the extents that go with it.
    fn rested(&self, o: &SceneObject, rng: &mut ChaCha8Rng) -> Rested {
        let rotation = match self.spec.placement.orientation {
            Orientation::Upright => {
                let yaw = rng.gen_range(0.0..std::f64::consts::TAU);
                o.rest_rotation(yaw, rng)
            }
            Orientation::Random => random_rotation(rng),
        };
        let pts: Vec<DVec3> = o
            .support_points_m
            .iter()
            .map(|v| rotation * v.as_dvec3())
            .collect();
        let (lo, hi) = pts.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), v| (lo.min(*v), hi.max(*v)),
        );
        let off = [(lo.x + hi.x) * 0.5, (lo.y + hi.y) * 0.5];
        let radius = pts
            .iter()
            .map(|v| ((v.x - off[0]).powi(2) + (v.y - off[1]).powi(2)).sqrt())
            .fold(0.0, f64::max);
        Rested {
            rotation,
            lo,
            hi,
            off,
            radius,
        }
    }

    /// `o` resting on top of a target already on the table (`placement.stack_prob`): one no
    /// narrower than it, its centre within half the base's radius of the base's centre, its
    /// footprint clear of every other; None after `max_tries`.
    fn stack_one(
        &self,
        o: &SceneObject,
        rng: &mut ChaCha8Rng,
        placed: &mut Vec<Footprint>,
    ) -> Option<Pose> {
        let p = &self.spec.placement;
        for _ in 0..p.max_tries {
            let bases: Vec<usize> = (0..placed.len()).filter(|&i| placed[i].free_top).collect();
            if bases.is_empty() {
                return None;
            }
            let b = bases[rng.gen_range(0..bases.len())];
            let Rested {
                lo,
                hi,
                off,
                radius,
                rotation,
            } = self.rested(o, rng);
            let base = &placed[b];
            if radius > base.radius {
                continue;
            }
            let (r, a) = (
                0.5 * base.radius * rng.gen::<f64>().sqrt(),
                rng.gen_range(0.0..std::f64::consts::TAU),
            );
            let center = [base.center[0] + r * a.cos(), base.center[1] + r * a.sin()];
            let clear = placed.iter().enumerate().all(|(i, f)| {
                i == b
                    || ((f.center[0] - center[0]).powi(2) + (f.center[1] - center[1]).powi(2))
                        .sqrt()
                        >= f.radius + radius + p.min_gap_m
            });
            if !clear {
                continue;
            }
            let z = base.top_z;
            placed[b].free_top = false;
            placed.push(Footprint {
                center,
                radius,
                top_z: z + hi.z - lo.z,
                free_top: false,
            });
            return Some(Pose::new(
                rotation,
                DVec3::new(center[0] - off[0], center[1] - off[1], z - lo.z),
            ));
        }
        None
    }

    /// The camera of view `attempt` (attempt 0 draws from the camera stream as frames
    /// without rejection always did; later attempts from their own ChaCha streams).
    fn sample_camera(&self, frame_index: u64, attempt: u32, world_from_objs: &[Pose]) -> Pose {
        let c = &self.spec.camera_pose;
        let mut rng = frame_rng(self.seed, frame_index, Stream::Camera);
        if attempt > 0 {
            rng.set_stream(u64::from(attempt));
        }
        let j = c.look_at_jitter_m;
        let mut target = scene_center(world_from_objs);
        if j > 0.0 {
            target.x += rng.gen_range(-j..=j);
            target.y += rng.gen_range(-j..=j);
        }
        let dist = uniform(&mut rng, c.distance_m);
        let elev = uniform(&mut rng, c.elevation_deg).to_radians();
        let azim = uniform(&mut rng, c.azimuth_deg).to_radians();
        let roll = uniform(&mut rng, c.inplane_deg).to_radians();
        let eye = target
            + dist * DVec3::new(elev.cos() * azim.cos(), elev.cos() * azim.sin(), elev.sin());
        let mut world_from_cam = Pose::world_from_cam_look_at(eye, target, DVec3::Z);
        world_from_cam.rotation *= DMat3::from_rotation_z(roll);
        world_from_cam
    }

    /// Lights with their positions in the world frame (in `position_cam_m`, moved to the
    /// camera frame once the view is chosen).
    fn sample_lights(&self, frame_index: u64, center: DVec3) -> (Vec<PointLight>, f32) {
        let l = &self.spec.lights;
        let mut rng = frame_rng(self.seed, frame_index, Stream::Lights);
        let n = rng.gen_range(l.count[0]..=l.count[1]);
        let lights = (0..n)
            .map(|_| {
                let d = uniform(&mut rng, l.distance_m);
                let e = uniform(&mut rng, l.elevation_deg).to_radians();
                let a = rng.gen_range(0.0..std::f64::consts::TAU);
                let p_world =
                    center + d * DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin());
                let color = match l.temperature_k {
                    Some(t) => kelvin_to_rgb(uniform(&mut rng, t)),
                    None => std::array::from_fn(|_| {
                        (1.0 - l.color_jitter * rng.gen::<f64>()).clamp(0.0, 1.0) as f32
                    }),
                };
                PointLight {
                    position_cam_m: p_world,
                    color,
                    intensity: uniform(&mut rng, l.intensity) as f32,
                }
            })
            .collect();
        let ambient = uniform(&mut rng, l.ambient) as f32;
        (lights, ambient)
    }
}

/// Mean of object origins, on the plane (z = 0) when there are none.
fn scene_center(world_from_objs: &[Pose]) -> DVec3 {
    if world_from_objs.is_empty() {
        return DVec3::ZERO;
    }
    world_from_objs
        .iter()
        .map(|p| p.translation_m)
        .sum::<DVec3>()
        / world_from_objs.len() as f64
}

/// The frame's environment light from `[lights] sky_color` / `ground_color`.
fn environment(l: &crate::scene::LightSpec) -> Option<[[f32; 3]; 2]> {
    if l.sky_color.is_none() && l.ground_color.is_none() {
        return None;
    }
    let c = |v: Option<[f64; 3]>| v.unwrap_or([1.0; 3]).map(|x| x as f32);
    Some([c(l.sky_color), c(l.ground_color)])
}

#[cfg(test)]
mod name_tests {
    use super::name_summary;

    /// Issue 13, item 12: 100000 objects printed 1.2 MB of names.
    #[test]
    fn summaries_of_many_objects_are_bounded() {
        let many = vec!["cube"; 100_000];
        assert_eq!(name_summary(many), "cube ×100000");
        let names: Vec<String> = (0..20).map(|i| format!("m{i}")).collect();
        let s = name_summary(names.iter().map(String::as_str).chain(["m0"]));
        assert_eq!(s, "m0 ×2, m1, m2, m3, m4, m5, m6, m7, and 12 more");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Model;
    use crate::rest::UpAxis;
    use glam::Vec3;

    fn objs(n: usize) -> Vec<SceneObject> {
        let m = Model::cuboid("box", Vec3::new(0.1, 0.06, 0.08));
        (0..n)
            .map(|i| SceneObject {
                model_index: 0,
                obj_id: i as u32 + 1,
                name: format!("box{i}"),
                support_points_m: m.support_points(64),
                up: UpAxis::PlusZ,
                tilt_deg: 0.0,
                rest_poses: Arc::from([]),
            })
            .collect()
    }

    fn world_from_objs(fr: &FrameScene) -> Vec<Pose> {
        fr.objects
            .iter()
            .map(|i| fr.world_from_cam.compose(&i.cam_from_obj))
            .collect()
    }

    #[test]
    fn subsets_have_sizes_in_range_and_are_deterministic() {
        let mut spec = SceneSpec::default();
        spec.placement.objects_per_frame = Some([2, 4]);
        let s = SceneSampler::new(spec.clone(), objs(6), 9).unwrap();
        let mut sizes = [0usize; 7];
        for f in 0..60 {
            let fr = s.sample(f).unwrap();
            let n = fr.objects.len();
            assert!((2..=4).contains(&n), "frame {f}: {n} objects");
            sizes[n] += 1;
            let ids: Vec<u32> = fr.objects.iter().map(|o| o.obj_id).collect();
            assert!(
                ids.windows(2).all(|w| w[0] < w[1]),
                "distinct, in order: {ids:?}"
            );
            assert_eq!(fr, s.sample(f).unwrap());
        }
        assert!(sizes[2] > 0 && sizes[3] > 0 && sizes[4] > 0, "{sizes:?}");
        // Clamped to the objects there are; [n, n] places all of them as without the field.
        spec.placement.objects_per_frame = Some([5, 9]);
        let s = SceneSampler::new(spec.clone(), objs(3), 9).unwrap();
        assert!((0..10).all(|f| s.sample(f).unwrap().objects.len() == 3));
        let plain = SceneSampler::new(SceneSpec::default(), objs(3), 9).unwrap();
        assert_eq!(s.sample(4).unwrap(), plain.sample(4).unwrap());
    }

    #[test]
    fn up_axis_points_up_within_the_tilt_and_objects_rest_on_the_plane() {
        let mut spec = SceneSpec::default();
        spec.placement.area_m = [0.3, 0.3];
        let o: Vec<SceneObject> = objs(4)
            .into_iter()
            .map(|o| o.with_rest(UpAxis::MinusX, 10.0))
            .collect();
        let s = SceneSampler::new(spec, o.clone(), 5).unwrap();
        let mut largest_tilt: f64 = 0.0;
        for f in 0..40 {
            let fr = s.sample(f).unwrap();
            let mut discs = Vec::new();
            for w in world_from_objs(&fr) {
                let up = w.rotation * DVec3::NEG_X;
                let tilt = up.z.clamp(-1.0, 1.0).acos().to_degrees();
                assert!(tilt <= 10.0 + 1e-9, "frame {f}: -x is {tilt}° from up");
                largest_tilt = largest_tilt.max(tilt);
                let pts: Vec<DVec3> = o[0]
                    .support_points_m
                    .iter()
                    .map(|p| w.transform_point(p.as_dvec3()))
                    .collect();
                let zmin = pts.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
                assert!(zmin.abs() < 1e-9, "lowest point at z={zmin}");
                let (lo, hi) = pts.iter().fold(
                    (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
                    |(lo, hi), v| (lo.min(*v), hi.max(*v)),
                );
                let c = (lo + hi) * 0.5;
                let r = pts
                    .iter()
                    .map(|p| (p.x - c.x).hypot(p.y - c.y))
                    .fold(0.0, f64::max);
                discs.push((c, r));
            }
            for i in 0..discs.len() {
                for j in i + 1..discs.len() {
                    let ((a, ra), (b, rb)) = (discs[i], discs[j]);
                    let d = (a.x - b.x).hypot(a.y - b.y);
                    assert!(d >= ra + rb, "frame {f}: footprints {i} and {j} overlap");
                }
            }
        }
        assert!(largest_tilt > 7.0, "tilts are drawn: {largest_tilt}");
    }

    #[test]
    fn sampling_is_deterministic_per_frame() {
        let s = SceneSampler::new(SceneSpec::default(), objs(3), 42).unwrap();
        let a = s.sample(17).unwrap();
        let b = s.sample(17).unwrap();
        assert_eq!(a, b);
        assert_ne!(a, s.sample(18).unwrap());
        let other_seed = SceneSampler::new(SceneSpec::default(), objs(3), 43).unwrap();
        assert_ne!(a, other_seed.sample(17).unwrap());
    }

    #[test]
    fn objects_rest_on_plane_without_overlap_and_in_front_of_camera() {
        for orientation in [Orientation::Upright, Orientation::Random] {
            let mut spec = SceneSpec::default();
            spec.placement.orientation = orientation;
            let o = objs(5);
            let s = SceneSampler::new(spec, o.clone(), 1).unwrap();
            for f in 0..50 {
                let fr = s.sample(f).unwrap();
                let world_from_objs: Vec<Pose> = fr
                    .objects
                    .iter()
                    .map(|i| fr.world_from_cam.compose(&i.cam_from_obj))
                    .collect();
                let mut boxes = Vec::new();
                for w in &world_from_objs {
                    assert!(w.validate(1e-9).is_ok());
                    let pts: Vec<DVec3> = o[0]
                        .support_points_m
                        .iter()
                        .map(|p| w.transform_point(p.as_dvec3()))
                        .collect();
                    let zmin = pts.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
                    assert!(zmin.abs() < 1e-9, "lowest point at z={zmin}");
                    boxes.push(pts);
                }
                // Footprint discs separate, so vertices of one box are not inside another's
                // xy extent circle: check the centres are apart by at least the box half-width.
                for i in 0..boxes.len() {
                    for j in i + 1..boxes.len() {
                        let ci = world_from_objs[i].translation_m;
                        let cj = world_from_objs[j].translation_m;
                        let d = ((ci.x - cj.x).powi(2) + (ci.y - cj.y).powi(2)).sqrt();
                        assert!(d > 0.06, "objects {i} and {j} overlap ({d} m apart)");
                    }
                }
                for inst in &fr.objects {
                    assert!(inst.cam_from_obj.translation_m.z > 0.1);
                }
                let cam_z = fr.world_from_cam.translation_m.z;
                assert!(cam_z > 0.0, "camera below the plane");
            }
        }
    }

    #[test]
    fn impossible_placement_errors() {
        // A bin too small for any object: not even one target fits, on any draw.
        let mut spec = SceneSpec::default();
        spec.bin.enabled = true;
        spec.bin.size_m = [0.001, 0.001];
        spec.placement.max_tries = 3;
        let s = SceneSampler::new(spec, objs(2), 1)
            .unwrap()
            .with_bin_models(2);
        let e = s.sample(0).unwrap_err();
        assert!(e.to_string().contains("cannot place"), "{e}");
    }

    /// Issue 27: real objects rest on others (YCB-Video scene 2's pudding box); with
    /// `placement.stack_prob` a target lies on one already on the table, no wider than it.
    #[test]
    fn stacked_targets_rest_on_a_wider_one() {
        let big = Model::cuboid("big", Vec3::new(0.2, 0.2, 0.05));
        let small = Model::cuboid("small", Vec3::new(0.06, 0.06, 0.04));
        let obj = |i: u32, m: &Model| SceneObject {
            model_index: i as usize,
            obj_id: i + 1,
            name: m.name.clone(),
            support_points_m: m.support_points(64),
            up: UpAxis::PlusZ,
            tilt_deg: 0.0,
            rest_poses: Arc::from([]),
        };
        let mut spec = SceneSpec::default();
        spec.placement.stack_prob = 1.0;
        let s = SceneSampler::new(spec, vec![obj(0, &big), obj(1, &small)], 4).unwrap();
        for f in 0..20 {
            let fr = s.sample(f).unwrap();
            let w = world_from_objs(&fr);
            // The small box's bottom (centre 2 cm above its base) on the big one's top (5 cm).
            assert!(
                (w[1].translation_m.z - 0.07).abs() < 1e-6,
                "frame {f}: {:?}",
                w[1]
            );
            let d = (w[1].translation_m - w[0].translation_m)
                .truncate()
                .length();
            assert!(
                d <= 0.5 * 0.2 * std::f64::consts::SQRT_2 + 1e-9,
                "frame {f}: {d} m off its base"
            );
        }
        // Reversed, the big box cannot rest on the small one: both stand on the table.
        let mut spec = SceneSpec::default();
        spec.placement.stack_prob = 1.0;
        let s = SceneSampler::new(spec, vec![obj(1, &small), obj(0, &big)], 4).unwrap();
        let w = world_from_objs(&s.sample(0).unwrap());
        assert!((w[1].translation_m.z - 0.025).abs() < 1e-6, "{:?}", w[1]);
    }

    /// Issue 27: a frame whose targets did not fit stopped the render. It is drawn again
    /// (other streams of its own RNG), then placed with fewer targets, deterministically.
    #[test]
    fn a_frame_that_does_not_fit_is_redrawn_then_placed_with_fewer_targets() {
        let mut spec = SceneSpec::default();
        spec.placement.area_m = [0.0, 0.0]; // one target fits at the centre, two never
        spec.placement.max_tries = 3;
        let s = SceneSampler::new(spec, objs(2), 1).unwrap();
        let f = s.sample(0).unwrap();
        assert_eq!(f.objects.len(), 1);
        let r = s.resamples();
        assert_eq!(r.len(), 1);
        assert_eq!((r[0].frame, r[0].redraws), (0, PLACEMENT_REDRAWS + 1));
        assert_eq!(r[0].dropped.len(), 1);
        assert_eq!(s.sample(0).unwrap(), f, "deterministic");
        // At most half of the targets are left out: four that cannot share a point fail.
        let mut spec = SceneSpec::default();
        spec.placement.area_m = [0.0, 0.0];
        spec.placement.max_tries = 3;
        let s = SceneSampler::new(spec, objs(4), 1).unwrap();
        let e = s.sample(0).unwrap_err();
        assert!(e.to_string().contains("cannot place"), "{e}");
        // Frames that fit on the first draw are sampled as before, and not recorded.
        let ok = SceneSampler::new(SceneSpec::default(), objs(2), 1).unwrap();
        let _ = ok.sample(3).unwrap();
        assert!(ok.resamples().is_empty());
    }
}
