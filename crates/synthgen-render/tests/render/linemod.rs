//! Real Linemod models: geometry round trip against the mesh, and a full 640x480 frame
//! written for a visual check when `SYNTHGEN_RENDER_CHECK_DIR` is set.

use std::path::Path;

use synthgen_core::mesh::point_triangle_distance;
use synthgen_core::{annotate, Model, NoProgress, SceneObject, SceneSampler, SceneSpec};
use synthgen_render::{CpuRenderer, Renderer};

use crate::common::*;

pub const LMO_IDS: [u32; 5] = [1, 5, 6, 8, 9];

fn load(dir: &Path) -> Vec<Model> {
    LMO_IDS
        .iter()
        .map(|id| {
            let path = dir.join(format!("obj_{id:06}.ply"));
            synthgen_assets::load_model(&path, synthgen_assets::Units::Mm, &NoProgress)
                .unwrap()
                .model
        })
        .collect()
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn linemod_frame_round_trip_and_check_images() {
    let dir = lmo_models_dir();
    let models = load(&dir);
    let objects: Vec<SceneObject> = models
        .iter()
        .enumerate()
        .map(|(i, m)| SceneObject::new(i, LMO_IDS[i], m))
        .collect();
    let r = CpuRenderer::new(models.clone(), vec![]).unwrap();
    let sampler = SceneSampler::new(SceneSpec::default(), objects, 1).unwrap();
    // The first frame that shows some background too (low camera elevation).
    let (scene, f) = (0..40)
        .map(|i| {
            let s = sampler.sample(i).unwrap();
            let f = r.render(&s).unwrap();
            (s, f)
        })
        .find(|(_, f)| f.depth_m.iter().filter(|&&d| d == 0.0).count() > 10_000)
        .expect("a frame with background among the first 40");
    let k = scene.intrinsics;
    let ann = annotate(&k, &f.depth_m, &f.alone, 0.015);

    // Every object's visible pixels back-project onto its mesh.
    let mut rng = TestRng::new(17);
    for (i, inst) in scene.objects.iter().enumerate() {
        let m = &models[inst.model_index];
        let p = &m.primitives[0];
        let obj_from_cam = inst.cam_from_obj.inverse();
        let pix: Vec<usize> = (0..f.instance.len())
            .filter(|&j| f.instance[j] == i as u16 + 1)
            .collect();
        assert_eq!(pix.len() as u64, ann[i].info.px_count_visib);
        if pix.is_empty() {
            continue;
        }
        let mut dists = Vec::new();
        for _ in 0..60 {
            let j = pix[(rng.next_f64() * pix.len() as f64) as usize];
            let (x, y) = ((j % 640) as f64, (j / 640) as f64);
            let q = obj_from_cam.transform_point(k.back_project(x, y, f.depth_m[j] as f64));
            let d = p
                .triangles
                .iter()
                .map(|t| {
                    let v = t.map(|i| p.positions_m[i as usize].as_dvec3());
                    point_triangle_distance(q, v[0], v[1], v[2])
                })
                .fold(f64::INFINITY, f64::min);
            dists.push(d);
        }
        let med = median(dists.clone());
        let max = dists.iter().cloned().fold(0.0, f64::max);
        assert!(med < 5e-4, "object {i}: median distance {med} m");
        assert!(max < 2e-3, "object {i}: max distance {max} m");
    }

    if let Some(out) = std::env::var_os("SYNTHGEN_RENDER_CHECK_DIR") {
        write_check_images(Path::new(&out), &f);
    }
}

fn write_check_images(out: &Path, f: &synthgen_core::RenderedFrame) {
    std::fs::create_dir_all(out).unwrap();
    let (w, h) = (f.width, f.height);
    image::RgbImage::from_raw(w, h, f.rgb.clone())
        .unwrap()
        .save(out.join("rgb.png"))
        .unwrap();
    let valid: Vec<f32> = f.depth_m.iter().cloned().filter(|&d| d > 0.0).collect();
    let (lo, hi) = valid
        .iter()
        .fold((f32::INFINITY, 0.0f32), |(a, b), &d| (a.min(d), b.max(d)));
    let depth: Vec<u8> = f
        .depth_m
        .iter()
        .map(|&d| {
            if d > 0.0 {
                (255.0 - 235.0 * (d - lo) / (hi - lo).max(1e-6)) as u8
            } else {
                0
            }
        })
        .collect();
    image::GrayImage::from_raw(w, h, depth)
        .unwrap()
        .save(out.join("depth.png"))
        .unwrap();
    let palette = [
        [0, 0, 0],
        [230, 25, 75],
        [60, 180, 75],
        [255, 225, 25],
        [0, 130, 200],
        [245, 130, 48],
    ];
    // Instance colours, with the alone silhouettes' outlines in white over them.
    let mut inst: Vec<u8> = f
        .instance
        .iter()
        .flat_map(|&i| palette[i as usize % palette.len()])
        .collect();
    for a in &f.alone {
        for y in 0..h as i32 {
            for x in 0..w as i32 {
                let here = a.at(x, y) > 0.0;
                let edge = here
                    && [(1, 0), (-1, 0), (0, 1), (0, -1)]
                        .iter()
                        .any(|(dx, dy)| a.at(x + dx, y + dy) == 0.0);
                if edge {
                    let o = ((y as u32 * w + x as u32) * 3) as usize;
                    inst[o..o + 3].copy_from_slice(&[255, 255, 255]);
                }
            }
        }
    }
    image::RgbImage::from_raw(w, h, inst)
        .unwrap()
        .save(out.join("instance.png"))
        .unwrap();
}
