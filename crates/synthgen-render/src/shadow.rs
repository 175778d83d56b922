//! Cast shadows for the embedded rasterizer (`[lights] shadows = true`): one shadow map per
//! point light, rendered with the same rasterizer from the light towards the objects (the
//! casters: targets and distractors), then every shaded pixel (objects, ground, walls) is
//! tested against it with 3x3 percentage-closer filtering (soft edges) and darkened by the
//! share of its light it loses: with the normal from the depth buffer
//! (`depth_features::normal_cam`, as the sensor models compute it), the pixel received
//! `ambient + Σ I_l max(0, n·l_l)` (Lambert, as it was shaded), so a blocked light `l` takes
//! `I_l max(0, n·l_l)` of it away (a face turned away from the light loses nothing it had);
//! applied in linear space.

use synthgen_core::glam::{Mat3, Vec3};
use synthgen_core::{depth_features, FrameScene, ObjectInstance};

use crate::prepare::PreparedModel;
use crate::raster::{raster_object, ObjScratch, Projection, Rect};

/// Shadow-map side, texels.
pub(crate) const MAP: usize = 1024;
/// Neighbours within this share of a pixel's depth lie on its surface (for its normal).
const SAME_SURFACE: f32 = 0.05;

/// Buffers reused from frame to frame.
#[derive(Default)]
pub(crate) struct ShadowScratch {
    map: Vec<f32>,
    alone: Vec<f32>,
    os: ObjScratch,
    /// Per pixel: the share of the light lost, summed over lights.
    lost: Vec<f32>,
    tables: LinearTables,
}

/// Lambert's cosine at camera-frame point `xc` of unit normal `n` towards a light at `light`
/// (0 for a face turned away).
#[inline]
fn lambert(n: Vec3, xc: Vec3, light: Vec3) -> f32 {
    n.dot((light - xc).normalize_or_zero()).max(0.0)
}

/// What the scene's point lights gave a surface point `xc` of unit normal `n` (camera frame),
/// as the shading computed it: Σ intensity × Lambert's cosine. The shadow and occlusion passes
/// weigh what they take away against it.
pub(crate) fn direct_lambert(scene: &FrameScene, n: Vec3, xc: Vec3) -> f32 {
    scene
        .lights
        .iter()
        .map(|l| l.intensity.max(0.0) * lambert(n, xc, l.position_cam_m.as_vec3()))
        .sum()
}

/// sRGB ↔ linear tables for darkening 8-bit pixels in linear light.
#[derive(Default)]
pub(crate) struct LinearTables {
    to_lin: Vec<f32>,
    to_srgb: Vec<u8>,
}

/// Scales each pixel of `rgb` (sRGB, 8 bits) by `1 − lost` in linear light (sRGB → linear by
/// a table, back by a 4096-step one); pixels with `lost <= 0` are left as they are.
pub(crate) fn darken_linear(rgb: &mut [u8], lost: &[f32], t: &mut LinearTables) {
    if t.to_lin.is_empty() {
        t.to_lin = (0..256).map(|v| (v as f32 / 255.0).powf(2.2)).collect();
        t.to_srgb = (0..4096)
            .map(|i| ((i as f32 / 4095.0).powf(1.0 / 2.2) * 255.0).round() as u8)
            .collect();
    }
    for (i, &lost) in lost.iter().enumerate() {
        if lost <= 0.0 {
            continue;
        }
        let keep = (1.0 - lost).max(0.0);
        for c in &mut rgb[3 * i..3 * i + 3] {
            let lin = t.to_lin[*c as usize] * keep;
            // lin ≥ 0: + 0.5 and a truncating cast round it (no libm call).
            *c = t.to_srgb[((lin * 4095.0 + 0.5) as usize).min(4095)];
        }
    }
}

