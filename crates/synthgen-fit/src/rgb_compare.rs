//! Real photographs against their synthetic twins (`render --replay`), inside the real visible
//! masks: how close a renderer's colours come to a camera's, per object. The RGB analogue of
//! `sensor::compare`.
//!
//! Per frame, the exposure and white balance of the render are fitted to the photograph first:
//! one gain per channel, least squares over every compared pixel of the frame (a camera's
//! auto-exposure and white balance are per frame, not per object). Then per instance (pixels in
//! the real visible mask that the render covers, the mask eroded by one pixel so that edge
//! misregistration does not dominate):
//! - `ncc_intensity`: normalized cross-correlation of the grey levels (1: the same shading and
//!   print up to brightness and contrast);
//! - `ncc_gradient`: the same for the Sobel gradient magnitudes (edges, print, texture: what a
//!   CNN's first layers see);
//! - `hist_distance`: the Hellinger distance between the two 16-bin-per-channel colour
//!   histograms (0: the same colours, 1: disjoint).

use std::collections::BTreeMap;

use serde::Serialize;

use synthgen_formats::bop::image::{read_rgb, Plane, RgbImage};
use synthgen_formats::source::{FrameSource, SourceFrame};
use synthgen_formats::Result;

/// Which frames and instances are compared.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbCompareOptions {
    /// Scene ids of the real dataset (all when empty).
    pub scenes: Vec<u32>,
    /// Instances with fewer compared pixels are left out.
    pub min_pixels: usize,
}

impl Default for RgbCompareOptions {
    fn default() -> Self {
        Self {
            scenes: Vec::new(),
            min_pixels: 200,
        }
    }
}

/// One instance's scores.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InstanceScore {
    pub scene_id: u32,
    pub im_id: u32,
    pub obj_id: u32,
    pub pixels: usize,
    pub ncc_intensity: f64,
    pub ncc_gradient: f64,
    pub hist_distance: f64,
}

/// Means over instances.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MeanScore {
    pub instances: usize,
    pub ncc_intensity: f64,
    pub ncc_gradient: f64,
    pub hist_distance: f64,
}

/// The comparison of two datasets' colour images.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RgbComparison {
    /// Real frames with a twin.
    pub frames: usize,
    /// Real frames without one (not compared).
    pub frames_without_twin: usize,
    /// Real frames whose namesake in the other dataset shows something else (another
    /// camera, other objects or poses): not compared.
    pub frames_not_twins: usize,
    /// A few of them, with why.
    pub not_twins: Vec<String>,
    pub all: MeanScore,
    pub objects: BTreeMap<u32, MeanScore>,
    pub instances: Vec<InstanceScore>,
}

/// Why `twin` is not a replay of `real` (its camera or its objects' GT poses differ), None
/// when it is one: the same intrinsics (within 0.01 px), the same objects in the same
/// order, each within 1 mm and 1e-3 of the rotation's entries.
pub fn not_a_twin(real: &SourceFrame, twin: &SourceFrame) -> Option<String> {
    let close = |a: &[f64], b: &[f64], tol: f64| a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol);
    if !close(&real.camera.cam_k, &twin.camera.cam_k, 0.01) {
        return Some("another camera (cam_K)".into());
    }
    let objs = |f: &SourceFrame| f.gt.iter().map(|g| g.obj_id).collect::<Vec<_>>();
    if objs(real) != objs(twin) {
        return Some(format!(
            "other objects ({:?} and {:?})",
            objs(real),
            objs(twin)
        ));
    }
    for (a, b) in real.gt.iter().zip(&twin.gt) {
        if !close(&a.cam_t_m2c, &b.cam_t_m2c, 1.0) || !close(&a.cam_r_m2c, &b.cam_r_m2c, 1e-3) {
            return Some(format!("object {} at another pose", a.obj_id));
        }
    }
    None
}

