//! Screen-space ambient occlusion for the embedded rasterizer (`[lights] ambient_occlusion`):
//! contact shadows where objects touch the table and each other. From the depth buffer alone
//! (objects, ground and walls alike): at every other pixel in x and y (a quarter of them; the
//! occlusion varies slowly), 8 samples within `RADIUS_M` (projected at the pixel's depth) on a
//! disk turned per pixel by a 4x4 pattern; a sample whose surface point lies above the pixel's
//! tangent plane occludes it, weighted by its elevation and by its distance (Alchemy/HBAO-style
//! obscurance); every pixel then takes the mean of the computed ones in its 4x4 block within
//! one surface (2x2 of them, 32 samples), and the pixel loses `strength × ao` of the
//! ambient share of its light (ambient / (ambient + Σ Lambert)), in linear light as the
//! shadow pass darkens.

use synthgen_core::{depth_features, FrameScene};

use crate::raster::Projection;
use crate::shadow::{darken_linear, direct_lambert};

/// World radius of the occlusion search, metres.
pub(crate) const RADIUS_M: f32 = 0.05;
/// Samples per pixel.
const SAMPLES: usize = 8;
/// Neighbours within this share of a pixel's depth lie on its surface (for its normal).
const SAME_SURFACE: f32 = 0.05;
/// Elevations below this (cosine) do not occlude: a flat surface must not occlude itself.
const BIAS: f32 = 0.1;

/// Buffers reused from frame to frame.
#[derive(Default)]
pub(crate) struct AoScratch {
    ao: Vec<f32>,
    tmp: Vec<f32>,
    lost: Vec<f32>,
    tables: crate::shadow::LinearTables,
}

/// The raw obscurance 0..1 at the pixels with even x and y of `depth_m` (0 where empty), −1
/// at the others (not computed), before filtering.
pub(crate) fn obscurance(
    scene: &FrameScene,
    proj: &Projection,
    depth_m: &[f32],
    ao: &mut Vec<f32>,
) {
    let k = &scene.intrinsics;
    let (w, h) = (k.width as usize, k.height as usize);
    ao.clear();
    ao.resize(depth_m.len(), -1.0);
    // 16 disk patterns (4x4 pixels): 8 directions each, turned and with radii 0.25..1.
    let dirs: Vec<[(f32, f32); SAMPLES]> = (0..16)
        .map(|p| {
            let turn = (p as f32 * 0.618_034).fract() * std::f32::consts::TAU / SAMPLES as f32;
            std::array::from_fn(|s| {
                let a = turn + s as f32 * std::f32::consts::TAU / SAMPLES as f32;
                let r = 0.25 + 0.75 * (((s * 5 + p * 3) % SAMPLES) as f32 + 0.5) / SAMPLES as f32;
                (a.cos() * r, a.sin() * r)
            })
        })
        .collect();
    for y in (0..h).step_by(2) {
        for x in (0..w).step_by(2) {
            let z = depth_m[y * w + x];
            ao[y * w + x] = 0.0;
            if z <= 0.0 {
                continue;
            }
            let Some(n) = depth_features::normal_cam(depth_m, SAME_SURFACE, k, x, y) else {
                continue;
            };
            let p = proj.unproject(x as f32, y as f32, z);
            let r_px = proj.fx * RADIUS_M / z;
            if r_px < 1.0 {
                continue;
            }
            let mut occ = 0.0;
            for &(dx, dy) in &dirs[((y / 2) % 4) * 4 + (x / 2) % 4] {
                let sx = (x as f32 + dx * r_px).round();
                let sy = (y as f32 + dy * r_px).round();
                if sx < 0.0 || sy < 0.0 || sx >= w as f32 || sy >= h as f32 {
                    continue;
                }
                let zs = depth_m[sy as usize * w + sx as usize];
                if zs <= 0.0 {
                    continue;
                }
                let v = proj.unproject(sx, sy, zs) - p;
                let d = v.length();
                if d <= 1e-6 || d >= RADIUS_M {
                    continue;
                }
                let fall = d / RADIUS_M;
                occ += (n.dot(v) / d - BIAS).max(0.0) * (1.0 - fall * fall);
            }
            ao[y * w + x] = (occ * 4.0 / SAMPLES as f32).min(1.0);
        }
    }
}

