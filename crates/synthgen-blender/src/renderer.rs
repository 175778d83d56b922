//! `BlenderRenderer`: the bpy interpreter on its own thread, Cycles renders read back from a
//! multilayer EXR, and the raster backend at the same pose for what Cycles does not give
//! cheaply (each object's alone depth, the sampled background).

use std::ffi::CString;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use pyo3::prelude::*;
use pyo3::types::PyBytes;
use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::sample::SurfaceTexture;
use synthgen_core::{FrameScene, Model, RenderedFrame, Texture};
use synthgen_render::{CpuRenderer, Renderer};

use crate::camera::{BlenderCamera, OPENCV_CAM_FROM_BLENDER_CAM};
use crate::exr_passes::read_passes;
use crate::passes::{composite_over, depth_from_z, instance_from_index};
use crate::venv::{bpy_site_packages, resolve_venv};
use crate::{BlenderOptions, Error};

/// The scene script, embedded so the binary needs only the venv.
const SCENE_SCRIPT: &str = include_str!("../../../blender/synthgen_scene.py");

/// Cycles point-light power (W) per unit of irradiance at 1 m. The raster backend's
/// `intensity` is the irradiance a light delivers (no falloff); for a Cycles point light of
/// `P` watts we take a white Lambertian surface facing it at `d` metres to reach the pixel
/// value `P / (4 π² d²)` (Cycles' point-light convention as we understand it; not
/// calibrated by a test — only the exposure depends on it, no annotation does). The power is
/// chosen so that the two agree at the objects' centroid; elsewhere Cycles' falloff is
/// physical.
pub const WATTS_PER_IRRADIANCE_AT_1M: f64 = 4.0 * std::f64::consts::PI * std::f64::consts::PI;

struct Job {
    frame_json: String,
    exr_path: PathBuf,
    reply: Sender<Result<(), Error>>,
}

/// Renders `FrameScene`s with Blender Cycles. One bpy interpreter per process, on one thread
/// that owns it (Blender treats the thread that imported bpy as its main thread); the scene
/// is built once and each frame only moves objects, lights and the camera.
pub struct BlenderRenderer {
    jobs: Mutex<Option<Sender<Job>>>,
    thread: Option<JoinHandle<()>>,
    raster: CpuRenderer,
    scratch: PathBuf,
    options: BlenderOptions,
    aspects: SurfaceAspects,
    /// Renders started, for the scratch file names.
    renders: std::sync::atomic::AtomicU64,
}

/// Height / width of each ground and wall image the renderer holds (in order), which the
/// frame JSON needs to tile them as the raster does.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceAspects {
    pub ground: Vec<f64>,
    pub walls: Vec<f64>,
}

impl SurfaceAspects {
    fn of(ground: &[Arc<Texture>], walls: &[Arc<Texture>]) -> SurfaceAspects {
        let a = |v: &[Arc<Texture>]| {
            v.iter()
                .map(|t| f64::from(t.height) / f64::from(t.width.max(1)))
                .collect()
        };
        SurfaceAspects {
            ground: a(ground),
            walls: a(walls),
        }
    }
}

impl BlenderRenderer {
    /// Finds bpy in the venv, starts the interpreter and builds the scene from `models`.
    pub fn new(
        models: Vec<Model>,
        backgrounds: Vec<Arc<Texture>>,
        options: BlenderOptions,
    ) -> Result<Self, Error> {
        Self::with_surfaces(models, backgrounds, Vec::new(), Vec::new(), options)
    }