/// Compares the colour images of `real` with those of `synth` (frames matched by scene and
/// image id, and refused as twins where the camera or the GT poses differ), inside `real`'s
/// visible masks.
pub fn compare_rgb(
    real: &dyn FrameSource,
    synth: &dyn FrameSource,
    opts: &RgbCompareOptions,
) -> Result<RgbComparison> {
    let twins: BTreeMap<(u32, u32), SourceFrame> = synth
        .annotation_frames(&[])?
        .into_iter()
        .map(|f| ((f.location.scene_id, f.location.im_id), f))
        .collect();
    let mut frames = 0;
    let mut without = 0;
    let (mut not_twins, mut not_twin_count) = (Vec::new(), 0usize);
    let mut instances = Vec::new();
    for f in real.frames(&[])? {
        if !opts.scenes.is_empty() && !opts.scenes.contains(&f.location.scene_id) {
            continue;
        }
        let Some(twin) = twins.get(&(f.location.scene_id, f.location.im_id)) else {
            without += 1;
            continue;
        };
        // Ids alone do not make a twin: a replay has the real frame's camera and GT poses.
        if let Some(why) = not_a_twin(&f, twin) {
            if not_twins.len() < 3 {
                not_twins.push(format!(
                    "scene {} image {}: {why}",
                    f.location.scene_id, f.location.im_id
                ));
            }
            not_twin_count += 1;
            continue;
        }
        frames += 1;
        let (a, b) = (read_rgb(&f.rgb)?, read_rgb(&twin.rgb)?);
        if (a.width, a.height) != (b.width, b.height) {
            return Err(synthgen_formats::Error::InvalidRequest(format!(
                "{} is {}x{}, its twin {} is {}x{}",
                f.rgb.display(),
                a.width,
                a.height,
                twin.rgb.display(),
                b.width,
                b.height
            )));
        }
        let mut masks = Vec::new();
        for (gt, m) in f.gt.iter().zip(&f.masks_visib) {
            let Some(m) = m else { continue };
            let plane = m.read()?;
            let px = compared_pixels(&plane, &b);
            if px.len() >= opts.min_pixels {
                masks.push((gt.obj_id, px));
            }
        }
        let all_px: Vec<usize> = masks.iter().flat_map(|(_, p)| p.iter().copied()).collect();
        let gain = channel_gains(&a, &b, &all_px);
        let (ga, gb) = (grey(&a, [1.0; 3]), grey(&b, gain));
        let (sa, sb) = (sobel(&ga, a.width as usize), sobel(&gb, b.width as usize));
        for (obj_id, px) in masks {
            instances.push(InstanceScore {
                scene_id: f.location.scene_id,
                im_id: f.location.im_id,
                obj_id,
                pixels: px.len(),
                ncc_intensity: ncc(&px, &ga, &gb),
                ncc_gradient: ncc(&px, &sa, &sb),
                hist_distance: hellinger(&px, &a, [1.0; 3], &b, gain),
            });
        }
    }
    let mean = |v: &[&InstanceScore]| MeanScore {
        instances: v.len(),
        ncc_intensity: avg(v.iter().map(|s| s.ncc_intensity)),
        ncc_gradient: avg(v.iter().map(|s| s.ncc_gradient)),
        hist_distance: avg(v.iter().map(|s| s.hist_distance)),
    };
    let mut by_obj: BTreeMap<u32, Vec<&InstanceScore>> = BTreeMap::new();
    for s in &instances {
        by_obj.entry(s.obj_id).or_default().push(s);
    }
    let objects = by_obj.iter().map(|(&k, v)| (k, mean(v))).collect();
    let all = mean(&instances.iter().collect::<Vec<_>>());
    Ok(RgbComparison {
        frames,
        frames_without_twin: without,
        frames_not_twins: not_twin_count,
        not_twins,
        all,
        objects,
        instances,
    })
}

fn avg(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

/// Pixels of the mask, eroded by one (4-neighbours), that the render covers (not black).
fn compared_pixels(mask: &Plane<u8>, render: &RgbImage) -> Vec<usize> {
    let (w, h) = (mask.width as usize, mask.height as usize);
    let on = |x: usize, y: usize| mask.data[y * w + x] != 0;
    let mut out = Vec::new();
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let i = y * w + x;
            if on(x, y) && on(x - 1, y) && on(x + 1, y) && on(x, y - 1) && on(x, y + 1) {
                let c = &render.rgb[3 * i..3 * i + 3];
                if c.iter().any(|&v| v > 0) {
                    out.push(i);
                }
            }
        }
    }
    out
}

/// Per channel, the gain g minimizing Σ (real − g · render)² over `px`.
fn channel_gains(real: &RgbImage, render: &RgbImage, px: &[usize]) -> [f64; 3] {
    let mut g = [1.0; 3];
    for (c, gc) in g.iter_mut().enumerate() {
        let (mut num, mut den) = (0.0, 0.0);
        for &i in px {
            let (a, b) = (
                f64::from(real.rgb[3 * i + c]),
                f64::from(render.rgb[3 * i + c]),
            );
            num += a * b;
            den += b * b;
        }
        if den > 0.0 {
            *gc = num / den;
        }
    }
    g
}

fn grey(img: &RgbImage, gain: [f64; 3]) -> Vec<f64> {
    img.rgb
        .chunks_exact(3)
        .map(|c| {
            (0..3)
                .map(|k| (f64::from(c[k]) * gain[k]).min(255.0))
                .sum::<f64>()
                / 3.0
        })
        .collect()
}