/// Darkens `rgb` (sRGB, 8 bits) by the ambient occlusion of `depth_m`, `strength` 0..1.
pub(crate) fn apply(
    scene: &FrameScene,
    proj: &Projection,
    depth_m: &[f32],
    strength: f32,
    rgb: &mut [u8],
    s: &mut AoScratch,
) {
    if strength <= 0.0 || scene.ambient <= 0.0 {
        return;
    }
    let k = &scene.intrinsics;
    let (w, h) = (k.width as usize, k.height as usize);
    obscurance(scene, proj, depth_m, &mut s.ao);
    // 4x4 box filter, only over computed pixels (≥ 0) of about the same depth.
    s.tmp.clear();
    s.tmp.resize(s.ao.len(), 0.0);
    for pass in 0..2 {
        let (src, dst) = if pass == 0 {
            (&s.ao, &mut s.tmp)
        } else {
            (&s.tmp, &mut s.ao)
        };
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let z = depth_m[i];
                if z <= 0.0 {
                    continue;
                }
                let (mut sum, mut cnt) = (0.0, 0.0);
                for o in -2i32..2 {
                    let (xx, yy) = if pass == 0 {
                        (x as i32 + o, y as i32)
                    } else {
                        (x as i32, y as i32 + o)
                    };
                    if xx < 0 || yy < 0 || xx >= w as i32 || yy >= h as i32 {
                        continue;
                    }
                    let j = yy as usize * w + xx as usize;
                    if src[j] >= 0.0 && (depth_m[j] - z).abs() <= SAME_SURFACE * z {
                        sum += src[j];
                        cnt += 1.0;
                    }
                }
                dst[i] = if cnt > 0.0 {
                    sum / cnt
                } else if pass == 0 {
                    -1.0
                } else {
                    0.0
                };
            }
        }
    }
    // The ambient share of what each pixel received (Lambert, as it was shaded).
    s.lost.clear();
    s.lost.resize(depth_m.len(), 0.0);
    let ambient = scene.ambient.max(0.0);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let ao = s.ao[i];
            if ao <= 0.0 {
                continue;
            }
            let xc = proj.unproject(x as f32, y as f32, depth_m[i]);
            let direct = depth_features::normal_cam(depth_m, SAME_SURFACE, k, x, y)
                .map_or(0.0, |n| direct_lambert(scene, n, xc));
            s.lost[i] = strength * ao * ambient / (ambient + direct);
        }
    }
    darken_linear(rgb, &s.lost, &mut s.tables);
}

#[cfg(test)]
mod tests {
    use super::*;
    use synthgen_core::Intrinsics;

    /// A floor 1 m away, facing the camera, with a 2 cm step in the middle of the image: the
    /// floor next to the step's foot is occluded, the open floor and the step's top are not.
    #[test]
    fn a_step_occludes_the_floor_at_its_foot_only() {
        let k = Intrinsics {
            width: 160,
            height: 120,
            fx: 200.0,
            fy: 200.0,
            cx: 80.0,
            cy: 60.0,
        };
        let proj = Projection {
            fx: 200.0,
            fy: 200.0,
            cx: 80.0,
            cy: 60.0,
            near_m: 0.01,
        };
        let mut depth = vec![1.0f32; 160 * 120];
        for y in 0..120 {
            for x in 80..160 {
                depth[y * 160 + x] = 0.98; // the step, 2 cm nearer
            }
        }
        let scene = FrameScene::bare(0, k, vec![]);
        let mut ao = Vec::new();
        obscurance(&scene, &proj, &depth, &mut ao);
        let at = |x: usize| ao[60 * 160 + x];
        assert_eq!(ao[61 * 160 + 79], -1.0, "odd pixels are not computed");
        assert!(at(78) > 0.15, "foot of the step: {}", at(78));
        // The step's edge looks down on the floor: nothing above its tangent plane.
        assert!(at(82) == 0.0, "edge of the step: {}", at(82));
        assert!(at(20) == 0.0, "open floor: {}", at(20));
        assert!(at(120) == 0.0, "top of the step: {}", at(120));
    }
}
