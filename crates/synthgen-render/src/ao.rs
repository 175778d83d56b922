//! Screen-space ambient occlusion for the embedded rasterizer (`[lights] ambient_occlusion`):
//! contact shadows where objects touch the table and each other. From the depth buffer alone
//! (objects, ground and walls alike): at every other pixel in x and y (a quarter of them; the
//! occlusion varies slowly), 8 samples within `RADIUS_M` (projected at the pixel's depth) on a
//! disk turned per pixel by a 4x4 pattern; a sample whose surface point lies above the pixel's
//! tangent plane occludes it, weighted by its elevation and by its distance (Alchemy/HBAO-style
//! obscurance); every pixel then takes the mean of the computed ones in its 4x4 block within
//! one surface (2x2 of them, 32 samples), and the pixel loses `strength × ao` of the
//! ambient share of its light (ambient / (ambient + Σ Lambert), computed with the obscurance
//! at the same pixels and filtered with it), in linear light as the shadow pass darkens.

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
    tiles: Vec<bool>,
    tables: crate::shadow::LinearTables,
}

/// The raw obscurance 0..1 at the pixels with even x and y of `depth_m` (0 where empty), −1
/// at the others (not computed), before filtering. With `share`, each computed pixel's
/// obscurance is multiplied by the ambient share of its light (ambient / (ambient + Σ
/// Lambert), from the same normal), so that the filter averages what the pixel loses.
pub(crate) fn obscurance(
    scene: &FrameScene,
    proj: &Projection,
    depth_m: &[f32],
    ao: &mut Vec<f32>,
    share: bool,
) {
    let k = &scene.intrinsics;
    let (w, h) = (k.width as usize, k.height as usize);
    ao.clear();
    ao.resize(depth_m.len(), -1.0);
    let ambient = scene.ambient.max(0.0);
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
                // Rounded to the nearest pixel (truncation of a non-negative value + 0.5:
                // no libm call).
                let (fx, fy) = (x as f32 + dx * r_px + 0.5, y as f32 + dy * r_px + 0.5);
                if fx < 0.0 || fy < 0.0 {
                    continue;
                }
                let (sx, sy) = (fx as usize, fy as usize);
                if sx >= w || sy >= h {
                    continue;
                }
                let zs = depth_m[sy * w + sx];
                if zs <= 0.0 {
                    continue;
                }
                let v = proj.unproject(sx as f32, sy as f32, zs) - p;
                let d2 = v.length_squared();
                // Below the tangent plane, or out of reach: no occlusion (most samples on a
                // flat floor), decided before the square root.
                let nv = n.dot(v);
                if nv <= 0.0 || d2 <= 1e-12 || d2 >= RADIUS_M * RADIUS_M {
                    continue;
                }
                let d = d2.sqrt();
                occ += (nv / d - BIAS).max(0.0) * (1.0 - d2 * (1.0 / (RADIUS_M * RADIUS_M)));
            }
            let mut a = (occ * 4.0 / SAMPLES as f32).min(1.0);
            if share && a > 0.0 {
                a *= ambient / (ambient + direct_lambert(scene, n, p));
            }
            ao[y * w + x] = a;
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
    obscurance(scene, proj, depth_m, &mut s.ao, true);
    filter(&mut s.ao, &mut s.tmp, &mut s.tiles, depth_m, w, h);
    // The filtered obscurance already carries the ambient share.
    s.lost.clear();
    s.lost.extend(s.ao.iter().map(|&a| strength * a.max(0.0)));
    darken_linear(rgb, &s.lost, &mut s.tables);
}

/// The 4x4 box filter of the obscurance `ao` (in place), only over computed pixels (≥ 0) of
/// about the same depth. A pixel's filtered value is positive only within 2 pixels of a
/// positive one, and the first pass's values there come from pixels within 2 pixels of it: both
/// passes run on the tiles holding a positive and their neighbours and leave the rest ≤ 0 — the
/// same values as over every pixel (test `the_tiled_filter_is_the_full_filter`).
fn filter(
    ao: &mut [f32],
    tmp: &mut Vec<f32>,
    tiles: &mut Vec<bool>,
    depth_m: &[f32],
    w: usize,
    h: usize,
) {
    let (tw, th) = (w.div_ceil(TILE), h.div_ceil(TILE));
    tiles.clear();
    tiles.resize(tw * th, false);
    for y in (0..h).step_by(2) {
        for x in (0..w).step_by(2) {
            if ao[y * w + x] > 0.0 {
                tiles[(y / TILE) * tw + x / TILE] = true;
            }
        }
    }
    let near = dilate(tiles, tw, th);
    tmp.clear();
    tmp.resize(ao.len(), 0.0);
    let pass = |src: &[f32], dst: &mut [f32], horizontal: bool| {
        for ty in 0..th {
            for tx in 0..tw {
                if !near[ty * tw + tx] {
                    continue;
                }
                for y in ty * TILE..((ty + 1) * TILE).min(h) {
                    for x in tx * TILE..((tx + 1) * TILE).min(w) {
                        if let Some(v) = box_tap(src, depth_m, w, h, x, y, horizontal) {
                            dst[y * w + x] = v;
                        }
                    }
                }
            }
        }
    };
    pass(ao, tmp, true);
    pass(tmp, ao, false);
}

