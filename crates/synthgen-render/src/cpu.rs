//! The embedded CPU renderer: per object a windowed raster (its alone depth), then a
//! composite with the ground plane, then deferred shading of the visible pixels.

use std::cell::RefCell;
use std::sync::Arc;

use rayon::prelude::*;
use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::scene::BackgroundKind;
use synthgen_core::{
    AloneDepth, DepthWindowMm, FrameScene, Model, ObjectInstance, RenderedFrame, Texture,
};

use crate::background::Background;
use crate::bits::select;
use crate::color::ColorLuts;
use crate::ground::{Ground, GroundRow, TileTables};
use crate::prepare::{prepare, validate_texture, PreparedModel};
use crate::raster::{canvas_and_image, raster_object, ObjScratch, Projection, Rect};
use crate::shade::{shade_pixels, Light, ShadeBatch, ShadeParams};
use crate::surface::{SurfaceImage, TexMap};
use crate::{Error, Renderer};

/// Tunables of the CPU renderer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CpuOptions {
    /// Near clipping plane, metres along the optical axis. Default 0.01.
    pub near_m: f32,
}

impl Default for CpuOptions {
    fn default() -> Self {
        Self { near_m: 0.01 }
    }
}

/// The embedded rasterizer. Immutable after construction, so one renderer can serve all
/// threads (`render_frames` renders frames in parallel).
#[derive(Clone)]
pub struct CpuRenderer {
    models: Arc<[PreparedModel]>,
    backgrounds: Vec<Arc<Texture>>,
    options: CpuOptions,
    luts: ColorLuts,
    tiles: TileTables,
    /// Images for `ground.texture_dir` and `walls.texture_dir`, prepared once.
    ground_textures: Arc<[Arc<SurfaceImage>]>,
    wall_textures: Arc<[Arc<SurfaceImage>]>,
}

/// Buffers reused from frame to frame on each thread, so a frame allocates only its output.
#[derive(Default)]
struct Scratch {
    objs: Vec<ObjScratch>,
    /// Depth of each distractor on the image (not the 3x canvas: they get no annotations).
    distractor_alone: Vec<AloneDepth>,
    xmap: Vec<u32>,
    ymap: Vec<u32>,
    cam_lights: Vec<Light>,
    batch: ShadeBatch,
    ground_row: GroundRow,
    shadow: crate::shadow::ShadowScratch,
    ao: crate::ao::AoScratch,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
    /// Buffers of `render_depth_mm`.
    static DEPTH_SCRATCH: RefCell<(ObjScratch, Vec<f32>)> = RefCell::new(Default::default());
}

/// Instance ids are u16 with 0 for the background.
const MAX_OBJECTS: usize = u16::MAX as usize - 1;

impl CpuRenderer {
    /// Prepares the models (validated: indices in range, attribute lengths, finite
    /// positions, texture sizes) and the background images for `BackgroundKind::Images`.
    pub fn new(models: Vec<Model>, backgrounds: Vec<Arc<Texture>>) -> Result<Self, Error> {
        Self::with_options(models, backgrounds, CpuOptions::default())
    }

    pub fn with_options(
        models: Vec<Model>,
        backgrounds: Vec<Arc<Texture>>,
        options: CpuOptions,
    ) -> Result<Self, Error> {
        if !(options.near_m.is_finite() && options.near_m > 0.0) {
            return Err(Error::InvalidOption {
                name: "near_m",
                reason: format!("must be finite and > 0, got {}", options.near_m),
            });
        }
        for b in &backgrounds {
            validate_texture(b)?;
        }
        let models = models
            .into_iter()
            .map(prepare)
            .collect::<Result<Vec<_>, _>>()?;
        Ok(CpuRenderer {
            models: models.into(),
            backgrounds,
            options,
            luts: ColorLuts::new(),
            tiles: TileTables::new(),
            ground_textures: Arc::new([]),
            wall_textures: Arc::new([]),
        })
    }

    /// Adds the images frames with `GroundInstance::texture` and `WallInstance::texture`
    /// pick from (validated, converted to linear light and mip-mapped here, once).
    pub fn with_surface_textures(
        mut self,
        ground: &[Arc<Texture>],
        walls: &[Arc<Texture>],
    ) -> Result<Self, Error> {
        self.ground_textures = SurfaceImage::prepare_all(ground)?.into();
        self.wall_textures = SurfaceImage::prepare_all(walls)?.into();
        Ok(self)
    }

    pub fn options(&self) -> &CpuOptions {
        &self.options
    }

