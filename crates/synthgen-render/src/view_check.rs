//! The view check for `camera.min_visib_fract`: a depth-only pass of the CPU raster (each
//! target alone on the 3x canvas, distractors on the image, the ground plane and walls where
//! a target is) and BOP's pixel counts, with no shading, background or mask images.

use synthgen_core::annotate::{visible_bop19, DEFAULT_VISIB_DELTA_M};
use synthgen_core::{AloneDepth, FrameScene, ViewCheck, Visibility};

use crate::cpu::{composite, raster_into};
use crate::ground::Ground;
use crate::raster::{canvas_and_image, ObjScratch, Rect};
use crate::CpuRenderer;

/// Counts target pixels exactly as a render followed by `synthgen_core::annotate` would
/// (same raster, same composite, same ground depth), at the full image resolution.
#[derive(Clone)]
pub struct ViewChecker {
    renderer: CpuRenderer,
    delta_m: f32,
}

impl ViewChecker {
    /// `renderer` must hold the same models, in the same order, as the one that renders the
    /// frames; `delta_m` is the visibility tolerance (BOP's `delta`).
    pub fn new(renderer: CpuRenderer, delta_m: f32) -> ViewChecker {
        ViewChecker { renderer, delta_m }
    }

    pub fn with_default_delta(renderer: CpuRenderer) -> ViewChecker {
        Self::new(renderer, DEFAULT_VISIB_DELTA_M)
    }

    /// The counts for every object of `scene`.
    pub fn count(&self, scene: &FrameScene) -> Result<Vec<Visibility>, crate::Error> {
        let r = &self.renderer;
        r.validate(scene)?;
        let k = &scene.intrinsics;
        let proj = r.projection(k);
        let (w, h) = (k.width as usize, k.height as usize);
        let (canvas, image) = canvas_and_image(k);
        let (wi, hi) = (image.x1, image.y1);
        let mut os = ObjScratch::default();
        let raster = |insts: &[synthgen_core::ObjectInstance], on: Rect, os: &mut ObjScratch| {
            insts
                .iter()
                .map(|inst| {
                    let mut a = AloneDepth::default();
                    raster_into(r.prepared(inst.model_index), inst, &proj, on, os, &mut a);
                    a
                })
                .collect::<Vec<_>>()
        };
        let targets = raster(&scene.objects, canvas, &mut os);
        let distractors = raster(&scene.distractors, image, &mut os);
        let mut depth = vec![0f32; w * h];
        let mut instance = vec![0u16; w * h];
        composite(&targets, 1, &image, w, &mut depth, &mut instance);
        let next = scene.objects.len() as u16 + 1;
        composite(&distractors, next, &image, w, &mut depth, &mut instance);

        // The ground and the walls win ties, as in the renderer; only where a target is
        // matters.
        let planes: Vec<Ground> = scene
            .ground
            .iter()
            .map(|g| Ground::new(g, None))
            .chain(scene.walls.iter().map(|w| Ground::wall(w, None)))
            .collect();
        let mut row = Vec::new();
        for g in &planes {
            for a in &targets {
                let x0 = a.x0.clamp(0, wi) as usize;
                let x1 = (a.x0 + a.width as i32).clamp(0, wi) as usize;
                if x0 >= x1 {
                    continue;
                }
                let y0 = a.y0.clamp(0, hi) as usize;
                let y1 = (a.y0 + a.height as i32).clamp(0, hi) as usize;
                row.resize(x1 - x0, 0.0);
                for y in y0..y1 {
                    g.plane_depths(y, &proj, x0, &mut row);
                    for (d, &gz) in depth[y * w + x0..y * w + x1].iter_mut().zip(&row) {
                        if gz > 0.0 && (*d == 0.0 || gz <= *d) {
                            *d = gz;
                        }
                    }
                }
            }
        }

        Ok(targets
            .iter()
            .map(|a| {
                let mut v = Visibility::default();
                for ly in 0..a.height as i32 {
                    let y = a.y0 + ly;
                    let src = &a.depth_m[ly as usize * a.width as usize..][..a.width as usize];
                    for (lx, &d) in src.iter().enumerate() {
                        if d <= 0.0 {
                            continue;
                        }
                        v.px_all += 1;
                        let x = a.x0 + lx as i32;
                        if x < 0 || y < 0 || x >= wi || y >= hi {
                            continue;
                        }
                        v.px_in_image += 1;
                        let ds = depth[y as usize * w + x as usize];
                        if visible_bop19(k, x, y, d, ds, self.delta_m) {
                            v.px_visib += 1;
                        }
                    }
                }
                v
            })
            .collect())
    }
}