/// Side of the square tiles the filter skips where nothing is occluded, pixels.
const TILE: usize = 16;

/// `tiles` (tw x th) with each set tile's 8 neighbours set too.
fn dilate(tiles: &[bool], tw: usize, th: usize) -> Vec<bool> {
    let mut out = vec![false; tiles.len()];
    for ty in 0..th {
        for tx in 0..tw {
            if !tiles[ty * tw + tx] {
                continue;
            }
            for y in ty.saturating_sub(1)..(ty + 2).min(th) {
                for x in tx.saturating_sub(1)..(tx + 2).min(tw) {
                    out[y * tw + x] = true;
                }
            }
        }
    }
    out
}

/// One pass of the 4-tap box filter at (x, y): horizontal (`x − 2 ..= x + 1`) or vertical,
/// over the computed taps (≥ 0) on the pixel's surface. None for an empty pixel (left as it
/// is); −1 after the first pass where no tap was computed, 0 after the second.
#[inline]
fn box_tap(
    src: &[f32],
    depth_m: &[f32],
    w: usize,
    h: usize,
    x: usize,
    y: usize,
    horizontal: bool,
) -> Option<f32> {
    let i = y * w + x;
    let z = depth_m[i];
    if z <= 0.0 {
        return None;
    }
    let (mut sum, mut cnt) = (0.0, 0.0);
    for o in -2i32..2 {
        let (xx, yy) = if horizontal {
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
    Some(if cnt > 0.0 {
        sum / cnt
    } else if horizontal {
        -1.0
    } else {
        0.0
    })
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
        obscurance(&scene, &proj, &depth, &mut ao, false);
        let at = |x: usize| ao[60 * 160 + x];
        assert_eq!(ao[61 * 160 + 79], -1.0, "odd pixels are not computed");
        assert!(at(78) > 0.15, "foot of the step: {}", at(78));
        // The step's edge looks down on the floor: nothing above its tangent plane.
        assert!(at(82) == 0.0, "edge of the step: {}", at(82));
        assert!(at(20) == 0.0, "open floor: {}", at(20));
        assert!(at(120) == 0.0, "top of the step: {}", at(120));
    }

    /// The tiled filter gives what the 4x4 filter over every pixel gives, bit for bit, on a
    /// floor with boxes (occlusion in some tiles only) and empty pixels.
    #[test]
    fn the_tiled_filter_is_the_full_filter() {
        let (w, h) = (203usize, 131usize);
        let k = Intrinsics {
            width: w as u32,
            height: h as u32,
            fx: 220.0,
            fy: 220.0,
            cx: 101.0,
            cy: 65.0,
        };
        let proj = Projection {
            fx: 220.0,
            fy: 220.0,
            cx: 101.0,
            cy: 65.0,
            near_m: 0.01,
        };
        let mut depth = vec![1.0f32; w * h];
        for (i, d) in depth.iter_mut().enumerate() {
            let (x, y) = (i % w, i / w);
            if (30..60).contains(&x) && (20..50).contains(&y) {
                *d = 0.97;
            }
            if (120..170).contains(&x) && (70..120).contains(&y) {
                *d = 0.95 + 0.0004 * (x - 120) as f32;
            }
            if x > 190 && y < 10 {
                *d = 0.0;
            }
        }
        let scene = FrameScene::bare(0, k, vec![]);
        let mut ao = Vec::new();
        obscurance(&scene, &proj, &depth, &mut ao, false);
        assert!(ao.iter().any(|&a| a > 0.0));
        // The filter over every pixel.
        let mut full = ao.clone();
        let mut tmp = vec![0.0; ao.len()];
        for y in 0..h {
            for x in 0..w {
                if let Some(v) = box_tap(&full, &depth, w, h, x, y, true) {
                    tmp[y * w + x] = v;
                }
            }
        }
        for y in 0..h {
            for x in 0..w {
                if let Some(v) = box_tap(&tmp, &depth, w, h, x, y, false) {
                    full[y * w + x] = v;
                }
            }
        }
        let (mut tiled, mut scratch, mut tiles) = (ao.clone(), Vec::new(), Vec::new());
        filter(&mut tiled, &mut scratch, &mut tiles, &depth, w, h);
        let clamp = |v: &[f32]| v.iter().map(|a| a.max(0.0).to_bits()).collect::<Vec<_>>();
        assert_eq!(clamp(&tiled), clamp(&full));
        assert!(tiles.iter().any(|&t| !t), "some tiles are skipped");
    }
}