    pub fn model_count(&self) -> usize {
        self.models.len()
    }

    pub(crate) fn prepared(&self, model_index: usize) -> &PreparedModel {
        &self.models[model_index]
    }

    pub(crate) fn projection(&self, k: &synthgen_core::Intrinsics) -> Projection {
        Projection {
            fx: k.fx as f32,
            fy: k.fy as f32,
            cx: k.cx as f32,
            cy: k.cy as f32,
            near_m: self.options.near_m,
        }
    }

    pub(crate) fn validate(&self, scene: &FrameScene) -> Result<(), Error> {
        let k = &scene.intrinsics;
        k.validate().map_err(|e| Error::InvalidIntrinsics {
            reason: e.to_string(),
        })?;
        let count = scene.objects.len() + scene.distractors.len();
        if count > MAX_OBJECTS {
            return Err(Error::TooManyObjects {
                count,
                max: MAX_OBJECTS,
            });
        }
        // Distractors are numbered after the objects in errors.
        for (i, o) in scene.objects.iter().chain(&scene.distractors).enumerate() {
            if o.model_index >= self.models.len() {
                return Err(Error::UnknownModel {
                    object: i,
                    model_index: o.model_index,
                    model_count: self.models.len(),
                });
            }
            o.cam_from_obj
                .validate(1e-4)
                .map_err(|e| Error::InvalidPose {
                    what: format!("object {i} ({})", self.models[o.model_index].name),
                    reason: e.to_string(),
                })?;
        }
        if scene.background.kind == BackgroundKind::Images && self.backgrounds.is_empty() {
            return Err(Error::NoBackgroundImages);
        }
        if let Some(g) = &scene.ground {
            g.cam_from_plane
                .validate(1e-4)
                .map_err(|e| Error::InvalidPose {
                    what: "ground plane".into(),
                    reason: e.to_string(),
                })?;
            if g.texture.is_some() && self.ground_textures.is_empty() {
                return Err(Error::NoSurfaceTextures { what: "ground" });
            }
        }
        for (i, wall) in scene.walls.iter().enumerate() {
            wall.cam_from_wall
                .validate(1e-4)
                .map_err(|e| Error::InvalidPose {
                    what: format!("wall {i}"),
                    reason: e.to_string(),
                })?;
            if wall.texture.is_some() && self.wall_textures.is_empty() {
                return Err(Error::NoSurfaceTextures { what: "walls" });
            }
        }
        Ok(())
    }