    /// [`BlenderRenderer::new`] with the images frames with ground and wall textures pick
    /// from (the same lists, in the same order, as the raster's
    /// `CpuRenderer::with_surface_textures`).
    pub fn with_surfaces(
        models: Vec<Model>,
        backgrounds: Vec<Arc<Texture>>,
        ground: Vec<Arc<Texture>>,
        walls: Vec<Arc<Texture>>,
        options: BlenderOptions,
    ) -> Result<Self, Error> {
        options.validate()?;
        let venv = resolve_venv(options.venv.as_deref()).ok_or_else(|| Error::BpyNotFound {
            reason: "no venv given and no HOME for the default location".into(),
            venv: PathBuf::new(),
        })?;
        let site = bpy_site_packages(&venv)?;
        let scratch = match &options.scratch_dir {
            Some(d) => d.clone(),
            None => std::env::temp_dir().join(format!("synthgen-blender-{}", std::process::id())),
        };
        std::fs::create_dir_all(&scratch).map_err(|source| Error::Io {
            action: "cannot create the scratch folder for render passes",
            source,
            path: scratch.clone(),
        })?;
        let raster = CpuRenderer::new(models.clone(), backgrounds)?
            .with_surface_textures(&ground, &walls)?;
        let aspects = SurfaceAspects::of(&ground, &walls);

        let (job_tx, job_rx) = channel::<Job>();
        let (ready_tx, ready_rx) = channel::<Result<(), Error>>();
        let settings = options.settings_json();
        let thread = std::thread::Builder::new()
            .name("blender".into())
            .spawn(move || {
                blender_thread(site, settings, models, [ground, walls], ready_tx, job_rx)
            })
            .map_err(|e| Error::ThreadGone {
                reason: format!("cannot start it: {e}"),
            })?;
        match ready_rx.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => {
                let _ = thread.join();
                return Err(e);
            }
            Err(_) => {
                return Err(Error::ThreadGone {
                    reason: "it ended while loading bpy".into(),
                })
            }
        }
        Ok(BlenderRenderer {
            jobs: Mutex::new(Some(job_tx)),
            thread: Some(thread),
            raster,
            scratch,
            options,
            aspects,
            renders: std::sync::atomic::AtomicU64::new(0),
        })
    }

    pub fn options(&self) -> &BlenderOptions {
        &self.options
    }

    /// The Cycles frame and the raster frame of the same scene (the raster one gives the
    /// alone depths; tests compare the two).
    pub fn render_with_raster(
        &self,
        scene: &FrameScene,
    ) -> Result<(RenderedFrame, RenderedFrame), Error> {
        // The raster render validates the scene (models, poses, intrinsics) first.
        let raster = self.raster.render(scene)?;
        let background_only = FrameScene {
            objects: Vec::new(),
            distractors: Vec::new(),
            ground: None,
            walls: Vec::new(),
            ..scene.clone()
        };
        let background = self.raster.render(&background_only)?;

        // A name per render, not per frame index: two threads may render scenes with the
        // same index (tests, replays of several splits), and each removes its file.
        let render_id = self
            .renders
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let exr_path = self
            .scratch
            .join(format!("frame_{:09}_{render_id}.exr", scene.frame_index));
        let (reply_tx, reply_rx) = channel();
        {
            let jobs = self.jobs.lock().map_err(|_| Error::ThreadGone {
                reason: "a previous render panicked".into(),
            })?;
            let tx = jobs.as_ref().ok_or_else(|| Error::ThreadGone {
                reason: "the renderer is shutting down".into(),
            })?;
            tx.send(Job {
                frame_json: frame_json_with(scene, &self.aspects),
                exr_path: exr_path.clone(),
                reply: reply_tx,
            })
            .map_err(|_| Error::ThreadGone {
                reason: "it no longer takes frames".into(),
            })?;
        }
        reply_rx.recv().map_err(|_| Error::ThreadGone {
            reason: "it ended during a render".into(),
        })??;
        let passes = read_passes(&exr_path);
        let _ = std::fs::remove_file(&exr_path);
        let passes = passes?;
        let k = &scene.intrinsics;
        if (passes.width, passes.height) != (k.width, k.height) {
            return Err(Error::Passes {
                reason: format!(
                    "passes are {}x{}, the camera is {}x{}",
                    passes.width, passes.height, k.width, k.height
                ),
                path: exr_path,
            });
        }
        let frame = RenderedFrame {
            width: k.width,
            height: k.height,
            rgb: composite_over(&passes.rgba, &background.rgb),
            depth_m: depth_from_z(&passes.z),
            instance: instance_from_index(&passes.index, scene.objects.len()),
            alone: raster.alone.clone(),
        };
        Ok((frame, raster))
    }
}