impl ViewCheck for ViewChecker {
    fn visibility(&self, scene: &FrameScene) -> Result<Vec<Visibility>, String> {
        self.count(scene).map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use synthgen_core::distractor::{primitive_models, DistractorPool};
    use synthgen_core::glam::Vec3;
    use synthgen_core::sample::SceneObject;
    use synthgen_core::{annotate, Model, SceneSampler, SceneSpec};

    use super::*;
    use crate::Renderer;

    /// Two boxes and up to 6 primitive distractors packed together, rendered.
    fn setup(min_visib: f64) -> (CpuRenderer, SceneSampler) {
        let mut spec = SceneSpec::default();
        spec.camera.width = Some(160);
        spec.camera.height = Some(120);
        spec.camera.fx = Some(143.0);
        spec.camera.fy = Some(143.0);
        spec.camera.cx = Some(80.0);
        spec.camera.cy = Some(60.0);
        spec.camera.min_visib_fract = min_visib;
        spec.camera.max_view_tries = 200;
        spec.camera.allow_truncation = false;
        spec.placement.area_m = [0.2, 0.2];
        spec.placement.min_gap_m = 0.0;
        spec.camera_pose.elevation_deg = [10.0, 40.0];
        spec.distractors.count = [4, 6];
        let mut models = vec![Model::cuboid("box", Vec3::new(0.06, 0.05, 0.08))];
        let targets = SceneObject::one_per_model(&models);
        let targets = vec![
            targets[0].clone(),
            SceneObject {
                obj_id: 2,
                ..targets[0].clone()
            },
        ];
        let prims = primitive_models(&spec.distractors);
        let pool = DistractorPool {
            primitives: prims
                .iter()
                .enumerate()
                .map(|(i, m)| SceneObject::new(1 + i, 0, m))
                .collect(),
            meshes: Vec::new(),
        };
        models.extend(prims);
        let renderer = CpuRenderer::new(models, vec![]).unwrap();
        let sampler = SceneSampler::new(spec, targets, 3)
            .unwrap()
            .with_distractors(pool)
            .with_view_check(Arc::new(ViewChecker::with_default_delta(renderer.clone())));
        (renderer, sampler)
    }

    #[test]
    fn counts_match_render_and_annotate_with_distractors() {
        let (renderer, sampler) = setup(0.0);
        let check = ViewChecker::with_default_delta(renderer.clone());
        let mut occluded = 0;
        for f in 0..12 {
            let scene = sampler.sample(f).unwrap();
            assert!(scene.distractors.len() >= 4);
            let frame = renderer.render(&scene).unwrap();
            assert_eq!(frame.alone.len(), 2, "distractors get no alone render");
            assert!(
                frame.instance.iter().all(|&i| i <= 2),
                "distractor ids leak"
            );
            let ann = annotate(&scene.intrinsics, &frame.depth_m, &frame.alone, 0.015);
            let vis = check.count(&scene).unwrap();
            for (a, v) in ann.iter().zip(&vis) {
                assert_eq!(a.info.px_count_all, v.px_all, "frame {f}");
                assert_eq!(a.info.px_count_visib, v.px_visib, "frame {f}");
                if v.visib_fract() < 0.999 {
                    occluded += 1;
                }
            }
        }
        assert!(
            occluded > 0,
            "no target was ever occluded: the test shows nothing"
        );
    }

    #[test]
    fn rejection_keeps_only_views_above_the_threshold() {
        let (renderer, sampler) = setup(0.8);
        for f in 0..12 {
            let scene = sampler.sample(f).unwrap();
            let frame = renderer.render(&scene).unwrap();
            let ann = annotate(&scene.intrinsics, &frame.depth_m, &frame.alone, 0.015);
            for a in &ann {
                assert!(
                    a.info.visib_fract >= 0.8,
                    "frame {f}: {}",
                    a.info.visib_fract
                );
                assert_eq!(
                    a.info.bbox_obj,
                    a.info.bbox_obj.map(|v| v.max(0)),
                    "truncated"
                );
            }
        }
    }
}