    /// Depth (mm along z) of model `model_index` alone at `cam_from_obj` = (`r`, `t_mm`), on
    /// the image of `k` only (a window of it in `out`): no shading, no compositing. Coverage
    /// and the nearest triangle per pixel come from the rasterizer; the depth of each covered
    /// pixel is then the exact (f64) intersection of its ray with that triangle's plane, so it
    /// does not carry the rasterizer's fixed-point snapping. No face is culled (scanned models
    /// have stray windings; OpenGL without face culling draws them). The rotation is used as
    /// given.
    /// Pixel (x, y) samples the projection at (x, y), as everywhere here.
    pub fn render_depth_mm(
        &self,
        model_index: usize,
        r: &DMat3,
        t_mm: DVec3,
        k: &synthgen_core::Intrinsics,
        out: &mut DepthWindowMm,
    ) -> Result<(), Error> {
        k.validate().map_err(|e| Error::InvalidIntrinsics {
            reason: e.to_string(),
        })?;
        let model = self.models.get(model_index).ok_or(Error::UnknownModel {
            object: 0,
            model_index,
            model_count: self.models.len(),
        })?;
        let proj = self.projection(k);
        let (_, image) = canvas_and_image(k);
        DEPTH_SCRATCH.with(|cell| {
            let mut guard = cell.try_borrow_mut();
            let mut fresh = (ObjScratch::default(), Vec::new());
            let (os, depth_m) = match guard.as_deref_mut() {
                Ok(s) => (&mut s.0, &mut s.1),
                Err(_) => (&mut fresh.0, &mut fresh.1),
            };
            self.depth_mm_with(model, r, t_mm, k, &proj, image, os, depth_m, out);
        });
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn depth_mm_with(
        &self,
        model: &PreparedModel,
        r: &DMat3,
        t_mm: DVec3,
        k: &synthgen_core::Intrinsics,
        proj: &Projection,
        image: Rect,
        os: &mut ObjScratch,
        depth_m: &mut Vec<f32>,
        out: &mut DepthWindowMm,
    ) {
        let rot = r.as_mat3();
        let t = (t_mm / 1000.0).as_vec3();
        let win = raster_object(model, true, &rot, t, proj, image, os, depth_m);
        out.x0 = win.x0;
        out.y0 = win.y0;
        out.width = win.width() as u32;
        out.height = win.height() as u32;
        out.depth_mm.clear();
        out.depth_mm.resize(depth_m.len(), 0.0);
        let vert = |i: u32| {
            let i = i as usize;
            let p = DVec3::new(model.xs[i] as f64, model.ys[i] as f64, model.zs[i] as f64);
            *r * (p * 1000.0) + t_mm
        };
        let w = win.width();
        if w == 0 {
            return;
        }
        // The plane of the last triangle seen (n, n·a): neighbouring pixels share triangles.
        let mut plane: Option<(u32, DVec3, f64)> = None;
        for (row, (drow, orow)) in depth_m
            .chunks_exact(w)
            .zip(out.depth_mm.chunks_exact_mut(w))
            .enumerate()
        {
            let ry = ((win.y0 + row as i32) as f64 - k.cy) / k.fy;
            for (col, (&d, out_d)) in drow.iter().zip(orow.iter_mut()).enumerate() {
                if d <= 0.0 {
                    continue;
                }
                let id = os.ids[row * w + col];
                let (n, na) = match plane {
                    Some((pid, n, na)) if pid == id => (n, na),
                    _ => {
                        let tri = model.tris[id as usize];
                        let (a, b, c) = (vert(tri[0]), vert(tri[1]), vert(tri[2]));
                        let n = (b - a).cross(c - a);
                        let na = n.dot(a);
                        plane = Some((id, n, na));
                        (n, na)
                    }
                };
                let rx = ((win.x0 + col as i32) as f64 - k.cx) / k.fx;
                let denom = n.dot(DVec3::new(rx, ry, 1.0));
                let z = na / denom;
                // A triangle seen edge-on has no usable plane: keep the rasterizer's depth.
                *out_d = if denom.abs() > 1e-12 * n.length() && z.is_finite() && z > 0.0 {
                    z as f32
                } else {
                    d * 1000.0
                };
            }
        }
    }

    /// Renders into `out`, reusing its buffers (no allocation once they have grown).
    pub fn render_into(&self, scene: &FrameScene, out: &mut RenderedFrame) -> Result<(), Error> {
        self.validate(scene)?;
        SCRATCH.with(|cell| match cell.try_borrow_mut() {
            Ok(mut s) => self.render_with(scene, out, &mut s),
            // Only reachable if rendering re-entered itself on this thread.
            Err(_) => self.render_with(scene, out, &mut Scratch::default()),
        })
    }

    fn render_with(
        &self,
        scene: &FrameScene,
        out: &mut RenderedFrame,
        scratch: &mut Scratch,
    ) -> Result<(), Error> {
        let k = &scene.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let proj = Projection {
            fx: k.fx as f32,
            fy: k.fy as f32,
            cx: k.cx as f32,
            cy: k.cy as f32,
            near_m: self.options.near_m,
        };
        let n = w * h;
        out.width = k.width;
        out.height = k.height;
        // Depth and instance are accumulated into and must start at 0. Every rgb pixel is
        // written below (background, ground or object); clearing it too is cheap insurance.
        reset(&mut out.rgb, n * 3, 0);
        reset(&mut out.depth_m, n, 0.0);
        reset(&mut out.instance, n, 0);
        out.alone
            .resize_with(scene.objects.len(), AloneDepth::default);
        let n_obj = scene.objects.len();
        let n_all = n_obj + scene.distractors.len();
        if scratch.objs.len() < n_all {
            scratch.objs.resize_with(n_all, ObjScratch::default);
        }
        scratch
            .distractor_alone
            .resize_with(scene.distractors.len(), AloneDepth::default);

        let ground = scene.ground.as_ref().map(|g| {
            let tex = g.texture.as_ref();
            Ground::new(g, tex.and_then(|t| TexMap::new(t, &self.ground_textures)))
        });
        let walls: Vec<Ground> = scene
            .walls
            .iter()
            .map(|w| {
                let tex = w.texture.as_ref();
                Ground::wall(w, tex.and_then(|t| TexMap::new(t, &self.wall_textures)))
            })
            .collect();

        // The canvas for alone renders is three times the image, centred on it.
        let (canvas, image) = canvas_and_image(k);
        for ((inst, alone), os) in scene
            .objects
            .iter()
            .zip(out.alone.iter_mut())
            .zip(scratch.objs.iter_mut())
        {
            let model = &self.models[inst.model_index];
            let rot = inst.cam_from_obj.rotation.as_mat3();
            let t = inst.cam_from_obj.translation_m.as_vec3();
            let win = raster_object(model, false, &rot, t, &proj, canvas, os, &mut alone.depth_m);
            alone.x0 = win.x0;
            alone.y0 = win.y0;
            alone.width = win.width() as u32;
            alone.height = win.height() as u32;
        }
        for ((inst, alone), os) in scene
            .distractors
            .iter()
            .zip(scratch.distractor_alone.iter_mut())
            .zip(scratch.objs[n_obj..].iter_mut())
        {
            raster_into(
                &self.models[inst.model_index],
                inst,
                &proj,
                image,
                os,
                alone,
            );
        }

        composite(
            &out.alone,
            1,
            &image,
            w,
            &mut out.depth_m,
            &mut out.instance,
        );
        // Distractors take the ids after the objects while shading, 0 in the output.
        composite(
            &scratch.distractor_alone,
            n_obj as u16 + 1,
            &image,
            w,
            &mut out.depth_m,
            &mut out.instance,
        );

        let params = ShadeParams {
            ambient: scene.ambient.max(0.0),
            ggx: scene.shading == synthgen_core::scene::Shading::Ggx,
            env: scene
                .environment
                .map(|[sky, ground]| crate::shade::Environment {
                    sky,
                    ground,
                    up_cam: (scene.world_from_cam.rotation.transpose()
                        * synthgen_core::glam::DVec3::Z)
                        .as_vec3(),
                }),
        };
        scratch.cam_lights.clear();
        scratch
            .cam_lights
            .extend(scene.lights.iter().map(Light::from_point_light));
        let bg = Background::new(
            &scene.background,
            &self.backgrounds,
            w,
            h,
            &mut scratch.xmap,
            &mut scratch.ymap,
        )?;
        shade_background_and_ground(
            &bg,
            ground.as_ref(),
            &walls,
            &proj,
            &params,
            &scratch.cam_lights,
            &self.tiles,
            &self.luts,
            out,
            &mut scratch.ground_row,
        );
        for (i, (inst, os)) in scene
            .objects
            .iter()
            .chain(&scene.distractors)
            .zip(&scratch.objs)
            .enumerate()
        {
            shade_object(
                &self.models[inst.model_index],
                inst,
                i as u16 + 1,
                os,
                &proj,
                &params,
                &scratch.cam_lights,
                &self.luts,
                &mut scratch.batch,
                out,
            );
        }
        if scene.ambient_occlusion > 0.0 {
            crate::ao::apply(
                scene,
                &proj,
                &out.depth_m,
                scene.ambient_occlusion.min(1.0),
                &mut out.rgb,
                &mut scratch.ao,
            );
        }
        if scene.shadows {
            crate::shadow::apply(
                &self.models,
                scene,
                &proj,
                &out.depth_m,
                &mut out.rgb,
                &mut scratch.shadow,
            );
        }
        if n_all > n_obj {
            let last = n_obj as u16;
            for v in out.instance.iter_mut() {
                *v = select_u16(*v > last, 0, *v);
            }
        }
        Ok(())
    }
}

#[inline(always)]
fn select_u16(c: bool, a: u16, b: u16) -> u16 {
    if c {
        a
    } else {
        b
    }
}

/// Rasterizes `inst` alone on `canvas` into `alone` (and the scratch's triangle ids).
pub(crate) fn raster_into(
    model: &PreparedModel,
    inst: &ObjectInstance,
    proj: &Projection,
    canvas: Rect,
    os: &mut ObjScratch,
    alone: &mut AloneDepth,
) {
    let rot = inst.cam_from_obj.rotation.as_mat3();
    let t = inst.cam_from_obj.translation_m.as_vec3();
    let win = raster_object(model, false, &rot, t, proj, canvas, os, &mut alone.depth_m);
    alone.x0 = win.x0;
    alone.y0 = win.y0;
    alone.width = win.width() as u32;
    alone.height = win.height() as u32;
}

/// Nearest object per pixel from the objects' alone depths (ties to the lower index); the
/// ground is tested against the result afterwards.
#[inline(never)]
pub(crate) fn composite(
    alone: &[AloneDepth],
    first_id: u16,
    image: &Rect,
    w: usize,
    depth: &mut [f32],
    instance: &mut [u16],
) {
    for (i, a) in alone.iter().enumerate() {
        let id = i as u16 + first_id;
        let win = Rect {
            x0: a.x0,
            y0: a.y0,
            x1: a.x0 + a.width as i32,
            y1: a.y0 + a.height as i32,
        };
        let vis = win.intersect(image);
        if vis.is_empty() {
            continue;
        }
        let aw = a.width as usize;
        for y in vis.y0..vis.y1 {
            let src = &a.depth_m[(y - win.y0) as usize * aw..][(vis.x0 - win.x0) as usize..]
                [..vis.width()];
            let o = y as usize * w + vis.x0 as usize;
            let dst = &mut depth[o..o + vis.width()];
            let ins = &mut instance[o..o + vis.width()];
            for ((&z, d), inst) in src.iter().zip(dst).zip(ins) {
                let win = (z > 0.0) & ((*d == 0.0) | (z < *d));
                *d = select(win, z, *d);
                let m = 0u16.wrapping_sub(win as u16);
                *inst = (id & m) | (*inst & !m);
            }
        }
    }
}

/// The ground plane (depth test against the objects, then its colour), the walls (depth
/// test against both, colour where they win) and the background, row by row.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn shade_background_and_ground(
    bg: &Background,
    ground: Option<&Ground>,
    walls: &[Ground],
    proj: &Projection,
    params: &ShadeParams,
    lights: &[Light],
    tables: &TileTables,
    luts: &ColorLuts,
    out: &mut RenderedFrame,
    row: &mut GroundRow,
) {
    let w = out.width as usize;
    for (y, ((depth, inst), rgb)) in out
        .depth_m
        .chunks_exact_mut(w)
        .zip(out.instance.chunks_exact_mut(w))
        .zip(out.rgb.chunks_exact_mut(w * 3))
        .enumerate()
    {
        if let Some(g) = ground {
            g.draw_row(y, proj, params, lights, tables, luts, depth, inst, rgb, row);
        }
        for wall in walls {
            wall.draw_row_masked(y, proj, params, lights, luts, depth, inst, rgb);
        }
        bg.fill_row(y, depth, rgb);
    }
}