impl Drop for BlenderRenderer {
    fn drop(&mut self) {
        if let Ok(mut jobs) = self.jobs.lock() {
            jobs.take(); // the thread's loop ends when its channel closes
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        let _ = std::fs::remove_dir(&self.scratch);
    }
}

impl Renderer for BlenderRenderer {
    fn render(&self, scene: &FrameScene) -> Result<RenderedFrame, synthgen_render::Error> {
        self.render_with_raster(scene)
            .map(|(frame, _)| frame)
            .map_err(|e| match e {
                Error::Raster(e) => e,
                other => synthgen_render::Error::Backend {
                    backend: "blender",
                    source: Box::new(other),
                },
            })
    }

    fn name(&self) -> &str {
        "blender"
    }
}

fn py_error(action: &str, py: Python<'_>, e: PyErr) -> Error {
    let tb = e
        .traceback(py)
        .and_then(|t| t.format().ok())
        .unwrap_or_default();
    Error::Python {
        action: action.to_string(),
        message: format!("{e}{}", if tb.is_empty() { "" } else { "\n" }) + tb.trim_end(),
    }
}

fn blender_thread(
    site: PathBuf,
    settings: String,
    models: Vec<Model>,
    surfaces: [Vec<Arc<Texture>>; 2],
    ready: Sender<Result<(), Error>>,
    jobs: Receiver<Job>,
) {
    let module = Python::attach(|py| init(py, &site, &settings, &models, &surfaces));
    drop(models);
    drop(surfaces);
    let module = match module {
        Ok(m) => {
            let _ = ready.send(Ok(()));
            m
        }
        Err(e) => {
            let _ = ready.send(Err(e));
            return;
        }
    };
    for job in jobs {
        let r = Python::attach(|py| {
            let path = job.exr_path.to_string_lossy().into_owned();
            module
                .bind(py)
                .getattr("render_frame")
                .and_then(|f| f.call1((job.frame_json.as_str(), path)))
                .map(|_| ())
                .map_err(|e| py_error("rendering a frame", py, e))
        });
        let _ = job.reply.send(r);
    }
}

fn init(
    py: Python<'_>,
    site: &Path,
    settings: &str,
    models: &[Model],
    surfaces: &[Vec<Arc<Texture>>; 2],
) -> Result<Py<PyModule>, Error> {
    let sys_path = py
        .import("sys")
        .and_then(|s| s.getattr("path"))
        .map_err(|e| py_error("reading sys.path", py, e))?;
    sys_path
        .call_method1("insert", (0, site.to_string_lossy().into_owned()))
        .map_err(|e| py_error("extending sys.path", py, e))?;
    let code = CString::new(SCENE_SCRIPT).map_err(|_| Error::Python {
        action: "loading the scene script".into(),
        message: "the script contains a NUL byte".into(),
    })?;
    let module =
        PyModule::from_code(py, &code, c"synthgen_scene.py", c"synthgen_scene").map_err(|e| {
            let err = py_error("importing bpy and the scene script", py, e);
            match err {
                Error::Python { message, .. } if message.contains("No module named") => {
                    Error::BpyNotFound {
                        reason: format!("python could not import it ({})", first_line(&message)),
                        venv: site.to_path_buf(),
                    }
                }
                other => other,
            }
        })?;
    module
        .getattr("setup")
        .and_then(|f| f.call1((settings,)))
        .map_err(|e| py_error("setting up the scene", py, e))?;
    let add_image = module
        .getattr("add_surface_image")
        .map_err(|e| py_error("setting up the scene", py, e))?;
    for (kind, images) in ["ground", "walls"].iter().zip(surfaces) {
        for t in images {
            add_image
                .call1((*kind, t.width, t.height, PyBytes::new(py, &t.rgb)))
                .map_err(|e| py_error("adding a surface texture", py, e))?;
        }
    }
    let add = module
        .getattr("add_primitive")
        .map_err(|e| py_error("setting up the scene", py, e))?;
    for (mi, model) in models.iter().enumerate() {
        for (pi, prim) in model.primitives.iter().enumerate() {
            let positions: Vec<u8> = prim
                .positions_m
                .iter()
                .flat_map(|p| p.to_array())
                .flat_map(f32::to_le_bytes)
                .collect();
            let triangles: Vec<u8> = prim
                .triangles
                .iter()
                .flatten()
                .flat_map(|i| i.to_le_bytes())
                .collect();
            let normals = prim.normals.as_ref().map(|n| {
                let b: Vec<u8> = n
                    .iter()
                    .flat_map(|v| v.to_array())
                    .flat_map(f32::to_le_bytes)
                    .collect();
                PyBytes::new(py, &b)
            });
            let colors = prim.colors.as_ref().map(|c| {
                let b: Vec<u8> = c
                    .iter()
                    .flatten()
                    .map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
                    .collect();
                PyBytes::new(py, &b)
            });
            let uvs = prim.uvs.as_ref().map(|u| {
                let b: Vec<u8> = u
                    .iter()
                    .flat_map(|v| v.to_array())
                    .flat_map(f32::to_le_bytes)
                    .collect();
                PyBytes::new(py, &b)
            });
            let texture = prim
                .material
                .texture
                .as_ref()
                .map(|t| (t.width, t.height, PyBytes::new(py, &t.rgb)));
            let m = &prim.material;
            let material = format!(
                "{{\"base_color\": [{}, {}, {}]}}",
                m.base_color[0], m.base_color[1], m.base_color[2]
            );
            let name = format!("{}.{pi}", model.name);
            add.call1((
                mi,
                name,
                PyBytes::new(py, &positions),
                PyBytes::new(py, &triangles),
                normals,
                colors,
                uvs,
                texture,
                material,
            ))
            .map_err(|e| py_error(&format!("loading model {}", model.name), py, e))?;
        }
    }
    Ok(module.unbind())
}

fn first_line(s: &str) -> &str {
    s.lines().next().unwrap_or(s)
}

fn rows(m: &DMat3, t: DVec3) -> String {
    let r = |i: usize| {
        let row = m.row(i);
        format!("[{}, {}, {}, {}]", row.x, row.y, row.z, t[i])
    };
    format!("[{}, {}, {}, [0, 0, 0, 1]]", r(0), r(1), r(2))
}

/// Principled roughness for a Blinn-Phong exponent (Beckmann α = sqrt(2 / (n + 2)),
/// roughness = sqrt(α)).
fn roughness(shininess: f32) -> f64 {
    (2.0 / (f64::from(shininess.max(0.0)) + 2.0)).sqrt().sqrt()
}

/// The frame for `render_frame` in blender/synthgen_scene.py, as JSON, for a renderer with
/// no surface images (image textures are left out). Every pose is in the OpenCV camera
/// frame; the camera's rotation is the one convention change.
pub fn frame_json(scene: &FrameScene) -> String {
    frame_json_with(scene, &SurfaceAspects::default())
}

/// The mapping of an image texture on a plane of `size_m` (x, y) for the script's mapping
/// node: tiles per object unit (the plane mesh is a unit square scaled by its size) and the
/// offset in tiles, y negated because Blender's image v runs from the bottom row up while
/// the raster's rows run down. `null` when there is no texture or no image.
fn texture_json(t: Option<&SurfaceTexture>, size_m: [f64; 2], aspects: &[f64]) -> String {
    let Some(t) = t else {
        return "null".into();
    };
    if aspects.is_empty() {
        return "null".into();
    }
    let image = (t.image % aspects.len() as u64) as usize;
    let a = aspects[image];
    format!(
        "{{\"image\": {image}, \"scale\": [{}, {}], \"offset\": [{}, {}]}}",
        size_m[0] / t.scale_m,
        -size_m[1] / (t.scale_m * a),
        t.offset[0],
        -t.offset[1]
    )
}

/// [`frame_json`] for a renderer holding surface images with these aspect ratios.
pub fn frame_json_with(scene: &FrameScene, aspects: &SurfaceAspects) -> String {
    let cam = BlenderCamera::from_intrinsics(&scene.intrinsics);
    let centre = if scene.objects.is_empty() {
        scene
            .ground
            .as_ref()
            .map_or(DVec3::new(0.0, 0.0, 1.0), |g| {
                g.cam_from_plane.translation_m
            })
    } else {
        scene
            .objects
            .iter()
            .map(|o| o.cam_from_obj.translation_m)
            .sum::<DVec3>()
            / scene.objects.len() as f64
    };
    // Distractors render with pass index 0: no instance id, like the background.
    let n = scene.objects.len();
    let ggx = scene.shading == synthgen_core::scene::Shading::Ggx;
    let objects: Vec<String> = scene
        .objects
        .iter()
        .chain(&scene.distractors)
        .enumerate()
        .map(|(i, o)| {
            let (tint, hue) = (o.tint, synthgen_core::color::hue_rotation(f64::from(o.hue_deg)));
            format!(
                "{{\"model_index\": {}, \"pass_index\": {}, \"matrix\": {}, \"brightness\": {}, \"tint\": [{}, {}, {}], \"hue_matrix\": {:?}, \"roughness\": {}, \"specular_ior_level\": {}, \"metallic\": {}}}",
                o.model_index,
                if i < n { i + 1 } else { 0 },
                rows(&o.cam_from_obj.rotation, o.cam_from_obj.translation_m),
                o.brightness,
                tint[0],
                tint[1],
                tint[2],
                hue,
                roughness(o.shininess),
                // Phong: the raster default specular 0.2 maps to Blender's default 0.5 (F0 =
                // 4 %). GGX: the same convention on both sides (F0 = 0.08 × specular).
                if ggx {
                    f64::from(o.specular).clamp(0.0, 1.0)
                } else {
                    (f64::from(o.specular) * 2.5).clamp(0.0, 1.0)
                },
                if ggx { f64::from(o.metallic.clamp(0.0, 1.0)) } else { 0.0 },
            )
        })
        .collect();
    let lights: Vec<String> = scene
        .lights
        .iter()
        .map(|l| {
            let d2 = (l.position_cam_m - centre).length_squared().max(1e-6);
            format!(
                "{{\"position\": [{}, {}, {}], \"color\": [{}, {}, {}], \"power_w\": {}}}",
                l.position_cam_m.x,
                l.position_cam_m.y,
                l.position_cam_m.z,
                l.color[0],
                l.color[1],
                l.color[2],
                f64::from(l.intensity) * d2 * WATTS_PER_IRRADIANCE_AT_1M
            )
        })
        .collect();
    let ground = scene.ground.as_ref().map_or("null".to_string(), |g| {
        format!(
            "{{\"matrix\": {}, \"size_m\": {}, \"color\": [{}, {}, {}], \"texture_strength\": {}, \"texture\": {}}}",
            rows(&g.cam_from_plane.rotation, g.cam_from_plane.translation_m),
            g.size_m,
            g.color[0],
            g.color[1],
            g.color[2],
            g.texture_strength,
            texture_json(g.texture.as_ref(), [g.size_m; 2], &aspects.ground)
        )
    });
    let walls: Vec<String> = scene
        .walls
        .iter()
        .map(|w| {
            format!(
                "{{\"matrix\": {}, \"width_m\": {}, \"height_m\": {}, \"color\": [{}, {}, {}], \"texture\": {}}}",
                rows(&w.cam_from_wall.rotation, w.cam_from_wall.translation_m),
                w.width_m,
                w.height_m,
                w.color[0],
                w.color[1],
                w.color[2],
                texture_json(w.texture.as_ref(), [w.width_m, w.height_m], &aspects.walls)
            )
        })
        .collect();
    // The sky/ground probe with the world's up in the camera frame (the Blender world frame).
    let environment = scene
        .environment
        .map_or("null".to_string(), |[sky, ground]| {
            let up = scene.world_from_cam.rotation.transpose() * DVec3::Z;
            format!(
                "{{\"sky\": [{}, {}, {}], \"ground\": [{}, {}, {}], \"up\": [{}, {}, {}]}}",
                sky[0], sky[1], sky[2], ground[0], ground[1], ground[2], up.x, up.y, up.z
            )
        });
    format!(
        "{{\"seed\": {}, \"camera\": {{\"width\": {}, \"height\": {}, \"lens_mm\": {}, \"sensor_width_mm\": {}, \"shift_x\": {}, \"shift_y\": {}, \"y_scale\": {}, \"matrix_world\": {}}}, \"objects\": [{}], \"lights\": [{}], \"ambient\": {}, \"environment\": {}, \"ground\": {}, \"walls\": [{}]}}",
        scene.frame_index,
        cam.width,
        cam.height,
        cam.lens_mm,
        cam.sensor_width_mm,
        cam.shift_x,
        cam.shift_y,
        cam.y_scale,
        rows(&OPENCV_CAM_FROM_BLENDER_CAM, DVec3::ZERO),
        objects.join(", "),
        lights.join(", "),
        scene.ambient,
        environment,
        ground,
        walls.join(", ")
    )
}