fn sobel(g: &[f64], w: usize) -> Vec<f64> {
    let h = g.len() / w.max(1);
    let mut out = vec![0.0; g.len()];
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let p = |dx: isize, dy: isize| {
                g[(y as isize + dy) as usize * w + (x as isize + dx) as usize]
            };
            let gx = p(1, -1) + 2.0 * p(1, 0) + p(1, 1) - p(-1, -1) - 2.0 * p(-1, 0) - p(-1, 1);
            let gy = p(-1, 1) + 2.0 * p(0, 1) + p(1, 1) - p(-1, -1) - 2.0 * p(0, -1) - p(1, -1);
            out[y * w + x] = (gx * gx + gy * gy).sqrt();
        }
    }
    out
}

/// Normalized cross-correlation of `a` and `b` over `px`; 0 when either is constant there.
fn ncc(px: &[usize], a: &[f64], b: &[f64]) -> f64 {
    let n = px.len() as f64;
    let (ma, mb) = (
        px.iter().map(|&i| a[i]).sum::<f64>() / n,
        px.iter().map(|&i| b[i]).sum::<f64>() / n,
    );
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for &i in px {
        let (x, y) = (a[i] - ma, b[i] - mb);
        sab += x * y;
        saa += x * x;
        sbb += y * y;
    }
    if saa <= 1e-12 || sbb <= 1e-12 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}

/// Hellinger distance between the 16-bin-per-channel histograms (channels concatenated).
fn hellinger(px: &[usize], a: &RgbImage, ga: [f64; 3], b: &RgbImage, gb: [f64; 3]) -> f64 {
    let hist = |img: &RgbImage, g: [f64; 3]| {
        let mut h = [0.0f64; 48];
        for &i in px {
            for c in 0..3 {
                let v = (f64::from(img.rgb[3 * i + c]) * g[c]).clamp(0.0, 255.0);
                h[c * 16 + ((v / 16.0) as usize).min(15)] += 1.0;
            }
        }
        let n: f64 = h.iter().sum();
        h.map(|x| x / n.max(1.0))
    };
    let (p, q) = (hist(a, ga), hist(b, gb));
    let bc: f64 = p.iter().zip(&q).map(|(x, y)| (x * y).sqrt()).sum::<f64>();
    (1.0 - bc).max(0.0).sqrt()
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 3]) -> RgbImage {
        let mut rgb = Vec::new();
        for y in 0..h {
            for x in 0..w {
                rgb.extend(f(x, y));
            }
        }
        RgbImage {
            width: w,
            height: h,
            rgb,
        }
    }

    /// A render that is the photograph at another exposure and white balance scores as the
    /// same image; a flat render of a textured object does not.
    #[test]
    fn exposure_is_fitted_and_texture_counts() {
        let (w, h) = (40u32, 30u32);
        let real = image(w, h, |x, y| {
            let v = (60 + (x * 5 + y * 3) % 120) as u8;
            [v, v / 2 + 20, 200 - v]
        });
        // Darker and bluer, everything else the same.
        let dim = image(w, h, |x, y| {
            let c = real.rgb[3 * (y * w + x) as usize..][..3].to_vec();
            [
                (f64::from(c[0]) * 0.6) as u8,
                (f64::from(c[1]) * 0.7) as u8,
                (f64::from(c[2]) * 0.9) as u8,
            ]
        });
        let flat = image(w, h, |_, _| [120, 80, 90]);
        let mask = Plane {
            width: w,
            height: h,
            data: vec![255u8; (w * h) as usize],
        };
        let px = compared_pixels(&mask, &dim);
        assert_eq!(px.len(), ((w - 2) * (h - 2)) as usize, "eroded by one");
        let g = channel_gains(&real, &dim, &px);
        assert!(
            (g[0] - 1.0 / 0.6).abs() < 0.02 && (g[2] - 1.0 / 0.9).abs() < 0.02,
            "{g:?}"
        );
        let ga = grey(&real, [1.0; 3]);
        let gd = grey(&dim, g);
        assert!(ncc(&px, &ga, &gd) > 0.99);
        let (sa, sd) = (sobel(&ga, w as usize), sobel(&gd, w as usize));
        assert!(ncc(&px, &sa, &sd) > 0.95);
        let hd = hellinger(&px, &real, [1.0; 3], &dim, g);
        assert!(hd < 0.3, "{hd}");
        let gf = channel_gains(&real, &flat, &px);
        assert_eq!(
            ncc(&px, &ga, &grey(&flat, gf)),
            0.0,
            "a flat render has no shading"
        );
        assert!(hellinger(&px, &real, [1.0; 3], &flat, gf) > 0.5);
    }
}