/// Darkens `rgb` (sRGB, 8 bits) where the scene's lights are blocked by its objects.
/// `depth_m` is the frame's z-depth (0: nothing there), `proj` its camera.
pub(crate) fn apply(
    models: &[PreparedModel],
    scene: &FrameScene,
    proj: &Projection,
    depth_m: &[f32],
    rgb: &mut [u8],
    s: &mut ShadowScratch,
) {
    let casters: Vec<&ObjectInstance> = scene.objects.iter().chain(&scene.distractors).collect();
    if casters.is_empty() || scene.lights.is_empty() {
        return;
    }
    let k = &scene.intrinsics;
    let w = k.width as usize;
    // Each caster's bounding-sphere radius about its origin, for the lights' fields of view.
    let radii: Vec<f32> = casters
        .iter()
        .map(|c| {
            let m = &models[c.model_index];
            m.xs.iter()
                .zip(&m.ys)
                .zip(&m.zs)
                .map(|((x, y), z)| x * x + y * y + z * z)
                .fold(0.0f32, f32::max)
                .sqrt()
        })
        .collect();
    s.lost.clear();
    s.lost.resize(depth_m.len(), 0.0);
    let centre = casters
        .iter()
        .map(|c| c.cam_from_obj.translation_m.as_vec3())
        .sum::<Vec3>()
        / casters.len() as f32;
    for light in &scene.lights {
        if light.intensity <= 0.0 {
            continue;
        }
        let p = light.position_cam_m.as_vec3();
        let Some(fwd) = (centre - p).try_normalize() else {
            continue;
        };
        let hint = if fwd.y.abs() < 0.9 { Vec3::Y } else { Vec3::X };
        let x = hint.cross(fwd).normalize();
        let y = fwd.cross(x);
        // light_from_cam: rows x, y, fwd.
        let lc = Mat3::from_cols(x, y, fwd).transpose();
        // A field of view holding every caster's bounding sphere.
        let mut tan_max = 0.0f32;
        for (c, &r) in casters.iter().zip(&radii) {
            let q = lc * (c.cam_from_obj.translation_m.as_vec3() - p);
            if q.z - r <= 0.02 {
                continue; // the light is inside or behind this caster: no map for it
            }
            let lateral = (q.x * q.x + q.y * q.y).sqrt();
            tan_max = tan_max.max((lateral + r) / (q.z - r));
        }
        if tan_max <= 0.0 {
            continue;
        }
        let half = MAP as f32 / 2.0;
        let f = half / tan_max.min(6.0);
        let lp = Projection {
            fx: f,
            fy: f,
            cx: half,
            cy: half,
            near_m: 0.01,
        };
        let canvas = Rect {
            x0: 0,
            y0: 0,
            x1: MAP as i32,
            y1: MAP as i32,
        };
        s.map.clear();
        s.map.resize(MAP * MAP, 0.0);
        for c in &casters {
            let rot = lc * c.cam_from_obj.rotation.as_mat3();
            let t = lc * (c.cam_from_obj.translation_m.as_vec3() - p);
            // The faces towards the light (culled as the camera culls): a closed surface's
            // first hit, at half the triangles.
            let win = raster_object(
                &models[c.model_index],
                false,
                &rot,
                t,
                &lp,
                canvas,
                &mut s.os,
                &mut s.alone,
            );
            let ww = win.width();
            for (row, y) in (win.y0..win.y1).enumerate() {
                if y < 0 || y >= MAP as i32 {
                    continue;
                }
                for (col, x) in (win.x0..win.x1).enumerate() {
                    if x < 0 || x >= MAP as i32 {
                        continue;
                    }
                    let z = s.alone[row * ww + col];
                    let d = &mut s.map[y as usize * MAP + x as usize];
                    if z > 0.0 && (*d == 0.0 || z < *d) {
                        *d = z;
                    }
                }
            }
        }
        // q = lc (xc − p) with xc = z (a_u, b_v, 1): per column lc (a_u, 0, 0), per row
        // lc (0, b_v, 1), so a pixel costs a multiply-add.
        let cols: Vec<Vec3> = (0..w)
            .map(|x| lc * Vec3::new((x as f32 + 0.5 - proj.cx) / proj.fx, 0.0, 0.0))
            .collect();
        let lp = lc * p;
        for (py, zrow) in depth_m.chunks_exact(w).enumerate() {
            let row_term = lc * Vec3::new(0.0, (py as f32 + 0.5 - proj.cy) / proj.fy, 1.0);
            for (px, &z) in zrow.iter().enumerate() {
                if z <= 0.0 {
                    continue;
                }
                let i = py * w + px;
                let q = z * (cols[px] + row_term) - lp;
                if q.z <= 0.01 {
                    continue;
                }
                let (mu, mv) = (f * q.x / q.z + half, f * q.y / q.z + half);
                if !(1.0..MAP as f32 - 1.0).contains(&mu) || !(1.0..MAP as f32 - 1.0).contains(&mv)
                {
                    continue;
                }
                // A texel spans q.z / f metres: a surface may sit that far behind its own texel.
                let bias = 2.5 * q.z / f + 0.004;
                let (cu, cv) = (mu as usize, mv as usize);
                let mut blocked = 0u32;
                for dv in 0..3 {
                    for du in 0..3 {
                        let d = s.map[(cv + dv - 1) * MAP + cu + du - 1];
                        blocked += u32::from(d > 0.0 && q.z > d + bias);
                    }
                }
                if blocked == 0 {
                    continue;
                }
                // What this light gave the pixel (Lambert, the normal from the depth buffer), out
                // of everything it received: a face turned away from the light loses nothing.
                let Some(n) = depth_features::normal_cam(depth_m, SAME_SURFACE, k, px, py) else {
                    continue;
                };
                let xc = proj.unproject(px as f32, py as f32, z);
                let received = scene.ambient.max(0.0) + direct_lambert(scene, n, xc);
                let from_this = light.intensity.max(0.0) * lambert(n, xc, p);
                if received > 0.0 {
                    s.lost[i] += from_this / received * blocked as f32 / 9.0;
                }
            }
        }
    }
    darken_linear(rgb, &s.lost, &mut s.tables);
}