/// Shades the pixels object `id` won, from the triangle ids of its window.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn shade_object(
    model: &PreparedModel,
    inst: &ObjectInstance,
    id: u16,
    os: &ObjScratch,
    proj: &Projection,
    params: &ShadeParams,
    cam_lights: &[Light],
    luts: &ColorLuts,
    batch: &mut ShadeBatch,
    out: &mut RenderedFrame,
) {
    let w = out.width as usize;
    let image = Rect {
        x0: 0,
        y0: 0,
        x1: out.width as i32,
        y1: out.height as i32,
    };
    let win = os.window;
    let vis = win.intersect(&image);
    if vis.is_empty() {
        return;
    }
    batch.clear();
    let aw = win.width();
    for y in vis.y0..vis.y1 {
        let ids =
            &os.ids[(y - win.y0) as usize * aw..][(vis.x0 - win.x0) as usize..][..vis.width()];
        let o = y as usize * w + vis.x0 as usize;
        let inst_row = &out.instance[o..o + vis.width()];
        for (k, (&i, &tri)) in inst_row.iter().zip(ids).enumerate() {
            if i == id {
                batch.push((o + k) as u32, tri, vis.x0 + k as i32, y);
            }
        }
    }
    shade_pixels(
        model,
        inst,
        proj,
        params,
        cam_lights,
        luts,
        batch,
        &mut out.rgb,
    );
}

/// `v = vec![value; n]`, reusing the allocation when it is big enough (a fresh zeroed
/// allocation comes from `calloc`, cheaper than writing zeros).
fn reset<T: Copy>(v: &mut Vec<T>, n: usize, value: T) {
    if v.capacity() < n {
        *v = vec![value; n];
    } else {
        v.clear();
        v.resize(n, value);
    }
}

impl Renderer for CpuRenderer {
    fn render(&self, scene: &FrameScene) -> Result<RenderedFrame, Error> {
        let mut out = RenderedFrame::default();
        self.render_into(scene, &mut out)?;
        Ok(out)
    }

    fn name(&self) -> &str {
        "cpu"
    }
}

/// Renders `scenes` in parallel (rayon, one frame per task). The result is the same, byte for
/// byte, whatever the number of threads.
pub fn render_frames(
    renderer: &CpuRenderer,
    scenes: &[FrameScene],
) -> Vec<Result<RenderedFrame, Error>> {
    scenes.par_iter().map(|s| renderer.render(s)).collect()
}
